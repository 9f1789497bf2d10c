"""Tests of awp_ros.evaluation.evaluator: the pipeline against hand results, LPs and Pinocchio."""

from __future__ import annotations

from dataclasses import replace
import json

import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import linprog

from awp_ros.errors import InputError
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.evaluation.result import AXES
from awp_ros.robot.config import load_config, RobotConfig
from awp_ros.robot.model import resolve_urdf
from awp_ros.robot.state import RobotState
from awp_ros.wrench.friction_polytope import friction_halfspaces, friction_polytope
from cases import G, M_BASE, M_FOOT, toy_urdf

ROBOTS = ('hyq', 'anymal_c', 'go2', 'solo12')


@pytest.fixture(scope='module')
def hyq():
    return FeasibilityEvaluator('hyq')


@pytest.fixture(scope='module')
def toy():
    cfg = RobotConfig.from_dict({'robot_name': 'toy', 'urdf': toy_urdf(),
                                 'feet': ['a_foot', 'b_foot'], 'friction_coefficient': 0.5})
    return FeasibilityEvaluator(cfg)


def toy_state(**kw):
    return RobotState(joint_positions={f'{leg}_j{i}': 0.0 for leg in 'ab' for i in (1, 2, 3)},
                      **kw)


def perturbed(ev, rng, spread=0.1, **kw):
    st = ev.standing_state(**kw)
    st.joint_positions = {n: v + rng.uniform(-spread, spread)
                          for n, v in st.joint_positions.items()}
    return st


# -- independent references -----------------------------------------------------------------


def reference_legs(ev, state):
    """Return (p (K,3), J list, bias list) from Pinocchio directly (not RobotModel)."""
    cfg = ev.config
    kind, src = resolve_urdf(cfg.urdf, cfg.base_dir)
    model = (pin.buildModelFromXML(src, pin.JointModelFreeFlyer()) if kind == 'xml'
             else pin.buildModelFromUrdf(src, pin.JointModelFreeFlyer()))
    data = model.createData()
    q = pin.neutral(model)
    q[3:7] = state.base_orientation
    for j in range(2, model.njoints):
        q[model.joints[j].idx_q] = state.joint_positions[model.names[j]]
    a = np.zeros(model.nv)
    if state.base_acceleration is not None:      # no twist: spatial = classical
        a[:6] = state.base_acceleration
    tau = pin.rnea(model, data, q, np.zeros(model.nv), a)
    com = pin.centerOfMass(model, data, q)
    pin.computeJointJacobians(model, data, q)
    pin.framesForwardKinematics(model, data, q)
    stance = cfg.feet if state.stance is None else [f for f in cfg.feet if f in state.stance]
    p, J, bias = [], [], []
    for foot in stance:
        fid = model.getFrameId(foot)
        cols = [model.joints[model.getJointId(n)].idx_v for n in ev.model.legs[foot].joints]
        Jf = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
        p.append(data.oMf[fid].translation - com)
        J.append(Jf[:, cols])
        bias.append(tau[cols])
    return np.array(p).reshape(-1, 3), J, bias


def pyramid(n, mu, sides):
    """Pyramid rows ``a . f <= 0`` plus ``-n . f <= 0``, from the common definition."""
    x = np.array([1.0, 0.0, 0.0])
    t1 = x - (x @ n) * n
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(n, t1)
    th = 2 * np.pi * np.arange(sides) / sides
    rows = np.cos(th)[:, None] * t1 + np.sin(th)[:, None] * t2 - mu * np.cos(np.pi / sides) * n
    return np.vstack([rows, -n])


def lift(p):
    return np.vstack([np.eye(3), np.array([[0, -p[2], p[1]], [p[2], 0, -p[0]],
                                           [-p[1], p[0], 0]])])


