"""
Read rosbag2 files (mcap or sqlite3) with ``rosbags``, as raw CDR messages.

Messages travel as raw CDR bytes (:class:`BagMessage`), so a bag is copied or replayed
without a round trip through Python objects. A bag path is a rosbag2 directory
(``metadata.yaml`` plus storage files) or a single ``.mcap`` / ``.db3`` file. Every failure
to read raises :class:`~awp_ros.errors.BagError` naming the file and the problem (a
truncated or corrupt file is called that).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass
import os
from pathlib import Path
import sqlite3
import struct

from awp_ros.errors import BagError

__all__ = ['BagMessage', 'TopicInfo', 'BagInfo', 'STORAGES', 'bag_info', 'read_bag',
           'require_topics']

#: Storage of a single-file bag by its suffix.
STORAGES = {'.mcap': 'mcap', '.db3': 'sqlite3'}


@dataclass(frozen=True)
class BagMessage:
    """
    One serialised message of a bag.

    Its ``topic``, ``msgtype`` (``pkg/msg/Name``), log time [ns] since the epoch, and its CDR
    bytes (with the 4-byte encapsulation header).
    """

    topic: str
    msgtype: str
    timestamp: int
    data: bytes


@dataclass(frozen=True)
class TopicInfo:
    """
    A topic of a bag.

    Its type, message count, definition (``ros2msg`` text, may be empty) and RIHS01 type hash
    (may be empty).
    """

    msgtype: str
    count: int
    msgdef: str = ''
    digest: str = ''


@dataclass(frozen=True)
class BagInfo:
    """
    Summary of a bag.

    Storage (``mcap`` / ``sqlite3``), topics, message count, first and last log times [ns].
    """

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
    """
    Return the topics, counts and time range of a bag.

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
        return STORAGES.get(path.suffix, path.suffix)
    return 'mcap' if any(path.glob('*.mcap')) else 'sqlite3'


def read_bag(path: str | os.PathLike, topics: Iterable[str] | None = None
             ) -> Iterator[BagMessage]:
    """
    Yield the messages of a bag in log-time order (ties: recorded order).

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
            require_topics(path, wanted, {c.topic for c in conns})
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


def require_topics(path: str | os.PathLike, wanted: Iterable[str], have: Iterable[str]
                   ) -> None:
    """
    Check that a bag has every ``wanted`` topic.

    :param have: the topics the bag at ``path`` has.
    :raises BagError: one is missing (the message names the topics the bag has).
    """
    have = sorted(set(have))
    missing = [t for t in wanted if t not in have]
    if missing:
        raise BagError(f'bag {str(path)!r} has no topic {missing[0]!r}; its topics are '
                       f'{have}')
