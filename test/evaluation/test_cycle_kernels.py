"""
The per-cycle sets and regions in one compiled call each equal the stage-by-stage code.

:meth:`FeasibilityEvaluator._cycle_sets` (``kernels.cycle_sets``, then
``kernels.cycle_regions``) runs the kernels of the stage-by-stage code
(:meth:`FeasibilityEvaluator._sets` and the regions' functions) on the same inputs without
Python between them: every output of ``evaluate`` must be the same, bit for bit, on every
joint state of the default bag and on random postures with wrenches inside and outside the
sets. The stage-by-stage code is itself checked against independent methods (qhull, LPs on the
definitions) in the tests of each set.
"""

import hashlib

from awp_ros_msgs.msg import ContactState
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState

from awp_ros.bags.reader import read_bag
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.geometry import kernels
from awp_ros.robot.config import load_parameters
from awp_ros.ros.pipeline import Pipeline
from awp_ros.wrench.contact_wrench_cone import reset_reuse

pytestmark = pytest.mark.skipif(not kernels.ENABLED, reason='the compiled kernels are off')


def digest(r) -> str:
    """Return a hash of everything ``evaluate`` outputs (arrays by their bytes)."""
    h = hashlib.sha256()

    def add(x) -> None:
        if isinstance(x, np.ndarray):
            h.update(str((x.shape, x.dtype)).encode())
            h.update(np.ascontiguousarray(x).tobytes())
        else:
            h.update(repr(x).encode())
    for x in (r.stance, r.warnings, r.mass, r.com, r.wrench, r.feasible,
              r.capture_margin_per_cycle):
        add(x)
    for s in (r.awp, r.fwp):
        for x in (s.margin, s.margin_in_hull, s.normal, s.dimension, s.affine_residual,
                  s.feasible, s.polytope.A, s.polytope.b, s.polytope.hull_origin,
                  s.polytope.hull_basis, sorted(s.polytope.meta)):
            add(x)
    add(r.fwp.polytope.meta['degenerate'])
    add(r.fwp.polytope.meta['source'])
    add(r.cwc.A)
    for region in (r.support_region, r.feasible_region_per_cycle, r.fwp.region):
        if region is None:
            add(None)
            continue
        for x in (region.dimension, region.vertices, region.A, region.b, region.margin,
                  region.meta.get('rows')):
            add(x)
    for leg in r.legs.values():
        F = leg.force_polytope
        for x in (F.A, F.b, F.vertices, F.meta['sigma_ratio'], leg.singular,
                  leg.near_singular, leg.friction_polytope.A, leg.friction_polytope.b):
            add(x)
    return h.hexdigest()


def run(evaluator, calls, *, fused: bool, monkeypatch) -> tuple[list[str], int]:
    """Return the digests of evaluating ``calls`` in order, and how often the call was fused."""
    used = [0]
    real = FeasibilityEvaluator._cycle_sets

    def counted(self, *args):
        out = real(self, *args) if fused else None
        used[0] += out is not None
        return out
    monkeypatch.setattr(FeasibilityEvaluator, '_cycle_sets', counted)
    reset_reuse()             # both runs see the same history of reused cone facets
    out = [digest(evaluator.evaluate(state, **{**kw, 'fws': False})) for state, kw in calls]
    monkeypatch.setattr(FeasibilityEvaluator, '_cycle_sets', real)
    return out, used[0]


def bag_calls(repo) -> tuple[FeasibilityEvaluator, list]:
    """Return the pipeline's evaluator and its evaluate calls over the default bag."""
    params, base_dir = load_parameters('hyq')
    pipeline = Pipeline.from_parameters(params, base_dir=base_dir)
    evaluator = pipeline.evaluator
    calls = []
    real = evaluator.evaluate

    def record(state, **kw):
        calls.append((state, kw))
        return real(state, **kw)
    evaluator.evaluate = record
    types = {'/joint_states': JointState, '/contacts': ContactState}
    for m in read_bag(str(repo / 'config' / 'hyq_gait.mcap'), topics=list(types)):
        msg = deserialize_message(m.data, types[m.topic])
        if m.topic == '/contacts':
            pipeline.on_contacts(msg)
        else:
            pipeline.on_joint_state(msg)
    del evaluator.evaluate
    return evaluator, calls


