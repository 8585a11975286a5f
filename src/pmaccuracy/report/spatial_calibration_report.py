"""The calibration report of a spatial robot (issue 39): one self-contained HTML page, as the planar one
(:mod:`pmaccuracy.report.calibration_report`).

``spatial_calibration_report(path, identification, data, experiment=..., clearances=...)`` (and ``pmaccuracy
calibrate report`` / ``calibrate simulate --report`` for a spatial robot) writes:

* a three-line verdict: what calibration removed, what is left, whether what is left is the clearance floor;
* the residuals of the readings before (nominal robot) and after (identified robot) calibration beside the
  clearance floor at the same readings (:func:`~pmaccuracy.accuracy.calibration.spatial_compensate
  .residuals_beside_floor`: the first-order worst case of the error sources and their exact RMS at the pose the
  identified robot takes there, at the reading's target for a laser tracker);
* the parameter estimates, as changes from nominal with 1-sigma error bars per unit group (mm, deg, gain);
* the singular value spectrum of the column-scaled whitened identification Jacobian and the parameters it
  cannot separate, in words;
* the observability indices of the poses (a simulation: the D-optimal plan beside random choices);
* with a virtual experiment, the accuracy on the true robot at targets the fit never saw, with the nominal and
  the compensated commands, beside the floor there and the compensated pose's predicted 1-sigma.

Residuals are those of the fit (:mod:`pmaccuracy.accuracy.calibration.spatial_identify`): the reading minus
what the model robot's forward kinematics predicts at its commands, in the device's frame; their size is the
distance (mm) and, for full poses, the rotation angle (deg). Lengths in mm, angles in degrees in the page.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from matplotlib.ticker import FormatStrFormatter, LogLocator, MaxNLocator, NullFormatter

from .. import __version__
from .._savefig import save_figure
from ..accuracy.calibration.spatial_compensate import FLOOR_SIGMAS, residuals_beside_floor
from ..accuracy.calibration.spatial_identify import (SpatialCalibrationData, SpatialIdentification,
                                                     measurement_jacobian, platform_poses, residuals)
from ..accuracy.calibration.spatial_simulate import SpatialExperiment
from ..errors import ConfigError
from ..model.spatial_sources import SpatialErrorSources
from .calibration_report import GAP_IN, _arrange, _fmt, _legend, _new_figure, _parameter_section, _spectrum_axes
from .document import Document, provenance
from .figures import FONT_PT, LABEL_PT, REPORT_WIDTH_IN, TITLE_PT, wrap_text


def _rms(v) -> float:
    v = np.asarray(v, dtype=float)
    v = v[np.isfinite(v)]
    return float(np.sqrt(np.mean(v ** 2))) if v.size else float("nan")


def _max(v) -> float:
    v = np.asarray(v, dtype=float)
    v = v[np.isfinite(v)]
    return float(v.max()) if v.size else float("nan")


def _sizes(r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position (mm) and rotation-angle (deg, NaN for position-only) sizes of residuals ``(N, k)``."""
    p = np.linalg.norm(r[:, :3], axis=1)
    a = np.degrees(np.linalg.norm(r[:, 3:], axis=1)) if r.shape[1] == 6 else np.full(len(r), np.nan)
    return p, a


