"""Runs joined into one batch per generation: each one's results as alone, a bad
value or an error stopping only whom it concerns, Ctrl-C stopping all."""

from __future__ import annotations

import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from evolution_helpers import TOY_INFO, ToyEvaluator, assert_same_run
from sdbc_evolution.run.evaluators import Evaluation, Evaluator, TaskSpec
from sdbc_evolution.run.experiment import Experiment
from sdbc_evolution.run.joined import run_joined
from test_experiment import small_config


def run_alone(config, out: Path) -> None:
    with Experiment.create(config, out, ToyEvaluator(), TOY_INFO) as experiment:
        experiment.run()


def run_with(config, out: Path):
    def work(evaluator: Evaluator) -> int:
        with Experiment.create(config, out, evaluator, TOY_INFO) as experiment:
            experiment.run()
            return experiment.state.generation

    return (ToyEvaluator.spec, work)


def configs():
    return [
        small_config("ns-sd+", generations=4),
        small_config("fit", generations=4).replace(seed=5),
        small_config("ns-ts", generations=2).replace(seed=6),
    ]


def test_joined_runs_are_the_runs_alone_in_fewer_batches(tmp_path: Path) -> None:
    for k, config in enumerate(configs()):
        run_alone(config, tmp_path / f"alone{k}")
    shared = ToyEvaluator()
    done = run_joined(
        shared,
        [
            run_with(config, tmp_path / f"joined{k}")
            for k, config in enumerate(configs())
        ],
    )
    assert done == [4, 4, 2]
    for k in range(3):
        assert_same_run(tmp_path / f"alone{k}", tmp_path / f"joined{k}")
    # Alone: 5 + 5 + 3 batches; joined: generation 0, the three runs' next
    # populations beside their re-evaluations, then the last re-evaluations.
    assert shared.calls == 5


class _Flagged(ToyEvaluator):
    """The toy, with NaN fitness in every trial of a genome whose first weight
    is 99."""

    def _run(self, genomes, seeds, bounds):
        parts = super()._run(genomes, seeds, bounds)
        for (a, _), part in zip(bounds, parts, strict=True):
            flagged = genomes[a : a + len(part.fitness), 0] == 99.0
            part.fitness[flagged] = np.nan
            part.trial_fitness[flagged] = np.nan
        return parts


def asking(genomes: np.ndarray, answers: list[object]):
    seeds = np.arange(genomes.shape[0] * 2, dtype=np.int64).reshape(-1, 2)

    def work(evaluator: Evaluator) -> Evaluation | None:
        try:
            return evaluator.evaluate(genomes, seeds)
        except ValueError as error:
            answers.append(str(error))
            return None

    return (ToyEvaluator.spec, work)


def test_a_bad_value_stops_only_its_run_naming_its_own_genome() -> None:
    rng = np.random.default_rng(3)
    good = rng.uniform(-1, 1, (4, 6))
    bad = rng.uniform(-1, 1, (3, 6))
    bad[2, 0] = 99.0
    errors: list[object] = []
    kept, refused = run_joined(_Flagged(), [asking(good, errors), asking(bad, errors)])
    assert refused is None and len(errors) == 1
    assert "genome 2" in str(errors[0]) and "\n" not in str(errors[0])
    alone = ToyEvaluator().evaluate(good, np.arange(8, dtype=np.int64).reshape(4, 2))
    assert kept is not None
    np.testing.assert_array_equal(kept.fitness, alone.fitness)
    np.testing.assert_array_equal(kept.sdbc, alone.sdbc)


class _Interrupted(ToyEvaluator):
    """Ctrl-C during its second batch."""

    def _run(self, genomes, seeds, bounds):
        if self.calls == 1:
            raise KeyboardInterrupt
        return super()._run(genomes, seeds, bounds)


def test_ctrl_c_in_a_batch_stops_every_run_at_its_evaluation() -> None:
    def looping(evaluator: Evaluator) -> str:
        genomes = np.zeros((2, 6))
        seeds = np.ones((2, 1), dtype=np.int64)
        try:
            for _ in range(5):
                evaluator.evaluate(genomes, seeds)
        except KeyboardInterrupt:
            return "interrupted"
        return "finished"

    spec = ToyEvaluator.spec
    assert run_joined(_Interrupted(), [(spec, looping)] * 3) == ["interrupted"] * 3


def test_a_run_that_fails_is_raised_once_every_run_has_ended() -> None:
    ended = []

    def failing(evaluator: Evaluator) -> None:
        raise RuntimeError("run 0 broke")

    def evaluating(evaluator: Evaluator) -> None:
        for _ in range(3):
            evaluator.evaluate(np.zeros((2, 6)), np.ones((2, 1), dtype=np.int64))
        ended.append(True)

    spec = ToyEvaluator.spec
    with pytest.raises(RuntimeError, match="run 0 broke"):
        run_joined(ToyEvaluator(), [(spec, failing), (spec, evaluating)])
    assert ended == [True]


def test_runs_of_another_task_are_refused() -> None:
    with pytest.raises(ValueError, match="joined runs share one task"):
        run_joined(ToyEvaluator(), [(TaskSpec("gate_escape"), lambda e: None)])


