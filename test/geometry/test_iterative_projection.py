"""
Tests of awp_ros.geometry.iterative_projection: Bretl & Lall's LP projection of CoM regions.

Checked against hand-computable regions (the support polygon of feet on level ground, a
box of forces) and against the exact slices of :mod:`awp_ros.wrench.com_region` on HyQ:
inner polygon inside the exact one, exact one inside the outer polygon, area gap within the
tolerance.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from awp_ros.errors import InputError
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.geometry.iterative_projection import iterative_projection, torque_halfspaces
from awp_ros.robot.config import load_config
from awp_ros.robot.state import resolve_state, RobotState
from awp_ros.wrench.com_region import com_region
from awp_ros.wrench.contact_wrench_cone import contact_wrench_cone
from awp_ros.wrench.friction_polytope import friction_rows

FEET = ('lf_foot', 'rf_foot', 'lh_foot', 'rh_foot')
SQUARE = np.array([[0.3, 0.2, -0.5], [-0.3, 0.2, -0.5], [-0.3, -0.2, -0.5], [0.3, -0.2, -0.5]])


def area(V: np.ndarray) -> float:
    """Return the signed area of a polygon (positive when ccw)."""
    x, y = V[:, 0], V[:, 1]
    return 0.5 * float(x @ np.roll(y, -1) - y @ np.roll(x, -1))


def inside(V: np.ndarray, x: np.ndarray, tol: float) -> bool:
    """Return whether x is in the ccw convex polygon V, up to tol [m]."""
    e = np.roll(V, -1, axis=0) - V
    d = x - V
    cross = (e[:, 0] * d[:, 1] - e[:, 1] * d[:, 0]) / np.linalg.norm(e, axis=1)
    return bool(np.all(cross >= -tol))


def pyramid_rows(mu: float) -> tuple[np.ndarray, np.ndarray]:
    """Return the 4-sided pyramid of mu around z and n . f >= 0, as (H, 0)."""
    c = mu / np.sqrt(2.0)
    H = np.array([[1, 0, -c], [0, 1, -c], [-1, 0, -c], [0, -1, -c], [0, 0, -1.0]])
    return H, np.zeros(5)


def test_support_polygon_of_four_feet():
    """Friction only, level ground, quasi-static: the hull of the feet, in a few LPs."""
    f = np.array([0.0, 0.0, 800.0])
    R = iterative_projection(SQUARE, [pyramid_rows(0.6)] * 4, f, np.zeros(3), area_tol=1e-9)
    assert R.converged and R.area_gap <= 1e-9 and R.lps <= 12
    assert R.vertices.shape == (4, 2) and area(R.vertices) > 0.0
    for v in SQUARE[:, :2]:
        assert np.min(np.linalg.norm(R.vertices - v, axis=1)) < 1e-7
    assert area(R.outer) == pytest.approx(area(R.vertices), abs=1e-9)


def test_moment_shifts_the_support_polygon():
    """L' = (0, M, 0) about the CoM: the region moves by x = M / f_z (delta x f = -L')."""
    f = np.array([0.0, 0.0, 800.0])
    M = 40.0
    R = iterative_projection(SQUARE, [pyramid_rows(0.6)] * 4, f, [0.0, M, 0.0], area_tol=1e-9)
    expected = SQUARE[:, :2] + [M / f[2], 0.0]
    for v in expected:
        assert np.min(np.linalg.norm(R.vertices - v, axis=1)) < 1e-7


def test_box_of_forces_bounds_the_region():
    """One foot under the CoM with a force box: the CoM must stay above it (a point)."""
    f = np.array([0.0, 0.0, 800.0])
    H = np.vstack([np.eye(3), -np.eye(3)])
    g = np.array([100.0, 100.0, 1000.0, 100.0, 100.0, 0.0])
    R = iterative_projection(np.array([[0.1, -0.05, -0.5]]), [(H, g)], f, np.zeros(3))
    assert R.vertices.shape[0] == 1
    np.testing.assert_allclose(R.vertices[0], [0.1, -0.05], atol=1e-7)


def test_infeasible_gives_an_empty_region():
    f = np.array([0.0, 0.0, 800.0])
    H = np.vstack([np.eye(3), -np.eye(3)])
    g = np.array([100.0, 100.0, 100.0, 100.0, 100.0, 0.0])       # f_z <= 100 N per leg
    R = iterative_projection(SQUARE, [(H, g)] * 4, f, np.zeros(3))
    assert R.is_empty and R.lps == 1 and R.converged
    assert iterative_projection(np.zeros((0, 3)), [], f, np.zeros(3)).is_empty


def test_torque_halfspaces_are_the_torque_box():
    rng = np.random.default_rng(0)
    J = rng.normal(size=(3, 3))
    b = rng.normal(size=3) * 20.0
    lo, hi = -np.array([50.0, 60.0, 70.0]), np.array([40.0, 60.0, 80.0])
    H, g = torque_halfspaces(J, b, lo, hi)
    for _ in range(200):
        f = rng.normal(size=3) * 200.0
        tau = b - J.T @ f
        assert bool(np.all(H @ f <= g)) == bool(np.all((lo <= tau) & (tau <= hi)))


def test_bad_inputs():
    with pytest.raises(InputError):
        iterative_projection(SQUARE, [pyramid_rows(0.5)] * 3, [0, 0, 800.0], np.zeros(3))
    with pytest.raises(InputError):
        iterative_projection(SQUARE, [pyramid_rows(0.5)] * 4, [0, 0, 800.0], np.zeros(3),
                             initial_directions=2)
    # No force (free fall): nothing ties the CoM to the feet.
    with pytest.raises(InputError, match='unbounded'):
        iterative_projection(SQUARE, [pyramid_rows(0.5)] * 4, np.zeros(3), np.zeros(3))


@pytest.mark.parametrize('seed', [0, 1])
def test_agrees_with_the_exact_slices(seed):
    """Feasible and support regions of HyQ: inner ⊆ exact ⊆ outer, gap <= area_tol."""
    rng = np.random.default_rng(seed)
    base = load_config('hyq')
    joints = [j for foot in FEET for j in base.leg_joints[foot]]
    limits = {j: (-150.0 * s, 150.0 * s) for j, s in zip(joints, rng.uniform(0.3, 0.6, 12))}
    ev = FeasibilityEvaluator(dataclasses.replace(base, torque_limits=limits))
    q = {j: v + rng.uniform(-0.1, 0.1) for j, v in base.standing_posture.items()}
    mu = float(rng.uniform(0.4, 1.0))
    state = RobotState(joint_positions=q, friction_coefficient=mu)
    result = ev.evaluate(state, fws=True)
    s = resolve_state(state, ev.model.joint_names, base.feet, default_mu=mu)
    kin = ev.model.kinematics(s.q, s.stance)
    rows = friction_rows(s.normals, s.mus, base.pyramid_sides)
    both, friction = [], []
    for k, foot in enumerate(s.stance):
        H, g = torque_halfspaces(kin.J[k], kin.bias[k], ev.model.legs[foot].tau_min,
                                 ev.model.legs[foot].tau_max)
        both.append((np.vstack([H, rows[k]]), np.concatenate([g, np.zeros(len(rows[k]))])))
        friction.append((rows[k], np.zeros(len(rows[k]))))
    f, m = result.wrench[:3], result.wrench[3:]
    cwc = contact_wrench_cone(kin.p_foot__com, s.normals, s.mus, base.pyramid_sides)
    tol = 1e-5
    for P, halfspaces in ((result.fws.polytope, both), (cwc, friction)):
        exact = com_region(P, f, m)
        R = iterative_projection(kin.p_foot__com, halfspaces, f, m, area_tol=tol)
        assert exact.dimension == 2 and R.converged and R.area_gap <= tol
        for v in R.vertices:
            assert exact.contains(v, tol=1e-7)
        for v in exact.vertices:
            assert inside(R.outer, v, 1e-7)
        assert area(R.vertices) - 1e-9 <= exact.area <= area(R.vertices) + R.area_gap + 1e-9
