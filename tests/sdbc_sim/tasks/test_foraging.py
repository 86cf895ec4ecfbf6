"""Foraging rules, sensors and results against hand-computed numbers.

STOP holds a robot still (o2 = 1 > 0.5), GO drives it straight at full speed (1 per
step, no turn); a robot moves in the step it is commanded. The nest is the circle
of radius 10 at (50, 50); a robot picks up an item within 2.5 + 1 = 3.5 of its
centre.
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from sdbc_evolution.sdbc.characterisation import SdbcExtractor
from sdbc_sim.engine import TrialStepper, run_batch
from sdbc_sim.sensors import bearing, norm, normalised_reading
from sdbc_sim.task import BodyState
from sdbc_sim.task_state import TaskState
from sdbc_sim.tasks import make_task
from sdbc_sim.tasks.foraging import Foraging, ForagingConfig

STOP = (0.0, 0.5, 1.0)
GO = (1.0, 0.5, 0.0)
CORNERS = [[10.0, 10.0], [90.0, 10.0], [10.0, 90.0], [90.0, 90.0]]
"""Where the robots that stay still wait, 40 sqrt 2 from the nest centre."""
FAR = 100 / math.sqrt(2)


def with_items(task: Foraging, items: list[list[float]]) -> Foraging:
    """``task`` with the items of every trial at ``items`` (M, 2)."""
    draw = task.reset

    def reset(rngs: list[np.random.Generator]):
        trials, position, angle = draw(rngs)
        trials.items[:] = np.asarray(items, dtype=np.float64)
        return trials, position, angle

    task.reset = reset  # type: ignore[method-assign]
    return task


def drive(task: Foraging, outputs) -> tuple[TrialStepper, list[TaskState], list]:
    """Runs one trial with constant outputs; returns the stepper, the task state
    and the network inputs after every step."""
    stepper = TrialStepper(task)
    stepper.reset(0)
    states, inputs = [], []
    while not stepper.done:
        stepper.step(np.array(outputs))
        states.append(stepper.state())
        inputs.append(stepper.sensors() if not stepper.done else None)
    return stepper, states, inputs


def test_pick_up_carry_and_deliver(placed) -> None:
    """Robot 0 at (70, 50) drives at the nest along y = 50, over item 0 at
    (66, 50): at x_k = 70 - k it is 3 from the item after step 1 (pick-up) and 10
    from the nest centre after step 10 (delivery). Item 1, at (50, 85), stays."""
    task = placed(
        make_task("foraging", n_items=2, max_steps=20),
        [[70.0, 50.0], *CORNERS],
        [math.pi, 0.0, 0.0, 0.0, 0.0],
    )
    task = with_items(task, [[66.0, 50.0], [50.0, 85.0]])
    stepper, states, inputs = drive(task, [GO] + [STOP] * 4)
    items = [s.groups[1] for s in states]
    # Carried from step 1 to step 9, riding on the robot; gone after step 10
    # (states[k - 1] is after step k).
    assert [bool(g.present[0, 0]) for g in items[7:10]] == [True, True, False]
    np.testing.assert_allclose(items[4].centres[0, 0], [65.0, 50.0], atol=1e-12)
    assert items[4].attributes[0, 0, 2] == 1.0 and items[4].attributes[0, 1, 2] == 0
    agents = [s.groups[0] for s in states]
    assert [float(a.attributes[0, 0, 4]) for a in agents[7:10]] == [1.0, 1.0, 0.0]
    assert inputs[0][0, 4] == 1.0 and inputs[9][0, 4] == -1.0
    fitness, characterisation, length = stepper.result()
    # One delivered of 2, no item in transit at the end, not all delivered:
    # (1 + 0.5 x 0 + 0) / 3.
    assert length == 20
    assert fitness == pytest.approx(1 / 3, abs=1e-15)
    # Carrying steps 1-9 (9 of 5 x 20 robot-steps); in the nest after steps
    # 10-20 (x_k <= 60: 11); distance to the nest: robot 0 20 - k at step k
    # (sum 190), the others 40 sqrt 2 each for 20 steps.
    distance = (190 + 4 * 20 * 40 * math.sqrt(2)) / 100 / FAR
    np.testing.assert_allclose(
        characterisation, [0.5, 0.5, 0.09, 0.11, distance], atol=1e-12
    )


def test_delivering_every_item_ends_the_trial_early(placed) -> None:
    """One item, delivered at step 10 as above: the trial ends there with the
    early bonus 1 - 10 / 600: F = (1 + 0 + 1 - 10 / 600) / 2."""
    task = placed(
        make_task("foraging", n_items=1),
        [[70.0, 50.0], *CORNERS],
        [math.pi, 0.0, 0.0, 0.0, 0.0],
    )
    task = with_items(task, [[66.0, 50.0]])
    stepper, states, _ = drive(task, [GO] + [STOP] * 4)
    fitness, characterisation, length = stepper.result()
    assert length == 10
    assert fitness == pytest.approx((2 - 10 / 600) / 2, abs=1e-15)
    assert characterisation[0] == 1.0 and characterisation[1] == 1.0
    assert not states[-1].groups[1].present.any()


def test_an_item_goes_to_the_first_robot_that_reaches_it(placed) -> None:
    """Robots 0 and 1 drive at item 0 from either side, both 3 from it after
    step 1: robot 0 takes it, robot 1 carries nothing; an item in transit at the
    end scores half: F = (0 + 0.5 x 1 + 0) / 2."""
    task = placed(
        make_task("foraging", n_items=1, max_steps=3),
        [[76.0, 70.0], [84.0, 70.0], *CORNERS[:3]],
        [0.0, math.pi, 0.0, 0.0, 0.0],
    )
    task = with_items(task, [[80.0, 70.0]])
    stepper, states, _ = drive(task, [GO, GO] + [STOP] * 3)
    carrying = states[0].groups[0].attributes[0, :, 4]
    assert carrying.tolist() == [1.0, 0.0, 0.0, 0.0, 0.0]
    fitness, characterisation, _ = stepper.result()
    assert fitness == pytest.approx(0.25, abs=1e-15)
    assert characterisation[:2].tolist() == [0.0, 1.0]


def test_sensors_by_hand(placed) -> None:
    """Robot 0 at (80, 50) facing +y: item 0 at (80, 60) straight ahead (10 of
    25: reads -0.2, bearing 0), item 1 at (90, 50) on its right, farther; the
    nest centre 30 to its left: 2 x 30 / (100 / sqrt 2) - 1, bearing pi / 2."""
    task = placed(
        make_task("foraging", n_items=2),
        [[80.0, 50.0], *CORNERS],
        [math.pi / 2, 0.0, 0.0, 0.0, 0.0],
    )
    task = with_items(task, [[80.0, 60.0], [90.0, 50.5]])
    stepper = TrialStepper(task)
    stepper.reset(0)
    x = stepper.sensors()
    assert x.shape == (5, 13)
    nest = 2 * 30 / FAR - 1
    np.testing.assert_allclose(x[0, :5], [-0.2, 0.0, nest, 0.5, -1.0], atol=1e-12)
    # Nobody else within 25 of robot 0, no wall within ray reach.
    np.testing.assert_allclose(x[0, 5:], 1.0, atol=1e-12)
    # Robot 4 at (90, 90) facing +x: item 1 40 below (out of range); the top and
    # right walls 10 away, beyond the rays' reach of 2.5 + 5.
    np.testing.assert_allclose(x[4, :2], [1.0, 0.0], atol=1e-12)


def test_random_starts() -> None:
    task = Foraging()
    trials, position, angle = task.reset([np.random.default_rng(s) for s in range(200)])
    assert np.all((position >= 2.5) & (position <= 97.5))
    gaps = np.linalg.norm(position[:, :, None] - position[:, None], axis=-1)
    assert np.all(gaps[:, ~np.eye(5, dtype=bool)] >= 5.0)
    nest = np.linalg.norm(trials.items - [50.0, 50.0], axis=-1)
    assert np.all(nest >= 11.0)
    assert np.all((trials.items >= 1.0) & (trials.items <= 99.0))
    assert np.all(trials.carrier == -1) and np.all(trials.load == -1)


def test_description_and_characterisations() -> None:
    task = make_task("foraging")
    d = task.description
    assert [g.name for g in d.groups] == ["Agent", "Item", "Nest", "Wall"]
    assert (d.group("Item").min_size, d.group("Item").max_size) == (0, 15)
    assert d.group("Nest").is_static and d.group("Wall").is_static
    assert task.genome_length == 88
    extractor = SdbcExtractor()
    rng = np.random.default_rng(3)
    result = run_batch(
        task, rng.uniform(-1, 1, (3, 88)), np.arange(6).reshape(3, 2), [extractor]
    )
    names = extractor.dimension_names
    assert len(names) == 33 and "Item group size (F)" in names
    assert np.all((result.fitness >= 0) & (result.fitness <= 1))
    c = result.characterisation
    assert np.all((c >= 0) & (c <= 1))


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"n_items": 0}, "n_items: Input should be greater than or equal to 1"),
        ({"carry_credit": 2.0}, "carry_credit: Input should be less than or equal"),
        ({"nest_radius": 49.0}, "arena_size: the arena is too small"),
        ({"item_radius": -1.0}, "item_radius: Input should be greater than 0"),
        ({"n_items": "15"}, "n_items: Input should be a valid integer"),
        ({"max_speed": 3.0}, "pass through walls"),
        ({"start_separation": 4.0}, "start_separation"),
    ],
)
def test_bad_settings_are_named(overrides: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        ForagingConfig(**overrides)
    with pytest.raises(ValueError, match=message):
        make_task("foraging", **overrides)


def test_a_trial_is_the_same_alone_in_a_batch_in_any_space_and_process(
    same_everywhere,
) -> None:
    """A small arena with two items, so robots meet and many teams deliver both
    (45 different trial lengths)."""
    same_everywhere(
        "foraging",
        arena_size=30.0,
        nest_radius=4.0,
        n_items=2,
        max_steps=150,
    )


def array_item_readings(task: Foraging, trials, bodies) -> np.ndarray:
    """Inputs 0 and 1 (nearest free item) as whole (B, N, M) arrays: the
    formulation the compiled loop replaced, kept as its oracle."""
    c = task.config
    pos = bodies.position
    ix = trials.items[:, None, :, 0] - pos[..., 0, None]
    iy = trials.items[:, None, :, 1] - pos[..., 1, None]
    d = norm(ix, iy)
    np.copyto(d, np.inf, where=(trials.carrier != -1)[:, None, :])
    nearest = np.argmin(d, axis=-1)[..., None]
    dn = d.min(axis=-1)
    seen = dn <= c.item_sensor_range
    ib = bearing(
        np.take_along_axis(ix, nearest, axis=-1)[..., 0],
        np.take_along_axis(iy, nearest, axis=-1)[..., 0],
        bodies.cos_angle,
        bodies.sin_angle,
    )
    return np.stack(
        [
            np.where(seen, normalised_reading(dn, c.item_sensor_range), 1.0),
            np.where(seen, ib / np.pi, 0.0),
        ],
        axis=-1,
    )


def array_pick_up_and_carry(task: Foraging, trials, pos: np.ndarray) -> None:
    """The pick-ups and the carrying of one step as whole arrays, robot by robot:
    the formulation the compiled loop replaced, kept as its oracle."""
    c = task.config
    ix = trials.items[:, None, :, 0] - pos[..., 0, None]
    iy = trials.items[:, None, :, 1] - pos[..., 1, None]
    d = norm(ix, iy)
    np.copyto(d, np.inf, where=(trials.carrier != -1)[:, None, :])
    reach = c.robot_radius + c.item_radius
    rows = np.arange(pos.shape[0])
    for i in range(pos.shape[1]):
        nearest = np.argmin(d[:, i], axis=-1)
        takes = (trials.load[:, i] < 0) & (d[rows, i, nearest] <= reach)
        t, k = rows[takes], nearest[takes]
        trials.load[t, i] = k
        trials.carrier[t, k] = i
        trials.picked[t] += 1
        d[t, :, k] = np.inf
    t, k = np.nonzero(trials.carrier >= 0)
    trials.items[t, k] = pos[t, trials.carrier[t, k]]


def crowded_trials(task: Foraging, n_trials: int, seed: int):
    """Trials whose robots stand among their items: on a coarse grid (so that
    distances tie and fall exactly on the reach and the sensor range), some items
    carried, some delivered, some trials with no free item left; away from the
    nest, so that the step delivers nothing."""
    c = task.config
    n, m = c.n_robots, c.n_items
    rng = np.random.default_rng(seed)
    trials, _, _ = task.reset([np.random.default_rng(t) for t in range(n_trials)])
    trials.items[:] = rng.integers(0, 13, (n_trials, m, 2)) * 0.5 + 15.0
    pos = rng.integers(0, 13, (n_trials, n, 2)) * 0.5 + 15.0
    pos[: n_trials // 4] += rng.normal(0.0, 1.0, (n_trials // 4, n, 2))
    angle = rng.uniform(-math.pi, math.pi, (n_trials, n))
    state = rng.integers(0, 3, (n_trials, m))
    trials.carrier[:] = np.where(state == 0, -2, -1)
    trials.carrier[-2:] = -2
    for t in range(n_trials):
        free_robots = iter(rng.permutation(n))
        for k in np.flatnonzero(state[t] == 1)[:n]:
            i = next(free_robots)
            if trials.carrier[t, k] == -1 and rng.random() < 0.5:
                trials.carrier[t, k], trials.load[t, i] = i, k
    bodies = BodyState.at_rest(pos, angle)
    return trials, bodies


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_compiled_item_sensor_and_pick_ups_equal_the_array_formulation(
    seed: int,
) -> None:
    """To the bit, on crowded trials (ties, distances exactly at the reach and the
    range, carried and delivered items, no free item left), for a strided view of
    the positions as the engine passes them and for contiguous ones."""
    task = make_task("foraging", n_items=9, item_sensor_range=2.0)
    trials, bodies = crowded_trials(task, 64, seed)
    want = array_item_readings(task, trials, bodies)
    got = task.sensors(trials, bodies)[..., 0:2]
    np.testing.assert_array_equal(got, want)
    assert (want[..., 0] < 1.0).any() and (want[..., 0] == 1.0).any()

    expected = copy.deepcopy(trials)
    array_pick_up_and_carry(task, expected, bodies.position)
    # The engine hands the rules positions as a strided view of its state rows.
    rows = np.zeros((*bodies.position.shape[:2], 5))
    rows[..., 0:2] = bodies.position
    bodies.position = rows[..., 0:2]
    task.update(trials, bodies, 0)
    assert expected.picked.sum() > 0
    for name in ("items", "carrier", "load", "picked"):
        np.testing.assert_array_equal(getattr(trials, name), getattr(expected, name))
