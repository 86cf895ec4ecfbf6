"""Every registered part of every kind keeps its kind's contract: the package's own
and those of installed distributions' entry points alike (the parts come from the
registries, so a new part is checked without naming it here; tests/test_example_parts.py
runs this file again with examples/07_own_parts installed).

Of every part: it has a docstring and so has each option, its declaration
round-trips (parse, to_plain, parse), an unknown option and an unknown name are
refused in one line naming them; then, per kind,
its answer has the kind's shape, and it is a function of its inputs and seed.
"""

from __future__ import annotations

import copy
import types
import typing
from typing import Any

import numpy as np
import pytest
from sdbc_evolution.characterise.base import per_controller
from sdbc_evolution.characterise.registry import (
    CHARACTERISATIONS,
    CharacterisationSpec,
)
from sdbc_evolution.ga.rankings import RANKINGS, RankingContext, RankingSpec
from sdbc_evolution.relevance.measures import MEASURES, RelevanceSpec
from sdbc_evolution.sdbc.standardise import StandardisationSettings
from sdbc_evolution.sdbc.weighting import WeightingSettings
from sdbc_evolution.transforms.pipeline import (
    TRANSFORMS,
    TransformSpec,
    apply_transforms,
)
from sdbc_sim.parts import PartSpec, Registry
from sdbc_sim.settings import SettingsError, field_docs, load

KINDS: dict[str, tuple[Registry[Any], type[PartSpec[Any]]]] = {
    "characterisation": (CHARACTERISATIONS, CharacterisationSpec),
    "relevance": (MEASURES, RelevanceSpec),
    "transform": (TRANSFORMS, TransformSpec),
    "ranking": (RANKINGS, RankingSpec),
}
SLOW = {("relevance", "dcor")}
"""Parts whose first use is slow (dcor compiles numba code on import)."""


def every_part() -> list[Any]:
    return [
        pytest.param(kind, name, id=f"{kind}:{name}", marks=[pytest.mark.slow])
        if (kind, name) in SLOW
        else pytest.param(kind, name, id=f"{kind}:{name}")
        for kind, (registry, _) in KINDS.items()
        for name in registry.names()
    ]


def parts_of(kind: str) -> list[Any]:
    return [p for p in every_part() if p.values[0] == kind]


def leaves(annotation: Any) -> list[Any]:
    """The plain types (and a Literal's values) an option's annotation allows."""
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin is typing.Annotated:
        return leaves(args[0])
    if origin is typing.Literal:
        return list(args)
    if origin in (typing.Union, types.UnionType):
        return [leaf for arg in args for leaf in leaves(arg)]
    return [annotation]


def other_values(annotation: Any, value: Any) -> list[Any]:
    """Plain values of ``annotation`` other than ``value`` to try an option with
    (those the options refuse are skipped)."""
    candidates: list[Any] = []
    for leaf in leaves(annotation):
        if leaf is bool:
            candidates.append(not value)
        elif leaf is int:
            candidates += [(value or 0) + 1, 2]
        elif leaf is float:
            candidates += [0.5 * (value or 1.0), 0.25]
        elif isinstance(leaf, str):  # a Literal's value
            candidates.append(leaf)
    return [c for c in candidates if c != value]


def changed_declarations(registry: Registry[Any], name: str) -> list[dict[str, Any]]:
    """Declarations of ``name`` with one option changed, each accepted."""
    options = registry[name].options
    found = []
    for field, info in options.__pydantic_fields__.items():
        default = getattr(options(), field)
        for value in other_values(info.annotation, default):
            try:
                load(options, {field: value})
            except SettingsError:
                continue
            found.append({name: {field: value}})
            break
    return found


def declarations(kind: str, name: str) -> list[Any]:
    """The part with its default options, then with each option changed."""
    return [name, *changed_declarations(KINDS[kind][0], name)]


