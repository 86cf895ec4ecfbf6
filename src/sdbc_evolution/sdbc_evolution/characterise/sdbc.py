"""The SDBC as a characteriser, with the options of the authors' later code and of
the paper's future work; the defaults are the paper's.

Options (:class:`SdbcOptions`):

- ``aggregation``: ``mean+final`` (paper), ``mean``, ``final``, ``regression`` or
  ``{frames: N}`` (:mod:`.aggregation`);
- ``state_deviation``: per group, the standard deviation of each state attribute
  over the group's present entities (ddof 0; undefined with none present):
  "<Group> <attribute> deviation" (the authors' later code);
- ``relations``: for every two groups g before h with a state attribute of the same
  name a, theta_g(a) - theta_h(a): "<Group>-<other> <attribute> difference" (the
  paper's extension (i), inter-group relations);
- ``ignore_groups``: groups left out by name, with every feature that involves them.

Per step the features are computed as for the paper (eqs. 2 to 5); the added ones
follow, in the order above; then the aggregation mode makes the dimensions. With the
paper's options the fast :class:`~sdbc_evolution.sdbc.characterisation.SdbcExtractor`
runs unchanged; any other options run :class:`OptionedSdbcExtractor`, which streams
too (per trial it keeps the mode's running sums, never the trajectory).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from sdbc_sim.settings import check, settings
from sdbc_sim.task_state import TaskDescription, TaskState, validate_task_state

from sdbc_evolution.characterise.aggregation import MODES, make_aggregator, mode_names
from sdbc_evolution.characterise.base import Characteriser, per_controller
from sdbc_evolution.sdbc.characterisation import SdbcExtractor
from sdbc_evolution.sdbc.features import (
    FeatureKind,
    StepFeatures,
    _lower_initial,
    behaviour_features,
)


@settings
class SdbcOptions:
    """How the SDBC is made; the defaults are the paper's."""

    aggregation: str | dict[str, int] = "mean+final"
    """``mean+final``, ``mean``, ``final``, ``regression`` or ``{frames: N}``."""
    state_deviation: bool = False
    """Add each group's per-attribute standard deviation over its entities."""
    relations: bool = False
    """Add the difference of same-named attributes between two groups."""
    ignore_groups: tuple[str, ...] = ()
    """Groups left out, by name."""

    def __post_init__(self) -> None:
        aggregation = self.aggregation
        modes = [m for m in MODES if m != "frames"]
        if isinstance(aggregation, dict):
            check(
                set(aggregation) == {"frames"},
                "aggregation",
                f"{aggregation!r} must be one of {modes} or {{frames: N}}",
            )
            check(
                aggregation["frames"] >= 1,
                "aggregation.frames",
                f"{aggregation['frames']!r} must be an integer >= 1",
            )
        else:
            check(
                aggregation in modes,
                "aggregation",
                f"{aggregation!r} must be one of {modes} or {{frames: N}}",
            )
        check(
            len(set(self.ignore_groups)) == len(self.ignore_groups),
            "ignore_groups",
            f"{list(self.ignore_groups)} has duplicates",
        )

    @property
    def mode(self) -> str:
        """The aggregation mode's name."""
        return "frames" if isinstance(self.aggregation, dict) else self.aggregation

    @property
    def frames(self) -> int:
        """N of ``frames: N`` (0 for the other modes)."""
        return self.aggregation["frames"] if isinstance(self.aggregation, dict) else 0

    @property
    def is_paper(self) -> bool:
        """The paper's options."""
        return self == SdbcOptions()


@dataclass(frozen=True)
class _Layout:
    """Which per-step features an options set yields for a task, and their names."""

    base: np.ndarray  # indices of the paper's features kept
    deviation: tuple[tuple[int, int], ...]  # (group, attribute)
    relations: tuple[tuple[int, int], ...]  # (feature of g, feature of h)
    names: tuple[str, ...]


def _layout(description: TaskDescription, options: SdbcOptions) -> _Layout:
    groups = description.groups
    known = [g.name for g in groups]
    unknown = [name for name in options.ignore_groups if name not in known]
    if unknown:
        raise ValueError(
            f"sdbc option ignore_groups: task {description.name!r} has no group "
            f"{unknown}; its groups: {known}"
        )
    ignored = {known.index(name) for name in options.ignore_groups}
    features = behaviour_features(description)
    base = [
        f
        for f, feature in enumerate(features)
        if feature.group not in ignored and feature.other not in ignored
    ]
    if not base:
        raise ValueError(
            f"sdbc option ignore_groups: nothing is left of task {description.name!r}"
        )
    names = [features[f].name for f in base]
    deviation: list[tuple[int, int]] = []
    if options.state_deviation:
        for g, spec in enumerate(groups):
            if g in ignored or spec.static or spec.max_size < 2:
                continue
            for a, attribute in enumerate(spec.attributes):
                deviation.append((g, a))
                names.append(f"{spec.name} {attribute} deviation")
    relations: list[tuple[int, int]] = []
    if options.relations:
        mean_state = {
            (feature.group, groups[feature.group].attributes[feature.attribute]): f
            for f, feature in enumerate(features)
            if feature.kind is FeatureKind.MEAN_STATE and feature.attribute is not None
        }
        for g, spec in enumerate(groups):
            for h in range(g + 1, len(groups)):
                if g in ignored or h in ignored:
                    continue
                for attribute in spec.attributes:
                    if attribute in groups[h].attributes:
                        relations.append(
                            (mean_state[g, attribute], mean_state[h, attribute])
                        )
                        names.append(
                            f"{spec.name}-{_lower_initial(groups[h].name)} "
                            f"{attribute} difference"
                        )
        if not relations:
            raise ValueError(
                f"sdbc option relations: task {description.name!r} has no state "
                "attribute shared by two groups"
            )
    return _Layout(np.array(base), tuple(deviation), tuple(relations), tuple(names))


