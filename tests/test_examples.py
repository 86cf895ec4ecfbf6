"""examples/01_custom_task, a task of one's own, installed from a copy into a
temporary folder (pip --target, no index), runs through sdbc-evolve, the
conformance checks, a smoke study and the live graph, and touches no file of the
package or of the example."""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "01_custom_task"
TASK = "beacon_homing"


def fingerprint(*folders: Path) -> dict[str, str]:
    """SHA-256 of every file below ``folders`` but caches."""
    return {
        str(path): hashlib.sha256(path.read_bytes()).hexdigest()
        for folder in folders
        for path in sorted(folder.rglob("*"))
        if path.is_file() and "__pycache__" not in path.parts
    }


def install_copy(example: Path, tmp: Path) -> tuple[dict[str, str], Path]:
    """``example`` copied into ``tmp`` and installed from the copy into
    ``tmp/site`` (pip --target, no index); returns (environment, copy)."""
    copy = tmp / example.name
    shutil.copytree(example, copy)
    site = tmp / "site"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "--quiet",
            "--no-deps",
            "--no-index",
            "--no-build-isolation",
            "--target",
            str(site),
            str(copy),
        ],
        check=True,
        capture_output=True,
        text=True,
    )
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(site), *(p for p in sys.path if p)])
    env["ROS_HOME"] = str(tmp / "ros_home")
    return env, copy


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory):
    """The example installed from a copy; yields (environment, copy)."""
    before = fingerprint(EXAMPLE, ROOT / "src")
    yield install_copy(EXAMPLE, tmp_path_factory.mktemp("example"))
    assert fingerprint(EXAMPLE, ROOT / "src") == before


def run(env: dict[str, str], module: str, *args: str, cwd: Path) -> str:
    done = subprocess.run(
        [sys.executable, "-m", module, *args],
        capture_output=True,
        text=True,
        env=env,
        cwd=cwd,
        timeout=1800,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return done.stdout


@pytest.mark.slow
def test_sdbc_evolve_lists_and_runs_the_installed_task(installed, tmp_path) -> None:
    env, _ = installed
    listed = run(env, "sdbc_evolution.run.cli", "--list-tasks", cwd=tmp_path)
    assert re.search(rf"^{TASK}  \(beacon_homing\.task:BeaconHoming", listed, re.M)
    config = tmp_path / "run.yaml"
    config.write_text(
        yaml.safe_dump(
            {
                "task": TASK,
                "task_config": {"max_steps": 100},
                "generations": 2,
                "ga": {"population_size": 6, "elites": 1, "tournament_size": 2},
                "novelty": {"k": 3},
                "evaluation": {"trials": 2, "reevaluation_trials": 2},
            }
        )
    )
    out = tmp_path / "run"
    args = ["--config", str(config), "--out", str(out), "--workers", "1"]
    run(env, "sdbc_evolution.run.cli", *args, "--quiet", "--no-gif", cwd=tmp_path)
    assert (out / "generations.csv").read_text().count("\n") == 3


@pytest.mark.ros  # the live check sends the task states through sdbc_msgs
@pytest.mark.slow
def test_the_installed_task_passes_the_conformance_checks(installed, tmp_path):
    env, _ = installed
    printed = run(env, "sdbc_evolution.conformance", TASK, cwd=tmp_path)
    assert "7/7 checks passed for beacon_homing" in printed


@pytest.mark.slow
def test_its_smoke_study_reports_with_no_paper_column(installed, tmp_path) -> None:
    env, copy = installed
    out = tmp_path / "study"
    preset = str(copy / "smoke.yaml")
    args = ["all", "--preset", preset, "--out", str(out), "--workers", "1"]
    run(env, "sdbc_evolution.study", *args, "--quiet", cwd=tmp_path)
    text = (out / "report" / "report.md").read_text()
    assert text.startswith("# A study with sdbc: beacon homing")
    assert "8 usable runs of 8 expected." in text
    for paper_only in ("(paper)", "paper mean (SD)", "## The paper's claims"):
        assert paper_only not in text


@pytest.mark.ros
@pytest.mark.slow
def test_a_live_graph_trial_equals_the_batch(installed, tmp_path) -> None:
    from sdbc_evolution.graph.graph_file import trial_graph
    from sdbc_sim.engine import run_batch

    env, copy = installed
    sys.path.insert(0, str(copy))
    try:
        from beacon_homing import BeaconHoming, BeaconHomingConfig
    finally:
        sys.path.remove(str(copy))
    task = BeaconHoming(BeaconHomingConfig(max_steps=120))
    genome = np.random.default_rng(4).uniform(-1, 1, task.genome_length)
    seed = 17
    batch = run_batch(task, genome[None], np.array([[seed]]))
    graph = tmp_path / "graph.yaml"
    graph.write_text(yaml.safe_dump(trial_graph(TASK, genome, {"max_steps": 120})))
    args = [str(graph), "--trial", str(seed), "--log-dir", str(tmp_path / "logs")]
    printed = run(env, "sdbc_evolution.graph.launch", *args, cwd=tmp_path)
    found = re.search(
        rf"trial seed {seed}: fitness (\S+), length (\d+), characterisation \[(.*)\]",
        printed,
    )
    assert found, printed
    assert float(found[1]) == pytest.approx(batch.fitness[0, 0], rel=1e-5)
    assert int(found[2]) == batch.length[0, 0]
    live = [float(v) for v in found[3].split(",")]
    np.testing.assert_allclose(live, batch.characterisation[0, 0], atol=1e-6)
