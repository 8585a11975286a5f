"""Report section "Design decisions": certified worst cases, global maxima, tolerance synthesis, statistics.

One section of ``pmaccuracy reproduce`` (:func:`pmaccuracy.report.reproduce`) that puts
side by side, for one robot, what a designer needs to fix clearances:

(a) **certified vs first-order vs best nonlinear** worst cases at a few poses for the
    clearance cases ``case1`` and ``case2`` at 1x and 10x
    (:func:`pmaccuracy.accuracy.certified.certified_pose_errors`): ``first_order <= nonlinear <=
    max over the error set of the exact pose error <= certified``; the relative gap
    ``(certified - nonlinear) / nonlinear`` says how well the exact worst case is known;
(b) the **certified global maximum** of ``dx, dy, dphi, dp`` over the workspace for
    ``phi`` in :data:`PHI_RANGE_DEG` (:func:`pmaccuracy.accuracy.global_worst.global_worst`, first-order
    model), with the attaining pose, against the best value of the report's own grid maps
    (``results["cases"]``, which only sample the paper's orientations);
(c) **tolerance synthesis** for :data:`TARGETS` over the same region
    (:func:`pmaccuracy.accuracy.synthesis.synthesize`, uniform scaling and minimum reciprocal cost),
    re-verified by the global worst case;
(d) **statistics** at the home pose and a percentile map
    (:func:`pmaccuracy.report.statistics_report.statistics_section`);
(e) **ISO 9283** AP / RP of a virtual repeated-pose test (:func:`pmaccuracy.experiment.iso9283.simulate_repeats`,
    as ``experiment simulate --repeats``) beside the model's predicted RP
    (:func:`pmaccuracy.experiment.iso9283.compare_repeatability`).

Every number shown is also stored, JSON-ready, in ``results["design_decisions"]``
(``results["design"]`` already holds section 6, the design comparison). Units: mm,
and degrees for every key ending in ``_deg``; the computations run in mm and rad.
The expensive parts run in the report's worker processes
(:meth:`pmaccuracy.report.figures.Renderer.compute`) while the certified table is computed.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from ..model.clearances import ClearanceSet
from .document import Document
from ..model.manipulator import Manipulator
from ..errors import PmAccuracyError
from ..io.resolve import load_clearances, robot_arg
from ..accuracy.bounds import max_pose_errors
from ..accuracy.certified import QUANTITIES, certified_pose_errors
from ..accuracy.distributions import pose_statistics
from ..accuracy.global_worst import global_worst, make_region
from ..accuracy.maps import certified_error_map, error_map
from ..accuracy.synthesis import default_template, parse_targets, synthesize
from ..experiment import iso9283
from ..experiment.virtual_rig import grid_poses
from ..kinematics import inverse_kinematics, regular_mask
from ..kinematics.workspace import constant_orientation_workspace
from .figures import plot_panels, render
from .statistics_report import statistics_section

#: Condition number (of A, and inverse transmission) above which a corner is left out of table (a).
WELL_CONDITIONED = 10.0
#: Clearance cases and scale factors of table (a).
CASES = ("case1", "case2")
SCALES = (1.0, 10.0)
#: Orientation interval of the global maxima and of the synthesis (deg).
PHI_RANGE_DEG = (-30.0, 30.0)
#: Certified relative gap of the global worst cases and of the synthesis' certificates (coarse: run time).
GLOBAL_GAP = 5e-3
#: Largest grid of the certified map of (a) (the report's map grid, at most this).
CERT_GRID = 101
#: Pieces of the error set the certified map's branch and bound may cut per point (1, with no split and no second
#: pass: one batched pass): near a singular edge a point would otherwise take seconds; it keeps the whole set's
#: valid, looser bound and its gap.
CERT_MAP_PIECES = 1
#: Targets of the synthesis: dp in mm, dphi in deg.
TARGETS = {"dp": 0.3, "dphi_deg": 0.3}
#: Threshold of P(|dp| > threshold) in the statistics (mm).
THRESHOLD_DP = 0.2
#: Samples of the pose statistics and of the percentile map; largest percentile-map grid.
POSE_SAMPLES, MAP_SAMPLES, MAP_GRID = 100_000, 2_000, 21
#: ISO 9283 test: clearance case, cycles, camera noise (mm, deg) and the points (3 x 3 grid: corners, centre).
ISO_CASE, ISO_CYCLES, ISO_NOISE_MM, ISO_NOISE_DEG = "case2", 30, 0.01, 0.01
ISO_POINTS = (0, 2, 4, 6, 8)
#: Quantity keys of results.json (dphi in deg) for the keys of pmaccuracy.accuracy.bounds.QUANTITIES.
KEYS = {"dx": "dx", "dy": "dy", "dphi": "dphi_deg", "dp": "dp"}
#: The keys of ``results["cases"]`` (the report's grid maps) for each quantity.
GRID_KEYS = {"dx": "dx_max", "dy": "dy_max", "dphi": "dphi_max_deg", "dp": "dp_max"}


def _deg(q: str, value: float) -> float:
    """A value of quantity ``q`` in results.json units: ``dphi`` rad -> deg, lengths unchanged (mm)."""
    return math.degrees(value) if q == "dphi" else float(value)


def _ready(value):
    """JSON-ready copy: numpy scalars/arrays to Python, non-finite floats to None, recursively."""
    if isinstance(value, dict):
        return {str(k): _ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_ready(v) for v in np.asarray(value, dtype=object).tolist()] if isinstance(value, np.ndarray) \
            else [_ready(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    return value


# ---------------------------------------------------------------------------------------------- poses
def home_pose(robot: Manipulator) -> np.ndarray:
    """The home pose ``(3,)`` [mm, mm, rad]: ``(0, 0, 0)`` when the robot reaches it, else the mean of the
    phi = 0 workspace's vertices."""

    home = np.zeros(3)
    if bool(np.asarray(inverse_kinematics(robot, home[None]).within_limits)[0]):
        return home
    ws = constant_orientation_workspace(robot, 0.0).require_nonempty()
    return np.array([*ws.vertices.mean(axis=0), 0.0])


