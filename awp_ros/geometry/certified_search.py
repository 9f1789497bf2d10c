r"""
The FWS's (2, 1, 1, 1) slice search along a stream of joint states, skipping certified choices.

The slice search (:mod:`awp_ros.geometry.minkowski_facets` (5),
:func:`awp_ros.geometry.kernels.slice_facet_normal_parts`) tests every face choice of a pattern:
leg A's facet class (normal ``n``), and edge classes of legs B, C, D, whose *walls* ``r_1, r_2,
r_3`` (4-vectors of the slice ``x = (lambda, t)``) give the choice's normal
``x = *(r_1 ^ r_2 ^ r_3)``; it passes with a sign when every leg's checks ``s`` (4-vectors
too) pass at ``+-x`` within their slack. A check's value is a determinant,
``s . x = det[r_1; r_2; r_3; s]``, so when each of the five vectors has moved by at most
``eps_i`` of its length since a *reference* joint state,

.. math::

    |\Delta (s \cdot x)| \le N |s| \,\eta_v, \qquad
    \eta_v = \prod_i (1 + \epsilon_i) - 1, \qquad N = |r_1| |r_2| |r_3|             \qquad (1)

(multilinearity and Hadamard's inequality), and its slack ``cone_tol |s| |x|`` (node legs B
and C: ``cone_tol |s| |r_1 ^ r_2| |r_3|``) by at most ``cone_tol N |s| (1 + eta_v)``. Each
sign's *score* at the reference,

.. math::

    \sigma_\pm = \min_{\text{legs}} \max_{\text{slots}} \min_{\text{checks}}
        \frac{\pm s \cdot x + \mathrm{slack}}{N |s|}                              \qquad (2)

(>= 0: the choice passes with that sign, exactly the kernel's test), so moves by at most
``eta = eta_v + cone_tol (1 + eta_v)``: a sign scoring below ``-eta`` still fails, above
``eta`` still passes. Per state (:func:`certified_search`): a choice failing with both signs
is skipped (a whole node, leg A's class with B's and C's, when its best score is below its
largest ``-eta``); a sign certain either way needs no test; a sign whose only uncertain legs are
in the band (:data:`BAND`: a check value 0 in exact arithmetic, which no certificate decides)
needs their tests; the rest are tested as the kernel tests them. The rows are the kernel's
formula (:func:`awp_ros.geometry.kernels._slice_normal`), in the kernel's order.
Nothing identifies facets between states (which failed on the degenerate facets, README): a
reference holds only for the same face classes, slots and padding, each choice's vectors then
compared with the reference's by index.

Which references are kept (:func:`try_rows`, :func:`after_kernel`, per thread, one per leg
tuple set): a reference is built (the scores, ~2 ms for HyQ's four legs, after a search) only
when the stream is *coherent*, its walls having moved by a median relative
:data:`COHERENT_STEP` or less since the previous search, as consecutive joint states at the
node's rate do; it is renewed after a search that tested more than :data:`LIMIT` of the
choices. Unrelated postures (``awp_bench``'s random ones, an FWS at 10 Hz) never build one
and pay only for the vectors' comparison (~0.05 ms); a stream too rough for the references to
pay (renewed after fewer than :data:`MIN_SERVED` searches), or not a stream (two pairs of
searches in a row not close), gets none for a cool-down that doubles while it stays so, and
then pays nothing.

Only the pattern (2, 1, 1, 1), three quarters of the four-leg choices, is searched so: the
same certificates on (2, 2, 1) (leg B's facet class as the node) cost more than that
pattern's kernel search, its nodes being few and its references renewed often (README,
"Speed").
"""

from __future__ import annotations

import threading

import numpy as np

from awp_ros.geometry import kernels as K
from awp_ros.geometry.linalg import cross3, workspace

__all__ = ['after_kernel', 'certified_search', 'choice_scores', 'COHERENT_STEP', 'compile_all',
           'LIMIT', 'PATTERN', 'reset', 'slice_vectors', 'statistics', 'try_rows']

