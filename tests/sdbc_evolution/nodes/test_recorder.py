"""Recording a trial is one command, and the bag it writes holds every step of
every topic, carries what rosbag2 writes (each topic's offered QoS, the type
hashes, the distribution), and is read back with rosbags alone and with mcap +
mcap-ros2-support (what Foxglove uses): every message decoded, sdbc_msgs types
included, from the definitions stored in the bag. The recorder is a full node: its
parameter and type description services answer."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import yaml

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[3]
SEED = 3
MAX_STEPS = 150


def batched_trial(genome: np.ndarray):
    from sdbc_evolution.sdbc.characterisation import SdbcExtractor
    from sdbc_sim.engine import run_batch
    from sdbc_sim.tasks import make_task

    extractor = SdbcExtractor()
    result = run_batch(
        make_task("gate_escape", max_steps=MAX_STEPS),
        genome[None],
        np.array([[SEED]]),
        observers=(extractor,),
    )
    return result, extractor.characterisations()[0]


STEPPED = ("sensors", "command")
"""Per-robot topics with one message per step."""


# Repeated: losing the first steps of a topic, or the last task state, happened in
# some runs only (discovery and shutdown races).
@pytest.mark.parametrize("attempt", range(3))
def test_one_command_records_every_step_of_a_trial(
    tmp_path, run_graph, graph_logs, attempt: int
):
    from rosbags.highlevel import AnyReader
    from sdbc_evolution.sdbc.messages import characterise_messages

    graph = yaml.safe_load((ROOT / "configs" / "ros" / "gate_escape.yaml").read_text())
    graph["/**"]["ros__parameters"]["task_config"] = {"max_steps": MAX_STEPS}
    graph_file = tmp_path / "graph.yaml"
    graph_file.write_text(yaml.safe_dump(graph))
    genome = np.asarray(graph["/**/controller"]["ros__parameters"]["genome"])
    bag = tmp_path / "trial"
    done = run_graph(
        str(graph_file),
        "--trial",
        str(SEED),
        "--record",
        str(bag),
        "--log-dir",
        str(tmp_path / "logs"),
    )
    assert done.returncode == 0, done.stderr + graph_logs(tmp_path / "logs")
    assert f"trial seed {SEED}: fitness" in done.stdout
    assert (bag / "metadata.yaml").is_file()
    assert len(list(bag.glob("*.mcap"))) == 1

    result, sdbc = batched_trial(genome)
    length = int(result.length[0, 0])
    # A reader that knows only the standard types: sdbc_msgs come from the bag.
    with AnyReader([bag]) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        definitions = {c.topic: c.msgdef.data for c in reader.connections}
        counts: Counter = Counter()
        steps: dict[str, list[int]] = {}
        task_states = []
        for connection, _, raw in reader.messages():
            message = reader.deserialize(raw, connection.msgtype)
            counts[connection.topic] += 1
            if hasattr(message, "step"):
                steps.setdefault(connection.topic, []).append(message.step)
            if connection.topic == "/task_state":
                task_states.append(message)
    assert types["/task_state"] == "sdbc_msgs/msg/TaskState"
    assert "MSG: sdbc_msgs/EntityGroup" in definitions["/task_state"]
    assert "MSG: sdbc_msgs/Entity" in definitions["/task_state"]
    assert types["/markers"] == "visualization_msgs/msg/MarkerArray"
    logs = graph_logs(tmp_path / "logs")
    for robot in range(4):
        assert types[f"/robot_{robot}/sensors"] == "sdbc_msgs/msg/SensorReadings"
        assert types[f"/robot_{robot}/command"] == "sdbc_msgs/msg/RobotCommand"
    # Every step of every stepped topic, once, in order.
    stepped = ["/task_state"] + [f"/robot_{r}/{t}" for r in range(4) for t in STEPPED]
    for topic in stepped:
        assert steps[topic] == list(range(1, length + 1)), (topic, logs)
    assert counts["/markers"] >= 1
    # The recorded task states characterise the trial as the engine does.
    assert [m.step for m in task_states] == list(range(1, length + 1))
    vectors = characterise_messages(task_states)
    assert len(vectors) == 1
    np.testing.assert_allclose(next(iter(vectors.values())), sdbc, rtol=0, atol=1e-9)
    check_what_rosbag2_writes(bag, set(types))
    check_mcap_reads_it(bag, counts)


def check_what_rosbag2_writes(bag: Path, topics: set[str]) -> None:
    """metadata.yaml: ros_distro jazzy and each topic's offered QoS (the lockstep
    topics reliable and transient-local); MCAP channels: offered_qos_profiles and
    topic_type_hash."""
    from mcap.reader import make_reader

    info = yaml.safe_load((bag / "metadata.yaml").read_text())
    info = info["rosbag2_bagfile_information"]
    assert info["ros_distro"] == "jazzy"
    offered = {
        t["topic_metadata"]["name"]: t["topic_metadata"]["offered_qos_profiles"]
        for t in info["topics_with_message_count"]
    }
    assert set(offered) == topics
    for topic, profiles in offered.items():
        assert profiles, topic
        assert {p["reliability"] for p in profiles} == {"reliable"}, topic
        durability = {p["durability"] for p in profiles}
        lockstep = topic.endswith(("/sensors", "/command"))
        assert durability == {"transient_local" if lockstep else "volatile"}, topic
    hashes = {
        t["topic_metadata"]["name"]: t["topic_metadata"]["type_description_hash"]
        for t in info["topics_with_message_count"]
    }
    with (bag / f"{bag.name}.mcap").open("rb") as f:
        summary = make_reader(f).get_summary()
    channels = {c.topic: c.metadata for c in summary.channels.values()}
    assert set(channels) == topics
    for topic, metadata in channels.items():
        assert metadata["topic_type_hash"] == hashes[topic]
        assert metadata["topic_type_hash"].startswith("RIHS01_")
        assert yaml.safe_load(metadata["offered_qos_profiles"]) == offered[topic]


def check_mcap_reads_it(bag: Path, counts: Counter) -> None:
    """mcap + mcap-ros2-support decode every message from the bag's schemas."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    decoded: Counter = Counter()
    with (bag / f"{bag.name}.mcap").open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _, channel, _, message in reader.iter_decoded_messages():
            decoded[channel.topic] += 1
            if channel.topic == "/task_state":
                assert message.groups[0].name == "Agent"
    assert decoded == counts


