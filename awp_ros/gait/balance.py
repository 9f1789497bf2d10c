r"""
The balance planner: a CoM trajectory whose ZMP stays where the support allows.

The cart-table model of the whole body, exact for the centroidal dynamics (equation 7 of
:mod:`awp_ros.gait.dynamics`) once the CoM height c_z(t) and the angular-momentum rate
:math:`\dot L(t)` are known: the ZMP is linear in the horizontal CoM path,

.. math::

    (8)\quad p_k = c_k - \alpha_k \ddot c_k + \beta_k, \qquad
    \alpha_k = \frac{c_{z,k}}{\ddot c_{z,k} + g}, \qquad
    \beta_k = \frac{(-\dot L_{y,k},\ \dot L_{x,k})}{m (\ddot c_{z,k} + g)}

(with :math:`\alpha = h / g = 1 / \omega^2`, :math:`\beta = 0` it is the linear inverted
pendulum, LIP). The horizontal CoM path c_k (world xy, every sample k, :math:`\ddot c_k`
and the jerk by finite differences, equation 3) is the solution of one equality-constrained
least-squares problem over the whole horizon, offline and deterministic:

.. math::

    (9)\quad \min_c \sum_k w_k \|p_k - r_k\|^2 + v_k \|c_k - r_k\|^2
    + \lambda \|\dddot c_k\|^2
    \quad \mathrm{s.t.} \quad n_j \cdot p_{k_j} = b_j, \quad c_{k_i} = \bar c_i

solved once as a sparse KKT system (SuperLU). The rows come from the support
(:func:`zmp_task`):

- four feet: r = the nominal CoM of the plan (its kinematic body path), a loose weight;
- three feet: r = the nominal CoM (in the crawl and the lurch ``crawl_margin_m`` inside the
  support triangle, still during the swing), tight weights on the ZMP and on the CoM;
- two feet (trot): the ZMP on the line through the two stance feet, a row per sample
  (:math:`n` the line's normal: equation 10, the contact wrench's moment about that line
  vanishes, as two point contacts require); r = the nominal CoM projected on the line, so
  that the ZMP moves along it;
- a :class:`~awp_ros.gait.plan.ZmpWindow` (the lurch): ZMP and CoM at rest over the
  window's start before it (rows), the ZMP on the window's line outside the support
  triangle in it (rows), then at the capture point (equation 11), tight for the first
  :data:`CATCH_SAMPLES` so that the ZMP is back inside the triangle at once;
- the CoM at rest at the first and last three samples (rows).

:math:`\alpha` and :math:`\beta` depend on the whole-body motion that the CoM path produces
(bob, roll, the swinging legs' momentum); :func:`awp_ros.gait.generator.generate_gait`
iterates: plan (9), whole-body IK, measure c_z and :math:`\dot L`, plan again.

.. math::

    (10)\quad \hat d \cdot (\tau + (c - p_1) \times f) = 0, \qquad
    \hat d = (p_2 - p_1) / \|p_2 - p_1\|

(:math:`\tau + (c - p_1) \times f`, the contact wrench's moment about p_1, must be
:math:`(p_2 - p_1) \times f_2`; with the feet on the ground it is :math:`f_z` times the
ZMP's distance from the line.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from awp_ros.errors import ModelError
from awp_ros.gait.plan import GaitPlan

__all__ = ['ZmpTask', 'zmp_task', 'plan_com', 'ZMP_SIGMA_M', 'COM_SIGMA_M', 'JERK_SIGMA',
           'CATCH_SAMPLES']

#: Tolerated ZMP distance from its reference [m] by number of stance feet, in a window, in
#: its first samples after it and in the rest of its recovery (w of equation 9 is
#: 1 / sigma^2 per sample); on two feet only the along-line part is free.
ZMP_SIGMA_M = {4: 0.05, 3: 0.004, 2: 0.03, 'window': 0.004, 'catch': 0.0005,
               'recovery': 0.01}
#: Samples after a window with the tight 'catch' weight (the ZMP jumps into the support).
CATCH_SAMPLES = 5
#: Tolerated CoM distance from the reference on three feet [m] (v of equation 9 is
#: 1 / sigma^2 per sample: holds the body still while a foot swings).
COM_SIGMA_M = 0.004
#: Tolerated CoM jerk [m/s^3] (lambda of equation 9 is 1 / JERK_SIGMA^2 per sample).
JERK_SIGMA = 20.0
_EPS_S = 1e-9   # [s] sample times within this of a boundary count as after it
#: Largest constraint residual of the solved system accepted [m].
SOLVE_TOL_M = 1e-9


@dataclass(frozen=True)
class ZmpTask:
    """
    The data of equation 9 at N samples.

    ``nominal`` (N, 2) the plan's nominal CoM [m] world xy; ``reference`` (N, 2) r [m];
    ``weight`` (N,) w [1/m^2] of the ZMP and ``com_weight`` (N,) v [1/m^2] of the CoM; the
    ZMP's equality rows ``rows`` (M,) sample indices, ``normals`` (M, 2) n, ``offsets``
    (M,) b [m]; the CoM's ``com_rows`` (L,) sample indices where it is at ``com_points``
    (L, 2) [m].
    """

    nominal: np.ndarray
    reference: np.ndarray
    weight: np.ndarray
    com_weight: np.ndarray
    rows: np.ndarray
    normals: np.ndarray
    offsets: np.ndarray
    com_rows: np.ndarray
    com_points: np.ndarray


def zmp_task(plan: GaitPlan, t: np.ndarray, feet_w: np.ndarray,
             stance: np.ndarray) -> ZmpTask:
    """
    Return the references, weights and constraints of equation 9 (see the module docstring).

    :param t: (N,) sample times [s].
    :param feet_w: (N, K, 3) foot positions, world [m].
    :param stance: (N, K) feet in contact.
    """
    nominal = plan.body.evaluate(t) + plan.com_offset
    ref = nominal.copy()
    count = stance.sum(axis=1)
    sigma = np.full(t.shape[0], ZMP_SIGMA_M[4])
    sigma[count == 3] = ZMP_SIGMA_M[3]
    com_weight = np.where(count == 3, 1.0 / COM_SIGMA_M ** 2, 0.0)
    rows, normals, offsets = [], [], []
    two = np.flatnonzero(count == 2)
    if two.size:
        idx = np.argsort(~stance[two], axis=1, kind='stable')[:, :2]
        a = feet_w[two, idx[:, 0], :2]
        d = feet_w[two, idx[:, 1], :2] - a
        d /= np.linalg.norm(d, axis=1)[:, None]
        n = np.column_stack([-d[:, 1], d[:, 0]])
        ref[two] = a + np.einsum('ij,ij->i', nominal[two] - a, d)[:, None] * d
        sigma[two] = ZMP_SIGMA_M[2]
        rows.append(two)
        normals.append(n)
        offsets.append(np.einsum('ij,ij->i', n, a))
    com_rows, com_points = [], []
    for win in plan.windows:
        hold, inside, after = (np.flatnonzero((t >= t0 - _EPS_S) & (t < t1 - _EPS_S))
                               for t0, t1 in ((win.hold, win.t0), (win.t0, win.t1),
                                              (win.t1, win.until)))
        # The hold: ZMP and CoM at rest over the start (both ZMP coordinates as rows).
        ref[hold] = win.start
        for axis in np.eye(2):
            rows.append(hold)
            normals.append(np.tile(axis, (hold.size, 1)))
            offsets.append(np.full(hold.size, axis @ win.start))
        com_rows.append(hold[-2:])
        com_points.append(np.tile(win.start, (min(2, hold.size), 1)))
        ref[inside] = win.point
        sigma[inside] = ZMP_SIGMA_M['window']
        com_weight[inside] = 0.0
        rows.append(inside)
        normals.append(np.tile(win.normal, (inside.size, 1)))
        offsets.append(np.full(inside.size, win.offset))
        ref[after] = win.catch
        sigma[after] = ZMP_SIGMA_M['recovery']
        sigma[after[:CATCH_SAMPLES]] = ZMP_SIGMA_M['catch']
        com_weight[after] = 0.0
    rows_a, normals_a, offsets_a = (np.concatenate(x) for x in ([np.zeros(0, int)] + rows,
                                                                [np.zeros((0, 2))] + normals,
                                                                [np.zeros(0)] + offsets))
    com_rows_a = np.concatenate([np.zeros(0, int)] + com_rows)
    com_points_a = np.concatenate([np.zeros((0, 2))] + com_points)
    return ZmpTask(nominal, ref, 1.0 / sigma ** 2, com_weight, rows_a, normals_a, offsets_a,
                   com_rows_a, com_points_a)


def _second_difference_matrix(n: int, dt: float) -> sp.csr_matrix:
    """Return the (n, n) matrix of equation 3's second derivative (rows 0, n-1 zero)."""
    main = np.r_[0.0, np.full(n - 2, -2.0), 0.0]
    off_lo = np.r_[np.ones(n - 2), 0.0]
    off_hi = np.r_[0.0, np.ones(n - 2)]
    return sp.diags([off_lo, main, off_hi], [-1, 0, 1], shape=(n, n), format='csr') / dt ** 2


