"""
awp_node's query service ``~/evaluate`` over real DDS (the node and its worker as processes).

Reports are checked against ``awp_eval`` (its ``main`` in this process, on the JSON document
of the same state), margins of given wrenches against the returned H-representations
(``polytope_margin`` on ``polytope_from_msg``, and membership from A, b, C, d alone), and bad
requests against their reasons, the node answering its joint states afterwards.
"""

from __future__ import annotations

from contextlib import redirect_stdout
from dataclasses import replace
import io
import json
import math
import os
from pathlib import Path
import signal
import time

from awp_ros_msgs.msg import ContactState, FeasibilityReport
from awp_ros_msgs.srv import Evaluate
from geometry_msgs.msg import Vector3, Wrench
import numpy as np
import pytest
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, JointState

from awp_ros.cli.eval import main as awp_eval
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.geometry.margin import polytope_margin
from awp_ros.node.launcher import start_node, stop_node
from awp_ros.robot.config import find_parameters_file
from awp_ros.robot.model import resolve_urdf
from awp_ros.robot.state import RobotState
from awp_ros.ros.conversions import polytope_from_msg, stamp_to_ns
from awp_ros.soak.probe import wait_until
from cases import DdsPeer, stamp

FEET = ['lf_foot', 'rf_foot', 'lh_foot', 'rh_foot']
QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                 reliability=ReliabilityPolicy.RELIABLE)
T0 = 1_700_000_000 * 10**9
FEASIBILITY_TOL = 1e-6


@pytest.fixture(scope='module')
def evaluator():
    return FeasibilityEvaluator('hyq')


class Client(DdsPeer):
    """The test's DDS participant: an ~/evaluate client, joint-state input, report output."""

    def __init__(self, env: dict) -> None:
        super().__init__(env, 'awp_evaluate_test')
        self.client = self.node.create_client(Evaluate, 'awp_node/evaluate')
        self.js = self.node.create_publisher(JointState, 'joint_states', QOS)
        self.contacts = self.node.create_publisher(ContactState, 'contacts', QOS)
        self.reports: list[FeasibilityReport] = []
        self.node.create_subscription(FeasibilityReport, 'awp_node/report',
                                      self.keep(self.reports), QOS)
        self.start()

    def call(self, request: Evaluate.Request, timeout_s: float = 120.0,
             attempts: int = 3) -> Evaluate.Response:
        """
        Call ~/evaluate; resend after ``timeout_s / attempts`` without an answer.

        DDS matches a service's request and response endpoints separately: a request sent
        right after ``wait_for_service`` can be answered before the server has matched this
        client's response reader, and that response is lost (seen once in a full CI run).
        Every request here is idempotent, so the first answer to any copy is taken.
        """
        futures = []
        for attempt in range(attempts):
            futures.append(self.client.call_async(request))
            try:
                wait_until(lambda: any(f.done() for f in futures), timeout_s / attempts,
                           'the ~/evaluate response')
                break
            except TimeoutError:
                if attempt == attempts - 1:
                    raise
        return next(f for f in futures if f.done()).result()


@pytest.fixture
def client(ros_env):
    """Start awp_node (hull_tolerance 0: the evaluator's default, as awp_eval uses it)."""
    proc = start_node(env=ros_env, robot=None, params_file=find_parameters_file('hyq'),
                      params={'hull_tolerance': 0.0})
    peer = Client(ros_env)
    try:
        assert peer.client.wait_for_service(timeout_sec=60.0), stop_node(proc)
        yield peer
    finally:
        peer.close()
        log = stop_node(proc)
    assert 'Traceback' not in log, log
    assert 'awp_node/evaluate ready' in log, log


