"""Tolerance synthesis: targets hold everywhere under an independent dense check, 2 % more breaks one.

The independent check evaluates the synthesized clearances, read back from the
written TOML file, with :func:`max_pose_errors` on a dense grid of the region plus
random poses (the synthesis uses the interval certificate and a cone program,
not these grids). "2 % more breaks a target" is shown by a pose where the
scaled clearances exceed a target: the attained lower bound of the global worst
case (a value of :func:`max_pose_errors` at a pose) above the target.
"""

from __future__ import annotations

import numpy as np
import pytest

from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.errors import ConfigError
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.accuracy.global_worst import global_worst, make_region
from pmaccuracy.kinematics import inverse_kinematics
from pmaccuracy.io.resolve import load_clearances
from pmaccuracy.accuracy.synthesis import clearance_toml, free_sources, parse_targets, pose_coefficients, synthesize
from conftest import run_cli

AALBORG = Manipulator.preset("aalborg_3ppr")
RNG = np.random.default_rng(5)
FIXED = make_region(AALBORG, (0.0, 0.0), None)
TARGETS = parse_targets(["dp=0.3", "dphi_deg=0.3"])


def dense_maxima(robot, clearances, region, n=81, n_phi=3, n_random=4000):
    """Largest exact maxima over a dense grid and random poses of the region in the workspace (mm, rad)."""
    phis = np.linspace(*region.phi, 1 if region.phi[0] == region.phi[1] else n_phi)
    X, Y, P = np.meshgrid(np.linspace(-25, 25, n), np.linspace(-25, 25, n), phis, indexing="ij")
    lo = np.array([region.x[0], region.y[0], region.phi[0]])
    hi = np.array([region.x[1], region.y[1], region.phi[1]])
    pts = np.vstack([np.column_stack([X.ravel(), Y.ravel(), P.ravel()]), lo + RNG.uniform(size=(n_random, 3)) * (hi - lo)])
    pts = pts[inverse_kinematics(robot, pts).within_limits]
    assert pts.shape[0] > 1000
    b = max_pose_errors(robot, clearances, pts)
    return {"dx": b.dx_max.max(), "dy": b.dy_max.max(), "dphi": b.dphi_max.max(), "dp": b.dp_max.max()}


def check_result(res, region, tmp_path):
    path = tmp_path / "synth.toml"
    path.write_text(clearance_toml(res, AALBORG, region))
    back = load_clearances(str(path), AALBORG)
    worst = dense_maxima(AALBORG, back, region)
    for q, target in res.targets.items():
        assert worst[q] <= target * (1 + 1e-12), q
        assert res.worst[q].upper <= target * (1 + 1e-12), q
    bigger = global_worst(AALBORG, back.scaled(1.02), region)
    assert any(bigger[q].lower > target for q, target in res.targets.items())
    return back


def test_uniform_scaling(tmp_path):
    res = synthesize(AALBORG, FIXED, TARGETS, mode="uniform")
    back = check_result(res, FIXED, tmp_path)
    # every source scaled by the same factor, from the case1 template (bearing tilt 0.0012 rad)
    assert np.allclose(res.values / res.template_values, res.scale)
    assert [s.key for s in free_sources(back)] == ["angular"] * 3
    assert np.allclose([s.value for s in free_sources(back)], 0.0012 * res.scale, rtol=1e-12)


def test_min_cost_with_a_cost_file(tmp_path):
    region = FIXED
    cost = tmp_path / "cost.toml"
    cost.write_text("[[legs]]\njoints = [{}, { angular = 1.0 }, { radial = 1.0 }]\n"
                    "[[legs]]\njoints = [{}, { angular = 1.0 }, { radial = 1.0 }]\n"
                    "[[legs]]\njoints = [{}, { angular = 1.0 }, { radial = 8.0 }]\n")
    targets = parse_targets(["dp=0.5", "dphi_deg=0.4"])
    res = synthesize(AALBORG, region, targets, template="case2", costs=str(cost), mode="min-cost")
    check_result(res, region, tmp_path)
    uni = synthesize(AALBORG, region, targets, template="case2", mode="uniform")
    weights = np.array([1, 1, 1, 1, 1, 8.0])
    # the uniform result is feasible for the cost model, so the optimum costs no more (up to the certificate's gap)
    assert res.cost <= float(weights @ (res.template_values / uni.values)) * (1 + 2e-3)
    ratio = res.values / res.template_values
    labels = [s.label for s in res.sources]
    assert ratio[labels.index("legs[3].joints[3].radial")] > ratio[labels.index("legs[1].joints[3].radial")]


