"""Statistics of spatial robots' pose errors at a pose (pmaccuracy.accuracy.spatial_statistics): the exact
covariance against one built here from the independent brute-force reference
(tests/reference/spatial_error_reference.py: first-order map by central differences of the nonlinear closures),
Monte Carlo against it within its standard error, sample maxima under the worst case, percentiles, seeds, the
command line and bad input."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import spatial_error_reference as eref
import spatial_reference as ref
from conftest import run_cli
from scipy.spatial.transform import Rotation

import pmaccuracy as pm
from pmaccuracy.accuracy import spatial_statistics as ss
from pmaccuracy.errors import ConfigError, PoseError
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.model.spatial_sources import SpatialErrorSources

ARCHS = ["6-UPS", "delta", "3-RPS", "3-PRS", "3-UPU"]
DEG = math.degrees(1.0)
COMPONENTS = ("dx", "dy", "dz", "drx_deg", "dry_deg", "drz_deg")


def _library(arch):
    robot_dict = ref.load_reference(arch)
    cl_dict = eref.load_clearances(arch)
    robot = SpatialManipulator.from_dict(robot_dict, source="r.toml")
    sources = SpatialErrorSources.from_dict(cl_dict, robot, source="c.toml")
    p, R = eref.nominal_pose(robot_dict)
    pose = np.concatenate([p, Rotation.from_matrix(R).as_rotvec()])
    return robot_dict, cl_dict, robot, sources, p, R, pose


def _reference_covariance(M, sources, law="uniform", sigma=1 / 3):
    """Exact covariance of t = M s with each source's variables uniform in its own ball of radius h (written
    here: Cov of a uniform d-ball of radius h is h^2 I / (d + 2); of an isotropic normal of sd sigma h
    truncated to it, by the chi-square moments)."""
    from scipy.special import gammainc

    cov = np.zeros((6, 6))
    for src in sources:
        d = eref.SHAPE_DIM[src["shape"]]
        assert M[:, src["columns"]].shape == (6, d)
        if law == "uniform":
            v = 1.0 / (d + 2)
        else:
            c = 0.5 / sigma ** 2
            v = sigma ** 2 * gammainc(d / 2 + 1, c) / gammainc(d / 2, c)
        Ms = M[:, src["columns"]]
        cov += v * src["half_width"] ** 2 * Ms @ Ms.T
    return cov


def _rms_from_cov(cov):
    var = np.diag(cov)
    return {**{q: math.sqrt(var[k]) * (DEG if k >= 3 else 1.0) for k, q in enumerate(COMPONENTS)},
            "dp": math.sqrt(var[:3].sum()), "dtheta_deg": math.sqrt(var[3:].sum()) * DEG}


@pytest.mark.parametrize("arch", ["6-UPS", pytest.param("delta", marks=pytest.mark.slow)])
def test_analytic_and_monte_carlo_against_the_independent_reference(arch):
    robot_dict, cl_dict, robot, sources, p, R, pose = _library(arch)
    M, ref_sources = eref.sensitivity(robot_dict, cl_dict, p, R)
    for law in ("uniform", "normal"):
        cov = _reference_covariance(M, ref_sources, law)
        expected = _rms_from_cov(cov)
        st = ss.spatial_pose_statistics(robot, sources, pose, samples=100_000, seed=3, distribution=law)
        np.testing.assert_allclose(st.covariance, cov, rtol=0, atol=1e-6 * np.max(np.diag(cov)))
        for q, rec in st.quantities.items():
            assert rec["rss"] == pytest.approx(expected[q], rel=1e-6), (arch, law, q)
            # Monte Carlo root mean square within 3 standard errors of the exact one
            assert abs(rec["rms"] - expected[q]) <= 3 * rec["se_rms"], (arch, law, q, rec["rms"], expected[q])
            if q in COMPONENTS:      # zero mean, std = rms
                assert abs(rec["mean"]) <= 4 * rec["se_mean"], (arch, law, q)


@pytest.mark.parametrize("arch", ARCHS)
def test_samples_never_exceed_the_worst_case_and_percentiles_are_monotone(arch):
    *_, robot, sources, p, R, pose = _library(arch)
    for law in ("uniform", "normal"):
        st = ss.spatial_pose_statistics(robot, sources, pose, samples=20_000, seed=1, distribution=law,
                                        percentiles=(50, 90, 95, 99, 99.9))
        assert st.within_worst, arch
        for q, rec in st.quantities.items():
            assert rec["max_abs"] <= rec["worst"] * (1 + 1e-9), (arch, law, q)
            chain = [rec["mean_abs"], rec["p90"], rec["p95"], rec["p99"], rec["p99.9"], rec["max_abs"]]
            assert all(a <= b for a, b in zip(chain[1:], chain[2:])), (arch, q, chain)
            assert rec["p50"] <= rec["p90"] and rec["p99"] <= rec["worst"]
            assert rec["p95_lo"] <= rec["p95"] <= rec["p95_hi"]
            assert rec["rms"] <= rec["max_abs"] and 0 < rec["max_over_worst"] <= 1 + 1e-9
    # the worst case is the library's own bound at the pose (dp: the certified upper bound)
    b = pm.spatial_pose_errors(robot, sources, pose)
    assert st.quantities["dp"]["worst"] == pytest.approx(float(b.dp_upper), rel=1e-12)
    assert st.quantities["drz_deg"]["worst"] == pytest.approx(float(b.components[5]) * DEG, rel=1e-12)


def test_extreme_samples_reach_close_to_the_worst_case_of_a_segment_sum():
    # a segment along dx: the uniform samples fill [-h, h]; the worst case is attained within 1e-3
    t = ss.sample_twists([np.eye(6)[:, :1] * 0.2], [1], 10_000, seed=0)
    assert 0.2 * (1 - 1e-3) <= np.abs(t[:, 0]).max() <= 0.2


@pytest.mark.parametrize("d", [1, 2, 3])
@pytest.mark.parametrize("law", ["uniform", "normal"])
def test_unit_set_laws(d, law):
    x = ss.sample_unit_set(np.random.default_rng(5), d, 200_000, law)
    r = np.linalg.norm(x, axis=1)
    assert x.shape == (200_000, d) and r.max() <= 1.0
    v = ss.unit_variance(d, law)
    for k in range(d):
        assert x[:, k].var() == pytest.approx(v, rel=0.02)
    if law == "uniform":    # uniform by volume: P(r <= 1/2) = 2^-d
        assert np.mean(r <= 0.5) == pytest.approx(0.5 ** d, abs=0.005)
    if d > 1:               # isotropic: uncorrelated coordinates
        assert abs(np.mean(x[:, 0] * x[:, 1])) < 0.01 * v


def test_thresholds_and_seeds():
    *_, robot, sources, p, R, pose = _library("3-UPU")
    a = ss.spatial_pose_statistics(robot, sources, pose, samples=5000, seed=7)
    b = ss.spatial_pose_statistics(robot, sources, pose, samples=5000, seed=7)
    c = ss.spatial_pose_statistics(robot, sources, pose, samples=5000, seed=8)
    assert a.quantities == b.quantities
    assert a.quantities["dp"]["rms"] != c.quantities["dp"]["rms"]
    thr = {"dp": a.quantities["dp"]["p95"], "dtheta_deg": 0.0, "dz": 1e9}
    t = ss.spatial_pose_statistics(robot, sources, pose, samples=5000, seed=7, thresholds=thr)
    assert t.quantities["dp"]["exceed"] == pytest.approx(0.05, abs=1e-3)
    assert t.quantities["dp"]["threshold"] == thr["dp"]
    assert t.quantities["dtheta_deg"]["exceed"] == 1.0 and t.quantities["dz"]["exceed"] == 0.0
    assert "exceed" not in t.quantities["dx"]
    d = t.to_dict()
    json.dumps(d)
    assert set(d["quantities"]) == set(ss.QUANTITIES) and np.array(d["covariance"]).shape == (6, 6)
    assert "SpatialPoseStatistics" in repr(t)


@pytest.mark.parametrize("kwargs, error, words", [
    ({"pose": np.zeros((2, 6))}, PoseError, "pose must be one pose (6,)"),
    ({"pose": [0, 0, 400]}, PoseError, "shape (..., 6)"),
    ({"pose": [0, 0, 400, 0, 0, float("nan")]}, PoseError, "not finite"),
    ({"samples": 999}, ConfigError, "samples: the number of samples must be a whole number >= 1000"),
    ({"samples": 1000.5}, ConfigError, "samples"),
    ({"distribution": "boundary"}, ConfigError, "distribution: unknown law 'boundary'"),
    ({"percentiles": (0.0,)}, ConfigError, "percentiles: must lie strictly between 0 and 100"),
    ({"percentiles": (95, 100)}, ConfigError, "percentiles"),
    ({"percentiles": ("x",)}, ConfigError, "percentiles"),
    ({"thresholds": {"dphi_deg": 1.0}}, ConfigError, "thresholds: unknown quantity 'dphi_deg'"),
    ({"thresholds": {"dp": -1.0}}, ConfigError, "thresholds: dp: must be a finite value >= 0"),
    ({"sigma": 0.0}, ConfigError, "sigma"),
])
def test_bad_input_names_the_argument(kwargs, error, words):
    args = {"pose": [0, 0, 400, 0, 0, 0], **kwargs}
    pose = args.pop("pose")
    with pytest.raises(error) as exc:
        ss.spatial_pose_statistics("stewart_6ups", "ups_typical", pose, **args)
    assert words in str(exc.value)


def test_planar_robot_refused():
    with pytest.raises(ConfigError, match="planar robot"):
        ss.spatial_pose_statistics("aalborg_3ppr", None, [0, 0, 0, 0, 0, 0], samples=1000)


# ---------------------------------------------------------------------------------------------- command line
def test_cli_json_agrees_with_the_library(capsys):
    status, out, err = run_cli(["statistics", "--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0,
                                "--samples", 5000, "--seed", 4, "--threshold", "dp=0.03", "--format", "json"],
                               capsys)
    assert status == 0, err
    data = json.loads(out)
    robot = pm.load_robot("stewart_6ups")
    pose = pm.poses_from_coordinates([0, 0, 400, 0, 0, 0], degrees=True)
    lib = ss.spatial_pose_statistics(robot, "ups_typical", pose, samples=5000, seed=4, thresholds={"dp": 0.03})
    assert data["pose"]["z"] == pytest.approx(400.0) and data["samples"] == 5000
    assert data["within_worst"] is True and data["clearances"] == "ups_typical"
    for q, rec in lib.quantities.items():
        for key, value in rec.items():
            assert data["quantities"][q][key] == pytest.approx(value, rel=1e-12, abs=1e-15), (q, key)
    assert "clearances: ups_typical (default)" in err


def test_cli_table_and_csv_have_one_row_per_quantity_with_units(capsys):
    status, out, err = run_cli(["statistics", "--robot", "delta_clavel", "--pose", 0, 0, -800, "--samples", 2000,
                                "--distribution", "normal", "--format", "csv"], capsys)
    assert status == 0, err
    lines = out.strip().splitlines()
    header = lines[0].split(",")
    assert header[:2] == ["quantity", "unit"] and {"rms", "rss", "p95", "p99", "worst"} <= set(header)
    assert [ln.split(",")[:2] for ln in lines[1:]] == [[q, "deg" if q.endswith("_deg") else "mm"]
                                                       for q in ss.QUANTITIES]
    status, out, err = run_cli(["statistics", "--robot", "rps_3", "--pose", 350, 5, -3, "--samples", 2000], capsys)
    assert status == 0, err
    assert out.split()[:9] == ["quantity", "unit", "mean_abs", "rms", "rss", "p95", "p99", "max_abs", "worst"]


@pytest.mark.parametrize("argv, words", [
    (["--robot", "stewart_6ups", "--pose", 0, 0, 400], "--pose (number 1): a 6-UPS takes 6 values"),
    (["--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0, "--samples", 10], "--samples: 10 is too few"),
    (["--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0, "--distribution", "boundary"],
     "--distribution: spatial robots take"),
    (["--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0, "--threshold", "dphi_deg=1"],
     "--threshold: dphi_deg is a planar quantity"),
    (["--robot", "stewart_6ups", "--phi-deg", 0, "--out", "x.nc"], "--phi-deg is not available for spatial"),
    (["--robot", "stewart_6ups"], "--pose: give one pose X Y Z ROLL PITCH YAW"),
    (["--robot", "delta_clavel", "--pose", 0, 0, -5000, "--samples", 1000], "--pose: the pose (x, y, z, roll, pitch, yaw) = (0, 0, -5000, 0, 0, 0) is outside the joint limits"),
    (["--robot", "stewart_6ups", "--pose", 0, 0, 0, 0, 0, 0, "--samples", 1000], "--pose: the pose (x, y, z, roll, pitch, yaw) = (0, 0, 0, 0, 0, 0) is outside the joint limits"),
    (["--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0, "--percentile", 100], "--percentile"),
    (["--pose", 0, 0, 0, 0], "--pose (number 1): a planar robot takes three values"),
    (["--pose", 0, 0, 0, "--threshold", "dz=1"], "--threshold: dz is a quantity of spatial robots"),
])
def test_cli_bad_input_one_line_status_2(argv, words, capsys):
    status, out, err = run_cli(["statistics", *argv], capsys)
    assert status == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and words in lines[0], err
    assert "Traceback" not in err


def test_cli_planar_pose_still_works(capsys):
    status, out, err = run_cli(["statistics", "--pose", 0, 0, 0, "--samples", 1000, "--format", "json"], capsys)
    assert status == 0, err
    assert set(json.loads(out)["quantities"]) == {"dx", "dy", "dp", "dphi_deg"}
