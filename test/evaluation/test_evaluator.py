"""Tests of awp_ros.evaluation.evaluator: the pipeline against hand results, LPs and Pinocchio."""

from __future__ import annotations

from dataclasses import replace
import json
import time

import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import linprog

from awp_ros.errors import InputError
from awp_ros.evaluation.evaluator import FeasibilityEvaluator, STAGES
from awp_ros.evaluation.result import AXES
from awp_ros.robot.config import load_config, RobotConfig
from awp_ros.robot.model import resolve_urdf
from awp_ros.robot.state import RobotState
from awp_ros.wrench.friction_polytope import friction_halfspaces, friction_polytope
from cases import G, M_BASE, M_FOOT, toy_urdf, vertex_sums

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
    v, a = np.zeros(model.nv), np.zeros(model.nv)
    if state.base_twist is not None:
        v[:6] = state.base_twist
    for j in range(2, model.njoints):
        name, i = model.names[j], model.joints[j].idx_v
        v[i] = (state.joint_velocities or {}).get(name, 0.0)
        a[i] = (state.joint_accelerations or {}).get(name, 0.0)
    if state.base_acceleration is not None:      # classical (None: zero) -> spatial
        a[:6] = state.base_acceleration
    a[:3] -= np.cross(v[3:6], v[:3])
    tau = pin.rnea(model, data, q, v, a)
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


def contact_of(ev, state, foot):
    """Return the unit normal and mu of ``foot``: the state's own, else the defaults."""
    n = np.asarray(state.normals.get(foot, ev.config.contact_normal), dtype=float)
    mu = state.friction_coefficient
    mu = ev.config.friction_coefficient if mu is None else mu
    return n / np.linalg.norm(n), float(state.friction_coefficients.get(foot, mu))


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
    stance = [f for f in ev.feet if f in (state.stance or ev.feet)]
    lo = [ev.model.legs[f].tau_min for f in stance]
    hi = [ev.model.legs[f].tau_max for f in stance]
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
        normal, mu = contact_of(ev, state, stance[k])
        rows = pyramid(normal, mu, ev.config.pyramid_sides)
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
            # The point set {0}: in its hull at the point, off it by |w| (minus the distance).
            assert r.awp.margin_in_hull == 0.0
            assert r.awp.margin == pytest.approx(-np.linalg.norm(r.wrench))
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


def test_joint_and_base_velocities_enter_the_bias_torques(hyq):
    # Coriolis and centrifugal torques b(q, v) move every force polytope: its vertices are
    # the corners of the torque box through the reference bias (Pinocchio, with v).
    rng = np.random.default_rng(21)
    st = perturbed(hyq, rng, spread=0.1)
    st.joint_velocities = {n: rng.uniform(-6.0, 6.0) for n in hyq.model.joint_names}
    st.base_twist = [0.3, -0.2, 0.1, 0.8, -0.6, 1.2]
    r = hyq.evaluate(st, fws=False)
    _, J, bias = reference_legs(hyq, st)
    still = replace(st, joint_velocities=None, base_twist=None)
    _, _, bias0 = reference_legs(hyq, still)
    assert max(np.max(np.abs(b - b0)) for b, b0 in zip(bias, bias0)) > 1.0
    for k, (foot, leg) in enumerate(r.legs.items()):
        info = hyq.model.legs[foot]
        tau = bias[k] - leg.force_polytope.vertices @ J[k]
        sat = np.isclose(np.abs(tau), info.tau_max, atol=1e-7 * np.max(info.tau_max))
        assert np.all(sat.sum(axis=1) == 3), foot
    h = wrench_lp(hyq, st, 'awp', direction=r.awp.normal)
    assert h == pytest.approx(r.awp.normal @ r.wrench + r.awp.margin, rel=1e-7, abs=1e-6)


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


