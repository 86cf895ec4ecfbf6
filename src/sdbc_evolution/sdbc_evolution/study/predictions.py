"""A study's own predictions: what its author expects of the treatments it compares,
declared in the preset and judged by the analysis.

A preset that asks a question (does NS-SD+ still fall below NS-SD at population
200? does my weighting beat the MI?) states its expected answer as predictions::

    predictions:
      - statement: NS-SD+ no longer falls below NS-SD at population 200
        a: ns-sd+
        b: ns-sd
        rule: not_below

This module declares them (a leaf of the study package: presets and the digest
import it).
:func:`sdbc_evolution.study.claims.judge_predictions` judges each on every task it
names (default: all of the study's) with the rules of the paper's claims, on each
run's best fitness: a two-sided Mann-Whitney test whose p is Holm-adjusted within
the task's fitness tests, and Vargha and Delaney's A with its bootstrap interval.
The report gives each its own row, apart from the paper's claims: *held*, *did not
hold*, or *cannot tell*. ``no_difference`` holds only when A's interval lies
inside ``claims.EQUIVALENCE_MARGIN``, ``not_below`` only when its lower end is
above the margin's lower bound: the absence of a significant difference alone,
which few runs give all too easily, is *cannot tell*.
"""

from __future__ import annotations

from typing import Annotated, Literal

from sdbc_sim.settings import Field, settings

from sdbc_evolution.ga.treatments import label

Rule = Literal["above", "no_difference", "not_below"]

RULE_TEXT: dict[str, str] = {
    "above": "{a} above {b}, significantly",
    "no_difference": "{a} and {b} within the equivalence margin",
    "not_below": "{a} not below {b} by more than the margin",
}
"""Each rule in words."""


@settings
class Prediction:
    """One expected outcome of a study, on each run's best fitness."""

    statement: Annotated[str, Field(min_length=1)]
    """The prediction in words, as the report prints it."""
    a: Annotated[str, Field(min_length=1)]
    """The first treatment, by its name in the preset."""
    b: Annotated[str, Field(min_length=1)]
    """The second treatment, by its name in the preset."""
    rule: Rule
    """``above``: ``a`` significantly above ``b``; ``no_difference``: A's
    interval inside the equivalence margin; ``not_below``: its lower end above
    the margin's lower bound (non-inferiority)."""
    tasks: tuple[str, ...] = ()
    """The tasks it concerns (empty: every task of the study)."""

    def concerns(self, task: str) -> bool:
        """Whether the prediction applies to ``task``."""
        return not self.tasks or task in self.tasks

    def rule_text(self) -> str:
        """The prediction in words, with the treatments' labels."""
        return RULE_TEXT[self.rule].format(a=label(self.a), b=label(self.b))