def _third_difference_matrix(n: int, dt: float) -> sp.csr_matrix:
    """Return the (n - 3, n) matrix of the jerk (c_{k+3} - 3 c_{k+2} + 3 c_{k+1} - c_k)."""
    ones = np.ones(n - 3)
    return sp.diags([-ones, 3.0 * ones, -3.0 * ones, ones], [0, 1, 2, 3],
                    shape=(n - 3, n), format='csr') / dt ** 3


def plan_com(task: ZmpTask, alpha: np.ndarray, beta: np.ndarray, dt: float,
             guess: np.ndarray | None = None) -> np.ndarray:
    """
    Solve equation 9 and return the horizontal CoM path (N, 2) [m], world xy.

    The CoM is at rest at the reference at both ends (three samples each).

    :param alpha: (N,) alpha of equation 8 [s^2].
    :param beta: (N, 2) beta of equation 8 [m].
    :param guess: (N, 2) a path near the solution (the previous one) [m]; None = the
        nominal CoM of the task.
    :raises ModelError: the system is singular (e.g. contradictory constraints).
    """
    n = alpha.shape[0]
    if n < 8:
        raise ModelError(f'the motion needs at least 8 samples to be planned, got {n}')
    x0 = task.nominal if guess is None else guess
    # The system is stiff (jerk against ZMP weights, condition ~1e11): solve for the step
    # from the guess x0, its right-hand side from differences of x0 (np.diff), so that the
    # rounding errors scale with the step and the guess's derivatives, not its positions.
    P = (sp.identity(n, format='csr') - sp.diags(alpha) @ _second_difference_matrix(n, dt))
    D3 = _third_difference_matrix(n, dt)
    lam = 1.0 / JERK_SIGMA ** 2
    H1 = (P.T @ sp.diags(task.weight) @ P + sp.diags(task.com_weight)
          + lam * (D3.T @ D3)).tocsr()
    acc0 = np.zeros_like(x0)
    acc0[1:-1] = np.diff(x0, 2, axis=0) / dt ** 2
    p0 = x0 - alpha[:, None] * acc0 + beta                  # equation 8 on the guess
    jerk0 = np.diff(x0, 3, axis=0) / dt ** 3
    g = np.column_stack([P.T @ (task.weight * (task.reference[:, i] - p0[:, i]))
                         + task.com_weight * (task.reference[:, i] - x0[:, i])
                         - lam * (D3.T @ jerk0[:, i]) for i in (0, 1)])
    H = sp.block_diag([H1, H1], format='csr')
    # Equality rows: n . p_k = b_k (p by equation 8), then the CoM at rest at both ends and
    # wherever the task holds it.
    Pk = P[task.rows]
    A_zmp = sp.hstack([sp.diags(task.normals[:, 0]) @ Pk, sp.diags(task.normals[:, 1]) @ Pk])
    b_zmp = task.offsets - np.einsum('ij,ij->i', task.normals, p0[task.rows])
    ends = np.r_[0, 1, 2, n - 3, n - 2, n - 1, task.com_rows]
    sel = sp.csr_matrix((np.ones(ends.size), (np.arange(ends.size), ends)),
                        shape=(ends.size, n))
    A_end = sp.block_diag([sel, sel], format='csr')
    points = np.concatenate([np.repeat(task.reference[:1], 3, axis=0),
                             np.repeat(task.reference[-1:], 3, axis=0), task.com_points])
    b_end = np.r_[points[:, 0] - x0[ends, 0], points[:, 1] - x0[ends, 1]]
    # Scale the blocks to O(1) for the factorisation: H by its largest entry, rows by theirs.
    h = abs(H).max()
    A = sp.vstack([A_zmp, A_end], format='csr')
    row_scale = 1.0 / np.maximum(abs(A).max(axis=1).toarray()[:, 0], 1e-300)
    A = sp.diags(row_scale) @ A
    b = np.r_[b_zmp, b_end] * row_scale
    K = sp.bmat([[H / h, A.T], [A, None]], format='csc')
    try:
        sol = spla.spsolve(K, np.r_[g[:, 0] / h, g[:, 1] / h, b])
    except RuntimeError as exc:   # SuperLU: singular
        raise ModelError(f'the balance plan has no solution: {exc}') from exc
    step = sol[:2 * n]
    residual = np.abs((A @ step - b) / row_scale).max()
    if not (np.isfinite(step).all() and residual < SOLVE_TOL_M):
        raise ModelError(f'the balance plan has no solution (constraint residual '
                         f'{residual:.3g} m)')
    return x0 + np.column_stack([step[:n], step[n:]])