#: The pattern searched with certificates.
PATTERN = (2, 1, 1, 1)
#: Choices this close to rank-deficient at the reference (``|r_1 ^ r_2| / (|r_1| |r_2|)`` or
#: ``|x| / (|r_1 ^ r_2| |r_3|)``) are tested at every state (the kernel's rank test may change).
RANK_GUARD = 1e-3
#: Added to every ``eta``: the scores are stored in float32 (|score| <= 1 + cone_tol, rounding
#: <= 6e-8) and computed in float64 (about 1e-15).
ROUNDING = 1e-7
#: A leg scoring within this of 0 passes by its slack alone (a check value 0 in exact arithmetic:
#: the degenerate facets' sub-choices, about 5 % of the choices, often two legs of one): no
#: certificate decides it, its test is repeated at every state.
BAND = 1e-4
#: A reference is renewed after a search that tested more than this share of the choices.
LIMIT = 0.1
#: A reference is built when the walls moved by at most this median relative change since the
#: previous search (consecutive joint states at 1 kHz: about 1e-4), and used while they moved by
#: at most :data:`COHERENT_REFERENCE` since it.
COHERENT_STEP = 1e-3
COHERENT_REFERENCE = 2e-2
#: A reference renewed after fewer certified searches than this did not pay for itself (it costs
#: about 1.5 kernel searches, each certified search saves about half of one): no reference is
#: then built for the next :data:`COOLDOWN` searches, doubled at each such failure in a row (up
#: to :data:`COOLDOWN_MAX`), during which the search is the kernel's at no extra cost. The same
#: after two pairs of consecutive searches in a row that were not close (one is a gap: the
#: first search after another stance).
MIN_SERVED = 3
COOLDOWN = 16
COOLDOWN_MAX = 1024

_jit = K._jit
_INF = np.inf


@_jit(fastmath=True)
def slice_vectors(positions, An, Ac, Am, nA, Bd, Bc, Bm, nB, legs, cone_tol):
    """
    Return the slice vectors of every leg tuple ``t`` and facet class ``fa`` of its leg A.

    ``SA, tA`` (T, mA, k, c, 4), (T, mA, k, c): A's check forms and slacks (``-inf``: no
    slot); ``W`` (T, mA, 3, mB, 4): the walls of legs B, C, D (roles 0-2) by edge class;
    ``S, tS``: their check forms and slacks, as the kernel computes them
    (:func:`awp_ros.geometry.kernels._slice_checks`).
    """
    T, mA, kA, cA = legs.shape[0], Ac.shape[1], Ac.shape[2], Ac.shape[3]
    mB, kB, cB = Bd.shape[1], Bc.shape[2], Bc.shape[3]
    SA, tA = np.zeros((T, mA, kA, cA, 4)), np.full((T, mA, kA, cA), -_INF)
    W = np.zeros((T, mA, 3, mB, 4))
    S, tS = np.zeros((T, mA, 3, mB, kB, cB, 4)), np.full((T, mA, 3, mB, kB, cB), -_INF)
    zero, dk, n = np.zeros(3), np.empty(3), np.empty(3)
    for t in range(T):
        A = legs[t, 0]
        for fa in range(nA[A]):
            for q in range(3):
                n[q] = An[A, fa, q]
            K._slice_checks(n, zero, Ac[A, fa], Am[A, fa], cone_tol, SA[t, fa], tA[t, fa])
            for role in range(3):
                k = legs[t, role + 1]
                for q in range(3):
                    dk[q] = positions[k, q] - positions[A, q]
                for e in range(nB[k]):
                    K._slice_lift(n, dk, Bd[k, e, 0], W[t, fa, role, e])
                    K._slice_checks(n, dk, Bc[k, e], Bm[k, e], cone_tol, S[t, fa, role, e],
                                    tS[t, fa, role, e])
    return SA, tA, W, S, tS


