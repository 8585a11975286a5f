"""Identification of a spatial robot's error parameters from full-pose or position-only readings.

Residual of reading ``n`` (forward, in the device's frame; :mod:`.spatial_parameters` for the model):

* full pose: ``[m_p - (t_F + R_F p), log(R_m (R_F R)^T)]`` (mm, rad; ``log`` the rotation vector), 6 numbers;
* position only, target ``k``: ``m - (t_F + R_F (p + R s_k))`` (mm), 3 numbers;

each divided by its stated 1-sigma (whitened). ``(p, R)`` is the forward kinematics of the robot with the
parameters at the actuated values ``q = offset + gain * c`` (Newton on the closure, warm-started at the
previous evaluation's poses).

Jacobian, through the closure: at the pose, the closure equations ``e(pose, q, theta) = 0`` give the
platform twist per parameter ``t = -W^-1 de/dtheta`` (``W`` the closure wrenches). ``de/dq`` is ``-G`` (the
closure's gains), so ``de/d offset_i = -G_i`` and ``de/d gain_i = -G_i c_i``; the derivatives of a leg's
closure with respect to its joint centres and lengths are central differences of that leg's closure
equations alone (smooth, closed-form: error ~1e-10 relative), not of the forward kinematics; a 6-UPS leg's
in closed form (``de/dA = -u``, ``de/db = R^T u``, ``u`` the unit vector along the leg). Then
``d(t_F + R_F x) = R_F (v + w x (x - p))`` for the platform point ``x``, ``d log(R_F R) = R_F w``, and the
frame's own derivatives ``dm/dt_F = I``, ``dm/dr_F = -[R_F x]x J_l(r_F)``, ``d log/dr_F = J_l(r_F)``
(``J_l`` the left Jacobian of SO(3)).

Clearances (``clearances``, as the planar identification's): each reading's covariance is ``Sigma_n =
diag(sigma_n^2) + C_n`` with ``C_n`` the first-order covariance of the clearance states at the pose the model
robot takes there (:func:`clearance_covariance`: the error sources uniform in their sets, independent from
reading to reading), and the residual and its Jacobian are whitened by ``L_n^-1`` (``L_n L_n^T = Sigma_n``,
Cholesky) instead of the stated sigmas; ``Sigma_n`` is taken at the start and again after the robust pass.

Fit: as the planar identification (:mod:`.identify`): the parameters :func:`~.identifiability.analyse`
keeps (the others fixed at nominal and reported with their combinations in words), a robust pass with
the ``soft_l1`` loss at :data:`~.identify.ROBUST_F_SCALE` stated sigmas (started from a plain least-squares
fit: from parameter errors of tens of sigmas the robust loss alone, linear there, made little progress), an
outlier test of every reading
(``chi2_n = |e_n|^2`` against the chi-square(k) :data:`~.identify.OUTLIER_QUANTILE` quantile, ``k`` = 6 or
3, widened by the median ratio when it exceeds :data:`~.identify.UNDERSTATED`), then plain least squares on
the readings kept, repeated until the kept set no longer changes. Covariance ``s^2 (J^T J)^-1`` with
``s^2 = |e|^2 / (m - L)`` (:func:`~.identify.covariance`). Before all this the frame is started from the
best rigid fit (Kabsch) of the nominal robot's predicted points to the measured ones, so a device placed
anywhere is found.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats
from threadpoolctl import threadpool_limits

from ...errors import ConfigError, MeasurementFileError, PoseError
from ...kinematics.spatial import closure, forward_kinematics
from ...model.spatial_chain import ChainLeg
from ...model.spatial_sources import SpatialErrorSources
from ...model.spatial_legs import UPSLeg
from ...numerics.spatial import normalize, rotations, rotvecs, skew
from ..spatial_bounds import error_sources_at
from .identifiability import PRACTICAL_MAX_SIGMA, RTOL, Identifiability, analyse
from .identify import MAX_ROUNDS, OUTLIER_QUANTILE, ROBUST_F_SCALE, UNDERSTATED, UNREACHABLE, covariance
from .spatial_parameters import (SpatialManipulator, SpatialParameterVector, _leg_fields, set_leg_values,
                                 spatial_error_parameters)

#: Default 1-sigma of a reading: 0.01 mm, 0.01 deg.
DEFAULT_SIGMA_MM = 0.01
DEFAULT_SIGMA_RAD = np.radians(0.01)


@dataclass(frozen=True, eq=False)
class SpatialCalibrationData:
    """Readings of a spatial robot.

    Attributes
    ----------
    labels : tuple of str ``(N,)``
        Point labels.
    commands : ndarray ``(N, n)``
        Commanded actuator values (mm, or rad for a Delta's arms).
    measured : ndarray ``(N, 6)`` or ``(N, 3)``
        Full pose ``[x, y, z mm, rotation vector rad]`` in the device's frame, or the position (mm) of target
        ``target[n]``.
    sigmas : ndarray, the shape of ``measured``
        1-sigma of each component (mm; rad for the rotation vector's).
    target : ndarray of int ``(N,)``
        Target (0-based) of a position reading (zeros for full poses).
    source : str
        The file read (for messages).
    """

    labels: tuple[str, ...]
    commands: np.ndarray
    measured: np.ndarray
    sigmas: np.ndarray
    target: np.ndarray
    source: str = "<data>"

    def __len__(self) -> int:
        return len(self.labels)

    def __repr__(self) -> str:
        return f"SpatialCalibrationData({len(self)} {self.kind} readings from {self.source!r})"

    @property
    def kind(self) -> str:
        """``"pose"`` or ``"position"``."""
        return "pose" if self.measured.shape[1] == 6 else "position"

    def subset(self, keep) -> "SpatialCalibrationData":
        """The readings ``keep`` (bool or indices)."""
        keep = np.asarray(keep)
        return SpatialCalibrationData(tuple(np.asarray(self.labels, dtype=object)[keep]), self.commands[keep],
                                      self.measured[keep], self.sigmas[keep], self.target[keep], self.source)


# ---------------------------------------------------------------------------------------------- model
def left_jacobian(r) -> np.ndarray:
    """The left Jacobian of SO(3) ``J_l(r)``, ``(..., 3) -> (..., 3, 3)``: ``exp([r + dr]x) = exp([J_l dr]x)
    exp([r]x)`` to first order; ``J_l = I + (1 - cos a)/a^2 [r]x + (a - sin a)/a^3 [r]x^2``, ``a = |r|``
    (series below ``a = 1e-4``)."""
    r = np.asarray(r, dtype=float)
    a = np.linalg.norm(r, axis=-1)[..., None, None]
    K = skew(r)
    small = a < 1e-4
    safe = np.where(small, 1.0, a)
    c1 = np.where(small, 0.5 - a ** 2 / 24, (1 - np.cos(safe)) / safe ** 2)
    c2 = np.where(small, 1.0 / 6 - a ** 2 / 120, (safe - np.sin(safe)) / safe ** 3)
    return np.eye(3) + c1 * K + c2 * (K @ K)


def platform_poses(pv: SpatialParameterVector, values, commands, guess=None) -> np.ndarray:
    """Poses ``(N, 6)`` (base frame, ``[p mm, rotvec rad]``) of the robot ``values`` at ``commands (N, n)``:
    Newton forward kinematics from ``guess`` (``(N, 6)``; default the home pose); NaN rows where it does not
    converge."""
    robot, off, gain, _, _ = pv.split(values)
    q = off + gain * np.asarray(commands, dtype=float)
    return forward_kinematics(robot, q, guess).poses


def predict(pv: SpatialParameterVector, values, poses, target=None) -> np.ndarray:
    """What the device reads for platform poses ``(N, 6)``: ``(N, 6)`` full poses ``[t_F + R_F p,
    log(R_F R)]`` or, with ``target (N,)`` (0-based, position-only ``pv``), ``(N, 3)`` points
    ``t_F + R_F (p + R s_k)`` (mm, rad)."""
    values = np.asarray(values, dtype=float)
    poses = np.asarray(poses, dtype=float)
    bad = ~np.all(np.isfinite(poses), axis=1)
    if np.any(bad):
        out = predict(pv, values, np.where(bad[:, None], 0.0, poses), target)
        out[bad] = np.nan
        return out
    frame = values[pv.frame_index]
    RF = rotations(frame[3:])
    R = rotations(poses[:, 3:])
    if pv.kind == "pose":
        return np.concatenate([frame[:3] + poses[:, :3] @ RF.T, rotvecs(RF @ R)], axis=1)
    s = values[pv.tool_index][np.asarray(target, dtype=int)]
    x = poses[:, :3] + np.einsum("nij,nj->ni", R, s)
    return frame[:3] + x @ RF.T


def residuals(pv: SpatialParameterVector, values, data: SpatialCalibrationData, poses) -> np.ndarray:
    """Raw residuals ``measured - predicted`` ``(N, k)`` at the platform ``poses (N, 6)`` (module docstring;
    the orientation part ``log(R_m (R_F R)^T)``)."""
    pred = predict(pv, values, poses, data.target)
    if pv.kind == "position":
        return data.measured - pred
    bad = ~np.isfinite(pred[:, 3])
    rot = rotvecs(rotations(data.measured[:, 3:]) @ np.swapaxes(rotations(np.where(bad[:, None], 0.0,
                                                                                    pred[:, 3:])), -1, -2))
    rot[bad] = np.nan
    return np.concatenate([data.measured[:, :3] - pred[:, :3], rot], axis=1)


def _closure_partials(robot: SpatialManipulator, pv: SpatialParameterVector, poses, q, values, leg_rows):
    """``de/dtheta`` ``(N, 6, P)`` of the closure for the legs' geometric parameters: a 6-UPS leg's in closed
    form (``e = |p + R b - A| - q``: ``de/dA = -u``, ``de/db = R^T u``), the other legs' by central differences
    of that leg's closure alone, a chain leg's (:meth:`~pmaccuracy.model.spatial_chain.ChainLeg.variant_closures`)
    at its own passive solution (the closure rows ``e = W xi`` change by ``W dxi`` at fixed freedoms: ``W`` is
    reciprocal to the passive ones)."""
    N = len(poses)
    E = np.zeros((N, 6, len(pv.names)))
    p, r = poses[:, :3], poses[:, 3:]
    R = rotations(r)
    for i, (leg, nominal, sl) in enumerate(zip(robot.legs, pv.robot.legs, pv.leg_slices)):
        fields = _leg_fields(nominal)
        base = values[sl]
        rows = leg_rows[i]
        if type(leg) is UPSLeg:      # e = |p + R b - A| - q: de/dA = -u, de/db = R^T u (u along the leg)
            u = normalize(p + R @ np.asarray(leg.platform) - np.asarray(leg.base))
            E[:, rows[0], sl.start:sl.start + 3] = -u
            E[:, rows[0], sl.start + 3:sl.start + 6] = np.einsum("nji,nj->ni", R, u)
            continue
        steps = [1e-5 * max(1.0, abs(b)) for b in base]
        variants = []
        for j, h in enumerate(steps):
            for sign in (1.0, -1.0):
                v = base.copy()
                v[j] += sign * h
                variants.append(set_leg_values(nominal, fields, v))
        if isinstance(leg, ChainLeg):
            vals = leg.variant_closures(p, R, q[:, i], variants)
        else:
            vals = [v.closure(p, R, r, q[:, i])[0] for v in variants]
        for j, h in enumerate(steps):
            E[:, rows, sl.start + j] = (vals[2 * j] - vals[2 * j + 1]) / (2 * h)
    return E


def residual_jacobian(pv: SpatialParameterVector, values, data: SpatialCalibrationData, poses) -> np.ndarray:
    """``d residual / d theta`` ``(N, k, P)`` (:func:`residuals`): ``-`` :func:`measurement_jacobian`, the
    orientation rows of full-pose data times ``J_r(rho)^-1`` (``rho`` the orientation residual, ``J_r(rho) =
    J_l(-rho)``: ``exp([rho]x) exp(-[d]x) = exp([rho - J_r^-1 d]x)``), exact also away from the solution."""
    J = -measurement_jacobian(pv, values, data, poses)
    if pv.kind == "pose":
        rho = residuals(pv, values, data, poses)[:, 3:]
        with np.errstate(all="ignore"):
            J[:, 3:] = np.linalg.solve(left_jacobian(-np.where(np.isfinite(rho), rho, 0.0)), J[:, 3:])
    return J


def measurement_jacobian(pv: SpatialParameterVector, values, data: SpatialCalibrationData, poses) -> np.ndarray:
    """``d predicted / d theta`` ``(N, k, P)`` at the platform ``poses (N, 6)`` (module docstring: through the
    closure, ``t = -W^-1 de/dtheta``). Rows of NaN poses are NaN."""
    values = np.asarray(values, dtype=float)
    robot, off, gain, frame, tools = pv.split(values)
    c = np.asarray(data.commands, dtype=float)
    q = off + gain * c
    cl = closure(robot, poses, q)
    leg_rows = [np.flatnonzero(cl.leg_of_row == i) for i in range(robot.n_legs)]
    E = _closure_partials(robot, pv, poses, q, values, leg_rows)
    oi, gi = pv.actuator_index
    E[:, :, oi] = -cl.gains
    E[:, :, gi] = -cl.gains * c[:, None, :]
    with np.errstate(all="ignore"):
        T = -np.linalg.solve(cl.wrenches, E)                    # (N, 6, P): twist per parameter
    RF = rotations(frame[3:])
    Jl = left_jacobian(frame[3:])
    N, P = len(poses), len(pv.names)
    if pv.kind == "pose":
        out = np.empty((N, 6, P))
        out[:, :3] = RF @ T[:, :3]
        out[:, 3:] = RF @ T[:, 3:]
        x = poses[:, :3]
    else:
        R = rotations(poses[:, 3:])
        k = np.asarray(data.target, dtype=int)
        arm = np.einsum("nij,nj->ni", R, tools[k])                      # R s (N, 3)
        dx = T[:, :3] - skew(arm) @ T[:, 3:]                              # v + w x (R s)
        out = RF @ dx
        x = poses[:, :3] + arm
        for t in range(pv.n_targets):
            sel = k == t
            out[np.ix_(sel, np.arange(3), pv.tool_index[t])] = RF @ R[sel]
    fi = pv.frame_index
    out[:, :3, fi[:3]] = np.eye(3)
    out[:, :3, fi[3:]] = -skew(x @ RF.T) @ Jl
    if pv.kind == "pose":
        out[:, 3:, fi[:3]] = 0.0
        out[:, 3:, fi[3:]] = Jl
    return out


# ---------------------------------------------------------------------------------------------- problem
class _Model:
    """The whitened residual and its Jacobian over the free parameters, with warm-started forward kinematics."""

    def __init__(self, pv: SpatialParameterVector, data: SpatialCalibrationData, x0: np.ndarray, free: np.ndarray):
        self.pv, self.data, self.x0, self.free = pv, data, np.asarray(x0, dtype=float), np.asarray(free)
        self.guess = None
        self.cache: dict = {}
        self.W: np.ndarray | None = None      # (N, k, k) whitening with clearances; None: the stated sigmas

    def values(self, z) -> np.ndarray:
        v = self.x0.copy()
        v[self.free] = z
        return v

    def poses(self, v) -> np.ndarray:
        key = v.tobytes()
        if key in self.cache:
            return self.cache[key]
        with np.errstate(all="ignore"):   # a trial step far out: no forward kinematics (NaN), not a warning
            poses = platform_poses(self.pv, v, self.data.commands, self.guess)
            bad = ~np.all(np.isfinite(poses), axis=1)
            if np.any(bad) and self.guess is not None:       # retry from home where the warm start failed
                poses[bad] = platform_poses(self.pv, v, self.data.commands[bad])
        ok = np.all(np.isfinite(poses), axis=1)
        if self.guess is None:
            self.guess = np.where(ok[:, None], poses, self.pv.robot.home_pose)
        else:
            self.guess = np.where(ok[:, None], poses, self.guess)
        self.cache = {key: poses}
        return poses

    def whitened(self, v, keep) -> np.ndarray:
        poses = self.poses(v)
        e = whiten(residuals(self.pv, v, self.data, poses), self.data.sigmas, self.W)
        return e[keep]

    def fun(self, keep):
        def f(z):
            e = self.whitened(self.values(z), keep)
            return np.where(np.isfinite(e), e, UNREACHABLE).ravel()
        return f

    def jac(self, keep):
        def j(z):
            v = self.values(z)
            poses = self.poses(v)
            sub = self.data.subset(keep)
            J = residual_jacobian(self.pv, v, sub, poses[keep])[:, :, self.free]
            J = J / sub.sigmas[:, :, None] if self.W is None else np.einsum("nij,njl->nil", self.W[keep], J)
            return np.where(np.isfinite(J), J, 0.0).reshape(-1, len(self.free))
        return j

    def chi2(self, v) -> np.ndarray:
        e = self.whitened(v, slice(None))
        out = np.sum(e ** 2, axis=1)
        return np.where(np.isfinite(out), out, np.inf)


def whiten(r, sigmas, W=None) -> np.ndarray:
    """Whitened residuals ``(N, k)``: ``r / sigmas``, or ``W_n r_n`` with the whitening ``W (N, k, k)``."""
    return r / sigmas if W is None else np.einsum("nij,nj->ni", W, r)


def clearance_covariance(pv: SpatialParameterVector, values, data: SpatialCalibrationData, poses,
                         clearances) -> np.ndarray:
    """``C (N, k, k)``: first-order covariance (mm^2, mm rad, rad^2) of what the device reads, from one clearance
    state per reading at the platform ``poses (N, 6)`` of the robot ``values``: the twist covariance
    ``S = sum_s M_s M_s^T / (d_s + 2)`` (Eq. 1 of :mod:`pmaccuracy.accuracy.spatial_bounds`, every source
    uniform in its unit set of dimension ``d_s``) carried to the reading, ``A S A^T`` with ``A = diag(R_F, R_F)``
    (full pose) or ``R_F [I, -[R s_k]x]`` (target ``k``). Zero where the pose is NaN or near a singularity."""
    robot, _, _, frame, tools = pv.split(values)
    sources = SpatialErrorSources.load(clearances, robot)
    poses = np.asarray(poses, dtype=float)
    k = 6 if pv.kind == "pose" else 3
    C = np.zeros((len(poses), k, k))
    ok = np.all(np.isfinite(poses), axis=1)
    if not ok.any():
        return C
    _, info = error_sources_at(robot, sources, poses[ok], strict=False, keep=True, allow_outside=True)
    S = np.zeros((int(ok.sum()), 6, 6))
    for src in info["sources"]:
        M = src.matrix
        S += np.einsum("nid,njd->nij", M, M) / (M.shape[-1] + 2)
    S[~info["valid"]] = 0.0
    RF = rotations(frame[3:])
    if pv.kind == "pose":
        A = np.zeros((6, 6))
        A[:3, :3] = A[3:, 3:] = RF
        C[ok] = A @ S @ A.T
    else:
        arm = np.einsum("nij,nj->ni", rotations(poses[ok, 3:]), tools[np.asarray(data.target, dtype=int)[ok]])
        B = np.concatenate([np.broadcast_to(np.eye(3), arm.shape + (3,)), -skew(arm)], axis=2)
        A = RF @ B
        C[ok] = A @ S @ np.swapaxes(A, 1, 2)
    return C


def _whitening(pv, values, data, poses, clearances) -> np.ndarray:
    """``L^-1 (N, k, k)`` with ``L L^T = diag(sigma^2) + C`` (:func:`clearance_covariance`)."""
    Sig = np.einsum("ni,ij->nij", data.sigmas ** 2, np.eye(data.sigmas.shape[1]))
    Sig = Sig + clearance_covariance(pv, values, data, poses, clearances)
    return np.linalg.inv(np.linalg.cholesky(Sig))


def kabsch_frame(model_points, measured_points) -> np.ndarray:
    """The frame ``[t, r]`` (6,) of the best rigid fit ``measured ~ t + R(r) model`` (Kabsch, least squares)
    of points ``(N, 3)``; rows with NaN are skipped; identity with fewer than 3 usable points."""
    a, b = np.asarray(model_points, dtype=float), np.asarray(measured_points, dtype=float)
    ok = np.all(np.isfinite(a), axis=1) & np.all(np.isfinite(b), axis=1)
    if ok.sum() < 3:
        return np.zeros(6)
    a, b = a[ok], b[ok]
    ca, cb = a.mean(0), b.mean(0)
    U, _, Vt = np.linalg.svd((a - ca).T @ (b - cb))
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    R = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
    return np.concatenate([cb - R @ ca, rotvecs(R[None])[0]])


#: The frame starts at the rigid fit only when that is further than this (mm, rad) from the nominal frame
#: (else at the nominal: the fixed frame parameters then keep their nominal values).
START_FRAME_MM = 20.0
START_FRAME_RAD = np.radians(3.0)


def _start_frame(pv: SpatialParameterVector, data: SpatialCalibrationData, x0: np.ndarray,
                 poses: np.ndarray) -> np.ndarray:
    """``x0`` with the frame from :func:`kabsch_frame` of the nominal robot's predicted points (identity frame)
    and the measured ones."""
    v = x0.copy()
    v[pv.frame_index] = 0.0
    pred = predict(pv, v, poses, data.target)
    frame = kabsch_frame(pred[:, :3], data.measured[:, :3])
    if np.linalg.norm(frame[:3]) > START_FRAME_MM or np.linalg.norm(frame[3:]) > START_FRAME_RAD:
        v[pv.frame_index] = frame
    return v


# ---------------------------------------------------------------------------------------------- identify
@dataclass(frozen=True)
class SpatialIdentification:
    """Result of :func:`identify_spatial`.

    Attributes
    ----------
    parameters : SpatialParameterVector
        Names, units, nominal.
    values, sigma : ndarray ``(P,)``
        Estimates and their 1-sigma (0 for fixed parameters).
    covariance : ndarray ``(L, L)``
        Of the identified parameters (``identifiability.identified`` order).
    identifiability : Identifiability
        What the data identify, the combinations they cannot separate in words.
    residuals_before, residuals_after : ndarray ``(N, k)``
        Raw residuals (mm, rad) at the start and at the estimate (NaN where no forward kinematics).
    rms_before, rms_after : float
        RMS whitened residual of the kept readings.
    outliers : tuple of int
        Rows (0-based) flagged and left out.
    scale : float
        ``s``: residual scale (about 1 when the stated sigmas are right).
    nfev : int
        Model evaluations.
    clearances : SpatialErrorSources or None
        The clearances of the readings' covariance (None: the stated sigmas alone).
    """

    parameters: SpatialParameterVector
    values: np.ndarray
    sigma: np.ndarray
    covariance: np.ndarray
    identifiability: Identifiability
    residuals_before: np.ndarray
    residuals_after: np.ndarray
    rms_before: float
    rms_after: float
    outliers: tuple[int, ...]
    scale: float
    nfev: int
    clearances: object = None

    def __repr__(self) -> str:
        return (f"SpatialIdentification({len(self.identifiability.identified)} identified, "
                f"{len(self.outliers)} outliers, rms {self.rms_before:.4g} -> {self.rms_after:.4g})")

    @property
    def robot(self) -> SpatialManipulator:
        """The identified robot (geometry only: offsets, gains, frame and targets are not part of it)."""
        return self.parameters.split(self.values)[0]

    def estimates(self) -> list[dict]:
        """Per parameter ``{name, unit, nominal, estimate, sigma, identified}``."""
        ident = set(self.identifiability.identified)
        return [{"name": n, "unit": u, "nominal": float(a), "estimate": float(b), "sigma": float(s),
                 "identified": n in ident}
                for n, u, a, b, s in zip(self.parameters.names, self.parameters.units, self.parameters.nominal,
                                         self.values, self.sigma)]


def spatial_identifiability(pv: SpatialParameterVector, data: SpatialCalibrationData, values=None,
                            fixed: tuple[str, ...] = (), rtol: float = RTOL,
                            max_sigma: float | None = None) -> Identifiability:
    """What ``data`` (its commands, targets and sigmas; the readings are not used) identify at ``values``
    (default: the nominal): :func:`~.identifiability.analyse` of the whitened Jacobian ``(N k, P)``
    (:func:`measurement_jacobian` at the forward kinematics of the commands)."""
    v = pv.nominal.copy() if values is None else np.asarray(values, dtype=float)
    with threadpool_limits(limits=1, user_api="blas"):    # small matrices (identify_spatial)
        poses = platform_poses(pv, v, data.commands)
        ok = np.all(np.isfinite(poses), axis=1)
        sub = data.subset(ok)
        J = measurement_jacobian(pv, v, sub, poses[ok]) / sub.sigmas[:, :, None]
        return analyse(pv, J.reshape(-1, len(pv.names)), rtol=rtol, fixed=tuple(fixed), max_sigma=max_sigma)


def _threshold(chi2: np.ndarray, k: int) -> float:
    finite = chi2[np.isfinite(chi2)]
    ratio = float(np.median(finite)) / stats.chi2.median(k) if finite.size else 1.0
    return float(stats.chi2.ppf(OUTLIER_QUANTILE, k) * (ratio if ratio > UNDERSTATED else 1.0))


def identify_spatial(data: SpatialCalibrationData, pv: SpatialParameterVector, *, fixed: tuple[str, ...] = (),
                     robust: bool = True, rtol: float = RTOL, max_sigma: float | None = PRACTICAL_MAX_SIGMA,
                     start=None, clearances=None) -> SpatialIdentification:
    """Identify the parameters of ``pv`` from ``data`` (module docstring for the model and the fit).

    ``fixed``: names kept at nominal; ``start (P,)``: the starting values (default: the nominal with the frame
    of the best rigid fit); ``clearances`` (:class:`~pmaccuracy.model.spatial_sources.SpatialErrorSources`, a preset
    or a file): the readings' clearance covariance in their weights (module docstring). Raises
    :class:`~pmaccuracy.errors.MeasurementFileError` when the data do not
    match the parameter vector or too few readings are left for the parameters. Runs with one BLAS thread:
    its matrices (a few hundred rows, at most ~60 columns) gain nothing from more, and on a loaded machine
    the threads' hand-offs made each decomposition 100 times slower (``benchmarks/bench_spatial_calibration.py``).
    """
    with threadpool_limits(limits=1, user_api="blas"):
        return _identify_spatial(data, pv, fixed=fixed, robust=robust, rtol=rtol, max_sigma=max_sigma,
                                 start=start, clearances=clearances)


def _identify_spatial(data, pv, *, fixed, robust, rtol, max_sigma, start, clearances) -> SpatialIdentification:
    k = 6 if pv.kind == "pose" else 3
    if data.measured.shape[1] != k:
        raise MeasurementFileError(f"{data.kind} readings for a parameter vector of {pv.kind} data "
                                   f"({'give the targets' if k == 3 else 'no targets for full poses'})",
                                   source=data.source)
    if data.commands.shape[1] != pv.robot.n_actuators:
        raise MeasurementFileError(f"{data.commands.shape[1]} command columns for a robot with "
                                   f"{pv.robot.n_actuators} actuators", source=data.source)
    if pv.kind == "position" and np.any((data.target < 0) | (data.target >= pv.n_targets)):
        n = int(np.flatnonzero((data.target < 0) | (data.target >= pv.n_targets))[0])
        raise MeasurementFileError(f"target {int(data.target[n]) + 1} but {pv.n_targets} targets are given",
                                   source=data.source, key=f"row {n + 1}")
    P = len(pv.names)
    everything = np.arange(P)
    x0 = pv.nominal.copy() if start is None else np.asarray(start, dtype=float).copy()
    probe = _Model(pv, data, x0, everything)
    try:
        poses0 = probe.poses(x0)
    except PoseError as exc:
        raise MeasurementFileError(f"commands the robot cannot take: {exc}", source=data.source) from None
    if start is None:
        x0 = _start_frame(pv, data, x0, poses0)
    ok0 = np.all(np.isfinite(poses0), axis=1)
    if ok0.sum() * k <= 6:
        raise MeasurementFileError("the nominal robot reaches too few of the commanded poses", source=data.source)
    idf = spatial_identifiability(pv, data, x0, fixed=fixed, rtol=rtol, max_sigma=max_sigma)
    free = np.array(pv.index(idf.identified), dtype=int)
    L = len(free)
    model = _Model(pv, data, x0, free)
    model.guess = probe.guess
    sources = None if clearances is None else SpatialErrorSources.load(clearances, pv.robot)
    if sources is not None:
        model.W = _whitening(pv, x0, data, model.poses(x0), sources)
    before = residuals(pv, x0, data, model.poses(x0))
    nfev = 0
    z = x0[free].copy()
    keep = ok0.copy()

    def enough(keep):
        if k * int(keep.sum()) <= L:
            raise MeasurementFileError(f"only {int(keep.sum())} of {len(data)} readings agree with one robot "
                                       f"({k * int(keep.sum())} residuals for {L} parameters)", source=data.source)

    if robust:
        enough(keep)
        # plain least squares first: from errors of tens of sigmas the soft_l1 loss alone (linear there) crawls
        sol = optimize.least_squares(model.fun(keep), z, jac=model.jac(keep), x_scale="jac", max_nfev=50)
        sol = optimize.least_squares(model.fun(keep), sol.x, jac=model.jac(keep), loss="soft_l1",
                                     f_scale=ROBUST_F_SCALE, x_scale="jac")
        nfev += sol.nfev
        z = sol.x
        if sources is not None:     # the covariance at the robust estimate
            v = model.values(z)
            model.W = _whitening(pv, v, data, model.poses(v), sources)
        chi2 = model.chi2(model.values(z))
        keep = chi2 <= _threshold(chi2, k)
    for _ in range(MAX_ROUNDS):
        enough(keep)
        sol = optimize.least_squares(model.fun(keep), z, jac=model.jac(keep), x_scale="jac", xtol=1e-15,
                                     ftol=1e-15, gtol=1e-15, max_nfev=100)
        nfev += sol.nfev
        z = sol.x
        chi2 = model.chi2(model.values(z))
        again = chi2 <= _threshold(chi2, k) if robust else np.isfinite(chi2)
        if np.array_equal(again, keep):
            break
        keep = again
    values = model.values(z)
    res = model.fun(keep)(z)
    J = model.jac(keep)(z)
    cov, sigma, s2 = covariance(res, J, free, P)
    after = residuals(pv, values, data, model.poses(values))
    wb = whiten(before, data.sigmas, model.W)[keep]
    return SpatialIdentification(parameters=pv, values=values, sigma=sigma, covariance=cov, identifiability=idf,
                                 residuals_before=before, residuals_after=after,
                                 rms_before=float(np.sqrt(np.nanmean(wb ** 2))),
                                 rms_after=float(np.sqrt(np.mean(res ** 2))),
                                 outliers=tuple(int(i) for i in np.flatnonzero(~keep)), scale=float(np.sqrt(s2)),
                                 nfev=nfev, clearances=sources)


def spatial_identification_to_dict(ident: SpatialIdentification) -> dict:
    """A JSON-ready record of ``ident``: the nominal robot file, the nominal targets (mm), every parameter
    (nominal, estimate, sigma; rad for angles, units stated), the covariance of the identified ones, the
    identifiability (fixed parameters and their combinations in words) and the fit."""
    idf = ident.identifiability
    pv = ident.parameters
    return {"robot": pv.robot.to_dict(), "targets_mm": pv.split(pv.nominal)[4].tolist(),
            "parameters": ident.estimates(), "covariance": ident.covariance.tolist(),
            "identifiability": {"identified": list(idf.identified), "fixed": list(idf.fixed),
                                "combinations": list(idf.combinations), "practical": list(idf.practical),
                                "singular_values": idf.singular_values.tolist(), "condition": idf.condition},
            "fit": {"readings": len(ident.residuals_before), "kind": pv.kind, "rms_before_sigmas": ident.rms_before,
                    "rms_after_sigmas": ident.rms_after, "scale": ident.scale,
                    "outlier_rows": [i + 1 for i in ident.outliers], "nfev": ident.nfev,
                    "clearances": None if ident.clearances is None else ident.clearances.name}}


def spatial_identification_from_dict(record: dict, source: str = "<identification>") -> SpatialIdentification:
    """Rebuild a :class:`SpatialIdentification` from :func:`spatial_identification_to_dict` (for compensation;
    no residuals). Raises :class:`~pmaccuracy.errors.ConfigError` naming the source of a malformed record."""
    from_dict = SpatialManipulator.from_dict
    try:
        robot = from_dict(record["robot"], source=source)
        targets = record.get("targets_mm") or None
        pv = spatial_error_parameters(robot, targets=targets)
        by_name = {p["name"]: p for p in record["parameters"]}
        # a record written before the axis angles were parameters: those at nominal (0), not identified
        for n, nominal in zip(pv.names, pv.nominal):
            if n not in by_name and n.endswith((".a", ".b")):
                by_name[n] = {"estimate": float(nominal), "sigma": 0.0}
        values = np.array([float(by_name[n]["estimate"]) for n in pv.names])
        sigma = np.array([float(by_name[n]["sigma"]) for n in pv.names])
        idf = record["identifiability"]
        fit = record["fit"]
        L = len(idf["identified"])
        cov = np.array(record["covariance"], dtype=float).reshape(L, L)
        pv.index(idf["identified"])
        ident = Identifiability(identified=tuple(idf["identified"]), fixed=tuple(idf["fixed"]),
                                combinations=tuple(idf["combinations"]),
                                null_directions=np.zeros((len(idf["fixed"]), len(pv.names))),
                                singular_values=np.array(idf["singular_values"], dtype=float),
                                condition=float(idf["condition"]), O1=float("nan"), O2=float("nan"),
                                O3=float("nan"), O4=float("nan"), practical=tuple(idf.get("practical", ())))
        empty = np.zeros((0, 6 if pv.kind == "pose" else 3))
        return SpatialIdentification(parameters=pv, values=values, sigma=sigma, covariance=cov, identifiability=ident,
                                     residuals_before=empty, residuals_after=empty,
                                     rms_before=float(fit["rms_before_sigmas"]),
                                     rms_after=float(fit["rms_after_sigmas"]),
                                     outliers=tuple(int(r) - 1 for r in fit["outlier_rows"]), scale=float(fit["scale"]),
                                     nfev=int(fit["nfev"]))
    except ConfigError as exc:
        raise ConfigError(exc.message, source=source, key=exc.key) from None
    except (KeyError, TypeError, ValueError) as exc:
        raise ConfigError(f"not a spatial identification record ({exc.__class__.__name__}: {exc})",
                          source=source) from None
