"""The batched simulation engine: ``run_batch(task, genomes, seeds, observers)``.

Every trial of a batch steps together: the task's sensors, the networks and the
task's rules run as numpy over all robots of all live trials, the physics by the
model ``PhysicsSettings.model`` names: rigid bodies in a few pymunk Spaces moved
in bulk (:mod:`sdbc_sim.physics`, the default) or the authors' kinematic robots
in one compiled loop (:mod:`sdbc_sim.kinematic`). A trial that ends freezes
at once (its results are taken at its last step); its rows keep riding along, held
still, until enough trials have ended to make dropping them worthwhile
(``compact_fraction``), and then stop costing anything.

The same stepping code serves one trial driven from outside, step by step
(:class:`TrialStepper`, for the live ROS graph), so a trial run live and in a batch
give the same results to the bit when the outputs come from the same network.

Per-controller aggregates (Gomes et al.; docs/reference-setup.md "Evolution"):
fitness is the harmonic mean over a controller's T trials, T / sum_t 1 / max(F_t, 1e-4),
as in the authors' code, or the arithmetic mean; the characterisation is the arithmetic
mean.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from sdbc_sim.compiled import compiled, load

# Re-exported: the engine's callers sum trials up with it.
from sdbc_sim.fitness import FITNESS_MEANS as FITNESS_MEANS
from sdbc_sim.fitness import HARMONIC_FLOOR as HARMONIC_FLOOR
from sdbc_sim.fitness import controller_fitness as controller_fitness
from sdbc_sim.generators import trial_generators
from sdbc_sim.kinematic import KinematicTrials
from sdbc_sim.network import TeamNetworks, check_genomes
from sdbc_sim.observer import NetworkObserver, Observer
from sdbc_sim.physics import (
    READ_WIDTH,
    WRITE_WIDTH,
    PhysicsSettings,
    TrialPhysics,
    TrialSpaces,
)
from sdbc_sim.task import BodyState, Task
from sdbc_sim.task_state import GroupState, TaskState

PHYSICS_MODELS: dict[str, type[TrialSpaces] | type[KinematicTrials]] = {
    "rigid": TrialSpaces,
    "kinematic": KinematicTrials,
}
"""The class behind each ``PhysicsSettings.model``."""


@dataclass(frozen=True)
class EngineSettings:
    """Settings of the engine.

    Attributes:
        physics: Layout of trials in pymunk and its solver settings.
        compact_fraction: Finished trials are dropped from the arrays and the
            Spaces once they make up this share of the rows still held.
    """

    physics: PhysicsSettings = field(default_factory=PhysicsSettings)
    compact_fraction: float = 0.125

    def __post_init__(self) -> None:
        if not 0.0 < self.compact_fraction <= 1.0:
            raise ValueError(
                "engine: compact_fraction must be in (0, 1], got "
                f"{self.compact_fraction}"
            )


def check_seeds(seeds: np.ndarray, n_genomes: int | None = None) -> np.ndarray:
    """Returns ``seeds`` as an int64 (G, T) array, or raises ValueError naming the
    problem (wrong shape, not integers, negative, genome count mismatch)."""
    s = np.asarray(seeds)
    if s.ndim != 2 or s.shape[1] < 1:
        raise ValueError(
            f"seeds: expected a (G, T) array with T >= 1, got shape {s.shape}"
        )
    if n_genomes is not None and s.shape[0] != n_genomes:
        raise ValueError(f"seeds: {s.shape[0]} rows for {n_genomes} genomes")
    if s.size and not np.issubdtype(s.dtype, np.integer):
        raise ValueError(f"seeds: expected integers, got {s.dtype}")
    s = s.astype(np.int64)
    if (s < 0).any():
        raise ValueError("seeds: must be non-negative")
    return s


class BatchSimulation:
    """A batch of trials of one task, stepped together.

    Args:
        task: The task.
        seeds: (B,) one seed per trial; trial b draws its initial conditions from
            ``numpy.random.default_rng(seeds[b])``.
        genomes: (B, W) the genome of each trial's team, or None to supply the
            network outputs from outside at every :meth:`step`.
        settings: Engine settings.
    """

    def __init__(
        self,
        task: Task,
        seeds: np.ndarray,
        genomes: np.ndarray | None = None,
        settings: EngineSettings | None = None,
    ) -> None:
        self.task = task
        self.settings = settings or EngineSettings()
        seeds = check_seeds(np.asarray(seeds).reshape(-1, 1)).ravel()
        n = self.n_trials = seeds.shape[0]
        layout = task.layout
        self._n_bodies = layout.n_bodies
        self._n_ctrl = layout.n_controlled
        self._networks: TeamNetworks | None = None
        if genomes is not None:
            g = check_genomes(genomes, task.network)
            if g.shape[0] != n:
                raise ValueError(f"genomes: {g.shape[0]} genomes for {n} trials")
            self._networks = TeamNetworks(task.network, g)
        # Before the starts are drawn, which use a loop once it is loaded.
        load()
        rngs = trial_generators(seeds)
        self.trials, position, angle = task.reset(rngs)
        if position.shape != (n, self._n_bodies, 2) or angle.shape != (
            n,
            self._n_bodies,
        ):
            raise ValueError(
                f"{task.name}: reset gave positions {position.shape} and angles "
                f"{angle.shape} for {n} trials of {self._n_bodies} bodies"
            )
        physics = self.settings.physics
        self.spaces: TrialPhysics = PHYSICS_MODELS[physics.model].of_task(
            task, position, angle, physics
        )
        self._rows = np.empty((n * self._n_bodies, READ_WIDTH))
        self._turn_rate = np.zeros((n, self._n_bodies))
        self.spaces.read(self._rows)
        self._cos = np.empty((n, self._n_bodies))
        self._sin = np.empty((n, self._n_bodies))
        _headings(self._rows[:, 2].reshape(n, self._n_bodies), self._cos, self._sin)
        self.bodies = self._body_views(
            np.ones((n, self._n_bodies), dtype=bool),
            np.zeros((n, self._n_bodies), dtype=bool),
        )
        self._enabled = self.bodies.enabled.copy()
        self._anchored = self.bodies.anchored.copy()
        self._running = np.ones(n, dtype=bool)
        self._took_step = np.zeros(n, dtype=bool)
        self.step_count = 0
        self.done = np.zeros(n, dtype=bool)
        self.length = np.zeros(n, dtype=np.int64)
        self.fitness = np.full(n, np.nan)
        self.characterisation = np.full((n, task.characterisation_size), np.nan)
        self._full: dict[tuple[int, int], np.ndarray] = {}
        self.network_observers: list[NetworkObserver] = []
        """Observers handed the network inputs and outputs at every step."""

    @property
    def live(self) -> np.ndarray:
        """Indices of the trials whose rows the arrays hold, in row order; they
        change only at the end of :meth:`step`."""
        return self.spaces.live

    @property
    def finished(self) -> bool:
        """True once every trial has ended."""
        return bool(self.done.all())

    def _body_views(self, enabled: np.ndarray, anchored: np.ndarray) -> BodyState:
        b, r = enabled.shape
        rows = self._rows
        return BodyState(
            position=rows[:, 0:2].reshape(b, r, 2),
            angle=rows[:, 2].reshape(b, r),
            velocity=rows[:, 3:5].reshape(b, r, 2),
            angular_velocity=self._turn_rate,
            cos_angle=self._cos,
            sin_angle=self._sin,
            enabled=enabled,
            anchored=anchored,
        )

    def sensors(self) -> np.ndarray:
        """(n_live, n_controlled, n_inputs) network inputs of the live trials."""
        return self.task.sensors(self.trials, self.bodies)

    def step(self, outputs: np.ndarray | None = None) -> None:
        """Advances every running trial by one step.

        Args:
            outputs: (n_live, n_controlled, n_outputs) network outputs in [0, 1]
                for the rows of :attr:`live`, when the simulation has no genomes.
        """
        if self.finished:
            raise RuntimeError("step: every trial has ended")
        task = self.task
        n_live = self.live.shape[0]
        shape = (n_live, self._n_ctrl, task.network.n_outputs)
        inputs: np.ndarray | None = None
        if outputs is None:
            if self._networks is None:
                raise ValueError("step: this simulation has no genomes; pass outputs")
            inputs = self.sensors()
            outputs = self._networks.forward(inputs)
        else:
            outputs = np.asarray(outputs, dtype=np.float64)
            if outputs.shape != shape:
                raise ValueError(
                    f"step: outputs have shape {outputs.shape}, need {shape}"
                )
            if not np.all((outputs >= 0.0) & (outputs <= 1.0)):
                raise ValueError(
                    "step: outputs must lie in [0, 1] (NaN is not allowed)"
                )
        if self.network_observers:
            self._tell_network_observers(inputs, outputs)
        speed, turn = task.actuate(self.trials, self.bodies, outputs)
        self.spaces.step(self._drive(speed, turn), self._rows)
        self.spaces.separate(self._rows, self.bodies.enabled, self._anchored)
        self.step_count += 1
        k = self.step_count
        ends = task.update(self.trials, self.bodies, k)
        if k >= task.max_steps:
            ends = np.ones_like(ends)
        switched_off = self._enabled & ~self.bodies.enabled
        if switched_off.any():
            self.spaces.disable(*np.nonzero(switched_off))
            self.bodies.velocity[switched_off] = 0.0
            self._enabled &= self.bodies.enabled
        changed = self._anchored != self.bodies.anchored
        if changed.any():
            trials, bodies = np.nonzero(changed)
            self.spaces.anchor(trials, bodies, self.bodies.anchored[changed])
            np.copyto(self._anchored, self.bodies.anchored)
        np.copyto(self._took_step, self._running)
        ends &= self._running
        if ends.any():
            rows = np.flatnonzero(ends)
            ids = self.live[rows]
            self.length[ids] = k
            f, c = task.results(
                self.trials.take(rows), np.full(rows.shape, k, np.int64)
            )
            self.fitness[ids] = f
            self.characterisation[ids] = c
            self.done[ids] = True
            self._running &= ~ends
        self._compact_if_worthwhile()

    def _tell_network_observers(
        self, inputs: np.ndarray | None, outputs: np.ndarray
    ) -> None:
        """Hands the running trials' network inputs and outputs to the observers
        that ask for them (reading the sensors adds nothing to the trials: they are
        a pure function of the state)."""
        if inputs is None:
            inputs = self.sensors()
        running = self._running
        enabled = self.bodies.enabled[:, : self._n_ctrl]
        trials = self.live
        if not running.all():
            trials, inputs = trials[running], inputs[running]
            outputs, enabled = outputs[running], enabled[running]
        for observer in self.network_observers:
            observer.observe_network(trials, inputs, outputs, enabled)

    def _drive(self, speed: np.ndarray, turn: np.ndarray) -> np.ndarray:
        """Drive rows (rows, 4), laid out as ``spaces.drive_columns``: angle,
        angular velocity, and velocity or force.

        A body turns at once, theta' = theta + turn (headings are kinematic:
        frictionless circles feel no torque), and gets the commanded velocity
        v* = speed (cos theta', sin theta'), which the contact solver then
        corrects. With ``velocity`` actuation v* is written as the body's
        velocity, and chipmunk, which integrates positions before velocities,
        moves the body by v* dt in this step. With ``force`` actuation the force
        F = m (v* - v) / dt is written instead; the body reaches v* at the end of
        this step and moves with it during the next one (one step of delay).
        Bodies switched off and trials that have ended are brought to rest.
        """
        physics = self.settings.physics
        col = self.spaces.drive_columns
        rows = self._rows
        drive = np.empty((rows.shape[0], WRITE_WIDTH))
        # The physics keeps the heading set here as the state's angle, so the
        # cosines and sines serve the next sensors too.
        _drive_rows(
            self.bodies.angle,
            np.asarray(speed, dtype=np.float64),
            np.asarray(turn, dtype=np.float64),
            self.bodies.enabled,
            self._running,
            physics.dt,
            self._turn_rate,
            self._cos,
            self._sin,
            drive,
            col.angle,
            col.angular_velocity,
            col.x,
            col.y,
        )
        if physics.actuation == "force":
            mass = self.spaces.masses / physics.dt
            drive[:, col.x] = (drive[:, col.x] - rows[:, 3]) * mass
            drive[:, col.y] = (drive[:, col.y] - rows[:, 4]) * mass
        return drive

    def _compact_if_worthwhile(self) -> None:
        """Drops the rows of trials that ended before the last step (those that
        ended at it stay for :meth:`state`) once they are worth dropping."""
        keep = self._running | self._took_step
        n_live = keep.shape[0]
        ended = n_live - int(keep.sum())
        if ended == 0 or ended < self.settings.compact_fraction * n_live:
            return
        rows = np.flatnonzero(keep)
        self.spaces.compact(keep)
        self.trials = self.trials.take(rows)
        body_rows = np.repeat(keep, self._n_bodies)
        self._rows = self._rows[body_rows]
        self._turn_rate = self._turn_rate[rows]
        self._cos = self._cos[rows]
        self._sin = self._sin[rows]
        self.bodies = self._body_views(
            self.bodies.enabled[rows], self.bodies.anchored[rows]
        )
        self._enabled = self._enabled[rows]
        self._anchored = self._anchored[rows]
        self._running = self._running[rows]
        self._took_step = self._took_step[rows]
        if self._networks is not None:
            self._networks.take(rows)

    def state(self) -> TaskState:
        """The task state of the whole batch after the last step.

        Arrays cover all B trials; ``active`` marks the trials that took the last
        step. Once finished trials have been dropped, the arrays are buffers the
        engine reuses at the next step: an observer that keeps them must copy.
        """
        groups = self.task.task_state(self.trials, self.bodies)
        active = np.zeros(self.n_trials, dtype=bool)
        live = self.live
        active[live[self._took_step]] = True
        if live.shape[0] == self.n_trials:
            return TaskState(step=self.step_count, active=active, groups=groups)
        return TaskState(
            step=self.step_count,
            active=active,
            groups=tuple(self._expand(i, g) for i, g in enumerate(groups)),
        )

    def _expand(self, index: int, group: GroupState) -> GroupState:
        """A group over the live rows spread over the whole batch (with a single
        live trial, shared arrays are spread too: only its row is read)."""
        n_live = self.live.shape[0]
        out = {}
        for j, name in enumerate(
            ("present", "attributes", "centres", "radii", "segments")
        ):
            a = getattr(group, name)
            if a is None or a.shape[0] != n_live:
                out[name] = a  # shared by every trial
                continue
            key = (index, j)
            buf = self._full.get(key)
            if buf is None or buf.shape[1:] != a.shape[1:]:
                buf = self._full[key] = np.zeros((self.n_trials, *a.shape[1:]), a.dtype)
            if a.flags.c_contiguous:
                # numpy's fancy assignment walked these small rows at several
                # times the cost of copying their bytes.
                _scatter_rows(_row_bytes(a), self.live, _row_bytes(buf))
            else:
                buf[self.live] = a
            out[name] = buf
        return GroupState(**out)


def _row_bytes(a: np.ndarray) -> np.ndarray:
    """A C-ordered array (rows, ...) as its rows' bytes (rows, row size)."""
    return a.reshape(a.shape[0], math.prod(a.shape[1:])).view(np.uint8)


