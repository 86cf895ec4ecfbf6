"""The report names every run left out, sums up a task not run at all, and times a
task by the sessions that ran it."""

from __future__ import annotations

from sdbc_evolution.study.report import _problem_lines, session_wall_seconds
from sdbc_evolution.study.rundirs import MISSING, RunProblem


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
