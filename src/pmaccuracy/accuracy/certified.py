"""Certified worst-case pose errors of the exact (nonlinear) loop closure, and the best feasible nonlinear maxima.

The first-order maxima of :mod:`pmaccuracy.accuracy.bounds` are exact for the linearized model ``A dX = e`` but
the true, nonlinear worst case is slightly larger (0.04-0.27 % at the paper's clearances). Here every
quantity gets two numbers:

* an **upper bound** that is guaranteed never below the maximum of the exact loop closure over the whole
  error set (first-order maximum plus a rigorous bound of the Taylor remainder, below), and
* a **lower bound**, the best feasible configuration of the exact model (:func:`nonlinear_pose_errors`:
  local ascent from the first-order worst vertices), with the relative ``gap = (upper - lower) / lower``.

Error set
---------
The sources of :mod:`pmaccuracy.model.sources` with non-zero half-width are the parameters ``delta`` (``n``
scalars, mm or rad). Each source ranges over its own set and the sets are independent (their product
``S``): an *interval* ``|delta| <= eps`` (``direction``: a turn about the joint's centre; ``angular``: a tilt of
a slide's block about its centre; ``actuator``, ``length``),
a *disk* ``|(dx, dy)| <= eps`` (``radial`` + ``position`` as one shift, global axes) or a *rhombus*
``|L tau +- 2 sigma| <= 2 eps`` (``lateral``). The support function of a linear form ``c . delta`` over
``S`` is the sum of the sources' own: ``eps |c|`` (interval), ``eps ||c||_2`` (disk),
``max(eps |c_sigma|, 2 eps |c_tau| / L)`` (rhombus).

Exact closure as a sum of rotated terms
---------------------------------------
Let ``v = (z, delta)`` with ``z`` the nine unknowns (pose ``x, y, phi`` and the six passive joints) and
write ``Delta = v - v0`` for the change from the commanded configuration ``v0 = (z0, 0)``. Walking each leg's
chain (:func:`pmaccuracy.accuracy.nonlinear._perturbed_end`: shift and turn before joint ``k``, joint motion, lateral
shift and tilt inside a slide, link) every frame angle is *affine* in ``v`` and every translation is a
term ``r_m(v) exp(i theta_m(v))`` with ``r_m`` (complex) and ``theta_m`` affine, plus affine shifts. So
the three closures are, for leg ``i``::

    F_i(v) = sum_m r_m exp(i theta_m) + (affine)  - p - exp(i phi) platform_i = 0      (complex, mm)
    G_i(v) = (affine frame angle) - phi - platform_angle_i = 0                          (rad, exact affine)

With ``Dr = r_m - r_m0`` and ``Dt = theta_m - theta_m0`` (both linear in ``Delta``) the remainder of one
term after its linearization is, exactly::

    R_m = exp(i theta_m0) [ r_m0 (exp(i Dt) - 1 - i Dt) + Dr (exp(i Dt) - 1) ]                    (1)

and the elementary inequalities ``|exp(ix) - 1| <= |x|``, ``exp(ix) - 1 - ix = -x^2/2 + rho3`` with
``|rho3| <= |x|^3 / 6`` bound it.

Remainder of the pose
---------------------
Let ``J = [J_z, J_delta]`` be the Jacobian of the nine real residuals ``(Re F_i, Im F_i, G_i)`` at ``v0``
and ``F0`` the (rounding-size) residual there. The first-order solution is ``Dz_lin = M delta`` with
``M = -J_z^-1 J_delta`` (its pose rows are the first-order error map of :mod:`pmaccuracy.accuracy.bounds`), and
the exact solution is ``Dz = M delta + w`` with::

    w = -J_z^-1 (F0 + R(M delta + w, delta))                                                      (2)

For a componentwise bound ``|w| <= b`` every ``Dt_m = alpha_m . delta + a_m . w`` is at most
``X_m = h_S(alpha_m) + |a_m| . b`` (``h_S``: support function, ``alpha_m = a_m,z M + a_m,delta``) and
every ``|Dr_m| <= D_m = hypot(h_S(Re beta_m), h_S(Im beta_m)) + |r'_m,z| . b``. By (1)
``|R_i| <= rho_i(b) = sum_m |r_m0| X_m^2 / 2 + D_m X_m`` and with ``kappa_ji = J_z^-1[j, Re_i] + i
J_z^-1[j, Im_i]``::

    |w_j| <= Phi_j(b) = |(J_z^-1 F0)_j| + sum_i |kappa_ji| rho_i(b)                               (3)

Iterating ``b <- Phi(b)`` from ``b = 0`` (monotone) gives ``b`` with ``Phi(b) <= b`` after a small outward
inflation; the map (2) then sends the box ``|w| <= b`` into itself (Brouwer: a solution exists in it). Its
Lipschitz constant in ``w`` over the box, from ``d R_m / d w = r'_z (e^{i theta} - e^{i theta0}) + i
theta'_z (r e^{i theta} - r0 e^{i theta0})`` bounded by ``|r'_z| X_m + |theta'_z| (D_m + |r_m0| X_m)``,
must be below 1 (checked in the norm ``max_j |w_j| / b_j``): then the solution in the box is unique,
``J_z`` is invertible on it, and by the implicit function theorem it is the continuation of the
commanded assembly over the connected set ``S`` -- the configuration Newton's method from the
commanded pose finds (:func:`pmaccuracy.accuracy.nonlinear.joint_displaced_pose`). When either check fails
(errors too large, near a singularity, a configuration that cannot be assembled) no bound is returned:
:class:`~pmaccuracy.errors.CertificationError` or NaN.

Term-by-term bound. For a pose row ``j`` and direction ``s = +-1``, with ``c_m = conj(kappa_ji) exp(i
theta_m0) r_m0`` (``i`` the leg of term ``m``)::

    s Dz_j <= h_S(s M_j) + s w_j,
    s w_j <= -s (J_z^-1 F0)_j + sum_m [ max(s Re c_m, 0) X_m^2/2 + |c_m| X_m^3/6 + |kappa_ji| D_m X_m ]   (4)

(the ``Dt^2`` terms keep their sign). This is valid but loose: the bilinear ``Dr Dt`` terms lose their
sign and every term takes its own maximum over ``S``.

Second-order model (the tight bound). With ``c'_m = conj(kappa_ji) exp(i theta_m0)``, expanding (1) by
``exp(ix) - 1 - ix = -x^2/2 + rho3`` and ``exp(ix) - 1 = ix + rho2`` (``|rho2| <= x^2/2``) and splitting
``Dt = alpha_m . delta + a_m,z . w``, ``Dr = beta_m . delta + r'_m,z . w``::

    s w_j = -s (J_z^-1 F0)_j + delta^T H delta + E,
    H = s sum_m [ Re(c_m) alpha_m alpha_m^T / 2 + sym(Im(c'_m beta_m) alpha_m^T) ]                      (5)
    |E| <= sum_m |c_m| (om_t (2 hX_m + om_t) / 2 + X_m^3 / 6) + |c'_m| (om_r X_m + hD_m om_t + D_m X_m^2 / 2)

with ``om_t = |a_m,z| . b >= |Dt - alpha_m . delta|``, ``om_r = |r'_m,z| . b``, ``hX_m = h_S(alpha_m)``,
``hD_m`` the bound of ``|beta_m . delta|``. So ``s Dz_j <= max_S (s M_j . delta + delta^T H delta) - s
(J_z^-1 F0)_j + E``, and the maximum of the quadratic over ``S`` is bounded by Lagrangian duality
(:func:`dual_bound`: ``S`` as quadratic constraints ``delta^T P_k delta <= 1``; for any ``lambda >= 0``
with ``sum lambda_k P_k - H`` positive definite, ``max <= sum lambda_k + g^T (sum lambda_k P_k - H)^-1 g /
4``), which equals the first-order support function at ``H = 0`` and exceeds the true maximum of the
model only by ``O(|H|^2 / |g|)``. The certified value is the smaller of this and (4).

The box ``b`` is first tightened the same way: ``|w_j| <= max_s [dual bound of max_S delta^T (s H_j) delta
- s (J_z^-1 F0)_j] + E_j(b)`` is another bound of the map (2) over the box, monotone in ``b``, so
``b <- min(b, Phi(b), that)`` keeps ``Phi(b) <= b`` (repeated until it stops shrinking).

``dx, dy, dphi`` take the larger of ``s = +-1``. For ``|dp|`` the same bounds are applied to ``u . (Dx,
Dy)`` for ``K = 256`` unit directions ``u_k`` (the cheap start value of :func:`dual_bound` for all, the
refined one for those whose bound exceeds the best refined one) and ``|p| <= max_k u_k . p / cos(pi /
K)``. Rounding: :func:`_dual_value` bounds the smallest eigenvalue from below and corrects the quadratic
form by its residual; every result is finally multiplied by ``1 + 1e-9`` and increased by ``1e-12 *
scale``.

Cutting the set. Where the bound is not certified or exceeds the best feasible value by more than
0.5 %, :func:`certified_pose_errors` bounds again over ``2^split`` pieces (:func:`_split_bounds`: the
interval sources that turn the chains most are halved; each piece is expanded about the exact closure at its
centre, so its remainder terms shrink) and keeps the smaller valid bound. A bound still missing, or more
than ``split_gap`` above the best feasible value, goes to branch and bound (:func:`_branch_and_bound`):
every piece not yet used or above the target is cut along its source of largest turning weight (intervals
halved and lateral rhombi quartered, both exact partitions; a disk covered by :data:`DISK_SECTORS` sectors,
each certified as the rectangle that contains it, :func:`sector_rect`, and a sector halved in angle or
radius), each child bounded about its own exact centre, until all are within the target or ``max_pieces``
pieces have been bounded. The bound is the largest over the leaves, which cover ``S``, of each leaf's own
bound capped by those of its used ancestors (an ancestor's bound holds over the leaf's part of ``S``; the
sector rectangles stick out of their disk, so a first cut can be looser than its parent). A pose whose
whole set could not be certified is certified this way when every leaf is used (budget ``REFUSED_BUDGET``
times larger once some piece is used). The extreme points of every used piece are solved exactly too and
raise the best feasible values (and so the targets) as it goes.

Continuation check. A piece's certificate proves one solution in a box about the Newton solution at its
centre, unique there, but Newton's method could have converged to another solution branch. A piece is
therefore used only if its solution is shown to be the commanded assembly's continuation; otherwise it
counts as not certified (it may be cut again; a set with an unused piece keeps its uncut bound, or is
refused if it has none; ``rejected`` counts such pieces). The argument: some point ``d`` of the piece has
a proven box of the continuation (an *anchor*) that lies inside the piece's box ``|Dz - dz - M (d - c)| <=
b`` at ``d``; by the piece's uniqueness its solution at ``d`` is then the continuation. The first anchor is
the commanded assembly, ``|Dz| <= b0`` at ``d = 0`` (:func:`_point_box`, rounding-size); the four pieces of
the first cut and the root of the branch and bound contain ``d = 0``. Every used piece adds anchors: its
centre (``|Dz - dz| <= bc``, ``bc``: equation (3) iterated at ``delta = c``, where the ``h_S`` terms
vanish) and the centre ``c_P`` of every cut piece it contains (every child of ``P`` contains ``c_P``):
Newton's method at ``c_P`` and a point certificate there (:func:`_point_anchor`) whose box lies in the used
piece's box. (In :func:`_split_bounds` a piece may also be checked *inside the parent*: its centre box in
the whole set's certified box, :func:`_continues`.) The piece's solution and the continuation are
continuous solution branches on the connected piece with ``J_z`` invertible (contraction), equal at one
point, so equal on the whole piece (implicit function theorem: the set where they agree is open and
closed). Measured: no piece rejected on the paper robot or the random robots of the tests at 1x and 10x; a
Newton solution moved to another branch (test) is rejected.

Guarantee: for every configuration in ``S`` the exact pose error (continued from the commanded assembly)
satisfies ``|dx| <= dx_upper`` etc. Joint ranges are not imposed on the perturbed passive joints.
Tightness (README, tests): within 0.01 % of the best configuration at the paper's clearances and 0.33 % at
10x on the Aalborg 3-PPR; on 25 random robots within 0.5 % of the dense search at 1x (24 certified, one
65 % nonlinear among them) and within 3.9 % at 10x (19 certified, up to 44 % nonlinear). Refused: robots
that cannot be closed over their whole error set, and a 3-RRR 75 % nonlinear at 10x (within the default
budget). Speed: 0.03-0.2 s (3-PPR) to 0.1-0.6 s (3-RRR, 21 source parameters) per pose on a shared 2-core
machine; 5-10 s where the set is cut up to the budget, up to 40 s for a pose with no whole-set certificate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .._display import html_table, summary, value_range
from .._optional import available
from ..errors import CertificationError, NoSolutionError
from ..kinematics import as_poses
from ..io.resolve import robot_arg

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
    from ..model.sources import JointDisplacements

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


# ============================================================================ closure as rotated terms
class _Aff:
    """An affine function ``c + g . Delta`` of ``Delta = (Dz (9), delta (n))``: ``c (N,)``, ``g (N, nv)``
    (complex or real)."""

    __slots__ = ("c", "g")

    def __init__(self, c, g):
        self.c, self.g = c, g

    def __add__(self, other):
        if isinstance(other, _Aff):
            return _Aff(self.c + other.c, self.g + other.g)
        return _Aff(self.c + other, self.g)

    def scale(self, k):
        return _Aff(self.c * k, self.g * k)


@dataclass(frozen=True)
class _Model:
    """The closure terms of a batch of ``N`` poses (module docstring, "Exact closure").

    r0, t0 : ``(N, m)`` nominal radius (complex mm) and angle (rad) of each term;  rg, tg : ``(N, m, nv)``
    their coefficients;  leg_of : ``(m,)`` leg of each term;  aff0, affg : ``(N, 3)``, ``(N, 3, nv)`` the
    affine part of each leg's F;  ang0, angg : ``(N, 3)``, ``(N, 3, nv)`` each leg's G;  n : parameters
    """

    r0: np.ndarray
    t0: np.ndarray
    rg: np.ndarray
    tg: np.ndarray
    leg_of: np.ndarray
    aff0: np.ndarray
    affg: np.ndarray
    ang0: np.ndarray
    angg: np.ndarray
    n: int
    z0: np.ndarray

    def residual(self, D: np.ndarray) -> np.ndarray:
        """The nine real residuals ``(..., N, 9)`` (Re F_i, Im F_i, G_i per leg) at ``Delta`` ``(..., N, nv)``."""
        r = self.r0 + np.einsum("nmv,...nv->...nm", self.rg, D)
        t = self.t0 + np.einsum("nmv,...nv->...nm", self.tg, D)
        terms = r * np.exp(1j * t)
        F = self.aff0 + np.einsum("niv,...nv->...ni", self.affg, D)
        F = F + np.stack([terms[..., self.leg_of == i].sum(axis=-1) for i in range(3)], axis=-1)
        G = self.ang0 + np.einsum("niv,...nv->...ni", self.angg, D)
        return np.stack([F.real, F.imag, G], axis=-1).reshape(F.shape[:-1] + (9,))

    def jacobian(self, D: np.ndarray) -> np.ndarray:
        """``d residual / d Delta`` ``(..., N, 9, nv)``."""
        r = self.r0 + np.einsum("nmv,...nv->...nm", self.rg, D)
        t = self.t0 + np.einsum("nmv,...nv->...nm", self.tg, D)
        e = np.exp(1j * t)
        dterm = e[..., None] * (self.rg + 1j * r[..., None] * self.tg)  # (..., N, m, nv)
        dF = self.affg + np.stack([dterm[..., self.leg_of == i, :].sum(axis=-2) for i in range(3)], axis=-2)
        dG = np.broadcast_to(self.angg, dF.shape)
        out = np.stack([dF.real, dF.imag, dG], axis=-2)  # (..., N, 3, 3, nv)
        return out.reshape(out.shape[:-3] + (9, out.shape[-1]))


def _build_model(robot, sets: tuple[SourceSet, ...], poses: np.ndarray) -> _Model:
    """Walk each leg's chain with the sources inserted (as :func:`pmaccuracy.accuracy.nonlinear._perturbed_end`) and
    collect the rotated terms and affine parts at the commanded configuration of ``poses`` ``(N, 3)``."""
    from ..kinematics import inverse_kinematics

    N = poses.shape[0]
    n = sum(len(s.cols) for s in sets)
    nv = 9 + n
    ik = inverse_kinematics(robot, poses)
    if not np.all(ik.reachable):
        bad = int(np.flatnonzero(~ik.reachable)[0])
        raise NoSolutionError(f"pose {bad} cannot be reached by every leg")
    joints = ik.joints
    where = {(s.leg, s.joint, s.field): s for s in sets}

    def const(c, dtype=float):
        return _Aff(np.broadcast_to(np.asarray(c, dtype=dtype), (N,)).copy(), np.zeros((N, nv), dtype=dtype))

    def var(index, c, dtype=float):
        a = const(c, dtype)
        a.g[:, index] = 1.0
        return a

    r0, t0, rg, tg, leg_of = [], [], [], [], []
    aff0, affg, ang0, angg = [], [], [], []
    for i, chain in enumerate(robot.chains):
        passive = dict(zip(chain.passive_indices, (3 + 2 * i, 4 + 2 * i)))
        angle = const(chain.base_angle)
        pos = const(chain.base_z, complex)
        terms = []
        for k, joint in enumerate(chain.joints):
            s = where.get((i, k, "shift"))
            if s:
                pos = pos + _Aff(0.0, np.zeros((N, nv), complex))
                pos.g[:, 9 + s.cols[0]] += 1.0
                pos.g[:, 9 + s.cols[1]] += 1j
            s = where.get((i, k, "turn"))
            if s:
                angle = angle + var(9 + s.cols[0], 0.0)
            if joint.actuated:
                value = const(joints[:, i, k])
                s = where.get((i, k, "dq"))
                if s:
                    value = value + var(9 + s.cols[0], 0.0)
            else:
                value = var(passive[k], joints[:, i, k])
            if joint.kind == "R":
                angle = angle + value + joint.offset
            else:
                # the block (sources.block_centre) shifts by sigma normal to the rail and tilts by tau + tilt:
                # a bushing before the slide (the rod slides along the tilted direction), a carriage after it
                angle = angle + joint.offset
                r = _Aff(value.c.astype(complex), value.g.astype(complex))
                lat, tilt = where.get((i, k, "lateral")), where.get((i, k, "tilt"))
                bushing = joint.block_kind == "bushing"
                if lat:
                    sh = r if not bushing else _Aff(np.zeros(N, complex), np.zeros((N, nv), complex))
                    sh.g[:, 9 + lat.cols[0]] += 1j
                    if bushing:
                        terms.append((sh, angle))
                turned = angle
                for col in ([lat.cols[1]] if lat else []) + ([tilt.cols[0]] if tilt else []):
                    turned = turned + var(9 + col, 0.0)
                terms.append((r, turned if bushing else angle))
                angle = turned
            if abs(joint.link_z) > 0:
                r = const(joint.link_z, complex)
                s = where.get((i, k, "dl"))
                if s:
                    r.g[:, 9 + s.cols[0]] += joint.link_z / abs(joint.link_z)
                terms.append((r, angle))
        # platform side: - p - exp(i phi) platform
        pos = pos + _Aff(np.zeros(N, complex), np.zeros((N, nv), complex))
        pos.c = pos.c - (poses[:, 0] + 1j * poses[:, 1])
        pos.g[:, 0] -= 1.0
        pos.g[:, 1] -= 1j
        if abs(chain.platform_z) > 0:
            terms.append((const(-chain.platform_z, complex), var(2, poses[:, 2])))
        for r, t in _merge_terms(terms):
            r0.append(r.c); rg.append(r.g); t0.append(t.c); tg.append(t.g); leg_of.append(i)
        aff0.append(pos.c); affg.append(pos.g)
        g = angle + var(2, poses[:, 2]).scale(-1.0)
        ang0.append(np.angle(np.exp(1j * (g.c - chain.platform_angle))))  # nominal residual, wrapped
        angg.append(g.g)
    z0 = np.concatenate([poses, ik.passive.reshape(N, 6)], axis=-1)
    return _Model(r0=np.stack(r0, -1), t0=np.stack(t0, -1), rg=np.stack(rg, 1), tg=np.stack(tg, 1),
                  leg_of=np.array(leg_of), aff0=np.stack(aff0, -1), affg=np.stack(affg, 1),
                  ang0=np.stack(ang0, -1), angg=np.stack(angg, 1), n=n, z0=z0)


def _merge_terms(terms: list) -> list:
    """One leg's rotated terms ``(r, theta)`` with those whose angles have the same variable part merged.

    ``r_a exp(i theta_a) + r_b exp(i theta_b) = (r_a exp(i (theta_a - theta_b)) + r_b) exp(i theta_b)``
    exactly when ``theta_a - theta_b`` is a constant, and the merged ``r`` is still affine. The remainder (1)
    of the sum is then bounded once, with ``|r_a + r_b|`` instead of ``|r_a| + |r_b|``: a rail's origin
    moved along the rail (the link before it shorter, the slide longer by as much) leaves the bound as it
    is.
    """
    out: list = []
    for r, t in terms:
        for j, (r2, t2) in enumerate(out):
            if np.array_equal(t.g, t2.g):
                turn = np.exp(1j * (t.c - t2.c))
                out[j] = (_Aff(r2.c + r.c * turn, r2.g + r.g * turn[:, None]), t2)
                break
        else:
            out.append((r, t))
    return out


# ============================================================================ certificate
@dataclass(frozen=True)
class CertifiedPoseErrors:
    """Certified and attained worst-case pose errors at a batch of ``N`` poses (module docstring); mm, rad for
    dphi.

    Attributes
    ----------
    poses : ``(N, 3)`` [mm, mm, rad]
    upper : ``{q: (N,)}`` certified upper bounds of the exact maxima (``q`` in :data:`QUANTITIES`; NaN where
        no certificate, see ``reason``)
    lower : ``{q: (N,)}`` best feasible values of the exact model (nonlinear maxima; NaN when not searched)
    first_order : ``{q: (N,)}`` the first-order maxima (:func:`pmaccuracy.accuracy.bounds.max_pose_errors`)
    gap : ``{q: (N,)}`` ``(upper - lower) / lower`` (0 where both are 0)
    worst : ``{q: (N, n)}`` the source values attaining ``lower`` (``delta``, module docstring)
    remainder : ``(N, 9)`` the bound ``b`` of ``|w|`` (pose rows mm, mm, rad; then passive joints)
    reason : ``(N,)`` empty where certified, else why not
    sets : the error set's sources (their ``cols`` index ``worst``)
    rejected : ``(N,)`` pieces of the cut error set certified but not used because the continuation check
        failed (module docstring, "Continuation check")
    """

    poses: np.ndarray
    upper: dict[str, np.ndarray]
    lower: dict[str, np.ndarray]
    first_order: dict[str, np.ndarray]
    gap: dict[str, np.ndarray]
    worst: dict[str, np.ndarray] = field(default_factory=dict)
    remainder: np.ndarray | None = None
    reason: np.ndarray | None = None
    sets: tuple[SourceSet, ...] = ()
    rejected: np.ndarray | None = None

    def __repr__(self) -> str:
        parts = [f"{q} upper {value_range(self.upper[q], 'deg' if q == 'dphi' else 'mm', 180 / math.pi if q == 'dphi' else 1.0)}"
                 for q in QUANTITIES]
        gaps = np.concatenate([np.ravel(self.gap[q]) for q in QUANTITIES])
        if np.any(np.isfinite(gaps)):
            parts.append(f"largest gap {np.nanmax(gaps) * 100:.3g} %")
        refused = int(np.sum(np.asarray([bool(r) for r in np.ravel(self.reason)])))
        if refused:
            parts.append(f"{refused} not certified")
        return summary("CertifiedPoseErrors", int(self.poses.shape[0]), parts)

    def _repr_html_(self) -> str:
        return html_table("Certified upper bounds (mm, deg)", self.records())

    def records(self, which: str = "upper") -> list[dict]:
        """One dict per pose with the ``bounds`` keys (x, y, phi_deg, dx_max, dy_max, dphi_max_deg, dp_max: the
        ``upper`` or ``lower`` values, mm and deg) and ``gap`` ``{dx, dy, dphi, dp}``."""
        vals = self.upper if which == "upper" else self.lower
        out = []
        for k, p in enumerate(self.poses):
            out.append({"x": float(p[0]), "y": float(p[1]), "phi_deg": float(np.degrees(p[2])),
                        "dx_max": float(vals["dx"][k]), "dy_max": float(vals["dy"][k]),
                        "dphi_max_deg": float(np.degrees(vals["dphi"][k])), "dp_max": float(vals["dp"][k]),
                        "gap": {q: float(self.gap[q][k]) for q in QUANTITIES}})
        return out


def _prepare(robot, clearances, poses):
    from ..model.manipulator import Manipulator
    from ..model.sources import ErrorSources
    from ..io.resolve import load_clearances

    if not isinstance(robot, Manipulator):
        robot = robot_arg(robot)
    sources = load_clearances(clearances, robot)
    if not isinstance(sources, ErrorSources):
        sources = ErrorSources.from_clearance_set(sources)
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
             target: dict | None = None) -> dict:
    """The certificate of :func:`remainder_bounds` for a built model (equations (2)-(5)); ``offset`` ``(N, 9)``
    is added to every bounded change (the exact change at the centre of a piece of the error set,
    :func:`_split_bounds`). With ``target`` ``{q: float}`` (mm, rad) the interior-point refinement of
    :func:`dual_bound` is skipped for the rows and directions whose cheaper bound is already below it (the
    branch and bound only needs a piece below its target; every value returned is still a valid bound)."""
    N, n = model.z0.shape[0], model.n
    offset = np.zeros((N, 9)) if offset is None else offset
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

    def pieces(kap: np.ndarray, rows: np.ndarray):
        """``c'_m``, ``c_m`` and the second-order model ``H`` (equation (5)) of row combinations ``kap``
        ``(N', R, 3)`` at the poses ``rows``."""
        cp = np.conj(kap[..., model.leg_of]) * e0[rows][:, None, :]  # (N', R, m)
        c = cp * model.r0[rows][:, None, :]
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
    oi = np.flatnonzero(ok)
    quad_w = np.full((N, 18), np.inf)
    if oi.size:
        cw, cpw, Hw = pieces(np.concatenate([kappa[oi], -kappa[oi]], axis=1), oi)
        f_w = np.concatenate([JinvF0[oi], -JinvF0[oi]], axis=1)
        # a piece of the branch and bound takes the first feasible multipliers (refining them moved the pieces'
        # bounds by less than 1 % on the test robots and cost 40 % of the time); refined where the box then
        # does not close or contract (below)
        quad_w[oi] = dual_bound(sets, np.zeros(Hw.shape[:-1]), Hw, refine=target is None, sdp=target is None) - f_w

    def phi2(b):
        out = phi(b)
        if oi.size:
            r = quad_w[oi] + rest_of(cw, cpw, b[oi], oi)
            out[oi] = np.fmin(out[oi], np.maximum(r[:, :9], r[:, 9:]))
        return out

    def close():
        """The box ``b`` ``(N, 9)`` (fixed point of Phi from 0, inflated), whether ``Phi(b) <= b`` and the
        contraction constant of (2) over it."""
        b = np.zeros((N, 9))
        with np.errstate(all="ignore"):
            for _ in range(max_iterations):
                nb = phi2(b)
                if np.all(np.abs(nb - b) <= 1e-12 * np.maximum(nb, 1e-300)):
                    b = nb
                    break
                b = nb
            b = b * (1 + 1e-6) + 1e-15 * scale
            fixed = np.all(phi2(b) <= b, axis=-1) & np.all(np.isfinite(b), axis=-1)
            X, D = terms(b)
            # Lipschitz constant of (2) in w over the box, in the norm max_j |w_j| / b_j
            lip_leg = np.einsum("nmj,nm,mi->nij", arz, X, onehot) + np.einsum(
                "nmj,nm,mi->nij", atz, D + ar0 * X, onehot)  # (N, 3 legs, 9)
            L = np.einsum("nji,nil,nl->nj", akap, lip_leg, b) / b
        return b, fixed, np.max(L, axis=-1)

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
                  stop: np.ndarray | None = None) -> np.ndarray:
        """Upper bound ``(N', R)`` of ``max over S of g . delta + (J_z^-1 row combination of -(F0 + R))`` at the
        poses ``rows`` (indices).

        ``kap`` ``(N', R, 3)``: the row combination's ``kappa`` per leg; ``g`` ``(N', R, n)`` its first-order
        map; ``f0`` ``(N', R)`` its ``(J_z^-1 F0)``. The smaller of the term-by-term bound (4) and the
        second-order model bound of :func:`dual_bound` plus its rest (equation (5)); the refinement of a row
        ends once it is below ``stop`` ``(N', R)`` (if given).
        """
        c, cp, H = pieces(kap, rows)
        X_, D_ = X[rows], D[rows]
        cheap = (support(sets, g) - f0 + np.einsum("nrm,nm->nr", np.maximum(c.real, 0), X_ ** 2 / 2)
                 + np.einsum("nrm,nm->nr", np.abs(c), X_ ** 3 / 6) + np.einsum("nrm,nm->nr", np.abs(cp), D_ * X_))
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
            ub = row_bound(kap_rows, g_rows, f_rows, ci, refine=False)
            t_rows = np.array([target[q] for q in ("dx", "dy", "dphi")] * 2) / (1 + 1e-6)
            kk, rr = np.nonzero(ub > t_rows)  # every (pose, row) still above: one batch, one row each
            if kk.size:
                ub[kk, rr] = row_bound(kap_rows[kk, rr][:, None], g_rows[kk, rr][:, None], f_rows[kk, rr][:, None],
                                       ci[kk], stop=t_rows[rr][:, None])[:, 0]
        for j, q in enumerate(("dx", "dy", "dphi")):
            upper[q][ci] = np.maximum(ub[:, j], ub[:, 3 + j])
        # |dp| <= max_k u_k . p / cos(pi / K) through K directions: the cheap bound of every direction, then the
        # refined one for the directions (8 at a time) whose bound exceeds the best refined one
        ang = 2 * np.pi * (np.arange(N_DIRECTIONS) + 0.5) / N_DIRECTIONS
        u = np.stack([np.cos(ang), np.sin(ang)], axis=-1)  # (K, 2)
        kap_u = np.einsum("kr,nri->nki", u, kappa[ci, :2, :])
        g_u = np.einsum("kr,nrd->nkd", u, M[ci, :2, :])
        f_u = np.einsum("kr,nr->nk", u, JinvF0[ci, :2] - offset[ci, :2])
        ub = row_bound(kap_u, g_u, f_u, ci, refine=False)
        floor = -np.inf if target is None else target["dp"] * math.cos(math.pi / N_DIRECTIONS) / (1 + 1e-6)
        done = np.zeros((ci.size, N_DIRECTIONS), dtype=bool)
        active = np.ones(ci.size, dtype=bool)
        while True:  # rounds: per pose the (up to) 8 worst directions not yet refined, all poses in one batch
            sel_k, sel_d = [], []
            for k in np.flatnonzero(active):
                todo = np.argsort(np.where(done[k], np.inf, -ub[k]))[:8]
                todo = todo[~done[k, todo]]
                if not todo.size or not np.max(ub[k, todo]) > max(np.max(ub[k, done[k]], initial=-np.inf), floor):
                    active[k] = False
                    continue
                sel_k.append(np.full(todo.size, k))
                sel_d.append(todo)
            if not sel_k:
                break
            kk, dd = np.concatenate(sel_k), np.concatenate(sel_d)
            ub[kk, dd] = row_bound(kap_u[kk, dd][:, None], g_u[kk, dd][:, None], f_u[kk, dd][:, None], ci[kk],
                                   stop=None if target is None else np.full((kk.size, 1), floor))[:, 0]
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
    return _Model(r0=model.r0 + np.einsum("nmv,nv->nm", model.rg, D),
                  t0=model.t0 + np.einsum("nmv,nv->nm", model.tg, D), rg=model.rg, tg=model.tg,
                  leg_of=model.leg_of, aff0=model.aff0 + np.einsum("niv,nv->ni", model.affg, D), affg=model.affg,
                  ang0=model.ang0 + np.einsum("niv,nv->ni", model.angg, D), angg=model.angg, n=model.n,
                  z0=model.z0 + D[:, :9])


