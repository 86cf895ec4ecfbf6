"""What killed processes leave behind is cleared: the temporary files of
interrupted atomic writes when the run resumes, multiprocessing's ``pymp-*``
folder of a SIGKILLed command when the next one starts its workers."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from evolution_helpers import TOY_INFO, ToyEvaluator
from sdbc_evolution.run.config import config_from_dict
from sdbc_evolution.run.experiment import Experiment
from sdbc_evolution.run.processes import TEMP_OWNER_FILE, clear_stale_temp_dirs


def toy_config(generations: int):  # type: ignore[no-untyped-def]
    return config_from_dict(
        {
            "task": "toy",
            "generations": generations,
            "ga": {"population_size": 6, "elites": 1, "tournament_size": 2},
            "novelty": {"k": 3},
            "evaluation": {"trials": 2, "reevaluation_trials": 0},
        }
    )


def test_temporary_files_of_killed_writes_are_removed_on_resume(
    tmp_path: Path,
) -> None:
    out = tmp_path / "run"
    with Experiment.create(toy_config(2), out, ToyEvaluator(), TOY_INFO) as run:
        run.run()
    # What a SIGKILL during a write leaves: mkstemp's name, half the bytes.
    left = [
        out / ".checkpoint.npz.a1b2c3d4",
        out / ".best_genomes.npy.zz_9x8w7",
        out / "individuals" / ".gen_00002.npz.k3j4h5g6",
    ]
    kept = [out / ".notes.txt.abcdefgh", out / "mine.txt"]
    for path in left + kept:
        path.write_bytes(b"half")
    with Experiment.resume(toy_config(3), out, ToyEvaluator(), TOY_INFO) as run:
        run.run()
    assert not any(p.exists() for p in left)
    assert all(p.exists() for p in kept)


def test_a_sigkilled_owners_pymp_folder_is_removed_by_the_next_start(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    env = dict(os.environ, TMPDIR=str(tmp_path))
    owner = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "from sdbc_evolution.run.processes import worker_pool\n"
            "pool = worker_pool(1)\n"
            "pool.submit(int).result()\n"
            "print('ready', flush=True)\n"
            "import time; time.sleep(120)\n",
        ],
        env=env,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert owner.stdout is not None and owner.stdout.readline() == "ready\n"
    finally:
        owner.send_signal(signal.SIGKILL)
        owner.wait(timeout=30)
    [folder] = tmp_path.glob("pymp-*")
    assert (folder / TEMP_OWNER_FILE).read_text().split()[0] == str(owner.pid)
    ours = Path(tempfile.mkdtemp(prefix="pymp-", dir=tmp_path))
    (ours / TEMP_OWNER_FILE).write_text(f"{os.getpid()} x\n")  # a reused pid
    alive = Path(tempfile.mkdtemp(prefix="pymp-", dir=tmp_path))
    with open(f"/proc/{os.getpid()}/stat") as f:
        started = f.read().rsplit(")", 1)[1].split()[19]
    (alive / TEMP_OWNER_FILE).write_text(f"{os.getpid()} {started}\n")
    unmarked = Path(tempfile.mkdtemp(prefix="pymp-", dir=tmp_path))
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    removed = clear_stale_temp_dirs()
    assert sorted(removed) == sorted([str(folder), str(ours)])
    assert alive.exists() and unmarked.exists() and not folder.exists()
