"""A study's runs alone against runs joined in one process, side by side.

``sdbc-study run`` joins runs of a task into one engine batch per generation
(``sdbc_evolution.run.joined``); this benchmark runs a cut copy of a preset both
ways and prints what joining saves:

1. the preset (default: ``configs/study/local_kinematic.yaml``) is cut to
   ``--runs`` runs per treatment and ``--generations`` generations per task;
2. per task, ``--alternations`` times, it is run with ``--joined-runs 1`` (every
   run alone) and as ``sdbc-study run`` runs it by default (joined), each in a
   fresh process pinned to one core (``--core``; default the last), into a fresh
   study directory, with ``--workers 1``;
3. each way's CPU seconds are the child process's (``resource.getrusage``);
   per task it prints both, their ratio (median over the alternations, and the
   range), and whether every run's outputs were the same both ways (they must
   be: wall-clock columns aside, to the bit).

Usage::

    scripts/sdbc bench study [--preset FILE] [--task NAME ...] [--runs 2]
        [--generations 10] [--alternations 2] [--core N]
"""

from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from common import pin_to_core
from sdbc_evolution.run.results import TIME_COLUMNS, read_generations, read_individuals
from sdbc_evolution.study.plan import study_plan
from sdbc_evolution.study.presets import load_preset_file

ROOT = Path(__file__).resolve().parent.parent
WAYS = {"alone": ["--joined-runs", "1"], "joined": []}
"""The two ways to run a study: the extra arguments of ``sdbc-study run``."""


def cut_preset(source: Path, runs: int, generations: int, out: Path) -> Path:
    """``source`` with ``runs`` runs per treatment and ``generations`` for every
    task, written to ``out``."""
    data = yaml.safe_load(source.read_text())
    data["name"] = f"{data['name']}_cut"
    data["runs"] = runs
    data["generations"] = {task: generations for task in data["tasks"]}
    out.write_text(yaml.safe_dump(data, sort_keys=False))
    return out


def run_way(preset: Path, task: str, way: str, out: Path) -> float:
    """Runs ``task`` of ``preset`` one way into ``out``; its CPU seconds."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "sdbc_evolution.study",
            "run",
            "--preset",
            str(preset),
            "--task",
            task,
            "--out",
            str(out),
            "--workers",
            "1",
            "--quiet",
            *WAYS[way],
        ],  # fmt: skip
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    if done.returncode != 0:
        raise SystemExit(f"bench study: {way} {task} failed:\n{done.stderr[-2000:]}")
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def run_outputs(run: Path) -> dict[str, Any]:
    """A run's outputs without its wall-clock columns."""
    columns = read_generations(run)
    outputs: dict[str, Any] = {
        k: v.tobytes() for k, v in columns.items() if k not in TIME_COLUMNS
    }
    for key, value in read_individuals(run).items():
        outputs[f"individuals:{key}"] = np.asarray(value).tobytes()
    return outputs


def same_outputs(preset: Path, task: str, a: Path, b: Path) -> bool:
    """Whether every run of ``task`` has the same outputs in both directories."""
    loaded = load_preset_file(preset)
    pairs = zip(study_plan(loaded, a), study_plan(loaded, b), strict=True)
    return all(
        run_outputs(x.path) == run_outputs(y.path) for x, y in pairs if x.task == task
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--preset",
        type=Path,
        default=ROOT / "configs" / "study" / "local_kinematic.yaml",
        help="study preset to cut (default: local_kinematic)",
    )
    parser.add_argument("--task", action="append", help="a task (default: all)")
    parser.add_argument("--runs", type=int, default=2, help="runs per treatment")
    parser.add_argument("--generations", type=int, default=10)
    parser.add_argument("--alternations", type=int, default=2)
    parser.add_argument("--core", type=int, help="pin to this core (default: last)")
    args = parser.parse_args(argv)
    for name in ("runs", "generations", "alternations"):
        if getattr(args, name) < 1:
            parser.error(f"--{name} must be at least 1")
    core = pin_to_core(args.core)
    with tempfile.TemporaryDirectory(prefix="sdbc-bench-study-") as scratch:
        work = Path(scratch)
        preset = cut_preset(args.preset, args.runs, args.generations, work / "p.yaml")
        tasks = args.task or list(load_preset_file(preset).tasks)
        print(
            f"{args.preset.name} cut to {args.runs} runs per treatment and "
            f"{args.generations} generations, core {core}, "
            f"{args.alternations} alternations"
        )
        print(
            f"{'task':18} {'alone s':>8} {'joined s':>9} {'ratio':>6} range      same"
        )
        for task in tasks:
            seconds: dict[str, list[float]] = {way: [] for way in WAYS}
            same = True
            for i in range(args.alternations):
                outs = {way: work / f"{task}-{way}-{i}" for way in WAYS}
                for way, out in outs.items():
                    seconds[way].append(run_way(preset, task, way, out))
                same = same and same_outputs(
                    preset, task, outs["alone"], outs["joined"]
                )
            ratios = [
                a / j for a, j in zip(seconds["alone"], seconds["joined"], strict=True)
            ]
            print(
                f"{task:18} {statistics.median(seconds['alone']):8.1f} "
                f"{statistics.median(seconds['joined']):9.1f} "
                f"{statistics.median(ratios):6.2f} {min(ratios):.2f}-{max(ratios):.2f}"
                f"  {'yes' if same else 'NO'}"
            )
            if not same:
                return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
