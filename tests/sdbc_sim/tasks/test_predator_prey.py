"""Predator-prey rules, sensors and results against hand-computed numbers.

The predators are driven by hand-written controllers: fixed outputs supplied to the
engine at every step. GO drives a predator straight at full speed (o0 = 1, o1 = 0.5:
no turn, 0.5 per step), STOP holds it still.

The engine moves a body by the speed commanded at step k during step k (velocity
actuation), so a predator that goes from the start is at y0 + 0.5 k after step k;
the prey decides from the positions before each step and moves in that same
step.
"""

from __future__ import annotations

import copy
import dataclasses
import math

import numpy as np
import pytest
from sdbc_evolution.sdbc.characterisation import SdbcExtractor
from sdbc_sim.engine import BatchSimulation, TrialStepper, run_batch
from sdbc_sim.sensors import bearing, norm, robot_sum, wrap_angle
from sdbc_sim.task import BodyState
from sdbc_sim.task_state import GroupState, TaskState
from sdbc_sim.tasks import make_task
from sdbc_sim.tasks.predator_prey import (
    PredatorPrey,
    PredatorPreyConfig,
    PredatorPreyTrials,
    _speeds_and_turns,
)
from trial_oracle import same_bits

GO = (1.0, 0.5)
STOP = (0.0, 0.5)
DIAGONAL = math.sqrt(2) * 100
UP = math.pi / 2


def drive(
    task: PredatorPrey, outputs: list[tuple[float, float]]
) -> tuple[TrialStepper, list[TaskState]]:
    """Runs one trial with constant predator outputs; returns the stepper and the
    task state of every step."""
    stepper = TrialStepper(task)
    stepper.reset(0)
    states = []
    while not stepper.done:
        stepper.step(np.array(outputs))
        states.append(stepper.state())
    return stepper, states


def prey_track(states: list[TaskState]) -> np.ndarray:
    """(steps, 4) the prey's x, y, turning speed and linear speed."""
    return np.array([s.groups[1].attributes[0, 0] for s in states])


def dispersion(predators: list[np.ndarray]) -> float:
    """Mean over steps of the predators' mean distance to their centroid,
    normalised by half the diagonal."""
    total = 0.0
    for p in predators:
        total += np.linalg.norm(p - p.mean(axis=0), axis=1).mean()
    return total / len(predators) / (DIAGONAL / 2)


def test_pincer_captures_at_centre_distance_4(placed) -> None:
    """Predators 0 and 2 close in on the prey from either side: their away-vectors
    cancel, so the prey stands still, and both reach centre distance
    10 - 0.5 k = 4 at step 12."""
    task = placed(
        PredatorPrey(),
        [[40.0, 50.0], [50.0, 0.0], [60.0, 50.0], [50.0, 50.0]],
        [0.0, UP, math.pi, 0.0],
    )
    stepper, states = drive(task, [GO, STOP, GO])
    fitness, characterisation, length = stepper.result()
    assert length == 12
    assert fitness == pytest.approx(2 - 12 / 600, abs=1e-15)
    track = prey_track(states[:-1])
    np.testing.assert_array_equal(track[:, 3], 0.0)
    np.testing.assert_allclose(track[:, :2], [[50.0, 50.0]] * 11, atol=1e-9)
    present = [bool(s.groups[1].present[0, 0]) for s in states]
    assert present == [True] * 11 + [False]
    predators = [
        np.array([[40 + 0.5 * k, 50], [50, 0], [60 - 0.5 * k, 50]])
        for k in range(1, 13)
    ]
    np.testing.assert_allclose(
        characterisation,
        [1.0, 12 / 600, (4 + 50 + 4) / 3 / DIAGONAL, dispersion(predators)],
        atol=1e-12,
    )


