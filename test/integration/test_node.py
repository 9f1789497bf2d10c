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
import time

from awp_ros_msgs.msg import ContactState, FeasibilityReport, LegPolytopes, WrenchPolytope
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PolygonStamped
import numpy as np
import pytest
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from visualization_msgs.msg import Marker, MarkerArray

from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.node.launcher import start_node
from awp_ros.robot.config import find_parameters_file
from awp_ros.robot.state import RobotState
from awp_ros.ros.conversions import polytope_from_msg, stamp_to_ns
from awp_ros.runtime import children
from awp_ros.soak.probe import wait_until
from cases import DdsPeer, stamp, stop_peers

AWP_EVAL = Path(sys.executable).parent / 'awp_eval'
FEET = ['lf_foot', 'rf_foot', 'lh_foot', 'rh_foot']
QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=20000,
                 reliability=ReliabilityPolicy.RELIABLE)
DIAG_PERIOD_S = 0.05            # the node's diagnostics period: how fast inputs are confirmed


@pytest.fixture(scope='module')
def evaluator():
    return FeasibilityEvaluator('hyq')


class Peer(DdsPeer):
    """The test's side of the DDS conversation with one awp_node process."""

    def __init__(self, env: dict, outputs: dict) -> None:
        super().__init__(env, 'awp_test_peer')
        self.js = self.node.create_publisher(JointState, 'joint_states', QOS)
        self.contacts = self.node.create_publisher(ContactState, 'contacts', QOS)
        self.got: dict[str, list] = {name: [] for name in outputs}
        for name, mtype in outputs.items():
            topic = name if name.startswith('/') else f'awp_node/{name}'
            self.node.create_subscription(mtype, topic, self.keep(self.got[name]), QOS)
        self.diag: list = []
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self.keep(self.diag), QOS)
        self.sent = {'joint_states': 0, 'contacts': 0}
        self.seq: dict[str, list] = {}
        self.start()

    def subscribe_late(self, name: str, mtype) -> None:
        """Subscribe to ``~/name`` now; keep (message, publication sequence number)."""
        self.seq[name] = []

        def callback(msg, info) -> None:
            with self.lock:
                self.seq[name].append((msg, info['publication_sequence_number']))
        self.node.create_subscription(mtype, f'awp_node/{name}', callback, QOS)

    def send_contacts(self, msg: ContactState) -> None:
        self.contacts.publish(msg)
        self.sent['contacts'] += 1

    def send_js(self, msg: JointState) -> None:
        self.js.publish(msg)
        self.sent['joint_states'] += 1

    def status(self, name: str) -> dict[str, str]:
        """Return the values of the latest diagnostics status ``awp_node: <name>`` ({} if none)."""
        with self.lock:
            arrays = list(self.diag)
        for arr in reversed(arrays):
            for st in arr.status:
                if st.name == f'awp_node: {name}':
                    return {kv.key: kv.value for kv in st.values}
        return {}

    def inputs(self) -> dict[str, str]:
        """Return the values of the node's latest 'inputs' diagnostics status ({} if none)."""
        return self.status('inputs')

    def evaluation(self) -> dict[str, str]:
        """Return the values of the node's latest 'evaluation' status ({} if none)."""
        return self.status('evaluation')

    def until_outputs(self, names, send, timeout: float = 30.0) -> int:
        """
        Send joint states until the outputs ``names`` all arrived for one; return its stamp.

        ``send(k)`` (k = 0, 1, ...) publishes the k-th joint state and returns its stamp.

        Discovery is not symmetric: the node may see a subscription of ours some time after
        we see its publisher, and it publishes an output only to subscribers it sees.
        """
        deadline = time.monotonic() + timeout
        k = 0
        while time.monotonic() < deadline:
            send(k)
            k += 1
            time.sleep(0.05)
            with self.lock:
                stamps = [{_out_stamp(m) for m in self.got[name]} for name in names]
            common = set.intersection(*stamps)
            if common:
                return min(common)
        raise AssertionError(f'the outputs {list(names)} never arrived for one joint state')

    def wait_received(self, topic: str, timeout: float = 30.0) -> None:
        """
        Wait until the node has received every ``topic`` message sent so far.

        From its ``/diagnostics`` (``<topic> received (total)``, every diagnostics period):
        an input sent before another on a different topic is taken first (no sleep).
        """
        deadline = time.monotonic() + timeout
        want = self.sent[topic]
        while time.monotonic() < deadline:
            if int(self.inputs().get(f'{topic} received (total)', -1)) >= want:
                return
            time.sleep(0.01)
        raise AssertionError(f'the node did not receive {want} {topic} messages in {timeout} s;'
                             f' diagnostics {self.inputs()}')

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


