"""The exploration numbers' sensitivity to the map: maps of other seeds and grids
from the run directories, kept in the digest and reported the same from it; other
region sizes from any digest; each claim judged again on every setting."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from sdbc_evolution.study.analysis import (
    REPORT_FILE,
    TABLES_DIR,
    AnalysisSettings,
    analyse,
    analyse_digest_dir,
)
from sdbc_evolution.study.claims import FIT, NS_SD, NS_SD_PLUS, NS_TS, Verdict
from sdbc_evolution.study.cli import main, parse_grids
from sdbc_evolution.study.digest import DIGEST_DIR, read_digest
from sdbc_evolution.study.exploration import (
    REGION_FRACTIONS,
    ExplorationMaps,
    Sensitivity,
    SomSettings,
    default_grids,
)
from sdbc_evolution.study.sensitivity import MAP, REGION, sensitivity
from study_helpers import straight_study, tiny_preset

SOM = SomSettings(rows=4, columns=4, sample_size=40, iterations=300)
GRIDS = ((3, 3), (4, 4))


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return straight_study(tiny_preset(), tmp_path_factory.mktemp("maps") / "study")


@pytest.fixture(scope="module")
def report(study: Path) -> Path:
    out = study.parent / "report"
    settings = AnalysisSettings(som=SOM, sensitivity_seeds=2, sensitivity_grids=GRIDS)
    analyse(study, out, settings)
    return out


def test_the_map_of_the_studys_own_seed_and_grid_gives_the_maps_numbers(
    report: Path,
) -> None:
    maps = read_digest(report / DIGEST_DIR).task("gate_escape").maps
    found = maps.sensitivity
    assert found is not None
    assert found.seeds == (0, 1) and found.grids == GRIDS
    own = found.metrics(maps.task, maps.treatments, GRIDS.index((4, 4)), 0)
    for k in range(len(maps.treatments)):
        np.testing.assert_array_equal(own.uniformity(k), maps.uniformity(k))
        np.testing.assert_array_equal(own.region_share(k), maps.region_share(k))
        assert found.uniformity[k].shape == (2, 2, maps.counts[k].shape[0])
        assert ((found.region_share[k] >= 0) & (found.region_share[k] <= 1)).all()


def test_a_digest_with_sensitivity_rebuilds_its_tables_and_report(
    report: Path, tmp_path: Path
) -> None:
    analyse_digest_dir(report / DIGEST_DIR, tmp_path)
    for name in (
        "exploration_sensitivity_gate_escape.csv",
        "exploration_stability_gate_escape.csv",
    ):
        assert (tmp_path / TABLES_DIR / name).read_bytes() == (
            report / TABLES_DIR / name
        ).read_bytes()
    text = (tmp_path / REPORT_FILE).read_text()
    assert "trained again with seeds 0-1 on grids 3 x 3, 4 x 4 (4 maps" in text
    rows = (
        tmp_path / TABLES_DIR / "exploration_sensitivity_gate_escape.csv"
    ).read_text()
    # 4 maps and 3 region sizes, each for both treatments.
    assert len(rows.splitlines()) == 1 + 2 * (4 + len(REGION_FRACTIONS))


def test_a_digest_without_sensitivity_says_the_map_was_not_varied(
    study: Path, tmp_path: Path
) -> None:
    analysis = analyse(study, tmp_path, AnalysisSettings(som=SOM))
    assert [s.kind for s in analysis.tasks[0].sensitivity] == [REGION]
    assert (
        "The SOM's seed and grid: not measured" in (tmp_path / REPORT_FILE).read_text()
    )
    with np.load(tmp_path / DIGEST_DIR / "gate_escape.npz") as npz:
        assert not [k for k in npz.files if k.startswith("som_sensitivity")]


def _maps(
    shares: dict[str, np.ndarray], pooled: np.ndarray, found: Sensitivity | None
) -> ExplorationMaps:
    """Four treatments of ten runs on a map of ``pooled`` percentiles, each
    run's individuals over the units as ``shares`` says (per treatment, one
    row for all its runs, scaled by the run's index so runs differ)."""
    treatments = tuple(shares)
    counts = tuple(
        np.stack([np.round(s * (100 + 7 * r)).astype(np.int64) for r in range(10)])
        for s in shares.values()
    )
    return ExplorationMaps(
        task="predator_prey",
        settings=SomSettings(rows=2, columns=5, high_fitness_units=0.1),
        treatments=treatments,
        run_names=tuple(tuple(f"{t}/run_{r}" for r in range(10)) for t in treatments),
        counts=counts,
        percentile=np.stack([pooled] * len(treatments)),
        pooled_percentile=pooled,
        sample_count=10,
        quantisation_error=0.0,
        sensitivity=found,
    )


