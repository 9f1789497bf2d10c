"""
The CoM regions of a FeasibilityResult: the evaluator's plumbing and the JSON form.

The regions the evaluator stores are checked against the core built here from the result's
own inputs (the CWC rebuilt from the feet, the FWS/FWP H-reps) and against independent
geometry: the support polygon of level ground is the feet's convex hull (qhull), the CoM
velocity is the finite difference of Pinocchio's CoM along the free-flyer motion, and the
capture point's margin is a point-to-polygon distance written here.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pinocchio as pin
import pytest
from scipy.spatial import ConvexHull

from awp_ros.evaluation.evaluator import FeasibilityEvaluator, STAGES
from awp_ros.evaluation.result import REGIONS
from awp_ros.robot.model import resolve_urdf
from awp_ros.wrench.com_region import com_region
from awp_ros.wrench.contact_wrench_cone import contact_wrench_cone

FEET = ('lf_foot', 'rf_foot', 'lh_foot', 'rh_foot')


@pytest.fixture(scope='module')
def hyq() -> FeasibilityEvaluator:
    return FeasibilityEvaluator('hyq')


def _cross(u: np.ndarray, w: np.ndarray) -> float:
    return float(u[0] * w[1] - u[1] * w[0])


def signed_distance(V: np.ndarray, x: np.ndarray) -> float:
    """Return the signed distance of x to a ccw polygon, segment (2 rows) or point (1 row)."""
    x = np.asarray(x, dtype=float)
    k = V.shape[0]
    d = []
    for i in range(k):
        a, b = V[i], V[(i + 1) % k]
        e = b - a
        t = 0.0 if not e.any() else min(1.0, max(0.0, float((x - a) @ e / (e @ e))))
        d.append(float(np.linalg.norm(a + t * e - x)))
    inside = k >= 3 and all(_cross(V[(i + 1) % k] - V[i], x - V[i]) >= 0 for i in range(k))
    return min(d) if inside else -min(d)


def cwc_of(result, sides: int):
    legs = list(result.legs.values())
    p = np.array([leg.position for leg in legs]).reshape(-1, 3)
    n = np.array([leg.normal for leg in legs]).reshape(-1, 3)
    mu = np.array([leg.friction_coefficient for leg in legs])
    return contact_wrench_cone(p, n, mu, sides)


def same_polygon(V: np.ndarray, W: np.ndarray, atol: float) -> bool:
    """Return whether two vertex lists are equal up to a cyclic shift, within atol [m]."""
    if V.shape != W.shape:
        return False
    return any(np.allclose(np.roll(V, s, axis=0), W, atol=atol, rtol=0.0)
               for s in range(max(V.shape[0], 1)))


@pytest.mark.parametrize('stance', [FEET, FEET[:3], ('lf_foot', 'rh_foot'), ('rf_foot',), ()])
def test_regions_of_the_result_are_the_slices_of_its_sets(hyq, stance):
    rng = np.random.default_rng(len(stance))
    state = hyq.standing_state(stance=list(stance), friction_coefficient=0.6)
    state.joint_positions = {k: v + rng.uniform(-0.05, 0.05)
                             for k, v in state.joint_positions.items()}
    r = hyq.evaluate(state)
    f, m = r.wrench[:3], r.wrench[3:]
    cwc = cwc_of(r, hyq.config.pyramid_sides) if stance else r.cwc
    expected = {'support_region': com_region(cwc, f, m),
                'fwp_region': com_region(r.fwp.polytope, f, m),
                'feasible_region': com_region(r.fws.polytope, f, m)}
    for name in REGIONS:
        got, want = getattr(r, name), expected[name]
        assert got.dimension == want.dimension, name
        # The feasible region comes from another method (projection by LPs, every cycle):
        # the same vertices up to rounding, maybe from another first vertex.
        atol = 1e-9 if name == 'feasible_region' else 1e-12
        assert same_polygon(got.vertices, want.vertices, atol), name
        assert got.margin == pytest.approx(want.margin, abs=atol) or \
            (math.isnan(got.margin) and math.isnan(want.margin))
    dims = {4: 2, 3: 2, 2: 1, 1: 0, 0: -1}
    assert r.support_region.dimension == dims[len(stance)]
    if not stance:
        assert all(getattr(r, n).is_empty and math.isnan(getattr(r, n).margin)
                   for n in REGIONS)
    # FWS ⊆ FWP ⊆ CWC: so are the regions (a point or segment lies in the larger sets).
    for inner, outer in (('feasible_region', 'fwp_region'), ('fwp_region', 'support_region')):
        a, b = getattr(r, inner), getattr(r, outer)
        if not a.is_empty:
            assert all(b.contains(v, tol=1e-7) for v in a.vertices)
    assert 'regions' in STAGES and r.timings_ms['regions'] >= 0.0
    assert r.timings_ms['feasible_region'] >= 0.0


def test_support_region_on_level_ground_is_the_feet_hull(hyq):
    r = hyq.evaluate(hyq.standing_state(), fws=False)
    feet = np.array([leg.position[:2] for leg in r.legs.values()])
    hull = feet[ConvexHull(feet).vertices]              # ccw
    R = r.support_region
    assert R.dimension == 2 and R.vertices.shape == hull.shape
    for v in hull:
        assert np.min(np.linalg.norm(R.vertices - v, axis=1)) < 1e-9
    assert R.margin == pytest.approx(signed_distance(hull, np.zeros(2)), abs=1e-9)
    # The feasible region every cycle (by projection), without the FWS.
    assert r.fws is None and r.feasible_region is r.feasible_region_per_cycle
    assert r.feasible_region.dimension == 2 and math.isnan(r.capture_point_margin)
    assert r.com_velocity is None and r.capture_point is None


def test_feasible_region_follows_the_fws_and_with_wrench_reslices(hyq):
    r = hyq.evaluate(hyq.standing_state(), fws=False)
    assert r.fws is None and r.fwp_region is r.fwp.region
    every_cycle = r.feasible_region
    hyq.add_fws(r)
    assert r.feasible_region is r.fws.region is every_cycle and every_cycle.dimension == 2
    assert same_polygon(every_cycle.vertices,
                        com_region(r.fws.polytope, r.wrench[:3], r.wrench[3:]).vertices, 1e-9)
    # A planned wrench pushing forward: the regions move; they are the slices at that wrench.
    w = r.wrench + np.array([60.0, 0.0, 0.0, 0.0, 20.0, 0.0])
    c = hyq.with_wrench(r, w)
    assert c.feasible_region is c.fws.region is c.feasible_region_per_cycle
    for name, P in (('support_region', r.cwc), ('fwp_region', r.fwp.polytope),
                    ('feasible_region', r.fws.polytope)):
        want = com_region(P, w[:3], w[3:])
        assert same_polygon(getattr(c, name).vertices, want.vertices,
                            1e-9 if name == 'feasible_region' else 1e-12), name
        shift = getattr(c, name).vertices.mean(axis=0) - getattr(r, name).vertices.mean(axis=0)
        assert abs(shift[0]) > 1e-3
    assert c.warnings is not r.warnings


def test_free_fall_leaves_the_regions_out_with_a_warning(hyq):
    st = hyq.standing_state()
    r = hyq.evaluate(st, wrench=np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0]))
    assert r.support_region is None and r.fwp_region is None and r.feasible_region is None
    assert any('support region not computed' in w for w in r.warnings)
    assert math.isnan(r.capture_point_margin)
    doc = json.loads(json.dumps(r.to_dict(), allow_nan=False))
    assert all(doc[name] is None for name in REGIONS)


def _free_flyer(hyq, state):
    """Return (model, data, q, v) of a state's free-flyer configuration (base at 0)."""
    _, path = resolve_urdf(hyq.config.urdf, hyq.config.base_dir)
    model = pin.buildModelFromUrdf(path, pin.JointModelFreeFlyer())
    q = pin.neutral(model)
    q[3:7] = state.base_orientation
    v = np.zeros(model.nv)
    v[:6] = state.base_twist
    for name in state.joint_positions:
        j = model.joints[model.getJointId(name)]
        q[j.idx_q] = state.joint_positions[name]
        v[j.idx_v] = state.joint_velocities[name]
    return model, model.createData(), q, v


