"""The one way YAML enters the project: configuration files, treatments, study
presets, graph files, digests and ``--task-config`` strings all come through here.

PyYAML's safe loader builds no objects but plain data, yet it still lets a small
file cost the machine: aliases share one node, so a 614-byte "billion laughs"
file stands for billions of values, which anything that walks the data (a
validator, a ``repr`` in an error) then expands; deep nesting overflows Python's
stack; duplicate keys keep the last one silently. This loader refuses, with one
line naming the file (and the line where it has one):

- files above :data:`~sdbc_sim.limits.CONFIG_FILE_BYTES`, and bytes that are not
  UTF-8;
- nesting deeper than :data:`~sdbc_sim.limits.CONFIG_DEPTH`, more than
  :data:`~sdbc_sim.limits.CONFIG_ALIASES` aliases, more than
  :data:`~sdbc_sim.limits.CONFIG_NODES` values once aliases are expanded, and an
  alias inside its own anchor;
- a key given twice in one mapping (a ``<<`` merge may still be overridden, as
  YAML means it).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from yaml.nodes import MappingNode, Node, SequenceNode

from sdbc_sim.limits import (
    CONFIG_ALIASES,
    CONFIG_DEPTH,
    CONFIG_FILE_BYTES,
    CONFIG_NODES,
    EXCERPT_CHARS,
    excerpt,
)
from sdbc_sim.settings import SettingsError

__all__ = ["YamlRefused", "parse_yaml", "read_yaml"]

_MERGE_TAG = "tag:yaml.org,2002:merge"


class YamlRefused(SettingsError):
    """YAML that is not read; the message names the source and the problem."""


class _Refusal(Exception):
    """Raised inside the loader; :func:`parse_yaml` names the source."""


def _line(node_or_mark: Any) -> str:
    mark = getattr(node_or_mark, "start_mark", node_or_mark)
    return f"line {mark.line + 1}" if mark is not None else "somewhere"


class _LimitedLoader(yaml.SafeLoader):
    """PyYAML's safe loader with the limits of the module docstring."""

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0
        self._aliases = 0

    def compose_node(self, parent: Node | None, index: Any) -> Node | None:
        event = self.peek_event()
        if self.check_event(yaml.AliasEvent):
            self._aliases += 1
            if self._aliases > CONFIG_ALIASES:
                raise _Refusal(
                    f"more than {CONFIG_ALIASES} aliases (CONFIG_ALIASES) at "
                    f"{_line(event)}"
                )
            return super().compose_node(parent, index)
        self._depth += 1
        try:
            if self._depth > CONFIG_DEPTH:
                raise _Refusal(
                    f"nested deeper than {CONFIG_DEPTH} levels (CONFIG_DEPTH) at "
                    f"{_line(event)}"
                )
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def get_single_data(self) -> Any:
        node = self.get_single_node()
        if node is None:
            return None
        _check_expansion(node)
        return self.construct_document(node)

    def construct_mapping(self, node: MappingNode, deep: bool = False) -> Any:
        if isinstance(node, MappingNode):
            seen: set[Any] = set()
            for key_node, _ in node.value:
                if key_node.tag == _MERGE_TAG:
                    continue
                key = self.construct_object(key_node, deep=True)
                try:
                    duplicate = key in seen
                except TypeError:
                    continue  # an unhashable key: PyYAML names it below
                if duplicate:
                    raise _Refusal(
                        f"key {excerpt(key)} given twice in one mapping (again at "
                        f"{_line(key_node)})"
                    )
                seen.add(key)
        return super().construct_mapping(node, deep=deep)


