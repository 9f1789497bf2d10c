"""The feasibility evaluator: one object per robot, one call per state, one result object.

Pipeline of :meth:`FeasibilityEvaluator.evaluate` (frames: world-aligned axes, origin at the
whole-robot CoM; SI units). Stage names are the keys of ``timings_ms``:

1. ``validate``: the :class:`~awp_ros.state.RobotState` against the model (InputError).
2. ``model``: Pinocchio update, base at the origin with the measured orientation: bias
   torques ``rnea(q, v, a)``, LOCAL_WORLD_ALIGNED foot Jacobians, CoM, mass and the
   gravito-inertial wrench ``w = [m (c'' - g); L']`` (quasi-static ``[0, 0, m g, 0, 0, 0]``).
3. ``force_polytopes``: per stance leg :math:`\\{f : \\tau_{min} \\le b - J^T f \\le
   \\tau_{max}\\}` (closed-form parallelepipeds for 3-joint legs, batched).
4. ``friction_polytopes``: each ∩ its friction pyramid ∩ ``n . f >= 0``.
5. ``awp``: :math:`\\sum_k L_k \\mathcal F_k`, a zonotope with 3K generators when every leg
   is a parallelepiped (or a singular leg's flat image), else the exact Minkowski sum.
6. ``cwc_fwp``: the contact wrench cone and FWP = AWP ∩ CWC (the seed's FWP).
7. ``margins``: signed Euclidean margins and witnesses of ``w`` for AWP and FWP.
8. ``fws``: the feasible wrench set :math:`\\sum_k L_k \\mathcal F_{\\mu,k}` (exact H-rep),
   ``fws_directional``: how far ``w`` can move along each wrench axis inside it, and
   ``fws_margin``: its signed Euclidean margin. FWS ⊆ FWP ⊆ AWP: the FWP only asks that
   *some* force distribution respects the torques and *some* (possibly other) distribution
   respects friction; the FWS asks for one distribution that respects both, per leg.

``total`` is the sum of every stage but ``fws_margin``: the per-cycle evaluation including
the FWS H-rep and its directional margins (``evaluate(..., fws=False)`` leaves the three FWS
stages out; :meth:`FeasibilityEvaluator.add_fws` adds them later, e.g. at a lower rate).
"""

from __future__ import annotations

from dataclasses import dataclass
import math
import time

import numpy as np

from awp_ros.contact_wrench_cone import contact_wrench_cone
from awp_ros.errors import ConfigError
from awp_ros.feasible_wrench_set import feasible_wrench_set, minkowski_sum_of_lifts
from awp_ros.force_polytope import force_polytope, parallelepipeds
from awp_ros.friction_polytope import friction_polytopes, friction_rows
from awp_ros.margin import directional_margins, polytope_margin, SetMargin
from awp_ros.polytope import Polytope
from awp_ros.robot_config import load_config, RobotConfig
from awp_ros.robot_model import RobotModel
from awp_ros.state import resolve_state, RobotState
from awp_ros.wrench_polytope import actuation_wrench_polytope, feasible_wrench_polytope

__all__ = ['AXES', 'FeasibilityEvaluator', 'FeasibilityResult', 'LegResult',
           'WrenchSetResult']

#: Names of the wrench axes, in the order of every 6-vector: force [N], moment [N.m].
AXES = ('fx', 'fy', 'fz', 'mx', 'my', 'mz')


