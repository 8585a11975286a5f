"""Reports of the experimental validation: ``comparison.json`` and a self-contained ``report.html``
(:func:`write_report`), and the virtual experiment section of the accuracy report
(:func:`virtual_experiment_section`). Lengths in mm, angles in degrees.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from . import figures
from ..model.clearances import ClearanceSet
from .document import Document
from ..experiment import QUANTITIES, Comparison, compare
from .experiment_plots import plot_accuracy, plot_boxplots, plot_measured_maps, plot_regression, write_figures
from ..model.manipulator import Manipulator
from ..experiment.measurements import DEFAULT_ACCURACY_DEG, DEFAULT_ACCURACY_MM, Measurements, write_measurements
from ..io.resolve import load_clearances
from ..experiment.virtual_rig import simulate_experiment
from ..io.resolve import robot_arg


def _json_ready(value: Any) -> Any:
    """numpy values and paths to JSON; NaN and infinities become None."""
    if isinstance(value, dict):
        return {str(k): _json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    if isinstance(value, np.ndarray):
        return _json_ready(value.tolist())
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value


_CAPTIONS = {
    "boxplot": "Measured errors per orientation (cf. Fig. 13).",
    "accuracy": "ISO 9283 accuracy per point, AP_p = dp and AP_phi = dphi (Eq. 24, cf. Fig. 14).",
    "regression": "Predicted maxima vs measured ranges with the band +-2 A_meas, paper convention (cf. Fig. 15).",
    "regression_x2": "Twice the predicted maxima vs measured ranges (width-consistent), band +-2 A_meas.",
}


def render_html(summary: Mapping[str, Any], figure_paths: Mapping[str, Path], *, title: str) -> str:
    """A self-contained HTML report (figures embedded as base64 PNG) of a :meth:`Comparison.summary`."""
    q_head = ["", "dx [mm]", "dy [mm]", "dp [mm]", "dphi [deg]"]

    def qrow(name: str, d: Mapping[str, Any], key: str | None = None) -> list[Any]:
        return [name] + [(d[q][key] if key else d[q]) for q in QUANTITIES]

    doc = Document(title)
    doc.paragraph(
        f"Measurements: `{summary['source']}`; robot **{summary['robot']}**, clearances "
        f"**{summary['clearances']}**; {summary['n_points']} points. Measured errors by Eq. 23a-d (ranges over "
        f"the six push readings), predicted maxima by Eq. 21-22 at the nominal poses. Camera accuracy A_meas = "
        f"{summary['accuracy_mm']:g} mm, {summary['accuracy_deg']:g} deg.")
    doc.heading("Conventions")
    conv = summary["conventions"]
    doc.bullets([f"**rmsd**: {conv['rmsd']}.", f"**rmsd_width_consistent**: {conv['rmsd_width_consistent']}."])
    doc.heading("Statistics over all points")
    doc.table(q_head, [qrow("RMSD, measured - max (paper)", summary["rmsd"]),
                       qrow("RMSD, measured - 2 max (width-consistent)", summary["rmsd_width_consistent"]),
                       qrow("mean of measured", summary["mean"]),
                       qrow("SSD of measured", summary["ssd"]),
                       qrow("share inside +-2A, direct", summary["band"]["direct"], "share"),
                       qrow("share inside +-2A, 2 x max", summary["band"]["width_consistent"], "share"),
                       qrow("largest excess beyond the band, direct", summary["band"]["direct"], "max_excess"),
                       qrow("Pearson r, direct", summary["regression"]["direct"], "r")])
    acc = summary["accuracy_iso9283"]
    doc.paragraph(f"ISO 9283 accuracy (Eq. 24): position AP_p from {acc['position'][0]:.4g} to "
                  f"{acc['position'][1]:.4g} mm, orientation AP_phi from {acc['orientation_deg'][0]:.4g} to "
                  f"{acc['orientation_deg'][1]:.4g} deg.")
    doc.heading("RMSD per orientation")
    doc.table(["phi [deg]", "points", "dx", "dy", "dp", "dphi [deg]", "dx (2x)", "dy (2x)", "dp (2x)",
               "dphi (2x) [deg]"],
              [[o["phi_deg"], o["n_points"], *(o["rmsd"][q] for q in QUANTITIES),
                *(o["rmsd_width_consistent"][q] for q in QUANTITIES)] for o in summary["orientations"]])
    doc.heading("Figures")
    for name, path in figure_paths.items():
        if name.startswith("map_"):
            caption = (f"Maximum pose errors over the workspace with the measured points (cf. Figs. 9-12), "
                       f"{'twice the maxima' if name.endswith('_x2') else 'paper convention'}.")
        else:
            caption = _CAPTIONS.get(name, name)
        doc.figure(path, caption)
    doc.heading("Points")
    point_cols = ["point", "x_nom", "y_nom", "phi_nom_deg", "dx", "dx_max", "dy", "dy_max", "dp", "dp_max",
                  "dphi_deg", "dphi_max_deg"]
    doc.table(point_cols, [[p[c] for c in point_cols] for p in summary["points"]])
    return doc.to_html()


def write_report(robot: Manipulator | str, clearances: ClearanceSet | str, comparison: Comparison,
                 out_dir: str | Path, *, map_grid: int = 41, title: str | None = None) -> dict[str, Path]:
    """Write the figures, ``comparison.json`` (:meth:`Comparison.summary` plus file names) and a
    self-contained ``report.html`` into ``out_dir``; returns ``{name: path}`` of every file written."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    figure_paths = write_figures(robot, clearances, comparison, out_dir, map_grid=map_grid)
    summary = comparison.summary()
    summary["figures"] = {k: p.name for k, p in figure_paths.items()}
    json_path = out_dir / "comparison.json"
    json_path.write_text(json.dumps(_json_ready(summary), indent=2) + "\n", encoding="utf-8")
    report = out_dir / "report.html"
    report.write_text(render_html(_json_ready(summary), figure_paths,
                                  title=title or f"Experimental validation: {comparison.robot}, "
                                                 f"clearances {comparison.clearances}"), encoding="utf-8")
    return {"report": report, "json": json_path, **figure_paths}


