"""A short probe of what a preset's study will cost on this machine.

For each task, runs of every treatment go a few generations with the real
engine, in this process (one core): as many runs as a study joins in one process
(``sdbc_evolution.run.joined``; one for the ``paper`` preset, seven for the local
ones), joined as it joins them. The cost of a run's generation is the CPU time
(``time.process_time``: what it takes on a core of its own, whatever else loads the
machine) from the end of one generation of every joined run to the end of the
next, divided by the runs, split into evaluation and the rest by the runs' own
``evaluation_time`` share (joined, a run's clock counts the whole batch and the
time it waited for the others: a share on the high side). Projected study time of
a task, with ``k`` processes side by side on ``k`` free cores::

    T_task = runs x sum_treatments(G_task x c_treatment) / k

The evaluation part of c scales with the trials' length; early generations (random
controllers) may stop sooner or later than evolved ones, so the worst case scales it
to every trial running ``max_steps``::

    c_worst = c_rest + c_eval x max_steps / mean measured trial length

Generation 0 (which builds the task, and evaluates its own population besides the
next one's) is left out of the mean.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sdbc_evolution.run.config import ExperimentConfig
from sdbc_evolution.run.evaluators import Evaluator, LocalEvaluator, TaskInfo
from sdbc_evolution.run.experiment import Experiment, task_spec
from sdbc_evolution.run.joined import run_joined
from sdbc_evolution.run.results import GenerationRecord
from sdbc_evolution.study.presets import StudyPreset

PROBE_GENERATIONS = 3
"""Generations each probe run goes (the first is left out of the mean)."""
LENGTH_DIMENSION = "Simulation length"
"""The SDBC dimension holding a controller's mean trial length in steps."""


@dataclass(frozen=True)
class Probe:
    """The measured cost of one treatment's generation on one task.

    Attributes:
        task: Task name.
        treatment: Treatment value.
        cpu_per_generation: Mean CPU seconds of a generation.
        wall_per_generation: Mean wall seconds of a generation (inflated by load).
        evaluation_share: Share of a generation's wall time spent evaluating.
        mean_length: Mean trial length of the measured generations, in steps.
        max_steps: The task's longest trial.
    """

    task: str
    treatment: str
    cpu_per_generation: float
    wall_per_generation: float
    evaluation_share: float
    mean_length: float
    max_steps: int

    @property
    def worst_cpu_per_generation(self) -> float:
        """CPU seconds of a generation if every trial ran ``max_steps``."""
        evaluation = self.cpu_per_generation * self.evaluation_share
        # Added to the measured cost, so that trials already at max_steps give it
        # back exactly (rest + evaluation x 1 may round below it).
        longer = self.max_steps / max(self.mean_length, 1.0) - 1.0
        return self.cpu_per_generation + evaluation * longer


Mark = tuple[float, float, GenerationRecord, float]
"""A probe run's generation: CPU and wall clock at its end, its record, and its
mean trial length."""


def _probe_job(
    config: ExperimentConfig,
    where: Path,
    info: TaskInfo,
    generations: int,
    marks: list[Mark],
) -> Callable[[Evaluator], None]:
    """A probe run's work: ``generations`` steps, each marked in ``marks``."""
    length_index = info.sdbc_names.index(LENGTH_DIMENSION)

    def work(evaluator: Evaluator) -> None:
        with Experiment.create(config, where, evaluator, info) as run:
            for g in range(generations):
                record = run.step()
                with np.load(run.results.individuals_path(g)) as data:
                    length = float(np.mean(data["sdbc"][:, length_index]))
                marks.append((time.process_time(), time.perf_counter(), record, length))

    return work


