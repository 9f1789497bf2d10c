"""
Time the parts of the FWS's (2, 1, 1, 1) slice search, and four variants that were slower.

::

    PYTHONPATH=. .venv/bin/python examples/experiments/slice_search_variants.py [--postures 200]

The measurement behind the README's "Speed: awp_bench" paragraph on the facet search. It records
the arguments of every (2, 1, 1, 1) call of
:func:`awp_ros.geometry.kernels.slice_facet_normal_parts` while the FWS of ``--postures`` random
HyQ postures (seed 0, joints +-0.1 rad around standing, as ``awp_bench``) is computed, then
times, alternated in three passes over the same calls, variants of
:func:`awp_ros.geometry.kernels._slice_search` compiled from its own source with a few lines
replaced (each replaced text must be found exactly once, else the script stops):

- ``copy``: the kernel unchanged (the baseline of the same compilation);
- ``no survivors``, ``no slot bounds``, ``no forms``: the time split of one node (leg A's facet
  class, an edge class of B and one of C): without the candidates that pass the node legs'
  slot bounds (their normal and legs A and D's checks), without those slot bounds, without the
  node legs' check forms ``G = -*(P ^ s)`` either;
- ``node pruned``: a node is skipped when legs A, B and C's checks, restricted to the node's
  plane of normals, leave no direction (tested at every boundary ray of a check);
- ``float32 prefilter``: all four legs' checks at every candidate in float32 vector loops
  (slack ``cone_tol + 1e-6`` of each value's bound, above float32 rounding), then the float64
  tests of the kernel on the candidates that pass;
- ``batched survivors``: the candidates that pass the node legs are kept, and processed in one
  batch per facet class of A (their normals, then legs A and D's checks, in loops over the
  batch) instead of one at a time.
- ``lanes``: every candidate of a node at once: their normals ``x_d = *(P ^ r3_d)`` in one
  loop over the candidates, then each check of the four legs in one loop over them (the node
  legs' at the slack bound ``|s| |P| |r3|``, legs A and D's at ``|x|``, the candidate leg's
  checks stored per candidate), no node-leg forms and no candidate-by-candidate tests.

It prints the mean rows and choices per call, whether each variant's rows equal the kernel's
(bit for bit, or how many differ), the nodes the pruning keeps, and each variant's mean time per
call [ms].
"""

from __future__ import annotations

import argparse
import inspect
import textwrap
import time

import numba
import numpy as np

from awp_ros.geometry import kernels as K

#: The kernel's lines a variant replaces: (old, new) pairs.
_NO_SURVIVORS = [(
    '                        if not (pos or neg):\n                            continue\n'
    '                        for i in range(4):\n                            r3[i] = R[i, d]\n',
    '                        if True:\n                            continue\n'
    '                        for i in range(4):\n                            r3[i] = R[i, d]\n')]
_NO_SLOT_BOUNDS = [
    ('_slot_bounds(GB, gB, kB, cB, R, Rn, nR, f1, h1, mn, mx)',
     'f1[:nR] = -1.0; h1[:nR] = 1.0'),
    ('_slot_bounds(GC, gC, kC, cC, R, Rn, nR, f2, h2, mn, mx)',
     'f2[:nR] = -1.0; h2[:nR] = 1.0')]
_NO_FORMS = _NO_SLOT_BOUNDS + [
    ('_cross4(P, SB[b, s, j], GB[s, j])', 'pass'),
    ('_cross4(P, SC[c, s, j], GC[s, j])', 'pass')]
