"""
Write rosbag2 files (mcap or sqlite3) with ``rosbags``, from raw CDR messages.

Writing to a path ending in ``.mcap`` or ``.db3`` produces that single file (Foxglove opens
``.mcap`` files directly; it is written in a temporary folder next to it and moved into
place when complete); any other path becomes a rosbag2 directory. Topics get the
definitions and RIHS01 hashes of the input bag they were copied from, or else those of
:func:`awp_ros.bags.message_types.typestore`. Every failure raises
:class:`~awp_ros.errors.BagError` naming the file and the problem, and leaves no partial output
behind.
"""

from __future__ import annotations

from collections.abc import Iterable
import os
from pathlib import Path
import shutil
import tempfile

from awp_ros.bags.message_types import typestore
from awp_ros.bags.reader import BagMessage, STORAGES
from awp_ros.errors import BagError

__all__ = ['BagWriter', 'reliable_qos', 'remove_path']


class BagWriter:
    """
    Write :class:`BagMessage` s to a new bag; topics are added on first use.

    Use as a context manager. ``path`` ending in ``.mcap`` / ``.db3`` gives a single file,
    anything else a rosbag2 directory whose storage is ``storage`` (``'mcap'`` or
    ``'sqlite3'``). Definitions and hashes come from ``definitions`` (topic ->
    :class:`~awp_ros.bags.reader.TopicInfo`, e.g. copied from an input bag) or else from
    :func:`~awp_ros.bags.message_types.typestore`.
    ``compress`` = zstd chunk compression of an mcap (readable by Foxglove, ros2 bag and
    rosbags; not byte-reproducible across zstd versions, so off for the default bag;
    ignored for sqlite3).

    :raises BagError: the path exists, a type is unknown, or writing fails.
    """

    def __init__(self, path: str | os.PathLike, *, storage: str = 'mcap',
                 definitions: dict | None = None, qos_depth: int = 1000,
                 compress: bool = False) -> None:
        self.path = Path(path)
        self.single_file = self.path.suffix in STORAGES
        self.storage = STORAGES[self.path.suffix] if self.single_file else storage
        if self.storage not in ('mcap', 'sqlite3'):
            raise BagError(f'unknown bag storage {storage!r}; storages are mcap, sqlite3')
        if self.path.exists():
            raise BagError(f'output bag {str(self.path)!r} exists already; not overwriting')
        self.definitions = dict(definitions or {})
        self.qos_depth = qos_depth
        self.compress = compress
        self.counts: dict[str, int] = {}
        self._connections: dict = {}
        self._writer = None
        self._tmp: tempfile.TemporaryDirectory | None = None

    def __enter__(self) -> BagWriter:
        """Open the bag."""
        from rosbags.rosbag2 import StoragePlugin, Writer

        if self.single_file:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._tmp = tempfile.TemporaryDirectory(dir=self.path.parent,
                                                    prefix='.awp_bag_')
            target = Path(self._tmp.name) / self.path.stem
        else:
            target = self.path
        plugin = StoragePlugin.MCAP if self.storage == 'mcap' else StoragePlugin.SQLITE3
        try:
            self._writer = Writer(target, version=9, storage_plugin=plugin)
            if self.compress and self.storage == 'mcap':   # sqlite3: no chunks
                from rosbags.rosbag2 import CompressionFormat, CompressionMode
                self._writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
            self._writer.open()
        except Exception as exc:  # noqa: BLE001
            self._cleanup()
            raise BagError(f'cannot create bag {str(self.path)!r}: {exc}') from exc
        return self

    def write(self, msg: BagMessage) -> None:
        """Append one message (topics must keep one type)."""
        conn = self._connections.get(msg.topic)
        if conn is None:
            conn = self._add(msg.topic, msg.msgtype)
        elif conn.msgtype != msg.msgtype:
            raise BagError(f'topic {msg.topic!r} is {conn.msgtype}; cannot also write '
                           f'{msg.msgtype}')
        self._writer.write(conn, msg.timestamp, msg.data)
        self.counts[msg.topic] = self.counts.get(msg.topic, 0) + 1

    def write_all(self, messages: Iterable[BagMessage]) -> None:
        """Append messages in order."""
        for msg in messages:
            self.write(msg)

    def _add(self, topic: str, msgtype: str):
        info = self.definitions.get(topic)
        kwargs: dict
        if info is not None and info.msgdef and info.digest and info.msgtype == msgtype:
            kwargs = {'msgdef': info.msgdef, 'rihs01': info.digest}
        else:
            store = typestore()
            if msgtype not in store.fielddefs:
                raise BagError(f'unknown message type {msgtype!r} on topic {topic!r}: no '
                               'definition in the bag nor in the ROS 2 Jazzy + awp_ros_msgs '
                               'types')
            kwargs = {'typestore': store}
        conn = self._writer.add_connection(topic, msgtype,
                                           offered_qos_profiles=[reliable_qos(self.qos_depth)],
                                           **kwargs)
        self._connections[topic] = conn
        return conn

    def __exit__(self, exc_type, exc, tb) -> bool:
        """Close the bag (keep nothing on error)."""
        writer, self._writer = self._writer, None
        if exc_type is not None:
            if writer is not None:
                writer.abort()
            self._cleanup(remove_output=True)
            return False
        try:
            writer.close()
        except Exception as err:  # noqa: BLE001
            self._cleanup(remove_output=True)
            raise BagError(f'cannot finish bag {str(self.path)!r}: {err}') from err
        if self.single_file:
            src = Path(self._tmp.name) / self.path.stem / f'{self.path.stem}{self.path.suffix}'
            shutil.move(str(src), self.path)
        self._cleanup()
        return False

    def _cleanup(self, remove_output: bool = False) -> None:
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None
        if remove_output and not self.single_file and self.path.exists():
            shutil.rmtree(self.path, ignore_errors=True)


def reliable_qos(depth: int = 1000):
    """Return the offered QoS stored with each written topic: reliable, volatile, keep last."""
    from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness,
                                    QosReliability, QosTime)

    zero = QosTime(sec=0, nsec=0)
    return Qos(history=QosHistory.KEEP_LAST, depth=depth,
               reliability=QosReliability.RELIABLE, durability=QosDurability.VOLATILE,
               deadline=zero, lifespan=zero, liveliness=QosLiveliness.AUTOMATIC,
               liveliness_lease_duration=zero, avoid_ros_namespace_conventions=False)


def remove_path(path: Path) -> None:
    """Remove ``path`` if it exists: a directory with its contents (rosbag2 folder), or a file."""
    if path.is_dir():
        shutil.rmtree(path)
    elif path.exists():
        path.unlink()
