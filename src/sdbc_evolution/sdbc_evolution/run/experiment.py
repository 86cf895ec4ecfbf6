"""The experiment runner: one evolutionary run, generation by generation, resumable.

A generation g, in order (the order fixes the GA generator's draws, so it is part of
the bit-identical resume contract):

1. trial seeds: (N, T) int64 from the GA's generator, fresh every generation (elites
   too: they are re-evaluated in new trials);
2. evaluation of the population (any evaluator: same results);
3. scoring by the treatment (``sdbc_evolution.ga.treatments``): NS-SD+ weights, novelty
   against population + archive, archive update, ranking order;
4. breeding: the ``elites`` first individuals of the order are copied, the other
   N - elites are bounded-Gaussian mutants of tournament winners;
5. re-evaluation of the generation's best (highest fitness) in fresh trials whose
   seeds come from a second generator, so turning re-evaluation on or off does not
   change the run; its fitness sums the trials up like every fitness (harmonic
   mean by default). Unless g is the last generation, the next generation's trial
   seeds are drawn here (step 1 of g + 1, the same draws) and its population is
   evaluated in the same batch (``Evaluator.evaluate_together``): on its own, a
   batch of a few re-evaluation trials pays the engine's cost per step for a few
   robots. The checkpoint keeps the GA generator as it was before that draw, so a
   resumed run draws the same seeds and evaluates them on its own, to the same
   bits;
6. outputs (``sdbc_evolution.run.results``), then the checkpoint (``checkpoint.npz``).

The run's two generators are children of ``np.random.SeedSequence(seed)``. A run
stopped anywhere and resumed from its checkpoint repeats nothing and skips nothing:
outputs of a generation whose checkpoint was not written are dropped on resume and
produced again, identically. :meth:`Experiment.create` writes the checkpoint of
generation 0, so a run stopped before its first generation ends resumes too.

One process writes a run: create and resume take the directory's lock
(``sdbc_evolution.run.lock``) before writing anything and hold it until
:meth:`Experiment.close`. Resume also checks every output the checkpoint vouches
for (``ResultsDirectory.verify``) and names the first damaged file.
"""

from __future__ import annotations

import json
import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from sdbc_sim.engine import controller_fitness

from sdbc_evolution.characterise.evaluation import SDBC, TASK
from sdbc_evolution.ga.rankings.nsga2 import positions
from sdbc_evolution.ga.search import TRIAL_SEED_BOUND, NoveltySearch, run_generators
from sdbc_evolution.ga.treatments import GenerationScores
from sdbc_evolution.run.checkpoint import (
    Checkpoint,
    CheckpointError,
    generator_from_state,
    load_checkpoint,
    save_checkpoint,
)
from sdbc_evolution.run.config import ExperimentConfig, dump_config
from sdbc_evolution.run.evaluators import Evaluation, Evaluator, TaskInfo, TaskSpec
from sdbc_evolution.run.lock import RunLock
from sdbc_evolution.run.results import GenerationRecord, ResultsDirectory, RunDamaged
from sdbc_evolution.run.system_errors import describe_system_error


class _PhaseClock:
    """Seconds spent in consecutive phases of a generation."""

    def __init__(self) -> None:
        self.start = self.last = time.perf_counter()
        self.phases: dict[str, float] = {}

    def lap(self, phase: str) -> None:
        now = time.perf_counter()
        self.phases[phase] = now - self.last
        self.last = now

    def total(self) -> float:
        return time.perf_counter() - self.start


class ExperimentError(RuntimeError):
    """A run that cannot start or go on; the message says why."""


def describe_failure(error: BaseException, prog: str = "sdbc-evolve") -> str:
    """What stopped a run, for a report of many runs: one line for a refusal of
    the system (``describe_system_error``) or of a run's input (a ``ValueError``
    or :class:`ExperimentError`: configuration, checkpoint, values out of range),
    the traceback for anything else (a bug, whose traceback is what helps)."""
    if isinstance(error, (OSError, MemoryError)):
        return describe_system_error(error, prog)
    if isinstance(error, (ValueError, ExperimentError)):
        return f"{type(error).__name__}: {error}"
    return "".join(traceback.format_exception(error)).rstrip()


def _locked(out_dir: str | Path, lock: RunLock | None) -> RunLock:
    """The output directory's lock: the caller's, checked, or taken now."""
    if lock is None:
        return RunLock(out_dir).acquire()
    if not lock.held or lock.directory != Path(out_dir):
        raise ValueError(f"the lock given is not a held lock of {out_dir}")
    return lock


