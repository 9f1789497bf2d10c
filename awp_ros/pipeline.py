"""The message-level pipeline shared by ``awp_node`` and the offline replay.

Messages in, messages out, no rclpy node inside: feed :meth:`Pipeline.on_contacts`,
:meth:`Pipeline.on_imu` and :meth:`Pipeline.on_joint_state` the input messages in arrival
(or recorded) order and every joint-state message returns a :class:`Cycle` holding the
outputs that answer it. The node publishes them; the replay writes them to a bag; both get
the same messages because every decision here depends on message stamps only, never on
the wall clock:

- one evaluation per joint-state message, with the ContactState (and Imu when ``use_imu``)
  that was current at its stamp: the newest received one whose stamp is not later than the
  joint state's (else the earliest received, the closest). So a node that lags and has
  already taken newer contacts or imu messages from its queues pairs them as the replay of
  the recorded order does. A report for every message, errors included
  (``STATUS_INVALID_INPUT`` with the reason, ``STATUS_STALE_INPUT`` when the contacts/imu
  stamp is more than ``stale_timeout_s`` older (or newer: clocks that disagree) than the
  joint state's or none arrived yet, ``STATUS_ERROR`` for an internal failure; reasons are
  cut to ``MAX_REASON_CHARS``). Joints the model does not have are ignored with a warning
  (an arm's joints in the robot's joint_states); no foot in contact is evaluated (every
  set is {0}) with a warning;
- ``awp``, ``fwp``, ``leg_polytopes`` every evaluated cycle; the FWS (H-rep, directional
  and Euclidean margins) when ``fws_rate_hz`` says so by stamp (0 = every cycle) or the
  stance set changed, the reports carrying the latest FWS with its ``fws_stamp``;
- ``markers`` throttled to ``marker_rate_hz`` by stamp (0 = never);
- every output's ``header.stamp`` is the joint state's stamp; wrench data use the frame
  ``wrench_frame_id`` (CoM origin, world-aligned axes), markers ``marker_frame_id`` ('' = the
  wrench frame, or the URDF root link, e.g. ``base_link``, to overlay them on the robot).

A stamp earlier than the previous joint state's restarts the throttles (a replay loop) and
adds a warning to that report. Output messages other than the report are built on demand
(:class:`Cycle` methods), so a node with no subscriber on a topic does not pay for it.
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields, replace
import math
import time

from awp_ros_msgs.msg import ContactState, FeasibilityReport, LegPolytopes, WrenchPolytope
from builtin_interfaces.msg import Time
import numpy as np
import pinocchio as pin
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Header
from visualization_msgs.msg import MarkerArray

from awp_ros.conversions import (error_report, leg_polytopes_msg, report_msg,
                                 robot_state_from_msgs, stamp_to_ns, wrench_polytope_msg)
from awp_ros.errors import AwpError, ConfigError, InputError
from awp_ros.evaluator import FeasibilityEvaluator, FeasibilityResult, WrenchSetResult
from awp_ros.markers import build_markers, error_markers, MarkerStyle, quaternion_matrix
from awp_ros.robot_config import RobotConfig

__all__ = ['Cycle', 'MAX_REASON_CHARS', 'OUTPUTS', 'PARAMETER_DOCS', 'Pipeline',
           'PipelineParams']

#: Output topics (relative to the node, ``~/<name>``) in the order of :meth:`Cycle.messages`.
OUTPUTS = ('report', 'awp', 'fwp', 'fws', 'leg_polytopes', 'markers')

_S = FeasibilityReport

#: Longest ``status_message`` of a report (longer reasons are cut, marked with '...').
MAX_REASON_CHARS = 1000


@dataclass(frozen=True)
class PipelineParams:
    """The node-only parameters that shape the pipeline's outputs (see PARAMETER_DOCS)."""

    wrench_frame_id: str = 'com_world_aligned'
    marker_frame_id: str = ''
    stale_timeout_s: float = 0.5
    fws_rate_hz: float = 10.0
    marker_rate_hz: float = 30.0
    marker_force_scale: float = 0.0005
    marker_moment_scale: float = 0.002
    use_imu: bool = False
    use_joint_velocities: bool = True

    def __post_init__(self) -> None:
        """Validate every field (raise ConfigError naming the bad value)."""
        for name in ('stale_timeout_s', 'fws_rate_hz', 'marker_rate_hz'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ConfigError(f'{name} must be a finite number >= 0, got {value!r}')
        for name in ('marker_force_scale', 'marker_moment_scale'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ConfigError(f'{name} must be a finite number > 0, got {value!r}')
        if not isinstance(self.wrench_frame_id, str) or not self.wrench_frame_id.strip():
            raise ConfigError(f'wrench_frame_id must be a non-empty frame name, got '
                              f'{self.wrench_frame_id!r}')
        if not isinstance(self.marker_frame_id, str):
            raise ConfigError(f'marker_frame_id must be a string, got {self.marker_frame_id!r}')

    @classmethod
    def from_dict(cls, params: Mapping) -> PipelineParams:
        """Read the known keys of a parameters mapping (a params file, its ``ros__parameters``
        section, or a flat mapping); other keys are ignored.

        :raises ConfigError: a value of the wrong type or range.
        """
        flat = _ros_parameters(params)
        kw = {}
        for f in fields(cls):
            if f.name in flat:
                value = flat[f.name]
                default = f.default
                if isinstance(default, bool):
                    if not isinstance(value, bool):
                        raise ConfigError(f'{f.name} must be true or false, got {value!r}')
                elif isinstance(default, float):
                    if isinstance(value, bool) or not isinstance(value, (int, float)):
                        raise ConfigError(f'{f.name} must be a number, got {value!r}')
                    value = float(value)
                kw[f.name] = value
        return cls(**kw)


#: Description of every pipeline parameter (used for the node's descriptors and the README).
PARAMETER_DOCS = {
    'wrench_frame_id': 'frame_id of reports and wrench/leg polytopes: origin at the CoM, '
                       'world-aligned axes (REP 103)',
    'marker_frame_id': "frame of the markers: '' = wrench_frame_id (set it as RViz's fixed "
                       'frame, no TF needed), or the URDF root link (e.g. base_link) to '
                       'overlay the robot model',
    'stale_timeout_s': 'contacts/imu older than this w.r.t. the joint-state stamp give a '
                       'STATUS_STALE_INPUT report [s]; 0 disables the check',
    'fws_rate_hz': 'rate of the FWS computation (H-rep, directional and Euclidean margins) '
                   'by joint-state stamps [Hz]; 0 = every cycle; a stance change forces it',
    'marker_rate_hz': 'marker publication rate by joint-state stamps [Hz]; 0 = no markers',
    'marker_force_scale': 'scene length per newton of the drawn polytopes and wrench [m/N]',
    'marker_moment_scale': 'scene length per newton-metre of the drawn moment [m/(N.m)]',
    'use_imu': 'subscribe to imu and take its orientation as the base orientation '
               '(read-only)',
    'use_joint_velocities': 'use joint_states velocities (Coriolis terms of the bias '
                            'torques, seed eq. 1)',
}


def _ros_parameters(params: Mapping) -> dict:
    """Return the merged ``ros__parameters`` sections of a parameters file, or params."""
    sections = [v['ros__parameters'] for v in params.values()
                if isinstance(v, Mapping) and isinstance(v.get('ros__parameters'), Mapping)]
    if isinstance(params.get('ros__parameters'), Mapping):
        sections.append(params['ros__parameters'])
    out: dict = {}
    for section in sections or [params]:
        out.update(section)
    return out


class _InputBuffer:
    """The received messages of one input topic not yet passed by a joint state's stamp.

    Kept as parallel lists from ``head`` on (stamps [ns], messages) so that a node lagging
    behind its joint states, which holds the contacts of the whole lag, finds the one to
    pair in O(log n) (bisection while the stamps are non-decreasing, the usual case) and
    drops the passed ones in O(1) amortised. At most ``maxlen`` are kept (the oldest go
    first; a joint state that then finds only later contacts is reported stale).
    """

    def __init__(self, maxlen: int = 10000) -> None:
        self.maxlen = max(int(maxlen), 1)
        self.stamps: list[int] = []
        self.msgs: list = []
        self.head = 0
        self.sorted = True

    def __len__(self) -> int:
        return len(self.stamps) - self.head

    def add(self, msg) -> None:
        ns = stamp_to_ns(msg.header.stamp)
        if len(self) and ns < self.stamps[-1]:
            self.sorted = False
        self.stamps.append(ns)
        self.msgs.append(msg)
        if len(self) > self.maxlen:
            self.head += 1
        self._compact()

    def pick(self, ns: int):
        """Return the newest message stamped at or before ``ns``, else the earliest one.

        Messages older than the one returned are dropped; None when empty.
        """
        stamps, h = self.stamps, self.head
        if h == len(stamps):
            return None
        if self.sorted:
            i = bisect_right(stamps, ns, h) - 1
        else:
            i = next((i for i in range(len(stamps) - 1, h - 1, -1) if stamps[i] <= ns), -1)
        if i >= h:
            self.head = h = i
            if h == len(stamps) - 1:
                self.sorted = True
            self._compact()
        return self.msgs[self.head]

    def _compact(self) -> None:
        if self.head > 64 and 2 * self.head > len(self.stamps):
            del self.stamps[:self.head]
            del self.msgs[:self.head]
            self.head = 0


class Cycle:
    """The outputs answering one joint-state message (built on demand, then cached).

    :ivar header: stamp of the joint state, frame_id ``wrench_frame_id``.
    :ivar report: the FeasibilityReport (always).
    :ivar result: the evaluation, or None when the message was not evaluated.
    :ivar fws_computed: whether the FWS was computed for this message.
    :ivar markers_due: whether markers are published for this message.
    """

    def __init__(self, header: Header, report: FeasibilityReport,
                 result: FeasibilityResult | None, *, fws_computed: bool, markers_due: bool,
                 marker_header: Header, marker_frame: tuple, style: MarkerStyle,
                 reference_point: np.ndarray, latest_fws: WrenchSetResult | None,
                 pyramid_sides: int) -> None:
        self.header = header
        self.report = report
        self.result = result
        self.fws_computed = fws_computed
        self.markers_due = markers_due
        self._marker_header = marker_header
        self._marker_frame = marker_frame
        self._style = style
        self._reference_point = reference_point
        self._latest_fws = latest_fws
        self._sides = pyramid_sides
        self._cache: dict = {}

    def _wrench(self, kind: str) -> WrenchPolytope | None:
        r = self.result
        if r is None or (kind == 'fws' and not self.fws_computed):
            return None
        if kind not in self._cache:
            self._cache[kind] = wrench_polytope_msg(self.header, kind, r.stance,
                                                    self._reference_point,
                                                    getattr(r, kind).polytope)
        return self._cache[kind]

    def awp(self) -> WrenchPolytope | None:
        """Return the AWP message (None when not evaluated)."""
        return self._wrench('awp')

    def fwp(self) -> WrenchPolytope | None:
        """Return the FWP message (None when not evaluated)."""
        return self._wrench('fwp')

    def fws(self) -> WrenchPolytope | None:
        """Return the FWS message when it was computed for this message, else None."""
        return self._wrench('fws')

    def leg_polytopes(self) -> LegPolytopes | None:
        """Return the LegPolytopes message (None when not evaluated)."""
        if self.result is None:
            return None
        if 'legs' not in self._cache:
            self._cache['legs'] = leg_polytopes_msg(self.header, self.result)
        return self._cache['legs']

    def markers(self) -> MarkerArray | None:
        """Return the MarkerArray when markers are due for this message, else None."""
        if not self.markers_due:
            return None
        if 'markers' not in self._cache:
            if self.result is None:
                self._cache['markers'] = error_markers(self._marker_header,
                                                       self.report.status_message,
                                                       style=self._style)
            else:
                R, t = self._marker_frame
                self._cache['markers'] = build_markers(
                    self.result, self._marker_header, style=self._style,
                    fws=self._latest_fws, pyramid_sides=self._sides, rotation=R,
                    translation=t, status_text=self.report.status_message)
        return self._cache['markers']

    def messages(self) -> dict:
        """Return every output of this message: topic name (``OUTPUTS``) -> message."""
        out = {'report': self.report, 'awp': self.awp(), 'fwp': self.fwp(),
               'fws': self.fws(), 'leg_polytopes': self.leg_polytopes(),
               'markers': self.markers()}
        return {k: v for k, v in out.items() if v is not None}


class Pipeline:
    """Turn input messages into output messages (see the module docstring).

    :param config: the robot config (a name or YAML path is loaded by the evaluator).
    :param params: the pipeline parameters.
    :param input_buffer: contacts (and imu) messages kept for joint states that have not
        caught up with them (the node passes its ``qos_depth``: a node lagging by that many
        joint states still pairs each with the contacts current at its stamp).
    :raises ConfigError, ModelError: bad config, unusable URDF, bad marker_frame_id.
    """

    def __init__(self, config: RobotConfig | str, params: PipelineParams | None = None, *,
                 input_buffer: int = 10000) -> None:
        self.evaluator = FeasibilityEvaluator(config)
        self._joint_names = frozenset(self.evaluator.model.joint_names)
        self.params = PipelineParams() if params is None else params
        self._check_marker_frame(self.params)
        self._contacts = _InputBuffer(input_buffer)
        self._imu = _InputBuffer(input_buffer)
        self._last_js_ns: int | None = None
        self._last_fws_ns: int | None = None
        self._last_marker_ns: int | None = None
        self._latest_fws: WrenchSetResult | None = None
        self._latest_fws_stamp: Time | None = None
        self._latest_fws_stance: tuple | None = None

    @classmethod
    def from_parameters(cls, params: Mapping, *, robot: str | None = None) -> Pipeline:
        """Build a pipeline from a parameters file's mapping (what the node reads).

        The robot part comes from ``robot`` (a config name or path; default the mapping's
        own ``robot`` key, else the mapping itself when it has ``robot_name``, else
        ``hyq``), with ``robot_description`` (URDF XML) replacing its URDF when non-empty.
        """
        flat = _ros_parameters(params)
        name = robot if robot is not None else flat.get('robot') or None
        if name is None and 'robot_name' in flat:
            config = RobotConfig.from_dict(flat)
        else:
            from awp_ros.robot_config import load_config
            config = load_config(name or 'hyq')
        if flat.get('robot_description'):
            config = replace(config, urdf=str(flat['robot_description']))
        return cls(config, PipelineParams.from_dict(flat))

    # -- configuration ---------------------------------------------------------------------

    @property
    def config(self) -> RobotConfig:
        """Return the robot config in use."""
        return self.evaluator.config

    @property
    def root_link(self) -> str:
        """Return the URDF root link (the free flyer's child body), e.g. ``base_link``."""
        model = self.evaluator.model.model
        for frame in model.frames:
            if frame.parentJoint == 1 and frame.type == pin.FrameType.BODY:
                return frame.name
        return ''

    def set_config(self, config: RobotConfig) -> None:
        """Use a new robot config from the next message on (rebuilds the evaluator).

        :raises ConfigError, ModelError: the config is unusable (the old one stays).
        """
        evaluator = FeasibilityEvaluator(config)
        old = self.evaluator
        self.evaluator = evaluator
        try:
            self._check_marker_frame(self.params)
        except ConfigError:
            self.evaluator = old
            raise
        self._joint_names = frozenset(evaluator.model.joint_names)
        self._latest_fws_stance = None

    def set_params(self, params: PipelineParams) -> None:
        """Use new pipeline parameters from the next message on.

        :raises ConfigError: ``marker_frame_id`` is neither '' nor the wrench frame nor the
            root link.
        """
        self._check_marker_frame(params)
        self.params = params

    def _check_marker_frame(self, params: PipelineParams) -> None:
        frame = params.marker_frame_id
        if frame not in ('', params.wrench_frame_id, self.root_link):
            msg = (f"marker_frame_id must be '', the wrench frame "
                   f'{params.wrench_frame_id!r} or the root link {self.root_link!r}; got '
                   f'{frame!r}')
            raise ConfigError(msg)

    # -- inputs ----------------------------------------------------------------------------

    def on_contacts(self, msg: ContactState) -> None:
        """Keep a contact state for the joint states it precedes (validated with them)."""
        self._contacts.add(msg)

    def on_imu(self, msg: Imu) -> None:
        """Keep an IMU message for the joint states it precedes (used when ``use_imu``)."""
        self._imu.add(msg)

    def on_joint_state(self, msg: JointState, notes: Sequence[str] = ()) -> Cycle:
        """Evaluate one joint-state message and return its outputs.

        :param notes: warnings of the caller about this message (e.g. messages lost
            before it), put first in the report's ``status_message``.
        """
        t0 = time.perf_counter()
        p = self.params
        ns = stamp_to_ns(msg.header.stamp)
        header = Header(stamp=msg.header.stamp, frame_id=p.wrench_frame_id)
        notes = list(notes)
        if self._last_js_ns is not None and ns < self._last_js_ns:
            notes.append(f'joint_states stamp went back by {(self._last_js_ns - ns) * 1e-9:.6g}'
                         ' s; throttles restarted')
            self._last_fws_ns = self._last_marker_ns = None
        self._last_js_ns = ns
        markers_due = p.marker_rate_hz > 0.0 and _due(self._last_marker_ns, ns,
                                                      p.marker_rate_hz)
        if markers_due:
            self._last_marker_ns = _advance(self._last_marker_ns, ns, p.marker_rate_hz)
        result = None
        fws_computed = False
        R = np.eye(3)
        contacts = self._contacts.pick(ns)
        imu = self._imu.pick(ns) if p.use_imu else None
        try:
            stale = self._stale_reason(ns, contacts, imu)
            if stale:
                report = error_report(header, _S.STATUS_STALE_INPUT,
                                      '; '.join(notes + [stale]))
            else:
                state = robot_state_from_msgs(
                    msg, contacts, imu, feet=self.evaluator.feet,
                    use_velocities=p.use_joint_velocities, joint_names=self._joint_names,
                    notes=notes)
                result = self.evaluator.evaluate(state, fws=False)
                if not result.stance:
                    notes.append('no foot in contact: every wrench set is {0}, no wrench '
                                 'but zero is feasible')
                if p.use_imu:
                    R = quaternion_matrix(state.base_orientation)
                by_rate = p.fws_rate_hz == 0.0 or _due(self._last_fws_ns, ns, p.fws_rate_hz)
                if by_rate or result.stance != self._latest_fws_stance:
                    self.evaluator.add_fws(result)
                    fws_computed = True
                    if by_rate:
                        self._last_fws_ns = _advance(self._last_fws_ns, ns, p.fws_rate_hz)
                    self._latest_fws = result.fws
                    self._latest_fws_stamp = msg.header.stamp
                    self._latest_fws_stance = result.stance
                warnings = notes + result.warnings
                status = _S.STATUS_WARNING if warnings else _S.STATUS_OK
                report = report_msg(header, result, compute_time=0.0, fws=self._latest_fws,
                                    fws_stamp=self._latest_fws_stamp, status=status,
                                    status_message='; '.join(warnings))
        except InputError as exc:
            report = error_report(header, _S.STATUS_INVALID_INPUT, '; '.join(notes + [str(exc)]))
            result = None
        except AwpError as exc:
            report = error_report(header, _S.STATUS_ERROR, f'{type(exc).__name__}: {exc}')
            result = None
        except Exception as exc:  # noqa: BLE001 -- a monitor must answer every message
            report = error_report(header, _S.STATUS_ERROR,
                                  f'internal error {type(exc).__name__}: {exc}')
            result = None
        if len(report.status_message) > MAX_REASON_CHARS:
            report.status_message = report.status_message[:MAX_REASON_CHARS - 3] + '...'
        report.compute_time = time.perf_counter() - t0
        com = np.zeros(3) if result is None else result.com
        marker_header = Header(stamp=msg.header.stamp,
                               frame_id=p.marker_frame_id or p.wrench_frame_id)
        if p.marker_frame_id in ('', p.wrench_frame_id):
            frame = (np.eye(3), np.zeros(3))
        else:  # the root link: x_base = R^T (com + x)
            frame = (R.T, R.T @ com)
        style = MarkerStyle(force_scale=p.marker_force_scale,
                            moment_scale=p.marker_moment_scale)
        return Cycle(header, report, result, fws_computed=fws_computed,
                     markers_due=markers_due, marker_header=marker_header,
                     marker_frame=frame, style=style, reference_point=R.T @ com,
                     latest_fws=self._latest_fws, pyramid_sides=self.config.pyramid_sides)

    def _stale_reason(self, ns: int, contacts: ContactState | None, imu: Imu | None) -> str:
        """Return why the inputs cannot be used with a joint state at ``ns``, or ''."""
        p = self.params
        timeout = int(p.stale_timeout_s * 1e9)
        checks = [('contacts', contacts)] + ([('imu', imu)] if p.use_imu else [])
        for topic, msg in checks:
            if msg is None:
                return f'no {topic} message received yet'
            age = ns - stamp_to_ns(msg.header.stamp)
            if timeout > 0 and age > timeout:
                return (f'{topic} is stale: its stamp is {age * 1e-9:.3f} s older than the '
                        f'joint state (stale_timeout_s {p.stale_timeout_s:g})')
            if timeout > 0 and -age > timeout:
                return (f'{topic} stamp is {-age * 1e-9:.3f} s later than the joint state '
                        f'(stale_timeout_s {p.stale_timeout_s:g}): clocks that disagree, '
                        'or joint states that went back')
        return ''


def _due(last_ns: int | None, ns: int, rate_hz: float) -> bool:
    """Return whether a throttled output is due at stamp ``ns`` [ns] for ``rate_hz``."""
    return last_ns is None or ns - last_ns >= int(round(1e9 / rate_hz))


def _advance(last_ns: int | None, ns: int, rate_hz: float) -> int:
    """Return the new reference stamp of a throttle that is due at ``ns``.

    Steps by whole periods while ``ns`` is within one period of the schedule, so that the
    average rate is ``rate_hz`` even when inputs do not fall on the period; restarts at
    ``ns`` after a gap or with rate 0 (every cycle).
    """
    if last_ns is None or rate_hz <= 0.0:
        return ns
    period = int(round(1e9 / rate_hz))
    nxt = last_ns + period
    return nxt if ns - nxt < period else ns
