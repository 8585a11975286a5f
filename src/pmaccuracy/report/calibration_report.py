"""The calibration report: one self-contained HTML page of a kinematic calibration (issue 23).

``calibration_report(path, identification, data, experiment=..., clearances=...)`` (and ``pmaccuracy calibrate
report`` / ``calibrate simulate --report``) writes what a designer reads after a calibration:

* a three-line verdict: what calibration removed, what is left, whether what is left is the clearance floor;
* the residuals of the measured poses over the workspace before (nominal robot) and after (identified robot)
  calibration as arrows (position) coloured by the orientation residual, over the workspace outline;
* the parameter estimates, as changes from nominal with 1-sigma error bars per unit group (mm, deg, gain);
* the singular value spectrum of the column-scaled identification Jacobian and the parameters it cannot
  separate, in words (:mod:`pmaccuracy.accuracy.calibration.identifiability`);
* the observability indices O1-O4 of the measured poses against a D-optimal plan, random and grid choices of
  the same number (:func:`pmaccuracy.accuracy.calibration.plan.pose_set_indices`);
* the accuracy before and after calibration beside the clearance floor at the same poses: the clearances'
  worst case (:func:`pmaccuracy.accuracy.bounds.max_pose_errors`) and RMS
  (:func:`pmaccuracy.accuracy.distributions.sample_pose_errors`).

Residuals are exact: the measured pose ``m_n`` minus the pose ``FK(theta; c_n)`` where the model robot
``theta`` (nominal, then identified) puts the commands ``c_n``, read in its measurement frame (the forward
kinematics of :func:`pmaccuracy.accuracy.calibration.simulate.measure`, noise-free, assembly mode nearest the
measured pose). With a virtual experiment (``experiment``) the before/after accuracy is the one measured on the
true robot at targets the fit never saw; with measured data alone it is the fit's residual at the measured
poses (not an independent check, and the report says so). Lengths in mm, angles in degrees in the page.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import LogLocator, MaxNLocator

from .. import __version__
from .._savefig import SYMBOLS, save_figure
from ..accuracy.bounds import max_pose_errors
from ..accuracy.calibration.compensate import sample_serial_errors
from ..accuracy.calibration.data import CalibrationData
from ..accuracy.calibration.identifiability import RTOL
from ..accuracy.calibration.identify import Identification, jacobian, serial_jacobian, serial_whitening, whitening
from ..accuracy.calibration.parameters import SerialParameterVector, frame_apply, serial_poses
from ..accuracy.calibration.plan import candidate_commands, pose_set_indices
from ..accuracy.calibration.simulate import Experiment, measure
from ..accuracy.distributions import sample_pose_errors
from ..errors import ConfigError
from ..io.resolve import load_clearances
from ..kinematics.workspace import constant_orientation_workspace
from ..model.serial import SerialArm, load_serial_sources, max_serial_errors
from .document import Document, provenance
from .figures import FONT_PT, LABEL_PT, REPORT_WIDTH_IN, SUPTITLE_PT, TITLE_PT, wrap_text

#: Monte Carlo samples of the clearance floor's RMS at each pose.
FLOOR_SAMPLES = 2000
#: The longest "before" arrow of the residual map is drawn this fraction of the workspace's span long.
ARROW_FRACTION = 0.12
#: Random joint values drawn for the reachable area of a serial arm behind its residual maps.
REACH_SAMPLES = 4000
#: What is left counts as the clearance floor at a pose when it is within the floor plus this many sigmas.
FLOOR_SIGMAS = 3.0


#: Space (inches) kept between a text and the next thing: another axes' texts, a legend, the figure's edge.
GAP_IN = 0.1


def _new_figure(height: float = 4.0) -> Figure:
    """A report-wide figure drawn by Agg (its renderer measures the texts as they will be drawn)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = Figure(figsize=(REPORT_WIDTH_IN, height))
    FigureCanvasAgg(fig)
    return fig


def _reach_in(fig: Figure, ax) -> tuple[float, float, float, float]:
    """How far (inches) the texts of ``ax`` (title, axis labels, tick labels, offset texts) reach past its
    box: left, bottom, right, top."""
    r = fig.canvas.get_renderer()
    box, tight = ax.get_window_extent(r), ax.get_tightbbox(r, bbox_extra_artists=[])
    return tuple(max(0.0, v) / fig.dpi for v in (box.x0 - tight.x0, box.y0 - tight.y0, tight.x1 - box.x1,
                                                 tight.y1 - box.y1))


def _arrange(fig: Figure, grid: list[list], heights: list[float], *, top: float = 0.0, bottom: float = 0.0,
             extra: list[float] | None = None, passes: int = 2) -> list[list[tuple[float, float, float, float]]]:
    """Place the axes of ``grid`` (rows of axes, None for an empty cell) at fixed positions measured in
    inches, with each row's axes ``heights[r]`` high and each column as wide as the figure leaves after
    every column's and row's texts (measured, :func:`_reach_in`) and :data:`GAP_IN` around them; ``top`` /
    ``bottom``: inches kept free above / below (a title, a legend); ``extra``: inches kept free under each
    row's texts (a key). Sizes the figure's height. Measured
    again after placing (``passes``), as the tick labels follow the axes' size. Returns each cell's box
    ``(x0, y0, w, h)`` in inches, row by row."""
    nrows, ncols = len(grid), len(grid[0])
    width = fig.get_figwidth()
    cells = []
    for _ in range(passes):
        reach = [[_reach_in(fig, ax) if ax is not None else (0.0, 0.0, 0.0, 0.0) for ax in row] for row in grid]
        left = [max(reach[r][c][0] for r in range(nrows)) + GAP_IN for c in range(ncols)]
        right = [max(reach[r][c][2] for r in range(nrows)) + GAP_IN for c in range(ncols)]
        below = [max(reach[r][c][1] for c in range(ncols)) + GAP_IN + (extra[r] if extra else 0.0)
                 for r in range(nrows)]
        above = [max(reach[r][c][3] for c in range(ncols)) + GAP_IN for r in range(nrows)]
        ax_w = (width - sum(left) - sum(right)) / ncols
        height = top + sum(above) + sum(heights) + sum(below) + bottom
        fig.set_size_inches(width, height)
        cells, y = [], height - top
        for r, row in enumerate(grid):
            y -= above[r] + heights[r]
            x, line = 0.0, []
            for c, ax in enumerate(row):
                x += left[c]
                line.append((x, y, ax_w, heights[r]))
                if ax is not None:
                    ax.set_position((x / width, y / height, ax_w / width, heights[r] / height))
                x += ax_w + right[c]
            cells.append(line)
            y -= below[r]
    return cells