def spatial_calibration_report(path: str | Path, identification: SpatialIdentification,
                               data: SpatialCalibrationData, *, experiment: SpatialExperiment | None = None,
                               clearances=None, command: str | None = None) -> dict:
    """Write the calibration report of a spatial robot's ``identification`` from ``data`` as one self-contained
    HTML file (module docstring).

    ``experiment``: the :func:`~pmaccuracy.accuracy.calibration.spatial_simulate.simulate_spatial_calibration`
    run the data come from (its true parameters beside the estimates, its plan, its accuracy at the targets);
    ``clearances`` (:class:`~pmaccuracy.model.spatial_sources.SpatialErrorSources`, a preset name or a file;
    default: those of the experiment): the clearance floor; ``command``: the command line, for the footer.

    Returns the report's numbers, JSON-ready: ``residuals`` (before/after and the floor per reading: mm, deg),
    ``estimates``, ``singular_values``, ``condition``, ``fixed``, ``combinations``, ``indices``, ``accuracy``
    (with an experiment: before/after, the floor and the predicted sigma per target), ``verdict``. Raises
    :class:`~pmaccuracy.errors.ConfigError` for a path that is not ``.html``.
    """
    path = Path(path)
    if path.suffix.lower() not in (".html", ".htm"):
        raise ConfigError(f"unsupported file type {path.suffix!r}: use .html", source=str(path), key="path")
    ident = identification
    pv = ident.parameters
    robot = pv.robot
    if clearances is None and experiment is not None:
        clearances = experiment.clearances
    sources = None if clearances is None else SpatialErrorSources.load(clearances, pv.split(ident.values)[0])
    start = pv.nominal.copy()
    fixed = pv.index(ident.identifiability.fixed)
    start[fixed] = ident.values[fixed]
    with np.errstate(all="ignore"):
        before = residuals(pv, start, data, platform_poses(pv, start, data.commands))
        after = residuals(pv, ident.values, data, platform_poses(pv, ident.values, data.commands))
    if any(i >= len(data) for i in ident.outliers):
        raise ConfigError(f"the identification leaves out row {max(ident.outliers) + 1} of {len(data)} readings: give "
                          "the readings it was identified from", key="data")
    outlier = np.zeros(len(data), dtype=bool)
    outlier[list(ident.outliers)] = True
    bp, bd = _sizes(before)
    ap, ad = _sizes(after)
    res = {"readings": len(data), "kind": pv.kind, "before_mm": bp.tolist(), "after_mm": ap.tolist(),
           "before_deg": bd.tolist(), "after_deg": ad.tolist(), "outliers": [int(i) + 1 for i in ident.outliers],
           "sigma_mm": np.sqrt(np.sum(data.sigmas[:, :3] ** 2, axis=1)).tolist(), "floor": None}
    if sources is not None:
        fl = residuals_beside_floor(ident, data, sources)
        res["floor"] = {"dp_max_mm": fl["floor"]["dp_max"].tolist(), "dp_rms_mm": fl["floor"]["dp_rms"].tolist(),
                        "dtheta_max_deg": np.degrees(fl["floor"]["dtheta_max"]).tolist(),
                        "dtheta_rms_deg": np.degrees(fl["floor"]["dtheta_rms"]).tolist()}
        res["within_floor"] = int(np.sum(fl["within"] & ~outlier))
    results = {"robot": robot.name, "architecture": robot.architecture, "readings": len(data), "kind": pv.kind,
               "source": data.source, "clearances": None if sources is None else sources.name,
               "residuals": res, "estimates": _estimates(ident, experiment),
               "singular_values": ident.identifiability.singular_values.tolist(),
               "condition": ident.identifiability.condition, "fixed": list(ident.identifiability.fixed),
               "combinations": list(ident.identifiability.combinations), "indices": _indices(ident, experiment),
               "accuracy": _accuracy(experiment), "scale": ident.scale}
    results["verdict"] = _verdict(results)
    doc = Document(f"pmaccuracy: kinematic calibration of {robot.name} ({robot.architecture})",
                   footer=provenance(command, __version__))
    with tempfile.TemporaryDirectory(prefix="pmaccuracy-calibration-") as tmp:
        tmp = Path(tmp)
        _intro(doc, results, ident, experiment)
        _residual_section(doc, tmp, results)
        _parameter_section(doc, tmp, results, experiment is not None)
        _identifiability_section(doc, tmp, ident, data, results)
        _observability_section(doc, results)
        if experiment is not None:
            _accuracy_section(doc, tmp, results)
        _method_section(doc)
        html = doc.to_html()
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(html, encoding="utf-8")
    return results


