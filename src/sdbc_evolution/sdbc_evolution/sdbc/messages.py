"""SDBCs from a stream of ``sdbc_msgs/TaskState`` messages.

Any ROS 2 system that publishes ``sdbc_msgs/TaskState`` (a simulator, real robots
with a tracker) gets systematic behaviour characterisations: messages are turned
into task state arrays (:mod:`sdbc_sim.task_state_msgs`) and fed, trial by trial, to
the same extractor the engine feeds, so that a trial gives the same vector either
way.

Two things differ from the engine's arrays, and both are handled here:

- A message packs the entities present into its first slots, so a slot does not
  keep its entity: when a static group's membership changes (food eaten, a target
  removed), the entity in slot 0 changes. Static groups' shapes are therefore read
  at every step, not once per trial.
- A group may be empty in the first message, so its geometry cannot be read there.
  Its features do not depend on its geometry while it is empty; the geometry is
  learnt from its first entity, and every open trial continues under the completed
  description (:meth:`SdbcExtractor.redescribe`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Mapping
from typing import Any

import numpy as np
from sdbc_sim.task_state import Geometry, TaskDescription
from sdbc_sim.task_state_msgs import (
    GEOMETRY_OF_CODE,
    task_description_from_msg,
    task_state_from_msg,
)

from sdbc_evolution.sdbc.characterisation import SdbcExtractor, dimension_names

PROVISIONAL_GEOMETRY = Geometry.POINT
"""Stands for the geometry of a group that has had no entity yet: an empty group
contributes nothing that depends on its geometry."""


class IncompleteTrials(ValueError):
    """Trials whose messages stop before their ``done`` message.

    Attributes:
        task: The task's name.
        steps: Steps received of each incomplete trial, by trial id.
    """

    def __init__(self, task: str, steps: Mapping[int, int]) -> None:
        self.task = task
        self.steps = dict(steps)
        listed = ", ".join(
            f"trial {t} ({n} step{'s' if n != 1 else ''})"
            for t, n in sorted(self.steps.items())
        )
        super().__init__(
            f"task {task!r}: {len(self.steps)} incomplete trial(s), no message with "
            f"done after the last step received: {listed}; messages were lost or the "
            "stream was cut (a bag stopped before its trial ended?)"
        )


class MessageSdbcExtractor:
    """Raw SDBC vectors from a stream of ``sdbc_msgs/TaskState`` messages.

    Messages of several trials may interleave; each trial (``trial_id``) gets its
    own streaming extractor, fed message by message from step 1, and yields its
    vector on its ``done`` message. Nothing but running sums is kept.

    Args:
        description: The task description; if None, it is read from the first
            message (see :func:`task_description_from_msg`). Every message is checked
            against it.
        geometries: Geometry of groups by name, for groups that are empty in the
            first message; a group not named here learns its geometry from its
            first entity.
        make_extractor: Makes each trial's streaming extractor (anything with
            ``start``, ``observe``, ``redescribe`` and ``characterisations``, as
            an SDBC with other options); by default the paper's
            :class:`SdbcExtractor`, reading static shapes at every step.
    """

    def __init__(
        self,
        description: TaskDescription | None = None,
        geometries: Mapping[str, Geometry] | None = None,
        make_extractor: Callable[[], Any] | None = None,
    ) -> None:
        self.description = description
        self.geometries = dict(geometries or {})
        self.make_extractor = make_extractor or (
            lambda: SdbcExtractor(fixed_static_geometry=False)
        )
        self._unknown_geometry: set[str] = set()
        # The paper's SdbcExtractor, or what make_extractor makes.
        self._trials: dict[int, Any] = {}

    @property
    def dimension_names(self) -> tuple[str, ...]:
        """Names of the paper's SDBC dimensions (once the description is known);
        with another ``make_extractor``, its own names apply."""
        if self.description is None:
            raise RuntimeError("message extractor: no message yet, no description")
        return dimension_names(self.description)

    @property
    def open_trials(self) -> tuple[int, ...]:
        """Trials seen but not done."""
        return tuple(self._trials)

    @property
    def unknown_geometries(self) -> tuple[str, ...]:
        """Groups that have had no entity yet, whose geometry is still unknown."""
        return tuple(sorted(self._unknown_geometry))

    def steps(self, trial_id: int) -> int:
        """Steps received so far of an open trial.

        Raises:
            KeyError: If the trial is not open.
        """
        return int(self._trials[trial_id].lengths[0])

    def add(self, msg: Any) -> np.ndarray | None:
        """Adds one message; returns its trial's (D,) raw vector if it is the last.

        Raises:
            ValueError: On a message that does not fit the description, or a step
                out of order within its trial (a lost message would bias the vector).
        """
        description = self.description
        if description is None:
            description = self._describe(msg)
        elif self._unknown_geometry:
            description = self._learn_geometries(description, msg)
        self.description = description
        trial_id = int(msg.trial_id)
        extractor = self._trials.get(trial_id)
        if extractor is None:
            if int(msg.step) != 1:
                raise ValueError(
                    f"task {msg.task!r}, trial {trial_id}: its first message is step "
                    f"{msg.step}; a trial's messages must start at step 1"
                )
            extractor = self.make_extractor()
            extractor.start(description, 1)
            self._trials[trial_id] = extractor
        try:
            extractor.observe(task_state_from_msg(msg, description))
        except ValueError:
            del self._trials[trial_id]
            raise
        if not msg.done:
            return None
        del self._trials[trial_id]
        return extractor.characterisations()[0]

    def close(self, trial_id: int) -> np.ndarray:
        """Ends an open trial without its ``done`` message (a timeout): its (D,) raw
        vector over the steps received; it is no longer open.

        Raises:
            KeyError: If the trial is not open.
        """
        return self._trials.pop(trial_id).characterisations()[0]

    def _describe(self, msg: Any) -> TaskDescription:
        geometries = dict(self.geometries)
        for group in msg.groups:
            if not group.entities and group.name not in geometries:
                geometries[group.name] = PROVISIONAL_GEOMETRY
                self._unknown_geometry.add(group.name)
        return task_description_from_msg(msg, geometries)

    def _learn_geometries(
        self, description: TaskDescription, msg: Any
    ) -> TaskDescription:
        """``description`` completed with the geometry of groups whose first entity
        is in ``msg``; every open trial continues under it."""
        groups = list(description.groups)
        learnt = False
        for g, group in enumerate(msg.groups[: len(groups)]):
            name = groups[g].name
            if name not in self._unknown_geometry or not group.entities:
                continue
            code = int(group.entities[0].geometry)
            if code not in GEOMETRY_OF_CODE:
                raise ValueError(
                    f"task {msg.task!r}, trial {msg.trial_id}, step {msg.step}, group "
                    f"{name!r}: unknown geometry {code}"
                )
            groups[g] = dataclasses.replace(groups[g], geometry=GEOMETRY_OF_CODE[code])
            self._unknown_geometry.discard(name)
            learnt = True
        if learnt:
            description = dataclasses.replace(description, groups=tuple(groups))
            for extractor in self._trials.values():
                extractor.redescribe(description)
        return description


def characterise_messages(
    messages: Iterable[Any], description: TaskDescription | None = None
) -> dict[int, np.ndarray]:
    """The raw vector of every trial in ``messages``, by trial id.

    Raises:
        IncompleteTrials: If a trial has no ``done`` message (its messages stop
            early), naming each such trial and the steps it has.
        ValueError: On a message that does not fit, or a step out of order.
    """
    extractor = MessageSdbcExtractor(description)
    vectors = {}
    task = ""
    for msg in messages:
        task = msg.task
        vector = extractor.add(msg)
        if vector is not None:
            vectors[int(msg.trial_id)] = vector
    if extractor.open_trials:
        raise IncompleteTrials(
            task, {t: extractor.steps(t) for t in extractor.open_trials}
        )
    return vectors
