"""
Tests of awp_ros.wrench.com_region: CoM regions checked against their definition.

The oracle is written here from Pinocchio directly (frame Jacobians, ``rnea`` bias torques,
CoM, mass) and scipy's ``linprog``: a CoM offset ``delta`` is feasible iff contact forces
``f_k`` exist with ``sum_k f_k = m (c'' - g)``, ``sum_k (p_k - delta) x f_k = L'``, the
friction pyramid of the config (inscribed, ``pyramid_sides`` sides, ``t1`` = world x on the
contact plane) and ``tau_min <= b_k - J_k^T f_k <= tau_max`` (feasible region, FWS), the
pyramid only (support region, CWC), or one distribution for each (FWP region). Points
``EPS`` inside the computed polygons must be feasible, points ``EPS`` outside infeasible.
"""

from __future__ import annotations

import dataclasses
from functools import lru_cache
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, HalfspaceIntersection

from awp_ros.errors import InputError
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.geometry.polytope import Polytope
from awp_ros.robot.config import load_config
from awp_ros.robot.model import resolve_urdf
from awp_ros.robot.state import RobotState
from awp_ros.wrench.com_region import com_region, com_wrench_map, ComRegion, feasible_region
from awp_ros.wrench.contact_wrench_cone import contact_wrench_cone

FEET = ('lf_foot', 'rf_foot', 'lh_foot', 'rh_foot')
EPS = 2e-3      # [m] offset of the probe points from the boundary
MIN_DEPTH = 1e-3  # [m] probes closer than this to the boundary are not judged


# -- the oracle: Pinocchio and linprog, nothing from awp_ros's wrench sets ------------------


class Oracle:
    """A robot at one posture, frozen: the quantities the LP of the definition needs."""

    def __init__(self, config, q_joints: dict[str, float], stance, mu: float) -> None:
        kind, path = resolve_urdf(config.urdf, config.base_dir)
        model = pin.buildModelFromUrdf(path, pin.JointModelFreeFlyer())
        data = model.createData()
        q = pin.neutral(model)
        q[:7] = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
        for name, value in q_joints.items():
            q[model.joints[model.getJointId(name)].idx_q] = value
        tau = pin.rnea(model, data, q, np.zeros(model.nv), np.zeros(model.nv))
        com = pin.centerOfMass(model, data, q)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        self.mass = sum(inertia.mass for inertia in model.inertias)
        self.gravity = model.gravity.linear.copy()
        self.legs = []
        for foot in stance:
            fid = model.getFrameId(foot)
            joints = config.leg_joints[foot]
            v = [model.joints[model.getJointId(j)].idx_v for j in joints]
            J = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            lo, hi = zip(*(config.torque_limits[j] for j in joints))
            self.legs.append({'p': data.oMf[fid].translation - com, 'J': J[:3, v],
                              'b': tau[v], 'lo': np.array(lo), 'hi': np.array(hi)})
        self.mu = mu
        self.sides = config.pyramid_sides

    def force(self, acc=(0.0, 0.0, 0.0)) -> np.ndarray:
        """Return m (c'' - g) [N]."""
        return self.mass * (np.asarray(acc, dtype=float) - self.gravity)

    def pyramid(self) -> np.ndarray:
        """Return the rows a with a . f <= 0 of the inscribed pyramid and of n . f >= 0."""
        n = np.array([0.0, 0.0, 1.0])
        t1 = np.array([1.0, 0.0, 0.0])
        t2 = np.cross(n, t1)
        N = self.sides
        th = 2.0 * np.pi * np.arange(N) / N
        rows = (np.cos(th)[:, None] * t1 + np.sin(th)[:, None] * t2
                - self.mu * np.cos(np.pi / N) * n)
        return np.vstack([rows, -n])

    def feasible(self, delta, force, moment, *, torque: bool, friction: bool) -> bool:
        """Return whether forces balance [force; moment] about the CoM moved by delta."""
        K = len(self.legs)
        d = np.array([delta[0], delta[1], 0.0])
        A_eq = np.zeros((6, 3 * K))
        A_ub, b_ub = [], []
        for k, leg in enumerate(self.legs):
            r = leg['p'] - d
            A_eq[:3, 3 * k:3 * k + 3] = np.eye(3)
            A_eq[3:, 3 * k:3 * k + 3] = [[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]],
                                         [-r[1], r[0], 0.0]]
            blocks = []
            if friction:
                blocks.append((self.pyramid(), np.zeros(self.sides + 1)))
            if torque:
                JT = leg['J'].T
                blocks += [(-JT, leg['hi'] - leg['b']), (JT, leg['b'] - leg['lo'])]
            for rows, rhs in blocks:
                row = np.zeros((rows.shape[0], 3 * K))
                row[:, 3 * k:3 * k + 3] = rows
                A_ub.append(row)
                b_ub.append(rhs)
        res = linprog(np.zeros(3 * K), A_ub=np.vstack(A_ub), b_ub=np.concatenate(b_ub),
                      A_eq=A_eq, b_eq=np.concatenate([force, moment]),
                      bounds=(None, None), method='highs')
        assert res.status in (0, 2), res.message
        return res.status == 0