def test_prey_flees_only_from_predators_within_5(placed) -> None:
    """One predator drives at the prey from 10 below. The prey flees (+y, 0.75 per
    step) at the steps where, before the step, the edge-to-edge distance
    y_prey - y_pred - 3 is below 5, and stands still otherwise."""
    task = placed(
        make_task("predator_prey", max_steps=15),
        [[10.0, 10.0], [50.0, 40.0], [90.0, 10.0], [50.0, 50.0]],
        [UP, UP, UP, 0.0],
    )
    stepper, states = drive(task, [STOP, GO, STOP])
    track = prey_track(states)
    # Predator after step k: 40 + 0.5 k; the prey moves 0.75 in a step where it
    # flees. Centre gaps before step k (flee below 8, edge 5):
    #   k = 1..5: 10, 9.5, 9, 8.5, 8       stays (prey at 50)
    #   k = 6: 50 - 42.5 = 7.5             flees (prey 50.75, predator 43)
    #   k = 7: 50.75 - 43 = 7.75           flees (51.5, 43.5)
    #   k = 8: 51.5 - 43.5 = 8             stays (51.5, 44)
    #   k = 9, 10: 7.5, 7.75               flee (52.25, 53; predator 45)
    #   k = 11: 53 - 45 = 8                stays (53, 45.5)
    #   k = 12, 13: 7.5, 7.75              flee (53.75, 54.5; predator 46.5)
    #   k = 14: 54.5 - 46.5 = 8            stays (54.5, 47)
    #   k = 15: 54.5 - 47 = 7.5            flees (55.25)
    fleeing = [0] * 5 + [1, 1, 0, 1, 1, 0, 1, 1, 0, 1]
    np.testing.assert_array_equal(track[:, 3], 0.75 * np.array(fleeing))
    y = [50.0] * 5 + [50.75, 51.5, 51.5, 52.25, 53.0, 53.0, 53.75, 54.5, 54.5, 55.25]
    np.testing.assert_allclose(track[:, 1], y, atol=1e-9)
    np.testing.assert_allclose(track[:, 0], 50.0, atol=1e-9)
    # The prey turns to +y once, at its first flight (step 6).
    turning = np.zeros(15)
    turning[5] = UP
    np.testing.assert_allclose(track[:, 2], turning, atol=1e-12)
    fitness, characterisation, length = stepper.result()
    assert length == 15 and fitness == 0.0
    assert characterisation[0] == 0.0 and characterisation[1] == 15 / 15


def test_prey_flees_along_weighted_sum_of_away_vectors(placed) -> None:
    """Predators 4 (below) and 3 (left) from the prey's edge, the third far away:
    u = (0, 1) / 4 + (1, 0) / 3 = (1/3, 1/4), whose direction is (0.8, 0.6)."""
    task = placed(
        make_task("predator_prey", max_steps=2),
        [[50.0, 43.0], [44.0, 50.0], [90.0, 10.0], [50.0, 50.0]],
        [UP, 0.0, UP, 0.0],
    )
    stepper, states = drive(task, [STOP, STOP, STOP])
    track = prey_track(states)
    assert track[0, 2] == pytest.approx(math.atan2(0.25, 1 / 3), abs=1e-12)
    np.testing.assert_allclose(track[:, 3], [0.75, 0.75], atol=1e-12)
    # It moves 0.75 (0.8, 0.6) in the step it decides.
    np.testing.assert_allclose(track[0, :2], [50.6, 50.45], atol=1e-9)
    # Step 2 decides from there: the still predators' weights are
    # 1 / (centre x edge), edge = centre - 3.
    prey = np.array([50.6, 50.45])
    u = np.zeros(2)
    for p in ([50.0, 43.0], [44.0, 50.0]):
        away = prey - p
        centre = float(np.linalg.norm(away))
        u += away / (centre * (centre - 3.0))
    step2 = prey + 0.75 * u / np.linalg.norm(u)
    np.testing.assert_allclose(track[1, :2], step2, atol=1e-9)


