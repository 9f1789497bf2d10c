"""Certified slice search: the bound it rests on, its rows against the kernel's on the bag."""

from pathlib import Path

from awp_ros_msgs.msg import ContactState
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from scipy.spatial import cKDTree
from sensor_msgs.msg import JointState

from awp_ros.bags.reader import read_bag
from awp_ros.evaluation.evaluator import compute_fws
from awp_ros.evaluation.result import AXES
from awp_ros.geometry import certified_search as CS, kernels as K
from awp_ros.geometry.linalg import cross3
from awp_ros.robot.config import load_parameters
from awp_ros.ros.pipeline import Pipeline
from cases import assert_same_polytope

BAG = Path(__file__).resolve().parents[2] / 'config' / 'hyq_gait.mcap'
TYPES = {'/joint_states': JointState, '/contacts': ContactState}


def _stream(params: dict):
    """Yield the pipeline's result of every joint state of the default bag."""
    config, base_dir = load_parameters('hyq', params)
    pipeline = Pipeline.from_parameters(config, base_dir=base_dir)
    for m in read_bag(str(BAG), topics=list(TYPES)):
        msg = deserialize_message(m.data, TYPES[m.topic])
        if m.topic == '/contacts':
            pipeline.on_contacts(msg)
            continue
        yield pipeline, pipeline.on_joint_state(msg).result


def _kernel_only(job: tuple) -> tuple:
    """Return ``compute_fws(*job)`` by the kernel's search alone, its directional margins too."""
    pattern, CS.PATTERN = CS.PATTERN, None
    try:
        return compute_fws(*job[:5], True)
    finally:
        CS.PATTERN = pattern


def test_a_check_value_moves_by_at_most_the_bound_of_its_vectors_changes():
    """
    Bound (1): ``|det[r1; r2; r3; s]' - det[...]| <= |r1| |r2| |r3| |s| (prod (1 + eps) - 1)``.

    Random 4-vectors and perturbations of relative sizes ``eps_i`` (up to 0.3), determinants
    by LU (numpy): the bound holds, and comes within a factor 3 of the change in some trials
    (it is not vacuous).
    """
    rng = np.random.default_rng(4)
    ratios = []
    for _ in range(20000):
        R = rng.normal(size=(4, 4)) * rng.uniform(0.01, 10.0, size=(4, 1))
        eps = rng.uniform(0.0, 0.3, size=4) * (rng.uniform(size=4) < 0.7)
        E = rng.normal(size=(4, 4))
        E *= (eps * np.linalg.norm(R, axis=1) / np.linalg.norm(E, axis=1))[:, None]
        change = abs(np.linalg.det(R + E) - np.linalg.det(R))
        bound = np.prod(np.linalg.norm(R, axis=1)) * (np.prod(1.0 + eps) - 1.0)
        assert change <= bound * (1 + 1e-12) + 1e-12 * np.prod(np.linalg.norm(R, axis=1))
        if bound > 0:
            ratios.append(change / bound)
    assert max(ratios) > 1 / 3


def test_every_fws_of_the_default_bag_equals_a_full_recomputation():
    """
    With the FWS every cycle, each four-leg FWS (certified search) is the full recomputation's.

    The pipeline replays the default bag with ``fws_rate_hz: 0``; every four-leg joint state's
    FWS is recomputed by the kernel's search alone. The H-reps must have the same rows (each
    row of one within 1e-9 of a row of the other, offsets in kN; else the same set by LPs)
    and margins, the directional margins (the evaluation's LPs) the recomputed H-rep's; most
    four-leg searches must have been certified (this thread's earlier streams forgotten).
    """
    CS.reset()
    before = CS.statistics()
    states = 0
    for pipeline, r in _stream({'fws_rate_hz': 0.0}):
        if r is None or len(r.stance) != 4:
            continue
        states += 1
        S, margin, plus, minus, _ = _kernel_only(pipeline.evaluator.fws_job(r))
        mine = r.fws.polytope
        rows = [np.column_stack([P.A, P.b / 1e3]) for P in (mine, S)]
        gaps = [cKDTree(rows[1 - i]).query(rows[i])[0].max() for i in (0, 1)]
        if max(gaps) > 1e-9:
            assert_same_polytope(mine, S, share=0.01)
        assert abs(r.fws.margin - margin.margin) <= 1e-9 * (1.0 + abs(margin.margin))
        got = np.array([r.fws.directional[axis] for axis in AXES])
        assert np.allclose(got, np.array([plus, minus]).T, rtol=1e-7, atol=1e-5, equal_nan=True)
    after = CS.statistics()
    assert states == 2800
    assert after['certified'] - before['certified'] > 0.8 * states
    assert after['tested'] - before['tested'] < 0.2 * (after['choices'] - before['choices'])


