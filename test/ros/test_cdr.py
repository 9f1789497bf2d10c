"""CDR packing of flat messages (awp_ros.ros.cdr) against the generated typesupport."""

from __future__ import annotations

import re
import struct

from awp_ros_msgs.msg import FeasibilityReport
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Wrench
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Header

from awp_ros.ros.cdr import (CdrLayout, JointStateBytes, layout, report_stamp_status,
                             report_status)


def _set(msg, path: str, value) -> None:
    *parents, name = path.split('.')
    for p in parents:
        msg = getattr(msg, p)
    setattr(msg, name, value)


def _random_message(rng, cls):
    """Return (message set field by field, the same values flattened for CdrLayout.pack)."""
    msg, values = cls(), []
    lay = layout(cls)
    for name, kind in zip(lay.names, lay.kinds):
        if kind[0] == 's':       # UTF-8 of 0-12 characters, some of 2 bytes (lengths in bytes)
            s = ''.join(rng.choice(list('abé_ x'), size=int(rng.integers(0, 13))))
            _set(msg, name, s)
            values.append(s.encode())
        elif kind[0] == 'S':
            items = [''.join(rng.choice(list('ab_c'), size=int(rng.integers(0, 9))))
                     for _ in range(int(rng.integers(0, 6)))]
            _set(msg, name, items)
            values.append([s.encode() for s in items])
        elif kind[0] == 'a':
            a = rng.normal(size=kind[3]) * 10.0 ** rng.integers(-3, 4)
            _set(msg, name, a)
            values.append(a.tolist())
        elif kind[1] == '?':
            v = bool(rng.integers(2))
            _set(msg, name, v)
            values.append(v)
        elif kind[1] in 'bBhHiIqQ':
            v = int(rng.integers(0, 120))
            _set(msg, name, v)
            values.append(v)
        else:
            v = float(rng.choice([rng.normal(), np.inf, -0.0, 1e300]))
            _set(msg, name, v)
            values.append(v)
    return msg, values


def _not_padding(lay: CdrLayout, values) -> np.ndarray:
    """Return which bytes of the packed message are not alignment padding (``x`` codes)."""
    keep = [True] * 4                            # the encapsulation header
    for count, code in re.findall(r'(\d*)([a-zA-Z?])', lay._struct(values).format[1:]):
        size = struct.calcsize(f'<{count}{code}')
        keep += [code != 'x'] * size
    return np.array(keep)


@pytest.mark.parametrize('cls', [FeasibilityReport, Header, Wrench, Time])
def test_packed_bytes_are_the_typesupport_bytes_but_for_padding(cls):
    rng = np.random.default_rng(7)
    lay = layout(cls)
    for _ in range(150):
        msg, values = _random_message(rng, cls)
        ours, theirs = lay.pack(values), serialize_message(msg)
        assert len(ours) == len(theirs)
        # Fast DDS leaves its padding bytes uninitialised: compare every other byte.
        keep = _not_padding(lay, values)
        a, b = np.frombuffer(ours, dtype=np.uint8), np.frombuffer(theirs, dtype=np.uint8)
        assert np.array_equal(a[keep], b[keep])
        assert deserialize_message(ours, cls) == msg


def test_report_status_and_stamp_read_from_the_bytes():
    rng = np.random.default_rng(3)
    for _ in range(100):
        msg, _ = _random_message(rng, FeasibilityReport)
        msg.compute_time = float(rng.uniform(0.0, 1.0))
        data = serialize_message(msg)
        assert report_stamp_status(data) == (
            msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec, msg.status)
        assert report_status(data) == (msg.status, msg.status_message, msg.compute_time)


def test_unsupported_fields_are_refused_by_name():
    with pytest.raises(TypeError, match="'position' of type 'sequence<double>'"):
        CdrLayout(JointState)


def _random_joint_state(rng, names_pool):
    msg = JointState()
    msg.header.stamp.sec = int(rng.integers(-2**31, 2**31))
    msg.header.stamp.nanosec = int(rng.integers(0, 10**9))
    msg.header.frame_id = ''.join(rng.choice(list('bé_1'), size=int(rng.integers(0, 9))))
    msg.name = list(names_pool[int(rng.integers(len(names_pool)))])
    k = len(msg.name)
    for field in ('position', 'velocity', 'effort'):     # one per name, none, or a wrong count
        n = int(rng.choice([k, 0, max(k - 1, 0), k + 2]))
        setattr(msg, field, (rng.normal(size=n) * 10.0 ** rng.integers(-3, 4)).tolist())
    return msg


def test_joint_state_bytes_read_what_the_typesupport_wrote():
    rng = np.random.default_rng(11)
    hyq = [f'{leg}_{j}_joint' for leg in ('lf', 'rf', 'lh', 'rh') for j in ('haa', 'hfe', 'kfe')]
    pool = [hyq, hyq[:6], hyq + ['é_wheel'], [], ['a'], ['ab', 'c'], ['abc'], hyq[::-1]]
    for _ in range(400):            # names repeat (the cache) and change (every pool entry)
        msg = _random_joint_state(rng, pool)
        got = JointStateBytes.parse(serialize_message(msg))
        ref = deserialize_message(serialize_message(msg), JointState)
        assert got.header.stamp == ref.header.stamp
        assert isinstance(got.header.stamp, Time)
        assert got.header.frame_id == ref.header.frame_id
        assert list(got.name) == list(ref.name)
        for field in ('position', 'velocity', 'effort'):
            assert np.array_equal(getattr(got, field), np.asarray(getattr(ref, field)))


@pytest.mark.parametrize('data', [b'', b'\x00\x01\x00\x00\x01', b'\x01\x00\x00\x00' + bytes(40),
                                  b'\x00\x01\x00\x00' + bytes(8) + b'\xff\xff\xff\x7f'])
def test_joint_state_bytes_refuse_what_is_not_one(data):
    with pytest.raises(ValueError):
        JointStateBytes.parse(data)
