"""Offline replay of a rosbag2 through the node's pipeline, and live playback onto DDS.

:func:`replay_bag` reads the input topics of a bag (``joint_states``, ``contacts``,
optionally ``imu``) in recorded order, feeds them to :class:`awp_ros.pipeline` exactly as
the node's callbacks do, and writes every output message (``report``, ``awp``, ``fwp``,
``fws``, ``leg_polytopes``, ``markers``) to a new bag under the node's topic names
(``/<node_name>/<output>``), logged at the log time of the joint state it answers, plus
the input topics. :func:`play_bag` publishes a bag's messages onto live DDS at the
recorded pace (scaled by ``rate``), for feeding a running ``awp_node`` where ``ros2 bag
play`` is not installed.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
import importlib
import math
from pathlib import Path
import sys
import time
from typing import TextIO

import numpy as np

from awp_ros.bag_io import bag_info, BagMessage, INPUT_TOPICS, read_bag
from awp_ros.errors import BagError

__all__ = ['Progress', 'ReplaySummary', 'summarize_reports', 'play_bag', 'message_class',
           'replay_bag', 'load_parameters', 'make_pipeline', 'check_input_topics']


class Progress:
    """A progress bar with rate and ETA on a text stream (stderr by default).

    On a terminal the bar is redrawn in place at most every ``interval_s``; otherwise a
    plain line is written every ``log_interval_s`` so that logs stay readable.
    """

    def __init__(self, total: int, *, label: str = '', unit: str = 'msgs',
                 stream: TextIO | None = None, enabled: bool = True,
                 interval_s: float = 0.1, log_interval_s: float = 5.0,
                 width: int = 30) -> None:
        self.total = max(0, int(total))
        self.label = label
        self.unit = unit
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled
        self.tty = bool(getattr(self.stream, 'isatty', lambda: False)())
        self.interval_s = interval_s if self.tty else log_interval_s
        self.width = width
        self.count = 0
        self.start = time.monotonic()
        self._last = self.start          # first draw after one interval: a meaningful rate

    @property
    def rate(self) -> float:
        """Return the items per second so far."""
        elapsed = time.monotonic() - self.start
        return self.count / elapsed if elapsed > 0.0 else 0.0

    def update(self, n: int = 1) -> None:
        """Count ``n`` more items; redraw when due."""
        self.count += n
        now = time.monotonic()
        if self.enabled and now - self._last >= self.interval_s:
            self._last = now
            self._draw(final=False)

    def close(self) -> None:
        """Draw the final state and end the line."""
        if self.enabled:
            self._draw(final=True)

    def text(self) -> str:
        """Return the bar as one line (no carriage return)."""
        total = self.total or 1
        frac = min(1.0, self.count / total)
        filled = int(round(frac * self.width))
        bar = '#' * filled + '.' * (self.width - filled)
        rate = self.rate
        left = (self.total - self.count) / rate if rate > 0 else math.inf
        eta = _clock(left) if math.isfinite(left) else '--:--'
        label = f'{self.label} ' if self.label else ''
        return (f'{label}[{bar}] {100 * frac:5.1f}% {self.count}/{self.total} {self.unit} '
                f'{rate:7.0f} {self.unit}/s  elapsed {_clock(time.monotonic() - self.start)}'
                f'  ETA {eta}')

    def _draw(self, final: bool) -> None:
        if self.tty:
            self.stream.write('\r' + self.text() + ('\n' if final else ''))
        else:
            self.stream.write(self.text() + '\n')
        self.stream.flush()


def _clock(seconds: float) -> str:
    seconds = max(0, int(round(seconds)))
    return f'{seconds // 60:02d}:{seconds % 60:02d}'


# -- summary ----------------------------------------------------------------------------------

_STATUS_NAMES = {0: 'ok', 1: 'warning', 2: 'invalid_input', 3: 'stale_input', 4: 'error'}


@dataclass
class ReplaySummary:
    """Counts and margin statistics of a replay (or of any list of reports).

    ``valid``: reports with status OK or WARNING; ``invalid``: any other status (by name in
    ``statuses``); ``infeasible``: valid reports whose ``feasible`` flag (the FWS) is false;
    ``fwp_infeasible``: valid reports outside the FWP (the seed's criterion). ``margins``:
    set -> {min, p5, median, mean, max} over valid reports [N, N.m] (NaN-free values only).
    """

    reports: int = 0
    valid: int = 0
    invalid: int = 0
    infeasible: int = 0
    fwp_infeasible: int = 0
    statuses: dict = field(default_factory=dict)
    margins: dict = field(default_factory=dict)
    inputs: dict = field(default_factory=dict)
    outputs: dict = field(default_factory=dict)
    wall_s: float = 0.0
    bag_s: float = 0.0

    @property
    def throughput(self) -> float:
        """Return joint-state messages (= reports) processed per wall second."""
        return self.reports / self.wall_s if self.wall_s > 0 else 0.0

    def to_dict(self) -> dict:
        """Return the summary as JSON-ready builtins."""
        return {'reports': self.reports, 'valid': self.valid, 'invalid': self.invalid,
                'infeasible': self.infeasible, 'fwp_infeasible': self.fwp_infeasible,
                'statuses': dict(self.statuses), 'margins': self.margins,
                'inputs': dict(self.inputs), 'outputs': dict(self.outputs),
                'wall_s': self.wall_s, 'bag_s': self.bag_s,
                'throughput_msgs_per_s': self.throughput}

    def to_text(self) -> str:
        """Return a human-readable multi-line summary."""
        lines = [f'reports: {self.reports} (one per joint state)  valid: {self.valid}  '
                 f'invalid: {self.invalid}  infeasible (FWS): {self.infeasible}  '
                 f'outside FWP: {self.fwp_infeasible}']
        bad = {k: v for k, v in self.statuses.items() if k not in ('ok', 'warning')}
        if bad or self.statuses.get('warning'):
            lines.append('statuses: ' + ', '.join(f'{k} {v}' for k, v in
                                                  sorted(self.statuses.items())))
        if self.margins:
            lines.append(f'{"margin [N, N.m]":<16}{"min":>10}{"p5":>10}{"median":>10}'
                         f'{"mean":>10}{"max":>10}{"n":>7}')
            for name, st in self.margins.items():
                lines.append(f'{name:<16}' + ''.join(f'{st[k]:10.2f}' for k in
                                                     ('min', 'p5', 'median', 'mean', 'max'))
                             + f'{st["n"]:7d}')
        if self.wall_s > 0:
            speed = f', {self.bag_s / self.wall_s:.2f}x real time' if self.bag_s else ''
            lines.append(f'time: {self.wall_s:.2f} s wall for {self.bag_s:.2f} s of bag '
                         f'({self.throughput:.0f} joint states/s{speed})')
        return '\n'.join(lines)


def summarize_reports(reports: Iterable) -> ReplaySummary:
    """Count valid / invalid / infeasible reports and compute margin statistics.

    :param reports: ``FeasibilityReport`` messages (rclpy or rosbags objects). FWS margins
        are taken only from reports whose ``fws_stamp`` equals their stamp (computed for
        that cycle, not carried over).
    """
    s = ReplaySummary()
    values: dict[str, list] = {'awp_margin': [], 'fwp_margin': [], 'fws_margin': []}
    for r in reports:
        s.reports += 1
        name = _STATUS_NAMES.get(int(r.status), f'status_{int(r.status)}')
        s.statuses[name] = s.statuses.get(name, 0) + 1
        if int(r.status) > 1:
            s.invalid += 1
            continue
        s.valid += 1
        s.infeasible += not r.feasible
        s.fwp_infeasible += not r.fwp_feasible
        values['awp_margin'].append(r.awp_margin)
        values['fwp_margin'].append(r.fwp_margin)
        if (r.fws_stamp.sec, r.fws_stamp.nanosec) == (r.header.stamp.sec,
                                                      r.header.stamp.nanosec):
            values['fws_margin'].append(r.fws_margin)
    for name, vals in values.items():
        x = np.asarray(vals, dtype=float)
        x = x[np.isfinite(x)]
        if x.size:
            s.margins[name] = {'min': float(x.min()), 'p5': float(np.percentile(x, 5)),
                               'median': float(np.median(x)), 'mean': float(x.mean()),
                               'max': float(x.max()), 'n': int(x.size)}
    return s


# -- live playback ----------------------------------------------------------------------------


def message_class(msgtype: str):
    """Return the rclpy message class of ``pkg/msg/Name``.

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


def play_bag(path, *, rate: float = 1.0, remap: Mapping[str, str] | None = None,
             topics: Iterable[str] | None = None, wait_s: float = 0.0,
             wait_topics: Iterable[str] | None = None, qos_depth: int = 1000,
             node_name: str = 'awp_replay_player', progress: bool = True,
             stream: TextIO | None = None, ack_timeout_s: float = 10.0,
             duration_s: float | None = None) -> int:
    """Publish a bag's messages onto live DDS at the recorded pace; return the count.

    rclpy must be initialised by the caller (``rclpy.init()``). Messages are published
    serialised (no deserialisation) on reliable, volatile, keep-last(``qos_depth``)
    publishers, which reliable and best-effort subscribers both match. The message with log
    time ``t`` goes out at ``start + (t - t_first) / rate`` (wall clock); a late player
    publishes at once, so nothing is dropped.

    :param rate: speed factor (2 = twice as fast); ``math.inf`` = as fast as possible.
    :param remap: bag topic -> published topic.
    :param topics: only these bag topics (default all).
    :param wait_s: wait up to this long before starting until every topic in
        ``wait_topics`` (default: all published topics) has a subscriber.
    :param ack_timeout_s: at the end, wait up to this long for reliable delivery.
    :param duration_s: play only messages logged less than this after the bag's start [s].
    :raises BagError: unreadable bag, missing topic, or a type without a Python interface.
    """
    import rclpy
    from rclpy.duration import Duration
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    if not rate > 0.0:
        raise BagError(f'rate must be > 0, got {rate!r}')
    info = bag_info(path)
    selected = list(info.topics) if topics is None else list(topics)
    missing = [t for t in selected if t not in info.topics]
    if missing:
        raise BagError(f'bag {str(path)!r} has no topic {missing[0]!r}; its topics are '
                       f'{sorted(info.topics)}')
    remap = dict(remap or {})
    classes = {t: message_class(info.topics[t].msgtype) for t in selected}
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=qos_depth,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.VOLATILE)
    node = rclpy.create_node(node_name)
    try:
        pubs = {t: node.create_publisher(classes[t], remap.get(t, t), qos) for t in selected}
        waited = [pubs[t] for t in (wait_topics if wait_topics is not None else selected)
                  if t in pubs]
        deadline = time.monotonic() + wait_s
        while waited and time.monotonic() < deadline and \
                any(p.get_subscription_count() == 0 for p in waited):
            time.sleep(0.01)
        total = sum(info.topics[t].count for t in selected)
        stop_ns = None if duration_s is None else info.start_ns + int(duration_s * 1e9)
        bar = Progress(total, label='play', enabled=progress, stream=stream)
        sent = 0
        t_first = None
        start = time.monotonic()
        for msg in read_bag(path, topics=selected):
            if stop_ns is not None and msg.timestamp >= stop_ns:
                break
            if t_first is None:
                t_first = msg.timestamp
            if math.isfinite(rate):
                due = start + (msg.timestamp - t_first) * 1e-9 / rate
                delay = due - time.monotonic()
                if delay > 0.0:
                    time.sleep(delay)
            pubs[msg.topic].publish(msg.data)
            sent += 1
            bar.update()
        bar.close()
        for pub in pubs.values():
            pub.wait_for_all_acked(Duration(seconds=ack_timeout_s))
        return sent
    finally:
        node.destroy_node()


