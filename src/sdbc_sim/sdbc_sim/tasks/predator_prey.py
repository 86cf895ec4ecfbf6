"""Predator-prey pursuit (Gomes, Mariano & Christensen, ALIFE 2014).

Numbers and their sources: docs/reference-setup.md, "Tasks".

Three predators, evolved, must catch a preprogrammed prey that runs away from them
faster than they can drive. Only teamwork (cornering the prey, closing in from
several sides) catches it.

The prey: at every step, the predators whose edge-to-edge distance d_i lies in
(0, ``flee_distance``) push it away along

    u = sum_i (p_prey - p_i) / |p_prey - p_i| x 1 / d_i,

and it turns to u and moves ``prey_speed`` along it; with no predator that close
(or u = 0, as when two predators close in from opposite sides) it stands still.
Capture: a predator centre within ``capture_distance`` (4) of the prey centre. The
trial ends at capture, when the prey's centre leaves the chase zone
[0, size]^2, or after ``max_steps``.

Fitness (paper, eq. F_p):

    F_p = 2 - t / tau                          if the prey was captured,
    F_p = max(d_i - d_f, 0) / diagonal          otherwise,

t the trial length, tau = ``max_steps``, d_i and d_f the mean predator-prey centre
distance at the start and at the end (d_f capped at the diagonal, as the authors'
code did), diagonal = sqrt(2) size.

Task-specific characterisation (Gomes et al. 2014), each in [0, 1]: captured (0 or
1); t / tau; d_f / diagonal (capped at 1); predator dispersion, the mean over the
trial's steps of the predators' mean distance to their centroid, / (diagonal / 2)
and capped at 1 (the authors' normalisation).

Sensors of predator i (inputs, in this order; as the authors' code, with
distances edge to edge d, read 2 d / size - 1 and not capped, bearings / pi):
  0, 1. the nearest other predator (by centre distance): distance, bearing;
  2, 3. the next one, and so on for every other predator;
  4, 5. the prey: distance, bearing.

Outputs: speed o0 x ``predator_speed``; turn (2 o1 - 1) x ``max_turn`` radians,
applied before the move.

Choices where the paper is silent (from the authors' code, MASE fd13449, where it says):
- Order within a step: the prey decides from the positions before the step, then
  predators and prey move together (one physics step), then capture, then leaving.
  A capture and a leaving at the same step count as a capture.
- Leaving: the centre strictly outside [0, size]^2.
- d_i and d_f are both centre to centre, d_i taken from the bodies before the
  first step (the authors' code took d_i edge to edge, d_f centre to centre); the
  characterisation divides d_f by the diagonal as the paper says (the authors' code:
  the edge-to-edge mean / (diagonal / 2), capped at 1).
- A predator touching the prey (edge distance 0) does not count in u, whose
  weight 1 / d_i it would make infinite (authors' code); capture comes first anyway.
- Start: predators in a row along y = ``predator_start_y``, ``predator_spacing``
  apart, centred on x = size / 2, facing +y; prey uniform in
  [margin, size - margin]^2, facing +x. The prey is the trial's only random draw.
- No walls: predators may wander off; the prey ends the trial if it leaves.
- Bodies collide (the authors' homogeneous setup enabled collisions); the prey has
  the predators' mass, so predators can push it.
- The captured prey leaves the Prey group (and the physics). The task state:
  Predators (x, y, turning speed = angular velocity, linear speed = |v|), Prey
  (same), Boundary (the chase zone's 4 edges, static).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sdbc_sim.compiled import compiled
from sdbc_sim.libm import hypot
from sdbc_sim.network import NetworkShape
from sdbc_sim.sensors import (
    bearing_arguments,
    centroid_spread,
    distance_sum,
    wrap_angle,
)
from sdbc_sim.settings import PositiveFloat, PositiveInt, check, settings
from sdbc_sim.task import (
    KINEMATICS,
    BodyLayout,
    BodyState,
    Task,
    TrialArrays,
    kinematics_and_centre_row,
    kinematics_row,
)
from sdbc_sim.task_state import EntityGroupSpec, Geometry, GroupState, TaskDescription


@settings
class PredatorPreyConfig:
    """Settings of the predator-prey task; defaults from docs/reference-setup.md."""

    arena_size: PositiveFloat = 100.0
    """Side of the square chase zone [0, size]^2 (open: no walls)."""
    n_predators: PositiveInt = 3
    """Predators in the team."""
    predator_radius: PositiveFloat = 1.5
    """Radius of a predator."""
    prey_radius: PositiveFloat = 1.5
    """Radius of the prey."""
    predator_speed: PositiveFloat = 0.5
    """Top speed of a predator, units per step."""
    max_turn: PositiveFloat = 1.57
    """Largest turn of a predator, radians per step."""
    predator_spacing: PositiveFloat = 5.0
    """Distance between neighbouring predators at the start."""
    predator_start_y: float = 0.0
    """The predators start on this line, facing +y."""
    prey_margin: float = 20.0
    """The prey starts uniform in [margin, size - margin]^2."""
    prey_speed: PositiveFloat = 0.75
    """Speed of a fleeing prey, units per step."""
    flee_distance: PositiveFloat = 5.0
    """The prey flees predators closer than this, edge to edge."""
    capture_distance: PositiveFloat = 4.0
    """A predator centre this close to the prey's captures it."""
    n_hidden: PositiveInt = 5
    """Hidden units of the network."""
    max_steps: PositiveInt = 600
    """tau, the longest trial."""

    def __post_init__(self) -> None:
        for speed, radius in (
            ("predator_speed", "predator_radius"),
            ("prey_speed", "prey_radius"),
        ):
            check(
                getattr(self, speed) < getattr(self, radius),
                speed,
                f"{getattr(self, speed)} must be below {radius} "
                f"{getattr(self, radius)}, or bodies could pass through each other "
                "in one step",
            )
        touch = self.predator_radius + self.prey_radius
        check(
            self.capture_distance >= touch,
            "capture_distance",
            f"{self.capture_distance} is below predator_radius + prey_radius "
            f"{touch}: no capture could happen",
        )
        check(
            self.predator_spacing >= 2.0 * self.predator_radius,
            "predator_spacing",
            f"{self.predator_spacing} is below a predator's diameter "
            f"{2.0 * self.predator_radius}",
        )
        s, m = self.arena_size, self.prey_margin
        row = (
            self.n_predators - 1
        ) * self.predator_spacing + 2.0 * self.predator_radius
        check(
            row <= s,
            "arena_size",
            f"the arena is too small for its robots: {self.n_predators} predators "
            f"{self.predator_spacing} apart span {row}, more than arena_size {s}",
        )
        check(
            self.prey_radius <= m <= s / 2.0,
            "prey_margin",
            f"{m} must lie in [prey_radius {self.prey_radius}, arena_size / 2 = "
            f"{s / 2.0}]",
        )
        y = self.predator_start_y
        check(
            not m - touch < y < s - m + touch,
            "predator_start_y",
            f"{y} lets the prey start on a predator: the prey's start box spans y "
            f"in [{m}, {s - m}]",
        )

    @property
    def n_inputs(self) -> int:
        """Distance and bearing to every other predator and to the prey."""
        return 2 * self.n_predators

    @property
    def diagonal(self) -> float:
        """The chase zone's diagonal, sqrt(2) size."""
        return math.sqrt(2.0) * self.arena_size


