"""What the operating system refuses, said in one line at the command line.

``sdbc-evolve`` and ``sdbc-study`` turn every ``OSError`` (a read-only or full
disk, a missing permission, an output path that is a file) and every
``MemoryError`` that reaches them into one line naming the path and what to do,
and exit with status 2, instead of a traceback.
"""

from __future__ import annotations

import errno
import sys
import traceback
from collections.abc import Callable

SYSTEM_ERROR_EXIT = 2
"""Exit status of a command stopped by the system's refusal (bad input, broadly)."""

CONTINUE_HINTS = {
    "sdbc-evolve": "--resume continues",
    "sdbc-study": "the same sdbc-study command continues",
}
"""How each command continues what a full disk stopped."""
_HINTS = {
    errno.EROFS: "choose a writable --out",
    errno.EACCES: "choose a directory you may write, or fix its permissions",
    errno.EPERM: "choose a directory you may write, or fix its permissions",
    errno.ENOSPC: "free some space or choose another --out; {continues}",
    errno.EDQUOT: "free some space or choose another --out; {continues}",
    errno.ENOTDIR: "a part of the path is a file, not a directory",
    errno.EEXIST: "a file is in the way of a directory",
    errno.EMFILE: "too many open files: raise the limit (ulimit -n)",
    errno.ENOENT: "check the path",
}


def describe_system_error(
    error: OSError | MemoryError, prog: str = "sdbc-evolve"
) -> str:
    """One line: what failed, on which path, and a hint (how ``prog`` goes on)."""
    if isinstance(error, MemoryError):
        return (
            "out of memory: choose a smaller population, fewer trials or fewer "
            "workers (or a machine with more memory)"
        )
    what = error.strerror or str(error) or type(error).__name__
    where = ""
    if error.filename is not None:
        where = f": {error.filename}"
        if error.filename2 is not None:
            where += f" -> {error.filename2}"
    hint = _HINTS.get(error.errno or 0)
    if hint is not None:
        hint = hint.format(continues=CONTINUE_HINTS.get(prog, "run it again"))
    return f"{what}{where}" + (f" ({hint})" if hint else "")


def describe_failure(error: BaseException, prog: str = "sdbc-evolve") -> str:
    """What stopped a run, for a report of many runs: one line for a refusal of
    the system (:func:`describe_system_error`) or of a run's input (a
    ``ValueError``: configuration, checkpoint, values out of range), the
    traceback for anything else (a bug, whose traceback is what helps)."""
    if isinstance(error, (OSError, MemoryError)):
        return describe_system_error(error, prog)
    if isinstance(error, ValueError):
        return f"{type(error).__name__}: {error}"
    return "".join(traceback.format_exception(error)).rstrip()


def named(error: OSError, path: object) -> OSError:
    """``error`` with ``path`` as its file name if it had none (a failed write or
    fsync on an open file names no path)."""
    if error.filename is not None:
        return error
    return type(error)(error.errno, error.strerror or str(error), str(path))


def one_line_errors(prog: str, main: Callable[[], int]) -> int:
    """Runs ``main``; an ``OSError`` or ``MemoryError`` becomes one line on
    stderr and exit status 2."""
    try:
        return main()
    except (OSError, MemoryError) as error:
        print(f"{prog}: error: {describe_system_error(error, prog)}", file=sys.stderr)
        return SYSTEM_ERROR_EXIT