# -- offline replay ---------------------------------------------------------------------------


def load_parameters(params_file=None, *, robot: str = 'hyq',
                    overrides: Mapping | None = None) -> dict:
    """Return the node's parameters as a flat mapping: a params file plus overrides.

    :param params_file: a ROS 2 parameters YAML (default ``config/<robot>.yaml`` found by
        :func:`awp_ros.robot_config.config_dirs`).
    :param overrides: key -> value applied on top (like ``-p key:=value``).
    :raises ConfigError: the file is missing or not a parameters mapping.
    """
    import yaml

    from awp_ros.errors import ConfigError
    from awp_ros.robot_config import config_dirs

    if params_file is None:
        found = [d / f'{robot}.yaml' for d in config_dirs() if (d / f'{robot}.yaml').is_file()]
        if not found:
            raise ConfigError(f'no parameters file {robot}.yaml in '
                              f'{[str(d) for d in config_dirs()]}')
        params_file = found[0]
    path = Path(params_file)
    try:
        data = yaml.safe_load(path.read_text(encoding='utf-8'))
    except (OSError, yaml.YAMLError) as exc:
        raise ConfigError(f'cannot read parameters file {str(path)!r}: {exc}') from exc
    if not isinstance(data, Mapping):
        raise ConfigError(f'parameters file {str(path)!r} must hold a mapping')
    sections = [v['ros__parameters'] for v in data.values()
                if isinstance(v, Mapping) and isinstance(v.get('ros__parameters'), Mapping)]
    flat: dict = {}
    for section in sections or [data]:
        flat.update(section)
    flat.update(overrides or {})
    flat['__base_dir__'] = str(path.resolve().parent)
    return flat