def wrench_lp(ev, state, kind, *, w=None, direction=None, line=None):
    """
    LP on the definitions over the contact forces f_1..f_K (3K variables).

    kind 'awp': torque boxes; 'fws': torque boxes and pyramids on the same forces; 'fwp':
    torque boxes on f and pyramids on a second set f' with equal total wrench.
    With ``w``: feasibility of sum L_k f_k = w (returns bool). With ``direction``: returns
    max direction . sum L_k f_k. With ``w`` and ``line`` (kind 'fws'): returns
    max t such that sum L_k f_k = w + t line.
    """
    p, J, bias = reference_legs(ev, state)
    K = len(J)
    lo = [ev.model.legs[f].tau_min for f in ev.feet if f in (state.stance or ev.feet)]
    hi = [ev.model.legs[f].tau_max for f in ev.feet if f in (state.stance or ev.feet)]
    L = np.hstack([lift(pk) for pk in p])                     # (6, 3K)
    torque_A = np.zeros((0, 3 * K))
    torque_b = np.zeros(0)
    fric_A = np.zeros((0, 3 * K))
    for k in range(K):
        nk = J[k].shape[1]
        blk = np.zeros((2 * nk, 3 * K))
        blk[:nk, 3 * k:3 * k + 3] = J[k].T
        blk[nk:, 3 * k:3 * k + 3] = -J[k].T
        torque_A = np.vstack([torque_A, blk])
        torque_b = np.concatenate([torque_b, bias[k] - lo[k], hi[k] - bias[k]])
        rows = pyramid(np.array([0.0, 0.0, 1.0]), ev.config.friction_coefficient, 4)
        blk = np.zeros((rows.shape[0], 3 * K))
        blk[:, 3 * k:3 * k + 3] = rows
        fric_A = np.vstack([fric_A, blk])
    Z = np.zeros_like
    if kind == 'awp':
        A_ub, b_ub, Aeq, n = torque_A, torque_b, L, 3 * K
    elif kind == 'fws':
        A_ub = np.vstack([torque_A, fric_A])
        b_ub = np.concatenate([torque_b, np.zeros(fric_A.shape[0])])
        Aeq, n = L, 3 * K
    else:
        A_ub = np.block([[torque_A, Z(torque_A)], [Z(fric_A), fric_A]])
        b_ub = np.concatenate([torque_b, np.zeros(fric_A.shape[0])])
        Aeq, n = np.hstack([L, -L]), 6 * K
    bounds = [(None, None)] * n
    if line is not None:
        c = np.zeros(n + 1)
        c[-1] = -1.0
        res = linprog(c, A_ub=np.hstack([A_ub, np.zeros((A_ub.shape[0], 1))]), b_ub=b_ub,
                      A_eq=np.hstack([Aeq, -line[:, None]]), b_eq=w,
                      bounds=bounds + [(None, None)], method='highs')
        assert res.status == 0
        return -res.fun
    if w is not None:
        if kind == 'fwp':
            A_eq = np.vstack([np.hstack([L, np.zeros_like(L)]), Aeq])
            b_eq = np.concatenate([w, np.zeros(6)])
        else:
            A_eq, b_eq = Aeq, w
        res = linprog(np.zeros(n), A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=b_eq,
                      bounds=bounds, method='highs')
        return res.status == 0
    c = np.concatenate([-(direction @ L), np.zeros(n - 3 * K)])
    kw = {'A_eq': Aeq, 'b_eq': np.zeros(6)} if kind == 'fwp' else {}
    res = linprog(c, A_ub=A_ub, b_ub=b_ub, bounds=bounds, method='highs', **kw)
    assert res.status == 0
    return -res.fun


# -- tests ----------------------------------------------------------------------------------


