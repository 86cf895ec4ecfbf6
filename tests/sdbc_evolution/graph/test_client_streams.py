"""The graph client says when a trial's task state stream is malformed, naming the
trial, rather than only running it again."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import pytest

pytestmark = pytest.mark.ros


class _Logger:
    def __init__(self) -> None:
        self.warnings: list[str] = []

    def warning(self, message: str) -> None:
        self.warnings.append(message)


class _Node:
    """What the client asks of its node, without a ROS graph."""

    def __init__(self) -> None:
        self.logger = _Logger()

    def create_client(self, *args: Any, **kwargs: Any) -> object:
        return object()

    def create_subscription(self, *args: Any, **kwargs: Any) -> object:
        return object()

    def get_logger(self) -> _Logger:
        return self.logger


def test_a_malformed_task_state_is_logged_naming_the_trial(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from sdbc_evolution.graph.client import TRIAL_ATTEMPTS, GraphClient, TrialFailed
    from sdbc_sim.tasks import make_task

    node = _Node()
    client = GraphClient(node, make_task("gate_escape"), "gate_escape", timeout=5)
    trial_ids: list[int] = []

    def simulator(_client: object, request: Any, what: str) -> Any:
        # The simulator answers, and its task state stream skips steps 1 and 2.
        trial_ids.append(request.trial_id)
        client._on_task_state(SimpleNamespace(trial_id=request.trial_id, step=3))
        return SimpleNamespace(success=True, length=5, fitness=0.0, message="")

    monkeypatch.setattr(client, "_call", simulator)
    with pytest.raises(TrialFailed, match="step 3 arrived after step 0"):
        client.run_trial(7)
    assert node.logger.warnings == [
        f"trial {trial_id} (seed 7): bad task state stream (step 3 arrived after "
        f"step 0); attempt {attempt} of {TRIAL_ATTEMPTS}"
        for attempt, trial_id in enumerate(trial_ids, start=1)
    ]
