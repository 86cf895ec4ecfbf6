"""End to end on the real engine: a run stopped and resumed on other evaluators
equals an uninterrupted one, bit for bit."""

from __future__ import annotations

from pathlib import Path

import pytest
from evolution_helpers import assert_same_run
from sdbc_evolution.run.config import config_from_dict
from sdbc_evolution.run.evaluators import DaskEvaluator, LocalEvaluator
from sdbc_evolution.run.experiment import Experiment, task_spec


def tiny(treatment: str, generations: int):
    return config_from_dict(
        {
            "task": "gate_escape",
            "task_config": {"max_steps": 60},
            "treatment": treatment,
            "generations": generations,
            "seed": 2,
            "ga": {"population_size": 8, "elites": 2, "tournament_size": 3},
            "novelty": {"k": 3, "archive_probability": 0.2},
            "evaluation": {"trials": 2, "reevaluation_trials": 3},
        }
    )


@pytest.mark.parametrize("treatment", ["ns-sd+", "fit"])
def test_stop_and_resume_on_other_evaluators_equals_a_straight_run(
    tmp_path: Path, treatment: str
) -> None:
    from distributed import LocalCluster

    spec = task_spec(tiny(treatment, 4))
    with LocalEvaluator(spec, workers=1) as one:
        Experiment.create(tiny(treatment, 4), tmp_path / "straight", one).run()
    with LocalEvaluator(spec, workers=2) as two:
        Experiment.create(tiny(treatment, 2), tmp_path / "resumed", two).run()
    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster,
        DaskEvaluator(spec, cluster.scheduler_address) as dask,
    ):
        experiment = Experiment.resume(tiny(treatment, 4), tmp_path / "resumed", dask)
        assert experiment.state.generation == 2
        experiment.run()
    assert_same_run(tmp_path / "straight", tmp_path / "resumed")
