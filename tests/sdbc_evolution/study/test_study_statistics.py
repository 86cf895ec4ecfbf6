"""The statistics behind the claims, on numbers worked out by hand."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from sdbc_evolution.ga.treatments import PAPER_TREATMENTS
from sdbc_evolution.study.claims import (
    Verdict,
    above,
    find_test,
    no_difference,
    not_below,
    quality_claims,
    totals,
)
from sdbc_evolution.study.cost import TaskCost, projected_hours
from sdbc_evolution.study.exploration import (
    ExplorationMaps,
    SomSettings,
    best_matching_units,
    high_fitness_region,
)
from sdbc_evolution.study.presets import StudyPreset
from sdbc_evolution.study.quality import (
    holm,
    mann_whitney,
    pairwise_tests,
    vargha_delaney,
)

FIT, TS, SD, PLUS = PAPER_TREATMENTS


def test_mann_whitney_on_separated_and_tied_samples() -> None:
    # 3 vs 3 fully separated: exact two-sided p = 2 / C(6, 3) = 0.1, U = 0.
    test = mann_whitney("t", FIT, TS, np.array([1.0, 2, 3]), np.array([4.0, 5, 6]))
    assert test.u == 0 and test.effect == 0
    assert test.p == pytest.approx(0.1)
    assert (test.median_a, test.median_b, test.mean_a, test.mean_b) == (2, 5, 2, 5)
    tied = mann_whitney("t", FIT, TS, np.zeros(3), np.zeros(3))
    assert tied.p == 1.0 and tied.effect == 0.5
    with pytest.raises(ValueError, match="no runs"):
        mann_whitney("t", FIT, TS, np.array([]), np.ones(2))


def test_pairwise_tests_cover_every_pair_in_order() -> None:
    bests = {t: np.arange(3.0) + i for i, t in enumerate(PAPER_TREATMENTS)}
    tests = pairwise_tests("t", bests)
    assert [(t.a, t.b) for t in tests] == [
        (FIT, TS), (FIT, SD), (FIT, PLUS), (TS, SD), (TS, PLUS), (SD, PLUS),
    ]  # fmt: skip


def test_verdict_rules() -> None:
    low, high = np.arange(10.0), np.arange(10.0) + 100
    significant_up = mann_whitney("t", TS, FIT, high, low)
    significant_down = mann_whitney("t", TS, FIT, low, high)
    unclear = mann_whitney("t", TS, FIT, low, low + 0.5)
    assert significant_up.p < 0.05 < unclear.p
    assert above(significant_up) is Verdict.AGREE
    assert above(significant_down) is Verdict.DISAGREE
    assert above(unclear) is Verdict.INCONCLUSIVE
    # Not significant is not agreement: 10 runs a side leave A's interval wide.
    assert no_difference(unclear) is Verdict.INCONCLUSIVE
    assert no_difference(significant_up) is Verdict.DISAGREE
    assert not_below(significant_up) is Verdict.AGREE
    assert not_below(unclear) is Verdict.INCONCLUSIVE
    assert not_below(significant_down) is Verdict.DISAGREE


def test_no_difference_needs_a_narrow_interval_inside_the_margin() -> None:
    """Constructed samples: the same centre, A = 0.5 exactly; with 8 runs a side
    the interval is wide and the rule cannot tell, with 400 interleaved runs a
    side it lies inside (0.36, 0.64) and the rule agrees."""
    few = np.arange(8.0)
    wide = mann_whitney("t", SD, PLUS, few, few + 0.5)
    assert wide.p > 0.05 and wide.effect_low < 0.36 and wide.effect_high > 0.64
    assert no_difference(wide) is Verdict.INCONCLUSIVE
    assert not_below(wide) is Verdict.INCONCLUSIVE
    many = np.arange(400.0)
    narrow = mann_whitney("t", SD, PLUS, many[::2], many[1::2])
    assert narrow.effect == pytest.approx(0.4975)
    assert 0.36 < narrow.effect_low < narrow.effect < narrow.effect_high < 0.64
    assert no_difference(narrow) is Verdict.AGREE
    assert not_below(narrow) is Verdict.AGREE
    # Turned round, the interval is mirrored.
    turned = find_test([narrow], PLUS, SD)
    assert turned is not None
    assert turned.effect_low == pytest.approx(1 - narrow.effect_high)
    assert turned.effect_high == pytest.approx(1 - narrow.effect_low)


def test_effect_interval_is_seeded_and_covers_the_effect() -> None:
    rng = np.random.default_rng(3)
    x, y = rng.normal(1.0, 1.0, 12), rng.normal(0.0, 1.0, 12)
    first = mann_whitney("t", SD, PLUS, x, y)
    again = mann_whitney("t", SD, PLUS, x, y)
    assert (first.effect_low, first.effect_high) == (
        again.effect_low,
        again.effect_high,
    )
    assert first.effect_low < first.effect < first.effect_high
    assert first.effect == pytest.approx(float(vargha_delaney(x, y)))
    separated = mann_whitney("t", SD, PLUS, np.arange(5.0) + 10, np.arange(5.0))
    assert (separated.effect_low, separated.effect_high) == (1.0, 1.0)


def test_holm_adjusts_within_a_family() -> None:
    base = mann_whitney("t", SD, PLUS, np.arange(5.0), np.arange(5.0))
    family = [dataclasses.replace(base, p=p) for p in (0.04, 0.01, 0.03, 0.5)]
    # Sorted 0.01, 0.03, 0.04, 0.5: x4, x3 (0.09), x2 (0.08 -> stays 0.09), x1.
    assert [t.p_holm for t in holm(family)] == pytest.approx([0.09, 0.04, 0.09, 0.5])
    assert [t.adjusted_p for t in holm(family)][1] == pytest.approx(0.04)
    tests = pairwise_tests("t", {t: np.arange(3.0) for t in PAPER_TREATMENTS})
    assert all(t.p_holm is not None for t in tests)


def test_claims_on_one_test_count_once_in_the_totals() -> None:
    rng = np.random.default_rng(1)
    bests = {
        FIT: rng.uniform(0.0, 0.1, 10),
        TS: rng.uniform(0.9, 1.0, 10),
        SD: rng.uniform(0.7, 0.8, 10),
        PLUS: rng.uniform(0.5, 0.6, 10),
    }
    claims = quality_claims("predator_prey", pairwise_tests("predator_prey", bests))
    shared = [c for c in claims if "NS-SD+" in c.statement and "NS-SD " in c.statement]
    # NS-SD+ below NS-SD: 'no difference' and 'not below' both disagree, one test.
    assert [c.verdict for c in shared] == [Verdict.DISAGREE, Verdict.DISAGREE]
    assert shared[0].test_key == shared[1].test_key
    counts = totals(claims)
    assert sum(counts.values()) == len(claims) - 1
    assert counts[Verdict.DISAGREE] == 1


def test_quality_claims_follow_the_paper_per_task() -> None:
    rng = np.random.default_rng(0)
    bests = {
        FIT: rng.uniform(0.0, 0.1, 10),
        TS: rng.uniform(0.9, 1.0, 10),
        SD: rng.uniform(0.5, 0.6, 10),
        PLUS: rng.uniform(0.7, 0.8, 10),
    }
    gate = {
        c.statement: c.verdict
        for c in quality_claims("gate_escape", pairwise_tests("gate_escape", bests))
    }
    assert gate["NS-TS above NS-SD+ in gate escape"] is Verdict.AGREE
    assert (
        gate["NS-SD+ reaches higher fitness than Fit in gate escape"] is Verdict.AGREE
    )
    # The paper: NS-SD and NS-SD+ differ only in resource sharing.
    assert (
        gate["NS-SD and NS-SD+ do not differ significantly in gate escape"]
        is Verdict.DISAGREE
    )
    sharing = {
        c.statement: c.verdict
        for c in quality_claims(
            "resource_sharing", pairwise_tests("resource_sharing", bests)
        )
    }
    assert sharing["NS-SD+ above NS-SD in resource sharing"] is Verdict.AGREE
    assert len(sharing) == len(gate) == 6


def _maps(counts: np.ndarray, pooled: np.ndarray) -> ExplorationMaps:
    settings = SomSettings(rows=2, columns=2, high_fitness_units=0.25)
    return ExplorationMaps(
        task="t",
        settings=settings,
        treatments=(FIT,),
        run_names=(("a", "b"),),
        counts=(counts,),
        percentile=pooled[None],
        pooled_percentile=pooled,
        sample_count=4,
        quantisation_error=0.0,
    )


def test_uniformity_coverage_and_region_share() -> None:
    counts = np.array([[3, 3, 3, 3], [5, 0, 0, 0]])
    # The best of four occupied units (a quarter of them) is the region.
    maps = _maps(counts, np.array([0.9, 0.1, 0.2, 0.1]))
    np.testing.assert_array_equal(maps.region, [True, False, False, False])
    np.testing.assert_allclose(maps.shares[0][0], [0.25, 0.25, 0.25, 0.25])
    np.testing.assert_allclose(maps.mean_share[0], [0.625, 0.125, 0.125, 0.125])
    np.testing.assert_allclose(maps.uniformity(0), [1.0, 0.0])
    np.testing.assert_allclose(maps.coverage(0), [1.0, 0.25])
    np.testing.assert_allclose(maps.region_share(0), [0.25, 1.0])


def test_best_matching_units_are_the_nearest_units() -> None:
    rng = np.random.default_rng(1)
    weights = rng.normal(size=(7, 3))
    z = rng.normal(size=(5000, 3))
    nearest = np.argmin(((z[:, None, :] - weights[None]) ** 2).sum(axis=2), axis=1)
    np.testing.assert_array_equal(best_matching_units(weights, z), nearest)


def test_projection_by_hand() -> None:
    cost = TaskCost(
        task="gate_escape",
        runs=1,
        bodies=4,
        max_steps=1000,
        mean_length=500.0,
        rate=1e6,
        serial_per_individual=1e-3,
        seconds_per_generation=1.0,
        run_seconds=1.0,
    )
    paper = StudyPreset(name="paper")
    # 80 runs x 500 generations x (1e-3 x 200 + 4 x 500 x (200 x 10 + 50) / 1e6 / W).
    count = 80 * 500
    serial, evaluation = 0.2, 4 * 500 * 2050 / 1e6
    for workers in (1, 8, 200):
        wall, cpu = projected_hours(cost, paper, workers, 500.0)
        assert wall == pytest.approx(count * (serial + evaluation / workers) / 3600)
        assert cpu == pytest.approx(count * (serial + evaluation) / 3600)
    # Beyond one worker per controller, more workers do not help.
    assert projected_hours(cost, paper, 512, 500.0) == projected_hours(
        cost, paper, 200, 500.0
    )


def test_high_fitness_region_takes_the_top_units_and_never_the_floor() -> None:
    nan = np.nan
    pooled = np.array([0.2, 0.9, nan, 0.5, 0.9, 0.2, 0.3, 0.2, 0.2, 0.2, 0.4])
    # 10 occupied units, 20 %: the two best (both 0.9).
    np.testing.assert_array_equal(
        np.flatnonzero(high_fitness_region(pooled, 0.2)), [1, 4]
    )
    # 30 %: the third best is 0.5, ties included.
    np.testing.assert_array_equal(
        np.flatnonzero(high_fitness_region(pooled, 0.3)), [1, 3, 4]
    )
    # Units at the floor never count, so an all-tied map has no region.
    assert not high_fitness_region(np.full(5, 0.2), 0.5).any()
    assert high_fitness_region(pooled, 1.0).sum() == 5
