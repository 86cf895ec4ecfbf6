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
from collections.abc import Callable
from typing import NoReturn

ORPHAN_EXIT = 128 + 9
"""Exit status of a child whose owner is gone (as if killed by SIGKILL with it)."""
OWNER_POLL_SECONDS = 1.0
"""Where pidfds are missing: how often a child looks whether its owner lives."""


def watch_owner(owner: int) -> None:
    """Ends this process (at once, with :data:`ORPHAN_EXIT`) when the process
    ``owner`` ends. A run's checkpoint is atomic, so whatever the child was
    doing is redone on resume."""
    when_gone(owner, _orphaned)


def when_gone(
    owner: int,
    then: Callable[[], None],
    *,
    parent: bool = False,
    name: str = "watch-owner",
) -> None:
    """Calls ``then`` in a daemon thread once the process ``owner`` has ended.

    If ``owner`` is gone already, this process exits at once with
    :data:`ORPHAN_EXIT` (nothing has started that ``then`` would stop). A pidfd
    tells when it ends; where pidfds are missing (not Linux >= 5.3) the thread
    looks every :data:`OWNER_POLL_SECONDS`.

    Args:
        owner: The pid to watch.
        then: What to do once it has ended; it runs in the watching thread.
        parent: ``owner`` is this process's parent. The watch then also sees
            an owner that died before its pidfd was opened, whose pid may have
            been reused since, and polls ``getppid()``, which a reused pid
            cannot fool.
        name: The watching thread's name.
    """

    def alive() -> bool:
        return os.getppid() == owner if parent else _alive(owner)

    try:
        fd: int | None = os.pidfd_open(owner)
    except ProcessLookupError:
        _orphaned()  # gone before we looked
    except (AttributeError, OSError):
        fd = None  # no pidfds: poll instead
    if parent and not alive():
        _orphaned()

    def wait() -> None:
        if fd is not None:
            select.select([fd], [], [])  # readable once the owner has exited
        else:
            while alive():
                time.sleep(OWNER_POLL_SECONDS)
        then()

    threading.Thread(target=wait, name=name, daemon=True).start()


def _orphaned() -> NoReturn:
    os._exit(ORPHAN_EXIT)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
