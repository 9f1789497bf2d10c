r"""
The feasibility evaluator: one object per robot, one call per state, one result object.

Pipeline of :meth:`FeasibilityEvaluator.evaluate` (frames: world-aligned axes, origin at the
whole-robot CoM; SI units). Stage names are the keys of ``timings_ms`` [ms]:

1. ``validate``: the :class:`~awp_ros.robot.state.RobotState` against the model (InputError).
2. ``model``: Pinocchio update, base at the origin with the measured orientation: bias
   torques ``rnea(q, v, a)``, LOCAL_WORLD_ALIGNED foot Jacobians, CoM, mass and the
   gravito-inertial wrench ``w = [m (c'' - g); L']`` (quasi-static ``[0, 0, m g, 0, 0, 0]``).
3. ``sets``: per stance leg the force polytope :math:`\{f : \tau_{min} \le b - J^T f \le
   \tau_{max}\}` (closed-form parallelepipeds for 3-joint legs, batched); its
   friction-bounded polytope (∩ its friction pyramid ∩ ``n . f >= 0``), computed on first
   use (:attr:`LegResult.friction_polytope`: the FWS, leg messages, markers), this stage
   only proving each non-empty (a force-polytope vertex, or a point on the pyramid's axis,
   strictly inside the pyramid) or, when that test fails, computing them to warn about a
   leg that cannot push; the AWP :math:`\sum_k L_k \mathcal F_k` (a zonotope with 3K
   generators when every leg is a parallelepiped or a singular leg's flat image, else the
   exact Minkowski sum); the contact wrench cone; and the FWP = AWP ∩ CWC (the seed's FWP).
   With three or more non-singular three-joint legs and friction, all of it is one compiled
   call (:func:`~awp_ros.geometry.kernels.cycle_sets`: the same kernels as the stage-by-stage
   code, :meth:`FeasibilityEvaluator._sets`, on the same inputs, without Python between
   them; the same results bit for bit).
4. ``margins``: signed Euclidean margins and witnesses of ``w`` for AWP and FWP.
5. ``regions``: the CoM regions at ``w``'s force and moment, exact: ``support_region``
   (:func:`~awp_ros.wrench.com_region.com_region`, the slice of the CWC, kept as
   ``result.cwc``), the feasible region
   (:func:`~awp_ros.wrench.com_region.feasible_region`, the projection of the contact-force
   LP; ``feasible_region_per_cycle``), ``fwp_region`` (the slice of the FWP), and the
   capture point when the state has a ``base_twist`` (the CoM velocity, Pinocchio's
   ``vcom`` of the model stage); after :func:`~awp_ros.geometry.kernels.cycle_sets`, the
   three regions' kernels in one compiled call
   (:func:`~awp_ros.geometry.kernels.cycle_regions`). The support and the feasible region
   alone, the two that planners use, are also timed as ``com_regions`` (part of
   ``regions``).

With three or more stance legs each evaluation then gives the FWS's directional margins, by
LPs on the feasible region's points (``fws_directional_per_cycle``,
:func:`~awp_ros.wrench.fws_queries.directional_margins_of_legs`), timed apart as
``fws_directional_lp`` (0 otherwise): an FWS query, outside ``total`` as the FWS's own steps.
When that region puts the CoM outside (the wrench is not in the FWS), the FWS's signed margin
and witness too, by the nearest point of the FWS to the wrench (``fws_margin_per_cycle``,
:func:`~awp_ros.wrench.fws_queries.outside_margin_of_points`, Wolfe's algorithm on the same
points), timed as ``fws_distance`` (0 otherwise).

``total`` is the wall time of the whole per-cycle evaluation, the five stages back to back:
what ``evaluate(state, fws=False)`` costs, but for ``fws_directional_lp``. The feasible wrench set
:math:`\sum_k L_k \mathcal F_{\mu,k}` is timed apart, as it may run at a lower rate
(:meth:`FeasibilityEvaluator.add_fws`): ``fws`` (its exact H-rep, including the
friction-bounded polytopes when not yet computed), ``fws_directional`` (how
far ``w`` can move along each wrench axis inside it), ``fws_margin`` (its signed Euclidean
margin) and ``feasible_region`` (its CoM region and the capture point's margin to it).
FWS ⊆ FWP ⊆ AWP: the FWP only asks that *some* force distribution respects the torques and
*some* (possibly other) distribution respects friction; the FWS asks for one distribution
that respects both, per leg.

The result classes live in :mod:`awp_ros.evaluation.result` and are re-exported here.
"""

from __future__ import annotations

from collections.abc import Generator, Sequence
from dataclasses import replace
from functools import partial
import time

import numpy as np

from awp_ros.errors import AwpError, ConfigError, GeometryError, InputError
from awp_ros.evaluation.result import directional_by_axis, FeasibilityResult, LegResult, \
    WrenchSetResult
from awp_ros.geometry import certified_search, kernels
from awp_ros.geometry.linalg import GRAM_CERTIFY, identity
from awp_ros.geometry.margin import directional_margins, polytope_margin, SetMargin
from awp_ros.geometry.minkowski_facets import STEP_CHOICES
from awp_ros.geometry.polytope import Polytope
from awp_ros.geometry.steps import run_steps, timed_steps
from awp_ros.geometry.zonotope import facet_complements, facet_subsets, ZONOTOPE_TOLS
from awp_ros.robot.config import load_config, RobotConfig
from awp_ros.robot.model import RobotModel
from awp_ros.robot.state import resolve_state, ResolvedState, RobotState
from awp_ros.wrench.com_region import (com_region, ComRegion, DISTANCE_TOL, EDGE_PARALLEL_TOL,
                                       feasible_region, feasible_region_of_kernel,
                                       feasible_region_of_rows, region_of_slice, slice_floor,
                                       VERTICAL_FORCE_TOL)
