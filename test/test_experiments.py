"""The measurement scripts of ``examples/experiments`` (the README's figures), checked."""

from pathlib import Path
import sys
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from cases import hyq_feet, vertex_sums

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / 'examples' / 'experiments'))


def _leg(rng) -> SimpleNamespace:
    """Return a random 3D polytope [N] with its vertices and facet rows (qhull's)."""
    points = rng.normal(size=(7, 3)) * [300.0, 300.0, 900.0] + [0.0, 0.0, 800.0]
    hull = ConvexHull(points)
    return SimpleNamespace(vertices=points[hull.vertices], A=hull.equations[:, :3],
                           b=-hull.equations[:, 3])


@pytest.mark.parametrize('K', [3, 4])
def test_facet_names_count_the_facets_of_qhull_and_the_pair_facets(K):
    """
    ``fws_facet_changes.facet_names`` finds as many facets as qhull on the vertex sums.

    Of them, on legs in general position, the degenerate ones are the two of every pair of
    feet (README, "Speed": faces adding up to 6), K (K - 1) of them.
    """
    from fws_facet_changes import facet_names
    from awp_ros.wrench.feasible_wrench_set import minkowski_sum_of_lifts
    rng = np.random.default_rng(40 + K)
    legs = [_leg(rng) for _ in range(K)]
    feet = hyq_feet(rng, K)
    S = minkowski_sum_of_lifts(feet, [leg.vertices for leg in legs])
    found = facet_names(feet, legs, S.A)
    points = vertex_sums(feet, [leg.vertices for leg in legs])
    eq = ConvexHull(points).equations
    eq /= np.linalg.norm(eq[:, :6], axis=1)[:, None]
    planes = np.unique(np.round(np.column_stack([eq[:, :6], eq[:, 6] / np.abs(points).max()]),
                                6), axis=0)
    assert len(found['names']) == len(planes)
    assert found['degenerate'] == K * (K - 1)


def test_slice_search_variants_compile_and_the_exact_ones_give_the_kernel_rows():
    """The script's variants still apply to the kernel; the exact ones give its rows."""
    import slice_search_variants as SV
    from awp_ros.geometry import kernels as K
    calls = SV.record_calls(2)
    assert len(calls) == 2
    out = np.empty((1 << 14, 6)), np.empty((1 << 14, 6))

    def rows(fn, call):
        npos, nneg, _ = fn(*call, *out)
        assert npos >= 0
        return np.vstack([out[0][:npos], out[1][:nneg]])

    for replacements, exact in ((SV._PREFILTER, True), (SV._BATCHED, True), (SV._LANES, True),
                                (SV._PRUNED, False),
                                (SV._NO_SURVIVORS + SV._NO_FORMS, False)):
        fn = SV.variant(replacements)
        for call in calls:
            got, ref = rows(fn, call), rows(K._slice_search, call)
            if exact:
                assert np.array_equal(got, ref)


def test_cycle_cost_split_times_every_kernel_call_of_the_loop():
    """The split's parts add up: its wrapped calls are the evaluations' kernels and Pinocchio."""
    import cycle_cost_split as C
    out = C.split(count=20, passes=2)
    names = {r['name'] for r in out['rows']}
    assert {'_cycle_sets', '_cycle_regions', 'pin.rnea', 'pin.getFrameJacobian'} <= names
    assert all(r['in_loop_us'] > 0.0 and r['isolated_us'] > 0.0 for r in out['rows'])
    assert out['calls_in_loop_us'] == pytest.approx(sum(r['in_loop_us'] for r in out['rows']))
    assert 0.0 < out['python_us'] < out['wrapped_loop_us']
    assert next(r for r in out['rows'] if r['name'] == 'pin.getFrameJacobian')[
        'calls_per_evaluation'] == 4.0                          # one per stance foot


def test_ros_glue_floor_relays_every_joint_state():
    """The relay answers every joint state of a short drive and its CPU is measured."""
    import ros_glue_floor as G
    out = G.measure(rate_hz=200.0, duration_s=2.0, domain=58)
    assert out['sent'] == out['relayed'] == out['received'] == 400
    assert 0.0 < out['relay_cpu_percent'] < 200.0
    assert out['relay_ms_per_joint_state'] == pytest.approx(10.0 * out['relay_cpu_percent']
                                                            / 200.0, rel=0.01)


