"""Where an engine step's CPU time goes, per task: the profile that picks the next
optimisation.

For every task of the registry (or ``--task``), a batch of ``--genomes`` x
``--trials`` random genomes (default 200 x 10, a generation) runs through
:func:`sdbc_sim.run_batch` with the SDBC extractor as its observer (as evolution
runs it; ``--no-sdbc`` leaves it out). The engine is not changed: for the duration
of the run, its own functions are wrapped in a timer that charges each call's CPU
time (``time.process_time``) to one part, minus the time of the timed parts it
calls (so every part is exclusive and the parts add up):

- chipmunk step: ``pymunk.Space.step``;
- kinematic step: ``KinematicTrials.step`` and ``read`` (with ``--physics
  model=kinematic``, where it replaces the chipmunk step and bulk transfer);
- bulk transfer: the rest of ``TrialSpaces.read`` and ``TrialSpaces.step``
  (pymunk.batch reads and writes, the copies around them);
- separation: ``TrialSpaces.separate`` (contacts read in bulk, projection; the
  projected positions reach pymunk with the next step's bulk write);
- sensors: ``task.sensors``; network: ``TeamNetworks.forward``;
- actuate: ``task.actuate``; drive: ``BatchSimulation._drive`` (headings and
  forces from speed and turn);
- task rules: ``task.update`` and ``task.results``;
- task state: ``BatchSimulation.state`` (``task.task_state`` and the spreading over
  the whole batch once trials have been dropped);
- SDBC extractor: the extractor's ``observe``;
- compaction: ``BatchSimulation._compact_if_worthwhile`` and
  ``TrialSpaces.disable``;
- setup: building the batch (``BatchSimulation.__init__``: reset, Spaces) and the
  extractor's ``start``;
- other: the rest of ``run_batch`` (the step loop, the checks in ``step``);
- compiled loops (with ``--loops``): every call of a loop of
  :mod:`sdbc_sim.compiled`, taken out of the part that made it, so that each
  part keeps what lies between its loops (numpy's work, Python's); the SDBC
  extractor's kernels too, which it takes once per batch and calls directly;
- numpy maths (with ``--loops``): numpy's ``exp`` (the network's sigmoids) and
  ``arctan2`` (bearings), likewise taken out of their parts: numpy's own
  implementations of them give those values their bits, in a batch and in a
  controller node alike, so a compiled loop could not take them over.

The first 5 genomes run first, untimed, so that what a process pays once (first
calls, numba imported and the compiled loops loaded) is not charged to a part;
then the garbage the process holds is collected, untimed, so that what earlier
work left (another model's batch) is not charged to this one.

Every part is printed with its CPU seconds, its share, its cost per step and per
robot-step, and the robot-steps per CPU-second the whole batch reached; the timer's
own cost (a few microseconds per call, about 15 calls per step) falls in the parts
it wraps. Robot-steps count every body of every trial for every step it took, as
``bench/engine.py`` counts them.

Run: ``scripts/sdbc bench profile`` (options: ``--task``, ``--genomes``,
``--trials``, ``--steps``, ``--seed``, ``--no-sdbc``, ``--loops``, ``--physics
NAME=VALUE``, ``--core N``, ``--json FILE``).
"""

from __future__ import annotations

import argparse
import gc
import json
import time
from collections.abc import Callable
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pymunk
from common import (
    add_batch_arguments,
    batch_arguments,
    patched,
    pin_to_core,
    random_batch,
)
from sdbc_evolution.sdbc.characterisation import SdbcExtractor
from sdbc_sim.engine import BatchSimulation, EngineSettings, run_batch
from sdbc_sim.kinematic import KinematicTrials
from sdbc_sim.network import TeamNetworks
from sdbc_sim.physics import TrialSpaces
from sdbc_sim.task import Task
from sdbc_sim.tasks import make_task

from sdbc_sim import compiled