@dataclass
class PredatorPreyTrials(TrialArrays):
    """Per-trial state of predator-prey.

    Attributes:
        captured: (B,) bool, the prey has been captured.
        initial_distance: (B,) d_i, mean predator-prey centre distance at the start
            (taken before the first step; NaN until then).
        final_distance: (B,) d_f, the same after the last step.
        dispersion_sum: (B,) sum over steps of the predators' mean distance to
            their centroid.
    """

    captured: np.ndarray
    initial_distance: np.ndarray
    final_distance: np.ndarray
    dispersion_sum: np.ndarray


class PredatorPrey(Task[PredatorPreyTrials]):
    """The predator-prey pursuit task over a batch of trials."""

    name = "predator_prey"
    config_class = PredatorPreyConfig
    default_generations = 750
    """Generations of the paper's runs."""
    fitness_range = (0.0, 2.0)
    sdbc_counterparts = {
        "captured": ("Prey group size (F)",),
        "trial length / tau": ("Simulation length",),
        "final predator-prey distance / diagonal": ("Predators-prey distance (F)",),
        "predator dispersion": ("Predators dispersion (M)",),
    }

    def __init__(self, config: PredatorPreyConfig | None = None) -> None:
        c = self.config = config or PredatorPreyConfig()
        n, s = c.n_predators, c.arena_size
        self.network = NetworkShape(c.n_inputs, c.n_hidden, 2)
        self.layout = BodyLayout(
            radii=(c.predator_radius,) * n + (c.prey_radius,),
            controlled=(True,) * n + (False,),
        )
        self.max_steps = c.max_steps
        self.characterisation_names = (
            "captured",
            "trial length / tau",
            "final predator-prey distance / diagonal",
            "predator dispersion",
        )
        self.walls = np.empty((0, 2, 2))
        corners = np.array([(0.0, 0.0), (s, 0.0), (s, s), (0.0, s), (0.0, 0.0)])
        self.boundary = np.stack([corners[:-1], corners[1:]], axis=1)
        half_row = (n - 1) * c.predator_spacing / 2.0
        self.start_x = s / 2.0 + np.linspace(-half_row, half_row, n)
        # No walls: predators can drive predator_speed x max_steps from anywhere
        # they start; the prey never gets farther than one step out of the zone,
        # plus what a push can add.
        reach = max(c.predator_speed, c.prey_speed) * c.max_steps + 2.0 * max(
            c.predator_radius, c.prey_radius
        )
        y0, y1 = min(0.0, c.predator_start_y), max(s, c.predator_start_y)
        self.extent = (-reach, y0 - reach, s + reach, y1 + reach)
        attributes = ("x", "y", "turning speed", "linear speed")
        self.description = TaskDescription(
            name=self.name,
            groups=(
                EntityGroupSpec(
                    name="Predators",
                    attributes=attributes,
                    min_size=n,
                    max_size=n,
                    static=False,
                    geometry=Geometry.CIRCLE,
                ),
                EntityGroupSpec(
                    name="Prey",
                    attributes=attributes,
                    min_size=0,
                    max_size=1,
                    static=False,
                    geometry=Geometry.CIRCLE,
                ),
                EntityGroupSpec(
                    name="Boundary",
                    attributes=(),
                    min_size=1,
                    max_size=1,
                    static=True,
                    geometry=Geometry.POLYGON,
                ),
            ),
        )
        self._predator_present = np.ones((1, n), dtype=bool)
        self._predator_radii = np.full((1, n), c.predator_radius)
        self._prey_radii = np.full((1, 1), c.prey_radius)
        self._boundary_present = np.ones((1, 1), dtype=bool)
        self._boundary_attributes = np.empty((1, 1, 0))
        self._boundary_segments = self.boundary[None, None]

    def reset(
        self, rngs: list[np.random.Generator]
    ) -> tuple[PredatorPreyTrials, np.ndarray, np.ndarray]:
        c = self.config
        n, s, m = c.n_predators, c.arena_size, c.prey_margin
        b = len(rngs)
        position = np.empty((b, n + 1, 2))
        position[:, :n, 0] = self.start_x
        position[:, :n, 1] = c.predator_start_y
        for t, rng in enumerate(rngs):
            position[t, n] = rng.uniform(m, s - m, size=2)
        angle = np.zeros((b, n + 1))
        angle[:, :n] = np.pi / 2.0
        trials = PredatorPreyTrials(
            captured=np.zeros(b, dtype=bool),
            initial_distance=np.full(b, np.nan),
            final_distance=np.full(b, np.nan),
            dispersion_sum=np.zeros(b),
        )
        return trials, position, angle

    def sensors(self, trials: PredatorPreyTrials, bodies: BodyState) -> np.ndarray:
        c = self.config
        n = c.n_predators
        b, r = bodies.angle.shape
        out = np.empty((b, n, c.n_inputs))
        cos_h, sin_h = bodies.cos_angle[:, :n], bodies.sin_angle[:, :n]
        scale = 2.0 / c.arena_size
        dist = np.empty((b, n, r - 1))
        left = np.empty((b, n, r - 1))
        ahead = np.empty((b, n, r - 1))
        _seen_by_predators(
            bodies.position,
            cos_h,
            sin_h,
            dist,
            left,
            ahead,
        )
        # The bearings (sensors.bearing's atan2) stay in numpy: see sdbc_sim.compiled.
        angle = np.arctan2(left, ahead)
        angle *= 1.0 / np.pi
        _predator_readings(
            dist,
            angle,
            2.0 * c.predator_radius,
            c.predator_radius + c.prey_radius,
            scale,
            out,
        )
        return out

    def actuate(
        self, trials: PredatorPreyTrials, bodies: BodyState, outputs: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        n = c.n_predators
        b = outputs.shape[0]
        # The prey's flight, from the positions before the step; d_i from the
        # bodies as the first step finds them (NaN until then).
        ux = np.empty(b)
        uy = np.empty(b)
        _flight(
            bodies.position,
            c.predator_radius + c.prey_radius,
            c.flee_distance,
            trials.initial_distance,
            ux,
            uy,
        )
        target = np.arctan2(uy, ux)
        speed = np.empty((b, n + 1))
        turn = np.empty((b, n + 1))
        _speeds_and_turns(
            outputs,
            bodies.angle,
            ux,
            uy,
            target,
            c.predator_speed,
            c.max_turn,
            c.prey_speed,
            speed,
            turn,
        )
        return speed, turn

    def update(
        self, trials: PredatorPreyTrials, bodies: BodyState, step: int
    ) -> np.ndarray:
        c = self.config
        ends = np.empty(bodies.angle.shape[0], dtype=bool)
        _pursuit(
            bodies.position,
            c.capture_distance,
            c.arena_size,
            trials.captured,
            bodies.enabled,
            trials.final_distance,
            trials.dispersion_sum,
            ends,
        )
        return ends

    def task_state(
        self, trials: PredatorPreyTrials, bodies: BodyState
    ) -> tuple[GroupState, ...]:
        n = self.config.n_predators
        b, r = bodies.angle.shape
        attributes = np.empty((b, r, len(KINEMATICS)))
        centres = np.empty((b, r, 2))
        prey_present = np.empty((b, 1), dtype=bool)
        _body_attributes(
            np.asarray(bodies.position, dtype=np.float64),
            np.asarray(bodies.angular_velocity, dtype=np.float64),
            np.asarray(bodies.velocity, dtype=np.float64),
            bodies.enabled,
            attributes,
            centres,
            prey_present,
        )
        return (
            GroupState(
                present=self._predator_present,
                attributes=attributes[:, :n],
                centres=centres[:, :n],
                radii=self._predator_radii,
            ),
            GroupState(
                present=prey_present,
                attributes=attributes[:, n:],
                centres=centres[:, n:],
                radii=self._prey_radii,
            ),
            GroupState(
                present=self._boundary_present,
                attributes=self._boundary_attributes,
                segments=self._boundary_segments,
            ),
        )

    def results(
        self, trials: PredatorPreyTrials, length: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        diagonal = c.diagonal
        final = np.minimum(trials.final_distance, diagonal)
        time = length / c.max_steps
        fitness = np.where(
            trials.captured,
            2.0 - time,
            np.maximum(trials.initial_distance - final, 0.0) / diagonal,
        )
        characterisation = np.stack(
            [
                trials.captured.astype(np.float64),
                time,
                final / diagonal,
                np.minimum(trials.dispersion_sum / length / (diagonal / 2.0), 1.0),
            ],
            axis=1,
        )
        return fitness, characterisation


TASK = PredatorPrey


@compiled(
    "void(float64[:, :, :], float64[:, :], float64[:, :], float64[:, :, ::1], "
    "float64[:, :, ::1], float64[:, :, ::1])",
    calls=(bearing_arguments,),
)
def _seen_by_predators(
    pos: np.ndarray,
    cos_h: np.ndarray,
    sin_h: np.ndarray,
    dist: np.ndarray,
    left: np.ndarray,
    ahead: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested through PredatorPrey.sensors
    """What each predator i sees ((B, N, R - 1) outputs): the other bodies, the
    other predators in index order and then the prey, as centre distances and
    as offsets rotated into i's frame (the arguments of
    :func:`~sdbc_sim.sensors.bearing`'s atan2, by its operations).

    A compiled loop (:mod:`sdbc_sim.compiled`), as is :func:`_predator_readings`:
    as whole arrays the predators' sensors made some forty numpy calls on
    (B, N) arrays per step; the readings are the array formulation's to the bit
    (``tests/sdbc_sim/tasks/test_predator_prey.py``).
    """
    n = cos_h.shape[1]
    for t in range(pos.shape[0]):
        for i in range(n):
            px = pos[t, i, 0]
            py = pos[t, i, 1]
            c = cos_h[t, i]
            s = sin_h[t, i]
            col = 0
            for j in range(pos.shape[1]):
                if j == i:
                    continue
                dx = pos[t, j, 0] - px
                dy = pos[t, j, 1] - py
                dist[t, i, col] = np.sqrt(dx * dx + dy * dy)
                left[t, i, col], ahead[t, i, col] = bearing_arguments(dx, dy, c, s)
                col += 1


@compiled(
    "void(float64[:, :, ::1], float64[:, :, ::1], float64, float64, float64, "
    "float64[:, :, ::1])"
)
def _predator_readings(
    dist: np.ndarray,
    angle: np.ndarray,
    predator_gap: float,
    prey_gap: float,
    scale: float,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested through PredatorPrey.sensors
    """The predators' inputs from :func:`_seen_by_predators`' distances and the
    bearings / pi: the other predators' edge readings and bearings, nearest
    first, then the prey's. The order is a bubble sort of compare-exchanges
    that swaps only a strictly nearer one, so ties keep index order; it sorts
    the other predators' indices by their distances, and each reading is
    computed once, where it is written (as three arrays sorted alongside, the
    loop took a fifth longer)."""
    m = dist.shape[2] - 1
    order = np.empty(m, dtype=np.intp)
    for t in range(dist.shape[0]):
        for i in range(dist.shape[1]):
            d = dist[t, i]
            for k in range(m):
                order[k] = k
            for end in range(m - 1, 0, -1):
                for j in range(end):
                    if d[order[j + 1]] < d[order[j]]:
                        order[j], order[j + 1] = order[j + 1], order[j]
            for k in range(m):
                other = order[k]
                out[t, i, 2 * k] = max(d[other] - predator_gap, 0.0) * scale - 1.0
                out[t, i, 2 * k + 1] = angle[t, i, other]
            out[t, i, 2 * m] = max(d[m] - prey_gap, 0.0) * scale - 1.0
            out[t, i, 2 * m + 1] = angle[t, i, m]


@compiled(
    "void(float64[:, :, :], float64, float64, float64[::1], float64[::1], float64[::1])"
)
def _flight(
    pos: np.ndarray,
    contact: float,
    flee_distance: float,
    initial_distance: np.ndarray,
    ux: np.ndarray,
    uy: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested through PredatorPrey.actuate
    """The prey's push u = sum_i (p_prey - p_i) / (|p_prey - p_i| d_i) over the
    predators whose edge distance d_i lies in (0, ``flee_distance``), summed in
    predator order from the first term; and d_i, the predators' mean centre
    distance to the prey, where ``initial_distance`` is still NaN."""
    n = pos.shape[1] - 1
    for t in range(pos.shape[0]):
        sx = 0.0
        sy = 0.0
        total = 0.0
        for i in range(n):
            ax = pos[t, n, 0] - pos[t, i, 0]
            ay = pos[t, n, 1] - pos[t, i, 1]
            c = np.sqrt(ax * ax + ay * ay)
            total = c if i == 0 else total + c
            edge = c - contact
            w = 1.0 / (edge * c) if edge > 0.0 and edge < flee_distance else 0.0
            if i == 0:
                sx = ax * w
                sy = ay * w
            else:
                sx += ax * w
                sy += ay * w
        if np.isnan(initial_distance[t]):
            initial_distance[t] = total / n
        ux[t] = sx
        uy[t] = sy


@compiled(
    "void(float64[:, :, :], float64[:, :], float64[::1], float64[::1], "
    "float64[::1], float64, float64, float64, float64[:, ::1], float64[:, ::1])",
    calls=(wrap_angle,),
)
def _speeds_and_turns(
    outputs: np.ndarray,
    angle: np.ndarray,
    ux: np.ndarray,
    uy: np.ndarray,
    target: np.ndarray,
    predator_speed: float,
    max_turn: float,
    prey_speed: float,
    speed: np.ndarray,
    turn: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested through PredatorPrey.actuate
    """Every body's speed and turn (B, N + 1): the predators' from the network's
    ``outputs`` (B, N, 2), the prey's from its push u (:func:`_flight`) and u's
    angle ``target`` (numpy's atan2, :mod:`sdbc_sim.compiled`): a fleeing prey
    (u not 0) turns to ``target`` and moves ``prey_speed``, else stands still. A
    compiled loop: as whole arrays some ten operations per step on (B, N) and
    (B,) arrays, which the loop does in their order; the turn is
    :func:`~sdbc_sim.sensors.wrap_angle` itself, compiled (its ``np.mod`` is the
    C library's exact ``fmod`` and the same sign fix-up in numpy and numba).
    """
    n = outputs.shape[1]
    for t in range(outputs.shape[0]):
        for i in range(n):
            speed[t, i] = outputs[t, i, 0] * predator_speed
            turn[t, i] = (2.0 * outputs[t, i, 1] - 1.0) * max_turn
        flees = ux[t] != 0.0 or uy[t] != 0.0
        speed[t, n] = prey_speed if flees else 0.0
        turn[t, n] = wrap_angle(target[t] - angle[t, n]) if flees else 0.0


@compiled(
    "void(float64[:, :, :], float64, float64, boolean[::1], boolean[:, :], "
    "float64[::1], float64[::1], boolean[::1])",
    calls=(centroid_spread, distance_sum),
)
def _pursuit(
    pos: np.ndarray,
    capture_distance: float,
    size: float,
    captured: np.ndarray,
    enabled: np.ndarray,
    final_distance: np.ndarray,
    dispersion_sum: np.ndarray,
    ends: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested through PredatorPrey.update
    """The rules after a step, per trial: a predator centre within
    ``capture_distance`` of the prey's captures it (``captured``, and the prey's
    body switched off), d_f the predators' mean centre distance to the prey, the
    dispersion sum grows by their mean distance to their centroid, and ``ends``
    at a capture or with the prey's centre outside [0, size]^2; sums in predator
    order from the first term."""
    n = pos.shape[1] - 1
    for t in range(pos.shape[0]):
        qx = pos[t, n, 0]
        qy = pos[t, n, 1]
        caught = False
        total = 0.0
        for i in range(n):
            ox = pos[t, i, 0] - qx
            oy = pos[t, i, 1] - qy
            c = np.sqrt(ox * ox + oy * oy)
            caught = caught or c <= capture_distance
            total = c if i == 0 else total + c
        if caught:
            captured[t] = True
            enabled[t, n] = False
        final_distance[t] = total / n
        dispersion_sum[t] += centroid_spread(pos, t, n) / n
        outside = qx < 0.0 or qy < 0.0 or qx > size or qy > size
        ends[t] = caught or outside


@compiled(
    "void(float64[:, :, :], float64[:, :], float64[:, :, :], boolean[:, :], "
    "float64[:, :, ::1], float64[:, :, ::1], boolean[:, ::1])",
    calls=(kinematics_and_centre_row, kinematics_row, hypot),
)
def _body_attributes(
    position: np.ndarray,
    angular_velocity: np.ndarray,
    velocity: np.ndarray,
    enabled: np.ndarray,
    attributes: np.ndarray,
    centres: np.ndarray,
    prey_present: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested against the array formulation
    """The task state's arrays in one pass: every body's kinematics
    (:meth:`~sdbc_sim.task.BodyState.kinematics`) and centre (a copy of the
    positions), and whether the prey (the last body) is still in the trial. As
    whole arrays: the kinematics' pass and two strided copies per step."""
    prey = position.shape[1] - 1
    for t in range(position.shape[0]):
        for i in range(position.shape[1]):
            kinematics_and_centre_row(
                position, angular_velocity, velocity, attributes, centres, t, i
            )
        prey_present[t, 0] = enabled[t, prey]
