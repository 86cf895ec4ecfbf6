"""One start-up and shut-down for every node program.

Each node program (``simulator_node``, ``controller_node``, ``evolution_node``,
``recorder``, ``characteriser_node``) does the same around its own work: split the
command line into ROS arguments and its own, start rclpy, make its node(s) on an
executor, serve until it is done or stopped, and leave cleanly. A
:class:`NodeProgram` says what differs; :func:`run_node_program` does the rest.

Each node's start-up overrides are checked once it is made: a name it does not
declare ends the program before any work (:mod:`sdbc_sim.nodes.parameters`).

Exit status: 0 done, 2 bad arguments or parameters (the message names them), or
what the program's ``serve`` returns.
"""

from __future__ import annotations

import argparse
import faulthandler
import gc
import os
import signal
import sys
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Generic, Literal, TypeVar

import rclpy
from rclpy.executors import (
    Executor,
    ExternalShutdownException,
    MultiThreadedExecutor,
    SingleThreadedExecutor,
)
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from sdbc_sim.nodes.interface import UsageError, split_ros_arguments
from sdbc_sim.nodes.parameters import UndeclaredParameters, check_overrides
from sdbc_sim.nodes.shutdown import StopSignals, flush_publishers

NodeT = TypeVar("NodeT", bound=Node)

LOOPBACK_PROFILE = "fastdds_localhost.xml"
"""The name of the project's Fast DDS profile (``scripts/fastdds_localhost.xml``),
which puts every socket on loopback."""

SIGNAL_POLL = 0.2
"""Seconds :func:`spin_until_stopped` lets the executor wait at most, so that
Ctrl-C is seen that soon."""

Signals = Literal["stop", "rclpy", "own"]
"""How a program hears Ctrl-C and SIGTERM:

- ``stop``: :class:`~sdbc_sim.nodes.shutdown.StopSignals`, a request to stop that
  keeps the ROS context up, so the program can still flush what it published;
- ``rclpy``: rclpy's own handler (Ctrl-C raises KeyboardInterrupt);
- ``own``: neither; the program installs handlers of its own."""


@dataclass(frozen=True)
class Startup:
    """What a program's node(s) start with.

    Attributes:
        args: The program's own arguments (outside ``--ros-args``), parsed; empty
            for a program without a parser.
        executor: The executor the nodes are added to.
        stop_signals: The stop request of a program with ``signals="stop"``.
        ros_args: The whole command line as rclpy was given it.
    """

    args: argparse.Namespace
    executor: Executor
    stop_signals: StopSignals | None
    ros_args: tuple[str, ...] = ()

    @property
    def stop(self) -> StopSignals:
        """The stop request of a program with ``signals="stop"``."""
        if self.stop_signals is None:
            raise RuntimeError("this node program does not use StopSignals")
        return self.stop_signals


@dataclass(frozen=True)
class NodeProgram(Generic[NodeT]):
    """What one node program does of its own.

    Attributes:
        name: The program's name, for messages.
        make_nodes: Makes the program's node(s); each is added to the executor as
            it comes (so those made before a failure are destroyed too).
        serve: Runs until the program is done or stopped; returns the exit status.
        parser: Parses the program's own arguments; None: it takes none.
        threads: Executor threads (1: a single-threaded executor).
        signals: How Ctrl-C and SIGTERM reach the program (:data:`Signals`).
        errors: Exceptions of ``make_nodes`` and ``serve`` that mean bad input:
            printed as ``NAME: error: ...``, exit status 2.
        flush: The publishers of a node whose last messages must reach their
            readers before it goes.
        close: Runs first on the way out, before the executor stops (a recorder
            finishing its bag).
    """

    name: str
    make_nodes: Callable[[Startup], Iterable[NodeT]]
    serve: Callable[[Startup, Sequence[NodeT]], int]
    parser: argparse.ArgumentParser | None = None
    threads: int = 1
    signals: Signals = "stop"
    errors: tuple[type[Exception], ...] = (ValueError,)
    flush: Callable[[NodeT], Iterable[Any]] | None = None
    close: Callable[[Sequence[NodeT]], None] | None = None


