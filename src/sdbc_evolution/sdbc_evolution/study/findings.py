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

    def __post_init__(self) -> None:
        if self.top_features < 1:
            raise ValueError(f"top_features must be >= 1, got {self.top_features}")
        if not 0 < self.alpha < 1:
            raise ValueError(f"alpha must be in (0, 1), got {self.alpha}")
        if not self.cluster_workers or min(self.cluster_workers) < 1:
            raise ValueError("cluster_workers must be positive")


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
