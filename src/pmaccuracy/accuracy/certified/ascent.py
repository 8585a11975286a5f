"""The best feasible configuration: local ascent of the exact model from the first-order vertices (the
lower bound that states the gap)."""

from __future__ import annotations

import numpy as np

from .closure import _Model, _objective, _source_gradient, _take, _take_many, exact_change
from .error_set import QUANTITIES, argsupport, project, support


def _ascent(model: _Model, M: np.ndarray, sets, q: str, start: np.ndarray, maxiter: int) -> tuple[float, np.ndarray]:
    """Local ascent (SLSQP) of quantity ``q`` of the exact model of one pose from ``start`` ``(n,)`` over ``S``;
    returns the best feasible value found and its ``delta`` (the start's own value counts)."""
    from scipy.optimize import minimize

    n = model.n
    scale = np.zeros(n)
    for s in sets:
        if s.kind == "rhombus":
            scale[s.cols[0]], scale[s.cols[1]] = s.eps, 2 * s.eps / s.block_length
        else:
            scale[list(s.cols)] = s.eps
    dz0 = exact_change(model, M, start[None])[0]
    best_val = float(_objective(q, dz0)) if np.all(np.isfinite(dz0)) else -np.inf
    best = start.copy()
    row = None if q == "dp" else QUANTITIES.index(q)
    sign = 1.0 if row is None or not np.isfinite(best_val) else (1.0 if dz0[row] >= 0 else -1.0)

    def fun(u):
        d = u * scale
        dz, G = exact_change(model, M, d[None], gradient=True)
        dz, G = dz[0], G[0]
        if not np.all(np.isfinite(dz)):
            return 0.0, np.zeros(n)
        if row is None:
            p = dz[:2]
            norm = max(float(np.hypot(*p)), 1e-300)
            return -norm, -(p @ G[:2]) / norm * scale
        return -sign * float(dz[row]), -sign * G[row] * scale

    cons = []
    for s in sets:
        if s.kind == "disk":
            a, b = s.cols
            cons.append({"type": "ineq", "fun": lambda u, a=a, b=b: 1.0 - u[a] ** 2 - u[b] ** 2,
                         "jac": lambda u, a=a, b=b: np.eye(n)[a] * (-2 * u[a]) + np.eye(n)[b] * (-2 * u[b])})
        elif s.kind == "rhombus":
            a, b = s.cols
            for sa, sb in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
                g = np.zeros(n)
                g[a], g[b] = -sa, -sb
                cons.append({"type": "ineq", "fun": lambda u, g=g: 1.0 + g @ u, "jac": lambda u, g=g: g})
    with np.errstate(all="ignore"):
        res = minimize(fun, start / scale, jac=True, method="SLSQP", bounds=[(-1.0, 1.0)] * n, constraints=cons,
                       options={"maxiter": maxiter, "ftol": 1e-15})
    cand = project(sets, res.x * scale)
    dz = exact_change(model, M, cand[None])[0]
    if np.all(np.isfinite(dz)):
        val = float(_objective(q, dz))
        if val > best_val:
            best_val, best = val, cand
    return best_val, best


#: Directions sampled for the local maxima of the first-order ``|dp|`` (each then refined by a ternary search).
DP_DIRECTIONS = 240


