"""The exact model's worst case over a region of poses: a bound of the Taylor remainder that holds at every pose
of a box of poses, and the best feasible values at sampled poses (used by
:func:`pmaccuracy.accuracy.global_worst.global_worst` with ``exact=True``).

Bound over a box
----------------
At a pose ``P`` the exact change of the pose row ``j`` is ``Dz_j = M_j(P) delta + w_j(P, delta)`` (package
docstring, equation (2)), so over a box ``B`` of poses::

    max_{P in B} max_S |Dz_j|  <=  max_{P in B} h_S(+-M_j(P))  +  max_{P in B} b_j(P)

The first term is the first-order maximum over the box (:func:`pmaccuracy.accuracy.interval.box_bounds`); the
second is a bound ``b`` of the remainder box (3) that holds at *every* pose of ``B``, built here. The closure of
pose ``P`` is the model of an *anchor* pose ``a`` of ``B`` (its centre, else a corner or a face centre that can
be reached) moved by ``Delta_P = v0(P) - v0(a)``: the pose, the passive joints and the actuated joints (each
actuated joint is a column of the model, a zero-width ``dq`` source where the error set has none). Every term
angle and radius is affine in ``v``, so with ``|Delta_P| <= d`` componentwise (pose: the box; joints: the
legs' interval inverse kinematics :func:`pmaccuracy.accuracy.interval.leg_box_state` over ``B``, about the
anchor's values)::

    |theta_m(P) - theta_m(a)| <= T_m = |t'_m| . d,      |r_m(P) - r_m(a)| <= R_m = |r'_m| . d

and every Jacobian column ``e^{i theta} (r'_j + i r t'_j)`` of a term moves by at most ``min(T_m, 2) |r'_j + i
r_a t'_j| + |t'_j| R_m``: ``|J(P) - J(a)| <= dJ`` elementwise (summed over each leg's terms; the angle rows
are affine, ``dJ = 0``). With ``E = |J_z(a)^-1| dJ_z`` of spectral radius below 1 the Neumann series gives,
for every ``P`` of the box::

    |J_z(P)^-1|  <=  K = (I - E)^-1 |J_z(a)^-1|,        |M(P) - M(a)|  <=  dM = K (dJ_delta + dJ_z |M(a)|)

and the ingredients of (3) are bounded over the box: ``|kappa_ji| <= hypot(K_j,Re_i, K_j,Im_i)``,
``h_S(alpha_m) <= h_S(alpha_m(a)) + h_S(|t'_m,z| dM)`` (the support functions of the sets are monotone in
the absolute values of the coefficients), likewise ``beta``, and ``|r_m0| <= |r_m(a)| + R_m``. The map
``Phi`` of (3) with these bounds dominates every pose's own, so its inflated fixed point ``b`` (checked
``Phi(b) <= b``, contraction below :data:`~pmaccuracy.accuracy.certified.error_set.CONTRACTION`) is a
remainder box at every pose of ``B``, with ``J_z`` invertible and the solution the commanded assembly's
continuation there (as at one pose). ``dp``: ``|dp| <= h_S(M_xy) + hypot(b_x, b_y)``.

The bound of ``b`` takes every term's own maximum over ``S`` (bound (3) and the term-by-term bound (4), not the
second-order model (5) of one pose): it overestimates the remainder by a factor of 2-5, a second-order quantity
(0.04-0.3 % of the error at the paper's clearances), and the first-order part converges like the box's width
squared (mean-value form), so this bound alone certifies a region to a few times the nonlinear share.

Second-order bound
------------------
Where that is not enough, a box also gets the second-order model (5) of the package docstring. For a row
combination ``kappa`` (``+-`` a pose row, or ``u . (x, y)`` for the ``K`` directions of ``|dp|``) at pose ``P``::

    s Dz_j(P) <= max_S [g_P . delta + delta^T H_P delta] + |J_z^-1 F0| + E_P(b)

and ``max_S [g_P . delta + delta^T H_P delta] <= dual bound of (g_a, H_a) + h_S(|g_P - g_a|) + max_S |delta^T
(H_P - H_a) delta|``. With ``t_m = alpha_m . delta``, ``rho_m = beta_m . delta`` the quadratic form is ``sum_m
Re(c_m) t_m^2 / 2 + Im(c'_m rho_m) t_m``, so its change is at most ``sum_m |Dc_m| Xb^2 / 2 + |c_m(a)| dX (2 X_a +
dX) / 2 + (|Dc'_m| Db + |c'_m(a)| dD) Xb + |c'_m(a)| D_a dX`` (``X_a = h_S(alpha_m(a))``, ``dX = h_S(|t'_m,z| dM)``,
``Xb = X_a + dX``; ``D`` likewise for ``beta``, ``dD = sqrt(2) h_S(|r'_m,z| dM)``; ``|Dc'_m| <= |Dkappa| +
|kappa(a)| min(T_m, 2)``, ``|Dc_m| <= |Dkappa| (|r_m(a)| + R_m) + |kappa(a)| (min(T_m, 2) |r_m(a)| + R_m)``,
``|Dkappa|`` from ``((I - E)^-1 - I) |J_z(a)^-1|``); ``h_S(|g_P - g_a|) <= h_S(dM_j)``; ``E_P(b)`` is the rest of
(5) with the box's ``b`` and ingredients. The dual bound takes the first feasible multipliers (refining them
moved the bounds by at most 0.06 % on the presets at 1x and 10x, and cost 4-10x). The added terms shrink like the
box's width (0.2-1.7 % above the per-pose certificate for a box 0.2 mm wide on the presets at 1x, 0.02-0.17 % at
0.02 mm), so
the branch and bound evaluates it only where the first-order bound leaves room for it
(:data:`~pmaccuracy.accuracy.global_worst.TIGHT_SLACK`).
"""