def test_prey_leaving_the_chase_zone_ends_the_trial(placed) -> None:
    """A still predator 4 below the prey's edge pushes it out through y = 100: it
    flees from step 1, at y = 99.75 after step 1 (edge gap 4.75 < 5, so it flees
    again) and 100.5 > 100 after step 2."""
    start = [[10.0, 10.0], [50.0, 92.0], [90.0, 10.0], [50.0, 99.0]]
    task = placed(PredatorPrey(), start, [UP, UP, UP, 0.0])
    stepper, states = drive(task, [STOP, STOP, STOP])
    fitness, characterisation, length = stepper.result()
    assert length == 2
    np.testing.assert_allclose(prey_track(states)[:, 1], [99.75, 100.5])
    predators = np.array(start[:3])
    d_final = np.linalg.norm(predators - [50.0, 100.5], axis=1).mean()
    d_initial = np.linalg.norm(predators - [50.0, 99.0], axis=1).mean()
    assert d_final > d_initial and fitness == 0.0
    np.testing.assert_allclose(
        characterisation,
        [0.0, 2 / 600, d_final / DIAGONAL, dispersion([predators] * 2)],
        atol=1e-12,
    )
    assert bool(states[-1].groups[1].present[0, 0])


def test_closing_in_without_capture_scores_the_distance_gained(placed) -> None:
    """The three predators drive straight up from the start for 10 steps towards
    a prey 50 away that never senses them: they move 0.5 in each of the 10
    steps and end 5 higher."""
    task = placed(
        make_task("predator_prey", max_steps=10),
        [[45.0, 0.0], [50.0, 0.0], [55.0, 0.0], [50.0, 50.0]],
        [UP] * 4,
    )
    stepper, _ = drive(task, [GO, GO, GO])
    fitness, characterisation, length = stepper.result()
    assert length == 10
    d_initial = (2 * math.hypot(5, 50) + 50) / 3
    d_final = (2 * math.hypot(5, 45) + 45) / 3
    assert fitness == pytest.approx((d_initial - d_final) / DIAGONAL, abs=1e-12)
    np.testing.assert_allclose(
        characterisation,
        [0.0, 1.0, d_final / DIAGONAL, (10 / 3) / (DIAGONAL / 2)],
        atol=1e-12,
    )


def test_sensors_by_hand(placed) -> None:
    start = [[45.0, 0.0], [50.0, 0.0], [55.0, 0.0], [50.0, 30.0]]
    task = placed(PredatorPrey(), start, [UP, UP, UP, 0.0])
    stepper = TrialStepper(task)
    stepper.reset(0)
    x = stepper.sensors()
    assert x.shape == (3, 6)
    # Edge distances read 2 d / 100 - 1: predators 5 and 10 apart are 2 and 7
    # apart edge to edge; bearings / pi from a predator facing +y.
    prey0 = math.hypot(5, 30) - 3
    bearing0 = (math.atan2(30, 5) - UP) / math.pi
    np.testing.assert_allclose(
        x[0], [-0.96, -0.5, -0.86, -0.5, 2 * prey0 / 100 - 1, bearing0], atol=1e-12
    )
    # Predator 1: both others 5 away; the tie keeps index order (0 left, 2 right).
    np.testing.assert_allclose(x[1], [-0.96, 0.5, -0.96, -0.5, -0.46, 0.0], atol=1e-12)
    np.testing.assert_allclose(
        x[2], [-0.96, 0.5, -0.86, 0.5, 2 * prey0 / 100 - 1, -bearing0], atol=1e-12
    )


def test_sensors_sort_any_number_of_predators_nearest_first(placed) -> None:
    """Five predators: from predator 0 (facing +y) the others are 10 (right), 4
    (ahead), 7 (left) and 4 (left) away; the tie keeps index order."""
    start = [[50.0, 10.0], [60.0, 10.0], [50.0, 14.0], [43.0, 10.0], [46.0, 10.0]]
    task = placed(
        make_task("predator_prey", n_predators=5),
        [*start, [50.0, 50.0]],
        [UP] * 5 + [0.0],
    )
    stepper = TrialStepper(task)
    stepper.reset(0)
    x = stepper.sensors()
    assert x.shape == (5, 10)
    edges = np.array([4, 4, 7, 10]) - 3
    np.testing.assert_allclose(x[0, 0:8:2], 2 * edges / 100 - 1, atol=1e-12)
    np.testing.assert_allclose(x[0, 1:8:2], [0.0, 0.5, 0.5, -0.5], atol=1e-12)