@compiled("void(uint8[:, ::1], intp[::1], uint8[:, ::1])")
def _scatter_rows(
    src: np.ndarray, rows: np.ndarray, dst: np.ndarray
) -> None:  # pragma: no cover - compiled; tested against fancy assignment
    """``dst[rows[k]] = src[k]``, row by row, byte by byte."""
    for k in range(rows.shape[0]):
        row = rows[k]
        for j in range(src.shape[1]):
            dst[row, j] = src[k, j]


@compiled(
    "void(float64[:, :], float64[:, :], float64[:, :], boolean[:, :], boolean[::1], "
    "float64, float64[:, ::1], float64[:, ::1], float64[:, ::1], float64[:, ::1], "
    "intp, intp, intp, intp)"
)
def _drive_rows(
    angle: np.ndarray,
    speed: np.ndarray,
    turn: np.ndarray,
    enabled: np.ndarray,
    running: np.ndarray,
    dt: float,
    turn_rate: np.ndarray,
    cos_h: np.ndarray,
    sin_h: np.ndarray,
    drive: np.ndarray,
    col_angle: int,
    col_angular_velocity: int,
    col_x: int,
    col_y: int,
) -> None:  # pragma: no cover - compiled; tested against the numpy form
    """:meth:`BatchSimulation._drive` for bodies (B, R): with m = 1 for a body
    that is enabled in a running trial and 0 otherwise, the turn t m, the turn
    rate t m / dt, the heading h = angle + t m and its cosine and sine, and the
    drive row (h, 0, v cos h, v sin h) with v = speed m, the operations of the
    array form (``tests/sdbc_sim/test_engine.py``) in its order.

    Unlike most loops (:mod:`sdbc_sim.compiled` names the exceptions), this
    one takes its cosine and sine from the C library numba calls rather than from
    numpy: as whole arrays they were most of the drive's cost, and on the
    platforms we build for both call the same C library (glibc; the test compares
    them to the bit).
    Every path to a heading's cosine goes through here or :func:`_headings`
    (the first), so a trial alone, in a batch and live still agree whatever
    that library. A body that does not turn keeps the cosine and sine its
    heading has (in resource sharing most bodies at most steps: robots out of
    energy or stopped), so ``cos_h`` and ``sin_h`` must hold those of ``angle``
    on entry, as the engine keeps them.

    It runs in three passes over the bodies: the headings, then their cosines
    and sines, then the drive rows. The middle pass is the C library's call
    and little else, so few values stay live across it; as one pass the loop
    took 13-19 % longer per body (``docs/speed-history.md``)."""
    n_trials, n = angle.shape
    heading = np.empty(n_trials * n)
    velocity = np.empty(n_trials * n)
    turned = np.empty(n_trials * n, dtype=np.bool_)
    for t in range(n_trials):
        run = running[t]
        for i in range(n):
            m = 1.0 if enabled[t, i] and run else 0.0
            tm = turn[t, i] * m
            turn_rate[t, i] = tm / dt
            a = angle[t, i]
            row = t * n + i
            heading[row] = a + tm
            # Not turned: h is a to the bit (a nonzero plus a zero of either
            # sign), whose cosine and sine the arrays hold already.
            turned[row] = not (tm == 0.0 and abs(a) > 0.0)
            velocity[row] = speed[t, i] * m
    cos_rows = cos_h.reshape(-1)
    sin_rows = sin_h.reshape(-1)
    for row in range(n_trials * n):
        if turned[row]:
            h = heading[row]
            cos_rows[row] = math.cos(h)
            sin_rows[row] = math.sin(h)
    for row in range(n_trials * n):
        drive[row, col_angle] = heading[row]
        drive[row, col_angular_velocity] = 0.0
        drive[row, col_x] = velocity[row] * cos_rows[row]
        drive[row, col_y] = velocity[row] * sin_rows[row]


