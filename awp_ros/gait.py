"""A kinematic gait generator for quadrupeds: a static crawl and a trot, as joint states.

The robot walks straight along world x on flat ground (z = 0, normal +z). The plan is made
in the world frame (REP 103, z up) from the feet's nominal positions in the standing
posture of the robot config:

- **stand**: all feet down, base at the standing height above the nominal feet.
- **crawl** (static walk, swing order LH, LF, RH, RF): before each swing the base moves
  (minimum-jerk, all four feet down) so that the whole-body CoM comes to the point nearest
  to the centre of the four feet that lies ``crawl_margin_m`` inside the support triangle
  of the three other feet (so the body sways sideways and shifts fore and aft); the base
  holds still while the foot swings ``crawl_step_m`` forward. At the end the base returns
  over the centre of the feet.
- **trot**: diagonal pairs (LF, RH) and (RF, LH) swing alternately with a duty factor
  above 1/2 (short four-foot phases between the pairs); the base speed ramps smoothly
  (quintic) to ``trot_speed_mps`` and back to zero; each swing foot lands where its hip
  will be at mid-stance; the body bobs and rolls slightly in step with the gait.

Swing feet follow a cycloid (horizontal; zero velocity and acceleration at lift-off and
touch-down) and a cosine bump of height ``swing_height_m`` (vertical). Joint angles come
from the feet's positions in the base frame by damped Newton inverse kinematics with
Pinocchio (each leg's translational foot Jacobian w.r.t. its own joints, warm-started
from the previous sample), joint velocities by central differences at the sample rate:

.. math::

    (1)\\quad p^{b}_k = R^T (p^{w}_k - p^{w}_{base}), \\qquad
    (2)\\quad q_k \\leftarrow q_k + J_k(q)^{-1} (p^{b}_k - \\mathrm{fk}_k(q)),
    \\qquad (3)\\quad \\dot q_i \\approx (q_{i+1} - q_{i-1}) / (2 \\Delta t)

The IMU signals follow from the base motion: orientation ``R`` (world from base),
angular velocity :math:`\\omega^b` and specific force :math:`R^T (\\ddot p_{base} - g)`,
both in the base frame. Everything is a deterministic function of the config and the
parameters (no clock, no randomness); positions and velocities are rounded to
``round_decimals`` so that the bytes of a bag written from them are reproducible.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np
import pinocchio as pin

from awp_ros.errors import ConfigError, InputError, ModelError
from awp_ros.robot_config import RobotConfig
from awp_ros.robot_model import RobotModel

__all__ = ['GaitParams', 'GaitSamples', 'generate_gait', 'GAITS', 'GRAVITY']

GAITS = ('stand', 'crawl', 'trot')
GRAVITY = 9.81  # [m/s^2], matches Pinocchio's default model.gravity


@dataclass(frozen=True)
class GaitParams:
    """Parameters of the generated motion (durations [s], lengths [m], angles [rad]).

    ``sequence`` lists the gaits in order, each preceded and followed by ``stand_s`` of
    standing. Durations are rounded to whole samples of ``rate_hz``.
    """

    sequence: tuple[str, ...] = ('crawl', 'trot')
    rate_hz: float = 500.0
    stand_s: float = 0.5
    crawl_shift_s: float = 0.6
    crawl_swing_s: float = 0.5
    crawl_step_m: float = 0.10
    crawl_cycles: int = 1
    crawl_margin_m: float = 0.06
    trot_period_s: float = 0.6
    trot_duty: float = 0.6
    trot_cycles: int = 5
    trot_speed_mps: float = 0.25
    trot_ramp_s: float = 0.9
    swing_height_m: float = 0.08
    bob_m: float = 0.006
    roll_rad: float = 0.02
    round_decimals: int = 9

    def __post_init__(self) -> None:
        """Validate (raise InputError naming the bad value)."""
        unknown = [g for g in self.sequence if g not in GAITS]
        if unknown:
            raise InputError(f'unknown gaits {unknown}; gaits are {list(GAITS)}')
        positive = ('rate_hz', 'crawl_shift_s', 'crawl_swing_s', 'trot_period_s',
                    'swing_height_m', 'trot_ramp_s')
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise InputError(f'{name} must be finite and > 0, got {value!r}')
        for name in ('stand_s', 'crawl_step_m', 'crawl_margin_m', 'trot_speed_mps', 'bob_m',
                     'roll_rad'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise InputError(f'{name} must be finite and >= 0, got {value!r}')
        if not 0.5 < self.trot_duty < 1.0:
            raise InputError(f'trot_duty must be in (0.5, 1), got {self.trot_duty!r}')
        if self.crawl_cycles < 1 or self.trot_cycles < 1:
            msg = f'crawl_cycles and trot_cycles must be >= 1, got ' \
                  f'{self.crawl_cycles!r}, {self.trot_cycles!r}'
            raise InputError(msg)


@dataclass(frozen=True)
class GaitSamples:
    """A sampled motion. N samples at ``rate_hz``; K feet; n_j joints.

    ``t`` (N,) [s] from the start; ``q``, ``v`` (N, n_j) joint positions [rad] and
    velocities [rad/s] in ``joint_names`` order; ``stance`` (N, K) feet in contact, in
    ``feet`` order; ``foot_positions`` (N, K, 3) world [m]; ``base_position`` (N, 3) world
    [m]; ``base_quaternion`` (N, 4) ``[x, y, z, w]`` world from base; ``angular_velocity``
    and ``specific_force`` (N, 3) what an IMU on the base reads (base frame, [rad/s] and
    [m/s^2]); ``com`` (N, 3) whole-body CoM, world [m]; ``segments`` the gait phases as
    ``(name, t_start, t_end)`` [s].
    """

    rate_hz: float
    t: np.ndarray
    joint_names: tuple[str, ...]
    q: np.ndarray
    v: np.ndarray
    feet: tuple[str, ...]
    stance: np.ndarray
    foot_positions: np.ndarray
    base_position: np.ndarray
    base_quaternion: np.ndarray
    angular_velocity: np.ndarray
    specific_force: np.ndarray
    com: np.ndarray
    base_frame: str
    segments: tuple[tuple[str, float, float], ...] = field(default=())

    def __len__(self) -> int:
        """Return the number of samples."""
        return int(self.t.shape[0])


def generate_gait(config: RobotConfig, params: GaitParams | None = None, *,
                  model: RobotModel | None = None, ik_tol: float = 1e-11,
                  ik_max_iter: int = 30) -> GaitSamples:
    """Generate the joint-space motion of ``params.sequence`` for a quadruped.

    :param config: robot config with 4 feet (one per quadrant of the base frame) and a
        ``standing_posture``.
    :param params: the motion parameters (default :class:`GaitParams`).
    :param model: a prebuilt model of ``config`` (built when None).
    :param ik_tol: IK stops when every foot is within this distance of its target [m].
    :param ik_max_iter: Newton iterations per sample before giving up.
    :raises ConfigError: the robot is not a quadruped with a standing posture.
    :raises ModelError: a foot target is out of reach or beyond the joint limits.
    """
    params = params or GaitParams()
    model = model or RobotModel(config)
    plan = _Plan.build(model, params)
    n = plan.n_samples
    t = np.arange(n) / params.rate_hz
    feet_w, stance = plan.feet(t)
    base_xy = plan.body.evaluate(t)
    speed = plan.speed_ratio(t)
    phase = 2.0 * np.pi * t / params.trot_period_s
    base_z = plan.height - params.bob_m * speed * 0.5 * (1.0 - np.cos(2.0 * phase))
    base = np.column_stack([base_xy, base_z])
    roll = params.roll_rad * speed * np.sin(phase)
    half = 0.5 * roll
    quat = np.column_stack([np.sin(half), np.zeros(n), np.zeros(n), np.cos(half)])
    # Equation 1: feet in the base frame, R = rot_x(roll).
    rel = feet_w - base[:, None, :]
    c, s = np.cos(roll)[:, None], np.sin(roll)[:, None]
    feet_b = np.stack([rel[..., 0], c * rel[..., 1] + s * rel[..., 2],
                       -s * rel[..., 1] + c * rel[..., 2]], axis=-1)
    q = _inverse_kinematics(model, feet_b, t, tol=ik_tol, max_iter=ik_max_iter)
    dt = 1.0 / params.rate_hz
    v = np.gradient(q, dt, axis=0)                                        # equation 3
    omega = np.column_stack([np.gradient(roll, dt), np.zeros(n), np.zeros(n)])
    acc = np.gradient(np.gradient(base, dt, axis=0), dt, axis=0)
    acc[:, 2] += GRAVITY
    force_b = np.column_stack([acc[:, 0], c[:, 0] * acc[:, 1] + s[:, 0] * acc[:, 2],
                               -s[:, 0] * acc[:, 1] + c[:, 0] * acc[:, 2]])
    com = _com_world(model, q, base, quat)
    d = params.round_decimals
    return GaitSamples(
        rate_hz=params.rate_hz, t=t, joint_names=model.joint_names, q=np.round(q, d),
        v=np.round(v, d), feet=tuple(config.feet), stance=stance,
        foot_positions=np.round(feet_w, d), base_position=np.round(base, d),
        base_quaternion=np.round(quat, d), angular_velocity=np.round(omega, d),
        specific_force=np.round(force_b, d), com=com, base_frame=_base_frame(model),
        segments=plan.segments)


# -- the plan ---------------------------------------------------------------------------------


class _Piecewise:
    """A function of time [s] made of segments ``[t0, t1)``; constant after the last one."""

    def __init__(self, start: np.ndarray) -> None:
        self.segments: list = []
        self.end = np.asarray(start, dtype=float)

    def add(self, t0: float, t1: float, fn) -> None:
        self.segments.append((t0, t1, fn))
        self.end = fn(np.array([t1]))[0]

    def evaluate(self, t: np.ndarray) -> np.ndarray:
        out = np.empty((t.shape[0], self.end.shape[0]))
        out[:] = self.segments[0][2](t[:1])[0] if self.segments else self.end
        for t0, t1, fn in self.segments:
            mask = t >= t0
            out[mask] = fn(np.minimum(t[mask], t1))
        return out


def _min_jerk(t0: float, t1: float, p0: np.ndarray, p1: np.ndarray):
    """Return the minimum-jerk path from p0 at t0 to p1 at t1 (rest to rest)."""
    def fn(t: np.ndarray) -> np.ndarray:
        u = np.clip((t - t0) / (t1 - t0), 0.0, 1.0)[:, None]
        return p0 + (p1 - p0) * (u ** 3 * (10.0 - 15.0 * u + 6.0 * u ** 2))
    return fn


@dataclass
class _Swing:
    foot: int
    t0: float
    t1: float
    p0: np.ndarray
    p1: np.ndarray


@dataclass
class _Plan:
    params: GaitParams
    nominal: np.ndarray          # (K, 2) feet xy in the base frame, standing [m]
    com_offset: np.ndarray       # (2,) CoM xy in the base frame, standing [m]
    height: float                # base height above the feet, standing [m]
    body: _Piecewise
    swings: list = field(default_factory=list)
    trots: list = field(default_factory=list)    # (t0, t1, ramp) [s] of each trot
    segments: tuple = ()
    n_samples: int = 0

    @classmethod
    def build(cls, model: RobotModel, params: GaitParams) -> _Plan:
        nominal3, com = _standing_geometry(model)
        order = _quadrants(model.config.feet, nominal3)
        plan = cls(params, nominal3[:, :2], com[:2], float(-nominal3[:, 2].mean()),
                   _Piecewise(np.zeros(2)))
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
        t1 = t + _whole(self.params.stand_s, self.params.rate_hz)
        target = feet.mean(axis=0) - self.nominal.mean(axis=0)
        if t1 > t:
            self.body.add(t, t1, _min_jerk(t, t1, self.body.end.copy(), target))
        return t1

    def _crawl(self, t: float, feet: np.ndarray, order: dict) -> float:
        """Plan one static crawl from time ``t`` [s]; update ``feet``; return the end."""
        p = self.params
        shift = _whole(p.crawl_shift_s, p.rate_hz)
        swing = _whole(p.crawl_swing_s, p.rate_hz)
        step = np.array([p.crawl_step_m, 0.0])
        for _ in range(p.crawl_cycles):
            for name in ('lh', 'lf', 'rh', 'rf'):
                k = order[name]
                others = [i for i in range(feet.shape[0]) if i != k]
                com_target = _nearest_inside(feet.mean(axis=0), feet[others],
                                             p.crawl_margin_m)
                target = com_target - self.com_offset
                self.body.add(t, t + shift, _min_jerk(t, t + shift, self.body.end.copy(),
                                                      target))
                t += shift
                self.swings.append(_Swing(k, t, t + swing, feet[k].copy(), feet[k] + step))
                feet[k] = feet[k] + step
                t += swing
        return t

    def _trot(self, t: float, feet: np.ndarray, order: dict) -> float:
        """Plan a trot from time ``t`` [s]; update ``feet``; return the end."""
        p = self.params
        period = _whole(p.trot_period_s, p.rate_hz)
        swing = _whole((1.0 - p.trot_duty) * p.trot_period_s, p.rate_hz)
        stance = period - swing
        duration = p.trot_cycles * period
        ramp = min(_whole(p.trot_ramp_s, p.rate_hz), 0.5 * duration)
        x0 = self.body.end.copy()
        t0 = t
        self.trots.append((t0, t0 + duration, ramp))

        def body(tt: np.ndarray) -> np.ndarray:
            out = np.empty((tt.shape[0], 2))
            out[:, 0] = x0[0] + _ramp_distance(tt - t0, duration, ramp, p.trot_speed_mps)
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
                    self.swings.append(_Swing(k, lift, land, feet[k].copy(), target))
                    feet[k] = target
        return t0 + duration

    def speed_ratio(self, t: np.ndarray) -> np.ndarray:
        """Return base speed / trot speed (0 outside trots), the scale of bob and roll."""
        out = np.zeros(t.shape[0])
        for t0, t1, ramp in self.trots:
            u = t - t0
            rise = _smoothstep(u / ramp)
            fall = _smoothstep((t1 - t0 - u) / ramp)
            out += np.where((t >= t0) & (t <= t1), np.minimum(rise, fall), 0.0)
        return out

    def feet(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return world foot positions (N, K, 3) [m] and stance flags (N, K)."""
        k_feet = self.nominal.shape[0]
        xy = np.empty((t.shape[0], k_feet, 2))
        z = np.zeros((t.shape[0], k_feet))
        stance = np.ones((t.shape[0], k_feet), dtype=bool)
        xy[:] = self.nominal
        h = self.params.swing_height_m
        for sw in self.swings:   # in time order per foot: later swings overwrite
            after = t >= sw.t0
            xy[after, sw.foot] = sw.p1
            during = after & (t < sw.t1)
            u = (t[during] - sw.t0) / (sw.t1 - sw.t0)
            xy[during, sw.foot] = sw.p0 + np.outer(u - np.sin(2.0 * np.pi * u) / (2 * np.pi),
                                                   sw.p1 - sw.p0)
            z[during, sw.foot] = 0.5 * h * (1.0 - np.cos(2.0 * np.pi * u))
            stance[during, sw.foot] = False
        return np.concatenate([xy, z[..., None]], axis=-1), stance


