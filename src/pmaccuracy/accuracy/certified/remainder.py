"""The certificate of one error set at a batch of poses: the remainder box (fixed point and contraction),
the first- and second-order bounds with their rest, the point box of the commanded assembly and the
continuation checks (package docstring, "Remainder of the pose")."""

from __future__ import annotations

import math

import numpy as np

from ...io.resolve import robot_arg
from ...kinematics import as_poses
from .closure import _build_model, _Model, _share_coefficients
from .dual import dual_bound
from .error_set import ROUND_ABS, ROUND_REL
from .error_set import (
    CONTRACTION,
    N_DIRECTIONS,
    PIECE_RTOL,
    QUANTITIES,
    _rect_coords,
    error_set,
    support,
)
from ...io.resolve import load_clearances
from ...model.manipulator import Manipulator
from ...model.sources import ErrorSources, refuse_first_order_only


#: Convergence tolerance of the dual bound of the box's second bound with ``refine_box``: the box only enters the
#: second-order rest of the bounds, so 1e-3 relative on it moves them by far less than their gap.
BOX_RTOL = 1e-3


def _prepare(robot, clearances, poses):

    if not isinstance(robot, Manipulator):
        robot = robot_arg(robot)
    sources = load_clearances(clearances, robot)
    if not isinstance(sources, ErrorSources):
        sources = ErrorSources.from_clearance_set(sources)
    refuse_first_order_only(sources, "the certified bound")
    poses = as_poses(poses).reshape(-1, 3)
    return robot, sources, poses


def remainder_bounds(robot, sources, poses: np.ndarray, *, max_iterations: int = 60) -> dict:
    """Certified signed bounds of the exact pose change over the error set at ``poses`` ``(N, 3)``.

    Returns ``upper`` ``{q: (N,)}`` (mm, rad; NaN where not certified), ``first_order`` ``{q: (N,)}``,
    ``M`` ``(N, 9, n)`` (first-order map of ``delta``), ``b`` ``(N, 9)`` (bound of ``|w|``), ``reason``
    ``(N,)`` and the model; the math is equations (2)-(4) of the module docstring. ``sources``: per-joint
    :class:`~pmaccuracy.model.sources.ErrorSources` checked against ``robot``.
    """
    sets = error_set(robot, sources)
    model = _build_model(robot, sets, poses)
    out = _certify(model, sets, robot.characteristic_length, max_iterations=max_iterations)
    if model.n == 0:  # no error source: the pose does not move, exactly
        out["upper"] = {q: np.zeros(poses.shape[0]) for q in QUANTITIES}
    out.update(model=model, sets=sets)
    return out


