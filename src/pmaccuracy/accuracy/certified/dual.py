"""The dual (S-lemma) bound of a quadratic over the error set: interior-point Newton steps in scaled
parameters, the semidefinite fallback of the hard case, and the rounding-safe evaluation of a multiplier
(package docstring, "Second-order model")."""

from __future__ import annotations

import numpy as np

from ..._optional import available
from .error_set import HARD_CASE_GRADIENT, MU_EVERY, MU_FACTOR, SourceSet, _rect_coords, constraint_matrices


def dual_bound(sets: tuple[SourceSet, ...], g: np.ndarray, H: np.ndarray, refine: bool = True,
               iterations: int = 40, sdp: bool = True, stop: np.ndarray | None = None,
               rtol: float = 1e-7) -> np.ndarray:
    """Upper bound of ``max over S of g . delta + delta^T H delta`` (Lagrangian duality, the S-lemma bound).

    With ``S = {delta^T P_k delta <= 1}`` (:func:`constraint_matrices`), for any ``lambda >= 0`` with
    ``Lambda - H = sum_k lambda_k P_k - H`` positive definite::

        g . delta + delta^T H delta <= sum_k lambda_k + g . delta - delta^T (Lambda - H) delta
                                   <= sum_k lambda_k + g^T (Lambda - H)^-1 g / 4        (on S)

    (the second line maximizes the concave quadratic over all ``delta``). At ``H = 0`` the best ``lambda``
    gives exactly the support function ``h_S(g)``; for small ``H`` the bound exceeds the true maximum by
    ``O(|H|^2 / |g|)``. ``lambda`` starts at the ``H = 0`` optimum (grown along ``|H| / |P_k|`` until
    ``Lambda - H`` is positive definite); with ``refine`` the convex dual is then minimized by an
    interior-point method (damped Newton steps on ``phi - mu log det(Lambda - H) - mu sum log lambda``,
    ``mu`` times :data:`MU_FACTOR` every :data:`MU_EVERY` steps, steps kept inside ``lambda > 0``; gradient
    ``1 - x^T P_k x / 4``, ``x = (Lambda - H)^-1 g``; a backtracking line search; it stops when the bound
    moves by less than ``rtol`` relative over :data:`MU_EVERY` steps). All of it runs in the parameters scaled by
    powers of two to unit size (``delta = D y``: ``g -> D g``, ``H -> D H D``, ``P_k -> D P_k D``, exact in
    floating point and the same bound): unscaled, with ``P_k`` entries from 1e1 to 1e6, the Newton steps
    stalled as far as 70 % above the optimum (checked against an SDP solver). With ``sdp``, rows that end in
    the hard case (final gradient above :data:`HARD_CASE_GRADIENT`) are solved again by :func:`_sdp_dual`.
    With ``stop`` (broadcast to ``g.shape[:-1]``) a row leaves the refinement as soon as its bound is at or
    below its ``stop`` value (the branch and bound only needs a piece below its target).
    Every value
    returned is that of a ``lambda`` whose ``Lambda - H`` passed the positive-definiteness test of
    :func:`_dual_value` (with its rounding margin); ``inf`` where none did. ``g`` ``(..., n)``, ``H``
    ``(..., n, n)`` (symmetric); returns ``(...)``.
    """
    batch = g.shape[:-1]
    if g.shape[-1] == 0:  # no source: the maximum is 0
        return np.zeros(batch)
    stop = np.full(batch, -np.inf) if stop is None else np.broadcast_to(np.asarray(stop, dtype=float), batch)
    if len(batch) != 1:  # one flat batch (the line search works on subsets of rows)
        n_ = g.shape[-1]
        return _dual_bound_flat(sets, g.reshape(-1, n_), np.broadcast_to(H, batch + (n_, n_)).reshape(-1, n_, n_),
                                refine, iterations, sdp, stop.reshape(-1), rtol).reshape(batch)
    return _dual_bound_flat(sets, g, H, refine, iterations, sdp, stop, rtol)