def _split_bounds(model: _Model, sets, scale: float, k: int, anchor_M: np.ndarray | None = None,
                  anchor_b: np.ndarray | None = None, anchor_b0: np.ndarray | None = None) -> dict:
    """Certified bounds over the error set cut into ``2^k`` pieces (then the largest over the pieces).

    The ``k`` interval sources that turn the chain the most (score ``eps sum_m |r_m0| |alpha_m|``, summed
    over the poses) are halved: each piece is a product of the same kinds of sets, centred at ``delta_c``
    (``+-eps/2`` on the halved sources). About its centre, the exact closure solved there (Newton,
    :func:`exact_change`, its residual kept in ``F0``), the certificate of :func:`_certify` applies unchanged
    with half the widths, so its remainder terms are smaller; the bound of the whole set is the largest of
    the pieces' (each is an upper bound over its piece, and the pieces cover ``S``). Every piece must pass
    :func:`_continues` against the whole set's certificate (``anchor_M`` ``(N, 9, n)``, ``anchor_b`` ``(N,
    9)``, about ``Dz = 0`` at ``delta = 0``) or, since every piece contains ``delta = 0``, against the
    commanded assembly's box ``anchor_b0`` ``(N, 9)`` (:func:`_point_box`); NaN or None: none. Returns
    ``upper`` ``{q: (N,)}``, ``certified`` ``(N,)`` and ``rejected`` ``(N,)`` (pieces certified but rejected).
    """
    N, n = model.z0.shape[0], model.n
    J = model.jacobian(np.zeros((N, 9 + n)))
    with np.errstate(all="ignore"):
        M = -np.linalg.solve(J[..., :9], J[..., 9:])
    alpha = np.einsum("nmj,njk->nmk", model.tg[..., :9], M) + model.tg[..., 9:]
    score = np.nansum(np.abs(model.r0)[..., None] * np.abs(alpha), axis=(0, 1))  # (n,)
    intervals = [s for s in sets if s.kind == "interval"]
    chosen = sorted(intervals, key=lambda s: -s.eps * score[s.cols[0]])[:k]
    if not chosen:
        return {"upper": {q: np.full(N, np.nan) for q in QUANTITIES}, "certified": np.zeros(N, dtype=bool),
                "rejected": np.zeros(N, dtype=int)}
    half = tuple(SourceSet(s.kind, s.leg, s.joint, s.field, s.eps / 2 if s in chosen else s.eps, s.cols,
                           s.block_length) for s in sets)
    if anchor_b is None:
        anchor_M, anchor_b = np.zeros((N, 9, n)), np.full((N, 9), np.nan)
    models, offsets, goods, centres = [], [], [], []
    for signs in np.ndindex(*(2,) * len(chosen)):
        centre = np.zeros(n)
        for s, sg in zip(chosen, signs):
            centre[s.cols[0]] = (s.eps / 2) * (1.0 if sg else -1.0)
        centre = np.broadcast_to(centre, (N, n))
        dz = exact_change(model, M, centre)
        good = np.all(np.isfinite(dz), axis=-1)
        dz = np.where(good[:, None], dz, 0.0)
        models.append(_recentre(model, np.concatenate([dz, centre], axis=-1)))
        offsets.append(dz)
        goods.append(good)
        centres.append(centre)
    # all pieces of all poses in one vectorized certificate
    stacked = _Model(**{f: (np.concatenate([getattr(m, f) for m in models]) if f not in ("leg_of", "n")
                            else getattr(model, f)) for f in ("r0", "t0", "rg", "tg", "leg_of", "aff0", "affg",
                                                               "ang0", "angg", "n", "z0")})
    part = _certify(stacked, half, scale, offset=np.concatenate(offsets))
    P = len(models)
    if anchor_b0 is None:
        anchor_b0 = np.full((N, 9), np.nan)
    cont = np.stack([np.array([bool(_continues(
        offsets[p][i:i + 1], part["b_centre"][p * N + i:p * N + i + 1], centres[p][i:i + 1],
        {"dz": np.zeros(9), "M": anchor_M[i], "b": anchor_b[i], "centre": np.zeros(n), "b0": anchor_b0[i]},
        part["M"][p * N + i:p * N + i + 1], part["b"][p * N + i:p * N + i + 1],
        _contains_zero(half, centres[p][i:i + 1]))[0]) for i in range(N)]) for p in range(P)])  # (P, N)
    pc = np.stack(goods) & part["certified"].reshape(P, N)
    rejected = np.sum(pc & ~cont, axis=0)
    certified = np.all(pc & cont, axis=0)
    upper = {q: np.where(certified, np.max(part["upper"][q].reshape(P, N), axis=0), np.nan) for q in QUANTITIES}
    return {"upper": upper, "certified": certified, "rejected": rejected}


