"""Markers: meshes of the right polytopes, the FWP force slice, and well-formed messages."""

from __future__ import annotations

import math

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from scipy.optimize import linprog
from scipy.spatial import ConvexHull
from std_msgs.msg import Header
from visualization_msgs.msg import Marker, MarkerArray

from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.geometry.linalg import quaternion_matrix
from awp_ros.geometry.mesh import force_slice, hull_triangles
from awp_ros.geometry.polytope import Polytope
from awp_ros.ros.markers import build_markers, error_markers, MarkerStyle

VALID_TYPES = set(range(12))


@pytest.fixture(scope='module')
def evaluator():
    return FeasibilityEvaluator('hyq')


def _area(tri: np.ndarray) -> float:
    return float(0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]),
                                      axis=1).sum())


def _volume(tri: np.ndarray) -> float:
    """Volume enclosed by a closed outward-wound mesh (divergence theorem)."""
    return float(np.einsum('ij,ij->i', tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6)


def test_unit_cube_mesh_has_area_6_volume_1_and_outward_winding():
    V = np.array(np.meshgrid([0, 1], [0, 1], [0, 1], indexing='ij')).reshape(3, -1).T + 5.0
    tri = hull_triangles(V.astype(float))
    assert tri.shape == (12, 3, 3)
    assert _area(tri) == pytest.approx(6.0)
    assert _volume(tri) == pytest.approx(1.0)   # positive: every normal points outward


def test_flat_square_is_fanned_both_sides_and_segments_give_nothing():
    V = np.array([[0, 0, 0], [1, 0, 1], [0, 1, 0], [1, 1, 1]], dtype=float)  # a tilted square
    tri = hull_triangles(V)
    assert tri.shape == (4, 3, 3)                           # 2 triangles x 2 windings
    assert _area(tri) == pytest.approx(2 * math.sqrt(2))
    assert hull_triangles(np.array([[0, 0, 0], [1, 1, 1.0], [2, 2, 2.0]])).shape == (0, 3, 3)


def _lp_support(P: Polytope, tau: np.ndarray, d: np.ndarray) -> float:
    """Return max d.f s.t. A [f; tau] <= b and [f; tau] in aff P: an LP on the definition."""
    E, e = P.equalities
    res = linprog(-d, A_ub=P.A[:, :3], b_ub=P.b - P.A[:, 3:] @ tau,
                  A_eq=E[:, :3] if E.size else None,
                  b_eq=(e - E[:, 3:] @ tau) if E.size else None,
                  bounds=[(None, None)] * 3, method='highs')
    assert res.status == 0
    return -res.fun


@pytest.mark.parametrize('stance', [None, ['lf_foot', 'rf_foot', 'rh_foot']])
def test_fwp_force_slice_vertices_match_lp_support_functions(evaluator, stance):
    r = evaluator.evaluate(evaluator.standing_state(stance=stance), fws=False)
    P, tau = r.fwp.polytope, r.wrench[3:]
    S = force_slice(P, tau, interior=r.wrench)
    assert S.shape[0] >= 4
    assert all(P.contains(np.concatenate([f, tau]), tol=1e-6) for f in S)
    rng = np.random.default_rng(1)
    for d in rng.normal(size=(8, 3)):
        assert np.max(S @ d) == pytest.approx(_lp_support(P, tau, d), rel=1e-7, abs=1e-6)
    # Without the interior hint the Chebyshev-centre path finds the same slice.
    S2 = force_slice(P, tau)
    assert ConvexHull(S2).volume == pytest.approx(ConvexHull(S).volume, rel=1e-9)


def test_force_slice_of_a_two_leg_fwp_is_a_polygon(evaluator):
    r = evaluator.evaluate(evaluator.standing_state(stance=['lf_foot', 'rh_foot']), fws=False)
    P, tau = r.fwp.polytope, r.wrench[3:]
    S = force_slice(P, tau, interior=r.wrench)
    assert S.shape[0] >= 3
    centred = S - S.mean(axis=0)
    assert np.linalg.matrix_rank(centred, tol=1e-6 * np.abs(centred).max()) == 2
    d = np.array([0.3, -0.2, 1.0])
    assert np.max(S @ d) == pytest.approx(_lp_support(P, tau, d), rel=1e-7, abs=1e-6)
    # A moment no force distribution of the two legs produces: empty slice.
    assert force_slice(P, tau + np.array([0.0, 0.0, 1e5])).shape == (0, 3)


def _check_well_formed(arr: MarkerArray, frame: str) -> dict[str, Marker]:
    """Assert what RViz and Foxglove need; return the ADD markers by namespace head."""
    markers = list(arr.markers)
    assert markers[0].action == Marker.DELETEALL
    by_ns = {}
    for m in markers[1:]:
        assert m.action == Marker.ADD and m.type in VALID_TYPES
        assert m.header.frame_id == frame
        assert 0.0 < m.color.a <= 1.0
        q = m.pose.orientation
        assert math.isclose(q.x ** 2 + q.y ** 2 + q.z ** 2 + q.w ** 2, 1.0)
        pts = np.array([[p.x, p.y, p.z] for p in m.points]).reshape(-1, 3)
        assert np.all(np.isfinite(pts))
        if m.type == Marker.TRIANGLE_LIST:
            assert len(pts) > 0 and len(pts) % 3 == 0
            assert (m.scale.x, m.scale.y, m.scale.z) == (1.0, 1.0, 1.0)
        elif m.type == Marker.ARROW:
            assert len(pts) == 2 and m.scale.x > 0 and m.scale.y > 0
        elif m.type == Marker.TEXT_VIEW_FACING:
            assert m.text and m.scale.z > 0
        else:
            assert min(m.scale.x, m.scale.y, m.scale.z) > 0
        key = (m.ns.split(' ')[0], m.id)
        assert key not in by_ns, f'duplicate marker {key}'
        by_ns[key] = m
    return by_ns


def test_markers_show_every_leg_the_wrench_and_coloured_margins(evaluator):
    r = evaluator.evaluate(evaluator.standing_state())
    style = MarkerStyle(force_scale=0.001)
    arr = deserialize_message(serialize_message(
        build_markers(r, Header(frame_id='com_world_aligned'), style=style)), MarkerArray)
    m = _check_well_formed(arr, 'com_world_aligned')
    for k, leg in enumerate(r.legs.values()):
        mesh = m[('force_polytope', k)]
        assert mesh.ns == 'force_polytope [0.001 m/N]'
        pts = np.array([[p.x, p.y, p.z] for p in mesh.points])
        # The mesh is the force polytope scaled by s and moved to the foot.
        expected = leg.position + 0.001 * leg.force_polytope.vertices
        assert ConvexHull(pts).volume == pytest.approx(ConvexHull(expected).volume, rel=1e-9)
        np.testing.assert_allclose(pts.min(axis=0), expected.min(axis=0), atol=1e-12)
        assert ('friction_polytope', k) in m and ('friction_pyramid', k) in m
    arrow = m[('gravito_inertial_wrench', 0)]
    tip = arrow.points[1]
    np.testing.assert_allclose([tip.x, tip.y, tip.z], 0.001 * r.wrench[:3], atol=1e-12)
    assert ('fwp_force_slice', 0) in m and ('com', 0) in m
    texts = [m[('margins', i)] for i in range(3)]
    assert texts[1].text.startswith('FWP margin +') and texts[1].color.g > texts[1].color.r


def test_infeasible_margin_text_is_red_and_base_frame_transform_applies(evaluator):
    # One stance leg cannot hold the robot: the wrench leaves the (flat) sets.
    state = evaluator.standing_state(stance=['lf_foot'],
                                     base_orientation=[0.0, 0.0, math.sin(0.3), math.cos(0.3)])
    r = evaluator.evaluate(state)
    R = quaternion_matrix(state.base_orientation)
    arr = build_markers(r, Header(frame_id='base_link'), rotation=R.T, translation=R.T @ r.com)
    m = _check_well_formed(arr, 'base_link')
    fwp_text = m[('margins', 1)]
    assert not r.fwp.feasible and fwp_text.color.r > fwp_text.color.g
    com = m[('com', 0)].pose.position
    np.testing.assert_allclose([com.x, com.y, com.z], R.T @ r.com, atol=1e-12)
    foot = r.legs['lf_foot'].position
    pyramid = np.array([[p.x, p.y, p.z] for p in m[('friction_pyramid', 0)].points])
    np.testing.assert_allclose(pyramid[0], R.T @ (r.com + foot), atol=1e-12)  # the apex


def test_error_markers_clear_the_scene_and_show_the_reason():
    arr = error_markers(Header(frame_id='w'), 'contacts is stale')
    m = _check_well_formed(arr, 'w')
    assert 'contacts is stale' in m[('margins', 0)].text


def test_render_markers_writes_a_png_of_the_offline_pipeline(tmp_path):
    from awp_ros.demo.render_markers import main
    out = tmp_path / 'm.png'
    assert main(['--robot', 'hyq', '--stance', 'lf_foot,rh_foot', '-o', str(out)]) == 0
    data = out.read_bytes()
    assert data[:8] == b'\x89PNG\r\n\x1a\n' and len(data) > 20_000


@pytest.mark.parametrize('stance', [None, ['lf_foot', 'rh_foot'], ['rf_foot'], []])
def test_com_regions_are_filled_polygons_on_the_feet_height(evaluator, stance):
    r = evaluator.evaluate(evaluator.standing_state(stance=stance))
    m = _check_well_formed(build_markers(r, Header(frame_id='w')), 'w')
    legs = list(r.legs.values())
    z0 = float(np.mean([leg.position[2] for leg in legs])) if legs else 0.0
    for name in ('support_region', 'fwp_region', 'feasible_region'):
        region = getattr(r, name)
        if region.is_empty:
            assert (name, 0) not in m
            continue
        mk = m[(name, 0)]
        pts = np.array([[p.x, p.y, p.z] for p in mk.points]) if mk.points else \
            np.array([[mk.pose.position.x, mk.pose.position.y, mk.pose.position.z]])
        assert np.ptp(pts[:, 2]) == 0.0 and 0.0 < pts[0, 2] - z0 < 0.02      # flat, just above
        assert all(np.min(np.linalg.norm(region.vertices - p[:2], axis=1)) < 1e-12
                   for p in pts)
        if region.dimension == 2:
            assert mk.type == Marker.TRIANGLE_LIST
            # Both windings: twice the polygon's area (shoelace on its vertices).
            x, y = region.vertices.T
            shoelace = 0.5 * abs(x @ np.roll(y, -1) - y @ np.roll(x, -1))
            assert _area(pts.reshape(-1, 3, 3)) == pytest.approx(2 * shoelace, rel=1e-12)
        elif region.dimension == 1:
            assert mk.type == Marker.LINE_STRIP and len(pts) == 2
        else:
            assert mk.type == Marker.SPHERE
    proj = m[('com_projection', 0)]
    p = proj.pose.position
    assert (p.x, p.y) == (0.0, 0.0) and p.z > z0
    margin = r.feasible_region.margin
    if math.isnan(margin):
        assert proj.color.r == proj.color.g                      # grey: no feasible region
    else:
        assert (proj.color.g > proj.color.r) == (margin >= 0.0)
    assert 'CoM region margins [m]' in m[('region_margins', 0)].text
