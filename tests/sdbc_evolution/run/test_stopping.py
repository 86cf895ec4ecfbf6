"""Stop signals go where a block says, and back after it; a stop whose
KeyboardInterrupt was lost still stops the command at the end of its batch."""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from evolution_helpers import ToyEvaluator
from sdbc_evolution.run.joined import run_joined
from sdbc_evolution.run.stopping import (
    STOP_SIGNALS,
    raise_if_stopped,
    stop_signals_to,
    stoppable,
)


@pytest.fixture(autouse=True)
def _handlers_kept() -> Iterator[None]:
    before = {sig: signal.getsignal(sig) for sig in STOP_SIGNALS}
    yield
    for sig, handler in before.items():
        signal.signal(sig, handler)


def test_ctrl_c_stops_a_command_started_with_it_ignored() -> None:
    # As a shell's background job starts: SIGINT ignored.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    with pytest.raises(KeyboardInterrupt), stoppable():
        os.kill(os.getpid(), signal.SIGINT)
    assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN


def test_each_signal_gets_its_handler_back_unless_replaced_meanwhile() -> None:
    seen: list[int] = []

    def note(signum: int, frame: Any) -> None:
        seen.append(signum)

    def ignore_further(signum: int, frame: Any) -> None:
        signal.signal(signal.SIGTERM, signal.SIG_IGN)

    signal.signal(signal.SIGINT, note)
    signal.signal(signal.SIGTERM, note)
    with stop_signals_to(ignore_further) as previous:
        assert previous == {signal.SIGINT: note, signal.SIGTERM: note}
        os.kill(os.getpid(), signal.SIGINT)
    assert seen == []
    assert signal.getsignal(signal.SIGINT) is note
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_IGN


def test_only_the_signals_named_are_redirected() -> None:
    signal.signal(signal.SIGTERM, signal.SIG_IGN)

    def handler(signum: int, frame: Any) -> None:
        raise AssertionError("not expected")

    with stop_signals_to(handler, [signal.SIGINT]) as previous:
        assert list(previous) == [signal.SIGINT]
        assert signal.getsignal(signal.SIGTERM) is signal.SIG_IGN
        assert signal.getsignal(signal.SIGINT) is handler
    assert signal.getsignal(signal.SIGINT) is not handler


def test_outside_the_main_thread_nothing_changes() -> None:
    before = {sig: signal.getsignal(sig) for sig in STOP_SIGNALS}
    got: list[object] = []

    def work() -> None:
        with stop_signals_to(lambda signum, frame: None) as previous:
            got.append(previous)
            got.append({sig: signal.getsignal(sig) for sig in STOP_SIGNALS})

    thread = threading.Thread(target=work)
    thread.start()
    thread.join()
    assert got == [{}, before]


class _SignalsFromItsFinalizer:
    """Sends SIGINT from its finalizer, where the handler then runs and Python
    drops the KeyboardInterrupt it raises, as in pymunk's callbacks that free
    chipmunk's objects."""

    def __del__(self) -> None:
        os.kill(os.getpid(), signal.SIGINT)
        sum(range(10))  # Python code: the handler runs here at the latest


@pytest.fixture
def dropped(monkeypatch: pytest.MonkeyPatch) -> list[type[BaseException] | None]:
    """The exceptions Python drops (``sys.unraisablehook``)."""
    seen: list[type[BaseException] | None] = []
    monkeypatch.setattr(sys, "unraisablehook", lambda u: seen.append(u.exc_type))
    return seen


def _batch() -> tuple[np.ndarray, np.ndarray]:
    return np.zeros((2, 6)), np.arange(4, dtype=np.int64).reshape(2, 2)


def test_a_stop_lost_in_a_finalizer_stops_the_next_batch_at_its_end(
    dropped: list[type[BaseException] | None],
) -> None:
    evaluator = ToyEvaluator()
    with stoppable():
        raise_if_stopped()  # nothing came yet
        _SignalsFromItsFinalizer()
        assert dropped == [KeyboardInterrupt]
        with pytest.raises(KeyboardInterrupt):
            evaluator.evaluate(*_batch())
        assert evaluator.calls == 1  # stopped after the batch, not before
    evaluator.evaluate(*_batch())  # the next command is not stopped


class _LosesAStopInItsFirstBatch(ToyEvaluator):
    def _run(self, genomes, seeds, bounds):  # type: ignore[no-untyped-def]
        if self.calls == 0:
            _SignalsFromItsFinalizer()
        return super()._run(genomes, seeds, bounds)


def test_a_stop_lost_in_a_joined_batch_stops_every_run(
    dropped: list[type[BaseException] | None],
) -> None:
    def work(evaluator: ToyEvaluator) -> str:
        for _ in range(20):
            try:
                evaluator.evaluate(*_batch())
            except KeyboardInterrupt:
                return "interrupted"
        return "finished"

    evaluator = _LosesAStopInItsFirstBatch()
    with stoppable():
        outcome = run_joined(evaluator, [(ToyEvaluator.spec, work)] * 3)
    assert dropped == [KeyboardInterrupt]
    assert evaluator.calls == 1
    assert outcome == ["interrupted"] * 3
