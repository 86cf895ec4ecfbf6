"""Every characterisation kind, registered in one place, and how a declaration
names one.

A characterisation is declared by its kind alone (``sdbc``) or by a mapping of the
kind to its options (``{sdbc: {aggregation: {frames: 5}}}``); :func:`parse`
turns either into a :class:`CharacterisationSpec`, refusing unknown kinds and bad
options with a message naming the part. A spec's :attr:`~CharacterisationSpec.key`
names its behaviour arrays in an evaluation: the kind for default options, the kind
and its non-default options otherwise (``sdbc{aggregation={frames=5}}``).

Adding a characterisation means one class (a :class:`~.base.Characteriser`) and one
entry in :data:`KINDS`; nothing downstream knows which exist.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from sdbc_evolution.characterise.base import Characteriser
from sdbc_evolution.characterise.evaluation import SDBC, TASK
from sdbc_evolution.characterise.sdbc import SdbcCharacteriser, SdbcOptions
from sdbc_evolution.characterise.sensor_effector import (
    SensorEffectorMean,
    SensorEffectorMeanOptions,
    StateCount,
    StateCountOptions,
)
from sdbc_evolution.characterise.task import TaskCharacteriser, TaskOptions
from sdbc_evolution.sdbc.declared import changed_options, declared_part


@dataclass(frozen=True)
class Kind:
    """A registered characterisation kind.

    Attributes:
        options: Its options dataclass (defaults: the kind's reference settings).
        build: Makes a fresh characteriser (one per batch) from options.
        needs_network: It reads the robots' network inputs and outputs, which a
            task-state stream does not carry.
        summary: One line for listings and errors.
    """

    options: type
    build: Callable[[Any], Characteriser]
    needs_network: bool
    summary: str


KINDS: dict[str, Kind] = {
    TASK: Kind(
        TaskOptions, TaskCharacteriser, False, "the task's own characterisation"
    ),
    SDBC: Kind(SdbcOptions, SdbcCharacteriser, False, "the SDBC (paper's defaults)"),
    "state_count": Kind(
        StateCountOptions,
        StateCount,
        True,
        "sensor-effector state count (Gomes & Christensen 2013)",
    ),
    "sensor_effector_mean": Kind(
        SensorEffectorMeanOptions,
        SensorEffectorMean,
        True,
        "mean sensor and effector values over the trial",
    ),
}
"""Every characterisation kind, by name."""


def _compact(value: Any) -> str:
    if isinstance(value, dict):
        return "{" + ",".join(f"{k}={_compact(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ",".join(_compact(v) for v in value) + "]"
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


@dataclass(frozen=True)
class CharacterisationSpec:
    """A declared characterisation: a kind and its options."""

    kind: str
    options: Any

    @property
    def key(self) -> str:
        """Names this characterisation's arrays in an evaluation."""
        changed = changed_options(self.options)
        return self.kind + (_compact(changed) if changed else "")

    @property
    def needs_network(self) -> bool:
        """Whether it reads network inputs and outputs."""
        return KINDS[self.kind].needs_network

    def build(self) -> Characteriser:
        """A fresh characteriser (for one batch)."""
        return KINDS[self.kind].build(self.options)

    def to_plain(self) -> str | dict[str, Any]:
        """The declaration, YAML-ready: the kind alone for default options."""
        changed = changed_options(self.options)
        return {self.kind: changed} if changed else self.kind


def parse(declaration: Any, where: str = "characterisation") -> CharacterisationSpec:
    """A spec from ``kind`` or ``{kind: {option: value, ...}}``.

    Raises:
        SettingsError: Unknown kind or bad options, naming ``where`` and the
            option.
    """
    if isinstance(declaration, CharacterisationSpec):
        return declaration
    options = {kind: k.options for kind, k in KINDS.items()}
    kind, chosen = declared_part(declaration, options, "characterisation", where)
    return CharacterisationSpec(kind, chosen)


PAPER_SDBC = CharacterisationSpec(SDBC, SdbcOptions())
"""The paper's SDBC."""
TASK_SPECIFIC = CharacterisationSpec(TASK, TaskOptions())
"""The task-specific characterisation."""
ALWAYS = (TASK_SPECIFIC, PAPER_SDBC)
"""Characterisations every evaluation carries (the run's outputs hold both)."""
