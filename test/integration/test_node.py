"""
awp_node as its own process (the installed console script), driven over real DDS.

The test process is the other DDS participant: an rclpy context on the test's own domain
(``ros_env``) with publishers of joint states and contacts and subscriptions to the node's
outputs, spun in a background thread.
"""

from __future__ import annotations

from dataclasses import replace
import json
import math
import os
from pathlib import Path
import signal
import subprocess
import sys
import threading
import time

from awp_ros_msgs.msg import ContactState, FeasibilityReport, LegPolytopes, WrenchPolytope
from diagnostic_msgs.msg import DiagnosticArray
import numpy as np
import pytest
from rcl_interfaces.srv import SetParameters
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from visualization_msgs.msg import Marker, MarkerArray

from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.node.launcher import start_node, stop_node
from awp_ros.robot.config import find_parameters_file
from awp_ros.robot.state import RobotState
from awp_ros.ros.conversions import polytope_from_msg, stamp_to_ns

AWP_EVAL = Path(sys.executable).parent / 'awp_eval'
FEET = ['lf_foot', 'rf_foot', 'lh_foot', 'rh_foot']
QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=20000,
                 reliability=ReliabilityPolicy.RELIABLE)


@pytest.fixture(scope='module')
def evaluator():
    return FeasibilityEvaluator('hyq')


class Peer:
    """The test's side of the DDS conversation with one awp_node process."""

    def __init__(self, env: dict, outputs: dict) -> None:
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=int(env['ROS_DOMAIN_ID']))
        self.node = rclpy.create_node('awp_test_peer', context=self.context)
        self.js = self.node.create_publisher(JointState, 'joint_states', QOS)
        self.contacts = self.node.create_publisher(ContactState, 'contacts', QOS)
        self.lock = threading.Lock()
        self.got: dict[str, list] = {name: [] for name in outputs}
        for name, mtype in outputs.items():
            topic = name if name.startswith('/') else f'awp_node/{name}'
            self.node.create_subscription(mtype, topic, self._store(name), QOS)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def _store(self, name: str):
        def callback(msg) -> None:
            with self.lock:
                self.got[name].append(msg)
        return callback

    def wait_for(self, predicate, timeout: float, what: str) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.lock:
                if predicate(self.got):
                    return
            time.sleep(0.02)
        with self.lock:
            counts = {k: len(v) for k, v in self.got.items()}
        raise AssertionError(f'timed out after {timeout} s waiting for {what}; got {counts}')

    def wait_matched(self, timeout: float = 30.0) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if (self.js.get_subscription_count() and self.contacts.get_subscription_count()
                    and self.node.count_publishers('awp_node/report')):
                time.sleep(0.3)
                return
            time.sleep(0.05)
        raise AssertionError('awp_node did not appear on DDS')

    def now_ns(self) -> int:
        return self.node.get_clock().now().nanoseconds

    def close(self) -> None:
        self.executor.shutdown()
        self.thread.join(timeout=5)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


@pytest.fixture
def run_node(ros_env, monkeypatch):
    """Start awp_node with extra --ros-args and return a connected Peer."""
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    started = []

    def start(outputs: dict, *args: str, robot: str = 'hyq') -> Peer:
        proc = start_node(env=ros_env, robot=None, params_file=find_parameters_file(robot),
                          ros_args=args)
        peer = Peer(ros_env, outputs)
        peer.proc = proc
        started.append((proc, peer))
        peer.wait_matched()
        return peer

    yield start
    for proc, peer in started:
        peer.close()
        out = stop_node(proc)
        assert 'Traceback' not in out, out


def _stamp(msg, ns: int):
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 10**9)
    return msg


def _contacts(ns: int, stance) -> ContactState:
    return _stamp(ContactState(names=FEET, in_contact=[f in stance for f in FEET]), ns)


def _joints(evaluator, ns: int, q: np.ndarray) -> JointState:
    return _stamp(JointState(name=list(evaluator.model.joint_names), position=q.tolist()), ns)


def _by_stamp(msgs) -> dict:
    return {stamp_to_ns(m.header.stamp): m for m in msgs}