REGION_CLAIM = (
    "NS-SD+ spends more effort in the high-fitness region than NS-SD in "
    "predator-prey pursuit"
)
UNITS = 10
POOLED = np.linspace(0.0, 0.9, UNITS)
"""Unit 9 is the best (the 10 % region), unit 8 joins it at 20 %."""


def _share(region: float, second: float) -> np.ndarray:
    rest = (1.0 - region - second) / (UNITS - 2)
    return np.array([rest] * (UNITS - 2) + [second, region])


def test_region_sizes_rejudge_the_region_claims_only() -> None:
    # NS-SD+ holds far more of the best unit than NS-SD; NS-SD far more of the
    # second best, so at 20 % NS-SD+ is no longer ahead.
    maps = _maps(
        {
            FIT: _share(0.1, 0.1),
            NS_TS: _share(0.1, 0.1),
            NS_SD: _share(0.0, 0.6),
            NS_SD_PLUS: _share(0.5, 0.0),
        },
        POOLED,
        None,
    )
    assert sensitivity(maps, MAP) is None
    found = sensitivity(maps, REGION)
    assert found is not None
    assert [s.fraction for s in found.settings] == list(REGION_FRACTIONS)
    claims = {c.statement: c for c in found.claims}
    assert len(claims) == 2  # uniformity does not move with the region
    plus = claims[REGION_CLAIM]
    assert plus.verdict is Verdict.AGREE
    assert [v for v in plus.verdicts] == [
        Verdict.AGREE,
        Verdict.AGREE,
        Verdict.DISAGREE,
    ]
    assert plus.same == 2 and plus.count(Verdict.DISAGREE) == 1
    k = found.treatments.index(NS_SD_PLUS)
    np.testing.assert_allclose(found.shares[k], [0.5, 0.5, 0.5], atol=0.01)
    np.testing.assert_allclose(found.on_map, found.shares[:, 1])


def test_maps_of_other_seeds_count_the_settings_with_the_same_verdict() -> None:
    shares = {
        FIT: _share(0.1, 0.1),
        NS_TS: _share(0.1, 0.1),
        NS_SD: _share(0.05, 0.1),
        NS_SD_PLUS: _share(0.5, 0.1),
    }
    base = _maps(shares, POOLED, None)
    metrics = base.metrics()
    uniformity = [np.stack([np.stack([metrics.uniformity(k)] * 3)]) for k in range(4)]
    region = [np.stack([np.stack([metrics.region_share(k)] * 3)]) for k in range(4)]
    # On the third seed's map NS-SD+ and NS-SD trade places.
    plus, sd = list(shares).index(NS_SD_PLUS), list(shares).index(NS_SD)
    region[plus][0, 2], region[sd][0, 2] = (
        region[sd][0, 2].copy(),
        region[plus][0, 2].copy(),
    )
    found = Sensitivity((0, 1, 2), ((2, 5),), tuple(uniformity), tuple(region))
    result = sensitivity(_maps(shares, POOLED, found), MAP)
    assert result is not None
    assert [s.label for s in result.settings] == [f"seed {s}, 2 x 5" for s in range(3)]
    claims = {c.statement: c for c in result.claims}
    assert len(claims) == 7
    moved = claims[REGION_CLAIM]
    assert moved.verdict is Verdict.AGREE
    assert (moved.same, moved.count(Verdict.DISAGREE), len(moved.verdicts)) == (2, 1, 3)
    uniform = claims[
        "NS-SD explores more uniformly than NS-TS in predator-prey pursuit"
    ]
    assert uniform.same == 3
    assert result.shares[plus].tolist() == pytest.approx([0.5, 0.5, 0.05], abs=0.01)


def test_default_grids_scale_the_map() -> None:
    assert default_grids(SomSettings()) == ((10, 10), (15, 15), (20, 20))
    assert default_grids(SomSettings(rows=2, columns=3)) == ((2, 2), (2, 3))


def test_grids_are_parsed_and_bad_ones_refused() -> None:
    assert parse_grids("10x10, 15X15,20x12") == ((10, 10), (15, 15), (20, 12))
    for bad in ("10", "10x", "axb", "1x5", "10x10;15x15"):
        with pytest.raises(ValueError, match="--som-grids"):
            parse_grids(bad)


def test_som_seeds_need_the_run_directories(
    report: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    digest = str(report / DIGEST_DIR)
    assert main(["analyse", "--from-digest", digest, "--som-seeds", "2"]) == 2
    assert "does not keep: give the study directory" in capsys.readouterr().err
    assert main(["analyse", "--from-digest", digest, "--som-grids", "3x3"]) == 2
    assert "--som-grids is the grids of --som-seeds" in capsys.readouterr().err
    assert main(["analyse", "--from-digest", digest, "--som-seeds", "-1"]) == 2