def _random_states(evaluator, rng, n: int) -> list[dict]:
    """Return n random states around standing: awp_eval documents (stance 0-4 feet)."""
    names = list(evaluator.model.joint_names)
    q0 = evaluator.model.standing_q
    docs = []
    for i in range(n):
        stance = sorted(rng.choice(FEET, size=i % 5, replace=False).tolist(), key=FEET.index)
        doc = {'robot': 'hyq', 'stance': stance,
               'joint_positions': dict(zip(names, (q0 + rng.uniform(-0.1, 0.1, q0.size))
                                           .tolist()))}
        if i % 3 == 1:      # per-foot friction coefficients and tilted normals
            doc['friction_coefficients'] = {f: float(rng.uniform(0.3, 1.0)) for f in FEET}
            tilt = rng.normal(size=(4, 3)) * [0.2, 0.2, 0.0] + [0.0, 0.0, 1.0]
            doc['normals'] = {f: (t / np.linalg.norm(t)).tolist() for f, t in zip(FEET, tilt)}
        docs.append(doc)
    return docs


def _messages(doc: dict, ns: int) -> tuple[JointState, ContactState]:
    names = list(doc['joint_positions'])
    js = stamp(JointState(name=names, position=[doc['joint_positions'][n] for n in names]), ns)
    contacts = ContactState(names=FEET, in_contact=[f in doc['stance'] for f in FEET])
    if 'friction_coefficients' in doc:
        contacts.friction_coefficients = [doc['friction_coefficients'][f] for f in FEET]
        contacts.normals = [Vector3(x=n[0], y=n[1], z=n[2])
                            for n in (doc['normals'][f] for f in FEET)]
    return js, stamp(contacts, ns)


def _awp_eval(doc: dict, tmp_path) -> dict:
    path = tmp_path / 'state.json'
    path.write_text(json.dumps(doc))
    out = io.StringIO()
    with redirect_stdout(out):
        assert awp_eval([str(path)]) == 0
    return json.loads(out.getvalue())


def _close(a, b) -> bool:
    return (a is None and not math.isfinite(b)) or b == pytest.approx(a, rel=1e-9, abs=1e-7)


def test_reports_of_100_states_equal_awp_eval(client, evaluator, tmp_path):
    docs = _random_states(evaluator, np.random.default_rng(7), 100)
    msgs = [_messages(doc, T0 + i) for i, doc in enumerate(docs)]
    response = client.call(Evaluate.Request(joint_states=[js for js, _ in msgs],
                                            contacts=[c for _, c in msgs]))
    assert len(response.reports) == 100 and not response.fwp and not response.fws
    for i, (doc, rep) in enumerate(zip(docs, response.reports)):
        ref = _awp_eval(doc, tmp_path)
        where = f'state {i}, stance {doc["stance"]}'
        assert rep.status in (FeasibilityReport.STATUS_OK, FeasibilityReport.STATUS_WARNING), \
            rep.status_message
        assert stamp_to_ns(rep.header.stamp) == T0 + i == stamp_to_ns(rep.fws_stamp)
        assert rep.header.frame_id == 'com_world_aligned'
        assert list(rep.stance_feet) == ref['stance'], where
        assert rep.mass == pytest.approx(ref['mass'], rel=1e-12)
        np.testing.assert_allclose([rep.com.x, rep.com.y, rep.com.z], ref['com'], atol=1e-12)
        w = rep.wrench
        np.testing.assert_allclose([w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y,
                                    w.torque.z], ref['wrench'], atol=1e-9)
        for name in ('awp', 'fwp', 'fws'):
            got, want = (lambda f: getattr(rep, f'{name}_{f}')), ref[name]
            for field in ('margin', 'margin_in_hull', 'affine_residual'):
                assert _close(want[field], got(field)), (where, name, field, got(field), want)
            np.testing.assert_allclose(got('normal'), want['normal'], atol=1e-7)
            assert got('dimension') == max(want['dimension'], 0), where
            assert got('feasible') == want['feasible'], where
        for axis, plus, minus in zip(('fx', 'fy', 'fz', 'mx', 'my', 'mz'),
                                     rep.fws_directional_plus, rep.fws_directional_minus):
            d = (ref['fws_directional_per_cycle'] or ref['fws']['directional'])[axis]
            assert _close(d['plus'], plus) and _close(d['minus'], minus), (where, axis)
        assert rep.feasible == ref['feasible'], where
        assert rep.compute_time > 0.0


def _rows(values, n: int = 6) -> np.ndarray:
    return np.array(values, dtype=float).reshape(-1, n)