def _legend(fig: Figure, handles: list, labels: list[str], *, loc: str = "lower center",
            anchor: tuple[float, float] = (0.5, 0.0), width: float | None = None):
    """A frameless figure legend at ``loc`` of the figure point ``anchor`` with as many columns as fit in
    ``width`` inches (default: the figure's width less :data:`GAP_IN` each side), its labels wrapped when even
    one column is too wide. Returns the legend and its height in inches."""
    if not labels:
        return None, 0.0
    width = (fig.get_figwidth() - 2 * GAP_IN) if width is None else width
    r = fig.canvas.get_renderer()
    for ncol in range(len(labels), 0, -1):
        texts = labels if ncol > 1 else [wrap_text(fig, t, width - 0.6, FONT_PT) for t in labels]
        leg = fig.legend(handles, texts, loc=loc, bbox_to_anchor=anchor, ncol=ncol, fontsize=FONT_PT,
                         frameon=False, handlelength=1.6, columnspacing=1.2, borderaxespad=0.2)
        box = leg.get_window_extent(r)
        if box.width / fig.dpi <= width or ncol == 1:
            return leg, box.height / fig.dpi
        leg.remove()
    raise AssertionError("unreachable")


def model_residuals(ident: Identification, data: CalibrationData, values: np.ndarray | None = None) -> np.ndarray:
    """Exact residuals ``(N, 3)`` (mm, mm, rad; measurement frame) of the measured poses against the robot
    ``values`` (default: the identified one): ``m_n - FK(values; c_n)``, the orientation wrapped to (-pi, pi];
    NaN rows where the model cannot reach the command near the measured pose (module docstring).

    >>> import pmaccuracy as pm
    >>> pv = pm.error_parameters(pm.Manipulator.preset("symmetric_3rpr"))
    >>> ex = pm.simulate_calibration(pv, 20, seed=1, n_targets=5)
    >>> r = model_residuals(ex.identification, ex.data)
    >>> r.shape, bool(np.nanmax(np.hypot(r[:, 0], r[:, 1])) < 0.05)
    ((20, 3), True)
    """
    pv = ident.parameters
    values = ident.values if values is None else np.asarray(values, dtype=float)
    if isinstance(pv, SerialParameterVector):   # explicit, single-valued forward kinematics of the arm
        model = serial_poses(pv, values, data.commands)
    else:
        reference = frame_apply(values[-3:], data.poses)
        model = measure(pv, values, data.commands, reference, noise=(0.0, 0.0, 0.0))
    r = data.poses - model
    r[:, 2] = np.angle(np.exp(1j * r[:, 2]))
    return r


def start_values(ident: Identification) -> np.ndarray:
    """The robot "before calibration" ``(P,)``: the nominal, with the parameters the fit kept fixed at their
    values in the identification (the measurement frame given to ``calibrate identify --frame``; otherwise
    nominal too)."""
    pv = ident.parameters
    values = pv.nominal.copy()
    fixed = pv.index(ident.identifiability.fixed)
    values[fixed] = np.asarray(ident.values, dtype=float)[fixed]
    return values


def _stats(r: np.ndarray) -> dict:
    """Max and RMS of the position (mm) and orientation (deg) size of residuals ``(N, 3)`` (NaN rows left out)."""
    ok = np.all(np.isfinite(r), axis=1)
    p, a = np.hypot(r[ok, 0], r[ok, 1]), np.degrees(np.abs(r[ok, 2]))
    if not ok.any():
        return {"points": 0, "max_mm": None, "rms_mm": None, "max_deg": None, "rms_deg": None}
    return {"points": int(ok.sum()), "max_mm": float(p.max()), "rms_mm": float(np.sqrt(np.mean(p ** 2))),
            "max_deg": float(a.max()), "rms_deg": float(np.sqrt(np.mean(a ** 2)))}


def _floor(robot, clearances, poses: np.ndarray, seed: int) -> dict:
    """The clearance floor at robot-frame ``poses (T, 3)``: worst case and RMS of ``|dp|`` (mm), ``|dphi|`` (rad).
    A serial arm (``robot`` a :class:`~pmaccuracy.model.serial.SerialArm`): ``poses`` are its joint values
    ``(T, n)`` (a pose does not say the arm's configuration), the worst case from
    :func:`~pmaccuracy.model.serial.max_serial_errors` as ``calibrate compensate`` takes it."""
    if isinstance(robot, SerialArm):
        b = max_serial_errors(robot, clearances, poses, allow_outside=True)
        e = sample_serial_errors(robot, clearances, poses, FLOOR_SAMPLES, seed=seed)
    else:
        b = max_pose_errors(robot, clearances, poses)
        e = sample_pose_errors(robot, clearances, poses, FLOOR_SAMPLES, seed=seed)
    return {"dp_max": np.asarray(b.dp_max, dtype=float), "dphi_max": np.asarray(b.dphi_max, dtype=float),
            "dp_rms": np.sqrt(np.mean(np.sum(e[..., :2] ** 2, axis=-1), axis=0)),
            "dphi_rms": np.sqrt(np.mean(e[..., 2] ** 2, axis=0))}


def _fmt(v: float | None, digits: int = 3) -> str:
    return "-" if v is None or not np.isfinite(v) else f"{v:.{digits}g}"


