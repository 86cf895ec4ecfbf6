"""The ROS 2 programs' console scripts, importable without ROS 2 (see
:mod:`sdbc_sim.nodes.entry`): each checks what it needs, then runs."""

from __future__ import annotations

from sdbc_sim.nodes.entry import require

BAGS = "rosbags"
"""The recorder's bag writer (the ``bags`` extra of this package)."""


def characteriser_node() -> int:
    """``characteriser_node``."""
    require("characteriser_node")
    from sdbc_evolution.nodes.characteriser_node import main

    return main()


def evolution_node() -> int:
    """``evolution_node``."""
    require("evolution_node")
    from sdbc_evolution.nodes.evolution_node import main

    return main()


def recorder() -> int:
    """``recorder``."""
    require("recorder")
    require("recorder", (BAGS,), "pip install 'sdbc_evolution[bags]'")
    from sdbc_evolution.nodes.recorder_node import main

    return main()


def graph() -> int:
    """``sdbc-graph``."""
    require("sdbc-graph")
    from sdbc_evolution.graph.launch import main

    return main()