def test_reports_equal_awp_eval_for_the_same_states(run_node, evaluator):
    peer = run_node({'report': FeasibilityReport}, '-p', 'fws_rate_hz:=0.0')
    q0 = evaluator.model.standing_q
    cases = [(FEET, q0), (['lf_foot', 'rh_foot'], q0 + 0.05), (['rf_foot', 'lh_foot', 'rh_foot'],
                                                               q0 - 0.03)]
    stamps = []
    for stance, q in cases:
        ns = peer.now_ns()
        peer.contacts.publish(_contacts(ns, stance))
        time.sleep(0.3)                      # contacts first: another topic, no ordering
        peer.js.publish(_joints(evaluator, ns + 1, q))
        stamps.append(ns + 1)
        peer.wait_for(lambda g: len(g['report']) == len(stamps), 30, 'a report')
    reports = _by_stamp(peer.got['report'])
    for ns, (stance, q) in zip(stamps, cases):
        rep = reports[ns]
        doc = {'robot': 'hyq', 'stance': stance,
               'joint_positions': dict(zip(evaluator.model.joint_names, q.tolist()))}
        res = subprocess.run([str(AWP_EVAL)], input=json.dumps(doc), capture_output=True,
                             text=True, timeout=60)
        assert res.returncode == 0, res.stderr
        ref = json.loads(res.stdout)
        assert rep.status == FeasibilityReport.STATUS_OK, rep.status_message
        assert list(rep.stance_feet) == [f for f in FEET if f in stance]
        np.testing.assert_allclose([rep.wrench.force.z, rep.wrench.torque.x], [
            ref['wrench'][2], ref['wrench'][3]], atol=1e-9)
        for name in ('awp', 'fwp', 'fws'):
            assert getattr(rep, f'{name}_margin') == pytest.approx(ref[name]['margin'],
                                                                   abs=1e-7)
            np.testing.assert_allclose(getattr(rep, f'{name}_normal'), ref[name]['normal'],
                                       atol=1e-7)
            assert getattr(rep, f'{name}_dimension') == ref[name]['dimension']
            assert getattr(rep, f'{name}_feasible') == ref[name]['feasible']
        assert rep.feasible == ref['feasible']
        assert stamp_to_ns(rep.fws_stamp) == ns and rep.compute_time > 0.0


def test_markers_are_well_formed_and_polytopes_roundtrip(run_node, evaluator):
    outputs = {'awp': WrenchPolytope, 'fwp': WrenchPolytope, 'fws': WrenchPolytope,
               'leg_polytopes': LegPolytopes, 'markers': MarkerArray,
               'report': FeasibilityReport, '/diagnostics': DiagnosticArray}
    peer = run_node(outputs, '-p', 'fws_rate_hz:=0.0')
    ns = peer.now_ns()
    stance = ['lf_foot', 'rf_foot', 'rh_foot']
    peer.contacts.publish(_contacts(ns, stance))
    time.sleep(0.3)
    q = evaluator.model.standing_q + 0.02
    peer.js.publish(_joints(evaluator, ns, q))
    peer.wait_for(lambda g: all(g[k] for k in outputs), 30, 'every output')
    ref = evaluator.evaluate(RobotState(
        joint_positions=dict(zip(evaluator.model.joint_names, q.tolist())), stance=stance))
    for kind in ('awp', 'fwp', 'fws'):
        msg = peer.got[kind][0]
        assert stamp_to_ns(msg.header.stamp) == ns
        assert msg.header.frame_id == 'com_world_aligned' and list(msg.stance_feet) == stance
        P, R = polytope_from_msg(msg.polytope), getattr(ref, kind).polytope
        assert P.dimension == R.dimension == 6
        np.testing.assert_allclose(P.A, R.A, atol=1e-9)
        np.testing.assert_allclose(P.b, R.b, atol=1e-7)
    legs = peer.got['leg_polytopes'][0]
    assert [leg.foot for leg in legs.legs] == stance
    for leg in legs.legs:
        F = polytope_from_msg(leg.force_polytope)
        np.testing.assert_allclose(F.A, ref.legs[leg.foot].force_polytope.A, atol=1e-9)
        np.testing.assert_allclose(F.b, ref.legs[leg.foot].force_polytope.b, atol=1e-7)
    markers = peer.got['markers'][0].markers
    assert markers[0].action == Marker.DELETEALL
    namespaces = set()
    for m in markers[1:]:
        assert m.action == Marker.ADD and 0 <= m.type <= 11
        assert m.header.frame_id == 'com_world_aligned' and stamp_to_ns(m.header.stamp) == ns
        assert 0.0 < m.color.a <= 1.0 and m.scale.x >= 0.0 and m.scale.z > 0.0
        if m.type == Marker.TRIANGLE_LIST:
            assert len(m.points) and len(m.points) % 3 == 0
        namespaces.add(m.ns.split(' ')[0])
    assert {'force_polytope', 'friction_polytope', 'friction_pyramid', 'fwp_force_slice',
            'gravito_inertial_wrench', 'com', 'margins'} <= namespaces
    peer.wait_for(lambda g: g['/diagnostics'], 5, 'diagnostics')
    names = {s.name for s in peer.got['/diagnostics'][-1].status}
    assert names == {'awp_node: inputs', 'awp_node: evaluation'}


