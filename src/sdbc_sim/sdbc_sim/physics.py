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
(One residual path remains in principle: chipmunk's hash table could alias two
adjacent cells that one robot covers in one batch and not in another, changing
the order in which it finds that robot's contacts; the determinism tests, with
robots in constant contact, have not met it.)

Actuation. Chipmunk's step integrates positions with the velocities the bodies
hold, then finds contacts, then integrates forces into velocities and solves the
contacts. With ``actuation="velocity"`` (the default) the commanded velocity is
written before the step, so a body moves in the step it is commanded; with
``"force"`` a force is written that reaches the commanded velocity at the end of
the step, so the body moves one step later (see :class:`PhysicsSettings`).

Contacts. Chipmunk moves bodies before it looks for contacts, so a body that meets
a wall or another body during a step ends that step overlapping it by up to its
speed times dt, which chipmunk would only push out during the next step. Here
chipmunk's own push-out is switched off (``collision_bias`` 1); after every step
the contacts it found are read in bulk (``get_space_arbiters``), and in every trial
where one overlaps by more than ``overlap_tolerance`` the bodies are projected apart
(:func:`~sdbc_sim.separation.project_apart`), leaving half the tolerance so that
chipmunk keeps the contact and its solver stops any further approach. The state the
engine reports then has no overlap beyond the tolerance.

Headings. Chipmunk never holds a robot's heading: its bodies keep angle 0, and
:class:`TrialSpaces` keeps the headings the engine writes into the drive rows. A
circle centred on its body collides and is solved the same at any body angle, and
the engine turns bodies itself (the angular velocity it writes is 0, so chipmunk
would only hand the heading back unchanged). A heading written to chipmunk cost a
sine and cosine at the write and at every position update; the results are the
same to the bit (``bench/identity.py`` on every task, both actuation modes).

A finished trial's bodies are removed from its Space when the engine compacts;
chipmunk then reorders its body list, so the mapping from a Space's body order to
the engine's rows is read back (``BODY_ID``) after every compaction.
"""

from __future__ import annotations

import atexit
import gc
import math
import weakref
from dataclasses import dataclass
from typing import Literal, Protocol

import numpy as np
import pymunk
import pymunk.batch as pb

from sdbc_sim import compiled
from sdbc_sim.limits import excerpt
from sdbc_sim.separation import project_apart
from sdbc_sim.task import Task

_READ = pb.BodyFields.POSITION | pb.BodyFields.VELOCITY
"""Fields read back after every step: x, y, vx, vy (the heading is not chipmunk's,
see :class:`TrialSpaces`)."""
_MOTION = {
    "velocity": pb.BodyFields.VELOCITY | pb.BodyFields.ANGULAR_VELOCITY,
    "force": pb.BodyFields.ANGULAR_VELOCITY | pb.BodyFields.FORCE,
}
"""Fields written before every step, per actuation mode. pymunk.batch keeps the
fields in the order POSITION, ANGLE, VELOCITY, ANGULAR_VELOCITY, FORCE: a write
row is the position (only after a projection), then the drive row as DRIVE_COLUMNS
lays it out, without its heading (column 0)."""
_POSITION_WIDTH = 2
"""Columns of a position in a Space's write rows."""
_SPACE_READ_WIDTH = 4
"""Columns pymunk fills per body for ``_READ``: x, y, vx, vy."""
_IDS = pb.BodyFields.BODY_ID
_CONTACT_IDS = (
    pb.ArbiterFields.BODY_A_ID
    | pb.ArbiterFields.BODY_B_ID
    | pb.ArbiterFields.CONTACT_COUNT
)
_CONTACT_DEPTH = pb.ArbiterFields.DISTANCE_1
READ_WIDTH = 5
"""Columns of a state row: x, y, angle, vx, vy."""
WRITE_WIDTH = 4
"""Columns of a drive row: angle, angular velocity and a vector (velocity or force)."""
_MOTION_WIDTH = WRITE_WIDTH - 1
"""Columns of a drive row that chipmunk gets: all but the heading."""
_IN_ORDER = np.zeros(0, dtype=np.intp)
"""A Space's ``perm`` when its body order is the rows' order (the compiled copies
then index rows directly)."""
ACTUATIONS = ("velocity", "force")
"""How the commanded motion reaches chipmunk (:class:`PhysicsSettings`)."""
Actuation = Literal["velocity", "force"]
MODELS = ("rigid", "kinematic")
"""How bodies move and meet (:class:`PhysicsSettings`)."""
Model = Literal["rigid", "kinematic"]


