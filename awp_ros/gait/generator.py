r"""
A balanced gait generator for quadrupeds: crawl, lurch and trot, as joint states and IMU.

The robot walks straight along world x on flat ground (z = 0, normal +z); everything is in
the world frame (REP 103, z up) and starts from the standing posture of the robot config.
The default sequence (HyQ, :class:`GaitParams` defaults, 500 Hz, 5801 samples, 11.6 s):

==============  ============  ======================================================
gait            time [s]      motion
==============  ============  ======================================================
stand           0.0 - 0.5     all feet down
crawl           0.5 - 4.9     static walk, swings LH, LF, RH, RF (0.5 s each, 0.10 m
                              forward), each after a 0.6 s four-foot shift that puts
                              the ZMP and the CoM ``crawl_margin_m`` (6 cm) inside the
                              triangle of the three other feet
stand           4.9 - 5.4     body back over the centre of the feet
lurch           5.4 - 7.6     shift onto RF, LH, RH (5.4 - 6.0); LF lifts in place
                              (6.0 - 7.6, up to 8 cm); at rest until 6.3; **6.3 - 6.5:
                              the body is thrown toward RH so hard that the ZMP is
                              4 cm outside the support triangle** (beyond the RF-LH
                              diagonal, on the lifted foot's side: infeasible, the
                              robot would tip over that diagonal onto LF); then the
                              ZMP catches the body (its capture point, 19 cm inside)
stand           7.6 - 8.1     body back over the centre of the feet
trot            8.1 - 11.1    diagonal pairs (LF, RH) and (RF, LH), period 0.6 s, duty
                              0.6 (0.06 s four-foot phases), speed ramping (quintic,
                              0.9 s) to 0.25 m/s and back; on two feet the ZMP is on
                              the line of the two stance feet; bob 6 mm, roll 0.02 rad
stand           11.1 - 11.6   at rest
==============  ============  ======================================================

The infeasible window is reported in :attr:`GaitSamples.infeasible` (``('lurch', 6.3,
6.5)``; on a small robot the window is shorter, see :class:`GaitParams`); everywhere else
the motion is dynamically balanced for point feet. Checked independently (Pinocchio and
finite differences of the samples, ``test/gait/test_gait_dynamics.py``): on two feet the
contact wrench's moment about the stance line is below 0.03 N.m (the samples' rounding),
the ZMP at least 6.0 cm inside the support triangle on three feet and 12.8 cm inside the
polygon on four, the friction demand below 0.25; in the lurch's window the ZMP is 4.0 cm
outside (a moment of 34 N.m about the RF-LH edge that no contact force can give).
:attr:`GaitSamples.wrench` is that contact wrench, the ground truth for an estimator.

**Planning.** :mod:`awp_ros.gait.plan` places the footholds and swings and a *nominal*
(kinematic) body path; :mod:`awp_ros.gait.balance` plans the horizontal whole-body CoM from
it by ZMP planning on the cart-table model (:math:`\omega^2 = g / h`, made exact by the
measured CoM height and angular-momentum rate): one sparse equality-constrained
least-squares solve over the whole horizon (equation 9), the ZMP on the two stance feet's
line in two-foot phases (equation 10), near the nominal CoM inside the support triangle on
three feet, loosely near it on four. :func:`~awp_ros.gait.kinematics.whole_body_ik` then
places the base so that Pinocchio's whole-body CoM is on the plan (equations 1, 2, 4, 5),
the base height (standing height, bob) and roll being given. The generator iterates
``balance_iterations`` times: plan, IK, measure (equations 3, 6, 7), plan again.

Swing feet follow a cycloid (horizontal: zero velocity and acceleration at lift-off and
touch-down; vertical: a cosine bump of height ``swing_height_m``). Joint velocities come
from central differences (equation 3).

**IMU** (on the base link, ``base_frame``, e.g. ``base_link``: its origin and axes, not the
URDF's ``trunk_imu`` link; the bag's rate is :data:`awp_ros.gait.bag.DEFAULT_IMU_RATE_HZ`,
one per joint state, same stamp): the
orientation R (world from base), the angular velocity :math:`\omega^b` and the specific
force of the base origin, with :math:`\ddot p` the second difference (equation 3) of the
commanded base positions, exact to the sampling:

.. math::

    (12)\quad a^{b} = R^T (\ddot p_{base} - g), \qquad g = (0, 0, -9.81)\ \mathrm{m/s^2}

Everything is a deterministic function of the config and the parameters (no clock, no
randomness); positions and velocities are rounded to ``round_decimals`` so that the bytes of
a bag written from them are reproducible.

Layout: :mod:`awp_ros.gait.params` (:class:`GaitParams`), :mod:`awp_ros.gait.plan`
(footholds, nominal path, ZMP windows), :mod:`awp_ros.gait.curves` (its curves),
:mod:`awp_ros.gait.balance` (equations 8 - 10), :mod:`awp_ros.gait.dynamics` (equations 3,
6, 7), :mod:`awp_ros.gait.kinematics` (equations 1, 2, 4, 5), :mod:`awp_ros.gait.bag` (the
bag's messages); ``python -m awp_ros.gait`` writes the bag.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from awp_ros.gait.balance import plan_com, zmp_task
from awp_ros.gait.dynamics import (central_difference, centroidal_motion, contact_wrench,
                                   second_difference, zmp)
from awp_ros.gait.kinematics import base_frame, rotate_to_base, whole_body_ik
from awp_ros.gait.params import GaitParams, GAITS, GRAVITY
from awp_ros.gait.plan import GaitPlan
from awp_ros.robot.config import RobotConfig
from awp_ros.robot.model import RobotModel

__all__ = ['GaitParams', 'GaitSamples', 'generate_gait', 'GAITS', 'GRAVITY']


@dataclass(frozen=True)
class GaitSamples:
    """
    A sampled motion. N samples at ``rate_hz``; K feet; n_j joints.

    ``t`` (N,) [s] from the start; ``q``, ``v`` (N, n_j) joint positions [rad] and
    velocities [rad/s] in ``joint_names`` order; ``stance`` (N, K) feet in contact, in
    ``feet`` order; ``foot_positions`` (N, K, 3) world [m]; ``base_position`` (N, 3) world
    [m]; ``base_quaternion`` (N, 4) ``[x, y, z, w]`` world from base; ``angular_velocity``
    and ``specific_force`` (N, 3) what an IMU on the base link ``base_frame`` reads (base
    frame, [rad/s] and [m/s^2]); ``com`` (N, 3) whole-body CoM, world [m]; ``segments`` the
    gaits as ``(name, t_start, t_end)`` [s]; ``wrench`` (N, 6) the contact wrench about the
    CoM that the motion needs, world axes [N, N.m] (equation 6); ``zmp`` (N, 2) its ZMP,
    world xy [m] (equation 7); ``infeasible`` the windows ``(name, t_start, t_end)`` [s]
    where the ZMP is planned outside the support polygon (the lurch).
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
    wrench: np.ndarray | None = None
    zmp: np.ndarray | None = None
    infeasible: tuple[tuple[str, float, float], ...] = field(default=())

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
    :param ik_tol: IK stops when every foot and the CoM are within this distance of their
        targets [m].
    :param ik_max_iter: Newton iterations per sample before giving up.
    :raises ConfigError: the robot is not a quadruped with a standing posture.
    :raises ModelError: a foot target is out of reach or beyond the joint limits.
    """
    params = params or GaitParams()
    model = model or RobotModel(config)
    plan = GaitPlan.build(model, params)
    n = plan.n_samples
    dt = 1.0 / params.rate_hz
    t = np.arange(n) / params.rate_hz
    feet_w, stance = plan.feet(t)
    speed = plan.speed_ratio(t)
    phase = 2.0 * np.pi * t / params.trot_period_s
    base_z = plan.height - params.bob_m * speed * 0.5 * (1.0 - np.cos(2.0 * phase))
    roll = params.roll_rad * speed * np.sin(phase)
    half = 0.5 * roll
    quat = np.column_stack([np.sin(half), np.zeros(n), np.zeros(n), np.cos(half)])
    omega = np.column_stack([central_difference(roll, dt), np.zeros(n), np.zeros(n)])
    task = zmp_task(plan, t, feet_w, stance)
    mass = model.total_mass
    # First guess of equation 8: the standing CoM height over the bobbing base, no L-dot.
    com_z = base_z + (plan.com_height - plan.height)
    alpha = com_z / (second_difference(com_z, dt) + GRAVITY)
    beta = np.zeros((n, 2))
    q = base_xy = com_xy = None
    for _ in range(params.balance_iterations):
        com_xy = plan_com(task, alpha, beta, dt, com_xy)
        q, base_xy = whole_body_ik(model, feet_w, base_z, roll, com_xy, t, tol=ik_tol,
                                   max_iter=ik_max_iter, q0=q, base0=base_xy)
        base = np.column_stack([base_xy, base_z])
        com, ang = centroidal_motion(model, q, base, quat, omega, dt)
        wrench = contact_wrench(mass, com, ang, dt)
        alpha = mass * com[:, 2] / wrench[:, 2]
        beta = np.column_stack([-wrench[:, 4], wrench[:, 3]]) / wrench[:, 2:3]
    v = central_difference(q, dt)                                         # equation 3
    acc = second_difference(base, dt)
    acc[:, 2] += GRAVITY
    force_b = rotate_to_base(acc, np.cos(roll), np.sin(roll))             # equation 12
    d = params.round_decimals
    return GaitSamples(
        rate_hz=params.rate_hz, t=t, joint_names=model.joint_names, q=np.round(q, d),
        v=np.round(v, d), feet=tuple(config.feet), stance=stance,
        foot_positions=np.round(feet_w, d), base_position=np.round(base, d),
        base_quaternion=np.round(quat, d), angular_velocity=np.round(omega, d),
        specific_force=np.round(force_b, d), com=com, base_frame=base_frame(model),
        segments=plan.segments, wrench=wrench, zmp=zmp(com, wrench),
        infeasible=tuple((w.name, w.t0, w.t1) for w in plan.windows))
