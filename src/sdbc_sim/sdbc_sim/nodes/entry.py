"""The ROS 2 programs' console scripts, importable without ROS 2.

``pip install`` gives the library and its command lines, not ROS 2: rclpy and the
built ``sdbc_msgs`` come from ``scripts/sdbc setup`` in a checkout. The node
modules import rclpy at their top, so a console script that named them directly
would end in a traceback on a plain install; these wrappers first check that
what a program needs is importable and otherwise say in one line what is missing
and how to get it, with exit status 2 (bad environment, like bad input).
"""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Sequence

MISSING_EXIT = 2
"""Exit status of a program whose dependencies are missing."""
ROS_MODULES = ("rclpy", "sdbc_msgs")
"""What every node needs: ROS 2's client library and the project's interfaces."""
HOW_TO_GET_ROS = (
    "ROS 2 Jazzy and the built sdbc_msgs come from a checkout of sdbc: run "
    "scripts/sdbc setup there, then source scripts/env.sh"
)


def missing_modules(modules: Sequence[str]) -> list[str]:
    """Those of ``modules`` that cannot be imported here."""
    missing = []
    for name in modules:
        try:
            found = importlib.util.find_spec(name) is not None
        except (ImportError, ValueError):
            found = False
        if not found:
            missing.append(name)
    return missing


def require(
    program: str, modules: Sequence[str] = ROS_MODULES, how: str = HOW_TO_GET_ROS
) -> None:
    """Exits with status 2 and one line on stderr if any of ``modules`` is
    missing."""
    missing = missing_modules(modules)
    if missing:
        print(
            f"{program}: error: needs {', '.join(missing)}, which "
            f"{'is' if len(missing) == 1 else 'are'} not installed ({how})",
            file=sys.stderr,
        )
        sys.exit(MISSING_EXIT)


def simulator_node() -> int:
    """``simulator_node``."""
    require("simulator_node")
    from sdbc_sim.nodes.simulator_node import main

    return main()


def controller_node() -> int:
    """``controller_node``."""
    require("controller_node")
    from sdbc_sim.nodes.controller_node import main

    return main()