from awp_ros.wrench.contact_forces import measured_contact_forces
from awp_ros.wrench.contact_wrench_cone import (cone_polytope, CONE_TOL,
                                                contact_wrench_cone_unchecked, facets_key,
                                                last_facets, pyramid_rays, record_facets)
from awp_ros.wrench.feasible_wrench_set import feasible_wrench_set_steps, minkowski_sum_of_lifts
from awp_ros.wrench.force_polytope import force_polytope, parallelepipeds
from awp_ros.wrench.friction_polytope import (friction_rows, FrictionPolytopes, inside_force,
                                              INSIDE_MARGIN)
from awp_ros.wrench.fws_queries import directional_margins_of_legs, directional_of_points, \
    lifted_points, outside_margin_of_points, two_leg_contains
from awp_ros.wrench.wrench_polytope import (awp_zonotope, feasible_wrench_polytope, INTERIOR_TOL,
                                            zonotope_awp)

__all__ = ['compute_fws', 'compute_fws_steps', 'FeasibilityEvaluator', 'STAGES', 'warm_up']

# The hull origin of the full-dimensional force polytopes (shared, read-only).
_ZERO3 = np.zeros(3)
_ZERO3.setflags(write=False)

#: The per-cycle stages of :meth:`FeasibilityEvaluator.evaluate`, in order.
STAGES = ('validate', 'model', 'sets', 'margins', 'regions')


