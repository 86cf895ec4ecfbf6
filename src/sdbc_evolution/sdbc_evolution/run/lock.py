"""One writer per run directory: an advisory lock on ``OUT/.lock``.

Two processes writing one run (two ``sdbc-evolve --resume``, two ``sdbc-study run``
sessions on one study) would interleave generations into one ``generations.csv``.
A writer holds an exclusive ``flock`` on ``OUT/.lock`` for as long as it writes,
and the file names the holder (pid and host) so that the second writer is told
who it is waiting for. The kernel drops the lock however the holder ends, SIGKILL
included, so a stale lock cannot outlive its process; the file itself stays
(empty once released) and means nothing without the lock.

Shards of a study lock only their own runs, so they still run at once. ``flock``
locks work on local filesystems and on NFS (Linux maps them to NFS byte-range
locks); a filesystem without locks fails loudly when the lock is taken.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import socket
from pathlib import Path
from typing import IO

from sdbc_evolution.run.system_errors import named

LOCK_FILE = ".lock"
"""The lock of a run directory, inside it."""


class RunBusy(RuntimeError):
    """Another process writes this run; the message names it."""


class RunLock:
    """The exclusive lock of one run directory (not re-entrant).

    Args:
        directory: The run directory; :meth:`acquire` creates it if needed.
    """

    def __init__(self, directory: str | Path) -> None:
        self.directory = Path(directory)
        self._file: IO[str] | None = None

    @property
    def path(self) -> Path:
        """The lock file in the run directory."""
        return self.directory / LOCK_FILE

    @property
    def held(self) -> bool:
        """Whether this process holds the lock."""
        return self._file is not None

    def acquire(self) -> RunLock:
        """Takes the lock without waiting.

        Raises:
            RunBusy: Another process (or another lock object) holds it.
            OSError: The directory cannot be created or the file opened.
        """
        if self._file is not None:
            return self
        self.directory.mkdir(parents=True, exist_ok=True)
        # "a+": never truncates another holder's note before the lock is ours.
        file = open(self.path, "a+")  # noqa: SIM115 (held until release)
        try:
            fcntl.flock(file, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            file.seek(0)
            holder = file.read().split()
            file.close()
            raise RunBusy(
                f"{self.directory} is being written by another process "
                f"({_describe(holder)}); wait for it to end, or choose another "
                "output directory"
            ) from None
        except BaseException:
            file.close()
            raise
        try:
            file.seek(0)
            file.truncate()
            file.write(f"{os.getpid()} {socket.gethostname()}\n")
            file.flush()
        except OSError as error:
            # A full disk fails here first; a write names no path by itself.
            # Closing flushes the note again (and fails again), but frees the
            # descriptor, and with it the lock.
            with contextlib.suppress(OSError):
                file.close()
            raise named(error, self.path) from None
        self._file = file
        return self

    def release(self) -> None:
        """Gives the lock up (and empties the holder's note); idempotent."""
        file, self._file = self._file, None
        if file is None:
            return
        try:
            file.seek(0)
            file.truncate()
        except OSError:
            pass  # the note is advisory; the unlock below is what counts
        finally:
            fcntl.flock(file, fcntl.LOCK_UN)
            file.close()

    def __enter__(self) -> RunLock:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()

    def __del__(self) -> None:
        self.release()


def _describe(holder: list[str]) -> str:
    if len(holder) == 2 and holder[0].isdigit():
        return f"pid {holder[0]} on {holder[1]}"
    return "holder not yet named"
