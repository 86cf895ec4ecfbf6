"""Hand-coded single-robot chargers on resource sharing, from random starts.

Two controllers steer at the station (the turn that cancels the station bearing,
capped at the largest turn) and stop once the station centre is closer than 0.5:

- ``full_speed``: speed 1 until then;
- ``slowing``: speed min(1, D), D the station centre distance.

With the default settings (velocity actuation: a robot moves in the step it is
commanded and a stop stops it at once) both dock and charge from every start. With
``PhysicsSettings(actuation="force")`` a robot moves one step after its command
and coasts one unit after a stop, so it overshoots the station.

The rate over 200 starts, per controller and actuation mode:
``scripts/sdbc run python tests/sdbc_sim/tasks/test_hand_coded_chargers.py 200``.

Teams: three robots with ``full_speed``, all making for the one station, push
each other; a *push-off* is a docked robot that is no longer docked after a step
in which it was told to stop and was alive. ``--team`` (same command, after the
number of starts) prints push-offs per trial and charging robot-steps per trial,
with and without ``anchor_docked``. Measured over 200 starts: 0.58 push-offs and
141.6 charging robot-steps per trial without anchoring, 0 and 277.7 with it.
"""

from __future__ import annotations

import sys
from collections.abc import Callable

import numpy as np
import pytest
from sdbc_sim.engine import BatchSimulation, EngineSettings
from sdbc_sim.physics import PhysicsSettings
from sdbc_sim.tasks import make_task

Policy = Callable[[np.ndarray], np.ndarray]


def _steer(x: np.ndarray, max_turn: float) -> np.ndarray:
    """o1 that turns by the station bearing (input 5, bearing / pi), capped."""
    bearing = x[..., 5] * np.pi
    return 0.5 + np.clip(bearing, -max_turn, max_turn) / (2.0 * max_turn)


def _distance(x: np.ndarray, sensor_range: float) -> np.ndarray:
    """Station centre distance from input 4, 2 D / range - 1."""
    return (x[..., 4] + 1.0) * sensor_range / 2.0


def full_speed(x: np.ndarray, max_turn: float, sensor_range: float) -> np.ndarray:
    """Full speed at the station, stop within 0.5 of its centre."""
    d = _distance(x, sensor_range)
    out = np.empty((*x.shape[:-1], 3))
    out[..., 0] = 1.0
    out[..., 1] = _steer(x, max_turn)
    out[..., 2] = np.where(d < 0.5, 1.0, 0.0)
    return out


def slowing(x: np.ndarray, max_turn: float, sensor_range: float) -> np.ndarray:
    """Speed min(1, D) at the station, stop within 0.5 of its centre."""
    d = _distance(x, sensor_range)
    out = full_speed(x, max_turn, sensor_range)
    out[..., 0] = np.minimum(1.0, d)
    return out


CONTROLLERS = {"full_speed": full_speed, "slowing": slowing}


def charged(controller: str, seeds: np.ndarray, actuation: str) -> np.ndarray:
    """(len(seeds),) bool: whether the lone robot charged at some step."""
    task = make_task("resource_sharing", n_robots=1)
    c = task.config
    policy = CONTROLLERS[controller]
    settings = EngineSettings(PhysicsSettings(actuation=actuation))
    sim = BatchSimulation(task, seeds, settings=settings)
    ever = np.zeros(seeds.shape[0], dtype=bool)
    while not sim.finished:
        out = policy(sim.sensors(), c.max_turn, c.station_sensor_range)
        sim.step(out)
        ever[sim.live] |= sim.trials.charging.any(axis=1)
    return ever


@pytest.mark.parametrize("controller", sorted(CONTROLLERS))
def test_hand_coded_chargers_charge_from_every_start(controller: str) -> None:
    assert charged(controller, np.arange(20), "velocity").all()


