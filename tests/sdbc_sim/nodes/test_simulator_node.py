"""The simulator node in process: refusals that need no controller, its
parameters' checks, and its markers."""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.ros


@pytest.fixture
def simulator(ros_home):
    import rclpy
    from rclpy.parameter import Parameter
    from sdbc_sim.nodes.simulator_node import SimulatorNode

    context = rclpy.Context()
    rclpy.init(context=context)
    node = SimulatorNode(
        context=context,
        parameter_overrides=[
            Parameter("task", value="resource_sharing"),
            Parameter("task_config", value="{max_steps: 40}"),
            Parameter("discovery_timeout", value=0.3),
        ],
    )
    yield node
    node.destroy_node()
    rclpy.try_shutdown(context=context)


def test_a_trial_without_controllers_is_aborted_naming_every_robot(simulator):
    from sdbc_sim.nodes.simulator_node import TrialAborted

    with pytest.raises(TrialAborted) as aborted:
        simulator.run_trial(seed=1)
    message = str(aborted.value)
    assert "no controller connected within 0.3 s" in message
    for robot in range(3):
        assert (
            f"robot {robot} (/robot_{robot}/sensors, /robot_{robot}/command)" in message
        )


def test_another_task_or_a_negative_seed_is_refused(simulator):
    from sdbc_sim.nodes.simulator_node import TrialAborted

    with pytest.raises(TrialAborted, match="runs task 'resource_sharing', not 'gate'"):
        simulator.run_trial(seed=1, task="gate")
    with pytest.raises(TrialAborted, match="non-negative"):
        simulator.run_trial(seed=-1)


def test_parameters_are_checked_when_set(simulator):
    from rclpy.parameter import Parameter

    [negative] = simulator.set_parameters([Parameter("command_timeout", value=-1.0)])
    assert not negative.successful
    [task] = simulator.set_parameters([Parameter("task", value="predator_prey")])
    assert not task.successful and "read-only" in task.reason
    [fine] = simulator.set_parameters([Parameter("command_timeout", value=0.5)])
    assert fine.successful


def test_a_bad_task_config_stops_the_simulator_before_any_work(ros_home):
    import rclpy
    from rclpy.parameter import Parameter
    from sdbc_sim.nodes.simulator_node import SimulatorNode

    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        with pytest.raises(ValueError, match="n_robots"):
            SimulatorNode(
                context=context,
                parameter_overrides=[Parameter("task_config", value="{n_robots: 0}")],
            )
    finally:
        rclpy.try_shutdown(context=context)


def test_markers_draw_every_entity_of_the_task_state():
    from sdbc_sim.engine import TrialStepper
    from sdbc_sim.nodes.markers import markers_from_task_state
    from sdbc_sim.task_state_msgs import task_state_to_msg
    from sdbc_sim.tasks import make_task
    from visualization_msgs.msg import Marker

    task = make_task("gate_escape")
    stepper = TrialStepper(task)
    stepper.reset(4)
    stepper.step(np.full((4, 3), 0.25))
    msg = task_state_to_msg(stepper.state(), task.description, 0, 9, task.name, False)
    markers = markers_from_task_state(msg).markers
    assert markers[0].action == Marker.DELETEALL
    by_group = {}
    for marker in markers[1:-1]:
        by_group.setdefault(marker.ns, []).append(marker)
    assert sorted(by_group) == ["Agent", "Gate", "Wall"]
    agents = by_group["Agent"]
    assert [m.type for m in agents] == [Marker.CYLINDER] * 4
    for marker, entity in zip(agents, msg.groups[0].entities, strict=True):
        assert marker.scale.x == 2 * entity.radius
        assert (marker.pose.position.x, marker.pose.position.y) == (
            entity.centre.x,
            entity.centre.y,
        )
    [walls] = by_group["Wall"]
    assert walls.type == Marker.LINE_LIST
    assert len(walls.points) == len(msg.groups[2].entities[0].segments)
    assert "step 1" in markers[-1].text
    assert all(m.header.frame_id == "arena" for m in markers)