def _estimates(ident: SpatialIdentification, experiment) -> list[dict]:
    """One row per parameter (mm, deg, gain); a simulation's truth is already in the fit's gauge (its
    unidentifiable parameters are left nominal: :mod:`~pmaccuracy.accuracy.calibration.spatial_simulate`)."""
    rows = []
    for k, e in enumerate(ident.estimates()):
        f = np.degrees if e["unit"] == "rad" else float
        row = {"parameter": e["name"], "unit": "deg" if e["unit"] == "rad" else e["unit"],
               "nominal": float(f(e["nominal"])), "estimate": float(f(e["estimate"])),
               "change": float(f(e["estimate"] - e["nominal"])),
               "sigma": float(f(e["sigma"])) if e["identified"] else None, "identified": bool(e["identified"])}
        if experiment is not None:
            row["true_change"] = float(f(experiment.true[k] - e["nominal"]))
        rows.append(row)
    return rows


def _indices(ident: SpatialIdentification, experiment) -> dict:
    idf = ident.identifiability
    out = {"fit": {"O1": idf.O1, "O2": idf.O2, "O3": idf.O3, "O4": idf.O4, "condition": idf.condition}}
    plan = None if experiment is None else experiment.plan
    if plan is not None:
        out["planned"] = dict(plan.index)
        out["random"] = dict(plan.random_index)
        out["candidates"] = plan.n_candidates
    return out


def _accuracy(experiment) -> dict | None:
    if experiment is None or experiment.compensation is None:
        return None
    comp = experiment.compensation
    b, a = experiment.errors_before, experiment.errors_after
    ok = np.all(np.isfinite(b), axis=1) & np.all(np.isfinite(a), axis=1)
    out = {"targets": int(ok.sum()), "left_out": int(np.sum(~ok)), "before_mm": b[ok, 0].tolist(),
           "after_mm": a[ok, 0].tolist(), "before_deg": np.degrees(b[ok, 1]).tolist(),
           "after_deg": np.degrees(a[ok, 1]).tolist(), "sigma_mm": comp.predicted_sigma[ok, 0].tolist(),
           "sigma_deg": np.degrees(comp.predicted_sigma[ok, 1]).tolist(), "floor": None,
           "mobility": experiment.identification.parameters.robot.mobility}
    if comp.floor is not None:
        fl = comp.floor
        out["floor"] = {"dp_max_mm": fl["dp_max"][ok].tolist(), "dp_rms_mm": fl["dp_rms"][ok].tolist(),
                        "dtheta_max_deg": np.degrees(fl["dtheta_max"][ok]).tolist(),
                        "dtheta_rms_deg": np.degrees(fl["dtheta_rms"][ok]).tolist()}
        within = a[ok, 0] <= fl["dp_max"][ok] + FLOOR_SIGMAS * comp.predicted_sigma[ok, 0]
        out["within_floor"] = int(np.sum(within))
    return out


def _verdict(r: dict) -> list[str]:
    res, acc = r["residuals"], r["accuracy"]
    if acc is not None and acc["targets"]:
        b, a = np.asarray(acc["before_mm"]), np.asarray(acc["after_mm"])
        where = f"at {acc['targets']} targets the fit never saw (measured on the true robot)"
        sig = _max(acc["sigma_mm"])
        left_sig = f"the identified parameters' own uncertainty accounts for up to {_fmt(sig)} mm (1 sigma)"
    else:
        keep = ~np.isin(np.arange(1, r["readings"] + 1), res["outliers"])
        b, a = np.asarray(res["before_mm"])[keep], np.asarray(res["after_mm"])[keep]
        where = f"at the {int(keep.sum())} readings (the fit's own residuals)"
        left_sig = f"a reading's 1 sigma is {_fmt(_max(res['sigma_mm']))} mm"
    line1 = (f"Removed: calibration took the largest position error {where} from {_fmt(_max(b))} mm to "
             f"{_fmt(_max(a))} mm (RMS {_fmt(_rms(b))} -> {_fmt(_rms(a))} mm), with {len(r['fixed'])} of "
             f"{len(r['estimates'])} parameters fixed at nominal (Section 3).")
    line2 = f"Left: up to {_fmt(_max(a))} mm; {left_sig}."
    fl = res["floor"]
    if fl is None:
        line3 = ("Floor: no clearances were given (`--clearances`), so whether what is left is the clearance floor "
                 "was not checked.")
    else:
        n = r["readings"] - len(res["outliers"])
        k = res["within_floor"]
        verdict = ("what is left is the clearance floor: only tighter joints remove it" if k == n else
                   "what is left is mostly the clearance floor" if k >= 0.9 * n else
                   "what is left is more than the clearances explain (unmodelled errors, or a poor fit)")
        line3 = (f"Floor: the clearances' worst case at the readings is {_fmt(np.nanmin(fl['dp_max_mm']))}-"
                 f"{_fmt(np.nanmax(fl['dp_max_mm']))} mm; {k} of {n} readings are within it plus "
                 f"{FLOOR_SIGMAS:g} reading sigmas: {verdict}.")
        if acc is not None and acc["floor"] is not None:
            line3 += (f" At the targets {acc['within_floor']} of {acc['targets']} compensated poses are within the "
                      f"floor plus {FLOOR_SIGMAS:g} predicted sigmas.")
    return [line1, line2, line3]


