r"""
Kinematics of the gait generator: standing geometry, inverse kinematics, CoM, frames.

Frames: world (REP 103, z up) and the base frame of the floating base; the base orientation
is a roll about world x only (``R = rot_x(roll)``), as the gait generator makes it. The
equations the gait module numbers (see :mod:`awp_ros.gait.generator`):

.. math::

    (1)\quad p^{b}_k = R^T (p^{w}_k - p^{w}_{base}), \qquad
    (2)\quad q_k \leftarrow q_k + J_k(q)^{-1} (p^{b}_k - \mathrm{fk}_k(q))
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from awp_ros.errors import ConfigError, ModelError
from awp_ros.robot.model import RobotModel

__all__ = ['standing_geometry', 'quadrants', 'rotate_to_base', 'inverse_kinematics',
           'com_world', 'base_frame']


def standing_geometry(model: RobotModel) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the feet (K, 3) and CoM (3,) in the base frame in the standing posture [m].

    :raises ConfigError: the config has no ``standing_posture``.
    """
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


def quadrants(feet: tuple[str, ...], nominal: np.ndarray) -> dict[str, int]:
    """
    Map 'lf', 'rf', 'lh', 'rh' to foot indices by the sign of the standing positions.

    :param nominal: (K, >= 2) standing foot positions in the base frame [m].
    :raises ConfigError: not 4 feet, or two feet in one quadrant.
    """
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


def rotate_to_base(v: np.ndarray, c: np.ndarray, s: np.ndarray) -> np.ndarray:
    """
    Return :math:`R^T v` for :math:`R = rot_x(roll)`: world vectors in the base frame.

    :param v: (..., 3) vectors, world frame.
    :param c: cos(roll), broadcastable to ``v[..., 0]``.
    :param s: sin(roll), likewise.
    """
    return np.stack([v[..., 0], c * v[..., 1] + s * v[..., 2],
                     -s * v[..., 1] + c * v[..., 2]], axis=-1)


def inverse_kinematics(model: RobotModel, feet_b: np.ndarray, t: np.ndarray, *,
                       tol: float, max_iter: int) -> np.ndarray:
    """
    Solve equation 2 at every sample, warm-started from the previous one.

    :param feet_b: (N, K, 3) foot targets in the base frame [m].
    :param t: (N,) sample times [s] (for the error messages).
    :param tol: stop when every foot is within this distance of its target [m].
    :param max_iter: Newton iterations per sample before giving up.
    :return: (N, n_j) joint positions [rad].
    :raises ModelError: a target is out of reach or a joint leaves its limits.
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


def com_world(model: RobotModel, q: np.ndarray, base: np.ndarray,
              quat: np.ndarray) -> np.ndarray:
    """
    Return the whole-body CoM in the world frame (N, 3) [m].

    :param q: (N, n_j) joint positions [rad].
    :param base: (N, 3) base positions, world [m].
    :param quat: (N, 4) base orientations ``[x, y, z, w]``, world from base.
    """
    pm, data = model.model, model.data
    q_full = pin.neutral(pm)
    out = np.empty((q.shape[0], 3))
    for i in range(q.shape[0]):
        q_full[:3] = base[i]
        q_full[3:7] = quat[i]
        q_full[7:] = q[i]
        out[i] = pin.centerOfMass(pm, data, q_full)
    return out


def base_frame(model: RobotModel) -> str:
    """Return the name of the body frame fixed to the floating base (e.g. base_link)."""
    for frame in model.model.frames:
        if frame.parentJoint == 1 and frame.type == pin.FrameType.BODY:
            return frame.name
    return 'base_link'
