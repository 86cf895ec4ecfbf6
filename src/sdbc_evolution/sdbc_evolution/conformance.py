"""Conformance: the checks every task must pass, the paper's and a user's alike.

``sdbc-conformance REFERENCE`` (or ``scripts/sdbc conformance REFERENCE``) runs them
on one task, named as anything :func:`sdbc_sim.tasks.resolve_task` takes::

    sdbc-conformance gate_escape
    sdbc-conformance my_pkg.tasks:MyTask --task-config '{max_steps: 300}'
    sdbc-conformance path/to/my_task.py:MyTask --check batch --check live

The checks, in order (:data:`CHECKS`):

- ``declaration``: the task class declares what a task must (``name``,
  ``config_class`` made with ``@settings`` with a docstring per field,
  ``default_generations``), and the built task is consistent: a description named
  after the task, controlled robots, a network, ``max_steps``, one name per
  characterisation dimension, and ``sdbc_counterparts`` naming its own
  characterisation dimensions and real SDBC dimensions;
- ``task_state``: at every step of a batch, the task state fits the description
  (shapes and dtypes, leading dimension of 1 or one row per trial), every present
  entity has finite attributes and geometry and a positive radius, every group's
  size of an active trial lies in [min_size, max_size], and static groups do not
  move;
- ``ranges``: fitness lies in the task's ``fitness_range`` ([0, 1] unless it
  declares another), every task-specific characterisation value in [0, 1], and
  the characterisation has one value per name;
- ``batch``: a trial gives the same fitness, characterisation, length and SDBC
  vector to the bit alone and within a batch of other genomes and seeds;
- ``process``: and in a fresh Python process;
- ``live``: stepped one step at a time from outside (the live graph's
  :class:`~sdbc_sim.engine.TrialStepper`, the controllers' network arithmetic),
  with every task state sent through an ``sdbc_msgs/TaskState`` message
  (serialised and read back as a subscriber would) into the message-path SDBC,
  a trial equals the batch run without observers to the bit, and its SDBC vector
  the batch's (to 1e-9);
- ``settings``: bad task settings are refused naming the setting: a value of the
  wrong type for every setting, NaN for every number, and an unknown key.

``sdbc-conformance --live TASK`` checks a running simulator instead, through ROS 2,
against the contract of evolution through another simulator (docs/ros2.md): the
graph's nodes and parameters, genomes, every step of a few trials' task state,
and the answers' ranges (:mod:`sdbc_evolution.graph.conformance`)::

    sdbc-conformance --live point_chase --robots 2 --genome-length 6
    sdbc-conformance --live gate_escape --namespace graph_0

A live check that fails stops the ones after it, which need what it checks.

Exit status: 0 every check passed, 1 some check failed, 2 bad input (or, with
``--live``, no rclpy or sdbc_msgs: ``scripts/sdbc setup`` brings them).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import subprocess
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
from sdbc_sim.engine import BatchResult, TrialStepper, run_batch
from sdbc_sim.limits import excerpt
from sdbc_sim.network import forward
from sdbc_sim.settings import SettingsError, field_docs, is_settings
from sdbc_sim.task import Task
from sdbc_sim.task_state import (
    Geometry,
    TaskDescription,
    TaskState,
    validate_task_state,
)
from sdbc_sim.tasks import UnknownTask, make_task, resolve_task, task_reference

from sdbc_evolution.sdbc.characterisation import SdbcExtractor, dimension_names

if TYPE_CHECKING:
    from sdbc_evolution.graph.conformance import LiveTarget

GENOMES = 4
"""Random genomes of the checks' batch."""
TRIALS = 3
"""Trials of each genome."""
LIVE_TRIALS = 2
"""Trials stepped live (one at a time, through messages)."""
MESSAGE_TOLERANCE = 1e-9
"""Largest difference allowed between the message-path and the batch SDBC vector
(the two sum the same numbers in a different order)."""


class CheckFailed(AssertionError):
    """A conformance check that does not hold; the message says what and where."""


