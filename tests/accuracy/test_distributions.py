"""Statistics of the pose error (distributions.py) against independent laws.

References: the error Jacobian by finite differences of the exact loop closures (``error_reference``,
independent of the library) split into the scalar laws of each source, whose distribution is known
(``distribution_reference``: sums of uniforms exactly, uniforms and semicircles by Gil-Pelaez).
Monte Carlo results must agree within ~4 of their own stated standard errors (fixed seeds).
"""

from __future__ import annotations

import json
import math
import tomllib
from importlib import resources

import numpy as np
import pytest

import distribution_reference as dref
import error_reference as eref
from pmaccuracy.accuracy import distributions as D
from pmaccuracy.report import statistics_report
from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.errors import ConfigError
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.kinematics import inverse_kinematics
from pmaccuracy.model.sources import ErrorSources, first_order_error

N = 100_000


def _robot_dict(name):
    return tomllib.loads((resources.files("pmaccuracy") / "data" / "robots" / f"{name}.toml").read_text())


def _ppr_spec(bearing=0.0012, lateral=0.0, radial=(0.0, 0.0, 0.0), L=50.0):
    """Per-joint spec of the 3-PPR format (guide on joint 1, bearing on joint 2, revolute on joint 3)."""
    legs = []
    for i in range(3):
        j1 = {"lateral": lateral, "block_length": L} if lateral else {}
        j2 = {"angular": bearing} if bearing else {}
        j3 = {"radial": radial[i]} if radial[i] else {}
        legs.append({"joints": [j1, j2, j3]})
    return {"legs": legs}


def _reference_laws(robot_name, spec, pose):
    """Per quantity dx, dy, dphi: (uniform half-widths, disk radii) from the FD Jacobian of the exact model."""
    merged = eref.merge_specs(_robot_dict(robot_name), spec)
    G, vars_ = eref.error_jacobian_fd(_robot_dict(robot_name), pose, merged)
    src = eref._sources(merged, vars_)
    return [dref.projections(G[q], src) for q in range(3)]


def _assert_cdf_close(values, cdf, xs, n_se=4.0):
    """Empirical CDF of ``values`` at ``xs`` within n_se binomial standard errors (+ 1/n) of ``cdf``."""
    n = values.size
    F = cdf(xs)
    emp = np.searchsorted(np.sort(values), xs, side="right") / n
    se = np.sqrt(np.maximum(F * (1 - F), 1.0 / n) / n)
    assert np.all(np.abs(emp - F) <= n_se * se + 1.0 / n), np.max(np.abs(emp - F) / se)


# ------------------------------------------------------------------ reference self-checks
def test_reference_gil_pelaez_equals_closed_forms():
    x = np.linspace(-1.3, 1.3, 27)
    np.testing.assert_allclose(dref.cdf_mixture(x, [0.3, 0.5, 0.4]), dref.cdf_sum_uniforms(x, [0.3, 0.5, 0.4]),
                               atol=1e-9)
    # a disk and a uniform: the semicircle CDF averaged over the uniform by quadrature
    from scipy import integrate
    conv = [integrate.quad(lambda u: dref.semicircle_cdf(xv - u, 1.0) / 0.6, -0.3, 0.3, epsabs=1e-13)[0] for xv in x]
    np.testing.assert_allclose(dref.cdf_mixture(x, [0.3], [1.0]), conv, atol=1e-8)
    # Irwin-Hall for two equal uniforms: triangle
    t = np.linspace(-2, 2, 9)
    tri = np.where(t < 0, (t + 2) ** 2 / 8, 1 - (2 - t) ** 2 / 8)
    np.testing.assert_allclose(dref.cdf_sum_uniforms(t, [1, 1]), np.clip(tri, 0, 1), atol=1e-15)


