"""Recording a trial is one command, and the bag it writes is read back with
rosbags alone: every message decoded, sdbc_msgs types included, from the
definitions stored in the bag."""

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


def test_one_command_records_a_trial_that_rosbags_decodes_whole(
    tmp_path, run_graph, graph_logs
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
        task_states = []
        for connection, _, raw in reader.messages():
            message = reader.deserialize(raw, connection.msgtype)
            counts[connection.topic] += 1
            if connection.topic == "/task_state":
                task_states.append(message)
    assert types["/task_state"] == "sdbc_msgs/msg/TaskState"
    assert "MSG: sdbc_msgs/EntityGroup" in definitions["/task_state"]
    assert "MSG: sdbc_msgs/Entity" in definitions["/task_state"]
    assert types["/markers"] == "visualization_msgs/msg/MarkerArray"
    for robot in range(4):
        assert types[f"/robot_{robot}/sensors"] == "sdbc_msgs/msg/SensorReadings"
        assert types[f"/robot_{robot}/command"] == "sdbc_msgs/msg/RobotCommand"
        assert counts[f"/robot_{robot}/sensors"] == length
        assert counts[f"/robot_{robot}/command"] == length
    assert counts["/task_state"] == length
    assert counts["/markers"] >= 1
    # The recorded task states characterise the trial as the engine does.
    assert [m.step for m in task_states] == list(range(1, length + 1))
    vectors = characterise_messages(task_states)
    assert len(vectors) == 1
    np.testing.assert_allclose(next(iter(vectors.values())), sdbc, rtol=0, atol=1e-9)


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
