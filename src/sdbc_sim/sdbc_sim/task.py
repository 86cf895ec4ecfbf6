"""The task interface: what a task declares, and what the engine asks of it.

How to write a task
===================

A task is a module holding a settings class made with
:func:`sdbc_sim.settings.settings` (every number as a default with its docstring,
its limits in the annotations, checks across fields in ``__post_init__``) and a
:class:`Task` subclass with class attributes ``name``, ``config_class`` and
``default_generations`` (and, optionally, ``sdbc_counterparts``). In
``sdbc_sim/tasks/`` it ends with ``TASK = MyTask``; anywhere else it is named as
``package.module:Class`` or ``path/file.py:Class``, or registered as an entry point
(:mod:`sdbc_sim.tasks`). It never touches the engine.

The engine owns the physics: every body of every trial is a pymunk circle driven
through its velocity and heading, walls are static segments, and trials never
meet. The task owns everything else, as numpy over the live trials of a batch (B
trials, R bodies each, batch-first arrays, trial-local coordinates; no Python loop
per trial or per robot inside a step). It declares, as attributes set in ``__init__``:

- ``description``: the :class:`~sdbc_sim.task_state.TaskDescription` (entity groups)
  that the SDBC extractor reads;
- ``network``: the :class:`~sdbc_sim.network.NetworkShape` of the controller;
- ``layout``: a :class:`BodyLayout`, the radius of each body of a trial and whether
  the network drives it (robots) or the task does (a scripted prey);
- ``walls``: (P, 2, 2) static segments, possibly empty;
- ``extent``: (x_min, y_min, x_max, y_max), a box no body centre can ever leave
  (for arenas without walls, allow for ``max speed x max_steps``); the engine sizes
  the trial slots from it;
- ``max_steps``;
- ``characterisation_names``: the names of the task-specific characterisation's
  dimensions (each valued in [0, 1]), in the order ``results`` returns them.

Then each step of a batch runs, in this order:

1. ``sensors(trials, bodies)`` -> (B, n_controlled, n_inputs) network inputs;
2. the network (or an outside controller) turns them into outputs in [0, 1];
3. ``actuate(trials, bodies, outputs)`` -> (speed, turn), each (B, R): every body
   turns by ``turn`` radians and moves ``speed`` units along its new heading; the
   engine turns it at once and gives it that velocity, so it moves during this
   step's physics (with ``PhysicsSettings(actuation="force")``, through
   F = m (v* - v) / dt, it moves one step later);
4. the physics step, after which bodies left overlapping a wall or each other by
   more than ``overlap_tolerance`` are projected apart; ``bodies`` then holds the
   new state;
5. ``update(trials, bodies, step)`` applies the rules and accumulates what the
   fitness and characterisation need, and returns which trials end at this step
   (the engine ends every trial at ``max_steps`` by itself). It may switch bodies
   off for good (``bodies.enabled[b, i] = False``: an escaped or captured robot):
   the engine then takes them out of every collision and holds them still. It may
   also anchor bodies (``bodies.anchored[b, i] = True``, e.g. a robot docked on a
   charger) and release them later: from the next step an anchored body is
   ``ANCHOR_MASS_FACTOR`` times heavier, so a body that runs into it cannot push
   it away, and the overlap projection moves only the other body;
6. if anyone observes: ``task_state(trials, bodies)`` -> one
   :class:`~sdbc_sim.task_state.GroupState` per group;
7. for the trials that ended: ``results(trials, length)`` -> (fitness (B,), each
   in the class's ``fitness_range``, [0, 1] unless it declares another;
   characterisation (B, C), each value in [0, 1]). Their values then freeze.

``reset(rngs)`` draws the initial conditions, each trial from its own
``numpy.random.Generator`` in a fixed order, and returns the task's per-trial state
(a :class:`TrialArrays` dataclass: every field an array with the trials first, so
the engine can drop finished trials) with the bodies' start positions and headings.
A trial's result must depend only on (settings, genome, seed).
"""

from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Generic, Self, TypeVar

import numpy as np

from sdbc_sim.compiled import compiled
from sdbc_sim.libm import hypot
from sdbc_sim.network import NetworkShape
from sdbc_sim.task_state import GroupState, TaskDescription


