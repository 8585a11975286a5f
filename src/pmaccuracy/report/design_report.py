"""Report section "Design decisions": certified worst cases, global maxima, tolerance synthesis, statistics.

One section of ``pmaccuracy reproduce`` (:func:`pmaccuracy.report.reproduce`) that puts
side by side, for one robot, what a designer needs to fix clearances:

(a) **certified vs first-order vs best nonlinear** worst cases at a few poses (:func:`check_poses`: the home pose
    or the region's reference pose, and the worst corners or worst grid points of the region at phi = 0 and at
    the ends of the orientation interval) for the clearance cases ``case1`` and ``case2`` at 1x and 10x
    (:func:`pmaccuracy.accuracy.certified.certified_pose_errors`): ``first_order <= nonlinear <=
    max over the error set of the exact pose error <= certified``; the relative gap
    ``(certified - nonlinear) / nonlinear`` says how well the exact worst case is known; (a') the certified map
    over the region at the report's map orientations, its grid coarsened to a time budget
    (:func:`certified_map_job`);
(b) the **certified global maximum** of ``dx, dy, dphi, dp`` over the region (default the workspace) for
    ``phi`` in :data:`PHI_RANGE_DEG` (:func:`pmaccuracy.accuracy.global_worst.global_worst`, first-order
    model), with the attaining pose, against the largest value of the report's grid maps over the same region
    at their orientations inside the interval (:func:`grid_maxima`);
(c) **tolerance synthesis** for :data:`TARGETS` over the same region
    (:func:`pmaccuracy.accuracy.synthesis.synthesize`, uniform scaling and minimum reciprocal cost),
    re-verified by the global worst case;
(d) **statistics** at the home (or reference) pose and a percentile map over the region
    (:func:`pmaccuracy.report.statistics_report.statistics_section`);
(e) **ISO 9283** AP / RP of a virtual repeated-pose test (:func:`pmaccuracy.experiment.iso9283.simulate_repeats`,
    as ``experiment simulate --repeats``) beside the model's predicted RP
    (:func:`pmaccuracy.experiment.iso9283.compare_repeatability`).

The verdict at the top is computed from these tables (:func:`trust`), never written apart from them. A part
that cannot be computed (a singular region, a pose where the loops cannot close) becomes a box naming it and the
reason; the rest is still written. Every number shown is also stored, JSON-ready, in
``results["design_decisions"]``
(``results["design"]`` already holds section 6, the design comparison). Units: mm,
and degrees for every key ending in ``_deg``; the computations run in mm and rad.
The expensive parts run in the report's worker processes
(:meth:`pmaccuracy.report.figures.Renderer.compute`) while the certified table is computed.
"""

from __future__ import annotations

import math
import time
import warnings
from pathlib import Path

import numpy as np

from ..model.clearances import ClearanceSet
from .document import Document
from ..model.manipulator import Manipulator
from ..errors import EmptyWorkspaceError, PmAccuracyError
from ..io.resolve import load_clearances, robot_arg
from ..accuracy.bounds import max_pose_errors
from ..accuracy.certified import QUANTITIES, certified_pose_errors
from ..accuracy.distributions import pose_statistics
from ..accuracy.global_worst import global_worst, make_region
from ..accuracy.maps import certified_error_map, error_map
from ..accuracy.regions import Disc, Polygon, Rect
from ..accuracy.synthesis import default_template, parse_targets, synthesize
from ..experiment import iso9283
from ..experiment.virtual_rig import grid_poses
from ..kinematics import inverse_kinematics, regular_mask
from ..kinematics.workspace import constant_orientation_workspace
from .figures import plot_panels, render
from .sections import SECTION_ERRORS, SectionFailedWarning
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
#: Seconds the certified map of (a') may take: a pilot on a 7 x 7 grid measures the cost per grid point and the
#: grid is coarsened (never below :data:`CERT_MIN_GRID`) so that the map stays within this budget.
CERT_MAP_BUDGET_S = 8.0
CERT_MIN_GRID = 11
#: Grid of the first-order search for the poses of table (a) inside a region (per axis).
REGION_POSE_GRID = 21
#: Pieces the certificates of table (a) may cut the error set into (a pose whose commanded assembly does not
#: continue over the whole set is given up after this many, in about a second, instead of after 256).
TABLE_PIECES = 16
#: Cutting planes of the report's min-cost synthesis (each one more certified global worst case); the design is
#: certified and meets the targets after any number, fewer cuts leave it a little more conservative.
REPORT_MAX_CUTS = 3
#: Boxes the branch and bound of (b) may open (a region that reaches a singularity stops there, in a few seconds,
#: reported as not certified, instead of after the library's default budget).
REPORT_MAX_BOXES = 400_000
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


def as_shape(region) -> Disc | Polygon | Rect | None:
    """The design section's region as a shape of :mod:`pmaccuracy.accuracy.regions`: ``None`` (the workspace), a
    shape, or a box ``(x0, x1, y0, y1)`` mm (made a :class:`~pmaccuracy.accuracy.regions.Rect`)."""
    if region is None or isinstance(region, (Disc, Polygon, Rect)):
        return region
    x0, x1, y0, y1 = (float(v) for v in region)
    return Rect((x0, x1), (y0, y1))


def describe_region(region) -> str:
    """``"the workspace"`` or the shape's own description (mm)."""
    shape = as_shape(region)
    return "the workspace" if shape is None else shape.describe()


