"""Gate escape (Gomes, Mariano & Christensen, ALIFE 2014; docs/reference-setup.md).

A team of robots in a walled square arena must leave through a gate in the middle
of the left wall. The gate starts closing when the first robot passes and is closed
``gate_closing_steps`` later, which ends the trial; the trial also ends when no
robot is left inside, and after ``max_steps``.

Fitness (paper, eq. F_g): F_g = (g + t / tau) / (1 + N), g robots escaped, t the
trial length, tau = ``max_steps``. The authors' code scored
``w g / N + (1 - w) (1 - t_open / tau)`` (0 if nobody escaped), t_open the step of
the first escape: ``fitness="mase"``.

Task-specific characterisation, each in [0, 1]: escaped fraction g / N; t_open / tau
(1 if the gate never started closing); mean distance of the robots to the gate
centre / arena size; mean distance of the robots to their centroid / (size / 2).
Both means run over every step and every robot, escaped ones included where they
left (as the authors' code did); the last two are capped at 1.

Sensors (inputs, in this order; readings in [-1, 1] as in the authors' code,
2 d / range - 1, 1 when nothing is sensed):
  0. gate centre distance (centre to gate centre), range ``gate_sensor_range``;
     1 when out of range;
  1. gate bearing / pi; 0 when out of range;
  2. robots within ``neighbour_range`` (edge to edge): 2 n / (N - 1) - 1;
  3.. ``n_robot_arcs`` arcs: nearest robot's edge distance per sector (sector j is
     centred on bearing -pi + 2 pi j / n, so 4 arcs look back, right, ahead, left);
  .. ``n_wall_rays`` rays from the robot's edge, the first at -pi / n_rays from the
     heading, then every 2 pi / n_rays; distance to the first wall crossed within
     ``wall_ray_range``.

Outputs: speed o0 x ``max_speed``, 0 if o2 > ``stop_threshold``; turn
(2 o1 - 1) x ``max_turn`` radians, applied before the move.

Choices where the paper is silent (from the authors' code where it says):
- Start: robot i at distance (i + 1) x ``start_spacing`` from the gate centre, at an
  angle drawn uniformly in [0, 2 pi) and redrawn until the robot lies inside the
  arena without touching a wall or an earlier robot; heading uniform in [-pi, pi).
  Per robot: the angle draws, then the heading.
- A robot has escaped once its centre crosses the gate line (x < 0); the walls let
  it cross only through the gate. It then leaves the Agent group, the physics (no
  more contacts, held still where it left) and the other robots' sensors.
- "Is passing gate": the centre is within one radius of the gate line and between
  the gate posts.
- The trial ends at step t_open + ``gate_closing_steps``.
- Task state: Agent (x, y, turning speed = angular velocity, linear speed = |v|,
  is passing gate; robots still inside), Gate (is closing; one segment spanning the
  opening, static), Wall (the walls as segments, the opening left out, static).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from sdbc_sim.arena import (
    RAN_OUT,
    UNDECIDED,
    WallRays,
    apart_from,
    draws_in_bulk,
    speed_and_turn,
    uniform,
    wall_group,
    wall_state,
)
from sdbc_sim.compiled import compiled
from sdbc_sim.libm import hypot
from sdbc_sim.network import NetworkShape
from sdbc_sim.sensors import (
    TWO_PI,
    bearing_arguments,
    centroid_spread,
    distance_sum,
    neighbour_sectors,
)
from sdbc_sim.settings import (
    Fraction,
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

_MAX_START_DRAWS = 100_000
"""Angle draws per robot before a start position counts as impossible."""


@settings
class GateEscapeConfig:
    """Settings of the gate escape task; defaults from docs/reference-setup.md."""

    arena_size: PositiveFloat = 200.0
    """Side of the square arena."""
    gate_width: PositiveFloat = 25.0
    """Width of the gate opening, centred in the left wall."""
    n_robots: PositiveInt = 4
    """N, robots in the team."""
    robot_radius: PositiveFloat = 2.5
    """Radius of a robot."""
    max_speed: PositiveFloat = 1.0
    """Top speed, units per step."""
    max_turn: PositiveFloat = 1.57
    """Largest turn, radians per step."""
    start_spacing: PositiveFloat = 49.375
    """Robot i starts (i + 1) x this from the gate centre."""
    gate_sensor_range: PositiveFloat = 50.0
    """Range of the gate distance and bearing sensor."""
    neighbour_range: PositiveFloat = 25.0
    """Range (edge to edge) of the neighbour count and arcs."""
    n_robot_arcs: PositiveInt = 4
    """Robot-sensing arcs."""
    wall_ray_range: PositiveFloat = 5.0
    """Length of a wall-sensing ray, from the robot's edge."""
    n_wall_rays: PositiveInt = 4
    """Wall-sensing rays."""
    n_hidden: PositiveInt = 7
    """Hidden units of the network."""
    stop_threshold: Fraction = 0.5
    """Output o2 above this stops the robot."""
    gate_closing_steps: NonNegativeInt = 75
    """Steps from the first escape until the gate is closed."""
    max_steps: PositiveInt = 1000
    """tau, the longest trial."""
    fitness: Literal["paper", "mase"] = "paper"
    """"paper" for F_g = (g + t / tau) / (1 + N), "mase" for the authors' code's
    w g / N + (1 - w) (1 - t_open / tau)."""
    mase_escape_weight: Fraction = 0.8
    """w of the "mase" fitness."""

    def __post_init__(self) -> None:
        r, s = self.robot_radius, self.arena_size
        check(
            self.max_speed < r,
            "max_speed",
            f"{self.max_speed} must be below the robot radius {r}, or robots could "
            "pass through walls in one step",
        )
        check(
            2.0 * r < self.gate_width < s,
            "gate_width",
            f"{self.gate_width} must lie between a robot's diameter {2.0 * r} and "
            f"the arena size {s}",
        )
        farthest = math.hypot(s - r, s / 2.0 - r)
        outer = self.n_robots * self.start_spacing
        check(
            self.start_spacing >= 2.0 * r and outer <= farthest,
            "start_spacing",
            f"the arena is too small for its robots: {self.n_robots} robots of "
            f"radius {r} on rings {self.start_spacing} apart need rings at least "
            f"{2.0 * r} apart, the outermost ({outer}) within {farthest:.3f} of the "
            f"gate in a {s} arena",
        )

    @property
    def n_inputs(self) -> int:
        """Gate distance and bearing, neighbour count, arcs, rays."""
        return 3 + self.n_robot_arcs + self.n_wall_rays


