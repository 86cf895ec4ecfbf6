"""RViz / Foxglove markers of a trial, drawn from its ``sdbc_msgs/TaskState``.

Every task renders without task-specific code, from the entity groups alone:
circles (robots, the prey, a station) as flat cylinders, points as spheres, and
polygons (walls, the gate, a boundary) as line lists, one colour per group, plus a
text line with the trial and step. Each array starts with a DELETEALL marker, so
entities that leave a group (an escaped robot, a captured prey) vanish. Given the
bodies' poses (:func:`body_poses`), an arrow per body shows its heading.

The frame is the task state's, ``arena`` (the arena's own coordinates, x to the
right, y up, headings counter-clockwise from x): the fixed frame to choose in
RViz or Foxglove. No TF is published; nothing moves the arena.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from geometry_msgs.msg import Point, Pose, PoseArray
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from sdbc_msgs.msg import Entity

PALETTE = (
    (0.12, 0.47, 0.71),
    (1.00, 0.50, 0.05),
    (0.17, 0.63, 0.17),
    (0.84, 0.15, 0.16),
    (0.58, 0.40, 0.74),
    (0.55, 0.34, 0.29),
)
"""Group colours, in group order (matplotlib's tab10)."""
DISC_HEIGHT = 0.5
"""Height of the cylinder drawn for a circle, arena units."""
POINT_DIAMETER = 2.0
"""Diameter of the sphere drawn for a point entity, arena units."""
LINE_WIDTH = 0.5
"""Width of polygon lines, arena units."""
TEXT_HEIGHT = 5.0
"""Height of the trial/step caption, arena units."""
ARROW_WIDTH = 0.4
"""Shaft width of a heading arrow, arena units; its length is the body's diameter."""
HEADING_NS = "heading"
"""Marker namespace of the heading arrows (id: the body's index)."""


def body_poses(header: Any, positions: np.ndarray, angles: np.ndarray) -> PoseArray:
    """The bodies' poses as a ``geometry_msgs/PoseArray``.

    Args:
        header: Frame and stamp of the poses (the task state's).
        positions: (R, 2) body centres in the arena frame.
        angles: (R,) headings, radians counter-clockwise from the x axis: a
            rotation about z, as a unit quaternion.
    """
    poses = []
    for (x, y), angle in zip(positions.tolist(), angles.tolist(), strict=True):
        pose = Pose()
        pose.position.x, pose.position.y = x, y
        pose.orientation.z = math.sin(0.5 * angle)
        pose.orientation.w = math.cos(0.5 * angle)
        poses.append(pose)
    return PoseArray(header=header, poses=poses)


def _colour(group_index: int) -> ColorRGBA:
    r, g, b = PALETTE[group_index % len(PALETTE)]
    return ColorRGBA(r=r, g=g, b=b, a=1.0)


def markers_from_task_state(
    state: Any, poses: PoseArray | None = None, radii: Sequence[float] = ()
) -> MarkerArray:
    """The markers of one ``sdbc_msgs/TaskState`` message, in its frame and stamp.

    Args:
        state: The task state.
        poses: The bodies' poses; each gets a heading arrow as long as its
            diameter (``radii``, in the poses' order).
        radii: The bodies' radii.
    """
    header = state.header
    markers = [Marker(header=header, action=Marker.DELETEALL)]
    top = 0.0
    for g, group in enumerate(state.groups):
        colour = _colour(g)
        for e, entity in enumerate(group.entities):
            marker = Marker(header=header, ns=group.name, id=e, color=colour)
            marker.pose.orientation.w = 1.0
            if entity.geometry == Entity.GEOMETRY_POLYGON:
                marker.type = Marker.LINE_LIST
                marker.scale.x = LINE_WIDTH
                marker.points = [Point(x=p.x, y=p.y) for p in entity.segments]
                top = max([top, *(p.y for p in entity.segments)])
            else:
                if entity.geometry == Entity.GEOMETRY_CIRCLE:
                    marker.type = Marker.CYLINDER
                    d = 2.0 * entity.radius
                    marker.scale.x, marker.scale.y, marker.scale.z = d, d, DISC_HEIGHT
                else:
                    marker.type = Marker.SPHERE
                    d = POINT_DIAMETER
                    marker.scale.x = marker.scale.y = marker.scale.z = d
                marker.pose.position.x = entity.centre.x
                marker.pose.position.y = entity.centre.y
                top = max(top, entity.centre.y + d)
            markers.append(marker)
    for b, pose in enumerate(poses.poses if poses is not None else ()):
        arrow = Marker(
            header=header,
            ns=HEADING_NS,
            id=b,
            type=Marker.ARROW,
            # Above its disc, so that the disc does not hide it.
            pose=Pose(
                position=Point(x=pose.position.x, y=pose.position.y, z=DISC_HEIGHT),
                orientation=pose.orientation,
            ),
            color=ColorRGBA(r=0.1, g=0.1, b=0.1, a=1.0),
        )
        arrow.scale.x = 2.0 * radii[b]
        arrow.scale.y = arrow.scale.z = ARROW_WIDTH
        markers.append(arrow)
    caption = Marker(
        header=header,
        ns="caption",
        id=0,
        type=Marker.TEXT_VIEW_FACING,
        text=f"{state.task}  trial {state.trial_id}  step {state.step}",
        color=ColorRGBA(r=0.2, g=0.2, b=0.2, a=1.0),
    )
    caption.scale.z = TEXT_HEIGHT
    caption.pose.orientation.w = 1.0
    caption.pose.position.y = top + TEXT_HEIGHT
    markers.append(caption)
    return MarkerArray(markers=markers)
