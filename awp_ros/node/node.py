"""
``awp_node``: recompute and publish the wrench polytopes of a legged robot every cycle.

A thin rclpy shell over :class:`awp_ros.ros.pipeline.Pipeline` (which the offline replay runs
too, so both produce the same messages)::

    awp_node --ros-args --params-file config/hyq.yaml
    ros2 run awp_ros awp_node --ros-args --params-file config/hyq.yaml -r joint_states:=/js

Subscriptions (relative names, remappable): ``joint_states`` (sensor_msgs/JointState, from
any number of publishers, each with any subset of the joints), ``contacts``
(awp_ros_msgs/ContactState, when ``contact_source`` is ``topic``), ``imu`` (sensor_msgs/Imu,
when ``use_imu``), ``odom`` (nav_msgs/Odometry, when ``use_odometry``). QoS: reliable (or
best effort, ``qos_reliability``), keep last ``qos_depth``; contacts volatile or
transient-local (``contacts_durability``). Their incompatible-QoS, incompatible-type and
matched events, and the types of their publishers in the ROS graph, feed ``/diagnostics``.

Publications: ``~/report`` (FeasibilityReport, one per joint state), ``~/awp``, ``~/fwp``
(WrenchPolytope, each evaluated cycle), ``~/fws`` (at ``fws_rate_hz``), ``~/leg_polytopes``
(LegPolytopes), ``~/support_region`` (PolygonStamped, each evaluated cycle),
``~/feasible_region`` (PolygonStamped, with the FWS), ``~/markers`` (MarkerArray at
``marker_rate_hz``), ``/diagnostics``
(DiagnosticArray, every ``diagnostics_period_s``). Polytope and marker messages are only
built when the topic has a subscriber. Service: ``~/evaluate`` (awp_ros_msgs/srv/Evaluate,
candidate states in, reports out), answered by a worker process beside the stream
(:mod:`awp_ros.node.evaluate_service`).

Parameters: the robot config keys of ``config/<robot>.yaml`` (``robot_name``, ``urdf``,
``feet``, ``leg_joints.<foot>``, ``torque_limits.<joint>``, ``friction_coefficient``,
``contact_normal``, ``pyramid_sides``, ``standing_posture.<joint>``), ``robot`` (a config
name or path to start from), ``robot_description`` (URDF XML replacing ``urdf``), the
pipeline parameters (:data:`awp_ros.ros.pipeline.PARAMETER_DOCS`) and the read-only
``qos_depth``, ``qos_reliability``, ``executor``, ``diagnostics_period_s``, ``blas_threads``,
``main_thread_cpu``.
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

Throughput: after answering a joint state the node takes the next ones straight from its
input queues (:class:`awp_ros.node.input_drain.InputDrain`), waiting for them on a wait set of its
inputs only, and returns to the executor (timers, parameter services) every
``drain_budget_s`` (20 ms): the executor's ~0.2 ms per message is paid ~50 times a second
instead of 1000. Joint states waiting in the DDS reader are moved into the node's own queue
(at most ``qos_depth``) each time it looks for the next one, so a backlog does not slow
Fast DDS's reception down.

Nothing is lost silently. A node slower than its input lets the reliable input queue
grow (``qos_depth`` joint states); beyond it the oldest queued joint states are dropped
without any event (by DDS, or by the node's own queue), so the node counts the gaps in each
publisher's sequence numbers: the next report carries a warning with the count and
``/diagnostics`` the total. With
``max_queue_delay_s`` > 0 the node sheds load instead: a joint state that waited longer
than that in the queue is answered at once with a ``STATUS_STALE_INPUT`` report (not
evaluated), so every joint state still gets its report and latency stays bounded.
"""

from __future__ import annotations

import argparse
import signal
import sys
import time

