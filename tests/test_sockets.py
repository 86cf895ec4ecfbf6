"""With ``scripts/env.sh``'s defaults, the project's processes bind nothing beyond
loopback: the graph's nodes (Fast DDS, through ``scripts/fastdds_localhost.xml``)
and a run on a Dask cluster. Read from /proc/net, for the processes' own sockets.

The test suite itself forces ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (see
conftest.py); here each process gets the environment a user's shell has after
``source scripts/env.sh``, with only the domain made the test's own."""

from __future__ import annotations

import ipaddress
import os
import re
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ENV_SH = ROOT / "scripts" / "env.sh"
DDS_VARIABLES = (
    "ROS_AUTOMATIC_DISCOVERY_RANGE",
    "ROS_STATIC_PEERS",
    "FASTRTPS_DEFAULT_PROFILES_FILE",
    "FASTDDS_DEFAULT_PROFILES_FILE",
)

NODE_NAMES = """\
import sys, time
import rclpy
rclpy.init()
node = rclpy.create_node("socket_test_probe")
deadline = time.monotonic() + float(sys.argv[1])
wanted = set(sys.argv[2:])
while time.monotonic() < deadline:
    rclpy.spin_once(node, timeout_sec=0.2)
    if wanted <= set(node.get_node_names()):
        print("found", flush=True)
        break
else:
    print("missing", sorted(wanted - set(node.get_node_names())), flush=True)
sys.stdin.read()  # stay up while the test reads the sockets
"""


def env_sh_defaults(**before: str) -> dict[str, str]:
    """The environment after ``source scripts/env.sh`` in a shell that set none
    of the DDS variables but ``before``."""
    env = {k: v for k, v in os.environ.items() if k not in DDS_VARIABLES}
    env.update(before)
    dumped = subprocess.run(
        ["bash", "-c", f"source {ENV_SH} && env -0"],
        env=env,
        capture_output=True,
        check=True,
    ).stdout
    out = dict(
        item.split("=", 1) for item in dumped.decode().split("\0") if "=" in item
    )
    out["ROS_DOMAIN_ID"] = os.environ["ROS_DOMAIN_ID"]
    return out


def descendants(pid: int) -> list[int]:
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        for task in Path(f"/proc/{p}/task").glob("*"):
            children = (task / "children").read_text().split()
            todo.extend(int(c) for c in children)
    return out


def socket_inodes(pids: list[int]) -> set[str]:
    inodes = set()
    for pid in pids:
        for fd in Path(f"/proc/{pid}/fd").glob("*"):
            try:
                target = os.readlink(fd)
            except OSError:
                continue
            match = re.fullmatch(r"socket:\[(\d+)\]", target)
            if match:
                inodes.add(match.group(1))
    return inodes


def _address(
    hex_address: str,
) -> tuple[ipaddress.IPv4Address | ipaddress.IPv6Address, int]:
    ip, port = hex_address.split(":")
    raw = bytes.fromhex(ip)
    if len(raw) == 4:
        return ipaddress.IPv4Address(struct.pack("<I", int(ip, 16))), int(port, 16)
    words = b"".join(raw[i : i + 4][::-1] for i in range(0, 16, 4))
    return ipaddress.IPv6Address(words), int(port, 16)


def ip_sockets(pids: list[int]) -> list[tuple[str, str, bool]]:
    """(protocol, local address, on loopback) of every UDP and TCP socket of
    ``pids``: bound, listening or connected."""
    inodes = socket_inodes(pids)
    out = []
    for protocol in ("udp", "udp6", "tcp", "tcp6"):
        lines = Path(f"/proc/net/{protocol}").read_text().splitlines()[1:]
        for line in lines:
            fields = line.split()
            if fields[9] not in inodes:
                continue
            ip, port = _address(fields[1])
            out.append((protocol, f"{ip}:{port}", ip.is_loopback))
    return out


def beyond_loopback(sockets: list[tuple[str, str, bool]]) -> list[tuple[str, str]]:
    return [
        (protocol, address) for protocol, address, loopback in sockets if not loopback
    ]