def test_the_recorder_is_a_full_node(tmp_path, ros_home) -> None:
    """Parameter services and the type description service answer while it
    records (rclpy's parameter client; the service rosbag2's tools call)."""
    import os
    import signal
    import subprocess
    import sys
    import time

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.parameter_client import AsyncParameterClient
    from rosbags.typesys import Stores, get_typestore
    from std_msgs.msg import Bool
    from type_description_interfaces.srv import GetTypeDescription

    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    recorder = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "sdbc_evolution.nodes.recorder_node",
            "--output",
            str(tmp_path / "bag"),
            "--topics",
            "/flag",
        ],
        env=env,
    )
    context = rclpy.Context()
    rclpy.init(context=context)
    node = Node("recorder_prober", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    ready: list[bool] = []
    try:
        from sdbc_sim.nodes.interface import LATCHED_QOS

        node.create_publisher(Bool, "/flag", 10)
        node.create_subscription(
            Bool, "/recorder/ready", lambda m: ready.append(m.data), LATCHED_QOS
        )
        deadline = time.monotonic() + 120.0
        while not ready and time.monotonic() < deadline:
            assert recorder.poll() is None, "the recorder died"
            executor.spin_once(timeout_sec=0.2)
        assert ready == [True]

        parameters = AsyncParameterClient(node, "recorder")
        assert parameters.wait_for_services(timeout_sec=60.0)
        future = parameters.list_parameters()
        executor.spin_until_future_complete(future, timeout_sec=60.0)
        assert "use_sim_time" in future.result().result.names

        describe = node.create_client(
            GetTypeDescription, "/recorder/get_type_description"
        )
        assert describe.wait_for_service(timeout_sec=60.0)
        request = GetTypeDescription.Request(
            type_name="std_msgs/msg/Bool",
            type_hash=get_typestore(Stores.ROS2_JAZZY).hash_rihs01("std_msgs/msg/Bool"),
            include_type_sources=True,
        )
        future = describe.call_async(request)
        executor.spin_until_future_complete(future, timeout_sec=60.0)
        answer = future.result()
        assert answer.successful, answer.failure_reason
        assert answer.type_description.type_description.type_name == (
            "std_msgs/msg/Bool"
        )
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        recorder.send_signal(signal.SIGINT)
        code = recorder.wait(timeout=30)
    assert code == 0
    assert (tmp_path / "bag" / "metadata.yaml").is_file()


def test_an_existing_bag_is_never_overwritten(tmp_path):
    from sdbc_evolution.graph.bags import BagWriter

    bag = tmp_path / "bag"
    with BagWriter(bag) as writer:
        writer.add_topic("/task_state", "sdbc_msgs/msg/TaskState")
    with pytest.raises(FileExistsError, match="exists"):
        BagWriter(bag)
    assert (bag / "metadata.yaml").is_file()


def test_an_unknown_message_type_is_named(tmp_path):
    from sdbc_evolution.graph.bags import BagWriter

    with (
        BagWriter(Path(tmp_path) / "bag") as writer,
        pytest.raises(LookupError, match="no_such_msgs"),
    ):
        writer.add_topic("/x", "no_such_msgs/msg/Nothing")
