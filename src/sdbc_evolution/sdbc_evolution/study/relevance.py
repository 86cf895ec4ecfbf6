"""Relevance of behaviour features: the paper's mutual information table, and the
same table for every other treatment that weighs the SDBC.

NS-SD+ weighs SDBC dimension k by w_k = delta + I(F; k) every generation, and the run
directory records the weights in force (``weight:<name>`` columns of
``generations.csv``). So each NS-SD+ run gives, per generation,

    I_g(F; k) = w_{g,k} - delta

in bits. The relevance of feature k in a run is its mean over the run's generations;
the table gives the mean and SD of that over the runs, sorted by the mean, and marks
the features that the task-specific characterisation also has. A declared
treatment that weighs by another relevance measure (``transforms: [standardise,
{weight: {relevance: NAME}}]``) records its weights the same way, so its table is
w - delta in that measure's units (for ``mi_chance``, the MI minus its chance
level, in bits).

Beside it, the **chance level** of each feature: the same estimate on the same
populations with each generation's fitness shuffled, I_g(F'; k), averaged over
:data:`CHANCE_GENERATIONS` evenly spaced generations of each run and then over the
runs. The plug-in estimate of a feature unrelated to fitness is not 0 but about
(b_F - 1)(b_k - 1) / (2 n ln 2) bits for b_F fitness classes, b_k occupied bins and
n individuals (Miller, 1955): 1.2 bits for 10 x 10 classes and n = 50. What a
feature has above its chance level is what it shares with fitness.

Which SDBC dimensions "the task-specific characterisation also has" is a judgement;
each task makes it once, in its ``sdbc_counterparts`` (read by
:func:`task_specific_features`): each task-specific feature maps to the SDBC
dimensions that measure the same thing with the same aggregation (a feature averaged
over the trial matches the (M) dimension, a final one the (F)).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from sdbc_evolution.relevance.measures import chance_information
from sdbc_evolution.run.config import ExperimentConfig
from sdbc_evolution.run.results import WEIGHT_PREFIX
from sdbc_evolution.study.digest import TaskDigest
from sdbc_evolution.study.rundirs import RunData


def task_specific_features(task: str) -> Mapping[str, tuple[str, ...]]:
    """Dimension of ``task``'s task-specific characterisation -> the SDBC dimensions
    that match it, as the task declares them (``Task.sdbc_counterparts``); empty
    for a task that declares none or that this project does not know."""
    from sdbc_sim.tasks import find_task

    task_class = find_task(task)
    return dict(task_class.sdbc_counterparts) if task_class is not None else {}


def task_specific_dimensions(task: str) -> frozenset[str]:
    """SDBC dimensions of ``task`` that its task-specific characterisation has
    (empty for a task without a mapping)."""
    return frozenset(
        name for names in task_specific_features(task).values() for name in names
    )


PAPER_WEIGHTED = "ns-sd+"
"""The paper's weighted treatment: its table is the one the paper's claims read."""
BITS = ("mi", "mi_chance")
"""Relevance measures in bits, to which the MI's chance level applies."""


def weight_measure(config: ExperimentConfig) -> str | None:
    """The relevance measure a run's weights come from; None if it weighs nothing."""
    from sdbc_evolution.transforms.pipeline import WeightOptions

    for transform in config.treatment.transforms:
        if isinstance(transform.options, WeightOptions):
            return transform.options.measure.name
    return None


def run_information(run: RunData) -> np.ndarray:
    """(D,) mean over the run's generations of w_k - delta: I(F; k) in bits for
    NS-SD+, the relevance by the run's own measure for any weighting treatment.

    Raises:
        ValueError: The run has no weights (it weighs nothing).
    """
    weights = np.column_stack(
        [run.columns[WEIGHT_PREFIX + name] for name in run.sdbc_names]
    )
    recorded = np.isfinite(weights).all(axis=1)
    if not recorded.any():
        raise ValueError(f"{run.name}: no weights in {WEIGHT_PREFIX}* columns")
    return weights[recorded].mean(axis=0) - run.config.weighting.delta


CHANCE_GENERATIONS = 20
"""Generations per run, evenly spaced, whose MI is re-estimated with shuffled
fitness for the chance level."""


def run_chance_information(
    run: RunData, generations: int = CHANCE_GENERATIONS
) -> np.ndarray:
    """(D,) mean of the chance level
    (:func:`sdbc_evolution.relevance.measures.chance_information`, the estimate
    weighted treatments can subtract) over ``generations`` evenly spaced
    generations of ``run``, with the run's own weighting settings, the shuffles
    seeded by the generation so that the analysis repeats."""
    chosen = np.unique(
        np.linspace(0, run.generations - 1, min(generations, run.generations))
        .round()
        .astype(int)
    )
    return np.mean(
        [
            chance_information(
                run.sdbc(g), run.fitness[g], run.config.weighting, int(g)
            )
            for g in chosen
        ],
        axis=0,
    )


