"""The task registry: every module of this package that defines ``TASK`` (a
:class:`~sdbc_sim.task.Task` subclass with ``name`` and ``config_class``) is a task,
so adding a task is adding a module."""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Mapping
from functools import cache
from typing import Any

from sdbc_sim.settings import SettingsError, load
from sdbc_sim.task import Task


@cache
def available_tasks() -> dict[str, type[Task]]:
    """Known tasks: name -> task class, found among this package's modules."""
    found: dict[str, type[Task]] = {}
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        module = importlib.import_module(f"{__name__}.{info.name}")
        task_class = getattr(module, "TASK", None)
        if task_class is not None:
            found[task_class.name] = task_class
    return found


def make_task(name: str, **overrides: Any) -> Task:
    """The task called ``name`` with its default settings except ``overrides``.

    Raises:
        ValueError: For an unknown task name.
        SettingsError: For an unknown setting or a bad value, naming it.
    """
    tasks = available_tasks()
    if name not in tasks:
        raise ValueError(
            f"unknown task {name!r}; known tasks: {', '.join(sorted(tasks))}"
        )
    task_class = tasks[name]
    try:
        settings = task_settings(task_class, overrides)
    except SettingsError as error:
        raise SettingsError(f"task {name!r}: {error}", error.problems) from None
    return task_class(settings)


def task_settings(task_class: type[Task], overrides: Mapping[str, Any]) -> Any:
    """The settings of ``task_class``: its defaults except ``overrides``, checked.

    Raises:
        SettingsError: Naming each unknown setting or bad value (its paths are the
            settings' names: prefix them with where they came from).
    """
    return load(task_class.config_class, overrides)
