"""Tasks broken on purpose, each in one way a conformance check must catch
(tests/sdbc_evolution/test_conformance.py). They are gate escape with one fault;
the conformance checks name them by this file's path."""

from __future__ import annotations

import random
from typing import Any

import numpy as np
from sdbc_sim.settings import settings
from sdbc_sim.tasks.gate_escape import GateEscape, GateEscapeConfig

SALT = random.SystemRandom().random()
"""Drawn anew in every process that imports this module."""


class WrongCounterparts(GateEscape):
    """Declares an SDBC counterpart that the task has no dimension for."""

    sdbc_counterparts = {"escaped fraction": ("Robot group size (F)",)}


class NaNSpeed(GateEscape):
    """Reports a NaN linear speed for robots that are present."""

    def task_state(self, trials, bodies):  # type: ignore[no-untyped-def]
        groups = super().task_state(trials, bodies)
        groups[0].attributes[..., 3] = np.nan
        return groups


class FitnessAboveOne(GateEscape):
    """Scores every trial 1.5 higher than gate escape does."""

    def results(self, trials, length):  # type: ignore[no-untyped-def]
        fitness, characterisation = super().results(trials, length)
        return fitness + 1.5, characterisation


class BatchDependent(GateEscape):
    """Halves the fitness of trials that end together with others."""

    def results(self, trials, length):  # type: ignore[no-untyped-def]
        fitness, characterisation = super().results(trials, length)
        return (fitness * 0.5 if len(length) > 1 else fitness), characterisation


class ProcessDependent(GateEscape):
    """Fitness moved by a number drawn when the process imported the task."""

    def results(self, trials, length):  # type: ignore[no-untyped-def]
        fitness, characterisation = super().results(trials, length)
        return fitness * (1.0 - 1e-6 * SALT), characterisation


class ObservedChanges(GateEscape):
    """Its task state has a side effect on its characterisation, so a trial
    whose state is read at every step (as the live graph does) differs from one
    run without observers."""

    def task_state(self, trials, bodies):  # type: ignore[no-untyped-def]
        trials.dispersion_sum += 1.0
        return super().task_state(trials, bodies)


@settings
class LaxConfig(GateEscapeConfig):
    """Gate escape's settings, but max_steps takes anything."""

    max_steps: Any = 1000
    """tau, unchecked."""


class LaxSettings(GateEscape):
    """Accepts max_steps of any type."""

    config_class = LaxConfig