def test_toy_leg_gives_the_hand_computed_box(toy):
    r = toy.evaluate(toy_state(stance=['a_foot']))
    mass = M_BASE + 2 * M_FOOT
    com = np.array([M_FOOT, 0.0, 0.5 * M_BASE]) / mass
    np.testing.assert_allclose(r.com, com, atol=1e-12)
    np.testing.assert_allclose(r.wrench, [0, 0, mass * G, 0, 0, 0], atol=1e-9)
    leg = r.legs['a_foot']
    np.testing.assert_allclose(leg.position, -com, atol=1e-12)
    bz = 0.3 * M_FOOT * G          # the knee (J_33 = 0.3) holds the 1 kg foot mass
    box = np.array([[x, y, z] for x in (-20, 20) for y in (-50, 50)
                    for z in ((bz - 30) / 0.3, (bz + 30) / 0.3)])
    V = leg.force_polytope.vertices
    assert V.shape == (8, 3)
    assert np.all(np.min(np.linalg.norm(V[:, None] - box[None], axis=2), axis=1) < 1e-9)
    # Friction-bounded: the box ∩ |fx|, |fy| <= c fz (c = 0.5/sqrt(2)) ∩ fz >= 0. Top face
    # fz = 109.81: |fy| <= c fz = 38.8 < 50 but |fx| <= 20 binds; the planes fx = +-20 meet
    # the pyramid at fz = 20 / c = 56.6, fy = +-20. With the apex: 9 vertices.
    Q = leg.friction_polytope
    c = 0.5 / np.sqrt(2)
    fz_max = (bz + 30) / 0.3
    expected = np.array([[0, 0, 0]]
                        + [[sx * 20, sy * c * fz_max, fz_max] for sx in (-1, 1)
                           for sy in (-1, 1)]
                        + [[sx * 20, sy * 20, 20 / c] for sx in (-1, 1) for sy in (-1, 1)])
    assert Q.vertices.shape == (9, 3)
    assert np.all(np.min(np.linalg.norm(Q.vertices[:, None] - expected[None], axis=2),
                         axis=1) < 1e-9)
    assert r.awp.dimension == r.fwp.dimension == r.fws.dimension == 3


@pytest.mark.parametrize('robot', ROBOTS)
def test_shipped_robots_stand_feasibly_with_four_legs(robot):
    ev = FeasibilityEvaluator(robot)
    r = ev.evaluate(ev.standing_state())
    assert r.status == 'ok' and not r.warnings
    for s in (r.awp, r.fwp, r.fws):
        assert s.dimension == 6 and s.feasible and s.margin > 0
        assert s.affine_residual < 1e-9
    assert r.fws.margin <= r.fwp.margin + 1e-6 <= r.awp.margin + 2e-6
    np.testing.assert_allclose(r.wrench, [0, 0, r.mass * 9.81, 0, 0, 0], rtol=1e-3)


def test_stance_of_zero_to_four_legs(hyq):
    dims = []
    for K in range(5):
        r = hyq.evaluate(hyq.standing_state(stance=hyq.feet[:K]))
        assert list(r.legs) == list(hyq.feet[:K])
        dims.append([r.awp.dimension, r.fwp.dimension, r.fws.dimension])
        if K < 3:
            assert r.awp.affine_residual > 1.0 and not r.feasible
        if K == 0:
            assert r.awp.margin == 0.0
            assert r.awp.affine_residual == pytest.approx(np.linalg.norm(r.wrench))
    assert dims == [[0] * 3, [3] * 3, [5] * 3, [6] * 3, [6] * 3]


def test_vertices_respect_torque_limits_and_friction(hyq):
    rng = np.random.default_rng(3)
    for _ in range(3):
        st = perturbed(hyq, rng, spread=0.2)
        r = hyq.evaluate(st, fws=False)
        p, J, bias = reference_legs(hyq, st)
        for k, (foot, leg) in enumerate(r.legs.items()):
            info = hyq.model.legs[foot]
            np.testing.assert_allclose(leg.position, p[k], atol=1e-12)
            slack_tol = 1e-7 * np.max(info.tau_max)
            for V, name in ((leg.force_polytope.vertices, 'force'),
                            (leg.friction_polytope.vertices, 'friction')):
                tau = bias[k] - V @ J[k]                     # tau = bias - J^T f
                assert np.all(tau >= info.tau_min - slack_tol), name
                assert np.all(tau <= info.tau_max + slack_tol), name
            # Force-polytope vertices sit at torque-box corners (3 joints saturated).
            tau = bias[k] - leg.force_polytope.vertices @ J[k]
            sat = np.isclose(np.abs(tau), info.tau_max, atol=slack_tol)
            assert np.all(sat.sum(axis=1) == 3)
            rows = pyramid(leg.normal, leg.friction_coefficient, 4)
            assert np.all(leg.friction_polytope.vertices @ rows.T <= 1e-7)


