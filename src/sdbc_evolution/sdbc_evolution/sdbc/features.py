"""Per-step behaviour features of a task state (eqs. 2 to 5 of the paper).

From a task description alone, :func:`behaviour_features` lists the features every
step yields, group by group in the description's order:

1. ``S_g = (|g| - eta_min) / (eta_max - eta_min)``, the group's size relative to its
   limits (eq. 2), only if ``eta_max > eta_min``;
2. ``theta_g = sum_{e in g} theta_e / |g|``, the mean of each state attribute
   over the group's entities (eq. 3);
3. ``D_g = sum_{i != j} f_D(e_i, e_j) / (|g| (|g| - 1))``, the dispersion: the
   mean distance of each entity to the others (eq. 4), only if the group is not
   static and ``eta_max > 1``. The paper's eq. 4 divides by ``(|g| - 1)^2``; its text
   and the authors' code take the mean, which docs/method.md follows. f_D is
   symmetric, so the mean over ordered pairs i != j is the mean over unordered
   pairs i < j;
4. ``d(g, h) = sum_{e_i in g} sum_{e_j in h} f_D(e_i, e_j) / (|g| |h|)``, the mean
   distance to every later group h (eq. 5), unless both groups are static.

With :class:`~.options.SdbcOptions`, groups may be left out (``ignore_groups``) and
two kinds follow the paper's, in this order: the standard deviation of each state
attribute over a group's entities (``state_deviation``) and the difference
of the mean states of an attribute two groups share (``relations``). Every kind is
declared here and only here: its :class:`FeatureKind`, its place in
:func:`behaviour_features`, its name in :func:`feature_name` and its sum and count
in :meth:`StepFeatures.compute`; the extractor, the aggregation and the naming of
dimensions know features only as rows.

A feature is NaN at a step where it is undefined: the means and distances of an empty
group, the dispersion of a group with fewer than two entities, a deviation of an
empty group, a difference where either mean is undefined.

:class:`StepFeatures` computes them all for a batch of trials, one compiled loop
per feature (:mod:`.fused`) where the shapes are discs, or a few numpy operations
per feature otherwise: pair indices are built once, and no Python loop runs over
trials or entities.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from enum import Enum
from typing import Any

import numpy as np
from sdbc_sim.sensors import axis_views
from sdbc_sim.task_state import (
    EntityGroupSpec,
    Geometry,
    GroupState,
    TaskDescription,
    TaskState,
    state_layout,
    validate_task_state,
)

from sdbc_evolution.sdbc import fused as loops
from sdbc_evolution.sdbc.distance import (
    Discs,
    Segments,
    Shapes,
    Workspace,
    disc_and_polygon,
    entity_distance,
    expand,
    group_shapes,
    pick,
    slot_major,
)
from sdbc_evolution.sdbc.options import PAPER, SdbcOptions


class FeatureKind(str, Enum):
    """The four kinds of behaviour feature (eqs. 2 to 5)."""

    GROUP_SIZE = "group size"
    """S_g, eq. 2."""
    MEAN_STATE = "mean state"
    """theta_g, one per state attribute, eq. 3."""
    DISPERSION = "dispersion"
    """D_g, eq. 4."""
    GROUP_DISTANCE = "group distance"
    """d(g, h), eq. 5."""
    STATE_DEVIATION = "state deviation"
    """The standard deviation (ddof 0) of one state attribute over the group's
    present entities (option ``state_deviation``, the authors' later code)."""
    RELATION = "relation"
    """theta_g[a] - theta_h[a] for an attribute a of both groups (option
    ``relations``, the paper's extension (i))."""


@dataclass(frozen=True)
class BehaviourFeature:
    """One per-step behaviour feature.

    Attributes:
        kind: Which of eqs. 2 to 5 it is.
        group: Index of its entity group in the task description.
        name: Human name, derived from the group and attribute names:
            "Agent group size", "Gate is closing", "Agent dispersion",
            "Predators-prey distance".
        attribute: Index of the state attribute in ``group`` (MEAN_STATE,
            STATE_DEVIATION, RELATION).
        other: Index of the second group (GROUP_DISTANCE, RELATION), always
            > ``group``.
    """

    kind: FeatureKind
    group: int
    name: str
    attribute: int | None = None
    other: int | None = None

    @property
    def second_group(self) -> int:
        """``other``, which a GROUP_DISTANCE or RELATION feature always has."""
        if self.other is None:
            raise ValueError(f"feature {self.name!r} has no second group")
        return self.other

    @property
    def state_attribute(self) -> int:
        """``attribute``, which a MEAN_STATE, STATE_DEVIATION or RELATION feature
        always has."""
        if self.attribute is None:
            raise ValueError(f"feature {self.name!r} has no state attribute")
        return self.attribute


def _lower_initial(name: str) -> str:
    """``"Prey"`` -> ``"prey"``; acronyms such as ``"GPS beacon"`` stay as they are."""
    if len(name) > 1 and name[1].isupper():
        return name
    return name[:1].lower() + name[1:]


def feature_name(
    description: TaskDescription,
    kind: FeatureKind,
    group: int,
    attribute: int | None = None,
    other: int | None = None,
) -> str:
    """The human name of a feature: "<Group> group size", "<Group> <attribute>",
    "<Group> dispersion", "<Group>-<other group> distance" with the other group's
    initial in lower case (the paper's "Predators-prey distance"), "<Group>
    <attribute> deviation", "<Group>-<other group> <attribute> difference"."""
    spec = description.groups[group]
    if kind is FeatureKind.GROUP_SIZE:
        return f"{spec.name} group size"
    if kind is FeatureKind.DISPERSION:
        return f"{spec.name} dispersion"
    if kind in (FeatureKind.MEAN_STATE, FeatureKind.STATE_DEVIATION):
        if attribute is None:
            raise ValueError(f"feature of {spec.name!r}: {kind.value} needs attribute")
        suffix = " deviation" if kind is FeatureKind.STATE_DEVIATION else ""
        return f"{spec.name} {spec.attributes[attribute]}{suffix}"
    if other is None:
        raise ValueError(f"feature of {spec.name!r}: {kind.value} needs another group")
    pair = f"{spec.name}-{_lower_initial(description.groups[other].name)}"
    if kind is FeatureKind.GROUP_DISTANCE:
        return f"{pair} distance"
    if attribute is None:
        raise ValueError(f"feature of {spec.name!r}: a relation needs attribute")
    return f"{pair} {spec.attributes[attribute]} difference"


def has_group_size(group: EntityGroupSpec) -> bool:
    """Eq. 2 applies: the group's size can change."""
    return group.max_size > group.min_size


def has_dispersion(group: EntityGroupSpec) -> bool:
    """Eq. 4 applies: the group moves and can hold two entities."""
    return not group.static and group.max_size > 1


def has_group_distance(group: EntityGroupSpec, other: EntityGroupSpec) -> bool:
    """Eq. 5 applies: at least one of the two groups moves."""
    return not (group.static and other.static)


def has_state_deviation(group: EntityGroupSpec) -> bool:
    """The deviation over entities is a behaviour: the group can hold two entities.
    Static groups too: static means the entities do not move, not that their state
    is constant (a charger's load)."""
    return group.max_size > 1


def _ignored(description: TaskDescription, options: SdbcOptions) -> set[int]:
    known = [g.name for g in description.groups]
    unknown = [name for name in options.ignore_groups if name not in known]
    if unknown:
        raise ValueError(
            f"sdbc option ignore_groups: task {description.name!r} has no group "
            f"{unknown}; its groups: {known}"
        )
    return {known.index(name) for name in options.ignore_groups}


def behaviour_features(
    description: TaskDescription, options: SdbcOptions | None = None
) -> tuple[BehaviourFeature, ...]:
    """The per-step features of a task, in characterisation order: the paper's
    (eqs. 2 to 5, group by group), then the deviations, then the relations that
    ``options`` adds (the paper's configuration by default).

    Raises:
        ValueError: If two features get the same name (for example a state attribute
            called "dispersion" or "group size", or two groups whose names differ only
            in the case of their first letter), or if the options do not fit the
            task (an unknown group to ignore, nothing left, no attribute to relate).
    """
    options = options or PAPER
    ignored = _ignored(description, options)
    specs: list[tuple[FeatureKind, int, int | None, int | None]] = []
    groups = description.groups
    kept = [g for g in range(len(groups)) if g not in ignored]
    for g in kept:
        group = groups[g]
        if has_group_size(group):
            specs.append((FeatureKind.GROUP_SIZE, g, None, None))
        specs.extend(
            (FeatureKind.MEAN_STATE, g, a, None) for a in range(len(group.attributes))
        )
        if has_dispersion(group):
            specs.append((FeatureKind.DISPERSION, g, None, None))
        specs.extend(
            (FeatureKind.GROUP_DISTANCE, g, None, h)
            for h in kept
            if h > g and has_group_distance(group, groups[h])
        )
    if ignored and not specs:
        raise ValueError(
            f"sdbc option ignore_groups: nothing is left of task {description.name!r}"
        )
    if options.state_deviation:
        specs.extend(
            (FeatureKind.STATE_DEVIATION, g, a, None)
            for g in kept
            if has_state_deviation(groups[g])
            for a in range(len(groups[g].attributes))
        )
    if options.relations:
        relations = [
            (FeatureKind.RELATION, g, a, h)
            for g in kept
            for h in kept
            if h > g
            for a, attribute in enumerate(groups[g].attributes)
            if attribute in groups[h].attributes
        ]
        if not relations:
            raise ValueError(
                f"sdbc option relations: task {description.name!r} has no state "
                "attribute shared by two groups"
            )
        specs.extend(relations)
    features = [
        BehaviourFeature(
            kind,
            g,
            feature_name(description, kind, g, attribute, other),
            attribute,
            other,
        )
        for kind, g, attribute, other in specs
    ]
    names = [f.name for f in features]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise ValueError(
            f"task description {description.name!r}: features with the same name "
            f"{duplicates}; rename the attribute or group"
        )
    return tuple(features)


def _shared(shapes: Shapes) -> bool:
    """The shapes are the same in every trial (a batch axis of 1)."""
    return (shapes.x if isinstance(shapes, Discs) else shapes.ax).shape[-1] == 1


def _slot_sum(
    a: np.ndarray, axes: tuple[int, ...], out: np.ndarray | None = None
) -> np.ndarray:
    """Sum over the consecutive slot ``axes`` of ``a``, one slot at a time in index
    order. numpy's own reduction sums 8 or more contiguous values pairwise, and a
    lone trial's slots are contiguous where a batch's are not, so a group of 8 or
    more entities would give a trial different last bits alone and in a batch;
    below 8 both orders are this one."""
    first = axes[0]
    shape = a.shape
    rest = shape[first + len(axes) :]
    rows = a.reshape(*shape[:first], -1, *rest)
    total = out if out is not None else np.empty((*shape[:first], *rest), a.dtype)
    # Views rather than np.take (a copy through a Python wrapper): a group of
    # many entities makes hundreds of these per step.
    head, *tail = axis_views(rows, first)
    np.copyto(total, head, casting="unsafe")
    for part in tail:
        total += part
    return total


def _ran(call: Callable[[], object] | None) -> bool:
    """Calls ``call`` if there is one; whether there was."""
    if call is None:
        return False
    call()
    return True


def _fused_distance_call(
    a: Shapes,
    a_absent: np.ndarray,
    b: Shapes,
    b_absent: np.ndarray,
    first: np.ndarray,
    second: np.ndarray,
    out: np.ndarray,
) -> Callable[[], None] | None:
    """The loop of :mod:`.fused` that computes ``out[b] = sum_p f_D(a[first[p]],
    b[second[p]])``, a pair with an absent entity adding 0, bound to its
    arguments; None for two groups of polygons, which the loops leave to numpy.
    A step plan calls it at every step on arrays it refills in place."""
    if isinstance(a, Discs) and isinstance(b, Discs):
        return functools.partial(
            _kernel(loops.disc_pair_total),
            *(a.x, a.y, _radii(a), a_absent),
            *(b.x, b.y, _radii(b), b_absent),
            *(first, second, out),
        )
    if isinstance(a, Segments) and isinstance(b, Segments):
        return None
    discs, polygons = disc_and_polygon(a, b)
    disc_slots, polygon_slots = (first, second) if discs is a else (second, first)
    disc_absent, polygon_absent = (
        (a_absent, b_absent) if discs is a else (b_absent, a_absent)
    )
    return functools.partial(
        _kernel(loops.disc_segment_total),
        *(discs.x, discs.y, _radii(discs), disc_absent),
        *(polygons.ax, polygons.ay, polygons.abx, polygons.aby),
        *(polygons.inverse, polygon_absent, disc_slots, polygon_slots, out),
    )


def _kernel(loop: Callable[..., Any]) -> Callable[..., Any]:
    """A compiled loop's numba kernel itself, without the wrapper that loads it
    at its first call (a frame per call, a dozen calls a step)."""
    load = getattr(loop, "load", None)
    return loop if load is None else load()


def _radii(discs: Discs) -> np.ndarray:
    """The discs' radii, zeros for points."""
    return loops.no_radius(discs.x.shape[0]) if discs.r is None else discs.r


@functools.lru_cache(maxsize=32)
def slot_pairs(first: int, second: int | None) -> tuple[np.ndarray, np.ndarray]:
    """The slot pairs i < j of ``first`` slots (``second`` None: eq. 4's), or every
    pair of ``first`` slots with ``second`` slots in row-major order (eq. 5's).

    Made for the slots a state's arrays hold (the engine's: max_size; a message's:
    the entities present) when first met, and shared read-only by every extractor:
    memory follows the entities, not the declared max_size, and a stream whose
    group sizes change keeps a few dozen lists, not one per size ever seen.
    """
    if second is None:
        i, j = np.triu_indices(first, k=1)
        return np.ascontiguousarray(i, np.int64), np.ascontiguousarray(j, np.int64)
    return loops.pair_slots(first, second)


class _StaticShapes:
    """A static group's shapes, read slot by slot at the first step each slot is
    present and reused after: static entities never move, and what an absent slot
    holds (NaN included) is never read (docs/method.md, "The task state")."""

    def __init__(self, shapes: Shapes, known: np.ndarray) -> None:
        self.shapes = shapes
        self.known = known  # (S, B|1): slots whose shapes are read
        self.complete = bool(known.all())

    @staticmethod
    def read(
        group: GroupState, geometry: Geometry, presence: np.ndarray
    ) -> _StaticShapes:
        # A workspace of its own: the arrays belong to the cache.
        shapes = group_shapes(group, geometry, Workspace(), "static")
        return _StaticShapes(shapes, _StaticShapes._present(shapes, presence))

    @staticmethod
    def _present(shapes: Shapes, presence: np.ndarray) -> np.ndarray:
        """(S, B|1) slots present, at the shapes' batch width: a row shared by
        every trial is read once the slot is present in any trial."""
        width = _batch_width(shapes)
        if width == presence.shape[1]:
            return presence.copy()
        if width == 1:
            return np.asarray(presence.any(axis=1, keepdims=True))
        return np.broadcast_to(presence, (presence.shape[0], width)).copy()

    def fits(self, group: GroupState) -> bool:
        """The cache has no fewer trials than ``group``'s shapes (its slots are
        the group's: a change of slot counts empties the caches)."""
        source = group.segments if group.segments is not None else group.centres
        rows = 1 if source is None else source.shape[0]
        return rows == 1 or rows == _batch_width(self.shapes)

    def update(
        self, group: GroupState, geometry: Geometry, presence: np.ndarray, ws: Workspace
    ) -> None:
        """Reads the slots present for the first time."""
        new = _StaticShapes._present(self.shapes, presence)
        np.logical_and(new, np.logical_not(self.known), out=new)
        if not new.any():
            return
        current = group_shapes(group, geometry, ws, "static update")
        for cached, read in zip(_arrays(self.shapes), _arrays(current), strict=True):
            np.copyto(cached, read, where=new)
        self.known |= new
        self.complete = bool(self.known.all())


def _batch_width(shapes: Shapes) -> int:
    return (shapes.x if isinstance(shapes, Discs) else shapes.ax).shape[-1]


def _shared_shapes(cache: _StaticShapes | None) -> Shapes | None:
    """A static group's cached shapes if every slot is known and one row serves
    every trial (so a gathered subset of trials can use them); else None."""
    if cache is None or not cache.complete or _batch_width(cache.shapes) != 1:
        return None
    return cache.shapes


def _arrays(shapes: Shapes) -> tuple[np.ndarray, ...]:
    if isinstance(shapes, Segments):
        return shapes.arrays()
    if shapes.r is None:
        return shapes.x, shapes.y
    return shapes.x, shapes.y, shapes.r


def _deviation(group: GroupState, attribute: int, out: np.ndarray) -> np.ndarray:
    """Writes into ``out`` (B,) the standard deviation (ddof 0) of one attribute
    over each trial's present entities, 0 where none is present; returns where
    it is defined."""
    present, values = np.broadcast_arrays(
        group.present, group.attributes[:, :, attribute]
    )
    n = present.sum(axis=1)
    safe = np.where(present, values, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = safe.sum(axis=1) / n
        spread = np.where(present, (values - mean[:, None]) ** 2, 0.0).sum(axis=1)
        sd = np.sqrt(spread / n)
    defined = np.asarray(n > 0)
    np.copyto(out, np.where(defined, sd, 0.0))
    return np.broadcast_to(defined, out.shape)


def _zero_where(array: np.ndarray, mask: np.ndarray) -> None:
    """Sets ``array`` to 0 where the broadcast ``mask`` holds, in place.

    Absent slots may hold anything, NaN included, so they are overwritten, never
    multiplied by 0. (``np.copyto`` with ``where=`` is fast for the mostly False
    masks of absent entities; ``np.putmask`` is faster only for dense masks.)
    """
    np.copyto(array, 0.0, where=mask)


@dataclass(frozen=True)
class _Plan:
    """A step of :meth:`StepFeatures.compute` for states of one layout: the
    ``reads`` take the state (checks, presence, shapes, attributes) into the
    arrays that the ``calls``, bound to them, then turn into ``total`` and
    ``count``."""

    layout: tuple[object, ...]
    reads: list[Callable[[TaskState], None]]
    calls: list[Callable[[], object]]
    total: np.ndarray
    count: np.ndarray

    def run(self, state: TaskState) -> tuple[np.ndarray, np.ndarray]:
        """``(total, count)`` of ``state``, a state of the plan's layout."""
        for read in self.reads:
            read(state)
        for call in self.calls:
            call()
        return self.total, self.count


def _reader(
    loop: Callable[..., Any], g: int, label: str, *out: np.ndarray
) -> Callable[[TaskState], None]:
    """``loop(array, *out)`` with the state's array ``label`` of group ``g``."""

    def read(state: TaskState) -> None:
        loop(getattr(state.groups[g], label), *out)

    return read


def _deviation_reader(
    g: int, attribute: int, total: np.ndarray, count: np.ndarray
) -> Callable[[TaskState], None]:
    """Group ``g``'s deviation of ``attribute`` into its rows of the totals."""

    def read(state: TaskState) -> None:
        np.copyto(count, _deviation(state.groups[g], attribute, total))

    return read


def _static_reader(
    g: int, cache: _StaticShapes, geometry: Geometry, ws: Workspace
) -> Callable[[TaskState], None]:
    """Reads the slots of a static group's cache as they appear, as
    :meth:`StepFeatures._compute_general` does, until every slot is known."""

    def read(state: TaskState) -> None:
        if cache.complete:
            return
        group = state.groups[g]
        source = group.present.T
        presence = ws.get(("present", g), source.shape, np.bool_)
        np.copyto(presence, source)
        cache.update(group, geometry, presence, ws)

    return read


def _discs_reader(
    g: int, key: Hashable, shapes: Discs, ws: Workspace
) -> Callable[[TaskState], None]:
    """Refills the arrays of ``shapes`` (made by :func:`group_shapes` under
    ``key`` for the layout) from each step's state."""
    centres = ws.get((key, "centres"), (2, *shapes.x.shape))
    radii = shapes.r

    def read(state: TaskState) -> None:
        group = state.groups[g]
        np.copyto(centres, slot_major(group, "centres"))
        if radii is not None:
            np.copyto(radii, slot_major(group, "radii"))

    return read


def _polygons_reader(
    g: int, key: Hashable, shapes: Segments, ws: Workspace
) -> tuple[Segments, Callable[[TaskState], None]]:
    """Segments whose every array a step refills in place from the state, with
    the operations of :func:`group_shapes` (under ``key``) and
    :meth:`Segments.between` (which would make new arrays at every step)."""
    source = ws.get((key, "segments"), (2, 2, *shapes.ax.shape))
    polygons = Segments.between(shapes.ax, shapes.ay, shapes.bx, shapes.by)

    def read(state: TaskState) -> None:
        np.copyto(source, slot_major(state.groups[g], "segments"))
        polygons.derive()

    return polygons, read


class StepFeatures:
    """Computes every behaviour feature of a task for a batch of trials at one step.

    Each feature is kept as a sum and a count over the entities or entity pairs it
    averages (the count is 1 for eq. 2), so that its value is ``total / count``,
    undefined where the count is 0, and so that a NaN or infinite input among present
    entities shows as a non-finite total rather than hiding behind an undefined
    feature. Arrays are feature-major, (F, B), so that each feature is one
    contiguous row.

    A group with ``min_size == max_size`` is *full*: all its slots hold an entity at
    every step (checked), so its sums need no mask and its counts are constants.

    Args:
        description: The task description.
        fixed_static_geometry: Read the geometry of static groups at the first
            step only and reuse it: static entities never move, so within one
            batch their shapes are fixed (their presence is still read every step).
            For a new batch, use a new instance.
        fused: Compute the mean states and every distance that involves a disc
            with the compiled loops of :mod:`.fused`; False computes everything
            with numpy arrays (:mod:`.distance`). Both give the same totals to the
            bit; the loops are faster at the batch sizes evolution runs.

    ``compute(state, trials)`` computes the features of some trials only (the
    active ones, once many trials have ended): a few gathers instead of
    arithmetic on trials whose results are thrown away.
    """

    def __init__(
        self,
        description: TaskDescription,
        fixed_static_geometry: bool = False,
        *,
        fused: bool = True,
        options: SdbcOptions | None = None,
    ) -> None:
        self.description = description
        self.options = options or PAPER
        self.features = behaviour_features(description, self.options)
        self.fixed_static_geometry = fixed_static_geometry
        self.fused = fused
        self._slot_counts: tuple[int, ...] = ()
        self._full = tuple(g.min_size == g.max_size for g in description.groups)
        self._workspace = Workspace()
        self._static: dict[int, _StaticShapes] = {}
        self._constant_counts = {
            f: c
            for f, feature in enumerate(self.features)
            if (c := self._constant_count(feature)) is not None
        }
        self._mean_rows = {
            (feature.group, feature.state_attribute): f
            for f, feature in enumerate(self.features)
            if feature.kind is FeatureKind.MEAN_STATE
        }
        self._buffers_by_size: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._plan: _Plan | None = None
        self._trials_plan: _Plan | None = None
        self._unplanned: tuple[object, ...] | None = None

    @property
    def n_features(self) -> int:
        """F, the number of per-step features."""
        return len(self.features)

    def _buffers(self, n_trials: int) -> tuple[np.ndarray, np.ndarray]:
        """The (F, B) total and count arrays, with the constant counts filled in."""
        buffers = self._buffers_by_size.get(n_trials)
        if buffers is None:
            total = np.empty((self.n_features, n_trials))
            count = np.empty((self.n_features, n_trials))
            for f, value in self._constant_counts.items():
                count[f] = value
            buffers = self._buffers_by_size[n_trials] = (total, count)
        return buffers

    def _gather(self, state: TaskState, trials: np.ndarray) -> TaskState:
        """The state of ``trials`` only, as a batch of their own (all active)."""
        ws = self._workspace
        n_trials = state.active.shape[0]

        def take(g: int, name: str, array: np.ndarray) -> np.ndarray:
            if array.shape[0] != n_trials:
                return array  # shared by every trial
            out = ws.get(
                ("gathered", g, name), trials.shape + array.shape[1:], array.dtype
            )
            return np.take(array, trials, axis=0, out=out)

        def take_any(g: int, name: str, array: np.ndarray | None) -> np.ndarray | None:
            return None if array is None else take(g, name, array)

        groups = tuple(
            GroupState(
                present=take(g, "present", group.present),
                attributes=take(g, "attributes", group.attributes),
                centres=take_any(g, "centres", group.centres),
                radii=take_any(g, "radii", group.radii),
                segments=take_any(g, "segments", group.segments),
            )
            for g, group in enumerate(state.groups)
        )
        active = ws.get("gathered active", trials.shape, np.bool_)
        active.fill(True)
        return TaskState(step=state.step, active=active, groups=groups)

    def _constant_count(self, feature: BehaviourFeature) -> float | None:
        """The count of a feature whose entities or pairs are always all there."""
        groups = self.description.groups
        n = float(groups[feature.group].max_size)
        if feature.kind is FeatureKind.GROUP_SIZE:
            return 1.0
        if feature.kind in (FeatureKind.STATE_DEVIATION, FeatureKind.RELATION):
            return None
        if not self._full[feature.group]:
            return None
        if feature.kind is FeatureKind.MEAN_STATE:
            return n
        if feature.kind is FeatureKind.DISPERSION:
            return n * (n - 1.0) / 2.0
        other = feature.second_group
        if self._full[other]:
            return n * groups[other].max_size
        return None

    def compute(
        self,
        state: TaskState,
        trials: np.ndarray | None = None,
        *,
        layout: tuple[object, ...] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(total, count)``, both (F, B) float64, for one step; the arrays are
        overwritten by the next call with as many trials.

        Args:
            state: The task state of the batch.
            trials: Indices of the trials to compute, all active (B = their
                number); None for the whole batch.
            layout: The state's :func:`~sdbc_sim.task_state.state_layout`, if the
                caller has it; read here otherwise.

        Raises:
            ValueError: If a full group misses an entity in an active trial.
        """
        if not self.fused:
            return self._compute_general(state, trials)
        if trials is not None:
            return self._compute_some(state, trials)
        # The static caches the trials' plan decided on may change from here.
        self._trials_plan = None
        if layout is None:
            layout = state_layout(state)
        plan = self._plan
        if (
            plan is not None
            and layout is not None
            and (plan.layout is layout or plan.layout == layout)
        ):
            return plan.run(state)
        result = self._compute_general(state, None)
        if layout is not None and layout != self._unplanned:
            self._plan = self._make_plan(state, layout, gathered=False)
            # Two polygons: the general path, without trying again every step.
            self._unplanned = layout if self._plan is None else None
        return result

    def _compute_some(
        self, state: TaskState, trials: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`compute` of some trials: their gathered state, a batch of its
        own, by the plan of its layout, which stays while only trials are
        computed (the full batch's steps update the static caches)."""
        self._forget_other_slots(state)
        gathered = self._gather(state, trials)
        layout = state_layout(gathered)
        plan = self._trials_plan
        if plan is not None and layout is not None and plan.layout == layout:
            return plan.run(gathered)
        result = self._compute_gathered(gathered, gathered=True)
        if layout is not None:
            self._trials_plan = self._make_plan(gathered, layout, gathered=True)
        return result

    def _make_plan(
        self, state: TaskState, layout: tuple[object, ...], *, gathered: bool
    ) -> _Plan | None:
        """What :meth:`_compute_general` does at every step with states of
        ``layout``, decided once, from a state it has just computed: which groups'
        presence and shapes to read into which arrays, which loop to call with
        which of them for each feature. None where a feature has no loop (two
        polygons), which then stays with :meth:`_compute_general`. ``gathered``:
        the state holds some trials of the batch (:meth:`_gather`)."""
        groups = self.description.groups
        full = self._full
        slot_counts = self._slot_counts
        total, count = self._buffers(state.active.shape[0])
        reads: list[Callable[[TaskState], None]] = []
        calls: list[Callable[[], object]] = []
        full_groups = [g for g, is_full in enumerate(full) if is_full]
        if full_groups:
            reads.append(functools.partial(self._check_full_groups, full_groups))
        counted: set[int] = set()
        shaped: set[int] = set()
        for feature in self.features:
            if feature.kind is FeatureKind.GROUP_DISTANCE:
                pair = {feature.group, feature.second_group}
                counted |= pair
                shaped |= pair
            elif feature.kind is not FeatureKind.STATE_DEVIATION and (
                feature.kind is not FeatureKind.RELATION
            ):
                counted.add(feature.group)
                if feature.kind is FeatureKind.DISPERSION:
                    shaped.add(feature.group)
        # Row g: group g's sizes in its first width[g] columns (1: one for all).
        sizes = np.empty((len(groups), total.shape[1]))
        width = np.ones(len(groups), dtype=np.int64)
        masks: dict[int, np.ndarray] = {}
        occupancy = _kernel(loops.occupancy)
        for g in sorted(counted):
            if full[g]:
                sizes[g, 0] = groups[g].max_size
                masks[g] = loops.none_absent(slot_counts[g])
                continue
            slot_major = state.groups[g].present.shape[::-1]
            masks[g] = self._workspace.get(("absent", g), slot_major, np.bool_)
            width[g] = slot_major[1]
            reads.append(_reader(occupancy, g, "present", masks[g], sizes[g]))
        # Rows of loops.size_features: (what, f, g, h, rows).
        sized: list[tuple[int, int, int, int, int]] = []
        shapes: dict[int, Shapes] = {}
        for g in sorted(shaped):
            planned = self._plan_shapes(state, g, gathered)
            if planned is None:
                return None
            shapes[g], read = planned
            if read is not None:
                reads.append(read)
        mean_state = _kernel(loops.mean_state_totals)
        constant = self._constant_counts
        for f, feature in enumerate(self.features):
            g = feature.group
            spec = groups[g]
            kind = feature.kind
            if kind is FeatureKind.GROUP_SIZE:
                span = spec.max_size - spec.min_size
                sized.append((loops.GROUP_SIZE, f, g, spec.min_size, span))
            elif kind is FeatureKind.MEAN_STATE:
                if feature.attribute != 0:
                    continue
                rows = slice(f, f + len(spec.attributes))
                reads.append(
                    _reader(mean_state, g, "attributes", masks[g], total[rows])
                )
                if f not in constant:
                    sized.append((loops.SIZE_COUNT, f, g, 0, len(spec.attributes)))
            elif kind is FeatureKind.DISPERSION:
                i, j = slot_pairs(slot_counts[g], None)
                mask = masks[g]
                call = _fused_distance_call(
                    shapes[g], mask, shapes[g], mask, i, j, total[f]
                )
                if call is None:
                    return None
                calls.append(call)
                if not full[g]:
                    sized.append((loops.PAIR_COUNT, f, g, 0, 0))
            elif kind is FeatureKind.GROUP_DISTANCE:
                h = feature.second_group
                first, second = slot_pairs(slot_counts[g], slot_counts[h])
                call = _fused_distance_call(
                    shapes[g], masks[g], shapes[h], masks[h], first, second, total[f]
                )
                if call is None:
                    return None
                calls.append(call)
                if not (full[g] and full[h]):
                    sized.append((loops.CROSS_COUNT, f, g, h, 0))
            elif kind is FeatureKind.STATE_DEVIATION:
                attribute = feature.state_attribute
                reads.append(_deviation_reader(g, attribute, total[f], count[f]))
            else:
                calls.append(functools.partial(self._relation, f, total, count))
        if sized:
            # First: the relations read the mean states' counts.
            rows_of_sizes = np.array(sized, dtype=np.int64)
            size_features = _kernel(loops.size_features)
            calls.insert(
                0,
                functools.partial(
                    size_features, sizes, width, rows_of_sizes, total, count
                ),
            )
        return _Plan(layout, reads, calls, total, count)

    def _plan_shapes(
        self, state: TaskState, g: int, gathered: bool
    ) -> tuple[Shapes, Callable[[TaskState], None] | None] | None:
        """Group ``g``'s shapes in a plan, and how a step reads them (None: never,
        a static group's shapes all known); None if the group has no cache yet.
        As :meth:`_compute_gathered` decides them."""
        spec = self.description.groups[g]
        ws = self._workspace
        group = state.groups[g]
        key: Hashable = g
        if self.fixed_static_geometry and spec.static:
            cache = self._static.get(g)
            if gathered:
                shared = _shared_shapes(cache)
                if shared is not None:
                    return shared, None
                key = ("static", g)
            elif cache is None:
                return None
            elif cache.complete:
                return cache.shapes, None
            else:
                return cache.shapes, _static_reader(g, cache, spec.geometry, ws)
        shapes = group_shapes(group, spec.geometry, ws, key)
        if isinstance(shapes, Discs):
            return shapes, _discs_reader(g, key, shapes, ws)
        return _polygons_reader(g, key, shapes, ws)

    def _check_full_groups(self, full_groups: list[int], state: TaskState) -> None:
        for g in full_groups:
            present = state.groups[g].present
            # Every slot present passes for any trial; else the full check.
            if np.count_nonzero(present) != present.size:
                self._check_full(state, g)

    def _relation(self, f: int, total: np.ndarray, count: np.ndarray) -> None:
        """Writes relation ``f``'s total and count from the mean states' rows."""
        feature = self.features[f]
        spec = self.description.groups[feature.group]
        h, attribute = feature.second_group, feature.state_attribute
        f_g = self._mean_rows[feature.group, attribute]
        same = self.description.groups[h].attributes.index(spec.attributes[attribute])
        f_h = self._mean_rows[h, same]
        defined = (count[f_g] > 0) & (count[f_h] > 0)
        with np.errstate(invalid="ignore", divide="ignore"):
            difference = total[f_g] / count[f_g] - total[f_h] / count[f_h]
        # Undefined: 0 over a count of 0, as an empty group's sums are.
        np.copyto(total[f], np.where(defined, difference, 0.0))
        np.copyto(count[f], defined)

    def _compute_general(
        self, state: TaskState, trials: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`compute`, deciding everything anew from the state."""
        self._forget_other_slots(state)
        if trials is None:
            return self._compute_gathered(state, gathered=False)
        return self._compute_gathered(self._gather(state, trials), gathered=True)

    def _forget_other_slots(self, state: TaskState) -> None:
        slot_counts = tuple(group.present.shape[1] for group in state.groups)
        if slot_counts != self._slot_counts:
            # The scratch arrays of other slot counts will not serve again soon:
            # a message stream's counts follow its entities, and keeping an
            # array for every count seen would grow without bound.
            self._workspace.clear()
            self._static.clear()
            self._slot_counts = slot_counts
            # They hold the caches just dropped, which a state of their layout
            # would read anew.
            self._plan = self._trials_plan = None

    def _compute_gathered(
        self, state: TaskState, *, gathered: bool
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_compute_general` of a state of the whole batch, or of some of
        its trials (``gathered``), whose slot counts are known."""
        groups = self.description.groups
        full = self._full
        ws = self._workspace
        slot_counts = self._slot_counts
        total, count = self._buffers(state.active.shape[0])
        fused = self.fused
        present: dict[int, np.ndarray] = {}
        absent: dict[int, np.ndarray] = {}
        sizes: dict[int, np.ndarray | float] = {}
        shapes: dict[int, Shapes] = {}

        for g, is_full in enumerate(full):
            if is_full:
                self._check_full(state, g)

        def presence(g: int) -> np.ndarray:
            # Slot-major (S, B|1): sums over entities become row additions.
            if g not in present:
                source = state.groups[g].present.T
                present[g] = ws.get(("present", g), source.shape, np.bool_)
                np.copyto(present[g], source)
            return present[g]

        def absence(g: int) -> np.ndarray:
            if g not in absent:
                if fused and not full[g]:
                    # With the size, in one pass over the presence.
                    source = state.groups[g].present
                    slot_major = source.shape[::-1]
                    absent[g] = ws.get(("absent", g), slot_major, np.bool_)
                    sizes[g] = counted = ws.get(("size", g), slot_major[1:])
                    loops.occupancy(source, absent[g], counted)
                else:
                    p = presence(g)
                    absent[g] = np.logical_not(
                        p, out=ws.get(("absent", g), p.shape, np.bool_)
                    )
            return absent[g]

        def size(g: int) -> np.ndarray | float:
            if g not in sizes:
                if full[g]:
                    sizes[g] = float(groups[g].max_size)
                elif fused:
                    absence(g)
                else:
                    p = presence(g)
                    out = ws.get(("size", g), p.shape[1:])
                    sizes[g] = _slot_sum(p.astype(np.float64), (0,), out)
            return sizes[g]

        def shape(g: int) -> Shapes:
            if g in shapes:
                return shapes[g]
            group, geometry = state.groups[g], groups[g].geometry
            if not (self.fixed_static_geometry and groups[g].static):
                shapes[g] = group_shapes(group, geometry, ws, g)
                return shapes[g]
            cache = self._static.get(g)
            if gathered:
                # Some trials only: the cache serves if it is complete and shared;
                # otherwise the gathered state's present slots hold their shapes.
                shared = _shared_shapes(cache)
                shapes[g] = (
                    shared
                    if shared is not None
                    else group_shapes(group, geometry, ws, ("static", g))
                )
                return shapes[g]
            if cache is None or not cache.fits(group):
                cache = self._static[g] = _StaticShapes.read(
                    group, geometry, presence(g)
                )
            elif not cache.complete:
                cache.update(group, geometry, presence(g), ws)
            shapes[g] = cache.shapes
            return shapes[g]

        def reduce_into(f: int, d: np.ndarray, axes: tuple[int, ...]) -> None:
            if d.shape[len(axes) :] == total.shape[1:]:
                _slot_sum(d, axes, total[f])
            else:
                total[f] = _slot_sum(d, axes)

        def mask(g: int) -> np.ndarray:
            return loops.none_absent(slot_counts[g]) if full[g] else absence(g)

        constant = self._constant_counts
        for f, feature in enumerate(self.features):
            g = feature.group
            spec = groups[g]
            if feature.kind is FeatureKind.GROUP_SIZE:
                # Eq. 2.
                np.subtract(size(g), spec.min_size, out=total[f])
                total[f] /= spec.max_size - spec.min_size
            elif feature.kind is FeatureKind.MEAN_STATE:
                # Eq. 3: one sum over slots gives every attribute's numerator, into
                # the group's consecutive attribute rows.
                if feature.attribute == 0:
                    rows = total[f : f + len(spec.attributes)]
                    if fused:
                        attributes = state.groups[g].attributes
                        loops.mean_state_totals(attributes, mask(g), rows)
                    else:
                        self._mean_state_totals(state, g, absence, rows)
                    if f not in constant:
                        count[f : f + len(spec.attributes)] = size(g)
            elif feature.kind is FeatureKind.DISPERSION:
                # Eq. 4 as the mean over unordered pairs i < j of present entities.
                i, j = slot_pairs(slot_counts[g], None)
                shapes_g = shape(g)
                if not (
                    fused
                    and _ran(
                        _fused_distance_call(
                            shapes_g, mask(g), shapes_g, mask(g), i, j, total[f]
                        )
                    )
                ):
                    d = entity_distance(
                        pick(shapes_g, i, ws, ("i", f)),
                        pick(shapes_g, j, ws, ("j", f)),
                        ws,
                        f,
                    )
                    if not full[g]:
                        a = absence(g)
                        shape_ij = (len(i),) + a.shape[1:]
                        invalid = ws.get(("invalid", f), shape_ij, np.bool_)
                        np.logical_or(a[i], a[j], out=invalid)
                        _zero_where(d, invalid)
                    reduce_into(f, d, (0,))
                if not full[g]:
                    # n (n - 1) / 2 in place.
                    n = size(g)
                    np.subtract(n, 1.0, out=count[f])
                    np.multiply(n, count[f], out=count[f])
                    count[f] /= 2.0
            elif feature.kind is FeatureKind.STATE_DEVIATION:
                defined = _deviation(state.groups[g], feature.state_attribute, total[f])
                np.copyto(count[f], defined)
            elif feature.kind is FeatureKind.RELATION:
                self._relation(f, total, count)
            else:
                # Eq. 5: the mean over all pairs of present entities of g and h.
                h = feature.second_group
                first, second = slot_pairs(slot_counts[g], slot_counts[h])
                a_shapes, b_shapes = shape(g), shape(h)
                if not (
                    fused
                    and _ran(
                        _fused_distance_call(
                            a_shapes,
                            mask(g),
                            b_shapes,
                            mask(h),
                            first,
                            second,
                            total[f],
                        )
                    )
                ):
                    d = entity_distance(expand(a_shapes, 1), expand(b_shapes, 0), ws, f)
                    if not (full[g] and full[h]):
                        if full[g]:
                            invalid = absence(h)[None]
                        elif full[h]:
                            invalid = absence(g)[:, None]
                        else:
                            invalid = ws.get(("invalid", f), d.shape, np.bool_)
                            np.logical_or(
                                absence(g)[:, None], absence(h)[None], out=invalid
                            )
                        _zero_where(d, invalid)
                    reduce_into(f, d, (0, 1))
                if not (full[g] and full[h]):
                    np.multiply(size(g), size(h), out=count[f])
        return total, count

    def _check_full(self, state: TaskState, g: int) -> None:
        present = state.groups[g].present
        if present.shape[0] == 1:
            missing = not present.all()
        else:
            missing = not np.logical_or(present, ~state.active[:, None]).all()
        if missing:
            spec = self.description.groups[g]
            raise ValueError(
                f"task {self.description.name!r}, step {state.step}: group "
                f"{spec.name!r} (min_size = max_size = {spec.max_size}) misses an "
                "entity in an active trial"
            )

    def _mean_state_totals(
        self,
        state: TaskState,
        g: int,
        absence: Callable[[int], np.ndarray],
        rows: np.ndarray,
    ) -> None:
        """The numerators of eq. 3 with numpy arrays (``fused=False``)."""
        source = state.groups[g].attributes.transpose(2, 1, 0)
        values = self._workspace.get(("attributes", g), source.shape)
        np.copyto(values, source)
        if not self._full[g]:
            # Absent slots may hold anything, NaN included: zero them.
            _zero_where(values, absence(g)[None])
        if values.shape[2:] == rows.shape[1:]:
            _slot_sum(values, (1,), rows)
        else:
            rows[...] = _slot_sum(values, (1,))

    def values(self, state: TaskState) -> np.ndarray:
        """The (B, F) feature values of one step, NaN where undefined."""
        n = state.active.shape[0]
        validate_task_state(self.description, state, n)
        total, count = self.compute(state)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(count > 0, total / count, np.nan).T
