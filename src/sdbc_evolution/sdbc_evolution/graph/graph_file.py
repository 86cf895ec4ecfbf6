"""Graph files: the whole live graph of a task in one YAML file.

A graph file is a ROS 2 parameters file (``--params-file`` syntax: node name keys,
``ros__parameters`` below them). The launcher's own settings
(:class:`LaunchSettings`) are the parameters of the key ``sdbc_graph``, so the file
stays valid for any node's ``--params-file``. The task is named once, under ``/**``
(``task``, ``task_config``), so that every node runs the same one.
:func:`trial_graph` writes the contents of one for a single genome.

Section keys are node names as rcl matches them: ``simulator`` means the node
``/simulator`` only, so a graph pushed into a namespace needs its relative keys
made absolute (:func:`namespaced_parameters`); ``/**`` and ``/**/controller``
match under any namespace as they are.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Annotated, Any

from sdbc_sim.limits import excerpt
from sdbc_sim.settings import (
    Field,
    PositiveFloat,
    PositiveInt,
    SettingsError,
    load,
    settings,
)
from sdbc_sim.yaml_input import YamlRefused, read_yaml

LAUNCH_KEY = "sdbc_graph"
"""Top-level key of a graph file whose ``ros__parameters`` are the
:class:`LaunchSettings`."""
SHARED_KEY = "/**"
"""Parameter section that every node reads; it names the task."""
CONTROLLERS_KEY = "/**/controller"
"""Parameter section of every controller node (in any robot's namespace)."""
GRAPH_NAMESPACE_PREFIX = "graph_"
"""With ``graphs: N`` (N > 1), graph k's simulator and controllers live in the
namespace ``graph_<k>`` (under the launcher's ``--namespace``, if any)."""
_NAME_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


class GraphError(SettingsError):
    """A graph file or launcher option is malformed; the message names it."""


@settings
class LaunchSettings:
    """The launcher's settings: the ``sdbc_graph`` section of a graph file."""

    robots_per_process: PositiveInt = 1
    """Controllers per process; 1 runs each robot's controller in a process of its
    own."""
    evolution: bool = False
    """Start the evolution node."""
    record_topics: tuple[Annotated[str, Field(min_length=1)], ...] = ()
    """Topics the recorder writes to the bag (with ``--record``); empty means
    :data:`~sdbc_evolution.graph.processes.DEFAULT_RECORD_TOPICS` plus every
    robot's sensors and command."""
    shutdown_timeout: PositiveFloat = 10.0
    """Seconds a process gets to exit after SIGINT before it is killed."""
    ready_timeout: PositiveFloat = 30.0
    """Seconds to wait for the simulator (and the recorder) to come up before
    ``--trial`` requests."""
    trial_timeout: PositiveFloat = 600.0
    """Seconds to wait for the answer to one ``--trial``."""
    graphs: PositiveInt = 1
    """Simulator graphs (a simulator and its controllers each) to start; with more
    than one, graph k runs in the namespace ``graph_<k>`` and the evolution node
    spreads each generation's trials over them (its ``graph_namespaces``)."""


@dataclass(frozen=True)
class GraphFile:
    """A parsed graph file.

    Attributes:
        settings: The ``sdbc_graph`` section.
        parameters: Every other section, as a ROS 2 parameters file holds them.
        task: The task name, from ``/**``.
        task_config: The task's setting overrides, from ``/**``.
    """

    settings: LaunchSettings
    parameters: dict[str, Any]
    task: str
    task_config: dict[str, Any] = field(default_factory=dict)

    def section(self, key: str) -> dict[str, Any]:
        """The ``ros__parameters`` of section ``key`` (empty if absent)."""
        return dict(self.parameters.get(key, {}).get("ros__parameters", {}))


def load_graph_file(
    path: str | Path,
    task: str | None = None,
    task_config: str | None = None,
    launch: Mapping[str, Any] | None = None,
) -> GraphFile:
    """Reads and checks a graph file.

    Args:
        path: The file.
        task, task_config: Replace the file's (under ``/**``), as a launch
            file's arguments do.
        launch: :class:`LaunchSettings` values that replace the file's.

    Raises:
        GraphError: Unreadable YAML, a section without ``ros__parameters``, an
            unknown ``sdbc_graph`` setting, no task under ``/**``, or a task_config
            that is not a mapping, each named.
    """
    from sdbc_sim.nodes.interface import format_task_config, parse_task_config
    from sdbc_sim.tasks import task_reference

    path = Path(path)
    try:
        data = read_yaml(path, "graph file")
    except YamlRefused as error:
        raise GraphError(str(error)) from None
    if not isinstance(data, Mapping):
        raise GraphError(f"graph file {path}: expected a mapping of sections")
    data = dict(data)
    section = data.pop(LAUNCH_KEY, None) or {"ros__parameters": {}}
    given = section.get("ros__parameters") if isinstance(section, Mapping) else None
    if not isinstance(given, Mapping):
        raise GraphError(
            f"graph file {path}: '{LAUNCH_KEY}' needs a 'ros__parameters' mapping"
        )
    try:
        settings = load(LaunchSettings, {**given, **(launch or {})}, LAUNCH_KEY)
    except SettingsError as error:
        raise GraphError(f"graph file {path}: {error}", error.problems) from None
    for key, section in data.items():
        if not (
            isinstance(section, Mapping)
            and isinstance(section.get("ros__parameters"), Mapping)
        ):
            raise GraphError(
                f"graph file {path}: section {key!r} needs a 'ros__parameters' mapping"
            )
    shared = dict(data.get(SHARED_KEY, {}).get("ros__parameters", {}))
    if task is not None:
        shared["task"] = task
    if task_config is not None:
        shared["task_config"] = task_config
    task = shared.get("task")
    if not isinstance(task, str) or not task:
        raise GraphError(
            f"graph file {path}: name the task once for every node, as "
            f"'{SHARED_KEY}: {{ros__parameters: {{task: gate_escape}}}}'"
        )
    # A task in a file of one's own, by its absolute path: every node finds it.
    task = shared["task"] = task_reference(task)
    config = shared.get("task_config", {})
    if isinstance(config, str):
        try:
            config = parse_task_config(config)
        except ValueError as error:
            raise GraphError(f"graph file {path}: {error}") from None
    if not isinstance(config, Mapping):
        raise GraphError(
            f"graph file {path}: '{SHARED_KEY}' task_config must be a mapping of task "
            f"settings, got {excerpt(config)}"
        )
    # Nodes read task_config as a string parameter.
    shared["task_config"] = format_task_config(config)
    data[SHARED_KEY] = {"ros__parameters": shared}
    return GraphFile(settings, data, task, dict(config))


def trial_graph(
    task: str,
    genome: Sequence[float],
    task_config: Mapping[str, Any] | None = None,
    launcher: Mapping[str, Any] | None = None,
    nodes: Mapping[str, Mapping[str, Any]] | None = None,
) -> dict[str, Any]:
    """The contents of a graph file that runs ``task`` with every controller on
    ``genome`` (what ``sdbc-graph --trial`` needs), to be dumped as YAML.

    Args:
        task: Task name.
        genome: The controllers' network weights.
        task_config: The task's settings.
        launcher: :class:`LaunchSettings` values (the ``sdbc_graph`` section).
        nodes: More parameters by node name, e.g. ``{"simulator": {...}}``.
    """
    return {
        LAUNCH_KEY: {"ros__parameters": dict(launcher or {})},
        SHARED_KEY: {
            "ros__parameters": {"task": task, "task_config": dict(task_config or {})}
        },
        **{name: {"ros__parameters": dict(p)} for name, p in (nodes or {}).items()},
        CONTROLLERS_KEY: {"ros__parameters": {"genome": [float(w) for w in genome]}},
    }


def with_parameters(
    graph: GraphFile, section: str, values: Mapping[str, Any]
) -> GraphFile:
    """``graph`` with ``values`` set in the ``ros__parameters`` of ``section``
    (made if absent); ``section`` :data:`SHARED_KEY` sets them in every section,
    so that they win over a node's own value as they would with ``-p``."""
    parameters = {key: dict(value) for key, value in graph.parameters.items()}
    keys = {section, *parameters} if section == SHARED_KEY else {section}
    for key in keys:
        parameters.setdefault(key, {})
        parameters[key] = {
            **parameters[key],
            "ros__parameters": {
                **parameters[key].get("ros__parameters", {}),
                **values,
            },
        }
    return replace(graph, parameters=parameters)


def has_genome(graph: GraphFile) -> bool:
    """Whether some section of ``graph`` gives the controllers a genome."""
    return any(
        "genome" in section.get("ros__parameters", {})
        for section in graph.parameters.values()
    )


def check_namespace(namespace: str) -> str:
    """``namespace`` without its leading and trailing slashes, checked as ROS 2
    names are (tokens of letters, digits and underscores, not starting with a
    digit, joined by ``/``); "" for none.

    Raises:
        GraphError: Naming the bad namespace.
    """
    stripped = namespace.strip("/")
    if stripped and not all(_NAME_TOKEN.match(t) for t in stripped.split("/")):
        raise GraphError(
            f"namespace {namespace!r}: a ROS 2 namespace is tokens of letters, "
            "digits and underscores (not starting with a digit) joined by '/'"
        )
    return stripped


def join_namespace(*parts: str) -> str:
    """The namespaces ``parts`` joined, without a leading slash ("" for none)."""
    return "/".join(p.strip("/") for p in parts if p.strip("/"))


def graph_namespaces(settings: LaunchSettings) -> tuple[str, ...]:
    """The namespaces of the simulator graphs, relative to the launcher's own:
    ("",) for one graph, ``graph_0``, ``graph_1``, ... for several."""
    if settings.graphs == 1:
        return ("",)
    return tuple(f"{GRAPH_NAMESPACE_PREFIX}{k}" for k in range(settings.graphs))


def namespaced_parameters(
    parameters: Mapping[str, Any], namespace: str
) -> dict[str, Any]:
    """``parameters`` (sections by node name) for nodes in ``namespace`` or in a
    graph's namespace below it: a relative key such as ``simulator`` becomes
    ``/<namespace>/**/simulator`` (``/**/simulator`` without a namespace); keys
    that start with ``/`` (``/**``, ``/**/controller``, absolute names) are kept
    as written."""
    prefix = f"/{namespace.strip('/')}" if namespace.strip("/") else ""
    return {
        (key if key.startswith("/") else f"{prefix}/**/{key}"): value
        for key, value in parameters.items()
    }
