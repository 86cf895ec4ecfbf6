"""Pieces the speed benchmarks share: random batches, physics overrides from the
command line, pinning to one core, loading one benchmark from another, and an
attribute replaced for the length of a block (the engine's functions, wrapped in
timers)."""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import os
import sys
import types
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from sdbc_sim.engine import EngineSettings
from sdbc_sim.physics import PhysicsSettings
from sdbc_sim.task import Task
from sdbc_sim.tasks import available_tasks


def random_batch(
    task: Task, genomes: int, trials: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """(G, W) genomes uniform in [-1, 1] and (G, T) trial seeds."""
    g = rng.uniform(-1.0, 1.0, (genomes, task.genome_length))
    s = rng.integers(0, 2**31 - 1, (genomes, trials))
    return g, s


def _parse_value(text: str) -> object:
    low = text.lower()
    if low == "none":
        return None
    if low in ("true", "false"):
        return low == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def physics_overrides(pairs: list[str] | None) -> dict[str, Any]:
    """``["hash_cell=32", ...]`` as PhysicsSettings keyword arguments (typed Any:
    PhysicsSettings checks each value itself); raises ValueError naming a
    malformed pair or an unknown setting."""
    known = {f.name for f in dataclasses.fields(PhysicsSettings)}
    out: dict[str, Any] = {}
    for pair in pairs or ():
        name, sep, value = pair.partition("=")
        name = name.strip()
        if not sep or not name:
            raise ValueError(f"--physics: expected NAME=VALUE, got {pair!r}")
        if name not in known:
            names = ", ".join(sorted(known))
            raise ValueError(f"--physics: unknown setting {name!r}; known: {names}")
        out[name] = _parse_value(value.strip())
    return out


def physics_sweep(base: PhysicsSettings, spec: str) -> list[PhysicsSettings]:
    """``"NAME=V1,V2,..."`` as ``base`` with NAME set to each value in turn; raises
    ValueError naming a malformed spec, an unknown setting or a bad value."""
    name, sep, values = spec.partition("=")
    if not sep or not values:
        raise ValueError(f"--sweep: expected NAME=V1,V2,..., got {spec!r}")
    return [
        dataclasses.replace(base, **physics_overrides([f"{name}={value}"]))
        for value in values.split(",")
    ]


def engine_settings(pairs: list[str] | None) -> EngineSettings:
    """Engine settings with the given physics overrides (checked by
    PhysicsSettings itself)."""
    return EngineSettings(physics=PhysicsSettings(**physics_overrides(pairs)))


def source_tree(tree: Path) -> list[str]:
    """The package folders of ``tree``, a checkout of this project at any
    commit, to put first on a process's path so that it runs that commit's
    engine with this environment's other packages.

    Raises:
        ValueError: If ``tree`` has no ``src/sdbc_sim/sdbc_sim/engine.py``.
    """
    tree = tree.resolve()
    if not (tree / "src/sdbc_sim/sdbc_sim/engine.py").is_file():
        raise ValueError(
            f"{tree} is not a source tree of this project "
            "(no src/sdbc_sim/sdbc_sim/engine.py)"
        )
    return [str(tree / "src/sdbc_sim"), str(tree / "src/sdbc_evolution")]


def pin_to_core(core: int | None) -> int | None:
    """Pins this process (and the processes it starts later) to ``core``; None
    picks the last core this process may run on. Returns the core, or None where
    the platform cannot pin."""
    if not hasattr(os, "sched_setaffinity"):
        return None
    allowed = sorted(os.sched_getaffinity(0))
    if core is None:
        core = allowed[-1]
    if core not in allowed:
        raise ValueError(f"--core {core}: this process may run on {allowed} only")
    os.sched_setaffinity(0, {core})
    return core


def add_batch_arguments(
    parser: argparse.ArgumentParser, genomes: int, trials: int, seed: int
) -> None:
    """The options that pick the batch: --task, --genomes, --trials, --steps,
    --seed, --physics."""
    parser.add_argument("--task", action="append", help="a task (default: all)")
    parser.add_argument("--genomes", type=int, default=genomes)
    parser.add_argument("--trials", type=int, default=trials, help="trials per genome")
    parser.add_argument("--steps", type=int, help="cap on trial length (max_steps)")
    parser.add_argument("--seed", type=int, default=seed)
    parser.add_argument(
        "--physics", action="append", metavar="NAME=VALUE", help="physics setting"
    )


def batch_arguments(
    parser: argparse.ArgumentParser, args: argparse.Namespace
) -> tuple[list[str], EngineSettings]:
    """The tasks (all by default) and engine settings the options name; a bad one
    ends the program with the parser's error."""
    try:
        settings = engine_settings(args.physics)
    except ValueError as e:
        parser.error(str(e))
    known = available_tasks()
    names = args.task or sorted(known)
    unknown = sorted(set(names) - set(known))
    if unknown:
        parser.error(f"unknown task(s) {unknown}; known: {sorted(known)}")
    return names, settings


def bench_module(name: str) -> types.ModuleType:
    """``bench/<name>.py`` loaded as the module ``bench_<name>``. A plain import
    finds ``bench/profile.py`` only while bench/ comes before the standard library
    on ``sys.path``, whose ``profile`` module has the same name."""
    module_name = f"bench_{name}"
    if module_name in sys.modules:
        return sys.modules[module_name]
    path = Path(__file__).with_name(f"{name}.py")
    spec = importlib.util.spec_from_file_location(module_name, path)
    if spec is None or spec.loader is None:
        raise ImportError(f"no benchmark {name!r} at {path}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


@contextmanager
def patched(owner: Any, name: str, replacement: Any) -> Iterator[None]:
    """``owner.name`` replaced while the context lasts."""
    had_own = name in vars(owner)
    saved = vars(owner).get(name)
    setattr(owner, name, replacement)
    try:
        yield
    finally:
        if had_own:
            setattr(owner, name, saved)
        else:
            delattr(owner, name)
