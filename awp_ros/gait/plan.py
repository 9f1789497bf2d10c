r"""
The gait generator's plan: footholds, swings, the nominal body path and the ZMP windows.

The robot walks straight along world x on flat ground (z = 0, normal +z). The plan is made
in the world frame (REP 103, z up) from the feet's nominal positions in the standing posture
(see :mod:`awp_ros.gait.generator` for the gaits). Base positions are in the horizontal
plane [m]; foot positions in 3D [m]; times [s].

The body path of the plan is *kinematic* (minimum-jerk shifts, the trot's speed ramp): it is
the nominal path that :mod:`awp_ros.gait.balance` turns into a balanced CoM trajectory (its
ZMP reference is the nominal CoM, ``body + com_offset``, projected where the support needs).
The plan also places the footholds (each trot foot lands under its hip's nominal mid-stance
position) and the :class:`ZmpWindow` s, the times where the ZMP is prescribed outside the
support on purpose (the lurch). The base height, bob and roll are added by
:func:`awp_ros.gait.generator.generate_gait` from :meth:`GaitPlan.speed_ratio`.

The lurch's recovery holds the ZMP at the capture point that the window leaves: on the
linear inverted pendulum (:math:`\omega^2 = g / h`, h the standing CoM height), a CoM at
rest at distance :math:`s_0 = n \cdot c_0 - b` from the ZMP line :math:`n \cdot p = b`
moves as :math:`s_0 \cosh(\omega t)`, so after the window's T

.. math::

    (11)\quad \xi = b + s_0 e^{\omega T} \quad \text{(along } n\text{)}
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np

from awp_ros.errors import ModelError
from awp_ros.gait.curves import min_jerk, Piecewise, ramp_distance, smoothstep, swing_foot, whole
from awp_ros.gait.kinematics import quadrants, standing_geometry
from awp_ros.gait.params import GaitParams, GRAVITY
from awp_ros.robot.model import RobotModel

__all__ = ['GaitPlan', 'Swing', 'ZmpWindow', 'nearest_inside', 'lurch_edge']

#: The feet next to each foot (same side, same end) and the diagonally opposite one.
_NEIGHBOURS = {'lf': ('rf', 'lh'), 'rf': ('lf', 'rh'), 'lh': ('lf', 'rh'), 'rh': ('rf', 'lh')}
_OPPOSITE = {'lf': 'rh', 'rf': 'lh', 'lh': 'rf', 'rh': 'lf'}


@dataclass
class Swing:
    """One foot's swing: foot index, lift-off and touch-down times [s], from/to xy [m]."""

    foot: int
    t0: float
    t1: float
    p0: np.ndarray
    p1: np.ndarray


@dataclass(frozen=True)
class ZmpWindow:
    r"""
    A window ``[t0, t1)`` [s] where the ZMP p is prescribed on a line: :math:`n \cdot p = b`.

    Before it, from ``hold`` [s], the body rests over ``start`` (2,) [m] (ZMP and CoM
    there); after it, until ``until`` [s], the ZMP catches the body at ``catch`` (2,) [m],
    the capture point at ``t1`` (equation 11). ``normal`` (2,) unit and ``offset`` b [m]
    define the line (world xy), ``point`` (2,) [m] is the ZMP reference on it. ``name``
    labels the window (e.g. 'lurch').
    """

    name: str
    hold: float
    t0: float
    t1: float
    until: float
    start: np.ndarray
    normal: np.ndarray
    offset: float
    point: np.ndarray
    catch: np.ndarray


