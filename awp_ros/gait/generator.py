r"""
A kinematic gait generator for quadrupeds: a static crawl and a trot, as joint states.

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

    (1)\quad p^{b}_k = R^T (p^{w}_k - p^{w}_{base}), \qquad
    (2)\quad q_k \leftarrow q_k + J_k(q)^{-1} (p^{b}_k - \mathrm{fk}_k(q)),
    \qquad (3)\quad \dot q_i \approx (q_{i+1} - q_{i-1}) / (2 \Delta t)

The IMU signals follow from the base motion: orientation ``R`` (world from base),
angular velocity :math:`\omega^b` and specific force :math:`R^T (\ddot p_{base} - g)`,
both in the base frame. Everything is a deterministic function of the config and the
parameters (no clock, no randomness); positions and velocities are rounded to
``round_decimals`` so that the bytes of a bag written from them are reproducible.

Layout: the plan (base path, foot swings) is :mod:`awp_ros.gait.plan`, its curves
:mod:`awp_ros.gait.curves`, equations 1 and 2 :mod:`awp_ros.gait.kinematics`, the bag's
messages :mod:`awp_ros.gait.bag`; ``python -m awp_ros.gait`` (:func:`main`) writes the bag.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np

from awp_ros.errors import InputError
from awp_ros.gait.kinematics import base_frame, com_world, inverse_kinematics, rotate_to_base
from awp_ros.gait.plan import GaitPlan
from awp_ros.robot.config import RobotConfig
from awp_ros.robot.model import RobotModel

__all__ = ['GaitParams', 'GaitSamples', 'generate_gait', 'GAITS', 'GRAVITY']

GAITS = ('stand', 'crawl', 'trot')
GRAVITY = 9.81  # [m/s^2], matches Pinocchio's default model.gravity


@dataclass(frozen=True)
class GaitParams:
    """
    Parameters of the generated motion (durations [s], lengths [m], angles [rad]).

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
    """
    A sampled motion. N samples at ``rate_hz``; K feet; n_j joints.

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
    """
    Generate the joint-space motion of ``params.sequence`` for a quadruped.

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
    plan = GaitPlan.build(model, params)
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
    c, s = np.cos(roll)[:, None], np.sin(roll)[:, None]
    feet_b = rotate_to_base(feet_w - base[:, None, :], c, s)
    q = inverse_kinematics(model, feet_b, t, tol=ik_tol, max_iter=ik_max_iter)
    dt = 1.0 / params.rate_hz
    v = np.gradient(q, dt, axis=0)                                        # equation 3
    omega = np.column_stack([np.gradient(roll, dt), np.zeros(n), np.zeros(n)])
    acc = np.gradient(np.gradient(base, dt, axis=0), dt, axis=0)
    acc[:, 2] += GRAVITY
    force_b = rotate_to_base(acc, c[:, 0], s[:, 0])
    com = com_world(model, q, base, quat)
    d = params.round_decimals
    return GaitSamples(
        rate_hz=params.rate_hz, t=t, joint_names=model.joint_names, q=np.round(q, d),
        v=np.round(v, d), feet=tuple(config.feet), stance=stance,
        foot_positions=np.round(feet_w, d), base_position=np.round(base, d),
        base_quaternion=np.round(quat, d), angular_velocity=np.round(omega, d),
        specific_force=np.round(force_b, d), com=com, base_frame=base_frame(model),
        segments=plan.segments)


# -- the generator script ----------------------------------------------------------------------