# -- the independent geometry of a polygon ---------------------------------------------------


def signed_distance(V: np.ndarray, x: np.ndarray) -> float:
    """Return the signed distance of x to the ccw convex polygon V (point to segments)."""
    x = np.asarray(x, dtype=float)
    k = V.shape[0]
    best = np.inf
    inside = True
    for i in range(k):
        a, b = V[i], V[(i + 1) % k]
        e = b - a
        t = np.clip((x - a) @ e / (e @ e), 0.0, 1.0)
        best = min(best, float(np.linalg.norm(a + t * e - x)))
        inside &= (e[0] * (x - a)[1] - e[1] * (x - a)[0]) >= 0.0
    return best if inside else -best


def probes(R: ComRegion, rng, count: int = 10) -> np.ndarray:
    """Return points EPS inside and outside of each edge's midpoint and past each vertex."""
    V = R.vertices
    k = V.shape[0]
    pick = rng.choice(k, size=min(k, count), replace=False)
    pts = []
    for i in pick:
        a, b, n = V[i - 1], V[i], R.A[i]                 # edge i joins vertices i - 1, i
        mid = 0.5 * (a + b)
        pts += [mid - EPS * n, mid + EPS * n]
        out = R.A[i] + R.A[(i + 1) % k]
        pts.append(b + EPS * out / np.linalg.norm(out))
    centre = V.mean(axis=0)
    pts += [centre, centre + 0.5 * (V[pick[0]] - centre)]
    return np.array(pts)


def check_polygon(R: ComRegion, judge, rng, *, count: int = 10) -> None:
    """Check the representation, the margin, and the definition at the probes."""
    assert R.dimension == 2
    V, A, b = R.vertices, R.A, R.b
    np.testing.assert_allclose(np.linalg.norm(A, axis=1), 1.0, atol=1e-12)
    assert R.area > 0.0                                   # counter-clockwise
    assert np.all(A @ V.T <= b[:, None] + 1e-9)
    for i in range(V.shape[0]):                           # edge i joins vertices i - 1, i
        assert abs(A[i] @ V[i - 1] - b[i]) < 1e-9 and abs(A[i] @ V[i] - b[i]) < 1e-9
    assert R.margin == pytest.approx(signed_distance(V, np.zeros(2)), abs=1e-6)
    for x in probes(R, rng, count):
        depth = signed_distance(V, x)
        if abs(depth) >= MIN_DEPTH:
            assert judge(x) == (depth > 0.0), (x, depth)


# -- cases -------------------------------------------------------------------------------------


@lru_cache(maxsize=None)
def evaluator(limits: tuple) -> FeasibilityEvaluator:
    """Return a HyQ evaluator with the given torque limits ((joint, lo, hi), ...)."""
    config = dataclasses.replace(load_config('hyq'),
                                 torque_limits={j: (lo, hi) for j, lo, hi in limits})
    return FeasibilityEvaluator(config)


def random_case(seed: int, K: int):
    """Return (evaluator, state, oracle) for a random posture, stance, mu and torque box."""
    rng = np.random.default_rng(seed)
    base = load_config('hyq')
    joints = [j for foot in FEET for j in base.leg_joints[foot]]
    scale = rng.uniform(0.3, 0.6, size=len(joints))
    limits = tuple((j, -150.0 * s, 150.0 * s) for j, s in zip(joints, scale))
    ev = evaluator(limits)
    q = {j: v + rng.uniform(-0.15, 0.15) for j, v in base.standing_posture.items()}
    stance = tuple(sorted(rng.choice(FEET, size=K, replace=False), key=FEET.index))
    mu = float(rng.uniform(0.3, 1.0))
    state = RobotState(joint_positions=q, stance=list(stance), friction_coefficient=mu)
    return ev, state, Oracle(ev.config, q, stance, mu), rng


def wrench_sets(ev, state):
    """Return (FWS, FWP, CWC) of a state from the evaluator."""
    result = ev.evaluate(state, fws=True)
    legs = list(result.legs.values())
    p = np.array([leg.position for leg in legs]).reshape(-1, 3)
    normals = np.array([leg.normal for leg in legs]).reshape(-1, 3)
    mus = np.array([leg.friction_coefficient for leg in legs])
    cwc = contact_wrench_cone(p, normals, mus, ev.config.pyramid_sides)
    return result, result.fws.polytope, result.fwp.polytope, cwc