def virtual_experiment_section(robot: Manipulator | str, clearances: ClearanceSet | str,
                               phi: float | Sequence[float], out_dir: str | Path, *, grid: int = 7,
                               take_up: float = 1.0, noise_mm: float = DEFAULT_ACCURACY_MM,
                               noise_deg: float = DEFAULT_ACCURACY_DEG, model: str = "exact", seed: int = 0,
                               map_grid: int = 41, prefix: str = "virtual_") -> dict[str, Any]:
    """Simulate the experiment at one or more orientations, compare with the model, write files for a report.

    Parameters
    ----------
    phi : orientation(s) in rad (e.g. ``(0, pi/6)`` as in the paper)
    out_dir : folder for the CSV, JSON and PNG files (created)
    grid, take_up, noise_mm, noise_deg, model, seed : see :func:`simulate_experiment`
        (orientation ``k`` uses seed ``seed + k``)
    map_grid : grid of the background error maps
    prefix : file-name prefix

    Returns
    -------
    JSON-ready dict: ``robot, clearances, model, take_up, noise_mm, noise_deg,
    seed, grid``; ``expected_noise_rmsd`` ``{"dx", "dy", "dphi_deg"}`` =
    ``sqrt(2) sigma``, the RMSD of (measured - 2 max) that noise alone produces
    when each extreme reading is unique (see :func:`simulate_readings`; with
    ``take_up = 1`` the Aalborg robot's dphi has two tied readings at each end,
    which raises it to ``sigma sqrt(2 (1 + 1/pi))``, 1.15 times more);
    ``orientations``: per orientation ``phi_deg, n_points, rmsd,
    rmsd_width_consistent, mean, ssd, accuracy_iso9283, band, regression``;
    ``files``: ``{name: path}`` (``measurements``, ``comparison_json``,
    ``boxplot`` (Fig. 13, one box per orientation), and per orientation
    ``map_phi{deg}``, ``map_phi{deg}_x2``, ``accuracy_phi{deg}``,
    ``regression_phi{deg}``, ``regression_phi{deg}_x2``), paths as strings;
    the JSON file also lists every point (:meth:`Comparison.records`).
    """
    robot = robot_arg(robot)
    clearances = load_clearances(clearances, robot)
    phis = [float(p) for p in np.atleast_1d(np.asarray(phi, dtype=float))]
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    parts = [simulate_experiment(robot, clearances, p, grid, take_up=take_up, noise_mm=noise_mm, noise_deg=noise_deg,
                                 model=model, seed=seed + k) for k, p in enumerate(phis)]
    offset = np.cumsum([0] + [len(m) for m in parts])
    everything = Measurements(
        points=np.concatenate([[str(int(lbl) + offset[k]) for lbl in m.points] for k, m in enumerate(parts)]),
        nominal=np.concatenate([m.nominal for m in parts]), readings=np.concatenate([m.readings for m in parts]),
        source=f"virtual experiment ({robot.name}, {clearances.name}, {model}, take-up {take_up:g}, "
               f"noise {noise_mm:g} mm / {noise_deg:g} deg, seed {seed})")
    files: dict[str, Path] = {"measurements": write_measurements(out_dir / f"{prefix}measurements.csv", everything)}
    comparison = compare(robot, clearances, everything)
    by_phi = comparison.by_orientation()
    for scale, suffix in ((1.0, ""), (2.0, "_x2")):
        for phi_deg, fig in plot_measured_maps(robot, clearances, comparison, grid=map_grid, scale=scale).items():
            files[f"map_phi{phi_deg:g}{suffix}"] = figures.save(fig, out_dir / f"{prefix}map_phi{phi_deg:g}{suffix}.png")
    files["boxplot"] = figures.save(plot_boxplots({f"phi = {p:g} deg": c.measured for p, c in by_phi.items()}),
                             out_dir / f"{prefix}boxplot.png")
    for phi_deg, sub in by_phi.items():
        tag = f"phi{phi_deg:g}"
        files[f"accuracy_{tag}"] = figures.save(plot_accuracy(sub), out_dir / f"{prefix}accuracy_{tag}.png")
        files[f"regression_{tag}"] = figures.save(plot_regression(sub, 1.0), out_dir / f"{prefix}regression_{tag}.png")
        files[f"regression_{tag}_x2"] = figures.save(plot_regression(sub, 2.0), out_dir / f"{prefix}regression_{tag}_x2.png")
    result: dict[str, Any] = {
        "robot": robot.name, "clearances": clearances.name, "model": model, "take_up": take_up,
        "noise_mm": noise_mm, "noise_deg": noise_deg, "seed": seed, "grid": grid,
        "expected_noise_rmsd": {"dx": math.sqrt(2) * noise_mm, "dy": math.sqrt(2) * noise_mm,
                                "dphi_deg": math.sqrt(2) * noise_deg},
        "orientations": [{"phi_deg": p, **c._statistics()} for p, c in by_phi.items()],
    }
    json_path = out_dir / f"{prefix}comparison.json"
    files["comparison_json"] = json_path
    result["files"] = files
    payload = _json_ready({**result, "points": comparison.records()})
    json_path.write_text(json.dumps(payload, indent=2) + "\n", encoding="utf-8")
    return _json_ready(result)