def test_margins_of_given_wrenches_are_those_of_the_returned_h_reps(client, evaluator):
    rng = np.random.default_rng(11)
    docs = _random_states(evaluator, rng, 20)
    msgs = [_messages(doc, T0 + i) for i, doc in enumerate(docs)]
    # First the sets and gravito-inertial wrenches; then random wrenches around these, half
    # of them put on the sets' affine hulls (flat for 0-2 stance legs).
    request = Evaluate.Request(joint_states=[js for js, _ in msgs],
                               contacts=[c for _, c in msgs], include_polytopes=True)
    plain = client.call(request)
    W = np.array([[r.wrench.force.x, r.wrench.force.y, r.wrench.force.z, r.wrench.torque.x,
                   r.wrench.torque.y, r.wrench.torque.z] for r in plain.reports])
    W += rng.normal(size=(20, 6)) * [150, 150, 150, 40, 40, 40]
    for i in range(0, 20, 2):
        P = plain.fwp[i].polytope
        C, d = _rows(P.equality_normals), np.array(P.equality_offsets)
        W[i] -= C.T @ (C @ W[i] - d)
    request.wrenches = [Wrench() for _ in range(20)]
    for w, msg in zip(W, request.wrenches):
        (msg.force.x, msg.force.y, msg.force.z, msg.torque.x, msg.torque.y,
         msg.torque.z) = w.tolist()
    response = client.call(request)
    assert len(response.fwp) == len(response.fws) == 20
    inside = {'fwp': 0, 'fws': 0}
    for i, (w, rep) in enumerate(zip(W, response.reports)):
        assert rep.status in (FeasibilityReport.STATUS_OK, FeasibilityReport.STATUS_WARNING), \
            rep.status_message
        g = rep.wrench
        np.testing.assert_array_equal([g.force.x, g.force.y, g.force.z, g.torque.x,
                                       g.torque.y, g.torque.z], w)
        for kind in ('fwp', 'fws'):
            msg = getattr(response, kind)[i]
            assert stamp_to_ns(msg.header.stamp) == T0 + i
            assert list(msg.stance_feet) == list(rep.stance_feet)
            P = msg.polytope
            m = polytope_margin(polytope_from_msg(P), w, feasibility_tol=FEASIBILITY_TOL)
            margin = getattr(rep, f'{kind}_margin')
            assert margin == pytest.approx(m.margin, rel=1e-9, abs=1e-9), (i, kind)
            assert getattr(rep, f'{kind}_feasible') == m.feasible
            # Membership from the message's A, b, C, d alone.
            A, b = _rows(P.halfspace_normals), np.array(P.halfspace_offsets)
            C, d = _rows(P.equality_normals), np.array(P.equality_offsets)
            assert C.shape == (6 - P.dimension, 6) and A.shape[0] == b.size
            slack = b - A @ w if b.size else np.array([math.inf])
            member = bool(np.all(slack >= -FEASIBILITY_TOL)
                          and np.all(np.abs(C @ w - d) <= FEASIBILITY_TOL))
            assert getattr(rep, f'{kind}_feasible') == member, (i, kind, margin)
            if member and P.dimension == 6:      # inside: the nearest facet's slack
                assert margin == pytest.approx(float(np.min(slack)), rel=1e-9)
            inside[kind] += member
            assert (margin < -FEASIBILITY_TOL) == (not member)
        assert rep.feasible == (rep.fwp_feasible and rep.fws_feasible)
    assert 0 < inside['fws'] <= inside['fwp'] < 20, inside     # both sides were checked


def _publish_and_wait(client, evaluator, ns: int) -> FeasibilityReport:
    client.contacts.publish(stamp(ContactState(names=FEET, in_contact=[True] * 4), ns))
    time.sleep(0.2)                  # another topic: let the contacts arrive first
    js = JointState(name=list(evaluator.model.joint_names),
                    position=evaluator.model.standing_q.tolist())
    client.js.publish(stamp(js, ns))

    def answered() -> bool:
        with client.lock:
            return any(stamp_to_ns(r.header.stamp) == ns for r in client.reports)
    wait_until(answered, 30.0, 'the report of a live joint state')
    with client.lock:
        return next(r for r in client.reports if stamp_to_ns(r.header.stamp) == ns)


