"""The Dask evaluator's failure modes and TLS: a refused port at once, a cluster
without workers after the timeout, a scheduler lost mid-run in one line that says
how to continue, and ``tls://`` schedulers with Dask's own TLS configuration."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import dask
import numpy as np
import pytest
from evolution_helpers import TINY_RUN_YAML
from sdbc_evolution.run.evaluators import (
    DaskEvaluator,
    LocalEvaluator,
    SchedulerLost,
    SchedulerUnreachable,
    TaskInfo,
    TaskSpec,
)
from sdbc_evolution.run.results import read_generations

SPEC = TaskSpec("gate_escape", {"max_steps": 60})


def batch() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    genomes = rng.uniform(-1, 1, (4, TaskInfo.of(SPEC).genome_length))
    return genomes, rng.integers(0, 2**62, (4, 2), dtype=np.int64)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def certificate(tmp_path: Path) -> tuple[Path, Path]:
    """A self-signed certificate for 127.0.0.1 and its key, made by openssl; it is
    its own certificate authority."""
    cert, key = tmp_path / "cert.pem", tmp_path / "key.pem"
    subprocess.run(
        ["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1",
         "-keyout", str(key), "-out", str(cert), "-subj", "/CN=127.0.0.1",
         "-addext", "subjectAltName=IP:127.0.0.1"],
        check=True, capture_output=True,
    )  # fmt: skip
    return cert, key


@pytest.fixture
def dask_config_from_environment() -> Iterator[None]:
    """Re-reads Dask's configuration after the test changed the environment, and
    again after the test, so that no other test sees its settings."""
    yield
    dask.config.refresh()


@pytest.mark.parametrize("how", ["environment", "security argument"])
def test_a_tls_scheduler_works_with_dasks_own_tls_settings(
    certificate: tuple[Path, Path],
    monkeypatch: pytest.MonkeyPatch,
    dask_config_from_environment: None,
    how: str,
) -> None:
    from distributed import LocalCluster
    from distributed.security import Security

    cert, key = map(str, certificate)
    server = Security(
        tls_ca_file=cert,
        tls_scheduler_cert=cert,
        tls_scheduler_key=key,
        tls_worker_cert=cert,
        tls_worker_key=key,
        tls_client_cert=cert,
        tls_client_key=key,
        require_encryption=True,
    )
    security = None
    if how == "environment":
        for name, value in (
            ("CA_FILE", cert),
            ("CLIENT__CERT", cert),
            ("CLIENT__KEY", key),
        ):
            monkeypatch.setenv(f"DASK_DISTRIBUTED__COMM__TLS__{name}", value)
        dask.config.refresh()
    else:
        security = Security(tls_ca_file=cert, tls_client_cert=cert, tls_client_key=key)
    genomes, seeds = batch()
    with LocalEvaluator(SPEC, workers=1) as local:
        expected = local.evaluate(genomes, seeds)
    with (
        LocalCluster(
            n_workers=1, threads_per_worker=1, processes=False, protocol="tls://",
            host="127.0.0.1", security=server, dashboard_address=None,
        ) as cluster,
        DaskEvaluator(SPEC, cluster.scheduler_address, 30, security) as evaluator,
    ):  # fmt: skip
        assert cluster.scheduler_address.startswith("tls://")
        result = evaluator.evaluate(genomes, seeds)
    np.testing.assert_array_equal(result.fitness, expected.fitness)
    np.testing.assert_array_equal(result.sdbc, expected.sdbc)


def test_a_refused_port_fails_at_once() -> None:
    port = free_port()  # nothing listens there now
    with pytest.raises(SchedulerUnreachable) as refused:
        DaskEvaluator(SPEC, f"tcp://127.0.0.1:{port}", timeout=120)
    assert str(refused.value) == (
        f"no Dask scheduler at 'tcp://127.0.0.1:{port}': connection refused (is it "
        "running? is the port right?)"
    )


def test_a_cluster_without_workers_is_an_error_after_the_timeout() -> None:
    from distributed import LocalCluster

    with (
        LocalCluster(n_workers=0, processes=False, dashboard_address=None) as cluster,
        pytest.raises(SchedulerUnreachable) as none,
    ):
        DaskEvaluator(SPEC, cluster.scheduler_address, timeout=2)
    assert str(none.value) == (
        f"the Dask scheduler at {cluster.scheduler_address!r} has no workers (waited "
        f"2 s, --connect-timeout): start some with `dask worker "
        f"{cluster.scheduler_address}`"
    )


def _evaluator_on(client: object, address: str) -> DaskEvaluator:
    """A DaskEvaluator of ``SPEC`` whose Dask client is ``client``, as if
    connected to ``address`` (no cluster needed)."""
    evaluator = DaskEvaluator.__new__(DaskEvaluator)
    evaluator.spec, evaluator.address, evaluator.timeout = SPEC, address, 1.0
    evaluator._client = client
    return evaluator


BATCH = (np.zeros((2, 10)), np.zeros((2, 1), dtype=np.int64))
"""Genomes and seeds for an evaluator whose client fails before any evaluation."""


def test_a_scheduler_gone_between_generations_is_a_lost_scheduler() -> None:
    # The end-to-end test below kills the scheduler at a random point; now and
    # then it dies before the next generation asks for the workers' threads,
    # and that call's reset connection must read as a lost scheduler too.
    class ResetClient:
        status = "running"

        def nthreads(self) -> dict[str, int]:
            raise ConnectionResetError(104, "Connection reset by peer")

    evaluator = _evaluator_on(ResetClient(), "tcp://x:1")
    with pytest.raises(SchedulerLost, match=r"tcp://x:1' \(ConnectionResetError\)"):
        evaluator.evaluate(*BATCH)


class _Done:
    def done(self) -> bool:
        return True


@pytest.mark.parametrize("listening", [False, True])
def test_a_reset_gather_is_a_lost_scheduler_only_if_its_port_is_closed(
    listening: bool,
) -> None:
    # gather can meet the reset connection before the client's status says the
    # scheduler is gone; an OSError while the scheduler still listens is the
    # task's own and passes through.
    class ResetClient:
        status = "running"

        def nthreads(self) -> dict[str, int]:
            return {"w": 1}

        def submit(self, *args: object, **kwargs: object) -> _Done:
            return _Done()

        def gather(self, futures: object) -> list[object]:
            raise ConnectionResetError(104, "Connection reset by peer")

    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        if listening:
            server.listen()
        address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
        evaluator = _evaluator_on(ResetClient(), address)
        expected = ConnectionResetError if listening else SchedulerLost
        with pytest.raises(expected) as raised:
            evaluator.evaluate(*BATCH)
        assert type(raised.value) is expected


def test_a_scheduler_lost_mid_run_is_one_line_saying_resume_continues(
    tmp_path: Path,
) -> None:
    address = f"tcp://127.0.0.1:{free_port()}"
    host, port = address.removeprefix("tcp://").split(":")
    scheduler = subprocess.Popen(
        [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", host,
         "--port", port, "--dashboard-address", "127.0.0.1:0"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    worker = subprocess.Popen(
        [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nworkers",
         "1", "--nthreads", "1", "--host", "127.0.0.1", "--dashboard-address",
         "127.0.0.1:0"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    config = tmp_path / "run.yaml"
    config.write_text(TINY_RUN_YAML.replace("generations: 2", "generations: 10000"))
    out = tmp_path / "run"
    evolve = subprocess.Popen(
        [sys.executable, "-m", "sdbc_evolution.run.cli", "--config", str(config),
         "--out", str(out), "--scheduler", address, "--connect-timeout", "5",
         "--quiet", "--no-gif"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 240
        while not (out / "individuals" / "gen_00000.npz").exists():
            assert evolve.poll() is None, evolve.communicate()[1]
            assert time.monotonic() < deadline, "no generation on the cluster"
            time.sleep(0.2)
        os.kill(scheduler.pid, signal.SIGKILL)
        _, err = evolve.communicate(timeout=300)
    finally:
        for process in (evolve, scheduler, worker):
            process.kill()
            process.communicate()
    assert evolve.returncode == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(
        f"sdbc-evolve: error: lost the Dask scheduler at '{address}'"
    )
    assert lines[0].endswith(
        f"the run's checkpoint is intact; continue with: sdbc-evolve --resume --out "
        f"{out} --scheduler ADDRESS"
    )
    done = read_generations(out)["generation"].tolist()
    assert done == list(range(len(done)))