@dataclass(frozen=True)
class DriveColumns:
    """Where a drive row holds each quantity (pymunk.batch's field order).

    Attributes:
        angle: Column of the heading.
        angular_velocity: Column of the angular velocity.
        x: Column of the x component of the velocity or force.
        y: Column of its y component.
    """

    angle: int
    angular_velocity: int
    x: int
    y: int


DRIVE_COLUMNS = {
    "velocity": DriveColumns(angle=0, angular_velocity=3, x=1, y=2),
    "force": DriveColumns(angle=0, angular_velocity=1, x=2, y=3),
}
"""Drive row layout per actuation mode: the heading first (the engine's own,
never chipmunk's), then what chipmunk gets, in pymunk.batch's field order."""
_WORLD_ORIGIN = 2.0**16
"""Every slot lies in [2^16, 2^17): one float exponent for all world coordinates."""
HASH_CELL_DIAMETERS = 32.0
"""The default spatial hash cell, in largest body diameters, rounded up to a power
of two (128 in predator-prey, 256 in the other four tasks).

Chipmunk looks up a body's candidate contacts in every cell its bounding box
covers, in hash tables shared by all a Space's trials (the walls in a static one).
A cell's bin sits at a hash of its coordinates, so neighbouring cells lie far
apart in the table, and most of a lookup's time is the load of a bin the cache
does not hold (``perf annotate`` of ``cpSpaceHashQuery``). The wider the cell, the
fewer distinct cells a trial's robots and walls fall in, and the more often the
next lookup finds its bin cached; the few more robots and walls per cell cost
less to test.

History: one diameter until 2026-12-02 (a trial's walls filled about a hundred
cells, a robot up to four), then 8, then 32. ``bench/engine.py --sweep
hash_cell=...`` (best of 3 and of 5, the same session) had the walled tasks fastest
at 256, against 64: gate escape +17-36 %, aggregation +8-9 %, foraging +14 %;
resource sharing and predator-prey, which have no walls, within the noise from 32
to 256. ``bench/versions.py`` against 8 diameters: gate escape 1.09, aggregation
1.07, predator-prey 1.01, foraging 1.00, resource sharing 0.98 (7 alternations;
5 for the others). The cell changes only the order in which chipmunk meets
contacts: on ``bench/identity.py``'s batches each change gave the same results on
four tasks and, in predator-prey, SDBC features off in the last bits in a few
trials (4 of 120 trials by 1e-11 relative at 8 diameters, 1 by 1.5e-12 at 32)."""
_NO_CONTACT = pymunk.ShapeFilter(categories=0)
ANCHOR_MASS_FACTOR = 1e6
"""An anchored body's mass (and moment) over its own: a body of the ordinary mass
that runs into it at full speed moves it by about a millionth of that speed."""

# Spaces left in reference cycles would otherwise be freed during interpreter
# shutdown, after pymunk's callbacks are gone (it then prints a warning per call).
atexit.register(gc.collect)