@dataclass
class LegResult:
    """The polytopes of one stance leg (forces [N] on the robot, world axes).

    ``position``: foot relative to the CoM [m]; ``normal``: unit contact normal;
    ``singular``: J rank-deficient, the force polytope is the seed's pseudo-inverse image;
    ``near_singular``: exact, but J is badly conditioned.
    """

    foot: str
    position: np.ndarray
    normal: np.ndarray
    friction_coefficient: float
    force_polytope: Polytope
    friction_polytope: Polytope
    singular: bool
    near_singular: bool

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
class WrenchSetResult:
    """A 6D wrench set (AWP, FWP or FWS) and the margin of the evaluated wrench.

    ``margin`` [N, N.m]: signed distance inside the affine hull (positive inside);
    ``normal``: unit witness (outward normal of the nearest facet, or direction from the set
    to ``w``); ``dimension``: affine dimension (-1 empty, 0 for no stance leg, 3 for one leg,
    5 for two, 6 otherwise); ``affine_residual``: distance of ``w`` to the hull;
    ``directional``: axis -> (plus, minus) extra admissible force [N] / moment [N.m].
    """

    name: str
    polytope: Polytope
    margin: float
    normal: np.ndarray
    dimension: int
    affine_residual: float
    feasible: bool
    directional: dict[str, tuple[float, float]] | None = None

    @classmethod
    def from_margin(cls, name: str, polytope: Polytope, m: SetMargin) -> WrenchSetResult:
        """Wrap a polytope and its :class:`~awp_ros.margin.SetMargin`."""
        return cls(name, polytope, float(m.margin), np.asarray(m.normal, dtype=float),
                   int(m.dimension), float(m.affine_residual), bool(m.feasible))

    def to_dict(self, *, halfspaces: bool = True) -> dict:
        """Return the set as JSON-ready builtins (non-finite numbers become None).

        ``halfspaces`` rows are ``[a_1 .. a_6, b]`` with ``a . x <= b``; for a flat set the
        affine hull is ``hull_origin + span(hull_basis columns)``.
        """
        out = {
            'margin': _float(self.margin),
            'normal': _floats(self.normal),
            'dimension': self.dimension,
            'affine_residual': _float(self.affine_residual),
            'feasible': self.feasible,
        }
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
    """Everything one evaluation computed (see the module docstring).

    ``com`` [m] is in the world frame with the base at the origin; ``wrench`` [N, N.m] is
    the gravito-inertial wrench the contacts must supply, about the CoM; ``legs`` maps each
    stance foot (config order) to its :class:`LegResult`; ``fws`` is None when not requested.
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

    @property
    def status(self) -> str:
        """Return ``'ok'``, or ``'warning'`` when a warning was recorded."""
        return 'warning' if self.warnings else 'ok'

    @property
    def feasible(self) -> bool:
        """Return whether ``w`` is in the FWS (when computed), else in the FWP."""
        return (self.fws if self.fws is not None else self.fwp).feasible

    def to_dict(self, *, halfspaces: bool = True) -> dict:
        """Return the result as the JSON document ``awp_eval`` prints."""
        return {
            'robot': self.robot,
            'status': self.status,
            'warnings': list(self.warnings),
            'feasible': self.feasible,
            'stance': list(self.stance),
            'mass': self.mass,
            'com': _floats(self.com),
            'wrench': _floats(self.wrench),
            'legs': {foot: leg.to_dict() for foot, leg in self.legs.items()},
            'awp': self.awp.to_dict(halfspaces=halfspaces),
            'fwp': self.fwp.to_dict(halfspaces=halfspaces),
            'fws': None if self.fws is None else self.fws.to_dict(halfspaces=halfspaces),
            'timings_ms': dict(self.timings_ms),
        }


class FeasibilityEvaluator:
    """Compute force polytopes, AWP, FWP, FWS and margins of a robot, one state at a time.

    :param config: a :class:`RobotConfig`, or a config name / YAML path for
        :func:`~awp_ros.robot_config.load_config`.
    :param singular_rtol: a leg whose Jacobian has smallest / largest singular value below
        this is singular (pseudo-inverse image, warning).
    :param near_singular_rtol: below this ratio a leg is flagged near-singular (warning).
    :param feasibility_tol: tolerance of ``feasible`` on margins and hull residuals
        [N, N.m].
    :raises ConfigError: bad config; :raises ModelError: unusable URDF.

    Not thread-safe: the evaluator owns one Pinocchio ``Data`` and reuses its buffers; use
    one evaluator per thread.
    """

    def __init__(self, config: RobotConfig | str = 'hyq', *, singular_rtol: float = 1e-9,
                 near_singular_rtol: float = 1e-2, feasibility_tol: float = 1e-6) -> None:
        self.config = config if isinstance(config, RobotConfig) else load_config(config)
        self.model = RobotModel(self.config)
        self.singular_rtol = singular_rtol
        self.near_singular_rtol = near_singular_rtol
        self.feasibility_tol = feasibility_tol
        legs = self.model.legs
        self._three_joint = all(len(leg.joints) == 3 for leg in legs.values())
        self._tau_min = {f: leg.tau_min for f, leg in legs.items()}
        self._tau_max = {f: leg.tau_max for f, leg in legs.items()}
        self._rows_cache: tuple | None = None
        self._limit_cache: dict[tuple[str, ...], tuple[np.ndarray, np.ndarray]] = {}

    @property
    def feet(self) -> tuple[str, ...]:
        """Return the config's feet (contact frames)."""
        return self.config.feet

    def standing_state(self, **kw) -> RobotState:
        """Return a :class:`RobotState` at the config's standing posture (kw override)."""
        if self.model.standing_q is None:
            raise ConfigError(f'robot {self.config.robot_name!r} has no standing_posture')
        joints = dict(zip(self.model.joint_names, self.model.standing_q.tolist()))
        return RobotState(joint_positions=joints, **kw)

    def evaluate(self, state: RobotState, *, fws: bool = True) -> FeasibilityResult:
        """Evaluate one state (see the module docstring for the stages).

        :param state: the robot state.
        :param fws: also compute the FWS, its directional margins and Euclidean margin.
        :return: the :class:`FeasibilityResult`.
        :raises InputError: invalid state (the message names the bad value).
        """
        clock = time.perf_counter
        t = {}
        t0 = clock()
        cfg = self.config
        s = resolve_state(state, self.model.joint_names, cfg.feet,
                          default_normal=cfg.unit_normal, default_mu=cfg.friction_coefficient,
                          position_limits=self.model.position_limits)
        warnings = s.warnings
        t1 = clock()
        t['validate'] = t1 - t0
        kin = self.model.kinematics(s.q, s.stance, quaternion=s.quaternion, v=s.v, a=s.a)
        w = kin.wrench
        p = kin.p_foot__com
        t2 = clock()
        t['model'] = t2 - t1
        forces = self._force_polytopes(s.stance, kin.J, kin.bias, warnings)
        t3 = clock()
        t['force_polytopes'] = t3 - t2
        sides = cfg.pyramid_sides
        frictions = friction_polytopes(forces, self._friction_rows(s.normals, s.mus))
        for foot, Q in zip(s.stance, frictions):
            if Q.is_empty:
                warnings.append(f'leg {foot!r} cannot push on the ground within its torque '
                                'limits (empty friction-bounded polytope)')
        t4 = clock()
        t['friction_polytopes'] = t4 - t3
        if s.stance:
            awp = self._awp(p, forces)
            t5 = clock()
            cwc = contact_wrench_cone(p, s.normals, s.mus, sides)
            fwp = feasible_wrench_polytope(awp, cwc)
        else:
            awp = fwp = _origin_set()
            t5 = clock()
        t6 = clock()
        t['awp'] = t5 - t4
        t['cwc_fwp'] = t6 - t5
        tol = self.feasibility_tol
        awp_r = WrenchSetResult.from_margin('awp', awp, polytope_margin(
            awp, w, feasibility_tol=tol))
        fwp_r = WrenchSetResult.from_margin('fwp', fwp, polytope_margin(
            fwp, w, feasibility_tol=tol))
        t7 = clock()
        t['margins'] = t7 - t6
        legs = {foot: LegResult(foot, p[k], s.normals[k], float(s.mus[k]), forces[k],
                                frictions[k], bool(forces[k].meta['singular']),
                                bool(forces[k].meta['near_singular']))
                for k, foot in enumerate(s.stance)}
        timings = {name: 1e3 * dt for name, dt in t.items()}
        timings['total'] = sum(timings.values())
        result = FeasibilityResult(cfg.robot_name, s.stance, kin.mass, kin.com, w, legs,
                                   awp_r, fwp_r, None, warnings, timings)
        if fws:
            self.add_fws(result)
        return result

    def add_fws(self, result: FeasibilityResult) -> FeasibilityResult:
        """Compute the FWS of an evaluated state and store it in ``result.fws``.

        Lets a caller run :meth:`evaluate` with ``fws=False`` every cycle and add the FWS
        (exact H-rep, directional margins, Euclidean margin) at a lower rate. Adds the
        ``fws``, ``fws_directional`` and ``fws_margin`` timings; ``total`` grows by the
        first two.

        :return: ``result``, updated in place.
        """
        clock = time.perf_counter
        tol = self.feasibility_tol
        w = result.wrench
        t0 = clock()
        if result.legs:
            p = np.array([leg.position for leg in result.legs.values()])
            S = feasible_wrench_set(p, [leg.friction_polytope for leg in result.legs.values()])
        else:
            S = _origin_set()
        t1 = clock()
        plus, minus = directional_margins(S, w, feasibility_tol=tol)
        t2 = clock()
        fws_r = WrenchSetResult.from_margin('fws', S, polytope_margin(
            S, w, feasibility_tol=tol))
        fws_r.directional = {axis: (float(a), float(b)) for axis, a, b in zip(AXES, plus, minus)}
        t3 = clock()
        result.fws = fws_r
        tm = result.timings_ms
        tm['fws'] = 1e3 * (t1 - t0)
        tm['fws_directional'] = 1e3 * (t2 - t1)
        tm['fws_margin'] = 1e3 * (t3 - t2)
        tm['total'] = sum(v for k, v in tm.items() if k not in ('total', 'fws_margin'))
        return result

    # -- stages ------------------------------------------------------------------------

    def _friction_rows(self, normals: np.ndarray, mus: np.ndarray) -> np.ndarray:
        """Return the pyramid rows of the stance legs (cached while contacts are unchanged)."""
        key = (normals.tobytes(), mus.tobytes())
        if self._rows_cache is None or self._rows_cache[0] != key:
            self._rows_cache = (key, friction_rows(normals, mus, self.config.pyramid_sides))
        return self._rows_cache[1]

    def _force_polytopes(self, stance: tuple[str, ...], J: list, bias: list,
                         warnings: list[str]) -> list[Polytope]:
        """Return the force polytope of each stance leg (batched for 3-joint legs)."""
        K = len(stance)
        out: list[Polytope | None] = [None] * K
        if self._three_joint and K:
            lo, hi = self._limits(stance)
            pp = parallelepipeds(np.array(J), np.array(bias), lo, hi,
                                 singular_rtol=self.singular_rtol)
            ratio = pp['sigma_ratio'].tolist()
            center, gen, V, A, b = (pp[key] for key in ('center', 'generators', 'vertices',
                                                        'A', 'b'))
            eye, zero = np.eye(3), np.zeros(3)
            for k in range(K):
                if ratio[k] > self.singular_rtol:
                    meta = {'singular': False,
                            'near_singular': ratio[k] <= self.near_singular_rtol,
                            'sigma_ratio': ratio[k], 'center': center[k],
                            'generators': gen[k]}
                    out[k] = Polytope(3, V[k], A[k], b[k], zero, eye, meta)
        for k, foot in enumerate(stance):
            if out[k] is None:
                out[k] = force_polytope(J[k], bias[k], self._tau_min[foot],
                                        self._tau_max[foot], singular_rtol=self.singular_rtol,
                                        near_singular_rtol=self.near_singular_rtol)
            meta = out[k].meta
            if meta['singular']:
                warnings.append(f'leg {foot!r} is singular (sigma ratio '
                                f'{meta["sigma_ratio"]:.2e}); its force polytope is the '
                                'pseudo-inverse image (flat)')
            elif meta['near_singular']:
                warnings.append(f'leg {foot!r} is near-singular (sigma ratio '
                                f'{meta["sigma_ratio"]:.2e})')
        return out

    def _limits(self, stance: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
        """Return the stacked torque limits (K, n) of a stance set (cached per set)."""
        lim = self._limit_cache.get(stance)
        if lim is None:
            lim = (np.array([self._tau_min[f] for f in stance]),
                   np.array([self._tau_max[f] for f in stance]))
            self._limit_cache[stance] = lim
        return lim

    def _awp(self, p: np.ndarray, forces: list[Polytope]) -> Polytope:
        """Return the AWP: zonotope fast path, or the exact sum of lifted vertex sets."""
        if all('generators' in F.meta and F.meta['generators'].shape == (3, 3)
               for F in forces):
            centers = np.array([F.meta['center'] for F in forces])
            generators = np.array([F.meta['generators'] for F in forces])
            return actuation_wrench_polytope(p, centers, generators)
        return minkowski_sum_of_lifts(p, [F.vertices for F in forces])


# -- helpers -------------------------------------------------------------------------------


def _origin_set() -> Polytope:
    """Return {0} in R^6 (no stance leg: every wrench set)."""
    return Polytope(0, np.zeros((1, 6)), np.zeros((0, 6)), np.zeros(0), np.zeros(6),
                    np.zeros((6, 0)))


def _float(x: float) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def _floats(x: np.ndarray) -> list:
    return [_float(v) for v in np.asarray(x, dtype=float).ravel()]


def _rows(X: np.ndarray) -> list:
    X = np.asarray(X, dtype=float)
    if np.all(np.isfinite(X)):
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