@pytest.mark.parametrize('K', range(5))
def test_feasible_exactly_when_the_signed_margin_is_not_below_minus_the_tolerance(hyq, K):
    """
    Check, for 0-4 stance legs, that the signed margin says the set membership of an LP.

    ``*_feasible`` is ``*_margin >= -tol`` for AWP, FWP and FWS; the margin is negative
    whenever the LP on the definition says the wrench is not in the set (off a flat set's
    affine hull included), positive only when it is.
    """
    rng = np.random.default_rng(40 + K)
    tol = hyq.feasibility_tol
    stance = hyq.feet[:K]
    st = perturbed(hyq, rng, spread=0.05, stance=stance)
    base = hyq.evaluate(st)
    seen = set()
    for trial in range(14):
        if trial == 0:
            w = base.wrench
        else:
            name = ('awp', 'fwp', 'fws')[trial % 3]
            P = getattr(base, name).polytope
            x = P.hull_origin.copy()
            if P.hull_basis.shape[1]:
                u = P.hull_basis @ rng.normal(size=P.hull_basis.shape[1])
                u /= np.linalg.norm(u)
                rate = P.A @ u
                reach = float(np.min((P.b - P.A @ x)[rate > 1e-12] / rate[rate > 1e-12]))
                x += u * rng.uniform(0.2, 1.8) * reach          # inside or outside the set
            if trial % 2:                                  # off the affine hull (if flat)
                x += rng.normal(size=6) * rng.uniform(0.0, 30.0)
            w = x
        r = hyq.evaluate(st, wrench=w)
        for name in ('awp', 'fwp', 'fws'):
            res = getattr(r, name)
            assert res.feasible == (res.margin >= -tol), (name, res)
            if abs(res.margin) < 1e-4:                     # on the boundary: no verdict
                continue
            # No stance leg: no contact force, so only the zero wrench (definition).
            member = wrench_lp(hyq, st, name, w=w) if K else bool(np.linalg.norm(w) < 1e-9)
            assert member == (res.margin > 0), (K, name, res.margin, res.affine_residual)
            assert res.margin_in_hull >= res.margin - 1e-9
            seen.add((name, member))
    # Every set was seen with wrenches inside and outside (3+ legs; flat sets: outside mostly).
    assert {('awp', False), ('fwp', False), ('fws', False)} <= seen
    if K >= 3:
        assert {('awp', True), ('fwp', True), ('fws', True)} <= seen


@pytest.mark.parametrize('K', [2, 3, 4])
def test_fws_verdict_every_cycle_from_the_feasible_region(hyq, K):
    """
    The CoM in this cycle's feasible region == the wrench in the FWS (LP on the definition).

    With three or more legs ``fws_feasible_per_cycle`` is the FWS's verdict without the FWS
    (``delta = 0`` in its slice), with two legs the one-dimensional LP of the legs' force
    distributions (``two_leg_fws_feasible``); ``feasible`` of an evaluation without the FWS
    uses it.
    """
    rng = np.random.default_rng(60 + K)
    st = perturbed(hyq, rng, spread=0.05, stance=hyq.feet[:K])
    base = hyq.evaluate(st)
    S = base.fws.polytope
    seen = set()
    for _ in range(24):
        # Around the standing wrench, inside or outside: +-400 N, +-80 N.m.
        w = base.wrench + rng.uniform(-1.0, 1.0, size=6) * [400, 400, 400, 80, 80, 80]
        if K == 2:           # onto the legs' hyperplane (the FWS's hull): both verdicts occur
            w = S.hull_origin + S.hull_basis @ (S.hull_basis.T @ (w - S.hull_origin))
        r = hyq.evaluate(st, wrench=w, fws=False)
        per_cycle = r.fws_feasible_per_cycle
        assert per_cycle is not None
        assert r.feasible == bool(per_cycle and r.fwp.feasible)
        full = hyq.evaluate(st, wrench=w)
        if abs(full.fws.margin) < 1e-3:                 # on the boundary: no verdict
            continue
        assert per_cycle == full.fws.feasible == wrench_lp(hyq, st, 'fws', w=w), full.fws.margin
        seen.add(per_cycle)
    assert seen == {True, False}


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
    # com_regions: in regions; fws_directional_lp, fws_distance: the FWS's per-cycle queries
    # (its LPs, its distance when the wrench is outside), outside total.
    assert set(per_cycle) == set(STAGES) | {'com_regions', 'total', 'fws_directional_lp',
                                            'fws_distance'}


