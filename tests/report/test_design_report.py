"""The report section "Design decisions" (issue 13, item 6): :mod:`pmaccuracy.report.design_report` in ``reproduce``.

The section's numbers are checked against direct calls of the functions it summarizes and against
independent computations written here:

* certified worst cases: the dense nonlinear search of ``nonlinear_search_reference.py`` (its own exact loop
  closure) never exceeds the certified bound; first-order values equal ``max_pose_errors``;
* global maxima: a brute-force grid over the region (``max_pose_errors`` at every pose in the workspace)
  never exceeds the certified maximum, which is never below the report's own grid maps;
* synthesis: the synthesized clearances, rebuilt here from the table, keep every pose of a brute-force grid
  within the targets; the uniform factor is ``min(target / certified max)`` of part (b)'s numbers;
* statistics: ``pose_statistics`` called directly; order of the percentiles and the worst case;
* ISO 9283: AP and RP recomputed here from the simulated repeated poses with the standard's formulas.

One reduced report (grid 11, no experiment) is built once for the module (about 10-15 s).
"""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

import nonlinear_search_reference as nsr
from pmaccuracy.accuracy import certified as C
from pmaccuracy.report import design_report as D
from pmaccuracy.experiment import iso9283
from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.model.clearances import ClearanceSet
from pmaccuracy.accuracy.distributions import pose_statistics
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.accuracy.global_worst import global_worst, make_region
from pmaccuracy.kinematics import inverse_kinematics
from pmaccuracy.report import reproduce
from pmaccuracy.model.sources import ErrorSources
from pmaccuracy.experiment.virtual_rig import grid_poses
from pmaccuracy.kinematics.workspace import constant_orientation_workspace

ROBOT = Manipulator.preset("aalborg_3ppr")
GRID = 11
SEED = 3
PNG = b"\x89PNG\r\n\x1a\n"
QKEYS = ("dx", "dy", "dphi_deg", "dp")
LIB = {"dx": "dx", "dy": "dy", "dphi_deg": "dphi", "dp": "dp"}


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("design")
    results = reproduce(out, grid=GRID, experiment=False, seed=SEED)
    return out, results, results["design_decisions"]


def _maxima(clearances, poses: np.ndarray) -> dict[str, np.ndarray]:
    b = max_pose_errors(ROBOT, clearances, poses, allow_outside=True)
    return {"dx": b.dx_max, "dy": b.dy_max, "dphi_deg": np.degrees(b.dphi_max), "dp": b.dp_max}


def _region_grid(n: int = 25, n_phi: int = 13) -> np.ndarray:
    """Poses of an n x n grid over each workspace's bounding box at n_phi orientations in [-30, 30] deg, kept
    where the inverse kinematics is within the joint ranges, plus every workspace corner."""
    out = []
    for phi in np.radians(np.linspace(-30.0, 30.0, n_phi)):
        ws = constant_orientation_workspace(ROBOT, float(phi))
        (x0, x1), (y0, y1) = ws.bounds
        X, Y = np.meshgrid(np.linspace(x0, x1, n), np.linspace(y0, y1, n))
        pts = np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, phi)])
        out += [pts[inverse_kinematics(ROBOT, pts).within_limits],
                np.column_stack([ws.vertices, np.full(len(ws.vertices), phi)])]
    return np.vstack(out)


# ----------------------------------------------------------------------------- files, keys, text
def test_results_json_has_the_section(report):
    out, results, d = report
    data = json.loads((out / "results.json").read_text())
    assert data["design_decisions"] == json.loads(json.dumps(d, allow_nan=False))
    assert set(d) == {"settings", "certified", "certified_errors", "global_worst", "synthesis", "statistics", "iso9283",
                      "certified_map",
                      "seconds"}
    assert set(d["global_worst"]) == set(d["statistics"]) == {"case1", "case2"}
    assert set(d["synthesis"]) == {"uniform", "min-cost"}
    assert len(d["certified"]) == 2 * 2 * 3  # cases x scales x poses
    assert d["settings"]["phi_range_deg"] == [-30.0, 30.0] and d["settings"]["targets"] == {"dp": 0.3,
                                                                                         "dphi_deg": 0.3}
    assert "design" in data and "case1" in data["design"]  # section 6 keeps its key
    assert d["seconds"] > 0


def test_report_text_and_figure(report):
    out, _, d = report
    md = (out / "report.md").read_text()
    assert "## 7. Design decisions: certified worst cases, global maxima, tolerance synthesis, statistics" in md
    assert md.index("## 6. Design comparison") < md.index("## 7. Design decisions")
    assert "design_percentiles.png" in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md)
    assert (out / "design_percentiles.png").read_bytes()[:8] == PNG
    assert d["statistics"]["case2"]["figure"].endswith("design_percentiles.png")
    for part in ("**(a)", "**(b)", "**(c)", "**(d)", "**(e)"):
        assert part in md, part
    # the section states its coarse settings
    assert "gap of 0.5 %" in md
    html = (out / "report.html").read_text()
    assert "Design decisions" in html