# ------------------------------------------------------------------ sampling and the linear model
def test_jacobian_errors_equal_first_order_error_of_the_sampled_configurations():
    robot = Manipulator.load("symmetric_3rpr")
    sources = D.as_sources(robot, "rpr_typical")
    poses = np.array([[0.0, 0.0, 0.0], [5.0, -3.0, 0.1]])
    Z = D.sample_sources(sources, 50, seed=3)
    J = D.error_jacobian(robot, sources, poses)  # (2, 3, K)
    fast = np.einsum("pqk,sk->spq", J, Z)
    cfg = D.to_displacements(D.source_terms(sources), Z)  # (50, 3, 3)
    joints = inverse_kinematics(robot, poses).joints
    direct = first_order_error(robot, joints[None], poses[None], JointDisplacementsBroadcast(cfg))
    np.testing.assert_allclose(fast, direct, atol=1e-15, rtol=1e-12)


def JointDisplacementsBroadcast(cfg):
    """Fields (n, 3, 3) -> (n, 1, 3, 3) so that they broadcast against poses (1, P, 3)."""
    from pmaccuracy.model.sources import JointDisplacements
    return JointDisplacements(*(getattr(cfg, f)[:, None] for f in ("shift", "turn", "sigma", "tau", "dq", "dl", "tilt")))


def test_samples_stay_in_their_sets_and_are_seeded():
    robot = Manipulator.load("aalborg_3ppr")
    sources = D.as_sources(robot, "all")
    for law in D.LAWS:
        Z = D.sample_sources(sources, 20_000, seed=5, distribution=law)
        np.testing.assert_array_equal(Z, D.sample_sources(sources, 20_000, seed=5, distribution=law))
        for t in D.source_terms(sources):
            c = t.start
            if t.shape == "interval":
                assert np.all(np.abs(Z[:, c]) <= t.eps * (1 + 1e-12))
            elif t.shape == "disk":
                r = np.hypot(Z[:, c], Z[:, c + 1])
                assert np.all(r <= t.eps * (1 + 1e-12))
                if law == "boundary":
                    np.testing.assert_allclose(r, t.eps, rtol=1e-12)
            else:
                s, tau = Z[:, c], Z[:, c + 1]
                edge = np.maximum(np.abs(t.block_length * tau + 2 * s), np.abs(t.block_length * tau - 2 * s))
                assert np.all(edge <= 2 * t.eps * (1 + 1e-12))
                if law == "boundary":
                    np.testing.assert_allclose(edge, 2 * t.eps, rtol=1e-12)
    assert not np.array_equal(D.sample_sources(sources, 10, seed=1), D.sample_sources(sources, 10, seed=2))


# ------------------------------------------------------------------ laws against the references
def test_case1_at_home_is_a_sum_of_three_uniforms():
    """Bearing clearances only: each of dx, dy, dphi is a sum of three uniforms (exact piecewise CDF)."""
    pose = np.zeros(3)
    laws = _reference_laws("aalborg_3ppr", _ppr_spec(), pose)
    E = D.sample_pose_errors("aalborg_3ppr", "case1", pose, N, seed=12)
    res = D.pose_statistics("aalborg_3ppr", "case1", pose, samples=N, seed=12,
                            thresholds={"dx": 0.15, "dphi_deg": 0.15})
    for q, name in enumerate(("dx", "dy", "dphi")):
        uniforms, disks = laws[q]
        assert not disks and len(uniforms) == 3
        cdf = lambda x: dref.cdf_sum_uniforms(x, uniforms)  # noqa: E731
        top = sum(uniforms)
        _assert_cdf_close(E[:, q], cdf, np.linspace(-top, top, 41))
        # Kolmogorov-Smirnov distance below the DKW bound P(sup |F_n - F| > e) <= 2 exp(-2 n e^2) = 1e-4
        v = np.sort(E[:, q])
        F = cdf(v)
        ks = max(np.max(np.arange(1, N + 1) / N - F), np.max(F - np.arange(N) / N))
        assert ks <= math.sqrt(math.log(2 / 1e-4) / (2 * N)), ks
        scale = math.degrees(1) if name == "dphi" else 1.0
        rec = res.quantities["dphi_deg" if name == "dphi" else name]
        # RSS = the analytic std; the Monte Carlo std within 4 of its standard errors
        sd = math.sqrt(dref.variance(uniforms, disks)) * scale
        assert rec["rss"] == pytest.approx(sd, rel=1e-6)
        assert abs(rec["std"] - sd) <= 4 * rec["se_std"]
        assert abs(rec["mean"]) <= 4 * rec["se_mean"]
        # worst case = sum of half-widths; the sample maximum below it
        assert rec["worst"] == pytest.approx(top * scale, rel=1e-6)
        assert rec["max_abs"] <= rec["worst"] * (1 + 1e-9)
        # percentile: the true quantile inside the stated interval
        true95 = dref.quantile_abs(0.95, cdf, top) * scale
        assert rec["p95_lo"] <= true95 <= rec["p95_hi"]
        if "exceed" in rec:
            thr = rec["threshold"] / scale
            p = 1 - cdf(np.array([thr]))[0] + cdf(np.array([-thr]))[0]
            assert abs(rec["exceed"] - p) <= 4 * max(rec["se_exceed"], 1 / N)