PARTS = (
    "chipmunk step",
    "kinematic step",
    "bulk transfer",
    "separation",
    "sensors",
    "network",
    "actuate",
    "drive",
    "task rules",
    "task state",
    "SDBC extractor",
    "compaction",
    "setup",
    "other",
    "compiled loops",
    "numpy maths",
)
FUSED_FLOOR = (
    "chipmunk step",
    "kinematic step",
    "bulk transfer",
    "compiled loops",
    "numpy maths",
)
"""The parts a step fused into a few compiled passes would still pay: the
physics' own step and the transfer to and from it, the compiled loops, whose
arithmetic (each IEEE operation, in its order) gives the results their bits,
and numpy's ``exp`` and ``arctan2``, whose implementations give theirs. The
other parts are what lies between them."""


@dataclass
class Clock:
    """Exclusive CPU seconds per part: a call's time minus its timed callees'."""

    seconds: dict[str, float] = field(default_factory=lambda: dict.fromkeys(PARTS, 0.0))
    calls: dict[str, int] = field(default_factory=lambda: dict.fromkeys(PARTS, 0))
    _children: list[float] = field(default_factory=list)

    def wrap(self, part: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        """``fn`` timed as ``part``."""
        seconds, calls, children = self.seconds, self.calls, self._children
        clock = time.process_time

        def timed(*args: Any, **kwargs: Any) -> Any:
            children.append(0.0)
            t0 = clock()
            try:
                return fn(*args, **kwargs)
            finally:
                elapsed = clock() - t0
                inner = children.pop()
                seconds[part] += elapsed - inner
                calls[part] += 1
                if children:
                    children[-1] += elapsed

        return timed


@contextmanager
def instrumented(
    clock: Clock, task: Task, extractor: SdbcExtractor | None, loops: bool = False
):
    """The engine's functions wrapped in ``clock`` for the duration; with
    ``loops``, the compiled loops and numpy's ``exp`` and ``arctan2`` too."""
    targets: list[tuple[Any, str, str]] = [
        (pymunk.Space, "step", "chipmunk step"),
        (TrialSpaces, "read", "bulk transfer"),
        (TrialSpaces, "step", "bulk transfer"),
        (TrialSpaces, "separate", "separation"),
        (TrialSpaces, "disable", "compaction"),
        (KinematicTrials, "read", "kinematic step"),
        (KinematicTrials, "step", "kinematic step"),
        (KinematicTrials, "separate", "separation"),
        (KinematicTrials, "disable", "compaction"),
        (TeamNetworks, "forward", "network"),
        (BatchSimulation, "_drive", "drive"),
        (BatchSimulation, "state", "task state"),
        (BatchSimulation, "_compact_if_worthwhile", "compaction"),
        (BatchSimulation, "__init__", "setup"),
        (task, "sensors", "sensors"),
        (task, "actuate", "actuate"),
        (task, "update", "task rules"),
        (task, "results", "task rules"),
    ]
    if extractor is not None:
        targets += [
            (extractor, "observe", "SDBC extractor"),
            (extractor, "start", "setup"),
        ]
    if loops:
        targets += [
            (compiled._Loop, "__call__", "compiled loops"),
            (np, "exp", "numpy maths"),
            (np, "arctan2", "numpy maths"),
        ]
    with ExitStack() as stack:
        for owner, name, part in targets:
            # A class's function is wrapped as a function (it binds as a method);
            # an instance's bound method is wrapped as it is.
            fn = vars(owner)[name] if isinstance(owner, type) else getattr(owner, name)
            stack.enter_context(patched(owner, name, clock.wrap(part, fn)))
        if loops:
            # The SDBC extractor takes its loops' kernels once, through ``load``,
            # and calls them directly: handed timed kernels, it is timed too.
            load = vars(compiled._Loop)["load"]

            def timed_load(loop: compiled._Loop) -> Callable[..., Any]:
                return clock.wrap("compiled loops", load(loop))

            stack.enter_context(patched(compiled._Loop, "load", timed_load))
        yield


@dataclass
class Profile:
    """One task's profile."""

    task: str
    sdbc: bool
    n_trials: int
    steps: int
    robot_steps: int
    total: float
    seconds: dict[str, float]
    calls: dict[str, int]

    @property
    def rate(self) -> float:
        """Robot-steps per CPU-second, instrumented."""
        return self.robot_steps / self.total

    def ns(self, *parts: str) -> float:
        """CPU nanoseconds per robot-step of ``parts`` together."""
        return 1e9 * sum(self.seconds[part] for part in parts) / self.robot_steps

    def share(self, *parts: str) -> float:
        """The fraction of the batch's CPU time spent in ``parts`` together."""
        return sum(self.seconds[part] for part in parts) / self.total


def profile_task(
    name: str,
    genomes: int,
    trials: int,
    steps: int | None,
    seed: int,
    settings: EngineSettings,
    sdbc: bool,
    loops: bool = False,
) -> Profile:
    """Runs and profiles one batch of the task (with ``loops``, the compiled
    loops as a part of their own)."""
    task = make_task(name) if steps is None else make_task(name, max_steps=steps)
    g, s = random_batch(task, genomes, trials, np.random.default_rng(seed))
    extractor = SdbcExtractor(check_values=False) if sdbc else None
    clock = Clock()
    observers = [extractor] if extractor is not None else []
    # A few genomes first, untimed: what a process pays once (first calls, numba
    # imported and the compiled loops loaded at the first setup) is not a cost
    # of the step.
    warm_up = [SdbcExtractor(check_values=False)] if sdbc else []
    run_batch(task, g[:5], s[:5], warm_up, settings=settings)
    # Garbage that earlier work in this process left (another model's batch,
    # whose pymunk objects only the cyclic collector frees) is not this batch's.
    gc.collect()
    with instrumented(clock, task, extractor, loops):
        t0 = time.process_time()
        result = run_batch(task, g, s, observers, settings=settings)
        total = time.process_time() - t0
    clock.seconds["other"] = total - sum(
        v for k, v in clock.seconds.items() if k != "other"
    )
    n_steps = int(result.length.max())
    return Profile(
        task=name,
        sdbc=sdbc,
        n_trials=genomes * trials,
        steps=n_steps,
        robot_steps=int(result.length.sum()) * task.layout.n_bodies,
        total=total,
        seconds=dict(clock.seconds),
        calls=dict(clock.calls),
    )


def report(p: Profile) -> str:
    """The profile as a table."""
    lines = [
        f"{p.task} ({'with' if p.sdbc else 'without'} SDBC): {p.n_trials} trials, "
        f"{p.steps} steps, {p.robot_steps:,} robot-steps in {p.total:.2f} CPU-s = "
        f"{p.rate:,.0f} robot-steps per CPU-second",
        f"  {'part':<16}{'CPU s':>8}{'share':>8}{'ms/step':>9}{'ns/robot-step':>15}"
        f"{'calls':>8}",
    ]
    for part in PARTS:
        sec = p.seconds[part]
        lines.append(
            f"  {part:<16}{sec:>8.2f}{100 * p.share(part):>7.1f}%"
            f"{1e3 * sec / p.steps:>9.3f}{p.ns(part):>15.1f}"
            f"{p.calls[part]:>8}"
        )
    physics = ("chipmunk step", "bulk transfer")
    if p.share(*physics) > 0.0:
        lines.append(
            f"  chipmunk + bulk transfer alone: {p.ns(*physics):.0f} ns per "
            f"robot-step, {1e9 / p.ns(*physics):,.0f} robot-steps per CPU-second"
        )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_batch_arguments(parser, genomes=200, trials=10, seed=0)
    parser.add_argument("--no-sdbc", action="store_true", help="no SDBC extractor")
    parser.add_argument(
        "--loops",
        action="store_true",
        help="the compiled loops, and numpy's exp and arctan2, as parts of their own",
    )
    parser.add_argument("--core", type=int, help="pin to this core (default: none)")
    parser.add_argument("--json", type=Path, help="also write the profiles here")
    args = parser.parse_args()
    names, settings = batch_arguments(parser, args)
    if args.core is not None:
        pin_to_core(args.core)
    profiles = []
    for name in names:
        p = profile_task(
            name,
            args.genomes,
            args.trials,
            args.steps,
            args.seed,
            settings,
            not args.no_sdbc,
            args.loops,
        )
        profiles.append(p)
        print(report(p), flush=True)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(
            json.dumps([vars(p) | {"rate": p.rate} for p in profiles], indent=1)
        )


if __name__ == "__main__":
    main()
