"""Tasks that break the contract's ranges, for the run's own check of what
evaluations bring in (tests/sdbc_evolution/run/test_boundaries.py): gate escape
with one fault each, named by this file's path."""

from __future__ import annotations

from sdbc_sim.tasks.gate_escape import GateEscape


class NegativeFitness(GateEscape):
    """Every trial's fitness is below 0 (the harmonic mean would floor it at
    1e-4, so evolution would get no signal)."""

    def results(self, trials, length):  # type: ignore[no-untyped-def]
        fitness, characterisation = super().results(trials, length)
        return fitness - 2.0, characterisation


class CharacterisationNineteen(GateEscape):
    """Characterisation values up to 19, where the contract says [0, 1]."""

    def results(self, trials, length):  # type: ignore[no-untyped-def]
        fitness, characterisation = super().results(trials, length)
        return fitness, characterisation * 18.0 + 1.0


class MissingGroup(GateEscape):
    """Its task state holds one group fewer than its description declares."""

    def task_state(self, trials, bodies):  # type: ignore[no-untyped-def]
        return super().task_state(trials, bodies)[:-1]
