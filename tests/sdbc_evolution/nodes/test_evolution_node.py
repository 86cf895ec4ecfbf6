"""The evolution node runs the command line's experiment; evaluated through the
live graph, it produces the same run as the command line's batched evaluation, and
publishes its progress."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

pytestmark = pytest.mark.ros

TASK_CONFIG = {"max_steps": 60}
EXPERIMENT = {
    "task": "gate_escape",
    "task_config": TASK_CONFIG,
    "treatment": "ns-sd+",
    "generations": 2,
    "seed": 3,
    "ga": {"population_size": 4, "elites": 1, "tournament_size": 2},
    "novelty": {"k": 2},
    "evaluation": {"trials": 2, "reevaluation_trials": 0},
}


def test_live_evolution_equals_the_command_line_and_publishes_its_progress(
    tmp_path, run_graph, graph_logs
):
    from rosbags.highlevel import AnyReader
    from sdbc_evolution.run.cli import main as evolve
    from sdbc_evolution.run.results import read_generations, read_individuals

    experiment = tmp_path / "experiment.yaml"
    experiment.write_text(yaml.safe_dump(EXPERIMENT))
    graph = tmp_path / "graph.yaml"
    graph.write_text(
        yaml.safe_dump(
            {
                "sdbc_graph": {
                    "ros__parameters": {"evolution": True, "robots_per_process": 2}
                },
                "/**": {
                    "ros__parameters": {
                        "task": "gate_escape",
                        "task_config": TASK_CONFIG,
                    }
                },
                "evolution": {
                    "ros__parameters": {
                        "experiment_config": str(experiment),
                        "output": str(tmp_path / "live"),
                        "evaluator": "live",
                        "replay_best": True,
                        "replay_seed": 5,
                    }
                },
            }
        )
    )
    bag = tmp_path / "bag"
    done = run_graph(
        str(graph), "--record", str(bag), "--log-dir", str(tmp_path / "logs")
    )
    assert done.returncode == 0, done.stderr + graph_logs(tmp_path / "logs")
    evolution_log = (tmp_path / "logs" / "evolution.log").read_text()
    assert "replay of generation 1's best (seed 5)" in evolution_log

    status = evolve(
        [
            "--config",
            str(experiment),
            "--out",
            str(tmp_path / "local"),
            "--workers",
            "1",
            "--no-gif",
            "--quiet",
        ]
    )
    assert status == 0
    live = read_generations(tmp_path / "live")
    local = read_generations(tmp_path / "local")
    for column in local:
        if column.endswith("time"):
            continue
        np.testing.assert_allclose(
            live[column], local[column], rtol=0, atol=1e-9, err_msg=column
        )
    np.testing.assert_array_equal(
        np.load(tmp_path / "live" / "best_genomes.npy"),
        np.load(tmp_path / "local" / "best_genomes.npy"),
    )
    live_individuals = read_individuals(tmp_path / "live")
    local_individuals = read_individuals(tmp_path / "local")
    for name in ("fitness", "trial_fitness", "sdbc", "characterisation"):
        np.testing.assert_allclose(
            live_individuals[name],
            local_individuals[name],
            rtol=0,
            atol=1e-6,  # stored as float32
            err_msg=name,
        )

    with AnyReader([bag]) as reader:
        stats = [
            reader.deserialize(raw, connection.msgtype)
            for connection, _, raw in reader.messages()
            if connection.topic == "/generation_stats"
        ]
        best = [
            reader.deserialize(raw, connection.msgtype)
            for connection, _, raw in reader.messages()
            if connection.topic == "/best_genome"
        ]
    assert [s.generation for s in stats] == [0, 1]
    assert all(s.treatment == "NS-SD+" and s.task == "gate_escape" for s in stats)
    np.testing.assert_allclose([s.best_fitness for s in stats], local["best_fitness"])
    assert all(len(s.weights) == len(s.feature_names) == 21 for s in stats)
    assert all(min(s.weights) >= 0.25 for s in stats)
    np.testing.assert_array_equal(
        stats[-1].best_genome, np.load(tmp_path / "local" / "best_genomes.npy")[-1]
    )
    np.testing.assert_array_equal(best[-1].data, stats[-1].best_genome)


def test_bad_parameters_stop_the_node_before_any_work_with_a_reason(tmp_path):
    env = {
        **os.environ,
        "ROS_HOME": str(tmp_path),
        "PYTHONPATH": os.pathsep.join(p for p in sys.path if p),
    }
    for parameter, message in (
        ("evaluator:=remote", "evaluator"),
        ("treatment:=ns-xx", "treatment"),
        ("experiment_config:=/no/such/file.yaml", "file.yaml"),
    ):
        result = subprocess.run(
            [
                sys.executable,
                "-m",
                "sdbc_evolution.nodes.evolution_node",
                "--ros-args",
                "-p",
                parameter,
                "-p",
                f"output:={Path(tmp_path) / 'out'}",
            ],
            capture_output=True,
            text=True,
            env=env,
            timeout=120,
        )
        assert result.returncode == 2, (parameter, result.stderr)
        assert message in result.stderr, (parameter, result.stderr)
        assert not (Path(tmp_path) / "out").exists()


BOUNDARY_TASKS = Path(__file__).resolve().parents[1] / "run" / "boundary_tasks.py"
"""Gate escape with one fault each (tests/sdbc_evolution/run/)."""


@pytest.mark.parametrize(
    ("task", "message"),
    [
        ("NegativeFitness", "a first trial: task '{task}' returned trial fitness -"),
        ("MissingGroup", "task '{task}' fails its first trial: ValueError: task "
         "'gate_escape', step 1: 2 groups in the state, 3 in the description"),
    ],
)  # fmt: skip
def test_the_node_runs_the_command_lines_first_trial_before_its_run_directory(
    tmp_path: Path, task: str, message: str
) -> None:
    # The probe sdbc-evolve makes (probe_task): a task breaking the contract is
    # one line and exit status 2, and no run directory is made.
    reference = f"{BOUNDARY_TASKS}:{task}"
    experiment = tmp_path / "experiment.yaml"
    experiment.write_text(yaml.safe_dump({**EXPERIMENT, "task": reference}))
    out = tmp_path / "out"
    env = {
        **os.environ,
        "ROS_HOME": str(tmp_path),
        "PYTHONPATH": os.pathsep.join(p for p in sys.path if p),
    }
    argv = [sys.executable, "-m", "sdbc_evolution.nodes.evolution_node"]
    argv += ["--ros-args", "-p", f"experiment_config:={experiment}"]
    argv += ["-p", f"output:={out}", "-p", "workers:=1"]
    result = subprocess.run(argv, capture_output=True, text=True, env=env, timeout=300)
    assert result.returncode == 2, result.stderr
    [line] = result.stderr.strip().splitlines()
    assert line.startswith("evolution_node: error: "), line
    assert message.format(task=reference) in line, line
    assert not out.exists()