def check_poses(robot: Manipulator, case, phi_range_deg=PHI_RANGE_DEG) -> tuple[np.ndarray, list[str]]:
    """Poses ``(n <= 3, 3)`` [mm, mm, rad] of table (a) and their labels: the home pose, the corner of the phi = 0
    workspace with the largest first-order ``dp`` and the corner of the workspaces at the ends of
    ``phi_range_deg`` with the largest one (for a 3-PPR at fixed phi every maximum is convex in the
    position, so these are the worst poses of those orientations). Corners farther from a singularity than
    :data:`WELL_CONDITIONED` allows are left out (a 3-RRR's workspace ends where a leg is stretched)."""

    cs = load_clearances(case, robot)
    poses, labels = [home_pose(robot)], ["home"]
    lo, hi = phi_range_deg
    for phis, label in (((0.0,), "worst corner, phi = 0"), ((lo, hi), f"worst corner, phi = {lo:g} or {hi:g}")):
        corners = np.vstack([np.column_stack([v, np.full(len(v), math.radians(p))])
                             for p in phis for v in [constant_orientation_workspace(robot, math.radians(p)).vertices]])
        dp = max_pose_errors(robot, cs, corners, allow_outside=True, singular="nan").dp_max
        dp = np.where(regular_mask(robot, corners, WELL_CONDITIONED), dp, np.nan)
        if np.isfinite(dp).any():           # corners at a singularity (a stretched leg) are left out
            poses.append(corners[int(np.nanargmax(dp))])
            labels.append(label)
    return np.array(poses), labels


# ---------------------------------------------------------------------------------------------- jobs
def certified_rows(robot: Manipulator, case: str, poses: np.ndarray, labels: list[str],
                   scales=SCALES, clearances=None) -> list[dict]:
    """Table (a) for one clearance case: per scale factor and pose, ``{q: {first_order, nonlinear, certified,
    gap}}`` (mm; deg for ``dphi_deg``) from :func:`pmaccuracy.accuracy.certified.certified_pose_errors` of
    the clearances ``case`` (a paper case name, or ``clearances``: any set, labelled ``case``) times each scale
    (``allow_outside``: the corners lie on the workspace's boundary; NaN / None and ``reason`` where no
    certificate)."""

    cs = load_clearances(case if clearances is None else clearances, robot)
    rows = []
    for scale in scales:
        r = certified_pose_errors(robot, cs.scaled(scale), poses, allow_outside=True, on_failure="nan",
                                  ascent=True)
        for k, (pose, label) in enumerate(zip(poses, labels)):
            qs = {}
            for q in QUANTITIES:
                qs[KEYS[q]] = {"first_order": _deg(q, r.first_order[q][k]), "nonlinear": _deg(q, r.lower[q][k]),
                               "certified": _deg(q, r.upper[q][k]), "gap": float(r.gap[q][k])}
            rows.append({"case": case, "scale": float(scale), "label": label,
                         "pose": {"x": float(pose[0]), "y": float(pose[1]), "phi_deg": math.degrees(pose[2])},
                         "reason": str(r.reason[k]) if r.reason is not None else "", "quantities": qs})
    return rows


def global_job(robot: Manipulator, case, phi_deg=PHI_RANGE_DEG, gap: float = GLOBAL_GAP, shape=None) -> dict:
    """(b): :func:`pmaccuracy.accuracy.global_worst.global_worst` of ``case`` over the workspace at ``phi`` in
    ``phi_deg``: per quantity ``lower`` (attained at ``x, y, phi_deg``), ``upper`` (certified), ``gap``,
    ``converged``; mm, deg for ``dphi_deg``."""

    region = make_region(robot, tuple(math.radians(p) for p in phi_deg), shape)
    res = global_worst(robot, case, region, gap=gap)
    qs = {KEYS[q]: {"lower": _deg(q, w.lower), "upper": _deg(q, w.upper), "gap": float(w.gap),
                    "x": float(w.pose[0]), "y": float(w.pose[1]), "phi_deg": math.degrees(w.pose[2]),
                    "converged": bool(w.converged)} for q, w in res.quantities.items()}
    return {"region": region.describe(), "target_gap": gap, "boxes": int(res.boxes), "seconds": res.seconds,
            "quantities": qs}


