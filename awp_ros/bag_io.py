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

This module gathers the public names of the bag modules, one idea each:

- :mod:`awp_ros.bag_types`: message types, input topics, the typestore;
- :mod:`awp_ros.bag_reader`: :class:`BagMessage`, :class:`BagInfo`, :func:`read_bag`,
  :func:`bag_info`;
- :mod:`awp_ros.bag_writer`: :class:`BagWriter`;
- :mod:`awp_ros.gait_bag`: the gait generator's messages and the committed default bag.
"""

from __future__ import annotations

from awp_ros.bag_reader import bag_info, BagInfo, BagMessage, read_bag, TopicInfo
from awp_ros.bag_types import (CONTACT_STATE, IMU, INPUT_TOPICS, JOINT_STATE, msg_dirs,
                               typestore)
from awp_ros.bag_writer import BagWriter, reliable_qos
from awp_ros.gait_bag import (DEFAULT_BAG_NAME, DEFAULT_IMU_RATE_HZ, DEFAULT_START_NS,
                              default_bag_path, gait_messages, write_gait_bag)

__all__ = [
    'BagMessage', 'BagInfo', 'TopicInfo', 'BagWriter', 'read_bag', 'bag_info', 'typestore',
    'msg_dirs', 'gait_messages', 'write_gait_bag', 'default_bag_path', 'JOINT_STATE',
    'CONTACT_STATE', 'IMU', 'INPUT_TOPICS', 'DEFAULT_START_NS', 'DEFAULT_BAG_NAME',
    'DEFAULT_IMU_RATE_HZ',
    'reliable_qos',
]
