"""``characteriser_node``: SDBCs for any ROS 2 system that publishes the task state.

The node subscribes to a ``sdbc_msgs/TaskState`` topic (``task_state`` by default)
from any publisher: this project's simulator, another simulator, real robots under
a tracker. It knows nothing of the task beforehand: the task description (groups,
attribute names, size limits, static flags, geometry) is read from the messages
themselves (:class:`sdbc_evolution.sdbc.messages.MessageSdbcExtractor`). Each
trial (``trial_id``; trials may interleave, and several tasks may share the topic)
is characterised message by message, keeping only running sums, and when it ends
its named vector goes out as one ``sdbc_msgs/Characterisation`` on
``characterisation``:

- a trial ends on its message with ``done``; the vector is ``complete``;
- a trial that gets no message for ``trial_timeout`` seconds is ended there: the
  node logs a warning naming it and its step count, and publishes the vector over
  the steps received with ``complete = false``;
- a trial whose messages do not fit (a step missing or out of order, a group
  outside its limits) is dropped with an error naming the problem; later messages
  of that trial are ignored.

The output topic is reliable, transient-local and a thousand messages deep
(:data:`sdbc_sim.nodes.interface.CHARACTERISATION_QOS`), so that no trial is lost to
a subscriber that joins late or reads slowly. The subscription asks for the task
state's depth too: the ROS default of 5 drops steps.

Usage::

    characteriser_node
    characteriser_node --ros-args -p trial_timeout:=30.0 \\
        -r task_state:=/tracker/task_state
    ros2 topic echo /characterisation --qos-durability transient_local
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from sdbc_sim.nodes.interface import (
    CHARACTERISATION_QOS,
    CHARACTERISATION_TOPIC,
    CHARACTERISER_NODE,
    TASK_STATE_QOS,
    TASK_STATE_TOPIC,
)
from sdbc_sim.nodes.parameters import CheckedNode
from sdbc_sim.nodes.startup import NodeProgram, run_node_program, spin_until_stopped

from sdbc_evolution.sdbc.messages import MessageSdbcExtractor
from sdbc_msgs.msg import Characterisation, TaskState

AGGREGATIONS = ("mean+final",)
"""Values of the ``aggregation`` parameter: the paper's, each feature's mean over
the trial, then its final value, then the trial length."""
DEFAULT_TRIAL_TIMEOUT = 10.0
"""Seconds without a message after which an open trial is ended as incomplete."""
MAX_TIMEOUT = 3600.0
"""Largest ``trial_timeout`` accepted, seconds."""


class CharacteriserNode(CheckedNode):
    """Characterises every trial seen on the task state topic.

    Parameters (ROS), read-only:
        trial_timeout: Seconds without a message after which an open trial ends,
            reported and published as incomplete.
        aggregation: How features become the vector; one of :data:`AGGREGATIONS`.

    Args:
        **kwargs: Passed on to :class:`rclpy.node.Node`.

    Raises:
        ValueError: A bad parameter, naming it.
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(CHARACTERISER_NODE, **kwargs)
        self.trial_timeout = self.declare_parameter(
            "trial_timeout",
            DEFAULT_TRIAL_TIMEOUT,
            ParameterDescriptor(
                description="Seconds without a message before a trial ends incomplete",
                read_only=True,
                floating_point_range=[
                    FloatingPointRange(from_value=1e-3, to_value=MAX_TIMEOUT)
                ],
            ),
        ).value
        self.aggregation = self.declare_parameter(
            "aggregation",
            AGGREGATIONS[0],
            ParameterDescriptor(
                description="Aggregation of features: " + ", ".join(AGGREGATIONS),
                read_only=True,
            ),
        ).value
        if self.aggregation not in AGGREGATIONS:
            raise ValueError(
                f"parameter aggregation: {self.aggregation!r} is not one of "
                f"{', '.join(AGGREGATIONS)}"
            )
        # One extractor per task: tasks that share the topic have their own
        # descriptions.
        self._extractors: dict[str, MessageSdbcExtractor] = {}
        self._last_seen: dict[tuple[str, int], float] = {}
        self._dropped: set[tuple[str, int]] = set()
        self.output = self.create_publisher(
            Characterisation, CHARACTERISATION_TOPIC, CHARACTERISATION_QOS
        )
        self.create_subscription(
            TaskState, TASK_STATE_TOPIC, self._on_task_state, TASK_STATE_QOS
        )
        self.create_timer(min(1.0, self.trial_timeout / 4), self._end_silent_trials)
        self.published = 0

    def _on_task_state(self, msg: TaskState) -> None:
        key = (msg.task, int(msg.trial_id))
        if key in self._dropped:
            return
        extractor = self._extractors.setdefault(msg.task, MessageSdbcExtractor())
        try:
            vector = extractor.add(msg)
        except ValueError as error:
            self._dropped.add(key)
            self._last_seen.pop(key, None)
            self.get_logger().error(
                f"task {msg.task!r}, trial {msg.trial_id} dropped, not characterised: "
                f"{error}"
            )
            return
        if vector is None:
            self._last_seen[key] = time.monotonic()
            return
        self._last_seen.pop(key, None)
        self._publish(msg.task, int(msg.trial_id), extractor, vector, complete=True)

    def _end_silent_trials(self) -> None:
        now = time.monotonic()
        silent = [k for k, t in self._last_seen.items() if now - t > self.trial_timeout]
        for task, trial_id in silent:
            del self._last_seen[(task, trial_id)]
            self._dropped.add((task, trial_id))
            extractor = self._extractors[task]
            steps = extractor.steps(trial_id)
            self.get_logger().warning(
                f"task {task!r}, trial {trial_id}: no message for "
                f"{self.trial_timeout:g} s after step {steps} and no done; published "
                "as incomplete"
            )
            self._publish(
                task, trial_id, extractor, extractor.close(trial_id), complete=False
            )

    def _publish(
        self,
        task: str,
        trial_id: int,
        extractor: MessageSdbcExtractor,
        vector: np.ndarray,
        complete: bool,
    ) -> None:
        msg = Characterisation(
            task=task,
            trial_id=trial_id,
            aggregation=self.aggregation,
            dimension_names=list(extractor.dimension_names),
            values=vector.tolist(),
            length=int(vector[-1]),
            complete=complete,
        )
        msg.header.stamp = self.get_clock().now().to_msg()
        self.output.publish(msg)
        self.published += 1


def main(argv: Sequence[str] | None = None) -> int:
    # Ctrl-C stops the node but keeps the context up, so that the last
    # characterisations still reach their readers before it leaves.
    return run_node_program(
        NodeProgram(
            name="characteriser_node",
            make_nodes=lambda startup: [CharacteriserNode()],
            serve=spin_until_stopped,
            flush=lambda node: [node.output],
        ),
        argv,
    )


if __name__ == "__main__":
    sys.exit(main())
