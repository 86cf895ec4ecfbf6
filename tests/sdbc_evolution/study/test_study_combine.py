"""A study whose tasks ran apart (separate study directories, e.g. sessions) and are
analysed together gives what the same runs analysed in one directory give."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from sdbc_evolution.study.analysis import (
    FIGURES_DIR,
    REPORT_FILE,
    TABLES_DIR,
    analyse,
    analyse_parts,
)
from sdbc_evolution.study.cli import main
from sdbc_evolution.study.combine import combine_digests
from sdbc_evolution.study.digest import DIGEST_DIR, DigestError, read_digest
from sdbc_evolution.study.exploration import SomSettings
from sdbc_evolution.study.findings import AnalysisSettings
from sdbc_evolution.study.presets import preset_from_dict
from sdbc_evolution.study.runner import Execution, run_study
from study_helpers import TINY
from test_study_digest import SMALL_SOM, tree_bytes

TWO_TASKS = {
    **TINY,
    "name": "tiny-two",
    "tasks": ["gate_escape", "aggregation"],
    "generations": {"gate_escape": 2, "aggregation": 2},
    "task_config": {
        "gate_escape": {"max_steps": 60},
        "aggregation": {"max_steps": 50},
    },
}


@pytest.fixture(scope="module")
def parts(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Each task run in a study directory of its own, and both copied into one."""
    base = tmp_path_factory.mktemp("combine")
    preset = preset_from_dict(TWO_TASKS)
    roots = {}
    for task in preset.tasks:
        roots[task] = base / task
        outcome = run_study(
            preset,
            roots[task],
            tasks=[task],
            execution=Execution(workers=1),
            quiet=True,
        )
        assert not outcome.failed
    whole = base / "whole"
    shutil.copytree(roots["gate_escape"], whole)
    shutil.copytree(roots["aggregation"] / "aggregation", whole / "aggregation")
    return {**roots, "whole": whole}


@pytest.mark.slow
def test_parts_analysed_together_equal_one_study(
    parts: dict[str, Path], tmp_path: Path
) -> None:
    whole = tmp_path / "whole"
    analyse(parts["whole"], whole, SMALL_SOM)
    first = tmp_path / "first"
    analyse(parts["gate_escape"], first, SMALL_SOM)
    # Analysed alone, a part lists the other task's runs as missing.
    assert "`aggregation`: not run yet (4 runs missing)" in (
        (first / REPORT_FILE).read_text()
    )
    combined = tmp_path / "combined"
    command = ["sdbc-study", "analyse", "AGGREGATION", "--from-digest", "FIRST"]
    analyse_parts(
        parts["aggregation"], [first / DIGEST_DIR], combined, SMALL_SOM, command
    )
    for folder in (TABLES_DIR, FIGURES_DIR):
        expected = tree_bytes(whole / folder)
        assert expected, folder
        assert tree_bytes(combined / folder) == expected, folder
    for task in ("gate_escape", "aggregation"):
        name = f"{task}.npz"
        assert (combined / DIGEST_DIR / name).read_bytes() == (
            whole / DIGEST_DIR / name
        ).read_bytes()
    report = (combined / REPORT_FILE).read_text()
    assert "missing" not in report
    assert "8 usable runs of 8 expected." in report
    assert "sdbc-study analyse AGGREGATION --from-digest FIRST" in report
    # The combined digest makes the same report again, by itself.
    again = tmp_path / "again"
    assert (
        main(
            [
                "analyse",
                "--from-digest",
                str(combined / DIGEST_DIR),
                "--out",
                str(again),
            ]
        )
        == 0
    )
    assert (again / REPORT_FILE).read_text() == report


@pytest.mark.slow
def test_parts_that_do_not_combine_are_refused_by_name(
    parts: dict[str, Path], tmp_path: Path
) -> None:
    analyse(parts["gate_escape"], tmp_path / "a", SMALL_SOM)
    digest = read_digest(tmp_path / "a" / DIGEST_DIR)
    with pytest.raises(DigestError, match="task gate_escape is in both one and two"):
        combine_digests([("one", digest), ("two", digest)])
    other = AnalysisSettings(
        som=SomSettings(rows=3, columns=3, sample_size=40, iterations=300)
    )
    analyse(parts["aggregation"], tmp_path / "b", other)
    with pytest.raises(DigestError, match="different SOM settings"):
        combine_digests(
            [("one", digest), ("two", read_digest(tmp_path / "b" / DIGEST_DIR))]
        )
    # Through the command line: a one-line error naming both parts.
    code = main(
        [
            "analyse",
            "--from-digest",
            str(tmp_path / "a" / DIGEST_DIR),
            "--from-digest",
            str(tmp_path / "a" / DIGEST_DIR),
            "--out",
            str(tmp_path / "c"),
        ]
    )
    assert code == 2
    with pytest.raises(DigestError, match="nothing to combine"):
        combine_digests([])


@pytest.mark.slow
def test_a_session_in_two_parts_is_counted_once(
    parts: dict[str, Path], tmp_path: Path
) -> None:
    """A task run later in the directory of a committed part has that part's
    session in its log too (the paper-count study's predator-prey, then gate
    escape): the report counts it once."""
    import dataclasses

    first = tmp_path / "first"
    analyse(parts["gate_escape"], first, SMALL_SOM)
    second = tmp_path / "second"
    analyse(parts["aggregation"], second, SMALL_SOM)
    one, two = read_digest(first / DIGEST_DIR), read_digest(second / DIGEST_DIR)
    assert one.sessions and two.sessions
    two = dataclasses.replace(two, sessions=one.sessions + two.sessions)
    combined = combine_digests([("first", one), ("second", two)], ())
    assert combined.sessions == one.sessions + tuple(
        s for s in two.sessions if s not in one.sessions
    )
    assert len(combined.sessions) == len(one.sessions) + 1
