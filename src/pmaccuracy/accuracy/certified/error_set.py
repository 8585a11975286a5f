"""The error set: its independent sources (intervals, disks, rhombi, sector rectangles), support functions,
constraint matrices of the S-lemma, projection onto the set and conversion to joint displacements
(package docstring, "Error set"); the constants of the certificate."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from ...model.sources import JointDisplacements

#: The four quantities, in output order.
QUANTITIES = ("dx", "dy", "dphi", "dp")
#: Directions used for the bound of |dp| (inflation 1 / cos(pi / K) = 1 + 7.5e-5).
N_DIRECTIONS = 256
#: Outward rounding of every certified value: relative and absolute (times the robot's length scale).
ROUND_REL, ROUND_ABS = 1e-9, 1e-12
#: Interior-point schedule of :func:`dual_bound`: mu is multiplied by MU_FACTOR every MU_EVERY Newton steps.
MU_FACTOR, MU_EVERY = 0.3, 4
#: :func:`dual_bound` solves a row again as a semidefinite program when its final gradient exceeds this (the hard
#: case: the optimum's Lambda - H is singular and the Newton steps in lambda crawl).
HARD_CASE_GRADIENT = 1e4
#: Convergence tolerance of :func:`dual_bound` for the branch and bound's pieces (rows with a target): their
#: bounds then differ by about 1e-9 relative from those at the default 1e-7, 30 % faster.
PIECE_RTOL = 1e-5
#: Largest accepted Lipschitz constant of the remainder map on the certified box (any value below 1 proves
#: uniqueness; the margin covers the rounding of its estimate).
CONTRACTION = 0.9


# ============================================================================ error set
@dataclass(frozen=True)
class SourceSet:
    """One independent source of the error set (module docstring, "Error set").

    kind : ``"interval"``, ``"disk"``, ``"rhombus"`` or ``"rect"`` (a piece of a cut disk, below)
    leg, joint : 0-based indices;  field : ``"turn"``, ``"tilt"``, ``"dq"``, ``"dl"``, ``"shift"`` or
        ``"lateral"`` (the fields of :class:`~pmaccuracy.model.sources.JointDisplacements`; ``"lateral"``: sigma, tau)
    eps : half-width (mm or rad); block_length : L (mm) of a rhombus
    cols : indices of its parameters in ``delta`` (1 or 2; disk ``(dx, dy)``, rhombus ``(sigma, tau)``)
    angle, eps_t, sector : only for a ``"rect"``: the rectangle ``|u_r . d| <= eps``, ``|u_t . d| <= eps_t``
        about its centre (``u_r = (cos angle, sin angle)``, ``u_t`` = ``u_r`` turned by +90 deg, mm) that
        contains the annular sector ``sector = (theta_c, half, r1, r2, ox, oy)`` of the cut disk
        ``{o + r (cos t, sin t): r1 <= r <= r2, |t - theta_c| <= half}`` (:func:`sector_rect`)
    """

    kind: str
    leg: int
    joint: int
    field: str
    eps: float
    cols: tuple[int, ...]
    block_length: float = 0.0
    angle: float = 0.0
    eps_t: float = 0.0
    sector: tuple[float, ...] = ()


def error_set(robot, sources) -> tuple[SourceSet, ...]:
    """The independent sources of non-zero half-width of per-joint ``sources`` on ``robot``, with their
    parameter columns in ``delta`` (module docstring; pose-independent)."""
    out, col = [], 0
    for i, (chain, leg) in enumerate(zip(robot.chains, sources.legs)):
        for k, (joint, e) in enumerate(zip(chain.joints, leg)):
            items = [("disk", "shift", e.radial + e.position, 2, 0.0),
                     ("interval", "turn", e.direction, 1, 0.0),
                     ("interval", "tilt", e.angular, 1, 0.0),
                     ("rhombus", "lateral", e.lateral, 2, e.block_length),
                     ("interval", "dq", e.actuator if joint.actuated else 0.0, 1, 0.0),
                     ("interval", "dl", e.length if joint.link != (0.0, 0.0) else 0.0, 1, 0.0)]
            for kind, fld, eps, size, L in items:
                if eps > 0:
                    out.append(SourceSet(kind, i, k, fld, float(eps), tuple(range(col, col + size)), float(L)))
                    col += size
    return tuple(out)


def support(sets: tuple[SourceSet, ...], c: np.ndarray) -> np.ndarray:
    """``h_S(c) = max_{delta in S} c . delta`` for real ``c`` ``(..., n)``: the sum of each source's support
    (interval ``eps |c|``, disk ``eps ||c||``, rhombus ``max(eps |c_sigma|, 2 eps |c_tau| / L)``), ``(...)``."""
    h = np.zeros(c.shape[:-1])
    for s in sets:
        if s.kind == "interval":
            h = h + s.eps * np.abs(c[..., s.cols[0]])
        elif s.kind == "disk":
            h = h + s.eps * np.hypot(c[..., s.cols[0]], c[..., s.cols[1]])
        elif s.kind == "rect":
            cr, ct = _rect_coords(s, c[..., s.cols[0]], c[..., s.cols[1]])
            h = h + s.eps * np.abs(cr) + s.eps_t * np.abs(ct)
        else:
            h = h + np.maximum(s.eps * np.abs(c[..., s.cols[0]]),
                               2 * s.eps / s.block_length * np.abs(c[..., s.cols[1]]))
    return h


def argsupport(sets: tuple[SourceSet, ...], c: np.ndarray) -> np.ndarray:
    """A maximizer ``delta (..., n)`` of ``c . delta`` over ``S`` (:func:`support`; ties: the + side)."""
    n = sum(len(s.cols) for s in sets)
    d = np.zeros(c.shape[:-1] + (n,))
    sgn = lambda x: np.where(x < 0, -1.0, 1.0)  # noqa: E731
    for s in sets:
        if s.kind == "interval":
            d[..., s.cols[0]] = s.eps * sgn(c[..., s.cols[0]])
        elif s.kind == "disk":
            cx, cy = c[..., s.cols[0]], c[..., s.cols[1]]
            norm = np.hypot(cx, cy)
            safe = np.where(norm > 0, norm, 1.0)
            d[..., s.cols[0]] = np.where(norm > 0, s.eps * cx / safe, s.eps)
            d[..., s.cols[1]] = np.where(norm > 0, s.eps * cy / safe, 0.0)
        elif s.kind == "rect":
            cr, ct = _rect_coords(s, c[..., s.cols[0]], c[..., s.cols[1]])
            ar, at = s.eps * sgn(cr), s.eps_t * sgn(ct)
            d[..., s.cols[0]] = ar * math.cos(s.angle) - at * math.sin(s.angle)
            d[..., s.cols[1]] = ar * math.sin(s.angle) + at * math.cos(s.angle)
        else:
            tilt = 2 * s.eps / s.block_length
            shift_wins = s.eps * np.abs(c[..., s.cols[0]]) >= tilt * np.abs(c[..., s.cols[1]])
            d[..., s.cols[0]] = np.where(shift_wins, s.eps * sgn(c[..., s.cols[0]]), 0.0)
            d[..., s.cols[1]] = np.where(shift_wins, 0.0, tilt * sgn(c[..., s.cols[1]]))
    return d


def _rect_coords(s: SourceSet, x, y):
    """The components ``(u_r . v, u_t . v)`` of ``v = (x, y)`` on a rect's axes (:class:`SourceSet`)."""
    ca, sa = math.cos(s.angle), math.sin(s.angle)
    return ca * x + sa * y, -sa * x + ca * y


