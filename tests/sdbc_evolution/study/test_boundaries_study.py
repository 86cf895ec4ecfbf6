"""``sdbc-study run`` at the boundaries: a real full disk (a small tmpfs) is one
line and exit 2 with the study's own way to continue, in process and with
worker processes alike, and the same command then finishes the study; the run
lock's note on a full disk names its file; the memory check counts the runs
side by side; a damaged finished run is run again; a run another session
finished is not counted as this one's; a digest opens nothing outside its
folder."""

from __future__ import annotations

import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml
from sdbc_evolution.study.cli import main as study
from study_helpers import TINY


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A 100 kB tmpfs: the tiny study needs about 150 kB."""
    mount = tmp_path / "disk"
    mount.mkdir()
    made = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=100k", "tmpfs", str(mount)],
        capture_output=True,
        text=True,
    )
    if made.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {made.stderr.strip()}")
    try:
        yield mount
    finally:
        subprocess.run(["umount", str(mount)], check=True)


@pytest.mark.parametrize("workers", ["1", "2"])
def test_a_full_disk_under_a_study_is_one_line_then_the_same_command_continues(
    tmp_path: Path, small_disk: Path, capsys: pytest.CaptureFixture[str], workers
) -> None:
    preset = tmp_path / "tiny.yaml"
    preset.write_text(yaml.safe_dump(TINY))
    out = small_disk / "study"
    argv = ["run", "--preset", str(preset), "--out", str(out), "--quiet"]
    argv += ["--workers", workers]
    assert study(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert "No space left on device: " in err and str(out) in err
    assert err.endswith(
        "(free some space or choose another --out; the same "
        "sdbc-study command continues)"
    ), err
    assert "--resume" not in err
    subprocess.run(["mount", "-o", "remount,size=2m", str(small_disk)], check=True)
    assert study(argv) == 0
    capsys.readouterr()
    assert study(argv) == 0
    assert "4 of 4 runs already finished" in capsys.readouterr().err


def test_the_memory_check_counts_the_runs_that_go_side_by_side(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from sdbc_evolution.run.evaluators import TaskInfo
    from sdbc_evolution.run.experiment import task_spec
    from sdbc_evolution.run.footprint import check_footprint, run_footprint
    from sdbc_evolution.study.plan import study_plan
    from study_helpers import tiny_preset

    config = study_plan(tiny_preset(), tmp_path / "plan")[0].config
    info = TaskInfo.of(task_spec(config))
    one = run_footprint(config, info).total
    two = run_footprint(config, info, runs=2).total
    assert two > 2 * one  # two runs' memory, and a process for each
    # Room for one run, not for two side by side.
    monkeypatch.setattr(
        "sdbc_evolution.run.footprint.available_memory", lambda: (one + two) // 2
    )
    check_footprint(config, info, runs=1)
    preset = tmp_path / "tiny.yaml"
    preset.write_text(yaml.safe_dump(TINY))
    out = tmp_path / "study"
    argv = ["run", "--preset", str(preset), "--out", str(out), "--quiet"]
    assert study([*argv, "--workers", "2", "--joined-runs", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert (
        "sdbc-study: error: ga.population_size 6 x evaluation.trials 2 in 2 runs "
        "side by side with 2 processes needs about" in err
    ), err
    assert err.endswith("fewer trials or fewer workers"), err
    # Joined (the default), the task's four runs share the two processes.
    assert study([*argv, "--workers", "2"]) == 2
    err = capsys.readouterr().err.strip()
    assert "in 4 runs side by side with 2 processes needs about" in err, err
    assert not out.exists()  # refused before the study directory


def test_a_finished_run_with_a_damaged_row_is_not_counted_finished_but_run_again(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    preset = tmp_path / "tiny.yaml"
    preset.write_text(yaml.safe_dump({**TINY, "runs": 1, "treatments": ["fit"]}))
    out = tmp_path / "study"
    argv = ["run", "--preset", str(preset), "--out", str(out), "--quiet"]
    argv += ["--workers", "1"]
    assert study(argv) == 0
    rows = out / "gate_escape" / "fit" / "run_00" / "generations.csv"
    lines = rows.read_text().splitlines()
    lines[1] = lines[1][: len(lines[1]) // 2]  # a row cut mid-way, as a crash can
    rows.write_text("\n".join(lines) + "\n")
    capsys.readouterr()
    assert study(argv) == 0
    err = capsys.readouterr().err
    assert "gate_escape/fit/run_00: cannot resume" in err, err
    assert f"{rows}: the row of generation 0 has" in err and "moved to" in err
    assert "already finished" not in err
    assert len(rows.read_text().splitlines()) == 1 + TINY["generations"]["gate_escape"]
    assert study(argv) == 0
    assert "1 of 1 runs already finished" in capsys.readouterr().err


@pytest.mark.parametrize("task", ["../outside", "/etc/passwd", ".hidden", "a/b", ""])
def test_a_digest_opens_no_file_outside_its_folder(tmp_path: Path, task: str) -> None:
    from sdbc_evolution.study.digest import DigestError, task_file

    with pytest.raises(DigestError, match="outside the digest's folder"):
        task_file(tmp_path, task, tmp_path / "study.json")
    assert task_file(tmp_path, "gate_escape", tmp_path / "study.json") == (
        tmp_path / "gate_escape.npz"
    )


def test_a_run_another_session_finished_is_not_counted_as_this_ones(
    tmp_path: Path,
) -> None:
    from sdbc_evolution.run.evaluators import LocalEvaluator
    from sdbc_evolution.run.experiment import task_spec
    from sdbc_evolution.study.plan import study_plan
    from sdbc_evolution.study.presets import preset_from_dict
    from sdbc_evolution.study.runner import execute_run, run_study

    preset = preset_from_dict({**TINY, "runs": 1, "treatments": ["fit"]})
    out = tmp_path / "study"
    first = run_study(preset, out, quiet=True)
    assert [r.name for r in first.ran] == ["gate_escape/fit/run_00"]
    # A second session that planned the run before the first finished it.
    [spec] = study_plan(preset, out)
    with LocalEvaluator(task_spec(spec.config), workers=1) as evaluator:
        outcome = execute_run(spec, evaluator, lambda g: None, {})
    assert outcome.finished and outcome.by_other


def test_a_lock_note_on_a_full_disk_names_the_lock_file(small_disk: Path) -> None:
    from sdbc_evolution.run.lock import RunLock

    (small_disk / "run").mkdir()
    with open(small_disk / "filler", "wb", buffering=0) as f:
        try:
            while True:
                f.write(b"x" * 4096)
        except OSError:
            pass  # full
    with pytest.raises(OSError) as refused:
        RunLock(small_disk / "run").acquire()
    assert refused.value.filename == str(small_disk / "run" / ".lock")
    assert "No space left on device" in str(refused.value)
