"""One object in front of the method: novelty search as ask/tell.

:class:`NoveltySearch` owns a population, the novelty archive, the NS-SD+ weights
and the GA's generator; the caller evaluates. One generation::

    search = NoveltySearch("ns-sd+", genome_length=W, population=N, seed=0,
                           task=description)
    genomes = search.ask()                       # (N, W)
    fitness, states = my_simulation(genomes)     # (N,) or (N, T); task states
    search.tell(fitness, states)                 # scores, archives, breeds

``tell`` takes the behaviours in one of three forms:

- the task states of every controller's trials: a sequence over steps of
  :class:`~sdbc_sim.task_state.TaskState`, each a batch of B = N T trials laid out
  controller-major (trial b is controller ``b // T``'s), as the engine steps
  them; the search extracts the treatment's SDBC itself (it needs ``task``, the
  task description) and averages each controller's trials;
- one (N, D) array: the raw vectors of the treatment's characterisation;
- a mapping from characterisation key (:attr:`NoveltySearch.behaviour_key`;
  ``"sdbc"`` for the paper's) to (N, D) arrays; other keys are ignored.

Fitness is (N,) per controller, or (N, T) per trial, which is summed up per
controller with ``fitness_mean`` (harmonic by default, as the engine does).
Fitness and vectors of any real dtype are converted to float64 (exact for
float16 and float32); task states are checked as the extractor checks them.

The GA is the paper's: ask/tell breeds the next population itself (elites,
tournaments on the treatment's order, bounded Gaussian mutation;
:mod:`.breeding`). With a GA of one's own, call :meth:`NoveltySearch.score`
instead of ask/tell: it scores any generation (novelty, archive, weights,
ranking) and breeds nothing; use one way or the other on one search.

Random numbers all come from the GA's generator, in sdbc-evolve's order: the
initial population when the search is made; per generation, the caller's trial
seeds if it draws them with :meth:`NoveltySearch.trial_seeds` (between ask and
tell), then the treatment's draws (a weight update, the archive), then breeding.
``seed=s`` makes the generator sdbc-evolve's run of seed s makes, so the search
over the engine repeats that run. :meth:`NoveltySearch.state_dict` is the whole
state as arrays (``np.savez`` writes it); :meth:`NoveltySearch.load_state_dict`
restores it, after which the search goes on bit for bit as if never stopped.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from sdbc_sim.fitness import FITNESS_MEANS, controller_fitness
from sdbc_sim.limits import excerpt
from sdbc_sim.settings import to_plain
from sdbc_sim.task_state import TaskDescription, TaskState

from sdbc_evolution.characterise.evaluation import SDBC, Evaluation
from sdbc_evolution.ga.archive import NoveltyArchive
from sdbc_evolution.ga.breeding import GaConfig, breed, initial_population
from sdbc_evolution.ga.novelty import NoveltyConfig
from sdbc_evolution.ga.treatments import (
    GenerationScores,
    TreatmentSpec,
    parse_treatment,
    score_generation,
)
from sdbc_evolution.sdbc.standardise import StandardisationSettings
from sdbc_evolution.sdbc.weighting import WeightingSettings

TRIAL_SEED_BOUND = 2**63 - 1
"""Trial seeds are drawn uniformly from [0, 2^63 - 1)."""
STATE_ARRAYS = (
    "generation",
    "population",
    "parent",
    "elite",
    "archive_behaviours",
    "archive_fitness",
    "archive_generation",
    "weights",
    "has_weights",
    "rng",
)
"""Keys every :meth:`NoveltySearch.state_dict` holds."""
BEST_ARRAYS = ("best_genome", "best_fitness", "best_generation")
"""Keys of the best so far, in a state that has one."""

Behaviours = np.ndarray | Mapping[str, np.ndarray] | Sequence[TaskState] | None
"""What :meth:`NoveltySearch.tell` takes as a generation's behaviours."""


def run_generators(seed: int) -> tuple[np.random.Generator, np.random.Generator]:
    """The GA's generator and the re-evaluation generator of sdbc-evolve's run of
    ``seed``: the two children of ``np.random.SeedSequence(seed)``."""
    ga_seed, reevaluation_seed = np.random.SeedSequence(seed).spawn(2)
    return np.random.default_rng(ga_seed), np.random.default_rng(reevaluation_seed)