def test_flat_pair_ab_times_both_searches_and_restores_the_compiled_one():
    """``flat_pair_ab.run`` times the numpy and the compiled two-leg search, then restores it."""
    import flat_pair_ab
    import awp_ros.geometry.minkowski_facets as mf
    compiled = mf._flat_pair
    out = flat_pair_ab.run(count=12, passes=1)
    assert set(out) == {'numpy', 'compiled'}
    assert all(len(v) == len(flat_pair_ab.PAIRS) and min(v) > 0.0 for v in out.values())
    assert mf._flat_pair is compiled


def test_fws_depth_bounds_are_lower_bounds_of_the_facets_they_would_skip():
    """
    ``fws_depth_bounds``' forces give the wrench, its bounds stay below the H-rep's slacks.

    Its forces sum to the wrench with every leg at least ``r`` deep in its polytope; bound (2)
    of a slice never exceeds the slack of an H-rep row whose normal lies in the slice (the
    exact H-rep, an independent computation), and a node's bound (a plane of the slice) is never
    below its slice's.
    """
    import fws_depth_bounds as DB
    from awp_ros.geometry.face_lattice import polytope_faces
    from awp_ros.wrench.feasible_wrench_set import _leg_inputs, lift_matrices
    positions, frictions, w = DB.four_leg_jobs(1000)[1]
    faces = [polytope_faces(V, H, rank_tol=1e-7, plane_tol=1e-9)
             for V, H in zip(*_leg_inputs(frictions))]
    forces, r = DB.interior_forces(np.asarray(positions), faces, w)
    lifted = np.einsum('kij,kj->i', lift_matrices(positions), forces)
    np.testing.assert_allclose(lifted, w, atol=1e-6 * np.abs(w).max())
    for F, f in zip(faces, forces):
        assert np.min(F.facet_offsets - F.facet_normals @ f) >= r - 1e-6 * abs(r)
    out = DB.measure(positions, frictions, w)
    assert out['r'] == pytest.approx(r) and 0.0 < r < out['d_star']
    assert -np.inf < out['worst'] <= 1e-9 * out['d_star']
    for item in DB.slice_bounds(np.asarray(positions), faces, forces):
        nodes = item['nodes'][np.isfinite(item['nodes'])]
        assert nodes.size and np.all(nodes >= item['bound'] * (1 - 1e-9) - 1e-9)


def test_every_report_of_the_default_bag_has_the_fws_verdict_of_its_own_joint_state():
    """
    Every report's ``feasible`` is its own FWS's verdict, and its directional margins too.

    With the FWS at 10 Hz: ``fws_verdict_age.count`` replays the default bag with the default
    parameters (the FWS at ``fws_rate_hz``) and computes an FWS for every joint state (a full
    recomputation): each report's ``feasible`` must equal the FWP's verdict and that FWS's
    (three or more legs: by the feasible region; two: by the one-dimensional LP), and with
    three or more legs its ``fws_directional_plus/minus`` that FWS's (by LPs every cycle). The
    latest FWS's verdict, which two-leg reports carried before session 21, would differ on
    the trot of this bag, and its directional margins, which the others carried before
    session 22, are off by more than 10 N or N.m.
    """
    from fws_verdict_age import count
    out = count()
    assert {k: c['reports'] for k, c in out.items()} == {2: 1201, 3: 1800, 4: 2800}
    assert all(c['differs'] == 0 for c in out.values())
    assert out[2]['latest differs'] > 50
    assert out[3]['directional differs'] == out[4]['directional differs'] == 0
    assert out[4]['latest directional off'] > 10.0
    assert out[3]['outside'] == out[4]['outside'] == 0       # quasi-static: never outside


def test_every_report_outside_the_fws_has_its_own_margin_with_the_imu():
    """
    With the bag's IMU the lurch leaves the FWS: those reports carry their own margin.

    ``fws_verdict_age.count(use_imu=True)`` over the joint states up to the lurch's end (6.5 s
    of the bag at 500 Hz): every three-leg report outside the FWS without an FWS of its own has
    the ``fws_margin`` of a full recomputation of its joint state's FWS, where the latest FWS's
    (what they carried before session 24) was off.
    """
    from fws_verdict_age import count
    out = count(max_states=3300, use_imu=True)
    assert out[3]['outside'] >= 90 and out[3]['margin differs'] == 0
    assert out[4]['outside'] == 0 and out[3]['latest margin off'] > 1.0
    assert all(c['differs'] == 0 for c in out.values())