def test_case1_dp_against_quadrature_over_the_bearing_states():
    """dp = |(dx, dy)| with dx, dy linear in the three bearing states: its mean, std, P(dp > 0.2 mm) and 95th
    percentile by a midpoint rule over the cube of states (FD Jacobian of the exact model)."""
    spec = _ppr_spec()
    merged = eref.merge_specs(_robot_dict("aalborg_3ppr"), spec)
    G, _ = eref.error_jacobian_fd(_robot_dict("aalborg_3ppr"), np.zeros(3), merged)
    m = 150
    u = ((np.arange(m) + 0.5) / m * 2 - 1) * 0.0012
    U = np.stack(np.meshgrid(u, u, u, indexing="ij"), -1).reshape(-1, 3)
    dp = np.hypot(U @ G[0], U @ G[1])
    rec = D.pose_statistics("aalborg_3ppr", "case1", [0, 0, 0], samples=N, seed=12,
                            thresholds={"dp": 0.2}).quantities["dp"]
    assert abs(rec["mean"] - dp.mean()) <= 4 * rec["se_mean"]
    assert abs(rec["std"] - dp.std()) <= 4 * rec["se_std"]
    p = float(np.mean(dp > 0.2))
    assert abs(rec["exceed"] - p) <= 4 * math.sqrt(p * (1 - p) / N)
    assert rec["p95_lo"] <= np.quantile(dp, 0.95) <= rec["p95_hi"]
    assert rec["rss"] == pytest.approx(math.sqrt(np.mean(dp ** 2)), rel=1e-4)


def test_single_revolute_disk_gives_the_semicircle_law():
    """One radial clearance: every quantity is a semicircle law of radius eps |g| (closed form)."""
    spec = _ppr_spec(bearing=0.0, radial=(0.0, 0.04, 0.0))
    pose = np.array([3.0, -2.0, math.radians(5)])
    laws = _reference_laws("aalborg_3ppr", spec, pose)
    sources = ErrorSources.from_dict(spec)
    E = D.sample_pose_errors("aalborg_3ppr", sources, pose, N, seed=2)
    for q in range(3):
        uniforms, disks = laws[q]
        assert not uniforms and len(disks) == 1
        R = disks[0]
        _assert_cdf_close(E[:, q], lambda x: dref.semicircle_cdf(x, R), np.linspace(-R, R, 31))


@pytest.mark.parametrize("clearances,robot,pose", [
    ("all", "aalborg_3ppr", (4.0, 6.0, math.radians(-10))),
    ("rpr_typical", "symmetric_3rpr", (2.0, -1.0, 0.05)),
])
def test_mixed_sources_against_gil_pelaez(clearances, robot, pose):
    """Guide rhombi, bearings, revolute disks (3-PPR) or revolute disks, actuators, slide tilts (3-RPR)."""
    pose = np.array(pose)
    rob = Manipulator.load(robot)
    sources = D.as_sources(rob, clearances)
    legs = sources.to_dict()["legs"]
    for leg in legs:  # the file format's default guide block length (50 mm) is left out by to_dict
        for j in leg["joints"]:
            if "lateral" in j:
                j.setdefault("block_length", 50.0)
    laws = _reference_laws(robot, {"legs": legs}, pose)
    E = D.sample_pose_errors(rob, sources, pose, 50_000, seed=4)
    res = D.pose_statistics(rob, sources, pose, samples=50_000, seed=4)
    for q, name in enumerate(("dx", "dy", "dphi_deg")):
        uniforms, disks = laws[q]
        top = sum(uniforms) + sum(disks)
        _assert_cdf_close(E[:, q], lambda x: dref.cdf_mixture(x, uniforms, disks), np.linspace(-top, top, 25))
        scale = math.degrees(1) if name == "dphi_deg" else 1.0
        assert res.quantities[name]["rss"] == pytest.approx(math.sqrt(dref.variance(uniforms, disks)) * scale,
                                                              rel=1e-6)
    # dp: its mean square is var dx + var dy
    rec = res.quantities["dp"]
    ms = dref.variance(*laws[0]) + dref.variance(*laws[1])
    assert rec["rss"] == pytest.approx(math.sqrt(ms), rel=1e-6)
    dp = np.hypot(E[:, 0], E[:, 1])
    se = np.std(dp ** 2) / math.sqrt(dp.size)
    assert abs(np.mean(dp ** 2) - ms) <= 4 * se