# -- the definition, on random postures --------------------------------------------------------


@pytest.mark.parametrize('seed, K', [(1, 4), (2, 4), (3, 3), (4, 3), (5, 4)])
def test_regions_match_the_definition(seed, K):
    """Feasible, support and FWP regions against LPs on the contact forces."""
    ev, state, oracle, rng = random_case(seed, K)
    result, fws, fwp, cwc = wrench_sets(ev, state)
    f = oracle.force()
    m = np.zeros(3)
    np.testing.assert_allclose(result.wrench, np.concatenate([f, m]), rtol=1e-9, atol=1e-9)
    feasible = com_region(fws, f, m)
    support = com_region(cwc, f, m)
    fwp_region = com_region(fwp, f, m)
    for region, judge in (
            (feasible, lambda x: oracle.feasible(x, f, m, torque=True, friction=True)),
            (support, lambda x: oracle.feasible(x, f, m, torque=False, friction=True)),
            (fwp_region, lambda x: oracle.feasible(x, f, m, torque=True, friction=False)
             and oracle.feasible(x, f, m, torque=False, friction=True))):
        if region.dimension == 2:
            check_polygon(region, judge, rng, count=8)
        else:
            assert region.dimension == -1 and np.isnan(region.margin)
            grid = support.vertices if support.dimension == 2 else np.zeros((1, 2))
            assert not any(judge(x) for x in np.vstack([grid, grid.mean(axis=0)]))
    # FWS ⊆ FWP ⊆ CWC: so are their regions.
    for inner, outer in ((feasible, fwp_region), (fwp_region, support)):
        if inner.dimension == 2:
            assert np.all(outer.A @ inner.vertices.T <= outer.b[:, None] + 1e-7)


def test_polygon_is_exact_against_qhull():
    """Vertices agree with scipy's half-space intersection of the same rows (another method)."""
    ev, state, oracle, _ = random_case(7, 4)
    _, fws, _, _ = wrench_sets(ev, state)
    f = oracle.force()
    R = com_region(fws, f, np.zeros(3))
    assert R.dimension == 2
    w0, D = com_wrench_map(f, np.zeros(3))
    n, h = fws.A @ D, fws.b - fws.A @ w0
    keep = np.linalg.norm(n, axis=1) > 1e-9
    hs = HalfspaceIntersection(np.column_stack([n[keep], -h[keep]]), R.vertices.mean(axis=0))
    Q = hs.intersections
    # Every qhull vertex lies on the polygon's boundary and every polygon vertex is a qhull one.
    for x in Q:
        assert abs(signed_distance(R.vertices, x)) < 1e-9
    for v in R.vertices:
        assert np.min(np.linalg.norm(Q - v, axis=1)) < 1e-9


def test_support_region_on_flat_ground_is_the_support_polygon():
    """Quasi-static, level ground: the support region is the hull of the feet (any mu)."""
    ev = FeasibilityEvaluator('hyq')
    for stance in (FEET, FEET[:3]):
        result, _, _, cwc = wrench_sets(ev, ev.standing_state(stance=list(stance)))
        p = np.array([leg.position[:2] for leg in result.legs.values()])
        R = com_region(cwc, result.wrench[:3], result.wrench[3:])
        assert R.dimension == 2 and R.vertices.shape[0] == len(stance)
        for v in R.vertices:
            assert np.min(np.linalg.norm(p - v, axis=1)) < 1e-9
        for x in p:
            assert np.min(np.linalg.norm(R.vertices - x, axis=1)) < 1e-9


def test_sign_convention_moving_com_forward_needs_a_nose_down_moment():
    """W(delta) = [f; L' + delta x f]: with f = m g z, delta = x gives tau_y = -m g."""
    w0, D = com_wrench_map([0.0, 0.0, 10.0], [1.0, 2.0, 3.0])
    np.testing.assert_allclose(w0 + D @ [1.0, 0.0], [0, 0, 10, 1, 2 - 10, 3])
    np.testing.assert_allclose(w0 + D @ [0.0, 1.0], [0, 0, 10, 1 + 10, 2, 3])
    f = np.array([1.0, -2.0, 9.0])
    d = np.array([0.3, -0.7])
    np.testing.assert_allclose(D.shape, (6, 2))
    _, D = com_wrench_map(f, np.zeros(3))
    np.testing.assert_allclose((D @ d)[3:], np.cross([*d, 0.0], f))


