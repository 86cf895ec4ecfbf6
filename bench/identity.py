"""Bit-identity of the engine's results, across a change: write, then compare.

``--write FILE`` runs fixed genomes and seeds of every registered task (or
``--task``) through :func:`sdbc_sim.run_batch` with the SDBC extractor as its
observer (the evolution's path), in two layouts: up to 500 trials per Space and 7
trials per Space. It stores every trial's fitness, task-specific characterisation,
length and raw SDBC vector, per task and layout, in one ``.npz``.

``--compare A B`` checks two such files to the bit (NaN equal to NaN of the same
bits) and names every array, task and layout that differs, with the number of
trials that differ; it exits 1 if anything differs or the files do not hold the
same tasks and layouts. It also says, as information, whether the two layouts of a
file agree with each other.

This is how an optimisation of the engine is shown not to change any result:
write a file on the code before, another on the code after, compare. ``--engine
DIR`` writes with the sources of the checkout ``DIR`` (a worktree of the commit
before) instead of this one's; a ``PYTHONPATH`` set before ``scripts/sdbc`` does
not, as the environment puts this checkout's sources first. Each file records a
digest of the engine sources that wrote it, and ``--compare`` says when both
came from the same sources: then they show nothing about a change of the code
(only, run on two machines, that the machines agree).

Run: ``scripts/sdbc bench identity --write results/before.npz`` (options:
``--engine DIR``, ``--task``, ``--genomes``, ``--trials``, ``--steps``,
``--seed``, ``--physics NAME=VALUE``), then ``scripts/sdbc bench identity
--compare A B``.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import os
import sys
from pathlib import Path

import numpy as np
from common import add_batch_arguments, batch_arguments, random_batch, source_tree
from sdbc_evolution.sdbc.characterisation import SdbcExtractor
from sdbc_sim.engine import EngineSettings, run_batch
from sdbc_sim.tasks import make_task

import sdbc_evolution
import sdbc_sim

LAYOUTS = {"space500": 500, "space7": 7}
"""Layouts written: name -> trials per Space."""
FIELDS = ("fitness", "characterisation", "length", "sdbc")
SOURCES = "engine/sources"
"""Key of the digest of the engine sources that wrote a file."""


def sources_digest() -> str:
    """sha256 over the Python sources of the loaded ``sdbc_sim`` and
    ``sdbc_evolution`` packages, with their paths inside the package."""
    digest = hashlib.sha256()
    for package in (sdbc_sim, sdbc_evolution):
        root = Path(package.__file__).parent
        for path in sorted(root.rglob("*.py")):
            digest.update(f"{package.__name__}/{path.relative_to(root)}".encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()


def with_engine(checkout: Path, argv: list[str]) -> None:
    """Runs this tool again, ``--engine`` left out of ``argv``, with the
    sources of ``checkout`` first on the path."""
    try:
        packages = source_tree(checkout)
    except ValueError as e:
        raise SystemExit(f"identity: --engine: {e}") from None
    path = os.pathsep.join([*packages, os.environ.get("PYTHONPATH", "")])
    os.execve(
        sys.executable,
        [sys.executable, __file__, *argv],
        {**os.environ, "PYTHONPATH": path},
    )


def run_task(
    name: str,
    genomes: int,
    trials: int,
    steps: int | None,
    seed: int,
    settings: EngineSettings,
) -> dict[str, np.ndarray]:
    """Every field of every layout of one task, keyed ``task/layout/field``."""
    task = make_task(name) if steps is None else make_task(name, max_steps=steps)
    g, s = random_batch(task, genomes, trials, np.random.default_rng(seed))
    out: dict[str, np.ndarray] = {}
    for layout, per_space in LAYOUTS.items():
        physics = dataclasses.replace(settings.physics, trials_per_space=per_space)
        layout_settings = dataclasses.replace(settings, physics=physics)
        extractor = SdbcExtractor(check_values=False)
        r = run_batch(task, g, s, [extractor], settings=layout_settings)
        values = {
            "fitness": r.fitness,
            "characterisation": r.characterisation,
            "length": r.length,
            "sdbc": extractor.characterisations().reshape(genomes, trials, -1),
        }
        for field, a in values.items():
            out[f"{name}/{layout}/{field}"] = np.ascontiguousarray(a)
    return out


def differing_trials(a: np.ndarray, b: np.ndarray) -> int:
    """Trials (entries of the first two axes) whose bits differ between a and b."""
    if a.shape != b.shape or a.dtype != b.dtype:
        return -1
    bits_a = a.view(np.uint8).reshape(a.shape[0], a.shape[1], -1)
    bits_b = b.view(np.uint8).reshape(b.shape[0], b.shape[1], -1)
    return int(np.count_nonzero((bits_a != bits_b).any(axis=2)))


def compare(path_a: Path, path_b: Path) -> bool:
    """Prints the comparison; True when the files agree to the bit."""
    a, b = np.load(path_a), np.load(path_b)
    keys_a, keys_b = set(a.files) - {SOURCES}, set(b.files) - {SOURCES}
    if SOURCES in a.files and SOURCES in b.files and a[SOURCES] == b[SOURCES]:
        print(
            "note: both files were written by the same engine sources, so they "
            "show nothing about a change of the code (--engine DIR writes with "
            "another checkout's)"
        )
    for path, data in ((path_a, a), (path_b, b)):
        if SOURCES not in data.files:
            print(f"  (information) {path.name}: its engine sources were not recorded")
    same = True
    for k in sorted(keys_a ^ keys_b):
        print(f"only in {path_a if k in keys_a else path_b}: {k}")
        same = False
    tasks = sorted({k.split("/")[0] for k in keys_a & keys_b})
    for task in tasks:
        for layout in LAYOUTS:
            diffs = []
            for field in FIELDS:
                key = f"{task}/{layout}/{field}"
                if key not in keys_a or key not in keys_b:
                    continue
                n = differing_trials(a[key], b[key])
                if n == -1:
                    diffs.append(
                        f"{field} shape/dtype {a[key].shape} {a[key].dtype} vs "
                        f"{b[key].shape} {b[key].dtype}"
                    )
                elif n:
                    diffs.append(f"{field} differs in {n} trials")
            n_trials = a[f"{task}/{layout}/fitness"].size
            verdict = "identical" if not diffs else "DIFFERENT: " + "; ".join(diffs)
            print(f"{task} {layout} ({n_trials} trials): {verdict}")
            same = same and not diffs
        for path, data in ((path_a, a), (path_b, b)):
            across = sum(
                differing_trials(
                    data[f"{task}/space500/{f}"], data[f"{task}/space7/{f}"]
                )
                != 0
                for f in FIELDS
            )
            if across:
                print(
                    f"  (information) {path.name}: the layouts of {task} differ in "
                    f"{across} field(s)"
                )
    print("bit-identical" if same else "NOT bit-identical")
    return same


def main() -> None:
    # No abbreviations: --engine is taken out of the arguments by its full name
    # before the tool runs again, and an abbreviation left in would run it again.
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0], allow_abbrev=False
    )
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--write", type=Path, metavar="FILE")
    mode.add_argument("--compare", type=Path, nargs=2, metavar=("A", "B"))
    parser.add_argument(
        "--engine",
        type=Path,
        metavar="DIR",
        help="write with the sources of this checkout (default: this one's)",
    )
    add_batch_arguments(parser, genomes=40, trials=3, seed=16)
    args = parser.parse_args()
    if args.engine is not None:
        if args.compare:
            parser.error("--engine writes; --compare reads files only")
        argv = sys.argv[1:]
        at = argv.index("--engine") if "--engine" in argv else None
        if at is None:  # --engine=DIR
            argv = [a for a in argv if not a.startswith("--engine=")]
        else:
            del argv[at : at + 2]
        with_engine(args.engine.resolve(), argv)
    if args.compare:
        sys.exit(0 if compare(*args.compare) else 1)
    names, settings = batch_arguments(parser, args)
    data: dict[str, np.ndarray] = {}
    for name in names:
        data.update(
            run_task(name, args.genomes, args.trials, args.steps, args.seed, settings)
        )
        print(f"{name}: {args.genomes * args.trials} trials x {len(LAYOUTS)} layouts")
    data[SOURCES] = np.array(sources_digest())
    args.write.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(args.write, **data)
    print(f"wrote {args.write} (engine sources: {Path(sdbc_sim.__file__).parents[3]})")


if __name__ == "__main__":
    main()