def make_pipeline(parameters: Mapping):
    """Build the node's :class:`~awp_ros.pipeline.Pipeline` from :func:`load_parameters`."""
    from awp_ros.pipeline import Pipeline, PipelineParams
    from awp_ros.robot_config import load_config, RobotConfig

    flat = {k: v for k, v in parameters.items() if k != '__base_dir__'}
    if flat.get('robot') and not flat.get('robot_name'):
        config = load_config(flat['robot'])
    else:
        config = RobotConfig.from_dict(flat, base_dir=parameters.get('__base_dir__'))
    if flat.get('robot_description'):
        config = replace(config, urdf=str(flat['robot_description']))
    return Pipeline(config, PipelineParams.from_dict(flat))


def check_input_topics(info, topics: Mapping[str, str], *, use_imu: bool) -> dict[str, str]:
    """Return the input roles present (role -> topic), checking names and types.

    :raises BagError: ``joint_states`` or ``contacts`` (or ``imu`` with ``use_imu``) is
        missing, or a topic carries another type than its role needs.
    """
    needed = ['joint_states', 'contacts'] + (['imu'] if use_imu else [])
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
            from awp_ros.bag_io import typestore
            known = found in typestore().fielddefs
            raise BagError(f'{"" if known else "unknown message type: "}the {role} topic '
                           f'{topic!r} has type {found!r}; expected {msgtype}')
        have[role] = topic
    return have


