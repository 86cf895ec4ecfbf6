"""Helpers for the task tests: one trial, the same to the bit wherever it runs."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from sdbc_sim.engine import BatchResult, EngineSettings, run_batch
from sdbc_sim.physics import PhysicsSettings
from sdbc_sim.task_state import TaskDescription, TaskState
from sdbc_sim.tasks import make_task

_ELSEWHERE = """\
import sys, numpy as np
from sdbc_sim import run_batch
from sdbc_sim.tasks import make_task
task = make_task(sys.argv[1], **eval(sys.argv[2]))
g = np.array([float.fromhex(v) for v in sys.argv[4:]])[None]
r = run_batch(task, g, np.array([[int(sys.argv[3])]]))
c = r.characterisation[0, 0]
print(r.fitness[0, 0].hex(), r.length[0, 0], *[v.hex() for v in c])
"""
"""Runs one trial in a fresh interpreter and prints its results exactly."""


class Closest:
    """Observer of the least centre distance between two present entities of the
    first group (the robots) in any active trial, relative to their radii."""

    def start(self, description: TaskDescription, n_trials: int) -> None:
        self.gap = np.inf

    def observe(self, state: TaskState) -> None:
        robots = state.groups[0]
        b = state.active.shape[0]
        n = robots.present.shape[1]
        # A leading dimension of 1 is shared by every trial.
        c = np.broadcast_to(robots.centres, (b, n, 2))[state.active]
        on = np.broadcast_to(robots.present, (b, n))[state.active]
        radii = np.broadcast_to(robots.radii, (b, n))[state.active]
        gap = np.linalg.norm(c[:, :, None] - c[:, None], axis=-1)
        gap -= radii[:, :, None] + radii[:, None]
        apart = ~(on[:, :, None] & on[:, None]) | np.eye(n, dtype=bool)
        nearest = np.where(apart, np.inf, gap).min(initial=np.inf)
        self.gap = min(self.gap, float(nearest))


def _same(a: BatchResult, g: int, t: int, b: BatchResult, h: int, u: int) -> bool:
    return bool(
        a.fitness[g, t] == b.fitness[h, u]
        and a.length[g, t] == b.length[h, u]
        and np.array_equal(a.characterisation[g, t], b.characterisation[h, u])
    )


def _same_everywhere(name: str, *, ends_apart: bool = True, **overrides: Any) -> None:
    task = make_task(name, **overrides)
    rng = np.random.default_rng(11)
    genomes = rng.uniform(-1.0, 1.0, (200, task.genome_length))
    seeds = rng.integers(0, 2**40, (200, 10))
    closest = Closest()
    batch = run_batch(task, genomes, seeds, [closest])
    # Independence only means something if robots touched and trials ended apart
    # (in a task whose trials can end early).
    assert closest.gap < 0.01
    if ends_apart:
        assert len(set(batch.length.ravel().tolist())) > 10
    for g, t in [(0, 0), (88, 4), (199, 9)]:
        alone = run_batch(task, genomes[g : g + 1], seeds[g : g + 1, t : t + 1])
        assert _same(alone, 0, 0, batch, g, t)
    # Slot 53, in the 7th Space of 8 trials, among other genomes.
    others = rng.uniform(-1.0, 1.0, (30, task.genome_length))
    mixed = np.vstack([others[:17], genomes[88:89], others[17:]])
    mixed_seeds = rng.integers(0, 2**40, (31, 3))
    mixed_seeds[17, 2] = seeds[88, 4]
    settings = EngineSettings(PhysicsSettings(trials_per_space=8))
    assert _same(
        run_batch(task, mixed, mixed_seeds, settings=settings), 17, 2, batch, 88, 4
    )
    src = Path(__file__).resolve().parents[3] / "src" / "sdbc_sim"
    args = [name, repr(overrides), str(seeds[199, 9]), *[v.hex() for v in genomes[199]]]
    out = subprocess.run(
        [sys.executable, "-c", _ELSEWHERE, *args],
        capture_output=True,
        text=True,
        check=True,
        env={"PYTHONPATH": str(src), "PATH": ""},
    ).stdout.split()
    assert float.fromhex(out[0]) == batch.fitness[199, 9]
    assert int(out[1]) == batch.length[199, 9]
    assert [float.fromhex(v) for v in out[2:]] == batch.characterisation[
        199, 9
    ].tolist()


@pytest.fixture
def same_everywhere() -> Callable[..., None]:
    """``same_everywhere(task_name, **settings)`` checks that trials of 200 random
    genomes x 10 seeds give the same results to the bit alone, in a batch of
    2000, in another slot and Space, and in another process. ``ends_apart=False``
    for a task whose every trial runs to max_steps."""
    return _same_everywhere