def test_other_laws_variances_against_scipy():
    """truncnormal and boundary: the RSS equals the reference variance (scipy truncnorm, quadrature);
    Monte Carlo std within 4 standard errors."""
    robot = Manipulator.load("aalborg_3ppr")
    pose = np.array([0.0, 5.0, 0.0])
    spec = _ppr_spec(bearing=0.0012, lateral=0.0015, radial=(0.039, 0.036, 0.037))
    sources = ErrorSources.from_dict(spec)
    merged = eref.merge_specs(_robot_dict("aalborg_3ppr"), spec)
    G, vars_ = eref.error_jacobian_fd(_robot_dict("aalborg_3ppr"), pose, merged)
    src = eref._sources(merged, vars_)
    for law, sigma in (("truncnormal", 0.4), ("boundary", None)):
        dist = D.Distribution.from_dict({"default": {"kind": law, "sigma": sigma} if sigma else law})
        # reference variance of each source's contribution to dx, dy, dphi
        var = np.zeros(3)
        for kind, eps, cols, L in src:
            g = G[:, cols]
            if kind == "interval":
                w = dref.truncnorm_unit_variance(sigma) if sigma else 1.0
                var += (eps * g[:, 0]) ** 2 * w
            elif kind == "disk":
                w = dref.truncated_disk_component_variance(sigma) if sigma else 0.5
                var += eps ** 2 * (g[:, 0] ** 2 + g[:, 1] ** 2) * w
            else:  # sigma = eps (u - v) / 2, tau = eps (u + v) / L; boundary: E u^2 = 1/2 + 1/6 on the square edge
                wu = dref.truncnorm_unit_variance(sigma) if sigma else 2 / 3
                cu = g[:, 0] * eps / 2 + g[:, 1] * eps / L
                cv = g[:, 1] * eps / L - g[:, 0] * eps / 2
                var += (cu ** 2 + cv ** 2) * wu
        res = D.pose_statistics(robot, sources, pose, samples=50_000, seed=8, distribution=dist)
        for q, name in enumerate(("dx", "dy", "dphi_deg")):
            scale = math.degrees(1) if name == "dphi_deg" else 1.0
            rec = res.quantities[name]
            assert rec["rss"] == pytest.approx(math.sqrt(var[q]) * scale, rel=1e-6), (law, name)
            assert abs(rec["std"] - rec["rss"]) <= 4 * rec["se_std"], (law, name)


def test_boundary_loading_reaches_the_worst_case():
    """Intervals only on their ends: 8 states, the sample maximum is exactly the worst case; with disks and
    rhombi on their edges the sample maximum approaches it from below."""
    pose = np.array([5.0, -5.0, math.radians(3)])
    b = max_pose_errors(Manipulator.load("aalborg_3ppr"), ErrorSources.from_dict(_ppr_spec()), pose)
    E = D.sample_pose_errors("aalborg_3ppr", "case1", pose, 2000, seed=1, distribution="boundary")
    np.testing.assert_allclose(np.abs(E).max(axis=0), [b.dx_max, b.dy_max, b.dphi_max], rtol=1e-12)
    np.testing.assert_allclose(np.hypot(E[:, 0], E[:, 1]).max(), b.dp_max, rtol=1e-12)
    robot = Manipulator.load("aalborg_3ppr")
    sources = D.as_sources(robot, "all")
    b = max_pose_errors(robot, sources, pose)
    worst = np.array([b.dx_max, b.dy_max, b.dphi_max, b.dp_max])
    for law, low in (("uniform", 0.6), ("boundary", 0.9)):
        E = D.sample_pose_errors(robot, sources, pose, 100_000, seed=3, distribution=law)
        got = np.array([*np.abs(E).max(axis=0), np.hypot(E[:, 0], E[:, 1]).max()])
        assert np.all(got <= worst * (1 + 1e-12))
        assert np.all(got >= low * worst), (law, got / worst)