def sector_rect(s: SourceSet, theta_c: float, half: float, r1: float, r2: float, origin) -> tuple[SourceSet,
                                                                                                   np.ndarray]:
    """The rectangle piece of disk source ``s`` covering the annular sector ``{o + r (cos t, sin t): r1 <= r <=
    r2, |t - theta_c| <= half}`` (``half <= pi / 4``, mm and rad) and its centre ``(2,)`` (absolute, mm).

    In the sector's own axes (radial ``u_r`` at ``theta_c``, tangential ``u_t``) every point has radial
    coordinate ``r cos(t - theta_c)`` in ``[r1 cos(half), r2]`` and tangential coordinate ``r sin(t - theta_c)``
    in ``[-r2 sin(half), r2 sin(half)]``, so the rectangle of these ranges contains it: centre ``o + (r2 + r1
    cos half) / 2 u_r``, half-widths ``(r2 - r1 cos half) / 2`` and ``r2 sin half``. Its outer side is tangent
    to the circle ``r2``; it leaves the disk only by its corners, at radius ``r2 / cos(half)``.

    >>> s = SourceSet("disk", 0, 0, "shift", 1.0, (0, 1))
    >>> piece, c = sector_rect(s, 0.0, math.pi / 8, 0.0, 1.0, (0.0, 0.0))
    >>> round(piece.eps, 3), round(piece.eps_t, 3), c.round(3).tolist()
    (0.5, 0.383, [0.5, 0.0])
    """
    lo = r1 * math.cos(half)
    centre = np.asarray(origin, dtype=float) + (r2 + lo) / 2 * np.array([math.cos(theta_c), math.sin(theta_c)])
    piece = SourceSet("rect", s.leg, s.joint, s.field, (r2 - lo) / 2, s.cols, 0.0, float(theta_c),
                      r2 * math.sin(half), (float(theta_c), float(half), float(r1), float(r2),
                                             float(origin[0]), float(origin[1])))
    return piece, centre