def _first_order_starts(sets, M: np.ndarray, n_dp: int = 3) -> np.ndarray:
    """First-order worst vertices ``(4, n_dp, N, n)``: of dx, dy, dphi (signs of the rows of ``M``, as
    :func:`pmaccuracy.model.sources.worst_configuration`; repeated) and of ``|dp|`` (the vertices maximizing ``u . p``
    for the ``n_dp`` best local maxima over :data:`DP_DIRECTIONS` directions ``u`` of the support function: the nonlinear
    maximum may belong to a direction that is not the first-order best; each direction refined by a ternary
    search so that the best is the exact first-order maximizer)."""
    N = M.shape[0]
    starts = [np.repeat(argsupport(sets, M[:, j, :])[None], n_dp, axis=0) for j in range(3)]
    ang = np.linspace(0, 2 * np.pi, DP_DIRECTIONS, endpoint=False)
    rowmap = np.cos(ang)[:, None] * M[:, None, 0, :] + np.sin(ang)[:, None] * M[:, None, 1, :]  # (N, DP_DIRECTIONS, n)
    h = support(sets, rowmap)  # (N, DP_DIRECTIONS)
    peak = (h >= np.roll(h, 1, axis=-1)) & (h >= np.roll(h, -1, axis=-1))
    order = np.argsort(np.where(peak, -h, np.inf), axis=-1)[:, :n_dp]  # best local maxima first
    order = np.where(np.take_along_axis(peak, order, axis=-1), order, order[:, :1])  # fewer peaks: repeat the best
    dp_starts = []
    for k in range(n_dp):  # each peak's direction refined by a ternary search (the support is smooth between
        # vertex switches): the best one is then the exact first-order maximizer of |dp|
        a = ang[order[:, k]]
        lo, hi = a - 2 * np.pi / DP_DIRECTIONS, a + 2 * np.pi / DP_DIRECTIONS
        for _ in range(32):
            m1, m2 = lo + (hi - lo) / 3, hi - (hi - lo) / 3
            up = _support_at(sets, M, m1) < _support_at(sets, M, m2)
            lo, hi = np.where(up, m1, lo), np.where(up, hi, m2)
        mid = (lo + hi) / 2
        a = np.where(_support_at(sets, M, mid) >= h[np.arange(N), order[:, k]], mid, a)
        dp_starts.append(argsupport(sets, np.cos(a)[:, None] * M[:, 0, :] + np.sin(a)[:, None] * M[:, 1, :]))
    starts.append(np.stack(dp_starts))
    return np.stack(starts)


