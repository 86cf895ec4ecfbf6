"""The characteriser node characterises a task our engine does not have, published
by another process: for every trial, interleaved ones and one that never sends done,
it publishes the library's vector, names included."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.ros

HERE = Path(__file__).parent
TRIAL_TIMEOUT = 5.0
WAIT = 180.0
"""Seconds the test waits for every characterisation on a loaded machine."""


def stop(process: subprocess.Popen) -> int:
    process.send_signal(signal.SIGINT)
    try:
        return process.wait(timeout=20)
    except subprocess.TimeoutExpired:
        process.kill()
        return process.wait()


def expected_vectors() -> tuple[dict[int, np.ndarray], tuple[str, ...]]:
    from sdbc_evolution.sdbc.messages import MessageSdbcExtractor

    sys.path.insert(0, str(HERE))
    from outside_publisher import WITHOUT_DONE, scripted_trials

    extractor = MessageSdbcExtractor()
    vectors = {}
    for msg in scripted_trials(with_gap=False):
        vector = extractor.add(msg)
        if vector is not None:
            vectors[msg.trial_id] = vector
    vectors[WITHOUT_DONE] = extractor.close(WITHOUT_DONE)
    return vectors, extractor.dimension_names


def test_characteriser_on_an_outside_publisher(tmp_path, ros_home) -> None:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from sdbc_sim.nodes.interface import CHARACTERISATION_QOS

    from sdbc_msgs.msg import Characterisation

    sys.path.insert(0, str(HERE))
    from outside_publisher import GAP, TASK, TRIALS, WITHOUT_DONE

    expected, names = expected_vectors()
    assert "Drone-buoy distance (M)" in names and "Drone-intruder distance (F)" in names
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    logs = {name: (tmp_path / f"{name}.log").open("w") for name in ("node", "pub")}
    characteriser = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "sdbc_evolution.nodes.characteriser_node",
            "--ros-args",
            "-p",
            f"trial_timeout:={TRIAL_TIMEOUT}",
        ],
        env=env,
        stdout=logs["node"],
        stderr=subprocess.STDOUT,
    )
    publisher = subprocess.Popen(
        [sys.executable, str(HERE / "outside_publisher.py")],
        env=env,
        stdout=logs["pub"],
        stderr=subprocess.STDOUT,
    )
    received: dict[int, Characterisation] = {}
    context = rclpy.Context()
    rclpy.init(context=context)
    node = Node("characterisation_listener", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        node.create_subscription(
            Characterisation,
            "characterisation",
            lambda m: received.setdefault(m.trial_id, m),
            CHARACTERISATION_QOS,
        )
        deadline = time.monotonic() + WAIT
        while len(received) < len(TRIALS) and time.monotonic() < deadline:
            assert characteriser.poll() is None, "the characteriser died"
            executor.spin_once(timeout_sec=0.2)
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        publisher_code, node_code = stop(publisher), stop(characteriser)
        for log in logs.values():
            log.close()
    node_log = (tmp_path / "node.log").read_text()
    assert sorted(received) == sorted(TRIALS), node_log
    publisher_log = (tmp_path / "pub.log").read_text()
    assert (publisher_code, node_code) == (0, 0), (
        f"publisher:\n{publisher_log}\ncharacteriser:\n{node_log}"
    )
    for trial_id, msg in received.items():
        assert msg.task == TASK
        assert msg.aggregation == "mean+final"
        assert tuple(msg.dimension_names) == names
        assert msg.complete == (trial_id != WITHOUT_DONE)
        assert msg.length == TRIALS[trial_id]
        np.testing.assert_allclose(
            np.asarray(msg.values), expected[trial_id], rtol=0, atol=1e-12
        )
    assert f"trial {WITHOUT_DONE}: no message for" in node_log
    # The trial that lost a step is dropped with the reason, never published.
    assert f"trial {GAP[0]} dropped, not characterised" in node_log
    assert f"step {GAP[2] + 1} follows step {GAP[2] - 1}" in node_log
    assert "published as incomplete" in node_log


def test_an_unknown_aggregation_is_refused(ros_home) -> None:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "sdbc_evolution.nodes.characteriser_node",
            "--ros-args",
            "-p",
            "aggregation:=median",
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    assert "parameter aggregation: 'median' is not one of mean+final" in done.stderr
