"""``awp_node``: recompute and publish the wrench polytopes of a legged robot every cycle.

A thin rclpy shell over :class:`awp_ros.pipeline.Pipeline` (which the offline replay runs
too, so both produce the same messages)::

    awp_node --ros-args --params-file config/hyq.yaml
    ros2 run awp_ros awp_node --ros-args --params-file config/hyq.yaml -r joint_states:=/js

Subscriptions (relative names, remappable): ``joint_states`` (sensor_msgs/JointState),
``contacts`` (awp_ros_msgs/ContactState), ``imu`` (sensor_msgs/Imu, when ``use_imu``).
QoS: reliable (or best effort, ``qos_reliability``), keep last ``qos_depth``.

Publications: ``~/report`` (FeasibilityReport, one per joint state), ``~/awp``, ``~/fwp``
(WrenchPolytope, each evaluated cycle), ``~/fws`` (at ``fws_rate_hz``), ``~/leg_polytopes``
(LegPolytopes), ``~/markers`` (MarkerArray at ``marker_rate_hz``), ``/diagnostics``
(DiagnosticArray, every ``diagnostics_period_s``). Polytope and marker messages are only
built when the topic has a subscriber.

Parameters: the robot config keys of ``config/<robot>.yaml`` (``robot_name``, ``urdf``,
``feet``, ``leg_joints.<foot>``, ``torque_limits.<joint>``, ``friction_coefficient``,
``contact_normal``, ``pyramid_sides``, ``standing_posture.<joint>``), ``robot`` (a config
name or path to start from), ``robot_description`` (URDF XML replacing ``urdf``), the
pipeline parameters (:data:`awp_ros.pipeline.PARAMETER_DOCS`) and the read-only
``qos_depth``, ``qos_reliability``, ``executor``, ``diagnostics_period_s``, ``blas_threads``.
Changes of the robot keys (e.g. ``friction_coefficient``, ``torque_limits.lf_kfe_joint``)
and pipeline parameters at runtime are validated and take effect with the next joint
state; invalid values are rejected with the reason.

Failures never stop the node: without a usable robot model (e.g. a malformed
``robot_description``) it stays up, answers every joint state with a ``STATUS_ERROR``
report giving the reason, reports it on ``/diagnostics`` (ERROR) and builds the model as
soon as a corrected ``robot_description`` (or robot key) is set at runtime; an output
message (polytopes, markers) that cannot be built is logged and counted in
``/diagnostics``, and the next message is processed as usual; a parameter of the wrong
type or range at startup is logged, listed in ``/diagnostics`` and replaced by its default
(an integer given for a double is taken as that double).

Nothing is lost silently. A node slower than its input lets the reliable input queue
grow (``qos_depth`` joint states); beyond it DDS replaces the oldest queued joint states
without any event, so the node counts the gaps in each publisher's sequence numbers: the
next report carries a warning with the count and ``/diagnostics`` the total. With
``max_queue_delay_s`` > 0 the node sheds load instead: a joint state that waited longer
than that in the queue is answered at once with a ``STATUS_STALE_INPUT`` report (not
evaluated), so every joint state still gets its report and latency stays bounded.
"""

from __future__ import annotations

import argparse
from array import array
from dataclasses import fields, replace
import sys
import time

from awp_ros_msgs.msg import (ContactState, FeasibilityReport, LegPolytopes,
                              WrenchPolytope)
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Header
from visualization_msgs.msg import MarkerArray

from awp_ros.conversions import error_report, stamp_to_ns
from awp_ros.diagnostics import NodeDiagnostics
from awp_ros.errors import AwpError, ConfigError
from awp_ros.pipeline import PARAMETER_DOCS, Pipeline, PipelineParams
from awp_ros.robot_config import load_config, RobotConfig

__all__ = ['AwpNode', 'NODE_PARAMETER_DOCS', 'ROBOT_PARAMETER_DOCS', 'main']

_T = Parameter.Type