def _children(pid: int) -> list[int]:
    """Return the process ids of the children of ``pid`` (Linux /proc)."""
    out = []
    for task in Path(f'/proc/{pid}/task').iterdir():
        out += [int(c) for c in (task / 'children').read_text().split()]
    return out


def test_markers_keep_coming_when_the_marker_worker_dies(run_node, evaluator):
    peer = run_node({'markers': MarkerArray, '/diagnostics': DiagnosticArray})
    q = evaluator.model.standing_q

    def one_second(t0: int) -> None:      # 100 joint states 10 ms apart: 30 markers due
        for i in range(100):
            if i % 10 == 0:
                peer.contacts.publish(_contacts(t0 + i * 10**7, FEET))
                time.sleep(0.005)
            peer.js.publish(_joints(evaluator, t0 + i * 10**7, q))
            time.sleep(0.01)

    t0 = peer.now_ns()
    one_second(t0)                         # the worker starts up meanwhile (some skipped)
    peer.wait_for(lambda g: g['markers'], 30, 'markers from the worker')
    time.sleep(0.5)
    n = len(peer.got['markers'])
    one_second(t0 + 10**9)
    peer.wait_for(lambda g: len(g['markers']) >= n + 28, 30, 'markers from the worker')
    (worker,) = _children(peer.proc.pid)
    assert 'awp_ros.node.marker_worker' in Path(f'/proc/{worker}/cmdline').read_text()
    os.kill(worker, signal.SIGKILL)
    time.sleep(0.5)
    n = len(peer.got['markers'])
    one_second(t0 + 2 * 10**9)
    peer.wait_for(lambda g: len(g['markers']) >= n + 28, 30, 'markers built by the node')
    assert all(any(mk.ns.startswith('force_polytope') for mk in m.markers)
               for m in peer.got['markers'][n:])            # full marker arrays, evaluated

    def reported(g) -> bool:
        return any('marker worker process ended' in kv.value for d in g['/diagnostics']
                   for st in d.status for kv in st.values)
    peer.wait_for(reported, 10, 'the end of the worker on /diagnostics')
    assert not _children(peer.proc.pid)                      # reaped