def test_bad_requests_get_reasons_and_the_node_keeps_answering(client, evaluator):
    wait_until(lambda: client.js.get_subscription_count() > 0, 30.0, 'the node to subscribe')
    docs = _random_states(evaluator, np.random.default_rng(3), 3)
    msgs = [_messages(doc, T0 + i) for i, doc in enumerate(docs)]
    joints = [js for js, _ in msgs]
    # Lengths that do not fit: every report says why, nothing is evaluated.
    response = client.call(Evaluate.Request(joint_states=joints,
                                            contacts=[c for _, c in msgs][:2],
                                            wrenches=[Wrench()] * 2, include_polytopes=True))
    assert [r.status for r in response.reports] == [FeasibilityReport.STATUS_INVALID_INPUT] * 3
    for r in response.reports:
        assert 'contacts has 2 entries for 3 joint states' in r.status_message
        assert 'wrenches has 2 entries' in r.status_message
        assert math.isnan(r.fwp_margin) and not r.feasible
    assert [p.polytope.dimension for p in response.fwp + response.fws] == [-1] * 6
    # One bad state among good ones: an unknown joint, positions missing, a NaN wrench.
    unknown = JointState(name=list(joints[0].name) + ['arm_joint'],
                         position=list(joints[0].position) + [0.0])
    short = JointState(name=list(joints[1].name), position=list(joints[1].position)[:-1])
    nan_wrench = Wrench()
    nan_wrench.force.z = math.nan
    cases = [(unknown, Wrench(), "unknown joints ['arm_joint']"),
             (short, Wrench(), '12 names but 11 positions'),
             (joints[2], nan_wrench, 'wrench must be 6 finite numbers'),
             (joints[2], Wrench(), None)]
    response = client.call(Evaluate.Request(joint_states=[c[0] for c in cases],
                                            contacts=[msgs[2][1]],
                                            wrenches=[c[1] for c in cases],
                                            include_polytopes=True))
    for (_, _, reason), r, fwp in zip(cases, response.reports, response.fwp):
        if reason is None:
            assert r.status in (FeasibilityReport.STATUS_OK, FeasibilityReport.STATUS_WARNING)
            assert fwp.polytope.dimension >= 0 and math.isfinite(r.fwp_margin)
        else:
            assert r.status == FeasibilityReport.STATUS_INVALID_INPUT
            assert reason in r.status_message, r.status_message
            assert fwp.polytope.dimension == -1
    # No joint state at all: an empty answer. The live stream and the service go on.
    assert not client.call(Evaluate.Request()).reports
    live = _publish_and_wait(client, evaluator, T0 + 10**9)
    assert live.status == FeasibilityReport.STATUS_OK and live.feasible, live.status_message
    standing = JointState(name=list(evaluator.model.joint_names),
                          position=evaluator.model.standing_q.tolist())
    again = client.call(Evaluate.Request(joint_states=[standing])).reports[0]
    assert list(again.stance_feet) == FEET                   # no contacts: every foot down
    for name in ('awp', 'fwp', 'fws'):
        assert getattr(again, f'{name}_margin') == pytest.approx(
            getattr(live, f'{name}_margin'), rel=1e-12)


def _evaluate_workers(pid: int) -> list[int]:
    """Return the children of ``pid`` (Linux /proc) that are ~/evaluate workers."""
    out = []
    for task in Path(f'/proc/{pid}/task').iterdir():
        for child in (task / 'children').read_text().split():
            try:
                cmdline = Path(f'/proc/{child}/cmdline').read_text()
            except FileNotFoundError:
                continue
            if 'awp_ros.node.evaluate_service' in cmdline:
                out.append(int(child))
    return out


