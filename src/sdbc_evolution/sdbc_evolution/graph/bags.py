"""rosbag2 bags (MCAP storage plus ``metadata.yaml``) written with ``rosbags``.

Standard tools read them (``ros2 bag info``, Foxglove, ``rosbags``) because every
topic's connection stores its message definition: the definitions of ROS 2 Jazzy's
standard interfaces come with ``rosbags``, and those of the project's own
interfaces (``sdbc_msgs``) are read from the ``.msg`` files that the workspace
installs (``share/sdbc_msgs/msg``) and registered before any connection is made.
A reader then decodes every message without this project installed.

Messages are written as the CDR bytes received from a subscription (``raw=True``),
never re-serialised: ``rclpy.serialization.serialize_message`` may append padding
that rosbags rejects (docs/ros2-from-pypi.md, pitfall 7).
"""

from __future__ import annotations

import importlib
from collections.abc import Iterable
from pathlib import Path

from rosbags.interfaces import Connection
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

BAG_VERSION = 9
"""rosbag2 metadata version written (that of ROS 2 Jazzy)."""
PROJECT_INTERFACES = ("sdbc_msgs",)
"""Interface packages of this project, registered in every bag's type store."""


def interface_definitions(package: str, share: Path | None = None) -> dict[str, str]:
    """The ``.msg`` definitions of an interface package, by type name
    (``sdbc_msgs/msg/TaskState``).

    Args:
        package: The package.
        share: Its ``share/<package>`` directory; default: found through the
            ament index.

    Raises:
        LookupError: If the package is not installed or holds no ``.msg`` file.
    """
    if share is None:
        from ament_index_python.packages import (
            PackageNotFoundError,
            get_package_share_directory,
        )

        try:
            share = Path(get_package_share_directory(package))
        except PackageNotFoundError:
            raise LookupError(
                f"interface package {package!r} is not installed (ament index: "
                "AMENT_PREFIX_PATH); build the workspace first"
            ) from None
    files = sorted((share / "msg").glob("*.msg"))
    if not files:
        raise LookupError(
            f"interface package {package!r}: no .msg files in {share}/msg"
        )
    return {f"{package}/msg/{f.stem}": f.read_text() for f in files}


def project_typestore(packages: Iterable[str] = PROJECT_INTERFACES) -> Typestore:
    """ROS 2 Jazzy's standard types plus those of ``packages``."""
    typestore = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for package in packages:
        for name, text in interface_definitions(package).items():
            types.update(get_types_from_msg(text, name))
    typestore.register(types)
    return typestore


def ensure_type(typestore: Typestore, msgtype: str) -> None:
    """Registers ``msgtype`` (``pkg/msg/Name``) and its package's other types if
    the store lacks it.

    Raises:
        LookupError: If the type's package is not installed or does not define it.
    """
    if msgtype in typestore.fielddefs:
        return
    package = msgtype.split("/")[0]
    types = {}
    for name, text in interface_definitions(package).items():
        types.update(get_types_from_msg(text, name))
    if msgtype not in types:
        raise LookupError(f"message type {msgtype!r} is not defined by {package!r}")
    typestore.register(types)


def message_class(msgtype: str) -> type:
    """The Python class of ``pkg/msg/Name``.

    Raises:
        LookupError: If it cannot be imported.
    """
    parts = msgtype.split("/")
    if len(parts) != 3 or parts[1] != "msg":
        raise LookupError(f"not a message type name: {msgtype!r}")
    try:
        return getattr(importlib.import_module(f"{parts[0]}.msg"), parts[2])
    except (ImportError, AttributeError):
        raise LookupError(f"message type {msgtype!r} cannot be imported") from None


class BagWriter:
    """A rosbag2 bag being written: MCAP storage, definitions of every type.

    Args:
        path: The bag's directory; it must not exist yet.
        typestore: Types the bag may hold; default :func:`project_typestore`.

    Raises:
        FileExistsError: If ``path`` exists.
    """

    def __init__(self, path: str | Path, typestore: Typestore | None = None) -> None:
        self.path = Path(path)
        if self.path.exists():
            raise FileExistsError(f"bag {self.path} exists already; not overwriting")
        self.typestore = typestore if typestore is not None else project_typestore()
        self._writer = Writer(
            self.path, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP
        )
        self._writer.open()
        self._connections: dict[str, Connection] = {}
        self.counts: dict[str, int] = {}

    def add_topic(self, topic: str, msgtype: str) -> None:
        """Declares a topic and its type; its definition goes into the bag.

        Raises:
            LookupError: If the type is unknown and cannot be registered.
            ValueError: If the topic was already added with another type.
        """
        existing = self._connections.get(topic)
        if existing is not None:
            if existing.msgtype != msgtype:
                raise ValueError(
                    f"topic {topic}: already recorded as {existing.msgtype}, "
                    f"not {msgtype}"
                )
            return
        ensure_type(self.typestore, msgtype)
        self._connections[topic] = self._writer.add_connection(
            topic, msgtype, typestore=self.typestore
        )
        self.counts[topic] = 0

    @property
    def topics(self) -> tuple[str, ...]:
        """Topics added so far."""
        return tuple(self._connections)

    def write(self, topic: str, timestamp_ns: int, data: bytes) -> None:
        """Writes one CDR-serialised message received at ``timestamp_ns``."""
        self._writer.write(self._connections[topic], timestamp_ns, data)
        self.counts[topic] += 1

    def close(self) -> None:
        """Finishes the MCAP file and writes ``metadata.yaml``; idempotent."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
