"""Wall rays: the compiled loop against the array formulation it replaced."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sdbc_sim.arena import (
    WallRays,
    _team_from_draws,
    draw_team,
    speed_and_turn,
    square_walls,
    uniform,
)
from sdbc_sim.sensors import normalised_reading, ray_segment_distance
from sdbc_sim.tasks import make_task

from sdbc_sim import compiled


def array_wall_rays(rays: WallRays, pos: np.ndarray, cos_h, sin_h) -> np.ndarray:
    """WallRays.read as whole arrays: the robots near the border gathered, their
    rays rotated, stacked and cast by ray_segment_distance, the readings
    scattered back. The formulation the compiled loop replaced, kept as its
    oracle."""
    n_rays, r = rays.n_rays, rays.robot_radius
    reach = r + rays.ray_range
    x0, y0, x1, y1 = rays.box
    out = np.ones((*cos_h.shape, n_rays))
    x, y = pos[..., 0], pos[..., 1]
    near = np.flatnonzero(
        (x < x0 + reach) | (x > x1 - reach) | (y < y0 + reach) | (y > y1 - reach)
    )
    p = pos.reshape(-1, 2)[near]
    c = cos_h.reshape(-1, 1)[near]
    s = sin_h.reshape(-1, 1)[near]
    arc = 2.0 * np.pi / n_rays
    angles = -arc / 2.0 + arc * np.arange(n_rays)
    ux = c * np.cos(angles) - s * np.sin(angles)
    uy = s * np.cos(angles) + c * np.sin(angles)
    u = np.stack([ux, uy], axis=-1).reshape(-1, 2)
    origin = np.repeat(p, n_rays, axis=0) + r * u
    d = ray_segment_distance(origin, u, rays.ray_range, rays.walls)
    reading = np.where(np.isfinite(d), normalised_reading(d, rays.ray_range), 1.0)
    out.reshape(-1, n_rays)[near] = reading.reshape(-1, n_rays)
    return out


@pytest.mark.parametrize("task", ["gate_escape", "foraging", "aggregation", None])
def test_compiled_wall_rays_equal_the_array_formulation(task: str | None) -> None:
    """To the bit, for each task's walls (gate escape's with its opening) and a
    plain box: robots on a unit grid along the border (rays that end exactly on a
    wall, run along one or meet a corner) and at random, headings on multiples of
    pi / 4 and at random, positions as the engine's strided view."""
    if task is None:
        rays = WallRays(square_walls(40.0), (0.0, 0.0, 40.0, 40.0), 5, 3.0, 1.0)
    else:
        rays = make_task(task)._wall_rays
    x0, y0, x1, y1 = rays.box
    rng = np.random.default_rng(7)
    b, n = 60, 4
    grid = rng.integers(-2, 9, (b, n, 2)).astype(np.float64)
    corner = np.where(rng.random((b, n, 2)) < 0.5, (x0, y0), (x1, y1))
    side = np.where(corner == (x0, y0), 1.0, -1.0)
    rows = np.zeros((b, n, 5))
    rows[..., 0:2] = corner + side * grid
    rows[: b // 3, :, 0] = rng.uniform(x0, x1, (b // 3, n))
    heading = rng.integers(-4, 4, (b, n)) * (math.pi / 4)
    heading[b // 2 :] = rng.uniform(-math.pi, math.pi, (b - b // 2, n))
    args = (rows[..., 0:2], np.cos(heading), np.sin(heading))
    want = array_wall_rays(rays, *args)
    np.testing.assert_array_equal(rays.read(*args), want)
    assert (want == 1.0).any() and (want < 1.0).any() and (want == -1.0).any()
    # Into the rays' columns of a wider array, the others left alone.
    wide = np.full((b, n, rays.n_rays + 2), np.nan)
    assert rays.read(*args, out=wide, column=1) is wide
    np.testing.assert_array_equal(wide[..., 1 : 1 + rays.n_rays], want)
    assert np.isnan(wide[..., 0]).all() and np.isnan(wide[..., -1]).all()


def test_compiled_speed_and_turn_equal_the_array_formulation() -> None:
    """The drive's loop does the operations of its array form, NaN outputs and
    outputs at the threshold included."""
    rng = np.random.default_rng(5)
    outputs = rng.uniform(0.0, 1.0, (37, 4, 3))
    outputs[0, 0] = np.nan
    outputs[1, 1, 2] = 0.5
    outputs[2, 2, 0] = np.nan
    for view in (outputs, outputs.transpose(1, 0, 2).copy().transpose(1, 0, 2)):
        speed, turn = speed_and_turn(view, 1.3, 1.57, 0.5)
        want_speed = np.where(view[..., 2] > 0.5, 0.0, view[..., 0] * 1.3)
        want_turn = (2.0 * view[..., 1] - 1.0) * 1.57
        assert np.array_equal(speed.view(np.int64), want_speed.view(np.int64))
        assert np.array_equal(turn.view(np.int64), want_turn.view(np.int64))


@pytest.mark.parametrize("bulk", [False, True])
def test_team_draws_are_numpys_uniform_draws(
    bulk: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """draw_team scales the generator's doubles itself, one by one or, once the
    loops are loaded, in bulk; either way its starts, and the stream it leaves
    (a buffered half-word included), are those of ``rng.uniform`` drawn
    position by position (x and y together) and heading by heading, redrawn
    while too close."""
    if bulk:
        compiled.load()
    monkeypatch.setattr(compiled, "loaded", lambda: bulk)

    def with_uniform(rng, n, low, high, separation, taken):
        position, heading = np.empty((n, 2)), np.empty(n)
        for i in range(n):
            while True:
                p = tuple(rng.uniform(low, high, size=2).tolist())
                if all(math.dist(q, p) >= separation for q in taken):
                    break
            taken.append(p)
            position[i], heading[i] = p, rng.uniform(-np.pi, np.pi)
        return position, heading

    for seed in range(300):
        for n, low, high, separation in [(3, 2.5, 97.5, 10.0), (8, -3.0, 3.0, 1.0)]:
            want_rng, got_rng = np.random.default_rng(seed), np.random.default_rng(seed)
            if seed % 2:
                # Leaves half of a 64-bit word buffered for the next 32-bit draw.
                for rng in (want_rng, got_rng):
                    rng.integers(2**32, dtype=np.uint32)
            want_taken, got_taken = [(0.5, 0.5)], [(0.5, 0.5)]
            want = with_uniform(want_rng, n, low, high, separation, want_taken)
            got = draw_team(got_rng, n, low, high, separation, got_taken, "t")
            for g, w in zip(got, want, strict=True):
                assert np.array_equal(g.view(np.int64), w.view(np.int64))
            assert got_taken == want_taken
            assert got_rng.integers(2**32, dtype=np.uint32) == want_rng.integers(
                2**32, dtype=np.uint32
            )
            assert got_rng.random() == want_rng.random()


def test_bulk_team_draws_leave_close_calls_and_short_draws_to_the_caller() -> None:
    """The bulk loop refuses to decide a distance within a relative 1e-9 of the
    separation (the C library's hypot and math.dist may round it apart) and
    says when it runs out of doubles; draw_team then draws one by one."""
    position, heading = np.empty((1, 2)), np.empty(1)
    taken = np.zeros((1, 2))
    # (0.6, 0.8) lies at 1 from the origin: a close call at separation 1.
    u = np.array([0.6, 0.8, 0.5])
    assert _team_from_draws(u, 0.0, 1.0, 1.0, taken, position, heading) == -2
    assert _team_from_draws(u, 0.0, 1.0, 0.5, taken, position, heading) == 3
    assert position.tolist() == [[0.6, 0.8]] and heading[0] == 0.0
    assert _team_from_draws(u[:2], 0.0, 1.0, 0.5, taken, position, heading) == -1
    # Rejected twice (too close), then accepted: 7 doubles.
    u = np.array([0.1, 0.1, 0.2, 0.2, 0.9, 0.9, 0.5])
    assert _team_from_draws(u, 0.0, 1.0, 0.5, taken, position, heading) == 7


@pytest.mark.parametrize(
    ("low", "high"), [(0.0, 2.0 * math.pi), (-math.pi, math.pi), (2.5, 97.5)]
)
def test_uniform_is_numpys_uniform(low: float, high: float) -> None:
    want_rng, got_rng = np.random.default_rng(3), np.random.default_rng(3)
    want = want_rng.uniform(low, high, 20000)
    got = np.array([uniform(got_rng, low, high) for _ in range(20000)])
    assert np.array_equal(got.view(np.int64), want.view(np.int64))


def test_wall_rays_refuse_an_out_they_cannot_fill() -> None:
    """The loop writes into the whole C-ordered sensor array from ``column``:
    an array of another type or order, or without room for every ray from that
    column, is refused in one line naming what it needs; so is a column
    without an out."""
    rays = make_task("gate_escape")._wall_rays
    b, n = 3, 4
    args = (np.full((b, n, 2), 100.0), np.ones((b, n)), np.zeros((b, n)))
    fine = np.empty((b, n, 11))
    assert rays.read(*args, out=fine, column=7) is fine
    for out, column in [
        (np.empty((b, n, 11)), 8),
        (np.empty((b, n, 11)), -1),
        (np.empty((b, n, 11), dtype=np.float32), 7),
        (np.empty((n, b, 11)).transpose(1, 0, 2), 7),
        (np.empty((b, n + 1, 11)), 7),
    ]:
        with pytest.raises(ValueError, match=r"^WallRays.read: out must be C-ordered"):
            rays.read(*args, out=out, column=column)
    with pytest.raises(ValueError, match="column 7 needs an out to write into"):
        rays.read(*args, column=7)
