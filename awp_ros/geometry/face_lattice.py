r"""
Face structure of a small convex polytope of R^3 given by its points, with normal cones.

For the Minkowski-sum engine (:mod:`awp_ros.wrench.feasible_wrench_set`) a polytope
:math:`Q = \mathrm{conv}\{v_1, \dots, v_n\} \subset \mathbb{R}^3` of dimension
:math:`d \le 3` (a force polytope [N], in world-aligned axes) is described by its faces
:math:`G` of every dimension :math:`1 \le \dim G \le d` (edges, facets and ``Q`` itself),
each with

- an orthonormal basis of its direction space :math:`\mathrm{dir}(G)` (``dirs``), and
- check vectors :math:`m_1, \dots` (``checks``) such that its normal cone is

.. math::

    N_Q(G) = \{c \in \mathbb{R}^3 : c \perp \mathrm{dir}(G),\; m_i \cdot c \ge 0\}
    \qquad (1)

(``c`` maximises ``c . x`` over ``Q`` on all of ``G`` iff ``c`` is in :math:`N_Q(G)`). For a
3D polytope: a facet with outward unit normal ``n`` has ``m = n`` (c = t n, t >= 0); an edge
between facets with normals ``n_f, n_g`` has the dual pair ``m_f = n_f - (n_f . n_g) n_g``,
``m_g`` likewise (c = alpha n_f + beta n_g, alpha, beta >= 0); ``Q`` itself has none
(c = 0). For a polygon with plane normal ``nu`` an edge has its in-plane outward normal as
the single check (c = alpha m + beta nu, alpha >= 0) and the polygon none (c = beta nu); a
segment has none. Zero check vectors pad the arrays (always satisfied).

The facets of a 3D polytope are read from its H-rep when one is given (rows holding a planar
set of points), else found by brute force over point triples (the point sets of the legs
have at most a few dozen points): a plane through three points is a facet plane when no
point lies beyond it. Facets are deduplicated by their incidence sets, and edges are the
pairs of facets sharing at least two points. No qhull, so coplanar facets and degenerate
inputs (flat, segment, point) are handled without joggling; a set flat within ``rank_tol``
is projected on its plane (or line) so that faces and points stay consistent.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from itertools import combinations

import numpy as np

from awp_ros.errors import InputError
from awp_ros.geometry import kernels
from awp_ros.geometry.linalg import cross3, orthonormal_span

__all__ = ['FaceGroup', 'Faces', 'polytope_faces']


@dataclass(frozen=True)
class FaceGroup:
    """
    Faces of one dimension ``d``, in classes of faces with the same direction space.

    ``dirs`` (m, d, 3): an orthonormal basis of each class's direction space; ``checks``
    (m, k, c, 3): the check vectors of the up to ``k`` faces of each class; ``mask`` (m, k):
    which of the ``k`` slots hold a face. Classes are sorted by decreasing size, so slot ``i``
    is filled for a prefix of the classes. Parallel edges (and opposite facets) share a class,
    so the engine solves for their normal once and tests the union of their normal cones.
    """

    dirs: np.ndarray
    checks: np.ndarray
    mask: np.ndarray

    @property
    def count(self) -> int:
        """Return the number of faces in the group."""
        return int(self.mask.sum())

    @classmethod
    def from_faces(cls, dirs: np.ndarray, checks: np.ndarray,
                   decimals: int = 10) -> FaceGroup:
        """
        Group faces given one by one (``dirs`` (n, d, 3), ``checks`` (n, c, 3)).

        Faces whose direction spaces agree after rounding the sign-normalised unit edge
        direction (d = 1) or plane normal (d = 2) to ``decimals`` decimals share a class.
        """
        n, d = dirs.shape[:2]
        if n == 1:
            return cls(dirs, checks[:, None], np.ones((1, 1), dtype=bool))
        if d == 1:
            key = dirs[:, 0, :]
        elif d == 2:
            key = cross3(dirs[:, 0, :], dirs[:, 1, :])
        else:
            key = np.zeros((n, 1))
        if key.shape[1] == 3:
            key = key / np.linalg.norm(key, axis=1)[:, None]
            lead = key[np.arange(n), np.argmax(np.abs(key), axis=1)]
            key = key * np.sign(lead)[:, None]
        if n > 1:
            q = np.round(key * 10.0 ** decimals).astype(np.int64)
            # Hash each row to one integer; verify (a collision falls back to rows).
            weights = np.array([1, 1000003, 998244353], dtype=np.int64)[:q.shape[1]]
            _, first, inverse = np.unique(q @ weights, return_index=True, return_inverse=True)
            if not np.array_equal(q, q[first[inverse]]):
                _, first, inverse = np.unique(q, axis=0, return_index=True,
                                              return_inverse=True)
            inverse = inverse.ravel()
        else:
            first, inverse = np.zeros(n, dtype=int), np.zeros(n, dtype=int)
        # Renumber the classes by decreasing size (the engine relies on it).
        counts = np.bincount(inverse, minlength=first.size)
        rank = np.empty(first.size, dtype=int)
        rank[np.argsort(-counts, kind='stable')] = np.arange(first.size)
        first[rank] = first.copy()
        inverse = rank[inverse]
        m = first.size
        order = np.argsort(inverse, kind='stable')
        counts = np.bincount(inverse, minlength=m)
        slot = np.empty(n, dtype=int)
        slot[order] = np.arange(n) - np.repeat(np.cumsum(counts) - counts, counts)
        k = int(counts.max()) if n else 0
        grouped = np.zeros((m, k) + checks.shape[1:])
        mask = np.zeros((m, k), dtype=bool)
        grouped[inverse, slot] = checks
        mask[inverse, slot] = True
        return cls(dirs[first], grouped, mask)


@dataclass(frozen=True)
class Faces:
    """
    Face structure of a polytope of R^3 (see the module docstring).

    :ivar dimension: affine dimension (-1 for the empty set).
    :ivar vertices: (n, 3) extreme points [same unit as the input].
    :ivar origin: (3,) a point of the affine hull (the vertex centroid).
    :ivar basis: (3, d) orthonormal basis of the hull's direction space.
    :ivar groups: ``groups[d - 1]`` holds the faces of dimension ``d`` for ``d = 1..dimension``.
    :ivar facet_normals: (F, 3) unit outward normals (3D only, else (0, 3)).
    :ivar facet_offsets: (F,) offsets, ``facet_normals @ x <= facet_offsets`` on ``Q``.
    """

    dimension: int
    vertices: np.ndarray
    origin: np.ndarray
    basis: np.ndarray
    groups: tuple[FaceGroup, ...]
    facet_normals: np.ndarray
    facet_offsets: np.ndarray


def polytope_faces(points: np.ndarray, halfspaces: tuple[np.ndarray, np.ndarray] | None = None,
                   *, rank_tol: float = 1e-9, plane_tol: float = 1e-9) -> Faces:
    r"""
    Return the faces and normal cones of ``conv(points)`` in R^3.

    .. math:: Q = \mathrm{conv}\{v_1, \dots, v_n\}, \quad
              N_Q(G) = \{c : c \perp \mathrm{dir}(G), m_i \cdot c \ge 0\}

    :param points: (n, 3) points, any unit (usually forces [N]); duplicates and non-extreme
        points are allowed; ``n = 0`` is the empty set.
    :param halfspaces: optional ``(A, b)``, rows with ``A x <= b`` on the polytope among which
        are all its facet planes (e.g. the H-rep the points were enumerated from); for a 3D
        polytope the facets are then read from them instead of from all point triples.
    :param rank_tol: singular values of the centred points below ``rank_tol`` times the
        largest distance from the centroid count as zero (flat, segment, point); such a set
        is projected on its affine hull (moving points by at most about that much).
    :param plane_tol: a point within ``plane_tol`` times that distance of a plane (or line)
        lies on it.
    :return: a :class:`Faces`.
    :raises InputError: when ``points`` is not a finite (n, 3) array.
    """
    V = np.asarray(points, dtype=float)
    if V.ndim != 2 or V.shape[1] != 3:
        raise InputError(f'points must have shape (n, 3); got shape {V.shape}')
    if not np.isfinite(V).all():
        raise InputError('points must be finite; got NaN or inf')
    if V.shape[0] == 0:
        empty = np.zeros((0, 3))
        return Faces(-1, empty, np.zeros(3), np.zeros((3, 0)), (), empty, np.zeros(0))
    if halfspaces is not None and kernels.ENABLED:
        found = kernels.certified_solid_faces(V, halfspaces[0], halfspaces[1], rank_tol,
                                              plane_tol)
        if found is not None:       # compiled, one call (the code below is its reference)
            origin, (extreme, N, offsets, ed, ec, em, fd, fc, fm) = found
            groups = (FaceGroup(ed, ec, em), FaceGroup(fd, fc, fm), _WHOLE)
            return Faces(3, extreme, origin, np.eye(3), groups, N, offsets)
    origin = V.mean(axis=0)
    X = V - origin
    scale = float(np.max(np.linalg.norm(X, axis=1)))
    basis = orthonormal_span(X, rtol=rank_tol) if scale > 0.0 else np.zeros((3, 0))
    d = basis.shape[1]
    tol = plane_tol * scale
    if d == 3 and halfspaces is not None and kernels.ENABLED:
        solid = kernels.solid_faces(V, halfspaces[0], halfspaces[1], origin, scale, tol)
        if solid is not None:       # compiled, one call (the code below is its reference)
            extreme, N, offsets, ed, ec, em, fd, fc, fm = solid
            groups = (FaceGroup(ed, ec, em), FaceGroup(fd, fc, fm), _WHOLE)
            return Faces(3, extreme, origin, np.eye(3), groups, N, offsets)
    # Merge points closer than tol (keep the first of each cluster). A set found flat (or a
    # segment) within rank_tol is projected on its affine hull: the faces and the points
    # then describe one and the same (flattened) polytope.
    dist = np.linalg.norm(X[:, None, :] - X[None, :, :], axis=2)
    V = V[~np.any(np.tril(dist <= tol, k=-1), axis=1)]
    if d < 3:
        V = origin + (V - origin) @ basis @ basis.T
    if d == 0:
        return Faces(0, origin[None, :], origin, basis, (), np.zeros((0, 3)), np.zeros(0))
    if d == 1:
        s = (V - origin) @ basis[:, 0]
        ends = V[[int(np.argmin(s)), int(np.argmax(s))]]
        whole = FaceGroup.from_faces(basis.T[None, :, :], np.zeros((1, 0, 3)))
        return Faces(1, ends, origin, basis, (whole,), np.zeros((0, 3)), np.zeros(0))
    if d == 2:
        return _polygon_faces(V, origin, basis, tol)
    if halfspaces is None:
        N, inc = _facet_planes(V, tol)
    else:
        N, inc = _facet_rows(V, halfspaces, tol)
    return _solid_faces(V, origin, scale, N, inc)


def _polygon_faces(V: np.ndarray, origin: np.ndarray, basis: np.ndarray,
                   tol: float) -> Faces:
    """Faces of a flat (2D) polytope: its edges (one check each) and itself."""
    Y = (V - origin) @ basis                      # (n, 2) plane coordinates
    n = Y.shape[0]
    i, j = _index_tuples(n, 2)
    t = Y[j] - Y[i]
    length = np.linalg.norm(t, axis=1)
    ok = length > tol
    i, j, t = i[ok], j[ok], t[ok] / length[ok, None]
    m2 = np.stack([t[:, 1], -t[:, 0]], axis=1)    # a normal of the line through i, j
    dist = Y @ m2.T - np.einsum('kd,kd->k', Y[i], m2)[None, :]   # (n, pairs)
    above = np.all(dist <= tol, axis=0)
    below = np.all(dist >= -tol, axis=0)
    keep = above | below
    m2 = np.where(below[:, None] & ~above[:, None], -m2, m2)[keep]
    inc = (np.abs(dist[:, keep]) <= tol).T        # (pairs, n)
    _, first = np.unique(_bit_keys(inc), return_index=True)
    inc, m2, t = inc[first], m2[first], t[keep][first]
    extreme = inc.sum(axis=0) >= 2
    dirs = (t @ basis.T)[:, None, :]
    checks = (m2 @ basis.T)[:, None, :]
    edges = FaceGroup.from_faces(dirs, checks)
    whole = FaceGroup.from_faces(basis.T[None, :, :], np.zeros((1, 0, 3)))
    return Faces(2, V[extreme], origin, basis, (edges, whole), np.zeros((0, 3)), np.zeros(0))


def _facet_planes(V: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Facet normals and incidence of a 3D point set, by brute force over point triples."""
    n = V.shape[0]
    i, j, k = _index_tuples(n, 3)
    N = cross3(V[j] - V[i], V[k] - V[i])
    area = np.linalg.norm(N, axis=1)              # twice the triangle's area
    longest = np.max(np.linalg.norm(np.stack([V[j] - V[i], V[k] - V[i], V[k] - V[j]]),
                                    axis=2), axis=0)
    ok = area > tol * longest                     # height above the longest side > tol
    i, N, area = i[ok], N[ok] / area[ok, None], area[ok]
    dist = V @ N.T - np.einsum('kd,kd->k', V[i], N)[None, :]    # (n, triples)
    above = np.all(dist <= tol, axis=0)
    below = np.all(dist >= -tol, axis=0)
    keep = above | below
    N = np.where(below[:, None] & ~above[:, None], -N, N)[keep]
    inc = (np.abs(dist[:, keep]) <= tol).T        # (facets with repeats, n)
    area = area[keep]
    # One representative per incidence set: the largest triangle gives the best normal.
    _, group = np.unique(_bit_keys(inc), return_inverse=True)
    order = np.lexsort((-area, group))
    first = order[np.r_[True, group[order][1:] != group[order][:-1]]]
    return N[first], inc[first]


