"""
Analytic whole-body motions of a free-flyer model and their truth, for the estimation tests.

Everything here is computed from the trajectory by Pinocchio kinematics and central finite
differences in time, never through :mod:`awp_ros.estimation`: the IMU reading from the IMU
point's world position (second difference) and the IMU frame's world rotation (log of the
relative rotation), the gravito-inertial wrench from the CoM position and the centroidal
angular momentum, the generalised acceleration from the generalised velocity.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np
import pinocchio as pin

#: Central-difference steps [s]: positions twice differentiated, first derivatives.
H_POS = 1e-3
H_VEL = 1e-4
H_ROT = 1e-5


@dataclass
class Trajectory:
    """
    A base pose p(t), R(t) and joint positions q_j(t) as sums of sinusoids, or a screw.

    ``p(t) = p0 + v0 t + A_p sin(W t + phi_p)`` [m] (world), ``rpy(t) = A_r sin(W t +
    phi_r)`` [rad] (roll, pitch, yaw; R = Rz Ry Rx), ``q_j(t) = q0 + qdot0 t + A_q sin(W t +
    phi_q)`` [rad], with ``W = 2 pi freq`` [rad/s]. With ``twist`` [v; omega] (base frame,
    [m/s, rad/s]) the base instead moves along the screw ``M(t) = M(p0) exp(t twist)``
    (a constant body twist: the base's classical acceleration is omega x v, nonzero).
    """

    q0: np.ndarray
    freq: float = 1.5
    p0: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 0.6]))
    v0: np.ndarray = field(default_factory=lambda: np.zeros(3))
    amp_p: np.ndarray = field(default_factory=lambda: np.zeros(3))
    phase_p: np.ndarray = field(default_factory=lambda: np.zeros(3))
    amp_r: np.ndarray = field(default_factory=lambda: np.zeros(3))
    phase_r: np.ndarray = field(default_factory=lambda: np.zeros(3))
    qdot0: np.ndarray | None = None
    amp_q: np.ndarray | None = None
    phase_q: np.ndarray | None = None
    twist: np.ndarray | None = None

    def __post_init__(self) -> None:
        """Fill the joint terms left out with zeros."""
        n = len(self.q0)
        self.qdot0 = np.zeros(n) if self.qdot0 is None else np.asarray(self.qdot0, float)
        self.amp_q = np.zeros(n) if self.amp_q is None else np.asarray(self.amp_q, float)
        self.phase_q = np.zeros(n) if self.phase_q is None else \
            np.asarray(self.phase_q, float)

    @property
    def omega(self) -> float:
        """Return the angular frequency W [rad/s]."""
        return 2.0 * math.pi * self.freq

    def position(self, t: float) -> np.ndarray:
        """Return the base position p(t) [m], world."""
        if self.twist is not None:
            return self.p0 + pin.exp6(pin.Motion(self.twist * t)).translation
        return self.p0 + self.v0 * t + self.amp_p * np.sin(self.omega * t + self.phase_p)

    def rotation(self, t: float) -> np.ndarray:
        """Return the base rotation R(t) (world from base)."""
        if self.twist is not None:
            return pin.exp6(pin.Motion(self.twist * t)).rotation
        return pin.rpy.rpyToMatrix(self.amp_r * np.sin(self.omega * t + self.phase_r))

    def joints(self, t: float) -> np.ndarray:
        """Return q_j(t) [rad]."""
        return self.q0 + self.qdot0 * t + self.amp_q * np.sin(self.omega * t + self.phase_q)

    def joint_velocities(self, t: float) -> np.ndarray:
        """Return dq_j/dt (analytic) [rad/s]."""
        return self.qdot0 + self.amp_q * self.omega * np.cos(self.omega * t + self.phase_q)

    def joint_accelerations(self, t: float) -> np.ndarray:
        """Return d2q_j/dt2 (analytic) [rad/s^2]."""
        return -self.amp_q * self.omega ** 2 * np.sin(self.omega * t + self.phase_q)

    def base_velocity(self, t: float) -> np.ndarray:
        """Return dp/dt [m/s], world (central difference)."""
        return (self.position(t + H_VEL) - self.position(t - H_VEL)) / (2.0 * H_VEL)

    def base_acceleration(self, t: float) -> np.ndarray:
        """Return d2p/dt2 [m/s^2], world (central second difference)."""
        return (self.position(t + H_POS) - 2.0 * self.position(t)
                + self.position(t - H_POS)) / H_POS ** 2

    def angular_velocity(self, t: float) -> np.ndarray:
        """Return omega_b(t) [rad/s], base frame, from R(t -+ h) (central difference)."""
        return _rate(self.rotation(t - H_ROT), self.rotation(t + H_ROT), H_ROT)

    def angular_acceleration(self, t: float) -> np.ndarray:
        """Return d omega_b / dt [rad/s^2], base frame (central difference)."""
        return (self.angular_velocity(t + H_VEL) - self.angular_velocity(t - H_VEL)) \
            / (2.0 * H_VEL)

    def configuration(self, t: float) -> np.ndarray:
        """Return the free-flyer configuration q(t) = [p, quat xyzw, q_j]."""
        quat = pin.Quaternion(self.rotation(t))
        return np.concatenate([self.position(t), quat.coeffs(), self.joints(t)])

    def velocity(self, t: float) -> np.ndarray:
        """Return the free-flyer velocity v(t) = [R^T dp/dt, omega_b, dq_j/dt]."""
        R = self.rotation(t)
        return np.concatenate([R.T @ self.base_velocity(t), self.angular_velocity(t),
                               self.joint_velocities(t)])

    def acceleration(self, t: float) -> np.ndarray:
        """Return Pinocchio's generalised acceleration dv/dt (central difference)."""
        return (self.velocity(t + H_VEL) - self.velocity(t - H_VEL)) / (2.0 * H_VEL)

    def classical_base_acceleration(self, t: float) -> np.ndarray:
        """Return the base origin's classical acceleration R^T d2p/dt2 [m/s^2], base frame."""
        return self.rotation(t).T @ self.base_acceleration(t)


def _rate(R0: np.ndarray, R1: np.ndarray, h: float) -> np.ndarray:
    """Return the body-frame angular velocity from R(t - h), R(t + h) [rad/s]."""
    return pin.log3(R0.T @ R1) / (2.0 * h)


class Truth:
    """Pinocchio kinematics of a trajectory: IMU readings, wrench, bias torques."""

    def __init__(self, model: pin.Model, traj: Trajectory, imu_frame: str) -> None:
        self.model = model
        self.data = model.createData()
        self.traj = traj
        self.imu_id = model.getFrameId(imu_frame)
        self.gravity = np.array(model.gravity.linear)
        self.mass = float(sum(inertia.mass for inertia in model.inertias))

    def imu_pose(self, t: float) -> pin.SE3:
        """Return the IMU frame's world placement at t."""
        pin.framesForwardKinematics(self.model, self.data, self.traj.configuration(t))
        return self.data.oMf[self.imu_id].copy()

    def imu_reading(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """
        Return the IMU's (quaternion xyzw, angular velocity, specific force) at t (REP 145).

        The angular velocity [rad/s] and specific force [m/s^2] are in the IMU frame.
        """
        M = self.imu_pose(t)
        p_minus = self.imu_pose(t - H_POS).translation
        p_plus = self.imu_pose(t + H_POS).translation
        acc = (p_plus - 2.0 * M.translation + p_minus) / H_POS ** 2
        R0 = self.imu_pose(t - H_ROT).rotation
        R1 = self.imu_pose(t + H_ROT).rotation
        omega = _rate(R0, R1, H_ROT)
        force = M.rotation.T @ (acc - self.gravity)
        return pin.Quaternion(M.rotation).coeffs().copy(), omega, force

    def com(self, t: float) -> np.ndarray:
        """Return the CoM position [m], world."""
        return pin.centerOfMass(self.model, self.data, self.traj.configuration(t)).copy()

    def angular_momentum(self, t: float) -> np.ndarray:
        """Return the centroidal angular momentum [N.m.s] (about the CoM, world axes)."""
        tr = self.traj
        h = pin.computeCentroidalMomentum(self.model, self.data, tr.configuration(t),
                                          tr.velocity(t))
        return h.angular.copy()

    def wrench(self, t: float) -> np.ndarray:
        """Return [m (c'' - g); L'] [N, N.m] by central differences of c(t) and L(t)."""
        c_dd = (self.com(t + H_POS) - 2.0 * self.com(t) + self.com(t - H_POS)) / H_POS ** 2
        l_d = (self.angular_momentum(t + H_POS) - self.angular_momentum(t - H_POS)) \
            / (2.0 * H_POS)
        return np.concatenate([self.mass * (c_dd - self.gravity), l_d])

    def rnea(self, t: float) -> np.ndarray:
        """Return the inverse dynamics at the true q, v and dv/dt [N.m]."""
        tr = self.traj
        return pin.rnea(self.model, self.data, tr.configuration(t), tr.velocity(t),
                        tr.acceleration(t)).copy()
