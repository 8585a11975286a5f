"""Figures of a 3D workspace (:class:`~pmaccuracy.kinematics.workspace3d.Workspace3D`): slices and a 3D view.

:func:`slices_figure` draws the region's cross-sections at a few values of its third coordinate, a grid of
small panels at one scale; :func:`view3d_figure` a static 3D view of its boundary points, coloured by the third
coordinate. Both are built on :class:`matplotlib.figure.Figure` objects (no pyplot state; matplotlib is
imported inside the functions), at the report's width with text at least
:data:`~pmaccuracy._savefig.MIN_TEXT_PX` high when shown :data:`~pmaccuracy._savefig.NARROW_DISPLAY_PX` wide,
and saved with :func:`~pmaccuracy._savefig.save_figure` in the format the file's suffix names.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .._savefig import DEFAULT_DPI, min_font_pt, save_figure
from ..errors import ConfigError
from ..kinematics.workspace3d import Workspace3D

#: Width of the figures (inches): the report's width.
WIDTH_IN = 7.5
#: Font sizes (points): tick labels and notes | titles.
FONT_PT = math.ceil(2 * min_font_pt(WIDTH_IN)) / 2
TITLE_PT = FONT_PT + 1
#: At most this many slice panels side by side (each stays readable at 400 px).
MAX_COLUMNS = 2
#: At most this many boundary points drawn in the 3D view (a random subset, the same for every call).
MAX_VIEW_POINTS = 20000
FILL_COLOUR = "#9ecae1"
EDGE_COLOUR = "#08306b"


def axis_label(ws: Workspace3D, axis: int) -> str:
    """``"<name> [<unit>]"`` of one of the workspace's coordinates."""
    return f"{ws.names[axis]} [{ws.units[axis]}]" if ws.units[axis] else ws.names[axis]


def subsample(points: np.ndarray, max_points: int = MAX_VIEW_POINTS, seed: int = 0) -> np.ndarray:
    """At most ``max_points`` of ``points`` (a random subset in their original order, reproducible)."""
    points = np.asarray(points)
    if len(points) <= max_points:
        return points
    keep = np.sort(np.random.default_rng(seed).choice(len(points), size=max_points, replace=False))
    return points[keep]


def _fmt(value: float) -> str:
    return f"{value:.4g}"


def value_with_error(value: float, error: float) -> str:
    """``"value +- error"`` with the error to two significant digits and the value to the same decimals.

    >>> value_with_error(104718.97, 517.86)
    '104719 ± 518'
    >>> value_with_error(4.18879, 0.0123)
    '4.189 ± 0.012'
    """
    if not (np.isfinite(error) and error > 0):
        return f"{value:.6g} ± {error:g}"
    decimals = max(0, 1 - math.floor(math.log10(error)))
    return f"{value:.{decimals}f} ± {error:.{decimals}f}"