@pytest.mark.parametrize(("kind", "name"), every_part())
def test_a_part_says_what_it_is_and_what_each_option_means(
    kind: str, name: str
) -> None:
    registered = KINDS[kind][0][name]
    assert registered.summary, f"{registered.origin}: no docstring"
    undocumented = [f for f, doc in field_docs(registered.options).items() if not doc]
    assert not undocumented, f"{registered.options.__name__}: {undocumented}"


@pytest.mark.parametrize(("kind", "name"), every_part())
def test_a_declaration_round_trips(kind: str, name: str) -> None:
    registry, spec_class = KINDS[kind]
    spec = spec_class.parse(name, kind)
    assert spec.name == name and spec.to_plain() == name
    assert type(spec.options) is registry[name].options
    assert spec_class.parse({name: {}}, kind) == spec
    for declaration in changed_declarations(registry, name):
        changed = spec_class.parse(declaration, kind)
        assert changed != spec
        assert changed.to_plain() == declaration
        assert spec_class.parse(changed.to_plain(), kind) == changed


@pytest.mark.parametrize(("kind", "name"), every_part())
def test_bad_options_and_names_are_refused_naming_them(kind: str, name: str) -> None:
    _, spec_class = KINDS[kind]
    with pytest.raises(SettingsError) as caught:
        spec_class.parse({name: {"no_such_option": 1}}, kind)
    message = str(caught.value)
    assert f"{kind}.{name}.no_such_option: unknown key" in message
    assert "\n" not in message
    with pytest.raises(SettingsError, match=rf"unknown .*'{name}_no_such_part'"):
        spec_class.parse(f"{name}_no_such_part", kind)


# --- rankings ----------------------------------------------------------------

N, M, D = 12, 5, 3


def generation(seed: int) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    return {
        "fitness": rng.random(N),
        "novelty": rng.random(N) * 3,
        "population": rng.normal(size=(N, D)),
        "archive": rng.normal(size=(M, D)),
        "archive_fitness": rng.random(M),
        "k": 3,
        "tie_break": "crowding",
    }


@pytest.mark.parametrize(("kind", "name"), parts_of("ranking"))
def test_a_ranking_orders_every_individual_as_a_function_of_its_seed(
    kind: str, name: str
) -> None:
    for declaration in declarations(kind, name):
        check_ranking(RankingSpec.parse(declaration))


def check_ranking(spec: RankingSpec) -> None:
    answers = []
    for _ in range(2):
        rng = np.random.default_rng(5)
        before = copy.deepcopy(rng.bit_generator.state)
        order, front = spec.rank(RankingContext(**generation(1), rng=rng))
        assert sorted(order.tolist()) == list(range(N))
        assert front.shape == (N,) and front.dtype == np.int64
        if not spec.registered.part.draws:
            assert rng.bit_generator.state == before, "draws, but says it does not"
        answers.append((order.tolist(), front.tolist()))
    assert answers[0] == answers[1]
    if not spec.uses_novelty:
        bare = {**generation(1), "novelty": None, "population": None, "archive": None}
        order, _ = spec.rank(RankingContext(**bare, rng=np.random.default_rng(5)))
        assert order.tolist() == answers[0][0]


# --- relevance measures ------------------------------------------------------


def population(seed: int = 0, n: int = 40) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    fitness = rng.random(n)
    raw = np.column_stack([fitness**2, rng.normal(size=n), np.full(n, 3.0)])
    return raw, fitness


@pytest.mark.parametrize(("kind", "name"), parts_of("relevance"))
def test_a_relevance_measure_gives_one_value_per_dimension_from_one_draw(
    kind: str, name: str
) -> None:
    for declaration in declarations(kind, name):
        check_relevance(RelevanceSpec.parse(declaration))


