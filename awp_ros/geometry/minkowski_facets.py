"""
Facet normals of a Minkowski sum of lifted 3D polytopes, by face combinations.

The engine of :mod:`awp_ros.wrench.feasible_wrench_set`. For stance feet at ``p_k`` [m] relative
to the CoM (world-aligned axes) and per-leg polytopes ``Q_k`` [N] (their faces and normal
cones from :mod:`awp_ros.geometry.face_lattice`), the set is ``S = sum_k L_k Q_k`` in R^6; all is
in the coordinates ``y = U^T (x - o)`` of the affine hull of ``S``, dimension ``r``, where
``M_k = U^T L_k``. The unit outward normals ``a`` of its facets are found by:

(2) every facet of ``S`` with unit normal ``a`` is ``sum_k M_k G_k`` for faces ``G_k`` of
    ``Q_k`` whose dimensions ``d_k`` add up to ``r - 1`` and whose lifted direction spaces
    ``M_k dir(G_k)`` are independent (an exchange argument on the faces maximising ``a``);
    so ``a`` is the generalised cross product of the ``r - 1`` lifted face directions,
    ``a . v = det[v, g_1, ..., g_{r-1}]``, computed with exterior products: the wedge
    ``X_k`` of each face's directions is a ``d_k``-vector and ``a = *(X_1 ^ ... ^ X_K)``;
(3) the choice is kept only if ``c_k = M_k^T a`` lies in the normal cone of ``G_k`` for
    every leg, up to one global sign (``m . c_k >= 0`` for the face's check vectors ``m``,
    :mod:`awp_ros.geometry.face_lattice`); each check value ``m . c_k = a . (M_k m)`` is a
    determinant too, the pairing of ``(M_k m) ^ X_k`` with the wedge of the other legs' faces, so
    one small matrix product per leg tests every combination at once (no loop over candidates).

(5) With the compiled kernels and a full-dimensional sum (``r = 6``: three or more stance legs,
    not all feet on a line), the patterns of three and four stance legs, (2, 1, 1, 1),
    (2, 2, 1), (3, 1, 1) and (3, 2), are searched on *slices* instead
    (:func:`awp_ros.geometry.kernels.slice_facet_normals`).
    For world-aligned ``a = (a_f, a_t)`` the legs see ``c_k = a_f + a_t x p_k``. When leg A
    gives a facet with unit normal ``n``, ``c_A = lambda n``, so
    ``a = (lambda n + p_A x a_t, a_t)`` with ``x = (lambda, a_t)`` in R^4, and every other
    leg sees ``c_k = lambda n + a_t x d_k``, ``d_k = p_k - p_A`` (when A gives all of
    ``Q_A``, ``lambda = 0``). An edge ``e`` of leg k is then the wall ``r . x = 0`` with
    ``r = (n . e, d_k x e)``, a check ``m`` the linear form ``(n . m, d_k x m) . x``, and a
    choice's normal is the generalised cross product of its three walls (with
    ``lambda = 0`` the wall ``(1, 0, 0, 0)`` is one of them),
    ``x . y = det[r_1; r_2; r_3; y]``. For one node (the first two walls,
    ``P = r_1 ^ r_2``) a check ``s`` of a node leg is ``s . x = -*(P ^ s) . r_3``, a linear
    form of the candidate wall ``r_3``: one pass over the candidate leg's edges per check, in
    float64, with the slack ``cone_tol |s| |x|`` (or its bound ``cone_tol |s| |P| |r_3|``).
    It keeps the same facets as (3) with fewer redundant copies
    (``test_fws_facets_equal_the_numpy_reference``) in less time (README, "Speed"); flat
    sums of three or more legs (feet on a line) and five or more legs stay with (2)-(3).
(6) With the compiled kernels and two solid stance legs (``r = 5``: the legs' hyperplane), the
    patterns (2, 2) and (3, 1) are searched in one call
    (:func:`awp_ros.geometry.kernels.flat_pair_facet_normals`): about 100 choices, each
    normal the generalised cross product of its four lifted directions in R^5, checked in
    float64 with the slack ``cone_tol |M_k m| |a|`` (numpy's grid machinery, built for 10^5
    choices, cost more in set-up than in search here).
(7) Along a stream of close joint states (the node's, at its rate) the pattern (2, 1, 1, 1) is
    searched by certificates (:mod:`awp_ros.geometry.certified_search`): a choice's check
    values are determinants of its walls and checks, which move by a bounded amount when
    those vectors do, so the choices a reference joint state decided by a wider margin are
    not tested again; the rows are the same
    (``test_every_fws_of_the_default_bag_equals_a_full_recomputation``).

The caller then sets each row's offset to the support function of ``S`` (an exact
supporting halfspace whatever ``a`` is). Every tolerance in (3) only admits extra (redundant
but valid) rows: a facet's check values are exactly >= 0, so it is kept as long as the slack
exceeds the rounding error. This is why
(3) may run in float32 (about 2/3 of the work, 4 stance legs): its slack ``cone_tol`` (1e-5
of the bound on the values) is 8x its worst rounding; the survivors' normals are recomputed
in float64, as are the caller's offsets. Legs with ``d_k = 0`` need no enumeration (their
vertex is the argmax of the support function).

Degenerate facets. The faces a facet takes from the legs may have dimensions adding up to more
than ``r - 1``, when the lifted direction spaces of two legs meet. A force along the line
through feet ``i`` and ``j`` is the same wrench from either foot, so ``L_i Q_i + L_j Q_j`` is
5-dimensional, and with a vertex of each other leg it is a facet (normal
``+-(p_i x d, d)``, ``d = p_j - p_i``) on every stance of three or more legs. Level feet on a
rectangle add many more: 497 of 1347 facets, on average over 300 consecutive four-leg joint
states of the default bag (``examples/experiments/fws_facet_changes.py``).
(2) finds such a facet through its independent sub-choices, whose check values (3) vanish
exactly: the slack keeps them, and the caller's deduplication merges their rows, all but
copies whose rounding differs (3224 rows for those 1347 facets, 638 of them supporting
halfspaces of smaller faces). A facet tracker that assumes simple facets fails on them (README,
"Speed: awp_bench").

Organisation and cost. Choices are grouped by *pattern* (the dimensions ``d_k`` in decreasing
order; reordering legs only flips the sign of ``a``, and both signs are tested), and all leg
assignments of a pattern run as one batch. Parallel edges (and opposite facets) of a leg form
one class: one normal, the union of their cones. Rank-deficient choices (a vanishing partial
wedge) are dropped (``normal_tol``): by the exchange argument of (2) each facet also has an
independent choice. For HyQ-like legs (11-13 vertices, about 14 edge classes, 7 facet
classes) and 4 legs this is about 9e4 choices (three quarters in the pattern (2, 1, 1, 1)),
4e3-1.2e4 survivors and 2-7e3 rows once deduplicated; the grid search in numpy took 3.09 ms
on one core, the slice search (5) 1.58 ms (``awp_bench -n 200 --kernels``, line ``FWS facet
search``, 2026-12-06, load 0.00-0.22; the whole H-rep is ``awp_bench``'s ``fws_ms``). Run
numpy's BLAS with
one thread (e.g. ``OPENBLAS_NUM_THREADS=1``): with two threads on two shared cores it is 2x
slower.
Large temporaries live in per-thread buffers reused across calls
(:func:`awp_ros.geometry.linalg.workspace`): fresh pages cost as much as the arithmetic.
"""

