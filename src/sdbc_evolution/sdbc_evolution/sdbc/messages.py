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
  learnt from its first entity, and the trial continues under the completed
  description (:meth:`SdbcExtractor.redescribe`); later trials start with it.

Without a description given, the description is learnt again whenever a trial's
first message describes its groups otherwise than the description so far (a
stray publisher, a simulator edited between runs): **a trial is characterised
under the description its first message carried**, its vector named after it,
and a message that does not fit its own trial's description drops that trial
only. :attr:`MessageSdbcExtractor.relearnt` counts the changes; the characteriser
node logs each. With a description given, every message is checked against it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from sdbc_sim.task_state import Geometry, TaskDescription
from sdbc_sim.task_state_msgs import (
    GEOMETRY_CODES,
    GEOMETRY_OF_CODE,
    LIMITS,
    TaskStateLimits,
    task_description_from_msg,
    task_state_from_msg,
)

from sdbc_evolution.sdbc.characterisation import SdbcExtractor, dimension_names
from sdbc_evolution.sdbc.options import PAPER, SdbcOptions

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


class StepGap(ValueError):
    """A trial's message is not the step after the last one received: messages
    were lost (a publisher or listener that fell behind) or came out of order.

    Attributes:
        task: The task's name.
        trial_id: The trial.
        last: The last step received.
        step: The step of the message.
    """

    def __init__(self, task: str, trial_id: int, last: int, step: int) -> None:
        self.task, self.trial_id, self.last, self.step = task, trial_id, last, step
        lost = f"{self.lost} step(s) lost" if self.lost else "out of order"
        super().__init__(
            f"task {task!r}, trial {trial_id}: step {step} follows step {last} "
            f"({lost}); steps must arrive in order from 1"
        )

    @property
    def lost(self) -> int:
        """Steps missing between the last one received and this one (0 if the
        message is older than the last)."""
        return max(self.step - self.last - 1, 0)


@dataclass
class _Trial:
    """An open trial: its extractor and the description it is characterised under."""

    extractor: Any
    description: TaskDescription
    unknown_geometry: set[str]
    steps: int = 0