@dataclass
class Subject:
    """The task under check, with the batch every check shares (built lazily).

    Attributes:
        reference: How the task is named (:func:`sdbc_sim.tasks.resolve_task`).
        task_config: Its settings that differ from the defaults.
        genomes: (G, W) random genomes.
        seeds: (G, T) trial seeds.
    """

    reference: str
    task_config: Mapping[str, Any] = field(default_factory=dict)
    seed: int = 0
    n_genomes: int = GENOMES
    n_trials: int = TRIALS
    _task: Task | None = None
    _plain: BatchResult | None = None
    _observed: tuple[BatchResult, np.ndarray] | None = None

    @property
    def task(self) -> Task:
        """The task, built once from the reference and its settings."""
        if self._task is None:
            self._task = make_task(self.reference, **dict(self.task_config))
        return self._task

    @property
    def genomes(self) -> np.ndarray:
        """(G, W) random genomes in [-1, 1], a function of ``seed``."""
        rng = np.random.default_rng(self.seed)
        return rng.uniform(-1.0, 1.0, (self.n_genomes, self.task.genome_length))

    @property
    def seeds(self) -> np.ndarray:
        """(G, T) trial seeds, a function of ``seed``."""
        rng = np.random.default_rng(self.seed + 1)
        return rng.integers(0, 2**40, (self.n_genomes, self.n_trials))

    def plain(self) -> BatchResult:
        """The batch run without observers (as evolution without the SDBC)."""
        if self._plain is None:
            self._plain = run_batch(self.task, self.genomes, self.seeds)
        return self._plain

    def observed(self) -> tuple[BatchResult, np.ndarray]:
        """The batch run with the SDBC extractor: (results, (G T, D) vectors)."""
        if self._observed is None:
            extractor = SdbcExtractor()
            result = run_batch(self.task, self.genomes, self.seeds, [extractor])
            self._observed = (result, extractor.characterisations())
        return self._observed


@dataclass(frozen=True)
class CheckResult:
    """The outcome of one check.

    Attributes:
        name: The check's name.
        passed: Whether it held.
        detail: What was checked (passed) or what failed, in a sentence.
        seconds: Wall time of the check.
    """

    name: str
    passed: bool
    detail: str
    seconds: float


def _fail(message: str) -> None:
    raise CheckFailed(message)


def check_declaration(subject: Subject) -> str:
    """The ``declaration`` check (module docstring); a summary of what passed."""
    task_class = resolve_task(subject.reference)  # checks name, settings class, ...
    docs = field_docs(task_class.config_class)
    undocumented = sorted(name for name, doc in docs.items() if not doc.strip())
    if undocumented:
        _fail(f"settings without a docstring: {', '.join(undocumented)}")
    generations = task_class.default_generations
    if isinstance(generations, bool) or not isinstance(generations, int):
        _fail(f"default_generations must be an integer, got {excerpt(generations)}")
    if generations < 1:
        _fail(f"default_generations must be at least 1, got {generations}")
    task = subject.task
    if not isinstance(task.description, TaskDescription):
        _fail("description is not a TaskDescription")
    if task.description.name != task_class.name:
        _fail(
            f"the description is named {task.description.name!r}, the task "
            f"{task_class.name!r}"
        )
    if task.layout.n_controlled < 1:
        _fail("no robot is controlled by the network")
    if task.genome_length < 1:
        _fail("the network has no weights")
    if isinstance(task.max_steps, bool) or not isinstance(task.max_steps, int):
        _fail(f"max_steps must be an integer, got {excerpt(task.max_steps)}")
    if task.max_steps < 1:
        _fail(f"max_steps must be at least 1, got {task.max_steps}")
    names = task.characterisation_names
    if not names or len(set(names)) != len(names):
        _fail(f"characterisation_names must be distinct and not empty: {names!r}")
    sdbc = set(dimension_names(task.description))
    counterparts = dict(task_class.sdbc_counterparts)
    for feature, dimensions in counterparts.items():
        if feature not in names:
            _fail(
                f"sdbc_counterparts: {feature!r} is not a characterisation dimension "
                f"({', '.join(names)})"
            )
        unknown = sorted(set(dimensions) - sdbc)
        if unknown:
            _fail(
                f"sdbc_counterparts[{feature!r}]: {unknown} are not SDBC dimensions "
                "of the task"
            )
    return (
        f"{task_class.name}: {len(docs)} documented settings, "
        f"{task.layout.n_controlled} robots, {task.genome_length} weights, "
        f"{len(names)} characterisation dimensions, {len(sdbc)} SDBC dimensions, "
        f"{len(counterparts)} with counterparts"
    )