def calibration_report(path: str | Path, identification: Identification, data: CalibrationData, *,
                       experiment: Experiment | None = None, clearances=None, seed: int = 0,
                       command: str | None = None) -> dict:
    """Write the calibration report of ``identification`` from ``data`` as one self-contained HTML file.

    ``experiment``: the :func:`~pmaccuracy.accuracy.calibration.simulate.simulate_calibration` run the data
    come from (its true parameters are drawn beside the estimates and its before/after errors at the targets
    are the accuracy section); ``clearances`` (a preset, file or object): the floor, the worst case and the RMS
    of the clearances at the same poses on the identified robot (an experiment run with clearances brings its
    own floor at the targets, :attr:`Compensation.floor_dp_max` etc., which is used as it is); ``seed``: of the random pose choices and the floor's Monte Carlo samples;
    ``command``: the command line, for the footer. The figures are PNG embedded in the page.

    Returns the report's numbers, JSON-ready: ``residuals`` (``before``/``after``: max and RMS, mm and deg),
    ``estimates`` (per parameter: name, unit, nominal, estimate, change, sigma in mm / deg / 1; ``true`` with an
    experiment), ``singular_values``, ``condition``, ``fixed`` and ``combinations``, ``indices`` (O1-O4 and
    condition of the measured poses, a plan, random and grid choices), ``accuracy`` (``where``: "targets" or
    "measured poses", before/after and the floor per pose, mm / deg), ``verdict`` (three sentences).
    Raises :class:`~pmaccuracy.errors.ConfigError` for a path that is not ``.html``.
    """
    path = Path(path)
    if path.suffix.lower() not in (".html", ".htm"):
        raise ConfigError(f"unsupported file type {path.suffix!r}: use .html", source=str(path), key="path")
    ident = identification
    pv = ident.parameters
    nominal_robot = pv.robot
    robot_id = pv.split(ident.values)[0]
    before = model_residuals(ident, data, start_values(ident))
    after = model_residuals(ident, data)
    positions = frame_apply(ident.values[-3:], data.poses)
    outliers = np.isin(np.asarray(data.labels, dtype=object), np.asarray(ident.outliers, dtype=object))
    res = {"before": _stats(before), "after": _stats(after[~outliers]),
           "outliers": list(ident.outliers)}
    serial = isinstance(pv, SerialParameterVector)
    indices = pose_set_indices(pv, positions, seed=seed, commands=data.commands if serial else None)
    if clearances is None:
        sources = None
    else:
        sources = load_serial_sources(clearances, robot_id) if serial else load_clearances(clearances, robot_id)
    acc = _accuracy(ident, data, experiment, sources, before, after, outliers, seed)
    results = {"robot": nominal_robot.name, "architecture": nominal_robot.architecture, "points": len(data),
               "source": data.source, "clearances": _clearance_name(sources, experiment),
               "residuals": res, "estimates": _estimates(ident, experiment),
               "singular_values": ident.identifiability.singular_values.tolist(),
               "condition": ident.identifiability.condition,
               "observability": {k: getattr(ident.identifiability, k) for k in ("O1", "O2", "O3", "O4")},
               "fixed": list(ident.identifiability.fixed), "combinations": list(ident.identifiability.combinations),
               "indices": indices, "accuracy": acc, "serial": serial}
    results["verdict"] = _verdict(results, experiment is not None)
    doc = Document(f"pmaccuracy: kinematic calibration of {nominal_robot.name} ({nominal_robot.architecture})",
                   footer=provenance(command, __version__))
    with tempfile.TemporaryDirectory(prefix="pmaccuracy-calibration-") as tmp:
        tmp = Path(tmp)
        _intro(doc, results, ident, experiment)
        _residual_section(doc, tmp, pv, float(ident.values[-1]), positions, before, after, outliers, res)
        _parameter_section(doc, tmp, results, experiment is not None)
        _identifiability_section(doc, tmp, ident, data, results)
        _observability_section(doc, tmp, results)
        _accuracy_section(doc, tmp, results, experiment is not None)
        _method_section(doc, serial)
        html = doc.to_html()
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(html, encoding="utf-8")
    return results


def true_in_gauge(ident: Identification, true: np.ndarray) -> np.ndarray:
    """The true parameters ``(P,)`` of a simulation as the fit can see them: moved along each unidentifiable
    direction (:attr:`Identifiability.null_directions`, first order) until the fixed parameters are at nominal,
    ``true - sum_f (true_f - nominal_f) n_f``. The estimates are compared with these (a camera cannot tell its
    frame's error from a rigid motion of the base, so the base points absorb it)."""
    pv = ident.parameters
    idf = ident.identifiability
    true = np.asarray(true, dtype=float)
    fixed = pv.index(idf.fixed)
    null = np.asarray(idf.null_directions, dtype=float)
    if not fixed or null.shape != (len(fixed), len(pv.names)):
        return true.copy()
    return true - (true[fixed] - pv.nominal[fixed]) @ null


def _clearance_name(sources, experiment) -> str | None:
    if sources is not None:
        return getattr(sources, "name", "given")
    if experiment is not None and experiment.compensation.floor_dp_max is not None:
        return "those of the experiment"
    return None


def _estimates(ident: Identification, experiment: Experiment | None) -> list[dict]:
    rows = []
    true = None if experiment is None else true_in_gauge(ident, experiment.true)
    for k, e in enumerate(ident.estimates()):
        f = np.degrees if e["unit"] == "rad" else float
        row = {"parameter": e["name"], "unit": "deg" if e["unit"] == "rad" else e["unit"],
               "nominal": float(f(e["nominal"])), "estimate": float(f(e["estimate"])),
               "change": float(f(e["estimate"] - e["nominal"])),
               "sigma": float(f(e["sigma"])) if e["identified"] else None, "identified": bool(e["identified"])}
        if true is not None:
            row["true_change"] = float(f(true[k] - e["nominal"]))
        rows.append(row)
    return rows


def _accuracy(ident, data, experiment, sources, before, after, outliers, seed) -> dict:
    """Per pose: before/after position (mm) and orientation (deg) error sizes and the floor (module docstring)."""
    pv = ident.parameters
    robot_id = pv.split(ident.values)[0]
    keep = None
    if experiment is not None:
        where = "targets"
        b, a = experiment.errors_before, experiment.errors_after
        poses = frame_apply(ident.values[-3:], experiment.targets)
        sigma = np.hypot(*experiment.compensation.predicted_sigma[:, :2].T)
        sigma_deg = np.degrees(experiment.compensation.predicted_sigma[:, 2])
    else:
        where = "measured poses"
        reached = ~outliers & np.all(np.isfinite(after), axis=1)
        keep = reached & np.all(np.isfinite(before), axis=1)
        unreached = int(np.sum(reached & ~keep))   # the nominal robot ends far from the reading (module docstring)
        b, a = before[keep], after[keep]
        poses = frame_apply(ident.values[-3:], data.poses[keep])
        sigma = np.hypot(data.sigmas[keep, 0], data.sigmas[keep, 1])
        sigma_deg = np.degrees(data.sigmas[keep, 2])
    out = {"where": where, "poses": len(b),
           "before_mm": np.hypot(b[:, 0], b[:, 1]).tolist(), "after_mm": np.hypot(a[:, 0], a[:, 1]).tolist(),
           "before_deg": np.degrees(np.abs(b[:, 2])).tolist(), "after_deg": np.degrees(np.abs(a[:, 2])).tolist(),
           "sigma_mm": sigma.tolist(), "sigma_deg": sigma_deg.tolist(), "floor": None,
           "left_out": 0 if experiment is not None else unreached}
    fl = None
    comp = None if experiment is None else experiment.compensation
    if comp is not None and comp.floor_dp_max is not None:   # the compensation's own floor at the targets
        fl = {"dp_max": comp.floor_dp_max, "dphi_max": comp.floor_dphi_max, "dp_rms": comp.floor_dp_rms,
              "dphi_rms": comp.floor_dphi_rms}
    elif sources is not None:
        if isinstance(pv, SerialParameterVector):   # the floor at the arm's joint values (as compensate takes it)
            _, off, gain, _ = pv.split(ident.values)
            poses = off + gain * data.commands[keep]
        fl = _floor(robot_id, sources, poses, seed)
    if fl is not None:
        out["floor"] = {"dp_max_mm": np.asarray(fl["dp_max"]).tolist(), "dp_rms_mm": np.asarray(fl["dp_rms"]).tolist(),
                        "dphi_max_deg": np.degrees(fl["dphi_max"]).tolist(),
                        "dphi_rms_deg": np.degrees(fl["dphi_rms"]).tolist()}
        within = np.asarray(out["after_mm"]) <= np.asarray(fl["dp_max"]) + FLOOR_SIGMAS * sigma
        within_deg = np.asarray(out["after_deg"]) <= np.degrees(fl["dphi_max"]) + FLOOR_SIGMAS * sigma_deg
        out["within_floor"] = int(np.sum(within & within_deg))
    return out


