"""What several tasks share beyond the sensors' geometry: walls on the border of a
box, wall-sensing rays, random starts kept apart, and the speed-and-turn drive.

Readings follow :mod:`sdbc_sim.sensors` (2 d / range - 1, 1 when nothing is in
range); everything is batch-first numpy in trial-local coordinates.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from sdbc_sim import compiled as compiled_loops
from sdbc_sim.compiled import compiled
from sdbc_sim.sensors import TWO_PI, ray_distance, readings_out
from sdbc_sim.task_state import EntityGroupSpec, Geometry, GroupState

MAX_START_DRAWS = 100_000
"""Position draws per robot before a start counts as impossible."""


def wall_group() -> EntityGroupSpec:
    """The Wall group: all of a trial's walls as one static polygon, without
    attributes."""
    return EntityGroupSpec(
        name="Wall",
        attributes=(),
        min_size=1,
        max_size=1,
        static=True,
        geometry=Geometry.POLYGON,
    )


def wall_state(walls: np.ndarray) -> GroupState:
    """The Wall group's state: the (P, 2, 2) ``walls``, shared by every trial."""
    return GroupState(
        present=np.ones((1, 1), dtype=bool),
        attributes=np.empty((1, 1, 0)),
        segments=walls[None, None],
    )


def square_walls(size: float) -> np.ndarray:
    """(4, 2, 2) the walls of the square [0, size]^2, counter-clockwise from the
    origin."""
    corners = [(0.0, 0.0), (size, 0.0), (size, size), (0.0, size), (0.0, 0.0)]
    return np.array([[corners[i], corners[i + 1]] for i in range(4)])


class WallRays:
    """Wall-sensing rays of circular robots whose walls all lie on the border of
    a box: ray k starts at the robot's edge at bearing -pi / n + 2 pi k / n and
    reads the distance d to the first wall it crosses within ``ray_range``.

    Rays are cast only for robots close enough to the border for a ray to reach
    it; the others read 1.

    Args:
        walls: (P, 2, 2) wall segments, all on the border of ``box``.
        box: (x_min, y_min, x_max, y_max) that border.
        n_rays: Rays per robot.
        ray_range: Length of a ray, from the robot's edge.
        robot_radius: Radius of every robot.
    """

    def __init__(
        self,
        walls: np.ndarray,
        box: tuple[float, float, float, float],
        n_rays: int,
        ray_range: float,
        robot_radius: float,
    ) -> None:
        # One contiguous (P, 2, 2) float64 copy, the layout the compiled loop takes.
        self.walls = np.ascontiguousarray(walls, dtype=np.float64).reshape(-1, 2, 2)
        self.box = box
        self.n_rays = n_rays
        self.ray_range = ray_range
        self.robot_radius = robot_radius
        arc = TWO_PI / n_rays
        angles = -arc / 2.0 + arc * np.arange(n_rays)
        self._cos = np.cos(angles)
        self._sin = np.sin(angles)
        reach = robot_radius + ray_range
        x0, y0, x1, y1 = box
        # Robots inside this box are beyond every ray's reach of the border.
        self._inner = np.array([x0 + reach, y0 + reach, x1 - reach, y1 - reach])

    def read(
        self,
        pos: np.ndarray,
        cos_heading: np.ndarray,
        sin_heading: np.ndarray,
        out: np.ndarray | None = None,
        column: int = 0,
    ) -> np.ndarray:
        """(B, N, n_rays) readings of robots at ``pos`` (B, N, 2) with headings of
        cosine and sine (B, N); or, given ``out`` (B, N, K), a task's sensor
        array, written into its columns ``column`` onwards and ``out`` returned.

        The loop takes the whole C-ordered array and the first column rather
        than a view of the columns: numba compiles a view whose rows are not
        contiguous with no fixed strides, which cost a quarter of the loop.

        Raises:
            ValueError: If ``out`` is not a C-ordered float64 array of the
                robots' shape with room for the rays from ``column`` on, or
                ``column`` is given without it.
        """
        b, n = cos_heading.shape
        out = readings_out(out, (b, n), self.n_rays, column, "WallRays.read")
        _wall_ray_readings(
            np.asarray(pos, dtype=np.float64).reshape(-1, 2),
            np.ascontiguousarray(cos_heading, dtype=np.float64).reshape(-1),
            np.ascontiguousarray(sin_heading, dtype=np.float64).reshape(-1),
            self._cos,
            self._sin,
            self.robot_radius,
            self.ray_range,
            2.0 / self.ray_range,
            self._inner,
            self.walls,
            out.reshape(b * n, -1),
            column,
        )
        return out