# ----------------------------------------------------------------------------- (a) certified
def test_certified_map_of_the_workspace(report):
    """The certified map of (a): the maps' orientations and grid, its numbers those of a direct one-pass
    ``certified_error_map`` beside the first-order ``error_map`` (never below it), checked at the grid point of
    largest |dp| against the independent dense nonlinear search, and its figure drawn and cited."""
    from pmaccuracy.accuracy.maps import certified_error_map, error_map

    out, results, d = report
    cm = d["certified_map"]
    phis = sorted(float(k) for k in results["cases"]["case1"])
    assert cm["case"] == "case2" and cm["grid"] == GRID and [float(k) for k in cm["layers"]] == phis
    cert = certified_error_map(ROBOT, "case2", np.radians(phis), n=GRID, split=0, max_pieces=1, refine=False)
    first = error_map(ROBOT, "case2", np.radians(phis), n=GRID)
    data = ROBOT.to_dict()
    cs = ClearanceSet.load("case2")  # the paper's Case 2 per joint: guide lateral, bearing angular, revolute radial
    spec = {"legs": [{"joints": [{"lateral": float(cs.guide_lateral[i]), "block_length": float(cs.guide_block_length[i])}
                                 if cs.guide_lateral[i] > 0 else {}, {"angular": float(cs.bearing_angle[i])},
                                 {"radial": float(cs.revolute_radial[i])}]} for i in range(3)]}
    for k, phi in enumerate(phis):
        layer = cm["layers"][f"{phi:g}"]
        inside = np.isfinite(first.dp_max.values[k])
        assert layer["points"] == int(inside.sum()) == layer["certified_points"]  # the paper's clearances: all
        c, f = cert.dp_max.values[k][inside], first.dp_max.values[k][inside]
        assert np.all(c >= f)
        assert layer["dp"]["certified"] == pytest.approx([c.min(), c.max()], rel=1e-12)
        assert layer["dp"]["excess"] == pytest.approx(np.max(c / f - 1), rel=1e-9)
        assert 0 <= layer["dp"]["gap"] <= 0.005
        iy, ix = np.unravel_index(np.nanargmax(np.where(inside, cert.dp_max.values[k], np.nan)), inside.shape)
        pose = [float(cert.x[ix]), float(cert.y[iy]), np.radians(phi)]
        ref = nsr.dense_search(data, pose, spec, n_random=200, dense=6)
        assert ref["dp"] <= cert.dp_max.values[k][iy, ix] <= ref["dp"] * 1.005
    md = (out / "report.md").read_text()
    assert "**(a') Certified maps.**" in md and "design_certified_map.png" in md
    assert (out / "design_certified_map.png").read_bytes()[:8] == PNG


def test_certified_rows_agree_with_direct_calls_and_invariants(report):
    _, _, d = report
    for case in ("case1", "case2"):
        for scale in (1.0, 10.0):
            rows = [r for r in d["certified"] if r["case"] == case and r["scale"] == scale]
            poses = np.array([[r["pose"]["x"], r["pose"]["y"], math.radians(r["pose"]["phi_deg"])] for r in rows])
            cs = ClearanceSet.load(case).scaled(scale)
            direct = C.certified_pose_errors(ROBOT, cs, poses, allow_outside=True, ascent=True)
            fo = _maxima(cs, poses)
            for k, r in enumerate(rows):
                assert r["reason"] == ""
                for q in QKEYS:
                    v = r["quantities"][q]
                    f = math.degrees if q == "dphi_deg" else float
                    assert v["certified"] == pytest.approx(f(direct.upper[LIB[q]][k]), rel=1e-12)
                    assert v["nonlinear"] == pytest.approx(f(direct.lower[LIB[q]][k]), rel=1e-12)
                    assert v["first_order"] == pytest.approx(fo[q][k], rel=1e-9)
                    assert v["certified"] >= v["nonlinear"] >= v["first_order"] * (1 - 1e-9), (case, scale, q)
                    assert v["gap"] == pytest.approx((v["certified"] - v["nonlinear"]) / v["nonlinear"], rel=1e-6)
            # the home pose first, then workspace corners
            assert rows[0]["label"] == "home" and rows[0]["pose"] == {"x": 0.0, "y": 0.0, "phi_deg": 0.0}


