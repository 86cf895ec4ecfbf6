"""How a long command is stopped: by Ctrl-C, or by a supervisor's or batch
scheduler's SIGTERM (SLURM at a job's time limit), both as ``KeyboardInterrupt``,
which ``sdbc-evolve``, ``sdbc-study run`` and ``sdbc-graph`` turn into a clean stop
that the same command resumes.

Ctrl-C also has to work where the command was started with SIGINT ignored, as a
non-interactive shell starts its background jobs (``cmd &`` in a script):
Python then keeps ignoring it unless told otherwise.

A handler's ``KeyboardInterrupt`` can be lost: Python runs a signal's handler at
its next check, wherever that falls, and drops an exception raised in a
finalizer (pymunk frees chipmunk's spaces, bodies and shapes in callbacks that
run Python code, many of them as a batch of trials ends). So the handler also
notes the signal, and every evaluator checks the note after each batch
(:func:`raise_if_stopped`): a command stops at the end of the batch under way
at the latest.
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


_stop_signalled = False
"""A stop signal came: in this :func:`stoppable` block, or in a process that
stops on its first (:func:`interrupt`)."""


def interrupt(signum: int, frame: FrameType | None) -> None:
    """A stop signal's handler: notes the signal and raises KeyboardInterrupt."""
    global _stop_signalled
    _stop_signalled = True
    raise KeyboardInterrupt


def raise_if_stopped() -> None:
    """Raises KeyboardInterrupt if a stop signal came (:func:`interrupt`), in
    case the one its handler raised was lost (module docstring)."""
    if _stop_signalled:
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


@contextlib.contextmanager
def stoppable() -> Iterator[None]:
    """Within the block, SIGINT and SIGTERM raise ``KeyboardInterrupt`` (in the
    main thread), even where they were ignored, and are noted for
    :func:`raise_if_stopped`; the previous handlers come back after it, and
    the note goes."""
    global _stop_signalled
    _stop_signalled = False
    try:
        with stop_signals_to(interrupt):
            yield
    finally:
        _stop_signalled = False
