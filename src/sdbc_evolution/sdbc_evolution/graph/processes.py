"""Supervising the node processes of a live graph.

:func:`graph_processes` turns a graph file into processes, each given every
parameter section as ``--params-file``:

- the simulator (``simulator_node``);
- the controllers of the task's N robots, ``robots_per_process`` per process
  (``controller_node --robots ...``; one process per robot by default);
- with ``graphs: K`` (K > 1), K such simulator graphs, graph k in the namespace
  ``graph_<k>``;
- the evolution node (``evolution_node``) if ``sdbc_graph.evolution`` is true,
  given the graphs' namespaces (``graph_namespaces``) when there are several;
- the recorder (``recorder``) if a bag directory is given.

With a namespace (``sdbc-graph --namespace NS``) every process is pushed into it
(``-r __ns:=/NS``), and the parameters file's relative section keys are made to
match there (:func:`~sdbc_evolution.graph.graph_file.namespaced_parameters`).
``/clock`` is absolute by ROS convention, so a namespaced graph's nodes have it
remapped to their graph's own (``/NS/clock``, ``/NS/graph_<k>/clock``; the
evolution node and the recorder follow the first graph's): two graphs with
``use_sim_time`` in one domain keep their times apart.

:class:`ProcessGraph` starts them, each under :mod:`sdbc_evolution.graph.owned`
(the node stops when the launcher dies, SIGKILL included), first removing the Fast
DDS shared-memory files that dead processes left in ``/dev/shm``; and it stops
them: SIGINT to every process, ``shutdown_timeout`` seconds for each, SIGKILL for
what is left, then the files they left are removed (:mod:`sdbc_evolution.graph.shm`).
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
import signal
import subprocess
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from sdbc_evolution.graph.graph_file import (
    GraphError,
    GraphFile,
    check_namespace,
    graph_namespaces,
    join_namespace,
    namespaced_parameters,
)
from sdbc_evolution.graph.shm import remove_orphaned_dds_files, remove_stale_dds_files

PARAMETERS_FILE = "parameters.yaml"
"""The nodes' parameters as ``--params-file`` reads them, in the graph's work dir."""

SIMULATOR_MODULE = "sdbc_sim.nodes.simulator_node"
CONTROLLER_MODULE = "sdbc_sim.nodes.controller_node"
EVOLUTION_MODULE = "sdbc_evolution.nodes.evolution_node"
RECORDER_MODULE = "sdbc_evolution.nodes.recorder_node"
OWNED_MODULE = "sdbc_evolution.graph.owned"
"""What every node process runs under: it stops the node when the launcher ends."""
STACKS_SECONDS = 1.0
"""Seconds a process that outlived the shutdown timeout gets to write its
threads' Python stacks to its output (SIGUSR1) before it is killed."""
DEFAULT_RECORD_TOPICS = ("clock", "task_state", "poses", "markers")
"""Topics of each simulator graph recorded when the graph file lists none, besides
every robot's sensors and command, and the evolution node's topics when it runs
(``clock``: the graph's ``/clock``, remapped under its namespace if it has one,
so that a player of the bag follows the trial's time)."""
EVOLUTION_TOPICS = ("generation_stats", "best_genome")
"""The evolution node's topics."""
GRAPH_NAMESPACES_PARAMETER = "graph_namespaces"
"""The evolution node's parameter naming the simulator graphs it evaluates on."""


PROGRAMS = {
    SIMULATOR_MODULE: ("sdbc_sim", "simulator_node"),
    CONTROLLER_MODULE: ("sdbc_sim", "controller_node"),
    EVOLUTION_MODULE: ("sdbc_evolution", "evolution_node"),
    RECORDER_MODULE: ("sdbc_evolution", "recorder"),
}
"""Each node program's module and its (package, executable), as colcon installs
it under ``lib/<package>`` (what a launch file's ``Node`` action names)."""