@_jit(inline=True, fastmath=True)
def _leg_scores(Sl, tl, x, scale, cone_tol):
    """
    Return one leg's (+ score, - score) of (2) times N; zero (padded) checks constrain nothing.

    ``|s| = tl / cone_tol`` (the slack ``tl = cone_tol |s|`` of a slot, -inf: no slot).
    """
    f, h = -_INF, _INF
    for s in range(Sl.shape[0]):
        if tl[s, 0] == -_INF:                     # no slot: fails both signs
            continue
        mn, mx = _INF, -_INF
        for j in range(Sl.shape[1]):
            if tl[s, j] == 0.0:
                continue
            v = Sl[s, j, 0] * x[0] + Sl[s, j, 1] * x[1] + Sl[s, j, 2] * x[2] + Sl[s, j, 3] * x[3]
            inv = cone_tol / tl[s, j]             # 1 / |s|
            mn = min(mn, v * inv + cone_tol * scale)
            mx = max(mx, v * inv - cone_tol * scale)
        f, h = max(f, mn), min(h, mx)
    return f, -h


@_jit(fastmath=True)
def choice_scores(SA, tA, W, S, tS, legs, nA, nB, cone_tol, worst, rest, band, node_best):
    """
    Write every choice's scores (2) in search order ``(t, fa, b, c, d)``; return the counts.

    Per sign (columns + and -): ``worst`` the smallest leg score, ``band`` the bit mask of the
    legs (bits 0-3: A, B, C, D) scoring within :data:`BAND` of 0, ``rest`` the smallest score
    of the others (inf: none), in float32; NaN for a choice close to rank-deficient
    (:data:`RANK_GUARD`, tested at every state). ``node_best``: per node ``(t, fa, b, c)`` the
    largest score of its choices (inf with a NaN one). Returns ``(choices, nodes)``.
    """
    P, x = np.empty(6), np.empty(4)
    g = np.empty((4, 2))
    i = 0
    node = 0
    for t in range(legs.shape[0]):
        A, B, C, D = legs[t, 0], legs[t, 1], legs[t, 2], legs[t, 3]
        for fa in range(nA[A]):
            for b in range(nB[B]):
                r1 = W[t, fa, 0, b]
                for c in range(nB[C]):
                    r2 = W[t, fa, 1, c]
                    nP = K._plucker4(r1, r2, P)
                    n12 = K._norm4(r1) * K._norm4(r2)
                    best = -_INF
                    for d in range(nB[D]):
                        r3 = W[t, fa, 2, d]
                        n3 = K._norm4(r3)
                        K._cross4(P, r3, x)
                        nx = K._norm4(x)
                        if not (nP > RANK_GUARD * n12 and nx > RANK_GUARD * nP * n3):
                            for sg in range(2):
                                worst[i, sg] = rest[i, sg] = np.nan
                                band[i, sg] = 0
                            best = _INF
                            i += 1
                            continue
                        g[0, 0], g[0, 1] = _leg_scores(SA[t, fa], tA[t, fa], x, nx, cone_tol)
                        g[1, 0], g[1, 1] = _leg_scores(S[t, fa, 0, b], tS[t, fa, 0, b], x,
                                                       nP * n3, cone_tol)
                        g[2, 0], g[2, 1] = _leg_scores(S[t, fa, 1, c], tS[t, fa, 1, c], x,
                                                       nP * n3, cone_tol)
                        g[3, 0], g[3, 1] = _leg_scores(S[t, fa, 2, d], tS[t, fa, 2, d], x, nx,
                                                       cone_tol)
                        inv_N = 1.0 / (n12 * n3)
                        for sg in range(2):
                            low, other, bits = _INF, _INF, 0
                            for k in range(4):
                                v = g[k, sg] * inv_N
                                low = min(low, v)
                                if abs(v) <= BAND:
                                    bits |= 1 << k
                                else:
                                    other = min(other, v)
                            worst[i, sg], rest[i, sg], band[i, sg] = low, other, bits
                            best = max(best, low)
                        i += 1
                    node_best[node] = best
                    node += 1
    return i, node


@_jit(inline=True, fastmath=True)
def _rel(a, b):
    """Return ``|a - b| / |b|`` (0 for two zero vectors, inf for a zero ``b`` that moved)."""
    da, nb = 0.0, 0.0
    for i in range(4):
        da += (a[i] - b[i]) * (a[i] - b[i])
        nb += b[i] * b[i]
    if nb == 0.0:
        return 0.0 if da == 0.0 else _INF
    return np.sqrt(da / nb)


@_jit(inline=True, fastmath=True)
def _checks_rel(Sl, S0):
    """Return the largest relative change of a slot set's check forms."""
    e = 0.0
    for s in range(Sl.shape[0]):
        for j in range(Sl.shape[1]):
            e = max(e, _rel(Sl[s, j], S0[s, j]))
    return e


