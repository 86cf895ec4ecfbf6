"""The distance function f_D of the task state (eq. 1 of the paper), over a batch.

f_D(e_i, e_j) estimates the physical distance between two entities from their shapes
(:class:`sdbc_sim.task_state.Geometry`), edge to edge and floored at 0:

- circle-circle: ``|c_i - c_j| - r_i - r_j``;
- circle-point: ``|c_i - p_j| - r_i`` (a point is a circle of radius 0);
- circle-polygon: ``min_s dist(c_i, s) - r_i`` over the polygon's segments s;
- polygon-polygon: ``min_{s, s'} dist(s, s')``, 0 where two segments cross.

Overlapping shapes are touching, hence 0, as in the authors' code (docs/method.md
states the floor for circle-circle; it changes no other case for shapes that do not
overlap).

Layout: slot-major, batch last. A group's discs are ``(S, B|1)`` arrays of x, y and
radius; its polygons are ``(P, S, B|1)`` arrays of segment end points. Every
reduction (the least over a polygon's segments here, the means over entities and
pairs in :mod:`features`) then runs over leading axes, which numpy does as whole-row
operations, and no Python loop runs over trials or entities.

Scratch arrays come from a :class:`Workspace` and are reused from step to step: at
thousands of trials a temporary is hundreds of kilobytes, and allocating a fresh one
for every operation costs more in page faults than the arithmetic (measured: about
500 faults and 1 ms per step of 2000 gate escape trials without it).
"""

from __future__ import annotations

from collections.abc import Hashable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import DTypeLike
from sdbc_sim.task_state import Geometry, GroupState


class Workspace:
    """Scratch arrays kept between steps, one per (key, shape, dtype)."""

    def __init__(self) -> None:
        self._arrays: dict[tuple, np.ndarray] = {}

    def get(
        self, key: Hashable, shape: tuple[int, ...], dtype: DTypeLike = np.float64
    ) -> np.ndarray:
        """An uninitialised array for ``key``, the same one at every call with the
        same key, shape and dtype."""
        entry = (key, shape, dtype)
        array = self._arrays.get(entry)
        if array is None:
            array = self._arrays[entry] = np.empty(shape, dtype)
        return array

    def clear(self) -> None:
        """Forgets every array (those handed out stay valid for their holders)."""
        self._arrays.clear()


@dataclass(frozen=True)
class Discs:
    """Circles and points of one group at one step (a point has radius 0).

    Attributes:
        x: (S, B|1) centre x, or the same with the slot axis indexed (see
            :func:`pick` and :func:`expand`).
        y: Centre y, shaped as ``x``.
        r: Radius shaped as ``x``, or None for points.
    """

    x: np.ndarray
    y: np.ndarray
    r: np.ndarray | None


@dataclass(frozen=True)
class Segments:
    """Polygons of one group at one step, as chains of line segments a -> b.

    Attributes:
        ax: (P, S, B|1) x of every segment's first end point; the slot axes follow
            the segment axis P.
        ay: y of every segment's first end point, shaped as ``ax``.
        bx: x of every segment's second end point, shaped as ``ax``.
        by: y of every segment's second end point, shaped as ``ax``.
        abx: ``bx - ax``.
        aby: ``by - ay``.
        inverse: ``1 / |b - a|^2``, 0 for a degenerate segment.

    :meth:`between` computes the last three; views and picks of segments
    (:func:`expand`, :func:`pick`) carry them along instead.
    """

    ax: np.ndarray
    ay: np.ndarray
    bx: np.ndarray
    by: np.ndarray
    abx: np.ndarray
    aby: np.ndarray
    inverse: np.ndarray

    @classmethod
    def between(
        cls, ax: np.ndarray, ay: np.ndarray, bx: np.ndarray, by: np.ndarray
    ) -> Segments:
        """The segments from (ax, ay) to (bx, by)."""
        segments = cls(ax, ay, bx, by, *(np.empty_like(ax) for _ in range(3)))
        segments.derive()
        return segments

    def derive(self) -> None:
        """Recomputes ``abx``, ``aby`` and ``inverse`` in place from the ends
        (1 / |b - a|^2, 0 for a segment of no length)."""
        np.subtract(self.bx, self.ax, out=self.abx)
        np.subtract(self.by, self.ay, out=self.aby)
        length2 = self.abx * self.abx + self.aby * self.aby
        self.inverse.fill(0.0)
        np.divide(1.0, length2, out=self.inverse, where=length2 > 0)

    def arrays(self) -> tuple[np.ndarray, ...]:
        """All seven arrays, in field order."""
        return self.ax, self.ay, self.bx, self.by, self.abx, self.aby, self.inverse


