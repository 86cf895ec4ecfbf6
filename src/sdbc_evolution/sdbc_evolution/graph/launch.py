"""``sdbc-graph``: the whole live graph of a task as processes, from one YAML file.

A graph file is a ROS 2 parameters file (``--params-file`` syntax: node name keys,
``ros__parameters`` below them). The launcher's own settings
(:class:`LaunchSettings`) are the parameters of the key ``sdbc_graph``, so the file
stays valid for any node's ``--params-file``. The task is named once, under ``/**``
(``task``, ``task_config``), so that every node runs the same one. The
launcher starts, each as its own process with every parameter section passed as
``--params-file``:

- the simulator (``simulator_node``);
- the controllers of the task's N robots, ``robots_per_process`` per process
  (``controller_node --robots ...``; one process per robot by default);
- the evolution node (``evolution_node``) if ``sdbc_graph.evolution`` is true;
- the recorder (``recorder``) if a bag directory is given (``--record``).

It then waits: for Ctrl-C, for a node process to exit (which stops the graph), or,
with ``--trial SEED`` (repeatable), for those trials, which it asks the simulator
for and reports, and stops. Stopping sends SIGINT to every process, gives each
``shutdown_timeout`` seconds, kills what is left, and removes the shared-memory
files that Fast DDS leaves in ``/dev/shm`` (after SIGKILL, and now and then after
a clean exit): those created since the graph started that no process uses.

Examples::

    sdbc-graph configs/ros/gate_escape.yaml
    sdbc-graph configs/ros/gate_escape.yaml --trial 7 --record bags/trial_7
    sdbc-graph configs/ros/evolution.yaml

Exit status: 0 done, 1 a node process failed or a trial was aborted, 2 bad input,
130 interrupted.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import importlib.util
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from sdbc_evolution.run.stopping import stoppable

LAUNCH_KEY = "sdbc_graph"
"""Top-level key of a graph file whose ``ros__parameters`` are the
:class:`LaunchSettings`."""
SHARED_KEY = "/**"
"""Parameter section that every node reads; it names the task."""
CONTROLLERS_KEY = "/**/controller"
"""Parameter section of every controller node (in any robot's namespace)."""
SHM_DIR = Path("/dev/shm")
"""Where Fast DDS keeps its shared-memory segments and locks."""
DDS_FILE_PREFIXES = ("fastrtps_", "sem.fastrtps_")
"""Names of the files Fast DDS creates in :data:`SHM_DIR`."""
PARAMETERS_FILE = "parameters.yaml"
"""The nodes' parameters as ``--params-file`` reads them, in the graph's work dir."""

SIMULATOR_MODULE = "sdbc_sim.nodes.simulator_node"
CONTROLLER_MODULE = "sdbc_sim.nodes.controller_node"
EVOLUTION_MODULE = "sdbc_evolution.nodes.evolution_node"
RECORDER_MODULE = "sdbc_evolution.nodes.recorder_node"
DEFAULT_RECORD_TOPICS = ("/task_state", "/markers")
"""Topics recorded when the graph file lists none, besides every robot's sensors
and command, and the evolution node's topics when it runs."""
EVOLUTION_TOPICS = ("/generation_stats", "/best_genome")
"""The evolution node's topics."""


class GraphError(ValueError):
    """A graph file or launcher option is malformed; the message names it."""


@dataclass(frozen=True)
class LaunchSettings:
    """The launcher's settings: the ``sdbc_graph`` section of a graph file.

    Attributes:
        robots_per_process: Controllers per process; 1 runs each robot's
            controller in a process of its own.
        evolution: Start the evolution node.
        record_topics: Topics the recorder writes to the bag (with ``--record``);
            empty means :data:`DEFAULT_RECORD_TOPICS` plus every robot's sensors
            and command.
        shutdown_timeout: Seconds a process gets to exit after SIGINT before it
            is killed.
        ready_timeout: Seconds to wait for the simulator (and the recorder) to
            come up before ``--trial`` requests.
        trial_timeout: Seconds to wait for the answer to one ``--trial``.
    """

    robots_per_process: int = 1
    evolution: bool = False
    record_topics: tuple[str, ...] = ()
    shutdown_timeout: float = 10.0
    ready_timeout: float = 30.0
    trial_timeout: float = 600.0

    def __post_init__(self) -> None:
        if not (
            isinstance(self.robots_per_process, int) and self.robots_per_process >= 1
        ):
            raise GraphError(
                f"sdbc_graph.robots_per_process: must be an integer >= 1, got "
                f"{self.robots_per_process!r}"
            )
        if not isinstance(self.evolution, bool):
            raise GraphError(
                f"sdbc_graph.evolution: must be true or false, got {self.evolution!r}"
            )
        topics = self.record_topics
        if isinstance(topics, str) or not all(isinstance(t, str) and t for t in topics):
            raise GraphError(
                "sdbc_graph.record_topics: must be a list of topic names, got "
                f"{topics!r}"
            )
        object.__setattr__(self, "record_topics", tuple(topics))
        for name in ("shutdown_timeout", "ready_timeout", "trial_timeout"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and 0 < value < float("inf")):
                raise GraphError(
                    f"sdbc_graph.{name}: must be a positive number, got {value!r}"
                )


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


def load_graph_file(path: str | Path) -> GraphFile:
    """Reads and checks a graph file.

    Raises:
        GraphError: Unreadable YAML, a section without ``ros__parameters``, an
            unknown ``sdbc_graph`` setting, no task under ``/**``, or a task_config
            that is not a mapping, each named.
    """
    from sdbc_sim.nodes.interface import format_task_config, parse_task_config

    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as error:
        raise GraphError(f"graph file {path}: {error}") from None
    if not isinstance(data, Mapping):
        raise GraphError(f"graph file {path}: expected a mapping of sections")
    data = dict(data)
    section = data.pop(LAUNCH_KEY, None) or {"ros__parameters": {}}
    launch = section.get("ros__parameters") if isinstance(section, Mapping) else None
    if not isinstance(launch, Mapping):
        raise GraphError(
            f"graph file {path}: '{LAUNCH_KEY}' needs a 'ros__parameters' mapping"
        )
    known = {f.name for f in dataclasses.fields(LaunchSettings)}
    unknown = sorted(set(launch) - known)
    if unknown:
        raise GraphError(
            f"graph file {path}: unknown {LAUNCH_KEY} settings {unknown}; known: "
            f"{', '.join(sorted(known))}"
        )
    settings = LaunchSettings(**launch)
    for key, section in data.items():
        if not (
            isinstance(section, Mapping)
            and isinstance(section.get("ros__parameters"), Mapping)
        ):
            raise GraphError(
                f"graph file {path}: section {key!r} needs a 'ros__parameters' mapping"
            )
    shared = dict(data.get(SHARED_KEY, {}).get("ros__parameters", {}))
    task = shared.get("task")
    if not isinstance(task, str) or not task:
        raise GraphError(
            f"graph file {path}: name the task once for every node, as "
            f"'{SHARED_KEY}: {{ros__parameters: {{task: gate_escape}}}}'"
        )
    task_config = shared.get("task_config", {})
    if isinstance(task_config, str):
        try:
            task_config = parse_task_config(task_config)
        except ValueError as error:
            raise GraphError(f"graph file {path}: {error}") from None
    if not isinstance(task_config, Mapping):
        raise GraphError(
            f"graph file {path}: '{SHARED_KEY}' task_config must be a mapping of task "
            f"settings, got {task_config!r}"
        )
    # Nodes read task_config as a string parameter.
    shared["task_config"] = format_task_config(task_config)
    data[SHARED_KEY] = {"ros__parameters": shared}
    return GraphFile(settings, data, task, dict(task_config))


@dataclass(frozen=True)
class NodeProcess:
    """One process of the graph.

    Attributes:
        name: Label in logs and messages ("simulator", "controllers 0-1").
        argv: The command line.
    """

    name: str
    argv: tuple[str, ...]


def module_command(module: str, *args: str) -> tuple[str, ...]:
    """Runs ``module`` with this interpreter (works with and without colcon's
    console scripts)."""
    return (sys.executable, "-m", module, *args)


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
    graph: GraphFile, params_file: Path, record: Path | None = None
) -> list[NodeProcess]:
    """The processes that make up ``graph``, each given ``params_file``."""
    from sdbc_sim.nodes.interface import COMMAND_TOPIC, SENSORS_TOPIC, robot_topic
    from sdbc_sim.tasks import make_task

    ros = ("--ros-args", "--params-file", str(params_file))
    try:
        n_robots = make_task(graph.task, **graph.task_config).layout.n_controlled
    except (TypeError, ValueError) as error:
        raise GraphError(f"graph file: {error}") from None
    processes = [NodeProcess("simulator", module_command(SIMULATOR_MODULE, *ros))]
    per = graph.settings.robots_per_process
    for first in range(0, n_robots, per):
        robots = [str(i) for i in range(first, min(first + per, n_robots))]
        label = robots[0] if len(robots) == 1 else f"{robots[0]}-{robots[-1]}"
        processes.append(
            NodeProcess(
                f"controller {label}",
                module_command(CONTROLLER_MODULE, "--robots", *robots, *ros),
            )
        )
    if graph.settings.evolution:
        processes.append(
            NodeProcess("evolution", module_command(EVOLUTION_MODULE, *ros))
        )
    if record is not None:
        topics = list(graph.settings.record_topics) or [
            *DEFAULT_RECORD_TOPICS,
            *(EVOLUTION_TOPICS if graph.settings.evolution else ()),
            *(
                "/" + robot_topic(i, t)
                for i in range(n_robots)
                for t in (SENSORS_TOPIC, COMMAND_TOPIC)
            ),
        ]
        processes.append(
            NodeProcess(
                "recorder",
                module_command(
                    RECORDER_MODULE, "--output", str(record), "--topics", *topics, *ros
                ),
            )
        )
    return processes


