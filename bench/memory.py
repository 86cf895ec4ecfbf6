"""Memory over a long run of batches: resident set size per trial, before and after
the pymunk Buffer workaround, side by side.

pymunk 7.3.1's ``pymunk.batch.Buffer`` never frees its C arrays
(``docs/upstream/pymunk-batch-buffer-leak.md``, reproducer
``bench/pymunk_buffer_leak.py``); the engine made new Buffers for every Space of
every batch, so a process that evaluates batch after batch (a pool worker, a Dask
worker) grew by a few hundred bytes per trial. ``sdbc_sim.physics`` now reuses
Buffers from free lists. This benchmark runs the same batches in two fresh
processes, one with the free lists (after) and one making a new Buffer each time
as before (before), alternating a batch of each so both see the same load, and
prints their RSS every ``--every`` batches after ``--warmup`` batches, then the
growth per trial.

Run: ``scripts/sdbc bench memory --batches 300 --every 25 --warmup 25`` (options:
``--task``, ``--genomes``, ``--trials``, ``--steps``).
"""

from __future__ import annotations

import argparse
import subprocess
import sys

WORKER = """
import gc, sys
import numpy as np
import pymunk.batch as pb
from sdbc_sim import physics
from sdbc_sim.engine import run_batch
from sdbc_sim.tasks import make_task

task_name, genomes_n, trials, steps, before = sys.argv[1:6]
if before == "1":
    physics._buffer = lambda kind: pb.Buffer()  # the engine before the workaround
task = make_task(task_name, max_steps=int(steps))
rng = np.random.default_rng(0)
genomes = rng.uniform(-1, 1, (int(genomes_n), task.genome_length))

def rss():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096

for line in sys.stdin:
    seeds = rng.integers(0, 2**62, (int(genomes_n), int(trials)), dtype=np.int64)
    run_batch(task, genomes, seeds)
    gc.collect()
    print(rss(), flush=True)
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--task", default="gate_escape")
    parser.add_argument("--genomes", type=int, default=20)
    parser.add_argument("--trials", type=int, default=10)
    parser.add_argument("--steps", type=int, default=50)
    parser.add_argument("--batches", type=int, default=300)
    parser.add_argument("--every", type=int, default=25)
    parser.add_argument("--warmup", type=int, default=25)
    args = parser.parse_args()
    trials = args.genomes * args.trials
    workers = {
        name: subprocess.Popen(
            [sys.executable, "-c", WORKER, args.task, str(args.genomes),
             str(args.trials), str(args.steps), flag],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
        )
        for name, flag in (("before", "1"), ("after", "0"))
    }  # fmt: skip
    print(
        f"{args.task}: {args.batches} batches of {trials} trials ({args.steps} "
        f"steps), RSS in MiB after {args.warmup} warm-up batches"
    )
    print(f"{'batch':>7} {'before':>10} {'after':>10}")
    start: dict[str, int] = {}
    last: dict[str, int] = {}
    for batch in range(1, args.warmup + args.batches + 1):
        for name, worker in workers.items():
            assert worker.stdin is not None and worker.stdout is not None
            worker.stdin.write("\n")
            worker.stdin.flush()
            last[name] = int(worker.stdout.readline())
        if batch == args.warmup:
            start = dict(last)
        done = batch - args.warmup
        if done > 0 and done % args.every == 0:
            mib = {name: rss / 2**20 for name, rss in last.items()}
            print(f"{done:7d} {mib['before']:10.2f} {mib['after']:10.2f}")
    for worker in workers.values():
        assert worker.stdin is not None
        worker.stdin.close()
        worker.wait()
    per_trial = {
        name: (last[name] - start[name]) / (args.batches * trials) for name in workers
    }
    print(
        f"growth per trial: before {per_trial['before']:.1f} bytes, after "
        f"{per_trial['after']:.1f} bytes"
    )


if __name__ == "__main__":
    main()
