r"""
A container for convex polytopes of any dimension, in V- and H-representation.

A polytope :math:`P \subset \mathbb{R}^n` of affine dimension :math:`r \le n` is stored as

.. math::

    P = \{x \in \mathbb{R}^n : A x \le b,\; x = o + U y,\; y \in \mathbb{R}^r\}

with ``A`` of shape ``(m, n)`` whose rows are unit outward facet normals lying in the
hull's direction space (``A = A_r U^T``), ``b`` of shape ``(m,)``, the hull origin
``o`` of shape ``(n,)`` and an orthonormal hull basis ``U`` of shape ``(n, r)``.
For a full-dimensional polytope ``U`` is the identity and the equalities vanish.
``vertices`` has shape ``(k, n)``; it is ``(0, n)`` when the vertices were not
enumerated (6D sums, whose vertex count explodes). ``dimension == -1`` is the empty set.

Units and frames are those of the caller: forces in [N] for 3D force polytopes,
wrenches ``[f; tau]`` in [N] and [N.m] for 6D wrench polytopes, expressed in a frame
with world-aligned axes (REP 103) and origin at the robot's centre of mass.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

__all__ = ['Polytope']


@dataclass(frozen=True)
class Polytope:
    """A bounded convex polytope, possibly flat or empty (see the module docstring)."""

    dimension: int
    vertices: np.ndarray
    A: np.ndarray
    b: np.ndarray
    hull_origin: np.ndarray
    hull_basis: np.ndarray
    meta: dict = field(default_factory=dict, compare=False)

    @property
    def ambient_dim(self) -> int:
        """Return n, the dimension of the space the polytope lives in."""
        return int(self.hull_origin.shape[0])

    @property
    def is_empty(self) -> bool:
        """Return True for the empty set."""
        return self.dimension < 0

    @cached_property
    def equalities(self) -> tuple[np.ndarray, np.ndarray]:
        r"""
        Return (E, e) with E x = e describing the affine hull, E of shape (n - r, n).

        ``E`` has orthonormal rows spanning the complement of ``span U``. A hyperplane
        (``r = n - 1``: two stance legs) takes the column of the projector
        :math:`I - U U^T` of largest norm, normalised; other cases the SVD of ``U``.
        Computed once per polytope (read-only arrays).
        """
        n, r = self.ambient_dim, self.hull_basis.shape[1]
        if r == n:
            E = np.zeros((0, n))
        elif r == n - 1:
            U = self.hull_basis
            Q = np.eye(n) - U @ U.T
            j = int(np.einsum('ij,ij->j', Q, Q).argmax())
            E = (Q[:, j] / np.linalg.norm(Q[:, j]))[None, :]
        else:
            u, _, _ = np.linalg.svd(self.hull_basis, full_matrices=True)
            E = u[:, r:].T
        e = E @ self.hull_origin
        E.setflags(write=False)
        e.setflags(write=False)
        return E, e

    def with_hyperplane(self, normal: np.ndarray) -> Polytope:
        """
        Store the equalities of a hull known to be a hyperplane, ``normal . x = normal . o``.

        For a caller that has the hull's unit ``normal`` (orthogonal to ``hull_basis``, r =
        n - 1) in closed form, e.g. two stance feet's wrenches: :attr:`equalities` is then
        not computed. Return ``self``.
        """
        E = np.array(normal, dtype=float).reshape(1, -1)
        e = E @ self.hull_origin
        E.setflags(write=False)
        e.setflags(write=False)
        self.__dict__['equalities'] = (E, e)
        return self

    def halfspaces(self) -> np.ndarray:
        """Return the rows ``[a_1 .. a_n, b]`` of ``a . x <= b``, shape (m, n + 1)."""
        return np.hstack([self.A, self.b[:, None]])

    def contains(self, x: np.ndarray, tol: float = 1e-9) -> bool:
        """Return True if x is in P, up to ``tol`` in each constraint's units."""
        if self.is_empty:
            return False
        x = np.asarray(x, dtype=float)
        E, e = self.equalities
        if E.shape[0] and np.max(np.abs(E @ x - e)) > tol:
            return False
        return bool(np.all(self.A @ x <= self.b + tol))

    @classmethod
    def empty(cls, n: int) -> Polytope:
        """Return the empty polytope of R^n."""
        return cls(-1, np.zeros((0, n)), np.zeros((0, n)), np.zeros(0),
                   np.zeros(n), np.zeros((n, 0)))
