"""The largest norm of a Minkowski sum of segments, discs and ellipsoids in 3D, certified, over many poses.

The set
-------
At each pose the error set is ``S = sum_j A_j B_j``: block ``j`` is a matrix ``A_j`` of shape ``(3, d_j)``,
``d_j`` in {1, 2, 3}, applied to the unit ball ``B_j`` of ``R^{d_j}`` (a segment ``{s a : |s| <= 1}`` for
``d = 1``, an elliptic disc for ``d = 2``, an ellipsoid for ``d = 3``; any of them may be degenerate). Its
support function is ``h(u) = max_{x in S} u.x = sum_j |A_j^T u|`` and the quantity sought is

    R = max_{x in S} |x| = max_{|u| = 1} h(u)

(``|x| = max_{|u|=1} u.x``; exchange the two maxima). ``S`` is centrally symmetric, so ``h(-u) = h(u)``.

Facts used (each proved here in one line)
----------------------------------------
(F1) *Every sampled direction is a lower bound*: ``R >= h(u)`` for every unit ``u`` (definition of R).

(F2) *The gradient is a point of S*: for ``x_j = A_j^T u / |A_j^T u|`` (any unit-ball point when
     ``A_j^T u = 0``; ``sign(a_j.u)`` for a segment) the point ``g(u) = sum_j A_j x_j`` lies in ``S`` and
     ``u.g(u) = h(u)``; hence ``R >= |g(u)| >= u.g(u) = h(u)``. The lower bound returned is always
     ``|sum_j A_j x_j|`` for an explicit configuration ``x_j`` with ``|x_j| <= 1``.

(F3) *The ascent is monotone*: for ``u' = g(u)/|g(u)|``, ``h(u') = max_{x in S} u'.x >= u'.g(u) = |g(u)|
     >= h(u)``; so ``u <- g(u)/|g(u)|`` never decreases ``h`` nor ``|g|`` (a power iteration for ``S``).

(F4) *Cell bound from convexity* (the upper bound used by the branch and bound): a cell is the central
     projection onto the sphere of a square ``Q`` on a face ``{x_a = 1}`` of the cube, with corners
     ``p_1..p_4``. Let ``u0`` be a unit vector with ``p_k.u0 > 0`` (the normalized centre). Every unit
     ``u`` of the cell is ``q/|q|`` for a ``q`` of the quadrilateral ``conv{q_k}``, ``q_k = p_k/(p_k.u0)``
     (the cone over Q cut by the plane ``{x.u0 = 1}``; central projection maps segments to segments), and
     ``|q| >= q.u0 = 1``. As ``h`` is convex, positively homogeneous and >= 0:

         h(u) = h(q)/|q| <= h(q) <= max_k h(q_k) = max_k h(p_k) / (p_k.u0).

     The bound exceeds the cell's maximum by ``O(|grad h| rho + rho^2)`` (``rho`` the cell's angular radius),
     second order at the maximum, so the cells around the optimum need only ``rho ~ sqrt(gap)``.

(F5) *Covering*: the three faces ``x_a = +1`` (squares ``[-1, 1]^2``) cover one of ``u, -u`` for every unit
     ``u`` (its largest component in absolute value, with the sign made positive), and ``h(-u) = h(u)``;
     so the maximum of the cell bounds over any partition of the three faces bounds ``R``.

(F6) *Zonotopes exactly* (every block a segment): ``|x|^2`` is convex, so its maximum over the polytope
     ``S`` is at a vertex. A vertex ``v`` of a full-rank zonotope has a 3D normal cone (a spherical polygon
     whose sides lie on the great circles ``a_j^perp``); a corner of it is ``+-n``, ``n = a_i x a_k`` for a
     pair of non-parallel generators, and ``v = lim_{eps->0} v(n + eps w)`` for ``w`` pointing into the
     cone, ``v(u) = sum_j sign(a_j.u) a_j``. Near ``n`` the signs are ``sign(a_j.n)`` where non-zero; the
     pair's own signs ``(s_i, s_k)`` choose one of 4 sectors around ``n``; a generator coplanar with
     ``a_i, a_k`` (a tie, ``a_j.n = 0``, including generators parallel to ``a_i`` or ``a_k``) takes
     ``sign(a_j.w)`` with ``w = s_i (a_k x n) + s_k (n x a_i)`` (``w.a_i = s_i |n|^2``,
     ``w.a_k = s_k |n|^2``: the sector's bisector in the dual basis). When ``a_i, a_k`` are consecutive
     in angle among the coplanar generators the sector holds no other ``a_j^perp``, so every vertex
     arises this way; ``-n`` gives the vertices ``-v`` (same norm), so ``+n`` suffices. A zonotope of
     rank 2 (a zonogon: all generators coplanar, all ties) is covered the same way; rank 1 by the extra
     candidate ``u = `` the largest generator. Every candidate is a point of ``S`` (a sign vector), so the
     best candidate is ``R`` exactly: ``O(s^3)`` operations per pose for ``s`` generators.

Rounding: ``h`` is evaluated as ``|A_j^T p|`` from the columns (not from ``A_j A_j^T``, whose square root
loses half the digits near a null direction); the cell bounds are widened by the relative ``ROUND``
(far above the rounding of a few hundred terms).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError

#: Relative widening of every upper bound, above the rounding of the evaluation of ``h``.
ROUND = 1e-12
#: Relative tolerance under which ``a_j.(a_i x a_k)`` counts as zero (coplanar generators).
_TIE = 1e-10
#: Poses processed at once (bounds the memory of the flat arrays of cells).
_CHUNK = 1 << 15
_DEBUG = False


@dataclass(frozen=True)
class MaxNorm:
    """Certified bounds on ``R = max_{x in S} |x|`` at each pose (shapes: the blocks' leading shape ``(...)``).

    * ``upper``: never below ``R`` (up to the widening :data:`ROUND`); ``lower``: ``= |point| <= R``;
    * ``direction``: unit ``u*`` at which the configuration attains ``h`` (``(..., 3)``);
    * ``point``: ``sum_j A_j x_j`` (``(..., 3)``), ``x_j = configuration[j]`` (``(..., d_j)``, ``|x_j| <= 1``);
    * ``certified``: ``upper - lower <= gap * lower``; ``exact``: the zonotope case, ``upper == lower``.
    """

    upper: np.ndarray
    lower: np.ndarray
    direction: np.ndarray
    point: np.ndarray
    configuration: list[np.ndarray]
    certified: np.ndarray
    exact: np.ndarray


# ----------------------------------------------------------------------------------------------- helpers


def _prepare(blocks) -> tuple[tuple[int, ...], list[np.ndarray]]:
    """Broadcast the blocks to one leading shape and flatten it: ``(N, 3, d_j)`` each."""
    if len(blocks) == 0:
        raise ConfigError("max_norm needs at least one block")
    arrays = [np.asarray(b, dtype=float) for b in blocks]
    for j, a in enumerate(arrays):
        if a.ndim < 2 or a.shape[-2] != 3 or a.shape[-1] not in (1, 2, 3):
            raise ConfigError(f"block {j} has shape {a.shape}, expected (..., 3, d) with d in 1, 2, 3")
        if not np.all(np.isfinite(a)):
            raise ConfigError(f"block {j} has non-finite entries")
    lead = np.broadcast_shapes(*(a.shape[:-2] for a in arrays))
    flat = [np.broadcast_to(a, lead + a.shape[-2:]).reshape((-1,) + a.shape[-2:]) for a in arrays]
    return lead, flat


class _Layout:
    """All blocks' columns side by side, ``C (N, 3, ncol)``: segments first, then discs, then ellipsoids."""

    def __init__(self, flat: list[np.ndarray]):
        self.dims = [b.shape[-1] for b in flat]
        self.order = [j for d in (1, 2, 3) for j, dj in enumerate(self.dims) if dj == d]
        self.n1 = sum(1 for d in self.dims if d == 1)
        self.n2 = sum(1 for d in self.dims if d == 2)
        self.n3 = sum(1 for d in self.dims if d == 3)
        self.C = np.ascontiguousarray(np.concatenate([flat[j] for j in self.order], axis=-1))
        self.s2 = self.n1 + 2 * self.n2  # end of the disc columns

    def h(self, Y: np.ndarray) -> np.ndarray:
        """``h`` from the products ``Y = p^T C`` (``(..., ncol)``)."""
        n1, s2 = self.n1, self.s2
        out = np.abs(Y[..., :n1]).sum(-1)
        if self.n2:
            q = Y[..., n1:s2] ** 2
            out = out + np.sqrt(q.reshape(q.shape[:-1] + (self.n2, 2)).sum(-1)).sum(-1)
        if self.n3:
            q = Y[..., s2:] ** 2
            out = out + np.sqrt(q.reshape(q.shape[:-1] + (self.n3, 3)).sum(-1)).sum(-1)
        return out

    def unit_config(self, Y: np.ndarray) -> np.ndarray:
        """The unit-ball points ``x`` attaining ``h`` (side by side like the columns), ``0`` at a null block."""
        n1, s2 = self.n1, self.s2
        X = np.empty_like(Y)
        X[..., :n1] = np.where(Y[..., :n1] >= 0, 1.0, -1.0)
        for lo, hi, d in ((n1, s2, 2), (s2, Y.shape[-1], 3)):
            if hi > lo:
                q = Y[..., lo:hi].reshape(Y.shape[:-1] + ((hi - lo) // d, d))
                nrm = np.sqrt((q ** 2).sum(-1, keepdims=True))
                with np.errstate(invalid="ignore", divide="ignore"):
                    x = np.where(nrm > 0, q / nrm, 0.0)
                X[..., lo:hi] = x.reshape(Y.shape[:-1] + (hi - lo,))
        return X

    def split(self, X: np.ndarray) -> list[np.ndarray]:
        """Side-by-side configuration ``(N, ncol)`` back to the blocks' order: list of ``(N, d_j)``."""
        out: list[np.ndarray] = [None] * len(self.dims)  # type: ignore[list-item]
        col = 0
        for j in self.order:
            out[j] = X[:, col:col + self.dims[j]]
            col += self.dims[j]
        return out


def support(blocks, u) -> np.ndarray:
    """Support function ``h(u) = sum_j |A_j^T u|`` of ``S = sum_j A_j B_j``: blocks ``(..., 3, d_j)``, ``u (..., 3)``.

    ``u`` need not be unit (``h`` is positively homogeneous); for a unit ``u``, ``h(u) <= R`` (F1).

    >>> ball = 2.0 * np.eye(3)[None]; seg = np.array([[[0.0], [0.0], [1.0]]])
    >>> support([ball, seg], np.array([[0.0, 0.0, 1.0]]))
    array([3.])
    """
    u = np.asarray(u, dtype=float)
    lead, flat = _prepare([np.asarray(b, dtype=float) + np.zeros(u.shape[:-1] + (1, 1)) for b in blocks])
    lay = _Layout(flat)
    uu = np.broadcast_to(u, lead + (3,)).reshape(-1, 3)
    Y = np.einsum("nc,ncm->nm", uu, lay.C)
    return lay.h(Y).reshape(lead)


# ----------------------------------------------------------------------------------------------- zonotope


def _zonotope(G: np.ndarray) -> np.ndarray:
    """Exact maximizing sign vector ``(N, s)`` of ``|sum_j s_j g_j|`` for generators ``G (N, s, 3)`` (F6)."""
    N, s, _ = G.shape
    gn = np.sqrt((G ** 2).sum(-1))  # (N, s)
    # rank-1 candidate: aligned with the largest generator
    m = np.argmax(gn, axis=1)
    am = G[np.arange(N), m]
    best_S = np.where(np.einsum("nsc,nc->ns", G, am) >= 0, 1.0, -1.0)
    v = np.einsum("ns,nsc->nc", best_S, G)
    best = (v ** 2).sum(-1)
    if s < 2:
        return best_S
    I, K = np.triu_indices(s, 1)
    p = I.size
    own = np.zeros((p, s), dtype=bool)
    own[np.arange(p), I] = True
    own[np.arange(p), K] = True
    ai, ak = G[:, I], G[:, K]                                   # (N, p, 3)
    n = np.cross(ai, ak)
    nn = np.sqrt((n ** 2).sum(-1))                              # (N, p)
    T = np.matmul(n, G.transpose(0, 2, 1))                      # (N, p, s)
    tie = (np.abs(T) <= _TIE * nn[..., None] * gn[:, None, :]) & ~own
    S0 = np.where(tie | own, 0.0, np.sign(T))
    v0 = np.matmul(S0, G)                                       # (N, p, 3)
    ci = (v0 * ai).sum(-1)
    ck = (v0 * ak).sum(-1)
    gik = (ai * ak).sum(-1)
    base = (v0 ** 2).sum(-1) + (ai ** 2).sum(-1) + (ak ** 2).sum(-1)
    sig = np.array([[1.0, 1.0], [1.0, -1.0], [-1.0, 1.0], [-1.0, -1.0]])
    vals = base[..., None] + 2.0 * (sig[:, 0] * ci[..., None] + sig[:, 1] * ck[..., None]
                                    + sig[:, 0] * sig[:, 1] * gik[..., None])   # (N, p, 4)
    # entries with ties besides the pair: full candidates with the tie rule sign(a_j . w)
    hard = np.flatnonzero(tie.any(-1).ravel())
    if hard.size:
        hn, hp = np.divmod(hard, p)
        n_h, ai_h, ak_h = n[hn, hp], ai[hn, hp], ak[hn, hp]
        w1, w2 = np.cross(ak_h, n_h), np.cross(n_h, ai_h)
        Gh = G[hn]                                              # (h, s, 3)
        tie_h = tie[hn, hp]
        for q in range(4):
            w = sig[q, 0] * w1 + sig[q, 1] * w2
            st = np.where(tie_h, np.sign(np.einsum("hsc,hc->hs", Gh, w)), 0.0)
            vq = v0[hn, hp] + sig[q, 0] * ai_h + sig[q, 1] * ak_h + np.einsum("hs,hsc->hc", st, Gh)
            vals[hn, hp, q] = (vq ** 2).sum(-1)
    flat = vals.reshape(N, -1)
    arg = np.argmax(flat, axis=1)
    val = flat[np.arange(N), arg]
    bp, bq = np.divmod(arg, 4)
    rows = np.arange(N)
    S = S0[rows, bp].copy()
    S[rows, I[bp]] = sig[bq, 0]
    S[rows, K[bp]] = sig[bq, 1]
    tb = tie[rows, bp]
    if tb.any():
        nb = n[rows, bp]
        w = sig[bq, 0, None] * np.cross(ak[rows, bp], nb) + sig[bq, 1, None] * np.cross(nb, ai[rows, bp])
        S = np.where(tb, np.sign(np.einsum("nsc,nc->ns", G, w)), S)
    use = val > best
    return np.where(use[:, None], S, best_S)


def _polish_signs(S: np.ndarray, G: np.ndarray) -> np.ndarray:
    """Replace the zero signs one by one by ``sign(v.g_j)`` (never decreases ``|v|``: ``|v+-g|^2 >= |v|^2``)."""
    S = S.copy()
    v = np.einsum("ns,nsc->nc", S, G)
    for j in range(S.shape[1]):
        z = S[:, j] == 0
        if z.any():
            sj = np.where((v * G[:, j]).sum(-1) >= 0, 1.0, -1.0)
            S[:, j] = np.where(z, sj, S[:, j])
            v = v + np.where(z, sj, 0.0)[:, None] * G[:, j]
    return S


# ----------------------------------------------------------------------------------------------- general


def _ascend(lay: _Layout, C: np.ndarray, u: np.ndarray, iters: int) -> tuple[np.ndarray, np.ndarray]:
    """``iters`` steps of ``u <- g(u)/|g(u)|`` (F3) from ``u (n, 3)``; returns ``(u, |g(u)|)`` of the last."""
    for _ in range(iters):
        Y = np.einsum("nc,ncm->nm", u, C)
        X = lay.unit_config(Y)
        g = np.einsum("ncm,nm->nc", C, X)
        gn = np.sqrt((g ** 2).sum(-1))
        ok = gn > 0
        u = np.where(ok[:, None], g / np.where(ok, gn, 1.0)[:, None], u)
    Y = np.einsum("nc,ncm->nm", u, C)
    g = np.einsum("ncm,nm->nc", C, lay.unit_config(Y))
    return u, np.sqrt((g ** 2).sum(-1))


def _segmax(values: np.ndarray, pose: np.ndarray, n: int) -> np.ndarray:
    """Max of ``values`` per pose (``pose`` sorted), ``-inf`` for poses absent."""
    out = np.full(n, -np.inf)
    if values.size:
        starts = np.flatnonzero(np.r_[True, pose[1:] != pose[:-1]])
        out[pose[starts]] = np.maximum.reduceat(values, starts)
    return out


# face a: the point (x, y, 1) of the face's square goes to coordinates  [a] = 1, [a+1] = x, [a+2] = y
_PERM = np.array([[2, 0, 1], [1, 2, 0], [0, 1, 2]])
_G3 = np.array([0.0, 0.5, 1.0])
_GX = np.repeat(_G3, 3)          # grid point k = 3*i + j at (x0 + w*_G3[i], y0 + w*_G3[j])
_GY = np.tile(_G3, 3)
_CHILD = np.array([[0, 0], [0, 1], [1, 0], [1, 1]])
_CORNERS = np.array([[3 * (i + a) + (j + b) for a in (0, 1) for b in (0, 1)] for i, j in _CHILD])  # (4, 4)


def _branch_and_bound(lay: _Layout, C: np.ndarray, gap: float, max_levels: int, ascent: int):
    """Branch and bound over the three cube faces for one chunk of poses (F1-F5)."""
    N = C.shape[0]
    # start: the 27 points of the faces' 3x3 grids, then the ascent from the best
    pose = np.repeat(np.arange(N), 3)
    face = np.tile(np.arange(3), N)
    x0 = np.full(pose.size, -1.0)
    y0 = np.full(pose.size, -1.0)
    w = 2.0
    lower = np.zeros(N)
    dirn = np.tile(np.array([0.0, 0.0, 1.0]), (N, 1))
    upruned = np.full(N, -np.inf)
    first = True
    for _level in range(max_levels):
        if pose.size == 0:
            break
        Cc = C[pose]                                                        # (n, 3, m)
        if _DEBUG: print("level", _level, pose.size / N)
        loc = np.empty((pose.size, 9, 3))
        loc[..., 0] = x0[:, None] + w * _GX
        loc[..., 1] = y0[:, None] + w * _GY
        loc[..., 2] = 1.0
        P = np.take_along_axis(loc, _PERM[face][:, None, :], axis=2)       # (n, 9, 3)
        hv = lay.h(np.matmul(P, Cc))                                        # (n, 9)
        pn = np.sqrt((loc ** 2).sum(-1))
        lv = hv / pn                                                        # h at unit directions (F1)
        # best grid direction per pose; ascent (F2, F3) where it beats the current lower bound
        k = np.argmax(lv, axis=1)
        cell_best = lv[np.arange(pose.size), k]
        pbest = _segmax(cell_best, pose, N)
        cand = np.flatnonzero((cell_best >= pbest[pose]) & (cell_best > lower[pose]))
        if cand.size:
            keep = np.r_[True, pose[cand][1:] != pose[cand][:-1]]
            cand = cand[keep]
            ps = pose[cand]
            u0 = P[cand, k[cand]] / pn[cand, k[cand], None]
            u1, l1 = _ascend(lay, C[ps], u0, ascent if first else max(2, ascent // 4))
            better = l1 > lower[ps]
            lower[ps[better]] = l1[better]
            dirn[ps[better]] = u1[better]
        first = False
        # children and their bounds (F4)
        h4 = hv[:, _CORNERS]                                                # (n, 4 children, 4 corners)
        cx = x0[:, None] + w * (_CHILD[:, 0] + 0.5) / 2.0                   # (n, 4)
        cy = y0[:, None] + w * (_CHILD[:, 1] + 0.5) / 2.0
        lc = loc[:, _CORNERS]                                               # (n, 4, 4, 3)
        dots = lc[..., 0] * cx[..., None] + lc[..., 1] * cy[..., None] + 1.0
        cnorm = np.sqrt(cx ** 2 + cy ** 2 + 1.0)
        ub = (h4 / dots).max(-1) * cnorm * (1.0 + ROUND)                    # (n, 4)
        live = ub > lower[pose, None] * (1.0 + gap)
        cpose = np.broadcast_to(pose[:, None], ub.shape)
        dead = ~live
        upruned = np.maximum(upruned, _segmax(ub[dead], cpose[dead], N))
        x0 = (x0[:, None] + w / 2.0 * _CHILD[:, 0])[live]
        y0 = (y0[:, None] + w / 2.0 * _CHILD[:, 1])[live]
        face = np.broadcast_to(face[:, None], ub.shape)[live]
        ulive = ub[live]
        pose = cpose[live]
        w = w / 2.0
    upper = np.maximum(upruned, _segmax(ulive, pose, N)) if pose.size else upruned
    return upper, dirn


def max_norm(blocks, *, gap: float = 1e-3, max_levels: int = 14, ascent: int = 20) -> MaxNorm:
    """Certified ``R = max_{x in S} |x|`` for ``S = sum_j A_j B_j`` at every pose (module docstring, F1-F6).

    ``blocks``: list of arrays ``(..., 3, d_j)`` (leading shapes broadcast together; the results have the
    broadcast shape ``(...)``). When every block is a segment the vertex enumeration (F6) gives ``R`` exactly
    (``upper == lower``, ``exact``); otherwise the branch and bound over the cube's faces stops when
    ``upper <= lower * (1 + gap)`` or after ``max_levels`` subdivisions (``certified`` False, bounds valid).
    The lower bound is ``|point|`` with ``point = sum_j A_j x_j`` for the returned configuration.

    >>> ball = np.eye(3)[None]                  # unit ball
    >>> seg = np.array([[[0.0], [0.0], [0.5]]])  # segment of half-length 0.5 along z
    >>> r = max_norm([ball, seg])
    >>> bool(r.lower[0] <= 1.5 <= r.upper[0] <= 1.5 * (1 + 1e-3)), bool(r.certified[0])
    (True, True)
    >>> z = max_norm([np.array([[[1.0], [0.0], [0.0]]]), np.array([[[0.0], [2.0], [0.0]]])])
    >>> round(float(z.upper[0]) ** 2, 12), bool(z.exact[0])
    (5.0, True)
    """
    lead, flat = _prepare(blocks)
    N = flat[0].shape[0]
    lay = _Layout(flat)
    C = lay.C
    m = C.shape[-1]
    X = np.zeros((N, m))
    direction = np.zeros((N, 3))
    upper = np.zeros(N)
    exact = lay.n2 == 0 and lay.n3 == 0
    for a in range(0, N, _CHUNK):
        b = min(N, a + _CHUNK)
        Cc = C[a:b]
        if exact:
            G = Cc.transpose(0, 2, 1)
            S = _polish_signs(_zonotope(G), G)
            X[a:b] = S
            v = np.einsum("ns,nsc->nc", S, G)
            vn = np.sqrt((v ** 2).sum(-1))
            direction[a:b] = np.where(vn[:, None] > 0, v / np.where(vn > 0, vn, 1.0)[:, None], [0.0, 0.0, 1.0])
        else:
            up, u = _branch_and_bound(lay, Cc, gap, max_levels, ascent)
            upper[a:b] = up
            direction[a:b] = u
            X[a:b] = lay.unit_config(np.einsum("nc,ncm->nm", u, Cc))
    point = np.einsum("ncm,nm->nc", C, X)
    lower = np.sqrt((point ** 2).sum(-1))
    if exact:
        upper = lower.copy()
    else:
        upper = np.maximum(upper, lower)
    certified = (upper - lower) <= gap * lower if not exact else np.ones(N, dtype=bool)
    config = [x.reshape(lead + (x.shape[-1],)) for x in lay.split(X)]
    return MaxNorm(upper=upper.reshape(lead), lower=lower.reshape(lead),
                   direction=direction.reshape(lead + (3,)), point=point.reshape(lead + (3,)),
                   configuration=config, certified=certified.reshape(lead),
                   exact=np.full(lead, exact, dtype=bool))
