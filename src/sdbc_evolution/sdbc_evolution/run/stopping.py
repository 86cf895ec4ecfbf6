"""How a long command is stopped: by Ctrl-C, or by a supervisor's or batch
scheduler's SIGTERM (SLURM at a job's time limit), both as ``KeyboardInterrupt``,
which ``sdbc-evolve``, ``sdbc-study run`` and ``sdbc-graph`` turn into a clean stop
that the same command resumes.

Ctrl-C also has to work where the command was started with SIGINT ignored, as a
non-interactive shell starts its background jobs (``cmd &`` in a script):
Python then keeps ignoring it unless told otherwise.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterable, Iterator
from types import FrameType
from typing import Any

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
"""The signals that stop a command."""

Handler = Callable[[int, FrameType | None], Any]
"""A signal handler, as :func:`signal.signal` takes one."""


def _raise_interrupt(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt


@contextlib.contextmanager
def stop_signals_to(
    handler: Handler, signals: Iterable[int] = STOP_SIGNALS
) -> Iterator[dict[int, Any]]:
    """Within the block, ``signals`` (SIGINT and SIGTERM) go to ``handler``;
    the block gets the handlers they had, by signal. After it, each gets its
    own back, unless a handler put another in its place meanwhile (one that
    ignores further signals once it has acted, say), which stays.

    Only the main thread can set handlers, and signals land only there: in any
    other thread nothing changes and the block gets no handlers."""
    previous: dict[int, Any] = {}
    try:
        if threading.current_thread() is threading.main_thread():
            for sig in signals:
                previous[sig] = signal.getsignal(sig)
                signal.signal(sig, handler)
        yield previous
    finally:
        for sig, old in previous.items():
            if signal.getsignal(sig) == handler:
                signal.signal(sig, old)


def stoppable() -> contextlib.AbstractContextManager[dict[int, Any]]:
    """Within the block, SIGINT and SIGTERM raise ``KeyboardInterrupt`` (in the
    main thread), even where they were ignored; the previous handlers come back
    after it."""
    return stop_signals_to(_raise_interrupt)
