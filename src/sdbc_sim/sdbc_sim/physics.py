"""Many trials in a few pymunk Spaces, with state moved in bulk (``pymunk.batch``).

A batch of trials is split into Spaces of at most ``trials_per_space`` trials, each
trial in its own *slot*: a square of side ``spacing`` (a power of two) far larger
than anything in the trial, so bodies of different trials never meet. Every slot
lies in [2^16, 2^17) in x and y, so every world coordinate has the same float
exponent and a trial's arithmetic is the same to the bit in any slot; slot corners
and the spatial-hash cell size are powers of two, so the hash cells line up the same
way relative to every trial.

Bit-for-bit independence from batch-mates also needs chipmunk to meet a trial's
contacts in the same order whatever else is in the Space. Robot shapes are added
before any wall, so their hash ids are 0..n-1 in row order, below the size of
chipmunk's handle set; the set then iterates them in row order, and two robots of a
trial always meet in the same order and orientation. ``Space.threads`` is never used.

A finished trial's bodies are removed from its Space when the engine compacts;
chipmunk then reorders its body list, so the mapping from a Space's body order to
the engine's rows is read back (``BODY_ID``) after every compaction.
"""

from __future__ import annotations

import atexit
import gc
import math
from dataclasses import dataclass

import numpy as np
import pymunk
import pymunk.batch as pb

_READ = pb.BodyFields.POSITION | pb.BodyFields.ANGLE | pb.BodyFields.VELOCITY
_WRITE = pb.BodyFields.ANGLE | pb.BodyFields.ANGULAR_VELOCITY | pb.BodyFields.FORCE
_IDS = pb.BodyFields.BODY_ID
READ_WIDTH = 5
"""Columns of a state row: x, y, angle, vx, vy."""
WRITE_WIDTH = 4
"""Columns of a drive row: angle, angular velocity, force x, force y."""
_WORLD_ORIGIN = 2.0**16
"""Every slot lies in [2^16, 2^17): one float exponent for all world coordinates."""
_NO_CONTACT = pymunk.ShapeFilter(categories=0)

# Spaces left in reference cycles would otherwise be freed during interpreter
# shutdown, after pymunk's callbacks are gone (it then prints a warning per call).
atexit.register(gc.collect)


@dataclass(frozen=True)
class PhysicsSettings:
    """How trials are laid out in pymunk and how pymunk steps them.

    Attributes:
        trials_per_space: Most trials in one Space. Chipmunk's cost per body grows
            past a few hundred trials per Space (cache); ``bench/engine.py
            --sweep`` measures it.
        dt: Physics time per control step; speeds are then in units per step.
        iterations: Contact solver iterations per step.
        collision_slop: Overlap chipmunk tolerates before it pushes bodies apart;
            well under 5% of the smallest radius.
        friction: Friction of bodies and walls; 0 lets a robot slide along a wall,
            like the authors' robots, which retry a blocked move sideways.
        hash_cell: Spatial hash cell size, a power of two; None picks the smallest
            power of two at least the largest body diameter.
        hash_cells_per_trial: Hash table cells per trial of a Space.
    """

    trials_per_space: int = 250
    dt: float = 1.0
    iterations: int = 10
    collision_slop: float = 0.01
    friction: float = 0.0
    hash_cell: float | None = None
    hash_cells_per_trial: int = 64

    def __post_init__(self) -> None:
        if self.trials_per_space < 1:
            raise ValueError(
                f"physics: trials_per_space must be >= 1, got {self.trials_per_space}"
            )
        if not (math.isfinite(self.dt) and self.dt > 0.0):
            raise ValueError(f"physics: dt must be positive, got {self.dt}")
        if self.iterations < 1:
            raise ValueError(f"physics: iterations must be >= 1, got {self.iterations}")
        if not (math.isfinite(self.collision_slop) and self.collision_slop >= 0.0):
            raise ValueError(
                f"physics: collision_slop must be >= 0, got {self.collision_slop}"
            )
        if not (math.isfinite(self.friction) and self.friction >= 0.0):
            raise ValueError(f"physics: friction must be >= 0, got {self.friction}")
        if self.hash_cell is not None and not _is_power_of_two(self.hash_cell):
            raise ValueError(
                f"physics: hash_cell must be a power of two, got {self.hash_cell}"
            )
        if self.hash_cells_per_trial < 1:
            raise ValueError(
                "physics: hash_cells_per_trial must be >= 1, got "
                f"{self.hash_cells_per_trial}"
            )


def _is_power_of_two(x: float) -> bool:
    m, _ = math.frexp(x)
    return x > 0.0 and m == 0.5