_ARRAYS = '    mn, mx = np.empty(mP), np.empty(mP)\n'
_CANDIDATES = "                    # The candidates: the node legs' checks first"
_PRUNED = [
    (_ARRAYS, _ARRAYS + textwrap.indent(textwrap.dedent("""\
        GA, gA = np.empty((kA, cA, 4)), np.empty((kA, cA))
        e1, e2, unit = np.empty(4), np.empty(4), np.empty(4)
        nmax = kA * cA + kB * cB + kC * cC
        fu, fv, fs = np.empty(nmax), np.empty(nmax), np.empty(nmax)
        fslot = np.empty(nmax, dtype=np.int64)
        slot_leg = np.empty(kA + kB + kC, dtype=np.int64)
        slot_ok = np.empty(kA + kB + kC, dtype=np.bool_)
        nodes = 0
        kept_nodes = 0
        """), '    ')),
    (_CANDIDATES, textwrap.indent(textwrap.dedent("""\
        for s in range(kA):
            for j in range(cA):
                _cross4(P, SA[s, j], GA[s, j])
                for i in range(4):
                    GA[s, j, i] = -GA[s, j, i]
                gA[s, j] = tA[s, j] * nP
        nodes += 1
        if not _node_feasible(P, GA, gA, kA, cA, GB, gB, kB, cB, GC, gC, kC, cC, pair, e1, e2,
                              unit, fu, fv, fs, fslot, slot_leg, slot_ok):
            continue
        kept_nodes += 1
        """), ' ' * 20) + _CANDIDATES),
    ('    return npos, nneg, choices\n',
     '    return npos, nneg, choices * 0 + nodes * 100000 + kept_nodes\n')]
_PREFILTER = [
    (_ARRAYS, _ARRAYS + textwrap.indent(textwrap.dedent("""\
        rho = 1.0 + 1e-6 / cone_tol
        f32 = np.float32
        P32 = np.empty(6, dtype=f32)
        R32, Rn32 = np.zeros((4, mP), dtype=f32), np.zeros(mP, dtype=f32)
        QD = np.zeros((kD, cD, 6, mP), dtype=f32)
        TD = np.full((kD, cD, mP), -np.inf, dtype=f32)
        GA, gA = np.empty((kA, cA, 4)), np.empty((kA, cA))
        GA32, gA32 = np.empty((kA, cA, 4), dtype=f32), np.empty((kA, cA), dtype=f32)
        GB32, gB32 = np.empty((kB, cB, 4), dtype=f32), np.empty((kB, cB), dtype=f32)
        GC32, gC32 = np.empty((kC, cC, 4), dtype=f32), np.empty((kC, cC), dtype=f32)
        fA, hA, fB, hB = (np.empty(mP, dtype=f32), np.empty(mP, dtype=f32),
                          np.empty(mP, dtype=f32), np.empty(mP, dtype=f32))
        fC, hC, fD, hD = (np.empty(mP, dtype=f32), np.empty(mP, dtype=f32),
                          np.empty(mP, dtype=f32), np.empty(mP, dtype=f32))
        mn32, mx32 = np.empty(mP, dtype=f32), np.empty(mP, dtype=f32)
        """), '    ')),
    ('                _slice_checks(n, dD, Dc[D, e], Dm[D, e], cone_tol, SD[e], tD[e])\n',
     '                _slice_checks(n, dD, Dc[D, e], Dm[D, e], cone_tol, SD[e], tD[e])\n'
     + textwrap.indent(textwrap.dedent("""\
        for i in range(4):
            R32[i, e] = r3[i]
        Rn32[e] = Rn[e]
        for s in range(kD):
            for j in range(cD):
                _wedge_form(r3, SD[e, s, j], QD[s, j], e)
                TD[s, j, e] = tD[e, s, j] * rho * Rn[e]
        """), ' ' * 16)),
    ('                    _slot_bounds(GB, gB, kB, cB, R, Rn, nR, f1, h1, mn, mx)\n'
     '                    if not pair:\n'
     '                        _slot_bounds(GC, gC, kC, cC, R, Rn, nR, f2, h2, mn, mx)\n'
     '                    for d in range(nD[D]):\n'
     '                        pos = f1[d] >= 0.0\n'
     '                        neg = h1[d] <= 0.0\n'
     '                        if not pair:\n'
     '                            pos = pos and f2[d] >= 0.0\n'
     '                            neg = neg and h2[d] <= 0.0\n',
     textwrap.indent(textwrap.dedent("""\
        for i in range(6):
            P32[i] = P[i]
        _node_forms32(P, nP, SA, tA, kA, cA, rho, GA, gA, GA32, gA32)
        _node_forms32(P, nP, SB[b], tB[b], kB, cB, rho, GB, gB, GB32, gB32)
        _slot_bounds(GA32, gA32, kA, cA, R32, Rn32, nR, fA, hA, mn32, mx32)
        _slot_bounds(GB32, gB32, kB, cB, R32, Rn32, nR, fB, hB, mn32, mx32)
        if not pair:
            _node_forms32(P, nP, SC[c], tC[c], kC, cC, rho, GC, gC, GC32, gC32)
            _slot_bounds(GC32, gC32, kC, cC, R32, Rn32, nR, fC, hC, mn32, mx32)
        else:
            for d in range(nR):
                fC[d] = f32(np.inf)
                hC[d] = f32(-np.inf)
        _wedge_bounds(P32, QD, TD, kD, cD, nR, fD, hD, mn32, mx32)
        nP32 = f32(nP)
        for d in range(nR):
            lo = min(min(fA[d], fB[d]), min(fC[d], fD[d] * nP32))
            hi = max(max(hA[d], hB[d]), max(hC[d], hD[d] * nP32))
            mn32[d] = lo if lo > -hi else -hi
        for d in range(nD[D]):
            if not mn32[d] >= 0.0:
                continue
            f1d, h1d = _leg_bounds_at(GB, gB, kB, cB, R, Rn, d)
            pos = f1d >= 0.0
            neg = h1d <= 0.0
            if not pair:
                f2d, h2d = _leg_bounds_at(GC, gC, kC, cC, R, Rn, d)
                pos = pos and f2d >= 0.0
                neg = neg and h2d <= 0.0
        """), ' ' * 20))]


