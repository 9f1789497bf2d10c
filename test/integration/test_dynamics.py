"""
Dynamics acceptance: the measured wrench of an analytic whole-body motion, offline and live.

A bag of an analytic HyQ motion of this file's own (base sway +-4 cm while drifting forward,
rotation +-0.06 rad about three axes, every joint +-0.15 rad at 1.5 Hz with distinct
phases), sampled at 500 Hz: joint states (positions and velocities), a full IMU in HyQ's
own IMU frame ``trunk_imu`` (29 cm ahead of and 10 cm above the base origin, upside down:
the mounting and the lever arm matter) and the contacts. Its truth comes from
``test/estimation/motion_truth.py``: Pinocchio kinematics and central finite differences
of the CoM and of the centroidal angular momentum, never the project's estimation code;
the IMU readings are second differences of the IMU point's world position and the log of
the IMU frame's relative rotation.

- offline: ``awp_replay IN -o OUT -p use_imu=true`` (the console script, defaults
  otherwise): every report after the filters settle has the wrench within 3 % of m g in
  force and 3 N.m in moment;
- live: ``awp_node`` with ``use_imu`` fed the same bag by ``awp_replay --play``: the same
  bounds, and the reports equal to the offline ones;
- measured contact forces through the pipeline: efforts computed by inverse dynamics from
  chosen contact forces (quasi-static, and along a uniform screw with spinning joints
  where the estimation is exact, with odometry) give those forces back, slip margins equal
  to an independent distance to the friction pyramid, the torque ratios and the external
  wrench;
- the wrench reference over DDS: one ``~/reference_report`` per ``~/wrench_reference``
  message, with margins equal to those of that wrench on the AWP / FWP H-reps the node
  published for the joint state nearest in time (exact formula inside, an LP on the
  nearest point outside).
"""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path
import subprocess
import sys
import textwrap
from types import SimpleNamespace

from awp_ros_msgs.msg import ContactState
from nav_msgs.msg import Odometry
import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import linprog
from sensor_msgs.msg import Imu, JointState

from awp_ros.bags.message_types import CONTACT_STATE, IMU, JOINT_STATE, typestore
from awp_ros.bags.reader import BagMessage
from awp_ros.bags.writer import BagWriter
from awp_ros.cli import bench as bench_cli
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.geometry.margin import polytope_margin
from awp_ros.node.launcher import start_node, stop_node
from awp_ros.robot.config import find_parameters_file
from awp_ros.robot.parameters import PipelineParams
from awp_ros.ros.conversions import polytope_from_msg
from awp_ros.ros.pipeline import Pipeline
from cases import FEET, REPORT_RECORDER, stamp

BIN = Path(sys.executable).parent
REPORT = '/awp_node/report'
G = 9.81
RATE_HZ = 500.0
STEP_NS = 2_000_000
START_NS = 1_750_000_000 * 10**9
DURATION_S = 1.5
#: The filters' start transients are over by then [s] (the issue's "after they settle").
SETTLE_S = 0.3
IMU_FRAME = 'trunk_imu'
CONTACTS_EVERY = 50                  # one contacts message every 0.1 s, the first at t = 0
FORCE_TOL = 0.03                     # of m g
MOMENT_TOL = 3.0                     # [N.m]


def _motion_truth():
    """Return test/estimation/motion_truth.py as a module (it is not on this folder's path)."""
    name = 'motion_truth'
    if name not in sys.modules:
        path = Path(__file__).resolve().parents[1] / 'estimation' / f'{name}.py'
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module          # before exec: dataclasses look it up
        spec.loader.exec_module(module)
    return sys.modules[name]


@pytest.fixture(scope='module')
def evaluator() -> FeasibilityEvaluator:
    return FeasibilityEvaluator('hyq')


def _whole_body(model):
    """Return this file's analytic motion (see the module docstring)."""
    n = len(model.joint_names)
    return _motion_truth().Trajectory(
        q0=model.standing_q, freq=1.5, v0=np.array([0.25, -0.1, 0.0]),
        amp_p=np.array([0.04, 0.04, 0.04]), phase_p=np.array([0.7, 2.6, 4.1]),
        amp_r=np.array([0.06, 0.06, 0.06]), phase_r=np.array([1.3, 5.0, 0.2]),
        amp_q=np.full(n, 0.15), phase_q=0.9 + 0.53 * np.arange(n))


