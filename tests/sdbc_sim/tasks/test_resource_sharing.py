"""Resource sharing rules, sensors and results against hand-computed numbers.

The robots are driven by hand-written controllers: fixed outputs supplied to the
engine at every step. STOP holds a robot still (o2 = 1 > 0.5), GO drives it
straight at full speed (o0 = 1, o1 = 0.5: no turn).

The engine moves a body by the speed commanded at step k during step k (velocity
actuation; its measured speed after step k is the commanded one), so a robot
commanded to stop at step k has speed 0 at step k and stays where it was after
step k - 1.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Callable

import numpy as np
import pytest
from sdbc_evolution.sdbc.characterisation import SdbcExtractor
from sdbc_sim.engine import BatchSimulation, TrialStepper, run_batch
from sdbc_sim.sensors import bearing, norm, robot_sum
from sdbc_sim.task import BodyState
from sdbc_sim.task_state import GroupState, TaskState
from sdbc_sim.tasks import make_task
from sdbc_sim.tasks.resource_sharing import (
    NO_CHARGE_OPTIMUM,
    ResourceSharing,
    ResourceSharingConfig,
    ResourceSharingTrials,
)
from trial_oracle import assert_same_trials, same_bits

STOP = (0.0, 0.5, 1.0)
GO = (1.0, 0.5, 0.0)
CENTRE = [75.0, 75.0]
"""The station centre in the default 150 x 150 arena."""
NORTH = [75.0, 125.0]
WEST = [25.0, 75.0]
"""Parking spots 50 from the station centre, far from everyone."""


def drive(
    task: ResourceSharing, policy: Callable[[int], list[tuple[float, float, float]]]
) -> tuple[TrialStepper, list[TaskState], list[np.ndarray], list[np.ndarray]]:
    """Runs one trial with the outputs ``policy(k)`` at step k = 1, 2, ...

    Returns the stepper, and per step the task state, the energies and the
    charging flags of the robots.
    """
    stepper = TrialStepper(task)
    stepper.reset(0)
    states, energy, charging = [], [], []
    while not stepper.done:
        stepper.step(np.array(policy(stepper.step_count + 1)))
        trials = stepper.sim.trials
        states.append(stepper.state())
        energy.append(trials.energy[0].copy())
        charging.append(trials.charging[0].copy())
    return stepper, states, energy, charging


def test_parked_robot_charges_after_five_stationary_steps(placed) -> None:
    task = placed(
        make_task("resource_sharing", initial_energy=100.0),
        [CENTRE, NORTH, WEST],
        [0.0, 0.0, 0.0],
    )
    stepper, states, energy, charging = drive(task, lambda k: [STOP] * 3)
    e = np.array(energy)
    # Robot 0 sits on the station: docked from step 1, it spends 1.05 per step for
    # 5 steps (100 - 5.25 = 94.75), then charges 20 - 1.05 = 18.95 net per step:
    # 94.75 + 21 x 18.95 = 492.7 at step 26, full (500) from step 27 on.
    assert e[4, 0] == pytest.approx(94.75, abs=1e-12)
    assert e[5, 0] == pytest.approx(113.7, abs=1e-12)
    assert e[25, 0] == pytest.approx(492.7, abs=1e-9)
    assert np.all(e[26:, 0] == 500.0)
    flags = np.array(charging)
    assert not flags[:5].any() and flags[5:, 0].all() and not flags[:, 1:].any()
    occupied = [float(s.groups[1].attributes[0, 0, 0]) for s in states]
    assert occupied[:5] == [0.0] * 5 and set(occupied[5:]) == {1.0}
    # The others drain 1.05 per step: 100 - 95 x 1.05 = 0.25 left after step 95,
    # dead at step 96, and gone from the Agent group.
    assert e[94, 1:] == pytest.approx([0.25, 0.25], abs=1e-9)
    assert np.all(e[95:, 1:] == 0.0)
    present = np.array([s.groups[0].present[0] for s in states])
    assert present[94].tolist() == [True, True, True]
    assert present[95].tolist() == [True, False, False]
    # The trial runs to max_steps with one survivor. Energy sums over the trial:
    # robot 1 or 2: sum_{k=1}^{95} (100 - 1.05 k) = 9500 - 1.05 x 4560 = 4712;
    # robot 0: sum_{k=1}^{5} (100 - 1.05 k) = 484.25, then 94.75 + 18.95 m for
    # m = 1..21 (6367.2), then 474 steps at 500 (237000): 243851.45.
    fitness, characterisation, length = stepper.result()
    assert length == 500
    energy_sum = 243851.45 + 2 * 4712.0
    assert fitness == pytest.approx((1 + energy_sum / (3 * 500) / 500) / 4, rel=1e-12)
    # Characterisation: survivors 1/3; the alive robots are sampled 95 x 3 + 405
    # = 690 times, holding energy_sum in all, at speed 0, 0 (robot 0) or 50 (the
    # others, 95 steps each) from the station.
    np.testing.assert_allclose(
        characterisation,
        [1 / 3, energy_sum / 690 / 500, 0.0, 2 * 95 * 50 / 690 / 75],
        rtol=1e-12,
    )


def test_station_takes_one_robot_at_a_time(placed) -> None:
    """Robot 0 charges on the station while robot 1 waits next to it; robot 0
    drives off at step 20, robot 1 drives on during steps 22..31 and stops there
    at 32."""

    def policy(k: int) -> list[tuple[float, float, float]]:
        return [STOP if k < 20 else GO, GO if 22 <= k <= 31 else STOP, STOP]

    task = placed(
        ResourceSharing(), [CENTRE, [75.0, 85.0], WEST], [0.0, -math.pi / 2, 0.0]
    )
    stepper, states, energy, charging = drive(task, policy)
    flags = np.array(charging)
    steps = np.arange(1, len(flags) + 1)
    # Robot 0 is docked from step 1 (centre on the station, speed 0), so it
    # charges from step 6 (5 docked steps before) until it moves, at step 20
    # (speed 1 then: not docked); robot 1, 10 from the station centre (2 from
    # robot 0's edge), cannot dock until robot 0 has left. Robot 1 moves 1 in
    # each of steps 22..31, from y = 85 to y = 75; at step 31 it is there but
    # moving, so it is docked from step 32 (speed 0), and charges from step 37.
    assert np.array_equal(steps[flags[:, 0]], np.arange(6, 20))
    assert np.array_equal(steps[flags[:, 1]], np.arange(37, 501))
    assert not flags[:, 2].any()
    assert flags.sum(axis=1).max() == 1
    # states[k - 1] is after step k: y = 85 after step 21, 84 after 22, 76 after
    # 30, 75 after 31 and 32.
    y1 = np.array([s.groups[0].centres[0, 1, 1] for s in states])
    np.testing.assert_allclose(
        y1[[20, 21, 29, 30, 31]], [85.0, 84.0, 76.0, 75.0, 75.0], atol=1e-9
    )
    # Robot 1's energy: 21 stopped steps, 10 at full speed (drain 2), 5 docked,
    # then charging: 500 - 21 x 1.05 - 10 x 2 - 5 x 1.05 = 452.7 at step 36,
    # 452.7 + 18.95 = 471.65 at step 37.
    e = np.array(energy)
    assert e[35, 1] == pytest.approx(452.7, abs=1e-9)
    assert e[36, 1] == pytest.approx(471.65, abs=1e-9)
    # Robot 0 was full when it left at step 20 and spends 2 per step after:
    # 498 at step 20, dead at step 20 + 249 = 269.
    assert e[19, 0] == 500.0 - 2.0
    assert e[267, 0] == pytest.approx(2.0, abs=1e-9) and e[268, 0] == 0.0
    occupied = np.array([s.groups[1].attributes[0, 0, 0] for s in states])
    np.testing.assert_array_equal(occupied, flags.any(axis=1))


def test_idle_team_dies_and_ends_the_trial() -> None:
    task = ResourceSharing()
    stepper, states, energy, _ = drive(task, lambda k: [STOP] * 3)
    # 500 / 1.05 = 476.19: 0.2 left after step 476, everyone dead at step 477.
    fitness, characterisation, length = stepper.result()
    assert length == 477
    e = np.array(energy)
    assert e[475] == pytest.approx([0.2] * 3, abs=1e-9)
    assert np.all(e[476] == 0.0)
    assert not states[-1].groups[0].present.any()
    # Mean energy over robots and steps: sum_{k=1}^{476} (500 - 1.05 k) / 477
    # = (238000 - 1.05 x 113526) / 477 = 118797.7 / 477.
    assert fitness == pytest.approx((0 + 118797.7 / 477 / 500) / 4, rel=1e-12)
    # The robots never move: the characterisation's distance is their start's.
    start = states[0].groups[0].centres[0]
    distance = np.linalg.norm(start - CENTRE, axis=1).mean()
    np.testing.assert_allclose(
        characterisation,
        [0.0, 118797.7 / 476 / 500, 0.0, distance / 75],
        rtol=1e-12,
    )


@pytest.mark.parametrize(
    ("outputs", "drain"),
    [
        ((1.0, 0.5, 0.0), 2.0),
        ((0.5, 0.5, 0.0), 1.05 + 0.95 * 0.5),
        ((0.0, 0.5, 0.0), 1.05),
        ((1.0, 0.5, 1.0), 1.05),
    ],
)
def test_drain_grows_with_the_speed_command(placed, outputs, drain) -> None:
    """1.05 + 0.95 o0 per step, o0 read as 0 when o2 stops the robot."""
    task = placed(
        make_task("resource_sharing", max_steps=3),
        [NORTH, WEST, [125.0, 75.0]],
        [math.pi / 2, math.pi, 0.0],
    )
    _, _, energy, _ = drive(task, lambda k: [outputs] * 3)
    np.testing.assert_allclose(
        np.array(energy)[:, 0], 500.0 - drain * np.arange(1, 4), rtol=1e-15
    )


def test_characterisation_interval_samples_every_nth_step(placed) -> None:
    """Robot 0 drives off the station from step 1 (moving 1 per step from step 1):
    sampled at steps 10 and 20 only, it is 10 and 20 from the station."""
    task = placed(
        make_task("resource_sharing", max_steps=20, characterisation_interval=10),
        [CENTRE, NORTH, WEST],
        [0.0, 0.0, 0.0],
    )
    stepper, _, _, _ = drive(task, lambda k: [GO, STOP, STOP])
    _, characterisation, _ = stepper.result()
    energy = (500 - 2 * 10) + 2 * (500 - 1.05 * 10) + (500 - 2 * 20) + 2 * (500 - 21)
    np.testing.assert_allclose(
        characterisation,
        [1.0, energy / 6 / 500, 2 / 6, (10 + 20 + 4 * 50) / 6 / 75],
        rtol=1e-12,
    )


def test_sensors_by_hand(placed) -> None:
    start = [[40.0, 75.0], [40.0, 95.0], [40.0, 40.0]]
    task = placed(ResourceSharing(), start, [0.0, math.pi, math.pi / 2])
    stepper = TrialStepper(task)
    stepper.reset(0)
    x = stepper.sensors()
    assert x.shape == (3, 8)
    # Robot 0 faces +x: the station 35 ahead; robot 1 on its left, 20 - 8 = 12
    # edge to edge; robot 2 35 - 8 = 27 away, out of range. Full, not charging.
    np.testing.assert_allclose(
        x[0], [1, 1, 1, 2 * 12 / 25 - 1, 2 * 35 / 75 - 1, 0, 1, -1], atol=1e-12
    )
    # Robot 1 faces -x: robot 0 on its left (bearing +pi/2); the station at
    # (35, -20), bearing atan2(-20, 35) - pi + 2 pi.
    station = math.hypot(35, 20)
    np.testing.assert_allclose(
        x[1],
        [
            1,
            1,
            1,
            2 * 12 / 25 - 1,
            2 * station / 75 - 1,
            (math.atan2(-20, 35) + math.pi) / math.pi,
            1,
            -1,
        ],
        atol=1e-12,
    )
    # Robot 2 faces +y; nobody within 25; the station at (35, 35), bearing -pi/4.
    np.testing.assert_allclose(
        x[2, 4:], [2 * math.hypot(35, 35) / 75 - 1, -0.25, 1, -1], atol=1e-12
    )


def test_sensors_read_energy_and_charging(placed) -> None:
    task = placed(
        make_task("resource_sharing", initial_energy=200.0, charge_delay=0),
        [CENTRE, NORTH, WEST],
        [0.0, 0.0, 0.0],
    )
    stepper = TrialStepper(task)
    stepper.reset(0)
    stepper.step(np.array([STOP] * 3))
    x = stepper.sensors()
    # With no delay robot 0 charges at once: 200 - 1.05 + 20 = 218.95.
    np.testing.assert_allclose(
        x[:, 6], 2 * np.array([218.95, 198.95, 198.95]) / 500 - 1
    )
    np.testing.assert_array_equal(x[:, 7], [1, -1, -1])


def test_task_state_groups(placed) -> None:
    task = placed(ResourceSharing(), [CENTRE, NORTH, WEST], [0.0, 1.0, 2.0])
    stepper = TrialStepper(task)
    stepper.reset(0)
    stepper.step(np.array([STOP, (1.0, 1.0, 0.0), STOP]))
    agent, station = stepper.state().groups
    # Robot 1 turned by 0.78 rad, to heading 1.78, and moved 1 along it in the
    # same step: its position and measured speeds.
    np.testing.assert_allclose(
        agent.attributes[0, 1],
        [75 + math.cos(1.78), 125 + math.sin(1.78), 0.78, 1.0, 500 - 2.0, 0.0],
        atol=1e-12,
    )
    np.testing.assert_allclose(
        agent.attributes[0, 0], [75, 75, 0.0, 0.0, 500 - 1.05, 0.0], atol=1e-12
    )
    assert agent.present.tolist() == [[True, True, True]]
    np.testing.assert_array_equal(agent.radii, [[4.0, 4.0, 4.0]])
    np.testing.assert_array_equal(station.centres, [[CENTRE]])
    np.testing.assert_array_equal(station.radii, [[5.0]])
    assert station.present.tolist() == [[True]]


def test_random_starts_keep_their_distances() -> None:
    task = ResourceSharing()
    c = task.config
    trials, position, angle = task.reset([np.random.default_rng(s) for s in range(300)])
    r = c.robot_radius
    assert np.all((position >= r) & (position <= c.arena_size - r))
    assert np.all(np.linalg.norm(position - CENTRE, axis=-1) >= 34.0)
    gaps = np.linalg.norm(position[:, :, None] - position[:, None], axis=-1)
    assert np.all(gaps[:, ~np.eye(3, dtype=bool)] >= 34.0)
    assert np.all((angle >= -np.pi) & (angle < np.pi))
    assert np.all(trials.energy == 500.0) and not trials.charging.any()
    again = task.reset([np.random.default_rng(7)])
    np.testing.assert_array_equal(again[1][0], position[7])


def test_description_gives_the_papers_21_dimensions() -> None:
    task = make_task("resource_sharing")
    d = task.description
    assert [g.name for g in d.groups] == ["Agent", "Station"]
    assert d.group("Agent").attributes == (
        "x",
        "y",
        "turning speed",
        "linear speed",
        "energy level",
        "is charging",
    )
    assert (d.group("Agent").min_size, d.group("Agent").max_size) == (0, 3)
    assert d.group("Station").attributes == ("is occupied",)
    assert d.group("Station").is_static and not d.group("Agent").is_static
    assert task.genome_length == 75
    # The SDBC extractor reads the task state of real trials into 2 x 10 + 1.
    extractor = SdbcExtractor()
    rng = np.random.default_rng(5)
    genomes = rng.uniform(-1, 1, (4, 75))
    result = run_batch(task, genomes, np.arange(8).reshape(4, 2), [extractor])
    names = extractor.dimension_names
    assert len(names) == 21
    assert "Agent energy level (M)" in names and "Station is occupied (F)" in names
    vectors = extractor.characterisations()
    assert vectors.shape == (8, 21) and np.isfinite(vectors).all()
    np.testing.assert_array_equal(vectors[:, -1], result.length.ravel())


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"robot_radius": -4.0}, "robot_radius: Input should be greater than 0"),
        ({"arena_size": 50.0}, "too small for its robots"),
        ({"arena_size": 20.0}, "too small for its robots"),
        ({"station_radius": 3.0}, "station_radius"),
        ({"station_radius": 8.0}, "could hold two robots"),
        ({"initial_energy": 600.0}, "initial_energy"),
        ({"min_energy_drain": 3.0}, "max_energy_drain"),
        (
            {"charge_delay": -1},
            "charge_delay: Input should be greater than or equal to 0",
        ),
        ({"max_speed": 5.0}, "pass through each other"),
        ({"start_separation": 6.0}, "start_separation"),
        ({"characterisation_interval": 0}, "characterisation_interval"),
        ({"stationary_speed": float("nan")}, "stationary_speed"),
        ({"charging_input": "charging"}, "charging_input: Input should be 'in_st"),
        ({"energy_mean_over": "steps"}, "energy_mean_over: Input should be 'trial'"),
        ({"stop_freezes_heading": 1}, "stop_freezes_heading: .* valid boolean, got 1"),
        ({"anchor_docked": "yes"}, "anchor_docked: .* valid boolean, got 'yes'"),
    ],
)
def test_bad_settings_are_named(overrides: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        ResourceSharingConfig(**overrides)
    with pytest.raises(ValueError, match=message):
        make_task("resource_sharing", **overrides)


def test_bad_genome_is_refused_before_running() -> None:
    task = ResourceSharing()
    with pytest.raises(ValueError, match="length 74"):
        run_batch(task, np.zeros((1, 74)), np.zeros((1, 1), dtype=np.int64))
    bad = np.zeros((1, 75))
    bad[0, 3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        run_batch(task, bad, np.zeros((1, 1), dtype=np.int64))


def test_unplaceable_team_is_refused_before_running() -> None:
    """Five robots 34 apart and from the station cannot start in a 60 arena (only
    its four corners are 34 from the centre), though the settings pass the
    quick checks."""
    task = make_task("resource_sharing", arena_size=60.0, n_robots=5)
    with pytest.raises(ValueError, match="no start for robot 4"):
        run_batch(task, np.zeros((1, 75)), np.zeros((1, 1), dtype=np.int64))


@pytest.mark.parametrize("anchor_docked", [False, True])
def test_a_trial_is_the_same_alone_in_a_batch_in_any_space_and_process(
    same_everywhere, anchor_docked: bool
) -> None:
    """A small arena where robots meet, and little energy, so trials end apart;
    also with docked robots anchored (their mass changes during the trial)."""
    same_everywhere(
        "resource_sharing",
        arena_size=40.0,
        start_separation=12.0,
        initial_energy=150.0,
        max_steps=150,
        anchor_docked=anchor_docked,
    )


def test_robots_crowding_the_station_never_sink_into_each_other() -> None:
    """Six robots of 40 trials steer for the station for 300 steps, robot i at
    speed 1 - 0.1 i: they pile up on it and push; robots 0 to 3 die on it (drain
    1.05 + 0.95 o0: at steps 250, 263, 277 and 292) and stay as obstacles. No
    robot overlaps another by more than 5% of its radius."""
    task = make_task("resource_sharing", n_robots=6, max_steps=300)
    r, turn = task.config.robot_radius, task.config.max_turn
    sim = BatchSimulation(task, np.arange(40))
    worst = -np.inf
    touching = 0
    while not sim.finished:
        bearing = sim.sensors()[..., 5] * np.pi
        out = np.zeros((sim.live.shape[0], 6, 3))
        out[..., 0] = 1.0 - 0.1 * np.arange(6)
        out[..., 1] = 0.5 + np.clip(bearing, -turn, turn) / (2 * turn)
        sim.step(out)
        pos = sim.bodies.position
        gap = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=-1)
        sink = 2 * r - gap[:, ~np.eye(6, dtype=bool)]
        touching += int((sink > -0.01).sum())
        worst = max(worst, float(sink.max()))
    assert touching > 10_000
    assert worst <= 2 * 0.05 * r  # each of the two robots sinks at most 5%
    assert np.all(np.count_nonzero(sim.trials.energy == 0.0, axis=1) == 4)


def wait_then_burn(task: ResourceSharing, waits: list[int], seeds: int) -> np.ndarray:
    """Fitness (len(waits), seeds) of teams whose robots all stand still for w
    steps, then drive straight at full speed until they die (never charging)."""
    w = np.repeat(np.array(waits), seeds)
    sim = BatchSimulation(task, np.tile(np.arange(seeds), len(waits)))
    while not sim.finished:
        go = (sim.step_count + 1 > w[sim.live])[:, None]
        out = np.zeros((sim.live.shape[0], 3, 3))
        out[..., 0] = np.where(go, 1.0, 0.0)
        out[..., 1] = 0.5
        out[..., 2] = np.where(go, 0.0, 1.0)
        sim.step(out)
    assert np.all(sim.length.reshape(len(waits), seeds)[0] == 345)
    return sim.fitness.reshape(len(waits), seeds)


def test_wait_then_burn_is_the_deceptive_optimum() -> None:
    """The module docstring's optimum, driven through the engine from 4 starts.

    Standing still for 200 steps leaves 500 - 1.05 x 200 = 290; full speed then
    drains 2 per step, so every robot dies at step 200 + 145 = 345, which ends the
    trial. Each robot's energy sums to sum_{k=1}^{200} (500 - 1.05 k)
    + sum_{j=1}^{145} (290 - 2 j) = 78895 + 20880 = 99775: e_bar = 99775 / 345
    and F = (0 + e_bar / 500) / 4 = 0.144601. Waiting one step less or more
    scores less; with energy_mean_over = max_steps the same team scores
    99775 / 500 / 2000 = 0.099775.
    """
    fitness = wait_then_burn(ResourceSharing(), [200, 199, 201], 4)
    np.testing.assert_allclose(fitness[0], NO_CHARGE_OPTIMUM, rtol=1e-12)
    assert pytest.approx(0.144601, abs=5e-7) == NO_CHARGE_OPTIMUM
    assert np.all(fitness[1:] < fitness[0])
    over_max_steps = make_task("resource_sharing", energy_mean_over="max_steps")
    fitness = wait_then_burn(over_max_steps, [200], 4)
    np.testing.assert_allclose(fitness[0], 99775 / 500 / 2000, rtol=1e-12)


def test_stop_freezes_the_heading_unless_told_otherwise(placed) -> None:
    """A stop output with a full left turn: the heading stays by default, and
    turns by max_turn (0.78) with stop_freezes_heading false."""
    for freezes, turned in ((True, 0.0), (False, 0.78)):
        task = placed(
            make_task("resource_sharing", stop_freezes_heading=freezes),
            [NORTH, WEST, [125.0, 75.0]],
            [0.0, 0.0, 0.0],
        )
        stepper = TrialStepper(task)
        stepper.reset(0)
        stepper.step(np.array([(0.0, 1.0, 1.0)] * 3))
        np.testing.assert_allclose(stepper.sim.bodies.angle[0], [turned] * 3)
        np.testing.assert_allclose(stepper.sim.bodies.position[0, 0], NORTH)


def test_charging_input_senses_the_station_or_the_charge(placed) -> None:
    """Robot 0 drives across the station centre at speed 1: by default its last
    input is 1 while its centre is within 1 of the station centre, moving or not;
    with charging_input = charged it stays -1 (it never charges)."""
    for cue, expected in (("in_station", [-1, 1, 1, -1]), ("charged", [-1] * 4)):
        task = placed(
            make_task("resource_sharing", charging_input=cue),
            [[73.5, 75.0], NORTH, WEST],
            [0.0, 0.0, 0.0],
        )
        stepper = TrialStepper(task)
        stepper.reset(0)
        seen = []
        for _ in range(4):
            # Before steps 1..4 robot 0 is at x = 73.5, 74.5, 75.5, 76.5:
            # 1.5, 0.5, 0.5, 1.5 from the station centre.
            seen.append(stepper.sensors()[0, 7])
            stepper.step(np.array([GO, STOP, STOP]))
        assert seen == expected


class ArrayResourceSharing(ResourceSharing):
    """The task with its station sensors and energy rules as whole-array numpy:
    the formulation the compiled loops replaced, kept as their oracle."""

    def sensors(self, trials: ResourceSharingTrials, bodies: BodyState) -> np.ndarray:
        out = super().sensors(trials, bodies)
        c = self.config
        k = c.n_robot_arcs
        pos = bodies.position
        cos_h, sin_h = bodies.cos_angle, bodies.sin_angle
        sx = self.station_centre[0] - pos[..., 0]
        sy = self.station_centre[1] - pos[..., 1]
        station = norm(sx, sy)
        out[..., k] = station * (2.0 / c.station_sensor_range) - 1.0
        out[..., k + 1] = bearing(sx, sy, cos_h, sin_h) * (1.0 / np.pi)
        out[..., k + 2] = trials.energy * (2.0 / c.max_energy) - 1.0
        if c.charging_input == "in_station":
            cue = station < c.docking_distance
        else:
            cue = trials.charging
        out[..., k + 3] = np.where(cue, 1.0, -1.0)
        return out

    def actuate(
        self, trials: ResourceSharingTrials, bodies: BodyState, outputs: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        alive = trials.energy > 0.0
        go = alive & (outputs[..., 2] <= c.stop_threshold)
        command = np.where(go, outputs[..., 0], 0.0)
        trials.command = command
        turning = go if c.stop_freezes_heading else alive
        turn = np.where(turning, (2.0 * outputs[..., 1] - 1.0) * c.max_turn, 0.0)
        return command * c.max_speed, turn

    def update(
        self, trials: ResourceSharingTrials, bodies: BodyState, step: int
    ) -> np.ndarray:
        c = self.config
        drain = c.min_energy_drain + (c.max_energy_drain - c.min_energy_drain) * (
            trials.command
        )
        energy = np.maximum(trials.energy - drain, 0.0, out=trials.energy)
        alive = energy > 0.0
        pos = bodies.position
        distance = norm(
            pos[..., 0] - self.station_centre[0], pos[..., 1] - self.station_centre[1]
        )
        speed = bodies.speed
        docked = alive & (distance < c.docking_distance) & (speed < c.stationary_speed)
        charging = docked & (trials.docked_steps >= c.charge_delay)
        trials.docked_steps = np.where(
            docked, np.minimum(trials.docked_steps + 1, c.charge_delay), 0
        )
        trials.charging = charging
        if c.anchor_docked:
            np.copyto(bodies.anchored, docked)
        np.minimum(
            energy + np.where(charging, c.charge_rate, 0.0), c.max_energy, out=energy
        )
        trials.energy_sum += robot_sum(energy)
        if step % c.characterisation_interval == 0:
            trials.samples += np.count_nonzero(alive, axis=1)
            trials.sampled_energy += robot_sum(energy * alive)
            trials.sampled_speed += robot_sum(speed * alive)
            trials.sampled_distance += robot_sum(distance * alive)
        return ~alive.any(axis=1)

    def task_state(
        self, trials: ResourceSharingTrials, bodies: BodyState
    ) -> tuple[GroupState, ...]:
        agents = bodies.kinematics(2)
        agents[..., 4] = trials.energy
        agents[..., 5] = trials.charging
        occupied = np.asarray(trials.charging.any(axis=1), np.float64)[:, None, None]
        _, station = super().task_state(trials, bodies)
        return (
            GroupState(
                present=trials.energy > 0.0,
                attributes=agents,
                centres=bodies.position.copy(),
                radii=self._radii,
            ),
            dataclasses.replace(station, attributes=occupied),
        )


@pytest.mark.parametrize("anchor_docked", [False, True])
@pytest.mark.parametrize("step", [1, 2])
def test_compiled_rules_equal_the_array_formulation(
    anchor_docked: bool, step: int
) -> None:
    """To the bit, over five steps of many trials: every trial array the rules
    write, the anchors and the ends, with robots dying, docking at exactly the
    docking distance and stationary speed, counting, charging to e_max, and
    samples taken every other step."""
    settings = {"anchor_docked": anchor_docked, "characterisation_interval": 2}
    task = make_task("resource_sharing", **settings)
    oracle = ArrayResourceSharing(ResourceSharingConfig(**settings))
    c = task.config
    rng = np.random.default_rng(step)
    b, n = 120, c.n_robots
    got, _, _ = task.reset([np.random.default_rng(t) for t in range(b)])
    got.energy[:] = rng.choice([0.0, 1.0, 2.5, 300.0, 495.0, 500.0], (b, n))
    got.docked_steps[:] = rng.integers(0, c.charge_delay + 1, (b, n))
    want = copy.deepcopy(got)
    rows = np.zeros((b, n, 5))
    near = rng.random((b, n)) < 0.6
    offset = np.where(near, rng.choice([0.0, 0.5, c.docking_distance], (b, n)), 30.0)
    rows[..., 0] = CENTRE[0] + offset
    rows[..., 1] = CENTRE[1]
    rows[..., 3] = rng.choice([0.0, 0.0005, c.stationary_speed, 0.5], (b, n))
    rows[..., 4] = rng.choice([0.0, 0.0004, -0.0007], (b, n))
    got_bodies = BodyState.at_rest(rows[..., 0:2], np.zeros((b, n)))
    got_bodies.velocity[..., 0] = rows[..., 3]
    want_bodies = copy.deepcopy(got_bodies)
    for k in range(step, step + 5):
        command = rng.choice([0.0, 0.3, 1.0], (b, n))
        got.command = command.copy()
        want.command = command.copy()
        np.testing.assert_array_equal(
            task.update(got, got_bodies, k), oracle.update(want, want_bodies, k)
        )
        assert_same_trials(got, want)
        np.testing.assert_array_equal(got_bodies.anchored, want_bodies.anchored)
    assert got.charging.any() and not got.charging.all()
    assert (got.energy == 0.0).any() and (got.energy == c.max_energy).any()


@pytest.mark.parametrize("charging_input", ["in_station", "charged"])
def test_compiled_station_sensors_equal_the_array_formulation(
    charging_input: str,
) -> None:
    """To the bit: the station distance, bearing, energy and station flag, with
    robots exactly at the docking distance, on the station centre and far out."""
    settings = {"charging_input": charging_input}
    task = make_task("resource_sharing", **settings)
    oracle = ArrayResourceSharing(ResourceSharingConfig(**settings))
    c = task.config
    rng = np.random.default_rng(9)
    b, n = 90, c.n_robots
    trials, _, _ = task.reset([np.random.default_rng(t) for t in range(b)])
    trials.energy[:] = rng.choice([0.0, 1.0, 250.0, c.max_energy], (b, n))
    trials.charging[:] = rng.random((b, n)) < 0.3
    offset = rng.choice([0.0, 0.5, c.docking_distance, 30.0, 200.0], (b, n))
    rows = np.zeros((b, n, 5))
    rows[..., 0] = CENTRE[0] + offset
    rows[..., 1] = CENTRE[1] - offset * rng.choice([0.0, 1.0], (b, n))
    heading = rng.uniform(-math.pi, math.pi, (b, n))
    bodies = BodyState.at_rest(rows[..., 0:2], heading)
    np.testing.assert_array_equal(
        task.sensors(trials, bodies), oracle.sensors(trials, bodies)
    )


@pytest.mark.parametrize("freezes", [True, False])
def test_compiled_commands_equal_the_array_formulation(freezes: bool) -> None:
    """To the bit: the speed commands, speeds and turns of dead and living robots
    told to go, to stop, and exactly at the stop threshold."""
    settings = {"stop_freezes_heading": freezes}
    task = make_task("resource_sharing", **settings)
    oracle = ArrayResourceSharing(ResourceSharingConfig(**settings))
    rng = np.random.default_rng(4)
    b, n = 90, task.config.n_robots
    got, _, _ = task.reset([np.random.default_rng(t) for t in range(b)])
    got.energy[:] = rng.choice([0.0, 1.0, 500.0], (b, n))
    want = copy.deepcopy(got)
    outputs = rng.uniform(0.0, 1.0, (b, n, 3))
    outputs[..., 1] = np.where(rng.random((b, n)) < 0.3, 0.5, outputs[..., 1])
    outputs[..., 2] = np.where(
        rng.random((b, n)) < 0.3, task.config.stop_threshold, outputs[..., 2]
    )
    bodies = BodyState.at_rest(np.zeros((b, n, 2)), np.zeros((b, n)))
    for got_array, want_array in zip(
        task.actuate(got, bodies, outputs),
        oracle.actuate(want, bodies, outputs),
        strict=True,
    ):
        assert same_bits(got_array, want_array)
    assert same_bits(got.command, want.command)


def test_compiled_task_state_equals_the_array_formulation() -> None:
    """To the bit: every array of both groups, with dead, charging and moving
    robots, and trials with and without a charging robot, positions and
    velocities read from strided state rows as the engine passes them."""
    task = make_task("resource_sharing")
    oracle = ArrayResourceSharing(ResourceSharingConfig())
    rng = np.random.default_rng(5)
    b, n = 90, task.config.n_robots
    trials, _, _ = task.reset([np.random.default_rng(t) for t in range(b)])
    trials.energy[:] = rng.choice([0.0, 1.0, 500.0], (b, n))
    trials.charging[:] = rng.random((b, n)) < 0.2
    rows = rng.normal(75.0, 30.0, (b, n, 5))
    bodies = BodyState.at_rest(rows[..., 0:2], rows[..., 2])
    bodies.velocity = rows[..., 3:5]
    bodies.angular_velocity = rng.uniform(-0.78, 0.78, (b, n))
    for got, want in zip(
        task.task_state(trials, bodies), oracle.task_state(trials, bodies), strict=True
    ):
        for field in dataclasses.fields(got):
            a, w = getattr(got, field.name), getattr(want, field.name)
            assert (a is None and w is None) or same_bits(a, w), field.name
    assert 0 < trials.charging.any(axis=1).sum() < b