def synthesis_job(robot: Manipulator, mode: str, targets: dict = TARGETS, phi_deg=PHI_RANGE_DEG,
                  gap: float = GLOBAL_GAP, template=None, shape=None) -> dict:
    """(c): :func:`pmaccuracy.accuracy.synthesis.synthesize` (default template) for ``targets`` (``dp`` mm,
    ``dphi_deg`` deg) over the workspace at ``phi`` in ``phi_deg``: sources (template and synthesized values,
    mm / rad), ``scale`` (uniform) or ``cost`` (min-cost), and the re-verified certificate per quantity."""

    t0 = time.perf_counter()
    region = make_region(robot, tuple(math.radians(p) for p in phi_deg), shape)
    res = synthesize(robot, region, parse_targets(dict(targets)), mode=mode, gap=gap,
                     template=template)
    worst = {KEYS[q]: {"lower": _deg(q, w.lower), "upper": _deg(q, w.upper), "x": float(w.pose[0]),
                       "y": float(w.pose[1]), "phi_deg": math.degrees(w.pose[2]), "converged": bool(w.converged)}
             for q, w in res.worst.quantities.items()}
    name = default_template(robot) if template is None else getattr(template, "name", str(template))
    return {"mode": mode, "template": name, "scale": res.scale, "cost": res.cost,
            "cuts": res.cuts, "sources": [{"source": s.label, "template": float(s.value), "value": float(v)}
                                          for s, v in zip(res.sources, res.values)],
            "worst": worst, "seconds": time.perf_counter() - t0}


def statistics_job(robot: Manipulator, case, pose: np.ndarray, grid: int | None, seed: int,
                   figure: str | Path | None, threshold_dp: float = THRESHOLD_DP) -> dict:
    """(d): :func:`pmaccuracy.report.statistics_report.statistics_section` of ``case`` at ``pose`` (threshold
    :data:`THRESHOLD_DP`) with a ``grid x grid`` percentile map at phi = 0 (written to ``figure``); with
    ``grid=None`` only the pose statistics (:func:`~pmaccuracy.accuracy.distributions.pose_statistics`, same
    settings): ``{"pose": ..., "threshold_dp": ...}``."""

    if grid is None:
        return {"pose": pose_statistics(robot, case, pose, samples=POSE_SAMPLES, seed=seed,
                                        thresholds={"dp": threshold_dp}).to_dict(), "threshold_dp": threshold_dp}
    return statistics_section(robot, case, 0.0, grid=grid, samples=MAP_SAMPLES, pose_samples=POSE_SAMPLES,
                              seed=seed, pose=pose, threshold_dp=threshold_dp, figure=figure)


def certified_map_job(robot: Manipulator, case, phis_deg: list[float], grid: int,
                      figure: str | Path | None) -> dict:
    """(a') The certified map of the whole workspace at the report's map orientations ``phis_deg`` (deg) for the
    clearances ``case``: :func:`pmaccuracy.accuracy.maps.certified_error_map` on the ``grid x grid`` grid of the
    report's maps (the default gap target, 0.5 %; the error set not cut, :data:`CERT_MAP_PIECES`) beside :func:`pmaccuracy.accuracy.maps.error_map` on the same
    grid. Per orientation: the certified ranges (mm, deg), the largest excess of the certified bound over the
    first-order maximum and the largest gap (relative), the grid points certified and inside the workspace, and
    the time taken (s); with ``figure`` the certified |dp| and its excess over first order are drawn there."""
    t = time.perf_counter()
    phis = np.radians(np.asarray(phis_deg, dtype=float))
    cert = certified_error_map(robot, case, phis, n=grid, max_pieces=CERT_MAP_PIECES, split=0, refine=False)
    seconds = time.perf_counter() - t
    first = error_map(robot, case, phis, n=grid)
    out = {"grid": int(grid), "seconds": seconds, "clearances": first.attrs.get("clearances", ""),
           "layers": {}}
    panels = []
    for k, phi_deg in enumerate(phis_deg):
        layer = {}
        inside = np.isfinite(first["dx_max"].values[k])
        certified = np.isfinite(cert["dx_max"].values[k]) & inside
        for q, var in (("dx", "dx_max"), ("dy", "dy_max"), ("dphi", "dphi_max"), ("dp", "dp_max")):
            c, f = cert[var].values[k], first[var].values[k]
            with np.errstate(invalid="ignore", divide="ignore"):
                excess = np.where(certified, c / f - 1.0, np.nan)
            key = "dphi_deg" if q == "dphi" else q   # the maps hold dphi in degrees
            layer[key] = {"certified": [float(np.nanmin(c[certified])), float(np.nanmax(c[certified]))]
                          if certified.any() else None,
                          "excess": float(np.nanmax(excess)) if certified.any() else None,
                          "gap": float(np.nanmax(cert[f"{q}_gap"].values[k][certified])) if certified.any() else None}
        layer["points"], layer["certified_points"] = int(inside.sum()), int(certified.sum())
        out["layers"][f"{phi_deg:g}"] = layer
        x, y = cert.x.values, cert.y.values
        with np.errstate(invalid="ignore", divide="ignore"):
            excess_pct = 100 * (cert["dp_max"].values[k] / first["dp_max"].values[k] - 1.0)
        panels += [(x, y, cert["dp_max"].values[k], f"$\\phi$ = {phi_deg:g} deg: certified $\\delta p_{{max}}$",
                    "mm"),
                   (x, y, excess_pct, f"$\\phi$ = {phi_deg:g} deg: certified above first order", "%")]
    if figure is not None:
        render(figure, plot_panels, panels, ncols=2,
               suptitle=f"{robot.name}, clearances {out['clearances']}: certified worst case of the exact model "
                        f"({grid} x {grid} grid)")
        out["figure"] = True
    return out