def _worst_grid_pose(robot: Manipulator, cs, phis_deg, shape, n: int = REGION_POSE_GRID) -> np.ndarray | None:
    """The well-conditioned grid point ``(3,)`` [mm, mm, rad] of largest first-order ``dp`` over ``shape`` at the
    orientations ``phis_deg`` (deg), on an ``n x n`` grid of its bounding box; ``None`` if no point qualifies."""
    best, pose = -np.inf, None
    for phi_deg in phis_deg:
        try:
            ds = error_map(robot, cs, np.radians([phi_deg]), n=n, region=shape, progress=False)
        except PmAccuracyError:         # no workspace inside the shape at this orientation
            continue
        X, Y = np.meshgrid(ds.x.values, ds.y.values)
        dp = ds.dp_max.values[0]
        ok = np.isfinite(dp)
        if not ok.any():
            continue
        pts = np.column_stack([X[ok], Y[ok], np.full(int(ok.sum()), math.radians(phi_deg))])
        vals = np.where(regular_mask(robot, pts, WELL_CONDITIONED), dp[ok], np.nan)
        if np.isfinite(vals).any() and np.nanmax(vals) > best:
            best, pose = float(np.nanmax(vals)), pts[int(np.nanargmax(vals))]
    return pose


def reference_pose(robot: Manipulator, region=None) -> tuple[np.ndarray, str]:
    """The pose ``(3,)`` [mm, mm, rad] where the section reports statistics, and its label: the home pose
    (:func:`home_pose`) when it lies in the region, else the well-conditioned point of the region at phi = 0
    nearest to the centre of the region's bounding box (on a :data:`REGION_POSE_GRID` grid)."""
    home = home_pose(robot)
    shape = as_shape(region)
    if shape is None or bool(shape.contains(home[0], home[1])):
        return home, "home"
    x0, x1, y0, y1 = shape.bounds
    x, y = np.linspace(x0, x1, REGION_POSE_GRID), np.linspace(y0, y1, REGION_POSE_GRID)
    X, Y = (a.ravel() for a in np.meshgrid(x, y))
    pts = np.column_stack([X, Y, np.zeros_like(X)])
    ok = np.asarray(shape.contains(X, Y)) & np.asarray(inverse_kinematics(robot, pts).within_limits) \
        & np.asarray(regular_mask(robot, pts, WELL_CONDITIONED))
    if not ok.any():
        raise EmptyWorkspaceError(f"{shape.describe()} holds no well-conditioned reachable pose at phi = 0")
    d = np.hypot(X - 0.5 * (x0 + x1), Y - 0.5 * (y0 + y1))
    k = int(np.argmin(np.where(ok, d, np.inf)))
    return pts[k], "centre of the region"


def check_poses(robot: Manipulator, case, phi_range_deg=PHI_RANGE_DEG, region=None) -> tuple[np.ndarray, list[str]]:
    """Poses ``(n <= 3, 3)`` [mm, mm, rad] of table (a) and their labels: the reference pose
    (:func:`reference_pose`) and, over the whole workspace, the corner of the phi = 0 workspace with the largest
    first-order ``dp`` and the corner of the workspaces at the ends of ``phi_range_deg`` with the largest one
    (for a 3-PPR at fixed phi every maximum is convex in the position, so these are the worst poses of those
    orientations); over a ``region`` (a shape or a box), the grid point of the region with the largest
    first-order ``dp`` at phi = 0 and at the ends of the interval (:func:`_worst_grid_pose`). Points farther from
    a singularity than :data:`WELL_CONDITIONED` allows are left out (a 3-RRR's workspace ends where a leg is
    stretched); the labels say which rows are present."""

    cs = load_clearances(case, robot)
    ref, ref_label = reference_pose(robot, region)
    poses, labels = [ref], [ref_label]
    lo, hi = phi_range_deg
    shape = as_shape(region)
    ends = (lo, hi) if lo != hi else (lo,)
    ends_text = " or ".join(f"{p:g}" for p in ends)
    groups = [((0.0,), "phi = 0")] if lo <= 0.0 <= hi else []
    groups.append((ends, f"phi = {ends_text}"))
    for phis, where in groups:
        if shape is not None:
            pose = _worst_grid_pose(robot, cs, phis, shape)
            if pose is not None:
                poses.append(pose)
                labels.append(f"worst point of the region, {where}")
            continue
        corners = np.vstack([np.column_stack([v, np.full(len(v), math.radians(p))])
                             for p in phis for v in [constant_orientation_workspace(robot, math.radians(p)).vertices]])
        dp = max_pose_errors(robot, cs, corners, allow_outside=True, singular="nan").dp_max
        dp = np.where(regular_mask(robot, corners, WELL_CONDITIONED), dp, np.nan)
        if np.isfinite(dp).any():           # corners at a singularity (a stretched leg) are left out
            poses.append(corners[int(np.nanargmax(dp))])
            labels.append(f"worst corner, {where}")
    return np.array(poses), labels


