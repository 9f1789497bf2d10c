"""
Offline replay of a rosbag2 through the node's pipeline.

:func:`replay_bag` reads the input topics of a bag (``joint_states``, ``contacts``,
optionally ``imu``) in recorded order, feeds them to :class:`awp_ros.ros.pipeline` exactly as
the node's callbacks do, and writes every output message (``report``, ``awp``, ``fwp``,
``fws``, ``leg_polytopes``, ``markers``) to a new bag under the node's topic names
(``/<node_name>/<output>``), logged at the log time of the joint state it answers, plus
the input topics. The pipeline is built from the node's parameters by
:meth:`awp_ros.ros.pipeline.Pipeline.from_parameters` (see
:func:`awp_ros.robot.config.load_parameters`).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
import time
from typing import TextIO

from awp_ros.bags.message_types import (INPUT_TOPICS, message_class, OUTPUT_TYPES,
                                        serialize, typestore)
from awp_ros.bags.progress import Progress
from awp_ros.bags.reader import bag_info, BagMessage, read_bag
from awp_ros.bags.summary import ReplaySummary, summarize_reports
from awp_ros.bags.writer import BagWriter
from awp_ros.errors import BagError

__all__ = ['check_input_topics', 'pipeline_cycles', 'replay_bag']


def check_input_topics(info, topics: Mapping[str, str], *, use_imu: bool,
                       use_contacts: bool = True) -> dict[str, str]:
    """
    Return the input roles present (role -> topic), checking names and types.

    :param use_contacts: the contacts topic is needed (``contact_source`` ``topic``).
    :raises BagError: ``joint_states`` or ``contacts`` (or ``imu`` with ``use_imu``) is
        missing, or a topic carries another type than its role needs.
    """
    needed = ['joint_states'] + (['contacts'] if use_contacts else []) \
        + (['imu'] if use_imu else [])
    have = {}
    for role, (_, msgtype) in INPUT_TOPICS.items():
        topic = topics.get(role, INPUT_TOPICS[role][0])
        if topic not in info.topics:
            if role in needed:
                flag = '--' + role.replace('_', '-')
                raise BagError(f'bag {info.path!r} has no {role} topic {topic!r}; its topics '
                               f'are {sorted(info.topics)} (remap with {flag})')
            continue
        found = info.topics[topic].msgtype
        if found != msgtype:
            known = found in typestore().fielddefs
            raise BagError(f'{"" if known else "unknown message type: "}the {role} topic '
                           f'{topic!r} has type {found!r}; expected {msgtype}')
        have[role] = topic
    return have


def pipeline_cycles(pipeline, in_bag, *, topics: Mapping[str, str] | None = None) -> Iterator:
    """
    Feed a bag's inputs to the pipeline in recorded order; yield each joint state's cycle.

    What :func:`replay_bag` does without writing a bag: the same topics and roles
    (:func:`check_input_topics`), each input deserialised into the class the node receives.
    Yields the :class:`~awp_ros.ros.cycle.Cycle` of every joint state, in order.

    :raises BagError: unreadable bag, missing input topic, wrong types.
    """
    from rclpy.serialization import deserialize_message

    roles = check_input_topics(bag_info(in_bag), topics or {}, use_imu=pipeline.params.use_imu,
                               use_contacts=pipeline.params.contact_source == 'topic')
    role_of = {topic: role for role, topic in roles.items()}
    classes = {topic: message_class(INPUT_TOPICS[role][1]) for topic, role in role_of.items()}
    for msg in read_bag(in_bag, topics=list(role_of)):
        role, obj = role_of[msg.topic], deserialize_message(msg.data, classes[msg.topic])
        if role == 'contacts':
            pipeline.on_contacts(obj)
        elif role == 'imu':
            pipeline.on_imu(obj)
        else:
            yield pipeline.on_joint_state(obj)


def replay_bag(in_bag, out_bag, *, pipeline, topics: Mapping[str, str] | None = None,
               node_name: str = 'awp_node', outputs: Iterable[str] | None = None,
               copy_inputs: bool = True, storage: str = 'mcap', progress: bool = True,
               stream: TextIO | None = None, compress: bool = True) -> ReplaySummary:
    """
    Run a bag through the node's pipeline and write the outputs to a new bag.

    Input messages are deserialised into the rclpy message classes the node receives and
    fed in recorded order; each joint state's outputs are written with its log time on
    ``/<node_name>/<output>``. With ``copy_inputs`` every topic of the input bag is copied
    too (with its stored definition).

    :param pipeline: a :class:`~awp_ros.ros.pipeline.Pipeline` (see
        :meth:`~awp_ros.ros.pipeline.Pipeline.from_parameters`).
    :param topics: role (``joint_states``, ``contacts``, ``imu``) -> input topic name.
    :param outputs: which of :data:`~awp_ros.ros.pipeline.OUTPUTS` to write (default all).
    :param compress: zstd chunk compression of the output (see
        :class:`~awp_ros.bags.writer.BagWriter`).
    :return: the summary (counts, margin statistics, wall time).
    :raises BagError: unreadable or truncated bag, missing input topic, wrong types.
    """
    from rclpy.serialization import deserialize_message

    from awp_ros.ros.cycle import OUTPUTS

    info = bag_info(in_bag)
    roles = check_input_topics(info, topics or {}, use_imu=pipeline.params.use_imu,
                               use_contacts=pipeline.params.contact_source == 'topic')
    wanted = tuple(OUTPUTS if outputs is None else outputs)
    unknown = [o for o in wanted if o not in OUTPUTS]
    if unknown:
        raise BagError(f'unknown outputs {unknown}; outputs are {list(OUTPUTS)}')
    role_of = {topic: role for role, topic in roles.items()}
    classes = {topic: message_class(INPUT_TOPICS[role][1]) for topic, role in role_of.items()}
    prefix = '/' + node_name.strip('/') + '/'
    read_topics = None if copy_inputs else list(role_of)
    total = sum(t.count for name, t in info.topics.items()
                if read_topics is None or name in read_topics)
    bar = Progress(total, label='replay', enabled=progress, stream=stream)
    summary = ReplaySummary()
    reports = []
    start = time.monotonic()
    with BagWriter(out_bag, storage=storage, definitions=info.topics,
                   compress=compress) as writer:
        for msg in read_bag(in_bag, topics=read_topics):
            if copy_inputs:
                writer.write(msg)
            role = role_of.get(msg.topic)
            bar.update()
            if role is None:
                continue
            summary.inputs[role] = summary.inputs.get(role, 0) + 1
            obj = deserialize_message(msg.data, classes[msg.topic])
            if role == 'contacts':
                pipeline.on_contacts(obj)
                continue
            if role == 'imu':
                pipeline.on_imu(obj)
                continue
            cycle = pipeline.on_joint_state(obj)
            reports.append(cycle.report)
            for name in wanted:
                out = cycle.report if name == 'report' else getattr(cycle, name)()
                if out is None:
                    continue
                writer.write(BagMessage(prefix + name, OUTPUT_TYPES[name], msg.timestamp,
                                        serialize(out, OUTPUT_TYPES[name])))
                summary.outputs[name] = summary.outputs.get(name, 0) + 1
    bar.close()
    wall = time.monotonic() - start
    result = summarize_reports(reports)
    result.inputs, result.outputs = summary.inputs, summary.outputs
    result.wall_s = wall
    result.bag_s = info.duration_s
    return result
