"""What a study's analysis found: per task and for the whole study, the numbers
that the tables, figures and the report are made from.

:mod:`.analysis` computes them and :mod:`.report` writes them up; both read them
from here, so neither imports the other's internals (the analysis calls the report
at its end, the report never calls back).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sdbc_evolution.study.claims import ALPHA, Claim, PredictionResult
from sdbc_evolution.study.cost import CLUSTER_WORKERS, Projection, TaskCost
from sdbc_evolution.study.digest import StudyDigest
from sdbc_evolution.study.exploration import ExplorationMaps, SomSettings
from sdbc_evolution.study.quality import Curves, PairTest
from sdbc_evolution.study.relevance import RelevanceTable
from sdbc_evolution.study.rundirs import RunProblem
from sdbc_evolution.study.sensitivity import MapSensitivity


@dataclass(frozen=True)
class AnalysisSettings:
    """How a study is analysed."""

    som: SomSettings = field(default_factory=SomSettings)
    """The exploration maps."""
    top_features: int = 6
    """Features per task in the report's relevance table (the paper: 5-6)."""
    alpha: float = ALPHA
    """Significance level of the claims."""
    cluster_workers: tuple[int, ...] = CLUSTER_WORKERS
    """Cluster sizes of the paper preset's projection."""
    sensitivity_seeds: int = 0
    """Maps trained again per grid, seeds ``som.seed`` on, to measure the
    exploration numbers' sensitivity (from run directories only; 0: none)."""
    sensitivity_grids: tuple[tuple[int, int], ...] | None = None
    """Their (rows, columns); None: :func:`~.exploration.default_grids`."""

    def __post_init__(self) -> None:
        if self.top_features < 1:
            raise ValueError(f"top_features must be >= 1, got {self.top_features}")
        if not 0 < self.alpha < 1:
            raise ValueError(f"alpha must be in (0, 1), got {self.alpha}")
        if not self.cluster_workers or min(self.cluster_workers) < 1:
            raise ValueError("cluster_workers must be positive")
        if self.sensitivity_seeds < 0:
            raise ValueError(
                f"sensitivity_seeds must be >= 0, got {self.sensitivity_seeds}"
            )
        if self.sensitivity_grids is not None and (
            not self.sensitivity_grids
            or min(min(g) for g in self.sensitivity_grids) < 2
        ):
            raise ValueError("sensitivity_grids: at least one, each at least 2 x 2")

    @property
    def seeds(self) -> tuple[int, ...]:
        """The sensitivity analysis's seeds (none when it is not asked for)."""
        return tuple(range(self.som.seed, self.som.seed + self.sensitivity_seeds))


@dataclass
class TaskAnalysis:
    """Everything computed for one task."""

    task: str
    curves: Curves
    bests: dict[str, np.ndarray]
    best_runs: dict[str, tuple[str, ...]]
    tests: list[PairTest]
    relevance: RelevanceTable | None
    maps: ExplorationMaps
    cost: TaskCost
    figures: dict[str, Path]
    other_relevance: dict[str, RelevanceTable] = field(default_factory=dict)
    """Relevance tables of the weighting treatments other than NS-SD+."""
    relevance_above_chance: RelevanceTable | None = None
    """NS-SD+'s MI above chance, ranked (the relevance claims' basis)."""
    statistic: str = ""
    """Which statistic of a run ``bests`` holds (:func:`.quality.run_statistic`)."""
    last_tests: list[PairTest] = field(default_factory=list)
    """The same tests on each run's last best (reported, deciding nothing)."""
    sensitivity: list[MapSensitivity] = field(default_factory=list)
    """The exploration numbers on other maps and region sizes
    (:mod:`.sensitivity`), of each kind the digest allows."""


@dataclass
class Analysis:
    """A whole study's analysis."""

    digest: StudyDigest
    settings: AnalysisSettings
    tasks: list[TaskAnalysis]
    claims: list[Claim]
    predictions: list[PredictionResult]
    """The preset's own predictions, judged (:mod:`.predictions`)."""
    projections: list[Projection]
    out: Path

    @property
    def problems(self) -> list[RunProblem]:
        """Runs left out."""
        return list(self.digest.problems)

    @property
    def sessions(self) -> list[dict[str, Any]]:
        """The study log's entries."""
        return list(self.digest.sessions)