_BATCHED = [
    (_ARRAYS, _ARRAYS + """    cap = Bd.shape[1] * max(Cd.shape[1], 1) * max(mD, 1)
    BP, Bn = np.empty((6, cap)), np.empty(cap)
    Bi = np.empty(cap, dtype=np.int64)
    Bpos, Bneg = np.empty(cap, dtype=np.bool_), np.empty(cap, dtype=np.bool_)
    X, NX = np.empty((4, cap)), np.empty(cap)
    FA, HA, FD, HD = np.empty(cap), np.empty(cap), np.empty(cap), np.empty(cap)
    bmn, bmx = np.empty(cap), np.empty(cap)
"""),
    ('            _slice_checks(n, zero, Ac[A, fa], Am[A, fa], cone_tol, SA, tA)\n',
     '            _slice_checks(n, zero, Ac[A, fa], Am[A, fa], cone_tol, SA, tA)\n'
     '            ns = 0\n'),
    (('                        for i in range(4):\n                            r3[i] = R[i, d]\n',
      '    return npos, nneg, choices\n'),
     """                        for i in range(6):
                            BP[i, ns] = P[i]
                        Bn[ns] = nP
                        Bi[ns] = d
                        Bpos[ns] = pos
                        Bneg[ns] = neg
                        ns += 1
            # The candidates that pass the node legs, in one batch per facet class of A: their
            # normals x, then leg A's and the candidate leg's checks at x.
            for s in range(ns):
                d = Bi[s]
                c0, c1, c2, c3 = R[0, d], R[1, d], R[2, d], R[3, d]
                p0, p1, p2, p3, p4, p5 = BP[0, s], BP[1, s], BP[2, s], BP[3, s], BP[4, s], BP[5, s]
                d123 = c1 * p5 - c2 * p4 + c3 * p3
                d023 = c0 * p5 - c2 * p2 + c3 * p1
                d013 = c0 * p4 - c1 * p2 + c3 * p0
                d012 = c0 * p3 - c1 * p1 + c2 * p0
                X[0, s] = -d123
                X[1, s] = d023
                X[2, s] = -d013
                X[3, s] = d012
                NX[s] = np.sqrt(d123 * d123 + d023 * d023 + d013 * d013 + d012 * d012)
            _slot_bounds(SA, tA, kA, cA, X, NX, ns, FA, HA, bmn, bmx)
            _slot_bounds_of(SD, tD, Bi, kD, cD, X, NX, ns, FD, HD, bmn, bmx)
            for s in range(ns):
                if not NX[s] > normal_tol * Bn[s] * Rn[Bi[s]]:       # rank-deficient choice
                    continue
                pos = Bpos[s] and FA[s] >= 0.0 and FD[s] >= 0.0
                neg = Bneg[s] and HA[s] <= 0.0 and HD[s] <= 0.0
                if not (pos or neg):
                    continue
                for i in range(4):
                    x[i] = X[i, s]
                if pos:
                    if npos == out_pos.shape[0]:
                        return -1, -1, choices
                    _slice_normal(x, n, pA, U, out_pos, npos, a)
                    npos += 1
                if neg:
                    if nneg == out_neg.shape[0]:
                        return -1, -1, choices
                    for i in range(4):
                        x[i] = -x[i]
                    _slice_normal(x, n, pA, U, out_neg, nneg, a)
                    nneg += 1
    return npos, nneg, choices
""")]


