"""A compiled loop alone, on the inputs it met in a batch: what a pass costs in
the step, alone on one step's inputs repeated, and alone on many steps' inputs.

For a task (``--task``, default gate escape), one batch of ``--genomes`` x
``--trials`` random genomes runs through :func:`sdbc_sim.run_batch` with the SDBC
extractor, every compiled loop of :mod:`sdbc_sim.compiled` wrapped so that each
call's time is charged to its loop, and the time of calls ``--start`` to
``--start + --record - 1`` of each loop is kept. The same batch then runs again
(it is deterministic, so the calls are the same), and for the loops named by
``--loop`` (default: the ``--top`` costliest in the step) the arguments of
those calls are copied as they were at the call. Then each loop runs alone on
copies of them:

- repeated: the first recorded call's inputs, again and again;
- varied: each recorded call's inputs in turn, several rounds.

Inputs are copied afresh before every timed call (a loop may write into an array
it also reads), so both alone forms start from data just written to memory.
Medians are printed, in microseconds per call, with the ratios of the step's
time to each.

Why two runs: the copies kept while recording grow the heap, so that the
arrays the engine allocates for a loop's outputs in the calls that follow land
on pages the process has not touched yet, and the loop pays their page faults.
Predator-prey's ``_seen_by_predators`` took 242-351 us per call in the step with
every loop's inputs kept, 48-49 with nothing kept. The step's times come from the
run that keeps nothing.

Why: a loop timed alone on one input repeated can run at half its cost in the
step, and that gap was read as the cache's (a step's arrays do not stay in the
second-level cache from one pass to the next). On this machine's CPU the branch
predictor learns a repeated call's branches, the C library's cosine and sine
among them; on varied inputs that learning is gone. The varied form tells the
two apart.

Run: ``scripts/sdbc bench replay`` (options: ``--task``, ``--genomes``,
``--trials``, ``--steps``, ``--seed``, ``--physics NAME=VALUE``, ``--loop NAME``,
``--top``, ``--start``, ``--record``, ``--rounds``, ``--core``).
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from common import (
    add_batch_arguments,
    batch_arguments,
    patched,
    pin_to_core,
    random_batch,
)
from sdbc_evolution.sdbc.characterisation import SdbcExtractor
from sdbc_sim.engine import EngineSettings, run_batch
from sdbc_sim.tasks import make_task

from sdbc_sim import compiled


def _copy_array(a: np.ndarray) -> np.ndarray:
    """A copy with ``a``'s strides: a view into the engine's state rows (a
    strided column) stays strided, as the loop met it."""
    if (
        a.flags.c_contiguous
        or a.size == 0
        or any(st < 0 or st % a.itemsize for st in a.strides)
    ):
        return a.copy()
    span = sum((n - 1) * st for n, st in zip(a.shape, a.strides, strict=True))
    base = np.empty(span // a.itemsize + 1, dtype=a.dtype)
    out = np.lib.stride_tricks.as_strided(base, a.shape, a.strides)
    out[...] = a
    return out


def _copy(args: tuple[Any, ...]) -> tuple[Any, ...]:
    return tuple(_copy_array(a) if isinstance(a, np.ndarray) else a for a in args)


@dataclass
class LoopCalls:
    """One loop's calls in the batch: their time, and each recorded call's."""

    seconds: float = 0.0
    calls: int = 0
    in_step: list[float] = field(default_factory=list)


@dataclass
class Replay:
    """A loop's median time per call, in seconds, in the step and alone."""

    name: str
    calls: int
    in_step: float
    repeated: float
    varied: float


@contextmanager
def timing(start: int, count: int) -> Iterator[dict[str, LoopCalls]]:
    """Wraps every compiled loop while the block runs: per loop name, the time
    of every call, and of calls ``start`` to ``start + count - 1`` (0-based)
    each (``in_step``)."""
    log: dict[str, LoopCalls] = {}
    call = compiled._Loop.__call__

    def timed(loop: compiled._Loop, *args: Any) -> Any:
        entry = log.setdefault(loop_name(loop), LoopCalls())
        t0 = time.perf_counter()
        result = call(loop, *args)
        took = time.perf_counter() - t0
        if start <= entry.calls < start + count:
            entry.in_step.append(took)
        entry.seconds += took
        entry.calls += 1
        return result

    with patched(compiled._Loop, "__call__", timed):
        yield log


@contextmanager
def recording(
    names: set[str], start: int, count: int
) -> Iterator[dict[str, list[tuple[Any, ...]]]]:
    """Wraps every compiled loop while the block runs: for the loops in
    ``names``, copies of the arguments of calls ``start`` to ``start + count -
    1`` (0-based), as they were at the call."""
    kept: dict[str, list[tuple[Any, ...]]] = {}
    calls: dict[str, int] = {}
    call = compiled._Loop.__call__

    def copying(loop: compiled._Loop, *args: Any) -> Any:
        name = loop_name(loop)
        k = calls[name] = calls.get(name, 0) + 1
        if name in names and start < k <= start + count:
            kept.setdefault(name, []).append(_copy(args))
        return call(loop, *args)

    with patched(compiled._Loop, "__call__", copying):
        yield kept


