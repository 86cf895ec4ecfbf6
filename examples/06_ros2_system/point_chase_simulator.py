"""Tutorial 06: a simulator of another system, written against the evolution
node's contract alone (docs/ros2.md, "Evolution through another simulator"), with
rclpy and sdbc_msgs and nothing of sdbc_sim: point chase, where ROBOTS point robots
chase a static target.

- Node ``simulator``, parameters ``task`` and ``task_config``, service
  ``run_trial`` (sdbc_msgs/srv/RunTrial): runs a trial of the seed with the
  controllers' current genomes, publishing every step on ``task_state``;
- a controller node ``robot_<i>/controller`` per robot, with the double-array
  parameter ``genome`` (GENOME_LENGTH values; anything else is rejected). How a
  simulator and its controllers talk is the system's own business: here they share
  the process and the simulator asks each controller for its action.

A trial is a function of (seed, genomes): the evolution node gets the same results
twice. Run as a script; Ctrl-C stops it (``evolve.py`` starts and stops it).
Its options make it break the contract as a faulty simulator would, for the
checks of what comes in (the evolution node's, ``sdbc-conformance --live``):
``--fitness VALUE`` answers every trial with that fitness, ``--characterisation
VALUE`` every characterisation value with that one, ``--skip-step N`` never
publishes step N's task state, ``--chasers N`` publishes N chasers in a group
that declares ROBOTS, ``--extra-group-from N`` publishes a third group from step
N on.
"""

from __future__ import annotations

import argparse
import math
import signal
import subprocess
import sys

import numpy as np

TASK = "point_chase"
ROBOTS = 2
GENOME_LENGTH = 6
"""A 2 x 3 matrix: velocity = tanh(W @ [dx, dy, 1]) towards the target."""
MAX_STEPS = 25
CATCH_RADIUS = 0.5


def faults(argv: list[str] | None = None) -> argparse.Namespace:
    """The ways of breaking the contract the command line asks for (none: it
    keeps to it)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--fitness", type=float, help="answer every trial with it")
    parser.add_argument(
        "--characterisation", type=float, help="answer every value with it"
    )
    parser.add_argument("--skip-step", type=int, help="never publish this step")
    parser.add_argument("--chasers", type=int, help="chasers published each step")
    parser.add_argument(
        "--extra-group-from", type=int, metavar="STEP", help="a third group from it"
    )
    return parser.parse_args(argv)


def main() -> int:
    fault = faults()
    import rclpy
    from geometry_msgs.msg import Point
    from rcl_interfaces.msg import SetParametersResult
    from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from sdbc_msgs.msg import Entity, EntityGroup, TaskState
    from sdbc_msgs.srv import RunTrial

    class Controller(Node):
        def __init__(self, robot: int) -> None:
            super().__init__("controller", namespace=f"robot_{robot}")
            self.genome = np.zeros(GENOME_LENGTH)
            self.add_on_set_parameters_callback(self._check)
            self.declare_parameter("genome", [0.0] * GENOME_LENGTH)

        def _check(self, parameters: list) -> SetParametersResult:
            for parameter in parameters:
                if parameter.name == "genome":
                    values = np.asarray(parameter.value, dtype=float)
                    if values.shape != (GENOME_LENGTH,):
                        return SetParametersResult(
                            successful=False,
                            reason=f"genome needs {GENOME_LENGTH} values",
                        )
                    self.genome = values
            return SetParametersResult(successful=True)

        def act(self, offset: np.ndarray) -> np.ndarray:
            return np.tanh(self.genome.reshape(2, 3) @ np.array([*offset, 1.0]))

    class Simulator(Node):
        def __init__(self, controllers: list[Controller]) -> None:
            super().__init__("simulator")
            self.declare_parameter("task", TASK)
            self.declare_parameter("task_config", "{}")
            self.controllers = controllers
            qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
            self.states = self.create_publisher(TaskState, "task_state", qos)
            self.create_service(RunTrial, "run_trial", self.run_trial)

        def run_trial(self, request, response):
            if request.task and request.task != TASK:
                response.success = False
                response.message = f"this simulator runs {TASK}, not {request.task}"
                return response
            rng = np.random.default_rng(request.seed)
            target = rng.uniform(-5.0, 5.0, 2)
            robots = rng.uniform(-10.0, 10.0, (ROBOTS, 2))
            start = np.linalg.norm(robots - target, axis=1).mean()
            for step in range(1, MAX_STEPS + 1):
                velocity = np.array(
                    [
                        c.act(target - p)
                        for c, p in zip(self.controllers, robots, strict=True)
                    ]
                )
                robots = robots + velocity
                distance = np.linalg.norm(robots - target, axis=1)
                done = step == MAX_STEPS or bool((distance < CATCH_RADIUS).all())
                if step != fault.skip_step:
                    self.states.publish(
                        self.state(request, step, robots, velocity, target, done)
                    )
                if done:
                    break
            response.success = True
            response.fitness = float(max(0.0, 1.0 - distance.mean() / start))
            if fault.fitness is not None:
                response.fitness = fault.fitness
            response.characterisation = [
                float(min(1.0, max(0.0, 0.5 + v / 40.0))) for v in robots.mean(axis=0)
            ]
            if fault.characterisation is not None:
                response.characterisation = [fault.characterisation] * 2
            response.characterisation_names = ["mean x", "mean y"]
            response.length = step
            return response

        def state(self, request, step, robots, velocity, target, done) -> TaskState:
            msg = TaskState(task=TASK, trial_id=request.trial_id, step=step, done=done)
            chasers = [
                Entity(
                    geometry=Entity.GEOMETRY_POINT,
                    centre=Point(x=float(x), y=float(y)),
                    state=[float(x), float(y), float(math.hypot(*v))],
                )
                for (x, y), v in zip(robots, velocity, strict=True)
            ]
            if fault.chasers is not None:
                chasers = (chasers * fault.chasers)[: fault.chasers]
            goal = Entity(
                geometry=Entity.GEOMETRY_POINT,
                centre=Point(x=float(target[0]), y=float(target[1])),
                state=[float(done)],
            )
            msg.groups = [
                EntityGroup(
                    name="Chaser",
                    attribute_names=["x", "y", "speed"],
                    entities=chasers,
                    min_size=ROBOTS,
                    max_size=ROBOTS,
                ),
                EntityGroup(
                    name="Target",
                    attribute_names=["is caught"],
                    entities=[goal],
                    min_size=1,
                    max_size=1,
                    is_static=True,
                ),
            ]
            if fault.extra_group_from is not None and step >= fault.extra_group_from:
                msg.groups.append(
                    EntityGroup(name="Extra", entities=[goal], min_size=1, max_size=1)
                )
            return msg

    rclpy.init()
    controllers = [Controller(i) for i in range(ROBOTS)]
    simulator = Simulator(controllers)
    executor = MultiThreadedExecutor(num_threads=2)
    for node in (simulator, *controllers):
        executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.shutdown()
        for node in (simulator, *controllers):
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


def stop(process: subprocess.Popen[bytes]) -> None:
    """Stops a simulator started as a script: Ctrl-C, then a kill after 20 s."""
    process.send_signal(signal.SIGINT)
    try:
        process.wait(timeout=20)
    except subprocess.TimeoutExpired:
        process.kill()


if __name__ == "__main__":
    sys.exit(main())
