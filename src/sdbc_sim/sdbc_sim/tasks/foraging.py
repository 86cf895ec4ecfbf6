"""Central-place foraging: robots carry items to a nest (a task beyond the paper).

After Liu, Winfield, Sa, Chen & Dou 2007 ("Towards energy optimization: emergent
task allocation in a swarm of foraging robots", Adaptive Behavior 15): items lie
scattered over a square walled arena with the nest at its centre; a robot picks
up an item by touching it, carries one item at a time, and delivers it by
bringing it into the nest, where it disappears. The Item group shrinks with every
delivery (min_size 0), which exercises groups whose membership changes; Nest and
Wall are static groups.

Rules, per step, after the physics step (robot order decides ties):
  pick-up:   a robot that carries nothing and whose centre is within
             ``robot_radius + item_radius`` of a free item's centre picks the
             nearest such item up (one per robot; an item goes to the first
             robot in index order that reaches for it). A carried item rides on
             its robot's centre.
  delivery:  a carrying robot whose centre is within ``nest_radius`` of the nest
             centre delivers its item, which leaves the arena.
A robot can deliver at the step it picks up if it is in the nest. The trial ends
when every item is delivered, or after ``max_steps``.

Fitness, in [0, 1], M items, d delivered, p picked up (d of them delivered), t the
trial length, tau = ``max_steps``:

    F = (d + 0.5 (p - d) + [d = M] (1 - t / tau)) / (M + 1),

each delivery worth 1, an item in transit half (``carry_credit``: without it the
harmonic mean over trials scores almost every early controller at its floor), and
a bonus for delivering everything early, in the manner of the paper's F_g.

Task-specific characterisation (the quantities Liu et al. 2007 track per robot,
as team means), each in [0, 1]: delivered d / M; picked up p / M; time spent
carrying, robot-steps / (N t); time spent in the nest, robot-steps / (N t); mean
centre distance to the nest centre over robots and steps / (arena_size / sqrt 2),
the largest distance from the centre.

Sensors (inputs, in this order; readings 2 d / range - 1, 1 when nothing is in
range, bearings / pi):
  0, 1. nearest free item (centre to centre): distance, range
     ``item_sensor_range``, and bearing (0 when none is in range);
  2, 3. nest centre: distance 2 D / (arena_size / sqrt 2) - 1 and bearing;
  4. carrying: 1 if the robot carries an item, -1 otherwise;
  5..8. ``n_robot_arcs`` arcs: nearest other robot's edge distance per sector,
     range ``robot_sensor_range``;
  9..12. ``n_wall_rays`` wall rays from the robot's edge, range ``wall_ray_range``.

Outputs: speed o0 x ``max_speed``, 0 if o2 > ``stop_threshold``; turn
(2 o1 - 1) x ``max_turn`` radians, applied before the move (the paper's drive).

Choices where Liu et al. 2007 is silent or differs, made here:
- The robots are the paper's gate-escape robots (radius, speed, turn, wall rays,
  stop output); items are not bodies: robots drive over them.
- Liu et al. let items reappear; here there are M items and no more, so the
  Item group shrinks and a trial can finish.
- Start: robot i uniform in [r, size - r]^2, at least ``start_separation`` from
  every earlier robot, then its heading; then item k uniform in
  [item_radius, size - item_radius]^2, at least ``nest_radius + item_radius``
  from the nest centre (no item starts in the nest).
- Task state: Agent (x, y, turning speed = angular velocity, linear speed = |v|,
  is carrying), Item (x, y, is carried; items not yet delivered), Nest (static
  circle), Wall (the four walls, static).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sdbc_sim.arena import (
    WallRays,
    draw_apart,
    draw_team,
    speed_and_turn,
    square_walls,
    wall_group,
    wall_state,
)
from sdbc_sim.compiled import compiled
from sdbc_sim.network import NetworkShape
from sdbc_sim.sensors import (
    bearing,
    neighbour_sectors,
    norm,
    normalised_reading,
    robot_sum,
)
from sdbc_sim.settings import Fraction, PositiveFloat, PositiveInt, check, settings
from sdbc_sim.task import BodyLayout, BodyState, Task, TrialArrays
from sdbc_sim.task_state import EntityGroupSpec, Geometry, GroupState, TaskDescription

_FREE = -1
"""``carrier`` of an item nobody carries."""
_GONE = -2
"""``carrier`` of a delivered item."""


@settings
class ForagingConfig:
    """Settings of the foraging task, each with its source."""

    arena_size: PositiveFloat = 100.0
    """Side of the square walled arena (chosen here: 100)."""
    n_robots: PositiveInt = 5
    """N, robots in the team (Liu et al. 2007's smallest swarm: 5)."""
    n_items: PositiveInt = 15
    """M, items at the start (chosen here: 15, three per robot)."""
    robot_radius: PositiveFloat = 2.5
    """Radius of a robot (the paper's gate escape robots: 2.5)."""
    item_radius: PositiveFloat = 1.0
    """Radius of an item (chosen here: 1)."""
    nest_radius: PositiveFloat = 10.0
    """Radius of the nest at the arena centre (chosen here: 10)."""
    max_speed: PositiveFloat = 1.0
    """Top speed, units per step (the paper's robots: 1)."""
    max_turn: PositiveFloat = 1.57
    """Largest turn, radians per step (the paper's gate escape: 1.57)."""
    start_separation: PositiveFloat = 5.0
    """Least centre distance between two robots at the start (chosen here: a
    robot's diameter, 5)."""
    item_sensor_range: PositiveFloat = 25.0
    """Range of the item sensor, centre to centre (chosen here: 25, the paper's
    robot sensing range)."""
    robot_sensor_range: PositiveFloat = 25.0
    """Range (edge to edge) of the robot arcs (the paper's gate escape: 25)."""
    n_robot_arcs: PositiveInt = 4
    """Robot-sensing arcs (the paper's tasks: 4)."""
    wall_ray_range: PositiveFloat = 5.0
    """Length of a wall ray from the robot's edge (the paper's gate escape: 5)."""
    n_wall_rays: PositiveInt = 4
    """Wall rays (the paper's gate escape: 4)."""
    n_hidden: PositiveInt = 5
    """Hidden units of the network (chosen here: 5)."""
    stop_threshold: Fraction = 0.5
    """Output o2 above this stops the robot (the paper: 0.5)."""
    carry_credit: Fraction = 0.5
    """Fitness credit of an item picked up and not yet delivered, as a fraction
    of a delivery (chosen here: 0.5)."""
    max_steps: PositiveInt = 600
    """tau, the longest trial (chosen here: 600, the paper's predator-prey)."""

    def __post_init__(self) -> None:
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
        # Items must fit between the nest and the walls, and robots in the box.
        sep, side = self.start_separation, s - 2.0 * r
        check(
            self.nest_radius + 2.0 * self.item_radius < s / 2.0
            and side > 0.0
            and self.n_robots * math.pi * (sep / 2.0) ** 2 <= (side + sep) ** 2,
            "arena_size",
            f"the arena is too small: arena_size {s} cannot hold a nest of radius "
            f"{self.nest_radius} with items around it and {self.n_robots} robots "
            f"of radius {r} at least start_separation {sep} apart",
        )

    @property
    def n_inputs(self) -> int:
        """Item, nest, carrying flag, robot arcs, wall rays."""
        return 5 + self.n_robot_arcs + self.n_wall_rays


@dataclass
class ForagingTrials(TrialArrays):
    """Per-trial state of foraging.

    Attributes:
        items: (B, M, 2) item centres (a carried item's is its robot's).
        carrier: (B, M) int, the robot carrying each item, ``_FREE`` or ``_GONE``.
        load: (B, N) int, the item each robot carries, -1 for none.
        picked: (B,) items picked up so far.
        delivered: (B,) items delivered so far.
        carrying_steps: (B,) robot-steps spent carrying.
        nest_steps: (B,) robot-steps spent in the nest.
        nest_distance: (B,) sum over robots and steps of the distance to the nest.
    """

    items: np.ndarray
    carrier: np.ndarray
    load: np.ndarray
    picked: np.ndarray
    delivered: np.ndarray
    carrying_steps: np.ndarray
    nest_steps: np.ndarray
    nest_distance: np.ndarray


class Foraging(Task[ForagingTrials]):
    """The central-place foraging task over a batch of trials."""

    name = "foraging"
    config_class = ForagingConfig
    default_generations = 500
    """No publication gives a budget for this setup: the paper's gate escape's."""
    sdbc_counterparts = {
        "delivered fraction": ("Item group size (F)",),
        "carrying time fraction": ("Agent is carrying (M)",),
        "distance to nest / (size / sqrt 2)": ("Agent-nest distance (M)",),
    }

    def __init__(self, config: ForagingConfig | None = None) -> None:
        c = self.config = config or ForagingConfig()
        n, m, s, r = c.n_robots, c.n_items, c.arena_size, c.robot_radius
        self.network = NetworkShape(c.n_inputs, c.n_hidden, 3)
        self.layout = BodyLayout(radii=(r,) * n, controlled=(True,) * n)
        self.max_steps = c.max_steps
        self.characterisation_names = (
            "delivered fraction",
            "picked up fraction",
            "carrying time fraction",
            "time in nest fraction",
            "distance to nest / (size / sqrt 2)",
        )
        self.walls = square_walls(s)
        self.extent = (0.0, 0.0, s, s)
        self.nest_centre = np.array([s / 2.0, s / 2.0])
        self._far = s / math.sqrt(2.0)
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
                        "is carrying",
                    ),
                    min_size=n,
                    max_size=n,
                    static=False,
                    geometry=Geometry.CIRCLE,
                ),
                EntityGroupSpec(
                    name="Item",
                    attributes=("x", "y", "is carried"),
                    min_size=0,
                    max_size=m,
                    static=False,
                    geometry=Geometry.CIRCLE,
                ),
                EntityGroupSpec(
                    name="Nest",
                    attributes=(),
                    min_size=1,
                    max_size=1,
                    static=True,
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
        self._item_radii = np.full((1, m), c.item_radius)
        self._one = np.ones((1, 1), dtype=bool)
        self._nest_centres = self.nest_centre[None, None, :]
        self._nest_radii = np.full((1, 1), c.nest_radius)

    def reset(
        self, rngs: list[np.random.Generator]
    ) -> tuple[ForagingTrials, np.ndarray, np.ndarray]:
        c = self.config
        n, m, r, s = c.n_robots, c.n_items, c.robot_radius, c.arena_size
        b = len(rngs)
        position = np.empty((b, n, 2))
        angle = np.empty((b, n))
        items = np.empty((b, m, 2))
        nest = [tuple(self.nest_centre.tolist())]
        clear = c.nest_radius + c.item_radius
        ir = c.item_radius
        for t, rng in enumerate(rngs):
            position[t], angle[t] = draw_team(
                rng, n, r, s - r, c.start_separation, [], self.name
            )
            for k in range(m):
                items[t, k] = draw_apart(
                    rng, ir, s - ir, clear, nest, self.name, f"item {k}"
                )
        trials = ForagingTrials(
            items=items,
            carrier=np.full((b, m), _FREE, dtype=np.int64),
            load=np.full((b, n), -1, dtype=np.int64),
            picked=np.zeros(b, dtype=np.int64),
            delivered=np.zeros(b, dtype=np.int64),
            carrying_steps=np.zeros(b, dtype=np.int64),
            nest_steps=np.zeros(b, dtype=np.int64),
            nest_distance=np.zeros(b),
        )
        return trials, position, angle

    def sensors(self, trials: ForagingTrials, bodies: BodyState) -> np.ndarray:
        c = self.config
        pos = bodies.position
        b, n = bodies.angle.shape
        out = np.empty((b, n, c.n_inputs))
        cos_h, sin_h = bodies.cos_angle, bodies.sin_angle
        dn = np.empty((b, n))
        ix = np.empty((b, n))
        iy = np.empty((b, n))
        _nearest_free_items(
            np.ascontiguousarray(trials.items),
            np.ascontiguousarray(trials.carrier),
            pos,
            dn,
            ix,
            iy,
        )
        seen = dn <= c.item_sensor_range
        out[..., 0] = np.where(seen, normalised_reading(dn, c.item_sensor_range), 1.0)
        ib = bearing(ix, iy, cos_h, sin_h)
        out[..., 1] = np.where(seen, ib / np.pi, 0.0)
        nx = self.nest_centre[0] - pos[..., 0]
        ny = self.nest_centre[1] - pos[..., 1]
        out[..., 2] = norm(nx, ny) * (2.0 / self._far) - 1.0
        out[..., 3] = bearing(nx, ny, cos_h, sin_h) / np.pi
        out[..., 4] = np.where(trials.load >= 0, 1.0, -1.0)
        k = c.n_robot_arcs
        neighbour_sectors(
            pos,
            cos_h,
            sin_h,
            c.robot_radius,
            c.robot_sensor_range,
            k,
            out=out,
            column=5,
        )
        self._wall_rays.read(pos, cos_h, sin_h, out=out, column=5 + k)
        return out

    def actuate(
        self, trials: ForagingTrials, bodies: BodyState, outputs: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        return speed_and_turn(outputs, c.max_speed, c.max_turn, c.stop_threshold)

    def update(
        self, trials: ForagingTrials, bodies: BodyState, step: int
    ) -> np.ndarray:
        c = self.config
        pos = bodies.position
        arrays = [trials.items, trials.carrier, trials.load, trials.picked]
        work = [np.ascontiguousarray(a) for a in arrays]
        items, carrier, load, picked = work
        _pick_up_and_carry(
            items,
            carrier,
            load,
            picked,
            pos,
            c.robot_radius + c.item_radius,
        )
        # The loop writes in place; an array that was not contiguous was copied.
        for a, w in zip(arrays, work, strict=True):
            if w is not a:
                a[...] = w
        nest = norm(
            pos[..., 0] - self.nest_centre[0], pos[..., 1] - self.nest_centre[1]
        )
        in_nest = nest <= c.nest_radius
        drops = in_nest & (trials.load >= 0)
        if drops.any():
            t, robot = np.nonzero(drops)
            trials.carrier[t, trials.load[t, robot]] = _GONE
            trials.load[t, robot] = -1
            trials.delivered += robot_sum(drops.astype(np.int64))
        trials.carrying_steps += robot_sum((trials.load >= 0).astype(np.int64))
        trials.nest_steps += robot_sum(in_nest.astype(np.int64))
        trials.nest_distance += robot_sum(nest)
        return trials.delivered == c.n_items

    def task_state(
        self, trials: ForagingTrials, bodies: BodyState
    ) -> tuple[GroupState, ...]:
        pos = bodies.position
        agents = bodies.kinematics(1)
        agents[..., 4] = trials.load >= 0
        items = np.empty((*trials.carrier.shape, 3))
        items[..., 0:2] = trials.items
        items[..., 2] = trials.carrier >= 0
        return (
            GroupState(
                present=self._present,
                attributes=agents,
                centres=pos.copy(),
                radii=self._radii,
            ),
            GroupState(
                present=trials.carrier != _GONE,
                attributes=items,
                centres=trials.items.copy(),
                radii=self._item_radii,
            ),
            GroupState(
                present=self._one,
                attributes=np.empty((1, 1, 0)),
                centres=self._nest_centres,
                radii=self._nest_radii,
            ),
            wall_state(self.walls),
        )

    def results(
        self, trials: ForagingTrials, length: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        m, n = c.n_items, c.n_robots
        d = trials.delivered.astype(np.float64)
        p = trials.picked.astype(np.float64)
        early = np.where(trials.delivered == m, 1.0 - length / c.max_steps, 0.0)
        fitness = (d + c.carry_credit * (p - d) + early) / (m + 1)
        robot_steps = n * length
        characterisation = np.stack(
            [
                d / m,
                p / m,
                trials.carrying_steps / robot_steps,
                trials.nest_steps / robot_steps,
                np.minimum(trials.nest_distance / robot_steps / self._far, 1.0),
            ],
            axis=1,
        )
        return fitness, characterisation


def _nearest_free_item(
    items: np.ndarray, carrier: np.ndarray, t: int, px: float, py: float
) -> tuple[float, int]:  # pragma: no cover - compiled into the loops below
    """The centre distance from (px, py) to trial ``t``'s nearest free item and
    its index: the first of the smallest distances, as ``argmin`` picks it (inf
    and 0 when no item is free). The distance is sqrt(dx dx + dy dy), the IEEE
    operations of :func:`~sdbc_sim.sensors.norm`. Only an item whose squared
    distance is below the best one's can be strictly nearer (sqrt is correctly
    rounded, so monotone), so only those pay for a square root."""
    best = np.inf
    best_squared = np.inf
    nearest = 0
    for k in range(items.shape[1]):
        if carrier[t, k] != _FREE:
            continue
        dx = items[t, k, 0] - px
        dy = items[t, k, 1] - py
        squared = dx * dx + dy * dy
        if squared < best_squared:
            d = np.sqrt(squared)
            if d < best:
                best = d
                nearest = k
            best_squared = squared
    return best, nearest


@compiled(
    "void(float64[:, :, ::1], int64[:, ::1], float64[:, :, :], float64[:, ::1], "
    "float64[:, ::1], float64[:, ::1])",
    calls=(_nearest_free_item,),
)
def _nearest_free_items(
    items: np.ndarray,
    carrier: np.ndarray,
    pos: np.ndarray,
    distance: np.ndarray,
    dx: np.ndarray,
    dy: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested through Foraging.sensors
    """Per robot ((B, N) outputs), the nearest free item's centre distance (inf
    when no item is free) and its offset from the robot's centre.

    A compiled loop (:mod:`sdbc_sim.compiled`): as whole arrays this made (B, N, M)
    offsets and distances at every step, twice; the readings are the array
    formulation's to the bit (``tests/sdbc_sim/tasks/test_foraging.py``).
    """
    for t in range(pos.shape[0]):
        for i in range(pos.shape[1]):
            px = pos[t, i, 0]
            py = pos[t, i, 1]
            distance[t, i], k = _nearest_free_item(items, carrier, t, px, py)
            dx[t, i] = items[t, k, 0] - px
            dy[t, i] = items[t, k, 1] - py


@compiled(
    "void(float64[:, :, ::1], int64[:, ::1], int64[:, ::1], int64[::1], "
    "float64[:, :, :], float64)",
    calls=(_nearest_free_item,),
)
def _pick_up_and_carry(
    items: np.ndarray,
    carrier: np.ndarray,
    load: np.ndarray,
    picked: np.ndarray,
    pos: np.ndarray,
    reach: float,
) -> None:  # pragma: no cover - compiled; tested through Foraging.update
    """The pick-ups of one step, in place: robot by robot in index order, a robot
    that carries nothing takes the nearest free item if its centre is within
    ``reach``, so an item goes to the first robot that reaches for it; then every
    carried item moves to its robot's centre."""
    for t in range(pos.shape[0]):
        for i in range(pos.shape[1]):
            if load[t, i] >= 0:
                continue
            d, k = _nearest_free_item(items, carrier, t, pos[t, i, 0], pos[t, i, 1])
            if d <= reach:
                load[t, i] = k
                carrier[t, k] = i
                picked[t] += 1
        for k in range(items.shape[1]):
            robot = carrier[t, k]
            if robot >= 0:
                items[t, k, 0] = pos[t, robot, 0]
                items[t, k, 1] = pos[t, robot, 1]


TASK = Foraging