_LANES = [
    (_ARRAYS, _ARRAYS + textwrap.indent(textwrap.dedent("""\
        X, NX, NB = np.zeros((4, mP)), np.zeros(mP), np.zeros(mP)
        ST, tT = np.zeros((kD, cD, 4, mP)), np.zeros((kD, cD, mP))
        F, H, fl, hl = np.empty(mP), np.empty(mP), np.empty(mP), np.empty(mP)
        """), '    ')),
    ('                _slice_checks(n, dD, Dc[D, e], Dm[D, e], cone_tol, SD[e], tD[e])\n',
     '                _slice_checks(n, dD, Dc[D, e], Dm[D, e], cone_tol, SD[e], tD[e])\n'
     + textwrap.indent(textwrap.dedent("""\
        for s in range(kD):
            for j in range(cD):
                for i in range(4):
                    ST[s, j, i, e] = SD[e, s, j, i]
                tT[s, j, e] = tD[e, s, j]
        """), ' ' * 16)),
    (('                    # A check S of a node leg at x(r3)',
      '                        pd, nd = _slot_signs(SD[d], tD[d], kD, cD, x, nx)\n'),
     textwrap.indent(textwrap.dedent("""\
        nR = (nD[D] + 3) // 4 * 4
        for d in range(nR):
            d123 = R[1, d] * P[5] - R[2, d] * P[4] + R[3, d] * P[3]
            d023 = R[0, d] * P[5] - R[2, d] * P[2] + R[3, d] * P[1]
            d013 = R[0, d] * P[4] - R[1, d] * P[2] + R[3, d] * P[0]
            d012 = R[0, d] * P[3] - R[1, d] * P[1] + R[2, d] * P[0]
            X[0, d], X[1, d], X[2, d], X[3, d] = -d123, d023, -d013, d012
            NX[d] = np.sqrt(d123 * d123 + d023 * d023 + d013 * d013 + d012 * d012)
            NB[d] = nP * Rn[d]
        _lane_leg(SB[b], tB[b], kB, cB, X, NB, nR, F, H, mn, mx, fl, hl, True)
        if not pair:
            _lane_leg(SC[c], tC[c], kC, cC, X, NB, nR, F, H, mn, mx, fl, hl, False)
        _lane_leg(SA, tA, kA, cA, X, NX, nR, F, H, mn, mx, fl, hl, False)
        _lane_candidates(ST, tT, kD, cD, X, NX, nR, F, H, mn, mx, fl, hl)
        for d in range(nD[D]):
            pos = F[d] >= 0.0
            neg = H[d] <= 0.0
            if not (pos or neg) or not NX[d] > normal_tol * NB[d]:
                continue
            for i in range(4):
                x[i] = X[i, d]
            pd = nd = True              # every leg's test is in F and H: the kernel's output
        """), ' ' * 20))]