def test_percentile_interval_coverage():
    """The stated 95 % order-statistic interval covers the true quantile in ~95 % of 400 replications."""
    uniforms = [0.2, 0.3, 0.1]
    rng = np.random.default_rng(12)
    reps, n = 400, 2000
    x = sum(rng.uniform(-a, a, (n, reps)) for a in uniforms)
    st = D.sample_statistics(x, percentiles=(95.0,))
    true = dref.quantile_abs(0.95, lambda v: dref.cdf_sum_uniforms(v, uniforms), sum(uniforms))
    cover = np.mean((st["p95_lo"] <= true) & (true <= st["p95_hi"]))
    assert abs(cover - 0.95) <= 4 * math.sqrt(0.95 * 0.05 / reps)


def test_exact_closure_differs_at_second_order():
    """Exact loop closures of the sampled states differ from the first-order errors by O(eps^2)."""
    robot = Manipulator.load("symmetric_3rpr")
    pose = np.array([1.0, 2.0, 0.05])
    diffs = []
    for factor in (1.0, 0.5):
        sources = D.as_sources(robot, "rpr_typical").scaled(factor * 10)
        Z = D.sample_sources(sources, 40, seed=6)
        exact = D.exact_pose_errors(robot, sources, pose, Z)
        first = Z @ D.error_jacobian(robot, sources, pose).T
        diffs.append(np.abs(exact - first).max())
        assert diffs[-1] < 0.05 * np.abs(first).max()
    assert 3.0 < diffs[0] / diffs[1] < 5.0  # halving the clearances quarters the gap


# ------------------------------------------------------------------ region
def test_region_statistics_against_pose_statistics():
    ds = D.region_statistics("aalborg_3ppr", "case1", [0.0], grid=5, samples=4000, seed=9,
                             thresholds={"dp": 0.15}, percentiles=(90.0,))
    inside = np.isfinite(ds["dp_max"].values[0])
    assert inside.sum() > 10
    assert np.all(np.isfinite(ds["dp_p90"].values[0][inside])) and np.all(np.isnan(ds["dp_p90"].values[0][~inside]))
    j, i = np.argwhere(inside)[3]
    pose = [float(ds.x[i]), float(ds.y[j]), 0.0]
    rec = D.pose_statistics("aalborg_3ppr", "case1", pose, samples=4000, seed=9, thresholds={"dp": 0.15},
                            percentiles=(90.0,)).quantities
    assert ds["dp_p90"].values[0, j, i] == pytest.approx(rec["dp"]["p90"], rel=1e-12)
    assert ds["dp_exceed"].values[0, j, i] == pytest.approx(rec["dp"]["exceed"], rel=1e-12)
    assert ds["dphi_rss"].values[0, j, i] == pytest.approx(rec["dphi_deg"]["rss"], rel=1e-12)
    assert ds["dx_max"].values[0, j, i] == pytest.approx(rec["dx"]["worst"], rel=1e-12)
    assert np.all(ds["dp_p90"].values[0][inside] <= ds["dp_max"].values[0][inside])
    summary = D.summarize_region(ds)
    rec0 = summary["orientations"]["0"]["dp"]
    assert 0 < rec0["p90_over_max"] < 1 and rec0["max"][1] == pytest.approx(float(np.nanmax(ds["dp_max"])))


def test_percentile_map_figure(tmp_path):
    ds = D.region_statistics("aalborg_3ppr", "case1", [0.0], grid=5, samples=500, seed=1)
    path = statistics_report.save_percentile_map_figure(ds, tmp_path / "p.png")
    assert path.stat().st_size > 10_000


