"""The paper's claims, and our verdict on each from a study's numbers.

Every claim the paper makes in its results (section "Results and Analysis";
docs/reference-setup.md, "Analysis the paper reports") is one :class:`Claim`, judged
on a two-sided Mann-Whitney test (:mod:`.quality`) whose p is **Holm-adjusted
within its family** (a task's fitness tests, every pair of its treatments; a task's
exploration tests), with Vargha and Delaney's A and its 95 % bootstrap interval:

- **A above B, significant** (e.g. "every NS variant beats Fit, p < 0.05"): agree
  when the adjusted p < alpha and A > 0.5; disagree when the adjusted p < alpha the
  other way; inconclusive otherwise (our runs cannot tell);
- **no significant difference** ("NS-SD and NS-SD+ differ only in resource
  sharing"): agree only when A's interval lies inside :data:`EQUIVALENCE_MARGIN`
  (an equivalence test: the runs show the treatments close); disagree when the
  adjusted p < alpha; otherwise inconclusive: a p above alpha alone is absence of
  evidence, which few runs give all too easily;
- **A not below B** ("weighting never harms"): agree only when the lower end of
  A's interval is above the margin's lower bound (non-inferiority); disagree when
  the adjusted p < alpha and A < 0.5; otherwise inconclusive;
- **relevance**: the paper's most relevant features are among ours (agree when at
  least half of its listed features are in our top list of the same length), some
  of our top features are in the task-specific characterisation (reported with
  the rule's chance pass rate), and relevance is consistent over runs (agree when
  the median coefficient of variation SD / mean of our top features is under
  :data:`CONSISTENT_CV`); all three judged on the ranking by MI above its chance
  level where the digest holds it (:mod:`.relevance`), the raw ranking beside.

The totals count tests, not claims, where claims share one (:func:`totals`).

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
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np

from sdbc_evolution.ga.treatments import label
from sdbc_evolution.study.exploration import MapNumbers
from sdbc_evolution.study.paper import is_paper_task, task_title
from sdbc_evolution.study.predictions import Prediction
from sdbc_evolution.study.quality import PairTest, holm, mann_whitney
from sdbc_evolution.study.relevance import RelevanceTable, chance_pass_rate

ALPHA = 0.05
"""Significance level of every claim (the paper's)."""
EQUIVALENCE_MARGIN = (0.36, 0.64)
"""The band of A taken as "no real difference": Vargha and Delaney's (2000)
"small" effect bounds. ``no_difference`` needs A's whole interval inside it,
``not_below`` its lower end above the lower bound; the one place it is declared."""
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
        p: Our raw p-value (None where the claim has no test).
        verdict: Agree, disagree or inconclusive.
        test: The test it rests on (None where it has none): its Holm p, A
            and A's interval.
        statistic: Which statistic of a run the test compares.
    """

    topic: str
    task: str
    statement: str
    paper: str
    ours: str
    p: float | None
    verdict: Verdict
    test: PairTest | None = None
    statistic: str = ""

    @property
    def test_key(self) -> tuple[str, ...] | None:
        """The test's identity, the same for two claims on one test (whichever
        way round they read it)."""
        if self.test is None:
            return None
        pair = sorted((self.test.a, self.test.b))
        return (self.topic, self.task, self.statistic, *pair)


def _fmt(x: float) -> str:
    return f"{x:.3g}" if math.isfinite(x) else "n/a"


def above(test: PairTest, alpha: float = ALPHA) -> Verdict:
    """Verdict on "test.a above test.b, significantly"."""
    if test.adjusted_p >= alpha:
        return Verdict.INCONCLUSIVE
    return Verdict.AGREE if test.effect > 0.5 else Verdict.DISAGREE


def no_difference(test: PairTest, alpha: float = ALPHA) -> Verdict:
    """Verdict on "test.a and test.b do not differ" (an equivalence test)."""
    low, high = EQUIVALENCE_MARGIN
    if low < test.effect_low and test.effect_high < high:
        return Verdict.AGREE
    if test.adjusted_p < alpha:
        return Verdict.DISAGREE
    return Verdict.INCONCLUSIVE


def not_below(test: PairTest, alpha: float = ALPHA) -> Verdict:
    """Verdict on "test.a is not below test.b" (non-inferiority)."""
    if test.effect_low > EQUIVALENCE_MARGIN[0]:
        return Verdict.AGREE
    if test.adjusted_p < alpha and test.effect < 0.5:
        return Verdict.DISAGREE
    return Verdict.INCONCLUSIVE


def evidence(test: PairTest, what: str = "best fitness") -> str:
    """A test in words: both medians, run counts, and A with its interval (the
    tables give the p-values in columns of their own)."""
    return (
        f"median {what} {label(test.a)} {_fmt(test.median_a)} vs {label(test.b)} "
        f"{_fmt(test.median_b)} (n = {test.n_a}, {test.n_b}); "
        f"A = {test.effect:.2f} [{test.effect_low:.2f}, {test.effect_high:.2f}]"
    )


def find_test(tests: list[PairTest], a: str, b: str) -> PairTest | None:
    """The test of a against b, turned round if it was run as b against a."""
    for t in tests:
        if (t.a, t.b) == (a, b):
            return t
        if (t.a, t.b) == (b, a):
            return t.turned()
    return None


def totals(claims: Sequence[Claim]) -> Counter[Verdict]:
    """Verdicts counted once per test: two claims on one test with the same
    verdict count once (one observation), with different verdicts once each;
    claims with no test count one each."""
    seen: set[tuple[object, ...]] = set()
    counts: Counter[Verdict] = Counter()
    for i, claim in enumerate(claims):
        key = (claim.test_key or ("claim", i), claim.verdict)
        if key not in seen:
            seen.add(key)
            counts[claim.verdict] += 1
    return counts


def quality_claims(
    task: str, tests: list[PairTest], alpha: float = ALPHA, statistic: str = ""
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
                test,
                statistic,
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


def relevance_claims(
    task: str, table: RelevanceTable | None, above: RelevanceTable | None = None
) -> list[Claim]:
    """The paper's claims on feature relevance for ``task``, judged on the ranking
    by MI above chance (``above``) where there is one, else on the raw ranking
    (``table``); the other ranking's result and each rule's chance pass rate (a
    random ranking's, :func:`.relevance.chance_pass_rate`) are in the evidence."""
    paper = PAPER_RELEVANCE.get(task)
    if table is None or paper is None:
        return []
    judged = above if above is not None else table
    basis = "MI above chance" if above is not None else "raw MI (no chance level here)"
    statistic = f"NS-SD+ ranking by {basis}"
    title = task_title(task)
    m = len(paper)
    d = len(judged.names)
    need = math.ceil(m / 2)

    def overlap(ranking: RelevanceTable) -> list[str]:
        top = ranking.top(m).names
        return [f.name for f in paper if f.name in top]

    shared = overlap(judged)
    listed = sum(f.name in judged.names for f in paper)
    first = paper[0]
    rank = judged.rank_of(first.name)
    other = "" if above is None else f"; raw MI: {len(overlap(table))} of {m}"
    claims = [
        Claim(
            "relevance",
            task,
            f"the most relevant features of {title} are those of the paper's table",
            ", ".join(f.label or f.name for f in paper),
            f"by {basis}: {len(shared)} of the paper's {m} are in our top {m} "
            f"({', '.join(shared) or 'none'}){other}; the paper's first, "
            f"{first.name}, is our #{rank} of {d}; our first: {judged.names[0]} "
            f"({judged.mean[0]:.2f} bits); a random ranking passes with "
            f"probability {chance_pass_rate(d, listed, m, need):.2g}",
            None,
            Verdict.AGREE if len(shared) >= need else Verdict.DISAGREE,
            statistic=statistic,
        )
    ]

    def matched(ranking: RelevanceTable) -> list[str]:
        top = ranking.top(m)
        return [n for n, t in zip(top.names, top.in_task_specific, strict=True) if t]

    found = matched(judged)
    other = "" if above is None else f"; raw MI: {', '.join(matched(table)) or 'none'}"
    marked = int(np.count_nonzero(judged.in_task_specific))
    claims.append(
        Claim(
            "relevance",
            task,
            f"some of the most relevant SDBC features of {title} match the "
            "task-specific characterisation",
            ", ".join(f.label or f.name for f in paper if f.in_task_specific),
            f"in our top {m} by {basis}: {', '.join(found) or 'none'}{other}; a "
            "random ranking passes with probability "
            f"{chance_pass_rate(d, marked, m, 1):.2g} ({marked} of {d} dimensions "
            "are in the task-specific characterisation)",
            None,
            Verdict.AGREE if found else Verdict.DISAGREE,
            statistic=statistic,
        )
    )
    top = judged.top(m)
    informative = top.mean > 0
    if judged.runs > 1 and informative.any():
        cv = float(np.median(top.sd[informative] / top.mean[informative]))
        raw_top = table.top(m)
        raw_cv = float(
            np.median(raw_top.sd[raw_top.mean > 0] / raw_top.mean[raw_top.mean > 0])
        )
        other = "" if above is None else f"; on raw MI {_fmt(raw_cv)}"
        claims.append(
            Claim(
                "relevance",
                task,
                f"feature relevance is consistent across runs in {title} (small SD)",
                "SD / mean 0.01-0.11",
                f"median SD / mean of our top {m} by {basis}: {_fmt(cv)} over "
                f"{judged.runs} runs{other}",
                None,
                Verdict.AGREE if cv < CONSISTENT_CV else Verdict.DISAGREE,
                statistic=statistic,
            )
        )
    return claims


def _metric_test(maps: MapNumbers, metric: str, a: str, b: str) -> PairTest | None:
    if a not in maps.treatments or b not in maps.treatments:
        return None
    values = {t: getattr(maps, metric)(k) for k, t in enumerate(maps.treatments)}
    return mann_whitney(maps.task, a, b, values[a], values[b])


def exploration_claims(maps: MapNumbers, alpha: float = ALPHA) -> list[Claim]:
    """The paper's reading of its exploration maps, tested on ``maps.task`` (none
    for a task the paper did not run); the tests are one family for Holm."""
    if not is_paper_task(maps.task):
        return []
    title = task_title(maps.task)
    planned: list[tuple[str, PairTest, str]] = []

    def add(statement: str, test: PairTest | None, what: str) -> None:
        if test is not None:
            planned.append((statement, test, what))

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
    adjusted = holm([test for _, test, _ in planned])
    return [
        Claim(
            "exploration",
            maps.task,
            statement,
            "figure 3 (resource sharing; 'similar' in the others)",
            evidence(test, what),
            test.p,
            above(test, alpha),
            test,
            f"per-run {what} of the SOM map",
        )
        for (statement, _, what), test in zip(planned, adjusted, strict=True)
    ]


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
        evidence: Medians, run counts, effect with its interval, p-values.
        p: The test's raw p-value.
        effect: A = U / (n_a n_b), the chance that a run of ``a`` beats one of ``b``.
        verdict: Agree (held), disagree (did not hold) or inconclusive.
    """

    prediction: Prediction
    task: str
    evidence: str
    p: float
    effect: float
    verdict: Verdict
    test: PairTest | None = None

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
                test=test,
            )
        )
    return results