@dataclass
class BatchResult:
    """Results of :func:`run_batch`.

    Attributes:
        fitness: (G, T) fitness of every trial.
        characterisation: (G, T, C) task-specific characterisation, each in [0, 1].
        length: (G, T) steps each trial took.
        controller_fitness: (G,) harmonic (default) or arithmetic mean over trials.
        controller_characterisation: (G, C) arithmetic mean over trials.
    """

    fitness: np.ndarray
    characterisation: np.ndarray
    length: np.ndarray
    controller_fitness: np.ndarray
    controller_characterisation: np.ndarray


def run_batch(
    task: Task,
    genomes: np.ndarray,
    seeds: np.ndarray,
    observers: Sequence[Observer] = (),
    *,
    fitness_mean: str = "harmonic",
    settings: EngineSettings | None = None,
) -> BatchResult:
    """Evaluates every genome in its trials.

    Args:
        task: The task (e.g. ``GateEscape()`` or ``make_task("gate_escape")``).
        genomes: (G, W) float64 network weights, W = ``task.genome_length``.
        seeds: (G, T) int64, seed of genome g's t-th trial.
        observers: Called ``start(task.description, G * T)`` once, then
            ``observe(state)`` after every step, with the trials in row-major
            order (trial b = g T + t). Those that are
            :class:`~sdbc_sim.observer.NetworkObserver` s are also handed the
            network inputs and outputs at every step.
        fitness_mean: "harmonic" (the authors') or "arithmetic".
        settings: Engine settings.

    Returns:
        Per-trial and per-controller results.

    Raises:
        ValueError: On malformed genomes or seeds or an unknown fitness mean,
            before anything is simulated.
    """
    if fitness_mean not in FITNESS_MEANS:
        raise ValueError(
            f"unknown fitness mean {fitness_mean!r}; known: {', '.join(FITNESS_MEANS)}"
        )
    g = check_genomes(genomes, task.network)
    s = check_seeds(seeds, g.shape[0])
    n_genomes, n_trials = s.shape
    sim = BatchSimulation(task, s.reshape(-1), np.repeat(g, n_trials, axis=0), settings)
    for o in observers:
        o.start(task.description, sim.n_trials)
    sim.network_observers = [o for o in observers if isinstance(o, NetworkObserver)]
    while not sim.finished:
        sim.step()
        if observers:
            state = sim.state()
            for o in observers:
                o.observe(state)
    fitness = sim.fitness.reshape(n_genomes, n_trials)
    characterisation = sim.characterisation.reshape(n_genomes, n_trials, -1)
    return BatchResult(
        fitness=fitness,
        characterisation=characterisation,
        length=sim.length.reshape(n_genomes, n_trials),
        controller_fitness=controller_fitness(fitness, fitness_mean),
        controller_characterisation=characterisation.mean(axis=1),
    )


