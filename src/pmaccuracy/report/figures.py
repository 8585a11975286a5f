"""Figures of error maps like the paper's Figs. 9-12 (Sec. 6).

Figures are built on :class:`matplotlib.figure.Figure` objects (no pyplot state),
so they can be made in threads, and saved with :func:`save_figure` in the format the file's extension names
(PNG at 200 dpi by default, PDF, SVG, JPEG, ...). The map figures
place their axes at fixed positions (:func:`panel_grid`: a grid of panels, each with a colour bar
of exactly its height) instead of running a layout engine, which costs more than drawing them.
Figures are at most :data:`REPORT_WIDTH_IN` wide so that the report shows them at their natural size.

:class:`Renderer` builds and saves figures in worker processes
(``concurrent.futures.ProcessPoolExecutor``), for reports with many figures.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from ..errors import ConfigError
from ..kinematics import DEFAULT_MAX_CONDITION, inverse_kinematics, regular_mask, singularity
from ..kinematics.workspace import constant_orientation_workspace
from ..model.manipulator import Manipulator
from .._savefig import (DEFAULT_DPI, FIGURE_TYPES, MIN_TEXT_PX, NARROW_DISPLAY_PX,  # noqa: F401  (re-exported)
                        SYMBOLS, check_dpi, figure_format, legible, min_font_pt, quantity_label, save_figure,
                        smallest_text_px)

#: Panels of a four-panel map: variable, measured-data key, title, units (:data:`SYMBOLS`, one notation).
PANELS = tuple((var, key, *SYMBOLS[var]) for var, key in
               (("dx_max", "dx"), ("dy_max", "dy"), ("dp_max", "dp"), ("dphi_max", "dphi_deg")))


#: Colour scales are clipped at this percentile of a map when the values above it (near-singular
#: edges of a 3-RRR or 3-PRR workspace) would take more than half of the colour range.
CLIP_PERCENTILE = 95.0
#: Size of the figures in the reports: at most this wide (inches). The HTML report shows a figure at most
#: 100 px per inch wide (750 px) and down to the screen's width; text is at least :data:`FONT_PT`, which
#: :func:`~pmaccuracy._savefig.min_font_pt` makes 8 px high on a 400 px wide screen.
REPORT_WIDTH_IN = 7.5
#: At most this many map panels side by side (more go to further rows), so each stays readable at 400 px.
MAX_COLUMNS = 2
#: Font sizes (points) of the report's figures: tick labels, legends and notes | axis labels | titles.
FONT_PT = math.ceil(2 * min_font_pt(REPORT_WIDTH_IN)) / 2
LABEL_PT = FONT_PT
TITLE_PT = FONT_PT + 1
SUPTITLE_PT = FONT_PT + 2


@dataclass(frozen=True)
class ColourRange:
    """Colour limits of a map: ``lo, hi`` (units of the map); ``clipped`` when ``hi`` is the
    :data:`CLIP_PERCENTILE` percentile and the map goes on up to ``top``."""

    lo: float
    hi: float
    clipped: bool = False
    top: float = float("nan")
    #: whether ``hi`` is the user's ``vmax`` (else the :data:`CLIP_PERCENTILE` percentile when clipped)
    user: bool = False


def colour_range(values: np.ndarray, extra: np.ndarray | None = None,
                 percentile: float = CLIP_PERCENTILE) -> ColourRange:
    """Colour range over a map (and measured values ``extra``); a constant field gets a +-1 % band.

    ``lo`` is the smallest value; ``hi`` the largest, unless the map's values above its
    ``percentile``-th percentile ``p`` span more than the values below (``max - p > p - min``): then
    ``hi = max(p, largest measured value)`` and the range is ``clipped`` (the colour bar says so).
    """
    field = np.asarray(values, dtype=float)
    field = field[np.isfinite(field)]
    pool = field
    if extra is not None:
        extra = np.asarray(extra, dtype=float)
        pool = np.concatenate([pool, extra[np.isfinite(extra)]])
    if pool.size == 0:
        return ColourRange(0.0, 1.0)
    lo, hi = float(pool.min()), float(pool.max())
    if hi - lo <= 1e-9 * max(abs(hi), 1e-12):
        pad = max(0.01 * abs(hi), 1e-9)
        return ColourRange(lo - pad, hi + pad)
    if field.size:
        p = float(np.percentile(field, percentile))
        fmin, fmax = float(field.min()), float(field.max())
        if fmax - p > p - fmin:
            cap = p if extra is None or not np.isfinite(extra).any() else max(p, float(np.nanmax(extra)))
            if cap < hi:
                return ColourRange(lo, cap, True, hi)
    return ColourRange(lo, hi)


def _limits(values: np.ndarray, extra: np.ndarray | None) -> tuple[float, float]:
    """``(lo, hi)`` of :func:`colour_range` (kept for callers that want the plain limits)."""
    r = colour_range(values, extra)
    return r.lo, r.hi


def _field_box(x: np.ndarray, y: np.ndarray, Z: np.ndarray, margin: float = 0.04,
               loops: tuple[np.ndarray, ...] | None = None) -> tuple[float, ...]:
    """``(x0, x1, y0, y1)``: the finite part of a field (its workspace) plus a margin (mm); with the workspace's
    exact boundary ``loops`` (``(k, 2)`` arrays, mm), the box holds all of it too (it reaches past the grid
    points with a value, e.g. past near-singular blank rows)."""
    finite = np.isfinite(Z)
    if not finite.any() and not loops:
        return float(x.min()), float(x.max()), float(y.min()), float(y.max())
    xs, ys = x[finite.any(axis=0)], y[finite.any(axis=1)]
    if loops:
        pts = np.vstack(loops)
        xs, ys = np.concatenate([xs, pts[:, 0]]), np.concatenate([ys, pts[:, 1]])
    dx = (xs.max() - xs.min()) * margin + 1e-9
    dy = (ys.max() - ys.min()) * margin + 1e-9
    return float(xs.min() - dx), float(xs.max() + dx), float(ys.min() - dy), float(ys.max() + dy)


def panel_grid(fig: Figure, nrows: int, ncols: int, aspect: float, *, width: float = REPORT_WIDTH_IN,
               top: float = 0.75, bottom: float = 0.15, title_space: float = 0.4,
               label_lines: int = 2) -> list[tuple[Any, Any]]:
    """Place ``nrows x ncols`` map axes, each with a horizontal colour-bar axes of exactly its width under
    it, and size ``fig``.

    Every axes box has the height/width ratio ``aspect`` (clamped to [0.3, 1.4]) so that an equal-aspect
    map fills it; its colour bar sits under its x label, with room for its tick labels and a label of
    ``label_lines`` lines, so no colour-bar text reaches into the next panel. Each column keeps room for its
    own y tick labels and y label. ``top``/``bottom``: inches kept free for the title / a legend. Returns
    ``[(ax, cax), ...]`` row by row. Axes are placed at fixed positions (no layout engine, no divider).
    """
    aspect = float(np.clip(aspect, 0.3, 1.4))
    left, right = 0.95, 0.35                        # y tick labels + y label of each column | right margin
    ax_w = (width - right - ncols * left) / ncols
    ax_h = ax_w * aspect
    if ax_h > 4.2:                                  # tall workspaces: keep the figure on one screen
        ax_h = 4.2
        ax_w = ax_h / aspect
    under = 0.62                                    # x tick labels and x label
    bar_gap, bar_h, bar_text = 0.1, 0.13, 0.3 + 0.21 * label_lines
    row_h = title_space + ax_h + under + bar_gap + bar_h + bar_text
    height = top + nrows * row_h + bottom
    fig.set_size_inches(width, height)
    out = []
    for r in range(nrows):
        for c in range(ncols):
            x0 = left + c * (left + ax_w)
            y0 = height - top - r * row_h - title_space - ax_h
            ax = fig.add_axes((x0 / width, y0 / height, ax_w / width, ax_h / height))
            yb = y0 - under - bar_gap - bar_h
            cax = fig.add_axes((x0 / width, yb / height, ax_w / width, bar_h / height))
            out.append((ax, cax))
    return out


def fit_limits(ax, x0: float, x1: float, y0: float, y1: float) -> None:
    """Show at least ``[x0, x1] x [y0, y1]`` (mm) at equal scales in x and y without resizing the axes box:
    the shorter side of the data box is widened about its centre to the box's height/width ratio."""
    fig = ax.get_figure()
    pos = ax.get_position()
    ratio = (pos.height * fig.get_figheight()) / (pos.width * fig.get_figwidth())
    w, h = max(x1 - x0, 1e-9), max(y1 - y0, 1e-9)
    if h / w < ratio:
        cy, h = (y0 + y1) / 2, w * ratio
        y0, y1 = cy - h / 2, cy + h / 2
    else:
        cx, w = (x0 + x1) / 2, h / ratio
        x0, x1 = cx - w / 2, cx + w / 2
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal", adjustable="box")


