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
from .clearances import ClearanceSet
from .experiment import LABELS, QUANTITIES, UNITS, Comparison, MeasuredErrors, measured_errors
from .geometry import Manipulator
from .maps import error_map
from .measurements import Measurements
from .sources import load_clearances


def plot_boxplots(datasets: Mapping[str, MeasuredErrors | Measurements], *, title: str | None = None) -> Figure:
    """Box plots of the measured errors as in Fig. 13: one panel per quantity, one box per dataset.

    ``datasets`` maps a label (e.g. ``"case 1, phi = 0"``) to measured errors or measurements.
    """
    names = list(datasets)
    values = [(d if isinstance(d, MeasuredErrors) else measured_errors(d)).values() for d in datasets.values()]
    fig = Figure(figsize=(10, 7.5))
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.08, top=0.92, wspace=0.28, hspace=0.3)  # no layout engine
    for ax, q in zip(fig.subplots(2, 2).ravel(), QUANTITIES):
        ax.boxplot([v[q] for v in values])
        ax.set_xticks(range(1, len(names) + 1))
        ax.set_xticklabels(names, rotation=15 if len(names) > 2 else 0, fontsize=8)
        ax.set_ylabel(f"measured {LABELS[q]} [{UNITS[q]}]")
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle(title or "Measured pose errors (Eq. 23), cf. paper Fig. 13")
    return fig


def plot_accuracy(measurements: Measurements | Comparison, *, title: str | None = None) -> Figure:
    """Position and orientation accuracy per point as bars (ISO 9283, Eq. 24; paper Fig. 14).

    ``AP_p = dp`` in mm and ``AP_phi = dphi`` in deg, one bar per measured point.
    """
    m = measurements.measurements if isinstance(measurements, Comparison) else measurements
    errors = measured_errors(m)
    n = len(m)
    fig = Figure(figsize=(max(6.0, min(0.28 * n + 3, 18.0)), 6))
    fig.subplots_adjust(left=0.1, right=0.98, bottom=0.13, top=0.9, hspace=0.12)
    ax_p, ax_r = fig.subplots(2, 1, sharex=True)
    pos = np.arange(n)
    ax_p.bar(pos, errors.dp, color="tab:blue")
    ax_p.set_ylabel(r"$AP_p = \delta p$ [mm]")
    ax_r.bar(pos, errors.dphi_deg, color="tab:orange")
    ax_r.set_ylabel(r"$AP_\phi = \delta\phi$ [deg]")
    ax_r.set_xticks(pos)
    ax_r.set_xticklabels(m.points, rotation=90 if n > 12 else 0, fontsize=7 if n > 24 else 9)
    ax_r.set_xlabel("measured point")
    for ax in (ax_p, ax_r):
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle(title or f"Accuracy at {n} poses (ISO 9283, Eq. 24), cf. paper Fig. 14")
    return fig


def plot_regression(comparison: Comparison, factor: float = 1.0, *, title: str | None = None) -> Figure:
    """Predicted vs measured errors with the band ``d_meas +- 2 A_meas`` (paper Fig. 15).

    One panel per quantity: points ``(d_meas, factor d_max)``, the line of
    equality with the shaded band, and the least-squares line when defined.
    """
    meas, pred = comparison.measured_values(), comparison.predicted_values(factor)
    half, band, reg = comparison.band_halfwidths(), comparison.band(factor), comparison.regression(factor)
    fig = Figure(figsize=(10, 9))
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.07, top=0.92, wspace=0.3, hspace=0.3)
    for ax, q in zip(fig.subplots(2, 2).ravel(), QUANTITIES):
        x, y = meas[q], pred[q]
        lo = float(min(x.min(), y.min())) - 2 * half[q]
        hi = float(max(x.max(), y.max())) + 2 * half[q]
        line = np.array([lo, hi])
        ax.fill_between(line, line - half[q], line + half[q], color="tab:green", alpha=0.2,
                        label=rf"$\delta_{{mea}} \pm 2A_{{mea}}$ ($\pm${half[q]:g} {UNITS[q]})")
        ax.plot(line, line, color="tab:green", lw=1)
        if math.isfinite(reg[q]["slope"]):
            ax.plot(line, reg[q]["slope"] * line + reg[q]["intercept"], "--", color="tab:red", lw=1,
                    label=f"least squares (r = {reg[q]['r']:.2f})" if math.isfinite(reg[q]["r"]) else "least squares")
        ax.scatter(x, y, s=18, color="black", zorder=3, label="points")
        ax.set_xlim(lo, hi)
        ax.set_ylim(lo, hi)
        ax.set_aspect("equal")
        pre = f"{factor:g} x " if factor != 1 else ""
        ax.set_xlabel(f"measured {LABELS[q]} [{UNITS[q]}]")
        ax.set_ylabel(f"{pre}predicted {LABELS[q]}" + r"$_{max}$" + f" [{UNITS[q]}]")
        ax.set_title(f"{100 * band[q]['share']:.0f} % inside the band")
        ax.legend(fontsize=7, loc="upper left")
    conv = "direct (paper)" if factor == 1 else f"{factor:g} x maxima (width-consistent)"
    fig.suptitle(title or f"Simulation vs measurement, {conv}, cf. paper Fig. 15")
    return fig


def plot_measured_maps(robot: Manipulator | str, clearances: ClearanceSet | str, comparison: Comparison, *,
                       grid: int = 41, scale: float = 1.0) -> dict[float, Figure]:
    """Four-panel error maps with the measured points overlaid (Figs. 9-12), one figure per orientation.

    Calls :func:`pmaccuracy.maps.error_map` at each nominal orientation of the
    measurements and :func:`pmaccuracy.figures.plot_error_map` with the measured
    errors; ``scale`` multiplies the drawn maxima (2 for the width-consistent view).
    Returns ``{phi_deg: Figure}``.
    """
    robot = Manipulator.load(robot)
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