# ------------------------------------------------------------------ input errors and CLI
@pytest.mark.parametrize("data,key", [
    ({"radial": "gaussian"}, "radial.kind"),
    ({"angular": {"kind": "truncnormal", "sigma": -1}}, "angular.sigma"),
    ({"spin": "uniform"}, "spin"),
    ({"radial": 3}, "radial"),
])
def test_bad_distribution_files(data, key):
    with pytest.raises(ConfigError) as exc:
        D.Distribution.from_dict(data, source="d.toml")
    assert key in str(exc.value)


def test_bad_arguments():
    with pytest.raises(ConfigError, match="samples"):
        D.pose_statistics("aalborg_3ppr", "case1", [0, 0, 0], samples=0)
    with pytest.raises(ConfigError, match="percentile"):
        D.pose_statistics("aalborg_3ppr", "case1", [0, 0, 0], samples=10, percentiles=(100.0,))
    with pytest.raises(ConfigError, match="dphi"):
        D.pose_statistics("aalborg_3ppr", "case1", [0, 0, 0], samples=10, thresholds={"dphi": 0.1})


def _cli(capsys, *args):
    from pmaccuracy.cli import main
    code = main(["statistics", *args])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_cli_pose_json_and_refusals(tmp_path, capsys):
    code, out, err = _cli(capsys, "--pose", "0", "0", "0", "--samples", "2000", "--seed", "3", "--threshold",
                          "dp=0.1", "--format", "json")
    assert code == 0, err
    lib = D.pose_statistics("aalborg_3ppr", "case1", [0, 0, 0], samples=2000, seed=3, thresholds={"dp": 0.1})
    assert json.loads(out)["quantities"]["dp"]["exceed"] == lib.quantities["dp"]["exceed"]
    bad = tmp_path / "d.toml"
    bad.write_text('radial = "gaussian"\n')
    for args, word in ((("--pose", "0", "0", "0", "--distribution", str(bad)), "radial.kind"),
                       (("--pose", "0", "0", "0", "--threshold", "dz=1"), "--threshold"),
                       (("--phi-deg", "0"), "--out"),
                       (("--phi-deg", "0", "--out", str(tmp_path / "m.txt")), "--out"),
                       (("--pose", "0", "0", "0", "--percentile", "100"), "--percentile")):
        try:
            code, out, err = _cli(capsys, *args)
        except SystemExit as exc:  # argparse refusals
            code, err = exc.code, capsys.readouterr().err
        assert code == 2 and len(err.strip().splitlines()) == 1 and word in err, err


def test_cli_map_csv(tmp_path, capsys):
    out = tmp_path / "m.csv"
    code, _, err = _cli(capsys, "--phi-deg", "0", "--grid", "4", "--samples", "300", "--out", str(out))
    assert code == 0, err
    header = out.read_text().splitlines()[0].split(",")
    assert header[:3] == ["x", "y", "phi_deg"] and "dphi_p95_deg" in header and "dp_rss" in header


def test_statistics_section_for_a_report(tmp_path):
    out = statistics_report.statistics_section("aalborg_3ppr", "case1", 0.0, grid=5, samples=500, pose_samples=2000,
                               figure=tmp_path / "s.png")
    assert out["threshold_dp"] == pytest.approx(round(0.5 * out["pose"]["quantities"]["dp"]["worst"], 4))
    assert out["region"]["orientations"]["0"]["dp"]["exceed"][1] >= 0
    assert (tmp_path / "s.png").stat().st_size > 10_000
    json.dumps(out)


def test_pose_statistics_is_a_frozen_result_with_a_readable_repr():
    import dataclasses
    res = D.pose_statistics("aalborg_3ppr", "case1", [0, 0, 0], samples=2000, seed=1, exact_samples=5)
    with pytest.raises(dataclasses.FrozenInstanceError):
        res.samples = 3
    text = repr(res)
    assert text.startswith("PoseStatistics(1 pose: 2000 samples") and "dphi_deg" in text
    assert "<table" in res._repr_html_()
    d = res.to_dict()
    assert d["pose"]["phi_deg"] == 0.0 and d["exact_check"]["samples"] == 5
    assert d["quantities"]["dp"]["worst"] == res.quantities["dp"]["worst"]
    json.dumps(d)