def limited_range(rng: ColourRange, vmin: float | None = None, vmax: float | None = None) -> ColourRange:
    """``rng`` with the user's colour limits (units of the map): ``vmin``/``vmax`` replace ``lo``/``hi``; the
    range stays marked ``clipped`` (colour bar extended, maximum stated) when the map goes above ``vmax``.
    A lone ``vmin`` above the map's values (or ``vmax`` below them) keeps a 10 % range on its side."""
    if vmin is None and vmax is None:
        return rng
    top = rng.top if rng.clipped else rng.hi
    lo = rng.lo if vmin is None else float(vmin)
    hi = rng.hi if vmax is None else float(vmax)
    if not hi > lo and vmax is None:
        hi = lo + max(0.1 * abs(lo), 1e-9)
    elif not hi > lo and vmin is None:
        lo = hi - max(0.1 * abs(hi), 1e-9)
    if not hi > lo:
        raise ConfigError(f"the colour range is empty: vmin {lo:g} >= vmax {hi:g}", key="vmin")
    return ColourRange(lo, hi, bool(top > hi), top, user=vmax is not None)


def nice_step(step: float) -> float:
    """The smallest of 1, 2, 2.5, 5 x 10^k that is >= ``step`` (> 0).

    >>> nice_step(0.0013), nice_step(0.02), nice_step(3.1)
    (0.002, 0.02, 5.0)
    """
    k = math.floor(math.log10(step))
    for m in (1.0, 2.0, 2.5, 5.0, 10.0):
        value = round(m * 10.0 ** k, 12 - k if k < 0 else 12)
        if value >= step * (1 - 1e-12):
            return value
    return 10.0 ** (k + 1)


