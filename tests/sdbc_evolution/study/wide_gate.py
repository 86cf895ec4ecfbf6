"""A task the paper did not run, for the study tests: gate escape through a wider
gate, named as ``wide_gate:WideGate`` (this folder is on the tests' path)."""

from __future__ import annotations

from sdbc_sim.settings import PositiveFloat, settings
from sdbc_sim.tasks.gate_escape import GateEscape, GateEscapeConfig


@settings
class WideGateConfig(GateEscapeConfig):
    """Gate escape's settings with a wider gate."""

    gate_width: PositiveFloat = 40.0
    """Width of the gate opening."""


class WideGate(GateEscape):
    """Gate escape through a 40-unit gate."""

    name = "wide_gate"
    config_class = WideGateConfig
    default_generations = 30
    # No sdbc_counterparts: a task need not declare them.
    sdbc_counterparts = {}
