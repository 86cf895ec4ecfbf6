"""A short probe of what a preset's study will cost on this machine.

For each task, one run of every treatment goes a few generations with the real
engine, in this process (one core). The cost of a generation is its CPU time
(``time.process_time``: what it takes on a core of its own, whatever else loads the
machine), split into evaluation and the rest by the run's own ``evaluation_time``
share. Projected study time of a task, with ``k`` runs side by side on ``k`` free
cores::

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
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sdbc_evolution.run.evaluators import LocalEvaluator, TaskInfo
from sdbc_evolution.run.experiment import Experiment, task_spec
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


def probe(
    preset: StudyPreset, task: str, generations: int = PROBE_GENERATIONS
) -> list[Probe]:
    """Measures one short run of every treatment of ``preset`` on ``task``."""
    if generations < 2:
        raise ValueError(f"generations must be at least 2, got {generations}")
    probes = []
    for treatment in preset.treatments:
        # One generation more than is stepped: a generation evaluates the next
        # one's population with its re-evaluation (sdbc_evolution.run.experiment),
        # which the last one of a run does not, so every one stepped here costs
        # what a generation in the middle of a run costs.
        config = preset.experiment_config(task, treatment, 0).replace(
            generations=generations + 1
        )
        spec = task_spec(config)
        info = TaskInfo.of(spec)
        max_steps = int(spec.build().max_steps)
        length_index = info.sdbc_names.index(LENGTH_DIMENSION)
        with (
            tempfile.TemporaryDirectory(prefix="sdbc-probe-") as out,
            LocalEvaluator(spec, workers=1) as evaluator,
        ):
            experiment = Experiment.create(config, Path(out), evaluator, info)
            cpu, wall, share, lengths = [], [], [], []
            for g in range(generations):
                c0, w0 = time.process_time(), time.perf_counter()
                record = experiment.step()
                c1, w1 = time.process_time(), time.perf_counter()
                if g == 0:
                    continue
                cpu.append(c1 - c0)
                wall.append(w1 - w0)
                share.append(record.evaluation_time / max(record.wall_time, 1e-12))
                with np.load(experiment.results.individuals_path(g)) as data:
                    lengths.append(float(np.mean(data["sdbc"][:, length_index])))
        probes.append(
            Probe(
                task=task,
                treatment=treatment.name,
                cpu_per_generation=float(np.mean(cpu)),
                wall_per_generation=float(np.mean(wall)),
                evaluation_share=float(np.mean(share)),
                mean_length=float(np.mean(lengths)),
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
        f"treatments per task, {concurrent_runs} runs side by side",
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