def _facet_rows(V: np.ndarray, halfspaces: tuple[np.ndarray, np.ndarray],
                tol: float) -> tuple[np.ndarray, np.ndarray]:
    """
    Facet normals and incidence read from supporting rows ``A x <= b`` of a 3D polytope.

    A row is a facet when the points on it span a plane (second eigenvalue of their scatter
    above ``tol^2``); rows with the same incidence are one facet.
    """
    A = np.asarray(halfspaces[0], dtype=float).reshape(-1, 3)
    b = np.asarray(halfspaces[1], dtype=float).reshape(-1)
    norm = np.linalg.norm(A, axis=1)
    ok = norm > 0.0
    A, b = A[ok] / norm[ok, None], b[ok] / norm[ok]
    inc = np.abs(V @ A.T - b[None, :]).T <= tol   # (rows, n)
    w = inc.astype(float)
    count = np.maximum(w.sum(axis=1), 1.0)
    mean = (w @ V) / count[:, None]
    scatter = np.einsum('rn,nd,ne->rde', w, V, V) / count[:, None, None] - \
        mean[:, :, None] * mean[:, None, :]
    flat = np.linalg.eigvalsh(scatter)[:, 1] > tol ** 2
    A, inc = A[flat], inc[flat]
    _, first = np.unique(_bit_keys(inc), return_index=True)
    return A[first], inc[first]