class TrialStepper:
    """One trial stepped from outside: the robots' network outputs come in at every
    step (the live ROS graph). Built on :class:`BatchSimulation` with one trial,
    so it matches :func:`run_batch` to the bit for the same outputs.

    Args:
        task: The task.
        settings: Engine settings.
    """

    def __init__(self, task: Task, settings: EngineSettings | None = None) -> None:
        self.task = task
        self.settings = settings
        self._sim: BatchSimulation | None = None

    def reset(self, seed: int) -> None:
        """Starts a new trial with initial conditions drawn from ``seed``."""
        self._sim = BatchSimulation(self.task, np.array([seed]), None, self.settings)

    @property
    def sim(self) -> BatchSimulation:
        """The underlying one-trial simulation."""
        if self._sim is None:
            raise RuntimeError("call reset(seed) first")
        return self._sim

    @property
    def done(self) -> bool:
        """True once the trial has ended."""
        return self.sim.finished

    @property
    def step_count(self) -> int:
        """Steps taken so far."""
        return self.sim.step_count

    def sensors(self) -> np.ndarray:
        """(n_controlled, n_inputs) the robots' network inputs."""
        return self.sim.sensors()[0]

    def step(self, outputs: np.ndarray) -> None:
        """Advances the trial by one step with (n_controlled, n_outputs) outputs."""
        self.sim.step(np.asarray(outputs, dtype=np.float64)[None])

    def state(self) -> TaskState:
        """The task state after the last step (a batch of one)."""
        return self.sim.state()

    def result(self) -> tuple[float, np.ndarray, int]:
        """(fitness, characterisation (C,), length) of the ended trial."""
        if not self.done:
            raise RuntimeError("result: the trial has not ended")
        sim = self.sim
        return float(sim.fitness[0]), sim.characterisation[0].copy(), int(sim.length[0])


@compiled("void(float64[:, :], float64[:, ::1], float64[:, ::1])")
def _headings(
    angle: np.ndarray, cos_h: np.ndarray, sin_h: np.ndarray
) -> None:  # pragma: no cover - compiled; tested against numpy's cos and sin
    """The cosines and sines of the bodies' first headings (B, R), from the C
    library :func:`_drive_rows` takes them from, which keeps them from then on."""
    for t in range(angle.shape[0]):
        for i in range(angle.shape[1]):
            cos_h[t, i] = math.cos(angle[t, i])
            sin_h[t, i] = math.sin(angle[t, i])
