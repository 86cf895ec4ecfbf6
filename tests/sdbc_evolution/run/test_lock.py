"""One writer per run directory: the lock, and what a second writer is told."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from evolution_helpers import TINY_RUN_YAML, TOY_INFO, ToyEvaluator
from sdbc_evolution.run.config import config_from_dict
from sdbc_evolution.run.experiment import Experiment
from sdbc_evolution.run.lock import LOCK_FILE, RunBusy, RunLock
from sdbc_evolution.run.results import read_generations

HOLD = """\
import sys, time
from sdbc_evolution.run.lock import RunLock
lock = RunLock(sys.argv[1]).acquire()
print("held", flush=True)
time.sleep(600)
"""


def toy_config(generations: int = 3):
    return config_from_dict(
        {
            "task": "toy",
            "treatment": "ns-ts",
            "generations": generations,
            "ga": {"population_size": 6, "tournament_size": 2, "elites": 1},
            "novelty": {"k": 3},
            "evaluation": {"trials": 2},
        }
    )


def wait_for(condition, what: str, seconds: float = 120) -> None:
    deadline = time.monotonic() + seconds
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"gave up waiting for {what}")
        time.sleep(0.05)


def test_a_second_lock_is_refused_naming_the_holder(tmp_path: Path) -> None:
    first = RunLock(tmp_path / "run").acquire()
    with pytest.raises(RunBusy) as busy:
        RunLock(tmp_path / "run").acquire()
    assert f"(pid {os.getpid()} on {socket.gethostname()})" in str(busy.value)
    first.release()
    assert (tmp_path / "run" / LOCK_FILE).read_text() == ""
    with RunLock(tmp_path / "run"):
        pass


def test_the_lock_goes_with_its_holder_even_on_sigkill(tmp_path: Path) -> None:
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLD, str(tmp_path)], stdout=subprocess.PIPE, text=True
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline() == "held\n"
        with pytest.raises(RunBusy, match=f"pid {holder.pid} on"):
            RunLock(tmp_path).acquire()
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait()
    with RunLock(tmp_path):
        pass


def test_an_experiment_holds_its_directory_until_closed(tmp_path: Path) -> None:
    experiment = Experiment.create(toy_config(), tmp_path, ToyEvaluator(), TOY_INFO)
    with pytest.raises(RunBusy, match="being written by another process"):
        Experiment.resume(toy_config(), tmp_path, ToyEvaluator(), TOY_INFO)
    experiment.step()
    experiment.close()
    with Experiment.resume(toy_config(), tmp_path, ToyEvaluator(), TOY_INFO) as again:
        again.run()
    assert read_generations(tmp_path)["generation"].tolist() == [0, 1, 2]


def test_a_generation_whose_rows_do_not_match_is_refused(tmp_path: Path) -> None:
    # The second guard: a row written behind the lock's back (a foreign writer).
    with Experiment.create(toy_config(), tmp_path, ToyEvaluator(), TOY_INFO) as run:
        run.step()
        with open(tmp_path / "generations.csv") as f:
            rows = f.readlines()
        with open(tmp_path / "generations.csv", "a") as f:
            f.write(rows[-1])
        with pytest.raises(
            RuntimeError, match="holds 2 generations before generation 1"
        ):
            run.step()


def evolve(out: Path, *args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "sdbc_evolution.run.cli",
            "--resume",
            "--out",
            str(out),
            "--workers",
            "1",
            "--quiet",
            "--no-gif",
            *args,
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # A resume that hangs can then be made to say where (stopped()).
        env={**os.environ, "PYTHONFAULTHANDLER": "1"},
    )


def stopped(process: subprocess.Popen[str], timeout: float) -> str:
    """``process``'s stderr once it ends; if it does not within ``timeout``
    seconds, its threads' Python stacks (SIGABRT through faulthandler) in the
    failure, so that an intermittent hang says where it was."""
    try:
        return process.communicate(timeout=timeout)[1]
    except subprocess.TimeoutExpired:
        process.send_signal(signal.SIGABRT)
        err = process.communicate(timeout=60)[1]
        raise AssertionError(f"pid {process.pid} did not end: {err[-8000:]}") from None


def test_two_resumes_at_once_on_one_run_one_is_refused(tmp_path: Path) -> None:
    from sdbc_evolution.run.cli import main

    config = tmp_path / "tiny.yaml"
    config.write_text(TINY_RUN_YAML)
    out = tmp_path / "run"
    assert (
        main(
            [
                "--config",
                str(config),
                "--out",
                str(out),
                "--quiet",
                "--no-gif",
                "--workers",
                "1",
            ]
        )
        == 0
    )
    # The first resume cannot finish before it is stopped: the second one surely
    # starts while the first writes.
    first = evolve(out, "--generations", "100000")
    failure: AssertionError | None = None
    try:
        wait_for(
            lambda: len(read_generations(out)["generation"]) >= 3
            or first.poll() is not None,
            "the first resume's generations",
        )
        assert first.poll() is None, "the first resume ended before the second began"
        second = evolve(out, "--generations", "100000")
        err = stopped(second, 300)
        assert second.returncode == 2, err
        assert err.strip() == (
            f"sdbc-evolve: error: {out} is being written by another process "
            f"(pid {first.pid} on {socket.gethostname()}); wait for it to end, or "
            "choose another output directory"
        )
    except AssertionError as error:
        failure = error
    finally:
        first.send_signal(signal.SIGINT)
        first_err = stopped(first, 300)
    # Whatever failed, what the first resume said comes with it.
    assert failure is None, f"{failure}\nthe first resume said: {first_err[-4000:]}"
    assert first.returncode == 130, first_err
    done = read_generations(out)["generation"].tolist()
    assert done == list(range(len(done)))  # every generation once, in order
    # and the run goes on from where the first stopped
    again = evolve(out, "--generations", str(len(done) + 1))
    again.communicate(timeout=300)
    assert again.returncode == 0
    assert read_generations(out)["generation"].tolist() == list(range(len(done) + 1))


def test_a_second_writer_is_refused_before_any_trial_of_the_checks(
    tmp_path: Path,
) -> None:
    # The probe trial of a task that breaks the contract would refuse the run;
    # a run another process holds is refused first (no trial: it is told at
    # once, whatever a trial costs), for --resume and for a new run alike.
    broken = Path(__file__).resolve().parent / "boundary_tasks.py"
    config = tmp_path / "broken.yaml"
    config.write_text(
        TINY_RUN_YAML.replace("task: gate_escape", f"task: {broken}:NegativeFitness")
    )
    out = tmp_path / "run"
    out.mkdir()
    (out / "config.yaml").write_text(config.read_text())
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLD, str(out)], stdout=subprocess.PIPE, text=True
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline() == "held\n"
        busy = f"{out} is being written by another process (pid {holder.pid} on"
        for argv in (
            ["--resume", "--task", f"{broken}:NegativeFitness"],
            ["--config", str(config)],
        ):
            done = subprocess.run(
                [sys.executable, "-m", "sdbc_evolution.run.cli", *argv]
                + ["--out", str(out), "--workers", "1", "--quiet", "--no-gif"],
                capture_output=True,
                text=True,
                timeout=300,
            )
            assert done.returncode == 2, done.stderr
            assert done.stderr.startswith(f"sdbc-evolve: error: {busy}"), done.stderr
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait()
    # The lock gone, the same command meets the probe.
    done = subprocess.run(
        [sys.executable, "-m", "sdbc_evolution.run.cli", "--config", str(config)]
        + ["--out", str(out), "--workers", "1", "--quiet", "--no-gif"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 2, done.stderr
    assert "a first trial: task" in done.stderr, done.stderr
