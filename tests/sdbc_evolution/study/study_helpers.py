"""Helpers of the study tests: a tiny preset on the real engine, run contents."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from sdbc_evolution.run.results import GENERATIONS_FILE, TIME_COLUMNS
from sdbc_evolution.study.compare import CLAIMS_TABLE, COLUMNS
from sdbc_evolution.study.plan import study_plan
from sdbc_evolution.study.presets import StudyPreset, preset_from_dict
from sdbc_evolution.study.runner import Execution, run_study
from sdbc_evolution.study.verdicts import RULE_COLUMNS

TINY = {
    "name": "tiny",
    "description": "two treatments, two runs, two generations of six",
    "runs": 2,
    "seed": 5,
    "tasks": ["gate_escape"],
    "treatments": ["fit", "ns-sd+"],
    "generations": {"gate_escape": 2},
    "task_config": {"gate_escape": {"max_steps": 60}},
    "experiment": {
        "ga": {"population_size": 6, "elites": 1, "tournament_size": 2},
        "novelty": {"k": 3},
        "evaluation": {"trials": 2, "reevaluation_trials": 2},
    },
}


def tiny_preset() -> StudyPreset:
    """The tiny study: gate escape, Fit and NS-SD+, 2 runs of 2 generations."""
    return preset_from_dict(TINY)


def _exact(array: np.ndarray) -> tuple[str, tuple[int, ...], bytes]:
    # Bytes, so that NaN equals NaN and -0.0 differs from 0.0.
    return (array.dtype.str, array.shape, array.tobytes())


def run_contents(run: Path) -> dict[str, object]:
    """A run directory's results without its timings: ``generations.csv`` rows
    with the time columns dropped, and every array of every individuals file."""
    with open(run / GENERATIONS_FILE, newline="") as f:
        rows = list(csv.reader(f))
    keep = [i for i, name in enumerate(rows[0]) if name not in TIME_COLUMNS]
    out: dict[str, object] = {"csv": [[r[i] for i in keep] for r in rows]}
    for file in sorted((run / "individuals").glob("*.npz")):
        with np.load(file) as data:
            for key in data.files:
                out[f"{file.name}:{key}"] = _exact(data[key])
    out["best_genomes"] = _exact(np.load(run / "best_genomes.npy"))
    return out


def straight_study(preset: StudyPreset, root: Path) -> Path:
    """``preset`` run in one go, in this process, one run after the other: what
    any other way of running it must equal."""
    run_study(preset, root, execution=Execution(workers=1, joined_runs=1), quiet=True)
    return root


def assert_same_study(preset: StudyPreset, a: Path, b: Path) -> None:
    """Every run of the two study directories has the same results."""
    for x, y in zip(study_plan(preset, a), study_plan(preset, b), strict=True):
        assert run_contents(x.path) == run_contents(y.path), x.name


def write_claims(
    folder: Path, rows: list[tuple[str, str, str, str]], rules: bool = False
) -> Path:
    """A claims table in ``folder``; rows: (task, statement, ours, verdict). With
    ``rules``, the columns of today's rules too: A is ``ours`` where that is a
    number (its interval +- 0.2), no test where it is empty."""
    path = folder / CLAIMS_TABLE
    path.parent.mkdir(parents=True)
    header = list(COLUMNS[:-1]) + (list(RULE_COLUMNS) if rules else []) + ["verdict"]
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        for task, statement, ours, verdict in rows:
            cells = ["quality", task, statement, "p < 0.05", ours, ""]
            if rules:
                a = [0.1, ours, float(ours) - 0.2, float(ours) + 0.2] if ours else []
                cells = cells[:-1] + [0.05] + (a or ["", "", "", ""]) + ["champion"]
            writer.writerow([*cells, verdict])
    return folder
