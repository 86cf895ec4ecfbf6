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


def main(starts: int) -> None:
    seeds = np.arange(starts)
    for actuation in ("velocity", "force"):
        for controller in sorted(CONTROLLERS):
            rate = charged(controller, seeds, actuation).mean()
            print(f"{actuation:8s} {controller:10s} charged in {100 * rate:.1f} %")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 200)