class FeasibilityEvaluator:
    """
    Compute force polytopes, AWP, FWP, FWS and margins of a robot, one state at a time.

    :param config: a :class:`RobotConfig`, or a config name / YAML path for
        :func:`~awp_ros.robot.config.load_config`.
    :param singular_rtol: a leg whose Jacobian has smallest / largest singular value below
        this is singular (pseudo-inverse image, warning).
    :param near_singular_rtol: below this ratio a leg is flagged near-singular (warning).
    :param feasibility_tol: tolerance of ``feasible`` on the signed margins [N, N.m].
    :param hull_tol: distance of the wrench from a flat set's affine hull (1-2 stance legs)
        up to which it counts as on the hull [N, N.m] (default ``feasibility_tol``): a
        measured wrench is on the 5D hull of two stance legs only up to its estimation error.
    :raises ConfigError: bad config; :raises ModelError: unusable URDF.

    Not thread-safe: the evaluator owns one Pinocchio ``Data`` and reuses its buffers; use
    one evaluator per thread.
    """

    def __init__(self, config: RobotConfig | str = 'hyq', *, singular_rtol: float = 1e-9,
                 near_singular_rtol: float = 1e-2, feasibility_tol: float = 1e-6,
                 hull_tol: float | None = None) -> None:
        kernels.compile_all()       # once per process, before any control cycle
        certified_search.compile_all()
        self.config = config if isinstance(config, RobotConfig) else load_config(config)
        self.model = RobotModel(self.config)
        self.singular_rtol = singular_rtol
        self.near_singular_rtol = near_singular_rtol
        self.feasibility_tol = feasibility_tol
        self.hull_tol = feasibility_tol if hull_tol is None else max(hull_tol, feasibility_tol)
        legs = self.model.legs
        self._three_joint = all(len(leg.joints) == 3 for leg in legs.values())
        self._tau_min = {f: leg.tau_min for f, leg in legs.items()}
        self._tau_max = {f: leg.tau_max for f, leg in legs.items()}
        self._rows_cache: tuple | None = None
        self._limit_cache: dict[tuple[str, ...], tuple[np.ndarray, np.ndarray]] = {}
        self._gravity = float(np.linalg.norm(self.model.model.gravity.linear))  # [m/s^2]

    @property
    def feet(self) -> tuple[str, ...]:
        """Return the config's feet, i.e. its contact frames."""
        return self.config.feet

    def standing_state(self, **kw) -> RobotState:
        """Return a :class:`RobotState` at the config's standing posture (kw override)."""
        if self.model.standing_q is None:
            raise ConfigError(f'robot {self.config.robot_name!r} has no standing_posture')
        joints = dict(zip(self.model.joint_names, self.model.standing_q.tolist()))
        return RobotState(joint_positions=joints, **kw)

    def evaluate(self, state: RobotState, *, fws: bool = True,
                 wrench: np.ndarray | None = None,
                 base_velocity_known: bool = True) -> FeasibilityResult:
        """
        Evaluate one state (see the module docstring for the stages).

        :param state: the robot state.
        :param fws: also compute the FWS, its directional margins and Euclidean margin
            (:meth:`add_fws`).
        :param wrench: a wrench ``[f; tau]`` [N, N.m] (about the CoM, world-aligned axes) whose
            margins to report instead of the state's gravito-inertial wrench, e.g. the
            centroidal wrench a planner or an MPC intends; the sets are the state's.
        :param base_velocity_known: whether the linear part of ``state.base_twist`` is
            measured (odometry): only then are the CoM velocity and the capture point
            computed (False: a twist whose linear velocity is a placeholder zero).
        :return: the :class:`FeasibilityResult`.
        :raises InputError: invalid state (the message names the bad value).
        """
        clock = time.perf_counter
        t0 = clock()
        cfg, model = self.config, self.model
        s = resolve_state(state, model.joint_names, cfg.feet, default_normal=cfg.unit_normal,
                          default_mu=cfg.friction_coefficient,
                          position_limits=model.position_limits)
        warnings = s.warnings
        t1 = clock()
        kin = model.kinematics(s.q, s.stance, quaternion=s.quaternion, v=s.v, a=s.a)
        w, p = kin.wrench, kin.p_foot__com
        if wrench is not None:
            w = np.asarray(wrench, dtype=float)
            if w.shape != (6,) or not np.isfinite(w).all():
                raise InputError(f'wrench must be 6 finite numbers [N, N.m], got {wrench!r}')
        # The CoM velocity (world axes), when the base's is known: Pinocchio's vcom, which
        # the centroidal momentum of the model stage filled (v holds the base twist).
        vcom = model.data.vcom[0].copy() \
            if state.base_twist is not None and base_velocity_known else None
        t2 = clock()
        rows = self._friction_rows(s.normals, s.mus)        # the stance legs' pyramids
        fused = self._cycle_sets(s, kin, w, rows, warnings)
        forces, frictions, force_rows, awp, cwc, fwp, slacks = fused if fused is not None \
            else self._sets(s, kin, rows, warnings) + ((None, None),)
        t3 = clock()
        tol = self.feasibility_tol
        awp_r = WrenchSetResult.from_margin('awp', awp, polytope_margin(
            awp, w, feasibility_tol=tol, hull_tol=self.hull_tol, slack=slacks[0]))
        fwp_r = WrenchSetResult.from_margin('fwp', fwp, polytope_margin(
            fwp, w, feasibility_tol=tol, hull_tol=self.hull_tol, slack=slacks[1]))
        measured = None
        if s.tau is not None and s.stance:
            info = [model.legs[f] for f in s.stance]
            measured = measured_contact_forces(
                s.stance, p, kin.J, kin.bias, [s.tau[leg.v_idx - 6] for leg in info],
                rows, [leg.tau_min for leg in info],
                [leg.tau_max for leg in info], w)
        legs = {foot: LegResult(foot, p[k], s.normals[k], float(s.mus[k]), forces[k],
                                partial(frictions.__getitem__, k), forces[k].meta['singular'],
                                forces[k].meta['near_singular'])
                for k, foot in enumerate(s.stance)}
        t4 = clock()
        # With the sets of one compiled call, the regions' kernels in one more (when a
        # vertical force defines them); each region the general code's when the kernel's
        # fast path does not hold.
        sliced = kernels.cycle_regions(
            cwc.A, fwp.A, fwp.b, *force_rows[:2], rows, p, w,
            DISTANCE_TOL, EDGE_PARALLEL_TOL, slice_floor(*w[:3].tolist())) \
            if fused is not None and abs(w[2]) > VERTICAL_FORCE_TOL else None
        support = sliced and region_of_slice(cwc, sliced[0])
        if support is None:
            support = _region(cwc, w, 'support region', warnings)
        if sliced is not None:
            feasible = feasible_region_of_kernel(sliced[1])
        elif force_rows is not None:
            feasible = feasible_region_of_rows(p, *force_rows[:2], rows, w)
        else:
            feasible = feasible_region(p, forces, rows, w[:3], w[3:]) if s.stance else None
        # Two legs: the FWS's verdict by its one-dimensional LP (the region is a segment).
        pair = two_leg_contains(p, *force_rows[:2], rows, w, hull_tol=self.hull_tol,
                                feasibility_tol=tol) \
            if len(s.stance) == 2 and force_rows is not None else None
        t5 = clock()
        fwp_r.region = sliced and region_of_slice(fwp, sliced[2])
        if fwp_r.region is None:
            fwp_r.region = _region(fwp, w, 'FWP region', warnings)
        capture = _capture_point(vcom, p, self._gravity)
        fwp_r.capture_point_margin = _point_margin(fwp_r.region, capture)
        t6 = clock()
        # Three or more legs: the FWS's directional margins by LPs on the feasible region's
        # points, timed apart (an FWS query, as the FWS's own steps).
        directional, lp_ms, outside, distance_ms = None, 0.0, None, 0.0
        if sliced is not None and len(s.stance) >= 3:
            margins = directional_of_points(len(s.stance), sliced[3], w)
            directional = None if margins is None else directional_by_axis(*margins)
            t7 = clock()
            lp_ms = 1e3 * (t7 - t6)
            # Outside the FWS (the CoM outside its slice): its margin, by the nearest point.
            if feasible is not None and not feasible.contains_origin():
                outside, problem = outside_margin_of_points(len(s.stance), sliced[3], w, tol)
                if problem:
                    warnings.append(problem)
                distance_ms = 1e3 * (clock() - t7)
        timings = {'validate': 1e3 * (t1 - t0), 'model': 1e3 * (t2 - t1),
                   'sets': 1e3 * (t3 - t2), 'margins': 1e3 * (t4 - t3),
                   'regions': 1e3 * (t6 - t4),
                   'com_regions': 1e3 * (t5 - t4), 'total': 1e3 * (t6 - t0),
                   'fws_directional_lp': lp_ms, 'fws_distance': distance_ms}
        result = FeasibilityResult(cfg.robot_name, s.stance, kin.mass, kin.com, w, legs,
                                   awp_r, fwp_r, None, warnings, timings,
                                   'quasi_static' if s.a is None else 'measured',
                                   measured, cwc=cwc, support_region=support,
                                   com_velocity=vcom, capture_point=capture,
                                   feasible_region_per_cycle=feasible,
                                   capture_margin_per_cycle=_point_margin(feasible, capture),
                                   two_leg_fws_feasible=pair,
                                   fws_directional_per_cycle=directional,
                                   fws_margin_per_cycle=outside)
        if fws:
            self.add_fws(result)
        return result

    def add_fws(self, result: FeasibilityResult) -> FeasibilityResult:
        """
        Compute the FWS of an evaluated state and store it in ``result.fws``.

        Lets a caller run :meth:`evaluate` with ``fws=False`` every cycle and add the FWS
        (exact H-rep, directional margins, Euclidean margin, the feasible region and the
        capture point's margin to it) at a lower rate. Adds the ``fws``,
        ``fws_directional``, ``fws_margin`` and ``feasible_region`` timings [ms] (``total``
        stays the per-cycle evaluation without them).

        :return: ``result``, updated in place.
        """
        return self.attach_fws(result, compute_fws(*self.fws_job(result)))

    def fws_job(self, result: FeasibilityResult) -> tuple:
        """
        Return the picklable arguments of :func:`compute_fws` for an evaluated state.

        What :meth:`add_fws` computes, as data: the node hands it to a worker process
        (``fws_lag_s``) and attaches the answer with :meth:`attach_fws`; the numbers are the
        same as :meth:`add_fws`'s (same function, same arguments). The FWS's directional
        margins are left out when the evaluation has them already (three or more legs, by
        exact LPs: ``fws_directional_per_cycle``).
        """
        legs = list(result.legs.values())
        positions = np.array([leg.position for leg in legs]) if legs else np.zeros((0, 3))
        return (positions, [leg.friction_polytope for leg in legs], result.wrench,
                self.feasibility_tol, self.hull_tol, result.fws_directional_per_cycle is None)

    def attach_fws(self, result: FeasibilityResult, part: tuple) -> FeasibilityResult:
        """
        Store :func:`compute_fws`'s answer for ``result`` in ``result.fws`` (see :meth:`add_fws`).

        Adds the feasible region (the per-cycle projection, else the FWS's slice) and the
        capture point's margin to it, and the FWS timings.

        :return: ``result``, updated in place.
        """
        S, margin, plus, minus, times = part
        t0 = time.perf_counter()
        fws_r = WrenchSetResult.from_margin('fws', S, margin)
        fws_r.directional = result.fws_directional_per_cycle if plus is None else \
            directional_by_axis(plus, minus)
        # The same set as the FWS's slice: the per-cycle projection when there is one.
        fws_r.region = result.feasible_region_per_cycle
        if fws_r.region is None:
            fws_r.region = _region(S, result.wrench, 'feasible region', result.warnings)
        fws_r.capture_point_margin = _point_margin(fws_r.region, result.capture_point)
        result.fws = fws_r
        tm = result.timings_ms
        tm['fws'], tm['fws_directional'], tm['fws_margin'] = times
        tm['feasible_region'] = 1e3 * (time.perf_counter() - t0)
        return result

    def with_wrench(self, result: FeasibilityResult, wrench: np.ndarray, *,
                    fws: WrenchSetResult | None = None) -> FeasibilityResult:
        """
        Return ``result`` with the margins of another wrench to the same sets.

        :param wrench: ``[f; tau]`` [N, N.m], about the CoM, world-aligned axes (e.g. the
            centroidal wrench a planner intends).
        :param fws: the FWS to use (default ``result.fws``; e.g. the latest one computed).
        :raises InputError: ``wrench`` is not 6 finite numbers.
        """
        w = np.asarray(wrench, dtype=float)
        if w.shape != (6,) or not np.isfinite(w).all():
            raise InputError(f'wrench must be 6 finite numbers [N, N.m], got {wrench!r}')
        fws = result.fws if fws is None else fws
        tol, hull_tol = self.feasibility_tol, self.hull_tol

        warnings = list(result.warnings)

        def margin(s: WrenchSetResult, region: str = '') -> WrenchSetResult:
            out = WrenchSetResult.from_margin(s.name, s.polytope, polytope_margin(
                s.polytope, w, feasibility_tol=tol, hull_tol=hull_tol))
            if region:          # the CoM region at this wrench's force and moment
                out.region = _region(s.polytope, w, region, warnings)
                out.capture_point_margin = _point_margin(out.region, result.capture_point)
            return out

        fws_r = None
        if fws is not None:
            fws_r = margin(fws, 'feasible region')
            plus, minus = directional_margins(fws.polytope, w, feasibility_tol=tol)
            fws_r.directional = directional_by_axis(plus, minus)
        support = None if result.cwc is None else _region(result.cwc, w, 'support region',
                                                          warnings)
        feasible = None if result.feasible_region_per_cycle is None else \
            self.feasible_region_at(list(result.legs.values()), w)
        if fws_r is not None and feasible is not None:
            fws_r.region = feasible
            fws_r.capture_point_margin = _point_margin(feasible, result.capture_point)
        outside = self.outside_margin_at(list(result.legs.values()), w, feasible, warnings) \
            if result.fws_directional_per_cycle is not None else None
        return replace(result, wrench=w, awp=margin(result.awp),
                       fwp=margin(result.fwp, 'FWP region'), fws=fws_r,
                       support_region=support, warnings=warnings,
                       feasible_region_per_cycle=feasible,
                       capture_margin_per_cycle=_point_margin(feasible, result.capture_point),
                       two_leg_fws_feasible=self.two_leg_verdict_at(list(result.legs.values()),
                                                                    w),
                       fws_directional_per_cycle=None if result.fws_directional_per_cycle is None
                       else self.directional_at(list(result.legs.values()), w),
                       fws_margin_per_cycle=outside)

    # -- stages ------------------------------------------------------------------------

    def two_leg_verdict_at(self, legs: Sequence[LegResult], wrench: np.ndarray) -> bool | None:
        """
        Return whether a wrench is in the FWS of two evaluated legs, without the FWS.

        :func:`~awp_ros.wrench.fws_queries.two_leg_contains` (exact: the one-dimensional LP
        of the legs' force distributions) on the legs' positions, force polytopes and
        pyramids, with the evaluator's hull and feasibility tolerances; ``wrench``
        ``[f; tau]`` [N, N.m]. None unless there are two legs with full-dimensional force
        polytopes of the same row count (a singular leg's is flat): the FWS decides then.
        """
        stacked = self._stacked_legs(legs) if len(legs) == 2 else None
        if stacked is None:
            return None
        return two_leg_contains(*stacked, wrench, hull_tol=self.hull_tol,
                                feasibility_tol=self.feasibility_tol)

    def directional_at(self, legs: Sequence[LegResult], wrench: np.ndarray
                       ) -> dict[str, tuple[float, float]] | None:
        """
        Return the FWS's directional margins of evaluated legs at a wrench, without the FWS.

        :func:`~awp_ros.wrench.fws_queries.directional_margins_of_legs` (exact LPs) on the
        legs' positions, force polytopes and pyramids; ``wrench`` ``[f; tau]`` [N, N.m].
        None unless there are three or more legs with full-dimensional force polytopes of
        the same row count (the FWS's H-rep answers then).
        """
        stacked = self._stacked_legs(legs) if len(legs) >= 3 else None
        out = None if stacked is None else directional_margins_of_legs(*stacked, wrench)
        return None if out is None else directional_by_axis(*out)

    def _stacked_legs(self, legs: Sequence[LegResult]) -> tuple | None:
        """
        Return the legs' ``(positions, force_A, force_b, pyramid_rows)`` stacked, or None.

        None when a force polytope is not full-dimensional (a singular leg's is flat) or the
        row counts differ: the arrays of the per-cycle queries on evaluated legs.
        """
        forces = [leg.force_polytope for leg in legs]
        if any(F.dimension != 3 or F.A.shape != forces[0].A.shape for F in forces):
            return None
        return (np.array([leg.position for leg in legs]), np.array([F.A for F in forces]),
                np.array([F.b for F in forces]), self._pyramid_rows(legs))

    def _pyramid_rows(self, legs: Sequence[LegResult]) -> np.ndarray:
        """Return the friction pyramids' rows of evaluated legs (:meth:`_friction_rows`)."""
        return self._friction_rows(np.array([leg.normal for leg in legs]),
                                   np.array([leg.friction_coefficient for leg in legs]))

    def outside_margin_at(self, legs: Sequence[LegResult], wrench: np.ndarray,
                          region: ComRegion | None, warnings: list[str]) -> SetMargin | None:
        """
        Return the FWS's signed margin of a wrench outside it, for evaluated legs, or None.

        :func:`~awp_ros.wrench.fws_queries.outside_margin_of_points` on the legs' friction
        polytopes' lifted vertices, when ``region`` (the feasible region at ``wrench``,
        :meth:`feasible_region_at`) leaves out the CoM with three or more legs; None
        otherwise (inside: the FWS's H-rep gives the margin). A failure is appended to
        ``warnings``.
        """
        if region is None or len(legs) < 3 or region.contains_origin():
            return None
        points = lifted_points(np.array([leg.position for leg in legs]),
                               [leg.friction_polytope.vertices for leg in legs])
        outside, problem = outside_margin_of_points(len(legs), points, wrench,
                                                    self.feasibility_tol)
        if problem:
            warnings.append(problem)
        return outside

    def feasible_region_at(self, legs: Sequence[LegResult], wrench: np.ndarray
                           ) -> ComRegion | None:
        """
        Return the feasible region of evaluated legs at a wrench, by projection.

        :func:`~awp_ros.wrench.com_region.feasible_region` (exact, without the FWS's H-rep)
        on the legs' positions, force polytopes and pyramids; ``wrench`` ``[f; L']`` [N,
        N.m]. None where it is not available so (no leg, a singular leg, no vertical force,
        numba off): the FWS's slice gives it then (:meth:`add_fws`).
        """
        if not legs:
            return None
        return feasible_region(np.array([leg.position for leg in legs]),
                               [leg.force_polytope for leg in legs], self._pyramid_rows(legs),
                               wrench[:3], wrench[3:])

    def _sets(self, s: ResolvedState, kin, rows: np.ndarray, warnings: list[str]) -> tuple:
        """
        Return the ``sets`` stage computed stage by stage (any stance, any legs).

        ``(forces, frictions, force_rows, awp, cwc, fwp)``, ``force_rows`` as
        :meth:`_force_polytopes` returns them.
        """
        p = kin.p_foot__com
        forces, stacked, force_rows = self._force_polytopes(s.stance, kin.J, kin.bias,
                                                            warnings)
        frictions: FrictionPolytopes | list = []
        if forces:
            frictions = FrictionPolytopes(forces, rows)
            _friction_warnings(s.stance, frictions,
                               inside_force(forces, rows, stacked=force_rows), warnings)
        if not s.stance:
            awp = fwp = cwc = _origin_set()
            return forces, frictions, force_rows, awp, cwc, fwp
        awp = awp_zonotope(p, *stacked) if stacked is not None else \
            minkowski_sum_of_lifts(p, [F.vertices for F in forces])
        cwc = contact_wrench_cone_unchecked(p, s.normals, s.mus, self.config.pyramid_sides)
        return forces, frictions, force_rows, awp, cwc, feasible_wrench_polytope(awp, cwc)

    def _cycle_sets(self, s: ResolvedState, kin, w: np.ndarray, rows: np.ndarray,
                    warnings: list[str]) -> tuple | None:
        """
        Return :meth:`_sets` from one compiled call (:func:`kernels.cycle_sets`), or None.

        For three or more three-joint stance legs with friction, when every leg is
        non-singular and the AWP and the CWC are full-dimensional (else None: the caller
        takes :meth:`_sets`). The same kernels on the same inputs as :meth:`_sets`, so the
        same sets, warnings and cone reuse, bit for bit; and, last, the AWP's and the FWP's
        least slack at the wrench ``w`` (:func:`~awp_ros.geometry.margin.polytope_margin`'s
        ``slack``).
        """
        K, sides = len(s.stance), self.config.pyramid_sides
        if not (kernels.ENABLED and self._three_joint and 3 <= K <= kernels.MAX_BITS // 3
                and K * sides <= kernels.MAX_BITS and float(s.mus.min()) > CONE_TOL):
            return None
        p = kin.p_foot__com
        rays = pyramid_rays(s.normals, s.mus, sides)
        key = facets_key(rays, 6)
        last = last_facets(key)
        lo, hi = self._limits(s.stance)
        tol = ZONOTOPE_TOLS
        status, legs, proven, awp, cone, stacked, slacks = kernels.cycle_sets(
            np.array(kin.J), np.array(kin.bias), lo, hi, self.singular_rtol, p, rays,
            max(CONE_TOL ** 2, GRAM_CERTIFY), facet_subsets(3 * K), facet_complements(3 * K),
            tol['zero_tol'], max(tol['span_tol'] ** 2, GRAM_CERTIFY), tol['rank_tol'],
            tol['incidence_tol'], last, CONE_TOL, CONE_TOL, rows, INSIDE_MARGIN, w,
            INTERIOR_TOL)
        if status != 0:
            return None
        lifted, cone_A, spans, masks, reused = cone
        record_facets(key, spans, masks, reused=reused)
        center, gen, V, A, b, ratio = legs
        forces = self._parallelepiped_polytopes(center, gen, V, A, b, ratio)
        _leg_warnings(s.stance, forces, warnings)
        frictions = FrictionPolytopes(forces, rows)
        _friction_warnings(s.stance, frictions, proven, warnings)
        awp = zonotope_awp(*awp, 3 * K)
        cwc = cone_polytope(cone_A, lifted, identity(6))
        i_awp, s_awp, i_fwp, s_fwp, interior = slacks
        fwp = feasible_wrench_polytope(awp, cwc, stacked=stacked, interior=interior)
        return forces, frictions, (A, b, V), awp, cwc, fwp, ((i_awp, s_awp), (i_fwp, s_fwp))

    def _parallelepiped_polytopes(self, center: np.ndarray, gen: np.ndarray, V: np.ndarray,
                                  A: np.ndarray, b: np.ndarray, ratio: np.ndarray
                                  ) -> list[Polytope | None]:
        """Return the batched parallelepipeds as Polytopes, None for a singular leg."""
        eye, zero = identity(3), _ZERO3
        out: list[Polytope | None] = []
        for k, r in enumerate(ratio.tolist()):
            out.append(Polytope(3, V[k], A[k], b[k], zero, eye, {
                'singular': False, 'near_singular': r <= self.near_singular_rtol,
                'sigma_ratio': r, 'center': center[k], 'generators': gen[k]})
                if r > self.singular_rtol else None)
        return out

    def _friction_rows(self, normals: np.ndarray, mus: np.ndarray) -> np.ndarray:
        """Return the pyramid rows of the stance legs (cached while contacts are unchanged)."""
        key = (normals.tobytes(), mus.tobytes())
        if self._rows_cache is None or self._rows_cache[0] != key:
            self._rows_cache = (key, friction_rows(normals, mus, self.config.pyramid_sides))
        return self._rows_cache[1]

    def _force_polytopes(self, stance: tuple[str, ...], J: list, bias: list,
                         warnings: list[str]) -> tuple[list[Polytope], tuple | None,
                                                       tuple | None]:
        """
        Return the force polytope of each stance leg (batched for 3-joint legs).

        Also return ``(centers (K, 3), generators (K, 3, 3))`` of the AWP's zonotope when
        every leg is a parallelepiped or a singular leg's flat image, else None; and the
        legs' stacked H-reps and vertices ``(A (K, 6, 3), b (K, 6), V (K, 8, 3))`` when every
        leg is a full-dimensional parallelepiped (the feasible region's input), else None.
        """
        K = len(stance)
        out: list[Polytope | None] = [None] * K
        stacked = rows = None
        if self._three_joint and K:
            lo, hi = self._limits(stance)
            pp = parallelepipeds(np.array(J), np.array(bias), lo, hi,
                                 singular_rtol=self.singular_rtol)
            center, gen, V, A, b, ratio = (pp[key] for key in (
                'center', 'generators', 'vertices', 'A', 'b', 'sigma_ratio'))
            out = self._parallelepiped_polytopes(center, gen, V, A, b, ratio)
            if float(ratio.min()) > self.singular_rtol:
                stacked, rows = (center, gen), (A, b, V)
        for k, foot in enumerate(stance):
            if out[k] is None:
                out[k] = force_polytope(J[k], bias[k], self._tau_min[foot],
                                        self._tau_max[foot], singular_rtol=self.singular_rtol,
                                        near_singular_rtol=self.near_singular_rtol)
        _leg_warnings(stance, out, warnings)
        if stacked is None and K and all(F.meta.get('generators', np.zeros(0)).shape == (3, 3)
                                         for F in out):
            stacked = (np.array([F.meta['center'] for F in out]),
                       np.array([F.meta['generators'] for F in out]))
        return out, stacked, rows

    def _limits(self, stance: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
        """Return the stacked torque limits (K, n) of a stance set (cached per set)."""
        lim = self._limit_cache.get(stance)
        if lim is None:
            lim = (np.array([self._tau_min[f] for f in stance]),
                   np.array([self._tau_max[f] for f in stance]))
            self._limit_cache[stance] = lim
        return lim

    # -- batches -----------------------------------------------------------------------

    def evaluate_many(self, states: Sequence[RobotState], *, fws: bool = False,
                      wrenches: np.ndarray | Sequence | None = None) -> list[FeasibilityResult]:
        """
        Evaluate many states, e.g. a planner's candidate postures; one result per state.

        Each result equals ``evaluate(states[i], fws=fws, wrench=wrenches[i])``. The states
        are taken grouped by their contacts (stance, normals, friction coefficients), so
        that the pyramid rows cached between calls are computed once per group, not once
        per change; the results come back in the order of ``states``. Within one state the
        stages are already vectorised across legs and facet candidates; across states the
        per-state geometry (zonotope facets, CWC, intersections) has different shapes and
        is not batched (the README, "For planners", has the measurements).

        :param states: the robot states.
        :param fws: also compute each state's FWS (~10 ms per state).
        :param wrenches: None (each state's gravito-inertial wrench), one wrench ``(6,)``
            for all, or one per state ``(len(states), 6)`` [N, N.m] (about the CoM,
            world-aligned axes).
        :return: the :class:`FeasibilityResult` of each state, in order.
        :raises InputError: wrenches of the wrong shape or not finite, or an invalid state
            (the message names its index and the bad value); nothing is returned then.
        """
        states = list(states)
        n = len(states)
        W = None
        if wrenches is not None:
            W = np.asarray(wrenches, dtype=float)
            if W.shape == (6,):
                W = np.broadcast_to(W, (n, 6))
            if W.shape != (n, 6) or not np.isfinite(W).all():
                raise InputError(f'wrenches must be 6 finite numbers [N, N.m] or one such row '
                                 f'per state ({n}, 6), got shape {W.shape}')
        order = sorted(range(n), key=lambda i: _contacts_key(states[i]))
        results: list[FeasibilityResult | None] = [None] * n
        for i in order:
            try:
                results[i] = self.evaluate(states[i], fws=fws,
                                           wrench=None if W is None else W[i])
            except InputError as exc:
                raise InputError(f'state {i}: {exc}') from exc
        return results


def compute_fws(positions: np.ndarray, frictions: Sequence[Polytope], wrench: np.ndarray,
                feasibility_tol: float, hull_tol: float, directional: bool = True) -> tuple:
    r"""
    Return the FWS of stance legs and a wrench's margins to it (the core of ``add_fws``).

    :math:`\mathcal{S} = \bigoplus_k \{[f; p_k \times f] : f \in F_k\}`, each leg's
    friction-bounded force polytope :math:`F_k` [N] lifted at its foot :math:`p_k` [m]
    (relative to the CoM, world-aligned), then the signed Euclidean margin and the
    directional margins of ``wrench`` ``[f; tau]`` [N, N.m]. A pure function of its
    arguments: the node may run it in another process, or in steps
    (:func:`compute_fws_steps`).

    ``directional``: False leaves the directional margins out (``plus``, ``minus`` None): the
    caller has them from the exact LPs of the evaluation.

    :return: ``(S, margin, plus, minus, (fws_ms, directional_ms, margin_ms))``.
    """
    return run_steps(compute_fws_steps(positions, frictions, wrench, feasibility_tol,
                                       hull_tol, directional, step_choices=None))


def compute_fws_steps(positions: np.ndarray, frictions: Sequence[Polytope],
                      wrench: np.ndarray, feasibility_tol: float, hull_tol: float,
                      directional: bool = True, *,
                      step_choices: int | None = STEP_CHOICES) -> Generator[None, None, tuple]:
    """
    Compute :func:`compute_fws` in steps of about 0.1-0.4 ms (:mod:`awp_ros.geometry.steps`).

    ``step_choices``: face choices of the facet search per step (None: each search pattern
    in one step, the fewest calls); the answer is the same whatever the steps. The times it
    returns are those spent in its steps, not between them.
    """
    if len(frictions):
        S, fws_s = yield from timed_steps(feasible_wrench_set_steps(
            np.asarray(positions), list(frictions), step_choices=step_choices))
    else:
        S, fws_s = _origin_set(), 0.0
    yield
    clock = time.perf_counter
    t1 = clock()
    plus, minus = directional_margins(S, wrench, feasibility_tol=feasibility_tol) \
        if directional else (None, None)
    t2 = clock()
    margin = polytope_margin(S, wrench, feasibility_tol=feasibility_tol, hull_tol=hull_tol)
    t3 = clock()
    return S, margin, plus, minus, (1e3 * fws_s, 1e3 * (t2 - t1), 1e3 * (t3 - t2))


def warm_up(config: RobotConfig | str) -> float:
    """
    Evaluate the standing posture once for every number of stance feet, FWS included.

    The compiled kernels load from their on-disk cache at their first call in a process
    (tens of ms each: a 500 Hz soak's first report took 48 ms, its first two-leg one 24 ms);
    a node calls this before its first joint state so that no report pays for it. A
    throwaway evaluator does the work: the caller's evaluators and their caches are not
    touched. The posture is the config's ``standing_posture``, else every joint at 0 rad.
    Failures (e.g. a posture where every leg is singular) are ignored: the stream then
    only loads the kernels it meets later.

    :return: the wall time it took [s].
    """
    t0 = time.perf_counter()
    evaluator = FeasibilityEvaluator(config)
    model = evaluator.model
    q = model.standing_q if model.standing_q is not None else np.zeros(len(model.joint_names))
    joints = dict(zip(model.joint_names, np.asarray(q, dtype=float).tolist()))
    feet = list(evaluator.feet)
    for n in range(len(feet), -1, -1):
        try:
            evaluator.evaluate(RobotState(joint_positions=joints, stance=feet[:n]))
        except (AwpError, ValueError, np.linalg.LinAlgError):
            pass
    return time.perf_counter() - t0


def _leg_warnings(stance: tuple[str, ...], forces: Sequence[Polytope],
                  warnings: list[str]) -> None:
    """Append a warning for each singular or near-singular stance leg."""
    for foot, F in zip(stance, forces):
        meta = F.meta
        if meta['singular']:
            warnings.append(f'leg {foot!r} is singular (sigma ratio '
                            f'{meta["sigma_ratio"]:.2e}); its force polytope is the '
                            'pseudo-inverse image (flat)')
        elif meta['near_singular']:
            warnings.append(f'leg {foot!r} is near-singular (sigma ratio '
                            f'{meta["sigma_ratio"]:.2e})')


def _friction_warnings(stance: tuple[str, ...], frictions: FrictionPolytopes,
                       proven: np.ndarray, warnings: list[str]) -> None:
    """Append a warning for each leg not proven to push whose friction polytope is empty."""
    for k, known in enumerate(proven.tolist()):
        if not known and frictions[k].is_empty:
            warnings.append(f'leg {stance[k]!r} cannot push on the ground within its torque '
                            'limits (empty friction-bounded polytope)')


def _origin_set() -> Polytope:
    """Return {0} in R^6 (no stance leg: every wrench set)."""
    return Polytope(0, np.zeros((1, 6)), np.zeros((0, 6)), np.zeros(0), np.zeros(6),
                    np.zeros((6, 0)))


def _region(P: Polytope, w: np.ndarray, name: str, warnings: list[str]) -> ComRegion | None:
    """
    Return the CoM region of a wrench set at the force and moment of ``w`` [N, N.m].

    A region that is not defined (no vertical force: free fall; a slice that is not
    bounded) or whose computation fails is None, with a warning naming the reason.
    """
    try:
        return com_region(P, w[:3], w[3:])
    except (InputError, GeometryError) as exc:
        warnings.append(f'{name} not computed: {exc}')
        return None


def _capture_point(vcom: np.ndarray | None, p: np.ndarray, gravity: float
                   ) -> np.ndarray | None:
    r"""
    Return the instantaneous capture point relative to the CoM (2,) [m], or None.

    .. math:: \xi - c = \dot c_{xy} / \omega_0, \quad \omega_0 = \sqrt{g / h}

    :param vcom: the CoM velocity ``c'`` (3,) [m/s], world axes (None: unknown).
    :param p: (K, 3) stance feet relative to the CoM [m]: ``h = -mean(p_z)`` is the CoM
        height above their mean height (None without a foot or for ``h <= 0``).
    :param gravity: ``g`` [m/s^2].
    """
    if vcom is None or not p.shape[0]:
        return None
    h = -float(np.mean(p[:, 2]))
    if not h > 0.0:
        return None
    return vcom[:2] * np.sqrt(h / gravity)


def _point_margin(region: ComRegion | None, x: np.ndarray | None) -> float:
    """
    Return the signed distance [m] of the CoM offset ``x`` (2,) to a CoM region.

    Positive inside a polygon (the distance to its nearest edge line), minus the distance
    to the region outside it (always for a segment or a point); NaN when ``x`` or the
    region is None or the region is empty.
    """
    if region is None or x is None or region.is_empty:
        return float('nan')
    if region.dimension == 2:
        inside = float(np.min(region.b - region.A @ x))
        if inside >= 0.0:
            return inside
    V = region.vertices - x
    E = np.roll(V, -1, axis=0) - V
    ee = np.einsum('ij,ij->i', E, E)
    t = np.clip(-np.einsum('ij,ij->i', V, E) / np.where(ee > 0.0, ee, 1.0), 0.0, 1.0)
    Q = V + t[:, None] * E
    return -float(np.sqrt(np.min(np.einsum('ij,ij->i', Q, Q))))


def _contacts_key(state: RobotState) -> tuple:
    """Return a sort key of a state's contacts (stance, normals, friction); ties keep order."""
    def items(mapping) -> tuple:
        try:
            return tuple(sorted((str(k), repr(v)) for k, v in dict(mapping).items()))
        except (TypeError, ValueError):
            return ()
    stance = () if state.stance is None else tuple(str(f) for f in state.stance)
    return (state.stance is None, stance, items(state.normals or {}),
            repr(state.friction_coefficient), items(state.friction_coefficients or {}))
