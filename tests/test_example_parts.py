"""examples/07_own_parts, a ranking and a characterisation of one's own, installed
from a copy into a temporary folder (pip --target, no index): sdbc-evolve runs
the treatment that names them as a function of its seed (resumed too), and the
contract test of every registered part checks them; no file of the package or of
the example is touched."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from test_examples import fingerprint, install_copy, run

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "07_own_parts"
PARTS = ("ranking:stochastic_ranking", "characterisation:final_position")


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory):
    """The example installed from a copy; yields (environment, copy)."""
    before = fingerprint(EXAMPLE, ROOT / "src")
    yield install_copy(EXAMPLE, tmp_path_factory.mktemp("parts"))
    assert fingerprint(EXAMPLE, ROOT / "src") == before


@pytest.mark.slow
def test_sdbc_evolve_runs_the_treatment_of_own_parts(installed, tmp_path) -> None:
    env, copy = installed
    config = tmp_path / "run.yaml"
    config.write_text(
        yaml.safe_dump(
            {
                "task": "gate_escape",
                "task_config": {"max_steps": 100},
                "generations": 3,
                "seed": 4,
                "ga": {"population_size": 6, "elites": 1, "tournament_size": 2},
                "novelty": {"k": 3},
                "evaluation": {"trials": 2, "reevaluation_trials": 2},
            }
        )
    )
    treatment = ["--treatment", str(copy / "treatment.yaml")]

    def evolve(out: Path, *more: str) -> None:
        args = ["--out", str(out), "--workers", "1", "--quiet", "--no-gif", *more]
        run(env, "sdbc_evolution.run.cli", *args, cwd=tmp_path)

    whole, resumed = tmp_path / "whole", tmp_path / "resumed"
    evolve(whole, "--config", str(config), *treatment)
    evolve(resumed, "--config", str(config), *treatment, "--generations", "2")
    evolve(resumed, "--resume", "--generations", "3")
    columns = []
    for out in (whole, resumed):
        with (out / "generations.csv").open() as file:
            rows = list(csv.DictReader(file))
        assert len(rows) == 3
        declared = yaml.safe_load((out / "config.yaml").read_text())["treatment"]
        assert declared["characterisation"] == "final_position"
        assert declared["ranking"] == "stochastic_ranking"
        columns.append([(r["best_fitness"], r["best_novelty"]) for r in rows])
    # The ranking draws from the run's generator: the run is still its seed's,
    # resumed from a checkpoint or not.
    assert columns[0] == columns[1]


@pytest.mark.slow
def test_the_parts_contract_checks_the_installed_parts(installed) -> None:
    env, _ = installed
    contract = str(ROOT / "tests" / "test_parts_contract.py")
    pick = " or ".join(part.split(":")[1] for part in PARTS)
    args = ["-v", "-p", "no:cacheprovider", contract, "-k", pick]
    printed = run(env, "pytest", *args, cwd=ROOT)
    for part in PARTS:
        results = [line for line in printed.splitlines() if f"[{part}]" in line]
        # Three checks of every part, and its kind's own.
        assert len(results) == 4 and all(" PASSED" in r for r in results), results
    assert "FAILED" not in printed


@pytest.mark.slow
def test_a_bad_option_of_an_installed_part_is_refused_naming_it(
    installed, tmp_path
) -> None:
    env, copy = installed
    bad = tmp_path / "bad.yaml"
    text = (copy / "treatment.yaml").read_text()
    bad.write_text(text.replace("p_fitness: 0.45", "p_fitness: 2"))
    args = ["--task", "gate_escape", "--treatment", str(bad), "--out", "out"]
    done = subprocess.run(
        [sys.executable, "-m", "sdbc_evolution.run.cli", *args],
        capture_output=True,
        text=True,
        env=env,
        cwd=tmp_path,
        timeout=600,
    )
    assert done.returncode != 0
    assert done.stderr.strip().splitlines()[-1] == (
        f"sdbc-evolve: error: {bad}: treatment.ranking.stochastic_ranking.p_fitness: "
        "Input should be less than or equal to 1, got 2"
    )
    assert not (tmp_path / "out").exists()