def monte_carlo_levels(lo: float, hi: float, error: float, max_levels: int = 12) -> np.ndarray:
    """Colour levels for a Monte Carlo map: a step no finer than its stated ``error`` (the map's units), so
    that sampling noise below the error cannot show as stripes; at most ``max_levels`` bands over ``[lo, hi]``.

    The step is :func:`nice_step` of ``max(error, (hi - lo) / max_levels)``; levels are multiples of it,
    from the one at or below ``lo`` to the one at or above ``hi``.

    >>> monte_carlo_levels(0.101, 0.118, 0.003)
    array([0.1  , 0.105, 0.11 , 0.115, 0.12 ])
    """
    if not (math.isfinite(error) and error > 0):
        raise ConfigError(f"the Monte Carlo error must be a finite value > 0, got {error!r}", key="error")
    span = max(hi - lo, 0.0)
    step = nice_step(max(error, span / max_levels, 1e-300))
    first = math.floor(lo / step + 1e-9)
    last = max(math.ceil(hi / step - 1e-9), first + 1)
    return np.round(np.arange(first, last + 1) * step, 12)


def _renderer(fig: Figure):
    """A renderer measuring text as the figure will draw it: its canvas's, else an Agg one at the figure's size
    and dpi (a bare ``Figure()`` has no renderer until it is saved)."""
    get = getattr(fig.canvas, "get_renderer", None)
    if get is not None:
        return get()
    from matplotlib.backends.backend_agg import RendererAgg

    w, h = fig.get_size_inches() * fig.dpi
    return RendererAgg(max(int(w), 1), max(int(h), 1), fig.dpi)


def _on_field(ax, box, field, region, n: int = 5) -> bool:
    """Whether an ``n x n`` grid of points over ``box`` (display units) lies on finite cells of ``field``
    ``(x, y, Z)`` (nearest grid point) and inside ``region`` (a Path in data units); either may be None."""
    u, v = np.meshgrid(np.linspace(box.x0, box.x1, n), np.linspace(box.y0, box.y1, n))
    pts = ax.transData.inverted().transform(np.column_stack([u.ravel(), v.ravel()]))
    if region is not None and not region.contains_points(pts).all():
        return False
    if field is not None:
        x, y, Z = field
        ix = np.clip(np.searchsorted(x, pts[:, 0]), 1, len(x) - 1)
        ix -= (pts[:, 0] - x[ix - 1]) < (x[ix] - pts[:, 0])
        iy = np.clip(np.searchsorted(y, pts[:, 1]), 1, len(y) - 1)
        iy -= (pts[:, 1] - y[iy - 1]) < (y[iy] - pts[:, 1])
        if not np.isfinite(Z[iy, ix]).all():
            return False
    return True


def text_width_in(fig: Figure, text: str, fontsize: float) -> float:
    """Width (inches) of ``text`` (one or more lines, mathtext allowed) at ``fontsize`` as ``fig`` draws it."""
    from matplotlib.text import Text

    probe = Text(0, 0, text, fontsize=fontsize, figure=fig)
    return probe.get_window_extent(_renderer(fig)).width / fig.dpi


def wrap_text(fig: Figure, text: str, width_in: float, fontsize: float) -> str:
    """``text`` with line breaks so that no line is wider than ``width_in`` inches at ``fontsize`` (measured,
    words kept whole, a ``$...$`` formula one word; existing line breaks kept)."""
    import re

    out = []
    for para in text.split("\n"):
        line = ""
        for word in re.findall(r"(?:\$[^$]*\$|[^\s$])+", para):
            trial = f"{line} {word}" if line else word
            if line and text_width_in(fig, trial, fontsize) > width_in:
                out.append(line)
                line = word
            else:
                line = trial
        out.append(line)
    return "\n".join(out)


def label_contours(ax, cs, *, fontsize: float = FONT_PT, fmt: str = "%.3g", colors: str = "white",
                   pad_pt: float = 2.0, field: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
                   region=None) -> list:
    """Label the contour lines ``cs`` of ``ax`` with their values, keeping only labels whose drawn boxes (rotation
    included, measured by the renderer, plus ``pad_pt``) lie inside the axes and clear of every label kept
    before them, so crowded contours (near a singular edge) keep readable labels. With ``field`` ``(x, y, Z)``
    (the drawn field) and ``region`` (a matplotlib Path in data units, e.g. the workspace outline) a label
    must also lie on coloured cells (finite ``Z``, nearest grid point) inside ``region``: white text is not
    left on the blank page. The kept labels are then placed inline (the lines broken under them only).
    Returns the labels."""
    fig = ax.get_figure()
    renderer = _renderer(fig)
    pad = pad_pt * fig.dpi / 72.0
    frame = ax.get_window_extent(renderer)
    trial = ax.clabel(cs, inline=False, fontsize=fontsize, fmt=fmt, colors=colors)
    kept, places = [], []
    for label in trial:
        b = label.get_window_extent(renderer).padded(pad)
        inside = frame.x0 <= b.x0 and b.x1 <= frame.x1 and frame.y0 <= b.y0 and b.y1 <= frame.y1
        if inside and (field is not None or region is not None):
            inside = _on_field(ax, b, field, region)
        if inside and not any(b.overlaps(k) for k in kept):
            kept.append(b)
            places.append(label.get_position())
    while cs.labelTexts:
        cs.pop_label()
    if not places:
        return []
    return ax.clabel(cs, inline=True, fontsize=fontsize, fmt=fmt, colors=colors, manual=places)


#: How the maps draw the singular places: the near-singular cells (left blank by the maps) hatched in this
#: colour, the parallel singularity det A = 0 as a line of this colour.
SINGULAR_COLOUR = "tab:red"


