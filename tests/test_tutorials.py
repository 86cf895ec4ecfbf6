"""Every tutorial under examples/ runs as its README says, from a fresh folder, and
prints what it promises; every tutorial says what it teaches and how long it runs,
and the README's table lists them all.

``examples/01_custom_task`` is run end to end by ``tests/test_examples.py``,
``examples/02_own_loop`` by ``tests/test_example_02.py`` (also from a fresh venv).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
UNTIMED = {"01_custom_task": "tests/test_examples.py"}
"""Tutorials that predate the ladder's README format: an installable package whose
README says how to use it, tested end to end elsewhere."""
TIMEOUT = 900.0
"""Seconds a tutorial may take on a loaded two-core machine (each takes under a
minute on an idle one)."""


def tutorials() -> list[Path]:
    return sorted(p.parent for p in EXAMPLES.glob("[0-9][0-9]_*/README.md"))


def run(script: Path, *args: str, cwd: Path) -> str:
    """Runs a tutorial's script as a reader would, from ``cwd``; its stdout."""
    done = subprocess.run(
        [sys.executable, str(script), *args],
        cwd=cwd,
        env=dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p)),
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
    )
    assert done.returncode == 0, done.stderr[-4000:]
    return done.stdout


@pytest.mark.parametrize("folder", tutorials(), ids=lambda p: p.name)
def test_every_tutorial_says_what_it_teaches_and_its_run_time(folder: Path) -> None:
    text = (folder / "README.md").read_text()
    if folder.name in UNTIMED:
        pytest.skip(f"{folder.name} is run by {UNTIMED[folder.name]}")
    assert "What it teaches:" in text, folder.name
    assert re.search(r"\b\d+(\.\d+)? ?(s|seconds|min|minutes)\b", text), folder.name
    runnable = list(folder.glob("*.py")) or (folder / "pyproject.toml").is_file()
    assert runnable, f"{folder.name} has neither a script nor a package to install"


def test_the_readme_lists_every_tutorial() -> None:
    readme = (ROOT / "README.md").read_text()
    for folder in tutorials():
        assert f"(examples/{folder.name}/README.md)" in readme, folder.name


def test_03_pyribs_novelty_beside_novelty_search(tmp_path: Path) -> None:
    out = run(
        EXAMPLES / "03_pyribs" / "pyribs_novelty.py",
        "--generations",
        "3",
        "--population",
        "12",
        cwd=tmp_path,
    )
    assert "predator_prey: 36 controllers each" in out
    assert "SDBC: 27 dimensions" in out
    rows = {
        line.split("  ")[0].strip(): line.split()[-3:]
        for line in out.splitlines()
        if line.startswith(("pyribs", "sdbc"))
    }
    assert set(rows) == {"pyribs ProximityArchive", "sdbc NoveltySearch"}
    for best, archive, distinct in rows.values():
        assert 0.0 <= float(best) <= 1.0
        # Every search met at least one behaviour, and the archives hold no more
        # than was evaluated.
        assert 0 <= int(archive) <= 36 and 1 <= int(distinct) <= 36


def test_04_irsim_evolves_over_the_sdbc_of_an_irsim_world(tmp_path: Path) -> None:
    out = run(
        EXAMPLES / "04_irsim" / "irsim_sdbc.py",
        "--generations",
        "2",
        "--population",
        "4",
        cwd=tmp_path,
    )
    assert "SDBC of the ir-sim world: 17 dimensions" in out
    assert "  Robot x (M)" in out
    log = [line.split() for line in out.splitlines() if re.match(r"\s+\d+\s+\d", line)]
    assert [int(row[0]) for row in log] == [0, 1]
    for _, best, mean, _archive in log:
        assert 0.0 <= float(mean) <= float(best) <= 1.0


def test_05_compares_characterisations_in_a_study(tmp_path: Path) -> None:
    out = run(
        EXAMPLES / "05_compare_characterisations" / "compare.py",
        "--out",
        str(tmp_path / "study"),
        cwd=tmp_path,
    )
    treatments = ("ns-ts", "ns-sd", "ns-sd-frames5", "ns-state-count")
    medians = [line.split() for line in out.splitlines() if line.startswith(treatments)]
    assert [row[0] for row in medians[:4]] == list(treatments)
    assert all(row[1] == "2" for row in medians[:4]), "2 runs per treatment"
    report = tmp_path / "study" / "report" / "report.md"
    assert report.is_file()
    assert "ns-state-count" in report.read_text()


@pytest.mark.ros
def test_06_evolves_through_a_ros2_system_of_ones_own(tmp_path: Path, ros_home) -> None:
    out = run(
        EXAMPLES / "06_ros2_system" / "evolve.py",
        "--out",
        str(tmp_path / "run"),
        cwd=tmp_path,
    )
    assert "evolved through the graph" in out
    log = [line.split() for line in out.splitlines() if re.match(r"\s+\d+\s+\d", line)]
    assert [int(row[0]) for row in log] == [0, 1, 2, 3]
    header = (tmp_path / "run" / "generations.csv").read_text().splitlines()[0]
    assert "Chaser-target distance (M)" in header