def dds_files_in_use() -> set[str]:
    """Names of the Fast DDS files in /dev/shm that some process has open or
    mapped."""
    used: set[str] = set()
    prefix = str(SHM_DIR) + "/"
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        with contextlib.suppress(OSError):
            for line in (proc / "maps").read_text().splitlines():
                at = line.find(prefix)
                if at >= 0:
                    used.add(line[at + len(prefix) :].split(" ")[0])
        with contextlib.suppress(OSError):
            for fd in (proc / "fd").iterdir():
                with contextlib.suppress(OSError):
                    target = os.readlink(fd)
                    if target.startswith(prefix):
                        used.add(target[len(prefix) :])
    return used


def remove_orphaned_dds_files(since: float) -> list[str]:
    """Removes Fast DDS shared-memory files created at or after ``since`` (a
    ``time.time()``) that no process uses any more: what processes killed with
    SIGKILL leave behind. Returns their names."""
    if not SHM_DIR.is_dir():
        return []
    candidates = []
    for path in SHM_DIR.iterdir():
        if path.name.startswith(DDS_FILE_PREFIXES):
            with contextlib.suppress(OSError):
                if path.stat().st_ctime >= since:
                    candidates.append(path)
    if not candidates:
        return []
    used = dds_files_in_use()
    removed = []
    for path in candidates:
        if path.name not in used:
            with contextlib.suppress(OSError):
                path.unlink()
                removed.append(path.name)
    return removed


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
    ) -> ProcessGraph:
        """The processes of ``graph_file``, not started yet; the nodes' parameters
        go to ``<work_dir>/parameters.yaml``, which must outlive the graph."""
        params_file = Path(work_dir) / PARAMETERS_FILE
        params_file.write_text(yaml.safe_dump(graph_file.parameters))
        return cls(
            graph_processes(graph_file, params_file, record),
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
        """Starts every process, or only ``name`` (again, after it ended)."""
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
                process.argv,
                env=self.env,
                stdout=output,
                stderr=subprocess.STDOUT if output is not None else None,
                # Ctrl-C in a terminal reaches the launcher alone; it then stops
                # the nodes in order.
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
        """Stops every process: SIGINT, then SIGKILL after ``shutdown_timeout``;
        then removes the Fast DDS files they left. Returns the exit codes."""
        for popen in self.running.values():
            if popen.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    popen.send_signal(signal.SIGINT)
        deadline = time.monotonic() + self.shutdown_timeout
        codes = {}
        for name, popen in self.running.items():
            try:
                codes[name] = popen.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                popen.kill()
                codes[name] = popen.wait()
        # Fast DDS leaves shared-memory files behind after SIGKILL, and sometimes
        # after a clean exit too (a port file that another process still mapped).
        remove_orphaned_dds_files(self._started_at)
        for log in self._logs:
            log.close()
        self._logs.clear()
        return codes

    def __enter__(self) -> ProcessGraph:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


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


def _has_genome(graph: GraphFile) -> bool:
    return any(
        "genome" in section.get("ros__parameters", {})
        for section in graph.parameters.values()
    )


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="sdbc-graph",
        description=(
            "Bring up the live ROS 2 graph of a task (simulator, one controller per "
            "robot, optionally the evolution node and a bag recorder) as processes, "
            "with parameters from a graph file; Ctrl-C stops it cleanly."
        ),
    )
    parser.add_argument("graph", type=Path, help="graph file (YAML), see configs/ros/")
    parser.add_argument(
        "--trial",
        type=int,
        action="append",
        metavar="SEED",
        help="run a trial with this seed, report it, and stop (repeatable)",
    )
    parser.add_argument(
        "--record", type=Path, metavar="BAG", help="record the graph's topics to BAG"
    )
    parser.add_argument(
        "--log-dir",
        type=Path,
        help="write each process's output to DIR/<name>.log instead of the terminal",
    )
    return parser