def _solid_faces(V: np.ndarray, origin: np.ndarray, scale: float, N: np.ndarray,
                 inc: np.ndarray) -> Faces:
    """Faces of a 3D polytope from its facets (unit normals ``N``, point incidence ``inc``)."""
    extreme = inc.sum(axis=0) >= 3
    offsets = np.max(V @ N.T, axis=0)
    f, g = _index_tuples(N.shape[0], 2)
    shared = inc[f] & inc[g]
    adjacent = shared.sum(axis=1) >= 2
    f, g = f[adjacent], g[adjacent]
    e = _edge_directions(V, N[f], N[g], shared[adjacent], scale)
    nf = N[f] - np.einsum('kd,kd->k', N[f], e)[:, None] * e
    ng = N[g] - np.einsum('kd,kd->k', N[g], e)[:, None] * e
    mf = nf - np.einsum('kd,kd->k', nf, ng)[:, None] * ng / np.einsum('kd,kd->k', ng, ng)[:, None]
    mg = ng - np.einsum('kd,kd->k', ng, nf)[:, None] * nf / np.einsum('kd,kd->k', nf, nf)[:, None]
    mf /= np.linalg.norm(mf, axis=1)[:, None]
    mg /= np.linalg.norm(mg, axis=1)[:, None]
    edges = FaceGroup.from_faces(e[:, None, :], np.stack([mf, mg], axis=1))
    facets = FaceGroup.from_faces(_plane_bases(N), N[:, None, :])
    return Faces(3, V[extreme], origin, np.eye(3), (edges, facets, _WHOLE), N, offsets)


