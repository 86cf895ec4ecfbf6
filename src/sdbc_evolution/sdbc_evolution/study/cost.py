"""What the runs cost, and what the paper's study would cost on a cluster.

Measured per task from the run directories (``generations.csv`` columns ``wall_time``
and ``evaluation_time``, trial lengths from the SDBC "Simulation length" dimension,
and ``study_run.json`` for the workers each run had; a run without it counts as one
worker):

- robot-steps of a generation: S_g = B x L_g x (N T + T_r), with B bodies per trial,
  L_g the mean trial length of generation g, N individuals, T trials and T_r
  re-evaluation trials (the re-evaluated best taken at the generation's mean length);
- per-worker rate: r = sum_g S_g / sum_g (evaluation_time_g x workers_g), in
  robot-steps per second;
- serial time per individual: c = sum_g (wall_time_g - evaluation_time_g) / sum_g N
  (ranking, mutual information, output: the parts no worker shares);
- generations per second of a run at the study's own sizes.

Projection of a preset (by default ``paper``, the settings of
docs/reference-setup.md) run by this study's command on a Dask cluster of W workers,
runs one after the other, each generation's N controllers spread over min(W, N) workers
(a controller's trials stay together)::

    T(W) = runs x treatments x G x (c N + B L (N T + T_r) / (r min(W, N)))

with L either the mean trial length measured here (the expected case) or the task's
``max_steps`` (the bound). The CPU time, runs x treatments x G x (c N + B L (N T +
T_r) / r), divided by W is what a scheduler running many runs at once could reach.
Not modelled: Dask's own overhead per generation, and controllers that evolve
longer or shorter trials at the paper's scale than at ours.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from sdbc_evolution.study.digest import TaskDigest
from sdbc_evolution.study.presets import PresetError, StudyPreset, load_preset
from sdbc_evolution.study.rundirs import RunData
from sdbc_evolution.study.runner import EXECUTION_FILE

CLUSTER_WORKERS = (8, 32, 128, 512)
"""Cluster sizes the report projects the paper's study onto."""


def workers_per_generation(run: RunData) -> np.ndarray:
    """(G,) workers that evaluated each generation (1 where not recorded)."""
    return _per_generation(run, "workers_per_run")


def joined_per_generation(run: RunData) -> np.ndarray:
    """(G,) runs each generation was evaluated with in one process
    (``sdbc_evolution.run.joined``; 1 where not recorded): its clock counted
    every one's trials and serial work."""
    return _per_generation(run, "joined_runs")


def _per_generation(run: RunData, key: str) -> np.ndarray:
    """(G,) the whole number ``key`` of the ``study_run.json`` segment each
    generation lies in, at least 1 (1 where not recorded)."""
    values = np.ones(run.generations)
    file = run.path / EXECUTION_FILE
    try:
        segments = json.loads(file.read_text()) if file.is_file() else []
    except (OSError, ValueError):
        segments = []
    for segment in segments if isinstance(segments, list) else []:
        try:
            lo, hi = int(segment["from_generation"]), int(segment["to_generation"])
            values[lo:hi] = max(1, int(segment.get(key, 1)))
        except (KeyError, TypeError, ValueError):
            continue
    return values


@dataclass(frozen=True)
class TaskCost:
    """Measured cost of one task's runs.

    Attributes:
        task: Task name.
        runs: Runs measured.
        bodies: Bodies per trial (B).
        max_steps: The task's longest trial.
        mean_length: Mean trial length over every evaluated individual (L).
        rate: Robot-steps per second per worker (r).
        serial_per_individual: Serial seconds per individual per generation (c).
        seconds_per_generation: Mean wall seconds of a generation of a run.
        run_seconds: Sum over runs of their wall time.
    """

    task: str
    runs: int
    bodies: int
    max_steps: int
    mean_length: float
    rate: float
    serial_per_individual: float
    seconds_per_generation: float
    run_seconds: float

    @property
    def generations_per_second(self) -> float:
        """Generations per second: the inverse of ``seconds_per_generation``."""
        return 1.0 / self.seconds_per_generation


def task_cost(task: TaskDigest) -> TaskCost:
    """Pools every usable run of the task (see the module docstring)."""
    bodies = task.bodies
    steps = busy = serial = individuals = trial_steps = controller_trials = 0.0
    walls = []
    for run in task.runs:
        evaluation = run.config.evaluation
        n = run.population.astype(np.float64)
        length = run.trial_steps / (n * evaluation.trials)
        steps += float(
            np.sum(
                bodies
                * length
                * (n * evaluation.trials + evaluation.reevaluation_trials)
            )
        )
        wall = run.wall_time
        evaluation_time = run.evaluation_time
        busy += float(np.sum(evaluation_time * run.workers))
        serial += float(np.sum(np.maximum(wall - evaluation_time, 0.0)))
        individuals += float(n.sum())
        trial_steps += float(run.trial_steps.sum())
        controller_trials += float(np.sum(n * evaluation.trials))
        walls.append(wall)
    wall_all = np.concatenate(walls)
    return TaskCost(
        task=task.task,
        runs=len(task.runs),
        bodies=bodies,
        max_steps=task.max_steps,
        mean_length=trial_steps / controller_trials,
        rate=steps / busy,
        serial_per_individual=serial / individuals,
        seconds_per_generation=float(wall_all.mean()),
        run_seconds=float(wall_all.sum()),
    )


@dataclass(frozen=True)
class Projection:
    """Projected wall time of one task of a preset on W workers.

    Attributes:
        task: Task name.
        workers: W.
        expected_hours: At the measured mean trial length.
        bound_hours: With every trial running ``max_steps``.
        cpu_hours: Total CPU time at the measured length (divide by W for a
            scheduler that runs many runs at once).
        runs: Runs of the task (runs x treatments); ``cpu_hours / runs`` is one
            run on one core, the least a study run side by side can take.
    """

    task: str
    workers: int
    expected_hours: float
    bound_hours: float
    cpu_hours: float
    runs: int


def projected_hours(
    cost: TaskCost, preset: StudyPreset, workers: int, length: float
) -> tuple[float, float]:
    """(T(W), CPU time) in hours for ``cost.task`` under ``preset``."""
    config = preset.experiment_config(cost.task, preset.treatments[0], 0)
    n = config.ga.population_size
    trials = config.evaluation.trials
    reevaluation = config.evaluation.reevaluation_trials
    generations = preset.generations_of(cost.task)
    count = preset.runs * len(preset.treatments) * generations
    serial = cost.serial_per_individual * n
    evaluation = cost.bodies * length * (n * trials + reevaluation) / cost.rate
    wall = count * (serial + evaluation / min(workers, n))
    cpu = count * (serial + evaluation)
    return wall / 3600.0, cpu / 3600.0


def projections(
    costs: list[TaskCost],
    preset: StudyPreset,
    workers: tuple[int, ...] = CLUSTER_WORKERS,
) -> list[Projection]:
    """The projection of every measured task that ``preset`` holds."""
    runs = preset.runs * len(preset.treatments)
    out = []
    for cost in costs:
        if cost.task not in preset.tasks:
            continue
        for w in workers:
            expected, cpu = projected_hours(cost, preset, w, cost.mean_length)
            bound, _ = projected_hours(cost, preset, w, float(cost.max_steps))
            out.append(Projection(cost.task, w, expected, bound, cpu, runs))
    return out


def paper_preset() -> StudyPreset:
    """The ``paper`` preset, or the settings of docs/reference-setup.md if its file
    is not at hand."""
    try:
        return load_preset("paper")
    except PresetError:
        return StudyPreset(name="paper")