def test_predator_outputs_set_speed_and_turn(placed) -> None:
    task = placed(
        PredatorPrey(),
        [[45.0, 0.0], [50.0, 0.0], [55.0, 0.0], [50.0, 50.0]],
        [UP] * 3 + [0.0],
    )
    stepper = TrialStepper(task)
    stepper.reset(0)
    stepper.step(np.array([(0.4, 1.0), (1.0, 0.0), (0.0, 0.75)]))
    predators = stepper.state().groups[0]
    # Speed 0.5 o0; turn (2 o1 - 1) 1.57.
    np.testing.assert_allclose(
        predators.attributes[0, :, 2:], [[1.57, 0.2], [-1.57, 0.5], [0.785, 0.0]]
    )


def test_random_start() -> None:
    task = PredatorPrey()
    trials, position, angle = task.reset([np.random.default_rng(s) for s in range(300)])
    np.testing.assert_array_equal(
        position[:, :3], np.tile([[45.0, 0.0], [50.0, 0.0], [55.0, 0.0]], (300, 1, 1))
    )
    np.testing.assert_array_equal(angle[:, :3], UP)
    prey = position[:, 3]
    assert np.all((prey >= 20.0) & (prey <= 80.0))
    assert prey[:, 0].std() > 10 and prey[:, 1].std() > 10
    again = task.reset([np.random.default_rng(7)])
    np.testing.assert_array_equal(again[1][0], position[7])
    assert not trials.captured.any()


def test_description_gives_the_papers_27_dimensions() -> None:
    task = make_task("predator_prey")
    d = task.description
    assert [g.name for g in d.groups] == ["Predators", "Prey", "Boundary"]
    attributes = ("x", "y", "turning speed", "linear speed")
    assert d.group("Predators").attributes == attributes
    assert d.group("Prey").attributes == attributes
    assert (d.group("Predators").min_size, d.group("Predators").max_size) == (3, 3)
    assert (d.group("Prey").min_size, d.group("Prey").max_size) == (0, 1)
    assert d.group("Boundary").is_static and d.group("Boundary").attributes == ()
    assert task.genome_length == 47
    # The SDBC extractor reads the task state of real trials into 2 x 13 + 1.
    extractor = SdbcExtractor()
    genomes = np.random.default_rng(5).uniform(-1, 1, (4, 47))
    result = run_batch(task, genomes, np.arange(8).reshape(4, 2), [extractor])
    names = extractor.dimension_names
    assert len(names) == 27
    for name in ("Predators-prey distance (F)", "Prey-boundary distance (F)"):
        assert name in names
    vectors = extractor.characterisations()
    assert vectors.shape == (8, 27) and np.isfinite(vectors).all()
    np.testing.assert_array_equal(vectors[:, -1], result.length.ravel())


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"predator_radius": -1.5}, "predator_radius: Input should be greater than 0"),
        ({"arena_size": 10.0}, "too small for its robots"),
        ({"capture_distance": 2.0}, "no capture could happen"),
        ({"predator_speed": 2.0}, "pass through each other"),
        ({"prey_margin": 60.0}, "prey_margin"),
        ({"predator_start_y": 50.0}, "predator_start_y"),
        ({"predator_spacing": 1.0}, "predator_spacing"),
        ({"n_predators": 0}, "n_predators: Input should be greater than or equal to 1"),
        ({"flee_distance": float("nan")}, "flee_distance"),
    ],
)
def test_bad_settings_are_named(overrides: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        PredatorPreyConfig(**overrides)
    with pytest.raises(ValueError, match=message):
        make_task("predator_prey", **overrides)


def test_a_trial_is_the_same_alone_in_a_batch_in_any_space_and_process(
    same_everywhere,
) -> None:
    """A 20 x 20 chase zone: predators start 2 apart and meet, and push or chase
    the prey out at different steps."""
    same_everywhere("predator_prey", arena_size=20.0, prey_margin=6.0, max_steps=150)


def test_predators_crowding_the_prey_never_sink_into_each_other(placed) -> None:
    """Three predators steer at full speed for the prey, which sits between two
    of them (they cancel its flight): they meet it and each other, in 40 trials,
    yet no body overlaps another by more than 5% of its radius."""
    start = [[40.0, 50.0], [50.0, 42.0], [60.0, 50.0], [50.0, 50.0]]
    task = placed(make_task("predator_prey", capture_distance=3.0), start, [0.0] * 4)
    r, turn = 1.5, task.config.max_turn
    sim = BatchSimulation(task, np.arange(40))
    worst = -np.inf
    while not sim.finished:
        bearing = sim.sensors()[..., 5] * np.pi
        out = np.ones((sim.live.shape[0], 3, 2))
        out[..., 1] = 0.5 + np.clip(bearing, -turn, turn) / (2 * turn)
        sim.step(out)
        pos = sim.bodies.position
        on = sim.bodies.enabled
        gap = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=-1)
        both = on[:, :, None] & on[:, None] & ~np.eye(4, dtype=bool)
        worst = max(worst, float(np.max(2 * r - gap[both], initial=-np.inf)))
    assert worst > -0.01  # they touched
    assert worst <= 2 * 0.05 * r