def test_timings_are_measured_durations_within_the_call(hyq):
    # Not "the stages add up" (true by construction): each stage and 'total' is a duration
    # [ms] measured inside the call, so it is >= 0 and within the call's wall time measured
    # here; 'total' holds every stage; the FWS stages fit in the add_fws call.
    st = hyq.standing_state()
    for _ in range(3):
        t0 = time.perf_counter()
        r = hyq.evaluate(st, fws=False)
        wall = 1e3 * (time.perf_counter() - t0)
        tm = r.timings_ms
        assert all(tm[s] >= 0.0 for s in STAGES)
        assert max(tm[s] for s in STAGES) <= tm['total'] <= wall
        assert sum(tm[s] for s in STAGES) <= wall
        assert tm['model'] > 0.0 and tm['sets'] > 0.0 and tm['regions'] > 0.0
        assert 0.0 < tm['fws_directional_lp'] and tm['total'] + tm['fws_directional_lp'] <= wall
        t0 = time.perf_counter()
        hyq.add_fws(r)
        wall = 1e3 * (time.perf_counter() - t0)
        fws = [tm[k] for k in ('fws', 'fws_directional', 'fws_margin')]
        assert min(fws) >= 0.0 and sum(fws) <= wall and fws[0] > 0.0


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


# -- per-foot contacts and pyramid sides, end to end against LPs on the definitions ---------


def tilted(axis, angle):
    """Return the world z axis rotated by ``angle`` [rad] about ``axis``."""
    R = pin.AngleAxis(angle, np.asarray(axis, dtype=float) / np.linalg.norm(axis))
    return (R.toRotationMatrix() @ [0.0, 0.0, 1.0]).tolist()


def leg_lp(ev, state, k, *, direction=None, point=None, friction=True):
    """
    LP on one stance leg's definition: tau_min <= b - J^T f <= tau_max (and the pyramid).

    With ``direction``: return max direction . f; with ``point``: return membership.
    """
    p, J, bias = reference_legs(ev, state)
    foot = [f for f in ev.feet if f in (state.stance or ev.feet)][k]
    info = ev.model.legs[foot]
    A = np.vstack([J[k].T, -J[k].T])
    b = np.concatenate([bias[k] - info.tau_min, info.tau_max - bias[k]])
    if friction:
        normal, mu = contact_of(ev, state, foot)
        rows = pyramid(normal, mu, ev.config.pyramid_sides)
        A, b = np.vstack([A, rows]), np.concatenate([b, np.zeros(len(rows))])
    if point is not None:
        res = linprog(np.zeros(3), A_ub=A, b_ub=b, A_eq=np.eye(3), b_eq=point,
                      bounds=[(None, None)] * 3, method='highs')
        return res.status == 0
    res = linprog(-np.asarray(direction), A_ub=A, b_ub=b, bounds=[(None, None)] * 3,
                  method='highs')
    assert res.status == 0
    return -res.fun


def cwc_lp(ev, state, a):
    """Return max a . sum_k L_k f_k over f_k in the pyramids (0, or inf when unbounded)."""
    p, _, _ = reference_legs(ev, state)
    stance = [f for f in ev.feet if f in (state.stance or ev.feet)]
    K = len(stance)
    A = np.zeros((0, 3 * K))
    for k, foot in enumerate(stance):
        rows = pyramid(*contact_of(ev, state, foot), ev.config.pyramid_sides)
        blk = np.zeros((len(rows), 3 * K))
        blk[:, 3 * k:3 * k + 3] = rows
        A = np.vstack([A, blk])
    L = np.hstack([lift(pk) for pk in p])
    res = linprog(-(a @ L), A_ub=A, b_ub=np.zeros(len(A)), bounds=[(None, None)] * 3 * K,
                  method='highs')
    return np.inf if res.status == 3 else -res.fun


