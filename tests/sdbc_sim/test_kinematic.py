"""The kinematic physics model: the authors' robots (refused moves, sidesteps)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sdbc_sim.engine import PHYSICS_MODELS, BatchSimulation, EngineSettings
from sdbc_sim.kinematic import SIDESTEP_SPEED, KinematicTrials
from sdbc_sim.physics import DRIVE_COLUMNS, MODELS, PhysicsSettings
from sdbc_sim.sensors import point_segment_distance
from sdbc_sim.tasks import make_task

KINEMATIC = EngineSettings(PhysicsSettings(model="kinematic"))


def is_free(
    centres: np.ndarray,
    radii: np.ndarray,
    walls: np.ndarray,
    others: list[int],
    i: int,
    p: np.ndarray,
) -> bool:
    """Body ``i`` of a trial (centres (R, 2)) overlaps no wall and none of the
    bodies ``others`` with its centre at ``p``, by true distances."""
    if walls.shape[0] and point_segment_distance(p, walls).min() < radii[i]:
        return False
    return all(math.dist(p, centres[j]) >= radii[i] + radii[j] for j in others)


def moves_like_the_authors(
    state: np.ndarray,
    drive: np.ndarray,
    radii: np.ndarray,
    walls: np.ndarray,
    collides: np.ndarray,
    dt: float,
) -> np.ndarray:
    """The oracle: the rule written plainly, with true distances (square roots)
    instead of the compiled loop's squared ones, body after body."""
    col = DRIVE_COLUMNS["velocity"]
    n = radii.shape[0]
    out = state.copy()
    for row in range(out.shape[0]):
        first, i = row - row % n, row % n
        out[row, 2] = drive[row, col.angle]
        dx, dy = drive[row, col.x] * dt, drive[row, col.y] * dt
        x, y = out[row, 0], out[row, 1]
        centres = out[first : first + n, :2]
        others = [j for j in range(n) if j != i and collides[first + j]]
        if (
            collides[row]
            and (dx or dy)
            and not is_free(
                centres, radii, walls, others, i, np.array([x + dx, y + dy])
            )
        ):
            sx, sy = -dy * SIDESTEP_SPEED, dx * SIDESTEP_SPEED
            if is_free(centres, radii, walls, others, i, np.array([x + sx, y + sy])):
                dx, dy = sx, sy
            elif is_free(centres, radii, walls, others, i, np.array([x - sx, y - sy])):
                dx, dy = -sx, -sy
            else:
                dx, dy = 0.0, 0.0
        out[row, :2] = x + dx, y + dy
        out[row, 3:5] = dx / dt, dy / dt
    return out


def test_every_model_has_a_class() -> None:
    assert tuple(PHYSICS_MODELS) == MODELS


def test_the_compiled_step_equals_the_rule() -> None:
    """Crowded random states (6 robots of radius 1 to 2 in a 12 x 12 box with a
    diagonal wall, some switched off), random velocities up to 1.5: every row
    of the compiled step equals the oracle's to the bit."""
    rng = np.random.default_rng(4)
    radii = np.array([1.0, 1.5, 2.0, 1.0, 1.25, 1.75])
    walls = np.array(
        [
            [[0.0, 0.0], [12.0, 0.0]],
            [[12.0, 0.0], [12.0, 12.0]],
            [[12.0, 12.0], [0.0, 12.0]],
            [[0.0, 12.0], [0.0, 0.0]],
            [[3.0, 9.0], [9.0, 3.0]],
        ]
    )
    n_trials, n = 300, radii.shape[0]
    position = rng.uniform(1.0, 11.0, (n_trials, n, 2))
    physics = KinematicTrials(
        radii,
        1.0,
        walls,
        (0.0, 0.0, 12.0, 12.0),
        position,
        rng.uniform(-3.0, 3.0, (n_trials, n)),
        PhysicsSettings(model="kinematic", dt=0.5),
    )
    off = rng.random((n_trials, n)) < 0.1
    physics.disable(*np.nonzero(off))
    state = np.empty((n_trials * n, 5))
    physics.read(state)
    moves = sidesteps = 0
    for _ in range(20):
        drive = np.zeros((n_trials * n, 4))
        drive[:, 0] = rng.uniform(-3.0, 3.0, n_trials * n)
        drive[:, 1:3] = rng.uniform(-1.5, 1.5, (n_trials * n, 2))
        drive[rng.random(n_trials * n) < 0.1, 1:3] = 0.0
        expected = moves_like_the_authors(
            state, drive, radii, walls, ~off.reshape(-1), 0.5
        )
        physics.step(drive, state)
        assert np.array_equal(state, expected)
        asked = drive[:, 1:3] * 0.5
        made = state[:, 3:5] * 0.5
        moves += int(np.all(made == asked, axis=1).sum())
        sidesteps += int(
            np.isclose(np.hypot(*made.T), SIDESTEP_SPEED * np.hypot(*asked.T)).sum()
        )
    # Both branches were taken often: the test is not only of free moves.
    assert moves > 1000 and sidesteps > 1000


