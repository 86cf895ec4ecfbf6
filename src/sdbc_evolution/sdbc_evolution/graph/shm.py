"""Cleaning the shared-memory files that Fast DDS leaves in ``/dev/shm``.

Fast DDS keeps its shared-memory transport's segments, port files and locks in
``/dev/shm``. A process killed with SIGKILL leaves its own there, and now and then
a clean exit does too (a port file that another process still mapped), so the
launcher removes, when a graph stops, those created since the graph started that
no process uses any more.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

SHM_DIR = Path("/dev/shm")
"""Where Fast DDS keeps its shared-memory segments and locks."""
DDS_FILE_PREFIXES = ("fastrtps_", "sem.fastrtps_")
"""Names of the files Fast DDS creates in :data:`SHM_DIR`."""


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


def remove_orphaned_dds_files(since: float) -> list[str]:
    """Removes Fast DDS shared-memory files created at or after ``since`` (a
    ``time.time()``) that no process uses any more: what processes killed with
    SIGKILL leave behind. Returns their names."""
    if not SHM_DIR.is_dir():
        return []
    candidates = []
    for path in SHM_DIR.iterdir():
        if path.name.startswith(DDS_FILE_PREFIXES):
            with contextlib.suppress(OSError):
                if path.stat().st_ctime >= since:
                    candidates.append(path)
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