@dataclass(frozen=True)
class PhysicsSettings:
    """How bodies move and meet: the model, and for the rigid one how trials are
    laid out in pymunk and how pymunk steps them.

    Attributes:
        model: ``rigid`` (the default): bodies are pymunk rigid bodies, in
            Spaces of many trials (:class:`TrialSpaces`); contacts go through
            chipmunk's solver and the overlap projection, so robots push each
            other and slide along walls. ``kinematic``: the authors' robots
            (:mod:`sdbc_sim.kinematic`): a move that would overlap is refused and
            retried sideways at half speed; nobody pushes anybody. It needs
            ``actuation="velocity"``, and the settings below it ignores (all but
            ``dt``).
        trials_per_space: Most trials in one Space. Chipmunk's cost per body grows
            past a few hundred trials per Space (cache). The default is the best of
            ``bench/engine.py --task gate_escape --steps 300 --sweep
            trials_per_space=125,250,500,1000,2000 --repeat 3`` on a quiet 2-core
            machine (engine robot-steps/s 0.98M, 0.96M, 1.01M, 0.99M, 0.96M: flat
            within 5 %).
        dt: Physics time per control step; speeds are then in units per step.
        iterations: Contact solver iterations per step.
        overlap_tolerance: Largest overlap of two bodies, or of a body and a wall,
            left after a step, as a fraction of the smallest radius.
        friction: Friction of bodies and walls; 0 lets a robot slide along a wall,
            like the authors' robots, which retry a blocked move sideways.
        hash_cell: Spatial hash cell size, a power of two; None picks the smallest
            power of two at least ``HASH_CELL_DIAMETERS`` largest body diameters.
        hash_cells_per_trial: Hash table cells per trial of a Space. Chipmunk
            empties the whole table of moving shapes at every step, so a larger
            table costs time whatever it holds; a smaller one puts more cells in
            one bin. 16 since 2026-12-03 (64 before): ``bench/engine.py --sweep
            hash_cells_per_trial=64,16,8,4 --repeat 4`` put the chipmunk floor
            of resource sharing at 5.46M, 6.13M, 6.12M, 5.97M robot-steps/s and
            of predator-prey at 3.69M, 4.62M, 4.07M, 4.16M; gate escape, whose
            walls dominate, was flat. Results stayed the same to the bit
            (``bench/identity.py``, and trials alone against in a batch of 2000).
        separation_iterations: Most projection passes per step in a trial with
            an overlap (see :func:`~sdbc_sim.separation.project_apart`).
        actuation: How a body gets its commanded velocity v*. ``velocity`` (the
            default) writes v* as the body's velocity before the step; chipmunk
            integrates positions first, so the body turns and moves in the step it
            is commanded, as the authors' kinematic robots do (the paper is
            silent), and a stop command stops it at once. Contacts still go
            through chipmunk's solver, which removes the approaching part of v*,
            and the overlap projection. ``force`` applies F = m (v* - v) / dt
            instead: the velocity changes only at the end of the step, so a body
            moves one step after its command (and coasts one step after a stop);
            the behaviour of earlier versions.
    """

    trials_per_space: int = 500
    dt: float = 1.0
    iterations: int = 10
    overlap_tolerance: float = 0.02
    friction: float = 0.0
    hash_cell: float | None = None
    hash_cells_per_trial: int = 16
    separation_iterations: int = 8
    actuation: Actuation = "velocity"
    model: Model = "rigid"

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise ValueError(
                f"physics: model must be one of {', '.join(MODELS)}, "
                f"got {excerpt(self.model)}"
            )
        if self.model == "kinematic" and self.actuation != "velocity":
            raise ValueError(
                "physics: the kinematic model moves bodies by their commanded "
                f"velocity; actuation {self.actuation!r} needs model 'rigid'"
            )
        if self.actuation not in ACTUATIONS:
            raise ValueError(
                f"physics: actuation must be one of {', '.join(ACTUATIONS)}, got "
                f"{self.actuation!r}"
            )
        if self.trials_per_space < 1:
            raise ValueError(
                f"physics: trials_per_space must be >= 1, got {self.trials_per_space}"
            )
        if not (math.isfinite(self.dt) and self.dt > 0.0):
            raise ValueError(f"physics: dt must be positive, got {self.dt}")
        if self.iterations < 1:
            raise ValueError(f"physics: iterations must be >= 1, got {self.iterations}")
        if not 0.0 < self.overlap_tolerance < 1.0:
            raise ValueError(
                "physics: overlap_tolerance must be in (0, 1), got "
                f"{self.overlap_tolerance}"
            )
        if not (math.isfinite(self.friction) and self.friction >= 0.0):
            raise ValueError(f"physics: friction must be >= 0, got {self.friction}")
        if self.hash_cell is not None and not _is_power_of_two(self.hash_cell):
            raise ValueError(
                f"physics: hash_cell must be a power of two, got {self.hash_cell}"
            )
        if self.separation_iterations < 1:
            raise ValueError(
                "physics: separation_iterations must be >= 1, got "
                f"{self.separation_iterations}"
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


def task_geometry(
    task: Task,
) -> tuple[np.ndarray, float, np.ndarray, tuple[float, float, float, float]]:
    """(radii (R,), mass, walls (P, 2, 2), extent) of a task's trials, as a
    physics model is built from them."""
    layout = task.layout
    return (
        np.asarray(layout.radii, dtype=np.float64),
        layout.mass,
        np.asarray(task.walls, dtype=np.float64).reshape(-1, 2, 2),
        task.extent,
    )


class TrialPhysics(Protocol):
    """What the engine asks of a physics model (one per ``PhysicsSettings.model``):
    the bodies of a batch's live trials, stepped together. Rows hold the live
    trials in increasing trial order, R bodies each; state rows are x, y, angle,
    vx, vy, trial-local. :class:`TrialSpaces` documents each call."""

    live: np.ndarray
    """Indices of the live trials, in row order."""

    @property
    def masses(self) -> np.ndarray:
        """(rows,) mass of every live body."""
        ...

    @property
    def drive_columns(self) -> DriveColumns:
        """The layout of the drive rows :meth:`step` takes."""
        ...

    def read(self, out: np.ndarray) -> None:
        """Fills ``out`` (rows, 5) with the live bodies' state."""
        ...

    def step(self, drive: np.ndarray, state: np.ndarray) -> None:
        """Steps every live body with ``drive`` and fills ``state``."""
        ...

    def separate(
        self, out: np.ndarray, enabled: np.ndarray, anchored: np.ndarray | None = None
    ) -> None:
        """Removes overlaps beyond the tolerance from ``out``."""
        ...

    def anchor(self, trials: np.ndarray, bodies: np.ndarray, on: np.ndarray) -> None:
        """Anchors bodies (``on``) or frees them."""
        ...

    def disable(self, trials: np.ndarray, bodies: np.ndarray) -> None:
        """Takes bodies out of every collision and stops them."""
        ...

    def compact(self, keep: np.ndarray) -> None:
        """Drops the live trials not in ``keep``."""
        ...


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
            raise ValueError(
                f"physics: extent {extent} plus a margin of {margin} on each side "
                f"(the largest body diameter and a hash cell of {cell}) is too large "
                f"for one slot: a slot must fit in {_WORLD_ORIGIN:g}; a smaller "
                "hash_cell, or smaller units, fits it"
            )
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


_FREE_BUFFERS: dict[str, list[pb.Buffer]] = {"read": [], "write": []}
"""pymunk Buffers kept for reuse, by kind. pymunk 7.3.1's ``Buffer`` never frees
its C arrays (docs/upstream/pymunk-batch-buffer-leak.md): a new one per Space and
batch leaked 200-600 bytes per trial. Read buffers are grown by pymunk; write
buffers point into numpy arrays (``set_float_buf``), so the kinds never mix."""


def _buffer(kind: str) -> pb.Buffer:
    """A Buffer of ``kind`` ("read" or "write") from the free list, or a new one."""
    free = _FREE_BUFFERS[kind]
    return free.pop() if free else pb.Buffer()


def _give_back(buffers: list[tuple[str, pb.Buffer]]) -> None:
    """Returns a collected Space's Buffers to the free lists."""
    for kind, buffer in buffers:
        if kind == "read":
            buffer.clear()
        _FREE_BUFFERS[kind].append(buffer)


class _Space:
    """One pymunk Space and the bookkeeping of its trials. Its pymunk Buffers
    come from free lists and go back when the Space is collected."""

    def __init__(self, trial_ids: list[int]) -> None:
        self.space = pymunk.Space()
        self.trial_ids = trial_ids
        self.bodies: dict[int, list[pymunk.Body]] = {}
        self.shapes: dict[int, list[pymunk.Circle]] = {}
        self.perm = _IN_ORDER
        self.read_buf = _buffer("read")
        # Write rows without and with the position (after a projection).
        self.write_bufs = (_buffer("write"), _buffer("write"))
        self.writes = (np.zeros((0, _MOTION_WIDTH)), np.zeros((0, _MOTION_WIDTH)))
        self.moved = False
        self.n_extra = 0
        self.contact_buf = _buffer("read")
        weakref.finalize(
            self,
            _give_back,
            [("read", self.read_buf), ("read", self.contact_buf)]
            + [("write", buffer) for buffer in self.write_bufs],
        )
        self.sorted_ids = np.zeros(0, dtype=np.uintp)
        self.sorted_rows = np.zeros(0, dtype=np.intp)

    @property
    def n_dynamic(self) -> int:
        return sum(len(b) for b in self.bodies.values())

    def attach_write(self) -> None:
        """Counts the Space's bodies (dynamic first, then static) and gives pymunk
        zero-copy views of the write rows: (bodies, 3) drive rows without the
        heading, and (bodies, 2 + 3) with the position first. Static bodies are
        written too: their rows keep the positions they have, and zero motion."""
        self.read_buf.clear()
        pb.get_space_bodies(self.space, _IDS | pb.BodyFields.POSITION, self.read_buf)
        total = len(memoryview(self.read_buf.int_buf()).cast("P"))
        self.n_extra = total - self.n_dynamic
        positions = np.frombuffer(self.read_buf.float_buf(), dtype=np.float64)
        still = np.zeros((total, _MOTION_WIDTH))
        moved = np.zeros((total, _POSITION_WIDTH + _MOTION_WIDTH))
        moved[:, :_POSITION_WIDTH] = positions.reshape(total, _POSITION_WIDTH)
        self.writes = (still, moved)
        for buf, rows in zip(self.write_bufs, self.writes, strict=True):
            buf.set_float_buf(rows.reshape(-1))

    def index_bodies(self) -> None:
        """Maps this Space's body order and body ids onto the engine's rows (its
        trials in increasing order, bodies in order)."""
        in_rows = [b for t in sorted(self.bodies) for b in self.bodies[t]]
        row_of = {b.id: i for i, b in enumerate(in_rows)}
        ids = np.array(list(row_of), dtype=np.uintp)
        order = np.argsort(ids)
        self.sorted_ids = ids[order]
        self.sorted_rows = np.array(list(row_of.values()), dtype=np.intp)[order]
        self.read_buf.clear()
        pb.get_space_bodies(self.space, _IDS, self.read_buf)
        in_space = memoryview(self.read_buf.int_buf()).cast("P").tolist()
        in_space = in_space[: self.n_dynamic]
        perm = np.empty(len(in_space), dtype=np.intp)
        perm[[row_of[i] for i in in_space]] = np.arange(len(in_space))
        in_order = np.array_equal(perm, np.arange(len(in_space)))
        self.perm = _IN_ORDER if in_order else perm

    def mark_deep(
        self, tolerance: float, first_row: int, n_bodies: int, deep: np.ndarray
    ) -> None:
        """Sets ``deep`` (live trials, bool) of every trial with a contact of the
        last step that overlaps by more than ``tolerance``; this Space's rows
        start at engine row ``first_row``."""
        buf = self.contact_buf
        buf.clear()
        pb.get_space_arbiters(self.space, _CONTACT_IDS | _CONTACT_DEPTH, buf)
        _mark_deep_trials(
            np.frombuffer(buf.int_buf(), dtype=np.uintp).reshape(-1, 3),
            np.frombuffer(buf.float_buf(), dtype=np.float64),
            self.sorted_ids,
            self.sorted_rows,
            tolerance,
            first_row,
            n_bodies,
            deep,
        )


@compiled.compiled(
    "void(uintp[:, ::1], float64[::1], uintp[::1], intp[::1], float64, intp, intp, "
    "boolean[::1])"
)
def _mark_deep_trials(
    contacts: np.ndarray,
    distance: np.ndarray,
    sorted_ids: np.ndarray,
    sorted_rows: np.ndarray,
    tolerance: float,
    first_row: int,
    n_bodies: int,
    deep: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested through TrialSpaces.separate
    """For each arbiter (body ids a and b, contact count; its first contact's
    distance, negative when overlapping) with a contact deeper than
    ``tolerance``, marks the trials of its dynamic bodies (a static body's id is
    not among ``sorted_ids``, which map a body's id to its row).

    A compiled loop (:mod:`sdbc_sim.compiled`): it ran at almost every step as a
    dozen whole-array calls per Space."""
    n = sorted_ids.shape[0]
    for k in range(contacts.shape[0]):
        if contacts[k, 2] == 0 or not -distance[k] > tolerance:
            continue
        for side in range(2):
            body = contacts[k, side]
            at = np.searchsorted(sorted_ids, body)
            if at < n and sorted_ids[at] == body:
                deep[(first_row + sorted_rows[at]) // n_bodies] = True


@compiled.compiled(
    "void(float64[:, ::1], intp[::1], float64[:, :, ::1], float64[:, :, ::1], "
    "float64[:, ::1], boolean[::1])"
)
def _write_projection(
    out: np.ndarray,
    trials: np.ndarray,
    before: np.ndarray,
    after: np.ndarray,
    offsets: np.ndarray,
    moved: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested through TrialSpaces.separate
    """Writes the centres of ``trials`` that the projection moved (``after``
    differs from ``before``) into the state rows ``out``, rounded as pymunk will
    hold them (to world coordinates and back: exact, as every world coordinate
    has the same exponent), and marks their rows in ``moved``."""
    n = after.shape[1]
    for s in range(trials.shape[0]):
        for i in range(n):
            x = after[s, i, 0]
            y = after[s, i, 1]
            if x != before[s, i, 0] or y != before[s, i, 1]:
                row = trials[s] * n + i
                out[row, 0] = (x + offsets[row, 0]) - offsets[row, 0]
                out[row, 1] = (y + offsets[row, 1]) - offsets[row, 1]
                moved[row] = True


@compiled.compiled(
    "void(float64[:, ::1], intp[::1], float64[:, ::1], intp, float64[:, ::1])"
)
def _rows_from_space(
    data: np.ndarray,
    perm: np.ndarray,
    offsets: np.ndarray,
    first_row: int,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested through TrialSpaces.read
    """Copies one Space's bodies (``data``: x, y, vx, vy in the Space's order)
    into state rows ``out`` from ``first_row`` on: row k is body ``perm[k]``
    (body k when ``perm`` is empty), x and y made trial-local.

    A compiled loop (:mod:`sdbc_sim.compiled`): as numpy, the two-column strided
    copies cost twice what pymunk's read itself did."""
    permuted = perm.shape[0] > 0
    for k in range(data.shape[0]):
        src = perm[k] if permuted else k
        row = first_row + k
        out[row, 0] = data[src, 0] - offsets[row, 0]
        out[row, 1] = data[src, 1] - offsets[row, 1]
        out[row, 3] = data[src, 2]
        out[row, 4] = data[src, 3]


@compiled.compiled(
    "void(float64[:, ::1], float64[:, ::1], float64[:, ::1], intp, intp[::1], "
    "boolean, float64[:, ::1])"
)
def _rows_to_space(
    state: np.ndarray,
    drive: np.ndarray,
    offsets: np.ndarray,
    first_row: int,
    perm: np.ndarray,
    with_position: bool,
    write: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested through TrialSpaces.step
    """Fills one Space's write rows (its first bodies, in its order) from the
    rows ``first_row`` on: body ``perm[k]`` (body k when ``perm`` is empty) gets
    row k's drive without its heading, after its world position when
    ``with_position``. The inverse of :func:`_rows_from_space`'s ordering."""
    permuted = perm.shape[0] > 0
    motion = drive.shape[1] - 1
    for k in range(write.shape[0]):
        dst = perm[k] if permuted else k
        row = first_row + k
        c = 0
        if with_position:
            write[dst, 0] = state[row, 0] + offsets[row, 0]
            write[dst, 1] = state[row, 1] + offsets[row, 1]
            c = _POSITION_WIDTH
        for j in range(motion):
            write[dst, c + j] = drive[row, 1 + j]


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
        # The compiled loops load here, not at the step that first needs one.
        compiled.load()
        n_trials, n_bodies = angle.shape
        self.n_bodies = n_bodies
        fields = _MOTION[settings.actuation]
        self._fields = (fields, pb.BodyFields.POSITION | fields)
        self._angle = np.array(angle, dtype=np.float64).reshape(-1)
        diameter = 2.0 * float(np.max(radii))
        cell = settings.hash_cell or _next_power_of_two(HASH_CELL_DIAMETERS * diameter)
        self.grid = SlotGrid.fit(extent, margin=diameter + cell, cell=cell)
        per_space = min(settings.trials_per_space, self.grid.capacity)
        self.live = np.arange(n_trials)
        self.spaces: list[_Space] = []
        self._space_of: dict[int, _Space] = {}
        offsets = np.empty((n_trials, 2))
        # Building Spaces makes many small objects and no garbage: the cyclic
        # collector would only walk them over and over.
        collecting = gc.isenabled()
        gc.disable()
        try:
            for start in range(0, n_trials, per_space):
                ids = list(range(start, min(start + per_space, n_trials)))
                sp = self._build_space(
                    ids, radii, mass, walls, position, angle, cell, offsets
                )
                for b in ids:
                    self._space_of[b] = sp
                self.spaces.append(sp)
        finally:
            if collecting:
                gc.enable()
        self._tolerance = settings.overlap_tolerance * float(np.min(radii))
        self._radii = np.asarray(radii, dtype=np.float64)
        self._walls = walls
        self._offsets = np.repeat(offsets, n_bodies, axis=0)
        self._mass = mass
        self._masses = np.full(n_trials * n_bodies, mass)
        self._index_spaces()

    def _build_space(
        self,
        ids: list[int],
        radii: np.ndarray,
        mass: float,
        walls: np.ndarray,
        position: np.ndarray,
        angle: np.ndarray,
        cell: float,
        offsets: np.ndarray,
    ) -> _Space:
        """One Space holding trials ``ids`` (filling their rows of ``offsets``)."""
        settings = self.settings
        sp = _Space(ids)
        space = sp.space
        space.iterations = settings.iterations
        # No push-out by chipmunk: overlaps are projected away after each step.
        space.collision_bias = 1.0
        space.use_spatial_hash(cell, settings.hash_cells_per_trial * len(ids))
        moments = [pymunk.moment_for_circle(mass, 0.0, float(r)) for r in radii]
        for slot, b in enumerate(ids):
            offsets[b] = self.grid.offset(slot)
        # World positions as Python floats in one go: a numpy sum per body cost
        # more than the body.
        world = (offsets[ids, None, :] + position[ids]).tolist()
        # All bodies first, then all shapes: chipmunk's bodies then lie together
        # in memory, which its per-body loops read in order.
        for b, starts in zip(ids, world, strict=True):
            bodies: list[pymunk.Body] = []
            sp.bodies[b] = bodies
            for moment, (x, y) in zip(moments, starts, strict=True):
                body = pymunk.Body(mass, moment)
                body.position = (x, y)
                bodies.append(body)
        robots: list[pymunk.Body | pymunk.Shape] = [
            body for b in ids for body in sp.bodies[b]
        ]
        for b in ids:
            shapes: list[pymunk.Circle] = []
            sp.shapes[b] = shapes
            for body, r in zip(sp.bodies[b], radii, strict=True):
                shape = pymunk.Circle(body, float(r))
                shape.friction = settings.friction
                shapes.append(shape)
            robots += shapes
        # Robots before walls: their hash ids follow the row order (see above).
        space.add(*robots)
        segments: list[pymunk.Segment] = []
        ends = (offsets[ids, None, None, :] + walls[None]).tolist()
        for trial_walls in ends:
            for (ax, ay), (zx, zy) in trial_walls:
                seg = pymunk.Segment(space.static_body, (ax, ay), (zx, zy), 0.0)
                seg.friction = settings.friction
                segments.append(seg)
        if segments:
            space.add(*segments)
        sp.attach_write()
        sp.index_bodies()
        return sp

    @classmethod
    def of_task(
        cls,
        task: Task,
        position: np.ndarray,
        angle: np.ndarray,
        settings: PhysicsSettings,
    ) -> TrialSpaces:
        """The Spaces of a batch of ``task``'s trials starting from ``position``
        (B, R, 2) and ``angle`` (B, R)."""
        return cls(*task_geometry(task), position, angle, settings)

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
            self._read_space(sp, rows, out)
        out[:, 2] = self._angle

    def _read_space(self, sp: _Space, rows: slice, out: np.ndarray) -> None:
        """x, y, vx, vy of one Space's rows, as :meth:`read` fills them."""
        sp.read_buf.clear()
        pb.get_space_bodies(sp.space, _READ, sp.read_buf)
        data = np.frombuffer(sp.read_buf.float_buf(), dtype=np.float64)
        data = data.reshape(-1, _SPACE_READ_WIDTH)[: rows.stop - rows.start]
        _rows_from_space(data, sp.perm, self._offsets, rows.start, out)

    def separate(
        self, out: np.ndarray, enabled: np.ndarray, anchored: np.ndarray | None = None
    ) -> None:
        """Projects apart the bodies of every trial where chipmunk found a contact
        overlapping by more than the tolerance, in ``out`` (as filled by
        :meth:`read`); the next :meth:`step` writes them into pymunk. See
        :func:`~sdbc_sim.separation.project_apart`.

        Args:
            out: (rows, 5) live body state, trial-local.
            enabled: (n_live, R) bool, bodies that still collide.
            anchored: (n_live, R) bool, anchored bodies (see :meth:`anchor`).
        """
        tol = self._tolerance
        n = self.n_bodies
        deep = np.zeros(self.live.shape[0], dtype=np.bool_)
        for sp, rows in self._ranges:
            sp.mark_deep(tol, rows.start, n, deep)
        if not deep.any():
            return
        trials = np.flatnonzero(deep)
        pos = out[:, 0:2].reshape(-1, n, 2)[trials]
        new = project_apart(
            pos,
            enabled[trials],
            self._radii,
            self._walls,
            tol,
            self.settings.separation_iterations,
            None if anchored is None or not anchored.any() else anchored[trials],
        )
        # What pymunk will hold: the next step writes every position of the
        # Spaces that hold a moved body from ``out``, in bulk.
        moved = np.zeros(out.shape[0], dtype=np.bool_)
        _write_projection(out, trials, pos, new, self._offsets, moved)
        for sp, span in self._ranges:
            if moved[span].any():
                sp.moved = True

    @property
    def drive_columns(self) -> DriveColumns:
        """The layout of the drive rows :meth:`step` takes."""
        return DRIVE_COLUMNS[self.settings.actuation]

    def step(self, drive: np.ndarray, state: np.ndarray) -> None:
        """Steps every Space once and reads it back into ``state``.

        Before its step, every body gets its angular velocity and velocity or
        force from ``drive`` (rows, 4, as :attr:`drive_columns` lays them out);
        the heading in it becomes the state's angle. (The angular velocity stays
        0: a turn written as one and integrated by chipmunk would give the same
        heading, but enter the contact solver's arithmetic and change results in
        the last bits.) In a Space where
        :meth:`separate` moved a body, every body also gets its position from
        ``state`` (rows, 5): the projection reaches pymunk here, in bulk
        (trial-local plus offset gives back the same world coordinate, so a body
        that was not moved is set where it is). Right after its own step, while
        its bodies are still in cache, each Space is read into ``state`` as
        :meth:`read` does.
        """
        dt = self.settings.dt
        for sp, rows in self._ranges:
            moved = int(sp.moved)
            write = sp.writes[moved][: rows.stop - rows.start]
            _rows_to_space(
                state, drive, self._offsets, rows.start, sp.perm, sp.moved, write
            )
            pb.set_space_bodies(sp.space, self._fields[moved], sp.write_bufs[moved])
            sp.moved = False
            sp.space.step(dt)
            self._read_space(sp, rows, state)
        self._angle[:] = drive[:, 0]
        state[:, 2] = self._angle

    def anchor(self, trials: np.ndarray, bodies: np.ndarray, on: np.ndarray) -> None:
        """Makes bodies ``ANCHOR_MASS_FACTOR`` times heavier (``on`` True) or
        gives them back their mass: ``trials`` are live-row trial indices,
        ``bodies`` body indices within those trials."""
        n = self.n_bodies
        for t, i, heavy in zip(
            trials.tolist(), bodies.tolist(), on.tolist(), strict=True
        ):
            trial = int(self.live[t])
            body = self._space_of[trial].bodies[trial][i]
            mass = ANCHOR_MASS_FACTOR * self._mass if heavy else self._mass
            # The moment scales with the mass (the same disc).
            body.moment = body.moment * (mass / body.mass)
            body.mass = mass
            self._masses[t * n + i] = mass

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
            sp.attach_write()
            sp.index_bodies()
        self.live = self.live[keep]
        rows = np.repeat(keep, self.n_bodies)
        self._offsets = self._offsets[rows]
        self._masses = self._masses[rows]
        self._angle = self._angle[rows]
        self._index_spaces()
