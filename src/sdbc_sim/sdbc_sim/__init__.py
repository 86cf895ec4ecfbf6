"""sdbc_sim: a batched pymunk simulator of robot teams, the paper's tasks and two more.

Importing the package loads nothing heavy: the engine's names below are loaded on
first use (PEP 562), so ``import sdbc_sim.task_state`` (the task-state
formalism that the SDBC reads) or ``sdbc_sim.settings`` does not load pymunk, numba
or the engine.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from sdbc_sim.exports import lazy_exports

if TYPE_CHECKING:
    from sdbc_sim.engine import (
        BatchResult,
        BatchSimulation,
        EngineSettings,
        TrialStepper,
        run_batch,
    )

_LAZY = {
    "BatchResult": "sdbc_sim.engine",
    "BatchSimulation": "sdbc_sim.engine",
    "EngineSettings": "sdbc_sim.engine",
    "TrialStepper": "sdbc_sim.engine",
    "run_batch": "sdbc_sim.engine",
}
"""Exported name -> the module that defines it."""

__all__ = [
    "BatchResult",
    "BatchSimulation",
    "EngineSettings",
    "TrialStepper",
    "run_batch",
]


__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
