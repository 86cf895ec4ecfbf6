"""The ask/tell object: what it takes, what it keeps, and that a restored search
goes on bit for bit."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from sdbc_evolution.characterise.evaluation import Evaluation
from sdbc_evolution.ga.archive import NoveltyArchive
from sdbc_evolution.ga.breeding import GaConfig
from sdbc_evolution.ga.novelty import NoveltyConfig
from sdbc_evolution.ga.search import NoveltySearch, run_generators
from sdbc_evolution.ga.treatments import PRESETS, score_generation
from sdbc_evolution.sdbc.characterisation import SdbcExtractor
from sdbc_evolution.sdbc.standardise import StandardisationSettings
from sdbc_evolution.sdbc.weighting import WeightingSettings
from sdbc_sim.fitness import controller_fitness
from sdbc_sim.settings import SettingsError
from sdbc_sim.task_state import (
    EntityGroupSpec,
    Geometry,
    GroupState,
    TaskDescription,
    TaskState,
)

N, W, T = 12, 4, 2
POINT = {"attributes": (), "min_size": 1, "max_size": 1, "geometry": Geometry.POINT}
TASK = TaskDescription(
    "walk",
    (
        EntityGroupSpec(name="Robot", static=False, **POINT),
        EntityGroupSpec(name="Home", static=True, **POINT),
    ),
)


def simulate(genomes: np.ndarray, trials: int) -> tuple[np.ndarray, list[TaskState]]:
    """(N, T) fitness and the task states of N T trials, controller-major: a robot
    walks 20 steps with a velocity its genes set."""
    batch = np.repeat(genomes, trials, axis=0)
    start = np.tile(np.linspace(-1.0, 1.0, trials)[:, None], (genomes.shape[0], 2))
    x, states = start.copy(), []
    home = GroupState(np.ones((1, 1), bool), np.zeros((1, 1, 0)), np.zeros((1, 1, 2)))
    for step in range(1, 21):
        x = x + 0.1 * np.tanh(batch[:, :2] * x + batch[:, 2:])
        robot = GroupState(np.ones((1, 1), bool), np.zeros((1, 1, 0)), x[:, None])
        states.append(TaskState(step, np.ones(batch.shape[0], bool), (robot, home)))
    fitness = 1.0 / (1.0 + np.hypot(*x.T))
    return fitness.reshape(genomes.shape[0], trials), states


def raw_sdbc(states: list[TaskState], trials: int) -> np.ndarray:
    extractor = SdbcExtractor()
    extractor.start(TASK, states[0].active.shape[0])
    for state in states:
        extractor.observe(state)
    vectors = extractor.characterisations()
    return vectors.reshape(-1, trials, vectors.shape[1]).mean(axis=1)


def make(**changes: object) -> NoveltySearch:
    settings: dict[str, object] = {
        "genome_length": W,
        "population": N,
        "seed": 3,
        "task": TASK,
        "ga": GaConfig(tournament_size=3, elites=2),
        "novelty": NoveltyConfig(k=3, archive_probability=0.3),
    }
    settings.update(changes)
    return NoveltySearch("ns-sd+", **settings)  # type: ignore[arg-type]


def run(search: NoveltySearch, generations: int) -> list[np.ndarray]:
    told = []
    for _ in range(generations):
        genomes = search.ask()
        fitness, states = simulate(genomes, T)
        search.tell(fitness, states)
        told.append(genomes)
    return told


def test_ask_gives_the_population_until_tell() -> None:
    search = make()
    first = search.ask()
    assert first.shape == (N, W) and first.dtype == np.float64
    assert ((first >= -1) & (first <= 1)).all()
    np.testing.assert_array_equal(search.ask(), first)
    fitness, states = simulate(first, T)
    scores = search.tell(fitness, states)
    assert search.generation == 1
    assert sorted(scores.order.tolist()) == list(range(N))
    assert scores.novelty.shape == (N,) and scores.weights is not None
    assert not np.array_equal(search.ask(), first)
    # The elites of the order are the next generation's first genomes.
    np.testing.assert_array_equal(search.ask()[:2], first[scores.order[:2]])
    assert search.elite.tolist() == [True, True] + [False] * (N - 2)


def test_task_states_arrays_and_mappings_give_the_same_search() -> None:
    by_states, by_array, by_mapping = make(), make(), make()
    for _ in range(3):
        genomes = by_states.ask()
        fitness, states = simulate(genomes, T)
        vectors = raw_sdbc(states, T)
        a = by_states.tell(fitness, states)
        b = by_array.tell(fitness, vectors)
        c = by_mapping.tell(fitness, {"sdbc": vectors, "other": np.zeros((N, 1))})
        for other in (b, c):
            np.testing.assert_array_equal(a.order, other.order)
            np.testing.assert_array_equal(a.novelty, other.novelty)
    for other in (by_array, by_mapping):
        np.testing.assert_array_equal(by_states.ask(), other.ask())
        np.testing.assert_array_equal(
            by_states.archive.behaviours, other.archive.behaviours
        )


def test_trial_fitness_is_summed_up_as_the_engine_does() -> None:
    harmonic, arithmetic = make(), make(fitness_mean="arithmetic")
    fitness, states = simulate(harmonic.ask(), T)
    harmonic.tell(fitness, states)
    arithmetic.tell(fitness, states)
    assert harmonic.best is not None and arithmetic.best is not None
    assert harmonic.best.fitness == controller_fitness(fitness).max()
    assert arithmetic.best.fitness == fitness.mean(axis=1).max()


def test_it_scores_as_score_generation_does() -> None:
    """ask/tell is the paper's generation: the same draws as the parts it is
    made of, in sdbc-evolve's order."""
    search = make()
    rng = run_generators(3)[0]
    ga = GaConfig(tournament_size=3, elites=2, population_size=N)
    population = rng.uniform(ga.gene_min, ga.gene_max, (N, W))
    np.testing.assert_array_equal(search.ask(), population)
    seeds = search.trial_seeds(T)
    assert seeds.shape == (N, T) and seeds.dtype == np.int64
    expected_seeds = rng.integers(0, 2**63 - 1, size=(N, T), dtype=np.int64)
    np.testing.assert_array_equal(seeds, expected_seeds)
    fitness, states = simulate(population, T)
    vectors = raw_sdbc(states, T)
    archive = NoveltyArchive(capacity=1000, probability=0.3)
    expected = score_generation(
        PRESETS["ns-sd+"],
        Evaluation(controller_fitness(fitness), fitness, {"sdbc": vectors}),
        archive,
        None,
        0,
        rng,
        NoveltyConfig(k=3, archive_probability=0.3),
        StandardisationSettings(),
        WeightingSettings(),
    )
    got = search.tell(fitness, states)
    np.testing.assert_array_equal(got.order, expected.order)
    np.testing.assert_array_equal(got.novelty, expected.novelty)
    np.testing.assert_array_equal(search.archive.behaviours, archive.behaviours)