def test_dynamic_force_and_moment_shift_the_region():
    """Non-zero c'' and L': the region moves, and still matches the LP with them."""
    ev, state, oracle, rng = random_case(11, 4)
    _, fws, _, cwc = wrench_sets(ev, state)
    f = oracle.force([1.2, -0.8, 0.6])
    m = np.array([6.0, -4.0, 3.0])
    static = com_region(fws, oracle.force(), np.zeros(3))
    moving = com_region(fws, f, m)
    assert moving.dimension == 2 and static.dimension == 2
    assert np.linalg.norm(moving.vertices.mean(axis=0) - static.vertices.mean(axis=0)) > 5e-3
    check_polygon(moving, lambda x: oracle.feasible(x, f, m, torque=True, friction=True), rng)
    support = com_region(cwc, f, m)
    check_polygon(support, lambda x: oracle.feasible(x, f, m, torque=False, friction=True),
                  rng)


# -- degenerate regions ------------------------------------------------------------------------


@pytest.mark.parametrize('stance', [('lf_foot', 'rh_foot'), ('lf_foot', 'lh_foot')])
def test_two_legs_give_a_segment(stance):
    """Flat 5D sets: the region is a segment on the line the equality row fixes."""
    ev = evaluator(tuple((j, -400.0, 400.0) for foot in FEET
                         for j in load_config('hyq').leg_joints[foot]))
    q = dict(load_config('hyq').standing_posture)
    mu = 0.8
    state = RobotState(joint_positions=q, stance=list(stance), friction_coefficient=mu)
    oracle = Oracle(ev.config, q, stance, mu)
    result, fws, fwp, cwc = wrench_sets(ev, state)
    assert fws.dimension == 5 and cwc.dimension == 5
    f, m = oracle.force(), np.zeros(3)
    feet = np.array([leg['p'][:2] for leg in oracle.legs])
    for P, torque, friction in ((fws, True, True), (cwc, False, True), (fwp, True, True)):
        R = com_region(P, f, m)
        assert R.dimension == 1 and R.vertices.shape == (2, 2)
        a, b = R.vertices
        assert np.all(R.A @ R.vertices.T <= R.b[:, None] + 1e-9)
        # On the line through the feet (vertical force: the CoM above the foot line).
        for v in (a, b):
            u, w = feet[1] - feet[0], v - feet[0]
            cross = u[0] * w[1] - u[1] * w[0]
            assert abs(cross) / np.linalg.norm(feet[1] - feet[0]) < 1e-9
        e = (b - a) / np.linalg.norm(b - a)
        normal = np.array([-e[1], e[0]])

        def judge(x):
            if P is fwp:
                return (oracle.feasible(x, f, m, torque=True, friction=False)
                        and oracle.feasible(x, f, m, torque=False, friction=True))
            return oracle.feasible(x, f, m, torque=torque, friction=friction)
        for t in (0.05, 0.5, 0.95):
            assert judge(a + t * (b - a))
        for x in (a - EPS * e, b + EPS * e, 0.5 * (a + b) + EPS * normal,
                  0.5 * (a + b) - EPS * normal):
            assert not judge(x)
        d = np.clip(-(a @ (b - a)) / ((b - a) @ (b - a)), 0.0, 1.0)
        assert R.margin == pytest.approx(-np.linalg.norm(a + d * (b - a)), abs=1e-9)
        assert R.contains(0.5 * (a + b)) and not R.contains(0.5 * (a + b) + EPS * normal)


def test_one_leg_gives_a_point_or_nothing():
    """Flat 3D sets: the CoM must be above the foot (quasi-static), if the leg can hold."""
    base = load_config('hyq')
    q = dict(base.standing_posture)
    for limit, holds in ((2000.0, True), (60.0, False)):
        ev = evaluator(tuple((j, -limit, limit) for foot in FEET for j in base.leg_joints[foot]))
        state = RobotState(joint_positions=q, stance=['lf_foot'], friction_coefficient=0.7)
        oracle = Oracle(ev.config, q, ('lf_foot',), 0.7)
        _, fws, fwp, cwc = wrench_sets(ev, state)
        f, m = oracle.force(), np.zeros(3)
        foot = oracle.legs[0]['p'][:2]
        support = com_region(cwc, f, m)
        assert support.dimension == 0
        np.testing.assert_allclose(support.vertices[0], foot, atol=1e-9)
        assert support.margin == pytest.approx(-np.linalg.norm(foot), abs=1e-9)
        assert oracle.feasible(foot, f, m, torque=False, friction=True)
        assert not oracle.feasible(foot + [EPS, 0.0], f, m, torque=False, friction=True)
        for P in (fws, fwp):
            R = com_region(P, f, m)
            assert oracle.feasible(foot, f, m, torque=True, friction=True) == holds
            if holds:
                assert R.dimension == 0
                np.testing.assert_allclose(R.vertices[0], foot, atol=1e-9)
            else:
                assert R.dimension == -1 and np.isnan(R.margin)
        # A moment the single foot cannot make (about the vertical through it): empty.
        assert com_region(cwc, f, [0.0, 0.0, 5.0]).dimension == -1