@dataclass(frozen=True)
class RelevanceTable:
    """Relevance of every SDBC dimension to fitness on one task, from one
    weighting treatment's runs (NS-SD+: mutual information, the paper's table).

    Attributes:
        task: Task name.
        names: (D,) dimension names, most relevant first.
        mean: (D,) mean over runs of each run's mean w - delta (for NS-SD+, the
            mean I(F; k), bits).
        sd: (D,) standard deviation over runs (ddof 1; NaN with one run).
        runs: Runs it comes from.
        in_task_specific: (D,) whether the task-specific characterisation has it.
        chance: (D,) mean over runs of the MI's chance level (module docstring),
            bits.
        treatment: The treatment whose runs it comes from.
        measure: Its relevance measure (``mi`` for NS-SD+).
    """

    task: str
    names: tuple[str, ...]
    mean: np.ndarray
    sd: np.ndarray
    runs: int
    in_task_specific: np.ndarray
    chance: np.ndarray
    treatment: str = PAPER_WEIGHTED
    measure: str = "mi"

    def top(self, n: int) -> RelevanceTable:
        """The ``n`` most relevant dimensions."""
        return RelevanceTable(
            self.task,
            self.names[:n],
            self.mean[:n],
            self.sd[:n],
            self.runs,
            self.in_task_specific[:n],
            self.chance[:n],
            self.treatment,
            self.measure,
        )

    def rank_of(self, name: str) -> int | None:
        """1-based rank of a dimension, None if absent."""
        return self.names.index(name) + 1 if name in self.names else None


def relevance_table(
    task: TaskDigest, treatment: str = PAPER_WEIGHTED
) -> RelevanceTable | None:
    """The table from the task's runs of ``treatment`` (None without any run
    that recorded weights)."""
    measured = [
        (r.information, r.chance, r.config)
        for r in task.of(treatment)
        if r.information is not None and r.chance is not None
    ]
    if not measured:
        return None
    information = np.stack([i for i, _, _ in measured])  # (R, D)
    chance = np.stack([c for _, c, _ in measured]).mean(axis=0)
    measure = weight_measure(measured[0][2]) or "mi"
    return _ranked(task, information, chance, treatment, measure)


def _ranked(
    task: TaskDigest,
    per_run: np.ndarray,
    chance: np.ndarray,
    treatment: str,
    measure: str,
) -> RelevanceTable:
    """The table of ``per_run`` (R, D) relevance: mean and SD over the runs,
    ranked by the mean, with each dimension's ``chance`` level (D,)."""
    mean = per_run.mean(axis=0)
    sd = (
        per_run.std(axis=0, ddof=1)
        if per_run.shape[0] > 1
        else np.full(mean.shape, np.nan)
    )
    order = np.argsort(-mean, kind="stable")
    matched = task_specific_dimensions(task.task)
    ordered = tuple(task.sdbc_names[i] for i in order)
    return RelevanceTable(
        task=task.task,
        names=ordered,
        mean=mean[order],
        sd=sd[order],
        runs=per_run.shape[0],
        in_task_specific=np.array([n in matched for n in ordered]),
        chance=chance[order],
        treatment=treatment,
        measure=measure,
    )


ABOVE_CHANCE = "mi above chance"
"""The measure of :func:`above_chance_table`: each run's MI minus its own chance
level, bits."""


def above_chance_table(
    task: TaskDigest, treatment: str = PAPER_WEIGHTED
) -> RelevanceTable | None:
    """The table of ``treatment``'s MI above its chance level: per run
    I(F; k) - chance_k (both from the digest), then mean and SD over runs and
    ranked by the mean. At population 50 the raw plug-in MI is mostly the
    estimator's bias, the same for every feature with the same number of
    occupied bins, so this ranking is the one that says what a feature shares
    with fitness. None where the treatment does not weigh by raw MI."""
    raw = relevance_table(task, treatment)
    if raw is None or raw.measure != "mi":
        return None
    measured = [
        r.information - r.chance
        for r in task.of(treatment)
        if r.information is not None and r.chance is not None
    ]
    chance = np.stack(
        [r.chance for r in task.of(treatment) if r.chance is not None]
    ).mean(axis=0)
    return _ranked(task, np.stack(measured), chance, treatment, ABOVE_CHANCE)


def chance_pass_rate(dimensions: int, marked: int, top: int, at_least: int) -> float:
    """The chance that a ranking drawn at random (every order of the
    ``dimensions`` equally likely) puts at least ``at_least`` of ``marked``
    dimensions among its first ``top``: the exact permutation probability,
    hypergeometric."""
    from math import comb

    total = comb(dimensions, top)
    hits = sum(
        comb(marked, j) * comb(dimensions - marked, top - j)
        for j in range(at_least, min(marked, top) + 1)
    )
    return hits / total


def other_relevance_tables(task: TaskDigest) -> dict[str, RelevanceTable]:
    """The tables of every weighting treatment but NS-SD+, in the task's
    treatment order."""
    tables = {}
    for treatment in task.treatments():
        if treatment == PAPER_WEIGHTED:
            continue
        table = relevance_table(task, treatment)
        if table is not None:
            tables[treatment] = table
    return tables