@dataclass(frozen=True)
class BodyLayout:
    """The physical bodies of one trial, in the order of the (B, R) arrays.

    Attributes:
        radii: Radius of each body.
        controlled: Whether each body is driven by the network (the first
            ``n_controlled`` bodies must be the controlled ones).
        mass: Mass of every body; the moment of inertia is that of a disc.
    """

    radii: tuple[float, ...]
    controlled: tuple[bool, ...]
    mass: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "radii", tuple(float(r) for r in self.radii))
        object.__setattr__(self, "controlled", tuple(bool(c) for c in self.controlled))
        if not self.radii:
            raise ValueError("body layout: a trial needs at least one body")
        if len(self.controlled) != len(self.radii):
            raise ValueError(
                f"body layout: {len(self.radii)} radii but {len(self.controlled)} "
                "controlled flags"
            )
        bad = [r for r in self.radii if not (np.isfinite(r) and r > 0.0)]
        if bad:
            raise ValueError(f"body layout: radii must be positive, got {bad}")
        n = self.n_controlled
        if not all(self.controlled[:n]) or any(self.controlled[n:]):
            raise ValueError("body layout: the controlled bodies must come first")
        if not (np.isfinite(self.mass) and self.mass > 0.0):
            raise ValueError(f"body layout: mass must be positive, got {self.mass}")

    @property
    def n_bodies(self) -> int:
        """R, the number of bodies per trial."""
        return len(self.radii)

    @property
    def n_controlled(self) -> int:
        """Number of bodies driven by the network."""
        return sum(self.controlled)


KINEMATICS = ("x", "y", "turning speed", "linear speed")
"""The first task-state attributes of a group of bodies
(:meth:`BodyState.kinematics`)."""


@dataclass
class BodyState:
    """Physical state of the bodies of the live trials, trial-local coordinates.

    Attributes:
        position: (B, R, 2) centres.
        angle: (B, R) headings, radians, not wrapped.
        velocity: (B, R, 2) linear velocities, units per step.
        angular_velocity: (B, R) turning speed, radians per step: the last turn.
        enabled: (B, R) bool; False once the task has switched a body off.
        anchored: (B, R) bool; True while the task anchors a body (see the
            module docstring); False for every body at the start.
        cos_angle: (B, R) cos(angle), kept by the engine (it needs it anyway).
        sin_angle: (B, R) sin(angle).
    """

    position: np.ndarray
    angle: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    enabled: np.ndarray
    anchored: np.ndarray
    cos_angle: np.ndarray
    sin_angle: np.ndarray

    @classmethod
    def at_rest(cls, position: np.ndarray, angle: np.ndarray) -> BodyState:
        """Bodies standing still at ``position`` (B, R, 2) with headings ``angle``
        (B, R), all enabled and none anchored: a state to call a task's sensors,
        actuation and rules with outside the engine (as a task's tests do)."""
        angle = np.asarray(angle, dtype=np.float64)
        shape = angle.shape
        return cls(
            position=position,
            angle=angle,
            velocity=np.zeros((*shape, 2)),
            angular_velocity=np.zeros(shape),
            enabled=np.ones(shape, dtype=bool),
            anchored=np.zeros(shape, dtype=bool),
            cos_angle=np.cos(angle),
            sin_angle=np.sin(angle),
        )

    @property
    def speed(self) -> np.ndarray:
        """(B, R) linear speed |v|."""
        return np.hypot(self.velocity[..., 0], self.velocity[..., 1])

    def kinematics(self, extra: int = 0) -> np.ndarray:
        """(B, R, 4 + extra) task-state attributes :data:`KINEMATICS` (x, y,
        turning speed = angular velocity, linear speed = |v|), then ``extra``
        columns for the caller to fill."""
        b, r = self.angle.shape
        out = np.empty((b, r, len(KINEMATICS) + extra))
        _kinematics(
            np.asarray(self.position, dtype=np.float64),
            np.asarray(self.angular_velocity, dtype=np.float64),
            np.asarray(self.velocity, dtype=np.float64),
            out,
        )
        return out


def kinematics_row(
    position: np.ndarray,
    angular_velocity: np.ndarray,
    velocity: np.ndarray,
    out: np.ndarray,
    t: int,
    i: int,
) -> None:  # pragma: no cover - compiled into the loops that call it
    """Body ``i`` of trial ``t`` of :func:`_kinematics`, a helper of the loops
    that fill a task's attributes in one pass."""
    out[t, i, 0] = position[t, i, 0]
    out[t, i, 1] = position[t, i, 1]
    out[t, i, 2] = angular_velocity[t, i]
    out[t, i, 3] = hypot(velocity[t, i, 0], velocity[t, i, 1])


def kinematics_and_centre_row(
    position: np.ndarray,
    angular_velocity: np.ndarray,
    velocity: np.ndarray,
    out: np.ndarray,
    centres: np.ndarray,
    t: int,
    i: int,
) -> None:  # pragma: no cover - compiled into the loops that call it
    """:func:`kinematics_row`, and the body's centre into ``centres`` (B, R, 2):
    a task state's centres are a copy of the strided positions, which the pass
    over the attributes makes for about nothing where a copy of its own cost
    as much as the pass (gate escape's, resource sharing's, predator-prey's)."""
    kinematics_row(position, angular_velocity, velocity, out, t, i)
    centres[t, i, 0] = position[t, i, 0]
    centres[t, i, 1] = position[t, i, 1]


