"""The project's environment keeps DDS discovery on this machine."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def env_after_sourcing(extra: dict[str, str]) -> dict[str, str]:
    base = {"PATH": os.environ["PATH"], "HOME": os.environ.get("HOME", "/tmp"), **extra}
    out = subprocess.run(
        ["bash", "-c", f"source {ROOT / 'scripts' / 'env.sh'} && env -0"],
        env=base,
        capture_output=True,
        check=True,
    ).stdout.decode()
    return dict(item.split("=", 1) for item in out.split("\0") if "=" in item)


def test_env_keeps_discovery_on_loopback_by_default():
    # Without a profile of the user's, env.sh installs the loopback-only Fast DDS
    # profile; LOCALHOST would make rmw_fastrtps add sockets on 0.0.0.0 beside it
    # (tests/test_sockets.py), so the range is left to the profile.
    env = env_after_sourcing({})
    assert env["FASTRTPS_DEFAULT_PROFILES_FILE"].endswith(
        "scripts/fastdds_localhost.xml"
    )
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SYSTEM_DEFAULT"
    assert env["AMENT_PREFIX_PATH"].endswith(str(ROOT / ".venv"))
    assert env["ROS_HOME"] == str(ROOT / ".ros")


def test_env_without_the_profile_defaults_discovery_to_localhost():
    env = env_after_sourcing({"FASTRTPS_DEFAULT_PROFILES_FILE": ""})
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"


def test_env_keeps_a_users_explicit_choice():
    env = env_after_sourcing({"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"})
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SUBNET"


def test_this_test_run_is_confined_to_localhost_and_its_own_domain():
    # conftest sets LOCALHOST; a node program run in this process leaves it to the
    # loopback profile instead (SYSTEM_DEFAULT), which is no wider.
    discovery = os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"]
    profile = os.environ.get("FASTRTPS_DEFAULT_PROFILES_FILE", "")
    assert discovery == "LOCALHOST" or (
        discovery == "SYSTEM_DEFAULT" and profile.endswith("fastdds_localhost.xml")
    ), (discovery, profile)
    assert 0 <= int(os.environ["ROS_DOMAIN_ID"]) <= 101


def test_ci_sets_localhost_discovery():
    assert (
        "ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST" in (ROOT / ".ci" / "run").read_text()
    )


@pytest.mark.ros
def test_console_scripts_of_the_built_workspace_start():
    script = shutil.which("sdbc-evolve")
    assert script is not None, "sdbc-evolve is not on PATH: source scripts/env.sh"
    assert Path(script).is_relative_to(ROOT / "install")
    out = subprocess.run([script, "--help"], capture_output=True, text=True, check=True)
    assert "--treatment" in out.stdout
