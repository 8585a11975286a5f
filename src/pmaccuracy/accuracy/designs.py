"""Design comparison across architectures: workspace, worst-case errors over it, ratios on the shared region.

For robots ``k = 0 .. K-1`` (any architecture, each with its own error
sources) and orientations ``phi`` this module gives:

* the exact area ``A_k(phi)`` (mm^2) of each constant-orientation workspace
  ``W_k(phi)`` (:func:`pmaccuracy.kinematics.workspace.constant_orientation_workspace`);
* over the ``n x n`` grid spanning each workspace's bounding box, at the grid
  points ``G_k = {p in grid : p in W_k}`` that are far from both singularities
  (:func:`pmaccuracy.kinematics.regular_mask`; the others are excluded and
  counted), the exact worst-case errors ``e_q(p)`` for ``q`` in
  ``dx_max, dy_max, dphi_max, dp_max`` (:func:`pmaccuracy.accuracy.bounds.max_pose_errors`)
  and their statistics::

      mean_q = 1/|G| sum_{p in G} e_q(p)        max_q = max_{p in G} e_q(p)   at  argmax_{p in G} e_q(p)

  On a regular grid ``mean_q`` is the midpoint-rule estimate of the area
  average ``1/A integral_W e_q dA``;
* the shared region ``S(phi) = W_0 ∩ ... ∩ W_{K-1}`` sampled by the ``n x n``
  grid spanning the intersection of the bounding boxes, and on its points that
  are regular for every robot the ratio maps ``r_kq(p) = e_q^k(p) / e_q^0(p)``
  (robot 0 is the reference: ``r_0q = 1`` exactly) with their mean, min and
  max. A ratio where the reference error is 0 is undefined (NaN).

Lengths in mm, ``dphi_max`` in rad in the arrays (degrees only in
:meth:`DesignComparison.records`). Everything is a pure function over arrays
except the figure helpers, which build a :class:`matplotlib.figure.Figure`.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .bounds import max_pose_errors
from .._savefig import DEFAULT_DPI, SYMBOLS, save_figure
from ..errors import ConfigError
from ..model.manipulator import Manipulator, round_trip_degrees
from ..model.plausibility import check_orientations
from ..kinematics import DEFAULT_MAX_CONDITION, regular_mask
from ..kinematics.workspace import Workspace, constant_orientation_workspace
from ..io.resolve import clearances_arg, robot_arg

#: The compared quantities, in the order of the last axis of every value array (mm, mm, rad, mm).
QUANTITIES = ("dx_max", "dy_max", "dphi_max", "dp_max")
#: Short names of the quantities in :meth:`DesignComparison.records` (dphi there in degrees).
SHORT = ("dx", "dy", "dphi", "dp")
#: Default grid points per axis.
DEFAULT_GRID = 101


# ------------------------------------------------------------------------------------------- arrays
def grid_poses(x: np.ndarray, y: np.ndarray, phi: float) -> np.ndarray:
    """Poses ``(ny, nx, 3)`` [mm, mm, rad] of the grid ``x (nx,)``, ``y (ny,)`` mm at orientation ``phi`` rad.

    ``poses[j, i] = (x[i], y[j], phi)``, the ``[y, x]`` indexing of
    :meth:`pmaccuracy.kinematics.workspace.Workspace.grid`.
    """
    X, Y = np.meshgrid(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    return np.stack([X, Y, np.full_like(X, float(phi))], axis=-1)


def error_fields(robot: Manipulator, clearances, poses: np.ndarray, inside: np.ndarray,
                 max_condition: float = DEFAULT_MAX_CONDITION) -> tuple[np.ndarray, np.ndarray]:
    """Exact worst-case errors at the regular poses among ``inside``.

    Parameters
    ----------
    poses : ``(..., 3)`` [mm, mm, rad]
    inside : ``(...)`` bool, poses inside the workspace (within every joint range)
    clearances : error sources of ``robot`` (:func:`pmaccuracy.load_clearances`)

    Returns
    -------
    values : ``(..., 4)`` ``e_q`` for :data:`QUANTITIES` (mm, mm, rad, mm); NaN where not evaluated
        (outside, or near a singularity)
    singular : ``(...)`` bool, inside but excluded: ``regular_mask`` is False (condition number of
        ``A`` above ``max_condition`` or a leg's transmission index below ``1 / max_condition``)
    """
    poses = np.asarray(poses, dtype=float)
    inside = np.asarray(inside, dtype=bool)
    values = np.full(poses.shape[:-1] + (4,), np.nan)
    singular = np.zeros(inside.shape, dtype=bool)
    pts = poses[inside]
    if pts.shape[0] == 0:
        return values, singular
    regular = regular_mask(robot, pts, max_condition)
    where = np.flatnonzero(inside.reshape(-1))
    singular.reshape(-1)[where[~regular]] = True
    if np.any(regular):
        # inside was decided by the same inverse kinematics with the limit tolerance: no range check again
        b = max_pose_errors(robot, clearances, pts[regular], allow_outside=True, max_condition=max_condition)
        flat = values.reshape(-1, 4)
        flat[where[regular]] = np.column_stack([b.dx_max, b.dy_max, b.dphi_max, b.dp_max])
    return values, singular


def field_statistics(values: np.ndarray, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean, max and argmax position of each quantity over the finite entries of ``values``.

    ``values`` ``(..., Q)`` with NaN at points not evaluated, ``positions``
    ``(..., 2)`` mm. Returns ``mean (Q,)``, ``max (Q,)`` and ``at (Q, 2)`` mm,
    the first position (in C order) where the max occurs; all NaN for a
    quantity without finite entries.
    """
    v = np.asarray(values, dtype=float).reshape(-1, np.shape(values)[-1])
    pos = np.asarray(positions, dtype=float).reshape(-1, 2)
    if v.shape[0] == 0:
        return np.full(v.shape[1], np.nan), np.full(v.shape[1], np.nan), np.full((v.shape[1], 2), np.nan)
    finite = np.isfinite(v)
    count = finite.sum(axis=0)
    total = np.where(finite, v, 0.0).sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    filled = np.where(finite, v, -np.inf)
    k = np.argmax(filled, axis=0)
    vmax = np.where(count > 0, filled[k, np.arange(v.shape[1])], np.nan)
    at = np.where((count > 0)[:, None], pos[k], np.nan)
    return mean, vmax, at


def ratio_fields(values: np.ndarray) -> np.ndarray:
    """``r[k] = values[k] / values[0]`` ``(K, ..., Q)``: each robot's errors over the reference's.

    NaN where either is NaN or where the reference error is 0 (the ratio is
    undefined there); ``r[0]`` is exactly 1 wherever defined.
    """
    values = np.asarray(values, dtype=float)
    ref = values[0]
    ok = np.isfinite(ref) & (ref != 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(ok, values / np.where(ok, ref, 1.0), np.nan)


def ratio_statistics(ratios: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean, min and max ``(Q,)`` over the finite entries of ``ratios`` ``(..., Q)``; NaN where none."""
    r = np.asarray(ratios, dtype=float).reshape(-1, np.shape(ratios)[-1])
    finite = np.isfinite(r)
    count = finite.sum(axis=0)
    has = count > 0
    mean = np.where(has, np.where(finite, r, 0.0).sum(axis=0) / np.maximum(count, 1), np.nan)
    lo = np.where(has, np.where(finite, r, np.inf).min(axis=0, initial=np.inf), np.nan)
    hi = np.where(has, np.where(finite, r, -np.inf).max(axis=0, initial=-np.inf), np.nan)
    return mean, lo, hi


def shared_box(workspaces: Sequence[Workspace]) -> tuple[tuple[float, float], tuple[float, float]] | None:
    """Intersection ``((xmin, xmax), (ymin, ymax))`` mm of the workspaces' bounding boxes; None if it is empty
    (an empty workspace, or boxes that do not overlap with positive width and height)."""
    if not workspaces or any(ws.is_empty for ws in workspaces):
        return None
    x0 = max(ws.bounds[0][0] for ws in workspaces)
    x1 = min(ws.bounds[0][1] for ws in workspaces)
    y0 = max(ws.bounds[1][0] for ws in workspaces)
    y1 = min(ws.bounds[1][1] for ws in workspaces)
    if not (x1 > x0 and y1 > y0):
        return None
    return (x0, x1), (y0, y1)


def shared_grid(workspaces: Sequence[Workspace], n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ``n x n`` grid over :func:`shared_box`: ``x (n,)``, ``y (n,)`` mm and ``inside (n, n)`` [y, x].

    ``inside[j, i]`` is True when ``(x[i], y[j])`` is in every workspace
    (:meth:`~pmaccuracy.kinematics.workspace.Workspace.contains`). An empty shared box
    gives empty ``x``, ``y`` and an ``(0, 0)`` mask.
    """
    box = shared_box(workspaces)
    if box is None:
        return np.zeros(0), np.zeros(0), np.zeros((0, 0), dtype=bool)
    (x0, x1), (y0, y1) = box
    x, y = np.linspace(x0, x1, n), np.linspace(y0, y1, n)
    X, Y = np.meshgrid(x, y)
    pts = np.stack([X, Y], axis=-1)
    inside = np.ones(X.shape, dtype=bool)
    for ws in workspaces:
        inside &= ws.contains(pts)
    return x, y, inside


# ------------------------------------------------------------------------------------------- results
@dataclass(frozen=True, eq=False)
class DesignRow:
    """One robot at one orientation.

    Attributes
    ----------
    label : name of the robot in this comparison (the robot's name, with its clearances' when repeated)
    robot, architecture, clearances : names
    phi : rad;  area : mm^2, exact (0.0 for an empty workspace)
    n_points : grid points inside the workspace;  n_singular : of those, excluded near a singularity
    mean, max : ``(4,)`` over the evaluated points, :data:`QUANTITIES` (mm, mm, rad, mm); NaN if none
    argmax : ``(4, 2)`` mm, position of each max (orientation ``phi``)
    n_shared : points of the shared-region grid evaluated for the ratios (regular for every robot)
    ratio_mean, ratio_min, ratio_max : ``(4,)`` statistics of ``e_q / e_q^reference`` over the shared
        region; NaN when it is empty
    """

    label: str
    robot: str
    architecture: str
    clearances: str
    phi: float
    area: float
    n_points: int
    n_singular: int
    mean: np.ndarray
    max: np.ndarray
    argmax: np.ndarray
    n_shared: int
    ratio_mean: np.ndarray
    ratio_min: np.ndarray
    ratio_max: np.ndarray

    def record(self) -> dict:
        """The row with the CLI's keys: lengths mm, dphi in deg (``*_deg``), ratios dimensionless."""
        rec = {"robot": self.label, "architecture": self.architecture, "clearances": self.clearances,
               "phi_deg": round_trip_degrees(self.phi), "area_mm2": self.area, "points": self.n_points,
               "singular": self.n_singular}
        scale = np.array([1.0, 1.0, np.degrees(1.0), 1.0])
        for q, name in enumerate(SHORT):
            unit = "_deg" if name == "dphi" else ""
            rec[f"{name}_mean{unit}"] = float(self.mean[q] * scale[q])
            rec[f"{name}_max{unit}"] = float(self.max[q] * scale[q])
        for q, name in enumerate(SHORT):
            rec[f"{name}_argmax_x"] = float(self.argmax[q, 0])
            rec[f"{name}_argmax_y"] = float(self.argmax[q, 1])
        rec["shared_points"] = self.n_shared
        for q, name in enumerate(SHORT):
            rec[f"{name}_ratio_mean"] = float(self.ratio_mean[q])
            rec[f"{name}_ratio_min"] = float(self.ratio_min[q])
            rec[f"{name}_ratio_max"] = float(self.ratio_max[q])
        return rec


@dataclass(frozen=True, eq=False)
class SharedRegion:
    """The region shared by every robot's workspace at one orientation, sampled on a grid.

    Attributes
    ----------
    phi : rad
    x, y : ``(n,)`` mm (empty when the bounding boxes do not overlap)
    inside : ``(n, n)`` [y, x] bool, in every workspace
    regular : ``(n, n)`` bool, inside and regular for every robot (where the ratios are evaluated)
    values : ``(K, n, n, 4)`` each robot's errors (:data:`QUANTITIES`), NaN outside ``regular``
    ratios : ``(K, n, n, 4)`` ``values[k] / values[0]``, NaN outside ``regular``
    """

    phi: float
    x: np.ndarray
    y: np.ndarray
    inside: np.ndarray
    regular: np.ndarray
    values: np.ndarray
    ratios: np.ndarray

    @property
    def is_empty(self) -> bool:
        """True when no grid point is in every workspace and regular for every robot."""
        return not bool(np.any(self.regular))


@dataclass(frozen=True, eq=False)
class DesignComparison:
    """Result of :func:`compare_designs`.

    Attributes
    ----------
    robots : the K robots (robot 0 is the reference of the ratios);  clearances : their error sources
    labels : K names (unique)
    phis : ``(P,)`` rad;  grid : points per axis
    workspaces : ``[p][k]`` the exact workspace of robot k at ``phis[p]``
    rows : ``P * K`` :class:`DesignRow`, orientation-major (``rows[p * K + k]``)
    shared : ``P`` :class:`SharedRegion`
    """

    robots: tuple[Manipulator, ...] = field(repr=False)
    clearances: tuple = field(repr=False)
    labels: tuple[str, ...]
    phis: np.ndarray
    grid: int
    workspaces: tuple[tuple[Workspace, ...], ...] = field(repr=False)
    rows: tuple[DesignRow, ...] = field(repr=False)
    shared: tuple[SharedRegion, ...] = field(repr=False)

    def row(self, p: int, k: int) -> DesignRow:
        """Robot ``k`` at orientation ``phis[p]``."""
        return self.rows[p * len(self.robots) + k]

    def records(self) -> list[dict]:
        """One dict per robot x orientation (:meth:`DesignRow.record`), orientation-major."""
        return [r.record() for r in self.rows]


def design_labels(robots: Sequence[Manipulator], clearances: Sequence) -> tuple[str, ...]:
    """Unique names: the robot's name, plus ``/clearances`` when a robot appears twice, plus ``#k`` if still equal."""
    names = [r.name for r in robots]
    labels = [n if names.count(n) == 1 else f"{n}/{getattr(c, 'name', 'custom')}"
              for n, c in zip(names, clearances)]
    return tuple(lab if labels.count(lab) == 1 else f"{lab}#{k + 1}" for k, lab in enumerate(labels))


def compare_designs(robots: Sequence[Manipulator], clearances: Sequence, phis: Sequence[float] | np.ndarray,
                    n: int = DEFAULT_GRID, max_condition: float = DEFAULT_MAX_CONDITION) -> DesignComparison:
    """Compare robots (any architectures, each with its error sources) at orientations ``phis`` (rad).

    For each orientation: exact workspace areas, statistics of the exact
    worst-case errors over an ``n x n`` grid of each workspace, and the ratio
    maps to ``robots[0]`` over the shared region (module docstring). Cost: about
    ``(K + K) n^2`` inverse kinematics and bounds per orientation.

    ``clearances`` has one entry per robot, as returned by
    :func:`pmaccuracy.load_clearances` for that robot.
    """
    check_orientations(phis, "phis")
    if isinstance(robots, (str, os.PathLike)) or isinstance(clearances, (str, os.PathLike)):
        raise ConfigError("expected one entry per robot (a list), got a single name", key="robots/clearances")
    robots = tuple(robot_arg(r, f"robots[{k}]") for k, r in enumerate(robots))
    clearances = tuple(clearances)
    if len(robots) < 1:
        raise ConfigError("compare_designs needs at least one robot", key="robots")
    if len(clearances) != len(robots):
        raise ConfigError(f"one clearance set per robot is needed: {len(robots)} robots, {len(clearances)} sets",
                          key="clearances")
    clearances = tuple(clearances_arg(c, r, f"clearances[{k}]") for k, (c, r) in enumerate(zip(clearances, robots)))
    try:
        n = int(n)
        phis = np.atleast_1d(np.asarray(phis, dtype=float))
    except (TypeError, ValueError):
        raise ConfigError(f"n must be a whole number and phis numbers (rad), got n={n!r}, phis={phis!r}",
                          key="n/phis") from None
    if n < 2:
        raise ConfigError(f"a grid needs n >= 2 points per axis, got {n}", key="n")
    if not np.all(np.isfinite(phis)):
        raise ConfigError(f"orientations must be finite, got {phis.tolist()}", key="phis")
    labels = design_labels(robots, clearances)
    K = len(robots)
    rows, shared, spaces = [], [], []
    for phi in phis:
        wss = tuple(constant_orientation_workspace(r, phi) for r in robots)
        spaces.append(wss)
        # the shared region: every robot's errors at the same points, regular for all
        x, y, inside = shared_grid(wss, n)
        poses = grid_poses(x, y, phi)
        vals = np.stack([error_fields(r, c, poses, inside, max_condition)[0] for r, c in zip(robots, clearances)])
        regular = inside & np.all(np.isfinite(vals[..., 3]), axis=0)
        vals = np.where(regular[None, ..., None], vals, np.nan)
        ratios = ratio_fields(vals)
        region = SharedRegion(phi=float(phi), x=x, y=y, inside=inside, regular=regular, values=vals, ratios=ratios)
        shared.append(region)
        for k, (robot, cl, ws) in enumerate(zip(robots, clearances, wss)):
            if ws.is_empty:
                nan4 = np.full(4, np.nan)
                n_points = n_singular = 0
                mean, vmax, at = nan4, nan4, np.full((4, 2), np.nan)
            else:
                gx, gy, ginside = ws.grid(n)
                gposes = grid_poses(gx, gy, phi)
                values, singular = error_fields(robot, cl, gposes, ginside, max_condition)
                n_points, n_singular = int(ginside.sum()), int(singular.sum())
                mean, vmax, at = field_statistics(values, gposes[..., :2])
            rmean, rmin, rmax = ratio_statistics(ratios[k])
            rows.append(DesignRow(label=labels[k], robot=robot.name, architecture=robot.architecture,
                                  clearances=getattr(cl, "name", "custom"), phi=float(phi), area=float(ws.area),
                                  n_points=n_points, n_singular=n_singular, mean=mean, max=vmax, argmax=at,
                                  n_shared=int(regular.sum()), ratio_mean=rmean, ratio_min=rmin, ratio_max=rmax))
    return DesignComparison(robots=robots, clearances=clearances, labels=labels, phis=phis, grid=n,
                            workspaces=tuple(spaces), rows=tuple(rows), shared=tuple(shared))


# ------------------------------------------------------------------------------------------- figure
_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown", "tab:pink", "tab:olive")


#: Factors offered as the end of the ratio colour scale and as its ticks (with their inverses).
_NICE_FACTORS = (1.1, 1.25, 1.5, 2.0, 3.0, 5.0, 10.0, 20.0, 50.0, 100.0, 1e3, 1e4, 1e5, 1e6)


def _ratio_span(result: DesignComparison) -> float:
    """The smallest factor ``m`` of :data:`_NICE_FACTORS` with every finite dp ratio in ``[1/m, m]``
    (one symmetric logarithmic scale for every ratio panel)."""
    m = 1.0
    for region in result.shared:
        r = region.ratios[1:, ..., 3]
        r = r[np.isfinite(r) & (r > 0)]
        if r.size:
            m = max(m, float(r.max()), float(1.0 / r.min()))
    return next((f for f in _NICE_FACTORS if f >= m * (1 - 1e-12)), m)


def _ratio_ticks(m: float) -> np.ndarray:
    """Tick values of a ratio scale ``[1/m, m]``: 1, ``m``, the nice factor nearest ``sqrt(m)`` (log scale)
    when it lies strictly between them, and their inverses."""
    inner = [f for f in _NICE_FACTORS if 1.0 < f < m * (1 - 1e-12)]
    ups = [m]
    if inner:
        ups.append(min(inner, key=lambda f: abs(np.log(f) - 0.5 * np.log(m))))
    return np.array(sorted({1.0, *ups, *(1.0 / f for f in ups)}))


def _bar_scale(ax, values: np.ndarray) -> str:
    """Linear axis from 0, or logarithmic (bottom at half the smallest value) when the values span more than 20x;
    returns the note for the axis label."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    v = values[np.isfinite(values) & (values > 0)]
    if v.size and v.max() > 20 * v.min():
        ax.set_yscale("log")
        ax.set_ylim(v.min() / 2, v.max() * 1.6)
        ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.yaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{x:g}"))
        ax.yaxis.set_minor_formatter(NullFormatter())
        return ", log scale"
    ax.set_ylim(0, (v.max() if v.size else 1.0) * 1.08)
    return ""


def plot_comparison(result: DesignComparison):
    """The comparison figure: one row of panels per orientation.

    Columns: (1) the workspaces overlaid, outlined in each robot's colour with
    their exact areas, the shared grid region shaded; (2 .. K) the ratio maps
    ``dp_max^k / dp_max^reference`` over the shared region on one logarithmic
    diverging scale centred on 1 (so 2x and 0.5x are equally strong); (last
    two) bars of the mean (filled) and max (outline) of dx_max, dy_max, dp_max
    (mm) and of dphi_max (deg) per robot, on a linear axis from 0 or, when the
    values span more than 20x (maxima near a singularity), a logarithmic one. Axes are placed at
    fixed positions in inches (no layout engine), colour bars glued to their
    maps. Returns a :class:`matplotlib.figure.Figure` (no pyplot state).
    """
    from matplotlib.colors import LogNorm
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullLocator
    from mpl_toolkits.axes_grid1 import make_axes_locatable

    K, P = len(result.robots), len(result.phis)
    # column widths and gaps (inches): workspaces, K-1 ratio maps (+ colour bar), bars mm, bars deg
    panel, top_pad, below = 3.5, 0.45, 0.5 + 0.2 * (K + 1) + 0.35
    cols = [(0.8, panel)] + [(1.0 if k == 0 else 1.7, panel) for k in range(K - 1)] + [(1.7, 2.9), (1.0, 1.0)]
    width = sum(g + w for g, w in cols) + 0.3
    row_h = top_pad + panel + below
    height = P * row_h + 0.45
    fig = Figure(figsize=(width, height))
    lefts, x = [], 0.0
    for gap, w in cols:
        lefts.append(x + gap)
        x += gap + w

    def axes_at(p: int, c: int):
        bottom = height - (p * row_h + top_pad + panel)
        return fig.add_axes([lefts[c] / width, bottom / height, cols[c][1] / width, panel / height])

    m = _ratio_span(result)
    norm = LogNorm(vmin=1.0 / m, vmax=m)
    ticks = _ratio_ticks(m)
    factor = FuncFormatter(lambda v, _: f"{v:.3g}×")
    for p in range(P):
        phi_deg = round_trip_degrees(float(result.phis[p]))
        region = result.shared[p]
        wss = result.workspaces[p]
        # (1) workspaces
        ax = axes_at(p, 0)
        for k, ws in enumerate(wss):
            color = _COLORS[k % len(_COLORS)]
            if ws.is_empty:
                ax.plot([], [], color=color, label=f"{result.labels[k]}: empty")
                continue
            for j, loop in enumerate(ws.loops):
                ax.plot(loop[:, 0], loop[:, 1], color=color, linewidth=1.8,
                        label=f"{result.labels[k]}: {ws.area:.0f} mm²" if j == 0 else None)
        if region.inside.any():
            ax.contourf(region.x, region.y, region.inside.astype(float), levels=[0.5, 1.5], colors=["0.55"],
                        alpha=0.35)
            ax.fill([], [], color="0.55", alpha=0.35, label="shared region (grid)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.set_title(f"workspaces at $\\phi$ = {phi_deg:g} deg", fontsize="medium")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.13), fontsize="small", frameon=False,
                  title="exact areas", title_fontsize="small", alignment="left")
        # (2 .. K) ratio maps of dp_max
        for k in range(1, K):
            ax = axes_at(p, k)
            ax.set_title(f"{SYMBOLS['dp_max'][0]} ratio at $\\phi$ = {phi_deg:g} deg\n{result.labels[k]} / {result.labels[0]}",
                         fontsize="small")
            if region.is_empty:
                why = ("no shared region" if not region.inside.any() else
                       "every shared grid point is\nnear a singularity of some robot")
                ax.text(0.5, 0.5, why, transform=ax.transAxes, ha="center", va="center")
                ax.set_xticks([])
                ax.set_yticks([])
                continue
            ratio = np.ma.masked_invalid(region.ratios[k, ..., 3])
            mesh = ax.pcolormesh(region.x, region.y, ratio, shading="nearest", cmap="RdBu_r", norm=norm)
            for kk, ws in enumerate(wss):
                for loop in ws.loops:
                    ax.plot(loop[:, 0], loop[:, 1], color=_COLORS[kk % len(_COLORS)], linewidth=0.9)
            ax.set_xlim(region.x[0], region.x[-1])
            ax.set_ylim(region.y[0], region.y[-1])
            ax.set_aspect("equal", adjustable="box")
            ax.set_xlabel("x [mm]")
            ax.set_ylabel("y [mm]")
            ax.tick_params(labelsize="small")
            cax = make_axes_locatable(ax).append_axes("right", size="5%", pad=0.06)
            cbar = fig.colorbar(mesh, cax=cax)
            cbar.ax.yaxis.set_major_locator(FixedLocator(ticks))
            cbar.ax.yaxis.set_minor_locator(NullLocator())
            cbar.ax.yaxis.set_major_formatter(factor)
            cbar.ax.tick_params(labelsize="small")
            cbar.set_label(f"{SYMBOLS['dp_max'][0]} ratio [1]", fontsize="small")
            row = result.row(p, k)
            ax.text(0.5, -0.2, f"mean {row.ratio_mean[3]:.3g}×, min {row.ratio_min[3]:.3g}×, "
                               f"max {row.ratio_max[3]:.3g}× ({row.n_shared} points)",
                    transform=ax.transAxes, ha="center", va="top", fontsize="small")
        # bars: mean (filled) and max (outline) per robot
        rows = [result.row(p, k) for k in range(K)]
        ax_mm, ax_deg = axes_at(p, K), axes_at(p, K + 1)
        step = 0.8 / K
        for k, row in enumerate(rows):
            color = _COLORS[k % len(_COLORS)]
            offs = (k - (K - 1) / 2) * step
            xs = np.arange(3) + offs
            mm = [0, 1, 3]
            ax_mm.bar(xs, row.max[mm], step * 0.9, facecolor="none", edgecolor=color, linewidth=1.4)
            ax_mm.bar(xs, row.mean[mm], step * 0.55, color=color)
            ax_deg.bar([offs], [np.degrees(row.max[2])], step * 0.9, facecolor="none", edgecolor=color,
                       linewidth=1.4)
            ax_deg.bar([offs], [np.degrees(row.mean[2])], step * 0.55, color=color)
        for a, idx, unit in ((ax_mm, [0, 1, 3], "mm"), (ax_deg, [2], "deg")):
            note = _bar_scale(a, np.degrees(np.concatenate([np.concatenate([r.mean[idx], r.max[idx]]) for r in rows]))
                              if unit == "deg" else np.concatenate([np.concatenate([r.mean[idx], r.max[idx]])
                                                                    for r in rows]))
            a.set_ylabel(f"worst-case error [{unit}]{note}")
            a.grid(True, axis="y", alpha=0.25)
            a.tick_params(labelsize="small")
        ax_mm.set_xticks(range(3), [SYMBOLS[q][0] for q in ("dx_max", "dy_max", "dp_max")])
        ax_mm.set_title(f"over each workspace, $\\phi$ = {phi_deg:g} deg\nmean (filled), max (outline)", fontsize="small")
        ax_deg.set_xticks([0], [SYMBOLS["dphi_max"][0]])
        ax_deg.set_xlim(-0.55, 0.55)
        handles = [Patch(color=_COLORS[k % len(_COLORS)], label=result.labels[k] + (
            "" if np.isfinite(rows[k].mean[3]) else ": empty workspace" if rows[k].n_points == 0
            else ": every point near a singularity")) for k in range(K)]
        ax_mm.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.0, -0.13), fontsize="small",
                     frameon=False)
    return fig


def save_comparison_figure(result: DesignComparison, path: str | Path, dpi: int = DEFAULT_DPI) -> Path:
    """Write :func:`plot_comparison` to ``path`` in the format its extension names (``.png`` at ``dpi``,
    ``.pdf``, ``.svg``, ...: :func:`pmaccuracy._savefig.save_figure`); returns the path."""
    fig = plot_comparison(result)
    path = save_figure(fig, path, dpi=dpi)
    fig.clear()
    return path