@compiled(
    "void(float64[:, :], float64[::1], float64[::1], float64[::1], float64[::1], "
    "float64, float64, float64, float64[::1], float64[:, :, ::1], float64[:, ::1], "
    "intp)",
    calls=(ray_distance,),
)
def _wall_ray_readings(
    pos: np.ndarray,
    cos_h: np.ndarray,
    sin_h: np.ndarray,
    ray_cos: np.ndarray,
    ray_sin: np.ndarray,
    radius: float,
    ray_range: float,
    scale: float,
    inner: np.ndarray,
    walls: np.ndarray,
    out: np.ndarray,
    column: int,
) -> None:  # pragma: no cover - compiled; tested through WallRays.read
    """Every robot's ray readings, in ``out`` (rows, K) from ``column`` on: 1
    for a robot inside ``inner`` (x_low, y_low, x_high, y_high; no ray reaches
    the border from there), else per ray the reading of
    :func:`~sdbc_sim.sensors.ray_distance` from the robot's edge.

    A compiled loop (:mod:`sdbc_sim.compiled`): as whole arrays the rays of the
    robots near a wall were gathered, rotated, stacked and scattered back at
    every step; the loop does the array formulation's operations in its order
    (``tests/sdbc_sim/test_arena.py``)."""
    for m in range(pos.shape[0]):
        x = pos[m, 0]
        y = pos[m, 1]
        c = cos_h[m]
        s = sin_h[m]
        near = x < inner[0] or x > inner[2] or y < inner[1] or y > inner[3]
        for k in range(ray_cos.shape[0]):
            if not near:
                out[m, column + k] = 1.0
                continue
            ux = c * ray_cos[k] - s * ray_sin[k]
            uy = s * ray_cos[k] + c * ray_sin[k]
            d = ray_distance(x + radius * ux, y + radius * uy, ux, uy, ray_range, walls)
            out[m, column + k] = min(d * scale - 1.0, 1.0) if np.isfinite(d) else 1.0


def speed_and_turn(
    outputs: np.ndarray, max_speed: float, max_turn: float, stop_threshold: float
) -> tuple[np.ndarray, np.ndarray]:
    """The authors' three-output drive: speed o0 x ``max_speed``, 0 if
    o2 > ``stop_threshold``; turn (2 o1 - 1) x ``max_turn``. Each (B, N).

    One compiled pass over the robots rather than six array operations, each
    robot's operations those of ``np.where(o2 > stop_threshold, 0.0, o0 *
    max_speed)`` and ``(2.0 * o1 - 1.0) * max_turn`` in their order
    (``tests/sdbc_sim/test_arena.py``)."""
    shape = outputs.shape[:2]
    speed = np.empty(shape)
    turn = np.empty(shape)
    _speed_and_turn(outputs, max_speed, max_turn, stop_threshold, speed, turn)
    return speed, turn