from awp_ros_msgs.msg import ContactState, FeasibilityReport, LegPolytopes, WrenchPolytope
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PolygonStamped, WrenchStamped
from nav_msgs.msg import Odometry
import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, qos_policy_name_from_kind, QoSProfile,
                       ReliabilityPolicy)
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu, JointState
from visualization_msgs.msg import MarkerArray

from awp_ros.errors import AwpError
from awp_ros.evaluation.evaluator import warm_up
from awp_ros.node.dds import queue_note
from awp_ros.node.diagnostics import NodeDiagnostics
from awp_ros.node.evaluate_service import EvaluateService
from awp_ros.node.fws_worker import FwsRunner
from awp_ros.node.input_drain import InputDrain
from awp_ros.node.lifecycle import run_node
from awp_ros.node.marker_worker import MarkerWorker
from awp_ros.node.parameters import NodeParameters
from awp_ros.node.yield_gate import YieldGate
from awp_ros.robot.parameters import PipelineParams
from awp_ros.ros.cdr import JointStateBytes
from awp_ros.ros.conversions import stamp_to_ns
from awp_ros.ros.pipeline import (InlineFws, loss_note, Pipeline, REFERENCE_HISTORY,
                                  unevaluated_report)
from awp_ros.runtime import (freeze_startup_objects, keep_freed_memory, limit_blas_threads,
                             pin_thread)

__all__ = ['AwpNode', 'SUBSCRIBERS_PERIOD_S', 'main']

#: How often [s] the node asks which outputs have subscribers (:meth:`AwpNode._subscribed`).
SUBSCRIBERS_PERIOD_S = 0.02
#: Period [s] of the timer that wakes the EventsExecutor for queued joint states (it has no
#: guard conditions); the timer runs only while some are queued.
PENDING_TIMER_S = 1e-4
#: The timings [ms] of an FWS computed in the loop (its H-rep, margins and feasible region),
#: whose sum goes to ``/diagnostics`` (``FWS in the loop max [ms]``).
FWS_TIMINGS = ('fws', 'fws_directional', 'fws_margin', 'feasible_region')