def test_pose_coefficients_reproduce_the_maxima():
    tpl = load_clearances("rpr_typical", Manipulator.preset("symmetric_3rpr"))
    robot = Manipulator.preset("symmetric_3rpr")
    pts = RNG.uniform(-20, 20, (200, 3)) * np.array([1, 1, 0.005])
    pts = pts[inverse_kinematics(robot, pts).within_limits]
    sources = free_sources(tpl)
    lin, Mx, My = pose_coefficients(robot, tpl, sources, pts)
    z = RNG.uniform(0.2, 3.0, len(sources))
    from pmaccuracy.accuracy.synthesis import with_values
    b = max_pose_errors(robot, with_values(tpl, sources, z * [s.value for s in sources], "z"), pts)
    np.testing.assert_allclose(lin @ z, np.column_stack([b.dx_max, b.dy_max, b.dphi_max]), rtol=1e-10)
    np.testing.assert_allclose(np.max(np.hypot(Mx @ z, My @ z), axis=1), b.dp_max, rtol=1e-10)


@pytest.mark.parametrize("items,needle", [
    (["dphi=0.3"], "dphi_deg"), (["foo=1"], "unknown target"), (["dp=-1"], "> 0"), (["dp=0"], "> 0"),
    (["dp=nan"], "> 0"), (["dp"], "NAME=VALUE"), ([], "at least one"), (["dp=1", "dp=2"], "twice"),
    (["dp=abc"], "not a number")])
def test_bad_targets(items, needle):
    with pytest.raises(ConfigError, match=needle):
        parse_targets(items)


def run(argv, capsys):
    return run_cli(argv, capsys)


def test_cli_writes_a_clearance_file_that_bounds_reads(tmp_path, capsys):
    out = tmp_path / "sub" / "c.toml"
    status, text, err = run(["synthesize", "--target", "dp=0.3", "--target", "dphi_deg=0.3", "--out", str(out)],
                            capsys)
    assert status == 0, err
    assert "legs[1].joints[2].angular" in text and "dphi_deg" in text
    status, text2, err = run(["bounds", "--clearances", str(out), "--pose", "-25", "-25", "0", "--format", "json"],
                             capsys)
    assert status == 0, err
    back = load_clearances(str(out), AALBORG)
    assert dense_maxima(AALBORG, back, FIXED)["dp"] <= 0.3 * (1 + 1e-12)


@pytest.mark.parametrize("argv,needle", [
    (["--target", "dphi=0.3"], "--target"),
    (["--target", "dp=-0.3"], "--target"),
    (["--target", "dp=0.3", "--phi-deg", "5", "0"], "--phi-deg"),
    (["--target", "dp=0.3", "--region", "100,200,100,200"], "no pose of the region"),
    (["--target", "dp=0.3", "--robot", "symmetric_3rpr", "--phi-deg", "-30", "-30"], "singularity"),
    (["--target", "dp=0.3", "--cost", "COST"], "not a free source"),
    (["--target", "dp=0.3", "--out", "/proc/nope/x.toml"], "--out"),
])
def test_cli_bad_input_exits_2_with_one_line(tmp_path, capsys, argv, needle):
    cost = tmp_path / "cost.toml"
    cost.write_text("[[legs]]\njoints = [{ lateral = 1.0 }]\n" + "[[legs]]\njoints = []\n" * 2)
    argv = [str(cost) if a == "COST" else a for a in argv]
    status, out, err = run(["synthesize", *argv], capsys)
    assert status == 2, err
    assert err.count("\n") == 1 and needle in err


def test_a_source_without_effect_is_kept_at_the_template_value():
    # the symmetric 3-RPR's slide tilt turns the leg about its base revolute, which the leg's constraint
    # force passes through: no first-order effect, so no target bounds it
    robot = Manipulator.preset("symmetric_3rpr")
    region = make_region(robot, (0.0, 0.0), (-5.0, 5.0, -5.0, 5.0))
    targets = parse_targets(["dphi_deg=0.1"])
    with pytest.warns(UserWarning, match="angular.*no first-order effect"):
        res = synthesize(robot, region, targets, mode="min-cost")
    ratio = res.values / res.template_values
    tilt = np.array([s.key == "angular" for s in res.sources])
    assert tilt.sum() == 3 and np.all(ratio[tilt] <= 1.0 + 1e-12) and np.all(ratio[tilt] >= 0.9)
    assert res.worst["dphi"].upper <= targets["dphi"] * (1 + 1e-12)
    assert res.worst["dphi"].lower >= targets["dphi"] / 1.02


@pytest.mark.parametrize("mode", ["uniform", "min-cost"])
def test_cli_template_without_effect_exits_2(tmp_path, capsys, mode):
    # only the 3-RPR's slide tilts, which have no first-order effect (see above): nothing to scale
    tpl = tmp_path / "tilt.toml"
    tpl.write_text("[[legs]]\njoints = [{}, { angular = 0.0005 }, {}]\n" * 3)
    status, out, err = run(["synthesize", "--robot", "symmetric_3rpr", "--clearances", str(tpl), "--target",
                            "dp=0.1", "--region=-5,5,-5,5", "--mode", mode], capsys)
    assert status == 2 and err.count("\n") == 1 and "--target" in err and "affect" in err


