r"""
The one LP of the geometry package: the Chebyshev ball of a polytope.

.. math::

    \max_{x, r} \; r \quad 	ext{s.t.} \quad a_i \cdot x + \|a_i\| \, r \le b_i, \quad
    r \le r_{max}

(Boyd & Vandenberghe, *Convex Optimization*, Section 8.5.1.) Its optimum ``r`` is the
radius of the largest ball inside ``{x : A x <= b}`` (negative when the set is empty:
then ``-r`` is how much every row must be relaxed for a point to exist), ``x`` its centre.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linprog

__all__ = ['chebyshev_ball']


def chebyshev_ball(A: np.ndarray, b: np.ndarray, *, max_radius: float | None = None,
                   min_radius: float | None = None) -> tuple[np.ndarray, float] | None:
    """
    Return the centre and radius of the largest ball in ``{x : A x <= b}``, or None.

    :param A: (m, d) row normals (any length; the radius is in the units of ``x``).
    :param b: (m,) offsets.
    :param max_radius: upper bound of the radius (keeps unbounded sets bounded).
    :param min_radius: lower bound of the radius (None: free, so an empty set gives a
        negative radius; 0: an empty set makes the LP infeasible, hence None).
    :return: ``(centre (d,), radius)``, None when the LP fails or is infeasible.
    """
    A = np.asarray(A, dtype=float)
    d = A.shape[1]
    norms = np.linalg.norm(A, axis=1)
    c = np.zeros(d + 1)
    c[-1] = -1.0
    bounds = [(None, None)] * d + [(min_radius, max_radius)]
    A_ub, b_ub = np.hstack([A, norms[:, None]]), np.asarray(b, dtype=float)
    res = linprog(c, A_ub=A_ub, b_ub=b_ub, bounds=bounds, method='highs')
    if res.status == 4:     # HiGHS' presolve sometimes fails numerically: solve without it
        res = linprog(c, A_ub=A_ub, b_ub=b_ub, bounds=bounds, method='highs',
                      options={'presolve': False})
    if res.status != 0:
        return None
    return res.x[:d], float(res.x[-1])
