"""Inverse and forward kinematics, Jacobians and singularities of any planar 3-leg manipulator.

The paper's Sec. 3 (Eq. 1-5) in general form: every leg is a chain of three
one-DOF joints (:class:`~pmaccuracy.model.chain.Chain`), solved in closed form; the
Jacobians come from the legs' constraint wrenches (screw theory,
:mod:`pmaccuracy.numerics.screws`) and reduce to Eq. 4a/4b for the 3-PPR.

Poses are arrays of shape ``(..., 3)`` holding ``[x, y, phi]`` (mm, mm, rad);
every function broadcasts over the leading axes. Actuated joint values are mm
(P) or rad (R).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError, GeometryError, NoSolutionError, OutsideJointLimitsError, PoseError, SingularPoseError
from ..model.manipulator import Manipulator, perp, unit
from ..model.spatial import SpatialManipulator, is_spatial, is_spatial_architecture
from ..model import _tomlio
from . import spatial as _spatial
from ..model.plausibility import check_angle_values, check_orientations, rotation_angles, spatial_robot_messages, warn
from ..numerics.linalg import inverse_3x3
from ..numerics.screws import wrap

#: A pose computed on the workspace boundary must count as inside: joint limits get this slack (mm or rad).
LIMIT_TOLERANCE = 1e-9
#: Poses whose homogenized A (Eq. 4a) has a larger condition number are refused as (near-)singular, and so are
#: poses where a leg's transmission index |B_ii| (normalized, <= 1) falls below its inverse (type-1 singularity).
#: 100 (a dexterity 1/cond below 0.01) refuses aalborg_3ppr within about 1 deg of phi = +-90 deg, where the
#: first-order bounds are already amplified ~20 times over phi = 0 and the linear model stops being meaningful.
DEFAULT_MAX_CONDITION = 100.0
#: Most assembly modes a planar 3-leg manipulator with R and P joints can have (a 3-RPR reaches six).
MAX_MODES = 6


#: Largest |actuator value| forward kinematics takes (mm or rad): far beyond any robot, below overflow.
MAX_ACTUATOR_VALUE = 1e9


def as_poses(poses: np.ndarray | list, *, name: str = "pose") -> np.ndarray:
    """Check and convert poses to a float array of shape ``(..., 3)``; non-finite values raise PoseError."""
    try:
        arr = np.asarray(poses, dtype=float)
    except (TypeError, ValueError):
        raise PoseError(f"{name}s must be numbers of shape (..., 3) = [x mm, y mm, phi rad], got "
                        f"{type(poses).__name__}") from None
    if arr.ndim == 0 or arr.shape[-1] != 3:
        raise PoseError(f"{name}s must have shape (..., 3) = [x mm, y mm, phi rad], got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.all(np.isfinite(arr), axis=-1))[0]
        raise PoseError(f"{name} {tuple(int(i) for i in bad)} is not finite: {arr[tuple(bad)].tolist()}")
    return arr



@dataclass(frozen=True)
class IKSolution:
    """Joint values of a batch of poses (Eq. 2a, 2b in general form).

    Attributes
    ----------
    joints : ``(..., 3, 3)`` every joint value, ``[pose..., leg, joint]`` base to platform (mm for P, rad for R)
    actuated_index : ``(3,)`` which joint of each leg is actuated
    within_limits : bool ``(...)``: every leg reaches the pose on its working mode and all nine joints lie
        inside their ranges (with :data:`LIMIT_TOLERANCE`)
    A, B : ``(..., 3, 3)`` forward and inverse Jacobians at the poses (:func:`jacobians`)

    For the 3-PPR the paper's names are kept: ``s`` (actuated guides) and ``l``
    (passive bearings), each ``(..., 3)`` mm.
    """

    joints: np.ndarray
    actuated_index: np.ndarray
    within_limits: np.ndarray
    A: np.ndarray
    B: np.ndarray
    #: The legs' :class:`~pmaccuracy.model.chain.LegState` (joint geometry and wrenches) behind these values.
    states: tuple | None = field(default=None, repr=False, compare=False)

    @property
    def q(self) -> np.ndarray:
        """Actuated joint values ``(..., 3)`` (mm or rad)."""
        return np.take_along_axis(self.joints, self.actuated_index[:, None] + np.zeros(
            self.joints.shape[:-1] + (1,), dtype=int), axis=-1)[..., 0]

    @property
    def passive(self) -> np.ndarray:
        """Passive joint values ``(..., 3, 2)`` in chain order (mm or rad)."""
        idx = np.array([[k for k in range(3) if k != a] for a in self.actuated_index])
        return np.take_along_axis(self.joints, idx + np.zeros(self.joints.shape[:-1] + (2,), dtype=int), axis=-1)

    @property
    def reachable(self) -> np.ndarray:
        """bool ``(...)``: every leg can be closed at the pose (joint ranges aside)."""
        return np.all(np.isfinite(self.joints), axis=(-2, -1))

    @property
    def s(self) -> np.ndarray:
        """3-PPR name of the actuated joint values ``(..., 3)`` mm (Eq. 2a)."""
        return self.q

    @property
    def l(self) -> np.ndarray:  # noqa: E743 - the paper's name
        """3-PPR name of the passive bearing values ``(..., 3)`` mm (Eq. 2b): the second joint of each leg."""
        return self.joints[..., :, 1]


def inverse_kinematics(robot: Manipulator, poses: np.ndarray, tol: float = LIMIT_TOLERANCE) -> IKSolution:
    """Joint values for poses, every leg on its working mode (closed form per leg).

    Each leg solves its chain for the pose (:meth:`pmaccuracy.model.chain.Chain.inverse_kinematics`);
    for the 3-PPR this is Eq. 2a/2b::

        s_i = (w_i^T E u_i)^-1 w_i^T E (p - a_i h_i - d_i v_i - r_i k_i)        (Eq. 2a)
        l_i = (u_i^T E w_i)^-1 u_i^T E (p - a_i h_i - d_i v_i - r_i k_i)        (Eq. 2b)

    Parameters
    ----------
    poses : array ``(..., 3)``, ``[x mm, y mm, phi rad]``

    Returns
    -------
    :class:`IKSolution`; joint values are NaN (and ``within_limits`` False) where a leg cannot reach.

    Example
    -------
    >>> robot = Manipulator.preset("aalborg_3ppr")
    >>> (inverse_kinematics(robot, [0.0, 0.0, 0.0]).s.round(6) + 0.0).tolist()   # (+ 0.0: no -0.0)
    [-15.0, -15.0, 0.0]

    A spatial robot (:class:`~pmaccuracy.model.spatial.SpatialManipulator`) takes poses ``(..., 6)``
    ``[x, y, z mm, rotation vector rad]`` and gives a :class:`~pmaccuracy.kinematics.spatial.SpatialIK`
    (:func:`pmaccuracy.kinematics.spatial.inverse_kinematics`).
    """
    robot = resolve_robot(robot)  # a preset name or a TOML path too
    if is_spatial(robot):
        check_angle_values(rotation_angles(poses), "poses[..., 3:] (rotation vectors)")
        return _spatial.inverse_kinematics(robot, poses, tol)
    check_orientations(poses, "poses", poses=True)
    poses = as_poses(poses)
    return ik_from_states(robot, leg_states(robot, poses), tol)


def leg_states(robot: Manipulator, poses: np.ndarray) -> tuple:
    """Each leg on its working mode at poses ``(..., 3)``: :class:`~pmaccuracy.model.chain.LegState` (one pass per leg,
    ``exp(i phi)`` shared)."""
    phi = poses[..., 2]
    if phi.size > 1 and phi.min() == phi.max():   # one orientation (a map's layer): its rotation once
        phi = float(phi.flat[0])
        e_phi = complex(np.cos(phi), np.sin(phi))
    else:
        e_phi = np.empty(phi.shape, dtype=complex)
        np.cos(phi, out=e_phi.real)
        np.sin(phi, out=e_phi.imag)
    pz = np.empty(phi.shape if np.ndim(phi) else poses.shape[:-1], dtype=complex)
    pz.real = poses[..., 0]
    pz.imag = poses[..., 1]
    return tuple(chain.state(poses, e_phi, pz, phi) for chain in robot.chains)


def ik_from_states(robot: Manipulator, states: tuple, tol: float = LIMIT_TOLERANCE) -> IKSolution:
    """:class:`IKSolution` of the legs' states (:func:`leg_states`): joint values, limits, A and B."""
    joints = np.stack([st.q for st in states], axis=-2)
    shape = joints.shape[:-2]
    A = np.empty(shape + (3, 3))
    B = np.zeros(shape + (3, 3))
    within = np.ones(shape, dtype=bool)
    for i, (chain, st) in enumerate(zip(robot.chains, states)):
        A[..., i, 0] = np.real(st.f)
        A[..., i, 1] = np.imag(st.f)
        A[..., i, 2] = st.m_P
        B[..., i, i] = st.B
        within &= chain.within_limits(st.q, tol)
    within &= np.all(np.isfinite(joints), axis=(-2, -1))
    act = np.array([c.actuated_index for c in robot.chains])
    return IKSolution(joints=joints, actuated_index=act, within_limits=within, A=A, B=B, states=states)