def graph_node_sockets(
    tmp_path: Path, env: dict[str, str], probe_env: dict[str, str]
) -> list[tuple[str, str, bool]]:
    """The sockets of a simulator and a controller started with ``env``, once a
    probe started with ``probe_env`` has found both."""
    env = {**env, "ROS_HOME": str(tmp_path)}
    nodes = [
        subprocess.Popen(
            [name], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        for name in ("simulator_node", "controller_node")
    ]
    probe = subprocess.Popen(
        [sys.executable, "-c", NODE_NAMES, "60", "simulator", "controller"],
        env={**probe_env, "ROS_HOME": str(tmp_path)},
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert probe.stdout is not None
        assert probe.stdout.readline().strip() == "found"
        sockets = ip_sockets([p.pid for p in nodes])
        assert sockets, "no sockets found: the processes did not start DDS"
        return sockets
    finally:
        for process in (*nodes, probe):
            process.kill()
            process.communicate()


@pytest.mark.ros
def test_graph_nodes_bind_only_loopback_and_still_find_each_other(
    tmp_path: Path,
) -> None:
    env = env_sh_defaults()
    assert env["FASTRTPS_DEFAULT_PROFILES_FILE"].endswith("fastdds_localhost.xml")
    assert beyond_loopback(graph_node_sockets(tmp_path, env, env)) == []


@pytest.mark.ros
def test_graph_nodes_stay_on_loopback_with_localhost_exported_after_env_sh(
    tmp_path: Path,
) -> None:
    # What a user who follows the usual ROS advice types after sourcing env.sh:
    # rmw_fastrtps would add a UDP transport on every interface beside the
    # profile's; the nodes leave discovery to the profile instead.
    env = {**env_sh_defaults(), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    sockets = graph_node_sockets(tmp_path, env, env_sh_defaults())
    assert beyond_loopback(sockets) == []


def test_localhost_exported_before_env_sh_is_left_to_the_profile() -> None:
    env = env_sh_defaults(ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    assert env["FASTRTPS_DEFAULT_PROFILES_FILE"].endswith("fastdds_localhost.xml")
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SYSTEM_DEFAULT"
    # A choice other than LOCALHOST, or LOCALHOST without the profile, is kept.
    env = env_sh_defaults(ROS_AUTOMATIC_DISCOVERY_RANGE="SUBNET")
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SUBNET"
    env = env_sh_defaults(
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", FASTRTPS_DEFAULT_PROFILES_FILE=""
    )
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"


def test_the_nodes_leave_an_exported_localhost_to_the_loopback_profile() -> None:
    pytest.importorskip("rclpy")
    from sdbc_sim.nodes.startup import keep_dds_on_loopback

    profile = str(ROOT / "scripts" / "fastdds_localhost.xml")
    env = {"FASTRTPS_DEFAULT_PROFILES_FILE": profile}
    for given, kept in (("LOCALHOST", "SYSTEM_DEFAULT"), ("SUBNET", "SUBNET")):
        adjusted = {**env, "ROS_AUTOMATIC_DISCOVERY_RANGE": given}
        keep_dds_on_loopback(adjusted)
        assert adjusted["ROS_AUTOMATIC_DISCOVERY_RANGE"] == kept
    # Another profile of the user's: LOCALHOST is theirs to keep.
    other = {"FASTRTPS_DEFAULT_PROFILES_FILE": "/etc/mine.xml"}
    other["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    keep_dds_on_loopback(other)
    assert other["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"


def test_a_dask_run_binds_only_loopback(tmp_path: Path) -> None:
    env = env_sh_defaults()
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    address = f"tcp://127.0.0.1:{port}"
    cluster = [
        subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host",
             "127.0.0.1", "--port", str(port), "--dashboard-address",
             "127.0.0.1:0"],
            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        ),
        subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_worker", address,
             "--nworkers", "1", "--nthreads", "1", "--host", "127.0.0.1",
             "--dashboard-address", "127.0.0.1:0"],
            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        ),
    ]  # fmt: skip
    config = tmp_path / "run.yaml"
    config.write_text(
        "task: gate_escape\ntask_config: {max_steps: 40}\ntreatment: fit\n"
        "generations: 400\nga: {population_size: 4, elites: 1, tournament_size: 2}\n"
        "evaluation: {trials: 1, reevaluation_trials: 0}\n"
    )
    out = tmp_path / "run"
    evolve = subprocess.Popen(
        [sys.executable, "-m", "sdbc_evolution.run.cli", "--config", str(config),
         "--out", str(out), "--scheduler", address, "--connect-timeout", "60",
         "--quiet", "--no-gif"],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 180
        while not (out / "individuals" / "gen_00002.npz").exists():
            assert evolve.poll() is None, evolve.communicate()[1]
            assert time.monotonic() < deadline, "the Dask run did not get going"
            time.sleep(0.2)
        # The project's processes: sdbc-evolve and whatever it started.
        sockets = ip_sockets(descendants(evolve.pid))
        assert any(protocol.startswith("tcp") for protocol, _, _ in sockets)
        assert beyond_loopback(sockets) == []
        # The cluster, started as the README says (--host and --dashboard-address
        # on loopback; a worker without them listens on 0.0.0.0, measured).
        cluster_pids = [pid for p in cluster for pid in descendants(p.pid)]
        assert beyond_loopback(ip_sockets(cluster_pids)) == []
    finally:
        for process in (evolve, *cluster):
            process.terminate()
        for process in (evolve, *cluster):
            process.wait(timeout=60)
