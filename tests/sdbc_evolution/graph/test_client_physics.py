"""The graph client refuses a simulator that runs another physics model than the
run's (``evaluation.physics`` against the simulator's ``physics_model``)."""

from __future__ import annotations

import threading

import pytest

pytestmark = pytest.mark.ros


@pytest.fixture
def kinematic_simulator(ros_home):
    """A client node and a simulator node of the kinematic model, spun together
    in one process; yields the client node."""
    import rclpy
    from rclpy.executors import MultiThreadedExecutor
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from sdbc_sim.nodes.simulator_node import SimulatorNode

    context = rclpy.Context()
    rclpy.init(context=context)
    simulator = SimulatorNode(
        context=context,
        parameter_overrides=[
            Parameter("task", value="gate_escape"),
            Parameter("physics_model", value="kinematic"),
        ],
    )
    node = Node("physics_test_client", context=context)
    executor = MultiThreadedExecutor(num_threads=2, context=context)
    executor.add_node(simulator)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        yield node
    finally:
        executor.shutdown()
        simulator.destroy_node()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        spinner.join(timeout=10)


def test_the_simulators_model_is_checked_with_the_task(kinematic_simulator):
    from sdbc_evolution.graph.client import GraphClient, GraphClientError
    from sdbc_sim.tasks import make_task

    task = make_task("gate_escape")

    def client(physics: str | None) -> GraphClient:
        return GraphClient(
            kinematic_simulator, task, "gate_escape", timeout=30, physics=physics
        )

    client("kinematic").check_task()
    client(None).check_task()  # a caller without a model checks the task only
    with pytest.raises(
        GraphClientError,
        match=r"the simulator runs the 'kinematic' physics model \(its "
        r"physics_model parameter\), this client expects 'rigid'",
    ):
        client("rigid").check_task()