def _intro(doc: Document, r: dict, ident: SpatialIdentification, experiment) -> None:
    doc.paragraph("**Verdict.**")
    doc.bullets(r["verdict"])
    kind = "full poses" if r["kind"] == "pose" else "target positions (laser tracker)"
    if experiment is not None:
        choice = ("D-optimal poses" if experiment.plan is not None else "random poses")
        src = (f"a virtual calibration experiment ({choice}; a true robot: the nominal plus seeded parameter errors, "
               "read on its exact forward kinematics with device noise"
               + (", and a clearance state per reading" if experiment.clearances is not None else "") + ")")
    else:
        src = f"the readings `{r['source']}`"
    outl = r["residuals"]["outliers"]
    doc.paragraph(f"Calibration of `{r['robot']}` ({r['architecture']}) from {r['readings']} readings of {kind} "
                  f"from {src}: {len(ident.identifiability.identified)} parameters identified, {len(r['fixed'])} "
                  f"fixed at nominal, "
                  + (f"{len(outl)} outlier(s) left out (rows {', '.join(map(str, outl))})" if outl else "no outlier")
                  + f"; clearances: {r['clearances'] or 'none given'}; the fit weighed each reading by its stated "
                  + ("sigmas and its clearance state's covariance" if ident.clearances is not None else "sigmas alone")
                  + f". Residual scale s = {r['scale']:.3g} (about 1 when the weights explain the residuals). Lengths "
                  "in mm, angles in degrees, gains as numbers (1 = nominal).")


def _sorted_panels(fig, series: list[dict], xlabel: str):
    """One axes per quantity: points before (grey) and after (blue), sorted by the size before, and the floor's
    worst case (red line) and RMS (red dashed) at the same places; log scale. ``series``: dicts with
    ``before, after, floor_max, floor_rms, ylabel`` (the floor entries may be None)."""
    order = np.argsort(series[0]["before"])
    axes = []
    for k, s in enumerate(series):
        ax = fig.add_axes((0.1 + 0.5 * k, 0.3, 0.35, 0.6))
        x = np.arange(1, len(order) + 1)
        ax.plot(x, np.asarray(s["before"])[order], "o", color="0.55", ms=4, label="before calibration")
        ax.plot(x, np.asarray(s["after"])[order], "o", color="C0", ms=4, label="after calibration")
        if s.get("floor_max") is not None:
            ax.plot(x, np.asarray(s["floor_max"])[order], "-", color="C3", lw=1.2,
                    label="clearance floor: worst case")
            ax.plot(x, np.asarray(s["floor_rms"])[order], "--", color="C3", lw=1.0, label="clearance floor: RMS")
        ax.set_yscale("log")
        lo, hi = ax.get_ylim()
        ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0) if hi / lo < 300 else (1.0,), numticks=12))
        ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.xaxis.set_major_locator(MaxNLocator(5, integer=True))
        ax.set_xlabel(wrap_text(fig, xlabel, REPORT_WIDTH_IN / len(series) - 1.0, LABEL_PT), fontsize=LABEL_PT)
        ax.set_ylabel(s["ylabel"], fontsize=LABEL_PT)
        ax.tick_params(labelsize=FONT_PT)
        axes.append(ax)
    handles, labels = axes[0].get_legend_handles_labels()
    _, legend_h = _legend(fig, handles, labels)
    _arrange(fig, [axes], [2.4], top=GAP_IN, bottom=legend_h + GAP_IN)