class _StateChecker:
    """An observer that checks every task state against the description."""

    def start(self, description: TaskDescription, n_trials: int) -> None:
        self.description = description
        self.n_trials = n_trials
        self.steps = 0
        self.static: dict[int, tuple[np.ndarray, ...]] = {}

    def observe(self, state: TaskState) -> None:
        d = self.description
        validate_task_state(d, state, self.n_trials)
        self.steps += 1
        if state.step != self.steps:
            _fail(f"step {state.step} follows step {self.steps - 1}")
        active = state.active
        for g, (spec, group) in enumerate(zip(d.groups, state.groups, strict=True)):
            where = f"step {state.step}, group {spec.name!r}"
            b, s = self.n_trials, spec.max_size
            present = np.broadcast_to(group.present, (b, s)) & active[:, None]
            sizes = present.sum(axis=1)[active]
            if sizes.size and (
                sizes.min() < spec.min_size or sizes.max() > spec.max_size
            ):
                _fail(
                    f"{where}: {int(sizes.min())} to {int(sizes.max())} entities, "
                    f"the description allows {spec.min_size} to {spec.max_size}"
                )
            a = np.broadcast_to(group.attributes, (b, s, len(spec.attributes)))
            if not np.isfinite(a[present]).all():
                _fail(f"{where}: a present entity has a non-finite attribute")
            shapes = self._shapes(spec.geometry, group, b, s)
            for label, array in shapes.items():
                if not np.isfinite(array[present]).all():
                    _fail(f"{where}: a present entity has non-finite {label}")
            if "radii" in shapes and not (shapes["radii"][present] > 0).all():
                _fail(f"{where}: a present entity has a radius <= 0")
            if spec.static:
                self._same_as_before(g, where, present, shapes)

    @staticmethod
    def _shapes(geometry: Geometry, group: Any, b: int, s: int) -> dict[str, Any]:
        if geometry is Geometry.POLYGON:
            seg = group.segments
            return {"segments": np.broadcast_to(seg, (b, s, *seg.shape[2:]))}
        shapes = {"centres": np.broadcast_to(group.centres, (b, s, 2))}
        if geometry is Geometry.CIRCLE:
            shapes["radii"] = np.broadcast_to(group.radii, (b, s))
        return shapes

    def _same_as_before(
        self, g: int, where: str, present: np.ndarray, shapes: dict[str, Any]
    ) -> None:
        """A static group's entities never move: where present at two steps, an
        entity slot has the same geometry."""
        current = (present.copy(), *(np.array(a) for a in shapes.values()))
        before = self.static.get(g)
        self.static[g] = current
        if before is None:
            return
        both = before[0] & present
        for old, new in zip(before[1:], current[1:], strict=True):
            if not np.array_equal(old[both], new[both]):
                _fail(f"{where}: the group is static but an entity moved")


def check_task_state(subject: Subject) -> str:
    """The ``task_state`` check (module docstring); a summary of what passed."""
    checker = _StateChecker()
    run_batch(subject.task, subject.genomes, subject.seeds, [checker])
    return (
        f"{checker.steps} steps of {checker.n_trials} trials, "
        f"{len(subject.task.description.groups)} groups"
    )


def check_ranges(subject: Subject) -> str:
    """The ``ranges`` check (module docstring); a summary of what passed."""
    result = subject.plain()
    task = subject.task
    c = result.characterisation
    if c.shape[-1] != task.characterisation_size:
        _fail(
            f"the characterisation has {c.shape[-1]} values, "
            f"characterisation_names {task.characterisation_size}"
        )
    ranges = (
        ("fitness", result.fitness, task.fitness_range),
        ("characterisation", c, (0.0, 1.0)),
    )
    for label, values, (low, high) in ranges:
        bad = ~(np.isfinite(values) & (values >= low) & (values <= high))
        if bad.any():
            where = tuple(int(i) for i in np.argwhere(bad)[0])
            value = float(values[where])
            dimension = (
                f" ({task.characterisation_names[where[-1]]!r})"
                if label == "characterisation"
                else ""
            )
            bounds = f"[{low:g}, {high:g}]"
            _fail(f"{label}{dimension} {value!r} outside {bounds} at {where}")
    lengths = result.length
    if lengths.min() < 1 or lengths.max() > task.max_steps:
        _fail(f"trial lengths {lengths.min()}-{lengths.max()} outside [1, max_steps]")
    return (
        f"{result.fitness.size} trials: fitness {result.fitness.min():.3g}-"
        f"{result.fitness.max():.3g}, {c.shape[-1]} characterisation values"
    )