def test_every_joint_state_of_the_default_bag_is_evaluated_as_stage_by_stage(repo, monkeypatch):
    evaluator, calls = bag_calls(repo)
    assert len(calls) > 5000
    fused, used = run(evaluator, calls, fused=True, monkeypatch=monkeypatch)
    general, none = run(evaluator, calls, fused=False, monkeypatch=monkeypatch)
    four = sum(len(c[0].stance or evaluator.feet) >= 3 for c in calls)
    assert none == 0 and used == four > 1000          # every state of 3+ legs took it
    assert fused == general


def test_random_postures_and_wrenches_in_and_out_of_the_sets(monkeypatch):
    evaluator = FeasibilityEvaluator('hyq')
    base = evaluator.standing_state()
    names = list(base.joint_positions)
    q0 = np.array([base.joint_positions[n] for n in names])
    rng = np.random.default_rng(7)
    calls = []
    for i, q in enumerate(q0 + rng.uniform(-0.3, 0.3, size=(120, q0.size))):
        state = evaluator.standing_state(stance=list(evaluator.feet[:3 + i % 2]))
        state.joint_positions = dict(zip(names, q.tolist()))
        state.friction_coefficient = float(rng.uniform(0.3, 1.0))
        # The gravito-inertial wrench, then wrenches around it: some outside the AWP and
        # the FWP (negative margins, the least-distance code), some without vertical force.
        for wrench in (None, rng.normal(0.0, [300, 300, 900, 150, 150, 60]) + [0, 0, 850, 0, 0, 0],
                       np.array([40.0, -30.0, 4000.0, 10.0, -50.0, 5.0]),
                       np.array([20.0, 10.0, 0.0, 1.0, 2.0, 0.0])):
            calls.append((state, {'wrench': wrench}))
    fused, used = run(evaluator, calls, fused=True, monkeypatch=monkeypatch)
    general, _ = run(evaluator, calls, fused=False, monkeypatch=monkeypatch)
    assert used > 0.8 * len(calls)
    assert fused == general
    infeasible = [evaluator.evaluate(s, fws=False, **kw).fwp.margin < 0 for s, kw in calls]
    assert 0 < sum(infeasible) < len(calls)


def test_singular_and_near_singular_legs_take_the_stage_by_stage_code(monkeypatch):
    # A singular leg's polytope is flat (status 1); a near-singular leg's long generators
    # leave the AWP's full rank uncertified (status 2): the general code decides both.
    evaluator = FeasibilityEvaluator('hyq')
    for knee, fused_calls, warning in ((0.0, 0, "'lf_foot' is singular"),
                                       (-0.01, 0, "'lf_foot' is near-singular"),
                                       (-0.5, 1, None)):
        state = evaluator.standing_state()
        state.joint_positions['lf_kfe_joint'] = knee           # a stretched knee
        fused, used = run(evaluator, [(state, {})], fused=True, monkeypatch=monkeypatch)
        general, _ = run(evaluator, [(state, {})], fused=False, monkeypatch=monkeypatch)
        assert used == fused_calls and fused == general
        warnings = evaluator.evaluate(state, fws=False).warnings
        assert any(warning in w for w in warnings) if warning else \
            not any('singular' in w for w in warnings)


def test_the_fws_of_every_two_leg_joint_state_of_the_default_bag_is_numpys(repo, monkeypatch):
    """
    Two stance legs (every trot phase): the flat-pair search gives numpy's polytope.

    The default bag's trot keeps level feet on a rectangle, the degenerate case (directions
    shared by two legs' faces); each FWS of a two-leg joint state, with the compiled
    ``flat_pair_facet_normals``, equals the numpy grid search's on the same legs (rows
    matched or implied by an LP, :func:`cases.assert_same_polytope`).
    """
    from cases import assert_same_polytope
    from awp_ros.wrench.feasible_wrench_set import feasible_wrench_set
    evaluator, calls = bag_calls(repo)
    jobs = []
    for state, kw in calls:
        result = evaluator.evaluate(state, **{**kw, 'fws': False})
        if len(result.stance) == 2:
            jobs.append(evaluator.fws_job(result)[:2])
    assert len(jobs) > 1000
    fast = [feasible_wrench_set(*job) for job in jobs]
    monkeypatch.setattr(kernels, 'ENABLED', False)
    for S, job in zip(fast, jobs):
        ref = feasible_wrench_set(*job)
        assert S.dimension == ref.dimension == 5
        assert_same_polytope(S, ref)
