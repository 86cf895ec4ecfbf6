"""The replication layer's scope: which tasks the paper ran.

The paper's claims, its relevance table (Table 1) and its run sizes apply to its
three tasks only (:mod:`sdbc_evolution.study.claims`,
:mod:`sdbc_evolution.study.relevance`, :mod:`sdbc_evolution.study.report`). Any
other task, ours or a user's, is reported on our numbers alone: what a task knows
about itself (its default generations, the SDBC dimensions that match its
task-specific characterisation) it declares on its class, not in a table here.
"""

from __future__ import annotations

PAPER_TASKS: tuple[str, ...] = ("gate_escape", "resource_sharing", "predator_prey")
"""The paper's tasks, in its order."""


def deceptive_optimum(task: str) -> float | None:
    """The fitness of ``task``'s deceptive optimum, where the task declares one
    (resource sharing: ``NO_CHARGE_OPTIMUM``, the best a team that never charges
    can score); None otherwise. The exploration's high-fitness region starts
    above it (:mod:`.exploration`): a region at or below it marks the deception,
    not the solutions."""
    if task == "resource_sharing":
        from sdbc_sim.tasks.resource_sharing import NO_CHARGE_OPTIMUM

        return float(NO_CHARGE_OPTIMUM)
    return None


def is_paper_task(task: str) -> bool:
    """Whether the paper ran ``task`` (so that its claims apply)."""
    return task in PAPER_TASKS


def paper_generations(task: str) -> int | None:
    """Generations of the paper's runs on ``task`` (None for another task): the
    paper's tasks declare them as their ``default_generations``."""
    if not is_paper_task(task):
        return None
    from sdbc_sim.tasks import resolve_task

    return resolve_task(task).default_generations


def task_title(task: str) -> str:
    """How a report names ``task``: the paper's words for its tasks, the task's
    ``name`` with spaces for any other (also one named as ``module:Class``)."""
    if task in _TITLES:
        return _TITLES[task]
    if ":" in task:
        from sdbc_sim.tasks import find_task

        task_class = find_task(task)
        if task_class is not None:
            task = task_class.name
    return task.replace("_", " ")


_TITLES = {
    "gate_escape": "gate escape",
    "resource_sharing": "resource sharing",
    "predator_prey": "predator-prey pursuit",
}