@dataclass(frozen=True)
class MapShape:
    """What a map's layer needs besides its values to be drawn true to the robot (mm, on the map's grid).

    ``loops``: the exact workspace boundary (:func:`~pmaccuracy.kinematics.workspace.constant_orientation_workspace`);
    ``near_singular`` ``(ny, nx)``: grid points inside the joint ranges but near a singularity (condition of
    A above ``max_condition`` or a leg's transmission below its inverse), where the maps have no value;
    ``det`` ``(ny, nx)``: det A inside the joint ranges (NaN outside), whose zero line is the parallel
    singularity.
    """

    loops: tuple[np.ndarray, ...]
    near_singular: np.ndarray
    det: np.ndarray
    max_condition: float

    @property
    def has_singular(self) -> bool:
        return bool(self.near_singular.any())

    @property
    def crosses_det_zero(self) -> bool:
        d = self.det[np.isfinite(self.det)]
        return bool(d.size and d.min() < 0 < d.max())

    def outline(self, Z: np.ndarray) -> tuple[tuple[np.ndarray, ...], np.ndarray]:
        """``(loops, keep_blank)`` for :func:`_draw_field` drawing the field ``Z`` of this grid: the blank cells
        to keep blank are those inside the joint ranges (near-singular, outside the map's region, ...); only
        the blank cells outside the workspace next to it are filled so that the field reaches the boundary."""
        return self.loops, self.near_singular | (np.isfinite(self.det) & ~np.isfinite(Z))


def map_shape(robot, phi_deg: float, x: np.ndarray, y: np.ndarray, max_condition: float | None = None) -> MapShape:
    """The :class:`MapShape` of ``robot`` at ``phi_deg`` (deg) on the grid ``x`` ``(nx,)``, ``y`` ``(ny,)`` (mm),
    with the maps' singularity test (:func:`pmaccuracy.kinematics.regular_mask`, default
    :data:`~pmaccuracy.kinematics.DEFAULT_MAX_CONDITION`)."""
    mc = DEFAULT_MAX_CONDITION if max_condition is None else float(max_condition)
    phi = math.radians(float(phi_deg))
    X, Y = np.meshgrid(np.asarray(x, float), np.asarray(y, float))
    poses = np.stack([X, Y, np.full_like(X, phi)], axis=-1)
    inside = inverse_kinematics(robot, poses).within_limits
    with np.errstate(all="ignore"):
        near = inside & ~regular_mask(robot, poses, mc)
        det = np.where(inside, singularity(robot, poses).det, np.nan)
    ws = constant_orientation_workspace(robot, phi)
    return MapShape(tuple(ws.loops), near, det, mc)


def panel_shapes(shapes, panels) -> list[MapShape | None]:
    """The :class:`MapShape` of each panel of :func:`plot_panels` (None where ``shapes`` has none)."""
    if shapes is None:
        return [None] * len(panels)
    if len(shapes) != len(panels):
        raise ValueError(f"plot_panels: {len(shapes)} shapes for {len(panels)} panels")
    out = []
    for shape, (x, y, *_rest) in zip(shapes, panels):
        if shape is None or isinstance(shape, MapShape):
            out.append(shape)
        else:
            robot, phi_deg = shape
            out.append(None if robot is None else map_shape(robot, phi_deg, x, y))
    return out


def _robot_of(ds: xr.Dataset):
    """The robot a map was computed for, from its ``robot_toml`` attribute (None when the map has none)."""
    text = ds.attrs.get("robot_toml")
    if not text:
        return None
    return Manipulator.from_toml_string(text, source="the map's robot_toml")


def _widen(Z: np.ndarray, keep_blank: np.ndarray, passes: int = 2) -> np.ndarray:
    """``Z`` with the blank cells next to its values given their neighbours' mean, ``passes`` times (cells in
    ``keep_blank`` stay blank): drawing only, so the field reaches the workspace boundary it is clipped to."""
    out = np.array(Z, dtype=float)
    for _ in range(passes):
        finite = np.isfinite(out)
        padded = np.pad(np.where(finite, out, 0.0), 1)
        count = np.pad(finite.astype(float), 1)
        total = padded[:-2, 1:-1] + padded[2:, 1:-1] + padded[1:-1, :-2] + padded[1:-1, 2:]
        n = count[:-2, 1:-1] + count[2:, 1:-1] + count[1:-1, :-2] + count[1:-1, 2:]
        grow = ~finite & (n > 0) & ~keep_blank
        out[grow] = total[grow] / n[grow]
    return out


def _outline(ax, mesh, loops):
    """Clip ``mesh`` to the workspace ``loops`` (holes kept) and draw the boundary as a thin black line; returns
    the boundary as a Path in data units (None without loops)."""
    from matplotlib.patches import PathPatch
    from matplotlib.path import Path as MplPath

    if not loops:
        return None
    verts, codes = [], []
    for loop in loops:
        verts.append(loop)
        codes += [MplPath.MOVETO] + [MplPath.LINETO] * (len(loop) - 2) + [MplPath.CLOSEPOLY]
    path = MplPath(np.vstack(verts), codes)
    mesh.set_clip_path(PathPatch(path, transform=ax.transData))
    ax.add_patch(PathPatch(path, facecolor="none", edgecolor="black", linewidth=0.8, zorder=3,
                           label="workspace boundary"))
    return path


