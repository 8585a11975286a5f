"""Figures of the experimental validation: maps with the measured points (Figs. 9-12), box plots (Fig. 13),
ISO 9283 accuracy per point (Fig. 14) and predicted vs measured errors (Fig. 15).

Every function returns a :class:`matplotlib.figure.Figure` (no pyplot state);
:func:`write_figures` saves them as PNG. Lengths in mm, angles in degrees.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from . import figures
from ..model.clearances import ClearanceSet
from ..experiment import LABELS, QUANTITIES, UNITS, Comparison, MeasuredErrors, measured_errors
from ..model.manipulator import Manipulator
from ..accuracy.maps import error_map
from ..experiment.measurements import Measurements
from ..io.resolve import load_clearances
from ..io.resolve import robot_arg


def plot_boxplots(datasets: Mapping[str, MeasuredErrors | Measurements], *, title: str | None = None,
                  data: str = "measured") -> Figure:
    """Box plots of the measured errors as in Fig. 13: one panel per quantity, one box per dataset.

    ``datasets`` maps a label (e.g. ``"case 1, phi = 0"``) to measured errors or measurements.
    """
    names = list(datasets)
    values = [(d if isinstance(d, MeasuredErrors) else measured_errors(d)).values() for d in datasets.values()]
    fig = Figure(figsize=(figures.REPORT_WIDTH_IN, 8.0))
    fig.subplots_adjust(left=0.12, right=0.98, bottom=0.1, top=0.92, wspace=0.4, hspace=0.38)  # no layout engine
    for ax, q in zip(fig.subplots(2, 2).ravel(), QUANTITIES):
        ax.boxplot([v[q] for v in values])
        ax.set_xticks(range(1, len(names) + 1))
        ax.set_xticklabels(names, rotation=15 if len(names) > 2 else 0, fontsize=8)
        ax.set_ylabel(f"{data} {LABELS[q]} [{UNITS[q]}]")
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle(title or "Measured pose errors (Eq. 23), cf. paper Fig. 13")
    return fig


#: Colours of the orientations in the experiment figures (one per nominal phi, in order).
ORIENTATION_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")


def _orientation_groups(m: Measurements) -> list[tuple[float, np.ndarray]]:
    """``[(phi_deg, indices), ...]`` of the points at each nominal orientation, in order of appearance."""
    keys = np.round(m.phi_nom_deg, 6)
    return [(float(k), np.flatnonzero(keys == k)) for k in dict.fromkeys(keys.tolist())]


def _phi_list(groups: list[tuple[float, np.ndarray]]) -> str:
    return ", ".join(f"{phi:g}" for phi, _ in groups) + " deg"


def _label_step(fig: Figure, ax, names, span: float, pad_em: float = 0.8) -> int:
    """Label every ``step``-th of bars one unit apart along ``ax``'s x axis (``span`` units wide) so that the
    point names, measured at the tick labels' size by the renderer, stay ``pad_em`` apart side by side."""
    from matplotlib.text import Text

    renderer = figures._renderer(fig)
    size = max(figures.FONT_PT, figures.min_font_pt(fig.get_figwidth()))
    probe = Text(0, 0, "", fontsize=size, figure=fig)
    widest = 0.0
    for name in dict.fromkeys(str(p) for p in names):
        probe.set_text(name)
        widest = max(widest, probe.get_window_extent(renderer).width)
    per_bar = ax.get_window_extent(renderer).width / max(span, 1.0)
    return max(1, math.ceil((widest + pad_em * size * fig.dpi / 72.0) / per_bar))


