"""Read and write rosbag2 files (mcap or sqlite3) with ``rosbags``, awp_ros_msgs included.

Messages travel as raw CDR bytes (:class:`BagMessage`), so a bag is copied or replayed
without a round trip through Python objects. The ``rosbags`` typestore (ROS 2 Jazzy types
plus ``awp_ros_msgs``, registered from its ``.msg`` files) provides the message
definitions and RIHS01 hashes a bag stores for each topic, and serialises the gait
generator's messages with zero padding (``rclpy``'s serialiser leaves padding bytes
uninitialised, so its output is not byte-reproducible).

A bag path is a rosbag2 directory (``metadata.yaml`` plus storage files) or a single
``.mcap`` / ``.db3`` file. Writing to a path ending in ``.mcap`` or ``.db3`` produces that
single file (Foxglove opens ``.mcap`` files directly); any other path becomes a rosbag2
directory. Every failure to read or write raises :class:`~awp_ros.errors.BagError` naming
the file and the problem.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
import functools
import os
from pathlib import Path
import shutil
import sqlite3
import struct
import sys
import tempfile

import numpy as np

from awp_ros.errors import BagError

__all__ = [
    'BagMessage', 'BagInfo', 'TopicInfo', 'BagWriter', 'read_bag', 'bag_info', 'typestore',
    'msg_dirs', 'gait_messages', 'write_gait_bag', 'default_bag_path', 'JOINT_STATE',
    'CONTACT_STATE', 'IMU', 'INPUT_TOPICS', 'DEFAULT_START_NS', 'DEFAULT_BAG_NAME',
    'DEFAULT_IMU_RATE_HZ',
    'reliable_qos',
]

JOINT_STATE = 'sensor_msgs/msg/JointState'
CONTACT_STATE = 'awp_ros_msgs/msg/ContactState'
IMU = 'sensor_msgs/msg/Imu'
#: Default input topics: role -> (topic, type). The node subscribes to these names.
INPUT_TOPICS = {
    'joint_states': ('/joint_states', JOINT_STATE),
    'contacts': ('/contacts', CONTACT_STATE),
    'imu': ('/imu', IMU),
}
#: First stamp of generated bags: 2024-01-01T00:00:00Z [ns]. Fixed for reproducible bytes.
DEFAULT_START_NS = 1_704_067_200 * 10**9
DEFAULT_BAG_NAME = 'hyq_gait.mcap'
#: IMU rate of the default bag [Hz] (joint states and contacts: the gait's 500 Hz).
DEFAULT_IMU_RATE_HZ = 100.0
_STORAGES = {'.mcap': 'mcap', '.db3': 'sqlite3'}
_MSG_PACKAGE = 'awp_ros_msgs'


@dataclass(frozen=True)
class BagMessage:
    """One serialised message: ``topic``, ``msgtype`` (``pkg/msg/Name``), log time [ns]
    since the epoch, and its CDR bytes (with the 4-byte encapsulation header)."""

    topic: str
    msgtype: str
    timestamp: int
    data: bytes


@dataclass(frozen=True)
class TopicInfo:
    """A topic of a bag: its type, message count, definition (``ros2msg`` text, may be
    empty) and RIHS01 type hash (may be empty)."""

    msgtype: str
    count: int
    msgdef: str = ''
    digest: str = ''


@dataclass(frozen=True)
class BagInfo:
    """Summary of a bag: storage (``mcap`` / ``sqlite3``), topics, message count, first and
    last log times [ns]."""

    path: str
    storage: str
    topics: dict
    message_count: int
    start_ns: int
    end_ns: int

    @property
    def duration_s(self) -> float:
        """Return the time between the first and last message [s]."""
        return max(0, self.end_ns - self.start_ns) * 1e-9


# -- types ------------------------------------------------------------------------------------


def msg_dirs() -> list[Path]:
    """Return the folders searched for the ``awp_ros_msgs`` ``.msg`` files, in order.

    ``<sys.prefix>/share/awp_ros_msgs/msg``, the same under every ``$AMENT_PREFIX_PATH``
    entry, then the source tree's ``msg_defs/msg``.
    """
    prefixes = [sys.prefix] + [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(
        os.pathsep) if p]
    dirs = [Path(p, 'share', _MSG_PACKAGE, 'msg') for p in prefixes]
    dirs.append(Path(__file__).resolve().parent.parent / 'msg_defs' / 'msg')
    return [d for d in dict.fromkeys(dirs) if d.is_dir() and any(d.glob('*.msg'))]


@functools.lru_cache(maxsize=1)
def typestore():
    """Return the rosbags typestore of ROS 2 Jazzy plus ``awp_ros_msgs`` (cached).

    :raises BagError: the ``awp_ros_msgs`` ``.msg`` files are nowhere to be found.
    """
    from rosbags.typesys import get_types_from_msg, get_typestore, Stores

    store = get_typestore(Stores.ROS2_JAZZY)
    dirs = msg_dirs()
    if not dirs:
        raise BagError(f'cannot find the {_MSG_PACKAGE} .msg files (looked in '
                       f'<prefix>/share/{_MSG_PACKAGE}/msg and msg_defs/msg)')
    types: dict = {}
    for path in sorted(dirs[0].glob('*.msg')):
        types.update(get_types_from_msg(path.read_text(encoding='utf-8'),
                                        f'{_MSG_PACKAGE}/msg/{path.stem}'))
    store.register(types)
    return store


def reliable_qos(depth: int = 1000):
    """Return the offered QoS stored with each written topic: reliable, volatile, keep last."""
    from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness,
                                    QosReliability, QosTime)

    zero = QosTime(sec=0, nsec=0)
    return Qos(history=QosHistory.KEEP_LAST, depth=depth,
               reliability=QosReliability.RELIABLE, durability=QosDurability.VOLATILE,
               deadline=zero, lifespan=zero, liveliness=QosLiveliness.AUTOMATIC,
               liveliness_lease_duration=zero, avoid_ros_namespace_conventions=False)


# -- reading ----------------------------------------------------------------------------------


def _open_reader(path: str | os.PathLike):
    from rosbags.rosbag2 import Reader

    path = Path(path)
    if not path.exists():
        raise BagError(f'bag {str(path)!r} does not exist')
    try:
        reader = Reader(path)
        reader.open()
    except BagError:
        raise
    except Exception as exc:  # noqa: BLE001 -- rosbags, yaml, sqlite3, struct, OS errors
        raise BagError(f'cannot open bag {str(path)!r}: {_describe(exc)}') from exc
    return reader


_CORRUPT_HINTS = ('runcated', 'magic', 'malformed', 'seems to be empty', 'missing tables',
                  'not a database', 'checksum', 'size mismatch', 'exceeds', 'Unexpected record',
                  'nvalid')


def _describe(exc: BaseException) -> str:
    """Return a reason for a rosbags/sqlite3/struct failure, naming truncation plainly."""
    text = str(exc) or type(exc).__name__
    if isinstance(exc, (struct.error, EOFError, sqlite3.DatabaseError)) \
            or any(h in text for h in _CORRUPT_HINTS):
        return f'the file is truncated or corrupt ({text})'
    return text


def bag_info(path: str | os.PathLike) -> BagInfo:
    """Return the topics, counts and time range of a bag.

    :raises BagError: the bag does not exist or cannot be read.
    """
    reader = _open_reader(path)
    try:
        topics = {}
        for conn in reader.connections:
            old = topics.get(conn.topic)
            count = conn.msgcount + (old.count if old else 0)
            topics[conn.topic] = TopicInfo(conn.msgtype, count, conn.msgdef.data or '',
                                           conn.digest or '')
        storage = _storage_of(Path(path), reader)
        count = reader.message_count
        start = reader.start_time if count else 0
        end = reader.end_time - 1 if count else 0
    finally:
        reader.close()
    return BagInfo(str(path), storage, topics, count, start, end)


def _storage_of(path: Path, reader) -> str:
    if path.is_file():
        return _STORAGES.get(path.suffix, path.suffix)
    return 'mcap' if any(path.glob('*.mcap')) else 'sqlite3'


def read_bag(path: str | os.PathLike, topics: Iterable[str] | None = None
             ) -> Iterator[BagMessage]:
    """Yield the messages of a bag in log-time order (ties: recorded order).

    :param path: rosbag2 directory or ``.mcap`` / ``.db3`` file.
    :param topics: only these topics (all when None).
    :raises BagError: the bag does not exist, is truncated or corrupt, or a requested topic
        is missing (the message lists the topics the bag has).
    """
    reader = _open_reader(path)
    try:
        conns = reader.connections
        if topics is not None:
            wanted = list(topics)
            have = sorted({c.topic for c in conns})
            missing = [t for t in wanted if t not in have]
            if missing:
                raise BagError(f'bag {str(path)!r} has no topic {missing[0]!r}; its topics '
                               f'are {have}')
            conns = [c for c in conns if c.topic in wanted]
        try:
            for conn, timestamp, data in reader.messages(connections=conns):
                yield BagMessage(conn.topic, conn.msgtype, timestamp, bytes(data))
        except BagError:
            raise
        except Exception as exc:  # noqa: BLE001 -- rosbags raises many kinds
            raise BagError(f'cannot read bag {str(path)!r}: {_describe(exc)}') from exc
    finally:
        reader.close()


# -- writing ----------------------------------------------------------------------------------


class BagWriter:
    """Write :class:`BagMessage` s to a new bag; topics are added on first use.

    Use as a context manager. ``path`` ending in ``.mcap`` / ``.db3`` gives a single file,
    anything else a rosbag2 directory whose storage is ``storage`` (``'mcap'`` or
    ``'sqlite3'``). Definitions and hashes come from ``definitions`` (topic ->
    :class:`TopicInfo`, e.g. copied from an input bag) or else from :func:`typestore`.
    ``compress`` = zstd chunk compression of an mcap (readable by Foxglove, ros2 bag and
    rosbags; not byte-reproducible across zstd versions, so off for the default bag;
    ignored for sqlite3).

    :raises BagError: the path exists, a type is unknown, or writing fails.
    """

    def __init__(self, path: str | os.PathLike, *, storage: str = 'mcap',
                 definitions: dict | None = None, qos_depth: int = 1000,
                 compress: bool = False) -> None:
        self.path = Path(path)
        self.single_file = self.path.suffix in _STORAGES
        self.storage = _STORAGES[self.path.suffix] if self.single_file else storage
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


# -- the gait generator's messages ------------------------------------------------------------


def gait_messages(samples, *, start_ns: int = DEFAULT_START_NS, imu_rate_hz: float | None
                  = None, topics: dict | None = None) -> Iterator[BagMessage]:
    """Yield the messages of a :class:`~awp_ros.gait.GaitSamples` in log-time order.

    Per sample i, stamped ``start_ns + round(t_i * 1e9)``: a ``sensor_msgs/Imu`` (base
    orientation, angular velocity, specific force; frame = the base link; every
    ``rate / imu_rate_hz``-th sample; covariances zero = unknown), an
    ``awp_ros_msgs/ContactState`` (all feet, ``in_contact``; normals and friction
    coefficients left empty = the configured defaults) and a ``sensor_msgs/JointState``
    (every joint's position and velocity, no effort). The three carry the same header
    stamp; the IMU and contacts are logged 2 us and 1 us before the joint state, so that
    every reader and player delivers them first.

    :param imu_rate_hz: IMU rate [Hz]; None = the sample rate; 0 = no IMU.
    :param topics: role -> topic name overrides for ``joint_states``, ``contacts``, ``imu``.
    """
    store = typestore()
    types = store.types
    time_t, header_t = types['builtin_interfaces/msg/Time'], types['std_msgs/msg/Header']
    js_t, cs_t, imu_t = types[JOINT_STATE], types[CONTACT_STATE], types[IMU]
    quat_t, vec_t = types['geometry_msgs/msg/Quaternion'], types['geometry_msgs/msg/Vector3']
    names = {role: topic for role, (topic, _) in INPUT_TOPICS.items()}
    names.update(topics or {})
    rate = samples.rate_hz
    imu_every = 0
    if imu_rate_hz is None:
        imu_every = 1
    elif imu_rate_hz > 0:
        imu_every = max(1, int(round(rate / imu_rate_hz)))
    joints = list(samples.joint_names)
    feet = list(samples.feet)
    empty = np.zeros(0)
    zeros9 = np.zeros(9)
    for i in range(len(samples)):
        stamp_ns = start_ns + int(round(float(samples.t[i]) * 1e9))
        sec, nsec = divmod(stamp_ns, 10**9)
        header = header_t(stamp=time_t(sec=sec, nanosec=nsec), frame_id='')
        if imu_every and i % imu_every == 0:
            x, y, z, w = (float(c) for c in samples.base_quaternion[i])
            imu = imu_t(
                header=header_t(stamp=time_t(sec=sec, nanosec=nsec),
                                frame_id=samples.base_frame),
                orientation=quat_t(x=x, y=y, z=z, w=w), orientation_covariance=zeros9,
                angular_velocity=vec_t(*(float(c) for c in samples.angular_velocity[i])),
                angular_velocity_covariance=zeros9,
                linear_acceleration=vec_t(*(float(c) for c in samples.specific_force[i])),
                linear_acceleration_covariance=zeros9)
            yield BagMessage(names['imu'], IMU, stamp_ns - 2000,
                             bytes(store.serialize_cdr(imu, IMU)))
        contacts = cs_t(header=header, names=feet,
                        in_contact=np.asarray(samples.stance[i], dtype=bool), normals=[],
                        friction_coefficients=empty)
        yield BagMessage(names['contacts'], CONTACT_STATE, stamp_ns - 1000,
                         bytes(store.serialize_cdr(contacts, CONTACT_STATE)))
        js = js_t(header=header, name=joints, position=np.asarray(samples.q[i], dtype=float),
                  velocity=np.asarray(samples.v[i], dtype=float), effort=empty)
        yield BagMessage(names['joint_states'], JOINT_STATE, stamp_ns,
                         bytes(store.serialize_cdr(js, JOINT_STATE)))


def write_gait_bag(samples, path: str | os.PathLike, *, storage: str = 'mcap',
                   start_ns: int = DEFAULT_START_NS, imu_rate_hz: float | None = None,
                   topics: dict | None = None) -> Path:
    """Write :func:`gait_messages` to a new bag and return its path.

    The bytes depend only on the samples, the arguments and the ``rosbags`` version (its
    name is in the MCAP header): no wall-clock time, fixed metadata.
    """
    path = Path(path)
    with BagWriter(path, storage=storage) as writer:
        writer.write_all(gait_messages(samples, start_ns=start_ns, imu_rate_hz=imu_rate_hz,
                                       topics=topics))
    return path


def default_bag_path() -> Path:
    """Return the committed default input bag (``config/hyq_gait.mcap``).

    Looked up in the config folders of :func:`awp_ros.robot_config.config_dirs` (installed
    share folder first, then the source tree).

    :raises BagError: not found anywhere.
    """
    from awp_ros.robot_config import config_dirs

    dirs: Sequence[Path] = config_dirs()
    for d in dirs:
        candidate = d / DEFAULT_BAG_NAME
        if candidate.is_file():
            return candidate
    raise BagError(f'default bag {DEFAULT_BAG_NAME!r} not found in {[str(d) for d in dirs]}; '
                   'regenerate it with: python -m awp_ros.gait')