def test_a_worker_that_dies_is_restarted_and_answers_again(ros_env, evaluator):
    proc = start_node(env=ros_env, robot=None, params_file=find_parameters_file('hyq'))
    peer = Client(ros_env)
    try:
        assert peer.client.wait_for_service(timeout_sec=60.0)
        standing = JointState(name=list(evaluator.model.joint_names),
                              position=evaluator.model.standing_q.tolist())
        before = peer.call(Evaluate.Request(joint_states=[standing])).reports[0]
        (worker,) = _evaluate_workers(proc.pid)
        os.kill(worker, signal.SIGKILL)
        wait_until(lambda: Path(proc.log_path).read_text().count('evaluate ready') == 2, 60.0,
                   'the new worker to serve')
        assert _evaluate_workers(proc.pid) not in ([], [worker])
        for attempt in range(3):      # a request sent before the new server matched is lost
            future = peer.client.call_async(Evaluate.Request(joint_states=[standing]))
            try:
                wait_until(future.done, 20.0, 'the answer of the new worker')
                break
            except TimeoutError:
                if attempt == 2:
                    raise
        after = future.result().reports[0]
        assert after.fwp_margin == before.fwp_margin and after.status == before.status
        assert proc.poll() is None
    finally:
        peer.close()
        log = stop_node(proc)
    assert 'its worker ended (exit -9); restarting it (1/3)' in log, log
    assert 'Traceback' not in log, log


def _set(peer: Client, **values) -> None:
    client = peer.node.create_client(SetParameters, 'awp_node/set_parameters')
    assert client.wait_for_service(timeout_sec=30.0)
    future = client.call_async(SetParameters.Request(parameters=[
        Parameter(name, value=value).to_parameter_msg() for name, value in values.items()]))
    wait_until(future.done, 30.0, 'set_parameters')
    for result in future.result().results:
        assert result.successful, result.reason