def test_empty_region_and_no_leg():
    """Torque limits too low to stand: empty, margin NaN; no stance leg: empty."""
    base = load_config('hyq')
    q = dict(base.standing_posture)
    ev = evaluator(tuple((j, -15.0, 15.0) for foot in FEET for j in base.leg_joints[foot]))
    state = RobotState(joint_positions=q, stance=list(FEET[:3]), friction_coefficient=0.7)
    oracle = Oracle(ev.config, q, FEET[:3], 0.7)
    _, fws, fwp, cwc = wrench_sets(ev, state)
    f, m = oracle.force(), np.zeros(3)
    support = com_region(cwc, f, m)
    for P in (fws, fwp):
        R = com_region(P, f, m)
        assert R.dimension == -1 and np.isnan(R.margin) and R.vertices.shape == (0, 2)
        assert not R.contains(np.zeros(2))
    for x in np.vstack([support.vertices.mean(axis=0), 0.5 * support.vertices]):
        assert not oracle.feasible(x, f, m, torque=True, friction=True)
    _, fws0, fwp0, cwc0 = wrench_sets(ev, ev.standing_state(stance=[]))
    for P in (fws0, fwp0, cwc0):
        R = com_region(P, f, m)
        assert R.dimension == -1 and np.isnan(R.margin)
    assert com_region(Polytope.empty(6), f, m).dimension == -1


def test_current_com_outside_and_near_the_boundary():
    """The general path (interior point by the Chebyshev LP) gives the same polygon."""
    ev, state, oracle, rng = random_case(3, 4)
    _, fws, _, _ = wrench_sets(ev, state)
    f, m = oracle.force(), np.zeros(3)
    R = com_region(fws, f, m)
    assert R.dimension == 2
    for shift in (np.zeros(2), R.vertices[0] + [0.05, 0.0], R.vertices[0],
                  0.5 * (R.vertices[0] + R.vertices[1]), R.vertices[0] * 3.0):
        # Shifting the moment is moving the reference: the region moves by -shift.
        _, D = com_wrench_map(f, m)
        S = com_region(fws, f, m + (D @ shift)[3:])
        assert S.vertices.shape == R.vertices.shape
        gap = np.linalg.norm((S.vertices + shift)[:, None] - R.vertices[None], axis=2)
        assert gap.min(axis=0).max() < 1e-9 and gap.min(axis=1).max() < 1e-9
        assert S.margin == pytest.approx(signed_distance(R.vertices, shift), abs=1e-6)


def test_bad_inputs_and_unbounded_regions():
    ev = FeasibilityEvaluator('hyq')
    _, fws, _, _ = wrench_sets(ev, ev.standing_state())
    with pytest.raises(InputError, match='vertical'):
        com_region(fws, [10.0, 0.0, 0.0], np.zeros(3))
    with pytest.raises(InputError, match='force'):
        com_region(fws, [0.0, 0.0, np.nan], np.zeros(3))
    with pytest.raises(InputError, match='moment'):
        com_region(fws, [0.0, 0.0, 800.0], np.zeros(2))
    with pytest.raises(InputError, match='force'):
        com_region(fws, 'up', np.zeros(3))
    with pytest.raises(InputError):
        com_region(np.zeros((3, 6)), [0.0, 0.0, 800.0], np.zeros(3))
    # |tau_x| <= 10 only: a strip in y, unbounded in x.
    strip = Polytope(6, np.zeros((0, 6)), np.array([[0, 0, 0, 1.0, 0, 0], [0, 0, 0, -1.0, 0, 0]]),
                     np.array([10.0, 10.0]), np.zeros(6), np.eye(6))
    with pytest.raises(InputError, match='unbounded'):
        com_region(strip, [0.0, 0.0, 800.0], np.zeros(3))


# -- synthetic sets: thin, contradictory, constant rows, the LP fallback ------------------------


def rows_set(rows, rhs) -> Polytope:
    """Return a full-dimensional 'polytope' of R^6 from rows (normalised) and offsets."""
    A = np.asarray(rows, dtype=float)
    norm = np.linalg.norm(A, axis=1)
    return Polytope(6, np.zeros((0, 6)), A / norm[:, None], np.asarray(rhs) / norm,
                    np.zeros(6), np.eye(6))


def box_rows(tx: float, ty: float, tz: float = 50.0, fmax: float = 2000.0):
    """Rows |f_i| <= fmax (constant in delta) and |tau_x| <= tx, |tau_y| <= ty, |tau_z| <= tz."""
    E = np.eye(6)
    return np.vstack([E, -E]), np.array([fmax] * 3 + [tx, ty, tz] + [fmax] * 3 + [tx, ty, tz])