from __future__ import annotations

import math

import numpy as np

from ...kinematics import inverse_kinematics
from ..interval import leg_box_state
from ...numerics.interval import Iv
from . import _first_order_map
from .ascent import _nonlinear
from .closure import _build_model
from .dual import dual_bound
from .error_set import CONTRACTION, N_DIRECTIONS, QUANTITIES, SourceSet, error_set, support
from .remainder import _direction_bounds, close_box

#: Relative widening of every remainder bound (rounding), as the per-pose certificate's ``ROUND_REL``.
ROUND_REL = 1e-9
#: Boxes bounded in one batch (memory: a few kB a box).
CHUNK = 2048
#: Largest spectral radius of ``E`` accepted for the Neumann bound of ``J_z(P)^-1`` over a box.
NEUMANN = 0.5
#: Refine the multipliers of the second-order bound over a box (interior point) or keep the first feasible ones.
REFINE = False


def _augmented(robot, sets: tuple[SourceSet, ...]) -> tuple[tuple[SourceSet, ...], list]:
    """``sets`` with a zero-width ``dq`` source appended for every actuated joint that has none, and each
    actuated joint's ``(leg, joint, column of delta)``."""
    n = sum(len(s.cols) for s in sets)
    have = {(s.leg, s.joint): s.cols[0] for s in sets if s.field == "dq"}
    extra, act = [], []
    for i, chain in enumerate(robot.chains):
        for k, joint in enumerate(chain.joints):
            if not joint.actuated:
                continue
            if (i, k) not in have:
                extra.append(SourceSet("interval", i, k, "dq", 0.0, (n,)))
                have[(i, k)] = n
                n += 1
            act.append((i, k, have[(i, k)]))
    return tuple(sets) + tuple(extra), act


