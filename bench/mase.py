"""Side by side with the authors' Java (MASE at fd13449), on one pinned core.

Given a git checkout of MASE (https://github.com/jorgemcgomes/mase) at commit
fd13449, this benchmark

1. checks that the checkout is at that commit with its sources unmodified;
2. compiles, with ``javac`` against the jars MASE ships in ``lib/``, only what the
   three tasks' parameter files name (their simulators and evaluation functions,
   and the ``SystematicEvaluator``) plus our driver ``bench/MaseBench.java``; javac
   pulls in what those reference. The classes go to
   ``~/.cache/sdbc/mase-build/<commit>`` and are reused while the sources and the
   driver are unchanged;
3. starts one JVM per task and configuration, each running MASE's own parameter
   files layered as an evolution run layers them (``ga.params``, the task's file,
   and ``syseval.params`` on top for the SDBC): ``indiana.params`` (gate escape),
   ``sharing_f.params`` (resource sharing) and ``oneprey_homo.params``
   (predator-prey), bare (fitness and task-specific characterisation) and with the
   systematic evaluator, as in the paper's runs. Each JVM is warmed up with one
   batch first, as a generation of an evolution run finds it;
4. interleaves, ``--alternations`` times, one batch of ``--genomes`` random genomes
   x ``--trials`` trials of each: MASE bare, MASE with SDBC, and for each of our
   physics models (``--model``; by default both, ``rigid`` and ``kinematic``, see
   ``PhysicsSettings.model``) our engine bare (:func:`sdbc_sim.run_batch`) and
   with the SDBC extractor (the evolution's path), each configuration of ours,
   like each of MASE's, in a warm process of its own (:class:`EngineProcess`),
   all on one core (this process and the ones it starts are pinned to it, as
   ``taskset -c CORE`` would), the order reversed on every other alternation;
5. prints, per task, medians over the alternations of robot-steps per CPU-second
   (each process's own CPU time, the JVM's JIT and GC threads included) and per
   wall-second, and per model the medians of the per-alternation ratios
   ours / MASE, bare and with the SDBC; then every alternation's ratio with the
   SDBC, per CPU-second, with their minimum and maximum;
6. says, per task and model, whether its ratio with the SDBC reaches the
   model's goal (:data:`GOALS`: 4.0 for ``kinematic``, 1.2 for ``rigid``; ``--goal
   MODEL=RATIO`` sets another), from a distribution-free interval for the median
   ratio (the alternations' range with 5 of them): it reaches the goal only if
   the whole interval does, is short if the whole interval is, and is at the
   goal within the run's noise otherwise; for one that does not reach it, it
   profiles one more batch with that model (``bench/profile.py``: each part of
   our step in ns per robot-step, the compiled loops and numpy's ``exp`` and
   ``arctan2`` as parts of their own) and
   prints it beside MASE's whole step with the SDBC in the same unit (from MASE's
   median rate) and the cost per robot-step the goal would need, which shows
   where the difference lies, and says whether a step fused into its compiled
   passes could reach the goal: what such a step would still pay (the physics'
   own step and transfer, the compiled loops, whose arithmetic gives the results
   their bits, and numpy's ``exp`` and ``arctan2``, whose implementations give
   theirs) against what lies between them (``--no-profile`` leaves the
   profiles out).

MASE's robots are kinematic, as ``kinematic`` models them; ``rigid`` (our default)
puts every contact through pymunk's solver.

Robot-steps count every body of every trial for every step it took, as
``bench/engine.py`` counts them: our task's bodies per trial (gate escape 4
robots, resource sharing 3, predator-prey 3 predators and the prey) times the steps
MASE's (or our) trial took. Random genomes are uniform in [-1, 1] in both.

Not part of the tests or CI: it needs MASE's sources, which this repository does
not include. The machine should otherwise be idle; on a shared one only the ratios
of one run mean anything.

Run: ``scripts/sdbc bench mase --mase PATH`` (options: ``--alternations``,
``--genomes``, ``--trials``, ``--task``, ``--model``, ``--core``, ``--seed``,
``--json``, ``--goal``, ``--no-profile``).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import numpy as np
from common import bench_module, pin_to_core, random_batch
from sdbc_evolution.sdbc.characterisation import SdbcExtractor
from sdbc_sim.engine import EngineSettings, run_batch
from sdbc_sim.physics import MODELS, Model, PhysicsSettings
from sdbc_sim.tasks import make_task

COMMIT = "fd13449bab51d23cfa28bd1cfc2f202a5edd5aa6"
"""The MASE commit of the paper's code."""
DRIVER = Path(__file__).with_name("MaseBench.java")
PARAMS = {
    "gate_escape": "src/mase/app/indiana/indiana.params",
    "resource_sharing": "src/mase/app/sharing/sharing_f.params",
    "predator_prey": "src/mase/app/pred/oneprey_homo.params",
}
"""Our task -> MASE's parameter file for it."""
GA_PARAMS = "src/mase/ga.params"
SYSEVAL_PARAMS = "src/mase/generic/systematic/syseval.params"
SOURCES = (
    "src/mase/app/indiana/IndianaSimulator.java",
    "src/mase/app/indiana/IndianaFitness2.java",
    "src/mase/app/indiana/IndianaBehaviourEval.java",
    "src/mase/app/sharing/ResourceSharingSimulator.java",
    "src/mase/app/sharing/RSFitness2.java",
    "src/mase/app/sharing/RSBehaviourEval.java",
    "src/mase/app/pred/PredatorPreySimulator.java",
    "src/mase/app/pred/OnePreyFitness2.java",
    "src/mase/app/pred/OnePreyGroupEval2.java",
    "src/mase/generic/systematic/SystematicEvaluator.java",
    "src/ec/simple/SimpleEvolutionState.java",
)
"""The classes the parameter files name (loaded by reflection, so javac must be
given them); javac compiles what they reference from src/."""
GOALS = {"kinematic": 4.0, "rigid": 1.2}
"""Per physics model, the ratio ours / MASE with the SDBC (per CPU-second) that the
engine aims for: with MASE's own robot model four times MASE's speed, with rigid
bodies (every contact through chipmunk's solver) 1.2 times."""
MEDIAN_LEVEL = 0.9
"""The least coverage of the interval a verdict reads the median ratio from
(:func:`median_interval`)."""
MASE_CONFIGS = ("mase", "mase+sdbc")
"""MASE bare and with its SystematicEvaluator; ours are each physics model bare
(its name) and with the SDBC extractor (its name + "+sdbc")."""