@dataclass(frozen=True)
class FKSolution:
    """Every assembly mode for a batch of actuator values.

    Attributes
    ----------
    poses : ``(..., M, 3)`` [x mm, y mm, phi rad], NaN where a mode does not exist (M = :data:`MAX_MODES`
        for :func:`forward_kinematics`), valid modes first, by increasing phi
    valid : bool ``(..., M)``
    joints : ``(..., M, 3, 3)`` every joint value of each mode (mm / rad), NaN where invalid
    within_limits : bool ``(..., M)``: valid and all joints inside their ranges
    working_modes : int ``(..., M, 3)``: sign of ``B_ii`` of each leg in that mode (0 where invalid)

    ``l`` keeps the 3-PPR name of the passive bearing values ``(..., M, 3)`` mm.
    """

    poses: np.ndarray
    valid: np.ndarray
    joints: np.ndarray
    within_limits: np.ndarray
    working_modes: np.ndarray | None = None

    @property
    def l(self) -> np.ndarray:  # noqa: E743
        return self.joints[..., 1]

    def nearest(self, reference: np.ndarray, angle_weight: float = 100.0) -> np.ndarray:
        """The assembly mode nearest to ``reference`` poses ``(..., 3)``; raises if none exists.

        Distance: ``|dp|^2 + (angle_weight * dphi)^2`` with ``angle_weight`` in mm/rad.
        """
        reference = np.asarray(reference, dtype=float)
        if np.any(np.all(~self.valid, axis=-1)):
            raise NoSolutionError("forward kinematics has no assembly mode for some actuator values")
        dphi = np.angle(np.exp(1j * (self.poses[..., 2] - reference[..., None, 2])))
        dist = np.sum((self.poses[..., :2] - reference[..., None, :2]) ** 2, axis=-1) + (angle_weight * dphi) ** 2
        idx = np.argmin(np.where(self.valid, np.nan_to_num(dist, nan=np.inf), np.inf), axis=-1)
        return np.take_along_axis(self.poses, idx[..., None, None], axis=-2)[..., 0, :]