def _anchors(robot, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A reachable pose of each box ``(k, 6)``: its centre, else the first reachable corner or face centre;
    ``(k, 3)`` poses, ``(k,)`` found and ``(k, legs, joints)`` their joint values (NaN where none is found)."""
    lo, hi = boxes[:, 0::2], boxes[:, 1::2]
    mid = 0.5 * (lo + hi)
    picks = [np.zeros(3)]
    picks += [np.array(c) for c in np.array(np.meshgrid(*[[-1.0, 1.0]] * 3, indexing="ij")).reshape(3, -1).T]
    picks += [s * e for e in np.eye(3) for s in (-1.0, 1.0)]
    pose = np.full(mid.shape, np.nan)
    joints = None
    found = np.zeros(boxes.shape[0], dtype=bool)
    for p in picks:
        todo = np.flatnonzero(~found)
        if not todo.size:
            break
        cand = mid[todo] + p * 0.5 * (hi[todo] - lo[todo])
        ik = inverse_kinematics(robot, cand)
        ok = ik.reachable
        if joints is None:
            joints = np.full((boxes.shape[0],) + ik.joints.shape[1:], np.nan)
        pose[todo[ok]] = cand[ok]
        joints[todo[ok]] = ik.joints[ok]
        found[todo[ok]] = True
    return pose, found, joints


def box_remainder(robot, sets: tuple[SourceSet, ...], boxes: np.ndarray, sigmas, tight=False):
    """Bounds ``(k, 4)`` of the remainder of ``dx, dy, dphi, |dp|`` (mm, rad) that hold at every pose of each box.

    ``boxes`` ``(k, 6)`` ``[x0, x1, y0, y1, phi0, phi1]`` (mm, rad); ``sigmas`` the legs' working-mode branches
    (:func:`pmaccuracy.accuracy.global_worst.leg_branches`). The math is the module docstring's: the exact
    maximum of a quantity over the box is at most the first-order maximum over the box plus this. ``inf``
    where the box is too large for the bound (the Neumann series or the fixed point fails: split it) or holds
    no reachable anchor; 0 for boxes with no feasible pose.

    Returns two arrays: the bounds above and, with ``tight`` (True, or ``(k, 4)`` booleans: the quantities
    wanted per box), ``(k, 4)`` bounds of the exact maxima themselves over each box by the second-order model
    (module docstring, "Second-order bound"; ``inf`` where not computed or not certified); without it, ``(k, 3)``
    the change of the first-order maxima of ``dx, dy, dphi`` over the box that bound adds (a cheap estimate of
    how far it stays above the first-order maximum: where that alone does not close, the second-order bound is
    not worth its cost).
    """
    boxes = np.asarray(boxes, dtype=float).reshape(-1, 6)
    mode = np.ndim(tight) > 0 or bool(tight)
    if boxes.shape[0] > CHUNK:
        parts = [box_remainder(robot, sets, boxes[i:i + CHUNK], sigmas,
                               tight if np.ndim(tight) == 0 else tight[i:i + CHUNK])
                 for i in range(0, boxes.shape[0], CHUNK)]
        return np.vstack([p[0] for p in parts]), np.vstack([p[1] for p in parts])
    k = boxes.shape[0]
    out = np.full((k, 4), np.inf)
    total = np.full((k, 4), np.inf)
    slack = np.full((k, 3), np.inf)
    n_real = sum(len(s.cols) for s in sets)
    if k == 0 or n_real == 0:
        out[:] = 0.0
        return (out, total) if mode else (out, np.zeros((k, 3)))
    anchor, found, joints = _anchors(robot, boxes)
    x, y, ph = (Iv(boxes[:, 0], boxes[:, 1]), Iv(boxes[:, 2], boxes[:, 3]), Iv(boxes[:, 4], boxes[:, 5]))
    legs = [leg_box_state(chain, x, y, ph, s) for chain, s in zip(robot.chains, sigmas)]
    infeasible = np.any([lb.infeasible for lb in legs], axis=0)
    out[infeasible] = 0.0
    total[infeasible] = 0.0
    slack[infeasible] = 0.0
    idx = np.flatnonzero(found & ~infeasible)
    if not idx.size:
        return (out, total) if mode else (out, slack)
    aug, act = _augmented(robot, sets)
    model = _build_model(robot, aug, anchor[idx])
    N, nv = idx.size, 9 + model.n
    # d: the largest change of every column of v between the anchor and a feasible pose of the box
    d = np.zeros((N, nv))
    bx = boxes[idx]
    for c in range(3):
        d[:, c] = np.maximum(bx[:, 2 * c + 1] - anchor[idx, c], anchor[idx, c] - bx[:, 2 * c])
    col = {}
    for i, chain in enumerate(robot.chains):
        for kk, c in zip(chain.passive_indices, (3 + 2 * i, 4 + 2 * i)):
            col[(i, kk)] = c
    for i, kk, c in act:
        col[(i, kk)] = 9 + c
    for (i, kk), c in col.items():
        q = legs[i].q[kk]
        lo, hi, a = q.lo[idx], q.hi[idx], joints[idx, i, kk]
        if robot.chains[i].joints[kk].kind == "R":  # the enclosure moved by whole turns onto the anchor's value
            turns = np.round((a - 0.5 * (lo + hi)) / (2 * np.pi))
            lo, hi = lo + 2 * np.pi * turns, hi + 2 * np.pi * turns
        with np.errstate(invalid="ignore"):
            dd = np.maximum(hi - a, a - lo)
        d[:, c] = np.where(np.isfinite(dd), np.maximum(dd, 0.0), np.inf)
    want = np.broadcast_to(np.asarray(tight, dtype=bool), (k, 4))[idx]
    with np.errstate(all="ignore"):
        rem, tot, var = _remainder(model, sets, n_real, d, robot.characteristic_length, want)
    out[idx] = rem
    total[idx] = tot
    slack[idx] = var
    return (out, total) if mode else (out, slack)


def _remainder(model, sets, n_real: int, d: np.ndarray, scale: float, want: np.ndarray):
    """The box bound ``(N, 4)`` (module docstring) for the anchor model and the column changes ``d`` ``(N, nv)``."""
    N = model.z0.shape[0]
    nv = 9 + model.n
    zeros = np.zeros((N, nv))
    J = model.jacobian(zeros)
    Jz, Jd = J[..., :9], J[..., 9:9 + n_real]
    F0 = model.residual(zeros)
    cond = np.linalg.cond(Jz)
    ok = np.isfinite(cond) & (cond < 1e12) & np.all(np.isfinite(d), axis=1)
    Jinv = np.linalg.inv(np.where(ok[:, None, None], Jz, np.eye(9)))
    aJinv = np.abs(Jinv)
    tg, rg = model.tg, model.rg                              # (N, m, nv) real, complex
    atg, arg = np.abs(tg), np.abs(rg)
    dfin = np.where(np.isfinite(d), d, 0.0)
    T = np.einsum("nmv,nv->nm", atg, dfin)
    R = np.einsum("nmv,nv->nm", arg, dfin)
    G = np.abs(rg + 1j * model.r0[..., None] * tg)           # (N, m, nv)
    V = np.minimum(T, 2.0)[..., None] * G + atg * R[..., None]
    onehot = (model.leg_of[:, None] == np.arange(3)[None, :]).astype(float)
    leg = np.einsum("nmv,mi->niv", V, onehot)                # (N, 3, nv)
    dJ = np.zeros((N, 9, nv))
    dJ[:, 0::3], dJ[:, 1::3] = leg, leg
    dJz, dJd = dJ[..., :9], dJ[..., 9:9 + n_real]
    E = aJinv @ dJz
    rho = np.max(np.abs(np.linalg.eigvals(np.where(ok[:, None, None], E, 0.0))), axis=-1)
    ok &= rho < NEUMANN
    NE = np.linalg.inv(np.eye(9) - np.where(ok[:, None, None], E, 0.0))
    ok &= np.all(NE >= -1e-12, axis=(1, 2))
    K = np.maximum(NE, 0.0) @ aJinv * (1 + ROUND_REL)
    M = -Jinv @ Jd
    dM = K @ (dJd + dJz @ np.abs(M))
    akap = np.hypot(K[:, :, 0::3], K[:, :, 1::3])            # (N, 9, 3)
    tz, td = tg[..., :9], tg[..., 9:9 + n_real]
    rz, rd = rg[..., :9], rg[..., 9:9 + n_real]
    atz, arz = np.abs(tz), np.abs(rz)
    alpha = np.einsum("nmj,njk->nmk", tz, M) + td
    beta = np.einsum("nmj,njk->nmk", rz, M) + rd
    s_t = support(sets, np.einsum("nmj,njk->nmk", atz, dM))
    s_r = support(sets, np.einsum("nmj,njk->nmk", arz, dM))
    hX = support(sets, alpha) + s_t
    hD = np.hypot(support(sets, beta.real) + s_r, support(sets, beta.imag) + s_r)
    ar0 = np.abs(model.r0) + R
    JF0 = np.einsum("nij,nj->ni", K, np.abs(F0))

    def terms(b):
        return hX + np.einsum("nmj,nj->nm", atz, b), hD + np.einsum("nmj,nj->nm", arz, b)

    def phi(b):
        X, D = terms(b)
        rho_leg = (ar0 * X ** 2 / 2 + D * X) @ onehot
        return JF0 + np.einsum("nji,ni->nj", akap, rho_leg)

    b, fixed, L = close_box(phi, terms, arz, atz, ar0, akap, onehot, scale)
    X, D = terms(b)
    ok &= fixed & (L < CONTRACTION)
    # the term-by-term bound (4) of the rows x, y, phi, both signs: the Dt^2 terms keep the sign of Re c_m at the
    # anchor, widened by the largest change of c_m = conj(kappa_ji) exp(i theta_m) r_m over the box
    kap_a = Jinv[:, :3, 0::3] + 1j * Jinv[:, :3, 1::3]                        # (N, 3 rows, 3 legs)
    Kd = np.maximum(NE - np.eye(9), 0.0) @ aJinv * (1 + ROUND_REL)            # >= |J_z(P)^-1 - J_z(a)^-1|
    dkap = np.hypot(Kd[:, :3, 0::3], Kd[:, :3, 1::3])
    lg = model.leg_of
    c_a = np.conj(kap_a[..., lg]) * (np.exp(1j * model.t0) * model.r0)[:, None, :]   # (N, 3, m)
    dc = dkap[..., lg] * ar0[:, None, :] + np.abs(kap_a[..., lg]) * (
        np.minimum(T, 2.0) * np.abs(model.r0) + R)[:, None, :]
    csup = akap[:, :3][..., lg] * ar0[:, None, :]
    rest = np.einsum("nrm,nm->nr", csup, X ** 3 / 6) + np.einsum("nrm,nm->nr", akap[:, :3][..., lg], D * X)
    rows = [JF0[:, :3] + rest + np.einsum("nrm,nm->nr", np.maximum(s * c_a.real, 0.0) + dc, X ** 2 / 2)
            for s in (1.0, -1.0)]
    w = np.minimum(np.maximum(*rows), b[:, :3])
    rem = np.column_stack([w[:, 0], w[:, 1], w[:, 2], np.hypot(w[:, 0], w[:, 1])]) * (1 + ROUND_REL)
    total = np.full((N, 4), np.inf)
    var_first = np.where(ok[:, None], support(sets, dM[:, :3]), np.inf)
    sel = np.flatnonzero(ok & np.any(want[:, :3], axis=1))

    def second(rows, kap, dk, ak, g, dMr, f0):
        """The second-order bound (module docstring) of the row combinations ``kap`` ``(S, R, 3)`` (at the
        anchor; ``dk`` bounds their change over the box, ``ak`` their size), first-order maps ``g`` ``(S, R, n)``
        (``dMr`` their change), ``|J_z^-1 F0|`` part ``f0`` ``(S, R)``, at the boxes ``rows`` ``(S,)``: ``(S, R)``."""
        cp = np.conj(kap[..., lg]) * np.exp(1j * model.t0[rows])[:, None, :]       # (S, R, m)
        c = cp * model.r0[rows][:, None, :]
        al, be = alpha[rows], beta[rows]
        v = np.imag(cp[..., None] * be[:, None, :, :])                            # (S, R, m, n)
        H = (np.einsum("nrm,nmk,nml->nrkl", c.real / 2, al, al)
             + 0.5 * (np.einsum("nrmk,nml->nrkl", v, al) + np.einsum("nml,nrmk->nrlk", al, v)))
        quad = dual_bound(sets, g, H, refine=REFINE, sdp=False)
        Xa = support(sets, al)
        Da = np.hypot(support(sets, be.real), support(sets, be.imag))
        dX, dD = s_t[rows], np.sqrt(2.0) * s_r[rows]
        Xb, Db = Xa + dX, Da + dD
        turn = np.minimum(T[rows], 2.0)[:, None, :]
        dcp = dk[..., lg] + np.abs(kap[..., lg]) * turn
        dcr = dk[..., lg] * ar0[rows][:, None, :] + np.abs(kap[..., lg]) * (
            turn * np.abs(model.r0[rows])[:, None, :] + R[rows][:, None, :])
        var_h = (np.einsum("nrm,nm->nr", dcr, Xb ** 2 / 2)
                 + np.einsum("nrm,nm->nr", np.abs(c), dX * (2 * Xa + dX) / 2)
                 + np.einsum("nrm,nm->nr", dcp, Db * Xb) + np.einsum("nrm,nm->nr", np.abs(cp), dD * Xb + Da * dX))
        bb = b[rows]
        wt, wr = np.einsum("nmj,nj->nm", atz[rows], bb), np.einsum("nmj,nj->nm", arz[rows], bb)
        hXs, hDs = hX[rows], hD[rows]
        Xs, Ds = hXs + wt, hDs + wr
        aks = ak[..., lg]
        rest = (np.einsum("nrm,nm->nr", aks * ar0[rows][:, None, :], wt * (2 * hXs + wt) / 2 + Xs ** 3 / 6)
                + np.einsum("nrm,nm->nr", aks, wr * Xs + hDs * wt + Ds * Xs ** 2 / 2))
        return quad + support(sets, dMr) + var_h + f0 + rest

    if sel.size:
        two = lambda a: np.concatenate([a, a], axis=1)  # noqa: E731 (rows x, y, phi for s = +1 then -1)
        B = second(sel, np.concatenate([kap_a[sel], -kap_a[sel]], axis=1), two(dkap[sel]), two(akap[sel, :3]),
                   np.concatenate([M[sel, :3], -M[sel, :3]], axis=1), two(dM[sel, :3]), two(JF0[sel, :3]))
        total[sel, :3] = np.maximum(B[:, :3], B[:, 3:]) * (1 + ROUND_REL)
    sel = np.flatnonzero(ok & want[:, 3])
    if sel.size:
        # |dp| <= max_k u_k . p / cos(pi / K) over the K directions of the per-pose certificate
        ang = 2 * np.pi * (np.arange(N_DIRECTIONS) + 0.5) / N_DIRECTIONS
        u = np.stack([np.cos(ang), np.sin(ang)], axis=-1)

        def direction(kk, dd):
            rows, ux, uy = sel[kk], u[dd, 0][:, None], u[dd, 1][:, None]
            ax, ay = np.abs(ux), np.abs(uy)
            kap = (ux * kap_a[rows, 0] + uy * kap_a[rows, 1])[:, None]
            dk = (ax * dkap[rows, 0] + ay * dkap[rows, 1])[:, None]
            ak = (ax * akap[rows, 0] + ay * akap[rows, 1])[:, None]
            g = (ux * M[rows, 0] + uy * M[rows, 1])[:, None]
            dMr = (ax * dM[rows, 0] + ay * dM[rows, 1])[:, None]
            f0 = (ax[:, 0] * JF0[rows, 0] + ay[:, 0] * JF0[rows, 1])[:, None]
            return second(rows, kap, dk, ak, g, dMr, f0)[:, 0]

        ub = _direction_bounds(direction, sel.size)
        total[sel, 3] = np.max(ub, axis=-1) / math.cos(math.pi / N_DIRECTIONS) * (1 + ROUND_REL)
    return np.where(ok[:, None], rem, np.inf), total, var_first


def exact_lower(robot, sources, poses: np.ndarray) -> np.ndarray:
    """Best feasible exact maxima ``(m, 4)`` of ``dx, dy, dphi, |dp|`` (mm, rad) at reachable ``poses``
    ``(m, 3)`` (attained by configurations of the error set: lower bounds of the true maxima; NaN where the
    closure fails), as :func:`pmaccuracy.accuracy.certified.nonlinear_pose_errors`."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    if poses.shape[0] == 0:
        return np.zeros((0, 4))
    sets = error_set(robot, sources)
    model = _build_model(robot, sets, poses)
    lower, _, _ = _nonlinear(model, _first_order_map(model), sets)
    return np.column_stack([np.asarray(lower[q], dtype=float) for q in QUANTITIES])