def replay_bag(in_bag, out_bag, *, pipeline, topics: Mapping[str, str] | None = None,
               node_name: str = 'awp_node', outputs: Iterable[str] | None = None,
               copy_inputs: bool = True, storage: str = 'mcap', progress: bool = True,
               stream: TextIO | None = None, compress: bool = True) -> ReplaySummary:
    """Run a bag through the node's pipeline and write the outputs to a new bag.

    Input messages are deserialised into the rclpy message classes the node receives and
    fed in recorded order; each joint state's outputs are written with its log time on
    ``/<node_name>/<output>``. With ``copy_inputs`` every topic of the input bag is copied
    too (with its stored definition).

    :param pipeline: a :class:`~awp_ros.pipeline.Pipeline` (see :func:`make_pipeline`).
    :param topics: role (``joint_states``, ``contacts``, ``imu``) -> input topic name.
    :param outputs: which of :data:`~awp_ros.pipeline.OUTPUTS` to write (default all).
    :param compress: zstd chunk compression of the output (see :class:`BagWriter`).
    :return: the summary (counts, margin statistics, wall time).
    :raises BagError: unreadable or truncated bag, missing input topic, wrong types.
    """
    from rclpy.serialization import deserialize_message, serialize_message

    from awp_ros.bag_io import BagWriter
    from awp_ros.pipeline import OUTPUTS

    info = bag_info(in_bag)
    roles = check_input_topics(info, topics or {}, use_imu=pipeline.params.use_imu)
    wanted = tuple(OUTPUTS if outputs is None else outputs)
    unknown = [o for o in wanted if o not in OUTPUTS]
    if unknown:
        raise BagError(f'unknown outputs {unknown}; outputs are {list(OUTPUTS)}')
    role_of = {topic: role for role, topic in roles.items()}
    classes = {topic: message_class(INPUT_TOPICS[role][1]) for topic, role in role_of.items()}
    out_types = {'report': 'awp_ros_msgs/msg/FeasibilityReport',
                 'awp': 'awp_ros_msgs/msg/WrenchPolytope',
                 'fwp': 'awp_ros_msgs/msg/WrenchPolytope',
                 'fws': 'awp_ros_msgs/msg/WrenchPolytope',
                 'leg_polytopes': 'awp_ros_msgs/msg/LegPolytopes',
                 'markers': 'visualization_msgs/msg/MarkerArray'}
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
                writer.write(BagMessage(prefix + name, out_types[name], msg.timestamp,
                                        bytes(serialize_message(out))))
                summary.outputs[name] = summary.outputs.get(name, 0) + 1
    bar.close()
    wall = time.monotonic() - start
    result = summarize_reports(reports)
    result.inputs, result.outputs = summary.inputs, summary.outputs
    result.wall_s = wall
    result.bag_s = info.duration_s
    return result