def _check_expansion(root: Node) -> None:
    """Refuses a document whose aliases expand beyond :data:`CONFIG_NODES` values
    or :data:`CONFIG_DEPTH` levels, or that holds an alias inside its own anchor.

    Walks the node graph once (a node shared by aliases is visited once, its size
    remembered), without recursion, so a long chain of aliases cannot overflow
    the stack either."""
    sizes: dict[int, tuple[int, int]] = {}  # id -> (values, depth), once done
    open_nodes: set[int] = set()
    stack: list[tuple[Node, bool]] = [(root, False)]
    while stack:
        node, children_done = stack.pop()
        key = id(node)
        if children_done:
            open_nodes.discard(key)
            size, depth = 1, 1
            for child in _children(node):
                child_size, child_depth = sizes[id(child)]
                size += child_size
                depth = max(depth, child_depth + 1)
            if size > CONFIG_NODES:
                raise _Refusal(
                    f"more than {CONFIG_NODES} values once its aliases are expanded "
                    f"(CONFIG_NODES), in the value at {_line(node)}"
                )
            if depth > CONFIG_DEPTH:
                raise _Refusal(
                    f"nested deeper than {CONFIG_DEPTH} levels once its aliases are "
                    f"expanded (CONFIG_DEPTH), in the value at {_line(node)}"
                )
            sizes[key] = (size, depth)
            continue
        if key in sizes:
            continue
        if key in open_nodes:
            raise _Refusal(f"an alias inside its own anchor at {_line(node)}")
        open_nodes.add(key)
        stack.append((node, True))
        for child in _children(node):
            if id(child) in open_nodes:
                raise _Refusal(f"an alias inside its own anchor at {_line(child)}")
            if id(child) not in sizes:
                stack.append((child, False))


def _children(node: Node) -> list[Node]:
    if isinstance(node, SequenceNode):
        return list(node.value)
    if isinstance(node, MappingNode):
        return [part for pair in node.value for part in pair]
    return []  # a scalar


def parse_yaml(text: str, source: str) -> Any:
    """The plain data of the YAML ``text`` (None for an empty document).

    Args:
        text: The YAML.
        source: What the text is, for messages: a file's path, ``--task-config``.

    Raises:
        YamlRefused: Not YAML, or beyond a limit, naming ``source``.
    """
    if len(text) > CONFIG_FILE_BYTES:
        raise YamlRefused(
            f"{source}: {len(text)} characters, more than CONFIG_FILE_BYTES="
            f"{CONFIG_FILE_BYTES}"
        )
    loader = _LimitedLoader(text)
    try:
        return loader.get_single_data()
    except _Refusal as error:
        raise YamlRefused(f"{source}: {error}") from None
    except yaml.YAMLError as error:
        raise YamlRefused(f"{source} is not valid YAML: {_one_line(error)}") from None
    except (ValueError, RecursionError) as error:
        # A scalar PyYAML cannot convert (an integer of 5000 digits), or a chain
        # the limits above did not foresee.
        detail = str(error)[:EXCERPT_CHARS]
        raise YamlRefused(f"{source}: {type(error).__name__}: {detail}") from None
    finally:
        loader.dispose()


def read_yaml(path: str | Path, what: str = "file") -> Any:
    """The plain data of the YAML file ``path`` (None for an empty file).

    Args:
        path: The file.
        what: What the file is, for messages ("configuration", "preset", ...).

    Raises:
        YamlRefused: Unreadable, larger than :data:`CONFIG_FILE_BYTES`, not
            UTF-8, not YAML, or beyond a limit, naming the file.
        OSError: never: a file that cannot be read is a refusal too.
    """
    path = Path(path)
    try:
        with path.open("rb") as f:
            data = f.read(CONFIG_FILE_BYTES + 1)
    except OSError as error:
        raise YamlRefused(
            f"cannot read {what} {path}: {error.strerror or error}"
        ) from None
    if len(data) > CONFIG_FILE_BYTES:
        raise YamlRefused(
            f"{what} {path} is larger than CONFIG_FILE_BYTES={CONFIG_FILE_BYTES} bytes"
        )
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise YamlRefused(
            f"{what} {path} is not UTF-8 text (byte {error.start})"
        ) from None
    return parse_yaml(text, f"{what} {path}")


def _one_line(error: yaml.YAMLError) -> str:
    return " ".join(str(error).split())