#: A cut disk is first covered by this many sector pieces (:func:`_children`); each leaves the disk by at most
#: ``1 / cos(pi / DISK_SECTORS) - 1`` (8 %) of its radius, only at its corners.
DISK_SECTORS = 8
#: A pose with no certificate yet (whole set and first cut) may bound this many times ``max_pieces`` pieces, once
#: some piece is used within the first ``max_pieces`` (otherwise it stops there).
REFUSED_BUDGET = 8
#: Directions of ``|dp|`` tried at the extreme points of every accepted piece for the best feasible values.
PIECE_DIRECTIONS = 16


def _children(s: SourceSet, c: np.ndarray) -> list[tuple[SourceSet, np.ndarray]]:
    """The cut of one source of a piece: smaller sets that cover it, each with its centre in the source's own
    parameters (``c`` ``(len(cols),)``: the source's centre in the piece, mm or rad).

    * interval: two halves (a partition), centres ``c +- eps/2``;
    * rhombus ``|L tau +- 2 sigma| <= 2 eps``, a square in its edge coordinates ``(2 sigma +- L tau) / (2 eps)``,
      quartered: four rhombi of half-width ``eps/2`` centred at ``c + (+-eps/2, 0)`` and ``c + (0, +-eps/L)``;
    * disk: :data:`DISK_SECTORS` sectors ``r <= eps``, ``|t - theta_j| <= pi / DISK_SECTORS``, each as the
      rectangle of :func:`sector_rect` that contains it;
    * rect (a sector): its sector halved across its longer side of the rectangle, in angle (two sectors of
      half the opening) or in radius (``[r1, rm]``, ``[rm, r2]``).

    Disk and rect children overlap and stick out of the disk by their corners: they cover the source's set,
    which is all an upper bound needs (the largest bound over a cover bounds the maximum over the set).

    >>> [c.tolist() for _, c in _children(SourceSet("interval", 0, 0, "turn", 0.002, (0,)), np.zeros(1))]
    [[-0.001], [0.001]]
    """
    c = np.asarray(c, dtype=float)
    if s.kind == "interval":
        h = s.eps / 2
        child = SourceSet(s.kind, s.leg, s.joint, s.field, h, s.cols)
        return [(child, c + np.array([-h])), (child, c + np.array([h]))]
    if s.kind == "rhombus":
        e, t = s.eps / 2, s.eps / s.block_length
        child = SourceSet(s.kind, s.leg, s.joint, s.field, e, s.cols, s.block_length)
        return [(child, c + np.array(o)) for o in ((e, 0.0), (-e, 0.0), (0.0, t), (0.0, -t))]
    if s.kind == "disk":
        half = math.pi / DISK_SECTORS
        return [sector_rect(s, 2 * half * j, half, 0.0, s.eps, c) for j in range(DISK_SECTORS)]
    if s.kind == "rect":
        theta, half, r1, r2, ox, oy = s.sector
        if s.eps_t >= s.eps:
            return [sector_rect(s, theta + sg * half / 2, half / 2, r1, r2, (ox, oy)) for sg in (-1, 1)]
        rm = (r1 + r2) / 2
        return [sector_rect(s, theta, half, a, b, (ox, oy)) for a, b in ((r1, rm), (rm, r2))]
    raise ValueError(f"a {s.kind} source is not cut")