def _ns(t) -> int:
    return int(t.sec) * 10**9 + int(t.nanosec)


# -- the bag -----------------------------------------------------------------------------------


def _bag_messages(model, truth):
    """Yield the bag's messages (IMU, contacts, joint state per sample; log-time order)."""
    store = typestore()
    types = store.types
    time_t, header_t = types['builtin_interfaces/msg/Time'], types['std_msgs/msg/Header']
    quat_t, vec_t = types['geometry_msgs/msg/Quaternion'], types['geometry_msgs/msg/Vector3']
    js_t, cs_t, imu_t = types[JOINT_STATE], types[CONTACT_STATE], types[IMU]
    traj = truth.traj
    zeros9 = np.zeros(9)
    for k in range(int(round(DURATION_S * RATE_HZ))):
        t = k / RATE_HZ
        ns = START_NS + k * STEP_NS
        sec, nsec = divmod(ns, 10**9)
        quat, omega, force = truth.imu_reading(t)
        imu = imu_t(header=header_t(stamp=time_t(sec=sec, nanosec=nsec), frame_id=IMU_FRAME),
                    orientation=quat_t(*(float(c) for c in quat)),
                    orientation_covariance=zeros9,
                    angular_velocity=vec_t(*(float(c) for c in omega)),
                    angular_velocity_covariance=zeros9,
                    linear_acceleration=vec_t(*(float(c) for c in force)),
                    linear_acceleration_covariance=zeros9)
        yield BagMessage('/imu', IMU, ns - 2000, bytes(store.serialize_cdr(imu, IMU)))
        if k % CONTACTS_EVERY == 0:
            cs = cs_t(header=header_t(stamp=time_t(sec=sec, nanosec=nsec), frame_id=''),
                      names=list(FEET), in_contact=np.ones(4, dtype=bool),
                      normals=[], friction_coefficients=np.zeros(0))
            yield BagMessage('/contacts', CONTACT_STATE, ns - 1000,
                             bytes(store.serialize_cdr(cs, CONTACT_STATE)))
        js = js_t(header=header_t(stamp=time_t(sec=sec, nanosec=nsec), frame_id=''),
                  name=list(model.joint_names),
                  position=np.asarray(traj.joints(t), dtype=float),
                  velocity=np.asarray(traj.joint_velocities(t), dtype=float),
                  effort=np.zeros(0))
        yield BagMessage('/joint_states', JOINT_STATE, ns,
                         bytes(store.serialize_cdr(js, JOINT_STATE)))


@pytest.fixture(scope='module')
def motion_bag(evaluator, tmp_path_factory):
    """Return the bag and the truth wrench [N, N.m] of every joint-state stamp after SETTLE_S."""
    model = evaluator.model
    truth = _motion_truth().Truth(model.model, _whole_body(model), IMU_FRAME)
    path = tmp_path_factory.mktemp('dynamics') / 'whole_body.mcap'
    with BagWriter(path) as writer:
        writer.write_all(_bag_messages(model, truth))
    n = int(round(DURATION_S * RATE_HZ))
    first = int(math.ceil(SETTLE_S * RATE_HZ))
    wrench = {START_NS + k * STEP_NS: truth.wrench(k / RATE_HZ) for k in range(first, n)}
    return SimpleNamespace(path=path, joint_states=n, wrench=wrench,
                           mg=model.total_mass * G)


def _read_reports(path) -> dict:
    from rosbags.highlevel import AnyReader

    out = {}
    with AnyReader([Path(path)], default_typestore=typestore()) as reader:
        conns = [c for c in reader.connections if c.topic == REPORT]
        for conn, _, raw in reader.messages(connections=conns):
            rep = reader.deserialize(raw, conn.msgtype)
            out[_ns(rep.header.stamp)] = rep
    return out


def _wrench(rep) -> np.ndarray:
    f, t = rep.wrench.force, rep.wrench.torque
    return np.array([f.x, f.y, f.z, t.x, t.y, t.z])