def _verdict(r: dict, simulated: bool) -> list[str]:
    acc = r["accuracy"]
    if acc["poses"] == 0:
        return ["Removed: not known: no pose has both a reading the nominal robot explains and one the identified "
                "robot explains (Section 1 lists the residuals that exist).",
                "Left: not known.", "Floor: not compared."]
    b, a = np.asarray(acc["before_mm"]), np.asarray(acc["after_mm"])
    bd, ad = np.asarray(acc["before_deg"]), np.asarray(acc["after_deg"])
    where = (f"at {acc['poses']} targets the fit never saw (measured on the true robot)" if simulated
             else f"at the {acc['poses']} measured poses (the fit's own residuals)")
    rms = lambda v: float(np.sqrt(np.mean(v ** 2)))  # noqa: E731
    line1 = (f"Removed: calibration took the largest position error {where} from {_fmt(b.max())} mm to "
             f"{_fmt(a.max())} mm (RMS {_fmt(rms(b))} -> {_fmt(rms(a))} mm) and the largest orientation error "
             f"from {_fmt(bd.max())} deg to {_fmt(ad.max())} deg, with {len(r['fixed'])} of "
             f"{len(r['estimates'])} parameters fixed at nominal (Section 3).")
    sig = float(np.max(acc["sigma_mm"]))
    line2 = (f"Left: up to {_fmt(a.max())} mm and {_fmt(ad.max())} deg; the identified parameters' own "
             f"uncertainty accounts for up to {_fmt(sig)} mm (1 sigma)" if simulated else
             f"Left: up to {_fmt(a.max())} mm and {_fmt(ad.max())} deg (RMS {_fmt(rms(a))} mm); the camera's "
             f"1 sigma is {_fmt(sig)} mm")
    line2 += "."
    if acc["floor"] is None:
        line3 = ("Floor: no clearances were given (`--clearances`), so whether what is left is the clearance floor "
                 "was not checked.")
    else:
        fl = np.asarray(acc["floor"]["dp_max_mm"])
        n, k = acc["poses"], acc["within_floor"]
        verdict = ("what is left is the clearance floor: only tighter joints remove it" if k == n else
                   "what is left is mostly the clearance floor" if k >= 0.9 * n else
                   "what is left is more than the clearances explain (unmodelled errors, or a poor fit)")
        line3 = (f"Floor: the clearances' worst case at the same poses is {_fmt(fl.min())}-{_fmt(fl.max())} mm; "
                 f"{k} of {n} poses are within it plus {FLOOR_SIGMAS:g} sigma in position and orientation: "
                 f"{verdict}.")
    return [line1, line2, line3]


def _intro(doc: Document, r: dict, ident: Identification, experiment) -> None:
    doc.paragraph("**Verdict.**")
    doc.bullets(r["verdict"])
    src = ("a virtual calibration experiment (a true robot: the nominal plus seeded parameter errors, measured on "
           "its exact forward kinematics with camera noise" + (" and clearance states" if r["clearances"] else "")
           + ")" if experiment is not None else f"the measurements `{r['source']}`")
    doc.paragraph(f"Calibration of `{r['robot']}` ({r['architecture']}) from {r['points']} measured poses of {src}: "
                  f"{len(ident.identifiability.identified)} parameters identified, {len(r['fixed'])} fixed at "
                  f"nominal, {_outliers(r['residuals']['outliers'])}; clearances: {r['clearances'] or 'none given'}. "
                  "Lengths in mm, angles in degrees, gains as numbers (1 = nominal; their changes in Figure 2 in "
                  "units of 10^-3).")


def _outliers(labels: list) -> str:
    if not labels:
        return "no outlier"
    return (f"{len(labels)} outlier{'s' if len(labels) > 1 else ''} dropped (point{'s' if len(labels) > 1 else ''} "
            f"{', '.join(map(str, labels))})")


def _outline(ax, robot, phis_rad) -> None:
    styles = ("-", "--", ":")
    for phi, ls in zip(phis_rad, styles):
        ws = constant_orientation_workspace(robot, float(phi))
        for k, loop in enumerate(ws.loops):
            ax.plot(loop[:, 0], loop[:, 1], ls, color="0.45", lw=1.0,
                    label=f"workspace, phi = {np.degrees(phi):.3g} deg" if k == 0 else None)


def _nice(v: float) -> float:
    """A round number (1, 2 or 5 times a power of ten) at most ``v``."""
    if not np.isfinite(v) or v <= 0:
        return 1.0
    e = 10 ** np.floor(np.log10(v))
    return float(max(m for m in (1, 2, 5) if m * e <= v) * e)


def _reach(ax, pv: SerialParameterVector) -> None:
    """The positions the nominal arm reaches: :data:`REACH_SAMPLES` seeded joint values within the ranges."""
    p = serial_poses(pv, pv.nominal, candidate_commands(pv, n=REACH_SAMPLES, seed=0))
    ax.plot(p[:, 0], p[:, 1], ".", color="0.82", ms=1.5, zorder=0,
            label=f"reachable by the nominal arm ({REACH_SAMPLES} random joint values within range)")


