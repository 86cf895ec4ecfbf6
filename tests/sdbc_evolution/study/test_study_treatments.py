"""A study of declared treatments end to end: the ``treatments-smoke`` preset (the
paper's four, NS-SD+ with chance-corrected MI, NS-SD on five time frames, NSLC on the
SDBC, the state-count baseline) runs, and its report compares all eight."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from sdbc_evolution.ga.treatments import PAPER_TREATMENTS, label
from sdbc_evolution.study.analysis import REPORT_FILE, TABLES_DIR
from sdbc_evolution.study.cli import main
from sdbc_evolution.study.plan import STUDY_FILE
from sdbc_evolution.study.presets import load_preset, load_preset_file

PRESET = load_preset("treatments-smoke")
NAMES = [t.name for t in PRESET.treatments]
DECLARED = [n for n in NAMES if n not in PAPER_TREATMENTS]


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("treatments") / "study"
    argv = ["--preset", "treatments-smoke", "--out", str(root), "--workers", "2"]
    assert main([*argv, "--quiet"]) == 0
    return root


def test_the_preset_holds_the_four_and_four_declared() -> None:
    assert NAMES[:4] == list(PAPER_TREATMENTS) and len(DECLARED) == 4
    assert {"ns-sd+chance", "ns-sd-frames5", "nslc-sdbc", "ns-state-count"} == set(
        DECLARED
    )


@pytest.mark.slow
def test_every_table_and_the_report_compare_all_eight(study: Path) -> None:
    tables = study / "report" / TABLES_DIR
    bests = read_csv(tables / "bests_predator_prey.csv")
    assert sorted({row["treatment"] for row in bests}) == sorted(NAMES)
    assert len(bests) == 2 * len(NAMES)
    header = read_csv(tables / "curves_predator_prey.csv")[0].keys()
    assert all(f"{name} mean" in header for name in NAMES)
    tests = read_csv(tables / "mann_whitney_predator_prey.csv")
    assert len(tests) == len(NAMES) * (len(NAMES) - 1) // 2
    exploration = read_csv(tables / "exploration_predator_prey.csv")
    assert sorted({row["treatment"] for row in exploration}) == sorted(NAMES)
    report = (study / "report" / REPORT_FILE).read_text()
    for name in NAMES:
        assert label(name) in report, name
    assert (tables / "relevance_predator_prey.csv").is_file()  # NS-SD+'s
    # Every weighting treatment has its relevance table, in its measure's units:
    # mi_chance's is the MI above its chance level, at least 0.
    chance = read_csv(tables / "relevance_predator_prey_ns-sd-pluschance.csv")
    assert len(chance) == len(read_csv(tables / "relevance_predator_prey.csv"))
    assert all(float(row["mean_relevance"]) >= 0 for row in chance)
    assert "#### ns-sd+chance: relevance by `mi_chance`" in report
    # Treatments that weigh nothing have none.
    # (NS-SD+'s raw MI also gets its ranking above chance.)
    assert sorted(p.name for p in tables.glob("relevance_*")) == [
        "relevance_above_chance_predator_prey.csv",
        "relevance_predator_prey.csv",
        "relevance_predator_prey_ns-sd-pluschance.csv",
    ]
    # The paper's claims concern its four treatments only.
    for claim in read_csv(tables / "claims.csv"):
        assert not any(name in claim["claim"] for name in DECLARED)


@pytest.mark.slow
def test_runs_keep_their_own_characterisation(study: Path) -> None:
    assert [t.name for t in load_preset_file(study / STUDY_FILE).treatments] == NAMES
    run = study / "predator_prey" / "ns-state-count" / "run_00"
    with np.load(run / "individuals" / "gen_00002.npz") as data:
        assert str(data["behaviour_names"][0]).startswith("State")
        np.testing.assert_allclose(data["behaviour"].sum(axis=1), 1.0, rtol=1e-5)
        assert data["sdbc"].shape[1] == len(data["sdbc_names"])
    frames = study / "predator_prey" / "ns-sd-frames5" / "run_01"
    with np.load(frames / "individuals" / "gen_00000.npz") as data:
        assert "Prey group size (frame 5/5)" in data["behaviour_names"]
