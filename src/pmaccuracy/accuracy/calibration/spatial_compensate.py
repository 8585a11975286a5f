"""Compensated commands of an identified spatial robot, and the errors they leave on a (virtual) true robot.

A target is a platform pose ``(6,)`` ``[x, y, z mm, rotation vector rad]`` read in the measuring device's
frame (where the calibration's readings were). The identified robot reaches it with the actuated values of
its inverse kinematics at the base-frame pose ``F^-1 * target`` (closed form, leg by leg), so the commands
are ``c = (q - offset) / gain``. A Delta or a 3-UPU reaches the target's position (its orientation is the
robot's own); a 3-RPS or 3-PRS the target's z, roll and pitch in the base frame (x, y and yaw follow). The nominal
commands are the nominal robot's inverse kinematics of the
target read as a base-frame pose (the nominal frame is the identity).

Clearance floor (:func:`clearance_floor`): what calibration cannot remove, the first-order worst case of the
error sources (clearances, backlash, actuator errors) at the same poses on the identified robot: the largest
``|dp|`` and rotation angle ``|dtheta|`` of ``t = sum_s M_s x_s`` over the sources' unit sets (Eq. 1 of
:mod:`pmaccuracy.accuracy.spatial_bounds`, :func:`~pmaccuracy.numerics.support.max_norm`; for a target point
``s_k`` on the platform the position blocks ``[I, -[R s_k]x] M_s``), and its RMS, exact from the sources'
variances (uniform in a unit set of dimension ``d``: ``1 / (d + 2)`` per coordinate):
``E|dp|^2 = sum_s ||M_s[:3]||_F^2 / (d_s + 2)``. The predicted 1-sigma of a compensated pose
(:func:`compensate_spatial`) is the identification's covariance carried to the pose at the target,
``sqrt(trace(A C A^T))`` for the position and the orientation rows of ``A`` (the full-pose measurement
Jacobian at the compensated commands, the parameters the fit identified).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import ConfigError
from ...kinematics.spatial import complete_poses, controlled_coordinates, inverse_kinematics
from ...model.spatial_sources import SpatialErrorSources
from ...numerics.spatial import rotations, rotvecs, skew
from ...numerics.support import max_norm
from ..spatial_bounds import error_sources_at
from ..spatial_statistics import sample_unit_set
from .spatial_identify import (SpatialCalibrationData, SpatialIdentification, measurement_jacobian, platform_poses,
                               residuals)
from .spatial_parameters import SpatialParameterVector, spatial_error_parameters


def frame_inverse_poses(frame, poses) -> np.ndarray:
    """Base-frame poses ``(N, 6)`` of device-frame ``poses (N, 6)``: ``p = R_F^T (m - t_F)``, ``R = R_F^T R_m``."""
    frame = np.asarray(frame, dtype=float)
    poses = np.asarray(poses, dtype=float)
    RF = rotations(frame[3:])
    p = (poses[:, :3] - frame[:3]) @ RF
    return np.concatenate([p, rotvecs(RF.T @ rotations(poses[:, 3:]))], axis=1)


def spatial_commands(pv: SpatialParameterVector, values, targets) -> np.ndarray:
    """Commands ``(N, n)`` that put the robot ``values`` at device-frame ``targets (N, 6)`` (module docstring);
    NaN rows where a leg cannot reach."""
    robot, off, gain, frame, _ = pv.split(values)
    base = frame_inverse_poses(frame, targets)
    if robot.mobility == "3T":          # the orientation is the robot's, not commanded
        base[:, 3:] = 0.0
    elif robot.mobility == "2R1T":      # z, roll, pitch commanded; x, y, yaw follow
        base = complete_poses(robot, controlled_coordinates(robot, base), strict=False)
    q = inverse_kinematics(robot, base).q
    return (q - off) / gain


@dataclass(frozen=True)
class SpatialCompensation:
    """Result of :func:`compensate_spatial`.

    Attributes
    ----------
    targets : ndarray ``(N, 6)``
        The targets (device frame).
    commands, nominal_commands : ndarray ``(N, n)``
        Compensated and nominal commands.
    predicted_sigma : ndarray ``(N, 2)`` or None
        1-sigma position (mm) and orientation (rad) error of the compensated pose from the parameters'
        covariance (module docstring).
    floor : dict or None
        With ``clearances``: :func:`clearance_floor` at the targets on the identified robot (``dp_max``,
        ``dtheta_max``, ``dp_rms``, ``dtheta_rms``, each ``(N,)``, mm and rad).
    """

    targets: np.ndarray
    commands: np.ndarray
    nominal_commands: np.ndarray
    predicted_sigma: np.ndarray | None = None
    floor: dict | None = None


def compensate_spatial(ident: SpatialIdentification, targets, *, clearances=None) -> SpatialCompensation:
    """Compensated commands of ``ident`` at ``targets (N, 6)`` (device frame, module docstring), their predicted
    1-sigma and, with ``clearances`` (:class:`~pmaccuracy.model.spatial_sources.SpatialErrorSources`, a preset
    name or a file), the clearance floor at the targets."""
    targets = np.asarray(targets, dtype=float)
    if targets.ndim != 2 or targets.shape[1] != 6 or not np.all(np.isfinite(targets)):
        raise ConfigError("targets must be finite poses [x, y, z mm, rotation vector rad], shape (N, 6)",
                          key="targets")
    pv = ident.parameters
    commands = spatial_commands(pv, ident.values, targets)
    base = frame_inverse_poses(ident.values[pv.frame_index], targets)
    at = platform_poses(pv, ident.values, np.where(np.isfinite(commands), commands, 0.0), base)
    at[~np.all(np.isfinite(commands), axis=1)] = np.nan
    floor = None
    if clearances is not None:
        floor = clearance_floor(pv, ident.values, clearances, at)
    return SpatialCompensation(targets=targets, commands=commands,
                               nominal_commands=spatial_commands(pv, pv.nominal, targets),
                               predicted_sigma=predicted_pose_sigma(ident, commands, at), floor=floor)


def predicted_pose_sigma(ident: SpatialIdentification, commands, poses) -> np.ndarray:
    """``(N, 2)``: 1-sigma position (mm) and orientation (rad) error at the base-frame ``poses (N, 6)`` the
    identified robot takes at ``commands (N, n)``, from the identification's covariance (module docstring;
    position-only data: the tool parameters left out, the pose is that of the platform's reference point).
    NaN rows where a pose is NaN."""
    pv = ident.parameters
    poses = np.asarray(poses, dtype=float)
    ok = np.all(np.isfinite(poses), axis=1)
    out = np.full((len(poses), 2), np.nan)
    if not ok.any():
        return out
    full = spatial_error_parameters(pv.robot) if pv.kind == "position" else pv
    P = len(full.names)
    values = np.asarray(ident.values, dtype=float)[:P]
    ident_names = list(ident.identifiability.identified)
    keep = [k for k, n in enumerate(ident_names) if n in full.names[:P]]
    cols = full.index([ident_names[k] for k in keep])
    C = np.asarray(ident.covariance, dtype=float)[np.ix_(keep, keep)]
    n = int(ok.sum())
    probe = SpatialCalibrationData(tuple(map(str, range(n))), np.asarray(commands, dtype=float)[ok],
                                   np.zeros((n, 6)), np.ones((n, 6)), np.zeros(n, dtype=int))
    A = measurement_jacobian(full, values, probe, poses[ok])[:, :, cols]       # (n, 6, L)
    cov = np.einsum("nil,lk,njk->nij", A, C, A)
    d = np.clip(np.einsum("nii->ni", cov), 0.0, None)
    out[ok] = np.column_stack([np.sqrt(d[:, :3].sum(axis=1)), np.sqrt(d[:, 3:].sum(axis=1))])
    return out


def _sources(robot, clearances) -> SpatialErrorSources:
    return SpatialErrorSources.load(clearances, robot)


def _point_blocks(M: np.ndarray, arm) -> np.ndarray:
    """Position blocks ``(N, 3, d)`` of a platform point ``arm (N, 3)`` away from P: ``M[:3] - [arm]x M[3:]``."""
    if arm is None:
        return M[:, :3]
    return M[:, :3] - skew(arm) @ M[:, 3:]


def clearance_floor(pv: SpatialParameterVector, values, clearances, poses, target=None) -> dict:
    """The clearance floor (module docstring) of the robot ``values (P,)`` at base-frame ``poses (N, 6)``: worst
    case and RMS of the position error (mm) of the platform's reference point, or with ``target (N,)`` (0-based,
    position-only ``pv``) of that target point, and of the rotation angle (rad). Returns ``{"dp_max",
    "dtheta_max", "dp_rms", "dtheta_rms"}``, each ``(N,)``; NaN at poses that are unreachable or near a
    singularity. ``clearances``: :class:`~pmaccuracy.model.spatial_sources.SpatialErrorSources`, a preset name
    or a file."""
    robot, _, _, _, tools = pv.split(values)
    sources = _sources(robot, clearances)
    poses = np.asarray(poses, dtype=float)
    ok = np.all(np.isfinite(poses), axis=1)
    out = {k: np.full(len(poses), np.nan) for k in ("dp_max", "dtheta_max", "dp_rms", "dtheta_rms")}
    if not ok.any():
        return out
    at = poses[ok]
    arm = None
    if target is not None and pv.n_targets:
        arm = np.einsum("nij,nj->ni", rotations(at[:, 3:]), tools[np.asarray(target, dtype=int)[ok]])
    blocks, info = error_sources_at(robot, sources, at, strict=False, keep=True, allow_outside=True)
    valid = info["valid"]
    if not blocks:
        for k in out:
            out[k][ok] = 0.0
        return out
    clean = [np.where(valid[:, None, None], b, 0.0) for b in blocks]
    dp = max_norm([_point_blocks(b, arm) for b in clean]).upper
    dth = max_norm([b[:, 3:] for b in clean]).upper
    var_p, var_w = np.zeros(len(at)), np.zeros(len(at))
    for src in info["sources"]:
        M = np.where(valid[:, None, None], src.matrix, 0.0)
        v = 1.0 / (M.shape[-1] + 2)
        var_p += v * np.sum(_point_blocks(M, arm) ** 2, axis=(1, 2))
        var_w += v * np.sum(M[:, 3:] ** 2, axis=(1, 2))
    nan = np.where(valid, 1.0, np.nan)
    for key, val in (("dp_max", dp), ("dtheta_max", dth), ("dp_rms", np.sqrt(var_p)), ("dtheta_rms", np.sqrt(var_w))):
        out[key][ok] = val * nan
    return out


def clearance_twists(robot, clearances, poses, seed=0) -> np.ndarray:
    """One clearance state per pose: first-order error twists ``(N, 6)`` ``[v mm, w rad]`` (at P, base frame)
    ``t = sum_s M_s x_s`` at ``poses (N, 6)`` of ``robot``, every source's variables ``x_s`` drawn uniformly in
    its unit set (:func:`~pmaccuracy.accuracy.spatial_statistics.sample_unit_set`) independently per pose and
    per source. NaN rows where the pose is unreachable or near a singularity. ``seed``: an int or a Generator."""
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    sources = _sources(robot, clearances)
    poses = np.asarray(poses, dtype=float)
    ok = np.all(np.isfinite(poses), axis=1)
    t = np.full((len(poses), 6), np.nan)
    if not ok.any():
        return t
    _, info = error_sources_at(robot, sources, poses[ok], strict=False, keep=True, allow_outside=True)
    tw = np.zeros((int(ok.sum()), 6))
    for src in info["sources"]:
        M = src.matrix
        x = sample_unit_set(rng, M.shape[-1], len(tw))
        tw += np.einsum("nid,nd->ni", M, x)
    tw[~info["valid"]] = np.nan
    t[ok] = tw
    return t


def displaced(poses, twists) -> np.ndarray:
    """Poses ``(N, 6)`` moved by small twists ``(N, 6)`` ``[v, w]`` at P: ``p + v``, ``exp([w]x) R``."""
    poses = np.asarray(poses, dtype=float)
    twists = np.asarray(twists, dtype=float)
    return np.concatenate([poses[:, :3] + twists[:, :3],
                           rotvecs(rotations(twists[:, 3:]) @ rotations(poses[:, 3:]))], axis=1)


def pose_errors(pv: SpatialParameterVector, true_values, commands, targets, *, clearances=None,
                seed=0) -> np.ndarray:
    """Errors ``(N, 2)`` of the true robot ``true_values`` at ``commands``: the distance (mm) and the angle
    (rad) between the pose it reaches, read in its true frame, and ``targets (N, 6)`` (device frame); for a
    3-RPS or 3-PRS the errors of what is commanded: ``|dz|`` and the larger of ``|d roll|``, ``|d pitch|``
    in the base frame (x, y, yaw are parasitic). With ``clearances`` the reached pose is moved by one
    clearance state each (:func:`clearance_twists`, ``seed``). NaN rows where the true robot cannot take the
    commands."""
    frame = np.asarray(true_values, dtype=float)[pv.frame_index]
    guess = frame_inverse_poses(frame, targets)
    poses = platform_poses(pv, true_values, commands, guess)
    if clearances is not None:
        poses = displaced(poses, clearance_twists(pv.split(true_values)[0], clearances, poses, seed))
    if pv.robot.mobility == "2R1T":
        c = controlled_coordinates(pv.robot, poses) - controlled_coordinates(pv.robot, guess)
        return np.column_stack([np.abs(c[:, 0]), np.max(np.abs(c[:, 1:]), axis=1)])
    RF = rotations(frame[3:])
    m = frame[:3] + poses[:, :3] @ RF.T
    R = RF @ rotations(np.where(np.isfinite(poses[:, 3:]), poses[:, 3:], 0.0))
    angle = np.linalg.norm(rotvecs(R @ np.swapaxes(rotations(targets[:, 3:]), -1, -2)), axis=1)
    out = np.column_stack([np.linalg.norm(m - targets[:, :3], axis=1), angle])
    out[~np.all(np.isfinite(poses), axis=1)] = np.nan
    return out


#: A residual counts as at the clearance floor when within the floor plus this many sigmas (of the readings, or
#: of the compensated pose).
FLOOR_SIGMAS = 3.0


def residuals_beside_floor(ident: SpatialIdentification, data: SpatialCalibrationData, clearances) -> dict:
    """The fit's residual at each reading (:func:`~.spatial_identify.residuals` of the identified robot) beside the
    clearance floor there (:func:`clearance_floor` on the
    identified robot at the pose it takes at the reading's commands; a position-only reading: at its target).

    Returns ``{"residual_mm" (N,), "residual_rad" (N,) (NaN for position-only data), "floor": {...} (N,) each,
    "sigma_mm" (N,): the reading's position 1-sigma as a length sqrt(sum sigma_i^2), "within" (N,) bool: the
    residual within ``floor + FLOOR_SIGMAS sigma`` in position (and orientation for full poses), "outlier"
    (N,) bool}``."""
    pv = ident.parameters
    poses = platform_poses(pv, ident.values, data.commands)
    r = residuals(pv, ident.values, data, poses)
    floor = clearance_floor(pv, ident.values, clearances, poses, data.target if pv.kind == "position" else None)
    res_mm = np.linalg.norm(r[:, :3], axis=1)
    sig_mm = np.sqrt(np.sum(data.sigmas[:, :3] ** 2, axis=1))
    within = res_mm <= floor["dp_max"] + FLOOR_SIGMAS * sig_mm
    res_rad = np.full(len(data), np.nan)
    if pv.kind == "pose":
        res_rad = np.linalg.norm(r[:, 3:], axis=1)
        within &= res_rad <= floor["dtheta_max"] + FLOOR_SIGMAS * np.sqrt(np.sum(data.sigmas[:, 3:] ** 2, axis=1))
    outlier = np.zeros(len(data), dtype=bool)
    outlier[[i for i in ident.outliers if i < len(data)]] = True
    return {"residual_mm": res_mm, "residual_rad": res_rad, "floor": floor, "sigma_mm": sig_mm, "within": within,
            "outlier": outlier}
