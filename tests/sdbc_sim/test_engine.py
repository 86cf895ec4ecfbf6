"""run_batch, BatchSimulation and TrialStepper: results, observers, determinism."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from sdbc_sim.engine import (
    BatchSimulation,
    EngineSettings,
    TrialStepper,
    _row_bytes,
    _scatter_rows,
    controller_fitness,
)
from sdbc_sim.network import forward
from sdbc_sim.physics import MODELS, PhysicsSettings
from sdbc_sim.task_state import TaskDescription, TaskState
from sdbc_sim.tasks import make_task

from sdbc_sim import run_batch

CROWDED = {"arena_size": 60.0, "start_spacing": 6.0, "n_robots": 6, "max_steps": 150}
"""A gate escape arena small enough that robots meet each other and the walls."""


def model_settings(model: str, **physics: object) -> EngineSettings:
    """Engine settings with the physics ``model`` and other physics settings."""
    return EngineSettings(PhysicsSettings(model=model, **physics))  # type: ignore[arg-type]


class Trajectories:
    """Observer keeping the Agent centres, presence and the active flag of some
    trials at every step."""

    def __init__(self, trials: list[int]) -> None:
        self.trials = trials
        self.steps: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self.closest = np.inf

    def start(self, description: TaskDescription, n_trials: int) -> None:
        self.n_trials = n_trials

    def observe(self, state: TaskState) -> None:
        agents = state.groups[0]
        idx = self.trials
        self.steps.append(
            (agents.centres[idx].copy(), agents.present[idx].copy(), state.active[idx])
        )
        c = agents.centres[state.active]
        gap = np.linalg.norm(c[:, :, None] - c[:, None], axis=-1)
        gap[:, np.eye(c.shape[1], dtype=bool)] = np.inf
        self.closest = min(self.closest, float(gap.min(initial=np.inf)))

    def of(self, k: int) -> list[tuple[np.ndarray, ...]]:
        """The steps of the k-th watched trial while it was active."""
        return [(c[k], p[k]) for c, p, a in self.steps if a[k]]


def same(a: list[tuple[np.ndarray, ...]], b: list[tuple[np.ndarray, ...]]) -> bool:
    return len(a) == len(b) and all(
        np.array_equal(x, y)
        for u, v in zip(a, b, strict=True)
        for x, y in zip(u, v, strict=True)
    )


PHYSICS = {
    **{model: {"model": model} for model in MODELS},
    "rigid-small-cells": {"model": "rigid", "hash_cell": 8.0},
}
"""Physics the independence tests run under: every model with its defaults, and
the rigid model with cells barely larger than a robot (the default before
HASH_CELL_DIAMETERS), where a robot often covers several hash cells."""


@pytest.fixture(scope="module", params=sorted(PHYSICS))
def big_batch(request):
    """2000 trials (200 genomes x 10 seeds) of a crowded gate escape, with the
    trajectories of four of them, under each of ``PHYSICS``; the fixture gives
    the physics as keyword arguments of PhysicsSettings."""
    physics = PHYSICS[request.param]
    task = make_task("gate_escape", **CROWDED)
    rng = np.random.default_rng(42)
    genomes = rng.uniform(-1.0, 1.0, (200, task.genome_length))
    seeds = rng.integers(0, 2**40, (200, 10))
    picks = [(0, 0), (57, 3), (123, 9), (199, 9)]
    watch = Trajectories([g * 10 + t for g, t in picks])
    result = run_batch(
        task, genomes, seeds, [watch], settings=model_settings(**physics)
    )
    return physics, task, genomes, seeds, picks, watch, result


NEAR = {"rigid": 0.01, "kinematic": 1.0}
"""How near two robots of the crowded gate escape came to touching in a batch
that tests independence: the rigid model pushes them into contact; the kinematic
model refuses a move that would overlap, so they stop within a step (speed 1)."""


@pytest.mark.slow
def test_a_trial_alone_equals_it_in_a_batch_of_2000(big_batch) -> None:
    physics, task, genomes, seeds, picks, watch, result = big_batch
    # The batch is only a test of independence if robots did meet.
    assert watch.closest < 2 * task.config.robot_radius + NEAR[physics["model"]]
    assert len(set(result.length.ravel().tolist())) > 1
    for k, (g, t) in enumerate(picks):
        alone = Trajectories([0])
        r = run_batch(
            task,
            genomes[g : g + 1],
            seeds[g : g + 1, t : t + 1],
            [alone],
            settings=model_settings(**physics),
        )
        assert r.fitness[0, 0] == result.fitness[g, t]
        assert np.array_equal(r.characterisation[0, 0], result.characterisation[g, t])
        assert r.length[0, 0] == result.length[g, t]
        assert same(alone.of(0), watch.of(k))


@pytest.mark.slow
def test_another_slot_and_space_give_the_same_trial(big_batch) -> None:
    physics, task, genomes, seeds, picks, _, result = big_batch
    g, t = picks[1]
    rng = np.random.default_rng(3)
    others = rng.uniform(-1.0, 1.0, (30, task.genome_length))
    mixed_g = np.vstack([others[:17], genomes[g : g + 1], others[17:]])
    mixed_s = rng.integers(0, 2**40, (31, 3))
    mixed_s[17, 2] = seeds[g, t]
    r = run_batch(
        task, mixed_g, mixed_s, settings=model_settings(**physics, trials_per_space=8)
    )
    assert r.fitness[17, 2] == result.fitness[g, t]
    assert np.array_equal(r.characterisation[17, 2], result.characterisation[g, t])
    assert r.length[17, 2] == result.length[g, t]


@pytest.mark.slow
def test_another_process_gives_the_same_trial(big_batch, tmp_path) -> None:
    physics, task, genomes, seeds, picks, _, result = big_batch
    g, t = picks[2]
    genome_file = tmp_path / "genome.npy"
    np.save(genome_file, genomes[g])
    script = (
        "import numpy as np, sys\n"
        "from sdbc_sim import run_batch\n"
        "from sdbc_sim.engine import EngineSettings\n"
        "from sdbc_sim.physics import PhysicsSettings\n"
        "from sdbc_sim.tasks import make_task\n"
        f"task = make_task('gate_escape', **{CROWDED!r})\n"
        "g = np.load(sys.argv[1])[None]\n"
        f"settings = EngineSettings(PhysicsSettings(**{physics!r}))\n"
        f"r = run_batch(task, g, np.array([[{int(seeds[g, t])}]]), settings=settings)\n"
        "print(r.fitness[0, 0].hex(), r.length[0, 0],"
        " *[v.hex() for v in r.characterisation[0, 0]])\n"
    )
    src = Path(__file__).resolve().parents[2] / "src" / "sdbc_sim"
    out = subprocess.run(
        [sys.executable, "-c", script, str(genome_file)],
        capture_output=True,
        text=True,
        check=True,
        env={"PYTHONPATH": str(src), "PATH": ""},
    ).stdout.split()
    assert float.fromhex(out[0]) == result.fitness[g, t]
    assert int(out[1]) == result.length[g, t]
    assert [float.fromhex(v) for v in out[2:]] == result.characterisation[g, t].tolist()


@pytest.mark.parametrize("model", MODELS)
def test_dropping_finished_trials_changes_nothing(model: str) -> None:
    task = make_task("gate_escape", **CROWDED)
    rng = np.random.default_rng(5)
    genomes = rng.uniform(-1.0, 1.0, (12, task.genome_length))
    seeds = rng.integers(0, 2**40, (12, 5))
    physics = PhysicsSettings(model=model)  # type: ignore[arg-type]
    results = [
        run_batch(
            task,
            genomes,
            seeds,
            settings=EngineSettings(physics=physics, compact_fraction=f),
        )
        for f in (0.01, 1.0)
    ]
    assert len(set(results[0].length.ravel().tolist())) > 1
    for name in ("fitness", "characterisation", "length"):
        assert np.array_equal(getattr(results[0], name), getattr(results[1], name))


@pytest.mark.parametrize("model", MODELS)
def test_live_stepper_matches_the_batch(model: str) -> None:
    task = make_task("gate_escape", **CROWDED)
    rng = np.random.default_rng(9)
    genome = rng.uniform(-1.0, 1.0, task.genome_length)
    batch = Trajectories([0])
    settings = model_settings(model)
    r = run_batch(task, genome[None], np.array([[77]]), [batch], settings=settings)
    stepper = TrialStepper(task, settings)
    stepper.reset(77)
    live = []
    while not stepper.done:
        stepper.step(forward(genome, task.network, stepper.sensors()))
        agents = stepper.state().groups[0]
        live.append((agents.centres[0].copy(), agents.present[0].copy()))
    fitness, characterisation, length = stepper.result()
    assert fitness == r.fitness[0, 0] and length == r.length[0, 0]
    assert np.array_equal(characterisation, r.characterisation[0, 0])
    assert same(live, batch.of(0))


class Recorder:
    def start(self, description: TaskDescription, n_trials: int) -> None:
        self.description, self.n_trials = description, n_trials
        self.steps: list[int] = []
        self.active: list[int] = []

    def observe(self, state: TaskState) -> None:
        self.steps.append(state.step)
        self.active.append(int(state.active.sum()))
        for group in state.groups:
            assert group.present.shape[0] in (1, self.n_trials)
            assert group.attributes.shape[0] in (1, self.n_trials)


def test_observers_see_every_step_of_the_whole_batch() -> None:
    task = make_task("gate_escape", **CROWDED)
    rng = np.random.default_rng(11)
    genomes = rng.uniform(-1.0, 1.0, (20, task.genome_length))
    seeds = rng.integers(0, 2**40, (20, 4))
    rec = Recorder()
    r = run_batch(task, genomes, seeds, [rec])
    assert rec.description is task.description and rec.n_trials == 80
    assert rec.steps == list(range(1, int(r.length.max()) + 1))
    expected = [(r.length >= k).sum() for k in rec.steps]
    assert rec.active == expected


def test_controller_aggregates() -> None:
    f = np.array([[0.5, 0.25], [0.0, 1.0]])
    np.testing.assert_allclose(
        controller_fitness(f), [1 / 3, 2 / (1e4 + 1)], rtol=1e-15
    )
    np.testing.assert_allclose(controller_fitness(f, "arithmetic"), [0.375, 0.5])
    task = make_task("gate_escape", max_steps=20)
    genomes = np.random.default_rng(0).uniform(-1, 1, (3, task.genome_length))
    seeds = np.arange(6).reshape(3, 2)
    h = run_batch(task, genomes, seeds)
    a = run_batch(task, genomes, seeds, fitness_mean="arithmetic")
    np.testing.assert_allclose(h.controller_fitness, controller_fitness(h.fitness))
    np.testing.assert_allclose(a.controller_fitness, h.fitness.mean(axis=1))
    np.testing.assert_allclose(
        h.controller_characterisation, h.characterisation.mean(axis=1)
    )
    assert h.characterisation.shape == (3, 2, 4)
    assert np.all((h.characterisation >= 0) & (h.characterisation <= 1))


@pytest.mark.parametrize(
    ("genomes", "seeds", "message"),
    [
        (np.zeros((2, 107)), np.zeros((2, 1), int), "length 107 .* needs 108"),
        (np.full((2, 108), np.nan), np.zeros((2, 1), int), "NaN or infinite"),
        (np.full((1, 108), np.inf), np.zeros((1, 1), int), "NaN or infinite"),
        (np.zeros(108), np.zeros((1, 1), int), "expected a \\(G, W\\) array"),
        (np.zeros((2, 108)), np.zeros((3, 1), int), "3 rows for 2 genomes"),
        (np.zeros((2, 108)), np.full((2, 1), -1), "non-negative"),
        (np.zeros((2, 108)), np.zeros((2, 1)), "expected integers"),
        (np.zeros((2, 108)), np.zeros(2, int), "\\(G, T\\)"),
    ],
)
def test_bad_input_is_named_before_anything_runs(genomes, seeds, message) -> None:
    task = make_task("gate_escape")

    def no_reset(rngs):
        raise AssertionError("simulation started")

    task.reset = no_reset  # type: ignore[method-assign]
    with pytest.raises(ValueError, match=message):
        run_batch(task, genomes, seeds)


def test_unknown_fitness_mean_and_bad_outputs() -> None:
    task = make_task("gate_escape")
    with pytest.raises(ValueError, match="unknown fitness mean 'median'"):
        run_batch(
            task, np.zeros((1, 108)), np.zeros((1, 1), int), fitness_mean="median"
        )
    stepper = TrialStepper(task)
    stepper.reset(0)
    with pytest.raises(ValueError, match="outputs have shape"):
        stepper.step(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="must lie in \\[0, 1\\]"):
        stepper.step(np.full((4, 3), np.nan))
    with pytest.raises(RuntimeError, match="has not ended"):
        stepper.result()
    sim = BatchSimulation(task, np.array([0]))
    with pytest.raises(ValueError, match="no genomes; pass outputs"):
        sim.step()


def test_state_after_all_but_one_trial_ended(placed) -> None:
    start = [[10.0, 100.0], [150.0, 20.0], [150.0, 60.0], [150.0, 180.0]]
    task = placed(make_task("gate_escape", max_steps=120), start, [np.pi, 0, 0, 0])
    sim = BatchSimulation(
        task, np.array([0, 1]), settings=EngineSettings(compact_fraction=0.1)
    )
    out = np.zeros((2, 4, 3))
    out[..., 1] = 0.5
    out[..., 2] = 1.0
    # Trial 0's robot 0 moves 1 per step from x = 10 in the step it is commanded:
    # x_k = 10 - k, so x_11 = -1 < 0 is its escape, and the gate closes 75 steps
    # later, at 86, which ends the trial.
    out[0, 0] = [1.0, 0.5, 0.0]
    while not sim.finished:
        sim.step(out[sim.live])
        state = sim.state()
        agents = state.groups[0]
        if sim.step_count == 100:
            assert sim.live.tolist() == [1] and state.active.tolist() == [False, True]
            np.testing.assert_array_equal(agents.centres[1], np.array(start))
            assert agents.present[1].all() and agents.radii[1].tolist() == [2.5] * 4
    assert sim.length.tolist() == [86, 120]


def array_drive(
    sim: BatchSimulation, speed: np.ndarray, turn: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """BatchSimulation._drive as whole numpy arrays, with numpy's cosine and sine:
    the form the compiled loop replaced, kept as its oracle. Returns the drive
    rows, the turn rates and the cosines and sines of the new headings."""
    physics = sim.settings.physics
    col = sim.spaces.drive_columns
    moving = sim.bodies.enabled & sim._running[:, None]
    turn = turn * moving
    heading = sim.bodies.angle + turn
    cos, sin = np.cos(heading), np.sin(heading)
    v = (speed * moving).reshape(-1)
    drive = np.empty((v.shape[0], 4))
    drive[:, col.angle] = heading.reshape(-1)
    drive[:, col.angular_velocity] = 0.0
    drive[:, col.x] = v * cos.reshape(-1)
    drive[:, col.y] = v * sin.reshape(-1)
    if physics.actuation == "force":
        mass = sim.spaces.masses / physics.dt
        drive[:, col.x] = (v * cos.reshape(-1) - sim._rows[:, 3]) * mass
        drive[:, col.y] = (v * sin.reshape(-1) - sim._rows[:, 4]) * mass
    return drive, turn / physics.dt, cos, sin


@pytest.mark.parametrize("actuation", ["velocity", "force"])
def test_compiled_drive_equals_the_array_formulation(actuation: str) -> None:
    """To the bit (signs of zeros included), after some steps of a crowded gate
    escape, with headings far from zero (cosines and sines taken after a long
    argument reduction), bodies switched off and trials ended: their turns, of
    either sign, become zeros."""
    task = make_task("gate_escape", **CROWDED)
    rng = np.random.default_rng(5)
    b = 40
    genomes = rng.uniform(-1.0, 1.0, (b, task.genome_length))
    settings = model_settings("rigid", actuation=actuation)
    sim = BatchSimulation(task, rng.integers(0, 2**31 - 1, b), genomes, settings)
    for _ in range(5):
        sim.step()
    shape = sim.bodies.angle.shape
    sim.bodies.angle[:] = rng.uniform(-2000.0, 2000.0, shape)
    # Headings of zero of either sign in trials that have ended: their turn is
    # a zero, which changes the sign of -0.0, so the kept sines must not serve.
    sim.bodies.angle[0] = -0.0
    sim.bodies.angle[1] = 0.0
    # The engine keeps the cosines and sines of the headings it holds.
    sim._cos[:] = np.cos(sim.bodies.angle)
    sim._sin[:] = np.sin(sim.bodies.angle)
    sim.bodies.enabled[:] = rng.random(shape) < 0.8
    sim._running[: b // 4] = False
    speed = rng.uniform(0.0, 2.0, shape)
    turn = rng.uniform(-0.5, 0.5, shape)
    want = array_drive(sim, speed, turn)
    got = (sim._drive(speed, turn), sim._turn_rate, sim._cos, sim._sin)
    for g, w in zip(got, want, strict=True):
        np.testing.assert_array_equal(g.view(np.int64), w.view(np.int64))
    assert (want[1] == 0.0).any() and np.signbit(want[1][want[1] == 0.0]).any()


@pytest.mark.parametrize("model", ["rigid", "kinematic"])
def test_the_first_headings_cosines_and_sines_are_numpys(model: str) -> None:
    """The engine takes its first headings' cosines and sines in a compiled
    loop from the C library numpy's float64 ``cos`` and ``sin`` call here; a
    body that never turns keeps them, so they must be those bits."""
    task = make_task("gate_escape", **CROWDED)
    sim = BatchSimulation(task, np.arange(50), settings=model_settings(model))
    for got, want in (
        (sim._cos, np.cos(sim.bodies.angle)),
        (sim._sin, np.sin(sim.bodies.angle)),
    ):
        assert np.array_equal(got.view(np.int64), want.view(np.int64))


def test_compiled_kinematics_equal_the_array_formulation() -> None:
    """BodyState.kinematics to the bit against its array form (numpy's hypot)
    on the engine's strided state views, with velocities at random and over many
    scales, zeros of both signs, subnormals, infinities and NaN."""
    task = make_task("gate_escape", **CROWDED)
    rng = np.random.default_rng(9)
    b = 30
    genomes = rng.uniform(-1.0, 1.0, (b, task.genome_length))
    sim = BatchSimulation(task, rng.integers(0, 2**31 - 1, b), genomes)
    sim.step()
    bodies = sim.bodies
    shape = bodies.velocity.shape
    v = rng.normal(0.0, 1.0, shape) * 10.0 ** rng.integers(-300, 300, shape)
    special = np.array([0.0, -0.0, 5e-324, -1e-310, np.inf, -np.inf, np.nan, 1.0])
    v.reshape(-1)[: 4 * special.size] = np.repeat(special, 4)
    v.reshape(-1)[1 : 4 * special.size : 2] = np.tile(special, 2)
    bodies.velocity[:] = v
    bodies.angular_velocity[:] = rng.normal(0.0, 1.0, shape[:2])
    got = bodies.kinematics(2)
    want = np.empty_like(got)
    want[..., 0:2] = bodies.position
    want[..., 2] = bodies.angular_velocity
    want[..., 3] = np.hypot(bodies.velocity[..., 0], bodies.velocity[..., 1])
    np.testing.assert_array_equal(
        got[..., :4].view(np.int64), want[..., :4].view(np.int64)
    )
    assert np.isinf(want[..., 3]).any() and np.isnan(want[..., 3]).any()


@pytest.mark.parametrize("name", ["gate_escape", "resource_sharing", "foraging"])
def test_trial_b_starts_from_default_rng_of_its_seed(name: str) -> None:
    """The engine builds each trial's generator as Generator(PCG64(seed)), what
    numpy documents ``default_rng(seed)`` to be; the starts are those."""
    task = make_task(name)
    seeds = np.array([0, 7, 2**31 - 2, 123456789])
    sim = BatchSimulation(task, seeds, settings=model_settings("kinematic"))
    _, position, angle = task.reset([np.random.default_rng(int(s)) for s in seeds])
    assert np.array_equal(sim.bodies.position, position)
    assert np.array_equal(sim.bodies.angle, angle)


@pytest.mark.parametrize("shape", [(7,), (7, 3), (7, 3, 6), (7, 3, 0), (7, 1, 2)])
@pytest.mark.parametrize("dtype", [np.bool_, np.float64, np.int64])
def test_rows_spread_over_the_batch_as_fancy_assignment_spreads_them(
    shape: tuple[int, ...], dtype: type
) -> None:
    """The live trials' rows of a group, copied byte by byte into the whole
    batch's buffer, as ``buf[live] = a`` would; NaN payloads kept."""
    rng = np.random.default_rng(1)
    a = rng.integers(-(2**62), 2**62, size=shape).astype(dtype)
    if dtype is np.float64:
        # NaNs with payloads, which an arithmetic copy could change.
        a.view(np.int64).reshape(-1)[::3] = 0x7FF8_0000_0000_0001
    live = np.array([0, 2, 3, 5, 8, 9, 11])
    want = np.zeros((12, *shape[1:]), dtype)
    got = want.copy()
    want[live] = a
    _scatter_rows(_row_bytes(a), live, _row_bytes(got))
    assert np.array_equal(got.view(np.uint8), want.view(np.uint8))
