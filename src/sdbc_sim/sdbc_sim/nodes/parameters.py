"""Parameters a node does not declare are refused, at start-up and at run time.

rclpy's defaults (``allow_undeclared_parameters=False``,
``automatically_declare_parameters_from_overrides=False``) refuse an undeclared
name given to ``set_parameters`` at run time, but an override given at start-up
(``-p``, ``--params-file``) for a name the node never declares sits unused in the
node's ``_parameter_overrides``, without a word: ``-p populaton:=8`` would run
with the default population. So every node program checks its nodes' overrides
once they have declared their parameters (:func:`check_overrides`, called by
:func:`sdbc_sim.nodes.startup.run_node_program`) and exits with status 2 and one
line naming the unknown names and the declared ones.

One exception: a parameters file shared by a whole graph gives every node the
names under its wildcard keys (``/**``, ``/team_a/*``), although each node
declares only some of them (the recorder has no ``task``). A name that reaches a
node only from such a key is let through when the node does not declare it; a
name given by ``-p``, or under a key that names the node (``simulator``,
``/**/controller``), must be declared.

At run time, :class:`CheckedNode` refuses a ``set_parameters`` of an undeclared
name with a reason that names the declared ones (what ``ros2 param set`` shows).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from typing import Any

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

from sdbc_sim.nodes.interface import ros_flag_values
from sdbc_sim.yaml_input import YamlRefused, read_yaml

WILDCARDS = ("*", "**")
"""The last part of a parameters file's node key that makes it a shared key."""


class UndeclaredParameters(ValueError):
    """Start-up overrides of names a node does not declare; the message names
    them and the declared ones."""


def declared_names(node: Node) -> list[str]:
    """Every parameter ``node`` declares, sorted."""
    return sorted(node.list_parameters([], 0).names)


def _refusal(node: Node, names: Sequence[str]) -> str:
    plural = "s" if len(names) > 1 else ""
    return (
        f"parameter{plural} {', '.join(names)} not declared by "
        f"{node.get_fully_qualified_name()} (it declares: "
        f"{', '.join(declared_names(node))})"
    )


def _flat_names(parameters: Any, prefix: str = "") -> Iterator[str]:
    """Parameter names of a ``ros__parameters`` mapping; nested mappings give
    dotted names, as rcl reads them."""
    if not isinstance(parameters, Mapping):
        return
    for key, value in parameters.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            yield from _flat_names(value, f"{name}.")
        else:
            yield name


def _node_sections(data: Any, prefix: str = "") -> Iterator[tuple[str, Any]]:
    """(node key, its ``ros__parameters``) of a parameters file; nested
    namespace keys are joined with ``/``, as rcl reads them."""
    if not isinstance(data, Mapping):
        return
    for key, value in data.items():
        if not isinstance(value, Mapping):
            continue
        if "ros__parameters" in value:
            yield f"{prefix}{key}", value["ros__parameters"]
        else:
            yield from _node_sections(value, f"{prefix}{key}/")


def shared_names(ros_args: Sequence[str]) -> set[str]:
    """Names given under the wildcard keys of the command line's parameters
    files, which every node gets whether it declares them or not."""
    names: set[str] = set()
    for path in ros_flag_values(ros_args, frozenset({"--params-file"})):
        try:
            data = read_yaml(path, "parameters file")
        except YamlRefused:
            continue  # rcl read it before the node existed, or refused it
        for key, parameters in _node_sections(data):
            if key.rstrip("/").rsplit("/", 1)[-1] in WILDCARDS:
                names.update(_flat_names(parameters))
    return names


def command_line_names(ros_args: Sequence[str]) -> set[str]:
    """Names given with ``-p NAME:=VALUE``."""
    rules = ros_flag_values(ros_args, frozenset({"-p", "--param"}))
    return {rule.partition(":=")[0] for rule in rules}


def undeclared_overrides(node: Node, ros_args: Sequence[str]) -> list[str]:
    """The start-up overrides of ``node`` that it does not declare and that are
    not only a shared file's (the module's rule), sorted."""
    shared = shared_names(ros_args) - command_line_names(ros_args)
    # rclpy keeps a node's start-up overrides, from the command line and its
    # parameters files, in this attribute and offers no public accessor.
    overrides: Mapping[str, Any] = node._parameter_overrides
    return sorted(
        name
        for name in overrides
        if not node.has_parameter(name) and name not in shared
    )


def check_overrides(node: Node, ros_args: Sequence[str]) -> None:
    """Refuses the start-up overrides of names that ``node`` does not declare.

    Raises:
        UndeclaredParameters: Naming them and the declared ones.
    """
    undeclared = undeclared_overrides(node, ros_args)
    if undeclared:
        raise UndeclaredParameters(_refusal(node, undeclared))


class CheckedNode(Node):
    """A node whose ``set_parameters`` of an undeclared name is refused with a
    reason naming the declared ones (rclpy's own says only that it is not
    declared), instead of an exception."""

    def set_parameters_atomically(
        self, parameter_list: list[Parameter]
    ) -> SetParametersResult:
        undeclared = [p.name for p in parameter_list if not self.has_parameter(p.name)]
        if undeclared:
            return SetParametersResult(
                successful=False, reason=_refusal(self, undeclared)
            )
        return super().set_parameters_atomically(parameter_list)
