"""The live graph, nodes in separate processes: equivalence with the batched engine,
bad genomes, bad requests, and a controller killed in the middle of a trial."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

pytestmark = pytest.mark.ros

EQUIVALENCE_TOLERANCE = 1e-9
SEEDS = np.array([1, 2, 3], dtype=np.int64)


def batched(live, genome: np.ndarray, seeds: np.ndarray):
    """The batched engine's evaluation of ``genome`` in ``seeds`` (the local
    evaluator's code path, SDBC extractor included)."""
    from sdbc_evolution.run.evaluators import TaskSpec, evaluate_chunk

    spec = TaskSpec(live.task_name, live.task_config)
    return evaluate_chunk(spec, genome[None], seeds[None])


def assert_same_evaluation(got, expected) -> None:
    for field in ("fitness", "trial_fitness", "characterisation", "sdbc"):
        np.testing.assert_allclose(
            getattr(got, field),
            getattr(expected, field),
            rtol=0.0,
            atol=EQUIVALENCE_TOLERANCE,
            err_msg=field,
        )


def test_a_genome_evaluated_live_equals_the_batched_engine(gate_escape_graph):
    from sdbc_evolution.graph.live_evaluator import LiveEvaluator
    from sdbc_evolution.run.evaluators import TaskSpec

    live = gate_escape_graph
    evaluator = LiveEvaluator(TaskSpec(live.task_name, live.task_config), live.client)
    got = evaluator.evaluate(live.genome[None], SEEDS[None])
    expected = batched(live, live.genome, SEEDS)
    assert_same_evaluation(got, expected)
    # Not a vacuous comparison: robots escaped and trials ended at different steps.
    assert expected.characterisation[0, 0] > 0.0
    assert got.sdbc.shape == (1, 21)
    lengths = {live.client.run_trial(int(s)).length for s in SEEDS}
    assert len(lengths) > 1


def test_a_declared_sdbc_evaluated_live_equals_the_batched_engine(gate_escape_graph):
    from sdbc_evolution.characterise.registry import parse
    from sdbc_evolution.graph.live_evaluator import LiveEvaluator
    from sdbc_evolution.run.evaluators import TaskSpec, evaluate_chunk

    live = gate_escape_graph
    declared = parse({"sdbc": {"aggregation": {"frames": 3}, "state_deviation": True}})
    spec = TaskSpec(live.task_name, live.task_config, characterisations=(declared,))
    got = LiveEvaluator(spec, live.client).evaluate(live.genome[None], SEEDS[None])
    expected = evaluate_chunk(spec, live.genome[None], SEEDS[None])
    assert_same_evaluation(got, expected)
    np.testing.assert_allclose(
        got.behaviour(declared.key),
        expected.behaviour(declared.key),
        rtol=0.0,
        atol=EQUIVALENCE_TOLERANCE,
    )
    counted = TaskSpec(
        live.task_name, live.task_config, characterisations=(parse("state_count"),)
    )
    with pytest.raises(ValueError, match=r"'state_count' cannot be made on the live"):
        LiveEvaluator(counted, live.client)


def test_a_bad_genome_is_rejected_with_a_reason_and_the_controller_keeps_running(
    gate_escape_graph,
):
    from sdbc_evolution.graph.client import GenomeRejected

    live = gate_escape_graph
    client = live.client
    with pytest.raises(GenomeRejected) as short:
        client.set_genome(live.genome[:-1])
    assert "107 values" in short.value.reason and "108" in short.value.reason
    with_nan = live.genome.copy()
    with_nan[17] = np.nan
    with pytest.raises(GenomeRejected) as nan:
        client.set_genome(with_nan)
    assert "non-finite" in nan.value.reason and "[17] = nan" in nan.value.reason
    # Each controller kept the genome it had and still answers: a trial runs and
    # matches the engine.
    trial = client.run_trial(int(SEEDS[0]))
    expected = batched(live, live.genome, SEEDS[:1])
    assert abs(trial.fitness - expected.trial_fitness[0, 0]) <= EQUIVALENCE_TOLERANCE
    np.testing.assert_allclose(trial.sdbc, expected.sdbc[0], atol=EQUIVALENCE_TOLERANCE)
    assert live.graph.exited() == {}


def call_run_trial(live, **request):
    """Calls the simulator's run_trial service directly; returns the future."""
    from sdbc_msgs.srv import RunTrial

    return live.client._run_trial.call_async(RunTrial.Request(**request))


def wait_for(future, timeout: float = 60.0):
    deadline = time.monotonic() + timeout
    while not future.done():
        assert time.monotonic() < deadline, "no answer from the simulator"
        time.sleep(0.01)
    return future.result()


def test_bad_trial_requests_are_refused_with_a_reason(gate_escape_graph):
    live = gate_escape_graph
    other = wait_for(call_run_trial(live, task="predator_prey", seed=1))
    assert not other.success
    assert "gate_escape" in other.message and "predator_prey" in other.message
    negative = wait_for(call_run_trial(live, seed=-5))
    assert not negative.success and "seed" in negative.message


def test_a_controller_killed_mid_trial_aborts_the_trial_naming_it_and_the_next_works(
    gate_escape_graph,
):
    from sdbc_sim.nodes.interface import TASK_STATE_QOS

    from sdbc_msgs.msg import TaskState

    live = gate_escape_graph
    trial_id = 4242
    started = threading.Event()

    def watch(msg) -> None:
        if msg.trial_id == trial_id and msg.step >= 10:
            started.set()

    watcher = live.node.create_subscription(
        TaskState, "task_state", watch, TASK_STATE_QOS
    )
    try:
        future = call_run_trial(live, seed=int(SEEDS[1]), trial_id=trial_id)
        assert started.wait(60.0), "the trial did not start\n" + live.logs()
        live.graph.kill("controller 2")
        answer = wait_for(future)
    finally:
        live.node.destroy_subscription(watcher)
    assert not answer.success
    assert "robot 2" in answer.message and "/robot_2/command" in answer.message
    assert f"trial {trial_id}" in answer.message
    # The simulator survived; with the controller restarted, the next trial runs
    # whole and equals the engine's.
    assert "simulator" not in live.graph.exited()
    live.graph.start("controller 2")
    live.client.wait_for_graph()
    trial = live.client.run_trial(int(SEEDS[1]))
    expected = batched(live, live.genome, SEEDS[1:2])
    assert abs(trial.fitness - expected.trial_fitness[0, 0]) <= EQUIVALENCE_TOLERANCE
    np.testing.assert_allclose(trial.sdbc, expected.sdbc[0], atol=EQUIVALENCE_TOLERANCE)