def task_spec(config: ExperimentConfig) -> TaskSpec:
    """What evaluators need to know of a configuration's task."""
    characterisation = config.treatment.characterisation
    return TaskSpec(
        name=config.task,
        overrides=dict(config.task_config),
        fitness_mean=config.evaluation.fitness_mean,
        physics=config.evaluation.physics,
        characterisations=() if characterisation is None else (characterisation,),
    )


def results_directory(
    config: ExperimentConfig, out_dir: str | Path, info: TaskInfo
) -> ResultsDirectory:
    """The run's output directory; its weight columns name the dimensions of the
    characterisation the treatment weights (the SDBC's for the paper's)."""
    characterisation = config.treatment.characterisation
    weight_names = (
        info.names_of(characterisation.key)
        if config.treatment.weights and characterisation is not None
        else info.sdbc_names
    )
    return ResultsDirectory(out_dir, info.sdbc_names, weight_names)


class Experiment:
    """One run of one treatment on one task; use :meth:`create` or :meth:`resume`.

    Args:
        config: The resolved configuration.
        evaluator: Where trials run.
        info: The task's sizes and SDBC dimension names.
        search: The GA's state before the next generation: the ask/tell object
            (population, archive, weights, the GA's generator).
        reevaluation_rng: The generator of re-evaluation trial seeds.
        results: The output directory.
        lock: The held lock of the output directory; :meth:`close` (or the end
            of a ``with`` block, or the process) releases it.
    """

    def __init__(
        self,
        config: ExperimentConfig,
        evaluator: Evaluator,
        info: TaskInfo,
        search: NoveltySearch,
        reevaluation_rng: np.random.Generator,
        results: ResultsDirectory,
        lock: RunLock,
    ) -> None:
        self.config = config
        self.evaluator = evaluator
        self.info = info
        self.search = search
        self.reevaluation_rng = reevaluation_rng
        self.results = results
        self.lock = lock
        self.timings: dict[str, float] = {}
        self._next: Evaluation | None = None
        """The next generation's evaluation, run beside this one's re-evaluation."""

    def close(self) -> None:
        """Releases the output directory to other writers."""
        self.lock.release()

    def __enter__(self) -> Experiment:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def state(self) -> NoveltySearch:
        """The GA's state (generation, population, archive, weights, generator):
        :attr:`search`, under the name callers know."""
        return self.search

    @property
    def generations(self) -> int:
        """Generations the run is configured to reach."""
        return self.config.resolved_generations

    @property
    def finished(self) -> bool:
        """Whether every generation of the run has been done."""
        return self.search.generation >= self.generations

    @classmethod
    def create(
        cls,
        config: ExperimentConfig,
        out_dir: str | Path,
        evaluator: Evaluator,
        info: TaskInfo | None = None,
        lock: RunLock | None = None,
    ) -> Experiment:
        """Starts a new run in ``out_dir``, which must not hold one already, and
        writes its generation-0 checkpoint (so it resumes from the start).

        Args:
            lock: The directory's lock if the caller holds it already.

        Raises:
            RunBusy: Another process writes ``out_dir``.
            ExperimentError: ``out_dir`` holds a run.
        """
        config = config.resolved()
        info = info or TaskInfo.of(task_spec(config))
        results = results_directory(config, out_dir, info)
        lock = _locked(out_dir, lock)
        if results.holds_a_run():
            lock.release()
            raise ExperimentError(
                f"{results.path} already holds a run: resume it (--resume) or choose "
                "another output directory"
            )
        ga_rng, reevaluation_rng = run_generators(config.seed)
        search = _search(config, info, ga_rng)
        experiment = cls(
            config, evaluator, info, search, reevaluation_rng, results, lock
        )
        try:
            results.create(dump_config(config))
            save_checkpoint(results.checkpoint_path, experiment._checkpoint())
        except BaseException:
            lock.release()
            raise
        return experiment

    @classmethod
    def resume(
        cls,
        config: ExperimentConfig,
        out_dir: str | Path,
        evaluator: Evaluator,
        info: TaskInfo | None = None,
        lock: RunLock | None = None,
    ) -> Experiment:
        """Continues the run in ``out_dir`` from its checkpoint.

        Args:
            lock: The directory's lock if the caller holds it already.

        Raises:
            RunBusy: Another process writes ``out_dir``.
            CheckpointError: The checkpoint is missing, corrupt, or from another
                task or configuration (``generations`` may change), or an output
                it vouches for is missing or damaged (named). Nothing in
                ``out_dir`` is touched then.
        """
        config = config.resolved()
        info = info or TaskInfo.of(task_spec(config))
        results = results_directory(config, out_dir, info)
        if not Path(out_dir).is_dir():
            raise CheckpointError(f"no run at {out_dir}: nothing to resume")
        lock = _locked(out_dir, lock)
        try:
            experiment = cls._resume(config, info, results, evaluator, lock)
        except BaseException:
            lock.release()
            raise
        return experiment

    @classmethod
    def _resume(
        cls,
        config: ExperimentConfig,
        info: TaskInfo,
        results: ResultsDirectory,
        evaluator: Evaluator,
        lock: RunLock,
    ) -> Experiment:
        checkpoint = load_checkpoint(results.checkpoint_path, config.to_dict())
        n = config.ga.population_size
        if checkpoint.population.shape != (n, info.genome_length):
            raise CheckpointError(
                f"checkpoint {results.checkpoint_path}: population of shape "
                f"{checkpoint.population.shape}, this task and configuration need "
                f"({n}, {info.genome_length})"
            )
        if checkpoint.generation > config.resolved_generations:
            raise CheckpointError(
                f"checkpoint {results.checkpoint_path} is after generation "
                f"{checkpoint.generation}, beyond generations="
                f"{config.resolved_generations}"
            )
        try:
            results.verify(checkpoint.generation, n)
        except RunDamaged as error:
            raise CheckpointError(f"cannot resume: {error}") from None
        try:
            results.truncate(checkpoint.generation)
        except (OSError, ValueError) as error:
            raise CheckpointError(f"cannot resume in {results.path}: {error}") from None
        # The checkpoint was checked against the configuration: its state is
        # the search's, without the best so far (the run's outputs keep that).
        search = _search(config, info, config.seed)
        try:
            search.load_state_dict(
                {
                    "generation": np.array(checkpoint.generation),
                    "population": checkpoint.population,
                    "parent": checkpoint.parent,
                    "elite": checkpoint.elite,
                    "archive_behaviours": checkpoint.archive_behaviours,
                    "archive_fitness": checkpoint.archive_fitness,
                    "archive_generation": checkpoint.archive_generation,
                    "weights": np.zeros(0)
                    if checkpoint.weights is None
                    else checkpoint.weights,
                    "has_weights": np.array(checkpoint.weights is not None),
                    "rng": np.array(json.dumps(checkpoint.ga_rng)),
                }
            )
        except ValueError as error:
            raise CheckpointError(
                f"checkpoint {results.checkpoint_path}: {error}"
            ) from None
        reevaluation_rng = generator_from_state(checkpoint.reevaluation_rng)
        results.write_config(dump_config(config))
        return cls(config, evaluator, info, search, reevaluation_rng, results, lock)

    def run(
        self, on_generation: Callable[[GenerationRecord], None] | None = None
    ) -> None:
        """Runs generations until the configured number is reached."""
        while not self.finished:
            record = self.step()
            if on_generation is not None:
                on_generation(record)

    def step(self) -> GenerationRecord:
        """Runs one generation, writes its outputs and the checkpoint.

        Afterwards :attr:`timings` holds the seconds each phase took: "evaluation"
        (the population's trials), "scoring" (standardisation, weights, novelty,
        archive, ranking), "breeding", "reevaluation", "outputs" and "checkpoint".
        """
        config, search = self.config, self.search
        clock = _PhaseClock()
        g = search.generation
        population, parent, elite = search.population, search.parent, search.elite
        n = population.shape[0]
        evaluation, self._next = self._next, None
        if evaluation is None:
            seeds = search.trial_seeds(config.evaluation.trials)
            evaluation = self.evaluator.evaluate(population, seeds)
        self._check_evaluation(evaluation, n)
        clock.lap("evaluation")
        scores = search.score(evaluation.fitness, evaluation.behaviours)
        clock.lap("scoring")
        search.breed()
        clock.lap("breeding")
        best = int(np.argmax(evaluation.fitness))
        ga_rng = dict(search.rng.bit_generator.state)
        reevaluated_fitness, reevaluated_mean = self._reevaluate(
            population[best], with_next=g + 1 < self.generations
        )
        clock.lap("reevaluation")
        record = GenerationRecord(
            generation=g,
            best_fitness=float(evaluation.fitness[best]),
            mean_fitness=float(evaluation.fitness.mean()),
            median_fitness=float(np.median(evaluation.fitness)),
            best_index=best,
            best_novelty=float(np.max(scores.novelty)),
            archive_size=len(search.archive),
            reevaluated_fitness=reevaluated_fitness,
            reevaluated_mean=reevaluated_mean,
            wall_time=clock.total(),
            evaluation_time=clock.phases["evaluation"] + clock.phases["reevaluation"],
            weights=scores.weights,
        )
        individuals = self._individuals(evaluation, scores, parent, elite)
        self.results.append_generation(record, individuals, population[best])
        clock.lap("outputs")
        save_checkpoint(self.results.checkpoint_path, self._checkpoint(ga_rng))
        clock.lap("checkpoint")
        self.timings = clock.phases
        return record

    def _check_evaluation(self, evaluation: Evaluation, n: int) -> None:
        if evaluation.fitness.shape != (n,):
            raise ExperimentError(
                f"the evaluator returned fitness {evaluation.fitness.shape} for {n} "
                "genomes"
            )
        keys = {SDBC}
        if self._behaviour_key is not None:
            keys.add(self._behaviour_key)
        for key in sorted(keys):
            d = len(self.info.names_of(key))
            got = evaluation.behaviour(key).shape
            if got != (n, d):
                raise ExperimentError(
                    f"the evaluator returned characterisation {key!r} of shape {got} "
                    f"for {n} genomes and {d} dimensions"
                )
        if not np.isfinite(evaluation.fitness).all():
            raise ExperimentError("the evaluator returned NaN or infinite fitness")

    def _reevaluate(self, genome: np.ndarray, with_next: bool) -> tuple[float, float]:
        """The best's fitness and mean over fresh trials; ``with_next``: the next
        generation's population is evaluated in the same batch (step 5 of the
        module docstring)."""
        trials = self.config.evaluation.reevaluation_trials
        if trials == 0:
            return float("nan"), float("nan")
        seeds = self.reevaluation_rng.integers(
            0, TRIAL_SEED_BOUND, size=(trials, 1), dtype=np.int64
        )
        # One row per trial lets the evaluator spread the trials over its workers;
        # a trial's result does not depend on its batch-mates.
        request = (np.repeat(genome[None], trials, 0), seeds)
        if with_next:
            search = self.search
            upcoming = (
                search.population,
                search.trial_seeds(self.config.evaluation.trials),
            )
            self._next, evaluation = self.evaluator.evaluate_together(
                [upcoming, request]
            )
        else:
            evaluation = self.evaluator.evaluate(*request)
        trial_fitness = evaluation.trial_fitness.reshape(1, trials)
        fitness = controller_fitness(trial_fitness, self.config.evaluation.fitness_mean)
        return float(fitness[0]), float(trial_fitness.mean())

    @property
    def _behaviour_key(self) -> str | None:
        characterisation = self.config.treatment.characterisation
        return None if characterisation is None else characterisation.key

    def _individuals(
        self,
        evaluation: Evaluation,
        scores: GenerationScores,
        parent: np.ndarray,
        elite: np.ndarray,
    ) -> dict[str, np.ndarray]:
        extra = {}
        key = self._behaviour_key
        if key not in (None, SDBC, TASK):
            # A characterisation of the treatment's own: kept beside the paper's.
            extra = {
                "behaviour": evaluation.behaviour(key).astype(np.float32),
                "behaviour_names": np.array(self.info.names_of(key)),
            }
        return {
            "fitness": evaluation.fitness,
            "trial_fitness": evaluation.trial_fitness.astype(np.float32),
            "characterisation": evaluation.characterisation.astype(np.float32),
            "sdbc": evaluation.sdbc.astype(np.float32),
            "novelty": scores.novelty,
            "front": scores.front.astype(np.int16),
            "rank": positions(scores.order).astype(np.int32),
            "archived": scores.archived,
            "parent": parent.astype(np.int32),
            "elite": elite,
            **extra,
        }

    def _checkpoint(self, ga_rng: dict[str, Any] | None = None) -> Checkpoint:
        """The run's state; ``ga_rng``: the GA generator's state to record, when
        it has drawn since for a generation not yet taken (step 5)."""
        state = self.search
        return Checkpoint(
            generation=state.generation,
            config=self.config.to_dict(),
            population=state.population,
            parent=state.parent,
            elite=state.elite,
            archive_behaviours=state.archive.behaviours,
            archive_fitness=state.archive.fitness,
            archive_generation=state.archive.generation,
            weights=state.weights,
            ga_rng=dict(state.rng.bit_generator.state) if ga_rng is None else ga_rng,
            reevaluation_rng=dict(self.reevaluation_rng.bit_generator.state),
        )


def _search(
    config: ExperimentConfig, info: TaskInfo, seed: int | np.random.Generator
) -> NoveltySearch:
    """The ask/tell object of a run of ``config``."""
    return NoveltySearch(
        config.treatment,
        genome_length=info.genome_length,
        seed=seed,
        ga=config.ga,
        novelty=config.novelty,
        standardisation=config.standardisation,
        weighting=config.weighting,
        fitness_mean=config.evaluation.fitness_mean,
    )
