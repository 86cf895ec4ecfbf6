"""The characteriser node survives 10^4 malformed task state messages with bounded
memory, and still characterises a valid trial after them (issue 38, items 1 and 2).

The kinds: issue 38's 137-byte message (a group declared 0..100000 with one
entity), a stray first message with another group list, a message that changes
its trial's description mid-trial (a group's size limits), a lost step, a first
message that is not step 1, a message over a limit (too many entities, a name of
10^4 characters), a NaN centre, trials that never end, and more task names than
the node keeps descriptions of. The node's resident memory is read from
/proc after every 2000 messages: it may grow by its own bounded state and by what
DDS keeps of the subscription's history (depth times the largest message); fed
in-process, without DDS, the node's own Python heap stays flat once its bounded
tables are full.
"""

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
MESSAGES = 10_000
WARM_UP = 2_000
OWN_GROWTH = 16 * 2**20
"""Resident memory the node's own state may gain after the warm-up, bytes; DDS's
history of the subscription adds up to its depth times the largest message."""
WAIT = 240.0
"""Seconds the test waits for the node at most, on a loaded machine."""


def rss(pid: int) -> int:
    """Resident memory of a process, bytes."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    raise AssertionError(f"no VmRSS for process {pid}")


def stop(process: subprocess.Popen) -> int:
    process.send_signal(signal.SIGINT)
    try:
        return process.wait(timeout=20)
    except subprocess.TimeoutExpired:
        process.kill()
        return process.wait()


def entity(x: float = 1.0, y: float = 2.0):
    from geometry_msgs.msg import Point

    from sdbc_msgs.msg import Entity

    return Entity(geometry=Entity.GEOMETRY_POINT, centre=Point(x=x, y=y))


def message(task: str, trial_id: int, step: int, done: bool, groups: list):
    from sdbc_msgs.msg import TaskState

    msg = TaskState(task=task, trial_id=trial_id, step=step, done=done)
    msg.header.frame_id = "arena"
    msg.groups = groups
    return msg


def group(name: str, entities: list, min_size: int = 0, max_size: int = 3):
    from sdbc_msgs.msg import EntityGroup

    return EntityGroup(
        name=name,
        attribute_names=[],
        entities=entities,
        min_size=min_size,
        max_size=max_size,
        is_static=False,
    )


def malformed(k: int) -> list:
    """The k-th batch of malformed messages (one of each kind, trial ids unique
    to the batch)."""
    base = 10 * k
    swarm = [group("Agent", [entity()], 0, 100000)]
    nan = entity(float("nan"))
    return [
        # The 137-byte message: valid, characterised, and no longer a MemoryError.
        message("swarm", base, 1, True, swarm),
        # A stray first message of task "small" with another group list.
        message("small", base + 1, 1, True, [group("Stray", [entity()])]),
        # A trial whose description changes at step 2 (an edited simulator).
        message("small", base + 2, 1, False, [group("Robots", [entity()])]),
        message("small", base + 2, 2, False, [group("Robots", [entity()], 0, 5)]),
        # A lost step: step 4 follows step 1.
        message("small", base + 3, 1, False, [group("Robots", [entity()])]),
        message("small", base + 3, 4, False, [group("Robots", [entity()])]),
        # A first message that is not step 1.
        message("small", base + 4, 7, False, [group("Robots", [entity()])]),
        # Over the limits: too many entities, a name of 10^4 characters.
        message("small", base + 5, 1, True, [group("Robots", [entity()] * 1100)]),
        message("x" * 10_000, base + 6, 1, True, [group("Robots", [entity()])]),
        # A NaN centre; a trial that never ends; one more task name.
        message("small", base + 7, 1, True, [group("Robots", [nan])]),
        message("small", base + 8, 1, False, [group("Robots", [entity()])]),
        message(f"task{k % 40}", base + 9, 1, True, [group("Robots", [entity()])]),
    ]


def valid_trial(trial_id: int) -> list:
    return [
        message(
            "small",
            trial_id,
            step,
            step == 3,
            [group("Robots", [entity(float(step), 0.0), entity(0.0, 2.0 * step)])],
        )
        for step in (1, 2, 3)
    ]


def test_characteriser_survives_malformed_messages(tmp_path, ros_home) -> None:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from sdbc_evolution.sdbc.messages import MessageSdbcExtractor
    from sdbc_sim.nodes.interface import CHARACTERISATION_QOS, TASK_STATE_QOS

    from sdbc_msgs.msg import Characterisation, TaskState

    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    log = (tmp_path / "node.log").open("w")
    node_process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "sdbc_evolution.nodes.characteriser_node",
            "--ros-args",
            "-p",
            "trial_timeout:=2.0",
        ],
        env=env,
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    received: list[Characterisation] = []
    context = rclpy.Context()
    rclpy.init(context=context)
    node = Node("malformed_publisher", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    batches = [malformed(k) for k in range(MESSAGES // 12 + 1)]
    messages = [m for batch in batches for m in batch][:MESSAGES]
    sizes = []
    try:
        node.create_subscription(
            Characterisation, "characterisation", received.append, CHARACTERISATION_QOS
        )
        publisher = node.create_publisher(TaskState, "task_state", TASK_STATE_QOS)
        deadline = time.monotonic() + WAIT

        def spin_until(condition) -> None:
            while not condition() and time.monotonic() < deadline:
                assert node_process.poll() is None, "the characteriser died"
                executor.spin_once(timeout_sec=0.1)

        def settle() -> None:
            """Waits until the node has published what it has (its output has
            not changed for 3 s)."""
            last, since = -1, time.monotonic()
            while time.monotonic() - since < 3.0 and time.monotonic() < deadline:
                assert node_process.poll() is None, "the characteriser died"
                executor.spin_once(timeout_sec=0.1)
                if len(received) != last:
                    last, since = len(received), time.monotonic()

        spin_until(lambda: publisher.get_subscription_count() > 0)
        for start in range(0, MESSAGES, 250):
            for msg in messages[start : start + 250]:
                publisher.publish(msg)
            # Paced in bursts, so that most of them reach the node.
            executor.spin_once(timeout_sec=0.05)
            if (start + 250) % WARM_UP == 0:
                settle()
                sizes.append(rss(node_process.pid))
        for msg in valid_trial(999_999):
            publisher.publish(msg)
        spin_until(lambda: any(m.trial_id == 999_999 for m in received))
        assert node_process.poll() is None, "the characteriser died"
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        code = stop(node_process)
        log.close()
    node_log = (tmp_path / "node.log").read_text()
    assert code == 0, node_log[-3000:]
    valid = [m for m in received if m.trial_id == 999_999]
    assert len(valid) == 1, node_log[-3000:]
    expected = MessageSdbcExtractor()
    vector = None
    for msg in valid_trial(999_999):
        vector = expected.add(msg)
    assert valid[0].complete
    assert tuple(valid[0].dimension_names) == expected.last_dimension_names
    np.testing.assert_allclose(np.asarray(valid[0].values), vector, rtol=0, atol=1e-12)
    # The 137-byte trials are characterised, under their own description.
    swarm = [m for m in received if m.task == "swarm"]
    assert swarm and swarm[0].dimension_names[0] == "Agent group size (M)"
    for reason in (
        "max_size is 5, the description says 3",
        "fell behind",
        "its first message is step 7",
        "limits.entities = 1024",
        "limits.name_length = 256",
        "state or centre is not finite",
        "describes the groups otherwise",
        "limits.tasks = 16",
    ):
        assert reason in node_log, reason
    from rclpy.serialization import serialize_message
    from sdbc_sim.nodes.interface import TASK_STATE_DEPTH

    largest = max(len(serialize_message(m)) for m in messages[:12])
    bound = OWN_GROWTH + TASK_STATE_DEPTH * largest
    mib = ", ".join(f"{size / 2**20:.1f}" for size in sizes)
    print(
        f"characteriser RSS every {WARM_UP} messages, MiB: {mib}; bound on the "
        f"growth {bound / 2**20:.1f} MiB"
    )
    assert sizes[-1] - sizes[0] < bound, mib


def test_the_node_state_stays_bounded(ros_home) -> None:
    """The callbacks fed directly: every table the node keeps stops at its limit
    and the Python heap stops growing."""
    import tracemalloc

    import rclpy
    from rclpy.logging import LoggingSeverity
    from sdbc_evolution.nodes.characteriser_node import CharacteriserNode
    from sdbc_sim.task_state_msgs import LIMITS

    context = rclpy.Context()
    rclpy.init(context=context)
    node = CharacteriserNode(context=context)
    node.get_logger().set_level(LoggingSeverity.FATAL)
    try:
        batches = iter(range(10**6))

        def feed(messages: int) -> None:
            for _ in range(messages // 12):
                for msg in malformed(next(batches)):
                    node._on_task_state(msg)
            node._end_silent_trials()

        # Traced from the start: a full table's new entries replace traced ones.
        tracemalloc.start()
        feed(MESSAGES)
        start, _ = tracemalloc.get_traced_memory()
        feed(MESSAGES)
        grown, _ = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        assert len(node._dropped) == LIMITS.dropped
        assert len(node._extractors) == LIMITS.tasks
        assert max(len(e.open_trials) for e in node._extractors.values()) <= (
            LIMITS.open_trials
        )
        print(f"node heap over {MESSAGES} more messages: {grown - start} bytes")
        assert grown - start < 1_000_000, grown - start
        assert node.dropped > MESSAGES and node.gaps > 0 and node.steps_lost > 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def test_any_failure_in_a_callback_drops_the_trial_not_the_node(
    ros_home, monkeypatch
) -> None:
    """A MemoryError (or any exception) inside the extractor drops that trial with
    its reason; the next trial is characterised."""
    import rclpy
    from sdbc_evolution.nodes.characteriser_node import CharacteriserNode
    from sdbc_evolution.sdbc.messages import MessageSdbcExtractor

    context = rclpy.Context()
    rclpy.init(context=context)
    node = CharacteriserNode(context=context)
    errors: list[str] = []
    monkeypatch.setattr(node, "get_logger", lambda: _Logger(errors))
    original = MessageSdbcExtractor.add

    def add(self, msg):
        if msg.trial_id == 1:
            raise MemoryError("Unable to allocate 9.31 GiB")
        return original(self, msg)

    monkeypatch.setattr(MessageSdbcExtractor, "add", add)
    try:
        for msg in valid_trial(1) + valid_trial(2):
            node._on_task_state(msg)
        assert node.published == 1
        assert node.dropped == 1
        assert any(
            "trial 1 dropped, not characterised: Unable to allocate 9.31 GiB" in e
            for e in errors
        ), errors
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


class _Logger:
    """Keeps what the node logs."""

    def __init__(self, lines: list[str]) -> None:
        self.lines = lines

    def error(self, text: str, **_) -> None:
        self.lines.append(text)

    warning = info = error