def keep_dds_on_loopback(environ: dict[str, str] | None = None) -> None:
    """Leaves discovery to the project's loopback profile when it is in force.

    With ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, rmw_fastrtps adds a UDP
    transport of its own, on every interface, beside the profile's loopback-only
    ones; ``SYSTEM_DEFAULT`` keeps the profile's alone (tests/test_sockets.py).
    ``scripts/env.sh`` does this when it is sourced; this covers a ``LOCALHOST``
    exported after it. Must run before rclpy is initialised (rcl reads the
    variable then).

    Args:
        environ: The environment to adjust; default: this process's.
    """
    env: Any = os.environ if environ is None else environ
    profiles = [
        env[name]
        for name in ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")
        if env.get(name)
    ]
    on_profile = bool(profiles) and all(
        Path(p).name == LOOPBACK_PROFILE for p in profiles
    )
    if on_profile and env.get("ROS_AUTOMATIC_DISCOVERY_RANGE") == "LOCALHOST":
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SYSTEM_DEFAULT"


def stacks_on_sigusr1() -> None:
    """Has SIGUSR1 write every thread's Python stack to stderr (``kill -USR1
    PID``; the process goes on). A node that hangs (twice seen on its way out, in
    rclpy's compiled code) then says where, however it was started; a graph's
    launcher sends SIGUSR1 before SIGKILL. An interpreter's original stderr
    stands in for a ``sys.stderr`` without a file descriptor (a notebook's, a
    test's capture); with neither, no stacks rather than no node."""
    for stream in (sys.stderr, sys.__stderr__):
        if stream is None:
            continue
        try:
            faulthandler.register(signal.SIGUSR1, file=stream, all_threads=True)
        except (AttributeError, OSError, ValueError):
            continue
        return


def run_node_program(program: NodeProgram[NodeT], argv: Sequence[str] | None) -> int:
    """Runs ``program`` with the command line ``argv`` (``sys.argv`` if None)."""
    stacks_on_sigusr1()
    keep_dds_on_loopback()
    try:
        ros_argv, plain = split_ros_arguments(
            program.name, argv, allow_plain=program.parser is not None
        )
    except UsageError as error:
        print(error, file=sys.stderr)
        return 2
    args = (
        program.parser.parse_args(plain)
        if program.parser is not None
        else argparse.Namespace()
    )
    rclpy.init(
        args=ros_argv,
        signal_handler_options=(
            SignalHandlerOptions.ALL
            if program.signals == "rclpy"
            else SignalHandlerOptions.NO
        ),
    )
    stop = (
        StopSignals(rclpy.get_default_context()).install()
        if program.signals == "stop"
        else None
    )
    executor: Executor = (
        MultiThreadedExecutor(num_threads=program.threads)
        if program.threads > 1
        else SingleThreadedExecutor()
    )
    startup = Startup(args, executor, stop, tuple(ros_argv))
    nodes: list[NodeT] = []
    try:
        for node in program.make_nodes(startup):
            nodes.append(node)
            check_overrides(node, ros_argv)
            executor.add_node(node)
        return program.serve(startup, nodes)
    except UndeclaredParameters as error:
        print(f"{program.name}: error: {error}", file=sys.stderr)
        return 2
    except program.errors as error:
        print(f"{program.name}: error: {error}", file=sys.stderr)
        return 2
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        if program.close is not None:
            program.close(nodes)
        executor.shutdown()
        if program.flush is not None:
            flush_publishers(p for node in nodes for p in program.flush(node))
        for node in nodes:
            node.destroy_node()
        if stop is not None:
            stop.destroy()
        rclpy.try_shutdown()
        # What the nodes left in reference cycles (subscriptions holding their
        # callbacks, which hold the node) goes now, while rclpy can still free it;
        # freed at interpreter exit instead, a DDS entity's thread is destroyed
        # running and the process aborts ("terminate called without an active
        # exception", the recorder after SIGINT).
        gc.collect()


def spin_until_stopped(startup: Startup, nodes: Sequence[Node]) -> int:
    """Serves the nodes' callbacks until a stop is requested (``signals="stop"``)."""
    # Bounded waits: Python runs the signal handler only between them.
    while not startup.stop.requested.is_set():
        startup.executor.spin_once(timeout_sec=SIGNAL_POLL)
    return 0