#: Robot config keys (parameters shared with the core's YAML), their type and meaning.
ROBOT_PARAMETER_DOCS = {
    'robot_name': (_T.STRING, 'robot name (diagnostics hardware_id)'),
    'urdf': (_T.STRING, 'URDF: example-robot-data://<path>, a file path, or the XML'),
    'feet': (_T.STRING_ARRAY, 'contact frames (feet), the order of every per-leg output'),
    'friction_coefficient': (_T.DOUBLE, 'default friction coefficient mu > 0 [-]'),
    'contact_normal': (_T.DOUBLE_ARRAY, 'default contact normal, world axes (normalised)'),
    'pyramid_sides': (_T.INTEGER, 'sides N >= 3 of the friction pyramids'),
}
#: Prefixed robot keys: one parameter per foot or joint.
ROBOT_PREFIXES = {
    'leg_joints': (_T.STRING_ARRAY, 'joints driving foot {} (hip to foot)'),
    'torque_limits': (None, 'torque limit of joint {}: L (range [-L, L]) or [min, max] '
                            '[N.m]'),
    'standing_posture': (_T.DOUBLE, 'standing posture of joint {} [rad]'),
}

#: Node-only parameters: (type, default, description, read_only).
NODE_PARAMETER_DOCS = {
    'robot': (_T.STRING, '', "robot config name or YAML path to start from ('' = the "
              'robot keys given as parameters, else hyq)', True),
    'robot_description': (_T.STRING, '', 'URDF XML (as robot_state_publisher takes it); '
                          'replaces urdf when non-empty', False),
    'qos_depth': (_T.INTEGER, 10000, 'keep-last depth of the input subscriptions and the '
                  'report publisher (10000 = 10 s of 1 kHz joint states of backlog)', True),
    'qos_reliability': (_T.STRING, 'reliable', "input QoS reliability: 'reliable' or "
                        "'best_effort' (matches best-effort publishers)", True),
    'executor': (_T.STRING, 'single_threaded', "rclpy executor: 'single_threaded' or "
                 "'events' (rclpy.experimental.EventsExecutor)", True),
    'diagnostics_period_s': (_T.DOUBLE, 1.0, 'period of /diagnostics [s]', True),
    'max_queue_delay_s': (_T.DOUBLE, 0.0, 'load shedding: a joint state that waited longer '
                          'than this in the input queue (the node is slower than its input) '
                          'is answered at once with a STATUS_STALE_INPUT report instead of '
                          'being evaluated, so latency stays bounded and the queue never '
                          'overflows [s]; 0 = evaluate every joint state however late', False),
    'blas_threads': (_T.INTEGER, 1, 'threads of the BLAS under numpy/scipy in this process '
                     '(threadpoolctl); 1 avoids the stalls of busy-waiting BLAS threads on '
                     'cores shared with DDS and other processes; 0 = leave as is', True),
}
_FIELDS = {f.name: f for f in fields(PipelineParams)}