@numba.njit(inline='always')
def _node_checks(G, g, k, c, e1, e2, leg, sid, fu, fv, fs, fslot, nf, slot_leg):
    """Append a leg's checks of its present slots in the node plane's basis (e1, e2)."""
    for s in range(k):
        if not g[s, 0] > -np.inf:
            continue
        slot_leg[sid] = leg
        for j in range(c):
            fu[nf] = G[s, j, 0] * e1[0] + G[s, j, 1] * e1[1] + G[s, j, 2] * e1[2] \
                + G[s, j, 3] * e1[3]
            fv[nf] = G[s, j, 0] * e2[0] + G[s, j, 1] * e2[1] + G[s, j, 2] * e2[2] \
                + G[s, j, 3] * e2[3]
            fs[nf] = g[s, j]
            fslot[nf] = sid
            nf += 1
        sid += 1
    return nf, sid


@numba.njit(inline='always')
def _node_feasible(P, GA, gA, kA, cA, GB, gB, kB, cB, GC, gC, kC, cC, pair, e1, e2, unit,
                   fu, fv, fs, fslot, slot_leg, slot_ok):
    """
    Whether some direction of the node plane passes legs A, B (and C).

    The plane ``{x : r1 . x = r2 . x = 0}`` gets an orthonormal basis (the longest
    ``*(P ^ e_i)``, then ``*(P ^ e1)``); a check ``s . x(y) = G . y`` is then a 2D form, and a
    nonempty intersection of the legs' slot cones contains a boundary ray of one of them.
    """
    best = -1.0
    for i in range(4):
        unit[:] = 0.0
        unit[i] = 1.0
        K._cross4(P, unit, e2)
        nn = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2] + e2[3] * e2[3]
        if nn > best:
            best = nn
            e1[:] = e2
    e1 /= np.sqrt(best)
    K._cross4(P, e1, e2)
    e2 /= K._norm4(e2)
    nf, ns = _node_checks(GA, gA, kA, cA, e1, e2, 0, 0, fu, fv, fs, fslot, 0, slot_leg)
    nf, ns = _node_checks(GB, gB, kB, cB, e1, e2, 1, ns, fu, fv, fs, fslot, nf, slot_leg)
    legs = 2
    if not pair:
        nf, ns = _node_checks(GC, gC, kC, cC, e1, e2, 2, ns, fu, fv, fs, fslot, nf, slot_leg)
        legs = 3
    any_check = False
    for i in range(nf):
        gu, gv = fu[i], fv[i]
        g2 = gu * gu + gv * gv
        if not g2 > fs[i] * fs[i]:
            continue
        any_check = True
        ng = np.sqrt(g2)
        for sign in range(2):
            y0 = -gv if sign == 0 else gv
            y1 = gu if sign == 0 else -gu
            slot_ok[:ns] = True
            for j in range(nf):
                if fu[j] * y0 + fv[j] * y1 + fs[j] * ng < 0.0:
                    slot_ok[fslot[j]] = False
            passed = 0
            for s in range(ns):
                if slot_ok[s]:
                    passed |= 1 << slot_leg[s]
            if passed == (1 << legs) - 1:
                return True
    return not any_check


@numba.njit(inline='always')
def _wedge_form(r, s, Q, d):
    """Write Q[:, d] with ``P . Q[:, d] = det[r1; r2; r; s]`` for ``P = r1 ^ r2``."""
    Q[0, d] = r[2] * s[3] - r[3] * s[2]
    Q[1, d] = r[3] * s[1] - r[1] * s[3]
    Q[2, d] = r[1] * s[2] - r[2] * s[1]
    Q[3, d] = r[0] * s[3] - r[3] * s[0]
    Q[4, d] = r[2] * s[0] - r[0] * s[2]
    Q[5, d] = r[0] * s[1] - r[1] * s[0]


