"""Compensated commands of an identified spatial robot, and the errors they leave on a (virtual) true robot.

A target is a platform pose ``(6,)`` ``[x, y, z mm, rotation vector rad]`` read in the measuring device's
frame (where the calibration's readings were). The identified robot reaches it with the actuated values of
its inverse kinematics at the base-frame pose ``F^-1 * target`` (closed form, leg by leg), so the commands
are ``c = (q - offset) / gain``. A Delta or a 3-UPU reaches the target's position (its orientation is the
robot's own); a 3-RPS or 3-PRS the target's z, roll and pitch in the base frame (x, y and yaw follow). The nominal commands are the nominal robot's inverse kinematics of the
target read as a base-frame pose (the nominal frame is the identity).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import ConfigError
from ...kinematics.spatial import complete_poses, controlled_coordinates, inverse_kinematics
from ...numerics.spatial import rotations, rotvecs
from .spatial_identify import SpatialIdentification, platform_poses
from .spatial_parameters import SpatialParameterVector


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
    """

    targets: np.ndarray
    commands: np.ndarray
    nominal_commands: np.ndarray


def compensate_spatial(ident: SpatialIdentification, targets) -> SpatialCompensation:
    """Compensated commands of ``ident`` at ``targets (N, 6)`` (device frame, module docstring)."""
    targets = np.asarray(targets, dtype=float)
    if targets.ndim != 2 or targets.shape[1] != 6 or not np.all(np.isfinite(targets)):
        raise ConfigError("targets must be finite poses [x, y, z mm, rotation vector rad], shape (N, 6)",
                          key="targets")
    pv = ident.parameters
    return SpatialCompensation(targets=targets, commands=spatial_commands(pv, ident.values, targets),
                               nominal_commands=spatial_commands(pv, pv.nominal, targets))


def pose_errors(pv: SpatialParameterVector, true_values, commands, targets) -> np.ndarray:
    """Errors ``(N, 2)`` of the true robot ``true_values`` at ``commands``: the distance (mm) and the angle
    (rad) between the pose it reaches, read in its true frame, and ``targets (N, 6)`` (device frame); for a
    3-RPS or 3-PRS the errors of what is commanded: ``|dz|`` and the larger of ``|d roll|``, ``|d pitch|``
    in the base frame (x, y, yaw are parasitic). NaN rows where the true robot cannot take the commands."""
    frame = np.asarray(true_values, dtype=float)[pv.frame_index]
    guess = frame_inverse_poses(frame, targets)
    poses = platform_poses(pv, true_values, commands, guess)
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
