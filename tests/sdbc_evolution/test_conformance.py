"""Each conformance check catches a task broken on purpose in the way it looks for
(the broken tasks are in broken_tasks.py), and passes on the task unbroken."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from sdbc_evolution.conformance import CHECKS, main, run_checks

BROKEN = Path(__file__).resolve().parent / "broken_tasks.py"
SHORT = {"max_steps": 60}
"""Short trials: the checks need not run the task's 1000 steps to catch a fault."""


@pytest.mark.parametrize(
    ("task", "check", "message"),
    [
        ("WrongCounterparts", "declaration", r"\['Robot group size \(F\)'\] are not"),
        ("NaNSpeed", "task_state", "group 'Agent': a present entity has a non-finite"),
        ("FitnessAboveOne", "ranges", r"fitness 1\.\d+ outside \[0, 1\]"),
        ("BatchDependent", "batch", "alone and in the batch, fitness"),
        ("ProcessDependent", "process", "in another process, fitness"),
        pytest.param(
            "ObservedChanges",
            "live",
            "live and in the batch, characterisation",
            marks=pytest.mark.ros,
        ),
        ("LaxSettings", "settings", "max_steps = 1000.5 is accepted"),
    ],
)
def test_each_check_catches_its_fault(task: str, check: str, message: str) -> None:
    reference = f"{BROKEN}:{task}"
    [result] = run_checks(reference, SHORT, [check])
    assert not result.passed
    assert result.name == check
    assert re.search(message, result.detail), result.detail


@pytest.mark.ros
def test_the_unbroken_task_passes_them_all_by_file_reference() -> None:
    results = run_checks(f"{BROKEN}:GateEscape", SHORT)
    failed = [f"{r.name}: {r.detail}" for r in results if not r.passed]
    assert [r.name for r in results] == list(CHECKS) and not failed, failed


def test_the_faults_are_caught_only_where_they_are() -> None:
    # A faulty task passes the checks it does not break: a check fails for its
    # reason, not for any fault at all.
    for task, check in (
        ("FitnessAboveOne", "batch"),
        ("BatchDependent", "ranges"),
        ("ObservedChanges", "batch"),
        ("LaxSettings", "declaration"),
    ):
        [result] = run_checks(f"{BROKEN}:{task}", SHORT, [check])
        assert result.passed, (task, check, result.detail)


def test_the_command_exits_1_on_a_failed_check_and_2_on_bad_input(
    capsys: pytest.CaptureFixture[str],
) -> None:
    reference = f"{BROKEN}:FitnessAboveOne"
    argv = [reference, "--task-config", "{max_steps: 60}", "--check", "ranges"]
    assert main(argv) == 1
    out = capsys.readouterr().out
    assert "FAIL ranges" in out and "0/1 checks passed" in out
    assert main(["gate_scape"]) == 2
    assert "unknown task 'gate_scape'" in capsys.readouterr().err
    assert main(["gate_escape", "--task-config", "[1, 2]"]) == 2
