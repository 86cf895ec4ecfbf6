"""Beacon homing: a team of robots in a walled square arena must gather within
``home_radius`` of a beacon whose place each trial draws.

It is a task of one's own, outside the sdbc package: a settings class made with
``@settings`` and a :class:`~sdbc_sim.task.Task` subclass, registered by its
package's entry point (``pyproject.toml``). sdbc's SDBC, GA, study and live graph
then use it unchanged; ``sdbc-conformance beacon_homing`` checks it.

Rules, per trial: the beacon is drawn uniform in [margin, size - margin]^2, then each
robot uniform in [2 r, size - 2 r]^2 (redrawn until it overlaps no earlier robot)
with a heading uniform in [-pi, pi). A robot is *home* while its centre lies within
``home_radius`` of the beacon. The trial ends when every robot is home, or after
``max_steps``.

Sensors (in [-1, 1]): the beacon's distance 2 d / diagonal - 1 and bearing / pi,
and the nearest other robot's edge distance 2 e / ``neighbour_range`` - 1 (1 when
none is in range). Outputs: speed o0 x ``max_speed``; turn (2 o1 - 1) x ``max_turn``.

Fitness, in [0, 1]: (h + 1 - D_final) / (N + 1), h the robots home at the end, N
the team size, D_final their mean final distance to the beacon over the arena's
diagonal. Task-specific characterisation: the fraction home at the end, the mean
distance to the beacon over the trial, and the final one (both / diagonal).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from sdbc_sim.network import NetworkShape
from sdbc_sim.sensors import (
    bearing,
    norm,
    normalised_reading,
    pairwise_offsets,
    robot_min,
    robot_sum,
)
from sdbc_sim.settings import (
    Fraction,
    PositiveFloat,
    PositiveInt,
    check,
    settings,
)
from sdbc_sim.task import BodyLayout, BodyState, Task, TrialArrays
from sdbc_sim.task_state import (
    EntityGroupSpec,
    Geometry,
    GroupState,
    TaskDescription,
)

_MAX_START_DRAWS = 10_000
"""Position draws per robot before a start counts as impossible."""


@settings
class BeaconHomingConfig:
    """Settings of beacon homing (example values, not from a publication)."""

    arena_size: PositiveFloat = 100.0
    """Side of the walled square arena."""
    n_robots: PositiveInt = 3
    """N, robots in the team."""
    robot_radius: PositiveFloat = 2.0
    """Radius of a robot."""
    max_speed: PositiveFloat = 1.0
    """Top speed, units per step."""
    max_turn: PositiveFloat = 0.5
    """Largest turn, radians per step."""
    beacon_margin: PositiveFloat = 15.0
    """The beacon is drawn at least this far from the walls."""
    home_radius: PositiveFloat = 10.0
    """A robot whose centre is this close to the beacon is home."""
    neighbour_range: PositiveFloat = 15.0
    """Range (edge to edge) of the nearest-robot sensor."""
    n_hidden: PositiveInt = 4
    """Hidden units of the network."""
    max_steps: PositiveInt = 300
    """The longest trial."""
    stop_fraction: Fraction = 1.0
    """The trial ends once this fraction of the team is home."""

    def __post_init__(self) -> None:
        r, s = self.robot_radius, self.arena_size
        check(self.max_speed < r, "max_speed", f"must be below robot_radius {r}")
        check(
            self.beacon_margin < s / 2.0,
            "beacon_margin",
            f"{self.beacon_margin} leaves no room in an arena of {s}",
        )
        check(
            self.n_robots * math.pi * (2.0 * r) ** 2 < (s - 4.0 * r) ** 2 / 2.0,
            "n_robots",
            f"{self.n_robots} robots of radius {r} do not fit in an arena of {s}",
        )

    @property
    def diagonal(self) -> float:
        """The arena's diagonal: the longest distance inside it."""
        return math.sqrt(2.0) * self.arena_size


@dataclass
class BeaconHomingTrials(TrialArrays):
    """Per-trial state: the beacon (B, 2), the robots home after the last step
    (B, N), the sum over steps of the team's mean distance to the beacon (B,) and
    that mean distance after the last step (B,)."""

    beacon: np.ndarray
    home: np.ndarray
    distance_sum: np.ndarray
    final_distance: np.ndarray


