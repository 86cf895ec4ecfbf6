"""Engine throughput: robot-steps per second, side by side in one run.

For every task of the registry (or ``--task``), at ``--genomes`` x ``--trials``
trials with random genomes (uniform in [-1, 1]):

- engine: :func:`sdbc_sim.run_batch` on the whole batch;
- naive: the same task code one trial at a time, one Space per trial, a Python
  loop over trials: after every engine step, ``--naive-trials`` steps of lone
  trials (the batch's first ``--naive-trials`` trials, in turn), so that engine
  and naive run under the same load on a shared machine;
- floor: the same Spaces stepped with bulk transfer only: the time the engine run
  itself spent reading the bodies in bulk and setting their drive and stepping
  chipmunk (same Spaces, same motion, same contacts), without sensors, network,
  rules, contact projection or observers. With ``--physics model=kinematic``, the
  time in the kinematic model's compiled loop instead.
- physics: the floor plus the contact projection (``separate``: the contacts
  read in bulk, overlapping bodies projected apart). The rigid model switches
  chipmunk's own push-out off and projects overlaps itself (``sdbc_sim.physics``),
  so this is everything the model does to move bodies and resolve their
  contacts; when the floor got cheaper than the rest of the step, this is the
  floor that still says what share of the step the physics takes.
- ``--standalone-floor`` also steps fresh copies of the same Spaces with bulk
  transfer only, bodies at rest and bodies pushed at full speed along their
  headings (piling up on walls), as bounds on chipmunk's cost.

Robot-steps count every body of every trial for every step it took. The last lines
read ``TASK robot-steps/s=N naive=Rx floor=F physics=P`` with R = engine / naive,
F = engine / floor (the share of the engine's time spent in chipmunk and bulk
transfer) and P = engine / physics (that share with the projection).
``--physics NAME=VALUE`` sets a physics setting for engine, naive and floor alike.
``--sweep NAME=V1,V2,...`` also times the engine (best of
``--repeat``) at each value of one physics setting, such as
``trials_per_space=125,250,500`` or ``hash_cell=8,16,32,64``: the defaults of
those settings come from it.

Run: ``.venv/bin/python bench/engine.py`` (options: ``--task``, ``--genomes``,
``--trials``, ``--steps``, ``--naive-trials``, ``--sweep``, ``--repeat``,
``--standalone-floor``, ``--seed``, ``--physics``).
"""

from __future__ import annotations

import argparse
import itertools
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from common import add_batch_arguments, batch_arguments, physics_sweep
from sdbc_sim.engine import PHYSICS_MODELS, BatchSimulation, EngineSettings
from sdbc_sim.physics import READ_WIDTH, WRITE_WIDTH, PhysicsSettings, TrialSpaces
from sdbc_sim.task import Task
from sdbc_sim.tasks import make_task


