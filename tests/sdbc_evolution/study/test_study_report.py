"""The report names every run left out, sums up a task not run at all, times a
task by the sessions that ran it, and sets the paper beside the paper's tasks only."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest
import yaml
from sdbc_evolution.study.analysis import REPORT_FILE, TABLES_DIR
from sdbc_evolution.study.cli import main
from sdbc_evolution.study.report import _problem_lines, session_wall_seconds
from sdbc_evolution.study.rundirs import MISSING, RunProblem
from study_helpers import TINY


def test_a_task_not_run_at_all_is_one_line_and_other_problems_stay_named():
    problems = [
        RunProblem("gate_escape/fit/run_03", "generations.csv: truncated"),
        RunProblem("gate_escape/fit/run_04", MISSING),
        RunProblem("predator_prey/fit/run_00", MISSING),
        RunProblem("predator_prey/ns-sd/run_00", MISSING),
    ]
    lines = _problem_lines(problems, tasks_with_runs={"gate_escape"})
    assert lines == [
        "- `gate_escape/fit/run_03`: generations.csv: truncated",
        "- `gate_escape/fit/run_04`: missing",
        "- `predator_prey`: not run yet (2 runs missing)",
    ]


def test_sessions_one_after_another_add_up_and_shards_at_once_count_once():
    def session(started: str, elapsed: float) -> dict:
        return {"started": f"2026-11-24T{started}+00:00", "elapsed_s": elapsed}

    one_after_another = [session("00:00:00", 60.0), session("01:00:00", 30.0)]
    assert session_wall_seconds(one_after_another) == 90.0
    at_once = [
        session("00:00:00", 60.0),
        session("00:00:10", 60.0),
        session("00:00:20", 10.0),
        session("00:05:00", 5.0),
    ]
    assert session_wall_seconds(at_once) == 75.0
    assert session_wall_seconds([{"elapsed_s": 4.0}, {"elapsed_s": 5.0}]) == 9.0


@pytest.mark.slow
def test_a_study_of_a_task_the_paper_did_not_run_has_no_paper_column(
    tmp_path: Path,
) -> None:
    """wide_gate:WideGate (this folder) is no task of the paper's: its report has
    our numbers only, and no claim of the paper's applies."""
    task = "wide_gate:WideGate"
    preset = {
        **TINY,
        "name": "other",
        "tasks": [task],
        "treatments": ["fit", "ns-sd+"],
        "generations": {task: 2},
        "task_config": {task: {"max_steps": 60}},
    }
    path = tmp_path / "other.yaml"
    path.write_text(yaml.safe_dump(preset))
    out = tmp_path / "study"
    argv = ["--preset", str(path), "--out", str(out), "--workers", "1", "--quiet"]
    assert main(argv) == 0
    text = (out / "report" / REPORT_FILE).read_text()
    assert text.startswith("# A study with sdbc: wide gate\n")
    for paper_only in (
        "(paper)",
        "paper mean (SD)",
        "## The paper's claims",
        "## Where we differ",
        "share of the paper's",
        "on a cluster",
    ):
        assert paper_only not in text, paper_only
    assert "### Relevance of behaviour features" in text
    assert "the task declares no mapping" in text
    with open(out / "report" / TABLES_DIR / "claims.csv", newline="") as f:
        assert list(csv.DictReader(f)) == []