def _contains(sets, centre: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Whether each of ``points`` ``(P, n)`` lies in the piece of shape ``sets`` centred at ``centre`` ``(n,)``."""
    return _contains_zero(sets, centre[None] - points)


def _piece_bounds(model1: _Model, M1: np.ndarray, sets, centres: np.ndarray, scale: float,
                  target: dict | None = None) -> dict:
    """Certificates of one pose (``model1``: one pose) over pieces of the same shape ``sets`` centred at
    ``centres`` ``(P, n)``: the closure solved exactly at each centre (Newton from the first-order solution
    ``M1`` ``(1, 9, n)``), the model expanded there and certified (:func:`_certify` with ``offset``; refined
    only above ``target``).

    Returns ``upper`` ``{q: (P,)}`` (inf where not certified), ``certified`` ``(P,)`` and per piece ``dz``
    ``(P, 9)`` (exact change at the centre), ``M`` ``(P, 9, n)``, ``b`` ``(P, 9)`` (the box: every ``delta``
    of the piece has one solution in ``|Dz - dz - M (delta - c)| <= b``, unique there) and ``bc`` ``(P, 9)``
    (the box of the solution at the centre). Whether that solution is the commanded assembly's continuation
    is decided by the caller (:func:`_branch_and_bound`)."""
    P = centres.shape[0]
    big = _take_many(model1, np.zeros(P, dtype=int))
    dz = exact_change(big, np.repeat(M1, P, axis=0), centres)
    good = np.all(np.isfinite(dz), axis=-1)
    dz = np.where(good[:, None], dz, 0.0)
    part = _certify(_recentre(big, np.concatenate([dz, centres], axis=-1)), sets, scale, offset=dz, target=target)
    cert = good & part["certified"]
    return {"upper": {q: np.where(cert, part["upper"][q], np.inf) for q in QUANTITIES}, "certified": cert,
            "dz": dz, "M": part["M"], "b": part["b"], "bc": part["b_centre"]}


def _point_anchor(model1: _Model, point: np.ndarray, guess: np.ndarray, scale: float):
    """A proven solution box at one point ``delta = point`` ``(n,)``: Newton's method from ``guess`` ``(9,)``,
    then :func:`_point_box` about the solution; returns ``(dz (9,), b (9,))`` (NaN where not proven)."""
    D = np.concatenate([guess, point])[None]
    moved = _recentre(model1, D)
    corr = exact_change(moved, np.zeros((1, 9, model1.n)), np.zeros((1, model1.n)))[0]
    if not np.all(np.isfinite(corr)):
        return np.full(9, np.nan), np.full(9, np.nan)
    dz = guess + corr
    b = _point_box(_recentre(model1, np.concatenate([dz, point])[None]), scale)[0]
    return dz, b


def _branch_and_bound(model1: _Model, sets, scale: float, lower: dict, gap: float = 0.005,
                      max_pieces: int = 96, anchor: dict | None = None, min_progress: int | None = None) -> dict:
    """Adaptive cutting of the error set of one pose until every bound is within ``gap`` of the best feasible
    value (module docstring, "Cutting the set" and "Continuation check").

    Pieces are products of the sources' sets with some sources cut (:func:`_children`: intervals halved,
    rhombi quartered, disks covered by sectors, sectors halved); each is certified by :func:`_piece_bounds`.
    A certified piece is *used* once its solution is shown to be the continuation of the commanded assembly:
    some point ``d`` of the piece has a proven continuation box (an *anchor*) inside the piece's box at ``d``
    (then, by the piece's uniqueness, its solution at ``d`` is the continuation, hence on the whole connected
    piece). Anchors: the commanded assembly at ``d = 0`` (``anchor["b0"]``, and the whole set's certified box
    ``anchor["b"]`` if any), the centre box of every used piece, and the centre ``c_P`` of every cut piece
    (contained in all of its children) once a used piece contains it: Newton at ``c_P`` from that piece's
    prediction and a point certificate (:func:`_point_anchor`) inside that piece's box.

    Rounds: every piece whose bound (its own if used, capped by its used ancestors') exceeds ``(1 + gap)``
    times the best feasible value is cut along its source of largest turning weight (``eps sum_m |r_m0|
    |alpha_m|``, interval, rhombus, disk or sector), worst first, until all are within or ``max_pieces``
    pieces have been certified, or no piece is used after ``min_progress`` (default ``max_pieces``). The best
    feasible values (``lower`` ``{q: float}``, raised as it goes) come from the extreme points of every used
    piece (the argsupport of its first-order rows and of :data:`PIECE_DIRECTIONS` directions of ``(dx, dy)``,
    projected onto ``S``), solved exactly from the piece's centre and kept only in the piece and inside its
    box there.

    Returns ``upper`` ``{q: float}`` (the largest capped bound over the pieces, which cover ``S``; inf while a
    piece has neither its own nor an ancestor's), ``lower`` ``{q: float}`` and ``worst`` ``{q: (n,) or
    None}`` (the configuration attaining it when it was raised here), ``pieces`` (leaves), ``bounded``
    (pieces certified in all) and ``rejected`` (leaves certified but never shown to be the continuation).
    """
    n = model1.n
    min_progress = max_pieces if min_progress is None else min_progress
    J = model1.jacobian(np.zeros((1, 9 + n)))
    M1 = -np.linalg.solve(J[..., :9], J[..., 9:])
    alpha = np.einsum("nmj,njk->nmk", model1.tg[..., :9], M1) + model1.tg[..., 9:]
    score = np.sum(np.abs(model1.r0)[..., None] * np.abs(alpha), axis=(0, 1))  # (n,)

    def weight(s):
        if s.kind == "interval":
            return s.eps * score[s.cols[0]]
        if s.kind in ("disk", "rect"):
            return max(s.eps, s.eps_t) * math.hypot(score[s.cols[0]], score[s.cols[1]])
        return max(s.eps * score[s.cols[0]], 2 * s.eps / s.block_length * score[s.cols[1]])

    anchor = anchor or {}
    anchors = []  # proven continuation boxes: (point (n,), lo (9,), hi (9,))
    for key in ("b0", "b"):
        b = np.asarray(anchor.get(key, np.full(9, np.nan)), dtype=float)
        if np.all(np.isfinite(b)):
            anchors.append((np.zeros(n), -b, b))
    lower = {q: float(lower[q]) if np.isfinite(lower[q]) else 0.0 for q in QUANTITIES}
    worst = {q: None for q in QUANTITIES}
    cut_points = []  # centres of the pieces cut so far, to be anchored when a used piece contains them
    anchored = set()

    # a leaf: dict(sets, centre, upper {q}, cert (dz, M, b, bc) or None, used)
    def bound(groups, target=None, caps=None):
        out = []
        for cs, C in groups:
            pb = _piece_bounds(model1, M1, cs, C, scale, target)
            for p in range(len(C)):
                cert = (pb["dz"][p], pb["M"][p], pb["b"][p], pb["bc"][p]) if pb["certified"][p] else None
                out.append({"sets": cs, "centre": C[p], "upper": {q: float(pb["upper"][q][p]) for q in QUANTITIES},
                            "cert": cert, "used": False, "cap": dict(caps[len(out)]) if caps else
                            {q: np.inf for q in QUANTITIES}})
        return out

    def box_at(leaf, d):
        dz, Mp, b, _ = leaf["cert"]
        mid = dz + Mp @ (d - leaf["centre"])
        return mid - b, mid + b

    def settle(leaves):
        """Use every certified leaf that contains an anchor inside its box; used leaves add anchors."""
        fresh, changed = [], True
        while changed:
            changed = False
            for leaf in leaves:
                if leaf["used"] or leaf["cert"] is None or not anchors:
                    continue
                pts = np.array([a[0] for a in anchors])
                inside = np.flatnonzero(_contains(leaf["sets"], leaf["centre"], pts))
                for a in inside:
                    d, lo, hi = anchors[a]
                    blo, bhi = box_at(leaf, d)
                    if np.all(np.isfinite(blo)) and np.all(lo >= blo) and np.all(hi <= bhi):
                        break
                else:
                    continue
                leaf["used"], changed = True, True
                fresh.append(leaf)
                dz, _, _, bc = leaf["cert"]
                if np.all(np.isfinite(bc)):
                    anchors.append((leaf["centre"].copy(), dz - bc, dz + bc))
                for k, p in enumerate(cut_points):
                    if k in anchored or not _contains(leaf["sets"], leaf["centre"], p[None])[0]:
                        continue
                    blo, bhi = box_at(leaf, p)
                    zp, bp = _point_anchor(model1, p, (blo + bhi) / 2, scale)
                    if np.all(np.isfinite(bp)) and np.all(zp - bp >= blo) and np.all(zp + bp <= bhi):
                        anchors.append((p.copy(), zp - bp, zp + bp))
                        anchored.add(k)
        return fresh

    def raise_lower(fresh):
        """The best feasible values at the extreme points of the newly used pieces (solved from each piece)."""
        if not fresh:
            return
        ang = 2 * np.pi * np.arange(PIECE_DIRECTIONS) / PIECE_DIRECTIONS
        u = np.stack([np.cos(ang), np.sin(ang)], axis=-1)
        for leaf in fresh:
            dz, Mp, b, _ = leaf["cert"]
            rows = np.concatenate([Mp[:3], -Mp[:3], u @ Mp[:2]])  # (6 + K, n)
            cand = project(sets, argsupport(leaf["sets"], rows) + leaf["centre"])
            moved = _recentre(model1, np.concatenate([dz, leaf["centre"]])[None])
            sol = exact_change(moved, Mp[None], (cand - leaf["centre"])[:, None, :])[:, 0] + dz  # (R, 9)
            pred = dz + (cand - leaf["centre"]) @ Mp.T
            # in the piece and inside its box there: the continuation (module docstring, "Continuation check")
            ok = np.all(np.abs(sol - pred) <= b, axis=-1) & _contains(leaf["sets"], leaf["centre"], cand)
            vals = np.stack([_objective(q, sol) for q in QUANTITIES])  # (4, R)
            vals = np.where(ok[None] & np.isfinite(vals), vals, -np.inf)
            for qi, q in enumerate(QUANTITIES):
                r = int(np.argmax(vals[qi]))
                if vals[qi, r] > lower[q]:
                    lower[q], worst[q] = float(vals[qi, r]), cand[r].copy()

    def effective(leaf, q):
        """A leaf's bound: its own if used, capped by its used ancestors' (each holds over the leaf's part)."""
        return min(leaf["upper"][q] if leaf["used"] else np.inf, leaf["cap"][q])

    leaves = bound([(tuple(sets), np.zeros((1, n)))])
    used = 1
    raise_lower(settle(leaves))
    while True:
        target = {q: lower[q] * (1 + gap) for q in QUANTITIES}

        def excess(leaf):
            return max(effective(leaf, q) / target[q] - 1 if target[q] > 0 else
                       (np.inf if effective(leaf, q) > 0 else -1.0) for q in QUANTITIES)

        ex = [excess(leaf) for leaf in leaves]
        over = [i for i, e in enumerate(ex) if e > 0]
        if not over:
            break
        if used >= min_progress and not any(leaf["used"] for leaf in leaves):
            break  # no piece shown to be the continuation yet: more cutting is unlikely to help
        over.sort(key=lambda i: -ex[i])
        plan, cost = [], 0
        for i in over:
            leaf = leaves[i]
            ps = leaf["sets"]
            k = max(range(len(ps)), key=lambda j: weight(ps[j]))
            cols = list(ps[k].cols)
            kids = _children(ps[k], leaf["centre"][cols])
            if used + cost + len(kids) > max_pieces:
                break
            plan.append((i, k, cols, kids))
            cost += len(kids)
        if not plan:
            break
        groups = {}  # children of the same shape are certified together (one vectorized certificate)
        for i, k, cols, kids in plan:
            leaf = leaves[i]
            cut_points.append(leaf["centre"].copy())
            cap = {q: effective(leaf, q) for q in QUANTITIES}
            for child, cc in kids:
                cs = leaf["sets"][:k] + (child,) + leaf["sets"][k + 1:]
                C = leaf["centre"].copy()
                C[cols] = cc
                groups.setdefault(cs, []).append((C, cap))
        drop = {i for i, *_ in plan}
        used += cost
        leaves = [x for i, x in enumerate(leaves) if i not in drop] + bound(
            [(cs, np.array([c for c, _ in Cs])) for cs, Cs in groups.items()], target,
            [cap for Cs in groups.values() for _, cap in Cs])
        # the cut pieces' centres may now lie in used pieces: anchor them, then use what they reach
        for leaf in leaves:
            if leaf["used"]:
                for k, p in enumerate(cut_points):
                    if k in anchored or not _contains(leaf["sets"], leaf["centre"], p[None])[0]:
                        continue
                    blo, bhi = box_at(leaf, p)
                    zp, bp = _point_anchor(model1, p, (blo + bhi) / 2, scale)
                    if np.all(np.isfinite(bp)) and np.all(zp - bp >= blo) and np.all(zp + bp <= bhi):
                        anchors.append((p.copy(), zp - bp, zp + bp))
                        anchored.add(k)
        raise_lower(settle(leaves))
    upper = {q: max(effective(leaf, q) for leaf in leaves) for q in QUANTITIES}
    return {"upper": upper, "lower": lower, "worst": worst, "pieces": len(leaves), "bounded": used,
            "rejected": sum(1 for leaf in leaves if leaf["cert"] is not None and not leaf["used"])}


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


def certified_pose_errors(robot, clearances, poses, *, search: bool = True, allow_outside: bool = False,
                          on_failure: str = "raise", split: int = 2, split_gap: float = 0.005,
                          max_pieces: int = 96) -> CertifiedPoseErrors:
    """Certified upper bounds of the exact worst-case ``|dx|, |dy|, |dphi|, |dp|`` and the best feasible values.

    Parameters
    ----------
    robot : :class:`~pmaccuracy.model.manipulator.Manipulator`, preset name or TOML path (any architecture)
    clearances : per-joint :class:`~pmaccuracy.model.sources.ErrorSources`, a 3-PPR
        :class:`~pmaccuracy.model.clearances.ClearanceSet` (bearing = ``angular`` on joint 2, guide play =
        ``lateral`` on joint 1, revolute = ``radial`` on joint 3), a preset name or a TOML path
    poses : ``(3,)`` or ``(N, 3)`` [x mm, y mm, phi rad]
    search : also find the best feasible configurations (:func:`nonlinear_pose_errors`) for ``lower`` and
        ``gap`` (otherwise NaN)
    allow_outside : accept poses outside the joint ranges (as :func:`pmaccuracy.accuracy.bounds.max_pose_errors`)
    on_failure : ``"raise"`` (:class:`~pmaccuracy.errors.CertificationError` naming the pose and why) or
        ``"nan"`` (NaN upper bounds and the reason in ``reason``)
    split, split_gap : where the bound is not certified or its gap to the best feasible value (to the
        first-order value without ``search``) exceeds ``split_gap``, it is computed again over ``2^split``
        pieces of the error set (:func:`_split_bounds`; 0: never) and the smaller valid bound is kept
    max_pieces : where the gap still exceeds ``split_gap`` (or there is no certificate), the set is cut
        adaptively (:func:`_branch_and_bound`) until the gap is below ``split_gap`` or ``max_pieces`` pieces
        (:data:`REFUSED_BUDGET` times as many for a pose with no certificate yet) have been bounded (0 or 1:
        never); the smaller valid bound is kept

    Notes
    -----
    Returns a :class:`CertifiedPoseErrors`: ``upper[q] >= `` the maximum over the whole error set of the
    exact pose error (module docstring) ``>= lower[q] >=`` the exact value at the first-order worst vertex.
    Poses outside the ranges or near a singularity are refused first, as by ``max_pose_errors``.

    Example
    -------
    >>> r = certified_pose_errors("aalborg_3ppr", "case1", [0.0, 0.0, 0.0])
    >>> bool(r.first_order["dx"][0] <= r.lower["dx"][0] <= r.upper["dx"][0])
    True
    """
    from .bounds import max_pose_errors

    if on_failure not in ("raise", "nan"):
        raise ValueError(f"on_failure must be 'raise' or 'nan', got {on_failure!r}")
    robot, sources, poses = _prepare(robot, clearances, poses)
    fo = max_pose_errors(robot, sources, poses, allow_outside=allow_outside)
    rb = remainder_bounds(robot, sources, poses)
    first = {q: np.asarray(getattr(fo, f"{q}_max"), dtype=float).reshape(-1) for q in QUANTITIES}
    if search:
        lower, worst, _ = _nonlinear(rb["model"], rb["M"], rb["sets"])
    else:
        lower = {q: np.full(poses.shape[0], np.nan) for q in QUANTITIES}
        worst = {}
    upper, reason = dict(rb["upper"]), rb["reason"].copy()
    # the whole set's certificate: the parent every piece is checked against (_continues)
    anc_b = np.where(rb["certified"][:, None], rb["b"], np.nan)
    anc_b0 = _point_box(rb["model"], robot.characteristic_length)
    rejected = np.zeros(poses.shape[0], dtype=int)
    if split:
        # poses without a certificate or with a gap above split_gap: bound again over 2^split pieces, keep the
        # smaller of the valid bounds (both hold)
        ref = {q: np.where(np.isfinite(lower[q]), lower[q], first[q]) for q in QUANTITIES}
        loose = (reason != "") | np.any([_gap(upper[q], ref[q]) > split_gap for q in QUANTITIES], axis=0)
        idx = np.flatnonzero(loose & (rb["reason"] != "singular loop-closure Jacobian at the commanded pose"))
        if idx.size:
            sp = _split_bounds(_take_many(rb["model"], idx), rb["sets"], robot.characteristic_length, split,
                               rb["M"][idx], anc_b[idx], anc_b0[idx])
            rejected[idx] += sp["rejected"]
            for q in QUANTITIES:
                upper[q][idx] = np.where(sp["certified"], np.fmin(upper[q][idx], sp["upper"][q]), upper[q][idx])
            reason[idx[sp["certified"]]] = ""
        # not certified, or certified but still loose: adaptive cutting (branch and bound) pose by pose until within
        # split_gap, no progress or the budget ends; a refused pose is certified only if every piece is used
        loose = (reason != "") | np.any([_gap(upper[q], ref[q]) > split_gap for q in QUANTITIES], axis=0)
        idx = np.flatnonzero(loose & (rb["reason"] != "singular loop-closure Jacobian at the commanded pose"))
        for k in idx if max_pieces > 1 else ():
            budget = max_pieces * (REFUSED_BUDGET if reason[k] else 1)
            bb = _branch_and_bound(_take(rb["model"], k), rb["sets"], robot.characteristic_length,
                                   {q: ref[q][k] for q in QUANTITIES}, split_gap, budget,
                                   {"b": anc_b[k], "b0": anc_b0[k]}, min_progress=max_pieces)
            rejected[k] += bb["rejected"]
            if all(np.isfinite(bb["upper"][q]) for q in QUANTITIES):
                for q in QUANTITIES:
                    upper[q][k] = np.fmin(upper[q][k], bb["upper"][q])
                reason[k] = ""
            for q in QUANTITIES:
                if search and bb["worst"][q] is not None and not bb["lower"][q] <= lower[q][k]:
                    lower[q][k], worst[q][k] = bb["lower"][q], bb["worst"][q]
    if on_failure == "raise" and np.any(reason != ""):
        k = int(np.flatnonzero(reason != "")[0])
        x, y, phi = poses[k]
        raise CertificationError(f"pose {k} (x={x:g} mm, y={y:g} mm, phi={math.degrees(phi):g} deg): {reason[k]}")
    gap = {q: _gap(upper[q], lower[q]) for q in QUANTITIES}
    return CertifiedPoseErrors(poses=poses, upper=upper, lower=lower, first_order=first, gap=gap,
                               worst=worst, remainder=rb["b"], reason=reason, sets=rb["sets"], rejected=rejected)


def nonlinear_pose_errors(robot, clearances, poses, *, allow_outside: bool = False, polish: int = 0
                          ) -> CertifiedPoseErrors:
    """The best feasible worst cases of the exact model: local ascent from the first-order worst vertices.

    From the first-order worst configuration of each quantity and its negative
    (:func:`pmaccuracy.model.sources.worst_configuration`, ``worst_signs``), the exact pose is solved
    (Newton on the closure, :func:`exact_change`) and the configuration is replaced by the extreme point of
    the error set that maximizes the linearization of the exact objective at it (``argsupport`` of its exact
    gradient, a successive-linearization ascent that only accepts increases, all poses at once); with
    ``polish`` (iterations) an SLSQP run over the source parameters follows, pose by pose. Every value is
    attained by a feasible configuration (``worst``), so it is a lower bound of the true maximum.

    Returns a :class:`CertifiedPoseErrors` with ``lower`` (the values), ``worst``, ``first_order`` and, when
    the certificate holds, ``upper`` and ``gap`` (NaN otherwise); arguments as :func:`certified_pose_errors`.
    """
    from .bounds import max_pose_errors

    robot, sources, poses = _prepare(robot, clearances, poses)
    fo = max_pose_errors(robot, sources, poses, allow_outside=allow_outside)
    rb = remainder_bounds(robot, sources, poses)
    lower, worst, _ = _nonlinear(rb["model"], rb["M"], rb["sets"], polish=polish)
    first = {q: np.asarray(getattr(fo, f"{q}_max"), dtype=float).reshape(-1) for q in QUANTITIES}
    gap = {q: _gap(rb["upper"][q], lower[q]) for q in QUANTITIES}
    return CertifiedPoseErrors(poses=poses, upper=rb["upper"], lower=lower, first_order=first, gap=gap,
                               worst=worst, remainder=rb["b"], reason=rb["reason"], sets=rb["sets"])


def _gap(upper: np.ndarray, lower: np.ndarray) -> np.ndarray:
    """``(upper - lower) / lower``; 0 where both are 0, NaN where either is NaN."""
    with np.errstate(all="ignore"):
        g = (upper - lower) / lower
    return np.where((upper == 0) & (lower == 0), 0.0, g)


# ============================================================================ exact model and local ascent
def _take(model: _Model, k: int) -> _Model:
    """The model of pose ``k`` alone (``N = 1``)."""
    sl = slice(k, k + 1)
    return _Model(r0=model.r0[sl], t0=model.t0[sl], rg=model.rg[sl], tg=model.tg[sl], leg_of=model.leg_of,
                  aff0=model.aff0[sl], affg=model.affg[sl], ang0=model.ang0[sl], angg=model.angg[sl], n=model.n,
                  z0=model.z0[sl])


def _take_many(model: _Model, idx: np.ndarray) -> _Model:
    """The model of the poses ``idx`` (indices)."""
    return _Model(r0=model.r0[idx], t0=model.t0[idx], rg=model.rg[idx], tg=model.tg[idx], leg_of=model.leg_of,
                  aff0=model.aff0[idx], affg=model.affg[idx], ang0=model.ang0[idx], angg=model.angg[idx],
                  n=model.n, z0=model.z0[idx])


def exact_change(model: _Model, M: np.ndarray, delta: np.ndarray, iterations: int = 20,
                 gradient: bool = False):
    """Exact change ``Dz`` ``(..., N, 9)`` of pose and passive joints for source values ``delta`` ``(..., N, n)``.

    Newton's method on the closure residuals (module docstring) from the first-order solution ``M delta``
    (the commanded assembly's continuation); NaN where it does not converge to ``|residual| < 1e-9 *
    scale``. With ``gradient`` also ``dDz / ddelta = -J_z^-1 J_delta`` at the solution ``(..., N, 9, n)``.
    """
    delta = np.asarray(delta, dtype=float)
    dz = np.einsum("nij,...nj->...ni", M, delta)
    scale = max(1.0, float(np.max(np.abs(model.r0)))) if model.r0.size else 1.0
    for _ in range(iterations):
        D = np.concatenate([dz, delta], axis=-1)
        r = model.residual(D)
        J = model.jacobian(D)[..., :9]
        with np.errstate(all="ignore"):
            try:
                step = np.linalg.solve(J, r[..., None])[..., 0]
            except np.linalg.LinAlgError:
                step = np.full_like(dz, np.nan)
        dz = dz - step
        if np.all((np.abs(step) <= 1e-14 * scale) | ~np.isfinite(step)):  # converged (quadratically) or NaN
            break
    D = np.concatenate([dz, delta], axis=-1)
    r = model.residual(D)
    good = np.all(np.abs(r) < 1e-9 * scale, axis=-1) & np.all(np.isfinite(dz), axis=-1)
    dz = np.where(good[..., None], dz, np.nan)
    if not gradient:
        return dz
    J = model.jacobian(D)
    with np.errstate(all="ignore"):
        try:
            G = -np.linalg.solve(J[..., :9], J[..., 9:])
        except np.linalg.LinAlgError:
            G = np.full(dz.shape + (model.n,), np.nan)
    return dz, G


def _objective(q: str, dz: np.ndarray) -> np.ndarray:
    """The quantity ``q`` of pose changes ``dz (..., 9)``: ``|dx|``, ``|dy|``, ``|dphi|`` or ``|dp|``."""
    if q == "dp":
        return np.hypot(dz[..., 0], dz[..., 1])
    return np.abs(dz[..., QUANTITIES.index(q)])


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


def _first_order_starts(sets, M: np.ndarray, n_dp: int = 3) -> np.ndarray:
    """First-order worst vertices ``(4, n_dp, N, n)``: of dx, dy, dphi (signs of the rows of ``M``, as
    :func:`pmaccuracy.model.sources.worst_configuration`; repeated) and of ``|dp|`` (the vertices maximizing ``u . p``
    for the ``n_dp`` best local maxima over 720 directions ``u`` of the support function: the nonlinear
    maximum may belong to a direction that is not the first-order best)."""
    N = M.shape[0]
    starts = [np.repeat(argsupport(sets, M[:, j, :])[None], n_dp, axis=0) for j in range(3)]
    ang = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    u = np.stack([np.cos(ang), np.sin(ang)], axis=-1)
    rowmap = np.einsum("kr,nrd->nkd", u, M[:, :2, :])
    h = support(sets, rowmap)  # (N, 720)
    peak = (h >= np.roll(h, 1, axis=-1)) & (h >= np.roll(h, -1, axis=-1))
    order = np.argsort(np.where(peak, -h, np.inf), axis=-1)[:, :n_dp]  # best local maxima first
    order = np.where(np.take_along_axis(peak, order, axis=-1), order, order[:, :1])  # fewer peaks: repeat the best
    starts.append(np.stack([argsupport(sets, rowmap[np.arange(N), order[:, k]]) for k in range(n_dp)]))
    return np.stack(starts)


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


def _nonlinear(model: _Model, M: np.ndarray, sets, iterations: int = 30, polish: int = 0
               ) -> tuple[dict, dict, dict]:
    """Best feasible exact values ``{q: (N,)}``, their ``delta`` ``{q: (N, n)}`` and the exact values at the
    first-order worst vertices ``{q: (N,)}`` (:func:`nonlinear_pose_errors`)."""
    N, n = M.shape[0], model.n
    if n == 0:
        z = {q: np.zeros(N) for q in QUANTITIES}
        return z, {q: np.zeros((N, 0)) for q in QUANTITIES}, dict(z)
    d0 = _first_order_starts(sets, M)  # (4, 3, N, n)
    cur = np.concatenate([d0, -d0], axis=1)  # (4, 6, N, n): both signs of each vertex
    dz, G = exact_change(model, M, cur, gradient=True)
    val, grad = _objective_gradient(dz, G)
    val = np.where(np.isfinite(val), val, -np.inf)
    vertex = np.max(val, axis=1)  # (4, N)
    for _ in range(iterations):
        # successive linearization: the vertex maximizing the exact gradient's linear form over S
        cand = argsupport(sets, grad)
        dzc, Gc = exact_change(model, M, cand, gradient=True)
        vc, gc = _objective_gradient(dzc, Gc)
        better = np.isfinite(vc) & (vc > val * (1 + 1e-15))
        if not np.any(better):
            break
        cur = np.where(better[..., None], cand, cur)
        val = np.where(better, vc, val)
        grad = np.where(better[..., None], gc, grad)
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
