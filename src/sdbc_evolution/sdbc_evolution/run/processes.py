"""Every process the project starts for its computations is made here.

Two kinds of work run in processes of their own: a generation's trials, in the
evaluator's pool (:class:`~sdbc_evolution.run.evaluators.LocalEvaluator`), and a
study's runs, one process each (:mod:`sdbc_evolution.study.runner`). Both start
them the same way, from this module:

- with ``forkserver``, so that a child starts clean whatever threads its parent
  has (a Dask client, a progress bar, rclpy's executor);
- one simulation per core, so each child limits BLAS and OpenMP to one thread
  (more would only oversubscribe the cores).

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


def _context() -> ForkServerContext:
    # forkserver: see the module docstring.
    return get_context("forkserver")


def worker_pool(workers: int) -> ProcessPoolExecutor:
    """A pool of ``workers`` processes, each limited to one thread."""
    return ProcessPoolExecutor(
        max_workers=workers, mp_context=_context(), initializer=limit_threads
    )


def message_queue() -> Queue[Any]:
    """A queue that child processes of :func:`start_process` can write to."""
    return _context().Queue()


def start_process(
    target: Callable[..., None], args: Sequence[Any], name: str
) -> BaseProcess:
    """Starts ``target(*args)`` in a process of its own, named ``name``; the
    target limits its threads itself (:func:`limit_threads`) where it computes."""
    process = _context().Process(target=target, args=tuple(args), name=name)
    process.start()
    return process