def grid_maxima(robot: Manipulator, case, phis_deg, grid: int, region=None) -> dict:
    """The largest first-order ``dx, dy, dphi_deg, dp`` (mm, deg) of the report's grid maps over ``region`` (the
    workspace when ``None``) at the orientations ``phis_deg`` (deg): the grid maxima that (b) compares with its
    certified values over the same region. ``{"orientations_deg": [...], "dx": max or None, ...}``."""
    out = {"orientations_deg": [float(p) for p in phis_deg]}
    out.update({KEYS[q]: None for q in GRID_KEYS})
    if not len(phis_deg):
        return out
    ds = error_map(robot, case, np.radians(np.asarray(phis_deg, dtype=float)), n=grid, region=as_shape(region),
                   progress=False)
    for q, var in (("dx", "dx_max"), ("dy", "dy_max"), ("dphi", "dphi_max"), ("dp", "dp_max")):
        v = ds[var].values
        out[KEYS[q]] = float(np.nanmax(v)) if np.isfinite(v).any() else None
    return out


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
                                  ascent=True, max_pieces=TABLE_PIECES)
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
    res = global_worst(robot, case, region, gap=gap, max_boxes=REPORT_MAX_BOXES)
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
                     template=template, max_cuts=REPORT_MAX_CUTS, max_boxes=REPORT_MAX_BOXES)
    worst = {KEYS[q]: {"lower": _deg(q, w.lower), "upper": _deg(q, w.upper), "x": float(w.pose[0]),
                       "y": float(w.pose[1]), "phi_deg": math.degrees(w.pose[2]), "converged": bool(w.converged)}
             for q, w in res.worst.quantities.items()}
    name = default_template(robot) if template is None else getattr(template, "name", str(template))
    return {"mode": mode, "template": name, "scale": res.scale, "cost": res.cost,
            "cuts": res.cuts, "sources": [{"source": s.label, "template": float(s.value), "value": float(v)}
                                          for s, v in zip(res.sources, res.values)],
            "worst": worst, "seconds": time.perf_counter() - t0}


def statistics_job(robot: Manipulator, case, pose: np.ndarray, grid: int | None, seed: int,
                   figure: str | Path | None, threshold_dp: float = THRESHOLD_DP, region=None) -> dict:
    """(d): :func:`pmaccuracy.report.statistics_report.statistics_section` of ``case`` at ``pose`` (threshold
    :data:`THRESHOLD_DP`) with a ``grid x grid`` percentile map at phi = 0 (written to ``figure``); with
    ``grid=None`` only the pose statistics (:func:`~pmaccuracy.accuracy.distributions.pose_statistics`, same
    settings): ``{"pose": ..., "threshold_dp": ...}``. ``region``: the map's shape or box (default the workspace)."""

    if grid is None:
        return {"pose": pose_statistics(robot, case, pose, samples=POSE_SAMPLES, seed=seed,
                                        thresholds={"dp": threshold_dp}).to_dict(), "threshold_dp": threshold_dp}
    return statistics_section(robot, case, 0.0, grid=grid, samples=MAP_SAMPLES, pose_samples=POSE_SAMPLES,
                              seed=seed, pose=pose, threshold_dp=threshold_dp, figure=figure,
                              region=as_shape(region))


def certified_grid(robot: Manipulator, case, phis: np.ndarray, grid: int, shape, budget_s: float = CERT_MAP_BUDGET_S
                   ) -> tuple[int, float]:
    """The grid per axis of the certified map of (a'), and the measured seconds per grid point: a pilot
    certified map on a 7 x 7 grid of the same region and orientations measures the cost; the report's ``grid``
    is kept if the whole map fits in ``budget_s`` seconds, else the largest grid that does (at least
    :data:`CERT_MIN_GRID`)."""
    t = time.perf_counter()
    certified_error_map(robot, case, phis, n=7, max_pieces=CERT_MAP_PIECES, split=0, refine=False, region=shape)
    per_point = (time.perf_counter() - t) / (49 * len(phis))
    fits = int(math.sqrt(budget_s / max(per_point * len(phis), 1e-12)))
    return max(min(grid, fits), min(grid, CERT_MIN_GRID)), per_point


