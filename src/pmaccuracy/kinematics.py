"""Inverse and forward kinematics, Jacobians and singularities (paper Sec. 3, Eq. 1-5).

Poses are arrays of shape ``(..., 3)`` holding ``[x, y, phi]`` (mm, mm, rad);
every function broadcasts over the leading axes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import NoSolutionError, OutsideJointLimitsError, PoseError, SingularPoseError
from .geometry import Manipulator, perp, unit

#: A pose computed on the workspace boundary must count as inside: joint limits get this slack (mm).
LIMIT_TOLERANCE = 1e-9
#: Poses whose homogenized A (Eq. 4a) has a larger condition number are refused as (near-)singular.
#: 100 (a dexterity 1/cond below 0.01) refuses aalborg_3ppr within about 1 deg of phi = +-90 deg, where the
#: first-order bounds are already amplified ~20 times over phi = 0 and the linear model stops being meaningful.
DEFAULT_MAX_CONDITION = 100.0


def as_poses(poses: np.ndarray | list, *, name: str = "pose") -> np.ndarray:
    """Check and convert poses to a float array of shape ``(..., 3)``; non-finite values raise PoseError."""
    arr = np.asarray(poses, dtype=float)
    if arr.ndim == 0 or arr.shape[-1] != 3:
        raise PoseError(f"{name}s must have shape (..., 3) = [x mm, y mm, phi rad], got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.all(np.isfinite(arr), axis=-1))[0]
        raise PoseError(f"{name} {tuple(int(i) for i in bad)} is not finite: {arr[tuple(bad)].tolist()}")
    return arr


@dataclass(frozen=True)
class IKSolution:
    """Joint values of a batch of poses (Eq. 2a, 2b).

    Attributes
    ----------
    s, l : arrays ``(..., 3)``, mm
        Actuated and passive prismatic joint values of legs 1-3.
    within_limits : bool array ``(...)``
        All six joints inside their ranges (with :data:`LIMIT_TOLERANCE`).
    """

    s: np.ndarray
    l: np.ndarray
    within_limits: np.ndarray


def loop_vectors(robot: Manipulator, poses: np.ndarray) -> np.ndarray:
    """``q_i = p - a_i h_i - d_i v_i - r_i k_i = s_i u_i + l_i w_i`` (mm), shape ``(..., 3, 2)``."""
    poses = np.asarray(poses, dtype=float)
    k = unit(poses[..., None, 2] + robot.psi)
    return (poses[..., None, :2] - robot.base_points - robot.d[:, None] * robot.v - robot.r[:, None] * k)


def within_joint_limits(robot: Manipulator, s: np.ndarray, l: np.ndarray,
                        tol: float = LIMIT_TOLERANCE) -> np.ndarray:
    """True where every ``s_i`` and ``l_i`` lies in its range (slack ``tol`` mm); shape ``(...)``."""
    s_ok = (s >= robot.s_range[:, 0] - tol) & (s <= robot.s_range[:, 1] + tol)
    l_ok = (l >= robot.l_range[:, 0] - tol) & (l <= robot.l_range[:, 1] + tol)
    return np.all(s_ok & l_ok, axis=-1)


def inverse_kinematics(robot: Manipulator, poses: np.ndarray, tol: float = LIMIT_TOLERANCE) -> IKSolution:
    """Joint values for poses (Eq. 2a, 2b).

    With ``q_i = s_i u_i + l_i w_i`` (:func:`loop_vectors`) and ``E`` the
    right-angle rotation, ``w^T E w = 0`` eliminates ``l_i``::

        s_i = (w_i^T E u_i)^-1 w_i^T E q_i        (Eq. 2a)
        l_i = (u_i^T E w_i)^-1 u_i^T E q_i        (Eq. 2b)

    The denominators are ``+-sin(gamma_i + theta_i)``, which the geometry
    keeps away from zero, so the inverse kinematics is defined everywhere.

    Parameters
    ----------
    poses : array ``(..., 3)``, ``[x mm, y mm, phi rad]``
    """
    poses = as_poses(poses)
    q = loop_vectors(robot, poses)
    w_E_u = np.sum(robot.w * perp(robot.u), axis=-1)  # w^T E u, shape (3,)
    u_E_w = np.sum(robot.u * perp(robot.w), axis=-1)  # u^T E w = -w^T E u
    s = np.sum(robot.w * perp(q), axis=-1) / w_E_u
    l = np.sum(robot.u * perp(q), axis=-1) / u_E_w
    return IKSolution(s=s, l=l, within_limits=within_joint_limits(robot, s, l, tol))


@dataclass(frozen=True)
class FKSolution:
    """Every assembly mode for a batch of actuator values (at most two).

    Attributes
    ----------
    poses : ``(..., 2, 3)``  [x mm, y mm, phi rad], NaN where a mode does not exist
    valid : bool ``(..., 2)``
    l : ``(..., 2, 3)`` passive joint values (mm), NaN where invalid
    within_limits : bool ``(..., 2)`` valid and all joints inside their ranges
    """

    poses: np.ndarray
    valid: np.ndarray
    l: np.ndarray
    within_limits: np.ndarray

    def nearest(self, reference: np.ndarray, angle_weight: float = 100.0) -> np.ndarray:
        """The assembly mode nearest to ``reference`` poses ``(..., 3)``; raises if none exists.

        Distance: ``|dp|^2 + (angle_weight * dphi)^2`` with ``angle_weight`` in mm/rad.
        """
        reference = np.asarray(reference, dtype=float)
        if np.any(np.all(~self.valid, axis=-1)):
            raise NoSolutionError("forward kinematics has no assembly mode for some actuator values")
        dphi = np.angle(np.exp(1j * (self.poses[..., 2] - reference[..., None, 2])))
        dist = np.sum((self.poses[..., :2] - reference[..., None, :2]) ** 2, axis=-1) + (angle_weight * dphi) ** 2
        idx = np.argmin(np.where(self.valid, dist, np.inf), axis=-1)
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


def forward_kinematics(robot: Manipulator, s: np.ndarray, tol: float = LIMIT_TOLERANCE) -> FKSolution:
    """Every pose reachable with actuator values ``s`` ``(..., 3)`` mm (analytic, at most two).

    ``c_i = a_i h_i + s_i u_i + d_i v_i`` is fixed once ``s`` is, and
    :func:`solve_loop_closure` solves Eq. 1 for the pose.
    """
    s = np.asarray(s, dtype=float)
    if s.ndim == 0 or s.shape[-1] != 3:
        raise PoseError(f"actuator values must have shape (..., 3), got {s.shape}")
    if not np.all(np.isfinite(s)):
        raise PoseError("actuator values must be finite")
    c = robot.base_points + s[..., None] * robot.u + robot.d[:, None] * robot.v
    poses, valid, l = solve_loop_closure(c, robot.w, robot.r, robot.psi)
    s_ok = np.all((s >= robot.s_range[:, 0] - tol) & (s <= robot.s_range[:, 1] + tol), axis=-1)
    l_ok = np.all((l >= robot.l_range[:, 0] - tol) & (l <= robot.l_range[:, 1] + tol), axis=-1)
    return FKSolution(poses=poses, valid=valid, l=l, within_limits=valid & l_ok & s_ok[..., None])


def jacobians(robot: Manipulator, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Forward and backward Jacobians ``A`` and ``B`` (Eq. 3, 4a, 4b), each ``(..., 3, 3)``.

    ``A [p_dot; phi_dot] = B s_dot`` with rows
    ``A_i = [w_i^T E^T, -r_i w_i^T k_i]`` (units 1, 1, mm) and
    ``B = diag(w_i^T E^T u_i)`` (constant: the paper's 3-PPR has no serial singularity).
    """
    poses = as_poses(poses)
    k = unit(poses[..., None, 2] + robot.psi)
    n = perp(robot.w)  # rows (E w_i)^T = w_i^T E^T
    A = np.empty(poses.shape[:-1] + (3, 3))
    A[..., :2] = n
    A[..., 2] = -robot.r * np.sum(robot.w * k, axis=-1)
    B = np.zeros(poses.shape[:-1] + (3, 3))
    idx = np.arange(3)
    B[..., idx, idx] = np.sum(n * robot.u, axis=-1)
    return A, B


