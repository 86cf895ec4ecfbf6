"""sdbc-study verdicts: several analyses' claims side by side under the same rules,
each disagreement with its declared cause, tested or untested."""

from __future__ import annotations

from pathlib import Path

import pytest
from sdbc_evolution.study.cli import main
from sdbc_evolution.study.compare import CompareError
from sdbc_evolution.study.verdicts import (
    NOT_JUDGED,
    NOT_RUN,
    read_causes,
    read_study,
    verdicts_page,
)
from study_helpers import write_claims

REPOSITORY = Path(__file__).resolve().parents[3]
STUDIES = REPOSITORY / "docs" / "study"
CAUSES = STUDIES / "disagreement-causes.yaml"
PAGE = STUDIES / "verdicts.md"


def page_studies() -> list[str]:
    """The studies of the committed page, in its order: the first column of its
    first table, each a folder of docs/study/ (the page names them so)."""
    lines = PAGE.read_text().splitlines()
    start = lines.index("| study | tasks | claims | agree | disagree | inconclusive |")
    rows = []
    for line in lines[start + 2 :]:
        if not line.startswith("| "):
            break
        rows.append(line.split(" | ")[0].removeprefix("| "))
    return rows


GE = "NS-SD+ above Fit in gate escape"
PP = "NS-SD above NS-SD+ in predator-prey pursuit"
PP2 = "NS-TS above Fit in predator-prey pursuit"
REL = (
    "the most relevant features of predator-prey pursuit are those of the paper's table"
)


ROWS = {
    "first": [
        ("gate_escape", GE, "0.8", "agree"),
        ("predator_prey", PP, "0.2", "disagree"),
        ("predator_prey", PP2, "0.7", "inconclusive"),
        ("predator_prey", REL, "", "disagree"),
    ],
    "second": [
        ("gate_escape", GE, "0.5", "inconclusive"),
        ("predator_prey", PP, "0.45", "inconclusive"),
        ("predator_prey", PP2, "0.9", "agree"),
        ("predator_prey", REL, "", "agree"),
    ],
    # The new study: one task done, and a treatment fewer.
    "new": [
        ("predator_prey", PP, "0.3", "disagree"),
        ("predator_prey", REL, "", "agree"),
    ],
}


@pytest.fixture
def three(tmp_path: Path) -> list[Path]:
    return [write_claims(tmp_path / name, rows, True) for name, rows in ROWS.items()]


def write_causes(path: Path) -> Path:
    path.write_text(
        f'"{PP}":\n  cause: >-\n    the MI at\n    population 50\n'
        "  tested: pp_pop200\n"
        f'"{GE}":\n  cause: not a disagreement anywhere\n'
    )
    return path


def test_each_claim_in_each_study_with_the_cause_of_its_disagreement(
    three: list[Path], tmp_path: Path
) -> None:
    studies = [read_study(p, p.name) for p in three]
    causes = read_causes(write_causes(tmp_path / "causes.yaml"))
    page, found = verdicts_page(studies, causes)
    assert [(d.statement, d.studies) for d in found] == [
        (PP, ("first", "new")),
        (REL, ("first",)),
    ]
    # Counts over everything, then over the task every study ran.
    assert "| first | gate escape, predator-prey pursuit | 4 | 1 | 2 | 1 |" in page
    assert "| new | predator-prey pursuit | 2 | 1 | 1 | 0 |" in page
    assert "On the tasks every study ran (predator-prey pursuit):" in page
    assert "| first | predator-prey pursuit | 3 | 0 | 2 | 1 |" in page
    assert f"| {GE} | agree, A = 0.80 [0.60, 1.00] | inconclusive, A = 0.50 " in page
    # The new study has no gate escape; a declared cause shows where verdicts
    # differ between studies, even with no disagreement.
    assert f"| {NOT_RUN} | *untested*: not a disagreement anywhere |" in page
    assert "differs between the studies that judged them: 4 " in page
    assert (
        f"| {PP} | **disagree**, A = 0.20 [0.00, 0.40] | inconclusive, "
        "A = 0.45 [0.25, 0.65] | **disagree**, A = 0.30 [0.10, 0.50] | "
        "*tested: pp_pop200*: the MI at population 50 |"
    ) in page
    assert f"| {PP2} | inconclusive, A = 0.70 [0.50, 0.90] | agree, " in page
    assert f"| {NOT_JUDGED} |  |" in page  # PP2 in the new study
    assert f"| {REL} | **disagree** | agree | agree | (no cause declared) |" in page
    assert "1 tested by an experiment, 0 untested, 1 not declared." in page
    # Tasks in the paper's order, whatever order the tables list them in.
    assert page.index("## Gate escape") < page.index("## Predator-prey pursuit")


