"""Treatments, declared: which characterisation, which transforms, which ranking.

A treatment turns a generation's evaluation into the order selection reads:

    characterisation -> transforms -> novelty (k nearest neighbours, population +
    archive) -> archive update -> ranking

and is declared in YAML, as a preset's name or a mapping::

    treatment:
      name: ns-sd+chance                      # names its runs and study rows
      characterisation: sdbc                  # or {sdbc: {aggregation: {frames: 5}}},
                                              # task, state_count, ... or none
      transforms: [standardise, {weight: {relevance: mi_chance}}]
      ranking: nsga2                          # or {nslc: {k: 15}}, fitness, ...

The parts come from their registries (:mod:`sdbc_evolution.characterise.registry`,
:mod:`sdbc_evolution.transforms.pipeline`, :mod:`sdbc_evolution.relevance.measures`,
:mod:`sdbc_evolution.ga.rankings`). The paper's four are presets (:data:`PRESETS`)
and keep their names:

- **fit**: no characterisation, ranked by fitness; no novelty, no archive.
- **ns-ts**: the task-specific characterisation as it is, NSGA-II on (fitness,
  novelty).
- **ns-sd**: the SDBC, standardised, NSGA-II.
- **ns-sd+**: the SDBC, standardised and weighted by mutual information, NSGA-II.

One generation, in the order the GA's generator is used (the order is part of the
bit-identical resume contract): [a weight update: one integer for the relevance
measure], then the archive's draws. Rankings draw nothing.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import numpy as np
from sdbc_sim.limits import excerpt
from sdbc_sim.parts import at
from sdbc_sim.settings import SettingsError, check

from sdbc_evolution.characterise.evaluation import Evaluation
from sdbc_evolution.characterise.registry import CharacterisationSpec
from sdbc_evolution.characterise.registry import parse as parse_characterisation
from sdbc_evolution.ga.archive import NoveltyArchive
from sdbc_evolution.ga.novelty import NoveltyConfig, novelty_scores
from sdbc_evolution.ga.rankings import RankingContext, RankingSpec, parse_ranking
from sdbc_evolution.sdbc.standardise import StandardisationSettings
from sdbc_evolution.sdbc.weighting import WeightingSettings
from sdbc_evolution.transforms.pipeline import (
    TransformSpec,
    apply_transforms,
    parse_transforms,
)

NAME_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]*$")
"""Treatment names: they name run directories (``+`` becomes ``-plus``)."""
KEYS = ("name", "characterisation", "transforms", "ranking")
"""Keys of a declared treatment."""


@dataclass(frozen=True)
class TreatmentSpec:
    """A declared treatment.

    Attributes:
        name: Names its runs, directories and rows in a study.
        characterisation: The behaviour it compares, or None (no novelty).
        transforms: Applied in order to the raw vectors before novelty.
        ranking: How fitness and novelty become an order.
    """

    name: str
    characterisation: CharacterisationSpec | None
    transforms: tuple[TransformSpec, ...]
    ranking: RankingSpec

    def __post_init__(self) -> None:
        # Paths relative to the declaration; the caller's where is added on top.
        check(
            isinstance(self.name, str) and bool(NAME_PATTERN.match(self.name)),
            "name",
            f"{self.name!r}: letters, digits and . _ + - only, starting with a "
            "letter or digit",
        )
        if self.characterisation is None:
            check(
                not self.ranking.uses_novelty,
                "ranking",
                f"{self.ranking.name!r} scores novelty, which needs a characterisation",
            )
            check(
                not self.transforms,
                "transforms",
                "transforms need a characterisation to transform",
            )
        else:
            check(
                self.ranking.uses_novelty,
                "ranking",
                f"{self.ranking.name!r} ignores novelty; declare characterisation: "
                "none",
            )
        check(
            self.name not in PRESET_DECLARATIONS
            or self.to_mapping() == _preset_mapping(self.name),
            "name",
            f"{self.name!r} is the name of a paper treatment; choose another name "
            "for a different declaration",
        )

    @property
    def weights(self) -> bool:
        """Whether a weight transform runs (the run then records weights)."""
        return any(t.name == "weight" for t in self.transforms)

    @property
    def is_paper(self) -> bool:
        """One of the paper's four treatments."""
        return self.name in PRESET_DECLARATIONS

    @property
    def directory(self) -> str:
        """Its directory name in a study (no ``+`` in paths)."""
        return treatment_directory(self.name)

    def to_mapping(self) -> dict[str, Any]:
        """The full declaration as plain data."""
        return {
            "name": self.name,
            "characterisation": None
            if self.characterisation is None
            else self.characterisation.to_plain(),
            "transforms": [t.to_plain() for t in self.transforms],
            "ranking": self.ranking.to_plain(),
        }

    def to_plain(self) -> str | dict[str, Any]:
        """YAML-ready: a preset's name, or the declaration."""
        return self.name if self.is_paper else self.to_mapping()


PRESET_DECLARATIONS: dict[str, dict[str, Any]] = {
    "fit": {"characterisation": None, "transforms": [], "ranking": "fitness"},
    "ns-ts": {"characterisation": "task", "transforms": [], "ranking": "nsga2"},
    "ns-sd": {
        "characterisation": "sdbc",
        "transforms": ["standardise"],
        "ranking": "nsga2",
    },
    "ns-sd+": {
        "characterisation": "sdbc",
        "transforms": ["standardise", "weight"],
        "ranking": "nsga2",
    },
}
"""The paper's four treatments, as declarations."""
PAPER_TREATMENTS = tuple(PRESET_DECLARATIONS)
"""Their names, in the paper's order."""
PAPER_LABELS = {"fit": "Fit", "ns-ts": "NS-TS", "ns-sd": "NS-SD", "ns-sd+": "NS-SD+"}
"""How the paper writes its treatments' names."""


