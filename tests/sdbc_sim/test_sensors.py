"""Sensor geometry against hand-computed values."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sdbc_sim.sensors import (
    arc_index,
    arc_minimum,
    bearing,
    neighbour_sectors,
    norm,
    normalised_reading,
    point_segment_distance,
    ray_segment_distance,
    robot_min,
    robot_sum,
    sector_minimum,
    wrap_angle,
)


def test_bearing_is_the_angle_in_the_robots_frame() -> None:
    h = np.array([0.0, math.pi / 2, math.pi])
    dx, dy = np.zeros(3), np.array([1.0, 1.0, -1.0])
    b = bearing(dx, dy, np.cos(h), np.sin(h))
    np.testing.assert_allclose(b, [math.pi / 2, 0.0, math.pi / 2], atol=1e-12)
    np.testing.assert_allclose(
        wrap_angle(np.array([3 * math.pi / 2, -4.0])), [-math.pi / 2, 2 * math.pi - 4.0]
    )


def test_four_arcs_look_back_right_ahead_left() -> None:
    b = np.array([math.pi, -math.pi, -math.pi / 2, 0.0, math.pi / 2, 0.7, -2.5, -2])
    assert arc_index(b, 4).tolist() == [0, 0, 1, 2, 3, 2, 0, 1]


def test_sector_minimum_sparse_equals_dense() -> None:
    readings = np.array([[[1.0, 0.2, -0.5, 0.9]]])
    bearings = np.array([[[0.0, 0.1, math.pi / 2, 0.2]]])
    dense = arc_minimum(readings, arc_index(bearings, 4), 4)
    np.testing.assert_array_equal(dense[0, 0], [1.0, 1.0, 0.2, -0.5])
    sparse = sector_minimum(
        np.zeros(3, int), bearings[0, 0, 1:], readings[0, 0, 1:], 1, 4
    )
    np.testing.assert_array_equal(sparse[0], dense[0, 0])


def test_rays_and_segments() -> None:
    segments = np.array([[[0.0, -1.0], [0.0, 1.0]], [[5.0, -1.0], [5.0, 1.0]]])
    origins = np.array([[3.0, 0.0], [3.0, 0.0], [3.0, 0.0], [3.0, 5.0]])
    s = math.sqrt(0.5)
    directions = np.array([[-1.0, 0.0], [1.0, 0.0], [-s, s], [-1.0, 0.0]])
    d = ray_segment_distance(origins, directions, 2.5, segments)
    # Left: x = 0 at 3 is beyond 2.5; right: x = 5 at 2; diagonal: crosses x = 0
    # at y = 3, off the segment; above: misses.
    np.testing.assert_allclose(d, [np.inf, 2.0, np.inf, np.inf])
    assert ray_segment_distance(origins[:1], directions[:1], 3.0, segments)[0] == 3.0
    parallel = ray_segment_distance(
        np.array([[0.0, -3.0]]), np.array([[0.0, 1.0]]), 9, segments
    )
    assert parallel[0] == np.inf
    p = point_segment_distance(np.array([[3.0, 0.0], [0.0, 4.0]]), segments)
    np.testing.assert_allclose(p, [[3.0, 2.0], [3.0, math.hypot(5.0, 3.0)]])


def array_ray_segment_distance(
    origins: np.ndarray, directions: np.ndarray, length: float, segments: np.ndarray
) -> np.ndarray:
    """Ray distances as whole-array numpy per segment: the formulation the
    sensors used before the compiled loop, kept as its oracle."""
    ox_all, oy_all = origins[:, 0], origins[:, 1]
    nearest = np.full(origins.shape[0], np.inf)
    for (ax, ay), (bx, by) in segments.tolist():
        near = np.flatnonzero(
            (ox_all >= min(ax, bx) - length)
            & (ox_all <= max(ax, bx) + length)
            & (oy_all >= min(ay, by) - length)
            & (oy_all <= max(ay, by) + length)
        )
        if near.size == 0:
            continue
        ox, oy = ox_all[near], oy_all[near]
        ux, uy = directions[near, 0], directions[near, 1]
        ex, ey = bx - ax, by - ay
        wx, wy = ax - ox, ay - oy
        denom = ux * ey - uy * ex
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (wx * ey - wy * ex) / denom
            s = (wx * uy - wy * ux) / denom
        best = nearest[near]
        hit = (t >= 0.0) & (t <= length) & (s >= 0.0) & (s <= 1.0) & (t < best)
        nearest[near[hit]] = t[hit]
    return nearest


def test_the_compiled_ray_loop_is_the_array_formulation_to_the_bit() -> None:
    """Random rays among random segments, with parallel rays, rays along a
    segment, points as segments and rays starting on a segment."""
    rng = np.random.default_rng(3)
    segments = rng.uniform(0.0, 20.0, (9, 2, 2))
    segments[1, 1] = segments[1, 0]  # a point
    segments[2, :, 1] = 7.0  # horizontal
    segments[3, :, 0] = 4.0  # vertical
    origins = rng.uniform(-3.0, 23.0, (3000, 2))
    angle = rng.uniform(-math.pi, math.pi, 3000)
    angle[::7] = 0.0  # parallel to the horizontal segment
    angle[1::7] = math.pi / 2  # parallel to the vertical one
    directions = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    origins[2::7, 1] = 7.0  # on the horizontal segment's line
    origins[3::7] = segments[0, 0]  # on an end point
    for length in (2.5, 10.0):
        want = array_ray_segment_distance(origins, directions, length, segments)
        got = ray_segment_distance(origins, directions, length, segments)
        assert np.all(got.view(np.int64) == want.view(np.int64))
        assert 0 < np.count_nonzero(np.isfinite(got)) < got.shape[0]


def test_readings_and_fixed_order_reductions() -> None:
    np.testing.assert_allclose(
        normalised_reading(np.array([0.0, 12.5, 25.0, 40.0]), 25.0), [-1, 0, 1, 1]
    )
    a = np.array([[1e16, 1.0, -1e16, 1.0]])
    # ((1e16 + 1) - 1e16) + 1 in that order, whatever numpy would do.
    assert robot_sum(a)[0] == ((1e16 + 1.0) - 1e16) + 1.0
    assert robot_min(np.array([[3.0, -2.0, 5.0]]), axis=1)[0] == -2.0
    with pytest.raises(IndexError):
        robot_sum(np.zeros((2, 0)))


def array_neighbour_sectors(
    pos: np.ndarray,
    cos_h: np.ndarray,
    sin_h: np.ndarray,
    robot_radius: float,
    sensor_range: float,
    n_sectors: int,
    visible: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """neighbour_sectors as whole (B, N, N) arrays and ``np.minimum.at``: the
    formulation the compiled loops replaced, kept as their oracle."""
    b, n = cos_h.shape
    x, y = pos[..., 0], pos[..., 1]
    dx = x[:, None, :] - x[:, :, None]
    dy = y[:, None, :] - y[:, :, None]
    edge = norm(dx, dy) - 2.0 * robot_radius
    sensed = (edge <= sensor_range) & visible
    pairs = np.flatnonzero(sensed)
    rows = pairs // n
    readings = np.maximum(
        normalised_reading(edge.reshape(-1)[pairs], sensor_range), -1.0
    )
    bearings = bearing(
        dx.reshape(-1)[pairs],
        dy.reshape(-1)[pairs],
        cos_h.reshape(-1)[rows],
        sin_h.reshape(-1)[rows],
    )
    out = np.full((b * n, n_sectors), 1.0)
    np.minimum.at(out, (rows, arc_index(bearings, n_sectors)), readings)
    return out.reshape(b, n, n_sectors), robot_sum(sensed.astype(np.float64), axis=-1)


@pytest.mark.parametrize("per_trial", [False, True])
@pytest.mark.parametrize("n_sectors", [3, 4, 8])
def test_neighbour_sectors_equal_the_array_formulation(
    per_trial: bool, n_sectors: int
) -> None:
    """To the bit, with robots on a unit grid (edge distances tie, fall exactly on
    the range, overlap, and bearings fall on sector borders), headings on
    multiples of pi / 4 and at random, a few trials off the grid, and the
    visibility shared by every trial or given per trial, with and without robots
    switched off, into a new array and into the columns of a wider one."""
    rng = np.random.default_rng(n_sectors)
    b, n = 64, 5
    pos = rng.integers(0, 7, (b, n, 2)).astype(np.float64)
    pos[: b // 4] += rng.normal(0.0, 0.5, (b // 4, n, 2))
    heading = rng.integers(-4, 4, (b, n)) * (math.pi / 4)
    heading[b // 2 :] = rng.uniform(-math.pi, math.pi, (b - b // 2, n))
    visible = ~np.eye(n, dtype=bool)
    if per_trial:
        visible = visible & (rng.random((b, n, n)) < 0.7)
    args = (pos, np.cos(heading), np.sin(heading), 0.5, 3.0, n_sectors, visible)
    got, got_counts = neighbour_sectors(*args)
    want, want_counts = array_neighbour_sectors(*args)
    np.testing.assert_array_equal(got_counts, want_counts)
    np.testing.assert_array_equal(got, want)
    assert (want == -1.0).any() and (want == 1.0).any() and (np.abs(want) < 1).any()
    if not per_trial:
        # No visibility given: every robot but itself, as the tasks use it.
        default, default_counts = neighbour_sectors(*args[:-1])
        np.testing.assert_array_equal(default_counts, want_counts)
        np.testing.assert_array_equal(default, want)

    enabled = rng.random((b, n)) < 0.6
    wide = np.full((b, n, n_sectors + 3), np.nan)
    got, got_counts = neighbour_sectors(*args, enabled=enabled, out=wide, column=2)
    assert got is wide
    want, want_counts = array_neighbour_sectors(
        *args[:-1], visible & enabled[:, None, :]
    )
    np.testing.assert_array_equal(got_counts, want_counts)
    np.testing.assert_array_equal(wide[..., 2 : 2 + n_sectors], want)
    assert np.isnan(wide[..., :2]).all() and np.isnan(wide[..., 2 + n_sectors :]).all()
    assert not np.array_equal(want, array_neighbour_sectors(*args)[0])


def test_neighbour_sectors_refuse_an_out_they_cannot_fill() -> None:
    """An ``out`` without room for the sectors from ``column`` on, of another
    type, or not C-ordered (the loop would fill a copy, and the readings would
    be lost), is refused in one line naming what it needs; so is a column
    without an out."""
    b, n = 3, 4
    args = (np.zeros((b, n, 2)), np.ones((b, n)), np.zeros((b, n)), 0.5, 3.0, 4)
    visible = ~np.eye(n, dtype=bool)
    need = r"neighbour_sectors: out must be C-ordered float64 \(3, 4, K\) with 4 "
    fine = np.empty((b, n, 6))
    assert neighbour_sectors(*args, visible, out=fine, column=2)[0] is fine
    for out, column in [
        (np.empty((b, n, 3)), 0),
        (fine, 3),
        (fine, -1),
        (np.empty((b, n, 6), dtype=np.float32), 0),
        (np.empty((n, b, 4)).transpose(1, 0, 2), 0),
        (np.empty((b, n + 1, 4)), 0),
    ]:
        with pytest.raises(ValueError, match=need + f"columns from column {column}"):
            neighbour_sectors(*args, visible, out=out, column=column)
    with pytest.raises(ValueError, match="column 2 needs an out to write into"):
        neighbour_sectors(*args, visible, column=2)
