"""
The gait generator's plan: where the base and every foot are, in the world, over time.

The robot walks straight along world x on flat ground (z = 0, normal +z). The plan is made
in the world frame (REP 103, z up) from the feet's nominal positions in the standing posture
(see :mod:`awp_ros.gait.generator` for the gaits). Base positions are in the horizontal plane [m];
foot positions in 3D [m]; times [s]. The base height, bob and roll are added by
:func:`awp_ros.gait.generator.generate_gait` from :meth:`GaitPlan.speed_ratio`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from awp_ros.errors import ModelError
from awp_ros.gait.curves import min_jerk, Piecewise, ramp_distance, smoothstep, swing_foot, whole
from awp_ros.gait.kinematics import quadrants, standing_geometry
from awp_ros.robot.model import RobotModel

if TYPE_CHECKING:
    from awp_ros.gait.generator import GaitParams

__all__ = ['GaitPlan', 'Swing', 'nearest_inside']


@dataclass
class Swing:
    """One foot's swing: foot index, lift-off and touch-down times [s], from/to xy [m]."""

    foot: int
    t0: float
    t1: float
    p0: np.ndarray
    p1: np.ndarray


@dataclass
class GaitPlan:
    """The base's horizontal path and the feet's swings of a whole gait sequence."""

    params: GaitParams
    nominal: np.ndarray          # (K, 2) feet xy in the base frame, standing [m]
    com_offset: np.ndarray       # (2,) CoM xy in the base frame, standing [m]
    height: float                # base height above the feet, standing [m]
    body: Piecewise
    swings: list = field(default_factory=list)
    trots: list = field(default_factory=list)    # (t0, t1, ramp) [s] of each trot
    segments: tuple = ()
    n_samples: int = 0

    @classmethod
    def build(cls, model: RobotModel, params: GaitParams) -> GaitPlan:
        """Plan ``params.sequence``, each gait preceded and followed by standing."""
        nominal3, com = standing_geometry(model)
        order = quadrants(model.config.feet, nominal3)
        plan = cls(params, nominal3[:, :2], com[:2], float(-nominal3[:, 2].mean()),
                   Piecewise(np.zeros(2)))
        feet = nominal3[:, :2].copy()
        t = 0.0
        segments = []
        for gait in params.sequence:
            t = plan._stand(t, feet)
            t0 = t
            if gait == 'crawl':
                t = plan._crawl(t, feet, order)
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
                com_target = nearest_inside(feet.mean(axis=0), feet[others],
                                            p.crawl_margin_m)
                target = com_target - self.com_offset
                self.body.add(t, t + shift, min_jerk(t, t + shift, self.body.end.copy(),
                                                     target))
                t += shift
                self.swings.append(Swing(k, t, t + swing, feet[k].copy(), feet[k] + step))
                feet[k] = feet[k] + step
                t += swing
        return t

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