def label(name: str) -> str:
    """How reports write a treatment's name: the paper's spelling for its four,
    the declared name for any other."""
    return PAPER_LABELS.get(name, name)


def treatment_directory(name: str) -> str:
    """A treatment's directory name in a study (no ``+`` in paths)."""
    return name.replace("+", "-plus")


def _preset_mapping(name: str) -> dict[str, Any]:
    return {"name": name, **PRESET_DECLARATIONS[name]}


def _build(name: str, data: dict[str, Any], where: str) -> TreatmentSpec:
    characterisation = data.get("characterisation")
    try:
        return TreatmentSpec(
            name=name,
            characterisation=None
            if characterisation in (None, "none")
            else parse_characterisation(characterisation, "characterisation"),
            transforms=parse_transforms(data.get("transforms") or [], "transforms"),
            ranking=parse_ranking(data.get("ranking", "nsga2"), "ranking"),
        )
    except SettingsError as error:
        # Every path so far is relative to the declaration.
        raise (error.prefixed(where) if where else error) from None


PRESETS: dict[str, TreatmentSpec] = {}


def parse_treatment(value: Any, where: str = "") -> TreatmentSpec:
    """A treatment from a preset's name or a declaration mapping.

    Args:
        value: The declaration.
        where: Its dotted path, for messages (empty: the caller adds it, as the
            configuration's ``treatment`` field does).

    Raises:
        SettingsError: Unknown preset, unknown keys, or a bad part, naming it.
    """
    if isinstance(value, TreatmentSpec):
        return value
    if isinstance(value, str):
        if value not in PRESET_DECLARATIONS:
            raise SettingsError.of(
                (
                    (
                        where,
                        f"{value!r} is not a preset ({list(PRESET_DECLARATIONS)}); "
                        "declare other treatments as a mapping with keys "
                        f"{list(KEYS)}",
                    ),
                )
            )
        return PRESETS[value]
    if not isinstance(value, dict):
        raise SettingsError.of(
            ((where, f"expected a preset's name or a mapping, got {excerpt(value)}"),)
        )
    unknown = sorted(str(k) for k in value if k not in KEYS)
    if unknown:
        raise SettingsError.of(
            ((where, f"unknown key(s) {unknown}; a treatment has {list(KEYS)}"),)
        )
    if "name" not in value:
        raise SettingsError.of(
            ((at(where, "name"), "a declared treatment needs a name"),)
        )
    return _build(value["name"], value, where)


for _name, _declaration in PRESET_DECLARATIONS.items():
    # The presets are read from their declarations, as any treatment is.
    PRESETS[_name] = _build(_name, _declaration, "")


@dataclass
class GenerationScores:
    """How a treatment scored one generation.

    Attributes:
        order: (N,) individual indices, best first; selection reads only this.
        novelty: (N,) novelty scores; NaN without a characterisation.
        front: (N,) front of each individual (0 where the ranking has none).
        weights: (D,) the weights in force (a weight transform); None otherwise.
        archived: (N,) bool, which individuals entered the archive.
        relevance: (D,) the relevance computed this generation, or None.
    """

    order: np.ndarray
    novelty: np.ndarray
    front: np.ndarray
    weights: np.ndarray | None
    archived: np.ndarray
    relevance: np.ndarray | None = None


def behaviour_vectors(
    treatment: TreatmentSpec, evaluation: Evaluation
) -> np.ndarray | None:
    """The raw behaviour vectors a treatment compares (None without any)."""
    if treatment.characterisation is None:
        return None
    return evaluation.behaviour(treatment.characterisation.key)


def score_generation(
    treatment: TreatmentSpec,
    evaluation: Evaluation,
    archive: NoveltyArchive,
    weights: np.ndarray | None,
    generation: int,
    rng: np.random.Generator,
    novelty: NoveltyConfig,
    standardisation: StandardisationSettings,
    weighting: WeightingSettings,
) -> GenerationScores:
    """Scores and ranks one evaluated generation, updating the archive.

    Args:
        treatment: The treatment.
        evaluation: The generation's evaluation.
        archive: The novelty archive (changed in place).
        weights: Weights in force from an earlier generation, or None.
        generation: Index of this generation (0-based).
        rng: The GA's generator.
        novelty: Novelty settings.
        standardisation: Standardisation settings (``standardise``).
        weighting: Weighting settings (``weight``).
    """
    fitness = evaluation.fitness
    n = fitness.shape[0]
    raw = behaviour_vectors(treatment, evaluation)
    if raw is None:
        order, front = treatment.ranking.rank(
            RankingContext(
                fitness, None, None, None, None, novelty.k, novelty.tie_break, rng
            )
        )
        return GenerationScores(
            order=order,
            novelty=np.full(n, np.nan),
            front=front,
            weights=None,
            archived=np.zeros(n, dtype=bool),
        )
    transformed = apply_transforms(
        treatment.transforms,
        raw,
        archive.behaviours,
        fitness,
        weights,
        generation,
        rng,
        standardisation,
        weighting,
    )
    scores = novelty_scores(transformed.population, transformed.archive, novelty.k)
    archive_fitness = archive.fitness.copy()
    archived = archive.offer(raw, fitness, generation, rng)
    order, front = treatment.ranking.rank(
        RankingContext(
            fitness=fitness,
            novelty=scores,
            population=transformed.population,
            archive=transformed.archive,
            archive_fitness=archive_fitness,
            k=novelty.k,
            tie_break=novelty.tie_break,
            rng=rng,
        )
    )
    return GenerationScores(
        order=order,
        novelty=scores,
        front=front,
        weights=transformed.weights,
        archived=archived,
        relevance=transformed.relevance,
    )
