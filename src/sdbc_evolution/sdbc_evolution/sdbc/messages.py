"""SDBCs from a stream of ``sdbc_msgs/TaskState`` messages.

Any ROS 2 system that publishes ``sdbc_msgs/TaskState`` (a simulator, real robots
with a tracker) gets systematic behaviour characterisations: messages are turned
into task state arrays (:mod:`sdbc_sim.task_state_msgs`) and fed, trial by trial, to
the same extractor the engine feeds, so that a trial gives the same vector either
way.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
from sdbc_sim.task_state import Geometry, TaskDescription
from sdbc_sim.task_state_msgs import task_description_from_msg, task_state_from_msg

from sdbc_evolution.sdbc.characterisation import SdbcExtractor, dimension_names


class MessageSdbcExtractor:
    """Raw SDBC vectors from a stream of ``sdbc_msgs/TaskState`` messages.

    Messages of several trials may interleave; each trial (``trial_id``) gets its
    own streaming extractor, fed message by message from step 1, and yields its
    vector on its ``done`` message. Nothing but running sums is kept.

    Args:
        description: The task description; if None, it is read from the first
            message (see :func:`task_description_from_msg`). Every message is checked
            against it.
        geometries: Geometry of groups by name, for reading the description from a
            first message in which a group is empty.
    """

    def __init__(
        self,
        description: TaskDescription | None = None,
        geometries: Mapping[str, Geometry] | None = None,
    ) -> None:
        self.description = description
        self.geometries = dict(geometries or {})
        self._trials: dict[int, SdbcExtractor] = {}

    @property
    def dimension_names(self) -> tuple[str, ...]:
        """Names of the vectors' dimensions (once the description is known)."""
        if self.description is None:
            raise RuntimeError("message extractor: no message yet, no description")
        return dimension_names(self.description)

    @property
    def open_trials(self) -> tuple[int, ...]:
        """Trials seen but not done."""
        return tuple(self._trials)

    def add(self, msg: Any) -> np.ndarray | None:
        """Adds one message; returns its trial's (D,) raw vector if it is the last.

        Raises:
            ValueError: On a message that does not fit the description, or a step
                out of order within its trial (a lost message would bias the vector).
        """
        if self.description is None:
            self.description = task_description_from_msg(msg, self.geometries)
        trial_id = int(msg.trial_id)
        extractor = self._trials.get(trial_id)
        if extractor is None:
            if int(msg.step) != 1:
                raise ValueError(
                    f"task {msg.task!r}, trial {trial_id}: its first message is step "
                    f"{msg.step}; a trial's messages must start at step 1"
                )
            extractor = SdbcExtractor()
            extractor.start(self.description, 1)
            self._trials[trial_id] = extractor
        try:
            extractor.observe(task_state_from_msg(msg, self.description))
        except ValueError:
            del self._trials[trial_id]
            raise
        if not msg.done:
            return None
        del self._trials[trial_id]
        return extractor.characterisations()[0]


def characterise_messages(
    messages: Iterable[Any], description: TaskDescription | None = None
) -> dict[int, np.ndarray]:
    """The raw vector of every trial that ends in ``messages``, by trial id."""
    extractor = MessageSdbcExtractor(description)
    vectors = {}
    for msg in messages:
        vector = extractor.add(msg)
        if vector is not None:
            vectors[int(msg.trial_id)] = vector
    return vectors