@_jit(fastmath=True)
def wall_change(W, W0, legs, nA, nB):
    """Return the median relative change ``|w - w_0| / |w_0|`` of the walls (coherence)."""
    T, mA, mB = W.shape[0], W.shape[1], W.shape[3]
    out = np.empty(T * mA * 3 * mB)
    n = 0
    for t in range(T):
        for fa in range(nA[legs[t, 0]]):
            for role in range(3):
                for e in range(nB[legs[t, role + 1]]):
                    out[n] = _rel(W[t, fa, role, e], W0[t, fa, role, e])
                    n += 1
    return np.median(out[:n]) if n else 0.0


@_jit(inline=True, fastmath=True)
def _decision(score, rest, eta):
    """Return 0: fails, 1: passes, 2: the band's legs decide, 3: test every leg."""
    if score < -eta:
        return 0
    if score > eta:
        return 1
    if rest > eta:
        return 2
    return 3


@_jit(fastmath=True)
def certified_search(SA, tA, W, S, tS, SA0, W0, S0, worst, rest, band, node_best, legs, nA,
                     nB, positions, An, U, cone_tol, normal_tol, scale, out_pos, out_neg):
    """
    Search the choices no certificate decides (module docstring); rows as the kernel's.

    The current vectors (:func:`slice_vectors`), the reference's ``SA0, W0, S0`` and its
    :func:`choice_scores`. ``scale`` multiplies every ``eta`` (1: the certificate; 0 trusts
    the reference's verdicts, for the test that a comparison catches it). Returns
    ``(npos, nneg, tested, band tests, nodes skipped)``: rows -1 when an output is full,
    ``tested`` the choices whose every check was evaluated.
    """
    T, mA, mB = legs.shape[0], W.shape[1], W.shape[3]
    eA = np.zeros((T, mA))
    eW, eS = np.zeros((T, mA, 3, mB)), np.zeros((T, mA, 3, mB))
    eWD, eSD = np.zeros((T, mA)), np.zeros((T, mA))
    for t in range(T):
        for fa in range(nA[legs[t, 0]]):
            eA[t, fa] = _checks_rel(SA[t, fa], SA0[t, fa])
            for role in range(3):
                for e in range(nB[legs[t, role + 1]]):
                    eW[t, fa, role, e] = _rel(W[t, fa, role, e], W0[t, fa, role, e])
                    eS[t, fa, role, e] = _checks_rel(S[t, fa, role, e], S0[t, fa, role, e])
                    if role == 2:
                        eWD[t, fa] = max(eWD[t, fa], eW[t, fa, role, e])
                        eSD[t, fa] = max(eSD[t, fa], eS[t, fa, role, e])
    P, x, a, n = np.empty(6), np.empty(4), np.empty(6), np.empty(3)
    kA, cA = SA.shape[2], SA.shape[3]
    kB, cB = S.shape[4], S.shape[5]
    npos, nneg, tested, single, skipped, i, node = 0, 0, 0, 0, 0, 0, 0
    for t in range(T):
        A, B, C, D = legs[t, 0], legs[t, 1], legs[t, 2], legs[t, 3]
        pA = positions[A]
        for fa in range(nA[A]):
            for q in range(3):
                n[q] = An[A, fa, q]
            for b in range(nB[B]):
                r1 = W[t, fa, 0, b]
                for c in range(nB[C]):
                    r2 = W[t, fa, 1, c]
                    f12 = (1.0 + eW[t, fa, 0, b]) * (1.0 + eW[t, fa, 1, c])
                    ce = max(eA[t, fa], max(eS[t, fa, 0, b], eS[t, fa, 1, c]))
                    ev = f12 * (1.0 + eWD[t, fa]) * (1.0 + max(ce, eSD[t, fa])) - 1.0
                    if node_best[node] < -scale * (ev + cone_tol * (1.0 + ev) + ROUNDING):
                        i += nB[D]                        # every choice of the node fails
                        node += 1
                        skipped += 1
                        continue
                    node += 1
                    state = 0                             # node: 0 not computed, 1 ok, -1 rank
                    nP = 0.0
                    for d in range(nB[D]):
                        ev = f12 * (1.0 + eW[t, fa, 2, d]) * (1.0 + max(ce, eS[t, fa, 2, d])) \
                            - 1.0
                        eta = scale * (ev + cone_tol * (1.0 + ev) + ROUNDING)
                        sp, sn = worst[i, 0], worst[i, 1]
                        ii = i
                        i += 1
                        if sp < -eta and sn < -eta:       # certified: fails with both signs
                            continue
                        if state == 0:
                            nP = K._plucker4(r1, r2, P)
                            state = 1 if nP > normal_tol * K._norm4(r1) * K._norm4(r2) else -1
                        if state < 0:
                            continue
                        r3 = W[t, fa, 2, d]
                        n3 = K._norm4(r3)
                        K._cross4(P, r3, x)
                        nx = K._norm4(x)
                        if not nx > normal_tol * nP * n3:      # the kernel's rank test
                            continue
                        dp = _decision(sp, rest[ii, 0], eta)
                        dn = _decision(sn, rest[ii, 1], eta)
                        ns = nP * n3
                        if dp == 3 or dn == 3:            # the kernel's test, every leg
                            tested += 1
                            pos, neg = K._slot_signs(S[t, fa, 0, b], tS[t, fa, 0, b], kB, cB, x,
                                                     ns)
                            if pos or neg:
                                pc, nc = K._slot_signs(S[t, fa, 1, c], tS[t, fa, 1, c], kB, cB,
                                                       x, ns)
                                pos, neg = pos and pc, neg and nc
                            if pos or neg:
                                pa, na = K._slot_signs(SA[t, fa], tA[t, fa], kA, cA, x, nx)
                                pd, nd = K._slot_signs(S[t, fa, 2, d], tS[t, fa, 2, d], kB, cB,
                                                       x, nx)
                                pos, neg = pos and pa and pd, neg and na and nd
                        else:                             # certain signs, or the band's legs
                            pos, neg = dp == 1, dn == 1
                            for sg in range(2):
                                if (dp if sg == 0 else dn) != 2:
                                    continue
                                single += 1
                                bits = band[ii, sg]
                                ok = True
                                if bits & 1:
                                    ok = K._slot_signs(SA[t, fa], tA[t, fa], kA, cA, x, nx)[sg]
                                if ok and bits & 2:
                                    ok = K._slot_signs(S[t, fa, 0, b], tS[t, fa, 0, b], kB, cB,
                                                       x, ns)[sg]
                                if ok and bits & 4:
                                    ok = K._slot_signs(S[t, fa, 1, c], tS[t, fa, 1, c], kB, cB,
                                                       x, ns)[sg]
                                if ok and bits & 8:
                                    ok = K._slot_signs(S[t, fa, 2, d], tS[t, fa, 2, d], kB, cB,
                                                       x, nx)[sg]
                                if sg == 0:
                                    pos = ok
                                else:
                                    neg = ok
                        if pos:
                            if npos == out_pos.shape[0]:
                                return -1, -1, tested, single, skipped
                            K._slice_normal(x, n, pA, U, out_pos, npos, a)
                            npos += 1
                        if neg:
                            if nneg == out_neg.shape[0]:
                                return -1, -1, tested, single, skipped
                            for q in range(4):
                                x[q] = -x[q]
                            K._slice_normal(x, n, pA, U, out_neg, nneg, a)
                            nneg += 1
    return npos, nneg, tested, single, skipped


