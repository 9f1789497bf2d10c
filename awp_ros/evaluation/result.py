"""
The result objects of one evaluation and their JSON form (``awp_eval``'s output).

Frames: world-aligned axes, origin at the whole-robot CoM (base at the world origin with the
measured orientation); forces [N], moments [N.m], positions [m]. See
:mod:`awp_ros.evaluation.evaluator` for how each field is computed; the JSON keys are documented in
:mod:`awp_ros.cli.eval`. Non-finite numbers become ``None`` (strict JSON).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
import math

import numpy as np

from awp_ros.geometry.margin import SetMargin
from awp_ros.geometry.polytope import Polytope
from awp_ros.wrench.com_region import ComRegion
from awp_ros.wrench.contact_forces import MeasuredForces

__all__ = ['AXES', 'FeasibilityResult', 'LegResult', 'REGIONS', 'WrenchSetResult',
           'directional_by_axis', 'margin_dict', 'region_dict']

#: Names of the wrench axes, in the order of every 6-vector: force [N], moment [N.m].
AXES = ('fx', 'fy', 'fz', 'mx', 'my', 'mz')
#: The CoM regions of a result (attributes of :class:`FeasibilityResult`, JSON keys).
REGIONS = ('feasible_region', 'support_region', 'fwp_region')


@dataclass
class LegResult:
    """
    The polytopes of one stance leg (forces [N] on the robot, world axes).

    ``position``: foot relative to the CoM [m]; ``normal``: unit contact normal;
    ``singular``: J rank-deficient, the force polytope is the seed's pseudo-inverse image;
    ``near_singular``: exact, but J is badly conditioned; ``friction``: the
    friction-bounded polytope, or a callable returning it, called on the first access to
    :attr:`friction_polytope` (it is then replaced by its value).
    """

    foot: str
    position: np.ndarray
    normal: np.ndarray
    friction_coefficient: float
    force_polytope: Polytope
    friction: Polytope | Callable[[], Polytope]
    singular: bool
    near_singular: bool

    @property
    def friction_polytope(self) -> Polytope:
        """Return the friction-bounded force polytope [N] (computed on first use)."""
        if callable(self.friction):
            self.friction = self.friction()
        return self.friction

    def to_dict(self) -> dict:
        """Return the leg as JSON-ready builtins."""
        return {
            'position': _floats(self.position),
            'normal': _floats(self.normal),
            'friction_coefficient': self.friction_coefficient,
            'singular': self.singular,
            'near_singular': self.near_singular,
            'force_polytope': _polytope_dict(self.force_polytope),
            'friction_polytope': _polytope_dict(self.friction_polytope),
        }


@dataclass
class WrenchSetResult(SetMargin):
    """
    A 6D wrench set (AWP, FWP or FWS) and the margin of the evaluated wrench.

    The margin fields are those of :class:`~awp_ros.geometry.margin.SetMargin`:

    ``margin`` [N, N.m]: signed margin, positive only when ``w`` is in the set (the distance
    to its boundary), negative whenever it is not (minus the distance from ``w`` to the set,
    off its affine hull included); ``margin_in_hull``: the margin of ``w``'s projection on
    the affine hull, measured inside it (equal to ``margin`` for 6D sets);
    ``normal``: unit witness (outward normal of the nearest facet, or direction from the set
    to ``w``); ``dimension``: affine dimension (-1 empty, 0 for no stance leg, 3 for one leg,
    5 for two, 6 otherwise); ``affine_residual``: distance of ``w`` to the hull;
    ``feasible``: ``margin >= -feasibility_tol``;
    ``directional``: axis -> (plus, minus) extra admissible force [N] / moment [N.m];
    ``region``: the set's CoM region for the evaluated force and moment
    (:func:`~awp_ros.wrench.com_region.com_region`: the FWP region of the FWP, the feasible
    region of the FWS; None when not computed); ``capture_point_margin``: signed distance
    [m] of the instantaneous capture point to ``region`` (NaN without a CoM velocity or a
    non-empty region).
    """

    name: str
    polytope: Polytope
    directional: dict[str, tuple[float, float]] | None = None
    region: ComRegion | None = None
    capture_point_margin: float = math.nan

    @classmethod
    def from_margin(cls, name: str, polytope: Polytope, m: SetMargin) -> WrenchSetResult:
        """Wrap a polytope and its :class:`~awp_ros.geometry.margin.SetMargin`."""
        return cls(margin=float(m.margin), normal=np.asarray(m.normal, dtype=float),
                   dimension=int(m.dimension), affine_residual=float(m.affine_residual),
                   feasible=bool(m.feasible), margin_in_hull=float(m.margin_in_hull),
                   name=name, polytope=polytope)

    def to_dict(self, *, halfspaces: bool = True) -> dict:
        """
        Return the set as JSON-ready builtins (non-finite numbers become None).

        ``halfspaces`` rows are ``[a_1 .. a_6, b]`` with ``a . x <= b``; for a flat set the
        affine hull is ``hull_origin + span(hull_basis columns)``.
        """
        out = margin_dict(self)
        if halfspaces:
            P = self.polytope
            out['halfspaces'] = _rows(P.halfspaces()) if not P.is_empty else []
            out['hull_origin'] = _floats(P.hull_origin)
            out['hull_basis'] = _rows(P.hull_basis.T)
        if self.directional is not None:
            out['directional'] = {axis: {'plus': _float(p), 'minus': _float(m)}
                                  for axis, (p, m) in self.directional.items()}
        return out


@dataclass
class FeasibilityResult:
    """
    Everything one evaluation computed (see the module docstring).

    ``com`` [m] is in the world frame with the base at the origin; ``wrench`` [N, N.m] is
    the gravito-inertial wrench the contacts must supply, about the CoM; ``legs`` maps each
    stance foot (config order) to its :class:`LegResult`; ``fws`` is None when not requested.
    ``timings_ms`` [ms]: one entry per stage, ``com_regions`` (the support and feasible
    regions, within ``regions``), ``total`` (the per-cycle evaluation without the FWS) and,
    once the FWS is computed, ``fws``, ``fws_directional`` and ``fws_margin``.
    ``motion``: ``'measured'`` when the state carried accelerations (the wrench and the leg
    biases include the dynamics terms), else ``'quasi_static'`` (no accelerations; joint
    velocities, when given, still enter the bias torques and the velocity-product terms).
    ``measured``: the contact forces from the joint efforts, when the state had efforts.

    CoM regions (:mod:`awp_ros.wrench.com_region`; world-aligned x/y, origin the current
    CoM, [m]; each a :class:`~awp_ros.wrench.com_region.ComRegion` with ``vertices``
    (counter-clockwise), ``A``, ``b``, ``dimension`` (2 polygon, 1 segment: two stance legs,
    0 point: one leg, -1 empty) and the signed ``margin`` of the CoM, NaN when empty):
    ``support_region`` (slice of the CWC ``cwc``: friction only) and ``fwp_region`` (slice
    of the FWP) every cycle, ``feasible_region`` (torque limits and friction with one force
    distribution: the FWS's slice) every cycle too, by projection
    (``feasible_region_per_cycle``, :func:`~awp_ros.wrench.com_region.feasible_region`),
    or from the FWS when that is not available (a singular leg); each None when not
    computed; ``capture_margin_per_cycle`` the capture point's margin to the per-cycle one;
    ``two_leg_fws_feasible``: with two stance legs, whether the wrench is in the FWS this
    cycle, without the FWS (:attr:`fws_feasible_per_cycle`; None otherwise);
    ``fws_directional_per_cycle``: with three or more stance legs, the FWS's directional
    margins at ``wrench`` this cycle, without the FWS (axis -> (plus, minus), as
    :attr:`WrenchSetResult.directional`;
    :func:`~awp_ros.wrench.fws_queries.directional_margins_of_legs`), else None.
    ``fws_margin_per_cycle``: with three or more stance legs and ``wrench`` outside the FWS
    (the feasible region without the CoM), the FWS's signed margin (minus the distance to it)
    and witness this cycle, without the FWS
    (:class:`~awp_ros.geometry.margin.SetMargin`;
    :func:`~awp_ros.wrench.fws_queries.outside_margin_of_points`), else None (inside, the
    margin is the distance to the nearest facet: the FWS's H-rep gives it).
    ``com_velocity``: ``c'`` (3,) [m/s], world axes, when the state had a ``base_twist``
    (else None); ``capture_point``: the instantaneous capture point ``c' / omega_0``
    (``omega_0 = sqrt(g / h)``, ``h`` the CoM height above the stance feet's mean height)
    relative to the CoM (2,) [m], or None; ``capture_point_margin``: its signed distance
    [m] to the feasible region (NaN without it).
    """

    robot: str
    stance: tuple[str, ...]
    mass: float
    com: np.ndarray
    wrench: np.ndarray
    legs: dict[str, LegResult]
    awp: WrenchSetResult
    fwp: WrenchSetResult
    fws: WrenchSetResult | None
    warnings: list[str]
    timings_ms: dict[str, float]
    motion: str = 'quasi_static'
    measured: MeasuredForces | None = None
    cwc: Polytope | None = None
    support_region: ComRegion | None = None
    com_velocity: np.ndarray | None = None
    capture_point: np.ndarray | None = None
    feasible_region_per_cycle: ComRegion | None = None
    capture_margin_per_cycle: float = math.nan
    two_leg_fws_feasible: bool | None = None
    fws_directional_per_cycle: dict[str, tuple[float, float]] | None = None
    fws_margin_per_cycle: SetMargin | None = None

    @property
    def feasible_region(self) -> ComRegion | None:
        """Return the feasible region: every cycle by projection, else the FWS's slice."""
        if self.feasible_region_per_cycle is not None:
            return self.feasible_region_per_cycle
        return None if self.fws is None else self.fws.region

    def feasible_region_with(self, fws: WrenchSetResult | None
                             ) -> tuple[ComRegion | None, float]:
        """
        Return the feasible region and the capture point's margin [m] to it.

        This cycle's (by projection) when computed, else those of ``fws`` (the latest FWS,
        e.g. of an earlier cycle; None and NaN without it).
        """
        if self.feasible_region_per_cycle is not None:
            return self.feasible_region_per_cycle, self.capture_margin_per_cycle
        if fws is None:
            return None, math.nan
        return fws.region, fws.capture_point_margin

    @property
    def fwp_region(self) -> ComRegion | None:
        """Return the FWP region (the FWP's slice)."""
        return self.fwp.region

    @property
    def capture_point_margin(self) -> float:
        """Return the capture point's signed distance [m] to the feasible region, or NaN."""
        if self.feasible_region_per_cycle is not None:
            return self.capture_margin_per_cycle
        return math.nan if self.fws is None else self.fws.capture_point_margin

    @property
    def status(self) -> str:
        """Return ``'ok'``, or ``'warning'`` when a warning was recorded."""
        return 'warning' if self.warnings else 'ok'

    @property
    def fws_feasible_per_cycle(self) -> bool | None:
        r"""
        Return whether ``w`` is in the FWS, from this cycle's sets; None if unknown.

        .. math:: R = \{\delta : [f;\ \dot L + \delta \times f] \in \mathrm{FWS}\},
                  \qquad 0 \in R \iff w \in \mathrm{FWS}

        The feasible region is the FWS's slice through ``w`` (``delta = 0`` gives ``w``
        itself), so the current CoM lies in it exactly when the wrench is in the FWS: the
        FWS's verdict every cycle, without its H-rep. Given with three or more stance legs
        (a 6D FWS: the region is a polygon, or empty when no CoM position balances ``w``),
        when the region was computed this cycle (``feasible_region_per_cycle``), with
        :meth:`~awp_ros.wrench.com_region.ComRegion.contains`'s tolerance (1e-9 m). With two
        legs (a 5D FWS, whose verdict allows ``w`` off its hull by the hull tolerance; the
        region is a segment): ``two_leg_fws_feasible``, the one-dimensional LP of the legs'
        force distributions (:func:`~awp_ros.wrench.fws_queries.two_leg_contains`), with the
        FWS's hull and feasibility tolerances. None otherwise (no verdict this cycle: a
        singular leg, one leg, no region).
        """
        if len(self.stance) == 2:
            return self.two_leg_fws_feasible
        region = self.feasible_region_per_cycle
        if region is None or len(self.stance) < 3:
            return None
        return region.contains_origin()

    @property
    def feasible(self) -> bool:
        """
        Return whether ``w`` is in the FWS: the FWS's verdict when computed, else this cycle's.

        Without the FWS: :attr:`fws_feasible_per_cycle` (with the FWP's verdict, its superset)
        when known, else the FWP's verdict.
        """
        if self.fws is not None:
            return self.fws.feasible
        per_cycle = self.fws_feasible_per_cycle
        return self.fwp.feasible if per_cycle is None else bool(per_cycle and self.fwp.feasible)

    def to_dict(self, *, halfspaces: bool = True) -> dict:
        """Return the result as the JSON document ``awp_eval`` prints."""
        return {
            'robot': self.robot,
            'status': self.status,
            'warnings': list(self.warnings),
            'feasible': self.feasible,
            'stance': list(self.stance),
            'motion': self.motion,
            'mass': self.mass,
            'com': _floats(self.com),
            'wrench': _floats(self.wrench),
            'legs': {foot: leg.to_dict() for foot, leg in self.legs.items()},
            'awp': self.awp.to_dict(halfspaces=halfspaces),
            'fwp': self.fwp.to_dict(halfspaces=halfspaces),
            'fws': None if self.fws is None else self.fws.to_dict(halfspaces=halfspaces),
            'measured_forces': None if self.measured is None else _measured_dict(self.measured),
            **{name: region_dict(getattr(self, name)) for name in REGIONS},
            'com_velocity': None if self.com_velocity is None else _floats(self.com_velocity),
            'capture_point': None if self.capture_point is None else _floats(self.capture_point),
            'capture_point_margin': _float(self.capture_point_margin),
            'fws_directional_per_cycle': None if self.fws_directional_per_cycle is None else {
                axis: {'plus': _float(p), 'minus': _float(m)}
                for axis, (p, m) in self.fws_directional_per_cycle.items()},
            'fws_margin_per_cycle': None if self.fws_margin_per_cycle is None
            else margin_dict(self.fws_margin_per_cycle),
            'timings_ms': dict(self.timings_ms),
        }


def margin_dict(m: SetMargin) -> dict:
    """Return a margin's fields as JSON-ready builtins (non-finite numbers become None)."""
    return {
        'margin': _float(m.margin),
        'margin_in_hull': _float(m.margin_in_hull),
        'normal': _floats(m.normal),
        'dimension': int(m.dimension),
        'affine_residual': _float(m.affine_residual),
        'feasible': bool(m.feasible),
    }


def directional_by_axis(t_plus: Sequence[float], t_minus: Sequence[float]
                        ) -> dict[str, tuple[float, float]]:
    """Return directional margins ``(t_plus, t_minus)`` (6,) [N, N.m] as axis -> (plus, minus)."""
    return {axis: (float(a), float(b)) for axis, a, b in zip(AXES, t_plus, t_minus)}


def region_dict(region: ComRegion | None) -> dict | None:
    """
    Return a CoM region as JSON-ready builtins (None when not computed).

    ``{"dimension": d, "vertices": [[x, y], ...], "halfspaces": [[a_x, a_y, b], ...],
    "margin": m, "area": a}``: [m] and [m^2], world-aligned x/y relative to the CoM; the
    vertices counter-clockwise, ``a . delta <= b`` with unit ``a``; ``margin`` None (JSON
    ``null``) when the region is empty.
    """
    if region is None:
        return None
    return {'dimension': int(region.dimension), 'vertices': _rows(region.vertices),
            'halfspaces': _rows(np.column_stack([region.A, region.b])),
            'margin': _float(region.margin), 'area': float(region.area)}


# -- JSON helpers ------------------------------------------------------------------------


def _measured_dict(m: MeasuredForces) -> dict:
    return {'forces': {f: _floats(v) for f, v in m.forces.items()},
            'slip_margins': {f: _float(v) for f, v in m.slip_margins.items()},
            'torque_ratios': {f: _float(v) for f, v in m.torque_ratios.items()},
            'slip_foot': m.slip_foot, 'slip_margin': _float(m.slip_margin),
            'torque_ratio': _float(m.torque_ratio),
            'external_wrench': _floats(m.external_wrench)}


def _float(x: float) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def _floats(x: np.ndarray) -> list:
    return [_float(v) for v in np.asarray(x, dtype=float).ravel()]


def _rows(X: np.ndarray) -> list:
    X = np.asarray(X, dtype=float)
    if np.isfinite(X).all():
        return X.tolist()
    return [_floats(row) for row in X]


def _polytope_dict(P: Polytope) -> dict:
    out = {
        'dimension': int(P.dimension),
        'vertices': _rows(P.vertices),
        'halfspaces': _rows(P.halfspaces()) if not P.is_empty else [],
    }
    if 0 <= P.dimension < P.ambient_dim:          # flat: halfspaces hold within the hull
        out['hull_origin'] = _floats(P.hull_origin)
        out['hull_basis'] = _rows(P.hull_basis.T)
    return out