def test_membership_and_margins_against_linear_programs(hyq):
    rng = np.random.default_rng(5)
    counts = [0, 0, 0, 0]            # margins <= 0, > 0; LP outside, inside
    lunge = [9.0, 0.0, 0.0, 0.0, 0.0, 0.0]       # 9 m/s^2 forward: beyond friction
    for stance, acc in ((None, None), (hyq.feet[:2], None), (None, lunge)):
        st = perturbed(hyq, rng, spread=0.1, stance=stance)
        st.base_acceleration = acc
        r = hyq.evaluate(st)
        sets = {'awp': r.awp, 'fwp': r.fwp, 'fws': r.fws}
        for name, res in sets.items():
            P = res.polytope
            # Support function at the witness normal = a . w + margin, inside or outside,
            # flat or not (a lies in the hull's direction space, so a . w = a . proj(w)).
            h = wrench_lp(hyq, st, name, direction=res.normal)
            assert h == pytest.approx(res.normal @ r.wrench + res.margin, rel=1e-7, abs=1e-6)
            counts[res.margin > 0] += 1
            # Random wrenches in the hull: H-rep membership == LP membership.
            scale = abs(res.margin) + 50.0
            for _ in range(6):
                u = P.hull_basis @ rng.normal(size=P.hull_basis.shape[1])
                x = P.hull_origin + (r.wrench - P.hull_origin) * (res.affine_residual < 1e-9)
                x = x + u / np.linalg.norm(u) * rng.uniform(0.5, 2.0) * scale
                inside = bool(np.all(P.A @ x <= P.b + 1e-7))
                border = np.min(np.abs(P.b - P.A @ x)) < 1e-5
                if not border:
                    assert inside == wrench_lp(hyq, st, name, w=x), name
                    counts[2 + inside] += 1
    assert min(counts) >= 2          # both signs of margins, both membership answers


def test_fws_directional_margins_are_exact_lps(hyq):
    st = hyq.standing_state()
    r = hyq.evaluate(st)
    for i, axis in enumerate(AXES):
        e = np.eye(6)[i]
        plus = wrench_lp(hyq, st, 'fws', w=r.wrench, line=e)
        minus = wrench_lp(hyq, st, 'fws', w=r.wrench, line=-e)
        assert r.fws.directional[axis][0] == pytest.approx(plus, rel=1e-7, abs=1e-6)
        assert r.fws.directional[axis][1] == pytest.approx(minus, rel=1e-7, abs=1e-6)


def test_nested_sets_give_ordered_margins(hyq):
    rng = np.random.default_rng(9)
    for _ in range(4):
        r = hyq.evaluate(perturbed(hyq, rng, spread=0.3))
        assert r.fws.margin <= r.fwp.margin + 1e-6
        assert r.fwp.margin <= r.awp.margin + 1e-6


def test_singular_and_near_singular_legs_warn_but_evaluate(hyq):
    st = hyq.standing_state()
    st.joint_positions['lf_kfe_joint'] = 0.0         # stretched knee: beyond its limit too
    r = hyq.evaluate(st)
    assert r.legs['lf_foot'].singular and r.status == 'warning'
    assert any("'lf_foot' is singular" in w for w in r.warnings)
    assert any("'lf_kfe_joint'" in w and 'outside its limits' in w for w in r.warnings)
    assert r.legs['lf_foot'].force_polytope.dimension == 2
    assert r.awp.dimension == 6 and np.isfinite(r.fws.margin)
    st.joint_positions['lf_kfe_joint'] = -0.01
    r = hyq.evaluate(st)
    assert r.legs['lf_foot'].near_singular and not r.legs['lf_foot'].singular
    assert any('near-singular' in w for w in r.warnings)


