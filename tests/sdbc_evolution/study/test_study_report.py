"""The report names every run left out, and sums up a task not run at all."""

from __future__ import annotations

from sdbc_evolution.study.report import _problem_lines
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
