"""Two versions of the engine side by side: the before/after ratio of a change.

Each alternation runs, for every task, one batch of ``--genomes`` x ``--trials``
random genomes (the same genomes and seeds for both) through :func:`run_batch`
with the SDBC extractor (``--no-sdbc`` leaves it out), once with the code of each
source tree, each in a fresh process pinned to one core, in alternating order.
A process runs the first 5 genomes first, so that what it pays once (first
calls, compiled loops loaded) stays out of the batch's time, and reports its own
CPU time for the batch, so the load on a shared machine weighs on both versions
alike. It prints, per task, the medians of robot-steps per CPU-second of each
version and the median of the per-alternation ratios new / old.

A source tree is a checkout of this repository (e.g. ``git worktree add /tmp/old
main``); only its ``src/`` is used, with this environment's packages.

Run: ``scripts/sdbc bench versions --old /tmp/old --new .`` (options: ``--task``,
``--genomes``, ``--trials``, ``--alternations``, ``--core``, ``--seed``,
``--no-sdbc``, ``--physics NAME=VALUE``, for both).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

from common import (
    add_batch_arguments,
    batch_arguments,
    physics_overrides,
    pin_to_core,
    source_tree,
)

_CHILD = """
import json, os, sys, time
import numpy as np
sys.path[:0] = sys.argv[1].split(os.pathsep)
from sdbc_evolution.sdbc.characterisation import SdbcExtractor
from sdbc_sim.engine import EngineSettings, run_batch
from sdbc_sim.physics import PhysicsSettings
from sdbc_sim.tasks import make_task
a = json.loads(sys.argv[2])
task = make_task(a["task"], **({"max_steps": a["steps"]} if a["steps"] else {}))
rng = np.random.default_rng(a["seed"])
g = rng.uniform(-1.0, 1.0, (a["genomes"], task.genome_length))
s = rng.integers(0, 2**31 - 1, (a["genomes"], a["trials"]))
settings = EngineSettings(physics=PhysicsSettings(**a["physics"]))
def observers():
    return [SdbcExtractor(check_values=False)] if a["sdbc"] else []
# A few genomes first: what a process pays once (first calls, numba imported
# and the compiled loops loaded at the first setup) stays out of the batch's
# time.
run_batch(task, g[:5], s[:5], observers(), settings=settings)
t0 = time.process_time()
r = run_batch(task, g, s, observers(), settings=settings)
cpu = time.process_time() - t0
print(json.dumps({"robot_steps": int(r.length.sum()) * task.layout.n_bodies,
                  "cpu": cpu}))
"""


def run_version(tree: Path, job: dict[str, object]) -> float:
    """Robot-steps per CPU-second of one batch with the code of ``tree``."""
    done = subprocess.run(
        [sys.executable, "-c", _CHILD, os.pathsep.join(source_tree(tree))]
        + [json.dumps(job)],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": ""},
    )
    if done.returncode != 0:
        raise SystemExit(f"{tree}: the batch failed:\n{done.stderr}")
    r = json.loads(done.stdout.strip().splitlines()[-1])
    return r["robot_steps"] / r["cpu"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", type=Path, required=True, help="source tree before")
    parser.add_argument("--new", type=Path, required=True, help="source tree after")
    add_batch_arguments(parser, genomes=200, trials=10, seed=0)
    parser.add_argument("--alternations", type=int, default=3)
    parser.add_argument("--core", type=int, help="core to pin to (default: last)")
    parser.add_argument("--no-sdbc", action="store_true", help="no SDBC extractor")
    args = parser.parse_args()
    names, _ = batch_arguments(parser, args)
    physics = physics_overrides(args.physics)
    trees = {"old": args.old.resolve(), "new": args.new.resolve()}
    for tree in trees.values():
        try:
            source_tree(tree)
        except ValueError as e:
            parser.error(str(e))
    core = pin_to_core(args.core)
    rates = {(t, v): [] for t in names for v in trees}
    for k in range(args.alternations):
        for t in names:
            job = {
                "task": t,
                "steps": args.steps,
                "seed": args.seed + k,
                "genomes": args.genomes,
                "trials": args.trials,
                "physics": physics,
                "sdbc": not args.no_sdbc,
            }
            order = list(trees) if k % 2 == 0 else list(reversed(trees))
            for v in order:
                rates[(t, v)].append(run_version(trees[v], job))
            print(
                f"alternation {k + 1} {t}: old {rates[(t, 'old')][-1]:,.0f}, new "
                f"{rates[(t, 'new')][-1]:,.0f} robot-steps/CPU-s",
                flush=True,
            )
    print(
        f"\nmedians over {args.alternations} alternations, core {core}, "
        f"{'without' if args.no_sdbc else 'with'} SDBC:"
    )
    for t in names:
        old, new = rates[(t, "old")], rates[(t, "new")]
        ratio = statistics.median(n / o for n, o in zip(new, old, strict=True))
        print(
            f"{t}: old {statistics.median(old):,.0f}, new {statistics.median(new):,.0f}"
            f" robot-steps/CPU-s, new/old {ratio:.3f}"
        )


if __name__ == "__main__":
    main()