def test_base_acceleration_and_orientation_enter_the_wrench(toy):
    quat = pin.Quaternion(pin.rpy.rpyToMatrix(0.0, 0.0, 0.4))
    xyzw = [quat.x, quat.y, quat.z, quat.w]
    acc = np.array([1.0, -0.5, 2.0])
    r = toy.evaluate(toy_state(base_orientation=xyzw,
                               base_acceleration=list(acc) + [0.0, 0.0, 0.0]))
    world_acc = quat.toRotationMatrix() @ acc
    np.testing.assert_allclose(r.wrench[:3], r.mass * (world_acc + [0, 0, G]), atol=1e-9)
    np.testing.assert_allclose(r.wrench[3:], 0.0, atol=1e-9)
    # Spinning at constant rate about z: classical acceleration = spatial + w x v; a pure
    # spin about the base origin has zero classical acceleration of the origin.
    r = toy.evaluate(toy_state(base_twist=[0, 0, 0, 0, 0, 2.0],
                               base_acceleration=[0, 0, 0, 0, 0, 0]))
    # The CoM (not on the axis) accelerates centripetally: -omega^2 * (c_xy).
    c_xy = np.array([r.com[0], r.com[1], 0.0])
    np.testing.assert_allclose(r.wrench[:3], r.mass * (-4.0 * c_xy + [0, 0, G]), atol=1e-9)


@pytest.mark.parametrize(('change', 'match'), [
    ({'joint_positions': {'a_j1': float('nan')}}, r"joint_positions\['a_j1'\] is not finite"),
    ({'joint_positions': {'zz': 0.0}}, "unknown joints \\['zz'\\]"),
    ({'drop': 'a_j2'}, "lacks joints \\['a_j2'\\]"),
    ({'stance': ['a_foot', 'c_foot']}, "unknown feet \\['c_foot'\\]"),
    ({'stance': 'a_foot'}, 'stance must be a list'),
    ({'normals': {'a_foot': [0.0, 0.0, 0.0]}}, "normals\\['a_foot'\\] is the zero vector"),
    ({'normals': {'a_foot': [0.0, 1.0]}}, "normals\\['a_foot'\\] must be a list of 3"),
    ({'normals': {'c_foot': [0.0, 0.0, 1.0]}}, 'normals names unknown feet'),
    ({'friction_coefficient': 0.0}, 'friction_coefficient must be > 0'),
    ({'friction_coefficients': {'b_foot': -1.0}},
     r"friction_coefficients\['b_foot'\] must be > 0"),
    ({'base_orientation': [0.0, 0.0, 0.0, 0.0]}, 'zero quaternion'),
    ({'base_orientation': [0.0, 0.0, float('inf'), 1.0]}, r'base_orientation\[2\]'),
    ({'base_twist': [0.0] * 5}, 'base_twist must be a list of 6'),
    ({'joint_velocities': {'a_j1': 1.0}}, 'joint_velocities lacks joints'),
    ({'joint_positions': {'a_j1': '0.1'}}, r"joint_positions\['a_j1'\] must be a number"),
])
def test_bad_input_raises_input_error_naming_it(toy, change, match):
    st = toy_state()
    change = dict(change)
    if 'drop' in change:
        del st.joint_positions[change.pop('drop')]
    if 'joint_positions' in change:
        st.joint_positions.update(change.pop('joint_positions'))
    for key, value in change.items():
        setattr(st, key, value)
    with pytest.raises(InputError, match=match):
        toy.evaluate(st)


