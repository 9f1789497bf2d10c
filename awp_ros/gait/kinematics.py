r"""
Kinematics of the gait generator: standing geometry, whole-body inverse kinematics, CoM.

Frames: world (REP 103, z up) and the base frame of the floating base; the base orientation
is a roll about world x only (``R = rot_x(roll)``), as the gait generator makes it. The
whole-body inverse kinematics places the base so that the whole-body CoM (Pinocchio) is
where the balance planner wants it, and the legs so that the feet are on their targets.
Unknowns: the base's world xy ``b`` and the joints ``q``; given: the base height and roll.
Equations (the gait module's numbering, see :mod:`awp_ros.gait.generator`):

.. math::

    (1)\quad p^{b}_k = R^T (p^{w}_k - p^{w}_{base}) = \mathrm{fk}_k(q), \qquad
    (2)\quad J_k \delta q_k + R^T E \delta b = e_k

    (4)\quad c_{xy} = b + [R\, c^{b}(q)]_{xy}, \qquad
    \delta b + G \textstyle\sum_k J^{c}_k \delta q_k = e_c

    (5)\quad \delta q_k = u_k - W_k \delta b, \quad u_k = J_k^{-1} e_k, \quad
    W_k = J_k^{-1} R^T E, \quad
    (I_2 - G \textstyle\sum_k J^{c}_k W_k)\, \delta b = e_c - G \sum_k J^{c}_k u_k

with ``fk_k`` / ``J_k`` foot k's position / translational Jacobian w.r.t. its leg's joints in
the base frame, ``c^b`` / ``J^c_k`` the CoM in the base frame and its Jacobian w.r.t. leg
k's joints, ``E = [e_x e_y]`` (3 x 2), ``G`` the first two rows of ``R``, and ``e_k``,
``e_c`` the residuals (target minus value) of the feet and the CoM.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from awp_ros.errors import ConfigError, ModelError
from awp_ros.robot.model import RobotModel

__all__ = ['standing_geometry', 'quadrants', 'rotate_to_base', 'whole_body_ik', 'base_frame']


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


def whole_body_ik(model: RobotModel, feet_w: np.ndarray, base_z: np.ndarray,
                  roll: np.ndarray, com_xy: np.ndarray, t: np.ndarray, *, tol: float,
                  max_iter: int, q0: np.ndarray | None = None,
                  base0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """
    Solve equations 1 and 4 at every sample: joints and base xy for feet and CoM targets.

    Newton (equation 2 for the feet, 4 for the CoM) on 14 unknowns (base x, y; 12 joints)
    and 14 equations (the feet in the base frame; the whole-body CoM xy), the base height
    and roll given. The legs' blocks are eliminated (equation 5), leaving a 2 x 2 solve for
    the base step. All samples iterate together (the linear algebra batched over them),
    from ``q0`` / ``base0`` (a previous solution) or else from the standing posture under
    the CoM target; a sample stops when solved.

    :param feet_w: (N, K, 3) foot targets, world [m].
    :param base_z: (N,) base heights, world [m].
    :param roll: (N,) base roll about world x [rad].
    :param com_xy: (N, 2) whole-body CoM targets, world xy [m].
    :param t: (N,) sample times [s] (for the error messages).
    :param tol: a sample is solved when every foot and the CoM are within this distance [m].
    :param max_iter: Newton steps before giving up.
    :param q0: (N, n_j) initial joint positions [rad]; ``base0`` (N, 2) initial base xy [m].
    :return: joint positions (N, n_j) [rad] and base xy (N, 2) world [m].
    :raises ModelError: a target is out of reach, a leg singular, or a joint beyond its
        limits.
    """
    pm, data = model.model, model.data
    legs = [model.legs[f] for f in model.config.feet]
    frames = [leg.frame_id for leg in legs]
    cols = np.array([leg.v_idx for leg in legs])            # (K, 3) columns in v
    q_cols = cols - 6                                       # the same joints in q[7:]
    n, n_feet = feet_w.shape[0], len(legs)
    c, s = np.cos(roll), np.sin(roll)
    R = np.zeros((n, 3, 3))
    R[:, 0, 0], R[:, 1, 1], R[:, 1, 2], R[:, 2, 1], R[:, 2, 2] = 1.0, c, -s, s, c
    # Equation 1 with the base's xy among the unknowns: R^T (p - z e_z) = fk(q) + R^T E b.
    lifted = feet_w.copy()
    lifted[..., 2] -= base_z[:, None]
    target = np.einsum('nkj,nji->nki', lifted, R)
    RtE = np.swapaxes(R[:, :2, :], 1, 2)                       # (N, 3, 2)
    if q0 is None:
        q = np.tile(model.standing_q, (n, 1))
        b = com_xy - standing_geometry(model)[1][:2]
    else:
        q, b = q0.copy(), base0.copy()
    q_full = pin.neutral(pm)
    lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    fk = np.empty((n, n_feet, 3))
    J = np.empty((n, n_feet, 3, 3))
    com = np.empty((n, 3))
    Jc = np.empty((n, 3, pm.nv))
    active = np.arange(n)
    for step in range(max_iter + 1):
        for i in active:
            q_full[7:] = q[i]
            pin.computeJointJacobians(pm, data, q_full)
            for k, frame in enumerate(frames):
                fk[i, k] = pin.updateFramePlacement(pm, data, frame).translation
                J[i, k] = pin.getFrameJacobian(pm, data, frame, lwa)[:3, cols[k]]
            Jc[i] = pin.jacobianCenterOfMass(pm, data, False)
            com[i] = data.com[0]
        a = active
        err = target[a] - fk[a] - np.einsum('nij,nj->ni', RtE[a], b[a])[:, None, :]
        err_c = com_xy[a] - b[a] - np.einsum('nij,nj->ni', R[a, :2], com[a])
        keep = np.maximum(np.abs(err).max(axis=(1, 2)), np.abs(err_c).max(axis=1)) >= tol
        a, err, err_c = a[keep], err[keep], err_c[keep]
        active = a
        if not a.size:
            break
        if step == max_iter:
            i = int(a[0])
            msg = (f'IK failed at t = {t[i]:.3f} s: the foot targets '
                   f'{np.round(target[i], 4).tolist()} m (base frame) or the CoM target '
                   f'{np.round(com_xy[i], 4).tolist()} m (world xy) are out of reach')
            raise ModelError(msg)
        # Equation 5: dq_k = u_k - W_k db, (I - G sum Jc_k W_k) db = e_c - G sum Jc_k u_k.
        rhs = np.concatenate([err[..., None],
                              np.broadcast_to(RtE[a][:, None], (a.size, n_feet, 3, 2))],
                             axis=-1)
        try:
            uw = np.linalg.solve(J[a], rhs)                              # (n, K, 3, 3)
        except np.linalg.LinAlgError as exc:
            i = int(a[0])
            raise ModelError(f'IK failed at t = {t[i]:.3f} s: a leg is singular') from exc
        GJ = np.einsum('nij,njkl->nkil', R[a, :2], Jc[a][:, :, cols])   # (n, K, 2, 3)
        lhs = np.eye(2) - np.einsum('nkij,nkjl->nil', GJ, uw[..., 1:])
        rhs_b = err_c - np.einsum('nkij,nkj->ni', GJ, uw[..., 0])
        db = np.linalg.solve(lhs, rhs_b[..., None])[..., 0]
        dq = uw[..., 0] - np.einsum('nkij,nj->nki', uw[..., 1:], db)
        q[a[:, None, None], q_cols[None]] += dq
        b[a] += db
    lo, hi = pm.lowerPositionLimit[7:], pm.upperPositionLimit[7:]
    bad = np.flatnonzero(((q < lo) | (q > hi)).any(axis=0))
    if bad.size:
        j = int(bad[0])
        i = int(np.flatnonzero((q[:, j] < lo[j]) | (q[:, j] > hi[j]))[0])
        msg = (f'joint {model.joint_names[j]!r} leaves its limits [{lo[j]:.3f}, {hi[j]:.3f}] '
               f'rad at t = {t[i]:.3f} s (q = {q[i, j]:.3f}); shorten the steps')
        raise ModelError(msg)
    return q, b


def base_frame(model: RobotModel) -> str:
    """Return the name of the body frame fixed to the floating base (e.g. base_link)."""
    for frame in model.model.frames:
        if frame.parentJoint == 1 and frame.type == pin.FrameType.BODY:
            return frame.name
    return 'base_link'
