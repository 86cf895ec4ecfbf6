"""Resource sharing (Gomes, Mariano & Christensen, ALIFE 2014; docs/reference-setup.md).

A team of robots shares a single charging station in the middle of an open arena.
Every robot spends energy at each step, more the faster it drives; a robot that
parks on the station long enough recharges, and a robot out of energy dies. The
station holds one robot at a time, so the team must take turns.

Energy (per robot, per step, in this order), e its energy, k its docked steps:

    drain:     e <- max(0, e - (d_min + (d_max - d_min) s)),  s = speed command / max
    death:     the robot is dead once e = 0 (it stays as an obstacle, still)
    charging:  e <- min(e_max, e + rate)  if docked and k >= delay
    counting:  k <- min(k + 1, delay) if docked, else 0

with d_min = ``min_energy_drain`` (1.05) and d_max = ``max_energy_drain`` (2), so the
drain is 1.05 + 0.95 o0 for a moving robot (o0 its speed output) and 1.05 for a
stopped one. A robot is *docked* when it is alive, its centre lies within
``station_radius - robot_radius`` (1) of the station centre (it is wholly on the
station) and its speed is below ``stationary_speed``; it charges from its
``charge_delay + 1``-th docked step on (after ``charge_delay`` = 5 stationary
steps), gaining ``charge_rate`` (20). The station holds one robot at a time: two
docked centres would be within 2 (station_radius - robot_radius) < 2 robot_radius
of each other, which the settings require.

Fitness (paper, eq. F_s):

    F_s = (s + e_bar / e_max) / (1 + N),

s the survivors at the end, e_bar the mean energy of the N robots over the steps of
the trial (a dead robot counts 0), N the team size.

The deceptive optimum. e_bar averages over the trial's actual length (as the
paper and the authors' code do), so a team that never charges scores more by
dying sooner once its energy is low. Scanning every team whose robots stand still
for w steps and then drive at speed s until they die (w = 0..476, s = 0, 0.05,
..., 1, all 10017 through the engine), the best is w = 200, energy 500 - 200 x 1.05 =
290, then full speed (drain 2): all dead at step 200 + 290 / 2 = 345. Each
robot's energy sums to sum_{k=1}^{200} (500 - 1.05 k) + sum_{j=1}^{145}
(290 - 2 j) = 78895 + 20880 = 99775, so e_bar = 99775 / 345 = 289.20 and
F = 289.20 / 500 / 4 = 0.144601 (w = 199 gives 0.144402, w = 201 0.144383).
Standing still until death (step 477) gives 118797.7 / 477 / 2000 = 0.1245. With
``energy_mean_over="max_steps"`` the w = 200 team scores 99775 / 500 / 2000 =
0.0998, and the best of these teams is standing still (0.1188): waiting to burn
no longer pays.
The harmonic mean over trials makes escaping the plateau fragile: an evolved
charger scored about 0.372 in a trial where a robot charged and 0.122 where none
did (measured in an earlier study), so a controller that charges in 1 of 5 trials
scores 5 / (1 / 0.372 + 4 / 0.122) = 0.141, below the plateau's 0.1446.

Task-specific characterisation (Gomes et al. 2013), each in [0, 1]: survivors s / N;
mean energy / e_max; mean speed / max_speed (capped at 1: a robot can be pushed
faster than it drives); mean centre distance to the station / (arena_size / 2),
capped at 1. The last three are means over the alive robots at every sampled step,
0 if no robot was ever alive at a sample; a step is sampled every
``characterisation_interval`` steps (the authors' code sampled every 10th step).

Sensors (inputs, in this order; readings as in the authors' code):
  0..3. ``n_robot_arcs`` arcs: nearest other robot's edge distance d per sector
     (sector j centred on bearing -pi + 2 pi j / n: back, right, ahead, left),
     2 d / ``robot_sensor_range`` - 1, 1 when no robot is in range; dead robots
     are sensed (they are obstacles);
  4. station centre distance D: 2 D / ``station_sensor_range`` - 1, not capped
     (the arena has no walls; a robot far out still reads how far it is);
  5. station bearing / pi;
  6. own energy: 2 e / e_max - 1;
  7. station flag: 1 if the robot's centre is within ``docking_distance`` (1) of
     the station centre, whatever its speed (``charging_input="in_station"``, the
     authors' cue), or if it charged at the last step (``"charged"``); -1
     otherwise.

Outputs: speed o0 x ``max_speed``, 0 if o2 > ``stop_threshold``; turn
(2 o1 - 1) x ``max_turn`` radians, applied before the move, 0 too when the robot
is told to stop (``stop_freezes_heading``, the authors' code).

Choices where the paper is silent (from the authors' code, MASE fd13449, where it says):
- No walls: the arena is open, as in the authors' code; robots may wander off.
- Start: robot i uniform in [r, size - r]^2 (wholly inside the arena), redrawn until
  its centre is at least ``start_separation`` from the station centre and from every
  earlier robot; then its heading, uniform in [-pi, pi). Per robot: positions, then
  heading.
- "Stationary" is the measured speed after the physics step, below
  ``stationary_speed`` (the authors' 0.001), so a robot pushed off its spot stops
  charging and starts counting again.
- The drain uses the speed command, not the measured speed (authors' code): a robot
  pushing against another pays for the speed it asks for.
- Drain before charging, so a robot can die on the station at its last unit of
  energy; a charging robot at full energy reads e_max.
- The charging input is the authors' "centre on the station" by default
  (``charging_input``); the "is charging" attribute of the task state is "charged
  at this step" (the paper: "whether it is currently charging").
- A stop command freezes the heading (``stop_freezes_heading``), as in the
  authors' code; in gate escape their robots do turn while stopped.
- A teammate can push a docked robot off the station, unless ``anchor_docked``:
  the authors' robots refuse a blocked move, which pymunk's solver has no way to
  do; anchoring makes the docked robot so heavy that the push moves it by about a
  millionth of the pusher's speed. Measured over 200 starts with three robots
  that all drive to the station at full speed and stop on it: push-offs per trial
  fall from 0.58 to 0 and charging robot-steps per trial rise from 141.6 to 277.7
  (tests/sdbc_sim/tasks/test_hand_coded_chargers.py, ``--team``).
- The station's "is occupied" is "some robot charged at this step" (the paper:
  "whether it is currently charging a robot or not").
- A trial ends when every robot is dead, or after ``max_steps``.
- Task state: Agent (x, y, turning speed = angular velocity, linear speed = |v|,
  energy level, is charging; alive robots only), Station (is occupied; a static
  circle of radius ``station_radius`` at the arena centre).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from sdbc_sim.arena import draw_team
from sdbc_sim.compiled import compiled
from sdbc_sim.libm import hypot
from sdbc_sim.network import NetworkShape
from sdbc_sim.sensors import bearing_arguments, neighbour_sectors
from sdbc_sim.settings import (
    Fraction,
    NonNegativeFloat,
    NonNegativeInt,
    PositiveFloat,
    PositiveInt,
    check,
    settings,
)
from sdbc_sim.task import (
    BodyLayout,
    BodyState,
    Task,
    TrialArrays,
    kinematics_and_centre_row,
    kinematics_row,
)
from sdbc_sim.task_state import EntityGroupSpec, Geometry, GroupState, TaskDescription

NO_CHARGE_OPTIMUM = 99775 / 345 / 2000
"""The fitness of the best team that never charges, at the default settings: wait
200 steps, then drive flat out until every robot dies at step 345 (the module
docstring's arithmetic; 0.144601). Resource sharing's plateau: the study's report
counts the runs whose best ends there."""


@settings
class ResourceSharingConfig:
    """Settings of the resource sharing task; defaults from docs/reference-setup.md."""

    arena_size: PositiveFloat = 150.0
    """Side of the square arena (open: no walls)."""
    n_robots: PositiveInt = 3
    """N, robots in the team."""
    robot_radius: PositiveFloat = 4.0
    """Radius of a robot."""
    max_speed: PositiveFloat = 1.0
    """Top speed, units per step."""
    max_turn: PositiveFloat = 0.78
    """Largest turn, radians per step."""
    start_separation: PositiveFloat = 34.0
    """Least centre distance at the start between two robots, and between a robot
    and the station centre."""
    station_radius: PositiveFloat = 5.0
    """Radius of the charging station at the arena centre."""
    max_energy: PositiveFloat = 500.0
    """e_max, the most energy a robot can hold."""
    initial_energy: PositiveFloat = 500.0
    """Energy of every robot at the start (e_max in docs/reference-setup.md)."""
    min_energy_drain: NonNegativeFloat = 1.05
    """Energy spent per step by a stopped robot."""
    max_energy_drain: NonNegativeFloat = 2.0
    """Energy spent per step by a robot at full speed; the drain grows linearly
    with the speed command in between."""
    charge_rate: NonNegativeFloat = 20.0
    """Energy gained per charging step."""
    charge_delay: NonNegativeInt = 5
    """Stationary steps on the station before charging starts."""
    stationary_speed: PositiveFloat = 0.001
    """A robot slower than this (units per step) is stationary."""
    robot_sensor_range: PositiveFloat = 25.0
    """Range (edge to edge) of the robot-sensing arcs."""
    n_robot_arcs: PositiveInt = 4
    """Robot-sensing arcs."""
    station_sensor_range: PositiveFloat = 75.0
    """Station distance that reads 1 (2 D / range - 1)."""
    n_hidden: PositiveInt = 6
    """Hidden units of the network."""
    stop_threshold: Fraction = 0.5
    """Output o2 above this stops the robot."""
    max_steps: PositiveInt = 500
    """tau, the longest trial."""
    characterisation_interval: PositiveInt = 1
    """The task-specific characterisation samples every this many steps (the
    authors' code: 10)."""
    stop_freezes_heading: bool = True
    """A robot told to stop (o2 above ``stop_threshold``) does not turn either, as
    in the authors' code (the paper is silent)."""
    charging_input: Literal["in_station", "charged"] = "in_station"
    """What the last input senses: ``in_station``, the robot's centre within
    ``docking_distance`` (1) of the station centre whatever its speed, as the
    authors' ``distance < resourceRadius - agentRadius``; or ``charged``, the robot
    charged at the last step (the paper's "whether it is currently charging")."""
    energy_mean_over: Literal["trial", "max_steps"] = "trial"
    """The steps e_bar averages over: ``trial``, the steps the trial lasted (the
    paper's and the authors' reading); or ``max_steps``, tau whatever the trial's
    length (the robots count 0 once all are dead), which removes the
    wait-then-burn optimum described in the module docstring."""
    anchor_docked: bool = False
    """A docked robot is anchored (``BodyState.anchored``: a million times heavier,
    left in place by the overlap projection) until it moves, so a teammate cannot
    push it off the station, as the authors' robots refuse a blocked move. Off by
    default: its effect on evolution has not been measured."""

    def __post_init__(self) -> None:
        check(
            self.initial_energy <= self.max_energy,
            "initial_energy",
            f"{self.initial_energy} exceeds max_energy {self.max_energy}",
        )
        check(
            self.max_energy_drain >= self.min_energy_drain,
            "max_energy_drain",
            f"{self.max_energy_drain} is below min_energy_drain "
            f"{self.min_energy_drain}",
        )
        r = self.robot_radius
        check(
            self.max_speed < r,
            "max_speed",
            f"{self.max_speed} must be below the robot radius {r}, or robots could "
            "pass through each other in one step",
        )
        check(
            self.station_radius > r,
            "station_radius",
            f"{self.station_radius} must exceed robot_radius {r}, or no robot fits "
            "on the station",
        )
        check(
            self.station_radius < 2.0 * r,
            "station_radius",
            f"{self.station_radius} must be below a robot's diameter {2.0 * r}, or "
            "the station could hold two robots",
        )
        check(
            self.start_separation >= 2.0 * r,
            "start_separation",
            f"{self.start_separation} must be at least a robot's diameter {2.0 * r}",
        )
        # Necessary for the start draws: the start box (side size - 2 r, centred
        # on the station) reaches sep from the station centre, and N + 1 discs of
        # radius sep / 2 centred in it fit, by area, in the box grown by sep / 2.
        sep, side = self.start_separation, self.arena_size - 2.0 * r
        needed = (self.n_robots + 1) * math.pi * (sep / 2.0) ** 2
        check(
            side > 0.0 and side / math.sqrt(2.0) >= sep and needed <= (side + sep) ** 2,
            "arena_size",
            f"the arena is too small for its robots: arena_size {self.arena_size} "
            f"cannot hold {self.n_robots} robots of radius {r} and the station at "
            f"least start_separation {sep} apart",
        )

    @property
    def n_inputs(self) -> int:
        """Arcs, station distance and bearing, energy, charging flag."""
        return self.n_robot_arcs + 4

    @property
    def docking_distance(self) -> float:
        """Largest centre distance to the station centre at which a robot lies
        wholly on the station (docs/reference-setup.md: 1)."""
        return self.station_radius - self.robot_radius


@dataclass
class ResourceSharingTrials(TrialArrays):
    """Per-trial state of resource sharing.

    Attributes:
        energy: (B, N) energy of each robot; 0 once dead.
        docked_steps: (B, N) int, consecutive docked steps, at most charge_delay.
        charging: (B, N) bool, robots that charged at the last step.
        command: (B, N) speed command of the last step / max_speed, in [0, 1].
        energy_sum: (B,) sum over steps of the N robots' energy (fitness).
        samples: (B,) alive robot samples taken for the characterisation.
        sampled_energy: (B,) sum of the sampled robots' energy.
        sampled_speed: (B,) sum of the sampled robots' speed.
        sampled_distance: (B,) sum of the sampled robots' distance to the station.
    """

    energy: np.ndarray
    docked_steps: np.ndarray
    charging: np.ndarray
    command: np.ndarray
    energy_sum: np.ndarray
    samples: np.ndarray
    sampled_energy: np.ndarray
    sampled_speed: np.ndarray
    sampled_distance: np.ndarray


class ResourceSharing(Task[ResourceSharingTrials]):
    """The resource sharing task over a batch of trials."""

    name = "resource_sharing"
    config_class = ResourceSharingConfig
    default_generations = 750
    """Generations of the paper's runs."""
    sdbc_counterparts = {
        "survivor fraction": ("Agent group size (F)",),
        "mean energy / max energy": ("Agent energy level (M)",),
        "mean speed / max speed": ("Agent linear speed (M)",),
        "distance to station / (size / 2)": ("Agent-station distance (M)",),
    }

    def __init__(self, config: ResourceSharingConfig | None = None) -> None:
        c = self.config = config or ResourceSharingConfig()
        n, s, r = c.n_robots, c.arena_size, c.robot_radius
        self.network = NetworkShape(c.n_inputs, c.n_hidden, 3)
        self.layout = BodyLayout(radii=(r,) * n, controlled=(True,) * n)
        self.max_steps = c.max_steps
        self.characterisation_names = (
            "survivor fraction",
            "mean energy / max energy",
            "mean speed / max speed",
            "distance to station / (size / 2)",
        )
        self.station_centre = np.array([s / 2.0, s / 2.0])
        self.walls = np.empty((0, 2, 2))
        # No walls: a robot can drive max_speed x max_steps beyond the arena.
        reach = c.max_speed * c.max_steps + r
        self.extent = (-reach, -reach, s + reach, s + reach)
        self.description = TaskDescription(
            name=self.name,
            groups=(
                EntityGroupSpec(
                    name="Agent",
                    attributes=(
                        "x",
                        "y",
                        "turning speed",
                        "linear speed",
                        "energy level",
                        "is charging",
                    ),
                    min_size=0,
                    max_size=n,
                    static=False,
                    geometry=Geometry.CIRCLE,
                ),
                EntityGroupSpec(
                    name="Station",
                    attributes=("is occupied",),
                    min_size=1,
                    max_size=1,
                    static=True,
                    geometry=Geometry.CIRCLE,
                ),
            ),
        )
        self._radii = np.full((1, n), r)
        self._station_centres = self.station_centre[None, None, :]
        self._station_radii = np.full((1, 1), c.station_radius)
        self._station_present = np.ones((1, 1), dtype=bool)

    def reset(
        self, rngs: list[np.random.Generator]
    ) -> tuple[ResourceSharingTrials, np.ndarray, np.ndarray]:
        c = self.config
        n, r, s = c.n_robots, c.robot_radius, c.arena_size
        b = len(rngs)
        position = np.empty((b, n, 2))
        angle = np.empty((b, n))
        centre = (s / 2.0, s / 2.0)
        for t, rng in enumerate(rngs):
            position[t], angle[t] = draw_team(
                rng, n, r, s - r, c.start_separation, [centre], self.name
            )
        trials = ResourceSharingTrials(
            energy=np.full((b, n), c.initial_energy),
            docked_steps=np.zeros((b, n), dtype=np.int64),
            charging=np.zeros((b, n), dtype=bool),
            command=np.zeros((b, n)),
            energy_sum=np.zeros(b),
            samples=np.zeros(b, dtype=np.int64),
            sampled_energy=np.zeros(b),
            sampled_speed=np.zeros(b),
            sampled_distance=np.zeros(b),
        )
        return trials, position, angle

    def sensors(self, trials: ResourceSharingTrials, bodies: BodyState) -> np.ndarray:
        c = self.config
        pos = bodies.position
        b, n = bodies.angle.shape
        k = c.n_robot_arcs
        out = np.empty((b, n, c.n_inputs))
        cos_h, sin_h = bodies.cos_angle, bodies.sin_angle
        # Other robots, dead ones too (obstacles); only the few in range.
        neighbour_sectors(
            pos, cos_h, sin_h, c.robot_radius, c.robot_sensor_range, k, out=out
        )
        left = np.empty((b, n))
        ahead = np.empty((b, n))
        _station_readings(
            pos,
            cos_h,
            sin_h,
            trials.energy,
            trials.charging,
            np.array(
                [
                    *self.station_centre,
                    2.0 / c.station_sensor_range,
                    2.0 / c.max_energy,
                    c.docking_distance,
                ]
            ),
            c.charging_input == "in_station",
            out[..., k:],
            left,
            ahead,
        )
        # The bearing's atan2 stays in numpy (sdbc_sim.compiled).
        out[..., k + 1] = np.arctan2(left, ahead) * (1.0 / np.pi)
        return out

    def actuate(
        self, trials: ResourceSharingTrials, bodies: BodyState, outputs: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        trials.command = np.empty(trials.energy.shape)
        speed = np.empty(trials.energy.shape)
        turn = np.empty(trials.energy.shape)
        _commands(
            trials.energy,
            outputs,
            c.stop_threshold,
            c.stop_freezes_heading,
            c.max_speed,
            c.max_turn,
            trials.command,
            speed,
            turn,
        )
        return speed, turn

    def update(
        self, trials: ResourceSharingTrials, bodies: BodyState, step: int
    ) -> np.ndarray:
        c = self.config
        ends = np.empty(trials.energy.shape[0], dtype=bool)
        _energy_rules(
            trials.energy,
            trials.command,
            trials.docked_steps,
            trials.charging,
            bodies.position,
            bodies.velocity,
            np.array(
                [
                    c.min_energy_drain,
                    c.max_energy_drain,
                    *self.station_centre,
                    c.docking_distance,
                    c.stationary_speed,
                    c.charge_rate,
                    c.max_energy,
                ]
            ),
            c.charge_delay,
            step % c.characterisation_interval == 0,
            c.anchor_docked,
            bodies.anchored,
            trials.energy_sum,
            trials.samples,
            trials.sampled_energy,
            trials.sampled_speed,
            trials.sampled_distance,
            ends,
        )
        return ends

    def task_state(
        self, trials: ResourceSharingTrials, bodies: BodyState
    ) -> tuple[GroupState, ...]:
        b, n = trials.energy.shape
        agents = np.empty((b, n, 6))
        present = np.empty((b, n), dtype=bool)
        centres = np.empty((b, n, 2))
        occupied = np.empty((b, 1, 1))
        _agent_attributes(
            np.asarray(bodies.position, dtype=np.float64),
            np.asarray(bodies.angular_velocity, dtype=np.float64),
            np.asarray(bodies.velocity, dtype=np.float64),
            trials.energy,
            trials.charging,
            agents,
            present,
            centres,
            occupied,
        )
        return (
            GroupState(
                present=present,
                attributes=agents,
                centres=centres,
                radii=self._radii,
            ),
            GroupState(
                present=self._station_present,
                attributes=occupied,
                centres=self._station_centres,
                radii=self._station_radii,
            ),
        )

    def results(
        self, trials: ResourceSharingTrials, length: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        n = c.n_robots
        survivors = np.count_nonzero(trials.energy > 0.0, axis=1).astype(np.float64)
        steps = length if c.energy_mean_over == "trial" else c.max_steps
        mean_energy = trials.energy_sum / (n * steps)
        fitness = (survivors + mean_energy / c.max_energy) / (1.0 + n)
        samples = np.maximum(trials.samples, 1)
        characterisation = np.stack(
            [
                survivors / n,
                trials.sampled_energy / samples / c.max_energy,
                np.minimum(trials.sampled_speed / samples / c.max_speed, 1.0),
                np.minimum(
                    trials.sampled_distance / samples / (c.arena_size / 2.0), 1.0
                ),
            ],
            axis=1,
        )
        return fitness, characterisation


@compiled(
    "void(float64[:, :, :], float64[:, :], float64[:, :], float64[:, :], "
    "boolean[:, :], float64[::1], boolean, float64[:, :, :], float64[:, ::1], "
    "float64[:, ::1])",
    calls=(bearing_arguments,),
)
def _station_readings(
    pos: np.ndarray,
    cos_h: np.ndarray,
    sin_h: np.ndarray,
    energy: np.ndarray,
    charging: np.ndarray,
    constants: np.ndarray,
    in_station: bool,
    out: np.ndarray,
    left: np.ndarray,
    ahead: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested against the array formulation
    """Inputs 4 to 7 of every robot (module docstring) into ``out`` (B, N, 4):
    the station distance reading, the bearing's place (its atan2 arguments, the
    station's offset rotated into the robot's frame, go to ``left`` and
    ``ahead``), the energy reading and the station flag. ``constants``: the
    station centre (x, y), 2 / station_sensor_range, 2 / e_max and the docking
    distance. The array formulation's operations, in its order
    (``tests/sdbc_sim/tasks/test_resource_sharing.py``)."""
    cx, cy, distance_scale, energy_scale, dock = constants
    for b in range(pos.shape[0]):
        for r in range(pos.shape[1]):
            sx = cx - pos[b, r, 0]
            sy = cy - pos[b, r, 1]
            d2 = sx * sx
            d2 += sy * sy
            station = np.sqrt(d2)
            c = cos_h[b, r]
            s = sin_h[b, r]
            out[b, r, 0] = station * distance_scale - 1.0
            left[b, r], ahead[b, r] = bearing_arguments(sx, sy, c, s)
            out[b, r, 2] = energy[b, r] * energy_scale - 1.0
            cue = station < dock if in_station else charging[b, r]
            out[b, r, 3] = 1.0 if cue else -1.0


@compiled(
    "void(float64[:, :], float64[:, :], int64[:, :], boolean[:, :], "
    "float64[:, :, :], float64[:, :, :], float64[::1], int64, boolean, boolean, "
    "boolean[:, :], float64[:], int64[:], float64[:], float64[:], float64[:], "
    "boolean[::1])",
    calls=(hypot,),
)
def _energy_rules(
    energy: np.ndarray,
    command: np.ndarray,
    docked_steps: np.ndarray,
    charging: np.ndarray,
    pos: np.ndarray,
    velocity: np.ndarray,
    constants: np.ndarray,
    charge_delay: int,
    sample: bool,
    anchor_docked: bool,
    anchored: np.ndarray,
    energy_sum: np.ndarray,
    samples: np.ndarray,
    sampled_energy: np.ndarray,
    sampled_speed: np.ndarray,
    sampled_distance: np.ndarray,
    ends: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested against the array formulation
    """One step of the energy rules (module docstring: drain, death, charging,
    counting), in place on the (B, N) trial arrays, then the fitness sum, the
    characterisation's samples when ``sample``, and ``ends`` (B,): no robot alive.

    ``constants`` are the drains at rest and at full speed, the station centre
    (x, y), the docking distance, the stationary speed, the charge rate and
    e_max. A compiled loop (:mod:`sdbc_sim.compiled`): as whole arrays these were
    some thirty operations over (B, N) at every step; the loop does each robot's
    operations in their order and sums the robots in index order, as
    ``robot_sum`` does (``tests/sdbc_sim/tasks/test_resource_sharing.py``). A
    robot's speed |v| (``BodyState.speed``, by :func:`sdbc_sim.libm.hypot`)
    is taken only where a rule reads it: for a robot alive on the station, and at
    a sampled step; as a whole array it was a strided ``hypot`` of every robot at
    every step.
    """
    least_drain, most_drain, cx, cy, dock, stationary, rate, most = constants
    for b in range(energy.shape[0]):
        anyone = False
        alive_count = 0
        total = s_energy = s_speed = s_distance = 0.0  # the first robot's, below
        for r in range(energy.shape[1]):
            drain = least_drain + (most_drain - least_drain) * command[b, r]
            e = energy[b, r] - drain
            # np.maximum(e, 0): a NaN stays.
            if not (e >= 0.0 or np.isnan(e)):
                e = 0.0
            alive = e > 0.0
            dx = pos[b, r, 0] - cx
            dy = pos[b, r, 1] - cy
            d2 = dx * dx
            d2 += dy * dy
            distance = np.sqrt(d2)
            near = alive and distance < dock
            speed = (
                hypot(velocity[b, r, 0], velocity[b, r, 1]) if near or sample else 0.0
            )
            docked = near and speed < stationary
            charges = docked and docked_steps[b, r] >= charge_delay
            docked_steps[b, r] = (
                min(docked_steps[b, r] + 1, charge_delay) if docked else 0
            )
            charging[b, r] = charges
            if anchor_docked:
                anchored[b, r] = docked
            e = e + (rate if charges else 0.0)
            # np.minimum(e, e_max): a NaN stays.
            if not (e <= most or np.isnan(e)):
                e = most
            energy[b, r] = e
            on = 1.0 if alive else 0.0
            if r == 0:
                total, s_energy, s_speed, s_distance = (
                    e,
                    e * on,
                    speed * on,
                    distance * on,
                )
            else:
                total += e
                s_energy += e * on
                s_speed += speed * on
                s_distance += distance * on
            anyone = anyone or alive
            alive_count += 1 if alive else 0
        energy_sum[b] += total
        if sample:
            samples[b] += alive_count
            sampled_energy[b] += s_energy
            sampled_speed[b] += s_speed
            sampled_distance[b] += s_distance
        ends[b] = not anyone


@compiled(
    "void(float64[:, :], float64[:, :, :], float64, boolean, float64, float64, "
    "float64[:, ::1], float64[:, ::1], float64[:, ::1])"
)
def _commands(
    energy: np.ndarray,
    outputs: np.ndarray,
    stop_threshold: float,
    stop_freezes_heading: bool,
    max_speed: float,
    max_turn: float,
    command: np.ndarray,
    speed: np.ndarray,
    turn: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested against the array formulation
    """Every robot's speed command / max_speed (module docstring's outputs), speed
    and turn (B, N) from the network's ``outputs`` (B, N, 3): a dead robot, and
    one told to stop, drives 0; it turns unless dead or (``stop_freezes_heading``)
    told to stop. A compiled loop (:mod:`sdbc_sim.compiled`), as whole arrays some
    ten operations over (B, N) at every step; the array formulation's operations
    (``tests/sdbc_sim/tasks/test_resource_sharing.py``)."""
    for b in range(energy.shape[0]):
        for r in range(energy.shape[1]):
            alive = energy[b, r] > 0.0
            go = alive and outputs[b, r, 2] <= stop_threshold
            c = outputs[b, r, 0] if go else 0.0
            command[b, r] = c
            speed[b, r] = c * max_speed
            turning = go if stop_freezes_heading else alive
            turn[b, r] = (2.0 * outputs[b, r, 1] - 1.0) * max_turn if turning else 0.0


@compiled(
    "void(float64[:, :, :], float64[:, :], float64[:, :, :], float64[:, :], "
    "boolean[:, :], float64[:, :, ::1], boolean[:, ::1], float64[:, :, ::1], "
    "float64[:, :, ::1])",
    calls=(kinematics_and_centre_row, kinematics_row, hypot),
)
def _agent_attributes(
    position: np.ndarray,
    angular_velocity: np.ndarray,
    velocity: np.ndarray,
    energy: np.ndarray,
    charging: np.ndarray,
    agents: np.ndarray,
    present: np.ndarray,
    centres: np.ndarray,
    occupied: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested against the array formulation
    """The task state's arrays in one pass: the Agent group's attributes (B, N,
    6), the kinematics (:meth:`~sdbc_sim.task.BodyState.kinematics`), energy and
    "is charging" (1 or 0); its ``present`` (alive) and ``centres`` (a copy of
    the positions); the Station's "is occupied" (B, 1, 1), 1 where some robot
    charged. As whole arrays: a strided copy, the kinematics' pass, two column
    writes, a comparison and a reduction over (B, N) at every step."""
    for t in range(agents.shape[0]):
        anyone = False
        for i in range(agents.shape[1]):
            kinematics_and_centre_row(
                position, angular_velocity, velocity, agents, centres, t, i
            )
            agents[t, i, 4] = energy[t, i]
            agents[t, i, 5] = 1.0 if charging[t, i] else 0.0
            present[t, i] = energy[t, i] > 0.0
            anyone = anyone or charging[t, i]
        occupied[t, 0, 0] = 1.0 if anyone else 0.0


TASK = ResourceSharing
