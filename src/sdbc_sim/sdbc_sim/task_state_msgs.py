"""The task state as ``sdbc_msgs/TaskState`` messages, both ways.

A message is one trial after one step, listing each entity group with its
description fields and its present entities. This module converts both ways between
a message and :class:`sdbc_sim.task_state.TaskState` arrays (a batch of one) and
builds the task description from a message. The simulator node publishes with it;
``sdbc_evolution.sdbc.messages`` characterises a stream of messages with it, so that
any ROS 2 system that publishes the task state gets SDBCs.

A message lists only the entities present, in slot order; converting back gives
each group as many slots as it has entities (one, absent, if it has none), so that
the arrays follow the entities present and a declared ``max_size`` costs nothing.
The features do not depend on entity order (they are means over entities and
pairs), so the vectors agree to round-off.

What a message may hold is bounded (:data:`LIMITS`, one place): a message over a
limit is refused before anything is allocated for it, naming the limit and the
value, so that no message, however large its declared sizes, costs more than the
limits allow. Polygons of one group may
have different numbers of segments in a message; the arrays pad shorter ones by
repeating their last segment, which leaves every nearest-segment distance unchanged.

``sdbc_msgs`` is imported when first needed, so importing this module needs no ROS 2
workspace.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from sdbc_sim.task_state import (
    EntityGroupSpec,
    Geometry,
    GroupState,
    TaskDescription,
    TaskState,
    validate_task_state,
)

FRAME_ID = "arena"
"""``header.frame_id`` of every message: the trial's arena frame."""

# Entity.GEOMETRY_* in sdbc_msgs/msg/Entity.msg.
GEOMETRY_CODES: dict[Geometry, int] = {
    Geometry.CIRCLE: 0,
    Geometry.POINT: 1,
    Geometry.POLYGON: 2,
}
GEOMETRY_OF_CODE: dict[int, Geometry] = {code: g for g, code in GEOMETRY_CODES.items()}


@dataclass(frozen=True)
class TaskStateLimits:
    """The most a ``sdbc_msgs/TaskState`` stream may hold, and what a characteriser
    keeps of it; every refusal names the limit (``limits.entities``) and the value.

    Attributes:
        groups: Entity groups in one message.
        entities: Entities present in one message, all groups together: the
            SDBC's pair lists grow as their square (dispersion and distances).
        attributes: State attributes of one group.
        segment_points: Segment end points of one polygon.
        name_length: Characters of a task, group or attribute name.
        open_trials: Trials a characteriser follows at once, per task.
        tasks: Task names a characteriser keeps a description of; the one unused
            longest is forgotten for a new one.
        dropped: Dropped trials a characteriser remembers (to ignore their later
            messages); the oldest is forgotten first.
    """

    groups: int = 64
    entities: int = 1024
    attributes: int = 256
    segment_points: int = 1024
    name_length: int = 256
    open_trials: int = 256
    tasks: int = 16
    dropped: int = 4096


LIMITS = TaskStateLimits()
"""The limits in force."""


def check_limits(msg: Any, limits: TaskStateLimits = LIMITS) -> None:
    """Refuses a message over a limit of ``limits``, before reading its values.

    Raises:
        ValueError: Naming the limit, its value and what the message holds.
    """
    task = str(msg.task)
    where = f"task {task[:40]!r}, trial {msg.trial_id}, step {msg.step}"

    def refuse(limit: str, got: int, what: str) -> None:
        raise ValueError(
            f"{where}: {what} {got}, more than limits.{limit} = "
            f"{getattr(limits, limit)}"
        )

    if len(task) > limits.name_length:
        refuse("name_length", len(task), "task name of length")
    if len(msg.groups) > limits.groups:
        refuse("groups", len(msg.groups), "groups")
    entities = 0
    for group in msg.groups:
        label = f"group {str(group.name)[:40]!r}"
        if len(group.name) > limits.name_length:
            refuse("name_length", len(group.name), f"{label}: name of length")
        if len(group.attribute_names) > limits.attributes:
            refuse("attributes", len(group.attribute_names), f"{label}: attributes")
        for name in group.attribute_names:
            if len(name) > limits.name_length:
                refuse("name_length", len(name), f"{label}: attribute name of length")
        entities += len(group.entities)
        if entities > limits.entities:
            refuse("entities", entities, f"{label}: entities in the message")
        for entity in group.entities:
            if len(entity.segments) > limits.segment_points:
                refuse(
                    "segment_points", len(entity.segments), f"{label}: segment points"
                )


