"""Geometry shared by the tasks' sensors, batch-first over trials and robots.

Everything here is element-wise numpy over whole batches, in trial-local
coordinates. Angles are in radians, counter-clockwise; a robot's *bearing* to a
point is the angle of the point in the robot's frame, in [-pi, pi].

Sums and minima over the few robots of a trial run as a fixed sequence of
element-wise operations (:func:`robot_sum`, :func:`robot_min`): numpy's own
reductions pick their summation order from the memory layout, which could make a
trial's numbers depend on the size of its batch, and are slow over short axes.

Sensor readings follow the authors' convention (MASE): a distance d sensed with
range r reads ``2 d / r - 1`` in [-1, 1], and 1 when nothing is in range.
"""

from __future__ import annotations

import functools

import numpy as np

from sdbc_sim.compiled import compiled

TWO_PI = 2.0 * np.pi


def axis_views(a: np.ndarray, axis: int) -> list[np.ndarray]:
    """The views a[..., k, ...] along ``axis``, in index order. Plain indexing
    rather than ``np.moveaxis``, whose argument checks cost more than the sums
    themselves on the engine's short axes (tens of thousands of calls a batch)."""
    if a.shape[axis] == 0:
        raise IndexError(f"nothing to reduce: axis {axis} of shape {a.shape} is empty")
    lead: tuple[slice | int, ...] = (slice(None),) * (axis % a.ndim)
    return [a[(*lead, k)] for k in range(a.shape[axis])]


def robot_sum(a: np.ndarray, axis: int = 1) -> np.ndarray:
    """Sum over a short axis, always in index order: ((a_0 + a_1) + a_2) + ..."""
    first, *rest = axis_views(a, axis)
    total = first.copy()
    for part in rest:
        total += part
    return total


def robot_min(a: np.ndarray, axis: int = -1) -> np.ndarray:
    """Minimum over a short axis, as a chain of element-wise minima."""
    first, *rest = axis_views(a, axis)
    low = first.copy()
    for part in rest:
        np.minimum(low, part, out=low)
    return low


def distance_sum(pos: np.ndarray, trial: int, n: int, x: float, y: float) -> float:
    """The sum, in index order, of the distances of robots 0..n-1 of ``trial`` (in
    (B, R, 2) ``pos``) to the point (x, y): a compiled loop's helper doing what
    ``norm`` and ``robot_sum`` do over arrays, in their order."""
    total = 0.0
    for r in range(n):
        dx = pos[trial, r, 0] - x
        dy = pos[trial, r, 1] - y
        d = np.sqrt(dx * dx + dy * dy)
        total = d if r == 0 else total + d
    return total


def centroid_spread(pos: np.ndarray, trial: int, n: int) -> float:
    """:func:`distance_sum` to the robots' centroid, the centroid as ``robot_sum``
    of the coordinates / n."""
    cx = pos[trial, 0, 0]
    cy = pos[trial, 0, 1]
    for r in range(1, n):
        cx += pos[trial, r, 0]
        cy += pos[trial, r, 1]
    return distance_sum(pos, trial, n, cx / n, cy / n)


