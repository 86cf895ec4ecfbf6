"""Every registered task, the paper's, the package's others and any entry point's,
passes every conformance check (sdbc_evolution/conformance.py). The tasks come from
the registry, so a new task is checked without naming it here."""

from __future__ import annotations

import pytest
from sdbc_evolution.conformance import CHECKS, run_checks
from sdbc_sim.tasks import available_tasks


@pytest.mark.ros  # the live check sends every task state through sdbc_msgs
@pytest.mark.slow
@pytest.mark.parametrize("task", sorted(available_tasks()))
def test_every_registered_task_passes_every_check(task: str) -> None:
    results = run_checks(task)
    assert [r.name for r in results] == list(CHECKS)
    failed = [f"{r.name}: {r.detail}" for r in results if not r.passed]
    assert not failed, "\n".join(failed)