def _errors(wrenches: dict, truth: dict) -> tuple[float, float]:
    """Return the largest force and moment errors [N], [N.m] over the truth's stamps."""
    df = max(np.linalg.norm(wrenches[s][:3] - w[:3]) for s, w in truth.items())
    dm = max(np.linalg.norm(wrenches[s][3:] - w[3:]) for s, w in truth.items())
    return float(df), float(dm)


@pytest.fixture(scope='module')
def offline(motion_bag, tmp_path_factory):
    """Replay the bag with the console script, defaults and use_imu; return its reports."""
    out = tmp_path_factory.mktemp('dynamics_out') / 'replayed.mcap'
    proc = subprocess.run([str(BIN / 'awp_replay'), str(motion_bag.path), '-o', str(out),
                           '-p', 'use_imu=true', '-q'], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return _read_reports(out)


# -- offline -----------------------------------------------------------------------------------


def test_offline_replay_gives_the_wrench_of_the_motion(offline, motion_bag):
    assert len(offline) == motion_bag.joint_states
    for ns in motion_bag.wrench:
        rep = offline[ns]
        assert rep.status <= rep.STATUS_WARNING, rep.status_message
        assert rep.motion == rep.MOTION_MEASURED
        assert list(rep.stance_feet) == list(FEET)
    df, dm = _errors({s: _wrench(r) for s, r in offline.items()}, motion_bag.wrench)
    print(f'offline: max |df| = {df:.2f} N ({100 * df / motion_bag.mg:.2f} % of m g), '
          f'max |dm| = {dm:.2f} N.m over {len(motion_bag.wrench)} joint states')
    assert df <= FORCE_TOL * motion_bag.mg
    assert dm <= MOMENT_TOL
    # Not trivially: the motion's dynamic part is far beyond the bounds.
    static = np.array([0.0, 0.0, motion_bag.mg, 0.0, 0.0, 0.0])
    sf, sm = _errors({s: static for s in motion_bag.wrench}, motion_bag.wrench)
    assert sf > 3.0 * FORCE_TOL * motion_bag.mg and sm > 10.0 * MOMENT_TOL


# -- live --------------------------------------------------------------------------------------


def test_live_node_fed_the_bag_gives_the_wrench_and_the_offline_reports(
        offline, motion_bag, ros_env):
    node = start_node(env=ros_env, robot=None, params_file=find_parameters_file('hyq'),
                      params={'use_imu': True})
    recorder = subprocess.Popen([sys.executable, '-c', REPORT_RECORDER,
                                 str(motion_bag.joint_states), '120'],
                                env=ros_env, stdout=subprocess.PIPE, text=True)
    log = ''
    try:
        assert recorder.stdout.readline().strip() == 'ready'
        play = subprocess.run([str(BIN / 'awp_replay'), '--play', str(motion_bag.path),
                               '--wait', '30', '-q'], env=ros_env, capture_output=True,
                              text=True, timeout=180)
        assert play.returncode == 0, play.stderr
        lines, _ = recorder.communicate(timeout=180)
    finally:
        stop_node(recorder)
        log = stop_node(node)
    rows = [json.loads(line) for line in lines.splitlines() if line.startswith('{')]
    live = {r['stamp']: r for r in rows}
    assert len(live) == motion_bag.joint_states, log[-2000:]
    for ns, r in live.items():
        ref = offline[ns]
        assert (r['status'], r['message'], r['motion'], r['stance']) == (
            ref.status, ref.status_message, ref.motion, list(ref.stance_feet)), ns
        np.testing.assert_allclose(r['wrench'], _wrench(ref), rtol=1e-9, atol=1e-9)
        assert r['fwp'] == pytest.approx(ref.fwp_margin, rel=1e-9, abs=1e-9)
        assert r['awp'] == pytest.approx(ref.awp_margin, rel=1e-9, abs=1e-9)
    df, dm = _errors({s: np.array(r['wrench']) for s, r in live.items()}, motion_bag.wrench)
    print(f'live: max |df| = {df:.2f} N, max |dm| = {dm:.2f} N.m')
    assert df <= FORCE_TOL * motion_bag.mg and dm <= MOMENT_TOL


# -- measured contact forces -------------------------------------------------------------------

#: Chosen contact forces [N], world axes: inside the mu = 0.7 pyramid, and one outside it.
FORCES = {'lf_foot': np.array([30.0, -20.0, 260.0]),
          'rf_foot': np.array([210.0, 60.0, 150.0]),      # |f_t| > 0.7 f_n: it would slip
          'rh_foot': np.array([-40.0, 55.0, 300.0])}
STANCE = ('lf_foot', 'rf_foot', 'rh_foot')


def _pyramid(mu: float, sides: int = 4) -> np.ndarray:
    """Return the unit rows a . f <= 0 of the N-sided pyramid about z (t1 = x), and -z."""
    th = 2.0 * np.pi * np.arange(sides) / sides
    rows = np.column_stack([np.cos(th), np.sin(th), np.full(sides, -mu * np.cos(np.pi / sides))])
    rows = np.vstack([rows, [0.0, 0.0, -1.0]])
    return rows / np.linalg.norm(rows, axis=1)[:, None]


def _signed_cone_distance(rows: np.ndarray, f: np.ndarray) -> float:
    """
    Return the distance of ``f`` to the boundary of {x : rows x <= 0}, negative outside.

    Outside: the nearest point lies in the relative interior of a face (the apex, an edge
    ray, a facet), so it is the closest feasible one among the projections of ``f`` onto
    the apex, every facet plane and every line where two planes meet.
    """
    slack = -rows @ f
    if np.all(slack >= 0.0):
        return float(slack.min())
    candidates = [np.zeros(3)] + [f - (a @ f) * a for a in rows]
    for i in range(len(rows)):
        for j in range(i + 1, len(rows)):
            d = np.cross(rows[i], rows[j])
            if np.linalg.norm(d) > 1e-12:
                d /= np.linalg.norm(d)
                candidates.append(max(0.0, d @ f) * d)
                candidates.append(max(0.0, -d @ f) * -d)
    feasible = [x for x in candidates if np.all(rows @ x <= 1e-9)]
    return -min(float(np.linalg.norm(f - x)) for x in feasible)


def _efforts(model, q, v, a, forces: dict) -> tuple[np.ndarray, dict, np.ndarray]:
    """
    Return the joint efforts rnea(q, v, a) - sum_k J_k^T f_k [N.m] of chosen contact forces.

    Also the feet relative to the CoM (world axes) [m] and the CoM [m]: Pinocchio's
    kinematics at the free-flyer configuration ``q`` (base anywhere: only its orientation
    matters for world-aligned relative positions).
    """
    pm, data = model.model, model.model.createData()
    tau = pin.rnea(pm, data, q, v, a).copy()
    pin.computeJointJacobians(pm, data, q)
    pin.framesForwardKinematics(pm, data, q)
    com = pin.centerOfMass(pm, data, q).copy()
    rel = {}
    for foot, f in forces.items():
        fid = pm.getFrameId(foot)
        J = pin.getFrameJacobian(pm, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3]
        tau -= J.T @ f
        rel[foot] = data.oMf[fid].translation - com
    return tau[6:], rel, com


def _check_measured(model, cycle, efforts, rel) -> None:
    """Check the report's and the leg polytopes' measured forces against the chosen ones."""
    rep = cycle.report
    assert rep.measured_forces, rep.status_message
    legs = {leg.foot: leg for leg in cycle.leg_polytopes().legs}
    assert set(legs) == set(STANCE)
    rows = _pyramid(0.7)
    limits = {j: model.model.effortLimit[model.model.joints[model.model.getJointId(j)].idx_v]
              for j in model.joint_names}
    tau = dict(zip(model.joint_names, efforts))
    slips, ratios, total = {}, {}, np.zeros(6)
    for foot, f in FORCES.items():
        leg = legs[foot]
        m = leg.measured_force
        np.testing.assert_allclose([m.x, m.y, m.z], f, atol=1e-3)
        slips[foot] = _signed_cone_distance(rows, f)
        assert leg.slip_margin == pytest.approx(slips[foot], abs=1e-3)
        joints = model.legs[foot].joints
        ratios[foot] = max(abs(tau[j]) / limits[j] for j in joints)
        assert leg.torque_ratio == pytest.approx(ratios[foot], rel=1e-6)
        total += np.concatenate([f, np.cross(rel[foot], f)])
    assert slips['rf_foot'] < 0.0 < min(slips['lf_foot'], slips['rh_foot'])
    assert rep.slip_foot == 'rf_foot'
    assert rep.slip_margin == pytest.approx(slips['rf_foot'], abs=1e-3)
    assert rep.torque_ratio == pytest.approx(max(ratios.values()), rel=1e-6)
    e = rep.external_wrench
    np.testing.assert_allclose([e.force.x, e.force.y, e.force.z, e.torque.x, e.torque.y,
                                e.torque.z], total - _wrench(rep), atol=1e-3)


def _joint_state(model, ns, q, v, tau) -> JointState:
    return stamp(JointState(name=list(model.joint_names), position=list(map(float, q)),
                            velocity=list(map(float, v)), effort=list(map(float, tau))), ns)


def _contacts(ns) -> ContactState:
    return stamp(ContactState(names=list(FEET), in_contact=[f in STANCE for f in FEET]), ns)


def test_measured_forces_quasi_static_with_joint_velocities(evaluator):
    # Defaults: no IMU, so a level base at rest; the joint velocities' Coriolis and
    # centrifugal torques are in the bias (dropping the velocities would change the forces
    # by several N at these rates).
    model = evaluator.model
    pl = Pipeline('hyq', PipelineParams(fws_rate_hz=0.0))
    rng = np.random.default_rng(5)
    qj = model.standing_q + rng.uniform(-0.1, 0.1, model.standing_q.size)
    vj = rng.choice([-1.0, 1.0], qj.size) * rng.uniform(2.0, 4.0, qj.size)
    q = np.concatenate([np.zeros(3), [0.0, 0.0, 0.0, 1.0], qj])
    v = np.concatenate([np.zeros(6), vj])
    efforts, rel, _ = _efforts(model, q, v, np.zeros(v.size), FORCES)
    pl.on_contacts(_contacts(START_NS))
    cycle = pl.on_joint_state(_joint_state(model, START_NS, qj, vj, efforts))
    assert cycle.report.status <= cycle.report.STATUS_WARNING, cycle.report.status_message
    _check_measured(model, cycle, efforts, rel)
    # Without the velocities the same efforts mean other forces: the terms matter here.
    still, _, _ = _efforts(model, q, np.zeros(v.size), np.zeros(v.size), FORCES)
    assert np.abs(still - efforts).max() > 2.0


def _imu_msg(ns, quat, omega, force) -> Imu:
    msg = stamp(Imu(), ns)
    msg.header.frame_id = IMU_FRAME
    o = msg.orientation
    o.x, o.y, o.z, o.w = (float(c) for c in quat)
    w, a = msg.angular_velocity, msg.linear_acceleration
    w.x, w.y, w.z = (float(c) for c in omega)
    a.x, a.y, a.z = (float(c) for c in force)
    return msg


def _odometry_msg(ns, quat, twist) -> Odometry:
    msg = stamp(Odometry(), ns)
    o, tw = msg.pose.pose.orientation, msg.twist.twist
    o.x, o.y, o.z, o.w = (float(c) for c in quat)
    tw.linear.x, tw.linear.y, tw.linear.z = (float(c) for c in twist[:3])
    tw.angular.x, tw.angular.y, tw.angular.z = (float(c) for c in twist[3:6])
    return msg


def test_measured_forces_and_wrench_along_a_screw_with_imu_and_odometry(evaluator):
    # A constant body twist (v and omega: the base's classical acceleration is omega x v,
    # converted to Pinocchio's spatial one with -omega x v) and joints spinning at constant
    # rates: every differentiated input is a ramp, which the filters differentiate exactly
    # from the second sample on, so the wrench and the measured forces equal the truth to
    # the finite differences' accuracy. Efforts by inverse dynamics at the true motion.
    mt = _motion_truth()
    model = evaluator.model
    qdot = np.array([1.6, -1.2, 2.0, -1.8, 1.1, -1.5, 1.9, -2.1, 1.3, -1.0, 2.2, -1.7])
    traj = mt.Trajectory(q0=model.standing_q, twist=np.array([0.9, -0.4, 0.1, 0.35, -0.3, 0.5]),
                         qdot0=qdot)
    truth = mt.Truth(model.model, traj, IMU_FRAME)
    pl = Pipeline('hyq', PipelineParams(use_imu=True, use_odometry=True, fws_rate_hz=0.0))
    pl.on_contacts(_contacts(START_NS))
    for k in range(8):
        t, ns = k / RATE_HZ, START_NS + k * STEP_NS
        q, v, a = traj.configuration(t), traj.velocity(t), traj.acceleration(t)
        pl.on_odometry(_odometry_msg(ns, q[3:7], v[:6]))
        pl.on_imu(_imu_msg(ns, *truth.imu_reading(t)))
        efforts, rel, _ = _efforts(model, q, v, a, FORCES)
        cycle = pl.on_joint_state(_joint_state(model, ns, q[7:], v[6:], efforts))
        rep = cycle.report
        assert rep.status <= rep.STATUS_WARNING, rep.status_message
        if k < 2:
            continue
        assert rep.motion == rep.MOTION_MEASURED
        np.testing.assert_allclose(_wrench(rep), truth.wrench(t), atol=2e-3)
        _check_measured(model, cycle, efforts, rel)


# -- the wrench reference over DDS -------------------------------------------------------------

_REFERENCE_PEER = textwrap.dedent("""
    import json, sys, time
    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from awp_ros_msgs.msg import ContactState, FeasibilityReport, WrenchPolytope
    from geometry_msgs.msg import WrenchStamped
    from sensor_msgs.msg import JointState

    plan = json.loads(sys.argv[1])
    rclpy.init()
    node = rclpy.create_node('awp_test_reference_peer')
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    pub_c = node.create_publisher(ContactState, '/contacts', qos)
    pub_j = node.create_publisher(JointState, '/joint_states', qos)
    pub_w = node.create_publisher(WrenchStamped, '/awp_node/wrench_reference', qos)
    got = {'report': {}, 'awp': {}, 'fwp': {}, 'reference': []}
    ns = lambda t: t.sec * 10**9 + t.nanosec
    node.create_subscription(FeasibilityReport, '/awp_node/report',
                             lambda m: got['report'].__setitem__(ns(m.header.stamp), m), qos)
    for kind in ('awp', 'fwp'):
        node.create_subscription(WrenchPolytope, '/awp_node/' + kind,
                                 lambda m, k=kind: got[k].__setitem__(ns(m.header.stamp), m),
                                 qos)
    node.create_subscription(FeasibilityReport, '/awp_node/reference_report',
                             got['reference'].append, qos)

    def spin_until(done, timeout):
        deadline = time.monotonic() + timeout
        while not done() and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.02)
        if not done():
            sys.exit('timed out: got ' + str({k: len(v) for k, v in got.items()}))

    def pause(seconds):
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.01)

    def stamped(msg, t):
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t, 10**9)
        return msg

    def evaluate(t, q, stance):
        # Contacts first, and time to arrive, then the joint state; wait for its outputs.
        pub_c.publish(stamped(ContactState(names=plan['feet'],
                                           in_contact=[f in stance for f in plan['feet']]), t))
        pause(0.05)
        pub_j.publish(stamped(JointState(name=plan['joints'], position=q), t))
        spin_until(lambda: all(t in got[k] for k in ('report', 'awp', 'fwp')), 20.0)

    spin_until(lambda: node.count_subscribers('/joint_states') > 0
               and node.count_subscribers('/awp_node/wrench_reference') > 0
               and all(node.count_publishers('/awp_node/' + k) > 0
                       for k in ('report', 'awp', 'fwp', 'reference_report')), 60.0)
    # Warm up until the node publishes the polytopes to us (it has matched our readers).
    t = plan['states'][0]['stamp'] - 10 * 10**9
    for _ in range(100):
        pub_c.publish(stamped(ContactState(names=plan['feet'], in_contact=[True] * 4), t))
        pause(0.05)
        pub_j.publish(stamped(JointState(name=plan['joints'], position=plan['states'][0]['q']),
                              t))
        deadline = time.monotonic() + 0.5
        while t not in got['fwp'] and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.02)
        if t in got['fwp'] and t in got['awp']:
            break
        t += 10**6
    for s in plan['states']:
        evaluate(s['stamp'], s['q'], s['stance'])
    out = {'reports': {}, 'polytopes': {}, 'references': []}
    for s in plan['states']:
        r = got['report'][s['stamp']]
        f, m = r.wrench.force, r.wrench.torque
        out['reports'][s['stamp']] = {'wrench': [f.x, f.y, f.z, m.x, m.y, m.z],
                                      'stance': list(r.stance_feet), 'awp': r.awp_margin,
                                      'fwp': r.fwp_margin}
        polys = {}
        for kind in ('awp', 'fwp'):
            p = got[kind][s['stamp']].polytope
            polys[kind] = {k: (list(getattr(p, k)) if k not in ('ambient_dimension',
                                                                 'dimension')
                               else int(getattr(p, k)))
                           for k in ('ambient_dimension', 'dimension', 'vertices',
                                     'halfspace_normals', 'halfspace_offsets', 'hull_origin',
                                     'hull_basis', 'equality_normals', 'equality_offsets')}
        out['polytopes'][s['stamp']] = polys
    # The references, one at a time (each answered before the next is sent).
    for ref in plan['references']:
        w = list(ref['wrench'])
        if ref.get('relative_to') is not None:
            base = out['reports'][ref['relative_to']]['wrench']
            w = [a + b for a, b in zip(base, w)]
        msg = stamped(WrenchStamped(), ref['stamp'])
        msg.header.frame_id = ref['frame_id']
        (msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z,
         msg.wrench.torque.x, msg.wrench.torque.y, msg.wrench.torque.z) = w
        count = len(got['reference'])
        pub_w.publish(msg)
        spin_until(lambda: len(got['reference']) > count, 20.0)
        r = got['reference'][-1]
        out['references'].append({
            'wrench': w, 'stamp': ns(r.header.stamp), 'frame_id': r.header.frame_id,
            'status': r.status, 'message': r.status_message,
            'awp': r.awp_margin, 'fwp': r.fwp_margin,
            'awp_in_hull': r.awp_margin_in_hull, 'fwp_in_hull': r.fwp_margin_in_hull,
            'awp_feasible': r.awp_feasible, 'fwp_feasible': r.fwp_feasible,
            'awp_normal': list(r.awp_normal), 'fwp_normal': list(r.fwp_normal)})
    pause(0.3)
    out['extra_answers'] = len(got['reference']) - len(plan['references'])
    print(json.dumps(out))
    node.destroy_node()
    rclpy.shutdown()
""")


def _check_by_definition(P, w: np.ndarray, margin: float, normal: np.ndarray) -> None:
    """
    Check a 6D polytope's signed margin of ``w`` on the definition, from the H-rep alone.

    Inside: the smallest distance to a facet plane (unit rows of a complete H-rep).
    Outside: x = w + margin * normal is in P and maximises normal . x over P (an LP):
    then w - x lies in the normal cone at x, i.e. x is the nearest point of P.
    """
    A, b = P.A, P.b
    norms = np.linalg.norm(A, axis=1)
    A, b = A / norms[:, None], b / norms
    slack = b - A @ w
    if slack.min() >= 0.0:
        assert margin == pytest.approx(slack.min(), rel=1e-9, abs=1e-6)
        return
    assert margin < 0.0
    x = w + margin * normal
    assert np.all(A @ x <= b + 1e-6 * (1.0 + np.abs(b)))
    lp = linprog(-normal, A_ub=A, b_ub=b, bounds=[(None, None)] * 6, method='highs')
    assert lp.status == 0
    assert -lp.fun == pytest.approx(normal @ x, abs=1e-6 * (1.0 + abs(normal @ x)))


def test_wrench_reference_round_trips_over_dds(evaluator, ros_env):
    model = evaluator.model
    ms = 10**6
    stances = [list(FEET), ['lf_foot', 'rf_foot', 'rh_foot'], ['lf_foot', 'rh_foot']]
    rng = np.random.default_rng(3)
    states = [{'stamp': START_NS + 50 * i * ms, 'stance': stance,
               'q': (model.standing_q + rng.uniform(-0.05, 0.05, 12)).tolist()}
              for i, stance in enumerate(stances)]
    offsets = [[0.0] * 6, [40.0, -30.0, 150.0, 5.0, -8.0, 3.0], [0.0, 0.0, 0.0, 40.0, 0.0, 0.0]]
    refs = []
    for s in states:
        for j, off in enumerate(offsets):
            refs.append({'stamp': s['stamp'] + (j + 1) * ms, 'frame_id': '', 'wrench': off,
                         'relative_to': s['stamp'], 'expect': s['stamp']})
        refs.append({'stamp': s['stamp'] - 4 * ms, 'frame_id': 'com_world_aligned',
                     'wrench': [700.0, 0.0, 851.0, 0.0, 0.0, 0.0], 'expect': s['stamp']})
    # Nearest in time: 30 ms after the first state is 20 ms before the second.
    refs.append({'stamp': states[0]['stamp'] + 30 * ms, 'frame_id': '',
                 'wrench': [0.0, 0.0, 900.0, 0.0, 0.0, 0.0], 'expect': states[1]['stamp']})
    refs.append({'stamp': states[2]['stamp'], 'frame_id': 'base_link',
                 'wrench': [0.0, 0.0, 851.0, 0.0, 0.0, 0.0], 'expect': None})
    plan = {'feet': list(FEET), 'joints': list(model.joint_names), 'states': states,
            'references': refs}
    node = start_node(env=ros_env, robot=None, params_file=find_parameters_file('hyq'))
    try:
        peer = subprocess.run([sys.executable, '-c', _REFERENCE_PEER, json.dumps(plan)],
                              env=ros_env, capture_output=True, text=True, timeout=240)
    finally:
        log = stop_node(node)
    assert peer.returncode == 0, peer.stderr[-3000:] + log[-2000:]
    out = json.loads(peer.stdout.strip().splitlines()[-1])
    assert out['extra_answers'] == 0                     # one answer per message
    assert len(out['references']) == len(refs)
    hull_tol = PipelineParams().hull_tolerance
    checked_outside = checked_inside = 0
    for ref, got in zip(refs, out['references']):
        if ref['expect'] is None:
            assert got['status'] == 2 and 'base_link' in got['message']     # INVALID_INPUT
            assert math.isnan(got['fwp'])
            continue
        key = str(ref['expect'])
        assert got['stamp'] == ref['expect'] and got['frame_id'] == 'com_world_aligned'
        assert got['status'] <= 1, got['message']
        w = np.array(got['wrench'])
        report = out['reports'][key]
        if ref.get('relative_to') is not None and not any(ref['wrench']):
            assert got['fwp'] == pytest.approx(report['fwp'], rel=1e-12, abs=1e-9)
            assert got['awp'] == pytest.approx(report['awp'], rel=1e-12, abs=1e-9)
        for kind in ('awp', 'fwp'):
            P = polytope_from_msg(SimpleNamespace(**out['polytopes'][key][kind]))
            m = polytope_margin(P, w, hull_tol=hull_tol)
            assert got[kind] == pytest.approx(m.margin, rel=1e-9, abs=1e-6), (kind, ref)
            assert got[f'{kind}_in_hull'] == pytest.approx(m.margin_in_hull, rel=1e-9,
                                                           abs=1e-6)
            assert got[f'{kind}_feasible'] == m.feasible
            if P.dimension == 6:
                _check_by_definition(P, w, got[kind], np.array(got[f'{kind}_normal']))
                checked_inside += got[kind] >= 0.0
                checked_outside += got[kind] < 0.0
    assert checked_inside >= 4 and checked_outside >= 2


# -- the benchmark key ---------------------------------------------------------------------------


def test_awp_bench_reports_the_estimation_time(capsys):
    assert bench_cli.main(['-n', '3', '--warmup', '1', '--no-fws']) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert any(line.split()[:1] == ['estimation'] for line in lines)
    summary = json.loads(lines[-1])
    assert summary['estimation_ms'] > 0.0
