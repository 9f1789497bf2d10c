r"""
The centroidal dynamics of a sampled motion: CoM, angular momentum, wrench and ZMP.

Everything is measured from the samples with Pinocchio and finite differences at the sample
period ``dt`` [s], in the world frame (REP 103, z up; flat ground z = 0): the whole-body CoM
c, the centroidal angular momentum L (about the CoM, world axes; Pinocchio's ``hg`` with the
generalised velocity of equation 3), and the wrench that the contacts must apply about the
CoM (gravity g = (0, 0, -g)):

.. math::

    (3)\quad \dot x_i = (x_{i+1} - x_{i-1}) / (2 \Delta t), \qquad
    \ddot x_i = (x_{i+1} - 2 x_i + x_{i-1}) / \Delta t^2

    (6)\quad w = [f; \tau] = [m (\ddot c - g); \dot L]

    (7)\quad p_x = c_x - (c_z f_x + \tau_y) / f_z, \qquad
    p_y = c_y - (c_z f_y - \tau_x) / f_z

Equation 7 is the ZMP p: the point of the ground about which the contact wrench has no
horizontal moment (:math:`\tau + (c - p) \times f` vertical). With point contacts it must lie
in the support polygon; with two feet p_1, p_2 on the segment between them, i.e. the moment
about their line of the contact wrench vanishes (equation 8, :mod:`awp_ros.gait.balance`).
Derivatives at the first and last sample repeat their neighbour's (the motion is at rest
there).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from awp_ros.gait.params import GRAVITY
from awp_ros.robot.model import RobotModel

__all__ = ['central_difference', 'second_difference', 'centroidal_motion', 'contact_wrench',
           'zmp']


def central_difference(x: np.ndarray, dt: float) -> np.ndarray:
    """Return equation 3's first derivative along axis 0 (one-sided at the ends)."""
    return np.gradient(x, dt, axis=0)


def second_difference(x: np.ndarray, dt: float) -> np.ndarray:
    """Return equation 3's second derivative along axis 0 (the ends copy their neighbour)."""
    out = np.empty_like(x)
    out[1:-1] = (x[2:] - 2.0 * x[1:-1] + x[:-2]) / dt ** 2
    out[0], out[-1] = out[1], out[-2]
    return out


def centroidal_motion(model: RobotModel, q: np.ndarray, base: np.ndarray, quat: np.ndarray,
                      omega_b: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the whole-body CoM (N, 3) [m] and angular momentum about it (N, 3) [kg m^2/s].

    :param q: (N, n_j) joint positions [rad]; their velocities: equation 3.
    :param base: (N, 3) base positions, world [m]; their velocities: equation 3.
    :param quat: (N, 4) base orientations ``[x, y, z, w]``, world from base.
    :param omega_b: (N, 3) base angular velocities, base frame [rad/s].
    """
    pm, data = model.model, model.data
    qd = central_difference(q, dt)
    vel_w = central_difference(base, dt)
    q_full = pin.neutral(pm)
    v_full = np.zeros(pm.nv)
    com, ang = np.empty((q.shape[0], 3)), np.empty((q.shape[0], 3))
    for i in range(q.shape[0]):
        q_full[:3], q_full[3:7], q_full[7:] = base[i], quat[i], q[i]
        R = pin.Quaternion(quat[i][3], *quat[i][:3]).matrix()
        v_full[:3], v_full[3:6], v_full[6:] = R.T @ vel_w[i], omega_b[i], qd[i]
        ang[i] = pin.computeCentroidalMomentum(pm, data, q_full, v_full).angular
        com[i] = data.com[0]
    return com, ang


def contact_wrench(mass: float, com: np.ndarray, ang: np.ndarray, dt: float) -> np.ndarray:
    """Return equation 6, the contact wrench about the CoM (N, 6) [N, N.m], world axes."""
    out = np.empty((com.shape[0], 6))
    out[:, :3] = mass * second_difference(com, dt)
    out[:, 2] += mass * GRAVITY
    out[:, 3:] = central_difference(ang, dt)
    return out


def zmp(com: np.ndarray, wrench: np.ndarray) -> np.ndarray:
    """Return equation 7, the ZMP (N, 2) [m] on the ground z = 0, world xy."""
    f, tau = wrench[:, :3], wrench[:, 3:]
    return np.column_stack([com[:, 0] - (com[:, 2] * f[:, 0] + tau[:, 1]) / f[:, 2],
                            com[:, 1] - (com[:, 2] * f[:, 1] - tau[:, 0]) / f[:, 2]])
