"""The authors' kinematic robots: ``PhysicsSettings(model="kinematic")``.

Gomes et al.'s robots are not rigid bodies (docs/reference-setup.md, "What holds
for every task"). At every step a robot turns, then tries to move by its
commanded displacement. A move that would leave it overlapping a wall or another
robot is refused; the robot then tries to step a quarter turn to one side at
half that speed, then to the other side, and stays where it is if both are
blocked. Robots move one after another, in body order within their trial, each
seeing where the ones before it have moved. Nobody pushes anybody, so no overlap
ever arises, and there is no contact solver to iterate.

Where the authors' code differs:

- The first side tried is always the left (counterclockwise); theirs draws it at
  random, from the simulation's random stream. Drawing it (or the order below)
  would make the physics consume randomness that the task's own draws share in
  their code and not here.
- Both sidesteps go at half the commanded speed; in their code the second goes
  at 0.5 units per step whatever the command.
- Walls are the task's segments, which a robot keeps its radius from. Theirs are
  the arena's box, and in gate escape a gate whose whole opening a robot's centre
  may pass, overlapping the gate's edges.
- Robots move in body order at every step; their scheduler (MASON's) shuffles
  the order of agents at every step.

The sidesteps rotate the displacement by a quarter turn, (dx, dy) to (-dy, dx),
which is exact in floating point, and every test compares squared distances, so
the model uses no transcendental function and no square root: a trial's result
depends on its own arithmetic alone, the same to the bit alone or in any batch.
"""

from __future__ import annotations

import numpy as np

from sdbc_sim import compiled
from sdbc_sim.physics import (
    ANCHOR_MASS_FACTOR,
    DRIVE_COLUMNS,
    READ_WIDTH,
    DriveColumns,
    PhysicsSettings,
    task_geometry,
)
from sdbc_sim.sensors import segment_offset
from sdbc_sim.task import Task

SIDESTEP_SPEED = 0.5
"""A sidestep's speed as a fraction of the commanded one (the authors' code)."""


def wall_boxes(walls: np.ndarray) -> np.ndarray:
    """(P, 4) each wall's bounding box, x low, x high, y low, y high."""
    ends = np.asarray(walls, dtype=np.float64).reshape(-1, 2, 2)
    low, high = ends.min(axis=1), ends.max(axis=1)
    return np.ascontiguousarray(
        np.stack([low[:, 0], high[:, 0], low[:, 1], high[:, 1]], axis=1)
    )


def _blocked(
    state: np.ndarray,
    radii: np.ndarray,
    walls: np.ndarray,
    boxes: np.ndarray,
    collides: np.ndarray,
    first: int,
    i: int,
    x: float,
    y: float,
) -> bool:  # pragma: no cover - compiled into _move; tested through it
    """Whether body ``i`` of the trial whose rows start at ``first`` would
    overlap a wall or another colliding body of its trial with its centre at
    (x, y); touching is allowed.

    A wall whose bounding box (``boxes``, :func:`wall_boxes`) lies more than
    the body's diameter away along an axis is skipped: its true distance then
    exceeds twice the radius, and the rounding of ``segment_offset`` (a few
    ulps of the coordinates) cannot bring its squared offset below the squared
    radius, so the answer is the one the offset would give."""
    r = radii[i]
    reach_wall = r + r
    for q in range(walls.shape[0]):
        if (
            x < boxes[q, 0] - reach_wall
            or x > boxes[q, 1] + reach_wall
            or y < boxes[q, 2] - reach_wall
            or y > boxes[q, 3] + reach_wall
        ):
            continue
        ox, oy = segment_offset(x, y, walls, q)
        if ox * ox + oy * oy < r * r:
            return True
    for j in range(radii.shape[0]):
        if j == i or not collides[first + j]:
            continue
        dx = x - state[first + j, 0]
        dy = y - state[first + j, 1]
        reach = r + radii[j]
        if dx * dx + dy * dy < reach * reach:
            return True
    return False


@compiled.compiled(
    "void(float64[:, ::1], float64[:, ::1], float64[::1], float64[:, :, ::1], "
    "float64[:, ::1], boolean[::1], intp, intp, intp, float64, float64)",
    calls=(_blocked, segment_offset),
)
def _move(
    state: np.ndarray,
    drive: np.ndarray,
    radii: np.ndarray,
    walls: np.ndarray,
    boxes: np.ndarray,
    collides: np.ndarray,
    angle_column: int,
    x_column: int,
    y_column: int,
    dt: float,
    sidestep: float,
) -> None:  # pragma: no cover - compiled; tested against its Python form
    """One step of every trial: each body takes the heading of its drive row and
    moves by its commanded velocity times ``dt``, sideways at ``sidestep`` of it
    to the left, or to the right, or not at all (module docstring). The state
    rows (x, y, angle, vx, vy) get the new centre, the heading, and the
    displacement made over ``dt`` as the velocity."""
    n = radii.shape[0]
    for row in range(state.shape[0]):
        first = row - row % n
        i = row - first
        state[row, 2] = drive[row, angle_column]
        dx = drive[row, x_column] * dt
        dy = drive[row, y_column] * dt
        x = state[row, 0]
        y = state[row, 1]
        if (
            collides[row]
            and (dx != 0.0 or dy != 0.0)
            and _blocked(state, radii, walls, boxes, collides, first, i, x + dx, y + dy)
        ):
            # A quarter turn to the left, then to the right, at reduced speed.
            sx = -dy * sidestep
            sy = dx * sidestep
            dx = 0.0
            dy = 0.0
            for side in (1.0, -1.0):
                to_x = x + side * sx
                to_y = y + side * sy
                if not _blocked(
                    state, radii, walls, boxes, collides, first, i, to_x, to_y
                ):
                    dx = side * sx
                    dy = side * sy
                    break
        state[row, 0] = x + dx
        state[row, 1] = y + dy
        state[row, 3] = dx / dt
        state[row, 4] = dy / dt


