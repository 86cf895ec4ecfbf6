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
  outside its limits, a message over :data:`~sdbc_sim.task_state_msgs.LIMITS`)
  is dropped with an error naming the problem; later messages of that trial are
  ignored. Any failure inside a callback, a MemoryError included, drops the trial
  it concerns with its reason, never the node;
- a task's description is learnt from its trials' first messages: a trial whose
  first message describes the groups otherwise than the trials before it (a
  stray publisher, a simulator edited between runs) is characterised under its
  own description, and the node logs the change; one stray message drops at
  most its own trial;
- a trial that loses steps (``step 41 follows step 34``: the publisher or this
  node fell behind) is dropped, and the node says it fell behind, with the
  steps lost and the counts so far.

What the node keeps is bounded (:data:`~sdbc_sim.task_state_msgs.LIMITS`): open
trials per task, task descriptions (the one unused longest is forgotten), and
the dropped trials whose later messages it ignores (the oldest forgotten first).

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
from collections import OrderedDict
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
from sdbc_sim.task_state_msgs import LIMITS, check_limits

from sdbc_evolution.sdbc.messages import MessageSdbcExtractor, StepGap
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
        # descriptions. Ordered by last use, so that the one unused longest goes
        # first when a new task name would pass the limit.
        self._extractors: OrderedDict[str, MessageSdbcExtractor] = OrderedDict()
        self._last_seen: dict[tuple[str, int], float] = {}
        self._dropped: OrderedDict[tuple[str, int], None] = OrderedDict()
        self.dropped = 0
        """Trials dropped so far, for any reason."""
        self.gaps = 0
        """Trials dropped so far because steps were lost."""
        self.steps_lost = 0
        """Steps those trials lost."""
        self.output = self.create_publisher(
            Characterisation, CHARACTERISATION_TOPIC, CHARACTERISATION_QOS
        )
        self.create_subscription(
            TaskState, TASK_STATE_TOPIC, self._on_task_state, TASK_STATE_QOS
        )
        self.create_timer(min(1.0, self.trial_timeout / 4), self._end_silent_trials)
        self.published = 0

    def _on_task_state(self, msg: TaskState) -> None:
        # A name over the limit is refused below; cut, it cannot take memory.
        key = (msg.task[: LIMITS.name_length + 1], int(msg.trial_id))
        if key in self._dropped:
            return
        try:
            check_limits(msg)
            extractor = self._extractor(msg.task)
            relearnt = extractor.relearnt
            vector = extractor.add(msg)
        except StepGap as gap:
            self.gaps += 1
            self.steps_lost += gap.lost
            self._drop(key, msg.task, gap)
            self.get_logger().warning(
                f"fell behind: task {_excerpt(key[0])!r}, trial {gap.trial_id} lost "
                f"{gap.lost} step(s) after step {gap.last}; {self.gaps} trial(s) "
                f"and {self.steps_lost} step(s) lost so far (a publisher faster "
                "than this node, or a history shallower than a trial)"
            )
            return
        except Exception as error:  # noqa: BLE001 - one trial's failure, never the node's
            self._drop(key, msg.task, error)
            return
        if extractor.relearnt != relearnt:
            self.get_logger().warning(
                f"task {_excerpt(key[0])!r}, trial {key[1]}: its first message "
                "describes the "
                "groups otherwise than the trials before it; characterised under its "
                f"own description ({extractor.relearnt} change(s) so far)"
            )
        if vector is None:
            self._last_seen[key] = time.monotonic()
            return
        self._last_seen.pop(key, None)
        try:
            self._publish(msg.task, key[1], extractor, vector, complete=True)
        except Exception as error:  # noqa: BLE001 - one trial's failure, never the node's
            self._drop(key, msg.task, error)

    def _extractor(self, task: str) -> MessageSdbcExtractor:
        extractor = self._extractors.get(task)
        if extractor is not None:
            self._extractors.move_to_end(task)
            return extractor
        if len(self._extractors) >= LIMITS.tasks:
            old, forgotten = self._extractors.popitem(last=False)
            for trial_id in forgotten.open_trials:
                self._last_seen.pop((old, trial_id), None)
            self.get_logger().warning(
                f"task {_excerpt(old)!r} forgotten for task {_excerpt(task)!r}: "
                f"limits.tasks = {LIMITS.tasks} task descriptions kept; its "
                f"{len(forgotten.open_trials)} open trial(s) are lost"
            )
        extractor = self._extractors[task] = MessageSdbcExtractor()
        return extractor

    def _drop(self, key: tuple[str, int], task: str, error: BaseException) -> None:
        self.dropped += 1
        self._dropped[key] = None
        if len(self._dropped) > LIMITS.dropped:
            self._dropped.popitem(last=False)
        self._last_seen.pop(key, None)
        extractor = self._extractors.get(task)
        if extractor is not None:
            extractor.discard(key[1])
        reason = str(error) or type(error).__name__
        self.get_logger().error(
            f"task {_excerpt(key[0])!r}, trial {key[1]} dropped, not characterised: "
            f"{_excerpt(reason, 400)} ({self.dropped} dropped so far)"
        )

    def _end_silent_trials(self) -> None:
        now = time.monotonic()
        silent = [k for k, t in self._last_seen.items() if now - t > self.trial_timeout]
        for task, trial_id in silent:
            del self._last_seen[(task, trial_id)]
            self._dropped[(task, trial_id)] = None
            if len(self._dropped) > LIMITS.dropped:
                self._dropped.popitem(last=False)
            extractor = self._extractors.get(task)
            if extractor is None or trial_id not in extractor.open_trials:
                continue
            try:
                steps = extractor.steps(trial_id)
                vector = extractor.close(trial_id)
                self.get_logger().warning(
                    f"task {_excerpt(task)!r}, trial {trial_id}: no message for "
                    f"{self.trial_timeout:g} s after step {steps} and no done; "
                    "published as incomplete"
                )
                self._publish(task, trial_id, extractor, vector, complete=False)
            except Exception as error:  # noqa: BLE001 - one trial's failure, never the node's
                self._drop((task, trial_id), task, error)

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
            dimension_names=list(extractor.last_dimension_names),
            values=vector.tolist(),
            length=int(vector[-1]),
            complete=complete,
        )
        msg.header.stamp = self.get_clock().now().to_msg()
        self.output.publish(msg)
        self.published += 1


def _excerpt(text: str, length: int = 60) -> str:
    """``text`` cut to ``length`` characters: logs and keys never echo a whole
    oversized value."""
    return text if len(text) <= length else text[: length - 3] + "..."


def main(argv: Sequence[str] | None = None) -> int:
    """The ``characteriser_node`` program: spins the node until Ctrl-C; the exit
    status."""
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