def inverse_3x3(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse and determinant of a batch of 3x3 matrices ``(..., 3, 3)`` by cofactors.

    Unlike ``np.linalg.inv`` it never raises: an exactly singular matrix gives
    non-finite entries, which the callers refuse.
    """
    a, b, c = M[..., 0, 0], M[..., 0, 1], M[..., 0, 2]
    d, e, f = M[..., 1, 0], M[..., 1, 1], M[..., 1, 2]
    g, h, i = M[..., 2, 0], M[..., 2, 1], M[..., 2, 2]
    cof = np.stack([
        np.stack([e * i - f * h, c * h - b * i, b * f - c * e], axis=-1),
        np.stack([f * g - d * i, a * i - c * g, c * d - a * f], axis=-1),
        np.stack([d * h - e * g, b * g - a * h, a * e - b * d], axis=-1),
    ], axis=-2)
    det = a * cof[..., 0, 0] + b * cof[..., 1, 0] + c * cof[..., 2, 0]
    # A determinant at rounding level relative to the rows' sizes (e.g. rank 1, where the cofactors are
    # noise too) is an exact singularity: make it 0 so the inverse is non-finite rather than plausible.
    row_norms = np.prod(np.linalg.norm(M, axis=-1), axis=-1)
    det = np.where(np.abs(det) <= 1e-13 * row_norms, 0.0, det)
    with np.errstate(divide="ignore", invalid="ignore"):
        return cof / det[..., None, None], det


@dataclass(frozen=True)
class Singularity:
    """Distance to the parallel singularity ``det A = 0``.

    det : ``(...)`` mm, determinant of A (its third column is a length).
    condition : ``(...)`` 1-norm condition number ``||A_h||_1 ||A_h^-1||_1`` of
        A with its third column divided by :attr:`Manipulator.characteristic_length`
        (dimensionless, >= 1; ``inf`` where A is exactly singular).

    For a 3-PPR the first two columns of A are constant (``E w_i``) and the
    third depends on phi only, so the singularity is a set of orientations
    (phi = +-90 deg for both presets), whatever x and y.
    """

    det: np.ndarray
    condition: np.ndarray


def _condition(robot: Manipulator, A: np.ndarray, A_inv: np.ndarray) -> np.ndarray:
    L = robot.characteristic_length
    scale = np.array([1.0, 1.0, 1.0 / L])
    norm_Ah = np.max(np.sum(np.abs(A * scale), axis=-2), axis=-1)
    norm_Ah_inv = np.max(np.sum(np.abs(A_inv / scale[:, None]), axis=-2), axis=-1)
    cond = norm_Ah * norm_Ah_inv
    return np.where(np.isfinite(cond), cond, np.inf)


def singularity(robot: Manipulator, poses: np.ndarray) -> Singularity:
    """det A and the condition number of the homogenized A at each pose (Eq. 4a)."""
    A, _ = jacobians(robot, poses)
    A_inv, det = inverse_3x3(A)
    return Singularity(det=det, condition=_condition(robot, A, A_inv))


def regular_mask(robot: Manipulator, poses: np.ndarray, max_condition: float = DEFAULT_MAX_CONDITION) -> np.ndarray:
    """True where the pose is far enough from the parallel singularity (condition <= max_condition)."""
    return singularity(robot, poses).condition <= max_condition


def _raise_singular(robot: Manipulator, poses: np.ndarray, ok: np.ndarray, cond: np.ndarray,
                    max_condition: float) -> None:
    idx = tuple(int(i) for i in np.argwhere(~ok)[0])
    x, y, phi = poses[idx]
    raise SingularPoseError(
        f"pose (x={x:g} mm, y={y:g} mm, phi={np.degrees(phi):g} deg) is at or near a parallel "
        f"singularity (det A ~ 0, condition number {float(cond[idx]):.3g} > {max_condition:g})")


def require_regular(robot: Manipulator, poses: np.ndarray, max_condition: float = DEFAULT_MAX_CONDITION) -> None:
    """Raise :class:`SingularPoseError` naming the first pose at or near det A = 0."""
    poses = as_poses(poses)
    cond = singularity(robot, poses).condition
    ok = cond <= max_condition
    if not np.all(ok):
        _raise_singular(robot, poses, ok, cond, max_condition)


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

    ``ik`` is anything with ``s``, ``l`` and ``within_limits`` (an :class:`IKSolution`
    or a :class:`pmaccuracy.error_model.PoseState`).
    """
    if np.all(ik.within_limits):
        return
    idx = tuple(int(i) for i in np.argwhere(~ik.within_limits)[0])
    x, y, phi = np.asarray(poses, float)[idx]
    s, l = ik.s[idx], ik.l[idx]
    parts = []
    for i in range(3):
        lo, hi = robot.s_range[i]
        if not lo - tol <= s[i] <= hi + tol:
            parts.append(f"s{i + 1}={s[i]:.4g} mm not in [{lo:g}, {hi:g}]")
        lo, hi = robot.l_range[i]
        if not lo - tol <= l[i] <= hi + tol:
            parts.append(f"l{i + 1}={l[i]:.4g} mm not in [{lo:g}, {hi:g}]")
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
    """``J = A^-1 B`` (Eq. 5), ``(..., 3, 3)``: ``[dx, dy, dphi] = J ds``. Refuses singular poses."""
    A, B = jacobians(robot, poses)
    return regular_inverse(robot, A, poses, max_condition) @ B