class AwpNode(Node):
    """
    The rclpy node: parameters, QoS, subscriptions, publishers, timers (module docstring).

    :param node_name: the node name (default ``awp_node``).
    :param kwargs: passed to :class:`rclpy.node.Node` (namespace, parameter_overrides, ...).
    """

    def __init__(self, node_name: str = 'awp_node', **kwargs) -> None:
        super().__init__(node_name, **kwargs)
        self.pipeline: Pipeline | None = None
        self.parameters = NodeParameters(
            self, self._apply_parameters,
            lambda: None if self.pipeline is None else self.pipeline.root_link)
        # fws_lag_s > 0: the FWS in a worker process (started on first use), or in steps here.
        self.fws_runner = FwsRunner(self._output_error) if self.parameters.value('fws_worker') \
            else InlineFws()
        blas_threads = self.parameters.value('blas_threads')
        self._blas = limit_blas_threads(blas_threads)
        if self._blas is None and blas_threads > 0:
            self.get_logger().warning('threadpoolctl is not installed; BLAS threads not limited')
        keep_freed_memory()
        self.model_error = self.parameters.base_error
        p = self.parameters.pipeline_params()
        if not self.model_error:
            try:
                self.pipeline = Pipeline(self.parameters.robot_config(), p,
                                         input_buffer=self.parameters.value('qos_depth'))
                self.pipeline.fws_runner = self.fws_runner
                self.parameters.declare_torque_limits(self.pipeline.evaluator.model)
                warm_s = warm_up(self.pipeline.config)
                self.get_logger().info(f'kernels loaded (the standing posture evaluated with '
                                       f'every stance size) in {warm_s:.2f} s')
            except (AwpError, ValueError) as exc:
                self.model_error = f'no robot model: {exc}'
        if self.model_error:
            self.get_logger().error(f'{self.model_error}; answering every joint state with '
                                    'STATUS_ERROR until a corrected robot_description (or '
                                    'robot key) is set')
        name = self.pipeline.config.robot_name if self.pipeline else 'unknown'
        topics = ['joint_states'] + (['contacts'] if p.contact_source == 'topic' else []) \
            + (['imu'] if p.use_imu else []) + (['odom'] if p.use_odometry else [])
        self.diagnostics = NodeDiagnostics(self.get_fully_qualified_name().lstrip('/'), name,
                                           topics, stale_timeout_s=p.stale_timeout_s)
        self.diagnostics.topic_timeouts['contacts'] = p.contacts_timeout_s
        self._extra_logged: frozenset = frozenset()
        self._behind = False        # the last /diagnostics said the node is falling behind
        self._last_contacts: ContactState | None = None     # received while no model
        self.diagnostics.model_error = self.model_error
        self.diagnostics.config_errors = self.parameters.config_errors
        self._limits_declared = self.pipeline is not None
        self._create_interfaces(p)
        self._log_startup(p)

    def _log_startup(self, p: PipelineParams) -> None:
        """Log one line: robot, feet, topics, rates."""
        if self.pipeline is None:
            return
        c = self.pipeline.config
        inputs = [s.topic_name for s in self.subscriptions_]
        where = 'in steps between joint states' if isinstance(self.fws_runner, InlineFws) \
            else 'in a worker process'
        self.get_logger().info(
            f'robot {c.robot_name!r}, feet {list(c.feet)}; inputs {inputs}; outputs '
            f'{self.pub_report.topic_name} (every joint state), FWS '
            f'{"every cycle" if p.fws_rate_hz == 0 else f"{p.fws_rate_hz:g} Hz"}'
            f'{f" {where}, {p.fws_lag_s:g} s behind" if p.fws_lag_s > 0 else ""}'
            ', markers '
            f'{"off" if p.marker_rate_hz == 0 else f"{p.marker_rate_hz:g} Hz"}')

    def _apply_parameters(self, evaluator, params: PipelineParams) -> None:
        """Apply an accepted parameter change (post-set): a new model and/or parameters."""
        if evaluator is not None and self.pipeline is None:
            self.pipeline = Pipeline(evaluator, params,
                                     input_buffer=self.parameters.value('qos_depth'))
            self.pipeline.fws_runner = self.fws_runner
            if self._last_contacts is not None:
                self.pipeline.on_contacts(self._last_contacts)
                self._last_contacts = None
            self.model_error = self.diagnostics.model_error = ''
            self.diagnostics.hardware_id = self.pipeline.config.robot_name
            self.get_logger().info(f'robot model {self.pipeline.config.robot_name!r} '
                                   'built; evaluating joint states')
        elif self.pipeline is not None:
            if evaluator is not None:
                self.pipeline.set_config(evaluator)
            self.pipeline.set_params(params)
        self.diagnostics.stale_timeout_s = params.stale_timeout_s
        self.diagnostics.topic_timeouts['contacts'] = params.contacts_timeout_s
        config = None if self.pipeline is None else self.pipeline.config
        self.evaluate_service.update(config, params, self.model_error)
        self._limits_declared = False   # declared on the next joint state (not in a callback)

    # -- interfaces ------------------------------------------------------------------------

    def _create_interfaces(self, p: PipelineParams) -> None:
        depth = self.parameters.value('qos_depth')
        warn, note = queue_note(depth)
        if note:
            (self.get_logger().warning if warn else self.get_logger().info)(note)
        rel = self.parameters.choice('qos_reliability', ('reliable', 'best_effort'))
        reliability = ReliabilityPolicy.RELIABLE if rel == 'reliable' \
            else ReliabilityPolicy.BEST_EFFORT
        qos_in = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                            reliability=reliability)
        qos_out = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                             reliability=ReliabilityPolicy.RELIABLE)
        qos_big = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                             reliability=ReliabilityPolicy.RELIABLE)
        self.pub_report = self.create_publisher(FeasibilityReport, '~/report', qos_out)
        self.pub_reference = self.create_publisher(FeasibilityReport, '~/reference_report',
                                                   qos_big)
        self.pub_wrench = {k: self.create_publisher(WrenchPolytope, f'~/{k}', qos_big)
                           for k in ('awp', 'fwp', 'fws')}
        self.pub_legs = self.create_publisher(LegPolytopes, '~/leg_polytopes', qos_big)
        self.pub_regions = {k: self.create_publisher(PolygonStamped, f'~/{k}', qos_big)
                            for k in ('feasible_region', 'support_region')}
        self.pub_markers = self.create_publisher(MarkerArray, '~/markers', qos_big)
        self._subscribed_set, self._subscribed_due = frozenset(), 0.0
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        # The single-threaded executor serves ready subscriptions in creation order: contacts
        # and imu first, so that a joint state is evaluated after the inputs sent before it.
        subs = [('contacts', ContactState, self._on_contacts)] \
            if p.contact_source == 'topic' else []
        if p.use_imu:
            subs.append(('imu', Imu, self._on_imu))
        if p.use_odometry:
            subs.append(('odom', Odometry, self._on_odometry))
        subs.append(('joint_states', JointState, self._on_joint_state))
        self.subscriptions_ = []
        # The message info (publication sequence number, reception time) drives the loss
        # count and the load shedding; rclpy's EventsExecutor cannot pass it (its callbacks
        # take the message only), so with it both are off.
        with_info = self.parameters.value('executor') != 'events'
        durability = self.parameters.choice('contacts_durability',
                                            ('volatile', 'transient_local'))
        for topic, mtype, callback in subs:
            if not with_info:
                callback = (lambda msg, f=callback: f(msg, {}))  # noqa: E731
            qos = qos_in
            if topic == 'contacts' and durability == 'transient_local':
                qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                                 reliability=reliability,
                                 durability=DurabilityPolicy.TRANSIENT_LOCAL)
            sub = self._input_subscription(topic, mtype, callback, qos,
                                           raw=topic == 'joint_states')
            self.subscriptions_.append(sub)
            c = self.diagnostics.inputs[topic]
            c.name, c.msg_type = sub.topic_name, _type_name(mtype)
        handlers = [h for h, on in ((self._on_contacts, p.contact_source == 'topic'),
                                    (self._on_imu, p.use_imu),
                                    (self._on_odometry, p.use_odometry)) if on]
        self.drain = InputDrain(list(zip(self.subscriptions_[:-1], handlers)),
                                (self.subscriptions_[-1], self._handle_joint_state),
                                self.context, budget_s=self.parameters.value('drain_budget_s'),
                                max_queued=depth)
        # Joint states left in the drain's own queue wake the executor (input_drain.py): a
        # guard condition, or with the EventsExecutor (which has none) a timer, reset when
        # they are left and cancelled when it fires.
        if with_info:
            self.pending_guard = self.create_guard_condition(self._on_pending)
            self.drain.on_pending = self.pending_guard.trigger
        else:
            self.pending_timer = self.create_timer(PENDING_TIMER_S, self._on_pending_timer)
            self.pending_timer.cancel()
            self.drain.on_pending = self.pending_timer.reset
        self.sub_reference = self.create_subscription(
            WrenchStamped, '~/wrench_reference', self._on_wrench_reference, qos_big)
        if p.fws_lag_s > 0.0:       # started now: it warms up before the first joint state
            self.fws_runner.start()
        self.marker_worker = None
        if self.parameters.value('marker_worker') and p.marker_rate_hz > 0.0:
            self.marker_worker = MarkerWorker(self.pub_markers.publish, self._output_error,
                                              fallback=self._build_marker_job)
        # ~/evaluate: answered by a worker process, beside the stream (evaluate_service.py);
        # its computation is paused while a joint state is handled (yield_gate.py).
        self.query_gate = YieldGate.create() if self.parameters.value('evaluate_yield') \
            and hasattr(signal, 'SIGSTOP') else None
        self.evaluate_service = EvaluateService(
            self.resolve_service_name('~/evaluate'), self.get_name(), self.get_namespace(),
            self._output_error, self.get_logger().info,
            gate='' if self.query_gate is None else self.query_gate.path)
        self.drain.on_idle = self._on_idle
        config = None if self.pipeline is None else self.pipeline.config
        self.evaluate_service.update(config, p, self.model_error)
        period = self.parameters.value('diagnostics_period_s')
        self.diag_timer = self.create_timer(period if period > 0 else 1.0,
                                            self._publish_diagnostics,
                                            clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _input_subscription(self, topic: str, mtype, callback, qos: QoSProfile, *,
                            raw: bool = False):
        """
        Subscribe to an input with the events that feed ``/diagnostics``.

        ``raw``: the callback gets the serialized message (joint states:
        :class:`~awp_ros.ros.cdr.JointStateBytes` reads them, ~4x cheaper than rclpy's
        conversion to the generated class).

        ``message_lost`` (counted), ``incompatible_qos`` (a publisher whose QoS does not
        match: named with the policy, instead of only rclpy's log line),
        ``incompatible_type`` and ``matched`` (the publisher count of the per-publisher
        sequence numbers); a middleware without some of them gets the others.
        """
        d = self.diagnostics

        def on_qos(info, t=topic) -> None:
            policy = qos_policy_name_from_kind(info.last_policy_kind)
            d.incompatible_qos(t, info.total_count, policy)
            self.get_logger().warning(
                f'{d.inputs[t].name}: a publisher offers incompatible QoS ({policy}); no '
                'message from it is received (see /diagnostics)')

        full = SubscriptionEventCallbacks(
            message_lost=lambda info, t=topic: d.lost(t, info.total_count_change),
            incompatible_qos=on_qos,
            incompatible_type=lambda info, t=topic: d.incompatible_type(t, info.total_count),
            matched=lambda info, t=topic: d.matched(t, info.current_count))
        lean = SubscriptionEventCallbacks(incompatible_qos=on_qos)
        for events in (full, lean):
            try:
                return self.create_subscription(mtype, topic, callback, qos,
                                                event_callbacks=events, raw=raw)
            except Exception:  # noqa: BLE001,S112 -- middleware without these events
                continue
        return self.create_subscription(mtype, topic, callback, qos, raw=raw)

    # -- callbacks -------------------------------------------------------------------------

    def _on_contacts(self, msg: ContactState, info: dict) -> None:
        self.diagnostics.received('contacts', time.monotonic())
        self.diagnostics.sequence('contacts', info.get('publication_sequence_number'))
        if self.pipeline is not None:
            self.pipeline.on_contacts(msg)
        else:                   # kept for a model built at runtime (contacts sent on change)
            self._last_contacts = msg

    def _on_imu(self, msg: Imu, info: dict) -> None:
        self.diagnostics.received('imu', time.monotonic())
        self.diagnostics.sequence('imu', info.get('publication_sequence_number'))
        if self.pipeline is not None:
            self.pipeline.on_imu(msg)

    def _on_odometry(self, msg: Odometry, info: dict) -> None:
        self.diagnostics.received('odom', time.monotonic())
        self.diagnostics.sequence('odom', info.get('publication_sequence_number'))
        if self.pipeline is not None:
            self.pipeline.on_odometry(msg)

    def _on_wrench_reference(self, msg: WrenchStamped) -> None:
        """Answer a wrench to check with one ``~/reference_report``."""
        if self.pipeline is None:
            report = unevaluated_report(msg, self.parameters.value('wrench_frame_id'),
                                        FeasibilityReport.STATUS_ERROR, self.model_error)
        else:
            report = self.pipeline.on_wrench_reference(msg)
        self.pub_reference.publish(report)

    def _on_joint_state(self, data: bytes, info: dict) -> None:
        self.drain.push(data, info)     # behind those the drain took from the reader before
        self._on_pending()

    def _on_pending(self) -> None:
        try:
            self.drain.run()
        finally:
            if self.query_gate is not None:     # back to the executor: the node is idle
                self.query_gate.resume()

    def _on_pending_timer(self) -> None:
        self.pending_timer.cancel()             # reset again if joint states are left
        self._on_pending()

    def _on_idle(self) -> bool:
        """
        Use a moment without joint states; return whether it ran an FWS step.

        A step of a lagged FWS computed here (the drain then looks at its queue again), else
        ``~/evaluate`` may run.
        """
        if self.pipeline is not None and self.pipeline.step_fws():
            return True
        if self.query_gate is not None:
            self.query_gate.resume()
        return False

    def _handle_joint_state(self, data: bytes, info: dict) -> None:
        # A query being evaluated is stopped from here until the input queue is empty (the
        # drain's on_idle, or the return to the executor): one stop per busy stretch.
        if self.query_gate is not None:
            self.query_gate.pause()
        try:
            msg = JointStateBytes.parse(data)
        except ValueError:          # not what a JointState publisher sends: rclpy decides
            msg = deserialize_message(data, JointState)
        self._answer_joint_state(msg, info)

    def _answer_joint_state(self, msg: JointState, info: dict) -> None:
        self.diagnostics.received('joint_states', time.monotonic())
        missing = self.diagnostics.sequence('joint_states',
                                            info.get('publication_sequence_number'))
        if self.pipeline is None:
            reason = '; '.join(([loss_note(missing)] if missing else []) + [self.model_error])
            frame = self.parameters.value('wrench_frame_id')
            self._publish_report(msg, unevaluated_report(msg, frame, FeasibilityReport.
                                                         STATUS_ERROR, reason))
            return
        if not self._limits_declared:           # a model built or changed at runtime
            self.parameters.declare_torque_limits(self.pipeline.evaluator.model)
            self._limits_declared = True
        delay = _queue_delay(info)
        cycle = self.pipeline.on_joint_state(msg, missing=missing or 0,
                                             queue_delay_s=delay or 0.0)
        self.pub_report.publish(cycle.report_bytes)
        subscribed = self._subscribed()
        if cycle.result is not None:
            for kind, pub in self.pub_wrench.items():
                if pub in subscribed:
                    self._publish_output(pub, kind, getattr(cycle, kind))
            if self.pub_legs in subscribed:
                self._publish_output(self.pub_legs, 'leg_polytopes', cycle.leg_polytopes)
            for name, pub in self.pub_regions.items():
                if pub in subscribed:
                    self._publish_output(pub, name, getattr(cycle, name))
        if cycle.markers_due and self.pub_markers in subscribed:
            self._publish_markers(cycle)
        self.diagnostics.evaluated(cycle.status, cycle.compute_time, self._latency(msg),
                                   cycle.status_message,
                                   None if cycle.result is None else len(cycle.result.stance),
                                   queue_delay_s=delay, transport_delay_s=_transport_delay(info))
        if cycle.fws_computed and cycle.result is not None:      # in the loop (fws_lag_s 0)
            tm = cycle.result.timings_ms
            self.diagnostics.fws_in_loop(sum(tm.get(k, 0.0) for k in FWS_TIMINGS))
        self.pipeline.step_fws()         # a lagged FWS computed here: one step per joint state

    def _subscribed(self) -> frozenset:
        """
        Return the output publishers that have subscribers (outputs are built only for them).

        Asked of the middleware at most every ``SUBSCRIBERS_PERIOD_S``, not per joint state
        (seven calls, ~1.5 us each): a subscriber that comes or goes is seen that much later.
        Likewise whether ``~/wrench_reference`` has publishers (the evaluated joint states
        kept for them, :meth:`~awp_ros.ros.pipeline.Pipeline.keep_references`).
        """
        now = time.monotonic()
        if now >= self._subscribed_due:
            outputs = [*self.pub_wrench.values(), self.pub_legs, *self.pub_regions.values(),
                       self.pub_markers]
            self._subscribed_set = frozenset(p for p in outputs if p.get_subscription_count())
            self._subscribed_due = now + SUBSCRIBERS_PERIOD_S
            if self.pipeline is not None:       # references kept only for a publisher of them
                self.pipeline.keep_references(
                    REFERENCE_HISTORY if self.sub_reference.get_publisher_count() else 1)
        return self._subscribed_set

    def _publish_markers(self, cycle) -> None:
        """Hand the markers to the worker process, or build and publish them here."""
        worker = self.marker_worker
        if worker is not None and worker.alive:
            try:
                if not worker.submit(cycle.marker_job()):
                    self.diagnostics.markers_skipped += 1
            except Exception as exc:  # noqa: BLE001 -- e.g. a job that cannot be pickled
                self._output_error(f'markers: {type(exc).__name__}: {exc}')
            return
        if worker is not None:
            self.marker_worker = None
            worker.close()
            self._output_error('the marker worker process ended; building markers in the '
                               'node from now on')
        self._publish_output(self.pub_markers, 'markers', cycle.markers)

    def _build_marker_job(self, job) -> None:
        """Build and publish, here, a marker job the worker took but died before answering."""
        function, args, kwargs = job
        self._publish_output(self.pub_markers, 'markers', lambda: function(*args, **kwargs))

    def _output_error(self, reason: str) -> None:
        """Count and log an output that could not be built or published (any thread)."""
        self.diagnostics.output_failed(reason)
        self.get_logger().error(reason, throttle_duration_sec=1.0)

    def destroy_node(self) -> None:
        """Stop the workers, release the drain's wait set, destroy the node."""
        if self.marker_worker is not None:
            self.marker_worker.close()
        self.fws_runner.close()
        self.evaluate_service.close()
        if self.query_gate is not None:
            self.query_gate.close()
        self.drain.close()
        super().destroy_node()

    def _publish_report(self, msg: JointState, report: FeasibilityReport) -> None:
        """Publish the report of a joint state that is not evaluated, and count it."""
        self.pub_report.publish(report)
        self.diagnostics.evaluated(report.status, report.compute_time, self._latency(msg),
                                   report.status_message)

    def _latency(self, msg: JointState) -> float | None:
        """Return wall time now minus the joint-state stamp [s], None when not plausible."""
        # The system clock (time_ns: what Clock(SYSTEM_TIME).now() reads, ~10x cheaper).
        latency = (time.time_ns() - stamp_to_ns(msg.header.stamp)) * 1e-9
        return latency if 0.0 <= latency < 60.0 else None

    def _publish_output(self, pub, name: str, build) -> None:
        """Publish ``build()`` unless None; a failure is logged and counted, not raised."""
        try:
            out = build()
            if out is not None:
                pub.publish(out)
        except Exception as exc:  # noqa: BLE001 -- the report went out; keep the node up
            self._output_error(f'could not build {name}: {type(exc).__name__}: {exc}')

    def _publish_diagnostics(self) -> None:
        self._check_inputs()
        worker = getattr(self.fws_runner, 'worker', None)     # InlineFws: none
        if worker is not None:
            self.diagnostics.fws_worker_late = worker.late
        arr = self.diagnostics.build(self.get_clock().now().to_msg(), time.monotonic())
        self.pub_diag.publish(arr)
        # Falling behind is logged when it starts and when it ends, not every period.
        behind = self.diagnostics.falling_behind
        if behind != self._behind:
            if behind:
                self.get_logger().warning(f'/diagnostics: {arr.status[1].message}')
            else:
                self.get_logger().info('keeping up with joint_states again (/diagnostics)')
            self._behind = behind

    def _check_inputs(self) -> None:
        """
        Refresh what ``/diagnostics`` says about the inputs (once per period, not per message).

        The types of every publisher of each input topic (from the ROS graph), the matched
        publishers, and the joints of ``joint_states`` the model does not have (logged once
        when new ones appear).
        """
        d = self.diagnostics
        for sub in self.subscriptions_:
            topic = next((t for t, c in d.inputs.items() if c.name == sub.topic_name), None)
            if topic is None:
                continue
            try:
                infos = self.get_publishers_info_by_topic(sub.topic_name)
                d.graph(topic, [i.topic_type for i in infos])
                d.matched(topic, sub.get_publisher_count())
            except Exception:  # noqa: BLE001 -- a graph query must not stop the diagnostics
                pass
        extra = self.pipeline.extra_joints if self.pipeline is not None else set()
        d.extra_joints = extra
        if extra and not self._extra_logged.issuperset(extra):
            self._extra_logged = frozenset(extra)
            self.get_logger().info(
                f'joint_states names joints the model does not have, ignored: '
                f'{sorted(extra)} (list them in ignored_joints to silence this)')


def _type_name(mtype) -> str:
    """Return a message class's type name, ``pkg/msg/Name``."""
    return f'{mtype.__module__.split(".")[0]}/msg/{mtype.__name__}'


def _queue_delay(info: dict) -> float | None:
    """
    Return how long a message waited since DDS received it [s] (None when unknown).

    ``received_timestamp`` of the message info is taken by the middleware on the system
    clock when the sample arrived, so this is the time spent in the subscription's queue,
    independent of the message's header stamp (which may be simulated or recorded time).
    """
    received = info.get('received_timestamp') if info else None
    if not received:
        return None
    return max(0.0, (time.time_ns() - received) * 1e-9)


def _transport_delay(info: dict) -> float | None:
    """
    Return how long a message took from its publisher's write to DDS receiving it [s].

    The message info's ``source_timestamp`` (the publisher's clock when it wrote the message)
    to its ``received_timestamp`` (this machine's clock when the sample arrived); None when
    either is unknown. With the publisher on another machine it includes the clocks' offset.
    """
    if not info:
        return None
    sent, received = info.get('source_timestamp'), info.get('received_timestamp')
    if not sent or not received:
        return None
    return (received - sent) * 1e-9


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
    return run_node(argv, AwpNode, _spin)


def _spin(node: AwpNode) -> int:
    """Spin the node with the executor its parameters name, until shutdown."""
    kind = node.parameters.choice('executor', ('single_threaded', 'events'))
    _pin_main_thread(node)
    if kind == 'events':
        from rclpy.experimental import EventsExecutor
        executor = EventsExecutor()
        executor.add_node(node)
        freeze_startup_objects()
        # EventsExecutor.spin() of this rclpy build never runs callbacks; spin_once works.
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    else:
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        freeze_startup_objects()
        executor.spin()
    return 0


def _pin_main_thread(node: AwpNode) -> None:
    """Pin this thread to ``main_thread_cpu`` when set; log the outcome (never fatal)."""
    cpu = node.parameters.value('main_thread_cpu')
    if cpu < 0:
        return
    try:
        allowed = pin_thread(cpu)
    except (OSError, ValueError) as exc:
        reason = f'main_thread_cpu {cpu}: {exc}; the main thread is not pinned'
        node.get_logger().error(reason)
        node.parameters.config_errors.append(reason)          # and on /diagnostics
        return
    others = sorted(allowed - {cpu}) or [cpu]
    node.get_logger().info(f'main thread pinned to CPU {cpu} (of {sorted(allowed)}); the '
                           f'worker processes run on CPUs {others}')


if __name__ == '__main__':
    sys.exit(main())