def team(seeds: np.ndarray, anchor: bool) -> tuple[np.ndarray, np.ndarray]:
    """(push-offs, charging robot-steps) per trial of three ``full_speed``
    robots, with or without ``anchor_docked``."""
    task = make_task("resource_sharing", anchor_docked=anchor)
    c = task.config
    sim = BatchSimulation(task, seeds)
    pushed = np.zeros(seeds.shape[0], dtype=np.int64)
    charging = np.zeros(seeds.shape[0], dtype=np.int64)
    while not sim.finished:
        out = full_speed(sim.sensors(), c.max_turn, c.station_sensor_range)
        was_docked = sim.trials.docked_steps > 0
        before = sim.live
        sim.step(out)
        # The step may drop the rows of trials that ended earlier.
        rows = np.searchsorted(before, sim.live)
        trials = sim.trials
        told_to_stop = out[rows, :, 2] > c.stop_threshold
        off = was_docked[rows] & (trials.docked_steps == 0) & told_to_stop
        off &= trials.energy > 0.0
        pushed[sim.live] += off.sum(axis=1)
        charging[sim.live] += trials.charging.sum(axis=1)
    return pushed, charging


def test_an_anchored_docked_robot_is_not_pushed_off(placed) -> None:
    """Robot 0 stops on the station centre; robot 1, 9 above it (1 apart edge to
    edge), drives down into it at full speed for 30 steps. Without anchoring
    robot 1 pushes it off; anchored from its first docked step (step 1), robot 0
    moves by far less than the tolerance and charges from step 6 on."""
    for anchor in (False, True):
        task = placed(
            make_task("resource_sharing", anchor_docked=anchor),
            [[75.0, 75.0], [75.0, 84.0], [25.0, 75.0]],
            [0.0, -np.pi / 2, 0.0],
        )
        sim = BatchSimulation(task, np.array([0]))
        flags = []
        for _ in range(30):
            sim.step(np.array([[[0.0, 0.5, 1.0], [1.0, 0.5, 0.0], [0.0, 0.5, 1.0]]]))
            flags.append(bool(sim.trials.charging[0, 0]))
        moved = np.linalg.norm(sim.bodies.position[0, 0] - [75.0, 75.0])
        if anchor:
            assert moved < 1e-3 and flags == [False] * 5 + [True] * 25
        else:
            assert moved > 1.0 and not flags[-1]


def _team_trials(seeds: np.ndarray, per_space: int) -> tuple[np.ndarray, np.ndarray]:
    """Fitness and the last positions of anchored ``full_speed`` teams."""
    task = make_task("resource_sharing", anchor_docked=True)
    c = task.config
    physics = PhysicsSettings(trials_per_space=per_space)
    sim = BatchSimulation(task, seeds, settings=EngineSettings(physics))
    last = np.zeros((seeds.shape[0], 3, 2))
    while not sim.finished:
        sim.step(full_speed(sim.sensors(), c.max_turn, c.station_sensor_range))
        last[sim.live] = sim.bodies.position
    return sim.fitness, last


def test_anchored_teams_are_the_same_alone_and_in_any_space() -> None:
    """Anchoring changes masses mid-trial while teammates push: 12 such trials
    give the same results to the bit in one Space, 3 per Space, and alone."""
    seeds = np.arange(12)
    fitness, last = _team_trials(seeds, 500)
    pushed, _ = team(seeds, anchor=False)
    assert pushed.sum() > 0  # without anchoring these teams do push
    small_fitness, small_last = _team_trials(seeds, 3)
    np.testing.assert_array_equal(small_fitness, fitness)
    np.testing.assert_array_equal(small_last, last)
    for i in (0, 5, 11):
        alone_fitness, alone_last = _team_trials(seeds[i : i + 1], 500)
        assert alone_fitness[0] == fitness[i]
        np.testing.assert_array_equal(alone_last[0], last[i])


def main(starts: int, teams: bool) -> None:
    seeds = np.arange(starts)
    if teams:
        for anchor in (False, True):
            pushed, charging = team(seeds, anchor)
            print(
                f"anchor_docked={anchor}: push-offs per trial {pushed.mean():.2f}, "
                f"charging robot-steps per trial {charging.mean():.1f}"
            )
        return
    for actuation in ("velocity", "force"):
        for controller in sorted(CONTROLLERS):
            rate = charged(controller, seeds, actuation).mean()
            print(f"{actuation:8s} {controller:10s} charged in {100 * rate:.1f} %")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 200, "--team" in sys.argv)
