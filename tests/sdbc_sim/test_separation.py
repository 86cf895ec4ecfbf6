"""The compiled overlap projection against its array formulation, to the bit."""

from __future__ import annotations

import numpy as np
import pytest
from sdbc_sim.sensors import norm, robot_sum, segment_offsets
from sdbc_sim.separation import project_apart


def array_project_apart(
    pos: np.ndarray,
    enabled: np.ndarray,
    radii: np.ndarray,
    walls: np.ndarray,
    tolerance: float,
    iterations: int,
    anchored: np.ndarray | None = None,
) -> np.ndarray:
    """The projection as whole-array numpy passes over every trial at once: the
    formulation the engine used before the compiled loop, kept as its oracle."""
    pos = pos.copy()
    target = 0.5 * tolerance
    n = radii.shape[0]
    reach = radii[:, None] + radii[None, :]
    pair = ~np.eye(n, dtype=bool) & enabled[:, :, None] & enabled[:, None, :]
    # Share of a pair's overlap that body i takes: 1/2, or 0 (i anchored, j not),
    # or 1 (j anchored, i not).
    share: np.ndarray | float = 0.5
    if anchored is not None:
        a = anchored.astype(np.float64)
        share = 0.5 + 0.5 * (a[:, None, :] - a[:, :, None])
    # Each pass works on the trials that moved in the pass before: a trial whose
    # pass finds no overlap would only be moved by +-0 from then on, so dropping
    # it changes none of its bits, and the last passes cost only the few trials
    # still moving.
    rows = np.arange(pos.shape[0])
    p = pos
    for _ in range(iterations):
        x, y = p[..., 0], p[..., 1]
        dx = x[:, None, :] - x[:, :, None]
        dy = y[:, None, :] - y[:, :, None]
        d = norm(dx, dy)
        over = reach - d
        hit = pair & (over > tolerance) & (d > 0.0)
        k = np.where(hit, (over - target) * share / np.where(d > 0.0, d, 1.0), 0.0)
        shift_x = -robot_sum(k * dx, axis=2)
        shift_y = -robot_sum(k * dy, axis=2)
        moving = hit.any(axis=(1, 2))
        if walls.shape[0]:
            off = segment_offsets(p, walls)
            dist = norm(off[..., 0], off[..., 1])
            over_w = radii[None, :, None] - dist
            hit_w = enabled[:, :, None] & (over_w > tolerance) & (dist > 0.0)
            k_w = np.where(
                hit_w, (over_w - target) / np.where(dist > 0.0, dist, 1.0), 0.0
            )
            shift_x += robot_sum(k_w * off[..., 0], axis=2)
            shift_y += robot_sum(k_w * off[..., 1], axis=2)
            moving |= hit_w.any(axis=(1, 2))
        if not moving.any():
            break
        keep = np.flatnonzero(moving)
        p = p[keep]
        p[..., 0] += shift_x[keep]
        p[..., 1] += shift_y[keep]
        rows = rows[keep]
        pos[rows] = p
        pair, enabled = pair[keep], enabled[keep]
        if isinstance(share, np.ndarray):
            share = share[keep]
    return pos


WALLS = np.array(
    [
        [[0.0, 0.0], [30.0, 0.0]],
        [[30.0, 0.0], [30.0, 20.0]],
        [[30.0, 20.0], [0.0, 20.0]],
        [[0.0, 20.0], [0.0, 0.0]],
        [[12.0, 8.0], [12.0, 8.0]],  # a point: a degenerate segment
        [[5.0, 14.0], [22.0, 9.0]],
    ]
)


def crowded(
    rng: np.random.Generator, trials: int, bodies: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Trials of bodies packed so that most overlap each other and the walls;
    some share a centre exactly (d = 0), some are switched off or anchored."""
    radii = rng.choice([1.5, 2.5, 4.0], size=bodies)
    pos = rng.uniform(-2.0, 32.0, (trials, bodies, 2))
    if bodies > 1:
        same = rng.random((trials, 1)) < 0.2
        pos[:, 1, :] = np.where(same, pos[:, 0, :], pos[:, 1, :])
    pos[rng.random((trials, bodies)) < 0.05] = [12.0, 8.0]
    enabled = rng.random((trials, bodies)) < 0.9
    anchored = rng.random((trials, bodies)) < 0.2
    return pos, enabled, radii, anchored


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and bool(np.all(a.view(np.int64) == b.view(np.int64)))


@pytest.mark.parametrize("bodies", [1, 3, 4, 8])
@pytest.mark.parametrize("walls", [0, 4, 6])
def test_the_compiled_loop_is_the_array_formulation_to_the_bit(
    bodies: int, walls: int
) -> None:
    rng = np.random.default_rng(100 * bodies + walls)
    moved = 0
    for iterations in (1, 3, 8):
        pos, enabled, radii, anchored = crowded(rng, 200, bodies)
        for anchors in (None, anchored):
            args = (pos, enabled, radii, WALLS[:walls], 0.05, iterations, anchors)
            want = array_project_apart(*args)
            got = project_apart(*args)
            assert same_bits(got, want)
            moved += int(np.sum(np.any(got != pos, axis=-1)))
    # The cases did exercise the projection, except where nothing can overlap.
    assert (moved > 0) == (bodies > 1 or walls > 0)


def test_a_trial_is_projected_the_same_alone_and_in_a_batch() -> None:
    pos, enabled, radii, anchored = crowded(np.random.default_rng(7), 50, 6)
    batch = project_apart(pos, enabled, radii, WALLS, 0.05, 8, anchored)
    for b in (0, 17, 49):
        alone = project_apart(
            pos[b : b + 1],
            enabled[b : b + 1],
            radii,
            WALLS,
            0.05,
            8,
            anchored[b : b + 1],
        )
        assert same_bits(alone[0], batch[b])


def test_enough_passes_leave_no_overlap_beyond_the_tolerance() -> None:
    """Two bodies deep in each other and in a wall, far from any corner."""
    radii = np.array([2.5, 2.5])
    pos = np.array([[[10.0, 1.0], [12.0, 1.5]]])
    new = project_apart(pos, np.ones((1, 2), dtype=bool), radii, WALLS[:4], 0.05, 50)
    gap = np.hypot(*(new[0, 1] - new[0, 0]))
    assert gap >= 5.0 - 0.05
    assert np.all(new[0, :, 1] >= 2.5 - 0.05)
