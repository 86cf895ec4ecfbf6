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

What rosbag2 itself writes is written too, so that ``ros2 bag play`` and other
readers get the same bag as from ``ros2 bag record``: each topic's offered QoS
profiles (one per publisher; a replay offers them again, so a reliable,
transient-local lockstep topic is not replayed with default QoS) in
``metadata.yaml`` and in its MCAP channel's metadata, beside the channel's
``topic_type_hash``; and ``ros_distro: jazzy``.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterable, Sequence
from io import BytesIO
from pathlib import Path
from typing import Any, Final, Literal

from rosbags.interfaces import (
    Connection,
    ConnectionExtRosbag2,
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.storage_mcap import (
    Channel,
    McapWriter,
    write_channel,
    write_string,
)
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

BAG_VERSION: Final[Literal[9]] = 9
"""rosbag2 metadata version written (that of ROS 2 Jazzy)."""
PROJECT_INTERFACES = ("sdbc_msgs",)
"""Interface packages of this project, registered in every bag's type store."""
ROS_DISTRO = "jazzy"
"""The ROS 2 distribution the bags are written for (``ros_distro`` in the metadata)."""
_ROSBAGS_DISTRO_LINE = "ros_distro: rosbags"
"""What rosbags writes in place of the distribution."""


def _jazzy(metadata: str) -> str:
    """``metadata`` (rosbag2 YAML) with ``ros_distro`` naming the distribution."""
    if _ROSBAGS_DISTRO_LINE not in metadata:
        raise RuntimeError(
            f"rosbags wrote no '{_ROSBAGS_DISTRO_LINE}' line: its writer changed "
            "(requirements.txt pins the version this module was written for)"
        )
    return metadata.replace(_ROSBAGS_DISTRO_LINE, f"ros_distro: {ROS_DISTRO}")


def _rosbag2_ext(connection: Connection) -> ConnectionExtRosbag2:
    """The rosbag2 part of a connection of a rosbag2 bag."""
    if not isinstance(connection.ext, ConnectionExtRosbag2):
        raise TypeError(f"connection {connection.topic!r} is not of a rosbag2 bag")
    return connection.ext


class _Rosbag2McapWriter(McapWriter):
    """rosbags' MCAP storage, with the channel and bag metadata of rosbag2's own
    MCAP storage: ``topic_type_hash`` beside ``offered_qos_profiles`` on each
    channel, and the Jazzy distribution in the serialized bag metadata."""

    def add_connection(self, connection: Connection, offered_qos_profiles: str) -> None:
        metadata = BytesIO()
        for key, value in (
            ("offered_qos_profiles", offered_qos_profiles),
            ("topic_type_hash", connection.digest),
        ):
            write_string(metadata, key)
            write_string(metadata, value)
        self.channels.append(
            Channel(
                connection.id,
                connection.msgtype,
                connection.topic,
                _rosbag2_ext(connection).serialization_format,
                metadata.getvalue(),
            )
        )
        self.channel_stats[connection.id] = 0
        write_channel(self.chunk.bio, self.channels[-1], self.schemas)

    def close(self, version: int, metadata: str) -> None:
        super().close(version, _jazzy(metadata))


class _Rosbag2Writer(Writer):
    """rosbags' writer with :class:`_Rosbag2McapWriter` and ``ros_distro: jazzy``."""

    STORAGE_PLUGINS = {**Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: _Rosbag2McapWriter}

    def close(self) -> None:
        super().close()
        self.metapath.write_text(_jazzy(self.metapath.read_text()))


def _time(nanoseconds: int) -> QosTime:
    return QosTime(*divmod(int(nanoseconds), 10**9))


def bag_qos(profile: Any) -> Qos:
    """An rclpy QoS profile (a publisher's, from the graph) as rosbags writes it.

    Policies that rmw reports as unknown for another process's publisher (its
    history and depth) stay unknown, as rosbag2 records them.
    """
    return Qos(
        history=QosHistory[profile.history.name],
        depth=int(profile.depth),
        reliability=QosReliability[profile.reliability.name],
        durability=QosDurability[profile.durability.name],
        deadline=_time(profile.deadline.nanoseconds),
        lifespan=_time(profile.lifespan.nanoseconds),
        liveliness=QosLiveliness[profile.liveliness.name],
        liveliness_lease_duration=_time(profile.liveliness_lease_duration.nanoseconds),
        avoid_ros_namespace_conventions=bool(profile.avoid_ros_namespace_conventions),
    )


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
        writer = _Rosbag2Writer(
            self.path, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP
        )
        writer.open()
        self._writer: _Rosbag2Writer | None = writer
        self._connections: dict[str, Connection] = {}
        self.counts: dict[str, int] = {}

    def add_topic(
        self, topic: str, msgtype: str, offered_qos: Sequence[Qos] = ()
    ) -> None:
        """Declares a topic, its type and its publishers' offered QoS (see
        :func:`bag_qos`); the type's definition goes into the bag.

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
        self._connections[topic] = self._open().add_connection(
            topic,
            msgtype,
            typestore=self.typestore,
            offered_qos_profiles=list(offered_qos),
        )
        self.counts[topic] = 0

    @property
    def topics(self) -> tuple[str, ...]:
        """Topics added so far."""
        return tuple(self._connections)

    def write(self, topic: str, timestamp_ns: int, data: bytes) -> None:
        """Writes one CDR-serialised message received at ``timestamp_ns``."""
        self._open().write(self._connections[topic], timestamp_ns, data)
        self.counts[topic] += 1

    def _open(self) -> _Rosbag2Writer:
        if self._writer is None:
            raise ValueError(f"bag {self.path} is closed")
        return self._writer

    def close(self) -> None:
        """Finishes the MCAP file and writes ``metadata.yaml``; idempotent."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