class BeaconHoming(Task):
    """Beacon homing over a batch of trials (see the module docstring)."""

    name = "beacon_homing"
    config_class = BeaconHomingConfig
    default_generations = 50
    """Enough for a team to home on a beacon in most trials (measured by hand)."""
    sdbc_counterparts = {
        "fraction home": ("Robot is home (F)",),
        "mean distance to the beacon / diagonal": ("Robot-beacon distance (M)",),
        "final distance to the beacon / diagonal": ("Robot-beacon distance (F)",),
    }

    def __init__(self, config: BeaconHomingConfig | None = None) -> None:
        c = self.config = config or BeaconHomingConfig()
        n, s, r = c.n_robots, c.arena_size, c.robot_radius
        self.network = NetworkShape(3, c.n_hidden, 2)
        self.layout = BodyLayout(radii=(r,) * n, controlled=(True,) * n)
        self.max_steps = c.max_steps
        corners = np.array([(0.0, 0.0), (s, 0.0), (s, s), (0.0, s), (0.0, 0.0)])
        self.walls = np.stack([corners[:-1], corners[1:]], axis=1)
        self.extent = (0.0, 0.0, s, s)
        self.characterisation_names = tuple(self.sdbc_counterparts)
        self.description = TaskDescription(
            name=self.name,
            groups=(
                EntityGroupSpec(
                    name="Robot",
                    attributes=("x", "y", "linear speed", "is home"),
                    min_size=n,
                    max_size=n,
                    static=False,
                    geometry=Geometry.CIRCLE,
                ),
                EntityGroupSpec(
                    name="Beacon",
                    attributes=(),
                    min_size=1,
                    max_size=1,
                    static=True,
                    geometry=Geometry.POINT,
                ),
                EntityGroupSpec(
                    name="Wall",
                    attributes=(),
                    min_size=1,
                    max_size=1,
                    static=True,
                    geometry=Geometry.POLYGON,
                ),
            ),
        )
        self._radii = np.full((1, n), r)
        self._not_self = ~np.eye(n, dtype=bool)

    def reset(
        self, rngs: list[np.random.Generator]
    ) -> tuple[BeaconHomingTrials, np.ndarray, np.ndarray]:
        c = self.config
        n, r, s, m = c.n_robots, c.robot_radius, c.arena_size, c.beacon_margin
        b = len(rngs)
        beacon = np.empty((b, 2))
        position = np.empty((b, n, 2))
        angle = np.empty((b, n))
        for t, rng in enumerate(rngs):
            beacon[t] = rng.uniform(m, s - m, 2)
            for i in range(n):
                for _ in range(_MAX_START_DRAWS):
                    p = rng.uniform(2.0 * r, s - 2.0 * r, 2)
                    if all(math.dist(p, q) >= 2.0 * r for q in position[t, :i]):
                        break
                else:
                    raise RuntimeError(f"beacon_homing: no start for robot {i}")
                position[t, i] = p
                angle[t, i] = rng.uniform(-np.pi, np.pi)
        trials = BeaconHomingTrials(
            beacon=beacon,
            home=np.zeros((b, n), dtype=bool),
            distance_sum=np.zeros(b),
            final_distance=np.zeros(b),
        )
        return trials, position, angle

    def _distances(self, trials: BeaconHomingTrials, bodies: BodyState) -> np.ndarray:
        """(B, N) centre distance of every robot to its trial's beacon."""
        offset = trials.beacon[:, None, :] - bodies.position
        return norm(offset[..., 0], offset[..., 1])

    def sensors(self, trials: BeaconHomingTrials, bodies: BodyState) -> np.ndarray:
        c = self.config
        b, n = bodies.angle.shape
        out = np.empty((b, n, 3))
        offset = trials.beacon[:, None, :] - bodies.position
        d = norm(offset[..., 0], offset[..., 1])
        out[..., 0] = normalised_reading(d, c.diagonal)
        out[..., 1] = (
            bearing(offset[..., 0], offset[..., 1], bodies.cos_angle, bodies.sin_angle)
            / np.pi
        )
        _, _, dist = pairwise_offsets(bodies.position)
        edge = np.where(self._not_self, dist - 2.0 * c.robot_radius, np.inf)
        nearest = robot_min(edge, axis=-1)
        out[..., 2] = np.where(
            nearest <= c.neighbour_range,
            normalised_reading(np.maximum(nearest, 0.0), c.neighbour_range),
            1.0,
        )
        return out

    def actuate(
        self, trials: BeaconHomingTrials, bodies: BodyState, outputs: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        return outputs[..., 0] * c.max_speed, (2.0 * outputs[..., 1] - 1.0) * c.max_turn

    def update(
        self, trials: BeaconHomingTrials, bodies: BodyState, step: int
    ) -> np.ndarray:
        c = self.config
        d = self._distances(trials, bodies)
        trials.home = d <= c.home_radius
        trials.final_distance = robot_sum(d) / c.n_robots
        trials.distance_sum += trials.final_distance
        home = robot_sum(trials.home.astype(np.float64))
        return home >= c.stop_fraction * c.n_robots

    def task_state(
        self, trials: BeaconHomingTrials, bodies: BodyState
    ) -> tuple[GroupState, ...]:
        b, n = bodies.angle.shape
        robots = np.empty((b, n, 4))
        robots[..., 0:2] = bodies.position
        robots[..., 2] = bodies.speed
        robots[..., 3] = trials.home
        one = np.ones((1, 1), dtype=bool)
        return (
            GroupState(
                present=np.ones((1, n), dtype=bool),
                attributes=robots,
                centres=bodies.position.copy(),
                radii=self._radii,
            ),
            GroupState(
                present=one,
                attributes=np.empty((1, 1, 0)),
                centres=trials.beacon[:, None, :].copy(),
            ),
            GroupState(
                present=one,
                attributes=np.empty((1, 1, 0)),
                segments=self.walls[None, None],
            ),
        )

    def results(
        self, trials: BeaconHomingTrials, length: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        n, diagonal = c.n_robots, c.diagonal
        home = robot_sum(trials.home.astype(np.float64))
        final = np.minimum(trials.final_distance / diagonal, 1.0)
        fitness = (home + 1.0 - final) / (n + 1.0)
        characterisation = np.stack(
            [
                home / n,
                np.minimum(trials.distance_sum / length / diagonal, 1.0),
                final,
            ],
            axis=1,
        )
        return fitness, characterisation
