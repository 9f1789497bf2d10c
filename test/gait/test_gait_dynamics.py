r"""
The default gait is dynamically balanced except in its lurch: an independent check.

Only the generated samples (joint positions and velocities, base pose, stance, feet) and
Pinocchio are used, not the generator's own dynamics. With c the whole-body CoM
(``pin.centerOfMass``), L the angular momentum about it (``pin.computeCentroidalMomentum``
with the sampled joint velocities and the base's angular velocity from the quaternions),
world frame (z up, ground z = 0), the contacts must apply about the CoM

.. math::

    (1)\quad w = [f; \tau] = [m (\ddot c - g); \dot L], \quad
    \ddot c_i = (c_{i+1} - 2 c_i + c_{i-1}) / \Delta t^2, \quad
    \dot L_i = (L_{i+1} - L_{i-1}) / (2 \Delta t)

Two point feet p_1, p_2 can apply it iff :math:`f = f_1 + f_2` and
:math:`\tau = (p_1 - c) \times f_1 + (p_2 - c) \times f_2`; the moment about p_1,
:math:`\tau + (c - p_1) \times f = (p_2 - p_1) \times f_2`, is then orthogonal to the line
of the feet, and conversely a moment orthogonal to it gives an f_2:

.. math::

    (2)\quad M_{line} = \hat d \cdot (\tau + (c - p_1) \times f) = 0, \qquad
    \hat d = (p_2 - p_1) / \|p_2 - p_1\|

On any support the ZMP (the point of the ground about which the contact wrench has no
horizontal moment) must be in the support polygon (on two feet: on the segment, which
makes both normal forces positive):

.. math::

    (3)\quad p_x = c_x - (c_z f_x + \tau_y) / f_z, \qquad
    p_y = c_y - (c_z f_y - \tau_x) / f_z
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from rosbags.highlevel import AnyReader
from scipy.spatial import ConvexHull

from awp_ros.bags.message_types import typestore
from awp_ros.gait.bag import DEFAULT_START_NS
from awp_ros.gait.generator import generate_gait
from awp_ros.robot.config import load_config
from awp_ros.robot.model import RobotModel

DEFAULT_BAG = Path(__file__).resolve().parents[2] / 'config' / 'hyq_gait.mcap'
G = np.array([0.0, 0.0, -9.81])       # [m/s^2], Pinocchio's gravity
#: Two feet: largest moment about the line of the stance feet [N.m] (measured 0.027: the
#: samples' rounding to 1e-9 m, amplified by 1 / dt^2 in c''; the unrounded motion: 6e-4).
LINE_MOMENT_TOL_NM = 0.1
#: Two feet: smallest ZMP distance from either foot along their line [m] (measured 0.39).
LINE_END_MARGIN_M = 0.2
#: Three and four feet: smallest ZMP distance inside the support polygon [m] (measured
#: 0.060 and 0.128), outside the lurch's window.
ZMP_MARGIN_M = {3: 0.05, 4: 0.1}
#: The lurch: ZMP at least this far outside the support triangle [m] (planned and measured
#: 0.040) ...
LURCH_OUTSIDE_M = 0.035
#: ... and a moment about the triangle's edge that no contact force gives, beyond [N.m]
#: (measured 34).
LURCH_MOMENT_NM = 25.0
#: Largest tangential / normal ratio of the total contact force (measured 0.25, in the
#: lurch; mu = 0.7 in hyq.yaml).
FRICTION_RATIO_MAX = 0.35
#: IMU vs. finite differences of the sampled base motion [m/s^2], [rad/s] (rounding to
#: 1e-9 m / 1e-9 of the samples, amplified by 1 / dt^2 and 1 / dt).
SPECIFIC_FORCE_TOL = 1e-3
ANGULAR_VELOCITY_TOL = 1e-6


@pytest.fixture(scope='module')
def hyq_model():
    return RobotModel(load_config('hyq'))


@pytest.fixture(scope='module')
def default_gait(hyq_model):
    return generate_gait(hyq_model.config, model=hyq_model)


def _rotations(quat: np.ndarray) -> np.ndarray:
    """Return the (N, 3, 3) rotations world from base of ``[x, y, z, w]`` quaternions."""
    return np.array([pin.Quaternion(w, x, y, z).normalized().matrix() for x, y, z, w in quat])


def _body_rates(R: np.ndarray, dt: float) -> np.ndarray:
    """Return the angular velocities (N, 3) [rad/s], base frame, by central differences."""
    omega = np.zeros((R.shape[0], 3))
    for i in range(1, R.shape[0] - 1):
        omega[i] = pin.log3(R[i - 1].T @ R[i + 1]) / (2.0 * dt)
    return omega


@pytest.fixture(scope='module')
def truth(hyq_model, default_gait):
    """Equations 1 and 3 from the samples: i, c, f, tau, zmp (valid at samples i)."""
    pm, data = hyq_model.model, hyq_model.model.createData()
    gait = default_gait
    dt = 1.0 / gait.rate_hz
    R = _rotations(gait.base_quaternion)
    omega = _body_rates(R, dt)
    vel = np.gradient(gait.base_position, dt, axis=0)
    n = len(gait)
    com, ang = np.empty((n, 3)), np.empty((n, 3))
    for i in range(n):
        q = np.concatenate([gait.base_position[i], gait.base_quaternion[i], gait.q[i]])
        v = np.concatenate([R[i].T @ vel[i], omega[i], gait.v[i]])
        com[i] = pin.centerOfMass(pm, data, q)
        ang[i] = pin.computeCentroidalMomentum(pm, data, q, v).angular
    mass = data.mass[0]
    i = np.arange(2, n - 2)
    f = mass * ((com[i + 1] - 2.0 * com[i] + com[i - 1]) / dt ** 2 - G)
    tau = (ang[i + 1] - ang[i - 1]) / (2.0 * dt)
    c = com[i]
    zmp = np.column_stack([c[:, 0] - (c[:, 2] * f[:, 0] + tau[:, 1]) / f[:, 2],
                           c[:, 1] - (c[:, 2] * f[:, 1] - tau[:, 0]) / f[:, 2]])
    return {'i': i, 'c': c, 'f': f, 'tau': tau, 'zmp': zmp, 't': gait.t[i]}


def _line_moment(p1, p2, c, f, tau):
    """Return equation 2 [N.m] and the unit line direction."""
    d = (p2 - p1) / np.linalg.norm(p2 - p1)
    return float(d @ (tau + np.cross(c - p1, f))), d


def _lurch_window(gait, ts):
    name, t0, t1 = gait.infeasible[0]
    return name, (ts >= t0 - 1e-9) & (ts < t1 - 1e-9)


def test_gait_two_feet_wrench_is_spanned_by_the_stance_feet(default_gait, truth):
    """(a) Equation 2 at every two-foot sample; the ZMP well inside the segment."""
    gait = default_gait
    worst, worst_end, count = 0.0, np.inf, 0
    for j, i in enumerate(truth['i']):
        feet = np.flatnonzero(gait.stance[i])
        if feet.size != 2:
            continue
        p1, p2 = gait.foot_positions[i, feet]
        moment, d = _line_moment(p1, p2, truth['c'][j], truth['f'][j], truth['tau'][j])
        worst = max(worst, abs(moment))
        s = (truth['zmp'][j] - p1[:2]) @ d[:2]
        worst_end = min(worst_end, s, np.linalg.norm(p2 - p1) - s)
        count += 1
    assert count > 1000                      # the trot's two-foot phases [samples]
    assert worst < LINE_MOMENT_TOL_NM, worst
    assert worst_end > LINE_END_MARGIN_M, worst_end


def test_gait_zmp_is_inside_the_support_polygon_on_three_and_four_feet(default_gait, truth):
    """(b) The ZMP with L-dot is inside the convex hull of the stance feet, except in the lurch."""
    gait = default_gait
    _, lurch = _lurch_window(gait, truth['t'])
    worst = {3: np.inf, 4: np.inf}
    for j, i in enumerate(truth['i']):
        feet = np.flatnonzero(gait.stance[i])
        if feet.size < 3 or lurch[j]:
            continue
        hull = ConvexHull(gait.foot_positions[i, feet, :2])
        margin = -(hull.equations[:, :2] @ truth['zmp'][j] + hull.equations[:, 2]).max()
        worst[feet.size] = min(worst[feet.size], margin)
    for k, margin in worst.items():
        assert margin > ZMP_MARGIN_M[k], (k, margin)


def test_gait_lurch_pushes_the_zmp_out_of_the_support_triangle(default_gait, truth):
    """(c) In the lurch window the ZMP is beyond the triangle's edge facing the lifted foot."""
    gait = default_gait
    name, lurch = _lurch_window(gait, truth['t'])
    assert name == 'lurch' and lurch.sum() == 100          # 0.2 s at 500 Hz
    segment = next(s for s in gait.segments if s[0] == 'lurch')
    assert segment[1] < gait.infeasible[0][1] < gait.infeasible[0][2] < segment[2]
    feet = list(gait.feet)
    for j in np.flatnonzero(lurch):
        i = truth['i'][j]
        stance = [feet[k] for k in np.flatnonzero(gait.stance[i])]
        assert stance == ['rf_foot', 'lh_foot', 'rh_foot']
        rf, lh, rh = (gait.foot_positions[i, feet.index(name)]
                      for name in ('rf_foot', 'lh_foot', 'rh_foot'))
        hull = ConvexHull(np.array([rf, lh, rh])[:, :2])
        outside = (hull.equations[:, :2] @ truth['zmp'][j] + hull.equations[:, 2]).max()
        assert outside > LURCH_OUTSIDE_M, (truth['t'][j], outside)
        # The normal force of RH gives a moment about the RF-LH edge of one sign only (the
        # tangential forces of all three feet and the normal forces of RF, LH none).
        moment, d = _line_moment(rf, lh, truth['c'][j], truth['f'][j], truth['tau'][j])
        possible = np.sign(d @ np.cross(rh - rf, [0.0, 0.0, 1.0]))
        assert possible * moment < -LURCH_MOMENT_NM, (truth['t'][j], moment)


