"""Exact nonlinear error models of the spatial robots at a pose, and certified bounds of their worst case (issue 37).

The 6-UPS (first part) reduces to one distance equation per leg; the 3-RPS, 3-PRS, 3-UPU and Delta (second part,
at the end) are solved as serial chains.

The nonlinear model
-------------------
Every source (``docs/guide/spatial-errors.md``) is a FINITE displacement of its joint's distal part relative to
its proximal part, applied before the joint's own motion, its directions fixed at the nominal pose (the
convention of :mod:`pmaccuracy.accuracy.spatial_bounds`). The sources of a joint add into one translation and
one rotation vector; leg ``i`` (base centre ``A``, platform centre ``B = p + R b``, ``r = B - p``, nominal
length ``L`` and unit direction ``d``, ``M = A + (L/2) d`` the carriage centre) gets

* base universal joint: translations ``t0`` (radial: pin 1 a disc normal to ``u1``, pin 2 a disc normal to
  ``u2``; axial along ``u1`` and ``u2``; position a ball; length along ``d``) and rotations about ``A`` (tilt,
  direction);
* slide: translations ``t1`` (actuator, backlash, length along ``d``; lateral a disc normal to ``d``; position a
  ball), a tilt ``w_t`` about ``M`` and a direction turn ``w_d`` about ``A`` (both normal to ``d``), applied as
  the turn ``w1 = w_t + w_d`` about ``M`` plus the translation ``(Rot(w_d) - I)(M - A)``;
* platform spherical joint: translations ``t2`` (radial, position balls).

Walking the chain ``E_U J_U E_P E_S J_S`` (``J`` the passive joints' finite motions), the spherical joint frees
the platform's rotation about ``B``, the universal joint (two rotations about ``A``) frees the direction of
``J_U(Y) - A``, and a rotation of the base joint about ``A`` is absorbed by it: the closure of leg ``i``
reduces EXACTLY to one distance equation for the platform's error twist ``t = [v, w]`` (the displaced pose
``p + v``, ``Rot(w) R``)::

    |L d + u| = |L d + z|,   u = v + (Rot(w) - I) r - t0,                                            (1)
    z = (L/2)(Rot(w1) - I) d + Rot(w1) t2 + t1 + (L/2)(Rot(w_d) - I) d.

(base-joint rotations drop out exactly). :func:`hexapod_error_twists` solves (1) by Newton's method
(vectorized over configurations; the arithmetic is on the small displacements: ``|L d + x| - L = d.x +
|x_perp|^2 / (|L d + x| + L + d.x)``, no cancellation against the 1000 mm coordinates).

Expansion. With ``|L d + x| - L = d.x + |x_perp|^2 / D_x``, ``D_x = |L d + x| + L + d.x`` and
``(Rot(w) - I) r = w x r + eps``, (1) is exactly ``W t = a(s) + q(s, t)``: ``W`` the closure matrix (rows
``[d, r x d]``), ``a_i = d.(t0 + t1 + t2)`` the first-order leg term (its range ``[-rho_i, rho_i]``,
``rho_i`` of :func:`~pmaccuracy.accuracy.spatial_bounds.hexapod_leg_terms`: ``t = W^-1 a`` is the first-order
model of :func:`~pmaccuracy.accuracy.spatial_bounds.spatial_pose_errors`), and::

    q = (L/2)(cos|w1| - 1) + (L/2)(cos|w_d| - 1) + d.(Rot(w1) - I) t2 + |z_perp|^2 / D_z
        - |u_perp|^2 / D_u - d.eps.                                                                  (2)

Bounds of the terms (``h`` the half-widths; ``O1 = sum h`` of the slide's tilt and direction, ``Od`` of its
direction, ``T1, T2`` the sums of the translations' half-widths, ``T1p`` of their parts normal to ``d``):
``|d.(Rot(w1) - I) t2| <= 2 sin(O1/2) T2``; ``|z| <= Z = L sin(O1/2) + T2 + T1 + L sin(Od/2)`` (``w1, w_d``
normal to ``d``), ``|z_perp| <= Zp`` (the same with ``T1p``) and ``D_z >= 2 (L - Z)``; ``|eps| <= |w|^2
|r| / 2`` (``|exp([w]x) - I - [w]x| <= |w|^2 / 2``: ``theta^2 - 2 theta sin(theta) + 2 - 2 cos(theta) <=
theta^4 / 4``) and, from ``eps = (sin t / t - 1) w x r + (1 - cos t) / t^2 w x (w x r)`` with ``d . (w x (w x
r)) = w^T (sym(d r^T) - (d.r) I) w`` (eigenvalues ``(+-|r| - d.r) / 2`` and ``-d.r``), ``|d . eps| <= e_d =
|w|^2 (|r| + |d.r|) / 4 + |w|^3 |r| / 6``; ``|u_perp| <= Up``, ``|u| <= U`` and ``D_u >= 2 (L - U)`` from the
box below. So ``q_i`` lies in ``[q_lo_i, q_hi_i]``::

    q_lo = -(L/2)(2 - cos O1 - cos Od) - 2 sin(O1/2) T2 - Up^2 / (2 (L - U)) - e_d
    q_hi =  2 sin(O1/2) T2 + Zp^2 / (2 (L - Z)) + e_d                                                  (3)

Theorem (certified at a pose). Let ``B`` be the convex set of twists ``|v| <= Rv``, ``|w| <= Rw``, ``|P_i
[I, -[r_i]x] t| <= Yp_i`` and ``|[I, -[r_i]x] t| <= Y_i`` (``P_i`` the projection normal to ``d_i``), with
``Up_i = Yp_i + Rw^2 |r_i| / 2 + T0p_i``, ``U_i = Y_i + Rw^2 |r_i| / 2 + T0_i`` below ``L_i``, and let every
bound of ``B`` be at least the largest value of its functional over ``W^-1 X``, ``X`` the box ``[-rho +
q_lo, rho + q_hi]`` (a convex function over a box: its largest value is at one of the 64 vertices). Then for
every configuration ``s`` of the sources the map ``t -> W^-1 (a(s) + q(s, t))`` sends ``B`` into itself
(Brouwer: (1) has a solution in ``B``). If moreover the 2 x 2 matrix ``Lam = [[sum_i |W^-1_v,i| a_i, sum_i
|W^-1_v,i| b_i], [the same for w]]``, ``a_i = Up_i / (L_i - U_i)`` and ``b_i = |r_i| (3 Rw / 2 + Rw^2 / 6 +
a_i)`` (bounds of ``|n - d|`` (the angle between ``L d + u`` and ``d``) and of the moment part of the closure's
Jacobian ``n^T [I, -[Rot(w) r]x J_l(w)]`` minus ``W``'s row, ``n = (L d + u) / |L d + u|``, with
``|Rot(w) r - r| <= |w| |r|`` and ``|J_l(w) - I| <= |w|/2 + |w|^2/6``), has
spectral radius below 1, that solution is the only one in ``B`` (so it is the continuation of the nominal
assembly that Newton's method from the nominal pose finds). Every quantity of the error is then at most
its largest value over ``W^-1 X``: for a component ``k``, ``max_X |(W^-1 x)_k| = sum_i |W^-1_ki| rho_i +
sum_i max(W^-1_ki q_lo_i, W^-1_ki q_hi_i)`` (or the other sign), the first-order maximum plus a remainder
``K h^2`` (every term of (3) is quadratic in the half-widths, ``Rv, Rw, Y`` linear); ``|dp|`` and
``|dtheta|`` (the error rotation's angle ``|w|``) over the 64 vertices.

Rounding: ``W^-1`` is enclosed from the computed inverse ``C``: with ``E = I - W C`` (its rounding bounded
by ``7 eps |W| |C|``) and ``eta = ||E||_inf < 1``, ``W^-1 = C (I - E)^-1 = C + C N`` with every entry of ``N =
sum_k>=1 E^k`` at most ``eta / (1 - eta)``, so ``|W^-1 - C|_kj <= eta / (1 - eta)`` times row ``k``'s sum of
``|C|``, added to every functional; the final values are multiplied by ``1 + 1e-13`` (the rounding of the
sums of a few tens of positive terms is below 1e-14 relative). The geometry is taken as represented in
floating point.

Refused (``certified`` False, upper ``inf``, with the reason): the box iteration does not close (the error
set reaches a singularity, or ``U >= L``), or ``Lam`` is not a contraction. A pose that is unreachable,
outside the joint limits or near-singular raises, as for the first-order bounds. A chain robot
(``spatial-chain``) raises :class:`~pmaccuracy.errors.UnsupportedArchitectureError`.

The lower values are attained: the exact model (1) at the first-order worst configuration of each quantity
(both signs for a component), improved by a few conditional-gradient steps over the sources' sets (gradients
of the exact model by implicit differentiation), each accepted only if it increases the quantity; the configuration
is returned (each source's displacement vector, base frame).

Second part: 3-RPS, 3-PRS, 3-UPU and Delta as serial chains
-----------------------------------------------------------
The exact model (the same as the independent reference ``tests/reference/spatial_error_reference.py``): each
leg is a chain from the base to the platform (a Delta leg two, one per rod, sharing the arm), written as a product
of rigid displacements about the nominal configuration, every factor in the base frame at the given pose::

    D_chain = prod_j E_j J_j = Delta,   Delta: x -> p + dp + Rot(w) (x - p),                               (4)

``J_j`` the passive joint's motion (a universal joint: rotations about ``u1`` then ``u2`` about its centre; a
revolute one; a spherical joint a rotation vector (3), a Delta's elbow ball a rotation vector normal to its rod
(2, the rod's spin is idle); the actuated joint held) and ``E_j : x -> c_j + Rot(omega_j) (x - c_j) + t_j +
sum_o (Rot(omega_o) - I)(c_j - O)`` the joint's sources summed into one rotation about its centre ``c_j`` (a
slide: the carriage centre) and one translation, a slide's direction tolerance ``omega_o`` turning about the
slide's origin ``O``. The unknowns ``y`` are ``dp, w`` and the passive rotations (18 for a 3-legged robot with
one chain per leg, 36 for a Delta); the equations per chain, at its origin ``o`` (its platform joint's centre),
``F = Phi_o(D_chain) - Phi_o(Delta) = 0`` with ``Phi_o(g) = (g(o) - o, vee(skew(R_g)))`` (equal skew parts
of two rotations below 90 deg: equal rotations). :func:`_chain_solve` iterates ``y <- y - A^-1 F(y)`` from 0.

Expansion. Each factor ``G_f`` is ``I + X_f + (G_f - I - X_f)`` (``X_f`` its twist, linear in its own
variables), and telescoping ``prod G_f - I = sum_f (G_f - I) + sum_f (G_f - I)(P_>f - I)`` (``P_>f`` the
product of the factors after ``f``) gives ``F = A y + B s + r`` exactly, ``A``, ``B`` the sums of the twists
(:func:`_chain_linear`; ``-A^-1 B`` is the first-order model of
:func:`~pmaccuracy.accuracy.spatial_bounds.spatial_pose_errors`) and, with ``theta_f`` a bound of ``G_f``'s
rotation angle, ``tau_f`` of its translation at ``o``, ``T_>f = sum_g>f tau_g``, ``Th_>f = sum_g>f theta_g``
(the bounds of ``P_>f``'s translation and angle), ``|Rot - I| <= theta``, ``|Rot - I - [w]x| <= theta^2/2``
and ``|vee skew(M)| <= |M|_2``::

    |r_trans| <= sum_f dt_f + sum_f theta_f T_>f + Rw^2 |o - p| / 2,
    |r_rot|   <= sum_f theta_f^3 / 6 + sum_f theta_f Th_>f (1 + theta_f + Th_>f + theta_f Th_>f / 2) / 2
                 + Rw^3 / 6                                                                          (5)

(``dt_f = theta_f^2 |c_f - o| / 2`` plus ``h^2 |c - O| / 2`` per origin-turn; the skew part of
``(Rot_f - I)(Rot_P - I)`` is ``(w_f x W_P) / 2`` plus third-order terms). For a box ``Y`` of the unknowns (a
bound of the norm of ``dp``, ``w`` and each passive joint's vector) the fixed-point map ``y -> -A^-1 (B s +
r(y, s))`` sends ``Y`` into its interior when, for every group ``g``, ``max_s |(A^-1 B s)_g|`` (certified by
:func:`~pmaccuracy.numerics.support.max_norm`) plus ``sum_chains |A^-1_g,trans| rho_t + |A^-1_g,rot| rho_r``
is below ``Y_g`` (Brouwer: a solution in ``Y`` for every configuration ``s``). The derivative of ``r`` in a
passive rotation ``e`` of factor ``f`` is ``Phi[P_<f (dG_f - X_e) P_>f + (P_<f - I) X_e P_>f + X_e (P_>f - I)]``,
so its translation part is at most ``beta T_>f + beta |c_f - o| + Th_<f (T_>f + |c_f - o|) + T_>f`` and its
rotation part ``beta + Th_<f + Th_>f`` (``beta = 3 theta / 2 + theta^2 / 6`` bounds ``|d Rot(phi)/de - [e]x|``);
in ``w`` (the platform's own remainder) ``beta |o - p|`` and ``Rw^2 / 2``; in ``dp`` 0. If the nonnegative
matrix ``Lam_gh = sum_chains |A^-1_g,block| k_block,h`` has spectral radius below 1 (Collatz-Wielandt bound
from its computed Perron vector) the map is a contraction on ``Y``: the solution is unique there, the
continuation of the nominal assembly that the iteration finds. Every quantity is then at most its first-order
maximum (exact support functions of the components; ``max_norm``'s certified ``|dp|``, ``|dtheta|``) plus
``sum_chains |A^-1_k,trans| rho_t + |A^-1_k,rot| rho_r`` (the remainder, quadratic in the half-widths).
Sharper, at the solution (Eq. 6): the second-order part of ``r`` is exactly the quadratic form ``Q(z) =
sum_f q_f(z_f) + sum_f<g (w_f x v_g, (w_f x w_g) / 2) - (w x (w x (o - p))) / 2`` (``(v_f, w_f)`` the factors'
twists at ``o``, ``q_f = -(w_f x (w_f x (c_f - o))) / 2`` plus ``(w_o x (w_o x (c_f - O))) / 2`` per origin-turn:
the skew part of ``[w_f]x [w_g]x`` is ``[w_f x w_g]x / 2``). At the solution ``y = L s + eta`` (``L = -A^-1 B``,
``|eta_g| <= sum |A^-1_g,block| rho_block``), so ``y_k = (L s)_k - (A^-1 Q(L s, s))_k - (A^-1 Delta)_k``: the
middle term is a quadratic form ``s^T H_k s`` of the sources' variables, bounded over their sets by ``sum_ab
|H_k[a, b]|_2`` (blocks per source: cancellations such as a 3-UPU's opposite universal-joint turns are kept),
and ``Delta`` is third order: ``|Rot - I - [w]x - [w]x^2 / 2| <= theta^3 / 6 + theta^4 / 24``, the cross terms
``(G_f - I - X_f)(P_>f - I) + X_f (P_>f - I - X_>f)`` bounded by ``theta_f^2 / 2`` times ``T_>f`` (``Th_>f``) plus
``theta_f`` times the second-order parts of ``P_>f`` (sums as in (5)), and ``Q(z) - Q(L s, s)`` by ``eta``
times the first-order bounds. These bounds hold at the unique solution only, so they are iterated: the
offset ``eta`` and the box shrink to ``|(A^-1 Q)_g| + |A^-1_g,block| Delta`` and ``max_s |(L s)_g|`` plus that
(four passes). The remainder of each quantity is the smaller of this and the bound from (5).
Rounding: ``A^-1`` enclosed as in the first part (``(n + 1) eps``); ``C B``'s rounding added per source.
Refused as in the first part when the box does not close (its angles above 0.5 rad) or ``Lam`` is not a
contraction. Lower values: the first-order worst configurations re-solved by (4) and improved by
conditional-gradient steps (gradients ``-A^-1 dF/ds`` at the solution), each kept only if it increases the
quantity. A 3-RPS or 3-PRS pose must satisfy its legs' constraints, a 3-UPU or Delta pose has no rotation
(:class:`~pmaccuracy.errors.PoseError` otherwise).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError, PoseError, UnsupportedArchitectureError
from ..kinematics.spatial import as_spatial_poses, inverse_kinematics
from ..model.plausibility import check_angle_values, rotation_angles
from ..model.spatial import SpatialManipulator
from ..model.spatial_sources import JOINTS, SpatialErrorSources
from ..numerics.spatial import normalize, rotations, skew
from ..numerics.support import max_norm
from .spatial_bounds import hexapod_leg_terms, spatial_pose_errors

#: The quantities, in order: the six components (mm, rad), then |dp| (mm) and |dtheta| (rad).
QUANTITIES = ("dx", "dy", "dz", "drx", "dry", "drz", "dp", "dtheta")
#: The architectures :func:`spatial_certified_bounds` certifies.
CERTIFIED_ARCHITECTURES = ("6-UPS", "3-RPS", "3-PRS", "3-UPU", "delta")
#: Relative allowance for the rounding of the final sums.
ROUNDING = 1e-13
_EPS = np.finfo(float).eps
# the 64 vertices of [-1, 1]^6 (one per sign pattern)
_VERTICES = np.array(list(itertools.product((-1.0, 1.0), repeat=6)))


# ------------------------------------------------------------------------------------------------ rotations
def _rot_minus_identity(w: np.ndarray) -> np.ndarray:
    """``Rot(w) - I`` ``(..., 3, 3)`` for rotation vectors ``(..., 3)``, without cancellation for small ``w``."""
    w = np.asarray(w, dtype=float)
    th2 = np.sum(w * w, axis=-1)
    th = np.sqrt(th2)
    small = th2 < 1e-6
    with np.errstate(invalid="ignore", divide="ignore"):
        a = np.where(small, 1 - th2 / 6 + th2 ** 2 / 120 - th2 ** 3 / 5040, np.sin(th) / th)
        b = np.where(small, 0.5 - th2 / 24 + th2 ** 2 / 720 - th2 ** 3 / 40320, 2 * np.sin(0.5 * th) ** 2 / th2)
    K = skew(w)
    return a[..., None, None] * K + b[..., None, None] * (K @ K)


def _left_jacobian(w: np.ndarray) -> np.ndarray:
    """``J_l(w) = I + (1 - cos t)/t^2 K + (t - sin t)/t^3 K^2`` ``(..., 3, 3)``: ``d/de Rot(w + e) =
    [J_l(w) e]x Rot(w)``."""
    th2 = np.sum(w * w, axis=-1)
    th = np.sqrt(th2)
    small = th2 < 1e-6
    with np.errstate(invalid="ignore", divide="ignore"):
        b = np.where(small, 0.5 - th2 / 24 + th2 ** 2 / 720, (1 - np.cos(th)) / th2)
        c = np.where(small, 1 / 6 - th2 / 120 + th2 ** 2 / 5040, (th - np.sin(th)) / (th2 * th))
    K = skew(w)
    return np.eye(3) + b[..., None, None] * K + c[..., None, None] * (K @ K)


def _excess(d: np.ndarray, x: np.ndarray, L: float | np.ndarray) -> np.ndarray:
    """``|L d + x| - L`` ``(...)`` computed as ``d.x + |x_perp|^2 / (|L d + x| + L + d.x)``."""
    dx = np.sum(d * x, axis=-1)
    perp = x - dx[..., None] * d
    full = np.linalg.norm(np.asarray(L)[..., None] * d + x, axis=-1)
    return dx + np.sum(perp * perp, axis=-1) / (full + L + dx)


# -------------------------------------------------------------------------------------------------- sources
@dataclass(frozen=True)
class HexapodSource:
    """One error source of a 6-UPS at a pose: its displacement ``h basis x`` (``|x| <= 1``), base frame.

    Attributes
    ----------
    leg, joint : int
        0-based leg and joint (0 universal, 1 slide, 2 spherical).
    key : str
        The source's key (``radial``, ``axial``, ...).
    part : int or None
        A universal joint's pin (1 or 2) for ``radial`` and ``axial``.
    role : str
        Where it enters Eq. 1: ``t0``, ``t1``, ``t2`` (translations), ``w1`` (slide tilt), ``wd`` (slide
        direction) or ``wbase`` (a rotation at the base joint: no effect).
    half_width : float
        ``h`` (mm or rad).
    basis : ndarray ``(3, k)``
        Orthonormal directions of its segment (k = 1), disc (2) or ball (3).
    """

    leg: int
    joint: int
    key: str
    part: int | None
    role: str
    half_width: float
    basis: np.ndarray = field(repr=False)

    @property
    def label(self) -> str:
        """``legs[i].joints[j].key`` (1-based), with ``[pin k]`` for a universal joint's pins."""
        pin = f"[pin {self.part}]" if self.part else ""
        return f"legs[{self.leg + 1}].joints[{self.joint + 1}].{self.key}{pin}"