def certified_map_job(robot: Manipulator, case, phis_deg: list[float], grid: int,
                      figure: str | Path | None, region=None, budget_s: float = CERT_MAP_BUDGET_S) -> dict:
    """(a') The certified map over ``region`` (a shape or box; the workspace when ``None``) at the report's map
    orientations ``phis_deg`` (deg) for the clearances ``case``: :func:`pmaccuracy.accuracy.maps.certified_error_map`
    (the default gap target, 0.5 %; the error set not cut, :data:`CERT_MAP_PIECES`) beside
    :func:`pmaccuracy.accuracy.maps.error_map` on the same grid: the report's map grid, coarsened by
    :func:`certified_grid` to stay within ``budget_s`` seconds. Per orientation: the certified ranges (mm, deg),
    the largest excess of the certified bound over the first-order maximum and the largest gap (relative), the
    grid points certified and inside the region, and the time taken (s); with ``figure`` the certified |dp| and its
    excess over first order are drawn there."""
    shape = as_shape(region)
    phis = np.radians(np.asarray(phis_deg, dtype=float))
    t = time.perf_counter()
    n, per_point = certified_grid(robot, case, phis, grid, shape, budget_s)
    cert = certified_error_map(robot, case, phis, n=n, max_pieces=CERT_MAP_PIECES, split=0, refine=False,
                               region=shape)
    seconds = time.perf_counter() - t
    first = error_map(robot, case, phis, n=n, region=shape)
    out = {"grid": int(n), "report_grid": int(grid), "seconds": seconds, "seconds_per_point": per_point,
           "budget_s": budget_s, "region": describe_region(shape),
           "clearances": first.attrs.get("clearances", ""), "layers": {}}
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
                          "first_order_max": float(np.nanmax(f[inside])) if inside.any() else None,
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
        render(figure, plot_panels, panels, ncols=2, shapes=[(robot, float(p)) for p in phis_deg for _ in range(2)],
               suptitle=f"{robot.name}, clearances {out['clearances']}: certified worst case of the exact model "
                        f"over {out['region']} ({n} x {n} grid)")
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
    shape = as_shape(region)
    ref, ref_label = reference_pose(robot, shape)
    # the exceedance threshold: the paper's 0.2 mm, or half the worst case of the last clearances at the pose
    threshold = THRESHOLD_DP if paper else round(0.5 * float(max_pose_errors(
        robot, cases[labels[-1]], ref, allow_outside=True).dp_max), 4)
    grid = int(min(results.get("grid", MAP_GRID), MAP_GRID))
    figure = out / "design_percentiles.png"
    # the report's map orientations: those of the certified map; the ones inside the interval give the grid maxima
    map_phis = sorted({float(k) for c in results.get("cases", {}).values() for k in c}) or [0.0]
    in_range = [p for p in map_phis if phi_range[0] - 1e-9 <= p <= phi_range[1] + 1e-9]
    # longest first: the workers may still be drawing the figures of the earlier sections
    jobs = {}
    if targets:
        jobs[("synthesis", "min-cost")] = renderer.compute(synthesis_job, robot, "min-cost", targets, phi_range,
                                                           GLOBAL_GAP, template, region)
    cert_figure = out / "design_certified_map.png"
    jobs[("certified_map", labels[-1])] = renderer.compute(certified_map_job, robot, cases[labels[-1]], map_phis,
                                                           int(min(results.get("grid", CERT_GRID), CERT_GRID)),
                                                           cert_figure, shape)
    jobs[("statistics", labels[-1])] = renderer.compute(statistics_job, robot, cases[labels[-1]], ref, grid, seed,
                                                         figure, threshold, shape)
    jobs.update({("global", c): renderer.compute(global_job, robot, cases[c], phi_range, GLOBAL_GAP, region)
                 for c in labels})
    if targets:
        jobs[("synthesis", "uniform")] = renderer.compute(synthesis_job, robot, "uniform", targets, phi_range,
                                                          GLOBAL_GAP, template, region)
    if iso:
        jobs[("iso", ISO_CASE)] = renderer.compute(iso_job, robot, seed)
    jobs.update({("statistics", c): renderer.compute(statistics_job, robot, cases[c], ref, None, seed, None,
                                                     threshold) for c in labels[:-1]})
    jobs.update({("grid", c): renderer.compute(grid_maxima, robot, cases[c], in_range, int(results.get("grid", 101)),
                                               shape) for c in labels})
    rows = []
    for label in labels:
        try:
            poses, pose_labels = check_poses(robot, cases[label], phi_range, shape)
            rows += certified_rows(robot, label, poses, pose_labels, scales, clearances=cases[label])
        except Exception as exc:   # noqa: BLE001 - a failing part becomes a box, the rest is still written
            rows.append({"case": label, "error": _reason(exc)})
    got = {}
    for key, job in jobs.items():
        t = time.perf_counter()
        try:
            got[key] = job.result()
        except Exception as exc:   # noqa: BLE001 - one part failing (a singular region...) is said, not fatal
            got[key] = {"error": _reason(exc)}
        got[key]["wait_s"] = time.perf_counter() - t
    data = {"settings": {"cases": labels, "scales": list(scales), "phi_range_deg": list(phi_range),
                         "gap": GLOBAL_GAP, "targets": dict(targets or {}), "threshold_dp": threshold,
                         "pose_samples": POSE_SAMPLES, "map_samples": MAP_SAMPLES, "map_grid": grid, "seed": seed,
                         "paper_cases": paper, "reference_pose": {"x": float(ref[0]), "y": float(ref[1]),
                                                                  "phi_deg": math.degrees(ref[2]),
                                                                  "label": ref_label},
                         "region": describe_region(shape) + " (within reach)",
                         "iso": {"clearances": ISO_CASE, "cycles": ISO_CYCLES, "noise_mm": ISO_NOISE_MM,
                                 "noise_deg": ISO_NOISE_DEG} if iso else None},
            "certified": [r for r in rows if "error" not in r],
            "certified_errors": {r["case"]: r["error"] for r in rows if "error" in r},
            "global_worst": {c: got[("global", c)] for c in labels},
            "synthesis": ({m: got[("synthesis", m)] for m in ("uniform", "min-cost")} if targets else None),
            "statistics": {c: got[("statistics", c)] for c in labels},
            "certified_map": {"case": labels[-1], **got[("certified_map", labels[-1])]},
            "iso9283": got[("iso", ISO_CASE)] if iso else None}
    for c, gw in data["global_worst"].items():
        if "error" in gw:
            continue
        grid_max = got[("grid", c)]
        for q in GRID_KEYS:
            gw["quantities"][KEYS[q]]["grid_best"] = grid_max.get(KEYS[q])
        gw["grid_orientations_deg"] = grid_max.get("orientations_deg", [])
        gw["grid_error"] = grid_max.get("error")
    data["seconds"] = time.perf_counter() - t0
    parts = {"synthesis": "(c) Tolerance synthesis", "statistics": "(d) Statistics", "global": "(b) Global maximum",
             "certified_map": "(a') Certified map", "iso": "(e) ISO 9283 test", "grid": "(b) grid maxima"}
    failed = [(f"{parts[k[0]]}, {k[1]}", v["error"]) for k, v in got.items() if "error" in v]
    failed += [(f"(a) Certified worst cases, {c}", e) for c, e in data["certified_errors"].items()]
    for part, reason in failed:   # one warning per part replaced by a box in the section
        warnings.warn(f"report part '{part}' of the design decisions could not be computed ({reason}); the report "
                      "was written with a box in its place", SectionFailedWarning, stacklevel=2)
    results.setdefault("failed_sections", []).extend({"section": f"Design decisions: {p}", "reason": r}
                                                      for p, r in failed)
    data = _ready(data)
    results["design_decisions"] = data
    _write(doc, robot, data, figure, cert_figure)
    return data