# The group of a solid polytope itself: all of R^3, no check (its normal cone is {0}).
_WHOLE = FaceGroup.from_faces(np.eye(3)[None, :, :], np.zeros((1, 0, 3)))
for _array in (_WHOLE.dirs, _WHOLE.checks, _WHOLE.mask):
    _array.setflags(write=False)


def _edge_directions(V: np.ndarray, nf: np.ndarray, ng: np.ndarray, shared: np.ndarray,
                     scale: float) -> np.ndarray:
    """
    Return unit edge directions: n_f x n_g, or the chord between the farthest shared points.

    The cross product loses accuracy as 1 / sin(angle) for nearly coplanar facets, the chord
    as scale / length for short edges; the better-conditioned one is used.
    """
    e = cross3(nf, ng)
    sin = np.linalg.norm(e, axis=1)
    e /= np.where(sin > 0.0, sin, 1.0)[:, None]
    s = (V @ e.T).T                               # (edges, n)
    p0 = V[np.argmin(np.where(shared, s, np.inf), axis=1)]
    p1 = V[np.argmax(np.where(shared, s, -np.inf), axis=1)]
    chord = p1 - p0
    length = np.linalg.norm(chord, axis=1)
    use_chord = length * sin < scale
    e[use_chord] = chord[use_chord] / length[use_chord, None]
    return e


