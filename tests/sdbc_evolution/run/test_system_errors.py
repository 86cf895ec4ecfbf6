"""What the system refuses (disk, permissions, memory) is one line and exit 2 at
``sdbc-evolve`` and ``sdbc-study``. The tests run as root, on a disk with room,
so the refusals are simulated where the system call would fail."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import pytest
import yaml
from sdbc_evolution.run import results
from sdbc_evolution.run.cli import main as evolve
from sdbc_evolution.study.cli import main as study

TINY = {
    "task": "gate_escape",
    "task_config": {"max_steps": 40},
    "treatment": "fit",
    "generations": 3,
    "ga": {"population_size": 6, "elites": 1, "tournament_size": 2},
    "evaluation": {"trials": 1, "reevaluation_trials": 0},
}


@pytest.fixture
def tiny(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.yaml"
    path.write_text(yaml.safe_dump(TINY))
    return path


def run(*args: str) -> int:
    return evolve([*args, "--quiet", "--no-gif", "--workers", "1"])


def refuse(code: int):
    def fail(*args: object, **kwargs: object) -> None:
        raise OSError(code, os.strerror(code))

    return fail


def one_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    return err.strip()


@pytest.mark.parametrize(
    ("command", "code", "expected"),
    [
        ("sdbc-evolve", errno.EROFS, "Read-only file system: {out}/config.yaml "
         "(choose a writable --out)"),
        ("sdbc-study", errno.EACCES, "Permission denied: {out}/study.yaml (choose a "
         "directory you may write, or fix its permissions)"),
    ],
)  # fmt: skip
def test_an_output_directory_that_cannot_be_written(
    tmp_path: Path,
    tiny: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    command: str,
    code: int,
    expected: str,
) -> None:
    monkeypatch.setattr(results.tempfile, "mkstemp", refuse(code))
    out = tmp_path / "out"
    if command == "sdbc-evolve":
        assert run("--config", str(tiny), "--out", str(out)) == 2
    else:
        assert study(["run", "--preset", "smoke", "--out", str(out)]) == 2
    assert one_line(capsys) == f"{command}: error: " + expected.format(out=out)


def test_a_full_disk_mid_run_names_the_file(
    tmp_path: Path, tiny: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    real_fsync, calls = os.fsync, []

    def fsync(fd: int) -> None:
        calls.append(fd)
        if len(calls) > 6:  # past the run's creation, in its first generations
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real_fsync(fd)

    monkeypatch.setattr(results.os, "fsync", fsync)
    out = tmp_path / "run"
    assert run("--config", str(tiny), "--out", str(out)) == 2
    line = one_line(capsys)
    assert line.startswith(f"sdbc-evolve: error: No space left on device: {out}/")
    assert line.endswith(
        "(free some space or choose another --out; --resume continues)"
    )
    monkeypatch.setattr(results.os, "fsync", real_fsync)
    assert run("--resume", "--out", str(out)) == 0


def test_out_of_memory(
    tmp_path: Path, tiny: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    def no_memory(*args: object, **kwargs: object) -> None:
        raise MemoryError

    monkeypatch.setattr("sdbc_evolution.run.experiment.Experiment.create", no_memory)
    assert run("--config", str(tiny), "--out", str(tmp_path / "run")) == 2
    assert one_line(capsys).startswith("sdbc-evolve: error: out of memory: choose")


def test_out_pointing_at_a_file_is_refused(tmp_path: Path, tiny: Path, capsys) -> None:
    file = tmp_path / "file"
    file.write_text("mine")
    assert run("--config", str(tiny), "--out", str(file)) == 2
    assert (
        one_line(capsys) == f"sdbc-evolve: error: --out {file}: a file, not a directory"
    )
    assert study(["run", "--preset", "smoke", "--out", str(file)]) == 2
    assert (
        one_line(capsys) == f"sdbc-study: error: --out {file}: a file, not a directory"
    )
    assert file.read_text() == "mine"


def test_a_population_too_big_for_memory_is_refused_before_any_file(
    tmp_path: Path, tiny: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    monkeypatch.setattr(
        "sdbc_evolution.run.footprint.available_memory", lambda: 8 * 2**30
    )
    out = tmp_path / "run"
    assert run("--config", str(tiny), "--out", str(out), "--population", "2000000") == 2
    line = one_line(capsys)
    assert line.startswith(
        "sdbc-evolve: error: ga.population_size 2000000 x evaluation.trials 1 needs "
        "about "
    )
    assert line.endswith(
        "GiB of memory at once, only 8.0 GiB available: choose a smaller population "
        "or fewer trials"
    )
    need = float(line.split("needs about ")[1].split(" GiB")[0])
    assert need > 8
    assert not out.exists()
    # A population that fits runs.
    assert run("--config", str(tiny), "--out", str(out)) == 0


@pytest.mark.parametrize("population", ["3", "4", "5"])
def test_a_population_too_small_for_the_defaults_names_the_population(
    tmp_path: Path, population: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert run("--task", "gate_escape", "--out", str(tmp_path / "r"),
               "--population", population) == 2  # fmt: skip
    assert one_line(capsys) == (
        f"sdbc-evolve: error: ga.population_size: {population} is too small: must "
        "be at least 6 for tournament_size=5 and elites=5 (or set those lower)"
    )


def test_an_empty_configuration_file_is_an_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    empty = tmp_path / "empty.yaml"
    empty.write_text("")
    assert run("--config", str(empty), "--out", str(tmp_path / "r")) == 2
    assert one_line(capsys) == (
        f"sdbc-evolve: error: {empty} is empty: give at least the task (e.g. "
        "'task: gate_escape'), or leave --config out for the quick start"
    )
    assert not (tmp_path / "r").exists()