def iso_job(robot: Manipulator, seed: int) -> dict:
    """(e): a virtual ISO 9283 test as ``experiment simulate --repeats`` does it
    (:func:`pmaccuracy.experiment.iso9283.simulate_repeats`, exact loop closure, camera noise, generator seeded with
    ``(seed, 9283)``) at the corners and centre of the 3 x 3 grid of the virtual experiment at phi = 0,
    compared with the model (:func:`pmaccuracy.experiment.iso9283.compare_repeatability`, same noise); each point
    also gets its worst case ``dp_max`` (mm) and ``dphi_max_deg``."""

    cs = ClearanceSet.load(ISO_CASE)
    grid = grid_poses(robot, 0.0, 3)
    nominal = grid[[k for k in ISO_POINTS if k < len(grid)]]
    repeats = iso9283.simulate_repeats(robot, cs, nominal, ISO_CYCLES, noise_mm=ISO_NOISE_MM,
                                       noise_deg=ISO_NOISE_DEG, model="exact",
                                       seed=np.random.default_rng((seed, 9283)),
                                       source=f"virtual ISO 9283 test ({robot.name}, {cs.name}, seed {seed})")
    out = iso9283.compare_repeatability(robot, cs, repeats, noise_mm=ISO_NOISE_MM, noise_deg=ISO_NOISE_DEG,
                                        seed=seed)
    b = max_pose_errors(robot, cs, nominal)
    for row, dp, dphi in zip(out["points"], np.atleast_1d(b.dp_max), np.atleast_1d(b.dphi_max)):
        row["dp_max"], row["dphi_max_deg"] = float(dp), math.degrees(dphi)
    out["cycles"] = ISO_CYCLES
    return out


# ---------------------------------------------------------------------------------------------- section
def design_section(doc: Document, robot: Manipulator, out: str | Path, results: dict, renderer, *,
                   seed: int = 0, cases: dict | None = None, targets: dict | None = TARGETS,
                   phi_range_deg: tuple[float, float] = PHI_RANGE_DEG, template=None, scales=SCALES,
                   iso: bool | None = None, region=None) -> dict:
    """Add the section to ``doc`` and its numbers to ``results["design_decisions"]`` (returned too).

    ``cases``: ``{label: clearances}`` (a set, a preset name or a path), default the paper's ``case1`` and
    ``case2``; ``targets`` of the synthesis (``{"dp": mm, "dphi_deg": deg, ...}``; ``None``: no synthesis)
    over the workspace for phi in ``phi_range_deg`` (deg), scaling ``template`` (default: the last case, or
    the paper's Case 1 template for the paper's cases); ``region``: the positions of (b) and (c), a shape of
    :mod:`pmaccuracy.accuracy.regions` or a box ``(x0, x1, y0, y1)`` mm (default: the whole workspace);
    ``iso``: the ISO 9283 test (default: only with the
    paper's cases). ``results["cases"]`` (the report's grid maps: ``{label: {phi_deg: {"dx_max": [lo, hi],
    ...}}}``, mm and deg) gives the grid maxima that (b) compares with; ``results["grid"]`` the map grid (the
    percentile map uses ``min(grid, MAP_GRID)``). ``renderer`` is a :class:`pmaccuracy.report.figures.Renderer`
    (its workers run the global maxima, the syntheses, the statistics with their figure and the ISO test).
    """
    t0 = time.perf_counter()
    out = Path(out)
    robot = robot_arg(robot)
    paper = cases is None
    cases = {c: c for c in CASES} if paper else dict(cases)
    labels = list(cases)
    iso = paper and robot.is_3ppr if iso is None else iso
    if template is None and not paper:
        template = cases[labels[-1]]
    phi_range = tuple(float(p) for p in phi_range_deg)
    home = home_pose(robot)
    # the exceedance threshold: the paper's 0.2 mm, or half the worst case of the last clearances at home
    threshold = THRESHOLD_DP if paper else round(0.5 * float(max_pose_errors(
        robot, cases[labels[-1]], home, allow_outside=True).dp_max), 4)
    grid = int(min(results.get("grid", MAP_GRID), MAP_GRID))
    figure = out / "design_percentiles.png"
    # longest first: the workers may still be drawing the figures of the earlier sections
    jobs = {}
    if targets:
        jobs[("synthesis", "min-cost")] = renderer.compute(synthesis_job, robot, "min-cost", targets, phi_range,
                                                           GLOBAL_GAP, template, region)
    jobs[("statistics", labels[-1])] = renderer.compute(statistics_job, robot, cases[labels[-1]], home, grid, seed,
                                                         figure, threshold)
    jobs.update({("global", c): renderer.compute(global_job, robot, cases[c], phi_range, GLOBAL_GAP, region)
                 for c in labels})
    if targets:
        jobs[("synthesis", "uniform")] = renderer.compute(synthesis_job, robot, "uniform", targets, phi_range,
                                                          GLOBAL_GAP, template, region)
    if iso:
        jobs[("iso", ISO_CASE)] = renderer.compute(iso_job, robot, seed)
    jobs.update({("statistics", c): renderer.compute(statistics_job, robot, cases[c], home, None, seed, None,
                                                     threshold) for c in labels[:-1]})
    map_phis = sorted({float(k) for c in results.get("cases", {}).values() for k in c}) or [0.0]
    cert_figure = out / "design_certified_map.png"
    jobs[("certified_map", labels[-1])] = renderer.compute(certified_map_job, robot, cases[labels[-1]], map_phis,
                                                           int(min(results.get("grid", CERT_GRID), CERT_GRID)),
                                                           cert_figure)
    rows = []
    for label in labels:
        poses, pose_labels = check_poses(robot, cases[label], phi_range)
        rows += certified_rows(robot, label, poses, pose_labels, scales, clearances=cases[label])
    got = {}
    for key, job in jobs.items():
        try:
            got[key] = job.result()
        except PmAccuracyError as exc:   # e.g. a region that reaches a singularity: said in the text, not hidden
            if key[0] in ("statistics", "certified_map"):
                raise
            got[key] = {"error": str(exc)}
    data = {"settings": {"cases": labels, "scales": list(scales), "phi_range_deg": list(phi_range),
                         "gap": GLOBAL_GAP, "targets": dict(targets or {}), "threshold_dp": threshold,
                         "pose_samples": POSE_SAMPLES, "map_samples": MAP_SAMPLES, "map_grid": grid, "seed": seed,
                         "paper_cases": paper,
                         "region": "the workspace" if region is None else
                         (region.describe() if hasattr(region, "describe") else
                          "the box x in [{:g}, {:g}] mm, y in [{:g}, {:g}] mm".format(*region)) + " (within reach)",
                         "iso": {"clearances": ISO_CASE, "cycles": ISO_CYCLES, "noise_mm": ISO_NOISE_MM,
                                 "noise_deg": ISO_NOISE_DEG} if iso else None},
            "certified": rows,
            "global_worst": {c: got[("global", c)] for c in labels},
            "synthesis": ({m: got[("synthesis", m)] for m in ("uniform", "min-cost")} if targets else None),
            "statistics": {c: got[("statistics", c)] for c in labels},
            "certified_map": {"case": labels[-1], **got[("certified_map", labels[-1])]},
            "iso9283": got[("iso", ISO_CASE)] if iso else None}
    for c, gw in data["global_worst"].items():
        if "error" in gw:
            continue
        cells = {k: v for k, v in results.get("cases", {}).get(c, {}).items()
                 if phi_range[0] - 1e-9 <= float(k) <= phi_range[1] + 1e-9}   # the map layers inside the interval
        for q, key in GRID_KEYS.items():
            best = max((cell[key][1] for cell in cells.values()), default=None)
            gw["quantities"][KEYS[q]]["grid_best"] = best
        gw["grid_orientations_deg"] = sorted(float(k) for k in cells)
    data["seconds"] = time.perf_counter() - t0
    data = _ready(data)
    results["design_decisions"] = data
    _write(doc, robot, data, figure, cert_figure)
    return data


