"""The smoke study end to end, and the analysis's figures and tables well-formed.

One smoke study (the ``smoke`` preset, every task and treatment, through the
``sdbc-study`` command) is made once for the module; the tests read its outputs.
"""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from sdbc_evolution.run.results import read_generations
from sdbc_evolution.sdbc.characterisation import dimension_names
from sdbc_evolution.study.analysis import FIGURES_DIR, REPORT_FILE, TABLES_DIR
from sdbc_evolution.study.claims import ALPHA, EQUIVALENCE_MARGIN
from sdbc_evolution.study.cli import main
from sdbc_evolution.study.plan import study_plan
from sdbc_evolution.study.presets import load_preset, preset_from_dict
from sdbc_evolution.study.relevance import task_specific_features
from sdbc_evolution.study.rundirs import load_study
from sdbc_evolution.study.runner import prepare_study_directory
from sdbc_sim.tasks import make_task

SMOKE = load_preset("smoke")
TASKS = SMOKE.tasks


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def smoke(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("smoke") / "study"
    assert (
        main(["--preset", "smoke", "--out", str(root), "--workers", "2", "--quiet"])
        == 0
    )
    return root


@pytest.mark.slow
def test_smoke_study_makes_every_figure_and_table(smoke: Path) -> None:
    report = smoke / "report"
    for task in TASKS:
        for figure in ("curves", "bests", "exploration"):
            path = report / FIGURES_DIR / f"{figure}_{task}.png"
            with Image.open(path) as image:
                assert image.format == "PNG" and min(image.size) >= 200
        for table in (
            "curves",
            "bests",
            "mann_whitney",
            "relevance",
            "exploration",
        ):
            assert read_csv(report / TABLES_DIR / f"{table}_{task}.csv"), table
    for table in ("claims", "cost", "projection"):
        assert read_csv(report / TABLES_DIR / f"{table}.csv"), table
    assert read_csv(report / TABLES_DIR / "problems.csv") == []


@pytest.mark.slow
def test_curves_have_one_point_per_generation_and_bests_match_runs(
    smoke: Path,
) -> None:
    study = load_study(smoke)
    for task in TASKS:
        rows = read_csv(smoke / "report" / TABLES_DIR / f"curves_{task}.csv")
        assert [int(r["generation"]) for r in rows] == list(
            range(SMOKE.generations_of(task))
        )
        for treatment in SMOKE.treatments:
            runs = study.of(task, treatment)
            values = np.array(
                [read_generations(r.path)["reevaluated_fitness"] for r in runs]
            )
            mean = [float(r[f"{treatment.name} mean"]) for r in rows]
            np.testing.assert_allclose(mean, values.mean(axis=0), rtol=1e-12)
            assert {int(r[f"{treatment.name} n"]) for r in rows} == {SMOKE.runs}
        bests = read_csv(smoke / "report" / TABLES_DIR / f"bests_{task}.csv")
        assert len(bests) == SMOKE.runs * len(SMOKE.treatments)
        for row in bests:
            column = read_generations(smoke / row["run"])["reevaluated_fitness"]
            assert float(row["best"]) == float(np.nanmax(column))


@pytest.mark.slow
def test_every_p_value_is_in_the_unit_interval(smoke: Path) -> None:
    tables = smoke / "report" / TABLES_DIR
    for task in TASKS:
        rows = read_csv(tables / f"mann_whitney_{task}.csv")
        assert len(rows) == 6  # every pair of 4 treatments
        for row in rows:
            assert 0.0 <= float(row["p"]) <= 1.0
            assert 0.0 <= float(row["A"]) <= 1.0
    claims = read_csv(tables / "claims.csv")
    assert {c["verdict"] for c in claims} <= {"agree", "disagree", "inconclusive"}
    assert {c["topic"] for c in claims} == {"quality", "relevance", "exploration"}
    for claim in claims:
        if claim["p"]:
            assert 0.0 <= float(claim["p"]) <= 1.0


@pytest.mark.slow
def test_relevance_names_are_the_characterisation_dimensions(smoke: Path) -> None:
    study = load_study(smoke)
    for task in TASKS:
        names = dimension_names(make_task(task).description)
        rows = read_csv(smoke / "report" / TABLES_DIR / f"relevance_{task}.csv")
        assert sorted(r["feature"] for r in rows) == sorted(names)
        assert [int(r["rank"]) for r in rows] == list(range(1, len(names) + 1))
        means = [float(r["mean_mi_bits"]) for r in rows]
        assert means == sorted(means, reverse=True)
        matched = {n for ns in task_specific_features(task).values() for n in ns}
        assert {r["feature"] for r in rows if r["in_task_specific"] == "True"} == (
            matched
        )
        # MI = weight - delta, averaged over generations, then over runs.
        per_run = []
        for run in study.of(task, "ns-sd+"):
            columns = read_generations(run.path)
            per_run.append({n: np.mean(columns[f"weight:{n}"]) - 0.25 for n in names})
        for row in rows:
            expected = np.mean([r[row["feature"]] for r in per_run])
            assert float(row["mean_mi_bits"]) == pytest.approx(expected, abs=1e-12)
            assert 0.0 <= float(row["chance_mi_bits"]) < 4.0


@pytest.mark.slow
def test_som_shares_of_every_run_sum_to_one(smoke: Path) -> None:
    for task in TASKS:
        with np.load(smoke / "report" / TABLES_DIR / f"exploration_{task}.npz") as data:
            treatments = list(data["treatments"])
            assert treatments == [t.name for t in SMOKE.treatments]
            units = 20 * 20
            for k, treatment in enumerate(treatments):
                shares = data[f"shares_{treatment}"]
                assert shares.shape == (SMOKE.runs, units)
                assert (shares >= 0).all()
                np.testing.assert_allclose(shares.sum(axis=1), 1.0, rtol=1e-12)
                np.testing.assert_allclose(data["mean_share"][k].sum(), 1.0)
                visited = data["mean_share"][k] > 0
                assert (np.isfinite(data["percentile"][k]) == visited).all()
                assert len(data[f"runs_{treatment}"]) == SMOKE.runs
            region, pooled = data["region"], data["pooled_percentile"]
            assert np.isfinite(pooled[region]).all()
            if region.any():
                assert pooled[region].min() > np.nanmax(pooled[~region], initial=-1)
        rows = read_csv(smoke / "report" / TABLES_DIR / f"exploration_{task}.csv")
        for row in rows:
            assert 0.0 <= float(row["uniformity"]) <= 1.0
            assert 0.0 < float(row["coverage"]) <= 1.0
            assert 0.0 <= float(row["high_fitness_share"]) <= 1.0


@pytest.mark.slow
def test_report_shows_every_figure_and_the_claims(smoke: Path) -> None:
    report = smoke / "report"
    text = (report / REPORT_FILE).read_text()
    for figure in sorted((report / FIGURES_DIR).glob("*.png")):
        assert f"]({FIGURES_DIR}/{figure.name})" in text
    for heading in (
        "## What ran",
        "## The paper's claims, one by one",
        "## Gate escape",
        "## Resource sharing",
        "## Predator-prey pursuit",
        "## Where we differ, and why we might",
        "## Cost, and the paper's study on a cluster",
    ):
        assert heading in text
    assert "sdbc-study all --preset smoke" in text
    assert "24 usable runs of 24 expected." in text
    assert "hours on W = 512" in text


@pytest.mark.slow
def test_missing_and_truncated_runs_are_named_and_the_rest_analysed(
    smoke: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = tmp_path / "damaged"
    shutil.copytree(smoke, root, ignore=shutil.ignore_patterns("report"))
    plan = {s.name: s for s in study_plan(SMOKE, root)}
    truncated = plan["gate_escape/fit/run_00"].path
    text = (truncated / "generations.csv").read_text()
    (truncated / "generations.csv").write_text(text[: len(text) - 40])
    corrupt = plan["gate_escape/ns-ts/run_01"].path / "individuals" / "gen_00001.npz"
    corrupt.write_bytes(corrupt.read_bytes()[:200])
    absent_file = plan["resource_sharing/ns-sd/run_00"].path / "individuals"
    (absent_file / "gen_00002.npz").unlink()
    shutil.rmtree(plan["predator_prey/ns-sd-plus/run_01"].path)
    assert main(["analyse", str(root)]) == 0
    said = capsys.readouterr().err
    problems = {
        r["run"]: r["reason"]
        for r in read_csv(root / "report" / TABLES_DIR / "problems.csv")
    }
    assert set(problems) == {
        "gate_escape/fit/run_00",
        "gate_escape/ns-ts/run_01",
        "resource_sharing/ns-sd/run_00",
        "predator_prey/ns-sd-plus/run_01",
    }
    assert "cells" in problems["gate_escape/fit/run_00"]
    assert "gen_00001.npz unreadable" in problems["gate_escape/ns-ts/run_01"]
    assert "gen_00002.npz is missing" in problems["resource_sharing/ns-sd/run_00"]
    assert problems["predator_prey/ns-sd-plus/run_01"] == "missing"
    for name in problems:
        assert f"left out {name}" in said
    report = (root / "report" / REPORT_FILE).read_text()
    assert "20 usable runs of 24 expected." in report
    assert "`gate_escape/fit/run_00`" in report
    bests = read_csv(root / "report" / TABLES_DIR / "bests_gate_escape.csv")
    assert len(bests) == 6
    # A run still going (fewer rows than its generations) is left out too.
    rows = (plan["resource_sharing/fit/run_01"].path / "generations.csv").read_text()
    lines = rows.splitlines(keepends=True)
    (plan["resource_sharing/fit/run_01"].path / "generations.csv").write_text(
        "".join(lines[:-1])
    )
    study = load_study(root)
    assert any(
        p.name == "resource_sharing/fit/run_01" and "truncated: " in p.reason
        for p in study.problems
    )


@pytest.mark.slow
def test_the_presets_predictions_are_judged_from_the_mann_whitney_table(
    smoke: Path, tmp_path: Path
) -> None:
    """Predictions added to a finished study are judged on every task they
    concern by their rule, from the same tests as the Mann-Whitney tables, and
    come out the same from the digest."""
    root = tmp_path / "predicted"
    shutil.copytree(smoke, root, ignore=shutil.ignore_patterns("report"))
    predictions = [
        {"statement": "NS-SD+ beats Fit", "a": "ns-sd+", "b": "fit", "rule": "above"},
        {
            "statement": "NS-TS and NS-SD alike",
            "a": "ns-ts",
            "b": "ns-sd",
            "rule": "no_difference",
            "tasks": ["resource_sharing"],
        },
        {
            "statement": "Fit not below NS-SD",
            "a": "fit",
            "b": "ns-sd",
            "rule": "not_below",
        },
    ]
    preset = preset_from_dict({**SMOKE.to_dict(), "predictions": predictions})
    prepare_study_directory(preset, root)
    assert main(["analyse", str(root)]) == 0
    rows = read_csv(root / "report" / TABLES_DIR / "predictions.csv")
    assert [(r["task"], r["a"]) for r in rows] == [
        (task, p["a"])
        for task in TASKS
        for p in predictions
        if task in p.get("tasks", [task])
    ]
    low_margin, high_margin = EQUIVALENCE_MARGIN
    for row in rows:
        p, holm, effect, low, high = _pair_test(
            root / "report", row["task"], row["a"], row["b"]
        )
        assert float(row["p"]) == p and float(row["p_holm"]) == holm
        assert (float(row["A_low"]), float(row["A_high"])) == (low, high)
        significant = holm < ALPHA
        if row["rule"] == "above":
            expected = "held" if effect > 0.5 else "did not hold"
            expected = expected if significant else "cannot tell"
        elif row["rule"] == "no_difference":
            inside = low_margin < low and high < high_margin
            expected = (
                "held" if inside else "did not hold" if significant else "cannot tell"
            )
        else:
            expected = (
                "held"
                if low > low_margin
                else "did not hold"
                if significant and effect < 0.5
                else "cannot tell"
            )
        assert row["outcome"] == expected, row
    report = (root / "report" / REPORT_FILE).read_text()
    section = report.split("## The study's predictions")[1].split("\n## ")[0]
    assert section.count("| **") == len(rows)
    assert "NS-SD+ not below" not in section
    assert "Fit not below NS-SD by more than the margin" in section
    again = tmp_path / "again"
    digest = str(root / "report" / "digest")
    assert main(["analyse", "--from-digest", digest, "--out", str(again)]) == 0
    assert (again / REPORT_FILE).read_text() == report


def _pair_test(
    report: Path, task: str, a: str, b: str
) -> tuple[float, float, float, float, float]:
    """p, Holm p, A and A's interval of ``a`` against ``b`` from the report's
    Mann-Whitney table."""
    for row in read_csv(report / TABLES_DIR / f"mann_whitney_{task}.csv"):
        p, holm = float(row["p"]), float(row["p_holm"])
        effect, low, high = float(row["A"]), float(row["A_low"]), float(row["A_high"])
        if (row["a"], row["b"]) == (a, b):
            return p, holm, effect, low, high
        if (row["a"], row["b"]) == (b, a):
            return p, holm, 1 - effect, 1 - high, 1 - low
    raise AssertionError(f"no test of {a} against {b} in {task}")


def test_task_specific_features_name_real_dimensions() -> None:
    for task in TASKS:
        built = make_task(task)
        names = set(dimension_names(built.description))
        features = task_specific_features(task)
        assert set(features) == set(built.characterisation_names), task
        for feature, dimensions in features.items():
            assert set(dimensions) <= names, (task, feature)


def test_analysing_a_directory_without_runs_is_a_clear_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["analyse", str(tmp_path)]) == 2
    assert "no usable run under" in capsys.readouterr().err
    assert main(["analyse", str(tmp_path / "absent")]) == 2
    assert "no study directory" in capsys.readouterr().err