def _dual_bound_flat(sets, g: np.ndarray, H: np.ndarray, refine: bool, iterations: int, sdp: bool = True,
                     stop: np.ndarray | None = None, rtol: float = 1e-7) -> np.ndarray:
    """:func:`dual_bound` for ``g`` ``(B, n)``, ``H`` ``(B, n, n)``."""
    P = constraint_matrices(sets)
    K, n = P.shape[0], P.shape[-1]
    if n == 0:
        return np.zeros(g.shape[:-1])
    # lambda at the H = 0 optimum, per source
    lam = np.zeros(g.shape[:-1] + (K,))
    k = 0
    for s in sets:
        if s.kind == "interval":
            lam[..., k] = s.eps * np.abs(g[..., s.cols[0]]) / 2
            k += 1
        elif s.kind == "disk":
            lam[..., k] = s.eps * np.hypot(g[..., s.cols[0]], g[..., s.cols[1]]) / 2
            k += 1
        elif s.kind == "rect":
            gr, gt = _rect_coords(s, g[..., s.cols[0]], g[..., s.cols[1]])
            lam[..., k], lam[..., k + 1] = s.eps * np.abs(gr) / 2, s.eps_t * np.abs(gt) / 2
            k += 2
        else:
            A = np.array([[1 / s.eps, s.block_length / (2 * s.eps)], [1 / s.eps, -s.block_length / (2 * s.eps)]])
            gt = np.einsum("ij,...j->...i", np.linalg.inv(A).T, g[..., list(s.cols)])
            lam[..., k:k + 2] = np.abs(gt) / 2
            k += 2
    # the same problem in the scaled parameters y = delta / d (d: powers of two, so exactly): every constraint
    # matrix then has entries of order one, which the interior-point Newton steps need (the bound is unchanged)
    d = 2.0 ** np.round(np.log2(1 / np.sqrt(np.max(np.diagonal(P, axis1=-2, axis2=-1), axis=0))))
    P = d[None, :, None] * P * d[None, None, :]
    g = g * d
    H = d[:, None] * H * d[None, :]
    Pnorm = np.linalg.norm(P, axis=(-2, -1))  # (K,)
    Hnorm = np.linalg.norm(H, axis=(-2, -1))[..., None]
    unit = Hnorm / Pnorm + 1e-300  # (..., K): a lambda of this size dominates H
    lam = np.maximum(lam, 1e-12 * unit)
    # grow lambda until Lambda - H is positive definite
    val, pd, _, _ = _dual_value(P, g, H, lam)
    todo, t = np.flatnonzero(~pd), 1e-6
    for _ in range(30):  # t = 1e-6 * 4^k on the rows still not positive definite
        if not todo.size:
            break
        v, ok, _, _ = _dual_value(P, g[todo], H[todo], lam[todo] + t * unit[todo])
        lam[todo[ok]] += t * unit[todo[ok]]
        val[todo[ok]], pd[todo[ok]] = v[ok], True
        todo, t = todo[~ok], 4 * t
    best = np.where(pd, val, np.inf)
    if not refine:
        return best
    # interior-point refinement: damped Newton on phi_mu = phi - mu log det(Lambda - H) - mu sum log lambda,
    # mu decreasing; every iterate is strictly feasible and its plain phi is a valid bound
    steps = 0.5 ** np.arange(10)
    mu = 1e-2 * np.where(np.isfinite(best), best, 0.0)[..., None] / (n + K) + 1e-300
    eyeK = np.eye(K)
    Pflat = P.reshape(K, n * n)

    def barrier_value(lam_, g_, H_, mu_):
        v, pd, _, logdet = _dual_value(P, g_, H_, lam_)
        with np.errstate(all="ignore"):
            bv = v - mu_[..., 0] * (logdet + np.sum(np.log(lam_), axis=-1))
        ok = pd & np.all(lam_ > 0, axis=-1) & np.isfinite(bv)
        return np.where(ok, bv, np.inf), np.where(ok, v, np.inf)

    stop = np.full(best.shape, -np.inf) if stop is None else stop
    live = np.isfinite(best)
    lam = np.where(live[..., None], lam, 1.0)
    gl = np.where(live[..., None], g, 0.0)
    Hl = np.where(live[..., None, None], H, -np.eye(n))
    cur, _ = barrier_value(lam, gl, Hl, mu)
    checkpoint = best.copy()
    grad = np.zeros(lam.shape)
    for it in range(iterations):
        live &= ~(best <= stop)  # rows already below their stop value are done
        if not np.any(live):
            break
        L = (lam @ Pflat).reshape(lam.shape[:-1] + (n, n)) - Hl
        Linv = np.linalg.inv(L)
        x = (Linv @ gl[..., None])[..., 0]
        Y = (P @ x[..., None, :, None])[..., 0]  # (..., K, n): P_k x
        Q = Linv[..., None, :, :] @ P  # (..., K, n, n): L^-1 P_k
        QQ = Q.reshape(Q.shape[:-2] + (n * n,)) @ np.swapaxes(Q, -1, -2).reshape(Q.shape[:-2] + (n * n,)
                                                                                   ).swapaxes(-1, -2)
        grad = np.where(live[..., None], 1 - (Y @ x[..., None])[..., 0] / 4 - mu * np.trace(Q, axis1=-2, axis2=-1)
                        - mu / lam, 0.0)
        hess = (Y @ Linv @ np.swapaxes(Y, -1, -2)) / 2 + mu[..., None] * QQ + eyeK * (mu / lam ** 2)[..., None, :]
        with np.errstate(all="ignore"):
            dl = -np.linalg.solve(hess + 1e-14 * eyeK * np.abs(hess).max(axis=(-2, -1), keepdims=True),
                                  grad[..., None])[..., 0]
        dl = np.where(np.isfinite(dl), dl, 0.0)
        with np.errstate(all="ignore"):  # fraction to the boundary lambda > 0
            tmax = np.minimum(1.0, 0.9 * np.min(np.where(dl < 0, lam / -dl, np.inf), axis=-1))
        # backtracking: the longest of the steps tmax * 2^-k that lowers the barrier (rows that still need one)
        todo = np.flatnonzero(live)
        for step in steps:
            cand = lam[todo] + (tmax[todo] * step)[:, None] * dl[todo]
            bv, pv = barrier_value(cand, gl[todo], Hl[todo], mu[todo])
            best[todo] = np.fmin(best[todo], pv)
            better = bv < cur[todo]
            lam[todo[better]] = cand[better]
            cur[todo[better]] = bv[better]
            todo = todo[~better]
            if not todo.size:
                break
        if it % MU_EVERY == MU_EVERY - 1:
            # converged: the bound moved by less than rtol (relative) over the last MU_EVERY steps
            with np.errstate(all="ignore"):
                if it > MU_EVERY and np.all(~live | (np.abs(checkpoint - best) <= rtol * np.abs(best))):
                    break
            checkpoint = best.copy()
            mu = mu * MU_FACTOR
            cur, _ = barrier_value(lam, gl, Hl, mu)
    # the hard case: at the optimum Lambda - H is singular, x = (Lambda - H)^-1 g grows without bound and the
    # Newton steps in lambda crawl (measured: 5 % above the optimum after 40 steps); such rows are solved again
    # as the semidefinite program of the same dual (cvxpy, Clarabel), whose lambda, inflated until _dual_value
    # certifies Lambda - H positive definite, gives the bound
    if iterations and sdp:
        hard = np.flatnonzero(live & ~(best <= stop) & (np.max(np.abs(grad), axis=-1) > HARD_CASE_GRADIENT))
        if hard.size:
            best[hard] = np.fmin(best[hard], _sdp_dual(P, g[hard], H[hard]))
    return best