# ---------------------------------------------------------------------------------------------- text
def _fmt(v, digits: int = 4) -> str:
    return "-" if v is None else f"{v:.{digits}f}"


def _pct(v, digits: int = 3) -> str:
    """A ratio as a percentage without the sign (the column header says [%])."""
    return "-" if v is None else f"{100 * v:.{digits}f}"


def _pose(x: float, y: float, phi_deg: float) -> str:
    return f"({x:.4g}, {y:.4g}, {phi_deg:.3g})"


def _verdict(d: dict) -> str:
    """Three lines a designer reads first: the certified worst case, the targets, how far the maps can be
    trusted (from the section's own numbers)."""
    s = d["settings"]
    lo, hi = s["phi_range_deg"]
    last = s["cases"][-1]
    if "error" in d["global_worst"][last]:
        gw = None
        line1 = (f"**Verdict.** (1) With the clearances `{last}` the worst case over {s['region']} at phi in "
                 f"[{lo:g}, {hi:g}] deg has no finite bound: {d['global_worst'][last]['error']}")
    else:
        gw = d["global_worst"][last]["quantities"]
        dp, dphi = gw["dp"], gw["dphi_deg"]
        line1 = (f"**Verdict.** (1) With the clearances `{last}`, no pose of {s['region']} at phi in [{lo:g}, "
                 f"{hi:g}] deg errs by more than dp = {_fmt(dp['upper'])} mm or dphi = {_fmt(dphi['upper'])} deg "
                 f"(certified; attained {_fmt(dp['lower'])} mm at {_pose(dp['x'], dp['y'], dp['phi_deg'])}).")
    syn_error = next((v["error"] for v in (d["synthesis"] or {}).values() if "error" in v), None)
    if syn_error:
        line2 = f" (2) The clearances could not be sized for the targets: {syn_error}"
    elif d["synthesis"]:
        uni = d["synthesis"]["uniform"]
        tgt = ", ".join(f"{k} <= {v:g} {'deg' if k.endswith('_deg') else 'mm'}" for k, v in s["targets"].items())
        meets = gw is not None and all(gw[k]["upper"] is not None and gw[k]["upper"] <= v
                                       for k, v in s["targets"].items())
        line2 = (f" (2) Against the targets {tgt}: `{last}` {'meets' if meets else 'misses'} them; the clearances "
                 f"of `{uni['template']}` may be scaled by {uni['scale']:.3g} (uniformly) and still meet them "
                 "everywhere, certified.")
    else:
        line2 = " (2) No targets were given (`--target`), so the clearances were not sized."
    at1 = [r for r in d["certified"] if r["scale"] == s["scales"][0] and r["case"] == last]
    excess = [(r["quantities"]["dp"]["certified"] - r["quantities"]["dp"]["first_order"])
              / r["quantities"]["dp"]["first_order"] for r in at1 if r["quantities"]["dp"]["certified"] is not None]
    line3 = (f" (3) The first-order maps hold to {100 * max(excess):.2g} % of the exact model at these clearances "
             "(certified at the poses of (a)), so they can be used as they are." if excess and max(excess) < 0.01
             else f" (3) The exact model exceeds the first-order maps by up to {100 * max(excess):.2g} % at the "
                  "poses of (a): use the certified values." if excess
             else " (3) The exact model could not be certified at the poses of (a): see the reasons there.")
    return line1 + line2 + line3