def test_gait_friction_demand_stays_well_below_mu(hyq_model, truth):
    ratio = np.linalg.norm(truth['f'][:, :2], axis=1) / truth['f'][:, 2]
    assert truth['f'][:, 2].min() > 0.5 * hyq_model.total_mass * 9.81   # feet push [N]
    assert ratio.max() < FRICTION_RATIO_MAX < load_config('hyq').friction_coefficient


def _bag_imu(path: Path) -> tuple[list, list]:
    """Return the (log time, message) lists of /imu and /joint_states (rosbags alone)."""
    out: dict = {'/imu': [], '/joint_states': []}
    with AnyReader([path], default_typestore=typestore()) as reader:
        conns = [c for c in reader.connections if c.topic in out]
        for conn, stamp, raw in reader.messages(connections=conns):
            out[conn.topic].append((stamp, reader.deserialize(raw, conn.msgtype)))
    return out['/imu'], out['/joint_states']


def _stamp(msg) -> int:
    return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


def test_gait_bag_imu_matches_the_finite_differences_of_the_base(hyq_model, default_gait):
    """(d) The committed bag's IMU (500 Hz, base link) vs. the sampled base motion."""
    gait = default_gait
    imu, joints = _bag_imu(DEFAULT_BAG)
    assert len(imu) == len(joints) == len(gait)            # one IMU per joint state
    assert [_stamp(m) for _, m in imu] == [_stamp(m) for _, m in joints]
    assert _stamp(imu[0][1]) == DEFAULT_START_NS
    frame = imu[0][1].header.frame_id
    pm = hyq_model.model
    assert frame == 'base_link' and {m.header.frame_id for _, m in imu} == {frame}
    placement = pm.frames[pm.getFrameId(frame)]
    assert placement.parentJoint == 1 and placement.placement.isIdentity()
    dt = 1.0 / gait.rate_hz
    R = _rotations(gait.base_quaternion)
    omega = _body_rates(R, dt)
    p = gait.base_position
    acc = np.zeros_like(p)
    acc[1:-1] = (p[2:] - 2.0 * p[1:-1] + p[:-2]) / dt ** 2
    force = np.einsum('nji,nj->ni', R, acc - G)             # R^T (p'' - g), base frame
    got = np.array([[m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w,
                     m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z,
                     m.linear_acceleration.x, m.linear_acceleration.y,
                     m.linear_acceleration.z] for _, m in imu])
    np.testing.assert_array_equal(got[:, :4], gait.base_quaternion)
    inner = slice(1, -1)
    np.testing.assert_allclose(got[inner, 4:7], omega[inner], atol=ANGULAR_VELOCITY_TOL)
    np.testing.assert_allclose(got[inner, 7:], force[inner], atol=SPECIFIC_FORCE_TOL)
    # The lurch throws the body: its specific force departs from standing by > 1.5 m/s^2.
    _, t0, t1 = gait.infeasible[0]
    window = (gait.t >= t0) & (gait.t < t1)
    assert np.linalg.norm(got[window, 7:9], axis=1).min() > 1.5