@numba.njit(inline='always', fastmath=K._FASTMATH)
def _wedge_bounds(P, Q, t, k, c, nR, f, h, mn, mx):
    """
    Write the candidate leg's slot bounds (as :func:`kernels._slot_bounds` writes them).

    Its check (s, j) at candidate d is ``P . Q[s, j, :, d]``, its slack ``t[s, j, d]``.
    """
    for s in range(k):
        for j in range(c):
            Qs, T = Q[s, j], t[s, j]
            for d in range(nR):
                v = P[0] * Qs[0, d] + P[1] * Qs[1, d] + P[2] * Qs[2, d] + P[3] * Qs[3, d] \
                    + P[4] * Qs[4, d] + P[5] * Qs[5, d]
                lo, hi = v + T[d], v - T[d]
                first = j == 0
                mn[d] = lo if first or lo < mn[d] else mn[d]
                mx[d] = hi if first or hi > mx[d] else mx[d]
        for d in range(nR):
            first = s == 0
            f[d] = mn[d] if first or mn[d] > f[d] else f[d]
            h[d] = mx[d] if first or mx[d] < h[d] else h[d]


@numba.njit(inline='always', fastmath=K._FASTMATH)
def _node_forms32(P, nP, S, t, k, c, rho, G, g, G32, g32):
    """Write a node leg's forms ``G = -*(P ^ s)``, slack ``t |P|``, and float32 copies."""
    for s in range(k):
        for j in range(c):
            K._cross4(P, S[s, j], G[s, j])
            for i in range(4):
                G[s, j, i] = -G[s, j, i]
                G32[s, j, i] = G[s, j, i]
            g[s, j] = t[s, j] * nP
            g32[s, j] = g[s, j] * rho


@numba.njit(inline='always', fastmath=K._FASTMATH)
def _leg_bounds_at(G, g, k, c, R, Rn, d):
    """(f, h) of one leg at candidate d, in float64, as :func:`kernels._slot_bounds`."""
    f, h = -np.inf, np.inf
    for s in range(k):
        mn, mx = np.inf, -np.inf
        for j in range(c):
            v = G[s, j, 0] * R[0, d] + G[s, j, 1] * R[1, d] + G[s, j, 2] * R[2, d] \
                + G[s, j, 3] * R[3, d]
            w = g[s, j] * Rn[d]
            mn, mx = min(mn, v + w), max(mx, v - w)
        f, h = max(f, mn), min(h, mx)
    return f, h


@numba.njit(inline='always', fastmath=K._FASTMATH)
def _slot_bounds_of(S, t, idx, k, c, X, NX, n, f, h, mn, mx):
    """Write :func:`kernels._slot_bounds` of items ``i`` with their own checks ``S[idx[i]]``."""
    for s in range(k):
        for j in range(c):
            for i in range(n):
                e = idx[i]
                v = S[e, s, j, 0] * X[0, i] + S[e, s, j, 1] * X[1, i] \
                    + S[e, s, j, 2] * X[2, i] + S[e, s, j, 3] * X[3, i]
                w = t[e, s, j] * NX[i]
                lo = v + w
                hi = v - w
                if j == 0:
                    mn[i] = lo
                    mx[i] = hi
                else:
                    mn[i] = lo if lo < mn[i] else mn[i]
                    mx[i] = hi if hi > mx[i] else mx[i]
        if c == 0:
            for i in range(n):
                mn[i] = np.inf
                mx[i] = -np.inf
        if s == 0:
            for i in range(n):
                f[i] = mn[i]
                h[i] = mx[i]
        else:
            for i in range(n):
                f[i] = mn[i] if mn[i] > f[i] else f[i]
                h[i] = mx[i] if mx[i] < h[i] else h[i]


@numba.njit(inline='always', fastmath=K._FASTMATH)
def _lane_fold(mn, mx, n, F, H, first):
    """Fold one slot's values into a leg's ``F`` (max over slots) and ``H`` (min), per lane."""
    for d in range(n):
        F[d] = mn[d] if first or mn[d] > F[d] else F[d]
        H[d] = mx[d] if first or mx[d] < H[d] else H[d]


