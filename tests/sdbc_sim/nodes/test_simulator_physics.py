"""The simulator node's ``physics_model`` parameter: declared read-only, given to
the engine it steps, and a bad value refused before any work, naming it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.ros


def make_simulator(context, *overrides):
    from rclpy.parameter import Parameter
    from sdbc_sim.nodes.simulator_node import SimulatorNode

    return SimulatorNode(
        context=context,
        parameter_overrides=[
            Parameter("task", value="gate_escape"),
            Parameter("task_config", value="{max_steps: 30}"),
            *overrides,
        ],
    )


@pytest.fixture
def context(ros_home):
    import rclpy

    context = rclpy.Context()
    rclpy.init(context=context)
    yield context
    rclpy.try_shutdown(context=context)


@pytest.mark.parametrize("model", ["rigid", "kinematic"])
def test_the_parameter_is_declared_read_only_and_builds_the_engine(context, model):
    from rclpy.parameter import Parameter
    from sdbc_sim.engine import EngineSettings
    from sdbc_sim.kinematic import KinematicTrials
    from sdbc_sim.physics import PhysicsSettings, TrialSpaces

    overrides = [Parameter("physics_model", value=model)] if model != "rigid" else []
    node = make_simulator(context, *overrides)
    try:
        assert node.has_parameter("physics_model")
        assert node.get_parameter("physics_model").value == model
        [descriptor] = node.describe_parameters(["physics_model"])
        assert descriptor.read_only and "kinematic" in descriptor.description
        assert node._stepper.settings == EngineSettings(
            physics=PhysicsSettings(model=model)
        )
        node._stepper.reset(3)
        expected = KinematicTrials if model == "kinematic" else TrialSpaces
        assert isinstance(node._stepper.sim.spaces, expected)
        other = "rigid" if model == "kinematic" else "kinematic"
        [refused] = node.set_parameters([Parameter("physics_model", value=other)])
        assert not refused.successful and "read-only" in refused.reason
    finally:
        node.destroy_node()


@pytest.mark.parametrize("value", ["soft", "Kinematic", ""])
def test_a_bad_model_is_refused_naming_the_parameter_and_the_models(context, value):
    from rclpy.parameter import Parameter

    with pytest.raises(
        ValueError,
        match=rf"^parameter physics_model: {value!r} is not one of rigid, kinematic$",
    ):
        make_simulator(context, Parameter("physics_model", value=value))


def test_a_params_file_sets_the_model(ros_home, tmp_path: Path):
    import rclpy
    from sdbc_sim.kinematic import KinematicTrials
    from sdbc_sim.nodes.simulator_node import SimulatorNode

    params = tmp_path / "simulator.yaml"
    params.write_text(
        yaml.safe_dump(
            {
                "/**": {"ros__parameters": {"task": "gate_escape"}},
                "simulator": {"ros__parameters": {"physics_model": "kinematic"}},
            }
        )
    )
    context = rclpy.Context()
    rclpy.init(
        args=["test", "--ros-args", "--params-file", str(params)], context=context
    )
    try:
        node = SimulatorNode(context=context)
        try:
            assert node.get_parameter("physics_model").value == "kinematic"
            node._stepper.reset(1)
            assert isinstance(node._stepper.sim.spaces, KinematicTrials)
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


def test_the_program_exits_2_with_a_one_line_error(ros_home):
    # As a user starts it: the refusal is the program's message and status 2.
    command = [
        sys.executable, "-m", "sdbc_sim.nodes.simulator_node",
        "--ros-args", "-p", "physics_model:=soft",
    ]  # fmt: skip
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    done = subprocess.run(
        command, env=env, capture_output=True, text=True, timeout=120, check=False
    )
    assert done.returncode == 2, done.stderr
    assert (
        "simulator_node: error: parameter physics_model: 'soft' is not one of "
        "rigid, kinematic" in done.stderr
    )
