"""A controller node started alone from the command line: ROS arguments honoured,
outputs equal to the engine's network to the bit, bad start-up input refused."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import numpy as np
import pytest

pytestmark = pytest.mark.ros

TASK = "predator_prey"


def controller_command(*ros_args: str) -> list[str]:
    return [
        sys.executable,
        "-m",
        "sdbc_sim.nodes.controller_node",
        "--ros-args",
        *ros_args,
    ]


def environment(ros_home) -> dict[str, str]:
    return {
        **os.environ,
        "ROS_HOME": str(ros_home),
        "PYTHONPATH": os.pathsep.join(p for p in sys.path if p),
    }


def test_a_controller_alone_answers_with_the_engines_network_outputs(ros_home):
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from sdbc_sim.network import forward
    from sdbc_sim.nodes.interface import LOCKSTEP_QOS
    from sdbc_sim.tasks import make_task

    from sdbc_msgs.msg import RobotCommand, SensorReadings

    shape = make_task(TASK).network
    genome = np.random.default_rng(7).uniform(-1.0, 1.0, shape.genome_length)
    genome_arg = "[" + ",".join(repr(float(v)) for v in genome) + "]"
    process = subprocess.Popen(
        controller_command(
            "-r", "__ns:=/robot_5", "-p", f"task:={TASK}", "-p", f"genome:={genome_arg}"
        ),
        env=environment(ros_home),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    context = rclpy.Context()
    rclpy.init(context=context)
    node = Node("test_sensors", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    commands: list[RobotCommand] = []
    try:
        publisher = node.create_publisher(
            SensorReadings, "/robot_5/sensors", LOCKSTEP_QOS
        )
        node.create_subscription(
            RobotCommand, "/robot_5/command", commands.append, LOCKSTEP_QOS
        )
        inputs = np.random.default_rng(8).uniform(-1.0, 1.0, (3, shape.n_inputs))
        deadline = time.monotonic() + 60.0
        for step, x in enumerate(inputs, start=1):
            publisher.publish(
                SensorReadings(values=x.tolist(), trial_id=77, step=step, robot=5)
            )
            while len(commands) < step:
                assert process.poll() is None, process.stdout.read().decode()
                assert time.monotonic() < deadline, "no command from the controller"
                executor.spin_once(timeout_sec=0.05)
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        process.send_signal(2)
        output = process.communicate(timeout=30)[0].decode()
    assert process.returncode == 0, output
    for step, (x, command) in enumerate(zip(inputs, commands, strict=True), start=1):
        assert (command.trial_id, command.step, command.robot) == (77, step, 5)
        expected = forward(genome, shape, x[None])[0]
        assert np.array_equal(np.asarray(command.outputs), expected)  # to the bit


@pytest.mark.parametrize(
    ("ros_args", "message"),
    [
        (("-p", "genome:=[0.5,0.25]"), "47"),
        (("-p", "genome:=[1,2,3]"), "genome"),
        (("-p", "task:=chess"), "unknown task 'chess'"),
        (("-p", "task_config:='{max_steps: -3}'"), "max_steps"),
    ],
)
def test_bad_start_up_input_stops_the_node_with_a_reason(ros_home, ros_args, message):
    result = subprocess.run(
        controller_command("-p", f"task:={TASK}", *ros_args),
        env=environment(ros_home),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2, result.stderr
    assert message in result.stderr
