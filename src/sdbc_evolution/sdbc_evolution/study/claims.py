"""The paper's claims, and our verdict on each from a study's numbers.

Every claim the paper makes in its results (section "Results and Analysis";
docs/reference-setup.md, "Analysis the paper reports") is one :class:`Claim`, judged
with the same test:

- **A above B, significant** (e.g. "every NS variant beats Fit, p < 0.05"): agree
  when our two-sided Mann-Whitney p < alpha and A beats B more often than not
  (effect A = U / (n_a n_b) > 0.5); disagree when p < alpha the other way;
  inconclusive when p >= alpha (our runs cannot tell; with fewer runs than the
  paper's 20 a real difference may not show);
- **no significant difference** ("NS-SD and NS-SD+ differ only in resource
  sharing"): agree when p >= alpha, disagree when p < alpha;
- **A not below B** ("weighting never harms"): disagree only when B is significantly
  above A;
- **relevance**: the paper's most relevant features are among ours (agree when at
  least half of its listed features are in our top list of the same length), and
  relevance is consistent over runs (agree when the median coefficient of variation
  SD / mean of our top features is under :data:`CONSISTENT_CV`).

The claims apply to the paper's three tasks only (:mod:`sdbc_evolution.study.paper`):
a study of any other task gets no claim.

The exploration claims apply the first rule to per-run numbers of the maps
(:mod:`sdbc_evolution.study.exploration`): uniformity and high-fitness share.

A study's own predictions (:mod:`sdbc_evolution.study.predictions`, declared in its
preset) are judged by the same three rules, apart from the paper's claims:
:func:`judge_predictions`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np

from sdbc_evolution.ga.treatments import label
from sdbc_evolution.study.exploration import ExplorationMaps
from sdbc_evolution.study.paper import is_paper_task, task_title
from sdbc_evolution.study.predictions import Prediction
from sdbc_evolution.study.quality import PairTest, mann_whitney
from sdbc_evolution.study.relevance import RelevanceTable

ALPHA = 0.05
"""Significance level of every claim (the paper's)."""
CONSISTENT_CV = 0.2
"""Median SD / mean of the top features under which relevance is "consistent"
(the paper's table: 0.01 to 0.11)."""

FIT, NS_TS, NS_SD, NS_SD_PLUS = "fit", "ns-ts", "ns-sd", "ns-sd+"


@dataclass(frozen=True)
class PaperFeature:
    """One row of the paper's MI table (Table 1).

    Attributes:
        name: Our dimension name.
        label: The paper's label, where it differs.
        mean: Mean MI, bits.
        sd: SD of the MI over runs.
        in_task_specific: The paper's tick.
    """

    name: str
    label: str
    mean: float
    sd: float
    in_task_specific: bool


PAPER_RELEVANCE: dict[str, tuple[PaperFeature, ...]] = {
    "gate_escape": (
        PaperFeature("Gate is closing (F)", "", 2.37, 0.05, False),
        PaperFeature("Agent group size (F)", "", 1.85, 0.03, True),
        PaperFeature("Simulation length", "", 1.46, 0.04, True),
        PaperFeature("Agent group size (M)", "", 1.43, 0.03, False),
        PaperFeature("Gate is closing (M)", "", 1.39, 0.04, False),
        PaperFeature("Agent is passing gate (M)", "", 0.81, 0.04, False),
    ),
    "resource_sharing": (
        PaperFeature("Agent energy level (M)", "", 1.58, 0.14, True),
        PaperFeature("Agent group size (F)", "", 1.56, 0.17, True),
        PaperFeature("Agent energy level (F)", "", 1.12, 0.09, False),
        PaperFeature("Simulation length", "", 0.96, 0.06, False),
        PaperFeature("Station is occupied (M)", "", 0.84, 0.08, False),
        PaperFeature("Agent is charging (M)", "", 0.81, 0.07, False),
    ),
    "predator_prey": (
        PaperFeature("Predators-prey distance (F)", "", 1.47, 0.05, True),
        PaperFeature("Predators-prey distance (M)", "", 0.98, 0.01, False),
        PaperFeature("Predators dispersion (F)", "", 0.66, 0.08, True),
        PaperFeature("Prey linear speed (F)", "Prey speed (F)", 0.57, 0.03, False),
        PaperFeature(
            "Prey-boundary distance (F)", "Prey-bounds distance (F)", 0.48, 0.02, False
        ),
    ),
}
"""The paper's Table 1, under our dimension names."""


class Verdict(str, Enum):
    """How our numbers stand to a claim of the paper."""

    AGREE = "agree"
    DISAGREE = "disagree"
    INCONCLUSIVE = "inconclusive"


@dataclass(frozen=True)
class Claim:
    """One claim of the paper and what our study says of it.

    Attributes:
        topic: "quality", "relevance" or "exploration".
        task: Task name.
        statement: The claim, as the paper makes it.
        paper: The paper's evidence.
        ours: Our evidence.
        p: Our p-value (None where the claim has no test).
        verdict: Agree, disagree or inconclusive.
    """

    topic: str
    task: str
    statement: str
    paper: str
    ours: str
    p: float | None
    verdict: Verdict


def _fmt(x: float) -> str:
    return f"{x:.3g}" if math.isfinite(x) else "n/a"


def _p(p: float) -> str:
    return f"p = {p:.3g}" if p >= 1e-3 else "p < 0.001"


def above(test: PairTest, alpha: float = ALPHA) -> Verdict:
    """Verdict on "test.a above test.b, significantly"."""
    if test.p >= alpha:
        return Verdict.INCONCLUSIVE
    return Verdict.AGREE if test.effect > 0.5 else Verdict.DISAGREE


def no_difference(test: PairTest, alpha: float = ALPHA) -> Verdict:
    """The verdict on a claim of no difference: agree unless the test is significant at
    ``alpha``."""
    return Verdict.AGREE if test.p >= alpha else Verdict.DISAGREE


def not_below(test: PairTest, alpha: float = ALPHA) -> Verdict:
    """Verdict on "test.a is not below test.b"."""
    return Verdict.DISAGREE if test.p < alpha and test.effect < 0.5 else Verdict.AGREE


def evidence(test: PairTest, what: str = "best fitness") -> str:
    """A test in words: both medians, run counts, effect and p-value."""
    return (
        f"median {what} {label(test.a)} {_fmt(test.median_a)} vs {label(test.b)} "
        f"{_fmt(test.median_b)} (n = {test.n_a}, {test.n_b}); "
        f"A = {test.effect:.2f}, {_p(test.p)}"
    )


def find_test(tests: list[PairTest], a: str, b: str) -> PairTest | None:
    """The test of a against b, turned round if it was run as b against a."""
    for t in tests:
        if (t.a, t.b) == (a, b):
            return t
        if (t.a, t.b) == (b, a):
            return PairTest(
                t.task,
                a,
                b,
                t.n_b,
                t.n_a,
                t.median_b,
                t.median_a,
                t.mean_b,
                t.mean_a,
                t.n_a * t.n_b - t.u,
                t.p,
            )
    return None


def quality_claims(
    task: str, tests: list[PairTest], alpha: float = ALPHA
) -> list[Claim]:
    """The paper's claims on the quality of solutions that concern ``task`` (none
    for a task the paper did not run)."""
    if not is_paper_task(task):
        return []
    title = task_title(task)
    claims = []

    def add(
        statement: str,
        paper: str,
        test: PairTest | None,
        rule: Callable[[PairTest, float], Verdict],
    ) -> None:
        if test is None:
            return
        claims.append(
            Claim(
                "quality",
                task,
                statement,
                paper,
                evidence(test),
                test.p,
                rule(test, alpha),
            )
        )

    for variant in (NS_TS, NS_SD, NS_SD_PLUS):
        add(
            f"{label(variant)} reaches higher fitness than Fit in {title}",
            "p < 0.05",
            find_test(tests, variant, FIT),
            above,
        )
    if task == "gate_escape":
        add(
            f"NS-TS above NS-SD+ in {title}",
            "p = 0.013",
            find_test(tests, NS_TS, NS_SD_PLUS),
            above,
        )
    if task == "resource_sharing":
        add(
            f"NS-TS above NS-SD+ in {title}",
            "p = 0.025",
            find_test(tests, NS_TS, NS_SD_PLUS),
            above,
        )
        add(
            f"NS-SD+ above NS-SD in {title}",
            "p < 0.01",
            find_test(tests, NS_SD_PLUS, NS_SD),
            above,
        )
    else:
        add(
            f"NS-SD and NS-SD+ do not differ significantly in {title}",
            "significant only in resource sharing",
            find_test(tests, NS_SD_PLUS, NS_SD),
            no_difference,
        )
    add(
        f"feature weighting never harms: NS-SD+ not below NS-SD in {title}",
        "NS-SD+ on average above NS-SD in every task",
        find_test(tests, NS_SD_PLUS, NS_SD),
        not_below,
    )
    return claims


def relevance_claims(task: str, table: RelevanceTable | None) -> list[Claim]:
    """The paper's claims on feature relevance for ``task``."""
    paper = PAPER_RELEVANCE.get(task)
    if table is None or paper is None:
        return []
    title = task_title(task)
    m = len(paper)
    ours = table.top(m)
    shared = [f.name for f in paper if f.name in ours.names]
    overlap = Verdict.AGREE if len(shared) >= math.ceil(m / 2) else Verdict.DISAGREE
    top = paper[0]
    rank = table.rank_of(top.name)
    claims = [
        Claim(
            "relevance",
            task,
            f"the most relevant features of {title} are those of the paper's table",
            ", ".join(f.label or f.name for f in paper),
            f"{len(shared)} of the paper's {m} are in our top {m} "
            f"({', '.join(shared) or 'none'}); the paper's first, {top.name}, is our "
            f"#{rank} of {len(table.names)}; our first: {table.names[0]} "
            f"({table.mean[0]:.2f} bits)",
            None,
            overlap,
        )
    ]
    matched = [n for n, t in zip(ours.names, ours.in_task_specific, strict=True) if t]
    claims.append(
        Claim(
            "relevance",
            task,
            f"some of the most relevant SDBC features of {title} match the "
            "task-specific characterisation",
            ", ".join(f.label or f.name for f in paper if f.in_task_specific),
            f"in our top {m}: {', '.join(matched) or 'none'}",
            None,
            Verdict.AGREE if matched else Verdict.DISAGREE,
        )
    )
    informative = ours.mean > 0
    if table.runs > 1 and informative.any():
        cv = float(np.median(ours.sd[informative] / ours.mean[informative]))
        claims.append(
            Claim(
                "relevance",
                task,
                f"feature relevance is consistent across runs in {title} (small SD)",
                "SD / mean 0.01-0.11",
                f"median SD / mean of our top {m}: {_fmt(cv)} over {table.runs} runs",
                None,
                Verdict.AGREE if cv < CONSISTENT_CV else Verdict.DISAGREE,
            )
        )
    return claims


def _metric_test(maps: ExplorationMaps, metric: str, a: str, b: str) -> PairTest | None:
    if a not in maps.treatments or b not in maps.treatments:
        return None
    values = {t: getattr(maps, metric)(k) for k, t in enumerate(maps.treatments)}
    return mann_whitney(maps.task, a, b, values[a], values[b])


def exploration_claims(maps: ExplorationMaps, alpha: float = ALPHA) -> list[Claim]:
    """The paper's reading of its exploration maps, tested on ``maps.task`` (none
    for a task the paper did not run)."""
    if not is_paper_task(maps.task):
        return []
    title = task_title(maps.task)
    claims = []

    def add(statement: str, test: PairTest | None, what: str) -> None:
        if test is not None:
            claims.append(
                Claim(
                    "exploration",
                    maps.task,
                    statement,
                    "figure 3 (resource sharing; 'similar' in the others)",
                    evidence(test, what),
                    test.p,
                    above(test, alpha),
                )
            )

    for variant in (NS_TS, NS_SD, NS_SD_PLUS):
        add(
            f"{label(variant)} explores more uniformly than Fit in {title}",
            _metric_test(maps, "uniformity", variant, FIT),
            "uniformity",
        )
    for other in (NS_TS, NS_SD_PLUS):
        add(
            f"NS-SD explores more uniformly than {label(other)} in {title}",
            _metric_test(maps, "uniformity", NS_SD, other),
            "uniformity",
        )
    add(
        f"NS-SD+ spends more effort in the high-fitness region than NS-SD in {title}",
        _metric_test(maps, "region_share", NS_SD_PLUS, NS_SD),
        "high-fitness share",
    )
    add(
        f"NS-TS focuses on the high-fitness region more than NS-SD+ in {title}",
        _metric_test(maps, "region_share", NS_TS, NS_SD_PLUS),
        "high-fitness share",
    )
    return claims


RULES: dict[str, Callable[[PairTest, float], Verdict]] = {
    "above": above,
    "no_difference": no_difference,
    "not_below": not_below,
}
"""Each prediction rule's judgement of a test of ``a`` against ``b``."""

OUTCOME: dict[Verdict, str] = {
    Verdict.AGREE: "held",
    Verdict.DISAGREE: "did not hold",
    Verdict.INCONCLUSIVE: "cannot tell",
}
"""How the report words a verdict on a prediction."""


@dataclass(frozen=True)
class PredictionResult:
    """A prediction judged on one task.

    Attributes:
        prediction: What was predicted.
        task: The task.
        evidence: Medians, run counts, effect and p-value.
        p: The test's p-value.
        effect: A = U / (n_a n_b), the chance that a run of ``a`` beats one of ``b``.
        verdict: Agree (held), disagree (did not hold) or inconclusive.
    """

    prediction: Prediction
    task: str
    evidence: str
    p: float
    effect: float
    verdict: Verdict

    @property
    def outcome(self) -> str:
        """The verdict in the words of a prediction (``OUTCOME``)."""
        return OUTCOME[self.verdict]


def judge_predictions(
    predictions: Sequence[Prediction],
    task: str,
    tests: list[PairTest],
    alpha: float = ALPHA,
) -> list[PredictionResult]:
    """The predictions that concern ``task``, judged on its tests (a prediction
    whose treatments have no usable runs there is left out)."""
    results = []
    for prediction in predictions:
        if not prediction.concerns(task):
            continue
        test = find_test(tests, prediction.a, prediction.b)
        if test is None:
            continue
        results.append(
            PredictionResult(
                prediction=prediction,
                task=task,
                evidence=evidence(test),
                p=test.p,
                effect=test.effect,
                verdict=RULES[prediction.rule](test, alpha),
            )
        )
    return results