@pytest.fixture
def run_node(ros_env, monkeypatch):
    """Start awp_node with extra --ros-args and return a connected Peer."""
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    started = []

    def start(outputs: dict, *args: str, robot: str = 'hyq') -> Peer:
        proc = start_node(env=ros_env, robot=None, params_file=find_parameters_file(robot),
                          ros_args=('-p', f'diagnostics_period_s:={DIAG_PERIOD_S}') + args)
        peer = Peer(ros_env, outputs)
        peer.proc = proc
        started.append((proc, peer))
        peer.wait_matched()
        return peer

    yield start
    stop_peers(started)


def _contacts(ns: int, stance) -> ContactState:
    return stamp(ContactState(names=FEET, in_contact=[f in stance for f in FEET]), ns)


def _joints(evaluator, ns: int, q: np.ndarray) -> JointState:
    return stamp(JointState(name=list(evaluator.model.joint_names), position=q.tolist()), ns)


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
        peer.send_contacts(_contacts(ns, stance))
        peer.wait_received('contacts')       # contacts first: another topic, no ordering
        peer.send_js(_joints(evaluator, ns + 1, q))
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
    t0 = peer.now_ns()
    stance = ['lf_foot', 'rf_foot', 'rh_foot']
    peer.send_contacts(_contacts(t0, stance))
    peer.wait_received('contacts')
    q = evaluator.model.standing_q + 0.02

    def send(k: int) -> int:                  # 50 ms apart: markers due for each
        t = t0 + k * 5 * 10**7
        peer.send_contacts(_contacts(t - 1000, stance))
        peer.send_js(_joints(evaluator, t, q))
        return t
    ns = peer.until_outputs(['awp', 'fwp', 'fws', 'leg_polytopes', 'markers'], send)
    peer.wait_for(lambda g: all(g[k] for k in outputs), 30, 'every output')
    ref = evaluator.evaluate(RobotState(
        joint_positions=dict(zip(evaluator.model.joint_names, q.tolist())), stance=stance))
    of = {kind: next(m for m in peer.got[kind] if _out_stamp(m) == ns)
          for kind in ('awp', 'fwp', 'fws', 'leg_polytopes', 'markers')}
    for kind in ('awp', 'fwp', 'fws'):
        msg = of[kind]
        assert stamp_to_ns(msg.header.stamp) == ns
        assert msg.header.frame_id == 'com_world_aligned' and list(msg.stance_feet) == stance
        P, R = polytope_from_msg(msg.polytope), getattr(ref, kind).polytope
        assert P.dimension == R.dimension == 6
        np.testing.assert_allclose(P.A, R.A, atol=1e-9)
        np.testing.assert_allclose(P.b, R.b, atol=1e-7)
    legs = of['leg_polytopes']
    assert [leg.foot for leg in legs.legs] == stance
    for leg in legs.legs:
        F = polytope_from_msg(leg.force_polytope)
        np.testing.assert_allclose(F.A, ref.legs[leg.foot].force_polytope.A, atol=1e-9)
        np.testing.assert_allclose(F.b, ref.legs[leg.foot].force_polytope.b, atol=1e-7)
    markers = of['markers'].markers
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