def _residual_section(doc, tmp, pv, frame_phi, positions, before, after, outliers, res) -> None:
    from matplotlib.colors import Normalize

    serial = isinstance(pv, SerialParameterVector)

    doc.heading("Residuals of the measured poses, before and after calibration")
    phi_lo, phi_hi = float(np.nanmin(positions[:, 2])), float(np.nanmax(positions[:, 2]))
    phis = list(dict.fromkeys(round(p, 9) for p in (0.0, phi_lo, phi_hi)))
    span = float(np.nanmax(np.ptp(positions[:, :2], axis=0))) if len(positions) > 1 else 1.0
    fig = _new_figure()
    axes = [fig.add_axes((0.1, 0.4, 0.4, 0.5))]
    axes.append(fig.add_axes((0.55, 0.4, 0.4, 0.5), sharex=axes[0], sharey=axes[0]))
    caxes = [fig.add_axes((0.1, 0.1, 0.4, 0.03)), fig.add_axes((0.55, 0.1, 0.4, 0.03))]
    c, s_ = np.cos(frame_phi), np.sin(frame_phi)   # residuals are in the measurement frame: turn to the robot's
    scales, extent, quivers = [], [], []
    for ax, cax, r, title in ((axes[0], caxes[0], before, "before: nominal robot"),
                              (axes[1], caxes[1], after, "after: identified robot")):
        ok = np.all(np.isfinite(r), axis=1)
        size = np.hypot(r[ok & ~outliers, 0], r[ok & ~outliers, 1])   # outliers drawn, not scaled for
        longest = float(size.max()) if size.size else 1.0
        magnify = ARROW_FRACTION * max(span, 1.0) / max(longest, 1e-12)
        key = _nice(longest / 2)
        vmax = float(np.max(np.degrees(np.abs(r[ok & ~outliers, 2])))) if (ok & ~outliers).any() else 1.0
        scales.append((magnify, key, vmax))
        if serial:
            _reach(ax, pv)
        else:
            _outline(ax, pv.robot, np.array(phis))
        u, v = c * r[ok, 0] - s_ * r[ok, 1], s_ * r[ok, 0] + c * r[ok, 1]
        extent.append(np.column_stack([positions[ok, 0] + magnify * u, positions[ok, 1] + magnify * v]))
        quiv = ax.quiver(positions[ok, 0], positions[ok, 1], u, v, np.degrees(r[ok, 2]), cmap="coolwarm",
                         norm=Normalize(-max(vmax, 1e-9), max(vmax, 1e-9)), angles="xy", scale_units="xy",
                         scale=1.0 / magnify, width=0.006, edgecolor="0.2", linewidth=0.3)
        quivers.append(quiv)
        ax.plot(positions[ok, 0], positions[ok, 1], ".", color="0.2", ms=2)
        if outliers.any():
            ax.plot(positions[outliers, 0], positions[outliers, 1], "x", color="k", ms=7, label="outlier (dropped)")
        ax.set_title(f"{title}\narrows magnified {magnify:.3g} times", fontsize=TITLE_PT)
        ax.set_aspect("equal", adjustable="box")
        ax.set_xlabel("x [mm]", fontsize=LABEL_PT)
        ax.tick_params(labelsize=FONT_PT)
        ax.xaxis.set_major_locator(MaxNLocator(5))
        ax.yaxis.set_major_locator(MaxNLocator(6))
        bar = fig.colorbar(quiv, cax=cax, orientation="horizontal")
        bar.set_label(r"orientation residual $\delta\phi$ [deg]", fontsize=LABEL_PT)
        cax.xaxis.set_major_locator(MaxNLocator(5, symmetric=True))
        cax.tick_params(labelsize=FONT_PT)
    axes[1].tick_params(labelleft=False)
    pts = np.vstack(extent + [np.vstack(line.get_xydata()) for ax in axes for line in ax.get_lines()])
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    (x0, y0), (x1, y1) = pts.min(axis=0), pts.max(axis=0)
    pad = 0.04 * max(x1 - x0, y1 - y0, 1.0)
    axes[0].set_xlim(x0 - pad, x1 + pad)            # every arrow tip inside (quiver does not autoscale)
    axes[0].set_ylim(y0 - pad, y1 + pad)
    axes[0].set_ylabel("y [mm]", fontsize=LABEL_PT)
    handles, labels = axes[0].get_legend_handles_labels()
    _, legend_h = _legend(fig, handles, labels)
    title = wrap_text(fig, "Measured minus model pose: arrows the position residual, colour the orientation "
                      "residual", REPORT_WIDTH_IN - 2 * GAP_IN, SUPTITLE_PT)
    head = fig.suptitle(title, fontsize=SUPTITLE_PT, va="top")
    head_h = head.get_window_extent(fig.canvas.get_renderer()).height / fig.dpi + 2 * GAP_IN
    key_h = 0.3                                      # the key arrow and its text, between a map and its colour bar
    ratio = (y1 - y0 + 2 * pad) / (x1 - x0 + 2 * pad)
    cells = _arrange(fig, [axes, caxes], [3.0, 0.13], top=head_h, bottom=legend_h + GAP_IN, extra=[key_h, 0.0])
    ax_h = float(np.clip(cells[0][0][2] * ratio, 1.5, 4.2))
    cells = _arrange(fig, [axes, caxes], [ax_h, 0.13], top=head_h, bottom=legend_h + GAP_IN, extra=[key_h, 0.0])
    height = fig.get_figheight()
    head.set_y(1.0 - GAP_IN / height)
    for ax, quiv, (magnify, key, _), (bx, by, bw, bh) in zip(axes, quivers, scales, cells[1]):
        ax.quiverkey(quiv, (bx + 0.3 * bw) / REPORT_WIDTH_IN, (by + bh + GAP_IN + key_h / 2) / height, key,
                     f"{key:g} mm residual", labelpos="E", coordinates="figure", fontproperties={"size": FONT_PT})
    (mb, kb, vb), (ma, ka, va) = scales
    res["arrows"] = {"before": {"magnify": mb, "key_mm": kb}, "after": {"magnify": ma, "key_mm": ka}}
    n = doc.figure(save_figure(fig, tmp / "residuals.png"),
                   f"Residuals (measured minus model pose) of the measured poses before (left) and after (right) "
                   f"calibration, drawn at the poses in the robot frame. Arrows are the position residuals, "
                   f"magnified {mb:.3g} times before (key arrow {kb:g} mm) and {ma:.3g} times after (key arrow "
                   f"{ka:g} mm); colours the orientation residual (deg; scales +-{vb:.3g} and +-{va:.3g} deg); "
                   + ("light grey dots the positions the nominal arm reaches within its joint ranges (an arm's "
                      "reachable area: its orientation is free there, so no outline per orientation is drawn). "
                      if serial else "grey lines the nominal robot's workspace at the orientations stated. ")
                   + "Outliers (crosses) are drawn "
                   "but set neither scale.")
    b, a = res["before"], res["after"]
    doc.paragraph(f"Figure {n}: the residual is the measured pose minus the pose where the model robot (nominal, "
                  "then identified) puts the same commands, by its exact forward kinematics, in its measurement "
                  "frame. Before calibration it is the geometric error the calibration sees; after, what the "
                  "identified model cannot explain: camera noise, the clearances' random states, and any error "
                  "the model does not have.")
    doc.table(["residual", "points", "max position [mm]", "RMS position [mm]", "max orientation [deg]",
               "RMS orientation [deg]"],
              [["before (nominal robot)", b["points"], b["max_mm"], b["rms_mm"], b["max_deg"], b["rms_deg"]],
               ["after (identified robot, outliers dropped)", a["points"], a["max_mm"], a["rms_mm"], a["max_deg"],
                a["rms_deg"]]])