def _next_power_of_two(x: float) -> float:
    return 2.0 ** math.ceil(math.log2(x))


@dataclass(frozen=True)
class SlotGrid:
    """Where trial slots sit in world coordinates.

    Attributes:
        spacing: Side of a slot, a power of two.
        columns: Slots per row (and most rows) of a Space.
        origin: (2,) trial-local point mapped to the slot corner plus this; the
            offset of a slot is corner + origin, a multiple of the hash cell.
    """

    spacing: float
    columns: int
    origin: np.ndarray

    @classmethod
    def fit(
        cls, extent: tuple[float, float, float, float], margin: float, cell: float
    ) -> SlotGrid:
        """The tightest grid whose slots hold ``extent`` plus ``margin``."""
        x0, y0, x1, y1 = extent
        if not (x1 > x0 and y1 > y0):
            raise ValueError(f"physics: empty extent {extent}")
        side = max(x1 - x0, y1 - y0) + 2.0 * margin
        spacing = max(_next_power_of_two(side), cell)
        columns = int(_WORLD_ORIGIN // spacing)
        if columns < 1:
            raise ValueError(f"physics: extent {extent} is too large for one slot")
        origin = np.array(
            [
                cell * math.ceil((margin - x0) / cell),
                cell * math.ceil((margin - y0) / cell),
            ]
        )
        return cls(spacing=spacing, columns=columns, origin=origin)

    @property
    def capacity(self) -> int:
        """Most slots one Space can hold."""
        return self.columns * self.columns

    def offset(self, slot: int) -> np.ndarray:
        """(2,) world offset of a slot: world = offset + local."""
        col, row = slot % self.columns, slot // self.columns
        return (
            _WORLD_ORIGIN
            + np.array([col, row], dtype=np.float64) * self.spacing
            + self.origin
        )


class _Space:
    """One pymunk Space and the bookkeeping of its trials."""

    def __init__(self, trial_ids: list[int]) -> None:
        self.space = pymunk.Space()
        self.trial_ids = trial_ids
        self.bodies: dict[int, list[pymunk.Body]] = {}
        self.shapes: dict[int, list[pymunk.Circle]] = {}
        self.perm: np.ndarray | None = None
        self.read_buf = pb.Buffer()
        self.write_buf = pb.Buffer()
        self.write = np.zeros((0, WRITE_WIDTH))
        self.n_extra = 0

    @property
    def n_dynamic(self) -> int:
        return sum(len(b) for b in self.bodies.values())

    def attach_write(self) -> None:
        """Counts the Space's bodies (dynamic first, then static) and gives pymunk
        a zero-copy view of a (bodies, 4) drive array."""
        self.read_buf.clear()
        pb.get_space_bodies(self.space, _IDS, self.read_buf)
        total = len(memoryview(self.read_buf.int_buf()).cast("P"))
        self.n_extra = total - self.n_dynamic
        self.write = np.zeros((total, WRITE_WIDTH))
        self.write_buf.set_float_buf(self.write.reshape(-1))

    def read_order(self, row_of: dict[int, int]) -> None:
        """Maps this Space's body order onto the engine's row order."""
        self.read_buf.clear()
        pb.get_space_bodies(self.space, _IDS, self.read_buf)
        ids = memoryview(self.read_buf.int_buf()).cast("P").tolist()[: self.n_dynamic]
        perm = np.empty(len(ids), dtype=np.intp)
        perm[[row_of[i] for i in ids]] = np.arange(len(ids))
        self.perm = None if np.array_equal(perm, np.arange(len(ids))) else perm


class TrialSpaces:
    """All trials of a batch in pymunk, read and driven in bulk.

    Rows: the engine's arrays hold the live trials in increasing trial order, R
    bodies each, flattened to ``(n_live * R, ...)`` rows.

    Args:
        radii: (R,) body radii of a trial.
        mass: Mass of every body.
        walls: (P, 2, 2) static segments of a trial, trial-local.
        extent: Box no body centre of a trial can leave, trial-local.
        position: (B, R, 2) initial centres, trial-local.
        angle: (B, R) initial headings.
        settings: Physics settings.
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
        self.settings = settings
        n_trials, n_bodies = angle.shape
        self.n_bodies = n_bodies
        diameter = 2.0 * float(np.max(radii))
        cell = settings.hash_cell or _next_power_of_two(diameter)
        self.grid = SlotGrid.fit(extent, margin=diameter + cell, cell=cell)
        per_space = min(settings.trials_per_space, self.grid.capacity)
        self.live = np.arange(n_trials)
        self.spaces: list[_Space] = []
        self._space_of: dict[int, _Space] = {}
        offsets = np.empty((n_trials, 2))
        for start in range(0, n_trials, per_space):
            ids = list(range(start, min(start + per_space, n_trials)))
            sp = _Space(ids)
            space = sp.space
            space.iterations = settings.iterations
            space.collision_slop = settings.collision_slop
            space.use_spatial_hash(cell, settings.hash_cells_per_trial * len(ids))
            robots: list[pymunk.Body | pymunk.Shape] = []
            for slot, b in enumerate(ids):
                self._space_of[b] = sp
                offsets[b] = self.grid.offset(slot)
                sp.bodies[b], sp.shapes[b] = [], []
                for i, r in enumerate(radii):
                    body = pymunk.Body(mass, pymunk.moment_for_circle(mass, 0.0, r))
                    body.position = tuple(offsets[b] + position[b, i])
                    body.angle = float(angle[b, i])
                    shape = pymunk.Circle(body, float(r))
                    shape.friction = settings.friction
                    sp.bodies[b].append(body)
                    sp.shapes[b].append(shape)
                    robots += [body, shape]
            # Robots before walls: their hash ids follow the row order (see above).
            space.add(*robots)
            for b in ids:
                for a, z in walls:
                    seg = pymunk.Segment(
                        space.static_body,
                        tuple(offsets[b] + a),
                        tuple(offsets[b] + z),
                        0.0,
                    )
                    seg.friction = settings.friction
                    space.add(seg)
            sp.attach_write()
            self.spaces.append(sp)
        self._offsets = np.repeat(offsets, n_bodies, axis=0)
        self._masses = np.full(n_trials * n_bodies, mass)
        self._index_spaces()

    def _index_spaces(self) -> None:
        """Row ranges of each Space in the engine's (live) rows."""
        self._ranges: list[tuple[_Space, slice]] = []
        row = 0
        for sp in self.spaces:
            n = sp.n_dynamic
            if n:
                self._ranges.append((sp, slice(row, row + n)))
            row += n

    @property
    def masses(self) -> np.ndarray:
        """(rows,) mass of every live body."""
        return self._masses

    def read(self, out: np.ndarray) -> None:
        """Fills ``out`` (rows, 5) with x, y, angle, vx, vy per live body, x and y
        trial-local."""
        for sp, rows in self._ranges:
            sp.read_buf.clear()
            pb.get_space_bodies(sp.space, _READ, sp.read_buf)
            data = np.frombuffer(sp.read_buf.float_buf(), dtype=np.float64)
            data = data.reshape(-1, READ_WIDTH)[: rows.stop - rows.start]
            out[rows] = data if sp.perm is None else data[sp.perm]
        out[:, 0:2] -= self._offsets

    def step(self, drive: np.ndarray) -> None:
        """Sets (rows, 4) angle, angular velocity and force of every live body and
        steps every Space once."""
        dt = self.settings.dt
        for sp, rows in self._ranges:
            n = rows.stop - rows.start
            if sp.perm is None:
                sp.write[:n] = drive[rows]
            else:
                sp.write[sp.perm] = drive[rows]
            pb.set_space_bodies(sp.space, _WRITE, sp.write_buf)
            sp.space.step(dt)

    def disable(self, trials: np.ndarray, bodies: np.ndarray) -> None:
        """Takes bodies out of every collision and stops them where they are:
        ``trials`` are live-row trial indices, ``bodies`` body indices within
        those trials."""
        for t, i in zip(self.live[trials].tolist(), bodies.tolist(), strict=True):
            sp = self._space_of[t]
            sp.shapes[t][i].filter = _NO_CONTACT
            sp.bodies[t][i].velocity = (0.0, 0.0)

    def compact(self, keep: np.ndarray) -> None:
        """Removes the live trials not in ``keep`` ((n_live,) bool) from pymunk."""
        gone = set(self.live[~keep].tolist())
        for sp in self.spaces:
            drop = [t for t in sp.trial_ids if t in gone and t in sp.bodies]
            if not drop:
                continue
            objs: list[pymunk.Body | pymunk.Shape] = []
            for t in drop:
                objs += sp.shapes.pop(t)
                objs += sp.bodies.pop(t)
            sp.space.remove(*objs)
            row_of = {}
            for t in sorted(sp.bodies):
                for body in sp.bodies[t]:
                    row_of[body.id] = len(row_of)
            sp.attach_write()
            sp.read_order(row_of)
        self.live = self.live[keep]
        rows = np.repeat(keep, self.n_bodies)
        self._offsets = self._offsets[rows]
        self._masses = self._masses[rows]
        self._index_spaces()