def _trial_row(array: np.ndarray, index: int) -> np.ndarray:
    """Row ``index`` of a batch-first array whose leading dimension may be 1."""
    return array[0] if array.shape[0] == 1 else array[index]


def task_state_to_msg(
    state: TaskState,
    description: TaskDescription,
    index: int,
    trial_id: int,
    task: str,
    done: bool,
) -> Any:
    """Trial ``index`` of a batch task state as an ``sdbc_msgs/TaskState`` message.

    Args:
        state: A task state (the engine's, or a :class:`TrialStepper`'s batch of one).
        description: Its task description.
        index: The trial within the batch.
        trial_id: Identifies the trial in the stream.
        task: The task's name.
        done: True on the trial's last step.

    Returns:
        The message; its ``header.stamp`` is left for the publisher to set.

    Raises:
        ValueError: If the state does not fit the description or ``index`` is out
            of the batch.
    """
    from geometry_msgs.msg import Point

    from sdbc_msgs.msg import Entity, EntityGroup
    from sdbc_msgs.msg import TaskState as TaskStateMsg

    n_trials = np.shape(state.active)[0]
    if not 0 <= index < n_trials:
        raise ValueError(
            f"task_state_to_msg: trial index {index} outside 0..{n_trials - 1}"
        )
    validate_task_state(description, state, n_trials)
    msg = TaskStateMsg()
    msg.header.frame_id = FRAME_ID
    msg.task = task
    msg.trial_id = int(trial_id)
    msg.step = int(state.step)
    msg.done = bool(done)
    for spec, group in zip(description.groups, state.groups, strict=True):
        code = GEOMETRY_CODES[spec.geometry]
        present = _trial_row(group.present, index)
        attributes = _trial_row(group.attributes, index)
        entities = []
        for s in np.flatnonzero(present):
            entity = Entity(state=attributes[s].tolist(), geometry=code)
            if spec.geometry is Geometry.POLYGON:
                ends = _trial_row(group.shapes("segments"), index)[s].reshape(-1, 2)
                entity.segments = [Point(x=float(x), y=float(y)) for x, y in ends]
            else:
                x, y = _trial_row(group.shapes("centres"), index)[s]
                entity.centre = Point(x=float(x), y=float(y))
                if spec.geometry is Geometry.CIRCLE:
                    entity.radius = float(_trial_row(group.shapes("radii"), index)[s])
            entities.append(entity)
        msg.groups.append(
            EntityGroup(
                name=spec.name,
                attribute_names=list(spec.attributes),
                entities=entities,
                min_size=spec.min_size,
                max_size=spec.max_size,
                is_static=spec.static,
            )
        )
    return msg


def task_description_from_msg(
    msg: Any, geometries: Mapping[str, Geometry] | None = None
) -> TaskDescription:
    """The task description that a message's group fields describe.

    Args:
        msg: An ``sdbc_msgs/TaskState``.
        geometries: Geometry of groups by name, needed only for groups that are
            empty in ``msg`` (their geometry is read from their entities otherwise).

    Raises:
        ValueError: If a group is empty and ``geometries`` does not name its
            geometry, if a group's entities disagree on it, or if the fields are not
            a valid description (min_size > max_size, duplicate names, ...).
    """
    check_limits(msg)
    geometries = geometries or {}
    specs = []
    for group in msg.groups:
        codes = {int(e.geometry) for e in group.entities}
        if len(codes) > 1:
            raise ValueError(
                f"task {msg.task!r}, group {group.name!r}: entities of several "
                f"geometries {sorted(codes)}"
            )
        if codes:
            code = codes.pop()
            if code not in GEOMETRY_OF_CODE:
                raise ValueError(
                    f"task {msg.task!r}, group {group.name!r}: unknown geometry {code}"
                )
            geometry = GEOMETRY_OF_CODE[code]
        elif group.name in geometries:
            geometry = Geometry(geometries[group.name])
        else:
            raise ValueError(
                f"task {msg.task!r}, group {group.name!r} is empty in this message: "
                "its geometry cannot be read; pass it in geometries or a description"
            )
        specs.append(
            EntityGroupSpec(
                name=group.name,
                attributes=tuple(group.attribute_names),
                min_size=int(group.min_size),
                max_size=int(group.max_size),
                static=bool(group.is_static),
                geometry=geometry,
            )
        )
    return TaskDescription(name=msg.task, groups=tuple(specs))


