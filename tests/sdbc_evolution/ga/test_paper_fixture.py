"""The paper's four treatments give the numbers they gave before treatments became
declared parts (issue 17), to the bit.

``paper_fixture.json`` holds 4 generations of each of Fit, NS-TS, NS-SD and NS-SD+ on
gate escape (20 individuals x 3 trials, max_steps 150, seed 5), recorded with the
code as it was before the change: per generation every individual's fitness,
novelty, rank, parent, archived flag and front; the weights in force; the archive
(fitness, generation, SHA-256 of its behaviours); and SHA-256 digests of the
behaviour arrays and of the next population. The recording reads only the run
directory (individuals files and checkpoint), a layout both codes share.

The runs take numpy's X86_V3 (AVX2) code paths, the recording's, in a fresh
interpreter with ``NPY_DISABLE_CPU_FEATURES`` set (:data:`NUMPY_PATHS`): on an
AVX-512 machine numpy computes float64 ``exp`` and ``arctan2`` with other code
(SVML), whose last bits differ now and then, and the novelty treatments' runs
then differ from generation 0 on. (So the numbers of a run depend on the numpy
paths the CPU takes; docs/platforms.md says so. A CPU without AVX2 would take yet
other paths; none has been met.)

Re-record (only when the engine's numbers change for a reason of their own, from a
checkout without the change under test)::

    SDBC_RECORD_PAPER_FIXTURE=1 scripts/sdbc test \
        tests/sdbc_evolution/ga/test_paper_fixture.py
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from sdbc_evolution.run.config import config_from_dict
from sdbc_evolution.run.evaluators import LocalEvaluator
from sdbc_evolution.run.experiment import Experiment, task_spec

FIXTURE = Path(__file__).with_name("paper_fixture.json")
NUMPY_PATHS = "X86_V4 AVX512_ICL AVX512_SPR"
"""numpy's CPU features switched off for the runs (ignored where absent)."""
TREATMENTS = ("fit", "ns-ts", "ns-sd", "ns-sd+")
GENERATIONS = 4
RECORD = os.environ.get("SDBC_RECORD_PAPER_FIXTURE") == "1"


def _sha(array: np.ndarray) -> str:
    array = np.ascontiguousarray(array)
    head = f"{array.dtype.str}{array.shape}".encode()
    return hashlib.sha256(head + array.tobytes()).hexdigest()


def _floats(values: np.ndarray) -> list[float | None]:
    # JSON has no NaN: Fit's novelty is recorded as null.
    return [None if math.isnan(v) else float(v) for v in np.asarray(values, float)]


def record_run(treatment: str, out: Path) -> list[dict[str, Any]]:
    """Runs 4 generations of ``treatment``; what each left in the run directory."""
    config = config_from_dict(
        {
            "task": "gate_escape",
            "task_config": {"max_steps": 150},
            "treatment": treatment,
            "generations": GENERATIONS,
            "seed": 5,
            "ga": {"population_size": 20},
            "evaluation": {"trials": 3, "reevaluation_trials": 0},
        }
    )
    generations = []
    with LocalEvaluator(task_spec(config), workers=1) as evaluator:
        experiment = Experiment.create(config, out, evaluator)
        for g in range(GENERATIONS):
            experiment.step()
            with np.load(out / "individuals" / f"gen_{g:05d}.npz") as data:
                individuals = {key: data[key] for key in data.files}
            with np.load(out / "checkpoint.npz") as data:
                checkpoint = {key: data[key] for key in data.files}
            meta = json.loads(str(checkpoint["meta"]))
            weights = checkpoint["weights"] if meta["has_weights"] else None
            generations.append(
                {
                    "fitness": _floats(individuals["fitness"]),
                    "novelty": _floats(individuals["novelty"]),
                    "rank": individuals["rank"].tolist(),
                    "parent": individuals["parent"].tolist(),
                    "archived": individuals["archived"].tolist(),
                    "front": individuals["front"].tolist(),
                    "weights": None if weights is None else _floats(weights),
                    "archive_fitness": _floats(checkpoint["archive_fitness"]),
                    "archive_generation": checkpoint["archive_generation"].tolist(),
                    "archive_behaviours": _sha(checkpoint["archive_behaviours"]),
                    "sdbc": _sha(individuals["sdbc"]),
                    "characterisation": _sha(individuals["characterisation"]),
                    "trial_fitness": _sha(individuals["trial_fitness"]),
                    "population": _sha(checkpoint["population"]),
                }
            )
    return generations


def record_run_on_avx2_paths(treatment: str, out: Path) -> list[dict[str, Any]]:
    """:func:`record_run` in a fresh interpreter whose numpy takes its X86_V3
    paths, whatever the CPU."""
    code = (
        "import json, sys\n"
        "from pathlib import Path\n"
        "sys.path.insert(0, sys.argv[1])\n"
        "import test_paper_fixture as fixture\n"
        "print(json.dumps(fixture.record_run(sys.argv[2], Path(sys.argv[3]))))\n"
    )
    env = {**os.environ, "NPY_DISABLE_CPU_FEATURES": NUMPY_PATHS}
    done = subprocess.run(
        [sys.executable, "-c", code, str(Path(__file__).parent), treatment, str(out)],
        capture_output=True,
        text=True,
        env=env,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.slow
@pytest.mark.parametrize("treatment", TREATMENTS)
def test_paper_treatment_matches_the_recording(treatment: str, tmp_path: Path) -> None:
    got = record_run_on_avx2_paths(treatment, tmp_path / "run")
    if RECORD:
        recorded = json.loads(FIXTURE.read_text()) if FIXTURE.exists() else {}
        recorded[treatment] = got
        FIXTURE.write_text(json.dumps(recorded, separators=(",", ":")) + "\n")
        pytest.skip(f"recorded {treatment} into {FIXTURE.name}")
    expected = json.loads(FIXTURE.read_text())[treatment]
    assert len(got) == len(expected) == GENERATIONS
    for g, (mine, theirs) in enumerate(zip(got, expected, strict=True)):
        for key in theirs:
            assert mine[key] == theirs[key], f"{treatment}, generation {g}: {key}"