@compiled(
    "void(float64[:, :, :], float64, float64, float64, float64[:, ::1], "
    "float64[:, ::1])"
)
def _speed_and_turn(
    outputs: np.ndarray,
    max_speed: float,
    max_turn: float,
    stop_threshold: float,
    speed: np.ndarray,
    turn: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested against the array formulation
    """:func:`speed_and_turn` into ``speed`` and ``turn`` (B, N)."""
    for t in range(outputs.shape[0]):
        for i in range(outputs.shape[1]):
            go = outputs[t, i, 0] * max_speed
            speed[t, i] = 0.0 if outputs[t, i, 2] > stop_threshold else go
            turn[t, i] = (2.0 * outputs[t, i, 1] - 1.0) * max_turn


def uniform(rng: np.random.Generator, low: float, high: float) -> float:
    """``rng.uniform(low, high)`` to the bit, from the same double u of the
    stream: low + (high - low) u, as numpy computes it, without its argument
    handling, which was most of the cost of a trial's start."""
    return low + (high - low) * rng.random()


def draw_team(
    rng: np.random.Generator,
    n: int,
    low: float,
    high: float,
    separation: float,
    taken: list[tuple[float, float]],
    task: str,
) -> tuple[np.ndarray, np.ndarray]:
    """Starts of ``n`` robots: per robot, a position from :func:`draw_apart` (kept
    ``separation`` from ``taken`` and from the earlier robots; appended to
    ``taken``), then a heading uniform in [-pi, pi).

    Returns:
        (n, 2) positions and (n,) headings.
    """
    position = np.empty((n, 2))
    heading = np.empty(n)
    if not _draw_team_in_bulk(rng, low, high, separation, taken, position, heading):
        for i in range(n):
            p = draw_apart(rng, low, high, separation, taken, task, f"robot {i}")
            taken.append(p)
            position[i] = p
            heading[i] = uniform(rng, -np.pi, np.pi)
    return position, heading


RAN_OUT = -1
"""What a bulk loop returns when its doubles run out."""
UNDECIDED = -2
"""What a bulk loop returns at a close call, left to the draw-by-draw path."""
CLOSE_CALL = 1e-9
"""Relative distance from ``separation`` within which the bulk path leaves the
decision to ``math.dist``."""


_BULK_DRAWS = (32, 256, 4096)
"""Doubles drawn at once by :func:`draws_in_bulk`, tried in turn; a start that
needs more takes the draw-by-draw path."""


def draws_in_bulk(rng: np.random.Generator, place: Callable[[np.ndarray], int]) -> bool:
    """Runs ``place`` on doubles of ``rng`` drawn in one call, a compiled loop
    that makes a trial's draw-by-draw start from them and returns how many it
    used, ``RAN_OUT`` when they are too few, or ``UNDECIDED`` at a close call.
    The generator's state is saved first and restored after, then exactly the
    doubles used are drawn again, so the stream it leaves (any buffered
    half-word included) is that of the draw-by-draw path. False, with ``rng``
    as it was, when ``place`` runs out of the most doubles tried or leaves a
    decision to the caller, which then draws one by one; False at once where the
    compiled loops are not loaded: a process that never steps the physics does
    not load numba for a trial's start."""
    if not compiled_loops.loaded():
        return False
    bit_generator = rng.bit_generator
    saved = bit_generator.state
    for size in _BULK_DRAWS:
        used = place(rng.random(size))
        bit_generator.state = saved
        if used == UNDECIDED:
            return False
        if used >= 0:
            rng.random(used)
            return True
    return False


def _draw_team_in_bulk(
    rng: np.random.Generator,
    low: float,
    high: float,
    separation: float,
    taken: list[tuple[float, float]],
    position: np.ndarray,
    heading: np.ndarray,
) -> bool:
    """:func:`draw_team` by :func:`draws_in_bulk`, which costs a third of drawing
    the doubles one by one with the rejections in Python. A close call is a
    distance too near ``separation`` for the C library's ``hypot`` to be sure
    to decide as Python's ``math.dist`` does (each is within an ulp of the
    exact distance). Nothing is written to ``taken`` unless it succeeds."""
    points = np.array(taken, dtype=np.float64).reshape(-1, 2)

    def place(u: np.ndarray) -> int:
        return int(
            _team_from_draws(u, low, high, separation, points, position, heading)
        )

    if not draws_in_bulk(rng, place):
        return False
    taken.extend(map(tuple, position.tolist()))
    return True


def apart_from(
    points: np.ndarray, m: int, x: float, y: float, separation: float
) -> int:  # pragma: no cover - compiled into the bulk start loops
    """Whether (x, y) lies at least ``separation`` from each of the first ``m``
    rows of ``points``, as ``math.dist`` would decide it: 1 if so, 0 if not,
    ``UNDECIDED`` when a distance, checked in row order, lies too near
    ``separation`` for the C library's ``hypot`` to be sure to decide alike."""
    for q in range(m):
        d = math.hypot(points[q, 0] - x, points[q, 1] - y)
        if abs(d - separation) <= CLOSE_CALL * separation:
            return UNDECIDED
        if d < separation:
            return 0
    return 1


@compiled(
    "intp(float64[::1], float64, float64, float64, float64[:, ::1], "
    "float64[:, ::1], float64[::1])",
    calls=(apart_from,),
)
def _team_from_draws(
    u: np.ndarray,
    low: float,
    high: float,
    separation: float,
    taken: np.ndarray,
    position: np.ndarray,
    heading: np.ndarray,
) -> int:  # pragma: no cover - compiled; tested against draw-by-draw draw_team
    """The team :func:`draw_team` draws from the doubles ``u``, with the
    operations of :func:`uniform`: the number of doubles used, ``RAN_OUT``
    when ``u`` is too short, or ``UNDECIDED`` at a close call."""
    n = heading.shape[0]
    m = taken.shape[0]
    points = np.empty((m + n, 2))
    points[:m] = taken
    k = 0
    for i in range(n):
        while True:
            if k + 3 > u.shape[0]:
                return RAN_OUT
            x = low + (high - low) * u[k]
            y = low + (high - low) * u[k + 1]
            k += 2
            verdict = apart_from(points, m, x, y, separation)
            if verdict == UNDECIDED:
                return UNDECIDED
            if verdict:
                break
        points[m, 0] = x
        points[m, 1] = y
        m += 1
        position[i, 0] = x
        position[i, 1] = y
        # uniform(rng, -pi, pi)'s operations.
        heading[i] = -math.pi + (math.pi - -math.pi) * u[k]
        k += 1
    return k


def draw_apart(
    rng: np.random.Generator,
    low: float,
    high: float,
    separation: float,
    taken: list[tuple[float, float]],
    task: str,
    what: str,
) -> tuple[float, float]:
    """A point uniform in [low, high]^2 (x then y from ``rng``), redrawn until it
    is at least ``separation`` from every point of ``taken``.

    Raises:
        ValueError: Naming ``task`` and ``what`` after ``MAX_START_DRAWS`` draws.
    """
    for _ in range(MAX_START_DRAWS):
        p = (uniform(rng, low, high), uniform(rng, low, high))
        if all(math.dist(q, p) >= separation for q in taken):
            return p
    raise ValueError(
        f"{task}: the arena is too small for its robots: no start for {what} at "
        f"least {separation} from the others after {MAX_START_DRAWS} draws"
    )