def probe(
    preset: StudyPreset,
    task: str,
    generations: int = PROBE_GENERATIONS,
    joined: int = 1,
) -> list[Probe]:
    """Measures short runs of every treatment of ``preset`` on ``task``,
    ``joined`` of them at once per treatment (module docstring)."""
    if generations < 2:
        raise ValueError(f"generations must be at least 2, got {generations}")
    if joined < 1:
        raise ValueError(f"joined runs must be at least 1, got {joined}")
    probes = []
    for treatment in preset.treatments:
        # One generation more than is stepped: a generation evaluates the next
        # one's population with its re-evaluation (sdbc_evolution.run.experiment),
        # which the last one of a run does not, so every one stepped here costs
        # what a generation in the middle of a run costs.
        configs = [
            preset.experiment_config(task, treatment, r).replace(
                generations=generations + 1
            )
            for r in range(joined)
        ]
        spec = task_spec(configs[0])
        info = TaskInfo.of(spec)
        max_steps = int(spec.build().max_steps)
        with (
            tempfile.TemporaryDirectory(prefix="sdbc-probe-") as out,
            LocalEvaluator(spec, workers=1) as evaluator,
        ):
            # Per run, per generation: (CPU, wall) clocks at its end, its record
            # and its mean trial length.
            ends: list[list[Mark]] = [[] for _ in configs]
            start = (time.process_time(), time.perf_counter())
            jobs = [
                (
                    task_spec(config),
                    _probe_job(
                        config, Path(out) / f"run_{r}", info, generations, ends[r]
                    ),
                )
                for r, config in enumerate(configs)
            ]
            run_joined(evaluator, jobs)
        # Generation g of the group ends when its last run ends it.
        cpu_end = [max(marks[g][0] for marks in ends) for g in range(generations)]
        wall_end = [max(marks[g][1] for marks in ends) for g in range(generations)]
        cpu = np.diff([start[0], *cpu_end])[1:] / joined
        wall = np.diff([start[1], *wall_end])[1:] / joined
        records = [marks[g] for marks in ends for g in range(1, generations)]
        probes.append(
            Probe(
                task=task,
                treatment=treatment.name,
                cpu_per_generation=float(np.mean(cpu)),
                wall_per_generation=float(np.mean(wall)),
                evaluation_share=float(
                    np.mean(
                        [
                            r.evaluation_time / max(r.wall_time, 1e-12)
                            for _, _, r, _ in records
                        ]
                    )
                ),
                mean_length=float(np.mean([length for *_, length in records])),
                max_steps=max_steps,
            )
        )
    return probes


def projected_task_seconds(
    preset: StudyPreset, probes: list[Probe], concurrent_runs: int, worst: bool
) -> float:
    """T_task of the module docstring for the probes of one task."""
    task = probes[0].task
    per_run = sum(
        preset.generations_of(task)
        * (p.worst_cpu_per_generation if worst else p.cpu_per_generation)
        for p in probes
    )
    return preset.runs * per_run / concurrent_runs


def probe_report(
    preset: StudyPreset, probes: dict[str, list[Probe]], concurrent_runs: int
) -> str:
    """The probes and the projected time per task, as a plain-text table."""
    lines = [
        f"preset {preset.name}: {preset.runs} runs x {len(preset.treatments)} "
        f"treatments per task, {concurrent_runs} processes side by side",
        f"{'task':18} {'treatment':9} {'cpu/gen s':>9} {'worst s':>8} "
        f"{'wall/gen s':>10} {'eval %':>6} {'length':>7}",
    ]
    for task, task_probes in probes.items():
        for p in task_probes:
            lines.append(
                f"{task:18} {p.treatment:9} {p.cpu_per_generation:9.3f} "
                f"{p.worst_cpu_per_generation:8.3f} {p.wall_per_generation:10.3f} "
                f"{100 * p.evaluation_share:6.1f} {p.mean_length:7.0f}"
            )
    for task, task_probes in probes.items():
        measured = projected_task_seconds(preset, task_probes, concurrent_runs, False)
        worst = projected_task_seconds(preset, task_probes, concurrent_runs, True)
        lines.append(
            f"{task}: {preset.generations_of(task)} generations; projected study "
            f"time {measured / 60:.1f} min at the measured trial lengths, "
            f"{worst / 60:.1f} min if every trial runs to max_steps"
        )
    return "\n".join(lines)
