"""Aggregation rules, sensors and results against hand-computed numbers.

STOP holds a robot still (o2 = 1 > 0.5), GO drives it straight at full speed (1 per
step, no turn); a robot moves in the step it is commanded.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from sdbc_evolution.sdbc.characterisation import SdbcExtractor
from sdbc_sim.engine import TrialStepper, run_batch
from sdbc_sim.tasks import make_task
from sdbc_sim.tasks.aggregation import Aggregation, AggregationConfig

STOP = (0.0, 0.5, 1.0)
GO = (1.0, 0.5, 0.0)
U_MAX = 2 * (250 - 2 * 2.5) ** 2 / 2
"""Two robots' largest sum of squared distances to their centroid, N L^2 / 2 with
L = 250 - 2 r the side their centres can reach (the 4 r^2 of u cancels in F)."""


def drive(task: Aggregation, outputs: list[tuple[float, float, float]]):
    """Runs one trial with constant outputs; returns its result."""
    stepper = TrialStepper(task)
    stepper.reset(0)
    while not stepper.done:
        stepper.step(np.array(outputs))
    return stepper.result()


def test_a_still_pair_scores_its_spread(placed) -> None:
    """Two still robots 50 apart: u(t) = 2 x 25^2 at every step, so the time
    weights cancel, F = 1 - 1250 / U_MAX, and each sample reads 25 / 250."""
    task = placed(
        make_task("aggregation", n_robots=2, max_steps=4, sample_interval=2),
        [[100.0, 100.0], [150.0, 100.0]],
        [0.0, 0.0],
    )
    fitness, characterisation, length = drive(task, [STOP, STOP])
    assert length == 4
    assert fitness == pytest.approx(1 - 1250 / U_MAX, abs=1e-15)
    np.testing.assert_allclose(characterisation, [0.1, 0.1], atol=1e-15)


def test_closing_in_weighs_later_steps_more(placed) -> None:
    """Two robots 50 apart drive at each other: 50 - 2 t apart after step t, each
    25 - t from the centroid, u(t) = 2 (25 - t)^2; c = sum_{t=1}^{10} t u(t),
    F = 1 - c / (U_MAX x 55); samples at steps 5 and 10: 20 / 250 and 15 / 250."""
    task = placed(
        make_task("aggregation", n_robots=2, max_steps=10, sample_interval=5),
        [[100.0, 100.0], [150.0, 100.0]],
        [0.0, math.pi],
    )
    fitness, characterisation, length = drive(task, [GO, GO])
    c = sum(t * 2 * (25 - t) ** 2 for t in range(1, 11))
    assert length == 10
    assert fitness == pytest.approx(1 - c / (U_MAX * 55), abs=1e-12)
    np.testing.assert_allclose(characterisation, [0.08, 0.06], atol=1e-12)


def test_sensors_by_hand(placed) -> None:
    """Robot 0 at (100, 100) facing +x; robot 1 30 ahead (25 edge to edge);
    robot 2 at (5, 100) facing the left wall, 95 from robot 0."""
    task = placed(
        make_task("aggregation", n_robots=3),
        [[100.0, 100.0], [130.0, 100.0], [5.0, 100.0]],
        [0.0, 0.0, math.pi],
    )
    stepper = TrialStepper(task)
    stepper.reset(0)
    x = stepper.sensors()
    assert x.shape == (3, 9)
    # Arcs back, right, ahead, left: robot 1 ahead reads 2 x 25 / 50 - 1 = 0; one
    # robot of two in range: 2 x 1 / 2 - 1 = 0; no wall within reach.
    np.testing.assert_allclose(x[0], [1, 1, 0, 1, 0, 1, 1, 1, 1], atol=1e-12)
    # Robot 1 sees robot 0 behind it.
    np.testing.assert_allclose(x[1], [0, 1, 1, 1, 0, 1, 1, 1, 1], atol=1e-12)
    # Robot 2 sees nobody (count 0 reads -1); its two front rays, at -+45 degrees
    # from heading pi, start at its edge and cross x = 0 after 5 sqrt(2) - 2.5.
    ray = 2 * (5 * math.sqrt(2) - 2.5) / 5 - 1
    np.testing.assert_allclose(x[2], [1, 1, 1, 1, -1, ray, ray, 1, 1], atol=1e-12)


def test_random_starts_keep_their_distances() -> None:
    task = Aggregation()
    trials, position, angle = task.reset([np.random.default_rng(s) for s in range(200)])
    assert np.all((position >= 2.5) & (position <= 247.5))
    gaps = np.linalg.norm(position[:, :, None] - position[:, None], axis=-1)
    assert np.all(gaps[:, ~np.eye(8, dtype=bool)] >= 20.0)
    assert np.all((angle >= -np.pi) & (angle < np.pi))
    assert trials.samples.shape == (200, 20) and not trials.weighted_cost.any()


def test_description_and_characterisations() -> None:
    task = make_task("aggregation")
    assert [g.name for g in task.description.groups] == ["Agent", "Wall"]
    assert task.genome_length == 68
    assert len(task.characterisation_names) == 20
    assert task.characterisation_names[-1].endswith("at step 500")
    extractor = SdbcExtractor()
    rng = np.random.default_rng(3)
    result = run_batch(
        task, rng.uniform(-1, 1, (3, 68)), np.arange(6).reshape(3, 2), [extractor]
    )
    assert len(extractor.dimension_names) == 13
    assert np.all((result.fitness >= 0) & (result.fitness <= 1))
    c = result.characterisation
    assert np.all((c >= 0) & (c <= 1))
    np.testing.assert_array_equal(result.length, 500)


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"n_robots": 1}, "n_robots: Input should be greater than or equal to 2"),
        ({"max_steps": 510}, "max_steps: 510 must be a multiple of sample_interval"),
        ({"robot_radius": float("nan")}, "robot_radius: "),
        ({"n_hidden": 2.5}, "n_hidden: Input should be a valid integer"),
        ({"max_speed": 3.0}, "pass through walls"),
        ({"start_separation": 4.0}, "start_separation"),
        ({"arena_size": 30.0}, "too small for its robots"),
        ({"stop_threshold": 1.5}, "stop_threshold"),
    ],
)
def test_bad_settings_are_named(overrides: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        AggregationConfig(**overrides)
    with pytest.raises(ValueError, match=message):
        make_task("aggregation", **overrides)


def test_a_trial_is_the_same_alone_in_a_batch_in_any_space_and_process(
    same_everywhere,
) -> None:
    """A small arena where robots meet; every trial runs to max_steps."""
    same_everywhere(
        "aggregation",
        ends_apart=False,
        arena_size=60.0,
        start_separation=6.0,
        max_steps=150,
    )


@pytest.mark.parametrize("name", ["aggregation", "foraging"])
def test_sdbc_vector_alone_equals_it_in_a_batch(name: str) -> None:
    """Groups of 8 or more entities (8 agents, 28 agent pairs; 15 items): the
    SDBC's sums over slots run in one order whatever the batch (numpy's own
    reduction summed a lone trial's contiguous slots pairwise, and the last bits
    differed)."""
    task = make_task(name, max_steps=100)
    rng = np.random.default_rng(1)
    genomes = rng.uniform(-1, 1, (3, task.genome_length))
    seeds = rng.integers(0, 2**31, (3, 3))
    batch = SdbcExtractor()
    run_batch(task, genomes, seeds, [batch])
    for g, t in [(0, 0), (2, 2)]:
        alone = SdbcExtractor()
        run_batch(task, genomes[g : g + 1], seeds[g : g + 1, t : t + 1], [alone])
        np.testing.assert_array_equal(
            alone.characterisations()[0], batch.characterisations()[3 * g + t]
        )