def _wait_until_ready(
    graph: ProcessGraph, node: Any, client: Any, record: bool, timeout: float
) -> None:
    """Waits for the simulator's service and, when recording, for the recorder
    to subscribe to the task state."""
    import rclpy
    from sdbc_sim.nodes.interface import RECORDER_NODE, TASK_STATE_TOPIC

    deadline = time.monotonic() + timeout

    def recorder_ready() -> bool:
        infos = node.get_subscriptions_info_by_topic("/" + TASK_STATE_TOPIC)
        return any(info.node_name == RECORDER_NODE for info in infos)

    while not (client.service_is_ready() and (not record or recorder_ready())):
        if dead := graph.exited():
            raise RuntimeError(f"node processes ended before the first trial: {dead}")
        if time.monotonic() > deadline:
            raise RuntimeError(
                f"the graph did not come up within {timeout:g} s (simulator service "
                f"ready: {client.service_is_ready()})"
            )
        rclpy.spin_once(node, timeout_sec=0.1)
    # Discovery is not symmetric: the simulator's writer may match the recorder's
    # reader a moment after this side sees it.
    time.sleep(0.5)


def run_trials(
    graph: ProcessGraph, seeds: Sequence[int], record: bool, settings: LaunchSettings
) -> int:
    """Asks the simulator for one trial per seed and prints each answer; 0 if all
    ran, 1 otherwise."""
    import rclpy
    from rclpy.node import Node
    from rclpy.signals import SignalHandlerOptions
    from sdbc_sim.nodes.interface import RUN_TRIAL_SERVICE

    from sdbc_msgs.srv import RunTrial

    # Ctrl-C stays a KeyboardInterrupt here: the launcher then stops the graph.
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = Node("graph_launcher")
    status = 0
    try:
        client = node.create_client(RunTrial, RUN_TRIAL_SERVICE)
        _wait_until_ready(graph, node, client, record, settings.ready_timeout)
        for seed in seeds:
            future = client.call_async(RunTrial.Request(seed=seed))
            rclpy.spin_until_future_complete(
                node, future, timeout_sec=settings.trial_timeout
            )
            answer = future.result()
            if answer is None:
                print(
                    f"trial seed {seed}: no answer within {settings.trial_timeout:g} s"
                )
                status = 1
            elif not answer.success:
                print(f"trial seed {seed}: aborted: {answer.message}")
                status = 1
            else:
                print(
                    f"trial seed {seed}: fitness {answer.fitness:.6g}, length "
                    f"{answer.length}, characterisation "
                    f"{[round(v, 6) for v in answer.characterisation]}"
                )
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return status


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    with stoppable():
        return _main(args)


