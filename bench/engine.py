"""Engine throughput: robot-steps per second, side by side in one run.

For every task of the registry (or ``--task``), at ``--genomes`` x ``--trials``
trials with random genomes (uniform in [-1, 1]):

- engine: :func:`sdbc_sim.run_batch` on the whole batch;
- naive: the same task code one trial at a time, one Space per trial, a Python
  loop over trials (measured on ``--naive-trials`` trials and scaled);
- floor: the same Spaces stepped with bulk transfer only: the time the engine run
  itself spent reading the bodies in bulk and setting their drive and stepping
  chipmunk (same Spaces, same motion, same contacts), without sensors, network,
  rules, contact projection or observers.
- ``--standalone-floor`` also steps fresh copies of the same Spaces with bulk
  transfer only, bodies at rest and bodies pushed at full speed along their
  headings (piling up on walls), as bounds on chipmunk's cost.

Robot-steps count every body of every trial for every step it took. The last lines
read ``TASK robot-steps/s=N naive=Rx floor=F`` with R = engine / naive and
F = engine / floor (the share of the engine's time spent in chipmunk and bulk
transfer). ``--sweep 100,250,500`` also times the engine at each number of trials
per Space (the setting's default comes from it).

Run: ``.venv/bin/python bench/engine.py`` (options: ``--task``, ``--genomes``,
``--trials``, ``--steps``, ``--naive-trials``, ``--sweep``, ``--repeat``,
``--standalone-floor``, ``--seed``).
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
from sdbc_sim.engine import BatchSimulation, EngineSettings, run_batch
from sdbc_sim.physics import READ_WIDTH, WRITE_WIDTH, PhysicsSettings, TrialSpaces
from sdbc_sim.task import Task
from sdbc_sim.tasks import available_tasks, make_task


class PhysicsClock:
    """Times TrialSpaces.read and TrialSpaces.step (bulk transfer and chipmunk)."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self._saved = (TrialSpaces.read, TrialSpaces.step)

    def __enter__(self) -> PhysicsClock:
        read, step = self._saved
        clock = self

        def timed_read(spaces: TrialSpaces, out: np.ndarray) -> None:
            t0 = time.perf_counter()
            read(spaces, out)
            clock.seconds += time.perf_counter() - t0

        def timed_step(spaces: TrialSpaces, drive: np.ndarray) -> None:
            t0 = time.perf_counter()
            step(spaces, drive)
            clock.seconds += time.perf_counter() - t0

        TrialSpaces.read, TrialSpaces.step = timed_read, timed_step
        return self

    def __exit__(self, *exc: object) -> None:
        TrialSpaces.read, TrialSpaces.step = self._saved


def engine_rate(
    task: Task, genomes: np.ndarray, seeds: np.ndarray, settings: EngineSettings
) -> tuple[float, float, int]:
    """(robot-steps per second of run_batch, of its bulk transfer and chipmunk
    steps alone, trial steps) on the whole batch."""
    with PhysicsClock() as clock:
        t0 = time.perf_counter()
        result = run_batch(task, genomes, seeds, settings=settings)
        elapsed = time.perf_counter() - t0
    steps = int(result.length.sum())
    robot_steps = steps * task.layout.n_bodies
    return robot_steps / elapsed, robot_steps / clock.seconds, steps


def naive_rate(task: Task, genomes: np.ndarray, seeds: np.ndarray, n: int) -> float:
    """Robot-steps per second of the first ``n`` trials run one at a time."""
    flat_g = np.repeat(genomes, seeds.shape[1], axis=0)[:n]
    flat_s = seeds.reshape(-1)[:n]
    steps = 0
    t0 = time.perf_counter()
    for g, s in zip(flat_g, flat_s, strict=True):
        sim = BatchSimulation(task, np.array([s]), g[None])
        while not sim.finished:
            sim.step()
        steps += int(sim.length[0])
    elapsed = time.perf_counter() - t0
    return steps * task.layout.n_bodies / elapsed


def standalone_floor_rate(
    task: Task, seeds: np.ndarray, steps: int, settings: PhysicsSettings, speed: float
) -> float:
    """Robot-steps per second of fresh copies of the Spaces with bulk transfer
    only, every body pushed at ``speed`` along its heading."""
    _, position, angle = task.reset(
        [np.random.default_rng(int(s)) for s in seeds.ravel()]
    )
    spaces = TrialSpaces.of_task(task, position, angle, settings)
    rows = np.empty((position.shape[0] * task.layout.n_bodies, READ_WIDTH))
    drive = np.zeros((rows.shape[0], WRITE_WIDTH))
    t0 = time.perf_counter()
    for _ in range(steps):
        spaces.read(rows)
        drive[:, 0] = rows[:, 2]
        drive[:, 2] = speed * np.cos(rows[:, 2]) - rows[:, 3]
        drive[:, 3] = speed * np.sin(rows[:, 2]) - rows[:, 4]
        spaces.step(drive)
    elapsed = time.perf_counter() - t0
    return steps * rows.shape[0] / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--task", action="append", help="task name (repeatable)")
    parser.add_argument("--genomes", type=int, default=200)
    parser.add_argument("--trials", type=int, default=10, help="trials per genome")
    parser.add_argument("--steps", type=int, help="override the task's max_steps")
    parser.add_argument("--naive-trials", type=int, default=20)
    parser.add_argument("--sweep", help="comma-separated trials per Space to time")
    parser.add_argument("--standalone-floor", action="store_true")
    parser.add_argument("--repeat", type=int, default=2, help="sweep repeats")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    names = args.task or sorted(available_tasks())
    rng = np.random.default_rng(args.seed)
    settings = EngineSettings()
    lines = []
    for name in names:
        task = make_task(name, **({"max_steps": args.steps} if args.steps else {}))
        genomes = rng.uniform(-1.0, 1.0, (args.genomes, task.genome_length))
        seeds = rng.integers(0, 2**31, (args.genomes, args.trials))
        n_trials = seeds.size
        engine, floor, steps = engine_rate(task, genomes, seeds, settings)
        naive = naive_rate(task, genomes, seeds, min(args.naive_trials, n_trials))
        print(
            f"{name}: {n_trials} trials, {steps / n_trials:.0f} steps per trial; "
            f"robot-steps/s engine {engine:,.0f}, naive {naive:,.0f}, "
            f"floor {floor:,.0f}"
        )
        mean_steps = max(1, steps // n_trials)
        if args.standalone_floor:
            for speed in (0.0, 1.0):
                f = standalone_floor_rate(
                    task, seeds, mean_steps, settings.physics, speed
                )
                print(f"  standalone floor, bodies at speed {speed}: {f:,.0f}")
        if args.sweep:
            # Round robin, best of --repeat: other load on the machine only slows.
            sizes = [int(v) for v in args.sweep.split(",")]
            best = dict.fromkeys(sizes, (0.0, 0.0))
            for _ in range(args.repeat):
                for k in sizes:
                    physics = dataclasses.replace(settings.physics, trials_per_space=k)
                    rate, f, _ = engine_rate(
                        task, genomes, seeds, EngineSettings(physics)
                    )
                    best[k] = max(best[k], (rate, f))
            for k in sizes:
                rate, f = best[k]
                print(f"  trials_per_space={k}: engine {rate:,.0f}, floor {f:,.0f}")
        lines.append(
            f"{name} robot-steps/s={engine:.0f} naive={engine / naive:.1f}x "
            f"floor={engine / floor:.2f}"
        )
    print("\n".join(lines))


if __name__ == "__main__":
    main()