def constraint_matrices(sets: tuple[SourceSet, ...]) -> np.ndarray:
    """``S`` as quadratic constraints ``delta^T P_k delta <= 1``, ``P`` ``(K, n, n)`` (PSD): an interval
    ``e e^T / eps^2``, a disk ``(e_x e_x^T + e_y e_y^T) / eps^2``, a rhombus ``a a^T`` for its two directions
    ``a = e_sigma / eps +- e_tau L / (2 eps)``, a rect ``a a^T`` for ``a = u_r / eps`` and ``u_t / eps_t``;
    their intersection is exactly ``S``."""
    n = sum(len(x.cols) for x in sets)
    out = []
    for s in sets:
        if s.kind == "interval":
            P = np.zeros((n, n))
            P[s.cols[0], s.cols[0]] = 1 / s.eps ** 2
            out.append(P)
        elif s.kind == "disk":
            P = np.zeros((n, n))
            P[s.cols[0], s.cols[0]] = P[s.cols[1], s.cols[1]] = 1 / s.eps ** 2
            out.append(P)
        elif s.kind == "rect":
            for ang, h in ((s.angle, s.eps), (s.angle + math.pi / 2, s.eps_t)):
                a = np.zeros(n)
                a[s.cols[0]], a[s.cols[1]] = math.cos(ang) / h, math.sin(ang) / h
                out.append(np.outer(a, a))
        else:
            for sign in (1.0, -1.0):
                a = np.zeros(n)
                a[s.cols[0]], a[s.cols[1]] = 1 / s.eps, sign * s.block_length / (2 * s.eps)
                out.append(np.outer(a, a))
    return np.array(out).reshape(len(out), n, n)


def project(sets: tuple[SourceSet, ...], delta: np.ndarray) -> np.ndarray:
    """The nearest point of ``S`` (per source; Euclidean in the source's own parameters), ``(..., n)``."""
    d = np.array(delta, dtype=float, copy=True)
    for s in sets:
        if s.kind == "interval":
            d[..., s.cols[0]] = np.clip(d[..., s.cols[0]], -s.eps, s.eps)
        elif s.kind == "disk":
            norm = np.hypot(d[..., s.cols[0]], d[..., s.cols[1]])
            f = np.where(norm > s.eps, s.eps / np.where(norm > 0, norm, 1.0), 1.0)
            d[..., s.cols[0]] *= f
            d[..., s.cols[1]] *= f
        elif s.kind == "rect":
            cr, ct = _rect_coords(s, d[..., s.cols[0]], d[..., s.cols[1]])
            cr, ct = np.clip(cr, -s.eps, s.eps), np.clip(ct, -s.eps_t, s.eps_t)
            d[..., s.cols[0]] = cr * math.cos(s.angle) - ct * math.sin(s.angle)
            d[..., s.cols[1]] = cr * math.sin(s.angle) + ct * math.cos(s.angle)
        else:
            # in u = 2 sigma / (2 eps), t = L tau / (2 eps) the rhombus is |u + t| <= 1, |u - t| <= 1: clip the
            # rotated coordinates (a projection in this scaled metric, enough for a feasible point)
            u = d[..., s.cols[0]] / s.eps
            t = d[..., s.cols[1]] * s.block_length / (2 * s.eps)
            a, b = np.clip(u + t, -1, 1), np.clip(u - t, -1, 1)
            d[..., s.cols[0]] = s.eps * (a + b) / 2
            d[..., s.cols[1]] = 2 * s.eps / s.block_length * (a - b) / 2
    return d


def to_displacements(sets: tuple[SourceSet, ...], delta: np.ndarray):
    """``delta (..., n)`` as :class:`~pmaccuracy.model.sources.JointDisplacements` ``(..., 3, 3)`` (the
    configuration format of :mod:`pmaccuracy.model.sources` and :func:`pmaccuracy.accuracy.nonlinear.joint_displaced_pose`)."""

    cfg = JointDisplacements.zeros(delta.shape[:-1])
    for s in sets:
        if s.field == "shift":
            cfg.shift[..., s.leg, s.joint] = delta[..., s.cols[0]] + 1j * delta[..., s.cols[1]]
        elif s.field == "lateral":
            cfg.sigma[..., s.leg, s.joint] = delta[..., s.cols[0]]
            cfg.tau[..., s.leg, s.joint] = delta[..., s.cols[1]]
        else:
            getattr(cfg, s.field)[..., s.leg, s.joint] = delta[..., s.cols[0]]
    return cfg