def test_uniform_mode_certifies_once_and_scales_that_certificate(monkeypatch):
    import pmaccuracy.accuracy.synthesis as S
    calls = []
    real = S.global_worst

    def counting(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(S, "global_worst", counting)
    region = make_region(AALBORG, (np.radians(-5), np.radians(5)), None)
    res = synthesize(AALBORG, region, TARGETS, mode="uniform")
    assert len(calls) == 1 and res.certified
    # against an independent certificate of the synthesized clearances and the exact maxima at the poses
    fresh = global_worst(AALBORG, res.clearances, region)
    for q, w in res.worst.quantities.items():
        assert w.lower <= fresh[q].upper * (1 + 1e-12) and fresh[q].lower <= w.upper * (1 + 1e-12), q
        b = max_pose_errors(AALBORG, res.clearances, w.pose[None])
        exact = {"dx": b.dx_max, "dy": b.dy_max, "dphi": b.dphi_max, "dp": b.dp_max}[q][0]
        assert exact == pytest.approx(w.lower, rel=1e-12), q
    assert max(res.worst[q].upper / TARGETS[q] for q in TARGETS) == pytest.approx(1.0, rel=1e-12)


@pytest.mark.parametrize("mode", ["uniform", "min-cost"])
def test_an_uncertified_worst_case_is_reported_with_its_gap(mode):
    from pmaccuracy.model.plausibility import PlausibilityWarning
    region = make_region(AALBORG, (np.radians(-30), np.radians(30)), None)
    with pytest.warns(PlausibilityWarning, match=r"not within the requested gap of 0.1 % for .*dp \("):
        res = synthesize(AALBORG, region, TARGETS, mode=mode, max_boxes=200)
    assert not res.certified and "dp" in res.uncertified
    assert all(g > 1e-3 for g in res.uncertified.values())
    assert all(res.worst[q].gap == g for q, g in res.uncertified.items())
    # the targets still hold: the result relies on the (valid) upper bounds
    worst = dense_maxima(AALBORG, res.clearances, region, n=41)
    for q, target in res.targets.items():
        assert res.worst[q].upper <= target * (1 + 1e-12) and worst[q] <= target * (1 + 1e-12), q


def test_cli_rows_say_whether_certified_and_the_gap(capsys):
    import json
    status, text, err = run(["synthesize", "--target", "dp=0.3", "--format", "json"], capsys)
    assert status == 0, err
    rows = {r["quantity"]: r for r in json.loads(text)["worst"]}
    assert rows["dp"]["certified"] is True and 0 <= rows["dp"]["gap_pct"] <= 0.1
    assert rows["dp"]["gap_pct"] == pytest.approx(100 * (rows["dp"]["upper"] - rows["dp"]["lower"]) / rows["dp"]["lower"],
                                                  rel=1e-6)


def test_cli_warns_in_one_line_when_the_certificate_stops_short(monkeypatch, capsys):
    import pmaccuracy.accuracy.synthesis as S
    real = S.global_worst

    def short(*args, **kwargs):   # a budget too small for the certificate to reach its gap
        kwargs["max_boxes"] = 200
        return real(*args, **kwargs)

    monkeypatch.setattr(S, "global_worst", short)
    status, text, err = run(["synthesize", "--target", "dp=0.3", "--phi-deg", "-30", "30", "--clearances", "case1"],
                            capsys)
    assert status == 0
    lines = [ln for ln in err.splitlines() if ln]
    assert len(lines) == 1 and lines[0].startswith("pmaccuracy synthesize: warning: the certified worst case is not")
    assert "dp (" in lines[0]
    assert "False" in text   # the certificate table's certified column


def test_min_cost_solver_failure_is_the_librarys_error(monkeypatch):
    """cvxpy's SolverError (seen near a singular band of a 3-PRR) reaches the user as a CertificationError that
    says what to do, not as an internal error."""
    import cvxpy as cp

    from pmaccuracy.accuracy.global_worst import make_region
    from pmaccuracy.accuracy.synthesis import synthesize
    from pmaccuracy.errors import CertificationError

    def fail(self, *args, **kwargs):
        raise cp.error.SolverError("Solver 'CLARABEL' failed.")
    monkeypatch.setattr(cp.Problem, "solve", fail)
    region = make_region("symmetric_3rpr", (0.0, 0.0), (-2.0, 2.0, -2.0, 2.0))
    with pytest.raises(CertificationError, match="cone program of the min-cost synthesis could not be solved"):
        synthesize("symmetric_3rpr", region, {"dp": 0.05}, clearances="rpr_typical", mode="min-cost")
