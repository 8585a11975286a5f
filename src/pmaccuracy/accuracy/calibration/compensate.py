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
from .identify import Identification, pose_sensitivity, raw_residuals
from .parameters import commands_for, frame_apply
from ...model.plausibility import check_orientations


@dataclass(frozen=True)
class Compensation:
    """``targets (T, 3)``; ``commands`` / ``nominal_commands (T, 3)`` (mm / rad); ``predicted_sigma (T, 3)``
    (mm, mm, rad) of the compensated pose from the parameter covariance; clearance floor ``floor_dp_max``,
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
               seed: int = 0) -> Compensation:
    """Commands of the identified robot for ``targets (T, 3)`` (measurement frame; module docstring).

    Raises :class:`~pmaccuracy.errors.OutsideJointLimitsError` naming the first target the identified robot
    cannot reach within its actuator ranges.
    """
    check_orientations(targets, "targets", poses=True)
    pv = ident.parameters
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
    fit = ident.residuals_after
    rms = float(np.sqrt(np.nanmean(np.sum(fit[:, :2] ** 2, axis=1)))) if len(fit) else float("nan")
    out = dict(targets=targets, commands=cmd, nominal_commands=nom, predicted_sigma=sigma, fit_rms_position=rms)
    if clearances is not None:
        robot = pv.split(ident.values)[0]
        poses = frame_apply(ident.values[-3:], targets)
        b = max_pose_errors(robot, clearances, poses)
        e = sample_pose_errors(robot, clearances, poses, samples, seed=seed)
        out.update(floor_dp_max=np.asarray(b.dp_max), floor_dphi_max=np.asarray(b.dphi_max),
                   floor_dp_rms=np.sqrt(np.mean(np.sum(e[..., :2] ** 2, axis=-1), axis=0)),
                   floor_dphi_rms=np.sqrt(np.mean(e[..., 2] ** 2, axis=0)))
    return Compensation(**out)
