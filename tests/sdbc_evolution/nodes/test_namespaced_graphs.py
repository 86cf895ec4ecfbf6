"""Graphs pushed into namespaces share a DDS domain without crosstalk; a launcher
refuses to start a graph where another one already offers its simulator; and live
evolution spread over several simulator graphs gives the run of one graph."""

from __future__ import annotations

import contextlib
import re
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

pytestmark = pytest.mark.ros

GRAPH_TIMEOUT = 120.0
"""Seconds graphs may take to come up on a loaded two-core machine."""
TRIAL_LINE = re.compile(r"trial seed (\d+): fitness (\S+), length (\d+), ")


def _genome(task: Any, rng_seed: int) -> np.ndarray:
    return np.random.default_rng(rng_seed).uniform(-1.0, 1.0, task.genome_length)


@contextlib.contextmanager
def _graph(
    tmp: Path, namespace: str, genome: np.ndarray, task_config: dict
) -> Iterator[Any]:
    """A gate escape graph (simulator, one controller process for the four robots)
    in ``namespace``, started; stopped at the end."""
    from sdbc_evolution.graph.graph_file import load_graph_file, trial_graph
    from sdbc_evolution.graph.processes import ProcessGraph, child_environment

    tmp.mkdir(parents=True, exist_ok=True)
    path = tmp / "graph.yaml"
    path.write_text(
        yaml.safe_dump(
            trial_graph(
                "gate_escape",
                genome,
                task_config,
                launcher={"robots_per_process": 4},
                nodes={"simulator": {"discovery_timeout": 30.0}},
            )
        )
    )
    env = child_environment()
    env["ROS_HOME"] = str(tmp / "ros_home")
    graph = ProcessGraph.from_graph_file(
        load_graph_file(path), tmp, log_dir=tmp / "logs", env=env, namespace=namespace
    )
    graph.start()
    try:
        yield graph
    finally:
        graph.stop()


def _logs(directory: Path) -> str:
    return "\n".join(
        f"--- {path}\n{path.read_text()[-2000:]}"
        for path in sorted(directory.rglob("*.log"))
    )


def test_two_namespaced_graphs_in_one_domain_answer_each_from_its_own_simulator(
    tmp_path, run_graph, client_node
):
    from sdbc_evolution.graph.client import GraphClient
    from sdbc_sim.engine import run_batch
    from sdbc_sim.tasks import make_task

    # Different genomes and trial lengths: an answer from the other graph shows.
    configs = {"team_a": {"max_steps": 40}, "team_b": {"max_steps": 70}}
    tasks = {ns: make_task("gate_escape", **c) for ns, c in configs.items()}
    genomes = {ns: _genome(tasks[ns], k) for k, ns in enumerate(configs)}
    seeds = [3, 4]
    with (
        _graph(tmp_path / "a", "team_a", genomes["team_a"], configs["team_a"]),
        _graph(tmp_path / "b", "/team_b/", genomes["team_b"], configs["team_b"]),
    ):
        node = client_node
        clients = {
            ns: GraphClient(
                node, tasks[ns], "gate_escape", configs[ns], namespace=f"/{ns}"
            )
            for ns in configs
        }
        try:
            for client in clients.values():
                client.wait_for_graph(GRAPH_TIMEOUT)
        except Exception as error:
            raise AssertionError(f"{error}\n{_logs(tmp_path)}") from None
        # Interleaved, so that both graphs run at once.
        answers: dict[str, list] = {ns: [] for ns in configs}
        threads = [
            threading.Thread(
                target=lambda ns=ns: answers[ns].extend(
                    clients[ns].run_trial(s) for s in seeds
                )
            )
            for ns in configs
        ]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join(GRAPH_TIMEOUT)
        # The launcher's --trial on a third graph, beside them: its own answer.
        done = run_graph(
            str(tmp_path / "a" / "graph.yaml"), "--namespace", "team_c", "--trial", "3"
        )
    for ns in configs:
        batched = run_batch(tasks[ns], genomes[ns][None], np.array([seeds]))
        assert [t.length for t in answers[ns]] == batched.length[0].tolist(), ns
        np.testing.assert_allclose(
            [t.fitness for t in answers[ns]], batched.fitness[0], rtol=0, atol=1e-9
        )
    assert done.returncode == 0, done.stderr
    seed, fitness, length = TRIAL_LINE.search(done.stdout).groups()
    assert (int(length), float(fitness)) == pytest.approx(
        (answers["team_a"][0].length, answers["team_a"][0].fitness), abs=1e-5
    )