def _positive(v) -> np.ndarray:
    """Sizes for a log axis: zeros (a reading exactly explained) drawn at 1e-9 of the largest."""
    v = np.asarray(v, dtype=float)
    top = _max(v)
    return np.where(v > 0, v, (top if np.isfinite(top) and top > 0 else 1.0) * 1e-9)


def _residual_section(doc, tmp, r: dict) -> None:
    doc.heading("Residuals of the readings, before and after calibration, beside the clearance floor")
    res = r["residuals"]
    keep = ~np.isin(np.arange(1, r["readings"] + 1), res["outliers"])
    fl = res["floor"]
    series = [{"before": _positive(np.asarray(res["before_mm"])[keep]),
               "after": _positive(np.asarray(res["after_mm"])[keep]),
               "floor_max": None if fl is None else np.asarray(fl["dp_max_mm"])[keep],
               "floor_rms": None if fl is None else np.asarray(fl["dp_rms_mm"])[keep],
               "ylabel": "position residual |dp| [mm]"}]
    if r["kind"] == "pose":
        series.append({"before": _positive(np.asarray(res["before_deg"])[keep]),
                       "after": _positive(np.asarray(res["after_deg"])[keep]),
                       "floor_max": None if fl is None else np.asarray(fl["dtheta_max_deg"])[keep],
                       "floor_rms": None if fl is None else np.asarray(fl["dtheta_rms_deg"])[keep],
                       "ylabel": "rotation residual |dθ| [deg]"})
    fig = _new_figure()
    _sorted_panels(fig, series, "readings (outliers left out), sorted by the residual before")
    n = doc.figure(save_figure(fig, tmp / "residuals.png"),
                   "Size of each reading's residual (reading minus the model robot's prediction at its commands) "
                   "before (nominal robot) and after (identified robot) calibration, log scale"
                   + ("; red, the clearance floor at the same reading: the first-order worst case of the error "
                      "sources (line) and their RMS (dashed) at the identified robot's pose there."
                      if fl is not None else " (no clearances given: no floor)."))
    rows = [["before (nominal robot)", _max(series[0]["before"]), _rms(series[0]["before"])],
            ["after (identified robot)", _max(series[0]["after"]), _rms(series[0]["after"])]]
    if fl is not None:
        rows += [["clearance floor, worst case", _max(series[0]["floor_max"]), _rms(series[0]["floor_max"])],
                 ["clearance floor, RMS", _max(series[0]["floor_rms"]), _rms(series[0]["floor_rms"])]]
    head = ["", "max |dp| [mm]", "RMS |dp| [mm]"]
    if r["kind"] == "pose":
        head += ["max |dθ| [deg]", "RMS |dθ| [deg]"]
        extra = [series[1][k] for k in ("before", "after")] + ([series[1]["floor_max"], series[1]["floor_rms"]]
                                                               if fl is not None else [])
        for row, v in zip(rows, extra):
            row += [_max(v), _rms(v)]
    text = (f"Figure {n} and the table: after calibration the residual is what the identified model cannot "
            "explain: the device's noise, the clearances' random states and any error the model does not have. ")
    if fl is not None:
        text += (f"{res['within_floor']} of {int(keep.sum())} readings are within the floor's worst case plus "
                 f"{FLOOR_SIGMAS:g} reading sigmas (a reading's 1 sigma, as a length: up to "
                 f"{_fmt(_max(res['sigma_mm']))} mm); the RMS residual after is to be read beside the floor's RMS.")
    else:
        text += "Give `--clearances` to see the floor that only tighter joints remove."
    doc.paragraph(text)
    doc.table(head, rows)