_GROUPS = (("mm", "change [mm]", 1.0), ("deg", "change [deg]", 1.0), ("1", "gain - 1 [10^-3]", 1e3))


def _parameter_section(doc, tmp, r, simulated: bool) -> None:
    doc.heading("Parameter estimates")
    groups = [(u, label, f, [e for e in r["estimates"] if e["unit"] == u]) for u, label, f in _GROUPS]
    groups = [g for g in groups if g[3]]
    heights = [len(g[3]) for g in groups]
    fig = _new_figure()
    axes = [fig.add_axes((0.3, 0.1, 0.6, 0.8)) for _ in groups]
    for ax, (unit, label, f, rows) in zip(axes, groups):
        y = np.arange(len(rows))
        for k, e in enumerate(rows):
            if e["identified"]:
                ax.errorbar(e["change"] * f, k, xerr=e["sigma"] * f, fmt="o", color="C0", ms=4, capsize=2)
            else:
                ax.plot(0.0, k, "o", mfc="white", mec="0.5", ms=5)
            if simulated:
                ax.plot(e["true_change"] * f, k, "x", color="C3", ms=6)
        ax.axvline(0.0, color="0.6", lw=0.8)
        ax.set_yticks(y, [e["parameter"] + ("" if e["identified"] else " (fixed)") for e in rows], fontsize=FONT_PT)
        ax.set_ylim(len(rows) - 0.5, -0.5)
        ax.set_xlabel(label, fontsize=LABEL_PT)
        ax.tick_params(axis="x", labelsize=FONT_PT)
        ax.xaxis.set_major_locator(MaxNLocator(6))
        ax.grid(axis="x", color="0.9")
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], marker="o", color="C0", ls="-", ms=4, label="estimate - nominal, +- 1 sigma"),
               Line2D([], [], marker="o", mfc="white", mec="0.5", ls="", label="fixed at nominal")]
    if simulated:
        handles.append(Line2D([], [], marker="x", color="C3", ls="",
                              label="true - nominal, in the fit's gauge (simulation)"))
    _, legend_h = _legend(fig, handles, [h.get_label() for h in handles], loc="upper center", anchor=(0.5, 1.0))
    _arrange(fig, [[ax] for ax in axes], [0.3 * h for h in heights], top=legend_h + GAP_IN)
    n = doc.figure(save_figure(fig, tmp / "parameters.png"),
                   "Change of each parameter from nominal with its 1-sigma error bar, per unit (mm; deg; gain - 1 "
                   "in 10^-3)" + (", and the true change of the simulation, moved along the unidentifiable directions "
                   "until the fixed parameters are nominal (what the fit can see: Section 3)" if simulated else "")
                   + "; hollow: fixed at nominal.")
    head = ["parameter", "unit", "nominal", "estimate", "change", "1 sigma"]
    rows = []
    for e in r["estimates"]:
        row = [e["parameter"], e["unit"], e["nominal"], e["estimate"], e["change"],
               e["sigma"] if e["identified"] else "fixed"]
        if simulated:
            t = e["true_change"]
            row += [t, (e["change"] - t) / e["sigma"] if e["identified"] and e["sigma"] else None]
        rows.append(row)
    if simulated:
        head += ["true change", "(change - true) / sigma"]
        z = [row[-1] for row in rows if row[-1] is not None]
        doc.paragraph(f"Figure {n} and the table: the simulation knows the true parameters, so the normalized "
                      f"errors (change - true) / sigma of the identified ones can be read: {len(z)} of them, "
                      f"largest |z| = {max(abs(v) for v in z):.3g}, RMS {np.sqrt(np.mean(np.square(z))):.3g} (near 1 "
                      "when the sigmas are honest).")
    else:
        doc.paragraph(f"Figure {n} and the table: each identified parameter's estimate and its 1-sigma uncertainty "
                      "(covariance s^2 (J^T J)^-1 of the weighted fit); gains as numbers (1 = nominal).")
    doc.table(head, rows)


def _spectrum_axes(J: np.ndarray, s: np.ndarray):
    """The singular value spectrum figure of a calibration: ``s`` (the identified parameters' scaled singular
    values at the start) as bars, and every parameter's at the estimate from the whitened Jacobian ``J (rows, P)``
    with its columns scaled to unit norm (zero columns as zeros, drawn at the axis floor) as circles, with the
    threshold ``RTOL s_1``. Returns ``(fig, ax, full)``; the caller adds the title, legend and layout."""
    norms = np.linalg.norm(J, axis=0)
    full = np.linalg.svd(J[:, norms > 0] / norms[norms > 0], compute_uv=False)
    full = np.concatenate([full, np.zeros(int(np.sum(norms == 0)))])
    fig = _new_figure()
    ax = fig.add_axes((0.15, 0.3, 0.8, 0.6))
    floor = s[0] * 1e-12 if s.size else 1e-12
    ax.bar(np.arange(1, s.size + 1), s, color="C0", label=f"identified parameters ({s.size}), at the start")
    ax.plot(np.arange(1, full.size + 1), np.maximum(full, floor), "o", color="0.3", ms=4, mfc="none",
            label=f"all {full.size} parameters, at the estimate (zeros drawn at the axis floor)")
    if s.size:
        ax.axhline(RTOL * s[0], color="C3", ls="--", lw=1, label=f"threshold {RTOL:g} s_1: below it, not separable")
    ax.set_yscale("log")
    ax.set_ylim(floor / 3, None)
    ax.yaxis.set_major_locator(LogLocator(numticks=6))
    ax.xaxis.set_major_locator(MaxNLocator(8, integer=True))
    ax.set_xlabel("index of the singular value", fontsize=LABEL_PT)
    ax.set_ylabel("scaled singular value", fontsize=LABEL_PT)
    ax.tick_params(labelsize=FONT_PT)
    return fig, ax, full