class PhysicsClock:
    """Times, while ``on``, ``read`` and ``step`` of every physics model (bulk
    transfer and chipmunk for the rigid model, the compiled loop for the kinematic
    one; a step reads its state back itself) into ``seconds``, and its
    ``separate`` (the contact projection) into ``projection``."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self.projection = 0.0
        self.on = False
        self._saved = {
            cls: (cls.read, cls.step, cls.separate)
            for cls in set(PHYSICS_MODELS.values())
        }

    def __enter__(self) -> PhysicsClock:
        for cls, (read, step, separate) in self._saved.items():
            cls.read = self._timed(read, "seconds")  # type: ignore[method-assign]
            cls.step = self._timed(step, "seconds")  # type: ignore[method-assign]
            cls.separate = self._timed(  # type: ignore[method-assign]
                separate, "projection"
            )
        return self

    def _timed(self, method: Callable[..., None], into: str) -> Callable[..., None]:
        clock = self

        def timed(*args: Any) -> None:
            t0 = time.perf_counter()
            method(*args)
            if clock.on:
                setattr(clock, into, getattr(clock, into) + time.perf_counter() - t0)

        return timed

    def __exit__(self, *exc: object) -> None:
        for cls, (read, step, separate) in self._saved.items():
            cls.read, cls.step = read, step  # type: ignore[method-assign]
            cls.separate = separate  # type: ignore[method-assign]


@dataclass
class Rates:
    """Robot-steps per second measured in one interleaved run."""

    engine: float
    naive: float
    floor: float
    physics: float
    steps: int


def measure(
    task: Task,
    genomes: np.ndarray,
    seeds: np.ndarray,
    settings: EngineSettings,
    naive_trials: int,
) -> Rates:
    """Runs the whole batch through the engine and, between its steps,
    ``naive_trials`` steps of trials run one at a time (the batch's first
    ``naive_trials`` trials, over and over), so that both see the same load.

    The engine is :func:`sdbc_sim.run_batch`'s loop (a BatchSimulation of every
    trial, stepped until all have ended); the floor is the engine's own time in
    bulk transfer and chipmunk steps, the physics that time and the projection's.
    """
    n_trials = seeds.shape[1]
    flat_g = np.repeat(genomes, n_trials, axis=0)
    flat_s = seeds.reshape(-1)
    sim = BatchSimulation(task, flat_s, flat_g, settings)
    pick = itertools.cycle(range(min(naive_trials, flat_s.shape[0])))
    lone: BatchSimulation | None = None
    engine_s = naive_s = 0.0
    naive_steps = 0
    with PhysicsClock() as clock:
        while not sim.finished:
            clock.on = True
            t0 = time.perf_counter()
            sim.step()
            engine_s += time.perf_counter() - t0
            clock.on = False
            t0 = time.perf_counter()
            for _ in range(naive_trials):
                if lone is None or lone.finished:
                    k = next(pick)
                    lone = BatchSimulation(
                        task, flat_s[k : k + 1], flat_g[k : k + 1], settings
                    )
                lone.step()
                naive_steps += 1
            naive_s += time.perf_counter() - t0
    steps = int(sim.length.sum())
    per_step = task.layout.n_bodies
    return Rates(
        engine=steps * per_step / engine_s,
        naive=naive_steps * per_step / naive_s if naive_steps else float("nan"),
        floor=steps * per_step / clock.seconds,
        physics=steps * per_step / (clock.seconds + clock.projection),
        steps=steps,
    )


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
    col = spaces.drive_columns
    # What the engine writes (see BatchSimulation._drive): the velocity itself, or
    # the force that reaches it in one step (unit mass, dt 1 in every task).
    force = settings.actuation == "force"
    spaces.read(rows)
    t0 = time.perf_counter()
    for _ in range(steps):
        drive[:, col.angle] = rows[:, 2]
        drive[:, col.x] = speed * np.cos(rows[:, 2]) - force * rows[:, 3]
        drive[:, col.y] = speed * np.sin(rows[:, 2]) - force * rows[:, 4]
        spaces.step(drive, rows)
    elapsed = time.perf_counter() - t0
    return steps * rows.shape[0] / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_batch_arguments(parser, genomes=200, trials=10, seed=0)
    parser.add_argument("--naive-trials", type=int, default=20)
    parser.add_argument(
        "--sweep",
        metavar="NAME=V1,V2,...",
        help="a physics setting and the values to time it at",
    )
    parser.add_argument("--standalone-floor", action="store_true")
    parser.add_argument("--repeat", type=int, default=2, help="sweep repeats")
    args = parser.parse_args()
    names, settings = batch_arguments(parser, args)
    sweep: list[PhysicsSettings] = []
    if args.sweep:
        try:
            sweep = physics_sweep(settings.physics, args.sweep)
        except ValueError as e:
            parser.error(str(e))
    rng = np.random.default_rng(args.seed)
    lines = []
    for name in names:
        task = make_task(name, **({"max_steps": args.steps} if args.steps else {}))
        genomes = rng.uniform(-1.0, 1.0, (args.genomes, task.genome_length))
        seeds = rng.integers(0, 2**31, (args.genomes, args.trials))
        n_trials = seeds.size
        r = measure(task, genomes, seeds, settings, args.naive_trials)
        engine, naive, floor, steps = r.engine, r.naive, r.floor, r.steps
        print(
            f"{name}: {n_trials} trials, {steps / n_trials:.0f} steps per trial; "
            f"robot-steps/s engine {engine:,.0f}, naive {naive:,.0f}, "
            f"floor {floor:,.0f}, physics {r.physics:,.0f}"
        )
        mean_steps = max(1, steps // n_trials)
        if args.standalone_floor:
            for speed in (0.0, 1.0):
                f = standalone_floor_rate(
                    task, seeds, mean_steps, settings.physics, speed
                )
                print(f"  standalone floor, bodies at speed {speed}: {f:,.0f}")
        if sweep:
            # Round robin, best of --repeat: other load on the machine only slows.
            best = [(0.0, 0.0)] * len(sweep)
            for _ in range(args.repeat):
                for k, physics in enumerate(sweep):
                    m = measure(task, genomes, seeds, EngineSettings(physics), 0)
                    best[k] = max(best[k], (m.engine, m.floor))
            setting = args.sweep.partition("=")[0]
            for physics, (rate, f) in zip(sweep, best, strict=True):
                value = getattr(physics, setting)
                print(f"  {setting}={value}: engine {rate:,.0f}, floor {f:,.0f}")
        lines.append(
            f"{name} robot-steps/s={engine:.0f} naive={engine / naive:.1f}x "
            f"floor={engine / floor:.2f} physics={engine / r.physics:.2f}"
        )
    print("\n".join(lines))


if __name__ == "__main__":
    main()