def norm(dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    """sqrt(dx^2 + dy^2) (np.hypot guards against overflow we never meet, slowly)."""
    d = dx * dx
    d += dy * dy
    return np.sqrt(d, out=d)


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return np.mod(a + np.pi, TWO_PI) - np.pi


def bearing(
    dx: np.ndarray, dy: np.ndarray, cos_h: np.ndarray, sin_h: np.ndarray
) -> np.ndarray:
    """Bearing in [-pi, pi] of the vector (dx, dy) seen from a robot whose heading
    has cosine ``cos_h`` and sine ``sin_h``: the angle of the vector rotated into
    the robot's frame, atan2(-dx sin h + dy cos h, dx cos h + dy sin h)."""
    return np.arctan2(dy * cos_h - dx * sin_h, dx * cos_h + dy * sin_h)


def bearing_arguments(
    dx: float, dy: float, cos_h: float, sin_h: float
) -> tuple[float, float]:
    """The two arguments of :func:`bearing`'s atan2 for one robot, by its
    operations: the offset (dx, dy) rotated into the frame of a robot whose heading
    has cosine ``cos_h`` and sine ``sin_h``. Compiled loops call it and leave the
    atan2 to numpy (:mod:`sdbc_sim.compiled`)."""
    return dy * cos_h - dx * sin_h, dx * cos_h + dy * sin_h


def normalised_reading(d: np.ndarray, sensor_range: float) -> np.ndarray:
    """A distance as a reading in [-1, 1]: 2 d / range - 1, and 1 beyond range."""
    r = d * (2.0 / sensor_range) - 1.0
    return np.minimum(r, 1.0, out=r)


def pairwise_offsets(pos: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Offsets and centre distances between the robots of each trial.

    Args:
        pos: (B, N, 2) centres.

    Returns:
        dx, dy, dist: (B, N, N) each, entry [b, i, j] from robot i to robot j.
    """
    x = np.ascontiguousarray(pos[..., 0])
    y = np.ascontiguousarray(pos[..., 1])
    dx = x[:, None, :] - x[:, :, None]
    dy = y[:, None, :] - y[:, :, None]
    return dx, dy, norm(dx, dy)


def arc_index(bearings: np.ndarray, n_arcs: int) -> np.ndarray:
    """Which of ``n_arcs`` equal sectors holds each bearing in [-pi, pi].

    Sector j is centred on bearing -pi + j 2 pi / n_arcs, so with 4 arcs sector 0
    looks back, 1 right, 2 ahead and 3 left, as in the authors' code.
    """
    width = TWO_PI / n_arcs
    idx = ((bearings + (np.pi + 0.5 * width)) * (1.0 / width)).astype(np.intp)
    idx[idx >= n_arcs] -= n_arcs
    return idx


def arc_minimum(
    readings: np.ndarray, arcs: np.ndarray, n_arcs: int, empty: float = 1.0
) -> np.ndarray:
    """Per-sector minimum of neighbour readings, dense form (every neighbour).

    Args:
        readings: (B, N, M) reading of each of M neighbours; ``empty`` (or more)
            where the neighbour is not sensed.
        arcs: (B, N, M) sector of each neighbour, from :func:`arc_index`.
        n_arcs: Number of sectors.
        empty: Value of a sector that senses nothing.

    Returns:
        (B, N, n_arcs) minimum reading per sector.
    """
    out = np.empty((*readings.shape[:-1], n_arcs))
    for j in range(n_arcs):
        out[..., j] = robot_min(np.where(arcs == j, readings, empty))
    return np.minimum(out, empty, out=out)


def sector_minimum(
    rows: np.ndarray,
    bearings: np.ndarray,
    readings: np.ndarray,
    n_rows: int,
    n_arcs: int,
    empty: float = 1.0,
    out: np.ndarray | None = None,
    column: int = 0,
) -> np.ndarray:
    """Per-sector minimum of the readings of sensed objects, sparse form (only the
    sensed ones, cheaper when few are).

    Args:
        rows: (K,) which robot (flat row) senses each object.
        bearings: (K,) bearing of each object from its robot.
        readings: (K,) reading of each object.
        n_rows: Number of robots.
        n_arcs: Number of sectors (see :func:`arc_index`).
        empty: Value of a sector that senses nothing.
        out: A C-ordered float64 (n_rows, W) array, such as a task's sensor
            array with its robots' rows merged, written in its columns
            ``column`` to ``column + n_arcs - 1``; None for a new (n_rows,
            n_arcs) one.
        column: The first column of ``out`` to write.

    Returns:
        The minimum reading per robot and sector: the new (n_rows, n_arcs) array,
        or ``out``.

    Raises:
        ValueError: If ``out`` is not such an array, or ``column`` is given
            without it.
    """
    out = readings_out(out, (n_rows,), n_arcs, column, "sector_minimum")
    width = TWO_PI / n_arcs
    _sector_minimum(
        np.ascontiguousarray(rows, dtype=np.intp),
        np.ascontiguousarray(bearings, dtype=np.float64),
        np.ascontiguousarray(readings, dtype=np.float64),
        np.pi + 0.5 * width,
        1.0 / width,
        empty,
        out,
        column,
        n_arcs,
    )
    return out


def readings_out(
    out: np.ndarray | None,
    rows: tuple[int, ...],
    width: int,
    column: int,
    name: str,
) -> np.ndarray:
    """The array a loop writes ``width`` readings per robot into from
    ``column`` on: a new (*rows, width) one when ``out`` is None (``column``
    must then be 0), else ``out``, checked to be a C-ordered float64 array of
    shape (*rows, K) with ``column + width <= K``. A task hands its whole
    sensor array and the first column rather than a view of its columns, whose
    rows numba would compile with unknown strides.

    Raises:
        ValueError: Naming ``name``, the shape needed and the one given.
    """
    if out is None:
        if column != 0:
            raise ValueError(f"{name}: column {column} needs an out to write into")
        return np.empty((*rows, width))
    if (
        out.dtype != np.float64
        or not out.flags.c_contiguous
        or out.ndim != len(rows) + 1
        or out.shape[:-1] != rows
        or not 0 <= column <= out.shape[-1] - width
    ):
        shape = ", ".join(map(str, rows))
        raise ValueError(
            f"{name}: out must be C-ordered float64 ({shape}, K) with {width} "
            f"columns from column {column}, got {out.dtype} {out.shape}"
        )
    return out


@compiled(
    "void(intp[::1], float64[::1], float64[::1], float64, float64, float64, "
    "float64[:, ::1], intp, intp)"
)
def _sector_minimum(
    rows: np.ndarray,
    bearings: np.ndarray,
    readings: np.ndarray,
    shift: float,
    per_width: float,
    empty: float,
    out: np.ndarray,
    column: int,
    n_arcs: int,
) -> None:  # pragma: no cover - compiled; tested through sector_minimum
    """Columns ``column`` to ``column + n_arcs - 1`` of ``out`` filled with
    ``empty``, then ``min(., reading)`` per sensed object in the column of its
    arc, as :func:`arc_index` computes it (``shift`` = pi + width / 2,
    ``per_width`` = 1 / width); a minimum does not depend on the order it is
    taken in. The fill is here because those are a few columns of a task's
    sensor array, which numpy's ``fill`` walks at several times this loop's
    cost."""
    for row in range(out.shape[0]):
        for arc in range(n_arcs):
            out[row, column + arc] = empty
    for k in range(rows.shape[0]):
        arc = int((bearings[k] + shift) * per_width)
        if arc >= n_arcs:
            arc -= n_arcs
        if readings[k] < out[rows[k], column + arc]:
            out[rows[k], column + arc] = readings[k]


def ray_segment_distance(
    origins: np.ndarray, directions: np.ndarray, length: float, segments: np.ndarray
) -> np.ndarray:
    """Distance along rays to the nearest segment they cross.

    Solves o + t u = a + s (b - a) for every ray and segment:
    t = ((a - o) x e) / (u x e), s = ((a - o) x u) / (u x e), with e = b - a and
    p x q = p_x q_y - p_y q_x; a hit needs 0 <= t <= length and 0 <= s <= 1.
    Parallel rays and segments never hit. A ray only looks at the segments whose
    bounding box, grown by ``length``, holds its start.

    A compiled loop (:mod:`sdbc_sim.compiled`): the wall rays of every robot near a
    wall, at every step, made a dozen whole-array operations per segment; the
    loop does the same IEEE operations in the same order (the results are the
    array formulation's to the bit, ``tests/sdbc_sim/test_sensors.py``).

    Args:
        origins: (M, 2) ray starts.
        directions: (M, 2) unit ray directions.
        length: Ray length.
        segments: (P, 2, 2) segments as their two end points.

    Returns:
        (M,) distance t of the nearest hit, inf where the ray hits nothing.
    """
    return _ray_segment_distance(
        np.ascontiguousarray(origins, dtype=np.float64),
        np.ascontiguousarray(directions, dtype=np.float64),
        float(length),
        np.ascontiguousarray(segments, dtype=np.float64).reshape(-1, 2, 2),
    )


def ray_distance(
    ox: float, oy: float, ux: float, uy: float, length: float, segments: np.ndarray
) -> float:  # pragma: no cover - compiled into the loops that call it
    """:func:`ray_segment_distance` for one ray from (ox, oy) along (ux, uy): the
    distance of its nearest hit, inf if none (a minimum: the segments' order does
    not matter). Compiled into the loops that call it."""
    nearest = np.inf
    for q in range(segments.shape[0]):
        ax = segments[q, 0, 0]
        ay = segments[q, 0, 1]
        bx = segments[q, 1, 0]
        by = segments[q, 1, 1]
        x_low = min(ax, bx) - length
        x_high = max(ax, bx) + length
        y_low = min(ay, by) - length
        y_high = max(ay, by) + length
        if not (ox >= x_low and ox <= x_high and oy >= y_low and oy <= y_high):
            continue
        ex = bx - ax
        ey = by - ay
        wx = ax - ox
        wy = ay - oy
        denom = ux * ey - uy * ex
        t = (wx * ey - wy * ex) / denom
        if not (t >= 0.0 and t <= length and t < nearest):
            continue
        # The second division only for a hit nearer than any so far: the
        # conditions are those of the array form, in another order.
        s = (wx * uy - wy * ux) / denom
        if s >= 0.0 and s <= 1.0:
            nearest = t
    return nearest


@compiled(
    "float64[::1](float64[:, ::1], float64[:, ::1], float64, float64[:, :, ::1])",
    calls=(ray_distance,),
)
def _ray_segment_distance(
    origins: np.ndarray, directions: np.ndarray, length: float, segments: np.ndarray
) -> np.ndarray:  # pragma: no cover - compiled; tested through ray_segment_distance
    nearest = np.empty(origins.shape[0])
    for m in range(origins.shape[0]):
        nearest[m] = ray_distance(
            origins[m, 0],
            origins[m, 1],
            directions[m, 0],
            directions[m, 1],
            length,
            segments,
        )
    return nearest


def segment_offsets(points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Vectors from the nearest point of each segment to each point.

    The nearest point of segment a-b to p is a + s (b - a) with
    s = clip((p - a).(b - a) / |b - a|^2, 0, 1).

    Args:
        points: (..., 2).
        segments: (P, 2, 2).

    Returns:
        (..., P, 2) p minus the nearest point of each segment.
    """
    a = segments[:, 0, :]
    e = segments[:, 1, :] - a
    ee = e[:, 0] * e[:, 0] + e[:, 1] * e[:, 1]
    w = points[..., None, :] - a
    dot = w[..., 0] * e[:, 0] + w[..., 1] * e[:, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(ee > 0.0, dot / ee, 0.0)
    s = np.clip(s, 0.0, 1.0)
    return w - s[..., None] * e


def segment_offset(
    x: float, y: float, segments: np.ndarray, q: int
) -> tuple[float, float]:  # pragma: no cover - compiled into the loops that call it
    """:func:`segment_offsets` for the point (x, y) and segment ``q`` of
    ``segments`` (P, 2, 2), with the same operations in the same order (np.clip:
    the max with 0 first, then the min with 1). Compiled into the loops that call
    it."""
    ax = segments[q, 0, 0]
    ay = segments[q, 0, 1]
    ex = segments[q, 1, 0] - ax
    ey = segments[q, 1, 1] - ay
    ee = ex * ex + ey * ey
    wx = x - ax
    wy = y - ay
    s = (wx * ex + wy * ey) / ee if ee > 0.0 else 0.0
    s = s if s > 0.0 else 0.0
    s = s if s < 1.0 else 1.0
    return wx - s * ex, wy - s * ey


def point_segment_distance(points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Euclidean distance from points (..., 2) to segments (P, 2, 2): (..., P)."""
    d = segment_offsets(points, segments)
    return norm(d[..., 0], d[..., 1])


def neighbour_sectors(
    pos: np.ndarray,
    cos_h: np.ndarray,
    sin_h: np.ndarray,
    robot_radius: float,
    sensor_range: float,
    n_sectors: int,
    visible: np.ndarray | None = None,
    *,
    enabled: np.ndarray | None = None,
    out: np.ndarray | None = None,
    column: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """The nearest sensed robot's reading per sector, for every robot.

    Robot i senses robot j when ``visible[b, i, j]`` and ``enabled[b, j]`` and
    their edge-to-edge distance d is at most ``sensor_range``; the reading is
    2 d / range - 1 (at least -1).

    Args:
        pos: (B, N, 2) centres.
        cos_h, sin_h: (B, N) headings.
        robot_radius: Radius of every robot.
        sensor_range: Range, edge to edge.
        n_sectors: Sectors (see :func:`arc_index`).
        visible: (B, N, N) or (N, N) bool, which robots each robot may sense;
            None for every robot but itself.
        enabled: (B, N) bool, the robots that can be sensed at all (those not
            switched off); None for all. Kept apart from ``visible`` so that a
            task with a fixed ``visible`` need not combine the two at every step.
        out: A task's C-ordered float64 (B, N, K) sensor array, written in its
            columns ``column`` to ``column + n_sectors - 1``; None for a new
            (B, N, n_sectors) one.
        column: The first column of ``out`` to write.

    Returns:
        The readings, 1 where a sector senses nobody (the new (B, N,
        n_sectors) array, or ``out``), and the (B, N) number of robots each
        robot senses (as float64).

    Raises:
        ValueError: If ``out`` is not such an array, or ``column`` is given
            without it.
    """
    b, n = cos_h.shape
    out = readings_out(out, (b, n), n_sectors, column, "neighbour_sectors")
    counts = np.empty((b, n))
    most = b * n * n
    rows = np.empty(most, dtype=np.intp)
    left = np.empty(most)
    ahead = np.empty(most)
    readings = np.empty(most)
    if visible is None:
        visible = _not_self(n)
    if enabled is None:
        enabled = _everyone(n)
    k = _sensed_pairs(
        np.asarray(pos, dtype=np.float64),
        np.ascontiguousarray(cos_h, dtype=np.float64),
        np.ascontiguousarray(sin_h, dtype=np.float64),
        np.ascontiguousarray(visible, dtype=np.bool_).reshape(-1, n, n),
        np.ascontiguousarray(enabled, dtype=np.bool_).reshape(-1, n),
        2.0 * robot_radius,
        sensor_range,
        2.0 / sensor_range,
        counts,
        rows,
        left,
        ahead,
        readings,
    )
    # bearing()'s atan2 stays in numpy (sdbc_sim.compiled), over the sensed pairs.
    bearings = np.arctan2(left[:k], ahead[:k])
    sector_minimum(
        rows[:k],
        bearings,
        readings[:k],
        b * n,
        n_sectors,
        out=out.reshape(b * n, out.shape[2]),
        column=column,
    )
    return out, counts


# Left writable: numba types a read-only array apart, and the compiled loop's
# signature names writable ones. Only neighbour_sectors hands them on, to that
# loop, which reads them.
@functools.cache
def _not_self(n: int) -> np.ndarray:
    """(N, N): every robot but itself, :func:`neighbour_sectors`' default
    visibility, made once per team size rather than at every step."""
    return ~np.eye(n, dtype=np.bool_)


@functools.cache
def _everyone(n: int) -> np.ndarray:
    """(1, N): no robot switched off, :func:`neighbour_sectors`' default
    ``enabled``."""
    return np.ones((1, n), dtype=np.bool_)


@compiled(
    "intp(float64[:, :, :], float64[:, ::1], float64[:, ::1], boolean[:, :, ::1], "
    "boolean[:, ::1], float64, float64, float64, float64[:, ::1], intp[::1], "
    "float64[::1], float64[::1], float64[::1])",
    calls=(bearing_arguments,),
)
def _sensed_pairs(
    pos: np.ndarray,
    cos_h: np.ndarray,
    sin_h: np.ndarray,
    visible: np.ndarray,
    enabled: np.ndarray,
    gap: float,
    sensor_range: float,
    scale: float,
    counts: np.ndarray,
    rows: np.ndarray,
    left: np.ndarray,
    ahead: np.ndarray,
    readings: np.ndarray,
) -> int:  # pragma: no cover - compiled; tested through neighbour_sectors
    """How many robots each robot senses (j where ``visible[., i, j]`` and
    ``enabled[., j]``, both of one row when shared by all trials; (B, N)
    ``counts``, summed in index order as ``robot_sum`` does) and, for the K
    sensed pairs in row-major order, the sensing robot's flat row, the offset
    rotated into its frame (:func:`bearing`'s atan2 arguments) and the reading;
    returns K.

    A compiled loop (:mod:`sdbc_sim.compiled`): as whole arrays this made
    (B, N, N) offsets, distances and masks and gathered them at every step; the
    operations are the array formulation's, in its order
    (``tests/sdbc_sim/test_sensors.py``)."""
    n = cos_h.shape[1]
    shared = visible.shape[0] == 1
    all_enabled = enabled.shape[0] == 1
    k = 0
    for t in range(pos.shape[0]):
        v = 0 if shared else t
        e = 0 if all_enabled else t
        for i in range(n):
            xi = pos[t, i, 0]
            yi = pos[t, i, 1]
            c = cos_h[t, i]
            s = sin_h[t, i]
            count = 0.0
            for j in range(n):
                dx = pos[t, j, 0] - xi
                dy = pos[t, j, 1] - yi
                edge = np.sqrt(dx * dx + dy * dy) - gap
                seen = edge <= sensor_range and visible[v, i, j] and enabled[e, j]
                if not seen:
                    continue
                count += 1.0
                reading = min(edge * scale - 1.0, 1.0)
                rows[k] = t * n + i
                left[k], ahead[k] = bearing_arguments(dx, dy, c, s)
                readings[k] = max(reading, -1.0)
                k += 1
            counts[t, i] = count
    return k
