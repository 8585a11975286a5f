"""Figures and the interactive view of a spatial robot's workspace (:mod:`pmaccuracy.kinematics.spatial_workspace`).

``save_spatial_workspace_figure`` writes the slices of the region along its third coordinate (z) and, beside it,
a static 3D view (``<stem>_3d<suffix>``); ``write_spatial_workspace_page`` an offline HTML page with the region's
boundary and the robot at its reference pose that the reader turns with the mouse or a finger.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .._savefig import DEFAULT_DPI
from ..kinematics.spatial import inverse_kinematics, platform_points, reference_pose
from ..numerics.spatial import rotations, rotvec_to_euler_xyz
from .view3d_html import write_view3d_page
from .workspace3d_figures import save_slices_figure, save_view3d_figure

#: Slices drawn along the third coordinate.
N_SLICES = 6


def robot_segments(robot, pose=None) -> np.ndarray:
    """Line segments ``(k, 2, 3)`` (mm) drawing ``robot`` at ``pose`` (default: its reference pose): every leg's
    bodies (a leg, a Delta's arm and both rods, a 3-PRS's rod) and the base and platform outlines."""
    pose = reference_pose(robot) if pose is None else np.asarray(pose, dtype=float)
    ik = inverse_kinematics(robot, pose)
    p, R = pose[:3], rotations(pose[3:])
    segs = [leg.segments(p, R, ik.q[i]) for i, leg in enumerate(robot.legs)]
    out = [s.reshape(-1, 2, 3) for s in segs]
    B = platform_points(robot, pose)
    A = np.array([leg.base for leg in robot.legs])
    for ring in (A, B):
        out.append(np.stack([ring, np.roll(ring, -1, axis=0)], axis=1))
    return np.concatenate(out, axis=0)


def _title(robot, ws) -> str:
    what = {"constant-orientation": "constant-orientation workspace", "reachable": "reachable workspace",
            "z-roll-pitch": "workspace in (roll, pitch, z)"}[ws.kind]
    extra = ""
    if ws.orientation is not None and np.any(ws.orientation):
        rpy = rotvec_to_euler_xyz(ws.orientation, degrees=True)
        extra = f" at roll, pitch, yaw = {', '.join(f'{a:g}' for a in np.round(rpy, 3))} deg"
    return f"{robot.name}, {robot.label}: {what}{extra}"


def slice_values(ws) -> np.ndarray:
    """:data:`N_SLICES` values of the third coordinate spread over the region (inside its extent)."""
    lo, hi = ws.region.bounding_box[2]
    return np.linspace(lo, hi, N_SLICES + 2)[1:-1]


def save_spatial_workspace_figure(robot, ws, path: str | os.PathLike, *, dpi: int = DEFAULT_DPI) -> list[Path]:
    """Write the slices figure to ``path`` and the 3D view to ``<stem>_3d<suffix>`` beside it; returns both."""
    path = Path(os.fspath(path))
    title = _title(robot, ws)
    first = save_slices_figure(ws.region, path, slice_values(ws), title=title, dpi=dpi)
    second = save_view3d_figure(ws.region, path.with_name(f"{path.stem}_3d{path.suffix}"), title=title, dpi=dpi)
    return [first, second]


def write_spatial_workspace_page(robot, ws, path: str | os.PathLike) -> Path:
    """An offline HTML page with the workspace's boundary in 3D (and the robot at its reference pose when the
    region's coordinates are positions)."""
    segments = robot_segments(robot) if ws.region.units == ("mm", "mm", "mm") else None
    return write_view3d_page(ws.region, path, _title(robot, ws), robot_segments=segments)
