"""Cost of SDBC extraction as a fraction of the engine's step, side by side in one run.

For every task of the registry (or ``--task``), a batch of ``--genomes`` x
``--trials`` trials (default 200 x 10 = 2000, as in a generation) with random genomes
runs through :func:`sdbc_sim.run_batch` with the SDBC extractor as its observer,
wrapped in a stopwatch. At every step the wrapper times the extractor's ``observe``
and the time since the previous ``observe`` returned: the engine's step, including
building the task state it hands to observers. Both are summed over the same steps
of the same run, so machine load weighs on both alike.

The last lines read ``TASK sdbc/engine=P% engine=E ms/step sdbc=S ms/step`` and a
verdict against the target (at most 15% of the engine's step). Where some steps had
at most a quarter of the trials still running (the extractor then computes only
those), the per-task line also gives the ratio over those steps alone.

Run: ``scripts/sdbc bench sdbc`` (options: ``--task``, ``--genomes``, ``--trials``,
``--steps``, ``--seed``, ``--no-checks``).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass

import numpy as np
from sdbc_evolution.sdbc.characterisation import SdbcExtractor
from sdbc_sim.engine import run_batch
from sdbc_sim.task_state import TaskDescription, TaskState
from sdbc_sim.tasks import available_tasks, make_task

TARGET = 0.15
"""The issue's target: extraction costs at most 15% of the engine's step."""
THINNED = 0.25
"""Steps with at most this share of the trials running are also reported apart."""


class Stopwatch:
    """An observer that times another one and the engine between its calls."""

    def __init__(self, inner: SdbcExtractor) -> None:
        self.inner = inner
        self.observer_seconds = 0.0
        self.engine_seconds = 0.0
        self.steps = 0
        self.thinned_observer_seconds = 0.0
        self.thinned_engine_seconds = 0.0
        self.thinned_steps = 0
        self._last = 0.0

    def start(self, description: TaskDescription, n_trials: int) -> None:
        self.inner.start(description, n_trials)
        self._last = time.perf_counter()

    def observe(self, state: TaskState) -> None:
        t0 = time.perf_counter()
        self.inner.observe(state)
        t1 = time.perf_counter()
        self.engine_seconds += t0 - self._last
        self.observer_seconds += t1 - t0
        self.steps += 1
        if np.count_nonzero(state.active) <= THINNED * state.active.shape[0]:
            self.thinned_engine_seconds += t0 - self._last
            self.thinned_observer_seconds += t1 - t0
            self.thinned_steps += 1
        self._last = time.perf_counter()


@dataclass(frozen=True)
class Measurement:
    """One task's timings."""

    task: str
    n_trials: int
    steps: int
    engine_ms: float
    sdbc_ms: float
    thinned_steps: int
    thinned_fraction: float

    @property
    def fraction(self) -> float:
        """SDBC time / engine time."""
        return self.sdbc_ms / self.engine_ms


def measure(
    name: str, genomes: int, trials: int, steps: int | None, seed: int, checks: bool
) -> Measurement:
    """Runs one batch of the task with the timed extractor."""
    task = make_task(name) if steps is None else make_task(name, max_steps=steps)
    rng = np.random.default_rng(seed)
    g = rng.uniform(-1.0, 1.0, (genomes, task.genome_length))
    s = rng.integers(0, 2**31 - 1, (genomes, trials))
    watch = Stopwatch(SdbcExtractor(check_values=checks))
    run_batch(task, g, s, [watch])
    return Measurement(
        task=name,
        n_trials=genomes * trials,
        steps=watch.steps,
        engine_ms=1e3 * watch.engine_seconds / watch.steps,
        sdbc_ms=1e3 * watch.observer_seconds / watch.steps,
        thinned_steps=watch.thinned_steps,
        thinned_fraction=(
            watch.thinned_observer_seconds / watch.thinned_engine_seconds
            if watch.thinned_steps
            else float("nan")
        ),
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", action="append", help="a task (default: all)")
    parser.add_argument("--genomes", type=int, default=200)
    parser.add_argument("--trials", type=int, default=10, help="trials per genome")
    parser.add_argument("--steps", type=int, help="cap on trial length (max_steps)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--no-checks", action="store_true", help="skip the per-step value checks"
    )
    args = parser.parse_args()
    names = args.task or sorted(available_tasks())
    results = []
    for name in names:
        m = measure(
            name, args.genomes, args.trials, args.steps, args.seed, not args.no_checks
        )
        results.append(m)
        print(
            f"{m.task}: {m.n_trials} trials, {m.steps} steps, engine "
            f"{m.engine_ms:.2f} ms/step, sdbc {m.sdbc_ms:.3f} ms/step",
            flush=True,
        )
    for m in results:
        thinned = (
            f" (steps with <= {100 * THINNED:.0f}% of trials running: "
            f"{m.thinned_steps}, sdbc/engine={100 * m.thinned_fraction:.1f}%)"
            if m.thinned_steps
            else ""
        )
        print(
            f"{m.task} sdbc/engine={100 * m.fraction:.1f}% engine={m.engine_ms:.2f} "
            f"ms/step sdbc={m.sdbc_ms:.3f} ms/step{thinned}"
        )
    worst = max(results, key=lambda m: m.fraction)
    verdict = "met" if worst.fraction <= TARGET else "MISSED"
    print(
        f"target sdbc/engine <= {100 * TARGET:.0f}%: {verdict} "
        f"(worst {worst.task} {100 * worst.fraction:.1f}%)"
    )


if __name__ == "__main__":
    main()