def check_checkout(mase: Path) -> None:
    """Raises SystemExit unless ``mase`` is a git checkout of COMMIT whose
    sources and jars are unmodified (a jar may be missing)."""
    if not (mase / "src/mase").is_dir():
        raise SystemExit(f"mase: {mase} holds no src/mase: not a MASE checkout")
    try:
        head = subprocess.run(
            ["git", "-C", str(mase), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(mase), "status", "--porcelain", "--", "src", "lib"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout
    except (OSError, subprocess.CalledProcessError) as e:
        raise SystemExit(f"mase: {mase} is not a git checkout ({e})") from e
    if head != COMMIT:
        raise SystemExit(
            f"mase: {mase} is at {head}, not {COMMIT}; run "
            f"`git -C {mase} checkout {COMMIT[:7]}`"
        )
    # A jar missing from lib/ changes nothing that runs: javac fails if the
    # classes need it. Mirrors often leave out the largest one (weka.jar).
    changed = [
        line
        for line in dirty.splitlines()
        if not (line.startswith(" D lib/") and line.endswith(".jar"))
    ]
    if changed:
        raise SystemExit(f"mase: {mase} has local changes:\n" + "\n".join(changed))


def classpath_jars(mase: Path) -> list[Path]:
    jars = sorted((mase / "lib").glob("*.jar"))
    if not jars:
        raise SystemExit(f"mase: no jars in {mase / 'lib'}")
    return jars


def build(mase: Path, javac: str) -> Path:
    """Compiles the needed classes and the driver (once per sources); returns the
    class directory."""
    digest = hashlib.sha256(DRIVER.read_bytes())
    for rel in SOURCES:
        digest.update(rel.encode())
    out = Path.home() / ".cache/sdbc/mase-build" / COMMIT[:7] / digest.hexdigest()[:12]
    if (out / "mase/mason/MaseBench.class").exists():
        return out
    tmp = out.with_name(out.name + ".tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    cp = os.pathsep.join(str(j) for j in classpath_jars(mase))
    cmd = [
        javac,
        "-nowarn",
        "-encoding",
        "UTF-8",
        "-d",
        str(tmp),
        "-cp",
        cp,
        "-sourcepath",
        str(mase / "src"),
        str(DRIVER),
        *(str(mase / rel) for rel in SOURCES),
    ]
    print(f"compiling MASE's classes into {out} ...", flush=True)
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"javac failed:\n{done.stdout}\n{done.stderr}")
    shutil.rmtree(out, ignore_errors=True)
    tmp.rename(out)
    return out


def layered_params(mase: Path, task: str, sdbc: bool, where: Path) -> Path:
    """A parameter file whose parents are MASE's own, first found wins:
    syseval.params (with the SDBC), the task's file, ga.params."""
    parents = ([SYSEVAL_PARAMS] if sdbc else []) + [PARAMS[task], GA_PARAMS]
    text = "".join(
        f"parent.{i} = {(mase / p).resolve()}\n" for i, p in enumerate(parents)
    )
    path = where / f"{task}{'_syseval' if sdbc else ''}.params"
    path.write_text(text)
    return path


class _BatchServer:
    """A warm process running batches on request: a "run" line on its stdin is
    answered by a "batch" line on its stdout; "quit" ends it."""

    def __init__(self, argv: list[str], log: Path, name: str) -> None:
        self.log = log
        self.name = name
        self.proc = subprocess.Popen(
            argv,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=log.open("w"),
            text=True,
            bufsize=1,
        )

    def _await(self, tag: str) -> str:
        """The rest of the next line that starts with ``tag``."""
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            if line.startswith(tag + " "):
                return line[len(tag) + 1 :].strip()
        raise SystemExit(
            f"{self.name} ended before '{tag}' (exit {self.proc.wait()}); "
            f"see {self.log}"
        )

    def _run(self) -> str:
        """The answer to one "run"."""
        assert self.proc.stdin is not None
        self.proc.stdin.write("run\n")
        self.proc.stdin.flush()
        return self._await("batch")

    def close(self) -> None:
        if self.proc.poll() is None:
            assert self.proc.stdin is not None
            self.proc.stdin.write("quit\n")
            self.proc.stdin.close()
            self.proc.wait(timeout=30)


def _pairs(text: str) -> dict[str, str]:
    """``key=value`` words as a dict."""
    return dict(kv.split("=", 1) for kv in text.split())


class MaseProcess(_BatchServer):
    """One warm JVM running batches of one task on request."""

    def __init__(
        self,
        java: str,
        classpath: str,
        params: Path,
        genomes: int,
        trials: int,
        seed: int,
        log: Path,
    ) -> None:
        argv = [java, "-cp", classpath, "mase.mason.MaseBench"]
        argv += ["--params", str(params), "--genomes", str(genomes)]
        argv += ["--trials", str(trials), "--seed", str(seed), "--warmup", "1"]
        super().__init__(argv, log, "MaseBench")
        self.evaluations = int(_pairs(self._await("ready"))["evaluations"])

    def batch(self) -> tuple[int, float, float]:
        """(trial steps, CPU seconds, wall seconds) of one batch."""
        r = _pairs(self._run())
        return int(r["trial_steps"]), int(r["cpu_ns"]) * 1e-9, int(r["wall_ns"]) * 1e-9


@dataclass
class Series:
    """Rates of one task and configuration, one per alternation."""

    cpu: list[float] = field(default_factory=list)
    wall: list[float] = field(default_factory=list)


def engine_batch(
    task_name: str,
    genomes: int,
    trials: int,
    sdbc: bool,
    rng: np.random.Generator,
    model: str = "rigid",
) -> tuple[int, float, float, float]:
    """(robot-steps, CPU seconds, wall seconds, mean fitness) of one batch
    through our engine with the physics ``model``."""
    task = make_task(task_name)
    g, s = random_batch(task, genomes, trials, rng)
    observers = [SdbcExtractor(check_values=False)] if sdbc else []
    settings = EngineSettings(physics=PhysicsSettings(model=cast(Model, model)))
    c0, w0 = time.process_time(), time.perf_counter()
    r = run_batch(task, g, s, observers, settings=settings)
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    fitness = float(np.mean(r.fitness))
    return int(r.length.sum()) * task.layout.n_bodies, cpu, wall, fitness


class EngineProcess(_BatchServer):
    """One warm process of ours running batches of one task and configuration
    on request, as a :class:`MaseProcess` runs MASE's. In one process for all
    configurations, the rigid model's garbage (pymunk's bodies and shapes, which
    only Python's cyclic collector frees) was collected in whichever batch came
    next: a kinematic batch of resource sharing after a rigid one spent 6-24 %
    of its time collecting it, 0.1-0.4 % after kinematic ones. Here each
    configuration pays for its own, as in a study, whose processes run one
    model."""

    def __init__(
        self,
        task: str,
        model: str,
        sdbc: bool,
        genomes: int,
        trials: int,
        seed: int,
        log: Path,
    ) -> None:
        job = {
            "task": task,
            "model": model,
            "sdbc": sdbc,
            "genomes": genomes,
            "trials": trials,
            "seed": seed,
        }
        argv = [sys.executable, __file__, "--serve", json.dumps(job)]
        super().__init__(argv, log, "our engine's process")
        self._await("ready")

    def batch(self) -> tuple[int, float, float, float]:
        """(robot-steps, CPU seconds, wall seconds, mean fitness) of one batch."""
        r = json.loads(self._run())
        return (
            int(r["robot_steps"]),
            float(r["cpu"]),
            float(r["wall"]),
            float(r["fitness"]),
        )


def serve(job: dict[str, Any]) -> None:
    """The loop of an :class:`EngineProcess`: one small batch untimed (imports,
    the compiled loops loaded, first allocations), then a batch per "run" line
    on stdin until "quit", each answered by a "batch" line."""
    rng = np.random.default_rng(job["seed"])
    task, model, sdbc = job["task"], job["model"], bool(job["sdbc"])
    engine_batch(task, 10, 2, sdbc, rng, model)
    print("ready {}", flush=True)
    for line in sys.stdin:
        if line.strip() != "run":
            break
        robot_steps, cpu, wall, fitness = engine_batch(
            task, job["genomes"], job["trials"], sdbc, rng, model
        )
        answer = {
            "robot_steps": robot_steps,
            "cpu": cpu,
            "wall": wall,
            "fitness": fitness,
        }
        print(f"batch {json.dumps(answer)}", flush=True)


def _ratios(ours: list[float], theirs: list[float]) -> list[float]:
    """Ours / theirs, alternation by alternation."""
    return [a / b for a, b in zip(ours, theirs, strict=True)]


def _median_ratio(ours: list[float], theirs: list[float]) -> float:
    """Median over the alternations of ours / theirs."""
    return statistics.median(_ratios(ours, theirs))


def median_interval(
    values: list[float], level: float = MEDIAN_LEVEL
) -> tuple[float, float] | None:
    """A distribution-free interval for the median of what ``values`` sample:
    their k-th lowest and k-th highest, with the largest k whose coverage, 1 -
    2 P(B <= k - 1) for B ~ Binomial(n, 1/2), is at least ``level``. None when
    even the lowest and the highest fall short of it (fewer than 5 values at
    0.9). With 5 values it is their range (coverage 0.94), with 9 the second
    lowest to the second highest (0.96)."""
    n = len(values)
    ordered = sorted(values)
    interval = None
    for k in range(1, n // 2 + 1):
        below = sum(math.comb(n, j) for j in range(k)) / 2**n
        if 1.0 - 2.0 * below < level:
            break
        interval = (ordered[k - 1], ordered[n - k])
    return interval


def verdicts(
    series: dict[tuple[str, str], Series],
    names: list[str],
    models: list[str],
    profile_batch: tuple[int, int, int] | None,
    goals: dict[str, float] | None = None,
) -> None:
    """Whether each task and model reaches its goal with the SDBC, per
    CPU-second (``goals[model]``, :data:`GOALS` by default), read from the
    interval of the median ratio (:func:`median_interval`): it reaches the goal
    when the whole interval does, is short of it when the whole interval is, and
    is at the goal within the run's noise otherwise (or with too few
    alternations to tell). For one that does not reach it, with
    ``profile_batch`` (genomes, trials per genome, seed), one more batch profiled
    part by part with that model, beside MASE's whole step and the cost per
    robot-step the goal needs."""
    goals = GOALS if goals is None else goals
    print(
        "\nwith the SDBC, per CPU-second (median ratio to MASE, the interval that "
        f"holds the median with probability >= {MEDIAN_LEVEL:g}, goal):"
    )
    short: list[tuple[str, str, float, float]] = []
    for t in names:
        mase = series[(t, "mase+sdbc")].cpu
        for m in models:
            ratios = _ratios(series[(t, f"{m}+sdbc")].cpu, mase)
            r = statistics.median(ratios)
            goal = goals[m]
            interval = median_interval(ratios)
            if interval is None:
                span = "(too few alternations)"
                verdict = "CANNOT TELL, goal"
            else:
                span = f"({interval[0]:.2f}-{interval[1]:.2f})"
                verdict = (
                    "reaches the goal"
                    if interval[0] >= goal
                    else "SHORT of the goal"
                    if interval[1] < goal
                    else "AT the goal within the noise,"
                )
            print(f"{t:<17}{m:<10}{r:.3f} {span:<13} {verdict} {goal:g}")
            if interval is None or interval[0] < goal:
                ours = statistics.median(series[(t, f"{m}+sdbc")].cpu)
                short.append((t, m, statistics.median(mase), ours))
    if profile_batch is None:
        return
    genomes, trials, seed = profile_batch
    profiler = bench_module("profile")
    for t, m, mase_rate, our_rate in short:
        settings = EngineSettings(physics=PhysicsSettings(model=cast(Model, m)))
        p = profiler.profile_task(
            t, genomes, trials, None, seed, settings, True, loops=True
        )
        mase_ns = 1e9 / mase_rate
        print(
            f"\nwhy {t} ({m}) does not reach its goal: MASE's whole step with the "
            f"SDBC took {mase_ns:.0f} ns per robot-step (its median rate above), "
            f"so the goal {goals[m]:g} needs {mase_ns / goals[m]:.0f}; ours, part by "
            "part, in one more batch (instrumented, so a little slower than the runs "
            "above):"
        )
        print(profiler.report(p))
        need = mase_ns / goals[m]
        print(fused_floor(p, 1e9 / our_rate, need, profiler.FUSED_FLOOR))


def fused_floor(p: Any, ours: float, need: float, floor_parts: tuple[str, ...]) -> str:
    """Whether a step fused into compiled passes could reach the goal that
    allows ``need`` ns per robot-step: what it would still pay (``floor_parts``,
    as a share of the profile ``p``'s step) at the runs' median step of ``ours``
    ns per robot-step, against what lies between them. The share, not the
    profile's own nanoseconds: one instrumented batch moves with the machine
    more than the median of the runs."""
    if ours <= need:
        return (
            f"  the runs' median step, {ours:.0f} ns per robot-step, is within the "
            f"{need:.0f} the goal allows: they fall short by their spread, not by "
            "a part of the step"
        )
    share = p.share(*floor_parts)
    floor = share * ours
    said = (
        f"  the physics' own step and transfer, the compiled loops and numpy's exp "
        f"and arctan2: {share:.0%} "
        f"of this batch's step, so about {floor:.0f} of the runs' median "
        f"{ours:.0f} ns per robot-step"
    )
    if floor > need:
        return (
            f"{said}, more than the {need:.0f} the goal allows: even a step fused "
            "into its compiled passes, with nothing between them, would be short; "
            "the loops and numpy's maths (which give the results their bits) or "
            "the physics would have to get faster"
        )
    return (
        f"{said}; the goal allows {need:.0f}, so {ours - need:.0f} of the other "
        f"{ours - floor:.0f}, which lie between them (Python, numpy's arrays, "
        "set-up), would have to go"
    )


def parse_goals(values: list[str] | None) -> dict[str, float]:
    """:data:`GOALS` with ``MODEL=RATIO`` overrides (``--goal``).

    Raises:
        ValueError: A value not of that form, an unknown model or a ratio <= 0.
    """
    goals = dict(GOALS)
    for value in values or []:
        model, sep, ratio = value.partition("=")
        if not sep or model not in goals:
            raise ValueError(
                f"--goal {value!r}: expected MODEL=RATIO with MODEL one of "
                f"{sorted(goals)}"
            )
        try:
            goal = float(ratio)
        except ValueError:
            goal = float("nan")
        if not goal > 0:
            raise ValueError(f"--goal {value!r}: the ratio must be a number > 0")
        goals[model] = goal
    return goals


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mase", type=Path, required=True, help="MASE checkout")
    parser.add_argument("--alternations", type=int, default=5)
    parser.add_argument("--genomes", type=int, default=200)
    parser.add_argument("--trials", type=int, default=10, help="trials per genome")
    parser.add_argument("--task", action="append", choices=sorted(PARAMS))
    parser.add_argument(
        "--model",
        action="append",
        choices=MODELS,
        help="our physics model (default: every one)",
    )
    parser.add_argument("--core", type=int, help="core to pin to (default: last)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--java", default="java")
    parser.add_argument("--javac", default="javac")
    parser.add_argument("--json", type=Path, help="also write every rate here")
    parser.add_argument(
        "--goal",
        action="append",
        metavar="MODEL=RATIO",
        help=f"a model's goal ratio with the SDBC (default {GOALS})",
    )
    parser.add_argument(
        "--no-profile",
        action="store_true",
        help="no profile of a task whose median ratio with the SDBC is short of "
        "its model's goal",
    )
    args = parser.parse_args()
    if args.alternations < 1:
        parser.error("--alternations must be >= 1")
    try:
        goals = parse_goals(args.goal)
    except ValueError as error:
        parser.error(str(error))
    mase = args.mase.resolve()
    check_checkout(mase)
    for tool in (args.java, args.javac):
        if shutil.which(tool) is None:
            raise SystemExit(f"mase: {tool} not found (a JDK 17 or later is needed)")
    classes = build(mase, args.javac)
    core = pin_to_core(args.core)
    print(f"pinned to core {core}", flush=True)
    classpath = os.pathsep.join([str(classes), *map(str, classpath_jars(mase))])
    names = args.task or list(PARAMS)
    models = args.model or list(MODELS)
    configs = [*MASE_CONFIGS, *(f"{m}{s}" for m in models for s in ("", "+sdbc"))]
    series = {(t, c): Series() for t in names for c in configs}
    processes: dict[tuple[str, str], MaseProcess] = {}
    ours: dict[tuple[str, str], EngineProcess] = {}
    try:
        for t in names:
            for sdbc in (False, True):
                params = layered_params(mase, t, sdbc, classes.parent)
                p = MaseProcess(
                    args.java,
                    classpath,
                    params,
                    args.genomes,
                    args.trials,
                    args.seed,
                    params.with_suffix(".log"),
                )
                expected = 3 if sdbc else 2
                if p.evaluations != expected:
                    raise SystemExit(
                        f"mase: {params} gave {p.evaluations} evaluation functions, "
                        f"expected {expected}"
                    )
                processes[(t, "mase+sdbc" if sdbc else "mase")] = p
        for i, t in enumerate(names):
            for j, c in enumerate(configs[len(MASE_CONFIGS) :]):
                model, _, sdbc_suffix = c.partition("+")
                ours[(t, c)] = EngineProcess(
                    t,
                    model,
                    bool(sdbc_suffix),
                    args.genomes,
                    args.trials,
                    args.seed + 1 + len(configs) * i + j,
                    classes.parent / f"{t}_{c}.log",
                )
        for k in range(args.alternations):
            order = [(t, c) for t in names for c in configs]
            if k % 2:
                order.reverse()
            for t, c in order:
                n_bodies = make_task(t).layout.n_bodies
                if c.startswith("mase"):
                    steps, cpu, wall = processes[(t, c)].batch()
                    robot_steps = steps * n_bodies
                else:
                    robot_steps, cpu, wall, _ = ours[(t, c)].batch()
                series[(t, c)].cpu.append(robot_steps / cpu)
                series[(t, c)].wall.append(robot_steps / wall)
                print(
                    f"alternation {k + 1} {t:<17} {c:<10} "
                    f"{robot_steps / cpu:>12,.0f} robot-steps/CPU-s "
                    f"{robot_steps / wall:>12,.0f} /wall-s",
                    flush=True,
                )
    finally:
        for p in processes.values():
            p.close()
        for e in ours.values():
            e.close()
    print(
        f"\nmedians over {args.alternations} alternations, {args.genomes} genomes x "
        f"{args.trials} trials per batch, core {core}:"
    )
    header = f"{'task':<17}{'':<6}" + "".join(f"{c:>15}" for c in configs)
    header += "".join(f"{m + '/MASE':>16}{'+SDBC':>7}" for m in models)
    print(header)
    for t in names:
        for kind in ("cpu", "wall"):
            rates = {c: getattr(series[(t, c)], kind) for c in configs}
            line = f"{t:<17}{kind:<6}" + "".join(
                f"{statistics.median(rates[c]):>15,.0f}" for c in configs
            )
            for m in models:
                bare = _median_ratio(rates[m], rates["mase"])
                with_sdbc = _median_ratio(rates[f"{m}+sdbc"], rates["mase+sdbc"])
                line += f"{bare:>16.2f}{with_sdbc:>7.2f}"
            print(line)
    print(
        "(robot-steps per CPU-second and per wall-second; <model>/MASE: median of "
        "the per-alternation ratios of our engine with that physics model to MASE, "
        "bare and with the SDBC)"
    )
    # The spread says how far a median can be trusted: between runs on a shared
    # machine the ratios themselves move.
    print("\nper-alternation ratios to MASE with the SDBC, per CPU-second:")
    for t in names:
        for m in models:
            ratios = _ratios(series[(t, f"{m}+sdbc")].cpu, series[(t, "mase+sdbc")].cpu)
            print(
                f"{t:<17}{m:<10}"
                + " ".join(f"{r:.2f}" for r in ratios)
                + f"   (min {min(ratios):.2f}, max {max(ratios):.2f})"
            )
    batch = (args.genomes, args.trials, args.seed)
    verdicts(series, names, models, None if args.no_profile else batch, goals)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(
            json.dumps(
                {
                    f"{t}/{c}": {"cpu": s.cpu, "wall": s.wall}
                    for (t, c), s in series.items()
                },
                indent=1,
            )
        )


if __name__ == "__main__":
    if sys.argv[1:2] == ["--serve"]:
        serve(json.loads(sys.argv[2]))
    else:
        main()