from __future__ import annotations

from collections.abc import Generator
from functools import lru_cache
from itertools import permutations
from math import comb, prod

import numpy as np

from awp_ros.geometry import certified_search, kernels
from awp_ros.geometry.exterior import hodge_normal, wedge_all, wedge_rows, wedge_table
from awp_ros.geometry.face_lattice import Faces
from awp_ros.geometry.linalg import workspace
from awp_ros.geometry.steps import run_steps

__all__ = ['FLOAT32_SLACK', 'facet_normal_steps', 'facet_normals', 'STEP_CHOICES']

#: Face choices searched between two yields of :func:`facet_normal_steps` (about 0.2 ms),
#: in whole leg tuples: four HyQ legs' (2, 1, 1, 1) tuples have ~18000 each (~0.4 ms).
STEP_CHOICES = 8000

# Bound on the float32 rounding of a check value (3), relative to ``bound``: each value is a
# float32 dot product of q <= 20 pairs of rounded float64 inputs (Y . O_j, or K . suffix with
# K the contraction of Y with a prefix row, |K| <= |Y| |prefix| for a decomposable prefix),
# so with u = 6e-8 the error is at most (q + 2) u |Y| |O_j| <= 1.32e-6 bound; the smallest
# slack accepted is about twice that.
FLOAT32_SLACK = 2.5e-6