@dataclass
class GaitPlan:
    """The nominal base path, the feet's swings and the ZMP windows of a gait sequence."""

    params: GaitParams
    nominal: np.ndarray          # (K, 2) feet xy in the base frame, standing [m]
    com_offset: np.ndarray       # (2,) CoM xy in the base frame, standing [m]
    height: float                # base height above the feet, standing [m]
    com_height: float            # CoM height above the feet, standing [m]
    body: Piecewise
    swings: list = field(default_factory=list)
    trots: list = field(default_factory=list)    # (t0, t1, ramp) [s] of each trot
    windows: list = field(default_factory=list)  # ZmpWindow s
    segments: tuple = ()
    n_samples: int = 0

    @classmethod
    def build(cls, model: RobotModel, params: GaitParams) -> GaitPlan:
        """Plan ``params.sequence``, each gait preceded and followed by standing."""
        nominal3, com = standing_geometry(model)
        order = quadrants(model.config.feet, nominal3)
        height = float(-nominal3[:, 2].mean())
        plan = cls(params, nominal3[:, :2], com[:2], height, height + float(com[2]),
                   Piecewise(np.zeros(2)))
        feet = nominal3[:, :2].copy()
        t = 0.0
        segments = []
        for gait in params.sequence:
            t = plan._stand(t, feet)
            t0 = t
            if gait == 'crawl':
                t = plan._crawl(t, feet, order)
            elif gait == 'lurch':
                t = plan._lurch(t, feet, order)
            elif gait == 'trot':
                t = plan._trot(t, feet, order)
            segments.append((gait, t0, t))
        t = plan._stand(t, feet)
        plan.segments = tuple(segments)
        plan.n_samples = int(round(t * params.rate_hz)) + 1
        return plan

    def _stand(self, t: float, feet: np.ndarray) -> float:
        """Move the base over the centre of the feet (all feet down)."""
        t1 = t + whole(self.params.stand_s, self.params.rate_hz)
        target = feet.mean(axis=0) - self.nominal.mean(axis=0)
        if t1 > t:
            self.body.add(t, t1, min_jerk(t, t1, self.body.end.copy(), target))
        return t1

    def _shift(self, t: float, duration: float, com_target: np.ndarray) -> float:
        """Move the nominal CoM to ``com_target`` (minimum jerk, all feet down)."""
        target = com_target - self.com_offset
        self.body.add(t, t + duration, min_jerk(t, t + duration, self.body.end.copy(),
                                                target))
        return t + duration

    def _crawl(self, t: float, feet: np.ndarray, order: dict) -> float:
        """Plan one static crawl from time ``t`` [s]; update ``feet``; return the end."""
        p = self.params
        shift = whole(p.crawl_shift_s, p.rate_hz)
        swing = whole(p.crawl_swing_s, p.rate_hz)
        step = np.array([p.crawl_step_m, 0.0])
        for _ in range(p.crawl_cycles):
            for name in ('lh', 'lf', 'rh', 'rf'):
                k = order[name]
                others = [i for i in range(feet.shape[0]) if i != k]
                t = self._shift(t, shift, nearest_inside(feet.mean(axis=0), feet[others],
                                                         p.crawl_margin_m))
                self.swings.append(Swing(k, t, t + swing, feet[k].copy(), feet[k] + step))
                feet[k] = feet[k] + step
                t += swing
        return t

    def _lurch(self, t: float, feet: np.ndarray, order: dict) -> float:
        """
        Plan the lurch from time ``t`` [s] (see :func:`lurch_edge`); return its end.

        Shift onto the three other feet (the ZMP ``crawl_margin_m`` inside their triangle),
        lift ``lurch_foot`` in place for ``lurch_lift_s``; ``lurch_delay_s`` after lift-off
        the ZMP is prescribed ``lurch_overshoot_m`` beyond the triangle's edge that faces the
        lifted foot, for ``lurch_s`` (a :class:`ZmpWindow`; shorter on a small robot, see
        :class:`~awp_ros.gait.params.GaitParams`).
        """
        p = self.params
        k = order[p.lurch_foot]
        others = [i for i in range(feet.shape[0]) if i != k]
        start = nearest_inside(feet.mean(axis=0), feet[others], p.crawl_margin_m)
        t = self._shift(t, whole(p.lurch_shift_s, p.rate_hz), start)
        lift = whole(p.lurch_lift_s, p.rate_hz)
        self.swings.append(Swing(k, t, t + lift, feet[k].copy(), feet[k].copy()))
        normal, offset = lurch_edge(feet, order, p.lurch_foot)
        b = offset - p.lurch_overshoot_m
        point = start - (normal @ start - b) * normal
        # Equation 11 (LIP, omega^2 = g / h): from rest at s_0 = n . start - b off the ZMP
        # line, after T the capture point is xi = b + s_0 exp(omega T) along the normal;
        # T is shortened if the CoM would travel more than lurch_travel_ratio * h.
        omega = math.sqrt(GRAVITY / self.com_height)
        s0 = float(normal @ start - b)
        longest = math.log1p(p.lurch_travel_ratio * self.com_height / s0) / omega
        duration = min(whole(p.lurch_s, p.rate_hz),
                       max(1.0, math.floor(longest * p.rate_hz)) / p.rate_hz)
        t0 = whole(t + p.lurch_delay_s, p.rate_hz)
        t1 = whole(t0 + duration, p.rate_hz)
        catch = point + s0 * math.exp(omega * duration) * normal
        self.windows.append(ZmpWindow('lurch', t, t0, t1, t + lift, start, normal, float(b),
                                      point, catch))
        return t + lift

    def _trot(self, t: float, feet: np.ndarray, order: dict) -> float:
        """Plan a trot from time ``t`` [s]; update ``feet``; return the end."""
        p = self.params
        period = whole(p.trot_period_s, p.rate_hz)
        swing = whole((1.0 - p.trot_duty) * p.trot_period_s, p.rate_hz)
        stance = period - swing
        duration = p.trot_cycles * period
        ramp = min(whole(p.trot_ramp_s, p.rate_hz), 0.5 * duration)
        x0 = self.body.end.copy()
        t0 = t
        self.trots.append((t0, t0 + duration, ramp))

        def body(tt: np.ndarray) -> np.ndarray:
            out = np.empty((tt.shape[0], 2))
            out[:, 0] = x0[0] + ramp_distance(tt - t0, duration, ramp, p.trot_speed_mps)
            out[:, 1] = x0[1]
            return out

        self.body.add(t0, t0 + duration, body)
        pairs = (('lf', 'rh'), ('rf', 'lh'))
        for i in range(p.trot_cycles):
            for j, pair in enumerate(pairs):
                lift = t0 + i * period + j * 0.5 * period
                land = lift + swing
                mid_stance = np.array([land + 0.5 * stance])
                hip_xy = body(np.minimum(mid_stance, t0 + duration))[0]
                for name in pair:
                    k = order[name]
                    target = hip_xy + self.nominal[k]
                    self.swings.append(Swing(k, lift, land, feet[k].copy(), target))
                    feet[k] = target
        return t0 + duration

    def speed_ratio(self, t: np.ndarray) -> np.ndarray:
        """Return base speed / trot speed (0 outside trots), the scale of bob and roll."""
        out = np.zeros(t.shape[0])
        for t0, t1, ramp in self.trots:
            u = t - t0
            rise = smoothstep(u / ramp)
            fall = smoothstep((t1 - t0 - u) / ramp)
            out += np.where((t >= t0) & (t <= t1), np.minimum(rise, fall), 0.0)
        return out

    def feet(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return world foot positions (N, K, 3) [m] and stance flags (N, K)."""
        k_feet = self.nominal.shape[0]
        xy = np.empty((t.shape[0], k_feet, 2))
        z = np.zeros((t.shape[0], k_feet))
        stance = np.ones((t.shape[0], k_feet), dtype=bool)
        xy[:] = self.nominal
        for sw in self.swings:   # in time order per foot: later swings overwrite
            after = t >= sw.t0
            xy[after, sw.foot] = sw.p1
            during = after & (t < sw.t1)
            u = (t[during] - sw.t0) / (sw.t1 - sw.t0)
            xy[during, sw.foot], z[during, sw.foot] = swing_foot(u, sw.p0, sw.p1,
                                                                 self.params.swing_height_m)
            stance[during, sw.foot] = False
        return np.concatenate([xy, z[..., None]], axis=-1), stance


def nearest_inside(point: np.ndarray, vertices: np.ndarray, margin: float, *,
                   tol: float = 1e-12) -> np.ndarray:
    r"""
    Return the point nearest to ``point`` at least ``margin`` inside a convex polygon.

    Candidates: the point itself, its projections on the inset edges and the inset
    vertices; the nearest one satisfying every inset halfspace (within ``tol`` [m]) wins.

    .. math:: \arg\min_x \|x - p\| \ \mathrm{s.t.}\ n_i \cdot x \le b_i - m

    :param point: (2,) the point p [m], world xy.
    :param vertices: (m, 2) polygon vertices in order (either orientation) [m].
    :param margin: the inset m [m].
    :raises ModelError: the polygon has no point that far inside.
    """
    edges = np.roll(vertices, -1, axis=0) - vertices
    normals = np.column_stack([edges[:, 1], -edges[:, 0]])
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    centroid = vertices.mean(axis=0)
    sign = np.where(np.einsum('ij,ij->i', normals, centroid - vertices) > 0.0, -1.0, 1.0)
    normals *= sign[:, None]                                  # outward
    b = np.einsum('ij,ij->i', normals, vertices) - margin     # inset: n . x <= b
    m = len(b)
    cand = [point[None, :], point - np.outer(normals @ point - b, np.ones(2)) * normals]
    i, j = np.triu_indices(m, 1)
    A = np.stack([normals[i], normals[j]], axis=1)
    ok = np.abs(np.linalg.det(A)) > tol
    cand.append(np.linalg.solve(A[ok], np.column_stack([b[i], b[j]])[ok][..., None])[..., 0])
    cand = np.concatenate(cand)
    inside = (cand @ normals.T <= b + tol).all(axis=1)
    if not inside.any():
        raise ModelError(f'the support polygon {np.round(vertices, 3).tolist()} has no point '
                         f'{margin} m inside; lower crawl_margin_m')
    cand = cand[inside]
    return cand[np.argmin(np.linalg.norm(cand - point, axis=1))]


def lurch_edge(feet: np.ndarray, order: dict, foot: str) -> tuple[np.ndarray, float]:
    r"""
    Return the support triangle's edge facing a lifted foot: inward normal n and offset b.

    The triangle of the three other feet has its edge through the lifted foot's two
    neighbours (for 'lf': 'rf' and 'lh', a diagonal); inside is :math:`n \cdot x \ge b`
    (toward the opposite foot).

    :param feet: (4, >= 2) foot positions, world [m].
    :param order: quadrant name -> foot index.
    :param foot: the lifted foot's quadrant ('lf', 'rf', 'lh', 'rh').
    """
    a, c = (feet[order[name], :2] for name in _NEIGHBOURS[foot])
    d = (c - a) / np.linalg.norm(c - a)
    normal = np.array([-d[1], d[0]])
    if normal @ (feet[order[_OPPOSITE[foot]], :2] - a) < 0.0:
        normal = -normal
    return normal, float(normal @ a)
