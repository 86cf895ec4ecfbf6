"""Aggregation: a team of robots gathers in one cluster (a task beyond the paper).

The authors' own aggregation task (Gomes, Urbano & Christensen 2013, "Evolution of
swarm robotics systems with novelty search", Swarm Intelligence 7): robots start
spread over a square walled arena and must come together, anywhere, and stay
together until the trial ends at ``max_steps``.

Fitness, from the cluster measure of Gauci, Chen, Li, Dodd & Gross 2014
("Self-organized aggregation without computation", IJRR 33), to be maximised:

    u(t) = sum_i |p_i(t) - p_bar(t)|^2 / (4 r^2)         (their eq. 1)
    c    = sum_{t=1}^{tau} t u(t)                        (their eq. 2: later steps
                                                          weigh more)
    F    = 1 - c / (u_max sum_{t=1}^{tau} t),

p_bar the robots' centroid, r the robot radius, tau = ``max_steps`` (every trial
runs to it), and u_max = N (size - 2 r)^2 / (8 r^2) the largest u any placement of
centres in [r, size - r]^2 can have (half the robots in each of two opposite
corners: each coordinate's variance is at most (size - 2 r)^2 / 4), so F is in
[0, 1], 1 only for robots stacked on one point.

Task-specific characterisation (Gomes et al. 2013): the robots' mean distance to
their centroid over ``arena_size``, sampled every ``sample_interval`` steps (25:
steps 25, 50, ..., 500, 20 values), each in [0, 1].

Sensors (inputs, in this order; readings 2 d / range - 1, 1 when nothing is in
range, as in the paper's tasks):
  0..3. ``n_robot_arcs`` arcs: nearest other robot's edge distance per sector
     (sector j centred on bearing -pi + 2 pi j / n: back, right, ahead, left),
     range ``robot_sensor_range``;
  4. robots within ``robot_sensor_range`` (edge to edge): 2 n / (N - 1) - 1;
  5..8. ``n_wall_rays`` wall rays from the robot's edge, range ``wall_ray_range``.

Outputs: speed o0 x ``max_speed``, 0 if o2 > ``stop_threshold``; turn
(2 o1 - 1) x ``max_turn`` radians, applied before the move (the paper's drive).

Choices where the publications are silent, made here:
- The robots are the paper's gate-escape robots (radius, speed, turn, wall rays,
  stop output), with a longer robot range (50) so that they can find each other
  in the larger arena; 5 hidden units give the 68-weight network.
- Start: robot i uniform in [r, size - r]^2, redrawn until its centre is at least
  ``start_separation`` from every earlier robot; then its heading, uniform in
  [-pi, pi). Per robot: position, then heading.
- Task state: Agent (x, y, turning speed = angular velocity, linear speed = |v|),
  Wall (the four walls, static).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated

import numpy as np

from sdbc_sim.arena import (
    WallRays,
    draw_team,
    speed_and_turn,
    square_walls,
    wall_group,
    wall_state,
)
from sdbc_sim.network import NetworkShape
from sdbc_sim.sensors import neighbour_sectors, norm, robot_sum
from sdbc_sim.settings import (
    Field,
    Fraction,
    PositiveFloat,
    PositiveInt,
    check,
    settings,
)
from sdbc_sim.task import BodyLayout, BodyState, Task, TrialArrays
from sdbc_sim.task_state import EntityGroupSpec, Geometry, GroupState, TaskDescription


@settings
class AggregationConfig:
    """Settings of the aggregation task, each with its source."""

    arena_size: PositiveFloat = 250.0
    """Side of the square walled arena (Gomes et al. 2013: 250)."""
    n_robots: Annotated[int, Field(ge=2)] = 8
    """N, robots in the team (Gomes et al. 2013: 8); a cluster needs two."""
    robot_radius: PositiveFloat = 2.5
    """Radius of a robot (the paper's gate escape robots: 2.5)."""
    max_speed: PositiveFloat = 1.0
    """Top speed, units per step (the paper's robots: 1)."""
    max_turn: PositiveFloat = 1.57
    """Largest turn, radians per step (the paper's gate escape: 1.57)."""
    start_separation: PositiveFloat = 20.0
    """Least centre distance between two robots at the start (chosen here: 20, so
    that no robot starts in a cluster)."""
    robot_sensor_range: PositiveFloat = 50.0
    """Range (edge to edge) of the robot arcs and count (chosen here: 50, a fifth
    of the arena)."""
    n_robot_arcs: PositiveInt = 4
    """Robot-sensing arcs (the paper's tasks: 4)."""
    wall_ray_range: PositiveFloat = 5.0
    """Length of a wall ray from the robot's edge (the paper's gate escape: 5)."""
    n_wall_rays: PositiveInt = 4
    """Wall rays (the paper's gate escape: 4)."""
    n_hidden: PositiveInt = 5
    """Hidden units of the network (chosen here: 5, 68 weights)."""
    stop_threshold: Fraction = 0.5
    """Output o2 above this stops the robot (the paper: 0.5)."""
    max_steps: PositiveInt = 500
    """tau, the length of every trial (Gomes et al. 2013: 500)."""
    sample_interval: PositiveInt = 25
    """The characterisation samples every this many steps (Gomes et al. 2013:
    25); ``max_steps`` must be a multiple of it."""

    def __post_init__(self) -> None:
        check(
            self.max_steps % self.sample_interval == 0,
            "max_steps",
            f"{self.max_steps} must be a multiple of sample_interval "
            f"{self.sample_interval}",
        )
        r, s = self.robot_radius, self.arena_size
        check(
            self.max_speed < r,
            "max_speed",
            f"{self.max_speed} must be below the robot radius {r}, or robots could "
            "pass through walls in one step",
        )
        check(
            self.start_separation >= 2.0 * r,
            "start_separation",
            f"{self.start_separation} must be at least a robot's diameter {2.0 * r}",
        )
        # Necessary for the start draws: N discs of radius sep / 2 centred in the
        # start box (side size - 2 r) fit, by area, in the box grown by sep / 2.
        sep, side = self.start_separation, s - 2.0 * r
        check(
            side > 0.0
            and self.n_robots * math.pi * (sep / 2.0) ** 2 <= (side + sep) ** 2,
            "arena_size",
            f"the arena is too small for its robots: arena_size {s} cannot hold "
            f"{self.n_robots} robots of radius {r} at least start_separation {sep} "
            "apart",
        )

    @property
    def n_inputs(self) -> int:
        """Robot arcs, robot count, wall rays."""
        return self.n_robot_arcs + 1 + self.n_wall_rays


@dataclass
class AggregationTrials(TrialArrays):
    """Per-trial state of aggregation.

    Attributes:
        weighted_cost: (B,) sum over steps t of t u(t), u in units of 4 r^2.
        samples: (B, tau / sample_interval) mean distance to the centroid at
            each sampled step, over ``arena_size``.
    """

    weighted_cost: np.ndarray
    samples: np.ndarray


class Aggregation(Task[AggregationTrials]):
    """The aggregation task over a batch of trials."""

    name = "aggregation"
    config_class = AggregationConfig
    default_generations = 500
    """No publication gives a budget for this setup: the paper's gate escape's."""

    def __init__(self, config: AggregationConfig | None = None) -> None:
        c = self.config = config or AggregationConfig()
        n, s, r = c.n_robots, c.arena_size, c.robot_radius
        self.network = NetworkShape(c.n_inputs, c.n_hidden, 3)
        self.layout = BodyLayout(radii=(r,) * n, controlled=(True,) * n)
        self.max_steps = c.max_steps
        n_samples = c.max_steps // c.sample_interval
        self.characterisation_names = tuple(
            f"distance to centroid / size at step {(k + 1) * c.sample_interval}"
            for k in range(n_samples)
        )
        self.walls = square_walls(s)
        self.extent = (0.0, 0.0, s, s)
        self.description = TaskDescription(
            name=self.name,
            groups=(
                EntityGroupSpec(
                    name="Agent",
                    attributes=("x", "y", "turning speed", "linear speed"),
                    min_size=n,
                    max_size=n,
                    static=False,
                    geometry=Geometry.CIRCLE,
                ),
                wall_group(),
            ),
        )
        self._wall_rays = WallRays(
            self.walls, self.extent, c.n_wall_rays, c.wall_ray_range, r
        )
        self._present = np.ones((1, n), dtype=bool)
        self._radii = np.full((1, n), r)
        # u in units of 4 r^2 is sum |p_i - p_bar|^2 / (4 r^2); its bound and the
        # time weights' total fix the scale of F.
        self._cost_scale = 1.0 / (4.0 * r * r)
        self._max_cost = n * (s - 2.0 * r) ** 2 / 2.0 * self._cost_scale
        self._weight_total = c.max_steps * (c.max_steps + 1) / 2.0

    def reset(
        self, rngs: list[np.random.Generator]
    ) -> tuple[AggregationTrials, np.ndarray, np.ndarray]:
        c = self.config
        n, r, s = c.n_robots, c.robot_radius, c.arena_size
        b = len(rngs)
        position = np.empty((b, n, 2))
        angle = np.empty((b, n))
        for t, rng in enumerate(rngs):
            position[t], angle[t] = draw_team(
                rng, n, r, s - r, c.start_separation, [], self.name
            )
        trials = AggregationTrials(
            weighted_cost=np.zeros(b),
            samples=np.zeros((b, c.max_steps // c.sample_interval)),
        )
        return trials, position, angle

    def sensors(self, trials: AggregationTrials, bodies: BodyState) -> np.ndarray:
        c = self.config
        pos = bodies.position
        b, n = bodies.angle.shape
        k = c.n_robot_arcs
        out = np.empty((b, n, c.n_inputs))
        cos_h, sin_h = bodies.cos_angle, bodies.sin_angle
        _, count = neighbour_sectors(
            pos, cos_h, sin_h, c.robot_radius, c.robot_sensor_range, k, out=out
        )
        out[..., k] = count * (2.0 / (n - 1)) - 1.0
        self._wall_rays.read(pos, cos_h, sin_h, out=out, column=k + 1)
        return out

    def actuate(
        self, trials: AggregationTrials, bodies: BodyState, outputs: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        return speed_and_turn(outputs, c.max_speed, c.max_turn, c.stop_threshold)

    def update(
        self, trials: AggregationTrials, bodies: BodyState, step: int
    ) -> np.ndarray:
        c = self.config
        n = c.n_robots
        x, y = bodies.position[..., 0], bodies.position[..., 1]
        ox = x - (robot_sum(x) / n)[:, None]
        oy = y - (robot_sum(y) / n)[:, None]
        cost = robot_sum(ox * ox + oy * oy) * self._cost_scale
        trials.weighted_cost += step * cost
        if step % c.sample_interval == 0:
            spread = robot_sum(norm(ox, oy)) / n / c.arena_size
            trials.samples[:, step // c.sample_interval - 1] = np.minimum(spread, 1.0)
        return np.zeros(x.shape[0], dtype=bool)

    def task_state(
        self, trials: AggregationTrials, bodies: BodyState
    ) -> tuple[GroupState, ...]:
        pos = bodies.position
        agents = bodies.kinematics()
        return (
            GroupState(
                present=self._present,
                attributes=agents,
                centres=pos.copy(),
                radii=self._radii,
            ),
            wall_state(self.walls),
        )

    def results(
        self, trials: AggregationTrials, length: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        fitness = 1.0 - trials.weighted_cost / (self._max_cost * self._weight_total)
        return fitness, trials.samples.copy()


TASK = Aggregation
