"""Cleaning the shared-memory files that Fast DDS leaves in ``/dev/shm``.

Fast DDS keeps its shared-memory transport's segments, port files and locks in
``/dev/shm``. A process killed with SIGKILL leaves its own there, and now and then
a clean exit does too (a port file that another process still mapped), so the
launcher removes, when a graph stops, those created since the graph started that
no process uses any more; and when a graph starts, every one that no process uses
(what a graph killed earlier left, its launcher included), except the youngest,
which a process that is just starting may not have mapped yet.

"In use" means mapped or open by a process this one can inspect (``/proc/<pid>/
maps`` and ``fd``); Fast DDS maps every file it uses for as long as it uses it.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable
from pathlib import Path

SHM_DIR = Path("/dev/shm")
"""Where Fast DDS keeps its shared-memory segments and locks."""
DDS_FILE_PREFIXES = ("fastrtps_", "sem.fastrtps_")
"""Names of the files Fast DDS creates in :data:`SHM_DIR`."""
STALE_MIN_AGE = 5.0
"""Seconds a file unused by any process must have existed before a graph's start
removes it: Fast DDS creates and maps a file within microseconds, so older unused
files belong to processes that are gone."""


def dds_files_in_use() -> set[str]:
    """Names of the Fast DDS files in /dev/shm that some process has open or
    mapped."""
    used: set[str] = set()
    prefix = str(SHM_DIR) + "/"
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        with contextlib.suppress(OSError):
            for line in (proc / "maps").read_text().splitlines():
                at = line.find(prefix)
                if at >= 0:
                    used.add(line[at + len(prefix) :].split(" ")[0])
        with contextlib.suppress(OSError):
            for fd in (proc / "fd").iterdir():
                with contextlib.suppress(OSError):
                    target = os.readlink(fd)
                    if target.startswith(prefix):
                        used.add(target[len(prefix) :])
    return used


def _dds_files(keep: Callable[[os.stat_result], bool]) -> list[Path]:
    if not SHM_DIR.is_dir():
        return []
    found = []
    for path in SHM_DIR.iterdir():
        if path.name.startswith(DDS_FILE_PREFIXES):
            with contextlib.suppress(OSError):
                if keep(path.stat()):
                    found.append(path)
    return found


def _remove_unused(candidates: list[Path]) -> list[str]:
    if not candidates:
        return []
    used = dds_files_in_use()
    removed = []
    for path in candidates:
        if path.name not in used:
            with contextlib.suppress(OSError):
                path.unlink()
                removed.append(path.name)
    return removed


def remove_orphaned_dds_files(since: float) -> list[str]:
    """Removes Fast DDS shared-memory files created at or after ``since`` (a
    ``time.time()``) that no process uses any more: what processes killed with
    SIGKILL leave behind. Returns their names."""
    return _remove_unused(_dds_files(lambda stat: stat.st_ctime >= since))


def remove_stale_dds_files(min_age: float = STALE_MIN_AGE) -> list[str]:
    """Removes every Fast DDS shared-memory file that no process uses and that
    has existed for at least ``min_age`` seconds: what dead processes left,
    whenever they died. Returns their names."""
    before = time.time() - min_age
    return _remove_unused(_dds_files(lambda stat: stat.st_ctime <= before))
