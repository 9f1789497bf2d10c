"""
Serialize flat ROS 2 messages to CDR bytes without building the message object.

A report is published once per joint state; building the generated ``FeasibilityReport``
(its property setters check every value) and converting it to C for the middleware cost
more than the evaluation's smaller stages. :class:`CdrLayout` packs a message's fields,
given in declaration order with nested messages flattened, straight into the bytes
``rclpy.serialization.serialize_message`` would produce (XCDR1 little endian, the
encapsulation header ``00 01 00 00``, every primitive aligned to its size from the start of
the payload), which ``Publisher.publish`` sends as they are.

Supported field types: the fixed-size primitives, ``string``, fixed arrays of primitives,
``sequence<string>`` and nested messages of these (what ``FeasibilityReport`` uses).
``test/ros/test_cdr.py`` checks the bytes against ``serialize_message`` of the generated
message holding the same values.
"""

from __future__ import annotations

from functools import lru_cache
import importlib
import re
import struct

from builtin_interfaces.msg import Time
import numpy as np

__all__ = ['CdrLayout', 'JointStateBytes', 'layout', 'report_stamp_status', 'report_status',
           'stamped']

# type name -> (struct code, size)
_PRIMITIVES = {
    'boolean': ('?', 1), 'octet': ('B', 1), 'byte': ('B', 1), 'char': ('b', 1),
    'uint8': ('B', 1), 'int8': ('b', 1), 'uint16': ('H', 2), 'int16': ('h', 2),
    'uint32': ('I', 4), 'int32': ('i', 4), 'uint64': ('Q', 8), 'int64': ('q', 8),
    'float': ('f', 4), 'double': ('d', 8), 'float32': ('f', 4), 'float64': ('d', 8),
}
_ARRAY = re.compile(r'^(\w+)\[(\d+)\]$')
_HEADER = b'\x00\x01\x00\x00'            # CDR_LE encapsulation


class CdrLayout:
    """
    The flattened fields of one message type and their CDR packing.

    :ivar names: the flattened field names in order (``'header.stamp.sec'``, ...).
    :ivar kinds: per field ``('p', code, size)`` a primitive, ``('a', code, size, n)`` a
        fixed array, ``('s',)`` a string, ``('S',)`` a sequence of strings.
    """

    def __init__(self, msg_type: type) -> None:
        self.names: list[str] = []
        self.kinds: list[tuple] = []
        self._add(msg_type, '')
        self._dynamic = tuple(i for i, k in enumerate(self.kinds) if k[0] in 'sS')
        self._structs: dict[tuple, struct.Struct] = {}

    def _add(self, msg_type: type, prefix: str) -> None:
        for name, kind in msg_type.get_fields_and_field_types().items():
            full = prefix + name
            match = _ARRAY.match(kind)
            if kind in _PRIMITIVES:
                self.kinds.append(('p',) + _PRIMITIVES[kind])
            elif match and match.group(1) in _PRIMITIVES:
                self.kinds.append(('a',) + _PRIMITIVES[match.group(1)]
                                  + (int(match.group(2)),))
            elif kind == 'string':
                self.kinds.append(('s',))
            elif kind == 'sequence<string>':
                self.kinds.append(('S',))
            elif '/' in kind and '<' not in kind and '[' not in kind:
                package, cls = kind.split('/')
                nested = getattr(importlib.import_module(f'{package}.msg'), cls)
                self._add(nested, full + '.')
                continue
            else:
                raise TypeError(f'CdrLayout: field {full!r} of type {kind!r} is not supported')
            self.names.append(full)

    def _struct(self, values: tuple | list) -> struct.Struct:
        """Return the packer for the lengths of these values' strings (cached)."""
        key = tuple(len(values[i]) if self.kinds[i][0] == 's'
                    else tuple(len(s) for s in values[i]) for i in self._dynamic)
        packer = self._structs.get(key)
        if packer is None:
            packer = struct.Struct(self._format(key))
            if len(self._structs) > 4096:        # unbounded variety of messages: start over
                self._structs.clear()
            self._structs[key] = packer
        return packer

    def _format(self, key: tuple) -> str:
        """Return the struct format of the payload for the given string lengths (bytes)."""
        out = ['<']
        offset = 0
        lengths = iter(key)

        def align(size: int) -> None:
            nonlocal offset
            pad = -offset % size
            if pad:
                out.append(f'{pad}x')
                offset += pad

        def string(n: int) -> None:
            nonlocal offset
            align(4)
            out.append(f'I{n + 1}s')
            offset += 4 + n + 1

        for kind in self.kinds:
            if kind[0] == 'p':
                align(kind[2])
                out.append(kind[1])
                offset += kind[2]
            elif kind[0] == 'a':
                align(kind[2])
                out.append(f'{kind[3]}{kind[1]}')
                offset += kind[2] * kind[3]
            elif kind[0] == 's':
                string(next(lengths))
            else:
                items = next(lengths)
                align(4)
                out.append('I')
                offset += 4
                for n in items:
                    string(n)
        return ''.join(out)

    def pack(self, values: tuple | list) -> bytes:
        """
        Return the serialized message of flattened ``values`` (in :attr:`names` order).

        Strings are given as ``bytes`` (UTF-8), string sequences as lists of ``bytes``,
        fixed arrays as sequences of numbers.
        """
        packer = self._struct(values)
        args = []
        append, extend = args.append, args.extend
        for kind, value in zip(self.kinds, values):
            tag = kind[0]
            if tag == 'p':
                append(value)
            elif tag == 'a':
                extend(value)
            elif tag == 's':
                append(len(value) + 1)
                append(value)
            else:
                append(len(value))
                for item in value:
                    append(len(item) + 1)
                    append(item)
        return _HEADER + packer.pack(*args)


