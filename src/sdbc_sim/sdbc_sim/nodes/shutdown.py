"""Stopping a node without losing what it last sent.

rclpy's own Ctrl-C handler shuts the ROS context down at once: a message published
just before, not yet acknowledged by a slower reader (a recorder), is then lost
with the node. The nodes that must not lose their last messages (the simulator,
the controllers, the characteriser) install :class:`StopSignals` instead: Ctrl-C
and SIGTERM become a request to stop, seen by the node's loops through a guard
condition, and the node then flushes its publishers (:func:`flush_publishers`)
before it leaves.
"""

from __future__ import annotations

import signal
import threading
import time
from collections.abc import Iterable
from typing import Any

from rclpy.duration import Duration
from rclpy.guard_condition import GuardCondition

FLUSH_TIMEOUT = 5.0
"""Seconds a node waits, at most and for all its publishers together, for its
readers to acknowledge what it published. Longer than Fast DDS's 3 s heartbeat
period, after which a reader that missed a message asks for it again; shorter than
the launcher's shutdown timeout, after which the node would be killed."""


def flush_publishers(
    publishers: Iterable[Any], timeout: float = FLUSH_TIMEOUT
) -> list[str]:
    """Waits until every reader has acknowledged every message of ``publishers``
    (reliable ones; best-effort ones are done at once), at most ``timeout`` seconds
    in all: one bound for the lot, so that a node with many publishers and readers
    that stopped still leaves in time.

    Returns:
        The topics not acknowledged in time.
    """
    deadline = time.monotonic() + timeout
    late = []
    for publisher in publishers:
        remaining = max(0.0, deadline - time.monotonic())
        if not publisher.wait_for_all_acked(Duration(nanoseconds=int(remaining * 1e9))):
            late.append(publisher.topic_name)
    return late


class StopSignals:
    """Ctrl-C (SIGINT) and SIGTERM as a request to stop, instead of rclpy's
    handler; rclpy must be initialised with ``SignalHandlerOptions.NO``.

    On a signal, :attr:`requested` is set and :attr:`guard` triggered (for loops
    that wait on an rcl wait set, in any thread). The context stays up, so that
    the node can still flush its publishers. Python runs the handler in the main
    thread between two bytecodes, not during a wait in C: the main thread must
    wait in bounded slices (``spin_once`` with a timeout, not ``spin``).

    Args:
        context: The rclpy context of the node's guard condition.
    """

    def __init__(self, context: Any) -> None:
        self.requested = threading.Event()
        self.guard = GuardCondition(None, None, context=context)

    def install(self) -> StopSignals:
        """Installs the handlers; returns self."""
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, self._handle)
        return self

    def _handle(self, signum: int, frame: object) -> None:
        self.requested.set()
        self.guard.trigger()

    def destroy(self) -> None:
        """Releases the guard condition."""
        self.guard.destroy()
