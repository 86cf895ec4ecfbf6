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


LIVE_WITHOUT = """\
import sys
for name in sys.argv[1:]:
    sys.modules[name] = None  # not importable, as on a plain pip install
from sdbc_evolution.conformance import main
sys.exit(main(["--live", "point_chase", "--robots", "2", "--genome-length", "6"]))
"""


@pytest.mark.parametrize("missing", [["rclpy"], ["sdbc_msgs"], ["rclpy", "sdbc_msgs"]])
def test_live_checks_without_ros_are_one_line_and_exit_2(missing: list[str]) -> None:
    import subprocess
    import sys

    done = subprocess.run(
        [sys.executable, "-c", LIVE_WITHOUT, *missing],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2, done.stderr
    assert done.stdout == ""
    [line] = done.stderr.strip().splitlines()
    assert line.startswith(
        f"sdbc-conformance --live: error: needs {', '.join(missing)}, which "
    ), line
    assert "run scripts/sdbc setup" in line, line


def test_the_task_checks_load_no_ros() -> None:
    import subprocess
    import sys

    done = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys, sdbc_evolution.conformance\n"
            "print(sorted({'rclpy', 'sdbc_msgs'} & set(sys.modules)))",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--check", "ranges"], "--check names checks of a task; --live runs its own"),
        (["--robots", "0"], "--robots: must be at least 1, got 0"),
        (["--graph-timeout", "1e300"], "--graph-timeout: must be in (0, "),
        (["--graph-timeout", "nan"], "--graph-timeout: must be in (0, "),
    ],
)
def test_bad_live_flags_are_one_line_and_exit_2(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["point_chase", "--live", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err, err