def test_synthetic_box_thin_and_empty():
    f = np.array([0.0, 0.0, 1000.0])
    # |tau_x| = |delta_y f_z| <= 50, |tau_y| = |delta_x f_z| <= 100: a 0.2 x 0.1 m box.
    R = com_region(rows_set(*box_rows(50.0, 100.0)), f, np.zeros(3))
    assert R.dimension == 2 and R.vertices.shape == (4, 2)
    np.testing.assert_allclose(np.sort(np.abs(R.vertices), axis=0), [[0.1, 0.05]] * 4)
    assert R.margin == pytest.approx(0.05)
    # A sliver 2e-10 m wide (below distance_tol): the segment along x.
    R = com_region(rows_set(*box_rows(1e-7, 100.0)), f, np.zeros(3))
    assert R.dimension == 1
    np.testing.assert_allclose(np.sort(R.vertices[:, 0]), [-0.1, 0.1], atol=1e-9)
    np.testing.assert_allclose(R.vertices[:, 1], 0.0, atol=1e-9)
    # Contradictory rows tau_x <= -1 and -tau_x <= -1: empty (Chebyshev radius < 0).
    A, b = box_rows(-1.0, 100.0)
    assert com_region(rows_set(A, b), f, np.zeros(3)).dimension == -1
    # A violated constant row (f_z <= 500 N): empty whatever delta.
    A, b = box_rows(50.0, 100.0, fmax=500.0)
    assert com_region(rows_set(A, b), f, np.zeros(3)).dimension == -1


def test_chebyshev_fallback_to_highs_agrees(monkeypatch):
    """The dual-simplex Chebyshev LP and one HiGHS LP over every row give the same region."""
    import awp_ros.wrench.com_region as module
    ev, state, oracle, _ = random_case(3, 3)
    _, fws, _, _ = wrench_sets(ev, state)
    f = oracle.force()
    m = np.array([0.0, -f[2] * 0.3, 0.0])                 # the CoM 0.3 m ahead: outside
    R = com_region(fws, f, m)
    assert R.dimension == 2 and R.margin < 0.0
    monkeypatch.setattr(module, '_MAX_PIVOTS', 0)
    S = com_region(fws, f, m)
    gap = np.linalg.norm(S.vertices[:, None] - R.vertices[None], axis=2)
    assert S.vertices.shape == R.vertices.shape and gap.min(axis=1).max() < 1e-9
    assert S.margin == pytest.approx(R.margin, abs=1e-12)


def test_lines_cutting_less_than_the_tolerance_are_dropped():
    """Corner cuts 3e-10 m deep (below distance_tol) leave the square's 4 edges only."""
    f = np.array([0.0, 0.0, 1000.0])
    A, b = box_rows(100.0, 100.0)
    diagonals = np.zeros((4, 6))
    diagonals[:, 3:5] = [[1, 1], [1, -1], [-1, 1], [-1, -1]]
    # (tau_x +- tau_y) / sqrt 2 <= (200 - eps) / sqrt 2: a cut of eps / (sqrt 2 f_z) [m].
    cut = 3e-10
    rows = rows_set(np.vstack([A, diagonals]),
                    np.concatenate([b, np.full(4, 200.0 - cut * np.sqrt(2.0) * f[2])]))
    R = com_region(rows, f, np.zeros(3))
    assert R.dimension == 2 and R.vertices.shape == (4, 2)
    np.testing.assert_allclose(np.abs(R.vertices), 0.1, atol=1e-9)
    np.testing.assert_allclose(np.abs(R.A).sum(axis=1), 1.0)      # the axis-aligned edges
    # Deeper cuts (1 mm) are edges: an octagon.
    rows = rows_set(np.vstack([A, diagonals]),
                    np.concatenate([b, np.full(4, 200.0 - 1e-3 * np.sqrt(2.0) * f[2])]))
    assert com_region(rows, f, np.zeros(3)).vertices.shape == (8, 2)


def test_a_slice_the_sampled_chain_misses_falls_back_to_the_exact_hull():
    """
    Check the FWS slice of the default bag at t = 3.402 s (3 legs, 303 rows) against qhull.

    The sampled support chain kept missing hull vertices there; the region must still be
    the polygon qhull finds for the same rows.
    """
    data = np.load(Path(__file__).parent / 'data' / 'fws_3legs_default_bag_t3402.npz')
    A, b, w = data['A'], data['b'], data['w']
    P = Polytope(6, np.zeros((0, 6)), A, b, np.zeros(6), np.eye(6))
    region = com_region(P, w[:3], w[3:])
    w0, D = com_wrench_map(w[:3], w[3:])
    N2, h = A @ D, b - A @ w0
    keep = np.linalg.norm(N2, axis=1) > 1e-9
    hs = HalfspaceIntersection(np.hstack([N2[keep], -h[keep, None]]), np.zeros(2))
    ref = hs.intersections[ConvexHull(hs.intersections).vertices]
    assert region.dimension == 2 and len(region.vertices) == len(ref)
    for v in ref:
        assert np.min(np.linalg.norm(region.vertices - v, axis=1)) < 1e-6
    distances = h[keep] / np.linalg.norm(N2[keep], axis=1)     # the CoM is inside
    assert region.margin == pytest.approx(float(np.min(distances)))


