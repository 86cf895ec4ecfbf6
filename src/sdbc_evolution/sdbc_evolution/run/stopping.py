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
from collections.abc import Iterator

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
"""The signals that stop a command."""


def _raise_interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


@contextlib.contextmanager
def stoppable() -> Iterator[None]:
    """Within the block, SIGINT and SIGTERM raise ``KeyboardInterrupt`` (in the
    main thread); the previous handlers come back after it."""
    previous = {sig: signal.getsignal(sig) for sig in STOP_SIGNALS}
    for sig in STOP_SIGNALS:
        signal.signal(sig, _raise_interrupt)
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