@pytest.mark.parametrize("where", ["checking values", "handing out answers"])
def test_ctrl_c_anywhere_in_the_serving_thread_stops_every_run(
    monkeypatch: pytest.MonkeyPatch, where: str
) -> None:
    """A signal lands wherever the serving thread is: after a batch, while its
    answers are checked or handed out, the runs waiting for them stop all the
    same."""
    from sdbc_evolution.run import joined

    if where == "checking values":

        def interrupted(evaluation: Evaluation, spec: TaskSpec) -> None:
            raise KeyboardInterrupt

        monkeypatch.setattr(joined, "check_values", interrupted)
    else:
        original = joined._Joiner._answer

        def answer_then_interrupted(self, asked, signals):  # type: ignore[no-untyped-def]
            original(self, asked, signals)
            raise KeyboardInterrupt

        monkeypatch.setattr(joined._Joiner, "_answer", answer_then_interrupted)

    def looping(evaluator: Evaluator) -> str:
        try:
            for _ in range(5):
                evaluator.evaluate(np.zeros((2, 6)), np.ones((2, 1), dtype=np.int64))
        except KeyboardInterrupt:
            return "interrupted"
        return "finished"

    outcome: list[object] = []
    serving = threading.Thread(
        target=lambda: outcome.append(
            run_joined(ToyEvaluator(), [(ToyEvaluator.spec, looping)] * 3)
        ),
        daemon=True,
    )
    serving.start()
    serving.join(timeout=60)
    assert not serving.is_alive(), "a run still waits for an answer"
    assert outcome == [["interrupted"] * 3]


_SCRIPT_START = """
import os, random, signal, sys, threading, time
import numpy as np
sys.path[:0] = {paths!r}
from evolution_helpers import ToyEvaluator
from sdbc_evolution.run import joined

signal.signal(signal.SIGINT, signal.default_int_handler)

def looping(evaluator):
    try:
        while True:
            evaluator.evaluate(np.zeros((2, 6)), np.ones((2, 1), dtype=np.int64))
    except KeyboardInterrupt:
        return "interrupted"
"""
"""A script's first lines: the test runs' paths, Ctrl-C as KeyboardInterrupt, a
run that evaluates until stopped."""

_CTRL_C_ANYWHERE = """
rng = random.Random(7)
for attempt in range({attempts}):
    delay = rng.uniform(0.0, 0.02)
    timer = threading.Timer(delay, os.kill, (os.getpid(), signal.SIGINT))
    try:
        # On a loaded machine the timer may fire before start() returns.
        timer.start()
        outcome = joined.run_joined(ToyEvaluator(), [(ToyEvaluator.spec, looping)] * 3)
    except KeyboardInterrupt:
        outcome = ["raised"]  # before the runs, or as they ended: as alone
    # None: a run whose thread the signal came before (run_joined's contract).
    assert outcome == ["raised"] or set(outcome) <= {{"interrupted", None}}, outcome
    timer.join()  # its signal was the one handled: the runs stop only on one
print("done", flush=True)
"""


def test_one_ctrl_c_at_any_moment_stops_the_joined_runs(tmp_path: Path) -> None:
    """A real SIGINT, at a random moment, many times over: whatever the serving
    thread was doing (taking the joiner's lock, waiting, answering), the runs
    stop and run_joined returns; none is left waiting for a lock or an answer."""
    script = tmp_path / "ctrl_c.py"
    here = str(Path(__file__).parent)
    script.write_text(
        (_SCRIPT_START + _CTRL_C_ANYWHERE).format(paths=[here, *sys.path], attempts=100)
    )
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=240
    )
    assert done.returncode == 0 and "done" in done.stdout, done.stderr[-2000:]


_SIGNAL_AS_THE_LOCK_IS_TAKEN = """
joiners = []
original_init = joined._Joiner.__init__

def recording_init(self, evaluator):
    original_init(self, evaluator)
    joiners.append(self)

joined._Joiner.__init__ = recording_init

class Meddling(ToyEvaluator):
    def _run(self, genomes, seeds, bounds):
        if self.calls == 2:
            taken = threading.Event()

            def meddle():
                with joiners[0]._changed:
                    taken.set()
                    time.sleep(0.3)  # the serving thread now waits for the lock
                # It gets the lock, then waits for the interpreter, which this
                # thread keeps while the signal arrives.
                os.kill(os.getpid(), signal.SIGINT)
                end = time.monotonic() + 0.05
                while time.monotonic() < end:
                    pass

            threading.Thread(target=meddle, daemon=True).start()
            taken.wait()
        return super()._run(genomes, seeds, bounds)

print(joined.run_joined(Meddling(), [(ToyEvaluator.spec, looping)] * 3), flush=True)
"""


def test_a_signal_handled_just_as_the_joiners_lock_is_taken_stops_every_run(
    tmp_path: Path,
) -> None:
    """The serving thread waits for the joiner's lock, gets it, and handles a
    SIGINT before its next line: raised there, KeyboardInterrupt would leave the
    lock taken and every run waiting for it (a study hung so). Held until the
    lock is let go, it stops every run."""
    script = tmp_path / "signal_at_lock.py"
    here = str(Path(__file__).parent)
    script.write_text(
        (_SCRIPT_START + _SIGNAL_AS_THE_LOCK_IS_TAKEN).format(paths=[here, *sys.path])
    )
    try:
        done = subprocess.run(
            [sys.executable, str(script)], capture_output=True, text=True, timeout=60
        )
    except subprocess.TimeoutExpired:
        pytest.fail("the runs still wait for the joiner's lock")
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == str(["interrupted"] * 3)