def _sdp_dual(P: np.ndarray, g: np.ndarray, H: np.ndarray) -> np.ndarray:
    """The dual bound of :func:`dual_bound` from the semidefinite program ``min sum lambda + t`` subject to
    ``[[Lambda - H, -g/2], [-g^T/2, t]] >= 0``, ``lambda >= 0`` (solved by cvxpy with Clarabel, row by row);
    the solver's ``lambda`` is inflated by ``1e-7``, ``1e-5`` and ``1e-3`` (relative, plus as much of its
    mean) and the smallest value that :func:`_dual_value` certifies is returned (so the result is a valid bound
    whatever the solver's accuracy; ``inf`` where none is certified). ``P`` ``(K, n, n)``, ``g`` ``(B, n)``,
    ``H`` ``(B, n, n)``; returns ``(B,)``. Without cvxpy (the ``design`` extra) every row is ``inf``: the
    interior point's bound stays (valid, looser in the hard case)."""
    if not available("cvxpy"):
        return np.full(g.shape[0], np.inf)
    import cvxpy as cp

    K, n = P.shape[0], P.shape[-1]
    lam, t = cp.Variable(K, nonneg=True), cp.Variable()
    gp, Hp = cp.Parameter(n), cp.Parameter((n, n), symmetric=True)
    L = sum(lam[k] * P[k] for k in range(K)) - Hp
    col = cp.reshape(gp, (n, 1), order="C") / 2
    M = cp.bmat([[L, -col], [-col.T, cp.reshape(t, (1, 1), order="C")]])
    prob = cp.Problem(cp.Minimize(cp.sum(lam) + t), [(M + M.T) / 2 >> 0])
    out = np.full(g.shape[0], np.inf)
    for r in range(g.shape[0]):
        gp.value, Hp.value = g[r], (H[r] + H[r].T) / 2
        try:
            prob.solve(solver="CLARABEL")
        except cp.error.SolverError:
            continue
        if lam.value is None:
            continue
        base = np.maximum(np.asarray(lam.value, dtype=float), 0.0)
        trials = np.array([base * (1 + f) + f * (np.mean(base) + 1e-300) for f in (1e-7, 1e-5, 1e-3)])
        val, pd, _, _ = _dual_value(P, np.broadcast_to(g[r], (3, n)), np.broadcast_to(H[r], (3, n, n)), trials)
        out[r] = np.min(np.where(pd, val, np.inf))
    return out