def test_queries_use_the_model_and_parameters_in_force(ros_env, evaluator, tmp_path):
    # No model at startup (a truncated robot_description): every report says why.
    kind, where = resolve_urdf(evaluator.config.urdf)
    urdf = Path(where).read_text() if kind == 'file' else where
    bad = tmp_path / 'bad.yaml'
    bad.write_text('/**:\n  ros__parameters:\n    robot_description: '
                   + json.dumps(urdf[:len(urdf) // 2]) + '\n')
    proc = start_node(env=ros_env, robot='hyq', ros_args=('--params-file', str(bad)))
    peer = Client(ros_env)
    docs = [_random_states(evaluator, np.random.default_rng(5), 10)[i] for i in (4, 9)]
    msgs = [_messages(doc, T0 + i) for i, doc in enumerate(docs)]
    request = Evaluate.Request(joint_states=[js for js, _ in msgs], contacts=[c for _, c in msgs])
    knees = [f'{leg}_kfe_joint' for leg in ('lf', 'rf', 'lh', 'rh')]
    weak = FeasibilityEvaluator(replace(evaluator.config, torque_limits={
        **evaluator.config.torque_limits, **{j: (-60.0, 60.0) for j in knees}}))
    try:
        assert peer.client.wait_for_service(timeout_sec=60.0)
        for rep in peer.call(request).reports:
            assert rep.status == FeasibilityReport.STATUS_ERROR
            assert 'no robot model' in rep.status_message
            assert 'robot_description' in rep.status_message
        # The corrected model, then weaker knees (60 N.m): the next query uses them.
        _set(peer, robot_description=urdf)
        for doc, rep in zip(docs, peer.call(request).reports):
            assert rep.fws_margin == pytest.approx(_awp_eval(doc, tmp_path)['fws']['margin'],
                                                   rel=1e-9)
        # (torque_limits.* are declared with the first joint state the new model answers)
        wait_until(lambda: peer.js.get_subscription_count() > 0, 30.0, 'the node to subscribe')
        _publish_and_wait(peer, evaluator, T0 + 10**9)
        _set(peer, **{f'torque_limits.{j}': 60.0 for j in knees})
        for doc, rep in zip(docs, peer.call(request).reports):
            state = RobotState(joint_positions=doc['joint_positions'], stance=doc['stance'],
                               friction_coefficients=doc.get('friction_coefficients', {}),
                               normals=doc.get('normals', {}))
            want = weak.evaluate(state)
            assert rep.fws_margin == pytest.approx(want.fws.margin, rel=1e-9)
            assert rep.fws_margin < _awp_eval(doc, tmp_path)['fws']['margin'] - 10.0
    finally:
        peer.close()
        log = stop_node(proc)
    assert 'Traceback' not in log, log


def test_an_imu_reading_gives_the_base_orientation(client, evaluator, tmp_path):
    # The IMU frame '' is the root link: the base orientation is the IMU's (awp_eval's
    # base_orientation); the default motion is quasi-static, so its rates do not enter.
    docs = _random_states(evaluator, np.random.default_rng(9), 5)[1:]     # 1-4 feet
    rng = np.random.default_rng(10)
    imus = []
    for doc in docs:
        axis = rng.normal(size=3)
        half = 0.5 * rng.uniform(0.05, 0.25) * axis / np.linalg.norm(axis)     # 3-14 deg
        q = np.r_[np.sin(np.linalg.norm(half)) * half / np.linalg.norm(half),
                  np.cos(np.linalg.norm(half))]
        doc['base_orientation'] = q.tolist()
        imu = Imu()
        imu.orientation.x, imu.orientation.y, imu.orientation.z, imu.orientation.w = q
        imu.angular_velocity.x = 0.5
        imus.append(imu)
    msgs = [_messages(doc, T0 + i) for i, doc in enumerate(docs)]
    response = client.call(Evaluate.Request(joint_states=[js for js, _ in msgs],
                                            contacts=[c for _, c in msgs], imu=imus))
    for doc, rep in zip(docs, response.reports):
        ref = _awp_eval(doc, tmp_path)
        assert rep.status <= FeasibilityReport.STATUS_WARNING, rep.status_message
        for name in ('awp', 'fwp', 'fws'):
            assert _close(ref[name]['margin'], getattr(rep, f'{name}_margin')), name
        np.testing.assert_allclose([rep.com.x, rep.com.y, rep.com.z], ref['com'], atol=1e-12)
        level = _awp_eval({k: v for k, v in doc.items() if k != 'base_orientation'}, tmp_path)
        assert not np.allclose(ref['com'], level['com'])       # the tilt did matter


def test_without_contacts_an_effort_source_takes_the_stance_from_the_efforts(ros_env,
                                                                             evaluator):
    # contact_source effort: efforts that make lf, rf and lh push 200 N up, rh nothing
    # (tau = b - J^T f, the leg equations the node inverts) give the stance lf, rf, lh.
    proc = start_node(env=ros_env, robot=None, params_file=find_parameters_file('hyq'),
                      params={'contact_source': 'effort'})
    peer = Client(ros_env)
    model = evaluator.model
    q = model.standing_q
    kin = model.kinematics(q, tuple(FEET))
    tau = np.zeros(q.size)
    for k, foot in enumerate(FEET):
        f = np.array([0.0, 0.0, 0.0 if foot == 'rh_foot' else 200.0])
        tau[model.legs[foot].v_idx - 6] = kin.bias[k] - kin.J[k].T @ f
    js = JointState(name=list(model.joint_names), position=q.tolist(), effort=tau.tolist())
    try:
        assert peer.client.wait_for_service(timeout_sec=60.0)
        no_efforts = JointState(name=list(model.joint_names), position=q.tolist())
        got, bad = peer.call(Evaluate.Request(joint_states=[js, no_efforts])).reports
        assert list(got.stance_feet) == ['lf_foot', 'rf_foot', 'lh_foot'], got.status_message
        assert bad.status == FeasibilityReport.STATUS_INVALID_INPUT
        assert 'carry no efforts' in bad.status_message
        # Contacts given in the request are used as they are.
        contacts = ContactState(names=FEET, in_contact=[True, False, False, True])
        given = peer.call(Evaluate.Request(joint_states=[js], contacts=[contacts])).reports[0]
        assert list(given.stance_feet) == ['lf_foot', 'rh_foot']
    finally:
        peer.close()
        log = stop_node(proc)
    assert 'Traceback' not in log, log