Shapes = Discs | Segments
"""The shapes of one group's entity slots at one step."""


_SLOT_MAJOR = {"segments": (3, 4, 2, 1, 0), "centres": (2, 1, 0), "radii": (1, 0)}
"""How a group's batch-first shape arrays turn slot-major: (B, S, P, 2, 2)
segments to (2 ends, 2 coordinates, P, S, B), (B, S, 2) centres to (2, S, B),
(B, S) radii to (S, B)."""


def slot_major(
    group: GroupState, name: Literal["centres", "radii", "segments"]
) -> np.ndarray:
    """The group's shape array ``name`` ("segments", "centres" or "radii") as a
    slot-major view, the layout this module's shapes are copied into."""
    return group.shapes(name).transpose(_SLOT_MAJOR[name])


def group_shapes(
    group: GroupState, geometry: Geometry, workspace: Workspace, key: Hashable
) -> Shapes:
    """A group's shapes, copied into the slot-major layout of this module.

    Args:
        group: One group of a task state (batch-first arrays).
        geometry: The group's geometry, from its task description.
        workspace: Where the copies live.
        key: Names the group in ``workspace``.

    Returns:
        :class:`Discs` for circles and points, :class:`Segments` for polygons.
    """
    if geometry is Geometry.POLYGON:
        # (B, S, P, 2 ends, 2 coordinates) -> (2, 2, P, S, B).
        source = slot_major(group, "segments")
        seg = workspace.get((key, "segments"), source.shape)
        np.copyto(seg, source)
        return Segments.between(ax=seg[0, 0], ay=seg[0, 1], bx=seg[1, 0], by=seg[1, 1])
    source = slot_major(group, "centres")
    centres = workspace.get((key, "centres"), source.shape)
    np.copyto(centres, source)
    radius = None
    if geometry is Geometry.CIRCLE:
        radius = workspace.get((key, "radii"), source.shape[1:])
        np.copyto(radius, slot_major(group, "radii"))
    return Discs(x=centres[0], y=centres[1], r=radius)


def pick(
    shapes: Shapes, index: np.ndarray, workspace: Workspace, key: Hashable
) -> Shapes:
    """The shapes of the slots ``index`` (an int array), copied into ``workspace``."""

    def take(array: np.ndarray, axis: int, part: str) -> np.ndarray:
        shape = array.shape[:axis] + index.shape + array.shape[axis + 1 :]
        out = workspace.get((key, part), shape)
        return np.take(array, index, axis=axis, out=out)

    if isinstance(shapes, Discs):
        r = None if shapes.r is None else take(shapes.r, 0, "r")
        return Discs(x=take(shapes.x, 0, "x"), y=take(shapes.y, 0, "y"), r=r)
    return Segments(
        *(take(v, 1, f"segments {k}") for k, v in enumerate(shapes.arrays()))
    )


def expand(shapes: Shapes, axis: int) -> Shapes:
    """The shapes with a broadcast axis inserted at slot axis ``axis`` (0 or 1; a
    view)."""
    # Segments have their segment axis before the slot axes.
    lead: tuple[slice, ...] = () if isinstance(shapes, Discs) else (slice(None),)
    index = (*lead, None) if axis == 0 else (*lead, slice(None), None)
    if isinstance(shapes, Discs):
        r = None if shapes.r is None else shapes.r[index]
        return Discs(x=shapes.x[index], y=shapes.y[index], r=r)
    return Segments(*(v[index] for v in shapes.arrays()))


def point_segment_distance2(
    px: np.ndarray,
    py: np.ndarray,
    segments: Segments,
    workspace: Workspace | None = None,
    key: Hashable = "point-segment",
) -> np.ndarray:
    """Squared Euclidean distance from points p to segments a-b, broadcasting.

    The nearest point of a segment is ``a + t (b - a)`` with
    ``t = clip(((p - a) . (b - a)) / |b - a|^2, 0, 1)``; a degenerate segment
    (a = b) is its end point a (t = 0).

    Args:
        px: Point x, broadcasting against the segments' arrays.
        py: Point y.
        segments: The segments.
        workspace: Scratch arrays (a fresh one if None); the result lives there.
        key: Names this use in ``workspace``.
    """
    ws = workspace if workspace is not None else Workspace()
    ax, ay, abx, aby = segments.ax, segments.ay, segments.abx, segments.aby
    inverse = segments.inverse
    shape = np.broadcast_shapes(px.shape, ax.shape)
    dx = np.subtract(px, ax, out=ws.get((key, "dx"), shape))
    dy = np.subtract(py, ay, out=ws.get((key, "dy"), shape))
    t = np.multiply(dx, abx, out=ws.get((key, "t"), shape))
    tmp = np.multiply(dy, aby, out=ws.get((key, "tmp"), shape))
    t += tmp
    t *= inverse
    np.clip(t, 0.0, 1.0, out=t)
    dx -= np.multiply(t, abx, out=tmp)
    dy -= np.multiply(t, aby, out=tmp)
    dx *= dx
    dy *= dy
    dx += dy
    return dx