def _dual_value(P: np.ndarray, g: np.ndarray, H: np.ndarray, lam: np.ndarray):
    """The dual bound ``sum lambda + g^T (Lambda - H)^-1 g / 4`` of :func:`dual_bound` at ``lambda``, made safe
    against rounding, whether ``Lambda - H`` is certified positive definite, ``x`` and ``log det``.

    With the computed eigenvalues ``mu`` of ``L = Lambda - H`` (a backward-stable symmetric eigensolver: exact
    for ``L + E``, ``|E| <= c n eps |L|``), ``mu_lo = mu_min - 1e-13 mu_max`` is a lower bound of the true
    smallest eigenvalue; ``L`` counts as positive definite when ``mu_lo > 0``. For ``x`` the computed solution
    of ``L x = g`` and ``r = g - L x``, exactly ``g^T L^-1 g = x^T L x + 2 x^T r + r^T L^-1 r``, so
    ``g^T L^-1 g <= x^T L x + 2 x^T r + |r|^2 / mu_lo``; the result is multiplied by ``1 + 1e-9`` for the
    rounding of these sums. Shapes: ``lam (..., K)``, ``g (..., n)``, ``H (..., n, n)``.
    """
    n = P.shape[-1]
    L = (lam @ P.reshape(P.shape[0], n * n)).reshape(lam.shape[:-1] + (n, n)) - H
    with np.errstate(all="ignore"):
        ev = np.linalg.eigvalsh(L)
    hi = ev[..., -1]
    lo = ev[..., 0] - 1e-13 * np.abs(hi)
    pd = (lo > 0) & np.all(np.isfinite(ev), axis=-1)
    Ls = np.where(pd[..., None, None], L, np.eye(n))
    x = np.linalg.solve(Ls, g[..., None])[..., 0]
    Lx = (Ls @ x[..., None])[..., 0]
    r = g - Lx
    safe_lo = np.where(pd, lo, 1.0)
    quad = (np.sum(x * Lx, axis=-1) + 2 * np.sum(x * r, axis=-1) + np.sum(r * r, axis=-1) / safe_lo) / 4
    with np.errstate(all="ignore"):
        logdet = np.sum(np.log(np.where(pd[..., None], ev, 1.0)), axis=-1)
    return (np.sum(lam, axis=-1) + quad) * (1 + 1e-9), pd, x, logdet