def test_invalid_input_and_parameter_changes_are_answered(run_node, evaluator):
    peer = run_node({'report': FeasibilityReport}, '-p', 'fws_rate_hz:=0.0')
    ns = peer.now_ns()
    peer.contacts.publish(_contacts(ns, FEET))
    time.sleep(0.3)
    bad = _joints(evaluator, ns + 1, evaluator.model.standing_q)
    bad.position[0] = math.nan
    peer.js.publish(bad)
    peer.wait_for(lambda g: len(g['report']) == 1, 30, 'the invalid report')
    rep = peer.got['report'][0]
    assert rep.status == FeasibilityReport.STATUS_INVALID_INPUT
    assert 'lf_haa_joint' in rep.status_message and not rep.feasible
    client = peer.node.create_client(SetParameters, '/awp_node/set_parameters')
    assert client.wait_for_service(timeout_sec=10)

    def set_param(name, value):
        req = SetParameters.Request(parameters=[Parameter(name, value=value)
                                                .to_parameter_msg()])
        future = client.call_async(req)
        deadline = time.monotonic() + 10
        while not future.done() and time.monotonic() < deadline:
            time.sleep(0.02)
        return future.result().results[0]

    bad_mu = set_param('friction_coefficient', -0.2)
    assert not bad_mu.successful and 'friction_coefficient must be finite and > 0' \
        in bad_mu.reason
    assert set_param('friction_coefficient', 0.3).successful
    assert set_param('torque_limits.lf_kfe_joint', [-90.0, 100.0]).successful
    peer.js.publish(_joints(evaluator, ns + 2, evaluator.model.standing_q))
    peer.wait_for(lambda g: len(g['report']) == 2, 30, 'the next report')
    rep = peer.got['report'][1]
    limits = dict(evaluator.config.torque_limits, lf_kfe_joint=(-90.0, 100.0))
    ref = FeasibilityEvaluator(replace(evaluator.config, friction_coefficient=0.3,
                                       torque_limits=limits))
    expected = ref.evaluate(ref.standing_state())
    assert rep.status == FeasibilityReport.STATUS_OK
    assert rep.fwp_margin == pytest.approx(expected.fwp.margin, abs=1e-7)
    assert rep.fws_margin == pytest.approx(expected.fws.margin, abs=1e-7)


def test_another_robot_runs_from_its_params_file(run_node):
    # go2.yaml defines the robot itself; an integer mu on the command line is accepted.
    peer = run_node({'report': FeasibilityReport}, '-p', 'friction_coefficient:=1',
                    robot='go2')
    go2 = FeasibilityEvaluator('go2')
    feet = list(go2.feet)
    ns = peer.now_ns()
    peer.contacts.publish(_stamp(ContactState(names=feet, in_contact=[True] * 4), ns))
    time.sleep(0.3)
    peer.js.publish(_stamp(JointState(name=list(go2.model.joint_names),
                                      position=go2.model.standing_q.tolist()), ns))
    peer.wait_for(lambda g: g['report'], 30, 'a go2 report')
    rep = peer.got['report'][0]
    ref = go2.evaluate(go2.standing_state(friction_coefficient=1.0))
    assert rep.status == FeasibilityReport.STATUS_OK, rep.status_message
    assert list(rep.stance_feet) == feet
    assert rep.fwp_margin == pytest.approx(ref.fwp.margin, abs=1e-7)


def test_one_report_per_joint_state_at_1khz(run_node, evaluator):
    peer = run_node({'report': FeasibilityReport}, '-p', 'qos_depth:=20000')
    names = list(evaluator.model.joint_names)
    q0 = evaluator.model.standing_q
    n, rate = 2000, 1000.0
    contacts = _contacts(peer.now_ns(), FEET)
    peer.contacts.publish(contacts)
    time.sleep(0.3)
    stamps = []
    start = time.perf_counter()
    for i in range(n):
        target = start + i / rate
        while (left := target - time.perf_counter()) > 0:
            time.sleep(left - 2e-4 if left > 4e-4 else 0)
        ns = peer.now_ns()
        if i % 20 == 0:                           # 50 Hz contacts, fresh stamps
            peer.contacts.publish(_stamp(contacts, ns))
        msg = JointState(name=names, position=(q0 + 0.02 * math.sin(i / 80)).tolist())
        peer.js.publish(_stamp(msg, ns))
        stamps.append(ns)
    sent_rate = n / (time.perf_counter() - start)
    peer.wait_for(lambda g: len(g['report']) >= n, 60, f'{n} reports')
    time.sleep(0.5)                                # a duplicate would arrive by now
    got = [stamp_to_ns(m.header.stamp) for m in peer.got['report']]
    assert sent_rate > 900.0
    assert len(got) == n and sorted(got) == sorted(stamps)   # exactly one per joint state
    assert got == stamps                                      # and in order
    status = np.bincount([m.status for m in peer.got['report']], minlength=5)
    assert status[FeasibilityReport.STATUS_OK] == n, status
    print(f'\n1 kHz drive: {n} joint states at {sent_rate:.0f} Hz, {len(got)} reports, '
          f'compute p50 {1e3 * np.median([m.compute_time for m in peer.got["report"]]):.2f}'
          f' ms', file=sys.stderr)
    assert os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