def _picks(subject: Subject) -> list[tuple[int, int]]:
    g, t = subject.n_genomes, subject.n_trials
    return sorted({(0, 0), (g // 2, t - 1), (g - 1, t // 2)})


def _differ(
    a: tuple[float, np.ndarray, int], b: tuple[float, np.ndarray, int]
) -> str | None:
    for label, x, y in zip(
        ("fitness", "characterisation", "length"), a, b, strict=True
    ):
        if not np.array_equal(np.asarray(x), np.asarray(y)):
            return f"{label} {x!r} != {y!r}"
    return None


def _trial(result: BatchResult, g: int, t: int) -> tuple[float, np.ndarray, int]:
    return (
        float(result.fitness[g, t]),
        result.characterisation[g, t],
        int(result.length[g, t]),
    )


def check_batch(subject: Subject) -> str:
    """The ``batch`` check (module docstring); a summary of what passed."""
    batch, vectors = subject.observed()
    for g, t in _picks(subject):
        extractor = SdbcExtractor()
        alone = run_batch(
            subject.task,
            subject.genomes[g : g + 1],
            subject.seeds[g : g + 1, t : t + 1],
            [extractor],
        )
        difference = _differ(_trial(alone, 0, 0), _trial(batch, g, t))
        if difference:
            _fail(f"genome {g}, trial {t}: alone and in the batch, {difference}")
        b = g * subject.n_trials + t
        if not np.array_equal(extractor.characterisations()[0], vectors[b]):
            _fail(f"genome {g}, trial {t}: the SDBC vector differs alone")
    return f"{len(_picks(subject))} trials alone equal the batch of {vectors.shape[0]}"


_ELSEWHERE = """\
import sys, numpy as np
from sdbc_sim.engine import run_batch
from sdbc_sim.tasks import make_task
from sdbc_sim.tasks import parse_task_config
task = make_task(sys.argv[1], **parse_task_config(sys.argv[2]))
g = np.array([float.fromhex(v) for v in sys.argv[4:]])[None]
r = run_batch(task, g, np.array([[int(sys.argv[3])]]))
c = r.characterisation[0, 0]
print(r.fitness[0, 0].hex(), r.length[0, 0], *[v.hex() for v in c])
"""
"""One trial in a fresh interpreter; prints its results exactly."""


def check_process(subject: Subject) -> str:
    """The ``process`` check (module docstring); a summary of what passed."""
    from sdbc_sim.tasks import format_task_config

    g, t = _picks(subject)[-1]
    args = [
        subject.reference,
        format_task_config(dict(subject.task_config)),
        str(int(subject.seeds[g, t])),
        *[float(w).hex() for w in subject.genomes[g]],
    ]
    done = subprocess.run(
        [sys.executable, "-c", _ELSEWHERE, *args],
        capture_output=True,
        text=True,
        env=dict(os.environ),
    )
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or ["no output"])[-1]
        _fail(f"the task does not run in another process: {last}")
    out = done.stdout.split()
    there = (float.fromhex(out[0]), np.array([float.fromhex(v) for v in out[2:]]))
    difference = _differ((*there, int(out[1])), _trial(subject.plain(), g, t))
    if difference:
        _fail(f"genome {g}, trial {t}: in another process, {difference}")
    return f"genome {g}, trial {t} equals the batch in process {os.getpid()}'s child"


def check_live(subject: Subject) -> str:
    """The ``live`` check (module docstring); a summary of what passed."""
    try:
        from rclpy.serialization import deserialize_message, serialize_message
        from sdbc_sim.task_state_msgs import task_state_to_msg

        from sdbc_evolution.sdbc.messages import MessageSdbcExtractor
        from sdbc_msgs.msg import TaskState as TaskStateMsg
    except ImportError as error:
        _fail(
            f"needs ROS 2 and the built sdbc_msgs ({error}): run it through "
            "scripts/sdbc"
        )
    task, plain = subject.task, subject.plain()
    _, vectors = subject.observed()
    name = type(task).name
    picks = _picks(subject)[:LIVE_TRIALS]
    for trial_id, (g, t) in enumerate(picks):
        stepper = TrialStepper(task)
        stepper.reset(int(subject.seeds[g, t]))
        messages = MessageSdbcExtractor()
        vector = None
        while not stepper.done:
            outputs = forward(subject.genomes[g], task.network, stepper.sensors())
            stepper.step(outputs)
            msg = task_state_to_msg(
                stepper.state(), task.description, 0, trial_id, name, stepper.done
            )
            # As a subscriber gets it: serialised and read back.
            received = deserialize_message(serialize_message(msg), TaskStateMsg)
            vector = messages.add(received)
        if vector is None:
            _fail(f"genome {g}, trial {t}: the last message was not marked done")
        fitness, characterisation, length = stepper.result()
        difference = _differ((fitness, characterisation, length), _trial(plain, g, t))
        if difference:
            _fail(f"genome {g}, trial {t}: live and in the batch, {difference}")
        reference = vectors[g * subject.n_trials + t]
        gap = float(np.max(np.abs(vector - reference)))
        if not gap <= MESSAGE_TOLERANCE:
            worst = messages.dimension_names[int(np.argmax(np.abs(vector - reference)))]
            _fail(
                f"genome {g}, trial {t}: the message-path SDBC differs from the "
                f"batch's by {gap:.3g} ({worst})"
            )
    return f"{len(picks)} trials stepped live through messages equal the batch"


def _bad_values(default: Any) -> list[Any]:
    """Values a setting with this default must refuse."""
    if isinstance(default, bool):
        return ["yes", 1]
    if isinstance(default, int):
        return [default + 0.5, str(default)]
    if isinstance(default, float):
        return [math.nan, math.inf, str(default)]
    if isinstance(default, str):
        return [7]
    if isinstance(default, tuple):
        return [7]
    return []


def check_settings(subject: Subject) -> str:
    """The ``settings`` check (module docstring); a summary of what passed."""
    from sdbc_evolution.run.config import ConfigError, check_task_config

    task_class = resolve_task(subject.reference)
    config_class = task_class.config_class
    if not is_settings(config_class):
        _fail("config_class is not a settings class made with @settings")
    made = config_class()
    defaults = {f.name: getattr(made, f.name) for f in dataclasses.fields(made)}
    tried = 0
    for name, default in defaults.items():
        for value in _bad_values(default):
            tried += 1
            try:
                check_task_config(subject.reference, {name: value})
            except ConfigError as error:
                if f"task_config.{name}" not in str(error):
                    _fail(f"{name} = {value!r} is refused without naming it: {error}")
                continue
            _fail(f"{name} = {value!r} is accepted (default {default!r})")
    try:
        check_task_config(subject.reference, {"no_such_setting": 1})
    except ConfigError as error:
        if "task_config.no_such_setting" not in str(error):
            _fail(f"an unknown setting is refused without naming it: {error}")
    else:
        _fail("an unknown setting, no_such_setting, is accepted")
    return f"{tried + 1} bad settings of {len(defaults)} refused, each by name"


CHECKS: dict[str, Callable[[Subject], str]] = {
    "declaration": check_declaration,
    "task_state": check_task_state,
    "ranges": check_ranges,
    "batch": check_batch,
    "process": check_process,
    "live": check_live,
    "settings": check_settings,
}
"""Every check, in the order they run."""


def run_checks(
    reference: str,
    task_config: Mapping[str, Any] | None = None,
    checks: Sequence[str] | None = None,
    seed: int = 0,
) -> list[CheckResult]:
    """Runs ``checks`` (default: all) on the task ``reference`` names.

    Raises:
        ValueError: An unknown check name.
    """
    names = list(checks or CHECKS)
    unknown = sorted(set(names) - set(CHECKS))
    if unknown:
        raise ValueError(f"unknown checks {unknown}; known: {', '.join(CHECKS)}")
    subject = Subject(task_reference(reference), dict(task_config or {}), seed)
    return run_named({name: CHECKS[name] for name in names}, subject)


S = TypeVar("S")


def run_named(
    checks: Mapping[str, Callable[[S], str]],
    subject: S,
    failures: tuple[type[Exception], ...] = (CheckFailed,),
    stop_at_failure: bool = False,
) -> list[CheckResult]:
    """Runs each of ``checks`` on ``subject`` in turn, timed.

    Args:
        failures: Exceptions that say a check does not hold (their message
            alone is the detail); any other is reported with its type.
        stop_at_failure: Whether the checks after a failed one are not run
            (failed, naming it), as when each needs what the one before checks.
    """
    holds_not: tuple[type[Exception], ...] = (CheckFailed, *failures)
    results: list[CheckResult] = []
    for name, check in checks.items():
        start = time.perf_counter()
        failed = next((r.name for r in results if not r.passed), None)
        try:
            if stop_at_failure and failed is not None:
                raise CheckFailed(f"not run: the {failed} check failed")
            detail, passed = check(subject), True
        except holds_not as error:
            detail, passed = str(error), False
        except (SettingsError, UnknownTask) as error:
            detail, passed = f"the task cannot be built: {error}", False
        except Exception as error:  # noqa: BLE001 - a task's own bug, reported
            detail, passed = f"{type(error).__name__}: {error}", False
        results.append(CheckResult(name, passed, detail, time.perf_counter() - start))
    return results


def run_live_checks(target: LiveTarget) -> list[CheckResult]:
    """Runs every live check (:mod:`sdbc_evolution.graph.conformance`) on the
    graph ``target``; needs rclpy and the built sdbc_msgs.

    Raises:
        ValueError: A target at odds with its task (the message says how).
    """
    from sdbc_evolution.graph.client import GraphClientError
    from sdbc_evolution.graph.conformance import LIVE_CHECKS, LiveSubject

    with LiveSubject(target) as subject:
        return run_named(
            LIVE_CHECKS, subject, failures=(GraphClientError,), stop_at_failure=True
        )


def main(argv: Sequence[str] | None = None) -> int:
    """``sdbc-conformance``: runs the checks on a task; the exit status of the module
    docstring."""
    from sdbc_sim.tasks import parse_task_config

    parser = argparse.ArgumentParser(
        prog="sdbc-conformance",
        description="Checks that a task works everywhere sdbc runs it (see "
        "sdbc_evolution/conformance.py for what each check asks).",
    )
    parser.add_argument(
        "task",
        help="a registered name, package.module:Class or path/to/file.py:Class",
    )
    parser.add_argument(
        "--task-config",
        default="",
        help="the task's settings that differ from its defaults, as YAML "
        "(e.g. '{max_steps: 300}')",
    )
    parser.add_argument(
        "--check",
        action="append",
        choices=list(CHECKS),
        help="run only this check (repeatable; default: all)",
    )
    live = parser.add_argument_group(
        "a running simulator", "checked through ROS 2 against the contract of "
        "evolution through another simulator (docs/ros2.md)"
    )  # fmt: skip
    live.add_argument(
        "--live",
        action="store_true",
        help="check the simulator running TASK on the graph instead of the task",
    )
    live.add_argument("--robots", type=int, help="robots of another system's task")
    live.add_argument(
        "--genome-length", type=int, help="genes of another system's task"
    )
    live.add_argument("--namespace", default="", help="the graph's namespace")
    live.add_argument(
        "--graph-timeout",
        type=float,
        default=60.0,
        help="seconds to wait for the graph and for each answer (default 60)",
    )
    args = parser.parse_args(argv)
    try:
        task_config = parse_task_config(args.task_config)
        if args.live:
            results = _live(args, task_config)
        else:
            resolve_task(args.task)
            results = run_checks(args.task, task_config, args.check)
    except ValueError as error:
        print(f"sdbc-conformance: error: {error}", file=sys.stderr)
        return 2
    for r in results:
        mark = "ok  " if r.passed else "FAIL"
        print(f"{mark} {r.name:<12} {r.seconds:6.1f} s  {r.detail}")
    passed = sum(r.passed for r in results)
    print(f"{passed}/{len(results)} checks passed for {args.task}")
    return 0 if passed == len(results) else 1


def _live(args: argparse.Namespace, task_config: dict[str, Any]) -> list[CheckResult]:
    """The live checks the command line asks for (or SystemExit 2 without ROS)."""
    from sdbc_sim.limits import MAX_CONNECT_TIMEOUT
    from sdbc_sim.nodes.entry import require

    if args.check:
        raise ValueError("--check names checks of a task; --live runs its own")
    for flag, value in (
        ("--robots", args.robots),
        ("--genome-length", args.genome_length),
    ):
        if value is not None and value < 1:
            raise ValueError(f"{flag}: must be at least 1, got {value}")
    timeout = args.graph_timeout
    if not 0 < timeout <= MAX_CONNECT_TIMEOUT:
        raise ValueError(
            f"--graph-timeout: must be in (0, MAX_CONNECT_TIMEOUT="
            f"{MAX_CONNECT_TIMEOUT:g}], got {timeout}"
        )
    require("sdbc-conformance --live")
    from sdbc_evolution.graph.conformance import LiveTarget
    from sdbc_evolution.graph.graph_file import GraphError, check_namespace

    try:
        namespace = check_namespace(args.namespace)
    except GraphError as error:
        raise ValueError(f"--namespace: {error}") from None
    return run_live_checks(
        LiveTarget(
            task=args.task,
            task_config=task_config,
            robots=args.robots,
            genome_length=args.genome_length,
            namespace=namespace,
            timeout=timeout,
        )
    )


if __name__ == "__main__":
    sys.exit(main())
