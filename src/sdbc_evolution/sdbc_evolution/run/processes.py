"""Every process the project starts for its computations is made here.

Two kinds of work run in processes of their own: a generation's trials, in the
evaluator's pool (:class:`~sdbc_evolution.run.evaluators.LocalEvaluator`), and a
study's runs, one process each (:mod:`sdbc_evolution.study.runner`). Both start
them the same way, from this module:

- with ``forkserver``, so that a child starts clean whatever threads its parent
  has (a Dask client, a progress bar, rclpy's executor);
- one simulation per core, so each child limits BLAS and OpenMP to one thread
  (more would only oversubscribe the cores);
- each child ends when the process that made it (its owner) ends, however it
  ends, SIGKILL included (:func:`~sdbc_evolution.run.owner.watch_owner`). The
  kernel's parent-death signal cannot do this here: a forkserver child's parent
  is the fork server, which stays up as long as any child holds its end of the
  server's pipe, and every child does. So a child watches its owner through a
  pidfd and exits when the owner is gone; the fork server, left without
  clients, exits too.

The node processes of a live graph are a different matter (a supervised command
line each); :mod:`sdbc_evolution.graph.processes` starts those.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from multiprocessing.context import ForkServerContext
from multiprocessing.process import BaseProcess
from multiprocessing.queues import Queue
from typing import Any

from sdbc_evolution.run.owner import watch_owner


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity where the OS tells)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1


def limit_threads() -> None:
    """Limits this process's BLAS and OpenMP pools to one thread: one simulation
    process per core."""
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)


def _start_worker(owner: int) -> None:
    watch_owner(owner)
    limit_threads()


def _owned(owner: int, target: Callable[..., None], *args: Any) -> None:
    watch_owner(owner)
    target(*args)


TEMP_OWNER_FILE = "sdbc-owner"
"""In multiprocessing's temporary folder (``$TMPDIR/pymp-*``, the fork server's
socket): the pid and start time of the process that made it."""


def _context() -> ForkServerContext:
    # forkserver: see the module docstring.
    _own_temp_dir()
    return get_context("forkserver")


def _start_time(pid: int) -> str | None:
    """The kernel's start time of process ``pid`` (tells a reused pid apart),
    or None if there is no such process."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            # Field 22, counted after the command name, which may hold spaces.
            return f.read().rsplit(")", 1)[1].split()[19]
    except (OSError, IndexError):
        return None


_OWNED: list[str] = []


def _own_temp_dir() -> None:
    """Marks this process's multiprocessing folder as its own, once, and first
    removes the folders of marked owners that are gone: a SIGKILLed command
    cannot run multiprocessing's clean-up, and left one ``pymp-*`` per kill."""
    if _OWNED:
        return
    from multiprocessing import util

    clear_stale_temp_dirs()
    folder = util.get_temp_dir()
    pid = os.getpid()
    marker = os.path.join(folder, TEMP_OWNER_FILE)
    with open(marker, "w") as f:
        f.write(f"{pid} {_start_time(pid)}\n")
    _OWNED.append(folder)


def clear_stale_temp_dirs() -> list[str]:
    """Removes the ``pymp-*`` folders under the temporary directory whose owner
    (as its :data:`TEMP_OWNER_FILE` says) is no longer running; returns them.
    Folders without the mark are not this project's to judge, and are left."""
    import glob
    import shutil
    import tempfile

    removed = []
    for folder in glob.glob(os.path.join(tempfile.gettempdir(), "pymp-*")):
        try:
            with open(os.path.join(folder, TEMP_OWNER_FILE)) as f:
                pid_text, started = f.read().split()
            pid = int(pid_text)
        except (OSError, ValueError):
            continue
        if _start_time(pid) == started:
            continue  # still running
        shutil.rmtree(folder, ignore_errors=True)
        removed.append(folder)
    return removed


def worker_pool(workers: int) -> ProcessPoolExecutor:
    """A pool of ``workers`` processes, each limited to one thread and ending
    with this process."""
    return ProcessPoolExecutor(
        max_workers=workers,
        mp_context=_context(),
        initializer=_start_worker,
        initargs=(os.getpid(),),
    )


def message_queue() -> Queue[Any]:
    """A queue that child processes of :func:`start_process` can write to."""
    return _context().Queue()


def start_process(
    target: Callable[..., None], args: Sequence[Any], name: str
) -> BaseProcess:
    """Starts ``target(*args)`` in a process of its own, named ``name``, that
    ends with this process; the target limits its threads itself
    (:func:`limit_threads`) where it computes."""
    process = _context().Process(
        target=_owned, args=(os.getpid(), target, *args), name=name
    )
    process.start()
    return process