def _reason(exc: BaseException) -> str:
    """An error's message on one line (its type when it has none); an error that is not the library's or a
    numerical one is named an internal error (a defect to report)."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    if not isinstance(exc, SECTION_ERRORS):
        text = f"internal error ({type(exc).__name__}: {text}); please report it with the command line"
    return text


# ---------------------------------------------------------------------------------------------- text
def _fmt(v, digits: int = 4) -> str:
    return "-" if v is None else f"{v:.{digits}f}"


def _pct(v, digits: int = 3) -> str:
    """A ratio as a percentage without the sign (the column header says [%])."""
    return "-" if v is None else f"{100 * v:.{digits}f}"


def _pose(x: float, y: float, phi_deg: float) -> str:
    return f"({x:.4g}, {y:.4g}, {phi_deg:.3g})"


def span(values, digits: int = 2, sep: str = "-") -> str:
    """``"a-b"`` of the smallest and largest of ``values`` at ``digits`` decimals, or one value when both ends
    print the same.

    >>> span([0.2412, 0.2398]), span([0.1, 0.25])
    ('0.24', '0.10-0.25')
    """
    lo, hi = f"{min(values):.{digits}f}", f"{max(values):.{digits}f}"
    return lo if lo == hi else f"{lo}{sep}{hi}"


def trust(d: dict) -> dict:
    """How far the first-order model can be trusted at the section's clearances, from the section's own numbers:
    ``poses_excess`` the largest relative excess of the certified dp over first order at the poses of (a) (last
    case, first scale), ``map_excess`` the largest one over the certified map of (a') (which includes the bound's
    own gap), ``map_gap`` the certified map's largest gap; each ``None`` where not computed; ``usable`` when the
    largest of them is below 1 %."""
    s = d["settings"]
    last = s["cases"][-1]
    at1 = [r for r in d["certified"] if r["scale"] == s["scales"][0] and r["case"] == last
           and r["quantities"]["dp"]["certified"] is not None]
    poses = max(((r["quantities"]["dp"]["certified"] - r["quantities"]["dp"]["first_order"])
                 / r["quantities"]["dp"]["first_order"] for r in at1), default=None)
    cm = d.get("certified_map") or {}
    layers = [L for L in (cm.get("layers") or {}).values() if L["dp"]["excess"] is not None]
    excess = max((L["dp"]["excess"] for L in layers), default=None)
    gap = max((L[q]["gap"] for L in layers for q in ("dx", "dy", "dphi_deg", "dp")), default=None)
    known = [v for v in (poses, excess) if v is not None]
    return {"poses_excess": poses, "map_excess": excess, "map_gap": gap,
            "usable": bool(known) and max(known) < 0.01}


def _verdict(d: dict) -> str:
    """Three lines a designer reads first: the certified worst case, the targets, how far the maps can be
    trusted (every number from the section's own results: :func:`trust`, ``global_worst``, ``synthesis``)."""
    s = d["settings"]
    lo, hi = s["phi_range_deg"]
    last = s["cases"][-1]
    if "error" in d["global_worst"][last]:
        gw = None
        line1 = (f"**Verdict.** (1) With the clearances `{last}` the worst case over {s['region']} at phi in "
                 f"[{lo:g}, {hi:g}] deg could not be bounded: {d['global_worst'][last]['error']}")
    elif any(d["global_worst"][last]["quantities"][q]["upper"] is None for q in ("dp", "dphi_deg")):
        gw = d["global_worst"][last]["quantities"]
        dp = gw["dp"]
        line1 = (f"**Verdict.** (1) With the clearances `{last}` the worst case over {s['region']} at phi in "
                 f"[{lo:g}, {hi:g}] deg has no finite certified bound: the errors found reach dp = "
                 f"{dp['lower']:.4g} mm at {_pose(dp['x'], dp['y'], dp['phi_deg'])}, where the region comes "
                 "(nearly) to a singularity. Narrow the region (`--disc`, `--box`, `--polygon`, `--phi-range-deg`) "
                 "to certify the rest.")
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
    t = trust(d)
    said = []
    if t["poses_excess"] is not None:
        said.append(f"the exact model exceeds the first-order worst case by at most {_pct(t['poses_excess'], 2)} % "
                    "at the poses of (a)")
    if t["map_excess"] is not None:
        said.append(f"over the certified map of {s['region']} the certified bound lies at most "
                    f"{_pct(t['map_excess'], 2)} % above first order (the exact excess plus the bound's own gap, up "
                    f"to {_pct(t['map_gap'], 2)} %)")
    if not said:
        line3 = " (3) The exact model could not be certified at these clearances: see the reasons in (a)."
    else:
        line3 = (" (3) At these clearances " + "; ".join(said)
                 + (": the first-order maps can be used as they are." if t["usable"] else
                    ": where that matters, use the certified values rather than the first-order maps."))
    return line1 + line2 + line3


def _poses_text(d: dict) -> str:
    """Which poses table (a) holds, from the labels of its rows."""
    labels = list(dict.fromkeys(r["label"] for r in d["certified"]))
    ref = d["settings"]["reference_pose"]
    where = "the home pose" if ref["label"] == "home" else \
        f"the well-conditioned point nearest to the region's centre ({ref['x']:.4g}, {ref['y']:.4g})"
    others = [lab for lab in labels if lab not in ("home", "centre of the region")]
    text = f"Poses: {where}" + (", " + ", ".join(f"the {lab}" for lab in others) if others else "")
    left = 3 - len(labels)
    if left > 0:
        text += (f" ({left} more {'pose was' if left == 1 else 'poses were'} left out: the worst candidates lie "
                 f"within a condition number of {WELL_CONDITIONED:g} of a singularity, where the linear model "
                 "no longer describes the robot)")
    return text + " (first-order dp decides which is worst)."


def _write_certified(doc: Document, d: dict) -> None:
    """(a): the certified worst cases at the poses of :func:`check_poses` and their reading."""
    s = d["settings"]
    doc.paragraph(
        "**(a) Certified worst cases of the exact model.** The maps use the paper's first-order model. The exact "
        "loop closure differs by the Taylor remainder: `nonlinear` is the largest error of a feasible clearance "
        "configuration (attained, a lower bound of the exact worst case), `certified` a rigorous upper bound of "
        f"it (`pmaccuracy bounds --certified`), `gap` their relative difference. {_poses_text(d)} Values in mm "
        "and deg.")
    rows = []
    for r in d["certified"]:
        p = r["pose"]
        dp, dphi = r["quantities"]["dp"], r["quantities"]["dphi_deg"]
        fo = dp["first_order"]
        excess = None if dp["certified"] is None else (dp["certified"] - fo) / fo
        rows.append([r["case"], f"{r['scale']:g}x", r["label"], _pose(p["x"], p["y"], p["phi_deg"]),
                     _fmt(fo, 5), _fmt(dp["nonlinear"], 5), _fmt(dp["certified"], 5), _pct(dp["gap"]),
                     _pct(excess), _fmt(dphi["first_order"], 5), _fmt(dphi["certified"], 5),
                     _pct(dphi["gap"])])
    doc.table(["case", "clearances", "pose", "(x, y, phi)", "dp first-order", "dp nonlinear", "dp certified",
               "dp gap [%]", "certified above first-order [%]", "dphi first-order", "dphi certified",
               "dphi gap [%]"], rows)
    ex, gaps = {}, {}
    for sc in s["scales"]:
        at = [r for r in d["certified"] if r["scale"] == sc and r["quantities"]["dp"]["certified"] is not None]
        ex[sc] = max(((r["quantities"]["dp"]["certified"] - r["quantities"]["dp"]["first_order"])
                      / r["quantities"]["dp"]["first_order"] for r in at), default=None)
        gaps[sc] = max((r["quantities"][q]["gap"] for r in at for q in ("dp", "dphi_deg")
                        if r["quantities"][q]["gap"] is not None), default=None)
    sc0, sc1 = s["scales"][0], s["scales"][-1]
    if ex[sc0] is None or ex[sc1] is None:
        doc.paragraph("**Reading.** Some poses could not be certified (the table shows `-`): see the reasons in "
                      "`results.json` (`design_decisions.certified[].reason`).")
        return
    clearances = "the paper" + chr(39) + "s" if s["paper_cases"] else "the given"
    doc.paragraph(
        f"**Reading.** At {clearances} clearances the exact worst case of dp exceeds the first-order one by at "
        f"most {_pct(ex[sc0])} % at these poses and dp, dphi are known to {_pct(gaps[sc0])} %"
        + (": the first-order values can be used as they are there." if ex[sc0] < 0.01 else
           ": use the certified values.")
        + f" At {sc1:g}x the clearances the excess reaches {_pct(ex[sc1], 2)} % (the remainder grows with the "
        f"square of the clearances) and the gap {_pct(gaps[sc1], 2)} %: add that margin to a first-order budget "
        "for loose joints, or use the certified value.")


def _write_certified_map(doc: Document, d: dict, cert_figure: Path | None) -> None:
    """(a'): the certified map over the region, with its figure."""
    s, cm = d["settings"], d["certified_map"]
    parts = []
    for phi, L in cm["layers"].items():
        if L["dp"]["certified"] is None:
            parts.append(f"at phi = {phi} deg no grid point of the region is certified")
            continue
        parts.append(f"at phi = {phi} deg dp up to {_fmt(L['dp']['certified'][1])} mm and dphi up to "
                     f"{_fmt(L['dphi_deg']['certified'][1])} deg, at most {_pct(L['dp']['excess'], 2)} % "
                     f"(dp) above the first-order maximum, largest gap "
                     f"{_pct(max(L[q]['gap'] for q in ('dx', 'dy', 'dphi_deg', 'dp')), 2)} %, "
                     f"{L['certified_points']} of {L['points']} grid points certified")
    coarse = (f", coarsened from the maps' {cm['report_grid']} x {cm['report_grid']} to stay within about "
              f"{cm['budget_s']:g} s (`pmaccuracy map --certified --grid N` for a finer one)"
              if cm["grid"] < cm["report_grid"] else "")
    doc.paragraph(
        f"**(a') Certified maps.** The same bounds over {cm['region']} ({cm['case']}, a {cm['grid']} x "
        f"{cm['grid']} grid{coarse}; {cm['seconds']:.1f} s): " + "; ".join(parts)
        + ". The excess over first order includes the bound's own gap; it is largest near a singular edge, where "
          "the linear model no longer describes the robot. A grid point not certified is left blank (NaN), never "
          "filled with a guess.")
    if cm.get("figure") and cert_figure is not None:
        doc.figure(cert_figure, f"{cm['case']}: certified upper bound of the exact worst-case |dp| over "
                                f"{cm['region']} (left) and how far it lies above the first-order maximum (right, "
                                "%): the exact model's excess plus the bound's own gap (refined only to 0.1 %, "
                                "hence the bands).")


def _write_global(doc: Document, d: dict, ok: dict) -> None:
    """(b): the certified global maxima over the region, beside the grid maxima over the same region."""
    s = d["settings"]
    lo, hi = s["phi_range_deg"]
    gw_rows = []
    for c, gw in ok.items():
        for key, w in gw["quantities"].items():
            best = w.get("grid_best")
            miss = None if best is None or not w["lower"] else (w["lower"] - best) / w["lower"]
            gw_rows.append([c, key, _fmt(w["lower"], 5), _fmt(w["upper"], 5), _pct(w["gap"], 2),
                            _pose(w["x"], w["y"], w["phi_deg"]), _fmt(best, 5),
                            "-" if miss is None else f"{round(100 * miss, 2) + 0.0:.2f}",
                            "yes" if w["converged"] else "no"])
    orients = next(iter(ok.values())).get("grid_orientations_deg") or []
    orient = ", ".join(f"{p:g}" for p in orients)
    grid_note = (f"The report's maps sample the same region on a grid at phi = {orient} deg only; `grid max` is "
                 "their largest value there and the next column how far it lies below the attained maximum "
                 "(negative: the grid found a larger value than the search's attained one, still below the "
                 "certified max)." if orients else
                 "No orientation of the report's maps lies in the interval, so there is no grid value to compare.")
    doc.paragraph(
        f"**(b) Global maximum over {s['region']} for phi in [{lo:g}, {hi:g}] deg** (`pmaccuracy worst`, "
        "first-order model): `attained` is the value at the pose shown, `certified max` a rigorous bound over "
        "every reachable pose of the region (branch and bound with interval arithmetic), `gap` their relative "
        f"difference. {grid_note}")
    doc.table(["case", "quantity", "attained", "certified max", "gap [%]", "at (x, y, phi)", "grid max",
               "grid max below attained [%]", "certified"], gw_rows)
    ws = [w for gw in ok.values() for w in gw["quantities"].values()]
    misses = [(w["lower"] - w["grid_best"]) / w["lower"] for w in ws if w.get("grid_best") is not None
              and w["lower"]]
    gaps = [w["gap"] for w in ws if w["gap"] is not None]
    at_end = sum(min(abs(w["phi_deg"] - lo), abs(w["phi_deg"] - hi)) < 1e-6 for w in ws)
    phis = ", ".join(f"{p:.3g}" for p in sorted({round(w["phi_deg"], 6) + 0.0 for w in ws}))
    if misses and max(misses) < 1e-3:
        grid_text = (f"the maps' grid at phi = {orient} deg already comes within "
                     f"{_pct(max(max(misses), 0.0), 2)} % of every maximum over the region")
    elif misses:
        grid_text = (f"the maps' grid at phi = {orient} deg underestimates a maximum over the region by up to "
                     f"{_pct(max(misses), 1)} %")
    else:
        grid_text = "the maps give no grid value to compare"
    unbounded = [w for w in ws if w["upper"] is None or w["gap"] is None]
    guarantee = (f"What the certificate adds is the guarantee: no pose of the region, at any orientation in between, "
                 f"is worse than `certified max`, at most {_pct(max(gaps), 2)} % above the attained value. That is "
                 "the number to compare with a specification over the whole task space."
                 if not unbounded else
                 f"{len(unbounded)} of {len(ws)} maxima have no finite certified bound (`-`): the region reaches a "
                 "singularity, where the errors are unbounded; cut the region away from it (`--disc`, `--box`, "
                 "`--polygon`) to certify the rest.")
    doc.paragraph(
        f"**Reading.** The maxima are attained at phi = {phis} deg ({at_end} of {len(ws)} at an end of the "
        f"interval); {grid_text}. {guarantee}")


def _write(doc: Document, robot: Manipulator, d: dict, figure: Path, cert_figure: Path | None = None) -> None:
    s = d["settings"]
    lo, hi = s["phi_range_deg"]
    doc.heading("Design decisions: certified worst cases, global maxima, tolerance synthesis, statistics")
    doc.paragraph(_verdict(d))
    doc.paragraph(
        f"What a designer of `{robot.name}` needs to fix the clearances over {s['region']}: how much the "
        "first-order worst case can be trusted, the certified worst case over the region, the largest clearances "
        "meeting a target, and how often the errors come near the worst case. Settings (coarse, for run time): "
        f"global maxima and synthesis certified to a gap of {100 * s['gap']:g} %, {s['pose_samples']} samples at "
        f"the pose, a {s['map_grid']} x {s['map_grid']} percentile map of {s['map_samples']} samples, seed "
        f"{s['seed']}. This section took {d['seconds']:.1f} s.")
    # (a) -----------------------------------------------------------------------------------------------------
    for case, reason in (d.get("certified_errors") or {}).items():
        doc.failure(f"(a) Certified worst cases, clearances {case}", reason)
    if d["certified"]:
        _write_certified(doc, d)
    cm = d.get("certified_map")
    if cm and "error" in cm:
        doc.failure(f"(a') Certified map over {s['region']}", cm["error"])
    elif cm:
        _write_certified_map(doc, d, cert_figure)
    # (b) -----------------------------------------------------------------------------------------------------
    ok = {c: gw for c, gw in d["global_worst"].items() if "error" not in gw}
    for c, gw in d["global_worst"].items():
        if "error" in gw:
            doc.failure(f"(b) Global maximum over {s['region']} for phi in [{lo:g}, {hi:g}] deg, clearances {c}",
                        gw["error"])
    if ok:
        _write_global(doc, d, ok)
    # (c) -----------------------------------------------------------------------------------------------------
    errors = [v["error"] for v in (d["synthesis"] or {}).values() if "error" in v]
    if errors:
        doc.failure("(c) Tolerance synthesis", errors[0])
    if d["synthesis"] and not errors:
        syn = d["synthesis"]
        uni, mc = syn["uniform"], syn["min-cost"]
        tgt = ", ".join(f"{k} = {v:g} {'deg' if k.endswith('_deg') else 'mm'}" for k, v in s["targets"].items())
        doc.paragraph(
            f"**(c) Tolerance synthesis** (`pmaccuracy synthesize`): the largest clearances of the template "
            f"`{uni['template']}` (its non-zero sources) that keep the certified worst case within {tgt} everywhere in {s['region']} for phi in "
            f"[{lo:g}, {hi:g}] deg. Uniform: the template times one factor; min-cost: per joint, minimizing "
            f"sum eps0 / eps (halving a clearance doubles its cost), equal weights, {mc['cuts']} cutting plane(s) "
            f"(the report stops at {REPORT_MAX_CUTS}; `pmaccuracy synthesize --mode min-cost` goes on: the design "
            "is certified either way, fewer cuts leave it more conservative). Values in mm or rad by the source.")
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
    stats = {c: st for c, st in d["statistics"].items() if "error" not in st}
    for c, st in d["statistics"].items():
        if "error" in st:
            doc.failure(f"(d) Statistics, clearances {c}", st["error"])
    last = stats.get(s["cases"][-1])
    if stats:
        st_rows = []
        for c, st in stats.items():
            q = st["pose"]["quantities"]["dp"]
            st_rows.append([c, _fmt(q["mean"]), _fmt(q["std"]), _fmt(q["rss"]),
                            f"{q['p95']:.4f} [{q['p95_lo']:.4f}, {q['p95_hi']:.4f}]",
                            f"{q['p99']:.4f} [{q['p99_lo']:.4f}, {q['p99_hi']:.4f}]",
                            f"{q['exceed']:.4f} +- {q['se_exceed']:.4f}", _fmt(q["worst"])])
        hp = next(iter(stats.values()))["pose"]["pose"]
        where = "the home pose" if s["reference_pose"]["label"] == "home" else "the region's reference pose"
        doc.paragraph(
            f"**(d) Statistics beside the worst case** at {where} ({hp['x']:.4g}, {hp['y']:.4g}, "
            f"{hp['phi_deg']:g}): every clearance independent and uniform in its set, first-order model, "
            f"{s['pose_samples']} samples. |dp| in mm; percentiles with their 95 % interval, the exceedance "
            f"P(|dp| > {s['threshold_dp']:g} mm) with its standard error; `rss` is the analytic root mean square "
            "sqrt(var dx + var dy).")
        doc.table(["case", "mean |dp|", "std |dp|", "rss", "p95", "p99", f"P(|dp| > {s['threshold_dp']:g})",
                   "worst case"], st_rows)
    if last is not None:
        reg = next(iter(last["region"]["orientations"].values()))
        q2 = last["pose"]["quantities"]["dp"]
        typical = [st["pose"]["quantities"]["dp"]["mean"] / st["pose"]["quantities"]["dp"]["worst"]
                   for st in stats.values()]
        doc.paragraph(
            f"**Reading.** The mean error is {span(typical)} times the worst case; 99 % of the "
            f"clearance states stay within {100 * q2['p99'] / q2['worst']:.0f} % of it ({s['cases'][-1]}). "
            f"Over {s['region']} at phi = 0 the 95th percentile of |dp| is on average "
            f"{reg['dp']['p95_over_max']:.2f} times the worst case, and at the pose above "
            f"{100 * q2['exceed']:.2f} % of the states exceed {s['threshold_dp']:g} mm. Designing to the worst "
            "case is therefore conservative for almost every clearance state; it is what a guarantee needs, while "
            "the percentiles tell how often a looser design would miss a specification.")
        if last.get("figure"):
            doc.figure(figure, f"{s['cases'][-1]}, phi = 0, over {s['region']}: 95th percentile of |dp| and "
                               f"|dphi| ({s['map_samples']} samples per point), their worst case and the ratio.")
    # (e) -----------------------------------------------------------------------------------------------------
    if d["iso9283"] and "error" in d["iso9283"]:
        doc.failure("(e) ISO 9283 pose accuracy and repeatability", d["iso9283"]["error"])
    elif d["iso9283"]:
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
            f"is {span(rl)} times the worst case dp_max and RP_phi {span(rphi)} "
            "times dphi_max: an ISO repeatability figure is of the order of the worst case but neither bounds it "
            "nor is bounded by it, since it counts the spread of random states (3 standard deviations), not the "
            "extreme configuration.")