@dataclass(frozen=True)
class NodeProcess:
    """One process of the graph.

    Attributes:
        name: Label in logs and messages ("simulator", "controllers 0-1").
        module: The node program's module, run with this interpreter.
        args: Its own arguments (before ``--ros-args``).
        namespace: The namespace it is pushed into ("" for none).
        params_file: Its ``--params-file``.
        parameters: Parameter overrides after the file (``-p name:=value``,
            values as YAML).
        remaps: Name remappings (``-r from:=to``).
        stops_last: Stopped only once every other process has ended (the
            recorder: it must take what the others sent as they stopped).
    """

    name: str
    module: str
    args: tuple[str, ...] = ()
    namespace: str = ""
    params_file: Path | None = None
    parameters: tuple[tuple[str, str], ...] = ()
    remaps: tuple[tuple[str, str], ...] = ()
    stops_last: bool = False

    @property
    def program(self) -> tuple[str, str]:
        """Its (package, executable)."""
        return PROGRAMS[self.module]

    @property
    def ros_arguments(self) -> tuple[str, ...]:
        """What follows ``--ros-args``."""
        remap: tuple[str, ...] = (
            ("-r", f"__ns:=/{self.namespace}") if self.namespace else ()
        )
        remap += tuple(a for old, new in self.remaps for a in ("-r", f"{old}:={new}"))
        params = ("--params-file", str(self.params_file)) if self.params_file else ()
        overrides = tuple(a for n, v in self.parameters for a in ("-p", f"{n}:={v}"))
        return (*remap, *overrides, *params)

    @property
    def argv(self) -> tuple[str, ...]:
        """The command line, as a user would type it."""
        ros = self.ros_arguments
        return module_command(
            self.module, *self.args, *(("--ros-args", *ros) if ros else ())
        )

    def owned_argv(self, owner: int, grace: float) -> tuple[str, ...]:
        """The command line that runs it under :mod:`sdbc_evolution.graph.owned`:
        it stops when the process ``owner`` ends (SIGINT, then an exit after
        ``grace`` seconds)."""
        return (
            *module_command(OWNED_MODULE, str(owner), f"{grace:g}"),
            *self.argv[2:],
        )


def module_command(module: str, *args: str) -> tuple[str, ...]:
    """Runs ``module`` with this interpreter (works with and without colcon's
    console scripts)."""
    return (sys.executable, "-m", module, *args)


def ignores_sigint(pid: int) -> bool:
    """Whether process ``pid`` ignores SIGINT now (Linux's /proc; False where it
    cannot tell)."""
    try:
        with open(f"/proc/{pid}/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("SigIgn:"):
                    return bool(int(line.split()[1], 16) >> (signal.SIGINT - 1) & 1)
    except (OSError, ValueError):
        pass
    return False


def child_environment(base: Mapping[str, str] | None = None) -> dict[str, str]:
    """The environment of node processes: this process's (ROS 2's runtime
    settings must carry over), with the packages this process imports from on
    ``PYTHONPATH`` so that children run the same code."""
    env = dict(os.environ if base is None else base)
    roots = []
    for package in ("sdbc_sim", "sdbc_evolution", "sdbc_msgs"):
        spec = importlib.util.find_spec(package)
        if spec is not None and spec.submodule_search_locations:
            roots.append(str(Path(next(iter(spec.submodule_search_locations))).parent))
    existing = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p]
    env["PYTHONPATH"] = os.pathsep.join(dict.fromkeys(roots + existing))
    return env