def test_a_graph_is_refused_where_another_graph_offers_its_simulator(
    tmp_path, run_graph, client_node
):
    from sdbc_evolution.graph.client import GraphClient
    from sdbc_sim.tasks import make_task

    task = make_task("gate_escape", max_steps=40)
    path = tmp_path / "other" / "graph.yaml"
    with _graph(tmp_path / "other", "team_a", _genome(task, 0), {"max_steps": 40}):
        GraphClient(
            client_node, task, "gate_escape", {"max_steps": 40}, namespace="/team_a"
        ).wait_for_graph(GRAPH_TIMEOUT)
        # The same namespace: /team_a/run_trial would have two servers.
        refused = run_graph(str(path), "--namespace", "team_a", "--trial", "3")
        elsewhere = run_graph(str(path), "--namespace", "team_b", "--trial", "3")
    assert refused.returncode == 2, refused.stdout + refused.stderr
    assert "/team_a/run_trial is offered already" in refused.stderr
    assert "--namespace" in refused.stderr
    assert "trial seed" not in refused.stdout
    assert elsewhere.returncode == 0, elsewhere.stderr
    assert "trial seed 3: fitness" in elsewhere.stdout


def test_a_client_waiting_for_the_simulator_does_not_block_its_graph(
    tmp_path, run_graph, client_node
):
    """A client of run_trial (an evolution node or a conformance check started
    before the graph) lists the service's name in the domain, but serves nothing:
    the launcher starts the graph it is waiting for."""
    from sdbc_evolution.graph.client import GraphClient
    from sdbc_evolution.graph.graph_file import trial_graph
    from sdbc_sim.tasks import make_task

    task = make_task("gate_escape", max_steps=40)
    GraphClient(
        client_node, task, "gate_escape", {"max_steps": 40}, namespace="/team_c"
    )
    path = tmp_path / "graph.yaml"
    path.write_text(
        yaml.safe_dump(
            trial_graph(
                "gate_escape",
                _genome(task, 0),
                {"max_steps": 40},
                launcher={"robots_per_process": 4},
                nodes={"simulator": {"discovery_timeout": 30.0}},
            )
        )
    )
    done = run_graph(str(path), "--namespace", "team_c", "--trial", "3")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "trial seed 3: fitness" in done.stdout


EXPERIMENT = {
    "task": "gate_escape",
    "task_config": {"max_steps": 40},
    "treatment": "ns-sd+",
    "generations": 2,
    "seed": 5,
    "ga": {"population_size": 5, "elites": 1, "tournament_size": 2},
    "novelty": {"k": 2},
    "evaluation": {"trials": 2, "reevaluation_trials": 0},
}


def test_live_evolution_on_one_two_and_four_graphs_gives_the_same_run(
    tmp_path, run_graph
):
    from sdbc_evolution.run.results import read_generations, read_individuals

    experiment = tmp_path / "experiment.yaml"
    experiment.write_text(yaml.safe_dump(EXPERIMENT))
    runs = {}
    for graphs in (1, 2, 4):
        graph = tmp_path / f"graph{graphs}.yaml"
        graph.write_text(
            yaml.safe_dump(
                {
                    "sdbc_graph": {
                        "ros__parameters": {
                            "evolution": True,
                            "robots_per_process": 4,
                            "graphs": graphs,
                        }
                    },
                    "/**": {
                        "ros__parameters": {
                            "task": "gate_escape",
                            "task_config": EXPERIMENT["task_config"],
                        }
                    },
                    "evolution": {
                        "ros__parameters": {
                            "experiment_config": str(experiment),
                            "output": str(tmp_path / f"live{graphs}"),
                            "evaluator": "live",
                            "graph_timeout": GRAPH_TIMEOUT,
                        }
                    },
                }
            )
        )
        logs = tmp_path / f"logs{graphs}"
        done = run_graph(
            str(graph), "--namespace", f"evo{graphs}", "--log-dir", str(logs)
        )
        assert done.returncode == 0, done.stderr + _logs(logs)
        if graphs > 1:
            assert f"graph_{graphs - 1} simulator" in done.stderr
        runs[graphs] = (
            read_generations(tmp_path / f"live{graphs}"),
            read_individuals(tmp_path / f"live{graphs}"),
        )
    one, one_individuals = runs[1]
    for graphs in (2, 4):
        generations, individuals = runs[graphs]
        assert list(generations) == list(one)
        for column in one:
            if column.endswith("time"):
                continue
            np.testing.assert_array_equal(
                generations[column], one[column], err_msg=f"{graphs}: {column}"
            )
        for name in ("fitness", "trial_fitness", "sdbc", "characterisation"):
            np.testing.assert_array_equal(
                individuals[name], one_individuals[name], err_msg=f"{graphs}: {name}"
            )