def _check_group_fields(where: str, spec: EntityGroupSpec, group: Any) -> None:
    fields = {
        "name": (group.name, spec.name),
        "attribute_names": (tuple(group.attribute_names), spec.attributes),
        "min_size": (int(group.min_size), spec.min_size),
        "max_size": (int(group.max_size), spec.max_size),
        "is_static": (bool(group.is_static), spec.static),
    }
    for field, (got, expected) in fields.items():
        if got != expected:
            raise ValueError(
                f"{where}, group {spec.name!r}: {field} is {got!r}, the description "
                f"says {expected!r}"
            )


def task_state_from_msg(msg: Any, description: TaskDescription) -> TaskState:
    """An ``sdbc_msgs/TaskState`` as task state arrays: a batch of one trial, which
    took the step ``msg.step``.

    Raises:
        ValueError: Naming the group, entity and field of a message that does not
            fit the description (group fields, the number of entities, the length
            of an entity's state vector, its geometry, its segments, non-finite
            values).
    """
    check_limits(msg)
    where = f"task {msg.task!r}, trial {msg.trial_id}, step {msg.step}"
    if len(msg.groups) != len(description.groups):
        raise ValueError(
            f"{where}: {len(msg.groups)} groups in the message, "
            f"{len(description.groups)} in the description"
        )
    groups = []
    for spec, group in zip(description.groups, msg.groups, strict=True):
        _check_group_fields(where, spec, group)
        groups.append(_group_from_msg(where, spec, group))
    return TaskState(
        step=int(msg.step), active=np.ones(1, dtype=bool), groups=tuple(groups)
    )


def _group_from_msg(where: str, spec: EntityGroupSpec, group: Any) -> GroupState:
    entities = list(group.entities)
    n, n_attributes = len(entities), len(spec.attributes)
    if not spec.min_size <= n <= spec.max_size:
        raise ValueError(
            f"{where}, group {spec.name!r}: {n} entities, outside its limits "
            f"[{spec.min_size}, {spec.max_size}]"
        )
    # As many slots as entities: memory follows them, not max_size.
    size = max(n, 1)
    code = GEOMETRY_CODES[spec.geometry]
    present = np.zeros((1, size), dtype=bool)
    present[0, :n] = True
    attributes = np.zeros((1, size, n_attributes))
    centres = np.zeros((1, size, 2))
    radii = np.zeros((1, size))
    for s, entity in enumerate(entities):
        label = f"{where}, group {spec.name!r}, entity {s}"
        values = np.asarray(entity.state, dtype=np.float64)
        if values.shape != (n_attributes,):
            raise ValueError(
                f"{label}: state has {values.shape[0]} values, expected {n_attributes} "
                f"({', '.join(spec.attributes) or 'none'})"
            )
        if int(entity.geometry) != code:
            raise ValueError(
                f"{label}: geometry {int(entity.geometry)}, the description says "
                f"{code} ({spec.geometry.value})"
            )
        attributes[0, s] = values
        centres[0, s] = entity.centre.x, entity.centre.y
        radii[0, s] = entity.radius
        if not (np.isfinite(values).all() and np.isfinite(centres[0, s]).all()):
            raise ValueError(f"{label}: state or centre is not finite")
    if spec.geometry is Geometry.POLYGON:
        return GroupState(
            present, attributes, segments=_segments(where, spec, entities)
        )
    if spec.geometry is Geometry.POINT:
        return GroupState(present, attributes, centres=centres)
    if not np.isfinite(radii).all() or (radii < 0).any():
        raise ValueError(
            f"{where}, group {spec.name!r}: a radius is negative or not finite"
        )
    return GroupState(present, attributes, centres=centres, radii=radii)


def _segments(where: str, spec: EntityGroupSpec, entities: list[Any]) -> np.ndarray:
    polygons = []
    for s, entity in enumerate(entities):
        ends = np.array([(p.x, p.y) for p in entity.segments], dtype=np.float64)
        if ends.shape[0] < 2 or ends.shape[0] % 2:
            raise ValueError(
                f"{where}, group {spec.name!r}, entity {s}: {ends.shape[0]} segment "
                "end points; a polygon needs a positive, even number (2 per segment)"
            )
        if not np.isfinite(ends).all():
            raise ValueError(
                f"{where}, group {spec.name!r}, entity {s}: segments not finite"
            )
        polygons.append(ends.reshape(-1, 2, 2))
    n_segments = max((p.shape[0] for p in polygons), default=1)
    segments = np.zeros((1, max(len(entities), 1), n_segments, 2, 2))
    for s, polygon in enumerate(polygons):
        segments[0, s, : polygon.shape[0]] = polygon
        # Repeating the last segment leaves the nearest-segment distance unchanged.
        segments[0, s, polygon.shape[0] :] = polygon[-1]
    return segments