@lru_cache(maxsize=None)
def layout(msg_type: type) -> CdrLayout:
    """Return the (cached) :class:`CdrLayout` of a generated message class."""
    return CdrLayout(msg_type)


def report_stamp_status(data: bytes) -> tuple[int, int]:
    """
    Return the header stamp [ns] and the status of a serialized ``FeasibilityReport``.

    Read from the CDR bytes without deserializing the message (the soak's subscriber, on the
    node's cores, keeps to what it measures): a 4-byte encapsulation header (little endian,
    ``00 01``), ``int32 sec``, ``uint32 nanosec``, the ``frame_id`` string (``uint32`` length
    with its NUL, then the bytes) and the ``uint8 status`` right after it.
    """
    if data[:2] != b'\x00\x01':
        raise ValueError(f'not a little-endian CDR message: {data[:4]!r}')
    sec, nanosec, length = struct.unpack_from('<iII', data, 4)
    return sec * 1_000_000_000 + nanosec, data[16 + length]


def stamped(data: bytearray, ns: int) -> bytes:
    """
    Return a serialized message whose first field is a ``std_msgs/Header`` with stamp ``ns`` [ns].

    Written into ``data`` in place (``int32 sec``, ``uint32 nanosec`` right after the 4-byte
    encapsulation header), then copied out: a message serialized once is sent with a new
    stamp each time (the soak's driver).
    """
    _INTS2.pack_into(data, 4, *divmod(ns, 1_000_000_000))
    return bytes(data)


def report_status(data: bytes) -> tuple[int, str, float]:
    """
    Return the ``status``, ``status_message`` and ``compute_time`` of a serialized report.

    After the status (:func:`report_stamp_status`) the message string is 4-aligned in the
    payload; ``float64 compute_time`` is the report's last field, its last 8 bytes.
    """
    _, status = report_stamp_status(data)
    at = 17 + struct.unpack_from('<I', data, 12)[0]        # the status byte, then align 4
    at += -(at - 4) % 4
    length, = struct.unpack_from('<I', data, at)
    message = data[at + 4:at + 3 + length].decode()
    compute_time, = struct.unpack_from('<d', data, len(data) - 8)
    return status, message, compute_time


class _Header:
    """``std_msgs/Header`` fields of a :class:`JointStateBytes` (``stamp`` a real ``Time``)."""

    __slots__ = ('stamp', 'frame_id')

    def __init__(self, stamp: Time, frame_id: str) -> None:
        self.stamp, self.frame_id = stamp, frame_id


class JointStateBytes:
    """
    A serialized ``sensor_msgs/JointState`` read straight from its CDR bytes.

    What the node takes from its joint-state subscription (``raw``): rclpy's conversion
    builds the generated message through its checked setters (~10 us, 3x that with the
    node's caches cold); reading the bytes costs a few us. ``header.stamp`` (a
    ``builtin_interfaces/Time``), ``header.frame_id``, ``name`` (a tuple of str: the same
    tuple while the names' bytes repeat, as they do in a stream), ``position``, ``velocity``
    and ``effort`` (read-only float64 arrays over the bytes) are what the pipeline reads of
    a ``JointState``. :meth:`parse` raises ``ValueError`` on bytes that are not one.
    """

    __slots__ = ('header', 'name', 'position', 'velocity', 'effort')

    _names_block = b''
    _names: tuple[str, ...] = ()

    @classmethod
    def parse(cls, data: bytes) -> JointStateBytes:
        """Return the message in ``data`` (XCDR1 little endian); ValueError when malformed."""
        if data[:2] != b'\x00\x01':
            raise ValueError(f'not a little-endian CDR message: {data[:4]!r}')
        try:
            sec, nanosec, length = _INTS3.unpack_from(data, 4)
            frame_id = data[16:15 + length].decode()
            at = _align4(16 + length)
            start = at
            block = cls._names_block
            if block and data[start:start + len(block)] == block:    # the names as before
                names, at = cls._names, start + len(block)
            else:
                count, = _UINT.unpack_from(data, at)
                at += 4
                items = []
                for _ in range(count):
                    at = _align4(at)
                    n, = _UINT.unpack_from(data, at)
                    items.append(data[at + 4:at + 3 + n].decode())
                    at += 4 + n
                names = tuple(items)
                cls._names_block, cls._names = data[start:at], names
            arrays = []
            for _ in range(3):
                at = _align4(at)
                count, = _UINT.unpack_from(data, at)
                at += 4
                if not count:
                    arrays.append(_EMPTY)
                    continue
                at += -(at - 4) % 8
                arrays.append(np.frombuffer(data, '<f8', count, at))
                at += 8 * count
        except (struct.error, UnicodeDecodeError, ValueError) as exc:
            raise ValueError(f'not a serialized sensor_msgs/JointState: {exc}') from exc
        out = cls.__new__(cls)
        stamp = Time()
        stamp.sec, stamp.nanosec = sec, nanosec
        out.header = _Header(stamp, frame_id)
        out.name = names
        out.position, out.velocity, out.effort = arrays
        return out


_INTS3 = struct.Struct('<iII')
_INTS2 = struct.Struct('<iI')
_EMPTY = np.zeros(0)
_EMPTY.setflags(write=False)
_UINT = struct.Struct('<I')


def _align4(at: int) -> int:
    """Return ``at`` (a byte offset in the message, payload from 4) aligned to 4."""
    return at + (-(at - 4) % 4)