def _marker_workers(pid: int) -> list[int]:
    """Return the children of ``pid`` that are marker workers (other workers exist)."""
    out = []
    for child in _children(pid):
        try:
            cmdline = Path(f'/proc/{child}/cmdline').read_text()
        except FileNotFoundError:
            continue
        if 'awp_ros.node.marker_worker' in cmdline:
            out.append(child)
    return out


def due_stamps(stamps, rate_hz: float) -> list[int]:
    """
    Return the stamps at which a throttled output is due (markers), by the documented rule.

    Due at the first stamp and when a period has passed since the schedule's last due time;
    the schedule then moves on by whole periods (restarting after a gap of more than one).
    """
    period = int(round(1e9 / rate_hz))
    out, next_due = [], None
    for ns in stamps:
        if next_due is None or ns >= next_due:
            out.append(ns)
            on_grid = next_due is not None and ns < next_due + period
            next_due = next_due + period if on_grid else ns + period
    return out


def _marker_stamp(msg: MarkerArray) -> int:
    return stamp_to_ns(msg.markers[-1].header.stamp)


def _out_stamp(msg) -> int:
    """Return the stamp of an output message (a MarkerArray's: that of its markers)."""
    return _marker_stamp(msg) if isinstance(msg, MarkerArray) else stamp_to_ns(msg.header.stamp)


def _zombie_or_gone(pid: int) -> bool:
    try:
        stat = Path(f'/proc/{pid}/stat').read_text()
    except FileNotFoundError:
        return True
    return stat[stat.rindex(')') + 2] in 'ZX'


def test_markers_keep_coming_when_the_marker_worker_dies(run_node, evaluator):
    # Markers are due by stamps (30 Hz of a 10 ms stamp grid): each due one is published
    # by the worker or counted as skipped (worker busy), and, once the worker is dead,
    # built and published by the node: counts, not rates.
    peer = run_node({'markers': MarkerArray})
    q = evaluator.model.standing_q
    t0 = peer.now_ns()
    stamps: list[int] = []

    def one_second(start: int) -> list[int]:   # 100 joint states, stamps 10 ms apart
        batch = [start + i * 10**7 for i in range(100)]
        for i, ns in enumerate(batch):
            if i % 10 == 0:                    # fresh contacts (the stance never changes)
                peer.send_contacts(_contacts(ns, FEET))
            peer.send_js(_joints(evaluator, ns, q))
            time.sleep(0.01)                   # pacing: ~100 Hz of input
        stamps.extend(batch)
        return batch

    def markers_of(batch) -> list[int]:
        with peer.lock:
            got = [_marker_stamp(m) for m in peer.got['markers']]
        return [ns for ns in got if batch[0] <= ns <= batch[-1]]

    def skipped() -> int:
        return int(peer.evaluation()['markers skipped, worker busy (total)'])

    def settled(batches, baseline: int) -> None:
        """Wait until every due marker of ``batches`` was published or counted skipped."""
        peer.wait_received('joint_states')
        due = len([ns for ns in due_stamps(stamps, 30.0)
                   if any(b[0] <= ns <= b[-1] for b in batches)])
        wait_until(lambda: sum(len(markers_of(b)) for b in batches) + skipped() - baseline
                   == due, 30, f'{due} markers published or skipped')

    # Warm-up, 10 s of stamps earlier: until the node sees our subscription and the worker
    # publishes (then a gap of more than a period restarts the schedule at t0).
    warm = t0 - 10 * 10**9

    def send(k: int) -> int:
        t = warm + k * 5 * 10**7
        peer.send_contacts(_contacts(t - 1000, FEET))
        peer.send_js(_joints(evaluator, t, q))
        return t
    peer.until_outputs(['markers'], send)
    peer.send_contacts(_contacts(t0 - 10**6, FEET))
    peer.wait_received('contacts')
    peer.wait_received('joint_states')
    baseline = skipped()
    first = one_second(t0)
    second = one_second(t0 + 10**9)
    settled([first, second], baseline)
    assert markers_of(second), 'no marker from the worker'
    skipped_before = skipped()
    (worker,) = _marker_workers(peer.proc.pid)
    os.kill(worker, signal.SIGKILL)
    wait_until(lambda: _zombie_or_gone(worker), 10, 'the worker to end')
    third = one_second(t0 + 2 * 10**9)
    due = [ns for ns in due_stamps(stamps, 30.0) if third[0] <= ns <= third[-1]]
    assert len(due) == 30
    wait_until(lambda: len(markers_of(third)) >= len(due), 30, 'markers built by the node')
    peer.wait_received('joint_states')
    assert sorted(markers_of(third)) == due                  # each due one, once, none else
    assert skipped() == skipped_before
    with peer.lock:
        built = [m for m in peer.got['markers'] if _marker_stamp(m) >= third[0]]
    assert all(any(mk.ns.startswith('force_polytope') for mk in m.markers)
               for m in built)                                # full marker arrays, evaluated
    with peer.lock:
        every = [_marker_stamp(m) for m in peer.got['markers']]
    assert len(every) == len(set(every))                     # no duplicate

    def reported() -> bool:
        with peer.lock:
            arrays = list(peer.diag)
        return any('marker worker process ended' in kv.value for d in arrays
                   for st in d.status for kv in st.values)
    wait_until(reported, 10, 'the end of the worker on /diagnostics')
    assert not _marker_workers(peer.proc.pid)                # reaped