class Reference:
    """A reference state of one leg tuple set: its vectors and scores (module docstring)."""

    def __init__(self, signature: bytes, vectors: tuple, counts: tuple, legs: np.ndarray,
                 cone_tol: float) -> None:
        self.signature = signature
        self.SA, _, self.W, self.S, _ = vectors
        nA, nB = counts
        choices = int(sum(nA[t[0]] * nB[t[1]] * nB[t[2]] * nB[t[3]] for t in legs))
        nodes = int(sum(nA[t[0]] * nB[t[1]] * nB[t[2]] for t in legs))
        self.worst = np.empty((choices, 2), dtype=np.float32)
        self.rest = np.empty((choices, 2), dtype=np.float32)
        self.band = np.empty((choices, 2), dtype=np.uint8)
        self.node_best = np.empty(nodes, dtype=np.float32)
        done = choice_scores(*vectors, legs, nA, nB, cone_tol, self.worst, self.rest, self.band,
                             self.node_best)
        assert done == (choices, nodes)
        self.choices = choices


class _Streams(threading.local):
    """Per thread: the references and the previous search's walls, by leg tuple set."""

    def __init__(self) -> None:
        self.references: dict = {}
        self.previous: dict = {}
        self.served: dict = {}            # certified searches by the current reference
        self.cooldown: dict = {}          # searches left without references, and its length
        self.apart: dict = {}             # the last pair of searches was not close
        self.counts = {'certified': 0, 'kernel': 0, 'references': 0, 'tested': 0, 'choices': 0}


