"""Interval enclosures of the legs' closed forms over pose boxes (the arithmetic: :mod:`pmaccuracy.numerics.interval`).

:func:`leg_box_state` runs a leg's closed-form inverse kinematics
(:meth:`pmaccuracy.model.chain.Chain.state`, same cases: one, two or three revolute
joints) on boxes of poses ``[x0, x1] x [y0, y1] x [phi0, phi1]`` (mm, rad):
joint values, directions, the vectors between joint centres, the constraint
wrench ``(f, m_P)`` and ``B_ii`` as intervals. Everything that holds at every
*feasible* pose of the box (leg reaches it, joints within their ranges, the
working mode's sign of ``B_ii``) is used to narrow the intervals, so the
enclosures bound the feasible part of a box straddling the workspace boundary;
a box proven to hold no feasible pose is flagged. :func:`box_maxima` turns the
legs' enclosures into upper bounds of ``dx, dy, dphi, dp`` (Eq. 21-22, the
zonotope of :func:`pmaccuracy.accuracy.bounds.zonotope_maxima`) with ``A^-1 = adj(A) /
det(A)`` (``+inf`` where the determinant's interval contains 0).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..model.sources import ErrorSources
from ..numerics.interval import GIv, NV, Iv, TWO_PI, iv_arcsin, Trig, Vec, angle_meets_range, cv_angle, iv_abs, iv_arccos, iv_intersect, iv_max, iv_sqr, iv_sqrt, t_cross, t_parts, v_cross, v_cv, v_dot


@dataclass(frozen=True)
class LegBox:
    """One leg's closed forms enclosed over boxes of poses ``(n,)``.

    q : three :class:`Iv` joint values (mm or rad; R values not wrapped)
    dirs : three :class:`Vec` unit directions of the joints (base frame)
    seg : four :class:`Vec` mm: ``seg[k]`` from joint centre ``k`` to the next (``seg[3] = 0``);
        centre 3 is the end frame's origin
    to_p : four :class:`Vec` mm: joint centre ``k`` (3: end origin) minus the platform centre P
    f : :class:`Vec` unit constraint force (0 for a pure couple); m_P : :class:`Iv` mm, its moment about P;
    B : :class:`Iv` ``B_ii``;  var : the angle variables of the phasors
    infeasible : bool ``(n,)``: no pose of the box is reachable within the joint ranges on the working mode
    line : the index of the joint centre on the constraint line (None for a couple)
    cut : where a narrowing removed part of an enclosure (the closed forms hold on part of the box only)
    """

    q: tuple
    dirs: tuple
    seg: tuple
    to_p: tuple
    f: Vec
    m_P: Iv
    B: Iv
    var: tuple
    infeasible: np.ndarray
    line: int | None
    m_P_trig: Trig | None = None
    cut: np.ndarray | None = None   # (n,) a narrowing removed part of an enclosure (part of the box is unreachable)

    def between(self, a: int, b: int) -> Vec:
        """Centre ``b`` minus centre ``a`` (``0..3``), as a sum of segments (no absolute positions)."""
        lo, hi = min(a, b), max(a, b)
        total = Vec([])
        for k in range(lo, hi):
            total = total + self.seg[k]
        return total if a <= b else -total


PHI, T, U, W = (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1)
#: rad (and relative, for the adjugate): slack of the intersection of two enclosures of one quantity (rounding).
MEET_SLACK = 1e-12
ZERO = (0, 0, 0, 0)


def _meet_angles(a: Iv, b: Iv) -> Iv:
    """Intersection of two enclosures of the same angle (mod 2 pi): ``b`` moved by whole turns onto ``a``'s
    middle; where either is wider than pi, ``a`` unchanged. ``b`` is widened by :data:`MEET_SLACK` rad first, so
    that two enclosures of one angle computed with different roundings (points, tiny boxes) never meet empty."""
    turns = np.round((a.mid - b.mid) / TWO_PI)
    lo, hi = b.lo + TWO_PI * turns - MEET_SLACK, b.hi + TWO_PI * turns + MEET_SLACK
    ok = (a.width < np.pi) & (b.width < np.pi) & np.isfinite(lo) & np.isfinite(hi)
    val = Iv(np.where(ok, np.maximum(a.lo, lo), a.lo), np.where(ok, np.minimum(a.hi, hi), a.hi))
    # the same function (up to whole turns): either's derivative enclosure holds
    if isinstance(a, GIv):
        return GIv.make(val, a.d)
    return GIv.make(val, b.d) if isinstance(b, GIv) else val


def leg_box_state(chain, x: Iv, y: Iv, phi: Iv, sigma: float, tol: float = 1e-9) -> LegBox:
    """Interval version of the leg's inverse kinematics on branch ``sigma`` (:meth:`Chain.state`) over boxes.

    Mirrors the closed forms of :meth:`pmaccuracy.model.chain.Chain.ik_branches` (one R:
    two slides from a 2x2 system; two R: a quadratic in the slide, then the
    turning angle ``t`` from the angles of the matched vectors; three R: law of
    cosines, angles ``t`` and ``u``), vectors as phasor sums (:class:`Vec`).
    Narrowing at feasible poses: slide values cut to their ranges (slack
    ``tol``), discriminants to ``>= 0``, the law-of-cosines argument to
    ``[-1, 1]``, ``B_ii`` to the working mode's sign; R values checked against
    their ranges modulo 2 pi. Where a cut leaves nothing the box is infeasible.
    """
    n = x.lo.shape[0]
    joints = chain.joints
    infeasible = np.zeros(n, dtype=bool)
    cut = np.zeros(n, dtype=bool)
    var = [phi, Iv(np.zeros(n)), Iv(np.zeros(n)), Iv(np.zeros(n))]
    eb = complex(np.exp(1j * chain.base_angle))
    base_z = complex(*chain.base)
    platform_z = complex(*chain.platform)
    pz = Vec([(x, ZERO, 1.0 + 0j), (y, ZERO, 1j)])
    att = Vec.const(platform_z, PHI)                       # exp(i phi) platform, base frame
    g = (pz + att - base_z).scale(eb.conjugate())            # end origin in the leg frame
    dang = chain.platform_angle - chain.base_angle
    oc = np.cumsum([j.offset for j in joints])
    links = [complex(*j.link) for j in joints]
    rot = [complex(np.exp(1j * o)) for o in oc]
    S = phi + (dang - oc[2])
    e_S = complex(np.exp(1j * (dang - oc[2])))             # exp(i S) = e_S exp(i phi)
    rs = [k for k, j in enumerate(joints) if j.kind == "R"]
    q: list = [None, None, None]

    def narrow(val: Iv, lo, hi) -> Iv:
        nonlocal infeasible, cut
        out = iv_intersect(val, lo, hi)
        infeasible = infeasible | out.empty()
        cut = cut | (out.lo > val.lo) | (out.hi < val.hi)
        return out

    def cut_slide(k: int, val: Iv) -> Iv:
        lo, hi = joints[k].range
        return narrow(val, lo - tol, hi + tol)

    def disc_root(disc: Iv) -> Iv:
        nonlocal infeasible, cut
        infeasible = infeasible | (disc.hi < 0)
        cut = cut | (disc.lo <= 0)
        return iv_sqrt(disc)

    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        if len(rs) == 1:
            m = rs[0]
            d = [Vec.const(rot[k] * e_S, PHI) if k >= m else Vec.const(rot[k]) for k in range(3)]
            rhs = g
            for k in range(3):
                rhs = rhs - d[k].scale(links[k])
            a, b = (k for k in range(3) if k != m)
            den = v_cross(d[a], d[b], var)
            q[a] = cut_slide(a, v_cross(rhs, d[b], var) / den)
            q[b] = cut_slide(b, v_cross(d[a], rhs, var) / den)
            q[m] = S
        elif len(rs) == 2:
            m, nn = rs
            k = 3 - m - nn
            fixed = Vec.const(sum(rot[j] * links[j] for j in range(m)) + 0j) + \
                Vec.const(sum(rot[j] * links[j] for j in range(nn, 3)) * e_S + 0j, PHI)
            V = complex(sum(np.exp(1j * oc[j]) * links[j] for j in range(m, nn)))
            Wv = g - fixed
            if m <= k < nn:
                ek = Vec.const(rot[k])
                root = disc_root(v_dot(Wv, Wv, var) - (V.real * rot[k].imag - V.imag * rot[k].real) ** 2)
                qk = cut_slide(k, root * sigma + (-(V.real * rot[k].real + V.imag * rot[k].imag)))
                t = cv_angle(v_cv(Wv, var)) - cv_angle(v_cv(Vec.const(V) + ek.scale(qk), var))
            else:
                ek = Vec.const(rot[k] * e_S, PHI) if k >= nn else Vec.const(rot[k])
                root = disc_root(abs(V) ** 2 - iv_sqr(v_cross(Wv, ek, var)))
                qk = cut_slide(k, v_dot(Wv, ek, var) + root * sigma)
                t = cv_angle(v_cv(Wv - ek.scale(qk), var)) - float(np.angle(V))
                # W - q e_k = e_k (i s - sigma sqrt(|V|^2 - s^2)) with s = e_k x W: its angle is
                # arg e_k + (arcsin(s/|V|) or pi - arcsin(s/|V|)), monotone in s (one occurrence)
                sv = narrow(v_cross(ek, Wv, var), -abs(V), abs(V))
                a = iv_arcsin(sv * (1.0 / abs(V)))
                a = a if sigma < 0 else np.pi - a
                arg_ek = phi + float(np.angle(rot[k] * e_S)) if k >= nn else float(np.angle(rot[k]))
                t = _meet_angles(a + arg_ek - float(np.angle(V)), t)
                infeasible = infeasible | t.empty()
            var[1] = t
            q[k] = qk
            q[m] = t
            q[nn] = S - t
            d = [Vec.const(rot[j]) if j < m else Vec.const(rot[j], T) if j < nn else Vec.const(rot[j] * e_S, PHI)
                 for j in range(3)]
        else:
            l1, l2, l3 = links
            L1, L2 = abs(l1), abs(l2)
            Wv = g - Vec.const(l3 * complex(np.exp(1j * dang)), PHI)
            c = (v_dot(Wv, Wv, var) - (L1 ** 2 + L2 ** 2)) / (2 * L1 * L2)
            c = narrow(c, -1.0 - 1e-12, 1.0 + 1e-12)
            ac = iv_arccos(c)
            rel = (ac if sigma > 0 else -ac) + (float(np.angle(l1)) - float(np.angle(l2)))
            var[2] = rel
            aW = cv_angle(v_cv(Wv, var))
            t1 = aW - cv_angle(v_cv(Vec.const(l1) + Vec.const(l2, U), var))
            # the second link's angle t1 + rel = arg W - arg(l1 exp(-i rel) + l2): rel enters once; both
            # enclosures hold (aligned to the same turn), so their intersection does
            t2 = aW - cv_angle(v_cv(Vec.const(l1, (0, 0, -1, 0)) + Vec.const(l2), var))
            t2 = _meet_angles(t2, t1 + rel)
            infeasible = infeasible | t2.empty()
            var[1] = t2
            q[0] = t1 - oc[0]
            q[1] = rel - joints[1].offset
            q[2] = S - q[0] - q[1]
            d = [Vec.const(1.0, (0, 1, -1, 0)), Vec.const(1.0, T), Vec.const(complex(np.exp(1j * dang)), PHI)]
        for k, joint in enumerate(joints):
            if joint.kind == "R" and joint.limited:
                lo, hi = joint.range
                infeasible = infeasible | ~angle_meets_range(q[k], lo, hi, tol)
        dirs = tuple(dk.scale(eb) for dk in d)
        seg = []
        for k, joint in enumerate(joints):
            if joint.kind == "P":
                seg.append(dirs[k].scale(q[k]) + dirs[k].scale(links[k]))
            else:
                seg.append(dirs[k].scale(links[k]))
        seg.append(Vec([]))
        to_p = [None, None, None, att]
        for k in (2, 1, 0):
            to_p[k] = to_p[k + 1] - seg[k]
        lb = LegBox(q=tuple(q), dirs=dirs, seg=tuple(seg), to_p=tuple(to_p), f=Vec([]), m_P=Iv(0.0), B=Iv(0.0),
                    var=tuple(var), infeasible=infeasible, line=None, cut=cut)
        return _wrench(chain, lb, n)


def _wrench(chain, lb: LegBox, n: int) -> LegBox:
    """The constraint wrench of the passive joints and ``B_ii`` (:meth:`Chain._screw_state` over boxes)."""
    i, j = chain.passive_indices
    ki, kj = chain.joints[i].kind, chain.joints[j].kind
    a = chain.actuated_index
    act_R = chain.joints[a].kind == "R"
    infeasible = lb.infeasible
    var = list(lb.var)
    if ki == "P" and kj == "P":
        return LegBox(q=lb.q, dirs=lb.dirs, seg=lb.seg, to_p=lb.to_p, f=Vec([]), m_P=Iv(np.ones(n)),
                      B=Iv(np.ones(n) if act_R else np.zeros(n)), var=lb.var, infeasible=infeasible, line=None,
                      m_P_trig=Trig.const(1.0), cut=lb.cut)
    if ki == "R" and kj == "R":
        segs = [k for k in range(i, j) if lb.seg[k].terms]
        k = segs[0] if len(segs) == 1 else None
        slide = k is not None and chain.joints[k].kind == "P" and chain.joints[k].link == (0.0, 0.0)
        if k is not None and chain.joints[k].kind == "R":   # one rigid link: f along it
            f = lb.dirs[k].scale(links_unit(chain, k))
        elif slide and np.all((lb.q[k].lo > 0) | lb.infeasible):   # one slide of positive length: f along it
            f = lb.dirs[k]
        elif slide and np.all((lb.q[k].hi < 0) | lb.infeasible):
            f = lb.dirs[k].scale(-1.0)
        else:
            var[3] = cv_angle(v_cv(lb.between(i, j), var))
            f = Vec.const(1.0, W)
        line = i
    else:
        line = i if ki == "R" else j
        f = (lb.dirs[j] if ki == "R" else lb.dirs[i]).scale(1j)
    var = tuple(var)
    m_P_trig = t_cross(lb.to_p[line], f)
    m_P = m_P_trig.iv(var)
    B = v_cross(lb.between(a, line), f, var) if act_R else v_dot(f, lb.dirs[a], var)
    cut = lb.cut
    if chain.n_branches == 2:   # on the working mode's branch sign(B_ii) = working_mode
        B0 = B
        B = iv_intersect(B, 0.0, np.inf) if chain.working_mode > 0 else iv_intersect(B, -np.inf, 0.0)
        infeasible = infeasible | B.empty()
        if cut is not None:
            cut = cut | (B.lo > B0.lo) | (B.hi < B0.hi)
    return LegBox(q=lb.q, dirs=lb.dirs, seg=lb.seg, to_p=lb.to_p, f=f, m_P=m_P, B=B, var=var,
                  infeasible=infeasible, line=line, m_P_trig=m_P_trig, cut=cut)


def links_unit(chain, k: int) -> complex:
    lz = complex(*chain.joints[k].link)
    return lz / abs(lz)


def leg_half_width_box(chain, leg_sources, lb: LegBox) -> Iv:
    """Interval of the leg's half-width ``c_i`` (mm): :func:`pmaccuracy.model.sources.states_half_widths` over boxes.

    Each joint moment ``m_P + (P - c) x f`` is written ``(line - c) x f`` with the
    vector between the two joint centres as a sum of segments.
    """
    n = lb.infeasible.shape[0]
    couple = lb.line is None
    var = lb.var
    c = Iv(np.zeros(n))
    abs_f = 0.0 if couple else 1.0
    for k, (joint, e) in enumerate(zip(chain.joints, leg_sources)):
        if e.radial or e.position:
            c = c + (e.radial + e.position) * abs_f
        if e.direction:
            mom = Iv(np.ones(n)) if couple else iv_abs(v_cross(lb.between(k, lb.line), lb.f, var))
            c = c + mom * e.direction
        if e.angular or e.lateral:
            # moment about the block's centre: a bushing at centre k, a carriage at b_k = centre k + q_k e_k
            if couple:
                tilt = Iv(np.ones(n))
            elif joint.block_kind == "bushing":
                tilt = iv_abs(v_cross(lb.between(k, lb.line), lb.f, var))
            else:
                tilt = iv_abs(v_cross(lb.between(k, lb.line) - lb.dirs[k].scale(lb.q[k]), lb.f, var))
            if e.angular:
                c = c + tilt * e.angular
            if e.lateral:
                shift = iv_abs(v_dot(lb.f, lb.dirs[k].scale(1j), var)) * e.lateral
                c = c + iv_max(shift, tilt * (2 * e.lateral / e.block_length))
        if e.actuator:
            c = c + iv_abs(lb.B) * e.actuator
        if e.length and joint.link != (0.0, 0.0):
            c = c + iv_abs(v_dot(lb.f, lb.dirs[k].scale(links_unit(chain, k)), var)) * e.length
    return c


#: Most pieces a leg's turning angle is split into by :func:`box_maxima` (near the leg's serial singularity).
MAX_ANGLE_PIECES = 32


def box_maxima(robot, sources: ErrorSources, boxes: np.ndarray, sigmas: tuple[float, float, float],
               tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Upper bounds of ``dx, dy, dphi, dp`` (mm, mm, rad, mm) over boxes of poses: the first three outputs of
    :func:`box_bounds`."""
    return box_bounds(robot, sources, boxes, sigmas, tol)[:3]