def test_outputs_are_published_only_to_subscribers(run_node, evaluator):
    # Without a subscriber the node does not publish (nor build) an output; from the first
    # subscriber on it publishes one per evaluated joint state (markers: per due stamp).
    # Observable through the publishers' sequence numbers: a late subscriber's first
    # message must be the publisher's first (1), and none may be missing after it.
    peer = run_node({'report': FeasibilityReport}, '-p', 'fws_rate_hz:=0.0',
                    '-p', 'marker_worker:=false')
    q = evaluator.model.standing_q
    ns = peer.now_ns()
    peer.send_contacts(_contacts(ns, FEET))
    peer.wait_received('contacts')
    step = 5 * 10**7                            # 50 ms: a marker is due for every one

    def send(t: int) -> None:                   # fresh contacts (or the previous ones)
        peer.send_contacts(_contacts(t - 1000, FEET))
        peer.send_js(_joints(evaluator, t, q))

    before = [ns + (i + 1) * step for i in range(5)]
    for t in before:
        send(t)
    peer.wait_for(lambda g: len(g['report']) == len(before), 30, 'the first reports')
    outputs = {'awp': WrenchPolytope, 'fwp': WrenchPolytope, 'fws': WrenchPolytope,
               'leg_polytopes': LegPolytopes, 'markers': MarkerArray,
               'feasible_region': PolygonStamped, 'support_region': PolygonStamped}
    for name, mtype in outputs.items():
        peer.subscribe_late(name, mtype)
    after: list[int] = []
    t = before[-1]
    deadline = time.monotonic() + 30
    while True:                                # until the node sees every subscription
        t += step
        send(t)
        after.append(t)
        peer.wait_for(lambda g: len(g['report']) == len(before) + len(after), 30, 'report')
        with peer.lock:
            if all(peer.seq[name] for name in outputs):
                break
        assert time.monotonic() < deadline, {k: len(v) for k, v in peer.seq.items()}
        time.sleep(0.05)
    for _ in range(5):                         # and a few more, every output subscribed
        t += step
        send(t)
        after.append(t)

    def complete() -> bool:
        with peer.lock:
            return all(peer.seq[name] and _stamp_of(name, peer.seq[name][-1][0]) == after[-1]
                       for name in outputs)
    wait_until(complete, 30, 'the outputs of the last joint state')
    with peer.lock:
        got = {name: list(v) for name, v in peer.seq.items()}
    for name in outputs:
        seqs = [s for _, s in got[name]]
        stamps = [_stamp_of(name, m) for m, _ in got[name]]
        # Nothing was published before the subscriber existed: numbering starts at 1 ...
        assert seqs == list(range(1, len(seqs) + 1)), (name, seqs[:5])
        # ... and from then on, one message per joint state, none for the earlier ones.
        assert stamps == after[after.index(stamps[0]):], name
        assert not set(stamps) & set(before), name
    reports = {stamp_to_ns(r.header.stamp): r for r in peer.got['report']}
    assert all(reports[t].status == FeasibilityReport.STATUS_OK for t in before + after)
    # The CoM regions of the standing state, in the wrench frame (z = 0: the CoM height).
    ref = evaluator.evaluate(evaluator.standing_state())
    for name in ('feasible_region', 'support_region'):
        poly = got[name][-1][0]
        assert poly.header.frame_id == 'com_world_aligned'
        pts = np.array([[p.x, p.y, p.z] for p in poly.polygon.points])
        np.testing.assert_allclose(pts[:, :2], getattr(ref, name).vertices, atol=1e-6)
        assert not pts[:, 2].any()
        assert getattr(reports[after[-1]], f'{name}_margin') == pytest.approx(
            getattr(ref, name).margin, abs=1e-9)