_STREAMS = _Streams()


def statistics() -> dict:
    """
    Return this thread's counts: searches by certificates and by the kernel, references built.

    ``tested``/``choices``: the choices tested in full and those of the certified searches.
    """
    return dict(_STREAMS.counts)


def reset() -> None:
    """Forget this thread's references, previous searches and cool-downs (not its counts)."""
    counts = _STREAMS.counts
    _STREAMS.__init__()
    _STREAMS.counts = counts


def _signature(groups: dict, legs: np.ndarray, cone_tol: float) -> bytes:
    """Return what a reference needs unchanged: classes, slots, padded checks, legs, slack."""
    parts = [np.float64(cone_tol).tobytes(), legs.tobytes()]
    for d in (1, 2):
        dirs, checks, mask, counts = groups[d]
        parts += [str(checks.shape).encode(), mask.tobytes(), counts.tobytes(),
                  (np.abs(checks).sum(axis=-1) == 0.0).tobytes()]
    return b'|'.join(parts)


def try_rows(positions: np.ndarray, U: np.ndarray, groups: dict, legs, cone_tol: float,
             normal_tol: float, *, build: bool = True) -> tuple[tuple | None, tuple]:
    """
    Return the pattern's rows by certificates, or None when this thread has no usable reference.

    ``(plus (N+, 6), minus (N-, 6), choices)`` as
    :func:`awp_ros.geometry.kernels.slice_facet_normal_parts` for :data:`PATTERN` (the same
    rows, up to the last bits of rounding, in the same order), and a context for
    :func:`after_kernel` (call it when the kernel searched instead). A search that tested
    more than :data:`LIMIT` of the choices renews the reference on this state (``build``;
    else at the next kernel search).
    """
    legs = np.ascontiguousarray(legs, dtype=np.int64)
    # Writeable copies if need be: a read-only array is another type to numba, compiled (or
    # loaded from its cache, ~10 ms) at its first call, inside a control cycle.
    positions = np.require(positions, dtype=float, requirements=['C', 'W'])
    key = (positions.shape[0], legs.tobytes())
    streams = _STREAMS
    if streams.cooldown.get(key, (0, 0))[0] > 0:      # references did not pay: the kernel
        return None, (key, None)
    cone_tol = float(cone_tol)
    A, B = groups[2], groups[1]
    An = np.ascontiguousarray(cross3(A[0][:, :, 0], A[0][:, :, 1]))
    vectors = slice_vectors(positions, An, A[1], A[2], A[3], B[0], B[1], B[2], B[3], legs,
                            cone_tol)
    signature = _signature(groups, legs, cone_tol)
    context = (key, signature, vectors, (A[3], B[3]), legs, cone_tol)
    ref = streams.references.get(key)
    if ref is None or ref.signature != signature \
            or wall_change(vectors[2], ref.W, legs, A[3], B[3]) > COHERENT_REFERENCE:
        return None, context
    U = np.require(U, dtype=float, requirements=['C', 'W'])
    cap = 4096
    while True:
        out_pos = workspace('certified_pos', (cap, 6))
        out_neg = workspace('certified_neg', (cap, 6))
        npos, nneg, tested, _, _ = certified_search(
            *vectors, ref.SA, ref.W, ref.S, ref.worst, ref.rest, ref.band, ref.node_best, legs,
            A[3], B[3], positions, An, U, cone_tol, float(normal_tol), 1.0, out_pos, out_neg)
        if npos >= 0:
            break
        cap *= 4
    counts = streams.counts
    counts['certified'] += 1
    counts['tested'] += tested
    counts['choices'] += ref.choices
    found = (out_pos[:npos].copy(), out_neg[:nneg].copy(), ref.choices)
    streams.previous[key] = (signature, vectors[2])
    streams.served[key] = served = streams.served.get(key, 0) + 1
    if tested > LIMIT * ref.choices:
        if served < MIN_SERVED:                       # too rough a stream: back off
            _back_off(streams, key)
        elif build:
            streams.cooldown.pop(key, None)
            _build(streams, context)
        else:
            streams.references.pop(key, None)
    return found, context


