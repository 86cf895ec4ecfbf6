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
   and the authors' code take the mean, which SPEC.md follows. f_D is symmetric, so
   the mean over ordered pairs i != j is the mean over unordered pairs i < j;
4. ``d(g, h) = sum_{e_i in g} sum_{e_j in h} f_D(e_i, e_j) / (|g| |h|)``, the mean
   distance to every later group h (eq. 5), unless both groups are static.

A feature is NaN at a step where it is undefined: the means and distances of an empty
group, the dispersion of a group with fewer than two entities.

:class:`StepFeatures` computes them all for a batch of trials in a few numpy
operations per feature: pair indices are built once, and no Python loop runs over
trials or entities.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np
from sdbc_sim.task_state import (
    EntityGroupSpec,
    Geometry,
    GroupState,
    TaskDescription,
    TaskState,
)

from sdbc_evolution.sdbc.distance import (
    Shapes,
    Workspace,
    entity_distance,
    expand,
    group_shapes,
    pick,
)


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


@dataclass(frozen=True)
class BehaviourFeature:
    """One per-step behaviour feature.

    Attributes:
        kind: Which of eqs. 2 to 5 it is.
        group: Index of its entity group in the task description.
        name: Human name, derived from the group and attribute names:
            "Agent group size", "Gate is closing", "Agent dispersion",
            "Predators-prey distance".
        attribute: Index of the state attribute (MEAN_STATE only).
        other: Index of the second group (GROUP_DISTANCE only), always > ``group``.
    """

    kind: FeatureKind
    group: int
    name: str
    attribute: int | None = None
    other: int | None = None


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
    initial in lower case (the paper's "Predators-prey distance")."""
    spec = description.groups[group]
    if kind is FeatureKind.GROUP_SIZE:
        return f"{spec.name} group size"
    if kind is FeatureKind.MEAN_STATE:
        return f"{spec.name} {spec.attributes[attribute]}"
    if kind is FeatureKind.DISPERSION:
        return f"{spec.name} dispersion"
    return f"{spec.name}-{_lower_initial(description.groups[other].name)} distance"


def has_group_size(group: EntityGroupSpec) -> bool:
    """Eq. 2 applies: the group's size can change."""
    return group.max_size > group.min_size


def has_dispersion(group: EntityGroupSpec) -> bool:
    """Eq. 4 applies: the group moves and can hold two entities."""
    return not group.is_static and group.max_size > 1


def has_group_distance(group: EntityGroupSpec, other: EntityGroupSpec) -> bool:
    """Eq. 5 applies: at least one of the two groups moves."""
    return not (group.is_static and other.is_static)


def behaviour_features(description: TaskDescription) -> tuple[BehaviourFeature, ...]:
    """The per-step features of a task, in characterisation order.

    Raises:
        ValueError: If two features get the same name (for example a state attribute
            called "dispersion" or "group size", or two groups whose names differ only
            in the case of their first letter).
    """
    features: list[BehaviourFeature] = []
    groups = description.groups
    for g, group in enumerate(groups):
        specs: list[tuple[FeatureKind, int | None, int | None]] = []
        if has_group_size(group):
            specs.append((FeatureKind.GROUP_SIZE, None, None))
        specs.extend(
            (FeatureKind.MEAN_STATE, a, None) for a in range(len(group.attributes))
        )
        if has_dispersion(group):
            specs.append((FeatureKind.DISPERSION, None, None))
        specs.extend(
            (FeatureKind.GROUP_DISTANCE, None, h)
            for h in range(g + 1, len(groups))
            if has_group_distance(group, groups[h])
        )
        for kind, attribute, other in specs:
            name = feature_name(description, kind, g, attribute, other)
            features.append(BehaviourFeature(kind, g, name, attribute, other))
    names = [f.name for f in features]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise ValueError(
            f"task description {description.name!r}: features with the same name "
            f"{duplicates}; rename the attribute or group"
        )
    return tuple(features)


def validate_task_state(
    description: TaskDescription, state: TaskState, n_trials: int
) -> None:
    """Checks that a task state has the shapes its description promises.

    Raises:
        ValueError: Naming the group and array that do not fit.
    """
    where = f"task {description.name!r}, step {state.step}"
    active = np.asarray(state.active)
    if active.shape != (n_trials,) or active.dtype != np.bool_:
        raise ValueError(
            f"{where}: active must be a ({n_trials},) bool array, got {active.dtype} "
            f"{active.shape}"
        )
    if len(state.groups) != len(description.groups):
        raise ValueError(
            f"{where}: {len(state.groups)} groups in the state, "
            f"{len(description.groups)} in the description"
        )
    for spec, group in zip(description.groups, state.groups, strict=True):
        _validate_group(where, spec, group, n_trials)


def _validate_group(
    where: str, spec: EntityGroupSpec, group: GroupState, n_trials: int
) -> None:
    def check(label: str, array: object, tail: tuple[int, ...]) -> None:
        if not isinstance(array, np.ndarray):
            raise ValueError(f"{where}, group {spec.name!r}: {label} is missing")
        if array.shape[:1] not in ((1,), (n_trials,)) or array.shape[1:] != tail:
            raise ValueError(
                f"{where}, group {spec.name!r}: {label} has shape {array.shape}, "
                f"expected ({n_trials} or 1, {', '.join(map(str, tail))})"
            )
        expected = np.bool_ if label == "present" else np.float64
        if array.dtype != expected:
            raise ValueError(
                f"{where}, group {spec.name!r}: {label} has dtype {array.dtype}, "
                f"expected {np.dtype(expected)}"
            )

    size = spec.max_size
    check("present", group.present, (size,))
    check("attributes", group.attributes, (size, len(spec.attributes)))
    if spec.geometry is Geometry.POLYGON:
        # Any number P >= 1 of segments per polygon.
        segments = group.segments
        n_segments = segments.shape[2] if getattr(segments, "ndim", 0) == 5 else 0
        check("segments", segments, (size, max(n_segments, 1), 2, 2))
    else:
        check("centres", group.centres, (size, 2))
        if spec.geometry is Geometry.CIRCLE:
            check("radii", group.radii, (size,))


class StepFeatures:
    """Computes every behaviour feature of a task for a batch of trials at one step.

    Each feature is kept as a sum and a count over the entities or entity pairs it
    averages (the count is 1 for eq. 2), so that its value is ``total / count``,
    undefined where the count is 0, and so that a NaN or infinite input among present
    entities shows as a non-finite total rather than hiding behind an undefined
    feature. Arrays are feature-major, (F, B), so that each feature is one
    contiguous row.

    Args:
        description: The task description.
    """

    def __init__(self, description: TaskDescription) -> None:
        self.description = description
        self.features = behaviour_features(description)
        self._pairs = {
            g: np.triu_indices(group.max_size, k=1)
            for g, group in enumerate(description.groups)
            if has_dispersion(group)
        }
        self._workspace = Workspace()

    @property
    def n_features(self) -> int:
        """F, the number of per-step features."""
        return len(self.features)

    def compute(self, state: TaskState, total: np.ndarray, count: np.ndarray) -> None:
        """Fills ``total`` and ``count``, both (F, B) float64, for one step."""
        groups = self.description.groups
        ws = self._workspace
        present: dict[int, np.ndarray] = {}
        sizes: dict[int, np.ndarray] = {}
        shapes: dict[int, Shapes] = {}
        attribute_sums: dict[int, np.ndarray] = {}

        def presence(g: int) -> np.ndarray:
            # Slot-major (S, B|1): sums over entities become row additions.
            if g not in present:
                source = state.groups[g].present.T
                present[g] = ws.get(("present", g), source.shape, np.bool_)
                np.copyto(present[g], source)
            return present[g]

        def size(g: int) -> np.ndarray:
            if g not in sizes:
                p = presence(g)
                sizes[g] = np.add.reduce(
                    p, axis=0, dtype=np.float64, out=ws.get(("size", g), p.shape[1:])
                )
            return sizes[g]

        def shape(g: int) -> Shapes:
            if g not in shapes:
                shapes[g] = group_shapes(state.groups[g], groups[g].geometry, ws, g)
            return shapes[g]

        def masked_sum(f: int, d: np.ndarray, valid: np.ndarray, axes: tuple[int, ...]):
            # Absent slots may hold anything, NaN included: zero them, never multiply.
            invalid = np.logical_not(valid, out=valid)
            np.copyto(d, 0.0, where=invalid)
            total[f] = np.add.reduce(
                d, axis=axes, out=ws.get(("sum", f), d.shape[len(axes) :])
            )

        for f, feature in enumerate(self.features):
            g = feature.group
            spec = groups[g]
            if feature.kind is FeatureKind.GROUP_SIZE:
                # Eq. 2.
                total[f] = (size(g) - spec.min_size) / (spec.max_size - spec.min_size)
                count[f] = 1.0
            elif feature.kind is FeatureKind.MEAN_STATE:
                # Eq. 3: one masked sum over slots gives every attribute's numerator.
                if g not in attribute_sums:
                    source = state.groups[g].attributes.transpose(2, 1, 0)
                    masked = ws.get(("attributes", g), source.shape)
                    np.copyto(masked, source)
                    p = presence(g)
                    absent_g = np.logical_not(
                        p, out=ws.get(("absent", g), p.shape, np.bool_)
                    )
                    np.copyto(masked, 0.0, where=absent_g[None])
                    attribute_sums[g] = np.add.reduce(
                        masked,
                        axis=1,
                        out=ws.get(("attribute sums", g), masked.shape[::2]),
                    )
                total[f] = attribute_sums[g][feature.attribute]
                count[f] = size(g)
            elif feature.kind is FeatureKind.DISPERSION:
                # Eq. 4 as the mean over unordered pairs i < j of present entities.
                i, j = self._pairs[g]
                d = entity_distance(
                    pick(shape(g), i, ws, ("i", f)),
                    pick(shape(g), j, ws, ("j", f)),
                    ws,
                    f,
                )
                p = presence(g)
                valid = ws.get(("valid", f), (len(i),) + p.shape[1:], np.bool_)
                np.logical_and(p[i], p[j], out=valid)
                masked_sum(f, d, valid, (0,))
                n = size(g)
                count[f] = n * (n - 1.0) / 2.0
            else:
                # Eq. 5: the mean over all pairs of present entities of g and h.
                h = feature.other
                d = entity_distance(expand(shape(g), 1), expand(shape(h), 0), ws, f)
                pg, ph = presence(g), presence(h)
                valid = ws.get(("valid", f), d.shape, np.bool_)
                np.logical_and(pg[:, None], ph[None, :], out=valid)
                masked_sum(f, d, valid, (0, 1))
                np.multiply(size(g), size(h), out=count[f])

    def values(self, state: TaskState) -> np.ndarray:
        """The (B, F) feature values of one step, NaN where undefined."""
        n = state.active.shape[0]
        validate_task_state(self.description, state, n)
        total = np.empty((self.n_features, n))
        count = np.empty((self.n_features, n))
        self.compute(state, total, count)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(count > 0, total / count, np.nan).T