def _normals(a: np.ndarray) -> np.ndarray:
    """Two orthonormal vectors normal to the unit ``a``, as columns ``(3, 2)``."""
    helper = np.array([1.0, 0, 0]) if abs(a[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = normalize(np.cross(a, helper))
    return np.stack([e1, np.cross(a, e1)], axis=1)


@dataclass(frozen=True)
class _Geometry:
    """A 6-UPS at a pose: per leg ``A, r, d, L`` ``(6, 3)``/``(6,)``, ``W`` ``(6, 6)``, its sources."""

    A: np.ndarray
    r: np.ndarray
    d: np.ndarray
    L: np.ndarray
    W: np.ndarray
    sources: tuple
    offsets: tuple


def _geometry(robot: SpatialManipulator, sources: SpatialErrorSources, pose: np.ndarray) -> _Geometry:
    p, R = pose[:3], rotations(pose[3:])
    _, _, _, u1s = hexapod_leg_terms(robot, sources)
    A = np.array([leg.base for leg in robot.legs], dtype=float)
    B = np.array([leg.platform_point(p, R) for leg in robot.legs])
    r = B - p
    L = np.linalg.norm(B - A, axis=-1)
    d = (B - A) / L[:, None]
    W = np.concatenate([d, np.cross(r, d)], axis=-1)
    out, offsets, col = [], [], 0
    eye = np.eye(3)
    for i in range(robot.n_legs):
        u1 = u1s[i]
        u2 = normalize(np.cross(d[i], u1))
        n = np.cross(u1, u2)
        nd = _normals(d[i])
        for j, joint in enumerate(sources.legs[i]):
            for key, h in joint.items():
                if j == 0:
                    table = {"radial": [("t0", np.stack([u2, n], 1), 1), ("t0", np.stack([u1, n], 1), 2)],
                             "axial": [("t0", u1[:, None], 1), ("t0", u2[:, None], 2)],
                             "position": [("t0", eye, None)], "length": [("t0", d[i][:, None], None)],
                             "tilt": [("wbase", n[:, None], None)], "direction": [("wbase", np.stack([u2, n], 1), None)]}
                elif j == 1:
                    table = {k: [("t1", d[i][:, None], None)] for k in ("actuator", "backlash", "length")}
                    table.update({"lateral": [("t1", nd, None)], "position": [("t1", eye, None)],
                                  "tilt": [("w1", nd, None)], "direction": [("wd", nd, None)]})
                else:
                    table = {"radial": [("t2", eye, None)], "position": [("t2", eye, None)]}
                for role, basis, part in table[key]:
                    out.append(HexapodSource(i, j, key, part, role, float(h), basis))
                    offsets.append(col)
                    col += basis.shape[1]
    offsets.append(col)
    return _Geometry(A, r, d, L, W, tuple(out), tuple(offsets))


def _displacements(geo: _Geometry, x: np.ndarray) -> dict[str, np.ndarray]:
    """Per role the summed displacement ``(N, 6, 3)`` of the unit variables ``x`` ``(N, m)``."""
    N = x.shape[0]
    out = {role: np.zeros((N, len(geo.L), 3)) for role in ("t0", "t1", "t2", "w1", "wd", "wbase")}
    for k, s in enumerate(geo.sources):
        xs = x[:, geo.offsets[k]:geo.offsets[k + 1]]
        out[s.role][:, s.leg] += s.half_width * xs @ s.basis.T
    return out


def _leg_targets(geo: _Geometry, disp: dict) -> tuple[np.ndarray, np.ndarray]:
    """``|L d + z| - L`` ``(N, 6)`` (the legs' lengths, Eq. 1) and ``t0`` ``(N, 6, 3)``."""
    d = geo.d
    w1 = disp["w1"] + disp["wd"]
    Rw1 = _rot_minus_identity(w1)
    half = 0.5 * geo.L[:, None]
    z = (half * np.einsum("nlij,lj->nli", Rw1, d) + disp["t2"] + np.einsum("nlij,nlj->nli", Rw1, disp["t2"])
         + disp["t1"] + half * np.einsum("nlij,lj->nli", _rot_minus_identity(disp["wd"]), d))
    return _excess(d, z, geo.L), disp["t0"]


def _residual(geo: _Geometry, t: np.ndarray, target: np.ndarray, t0: np.ndarray, jac: bool = True):
    """Eq. 1's residuals ``(N, 6)`` and (``jac``) their Jacobian ``(N, 6, 6)`` in the twist ``t`` ``(N, 6)``."""
    v, w = t[:, :3], t[:, 3:]
    Rm = _rot_minus_identity(w)                                   # (N, 3, 3)
    rr = np.einsum("nij,lj->nli", Rm, geo.r)                      # (Rot(w) - I) r  (N, 6, 3)
    u = v[:, None, :] + rr - t0
    F = _excess(geo.d, u, geo.L[None, :]) - target
    if not jac:
        return F, None
    x = geo.L[:, None] * geo.d + u
    nvec = x / np.linalg.norm(x, axis=-1, keepdims=True)
    rot_r = geo.r[None] + rr                                      # Rot(w) r
    Jl = _left_jacobian(w)
    # d/dw of Rot(w) r = -[Rot(w) r]x J_l(w)
    dw = -np.einsum("nlij,njk->nlik", skew(rot_r), Jl)
    J = np.concatenate([nvec, np.einsum("nli,nlik->nlk", nvec, dw)], axis=-1)
    return F, J


def _solve(geo: _Geometry, x: np.ndarray, iterations: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """Newton's method on Eq. 1 from the nominal pose for unit variables ``x`` ``(N, m)``: the error twists
    ``(N, 6)`` and whether each converged (residual below ``1e-13`` mm times the legs' scale)."""
    target, t0 = _leg_targets(geo, _displacements(geo, x))
    t = np.zeros((x.shape[0], 6))
    tol = 1e-15 * max(1.0, float(np.max(geo.L)))
    for _ in range(iterations):
        F, J = _residual(geo, t, target, t0)
        if np.all(np.abs(F) <= tol):
            break
        try:
            step = np.linalg.solve(J, F[..., None])[..., 0]
        except np.linalg.LinAlgError:
            step = np.full_like(t, np.nan)
        t = t - step
    F, _ = _residual(geo, t, target, t0, jac=False)
    ok = np.all(np.abs(F) <= 100 * tol, axis=-1) & np.all(np.isfinite(t), axis=-1)
    return np.where(ok[:, None], t, np.nan), ok


def _quantities(t: np.ndarray) -> np.ndarray:
    """``(N, 8)``: the twist's six components, ``|dp|`` and ``|dtheta|``."""
    return np.concatenate([t, np.linalg.norm(t[:, :3], axis=-1, keepdims=True),
                           np.linalg.norm(t[:, 3:], axis=-1, keepdims=True)], axis=-1)


def _check(robot: SpatialManipulator, sources, pose, allowed=("6-UPS",)) -> tuple[SpatialErrorSources, np.ndarray]:
    if robot.architecture not in allowed:
        names = " and ".join(allowed) if len(allowed) == 1 else ", ".join(allowed[:-1]) + " and " + allowed[-1]
        raise UnsupportedArchitectureError(
            f"this exact nonlinear model is available for the {names} only ({robot.name} is a "
            f"{robot.architecture})", key="architecture")
    sources = SpatialErrorSources.load(sources, robot)
    pose = as_spatial_poses(pose)
    if pose.shape != (6,):
        raise PoseError(f"one pose (6,) at a time, got shape {pose.shape}")
    return sources, pose


def hexapod_error_twists(robot: SpatialManipulator, sources, pose, displacements) -> np.ndarray:
    """The exact error twists ``[dp, dtheta]`` ``(N, 6)`` (mm, rotation vector rad: the displaced pose is ``p + dp``,
    ``Rot(dtheta) R``) of a 6-UPS at ``pose`` ``(6,)`` (rotation vector, rad) for configurations of its sources.

    ``displacements``: a list of ``N`` dicts ``{label: vector (3,)}`` (or one dict ``{label: (N, 3)}``), each
    source's displacement (mm for translations, a rotation vector in rad for rotations; base frame; labels of
    :class:`HexapodSource`; a missing label is 0). Each vector is projected on its source's directions (it must lie in its set: segment,
    disc or ball of its half-width). Eq. 1 of the module text, solved by Newton's method; NaN where it does
    not converge.
    """
    check_angle_values(rotation_angles(pose), "pose[3:] (rotation vector)")
    sources, pose = _check(robot, sources, pose)
    spatial_pose_errors(robot, sources, pose)      # reachability, joint limits, singularity: raise as it does
    geo = _geometry(robot, sources, pose)
    return _solve(geo, _variables(geo, displacements))[0]


def _variables(geo: _Geometry, displacements) -> np.ndarray:
    """The unit variables ``(N, m)`` of a list of ``N`` dicts ``{label: (3,)}`` or one dict ``{label: (N, 3)}``."""
    if isinstance(displacements, dict):
        arrays = {k: np.atleast_2d(np.asarray(v, dtype=float)) for k, v in displacements.items()}
        n = max((a.shape[0] for a in arrays.values()), default=0)
    else:
        n = len(displacements)
        arrays = {label: None for conf in displacements for label in conf}
        for s in geo.sources:
            if any(s.label in conf for conf in displacements):
                arrays[s.label] = np.array([np.asarray(conf.get(s.label, np.zeros(3)), float) for conf in displacements])
    unknown = set(arrays) - {s.label for s in geo.sources}
    if unknown:
        raise ConfigError(f"no such source (with a non-zero half-width): {sorted(unknown)[0]}", key="displacements")
    x = np.zeros((n, geo.offsets[-1]))
    for k, s in enumerate(geo.sources):
        if s.label in arrays:
            vec = arrays[s.label]
            xs = vec @ s.basis / s.half_width
            off = np.linalg.norm(vec - s.half_width * xs @ s.basis.T, axis=-1)
            if np.any(np.linalg.norm(xs, axis=-1) > 1 + 1e-9) or np.any(off > 1e-9 * s.half_width):
                raise ConfigError(f"a displacement outside its {('segment', 'disc', 'ball')[s.basis.shape[1] - 1]} "
                                  f"of half-width {s.half_width:g}", key=f"displacements: {s.label}")
            x[:, geo.offsets[k]:geo.offsets[k + 1]] = xs
    return x


def _configuration(geo: _Geometry, x: np.ndarray) -> dict[str, np.ndarray]:
    return {s.label: s.half_width * s.basis @ x[geo.offsets[k]:geo.offsets[k + 1]]
            for k, s in enumerate(geo.sources)}


# ----------------------------------------------------------------------------------------------- the result
@dataclass(frozen=True)
class SpatialCertifiedBounds:
    """Certified bounds of the exact nonlinear worst case of a spatial robot at a pose (module text).

    Attributes
    ----------
    pose : ndarray ``(6,)``
        The pose (mm, rotation vector rad).
    first_order : ndarray ``(8,)``
        The first-order maxima of ``|dx|, |dy|, |dz|`` (mm), ``|drx|, |dry|, |drz|`` (rad), ``|dp|`` (mm),
        ``|dtheta|`` (rad) (:data:`QUANTITIES`).
    lower : ndarray ``(8,)``
        Values the exact model attains at :attr:`configurations`.
    upper : ndarray ``(8,)``
        Proven upper bounds of the exact model's maxima over the whole error set (``inf`` if not certified).
    certified : bool
        Whether the upper bounds are proven.
    reason : str
        Why not (empty when certified).
    configurations : list of dict
        Per quantity, each source's displacement ``{label: (3,)}`` (mm or rad, base frame) attaining ``lower``.
    twists : ndarray ``(8, 6)``
        The exact error twists at those configurations.
    box : dict
        The proven bounds of the solution set: ``Rv`` (mm), ``Rw`` (rad), and the contraction's spectral radius.
    """

    pose: np.ndarray
    first_order: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    certified: bool
    reason: str
    configurations: list = field(repr=False)
    twists: np.ndarray = field(repr=False)
    box: dict = field(default_factory=dict)

    @property
    def gap(self) -> np.ndarray:
        """``(upper - lower) / lower`` ``(8,)`` (``inf`` if not certified)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.lower > 0, (self.upper - self.lower) / self.lower, np.where(
                self.upper > 0, np.inf, 0.0))

    @property
    def remainder(self) -> np.ndarray:
        """``upper - first_order`` ``(8,)``: the proven bound of the nonlinear remainder."""
        return self.upper - self.first_order

    def records(self) -> list[dict]:
        """One dict per quantity: ``quantity, first_order, lower, upper, gap_pct, certified`` (rotations in
        deg, their names ending in ``_deg``)."""
        out = []
        for k, name in enumerate(QUANTITIES):
            f = 1.0 if k in (0, 1, 2, 6) else 180.0 / np.pi
            out.append({"quantity": name + ("" if f == 1.0 else "_deg"), "first_order": float(self.first_order[k] * f),
                        "lower": float(self.lower[k] * f), "upper": float(self.upper[k] * f),
                        "gap_pct": float(100 * self.gap[k]), "certified": bool(self.certified)})
        return out


# ----------------------------------------------------------------------------------------------- the bound
def _leg_sums(geo: _Geometry) -> dict[str, np.ndarray]:
    """Per leg ``(6,)``: ``rho`` and the sums of half-widths of Eq. 3 (module text)."""
    n = len(geo.L)
    keys = ("rho", "T0", "T0p", "T1", "T1p", "T2", "O1", "Od")
    out = {k: np.zeros(n) for k in keys}
    for s in geo.sources:
        i, h = s.leg, s.half_width
        d = geo.d[s.leg]
        if s.role in ("t0", "t1", "t2"):
            out["rho"][i] += h * np.linalg.norm(s.basis.T @ d)
            perp = s.basis - np.outer(d, d @ s.basis)
            hp = h * np.linalg.norm(perp, ord=2)
            if s.role == "t0":
                out["T0"][i] += h
                out["T0p"][i] += hp
            elif s.role == "t1":
                out["T1"][i] += h
                out["T1p"][i] += hp
            else:
                out["T2"][i] += h
        elif s.role in ("w1", "wd"):
            out["O1"][i] += h
            if s.role == "wd":
                out["Od"][i] += h
    return out


def _inverse_enclosure(W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``C`` (the computed ``W^-1``) and ``c`` ``(6,)`` with ``|W^-1 - C|_kj <= c_k`` (module text, rounding)."""
    C = np.linalg.inv(W)
    # W C = I - E, so W^-1 = C (I - E)^-1 = C + C N with every entry of N at most eta / (1 - eta)
    E = np.abs(np.eye(6) - W @ C) + 7 * _EPS * np.abs(W) @ np.abs(C)
    eta = float(np.max(np.sum(E, axis=-1)))
    if not eta < 0.5:
        return C, np.full(6, np.inf)
    return C, eta / (1 - eta) * np.sum(np.abs(C), axis=-1) * (1 + 1e-12)


def _functionals(geo: _Geometry) -> list[np.ndarray]:
    """The linear maps of the box ``B`` ``(k, 6)``: ``v``, ``w``, per leg ``P_i [I, -[r_i]x]`` and
    ``[I, -[r_i]x]``."""
    out = [np.eye(6)[:3], np.eye(6)[3:]]
    for i in range(len(geo.L)):
        Mi = np.concatenate([np.eye(3), -skew(geo.r[i])], axis=1)
        P = np.eye(3) - np.outer(geo.d[i], geo.d[i])
        out.append(P @ Mi)
    for i in range(len(geo.L)):
        out.append(np.concatenate([np.eye(3), -skew(geo.r[i])], axis=1))
    return out


def _image(maps, C, c, lo, hi) -> np.ndarray:
    """For each map ``Phi`` the largest ``|Phi W^-1 x|`` over the box ``lo <= x <= hi`` (vertices, plus the
    enclosure of ``W^-1``)."""
    X = 0.5 * (lo + hi) + 0.5 * (hi - lo) * _VERTICES          # (64, 6)
    Y = X @ C.T                                                  # (64, 6): C x
    l1 = float(np.max(np.sum(np.abs(X), axis=-1)))
    out = []
    for Phi in maps:
        vals = np.linalg.norm(Y @ Phi.T, axis=-1)
        corr = np.linalg.norm(np.abs(Phi) @ c) * l1
        out.append(float(np.max(vals)) + corr)
    return np.array(out)


def _q_bounds(geo: _Geometry, sums: dict, box: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``q_lo, q_hi`` ``(6,)`` of Eq. 3 for the box ``(Rv, Rw, Yp_1..6, Y_1..6)``, and ``U``, ``Up``."""
    n = len(geo.L)
    L, rn = geo.L, np.linalg.norm(geo.r, axis=-1)
    Rw = box[1]
    eps = Rw * Rw * rn / 2                                   # |eps| (the point's own displacement)
    dr = np.abs(np.sum(geo.d * geo.r, axis=-1))
    deps = Rw * Rw * (rn + dr) / 4 + Rw ** 3 * rn / 6        # |d . eps|
    Up = box[2:2 + n] + eps + sums["T0p"]
    U = box[2 + n:2 + 2 * n] + eps + sums["T0"]
    O1, Od, T1, T1p, T2 = sums["O1"], sums["Od"], sums["T1"], sums["T1p"], sums["T2"]
    Z = L * np.sin(O1 / 2) + T2 + T1 + L * np.sin(Od / 2)
    Zp = L * np.sin(O1 / 2) + T2 + T1p + L * np.sin(Od / 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        uterm = np.where(U < L, Up ** 2 / (2 * (L - U)), np.inf)
        zterm = np.where(Z < L, Zp ** 2 / (2 * (L - Z)), np.inf)
    cross = 2 * np.sin(O1 / 2) * T2
    q_lo = -(L / 2) * (2 - np.cos(O1) - np.cos(Od)) - cross - uterm - deps
    q_hi = cross + zterm + deps
    return q_lo, q_hi, U, Up


def _certify(geo: _Geometry, sums: dict):
    """The invariant box and the contraction (module text): ``(q_lo, q_hi, box, radius, reason)``."""
    C, c = _inverse_enclosure(geo.W)
    if not np.all(np.isfinite(c)):
        return None, None, None, np.inf, "W^-1 could not be enclosed (near-singular)"
    maps = _functionals(geo)
    rho = sums["rho"]
    box = _image(maps, C, c, -rho, rho)
    reason = "the bounds of the solution set do not close (the error set is too large for the distance to a " \
             "singularity, or a leg's displacement reaches its length)"
    if np.any(sums["O1"] > 0.5):
        return None, None, None, np.inf, "a slide's tilt and direction turns exceed 0.5 rad"
    for _ in range(200):
        q_lo, q_hi, _, _ = _q_bounds(geo, sums, box)
        if not (np.all(np.isfinite(q_lo)) and np.all(np.isfinite(q_hi))) or box[1] > 1.0:
            return None, None, None, np.inf, reason
        new = _image(maps, C, c, -rho + q_lo, rho + q_hi)
        if np.all(new <= box * (1 + 1e-14)):
            break
        box = np.maximum(box, new)
    for inflate in (1e-9, 1e-6, 1e-3, 1e-1):
        trial = box * (1 + inflate) + 1e-300
        q_lo, q_hi, U, _ = _q_bounds(geo, sums, trial)
        if np.all(np.isfinite(q_lo)) and np.all(np.isfinite(q_hi)) and trial[1] <= 1.0:
            new = _image(maps, C, c, -rho + q_lo, rho + q_hi)
            if np.all(new <= trial):
                break
    else:
        return None, None, None, np.inf, reason
    # uniqueness: the contraction of t -> t - W^-1 (G(t) - target) over the box
    Rw, L, rn = trial[1], geo.L, np.linalg.norm(geo.r, axis=-1)
    _, _, U, Up = _q_bounds(geo, sums, trial)
    alpha = Up / (L - U)                                        # |n - d| <= |u_perp| / (L - |u|)
    beta = rn * (1.5 * Rw + Rw * Rw / 6 + alpha)
    absinv = np.abs(C) + c[:, None]
    cv = np.linalg.norm(absinv[:3], axis=0)
    cw = np.linalg.norm(absinv[3:], axis=0)
    lam = np.array([[cv @ alpha, cv @ beta], [cw @ alpha, cw @ beta]])
    tr, det = lam[0, 0] + lam[1, 1], lam[0, 0] * lam[1, 1] - lam[0, 1] * lam[1, 0]
    radius = 0.5 * (tr + np.sqrt(max(tr * tr - 4 * det, 0.0)))
    if not radius < 1:
        return None, None, None, radius, f"the closure is not proven a contraction over the box (radius {radius:.3g})"
    return q_lo, q_hi, trial, radius, ""


def _upper(geo: _Geometry, sums: dict, q_lo, q_hi) -> np.ndarray:
    """The largest of each quantity over ``W^-1 X`` (module text) ``(8,)``."""
    C, c = _inverse_enclosure(geo.W)
    rho = sums["rho"]
    lo, hi = -rho + q_lo, rho + q_hi
    X = 0.5 * (lo + hi) + 0.5 * (hi - lo) * _VERTICES
    l1 = float(np.max(np.sum(np.abs(X), axis=-1)))
    Y = X @ C.T
    comp = np.max(np.abs(Y), axis=0) + c * l1
    dp = np.max(np.linalg.norm(Y[:, :3], axis=-1)) + np.linalg.norm(c[:3]) * l1
    dth = np.max(np.linalg.norm(Y[:, 3:], axis=-1)) + np.linalg.norm(c[3:]) * l1
    return np.concatenate([comp, [dp, dth]]) * (1 + ROUNDING)


# ----------------------------------------------------------------------------------------------- the lower
def _support_point(geo: _Geometry, g: np.ndarray) -> np.ndarray:
    """The point of the sources' set maximizing ``g . x`` (per source ``g_s / |g_s|``; 0 where ``g_s = 0``)
    for rows of ``g`` ``(N, m)``."""
    x = np.zeros_like(g)
    for k in range(len(geo.sources)):
        a, b = geo.offsets[k], geo.offsets[k + 1]
        nrm = np.linalg.norm(g[:, a:b], axis=-1, keepdims=True)
        x[:, a:b] = np.where(nrm > 0, g[:, a:b] / np.where(nrm > 0, nrm, 1.0), 0.0)
    return x


def _first_order_configs(geo: _Geometry, sums: dict) -> np.ndarray:
    """The first-order worst configurations ``(14, m)``: each component's (+ then -), ``|dp|``'s and
    ``|dtheta|``'s."""
    C = np.linalg.inv(geo.W)
    rho = sums["rho"]
    patterns = []
    for k in range(6):
        sig = np.where(C[k] >= 0, 1.0, -1.0)
        patterns += [sig, -sig]
    for rows in (slice(0, 3), slice(3, 6)):
        vals = np.linalg.norm((_VERTICES * rho) @ C[rows].T, axis=-1)
        patterns.append(_VERTICES[int(np.argmax(vals))])
    patterns = np.array(patterns)                                  # (14, 6) signs per leg
    # each source's first-order effect on its leg's term: g_s = sign_i h_s basis^T d_i (0 for rotations)
    m = geo.offsets[-1]
    g = np.zeros((len(patterns), m))
    for k, s in enumerate(geo.sources):
        a, b = geo.offsets[k], geo.offsets[k + 1]
        if s.role in ("t0", "t1", "t2"):
            g[:, a:b] = patterns[:, s.leg, None] * (s.basis.T @ geo.d[s.leg])[None]
    return _support_point(geo, g)


def _line_search(x, t, f, target, solve, which, sign):
    """One step of the lower bound's ascent: from the configurations ``x`` (exact twists ``t``, objective ``f``)
    toward ``target``, the first of the steps 1, 1/2, 1/4, 1/10, 1/30 whose exact objective (``solve`` of the
    candidate configuration) is larger is kept, per configuration. Returns ``(x, t, f, improved)``."""
    improved = np.zeros(len(x), bool)
    for tau in (1.0, 0.5, 0.25, 0.1, 0.03):
        cand = x + tau * (target - x)
        tc = solve(cand)
        fc = _objective(tc, which, sign)
        better = (fc > f) & ~improved & np.isfinite(fc)
        x = np.where(better[:, None], cand, x)
        t = np.where(better[:, None], tc, t)
        f = np.where(better, fc, f)
        improved |= better
    return x, t, f, improved


def _objective(t: np.ndarray, which: np.ndarray, sign: np.ndarray) -> np.ndarray:
    q = _quantities(t)
    return sign * q[np.arange(len(which)), which]


def _gradient(geo: _Geometry, x: np.ndarray, t: np.ndarray, which: np.ndarray, sign: np.ndarray) -> np.ndarray:
    """The gradient ``(N, m)`` of each row's quantity in the unit variables at the solutions ``t``: implicit
    differentiation of Eq. 1, ``dt/dx = -J^-1 dF/dx`` with ``dF/dx`` by central differences at fixed ``t`` (no
    solve)."""
    N, m = x.shape
    step = 1e-6
    E = np.eye(m) * step
    X = np.concatenate([x[:, None, :] + E, x[:, None, :] - E], axis=1).reshape(-1, m)
    target, t0 = _leg_targets(geo, _displacements(geo, X))
    F, _ = _residual(geo, np.repeat(t, 2 * m, axis=0), target, t0, jac=False)
    F = F.reshape(N, 2, m, -1)
    dF = np.swapaxes((F[:, 0] - F[:, 1]) / (2 * step), 1, 2)          # (N, 6 legs, m)
    _, J = _residual(geo, t, *_leg_targets(geo, _displacements(geo, x)))
    dt = -np.linalg.solve(J, dF)                                       # (N, 6, m)
    q = _quantities(t)
    out = np.empty((N, m))
    for n in range(N):
        k = which[n]
        if k < 6:
            out[n] = sign[n] * dt[n, k]
        else:
            rows = slice(0, 3) if k == 6 else slice(3, 6)
            out[n] = sign[n] * (t[n, rows] / max(q[n, k], 1e-300)) @ dt[n, rows]
    return np.where(np.isfinite(out), out, 0.0)


def _ascent(geo: _Geometry, x: np.ndarray, which: np.ndarray, sign: np.ndarray, steps: int) -> tuple:
    """Conditional-gradient ascent of each row's quantity over the sources' sets (gradients of the exact
    model, :func:`_gradient`); returns ``x``, the twists and the objective values."""
    t, _ = _solve(geo, x)
    f = _objective(t, which, sign)
    m = x.shape[1]
    if steps == 0 or m == 0:
        return x, t, f
    for _ in range(steps):
        grad = _gradient(geo, x, t, which, sign)
        target = _support_point(geo, grad)
        x, t, f, improved = _line_search(x, t, f, target, lambda cand: _solve(geo, cand)[0], which, sign)
        if not np.any(improved):
            break
    return x, t, f


def spatial_certified_bounds(robot: SpatialManipulator, sources, pose, *, ascent_steps: int = 4,
                             allow_outside: bool = False) -> SpatialCertifiedBounds:
    """Certified bounds of the exact nonlinear worst case of a 6-UPS's, 3-RPS's, 3-PRS's, 3-UPU's or Delta's error
    at one pose (module text: Eq. 1 for a 6-UPS, Eq. 4 for the others).

    ``sources``: a :class:`~pmaccuracy.model.spatial_sources.SpatialErrorSources`, a preset name or a TOML path;
    ``pose`` ``(6,)``: ``[x, y, z mm, rotation vector rad]``. Returns a :class:`SpatialCertifiedBounds`: per
    quantity (:data:`QUANTITIES`: ``|dx|, |dy|, |dz|`` mm, ``|drx|, |dry|, |drz|`` rad, ``|dp|`` mm, ``|dtheta|``
    rad) the first-order maximum, a ``lower`` value attained by the exact model (Eq. 1) at a returned
    configuration of the sources (the first-order worst one improved by ``ascent_steps`` conditional-gradient
    steps), and an ``upper`` value proven never below the exact model's maximum over the whole error set
    (first-order maximum plus the proven remainder: Eq. 3 and the theorem, Eq. 5). Where the proof fails
    ``upper`` is ``inf``, ``certified`` False and ``reason`` says why.

    Raises :class:`~pmaccuracy.errors.UnsupportedArchitectureError` for a chain robot,
    :class:`~pmaccuracy.errors.PoseError` for a lower-mobility robot's pose that its legs forbid,
    :class:`~pmaccuracy.errors.OutsideJointLimitsError` and :class:`~pmaccuracy.errors.SingularPoseError` as
    :func:`~pmaccuracy.accuracy.spatial_bounds.spatial_pose_errors` does.
    """
    check_angle_values(rotation_angles(pose), "pose[3:] (rotation vector)")
    sources, pose = _check(robot, sources, pose, CERTIFIED_ARCHITECTURES)
    spatial_pose_errors(robot, sources, pose, allow_outside=allow_outside, details=False)   # raises as it does
    if robot.architecture != "6-UPS":
        return _chain_certified_bounds(robot, sources, pose, ascent_steps)
    geo = _geometry(robot, sources, pose)
    sums = _leg_sums(geo)
    m = geo.offsets[-1]
    if m == 0 or not np.any(sums["rho"] > 0) and not np.any(sums["O1"] + sums["T1p"] + sums["T0p"] > 0):
        zero = np.zeros(8)
        return SpatialCertifiedBounds(pose, zero, zero, zero, True, "", [{} for _ in QUANTITIES], np.zeros((8, 6)))
    C = np.linalg.inv(geo.W)
    rho = sums["rho"]
    Y = (_VERTICES * rho) @ C.T
    first = np.concatenate([np.abs(C) @ rho, [np.max(np.linalg.norm(Y[:, :3], axis=-1)),
                                               np.max(np.linalg.norm(Y[:, 3:], axis=-1))]])
    # lower: the exact model at the first-order worst configurations, improved
    x0 = _first_order_configs(geo, sums)
    which = np.array([k for k in range(6) for _ in (0, 1)] + [6, 7])
    sign = np.array([1.0, -1.0] * 6 + [1.0, 1.0])
    x, t, f = _ascent(geo, x0, which, sign, ascent_steps)
    lower, configs, twists = np.zeros(8), [], np.zeros((8, 6))
    for k in range(8):
        rows = np.flatnonzero(which == k)
        best = rows[int(np.argmax(np.where(np.isfinite(f[rows]), f[rows], -np.inf)))]
        lower[k] = f[best]
        twists[k] = t[best]
        configs.append(_configuration(geo, x[best]))
    q_lo, q_hi, box, radius, reason = _certify(geo, sums)
    if reason:
        upper = np.full(8, np.inf)
        info = {"contraction": float(radius)}
    else:
        upper = _upper(geo, sums, q_lo, q_hi)
        info = {"Rv": float(box[0]), "Rw": float(box[1]), "contraction": float(radius)}
    return SpatialCertifiedBounds(pose=pose, first_order=first, lower=lower, upper=upper, certified=not reason,
                                  reason=reason, configurations=configs, twists=twists, box=info)


# =========================================================================================================
# The other architectures: legs as serial chains (3-RPS, 3-PRS, 3-UPU, Delta; module text, second part)
# =========================================================================================================
@dataclass(frozen=True)
class ChainSource:
    """One error source of a chain robot at a pose: its displacement ``h basis x`` (``|x| <= 1``), base frame.

    Attributes
    ----------
    leg, joint : int
        0-based leg and joint.
    key : str
        The source's key.
    part : int or None
        A universal joint's pin (1 or 2) for ``radial`` and ``axial``.
    role : str
        ``t`` (a translation), ``r`` (a rotation about the joint's centre) or ``o`` (a rotation about the slide's
        origin: a prismatic joint's ``direction``).
    half_width : float
        ``h`` (mm or rad).
    basis : ndarray ``(3, k)``
        Orthonormal directions of its segment (k = 1), disc (2) or ball (3).
    origin : ndarray ``(3,)``
        The centre of an ``o`` rotation relative to the platform centre ``p`` (mm; unused otherwise).
    """

    leg: int
    joint: int
    key: str
    part: int | None
    role: str
    half_width: float
    basis: np.ndarray = field(repr=False)
    origin: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(3))

    @property
    def label(self) -> str:
        """``legs[i].joints[j].key`` (1-based), with ``[pin k]`` for a universal joint's pins."""
        pin = f"[pin {self.part}]" if self.part else ""
        return f"legs[{self.leg + 1}].joints[{self.joint + 1}].{self.key}{pin}"


@dataclass(frozen=True)
class _ChainGeometry:
    """A chain robot at a pose, every position relative to the platform centre ``p`` (mm).

    ``centres[i][j]`` the joint centres; ``passive[i][j]`` the bases ``(3, k)`` of the joint's passive rotations
    about its centre, in order (a universal joint: two, ``u1`` then ``u2``; a revolute one; a spherical joint
    one ``(3, 3)`` (a Delta's elbow ball ``(3, 2)``, its rod's spin left out); ``()`` for the actuated joint);
    ``chains`` ``(leg, joints)`` from the base to the platform; ``groups`` the unknowns after ``dp, w``: ``(leg,
    joint, factor, offset, k)``; ``sources`` and their column ``offsets``."""

    centres: list
    passive: list
    chains: list
    groups: list
    n: int
    sources: tuple
    offsets: tuple
    scale: float
    origins: list
    group_offset: dict


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _joint_table(kind: str, key: str, axes: dict) -> list:
    """``(role, basis, part)`` of one key of one joint (the conventions of ``docs/guide/spatial-errors.md`` and of
    :mod:`pmaccuracy.accuracy.spatial_bounds`)."""
    eye = np.eye(3)
    if key == "position":
        return [("t", eye, None)]
    if key == "length":
        return [("t", axes["ldir"][:, None], None)]
    if kind == "S":
        return [("t", eye, None)]
    if kind == "R":
        a = axes["axis"]
        nn = _normals(a)
        return {"radial": [("t", nn, None)], "axial": [("t", a[:, None], None)], "tilt": [("r", nn, None)],
                "direction": [("r", nn, None)], "actuator": [("r", a[:, None], None)],
                "backlash": [("r", a[:, None], None)]}[key]
    if kind == "U":
        u1, u2, n = axes["u1"], axes["u2"], axes["n"]
        return {"radial": [("t", np.stack([u2, n], 1), 1), ("t", np.stack([u1, n], 1), 2)],
                "axial": [("t", u1[:, None], 1), ("t", u2[:, None], 2)], "tilt": [("r", n[:, None], None)],
                "direction": [("r", np.stack([u2, n], 1), None)]}[key]
    s = axes["slide"]
    nn = _normals(s)
    return {"actuator": [("t", s[:, None], None)], "backlash": [("t", s[:, None], None)],
            "lateral": [("t", nn, None)], "tilt": [("r", nn, None)], "direction": [("o", nn, None)]}[key]


def _chain_geometry(robot: SpatialManipulator, sources: SpatialErrorSources, pose: np.ndarray) -> _ChainGeometry:
    """The joints, passive motions and sources of a 3-RPS, 3-PRS, 3-UPU or Delta at ``pose`` (module text)."""
    arch = robot.architecture
    p, R = pose[:3], rotations(pose[3:])
    q = np.asarray(inverse_kinematics(robot, pose).q, dtype=float)
    centres, passive, axes_all, chains = [], [], [], []
    scale = 1.0
    for i, leg in enumerate(robot.legs):
        A = np.asarray(leg.base, dtype=float)
        B = np.asarray(leg.platform_point(p, R), dtype=float)
        scale = max(scale, float(np.linalg.norm(B - A)), float(np.linalg.norm(A - p)))
        if arch in ("3-RPS", "3-UPU"):
            d = _unit(B - A)
            M = 0.5 * (A + B)
            pri = {"slide": d, "ldir": d, "origin": A - p}
            if arch == "3-RPS":
                a = np.asarray(leg.axis, dtype=float)
                if abs(a @ (B - A)) > 1e-7 * max(1.0, np.linalg.norm(B - A)):
                    raise PoseError("the pose violates the 3-RPS legs' constraints (complete it from its controlled "
                                    "coordinates first)")
                axes = [{"axis": a, "ldir": d}, pri, {}]
                pas = [(a[:, None],), (), (np.eye(3),)]
            else:
                if np.linalg.norm(pose[3:]) > 1e-9:
                    raise PoseError("a 3-UPU moves in pure translation: the pose's rotation must be zero")
                u1 = np.asarray(leg.base_axis, dtype=float)
                u2 = _unit(np.cross(d, u1))
                v = R @ np.asarray(leg.platform_axis, dtype=float)
                axes = [{"u1": u1, "u2": u2, "n": np.cross(u1, u2), "ldir": d}, pri,
                        {"u1": u2, "u2": v, "n": _unit(np.cross(u2, v))}]
                pas = [(u1[:, None], u2[:, None]), (), (u2[:, None], v[:, None])]
            centres.append([A - p, M - p, B - p])
            chains.append((i, [0, 1, 2]))
        elif arch == "3-PRS":
            s = np.asarray(leg.slide, dtype=float)
            a = np.asarray(leg.axis, dtype=float)
            C = np.asarray(leg.carriage(q[i]), dtype=float)
            if abs(a @ (B - A)) > 1e-7 * max(1.0, np.linalg.norm(B - A)):
                raise PoseError("the pose violates the 3-PRS legs' constraints (complete it from its controlled "
                                "coordinates first)")
            axes = [{"slide": s, "ldir": s, "origin": A - p}, {"axis": a, "ldir": _unit(B - C)}, {}]
            pas = [(), (a[:, None],), (np.eye(3),)]
            centres.append([C - p, C - p, B - p])
            chains.append((i, [0, 1, 2]))
        else:   # delta
            if np.linalg.norm(pose[3:]) > 1e-9:
                raise PoseError("a Delta moves in pure translation: the pose's rotation must be zero")
            a = np.asarray(leg.axis, dtype=float)
            C = np.asarray(leg.elbow(q[i]), dtype=float)
            half, halfp = 0.5 * leg.spacing * a, 0.5 * leg.spacing * (R @ a)
            axes, pas, cen = [{"axis": a, "ldir": _unit(C - A)}], [()], [A - p]
            for sg in (1.0, -1.0):
                Ce, Bp = C + sg * half, B + sg * halfp
                rod = _unit(Bp - Ce)
                axes += [{"ldir": rod}, {}]
                pas += [(_normals(rod),), (np.eye(3),)]
                cen += [Ce - p, Bp - p]
            centres.append(cen)
            chains += [(i, [0, 1, 2]), (i, [0, 3, 4])]
        passive.append(pas)
        axes_all.append(axes)
    groups, off = [], 6
    for i, pas in enumerate(passive):
        for j, factors in enumerate(pas):
            for f, basis in enumerate(factors):
                groups.append((i, j, f, off, basis.shape[1]))
                off += basis.shape[1]
    kinds = JOINTS[arch]
    out, offsets, col = [], [], 0
    for i in range(robot.n_legs):
        for j, joint in enumerate(sources.legs[i]):
            for key, h in joint.items():
                kind = kinds[j]
                for role, basis, part in _joint_table(kind, key, axes_all[i][j]):
                    origin = axes_all[i][j].get("origin", np.zeros(3)) if role == "o" else np.zeros(3)
                    out.append(ChainSource(i, j, key, part, role, float(h), basis, origin))
                    offsets.append(col)
                    col += basis.shape[1]
    offsets.append(col)
    origins = [centres[i][joints[-1]] for i, joints in chains]          # each chain's platform joint centre
    group_offset = {(li, lj, lf): o for (li, lj, lf, o, _) in groups}
    return _ChainGeometry(centres, passive, chains, groups, off, tuple(out), tuple(offsets), scale, origins,
                          group_offset)


# ----------------------------------------------------------------------------------------- the exact closure
def _about(w: np.ndarray, c: np.ndarray, t: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``x -> c + Rot(w) (x - c) + t`` stored as ``(Rot(w) - I, translation)`` ``((N, 3, 3), (N, 3))``."""
    Am = _rot_minus_identity(w)
    tt = -Am @ c
    return Am, tt if t is None else tt + t


def _compose(g1, g2):
    """``g1 o g2`` for transforms stored as ``(R - I, t)`` (arithmetic on the small displacements)."""
    A1, t1 = g1
    A2, t2 = g2
    return A1 + A2 + A1 @ A2, t1 + t2 + np.einsum("nij,nj->ni", A1, t2)


def _vee_skew(Am: np.ndarray) -> np.ndarray:
    return 0.5 * np.stack([Am[:, 2, 1] - Am[:, 1, 2], Am[:, 0, 2] - Am[:, 2, 0], Am[:, 1, 0] - Am[:, 0, 1]], -1)


def _joint_displacements(geo: _ChainGeometry, x: np.ndarray) -> list:
    """Per leg, per joint: ``E_j`` (module text) for the unit variables ``x`` ``(N, m)``."""
    N = x.shape[0]
    rot = [[np.zeros((N, 3)) for _ in c] for c in geo.centres]
    tra = [[np.zeros((N, 3)) for _ in c] for c in geo.centres]
    for k, s in enumerate(geo.sources):
        v = s.half_width * x[:, geo.offsets[k]:geo.offsets[k + 1]] @ s.basis.T
        if s.role == "t":
            tra[s.leg][s.joint] = tra[s.leg][s.joint] + v
        else:
            rot[s.leg][s.joint] = rot[s.leg][s.joint] + v
            if s.role == "o":
                c = geo.centres[s.leg][s.joint]
                tra[s.leg][s.joint] = tra[s.leg][s.joint] + _rot_minus_identity(v) @ (c - s.origin)
    return [[_about(rot[i][j], c, tra[i][j]) for j, c in enumerate(cs)] for i, cs in enumerate(geo.centres)]


def _chain_residual(geo: _ChainGeometry, y: np.ndarray, E: list) -> np.ndarray:
    """``F = Phi_o(D_chain) - Phi_o(Delta)`` ``(N, 6 n_chains)`` for the unknowns ``y`` ``(N, n)`` (``dp, w``, the
    passive joints' rotations): per chain the displacement of its origin ``o`` (mm), then the vee of the
    rotation's skew part (module text)."""
    N = y.shape[0]
    dp, w = y[:, :3], y[:, 3:6]
    Aw = _rot_minus_identity(w)
    T = []
    for i, cs in enumerate(geo.centres):
        row = []
        for j, c in enumerate(cs):
            g = E[i][j]
            for f, basis in enumerate(geo.passive[i][j]):
                off = geo.group_offset[(i, j, f)]
                g = _compose(g, _about(y[:, off:off + basis.shape[1]] @ basis.T, c))
            row.append(g)
        T.append(row)
    out = []
    for r, (i, joints) in enumerate(geo.chains):
        D = (np.zeros((N, 3, 3)), np.zeros((N, 3)))
        for j in joints:
            D = _compose(D, T[i][j])
        o = geo.origins[r]
        out += [D[1] + D[0] @ o - dp - Aw @ o, _vee_skew(D[0]) - _vee_skew(Aw)]
    return np.concatenate(out, axis=-1)


def _chain_linear(geo: _ChainGeometry) -> tuple[np.ndarray, np.ndarray]:
    """The closure's derivatives at the nominal configuration: ``A = dF/dy`` ``(6 n_c, n)`` and ``B = dF/dx``
    ``(6 n_c, m)`` (unit variables: the half-widths included). Every factor is written in the base frame at the
    nominal configuration, so the derivative of the product is the sum of the factors' twists ``(v, w)``: a
    translation ``(e, 0)``, a rotation about ``c`` ``(c x e, e)``."""
    nc = len(geo.chains)
    A = np.zeros((6 * nc, geo.n))
    B = np.zeros((6 * nc, geo.offsets[-1]))
    for r, (i, joints) in enumerate(geo.chains):
        A[6 * r:6 * r + 3, :3] = -np.eye(3)             # Delta: dp + w x (o - p), w
        A[6 * r + 3:6 * r + 6, 3:6] = -np.eye(3)
        for (li, lj, lf, off, k) in geo.groups:
            if li == i and lj in joints:
                basis = geo.passive[li][lj][lf]
                c = geo.centres[li][lj]
                A[6 * r:6 * r + 3, off:off + k] = np.cross(c, basis.T).T
                A[6 * r + 3:6 * r + 6, off:off + k] = basis
        for k, s in enumerate(geo.sources):
            if s.leg != i or s.joint not in joints:
                continue
            a, b = geo.offsets[k], geo.offsets[k + 1]
            if s.role == "t":
                B[6 * r:6 * r + 3, a:b] = s.half_width * s.basis
            else:
                c = s.origin if s.role == "o" else geo.centres[s.leg][s.joint]
                B[6 * r:6 * r + 3, a:b] = s.half_width * np.cross(c, s.basis.T).T
                B[6 * r + 3:6 * r + 6, a:b] = s.half_width * s.basis
        # at the chain's origin o: a twist's translation part v + w x o
        Ko = -skew(geo.origins[r])
        A[6 * r:6 * r + 3] += Ko @ A[6 * r + 3:6 * r + 6]
        B[6 * r:6 * r + 3] += Ko @ B[6 * r + 3:6 * r + 6]
    return A, B


def _chain_solve(geo: _ChainGeometry, C: np.ndarray, x: np.ndarray, iterations: int = 60
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The exact closure solved from the nominal configuration by the chord iteration ``y <- y - C F(y)`` (``C``
    the nominal ``A^-1``; the map the certificate proves a contraction): the error twists ``(N, 6)`` (NaN where
    it does not converge) and whether each converged."""
    E = _joint_displacements(geo, x)
    y = np.zeros((x.shape[0], geo.n))
    tol = np.tile(np.r_[np.full(3, 1e-15 * geo.scale), np.full(3, 1e-15)], len(geo.chains))
    for _ in range(iterations):
        F = _chain_residual(geo, y, E)
        if np.all(np.abs(F) <= tol):
            break
        y = y - F @ C.T
    F = _chain_residual(geo, y, E)
    ok = np.all(np.abs(F) <= 100 * tol, axis=-1) & np.all(np.isfinite(y), axis=-1)
    return np.where(ok[:, None], y[:, :6], np.nan), ok


# ------------------------------------------------------------------------------------ the chain certificate
def _beta(phi):
    """``|d/de Rot(phi) - [e]x|`` over unit ``e`` and ``|phi| <= phi``: ``1.5 phi + phi^2 / 6`` (module text)."""
    return 1.5 * phi + phi * phi / 6


def _chain_factors(geo: _ChainGeometry) -> list:
    """Per chain ``(factors, |o - p|)``, its factors in order: per joint its sources' displacement ``("src",
    (Omega, T, [(h, |c - O|)]), |c - o|)`` and its passive rotations ``("pas", group, |c - o|)``."""
    out = []
    gidx = {(li, lj, lf): g for g, (li, lj, lf, _, _) in enumerate(geo.groups)}
    for r, (i, joints) in enumerate(geo.chains):
        o = geo.origins[r]
        fs = []
        for j in joints:
            c = geo.centres[i][j]
            om, tr, ro = 0.0, 0.0, []
            for s in geo.sources:
                if s.leg == i and s.joint == j:
                    if s.role == "t":
                        tr += s.half_width
                    else:
                        om += s.half_width
                        if s.role == "o":
                            ro.append((s.half_width, float(np.linalg.norm(c - s.origin))))
            if om > 0 or tr > 0:
                fs.append(("src", (om, tr, ro), float(np.linalg.norm(c - o))))
            for f in range(len(geo.passive[i][j])):
                fs.append(("pas", gidx[(i, j, f)], float(np.linalg.norm(c - o))))
        out.append((fs, float(np.linalg.norm(o))))
    return out


def _chain_bounds(factors: list, box: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """For the box of the unknowns (``box[0] = |dp|``, ``box[1] = |w|``, ``box[2 + g]`` the passive groups' norms):
    per chain the bounds ``rho_t, rho_r`` of the remainder's translation and rotation parts and ``k_t, k_r``
    ``(n_chains, 2 + n_groups)`` of its derivative in each group (module text)."""
    nc = len(factors)
    rho_t, rho_r = np.zeros(nc), np.zeros(nc)
    kt, kr = np.zeros((nc, len(box))), np.zeros((nc, len(box)))
    Rw = box[1]
    for r, (fs, op) in enumerate(factors):
        th, tau, dt, dr = [], [], [], []
        for kind, data, c in fs:
            if kind == "pas":
                a = box[2 + data]
                th.append(a), tau.append(a * c), dt.append(a * a * c / 2), dr.append(a ** 3 / 6)
            else:
                om, tr, ro = data
                th.append(om)
                tau.append(tr + om * c + sum(h * e for h, e in ro))
                dt.append(om * om * c / 2 + sum(h * h * e / 2 for h, e in ro))
                dr.append(om ** 3 / 6)
        th, tau = np.array(th), np.array(tau)
        after_t = np.concatenate([np.cumsum(tau[::-1])[::-1][1:], [0.0]])      # T_{>f}
        after_r = np.concatenate([np.cumsum(th[::-1])[::-1][1:], [0.0]])       # Theta_{>f}
        before_r = np.concatenate([[0.0], np.cumsum(th)[:-1]])                 # Theta_{<f}
        # the platform's own remainder (Rot(w) - I - [w]x)(o - p), (sinc|w| - 1) w
        rho_t[r] = np.sum(dt) + np.sum(th * after_t) + Rw * Rw * op / 2
        rho_r[r] = np.sum(dr) + np.sum(0.5 * th * after_r * (1 + th + after_r + 0.5 * th * after_r)) + Rw ** 3 / 6
        kt[r, 1] += _beta(Rw) * op
        kr[r, 1] += Rw * Rw / 2
        for f, (kind, data, c) in enumerate(fs):
            if kind == "pas":
                g = 2 + data
                b = _beta(box[g])
                kt[r, g] += b * after_t[f] + b * c + before_r[f] * (after_t[f] + c) + after_t[f]
                kr[r, g] += b + before_r[f] + after_r[f]
    return rho_t, rho_r, kt, kr


def _enclosed_inverse(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``C`` (the computed ``A^-1``) and ``c`` with ``|A^-1 - C|_kj <= c_k`` (module text, rounding)."""
    n = A.shape[0]
    C = np.linalg.inv(A)
    E = np.abs(np.eye(n) - A @ C) + (n + 1) * _EPS * np.abs(A) @ np.abs(C)
    eta = float(np.max(np.sum(E, axis=-1)))
    if not eta < 0.5:
        return C, np.full(n, np.inf)
    return C, eta / (1 - eta) * np.sum(np.abs(C), axis=-1) * (1 + 1e-12)


def _rows_of_groups(geo: _ChainGeometry) -> list:
    return [slice(0, 3), slice(3, 6)] + [slice(off, off + k) for (_, _, _, off, k) in geo.groups]


def _block_norms(C: np.ndarray, c: np.ndarray, rows: list, nc: int) -> np.ndarray:
    """``|A^-1[rows_g, block]|_2`` bounds ``(n_rows, n_chains, 2)`` (translation, rotation blocks), rounding
    included."""
    out = np.zeros((len(rows), nc, 2))
    for g, rs in enumerate(rows):
        for r in range(nc):
            for b in range(2):
                blk = C[rs, 6 * r + 3 * b:6 * r + 3 * b + 3]
                out[g, r, b] = np.linalg.norm(blk, ord=2) + np.sqrt(3.0 * blk.shape[0]) * np.max(c[rs])
    return out


def _group_maxima(geo: _ChainGeometry, P: np.ndarray, err: np.ndarray, rows: list) -> np.ndarray:
    """Per group of unknowns the largest norm of its first-order part ``(P x)_g`` over the sources' sets (certified
    upper value of :func:`~pmaccuracy.numerics.support.max_norm`; a scalar: the sum of the support functions),
    plus the rounding ``err`` of ``P``."""
    out = np.zeros(len(rows))
    cols = [slice(geo.offsets[k], geo.offsets[k + 1]) for k in range(len(geo.sources))]
    for g, rs in enumerate(rows):
        e = sum(np.linalg.norm(err[rs, c]) for c in cols)
        k = rs.stop - rs.start
        if k == 1:
            out[g] = sum(np.linalg.norm(P[rs, c]) for c in cols) + e
        else:
            blocks = [np.concatenate([P[rs, c], np.zeros((3 - k, c.stop - c.start))])[None] for c in cols]
            out[g] = float(max_norm(blocks).upper[0]) + e
    return out


def _perron_bound(lam: np.ndarray) -> float:
    """An upper bound of the spectral radius of a nonnegative matrix (Collatz-Wielandt: ``max_i (lam v)_i / v_i``
    for any positive ``v``; ``v`` the computed Perron vector, floored)."""
    vals, vecs = np.linalg.eig(lam + 1e-300)
    v = np.abs(np.real(vecs[:, int(np.argmax(np.abs(vals)))]))
    v = np.maximum(v, 1e-12 * max(float(np.max(v)), 1e-300))
    return float(np.max((lam @ v) / v)) * (1 + 1e-12)


def _chain_certify(geo: _ChainGeometry, A: np.ndarray, B: np.ndarray):
    """The invariant box of the unknowns and the contraction (module text): ``(rho_t, rho_r, box, radius,
    reason)``."""
    C, c = _enclosed_inverse(A)
    nc = len(geo.chains)
    if not np.all(np.isfinite(c)):
        return None, None, None, np.inf, "the closure's matrix could not be enclosed (near-singular)"
    rows = _rows_of_groups(geo)
    P = C @ B
    err = c[:, None] * np.sum(np.abs(B), axis=0)[None] + (A.shape[0] + 2) * _EPS * np.abs(C) @ np.abs(B)
    FO = _group_maxima(geo, P, err, rows)
    N = _block_norms(C, c, rows, nc)
    factors = _chain_factors(geo)
    reason = "the bounds of the solution set do not close (the error set is too large for the distance to a " \
             "singularity)"

    def image(box):
        rho_t, rho_r, _, _ = _chain_bounds(factors, box)
        return FO + N[:, :, 0] @ rho_t + N[:, :, 1] @ rho_r

    box = FO.copy()
    for _ in range(200):
        if not np.all(np.isfinite(box)) or np.max(box[1:]) > 0.5:
            return None, None, None, np.inf, reason
        new = image(box)
        if np.all(new <= box * (1 + 1e-14)):
            break
        box = np.maximum(box, new)
    for inflate in (1e-9, 1e-6, 1e-3, 1e-1):
        trial = box * (1 + inflate) + 1e-300
        if np.max(trial[1:]) <= 0.5 and np.all(image(trial) < trial):
            break
    else:
        return None, None, None, np.inf, reason
    rho_t, rho_r, kt, kr = _chain_bounds(factors, trial)
    lam = N[:, :, 0] @ kt + N[:, :, 1] @ kr                 # (groups, groups)
    radius = _perron_bound(lam)
    if not radius < 1:
        return None, None, None, radius, f"the closure is not proven a contraction over the box (radius {radius:.3g})"
    return rho_t, rho_r, trial, radius, ""


def _chain_support(geo: _ChainGeometry, g: np.ndarray) -> np.ndarray:
    """The point of the sources' set maximizing ``g . x`` for rows of ``g`` ``(N, m)``."""
    x = np.zeros_like(g)
    for k in range(len(geo.sources)):
        a, b = geo.offsets[k], geo.offsets[k + 1]
        nrm = np.linalg.norm(g[:, a:b], axis=-1, keepdims=True)
        x[:, a:b] = np.where(nrm > 0, g[:, a:b] / np.where(nrm > 0, nrm, 1.0), 0.0)
    return x


def _chain_ascent(geo: _ChainGeometry, C: np.ndarray, x: np.ndarray, which: np.ndarray, sign: np.ndarray,
                  steps: int) -> tuple:
    """Conditional-gradient ascent of each row's quantity over the sources' sets: gradients ``-(C dF/dx)`` (``dF/dx``
    by central differences at the solution), each step accepted only if the exact quantity increases."""
    t, _ = _chain_solve(geo, C, x)
    f = _objective(t, which, sign)
    N, m = x.shape
    for _ in range(steps if m else 0):
        _, y = _chain_solve_full(geo, C, x)
        step = 1e-6
        X = np.concatenate([x[:, None, :] + np.eye(m) * step, x[:, None, :] - np.eye(m) * step], 1).reshape(-1, m)
        F = _chain_residual(geo, np.repeat(y, 2 * m, axis=0), _joint_displacements(geo, X)).reshape(N, 2, m, -1)
        dF = np.swapaxes((F[:, 0] - F[:, 1]) / (2 * step), 1, 2)             # (N, rows, m)
        dt = -np.einsum("kr,nrm->nkm", C[:6], dF)                            # (N, 6, m)
        q = _quantities(t)
        grad = np.empty((N, m))
        for n in range(N):
            k = which[n]
            if k < 6:
                grad[n] = sign[n] * dt[n, k]
            else:
                rs = slice(0, 3) if k == 6 else slice(3, 6)
                grad[n] = (t[n, rs] / max(q[n, k], 1e-300)) @ dt[n, rs]
        target = _chain_support(geo, np.where(np.isfinite(grad), grad, 0.0))
        x, t, f, improved = _line_search(x, t, f, target, lambda cand: _chain_solve(geo, C, cand)[0], which,
                                         sign)
        if not np.any(improved):
            break
    return x, t, f


def _chain_solve_full(geo: _ChainGeometry, C: np.ndarray, x: np.ndarray, iterations: int = 60):
    """As :func:`_chain_solve`, returning also all the unknowns ``(N, n)``."""
    E = _joint_displacements(geo, x)
    y = np.zeros((x.shape[0], geo.n))
    for _ in range(iterations):
        step = _chain_residual(geo, y, E) @ C.T
        y = y - step
        if np.all(np.abs(step) <= 1e-17 * geo.scale):
            break
    return y[:, :6], y


def spatial_error_twists(robot: SpatialManipulator, sources, pose, displacements) -> np.ndarray:
    """The exact error twists ``[dp, dtheta]`` ``(N, 6)`` (mm, rotation vector rad: the displaced pose is ``p +
    dp``, ``Rot(dtheta) R``) of a 6-UPS, 3-RPS, 3-PRS, 3-UPU or Delta at ``pose`` ``(6,)`` (rotation vector, rad)
    for configurations of its sources.

    ``displacements``: a list of ``N`` dicts ``{label: vector (3,)}`` (or one dict ``{label: (N, 3)}``), each
    source's displacement (mm for translations, a rotation vector in rad for rotations; base frame; labels
    ``legs[i].joints[j].key`` with ``[pin k]`` for a universal joint's pins; a missing label is 0); each vector must
    lie in its source's set (segment, disc or ball of its half-width). A 6-UPS: Eq. 1 of the module text
    (:func:`hexapod_error_twists`); the others: the chains' closure, Eq. 4, solved from the nominal
    configuration. NaN where the solve does not converge.
    """
    check_angle_values(rotation_angles(pose), "pose[3:] (rotation vector)")
    if getattr(robot, "architecture", None) == "6-UPS":
        return hexapod_error_twists(robot, sources, pose, displacements)
    sources, pose = _check(robot, sources, pose, CERTIFIED_ARCHITECTURES)
    spatial_pose_errors(robot, sources, pose)      # reachability, joint limits, singularity: raise as it does
    geo = _chain_geometry(robot, sources, pose)
    A, _ = _chain_linear(geo)
    return _chain_solve(geo, np.linalg.inv(A), _variables(geo, displacements))[0]


def _chain_certified_bounds(robot: SpatialManipulator, sources: SpatialErrorSources, pose: np.ndarray,
                            ascent_steps: int) -> SpatialCertifiedBounds:
    """:func:`spatial_certified_bounds` for a 3-RPS, 3-PRS, 3-UPU or Delta (module text, second part)."""
    geo = _chain_geometry(robot, sources, pose)
    m = geo.offsets[-1]
    if m == 0:
        zero = np.zeros(8)
        return SpatialCertifiedBounds(pose, zero, zero, zero, True, "", [{} for _ in QUANTITIES], np.zeros((8, 6)))
    A, B = _chain_linear(geo)
    C, c = _enclosed_inverse(A)
    P = -(C @ B)[:6]                                              # first-order twist per unit variable
    blocks = [P[:, geo.offsets[k]:geo.offsets[k + 1]] for k in range(len(geo.sources))]
    comp = sum(np.linalg.norm(b, axis=-1) for b in blocks)
    dpn = max_norm([b[:3][None] for b in blocks], gap=1e-4)
    dtn = max_norm([b[3:][None] for b in blocks], gap=1e-4)
    first = np.concatenate([comp, [dpn.upper[0], dtn.upper[0]]])
    # lower: the first-order worst configurations (each component's + and -, |dp|'s, |dtheta|'s), improved
    g = [P[k] * sgn for k in range(6) for sgn in (1.0, -1.0)]
    x0 = np.array([*_chain_support(geo, np.array(g)),
                   np.concatenate([cfg[0] for cfg in dpn.configuration]),
                   np.concatenate([cfg[0] for cfg in dtn.configuration])])
    which = np.array([k for k in range(6) for _ in (0, 1)] + [6, 7])
    sign = np.array([1.0, -1.0] * 6 + [1.0, 1.0])
    x, t, f = _chain_ascent(geo, C, x0, which, sign, ascent_steps)
    lower, configs, twists = np.zeros(8), [], np.zeros((8, 6))
    for k in range(8):
        rows = np.flatnonzero(which == k)
        best = rows[int(np.argmax(np.where(np.isfinite(f[rows]), f[rows], -np.inf)))]
        lower[k], twists[k] = f[best], t[best]
        configs.append({s.label: s.half_width * s.basis @ x[best, geo.offsets[j]:geo.offsets[j + 1]]
                        for j, s in enumerate(geo.sources)})
    rho_t, rho_r, box, radius, reason = _chain_certify(geo, A, B)
    if reason:
        return SpatialCertifiedBounds(pose=pose, first_order=first, lower=lower, upper=np.full(8, np.inf),
                                      certified=False, reason=reason, configurations=configs, twists=twists,
                                      box={"contraction": float(radius)})
    nc = len(geo.chains)
    rows = [slice(k, k + 1) for k in range(6)] + [slice(0, 3), slice(3, 6)]
    Nb = _block_norms(C, c, rows, nc)
    rem = Nb[:, :, 0] @ rho_t + Nb[:, :, 1] @ rho_r
    rem = np.minimum(rem, _chain_refined(geo, A, B, C, c, box, rho_t, rho_r))      # both proven: the smaller
    # rounding of C B: |A^-1 B - C B| <= c 1^T |B| (+ the product's own rounding), per unit variable
    err = (c[:6, None] * np.sum(np.abs(B), axis=0)[None] + (A.shape[0] + 2) * _EPS * (np.abs(C) @ np.abs(B))[:6])
    errs = np.array([sum(np.linalg.norm(err[k, geo.offsets[j]:geo.offsets[j + 1]]) for j in range(len(geo.sources)))
                     for k in range(6)])
    fo_up = np.concatenate([comp + errs, [dpn.upper[0] + np.linalg.norm(errs[:3]),
                                          dtn.upper[0] + np.linalg.norm(errs[3:])]])
    upper = (fo_up + rem) * (1 + ROUNDING)
    info = {"Rv": float(box[0]), "Rw": float(box[1]), "contraction": float(radius)}
    return SpatialCertifiedBounds(pose=pose, first_order=first, lower=lower, upper=upper, certified=True, reason="",
                                  configurations=configs, twists=twists, box=info)


# ------------------------------------------------------------------ the second-order term as a quadratic form
_LEVI = np.zeros((3, 3, 3))
_LEVI[0, 1, 2] = _LEVI[1, 2, 0] = _LEVI[2, 0, 1] = 1.0
_LEVI[0, 2, 1] = _LEVI[2, 1, 0] = _LEVI[1, 0, 2] = -1.0


def _double_cross(c: np.ndarray) -> np.ndarray:
    """``M_i`` ``(3, 3, 3)`` with ``(w x (w x c))_i = w^T M_i w``: ``sym(e_i c^T) - c_i I``."""
    E = np.eye(3)
    return np.array([0.5 * (np.outer(E[i], c) + np.outer(c, E[i])) - c[i] * E for i in range(3)])


def _block_sums(H: np.ndarray, offsets: tuple) -> np.ndarray:
    """``sum_ab |H_k[a, b]|_2`` over the sources' blocks for each ``H_k`` ``(K, m, m)``: a bound of ``max |x^T H_k
    x|`` over the product of the sources' unit balls (each block padded to 3 x 3: the same spectral norm)."""
    n = len(offsets) - 1
    P = np.zeros((H.shape[0], n, n, 3, 3))
    for a in range(n):
        for b in range(n):
            blk = H[:, offsets[a]:offsets[a + 1], offsets[b]:offsets[b + 1]]
            P[:, a, b, :blk.shape[1], :blk.shape[2]] = blk
    return np.sum(np.linalg.norm(P, ord=2, axis=(-2, -1)), axis=(1, 2))


def _chain_refined(geo: _ChainGeometry, A: np.ndarray, B: np.ndarray, C: np.ndarray, c: np.ndarray,
                   box: np.ndarray, rho_t: np.ndarray, rho_r: np.ndarray) -> np.ndarray:
    """The remainder of each quantity ``(8,)`` at the unique solution in ``box`` (module text, Eq. 6): the exact
    second-order term of the closure as a quadratic form of the sources' variables, the rest (third order)
    bounded by norms. ``rho_t, rho_r`` the bounds (5) over the box."""
    m, nc = geo.offsets[-1], len(geo.chains)
    L = -(C @ B)                                                   # y = L x + eta
    rows = _rows_of_groups(geo)
    Nb = _block_norms(C, c, rows, nc)
    # |eta_g| at any solution in the box: -A^-1 r, plus (C - A^-1) B x (rounding of L)
    bsum = float(np.sum(np.abs(B)))
    eps_g = Nb[:, :, 0] @ rho_t + Nb[:, :, 1] @ rho_r + np.array(
        [np.sqrt(rs.stop - rs.start) * np.max(c[rs]) * bsum for rs in rows])
    Ww = L[3:6]
    gidx = {(li, lj, lf): g for g, (li, lj, lf, _, _) in enumerate(geo.groups)}

    def one_pass(box, eps_g, build):
        Hs = np.zeros((geo.n, m, m)) if build else None
        delta_t, delta_r = np.zeros(nc), np.zeros(nc)
        for r, (i, joints) in enumerate(geo.chains):
            o = geo.origins[r]
            Qt, Qr = np.zeros((3, m, m)), np.zeros((3, m, m))
            cum = np.zeros((3, m))
            th, tau, dt, ep, epc, cub_t, cub_r = [], [], [], [], [], [], []
            for j in joints:
                cj = geo.centres[i][j]
                co = float(np.linalg.norm(cj - o))
                facs = []
                W, T, ro = np.zeros((3, m)), np.zeros((3, m)), []
                om = tr = 0.0
                for k, s in enumerate(geo.sources):
                    if s.leg != i or s.joint != j:
                        continue
                    a, b = geo.offsets[k], geo.offsets[k + 1]
                    if s.role == "t":
                        T[:, a:b] += s.half_width * s.basis
                        tr += s.half_width
                    else:
                        W[:, a:b] += s.half_width * s.basis
                        om += s.half_width
                        if s.role == "o":
                            Ws = np.zeros((3, m))
                            Ws[:, a:b] = s.half_width * s.basis
                            ro.append((Ws, cj - s.origin, s.half_width))
                if om > 0 or tr > 0:
                    V = T + skew(cj - o) @ W - sum(skew(e) @ Ws for Ws, e, _ in ro)
                    self_q = -0.5 * np.einsum("ja,ijk,kb->iab", W, _double_cross(cj - o), W)
                    for Ws, e, _ in ro:
                        self_q = self_q + 0.5 * np.einsum("ja,ijk,kb->iab", Ws, _double_cross(e), Ws)
                    eo = [(h, float(np.linalg.norm(e))) for _, e, h in ro]
                    cubic = (om ** 3 / 6 + om ** 4 / 24) * co + sum((h ** 3 / 6 + h ** 4 / 24) * e for h, e in eo)
                    facs.append((W, V, self_q, om, tr + om * co + sum(h * e for h, e in eo),
                                 om * om * co / 2 + sum(h * h * e / 2 for h, e in eo), 0.0, 0.0, cubic))
                for f, basis in enumerate(geo.passive[i][j]):
                    g = gidx[(i, j, f)]
                    off, k = geo.groups[g][3], geo.groups[g][4]
                    W = basis @ L[off:off + k]
                    V = skew(cj - o) @ W
                    self_q = -0.5 * np.einsum("ja,ijk,kb->iab", W, _double_cross(cj - o), W)
                    a = box[2 + g]
                    facs.append((W, V, self_q, a, a * co, a * a * co / 2, eps_g[2 + g], eps_g[2 + g] * co,
                                 (a ** 3 / 6 + a ** 4 / 24) * co))
                for W, V, self_q, a, t_f, d_f, e_f, ec_f, cb in facs:
                    Qt += np.einsum("ja,ijk,kb->iab", cum, _LEVI, V) + self_q
                    Qr += 0.5 * np.einsum("ja,ijk,kb->iab", cum, _LEVI, W)
                    cum = cum + W
                    th.append(a), tau.append(t_f), dt.append(d_f), ep.append(e_f), epc.append(ec_f), cub_t.append(cb)
                    cub_r.append(a ** 3 / 6)
            Qt -= 0.5 * np.einsum("ja,ijk,kb->iab", Ww, _double_cross(o), Ww)          # the platform's own
            th, tau, dt, ep, epc = map(np.array, (th, tau, dt, ep, epc))

            def after(v):
                return np.concatenate([np.cumsum(v[::-1])[::-1][1:], [0.0]])
            T_a, Th_a, E_a, Ec_a = after(tau), after(th), after(ep), after(epc)
            # e_t, e_R of the products P_>f (second-order parts of their translation and rotation)
            et = after(dt + th * T_a)
            eR = after(th * th / 2 + th * Th_a)
            Rw, ew, op = box[1], eps_g[1], float(np.linalg.norm(o))
            delta_t[r] = (np.sum(cub_t) + np.sum(th * th / 2 * T_a + th * et) + (Rw ** 3 / 6 + Rw ** 4 / 24) * op
                          + np.sum(ep * T_a + th * Ec_a) + np.sum(th * epc) + Rw * ew * op)
            delta_r[r] = (np.sum(cub_r) + np.sum(th * th / 2 * Th_a + th * eR) + Rw ** 3 / 6
                          + 0.5 * np.sum(ep * Th_a + th * E_a))
            if build:
                Hs -= (np.einsum("ki,iab->kab", C[:, 6 * r:6 * r + 3], Qt)
                       + np.einsum("ki,iab->kab", C[:, 6 * r + 3:6 * r + 6], Qr))
        return delta_t, delta_r, Hs

    factors = _chain_factors(geo)
    FO = _group_maxima(geo, -L, c[:, None] * np.sum(np.abs(B), axis=0)[None]
                       + (A.shape[0] + 2) * _EPS * np.abs(C) @ np.abs(B), rows)
    delta_t, delta_r, Hs = one_pass(box, eps_g, True)
    Hs = 0.5 * (Hs + np.swapaxes(Hs, 1, 2))
    quad_rows = _block_sums(Hs, geo.offsets)                      # max |(C Q(L x, x))_row| over the sets
    Nall = Nb
    for _ in range(4):
        # at the solution: |eta_g| <= |(A^-1 Q)_g| + |A^-1_g,block| Delta_block (+ rounding); |y_g| <= FO_g + that
        rho_t, rho_r, _, _ = _chain_bounds(factors, box)
        rowq = quad_rows + c * np.sum(np.sqrt(3.0) * (rho_t + rho_r + delta_t + delta_r))   # |Q| <= |r| + |Delta|
        new = np.array([np.linalg.norm(rowq[rs]) for rs in rows]) + Nall[:, :, 0] @ delta_t \
            + Nall[:, :, 1] @ delta_r + np.array([np.sqrt(rs.stop - rs.start) * np.max(c[rs]) * bsum for rs in rows])
        eps_g = np.minimum(eps_g, new)
        box = np.minimum(box, FO + eps_g)
        delta_t, delta_r, _ = one_pass(box, eps_g, False)
    rho_t, rho_r, _, _ = _chain_bounds(factors, box)
    quad = quad_rows[:6] + c[:6] * np.sum(np.sqrt(3.0) * (rho_t + rho_r + delta_t + delta_r))
    qrows = [slice(k, k + 1) for k in range(6)] + [slice(0, 3), slice(3, 6)]
    Nq = _block_norms(C, c, qrows, nc)
    rest = Nq[:, :, 0] @ delta_t + Nq[:, :, 1] @ delta_r
    return np.concatenate([quad, [np.linalg.norm(quad[:3]), np.linalg.norm(quad[3:])]]) + rest