def _identifiability_section(doc, tmp, ident: Identification, data: CalibrationData, r: dict) -> None:
    doc.heading("Identifiability: the singular value spectrum")
    idf = ident.identifiability
    s = np.asarray(idf.singular_values, dtype=float)
    pv = ident.parameters
    if isinstance(pv, SerialParameterVector):
        J = serial_jacobian(pv, ident.values, data, W=serial_whitening(pv, ident.values, data, ident.clearances))
    else:
        J = jacobian(pv, ident.values, data, whitening(pv, ident.values, data, ident.clearances))
    fig, ax, full = _spectrum_axes(J, s)
    r["full_spectrum"] = full.tolist()
    ax.set_title(f"condition number {idf.condition:.4g}, O1 = {idf.O1:.3g}", fontsize=TITLE_PT)
    handles, labels = ax.get_legend_handles_labels()
    leg, legend_h = _legend(fig, handles, labels)
    note, note_h = None, 0.0
    if idf.fixed:   # under the axes (the bars fill the plot down to its floor), wrapped to the figure's width
        text = (f"{len(idf.fixed)} not separable (circles below the dashed line): " + ", ".join(idf.fixed[:6])
                + (f" and {len(idf.fixed) - 6} more" if len(idf.fixed) > 6 else ""))
        text = wrap_text(fig, text, REPORT_WIDTH_IN - 2 * GAP_IN, FONT_PT)
        note = fig.text(0.5, 0.0, text, ha="center", va="bottom", fontsize=FONT_PT)
        note_h = note.get_window_extent(fig.canvas.get_renderer()).height / fig.dpi + GAP_IN
    _arrange(fig, [[ax]], [2.4], top=GAP_IN, bottom=legend_h + note_h + GAP_IN)
    if note is not None:
        note.set_y((legend_h + GAP_IN) / fig.get_figheight())
    n = doc.figure(save_figure(fig, tmp / "spectrum.png"),
                   "Singular values of the whitened identification Jacobian with unit-length columns: bars, the "
                   "identified parameters (the fit's own spectrum); circles, every parameter at the estimate. A "
                   "direction whose singular value is below the dashed line changes no residual: it cannot be "
                   "identified.")
    doc.paragraph(f"Figure {n}: condition number {idf.condition:.4g}; observability indices O1 = {idf.O1:.4g} "
                  f"(Borm-Menq), O2 = {idf.O2:.4g} (Driels-Pathre), O3 = {idf.O3:.4g}, O4 = {idf.O4:.4g} "
                  "(Nahvi-Hollerbach). What the measurements cannot separate, fixed at nominal before the fit "
                  "(never absorbed silently):")
    doc.bullets(list(idf.combinations) or ["every parameter is identifiable from these poses"])


def _observability_section(doc, tmp, r: dict) -> None:
    doc.heading("Observability of the measured poses")
    ind = r["indices"]
    names = [("poses", "measured poses"), ("planned", "D-optimal plan"), ("random", "random (mean of 20)"),
             ("grid", "grid")]
    keys = ("O1", "O2", "O3", "O4", "condition")
    colours = ["C0", "C2", "0.6", "0.8"]
    fig = _new_figure()
    grid = [[fig.add_axes((0.1, 0.1, 0.2, 0.2)) for _ in range(3)], [None, None, None]]
    grid[1][:2] = [fig.add_axes((0.1, 0.1, 0.2, 0.2)) for _ in range(2)]
    axes = grid[0] + grid[1][:2]
    for ax, k in zip(axes, keys):
        vals = np.array([ind[n][k] for n, _ in names], dtype=float)
        top = float(np.nanmax(np.abs(vals))) if np.isfinite(vals).any() else 1.0
        e = int(np.floor(np.log10(top))) if top > 0 else 0
        e = e if e < -1 or e > 3 else 0       # the power of ten in the title, not as an offset over the axes
        ax.bar(range(len(names)), vals / 10.0 ** e, color=colours)
        ax.set_xticks([])
        ax.yaxis.set_major_locator(MaxNLocator(4))
        ax.tick_params(axis="y", labelsize=FONT_PT)
        title = k + (rf" [$10^{{{e}}}$]" if e else "") + (" (lower: better)" if k == "condition" else "")
        ax.set_title(title, fontsize=TITLE_PT)
    from matplotlib.patches import Patch

    cells = _arrange(fig, grid, [1.5, 1.5])
    x0, y0, w, h = cells[1][1]                       # the key: in the free cell, right of the last panel
    lo, hi = x0 + w + _reach_in(fig, grid[1][1])[2] + GAP_IN, REPORT_WIDTH_IN - GAP_IN
    _legend(fig, [Patch(color=c) for c in colours], [lbl for _, lbl in names], loc="center",
            anchor=((lo + hi) / 2 / REPORT_WIDTH_IN, (y0 + h / 2) / fig.get_figheight()), width=hi - lo)
    n = doc.figure(save_figure(fig, tmp / "observability.png"),
                   f"Observability indices of the {r['points']} measured poses beside a D-optimal plan, random "
                   "choices (mean of 20) and evenly spaced candidates of the same number; larger is better, "
                   "except the condition number.")
    if r.get("serial"):
        doc.paragraph(f"Figure {n} and the table: the indices on the plan's scale (the nominal arm's identification "
                      "Jacobian with the default camera sigmas, columns scaled by their RMS over the candidates of "
                      "`calibrate plan`: 4000 seeded random joint values within the ranges), so the rows compare as "
                      "they are; the measured poses are taken at the commands they were measured with (a pose "
                      "alone does not say the arm's configuration).")
    else:
        doc.paragraph(f"Figure {n} and the table: the indices on the plan's scale (the nominal robot's whitened "
                      "identification Jacobian with the default camera sigmas, columns scaled by their RMS over the "
                      "default candidate grid of `calibrate plan`, orientations within +-0.35 rad, about 20 deg), so "
                      "the rows compare as they are; the measured poses are taken where they were measured (robot "
                      "frame).")
    doc.table(["poses", "O1", "O2", "O3", "O4", "condition"],
              [[lbl] + [ind[n][k] for k in keys] for n, lbl in names])