@compiled(
    "void(float64[:, :, :], float64[:, :], float64[:, :, :], float64[:, :, ::1])",
    calls=(kinematics_row, hypot),
)
def _kinematics(
    position: np.ndarray,
    angular_velocity: np.ndarray,
    velocity: np.ndarray,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested against the numpy form
    """The first four columns of ``out`` (B, R, K): x, y, angular velocity and
    |v|, read from the engine's strided state rows in one pass (as whole arrays:
    a strided copy, a strided hypot and three column writes). |v| is
    :func:`sdbc_sim.libm.hypot`: the C library's ``hypot``, which numpy's
    ``np.hypot`` calls too, to the bit."""
    for t in range(out.shape[0]):
        for i in range(out.shape[1]):
            kinematics_row(position, angular_velocity, velocity, out, t, i)


@dataclass
class TrialArrays:
    """Base of a task's per-trial state: every field an array, trials first."""

    def take(self, rows: np.ndarray) -> Self:
        """The same state restricted to ``rows`` (an index array)."""
        return type(self)(
            **{f.name: getattr(self, f.name)[rows] for f in dataclasses.fields(self)}
        )


TrialsT = TypeVar("TrialsT", bound=TrialArrays)
"""A task's own per-trial state (its :class:`TrialArrays` subclass)."""


class Task(ABC, Generic[TrialsT]):
    """A task of the paper: arena, bodies, sensors, rules, fitness and
    characterisation, over a batch of trials. See the module docstring.

    Generic over its per-trial state: ``class GateEscape(Task[GateEscapeTrials])``
    gets its own trials back in every method after :meth:`reset`.
    """

    name: ClassVar[str]
    """The task's registered name ("gate_escape"): run folders and reports use it."""
    config_class: ClassVar[type]
    """Its settings class, made with :func:`sdbc_sim.settings.settings`."""
    default_generations: ClassVar[int]
    """Generations of a run when the configuration sets none (required)."""
    fitness_range: ClassVar[tuple[float, float]] = (0.0, 1.0)
    """Where every trial's fitness lies (predator-prey's reaches 2: a capture
    scores 2 - t/tau); evaluations with a fitness outside it are refused
    (``sdbc_evolution.run.evaluators.check_values``)."""
    sdbc_counterparts: ClassVar[Mapping[str, tuple[str, ...]]] = {}
    """Optional: for a dimension of the task-specific characterisation (a name in
    :attr:`characterisation_names`), the SDBC dimensions that measure the same
    thing (e.g. ``"escaped fraction": ("Agent group size (F)",)``); the study's
    relevance table marks them."""
    config: Any
    description: TaskDescription
    network: NetworkShape
    layout: BodyLayout
    walls: np.ndarray
    extent: tuple[float, float, float, float]
    max_steps: int
    characterisation_names: tuple[str, ...]

    def __init__(self, config: Any) -> None:
        """Builds the task from its settings (an instance of :attr:`config_class`);
        a task's own ``__init__`` derives the rest from them."""
        self.config = config

    @property
    def characterisation_size(self) -> int:
        """C, the length of the task-specific characterisation."""
        return len(self.characterisation_names)

    @property
    def genome_length(self) -> int:
        """Number of network weights a genome holds."""
        return self.network.genome_length

    @abstractmethod
    def reset(
        self, rngs: list[np.random.Generator]
    ) -> tuple[TrialsT, np.ndarray, np.ndarray]:
        """Initial conditions of ``len(rngs)`` trials.

        Returns:
            (trials, position (B, R, 2), angle (B, R)).
        """

    @abstractmethod
    def sensors(self, trials: TrialsT, bodies: BodyState) -> np.ndarray:
        """(B, n_controlled, n_inputs) network inputs."""

    @abstractmethod
    def actuate(
        self, trials: TrialsT, bodies: BodyState, outputs: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Speed and turn (B, R) of every body from the network outputs
        (B, n_controlled, n_outputs)."""

    @abstractmethod
    def update(self, trials: TrialsT, bodies: BodyState, step: int) -> np.ndarray:
        """Rules after the physics step ``step`` (1-based); (B,) bool: trials that
        end at this step."""

    @abstractmethod
    def task_state(self, trials: TrialsT, bodies: BodyState) -> tuple[GroupState, ...]:
        """The task state of the live trials, one group per description group."""

    @abstractmethod
    def results(
        self, trials: TrialsT, length: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Fitness (B,) and task-specific characterisation (B, C) of trials that
        ended after ``length`` (B,) steps."""