@dataclass(frozen=True, eq=False)
class BestSoFar:
    """The fittest controller told so far (by the fitness told, not re-evaluated).

    Attributes:
        genome: (W,) its genes.
        fitness: Its fitness.
        generation: The generation it was told in (0-based).
    """

    genome: np.ndarray
    fitness: float
    generation: int


def _real(value: Any, what: str) -> np.ndarray:
    """``value`` as float64, refusing what is not an array of real numbers."""
    array = np.asarray(value)
    kind = array.dtype
    if kind == np.bool_ or not (
        np.issubdtype(kind, np.floating) or np.issubdtype(kind, np.integer)
    ):
        raise ValueError(f"{what} has dtype {array.dtype}, expected real numbers")
    return array.astype(np.float64)


class NoveltySearch:
    """Novelty search with a treatment's characterisation, as ask/tell.

    Args:
        treatment: A preset's name (``"ns-sd+"``, ``"ns-sd"``, ``"ns-ts"``,
            ``"fit"``), a declaration mapping or a :class:`TreatmentSpec`.
        genome_length: W, genes per genome.
        population: N, genomes per generation (default: ``ga``'s, 200).
        seed: The run's seed (as sdbc-evolve's), or the GA's generator itself.
        task: The task description, needed to tell task states.
        ga: The GA's settings (default: the paper's).
        novelty: Novelty and archive settings (default: the paper's).
        standardisation: Standardisation settings (default: the paper's).
        weighting: NS-SD+ weighting settings (default: the paper's).
        fitness_mean: How (N, T) trial fitness is summed up per controller:
            ``"harmonic"`` or ``"arithmetic"``.

    Raises:
        SettingsError: A bad treatment or setting, naming it.
        ValueError: A bad size, seed or fitness mean.
    """

    def __init__(
        self,
        treatment: str | Mapping[str, Any] | TreatmentSpec = "ns-sd+",
        *,
        genome_length: int,
        population: int | None = None,
        seed: int | np.random.Generator = 0,
        task: TaskDescription | None = None,
        ga: GaConfig | None = None,
        novelty: NoveltyConfig | None = None,
        standardisation: StandardisationSettings | None = None,
        weighting: WeightingSettings | None = None,
        fitness_mean: str = "harmonic",
    ) -> None:
        self.treatment = parse_treatment(
            dict(treatment) if isinstance(treatment, Mapping) else treatment,
            "treatment",
        )
        if isinstance(genome_length, bool) or not isinstance(genome_length, int):
            raise ValueError(
                f"genome_length must be an integer, got {excerpt(genome_length)}"
            )
        if genome_length < 1:
            raise ValueError(f"genome_length must be at least 1, got {genome_length}")
        ga = ga or GaConfig()
        if population is not None:
            ga = dataclasses.replace(ga, population_size=population)
        if fitness_mean not in FITNESS_MEANS:
            raise ValueError(
                f"fitness_mean {fitness_mean!r}: known {', '.join(FITNESS_MEANS)}"
            )
        if task is not None and not isinstance(task, TaskDescription):
            raise ValueError(f"task must be a TaskDescription, got {excerpt(task)}")
        self.genome_length = genome_length
        self.task = task
        self.ga = ga
        self.novelty = novelty or NoveltyConfig()
        self.standardisation = standardisation or StandardisationSettings()
        self.weighting = weighting or WeightingSettings()
        self.fitness_mean = fitness_mean
        if isinstance(seed, np.random.Generator):
            self.rng = seed
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            self.rng = run_generators(int(seed))[0]
        else:
            raise ValueError(
                f"seed must be an integer or a Generator, got {excerpt(seed)}"
            )
        n = ga.population_size
        self.generation = 0
        """Generations told so far (the index of the next one)."""
        self.population = initial_population(ga, genome_length, self.rng)
        """(N, W) the genomes :meth:`ask` gives."""
        self.parent = np.full(n, -1, dtype=np.int64)
        """(N,) index in the previous generation each came from (-1: none)."""
        self.elite = np.zeros(n, dtype=bool)
        """(N,) copied unchanged from the previous generation."""
        self.archive = NoveltyArchive(
            capacity=self.novelty.archive_size,
            probability=self.novelty.archive_probability,
        )
        self.weights: np.ndarray | None = None
        """(D,) NS-SD+ weights in force, or None."""
        self.scores: GenerationScores | None = None
        """How the last generation told was scored (order, novelty, front,
        weights, archived), or None before the first."""
        self.best: BestSoFar | None = None
        """The fittest controller told so far, or None."""
        self._unbred = False

    # --- ask/tell ---------------------------------------------------------------

    @property
    def population_size(self) -> int:
        """N."""
        return self.ga.population_size

    @property
    def behaviour_key(self) -> str | None:
        """The key of the treatment's characterisation in a mapping of
        behaviours (``"sdbc"`` for the paper's SDBC); None for fitness only."""
        spec = self.treatment.characterisation
        return None if spec is None else spec.key

    def ask(self) -> np.ndarray:
        """(N, W) the genomes to evaluate next (the same until :meth:`tell`)."""
        return self.population.copy()

    def trial_seeds(self, trials: int) -> np.ndarray:
        """(N, T) int64 trial seeds from the GA's generator, fresh at every call;
        sdbc-evolve draws them between ask and tell, for the engine's trials."""
        if isinstance(trials, bool) or not isinstance(trials, int) or trials < 1:
            raise ValueError(
                f"trials must be a positive integer, got {excerpt(trials)}"
            )
        return self.rng.integers(
            0, TRIAL_SEED_BOUND, size=(self.population_size, trials), dtype=np.int64
        )

    def tell(self, fitness: Any, behaviours: Behaviours = None) -> GenerationScores:
        """Scores the genomes of the last :meth:`ask` and breeds the next ones.

        Args:
            fitness: (N,) or (N, T) fitness of the genomes :meth:`ask` gave.
            behaviours: Their behaviours (module docstring); None only for a
                treatment without characterisation (``fit``).

        Returns:
            How the generation was scored (also :attr:`scores`).

        Raises:
            ValueError: Shapes, dtypes or values that do not fit, named.
        """
        scores = self.score(fitness, behaviours)
        self.breed()
        return scores

    def breed(self) -> None:
        """Replaces the population by the next generation, bred on the order of
        the generation :meth:`score` scored last (:meth:`tell` does both).

        Raises:
            RuntimeError: No generation was scored since the last breeding.
        """
        if self.scores is None or not self._unbred:
            raise RuntimeError("breed() needs a generation scored by score() first")
        self.population, self.parent, self.elite = breed(
            self.population, self.scores.order, self.ga, self.rng
        )
        self._unbred = False

    def score(self, fitness: Any, behaviours: Behaviours = None) -> GenerationScores:
        """Scores a generation of N controllers (novelty against population and
        archive, archive update, weights, ranking) without breeding: for a GA of
        one's own. :meth:`tell` is this, then breeding."""
        evaluation = self.evaluation(fitness, behaviours)
        scores = score_generation(
            self.treatment,
            evaluation,
            self.archive,
            self.weights,
            self.generation,
            self.rng,
            self.novelty,
            self.standardisation,
            self.weighting,
        )
        best = int(np.argmax(evaluation.fitness))
        if self.best is None or evaluation.fitness[best] > self.best.fitness:
            self.best = BestSoFar(
                self.population[best].copy(),
                float(evaluation.fitness[best]),
                self.generation,
            )
        self.weights = scores.weights
        self.scores = scores
        self._unbred = True
        self.generation += 1
        return scores

    # --- checking what is told ----------------------------------------------------

    def evaluation(self, fitness: Any, behaviours: Behaviours = None) -> Evaluation:
        """What :meth:`tell` scores: fitness and behaviours checked and in the
        engine's form (behaviours keyed by characterisation)."""
        n = self.population_size
        values = _real(fitness, "fitness")
        if values.ndim == 1:
            values = values[:, None]
        if values.ndim != 2 or values.shape[0] != n or values.shape[1] < 1:
            raise ValueError(
                f"fitness has shape {np.shape(fitness)}, expected ({n},) or ({n}, T)"
            )
        if not np.isfinite(values).all():
            raise ValueError("fitness holds NaN or infinite values")
        controller = (
            values[:, 0]
            if values.shape[1] == 1
            else controller_fitness(values, self.fitness_mean)
        )
        return Evaluation(
            fitness=controller,
            trial_fitness=values,
            behaviours=self._behaviours(behaviours),
        )

    def _behaviours(self, behaviours: Behaviours) -> dict[str, np.ndarray]:
        key = self.behaviour_key
        if key is None:
            return {} if behaviours is None else self._named(behaviours)
        if behaviours is None:
            raise ValueError(
                f"treatment {self.treatment.name!r} compares behaviours: tell them "
                f"(an (N, D) array, a mapping with key {key!r}, or task states)"
            )
        named = self._named(behaviours)
        if key not in named:
            raise ValueError(
                f"behaviours have keys {sorted(named)}; treatment "
                f"{self.treatment.name!r} needs {key!r}"
            )
        vectors = named[key]
        n = self.population_size
        if vectors.ndim != 2 or vectors.shape[0] != n or vectors.shape[1] < 1:
            raise ValueError(
                f"behaviours {key!r} have shape {vectors.shape}, expected ({n}, D)"
            )
        d = self.archive.behaviours.shape[1] if len(self.archive) else None
        if d is not None and vectors.shape[1] != d:
            raise ValueError(
                f"behaviours {key!r} have {vectors.shape[1]} dimensions, the archive's "
                f"{d}"
            )
        if not np.isfinite(vectors).all():
            row = int(np.flatnonzero(~np.isfinite(vectors).all(axis=1))[0])
            raise ValueError(
                f"behaviours {key!r} of controller {row} hold NaN or infinite values"
            )
        return named

    def _named(self, behaviours: Behaviours) -> dict[str, np.ndarray]:
        if isinstance(behaviours, Mapping):
            named = behaviours.items()
            return {str(k): _real(v, f"behaviours {k!r}") for k, v in named}
        if isinstance(behaviours, np.ndarray):
            key = self.behaviour_key or SDBC
            return {key: _real(behaviours, "behaviours")}
        if isinstance(behaviours, Sequence) and all(
            isinstance(s, TaskState) for s in behaviours
        ):
            return {self.behaviour_key or SDBC: self._from_states(behaviours)}
        raise ValueError(
            "behaviours must be an (N, D) array, a mapping of them, or a sequence "
            f"of TaskState, got {type(behaviours).__name__}"
        )

    def _from_states(self, states: Sequence[TaskState]) -> np.ndarray:
        """(N, D) the treatment's SDBC of every controller, from the task states of
        its trials (B = N T, controller-major)."""
        spec = self.treatment.characterisation
        if spec is None or spec.kind != SDBC:
            raise ValueError(
                f"treatment {self.treatment.name!r} compares "
                f"{'nothing' if spec is None else spec.key!r}, which task states do "
                "not give: tell its (N, D) vectors"
            )
        if self.task is None:
            raise ValueError(
                "task states need the task description: NoveltySearch(..., task=...)"
            )
        if not states:
            raise ValueError("no task states: tell at least one step")
        n = self.population_size
        batch = int(np.shape(states[0].active)[0]) if states[0].active.ndim else 0
        if batch < n or batch % n:
            raise ValueError(
                f"task states of {batch} trials for {n} controllers: a batch holds "
                "N T trials, controller-major"
            )
        characteriser = spec.build()
        characteriser.start(self.task, batch)
        for state in states:
            characteriser.observe(state)
        return characteriser.controller_vectors(None, batch // n)

    # --- state --------------------------------------------------------------------

    def settings(self) -> dict[str, Any]:
        """Everything the search was made with but the seed, as plain data."""
        return {
            "treatment": self.treatment.to_mapping(),
            "genome_length": self.genome_length,
            "ga": to_plain(self.ga),
            "novelty": to_plain(self.novelty),
            "standardisation": to_plain(self.standardisation),
            "weighting": to_plain(self.weighting),
            "fitness_mean": self.fitness_mean,
        }

    def state_dict(self) -> dict[str, np.ndarray]:
        """The whole state between two generations, as arrays (``np.savez(path,
        **search.state_dict())`` writes it): population, its parents and elites,
        the archive, the weights, the best so far, the generator's state and the
        settings (both as JSON text)."""
        state = {
            "generation": np.array(self.generation),
            "population": self.population.copy(),
            "parent": self.parent.copy(),
            "elite": self.elite.copy(),
            "archive_behaviours": self.archive.behaviours.copy(),
            "archive_fitness": self.archive.fitness.copy(),
            "archive_generation": self.archive.generation.copy(),
            "weights": np.zeros(0) if self.weights is None else self.weights.copy(),
            "has_weights": np.array(self.weights is not None),
            "rng": np.array(json.dumps(self.rng.bit_generator.state)),
            "settings": np.array(json.dumps(self.settings(), sort_keys=True)),
        }
        if self.best is not None:
            state["best_genome"] = self.best.genome.copy()
            state["best_fitness"] = np.array(self.best.fitness)
            state["best_generation"] = np.array(self.best.generation)
        return state

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restores a :meth:`state_dict` (or what ``np.load`` read of one) into a
        search made with the same settings; it goes on as the saved one would.

        A state without ``settings`` or the best so far (as an sdbc-evolve
        checkpoint gives) restores without those checks or without a best.

        Raises:
            ValueError: Missing or inconsistent arrays, or other settings, named.
        """
        missing = [k for k in STATE_ARRAYS if k not in state]
        if missing:
            raise ValueError(f"search state lacks {missing}")
        if "settings" in state:
            saved = json.loads(str(state["settings"]))
            mine = json.loads(json.dumps(self.settings(), sort_keys=True))
            keys = set(saved) | set(mine)
            differ = sorted(k for k in keys if saved.get(k) != mine.get(k))
            if differ:
                raise ValueError(
                    f"search state was saved with other settings: {', '.join(differ)}"
                )
        n, w = self.population_size, self.genome_length
        population = np.asarray(state["population"], dtype=np.float64)
        parent = np.asarray(state["parent"]).astype(np.int64)
        elite = np.asarray(state["elite"]).astype(bool)
        if population.shape != (n, w) or parent.shape != (n,) or elite.shape != (n,):
            raise ValueError(
                f"search state holds a population of shape {population.shape}, this "
                f"search's is ({n}, {w})"
            )
        archive = NoveltyArchive(
            capacity=self.novelty.archive_size,
            probability=self.novelty.archive_probability,
            behaviours=np.asarray(state["archive_behaviours"]),
            fitness=np.asarray(state["archive_fitness"]),
            generation=np.asarray(state["archive_generation"]),
        )
        try:
            rng = generator_from_state(json.loads(str(state["rng"])))
        except ValueError as error:
            raise ValueError(f"search state: bad generator state ({error})") from None
        best = None
        if all(k in state for k in BEST_ARRAYS):
            genome = np.asarray(state["best_genome"], dtype=np.float64)
            if genome.shape != (w,):
                raise ValueError(f"search state's best genome has shape {genome.shape}")
            best = BestSoFar(
                genome, float(state["best_fitness"]), int(state["best_generation"])
            )
        self.generation = int(state["generation"])
        self.population, self.parent, self.elite = population, parent, elite
        self.archive = archive
        self.weights = (
            np.asarray(state["weights"], dtype=np.float64)
            if bool(state["has_weights"])
            else None
        )
        self.rng = rng
        self.best = best
        self.scores = None
        self._unbred = False


BIT_GENERATORS = ("PCG64", "PCG64DXSM", "Philox", "SFC64", "MT19937")
"""numpy bit generators a saved state may name."""


def generator_from_state(state: Any) -> np.random.Generator:
    """A generator restored to a saved ``bit_generator.state``.

    Raises:
        ValueError: Not the state of one of :data:`BIT_GENERATORS`.
    """
    try:
        name = state["bit_generator"]
        if name not in BIT_GENERATORS:
            raise ValueError(f"unknown bit generator {name!r}")
        bit_generator = getattr(np.random, name)()
        bit_generator.state = state
    except (AttributeError, KeyError, TypeError, ValueError) as error:
        raise ValueError(str(error)) from None
    return np.random.Generator(bit_generator)