@numba.njit(inline='always', fastmath=K._FASTMATH)
def _lane_leg(S, t, k, c, X, scale, n, F, H, mn, mx, fl, hl, first_leg):
    """
    Fold one leg's slot tests at every lane's ``x = X[:, d]`` into ``F`` (min) and ``H`` (max).

    The leg's check (s, j) is the same at every lane: ``S[s, j] . x`` within ``t[s, j]
    scale[d]``; missing slots (``t = -inf``) are skipped, a leg without a slot fails both signs.
    """
    seen = False
    for s in range(k):
        if c > 0 and not t[s, 0] > -np.inf:
            continue
        for j in range(c):
            g0, g1, g2, g3, tj = S[s, j, 0], S[s, j, 1], S[s, j, 2], S[s, j, 3], t[s, j]
            for d in range(n):
                v = g0 * X[0, d] + g1 * X[1, d] + g2 * X[2, d] + g3 * X[3, d]
                w = tj * scale[d]
                mn[d] = v + w if j == 0 or v + w < mn[d] else mn[d]
                mx[d] = v - w if j == 0 or v - w > mx[d] else mx[d]
        if c == 0:
            mn[:n] = np.inf
            mx[:n] = -np.inf
        _lane_fold(mn, mx, n, fl, hl, not seen)
        seen = True
    if not seen:
        fl[:n] = -np.inf
        hl[:n] = np.inf
    for d in range(n):
        F[d] = fl[d] if first_leg or fl[d] < F[d] else F[d]
        H[d] = hl[d] if first_leg or hl[d] > H[d] else H[d]


@numba.njit(inline='always', fastmath=K._FASTMATH)
def _lane_candidates(ST, tT, k, c, X, NX, n, F, H, mn, mx, fl, hl):
    """:func:`_lane_leg` for the candidate leg, its checks ``ST[s, j, :, d]`` per lane."""
    for s in range(k):
        for j in range(c):
            S, t = ST[s, j], tT[s, j]
            for d in range(n):
                v = S[0, d] * X[0, d] + S[1, d] * X[1, d] + S[2, d] * X[2, d] + S[3, d] * X[3, d]
                w = t[d] * NX[d]
                mn[d] = v + w if j == 0 or v + w < mn[d] else mn[d]
                mx[d] = v - w if j == 0 or v - w > mx[d] else mx[d]
        if c == 0:
            mn[:n] = np.inf
            mx[:n] = -np.inf
        _lane_fold(mn, mx, n, fl, hl, s == 0)
    if k == 0:
        fl[:n] = -np.inf
        hl[:n] = np.inf
    for d in range(n):
        F[d] = fl[d] if fl[d] < F[d] else F[d]
        H[d] = hl[d] if hl[d] > H[d] else H[d]


def variant(replacements: list[tuple]):
    """
    Compile ``_slice_search`` with ``replacements`` applied to its source (each found once).

    Each is ``(old, new)``; ``old`` may be ``(first, last)``: from the first occurrence of
    ``first`` through the next of ``last``.
    """
    source = inspect.getsource(K._slice_search.py_func).replace('@_jit(fastmath=True)\n', '')
    for old, new in replacements:
        if isinstance(old, tuple):          # (first line, last line): the text between
            start = source.find(old[0])
            old = source[start:source.index(old[1], start) + len(old[1])]
        if source.count(old) != 1:
            raise SystemExit(f'the kernel changed: {old[:60]!r} found {source.count(old)} times')
        source = source.replace(old, new)
    namespace = dict(vars(K))
    namespace.update(_node_feasible=_node_feasible, _wedge_form=_wedge_form,
                     _wedge_bounds=_wedge_bounds, _node_forms32=_node_forms32,
                     _leg_bounds_at=_leg_bounds_at, _slot_bounds_of=_slot_bounds_of,
                     _lane_leg=_lane_leg, _lane_candidates=_lane_candidates)
    exec(textwrap.dedent(source), namespace)
    return numba.njit(fastmath=K._FASTMATH)(namespace['_slice_search'])


