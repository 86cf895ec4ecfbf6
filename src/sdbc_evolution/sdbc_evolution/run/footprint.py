"""How much memory a run needs at once, checked before anything is written.

A generation evaluates its N x T trials at once (split over the workers, but alive
together), so the run's peak memory grows with N x T. A population of two million
would otherwise be found out by a ``MemoryError`` (or the kernel's OOM killer)
after the run directory was made; :func:`check_footprint` refuses it up front,
with the estimate and what the machine has available.

The estimate is deliberately simple and on the high side:

- ``TRIAL_BYTES`` per trial simulated at once: the engine's and the SDBC
  extractor's per-trial state (bodies in pymunk, sensor and network arrays,
  feature accumulators). Measured as the growth of peak RSS from a batch of 200
  trials to one of 4000, on the real engine: 26.9 KB per trial for gate escape,
  14.5 KB for resource sharing, 17.8 KB for predator-prey; rounded up.
- the GA's arrays: the population and its offspring (N x W float64, a few times),
  the seeds and per-trial fitness (N x T), characterisations and SDBC vectors
  (N x (C + D), a few times), and the novelty archive;
- ``WORKER_BYTES`` per local worker process (:mod:`sdbc_sim.limits`): a pool of
  W workers starts min(W, N) processes, one chunk of individuals each;
- runs side by side (``sdbc-study run --workers P``: P processes at once, each
  evaluating in process one run or several joined, :mod:`.joined`): R runs at
  once take R times a run's trials and arrays, and ``WORKER_BYTES`` for each of
  the P processes.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from sdbc_sim.limits import WORKER_BYTES

from sdbc_evolution.run.config import ExperimentConfig
from sdbc_evolution.run.evaluators import TaskInfo

TRIAL_BYTES = 32 * 1024
"""Memory per trial simulated at once (measured at most 26.9 KB; see above)."""
COPIES = 4
"""Copies of each per-individual array a generation holds at its peak (the
evaluation's, the scores', the outputs' and the next population's)."""
GIB = 2.0**30


class FootprintError(ValueError):
    """A run that cannot fit in this machine's memory; the message says how much
    it needs."""


@dataclass(frozen=True)
class Footprint:
    """A run's estimated peak memory.

    Attributes:
        trials: Bytes of the trials simulated at once.
        arrays: Bytes of the GA's per-individual arrays and the archive.
        workers: Bytes of the worker processes themselves.
    """

    trials: int
    arrays: int
    workers: int = 0

    @property
    def total(self) -> int:
        """Bytes in all: trials, arrays and worker processes."""
        return self.trials + self.arrays + self.workers


def worker_processes(
    config: ExperimentConfig, workers: int, runs: int = 1, processes: int | None = None
) -> int:
    """Processes ``runs`` runs of ``config`` start side by side, each with a local
    pool of ``workers``: a pool starts one process per chunk, and a batch is cut
    into at most one chunk per individual; one worker runs in process. More than
    one run: ``processes`` of their own too (default: one per run; 0: the runs
    go in this process)."""
    pool = 0 if workers <= 1 else min(workers, config.ga.population_size)
    own = processes if processes is not None else (runs if runs > 1 else 0)
    return runs * pool + own


def run_footprint(
    config: ExperimentConfig,
    info: TaskInfo,
    workers: int = 1,
    runs: int = 1,
    processes: int | None = None,
) -> Footprint:
    """The peak memory of a generation of ``config`` on the task ``info`` with
    ``workers`` local worker processes (1: in process; a Dask cluster's workers
    are not on this machine), for ``runs`` such runs side by side in
    ``processes`` (:func:`worker_processes`)."""
    n, t = config.ga.population_size, config.evaluation.trials
    w, c, d = info.genome_length, info.characterisation_size, len(info.sdbc_names)
    per_individual = 8 * (w + 2 * t + c + d)
    archive = config.novelty.archive_size * 8 * (max(c, d) + 2)
    return Footprint(
        trials=runs * n * t * TRIAL_BYTES,
        arrays=runs * (COPIES * n * per_individual + archive),
        workers=worker_processes(config, workers, runs, processes) * WORKER_BYTES,
    )


def available_memory() -> int | None:
    """Bytes the kernel says can be had without swapping (``MemAvailable``), or
    None where it does not say."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError):
        return None


def check_footprint(
    config: ExperimentConfig,
    info: TaskInfo,
    workers: int = 1,
    runs: int = 1,
    processes: int | None = None,
) -> None:
    """Refuses a run whose estimated peak memory exceeds what is available.

    Args:
        workers: Local worker processes of a run (1: in process).
        runs: Runs of ``config`` side by side.
        processes: The processes they go in (:func:`worker_processes`).

    Raises:
        FootprintError: Naming the population, the trials, the runs side by side,
            the workers, the estimate and the memory available.
    """
    footprint = run_footprint(config, info, workers, runs, processes)
    need = footprint.total
    have = available_memory()
    if have is None or need <= have:
        return
    started = worker_processes(config, workers, runs, processes)
    kind = "processes" if runs > 1 else "worker processes"
    raise FootprintError(
        f"ga.population_size {config.ga.population_size} x evaluation.trials "
        f"{config.evaluation.trials}"
        + (f" in {runs} runs side by side" if runs > 1 else "")
        + (f" with {started} {kind}" if started else "")
        + f" needs about {need / GIB:.1f} GiB of memory at once, only "
        f"{have / GIB:.1f} GiB available: choose a smaller population"
        + (", fewer trials or fewer workers" if started else " or fewer trials")
    )
