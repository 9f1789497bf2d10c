"""
Message types of bags and live playback: the node's inputs and outputs, the typestore.

The ``rosbags`` typestore (ROS 2 Jazzy types plus ``awp_ros_msgs``, registered from its
``.msg`` files) provides the message definitions and RIHS01 hashes a bag stores for each
topic, and serialises the gait generator's messages with zero padding (``rclpy``'s
serialiser leaves padding bytes uninitialised, so its output is not byte-reproducible).
:func:`message_class` finds the rclpy (Python interface) class of a type for live DDS.
"""

from __future__ import annotations

import functools
import importlib
import os
from pathlib import Path
import sys

from awp_ros.errors import BagError

__all__ = ['CONTACT_STATE', 'IMU', 'INPUT_TOPICS', 'JOINT_STATE', 'OUTPUT_TYPES', 'message_class',
           'msg_dirs', 'serialize', 'typestore']

JOINT_STATE = 'sensor_msgs/msg/JointState'
CONTACT_STATE = 'awp_ros_msgs/msg/ContactState'
IMU = 'sensor_msgs/msg/Imu'
#: Default input topics: role -> (topic, type). The node subscribes to these names.
INPUT_TOPICS = {
    'joint_states': ('/joint_states', JOINT_STATE),
    'contacts': ('/contacts', CONTACT_STATE),
    'imu': ('/imu', IMU),
}
#: Message type of each output of the node's pipeline (topic ``/<node_name>/<output>``).
OUTPUT_TYPES = {'report': 'awp_ros_msgs/msg/FeasibilityReport',
                'awp': 'awp_ros_msgs/msg/WrenchPolytope',
                'fwp': 'awp_ros_msgs/msg/WrenchPolytope',
                'fws': 'awp_ros_msgs/msg/WrenchPolytope',
                'leg_polytopes': 'awp_ros_msgs/msg/LegPolytopes',
                'markers': 'visualization_msgs/msg/MarkerArray',
                'feasible_region': 'geometry_msgs/msg/PolygonStamped',
                'support_region': 'geometry_msgs/msg/PolygonStamped'}
_MSG_PACKAGE = 'awp_ros_msgs'


def msg_dirs() -> list[Path]:
    """
    Return the folders searched for the ``awp_ros_msgs`` ``.msg`` files, in order.

    ``<sys.prefix>/share/awp_ros_msgs/msg``, the same under every ``$AMENT_PREFIX_PATH``
    entry, then the source tree's ``msg_defs/msg``.
    """
    prefixes = [sys.prefix] + [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(
        os.pathsep) if p]
    dirs = [Path(p, 'share', _MSG_PACKAGE, 'msg') for p in prefixes]
    dirs.append(Path(__file__).resolve().parents[2] / 'msg_defs' / 'msg')
    return [d for d in dict.fromkeys(dirs) if d.is_dir() and any(d.glob('*.msg'))]


@functools.lru_cache(maxsize=1)
def typestore():
    """
    Return the rosbags typestore of ROS 2 Jazzy plus ``awp_ros_msgs`` (cached).

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


def message_class(msgtype: str):
    """
    Return the rclpy message class of ``pkg/msg/Name``.

    :raises BagError: the type's Python package is not installed (unknown message type).
    """
    parts = msgtype.split('/')
    if len(parts) != 3 or not all(parts):
        raise BagError(f'unknown message type {msgtype!r} (expected pkg/msg/Name)')
    pkg, kind, name = parts
    try:
        module = importlib.import_module(f'{pkg}.{kind}')
        return getattr(module, name)
    except (ImportError, AttributeError) as exc:
        raise BagError(f'unknown message type {msgtype!r}: no Python interface for it is '
                       f'installed ({exc})') from exc


def serialize(msg, msgtype: str) -> bytes:
    """
    Return an rclpy message as CDR bytes of exactly its serialized length.

    rclpy's ``serialize_message`` (rmw_fastrtps) returns a buffer sized by an estimate that
    counts 8-byte alignment for empty ``float64[]`` sequences, so it can end with a few
    bytes of garbage; strict readers (rosbags: at most 3 trailing bytes) reject such a bag.
    The true length is where the typestore's deserializer stops, rounded up to 4 bytes.
    """
    from rclpy.serialization import serialize_message

    raw = bytes(serialize_message(msg))
    store = typestore()
    msgdef = store.get_msgdef(msgtype)
    func = msgdef.deserialize_cdr_le if raw[1] else msgdef.deserialize_cdr_be
    _, pos = func(raw[4:], 0, msgdef.cls, store)
    end = 4 + pos + (-pos % 4)
    return raw[:end] if end < len(raw) else raw