class ArrayPredatorPrey(PredatorPrey):
    """The task with its sensors, prey and rules as whole-array numpy: the
    formulation the compiled loops replaced, kept as their oracle."""

    def sensors(self, trials: PredatorPreyTrials, bodies: BodyState) -> np.ndarray:
        c = self.config
        n = c.n_predators
        pos = bodies.position[:, :n]
        b = pos.shape[0]
        out = np.empty((b, n, c.n_inputs))
        cos_h, sin_h = bodies.cos_angle[:, :n], bodies.sin_angle[:, :n]
        scale = 2.0 / c.arena_size
        if n > 1:
            # Every other predator's reading, then sorted nearest first by a stable
            # bubble sort of compare-exchanges (ties keep index order).
            others = [[j for j in range(n) if j != i] for i in range(n)]
            other = pos[:, np.array(others, dtype=np.intp)]
            ox = other[..., 0] - pos[..., 0, None]
            oy = other[..., 1] - pos[..., 1, None]
            d = norm(ox, oy)
            reading = np.maximum(d - 2.0 * c.predator_radius, 0.0) * scale - 1.0
            angle = bearing(ox, oy, cos_h[..., None], sin_h[..., None]) * (1.0 / np.pi)
            cols = [(d[..., j], reading[..., j], angle[..., j]) for j in range(n - 1)]
            for end in range(n - 2, 0, -1):
                for j in range(end):
                    (da, ra, aa), (db, rb, ab) = cols[j], cols[j + 1]
                    swap = db < da
                    cols[j] = (
                        np.where(swap, db, da),
                        np.where(swap, rb, ra),
                        np.where(swap, ab, aa),
                    )
                    cols[j + 1] = (
                        np.where(swap, da, db),
                        np.where(swap, ra, rb),
                        np.where(swap, aa, ab),
                    )
            for k, (_, r, a) in enumerate(cols):
                out[..., 2 * k] = r
                out[..., 2 * k + 1] = a
        px = bodies.position[:, n : n + 1, 0] - pos[..., 0]
        py = bodies.position[:, n : n + 1, 1] - pos[..., 1]
        edge = np.maximum(norm(px, py) - (c.predator_radius + c.prey_radius), 0.0)
        out[..., -2] = edge * scale - 1.0
        out[..., -1] = bearing(px, py, cos_h, sin_h) * (1.0 / np.pi)
        return out

    def actuate(
        self, trials: PredatorPreyTrials, bodies: BodyState, outputs: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        n = c.n_predators
        b = outputs.shape[0]
        speed = np.empty((b, n + 1))
        turn = np.empty((b, n + 1))
        speed[:, :n] = outputs[..., 0] * c.predator_speed
        turn[:, :n] = (2.0 * outputs[..., 1] - 1.0) * c.max_turn
        # The prey's flight, from the positions before the step.
        away = bodies.position[:, n : n + 1] - bodies.position[:, :n]
        centre = norm(away[..., 0], away[..., 1])
        # d_i from the bodies as the first step finds them (NaN until then).
        first = np.isnan(trials.initial_distance)
        if first.any():
            trials.initial_distance[first] = robot_sum(centre[first]) / n
        edge = centre - (c.predator_radius + c.prey_radius)
        close = (edge > 0.0) & (edge < c.flee_distance)
        weight = np.where(close, 1.0 / np.where(close, edge * centre, 1.0), 0.0)
        ux = robot_sum(away[..., 0] * weight)
        uy = robot_sum(away[..., 1] * weight)
        flees = (ux != 0.0) | (uy != 0.0)
        speed[:, n] = np.where(flees, c.prey_speed, 0.0)
        target = np.arctan2(uy, ux)
        turn[:, n] = np.where(flees, wrap_angle(target - bodies.angle[:, n]), 0.0)
        return speed, turn

    def update(
        self, trials: PredatorPreyTrials, bodies: BodyState, step: int
    ) -> np.ndarray:
        c = self.config
        n, s = c.n_predators, c.arena_size
        pos = bodies.position
        prey = pos[:, n]
        offset = pos[:, :n] - prey[:, None, :]
        centre = norm(offset[..., 0], offset[..., 1])
        captured = (centre <= c.capture_distance).any(axis=1)
        trials.captured |= captured
        bodies.enabled[:, n] &= ~captured
        trials.final_distance = robot_sum(centre) / n
        x, y = pos[:, :n, 0], pos[:, :n, 1]
        cx = robot_sum(x) / n
        cy = robot_sum(y) / n
        trials.dispersion_sum += robot_sum(norm(x - cx[:, None], y - cy[:, None])) / n
        outside = (prey < 0.0).any(axis=1) | (prey > s).any(axis=1)
        return captured | outside

    def task_state(
        self, trials: PredatorPreyTrials, bodies: BodyState
    ) -> tuple[GroupState, ...]:
        n = self.config.n_predators
        attributes = bodies.kinematics()
        centres = bodies.position.copy()
        predators, prey, boundary = super().task_state(trials, bodies)
        return (
            dataclasses.replace(
                predators, attributes=attributes[:, :n], centres=centres[:, :n]
            ),
            dataclasses.replace(
                prey,
                present=bodies.enabled[:, n : n + 1].copy(),
                attributes=attributes[:, n:],
                centres=centres[:, n:],
            ),
            boundary,
        )


def scattered_bodies(n: int, n_trials: int, seed: int) -> BodyState:
    """Predators and prey on a unit grid, so that distances tie, edges touch (0)
    and fall exactly on the flee distance (3 here) and the capture distance; a
    few trials off the grid. Positions as a strided view of state rows, as the
    engine passes them."""
    rng = np.random.default_rng(seed)
    r = n + 1
    rows = np.zeros((n_trials, r, 5))
    rows[..., 0:2] = rng.integers(0, 9, (n_trials, r, 2)) + 40.0
    rows[: n_trials // 4, :, 0:2] += rng.normal(0.0, 3.0, (n_trials // 4, r, 2))
    rows[-2:, n, 0] = (-1.0, 101.0)
    angle = rng.uniform(-2 * math.pi, 2 * math.pi, (n_trials, r))
    return BodyState.at_rest(rows[..., 0:2], angle)


@pytest.mark.parametrize("n", [1, 3, 5])
@pytest.mark.parametrize("seed", [0, 1])
def test_compiled_sensors_prey_and_rules_equal_the_array_formulation(
    n: int, seed: int
) -> None:
    """To the bit: the predators' inputs, the prey's speed and turn, d_i, every
    trial array the rules write and the task state, on scattered trials (ties,
    touching bodies, distances exactly at the flee and capture thresholds, a prey
    outside)."""
    settings = {"n_predators": n, "flee_distance": 3.0}
    task = make_task("predator_prey", **settings)
    oracle = ArrayPredatorPrey(PredatorPreyConfig(**settings))
    n_trials = 96
    got_trials, _, _ = task.reset([np.random.default_rng(t) for t in range(n_trials)])
    want_trials = copy.deepcopy(got_trials)
    got_trials.initial_distance[: n_trials // 2] = 7.0
    want_trials.initial_distance[: n_trials // 2] = 7.0
    got_bodies = scattered_bodies(n, n_trials, seed)
    want_bodies = copy.deepcopy(got_bodies)
    outputs = np.random.default_rng(seed).uniform(0.0, 1.0, (n_trials, n, 2))

    np.testing.assert_array_equal(
        task.sensors(got_trials, got_bodies), oracle.sensors(want_trials, want_bodies)
    )
    for got, want in zip(
        task.actuate(got_trials, got_bodies, outputs),
        oracle.actuate(want_trials, want_bodies, outputs),
        strict=True,
    ):
        assert same_bits(got, want)
    assert same_bits(
        task.update(got_trials, got_bodies, 1),
        oracle.update(want_trials, want_bodies, 1),
    )
    for name in ("captured", "initial_distance", "final_distance", "dispersion_sum"):
        assert same_bits(getattr(got_trials, name), getattr(want_trials, name)), name
    assert same_bits(got_bodies.enabled, want_bodies.enabled)
    assert got_trials.captured.any() and not got_trials.captured.all()
    got_bodies.velocity = np.random.default_rng(seed).normal(
        0.0, 0.5, (n_trials, n + 1, 2)
    )
    got_bodies.angular_velocity = outputs[:, :1, 0].repeat(n + 1, axis=1)
    for got, want in zip(
        task.task_state(got_trials, got_bodies),
        oracle.task_state(got_trials, got_bodies),
        strict=True,
    ):
        for field in dataclasses.fields(got):
            a, w = getattr(got, field.name), getattr(want, field.name)
            assert (a is None and w is None) or same_bits(a, w), field.name


def test_compiled_speeds_and_turns_equal_the_array_formulation() -> None:
    """To the bit: the prey's turn where its heading is exactly half a turn,
    and more, from u's angle (wrapping to the edges of [-pi, pi)), with and
    without a push; the predators' speeds and turns, no turn at o1 = 0.5."""
    c = PredatorPreyConfig()
    n, b = c.n_predators, 12
    rng = np.random.default_rng(3)
    outputs = rng.uniform(0.0, 1.0, (b, n, 2))
    outputs[::3, :, 1] = 0.5
    ux = rng.choice([0.0, -0.3, 2.0], b)
    uy = rng.choice([0.0, 0.0, 1e-300], b)
    target = np.arctan2(uy, ux)
    angle = rng.uniform(-2 * math.pi, 2 * math.pi, (b, n + 1))
    half = np.array([math.pi, -math.pi, 3 * math.pi, 0.0, 2 * math.pi, -0.0])
    angle[:, n] = target + np.resize(half, b)
    angle[-1, n] = np.nextafter(target[-1] + math.pi, np.inf)
    speed = np.empty((b, n + 1))
    turn = np.empty((b, n + 1))
    _speeds_and_turns(
        outputs, angle, ux, uy, target, c.predator_speed, c.max_turn, 0.75, speed, turn
    )
    flees = (ux != 0.0) | (uy != 0.0)
    want_turn = np.empty((b, n + 1))
    want_turn[:, :n] = (2.0 * outputs[..., 1] - 1.0) * c.max_turn
    want_turn[:, n] = np.where(flees, wrap_angle(target - angle[:, n]), 0.0)
    want_speed = np.empty((b, n + 1))
    want_speed[:, :n] = outputs[..., 0] * c.predator_speed
    want_speed[:, n] = np.where(flees, 0.75, 0.0)
    assert same_bits(speed, want_speed)
    assert same_bits(turn, want_turn)
    assert flees.any() and not flees.all()