def _certify(model: _Model, sets, scale: float, offset: np.ndarray | None = None, max_iterations: int = 60,
             target: dict | None = None, lazy_box: bool = False, refine_box: bool = False) -> dict:
    """The certificate of :func:`remainder_bounds` for a built model (equations (2)-(5)); ``offset`` ``(N, 9)``
    is added to every bounded change (the exact change at the centre of a piece of the error set,
    :func:`_split_bounds`). With ``target`` ``{q: float}`` (mm, rad) the interior-point refinement of
    :func:`dual_bound` is skipped for the rows and directions whose cheaper bound is already below it (the
    branch and bound only needs a piece below its target; every value returned is still a valid bound). With
    ``lazy_box`` the box ``b`` is tightened by the second-order bound (module docstring) only at the poses where
    the box of (3) alone does not close or contract (a looser but valid box, much cheaper for a batch); with
    ``refine_box`` the multipliers of that second bound are refined (interior point, no SDP) even with a target."""
    N, n = model.z0.shape[0], model.n
    offset = np.zeros((N, 9)) if offset is None else offset
    if target is not None:  # per pose (N,); no target (NaN) refines every row
        tgt = {q: np.broadcast_to(np.asarray(target[q], dtype=float), (N,)) for q in QUANTITIES}
        tgt = {q: np.where(np.isfinite(v), v, -np.inf) for q, v in tgt.items()}
    J = model.jacobian(np.zeros((N, 9 + n)))
    Jz, Jd = J[..., :9], J[..., 9:]
    reason = np.full(N, "", dtype=object)
    with np.errstate(all="ignore"):
        cond = np.linalg.cond(Jz)
    ok = np.isfinite(cond) & (cond < 1e12)
    reason[~ok] = "singular loop-closure Jacobian at the commanded pose"
    Jz_safe = np.where(ok[:, None, None], Jz, np.eye(9))
    Jinv = np.linalg.inv(Jz_safe)
    M = -Jinv @ Jd  # (N, 9, n)
    F0 = model.residual(np.zeros((N, 9 + n)))
    JF0 = np.abs(np.einsum("nij,nj->ni", Jinv, F0))
    kappa = Jinv[:, :, 0::3] + 1j * Jinv[:, :, 1::3]  # (N, 9, 3): row j, leg i
    akap = np.abs(kappa)
    # per term: coefficients of Dt and Dr in delta (through Dz_lin = M delta) and in w
    tz, td = model.tg[..., :9], model.tg[..., 9:]
    rz, rd = model.rg[..., :9], model.rg[..., 9:]
    alpha = np.einsum("nmj,njk->nmk", tz, M) + td  # (N, m, n)
    beta = np.einsum("nmj,njk->nmk", rz, M) + rd
    hX = support(sets, alpha)
    hD = np.hypot(support(sets, beta.real), support(sets, beta.imag))
    atz, arz = np.abs(tz), np.abs(rz)
    ar0 = np.abs(model.r0)
    onehot = (model.leg_of[:, None] == np.arange(3)[None, :]).astype(float)  # (m, 3)

    def terms(b):
        X = hX + np.einsum("nmj,nj->nm", atz, b)
        D = hD + np.einsum("nmj,nj->nm", arz, b)
        return X, D

    def phi(b):
        X, D = terms(b)
        rho = (ar0 * X ** 2 / 2 + D * X) @ onehot  # (N, 3)
        return JF0 + np.einsum("nji,ni->nj", akap, rho)

    e0 = np.exp(1j * model.t0)
    JinvF0 = np.einsum("nij,nj->ni", Jinv, F0)

    def coefficients(kap: np.ndarray, rows: np.ndarray):
        """``c'_m`` and ``c_m`` ``(N', R, m)`` of row combinations ``kap`` ``(N', R, 3)`` at the poses ``rows``."""
        cp = np.conj(kap[..., model.leg_of]) * e0[rows][:, None, :]  # (N', R, m)
        return cp * model.r0[rows][:, None, :], cp

    def pieces(kap: np.ndarray, rows: np.ndarray):
        """``c'_m``, ``c_m`` and the second-order model ``H`` (equation (5)) of row combinations ``kap``
        ``(N', R, 3)`` at the poses ``rows``."""
        c, cp = coefficients(kap, rows)
        al, be = alpha[rows], beta[rows]
        v = np.imag(cp[..., None] * be[:, None, :, :])  # (N', R, m, n)
        H = (np.einsum("nrm,nmk,nml->nrkl", c.real / 2, al, al)
             + 0.5 * (np.einsum("nrmk,nml->nrkl", v, al) + np.einsum("nml,nrmk->nrlk", al, v)))
        return c, cp, H

    def rest_of(c: np.ndarray, cp: np.ndarray, bb: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """Bound ``(N', R)`` of (true remainder) - (second-order model) over ``S`` and the box ``|w| <= bb``."""
        wt = np.einsum("nmj,nj->nm", atz[rows], bb)  # |Dt - Dt_lin|
        wr = np.einsum("nmj,nj->nm", arz[rows], bb)  # |Dr - Dr_lin|
        hX_, hD_ = hX[rows], hD[rows]
        X_, D_ = hX_ + wt, hD_ + wr
        return (np.einsum("nrm,nm->nr", np.abs(c), wt * (2 * hX_ + wt) / 2 + X_ ** 3 / 6)
                + np.einsum("nrm,nm->nr", np.abs(cp), wr * X_ + hD_ * wt + D_ * X_ ** 2 / 2))

    # A second bound of the map (2) over the box: |w_j| <= max_s [max_S delta^T (s H_j) delta - s (J_z^-1 F0)_j]
    # + rest_j(b) (the duality bound of the second-order model, module docstring). The smaller of it and (3) is
    # still monotone in b: iterate b <- Phi(b) from 0 (increasing) and check Phi(b) <= b after inflation.
    quad_w = np.full((N, 18), np.inf)
    oi = np.zeros(0, dtype=int)

    def second_order_box(idx: np.ndarray) -> None:
        """The second bound of the box at the poses ``idx`` (one batch): ``cw``, ``cpw``, ``Hw``, ``f_w`` of ``oi``."""
        nonlocal oi, cw, cpw, Hw, f_w
        oi = idx
        cw, cpw, Hw = pieces(np.concatenate([kappa[oi], -kappa[oi]], axis=1), oi)
        f_w = np.concatenate([JinvF0[oi], -JinvF0[oi]], axis=1)
        # a piece of the branch and bound takes the first feasible multipliers (refining them moved the pieces'
        # bounds by less than 1 % on the test robots and cost 40 % of the time); refined where the box then
        # does not close or contract (below)
        quad_w[oi] = dual_bound(sets, np.zeros(Hw.shape[:-1]), Hw, refine=target is None or refine_box,
                                sdp=target is None, rtol=1e-7 if target is None else BOX_RTOL) - f_w

    cw = cpw = Hw = f_w = None
    if not lazy_box:
        second_order_box(np.flatnonzero(ok))

    def phi2(b):
        out = phi(b)
        if oi.size:
            r = quad_w[oi] + rest_of(cw, cpw, b[oi], oi)
            out[oi] = np.fmin(out[oi], np.maximum(r[:, :9], r[:, 9:]))
        return out

    def close():
        """The box ``b`` ``(N, 9)`` (fixed point of Phi from 0, inflated), whether ``Phi(b) <= b`` and the
        contraction constant of (2) over it (:func:`close_box`)."""
        return close_box(phi2, terms, arz, atz, ar0, akap, onehot, scale, max_iterations)

    b, fixed, contraction = close()
    if lazy_box:  # the box of (3) alone where it closes and contracts; the second bound where it does not
        again = np.flatnonzero(ok & ~(fixed & (contraction < CONTRACTION)))
        if again.size:
            second_order_box(again)
            b, fixed, contraction = close()
    redo = np.flatnonzero((ok & ~(fixed & (contraction < CONTRACTION)))[oi])
    if target is not None and redo.size:  # the pieces not certified: again with refined multipliers
        quad_w[oi[redo]] = dual_bound(sets, np.zeros(Hw[redo].shape[:-1]), Hw[redo], iterations=12,
                                      sdp=False) - f_w[redo]
        b, fixed, contraction = close()
    bad_fixed = ok & ~fixed
    reason[bad_fixed] = "the remainder bound does not close (errors too large for this pose: some configurations " \
                        "may not be assembled)"
    bad_contr = ok & fixed & ~(contraction < CONTRACTION)
    reason[bad_contr] = "the remainder is not a contraction (errors too large or near a singularity)"
    certified = ok & fixed & (contraction < CONTRACTION)
    b = np.where(certified[:, None], b, 0.0)
    ci = np.flatnonzero(certified)  # only certified poses are bounded further
    X, D = terms(b)

    def row_bound(kap: np.ndarray, g: np.ndarray, f0: np.ndarray, rows: np.ndarray, refine: bool = True,
                  stop: np.ndarray | None = None, skip: np.ndarray | None = None) -> np.ndarray:
        """Upper bound ``(N', R)`` of ``max over S of g . delta + (J_z^-1 row combination of -(F0 + R))`` at the
        poses ``rows`` (indices).

        ``kap`` ``(N', R, 3)``: the row combination's ``kappa`` per leg; ``g`` ``(N', R, n)`` its first-order
        map; ``f0`` ``(N', R)`` its ``(J_z^-1 F0)``. The smaller of the term-by-term bound (4) and the
        second-order model bound of :func:`dual_bound` plus its rest (equation (5)); the refinement of a row
        ends once it is below ``stop`` ``(N', R)`` (if given). Rows whose bound (4) is already at or below ``skip``
        ``(N', R)`` (if given) keep it: the second-order bound is computed (batched) for the others only.
        """
        c, cp = coefficients(kap, rows)
        X_, D_ = X[rows], D[rows]
        cheap = (support(sets, g) - f0 + np.einsum("nrm,nm->nr", np.maximum(c.real, 0), X_ ** 2 / 2)
                 + np.einsum("nrm,nm->nr", np.abs(c), X_ ** 3 / 6) + np.einsum("nrm,nm->nr", np.abs(cp), D_ * X_))
        if skip is not None:
            kk, rr = np.nonzero(~(cheap <= np.broadcast_to(skip, cheap.shape)))
            if kk.size:
                st = None if stop is None else np.broadcast_to(stop, cheap.shape)[kk, rr][:, None]
                cheap[kk, rr] = row_bound(kap[kk, rr][:, None], g[kk, rr][:, None], f0[kk, rr][:, None], rows[kk],
                                          refine, st)[:, 0]
            return cheap
        _, _, H = pieces(kap, rows)
        extra = -f0 + rest_of(c, cp, b[rows], rows)
        model_bound = dual_bound(sets, g, H, refine=refine, stop=None if stop is None else stop - extra,
                                 rtol=1e-7 if stop is None else PIECE_RTOL) + extra
        return np.fmin(cheap, model_bound)

    upper = {q: np.full(N, np.nan) for q in QUANTITIES}
    first = {}
    for j, q in enumerate(("dx", "dy", "dphi")):
        first[q] = support(sets, M[:, j, :])
    if ci.size:
        kap_rows = np.stack([kappa[ci, j, :] for j in range(3)] + [-kappa[ci, j, :] for j in range(3)], axis=1)
        g_rows = np.concatenate([M[ci, :3, :], -M[ci, :3, :]], axis=1)
        f_rows = np.concatenate([JinvF0[ci, :3] - offset[ci, :3], -JinvF0[ci, :3] + offset[ci, :3]], axis=1)
        if target is None:
            ub = row_bound(kap_rows, g_rows, f_rows, ci)  # (N', 6)
        else:  # the refined bound only for the rows still above their target
            t_rows = np.stack([tgt[q][ci] for q in ("dx", "dy", "dphi")] * 2, axis=1) / (1 + 1e-6)  # (N', 6)
            ub = row_bound(kap_rows, g_rows, f_rows, ci, refine=False, skip=t_rows)
            kk, rr = np.nonzero(ub > t_rows)  # every (pose, row) still above: one batch, one row each
            if kk.size:
                ub[kk, rr] = row_bound(kap_rows[kk, rr][:, None], g_rows[kk, rr][:, None], f_rows[kk, rr][:, None],
                                       ci[kk], stop=t_rows[kk, rr][:, None])[:, 0]
        for j, q in enumerate(("dx", "dy", "dphi")):
            upper[q][ci] = np.maximum(ub[:, j], ub[:, 3 + j])
        # |dp| <= max_k u_k . p / cos(pi / K) through K directions: the cheap bound of every direction (bounded
        # directly or combined from its coarse neighbours, _direction_bounds), then the refined one for the
        # directions (8 at a time) whose bound exceeds the best refined one
        ang = 2 * np.pi * (np.arange(N_DIRECTIONS) + 0.5) / N_DIRECTIONS
        u = np.stack([np.cos(ang), np.sin(ang)], axis=-1)  # (K, 2)
        kap_p, M_p, f_p = kappa[ci, :2, :], M[ci, :2, :], JinvF0[ci, :2] - offset[ci, :2]

        def direction_rows(kk: np.ndarray, dd: np.ndarray):
            """``kappa``, ``g`` and ``J_z^-1 F0`` of ``u_dd . p`` at the poses ``kk`` (flat pairs), one row each."""
            c, s_ = u[dd, 0], u[dd, 1]
            return ((c[:, None] * kap_p[kk, 0] + s_[:, None] * kap_p[kk, 1])[:, None],
                    (c[:, None] * M_p[kk, 0] + s_[:, None] * M_p[kk, 1])[:, None],
                    (c * f_p[kk, 0] + s_ * f_p[kk, 1])[:, None])

        floor = (np.full(ci.size, -np.inf) if target is None
                 else tgt["dp"][ci] * math.cos(math.pi / N_DIRECTIONS) / (1 + 1e-6))  # (N',)
        ub = _direction_bounds(lambda kk, dd: row_bound(*direction_rows(kk, dd), ci[kk], refine=False,
                                                        skip=None if target is None else floor[kk][:, None])[:, 0],
                               ci.size)
        done = np.zeros((ci.size, N_DIRECTIONS), dtype=bool)
        active = np.ones(ci.size, dtype=bool)
        while True:  # rounds: per pose the (up to) 8 worst directions not yet refined, all poses in one batch
            ak = np.flatnonzero(active)
            if not ak.size:
                break
            todo = np.argsort(np.where(done[ak], np.inf, -ub[ak]), axis=-1)[:, :8]  # (A, 8)
            fresh = ~np.take_along_axis(done[ak], todo, axis=-1)
            top = np.max(np.where(fresh, np.take_along_axis(ub[ak], todo, axis=-1), -np.inf), axis=-1)
            best_done = np.max(np.where(done[ak], ub[ak], -np.inf), axis=-1)
            go = top > np.maximum(best_done, floor[ak])
            active[ak[~go]] = False
            if not np.any(go):
                break
            sel = fresh & go[:, None]
            kk = np.broadcast_to(ak[:, None], todo.shape)[sel]
            dd = todo[sel]
            ub[kk, dd] = np.fmin(ub[kk, dd], row_bound(*direction_rows(kk, dd), ci[kk],
                                                       stop=None if target is None else floor[kk][:, None])[:, 0])
            done[kk, dd] = True
        upper["dp"][ci] = np.max(ub, axis=-1) / math.cos(math.pi / N_DIRECTIONS)
    # first-order |dp|: the largest vertex norm of the zonotope (max over directions of the support, exactly)
    first["dp"] = _first_order_dp(sets, M[:, :2, :]) if target is None else np.full(N, np.nan)
    for q in QUANTITIES:
        upper[q] = np.where(certified, upper[q] * (1 + ROUND_REL) + ROUND_ABS * scale, np.nan)
    # at the expansion point itself (delta = centre, so h_S terms vanish) the certified solution w* satisfies
    # |w*| = |T(w*)| <= Phi_0(b) (equation (3) with X_m = |a_m| . b, D_m = |r'_m| . b), monotone: iterate
    with np.errstate(all="ignore"):
        bc = b.copy()
        for _ in range(4):
            Xc, Dc = np.einsum("nmj,nj->nm", atz, bc), np.einsum("nmj,nj->nm", arz, bc)
            bc = np.fmin(bc, JF0 + np.einsum("nji,ni->nj", akap, (ar0 * Xc ** 2 / 2 + Dc * Xc) @ onehot))
        bc = np.where(certified[:, None], bc * (1 + 1e-6) + 1e-15 * scale, np.nan)
    return {"upper": upper, "first_order": first, "M": M, "b": b, "b_centre": bc, "reason": reason,
            "certified": certified}


#: Every COARSE_STEP-th of the :data:`N_DIRECTIONS` directions of ``|dp|`` is bounded first (:func:`_direction_bounds`).
COARSE_STEP = 8


def close_box(phi, terms, arz: np.ndarray, atz: np.ndarray, ar0: np.ndarray, akap: np.ndarray,
              onehot: np.ndarray, scale: float, max_iterations: int = 60) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The remainder box of equation (3): ``b`` ``(N, 9)`` iterated ``b <- phi(b)`` from 0 (monotone) to its fixed
    point and inflated (``1e-6`` relative, ``1e-15 * scale``), whether ``phi(b) <= b`` (the map (2) sends the box
    into itself) and the Lipschitz constant ``(N,)`` of (2) in ``w`` over it in the norm ``max_j |w_j| / b_j``
    (from ``|d R_m / d w| <= |r'_z| X_m + |theta'_z| (D_m + |r_m0| X_m)``, package docstring).

    ``terms(b)`` gives ``X_m, D_m`` ``(N, m)``; ``arz, atz`` ``(N, m, 9)`` are ``|r'_m,z|, |theta'_m,z|``, ``ar0``
    ``(N, m)`` ``|r_m0|``, ``akap`` ``(N, 9, 3)`` ``|kappa_ji|``, ``onehot`` ``(m, 3)`` the legs of the terms (at a
    pose, or bounds of them over a box of poses: :mod:`pmaccuracy.accuracy.certified.region`)."""
    N = akap.shape[0]
    b = np.zeros((N, 9))
    with np.errstate(all="ignore"):
        for _ in range(max_iterations):
            nb = phi(b)
            if np.all(np.abs(nb - b) <= 1e-12 * np.maximum(nb, 1e-300)):
                b = nb
                break
            b = nb
        b = b * (1 + 1e-6) + 1e-15 * scale
        fixed = np.all(phi(b) <= b, axis=-1) & np.all(np.isfinite(b), axis=-1)
        X, D = terms(b)
        lip_leg = np.einsum("nmj,nm,mi->nij", arz, X, onehot) + np.einsum(
            "nmj,nm,mi->nij", atz, D + ar0 * X, onehot)  # (N, 3 legs, 9)
        L = np.einsum("nji,nil,nl->nj", akap, lip_leg, b) / b
    return b, fixed, np.max(L, axis=-1)


def _direction_bounds(bound, P: int) -> np.ndarray:
    """Upper bounds ``(P, K)`` of ``u_k . p`` for the ``K = N_DIRECTIONS`` directions ``u_k`` at angles ``2 pi (k + 1/2)
    / K``, from ``bound(kk, dd)`` (the bounds of the (pose, direction) pairs ``kk``, ``dd`` (flat indices), valid
    upper bounds of ``u_dd . p`` at pose ``kk``), computed for few directions.

    Every :data:`COARSE_STEP`-th direction is bounded first. A direction ``u`` between two of them, ``u_a`` and
    ``u_b`` (``Delta`` apart, ``u`` at ``theta`` from ``u_a``), is their combination with non-negative weights,
    ``u = (sin(Delta - theta) u_a + sin(theta) u_b) / sin(Delta)``, so the same combination of their bounds bounds
    ``u . p`` (at most ``1 / cos(Delta / 2)`` times the larger). Only the directions whose combined bound exceeds
    the largest coarse bound (the result is at least that) are bounded themselves, and keep the smaller value.
    """
    K, step = N_DIRECTIONS, COARSE_STEP
    coarse = np.arange(0, K, step)
    ub = np.empty((P, K))
    kk, dd = np.repeat(np.arange(P), coarse.size), np.tile(coarse, P)
    ub[:, coarse] = bound(kk, dd).reshape(P, coarse.size)
    j = np.arange(K)
    a_idx, b_idx = (j // step) * step, ((j // step + 1) * step) % K
    delta = 2 * np.pi * step / K
    theta = 2 * np.pi * (j - a_idx) / K
    wa, wb = np.sin(delta - theta) / np.sin(delta), np.sin(theta) / np.sin(delta)
    with np.errstate(invalid="ignore"):  # inf - inf: a direction without a bound stays inf
        comb = ub[:, a_idx] * wa + ub[:, b_idx] * wb
    comb[:, coarse] = ub[:, coarse]
    comb = np.where(np.isnan(comb), np.inf, comb)
    kk, dd = np.nonzero(~(comb <= np.max(ub[:, coarse], axis=-1, keepdims=True)))
    if kk.size:
        comb[kk, dd] = np.fmin(comb[kk, dd], bound(kk, dd))
    return comb


def _point_box(model: _Model, scale: float, iterations: int = 30) -> np.ndarray:
    """The certificate of the commanded configuration alone (the set ``S = {0}``): ``b0`` ``(N, 9)`` with one
    solution of the closure at ``delta = 0`` in ``|Dz| <= b0``, unique there (equation (3) with ``X_m = |a_m|
    . b``, ``D_m = |r'_m| . b``: ``Phi_0(b0) <= b0`` and Lipschitz constant below ``CONTRACTION``); it is the
    commanded assembly (rounding-size, about ``|J_z^-1 F0|``). NaN where not proven."""
    N, n = model.z0.shape[0], model.n
    D0 = np.zeros((N, 9 + n))
    with np.errstate(all="ignore"):
        Jinv = np.linalg.inv(model.jacobian(D0)[..., :9])
        JF0 = np.abs(np.einsum("nij,nj->ni", Jinv, model.residual(D0)))
        akap = np.abs(Jinv[:, :, 0::3] + 1j * Jinv[:, :, 1::3])
        atz, arz, ar0 = np.abs(model.tg[..., :9]), np.abs(model.rg[..., :9]), np.abs(model.r0)
        onehot = (model.leg_of[:, None] == np.arange(3)[None, :]).astype(float)

        def phi0(b):
            X, D = np.einsum("nmj,nj->nm", atz, b), np.einsum("nmj,nj->nm", arz, b)
            return JF0 + np.einsum("nji,ni->nj", akap, (ar0 * X ** 2 / 2 + D * X) @ onehot), X, D

        b = np.zeros((N, 9))
        for _ in range(iterations):
            b = phi0(b)[0]
        b = b * (1 + 1e-6) + 1e-15 * scale
        nb, X, D = phi0(b)
        lip = np.einsum("nmj,nm,mi->nij", arz, X, onehot) + np.einsum("nmj,nm,mi->nij", atz, D + ar0 * X, onehot)
        L = np.max(np.einsum("nji,nil,nl->nj", akap, lip, b) / b, axis=-1)
        ok = np.all(nb <= b, axis=-1) & np.all(np.isfinite(b), axis=-1) & (L < CONTRACTION)
    return np.where(ok[:, None], b, np.nan)


def _contains_zero(sets, centres: np.ndarray) -> np.ndarray:
    """Whether ``delta = 0`` lies in the pieces of shape ``sets`` centred at ``centres`` ``(P, n)`` (the cut
    centres are dyadic fractions of the half-widths; a relative 1e-12 absorbs their rounding), ``(P,)``."""
    ok = np.ones(centres.shape[0], dtype=bool)
    tol = 1 + 1e-12
    for s in sets:
        c = centres[:, list(s.cols)]
        if s.kind == "interval":
            ok &= np.abs(c[:, 0]) <= s.eps * tol
        elif s.kind == "disk":
            ok &= np.hypot(c[:, 0], c[:, 1]) <= s.eps * tol
        elif s.kind == "rect":
            cr, ct = _rect_coords(s, c[:, 0], c[:, 1])
            ok &= (np.abs(cr) <= s.eps * tol) & (np.abs(ct) <= s.eps_t * tol)
        else:
            ok &= (np.abs(s.block_length * c[:, 1] + 2 * c[:, 0]) <= 2 * s.eps * tol) & (
                np.abs(s.block_length * c[:, 1] - 2 * c[:, 0]) <= 2 * s.eps * tol)
    return ok


def _continues(dz: np.ndarray, bc: np.ndarray, centre: np.ndarray, anchor: dict, M: np.ndarray | None = None,
               b: np.ndarray | None = None, at_zero: np.ndarray | None = None) -> np.ndarray:
    """Whether a piece's certified solution is the continuation of its parent's (module docstring,
    "Continuation check"): at the piece's centre ``c`` the piece's box ``|Dz - dz| <= bc`` lies inside the
    parent's box ``|Dz - dz_p - M_p (c - c_p)| <= b_p``. ``dz``, ``bc`` ``(P, 9)``, ``centre`` ``(P, n)``;
    ``anchor``: the parent's ``dz``, ``M`` ``(9, n)``, ``b`` ``(9,)``, ``centre`` ``(n,)`` and ``b0`` ``(9,)``
    (:func:`_point_box`). Or, where the piece contains ``delta = 0`` (``at_zero`` ``(P,)``), the commanded
    assembly's box ``|Dz| <= b0`` lies inside the piece's own box at ``delta = 0``, ``|Dz - dz + M c| <= b``
    (``M`` ``(P, 9, n)``, ``b`` ``(P, 9)``: the piece's certificate). Returns ``(P,)`` (False where anything is
    not finite)."""
    pred = anchor["dz"] + np.einsum("jk,pk->pj", anchor["M"], centre - anchor["centre"])
    with np.errstate(invalid="ignore"):
        inside = np.all((np.abs(dz - pred) + bc <= anchor["b"]) & np.isfinite(bc) & np.isfinite(dz)
                        & np.isfinite(anchor["b"]), axis=-1)
        if at_zero is not None and "b0" in anchor:
            w0 = np.abs(-dz + np.einsum("pjk,pk->pj", M, centre)) + anchor["b0"]
            inside |= at_zero & np.all((w0 <= b) & np.isfinite(w0) & np.isfinite(b), axis=-1)
    return inside


def _recentre(model: _Model, D: np.ndarray) -> _Model:
    """The model expanded about ``v0 + D`` (``D`` ``(N, 9 + n)``): the same affine coefficients, constants moved."""
    out = _Model(r0=model.r0 + np.einsum("nmv,nv->nm", model.rg, D),
                 t0=model.t0 + np.einsum("nmv,nv->nm", model.tg, D), rg=model.rg, tg=model.tg,
                 leg_of=model.leg_of, aff0=model.aff0 + np.einsum("niv,nv->ni", model.affg, D), affg=model.affg,
                 ang0=model.ang0 + np.einsum("niv,nv->ni", model.angg, D), angg=model.angg, n=model.n,
                 z0=model.z0 + D[:, :9])
    _share_coefficients(model, out)
    return out


def _first_order_dp(sets, Mp: np.ndarray) -> np.ndarray:
    """``max_{delta in S} |Mp delta|`` ``(N,)`` for ``Mp`` ``(N, 2, n)``: the support function's largest value
    over directions: 721 directions, then a ternary search around the best one (first order only)."""
    ang = np.linspace(0, 2 * np.pi, 721)
    best = np.zeros(Mp.shape[0])
    arg = np.zeros(Mp.shape[0])
    for a in ang:
        h = support(sets, np.cos(a) * Mp[:, 0, :] + np.sin(a) * Mp[:, 1, :])
        upd = h > best
        best = np.where(upd, h, best)
        arg = np.where(upd, a, arg)
    # the support function is smooth between vertex switches: refine by a few ternary steps
    lo, hi = arg - 2 * np.pi / 720, arg + 2 * np.pi / 720
    for _ in range(40):
        m1, m2 = lo + (hi - lo) / 3, hi - (hi - lo) / 3
        h1 = support(sets, np.cos(m1)[:, None] * Mp[:, 0, :] + np.sin(m1)[:, None] * Mp[:, 1, :])
        h2 = support(sets, np.cos(m2)[:, None] * Mp[:, 0, :] + np.sin(m2)[:, None] * Mp[:, 1, :])
        lo = np.where(h1 < h2, m1, lo)
        hi = np.where(h1 < h2, hi, m2)
    mid = (lo + hi) / 2
    h = support(sets, np.cos(mid)[:, None] * Mp[:, 0, :] + np.sin(mid)[:, None] * Mp[:, 1, :])
    return np.maximum(best, h)