def _write(doc: Document, robot: Manipulator, d: dict, figure: Path, cert_figure: Path | None = None) -> None:
    s = d["settings"]
    lo, hi = s["phi_range_deg"]
    doc.heading("Design decisions: certified worst cases, global maxima, tolerance synthesis, statistics")
    doc.paragraph(_verdict(d))
    doc.paragraph(
        f"What a designer of `{robot.name}` needs to fix the clearances: how much the first-order worst case "
        "can be trusted, the worst case over the whole workspace, the largest clearances meeting a target, "
        "and how often the errors come near the worst case. Settings (coarse, for run time): global maxima "
        f"and synthesis certified to a gap of {100 * s['gap']:g} %, {s['pose_samples']} samples at the pose, "
        f"a {s['map_grid']} x {s['map_grid']} percentile map of {s['map_samples']} samples, seed {s['seed']}. "
        f"This section took {d['seconds']:.1f} s.")
    # (a) -----------------------------------------------------------------------------------------------------
    doc.paragraph(
        "**(a) Certified worst cases of the exact model.** The maps use the paper's first-order model. The exact "
        "loop closure differs by the Taylor remainder: `nonlinear` is the largest error of a feasible clearance "
        "configuration (attained, a lower bound of the exact worst case), `certified` a rigorous upper bound of "
        "it (`pmaccuracy bounds --certified`), `gap` their relative difference. Poses: home, and the corners "
        "of the workspace with the largest first-order dp at phi = 0 and at the ends of the orientation "
        f"interval [{lo:g}, {hi:g}] deg. Values in mm and deg.")
    rows = []
    for r in d["certified"]:
        p = r["pose"]
        dp, dphi = r["quantities"]["dp"], r["quantities"]["dphi_deg"]
        fo = dp["first_order"]
        excess = None if dp["certified"] is None else (dp["certified"] - fo) / fo
        rows.append([r["case"], f"{r['scale']:g}x", _pose(p["x"], p["y"], p["phi_deg"]),
                     _fmt(fo, 5), _fmt(dp["nonlinear"], 5), _fmt(dp["certified"], 5), _pct(dp["gap"]),
                     _pct(excess), _fmt(dphi["first_order"], 5), _fmt(dphi["certified"], 5),
                     _pct(dphi["gap"])])
    doc.table(["case", "clearances", "pose (x, y, phi)", "dp first-order", "dp nonlinear", "dp certified",
               "dp gap [%]", "certified above first-order [%]", "dphi first-order", "dphi certified",
               "dphi gap [%]"], rows)
    ex = {sc: max((r["quantities"]["dp"]["certified"] - r["quantities"]["dp"]["first_order"])
                  / r["quantities"]["dp"]["first_order"] for r in d["certified"]
                  if r["scale"] == sc and r["quantities"]["dp"]["certified"] is not None)
          for sc in s["scales"]}
    gaps = {sc: max(r["quantities"][q]["gap"] for r in d["certified"] for q in ("dp", "dphi_deg")
                    if r["scale"] == sc and r["quantities"][q]["gap"] is not None) for sc in s["scales"]}
    sc0, sc1 = s["scales"][0], s["scales"][-1]
    doc.paragraph(
        f"**Reading.** At {'the paper' + chr(39) + 's' if s['paper_cases'] else 'the given'} clearances the exact worst case of dp exceeds the first-order one by at "
        f"most {100 * ex[sc0]:.3f} % and dp, dphi are known to {100 * gaps[sc0]:.3f} %: the first-order maps "
        f"can be used as they are. At {sc1:g}x the clearances the excess reaches {100 * ex[sc1]:.2f} % (the "
        f"remainder grows with the square of the clearances) and the gap {100 * gaps[sc1]:.2f} %: add that "
        "margin to a first-order budget for loose joints, or use the certified value.")
    cm = d.get("certified_map")
    if cm:
        layers = cm["layers"]
        parts = []
        for phi, L in layers.items():
            if L["dp"]["certified"] is None:
                parts.append(f"at phi = {phi} deg no grid point is certified")
                continue
            parts.append(f"at phi = {phi} deg dp up to {_fmt(L['dp']['certified'][1])} mm and dphi up to "
                         f"{_fmt(L['dphi_deg']['certified'][1])} deg, at most {_pct(L['dp']['excess'])} % "
                         f"(dp) above the first-order maximum, largest gap "
                         f"{_pct(max(L[q]['gap'] for q in ('dx', 'dy', 'dphi_deg', 'dp')))} %, "
                         f"{L['certified_points']} of {L['points']} grid points certified")
        doc.paragraph(
            f"**Certified maps.** The same bounds over the whole workspace ({cm['case']}, the "
            f"{cm['grid']} x {cm['grid']} grid of the maps, `pmaccuracy map --certified`, {cm['seconds']:.1f} s): "
            + "; ".join(parts) + ". A grid point not certified is left blank (NaN), never filled with a guess.")
        if cm.get("figure") and cert_figure is not None:
            doc.figure(cert_figure, f"{cm['case']}: certified upper bound of the exact worst-case |dp| over the "
                                    "workspace (left) and how far it lies above the first-order maximum (right, %): "
                                    "the exact model's excess plus the bound's own gap (refined only to 0.1 %, "
                                    "hence the bands).")
    # (b) -----------------------------------------------------------------------------------------------------
    ok = {c: gw for c, gw in d["global_worst"].items() if "error" not in gw}
    for c, gw in d["global_worst"].items():
        if "error" in gw:
            doc.paragraph(f"**(b) Global maximum over {s['region']} for phi in [{lo:g}, {hi:g}] deg**, "
                          f"clearances `{c}`: not bounded. {gw['error']}")
    if ok:
        gw_rows = []
        for c, gw in ok.items():
            for key, w in gw["quantities"].items():
                miss = None if w["grid_best"] is None else (w["lower"] - w["grid_best"]) / w["lower"]
                gw_rows.append([c, key, _fmt(w["lower"], 5), _fmt(w["upper"], 5), _pct(w["gap"], 2),
                                _pose(w["x"], w["y"], w["phi_deg"]), _fmt(w["grid_best"], 5),
                                "-" if miss is None else f"{round(100 * miss, 2) + 0.0:.2f}",
                                "yes" if w["converged"] else "no"])
        orient = ", ".join(f"{p:g}" for p in next(iter(ok.values()))["grid_orientations_deg"])
        doc.paragraph(
            f"**(b) Global maximum over {s['region']} for phi in [{lo:g}, {hi:g}] deg** (`pmaccuracy worst`, "
            "first-order model): `attained` is the value at the pose shown, `certified max` a rigorous bound over "
            "every reachable pose of the region (branch and bound with interval arithmetic), `gap` their relative "
            f"difference. The report's maps sample the region on a grid at phi = {orient} deg only; `grid max` is "
            "their largest value and the next column how far it lies below the attained maximum.")
        doc.table(["case", "quantity", "attained", "certified max", "gap [%]", "at (x, y, phi)", "grid max",
                   "grid max below attained [%]", "certified"], gw_rows)
        ws = [w for gw in ok.values() for w in gw["quantities"].values()]
        misses = [(w["lower"] - w["grid_best"]) / w["lower"] for w in ws if w["grid_best"] is not None]
        at_end = sum(min(abs(w["phi_deg"] - lo), abs(w["phi_deg"] - hi)) < 1e-6 for w in ws)
        phis = ", ".join(f"{p:.3g}" for p in sorted({round(w["phi_deg"], 6) + 0.0 for w in ws}))
        if misses and max(misses) < 1e-3:
            grid_text = (f"the maps' grid, which holds the corners of the phi = {orient} deg workspaces, already "
                         f"comes within {100 * max(max(misses), 0.0):.2f} % of every maximum")
        elif misses:
            grid_text = f"a grid at a few orientations underestimates the maximum by up to {100 * max(misses):.1f} %"
        else:
            grid_text = "the maps give no grid value to compare"
        doc.paragraph(
            f"**Reading.** The maxima are attained at phi = {phis} deg ({at_end} of {len(ws)} at an end of the "
            f"interval); {grid_text}. What the certificate adds is the guarantee: no pose "
            f"of the region, at any orientation in between, is worse than `certified max`, at most "
            f"{100 * max(w['gap'] for w in ws):.2f} % above the attained value. That is the number to compare with a "
            "specification over the whole task space.")
    # (c) -----------------------------------------------------------------------------------------------------
    errors = [v["error"] for v in (d["synthesis"] or {}).values() if "error" in v]
    if errors:
        doc.paragraph(f"**(c) Tolerance synthesis**: not possible over this region. {errors[0]}")
    if d["synthesis"] and not errors:
        syn = d["synthesis"]
        uni, mc = syn["uniform"], syn["min-cost"]
        tgt = ", ".join(f"{k} = {v:g} {'deg' if k.endswith('_deg') else 'mm'}" for k, v in s["targets"].items())
        doc.paragraph(
            f"**(c) Tolerance synthesis** (`pmaccuracy synthesize`): the largest clearances of the template "
            f"`{uni['template']}` (its non-zero sources) that keep the certified worst case within {tgt} everywhere in {s['region']} for phi in "
            f"[{lo:g}, {hi:g}] deg. Uniform: the template times one factor; min-cost: per joint, minimizing "
            "sum eps0 / eps (halving a clearance doubles its cost), equal weights. Values in mm or rad by the source.")
        doc.table(["source", "template", "uniform", "min-cost"],
                  [[a["source"], f"{a['template']:.6g}", f"{a['value']:.6g}", f"{b['value']:.6g}"]
                   for a, b in zip(uni["sources"], mc["sources"])])
        ver = []
        for key in ("dx", "dy", "dphi_deg", "dp"):
            target = s["targets"].get(key)
            ver.append([key, "-" if target is None else f"{target:g}", _fmt(uni["worst"][key]["upper"], 5),
                        _fmt(mc["worst"][key]["upper"], 5)])
        doc.paragraph("Re-verified certified worst cases of the synthesized clearances (mm, deg):")
        doc.table(["quantity", "target", "uniform", "min-cost"], ver)
        binding = [k for k, t in s["targets"].items() if uni["worst"][k]["upper"] >= t * (1 - 2 * s["gap"])]
        looser = [b["source"] for a, b in zip(uni["sources"], mc["sources"]) if b["value"] > a["value"] * (1 + 1e-4)]
        tighter = [b["source"] for a, b in zip(uni["sources"], mc["sources"]) if b["value"] < a["value"] * (1 - 1e-4)]
        change = (f"loosens {', '.join(looser) or 'nothing'} and tightens {', '.join(tighter) or 'nothing'}"
                  if looser or tighter else "is the uniform one to 0.01 %")
        doc.paragraph(
            f"**Reading.** Uniform scaling allows {uni['scale']:.4f} times the template "
            f"({'binding: ' + ', '.join(binding) if binding else 'no target binding'}). The min-cost design "
            f"{change}, cost {mc['cost']:.4f} against "
            f"{len(uni['sources']) / uni['scale']:.4f} for the uniform one. Both are certified over the whole "
            f"region; with a {100 * s['gap']:g} % certificate they are conservative by at most that much.")
    # (d) -----------------------------------------------------------------------------------------------------
    st_rows = []
    for c, st in d["statistics"].items():
        q = st["pose"]["quantities"]["dp"]
        st_rows.append([c, _fmt(q["mean"]), _fmt(q["std"]), _fmt(q["rss"]),
                        f"{q['p95']:.4f} [{q['p95_lo']:.4f}, {q['p95_hi']:.4f}]",
                        f"{q['p99']:.4f} [{q['p99_lo']:.4f}, {q['p99_hi']:.4f}]",
                        f"{q['exceed']:.4f} +- {q['se_exceed']:.4f}", _fmt(q["worst"])])
    hp = next(iter(d["statistics"].values()))["pose"]["pose"]
    doc.paragraph(
        f"**(d) Statistics beside the worst case** at the home pose ({hp['x']:g}, {hp['y']:g}, "
        f"{hp['phi_deg']:g}): every clearance independent and uniform in its set, first-order model, "
        f"{s['pose_samples']} samples. |dp| in mm; percentiles with their 95 % interval, the exceedance "
        f"P(|dp| > {s['threshold_dp']:g} mm) with its standard error; `rss` is the analytic root mean square "
        "sqrt(var dx + var dy).")
    doc.table(["case", "mean |dp|", "std |dp|", "rss", "p95", "p99", f"P(|dp| > {s['threshold_dp']:g})",
               "worst case"], st_rows)
    last = d["statistics"][s["cases"][-1]]
    reg = next(iter(last["region"]["orientations"].values()))
    q2 = last["pose"]["quantities"]["dp"]
    typical = [st["pose"]["quantities"]["dp"]["mean"] / st["pose"]["quantities"]["dp"]["worst"]
               for st in d["statistics"].values()]
    doc.paragraph(
        f"**Reading.** The mean error is {min(typical):.2f}-{max(typical):.2f} times the worst case; 99 % of the "
        f"clearance states stay within {100 * q2['p99'] / q2['worst']:.0f} % of it ({s['cases'][-1]}). "
        "Over the phi = 0 workspace the 95th "
        f"percentile of |dp| is on average {reg['dp']['p95_over_max']:.2f} times the worst case, and at the home "
        f"pose {100 * q2['exceed']:.2f} % of the states exceed {s['threshold_dp']:g} mm. Designing to the worst "
        "case is therefore conservative for almost every clearance state; it is what a guarantee needs, while "
        "the percentiles tell how often a looser design would miss a specification.")
    if last.get("figure"):
        doc.figure(figure, f"{s['cases'][-1]}, phi = 0: 95th percentile of |dp| and |dphi| ({s['map_samples']} "
                           "samples per point), their worst case and the ratio.")
    # (e) -----------------------------------------------------------------------------------------------------
    if d["iso9283"]:
        iso = d["iso9283"]
        iso_rows = [[r["point"], f"({r['x_nom']:g}, {r['y_nom']:g})", r["n"], _fmt(r["ap_p"]), _fmt(r["rp_l"]),
                     f"{r['rp_l_model']:.4f} [{r['rp_l_model_lo']:.4f}, {r['rp_l_model_hi']:.4f}]",
                     _fmt(r["rp_phi_deg"]),
                     f"{r['rp_phi_model_deg']:.4f} [{r['rp_phi_model_lo_deg']:.4f}, {r['rp_phi_model_hi_deg']:.4f}]",
                     _fmt(r["dp_max"])] for r in iso["points"]]
        doc.paragraph(
            f"**(e) ISO 9283 pose accuracy and repeatability** from a virtual test (`experiment simulate --repeats "
            f"{s['iso']['cycles']}`): {len(iso['points'])} points at phi = 0, {s['iso']['cycles']} cycles each, "
            f"clearances {s['iso']['clearances']}, every cycle a fresh uniform clearance state, exact loop closure, "
            f"camera noise {s['iso']['noise_mm']:g} mm / {s['iso']['noise_deg']:g} deg. Beside the simulated test's AP_p (ISO "
            "9283: the offset of the barycentre of the attained positions) and RP the model's predicted RP (mean of 2000 simulated tests, with the 5-95 % range of one test), and the "
            "worst case dp_max. mm and deg.")
        doc.table(["point", "(x, y)", "cycles", "AP_p", "RP_l", "RP_l model [5-95 %]", "RP_phi", "RP_phi model [5-95 %]",
                   "dp_max"], iso_rows)
        ratio = np.mean([r["rp_l"] / r["rp_l_model"] for r in iso["points"]])
        rl = [r["rp_l"] / r["dp_max"] for r in iso["points"]]
        rphi = [r["rp_phi_deg"] / r["dphi_max_deg"] for r in iso["points"]]
        doc.paragraph(
            f"**Reading.** {100 * iso['share_rp_l_in_model_range']:.0f} % of the simulated RP_l lie in the model's "
            f"range for one test (mean ratio simulated / predicted {ratio:.2f}): "
            + ("the clearance model explains the scatter. " if iso["share_rp_l_in_model_range"] >= 0.6
               else "the scatter departs from the clearance model. ")
            + f"AP_p is only the barycentre's scatter: symmetric clearances cause no systematic offset. RP_l "
            f"is {min(rl):.2f}-{max(rl):.2f} times the worst case dp_max and RP_phi {min(rphi):.2f}-{max(rphi):.2f} "
            "times dphi_max: an ISO repeatability figure is of the order of the worst case but neither bounds it "
            "nor is bounded by it, since it counts the spread of random states (3 standard deviations), not the "
            "extreme configuration.")
