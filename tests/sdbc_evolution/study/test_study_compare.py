"""sdbc-study compare: two analyses' claims side by side."""

from __future__ import annotations

from pathlib import Path

import pytest
from sdbc_evolution.study.cli import main
from sdbc_evolution.study.compare import (
    CompareError,
    comparison_page,
    read_claims,
    read_reasons,
)
from study_helpers import write_claims

A = "NS-SD+ above Fit in resource sharing"
B = "NS-TS above Fit in resource sharing"
C = "NS-SD+ above Fit in gate escape"


@pytest.fixture
def studies(tmp_path: Path) -> tuple[Path, Path]:
    before = write_claims(
        tmp_path / "v1",
        [
            ("resource_sharing", A, "p = 0.4", "inconclusive"),
            ("resource_sharing", B, "p = 0.01", "agree"),
            ("gate_escape", C, "p = 0.02", "agree"),
        ],
    )
    after = write_claims(
        tmp_path / "v2",
        [
            ("resource_sharing", A, "p = 0.003", "agree"),
            ("resource_sharing", B, "p = 0.3", "inconclusive"),
        ],
    )
    return before, after


def test_changed_verdicts_with_both_studies_evidence(studies) -> None:
    before, after = (read_claims(s) for s in studies)
    page, found = comparison_page(
        before, after, {A: "robots now stop on the station"}, ("v1", "v2")
    )
    assert [c.after.statement for c in found] == [A, B]
    assert "- v1: 3 claims: 2 agree, 0 disagree, 1 inconclusive." in page
    assert "- v2: 2 claims: 1 agree, 0 disagree, 1 inconclusive." in page
    # The earlier study on the tasks both ran, and what the later one lacks.
    assert "on the tasks both studies ran (resource sharing): 2 claims" in page
    assert "Not run in v2: gate escape." in page
    assert (
        f"| {A} | **inconclusive**: p = 0.4 | **agree**: p = 0.003 | "
        "robots now stop on the station |"
    ) in page
    assert f"| {B} | **agree**: p = 0.01 | **inconclusive**: p = 0.3 | " in page
    assert "(not explained) |" in page


def test_the_command_names_unexplained_changes(studies, tmp_path, capsys) -> None:
    reasons = tmp_path / "why.yaml"
    reasons.write_text(f"{A}: >-\n  robots now\n  stop on the station\n")
    out = tmp_path / "comparison.md"
    code = main(
        ["compare", *map(str, studies), "--reasons", str(reasons), "--out", str(out)]
    )
    assert code == 0
    assert "robots now stop on the station" in out.read_text()
    err = capsys.readouterr().err
    assert f"not explained: {B}" in err
    assert f"not explained: {A}" not in err


def test_bad_input_is_named(studies, tmp_path, capsys) -> None:
    with pytest.raises(CompareError, match="claims.csv: missing"):
        read_claims(tmp_path / "nowhere")
    bad = write_claims(tmp_path / "bad", [("gate_escape", C, "", "maybe")])
    with pytest.raises(CompareError, match="claims.csv:2: unknown verdict 'maybe'"):
        read_claims(bad)
    listed = tmp_path / "why.yaml"
    listed.write_text("- a list\n")
    with pytest.raises(CompareError, match="must map claim statements"):
        read_reasons(listed)
    assert main(["compare", str(studies[0]), str(studies[1]), "--names", "x"]) == 2
    assert "--names: two names" in capsys.readouterr().err


STUDIES = Path(__file__).resolve().parents[3] / "docs" / "study"


COMPARISONS = {
    "local": ("local-v1", "the first local study,the second local study"),
    "local_kinematic": (
        "local",
        "the second local study (rigid bodies),the kinematic local study",
    ),
}
"""Committed comparison pages: the later study's folder -> (the earlier study's
folder, the names the page gives the two)."""


@pytest.mark.parametrize("later", sorted(COMPARISONS))
def test_the_committed_comparison_is_current_and_explains_every_change(
    later: str, tmp_path: Path, capsys
) -> None:
    """docs/study/LATER/comparison.md is what the command makes from the two
    committed studies, and every changed verdict has its reason."""
    earlier, names = COMPARISONS[later]
    out = tmp_path / "comparison.md"
    argv = [
        "compare",
        str(STUDIES / earlier),
        str(STUDIES / later),
        "--names",
        names,
        "--reasons",
        str(STUDIES / later / "comparison-reasons.yaml"),
        "--out",
        str(out),
    ]
    assert main(argv) == 0
    assert "not explained" not in capsys.readouterr().err
    assert out.read_text() == (STUDIES / later / "comparison.md").read_text()
