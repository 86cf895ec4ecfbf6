"""Geometry shared by the tasks' sensors, batch-first over trials and robots.

Everything here is element-wise numpy over whole batches, in trial-local
coordinates. Angles are in radians, counter-clockwise; a robot's *bearing* to a
point is the angle of the point in the robot's frame, in [-pi, pi).

Sensor readings follow the authors' convention (MASE): a distance d sensed with
range r reads ``2 d / r - 1`` in [-1, 1], and 1 when nothing is in range.
"""

from __future__ import annotations

import numpy as np

TWO_PI = 2.0 * np.pi


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return np.mod(a + np.pi, TWO_PI) - np.pi


def bearing(dx: np.ndarray, dy: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """Bearing in [-pi, pi) of the vector (dx, dy) seen from a robot facing
    ``heading``: wrap(atan2(dy, dx) - heading)."""
    return wrap_angle(np.arctan2(dy, dx) - heading)


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
    x = pos[..., 0]
    y = pos[..., 1]
    dx = x[:, None, :] - x[:, :, None]
    dy = y[:, None, :] - y[:, :, None]
    return dx, dy, np.hypot(dx, dy)


def arc_index(bearings: np.ndarray, n_arcs: int) -> np.ndarray:
    """Which of ``n_arcs`` equal sectors holds each bearing.

    Sector j is centred on bearing -pi + j 2 pi / n_arcs, so with 4 arcs sector 0
    looks back, 1 right, 2 ahead and 3 left, as in the authors' code.
    """
    width = TWO_PI / n_arcs
    idx = np.floor((bearings + (np.pi + 0.5 * width)) / width).astype(np.intp)
    return np.mod(idx, n_arcs, out=idx)


def arc_minimum(
    readings: np.ndarray, arcs: np.ndarray, n_arcs: int, empty: float = 1.0
) -> np.ndarray:
    """Per-sector minimum of neighbour readings.

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
        np.min(np.where(arcs == j, readings, empty), axis=-1, out=out[..., j])
    return np.minimum(out, empty, out=out)


def ray_segment_distance(
    origins: np.ndarray, directions: np.ndarray, length: float, segments: np.ndarray
) -> np.ndarray:
    """Distance along rays to the nearest segment they cross.

    Solves o + t u = a + s (b - a) for every ray and segment:
    t = ((a - o) x e) / (u x e), s = ((a - o) x u) / (u x e), with e = b - a and
    p x q = p_x q_y - p_y q_x; a hit needs 0 <= t <= length and 0 <= s <= 1.
    Parallel rays and segments never hit.

    Args:
        origins: (M, 2) ray starts.
        directions: (M, 2) unit ray directions.
        length: Ray length.
        segments: (P, 2, 2) segments as their two end points.

    Returns:
        (M,) distance t of the nearest hit, inf where the ray hits nothing.
    """
    a = segments[:, 0, :]
    ex = segments[:, 1, 0] - a[:, 0]
    ey = segments[:, 1, 1] - a[:, 1]
    wx = a[None, :, 0] - origins[:, 0:1]
    wy = a[None, :, 1] - origins[:, 1:2]
    ux = directions[:, 0:1]
    uy = directions[:, 1:2]
    denom = ux * ey - uy * ex
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (wx * ey - wy * ex) / denom
        s = (wx * uy - wy * ux) / denom
    hit = (t >= 0.0) & (t <= length) & (s >= 0.0) & (s <= 1.0)
    return np.where(hit, t, np.inf).min(axis=1)


def point_segment_distance(points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Euclidean distance from points to segments.

    Args:
        points: (..., 2).
        segments: (P, 2, 2).

    Returns:
        (..., P) distance from each point to each segment.
    """
    a = segments[:, 0, :]
    e = segments[:, 1, :] - a
    ee = np.einsum("pk,pk->p", e, e)
    w = points[..., None, :] - a
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(ee > 0.0, np.einsum("...pk,pk->...p", w, e) / ee, 0.0)
    s = np.clip(s, 0.0, 1.0)
    d = w - s[..., None] * e
    return np.hypot(d[..., 0], d[..., 1])
