"""The largest norm of a Minkowski sum of segments, discs and ellipsoids in 3D, certified, over many poses.

The set
-------
At each pose the error set is ``S = sum_j A_j B_j``: block ``j`` is a matrix ``A_j`` of shape ``(3, d_j)``,
``d_j`` in {1, 2, 3}, applied to the unit ball ``B_j`` of ``R^{d_j}`` (a segment ``{s a : |s| <= 1}`` for
``d = 1``, an elliptic disc for ``d = 2``, an ellipsoid for ``d = 3``; any of them may be degenerate). Its
support function is ``h(u) = max_{x in S} u.x = sum_j |A_j^T u|`` and the quantity sought is

    R = max_{x in S} |x| = max_{|u| = 1} h(u)

(``|x| = max_{|u|=1} u.x``; exchange the two maxima). ``S`` is centrally symmetric, so ``h(-u) = h(u)``.

Method
------
Balls are taken out (F8). If the rest are segments, the vertices of the zonotope are enumerated (F6): exact.
Otherwise, per chunk of poses, a branch and bound over the sphere: the cells are the three faces
``x_a = +1`` of the cube ``[-1, 1]^3`` (F5), each split 2x2 at every level; ``h`` is evaluated on each live
cell's 3x3 grid (its 4 corners are known from the level above), which gives the 4 children's bounds (F4,
F7) and lower bounds at the grid directions (F1); from the best grid direction of each pose whose lower
bound it beats, a few steps of the ascent (F3) give the lower bound ``|g(u)|`` (F2). A child whose bound is
at most ``lower (1 + gap)`` is pruned (its bound kept in the pose's running maximum); the upper bound is
the maximum over pruned and still-live cells (F5). All poses and all their live cells sit in flat arrays
(a loop over the levels only); after ``max_levels`` the bounds stay valid and ``certified`` says whether the
gap is reached. Finally ``u = point/|point|`` and every block's unit-ball point is taken at ``u`` (this
only increases ``|point|``, F3).

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
     ``p_1..p_4``. Let ``u0`` be a unit vector with ``p_k.u0 > 0`` (any point of the cell: the corners of
     a dyadic square inside ``[-1, 0]^2`` or ``[0, 1]^2`` have ``p_k.p_l >= 1``). Every unit
     ``u`` of the cell is ``q/|q|`` for a ``q`` of the quadrilateral ``conv{q_k}``, ``q_k = p_k/(p_k.u0)``
     (the cone over Q cut by the plane ``{x.u0 = 1}``; central projection maps segments to segments), and
     ``|q| >= q.u0 = 1``. As ``h`` is convex, positively homogeneous and >= 0:

         h(u) = h(q)/|q| <= h(q) <= max_k h(q_k) = max_k h(p_k) / (p_k.u0).

     Since ``h(q_k) = h(p_k/|p_k|) / cos(p_k, u0)``, the bound is at most ``max_cell h / cos(rho)``
     (``rho`` the cell's angular radius): a relative excess ``rho^2/2``, second order, so the cells around
     the optimum need only ``rho ~ sqrt(2 gap)`` (about 5 levels for ``gap = 1e-3``). The bound is taken
     for two ``u0`` (the centre, and halfway to the corner of largest ``h``) and the smaller kept: a
     third fewer cells where ``h`` slopes across the cell.

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
     best candidate is ``R`` exactly: ``O(s^3)`` operations per pose for ``s`` generators. Ties are
     decided on the cosine ``|a_j.n| / (|a_j| |n|) <= 1e-10`` (rounding of exactly coplanar data); the
     lower bound is a point of ``S`` whatever the decision.

(F8) *Balls come out exactly*: a block with ``A A^T = r^2 I`` is the ball ``r B``, and for
     ``S = r B + S'``, ``R = r + R'``: ``|x' + r b| <= R' + r``, with equality at ``x'`` farthest in ``S'``
     and ``b = x'/|x'|``. Such blocks (tested at ``1e-12``; the upper bound uses
     ``sqrt(r^2 + ||A A^T - r^2 I||_F) >= ||A||_2``) are removed before the search and added back along
     the final direction, so balls and segments together are solved exactly (F6).

(F7) *Rounding*: the cells' corner values are computed in floating point of unit roundoff ``eps``
     (float32, ``eps = 2^-24``, when ``gap >= 1e-4``, else float64) at corners ``p = (x, y, 1)`` (permuted)
     whose coordinates are dyadic, hence exact. Each product ``Y = p^T C`` is off by at most
     ``gamma_5 sum_c |p_c| |C_c,col|`` (``gamma_n = n eps / (1 - n eps)``; the rounding of C included),
     so a block's ``|A_j^T p|`` by at most ``gamma_5 |p| ||A_j||_F`` (triangle and Cauchy-Schwarz
     inequalities), and the sums of ``m`` positive terms and the square roots add a relative
     ``gamma_(m+6)``; the bound (F4) uses ``h_hat (1 + gamma_(m+6)) + gamma_5 (1 + gamma_(m+6)) |p|
     sum_j ||A_j||_F``, never below the exact ``h(p)``. The lower bound (F2) is recomputed in float64 from
     the columns ``A_j`` (never from ``A_j A_j^T``, whose square root loses half the digits near a null
     direction): ``|point|`` is exact up to the float64 rounding of one 3-vector's norm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError

#: Gaps from which the cells are evaluated in float32 (F7: its rounding widens the bounds by a relative
#: ``(m + 6) 2^-24 + 9 2^-24 sum_j ||A_j||_F / R``, about 3e-6 for 6 ellipsoids and 12 segments).
_FLOAT32_GAP = 1e-4
#: Relative tolerance under which ``a_j.(a_i x a_k)`` counts as zero (coplanar generators).
_TIE = 1e-10
#: Poses processed at once (bounds the memory of the flat arrays of cells).
_CHUNK = 1 << 11
_ZCHUNK = 1 << 9
#: Zonotopes of at most this many generators are solved by enumerating their sign vectors (F6), in chunks of
#: ``_ECHUNK`` poses: ``2^(s-1)`` candidates in one matrix product beat the pair construction up to about 8.
_ENUMERATE = 8
_ECHUNK = 1 << 13
#: Live cells of one chunk refined at once, at most (more are split between poses: bounded memory).
_MAX_CELLS = 1 << 17


@dataclass(frozen=True)
class MaxNorm:
    """Certified bounds on ``R = max_{x in S} |x|`` at each pose (shapes: the blocks' leading shape ``(...)``).

    * ``upper``: never below ``R`` (rounding accounted for, F7); ``lower``: ``= |point| <= R``;
    * ``direction``: unit ``u*`` at which the configuration attains ``h`` (``(..., 3)``);
    * ``point``: ``sum_j A_j x_j`` (``(..., 3)``), ``x_j = configuration[j]`` (``(..., d_j)``, ``|x_j| <= 1``);
    * ``certified``: ``upper - lower <= gap * lower``; ``exact``: every block a segment or a ball (F6, F8),
      ``upper == lower`` up to rounding.
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
    """All blocks' columns side by side, ``C (N, 3, ncol)``: the segments, then the discs' first columns, their
    second columns, then the ellipsoids' first, second and third columns (each group contiguous)."""

    def __init__(self, flat: list[np.ndarray]):
        self.dims = [b.shape[-1] for b in flat]
        seg = [j for j, d in enumerate(self.dims) if d == 1]
        disc = [j for j, d in enumerate(self.dims) if d == 2]
        ell = [j for j, d in enumerate(self.dims) if d == 3]
        self.n1, self.n2, self.n3 = len(seg), len(disc), len(ell)
        self.cols = [(j, 0) for j in seg] + [(j, c) for c in range(2) for j in disc] \
            + [(j, c) for c in range(3) for j in ell]
        self.flat = flat
        self.s2 = self.n1 + 2 * self.n2  # end of the disc columns

    def columns(self, a: int = 0, b: int | None = None) -> np.ndarray:
        """The columns ``C (b - a, 3, ncol)`` of the poses ``a:b`` (built per chunk: no copy of all poses)."""
        return np.stack([self.flat[j][a:b, :, c] for j, c in self.cols], axis=-1)

    def _groups(self):
        n1, n2, n3, s2 = self.n1, self.n2, self.n3, self.s2
        if n2:
            yield n1, n2, 2
        if n3:
            yield s2, n3, 3

    def h(self, Y: np.ndarray) -> np.ndarray:
        """``h`` from the products ``Y = p^T C`` (``(..., ncol)``)."""
        out = np.abs(Y[..., :self.n1]).sum(-1)
        for lo, n, d in self._groups():
            q = Y[..., lo:lo + n] ** 2
            for c in range(1, d):
                q += Y[..., lo + c * n:lo + (c + 1) * n] ** 2
            out += np.sqrt(q).sum(-1)
        return out

    def h0(self, Y: np.ndarray) -> np.ndarray:
        """``h`` from the products laid out with the columns first, ``Y (ncol, ...)``."""
        out = np.abs(Y[:self.n1]).sum(0)
        for lo, n, d in self._groups():
            q = Y[lo:lo + n] ** 2
            for c in range(1, d):
                q += Y[lo + c * n:lo + (c + 1) * n] ** 2
            out += np.sqrt(q, out=q).sum(0)
        return out

    def unit_config0(self, Y: np.ndarray) -> np.ndarray:
        """:meth:`unit_config` for products laid out with the columns first, ``Y (ncol, n)``."""
        n1 = self.n1
        X = np.empty_like(Y)
        X[:n1] = np.where(Y[:n1] >= 0, 1.0, -1.0)
        for lo, n, d in self._groups():
            nrm = Y[lo:lo + n] ** 2
            for c in range(1, d):
                nrm += Y[lo + c * n:lo + (c + 1) * n] ** 2
            np.sqrt(nrm, out=nrm)
            inv = np.where(nrm > 0, 1.0 / np.where(nrm > 0, nrm, 1.0), 0.0)
            for c in range(d):
                X[lo + c * n:lo + (c + 1) * n] = Y[lo + c * n:lo + (c + 1) * n] * inv
        return X

    def unit_config(self, Y: np.ndarray) -> np.ndarray:
        """The unit-ball points ``x`` attaining ``h`` (laid out like the columns), ``0`` at a null block."""
        n1 = self.n1
        X = np.empty_like(Y)
        X[..., :n1] = np.where(Y[..., :n1] >= 0, 1.0, -1.0)
        for lo, n, d in self._groups():
            q = Y[..., lo:lo + d * n]
            nrm = np.sqrt(sum(q[..., c * n:(c + 1) * n] ** 2 for c in range(d)))
            inv = np.where(nrm > 0, 1.0 / np.where(nrm > 0, nrm, 1.0), 0.0)
            X[..., lo:lo + d * n] = q * np.tile(inv, d)
        return X

    def split(self, X: np.ndarray) -> list[np.ndarray]:
        """Configuration laid out like the columns ``(N, ncol)`` back to the blocks: list of ``(N, d_j)``."""
        out = [np.empty((X.shape[0], d)) for d in self.dims]
        for k, (j, c) in enumerate(self.cols):
            out[j][:, c] = X[:, k]
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
    Y = np.einsum("nc,ncm->nm", uu, lay.columns())
    return lay.h(Y).reshape(lead)


# ----------------------------------------------------------------------------------------------- zonotope


def _zonotope(G: np.ndarray) -> np.ndarray:
    """Exact maximizing sign vector ``(N, s)`` of ``|sum_j s_j g_j|`` for generators ``G (N, s, 3)`` (F6).

    Candidates, each a sign vector (so a point of S): the rank-1 one ``sign(g_j . g_max)``, and for every
    pair ``i < k`` and ``(s_i, s_k)`` the vertex at the corner ``n = g_i x g_k`` (ties by ``sign(g_j . w)``).
    Arrays are laid out with the poses last, so every operation runs along the poses.

    >>> G = np.array([[[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [1.0, 1.0, 0.0]]])   # a hexagon in the xy-plane
    >>> _zonotope(G)                                                            # |(2, 3, 0)|^2 = 13
    array([[1., 1., 1.]])
    """
    N, s, _ = G.shape
    Gt = np.ascontiguousarray(G.transpose(2, 1, 0))                  # (3, s, N)
    gn = np.sqrt((Gt ** 2).sum(0))                                  # (s, N)
    # rank-1 candidate: aligned with the largest generator
    m = np.argmax(gn, axis=0)
    am = G[np.arange(N), m]                                         # (N, 3)
    best_S = np.where(np.einsum("nsc,nc->ns", G, am) >= 0, 1.0, -1.0)
    v = np.einsum("ns,nsc->nc", best_S, G)
    best = (v ** 2).sum(-1)
    if s < 2:
        return best_S
    I, K = np.triu_indices(s, 1)
    p = I.size
    notown = np.ones((p, s, 1))
    notown[np.arange(p), I] = 0.0
    notown[np.arange(p), K] = 0.0
    Gh = Gt / np.where(gn > 0, gn, 1.0)                              # unit generators (0 for a zero one)
    ai, ak = Gt[:, I], Gt[:, K]                                     # (3, p, N)
    n = np.stack([ai[1] * ak[2] - ai[2] * ak[1], ai[2] * ak[0] - ai[0] * ak[2], ai[0] * ak[1] - ai[1] * ak[0]])
    nn = np.sqrt((n ** 2).sum(0))                                   # (p, N)
    nh = n / np.where(nn > 0, nn, 1.0)
    T = nh[0][:, None] * Gh[0][None]                                # (p, s, N): cosines to the normal
    T += nh[1][:, None] * Gh[1][None]
    T += nh[2][:, None] * Gh[2][None]
    S0 = np.sign(T)
    S0 *= np.abs(T) > _TIE                                          # ties (coplanar with the pair) -> 0
    S0 *= notown                                                    # the pair's own signs come below
    zeros = (S0 == 0).sum(1)                                        # (p, N): 2 + the ties
    v0 = np.stack([(S0 * Gt[c][None]).sum(1) for c in range(3)])    # (3, p, N)
    ci = (v0 * ai).sum(0)
    ck = (v0 * ak).sum(0)
    gik = (ai * ak).sum(0)
    base = (v0 ** 2).sum(0) + (ai ** 2).sum(0) + (ak ** 2).sum(0)
    sig = np.array([[1.0, 1.0], [1.0, -1.0], [-1.0, 1.0], [-1.0, -1.0]])
    vals = base[None] + 2.0 * (sig[:, 0, None, None] * ci[None] + sig[:, 1, None, None] * ck[None]
                               + (sig[:, 0] * sig[:, 1])[:, None, None] * gik[None])   # (4, p, N)
    # pairs with ties besides their own: full candidates with the tie rule sign(g_j . w)
    hp, hn = np.nonzero(zeros > 2)
    tie_of = lambda pp, nn_: (np.abs(T[pp, :, nn_]) <= _TIE) & (notown[pp, :, 0] > 0)  # noqa: E731
    if hp.size:
        n_h, ai_h, ak_h = n[:, hp, hn].T, ai[:, hp, hn].T, ak[:, hp, hn].T
        w1, w2 = np.cross(ak_h, n_h), np.cross(n_h, ai_h)
        Gh_ = G[hn]                                                 # (h, s, 3)
        tie_h = tie_of(hp, hn)
        for q in range(4):
            w = sig[q, 0] * w1 + sig[q, 1] * w2
            st = np.where(tie_h, np.sign(np.einsum("hsc,hc->hs", Gh_, w)), 0.0)
            vq = v0[:, hp, hn].T + sig[q, 0] * ai_h + sig[q, 1] * ak_h + np.einsum("hs,hsc->hc", st, Gh_)
            vals[q, hp, hn] = (vq ** 2).sum(-1)
    flat = vals.reshape(4 * p, N)
    arg = np.argmax(flat, axis=0)
    rows = np.arange(N)
    val = flat[arg, rows]
    bq, bp = np.divmod(arg, p)
    S = S0[bp, :, rows].copy()                                      # (N, s)
    S[rows, I[bp]] = sig[bq, 0]
    S[rows, K[bp]] = sig[bq, 1]
    tb = tie_of(bp, rows)
    if tb.any():
        nb, aib, akb = n[:, bp, rows].T, ai[:, bp, rows].T, ak[:, bp, rows].T
        w = sig[bq, 0, None] * np.cross(akb, nb) + sig[bq, 1, None] * np.cross(nb, aib)
        S = np.where(tb, np.sign(np.einsum("nsc,nc->ns", G, w)), S)
    use = val > best
    return np.where(use[:, None], S, best_S)


def _sign_vectors(s: int) -> np.ndarray:
    """The ``2^(s-1)`` sign vectors ``(2^(s-1), s)`` with a first sign ``+1`` (``-x`` has the same norm)."""
    k = np.arange(1 << (s - 1))[:, None]
    rest = 1.0 - 2.0 * ((k >> np.arange(s - 1)[None]) & 1)
    return np.concatenate([np.ones((k.size, 1)), rest], axis=1)


def _enumerate_signs(G: np.ndarray) -> np.ndarray:
    """Exact maximizing sign vector ``(N, s)`` of ``|sum_j s_j g_j|`` for few generators ``G (N, s, 3)``: every
    vertex of the zonotope is ``sum_j s_j g_j`` for a sign vector (F6), so the largest of the ``2^(s-1)``
    candidates (up to the symmetry ``x -> -x``), computed as one matrix product, is the maximum.

    >>> G = np.array([[[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [1.0, 1.0, 0.0]]])   # a hexagon in the xy-plane
    >>> _enumerate_signs(G)                                                     # |(2, 3, 0)|^2 = 13
    array([[1., 1., 1.]])
    """
    N, s, _ = G.shape
    S = _sign_vectors(s)
    V = (np.ascontiguousarray(G.transpose(0, 2, 1)).reshape(N * 3, s) @ S.T).reshape(N, 3, S.shape[0])
    return S[np.argmax(np.einsum("nck,nck->nk", V, V), axis=1)]


def _polish_signs(S: np.ndarray, G: np.ndarray) -> np.ndarray:
    """Replace the zero signs one by one by ``sign(v.g_j)`` (never decreases ``|v|``: ``|v+-g|^2 >= |v|^2``).

    >>> _polish_signs(np.array([[1.0, 0.0]]), np.array([[[1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]]))
    array([[1., 1.]])
    """
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


def _ascend(lay: _Layout, Ct: np.ndarray, u: np.ndarray, iters: int) -> tuple[np.ndarray, np.ndarray]:
    """``iters`` steps of ``u <- g(u)/|g(u)|`` (F3) from ``u (3, n)`` with the columns ``Ct (3, m, n)``;
    returns ``(u, |g(u)|)`` of the last ``u`` (``|g(u)| >= h(u)``, F2).

    >>> lay = _Layout([np.diag([1.0, 2.0, 3.0])[None]])                    # an ellipsoid: R = 3
    >>> u, g = _ascend(lay, lay.columns().transpose(1, 2, 0), np.array([[0.6], [0.0], [0.8]]), 30)
    >>> round(float(g[0]), 9)
    3.0
    """
    for it in range(iters + 1):
        Y = Ct[0] * u[0]
        Y += Ct[1] * u[1]
        Y += Ct[2] * u[2]
        X = lay.unit_config0(Y)
        g = np.stack([(Ct[c] * X).sum(0) for c in range(3)])
        gn = np.sqrt((g ** 2).sum(0))
        if it == iters:
            return u, gn
        ok = gn > 0
        u = np.where(ok, g / np.where(ok, gn, 1.0), u)
    raise AssertionError  # pragma: no cover


def _segmax(values: np.ndarray, pose: np.ndarray, n: int) -> np.ndarray:
    """Max of ``values`` per pose (``pose`` sorted), ``-inf`` for poses absent.

    >>> _segmax(np.array([1.0, 3.0, 2.0]), np.array([0, 0, 2]), 3)
    array([  3., -inf,   2.])
    """
    out = np.full(n, -np.inf)
    if values.size:
        starts = np.flatnonzero(np.r_[True, pose[1:] != pose[:-1]])
        out[pose[starts]] = np.maximum.reduceat(values, starts)
    return out


# face a: the point (x, y, 1) of the face's square goes to coordinates  [a] = 1, [a+1] = x, [a+2] = y;
# _ROWS[a] lists the rows of C multiplying x, y and 1
_ROWS = np.array([[1, 2, 0], [2, 0, 1], [0, 1, 2]])
_G3 = np.array([0.0, 0.5, 1.0])
_GX = np.repeat(_G3, 3)          # grid point k = 3*i + j at (x0 + w*_G3[i], y0 + w*_G3[j])
_GY = np.tile(_G3, 3)
_OLD = np.array([0, 2, 6, 8])    # the cell's corners (known from the level above)
_NEW = np.array([1, 3, 4, 5, 7])
_CHILD = np.array([[0, 0], [0, 1], [1, 0], [1, 1]])
_CORNERS = np.array([[3 * (i + a) + (j + b) for a in (0, 1) for b in (0, 1)] for i, j in _CHILD])  # (4, 4)


def _h_grid(lay: _Layout, R: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``h(p)`` at ``p = x e_x' + y e_y' + e_1'`` (``x, y (n, k)``) with the rows of C in the face's order,
    laid out columns first ``R (3, m, n)`` (so every operation runs along the cells)."""
    out = np.empty(x.shape)
    x = x.astype(R.dtype)
    y = y.astype(R.dtype)
    for i in range(x.shape[1]):
        Y = R[0] * x[:, i]
        Y += R[1] * y[:, i]
        Y += R[2]
        out[:, i] = lay.h0(Y)
    return out


def _branch_and_bound(lay: _Layout, C: np.ndarray, gap: float, max_levels: int, ascent: int):
    """Branch and bound over the three cube faces for one chunk of poses (F1-F5, F7).

    Cells are flat arrays (pose, face, corner ``x0, y0``, width ``w``), sorted by pose; per-cell values are
    laid out with the cells last (``(9, n)`` grid values, ``(4, n)`` children) so numpy runs along the cells.
    """
    N, _, m = C.shape
    # rows of C multiplying (x, y, 1) on each face, columns first, cells (pose, face) last: (3, m, 3 N)
    dtype = np.float32 if gap >= _FLOAT32_GAP else np.float64
    CF = np.ascontiguousarray(C[:, _ROWS].transpose(2, 3, 0, 1).reshape(3, m, 3 * N), dtype=dtype)
    CT = np.ascontiguousarray(C.transpose(1, 2, 0))                         # (3, m, N) for the ascent
    # rounding of the corner values (F7): h <= h_hat (1 + g1) + g2 |p| F
    eps = float(np.finfo(dtype).eps) / 2.0
    gam = lambda k: k * eps / (1.0 - k * eps)  # noqa: E731
    g1 = gam(m + 6)
    g2 = gam(5) * (1.0 + g1)
    F = lay.h0(np.sqrt((C ** 2).sum(1)).T)                                  # sum_j ||A_j||_F, (N,)
    pose = np.repeat(np.arange(N), 3)
    face = np.tile(np.arange(3), N)
    x0 = np.full(pose.size, -1.0)
    y0 = np.full(pose.size, -1.0)
    w = 2.0
    hc = _h_grid(lay, CF, x0[:, None] + 2.0 * _GX[_OLD], y0[:, None] + 2.0 * _GY[_OLD]).T   # (4, n)
    lower = np.zeros(N)
    dirn = np.tile(np.array([[0.0], [0.0], [1.0]]), (1, N))               # (3, N)
    upruned = np.full(N, -np.inf)
    def run(pose, face, x0, y0, w, hc, ulive, level):
        """Refine the cells from ``level`` on; split them (between poses) when they exceed ``_MAX_CELLS``."""
        while level < max_levels and pose.size:
            if pose.size > _MAX_CELLS and pose[0] != pose[-1]:
                cut = np.searchsorted(pose, pose[pose.size // 2])
                cut = cut if cut > 0 else np.searchsorted(pose, pose[0], side="right")
                for sl in (slice(0, cut), slice(cut, None)):
                    run(pose[sl], face[sl], x0[sl], y0[sl], w, hc[:, sl], ulive[sl], level)
                return
            n = pose.size
            xg = x0 + w * _GX[:, None]                                          # (9, n)
            yg = y0 + w * _GY[:, None]
            hv = np.empty((9, n))
            hv[_OLD] = hc
            hv[_NEW] = _h_grid(lay, np.take(CF, 3 * pose + face, axis=2), xg[_NEW].T, yg[_NEW].T).T
            pn = np.sqrt(xg ** 2 + yg ** 2 + 1.0)
            lv = hv / pn                                                        # h at unit directions (F1)
            # best grid direction per pose; ascent (F2, F3) where it beats the current lower bound
            cell_best = lv.max(0)
            pbest = _segmax(cell_best, pose, N)
            cand = np.flatnonzero((cell_best >= pbest[pose]) & (cell_best > lower[pose]))
            if cand.size:
                keep = np.r_[True, pose[cand][1:] != pose[cand][:-1]]
                cand = cand[keep]
                ps = pose[cand]
                kc = np.argmax(lv[:, cand], axis=0)
                loc = np.stack([xg[kc, cand], yg[kc, cand], np.ones(cand.size)]) / pn[kc, cand]
                u0 = np.empty_like(loc)
                u0[_ROWS[face[cand]].T, np.arange(cand.size)] = loc
                u1, l1 = _ascend(lay, np.take(CT, ps, axis=2), u0, ascent if level == 0 else max(2, ascent // 4))
                better = l1 > lower[ps]
                lower[ps[better]] = l1[better]
                dirn[:, ps[better]] = u1[:, better]
            # children and their bounds (F4, F7): ub = max_k h+(p_k) |e| / (p_k . e) for two choices of the plane's
            # normal e: the child's centre, and halfway from it to the corner of largest h (better where h slopes)
            hup = hv * (1.0 + g1)
            hup += (g2 * F[pose]) * pn                                          # >= h at the grid points
            H = hup[_CORNERS]                                                   # (4 children, 4 corners, n)
            XK = xg[_CORNERS]
            YK = yg[_CORNERS]
            cx = x0 + (w * (_CHILD[:, 0] + 0.5) / 2.0)[:, None]                 # (4, n) centres
            cy = y0 + (w * (_CHILD[:, 1] + 0.5) / 2.0)[:, None]
            ub = (H / (XK * cx[:, None] + YK * cy[:, None] + 1.0)).max(1) * np.sqrt(cx ** 2 + cy ** 2 + 1.0)
            L4 = lv[_CORNERS]
            best = L4[:, 0].copy()
            kb = np.zeros((4, 1, n), dtype=np.intp)                             # corner of largest h
            for c in range(1, 4):
                gt = L4[:, c] > best
                np.maximum(best, L4[:, c], out=best)
                kb[:, 0][gt] = c
            ex = 0.5 * (cx + np.take_along_axis(XK, kb, axis=1)[:, 0])
            ey = 0.5 * (cy + np.take_along_axis(YK, kb, axis=1)[:, 0])
            ub1 = (H / (XK * ex[:, None] + YK * ey[:, None] + 1.0)).max(1) * np.sqrt(ex ** 2 + ey ** 2 + 1.0)
            np.minimum(ub, ub1, out=ub)
            ub *= 1.0 + 8 * 2.0 ** -53
            ub = ub.T                                                           # (n, 4): children by pose
            live = ub > (lower[pose] * ((1.0 + gap) * (1.0 - 1e-12)))[:, None]
            cpose = np.broadcast_to(pose[:, None], ub.shape)
            dead = ~live
            np.maximum(upruned, _segmax(ub[dead], cpose[dead], N), out=upruned)
            x0 = (x0[:, None] + w / 2.0 * _CHILD[:, 0])[live]
            y0 = (y0[:, None] + w / 2.0 * _CHILD[:, 1])[live]
            face = np.broadcast_to(face[:, None], ub.shape)[live]
            hc = hv[_CORNERS].transpose(2, 0, 1)[live].T                       # (4 corners, n live)
            ulive = ub[live]
            pose = cpose[live]
            w = w / 2.0
            level += 1

        np.maximum(upruned, _segmax(ulive, pose, N), out=upruned)

    run(pose, face, x0, y0, w, hc, np.full(pose.size, np.inf), 0)
    del run   # the recursive closure refers to itself: without this its temporaries wait for the cycle collector
    return upruned, dirn.T


def max_norm(blocks, *, gap: float = 1e-3, max_levels: int = 14, ascent: int = 10) -> MaxNorm:
    """Certified ``R = max_{x in S} |x|`` for ``S = sum_j A_j B_j`` at every pose (module docstring, F1-F8).

    ``blocks``: list of arrays ``(..., 3, d_j)`` (leading shapes broadcast together; the results have the
    broadcast shape ``(...)``). When every block is a segment or a ball the vertex enumeration (F6, F8)
    gives ``R`` exactly (``upper == lower`` up to rounding, ``exact``); otherwise the branch and bound over
    the cube's faces stops when ``upper <= lower * (1 + gap)`` or after ``max_levels`` subdivisions
    (``certified`` False, bounds still valid). ``ascent``: steps of (F3) from the first grid's best
    direction (a quarter of them at later levels).
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
    # balls (A A^T = r^2 I up to 1e-12 at every pose) come out of the search exactly (F8)
    radius, radius_up = {}, np.zeros(N)
    for j, A in enumerate(flat):
        if A.shape[-1] == 3:
            M = np.matmul(A, A.transpose(0, 2, 1))
            r2 = np.trace(M, axis1=1, axis2=2) / 3.0
            dev = np.sqrt(((M - r2[:, None, None] * np.eye(3)) ** 2).sum((1, 2)))
            if np.all(dev <= 1e-12 * r2):
                radius[j] = np.sqrt(r2)
                radius_up += np.sqrt(r2 + dev) * (1.0 + 2.0 ** -50)      # >= the largest singular value
    rest = [j for j in range(len(flat)) if j not in radius]
    exact = all(flat[j].shape[-1] == 1 for j in rest)
    upper = np.zeros(N)
    u = np.tile([0.0, 0.0, 1.0], (N, 1))
    config: list[np.ndarray] = [None] * len(flat)  # type: ignore[list-item]
    point = np.zeros((N, 3))
    if rest:
        lay = _Layout([flat[j] for j in rest])
        X = np.zeros((N, len(lay.cols)))
        few = exact and len(lay.cols) <= _ENUMERATE
        chunk = _ECHUNK if few else _ZCHUNK if exact else _CHUNK
        for a in range(0, N, chunk):
            b = min(N, a + chunk)
            Cc = lay.columns(a, b)
            if exact:
                G = Cc.transpose(0, 2, 1)
                X[a:b] = _enumerate_signs(G) if few else _polish_signs(_zonotope(G), G)
            else:
                upper[a:b], ua = _branch_and_bound(lay, Cc, gap, max_levels, ascent)
                X[a:b] = lay.unit_config(np.einsum("nc,ncm->nm", ua, Cc))
            pt = np.einsum("ncm,nm->nc", Cc, X[a:b])
            pn = np.sqrt((pt ** 2).sum(-1))
            # final direction u = point / |point|: h(u) >= |point| (F3), and every block attains h at u
            u[a:b] = np.where(pn[:, None] > 0, pt / np.where(pn > 0, pn, 1.0)[:, None], u[a:b])
            if exact:
                upper[a:b] = pn
            else:
                X[a:b] = lay.unit_config(np.einsum("nc,ncm->nm", u[a:b], Cc))
                pt = np.einsum("ncm,nm->nc", Cc, X[a:b])
            point[a:b] = pt
        for j, x in zip(rest, lay.split(X)):
            config[j] = x
    for j, r in radius.items():
        x = np.einsum("ncd,nc->nd", flat[j], u) / np.where(r > 0, r, 1.0)[:, None]
        config[j] = np.where(r[:, None] > 0, x, 0.0)
        point = point + np.einsum("ncd,nd->nc", flat[j], config[j])
    lower = np.sqrt((point ** 2).sum(-1))
    upper = np.maximum(upper + radius_up, lower)
    certified = np.full(N, True) if exact else (upper - lower) <= gap * lower
    return MaxNorm(upper=upper.reshape(lead), lower=lower.reshape(lead),
                   direction=u.reshape(lead + (3,)), point=point.reshape(lead + (3,)),
                   configuration=[x.reshape(lead + (x.shape[-1],)) for x in config],
                   certified=certified.reshape(lead), exact=np.full(lead, exact, dtype=bool))