def plot_accuracy(measurements: Measurements | Comparison, *, title: str | None = None,
                  data: str = "measured") -> Figure:
    """Position and orientation error per point as bars (the paper's Eq. 24 and Fig. 14; not the ISO 9283 AP).

    ``dp`` in mm and ``dphi`` in deg, one bar per measured point, the points of each
    nominal orientation grouped and coloured (legend above the panels, outside the bars); the title
    names every orientation. 10 x 5.4 in with 9-11 pt text: readable at the report's column width.
    """
    m = measurements.measurements if isinstance(measurements, Comparison) else measurements
    errors = measured_errors(m)
    groups = _orientation_groups(m)
    n = len(m)
    fig = Figure(figsize=(figures.REPORT_WIDTH_IN, 6.0))
    fig.subplots_adjust(left=0.13, right=0.98, bottom=0.14, top=0.8, hspace=0.14)
    ax_p, ax_r = fig.subplots(2, 1, sharex=True)
    pos = np.empty(n)
    start = 0.0
    for phi, idx in groups:                      # a gap of two bars between orientations
        pos[idx] = start + np.arange(idx.size)
        start += idx.size + 2
    for j, (phi, idx) in enumerate(groups):
        colour = ORIENTATION_COLOURS[j % len(ORIENTATION_COLOURS)]
        label = f"$\\phi$ = {phi:g} deg ({idx.size} points)"
        ax_p.bar(pos[idx], errors.dp[idx], width=0.8, color=colour, label=label)
        ax_r.bar(pos[idx], errors.dphi_deg[idx], width=0.8, color=colour)
    ax_p.set_ylabel("$\\delta p$ (Eq. 24) [mm]", fontsize=10)
    ax_r.set_ylabel("$\\delta\\phi$ (Eq. 24) [deg]", fontsize=10)
    for ax in (ax_p, ax_r):
        ax.grid(axis="y", alpha=0.3)
        ax.tick_params(labelsize=figures.FONT_PT)
        ax.set_xlim(-1, float(pos.max()) + 1)
    step = _label_step(fig, ax_r, m.points, float(pos.max()) + 2)
    order = np.argsort(pos)
    ticks = order[::step]
    ax_r.set_xticks(pos[ticks])
    ax_r.set_xticklabels(m.points[ticks], fontsize=figures.FONT_PT)
    ax_r.set_xlabel(f"{data} point" + (f" (one in {step} labelled)" if step > 1 else ""), fontsize=10)
    fig.legend(*ax_p.get_legend_handles_labels(), loc="upper center", bbox_to_anchor=(0.5, 0.925),
               ncol=len(groups), frameon=False, fontsize=9)
    fig.suptitle(title or f"Pose error per point at {n} poses, $\\phi$ = {_phi_list(groups)} (Eq. 24, cf. paper Fig. 14)",
                 fontsize=11, y=0.985)
    return fig


def plot_regression(comparison: Comparison, factor: float = 1.0, *, title: str | None = None,
                    data: str = "measured") -> Figure:
    """Predicted vs measured errors with the band ``d_meas +- 2 A_meas`` (paper Fig. 15).

    One panel per quantity: points ``(d_meas, factor d_max)`` coloured by nominal orientation, the line
    of equality with the shaded band, and the least-squares line when defined. The legend sits under
    the title, outside the panels; the title names the orientations.
    """
    meas, pred = comparison.measured_values(), comparison.predicted_values(factor)
    half, band, reg = comparison.band_halfwidths(), comparison.band(factor), comparison.regression(factor)
    groups = _orientation_groups(comparison.measurements)
    fig = Figure(figsize=(figures.REPORT_WIDTH_IN, 9.6))
    fig.subplots_adjust(left=0.13, right=0.98, bottom=0.07, top=0.85, wspace=0.45, hspace=0.42)
    pre = f"{factor:g} x " if factor != 1 else ""
    for k, (ax, q) in enumerate(zip(fig.subplots(2, 2).ravel(), QUANTITIES)):
        x, y = meas[q], pred[q]
        lo = float(min(x.min(), y.min())) - 2 * half[q]
        hi = float(max(x.max(), y.max())) + 2 * half[q]
        line = np.array([lo, hi])
        ax.fill_between(line, line - half[q], line + half[q], color="tab:green", alpha=0.2,
                        label="band $\\delta_{mea} \\pm 2A_{mea}$" if k == 0 else None)
        ax.plot(line, line, color="tab:green", lw=1, label="equality" if k == 0 else None)
        if math.isfinite(reg[q]["slope"]):
            ax.plot(line, reg[q]["slope"] * line + reg[q]["intercept"], "--", color="tab:red", lw=1,
                    label="least squares" if k == 0 else None)
        for j, (phi, idx) in enumerate(groups):
            ax.scatter(x[idx], y[idx], s=18, color=ORIENTATION_COLOURS[j % len(ORIENTATION_COLOURS)], zorder=3,
                       edgecolors="black", linewidths=0.4, label=f"points, $\\phi$ = {phi:g} deg" if k == 0 else None)
        ax.set_xlim(lo, hi)
        ax.set_ylim(lo, hi)
        ax.set_aspect("equal")
        ax.set_xlabel(f"{data} {LABELS[q]} [{UNITS[q]}]", fontsize=10)
        ax.set_ylabel(f"{pre}predicted {LABELS[q]}" + r"$_{max}$" + f" [{UNITS[q]}]", fontsize=10)
        r = reg[q]["r"]
        ax.set_title(f"{100 * band[q]['share']:.0f} % inside $\\pm${half[q]:g} {UNITS[q]}"
                     + (f", r = {r:.2f}" if math.isfinite(r) else ""), fontsize=10)
        ax.tick_params(labelsize=9)
    handles, labels = fig.axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.945), ncol=min(len(labels), 3),
               frameon=False, fontsize=9)
    conv = "direct (paper)" if factor == 1 else f"{factor:g} x maxima (width-consistent)"
    fig.suptitle(title or f"Simulation vs measurement, {conv}, $\\phi$ = {_phi_list(groups)}, cf. paper Fig. 15",
                 fontsize=11, y=0.99)
    return fig


