"""
The message-level pipeline shared by ``awp_node`` and the offline replay.

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
  (``STATUS_INVALID_INPUT`` with the reason, ``STATUS_STALE_INPUT`` when the imu/odom
  stamp is more than ``stale_timeout_s`` older (or any input's newer: clocks that
  disagree) than the joint state's, the contacts more than ``contacts_timeout_s`` older
  (when > 0: by default a contacts message holds until the next one), or none arrived
  yet, ``STATUS_ERROR`` for an internal failure; reasons are cut to ``MAX_REASON_CHARS``).
  The stance comes from ``contact_source``: the contacts (``topic``), the joint efforts
  (``effort``: :mod:`awp_ros.ros.contact_source`) or every foot (``all``). Joint-state
  messages may carry subsets of the joints (several publishers): they are merged, each
  joint's latest value (:mod:`awp_ros.ros.joint_merge`), and evaluated once every joint
  has a value younger than ``joint_states_timeout_s``; joints the model does not have
  (an arm's, wheels) are ignored without a warning (:attr:`Pipeline.extra_joints` lists
  them); no foot in contact is evaluated (every set is {0}) with a warning;
- ``awp``, ``fwp``, ``leg_polytopes`` every evaluated cycle; the FWS (H-rep, directional
  and Euclidean margins) when ``fws_rate_hz`` says so by stamp (0 = every cycle) or the
  stance set changed (which restarts the schedule: the next one comes a period later), the
  reports carrying the latest FWS with its ``fws_stamp``. With ``fws_lag_s`` > 0 it is
  computed beside the loop (:attr:`Pipeline.fws_runner`: the node's worker process) and
  released in the first joint state stamped ``fws_lag_s`` after the one it was due for,
  so node and replay still agree; after a stance change the reports carry no FWS until
  the new stance's is released (``feasible`` is then ``fwp_feasible``);
- ``markers`` throttled to ``marker_rate_hz`` by stamp (0 = never);
- every output's ``header.stamp`` is the joint state's stamp; wrench data use the frame
  ``wrench_frame_id`` (CoM origin, world-aligned axes), markers ``marker_frame_id`` ('' = the
  wrench frame, or the URDF root link, e.g. ``base_link``, to overlay them on the robot).

A stamp earlier than the previous joint state's restarts the throttles (a replay loop) and
adds a warning to that report (for a message with a subset of the joints, only a step back
larger than ``joint_states_timeout_s``: two publishers' messages interleave out of order).
Output messages other than the report are built on demand (:class:`Cycle` methods), so a
node with no subscriber on a topic does not pay for it.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import replace
import os
import time

from awp_ros_msgs.msg import ContactState, FeasibilityReport
from builtin_interfaces.msg import Time
from geometry_msgs.msg import WrenchStamped
from nav_msgs.msg import Odometry
import numpy as np
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Header

from awp_ros.errors import AwpError, ConfigError, InputError
from awp_ros.estimation.motion import fill_motion, MotionEstimator
from awp_ros.evaluation.evaluator import compute_fws_steps, FeasibilityEvaluator
from awp_ros.evaluation.result import FeasibilityResult, WrenchSetResult
from awp_ros.geometry.linalg import identity, quaternion_matrix
from awp_ros.robot.config import check_keys, load_config, RobotConfig
from awp_ros.robot.parameters import PipelineParams, ros_parameters
from awp_ros.ros.contact_source import EffortContacts
from awp_ros.ros.conversions import (error_report, report_bytes, report_msg,
                                     robot_state_from_msgs, stamp_to_ns)
from awp_ros.ros.cycle import Cycle
from awp_ros.ros.input_buffer import InputBuffer, stale_reason
from awp_ros.ros.joint_merge import JointMerger
from awp_ros.ros.markers import MarkerStyle

__all__ = ['FWS_LATE_GRACE_S', 'MAX_REASON_CHARS', 'Pipeline', 'REFERENCE_HISTORY',
           'check_marker_frame', 'loss_note', 'shorten_reason', 'unevaluated_report']

_S = FeasibilityReport

#: Longest ``status_message`` of a report (longer reasons are cut, marked with '...').
MAX_REASON_CHARS = 1000

_ORIGIN = np.zeros(3)
_ORIGIN.setflags(write=False)

#: Evaluated joint states kept for :meth:`Pipeline.on_wrench_reference` (the nearest in time).
REFERENCE_HISTORY = 64
#: Wall time [s] a lagged FWS job's runner gets beyond ``fws_lag_s`` from the job's submission;
#: an answer not in by then is computed here (the same numbers): a worker process that is not
#: scheduled (it runs at a lower priority, beside the processes that feed the node) is not
#: waited for with the node's own CPU idle.
FWS_LATE_GRACE_S = 0.005


class Pipeline:
    """
    Turn input messages into output messages (see the module docstring).

    :param config: the robot config (a name or YAML path is loaded by the evaluator), or
        an evaluator built for it.
    :param params: the pipeline parameters.
    :param input_buffer: contacts (and imu) messages kept for joint states that have not
        caught up with them (the node passes its ``qos_depth``: a node lagging by that many
        joint states still pairs each with the contacts current at its stamp).
    :raises ConfigError, ModelError: bad config, unusable URDF, bad marker_frame_id.
    """

    def __init__(self, config: RobotConfig | str | FeasibilityEvaluator,
                 params: PipelineParams | None = None, *, input_buffer: int = 10000) -> None:
        self.evaluator = config if isinstance(config, FeasibilityEvaluator) \
            else FeasibilityEvaluator(config)
        self._joint_names = frozenset(self.evaluator.model.joint_names)
        self.params = PipelineParams() if params is None else params
        check_marker_frame(self.params, self.root_link)
        self.evaluator.hull_tol = max(self.params.hull_tolerance, self.evaluator.feasibility_tol)
        self._contacts = InputBuffer(input_buffer)
        self._imu = InputBuffer(input_buffer)
        self._odom = InputBuffer(input_buffer)
        self._estimator = self._new_estimator()
        self._imu_error = ''
        self._evaluated: deque = deque(maxlen=REFERENCE_HISTORY)
        self._style = MarkerStyle(force_scale=self.params.marker_force_scale,
                                  moment_scale=self.params.marker_moment_scale)
        self._last_js_ns: int | None = None
        self._last_fws_ns: int | None = None
        self._last_marker_ns: int | None = None
        self._latest_fws: WrenchSetResult | None = None
        self._latest_fws_stamp: Time | None = None
        self._latest_fws_stance: tuple | None = None
        # fws_lag_s > 0: FWS jobs submitted, not yet released (release stamp [ns], job
        # stamp, result, cycle's reference point, handle) and the last submission's stance.
        self._fws_pending: deque = deque()
        self._submitted_stance: tuple | None = None
        #: Runs the lagged FWS jobs: ``submit(job) -> handle`` with ``handle.result(timeout)``
        #: returning :func:`~awp_ros.evaluation.evaluator.compute_fws`'s answer, computed
        #: here when the runner's is not in within ``timeout`` [s] (the node sets a worker
        #: process's; by default computed here, on release).
        self.fws_runner = InlineFws()
        self._merger = self._new_merger()
        self._effort = self._new_effort_contacts()

    @classmethod
    def from_parameters(cls, params: Mapping, *, base_dir: str | os.PathLike | None = None,
                        input_buffer: int = 10000) -> Pipeline:
        """
        Build a pipeline from the node's parameters (a parameters file's mapping, or flat).

        The robot comes from the ``robot`` key (a config name or path, its robot keys
        overridden by the mapping's) when the mapping has no ``urdf`` or ``feet`` of its
        own, else from the mapping's robot keys (``urdf`` relative to ``base_dir``);
        ``robot_description`` (URDF XML) replaces the URDF when non-empty.

        :raises ConfigError: a key no reader knows (named with its close matches), a bad
            value, a required robot key missing.
        """
        flat = ros_parameters(params)
        check_keys(flat)
        if flat.get('robot') and 'urdf' not in flat and 'feet' not in flat:
            config = load_config(flat['robot'], overrides=flat)
        else:
            config = RobotConfig.from_dict(flat, base_dir=base_dir)
        if flat.get('robot_description'):
            config = replace(config, urdf=str(flat['robot_description']))
        return cls(config, PipelineParams.from_dict(flat), input_buffer=input_buffer)

    # -- configuration ---------------------------------------------------------------------

    @property
    def config(self) -> RobotConfig:
        """Return the robot config in use."""
        return self.evaluator.config

    @property
    def root_link(self) -> str:
        """Return the URDF root link (the free flyer's child body), e.g. ``base_link``."""
        return self.evaluator.model.root_link

    def set_config(self, config: RobotConfig | FeasibilityEvaluator) -> None:
        """
        Use a new robot config (or an evaluator built for it) from the next message on.

        :raises ConfigError, ModelError: the config is unusable, or ``marker_frame_id`` is
            not valid for its model (the old config stays).
        """
        evaluator = config if isinstance(config, FeasibilityEvaluator) \
            else FeasibilityEvaluator(config)
        check_marker_frame(self.params, evaluator.model.root_link)
        evaluator.hull_tol = max(self.params.hull_tolerance, evaluator.feasibility_tol)
        self.evaluator = evaluator
        self._joint_names = frozenset(evaluator.model.joint_names)
        self._latest_fws_stance = None
        self._drop_pending_fws()
        self._estimator = self._new_estimator()
        self._evaluated.clear()
        self._merger = self._new_merger()
        self._effort = self._new_effort_contacts()

    def set_params(self, params: PipelineParams) -> None:
        """
        Use new pipeline parameters from the next message on.

        :raises ConfigError: ``marker_frame_id`` is neither '' nor the wrench frame nor the
            root link.
        """
        check_marker_frame(params, self.root_link)
        old, self.params = self.params, params
        self.evaluator.hull_tol = max(params.hull_tolerance, self.evaluator.feasibility_tol)
        if params.acceleration_cutoff_hz != old.acceleration_cutoff_hz \
                or params.stale_timeout_s != old.stale_timeout_s:
            self._estimator = self._new_estimator()
        if (params.joint_states_timeout_s, params.ignored_joints) \
                != (old.joint_states_timeout_s, old.ignored_joints):
            self._merger.timeout_ns = int(round(params.joint_states_timeout_s * 1e9))
            self._merger.ignored = frozenset(params.ignored_joints)
            self._merger.extra -= self._merger.ignored
        if (params.contact_force_on_n, params.contact_force_off_n) \
                != (old.contact_force_on_n, old.contact_force_off_n):
            self._effort = self._new_effort_contacts()

    def _new_estimator(self) -> MotionEstimator:
        """Return a motion estimator for the model and parameters in use (no history)."""
        p = self.params
        age = p.stale_timeout_s if p.stale_timeout_s > 0.0 else 1e9   # 0: no age limit
        # History as deep as the input buffer: a node lagging behind its joint states holds
        # the IMU readings of the whole lag (with 32, a lag over 64 ms at 500 Hz silently
        # paired no IMU: level base, no base acceleration).
        return MotionEstimator(self.evaluator.model, cutoff_hz=p.acceleration_cutoff_hz,
                               max_imu_age_s=age, max_odometry_age_s=age,
                               history=self._imu.maxlen)

    def _new_merger(self) -> JointMerger:
        """Return a joint-state merger for the model and parameters in use (no values)."""
        p = self.params
        return JointMerger(self.evaluator.model.joint_names, timeout_s=p.joint_states_timeout_s,
                           ignored=p.ignored_joints)

    def _new_effort_contacts(self) -> EffortContacts:
        """Return the effort stance detector for the model and thresholds in use."""
        p = self.params
        return EffortContacts(self.evaluator, on_n=p.contact_force_on_n,
                              off_n=p.contact_force_off_n)

    @property
    def extra_joints(self) -> set[str]:
        """Return the joints seen in joint_states that the model does not have (not ignored)."""
        return self._merger.extra

    @property
    def normal_forces(self):
        """Return the last measured normal forces [N] of every foot (``contact_source`` effort)."""
        return self._effort.normal_forces

    # -- inputs ----------------------------------------------------------------------------

    def on_contacts(self, msg: ContactState) -> None:
        """
        Keep a contact state for the joint states it precedes (validated with them).

        Ignored unless ``contact_source`` is ``topic``. A contacts message holds until the
        next one, unless ``contacts_timeout_s`` > 0.
        """
        if self.params.contact_source == 'topic':
            self._contacts.add(msg)

    def on_imu(self, msg: Imu) -> None:
        """
        Take an IMU message (used when ``use_imu``): base orientation and motion.

        The IMU's mounting comes from the URDF frame ``header.frame_id`` ('' = the root
        link); a frame the URDF does not have, or a bad reading, makes the joint states
        paired with it invalid (the reason names the frame), until a good reading comes.
        """
        self._imu.add(msg)
        try:
            self._estimator.set_imu_frame(msg.header.frame_id or self.root_link)
            o = msg.orientation
            has = msg.orientation_covariance[0] != -1.0 and (o.x, o.y, o.z, o.w) != (0, 0, 0, 0)
            w, f = msg.angular_velocity, msg.linear_acceleration
            self._estimator.add_imu(stamp_to_ns(msg.header.stamp),
                                    (o.x, o.y, o.z, o.w) if has else None,
                                    (w.x, w.y, w.z), (f.x, f.y, f.z))
            self._imu_error = ''
        except AwpError as exc:
            self._imu_error = f'imu: {exc}'

    def on_odometry(self, msg: Odometry) -> None:
        """
        Take a ``nav_msgs/Odometry`` message (used when ``use_odometry``).

        ``pose.pose.orientation``: the base orientation when there is no IMU;
        ``twist.twist``: the base twist in ``child_frame_id`` (the base) [m/s, rad/s].
        """
        self._odom.add(msg)
        o, tw = msg.pose.pose.orientation, msg.twist.twist
        quat = (o.x, o.y, o.z, o.w)
        try:
            self._estimator.add_odometry(
                stamp_to_ns(msg.header.stamp), quat if any(quat) else None,
                (tw.linear.x, tw.linear.y, tw.linear.z),
                (tw.angular.x, tw.angular.y, tw.angular.z))
        except AwpError as exc:
            self._imu_error = f'odometry: {exc}'

    def keep_references(self, history: int) -> None:
        """
        Keep the last ``history`` (>= 1) evaluated joint states for :meth:`on_wrench_reference`.

        The node keeps :data:`REFERENCE_HISTORY` while ``~/wrench_reference`` has publishers
        and only the latest otherwise: a kept evaluation (~0.3 MB of polytopes) is freed
        ``history`` joint states later, when its memory is no longer in the caches (~25 us
        a joint state at 2 kHz, measured), instead of one cycle later.
        """
        history = max(1, int(history))
        if history != self._evaluated.maxlen:
            self._evaluated = deque(self._evaluated, maxlen=history)

    def on_wrench_reference(self, msg: WrenchStamped) -> FeasibilityReport:
        """
        Return the report of a wrench to check, against the joint state nearest in time.

        The wrench is force [N] and moment about the CoM [N.m] in world-aligned axes (the
        wrench frame: ``header.frame_id`` '' or ``wrench_frame_id``), e.g. what an MPC plans;
        its margins are taken to the AWP, FWP and (latest) FWS of the evaluated joint state
        whose stamp is nearest to ``header.stamp``, whose stamp the report carries.
        """
        t0 = time.perf_counter()
        p = self.params
        header = Header(stamp=msg.header.stamp, frame_id=p.wrench_frame_id)
        if msg.header.frame_id not in ('', p.wrench_frame_id):
            return unevaluated_report(msg, p.wrench_frame_id, _S.STATUS_INVALID_INPUT,
                                      f'wrench_reference frame_id {msg.header.frame_id!r}: '
                                      f"expected '' or {p.wrench_frame_id!r} (force and moment "
                                      'about the CoM, world-aligned axes)', t0=t0)
        if not self._evaluated:
            return unevaluated_report(msg, p.wrench_frame_id, _S.STATUS_STALE_INPUT,
                                      'no evaluated joint state yet', t0=t0)
        ns = stamp_to_ns(msg.header.stamp)
        js_stamp, result, fws, fws_stamp = min(
            self._evaluated, key=lambda e: abs(stamp_to_ns(e[0]) - ns))
        f, t = msg.wrench.force, msg.wrench.torque
        w = np.array([f.x, f.y, f.z, t.x, t.y, t.z], dtype=float)
        try:
            checked = self.evaluator.with_wrench(result, w, fws=fws)
        except InputError as exc:
            return unevaluated_report(msg, p.wrench_frame_id, _S.STATUS_INVALID_INPUT,
                                      str(exc), t0=t0)
        header.stamp = js_stamp
        report = report_msg(header, checked, compute_time=0.0, fws=checked.fws,
                            fws_stamp=fws_stamp)
        report.compute_time = time.perf_counter() - t0
        return report

    def on_joint_state(self, msg: JointState, *, missing: int = 0,
                       queue_delay_s: float = 0.0) -> Cycle:
        """
        Evaluate one joint-state message and return its outputs.

        :param missing: joint states published before this one that never arrived (the
            node counts them from sequence gaps): a warning first in ``status_message``.
        :param queue_delay_s: how long the message waited in the input queue [s]; beyond
            ``max_queue_delay_s`` (when > 0) it is answered unevaluated (load shedding).
        """
        t0 = time.perf_counter()
        p = self.params
        notes = [loss_note(missing)] if missing else []
        if 0.0 < p.max_queue_delay_s < queue_delay_s:
            report = unevaluated_report(msg, p.wrench_frame_id, _S.STATUS_STALE_INPUT, '; '.join(
                notes + [f'not evaluated: the joint state waited {queue_delay_s:.3f} s in the '
                         f'input queue (max_queue_delay_s {p.max_queue_delay_s:g}); the node '
                         'is overloaded and sheds load']), t0=t0)
            return Cycle.unevaluated(report)
        ns = stamp_to_ns(msg.header.stamp)
        header = Header(stamp=msg.header.stamp, frame_id=p.wrench_frame_id)
        # Messages of several publishers, each with a subset of the joints, interleave out
        # of stamp order by up to the merge timeout: only a larger step back is one.
        back = 0 if self._merger.is_full(msg.name) else self._merger.timeout_ns
        if self._last_js_ns is not None and ns < self._last_js_ns - back:
            notes.append(f'joint_states stamp went back by {(self._last_js_ns - ns) * 1e-9:.6g}'
                         ' s; throttles restarted')
            self._last_fws_ns = self._last_marker_ns = None
            self._drop_pending_fws()
            self._merger.clear()
            self._effort.reset()
            self._last_js_ns = ns
        elif self._last_js_ns is None or ns > self._last_js_ns:
            self._last_js_ns = ns
        markers_due = p.marker_rate_hz > 0.0 and _due(self._last_marker_ns, ns,
                                                      p.marker_rate_hz)
        if markers_due:
            self._last_marker_ns = _advance(self._last_marker_ns, ns, p.marker_rate_hz)
        result = None
        fws_computed = False
        released = None
        R = identity(3)
        source = p.contact_source
        contacts = self._contacts.pick(ns) if source == 'topic' else None
        imu = self._imu.pick(ns) if p.use_imu else None
        try:
            joints = self._merger.add(msg, ns)          # str: why the merged state is not
            inputs = ([('contacts', contacts, p.contacts_timeout_s)] if source == 'topic'
                      else []) + ([('imu', imu)] if p.use_imu else []) \
                + ([('odom', self._odom.pick(ns))] if p.use_odometry else [])
            stale = joints if isinstance(joints, str) else \
                stale_reason(ns, inputs, p.stale_timeout_s)
            if not stale and self._imu_error and (p.use_imu or p.use_odometry):
                raise InputError(self._imu_error)
            if stale:
                report = error_report(header, _S.STATUS_STALE_INPUT,
                                      '; '.join(notes + [stale]))
            else:
                state = robot_state_from_msgs(
                    joints, contacts, imu, feet=self.evaluator.feet,
                    use_velocities=p.use_joint_velocities,
                    use_efforts=p.use_joint_efforts or source == 'effort', notes=notes)
                if p.use_imu or p.use_odometry or p.measured_motion:
                    fill_motion(self._estimator, ns, state, measured=p.measured_motion)
                if source == 'effort':
                    state.stance = self._effort.update(state)
                    if not p.use_joint_efforts:
                        state.joint_efforts = None
                elif source == 'all':
                    state.stance = list(self.evaluator.feet)
                result = self.evaluator.evaluate(state, fws=False,
                                                 base_velocity_known=p.use_odometry)
                if not result.stance:
                    notes.append('no foot in contact: every wrench set is {0}, no wrench '
                                 'but zero is feasible')
                if p.use_imu:
                    R = quaternion_matrix(state.base_orientation)
                by_rate = p.fws_rate_hz == 0.0 or _due(self._last_fws_ns, ns, p.fws_rate_hz)
                if p.fws_lag_s > 0.0:
                    released = self._lagged_fws(result, ns, msg.header.stamp, by_rate,
                                                R.T @ result.com)
                elif by_rate or result.stance != self._latest_fws_stance:
                    self._drop_pending_fws()
                    self.evaluator.add_fws(result)
                    fws_computed = True
                    # A stance change restarts the schedule: the FWS is never older than
                    # one period, and not computed twice within one.
                    self._last_fws_ns = _advance(self._last_fws_ns, ns, p.fws_rate_hz) \
                        if by_rate else ns
                    self._latest_fws = result.fws
                    self._latest_fws_stamp = msg.header.stamp
                    self._latest_fws_stance = result.stance
                self._evaluated.append((msg.header.stamp, result, self._latest_fws,
                                        self._latest_fws_stamp))
                warnings = notes + result.warnings
                report = None                   # made as bytes below, once timed
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
        if report is None:
            message = shorten_reason('; '.join(warnings))
            report = report_bytes(header, result, compute_time=time.perf_counter() - t0,
                                  fws=self._latest_fws, fws_stamp=self._latest_fws_stamp,
                                  status=_S.STATUS_WARNING if message else _S.STATUS_OK,
                                  status_message=message,
                                  fws_pending=self._latest_fws is None)
        else:
            report.status_message = shorten_reason(report.status_message)
            report.compute_time = time.perf_counter() - t0
        com = _ORIGIN if result is None else result.com
        if p.marker_frame_id in ('', p.wrench_frame_id):
            frame = (identity(3), _ORIGIN)
        else:  # the root link: x_base = R^T (com + x)
            frame = (R.T, R.T @ com)
        style = self._style
        if style.force_scale != p.marker_force_scale \
                or style.moment_scale != p.marker_moment_scale:
            style = self._style = MarkerStyle(force_scale=p.marker_force_scale,
                                              moment_scale=p.marker_moment_scale)
        return Cycle(header, report, result, fws_computed=fws_computed,
                     markers_due=markers_due,
                     marker_frame_id=p.marker_frame_id or p.wrench_frame_id,
                     marker_frame=frame, style=style,
                     reference_point=com if R is identity(3) else R.T @ com,
                     latest_fws=self._latest_fws, pyramid_sides=self.config.pyramid_sides,
                     released_fws=released)

    def _lagged_fws(self, result: FeasibilityResult, ns: int, stamp: Time, by_rate: bool,
                    reference_point: np.ndarray) -> tuple | None:
        """
        Submit the FWS when due, release those whose lag has passed (``fws_lag_s`` > 0).

        Due as with no lag (``fws_rate_hz`` by stamp, or a stance change, which drops the
        pending jobs of the old stance and the latest FWS: reports then carry no FWS until
        the new stance's arrives). A job due at stamp ``t`` is released in the first
        evaluated joint state stamped ``>= t + fws_lag_s``: the reports depend on stamps
        only. A runner whose answer is not in by ``fws_lag_s`` + :data:`FWS_LATE_GRACE_S` of
        wall time after the submission is not waited for: the job is computed here then.

        :return: ``(stamp, result, reference point)`` of the job released last in this
            cycle (its ``~/fws`` message), or None.
        """
        p = self.params
        changed = result.stance != self._submitted_stance
        if changed:
            self._drop_pending_fws()
            self._latest_fws = self._latest_fws_stamp = self._latest_fws_stance = None
        if by_rate or changed:
            self._last_fws_ns = _advance(self._last_fws_ns, ns, p.fws_rate_hz) \
                if by_rate else ns
            handle = self.fws_runner.submit(self.evaluator.fws_job(result))
            deadline = time.monotonic() + p.fws_lag_s + FWS_LATE_GRACE_S   # wall time
            self._fws_pending.append((ns + int(round(p.fws_lag_s * 1e9)), stamp, result,
                                      reference_point, handle, deadline))
            self._submitted_stance = result.stance
        released = None
        while self._fws_pending and self._fws_pending[0][0] <= ns:
            _, job_stamp, job_result, ref, handle, deadline = self._fws_pending.popleft()
            self.evaluator.attach_fws(job_result,
                                      handle.result(timeout=deadline - time.monotonic()))
            self._latest_fws = job_result.fws
            self._latest_fws_stamp = job_stamp
            self._latest_fws_stance = job_result.stance
            released = (job_stamp, job_result, ref)
        return released

    def step_fws(self) -> bool:
        """
        Run one step of the oldest unfinished lagged FWS job computed here; return if one ran.

        Steps are :class:`InlineFws`'s (about 0.1-0.4 ms each); jobs of another runner (a
        worker process) have none. A job not finished when released is finished then.
        """
        for *_, handle, _ in self._fws_pending:
            step = getattr(handle, 'step', None)
            if step is not None and not step():
                return True
        return False

    def _drop_pending_fws(self) -> None:
        """Forget the lagged FWS jobs not yet released (their answers are ignored)."""
        for *_, handle, _ in self._fws_pending:
            cancel = getattr(handle, 'cancel', None)
            if cancel is not None:
                cancel()
        self._fws_pending.clear()
        self._submitted_stance = None


class InlineFws:
    """
    Run lagged FWS jobs in this process, in steps (:func:`compute_fws_steps`).

    A job advances by :meth:`Handle.step` (the node: between joint states,
    :meth:`Pipeline.step_fws`) and finishes when its answer is asked for: the answer is the
    same whenever its steps ran.
    """

    class Handle:
        """A job computed in steps, finished on :meth:`result`."""

        def __init__(self, job: tuple) -> None:
            self._steps, self._part = compute_fws_steps(*job), None

        def step(self) -> bool:
            """Run the job's next piece (about 0.2 ms); return whether its answer is in."""
            if self._part is None:
                try:
                    next(self._steps)
                except StopIteration as stop:
                    self._part = stop.value
            return self._part is not None

        def result(self, timeout: float | None = None) -> tuple:
            """Return :func:`~awp_ros.evaluation.evaluator.compute_fws` of the job."""
            while not self.step():
                pass
            return self._part

    def submit(self, job: tuple) -> InlineFws.Handle:
        """Return a handle computing ``compute_fws(*job)`` in steps."""
        return InlineFws.Handle(job)

    def start(self) -> None:
        """Start nothing (the node's runner protocol, as ``fws_worker.FwsRunner``)."""

    def close(self) -> None:
        """Nothing to stop."""


def _due(last_ns: int | None, ns: int, rate_hz: float) -> bool:
    """Return whether a throttled output is due at stamp ``ns`` [ns] for ``rate_hz``."""
    return last_ns is None or ns - last_ns >= int(round(1e9 / rate_hz))


def _advance(last_ns: int | None, ns: int, rate_hz: float) -> int:
    """
    Return the new reference stamp of a throttle that is due at ``ns``.

    Steps by whole periods while ``ns`` is within one period of the schedule, so that the
    average rate is ``rate_hz`` even when inputs do not fall on the period; restarts at
    ``ns`` after a gap or with rate 0 (every cycle).
    """
    if last_ns is None or rate_hz <= 0.0:
        return ns
    period = int(round(1e9 / rate_hz))
    nxt = last_ns + period
    return nxt if ns - nxt < period else ns


def shorten_reason(reason: str) -> str:
    """Return ``reason`` cut to ``MAX_REASON_CHARS`` (ending in ``...`` when cut)."""
    if len(reason) > MAX_REASON_CHARS:
        return reason[:MAX_REASON_CHARS - 3] + '...'
    return reason


def loss_note(missing: int) -> str:
    """Return the report warning for ``missing`` joint states that never arrived."""
    return (f'{missing} joint states published before this one never arrived (a full input '
            'queue: the node fell qos_depth behind; or a lossy link); they got no report')


def unevaluated_report(msg: JointState, frame_id: str, status: int, reason: str, *,
                       t0: float | None = None) -> FeasibilityReport:
    """
    Return the report of a joint state that is not evaluated (margins NaN, not feasible).

    :param t0: ``time.perf_counter()`` when the message was taken (for ``compute_time``).
    """
    t0 = time.perf_counter() if t0 is None else t0
    report = error_report(Header(stamp=msg.header.stamp, frame_id=frame_id), status,
                          shorten_reason(reason))
    report.compute_time = time.perf_counter() - t0
    return report


def check_marker_frame(params: PipelineParams, root_link: str) -> None:
    """
    Check ``marker_frame_id``: '', the wrench frame, or the model's root link.

    :raises ConfigError: any other frame (markers are drawn in one of these two frames).
    """
    frame = params.marker_frame_id
    if frame not in ('', params.wrench_frame_id, root_link):
        msg = (f"marker_frame_id must be '', the wrench frame {params.wrench_frame_id!r} or "
               f'the root link {root_link!r}; got {frame!r}')
        raise ConfigError(msg)
