"""Stop signals go where a block says, and back after it."""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterator
from typing import Any

import pytest
from sdbc_evolution.run.stopping import STOP_SIGNALS, stop_signals_to, stoppable


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