def _stamp_of(name: str, msg) -> int:
    return _marker_stamp(msg) if name == 'markers' else stamp_to_ns(msg.header.stamp)


def test_invalid_input_and_parameter_changes_are_answered(run_node, evaluator):
    peer = run_node({'report': FeasibilityReport}, '-p', 'fws_rate_hz:=0.0')
    ns = peer.now_ns()
    peer.send_contacts(_contacts(ns, FEET))
    peer.wait_received('contacts')
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
    peer.send_contacts(stamp(ContactState(names=feet, in_contact=[True] * 4), ns))
    peer.wait_received('contacts')
    peer.send_js(stamp(JointState(name=list(go2.model.joint_names),
                                  position=go2.model.standing_q.tolist()), ns))
    peer.wait_for(lambda g: g['report'], 30, 'a go2 report')
    rep = peer.got['report'][0]
    ref = go2.evaluate(go2.standing_state(friction_coefficient=1.0))
    assert rep.status == FeasibilityReport.STATUS_OK, rep.status_message
    assert list(rep.stance_feet) == feet
    assert rep.fwp_margin == pytest.approx(ref.fwp.margin, abs=1e-7)


def _allowed_cpus(pid: int, tid: int | None = None) -> set[int]:
    """Return the CPUs a thread (default the process's main thread) may run on, from /proc."""
    path = f'/proc/{pid}/task/{tid or pid}/status'
    line = next(x for x in open(path).read().splitlines() if x.startswith('Cpus_allowed_list'))
    cpus = set()
    for part in line.split(':')[1].strip().split(','):
        lo, _, hi = part.partition('-')
        cpus.update(range(int(lo), int(hi or lo) + 1))
    return cpus


@pytest.mark.skipif(not hasattr(os, 'sched_getaffinity'), reason='Linux CPU affinity')
def test_main_thread_cpu_pins_the_joint_state_thread_and_the_workers_take_the_others(
        run_node, evaluator):
    allowed = os.sched_getaffinity(0)
    cpu = max(allowed)
    # fws_lag_s: the FWS worker process runs beside the node (besides the marker worker).
    peer = run_node({'report': FeasibilityReport}, '-p', f'main_thread_cpu:={cpu}',
                    '-p', 'fws_lag_s:=0.02')
    ns = peer.now_ns()
    peer.send_contacts(_contacts(ns, FEET))
    peer.wait_received('contacts')
    for i in range(1, 40):
        peer.js.publish(_joints(evaluator, ns + i * 1_000_000, evaluator.model.standing_q))
    peer.wait_for(lambda g: len(g['report']) == 39, 30, '39 reports')
    assert all(m.status == FeasibilityReport.STATUS_OK for m in peer.got['report'])
    pid = peer.proc.pid
    assert _allowed_cpus(pid) == {cpu}
    # Fast DDS's threads, started before the pinning, keep every CPU.
    tids = [int(t) for t in os.listdir(f'/proc/{pid}/task') if int(t) != pid]
    assert any(_allowed_cpus(pid, t) == allowed for t in tids)
    workers = children(pid)
    assert {'awp_ros.node.fws_worker', 'awp_ros.node.marker_worker'} <= set(workers.values())
    others = allowed - {cpu} or allowed
    assert {w: _allowed_cpus(p) for p, w in workers.items()} \
        == {w: others for w in workers.values()}
    log = open(peer.proc.log_path).read()
    assert f'main thread pinned to CPU {cpu}' in log


