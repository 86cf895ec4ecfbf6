"""Gate escape rules, sensors and results against hand-computed numbers.

A body moves in the step it is commanded (velocity actuation): a robot that drives
at speed 1 from x0 straight at the gate is at x_k = x0 - k after step k.
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from sdbc_sim.engine import TrialStepper
from sdbc_sim.sensors import bearing, norm, normalised_reading, robot_sum
from sdbc_sim.task import BodyState
from sdbc_sim.tasks import make_task
from sdbc_sim.tasks.gate_escape import (
    GateEscape,
    GateEscapeConfig,
    GateEscapeTrials,
    _ring_starts,
)
from trial_oracle import assert_same_trials

from sdbc_sim import compiled

PARKED = [[150.0, 20.0], [150.0, 60.0], [150.0, 180.0]]
"""Where the robots that stay still wait in the hand-written runs."""


def drive(task: GateEscape, speeds: list[float], seed: int = 0):
    """Runs one trial with constant outputs: robot i at speed ``speeds[i]``
    (0 = the stop output), straight ahead. Returns the stepper and the task
    states of every step."""
    stepper = TrialStepper(task)
    stepper.reset(seed)
    out = np.zeros((len(speeds), 3))
    out[:, 0] = speeds
    out[:, 1] = 0.5
    out[:, 2] = [0.0 if s > 0 else 1.0 for s in speeds]
    states = []
    while not stepper.done:
        stepper.step(out)
        states.append(stepper.state())
    return stepper, states


def expected_characterisation(xs0: np.ndarray, others: np.ndarray, length: int):
    """Mean gate distance and dispersion of a run where robot 0 moves along
    y = 100 with positions ``xs0`` per step and the others stay at ``others``."""
    gate = np.array([0.0, 100.0])
    gd = dispersion = 0.0
    for x in xs0[:length]:
        pos = np.vstack([[x, 100.0], others])
        gd += np.linalg.norm(pos - gate, axis=1).mean()
        dispersion += np.linalg.norm(pos - pos.mean(axis=0), axis=1).mean()
    return gd / length / 200.0, dispersion / length / 100.0


def test_robot_through_gate_escapes_and_gate_closes_75_steps_later(placed) -> None:
    task = placed(GateEscape(), [[10.0, 100.0], *PARKED], [math.pi, 0.0, 0.0, 0.0])
    stepper, states = drive(task, [1.0, 0.0, 0.0, 0.0])
    # The move commanded at step k happens during step k: x_k = 10 - k, so
    # x_10 = 0 is still inside (escape is x < 0) and x_11 = -1 is the escape; the
    # gate then closes at 11 + 75 = 86, which ends the trial.
    fitness, characterisation, length = stepper.result()
    assert length == 86
    assert fitness == pytest.approx((1 + 86 / 1000) / 5, abs=1e-15)
    # Robot 0 is at 9, 8, ..., -1 after steps 1..11, then held where it left.
    xs0 = np.concatenate([9.0 - np.arange(11), np.full(75, -1.0)])
    gd, dispersion = expected_characterisation(xs0, np.array(PARKED), 86)
    np.testing.assert_allclose(
        characterisation, [0.25, 11 / 1000, gd, dispersion], rtol=0, atol=1e-12
    )
    agent = [s.groups[0] for s in states]
    gate = [s.groups[1] for s in states]
    # states[k - 1] is the state after step k: present after step 10, gone and
    # the gate closing after step 11.
    assert [bool(a.present[0, 0]) for a in agent[9:11]] == [True, False]
    assert [float(g.attributes[0, 0, 0]) for g in gate[9:11]] == [0.0, 1.0]
    # Passing the gate: centre within one radius (2.5) of the gate line; after
    # steps 6..10 robot 0 is at x = 4, 3, 2, 1, 0.
    assert [float(a.attributes[0, 0, 4]) for a in agent[5:10]] == [0, 0, 1, 1, 1]
    # It moves at speed 1 from step 1 on.
    assert agent[0].attributes[0, 0, 3] == pytest.approx(1.0, abs=1e-12)
    assert all(s.active[0] for s in states)


def test_trial_ends_when_no_robot_is_left_inside(placed) -> None:
    start = [[10.0, 100.0], [20.0, 100.0], [30.0, 100.0], [40.0, 100.0]]
    task = placed(GateEscape(), start, [math.pi] * 4)
    stepper, states = drive(task, [1.0] * 4)
    # Robot i is at x0 - k after step k and escapes when x0 - k = -1 < 0, at step
    # x0 + 1: 11, 21, 31, 41; following robots pass through the escaped ones,
    # which no longer collide. The last escape ends the trial at 41; the gate
    # opened at 11.
    fitness, characterisation, length = stepper.result()
    assert length == 41
    assert fitness == pytest.approx((4 + 41 / 1000) / 5, abs=1e-15)
    assert characterisation[0] == 1.0
    assert characterisation[1] == pytest.approx(11 / 1000, abs=1e-15)
    # states[k - 1]: 4 inside after step 10, 3 after 11; 3 after 20, 2 after 21.
    sizes = [int(s.groups[0].present[0].sum()) for s in states]
    assert sizes[9:11] == [4, 3] and sizes[19:21] == [3, 2] and sizes[-1] == 0


def test_nobody_moves_until_max_steps(placed) -> None:
    start = [[60.0, 100.0], *PARKED]
    task = placed(make_task("gate_escape", max_steps=30), start, [0.0] * 4)
    stepper, _ = drive(task, [0.0] * 4)
    fitness, characterisation, length = stepper.result()
    assert length == 30
    assert fitness == pytest.approx((0 + 30 / 30) / 5, abs=1e-15)
    gd, dispersion = expected_characterisation(np.full(30, 60.0), np.array(PARKED), 30)
    np.testing.assert_allclose(characterisation, [0, 1, gd, dispersion], atol=1e-12)


def test_mase_fitness_option(placed) -> None:
    task = placed(
        make_task("gate_escape", fitness="mase"),
        [[10.0, 100.0], *PARKED],
        [math.pi, 0.0, 0.0, 0.0],
    )
    stepper, _ = drive(task, [1.0, 0.0, 0.0, 0.0])
    fitness, _, _ = stepper.result()
    # One of 4 escaped, the first (and only) escape at step 11 (x_11 = 10 - 11).
    assert fitness == pytest.approx(0.8 * 1 / 4 + 0.2 * (1 - 11 / 1000), abs=1e-15)


def test_gate_closing_steps_setting(placed) -> None:
    task = placed(
        make_task("gate_escape", gate_closing_steps=10),
        [[10.0, 100.0], *PARKED],
        [math.pi, 0.0, 0.0, 0.0],
    )
    stepper, _ = drive(task, [1.0, 0.0, 0.0, 0.0])
    # Escape at step 11 (x_11 = 10 - 11 < 0); closed 10 steps later.
    assert stepper.result()[2] == 21


def test_sensors_by_hand(placed) -> None:
    start = [[30.0, 100.0], [30.0, 120.0], [10.0, 100.0], [5.0, 150.0]]
    task = placed(GateEscape(), start, [math.pi / 2, 0.0, 0.0, math.pi])
    stepper = TrialStepper(task)
    stepper.reset(0)
    x = stepper.sensors()
    assert x.shape == (4, 11)
    # Robot 0 faces +y: gate 30 away on its left; robots 1 (ahead) and 2 (left)
    # 15 away edge to edge; robot 3 out of range; no wall within ray reach.
    np.testing.assert_allclose(
        x[0], [0.2, 0.5, 1 / 3, 1, 1, 0.2, 0.2, 1, 1, 1, 1], atol=1e-12
    )
    # Robot 3 faces the left wall 5 away: rays at heading -+45 degrees start at
    # its edge and cross x = 0 after 5 sqrt(2) - 2.5; the gate is 50.25 away.
    ray = 2 * (5 * math.sqrt(2) - 2.5) / 5 - 1
    np.testing.assert_allclose(x[3, [0, 1, 2]], [1, 0, -1], atol=1e-12)
    np.testing.assert_allclose(x[3, 7:], [ray, ray, 1, 1], atol=1e-12)


def test_random_starts_are_valid_rings() -> None:
    task = GateEscape()
    c = task.config
    trials, position, angle = task.reset([np.random.default_rng(s) for s in range(200)])
    rings = np.linalg.norm(position - task.gate_centre, axis=-1)
    np.testing.assert_allclose(
        rings, np.tile([49.375, 98.75, 148.125, 197.5], (200, 1))
    )
    r = c.robot_radius
    assert np.all((position >= r) & (position <= c.arena_size - r))
    assert np.all((angle >= -np.pi) & (angle < np.pi))
    gaps = np.linalg.norm(position[:, :, None] - position[:, None], axis=-1)
    assert np.all(gaps[:, ~np.eye(4, dtype=bool)] >= 2 * r)
    assert not trials.escaped.any() and np.all(trials.open_step == -1)


@pytest.mark.parametrize("bulk", [False, True])
def test_starts_are_numpys_uniform_draws(
    bulk: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """reset draws each robot's ring angle until it fits, then its heading, one
    by one or, once the loops are loaded, in bulk; either way its starts, and
    the stream it leaves (a buffered half-word included), are those of
    ``rng.uniform`` drawn angle by angle."""
    if bulk:
        compiled.load()
    monkeypatch.setattr(compiled, "loaded", lambda: bulk)
    task = GateEscape(GateEscapeConfig(robot_radius=12.0, start_spacing=24.0))
    c = task.config
    r, s = c.robot_radius, c.arena_size
    gx, gy = task.gate_centre.tolist()

    def with_uniform(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        position, heading = np.empty((c.n_robots, 2)), np.empty(c.n_robots)
        for i in range(c.n_robots):
            ring = (i + 1) * c.start_spacing
            while True:
                a = rng.uniform(0.0, 2.0 * math.pi)
                p = (gx + ring * math.cos(a), gy + ring * math.sin(a))
                inside = all(r <= v <= s - r for v in p)
                if inside and all(
                    math.dist(q, p) >= 2.0 * r for q in position[:i].tolist()
                ):
                    break
            position[i], heading[i] = p, rng.uniform(-np.pi, np.pi)
        return position, heading

    seeds = range(400)
    want_rngs = [np.random.default_rng(seed) for seed in seeds]
    got_rngs = [np.random.default_rng(seed) for seed in seeds]
    for rngs in (want_rngs, got_rngs):
        for rng in rngs[1::2]:
            # Leaves half of a 64-bit word buffered for the next 32-bit draw.
            rng.integers(2**32, dtype=np.uint32)
    want = [with_uniform(rng) for rng in want_rngs]
    _, position, heading = task.reset(got_rngs)
    for t, (want_position, want_heading) in enumerate(want):
        assert np.array_equal(position[t].view(np.int64), want_position.view(np.int64))
        assert np.array_equal(heading[t].view(np.int64), want_heading.view(np.int64))
    for got_rng, want_rng in zip(got_rngs, want_rngs, strict=True):
        assert got_rng.integers(2**32, dtype=np.uint32) == want_rng.integers(
            2**32, dtype=np.uint32
        )
        assert got_rng.random() == want_rng.random()


def test_bulk_starts_leave_close_calls_and_short_draws_to_the_caller() -> None:
    """The bulk loop refuses to decide a distance within a relative 1e-9 of the
    diameter (the C library's hypot and math.dist may round it apart) and says
    when it runs out of doubles; reset then draws one by one."""
    position, heading = np.empty((2, 2)), np.empty(2)
    # Both robots at angle 0 from the gate (0, 100) on rings 10 apart: their
    # centres lie exactly a diameter apart.
    u = np.array([0.0, 0.5, 0.0, 0.5])
    assert _ring_starts(u, 0.0, 100.0, 10.0, 5.0, 200.0, position, heading) == -2
    # Radius 4: apart; four doubles used.
    assert _ring_starts(u, 0.0, 100.0, 10.0, 4.0, 200.0, position, heading) == 4
    assert position.tolist() == [[10.0, 100.0], [20.0, 100.0]]
    assert heading.tolist() == [0.0, 0.0]
    assert _ring_starts(u[:3], 0.0, 100.0, 10.0, 4.0, 200.0, position, heading) == -1
    # Angle 0.5 (pi) lies outside the arena (x < 0): drawn again.
    u = np.array([0.5, 0.0, 0.5, 0.5, 0.0, 0.5])
    assert _ring_starts(u, 0.0, 100.0, 10.0, 4.0, 200.0, position, heading) == 6


def test_same_seed_same_start() -> None:
    task = GateEscape()
    a = task.reset([np.random.default_rng(7)])
    b = task.reset([np.random.default_rng(7)])
    np.testing.assert_array_equal(a[1], b[1])
    np.testing.assert_array_equal(a[2], b[2])


def count_sdbc_features(task: GateEscape) -> int:
    """Features per docs/method.md's rules, from the task description alone."""
    groups = task.description.groups
    n = 0
    for i, g in enumerate(groups):
        n += (g.max_size > g.min_size) + len(g.attributes)
        n += (not g.is_static) and g.max_size > 1
        n += sum(not (g.is_static and h.is_static) for h in groups[i + 1 :])
    return n


def test_description_gives_the_papers_21_dimensions() -> None:
    task = GateEscape()
    d = task.description
    assert [g.name for g in d.groups] == ["Agent", "Gate", "Wall"]
    assert d.group("Agent").attributes == (
        "x",
        "y",
        "turning speed",
        "linear speed",
        "is passing gate",
    )
    assert count_sdbc_features(task) == 10
    assert 2 * count_sdbc_features(task) + 1 == 21
    assert task.genome_length == 108


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"robot_radius": -1.0}, "robot_radius: Input should be greater than 0"),
        ({"arena_size": 100.0}, "too small for its robots"),
        ({"gate_width": 4.0}, "gate_width"),
        ({"max_speed": 3.0}, "pass through walls"),
        ({"fitness": "best"}, "fitness: Input should be 'paper' or 'mase', got 'best'"),
        ({"n_robots": 0}, "n_robots: Input should be greater than or equal to 1"),
        ({"max_steps": 0}, "max_steps: Input should be greater than or equal to 1"),
        ({"stop_threshold": float("nan")}, "stop_threshold: .* finite number"),
    ],
)
def test_bad_settings_are_named(overrides: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        GateEscapeConfig(**overrides)


def test_registry_names_unknown_tasks_and_settings() -> None:
    with pytest.raises(ValueError, match="unknown task 'gate'.*gate_escape"):
        make_task("gate")
    with pytest.raises(ValueError, match="radius: unknown key"):
        make_task("gate_escape", radius=3.0)
    with pytest.raises(
        ValueError, match="robot_radius: Input should be greater than 0"
    ):
        make_task("gate_escape", robot_radius=-2.5)


class ArrayGateEscape(GateEscape):
    """The task with its gate sensor and rules as whole-array numpy: the
    formulation the compiled loops replaced, kept as their oracle."""

    def sensors(self, trials: GateEscapeTrials, bodies: BodyState) -> np.ndarray:
        out = super().sensors(trials, bodies)
        c = self.config
        pos = bodies.position
        cos_h, sin_h = bodies.cos_angle, bodies.sin_angle
        gx = self.gate_centre[0] - pos[..., 0]
        gy = self.gate_centre[1] - pos[..., 1]
        gd = norm(gx, gy)
        seen = gd <= c.gate_sensor_range
        out[..., 0] = np.where(seen, normalised_reading(gd, c.gate_sensor_range), 1.0)
        out[..., 1] = 0.0
        if seen.any():
            out[seen, 1] = bearing(gx[seen], gy[seen], cos_h[seen], sin_h[seen]) / np.pi
        return out

    def update(
        self, trials: GateEscapeTrials, bodies: BodyState, step: int
    ) -> np.ndarray:
        c = self.config
        pos = bodies.position
        crossed = bodies.enabled & (pos[..., 0] < 0.0)
        if crossed.any():
            trials.escaped |= crossed
            bodies.enabled &= ~crossed
            opens = crossed.any(axis=1) & (trials.open_step < 0)
            trials.open_step[opens] = step
        x, y = pos[..., 0], pos[..., 1]
        n = c.n_robots
        gd = norm(x - self.gate_centre[0], y - self.gate_centre[1])
        trials.gate_distance_sum += robot_sum(gd) / n
        cx = robot_sum(x) / n
        cy = robot_sum(y) / n
        trials.dispersion_sum += robot_sum(norm(x - cx[:, None], y - cy[:, None])) / n
        closed = (trials.open_step >= 0) & (
            step - trials.open_step >= c.gate_closing_steps
        )
        return closed | trials.escaped.all(axis=1)


def test_compiled_sensor_and_rules_equal_the_array_formulation() -> None:
    """To the bit, over steps of many trials: the gate sensor (robots exactly at
    its range, in and out of it), escapes (robots exactly on the gate line stay
    in), the gate opening at the first and closing gate_closing_steps later,
    robots already out, every robot out, and the distance sums."""
    task = make_task("gate_escape", gate_closing_steps=3)
    oracle = ArrayGateEscape(GateEscapeConfig(gate_closing_steps=3))
    n_trials, n = 150, task.config.n_robots
    rng = np.random.default_rng(4)
    got, _, _ = task.reset([np.random.default_rng(t) for t in range(n_trials)])
    got.open_step[: n_trials // 3] = rng.integers(1, 4, n_trials // 3)
    got.escaped[: n_trials // 3] = rng.random((n_trials // 3, n)) < 0.5
    got.escaped[0] = True
    want = copy.deepcopy(got)
    rows = np.zeros((n_trials, n, 5))
    got_bodies = BodyState.at_rest(rows[..., 0:2], np.zeros((n_trials, n)))
    got_bodies.enabled[:] = ~got.escaped
    want_bodies = copy.deepcopy(got_bodies)
    reach = task.config.gate_sensor_range
    for step in range(4, 9):
        xy = np.stack(
            [
                rng.choice([-1.5, -0.0, 0.0, 0.5, 40.0, reach], (n_trials, n)),
                rng.choice([80.0, 100.0, 100.0 + reach, 117.3], (n_trials, n)),
            ],
            axis=-1,
        )
        got_bodies.position[:] = xy
        want_bodies.position[:] = xy
        heading = rng.uniform(-math.pi, math.pi, (n_trials, n))
        for bodies in (got_bodies, want_bodies):
            bodies.cos_angle[:] = np.cos(heading)
            bodies.sin_angle[:] = np.sin(heading)
        np.testing.assert_array_equal(
            task.sensors(got, got_bodies), oracle.sensors(want, want_bodies)
        )
        np.testing.assert_array_equal(
            task.update(got, got_bodies, step), oracle.update(want, want_bodies, step)
        )
        assert_same_trials(got, want)
        np.testing.assert_array_equal(got_bodies.enabled, want_bodies.enabled)
    assert got.escaped.all(axis=1).any() and not got.escaped.all()
    assert (got.open_step >= 0).any() and (got.open_step < 0).any()


def test_compiled_agent_attributes_equal_the_array_formulation() -> None:
    """The Agent group's attributes and centres in one pass: the kinematics,
    then "is passing gate" by the array form's comparisons, NaN and the gate's
    edges included; the centres are the positions to the bit."""
    task = GateEscape()
    rng = np.random.default_rng(3)
    b, n = 50, task.config.n_robots
    r = task.config.robot_radius
    position = rng.uniform(-2.0 * r, 200.0, (b, n, 2))
    position[:10, :, 0] = rng.uniform(-r, r, (10, n))
    position[10:20, :, 1] = rng.uniform(
        task.gate_low - 1.0, task.gate_high + 1.0, (10, n)
    )
    position[0, 0] = (r, task.gate_low)
    position[0, 1] = (-r, task.gate_high)
    position[0, 2] = (r, np.nan)
    position[1, 0] = (0.0, (task.gate_low + task.gate_high) / 2.0)
    bodies = BodyState.at_rest(position, rng.uniform(-np.pi, np.pi, (b, n)))
    bodies.velocity[:] = rng.normal(size=(b, n, 2))
    bodies.angular_velocity[:] = rng.normal(size=(b, n))
    trials, _, _ = task.reset([np.random.default_rng(s) for s in range(b)])
    group = task.task_state(trials, bodies)[0]
    agents = group.attributes
    pos = bodies.position
    assert group.centres is not None
    assert np.array_equal(group.centres.view(np.int64), pos.view(np.int64))
    want = bodies.kinematics(1)
    want[..., 4] = (
        (np.abs(pos[..., 0]) <= r)
        & (pos[..., 1] > task.gate_low)
        & (pos[..., 1] < task.gate_high)
    )
    assert np.array_equal(agents.view(np.int64), want.view(np.int64))
    assert want[1, 0, 4] == 1.0 and want[0, 2, 4] == 0.0
