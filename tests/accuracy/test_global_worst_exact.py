"""The exact model's certified worst case over a region (``global_worst(..., exact=True)``, ``worst --certified``)
against the independent dense search (``nonlinear_search_reference``, its own exact closure) at poses of the
region: the region's upper bound is never below the exact worst case the search attains at any pose of it, the
lower bound is attained (at most the per-pose certified bound at its pose) and the gap is as reported."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import error_reference as eref
import nonlinear_search_reference as nsr
import planar_reference as pref
from test_global_worst import run  # the CLI in-process: (status, stdout, stderr)
from pmaccuracy.accuracy import certified as C
from pmaccuracy.accuracy.global_worst import global_worst, make_region
from pmaccuracy.accuracy.regions import Rect
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.model.sources import ErrorSources

GENERATORS = {"3-RPR": pref.random_rpr, "3-RRR": pref.random_rrr, "3-PRR": pref.random_prr}


def _case(kind: str, factor: float, seed: int = 1):
    rng = np.random.default_rng(seed)
    data, nominal = GENERATORS[kind](rng)
    robot = Manipulator.from_dict(data, source="random")
    clear, _ = eref.random_clearances(rng, eref.load_robot(data))
    spec = nsr.scaled_spec(clear, factor)
    return data, robot, np.asarray(nominal, dtype=float), spec


#: Each case takes 2-7 s (the dense search at five to seven poses): one in ``make test``, all in ``make test-all``.
@pytest.mark.parametrize("kind,factor", [pytest.param("3-RPR", 1, marks=pytest.mark.slow),
                                         pytest.param("3-RRR", 1, marks=pytest.mark.slow), ("3-RRR", 10),
                                         pytest.param("3-PRR", 10, marks=pytest.mark.slow)])
def test_region_bound_never_below_the_dense_search(kind, factor):
    data, robot, nominal, spec = _case(kind, factor)
    sources = ErrorSources.from_dict(spec)
    h, dphi = 3.0, np.radians(1.0)
    region = make_region(robot, (nominal[2] - dphi, nominal[2] + dphi),
                         Rect((nominal[0] - h, nominal[0] + h), (nominal[1] - h, nominal[1] + h)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = global_worst(robot, sources, region, exact=True, gap=0.02 if factor == 1 else 0.1)
        fo = global_worst(robot, sources, region)
    # poses of the region: its corners at both end angles, its centre and the poses the certificate names
    rng = np.random.default_rng(7)
    corners = np.array([[nominal[0] + sx * h, nominal[1] + sy * h, nominal[2] + sp * dphi]
                        for sx in (-1, 1) for sy in (-1, 1) for sp in (-1, 1)])
    picks = corners[rng.choice(8, 2, replace=False)]
    poses = np.unique(np.vstack([picks, nominal, *[res[q].pose for q in C.QUANTITIES]]), axis=0)
    found = {q: 0.0 for q in C.QUANTITIES}
    for pose in poses:
        ref = nsr.dense_search(data, pose, spec, n_random=100, dense=4)
        for q in C.QUANTITIES:
            found[q] = max(found[q], ref[q])
    for q in C.QUANTITIES:
        w = res[q]
        assert w.upper >= found[q], (kind, factor, q, w.upper, found[q])
        assert w.lower <= w.upper and w.gap == pytest.approx((w.upper - w.lower) / w.lower)
        assert not w.converged or w.gap <= res.target_gap + 1e-12
        # the exact model's worst case differs from the first-order one by its nonlinear part only
        assert abs(w.upper / fo[q].upper - 1) < (0.03 if factor == 1 else 0.3)
    # the lower bounds are attained: never above the per-pose certified bound at their poses
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        at = C.certified_pose_errors(robot, sources, np.array([res[q].pose for q in C.QUANTITIES]), on_failure="nan",
                                     split_gap=0.05, max_pieces=16)
    for i, q in enumerate(C.QUANTITIES):
        if np.isfinite(at.upper[q][i]):
            assert res[q].lower <= at.upper[q][i] * (1 + 1e-9)


def test_default_robot_exact_worst_case_of_the_workspace():
    """Case 2 over the whole workspace at phi = 0: certified within the default 1 %, above the first-order
    worst case by its nonlinear part, and above the per-pose certified bound at the first-order worst pose (the
    region's maximum holds for every pose of it)."""
    robot = Manipulator.preset("aalborg_3ppr")
    from pmaccuracy.model.clearances import ClearanceSet

    case = ClearanceSet.preset("case2")
    region = make_region(robot, (0.0, 0.0), None)
    res = global_worst(robot, case, region, exact=True)
    fo = global_worst(robot, case, region)
    at = C.certified_pose_errors(robot, case, np.array([fo[q].pose for q in C.QUANTITIES]))
    for i, q in enumerate(C.QUANTITIES):
        assert res[q].converged and res[q].gap <= 0.01
        assert res[q].upper >= at.upper[q][i] * (1 - 1e-12)
        assert res[q].upper >= fo[q].lower
        assert res[q].lower >= fo[q].lower * (1 - 1e-3)   # the exact worst case is a little above first order
    assert res.exact and not fo.exact


def test_cli_worst_certified(capsys):
    """``worst --certified`` prints the exact model's certified worst case: every upper bound at least the
    per-pose certified bound at the first-order worst pose the plain ``worst`` reports (an independent path)."""
    import json

    argv = ["worst", "--phi-deg", "0", "0", "--clearances", "case2", "--grid", "21", "3", "--format", "json"]
    status, out, err = run(argv + ["--certified"], capsys)
    assert status == 0, err
    data = json.loads(out)
    assert data["model"] == "exact" and data["target_gap_pct"] == 1.0
    status, out, _ = run(argv, capsys)
    first = json.loads(out)
    assert first["model"] == "first-order" and first["target_gap_pct"] == 0.1
    poses = np.array([[r["x"], r["y"], np.radians(r["phi_deg"])] for r in first["quantities"]])
    at = C.certified_pose_errors(Manipulator.preset("aalborg_3ppr"), "case2", poses)
    for i, (rec, q) in enumerate(zip(data["quantities"], C.QUANTITIES)):
        k = np.degrees(1.0) if q == "dphi" else 1.0
        assert rec["certified"] and rec["gap_pct"] <= 1.0
        assert rec["upper"] >= at.upper[q][i] * k * (1 - 1e-12)
        assert rec["lower"] <= rec["upper"]


@pytest.mark.parametrize("extra,key", [(["--gap-pct", "0"], "--gap-pct"),
                                       (["--largest-disc", "0", "0", "--target", "dp=0.3"], "--certified")])
def test_cli_worst_certified_bad_options(capsys, extra, key):
    status, out, err = run(["worst", "--phi-deg", "0", "0", "--certified"] + extra, capsys)
    assert status == 2 and not out
    assert len(err.strip().splitlines()) == 1 and key in err and "Traceback" not in err


def _small_box(kind, factor, h=0.05, dphi_deg=0.02):
    from pmaccuracy.accuracy.certified.error_set import error_set
    from pmaccuracy.accuracy.certified.region import box_remainder
    from pmaccuracy.accuracy.global_worst import leg_branches
    from pmaccuracy.accuracy.interval import box_bounds

    data, robot, nominal, spec = _case(kind, factor)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sources = ErrorSources.from_dict(spec)
    dphi = np.radians(dphi_deg)
    box = np.array([[nominal[0] - h, nominal[0] + h, nominal[1] - h, nominal[1] + h,
                     nominal[2] - dphi, nominal[2] + dphi]])
    sigmas = leg_branches(robot, nominal)
    rem, total = box_remainder(robot, error_set(robot, sources), box, sigmas, tight=True)
    first = box_bounds(robot, sources, box, sigmas)[0]
    assert np.all(np.isfinite(total)) and np.all(np.isfinite(rem))
    return data, robot, sources, spec, nominal, h, dphi, first[0] + rem[0], total[0]


@pytest.mark.parametrize("kind", [pytest.param("3-RPR", marks=pytest.mark.slow), "3-RRR",
                                  pytest.param("3-PRR", marks=pytest.mark.slow)])
def test_box_bounds_never_below_the_dense_search_at_10x(kind):
    """Over a small box (0.1 mm x 0.04 deg) at 10x the clearances (up to 15 % nonlinear) both bounds of the exact
    maxima (first order + remainder; second-order model, ``box_remainder(..., tight=True)``) are never below
    the dense search at the box's centre and a corner."""
    data, robot, sources, spec, nominal, h, dphi, plain, second = _small_box(kind, 10)
    for pose in (nominal, nominal + np.array([h, -h, dphi])):
        ref = nsr.dense_search(data, pose, spec, n_random=100, dense=4)
        for i, q in enumerate(C.QUANTITIES):
            assert second[i] >= ref[q], (kind, q, second[i], ref[q])
            assert plain[i] >= ref[q], (kind, q, plain[i], ref[q])


@pytest.mark.parametrize("kind", ["3-RPR", "3-RRR", "3-PRR"])
def test_second_order_box_bound_is_tight_at_1x(kind):
    """At 1x the second-order bound over a box of 0.01 mm x 0.004 deg is within 0.5 % of the per-pose certificate
    of the whole error set at its centre (so the region's gap can close), and above the best feasible value there
    (the part proportional to the box's size is 0.7-0.9 % at ten times that box)."""
    data, robot, sources, spec, nominal, h, dphi, plain, second = _small_box(kind, 1, 0.005, 0.002)
    at = C.certified_pose_errors(robot, sources, nominal, split=0, max_pieces=1)
    for i, q in enumerate(C.QUANTITIES):
        assert at.lower[q][0] <= second[i] <= at.upper[q][0] * 1.005, (kind, q, second[i], at.upper[q][0])


def test_exact_values_at_the_best_poses_inside_the_workspace():
    """The exact values go to the poses of largest first-order value *inside* the workspace, however many poses
    of the batch lie outside it (once, the outside ones were taken first and the lower bounds missed the
    maxima); they are the best feasible values there."""
    from pmaccuracy.accuracy.global_worst import EXACT_CANDIDATES, _exact, as_sources
    from pmaccuracy.model.clearances import ClearanceSet

    robot = Manipulator.preset("aalborg_3ppr")
    case = ClearanceSet.preset("case2")
    inside = np.array([[0.0, 0.0, 0.0], [25.0, -25.0, 0.0], [0.0, 20.0, 0.0]])
    outside = np.tile([[100.0, 100.0, 0.0]], (2 * EXACT_CANDIDATES, 1))
    poses = np.vstack([outside, inside])
    values, ins = _exact(robot, case, poses, as_sources(robot, case))
    assert not np.any(ins[:-3]) and np.all(ins[-3:])
    assert np.all(np.isnan(values[:-3])) and np.all(np.isfinite(values[-3:]))
    ref = C.nonlinear_pose_errors(robot, case, inside)
    for i, q in enumerate(C.QUANTITIES):
        np.testing.assert_allclose(values[-3:, i], ref.lower[q], rtol=1e-12)