def check_sets_against_lps(ev, st, r, rng, *, n_dirs=6):
    """
    Check the friction-bounded polytopes, the CWC rows of the FWP, FWP and FWS by LPs.

    Returns the support values of each set, for the sensitivity checks of the callers.
    """
    supports = {}
    for k, leg in enumerate(r.legs.values()):
        Q = leg.friction_polytope
        assert Q.dimension == 3
        D = rng.normal(size=(n_dirs, 3))
        h = np.max(D @ Q.vertices.T, axis=1)
        ref = np.array([leg_lp(ev, st, k, direction=d) for d in D])
        np.testing.assert_allclose(h, ref, rtol=1e-7, atol=1e-6)
        supports[leg.foot] = ref
        c = Q.vertices.mean(axis=0)
        spread = np.ptp(Q.vertices, axis=0).max()
        for x in c + rng.normal(size=(8, 3)) * 0.4 * spread:
            if np.min(np.abs(Q.b - Q.A @ x)) > 1e-6 * spread:
                assert bool(np.all(Q.A @ x <= Q.b)) == leg_lp(ev, st, k, point=x)
    # Rows of the FWP taken from the CWC are valid for the cone the LP defines (a . w <= 0)
    # and support it (some lifted pyramid force reaches a . w = 0 from below).
    P = r.fwp.polytope
    rows = P.A[P.meta['source'] == 1]
    assert len(rows) > 0
    for a in rows[rng.choice(len(rows), size=min(6, len(rows)), replace=False)]:
        assert cwc_lp(ev, st, a) == pytest.approx(0.0, abs=1e-6)
    for name in ('awp', 'fwp', 'fws'):
        res = getattr(r, name)
        P = res.polytope
        D = rng.normal(size=(n_dirs, 6)) @ P.hull_basis @ P.hull_basis.T
        ref = np.array([wrench_lp(ev, st, name, direction=d) for d in D])
        # Support of the H-rep set, from its rows (LP over the set itself).
        h = []
        for d in D:
            lp = linprog(-d, A_ub=P.A, b_ub=P.b, A_eq=np.eye(6) - P.hull_basis @ P.hull_basis.T,
                         b_eq=(np.eye(6) - P.hull_basis @ P.hull_basis.T) @ P.hull_origin,
                         bounds=[(None, None)] * 6, method='highs')
            assert lp.status == 0
            h.append(-lp.fun)
        np.testing.assert_allclose(h, ref, rtol=1e-6, atol=1e-5)
        supports[name] = ref
        assert wrench_lp(ev, st, name, direction=res.normal) == pytest.approx(
            res.normal @ r.wrench + res.margin, rel=1e-7, abs=1e-6)
        scale = abs(res.margin) + 50.0
        x0 = P.hull_origin + (r.wrench - P.hull_origin) * (res.affine_residual < 1e-9)
        for _ in range(6):
            u = P.hull_basis @ rng.normal(size=P.hull_basis.shape[1])
            x = x0 + u / np.linalg.norm(u) * rng.uniform(0.5, 2.0) * scale
            if np.min(np.abs(P.b - P.A @ x)) > 1e-5:
                assert bool(np.all(P.A @ x <= P.b + 1e-7)) == wrench_lp(ev, st, name, w=x)
    return supports


CONTACTS = {
    'normals': {'lf_foot': tilted([1.0, 0.0, 0.0], 0.35),
                'rf_foot': tilted([0.0, 1.0, 0.0], -0.3),
                'lh_foot': tilted([1.0, -1.0, 0.0], 0.4)},     # rh_foot: the default
    'friction_coefficients': {'lf_foot': 0.4, 'rf_foot': 1.0, 'lh_foot': 0.55},
    'friction_coefficient': 0.8,                                # rh_foot's
}