def test_the_command_names_undeclared_and_stale_causes(
    three: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "verdicts.md"
    causes = write_causes(tmp_path / "causes.yaml")
    args = ["verdicts", *map(str, three), "--causes", str(causes), "--out", str(out)]
    assert main([*args, "--names", "v1,v2,v3"]) == 0
    err = capsys.readouterr().err
    assert f"no cause declared: {REL} (v1)" in err
    assert "cause of no claim here" not in err  # GE is a claim, if no disagreement
    assert "| claim | v1 | v2 | v3 | cause of a disagreement |" in out.read_text()
    causes.write_text(causes.read_text() + '"a claim no study makes":\n  cause: x\n')
    assert main(args) == 0
    assert "cause of no claim here: a claim no study makes" in capsys.readouterr().err
    assert "| claim | first | second | new |" in out.read_text()
    assert main([*args, "--names", "a,b"]) == 2
    assert main(["verdicts", str(three[0])]) == 2
    assert "at least two studies" in capsys.readouterr().err


def test_a_table_of_the_earlier_rules_is_refused(tmp_path: Path) -> None:
    old = write_claims(tmp_path / "old", [("gate_escape", GE, "", "agree")])
    with pytest.raises(CompareError, match="judged by the rules before today's"):
        read_study(old, "old")


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ("- a list\n", "must map claim statements"),
        (f'"{PP}": just a text\n', "must map to"),
        (f'"{PP}":\n  cause: x\n  tseted: y\n', "unknown key"),
        (f'"{PP}":\n  tested: y\n', "'cause' must be a text"),
        (f'"{PP}":\n  cause: x\n  tested: ""\n', "'tested' must name"),
    ],
)
def test_a_bad_causes_file_is_refused(tmp_path: Path, text: str, problem: str) -> None:
    path = tmp_path / "causes.yaml"
    path.write_text(text)
    with pytest.raises(CompareError, match=problem):
        read_causes(path)


def test_every_committed_disagreement_has_a_declared_cause() -> None:
    studies = [read_study(STUDIES / s, s) for s in page_studies()]
    assert len(studies) >= 5  # local-v1, local, local_kinematic and both pp ones
    causes = read_causes(CAUSES)
    _, found = verdicts_page(studies, causes)
    assert found, "the committed studies have disagreements to explain"
    assert [d.statement for d in found if d.cause is None] == []
    claimed = {r.statement for s in studies for r in s.rows}
    assert sorted(set(causes) - claimed) == []


def test_the_committed_page_is_what_the_committed_analyses_give(
    tmp_path: Path,
) -> None:
    out = tmp_path / "verdicts.md"
    folders = [str(STUDIES / s) for s in page_studies()]
    names = ",".join(page_studies())
    args = ["verdicts", *folders, "--names", names, "--causes", str(CAUSES)]
    assert main([*args, "--out", str(out)]) == 0
    # The page names the causes file as it was given; the committed page was
    # made from the repository's root.
    made = out.read_text().replace(str(CAUSES), "docs/study/disagreement-causes.yaml")
    assert made == PAGE.read_text()
