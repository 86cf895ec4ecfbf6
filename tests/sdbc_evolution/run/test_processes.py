"""The processes the project starts end with their owner, however it ends."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from evolution_helpers import TINY_RUN_YAML


def descendants(pid: int) -> set[int]:
    out, todo = set(), [pid]
    while todo:
        parent = todo.pop()
        for task in Path(f"/proc/{parent}/task").glob("*"):
            try:
                children = (task / "children").read_text().split()
            except OSError:
                continue
            for child in map(int, children):
                if child not in out:
                    out.add(child)
                    todo.append(child)
    return out


def running(pid: int) -> bool:
    """Alive and not a zombie (a zombie has ended, only its exit status is left)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def test_sigkill_of_sdbc_evolve_takes_its_workers_with_it(tmp_path: Path) -> None:
    config = tmp_path / "run.yaml"
    config.write_text(TINY_RUN_YAML.replace("generations: 2", "generations: 10000"))
    out = tmp_path / "run"
    evolve = subprocess.Popen(
        [sys.executable, "-m", "sdbc_evolution.run.cli", "--config", str(config),
         "--out", str(out), "--workers", "2", "--quiet", "--no-gif"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 240
        while not (out / "individuals" / "gen_00000.npz").exists():
            assert evolve.poll() is None, "sdbc-evolve ended early"
            assert time.monotonic() < deadline, "no generation within four minutes"
            time.sleep(0.1)
        children = descendants(evolve.pid)
        # The fork server and the pool's two workers at least.
        assert len(children) >= 3, children
    finally:
        os.kill(evolve.pid, signal.SIGKILL)
        evolve.wait()
    deadline = time.monotonic() + 30
    while any(running(pid) for pid in children) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert [pid for pid in children if running(pid)] == []
