"""Figures and the interactive view of a spatial robot's workspace (:mod:`pmaccuracy.kinematics.spatial_workspace`).

``save_spatial_workspace_figure`` writes the slices of the region along its third coordinate (z) and, beside it,
a static 3D view (``<stem>_3d<suffix>``); ``write_spatial_workspace_page`` an offline HTML page with the region's
boundary and the robot at its reference pose that the reader turns with the mouse or a finger.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

import math

from .._savefig import DEFAULT_DPI, save_figure
from ..kinematics.spatial import inverse_kinematics, platform_points, reference_pose
from ..numerics.spatial import rotations, rotvec_to_euler_xyz
from .view3d_html import write_view3d_page
from .workspace3d_figures import FONT_PT, TITLE_PT, WIDTH_IN, save_slices_figure, save_view3d_figure

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


def map_slices_figure(robot, ds, variable: str = "dp_max", *, n_slices: int = N_SLICES, vmin=None, vmax=None):
    """Slices of a spatial error map (:func:`pmaccuracy.accuracy.spatial_maps.spatial_error_map`) along its third
    coordinate: one panel per slice (two per row), one colour scale for all (in mm, or deg for rotations),
    blank outside the workspace. Returns a Figure with an Agg canvas."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    var = ds[variable]
    dims = var.dims
    values = var.values * (np.degrees(1.0) if var.attrs.get("units") == "rad" else 1.0)
    unit = "deg" if var.attrs.get("units") == "rad" else var.attrs.get("units", "")
    third = ds[dims[2]].values
    filled = np.flatnonzero(np.any(np.isfinite(values), axis=(0, 1)))
    if len(filled) == 0:
        raise ValueError("the map is empty")
    pick = filled[np.unique(np.linspace(0, len(filled) - 1, min(n_slices, len(filled))).round().astype(int))]
    lo = float(np.nanmin(values)) if vmin is None else vmin
    hi = float(np.nanmax(values)) if vmax is None else vmax
    a, b = ds[dims[0]].values, ds[dims[1]].values
    ua, ub, uc = (ds[d].attrs.get("units", "") for d in dims)
    cols = 2
    rows = math.ceil(len(pick) / cols)
    left, right, gap_x, top, gap_y, bottom = 0.95, 0.25, 0.85, 0.8, 0.95, 1.35
    panel_w = (WIDTH_IN - left - right - gap_x * (cols - 1)) / cols
    aspect = (b[-1] - b[0]) / (a[-1] - a[0]) if ua == ub else 0.8
    panel_h = float(np.clip(panel_w * aspect, 1.2, 4.0))
    height = top + rows * panel_h + (rows - 1) * gap_y + bottom
    fig = Figure(figsize=(WIDTH_IN, height))
    FigureCanvasAgg(fig)
    label = {"dp_max": "|dp|", "dtheta_max": "|dtheta|"}.get(variable, variable)
    fig.suptitle(f"{robot.name}: worst {label} ({unit}), clearances {ds.attrs.get('clearances', '')}",
                 fontsize=TITLE_PT + 1, y=1 - 0.22 / height, va="top")
    mesh = None
    for k, iz in enumerate(pick):
        r, c = divmod(k, cols)
        x0 = left + c * (panel_w + gap_x)
        y0 = height - top - (r + 1) * panel_h - r * gap_y
        ax = fig.add_axes((x0 / WIDTH_IN, y0 / height, panel_w / WIDTH_IN, panel_h / height))
        mesh = ax.pcolormesh(a, b, values[:, :, iz].T, vmin=lo, vmax=hi, cmap="viridis", shading="nearest")
        if ua == ub:
            ax.set_aspect("equal", adjustable="box")
        ax.set_title(f"{dims[2]} = {third[iz]:.4g} {uc}", fontsize=TITLE_PT)
        ax.set_xlabel(f"{dims[0]} [{ua}]", fontsize=FONT_PT)
        ax.set_ylabel(f"{dims[1]} [{ub}]", fontsize=FONT_PT)
        ax.tick_params(labelsize=FONT_PT)
    cax = fig.add_axes((left / WIDTH_IN, 0.45 / height, (WIDTH_IN - left - right) / WIDTH_IN, 0.16 / height))
    bar = fig.colorbar(mesh, cax=cax, orientation="horizontal")
    bar.set_label(f"{label} [{unit}] (blank: outside the workspace)", fontsize=FONT_PT)
    bar.ax.tick_params(labelsize=FONT_PT)
    return fig


def save_map_slices_figure(robot, ds, path, *, variable: str = "dp_max", dpi: int = DEFAULT_DPI, vmin=None,
                           vmax=None) -> Path:
    """Write :func:`map_slices_figure` to ``path`` (format by its suffix)."""
    fig = map_slices_figure(robot, ds, variable, vmin=vmin, vmax=vmax)
    out = save_figure(fig, path, dpi=dpi)
    fig.clear()
    return out
