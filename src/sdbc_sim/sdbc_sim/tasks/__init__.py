"""The task registry, and how a task is named from anywhere.

A task is a :class:`~sdbc_sim.task.Task` subclass with ``name``, ``config_class``
and ``default_generations``. Three kinds of reference name one (:func:`resolve_task`):

- a registered name: every module of this package that defines ``TASK`` (so adding
  a task here is adding a module), and every entry point of the group
  :data:`ENTRY_POINT_GROUP` of an installed distribution, e.g. in its
  ``pyproject.toml``::

      [project.entry-points."sdbc.tasks"]
      beacon_homing = "beacon_homing.task:BeaconHoming"

- ``package.module:Class``, any importable module;
- ``path/to/file.py:Class``, a file of one's own (made absolute by
  :func:`task_reference`, so that other processes find it).

Every front end takes these: ``sdbc-evolve --task``, study presets, graph files and
the simulator, controller and evolution nodes.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import pkgutil
import sys
from collections.abc import Mapping
from functools import cache
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

from sdbc_sim.limits import MAX_STEPS, excerpt
from sdbc_sim.settings import SettingsError, is_settings, load
from sdbc_sim.task import Task

ENTRY_POINT_GROUP = "sdbc.tasks"
"""Entry point group under which installed distributions register their tasks."""

HOW_TO_REGISTER = (
    "name a task of your own as package.module:Class or path/to/file.py:Class, or "
    f"register it as an entry point of the group '{ENTRY_POINT_GROUP}' in its "
    'package\'s pyproject.toml (README, "Your own task")'
)


class UnknownTask(ValueError):
    """A task reference that names no task; the message lists the known ones."""


@cache
def package_tasks() -> dict[str, type[Task]]:
    """The tasks of this package: name -> task class."""
    found: dict[str, type[Task]] = {}
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        module = importlib.import_module(f"{__name__}.{info.name}")
        task_class = getattr(module, "TASK", None)
        if task_class is not None:
            task_class = _checked_task_class(task_class, f"{module.__name__}.TASK")
            found[task_class.name] = task_class
    return found


@cache
def available_tasks() -> dict[str, type[Task]]:
    """Registered tasks: name -> task class, this package's first, then those of
    the :data:`ENTRY_POINT_GROUP` entry points (a name taken by this package is not
    overridden).

    Raises:
        UnknownTask: An entry point that does not load a task, naming it.
    """
    found = dict(package_tasks())
    for point in sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda p: p.name):
        if point.name in found:
            continue
        try:
            loaded = point.load()
        except Exception as error:  # noqa: BLE001 - any import failure, named
            raise UnknownTask(
                f"entry point {point.name} = {point.value!r} of group "
                f"'{ENTRY_POINT_GROUP}' does not load: {type(error).__name__}: "
                f"{error}"
            ) from None
        found[point.name] = _checked_task_class(loaded, f"entry point {point.name}")
    return found


def task_reference(reference: str) -> str:
    """``reference`` as every process can read it: a ``file.py:Class`` reference
    with its file made absolute; any other reference unchanged."""
    path, separator, attribute = reference.rpartition(":")
    if separator and _is_file_reference(path):
        return f"{Path(path).expanduser().resolve()}:{attribute}"
    return reference


def is_file_reference(reference: str) -> bool:
    """Whether ``reference`` names a task by a file path (``path/file.py:Class``)."""
    path, separator, _ = reference.rpartition(":")
    return bool(separator) and _is_file_reference(path)


def _is_file_reference(path: str) -> bool:
    return path.endswith(".py") or "/" in path or "\\" in path


def resolve_task(reference: str) -> type[Task]:
    """The task class that ``reference`` names (see the module docstring).

    Raises:
        UnknownTask: Nothing by that name, a module or file that cannot be loaded,
            or something that is not a task; the message lists the registered
            tasks and how to name or register another.
    """
    if not isinstance(reference, str) or not reference:
        raise UnknownTask(
            f"a task reference must be a non-empty string, got {excerpt(reference)}"
        )
    tasks = available_tasks()
    if reference in tasks:
        return tasks[reference]
    path, separator, attribute = reference.rpartition(":")
    if not separator or not path or not attribute:
        raise UnknownTask(
            f"unknown task {reference!r}; known tasks: {', '.join(sorted(tasks))}; "
            f"{HOW_TO_REGISTER}"
        )
    if _is_file_reference(path):
        module = _module_from_file(Path(path).expanduser().resolve(), reference)
    else:
        try:
            module = importlib.import_module(path)
        except ImportError as error:
            raise UnknownTask(
                f"task {reference!r}: cannot import module {path!r} ({error}); "
                f"known tasks: {', '.join(sorted(tasks))}"
            ) from None
    if not hasattr(module, attribute):
        raise UnknownTask(f"task {reference!r}: {path} has no {attribute!r}")
    return _checked_task_class(getattr(module, attribute), f"task {reference!r}")


def find_task(reference: str) -> type[Task] | None:
    """The task class ``reference`` names, or None if it names none (a task that
    another system runs)."""
    try:
        return resolve_task(reference)
    except UnknownTask:
        return None


def _module_from_file(path: Path, reference: str) -> Any:
    """The module in file ``path``, loaded once per process under a name of its
    own (so that two files with the same name do not collide)."""
    if not path.is_file():
        raise UnknownTask(f"task {reference!r}: no file {path}")
    name = "sdbc_user_task_" + hashlib.sha256(str(path).encode()).hexdigest()[:16]
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise UnknownTask(f"task {reference!r}: cannot load {path} as Python")
    module = importlib.util.module_from_spec(spec)
    # Registered before it runs, as an import would, so that its dataclasses and
    # pickling find it.
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except Exception as error:
        del sys.modules[name]
        raise UnknownTask(
            f"task {reference!r}: {path} fails to load: {type(error).__name__}: {error}"
        ) from error
    return module


def _checked_task_class(value: Any, where: str) -> type[Task]:
    """``value`` if it is a task class that declares what a task must."""
    if not (isinstance(value, type) and issubclass(value, Task)):
        raise UnknownTask(f"{where}: {value!r} is not a subclass of sdbc_sim.task.Task")
    missing = [
        attribute
        for attribute in ("name", "config_class", "default_generations")
        if not hasattr(value, attribute)
    ]
    if missing:
        raise UnknownTask(
            f"{where}: {value.__name__} does not declare {', '.join(missing)} "
            "(see sdbc_sim/task.py, 'How to write a task')"
        )
    if not is_settings(value.config_class):
        raise UnknownTask(
            f"{where}: {value.__name__}.config_class must be a settings class made "
            "with @sdbc_sim.settings.settings"
        )
    return value


def make_task(reference: str, **overrides: Any) -> Task:
    """The task that ``reference`` names, with its default settings except
    ``overrides``.

    Raises:
        UnknownTask: For a reference that names no task.
        SettingsError: For an unknown setting or a bad value, naming it.
    """
    task_class = resolve_task(reference)
    try:
        settings = task_settings(task_class, overrides)
    except SettingsError as error:
        raise SettingsError(f"task {reference!r}: {error}", error.problems) from None
    return task_class(settings)


def task_settings(task_class: type[Task], overrides: Mapping[str, Any]) -> Any:
    """The settings of ``task_class``: its defaults except ``overrides``, checked.

    Raises:
        SettingsError: Naming each unknown setting or bad value (its paths are the
            settings' names: prefix them with where they came from), or a
            ``max_steps`` beyond :data:`sdbc_sim.limits.MAX_STEPS`.
    """
    made: Any = load(task_class.config_class, overrides)
    max_steps = getattr(made, "max_steps", None)
    if isinstance(max_steps, int) and max_steps > MAX_STEPS:
        raise SettingsError.of(
            (("max_steps", f"{max_steps} is more than MAX_STEPS={MAX_STEPS}"),)
        )
    return made