def _main(args: argparse.Namespace) -> int:
    try:
        graph_file = load_graph_file(args.graph)
        if (
            args.trial
            and not graph_file.settings.evolution
            and not _has_genome(graph_file)
        ):
            raise GraphError(
                f"graph file {args.graph}: --trial needs a genome for the controllers "
                f"('{CONTROLLERS_KEY}: {{ros__parameters: {{genome: [...]}}}}')"
            )
        if args.record is not None and args.record.exists():
            raise GraphError(f"--record: {args.record} exists already; not overwriting")
        if args.trial and any(seed < 0 for seed in args.trial):
            raise GraphError(f"--trial: seeds must be non-negative, got {args.trial}")
        with tempfile.TemporaryDirectory(prefix="sdbc-graph-") as tmp:
            graph = ProcessGraph.from_graph_file(
                graph_file, Path(tmp), args.record, args.log_dir
            )
            return _run(graph, args, graph_file.settings)
    except GraphError as error:
        print(f"sdbc-graph: error: {error}", file=sys.stderr)
        return 2


def _run(
    graph: ProcessGraph, args: argparse.Namespace, settings: LaunchSettings
) -> int:
    names = ", ".join(graph.processes)
    print(f"sdbc-graph: starting {names}", file=sys.stderr)
    status = 0
    graph.start()
    try:
        if args.trial:
            status = run_trials(graph, args.trial, args.record is not None, settings)
        else:
            while not (ended := graph.exited()):
                time.sleep(0.2)
            # A node that finishes its work (the evolution node at the end of its
            # run) ends the graph; one that fails ends it with an error.
            print(f"sdbc-graph: node process ended: {ended}; stopping", file=sys.stderr)
            status = 0 if all(code == 0 for code in ended.values()) else 1
    except KeyboardInterrupt:
        status = 130
    except RuntimeError as error:
        print(f"sdbc-graph: error: {error}", file=sys.stderr)
        status = 1
    finally:
        codes = graph.stop()
    failed = {n: c for n, c in codes.items() if c not in (0, -signal.SIGINT)}
    if failed and status == 0:
        print(f"sdbc-graph: processes failed: {failed}", file=sys.stderr)
        status = 1
    if args.record is not None:
        print(f"sdbc-graph: bag in {args.record}", file=sys.stderr)
    return status


if __name__ == "__main__":
    sys.exit(main())