# -- the feasible region every cycle: projection by LPs, without the FWS's H-rep ---------------


def projected(ev, result, f, m):
    """Return feasible_region() of an evaluated state at the force and moment (f, m)."""
    legs = list(result.legs.values())
    rows = ev._friction_rows(np.array([leg.normal for leg in legs]).reshape(-1, 3),
                             np.array([leg.friction_coefficient for leg in legs]))
    return feasible_region(np.array([leg.position for leg in legs]).reshape(-1, 3),
                           [leg.force_polytope for leg in legs], rows, f, m)


def chain_distance(V: np.ndarray, x: np.ndarray) -> float:
    """Return the distance of x to the closed chain of vertices V (its boundary)."""
    a, b = V, np.roll(V, -1, axis=0)
    e = b - a
    ee = np.maximum((e * e).sum(axis=1), 1e-300)
    t = np.clip(((x - a) * e).sum(axis=1) / ee, 0.0, 1.0)
    return float(np.linalg.norm(a + t[:, None] * e - x, axis=1).min())


def assert_same_region(R: ComRegion, S: ComRegion, atol: float = 1e-9) -> None:
    """
    Two regions with the same dimension, boundaries within ``atol`` [m], the same margin.

    Every vertex of each lies within ``atol`` of the other's boundary (a Hausdorff test: an
    edge shorter than the methods' rounding may be one vertex in one and two in the other).
    """
    assert R.dimension == S.dimension
    if R.vertices.size:
        assert max(chain_distance(S.vertices, v) for v in R.vertices) < atol, (R, S)
        assert max(chain_distance(R.vertices, v) for v in S.vertices) < atol, (R, S)
    assert R.margin == pytest.approx(S.margin, abs=atol) or \
        (np.isnan(R.margin) and np.isnan(S.margin))


@pytest.mark.parametrize('seed, K', [(11, 4), (12, 4), (13, 3), (14, 3), (15, 4), (16, 3)])
def test_feasible_region_by_projection_matches_the_definition(seed, K):
    """The per-cycle feasible region: LPs of the definition, and the FWS's exact slice."""
    ev, state, oracle, rng = random_case(seed, K)
    result, fws, _, _ = wrench_sets(ev, state)
    f, m = oracle.force(), np.zeros(3)
    R = projected(ev, result, f, m)
    assert_same_region(R, com_region(fws, f, m))
    if R.dimension == 2:
        check_polygon(R, lambda x: oracle.feasible(x, f, m, torque=True, friction=True), rng,
                      count=8)
    # A moving robot: the region for another force and moment (c'' and L' measured).
    f2, m2 = oracle.force((0.8, -0.5, 1.5)), np.array([3.0, -6.0, 2.0])
    R2 = projected(ev, result, f2, m2)
    assert_same_region(R2, com_region(fws, f2, m2))
    if R2.dimension == 2:
        check_polygon(R2, lambda x: oracle.feasible(x, f2, m2, torque=True, friction=True),
                      rng, count=6)


@pytest.mark.parametrize('stance', [('lf_foot', 'rh_foot'), ('rf_foot', 'lh_foot'),
                                    ('lf_foot',)])
def test_feasible_region_by_projection_degenerate_cases(stance):
    """Two legs: the same segment as the FWS's slice; one leg: the same point (or none)."""
    base = load_config('hyq')
    q = dict(base.standing_posture)
    for limit in (400.0, 60.0):
        ev = evaluator(tuple((j, -limit, limit) for foot in FEET for j in base.leg_joints[foot]))
        state = RobotState(joint_positions=q, stance=list(stance), friction_coefficient=0.8)
        result, fws, _, _ = wrench_sets(ev, state)
        f, m = result.wrench[:3], result.wrench[3:]
        R = projected(ev, result, f, m)
        assert_same_region(R, com_region(fws, f, m))
        assert R.dimension in (-1, len(stance) - 1)
        assert result.feasible_region is result.feasible_region_per_cycle