def record_calls(postures: int) -> list[tuple]:
    """Return the arguments of the (2, 1, 1, 1) searches of the FWS of random HyQ postures."""
    from awp_ros.evaluation.evaluator import compute_fws, FeasibilityEvaluator
    ev = FeasibilityEvaluator('hyq')
    names = list(ev.standing_state().joint_positions)
    q0 = np.array([ev.standing_state().joint_positions[n] for n in names])
    rng = np.random.default_rng(0)
    calls, original = [], K.slice_facet_normal_parts

    def spy(positions, U, groups, dims, legs, cone_tol, normal_tol):
        if tuple(dims) == (2, 1, 1, 1):
            A, E = groups[2], groups[1]
            An = np.ascontiguousarray(K.cross3(A[0][:, :, 0], A[0][:, :, 1]))
            calls.append((np.array(positions), An, *[np.array(x) for x in A[1:]], False,
                          *[np.array(x) for x in E], False, *[np.array(x) for x in E],
                          *[np.array(x) for x in E], np.ascontiguousarray(legs, dtype=np.int64),
                          np.array(U), float(cone_tol), float(normal_tol)))
        return original(positions, U, groups, dims, legs, cone_tol, normal_tol)

    K.slice_facet_normal_parts = spy
    try:
        for q in q0 + rng.uniform(-0.1, 0.1, size=(postures, q0.size)):
            state = ev.standing_state()
            state.joint_positions = dict(zip(names, q.tolist()))
            compute_fws(*ev.fws_job(ev.evaluate(state, fws=False)))
    finally:
        K.slice_facet_normal_parts = original
    return calls


def main(argv: list[str] | None = None) -> int:
    """Print the rows, nodes and times of the variants (module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--postures', type=int, default=200)
    args = parser.parse_args(argv)
    calls = record_calls(args.postures)
    out = np.empty((1 << 14, 6)), np.empty((1 << 14, 6))
    variants = {'kernel': K._slice_search, 'copy': variant([]),
                'no survivors': variant(_NO_SURVIVORS),
                'no slot bounds': variant(_NO_SURVIVORS + _NO_SLOT_BOUNDS),
                'no forms': variant(_NO_SURVIVORS + _NO_FORMS),
                'node pruned': variant(_PRUNED), 'float32 prefilter': variant(_PREFILTER),
                'batched survivors': variant(_BATCHED), 'lanes': variant(_LANES)}

    def rows(fn, call):
        npos, nneg, count = fn(*call, *out)
        return np.vstack([out[0][:npos], out[1][:nneg]]), count

    reference = [rows(K._slice_search, call) for call in calls]
    print(f'{len(calls)} (2, 1, 1, 1) searches: mean {np.mean([len(r) for r, _ in reference]):.0f}'
          f' rows, {np.mean([n for _, n in reference]):.0f} face choices')
    for name in ('copy', 'node pruned', 'float32 prefilter', 'batched survivors', 'lanes'):
        got = [rows(variants[name], call) for call in calls]
        same = sum(g.shape == r.shape and np.array_equal(g, r)
                   for (g, _), (r, _) in zip(got, reference))
        print(f'{name}: rows equal to the kernel rows bit for bit in {same} of {len(calls)}; '
              f'mean rows {np.mean([len(g) for g, _ in got]):.2f}')
        if name == 'node pruned':
            nodes = np.array([n for _, n in got])
            print(f'  nodes kept {np.mean(nodes % 100000):.0f} of {np.mean(nodes // 100000):.0f}')
    for fn in variants.values():                   # compiled before the timed passes
        fn(*calls[0], *out)
    times = {name: [] for name in variants}
    for _ in range(3):
        for name, fn in variants.items():
            t0 = time.perf_counter()
            for call in calls:
                fn(*call, *out)
            times[name].append(1e3 * (time.perf_counter() - t0) / len(calls))
    for name, ms in times.items():
        print(f'{name:>18}: ' + ' / '.join(f'{m:.3f}' for m in ms) + ' ms per call')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