@pytest.mark.parametrize('stance', [None, ['lf_foot', 'rf_foot', 'lh_foot']])
def test_per_foot_tilted_normals_and_mu_reach_every_set(hyq, stance):
    rng = np.random.default_rng(11)
    st = hyq.standing_state(stance=stance, **CONTACTS)
    r = hyq.evaluate(st)
    for foot, leg in r.legs.items():
        normal, mu = contact_of(hyq, st, foot)
        np.testing.assert_allclose(leg.normal, normal, atol=1e-15)
        assert leg.friction_coefficient == mu
    supports = check_sets_against_lps(hyq, st, r, np.random.default_rng(11))
    # The contacts matter: the same LPs with the default normal and mu give other supports
    # (so an evaluator ignoring the per-foot normal or mu would fail the checks above).
    plain = hyq.standing_state(stance=stance)
    rng = np.random.default_rng(11)
    for k, foot in enumerate(r.legs):
        D = rng.normal(size=(6, 3))
        default = np.array([leg_lp(hyq, plain, k, direction=d) for d in D])
        if foot != 'rh_foot':
            assert np.max(np.abs(default - supports[foot])) > 1.0, foot
        rng.normal(size=(8, 3))
    for name in ('fwp', 'fws'):
        D = rng.normal(size=(4, 6))
        assert max(abs(wrench_lp(hyq, plain, name, direction=d)
                       - wrench_lp(hyq, st, name, direction=d)) for d in D) > 1.0, name


@pytest.fixture(scope='module')
def by_sides():
    return {N: FeasibilityEvaluator(replace(load_config('hyq'), pyramid_sides=N))
            for N in (3, 4, 6, 8)}


@pytest.mark.parametrize('sides', [3, 6, 8])
def test_pyramid_sides_other_than_four_reach_every_set(by_sides, sides):
    ev = by_sides[sides]
    assert ev.config.pyramid_sides == sides
    st = ev.standing_state(**CONTACTS)
    r = ev.evaluate(st)
    supports = check_sets_against_lps(ev, st, r, np.random.default_rng(sides), n_dirs=4)
    # Sensitivity: the 4-sided pyramid gives other supports.
    four = by_sides[4].evaluate(st)
    for name in ('fwp', 'fws'):
        res = getattr(r, name)
        assert abs(getattr(four, name).margin - res.margin) > 1e-3, name
    rng = np.random.default_rng(sides)
    foot = next(iter(r.legs))
    D = rng.normal(size=(4, 3))
    h4 = np.max(D @ four.legs[foot].friction_polytope.vertices.T, axis=1)
    assert np.max(np.abs(h4 - supports[foot])) > 1.0
    # Pyramid facets with N sides: every friction-bounded vertex satisfies them, and N + 1
    # rows (N facets and n . f >= 0) are tight at the apex.
    for foot, leg in r.legs.items():
        rows = pyramid(*contact_of(ev, st, foot), sides)
        assert np.all(leg.friction_polytope.vertices @ rows.T <= 1e-7)


# -- the FWS directional margins, by LP on the vertex definition ------------------------------


def directional_lp(result, axis: int, sign: float) -> float:
    """
    Return max t with w + sign t e_axis in sum_k L_k conv(V_k) (NaN when the line misses).

    Variables: barycentric weights lam_k >= 0, 1^T lam_k = 1, per leg, and t.
    """
    legs = list(result.legs.values())
    V = [leg.friction_polytope.vertices for leg in legs]
    cols = [lift(leg.position) @ v.T for leg, v in zip(legs, V)]
    n = sum(v.shape[0] for v in V)
    e = np.zeros(6)
    e[axis] = sign
    A_eq = np.zeros((6 + len(V), n + 1))
    A_eq[:6, :n] = np.hstack(cols)
    A_eq[:6, n] = -e
    start = 0
    for k, v in enumerate(V):
        A_eq[6 + k, start:start + v.shape[0]] = 1.0
        start += v.shape[0]
    b_eq = np.concatenate([result.wrench, np.ones(len(V))])
    c = np.zeros(n + 1)
    c[-1] = -1.0
    res = linprog(c, A_eq=A_eq, b_eq=b_eq, bounds=[(0, None)] * n + [(None, None)],
                  method='highs')
    if res.status == 2:
        return np.nan
    assert res.status == 0
    return -res.fun