class KinematicTrials:
    """All trials of a batch as kinematic robots, stepped by one compiled loop.

    The same interface as :class:`~sdbc_sim.physics.TrialSpaces` (the engine
    picks one by ``PhysicsSettings.model``); the state rows it keeps are the
    bodies' own, so there is nothing to transfer and nothing to project apart.

    Args:
        radii: (R,) body radii of a trial.
        mass: Mass of every body (kept for the engine; nothing here has inertia).
        walls: (P, 2, 2) static segments of a trial, trial-local.
        extent: Box no body centre of a trial can leave, trial-local (unused:
            trials never meet here).
        position: (B, R, 2) initial centres, trial-local.
        angle: (B, R) initial headings.
        settings: Physics settings; ``actuation`` must be "velocity".
    """

    def __init__(
        self,
        radii: np.ndarray,
        mass: float,
        walls: np.ndarray,
        extent: tuple[float, float, float, float],
        position: np.ndarray,
        angle: np.ndarray,
        settings: PhysicsSettings,
    ) -> None:
        del extent
        if settings.actuation != "velocity":
            raise ValueError(
                "physics: the kinematic model moves bodies by their commanded "
                f"velocity; actuation {settings.actuation!r} is not available"
            )
        self.settings = settings
        compiled.load()
        n_trials, n_bodies = angle.shape
        self.n_bodies = n_bodies
        self.live = np.arange(n_trials)
        self._radii = np.ascontiguousarray(radii, dtype=np.float64)
        self._walls = np.ascontiguousarray(walls, dtype=np.float64).reshape(-1, 2, 2)
        self._wall_boxes = wall_boxes(self._walls)
        self._state = np.zeros((n_trials * n_bodies, READ_WIDTH))
        self._state[:, 0:2] = np.asarray(position, dtype=np.float64).reshape(-1, 2)
        self._state[:, 2] = np.asarray(angle, dtype=np.float64).reshape(-1)
        self._collides = np.ones(n_trials * n_bodies, dtype=np.bool_)
        self._mass = mass
        self._masses = np.full(n_trials * n_bodies, mass)

    @classmethod
    def of_task(
        cls,
        task: Task,
        position: np.ndarray,
        angle: np.ndarray,
        settings: PhysicsSettings,
    ) -> KinematicTrials:
        """The trials of a batch of ``task`` starting from ``position`` (B, R, 2)
        and ``angle`` (B, R)."""
        return cls(*task_geometry(task), position, angle, settings)

    @property
    def masses(self) -> np.ndarray:
        """(rows,) mass of every live body."""
        return self._masses

    @property
    def drive_columns(self) -> DriveColumns:
        """The layout of the drive rows :meth:`step` takes."""
        return DRIVE_COLUMNS[self.settings.actuation]

    def read(self, out: np.ndarray) -> None:
        """Fills ``out`` (rows, 5) with x, y, angle, vx, vy per live body."""
        np.copyto(out, self._state)

    def step(self, drive: np.ndarray, state: np.ndarray) -> None:
        """Moves every body once (module docstring) with the headings and
        velocities of ``drive`` (rows, 4, laid out as :attr:`drive_columns`) and
        fills ``state`` as :meth:`read` does."""
        col = self.drive_columns
        _move(
            self._state,
            np.ascontiguousarray(drive),
            self._radii,
            self._walls,
            self._wall_boxes,
            self._collides,
            col.angle,
            col.x,
            col.y,
            self.settings.dt,
            SIDESTEP_SPEED,
        )
        np.copyto(state, self._state)

    def separate(
        self, out: np.ndarray, enabled: np.ndarray, anchored: np.ndarray | None = None
    ) -> None:
        """Nothing to do: a move that would overlap is never made."""

    def anchor(self, trials: np.ndarray, bodies: np.ndarray, on: np.ndarray) -> None:
        """Records anchored bodies' masses as the rigid model does; it changes
        no motion here, where no body pushes another."""
        rows = trials * self.n_bodies + bodies
        self._masses[rows] = np.where(on, ANCHOR_MASS_FACTOR * self._mass, self._mass)

    def disable(self, trials: np.ndarray, bodies: np.ndarray) -> None:
        """Takes bodies out of every collision and stops them where they are:
        ``trials`` are live-row trial indices, ``bodies`` body indices within
        those trials."""
        rows = trials * self.n_bodies + bodies
        self._collides[rows] = False
        self._state[rows, 3:5] = 0.0

    def compact(self, keep: np.ndarray) -> None:
        """Drops the live trials not in ``keep`` ((n_live,) bool)."""
        rows = np.repeat(keep, self.n_bodies)
        self.live = self.live[keep]
        self._state = self._state[rows]
        self._collides = self._collides[rows]
        self._masses = self._masses[rows]