def after_kernel(context: tuple, *, build: bool = True) -> None:
    """
    Note a kernel search of :func:`try_rows`'s context; make it a reference if coherent.

    ``build``: whether a reference may be built now (~2 ms for HyQ's four legs; the stepped
    search, whose steps are ~0.2 ms, passes False).
    """
    streams = _STREAMS
    streams.counts['kernel'] += 1
    if context[1] is None:                            # in a cool-down
        left, length = streams.cooldown[context[0]]
        streams.cooldown[context[0]] = (left - 1, length)
        return
    key, signature, vectors, counts, legs, _ = context
    previous = streams.previous.get(key)
    streams.previous[key] = (signature, vectors[2])
    streams.references.pop(key, None)
    if not build or previous is None or previous[0] != signature:
        return
    if wall_change(vectors[2], previous[1], legs, *counts) <= COHERENT_STEP:
        streams.apart.pop(key, None)
        _build(streams, context)
    elif streams.apart.setdefault(key, 0) >= 1:      # two pairs apart in a row: not a stream
        streams.apart.pop(key, None)
        _back_off(streams, key)
    else:                                             # one pair apart: a gap, e.g. a stance
        streams.apart[key] = 1


def _back_off(streams: _Streams, key: tuple) -> None:
    """Build no reference for the next searches of ``key``: twice as many as last time."""
    streams.references.pop(key, None)
    streams.previous.pop(key, None)
    length = min(max(2 * streams.cooldown.get(key, (0, 0))[1], COOLDOWN), COOLDOWN_MAX)
    streams.cooldown[key] = (length, length)


def _build(streams: _Streams, context: tuple) -> None:
    """Make the context's state the reference of its leg tuple set."""
    key, signature, vectors, counts, legs, cone_tol = context
    if len(streams.references) >= 8 and key not in streams.references:
        streams.references.clear()
    if len(streams.previous) >= 8 and key not in streams.previous:
        streams.previous.clear()
        streams.cooldown.clear()
        streams.apart.clear()
    streams.references[key] = Reference(signature, vectors, counts, legs, cone_tol)
    streams.served[key] = 0
    streams.counts['references'] += 1


def compile_all() -> None:
    """Compile (or load from the disk cache) this module's kernels on small inputs, once."""
    global _COMPILED
    if _COMPILED or not K.ENABLED:
        return
    _COMPILED = True
    rng = np.random.default_rng(0)
    groups = {d: (rng.normal(size=(2, 2, d, 3)), rng.normal(size=(2, 2, 2, 2, 3)),
                  np.ones((2, 2, 2), dtype=bool), np.full(2, 2)) for d in (1, 2)}
    legs = np.array([[0, 1, 1, 1]], dtype=np.int64)
    positions = rng.normal(size=(2, 3))
    An = np.ascontiguousarray(cross3(groups[2][0][:, :, 0], groups[2][0][:, :, 1]))
    counts = (groups[2][3], groups[1][3])
    vectors = slice_vectors(positions, An, *groups[2][1:], *groups[1], legs, 1e-5)
    ref = Reference(b'', vectors, counts, legs, 1e-5)
    wall_change(vectors[2], ref.W, legs, *counts)
    certified_search(*vectors, ref.SA, ref.W, ref.S, ref.worst, ref.rest, ref.band, ref.node_best,
                     legs, *counts, positions, An, np.eye(6), 1e-5, 1e-8, 1.0, np.empty((64, 6)),
                     np.empty((64, 6)))


_COMPILED = False
