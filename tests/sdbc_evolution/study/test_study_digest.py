"""The study digest: the committed one rebuilds the committed tables, a digest gives
the same tables and figures as the run directories it came from, it is the same
bytes every time it is written, and a damaged one is refused with the problem named.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from sdbc_evolution.run.results import npz_bytes
from sdbc_evolution.study.analysis import (
    FIGURES_DIR,
    REPORT_FILE,
    TABLES_DIR,
    AnalysisSettings,
    analyse,
    analyse_digest_dir,
)
from sdbc_evolution.study.cli import main
from sdbc_evolution.study.digest import (
    DIGEST_DIR,
    STUDY_JSON,
    DigestError,
    read_digest,
    write_digest,
)
from sdbc_evolution.study.exploration import SomSettings
from sdbc_evolution.study.runner import Execution, run_study
from study_helpers import tiny_preset

REPOSITORY = Path(__file__).resolve().parents[3]
STUDIES = REPOSITORY / "docs" / "study"
COMMITTED = (
    "local",
    "local-v1",
    "pp_pop200",
    "local_new_tasks",
    "local_kinematic",
    "pp_pop50_control",
    "paper_runs_kinematic",
)
"""The committed studies: the second local study (the engine's defaults since
2026-12-01), the first, the population-200 test (its report has the preset's
predictions), the study of the two tasks beyond the paper (no paper column) and
the study at the paper's run count (champions re-evaluated; tasks analysed as
digest parts)."""
SMALL_SOM = AnalysisSettings(
    som=SomSettings(rows=4, columns=4, sample_size=40, iterations=300)
)


def tree_bytes(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


@pytest.fixture(scope="module")
def tiny_study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("digest") / "study"
    outcome = run_study(tiny_preset(), root, execution=Execution(workers=1), quiet=True)
    assert not outcome.failed
    return root


@pytest.fixture(scope="module")
def tiny_report(tiny_study: Path) -> Path:
    out = tiny_study.parent / "from_runs"
    analyse(tiny_study, out, SMALL_SOM)
    return out


@pytest.mark.parametrize("study", COMMITTED)
def test_committed_digest_rebuilds_the_committed_tables_and_figures(
    study: str, tmp_path: Path
) -> None:
    committed = STUDIES / study
    digest = committed / DIGEST_DIR
    assert main(["analyse", "--from-digest", str(digest), "--out", str(tmp_path)]) == 0
    for folder in (TABLES_DIR, FIGURES_DIR):
        kept = tree_bytes(committed / folder)
        rebuilt = tree_bytes(tmp_path / folder)
        assert sorted(rebuilt) == sorted(kept), folder
        for name, data in kept.items():
            assert rebuilt[name] == data, f"{folder}/{name}"
    # The rebuilt folder holds the digest too, the same bytes.
    assert tree_bytes(tmp_path / DIGEST_DIR) == tree_bytes(digest)
    # The report too: made from the digest, it is the report the run directories
    # gave (its commands are those that made the runs and the digest).
    assert (tmp_path / REPORT_FILE).read_bytes() == (
        committed / REPORT_FILE
    ).read_bytes()


@pytest.mark.slow
def test_digest_gives_what_the_run_directories_give(
    tiny_report: Path, tmp_path: Path
) -> None:
    again = tmp_path / "from_digest"
    analyse_digest_dir(tiny_report / DIGEST_DIR, again)
    for folder in (TABLES_DIR, FIGURES_DIR, DIGEST_DIR):
        expected = tree_bytes(tiny_report / folder)
        assert expected, folder
        assert tree_bytes(again / folder) == expected, folder
    # Neither was given a command line to record, so the reports are equal too.
    assert (again / REPORT_FILE).read_text() == (tiny_report / REPORT_FILE).read_text()


@pytest.mark.slow
def test_writing_a_digest_twice_gives_the_same_bytes(
    tiny_study: Path, tiny_report: Path, tmp_path: Path
) -> None:
    digest = tiny_report / DIGEST_DIR
    write_digest(read_digest(digest), tmp_path / "rewritten")
    assert tree_bytes(tmp_path / "rewritten") == tree_bytes(digest)
    # From the run directories again, in another folder: the same bytes.
    analyse(tiny_study, tmp_path / "second", SMALL_SOM)
    assert tree_bytes(tmp_path / "second" / DIGEST_DIR) == tree_bytes(digest)
    # The digest holds the curves exactly, not a rounding of them.
    read = read_digest(digest)
    run = read.runs[0]
    columns = np.genfromtxt(
        tiny_study / run.name / "generations.csv", delimiter=",", names=True
    )
    np.testing.assert_array_equal(run.curve, columns["reevaluated_fitness"])


def _damage_npz(file: Path, change: dict[str, np.ndarray | None]) -> None:
    with np.load(file) as data:
        arrays = {k: data[k] for k in data.files}
    for key, value in change.items():
        if value is None:
            del arrays[key]
        else:
            arrays[key] = value
    file.write_bytes(npz_bytes(arrays))


@pytest.mark.slow
def test_a_bad_digest_is_refused_with_the_problem_named(
    tiny_report: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    def copy() -> Path:
        target = tmp_path / f"d{len(list(tmp_path.iterdir()))}"
        shutil.copytree(tiny_report / DIGEST_DIR, target)
        return target

    def refused(digest: Path) -> str:
        with pytest.raises(DigestError) as error:
            read_digest(digest)
        return str(error.value)

    assert "no digest folder" in refused(tmp_path / "absent")

    missing = copy()
    (missing / STUDY_JSON).unlink()
    assert f"{STUDY_JSON}: missing" in refused(missing)

    newer = copy()
    data = json.loads((newer / STUDY_JSON).read_text())
    data["version"] = 99
    (newer / STUDY_JSON).write_text(json.dumps(data))
    assert "version 99" in refused(newer)

    no_task = copy()
    (no_task / "gate_escape.npz").unlink()
    assert "gate_escape.npz: missing" in refused(no_task)

    truncated = copy()
    npz = truncated / "gate_escape.npz"
    npz.write_bytes(npz.read_bytes()[:300])
    assert "gate_escape.npz: unreadable" in refused(truncated)

    no_curve = copy()
    _damage_npz(no_curve / "gate_escape.npz", {"curve": None})
    assert "no array 'curve'" in refused(no_curve)

    short = copy()
    with np.load(short / "gate_escape.npz") as data:
        curve = data["curve"]
    _damage_npz(short / "gate_escape.npz", {"curve": curve[:-1]})
    assert "'curve' has shape" in refused(short)

    bad_som = copy()
    with np.load(bad_som / "gate_escape.npz") as data:
        # Same length as the real list, so that the names, not the shapes, are wrong.
        unknown = np.array([f"nope{i}" for i in range(len(data["som_treatments"]))])
    _damage_npz(bad_som / "gate_escape.npz", {"som_treatments": unknown})
    assert "'som_treatments'" in refused(bad_som)

    bad_prediction = copy()
    data = json.loads((bad_prediction / STUDY_JSON).read_text())
    data["preset"]["predictions"] = [
        {"statement": "x", "a": "fit", "b": "ns-sd+", "rule": "bigger"}
    ]
    (bad_prediction / STUDY_JSON).write_text(json.dumps(data))
    assert "predictions.0.rule" in refused(bad_prediction)

    # Through the command line: exit status 2, the problem on stderr.
    assert main(["analyse", "--from-digest", str(no_curve)]) == 2
    assert "no array 'curve'" in capsys.readouterr().err
    assert main(["analyse"]) == 2
    assert "a study directory, --from-digest DIR, or both" in capsys.readouterr().err