def _recorded_searches(dims: tuple, count: int, start: int = 100) -> list:
    """Return the arguments of the ``dims`` searches of consecutive four-leg bag states."""
    calls, found = [], []
    original = K.slice_facet_normal_parts

    def spy(*args):
        if tuple(args[3]) == dims:
            calls.append(args)
        return original(*args)

    pattern, CS.PATTERN = CS.PATTERN, None
    K.slice_facet_normal_parts = spy
    try:
        for _, r in _stream({'fws_rate_hz': 0.0}):
            if r is not None and len(r.stance) == 4 and len(calls) == 1:
                found.append(calls[0])
            calls.clear()
            if len(found) == start + count:
                break
    finally:
        K.slice_facet_normal_parts = original
        CS.PATTERN = pattern
    return found[start:]


def test_a_search_that_trusts_the_reference_misses_facets_the_certificate_keeps():
    """
    Thirty joint states after a reference the certificates give the kernel's rows; eta 0 does not.

    With ``eta = 0`` the reference's verdicts are taken as they are, and facets that appeared
    or vanished since are missed. The certificates leave fewer than a fifth of the choices to
    be tested in full.
    """
    searches = _recorded_searches(CS.PATTERN, 31)

    def vectors(args):
        F, E = args[2][2], args[2][1]
        An = np.ascontiguousarray(cross3(F[0][:, :, 0], F[0][:, :, 1]))
        return An, CS.slice_vectors(args[0], An, *F[1:], *E, args[4], args[5])

    first, args = searches[0], searches[-1]
    counts = (first[2][2][3], first[2][1][3])
    ref = CS.Reference(b'', vectors(first)[1], counts, first[4], first[5])
    An, now = vectors(args)
    plus, minus, choices = K.slice_facet_normal_parts(*args)
    assert choices == ref.choices
    outcomes = []
    for scale in (1.0, 0.0):
        out_pos, out_neg = np.empty((20000, 6)), np.empty((20000, 6))
        npos, nneg, tested, _, _ = CS.certified_search(
            *now, ref.SA, ref.W, ref.S, ref.worst, ref.rest, ref.band, ref.node_best, args[4],
            *counts, args[0], An, args[1], args[5], args[6], scale, out_pos, out_neg)
        same = all(a.shape == b.shape and cKDTree(a).query(b)[0].max() <= 1e-12
                   and cKDTree(b).query(a)[0].max() <= 1e-12
                   for a, b in ((out_pos[:npos], plus), (out_neg[:nneg], minus)))
        outcomes.append(same)
        if scale == 1.0:
            assert tested < 0.2 * choices
    assert outcomes == [True, False]


def test_unrelated_postures_build_no_reference_and_get_the_kernels_rows():
    """Random postures (not a stream): every search is the kernel's, no reference is built."""
    from awp_ros.evaluation.evaluator import FeasibilityEvaluator
    evaluator = FeasibilityEvaluator('hyq')
    rng = np.random.default_rng(7)
    CS.reset()
    before = CS.statistics()
    base = evaluator.standing_state()
    names = list(base.joint_positions)
    q0 = np.array([base.joint_positions[n] for n in names])
    for q in q0 + rng.uniform(-0.1, 0.1, size=(6, q0.size)):
        base.joint_positions = dict(zip(names, q.tolist()))
        evaluator.evaluate(base, fws=True)
    after = CS.statistics()
    assert after['kernel'] - before['kernel'] == 6
    assert after['references'] == before['references']
    assert after['certified'] == before['certified']


@pytest.mark.parametrize('coherent_step', [CS.COHERENT_STEP, 1.0])
def test_a_stream_too_rough_for_references_backs_off_to_the_kernel(monkeypatch, coherent_step):
    """
    A random walk renewing its references too often gets few: cool-downs of 16, 32, 64 searches.

    ``awp_bench``'s walk moves every joint at 2 rad/s in a random direction: the searches are
    the kernel's (a reference would cost more than it saves). Its consecutive searches are not
    close; with every pair taken as close (``COHERENT_STEP`` 1) the references are built and
    renewed after one search each, and the back-off is the same. Without the back-off, 120
    searches would build tens of references.
    """
    from awp_ros.cli.bench import stream_times
    from awp_ros.evaluation.evaluator import FeasibilityEvaluator
    monkeypatch.setattr(CS, 'COHERENT_STEP', coherent_step)
    evaluator = FeasibilityEvaluator('hyq')
    CS.reset()
    before = CS.statistics()
    stream_times(evaluator, 120)
    after = CS.statistics()
    assert after['kernel'] - before['kernel'] + after['certified'] - before['certified'] == 120
    assert after['references'] - before['references'] <= 4
    assert after['kernel'] - before['kernel'] >= 110


def test_the_node_s_first_certified_search_needs_no_compilation():
    """
    ``compile_all`` compiles every signature a stream calls: none is added along the bag.

    A read-only hull basis (as the FWS passes it) was another numba type, compiled or loaded
    at the first certified search, inside a control cycle (~10 ms, or seconds uncached).
    """
    CS.compile_all()
    kernels = (CS.slice_vectors, CS.choice_scores, CS.wall_change, CS.certified_search)
    CS.reset()
    before = [len(k.signatures) for k in kernels]
    for n, (_, r) in enumerate(_stream({'fws_rate_hz': 0.0})):
        if n == 700:
            break
    assert CS.statistics()['certified'] > 0
    assert [len(k.signatures) for k in kernels] == before