def _nearest_inside(point: np.ndarray, vertices: np.ndarray, margin: float, *,
                    tol: float = 1e-12) -> np.ndarray:
    """Return the point nearest to ``point`` at least ``margin`` inside a convex polygon.

    Candidates: the point itself, its projections on the inset edges and the inset
    vertices; the nearest one satisfying every inset halfspace (within ``tol`` [m]) wins.

    :param vertices: (m, 2) polygon vertices in order (either orientation) [m].
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


def _whole(duration: float, rate_hz: float) -> float:
    """Round a duration [s] to a whole number of samples."""
    return round(duration * rate_hz) / rate_hz


def _smoothstep(u: np.ndarray) -> np.ndarray:
    u = np.clip(u, 0.0, 1.0)
    return u ** 3 * (10.0 - 15.0 * u + 6.0 * u ** 2)


def _ramp_distance(u: np.ndarray, duration: float, ramp: float, speed: float) -> np.ndarray:
    """Distance [m] travelled at time u [s] with a quintic speed ramp up and down.

    Speed: ``speed * S(u / ramp)`` up, constant, ``speed * S((duration - u) / ramp)`` down,
    with :math:`S(x) = 10x^3 - 15x^4 + 6x^5`, whose integral is
    :math:`x^6 - 3x^5 + 2.5x^4`.
    """
    def integral(x):
        x = np.clip(x, 0.0, 1.0)
        return x ** 6 - 3.0 * x ** 5 + 2.5 * x ** 4

    u = np.clip(u, 0.0, duration)
    total = speed * (duration - ramp)       # each ramp covers speed * ramp / 2
    up = speed * ramp * integral(u / ramp)
    flat = speed * np.clip(u - ramp, 0.0, duration - 2.0 * ramp)
    down = speed * ramp * (0.5 - integral((duration - u) / ramp))
    down = np.where(u > duration - ramp, down, 0.0)
    return np.minimum(up + flat + down, total)


# -- robot helpers ----------------------------------------------------------------------------


def _standing_geometry(model: RobotModel) -> tuple[np.ndarray, np.ndarray]:
    """Return the feet (K, 3) and CoM (3,) in the base frame in the standing posture [m]."""
    if model.standing_q is None:
        raise ConfigError(f'robot {model.config.robot_name!r} has no standing_posture; the '
                          'gait generator starts from it')
    q = pin.neutral(model.model)
    q[7:] = model.standing_q
    pin.framesForwardKinematics(model.model, model.data, q)
    feet = np.array([model.data.oMf[model.legs[f].frame_id].translation
                     for f in model.config.feet])
    com = pin.centerOfMass(model.model, model.data, q).copy()
    return feet, com


def _quadrants(feet: tuple[str, ...], nominal: np.ndarray) -> dict[str, int]:
    """Map 'lf', 'rf', 'lh', 'rh' to foot indices by the sign of the standing positions."""
    if len(feet) != 4:
        raise ConfigError(f'the gait generator needs 4 feet, got {list(feet)}')
    order = {}
    for k, (x, y) in enumerate(nominal[:, :2]):
        name = ('l' if y > 0.0 else 'r') + ('f' if x > 0.0 else 'h')
        if name in order:
            raise ConfigError(f'feet {feet[order[name]]!r} and {feet[k]!r} are both in the '
                              f'{name} quadrant of the base frame; need one foot per quadrant')
        order[name] = k
    return order


def _inverse_kinematics(model: RobotModel, feet_b: np.ndarray, t: np.ndarray, *,
                        tol: float, max_iter: int) -> np.ndarray:
    """Solve equation 2 at every sample, warm-started from the previous one.

    :param feet_b: (N, K, 3) foot targets in the base frame [m].
    :return: (N, n_j) joint positions [rad].
    """
    pm, data = model.model, model.data
    legs = [model.legs[f] for f in model.config.feet]
    cols = np.array([leg.v_idx for leg in legs])            # (K, 3) columns in v
    q_full = pin.neutral(pm)
    q_full[7:] = model.standing_q
    lo, hi = pm.lowerPositionLimit[7:], pm.upperPositionLimit[7:]
    lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    out = np.empty((feet_b.shape[0], pm.nq - 7))
    J = np.empty((len(legs), 3, 3))
    for i in range(feet_b.shape[0]):
        for _ in range(max_iter):
            pin.framesForwardKinematics(pm, data, q_full)
            err = feet_b[i] - np.array([data.oMf[leg.frame_id].translation for leg in legs])
            if np.abs(err).max() < tol:
                break
            pin.computeJointJacobians(pm, data, q_full)
            for k, leg in enumerate(legs):
                J[k] = pin.getFrameJacobian(pm, data, leg.frame_id, lwa)[:3, leg.v_idx]
            q_full[cols + 1] += np.linalg.solve(J, err[..., None])[..., 0]
        else:
            k = int(np.abs(err).max(axis=1).argmax())
            msg = (f'IK failed at t = {t[i]:.3f} s: foot {legs[k].foot!r} target '
                   f'{np.round(feet_b[i, k], 4).tolist()} m (base frame) is out of reach')
            raise ModelError(msg)
        out[i] = q_full[7:]
    bad = np.flatnonzero(((out < lo) | (out > hi)).any(axis=0))
    if bad.size:
        j = int(bad[0])
        i = int(np.flatnonzero((out[:, j] < lo[j]) | (out[:, j] > hi[j]))[0])
        msg = (f'joint {model.joint_names[j]!r} leaves its limits [{lo[j]:.3f}, {hi[j]:.3f}] '
               f'rad at t = {t[i]:.3f} s (q = {out[i, j]:.3f}); shorten the steps')
        raise ModelError(msg)
    return out


def _com_world(model: RobotModel, q: np.ndarray, base: np.ndarray,
               quat: np.ndarray) -> np.ndarray:
    """Return the whole-body CoM in the world frame (N, 3) [m]."""
    pm, data = model.model, model.data
    q_full = pin.neutral(pm)
    out = np.empty((q.shape[0], 3))
    for i in range(q.shape[0]):
        q_full[:3] = base[i]
        q_full[3:7] = quat[i]
        q_full[7:] = q[i]
        out[i] = pin.centerOfMass(pm, data, q_full)
    return out


def _base_frame(model: RobotModel) -> str:
    """Return the name of the body frame fixed to the floating base (e.g. base_link)."""
    for frame in model.model.frames:
        if frame.parentJoint == 1 and frame.type == pin.FrameType.BODY:
            return frame.name
    return 'base_link'


# -- the generator script ----------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    """Write a gait bag; with no arguments, regenerate the committed default bag.

    ``python -m awp_ros.gait`` rewrites ``config/hyq_gait.mcap`` of the source tree
    byte-for-byte (HyQ, :class:`GaitParams` defaults, IMU at 100 Hz).
    """
    import argparse
    from pathlib import Path
    import sys

    from awp_ros.bag_io import DEFAULT_BAG_NAME, DEFAULT_IMU_RATE_HZ, write_gait_bag
    from awp_ros.errors import AwpError
    from awp_ros.robot_config import load_config

    default_out = Path(__file__).resolve().parent.parent / 'config' / DEFAULT_BAG_NAME
    parser = argparse.ArgumentParser(
        prog='python -m awp_ros.gait',
        description='Generate a crawl/trot bag (joint states, contacts, imu) for a quadruped.')
    parser.add_argument('-o', '--output', default=str(default_out),
                        help='output bag: a .mcap/.db3 file or a rosbag2 directory '
                             '(default: %(default)s)')
    parser.add_argument('--robot', default='hyq', help='robot config name or YAML path')
    parser.add_argument('--gaits', nargs='+', default=list(GaitParams.sequence),
                        choices=GAITS, help='gaits in order (default: %(default)s)')
    parser.add_argument('--storage', choices=['mcap', 'sqlite3'], default='mcap',
                        help='storage of a rosbag2 directory output')
    parser.add_argument('--imu-rate', type=float, default=DEFAULT_IMU_RATE_HZ,
                        help='IMU rate [Hz], 0 = no imu (default: %(default)s)')
    parser.add_argument('--force', action='store_true', help='overwrite the output')
    args = parser.parse_args(argv)
    out = Path(args.output)
    try:
        samples = generate_gait(load_config(args.robot), GaitParams(sequence=tuple(args.gaits)))
        if out.exists() and args.force:
            if out.is_dir():
                import shutil
                shutil.rmtree(out)
            else:
                out.unlink()
        write_gait_bag(samples, out, storage=args.storage, imu_rate_hz=args.imu_rate)
    except AwpError as exc:
        sys.stderr.write(f'error: {exc}\n')
        return 2
    sys.stdout.write(f'{out} ({len(samples)} samples, {samples.t[-1]:.2f} s)\n')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