def test_non_unit_normals_and_quaternions_are_normalised_with_a_warning(toy):
    r = toy.evaluate(toy_state(normals={'a_foot': [0.0, 0.0, 2.0]},
                               base_orientation=[0.0, 0.0, 0.0, 2.0]))
    np.testing.assert_allclose(r.legs['a_foot'].normal, [0, 0, 1])
    assert r.status == 'warning' and len(r.warnings) == 2
    ref = toy.evaluate(toy_state())
    assert r.fws.margin == pytest.approx(ref.fws.margin)


def test_per_foot_contacts_change_only_their_leg(toy):
    tilted = np.array([0.3, 0.0, 1.0]) / np.linalg.norm([0.3, 0.0, 1.0])
    r = toy.evaluate(toy_state(normals={'b_foot': tilted.tolist()},
                               friction_coefficients={'b_foot': 0.9}))
    ref = toy.evaluate(toy_state())
    np.testing.assert_allclose(r.legs['a_foot'].friction_polytope.vertices,
                               ref.legs['a_foot'].friction_polytope.vertices)
    assert r.legs['b_foot'].friction_coefficient == 0.9
    assert r.legs['a_foot'].friction_coefficient == 0.5
    np.testing.assert_allclose(r.legs['b_foot'].normal, tilted)


def test_result_dict_is_strict_json_with_the_documented_keys(hyq):
    r = hyq.evaluate(hyq.standing_state(stance=hyq.feet[:2]))
    d = json.loads(json.dumps(r.to_dict(), allow_nan=False))
    for key in ('mass', 'com', 'wrench', 'legs', 'awp', 'fwp', 'fws', 'status', 'warnings',
                'timings_ms', 'feasible', 'stance'):
        assert key in d
    leg = d['legs'][hyq.feet[0]]
    assert len(leg['position']) == 3 and len(leg['force_polytope']['vertices']) == 8
    assert leg['singular'] is False and 'vertices' in leg['friction_polytope']
    for name in ('awp', 'fwp', 'fws'):
        s = d[name]
        assert len(s['normal']) == 6 and s['dimension'] == 5
        assert all(len(row) == 7 for row in s['halfspaces'])
        assert len(s['hull_basis']) == 5 and s['feasible'] is False
    assert set(d['fws']['directional']) == set(AXES)
    assert d['timings_ms']['total'] > 0
    d = r.to_dict(halfspaces=False)
    assert 'halfspaces' not in d['awp']


def test_add_fws_matches_evaluate_with_fws(hyq):
    st = hyq.standing_state()
    a = hyq.evaluate(st)
    b = hyq.evaluate(st, fws=False)
    assert b.fws is None and 'fws' not in b.timings_ms and b.feasible == b.fwp.feasible
    per_cycle = dict(b.timings_ms)
    hyq.add_fws(b)
    assert b.fws.margin == pytest.approx(a.fws.margin)
    for axis in AXES:
        assert b.fws.directional[axis] == pytest.approx(a.fws.directional[axis])
    assert {'fws', 'fws_directional', 'fws_margin'} <= set(b.timings_ms)
    # 'total' is the per-cycle evaluation: its stages and glue, never the FWS stages.
    assert b.timings_ms['total'] == per_cycle['total']
    stages = ('validate', 'model', 'force_polytopes', 'friction_polytopes', 'awp', 'cwc_fwp',
              'margins')
    assert set(per_cycle) == set(stages) | {'total'}
    assert sum(per_cycle[s] for s in stages) == pytest.approx(per_cycle['total'], rel=1e-9)


def test_evaluator_accepts_a_config_name_or_object():
    ev = FeasibilityEvaluator(load_config('solo12'))
    assert ev.config.robot_name == 'solo12' and ev.feet[0] == 'FL_FOOT'