def test_a_robot_driven_into_a_wall_steps_left_at_half_speed(placed) -> None:
    """Facing the top wall (y = 200) from y = 197 at speed 1: the move to 198
    would overlap (radius 2.5), so it steps a quarter turn left (-x) at 0.5 per
    step and keeps its heading and its y."""
    task = placed(
        make_task("gate_escape"),
        [[100.0, 197.0], [150.0, 20.0], [150.0, 60.0], [150.0, 100.0]],
        [math.pi / 2, 0.0, 0.0, 0.0],
    )
    sim = BatchSimulation(task, np.array([0]), settings=KINEMATIC)
    out = np.zeros((1, 4, 3))
    out[0, 0] = [1.0, 0.5, 0.0]
    out[0, 1:, 2] = 1.0
    for k in range(1, 11):
        sim.step(out)
        x, y = sim.bodies.position[0, 0]
        assert y == 197.0
        assert x == pytest.approx(100.0 - 0.5 * k, abs=1e-12)
        assert sim.bodies.angle[0, 0] == math.pi / 2
        assert np.hypot(*sim.bodies.velocity[0, 0]) == pytest.approx(0.5)


def test_a_robot_boxed_in_on_three_sides_stays(placed) -> None:
    """Robot 0 faces robot 1 (touching ahead) with robots 2 and 3 touching on its
    left and right: the move and both sidesteps are refused; it stays, at rest,
    facing where it was told."""
    d = 5.0  # two radii: touching is allowed
    task = placed(
        make_task("gate_escape"),
        [[100.0, 100.0], [100.0 + d, 100.0], [100.0, 100.0 + d], [100.0, 100.0 - d]],
        [0.0, 0.0, 0.0, 0.0],
    )
    sim = BatchSimulation(task, np.array([0]), settings=KINEMATIC)
    out = np.zeros((1, 4, 3))
    out[0, 0] = [1.0, 0.5, 0.0]
    out[0, 1:, 2] = 1.0
    for _ in range(5):
        sim.step(out)
        assert np.array_equal(sim.bodies.position[0, 0], [100.0, 100.0])
        assert np.array_equal(sim.bodies.velocity[0, 0], [0.0, 0.0])


def test_random_controllers_never_overlap_anything(pushing_crowd) -> None:
    """The overlap bound, exactly: 8 robots in a 60 x 60 arena under random
    outputs for 1000 steps never overlap a wall or each other, though many of
    their moves are refused."""
    task = pushing_crowd
    r = task.config.robot_radius
    sim = BatchSimulation(task, np.arange(40), settings=KINEMATIC)
    rng = np.random.default_rng(0)
    refused = 0
    while not sim.finished:
        out = rng.uniform(0.0, 1.0, (sim.live.shape[0], 8, 3))
        out[..., 2] *= 0.55  # stop rarely, so robots keep running into things
        sim.step(out)
        on = sim.bodies.enabled
        pos = sim.bodies.position
        assert point_segment_distance(pos, task.walls)[on].min() >= r * (1 - 1e-12)
        gap = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=-1)
        both = on[:, :, None] & on[:, None] & ~np.eye(8, dtype=bool)
        assert gap[both].min() >= 2 * r * (1 - 1e-12)
        speed = np.hypot(*np.moveaxis(sim.bodies.velocity, -1, 0))
        refused += int((speed < 0.5 * out[..., 0] * task.config.max_speed).sum())
    assert refused > 1000


def test_the_kinematic_model_needs_velocity_actuation() -> None:
    with pytest.raises(ValueError, match="actuation 'force' needs model 'rigid'"):
        PhysicsSettings(model="kinematic", actuation="force")
    with pytest.raises(ValueError, match="model must be one of rigid, kinematic"):
        PhysicsSettings(model="chipmunk")  # type: ignore[arg-type]
