"""Running a node program so that it ends when the launcher that started it ends.

The launcher starts every node in a session of its own (so that Ctrl-C in the
terminal reaches the launcher alone, which then stops the nodes in order), so
nothing would stop the nodes if the launcher died without stopping them (SIGKILL,
an out-of-memory kill). Each node therefore runs under this module, which watches
the launcher with the watch ``sdbc-evolve``'s workers use for their owner
(:func:`sdbc_evolution.run.owner.when_gone`: a pidfd, readable once the
process has ended), but stops the node the way the launcher would: SIGINT first,
so that the recorder closes its bag and Fast DDS removes its shared-memory files,
then, after ``grace`` seconds, an immediate exit.

Usage (what :mod:`sdbc_evolution.graph.processes` runs)::

    python -m sdbc_evolution.graph.owned OWNER_PID GRACE MODULE [ARGS...]
"""

from __future__ import annotations

import faulthandler
import os
import runpy
import signal
import sys
import time
from collections.abc import Sequence


def watch_launcher(owner: int, grace: float) -> None:
    """Stops this process when the process ``owner`` (its parent) ends: SIGINT
    at once, an exit with :data:`~sdbc_evolution.run.owner.ORPHAN_EXIT`
    ``grace`` seconds later if it is still running."""
    from sdbc_evolution.run.owner import ORPHAN_EXIT, when_gone

    def stop() -> None:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(grace)
        os._exit(ORPHAN_EXIT)

    when_gone(owner, stop, parent=True, name="watch-launcher")


def main(argv: Sequence[str] | None = None) -> None:
    """Runs the module named in ``argv`` (``OWNER GRACE MODULE [ARGS...]``) as
    ``__main__``, stopped when the process ``OWNER`` ends."""
    # SIGINT is how the launcher (and the watcher) stops a node, so a node must
    # not inherit it ignored, as every program started by a non-interactive
    # shell's `&` does: a stop in its first seconds would be lost, and the node
    # killed after the grace time, its bag unclosed and its DDS files left. First
    # thing, before any import: the launcher holds a stop back until this is done
    # (graph/processes.py). Its default action, not Python's KeyboardInterrupt:
    # until the node program installs its own handlers (before it makes any
    # node), a stop ends the process at once, with nothing started to clean up.
    # A KeyboardInterrupt raised inside an import can leave the interpreter's
    # import lock held, and the process then hung on its way out until the
    # launcher killed it (a stop at a graph's start, about 1 in 60 under load).
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    # A node that outlives the launcher's shutdown timeout gets SIGUSR1 before
    # SIGKILL: its threads' Python stacks then show in its log where it hung.
    faulthandler.register(signal.SIGUSR1, all_threads=True)
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) < 3:
        sys.exit("usage: python -m sdbc_evolution.graph.owned OWNER GRACE MODULE ...")
    owner, grace, module, rest = int(args[0]), float(args[1]), args[2], args[3:]
    watch_launcher(owner, grace)
    sys.argv = [module, *rest]
    runpy.run_module(module, run_name="__main__", alter_sys=True)


if __name__ == "__main__":
    main()
