"""Champions re-evaluated: fresh seeds of their own, part of a run, resumable."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from sdbc_evolution.run.results import read_generations
from sdbc_evolution.study import champions as champions_module
from sdbc_evolution.study.champions import (
    CHAMPION_FILE,
    champion_seeds,
    read_champions,
)
from sdbc_evolution.study.plan import RunProgress, run_status, study_plan
from sdbc_evolution.study.presets import PresetError, preset_from_dict
from sdbc_evolution.study.runner import Execution, run_study
from study_helpers import TINY

CHAMPIONS = {**TINY, "champion_trials": 50}


def test_champion_seeds_are_a_branch_of_their_own() -> None:
    seeds = champion_seeds(5, "gate_escape", "fit", 0, 50)
    assert seeds.dtype == np.int64 and seeds.shape == (50,)
    assert (seeds >= 0).all() and len(set(seeds.tolist())) == 50
    assert np.array_equal(seeds, champion_seeds(5, "gate_escape", "fit", 0, 50))
    # Every run, every study seed, another stream; the first trials are the
    # same whatever the count, so more trials only add seeds.
    others = [
        champion_seeds(5, "gate_escape", "fit", 1, 50),
        champion_seeds(5, "gate_escape", "ns-sd+", 0, 50),
        champion_seeds(6, "gate_escape", "fit", 0, 50),
    ]
    assert all(not set(seeds.tolist()) & set(o.tolist()) for o in others)
    assert np.array_equal(champion_seeds(5, "gate_escape", "fit", 0, 60)[:50], seeds)


def test_preset_refuses_too_few_champion_trials() -> None:
    with pytest.raises(PresetError, match="champion_trials"):
        preset_from_dict({**TINY, "champion_trials": 10})
    assert "champion_trials" not in preset_from_dict(TINY).to_dict()


def test_a_run_ends_with_its_champions_reevaluated_and_resumes_them(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    preset = preset_from_dict(CHAMPIONS)
    root = tmp_path / "study"
    outcome = run_study(preset, root, execution=Execution(workers=1), quiet=True)
    assert not outcome.failed and len(outcome.ran) == 4
    plan = study_plan(preset, root)
    for spec in plan:
        assert run_status(spec).state is RunProgress.FINISHED
        judged = read_champions(spec.path)
        assert judged.trials == 50 and judged.seeds == spec.champion_seeds
        columns = read_generations(spec.path)
        curve = columns["reevaluated_fitness"]
        assert judged.champion.generation == int(np.argmax(curve))
        assert judged.curve_value == curve[judged.champion.generation]
        assert judged.last.generation == spec.generations - 1
        assert len(judged.champion.trial_fitness) == 50
        assert np.isclose(judged.champion.mean, np.mean(judged.champion.trial_fitness))
    first = plan[0].path / CHAMPION_FILE
    kept = first.read_bytes()

    # A re-evaluation killed halfway leaves no file: the run is not finished,
    # and the next session does the re-evaluation, nothing else.
    first.unlink()
    assert run_status(plan[0]).state is RunProgress.REEVALUATE

    def killed(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    with monkeypatch.context() as patch:
        patch.setattr(champions_module.Evaluator, "evaluate", killed)
        outcome = run_study(preset, root, execution=Execution(workers=1), quiet=True)
    assert outcome.interrupted and not first.exists()
    said: list[str] = []
    outcome = run_study(
        preset, root, execution=Execution(workers=1), quiet=True, say=said.append
    )
    assert [r.name for r in outcome.ran] == [plan[0].name] and outcome.ran[0].finished
    assert any("champions to re-evaluate" in line for line in said)
    assert first.read_bytes() == kept  # the same trials give the same numbers

    # A file made with other seeds (or trials) is not the study's.
    other = plan[1].path / CHAMPION_FILE
    other.write_text(other.read_text().replace('"trials": 50', '"trials": 49'))
    assert run_status(plan[1]).state is RunProgress.REEVALUATE


def test_the_digest_keeps_the_champions_and_verdicts_use_them(
    tmp_path: Path,
) -> None:
    from sdbc_evolution.study.analysis import analyse, analyse_digest_dir
    from sdbc_evolution.study.digest import DIGEST_DIR, read_digest
    from sdbc_evolution.study.exploration import SomSettings
    from sdbc_evolution.study.findings import AnalysisSettings

    preset = preset_from_dict(CHAMPIONS)
    root = tmp_path / "study"
    run_study(preset, root, execution=Execution(workers=1), quiet=True)
    settings = AnalysisSettings(som=SomSettings(rows=3, columns=3, iterations=200))
    analysis = analyse(root, tmp_path / "report", settings)
    digest = read_digest(tmp_path / "report" / DIGEST_DIR)
    for run in digest.runs:
        judged = read_champions(root / run.name)
        assert run.champions is not None
        assert run.champions.fitness == judged.champion.fitness
        assert run.champions.last_fitness == judged.last.fitness
        assert run.champions.generation == judged.champion.generation
    task = analysis.tasks[0]
    assert task.statistic.startswith("champion re-evaluated in 50 fresh trials")
    assert task.bests["fit"].tolist() == [
        r.champions.fitness for r in digest.of("gate_escape", "fit") if r.champions
    ]
    report = (tmp_path / "report" / "report.md").read_text()
    assert "champion re-evaluated in 50 fresh trials" in report
    # From the digest alone: the same numbers.
    again = analyse_digest_dir(tmp_path / "report" / DIGEST_DIR, tmp_path / "again")
    assert again.tasks[0].bests["fit"].tolist() == task.bests["fit"].tolist()

    # A run whose champions are missing is left out and named.
    (root / digest.runs[0].name / CHAMPION_FILE).unlink()
    from sdbc_evolution.study.rundirs import load_study

    study = load_study(root)
    assert [p.name for p in study.problems] == [digest.runs[0].name]
    assert "champions not re-evaluated" in study.problems[0].reason

    # A finished task alone, as a digest part: the others' runs are left aside.
    from sdbc_evolution.study.analysis import only_tasks

    assert only_tasks(study, ["gate_escape"]).runs == study.runs
    assert only_tasks(study, None) is study
    with pytest.raises(FileNotFoundError, match="predator_prey"):
        only_tasks(study, ["predator_prey"])


def test_an_old_digest_says_it_uses_the_curve_maximum(tmp_path: Path) -> None:
    from sdbc_evolution.study.analysis import analyse_digest_dir

    studies = Path(__file__).resolve().parents[3] / "docs" / "study"
    analysis = analyse_digest_dir(studies / "local" / "digest", tmp_path)
    assert all(
        t.statistic.startswith("highest point of the curve") for t in analysis.tasks
    )
    assert "10 trials; no champion re-evaluation" in analysis.tasks[0].statistic