def test_feasible_region_by_projection_empty_and_unavailable():
    """Too weak to stand: empty (NaN margin); no leg or no vertical force: not computed."""
    base = load_config('hyq')
    q = dict(base.standing_posture)
    ev = evaluator(tuple((j, -15.0, 15.0) for foot in FEET for j in base.leg_joints[foot]))
    state = RobotState(joint_positions=q, stance=list(FEET), friction_coefficient=0.7)
    result, fws, _, _ = wrench_sets(ev, state)
    f, m = result.wrench[:3], result.wrench[3:]
    R = projected(ev, result, f, m)
    assert R.dimension == -1 and np.isnan(R.margin) and com_region(fws, f, m).dimension == -1
    assert projected(ev, result, np.array([10.0, 0.0, 0.0]), m) is None      # free fall
    assert feasible_region(np.zeros((0, 3)), [], np.zeros((0, 5, 3)), f, m) is None


def force_lp_support(result, u: np.ndarray) -> float:
    """
    Return max u . delta over the feasible region by one LP on the contact forces.

    Variables ``f_k`` (torque rows of the force polytope and pyramid rows per leg) and
    ``delta``: ``sum_k L_k f_k = w_0 + D delta`` (HiGHS, tolerances 1e-10).
    """
    from awp_ros.wrench.friction_polytope import friction_rows
    legs = list(result.legs.values())
    K = len(legs)
    rows = friction_rows(np.array([leg.normal for leg in legs]),
                         np.array([leg.friction_coefficient for leg in legs]), 4)
    w0, D = com_wrench_map(result.wrench[:3], result.wrench[3:])
    A_eq = np.zeros((6, 3 * K + 2))
    A_eq[:, 3 * K:] = -D
    A_ub, b_ub = [], []
    for k, leg in enumerate(legs):
        x, y, z = leg.position
        A_eq[:3, 3 * k:3 * k + 3] = np.eye(3)
        A_eq[3:, 3 * k:3 * k + 3] = [[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]]
        H = np.vstack([leg.force_polytope.A, rows[k]])
        block = np.zeros((H.shape[0], 3 * K + 2))
        block[:, 3 * k:3 * k + 3] = H
        A_ub.append(block)
        b_ub.append(np.concatenate([leg.force_polytope.b, np.zeros(rows.shape[1])]))
    res = linprog(np.concatenate([np.zeros(3 * K), -np.asarray(u)]), A_ub=np.vstack(A_ub),
                  b_ub=np.concatenate(b_ub), A_eq=A_eq, b_eq=w0, bounds=(None, None),
                  method='highs', options={'primal_feasibility_tolerance': 1e-10,
                                           'dual_feasibility_tolerance': 1e-10})
    assert res.status == 0, res.message
    return float(-res.fun)


def test_feasible_region_every_cycle_on_the_default_bag(tmp_path):
    """Node pipeline over the default bag: at every FWS cycle the projection is its slice."""
    from awp_ros.bags.replay import replay_bag
    from awp_ros.robot.config import load_parameters
    from awp_ros.ros.pipeline import Pipeline
    values, base_dir = load_parameters('hyq', {'use_imu': True})
    pipe = Pipeline.from_parameters(values, base_dir=base_dir)
    seen = {'cycles': 0, 'compared': 0, 'decided': 0, 'dims': set()}
    evaluate = pipe.on_joint_state

    def check(msg, **kw):
        cycle = evaluate(msg, **kw)
        r = cycle.result
        if r is not None and r.legs:
            seen['cycles'] += 1
            assert r.feasible_region_per_cycle is not None
            if r.fws is not None:
                R = r.feasible_region_per_cycle
                S = com_region(r.fws.polytope, r.wrench[:3], r.wrench[3:])
                # The FWS's H-rep may overshoot by ~1e-16 / rank_tol relative (its docs):
                # up to 1.4e-7 m seen here in the CoM plane. Where the two differ by more
                # than 1e-9 m, an LP on the contact forces decides: the projection's
                # support value is the LP's.
                assert_same_region(R, S, atol=5e-7)
                gaps = [float(np.min(R.b - R.A @ v)) for v in S.vertices] \
                    if R.dimension == 2 else []
                if gaps and min(gaps) < -1e-9:
                    i = int(np.argmin(R.b - R.A @ S.vertices[int(np.argmin(gaps))]))
                    assert force_lp_support(r, R.A[i]) == pytest.approx(R.b[i], abs=1e-9)
                    seen['decided'] += 1
                seen['compared'] += 1
                seen['dims'].add(r.feasible_region_per_cycle.dimension)
        return cycle
    pipe.on_joint_state = check
    bag = Path(__file__).resolve().parents[2] / 'config' / 'hyq_gait.mcap'
    replay_bag(bag, tmp_path / 'out.mcap', pipeline=pipe, outputs=['report'], progress=False,
               copy_inputs=False)
    assert seen['cycles'] > 5000 and seen['compared'] > 100
    assert {1, 2} <= seen['dims']              # the trot's segments and the crawl's polygons
