"""Which characterisations the live graph makes, and why it refuses the others."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from sdbc_evolution.characterise.base import Characteriser
from sdbc_evolution.characterise.registry import CHARACTERISATIONS, parse
from sdbc_evolution.graph.client import check_live_characterisations


class _FromTaskState(Characteriser):
    """A characterisation of the task state alone, as a user's part may be."""

    def names(self, task: Any) -> tuple[str, ...]:
        return ("x",)

    def controller_vectors(self, result: Any, trials: int) -> np.ndarray:
        return np.zeros((1, 1))


@pytest.fixture
def task_state_part() -> Iterator[str]:
    CHARACTERISATIONS.register("test_from_task_state", _FromTaskState)
    try:
        yield "test_from_task_state"
    finally:
        CHARACTERISATIONS._own.pop("test_from_task_state")


def test_the_sdbc_with_options_is_made_and_the_two_always_there_are_skipped() -> None:
    specs = (parse("task"), parse("sdbc"), parse({"sdbc": {"aggregation": "mean"}}))
    assert check_live_characterisations(specs) == specs[2:]


def test_a_network_characterisation_is_refused_for_what_it_needs() -> None:
    with pytest.raises(ValueError, match="needs the robots' network inputs"):
        check_live_characterisations((parse("state_count"),))


def test_a_task_state_part_is_refused_for_what_the_client_makes(
    task_state_part: str,
) -> None:
    with pytest.raises(ValueError, match="makes only SDBCs") as refused:
        check_live_characterisations((parse(task_state_part),))
    assert "network" not in str(refused.value)