@pytest.mark.parametrize('case', ['standing', 'lunge', 'tilted', 'two_legs', 'three_legs'])
def test_fws_directional_margins_equal_an_lp_on_the_definition(hyq, case):
    kw = {'standing': {}, 'tilted': CONTACTS, 'two_legs': {'stance': ['lf_foot', 'rh_foot']},
          'three_legs': {'stance': ['lf_foot', 'rf_foot', 'rh_foot']},
          'lunge': {'base_acceleration': [9.0, 0.0, 0.0, 0.0, 0.0, 0.0]}}[case]
    st = hyq.standing_state(**kw)
    r = hyq.evaluate(st)
    values = []
    for i, axis in enumerate(AXES):
        plus, minus = r.fws.directional[axis]
        ref_plus, ref_minus = directional_lp(r, i, 1.0), directional_lp(r, i, -1.0)
        for got, ref in ((plus, ref_plus), (minus, ref_minus)):
            if np.isnan(ref):
                assert np.isnan(got), (axis, got)
            else:
                assert got == pytest.approx(ref, rel=1e-6, abs=1e-5), axis
                values.append(ref)
    # Not vacuous: finite values on every case, signs as the case says.
    assert values
    if case in ('standing', 'tilted', 'three_legs'):
        assert r.fws.feasible and min(values) > 0.0
    if case == 'lunge':
        assert not r.fws.feasible and min(values) < 0.0


def test_two_joint_legs_are_planar_by_design_not_singular():
    """Solo8 (example-robot-data's solo.urdf): 2-joint sagittal legs, no HAA."""
    cfg = RobotConfig.from_dict({
        'urdf': 'example-robot-data://solo_description/robots/solo.urdf',
        'feet': ['FL_FOOT', 'FR_FOOT', 'HL_FOOT', 'HR_FOOT'],
        'torque_limits': {f'{leg}_{j}': 2.7 for leg in ('FL', 'FR', 'HL', 'HR')
                          for j in ('HFE', 'KFE')}})
    ev = FeasibilityEvaluator(cfg)
    q = {'FL_HFE': 0.8, 'FL_KFE': -1.6, 'FR_HFE': 0.8, 'FR_KFE': -1.6,
         'HL_HFE': -0.8, 'HL_KFE': 1.6, 'HR_HFE': -0.8, 'HR_KFE': 1.6}
    res = ev.evaluate(RobotState(joint_positions=q))
    assert res.warnings == [] and not any(leg.singular for leg in res.legs.values())
    assert all(leg.force_polytope.dimension == 2 for leg in res.legs.values())
    # The legs push in their sagittal planes: every force has f_y = 0.
    assert all(np.max(np.abs(leg.force_polytope.vertices[:, 1])) < 1e-9
               for leg in res.legs.values())
    # The AWP (a zonotope with zero generator columns, H-rep) equals the Minkowski sum of
    # the legs' vertex sets by brute force (every sum of lifted vertices): support
    # functions in random directions, by LP over the H-rep and its affine hull.
    p = np.array([leg.position for leg in res.legs.values()])
    ref = vertex_sums(p, [leg.force_polytope.vertices for leg in res.legs.values()])
    awp = res.awp.polytope
    C, d_eq = awp.equalities
    assert awp.dimension == 5
    for d in np.random.default_rng(3).normal(size=(30, 6)):
        lp = linprog(-d, A_ub=awp.A, b_ub=awp.b, A_eq=C, b_eq=d_eq,
                     bounds=[(None, None)] * 6, method='highs')
        assert lp.status == 0
        assert -lp.fun == pytest.approx(np.max(ref @ d), rel=1e-7, abs=1e-6)
    # A stretched knee is singular within the leg's own rank, and flagged.
    res = ev.evaluate(RobotState(joint_positions=dict(q, FL_KFE=0.0)))
    assert res.legs['FL_FOOT'].singular and "leg 'FL_FOOT' is singular" in res.warnings[0]