def graph_processes(
    graph: GraphFile,
    params_file: Path,
    record: Path | None = None,
    namespace: str = "",
) -> list[NodeProcess]:
    """The processes that make up ``graph``, each given ``params_file``, all in
    ``namespace`` ("" for none)."""
    from sdbc_sim.nodes.interface import (
        CLOCK_TOPIC,
        COMMAND_TOPIC,
        SENSORS_TOPIC,
        robot_topic,
    )
    from sdbc_sim.tasks import make_task

    namespace = check_namespace(namespace)
    try:
        n_robots = make_task(graph.task, **graph.task_config).layout.n_controlled
    except (TypeError, ValueError) as error:
        raise GraphError(f"graph file: {error}") from None

    subgraphs = graph_namespaces(graph.settings)

    def node(
        name: str, module: str, ns: str, *args: str, clock: str = "", **more: Any
    ) -> NodeProcess:
        clock = clock or ns
        return NodeProcess(
            name,
            module,
            args,
            namespace=ns,
            params_file=params_file,
            remaps=((CLOCK_TOPIC, f"/{clock}{CLOCK_TOPIC}"),) if clock else (),
            **more,
        )

    first_clock = join_namespace(namespace, subgraphs[0])
    processes = []
    for sub in subgraphs:
        ns = join_namespace(namespace, sub)
        label = f"{sub} " if sub else ""
        processes.append(node(f"{label}simulator", SIMULATOR_MODULE, ns))
        per = graph.settings.robots_per_process
        for first in range(0, n_robots, per):
            robots = [str(i) for i in range(first, min(first + per, n_robots))]
            which = robots[0] if len(robots) == 1 else f"{robots[0]}-{robots[-1]}"
            processes.append(
                node(
                    f"{label}controller {which}",
                    CONTROLLER_MODULE,
                    ns,
                    "--robots",
                    *robots,
                )
            )
    if graph.settings.evolution:
        several = (
            ((GRAPH_NAMESPACES_PARAMETER, f"[{', '.join(subgraphs)}]"),)
            if len(subgraphs) > 1
            else ()
        )
        processes.append(
            node(
                "evolution",
                EVOLUTION_MODULE,
                namespace,
                clock=first_clock,
                parameters=several,
            )
        )
    if record is not None:
        # Resolved here, so that the bag names the topics as `ros2 topic list` does.
        topics = [
            t if t.startswith("/") else "/" + join_namespace(namespace, t)
            for t in graph.settings.record_topics
        ] or [
            "/" + join_namespace(namespace, sub, topic)
            for sub in subgraphs
            for topic in (
                *DEFAULT_RECORD_TOPICS,
                *(
                    robot_topic(i, t)
                    for i in range(n_robots)
                    for t in (SENSORS_TOPIC, COMMAND_TOPIC)
                ),
            )
        ] + [
            "/" + join_namespace(namespace, topic)
            for topic in (EVOLUTION_TOPICS if graph.settings.evolution else ())
        ]
        processes.append(
            node(
                "recorder",
                RECORDER_MODULE,
                namespace,
                "--output",
                str(record),
                "--topics",
                *topics,
                clock=first_clock,
                stops_last=True,
            )
        )
    return processes


def write_parameters(graph_file: GraphFile, path: Path, namespace: str = "") -> None:
    """Writes the nodes' parameters of ``graph_file`` to ``path`` (a
    ``--params-file``), with its section keys made to match in ``namespace``."""
    path.write_text(
        yaml.safe_dump(
            namespaced_parameters(graph_file.parameters, check_namespace(namespace))
        )
    )


