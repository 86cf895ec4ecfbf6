"""sdbc_sim: a batched pymunk simulator of robot teams and the paper's three tasks."""

from sdbc_sim.engine import (
    BatchResult,
    BatchSimulation,
    EngineSettings,
    TrialStepper,
    run_batch,
)

__all__ = [
    "BatchResult",
    "BatchSimulation",
    "EngineSettings",
    "TrialStepper",
    "run_batch",
]