def test_a_restored_search_goes_on_bit_for_bit(tmp_path: Path) -> None:
    uninterrupted = make()
    run(uninterrupted, 2)
    path = tmp_path / "search.npz"
    np.savez(path, **uninterrupted.state_dict())
    later = run(uninterrupted, 3)

    restored = make(seed=99)  # its own start is overwritten by the state
    with np.load(path) as saved:
        restored.load_state_dict(saved)
    assert restored.generation == 2
    for genomes in later:
        np.testing.assert_array_equal(restored.ask(), genomes)
        fitness, states = simulate(restored.ask(), T)
        restored.tell(fitness, states)
    assert restored.scores is not None and uninterrupted.scores is not None
    np.testing.assert_array_equal(restored.scores.order, uninterrupted.scores.order)
    np.testing.assert_array_equal(restored.ask(), uninterrupted.ask())
    np.testing.assert_array_equal(
        restored.archive.behaviours, uninterrupted.archive.behaviours
    )
    assert restored.weights is not None and uninterrupted.weights is not None
    np.testing.assert_array_equal(restored.weights, uninterrupted.weights)
    assert restored.best is not None and uninterrupted.best is not None
    assert restored.best.fitness == uninterrupted.best.fitness
    assert restored.best.generation == uninterrupted.best.generation
    np.testing.assert_array_equal(restored.best.genome, uninterrupted.best.genome)
    assert restored.rng.bit_generator.state == uninterrupted.rng.bit_generator.state


def test_a_state_from_other_settings_is_refused() -> None:
    state = make().state_dict()
    with pytest.raises(ValueError, match="other settings: ga"):
        make(ga=GaConfig(tournament_size=4, elites=2)).load_state_dict(state)
    with pytest.raises(ValueError, match="lacks"):
        make().load_state_dict({"population": state["population"]})


@pytest.mark.parametrize(
    ("fitness", "behaviours", "message"),
    [
        (np.ones(N - 1), np.zeros((N, 3)), r"fitness has shape \(11,\)"),
        (np.full(N, np.nan), np.zeros((N, 3)), "NaN or infinite"),
        (np.ones(N, bool), np.zeros((N, 3)), "dtype bool"),
        (np.ones(N), None, "compares behaviours"),
        (np.ones(N), {"task": np.zeros((N, 3))}, "needs 'sdbc'"),
        (np.ones(N), np.zeros((N - 1, 3)), r"shape \(11, 3\)"),
        (np.ones(N), np.full((N, 3), np.inf), "controller 0 hold NaN"),
        (np.ones(N), "states", "must be an \\(N, D\\) array"),
    ],
)
def test_bad_input_is_refused_by_name(
    fitness: np.ndarray, behaviours: object, message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        make().tell(fitness, behaviours)  # type: ignore[arg-type]


def test_float32_vectors_are_taken_exactly() -> None:
    a, b = make(), make()
    vectors = np.random.default_rng(0).random((N, 3)).astype(np.float32)
    a.tell(np.linspace(0, 1, N), vectors)
    b.tell(np.linspace(0, 1, N), vectors.astype(np.float64))
    np.testing.assert_array_equal(a.ask(), b.ask())


def test_task_states_need_the_task_and_a_batch_of_n_t_trials() -> None:
    fitness, states = simulate(make().ask(), T)
    with pytest.raises(ValueError, match="need the task description"):
        make(task=None).tell(fitness, states)
    _, short = simulate(make().ask()[:5], 1)
    with pytest.raises(ValueError, match="5 trials for 12 controllers"):
        make().tell(fitness, short)


def test_presets_names_and_settings_are_checked() -> None:
    with pytest.raises(SettingsError, match="not a preset"):
        NoveltySearch("ns-xx", genome_length=W)
    with pytest.raises(SettingsError, match="population_size"):
        NoveltySearch(genome_length=W, population=3)
    with pytest.raises(ValueError, match="genome_length"):
        NoveltySearch(genome_length=0)
    fit = NoveltySearch("fit", genome_length=W, population=N)
    scores = fit.tell(np.arange(N, dtype=float))
    assert scores.order[0] == N - 1 and np.isnan(scores.novelty).all()


def test_breed_needs_a_scored_generation() -> None:
    search = make()
    with pytest.raises(RuntimeError, match="score"):
        search.breed()
    search.score(np.linspace(0, 1, N), np.zeros((N, 2)) + np.arange(N)[:, None])
    search.breed()
    with pytest.raises(RuntimeError, match="score"):
        search.breed()
