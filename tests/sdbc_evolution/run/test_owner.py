"""``when_gone``: the one watch behind a worker's and a graph node's end with
their owner (``run/owner.py``); ``test_processes.py`` kills the real owners."""

from __future__ import annotations

import os
import subprocess
import sys
import threading

import pytest
from sdbc_evolution.run import owner as owner_module
from sdbc_evolution.run.owner import ORPHAN_EXIT, when_gone


def _watch_a_sleeper(parent: bool = False) -> None:
    sleeper = subprocess.Popen(["sleep", "30"])
    gone = threading.Event()
    try:
        when_gone(sleeper.pid, gone.set, parent=parent)
        assert not gone.wait(0.3), "called while the owner still runs"
    finally:
        sleeper.kill()
        sleeper.wait()
    assert gone.wait(10.0), "not called after the owner ended"


def test_then_runs_once_the_owner_has_ended() -> None:
    _watch_a_sleeper()


def test_then_runs_once_the_owner_has_ended_without_pidfds(monkeypatch) -> None:
    monkeypatch.delattr(os, "pidfd_open")
    monkeypatch.setattr(owner_module, "OWNER_POLL_SECONDS", 0.05)
    _watch_a_sleeper()


def _exit_of(code: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60
    )


def test_an_owner_gone_before_the_watch_ends_the_process_at_once() -> None:
    dead = subprocess.Popen(["true"])
    dead.wait()
    done = _exit_of(
        "from sdbc_evolution.run.owner import when_gone\n"
        f"when_gone({dead.pid}, print)\n"
        "print('went on')\n"
    )
    assert done.returncode == ORPHAN_EXIT
    assert "went on" not in done.stdout


@pytest.mark.parametrize("parent", [True, False])
def test_a_parent_watch_of_a_pid_that_is_not_the_parent_ends_the_process(
    parent: bool,
) -> None:
    # pid 1 runs, but it is not the child's parent: the parent it was given
    # died and its pid was reused. Without ``parent`` it is just a process.
    done = _exit_of(
        "from sdbc_evolution.run.owner import when_gone\n"
        f"when_gone(1, print, parent={parent})\n"
        "print('went on')\n"
    )
    if parent:
        assert done.returncode == ORPHAN_EXIT, done.stderr
        assert "went on" not in done.stdout
    else:
        assert done.returncode == 0, done.stderr
        assert "went on" in done.stdout
