r"""
Measured contact forces: what each stance leg pushes with, from its joint efforts.

For stance leg ``k`` with foot Jacobian ``J_k`` (3 x n_k, LOCAL_WORLD_ALIGNED), bias torques
``b_k`` (the leg rows of ``rnea(q, v, a)``: seed eq. (1) without ``tau``) and measured joint
efforts ``tau_k`` [N.m], the leg's equations of motion ``tau_k = b_k - J_k^T f_k`` give

.. math::

    f_k = J_k^{-T} (b_k - \tau_k) \quad [N] \qquad (1)

(least squares, ``J_k^{T\#}``, when the leg does not have 3 joints or is singular). Then

- the **slip margin** of leg ``k``: the signed distance of ``f_k`` to the boundary of its
  friction pyramid ``C_k = {f : a_i . f <= 0}`` (unit rows, the pyramid the sets use), [N]:
  ``min_i -a_i . f_k`` inside, minus the distance to ``C_k`` outside (the force would make
  the foot slip or lift);                                                              (2)
- the **torque ratio** of leg ``k``: ``max_j |tau_j| / limit_j``, with ``limit_j`` the
  joint's upper limit for ``tau_j >= 0`` and minus its lower limit otherwise [-];          (3)
- the **external wrench**: the measured contact wrench minus the gravito-inertial one,

  .. math:: w_{ext} = \sum_k \begin{bmatrix} f_k \\ p_k \times f_k \end{bmatrix} - w
            \quad [N, N.m] \qquad (4)

  about the CoM, world-aligned axes: what the model does not explain (a push, a payload,
  estimation errors).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from awp_ros.geometry.margin import polytope_margin
from awp_ros.geometry.polytope import Polytope

__all__ = ['MeasuredForces', 'measured_contact_forces']


@dataclass(frozen=True)
class MeasuredForces:
    """
    Measured contact forces of the stance legs and what follows from them (module docstring).

    ``forces``, ``slip_margins``, ``torque_ratios``: per stance foot, (3,) [N], [N], [-];
    ``slip_foot`` the foot with the smallest slip margin (``''`` without stance legs) and
    ``slip_margin`` its margin; ``torque_ratio`` the largest ratio; ``external_wrench``
    (6,) [N, N.m], eq. (4).
    """

    forces: dict[str, np.ndarray]
    slip_margins: dict[str, float]
    torque_ratios: dict[str, float]
    slip_foot: str
    slip_margin: float
    torque_ratio: float
    external_wrench: np.ndarray


def measured_contact_forces(feet: Sequence[str], positions: np.ndarray, J: Sequence,
                            bias: Sequence, tau: Sequence, pyramid_rows: np.ndarray,
                            tau_min: Sequence, tau_max: Sequence,
                            wrench: np.ndarray) -> MeasuredForces:
    """
    Return the measured contact forces of the stance legs, eqs. (1)-(4).

    :param feet: the stance feet, in the order of the other arguments.
    :param positions: (K, 3) feet relative to the CoM, world-aligned axes [m].
    :param J: per leg (3, n_k) translational foot Jacobian [m/rad].
    :param bias: per leg (n_k,) bias torques [N.m].
    :param tau: per leg (n_k,) measured joint efforts [N.m].
    :param pyramid_rows: (K, N + 1, 3) unit rows ``a . f <= 0`` of each leg's friction
        pyramid and ``-n . f <= 0``.
    :param tau_min, tau_max: per leg (n_k,) torque limits [N.m].
    :param wrench: (6,) gravito-inertial wrench [N, N.m].
    """
    forces, slips, ratios = {}, {}, {}
    total = np.zeros(6)
    for k, foot in enumerate(feet):
        Jt = np.asarray(J[k]).T                               # (n_k, 3)
        rhs = np.asarray(bias[k]) - np.asarray(tau[k])
        f = np.linalg.lstsq(Jt, rhs, rcond=None)[0]           # eq. (1)
        forces[foot] = f
        rows = pyramid_rows[k] / np.linalg.norm(pyramid_rows[k], axis=1)[:, None]
        cone = Polytope(3, np.zeros((0, 3)), rows, np.zeros(rows.shape[0]), np.zeros(3),
                        np.eye(3))
        slips[foot] = float(polytope_margin(cone, f).margin)  # eq. (2)
        t = np.asarray(tau[k], dtype=float)
        limit = np.where(t >= 0.0, np.asarray(tau_max[k]), -np.asarray(tau_min[k]))
        ratios[foot] = float(np.max(np.abs(t) / limit)) if t.size else 0.0   # eq. (3)
        total[:3] += f
        total[3:] += np.cross(positions[k], f)
    slip_foot = min(slips, key=slips.get) if slips else ''
    return MeasuredForces(forces, slips, ratios, slip_foot,
                          slips[slip_foot] if slips else float('nan'),
                          max(ratios.values(), default=float('nan')),
                          total - np.asarray(wrench, dtype=float))          # eq. (4)