def sdbc_dimension_names(
    description: TaskDescription, options: SdbcOptions | None = None
) -> tuple[str, ...]:
    """The human name of every dimension of the SDBC with ``options`` of a task."""
    options = options or SdbcOptions()
    return mode_names(options.mode, options.frames, _layout(description, options).names)


def _deviation(group: Any, attribute: int, n_trials: int) -> np.ndarray:
    """(B,) SD over present entities of one attribute; NaN with none present."""
    present, values = np.broadcast_arrays(
        group.present, group.attributes[:, :, attribute]
    )
    n = present.sum(axis=1)
    safe = np.where(present, values, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = safe.sum(axis=1) / n
        spread = np.where(present, (values - mean[:, None]) ** 2, 0.0).sum(axis=1)
        sd = np.where(n > 0, np.sqrt(spread / n), np.nan)
    return np.broadcast_to(sd, (n_trials,))


class OptionedSdbcExtractor:
    """Streams task states into per-trial SDBC vectors with any :class:`SdbcOptions`.

    An engine observer like :class:`SdbcExtractor` (``start``, ``observe``,
    ``characterisations``); it also reads ``sdbc_msgs`` streams through
    :class:`~sdbc_evolution.sdbc.messages.MessageSdbcExtractor`'s states.
    """

    def __init__(
        self, options: SdbcOptions, fixed_static_geometry: bool = True
    ) -> None:
        self.options = options
        self.fixed_static_geometry = fixed_static_geometry
        self._features: StepFeatures | None = None
        self._layout: _Layout | None = None
        self._aggregator: Any = None
        self._step = 0

    def start(self, description: TaskDescription, n_trials: int) -> None:
        """Prepares for a batch of ``n_trials`` trials of the described task."""
        self._features = StepFeatures(
            description, fixed_static_geometry=self.fixed_static_geometry
        )
        self._layout = _layout(description, self.options)
        self._aggregator = make_aggregator(
            self.options.mode, self.options.frames, n_trials, len(self._layout.names)
        )
        self._n_trials = n_trials
        self._step = 0

    def redescribe(self, description: TaskDescription) -> None:
        """Continues under ``description``, which must yield the same features
        (a group's geometry learnt from a message stream); the sums are kept.

        Raises:
            ValueError: If the features differ.
        """
        if behaviour_features(description) != self._step_features().features:
            raise ValueError(
                f"SDBC extractor, task {description.name!r}: a new description must "
                "keep the features of the old one"
            )
        self._features = StepFeatures(
            description, fixed_static_geometry=self.fixed_static_geometry
        )

    @property
    def dimension_names(self) -> tuple[str, ...]:
        """Names of the dimensions of :meth:`characterisations`."""
        layout = self._started()
        return mode_names(self.options.mode, self.options.frames, layout.names)

    def _started(self) -> _Layout:
        if self._layout is None:
            raise RuntimeError("SDBC extractor: start() was not called")
        return self._layout

    def _step_features(self) -> StepFeatures:
        if self._features is None:
            raise RuntimeError("SDBC extractor: start() was not called")
        return self._features

    def observe(self, state: TaskState) -> None:
        """Adds the step ``state.step`` of every active trial."""
        layout = self._started()
        features = self._step_features()
        description = features.description
        validate_task_state(description, state, self._n_trials)
        if state.step != self._step + 1:
            raise ValueError(
                f"SDBC extractor, task {description.name!r}: step {state.step} follows "
                f"step {self._step}; steps must arrive in order from 1"
            )
        total, count = features.compute(state)
        with np.errstate(invalid="ignore", divide="ignore"):
            every = np.where(count > 0, total / count, np.nan).T  # (B, F)
        columns = [every[:, layout.base]]
        for g, a in layout.deviation:
            columns.append(_deviation(state.groups[g], a, self._n_trials)[:, None])
        for f, h in layout.relations:
            columns.append((every[:, f] - every[:, h])[:, None])
        self._aggregator.update(np.concatenate(columns, axis=1), state.active)
        self._step = state.step

    def characterisations(self) -> np.ndarray:
        """(B, D) per-trial vectors so far."""
        self._started()
        return self._aggregator.result()


class SdbcCharacteriser(Characteriser):
    """The SDBC of every controller: the mean over its trials of the trial vectors."""

    def __init__(self, options: SdbcOptions | None = None) -> None:
        self.options = options or SdbcOptions()
        self.extractor: Any = (
            SdbcExtractor(check_values=False)
            if self.options.is_paper
            else OptionedSdbcExtractor(self.options)
        )

    def names(self, task: Any) -> tuple[str, ...]:
        return sdbc_dimension_names(task.description, self.options)

    def start(self, description: TaskDescription, n_trials: int) -> None:
        self.extractor.start(description, n_trials)

    def observe(self, state: TaskState) -> None:
        self.extractor.observe(state)

    def controller_vectors(self, result: Any, trials: int) -> np.ndarray:
        return per_controller(self.extractor.characterisations(), trials)
