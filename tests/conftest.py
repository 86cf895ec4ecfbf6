"""Test-wide settings: DDS discovery stays on this machine, on a domain of its own."""

from __future__ import annotations

import importlib
import os

import pytest


def _isolate_dds() -> None:
    # Set before any rclpy import: every node of this test run, in this process and in
    # the subprocesses that inherit os.environ, discovers only on localhost and only
    # in this run's domain. .ci/run picks the domain; a local run derives one.
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 100))


_isolate_dds()


def _have_ros() -> bool:
    # Import rather than find_spec: tests/sdbc_msgs would pass for a namespace
    # package called sdbc_msgs when the built interfaces are not on the path.
    try:
        importlib.import_module("rclpy")
        importlib.import_module("sdbc_msgs.msg")
    except ImportError:
        return False
    return True


HAVE_ROS = _have_ros()


def pytest_collection_modifyitems(
    config: pytest.Config, items: list[pytest.Item]
) -> None:
    if HAVE_ROS:
        return
    skip = pytest.mark.skip(
        reason="rclpy or sdbc_msgs not importable: run through `scripts/sdbc test`, "
        "which builds the workspace and sets up its environment"
    )
    for item in items:
        if "ros" in item.keywords:
            item.add_marker(skip)


@pytest.fixture
def ros_home(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch):
    """A private ROS_HOME (node logs) for one test, inherited by its subprocesses."""
    home = tmp_path_factory.mktemp("ros_home")
    monkeypatch.setenv("ROS_HOME", str(home))
    return home