class AwpNode(Node):
    """The rclpy node: parameters, QoS, subscriptions, publishers, timers (module docstring).

    :param node_name: the node name (default ``awp_node``).
    :param kwargs: passed to :class:`rclpy.node.Node` (namespace, parameter_overrides, ...).
    """

    def __init__(self, node_name: str = 'awp_node', **kwargs) -> None:
        super().__init__(node_name, **kwargs)
        self.config_errors: list[str] = []
        for name, (ptype, default, text, ro) in NODE_PARAMETER_DOCS.items():
            self._declare(name, default, text, read_only=ro)
        for name, f in _FIELDS.items():
            self._declare(name, f.default, PARAMETER_DOCS[name],
                          read_only=name == 'use_imu')
        self._blas = _limit_blas_threads(self.get_parameter('blas_threads').value,
                                         self.get_logger())
        self.pipeline: Pipeline | None = None
        self.model_error = ''
        self._limits_declared = False
        self.max_queue_delay_s = float(self.get_parameter('max_queue_delay_s').value)
        self._declare_robot_parameters()
        try:
            self.pipeline = Pipeline(self._robot_config(), self._pipeline_params(),
                                     input_buffer=self.get_parameter('qos_depth').value)
            self._declare_torque_limits()
        except (AwpError, ValueError) as exc:
            self.model_error = f'no robot model: {exc}'
            self.get_logger().error(f'{self.model_error}; answering every joint state with '
                                    'STATUS_ERROR until a corrected robot_description (or '
                                    'robot key) is set')
        p = self._pipeline_params()
        name = self.pipeline.config.robot_name if self.pipeline else 'unknown'
        topics = ['joint_states', 'contacts'] + (['imu'] if p.use_imu else [])
        self.diagnostics = NodeDiagnostics(self.get_fully_qualified_name().lstrip('/'), name,
                                           topics, stale_timeout_s=p.stale_timeout_s)
        self.diagnostics.model_error = self.model_error
        self.diagnostics.config_errors = self.config_errors
        self._wall = Clock(clock_type=ClockType.SYSTEM_TIME)
        self._create_interfaces(p)
        self.add_on_set_parameters_callback(self._on_set_parameters)

    # -- parameters ------------------------------------------------------------------------

    def _declare(self, name: str, default, text: str, *, read_only: bool = False,
                 dynamic: bool = False):
        desc = ParameterDescriptor(name=name, description=text, read_only=read_only,
                                   dynamic_typing=dynamic)
        if name in ('stale_timeout_s', 'fws_rate_hz', 'marker_rate_hz', 'diagnostics_period_s',
                    'max_queue_delay_s'):
            desc.floating_point_range = [FloatingPointRange(from_value=0.0, to_value=1e6)]
        if name == 'qos_depth':
            desc.integer_range = [IntegerRange(from_value=1, to_value=1_000_000)]
        try:
            return self.declare_parameter(name, default, desc)
        except (InvalidParameterTypeException, InvalidParameterValueException) as first:
            error: Exception = first
            override = self._overrides()[name].value
        # A bad value from the params file or -p: an integer where a double is expected is
        # taken as that double; anything else is reported and the default used.
        if isinstance(default, float) and isinstance(override, int) \
                and not isinstance(override, bool):
            try:
                return self.declare_parameter(
                    name, float(override), desc, ignore_override=True)
            except InvalidParameterValueException as second:
                error = second
        reason = (f'parameter {name} = {override!r} rejected ({type(error).__name__}: '
                  f'{str(error).splitlines()[0]}); using the default {default!r}')
        self.get_logger().error(reason)
        self.config_errors.append(reason)
        return self.declare_parameter(name, default, desc, ignore_override=True)

    def _overrides(self) -> dict:
        """Return the parameter overrides (params file, -p) by name."""
        return dict(getattr(self, '_parameter_overrides', {}))

    def _declare_robot_parameters(self) -> None:
        """Declare the robot keys; defaults from the base config (see ``robot``)."""
        overrides = self._overrides()
        robot = self.get_parameter('robot').value
        self._base: RobotConfig | None = None
        try:
            if robot or not any(k in overrides for k in ('robot_name', 'urdf', 'feet')):
                self._base = load_config(robot or 'hyq')
        except AwpError as exc:
            self.model_error = f'no robot model: {exc}'
        base = self._base_dict()
        for name, (ptype, text) in ROBOT_PARAMETER_DOCS.items():
            if name in base or name in overrides:   # any type: RobotConfig validates
                default = base[name] if name in base else overrides[name].value
                self._declare(name, default, text, dynamic=True)
            else:
                self.declare_parameter(name, ptype, ParameterDescriptor(description=text))
        prefixed = {k for k in overrides if k.split('.', 1)[0] in ROBOT_PREFIXES and '.' in k}
        prefixed |= {k for k in base if '.' in k}
        for key in sorted(prefixed):
            prefix, item = key.split('.', 1)
            ptype, text = ROBOT_PREFIXES[prefix]
            self._declare(key, base.get(key, overrides.get(key).value if key in overrides
                                        else None), text.format(item), dynamic=True)

    def _base_dict(self) -> dict:
        """Return the base config as flat parameter values (dotted keys)."""
        c = self._base
        if c is None:
            return {}
        out = {'robot_name': c.robot_name, 'urdf': c.urdf, 'feet': list(c.feet),
               'friction_coefficient': float(c.friction_coefficient),
               'contact_normal': [float(x) for x in c.contact_normal],
               'pyramid_sides': int(c.pyramid_sides)}
        out.update({f'leg_joints.{k}': list(v) for k, v in c.leg_joints.items()})
        out.update({f'torque_limits.{k}': _limit_value(v) for k, v in c.torque_limits.items()})
        out.update({f'standing_posture.{k}': float(v) for k, v in c.standing_posture.items()})
        return out

    def _declare_torque_limits(self) -> None:
        """Declare ``torque_limits.<joint>`` for every leg joint, with the limit in use.

        One call for all of them: after a runtime model recovery the on-set callback then
        runs once (the values are the ones in use, so nothing changes).
        """
        new = []
        for leg in self.pipeline.evaluator.model.legs.values():
            for j, lo, hi in zip(leg.joints, leg.tau_min.tolist(), leg.tau_max.tolist()):
                key = f'torque_limits.{j}'
                if not self.has_parameter(key):
                    text = ROBOT_PREFIXES['torque_limits'][1].format(j)
                    new.append((key, _limit_value((lo, hi)),
                                ParameterDescriptor(name=key, description=text,
                                                    dynamic_typing=True)))
        self._limits_declared = True
        if new:
            try:
                self.declare_parameters('', new)
            except Exception as exc:  # noqa: BLE001 -- the limits stay in use, undeclared
                self.get_logger().warning(f'torque_limits.* parameters not declared: {exc}')

    def _robot_values(self, changes: dict | None = None) -> dict:
        """Return the robot keys' values (with ``changes``) as plain Python values."""
        names = [n for n in self.list_parameters([], 0).names
                 if n in ROBOT_PARAMETER_DOCS or n.split('.', 1)[0] in ROBOT_PREFIXES]
        values = {p.name: p.value for p in self.get_parameters(names)}
        values.update(changes or {})
        values = {k: (list(v) if isinstance(v, (array, tuple)) else v)
                  for k, v in values.items() if v is not None}
        return values

    def _robot_config(self, changes: dict | None = None) -> RobotConfig:
        """Build the RobotConfig from the parameters (``changes`` applied)."""
        values = self._robot_values(changes)
        base_dir = self._base.base_dir if self._base is not None else None
        config = RobotConfig.from_dict(values, base_dir=base_dir)
        urdf = (changes or {}).get('robot_description',
                                   self.get_parameter('robot_description').value)
        if urdf:
            if not isinstance(urdf, str) or not urdf.lstrip().startswith('<'):
                text = urdf[:60] if isinstance(urdf, str) else urdf
                raise ConfigError(f'robot_description must be URDF XML (starting with <), '
                                  f'got {text!r}')
            config = replace(config, urdf=urdf)
        return config

    def _pipeline_params(self, changes: dict | None = None) -> PipelineParams:
        """Build the PipelineParams from the parameters (``changes`` applied)."""
        kw = {name: self.get_parameter(name).value for name in _FIELDS}
        kw.update({k: v for k, v in (changes or {}).items() if k in _FIELDS})
        return PipelineParams.from_dict(kw)

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """Validate a parameter change; apply it from the next joint state on."""
        changes = {p.name: p.value for p in params}
        try:
            new_params = self._pipeline_params(changes)
            robot = {k for k in changes if k in ROBOT_PARAMETER_DOCS or k == 'robot_description'
                     or k.split('.', 1)[0] in ROBOT_PREFIXES}
            if self.pipeline is None and robot:
                self.pipeline = Pipeline(self._robot_config(changes), new_params,
                                         input_buffer=self.get_parameter('qos_depth').value)
                self.model_error = self.diagnostics.model_error = ''
                self.diagnostics.hardware_id = self.pipeline.config.robot_name
                self.get_logger().info(f'robot model {self.pipeline.config.robot_name!r} '
                                       'built; evaluating joint states')
            elif self.pipeline is not None:
                if robot:
                    self.pipeline.set_config(self._robot_config(changes))
                self.pipeline.set_params(new_params)
        except (AwpError, ValueError, TypeError) as exc:
            reason = f'rejected {sorted(changes)}: {exc}'
            self.get_logger().warning(reason)
            return SetParametersResult(successful=False, reason=reason)
        self.diagnostics.stale_timeout_s = new_params.stale_timeout_s
        if 'max_queue_delay_s' in changes:
            self.max_queue_delay_s = float(changes['max_queue_delay_s'])
        return SetParametersResult(successful=True)

    # -- interfaces ------------------------------------------------------------------------

    def _create_interfaces(self, p: PipelineParams) -> None:
        depth = self.get_parameter('qos_depth').value
        rel = self.get_parameter('qos_reliability').value
        if rel not in ('reliable', 'best_effort'):
            reason = (f"qos_reliability must be 'reliable' or 'best_effort', got {rel!r}; "
                      "using 'reliable'")
            self.get_logger().error(reason)
            self.config_errors.append(reason)
            rel = 'reliable'
        reliability = ReliabilityPolicy.RELIABLE if rel == 'reliable' \
            else ReliabilityPolicy.BEST_EFFORT
        qos_in = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                            reliability=reliability)
        qos_out = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                             reliability=ReliabilityPolicy.RELIABLE)
        qos_big = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                             reliability=ReliabilityPolicy.RELIABLE)
        self.pub_report = self.create_publisher(FeasibilityReport, '~/report', qos_out)
        self.pub_wrench = {k: self.create_publisher(WrenchPolytope, f'~/{k}', qos_big)
                           for k in ('awp', 'fwp', 'fws')}
        self.pub_legs = self.create_publisher(LegPolytopes, '~/leg_polytopes', qos_big)
        self.pub_markers = self.create_publisher(MarkerArray, '~/markers', qos_big)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        # The single-threaded executor serves ready subscriptions in creation order: contacts
        # and imu first, so that a joint state is evaluated after the inputs sent before it.
        subs = [('contacts', ContactState, self._on_contacts)]
        if p.use_imu:
            subs.append(('imu', Imu, self._on_imu))
        subs.append(('joint_states', JointState, self._on_joint_state))
        self.subscriptions_ = []
        # The message info (publication sequence number, reception time) drives the loss
        # count and the load shedding; rclpy's EventsExecutor cannot pass it (its callbacks
        # take the message only), so with it both are off.
        with_info = self.get_parameter('executor').value != 'events'
        for topic, mtype, callback in subs:
            if not with_info:
                callback = (lambda msg, f=callback: f(msg, {}))  # noqa: E731
            events = SubscriptionEventCallbacks(
                message_lost=lambda info, t=topic: self.diagnostics.lost(
                    t, info.total_count_change))
            try:
                sub = self.create_subscription(mtype, topic, callback, qos_in,
                                               event_callbacks=events)
            except Exception:  # noqa: BLE001 -- middleware without message_lost events
                sub = self.create_subscription(mtype, topic, callback, qos_in)
            self.subscriptions_.append(sub)
        period = self.get_parameter('diagnostics_period_s').value
        self.diag_timer = self.create_timer(period if period > 0 else 1.0,
                                            self._publish_diagnostics,
                                            clock=Clock(clock_type=ClockType.STEADY_TIME))

    # -- callbacks -------------------------------------------------------------------------

    def _on_contacts(self, msg: ContactState, info: dict) -> None:
        self.diagnostics.received('contacts', time.monotonic())
        self.diagnostics.sequence('contacts', info.get('publication_sequence_number'))
        if self.pipeline is not None:
            self.pipeline.on_contacts(msg)

    def _on_imu(self, msg: Imu, info: dict) -> None:
        self.diagnostics.received('imu', time.monotonic())
        self.diagnostics.sequence('imu', info.get('publication_sequence_number'))
        if self.pipeline is not None:
            self.pipeline.on_imu(msg)

    def _on_joint_state(self, msg: JointState, info: dict) -> None:
        self.diagnostics.received('joint_states', time.monotonic())
        missing = self.diagnostics.sequence('joint_states',
                                            info.get('publication_sequence_number'))
        notes = [f'{missing} joint states published before this one never arrived (a full '
                 'input queue: the node fell qos_depth behind; or a lossy link); they got no '
                 'report'] if missing else []
        delay = _queue_delay(info)
        if self.pipeline is None:
            self._answer_unevaluated(msg, FeasibilityReport.STATUS_ERROR,
                                     '; '.join(notes + [self.model_error]))
            return
        if 0.0 < self.max_queue_delay_s < delay:
            self._answer_unevaluated(msg, FeasibilityReport.STATUS_STALE_INPUT, '; '.join(
                notes + [f'not evaluated: the joint state waited {delay:.3f} s in the input '
                         f'queue (max_queue_delay_s {self.max_queue_delay_s:g}); the node is '
                         'overloaded and sheds load']))
            return
        if not self._limits_declared:           # the model was built at runtime
            self._declare_torque_limits()
        cycle = self.pipeline.on_joint_state(msg, notes)
        report = cycle.report
        self.pub_report.publish(report)
        if cycle.result is not None:
            for kind, pub in self.pub_wrench.items():
                if pub.get_subscription_count():
                    self._publish_output(pub, kind, getattr(cycle, kind))
            if self.pub_legs.get_subscription_count():
                self._publish_output(self.pub_legs, 'leg_polytopes', cycle.leg_polytopes)
        if cycle.markers_due and self.pub_markers.get_subscription_count():
            self._publish_output(self.pub_markers, 'markers', cycle.markers)
        self.diagnostics.evaluated(report.status, report.compute_time, self._latency(msg),
                                   report.status_message,
                                   None if cycle.result is None else len(cycle.result.stance))

    def _answer_unevaluated(self, msg: JointState, status: int, reason: str) -> None:
        """Publish the report of a joint state that is not evaluated (fast path)."""
        t0 = time.perf_counter()
        frame = self.pipeline.params.wrench_frame_id if self.pipeline is not None \
            else self.get_parameter('wrench_frame_id').value
        report = error_report(Header(stamp=msg.header.stamp, frame_id=frame), status, reason)
        report.compute_time = time.perf_counter() - t0
        self.pub_report.publish(report)
        self.diagnostics.evaluated(status, report.compute_time, self._latency(msg), reason)

    def _latency(self, msg: JointState) -> float | None:
        """Return wall time now minus the joint-state stamp [s], None when not plausible."""
        latency = (self._wall.now().nanoseconds - stamp_to_ns(msg.header.stamp)) * 1e-9
        return latency if 0.0 <= latency < 60.0 else None

    def _publish_output(self, pub, name: str, build) -> None:
        """Publish ``build()`` unless None; a failure is logged and counted, not raised."""
        try:
            out = build()
            if out is not None:
                pub.publish(out)
        except Exception as exc:  # noqa: BLE001 -- the report went out; keep the node up
            reason = f'{name}: {type(exc).__name__}: {exc}'
            self.diagnostics.output_failed(reason)
            self.get_logger().error(f'could not build {reason}', throttle_duration_sec=1.0)

    def _publish_diagnostics(self) -> None:
        self.pub_diag.publish(self.diagnostics.build(self.get_clock().now().to_msg(),
                                                     time.monotonic()))