def _accuracy_section(doc, tmp, r: dict, simulated: bool) -> None:
    doc.heading("Accuracy before and after calibration, beside the clearance floor")
    acc = r["accuracy"]
    if acc["poses"] == 0:
        doc.paragraph("No pose to compare: the nominal or the identified robot reaches none of the readings "
                      "within 5 mm and 5 deg.")
        return
    if acc["left_out"]:
        doc.paragraph(f"{acc['left_out']} measured poses are left out here: the nominal robot's forward kinematics "
                      "ends more than 5 mm or 5 deg from the reading (or has no assembly mode there), so their error "
                      "before calibration is not a number; Section 1 shows them after.")
    order = np.argsort(acc["before_mm"])
    x = np.arange(1, acc["poses"] + 1)
    fig = _new_figure()
    axes = [fig.add_axes((0.1, 0.3, 0.35, 0.6)), fig.add_axes((0.6, 0.3, 0.35, 0.6))]
    fl = acc["floor"]
    xlabel = wrap_text(fig, f"{acc['where']}, sorted by the position error before", REPORT_WIDTH_IN / 2 - 1.0,
                       LABEL_PT)
    for ax, q, unit in ((axes[0], "mm", "mm"), (axes[1], "deg", "deg")):
        b, a = np.asarray(acc[f"before_{q}"])[order], np.asarray(acc[f"after_{q}"])[order]
        ax.plot(x, b, "o", color="0.55", ms=4, label="before calibration")
        ax.plot(x, a, "o", color="C0", ms=4, label="after calibration")
        if fl is not None:
            key = "dp" if q == "mm" else "dphi"
            ax.plot(x, np.asarray(fl[f"{key}_max_{unit}"])[order], "-", color="C3", lw=1.2,
                    label=f"clearance floor: worst case ({SYMBOLS['dp_max'][0]}, {SYMBOLS['dphi_max'][0]})")
            ax.plot(x, np.asarray(fl[f"{key}_rms_{unit}"])[order], "--", color="C3", lw=1.0,
                    label="clearance floor: RMS")
        ax.set_xlabel(xlabel, fontsize=LABEL_PT)
        ax.set_ylabel(("position error |dp|" if q == "mm" else "orientation error |dphi|") + f" [{unit}]",
                      fontsize=LABEL_PT)
        ax.tick_params(labelsize=FONT_PT)
        ax.xaxis.set_major_locator(MaxNLocator(5, integer=True))
        ax.yaxis.set_major_locator(MaxNLocator(6))
        ax.set_ylim(0, None)
    handles, labels = axes[0].get_legend_handles_labels()
    _, legend_h = _legend(fig, handles, labels)
    _arrange(fig, [axes], [2.4], top=GAP_IN, bottom=legend_h + GAP_IN)
    what = ("measured on the true robot at targets the fit never saw, with the nominal commands (before) and "
            "the compensated commands of the identified robot (after)" if simulated else
            "the residuals at the measured poses, of the nominal (before) and the identified (after) robot: the "
            "fit's own residuals, not an independent check")
    n = doc.figure(save_figure(fig, tmp / "accuracy.png"),
                   f"Pose errors: {what}; beside them the clearance floor at the same poses on the identified robot."
                   if fl is not None else f"Pose errors: {what} (no clearances given: no floor).")
    rms = lambda v: float(np.sqrt(np.mean(np.square(v))))  # noqa: E731
    rows = [["before calibration", max(acc["before_mm"]), rms(acc["before_mm"]), max(acc["before_deg"]),
             rms(acc["before_deg"])],
            ["after calibration", max(acc["after_mm"]), rms(acc["after_mm"]), max(acc["after_deg"]),
             rms(acc["after_deg"])]]
    if fl is not None:
        rows += [["clearance floor, worst case (as `bounds`)", max(fl["dp_max_mm"]), rms(fl["dp_max_mm"]),
                  max(fl["dphi_max_deg"]), rms(fl["dphi_max_deg"])],
                 ["clearance floor, RMS (as `statistics`)", max(fl["dp_rms_mm"]), rms(fl["dp_rms_mm"]),
                  max(fl["dphi_rms_deg"]), rms(fl["dphi_rms_deg"])]]
    doc.paragraph(f"Figure {n} and the table, over the {acc['poses']} {acc['where']}: " + (
        f"{acc['within_floor']} of them are within the clearances' worst case plus {FLOOR_SIGMAS:g} sigma "
        + ("of the identified parameters' uncertainty carried to the pose" if simulated else "of the camera")
        + " in both position and orientation." if fl is not None else
        "give `--clearances` to see the floor that only tighter joints remove."))
    doc.table(["", "max |dp| [mm]", "RMS |dp| [mm]", "max |dphi| [deg]", "RMS |dphi| [deg]"], rows)


def _method_section(doc: Document, serial: bool = False) -> None:
    doc.heading("Method", numbered=False)
    if serial:
        doc.paragraph("Identification (`calibrate identify`) of a serial arm: nonlinear least squares on the exact "
                      "model, the forward residual (measured pose minus the arm's explicit forward kinematics at the "
                      "commands) divided by the readings' sigmas, a robust soft_l1 pass that drops outliers, then a "
                      "plain pass whose covariance s^2 (J^T J)^-1 gives the 1-sigma uncertainties. Parameters whose "
                      "scaled Jacobian columns add a singular value below 1e-6 s_1 are fixed at nominal and named in "
                      "words. The clearance floor: the worst case of the joints' clearances and the actuator errors "
                      "(exact first-order bound, as `pmaccuracy bounds` on the arm) and their RMS (Monte Carlo, "
                      "uniform in the sets) at the joint values of the same poses on the identified arm.")
        return
    doc.paragraph("Identification (`calibrate identify`): nonlinear least squares on the exact model, each leg's "
                  "inverse-kinematic residual whitened by the inverse-kinematic Jacobian and the readings' sigmas "
                  "(first-order equal to the forward pose residual), a robust soft_l1 pass that drops outliers, "
                  "then a plain pass whose covariance s^2 (J^T J)^-1 gives the 1-sigma uncertainties. Parameters "
                  "whose scaled Jacobian columns add a singular value below 1e-6 s_1 are fixed at nominal and "
                  "named in words. The clearance floor: the worst case of the clearances (exact first-order "
                  "bound, as `pmaccuracy bounds`) and their RMS (Monte Carlo over states inside the sets, as "
                  "`pmaccuracy statistics`) at the same poses on the identified robot.")