def _identifiability_section(doc, tmp, ident: SpatialIdentification, data: SpatialCalibrationData, r: dict) -> None:
    doc.heading("Identifiability: the singular value spectrum")
    idf = ident.identifiability
    pv = ident.parameters
    s = np.asarray(idf.singular_values, dtype=float)
    poses = platform_poses(pv, ident.values, data.commands)
    ok = np.all(np.isfinite(poses), axis=1) & ~np.isin(np.arange(len(data)), ident.outliers)
    sub = data.subset(ok)
    J = (measurement_jacobian(pv, ident.values, sub, poses[ok]) / sub.sigmas[:, :, None]).reshape(-1, len(pv.names))
    fig, ax, full = _spectrum_axes(J, s)
    r["full_spectrum"] = full.tolist()
    ax.set_title(f"condition number {idf.condition:.4g}", fontsize=TITLE_PT)
    handles, labels = ax.get_legend_handles_labels()
    _, legend_h = _legend(fig, handles, labels)
    _arrange(fig, [[ax]], [2.4], top=GAP_IN, bottom=legend_h + GAP_IN)
    n = doc.figure(save_figure(fig, tmp / "spectrum.png"),
                   "Singular values of the whitened identification Jacobian with unit-length columns: bars, the "
                   "identified parameters (the fit's own spectrum); circles, every parameter at the estimate. A "
                   "direction whose singular value is below the dashed line changes no reading: it cannot be "
                   "identified.")
    doc.paragraph(f"Figure {n}: condition number {idf.condition:.4g}. What the readings cannot separate, fixed at "
                  f"nominal before the fit (never absorbed silently; {len(idf.fixed)} parameters):")
    doc.bullets(list(idf.combinations) or ["every parameter is identifiable from these readings"])


def _observability_section(doc, r: dict) -> None:
    doc.heading("Observability of the poses")
    ind = r["indices"]
    keys = ("O1", "O2", "O3", "O4", "condition")
    if "planned" in ind:
        doc.paragraph(f"The poses are a D-optimal choice out of {ind['candidates']} candidates (`calibrate plan`); "
                      "the table gives its observability indices beside random choices of as many candidates (mean "
                      "of 5), on the plan's scale (the nominal robot's whitened Jacobian, default sigmas, columns "
                      "scaled by their RMS over the candidates): larger is better, except the condition number.")
        doc.table(["poses"] + list(keys), [["D-optimal plan"] + [ind["planned"][k] for k in keys],
                                           ["random (mean of 5)"] + [ind["random"][k] for k in keys]])
    doc.paragraph("Indices of the fit itself (its identified parameters, Jacobian with unit-length columns; O1 "
                  "Borm-Menq, O2 Driels-Pathre, O3, O4 Nahvi-Hollerbach):")
    doc.table(["poses"] + list(keys), [["the readings"] + [ind["fit"][k] for k in keys]])


