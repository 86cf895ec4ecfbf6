"""The sensor-effector baselines by hand, and the engine's network observers: they
get the network's own inputs and outputs and change no result."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from sdbc_evolution.characterise.registry import parse
from sdbc_evolution.characterise.sensor_effector import (
    SensorEffectorMean,
    StateCount,
    StateCountOptions,
)
from sdbc_evolution.sdbc.characterisation import SdbcExtractor
from sdbc_sim.engine import run_batch
from sdbc_sim.network import TeamNetworks
from sdbc_sim.observer import NetworkObserver
from sdbc_sim.tasks import make_task

# A team of 2 robots, 2 sensors in [-1, 1], 1 effector in [0, 1].
TASK = SimpleNamespace(network=SimpleNamespace(n_inputs=2, n_outputs=1))


def feed(characteriser, steps) -> np.ndarray:
    """Two trials of one controller each; ``steps`` lists (trials, inputs,
    outputs, enabled) as the engine hands them."""
    characteriser.start(None, 2)
    for trials, inputs, outputs, enabled in steps:
        characteriser.observe_network(
            np.array(trials), np.array(inputs), np.array(outputs), np.array(enabled)
        )
    return characteriser.controller_vectors(None, 1)


STEPS = [
    # Both trials; trial 1's second robot is out of play.
    (
        [0, 1],
        [[[-0.5, 0.5], [0.2, -0.9]], [[0.9, 0.9], [0.0, 0.0]]],
        [[[0.1], [0.7]], [[0.6], [0.2]]],
        [[True, True], [True, False]],
    ),
    # Only trial 0 is still running.
    ([0], [[[-0.5, 0.5], [-1.0, 1.0]]], [[[0.1], [1.0]]], [[True, True]]),
]


def test_state_count_by_hand() -> None:
    got = feed(StateCount(StateCountOptions(levels=2)), STEPS)
    # State index = s1 + 2 s2 + 4 e with each value's bin (0 or 1): 8 states.
    # Trial 0: (0,1,0)=2, (1,0,1)=5, (0,1,0)=2, (0,1,1)=6 -> 2:2, 5:1, 6:1 of 4.
    # Trial 1: (1,1,1)=7 -> 7:1 of 1 (the robot out of play does not count).
    expected = np.zeros((2, 8))
    expected[0, [2, 5, 6]] = [0.5, 0.25, 0.25]
    expected[1, 7] = 1.0
    np.testing.assert_array_equal(got, expected)
    assert StateCount().names(TASK) == tuple(f"State {s}" for s in range(8))


def test_state_count_hashes_into_buckets_when_states_are_many() -> None:
    characteriser = StateCount(StateCountOptions(levels=2, max_states=4))
    got = feed(characteriser, STEPS)
    assert got.shape == (2, 4)
    np.testing.assert_allclose(got.sum(axis=1), 1.0)
    assert characteriser.names(TASK)[0] == "State bucket 0"
    again = feed(StateCount(StateCountOptions(levels=2, max_states=4)), STEPS)
    np.testing.assert_array_equal(got, again)


def test_sensor_effector_mean_by_hand() -> None:
    got = feed(SensorEffectorMean(), STEPS)
    trial0 = np.array(
        [[-0.5, 0.5, 0.1], [0.2, -0.9, 0.7], [-0.5, 0.5, 0.1], [-1.0, 1.0, 1.0]]
    ).mean(axis=0)
    np.testing.assert_allclose(got, [trial0, [0.9, 0.9, 0.6]], rtol=1e-12)
    assert SensorEffectorMean().names(TASK) == (
        "Sensor 1 (mean)",
        "Sensor 2 (mean)",
        "Effector 1 (mean)",
    )


class NetworkRecorder:
    def start(self, description, n_trials: int) -> None:
        self.calls = []

    def observe(self, state) -> None:
        pass

    def observe_network(self, trials, inputs, outputs, enabled) -> None:
        self.calls.append((trials.copy(), inputs.copy(), outputs.copy()))


def test_network_observers_get_the_network_arrays_and_change_nothing() -> None:
    task = make_task("gate_escape", max_steps=40)
    genomes = np.random.default_rng(0).uniform(-1, 1, (3, task.genome_length))
    seeds = np.arange(6, dtype=np.int64).reshape(3, 2)
    plain = SdbcExtractor()
    baseline = run_batch(task, genomes, seeds, observers=(plain,))
    recorder = NetworkRecorder()
    assert isinstance(recorder, NetworkObserver)
    observed = SdbcExtractor()
    extra = (recorder, StateCount(), SensorEffectorMean())
    result = run_batch(task, genomes, seeds, observers=(observed, *extra))
    np.testing.assert_array_equal(result.fitness, baseline.fitness)
    np.testing.assert_array_equal(result.characterisation, baseline.characterisation)
    np.testing.assert_array_equal(
        observed.characterisations(), plain.characterisations()
    )
    assert len(recorder.calls) == int(result.length.max())
    for trials, inputs, outputs in recorder.calls:
        teams = TeamNetworks(task.network, np.repeat(genomes, 2, axis=0)[trials])
        np.testing.assert_array_equal(teams.forward(inputs), outputs)
    # Trials drop out of the calls once they have ended.
    for step, (trials, _, _) in enumerate(recorder.calls, start=1):
        assert set(trials) == set(np.flatnonzero(result.length.reshape(-1) >= step))


def test_registry_builds_fresh_characterisers() -> None:
    spec = parse({"state_count": {"levels": 3}})
    assert spec.key == "state_count{levels=3}" and spec.needs_network
    assert spec.build() is not spec.build()
    assert not parse("sdbc").needs_network
