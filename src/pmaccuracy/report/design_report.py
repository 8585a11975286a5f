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
from .design_text import span, trust, write  # noqa: F401 - span and trust are part of this module's face
from .sections import SectionFailedWarning, reason_of
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
            rows.append({"case": label, "error": reason_of(exc)})
    got = {}
    for key, job in jobs.items():
        t = time.perf_counter()
        try:
            got[key] = job.result()
        except Exception as exc:   # noqa: BLE001 - one part failing (a singular region...) is said, not fatal
            got[key] = {"error": reason_of(exc)}
        got[key]["wait_s"] = time.perf_counter() - t
    data = {"settings": {"cases": labels, "scales": list(scales), "phi_range_deg": list(phi_range),
                         "gap": GLOBAL_GAP, "targets": dict(targets or {}), "threshold_dp": threshold,
                         "pose_samples": POSE_SAMPLES, "map_samples": MAP_SAMPLES, "map_grid": grid, "seed": seed,
                         "paper_cases": paper, "well_conditioned": WELL_CONDITIONED, "max_cuts": REPORT_MAX_CUTS,
                         "reference_pose": {"x": float(ref[0]), "y": float(ref[1]),
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
    write(doc, robot, data, figure, cert_figure)
    return data