def check_relevance(spec: RelevanceSpec) -> None:
    raw, fitness = population()
    answers = []
    for _ in range(2):
        rng = np.random.default_rng(3)
        values = spec.compute(raw, fitness, WeightingSettings(), rng)
        assert values.shape == (D,) and values.dtype == np.float64
        assert np.isfinite(values).all() and (values >= 0).all()
        reference = np.random.default_rng(3)
        reference.integers(2**31 - 1)
        assert rng.bit_generator.state == reference.bit_generator.state
        answers.append(values)
    np.testing.assert_array_equal(answers[0], answers[1])


# --- transforms --------------------------------------------------------------


@pytest.mark.parametrize(("kind", "name"), parts_of("transform"))
def test_a_transform_maps_population_and_archive_alike(kind: str, name: str) -> None:
    for declaration in declarations(kind, name):
        check_transform(TransformSpec.parse(declaration))


def check_transform(spec: TransformSpec) -> None:
    raw, fitness = population(n=N)
    archive = np.random.default_rng(9).normal(size=(M, D))
    answers = []
    for _ in range(2):
        done = apply_transforms(
            (spec,),
            raw,
            archive,
            fitness,
            None,
            0,
            np.random.default_rng(2),
            StandardisationSettings(),
            WeightingSettings(),
        )
        assert done.population.shape[0] == N and done.archive.shape[0] == M
        assert done.population.shape[1] == done.archive.shape[1]
        assert np.isfinite(done.population).all() and np.isfinite(done.archive).all()
        if done.weights is not None:
            assert done.weights.shape == (done.population.shape[1],)
        answers.append(done)
    np.testing.assert_array_equal(answers[0].population, answers[1].population)
    np.testing.assert_array_equal(answers[0].archive, answers[1].archive)


# --- characterisations -------------------------------------------------------

TASKS = ("gate_escape", "foraging", "predator_prey", "aggregation")
"""Tasks to make a characterisation for, the first that it can be made for (a
characterisation may refuse a task, in one line naming itself)."""


def made_for_a_task(spec: CharacterisationSpec) -> tuple[Any, tuple[str, ...]]:
    """The first task spec of :data:`TASKS` the characterisation can be made for,
    and its dimension names."""
    from sdbc_evolution.run.evaluators import TaskSpec

    refusals = []
    for task in TASKS:
        task_spec = TaskSpec(task, {"max_steps": 30}, characterisations=(spec,))
        try:
            return task_spec, spec.build().names(task_spec.build())
        except ValueError as error:
            assert "\n" not in str(error) and spec.name in str(error)
            refusals.append(str(error))
    raise AssertionError(f"{spec.key} can be made for none of {TASKS}: {refusals}")


@pytest.mark.parametrize(("kind", "name"), parts_of("characterisation"))
def test_a_characterisation_names_every_dimension_of_its_vectors(
    kind: str, name: str
) -> None:
    for declaration in declarations(kind, name):
        check_characterisation(CharacterisationSpec.parse(declaration))


def check_characterisation(spec: CharacterisationSpec) -> None:
    from sdbc_evolution.run.evaluators import evaluate_chunk

    task_spec, names = made_for_a_task(spec)
    task = task_spec.build()
    assert isinstance(names, tuple) and all(isinstance(n, str) and n for n in names)
    assert len(set(names)) == len(names)
    genomes = np.random.default_rng(0).uniform(-1, 1, (3, task.genome_length))
    seeds = np.arange(6, dtype=np.int64).reshape(3, 2)
    first = evaluate_chunk(task_spec, genomes, seeds).behaviour(spec.key)
    again = evaluate_chunk(task_spec, genomes, seeds).behaviour(spec.key)
    assert first.shape == (3, len(names)) and first.dtype == np.float64
    assert np.isfinite(first).all()
    np.testing.assert_array_equal(first, again)
    if spec.registered.part.mean_of_trials:
        # What it declares: the same trials one per row, averaged per controller
        # by per_controller, give its vectors to the bit.
        rows = evaluate_chunk(
            task_spec, np.repeat(genomes, 2, axis=0), seeds.reshape(-1, 1)
        ).behaviour(spec.key)
        np.testing.assert_array_equal(per_controller(rows, 2), first)