@dataclass
class GateEscapeTrials(TrialArrays):
    """Per-trial state of gate escape.

    Attributes:
        escaped: (B, N) bool, robots that have left through the gate.
        open_step: (B,) int, step of the first escape (gate starts closing), -1
            before.
        gate_distance_sum: (B,) sum over steps of the robots' mean distance to
            the gate centre.
        dispersion_sum: (B,) sum over steps of the robots' mean distance to
            their centroid.
    """

    escaped: np.ndarray
    open_step: np.ndarray
    gate_distance_sum: np.ndarray
    dispersion_sum: np.ndarray


class GateEscape(Task[GateEscapeTrials]):
    """The gate escape task over a batch of trials."""

    name = "gate_escape"
    config_class = GateEscapeConfig
    default_generations = 500
    """Generations of the paper's runs."""
    sdbc_counterparts = {
        "escaped fraction": ("Agent group size (F)",),
        # The trial ends a fixed gate_closing_steps after the gate starts closing.
        "gate closing start / tau": ("Simulation length",),
        "distance to gate / size": ("Agent-gate distance (M)",),
        "distance to team centroid / (size / 2)": ("Agent dispersion (M)",),
    }

    def __init__(self, config: GateEscapeConfig | None = None) -> None:
        c = self.config = config or GateEscapeConfig()
        n, s, r = c.n_robots, c.arena_size, c.robot_radius
        self.network = NetworkShape(c.n_inputs, c.n_hidden, 3)
        self.layout = BodyLayout(radii=(r,) * n, controlled=(True,) * n)
        self.max_steps = c.max_steps
        self.characterisation_names = (
            "escaped fraction",
            "gate closing start / tau",
            "distance to gate / size",
            "distance to team centroid / (size / 2)",
        )
        self.gate_centre = np.array([0.0, s / 2.0])
        self.gate_low = s / 2.0 - c.gate_width / 2.0
        self.gate_high = s / 2.0 + c.gate_width / 2.0
        # The authors' wall polygon: from the upper gate post round to the lower one.
        corners = [(0.0, self.gate_high), (0.0, s), (s, s), (s, 0.0), (0.0, 0.0)]
        corners.append((0.0, self.gate_low))
        self.walls = np.array([[corners[i], corners[i + 1]] for i in range(5)])
        self.gate = np.array([[[0.0, self.gate_low], [0.0, self.gate_high]]])
        # Escaped robots stop just outside the gate; leave them room.
        self.extent = (-s / 2.0, 0.0, s, s)
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
                        "is passing gate",
                    ),
                    min_size=0,
                    max_size=n,
                    static=False,
                    geometry=Geometry.CIRCLE,
                ),
                EntityGroupSpec(
                    name="Gate",
                    attributes=("is closing",),
                    min_size=1,
                    max_size=1,
                    static=True,
                    geometry=Geometry.POLYGON,
                ),
                wall_group(),
            ),
        )
        self._wall_rays = WallRays(
            self.walls, (0.0, 0.0, s, s), c.n_wall_rays, c.wall_ray_range, r
        )
        self._radii = np.full((1, n), r)
        self._gate_segments = self.gate[None, None]

    def reset(
        self, rngs: list[np.random.Generator]
    ) -> tuple[GateEscapeTrials, np.ndarray, np.ndarray]:
        c = self.config
        n, r, s = c.n_robots, c.robot_radius, c.arena_size
        b = len(rngs)
        position = np.empty((b, n, 2))
        angle = np.empty((b, n))
        gx, gy = self.gate_centre.tolist()
        for t, rng in enumerate(rngs):
            if self._starts_in_bulk(rng, gx, gy, position[t], angle[t]):
                continue
            placed: list[tuple[float, float]] = []
            for i in range(n):
                ring = (i + 1) * c.start_spacing
                for _ in range(_MAX_START_DRAWS):
                    a = uniform(rng, 0.0, TWO_PI)
                    px, py = gx + ring * math.cos(a), gy + ring * math.sin(a)
                    inside = r <= px <= s - r and r <= py <= s - r
                    if inside and all(
                        math.dist(q, (px, py)) >= 2.0 * r for q in placed
                    ):
                        break
                else:
                    raise RuntimeError(
                        f"gate_escape: no valid start for robot {i} after "
                        f"{_MAX_START_DRAWS} draws"
                    )
                placed.append((px, py))
                angle[t, i] = uniform(rng, -np.pi, np.pi)
            position[t] = placed
        trials = GateEscapeTrials(
            escaped=np.zeros((b, n), dtype=bool),
            open_step=np.full(b, -1, dtype=np.int64),
            gate_distance_sum=np.zeros(b),
            dispersion_sum=np.zeros(b),
        )
        return trials, position, angle

    def _starts_in_bulk(
        self,
        rng: np.random.Generator,
        gx: float,
        gy: float,
        position: np.ndarray,
        heading: np.ndarray,
    ) -> bool:
        """One trial's starts around the gate centre (``gx``, ``gy``), into
        ``position`` (N, 2) and ``heading`` (N,), by
        :func:`~sdbc_sim.arena.draws_in_bulk`, at two fifths of the cost of the
        draw-by-draw loop in Python; False when that loop must decide."""
        c = self.config

        def place(u: np.ndarray) -> int:
            return int(
                _ring_starts(
                    u,
                    gx,
                    gy,
                    c.start_spacing,
                    c.robot_radius,
                    c.arena_size,
                    position,
                    heading,
                )
            )

        return draws_in_bulk(rng, place)

    def sensors(self, trials: GateEscapeTrials, bodies: BodyState) -> np.ndarray:
        c = self.config
        pos = bodies.position
        b, n = bodies.angle.shape
        out = np.empty((b, n, c.n_inputs))
        cos_h, sin_h = bodies.cos_angle, bodies.sin_angle
        # Gate centre; bearings only where it is in range (few robots are), their
        # atan2 in numpy (sdbc_sim.compiled).
        rows = np.empty(b * n, dtype=np.intp)
        left = np.empty(b * n)
        ahead = np.empty(b * n)
        k = _gate_readings(
            pos,
            cos_h,
            sin_h,
            self.gate_centre[0],
            self.gate_centre[1],
            c.gate_sensor_range,
            2.0 / c.gate_sensor_range,
            out,
            rows,
            left,
            ahead,
        )
        if k:
            out.reshape(b * n, -1)[rows[:k], 1] = (
                np.arctan2(left[:k], ahead[:k]) / np.pi
            )
        # Other robots still inside, edge to edge.
        _, count = neighbour_sectors(
            pos,
            cos_h,
            sin_h,
            c.robot_radius,
            c.neighbour_range,
            c.n_robot_arcs,
            enabled=bodies.enabled,
            out=out,
            column=3,
        )
        out[..., 2] = count * (2.0 / max(n - 1, 1)) - 1.0
        self._wall_rays.read(pos, cos_h, sin_h, out=out, column=3 + c.n_robot_arcs)
        return out

    def actuate(
        self, trials: GateEscapeTrials, bodies: BodyState, outputs: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        return speed_and_turn(outputs, c.max_speed, c.max_turn, c.stop_threshold)

    def update(
        self, trials: GateEscapeTrials, bodies: BodyState, step: int
    ) -> np.ndarray:
        ends = np.empty(trials.open_step.shape[0], dtype=bool)
        _escape_rules(
            bodies.position,
            bodies.enabled,
            trials.escaped,
            trials.open_step,
            trials.gate_distance_sum,
            trials.dispersion_sum,
            self.gate_centre[0],
            self.gate_centre[1],
            step,
            self.config.gate_closing_steps,
            ends,
        )
        return ends

    def task_state(
        self, trials: GateEscapeTrials, bodies: BodyState
    ) -> tuple[GroupState, ...]:
        c = self.config
        pos = bodies.position
        agents = np.empty((*bodies.angle.shape, 5))
        centres = np.empty((*bodies.angle.shape, 2))
        _agent_attributes(
            np.asarray(pos, dtype=np.float64),
            np.asarray(bodies.angular_velocity, dtype=np.float64),
            np.asarray(bodies.velocity, dtype=np.float64),
            c.robot_radius,
            self.gate_low,
            self.gate_high,
            agents,
            centres,
        )
        closing = (trials.open_step >= 0).astype(np.float64)[:, None, None]
        return (
            GroupState(
                present=bodies.enabled.copy(),
                attributes=agents,
                centres=centres,
                radii=self._radii,
            ),
            GroupState(
                present=np.ones((1, 1), dtype=bool),
                attributes=closing,
                segments=self._gate_segments,
            ),
            wall_state(self.walls),
        )

    def results(
        self, trials: GateEscapeTrials, length: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        n, tau = c.n_robots, c.max_steps
        escaped = trials.escaped.sum(axis=1).astype(np.float64)
        opened = trials.open_step >= 0
        if c.fitness == "paper":
            fitness = (escaped + length / tau) / (1.0 + n)
        else:
            w = c.mase_escape_weight
            early = 1.0 - trials.open_step / tau
            fitness = np.where(opened, w * escaped / n + (1.0 - w) * early, 0.0)
        characterisation = np.stack(
            [
                escaped / n,
                np.where(opened, trials.open_step / tau, 1.0),
                np.minimum(trials.gate_distance_sum / length / c.arena_size, 1.0),
                np.minimum(trials.dispersion_sum / length / (c.arena_size / 2.0), 1.0),
            ],
            axis=1,
        )
        return fitness, characterisation


@compiled(
    "intp(float64[::1], float64, float64, float64, float64, float64, "
    "float64[:, ::1], float64[::1])",
    calls=(apart_from,),
)
def _ring_starts(
    u: np.ndarray,
    gate_x: float,
    gate_y: float,
    spacing: float,
    radius: float,
    size: float,
    position: np.ndarray,
    heading: np.ndarray,
) -> int:  # pragma: no cover - compiled; tested against the draw-by-draw reset
    """One trial's starts as :meth:`GateEscape.reset` draws them one by one,
    from the doubles ``u`` with the operations of :func:`uniform`: per robot,
    angles on its ring until it lies inside and apart from the robots before
    it, then its heading. Returns the number of doubles used, ``RAN_OUT`` when
    ``u`` is too short, or ``UNDECIDED`` when a distance lies too near the
    diameter for the C library's ``hypot`` to be sure to decide as
    ``math.dist`` does. The angle's cosine and sine are the C library's, as
    Python's ``math.cos`` and ``math.sin`` take them."""
    n = heading.shape[0]
    apart_at = radius + radius
    k = 0
    for i in range(n):
        ring = (i + 1) * spacing
        while True:
            if k >= u.shape[0]:
                return RAN_OUT
            a = 0.0 + (TWO_PI - 0.0) * u[k]
            k += 1
            px = gate_x + ring * math.cos(a)
            py = gate_y + ring * math.sin(a)
            if not (radius <= px <= size - radius and radius <= py <= size - radius):
                continue
            verdict = apart_from(position, i, px, py, apart_at)
            if verdict == UNDECIDED:
                return UNDECIDED
            if verdict:
                break
        if k >= u.shape[0]:
            return RAN_OUT
        position[i, 0] = px
        position[i, 1] = py
        heading[i] = -math.pi + (math.pi - -math.pi) * u[k]
        k += 1
    return k


@compiled(
    "intp(float64[:, :, :], float64[:, :], float64[:, :], float64, float64, float64, "
    "float64, float64[:, :, ::1], intp[::1], float64[::1], float64[::1])",
    calls=(bearing_arguments,),
)
def _gate_readings(
    pos: np.ndarray,
    cos_h: np.ndarray,
    sin_h: np.ndarray,
    gate_x: float,
    gate_y: float,
    sensor_range: float,
    scale: float,
    out: np.ndarray,
    rows: np.ndarray,
    left: np.ndarray,
    ahead: np.ndarray,
) -> int:  # pragma: no cover - compiled; tested against the array formulation
    """The gate sensor's inputs 0 and 1 in ``out`` (B, N, inputs): the centre
    distance reading (``normalised_reading``, 1 out of range) and 0 for the
    bearing; for the K robots in range, in row-major order, their flat row and
    the gate's offset rotated into their frame (:func:`~sdbc_sim.sensors.bearing`'s
    atan2 arguments). Returns K. The array formulation's operations, in its order
    (``tests/sdbc_sim/tasks/test_gate_escape.py``)."""
    n = pos.shape[1]
    k = 0
    for t in range(pos.shape[0]):
        for i in range(n):
            gx = gate_x - pos[t, i, 0]
            gy = gate_y - pos[t, i, 1]
            d2 = gx * gx
            d2 += gy * gy
            d = np.sqrt(d2)
            out[t, i, 1] = 0.0
            if not d <= sensor_range:
                out[t, i, 0] = 1.0
                continue
            out[t, i, 0] = min(d * scale - 1.0, 1.0)
            c = cos_h[t, i]
            s = sin_h[t, i]
            rows[k] = t * n + i
            left[k], ahead[k] = bearing_arguments(gx, gy, c, s)
            k += 1
    return k


@compiled(
    "void(float64[:, :, :], boolean[:, :], boolean[:, :], int64[:], float64[:], "
    "float64[:], float64, float64, int64, int64, boolean[::1])",
    calls=(centroid_spread, distance_sum),
)
def _escape_rules(
    pos: np.ndarray,
    enabled: np.ndarray,
    escaped: np.ndarray,
    open_step: np.ndarray,
    gate_distance_sum: np.ndarray,
    dispersion_sum: np.ndarray,
    gate_x: float,
    gate_y: float,
    step: int,
    closing_steps: int,
    ends: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested against the array formulation
    """One step of the rules (module docstring), in place: a robot still in
    whose centre crossed the gate line (x < 0) has escaped and is switched off,
    and the first escape opens the gate; then the sums of the robots' mean
    distance to the gate centre and to their centroid; ``ends`` (B,): the gate
    closed or every robot out.

    A compiled loop (:mod:`sdbc_sim.compiled`): as whole arrays these were about
    twenty operations over (B, N) at every step; the loop does each robot's
    operations in their order and sums the robots in index order, as
    ``robot_sum`` does (``tests/sdbc_sim/tasks/test_gate_escape.py``).
    """
    n = pos.shape[1]
    for b in range(pos.shape[0]):
        crossed = False
        for r in range(n):
            if enabled[b, r] and pos[b, r, 0] < 0.0:
                escaped[b, r] = True
                enabled[b, r] = False
                crossed = True
        if crossed and open_step[b] < 0:
            open_step[b] = step
        gate_distance_sum[b] += distance_sum(pos, b, n, gate_x, gate_y) / n
        dispersion_sum[b] += centroid_spread(pos, b, n) / n
        everyone = True
        for r in range(n):
            everyone = everyone and escaped[b, r]
        closed = open_step[b] >= 0 and step - open_step[b] >= closing_steps
        ends[b] = closed or everyone


@compiled(
    "void(float64[:, :, :], float64[:, :], float64[:, :, :], float64, float64, "
    "float64, float64[:, :, ::1], float64[:, :, ::1])",
    calls=(kinematics_and_centre_row, kinematics_row, hypot),
)
def _agent_attributes(
    position: np.ndarray,
    angular_velocity: np.ndarray,
    velocity: np.ndarray,
    radius: float,
    gate_low: float,
    gate_high: float,
    out: np.ndarray,
    centres: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested against the array formulation
    """The Agent group's attributes (B, N, 5) in one pass: the kinematics
    (:meth:`~sdbc_sim.task.BodyState.kinematics`), then "is passing gate", 1
    where ``|x| <= radius`` and ``gate_low < y < gate_high``, else 0 (the array
    formulation's comparisons, ``tests/sdbc_sim/tasks/test_gate_escape.py``);
    and the centres (B, N, 2)."""
    for t in range(out.shape[0]):
        for i in range(out.shape[1]):
            kinematics_and_centre_row(
                position, angular_velocity, velocity, out, centres, t, i
            )
            x = position[t, i, 0]
            y = position[t, i, 1]
            passing = abs(x) <= radius and y > gate_low and y < gate_high
            out[t, i, 4] = 1.0 if passing else 0.0


TASK = GateEscape
"""The task this module registers (see :mod:`sdbc_sim.tasks`)."""