class ProcessGraph:
    """Runs node processes and stops them cleanly; a context manager.

    Args:
        processes: What to run.
        shutdown_timeout: Seconds each process gets to exit after SIGINT.
        log_dir: If given, each process's output goes to ``<log_dir>/<name>.log``
            instead of this process's terminal.
        env: Environment of the processes; default :func:`child_environment`.
    """

    def __init__(
        self,
        processes: Sequence[NodeProcess],
        shutdown_timeout: float = 10.0,
        log_dir: Path | None = None,
        env: Mapping[str, str] | None = None,
    ) -> None:
        names = [p.name for p in processes]
        if len(set(names)) != len(names):
            raise GraphError(f"process names must be unique, got {names}")
        self.processes = {p.name: p for p in processes}
        self.shutdown_timeout = shutdown_timeout
        self.log_dir = log_dir
        self.env = dict(env) if env is not None else child_environment()
        self.running: dict[str, subprocess.Popen] = {}
        self._started_at = time.time()
        self._logs: list[Any] = []

    @classmethod
    def from_graph_file(
        cls,
        graph_file: GraphFile,
        work_dir: Path,
        record: Path | None = None,
        log_dir: Path | None = None,
        env: Mapping[str, str] | None = None,
        namespace: str = "",
    ) -> ProcessGraph:
        """The processes of ``graph_file`` in ``namespace``, not started yet; the
        nodes' parameters go to ``<work_dir>/parameters.yaml``, which must outlive
        the graph."""
        params_file = Path(work_dir) / PARAMETERS_FILE
        write_parameters(graph_file, params_file, namespace)
        return cls(
            graph_processes(graph_file, params_file, record, namespace),
            graph_file.settings.shutdown_timeout,
            log_dir,
            env,
        )

    def log_path(self, name: str) -> Path | None:
        """Where process ``name`` writes its output (None: the terminal)."""
        if self.log_dir is None:
            return None
        return self.log_dir / (name.replace(" ", "_") + ".log")

    def start(self, name: str | None = None) -> None:
        """Starts every process, or only ``name`` (again, after it ended); first
        removes the Fast DDS files in /dev/shm that dead processes left (a graph
        killed earlier, or one of this graph's processes killed since)."""
        remove_stale_dds_files()
        for process in (
            self.processes.values() if name is None else [self.processes[name]]
        ):
            if (
                process.name in self.running
                and self.running[process.name].poll() is None
            ):
                raise RuntimeError(f"process {process.name!r} is already running")
            output = None
            path = self.log_path(process.name)
            if path is not None:
                path.parent.mkdir(parents=True, exist_ok=True)
                output = path.open("ab")
                self._logs.append(output)
            self.running[process.name] = subprocess.Popen(
                process.owned_argv(os.getpid(), self.shutdown_timeout),
                env=self.env,
                stdout=output,
                stderr=subprocess.STDOUT if output is not None else None,
                # Ctrl-C in a terminal reaches the launcher alone; it then stops
                # the nodes in order. Should it die first, each node stops itself
                # (graph/owned.py).
                start_new_session=True,
            )

    def exited(self) -> dict[str, int]:
        """Processes that have ended, with their exit codes."""
        return {
            name: code
            for name, popen in self.running.items()
            if (code := popen.poll()) is not None
        }

    def kill(self, name: str) -> None:
        """Kills process ``name`` at once (SIGKILL), as a crash would."""
        popen = self.running[name]
        popen.kill()
        popen.wait()

    def stop(self) -> dict[str, int]:
        """Stops every process: SIGINT, then SIGKILL after ``shutdown_timeout``
        (SIGUSR1 just before, for its threads' stacks in its log),
        first the others, then those that stop last (each round with its own
        timeout); then removes the Fast DDS files they left. Returns the exit
        codes."""
        codes: dict[str, int] = {}
        for last in (False, True):
            codes.update(
                self._stop_round(
                    {
                        name: popen
                        for name, popen in self.running.items()
                        if self.processes[name].stops_last == last
                    }
                )
            )
        # Fast DDS leaves shared-memory files behind after SIGKILL, and sometimes
        # after a clean exit too (a port file that another process still mapped).
        remove_orphaned_dds_files(self._started_at)
        for log in self._logs:
            log.close()
        self._logs.clear()
        return {name: codes[name] for name in self.running}

    def _stop_round(self, popens: Mapping[str, subprocess.Popen]) -> dict[str, int]:
        deadline = time.monotonic() + self.shutdown_timeout
        # A process started from a shell's background job ignores SIGINT until
        # graph/owned.py restores it, its first step: a SIGINT before that would
        # be lost. Each gets it as soon as it hears it, none waiting on another.
        unsignalled = list(popens.values())
        while unsignalled:
            for popen in list(unsignalled):
                if popen.poll() is not None:
                    unsignalled.remove(popen)
                elif not ignores_sigint(popen.pid) or time.monotonic() >= deadline:
                    with contextlib.suppress(ProcessLookupError):
                        popen.send_signal(signal.SIGINT)
                    unsignalled.remove(popen)
            if unsignalled:
                time.sleep(0.01)
        codes = {}
        for name, popen in popens.items():
            try:
                codes[name] = popen.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                # Its threads' stacks to its log first (graph/owned.py), so that
                # where it hung can be read.
                with contextlib.suppress(ProcessLookupError):
                    popen.send_signal(signal.SIGUSR1)
                with contextlib.suppress(subprocess.TimeoutExpired):
                    popen.wait(STACKS_SECONDS)
                popen.kill()
                codes[name] = popen.wait()
        return codes

    def __enter__(self) -> ProcessGraph:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