def solve_loop_closure(c: np.ndarray, w: np.ndarray, r: np.ndarray, psi: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Solve ``p = c_i + l_i w_i + r_i vec(phi + psi_i)``, i = 1..3, for ``(x, y, phi, l)``.

    This is Eq. 1 with everything up to the passive joint lumped into the
    known point ``c_i`` (so it also serves perturbed models with clearances).
    Dotting with ``n_i = E w_i`` removes ``l_i``::

        n_i . p - m_i . q = n_i . c_i,   q = [cos phi, sin phi],   m_i = r_i R(-psi_i) n_i

    Three equations linear in ``p`` (2 unknowns) and ``q``. With ``z`` the left
    null vector of ``N = [n_1; n_2; n_3]`` (``z = N[:,0] x N[:,1]``), ``p``
    drops out: ``g . q = -z . b`` with ``g = M^T z``, ``b_i = n_i . c_i``, so
    ``phi = atan2(g) +- arccos(-z.b / |g|)``: at most two assembly modes.

    Parameters
    ----------
    c : ``(..., 3, 2)`` mm;  w : ``(..., 3, 2)`` unit;  r, psi : ``(..., 3)`` mm, rad

    Returns
    -------
    poses ``(..., 2, 3)``, valid ``(..., 2)``, l ``(..., 2, 3)``; NaN where invalid.
    """
    c, w = np.broadcast_arrays(np.asarray(c, float), np.asarray(w, float))
    r = np.broadcast_to(np.asarray(r, float), c.shape[:-1])
    psi = np.broadcast_to(np.asarray(psi, float), c.shape[:-1])
    n = perp(w)
    b = np.sum(n * c, axis=-1)
    cos_p, sin_p = np.cos(psi), np.sin(psi)
    m = r[..., None] * np.stack([cos_p * n[..., 0] + sin_p * n[..., 1],
                                 -sin_p * n[..., 0] + cos_p * n[..., 1]], axis=-1)
    z = np.cross(n[..., 0], n[..., 1])  # (..., 3): z . N = 0
    g = np.sum(z[..., None] * m, axis=-2)
    rhs = -np.sum(z * b, axis=-1)
    g_norm = np.hypot(g[..., 0], g[..., 1])
    scale = np.max(np.abs(z), axis=-1) * np.max(r, axis=-1)
    # |g| ~ 0: the loop condition does not involve phi (a degenerate architecture): no isolated solution.
    ok_g = g_norm > 1e-12 * np.maximum(scale, 1e-300)
    ratio = np.where(ok_g, rhs / np.where(ok_g, g_norm, 1.0), np.inf)
    # Rounding can push a tangent (double) solution just past |ratio| = 1.
    ratio = np.where(np.abs(ratio) <= 1 + 1e-12, np.clip(ratio, -1, 1), ratio)
    exists = np.abs(ratio) <= 1
    delta = np.arccos(np.where(exists, ratio, 0.0))
    base = np.arctan2(g[..., 1], g[..., 0])
    phi = np.stack([base + delta, base - delta], axis=-1)
    phi = np.angle(np.exp(1j * phi))  # wrap to (-pi, pi]
    valid = np.stack([exists, exists & (delta > 1e-14)], axis=-1)
    q = unit(phi)  # (..., 2, 2)
    rhs_p = b[..., None, :] + np.einsum("...ij,...kj->...ki", m, q)  # (..., 2, 3)
    NtN = np.einsum("...ij,...ik->...jk", n, n)  # (..., 2, 2)
    # All bearings parallel: N has rank 1 and p is undetermined; those entries are invalid anyway.
    NtN = np.where(valid.any(axis=-1)[..., None, None], NtN, np.eye(2))
    Ntb = np.einsum("...ij,...ki->...kj", n, rhs_p)  # (..., 2 modes, 2)
    p = np.linalg.solve(NtN[..., None, :, :], Ntb[..., None])[..., 0]
    k = unit(phi[..., None] + psi[..., None, :])  # (..., 2, 3, 2)
    D = p[..., None, :] - r[..., None, :, None] * k
    l = np.sum((D - c[..., None, :, :]) * w[..., None, :, :], axis=-1)
    poses = np.concatenate([p, phi[..., None]], axis=-1)
    poses = np.where(valid[..., None], poses, np.nan)
    l = np.where(valid[..., None], l, np.nan)
    return poses, valid, l


# ====================================================================== forward kinematics
#: Orientation samples of the eliminant (its trigonometric degree is at most 5: 16 samples resolve it exactly).
_N_SAMPLES = 16
_MAX_DEGREE = 6


def _quadrics(dyads, phi):
    """``kappa, g, h`` of the three locked legs at ``phi`` (broadcast), stacked on a last axis of 3."""
    ks, gs, hs = [], [], []
    for dy in dyads:
        k, g, h = dy.quadric(phi)
        g, h = np.broadcast_arrays(g, h)
        ks.append(np.full(h.shape, float(k)))
        gs.append(g)
        hs.append(h)
    return np.stack(ks, axis=-1), np.stack(gs, axis=-1), np.stack(hs, axis=-1)


def _det3(c0, c1, c2):
    """Determinant of 3x3 matrices given by their columns, each ``(..., 3)``."""
    return (c0[..., 0] * (c1[..., 1] * c2[..., 2] - c1[..., 2] * c2[..., 1])
            - c1[..., 0] * (c0[..., 1] * c2[..., 2] - c0[..., 2] * c2[..., 1])
            + c2[..., 0] * (c0[..., 1] * c1[..., 2] - c0[..., 2] * c1[..., 1]))


def eliminant(dyads, phi: np.ndarray) -> np.ndarray:
    """The univariate equation in ``phi`` whose real roots are the assembly modes.

    Each locked leg reads ``kappa_i |p|^2 + g_i(phi) . p + h_i(phi) = 0``
    (:meth:`pmaccuracy.model.chain.Dyad.quadric`; ``kappa = 1`` for a circle, 0 for a
    line). Treat ``w = |p|^2`` as a third unknown of the linear system
    ``K [w, x, y]^T = -h`` with rows ``K_i = [kappa_i, g_ix, g_iy]``; by
    Cramer's rule ``w = W/D, x = X/D, y = Y/D`` and ``w = x^2 + y^2`` gives::

        F(phi) = X^2 + Y^2 - W D = 0            (some leg is a circle)
        F(phi) = det [g_x, g_y, h] = 0          (all legs are lines)

    ``g`` and ``h`` are trigonometric polynomials of degree <= 1 in ``phi``,
    so ``F`` is one of degree <= 5. Returns ``F`` of shape ``phi``'s broadcast.
    """
    kappa, g, h = _quadrics(dyads, phi)
    gx, gy = g.real, g.imag
    if np.all(kappa == 0):
        return _det3(gx, gy, h)
    D = _det3(kappa, gx, gy)
    W = _det3(-h, gx, gy)
    X = _det3(kappa, -h, gy)
    Y = _det3(kappa, gx, -h)
    return X ** 2 + Y ** 2 - W * D


def _trig_roots(values: np.ndarray, tol: float = 1e-3) -> np.ndarray:
    """Real roots of trigonometric polynomials sampled at ``2 pi k / n``: ``(N, n)`` -> candidate phi ``(N, 2 D)``.

    The FFT of the samples gives the coefficients ``c_k`` of
    ``F = sum_{|k| <= D} c_k exp(i k phi)`` exactly (no aliasing for ``2D < n``);
    ``z^D F`` is a polynomial in ``z = exp(i phi)`` whose roots on the unit
    circle (``| |z| - 1 | < tol``, loose: the candidates are polished later)
    are the real roots. Leading and trailing coefficients below 1e-11 of the
    largest are dropped (lower effective degree; roots at 0 or infinity).
    NaN pads the rows.
    """
    n = values.shape[-1]
    c = np.fft.fft(values, axis=-1) / n
    D = _MAX_DEGREE
    coef = np.concatenate([c[..., n - D:], c[..., :D + 1]], axis=-1)  # c_{-D} .. c_{D}: ascending powers of z
    coef = coef[..., ::-1]                                             # descending powers
    size = np.max(np.abs(coef), axis=-1, keepdims=True)
    significant = np.abs(coef) > 1e-11 * size
    N = coef.shape[0]
    out = np.full((N, 2 * D), np.nan)
    first = np.argmax(significant, axis=-1)
    last = coef.shape[-1] - 1 - np.argmax(significant[..., ::-1], axis=-1)
    degree = last - first
    for key in set(zip(first.tolist(), degree.tolist())):
        f, d = key
        if d < 1:
            continue
        rows = np.nonzero((first == f) & (degree == d))[0]
        poly = coef[rows, f:f + d + 1]
        poly = poly / poly[:, :1]
        comp = np.zeros((rows.size, d, d), dtype=complex)
        comp[:, 0, :] = -poly[:, 1:]
        if d > 1:
            comp[:, np.arange(1, d), np.arange(d - 1)] = 1.0
        z = np.linalg.eigvals(comp)
        on_circle = np.abs(np.log(np.abs(z) + 1e-300)) < tol
        phis = np.where(on_circle, np.angle(z), np.nan)
        out[rows, :d] = phis
    return out


def _solve_pair(k1, g1, h1, k2, g2, h2):
    """Points ``p`` (complex) with two constraints ``k |p|^2 + g . p + h = 0`` at a fixed phi: ``(..., 2)``.

    Two lines: one point. A circle and a line (two circles: subtract them
    first): the line ``p = p0 + t n_perp`` put into the circle gives a
    quadratic in ``t``. NaN where no real point exists.
    """
    # make the second one a line if any circle is present
    circle1 = k1 != 0
    g2l = np.where(k2 != 0, g2 - np.where(circle1, g1, 0), g2)
    h2l = np.where(k2 != 0, h2 - np.where(circle1, h1, 0), h2)
    # if only the second is a circle, swap roles
    swap = (~circle1) & (k2 != 0)
    kc = np.where(swap, k2, k1)
    gc, hc = np.where(swap, g2, g1), np.where(swap, h2, h1)
    gl, hl = np.where(swap, g1, g2l), np.where(swap, h1, h2l)
    with np.errstate(invalid="ignore", divide="ignore"):
        # line gl . p + hl = 0: p0 = -hl gl / |gl|^2, direction t = i gl / |gl|
        n2 = np.abs(gl) ** 2
        p0 = -hl * gl / n2
        t_dir = 1j * gl / np.sqrt(n2)
        # circle (kc = 1): |p|^2 + gc . p + hc = 0 along the line: t^2 + b t + c = 0
        b = 2 * np.real(np.conj(p0) * t_dir) + np.real(np.conj(gc) * t_dir)
        cc = np.abs(p0) ** 2 + np.real(np.conj(gc) * p0) + hc
        disc = b ** 2 - 4 * cc
        disc = np.where(disc >= -1e-12 * np.maximum(b ** 2, 1.0), np.maximum(disc, 0.0), np.nan)
        roots = np.stack([(-b + np.sqrt(disc)) / 2, (-b - np.sqrt(disc)) / 2], axis=-1)
        circle_pts = p0[..., None] + roots * t_dir[..., None]
        # two lines: cross solve of g1 . p = -h1, g2 . p = -h2
        det = np.real(gc) * np.imag(gl) - np.imag(gc) * np.real(gl)
        x = (-hc * np.imag(gl) + hl * np.imag(gc)) / det
        y = (-np.real(gc) * hl + np.real(gl) * hc) / det
        line_pts = np.stack([x + 1j * y, np.full(x.shape, np.nan + 0j)], axis=-1)
    return np.where((kc != 0)[..., None], circle_pts, line_pts)


def _residuals(dyads, poses):
    """Constraint values and their gradients in ``(x, y, phi)``: ``r (..., 3)``, ``J (..., 3, 3)``."""
    phi = poses[..., 2]
    p = poses[..., 0] + 1j * poses[..., 1]
    r, J = [], []
    for dy in dyads:
        k, g, h = dy.quadric(phi)
        dg, dh = dy.quadric_dphi(phi)
        r.append(k * np.abs(p) ** 2 + np.real(np.conj(g) * p) + h)
        grad = 2 * k * p + g
        J.append(np.stack(np.broadcast_arrays(grad.real, grad.imag, np.real(np.conj(dg) * p) + dh), axis=-1))
    return np.stack(r, axis=-1), np.stack(J, axis=-2)


def _polish(dyads, poses, iterations: int = 8):
    """Newton steps on the three constraints in ``(x, y, phi)``; returns poses and the residual (mm)."""
    for _ in range(iterations):
        r, J = _residuals(dyads, poses)
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            Jinv, det = inverse_3x3(J)
            step = np.einsum("...ij,...j->...i", Jinv, r)
        ok = np.all(np.isfinite(step), axis=-1)
        poses = np.where(ok[..., None], poses - np.where(ok[..., None], step, 0.0), poses)
    r, J = _residuals(dyads, poses)
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.linalg.norm(J[..., :2], axis=-1)
        dist = np.where(scale > 0, np.abs(r) / np.where(scale > 0, scale, 1.0), np.abs(r))
    return poses, np.max(dist, axis=-1)


def _expand_locked(robot, q):
    return [chain.locked(chain.actuated_index, q[..., i]) for i, chain in enumerate(robot.chains)]


def forward_kinematics(robot: Manipulator, q: np.ndarray, tol: float = LIMIT_TOLERANCE,
                       residual_tol: float = 1e-7, *, guess=None) -> FKSolution:
    """Every assembly mode for actuator values ``q (..., 3)`` (mm or rad), whatever the working modes.

    A spatial robot: one set of actuator values ``(n,)`` without ``guess`` gives every real assembly mode
    (:func:`pmaccuracy.kinematics.spatial.assembly_modes`); a batch ``(..., n)`` or a ``guess`` (poses
    ``(..., 6)``) gives the pose Newton's method reaches from the guess (default: the home pose;
    :func:`pmaccuracy.kinematics.spatial.forward_kinematics`).

    1. Lock each leg's actuated joint: its two passive joints make a dyad,
       ``kappa |p|^2 + g(phi) . p + h(phi) = 0`` (:meth:`pmaccuracy.model.chain.Chain.locked`).
    2. Eliminate ``p`` (:func:`eliminant`); sample it at 16 orientations, take
       its exact Fourier coefficients and the roots of the polynomial in
       ``exp(i phi)`` on the unit circle (batched companion matrices). A leg
       with two passive slides fixes ``phi`` directly instead.
    3. Recover ``p`` at each root from every pair of legs, keep the point that
       satisfies the third, polish ``(x, y, phi)`` by Newton's method on the
       three constraints, accept residuals below ``residual_tol`` mm and merge
       duplicates.
    4. Joint values of each mode: the IK branch of each leg whose actuated
       value matches ``q``; ``within_limits`` checks all nine joints.

    A 3-PPR has at most two modes (the paper's analytic solution), a 3-RPR up to six.
    """
    robot = resolve_robot(robot)  # a preset name or a TOML path too
    if is_spatial(robot):
        check_angle_values(rotation_angles(guess), "guess[..., 3:] (rotation vectors)")
        q_arr = np.asarray(q, dtype=float)
        if guess is None and q_arr.ndim == 1:
            return _spatial.assembly_modes(robot, q_arr)
        return _spatial.forward_kinematics(robot, q_arr, guess)
    if guess is not None:
        raise ConfigError("guess= is for spatial robots; a planar robot's forward kinematics gives every mode",
                          key="guess")
    try:
        q = np.asarray(q, dtype=float)
    except (TypeError, ValueError):
        raise PoseError(f"actuator values q must be numbers of shape (..., 3), got {type(q).__name__}") from None
    if q.ndim == 0 or q.shape[-1] != 3:
        raise PoseError(f"actuator values must have shape (..., 3), got {q.shape}")
    if not np.all(np.isfinite(q)):
        raise PoseError("actuator values must be finite")
    revolute = [chain.actuated.kind == "R" for chain in robot.chains]
    if any(revolute):   # revolute actuators' values in rad: degrees typed in warn
        check_orientations(q[..., revolute], "q (revolute actuators)", "revolute joint values")
    if np.any(np.abs(q) > MAX_ACTUATOR_VALUE):  # the eliminant's coefficients would overflow
        raise PoseError(f"actuator values must be below {MAX_ACTUATOR_VALUE:g} in magnitude (mm or rad), got "
                        f"{q[np.abs(q) > MAX_ACTUATOR_VALUE].reshape(-1)[0]:g}")
    batch = q.shape[:-1]
    qf = q.reshape(-1, 3)
    N = qf.shape[0]
    dyads = _expand_locked(robot, qf)
    pp = [i for i, dy in enumerate(dyads) if dy.kind == "PP"]
    if pp:
        dy = dyads[pp[0]]
        phi_c = wrap(dy.base_angle + dy.c_angle - dy.platform_angle)[:, None] + np.zeros((N, 1))
    else:
        samples = 2 * np.pi * np.arange(_N_SAMPLES) / _N_SAMPLES
        values = eliminant([_broadcast_dyad(dy, 1) for dy in dyads], samples)  # (N, 16)
        phi_c = _trig_roots(values)
    C = phi_c.shape[1]
    # recover p at each candidate phi from each pair of legs; keep the best against all three
    cand_phi = phi_c.reshape(-1)
    dy_c = [_broadcast_dyad(dy, C, flat=True) for dy in dyads]
    kappa, g, h = _quadrics(dy_c, np.nan_to_num(cand_phi))
    points = []
    for a, b in ((0, 1), (0, 2), (1, 2)):
        points.append(_solve_pair(kappa[:, a], g[:, a], h[:, a], kappa[:, b], g[:, b], h[:, b]))
    points = np.concatenate(points, axis=-1)  # (N*C, 6)
    trial = np.stack([points.real, points.imag, np.broadcast_to(cand_phi[:, None], points.shape)], axis=-1)
    finite = np.isfinite(trial).all(-1)
    res, _ = _residuals([_broadcast_dyad(dy, 6) for dy in dy_c], np.where(finite[..., None], trial, 0.0))
    score = np.where(finite, np.max(np.abs(res), axis=-1), np.inf)
    best = np.argmin(score, axis=-1)
    start = np.take_along_axis(trial, best[:, None, None], axis=1)[:, 0, :]
    good_start = np.isfinite(start).all(-1) & np.isfinite(cand_phi)
    polished, dist = _polish(dy_c, np.where(good_start[:, None], start, 0.0))
    accept = good_start & (dist < residual_tol) & np.all(np.isfinite(polished), axis=-1)
    polished[:, 2] = wrap(polished[:, 2])
    polished = polished.reshape(N, C, 3)
    accept = accept.reshape(N, C)
    poses, valid = _unique_modes(polished, accept, robot.characteristic_length)
    joints, within, modes = _mode_joints(robot, poses, valid, qf, tol)
    shape = batch + (MAX_MODES,)
    return FKSolution(poses=poses.reshape(shape + (3,)), valid=valid.reshape(shape),
                      joints=joints.reshape(shape + (3, 3)), within_limits=within.reshape(shape),
                      working_modes=modes.reshape(shape + (3,)))


def _broadcast_dyad(dy, count: int, flat: bool = False):
    """A dyad whose arrays gain a trailing axis of ``count`` (or are repeated and flattened)."""
    from dataclasses import replace
    fields = ("base_angle", "base_point", "platform_angle", "platform_point", "c_angle", "c_trans")
    if flat:
        return replace(dy, **{f: np.repeat(np.asarray(getattr(dy, f)), count) for f in fields})
    return replace(dy, **{f: np.asarray(getattr(dy, f))[..., None] for f in fields})


def _unique_modes(poses, accept, length):
    """Merge candidates that converged to the same mode; sort by phi; pad to MAX_MODES with NaN."""
    N, C, _ = poses.shape
    key = np.where(accept, poses[..., 2], np.inf)
    order = np.argsort(key, axis=-1)
    poses = np.take_along_axis(poses, order[..., None], axis=1)
    accept = np.take_along_axis(accept, order, axis=1)
    keep = accept.copy()
    for i in range(1, C):
        for j in range(i):
            dphi = np.abs(wrap(poses[:, i, 2] - poses[:, j, 2]))
            dp = np.hypot(poses[:, i, 0] - poses[:, j, 0], poses[:, i, 1] - poses[:, j, 1])
            same = keep[:, j] & (dp < 1e-6 * max(length, 1.0)) & (dphi < 1e-7)
            keep[:, i] &= ~same
    order = np.argsort(~keep, axis=-1, kind="stable")
    poses = np.take_along_axis(poses, order[..., None], axis=1)
    keep = np.take_along_axis(keep, order, axis=1)
    out = np.full((N, MAX_MODES, 3), np.nan)
    valid = np.zeros((N, MAX_MODES), dtype=bool)
    m = min(C, MAX_MODES)
    out[:, :m] = np.where(keep[:, :m, None], poses[:, :m], np.nan)
    valid[:, :m] = keep[:, :m]
    return out, valid


def _mode_joints(robot, poses, valid, q, tol):
    """For each mode, each leg's IK branch whose actuated value matches ``q``: joints, within limits, modes."""
    N = poses.shape[0]
    joints = np.full((N, MAX_MODES, 3, 3), np.nan)
    modes = np.zeros((N, MAX_MODES, 3), dtype=int)
    within = valid.copy()
    safe = np.where(valid[..., None], poses, 0.0)
    for i, chain in enumerate(robot.chains):
        a = chain.actuated_index
        branches = chain.ik_branches(safe)  # (N, M, 2, 3)
        _, Bs = chain.screws(branches, safe[..., None, :])
        diff = branches[..., a] - q[:, None, None, i]
        if chain.actuated.kind == "R":
            diff = wrap(diff)
        err = np.nan_to_num(np.abs(diff), nan=np.inf)
        pick = np.argmin(err, axis=-1)
        chosen = np.take_along_axis(branches, pick[..., None, None], axis=-2)[..., 0, :]
        B = np.take_along_axis(Bs, pick[..., None], axis=-1)[..., 0]
        joints[:, :, i] = np.where(valid[..., None], chosen, np.nan)
        modes[:, :, i] = np.where(valid, np.sign(np.nan_to_num(B)).astype(int), 0)
        within &= chain.within_limits(chosen, tol)
    return joints, within, modes


def check_reachable(robot: Manipulator, samples: int = 256) -> None:
    """Raise :class:`GeometryError` when no assembly mode lies within the joint ranges.

    Tries the middle of the actuated ranges and ``samples - 1`` seeded random
    actuator values inside them (forward kinematics of each). A robot whose
    legs cannot be closed anywhere, or only outside their ranges, is refused
    when its file is read.
    """
    lo, hi = robot.s_range[:, 0], robot.s_range[:, 1]
    rng = np.random.default_rng(0)
    q = np.vstack([(lo + hi) / 2, lo + (hi - lo) * rng.random((samples - 1, 3))])
    fk = forward_kinematics(robot, q)
    if not np.any(fk.within_limits):
        raise GeometryError(
            f"unreachable geometry: no assembly mode lies within the joint ranges for any of {samples} actuator "
            "values sampled in their ranges (check the lengths, ranges and attachment points)", key="legs")


def resolve_robot(robot, name: str = "robot") -> Manipulator:
    """A :class:`~pmaccuracy.model.manipulator.Manipulator` (or, for a file whose ``architecture`` is spatial, a
    :class:`~pmaccuracy.model.spatial.SpatialManipulator`) from an instance (returned as it is), a preset name or
    a TOML path: the one place where a robot file is read for the public functions. A file's robot must
    assemble somewhere within its joint ranges (:func:`check_reachable`; a spatial robot: its home pose within
    its limits, :func:`pmaccuracy.kinematics.spatial.check_reachable`), else :class:`GeometryError` naming the
    file.

    >>> resolve_robot("aalborg_3ppr").architecture
    '3-PPR'
    """
    if isinstance(robot, (str, os.PathLike)):
        data, source = _tomlio.read_spec(robot, kind="robot", folder=Manipulator.PRESET_FOLDER)
        if is_spatial_architecture(data.get("architecture")):
            loaded = SpatialManipulator.from_dict(data, source=source)
            warn(spatial_robot_messages(loaded, source), stacklevel=3)
            _spatial.check_reachable(loaded, source)
            return loaded
        loaded = Manipulator.from_dict(data, source=source)
        try:
            check_reachable(loaded)
        except GeometryError as exc:
            raise GeometryError(exc.message, source=os.fspath(robot), key=exc.key) from None
        except PoseError as exc:   # e.g. an actuated range of 1e25 mm: its samples are no usable joint values
            raise GeometryError(f"the actuated joint ranges give no usable joint values ({exc})",
                                source=os.fspath(robot), key="legs") from None
        return loaded
    if not hasattr(robot, "chains") and not is_spatial(robot):
        raise ConfigError(f"expected a Manipulator, a preset name or a robot TOML path, got {type(robot).__name__}",
                          key=name)
    return robot


def jacobians(robot: Manipulator, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Forward and inverse Jacobians ``A`` and ``B`` (Eq. 3-4 in general form), each ``(..., 3, 3)``.

    ``A [p_dot; phi_dot] = B q_dot`` where row ``i`` of ``A`` is leg ``i``'s
    constraint wrench about P, ``[f_x, f_y, m_P]``, and ``B = diag(zeta_i . T_i)``
    its pairing with the actuated joint's twist
    (:meth:`pmaccuracy.model.chain.Chain.screws`). For the 3-PPR
    ``A_i = [w_i^T E^T, -r_i w_i^T k_i]`` and ``B = diag(w_i^T E^T u_i)`` (Eq. 4a, 4b).
    NaN where a leg cannot reach the pose.

    A spatial robot gives a :class:`~pmaccuracy.kinematics.spatial.SpatialJacobians` (the legs' actuation and
    constraint wrenches, the overall 6 x 6 Jacobian and the forward one).
    """
    robot = resolve_robot(robot)
    if is_spatial(robot):
        check_angle_values(rotation_angles(poses), "poses[..., 3:] (rotation vectors)")
        return _spatial.jacobians(robot, poses)
    check_orientations(poses, "poses", poses=True)
    ik = inverse_kinematics(robot, poses)
    return ik.A, ik.B


@dataclass(frozen=True)
class Singularity:
    """Distance to the type-2 (parallel, ``det A = 0``) and type-1 (serial, ``B_ii = 0``) singularities.

    det : ``(...)`` determinant of A (mm: its third column is a length).
    condition : ``(...)`` 1-norm condition number ``||A_h||_1 ||A_h^-1||_1`` of
        A with its third column divided by :attr:`Manipulator.characteristic_length`
        (dimensionless, >= 1; ``inf`` where A is exactly singular or a leg cannot reach).
    transmission : ``(..., 3)`` each leg's normalized ``|B_ii|`` in [0, 1]: ``|f . e|`` for an actuated
        slide, the sine ``|B_ii| / |c - c_a|`` of the angle between the constraint line and the arm from
        the actuated revolute for an actuated R (1 for a couple); 0 at a serial singularity.

    For a 3-PPR the first two columns of A are constant (``E w_i``) and the
    third depends on phi only, so the singularity is a set of orientations
    (phi = +-90 deg for both presets), whatever x and y; its transmission is
    ``|sin(gamma_i + theta_i)|``, constant.
    """

    det: np.ndarray
    condition: np.ndarray
    transmission: np.ndarray


def _condition(robot: Manipulator, A: np.ndarray, A_inv: np.ndarray) -> np.ndarray:
    L = robot.characteristic_length
    scale = np.array([1.0, 1.0, 1.0 / L])
    norm_Ah = np.max(np.sum(np.abs(A * scale), axis=-2), axis=-1)
    norm_Ah_inv = np.max(np.sum(np.abs(A_inv / scale[:, None]), axis=-2), axis=-1)
    cond = norm_Ah * norm_Ah_inv
    return np.where(np.isfinite(cond), cond, np.inf)


def _transmission(robot: Manipulator, ik: IKSolution, poses: np.ndarray) -> np.ndarray:
    """Each leg's transmission index ``(..., 3)`` in [0, 1]: ``|B_ii|`` normalized by the actuated joint's
    moment arm (1 for a pure couple); 0 where undefined."""
    states = ik.states if ik.states is not None else \
        tuple(chain.state_at(ik.joints[..., i, :], poses) for i, chain in enumerate(robot.chains))
    return states_transmission(robot, states, ik.B.shape[:-2])


def states_transmission(robot: Manipulator, states: tuple, shape: tuple) -> np.ndarray:
    """Transmission indices ``(*shape, 3)`` of the legs' states (:func:`_transmission`)."""
    t = np.stack([np.broadcast_to(v, shape) for v in raw_transmission(robot, states)], axis=-1)
    return np.where(np.isfinite(t), np.minimum(t, 1.0), 0.0)


def raw_transmission(robot: Manipulator, states: tuple) -> list:
    """Each leg's ``|B_ii|`` over the actuated joint's moment arm (scalar or ``(...)``), before clipping to
    [0, 1] (NaN where undefined: any comparison with it is False)."""
    out = []
    for i, (chain, st) in enumerate(zip(robot.chains, states)):
        B = st.B
        if chain.actuated.kind == "P":
            out.append(np.abs(B))
            continue
        a = chain.actuated_index
        pi, pj = chain.passive_indices
        kinds = chain.joints[pi].kind + chain.joints[pj].kind
        if kinds == "PP":
            out.append(1.0)
            continue
        line_point = st.centres[pi] if chain.joints[pi].kind == "R" else st.centres[pj]
        with np.errstate(invalid="ignore", divide="ignore"):
            out.append(np.abs(B) * (1.0 / np.abs(line_point - st.centres[a])))   # arm 0: inf or NaN
    return out


def singularity(robot: Manipulator, poses: np.ndarray) -> Singularity:
    """det A, the condition number of the homogenized A and the legs' transmission indices (Eq. 4a-4b).

    A spatial robot gives a :class:`~pmaccuracy.kinematics.spatial.SpatialSingularity` (serial, parallel and
    constraint singularity measures).
    """
    robot = resolve_robot(robot)  # a preset name or a TOML path too
    if is_spatial(robot):
        check_angle_values(rotation_angles(poses), "poses[..., 3:] (rotation vectors)")
        return _spatial.singularity(robot, poses)
    check_orientations(poses, "poses", poses=True)
    poses = as_poses(poses)
    ik = inverse_kinematics(robot, poses)
    A_inv, det = inverse_3x3(ik.A)
    return Singularity(det=det, condition=_condition(robot, ik.A, A_inv),
                       transmission=_transmission(robot, ik, poses))


def regular_mask(robot: Manipulator, poses: np.ndarray, max_condition: float = DEFAULT_MAX_CONDITION) -> np.ndarray:
    """True where the pose is far enough from both singularities (condition <= max, transmission >= 1/max)."""
    sing = singularity(robot, poses)
    return (sing.condition <= max_condition) & np.all(sing.transmission >= 1.0 / max_condition, axis=-1)


def _raise_singular(robot: Manipulator, poses: np.ndarray, ok: np.ndarray, cond: np.ndarray,
                    max_condition: float) -> None:
    idx = tuple(int(i) for i in np.argwhere(~ok)[0])
    x, y, phi = poses[idx]
    raise SingularPoseError(
        f"pose (x={x:g} mm, y={y:g} mm, phi={np.degrees(phi):g} deg) is at or near a parallel "
        f"singularity (det A ~ 0, condition number {float(cond[idx]):.3g} > {max_condition:g})")


def _raise_serial(poses: np.ndarray, trans: np.ndarray, max_condition: float) -> None:
    bad = trans < 1.0 / max_condition
    idx = tuple(int(i) for i in np.argwhere(np.any(bad, axis=-1))[0])
    leg = int(np.argmax(bad[idx])) + 1
    x, y, phi = poses[idx]
    raise SingularPoseError(
        f"pose (x={x:g} mm, y={y:g} mm, phi={np.degrees(phi):g} deg) is at or near a serial singularity of "
        f"leg {leg} (B_{leg}{leg} ~ 0, transmission index {float(trans[idx][leg - 1]):.3g} < "
        f"{1.0 / max_condition:g})")


def require_regular(robot: Manipulator, poses: np.ndarray, max_condition: float = DEFAULT_MAX_CONDITION) -> None:
    """Raise :class:`SingularPoseError` naming the first pose at or near det A = 0 or B_ii = 0."""
    poses = as_poses(poses)
    sing = singularity(robot, poses)
    ok = sing.condition <= max_condition
    if not np.all(ok):
        _raise_singular(robot, poses, ok, sing.condition, max_condition)
    if np.any(sing.transmission < 1.0 / max_condition):
        _raise_serial(poses, sing.transmission, max_condition)


def regular_inverse(robot: Manipulator, A: np.ndarray, poses: np.ndarray,
                    max_condition: float = DEFAULT_MAX_CONDITION) -> np.ndarray:
    """``A^-1`` ``(..., 3, 3)``, raising :class:`SingularPoseError` where A is (nearly) singular."""
    A_inv, _ = inverse_3x3(A)
    cond = _condition(robot, A, A_inv)
    ok = cond <= max_condition
    if not np.all(ok):
        _raise_singular(robot, poses, ok, cond, max_condition)
    return A_inv


def check_within_limits(robot: Manipulator, poses: np.ndarray, ik: IKSolution,
                        tol: float = LIMIT_TOLERANCE) -> None:
    """Raise :class:`OutsideJointLimitsError` naming the first pose outside the ranges, and its joints.

    ``ik`` is anything with ``joints`` (``(..., 3, 3)``) and ``within_limits`` (an
    :class:`IKSolution` or a :class:`pmaccuracy.accuracy.error_model.PoseState`). For a
    3-PPR the joints are named as in the paper (``s1``, ``l2``, ...).
    """
    if np.all(ik.within_limits):
        return
    idx = tuple(int(i) for i in np.argwhere(~ik.within_limits)[0])
    x, y, phi = np.asarray(poses, float)[idx]
    joints = ik.joints[idx]
    parts = []
    names = ("s", "l", None) if robot.is_3ppr else None
    for i, chain in enumerate(robot.chains):
        for k, joint in enumerate(chain.joints):
            v = joints[i, k]
            if not np.isfinite(v):
                parts.append(f"leg {i + 1} cannot reach the pose")
                break
            if joint.within(v, tol):
                continue
            lo, hi = joint.range
            if joint.kind == "R":
                label = f"leg {i + 1} joint {k + 1}"
                parts.append(f"{label}={np.degrees(wrap(v)):.4g} deg not in [{np.degrees(lo):g}, {np.degrees(hi):g}]")
            else:
                label = f"{names[k]}{i + 1}" if names and names[k] else f"leg {i + 1} joint {k + 1}"
                parts.append(f"{label}={v:.4g} mm not in [{lo:g}, {hi:g}]")
    raise OutsideJointLimitsError(
        f"pose (x={x:g} mm, y={y:g} mm, phi={np.degrees(phi):g} deg) is outside the joint ranges: "
        + ", ".join(parts))


def require_within_limits(robot: Manipulator, poses: np.ndarray, tol: float = LIMIT_TOLERANCE) -> IKSolution:
    """Inverse kinematics, raising :class:`OutsideJointLimitsError` for the first pose outside the ranges."""
    ik = inverse_kinematics(robot, poses, tol)
    check_within_limits(robot, poses, ik, tol)
    return ik


def kinematic_jacobian(robot: Manipulator, poses: np.ndarray,
                       max_condition: float = DEFAULT_MAX_CONDITION) -> np.ndarray:
    """``J = A^-1 B`` (Eq. 5), ``(..., 3, 3)``: ``[dx, dy, dphi] = J dq``. Refuses singular poses."""
    check_orientations(poses, "poses", poses=True)
    robot = resolve_robot(robot)  # a preset name or a TOML path too
    A, B = jacobians(robot, poses)
    return regular_inverse(robot, A, poses, max_condition) @ B