def test_legs_with_four_joints_use_the_exact_set_and_minkowski_sum():
    # A 4th joint (axis z) at the 3rd one, 0.3 m from the foot: column z x (-0.3 x) = -0.3 y,
    # so |0.3 f_y| <= 5 N.m cuts the box |f_y| <= 50 N down to 16.7 N.
    urdf = toy_urdf()
    for leg in 'ab':
        urdf = urdf.replace(
            f'<joint name="{leg}_fj" type="fixed"><parent link="{leg}_l3"/>',
            f'<link name="{leg}_l4"/><joint name="{leg}_j4" type="revolute">'
            f'<parent link="{leg}_l3"/><child link="{leg}_l4"/><axis xyz="0 0 1"/>'
            '<limit effort="5" lower="-3" upper="3" velocity="10"/></joint>'
            f'<joint name="{leg}_fj" type="fixed"><parent link="{leg}_l4"/>')
    cfg = RobotConfig.from_dict({'robot_name': 'toy4', 'urdf': urdf,
                                 'feet': ['a_foot', 'b_foot'], 'friction_coefficient': 0.5})
    ev = FeasibilityEvaluator(cfg)
    assert ev.model.legs['a_foot'].joints == ('a_j1', 'a_j2', 'a_j3', 'a_j4')
    st = RobotState({f'{leg}_j{i}': 0.0 for leg in 'ab' for i in (1, 2, 3, 4)})
    r = ev.evaluate(st)
    assert 'candidates' in r.awp.polytope.meta           # not the zonotope fast path
    p, J, bias = reference_legs(ev, st)
    for k, leg in enumerate(r.legs.values()):
        F = leg.force_polytope
        assert F.dimension == 3 and 'generators' not in F.meta
        tau = bias[k] - F.vertices @ J[k]
        assert np.all(np.abs(tau) <= np.array([10, 20, 30, 5]) + 1e-7)
        np.testing.assert_allclose(np.max(np.abs(F.vertices), axis=0)[1], 5 / 0.3)
    for name in ('awp', 'fwp', 'fws'):
        res = getattr(r, name)
        assert res.dimension == 5
        h = wrench_lp(ev, st, name, direction=res.normal)
        assert h == pytest.approx(res.normal @ r.wrench + res.margin, rel=1e-7, abs=1e-6)


def test_legs_that_cannot_push_are_warned_and_friction_polytopes_come_on_use(hyq):
    # HyQ standing: every leg has a vertex inside its pyramid, so the cycle computes no
    # friction-bounded polytope; asked for, they equal the direct computation.
    r = hyq.evaluate(hyq.standing_state(), fws=False)
    assert not [w for w in r.warnings if 'cannot push' in w]
    assert all(callable(leg.friction) for leg in r.legs.values())
    for leg in r.legs.values():
        ref = friction_polytope(leg.force_polytope, leg.normal, leg.friction_coefficient,
                                hyq.config.pyramid_sides)
        assert leg.friction_polytope.dimension == ref.dimension == 3
        assert not callable(leg.friction)
        np.testing.assert_allclose(np.sort(leg.friction_polytope.vertices, axis=0),
                                   np.sort(ref.vertices, axis=0), atol=1e-9)
    # Torque limits of 0.5 N.m cannot hold the legs' own weight within friction: an LP on
    # the definition finds no force, and every leg is named in a warning.
    weak = replace(hyq.config, torque_limits={n: (-0.5, 0.5) for n in hyq.model.joint_names})
    ev = FeasibilityEvaluator(weak)
    r = ev.evaluate(ev.standing_state(), fws=False)
    for foot, leg in r.legs.items():
        F = leg.force_polytope
        rows = friction_halfspaces(leg.normal, leg.friction_coefficient, 4)
        lp = linprog(np.zeros(3), A_ub=np.vstack([F.A, rows]),
                     b_ub=np.concatenate([F.b, np.zeros(rows.shape[0])]),
                     bounds=[(None, None)] * 3, method='highs')
        assert lp.status == 2 and leg.friction_polytope.is_empty
        assert any(f'leg {foot!r} cannot push' in w for w in r.warnings)