def test_capture_point_from_the_finite_difference_of_the_com(hyq):
    rng = np.random.default_rng(3)
    st = hyq.standing_state()
    st.base_orientation = tuple(pin.Quaternion(pin.rpy.rpyToMatrix(0.05, -0.04, 0.3)).coeffs())
    st.base_twist = [0.25, -0.1, 0.02, 0.1, -0.2, 0.3]
    st.joint_velocities = {k: float(rng.uniform(-0.5, 0.5)) for k in st.joint_positions}
    r = hyq.evaluate(st)
    model, data, q, v = _free_flyer(hyq, st)
    dt = 1e-6
    c1 = pin.centerOfMass(model, data, pin.integrate(model, q, v * dt)).copy()
    c0 = pin.centerOfMass(model, data, pin.integrate(model, q, -v * dt)).copy()
    vcom = (c1 - c0) / (2 * dt)
    np.testing.assert_allclose(r.com_velocity, vcom, atol=1e-6)
    h = -np.mean([leg.position[2] for leg in r.legs.values()])
    xi = vcom[:2] / math.sqrt(9.81 / h)
    np.testing.assert_allclose(r.capture_point, xi, atol=1e-6)
    V = r.feasible_region.vertices
    assert r.capture_point_margin == pytest.approx(signed_distance(V, xi), abs=1e-6)
    assert r.capture_point_margin < r.feasible_region.margin      # moving towards an edge
    # Fast enough to leave the region: the margin becomes negative (distance outside).
    st.base_twist = [2.5, 0.0, 0.0, 0.0, 0.0, 0.0]
    fast = hyq.evaluate(st)
    xi = fast.capture_point
    assert fast.capture_point_margin < 0.0
    assert fast.capture_point_margin == pytest.approx(
        signed_distance(fast.feasible_region.vertices, xi), abs=1e-9)


def test_json_regions_equal_the_result_and_null_when_empty(hyq):
    st = hyq.standing_state(stance=['lf_foot', 'rh_foot'], base_twist=[0.1] + [0.0] * 5)
    r = hyq.evaluate(st)
    doc = json.loads(json.dumps(r.to_dict(), allow_nan=False))
    for name in REGIONS:
        region, d = getattr(r, name), doc[name]
        assert d['dimension'] == region.dimension == 1
        np.testing.assert_allclose(d['vertices'], region.vertices, atol=0)
        np.testing.assert_allclose(d['halfspaces'], np.column_stack([region.A, region.b]))
        assert d['margin'] == region.margin < 0.0            # a segment has no interior
    assert doc['capture_point_margin'] == r.capture_point_margin
    assert doc['com_velocity'] == pytest.approx(list(r.com_velocity))
    one = hyq.evaluate(hyq.standing_state(stance=['lf_foot']))
    doc = json.loads(json.dumps(one.to_dict(), allow_nan=False))
    assert doc['support_region']['dimension'] == 0 and len(doc['support_region']['vertices']) == 1
    assert doc['feasible_region'] == {'dimension': -1, 'vertices': [], 'halfspaces': [],
                                      'margin': None, 'area': 0.0}
    assert doc['capture_point_margin'] is None and doc['capture_point'] is None