@pytest.mark.parametrize('posture', ['standing', 'none'])
def test_warm_up_evaluates_every_stance_size_and_leaves_other_evaluators_alone(posture):
    from awp_ros.evaluation.evaluator import warm_up
    config = load_config('hyq')
    if posture == 'none':           # no standing posture: every joint at 0 rad (legs straight)
        config = replace(config, standing_posture={})
    ev = FeasibilityEvaluator('hyq')
    state = ev.standing_state(stance=list(ev.feet)[:3])
    before = ev.evaluate(state)
    assert warm_up(config) > 0.0
    after = ev.evaluate(state)
    assert after.fws.margin == before.fws.margin and after.fwp.margin == before.fwp.margin


def test_fws_margin_per_cycle_is_the_fws_margin_of_every_wrench_outside(hyq):
    """
    Three or more legs: a wrench outside the FWS gets the FWS's margin every cycle.

    Its signed margin and witness without the FWS (Wolfe's nearest point) are those of the
    H-rep's least-distance program of the same state (``evaluate`` with the FWS); inside, or
    with two legs, there is none. ``with_wrench`` (a planner's wrench) gives the same.
    """
    from awp_ros.geometry import kernels
    if not kernels.ENABLED:
        pytest.skip('the compiled kernels are off')
    rng = np.random.default_rng(12)
    feet = list(hyq.feet)
    stances = [tuple(feet), tuple(feet[:3]), tuple(feet[1:]), (feet[0], feet[1], feet[3])]
    seen = {'inside': 0, 'outside': 0}
    for i in range(8):
        state = hyq.standing_state(stance=stances[i % len(stances)])
        for name in state.joint_positions:
            state.joint_positions[name] += rng.uniform(-0.15, 0.15)
        base = hyq.evaluate(state, fws=False)
        full = hyq.evaluate(state)
        plus = full.fws.directional['fz'][0]
        push = rng.normal(size=6)
        wrenches = [full.wrench, full.wrench * [1, 1, -1, 1, 1, 1], full.wrench + 4.0 * push]
        wrenches += [full.wrench + (plus + beyond) * np.eye(6)[2] for beyond in (1e-3, 20.0)]
        for w in wrenches:
            r = hyq.evaluate(state, wrench=w)
            m, planner = r.fws_margin_per_cycle, hyq.with_wrench(base, w).fws_margin_per_cycle
            assert (m is None) == (planner is None)
            if m is not None:
                assert planner.margin == pytest.approx(m.margin, abs=1e-9)
            if r.fws.margin >= 0.0:
                assert m is None
                seen['inside'] += 1
                continue
            assert not r.warnings
            assert m.margin == pytest.approx(r.fws.margin, abs=1e-7 * (1.0 - r.fws.margin))
            np.testing.assert_allclose(m.normal, r.fws.normal, atol=1e-6)
            assert (m.feasible, m.dimension, m.affine_residual) == (False, 6, 0.0)
            assert r.timings_ms['fws_distance'] > 0.0
            seen['outside'] += 1
    assert seen['inside'] >= 8 and seen['outside'] >= 24, seen
    two = hyq.evaluate(hyq.standing_state(stance=(feet[0], feet[3])),
                       wrench=np.array([0.0, 0.0, -100.0, 0.0, 0.0, 0.0]))
    assert not two.fws.feasible and two.fws_margin_per_cycle is None
    assert two.to_dict()['fws_margin_per_cycle'] is None
    assert r.to_dict()['fws_margin_per_cycle']['margin'] == pytest.approx(m.margin)