def test_a_main_thread_cpu_it_may_not_run_on_is_reported_and_not_fatal(run_node, evaluator):
    peer = run_node({'report': FeasibilityReport}, '-p', 'main_thread_cpu:=4095')
    ns = peer.now_ns()
    peer.send_contacts(_contacts(ns, FEET))
    peer.wait_received('contacts')
    peer.js.publish(_joints(evaluator, ns + 1, evaluator.model.standing_q))
    peer.wait_for(lambda g: len(g['report']) == 1, 30, 'the report')
    assert peer.got['report'][0].status == FeasibilityReport.STATUS_OK
    assert _allowed_cpus(peer.proc.pid) == os.sched_getaffinity(0)
    wait_until(lambda: 'main_thread_cpu 4095: CPU 4095 is not one this process may run on'
               in peer.status('evaluation').get('rejected parameters', ''), 30,
               'the rejection on /diagnostics')


def test_one_report_per_joint_state_at_1khz(run_node, evaluator):
    peer = run_node({'report': FeasibilityReport}, '-p', 'qos_depth:=20000')
    names = list(evaluator.model.joint_names)
    q0 = evaluator.model.standing_q
    n, rate = 2000, 1000.0
    contacts = _contacts(peer.now_ns(), FEET)
    peer.send_contacts(contacts)
    peer.wait_received('contacts')
    stamps = []
    start = time.perf_counter()
    for i in range(n):
        target = start + i / rate
        while (left := target - time.perf_counter()) > 0:
            time.sleep(left - 2e-4 if left > 4e-4 else 0)
        ns = peer.now_ns()
        if i % 20 == 0:                           # 50 Hz contacts, fresh stamps
            peer.contacts.publish(stamp(contacts, ns))
        msg = JointState(name=names, position=(q0 + 0.02 * math.sin(i / 80)).tolist())
        peer.js.publish(stamp(msg, ns))
        stamps.append(ns)
    sent_rate = n / (time.perf_counter() - start)
    peer.wait_for(lambda g: len(g['report']) >= n, 60, f'{n} reports')
    # The node's own count of published reports: once it says n, n is all there is.
    wait_until(lambda: sum(int(v) for k, v in peer.evaluation().items()
                           if k.startswith('reports ') and k.endswith(' (total)')) >= n,
               30, 'the diagnostics of the last report')
    got = [stamp_to_ns(m.header.stamp) for m in peer.got['report']]
    assert len(got) == n and sorted(got) == sorted(stamps)   # exactly one per joint state
    assert got == stamps                                      # and in order
    status = np.bincount([m.status for m in peer.got['report']], minlength=5)
    assert status[FeasibilityReport.STATUS_OK] == n, status
    # The FWS in the loop (10 Hz by stamps) is timed in /diagnostics, period by period.
    with peer.lock:
        fws_ms = [float(kv.value) for arr in peer.diag for s in arr.status
                  if s.name == 'awp_node: evaluation' for kv in s.values
                  if kv.key == 'FWS in the loop max [ms]']
    assert sum(x > 0.1 for x in fws_ms) >= 5, fws_ms
    print(f'\n1 kHz drive: {n} joint states at {sent_rate:.0f} Hz, {len(got)} reports, '
          f'compute p50 {1e3 * np.median([m.compute_time for m in peer.got["report"]]):.2f}'
          f' ms', file=sys.stderr)
    assert os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