def loop_name(loop: compiled._Loop) -> str:
    """``module.function`` (the module's last part): tasks name their own loops
    alike (``gate_escape._agent_attributes``, ``resource_sharing._agent_...``)."""
    return f"{loop.fn.__module__.rpartition('.')[2]}.{loop.fn.__qualname__}"


def _loop_named(name: str) -> compiled._Loop:
    for loop in compiled._LOOPS:
        if loop_name(loop) == name:
            return loop
    raise ValueError(f"no compiled loop named {name!r}")


def _alone(loop: compiled._Loop, inputs: list[tuple[Any, ...]], calls: int) -> float:
    """Median seconds of ``calls`` calls on fresh copies of ``inputs`` in turn."""
    times = []
    for k in range(calls):
        args = _copy(inputs[k % len(inputs)])
        t0 = time.perf_counter()
        loop(*args)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def replay(
    task_name: str,
    genomes: int,
    trials: int,
    steps: int | None,
    seed: int,
    settings: EngineSettings,
    loops: list[str] | None = None,
    top: int = 6,
    start: int = 100,
    record: int = 20,
    rounds: int = 5,
) -> list[Replay]:
    """Each recorded loop's median time per call in the step, alone repeated and
    alone varied (see the module docstring), costliest in the step first."""
    task = (
        make_task(task_name) if steps is None else make_task(task_name, max_steps=steps)
    )
    g, s = random_batch(task, genomes, trials, np.random.default_rng(seed))
    # A first small batch loads the loops, so no call below pays for that.
    run_batch(task, g[:1], s[:1, :1], settings=settings)
    with timing(start, record) as log:
        run_batch(task, g, s, [SdbcExtractor(check_values=False)], settings=settings)
    timed = [n for n in log if log[n].in_step]
    if loops:
        missing = sorted(set(loops) - set(timed))
        if missing:
            raise ValueError(
                f"{task_name}: no recorded calls of {missing} (they run fewer than "
                f"--start {start} + 1 times, or are not this task's loops)"
            )
        chosen = list(loops)
    else:
        chosen = sorted(timed, key=lambda n: -log[n].seconds)[:top]
    with recording(set(chosen), start, record) as kept:
        run_batch(task, g, s, [SdbcExtractor(check_values=False)], settings=settings)
    out = []
    for name in chosen:
        entry = log[name]
        loop = _loop_named(name)
        inputs = kept[name]
        out.append(
            Replay(
                name=name,
                calls=entry.calls,
                in_step=statistics.median(entry.in_step),
                repeated=_alone(loop, inputs[:1], len(inputs) * rounds),
                varied=_alone(loop, inputs, len(inputs) * rounds),
            )
        )
    return sorted(out, key=lambda r: -log[r.name].seconds)


def report(rows: list[Replay]) -> str:
    lines = [
        f"  {'loop':<36}{'calls':>7}{'in step':>10}{'repeated':>10}{'varied':>10}"
        f"{'step/rep':>10}{'step/var':>10}   (us per call, medians)"
    ]
    for r in rows:
        lines.append(
            f"  {r.name:<36}{r.calls:>7}{r.in_step * 1e6:>10.1f}"
            f"{r.repeated * 1e6:>10.1f}{r.varied * 1e6:>10.1f}"
            f"{r.in_step / r.repeated:>10.2f}{r.in_step / r.varied:>10.2f}"
        )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_batch_arguments(parser, genomes=200, trials=10, seed=0)
    parser.add_argument(
        "--loop",
        action="append",
        help="a loop, as module.function (engine._drive_rows); repeatable",
    )
    parser.add_argument("--top", type=int, default=6)
    parser.add_argument("--start", type=int, default=100)
    parser.add_argument("--record", type=int, default=20)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--core", type=int, help="pin to this core (default: none)")
    args = parser.parse_args()
    for option in ("top", "record", "rounds"):
        if getattr(args, option) < 1:
            parser.error(f"--{option} must be >= 1")
    if args.start < 0:
        parser.error("--start must be >= 0")
    names, settings = batch_arguments(parser, args)
    if args.task is None:
        names = ["gate_escape"]
    core = pin_to_core(args.core)
    if core is not None:
        print(f"pinned to core {core}")
    batch = (args.genomes, args.trials, args.steps, args.seed)
    for name in names:
        try:
            rows = replay(
                name,
                *batch,
                settings,
                loops=args.loop,
                top=args.top,
                start=args.start,
                record=args.record,
                rounds=args.rounds,
            )
        except ValueError as error:
            parser.error(str(error))
        print(f"{name} ({settings.physics.model}), {args.genomes} x {args.trials}:")
        print(report(rows))


if __name__ == "__main__":
    main()