@lru_cache(maxsize=None)
def _index_tuples(n: int, k: int) -> np.ndarray:
    """Return the k-subsets of range(n) as a read-only (k, C(n, k)) index array."""
    out = np.array(list(combinations(range(n), k)), dtype=int).reshape(-1, k).T
    out.setflags(write=False)
    return out


def _bit_keys(inc: np.ndarray) -> np.ndarray:
    """Return one integer key per boolean row (its bits), rows of any length."""
    if inc.shape[1] <= 62:
        return inc.astype(np.int64) @ (np.int64(1) << np.arange(inc.shape[1], dtype=np.int64))
    words = np.packbits(inc, axis=1)
    pad = (-words.shape[1]) % 8
    words = np.pad(words, ((0, 0), (0, pad)))
    keys = words.view('>u8')
    if keys.shape[1] == 1:
        return keys[:, 0]
    return np.unique(keys, axis=0, return_inverse=True)[1].ravel()


def _plane_bases(N: np.ndarray) -> np.ndarray:
    """Return (F, 2, 3) orthonormal bases of the planes orthogonal to the unit rows of N."""
    axis = np.eye(3)[np.argmin(np.abs(N), axis=1)]
    u = cross3(N, axis)
    u /= np.linalg.norm(u, axis=1)[:, None]
    return np.stack([u, cross3(N, u)], axis=1)