def _singular_entries(shape: MapShape) -> dict[str, str]:
    """The legend entries of what :func:`draw_singular` draws for ``shape``: ``{label: "hatch" | "line"}``."""
    out = {}
    if shape.has_singular:
        out[f"near-singular (cond. A > {shape.max_condition:g} or a leg's transmission < "
            f"{1 / shape.max_condition:g}): no bound, left blank"] = "hatch"
    if shape.crosses_det_zero:
        out["parallel singularity (det A = 0)"] = "line"
    return out


def _singular_handle(kind: str, label: str):
    """A legend handle of :func:`draw_singular`'s hatching (``"hatch"``) or det A = 0 line (``"line"``)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    if kind == "hatch":
        return Patch(facecolor="white", edgecolor=SINGULAR_COLOUR, hatch="////", label=label)
    return Line2D([], [], color=SINGULAR_COLOUR, linewidth=1.6, label=label)


def draw_singular(ax, x: np.ndarray, y: np.ndarray, shape: MapShape) -> list:
    """Hatch the near-singular part of the grid (the maps' blank cells there) and draw det A = 0; returns the
    legend handles of what was drawn (none on a map without singular places)."""
    if shape.has_singular:
        ax.contourf(x, y, shape.near_singular.astype(float), levels=[0.5, 1.5], colors="none",
                    hatches=["////"], zorder=2.5)
        for coll in ax.collections[-1:]:
            coll.set_edgecolor(SINGULAR_COLOUR)
            coll.set_linewidth(0.0)
    if shape.crosses_det_zero:
        ax.contour(x, y, shape.det, levels=[0.0], colors=SINGULAR_COLOUR, linewidths=1.6, zorder=4)
    return [_singular_handle(kind, label) for label, kind in _singular_entries(shape).items()]


def _draw_field(fig: Figure, ax, cax, x: np.ndarray, y: np.ndarray, Z: np.ndarray, label: str, units: str, *,
                rng: ColourRange | None = None, extra: np.ndarray | None = None, contours: bool = True,
                cmap: str = "viridis", log: bool = False, error: float | None = None,
                box: tuple[float, float, float, float] | None = None,
                outline: tuple[list[np.ndarray], np.ndarray] | None = None) -> Any:
    """One map panel: the field, labelled contour lines (their levels also marked on the colour bar) and a
    colour bar labelled ``label [units]``, noting a clipped scale.

    ``log``: logarithmic colour scale (values <= 0 left blank). ``error`` (units of the map): a Monte Carlo
    map's stated error; the colours come in discrete bands of :func:`monte_carlo_levels` (step >= error),
    and the colour bar states both (``log`` does not apply to such a panel: its bands stay linear). ``box``: axis limits ``(x0, x1, y0, y1)`` in mm (default: the field's
    own workspace), e.g. one box for every panel of a comparison. ``outline``: ``(loops, keep_blank)`` from
    :func:`workspace_outline`: the field is clipped to the workspace's exact boundary (drawn as a line)
    instead of ending in grid cells; ``keep_blank`` marks the blank cells not to be filled (near-singular).
    A colour-bar axes wider than high gets a horizontal colour bar.
    """
    from matplotlib.colors import BoundaryNorm, LogNorm, Normalize
    from matplotlib.ticker import LogLocator, MaxNLocator

    rng = rng or colour_range(Z, extra)
    finite = Z[np.isfinite(Z)]
    lo, hi = rng.lo, rng.hi
    levels = None
    log = log and error is None              # a Monte Carlo map keeps its bands of the stated error
    if log:
        positive = finite[finite > 0]
        lo = lo if lo > 0 else (float(positive.min()) if positive.size else 1e-12)
        hi = max(hi, lo * 10 ** 0.01)
        norm = LogNorm(vmin=lo, vmax=hi)
        levels = LogLocator(subs=(1.0, 2.0, 5.0)).tick_values(lo, hi)
    elif error is not None:
        levels = monte_carlo_levels(lo, hi, error)
        norm = BoundaryNorm(levels, ncolors=256, extend="max" if rng.clipped else "neither")
    else:
        norm = Normalize(vmin=lo, vmax=hi)
        levels = MaxNLocator(6).tick_values(lo, hi)
    shown = Z if outline is None else _widen(Z, outline[1])
    mesh = ax.pcolormesh(x, y, shown, shading="auto", cmap=cmap, norm=norm)
    fit_limits(ax, *(box or _field_box(x, y, Z, loops=None if outline is None else outline[0])))
    region = None if outline is None else _outline(ax, mesh, outline[0])
    cpos = cax.get_position()
    horizontal = cpos.width * fig.get_figwidth() > cpos.height * fig.get_figheight()
    cbar = fig.colorbar(mesh, cax=cax, extend="max" if rng.clipped else "neither",
                        orientation="horizontal" if horizontal else "vertical")
    if horizontal and not log and error is None:
        ticks = MaxNLocator(4).tick_values(lo, hi)
        cbar.set_ticks(ticks[(ticks >= lo - 1e-9 * abs(hi)) & (ticks <= hi + 1e-9 * abs(hi))])
    elif horizontal and log:                                      # decades only, no crowded minor labels
        from matplotlib.ticker import NullFormatter

        cbar.ax.xaxis.set_minor_formatter(NullFormatter())
    elif horizontal and error is not None and len(levels) > 5:     # every k-th band edge: at most 5 labels
        cbar.set_ticks(levels[::math.ceil(len(levels) / 5)])
    constant = finite.size == 0 or float(np.ptp(finite)) <= 1e-9 * max(float(np.max(np.abs(finite))), 1e-300)
    if contours and not constant:
        inner = levels[(levels > float(finite.min())) & (levels < min(float(finite.max()), hi))]
        if inner.size > 8:                                  # keep the map readable: every other level
            inner = inner[::2]
        if inner.size:
            cs = ax.contour(x, y, Z, levels=inner, colors="white", linewidths=0.7, alpha=0.9)
            label_contours(ax, cs, field=(x, y, shown), region=region)
            cbar.add_lines(cs)
    text = f"{label} [{units}]" if label else units
    if log:
        text += ", log scale"
    if error is not None:
        step = float(levels[1] - levels[0])
        text += f"\nsteps {step:.2g} >= Monte Carlo error {error:.2g}"
    if rng.clipped:
        at = f"vmax {rng.hi:.3g}" if rng.user else f"{CLIP_PERCENTILE:g}th pct."
        text += f"\nclipped at {at} (max {rng.top:.3g})"
    cbar.set_label(text, fontsize=FONT_PT)
    cbar.ax.tick_params(labelsize=FONT_PT)
    return mesh


def plot_error_map(ds: xr.Dataset, phi_deg: float, *, measured: Mapping[str, np.ndarray] | None = None,
                   title: str | None = None, scale: float = 1.0, vmin: float | None = None,
                   vmax: float | None = None, log: bool = False, data: str = "measured", robot=None,
                   max_condition: float | None = None) -> Figure:
    """Four panels (dx_max, dy_max, dp_max in mm; dphi_max in deg) over the workspace at ``phi_deg``.

    ``measured`` points are named ``data`` in the legend ("simulated" for a virtual experiment's).

    Each panel fills a box of the workspace's aspect ratio with a colour bar of exactly its width under it
    (:func:`panel_grid`), labelled with what is drawn, factor included (``2 x dx_max [mm]``). Contour
    lines are labelled with their values and marked on the colour bar. A constant field says so in its
    title. Colour scales dominated by near-singular edges are clipped (:func:`colour_range`).

    With the robot (``robot``, else the map's own ``robot_toml`` attribute) the field is clipped to the exact
    workspace boundary, drawn as a line, and the singular places are drawn (:func:`draw_singular`): the grid
    points the map leaves blank near a singularity are hatched and the parallel singularity det A = 0 is a
    line, both named in the legend under the title. ``max_condition``: the map's singularity threshold
    (default :data:`~pmaccuracy.kinematics.DEFAULT_MAX_CONDITION`, the maps' own).

    Parameters
    ----------
    ds : a map from :func:`pmaccuracy.accuracy.maps.error_map`
    phi_deg : orientation layer to draw (deg)
    measured : optional measured points, arrays keyed ``x, y`` (mm) and ``dx, dy, dp`` (mm),
        ``dphi_deg`` (deg), drawn as dots coloured on the same scale with black rims; their legend
        goes under the title, outside the maps
    scale : factor applied to the predicted maxima before drawing (e.g. 2 for the
        width-consistent comparison with measured ranges)
    vmin, vmax : colour limits of the three length panels (mm); the dphi_max panel (deg) keeps its own range
    log : logarithmic colour scales

    Contour lines are labelled with their values; the title names the robot, the clearances and phi.
    """
    from matplotlib.lines import Line2D

    layer = ds.sel(phi=phi_deg, method="nearest")
    x, y = layer.x.values, layer.y.values
    robot = robot if robot is not None else _robot_of(ds)
    shape = None if robot is None else map_shape(robot, float(layer.phi), x, y, max_condition)
    x0, x1, y0, y1 = _field_box(x, y, layer["dp_max"].values, loops=None if shape is None else shape.loops)
    handles = []
    if measured is not None:
        handles.append(Line2D([], [], linestyle="none", marker="o", markersize=6, markerfacecolor="white",
                              markeredgecolor="black",
                              label=f"{data} points, filled with the {data} value on the map's colour scale"))
    singular = shape is not None and (shape.has_singular or shape.crosses_det_zero)
    n_legend = len(handles) + (shape.has_singular + shape.crosses_det_zero if singular else 0)
    fig = Figure()
    cells = panel_grid(fig, 2, 2, (y1 - y0) / max(x1 - x0, 1e-9), top=0.55 + 0.3 * n_legend)
    prefix = f"{scale:g} x " if scale != 1 else ""
    drawn: list = []
    for (ax, cax), (var, mkey, label, units) in zip(cells, PANELS):
        values = layer[var].values * scale
        extra = None if measured is None else np.asarray(measured[mkey], dtype=float)
        rng = colour_range(values, extra)
        if units == "mm":
            rng = limited_range(rng, vmin, vmax)
        _draw_field(fig, ax, cax, x, y, values, prefix + label, units, rng=rng, extra=extra, log=log,
                    outline=None if shape is None else shape.outline(values))
        if shape is not None:
            drawn = draw_singular(ax, x, y, shape)
        panel_title = f"{prefix}{label} [{units}]" + constant_note(values, units)
        if measured is not None:
            ax.scatter(measured["x"], measured["y"], c=extra, cmap="viridis", vmin=rng.lo, vmax=rng.hi, s=30,
                       edgecolors="black", linewidths=0.9, label=data, zorder=5)
        ax.set_title(panel_title, fontsize=TITLE_PT)
        ax.set_xlabel("x [mm]", fontsize=LABEL_PT)
        ax.set_ylabel("y [mm]", fontsize=LABEL_PT)
        ax.tick_params(labelsize=FONT_PT)
    handles += drawn
    if handles:
        fig.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, 1 - 0.45 / fig.get_figheight()),
                   frameon=False, fontsize=FONT_PT, handlelength=1.6)
    fig.suptitle(title or f"{ds.attrs.get('robot', '')}, clearances {ds.attrs.get('clearances', '')}, "
                          f"$\\phi$ = {float(layer.phi):g} deg", fontsize=SUPTITLE_PT,
                 y=1 - 0.1 / fig.get_figheight(), va="top")
    return fig


def plot_layers(ds: xr.Dataset, var: str, *, title: str | None = None, robot=None) -> Figure:
    """One variable of a map at every orientation, side by side on a common colour scale (at most
    :data:`MAX_COLUMNS` a row): :func:`plot_panels` with ``shared_scale``.

    With the robot (``robot``, else the map's own ``robot_toml`` attribute) each panel is clipped to the exact
    workspace boundary of its orientation and its singular places are drawn, as in :func:`plot_error_map`.
    """
    units = ds[var].attrs.get("units", "")
    x, y = ds.x.values, ds.y.values
    robot = robot if robot is not None else _robot_of(ds)
    phis = [float(p) for p in ds.phi.values]
    panels = [(x, y, ds[var].sel(phi=phi).values, f"$\\phi$ = {phi:g} deg", quantity_label(var, units))
              for phi in phis]
    return plot_panels(panels, shared_scale=True, contours=True,
                       shapes=None if robot is None else [(robot, phi) for phi in phis],
                       suptitle=title or f"{ds.attrs.get('robot', '')}, clearances "
                                         f"{ds.attrs.get('clearances', '')}: {quantity_label(var, units)}")


def save(fig: Figure, path: str | Path, dpi: int = DEFAULT_DPI) -> Path:
    """:func:`save_figure` (the format its extension names, ``dpi`` for raster formats); returns the path."""
    return save_figure(fig, path, dpi=dpi)


def render(path: str | Path, build: Callable[..., Any], *args: Any, dpi: int = DEFAULT_DPI, **kwargs: Any) -> Path:
    """``save(build(*args, **kwargs), path)``: one job of a :class:`Renderer` (runs in a worker process).

    A ``build`` that writes ``path`` itself (returns no Figure) is just called.
    """
    result = build(*args, **kwargs)
    if isinstance(result, Figure):
        save(result, path, dpi=dpi)
    return Path(path)


class Renderer:
    """Build and save figures in worker processes while the caller goes on computing.

    ``submit(path, build, *args, **kwargs)`` queues ``build(*args, **kwargs)``
    (a module-level function returning a Figure; its arguments are pickled) and
    returns the path at once; leaving the ``with`` block waits for every figure
    and re-raises the first error. ``on_done`` is called (in a helper thread)
    after each figure, e.g. to advance a progress bar. ``workers=0`` renders in
    the calling process (same results, no pool).
    """

    def __init__(self, workers: int = 2, on_done: Callable[[], None] | None = None):
        self.workers = workers
        self.on_done = on_done
        self._pool: ProcessPoolExecutor | None = None
        self._futures: list[Future] = []

    def __enter__(self) -> Renderer:
        if self.workers > 0:
            import multiprocessing as mp

            # fork (where available) starts workers with numpy and matplotlib already imported
            context = mp.get_context("fork") if "fork" in mp.get_all_start_methods() else None
            self._pool = ProcessPoolExecutor(max_workers=self.workers, mp_context=context)
        return self

    def submit(self, path: str | Path, build: Callable[..., Figure], *args: Any, **kwargs: Any) -> Path:
        path = Path(path)
        if self._pool is None:
            render(path, build, *args, **kwargs)
            if self.on_done:
                self.on_done()
            return path
        future = self._pool.submit(render, path, build, *args, **kwargs)
        if self.on_done:
            future.add_done_callback(lambda _: self.on_done())
        self._futures.append(future)
        return path

    def compute(self, function: Callable[..., Any], *args: Any, **kwargs: Any) -> Future:
        """Run any module-level ``function(*args, **kwargs)`` in a worker; a Future of its (pickled) result."""
        if self._pool is None:   # in this process: the Future holds the result or the exception, as a worker's
            future: Future = Future()
            try:
                future.set_result(function(*args, **kwargs))
            except Exception as exc:   # noqa: BLE001 - handed to the caller through the Future
                future.set_exception(exc)
            return future
        return self._pool.submit(function, *args, **kwargs)

    def __exit__(self, exc_type, exc, tb) -> None:
        if self._pool is None:
            return
        try:
            if exc_type is None:
                for future in self._futures:
                    future.result()
        finally:
            self._pool.shutdown(wait=True, cancel_futures=exc_type is not None)


def constant_note(values: np.ndarray, units: str) -> str:
    """``": constant, V units"`` for a field whose finite values are all equal (to 1e-9 relative), else ``""``:
    a panel title says so instead of showing a flat colour against a meaningless colour bar."""
    finite = np.asarray(values)[np.isfinite(values)]
    if finite.size and float(np.ptp(finite)) <= 1e-9 * max(float(np.max(np.abs(finite))), 1e-300):
        return f": constant, {float(finite.max()):.4g} {units}"
    return ""


def plot_panels(panels: list[tuple[np.ndarray, np.ndarray, np.ndarray, str, str]], *, suptitle: str,
                shared_scale: bool = False, ncols: int | None = None, same_axes: bool = False,
                errors: list[float | None] | None = None, vmin: float | None = None, vmax: float | None = None,
                log: bool = False, limited: list[bool] | None = None, contours: bool = False,
                shapes: list | None = None) -> Figure:
    """Several scalar fields side by side: each panel is ``(x (n,), y (m,), Z (m, n), title, units)``
    (x, y in mm).

    With ``shared_scale`` every panel uses one colour range (for comparing designs); with ``same_axes``
    every panel shows the same x and y limits (the union of the fields' workspaces) in boxes of the same
    size, so that workspaces of different areas are drawn to one scale. Each colour bar has its panel's
    height (:func:`panel_grid`) and is labelled ``units`` (e.g. ``"dp_max [mm]"``). ``errors``: per panel a
    Monte Carlo error (units of the panel) or None: such a panel is drawn in colour bands no finer than its
    error (:func:`monte_carlo_levels`). ``vmin``/``vmax`` (units of the panels marked in ``limited``, default
    all) and ``log`` set the colour scales.

    ``shapes``: per panel ``(robot, phi_deg)`` (or a :class:`MapShape` of the panel's grid, or None): such a
    panel is clipped to the robot's exact workspace boundary at ``phi_deg`` (drawn as a line) instead of
    ending in grid cells, its near-singular blank cells are hatched and det A = 0 is drawn
    (:func:`draw_singular`), named in a legend under the title.
    """
    shaped = panel_shapes(shapes, panels)
    ncols = min(ncols or len(panels), MAX_COLUMNS)
    nrows = int(np.ceil(len(panels) / ncols))
    boxes = [_field_box(x, y, Z, loops=None if shape is None else shape.loops)
             for (x, y, Z, _, _), shape in zip(panels, shaped)]
    common_box = None
    if same_axes:
        common_box = (min(b[0] for b in boxes), max(b[1] for b in boxes), min(b[2] for b in boxes),
                      max(b[3] for b in boxes))
        aspect = (common_box[3] - common_box[2]) / max(common_box[1] - common_box[0], 1e-9)
    else:
        aspect = float(np.median([(b[3] - b[2]) / max(b[1] - b[0], 1e-9) for b in boxes]))
    fig = Figure()
    width = min(REPORT_WIDTH_IN, 3.6 * ncols + 0.8)
    slot = (width - 0.35) / ncols - 0.95 + 0.6          # a title centred over its panel (panel_grid's margins)
    titles = [wrap_text(fig, title + constant_note(Z, units), slot, TITLE_PT) for _, _, Z, title, units in panels]
    lines = max(t.count("\n") + 1 for t in titles)
    suptitle = wrap_text(fig, suptitle, width - 0.2, SUPTITLE_PT)
    legend = {}
    for shape in shaped:
        if shape is not None:
            legend.update(_singular_entries(shape))
    legend_lines = [wrap_text(fig, text, width - 0.6, FONT_PT).count("\n") + 1 for text in legend]
    head = 0.3 + (suptitle.count("\n") + 1) * 1.25 * SUPTITLE_PT / 72
    top = max(0.75, head + sum(0.05 + n * 1.25 * FONT_PT / 72 for n in legend_lines) + (0.1 if legend else 0.0))
    cells = panel_grid(fig, nrows, ncols, aspect, width=width, top=top, title_space=0.4 + (lines - 1) * 1.25 * TITLE_PT / 72,
                       label_lines=3 if any(e is not None for e in (errors or [])) else 2)
    common = colour_range(np.concatenate([p[2].ravel() for p in panels])) if shared_scale else None
    errors = errors or [None] * len(panels)
    limited = limited or [True] * len(panels)
    for (ax, cax), (x, y, Z, _, units), title, error, lim, shape in zip(cells, panels, titles, errors, limited,
                                                                        shaped):
        rng = common or colour_range(Z)
        if lim:
            rng = limited_range(rng, vmin, vmax)
        _draw_field(fig, ax, cax, x, y, Z, "", units, rng=rng, contours=contours or error is not None,
                    error=error, log=log, box=common_box, outline=None if shape is None else shape.outline(Z))
        if shape is not None:
            draw_singular(ax, x, y, shape)
        ax.set_title(title, fontsize=TITLE_PT)
        ax.set_xlabel("x [mm]", fontsize=LABEL_PT)
        ax.set_ylabel("y [mm]", fontsize=LABEL_PT)
        ax.tick_params(labelsize=FONT_PT)
    for ax, cax in cells[len(panels):]:
        ax.set_visible(False)
        fig.delaxes(cax)
    if legend:
        fig.legend(handles=[_singular_handle(kind, wrap_text(fig, text, width - 0.6, FONT_PT))
                            for text, kind in legend.items()],
                   loc="upper center", bbox_to_anchor=(0.5, 1 - (head - 0.05) / fig.get_figheight()),
                   frameon=False, fontsize=FONT_PT, handlelength=1.6)
    fig.suptitle(suptitle, fontsize=SUPTITLE_PT,
                 y=1 - 0.12 / fig.get_figheight(), va="top")
    return fig


def _crop(ax, x: np.ndarray, y: np.ndarray, Z: np.ndarray, margin: float = 0.05) -> None:
    """Limit the axes to the finite part of a field (its workspace) plus a margin, at equal scales."""
    fit_limits(ax, *_field_box(x, y, Z, margin))
