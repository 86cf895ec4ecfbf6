"""A child process that ends when the process that made it (its owner) ends.

The project's children (a generation's workers, a study's runs: made in
:mod:`sdbc_evolution.run.processes`; a live graph's nodes:
:mod:`sdbc_evolution.graph.owned`) must not outlive their owner however it
ends, SIGKILL included. Each watches its owner through a pidfd, which becomes
readable once the owner has exited. This module imports nothing beyond the
standard library's basics, so a node program pays nothing for it at start.
"""

from __future__ import annotations

import os
import select
import threading
import time

ORPHAN_EXIT = 128 + 9
"""Exit status of a child whose owner is gone (as if killed by SIGKILL with it)."""
OWNER_POLL_SECONDS = 1.0
"""Where pidfds are missing: how often a child looks whether its owner lives."""


def watch_owner(owner: int) -> None:
    """Ends this process (at once, with :data:`ORPHAN_EXIT`) when the process
    ``owner`` ends; a daemon thread waits for it on a pidfd. A run's checkpoint
    is atomic, so whatever the child was doing is redone on resume."""
    try:
        fd = os.pidfd_open(owner)
    except ProcessLookupError:
        os._exit(ORPHAN_EXIT)  # gone before we looked
    except (AttributeError, OSError):
        fd = None  # no pidfds (not Linux >= 5.3): poll instead

    def wait() -> None:
        if fd is not None:
            select.select([fd], [], [])  # readable once the owner has exited
        else:
            while _alive(owner):
                time.sleep(OWNER_POLL_SECONDS)
        os._exit(ORPHAN_EXIT)

    threading.Thread(target=wait, name="watch-owner", daemon=True).start()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