def _accuracy_section(doc, tmp, r: dict) -> None:
    doc.heading("Accuracy before and after calibration at other poses, beside the clearance floor")
    acc = r["accuracy"]
    if acc is None or acc["targets"] == 0:
        doc.paragraph("No target to compare: the true robot takes none of the compensated commands.")
        return
    fl = acc["floor"]
    series = [{"before": _positive(acc["before_mm"]), "after": _positive(acc["after_mm"]),
               "floor_max": None if fl is None else fl["dp_max_mm"],
               "floor_rms": None if fl is None else fl["dp_rms_mm"], "ylabel": "position error |dp| [mm]"}]
    angle = "rotation error |dθ|" if acc["mobility"] != "2R1T" else "larger of |d roll|, |d pitch|"
    if acc["mobility"] != "3T":     # a 3T robot's orientation is not commanded: calibration cannot change it
        series.append({"before": _positive(acc["before_deg"]), "after": _positive(acc["after_deg"]),
                       "floor_max": None if fl is None else fl["dtheta_max_deg"],
                       "floor_rms": None if fl is None else fl["dtheta_rms_deg"], "ylabel": f"{angle} [deg]"})
    if acc["mobility"] == "2R1T":
        series[0]["ylabel"] = "height error |dz| [mm]"
    fig = _new_figure()
    _sorted_panels(fig, series, "targets, sorted by the position error before")
    n = doc.figure(save_figure(fig, tmp / "accuracy.png"),
                   "Pose errors of the true robot at targets the fit never saw, with the nominal commands (before) "
                   "and the compensated commands of the identified robot (after), each with its own clearance "
                   "state, log scale" + ("; red, the clearance floor there (worst case, line; RMS, dashed)."
                                        if fl is not None else " (no clearances: no floor)."))
    rows = [["before calibration", _max(acc["before_mm"]), _rms(acc["before_mm"]), _max(acc["before_deg"]),
             _rms(acc["before_deg"])],
            ["after calibration", _max(acc["after_mm"]), _rms(acc["after_mm"]), _max(acc["after_deg"]),
             _rms(acc["after_deg"])],
            ["predicted 1 sigma after (parameters' covariance)", _max(acc["sigma_mm"]), _rms(acc["sigma_mm"]),
             _max(acc["sigma_deg"]), _rms(acc["sigma_deg"])]]
    if fl is not None:
        rows += [["clearance floor, worst case", _max(fl["dp_max_mm"]), _rms(fl["dp_max_mm"]),
                  _max(fl["dtheta_max_deg"]), _rms(fl["dtheta_max_deg"])],
                 ["clearance floor, RMS", _max(fl["dp_rms_mm"]), _rms(fl["dp_rms_mm"]), _max(fl["dtheta_rms_deg"]),
                  _rms(fl["dtheta_rms_deg"])]]
    doc.paragraph(f"Figure {n} and the table, over {acc['targets']} targets"
                  + (f" ({acc['left_out']} left out: the true robot cannot take their commands)" if acc["left_out"]
                     else "") + ": "
                  + (f"{acc['within_floor']} of them are within the clearances' worst case plus {FLOOR_SIGMAS:g} "
                     "predicted sigmas in position." if fl is not None else
                     "give `--clearances` to see the floor that only tighter joints remove.")
                  + (" The platform's orientation is not commanded on this robot (3 translations): its angle to the "
                     f"device's axes is the same before and after, and Figure {n} leaves it out." if acc["mobility"] == "3T"
                     else "")
                  + (" This robot commands z, roll and pitch: the errors are |dz| and the larger of |d roll| and "
                     "|d pitch| (base frame), the floor's worst |dp| and angle bound them." if acc["mobility"] == "2R1T"
                     else ""))
    doc.table(["", "max |dp| [mm]", "RMS |dp| [mm]", "max angle [deg]", "RMS angle [deg]"], rows)


def _method_section(doc: Document) -> None:
    doc.heading("Method", numbered=False)
    doc.paragraph("Identification (`calibrate identify`): nonlinear least squares on the exact model, the forward "
                  "residual (reading minus the model robot's forward kinematics at the commands, in the device's "
                  "frame) whitened by the readings' sigmas and, given clearances, the first-order covariance of "
                  "each reading's clearance state, a robust soft_l1 pass that leaves outliers out, then a "
                  "plain pass whose covariance s^2 (J^T J)^-1 gives the 1-sigma uncertainties. Parameters whose "
                  "scaled Jacobian columns add a singular value below 1e-6 s_1 are fixed at nominal and named in "
                  "words. The clearance floor: the first-order worst case of the error sources (as `pmaccuracy "
                  "bounds` on a spatial robot) and their exact RMS (the sources uniform in their sets, as "
                  "`pmaccuracy statistics`) at the identified robot's pose of each reading or target. A simulated "
                  "clearance state moves the platform by the same first-order model (one state per reading).")
