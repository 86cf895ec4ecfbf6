"""The task state formalism (eq. 1 of Gomes, Mariano & Christensen, ALIFE 2014).

A *task description* lists the *entity groups* of a task: their names, the names of
their per-entity state attributes (the kappa values), their size limits
(eta_min, eta_max), whether they are static, and the geometry that the distance
function f_D needs for their entities. It is the only thing the SDBC extractor knows
about a task.

A *task state* is one step of a batch of trials, batch-first: for every group, which
entity slots are present in every trial, their attributes and their geometry. The
engine hands one to its observers after every step; a stream of
``sdbc_msgs/TaskState`` messages converts to the same arrays with a batch of one.

Shapes use B for the number of trials, S for a group's entity slots, A for its
number of attributes and P for the number of segments of a polygon. Coordinates
are trial-local arena units.

The contract a task state keeps (:func:`validate_task_state` checks the shapes
and dtypes; the SDBC extractor, with ``check_values``, the values):

- **Slots.** A group's arrays hold S slots, ``max(min_size, 1) <= S <= max_size``;
  slots beyond S are absent. The engine's tasks give every group S = max_size; a
  message's arrays hold only its entities, so that the declared max_size costs
  nothing until entities are present.
- **Absent slots** (``present`` False) may hold anything in their attributes and
  shapes, NaN included, in static groups as in moving ones, before a slot's entity
  appears and after it leaves: nothing of them is read.
- **Present slots** hold finite attributes and the shapes of their entity.
- **Static groups**: an entity never moves, and a slot keeps its entity from the
  first step it is present to the end of the trial (it may leave and come back,
  at the same place). An observer may therefore read a static slot's shapes
  once, at the first step it is present, and reuse them (the engine's SDBC
  extractor does); a source whose slots change entities (a message packs the
  present entities into its first slots) is read every step instead.
- **dtypes** (:data:`DTYPE_RULE`): presence and ``active`` are bool; attributes
  and shapes are float64 here. The SDBC takes any real dtype (float32, integers,
  bool) and converts it to float64 once per step on entry
  (:func:`real_task_state`), so that float32 arrays from JAX or torch give the
  features of their float64 values; complex, object and other dtypes are refused
  with the rule in the message.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Literal

import numpy as np

from sdbc_sim.limits import excerpt


class Geometry(str, Enum):
    """The shape an entity has for the distance function f_D."""

    CIRCLE = "circle"
    """A disc: a centre and a radius (robots, the prey, a charging station)."""
    POINT = "point"
    """A point: a centre only."""
    POLYGON = "polygon"
    """A chain of line segments (walls, a gate, a boundary); distance is to the
    nearest segment."""


@dataclass(frozen=True, kw_only=True)
class EntityGroupSpec:
    """One entity group of a task description, declared by keyword::

        EntityGroupSpec(
            name="Gate", attributes=("is closing",), min_size=1, max_size=1,
            static=True, geometry=Geometry.POLYGON,
        )

    Attributes:
        name: Human name of the group, used to name features ("Agent", "Gate").
        attributes: Names of the per-entity state attributes (kappa values), in the
            order they appear in :attr:`GroupState.attributes`.
        min_size: eta_min, the fewest entities the group can hold.
        max_size: eta_max, the most entities the group can hold; also the most
            entity slots the arrays may have (the engine's have exactly as many).
        static: True if the group's entities never move. Static groups get no
            dispersion feature, and no distance feature to another static group.
            (``sdbc_msgs/EntityGroup`` calls it ``is_static``.)
        geometry: The shape of the group's entities for f_D.
    """

    name: str
    attributes: tuple[str, ...]
    min_size: int
    max_size: int
    static: bool
    geometry: Geometry

    def __post_init__(self) -> None:
        where = f"entity group {self.name!r}"
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(
                "entity group: the name must be a non-empty string, "
                f"got {excerpt(self.name)}"
            )
        if isinstance(self.attributes, str) or not all(
            isinstance(a, str) and a for a in self.attributes
        ):
            raise ValueError(
                f"{where}: attributes must be a sequence of names, got "
                f"{self.attributes!r}"
            )
        for label in ("min_size", "max_size"):
            value = getattr(self, label)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise ValueError(
                    f"{where}: {label} must be an integer, got {excerpt(value)}"
                )
        if not isinstance(self.static, (bool, np.bool_)):
            raise ValueError(
                f"{where}: static must be True or False, got {excerpt(self.static)}"
            )
        try:
            geometry = Geometry(self.geometry)
        except ValueError:
            raise ValueError(
                f"{where}: geometry must be one of "
                f"{[g.value for g in Geometry]}, got {excerpt(self.geometry)}"
            ) from None
        if self.min_size < 0:
            raise ValueError(f"{where}: min_size {self.min_size} < 0")
        if self.min_size > self.max_size:
            raise ValueError(
                f"{where}: min_size {self.min_size} > max_size {self.max_size}"
            )
        if self.max_size < 1:
            raise ValueError(f"{where}: max_size {self.max_size} < 1")
        if len(set(self.attributes)) != len(self.attributes):
            raise ValueError(f"{where}: duplicate attribute names")
        object.__setattr__(self, "geometry", geometry)
        object.__setattr__(self, "attributes", tuple(self.attributes))
        object.__setattr__(self, "min_size", int(self.min_size))
        object.__setattr__(self, "max_size", int(self.max_size))
        object.__setattr__(self, "static", bool(self.static))

    @property
    def is_static(self) -> bool:
        """:attr:`static` under the name ``sdbc_msgs/EntityGroup`` gives it."""
        return self.static


@dataclass(frozen=True)
class TaskDescription:
    """The entity groups of a task, in the order the task state lists them.

    Attributes:
        name: The task's name ("gate_escape").
        groups: The entity groups.
    """

    name: str
    groups: tuple[EntityGroupSpec, ...]

    def __post_init__(self) -> None:
        names = [g.name for g in self.groups]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ValueError(
                f"task description {self.name!r}: duplicate group names {duplicates}"
            )
        object.__setattr__(self, "groups", tuple(self.groups))

    def group(self, name: str) -> EntityGroupSpec:
        """Returns the group called ``name``."""
        for g in self.groups:
            if g.name == name:
                return g
        raise KeyError(f"task description {self.name!r} has no group {name!r}")


@dataclass
class GroupState:
    """One entity group at one step, over a batch of trials.

    Every array below may have a leading dimension of 1 instead of B: one row
    shared by every trial (a static polygon, radii that never change, a presence
    that is the same in all trials); readers broadcast it, and it gives the same
    features as B repeated rows. Any other leading dimension is refused, naming the
    group and the array (:func:`validate_task_state`). Only
    :attr:`TaskState.active` always has one row per trial.

    Attributes:
        present: (B, S) bool. Which entity slots hold an entity at this step; the
            group's size |g| is the row sum. S is at most the group's max_size.
        attributes: (B, S, A) float64. State attribute values; anything (NaN
            included) where not present.
        centres: (B, S, 2) float64 for circles and points; None for polygons.
        radii: (B, S) float64 for circles; None otherwise.
        segments: (B, S, P, 2, 2) float64 for polygons, each segment as its two end
            points; None otherwise.
    """

    present: np.ndarray
    attributes: np.ndarray
    centres: np.ndarray | None = None
    radii: np.ndarray | None = None
    segments: np.ndarray | None = None

    def shapes(self, label: Literal["centres", "radii", "segments"]) -> np.ndarray:
        """The array ``label``, which the group's geometry says it has.

        Raises:
            ValueError: The group has no such array.
        """
        array = getattr(self, label)
        if array is None:
            raise ValueError(f"entity group state: {label} is missing")
        return array


@dataclass
class TaskState:
    """The task state of a batch of trials after one step.

    Attributes:
        step: Number of steps taken so far (1 after the first step).
        active: (B,) bool. Trials that took this step; a finished trial stays
            inactive and its groups' contents are then meaningless.
        groups: One :class:`GroupState` per group of the task description, same order.
    """

    step: int
    active: np.ndarray
    groups: tuple[GroupState, ...]


_BOOL = np.dtype(np.bool_)
_FLOAT = np.dtype(np.float64)
_REAL_KINDS = "biuf"
"""numpy dtype kinds of real numbers: bool, signed and unsigned integers, floats."""

DTYPE_RULE = (
    "presence and active are bool; attributes, centres, radii and segments are "
    "real numbers, float64 or any real dtype (float32, integers, bool) that the "
    "SDBC converts to float64 once per step on entry"
)
"""The dtypes a task state may have, as refusals state it."""


def real_task_state(description: TaskDescription, state: TaskState) -> TaskState:
    """``state`` with every attribute and shape array as float64: the same object
    if they all are, else a copy whose arrays of another real dtype are converted
    (anything numpy can read as an array, a JAX or torch CPU array included).

    Raises:
        ValueError: An array of a dtype that is not real (complex, object,
            strings, dates), or a presence or ``active`` that is not bool, naming
            the group, the array and :data:`DTYPE_RULE`.
    """
    if _as_declared(state):
        return state
    groups = []
    for g, group in enumerate(state.groups):
        spec = description.groups[g] if g < len(description.groups) else None
        arrays = {
            label: _real_array(description, state, spec, label, getattr(group, label))
            for label in ("present", "attributes", "centres", "radii", "segments")
        }
        groups.append(GroupState(**arrays))  # type: ignore[arg-type]
    active = _real_array(description, state, None, "active", state.active)
    return TaskState(
        step=state.step,
        active=state.active if active is None else active,
        groups=tuple(groups),
    )


def _as_declared(state: TaskState) -> bool:
    """Every array is an ndarray of the dtype :func:`validate_task_state` wants.
    A plain loop, identity before equality (numpy's dtypes are singletons, except
    in arrays from a pickle and their copies): the SDBC asks at every step."""
    active = state.active
    if type(active) is not np.ndarray or not _is(active.dtype, _BOOL):
        return False
    for group in state.groups:
        present = group.present
        if type(present) is not np.ndarray or not _is(present.dtype, _BOOL):
            return False
        for array in (group.attributes, group.centres, group.radii, group.segments):
            if array is not None and (
                type(array) is not np.ndarray or not _is(array.dtype, _FLOAT)
            ):
                return False
    return True


def _is(dtype: np.dtype, expected: np.dtype) -> bool:
    return dtype is expected or dtype == expected


def _real_array(
    description: TaskDescription,
    state: TaskState,
    spec: EntityGroupSpec | None,
    label: str,
    value: object,
) -> np.ndarray | None:
    """One array of a state under :data:`DTYPE_RULE`: presence and ``active`` as
    they are if bool, the others as float64 if real; None stays None (the
    validation names a missing array)."""
    if value is None:
        return None
    where = f"task {description.name!r}, step {state.step}"
    where = where if spec is None else f"{where}, group {spec.name!r}"
    try:
        array = value if isinstance(value, np.ndarray) else np.asarray(value)
    except (TypeError, ValueError) as error:
        raise ValueError(
            f"{where}: {label} is not an array ({error}); {DTYPE_RULE}"
        ) from None
    if label in ("active", "present"):
        if array.dtype != _BOOL:
            raise ValueError(f"{where}: {label} has dtype {array.dtype}; {DTYPE_RULE}")
        return array
    if array.dtype.kind not in _REAL_KINDS:
        raise ValueError(
            f"{where}: {label} has dtype {array.dtype}, not a real number; {DTYPE_RULE}"
        )
    return array if array.dtype == _FLOAT else array.astype(_FLOAT)


def validate_task_state(
    description: TaskDescription, state: TaskState, n_trials: int
) -> None:
    """Checks that a task state has the shapes and dtypes its description promises.

    Raises:
        ValueError: Naming the group and array that do not fit.
    """
    active = state.active
    if (
        not isinstance(active, np.ndarray)
        or active.shape != (n_trials,)
        or active.dtype != _BOOL
    ):
        raise ValueError(
            f"task {description.name!r}, step {state.step}: active must be a "
            f"({n_trials},) bool array, got {np.asarray(active).dtype} "
            f"{np.shape(active)}"
        )
    if len(state.groups) != len(description.groups):
        raise ValueError(
            f"task {description.name!r}, step {state.step}: {len(state.groups)} groups "
            f"in the state, {len(description.groups)} in the description"
        )
    for spec, group in zip(description.groups, state.groups, strict=True):
        size = _slots(description, state, spec, group.present)
        _check_array(description, state, spec, "present", group.present, (size,))
        attributes_tail = (size, len(spec.attributes))
        _check_array(
            description, state, spec, "attributes", group.attributes, attributes_tail
        )
        if spec.geometry is Geometry.POLYGON:
            # Any number P >= 1 of segments per polygon.
            seg = group.segments
            n_segments = seg.shape[2] if seg is not None and seg.ndim == 5 else 0
            segments_tail = (size, max(n_segments, 1), 2, 2)
            _check_array(description, state, spec, "segments", seg, segments_tail)
        else:
            _check_array(description, state, spec, "centres", group.centres, (size, 2))
            if spec.geometry is Geometry.CIRCLE:
                _check_array(description, state, spec, "radii", group.radii, (size,))


def state_layout(state: TaskState) -> tuple[object, ...] | None:
    """All that :func:`real_task_state` and :func:`validate_task_state` read of a
    state besides its description and batch size: every array's type, shape and
    dtype (None for no array), group by group. Two states of the same layout pass
    or fail both alike; None if an array has no shape or dtype to read."""
    try:
        active = state.active
        layout: list[object] = [(type(active), active.shape, active.dtype)]
        for group in state.groups:
            for array in (
                group.present,
                group.attributes,
                group.centres,
                group.radii,
                group.segments,
            ):
                # A triple per array, never flattened: numpy's dtypes compare
                # equal to None (the default dtype), which a shifted flat key
                # would line up against them.
                layout.append(
                    None if array is None else (type(array), array.shape, array.dtype)
                )
    except Exception:  # noqa: BLE001 - anything unreadable takes the full checks
        return None
    return tuple(layout)


class TaskStateCheck:
    """:func:`real_task_state` then :func:`validate_task_state` for a stream of
    states of one description and batch size, as an observer gets them at every
    step.

    A state of the layout (:func:`state_layout`) of the last one accepted as it was
    (float64 and bool ndarrays, nothing converted) passes on one comparison of
    layouts: the checks would read nothing else. Any other state gets them in full,
    with their messages.

    Args:
        description: The task description.
        n_trials: B, the batch size every state must have.
    """

    def __init__(self, description: TaskDescription, n_trials: int) -> None:
        self.description = description
        self.n_trials = n_trials
        self._accepted: tuple[object, ...] | None = None
        self.layout: tuple[object, ...] | None = None
        """The layout of the state the last call returned (None if unreadable);
        the same object at every step while the layout holds."""

    def __call__(self, state: TaskState) -> TaskState:
        """``state`` as :func:`real_task_state` returns it, checked.

        Raises:
            ValueError: As :func:`real_task_state` and :func:`validate_task_state`.
        """
        layout = state_layout(state)
        accepted = self._accepted
        if layout is not None and layout == accepted:
            self.layout = accepted
            return state
        real = real_task_state(self.description, state)
        validate_task_state(self.description, real, self.n_trials)
        if real is state:
            self._accepted = self.layout = layout
        else:
            self.layout = state_layout(real)
        return real


def _slots(
    description: TaskDescription,
    state: TaskState,
    spec: EntityGroupSpec,
    present: np.ndarray | None,
) -> int:
    """S, the slots of a group's arrays (its presence's last axis), checked to be
    within ``max(min_size, 1)..max_size``; max_size when the presence has no
    last axis (its own check then names the problem)."""
    if not isinstance(present, np.ndarray) or present.ndim != 2:
        return spec.max_size
    slots = int(present.shape[1])
    least = max(spec.min_size, 1)
    if not least <= slots <= spec.max_size:
        raise ValueError(
            f"task {description.name!r}, step {state.step}, group {spec.name!r}: "
            f"present has {slots} slots, expected {least} to {spec.max_size} "
            "(min_size, or 1, to max_size)"
        )
    return slots


def _check_array(
    description: TaskDescription,
    state: TaskState,
    spec: EntityGroupSpec,
    label: str,
    array: np.ndarray | None,
    tail: tuple[int, ...],
) -> None:
    """One array of a group: (B or 1, *tail), bool for presence, else float64."""
    expected = _BOOL if label == "present" else _FLOAT
    if (
        isinstance(array, np.ndarray)
        and array.shape[1:] == tail
        and (array.shape[0] == 1 or array.shape[0] == state.active.shape[0])
        and array.dtype == expected
    ):
        return
    where = f"task {description.name!r}, step {state.step}, group {spec.name!r}"
    if not isinstance(array, np.ndarray):
        raise ValueError(f"{where}: {label} is missing")
    if array.dtype != expected:
        raise ValueError(
            f"{where}: {label} has dtype {array.dtype}, expected {expected} "
            f"({DTYPE_RULE}: real_task_state converts)"
        )
    n_trials = state.active.shape[0]
    if array.ndim >= 1 and array.shape[1:] == tail:
        raise ValueError(
            f"{where}: {label} has {array.shape[0]} rows, expected {n_trials} (one "
            "per trial) or 1 (shared by every trial)"
        )
    slots = "" if label == "present" else f" (S = {tail[0]} slots, as present has)"
    raise ValueError(
        f"{where}: {label} has shape {array.shape}, expected "
        f"({state.active.shape[0]} or 1, {', '.join(map(str, tail))}){slots}"
    )
