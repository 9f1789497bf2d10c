"""
``awp_bench``: time the feasibility pipeline stage by stage over random standing postures.

Each sample perturbs every joint of the config's standing posture by a uniform offset in
``[-spread, spread]`` [rad] (seeded) with every foot in stance (or ``--stance``). Two passes
over the same states, as the node runs them (the per-cycle evaluation at the joint-state
rate, the FWS apart, possibly at a lower rate):

1. the per-cycle evaluation, ``evaluate(state, fws=False)``: its stages (``validate``,
   ``model``, ``sets``, ``margins``, ``regions``: :data:`~awp_ros.evaluation.evaluator.STAGES`)
   and ``total``;
2. the FWS of each evaluated state (skipped with ``--no-fws``): ``fws_friction``, the
   friction-bounded leg polytopes both FWS methods start from (the per-cycle evaluation
   computes them only on use), then
   :meth:`~awp_ros.evaluation.evaluator.FeasibilityEvaluator.add_fws` (``fws``: the exact H-rep,
   ``fws_directional``: the 12 directional margins on it, ``fws_margin``: the Euclidean
   margin on it), and ``fws_query_lp``: membership and the 12 directional margins by
   :func:`~awp_ros.wrench.fws_queries.lp_directional_margins` (exact LPs, no H-rep);
   ``fws_outside``: the FWS's signed margin of a wrench outside it, as every cycle gives it with
   three or more stance legs (the evaluation's ``fws_distance``: Wolfe's algorithm on the legs'
   points, no H-rep), for the state's wrench moved :data:`OUTSIDE_N` beyond the FWS along
   +fz, and ``fws_outside_ldp`` the same margin by the least-distance program on the FWS's
   H-rep (given the H-rep); JSON ``fws_outside_vs_hrep`` (``fws_margin_ms`` over
   ``fws_outside_ms``: what the margin costs per cycle against through the H-rep) and
   ``fws_outside_max_error`` (the largest difference of the two margins [N, N.m]);
   ``regions_baseline``: the feasible and the support region by Bretl & Lall's iterative
   projection with LPs
   (:func:`~awp_ros.geometry.iterative_projection.iterative_projection`, as jet-leg does;
   area tolerance 1e-6 m^2) on the first ``--baseline-samples`` of the same states.

The table gives the median, 90th percentile and maximum [ms] of each; the last line is one
JSON object with the medians: ``total_ms`` (the per-cycle evaluation without the FWS),
``fws_margin_ms`` (friction polytopes + FWS H-rep + Euclidean margin: the exact FWS margin),
``fws_query_lp_ms`` (friction polytopes + the LP queries), ``fws_directional_lp_ms`` (the
FWS's directional margins that every cycle gives with three or more stance legs, by LPs on
the feasible region's points, timed apart from ``total``),
and ``<stage>_ms`` for every stage, the FWS's margin step alone as ``fws_margin_step_ms``;
``regions_ms`` (``com_regions`` of pass 1: the two CoM regions inside the per-cycle
evaluation, the feasible region by exact projection,
:func:`~awp_ros.wrench.com_region.feasible_region`, and the support region as the CWC's
exact slice, :func:`~awp_ros.wrench.com_region.com_region`), ``regions_baseline_ms`` and
``regions_speedup`` (their ratio); the whole per-cycle ``regions`` stage (support,
feasible and FWP regions, the capture point) is ``regions_stage_ms``. ``batch_states_per_s``:
states per second of :meth:`~awp_ros.evaluation.evaluator.FeasibilityEvaluator.evaluate_many`
on the same postures (per-cycle sets, no FWS), ``loop_states_per_s`` the same by a loop of
``evaluate``.
``estimation_ms``: the motion estimation of one joint state as the pipeline runs it with
``use_imu`` (:func:`estimation_times`), not included in ``total``.

A third pass follows a stream of close postures, as the node's consecutive joint states are
(:func:`stream_times`): ``total_stream_ms`` is its per-cycle evaluation (what is reused
between cycles, reused) and ``fws_per_cycle_ms`` the FWS added to every cycle (what
``fws_rate_hz: 0`` costs). The baselines: qhull's hull of the AWP's and the FWS's vertex
sums on ``--qhull-samples`` postures (:func:`qhull_baselines`), ``awp_qhull_ms`` and
``fws_qhull_ms``, and the ratios ``total_vs_qhull`` (AWP hull / per-cycle ``total``) and
``fws_vs_qhull`` (FWS hull / ``fws_per_cycle_ms``), measured in the same run.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
import json
import sys
import time

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from awp_ros.errors import AwpError
from awp_ros.estimation.motion import MotionEstimator
from awp_ros.evaluation.evaluator import compute_fws, FeasibilityEvaluator, STAGES
from awp_ros.geometry.face_lattice import polytope_faces
from awp_ros.geometry.iterative_projection import iterative_projection, torque_halfspaces
from awp_ros.geometry.margin import directional_margins, polytope_margin
from awp_ros.geometry.minkowski_facets import facet_normals
from awp_ros.robot.state import resolve_state
from awp_ros.runtime import tune_process
from awp_ros.wrench.com_region import com_region
from awp_ros.wrench.feasible_wrench_set import lifted_hull, minkowski_sum_of_lifts
from awp_ros.wrench.friction_polytope import friction_polytopes, friction_rows
from awp_ros.wrench.fws_queries import lp_directional_margins, two_leg_contains

__all__ = ['main', 'run_benchmark']

PROG = 'awp_bench'
FWS_STAGES = ('fws_friction', 'fws', 'fws_directional', 'fws_margin', 'fws_query_lp',
              'fws_outside', 'fws_outside_ldp')
#: How far beyond the FWS's boundary along +fz the outside wrench of pass 2 is [N].
OUTSIDE_N = 50.0


def run_benchmark(evaluator: FeasibilityEvaluator, samples: int, *, seed: int = 0,
                  spread: float = 0.1, warmup: int = 5,
                  stance: tuple[str, ...] | None = None,
                  fws: bool = True, baseline_samples: int = 20) -> dict[str, np.ndarray]:
    """
    Return the per-stage timings [ms] of ``samples`` random standing postures.

    :param evaluator: the evaluator (its config needs a standing posture).
    :param samples: number of timed evaluations.
    :param seed: seed of the posture perturbations.
    :param spread: half-width of the uniform joint offsets [rad].
    :param warmup: untimed evaluations first (caches, allocations).
    :param stance: stance feet (default all).
    :param fws: also time the FWS stages, the LP queries and the CoM regions, in a second
        pass.
    :param baseline_samples: states (the first ones) on which the iterative-projection
        baseline of the regions is timed.
    :return: stage name -> array (samples,) [ms] (:data:`~awp_ros.evaluation.evaluator.STAGES`,
        ``total``, ``fws_directional_lp`` and, with ``fws``, :data:`FWS_STAGES`), plus
        ``feasible`` (bool array:
        ``result.feasible``, ``w`` in the FWS: the FWS's verdict when computed, else that of
        the per-cycle feasible region with three or more legs, else the FWP's).
    """
    rng = np.random.default_rng(seed)
    base = evaluator.standing_state(stance=stance)
    names = list(base.joint_positions)
    q0 = np.array([base.joint_positions[n] for n in names])
    postures = q0 + rng.uniform(-spread, spread, size=(warmup + samples, q0.size))
    keys = list(STAGES) + ['com_regions', 'total', 'fws_directional_lp'] + \
        (list(FWS_STAGES) if fws else [])
    times = {name: np.zeros(samples) for name in keys}
    if fws:
        times['regions_baseline'] = np.zeros(min(samples, max(baseline_samples, 0)))
    feasible = np.zeros(samples, dtype=bool)
    errors = np.full(samples, np.nan)
    # Pass 1, the per-cycle evaluation. Results are dropped as in the node's loop (keeping
    # them all would grow the heap and put page faults in the timings).
    for i, q in enumerate(postures):
        base.joint_positions = dict(zip(names, q.tolist()))
        result = evaluator.evaluate(base, fws=False)
        if i >= warmup:
            for name in STAGES + ('com_regions', 'total', 'fws_directional_lp'):
                times[name][i - warmup] = result.timings_ms[name]
            feasible[i - warmup] = result.feasible
    # Pass 2, the same states re-evaluated (untimed), then the LP queries (as a per-cycle
    # step would run them) and the FWS.
    for i, q in enumerate(postures if fws else ()):
        base.joint_positions = dict(zip(names, q.tolist()))
        result = evaluator.evaluate(base, fws=False)
        t0 = time.perf_counter()
        for leg in result.legs.values():
            leg.friction_polytope  # noqa: B018 -- computed on first use: time it here
        friction_ms = 1e3 * (time.perf_counter() - t0)
        lp_ms = _lp_query(result)
        evaluator.add_fws(result)
        outside = _outside_times(evaluator, base, result)
        if i >= warmup:
            for name in FWS_STAGES[1:4]:
                times[name][i - warmup] = result.timings_ms[name]
            times['fws_friction'][i - warmup] = friction_ms
            times['fws_query_lp'][i - warmup] = lp_ms
            times['fws_outside'][i - warmup], times['fws_outside_ldp'][i - warmup], \
                errors[i - warmup] = outside
            if i - warmup < times['regions_baseline'].size:
                times['regions_baseline'][i - warmup] = _regions_baseline(evaluator, base,
                                                                          result)
            feasible[i - warmup] = result.feasible
    times['estimation'] = estimation_times(evaluator, postures, seed=seed)[warmup:]
    times['feasible'] = feasible
    if fws:
        times['outside_error'] = errors
    return times


def _outside_times(evaluator: FeasibilityEvaluator, state, result) -> tuple[float, float, float]:
    """
    Return the FWS's margin of a wrench outside it: per cycle and on the H-rep, and their gap.

    The wrench is ``result``'s moved :data:`OUTSIDE_N` beyond the FWS along +fz (past its
    directional margin ``fz`` plus: outside, the FWS being convex). ``(per-cycle ms``, the
    evaluation's ``fws_distance`` (Wolfe's algorithm on the legs' points),
    ``least-distance program on the H-rep ms``, ``|difference of the margins|`` [N, N.m]``)``;
    NaN without the directional margin or with fewer than three stance legs.
    """
    plus = result.fws.directional['fz'][0] if result.fws.directional else np.nan
    if not np.isfinite(plus) or len(result.stance) < 3:
        return np.nan, np.nan, np.nan
    w = result.wrench + (plus + OUTSIDE_N) * np.eye(6)[2]
    per_cycle = evaluator.evaluate(state, fws=False, wrench=w)
    t0 = time.perf_counter()
    reference = polytope_margin(result.fws.polytope, w, feasibility_tol=evaluator.feasibility_tol,
                                hull_tol=evaluator.hull_tol)
    ldp_ms = 1e3 * (time.perf_counter() - t0)
    m = per_cycle.fws_margin_per_cycle
    error = np.nan if m is None else abs(m.margin - reference.margin)
    return per_cycle.timings_ms['fws_distance'], ldp_ms, error


def _lp_query(result) -> float:
    """Return the time [ms] of the LP membership and directional margins of ``result``."""
    p = np.array([leg.position for leg in result.legs.values()]).reshape(-1, 3)
    V = [leg.friction_polytope.vertices for leg in result.legs.values()]
    t0 = time.perf_counter()
    lp_directional_margins(p, V, result.wrench)
    return 1e3 * (time.perf_counter() - t0)


def _regions_baseline(evaluator: FeasibilityEvaluator, state, result) -> float:
    """Return the time [ms] of both regions by iterative projection with LPs (baseline)."""
    cfg, model = evaluator.config, evaluator.model
    s = resolve_state(state, model.joint_names, cfg.feet, default_normal=cfg.unit_normal,
                      default_mu=cfg.friction_coefficient)
    kin = model.kinematics(s.q, s.stance, quaternion=s.quaternion, v=s.v, a=s.a)
    rows = friction_rows(s.normals, s.mus, cfg.pyramid_sides)
    both, friction = [], []
    for k, foot in enumerate(s.stance):
        H, g = torque_halfspaces(kin.J[k], kin.bias[k], model.legs[foot].tau_min,
                                 model.legs[foot].tau_max)
        zero = np.zeros(len(rows[k]))
        both.append((np.vstack([H, rows[k]]), np.concatenate([g, zero])))
        friction.append((rows[k], zero))
    f, m = result.wrench[:3], result.wrench[3:]
    t0 = time.perf_counter()
    for halfspaces in (both, friction):
        iterative_projection(kin.p_foot__com, halfspaces, f, m, area_tol=1e-6)
    return 1e3 * (time.perf_counter() - t0)


def stream_times(evaluator: FeasibilityEvaluator, samples: int, *, seed: int = 0,
                 spread: float = 0.1, step: float = 0.002,
                 stance: tuple[str, ...] | None = None, fws: bool = True
                 ) -> dict[str, np.ndarray]:
    """
    Return per-cycle timings [ms] along a stream of postures, as the node evaluates them.

    The postures follow a random walk from the standing posture (each joint moves by a
    uniform step in ``[-step, step]`` [rad] per cycle, reflected at ``spread``: 2 rad/s at
    1 kHz), so consecutive states are close, as consecutive joint states are: what the
    per-cycle evaluation reuses between cycles (the contact wrench cone's facets) is reused.
    ``stream_total``: ``evaluate(state, fws=False)``; ``stream_fws`` (with ``fws``): the FWS
    added to every cycle (:meth:`~awp_ros.evaluation.evaluator.FeasibilityEvaluator.add_fws`:
    H-rep, directional and Euclidean margins, feasible region), what ``fws_rate_hz: 0``
    costs per cycle, timed in a second walk over the same postures.
    """
    rng = np.random.default_rng(seed + 1)
    base = evaluator.standing_state(stance=stance)
    names = list(base.joint_positions)
    q0 = np.array([base.joint_positions[n] for n in names])
    offset = np.zeros_like(q0)
    walk = []
    for _ in range(samples):
        offset += rng.uniform(-step, step, size=q0.size)
        offset = np.where(np.abs(offset) > spread, np.sign(offset) * 2 * spread - offset, offset)
        walk.append(dict(zip(names, (q0 + offset).tolist())))
    out = {'stream_total': np.zeros(samples)}
    for i, q in enumerate(walk):
        base.joint_positions = q
        out['stream_total'][i] = evaluator.evaluate(base, fws=False).timings_ms['total']
    if fws:
        # A second walk: the FWS's ~4 ms between two cycles evicts the caches, so timing
        # both in one walk would time a cold per-cycle evaluation (~1.5x slower).
        out['stream_fws'] = np.zeros(samples)
        for i, q in enumerate(walk):
            base.joint_positions = q
            result = evaluator.evaluate(base, fws=False)
            t0 = time.perf_counter()
            evaluator.add_fws(result)
            out['stream_fws'][i] = 1e3 * (time.perf_counter() - t0)
    return out


def qhull_baselines(evaluator: FeasibilityEvaluator, samples: int, *, seed: int = 0,
                    spread: float = 0.1, stance: tuple[str, ...] | None = None
                    ) -> dict[str, np.ndarray]:
    """
    Return the time [ms] of qhull's hull of the AWP's and the FWS's vertex sums.

    The baseline an exact H-rep is measured against: ``scipy.spatial.ConvexHull`` of all
    sums of one lifted vertex per leg (8^4 = 4096 points in R^6 for the AWP of four
    parallelepipeds, about 11^4 for the FWS), on the first ``samples`` random postures of
    :func:`run_benchmark` (``awp_qhull``, ``fws_qhull``; NaN when qhull fails on the
    nearly degenerate sums, which it does on the FWS without option Q12).
    """
    rng = np.random.default_rng(seed)
    base = evaluator.standing_state(stance=stance)
    names = list(base.joint_positions)
    q0 = np.array([base.joint_positions[n] for n in names])
    out = {'awp_qhull': np.full(samples, np.nan), 'fws_qhull': np.full(samples, np.nan)}
    for i, q in enumerate(q0 + rng.uniform(-spread, spread, size=(samples, q0.size))):
        base.joint_positions = dict(zip(names, q.tolist()))
        result = evaluator.evaluate(base, fws=False)
        p = [leg.position for leg in result.legs.values()]
        for key, polytopes in (('awp', [leg.force_polytope for leg in result.legs.values()]),
                               ('fws', [leg.friction_polytope for leg in result.legs.values()])):
            points = np.zeros((1, 6))
            for pk, Q in zip(p, polytopes):
                lifted = np.hstack([Q.vertices, np.cross(pk, Q.vertices)])
                points = (points[:, None, :] + lifted[None, :, :]).reshape(-1, 6)
            t0 = time.perf_counter()
            try:
                ConvexHull(points, qhull_options='Qt Qx Q12')
            except QhullError:
                continue
            out[f'{key}_qhull'][i] = 1e3 * (time.perf_counter() - t0)
    return out


def kernel_ratios(evaluator: FeasibilityEvaluator, samples: int = 60, *, seed: int = 0,
                  spread: float = 0.1, repeats: int = 6) -> dict[str, tuple[float, float]]:
    """
    Return ``step -> (numpy ms, kernel ms)``: the compiled kernels against their reference.

    Over ``samples`` random postures (all feet in stance), each step runs on every posture
    with :data:`awp_ros.geometry.kernels.ENABLED` off, then on, ``repeats`` times interleaved
    in this process (medians): the force parallelepipeds, the AWP, the contact wrench cone
    with new feet every call (its facets searched) and along a stream (the feet moving 10 um
    per call: the last facets verified and reused), and the two CoM regions of the per-cycle
    stage (support region of the CWC, FWP region: the polygon step compiled); then the whole
    per-cycle evaluation (``evaluate(state, fws=False)``) of the same postures, and along a
    stream of close postures (:func:`stream_times`' walk), every kernel off, then on; then
    the FWS's steps: the friction-bounded leg polytopes (their vertex enumeration), the leg
    polytopes' faces, the facet search (the numpy reference's grid search against the
    compiled slice search, :mod:`awp_ros.geometry.minkowski_facets`), the 12 directional
    margins on the FWS (the ratio test), and the whole FWS with its margins
    (:func:`~awp_ros.evaluation.evaluator.compute_fws`) of the same postures; last the FWS's
    verdict of two of the legs (a diagonal pair) by its one-dimensional LP
    (:func:`~awp_ros.wrench.fws_queries.two_leg_contains`, the wrench on their hyperplane),
    and the FWS's 12 directional margins by LPs without its H-rep, every cycle's
    (:func:`~awp_ros.wrench.fws_queries.directional_margins_of_legs`, the compiled simplex)
    against HiGHS (:func:`~awp_ros.wrench.fws_queries.lp_directional_margins`).
    """
    from awp_ros.geometry import kernels
    from awp_ros.wrench import contact_wrench_cone as cwc
    from awp_ros.wrench.force_polytope import parallelepipeds
    from awp_ros.wrench.wrench_polytope import actuation_wrench_polytope, \
        feasible_wrench_polytope

    rng = np.random.default_rng(seed)
    base = evaluator.standing_state()
    names = list(base.joint_positions)
    q0 = np.array([base.joint_positions[n] for n in names])
    feet = tuple(evaluator.feet)
    lo, hi = evaluator._limits(feet)
    normals = np.tile(evaluator.config.unit_normal, (len(feet), 1))
    mus = np.full(len(feet), evaluator.config.friction_coefficient)
    cases = []
    postures = q0 + rng.uniform(-spread, spread, size=(samples, q0.size))
    for q in postures:
        kin = evaluator.model.kinematics(evaluator.model.joint_vector(dict(zip(names, q))), feet)
        pp = parallelepipeds(np.array(kin.J), np.array(kin.bias), lo, hi)
        awp = actuation_wrench_polytope(kin.p_foot__com, pp['center'], pp['generators'])
        cone = cwc.contact_wrench_cone(kin.p_foot__com, normals, mus)
        cases.append((kin.p_foot__com, np.array(kin.J), np.array(kin.bias), pp['center'],
                      pp['generators'], cone, feasible_wrench_polytope(awp, cone), kin.wrench))
    walk = q0 + np.cumsum(rng.uniform(-0.002, 0.002, size=(samples, q0.size)), axis=0)
    states = [[replace(base, joint_positions=dict(zip(names, q.tolist()))) for q in qs]
              for qs in (postures, walk)]
    results = [evaluator.evaluate(state, fws=False) for state in states[0]]
    jobs = [evaluator.fws_job(result) for result in results]
    searches = [_facet_search_case(job) for job in jobs]
    forces = [[leg.force_polytope for leg in result.legs.values()] for result in results]
    rows = evaluator._friction_rows(normals, mus)
    fws_sets = [compute_fws(*job)[0] for job in jobs]
    two_legs = [_two_leg_case(result, (feet[0], feet[-1]), rows[[0, -1]]) for result in results]
    steps = {
        'force parallelepipeds': lambda c, i: parallelepipeds(c[1], c[2], lo, hi),
        'AWP zonotope': lambda c, i: actuation_wrench_polytope(c[0], c[3], c[4]),
        'CWC, new feet every call': lambda c, i: cwc.contact_wrench_cone(c[0], normals, mus),
        'CWC along a stream': lambda c, i: cwc.contact_wrench_cone(cases[0][0] + 1e-5 * i,
                                                                   normals, mus),
        'support + FWP regions': lambda c, i: (com_region(c[5], c[7][:3], c[7][3:]),
                                               com_region(c[6], c[7][:3], c[7][3:])),
        'per-cycle evaluation': lambda c, i: evaluator.evaluate(states[0][i], fws=False),
        'per-cycle evaluation, stream': lambda c, i: evaluator.evaluate(states[1][i],
                                                                        fws=False),
        'friction-bounded polytopes': lambda c, i: friction_polytopes(forces[i], rows),
        'FWS leg faces': lambda c, i: [polytope_faces(Q.vertices, (Q.A, Q.b))
                                       for Q in jobs[i][1]],
        'FWS facet search': lambda c, i: facet_normals(*searches[i][:5], feet=searches[i][5],
                                                       basis=searches[i][6]),
        'FWS directional margins': lambda c, i: directional_margins(fws_sets[i], jobs[i][2]),
        'FWS with margins': lambda c, i: compute_fws(*jobs[i]),
        'two-leg FWS verdict (LP)': lambda c, i: two_leg_contains(
            *two_legs[i], hull_tol=evaluator.hull_tol, feasibility_tol=evaluator.feasibility_tol),
        'FWS directional margins (LPs)': lambda c, i: evaluator.directional_at(
            list(results[i].legs.values()), jobs[i][2]) if kernels.ENABLED else
        lp_directional_margins(jobs[i][0], [Q.vertices for Q in jobs[i][1]], jobs[i][2]),
    }
    times = {name: ([], []) for name in steps}
    enabled = kernels.ENABLED
    try:
        for _ in range(repeats):
            for on in (False, True):
                kernels.ENABLED = on and enabled
                for name, step in steps.items():
                    cwc.reset_reuse()
                    t0 = time.perf_counter()
                    for i, c in enumerate(cases):
                        step(c, i)
                    times[name][on].append(1e3 * (time.perf_counter() - t0) / len(cases))
    finally:
        kernels.ENABLED = enabled
    return {name: (float(np.median(a)), float(np.median(b))) for name, (a, b) in times.items()}


def _two_leg_case(result, feet: tuple[str, str], rows: np.ndarray) -> tuple:
    """
    Return :func:`two_leg_contains`'s arguments for two legs of an evaluated posture.

    The wrench is the posture's, projected on the two legs' hyperplane (a wrench off it is
    answered before the LP).
    """
    from awp_ros.geometry import kernels
    legs = [result.legs[f] for f in feet]
    p = np.array([leg.position for leg in legs])
    nu = kernels.pair_hyperplane(p)[0]                   # unit normal of their hyperplane
    w = result.wrench - (nu @ result.wrench) * nu
    return (p, np.array([leg.force_polytope.A for leg in legs]),
            np.array([leg.force_polytope.b for leg in legs]), rows, w)


def _facet_search_case(job: tuple) -> tuple:
    """Return the arguments of the FWS's facet search (faces, lifts, tolerances, feet, U)."""
    positions, frictions = np.asarray(job[0]), job[1]
    tol = minkowski_sum_of_lifts.__kwdefaults__          # the FWS's own tolerances
    faces = [polytope_faces(Q.vertices, (Q.A, Q.b), rank_tol=tol['rank_tol'],
                            plane_tol=tol['plane_tol']) for Q in frictions]
    _, _, U, M = lifted_hull(positions, faces, rank_tol=tol['rank_tol'])
    return faces, M, U.shape[1], tol['cone_tol'], tol['normal_tol'], positions, U


def batch_rates(evaluator: FeasibilityEvaluator, samples: int, *, seed: int = 0,
                spread: float = 0.1, stance: tuple[str, ...] | None = None
                ) -> tuple[float, float]:
    """
    Return the states/s of ``evaluate_many`` and of a loop of ``evaluate`` (no FWS).

    Over the ``samples`` postures of :func:`run_benchmark` (same seed and spread), each
    timed once after an untimed run of both.
    """
    rng = np.random.default_rng(seed)
    base = evaluator.standing_state(stance=stance)
    names = list(base.joint_positions)
    q0 = np.array([base.joint_positions[n] for n in names])
    states = [replace(base, joint_positions=dict(zip(names, q.tolist())))
              for q in q0 + rng.uniform(-spread, spread, size=(samples, q0.size))]
    rates = []
    for run in (lambda: evaluator.evaluate_many(states),
                lambda: [evaluator.evaluate(s, fws=False) for s in states]):
        run()
        t0 = time.perf_counter()
        run()
        rates.append(samples / (time.perf_counter() - t0))
    return rates[0], rates[1]


def estimation_times(evaluator: FeasibilityEvaluator, postures: np.ndarray, *,
                     seed: int = 0, rate_hz: float = 500.0) -> np.ndarray:
    """
    Return the time [ms] of the motion estimation of each posture, one joint state each.

    What the pipeline adds per joint state with ``use_imu``: an IMU reading (synthetic: in
    the root link's frame, level, at rest with gyro and accelerometer noise) into
    :meth:`~awp_ros.estimation.motion.MotionEstimator.add_imu`, the joint state's positions
    and (random) velocities from name maps into
    :meth:`~awp_ros.estimation.motion.MotionEstimator.add_joints`, and the estimate's motion
    fields into the state; stamps ``1 / rate_hz`` apart.
    """
    model = evaluator.model
    rng = np.random.default_rng(seed)
    names = model.joint_names
    est = MotionEstimator(model, imu_frame=model.root_link)
    state = evaluator.standing_state()
    gyro = rng.normal(0.0, 0.01, size=(len(postures), 3))
    accel = rng.normal(0.0, 0.05, size=(len(postures), 3)) + (0.0, 0.0, 9.81)
    velocities = rng.normal(0.0, 0.5, size=postures.shape)
    step = int(round(1e9 / rate_hz))
    out = np.zeros(len(postures))
    for i, q in enumerate(postures):
        state.joint_positions = dict(zip(names, q.tolist()))
        state.joint_velocities = dict(zip(names, velocities[i].tolist()))
        stamp = i * step
        t0 = time.perf_counter()
        est.add_imu(stamp, (0.0, 0.0, 0.0, 1.0), gyro[i], accel[i])
        e = est.add_joints(stamp, model.joint_vector(state.joint_positions),
                           model.joint_vector(state.joint_velocities))
        fields = e.state_fields()
        state.base_orientation = e.base_orientation
        state.base_twist = fields['base_twist']
        state.base_acceleration = fields['base_acceleration']
        state.joint_velocities = fields['joint_velocities']
        state.joint_accelerations = fields['joint_accelerations']
        out[i] = 1e3 * (time.perf_counter() - t0)
    return out


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``awp_bench``."""
    parser = argparse.ArgumentParser(
        prog=PROG,
        description='Time the feasibility pipeline over random postures near the standing '
                    'posture: the per-cycle evaluation (model, leg polytopes, AWP, CWC/FWP, '
                    'margins; "total") and, apart, the FWS (exact H-rep, directional and '
                    'Euclidean margins) and the LP queries of the FWS; print a table and one '
                    'JSON line of medians in ms (total_ms, fws_margin_ms = FWS H-rep + '
                    'margin, fws_query_lp_ms, <stage>_ms).')
    parser.add_argument('--robot', default='hyq',
                        help='robot config name or YAML path (default: hyq)')
    parser.add_argument('-n', '--samples', type=int, default=200,
                        help='number of timed postures (default: 200)')
    parser.add_argument('--seed', type=int, default=0, help='random seed (default: 0)')
    parser.add_argument('--spread', type=float, default=0.1,
                        help='uniform joint offset half-width [rad] (default: 0.1)')
    parser.add_argument('--warmup', type=int, default=5,
                        help='untimed evaluations first (default: 5)')
    parser.add_argument('--stance', nargs='*', default=None, metavar='FOOT',
                        help='stance feet (default: all)')
    parser.add_argument('--no-fws', action='store_true',
                        help='time the per-cycle evaluation only (no FWS, no LP queries)')
    parser.add_argument('--baseline-samples', type=int, default=20,
                        help='states timed with the iterative-projection baseline of the CoM '
                             'regions (default: 20)')
    parser.add_argument('--qhull-samples', type=int, default=1,
                        help='postures on which qhull hulls the AWP and FWS vertex sums, the '
                             'baselines of the ratios (default: 1; ~4 s and ~20 s each)')
    parser.add_argument('--kernels', action='store_true',
                        help='also time the compiled kernels against their numpy reference, '
                             'interleaved (JSON key kernel_ratios)')
    parser.add_argument('--json-only', action='store_true',
                        help='print only the JSON line')
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run ``awp_bench``; return the exit status."""
    tune_process()
    args = build_parser().parse_args(argv)
    if args.samples < 1:
        sys.stderr.write(f'{PROG}: error: --samples must be >= 1, got {args.samples}\n')
        return 2
    try:
        evaluator = FeasibilityEvaluator(args.robot)
        stance = None if args.stance is None else tuple(args.stance)
        times = run_benchmark(evaluator, args.samples, seed=args.seed, spread=args.spread,
                              warmup=args.warmup, stance=stance, fws=not args.no_fws,
                              baseline_samples=args.baseline_samples)
        times.update(stream_times(evaluator, args.samples, seed=args.seed,
                                  spread=args.spread, stance=stance, fws=not args.no_fws))
        if args.qhull_samples > 0:
            times.update(qhull_baselines(evaluator, args.qhull_samples, seed=args.seed,
                                         spread=args.spread, stance=stance))
    except (ValueError, AwpError) as exc:
        sys.stderr.write(f'{PROG}: error: {" ".join(str(exc).split())}\n')
        return 2
    feasible = times.pop('feasible')
    outside_error = times.pop('outside_error', None)
    median = {s: float(np.nanmedian(t)) if np.isfinite(t).any() else np.nan
              for s, t in times.items()}
    if not args.json_only:
        out = [f'{PROG}: robot {evaluator.config.robot_name}, {args.samples} postures, '
               f'seed {args.seed}, spread {args.spread} rad, '
               f'{int(feasible.sum())}/{feasible.size} feasible',
               f'{"stage":<20}{"median ms":>12}{"p90 ms":>12}{"max ms":>12}']
        for s, t in times.items():
            out.append(f'{s:<20}{median[s]:>12.4f}{np.percentile(t, 90):>12.4f}'
                       f'{np.max(t):>12.4f}')
        sys.stdout.write('\n'.join(out) + '\n')
    summary = {'robot': evaluator.config.robot_name, 'samples': args.samples,
               'total_ms': round(median['total'], 4)}
    if 'fws' in times:
        friction = times['fws_friction']
        summary['fws_margin_ms'] = round(float(np.median(
            friction + times['fws'] + times['fws_margin'])), 4)
        summary['fws_query_lp_ms'] = round(float(np.median(friction + times['fws_query_lp'])),
                                           4)
    summary['total_stream_ms'] = round(median['stream_total'], 4)
    if 'stream_fws' in times:
        summary['fws_per_cycle_ms'] = round(median['stream_fws'], 4)
    for s in times:
        if s not in ('total', 'fws_query_lp', 'stream_total', 'stream_fws'):
            key = {'fws_margin': 'fws_margin_step', 'regions': 'regions_stage',
                   'com_regions': 'regions'}.get(s, s)
            summary[f'{key}_ms'] = round(median[s], 4)
    if times.get('regions_baseline', np.zeros(0)).size:
        summary['regions_speedup'] = round(median['regions_baseline'] / median['com_regions'],
                                           1)
        if not args.json_only:     # a table row: the ratio of the two medians
            sys.stdout.write(f'{"regions_speedup":<20}{summary["regions_speedup"]:>12.1f}  '
                             '(x: iterative projection / per-cycle exact, CoM regions)\n')
    if outside_error is not None and np.isfinite(outside_error).any():
        summary['fws_outside_max_error'] = float(np.nanmax(outside_error))
        summary['fws_outside_vs_hrep'] = round(summary['fws_margin_ms'] /
                                               median['fws_outside'], 1)
        if not args.json_only:
            sys.stdout.write(f'{"fws_outside_vs_hrep":<20}{summary["fws_outside_vs_hrep"]:>12.1f}'
                             '  (x: FWS H-rep + margin / per-cycle distance, wrenches '
                             f'{OUTSIDE_N:g} N outside; margins differ by at most '
                             f'{summary["fws_outside_max_error"]:.2e})\n')
    ratios = [('total_vs_qhull', 'awp_qhull', median['total'], 'per-cycle total'),
              ('fws_vs_qhull', 'fws_qhull', summary.get('fws_per_cycle_ms'), 'FWS per cycle')]
    for key, baseline, ours, what in ratios:
        if baseline in times and ours and np.isfinite(median[baseline]):
            summary[key] = round(median[baseline] / ours, 1)
            if not args.json_only:
                sys.stdout.write(f'{key:<20}{summary[key]:>12.1f}  (x: qhull hull of the '
                                 f'{baseline[:3].upper()} vertex sums / {what})\n')
    if args.kernels:
        pairs = kernel_ratios(evaluator, seed=args.seed, spread=args.spread)
        summary['kernel_ratios'] = {k: round(a / b, 2) for k, (a, b) in pairs.items()}
        if not args.json_only:
            for name, (a, b) in pairs.items():
                sys.stdout.write(f'kernel {name:<26} numpy {a:.4f} ms, kernel {b:.4f} ms: '
                                 f'{a / b:.2f}x\n')
    batch, loop = batch_rates(evaluator, args.samples, seed=args.seed, spread=args.spread,
                              stance=stance)
    summary['batch_states_per_s'] = round(batch, 1)
    summary['loop_states_per_s'] = round(loop, 1)
    if not args.json_only:
        sys.stdout.write(f'evaluate_many: {batch:.0f} states/s (a loop of evaluate: '
                         f'{loop:.0f} states/s), per-cycle sets, no FWS\n')
    sys.stdout.write(json.dumps(summary) + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