def _orientation(
    ax: np.ndarray,
    ay: np.ndarray,
    bx: np.ndarray,
    by: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
) -> np.ndarray:
    """Sign of the turn a -> b -> c (cross product of b - a and c - a)."""
    return np.sign((bx - ax) * (cy - ay) - (by - ay) * (cx - ax))


def segment_segment_distance2(a: Segments, b: Segments) -> np.ndarray:
    """Squared distance between segments a and b, broadcasting.

    Segments that cross properly are at distance 0; otherwise the nearest pair of
    points involves an end point, so the distance is the least of the four end
    point-to-segment distances (collinear and touching cases give 0 through them).
    Only moving polygons need this; it allocates its temporaries.
    """
    crossing = (
        _orientation(a.ax, a.ay, a.bx, a.by, b.ax, b.ay)
        * _orientation(a.ax, a.ay, a.bx, a.by, b.bx, b.by)
        < 0
    ) & (
        _orientation(b.ax, b.ay, b.bx, b.by, a.ax, a.ay)
        * _orientation(b.ax, b.ay, b.bx, b.by, a.bx, a.by)
        < 0
    )
    ends = np.minimum(
        np.minimum(
            point_segment_distance2(a.ax, a.ay, b),
            point_segment_distance2(a.bx, a.by, b),
        ),
        np.minimum(
            point_segment_distance2(b.ax, b.ay, a),
            point_segment_distance2(b.bx, b.by, a),
        ),
    )
    return np.where(crossing, 0.0, ends)


def entity_distance(
    a: Shapes, b: Shapes, workspace: Workspace | None = None, key: Hashable = "f_D"
) -> np.ndarray:
    """f_D between the entities of ``a`` and ``b``, floored at 0.

    Args:
        a: Shapes whose slot axes broadcast against ``b``'s (see :func:`expand`).
        b: The other shapes.
        workspace: Scratch arrays (a fresh one if None); the result lives there and
            is overwritten by the next call with the same key.
        key: Names this use in ``workspace``.

    Returns:
        The distances, shaped as the broadcast of the slot and batch axes.
    """
    ws = workspace if workspace is not None else Workspace()
    if isinstance(a, Discs) and isinstance(b, Discs):
        shape = np.broadcast_shapes(a.x.shape, b.x.shape)
        d = np.subtract(a.x, b.x, out=ws.get((key, "d"), shape))
        dy = np.subtract(a.y, b.y, out=ws.get((key, "dy"), shape))
        d *= d
        dy *= dy
        d += dy
        np.sqrt(d, out=d)
        if a.r is not None:
            d -= a.r
        if b.r is not None:
            d -= b.r
    elif isinstance(a, Segments) and isinstance(b, Segments):
        # a's segments on axis 0, b's on a new axis 1: the least over both.
        sa = Segments(*(v[:, None] for v in a.arrays()))
        sb = Segments(*(v[None] for v in b.arrays()))
        d = np.sqrt(segment_segment_distance2(sa, sb).min(axis=(0, 1)))
    else:
        discs, poly = disc_and_polygon(a, b)
        # The polygon's segment axis leads: the least over it is a row-wise minimum.
        d2 = point_segment_distance2(discs.x[None], discs.y[None], poly, ws, key)
        d = np.minimum.reduce(d2, axis=0, out=ws.get((key, "d"), d2.shape[1:]))
        np.sqrt(d, out=d)
        if discs.r is not None:
            d -= discs.r
    return np.maximum(d, 0.0, out=d)


def disc_and_polygon(a: Shapes, b: Shapes) -> tuple[Discs, Segments]:
    """``a`` and ``b``, one of discs and one of segments, in that order."""
    if isinstance(a, Discs) and isinstance(b, Segments):
        return a, b
    if isinstance(b, Discs) and isinstance(a, Segments):
        return b, a
    raise TypeError(f"expected discs and segments, got {type(a)} and {type(b)}")