def test_certified_bound_above_independent_dense_search(report):
    """At the 10x case2 corner of the interval's ends the dense exact search never exceeds the bound."""
    _, _, d = report
    row = [r for r in d["certified"] if r["case"] == "case2" and r["scale"] == 10.0][-1]
    pose = np.array([row["pose"]["x"], row["pose"]["y"], math.radians(row["pose"]["phi_deg"])])
    cs = ClearanceSet.load("case2")
    spec = {"legs": [{"joints": [{}, {"angular": 10 * float(cs.bearing_angle[i])},
                                 {"radial": 10 * float(cs.revolute_radial[i])}]} for i in range(3)]}
    ref = nsr.dense_search(ROBOT.to_dict(), pose, spec, n_random=300, dense=8)
    for q in QKEYS:
        dense = math.degrees(ref[LIB[q]]) if q == "dphi_deg" else ref[LIB[q]]
        v = row["quantities"][q]
        assert v["certified"] >= dense, q
        assert (v["certified"] - dense) / dense < 0.02, q
        # the report's first-order value against the reference's finite differences
        fo = math.degrees(ref["first_order"][LIB[q]]) if q == "dphi_deg" else ref["first_order"][LIB[q]]
        assert v["first_order"] == pytest.approx(fo, rel=1e-6)


# ----------------------------------------------------------------------------- (b) global maxima
def test_global_maxima_agree_with_direct_call_grid_and_brute_force(report):
    _, results, d = report
    region = make_region(ROBOT, (math.radians(-30), math.radians(30)), None)
    poses = _region_grid()
    for case in ("case1", "case2"):
        gw = d["global_worst"][case]
        direct = global_worst(ROBOT, ClearanceSet.load(case), region, gap=D.GLOBAL_GAP)
        brute = _maxima(ClearanceSet.load(case), poses)
        for q in QKEYS:
            w = gw["quantities"][q]
            f = math.degrees if q == "dphi_deg" else float
            assert w["upper"] == pytest.approx(f(direct[LIB[q]].upper), rel=1e-12)
            assert w["lower"] == pytest.approx(f(direct[LIB[q]].lower), rel=1e-12)
            assert w["converged"] and w["lower"] <= w["upper"] <= w["lower"] * (1 + D.GLOBAL_GAP)
            # attained at the pose shown
            at = np.array([[w["x"], w["y"], math.radians(w["phi_deg"])]])
            assert _maxima(ClearanceSet.load(case), at)[q][0] == pytest.approx(w["lower"], rel=1e-9)
            # rigorous: no pose of a brute-force grid of the region above it
            assert brute[q].max() <= w["upper"] * (1 + 1e-9), (case, q)
            # the report's own grid maps: best value recomputed from results["cases"], below the certificate
            grid_best = max(cell[D.GRID_KEYS[LIB[q]]][1] for cell in results["cases"][case].values())
            assert w["grid_best"] == pytest.approx(grid_best, rel=1e-12)
            assert w["upper"] >= grid_best
        assert gw["grid_orientations_deg"] == [0.0, 30.0]


# ----------------------------------------------------------------------------- (c) synthesis
def _sources_from_rows(rows: list[dict]) -> ErrorSources:
    legs = [[{}, {}, {}] for _ in range(3)]
    for r in rows:
        m = re.fullmatch(r"legs\[(\d)\]\.joints\[(\d)\]\.(\w+)", r["source"])
        legs[int(m[1]) - 1][int(m[2]) - 1][m[3]] = r["value"]
    return ErrorSources.from_dict({"legs": [{"joints": j} for j in legs]})


def test_synthesis_meets_targets_and_matches_part_b(report):
    _, _, d = report
    targets = d["settings"]["targets"]
    poses = _region_grid(21, 9)
    gw1 = d["global_worst"]["case1"]["quantities"]
    uni = d["synthesis"]["uniform"]
    # uniform: one factor, the smallest target / certified maximum of the template (case1, part (b))
    assert uni["scale"] == pytest.approx(min(targets[q] / gw1[q]["upper"] for q in targets), rel=1e-9)
    for r in uni["sources"]:
        assert r["value"] == pytest.approx(r["template"] * uni["scale"], rel=1e-12)
        assert r["template"] == pytest.approx(float(ClearanceSet.load("case1").bearing_angle[0]))
    for mode in ("uniform", "min-cost"):
        syn = d["synthesis"][mode]
        cs = _sources_from_rows(syn["sources"])
        brute = _maxima(cs, poses)
        for q, target in targets.items():
            assert syn["worst"][q]["upper"] <= target * (1 + 1e-12), (mode, q)  # re-verified certificate
            assert brute[q].max() <= target * (1 + 1e-9), (mode, q)  # and a dense grid
        # a target binds: 1 % larger clearances break the certified targets' lower bounds
        assert max(syn["worst"][q]["lower"] * 1.01 / t for q, t in targets.items()) > 1, mode
    mc = d["synthesis"]["min-cost"]
    assert mc["cost"] == pytest.approx(sum(r["template"] / r["value"] for r in mc["sources"]), rel=1e-9)
    assert mc["cost"] <= len(uni["sources"]) / uni["scale"] * (1 + 1e-6)  # never costlier than uniform