def plot_measured_maps(robot: Manipulator | str, clearances: ClearanceSet | str, comparison: Comparison, *,
                       grid: int = 41, scale: float = 1.0) -> dict[float, Figure]:
    """Four-panel error maps with the measured points overlaid (Figs. 9-12), one figure per orientation.

    Calls :func:`pmaccuracy.accuracy.maps.error_map` at each nominal orientation of the
    measurements and :func:`pmaccuracy.report.figures.plot_error_map` with the measured
    errors; ``scale`` multiplies the drawn maxima (2 for the width-consistent view).
    Returns ``{phi_deg: Figure}``.
    """
    robot = robot_arg(robot)
    clearances = load_clearances(clearances, robot)
    out = {}
    for phi_deg, sub in comparison.by_orientation().items():
        ds = error_map(robot, clearances, math.radians(phi_deg), n=grid, progress=False)
        measured = {"x": sub.measurements.nominal[:, 0], "y": sub.measurements.nominal[:, 1],
                    **sub.measured_values()}
        conv = "measured ranges vs maxima (paper)" if scale == 1 else f"measured ranges vs {scale:g} x maxima"
        out[phi_deg] = figures.plot_error_map(
            ds, phi_deg, measured=measured, scale=scale,
            title=f"{robot.name}, clearances {clearances.name}, $\\phi$ = {phi_deg:g} deg: {conv}")
    return out


def write_figures(robot: Manipulator | str, clearances: ClearanceSet | str, comparison: Comparison,
                  out_dir: str | Path, *, prefix: str = "", map_grid: int = 41,
                  box_datasets: Mapping[str, MeasuredErrors | Measurements] | None = None) -> dict[str, Path]:
    """Write every figure of a comparison as PNG into ``out_dir``; returns ``{name: path}``.

    Names: ``map_phi{deg}`` and ``map_phi{deg}_x2`` (maps with measured points,
    direct and width-consistent), ``boxplot`` (Fig. 13; one box per orientation
    unless ``box_datasets`` is given), ``accuracy`` (Fig. 14), ``regression`` and
    ``regression_x2`` (Fig. 15).
    """
    out_dir = Path(out_dir)
    paths: dict[str, Path] = {}
    for scale, suffix in ((1.0, ""), (2.0, "_x2")):
        for phi_deg, fig in plot_measured_maps(robot, clearances, comparison, grid=map_grid, scale=scale).items():
            name = f"map_phi{phi_deg:g}{suffix}"
            paths[name] = figures.save(fig, out_dir / f"{prefix}{name}.png")
    if box_datasets is None:
        box_datasets = {f"phi = {phi:g} deg": sub.measured for phi, sub in comparison.by_orientation().items()}
    paths["boxplot"] = figures.save(plot_boxplots(box_datasets), out_dir / f"{prefix}boxplot.png")
    paths["accuracy"] = figures.save(plot_accuracy(comparison), out_dir / f"{prefix}accuracy.png")
    paths["regression"] = figures.save(plot_regression(comparison, 1.0), out_dir / f"{prefix}regression.png")
    paths["regression_x2"] = figures.save(plot_regression(comparison, 2.0), out_dir / f"{prefix}regression_x2.png")
    return paths