def _support_at(sets, M: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """``h_S(u . M_p)`` ``(N,)`` for the unit directions ``u = (cos angle, sin angle)`` ``(N,)`` of the position rows
    of ``M`` ``(N, 9, n)``."""
    return support(sets, np.cos(angle)[:, None] * M[:, 0, :] + np.sin(angle)[:, None] * M[:, 1, :])


def _objective_gradient(dz: np.ndarray, G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Values ``(4, ...)`` of |dx|, |dy|, |dphi|, |dp| at ``dz (4, ..., 9)`` (quantity q on slice q) and their
    gradients ``(4, ..., n)`` in ``delta`` from ``G = dDz/ddelta`` ``(4, ..., 9, n)``."""
    vals, grads = [], []
    for j in range(3):
        sgn = np.where(dz[j, ..., j] < 0, -1.0, 1.0)
        vals.append(np.abs(dz[j, ..., j]))
        grads.append(sgn[..., None] * G[j, ..., j, :])
    p = dz[3, ..., :2]
    norm = np.hypot(p[..., 0], p[..., 1])
    unit = p / np.where(norm > 0, norm, 1.0)[..., None]
    vals.append(norm)
    grads.append(np.einsum("...r,...rd->...d", unit, G[3, ..., :2, :]))
    return np.stack(vals), np.stack(grads)


def _row_objective(q: np.ndarray, dz: np.ndarray, G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Value and gradient in ``delta`` of quantity ``q`` (index into :data:`QUANTITIES`, broadcast to
    ``dz.shape[:-1]``) at ``dz (..., 9)`` with ``G = dDz/ddelta (..., 9, n)``: ``(...)``, ``(..., n)``."""
    q = np.broadcast_to(q, dz.shape[:-1])
    j = np.minimum(q, 2)
    row = np.take_along_axis(dz, j[..., None], axis=-1)[..., 0]
    grow = np.take_along_axis(G, j[..., None, None], axis=-2)[..., 0, :]
    sgn = np.where(row < 0, -1.0, 1.0)
    p = dz[..., :2]
    norm = np.hypot(p[..., 0], p[..., 1])
    unit = p / np.where(norm > 0, norm, 1.0)[..., None]
    gp = np.einsum("...r,...rd->...d", unit, G[..., :2, :])
    is_p = q == 3
    return np.where(is_p, norm, np.abs(row)), np.where(is_p[..., None], gp, sgn[..., None] * grow)


def _nonlinear(model: _Model, M: np.ndarray, sets, iterations: int = 30, polish: int = 0,
               ascend: bool | np.ndarray = True) -> tuple[dict, dict, dict]:
    """Best feasible exact values ``{q: (N,)}``, their ``delta`` ``{q: (N, n)}`` and the exact values at the
    first-order worst vertices ``{q: (N,)}`` (:func:`nonlinear_pose_errors`).

    The starts (each first-order worst vertex of dx, dy, dphi and the three of ``|dp|``, both signs: 12 rows per
    pose) are solved exactly in one batch; then, at the poses ``ascend`` (``(N,)`` mask or all/none), each row
    steps to the vertex maximizing its exact gradient's linear form while that increases its value, only the
    rows still increasing being solved again. Without the ascent the values are those of the best start (a
    feasible configuration too: still a lower bound of the maximum)."""
    N, n = M.shape[0], model.n
    if n == 0:
        z = {q: np.zeros(N) for q in QUANTITIES}
        return z, {q: np.zeros((N, 0)) for q in QUANTITIES}, dict(z)
    ascend = np.broadcast_to(np.asarray(ascend, dtype=bool), (N,))
    d0 = _first_order_starts(sets, M)  # (4, 3, N, n); the rows of dx, dy, dphi are repeated
    qidx = np.array([0, 0, 1, 1, 2, 2] + [3] * 6)
    cur = np.stack([sg * d0[q, 0] for q in range(3) for sg in (1, -1)]
                   + [sg * d0[3, k] for k in range(d0.shape[1]) for sg in (1, -1)])  # (12, N, n)
    dz = exact_change(model, M, cur)
    val = _row_objective(qidx[:, None], dz, np.zeros(dz.shape + (0,)))[0]  # values only: no gradient columns
    val = np.where(np.isfinite(val), val, -np.inf)
    at_start = val.copy()
    grad = np.zeros(cur.shape)
    active = np.isfinite(val) & ascend[None, :]
    if np.any(active):  # the exact gradients at the starts of the poses that ascend
        rr, kk = np.nonzero(active)
        grad[rr, kk] = _row_objective(qidx[rr], dz[rr, kk], _source_gradient(_take_many(model, kk), dz[rr, kk],
                                                                             cur[rr, kk]))[1]
    for _ in range(iterations):
        # successive linearization: the vertex maximizing the exact gradient's linear form over S
        rr, kk = np.nonzero(active)
        if not rr.size:
            break
        cand = argsupport(sets, grad[rr, kk])  # (B, n)
        dzc, Gc = exact_change(_take_many(model, kk), M[kk], cand, gradient=True)
        vc, gc = _row_objective(qidx[rr], dzc, Gc)
        better = np.isfinite(vc) & (vc > val[rr, kk] * (1 + 1e-15))
        active[rr, kk] = better
        rb, kb = rr[better], kk[better]
        cur[rb, kb], val[rb, kb], grad[rb, kb] = cand[better], vc[better], gc[better]
    R = len(qidx)
    val4, start4 = np.full((4, R, N), -np.inf), np.full((4, R, N), -np.inf)
    val4[qidx, np.arange(R)], start4[qidx, np.arange(R)] = val, at_start
    cur4 = np.zeros((4, R, N, n))
    cur4[qidx, np.arange(R)] = cur
    val, cur = val4, cur4
    vertex = np.max(start4, axis=1)  # (4, N)
    pick = np.argmax(val, axis=1)  # (4, N)
    best_val = np.take_along_axis(val, pick[:, None, :], axis=1)[:, 0]
    best = np.take_along_axis(cur, pick[:, None, :, None], axis=1)[:, 0]
    if polish:
        for k in range(N):
            mk, Mk = _take(model, k), M[k:k + 1]
            for qi, q in enumerate(QUANTITIES):
                v, d = _ascent(mk, Mk, sets, q, best[qi, k], polish)
                if v > best_val[qi, k]:
                    best_val[qi, k], best[qi, k] = v, d
    lower = {q: np.where(np.isfinite(best_val[qi]), best_val[qi], np.nan) for qi, q in enumerate(QUANTITIES)}
    worst = {q: best[qi] for qi, q in enumerate(QUANTITIES)}
    at_vertex = {q: np.where(np.isfinite(vertex[qi]), vertex[qi], np.nan) for qi, q in enumerate(QUANTITIES)}
    return lower, worst, at_vertex