def test_synthesis_agrees_with_direct_call(report):
    from pmaccuracy.accuracy.synthesis import parse_targets, synthesize

    _, _, d = report
    region = make_region(ROBOT, (math.radians(-30), math.radians(30)), None)
    for mode in ("uniform", "min-cost"):
        res = synthesize(ROBOT, region, parse_targets(D.TARGETS), mode=mode, gap=D.GLOBAL_GAP)
        got = [r["value"] for r in d["synthesis"][mode]["sources"]]
        np.testing.assert_allclose(got, res.values, rtol=1e-6)
        assert d["synthesis"][mode]["worst"]["dp"]["upper"] == pytest.approx(res.worst["dp"].upper, rel=1e-6)


# ----------------------------------------------------------------------------- (d) statistics
def test_statistics_agree_with_direct_call_and_invariants(report):
    _, _, d = report
    for case, st in d["statistics"].items():
        direct = pose_statistics(ROBOT, case, np.zeros(3), samples=D.POSE_SAMPLES, seed=SEED,
                                 thresholds={"dp": D.THRESHOLD_DP})
        q = st["pose"]["quantities"]["dp"]
        for key, value in direct.quantities["dp"].items():
            assert q[key] == pytest.approx(value, rel=1e-12), (case, key)
        assert q["worst"] == pytest.approx(float(max_pose_errors(ROBOT, ClearanceSet.load(case), np.zeros(3)).dp_max))
        assert q["mean"] <= q["rss"]  # E|dp| <= sqrt(E |dp|^2) (Jensen)
        assert q["p95_lo"] <= q["p95"] <= q["p95_hi"] <= q["p99_lo"] <= q["p99"] <= q["max_abs"] <= q["worst"]
        assert 0 < q["exceed"] < 1 and q["threshold"] == D.THRESHOLD_DP
        assert q["se_exceed"] == pytest.approx(math.sqrt(q["exceed"] * (1 - q["exceed"]) / D.POSE_SAMPLES))
        assert st["pose"]["samples"] == D.POSE_SAMPLES
    region = d["statistics"]["case2"]["region"]["orientations"]["0"]["dp"]
    assert 0 < region["p95_over_max"] < 1 and d["statistics"]["case2"]["region"]["samples"] == D.MAP_SAMPLES


# ----------------------------------------------------------------------------- (e) ISO 9283
def test_iso9283_recomputed_from_the_repeats(report):
    _, _, d = report
    iso = d["iso9283"]
    cs = ClearanceSet.load(D.ISO_CASE)
    nominal = grid_poses(ROBOT, 0.0, 3)[list(D.ISO_POINTS)]
    reps = iso9283.simulate_repeats(ROBOT, cs, nominal, D.ISO_CYCLES, noise_mm=D.ISO_NOISE_MM,
                                    noise_deg=D.ISO_NOISE_DEG, seed=np.random.default_rng((SEED, 9283)))
    assert len(iso["points"]) == 5 and iso["cycles"] == 30
    dp_max = _maxima(cs, nominal)["dp"]
    for k, r in enumerate(iso["points"]):
        a = reps.attained[k]  # (30, 3) mm, mm, rad
        assert a.shape == (30, 3) and [r["x_nom"], r["y_nom"]] == pytest.approx(nominal[k, :2].tolist())
        bx, by, bphi = a[:, 0].mean(), a[:, 1].mean(), a[:, 2].mean()
        assert r["ap_p"] == pytest.approx(math.hypot(bx - nominal[k, 0], by - nominal[k, 1]), rel=1e-9, abs=1e-12)
        assert r["ap_phi_deg"] == pytest.approx(math.degrees(bphi - nominal[k, 2]), rel=1e-9, abs=1e-12)
        l = np.hypot(a[:, 0] - bx, a[:, 1] - by)
        assert r["rp_l"] == pytest.approx(l.mean() + 3 * l.std(ddof=1), rel=1e-9)
        assert r["rp_phi_deg"] == pytest.approx(3 * math.degrees(a[:, 2].std(ddof=1)), rel=1e-9)
        assert r["rp_l_model_lo"] <= r["rp_l_model"] <= r["rp_l_model_hi"]
        assert r["dp_max"] == pytest.approx(dp_max[k], rel=1e-12)
    direct = iso9283.compare_repeatability(ROBOT, cs, reps, noise_mm=D.ISO_NOISE_MM, noise_deg=D.ISO_NOISE_DEG,
                                           seed=SEED)
    for got, ref in zip(iso["points"], direct["points"]):
        assert got["rp_l_model"] == pytest.approx(ref["rp_l_model"], rel=1e-12)
        assert got["rp_l"] == pytest.approx(ref["rp_l"], rel=1e-12)
