"""A publisher of sdbc_msgs/TaskState for a task this project's engine does not have,
written with rclpy alone: drones patrol around buoys that are collected one by one,
inside a fence, while an intruder comes and goes.

``scripted_trials()`` gives the messages in the order they are published: three
trials interleaved step by step, the last without a ``done`` message (its publisher
"crashed"). Run as a script, it publishes them once a subscriber has matched, then
stays up (so that reliable delivery can finish) until Ctrl-C or SIGTERM.
"""

from __future__ import annotations

import math
import signal
import sys
import time

TASK = "buoy_patrol"
TRIALS = {11: 40, 12: 55, 13: 30}
"""Trial id: length. Trial 13 never sends done."""
WITHOUT_DONE = 13
GAP = (14, 20, 5)
"""Trial 14 of 20 steps loses its step 5: it must be dropped, not characterised."""


def _trial_messages(trial_id: int, length: int) -> list:
    from geometry_msgs.msg import Point

    from sdbc_msgs.msg import Entity, EntityGroup, TaskState

    buoys = [(10.0 * k, 5.0 * (k % 2)) for k in range(1, 6)]
    fence = [(-5.0, -5.0), (60.0, -5.0), (60.0, -5.0), (60.0, 30.0)]
    messages = []
    for step in range(1, length + 1):
        t = step / 7.0 + trial_id
        drones = [
            Entity(
                geometry=Entity.GEOMETRY_POINT,
                centre=Point(x=25.0 + 15.0 * math.cos(t + d), y=8.0 * math.sin(t * d)),
                state=[math.cos(t + d), 0.5 + 0.1 * d, float(d == 0)],
            )
            for d in range(3)
        ]
        # A buoy is collected every 9 steps: the static group shrinks, and the
        # buoys left are no longer in their first slots.
        left = buoys[min(step // 9, len(buoys) - 1) :] if step < 45 else []
        # The intruder is away at step 1 (an empty group in the first message, so
        # its geometry is learnt later), then present on two steps in three.
        intruder = (
            [
                Entity(
                    geometry=Entity.GEOMETRY_CIRCLE,
                    centre=Point(x=40.0 - step, y=20.0 - 0.3 * step),
                    radius=1.5,
                    state=[0.1 * step],
                )
            ]
            if step % 3 != 1
            else []
        )
        msg = TaskState(task=TASK, trial_id=trial_id, step=step)
        msg.header.frame_id = "lake"
        msg.groups = [
            EntityGroup(
                name="Drone",
                attribute_names=["heading", "battery", "is leader"],
                entities=drones,
                min_size=3,
                max_size=3,
            ),
            EntityGroup(
                name="Buoy",
                attribute_names=["depth"],
                entities=[
                    Entity(
                        geometry=Entity.GEOMETRY_POINT,
                        centre=Point(x=x, y=y),
                        state=[x / 10.0],
                    )
                    for x, y in left
                ],
                min_size=0,
                max_size=5,
                is_static=True,
            ),
            EntityGroup(
                name="Fence",
                entities=[
                    Entity(
                        geometry=Entity.GEOMETRY_POLYGON,
                        segments=[Point(x=x, y=y) for x, y in fence],
                    )
                ],
                min_size=1,
                max_size=1,
                is_static=True,
            ),
            EntityGroup(
                name="Intruder",
                attribute_names=["threat"],
                entities=intruder,
                min_size=0,
                max_size=1,
            ),
        ]
        msg.done = step == length and trial_id != WITHOUT_DONE
        messages.append(msg)
    return messages


def scripted_trials(with_gap: bool = True) -> list:
    """Every message, trials interleaved step by step."""
    per_trial = [_trial_messages(t, n) for t, n in TRIALS.items()]
    if with_gap:
        trial_id, length, lost = GAP
        per_trial.append(
            [m for m in _trial_messages(trial_id, length) if m.step != lost]
        )
    order = []
    for step in range(max(len(m) for m in per_trial)):
        order.extend(m[step] for m in per_trial if step < len(m))
    return order


def main() -> int:
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from sdbc_msgs.msg import TaskState

    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    rclpy.init()
    node = Node("buoy_tracker")
    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    publisher = node.create_publisher(TaskState, "task_state", qos)
    try:
        while rclpy.ok() and publisher.get_subscription_count() == 0:
            time.sleep(0.05)
        for msg in scripted_trials():
            publisher.publish(msg)
        while rclpy.ok():
            rclpy.spin_once(node, timeout_sec=0.5)
    except (KeyboardInterrupt, ExternalShutdownException):
        # rclpy's SIGINT handler shuts the context down: inside spin_once that
        # surfaces as ExternalShutdownException, between calls as rclpy.ok()
        # turning false; both are a requested stop, not a failure.
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