def box_bounds(robot, sources: ErrorSources, boxes: np.ndarray, sigmas: tuple[float, float, float],
               tol: float = 1e-9, threshold: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Upper bounds of ``dx, dy, dphi, dp`` (mm, mm, rad, mm) over boxes of poses, by the smaller of two
    enclosures, refined near serial singularities; and the bounds of their slopes.

    Natural enclosure: :func:`box_maxima_once` over the box (interval arithmetic on the closed forms; it
    overestimates by a fraction that shrinks like the box's width ``w``). Mean-value form: with ``c`` the
    box's centre and ``r`` its half-widths (mm, mm, rad), for every pose ``X`` of the box::

        Q(X) <= Q(c) + sum_j G_j r_j,     G_j >= |dQ/dX_j| over the box

    (mean-value theorem along the segment ``c -> X``, Clarke's generalized gradient where ``|.|`` or ``max``
    make ``Q`` non-smooth), ``G`` from the closed forms differentiated in interval arithmetic
    (:class:`pmaccuracy.numerics.interval.GIv`); its overestimation shrinks like ``w^2``. ``G`` is
    ``inf`` wherever a closed form is not smooth over the whole box (a square root or ``1/x`` at 0, the box
    cut by a joint range or the reach: such boxes keep the natural bound only); ``Q(c)`` is
    :func:`box_maxima_once` at the centre (``inf`` if the centre is not feasible). For ``dp``, the largest of
    the four sign patterns' norms of Eq. 22, each pattern gets its own form and the largest is taken. Both
    bounds hold, the smaller is returned.

    ``threshold`` ``(n, 4)`` (optional): the mean-value form is only evaluated for the boxes whose natural
    enclosure exceeds it for some quantity (the others are closed already; it costs several natural ones).

    The fourth output ``(n, 4, 3)``: ``G_j r_j`` divided by the bound (the share of the bound each side of
    the box is responsible for; ``inf`` where unknown or where the natural enclosure is the smaller), which
    the branch and bound (:func:`pmaccuracy.accuracy.global_worst.global_worst`) uses to choose the side to
    bisect.

    >>> from pmaccuracy.model.manipulator import Manipulator
    >>> from pmaccuracy.accuracy.global_worst import as_sources
    >>> robot = Manipulator.preset("symmetric_3rpr")
    >>> box = np.array([[0.0, 0.2, 0.0, 0.2, 0.0, 0.002]])   # 0.2 x 0.2 mm x 0.11 deg
    >>> upper, infeasible, det_zero, share = box_bounds(robot, as_sources(robot, "rpr_typical"), box, (1.0, 1.0, 1.0))
    >>> bool(np.all(np.isfinite(share[0, :3])))   # the mean-value form is the smaller bound of dx, dy, dphi
    True

    Then, in the boxes where a leg's
    turning angle ``t`` (its first angle variable, ``var[1]`` of :class:`LegBox`) has an enclosure much wider
    than the box (width ``w_t > 2 s / ell``, ``s`` the box's largest side with phi times the characteristic
    length ``ell``, mm): a box touching the leg's serial singularity (the workspace boundary where its distal
    link is normal to the guide, ``B_ii = 0``), where ``t`` varies like the square root of the distance and
    every enclosure using ``t`` as an independent interval stays loose. There the leg whose ratio
    ``w_t ell / s`` is largest has ``[t]`` cut into ``K = min(ceil(w_t ell / (2 s)),``
    :data:`MAX_ANGLE_PIECES` ``)`` equal pieces and the bounds are evaluated once per piece. Every feasible pose of
    the box has its ``t`` in one piece, so the largest bound over the pieces not proven infeasible encloses the
    maximum too; the smaller of the two enclosures is returned (both hold).
    """
    upper, infeasible, det_zero, t, _, cut = box_maxima_once(robot, sources, boxes, sigmas, tol, parts=True)
    share = np.full(upper.shape + (NV,), np.inf)
    need = ~infeasible & ~det_zero & ~cut   # (a cut makes the slopes unknown: the form would be inf)
    if threshold is not None:
        need &= np.any(upper > threshold, axis=1)
    if np.any(need):
        idx = np.flatnonzero(need)
        sub = boxes[idx]
        nat, _, _, _, slopes, t_slopes, _ = box_maxima_once(robot, sources, sub, sigmas, tol, gradients=True)
        half = 0.5 * (sub[:, 1::2] - sub[:, 0::2])
        centre = np.repeat(0.5 * (sub[:, 0::2] + sub[:, 1::2]), 2, axis=1)
        f_c, c_out, _, _, t_c, _ = box_maxima_once(robot, sources, centre, sigmas, tol, parts=True)
        with np.errstate(invalid="ignore"):
            spread = np.where(half[:, None, :] > 0, slopes * half[:, None, :], 0.0)   # (k, 4, 3)
            mv = f_c + spread.sum(axis=-1)
            # dp = max over the sign patterns t of |v_t|: the largest of the patterns' own mean-value forms
            t_spread = np.where(half[:, None, :] > 0, t_slopes * half[:, None, :], 0.0)
            mv[:, 3] = np.max(t_c + t_spread.sum(axis=-1), axis=1)
        mv = np.where(c_out[:, None] | ~np.isfinite(mv), np.inf, mv)
        best = np.minimum(upper[idx], mv)
        spread = np.where((mv <= upper[idx])[:, :, None], spread, np.inf)   # the split rule where the form binds
        with np.errstate(invalid="ignore", divide="ignore"):
            sh = np.where(np.isfinite(best)[:, :, None] & (best[:, :, None] > 0),
                          spread / np.where(best > 0, best, 1.0)[:, :, None], np.inf)
        share[idx] = np.where(np.isnan(sh), np.inf, sh)
        upper = upper.copy()
        upper[idx] = best
    ell = robot.characteristic_length
    side = np.max((boxes[:, 1::2] - boxes[:, 0::2]) * np.array([1.0, 1.0, ell]), axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(np.isfinite(t[:, :, 1] - t[:, :, 0]), (t[:, :, 1] - t[:, :, 0]) * ell, 0.0) / \
            np.maximum(side, 1e-300)[:, None]
    leg = np.argmax(ratio, axis=1)
    rows = np.arange(boxes.shape[0])
    pieces = np.minimum(np.ceil(ratio[rows, leg] / 2.0), MAX_ANGLE_PIECES)
    split = ~infeasible & (pieces >= 2)
    if not np.any(split):
        return upper, infeasible, det_zero, share
    idx = np.flatnonzero(split)
    k = pieces[idx].astype(int)
    rep = np.repeat(idx, k)                                      # one row per piece
    j = np.arange(rep.size) - np.repeat(np.cumsum(k) - k, k)     # piece number within its box
    kk = np.repeat(k, k).astype(float)
    lo, hi = t[rep, leg[rep], 0], t[rep, leg[rep], 1]
    width = (hi - lo) / kk
    limits = np.empty((rep.size, len(robot.chains), 2))
    limits[:, :, 0], limits[:, :, 1] = -np.inf, np.inf
    limits[np.arange(rep.size), leg[rep], 0] = np.where(j == 0, lo, lo + j * width)
    limits[np.arange(rep.size), leg[rep], 1] = np.where(j == kk - 1, hi, lo + (j + 1) * width)
    up_p, inf_p, dz_p, _ = box_maxima_once(robot, sources, boxes[rep], sigmas, tol, limits)
    up_p = np.where(inf_p[:, None], 0.0, up_p)                   # pieces holding no feasible pose
    up_s = np.zeros((idx.size, 4))
    np.maximum.at(up_s, np.searchsorted(idx, rep), up_p)
    all_inf = np.ones(idx.size, dtype=bool)
    np.logical_and.at(all_inf, np.searchsorted(idx, rep), inf_p)
    dz_s = np.zeros(idx.size, dtype=bool)
    np.logical_or.at(dz_s, np.searchsorted(idx, rep), dz_p & ~inf_p)
    upper, infeasible, det_zero = upper.copy(), infeasible.copy(), det_zero.copy()
    upper[idx] = np.minimum(upper[idx], up_s)
    infeasible[idx] = all_inf
    det_zero[idx] = det_zero[idx] & dz_s
    return upper, infeasible, det_zero, share


def box_maxima_once(robot, sources: ErrorSources, boxes: np.ndarray, sigmas: tuple[float, float, float],
                    tol: float = 1e-9, angle_limits: np.ndarray | None = None, gradients: bool = False,
                    parts: bool = False) -> tuple:
    """Upper bounds of ``dx, dy, dphi, dp`` (mm, mm, rad, mm) over boxes of poses.

    Parameters
    ----------
    boxes : ``(n, 6)`` ``[x0, x1, y0, y1, phi0, phi1]`` mm, mm, rad
    sigmas : each leg's IK branch (the root sign of its working mode)
    angle_limits : optional ``(n, 3, 2)`` rad: only the poses whose leg ``i`` turning angle ``t`` (``var[1]``)
        lies in ``[lo, hi]`` count (``-inf, inf``: no limit); ``[t]`` is intersected with it

    gradients : also return ``(n, 4, 3)`` bounds of ``|dQ/dx|, |dQ/dy|, |dQ/dphi|`` over the box (mm/mm,
        mm/rad; rad/mm, rad/rad for dphi) for ``Q = dx, dy, dphi, dp`` (:class:`GIv`; ``inf`` where unknown),
        the same ``(n, 4, 3)`` for the four sign patterns ``t`` whose largest norm is ``dp``, and those four
        norms' upper bounds ``(n, 4)``
    parts : (without ``gradients``) also return the four norms' upper bounds ``(n, 4)`` and ``(n,)`` where a
        narrowing removed part of an enclosure (the closed forms hold on part of the box only)

    Returns ``upper (n, 4)`` (``+inf`` where ``det A`` may vanish), ``infeasible (n,)``
    (no pose of the box, with the angle limits, is in the workspace), ``det_has_zero (n,)`` and each leg's
    ``[t]`` ``(n, 3, 2)`` rad (and the gradient bounds when asked).
    With ``c_i`` the half-width intervals and ``A^-1 = adj(A) / det A``::

        dx <= sum_i c_i^hi |A^-1[0, i]|^hi                  (likewise dy, dphi)
        dp <= max over t of sqrt(max v_x^2 + max v_y^2),  v = sum_i t_i c_i A^-1[:2, i]
    """
    x, y, phi = Iv(boxes[:, 0], boxes[:, 1]), Iv(boxes[:, 2], boxes[:, 3]), Iv(boxes[:, 4], boxes[:, 5])
    if gradients:
        unit = [tuple(Iv(float(j == k)) for k in range(NV)) for j in range(NV)]
        x, y, phi = (GIv(v.lo, v.hi, u) for v, u in zip((x, y, phi), unit))
    n = boxes.shape[0]
    infeasible = np.zeros(n, dtype=bool)
    cut = np.zeros(n, dtype=bool)
    rows, rows_iv, cs, t_encl = [], [], [], []
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        gvar = [phi]
        for i, (chain, leg, sigma) in enumerate(zip(robot.chains, sources.legs, sigmas)):
            lb = leg_box_state(chain, x, y, phi, sigma, tol)
            if angle_limits is not None:
                t = lb.var[1]
                t = Iv(np.maximum(t.lo, angle_limits[:, i, 0]), np.minimum(t.hi, angle_limits[:, i, 1]))
                lb = _wrench(chain, replace(lb, var=(lb.var[0], t) + tuple(lb.var[2:]),
                                            infeasible=lb.infeasible | t.empty()), n)
            t_encl.append((np.broadcast_to(lb.var[1].lo, (n,)), np.broadcast_to(lb.var[1].hi, (n,))))
            infeasible |= lb.infeasible
            if lb.cut is not None:
                cut |= lb.cut
            index = (0, 1 + 3 * i, 2 + 3 * i, 3 + 3 * i)
            gvar.extend(lb.var[1:])
            fx, fy = t_parts(lb.f)
            rows.append(tuple(t.remap(index, 10) for t in (fx, fy, lb.m_P_trig)))
            fc = v_cv(lb.f, lb.var)
            rows_iv.append((fc.re, fc.im, lb.m_P))
            cs.append(leg_half_width_box(chain, leg, lb))
        A = rows

        def minor(r0, r1, c0, c1):   # a trigonometric polynomial: one interval evaluation at the end
            return A[r0][c0] * A[r1][c1] - A[r0][c1] * A[r1][c0]

        # adj(A)[r, i] = cofactor of A[i, r]
        adj = [[None] * 3 for _ in range(3)]
        for i in range(3):
            ri = [k for k in range(3) if k != i]
            for r in range(3):
                cc = [k for k in range(3) if k != r]
                m = minor(ri[0], ri[1], cc[0], cc[1])
                adj[r][i] = m if (i + r) % 2 == 0 else -m
        # the same with interval products; both enclose the true values, so their intersection does
        B_ = rows_iv
        adj_iv = [[None] * 3 for _ in range(3)]
        for i in range(3):
            ri = [k for k in range(3) if k != i]
            for r in range(3):
                cc = [k for k in range(3) if k != r]
                m = B_[ri[0]][cc[0]] * B_[ri[1]][cc[1]] - B_[ri[0]][cc[1]] * B_[ri[1]][cc[0]]
                adj_iv[r][i] = m if (i + r) % 2 == 0 else -m
        det_iv = B_[0][0] * adj_iv[0][0] + B_[0][1] * adj_iv[1][0] + B_[0][2] * adj_iv[2][0]

        def meet(a: Iv, b: Iv) -> Iv:   # two enclosures of one function: either derivative holds
            slack = MEET_SLACK * np.maximum(np.abs(b.lo), np.abs(b.hi))
            val = Iv(np.maximum(a.lo, b.lo - slack), np.minimum(a.hi, b.hi + slack))
            return GIv.make(val, a.d) if isinstance(a, GIv) else GIv.make(val, b.d) if isinstance(b, GIv) else val

        det = meet((A[0][0] * adj[0][0] + A[0][1] * adj[1][0] + A[0][2] * adj[2][0]).iv(gvar), det_iv)
        adj = [[meet(adj[r][i].iv(gvar), adj_iv[r][i]) for i in range(3)] for r in range(3)]
        det_zero = det.contains_zero() | ~np.isfinite(det.lo) | ~np.isfinite(det.hi)
        inv = [[adj[r][i] / det for i in range(3)] for r in range(3)]
        upper = np.zeros((n, 4))
        for r in range(3):
            total = np.zeros(n)
            for i in range(3):
                total = total + cs[i].hi * iv_abs(inv[r][i]).hi
            upper[:, r] = total
        best = np.zeros(n)
        slopes = np.zeros((n, 8, NV))   # dx, dy, dphi, dp; then dp's four sign patterns
        per_t = np.zeros((n, 4))
        for it, t in enumerate(((1, 1, 1), (1, 1, -1), (1, -1, 1), (1, -1, -1))):
            vx, vy = Iv(0.0), Iv(0.0)
            for i in range(3):
                vx = vx + cs[i] * inv[0][i] * float(t[i])
                vy = vy + cs[i] * inv[1][i] * float(t[i])
            per_t[:, it] = np.sqrt(iv_sqr(vx).hi + iv_sqr(vy).hi)
            best = np.maximum(best, per_t[:, it])
            if gradients:   # max_t g_t(X) <= max_t (g_t(c) + sum_j |dg_t/dX_j| r_j)
                norm = iv_sqrt(iv_sqr(vx) + iv_sqr(vy))
                slopes[:, 4 + it] = _magnitude(norm, n)
                slopes[:, 3] = np.maximum(slopes[:, 3], slopes[:, 4 + it])
        upper[:, 3] = best
        if gradients:
            for r in range(3):
                total = Iv(0.0)
                for i in range(3):
                    total = total + cs[i] * iv_abs(inv[r][i])
                slopes[:, r] = _magnitude(total, n)
    upper = np.where(det_zero[:, None] | np.isnan(upper), np.inf, upper)
    t_out = np.stack([np.stack(p, axis=-1) for p in t_encl], axis=1)
    if gradients:
        return upper, infeasible, det_zero, t_out, np.where(det_zero[:, None, None], np.inf, slopes[:, :4]), \
            np.where(det_zero[:, None, None], np.inf, slopes[:, 4:]), np.where(det_zero[:, None], np.inf, per_t)
    if parts:
        return upper, infeasible, det_zero, t_out, np.where(det_zero[:, None], np.inf, per_t), cut
    return upper, infeasible, det_zero, t_out


def _magnitude(v: Iv, n: int) -> np.ndarray:
    """``(n, NV)`` bounds of the partial derivatives' magnitudes of ``v`` (inf without derivatives)."""
    if not isinstance(v, GIv):
        return np.full((n, NV), np.inf)
    return np.broadcast_to(v.magnitude(), (n, NV)) if np.ndim(v.magnitude()) == 2 else \
        np.broadcast_to(v.magnitude()[None, :], (n, NV))
