"""Compensation: the commands of the identified robot for target poses, its predicted accuracy, and the
clearance floor beside it.

For targets ``t (T, 3)`` in the measurement frame (mm, mm, rad), the compensated commands are
``(q(theta_hat; F_hat * t) - offset) / gain`` (the identified robot's exact inverse kinematics,
:func:`~.parameters.commands_for`); the nominal commands are those of the nominal robot. The predicted
1-sigma pose error after compensation is the parameter covariance carried to the pose,
``Cov_t = A C A^T`` with ``A = G^-1 dr/dtheta`` (the identification's residual model at the target), and
the clearance floor is what calibration cannot remove: the worst case
(:func:`pmaccuracy.accuracy.bounds.max_pose_errors`) and the RMS (:func:`~pmaccuracy.accuracy.distributions
.sample_pose_errors`) of the clearances at the same poses on the identified robot.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import OutsideJointLimitsError
from ..bounds import max_pose_errors
from ..distributions import sample_pose_errors
from ...model.serial import error_generators, load_serial_sources, max_serial_errors
from .identify import Identification, pose_sensitivity, raw_residuals
from .parameters import SerialParameterVector, actuators, commands_for, frame_apply, serial_poses
from ...model.plausibility import check_orientations


@dataclass(frozen=True)
class Compensation:
    """``targets (T, 3)``; ``commands`` / ``nominal_commands (T, 3)`` (mm / rad); ``predicted_sigma (T, 3)``
    (mm, mm, rad) of the compensated pose from the parameter covariance; ``fit_rms_position`` (mm) the
    identification's RMS position residual at its measured points (:class:`~.identify.Identification`); clearance
    floor ``floor_dp_max``,
    ``floor_dphi_max`` (worst case, mm / rad) and ``floor_dp_rms``, ``floor_dphi_rms`` (T,) or None."""

    targets: np.ndarray
    commands: np.ndarray
    nominal_commands: np.ndarray
    predicted_sigma: np.ndarray
    fit_rms_position: float
    floor_dp_max: np.ndarray | None = None
    floor_dphi_max: np.ndarray | None = None
    floor_dp_rms: np.ndarray | None = None
    floor_dphi_rms: np.ndarray | None = None

    def __repr__(self) -> str:
        fl = "" if self.floor_dp_max is None else f", clearance floor dp_max <= {np.max(self.floor_dp_max):.4g} mm"
        return f"Compensation({len(self.targets)} targets, predicted sigma <= " \
               f"{np.max(np.hypot(*self.predicted_sigma[:, :2].T)):.4g} mm{fl})"


def compensate(ident: Identification, targets: np.ndarray, *, clearances=None, samples: int = 2000,
               seed: int = 0, start: np.ndarray | None = None) -> Compensation:
    """Commands of the identified robot for ``targets (T, 3)`` (measurement frame; module docstring).

    A serial arm (:func:`serial_commands`): ``start (T, n)`` are the commands the nominal arm was given for
    the targets (default: the nominal arm's own solution nearest the middle of the joint ranges); its
    clearance floor comes from :func:`pmaccuracy.model.serial.max_serial_errors` (worst case) and uniform
    draws of its sources (RMS).

    Raises :class:`~pmaccuracy.errors.OutsideJointLimitsError` naming the first target the identified robot
    cannot reach within its actuator ranges.
    """
    check_orientations(targets, "targets", poses=True)
    pv = ident.parameters
    if isinstance(pv, SerialParameterVector):
        return _compensate_serial(ident, targets, start=start, clearances=clearances, samples=samples, seed=seed)
    targets = np.atleast_2d(np.asarray(targets, dtype=float))
    cmd = commands_for(pv, ident.values, targets)
    nom = commands_for(pv, pv.nominal, targets)
    rng_ = np.array([c.actuated.range for c in pv.robot.chains])
    bad = ~np.all(np.isfinite(cmd), axis=1) | np.any((cmd < rng_[:, 0] - 1e-9) | (cmd > rng_[:, 1] + 1e-9), axis=1)
    if np.any(bad):
        n = int(np.flatnonzero(bad)[0])
        raise OutsideJointLimitsError(f"target {n + 1} ({targets[n, 0]:.6g} mm, {targets[n, 1]:.6g} mm, "
                                      f"{np.degrees(targets[n, 2]):.6g} deg) is out of the identified robot's "
                                      "actuator ranges")
    free = pv.index(ident.identifiability.identified)
    G = pose_sensitivity(pv, ident.values, cmd, targets)
    h = 1e-6
    cols = []
    for j in free:
        vp, vm = ident.values.copy(), ident.values.copy()
        vp[j] += h
        vm[j] -= h
        cols.append((raw_residuals(pv, vp, cmd, targets) - raw_residuals(pv, vm, cmd, targets)) / (2 * h))
    dr = np.stack(cols, axis=-1)                                   # (T, 3, L)
    A = -np.linalg.solve(G, dr)                                    # pose change per parameter change
    cov = np.einsum("til,lk,tjk->tij", A, ident.covariance, A)
    sigma = np.sqrt(np.clip(np.einsum("tii->ti", cov), 0, None))
    out = dict(targets=targets, commands=cmd, nominal_commands=nom, predicted_sigma=sigma,
               fit_rms_position=ident.fit_rms_position)
    if clearances is not None:
        robot = pv.split(ident.values)[0]
        poses = frame_apply(ident.values[-3:], targets)
        b = max_pose_errors(robot, clearances, poses)
        e = sample_pose_errors(robot, clearances, poses, samples, seed=seed)
        out.update(floor_dp_max=np.asarray(b.dp_max), floor_dphi_max=np.asarray(b.dphi_max),
                   floor_dp_rms=np.sqrt(np.mean(np.sum(e[..., :2] ** 2, axis=-1), axis=0)),
                   floor_dphi_rms=np.sqrt(np.mean(e[..., 2] ** 2, axis=0)))
    return Compensation(**out)


#: Weight of an orientation residual against a position one in the serial arm's inverse kinematics, mm/rad.
SERIAL_PHI_WEIGHT = 100.0


def serial_commands(pv: SerialParameterVector, values: np.ndarray, targets: np.ndarray, start: np.ndarray,
                    iterations: int = 60) -> np.ndarray:
    """Commands ``(T, n)`` (rad / mm) that put the serial arm ``values`` at ``targets (T, 3)`` (measurement
    frame): Gauss-Newton on its forward kinematics from ``start (T, n)``, the minimum-norm step for a
    redundant arm (so the nearest solution of the branch of ``start``); NaN rows where it does not reach the
    target to 1e-9 mm and 1e-11 rad."""
    targets = np.atleast_2d(np.asarray(targets, dtype=float))
    c = np.array(start, dtype=float)
    w = np.array([1.0, 1.0, SERIAL_PHI_WEIGHT])
    n = c.shape[1]
    h = 1e-7

    def residual(c):
        r = targets - serial_poses(pv, values, c)
        r[:, 2] = np.angle(np.exp(1j * r[:, 2]))
        return r

    for _ in range(iterations):
        r = residual(c)
        if np.all((np.hypot(r[:, 0], r[:, 1]) < 1e-10) & (np.abs(r[:, 2]) < 1e-12)):
            break
        J = serial_pose_jacobian(pv, values, c)
        c = c + np.einsum("tnk,tk->tn", np.linalg.pinv(J * w[:, None]), r * w)
    rev = np.array([kind == "R" for kind, _ in actuators(pv.robot)])
    c = np.where(rev, start + np.angle(np.exp(1j * (c - start))), c)    # whole turns back to the start's
    r = residual(c)
    ok = (np.hypot(r[:, 0], r[:, 1]) < 1e-9) & (np.abs(r[:, 2]) < 1e-11)
    c[~ok] = np.nan
    return c


def serial_pose_jacobian(pv: SerialParameterVector, values: np.ndarray, commands: np.ndarray) -> np.ndarray:
    """``d pose / d command (T, 3, n)`` of the serial arm ``values`` by central differences."""
    c = np.atleast_2d(np.asarray(commands, dtype=float))
    n, h = c.shape[1], 1e-7
    return np.stack([(serial_poses(pv, values, c + h * np.eye(n)[k]) - serial_poses(pv, values, c - h * np.eye(n)[k]))
                     / (2 * h) for k in range(n)], axis=-1)


def serial_start(pv: SerialParameterVector, targets: np.ndarray, tries: int = 24, seed: int = 0) -> np.ndarray:
    """The nominal arm's commands for ``targets``: of :func:`serial_commands` from ``tries`` starts (the middle
    of the ranges and seeded draws within them), the solution within the ranges nearest their middle."""
    rng_ = np.array([r for _, r in actuators(pv.robot)])
    lo = np.where(np.isfinite(rng_[:, 0]), rng_[:, 0], -np.pi)
    hi = np.where(np.isfinite(rng_[:, 1]), rng_[:, 1], np.pi)
    mid = (lo + hi) / 2
    starts = [mid] + list(np.random.default_rng(seed).uniform(lo, hi, size=(tries - 1, len(lo))))
    best = np.full((len(targets), len(lo)), np.nan)
    best_d = np.full(len(targets), np.inf)
    for s0 in starts:
        c = serial_commands(pv, pv.nominal, targets, np.tile(s0, (len(targets), 1)))
        inside = np.all((c >= rng_[:, 0] - 1e-9) & (c <= rng_[:, 1] + 1e-9), axis=1)
        d = np.where(inside, np.sum(((c - mid) / (hi - lo)) ** 2, axis=1), np.inf)
        better = d < best_d
        best[better], best_d[better] = c[better], d[better]
    return best


def _compensate_serial(ident: Identification, targets: np.ndarray, *, start, clearances, samples, seed) -> Compensation:
    pv = ident.parameters
    targets = np.atleast_2d(np.asarray(targets, dtype=float))
    nom = serial_start(pv, targets) if start is None else np.atleast_2d(np.asarray(start, dtype=float))
    cmd = serial_commands(pv, ident.values, targets, np.where(np.isfinite(nom), nom, 0.0))
    rng_ = np.array([r for _, r in actuators(pv.robot)])
    bad = ~np.all(np.isfinite(cmd), axis=1) | np.any((cmd < rng_[:, 0] - 1e-9) | (cmd > rng_[:, 1] + 1e-9), axis=1)
    if np.any(bad):
        n = int(np.flatnonzero(bad)[0])
        raise OutsideJointLimitsError(f"target {n + 1} ({targets[n, 0]:.6g} mm, {targets[n, 1]:.6g} mm, "
                                      f"{np.degrees(targets[n, 2]):.6g} deg) is out of the identified arm's reach "
                                      "within its joint ranges")
    free = pv.index(ident.identifiability.identified)
    h = 1e-6
    cols = []
    for j in free:   # pose change per parameter change at the compensated commands
        vp, vm = ident.values.copy(), ident.values.copy()
        vp[j] += h
        vm[j] -= h
        d = serial_poses(pv, vp, cmd) - serial_poses(pv, vm, cmd)
        d[:, 2] = np.angle(np.exp(1j * d[:, 2]))
        cols.append(d / (2 * h))
    A = np.stack(cols, axis=-1)                                    # (T, 3, L)
    cov = np.einsum("til,lk,tjk->tij", A, ident.covariance, A)
    sigma = np.sqrt(np.clip(np.einsum("tii->ti", cov), 0, None))
    out = dict(targets=targets, commands=cmd, nominal_commands=nom, predicted_sigma=sigma,
               fit_rms_position=ident.fit_rms_position)
    if clearances is not None:
        arm, off, gain, _ = pv.split(ident.values)
        q = off + gain * cmd
        b = max_serial_errors(arm, clearances, q, allow_outside=True)
        e = sample_serial_errors(arm, clearances, q, samples, seed=seed)
        out.update(floor_dp_max=np.asarray(b.dp_max), floor_dphi_max=np.asarray(b.dphi_max),
                   floor_dp_rms=np.sqrt(np.mean(np.sum(e[..., :2] ** 2, axis=-1), axis=0)),
                   floor_dphi_rms=np.sqrt(np.mean(e[..., 2] ** 2, axis=0)))
    return Compensation(**out)


def sample_serial_errors(arm, sources, q: np.ndarray, samples: int, seed=0) -> np.ndarray:
    """``(samples, T, 3)`` first-order end-effector errors of a serial arm at joint values ``q (T, n)``: each
    source uniform in its set (segment coefficients in ``[-1, 1]``, the play disk uniform in area), one
    draw per sample and pose (:func:`pmaccuracy.model.serial.error_generators`)."""
    sources = load_serial_sources(sources, arm)
    G, layout = error_generators(arm, sources, q)                 # (T, m, 3)
    rng = np.random.default_rng(seed)
    a = rng.uniform(-1.0, 1.0, size=(samples,) + G.shape[:-1])
    e = np.einsum("stm,tmk->stk", a, G)
    rad = layout.disk_radius * np.sqrt(rng.uniform(size=(samples, len(q))))
    ang = rng.uniform(0, 2 * np.pi, size=(samples, len(q)))
    e[..., 0] += rad * np.cos(ang)
    e[..., 1] += rad * np.sin(ang)
    return e