class MessageSdbcExtractor:
    """Raw SDBC vectors from a stream of ``sdbc_msgs/TaskState`` messages.

    Messages of several trials may interleave; each trial (``trial_id``) gets its
    own streaming extractor, fed message by message from step 1, and yields its
    vector on its ``done`` message. Nothing but running sums is kept.

    Args:
        description: The task description; if None, it is read from the messages
            (see :func:`task_description_from_msg`), learnt again from a trial's
            first message that describes the groups otherwise. Every message is
            checked against its trial's description.
        geometries: Geometry of groups by name, for groups that are empty in a
            trial's first message; a group not named here learns its geometry from
            its first entity.
        make_extractor: Makes each trial's streaming extractor (anything with
            ``start``, ``observe``, ``redescribe``, ``characterisations`` and
            ``dimension_names``); by default the :class:`SdbcExtractor` with
            ``options``, reading static shapes at every step.
        options: The SDBC's options for the default extractor (the paper's if
            None).
        limits: What the stream may hold (:data:`LIMITS`); ``open_trials`` is
            checked here, the message limits by the conversion.
    """

    def __init__(
        self,
        description: TaskDescription | None = None,
        geometries: Mapping[str, Geometry] | None = None,
        make_extractor: Callable[[], Any] | None = None,
        options: SdbcOptions | None = None,
        limits: TaskStateLimits = LIMITS,
    ) -> None:
        self.description = description
        self.fixed = description is not None
        self.geometries = dict(geometries or {})
        self.options = options or PAPER
        self.make_extractor = make_extractor or (
            lambda: SdbcExtractor(self.options, fixed_static_geometry=False)
        )
        self.limits = limits
        self.relearnt = 0
        """Times a trial's first message brought a description other than the
        one so far."""
        self.last_dimension_names: tuple[str, ...] = ()
        """Names of the vector :meth:`add` or :meth:`close` returned last."""
        self._unknown_geometry: set[str] = set()
        self._trials: dict[int, _Trial] = {}

    @property
    def dimension_names(self) -> tuple[str, ...]:
        """Names of the dimensions under the latest description (once one is
        known); a trial begun under an earlier one has the names
        :attr:`last_dimension_names` gives with its vector."""
        if self.description is None:
            raise RuntimeError("message extractor: no message yet, no description")
        return dimension_names(self.description, self.options)

    @property
    def open_trials(self) -> tuple[int, ...]:
        """Trials seen but not done."""
        return tuple(self._trials)

    @property
    def unknown_geometries(self) -> tuple[str, ...]:
        """Groups of the latest description that have had no entity yet, whose
        geometry is still unknown."""
        return tuple(sorted(self._unknown_geometry))

    def steps(self, trial_id: int) -> int:
        """Steps received so far of an open trial.

        Raises:
            KeyError: If the trial is not open.
        """
        return self._trials[trial_id].steps

    def add(self, msg: Any) -> np.ndarray | None:
        """Adds one message; returns its trial's (D,) raw vector if it is the last.

        Raises:
            StepGap: A step missing or out of order within its trial (a lost
                message would bias the vector); the trial is dropped.
            ValueError: On a message that does not fit its trial's description, or
                over a limit; the trial, if open, is dropped.
        """
        trial_id = int(msg.trial_id)
        trial = self._trials.get(trial_id)
        step = int(msg.step)
        try:
            if trial is None:
                if step != 1:
                    raise ValueError(
                        f"task {msg.task!r}, trial {trial_id}: its first message is "
                        f"step {step}; a trial's messages must start at step 1"
                    )
                if len(self._trials) >= self.limits.open_trials:
                    raise ValueError(
                        f"task {msg.task!r}, trial {trial_id}: {len(self._trials)} "
                        "trials open, the most limits.open_trials = "
                        f"{self.limits.open_trials} allows; end some (done) first"
                    )
                trial = self._begin(msg)
            else:
                if step != trial.steps + 1:
                    raise StepGap(str(msg.task), trial_id, trial.steps, step)
                if trial.unknown_geometry:
                    self._learn_geometries(trial, msg)
            trial.extractor.observe(task_state_from_msg(msg, trial.description))
        except Exception:
            # Whatever failed (a MemoryError too), the trial is not left half fed.
            self._trials.pop(trial_id, None)
            raise
        trial.steps = step
        self._trials[trial_id] = trial
        if not msg.done:
            return None
        del self._trials[trial_id]
        return self._vector(trial)

    def close(self, trial_id: int) -> np.ndarray:
        """Ends an open trial without its ``done`` message (a timeout): its (D,) raw
        vector over the steps received; it is no longer open.

        Raises:
            KeyError: If the trial is not open.
        """
        return self._vector(self._trials.pop(trial_id))

    def discard(self, trial_id: int) -> None:
        """Forgets a trial, open or not, without a vector."""
        self._trials.pop(trial_id, None)

    def _vector(self, trial: _Trial) -> np.ndarray:
        self.last_dimension_names = tuple(trial.extractor.dimension_names)
        return trial.extractor.characterisations()[0]

    def _begin(self, msg: Any) -> _Trial:
        """A new trial, under the description so far if its first message fits
        it, else under the description the message gives."""
        description = self.description
        if description is None or not (self.fixed or self._fits(description, msg)):
            previous = description
            description = self._describe(msg)
            if previous is not None:
                self.relearnt += 1
            self.description = description
        extractor = self.make_extractor()
        extractor.start(description, 1)
        unknown = set() if self.fixed else set(self._unknown_geometry)
        trial = _Trial(extractor, description, unknown)
        if unknown:
            self._learn_geometries(trial, msg)
        return trial

    def _fits(self, description: TaskDescription, msg: Any) -> bool:
        """The message's group fields are the description's, and its entities
        have the geometry it gives (or one it has not learnt yet)."""
        if len(msg.groups) != len(description.groups):
            return False
        for spec, group in zip(description.groups, msg.groups, strict=True):
            if (
                group.name != spec.name
                or tuple(group.attribute_names) != spec.attributes
                or int(group.min_size) != spec.min_size
                or int(group.max_size) != spec.max_size
                or bool(group.is_static) != spec.static
            ):
                return False
            if (
                group.entities
                and spec.name not in self._unknown_geometry
                and int(group.entities[0].geometry) != GEOMETRY_CODES[spec.geometry]
            ):
                return False
        return True

    def _describe(self, msg: Any) -> TaskDescription:
        geometries = dict(self.geometries)
        unknown = set()
        for group in msg.groups:
            if not group.entities and group.name not in geometries:
                geometries[group.name] = PROVISIONAL_GEOMETRY
                unknown.add(str(group.name))
        description = task_description_from_msg(msg, geometries)
        self._unknown_geometry = unknown
        return description

    def _learn_geometries(self, trial: _Trial, msg: Any) -> None:
        """The trial's description completed with the geometry of groups whose
        first entity is in ``msg``; later trials of that description start with
        it."""
        groups = list(trial.description.groups)
        learnt = False
        for g, group in enumerate(msg.groups[: len(groups)]):
            name = groups[g].name
            if name not in trial.unknown_geometry or not group.entities:
                continue
            code = int(group.entities[0].geometry)
            if code not in GEOMETRY_OF_CODE:
                raise ValueError(
                    f"task {msg.task!r}, trial {msg.trial_id}, step {msg.step}, group "
                    f"{name!r}: unknown geometry {code}"
                )
            groups[g] = dataclasses.replace(groups[g], geometry=GEOMETRY_OF_CODE[code])
            trial.unknown_geometry.discard(name)
            learnt = True
        if not learnt:
            return
        completed = dataclasses.replace(trial.description, groups=tuple(groups))
        if trial.description is self.description:
            self.description = completed
            self._unknown_geometry = set(trial.unknown_geometry)
        trial.description = completed
        trial.extractor.redescribe(completed)


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