def slices_figure(ws: Workspace3D, values: Sequence[float], *, title: str = "workspace slices",
                  axis: int = 2):
    """Cross-sections of ``ws`` at ``values`` of coordinate ``axis`` (default the third): one panel per value,
    :data:`MAX_COLUMNS` per row, all at one scale (the region's extent over the two other coordinates, equal
    aspect when their units agree). Each panel fills the cells of the nearest grid layer whose centres are
    inside (the contour half-way between inside and outside centres) and marks the boundary points found by
    bisection in that layer; its title gives the layer's coordinate. An empty layer says so.
    Returns a :class:`matplotlib.figure.Figure` with an Agg canvas.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    from matplotlib.ticker import MaxNLocator

    values = [float(v) for v in np.atleast_1d(np.asarray(values, dtype=float))]
    if not values:
        raise ConfigError("needs at least one value", key="values")
    layers = [ws.slice_value(axis, v) for v in values]           # checks axis and the values first
    a_ax, b_ax = [d for d in range(3) if d != axis]
    if ws.is_empty:
        (a0, a1), (b0, b1) = ws.box[a_ax], ws.box[b_ax]
    else:
        bb = ws.bounding_box
        pad_a = 0.06 * (bb[a_ax, 1] - bb[a_ax, 0]) + ws.cell[a_ax]
        pad_b = 0.06 * (bb[b_ax, 1] - bb[b_ax, 0]) + ws.cell[b_ax]
        a0, a1, b0, b1 = bb[a_ax, 0] - pad_a, bb[a_ax, 1] + pad_a, bb[b_ax, 0] - pad_b, bb[b_ax, 1] + pad_b
    equal = ws.units[a_ax] == ws.units[b_ax]
    cols = min(MAX_COLUMNS, len(values))
    rows = math.ceil(len(values) / cols)
    left, right, gap_x = 0.95, 0.25, 0.85
    panel_w = (WIDTH_IN - left - right - gap_x * (cols - 1)) / cols
    aspect = (b1 - b0) / (a1 - a0) if equal else 0.8
    panel_h = float(np.clip(panel_w * aspect, 1.2, 4.0))
    top, gap_y, bottom = 0.75, 0.95, 1.05
    height = top + rows * panel_h + (rows - 1) * gap_y + bottom
    fig = Figure(figsize=(WIDTH_IN, height))
    FigureCanvasAgg(fig)
    fig.suptitle(title, fontsize=TITLE_PT + 1, y=1 - 0.22 / height, va="top")
    for k, (v, layer) in enumerate(zip(values, layers)):
        r, c = divmod(k, cols)
        x0 = left + c * (panel_w + gap_x)
        y0 = height - top - (r + 1) * panel_h - r * gap_y
        ax = fig.add_axes((x0 / WIDTH_IN, y0 / height, panel_w / WIDTH_IN, panel_h / height))
        grid, a, b = ws.slice(axis, v)
        if grid.any():
            ax.contourf(a, b, grid.T.astype(float), levels=[0.5, 1.5], colors=[FILL_COLOUR])
            pts = ws.slice_boundary(axis, v)
            ax.plot(pts[:, a_ax], pts[:, b_ax], ".", color=EDGE_COLOUR, markersize=2.0)
        else:
            ax.text(0.5, 0.5, "empty", transform=ax.transAxes, ha="center", va="center", fontsize=FONT_PT,
                    color="0.4")
        ax.set_xlim(a0, a1)
        ax.set_ylim(b0, b1)
        if equal:
            ax.set_aspect("equal", adjustable="box")
        ax.set_title(f"{ws.names[axis]} = {_fmt(layer)} {ws.units[axis]}", fontsize=TITLE_PT)
        ax.set_xlabel(axis_label(ws, a_ax), fontsize=FONT_PT)
        ax.set_ylabel(axis_label(ws, b_ax), fontsize=FONT_PT)
        ax.tick_params(labelsize=FONT_PT)
        ax.xaxis.set_major_locator(MaxNLocator(4))
        ax.yaxis.set_major_locator(MaxNLocator(5))
        ax.grid(True, color="0.9", linewidth=0.6)
        ax.set_axisbelow(True)
    handles = [Patch(facecolor=FILL_COLOUR, label="inside (grid cells)"),
               Line2D([], [], marker=".", linestyle="", color=EDGE_COLOUR, markersize=6,
                      label="boundary (bisection)")]
    fig.legend(handles=handles, loc="lower center", ncol=2, frameon=False, fontsize=FONT_PT,
               bbox_to_anchor=(0.5, 0.05 / height))
    return fig


def save_slices_figure(ws: Workspace3D, path: str | os.PathLike, values: Sequence[float], *,
                       title: str = "workspace slices", axis: int = 2, dpi: int = DEFAULT_DPI) -> Path:
    """Write :func:`slices_figure` to ``path`` in the format its suffix names; returns the path."""
    fig = slices_figure(ws, values, title=title, axis=axis)
    out = save_figure(fig, path, dpi=dpi)
    fig.clear()
    return out


def view3d_figure(ws: Workspace3D, *, title: str = "workspace", max_points: int = MAX_VIEW_POINTS,
                  elev: float = 24.0, azim: float = -58.0):
    """A static 3D view (``mpl_toolkits.mplot3d``) of the boundary points of ``ws``, coloured by the third
    coordinate (colour bar), at most ``max_points`` of them (a reproducible random subset; the note under the
    view says how many). Equal scales when the three units agree. Returns a Figure with an Agg canvas.
    An empty workspace raises :class:`~pmaccuracy.errors.EmptyWorkspaceError`.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    ws.require_nonempty()
    pts = ws.boundary_points
    shown = subsample(pts, max_points)
    height = 6.6
    fig = Figure(figsize=(WIDTH_IN, height))
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0.0, 0.18, 0.76, 0.72), projection="3d")
    sc = ax.scatter(shown[:, 0], shown[:, 1], shown[:, 2], c=shown[:, 2], cmap="viridis", s=1.5,
                    depthshade=False, linewidths=0)
    bb = ws.bounding_box
    if len(set(ws.units)) == 1:
        ext = np.maximum(bb[:, 1] - bb[:, 0], 1e-12 * max(1.0, float(np.abs(bb).max())))
        ax.set_box_aspect(ext / ext.max())
    for d, (set_lim, axis) in enumerate(((ax.set_xlim, ax.xaxis), (ax.set_ylim, ax.yaxis),
                                         (ax.set_zlim, ax.zaxis))):
        set_lim(bb[d, 0], bb[d, 1])
        axis.set_major_locator(MaxNLocator(4))
    ax.set_xlabel(axis_label(ws, 0), fontsize=FONT_PT, labelpad=14)
    ax.set_ylabel(axis_label(ws, 1), fontsize=FONT_PT, labelpad=16)
    ax.set_zlabel(axis_label(ws, 2), fontsize=FONT_PT, labelpad=12)
    ax.tick_params(labelsize=FONT_PT)
    ax.view_init(elev=elev, azim=azim)
    fig.suptitle(title, fontsize=TITLE_PT + 1, y=1 - 0.2 / height, va="top")
    cax = fig.add_axes((0.82, 0.22, 0.025, 0.58))
    cb = fig.colorbar(sc, cax=cax)
    cb.set_label(axis_label(ws, 2), fontsize=FONT_PT)
    cb.ax.tick_params(labelsize=FONT_PT)
    cb.ax.yaxis.set_major_locator(MaxNLocator(5))
    u = "\u00b7".join(ws.units) if len(set(ws.units)) > 1 else f"{ws.units[0]}$^3$"
    fig.text(0.5, 0.02, f"{len(shown)} of {len(pts)} boundary points shown; volume "
             f"{value_with_error(ws.volume, ws.volume_error)} {u}",
             ha="center", va="bottom", fontsize=FONT_PT)
    return fig


def save_view3d_figure(ws: Workspace3D, path: str | os.PathLike, *, title: str = "workspace",
                       dpi: int = DEFAULT_DPI, **kwargs) -> Path:
    """Write :func:`view3d_figure` to ``path`` in the format its suffix names; returns the path."""
    fig = view3d_figure(ws, title=title, **kwargs)
    out = save_figure(fig, path, dpi=dpi)
    fig.clear()
    return out
