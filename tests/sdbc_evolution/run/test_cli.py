"""The command line: runs, resumes, and bad input that exits 2 with a clear message."""

from __future__ import annotations

from pathlib import Path

import pytest
from evolution_helpers import TINY_RUN_YAML as TINY
from sdbc_evolution.run.cli import main
from sdbc_evolution.run.config import (
    ExperimentConfig,
    config_from_dict,
    load_config,
    quickstart_config,
)
from sdbc_evolution.run.results import read_generations

CONFIGS = Path(__file__).resolve().parents[3] / "configs"


@pytest.fixture
def tiny(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.yaml"
    path.write_text(TINY)
    return path


def run_cli(*args: str) -> int:
    return main([*args, "--no-gif", "--quiet", "--workers", "1"])


def snapshot(out: Path) -> dict[str, bytes]:
    return {str(p): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}


def test_run_then_resume_for_more_generations(
    tmp_path: Path, tiny: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    assert run_cli("--config", str(tiny), "--out", str(out), "--seed", "4") == 0
    printed = capsys.readouterr().out
    assert f"results: {out.resolve()}" in printed and "best individual" in printed
    assert len(read_generations(out)["generation"]) == 2
    assert load_config(out / "config.yaml").seed == 4
    assert run_cli("--resume", "--out", str(out), "--generations", "3") == 0
    assert read_generations(out)["generation"].tolist() == [0, 1, 2]
    assert load_config(out / "config.yaml").generations == 3


def test_the_best_individual_is_rendered_to_a_gif(
    tmp_path: Path, tiny: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    argv = ["--config", str(tiny), "--out", str(out), "--quiet", "--workers", "2"]
    assert main(argv) == 0
    gif = out / "best.gif"
    assert gif.read_bytes()[:6] in (b"GIF87a", b"GIF89a")
    assert f"its trial: {gif.resolve()}" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--population", "1"], "ga.population_size: Input should be greater than"),
        (["--generations", "0"], "generations: Input should be greater than"),
        (["--task", "gate_scape"], "unknown task 'gate_scape'"),
        (["--physics", "soft"], "evaluation.physics: Input should be 'rigid' or"),
        (
            # Refused at once, not after the timeout.
            ["--scheduler", "tcp://127.0.0.1:9", "--connect-timeout", "600"],
            "no Dask scheduler at 'tcp://127.0.0.1:9': connection refused",
        ),
    ],
)
def test_bad_input_exits_2_naming_the_problem(
    tmp_path: Path,
    tiny: Path,
    capsys: pytest.CaptureFixture[str],
    args: list[str],
    message: str,
) -> None:
    argv = [
        "--config",
        str(tiny),
        "--out",
        str(tmp_path / "x"),
        "--no-gif",
        "--quiet",
        *args,
    ]
    assert main(argv) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_resume_needs_the_run_directory(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["--resume", "--no-gif"]) == 2
    assert "--resume needs --out" in capsys.readouterr().err
    assert main(["--resume", "--out", str(tmp_path / "nothing"), "--no-gif"]) == 2
    assert "holds no run" in capsys.readouterr().err


def test_bad_config_file_names_the_key(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("task: gate_escape\nga: {elite: 3}\n")
    assert run_cli("--config", str(bad), "--out", str(tmp_path / "x")) == 2
    assert "ga.elite" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("setting", "message"),
    [
        ("max_steps: .nan", "task_config.max_steps: Input should be a valid integer"),
        ("max_steps: 300.5", "task_config.max_steps: Input should be a valid integer"),
        ("max_speed: .inf", "task_config.max_speed: Input should be a finite number"),
        ("max_speed: '1'", "task_config.max_speed: Input should be a valid number"),
    ],
)
def test_a_bad_task_setting_exits_2_before_any_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], setting: str, message: str
) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text(TINY.replace("{max_steps: 60}", "{" + setting + "}"))
    assert run_cli("--config", str(bad), "--out", str(tmp_path / "x")) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_corrupt_or_foreign_checkpoints_exit_2_and_change_nothing(
    tmp_path: Path, tiny: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    assert run_cli("--config", str(tiny), "--out", str(out)) == 0
    capsys.readouterr()
    before = snapshot(out)
    assert run_cli("--config", str(tiny), "--out", str(out)) == 2
    assert "already holds a run" in capsys.readouterr().err
    assert run_cli("--resume", "--out", str(out), "--population", "8") == 2
    assert "ga.population_size: 6 in the checkpoint, 8 now" in capsys.readouterr().err
    assert run_cli("--resume", "--out", str(out), "--task", "predator_prey") == 2
    assert "from task 'gate_escape'" in capsys.readouterr().err
    assert snapshot(out) == before
    checkpoint = out / "checkpoint.npz"
    checkpoint.write_bytes(checkpoint.read_bytes()[:100])
    before = snapshot(out)
    assert run_cli("--resume", "--out", str(out), "--generations", "3") == 2
    assert "corrupt checkpoint" in capsys.readouterr().err
    assert snapshot(out) == before


def test_the_quickstart_file_is_the_quickstart_config() -> None:
    assert load_config(CONFIGS / "quickstart.yaml") == quickstart_config()


@pytest.mark.parametrize("task", ["gate_escape", "resource_sharing", "predator_prey"])
def test_paper_configs_are_spec_defaults(task: str) -> None:
    config = load_config(CONFIGS / "paper" / f"{task}.yaml")
    assert config == ExperimentConfig(task=task).resolved()
    assert config == config_from_dict({"task": task}).resolved()


@pytest.mark.slow
def test_sigterm_to_the_command_alone_stops_it_and_resume_finishes(
    tmp_path: Path,
) -> None:
    # As a batch scheduler stops a job at its time limit: SIGTERM to the command,
    # not its worker processes, which must stop with it all the same.
    import os
    import signal
    import subprocess
    import sys
    import time

    config = tmp_path / "longer.yaml"
    config.write_text(TINY.replace("generations: 2", "generations: 40"))
    out = tmp_path / "run"
    command = [
        sys.executable, "-m", "sdbc_evolution.run.cli", "--config", str(config),
        "--out", str(out), "--workers", "2", "--quiet", "--no-gif",
    ]  # fmt: skip
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    process = subprocess.Popen(command, env=env, stderr=subprocess.PIPE, text=True)

    def generations_done() -> int:
        try:
            return len((out / "generations.csv").read_text().splitlines()) - 1
        except OSError:
            return 0  # not written yet

    deadline = time.monotonic() + 120
    while generations_done() < 1:
        assert process.poll() is None, process.stderr.read()
        assert time.monotonic() < deadline, "no generation within two minutes"
        time.sleep(0.1)
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 130, stderr
    assert "resume with" in stderr
    assert 1 <= len(read_generations(out)["generation"]) < 40
    resumed = subprocess.run(
        [*command, "--resume"], env=env, capture_output=True, text=True, timeout=300
    )
    assert resumed.returncode == 0, resumed.stderr
    assert read_generations(out)["generation"].tolist() == list(range(40))


def test_list_tasks_names_every_registered_task(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from sdbc_sim.tasks import available_tasks

    assert main(["--list-tasks"]) == 0
    out = capsys.readouterr().out
    for name, task_class in available_tasks().items():
        assert f"{name}  (" in out
        assert f"{task_class.default_generations} generations by default" in out