def facet_normals(faces: list[Faces], M: np.ndarray, r: int, cone_tol: float,
                  normal_tol: float, *, feet: np.ndarray | None = None,
                  basis: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """Return :func:`facet_normal_steps`'s normals and count, the search in one piece."""
    return run_steps(facet_normal_steps(faces, M, r, cone_tol, normal_tol, feet=feet,
                                        basis=basis, step_choices=None))


def facet_normal_steps(faces: list[Faces], M: np.ndarray, r: int, cone_tol: float,
                       normal_tol: float, *, feet: np.ndarray | None = None,
                       basis: np.ndarray | None = None, step_choices: int | None = STEP_CHOICES
                       ) -> Generator[None, None, tuple[np.ndarray, int]]:
    """
    Return unit candidate normals (N, r) that pass the normal-cone tests, and the count.

    A stepped computation (:mod:`awp_ros.geometry.steps`): it yields after the legs'
    preparation and after each pattern, and within a sliced pattern after each run of leg
    tuples of about ``step_choices`` face choices (None: each pattern in one piece). The
    rows are the same whatever ``step_choices``.

    The face choices are grouped by *pattern*, the face dimensions sorted in decreasing order
    (reordering the legs only flips the sign of ``a``, and both signs are tested); all leg
    assignments of one pattern run as one batch, padded to the largest class count. With the
    compiled kernels, the feet ``feet`` (K, 3) [m] and the hull's basis ``basis`` (6, r) of
    ``M_k = basis^T L_k``, and ``r = 6``, the patterns (2, 1, 1, 1), (2, 2, 1), (3, 1, 1)
    and (3, 2) are searched on slices instead (5).
    """
    if r == 1:                                    # a segment: both directions of the line
        return np.array([[1.0], [-1.0]]), 2
    if _flat_pair(faces, r):                       # two solid legs: (6), one call
        yield
        return kernels.flat_pair_facet_normals(M, _padded_groups(faces, 1),
                                               _padded_groups(faces, 2), cone_tol, normal_tol)
    offered = tuple(tuple(range(1, min(len(F.groups), r - 1) + 1)) for F in faces)
    patterns = _patterns(offered, r - 1)
    sliced = kernels.ENABLED and r == 6 and feet is not None and basis is not None
    if sliced:
        numpy_dims = {d for dims, _ in patterns if tuple(dims) not in kernels.SLICE_PATTERNS
                      for d in dims}
        padded = {d: _padded_groups(faces, d) for d in (1, 2, 3)}
    else:
        numpy_dims = {d for dims, _ in patterns for d in dims}
    # Per leg and face dimension d: X (m, C(r, d)) wedges, Y (m, k, c, C(r, d + 1)) checks.
    lifted = []
    for F, Mk in zip(faces, M):
        per_dim = {}
        for d, group in enumerate(F.groups, start=1):
            if d > r - 1:
                break
            if d not in numpy_dims:
                continue
            dirs = group.dirs @ Mk.T               # (m, d, r)
            X = dirs[:, 0, :]
            for i in range(1, d):
                X = wedge_rows(X, dirs[:, i, :], r, i, 1)
            checks = group.checks @ Mk.T            # (m, k, c, r)
            m, k, c = checks.shape[:3]
            Y = wedge_rows(checks.reshape(m * k * c, r), np.repeat(X, k * c, axis=0), r, 1, d)
            # In the form that pairs with the other legs' wedge O (3), up to a sign.
            Y = Y @ wedge_table(r, r - 1 - d, d + 1)[:, :, 0].T
            per_dim[d] = (X, Y.reshape(m, k, c, Y.shape[-1]), group.mask)
        lifted.append(per_dim)
    # The largest singular value of any M_k (one batched 3x3 eigenproblem, not K SVDs),
    # for the patterns the numpy grid searches.
    scale = float(np.sqrt(np.linalg.eigvalsh(np.einsum('krd,kre->kde', M, M))[:, -1].max())) \
        if numpy_dims else 0.0
    stacked = {d: _stack([per_dim.get(d) for per_dim in lifted], r, d)
               for d in {d for per_dim in lifted for d in per_dim}}
    normals, count = [], 0
    for dims, legs in patterns:
        yield
        if sliced and tuple(dims) in kernels.SLICE_PATTERNS:
            context = None
            if tuple(dims) == certified_search.PATTERN:     # (7): by certificates
                found, context = certified_search.try_rows(
                    feet, basis, padded, legs, cone_tol, normal_tol, build=step_choices is None)
                if found is not None:
                    normals.append(np.vstack(found[:2]))
                    count += found[2]
                    continue
            plus, minus = [], []
            for j, run in enumerate(_runs(legs, dims, padded, step_choices)):
                if j:
                    yield
                p, m, n = kernels.slice_facet_normal_parts(feet, basis, padded, dims, run,
                                                           cone_tol, normal_tol)
                plus.append(p)
                minus.append(m)
                count += n
            normals.append(np.vstack(plus + minus))       # the order of one piece
            if context is not None:
                certified_search.after_kernel(context, build=step_choices is None)
            continue
        sets = [_select(stacked[d], column) for d, column in zip(dims, zip(*legs))]
        a, n = _pattern_normals(sets, dims, r, scale, cone_tol, normal_tol)
        normals.append(a)
        count += n
    if not normals:
        return np.zeros((0, r)), 0
    return np.vstack(normals), count


def _flat_pair(faces: list[Faces], r: int) -> bool:
    """Return whether the compiled flat-pair search (6) applies: two solid legs, r = 5."""
    return kernels.ENABLED and r == 5 and len(faces) == 2 and all(
        len(F.groups) == 3 for F in faces)


def _runs(legs: list[tuple], dims: tuple, padded: dict,
          step_choices: int | None) -> list[np.ndarray]:
    """
    Return the leg tuples of a sliced pattern in consecutive runs of about ``step_choices``.

    A tuple's choices are estimated as the product of its legs' class counts (a whole leg,
    dimension 3, counts 1); a run ends once its estimate reaches ``step_choices`` (None: one
    run).
    """
    if step_choices is None:
        return [np.array(legs)]
    counts = [[1] * len(padded[1][3]) if d == 3 else padded[d][3].tolist() for d in dims]
    runs, start, total = [], 0, 0
    for i, tup in enumerate(legs):
        total += prod(c[k] for c, k in zip(counts, tup))
        if total >= step_choices or i == len(legs) - 1:
            runs.append(np.array(legs[start:i + 1]))
            start, total = i + 1, 0
    return runs


def _padded_groups(faces: list[Faces], d: int) -> tuple[np.ndarray, ...]:
    """
    Return every leg's face classes of dimension ``d``, padded.

    ``(dirs (K, m, d, 3), checks (K, m, k, c, 3), mask (K, m, k), counts (K,))``, count 0
    for a leg without them.
    """
    groups = [F.groups[d - 1] if len(F.groups) >= d else None for F in faces]
    shapes = [g.checks.shape[:3] for g in groups if g is not None]
    m = max([1] + [sh[0] for sh in shapes])
    k = max([1] + [sh[1] for sh in shapes])
    c = max([0] + [sh[2] for sh in shapes])
    K = len(faces)
    dirs = np.zeros((K, m, d, 3))
    checks = np.zeros((K, m, k, c, 3))
    mask = np.zeros((K, m, k), dtype=bool)
    counts = np.zeros(K, dtype=np.int64)
    for i, g in enumerate(groups):
        if g is not None:
            mi, ki, ci = g.checks.shape[:3]
            dirs[i, :mi] = g.dirs
            checks[i, :mi, :ki, :ci] = g.checks
            mask[i, :mi, :ki] = g.mask
            counts[i] = mi
    return dirs, checks, mask, counts


@lru_cache(maxsize=64)
def _patterns(lifted: tuple[tuple[int, ...], ...],
              total: int) -> tuple[tuple[list[int], list[tuple]], ...]:
    """
    Return (dims, leg tuples): face dimensions in decreasing order adding up to ``total``.

    ``lifted[k]`` lists the face dimensions leg ``k`` offers. Legs are distinct, and
    increasing within a run of equal dimensions (each face choice once).
    """
    out = []
    available = sorted({d for per_dim in lifted for d in per_dim}, reverse=True)

    def partitions(rest: int, largest: int) -> list[list[int]]:
        if rest == 0:
            return [[]]
        return [[d] + tail for d in available if d <= min(rest, largest)
                for tail in partitions(rest - d, d)]

    for dims in partitions(total, total):
        if len(dims) > len(lifted):
            continue
        legs = [ks for ks in permutations(range(len(lifted)), len(dims))
                if all(d in lifted[k] for k, d in zip(ks, dims))
                and all(ks[i] < ks[i + 1] for i in range(len(dims) - 1)
                        if dims[i] == dims[i + 1])]
        if legs:
            out.append((dims, legs))
    return tuple(out)


def _stack(items: list[tuple | None], r: int, d: int) -> tuple[np.ndarray, ...]:
    """
    Stack the (X, Y, mask) of every leg into one batch, padding with empty classes.

    Returns ``(X, Y, mask, sizes)``, ``sizes`` (K, 3) the class, slot and check counts of
    each leg (0 for a leg without faces of dimension ``d``, None in ``items``).
    """
    sizes = np.array([(0, 0, 0) if item is None else item[1].shape[:3] for item in items])
    n, k, c = sizes.max(axis=0)
    B = len(items)
    Xb = np.zeros((B, n, comb(r, d)))
    Yb = np.zeros((B, n, k, c, comb(r, d + 1)))
    mb = np.zeros((B, n, k), dtype=bool)
    for b, item in enumerate(items):
        if item is not None:
            X, Y, mask = item
            Xb[b, :X.shape[0]] = X
            Yb[b, :Y.shape[0], :Y.shape[1], :Y.shape[2]] = Y
            mb[b, :mask.shape[0], :mask.shape[1]] = mask
    return Xb, Yb, mb, sizes


def _select(stacked: tuple[np.ndarray, ...], legs: tuple[int, ...]) -> tuple[np.ndarray, ...]:
    """Return the batch of some legs, padded only to their own largest counts."""
    Xb, Yb, mb, sizes = stacked
    legs = list(legs)
    n, k, c = sizes[legs].max(axis=0)
    return Xb[legs, :n], Yb[legs, :n, :k, :c], mb[legs, :n, :k]


def _pattern_normals(sets: list, dims: list[int], r: int, scale: float, cone_tol: float,
                     normal_tol: float) -> tuple[np.ndarray, int]:
    """
    Return the normals of every face choice of one pattern (a batch of leg tuples) passing (3).

    ``scale`` bounds the norm of every lifted unit vector, so ``bound = scale ** r`` bounds
    ``|a|`` times the norm of a lifted check vector (Hadamard) and ``cone_tol * bound`` is an
    absolute slack. Arrays carry a leading batch axis ``B``; the candidates of one batch entry
    form the grid ``(n_0, ..., n_{J-1})`` of class indices.
    """
    J = len(sets)
    bound = scale ** r
    Xs = [item[0] for item in sets]
    B = Xs[0].shape[0]
    ns = [X.shape[1] for X in Xs]
    N = int(np.prod(ns))
    # Prefix and suffix wedges; O_j = prefix_{<j} ^ suffix_{>j}.
    pre, suf = [np.ones((B, 1, 1))], [np.ones((B, 1, 1))]
    deg_pre, deg_suf = [0], [0]
    for j in range(J - 1):
        pre.append(_wedge_into(f'fws_pre{j}', pre[-1], Xs[j], r, deg_pre[-1], dims[j]))
        deg_pre.append(deg_pre[-1] + dims[j])
    for j in range(J - 1, 0, -1):
        suf.append(_wedge_into(f'fws_suf{j}', Xs[j], suf[-1], r, dims[j], deg_suf[-1]))
        deg_suf.append(deg_suf[-1] + dims[j])
    suf.reverse()
    deg_suf.reverse()
    # Running min and max over all check values (3), in the grid layout (B, n_0, ..., n_J-1),
    # in float32 (a filter whose slack exceeds its rounding; the survivors' normals are
    # recomputed in float64). Buffers are reused across calls (no page faults).
    lo = workspace('fws_lo', (B,) + tuple(ns), np.float32)
    hi = workspace('fws_hi', (B,) + tuple(ns), np.float32)
    lo.fill(0.0)
    hi.fill(0.0)
    for j in range(J):
        _, Y, mask = sets[j]                        # Y (B, n_j, k, c, C(r, d_j + 1))
        k, c = Y.shape[2:4]
        if c == 0:
            continue
        sign = (-1.0) ** (deg_pre[j] + (dims[j] + 1) * deg_suf[j])   # Y pairs with O up to it
        # The value Y . O_j with O_j = prefix ^ suffix, O_s = sum_{u,t} pre_u suf_t W_uts, is
        # sum_t K_t suf_t with K_t = sum_{u,s} Y_s pre_u W_uts. With fewer prefix rows than
        # suffix rows, Y is contracted with each prefix row, then one float32 product pairs
        # it with every suffix row (O_j, N / n_j rows, is never formed); else O_j is formed
        # (the prefix then holds most rows: O_j is a copy of it when j is the last leg).
        n_pre, n_suf = pre[j].shape[1], suf[j].shape[1]
        rows = n_pre * n_suf
        contract = n_pre < n_suf
        if contract:
            W = wedge_table(r, deg_pre[j], deg_suf[j])
            cq = W.shape[1]
            PT = (pre[j] @ W.reshape(W.shape[0], -1)).reshape(B, n_pre * cq, W.shape[2])
            PT = np.swapaxes(PT, 1, 2)                # (B, C(r, 5 - d_j), n_pre cq)
            right = workspace('fws_right', (B, cq, n_suf), np.float32)
            right[...] = np.swapaxes(suf[j], 1, 2)
        else:
            other = _wedge_into('fws_o', pre[j], suf[j], r, deg_pre[j], deg_suf[j])
            right = workspace('fws_right', (B, other.shape[2], rows), np.float32)
            right[...] = np.swapaxes(other, 1, 2)
            n_pre, n_suf = 1, rows                  # the pairing below, with K = Y
        # Slot i (the i-th parallel face of a class) exists for a prefix of the classes
        # (classes come sorted by size), so slot i > 0 only runs over that prefix.
        vmin = vmax = None
        for i in range(k):
            m = ns[j] if i == 0 else int(mask[:, :, i].sum(axis=1).max())
            if m == 0:
                break
            Yi = Y[:, :m, i].transpose(0, 2, 1, 3).reshape(B, c * m, -1)
            K = workspace(f'fws_k{min(i, 1)}', (B, c * m * n_pre, right.shape[1]), np.float32)
            K.reshape(B, c * m, -1)[...] = sign * (Yi @ PT if contract else Yi)
            out = workspace(f'fws_vals{min(i, 1)}', (B, c * m * n_pre, n_suf), np.float32)
            vals = np.matmul(K, right, out=out).reshape(B, c, m, rows)  # [b, check, class, row]
            fmin = vals[:, 0]
            fmax = workspace(f'fws_fmax{min(i, 1)}', (B, m, rows), np.float32)
            fmax[...] = fmin
            for ci in range(1, c):
                np.minimum(fmin, vals[:, ci], out=fmin)
                np.maximum(fmax, vals[:, ci], out=fmax)
            # A class passes when one of its faces does (union of their normal cones);
            # empty slots (padding) get -inf / +inf, so an empty class fails both signs.
            empty = ~mask[:, :m, i]
            fmin[empty] = -np.inf
            fmax[empty] = np.inf
            if vmin is None:
                vmin, vmax = fmin, fmax
            else:
                np.maximum(vmin[:, :m], fmin, out=vmin[:, :m])
                np.minimum(vmax[:, :m], fmax, out=vmax[:, :m])
        shape = [B, ns[j]] + ns[:j] + ns[j + 1:]
        np.minimum(lo, np.moveaxis(vmin.reshape(shape), 1, j + 1), out=lo)
        np.maximum(hi, np.moveaxis(vmax.reshape(shape), 1, j + 1), out=hi)
    # Rank-deficient choices (a vanishing partial wedge) fail both signs.
    small = (normal_tol * bound) ** 2
    dead_last = np.einsum('bnp,bnp->bn', pre[J - 1], pre[J - 1]) <= small   # (B, N / n_-1)
    dead_first = np.einsum('bnp,bnp->bn', suf[0], suf[0]) <= small          # (B, N / n_0)
    for grid, fill in ((lo, -np.inf), (hi, np.inf)):
        grid.reshape(B, -1, ns[-1])[dead_last] = fill
        grid.reshape(B, ns[0], -1).transpose(0, 2, 1)[dead_first] = fill
    tol = cone_tol * bound
    pos, neg = np.flatnonzero(lo >= -tol), np.flatnonzero(hi <= tol)
    # Normals of the survivors only: W = prefix_{<J-1} ^ X_{J-1}, a_i = (-1)^i W_{[r] - i}.
    idx = np.concatenate([pos, neg])
    b, rest = idx // N, idx % N
    if kernels.ENABLED:             # compiled, one call (the numpy code below is its reference)
        return kernels.survivor_normals(pre[J - 1], Xs[-1], b, rest // ns[-1], rest % ns[-1],
                                        deg_pre[J - 1], dims[-1], pos.size,
                                        normal_tol * bound), B * N
    W = wedge_rows(pre[J - 1][b, rest // ns[-1]], Xs[-1][b, rest % ns[-1]], r,
                   deg_pre[J - 1], dims[-1])
    a = hodge_normal(W)
    a[pos.size:] *= -1.0
    norm = np.linalg.norm(a, axis=1)
    keep = norm > normal_tol * bound
    return a[keep] / norm[keep, None], B * N


def _wedge_into(name: str, X: np.ndarray, Y: np.ndarray, r: int, p: int,
                q: int) -> np.ndarray:
    """Return :func:`~awp_ros.geometry.exterior.wedge_all` written to workspace buffer ``name``."""
    out = workspace(name, (X.shape[0], X.shape[1], Y.shape[1] * comb(r, p + q)))
    return wedge_all(X, Y, r, p, q, out=out)
