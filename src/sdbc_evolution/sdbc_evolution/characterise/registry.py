"""Every characterisation, registered in one place (:data:`CHARACTERISATIONS`, open
to the entry point group ``sdbc.characterisations``), and how a declaration names
one.

A characterisation is declared by its name alone (``sdbc``) or by a mapping of the
name to its options (``{sdbc: {aggregation: {frames: 5}}}``); :func:`parse` turns
either into a :class:`CharacterisationSpec`, refusing unknown names and bad options
with a message naming the part. A spec's :attr:`~CharacterisationSpec.key` names its
behaviour arrays in an evaluation: the name for default options, the name and its
non-default options otherwise (``sdbc{aggregation={frames=5}}``).

Adding a characterisation means one part (a :class:`~.base.Characteriser` with its
``options_class``) and one registration, here or by an entry point; nothing
downstream knows which exist.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from sdbc_sim.parts import PartSpec, Registry, changed_options

from sdbc_evolution.characterise.base import Characteriser
from sdbc_evolution.characterise.evaluation import SDBC, TASK
from sdbc_evolution.characterise.sdbc import SdbcCharacteriser
from sdbc_evolution.characterise.sensor_effector import SensorEffectorMean, StateCount
from sdbc_evolution.characterise.task import TaskCharacteriser

ENTRY_POINT_GROUP = "sdbc.characterisations"
"""Entry point group of characterisations from other distributions."""

CHARACTERISATIONS: Registry[Characteriser] = Registry(
    "characterisation", ENTRY_POINT_GROUP, Characteriser
)
"""Every characterisation, by name."""
CHARACTERISATIONS.register(TASK, TaskCharacteriser)
CHARACTERISATIONS.register(SDBC, SdbcCharacteriser)
CHARACTERISATIONS.register("state_count", StateCount)
CHARACTERISATIONS.register("sensor_effector_mean", SensorEffectorMean)


def _compact(value: Any) -> str:
    if isinstance(value, dict):
        return "{" + ",".join(f"{k}={_compact(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ",".join(_compact(v) for v in value) + "]"
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


@dataclass(frozen=True)
class CharacterisationSpec(PartSpec[Characteriser]):
    """A declared characterisation: its name and options."""

    registry = CHARACTERISATIONS

    @property
    def kind(self) -> str:
        """Its registered name."""
        return self.name

    @property
    def key(self) -> str:
        """Names this characterisation's arrays in an evaluation."""
        changed = changed_options(self.options)
        return self.name + (_compact(changed) if changed else "")

    @property
    def needs_network(self) -> bool:
        """Whether it reads network inputs and outputs."""
        return self.registered.part.needs_network


def parse(declaration: Any, where: str = "characterisation") -> CharacterisationSpec:
    """A spec from ``name`` or ``{name: {option: value, ...}}``.

    Raises:
        SettingsError: Unknown name or bad options, naming ``where`` and the
            option.
    """
    return CharacterisationSpec.parse(declaration, where)


PAPER_SDBC = CharacterisationSpec.parse(SDBC)
"""The paper's SDBC."""
TASK_SPECIFIC = CharacterisationSpec.parse(TASK)
"""The task-specific characterisation."""
ALWAYS = (TASK_SPECIFIC, PAPER_SDBC)
"""Characterisations every evaluation carries (the run's outputs hold both)."""
