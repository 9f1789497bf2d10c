"""
The Fast DDS setting the node's input queues need (rmw_fastrtps, the ROS 2 default).

A ROS QoS ``depth`` sets a Fast DDS reader's history depth, not its resource limits, whose
default ``max_samples`` is 5000. A reliable keep-last reader asked for 8000 samples holds
the *oldest* 5000 and rejects the rest, which the publisher keeps resending: 7000 joint
states published into a depth-8000 queue, the reader gives 5000 (stamps 0 to 4999;
``test/node/test_dds.py``). So ``qos_depth`` (default 10000) was silently 5000, and a node
that fell more than 5000 joint states behind spent its cores on the resends: in a 1 kHz
soak on a machine where it answers ~600 joint states/s, the rate fell to ~100-150
reports/s once the backlog passed ~5000 and the latency grew without bound (README,
"Real time").

:func:`use_deep_queues` points Fast DDS at ``fastdds_profile.xml`` (beside this module),
whose default data reader holds up to :data:`READER_SAMPLES` samples (the largest
``qos_depth``), before rclpy creates the process's participant. It leaves alone a user who
configures Fast DDS (a profiles file already set, or ``RMW_FASTRTPS_USE_QOS_FROM_XML``) and
other middlewares; :func:`queue_note` says what applies (logged at startup).
"""

from __future__ import annotations

from collections.abc import MutableMapping
import os
from pathlib import Path

__all__ = ['FASTDDS_READER_SAMPLES', 'PROFILE', 'READER_SAMPLES', 'queue_note',
           'use_deep_queues']

#: Fast DDS's default ``max_samples`` of a data reader.
FASTDDS_READER_SAMPLES = 5000
#: ``max_samples`` of the data readers in :data:`PROFILE` (the largest ``qos_depth``).
READER_SAMPLES = 1_000_000
#: The node's Fast DDS profiles file.
PROFILE = Path(__file__).with_name('fastdds_profile.xml')
#: The environment variables Fast DDS reads a profiles file from (2.x, 3.x).
_PROFILE_VARS = ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE')


def _fast_dds(environ: MutableMapping[str, str]) -> bool:
    """Return whether the middleware is Fast DDS (``RMW_IMPLEMENTATION`` unset = default)."""
    rmw = environ.get('RMW_IMPLEMENTATION', '')
    return rmw == '' or rmw.startswith('rmw_fastrtps')


def use_deep_queues(environ: MutableMapping[str, str] | None = None) -> bool:
    """
    Select :data:`PROFILE` for this process's Fast DDS participant, unless configured.

    Call before ``rclpy.init``. Sets ``FASTRTPS_DEFAULT_PROFILES_FILE`` when the middleware
    is Fast DDS, no profiles file is set and ``RMW_FASTRTPS_USE_QOS_FROM_XML`` is not (with it
    the XML would also replace the ROS QoS). Child processes inherit it.

    :param environ: the environment to change (default ``os.environ``).
    :return: whether it was set.
    """
    env = os.environ if environ is None else environ
    if not _fast_dds(env) or env.get('RMW_FASTRTPS_USE_QOS_FROM_XML', '0') not in ('', '0') \
            or any(env.get(var) for var in _PROFILE_VARS):
        return False
    env['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(PROFILE)
    return True


def queue_note(qos_depth: int, environ: MutableMapping[str, str] | None = None
               ) -> tuple[bool, str]:
    """
    Return ``(warn, text)``: whether input queues of ``qos_depth`` hold what they are asked.

    ``warn`` when the middleware is Fast DDS, ``qos_depth`` exceeds its default reader limit
    and the profiles file in use is not :data:`PROFILE` (it may or may not raise the limit).
    """
    env = os.environ if environ is None else environ
    if not _fast_dds(env):
        return False, ''
    files = [env[var] for var in _PROFILE_VARS if env.get(var)]
    if files and files[0] == str(PROFILE):
        return False, (f'Fast DDS profile {PROFILE}: input queues hold up to {READER_SAMPLES} '
                       f'samples (qos_depth {qos_depth})')
    if qos_depth <= FASTDDS_READER_SAMPLES:
        return False, ''
    if files:
        source = f'Fast DDS is configured by the profiles file {files[0]}: unless it raises'
    elif env.get('RMW_FASTRTPS_USE_QOS_FROM_XML', '0') not in ('', '0'):
        source = 'Fast DDS is configured by RMW_FASTRTPS_USE_QOS_FROM_XML: unless its XML raises'
    else:
        source = ('no Fast DDS profile is set (use_deep_queues was not called): without one '
                  'that raises')
    return True, (f"qos_depth {qos_depth} exceeds Fast DDS's default data-reader limit of "
                  f'{FASTDDS_READER_SAMPLES} samples and {source} resourceLimitsQos '
                  f'max_samples of data readers, the input queues hold '
                  f'{FASTDDS_READER_SAMPLES} and a reliable publisher resends the rest (see '
                  f'{PROFILE.name} in awp_ros/node)')
