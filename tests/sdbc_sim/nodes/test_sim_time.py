"""Simulated time and poses: with ``use_sim_time`` a recorded trial's bag advances
by the step period per step, with ``/clock`` in it, and the bodies' poses carry
their headings (also as marker arrows)."""

from __future__ import annotations

import math
import signal
import time
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.ros

TASK = "gate_escape"
MAX_STEPS = 25
STEP_PERIOD = 0.25
STEP_NS = 250_000_000
TIMEOUT = 60.0
RECORDED = ("/clock", "/task_state", "/poses", "/robot_0/sensors", "/robot_0/command")


def record_a_trial(
    tmp_path: Path, start_node, test_node, seed: int
) -> tuple[Path, object]:
    """Runs one trial with simulated time on every node and a recorder; returns
    the bag and the trial's answer."""
    from sdbc_sim.nodes.interface import LATCHED_QOS
    from sdbc_sim.tasks import make_task
    from std_msgs.msg import Bool

    from sdbc_msgs.srv import RunTrial

    genome = np.random.default_rng(0).uniform(-1, 1, make_task(TASK).genome_length)
    ros = ["--ros-args", "-p", "use_sim_time:=true", "-p", f"task:={TASK}"]
    ros += ["-p", f"task_config:='{{max_steps: {MAX_STEPS}}}'"]
    bag = tmp_path / "bag"
    nodes = {
        "simulator": start_node(
            "sdbc_sim.nodes.simulator_node",
            *ros,
            "-p",
            f"step_period:={STEP_PERIOD}",
        ),
        "controllers": start_node(
            "sdbc_sim.nodes.controller_node",
            "--robots",
            "0",
            "1",
            "2",
            "3",
            *ros,
            "-p",
            "genome:=[" + ",".join(map(repr, genome.tolist())) + "]",
        ),
    }
    recorder = start_node(
        "sdbc_evolution.nodes.recorder_node",
        "--output",
        str(bag),
        "--topics",
        *RECORDED,
        "--ros-args",
        "-p",
        "use_sim_time:=true",
    )
    node, executor = test_node
    ready: list[bool] = []
    node.create_subscription(Bool, "/recorder/ready", ready.append, LATCHED_QOS)
    try:
        deadline = time.monotonic() + TIMEOUT
        while not ready:
            processes = [*nodes.values(), recorder]
            assert all(p.poll() is None for p in processes), "a node ended early"
            assert time.monotonic() < deadline, "the recorder was never ready"
            executor.spin_once(timeout_sec=0.1)
        client = node.create_client(RunTrial, "/run_trial")
        assert client.wait_for_service(timeout_sec=TIMEOUT)
        future = client.call_async(RunTrial.Request(seed=seed, task=TASK))
        executor.spin_until_future_complete(future, timeout_sec=TIMEOUT)
        answer = future.result()
    finally:
        # The recorder last, so that it gets everything the others sent.
        for process in nodes.values():
            process.send_signal(signal.SIGINT)
        outputs = [p.communicate(timeout=60)[0] for p in nodes.values()]
        recorder.send_signal(signal.SIGINT)
        outputs.append(recorder.communicate(timeout=60)[0])
    assert answer is not None and answer.success, (answer, outputs)
    return bag, answer


def test_a_recorded_trial_advances_by_the_step_period_per_step(
    tmp_path, start_node, test_node
):
    from rosbags.highlevel import AnyReader

    bag, answer = record_a_trial(tmp_path, start_node, test_node, seed=4)
    length = answer.length
    times: dict[str, list[int]] = {}
    stamps: dict[str, list[int]] = {}
    poses = []
    with AnyReader([bag]) as reader:
        for connection, timestamp, raw in reader.messages():
            message = reader.deserialize(raw, connection.msgtype)
            times.setdefault(connection.topic, []).append(timestamp)
            header = getattr(message, "header", None)
            stamp = header.stamp if header is not None else message.clock
            stamps.setdefault(connection.topic, []).append(
                stamp.sec * 1_000_000_000 + stamp.nanosec
            )
            if connection.topic == "/poses":
                poses.append(message)
    assert set(times) == set(RECORDED)
    # The trial's timeline: step k's task state at T0 + k * step period, in the
    # bag and in its stamp.
    ticks = times["/task_state"]
    assert len(ticks) == length
    start = ticks[0] - STEP_NS
    assert ticks == [start + k * STEP_NS for k in range(1, length + 1)]
    assert stamps["/task_state"] == ticks
    # /clock ticks once at the trial's start and once per step.
    assert stamps["/clock"] == [start + k * STEP_NS for k in range(length + 1)]
    # Readings for step k carry the time before it; the commands answer at it.
    sensors = [start + k * STEP_NS for k in range(length)]
    assert stamps["/robot_0/sensors"] == sensors
    assert stamps["/robot_0/command"] == sensors
    assert times["/robot_0/command"] == sensors
    # One pose per body per step, headings as unit quaternions about z.
    assert len(poses) == length
    assert all(len(p.poses) == 4 and p.header.frame_id == "arena" for p in poses)
    q = poses[-1].poses[0].orientation
    assert (q.x, q.y) == (0.0, 0.0)
    assert math.isclose(q.z**2 + q.w**2, 1.0)


def test_poses_and_marker_arrows_show_each_bodys_heading():
    from sdbc_sim.engine import TrialStepper
    from sdbc_sim.nodes.markers import (
        HEADING_NS,
        body_poses,
        markers_from_task_state,
    )
    from sdbc_sim.task_state_msgs import task_state_to_msg
    from sdbc_sim.tasks import make_task
    from visualization_msgs.msg import Marker

    task = make_task("predator_prey")
    stepper = TrialStepper(task)
    stepper.reset(5)
    stepper.step(np.full((task.layout.n_controlled, task.network.n_outputs), 0.7))
    state = task_state_to_msg(stepper.state(), task.description, 0, 1, task.name, False)
    bodies = stepper.sim.bodies
    poses = body_poses(state.header, bodies.position[0], bodies.angle[0])
    assert len(poses.poses) == task.layout.n_bodies
    for pose, (x, y), angle in zip(
        poses.poses, bodies.position[0], bodies.angle[0], strict=True
    ):
        assert (pose.position.x, pose.position.y) == (x, y)
        heading = 2.0 * math.atan2(pose.orientation.z, pose.orientation.w)
        assert math.isclose(math.cos(heading), math.cos(angle), abs_tol=1e-12)
        assert math.isclose(math.sin(heading), math.sin(angle), abs_tol=1e-12)
    markers = markers_from_task_state(state, poses, task.layout.radii).markers
    arrows = [m for m in markers if m.ns == HEADING_NS]
    assert [m.type for m in arrows] == [Marker.ARROW] * task.layout.n_bodies
    assert [m.scale.x for m in arrows] == [2.0 * r for r in task.layout.radii]
    assert all(
        m.pose.orientation == p.orientation
        for m, p in zip(arrows, poses.poses, strict=True)
    )
    assert all(p.position.z == 0.0 for p in poses.poses)  # arrows lifted, not poses
