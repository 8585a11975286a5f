"""Workspaces of spatial robots: the region of the controlled coordinates where every joint limit holds.

* 6-UPS: the **constant-orientation workspace**, positions of P (x, y, z mm) at a fixed orientation, and the
  **orientation workspace** at a point (tilt and torsion angles, :func:`pmaccuracy.kinematics.workspace3d.
  orientation_workspace`);
* Delta and 3-UPU: their **reachable workspace** (x, y, z; the orientation is fixed by their legs);
* 3-RPS and 3-PRS: the region of their controlled coordinates (roll deg, pitch deg, z mm), the parasitic
  motions solved at every point.

A point is inside when every leg reaches it on its working mode, every actuated joint is within its stroke,
every passive joint within its cone or angle range and no two legs' capsules intersect
(:class:`pmaccuracy.kinematics.spatial.SpatialIK`). The region is sampled on a grid, its boundary refined by
bisection and its volume estimated with an error (:func:`pmaccuracy.kinematics.workspace3d.grid_workspace`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import EmptyWorkspaceError
from ..model.plausibility import check_angle_values
from ..model.spatial import SpatialManipulator
from ..numerics.spatial import rotvecs
from .spatial import complete_poses, controlled_coordinates, inverse_kinematics, reference_pose
from .workspace3d import OrientationWorkspace, Workspace3D, find_box, grid_workspace, orientation_workspace


@dataclass(frozen=True)
class SpatialWorkspace:
    """A spatial robot's workspace: the 3D region, what it is, and the orientation workspace at its reference
    point (6-UPS only).

    Attributes
    ----------
    kind : str
        ``"constant-orientation"``, ``"reachable"`` or ``"z-roll-pitch"``.
    orientation : ``(3,)`` or None
        Rotation vector (rad) of a 6-UPS's fixed orientation.
    region : :class:`~pmaccuracy.kinematics.workspace3d.Workspace3D`
        The region (coordinates and units in its ``names``, ``units``).
    reference : ``(3,)``
        The point of the region the search started from (the home pose's coordinates).
    orientations : :class:`~pmaccuracy.kinematics.workspace3d.OrientationWorkspace` or None
        The tilt-and-torsion workspace at ``reference`` (6-UPS).
    """

    kind: str
    orientation: np.ndarray | None
    region: Workspace3D
    reference: np.ndarray
    orientations: OrientationWorkspace | None = None

    def summary(self) -> dict:
        """Volume with its error, bounds per coordinate and (6-UPS) the tilt reachable at the reference point."""
        r = self.region
        bb = r.bounding_box
        out = {"workspace": self.kind, "coordinates": list(r.names), "units": list(r.units),
               "volume": r.volume, "volume_error": r.volume_error,
               "volume_units": "*".join(r.units), "grid": list(r.inside.shape), "cells_inside": r.cells}
        for name, (lo, hi) in zip(r.names, bb):
            out[f"{name}_min"] = float(lo)
            out[f"{name}_max"] = float(hi)
        if self.orientations is not None:
            out["max_tilt_deg"] = float(self.orientations.max_tilt_deg[0])
            out["guaranteed_tilt_deg"] = float(self.orientations.guaranteed_tilt_deg[0])
        return out


def membership(robot: SpatialManipulator, orientation=None):
    """The vectorized membership function of :func:`spatial_workspace`'s region: points ``(..., 3)`` (x, y, z mm;
    for a 3-RPS/3-PRS roll deg, pitch deg, z mm) -> bool ``(...)``."""
    if robot.mobility == "2R1T":
        def inside(points):
            pts = np.asarray(points, dtype=float)
            c = np.stack([pts[..., 2], np.radians(pts[..., 0]), np.radians(pts[..., 1])], axis=-1)
            poses = complete_poses(robot, c, strict=False)
            ok = np.all(np.isfinite(poses), axis=-1)
            out = np.zeros(pts.shape[:-1], dtype=bool)
            if np.any(ok):
                out[ok] = inverse_kinematics(robot, poses[ok]).within_limits
            return out
        return inside
    if robot.is_chain and robot.mobility == "3T":
        def inside(points):           # a chain's orientation follows from its constraints
            poses = complete_poses(robot, np.asarray(points, dtype=float), strict=False)
            ok = np.all(np.isfinite(poses), axis=-1)
            out = np.zeros(ok.shape, dtype=bool)
            if np.any(ok):
                out[ok] = inverse_kinematics(robot, poses[ok]).within_limits
            return out
        return inside
    r = np.zeros(3) if orientation is None or robot.mobility == "3T" else np.asarray(orientation, dtype=float)

    def inside(points):
        pts = np.asarray(points, dtype=float)
        poses = np.concatenate([pts, np.broadcast_to(r, pts.shape)], axis=-1)
        return np.asarray(inverse_kinematics(robot, poses).within_limits)
    return inside


def _size(robot: SpatialManipulator) -> float:
    if robot.is_chain:       # the farthest joint centre from the home position
        centres = np.array([j.centre for leg in robot.legs for j in leg.joints])
        return float(np.max(np.linalg.norm(centres - robot.home_pose[:3], axis=-1)))
    size = max(max(np.linalg.norm(leg.base), np.linalg.norm(leg.platform)) for leg in robot.legs)
    strokes = robot.strokes
    span = float(np.max(strokes[:, 1])) if robot.actuated_kinds[0] == "P" else \
        float(robot.legs[0].arm + robot.legs[0].rod)
    return max(size, span)


@dataclass(frozen=True, eq=False)
class WorkspaceBox:
    """What :func:`spatial_workspace` samples: the membership function and the box holding the region.

    Attributes
    ----------
    inside : callable
        Points ``(..., 3)`` in the region's coordinates -> bool ``(...)`` (:func:`membership`).
    box : ``(3, 2)``
        ``[[lo, hi], ...]`` per coordinate, found from the reference point
        (:func:`pmaccuracy.kinematics.workspace3d.find_box`).
    names, units : tuple of 3 str
        The coordinates (``x, y, z`` mm, or ``roll, pitch`` deg and ``z`` mm).
    kind : str
        As :attr:`SpatialWorkspace.kind`.
    orientation : ``(3,)`` or None
        A 6-UPS's fixed orientation (rotation vector, rad).
    reference : ``(3,)``
        The reference point (inside).
    """

    inside: object
    box: np.ndarray
    names: tuple
    units: tuple
    kind: str
    orientation: np.ndarray | None
    reference: np.ndarray


def workspace_box(robot: SpatialManipulator, orientation=None) -> WorkspaceBox:
    """The membership function and the box of :func:`spatial_workspace`'s region (no grid sampled): a map can
    then sample the grid ``pmaccuracy.kinematics.workspace3d.cell_centres(box, n)`` piece by piece. Raises
    :class:`~pmaccuracy.errors.EmptyWorkspaceError` when the reference point is outside.

    >>> wb = workspace_box(SpatialManipulator.preset("upu_3"))
    >>> wb.kind, wb.box.shape, bool(wb.inside(wb.reference[None])[0])
    ('reachable', (3, 2), True)
    """
    ref = reference_pose(robot)
    size = _size(robot)
    inside = membership(robot, orientation)
    if robot.mobility == "2R1T":
        c = controlled_coordinates(robot, ref)
        seed = np.array([np.degrees(c[1]), np.degrees(c[2]), c[0]])
        start, most = np.array([10.0, 10.0, 0.1 * size]), np.array([90.0, 90.0, 3 * size])
        names, units, kind = ("roll", "pitch", "z"), ("deg", "deg", "mm"), "z-roll-pitch"
        orientation = None
    else:
        seed = ref[:3]
        start, most = np.full(3, 0.1 * size), np.full(3, 3 * size)
        names, units = ("x", "y", "z"), ("mm", "mm", "mm")
        kind = "constant-orientation" if robot.mobility == "6" else "reachable"
        orientation = None if robot.mobility == "3T" else np.zeros(3) if orientation is None else \
            np.asarray(orientation, dtype=float)
    if not bool(np.asarray(inside(seed[None]))[0]):
        what = "" if orientation is None or not np.any(orientation) else " at this orientation"
        raise EmptyWorkspaceError(f"the reference pose{what} of {robot.name} violates a joint limit: no workspace to "
                                  "grow from it (check the orientation, or the robot's [home] pose)")
    box = find_box(inside, seed, start, most)
    return WorkspaceBox(inside=inside, box=np.asarray(box, dtype=float), names=names, units=units, kind=kind,
                        orientation=orientation, reference=seed)


def spatial_workspace(robot: SpatialManipulator, orientation=None, n: int = 40, *, tilt: bool = True
                      ) -> SpatialWorkspace:
    """The workspace of ``robot`` (see the module text): a box around the region is found from the reference
    pose (:func:`pmaccuracy.kinematics.spatial.reference_pose`, with the given orientation for a 6-UPS), then
    sampled with ``n`` points per axis. Raises :class:`~pmaccuracy.errors.EmptyWorkspaceError` when the
    reference point itself is outside.

    >>> ws = spatial_workspace(SpatialManipulator.preset("upu_3"), n=12, tilt=False)
    >>> ws.kind, ws.region.names
    ('reachable', ('x', 'y', 'z'))
    """
    if orientation is not None:
        check_angle_values(np.linalg.norm(np.asarray(orientation, dtype=float)), "orientation (rotation vector)")
    wb = workspace_box(robot, orientation)
    region = grid_workspace(wb.inside, wb.box, n, names=wb.names, units=wb.units)
    kind, orientation, seed = wb.kind, wb.orientation, wb.reference
    orients = None
    if tilt and robot.mobility == "6":
        orients = orientation_workspace_at(robot, seed)
    return SpatialWorkspace(kind=kind, orientation=orientation, region=region, reference=seed, orientations=orients)


def orientation_workspace_at(robot: SpatialManipulator, position, *, torsions_deg=(0.0,), n_azimuth: int = 72
                             ) -> OrientationWorkspace:
    """The tilt-and-torsion workspace of a 6-UPS with P held at ``position`` (mm)."""
    p = np.asarray(position, dtype=float)

    def inside(R):
        R = np.asarray(R, dtype=float)
        poses = np.concatenate([np.broadcast_to(p, R.shape[:-2] + (3,)), rotvecs(R)], axis=-1)
        return np.asarray(inverse_kinematics(robot, poses).within_limits)
    return orientation_workspace(inside, torsions_deg=torsions_deg, n_azimuth=n_azimuth)