def _queue_delay(info: dict) -> float:
    """Return how long a message waited since DDS received it [s] (0 when unknown).

    ``received_timestamp`` of the message info is taken by the middleware on the system
    clock when the sample arrived, so this is the time spent in the subscription's queue,
    independent of the message's header stamp (which may be simulated or recorded time).
    """
    received = info.get('received_timestamp') if info else None
    if not received:
        return 0.0
    return max(0.0, (time.time_ns() - received) * 1e-9)


def _limit_blas_threads(n: int, logger):
    """Limit the BLAS thread pools of this process to ``n`` threads (0: leave them).

    OpenBLAS threads busy-wait between calls; on a machine whose cores are shared with the
    DDS threads, the message publisher and other processes they stalled single FWS
    evaluations for ~300 ms (measured on 2 cores); with 1 thread the same took ~10 ms.
    """
    if n <= 0:
        return None
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        logger.warning('threadpoolctl is not installed; BLAS threads not limited')
        return None
    return threadpool_limits(limits=n, user_api='blas')


def _limit_value(pair) -> float | list[float]:
    """Return a torque range as a parameter value: L when symmetric, else [min, max]."""
    lo, hi = (float(x) for x in pair)
    return hi if lo == -hi else [lo, hi]


def main(args=None) -> int:
    """Run the node until Ctrl-C (console script ``awp_node``)."""
    argv = sys.argv if args is None else list(args)
    user = rclpy.utilities.remove_ros_args(argv)[1:]
    parser = argparse.ArgumentParser(
        prog='awp_node', description=__doc__.split('\n\n')[0],
        epilog='ROS arguments go after --ros-args, e.g. awp_node --ros-args --params-file '
               'config/hyq.yaml -p fws_rate_hz:=20.0 -r joint_states:=/robot/joint_states. '
               'Topics and parameters: see the README.')
    parser.parse_args(user)
    rclpy.init(args=argv)
    node = None
    try:
        node = AwpNode()
        kind = node.get_parameter('executor').value
        if kind not in ('single_threaded', 'events'):
            reason = (f"executor must be 'single_threaded' or 'events', got {kind!r}; using "
                      "'single_threaded'")
            node.get_logger().error(reason)
            node.config_errors.append(reason)
        if kind == 'events':
            from rclpy.experimental import EventsExecutor
            executor = EventsExecutor()
            executor.add_node(node)
            # EventsExecutor.spin() of this rclpy build never runs callbacks; spin_once works.
            while rclpy.ok():
                executor.spin_once(timeout_sec=0.1)
        else:
            executor = SingleThreadedExecutor()
            executor.add_node(node)
            executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
