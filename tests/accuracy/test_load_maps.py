"""Loaded maps over the workspace (issue 24, deliverable 4): one wrench, and a box of process wrenches.

Independent references, written here without ``pmaccuracy.accuracy.loads``' map code:
- the first-order loaded error at a grid pose is the vertex of the error zonotope (generators from
  ``max_pose_errors(details=True)``) maximizing the load's virtual work ``W . dX`` (brute force over the eight
  sign vertices), and the leg intensities solve ``A^T lambda = -W`` with the rows ``A`` from the exact
  forward kinematics' virtual work: checked through ``loaded_pose_error`` in ``test_loads.py``, here the map
  must hold the same numbers at its grid poses and NaN exactly where ``error_map`` is NaN;
- the range over a wrench box against a dense sample of the box (each sample wrench's loaded error, brute
  force over the vertices as above; a leg with ``|lambda| <= threshold`` spans its generator), and the flips
  against the intensities' extremes over the box's eight corners (``lambda`` is linear in ``W``).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.accuracy.loads import Load, loaded_error_map, wrench_rows, wrench_set_errors, wrench_set_map
from pmaccuracy.accuracy.maps import error_map
from pmaccuracy.accuracy.regions import Disc

ROBOTS = [("aalborg_3ppr", "case2"), ("symmetric_3rpr", "rpr_typical"), ("symmetric_3rrr", "rrr_typical"),
          ("symmetric_3prr", "prr_typical")]
VERTICES = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))


def brute_loaded(G: np.ndarray, W: np.ndarray) -> np.ndarray:
    """First-order loaded error ``(3,)``: the vertex of the zonotope with generators ``G`` (columns) maximizing
    ``W . dX``; requires a unique maximizer."""
    points = VERTICES @ G.T
    work = points @ W
    best = np.flatnonzero(work >= work.max() - 1e-9 * np.abs(work).max())
    assert len(best) == 1
    return points[best[0]]


@pytest.mark.parametrize("name, clear", ROBOTS)
def test_loaded_map_has_the_grid_of_error_map_and_the_support_points_of_the_error_set(name, clear):
    load = Load(fx=4.0, fy=-7.0, m=55.0)
    phi = math.radians(5.0)
    ds = loaded_error_map(name, clear, load, phi, n=9, exact=True)
    ref = error_map(name, clear, phi, n=9)
    for c in ("phi", "y", "x"):
        np.testing.assert_array_equal(ds[c].values, ref[c].values)
    assert ds.dx.dims == ("phi", "y", "x") and ds.dx.attrs["units"] == "mm" and ds.dphi.attrs["units"] == "deg"
    np.testing.assert_array_equal(np.isnan(ds.dx.values), np.isnan(ref.dx_max.values))
    X, Y = np.meshgrid(ds.x.values, ds.y.values)
    ok = np.isfinite(ds.dx.values[0])
    poses = np.column_stack([X[ok], Y[ok], np.full(int(ok.sum()), phi)])
    G = max_pose_errors(name, clear, poses, details=True).generators
    W = load.wrench(poses[0])
    got = np.column_stack([ds.dx.values[0][ok], ds.dy.values[0][ok], np.radians(ds.dphi.values[0][ok])])
    for k in range(len(poses)):
        np.testing.assert_allclose(got[k], brute_loaded(G[k], W), rtol=1e-9, atol=1e-14)
    assert np.all(ds.unloaded_legs.values[0][ok] == 0) and np.all(ds.dx_spread.values[0][ok] == 0)
    np.testing.assert_allclose(ds.dp.values, np.hypot(ds.dx.values, ds.dy.values))
    # exact: second-order close to the first-order map
    size = np.nanmax(np.abs(ds.dx.values))
    assert np.nanmax(np.abs(ds.dx_exact.values - ds.dx.values)) < 0.05 * size


def test_loaded_map_reports_the_unloaded_leg_and_its_spread():
    """A push along -y leaves the 3-PPR's x-fixing leg unloaded everywhere: x is a range of half-width |g_3|."""
    ds = loaded_error_map("aalborg_3ppr", "case2", Load(fy=-20.0), 0.0, n=5)
    assert np.all(ds.unloaded_legs.values == 1)
    poses = np.array([[x, y, 0.0] for y in ds.y.values for x in ds.x.values])
    G = max_pose_errors("aalborg_3ppr", "case2", poses, details=True).generators
    np.testing.assert_allclose(ds.dx_spread.values.ravel(), np.abs(G[:, 0, 2]), rtol=1e-12)


def test_loaded_map_region_and_bad_input():
    from pmaccuracy.errors import ConfigError, EmptyWorkspaceError

    disc = Disc((5.0, 0.0), 6.0)
    ds = loaded_error_map("symmetric_3rpr", "rpr_typical", Load(fx=3.0), 0.0, n=11, region=disc)
    X, Y = np.meshgrid(ds.x.values, ds.y.values)
    inside = (X - 5.0) ** 2 + Y ** 2 <= 36.0 * (1 + 1e-12)
    assert np.all(np.isnan(ds.dx.values[0][~inside])) and np.isfinite(ds.dx.values[0][inside]).any()
    assert "region" in ds.attrs
    with pytest.raises(ConfigError):
        loaded_error_map("symmetric_3rpr", "rpr_typical", "fx=3", 0.0, n=5)
    with pytest.raises(ConfigError):
        wrench_set_map("symmetric_3rpr", "rpr_typical", [0, 0, 0], [-1, 0, 0], 0.0, n=5)
    with pytest.raises(EmptyWorkspaceError):
        loaded_error_map("symmetric_3rpr", "rpr_typical", Load(fx=3.0), 0.0, n=5, region=Disc((1e4, 0.0), 1.0))


@pytest.mark.parametrize("name, clear", ROBOTS)
def test_wrench_set_map_against_a_dense_sample_of_the_box(name, clear):
    center, half = np.array([3.0, -12.0, 20.0]), np.array([2.0, 5.0, 60.0])
    phi = math.radians(5.0)
    ds = wrench_set_map(name, clear, center, half, phi, n=7)
    X, Y = np.meshgrid(ds.x.values, ds.y.values)
    ok = np.isfinite(ds.dx_lo.values[0])
    poses = np.column_stack([X[ok], Y[ok], np.full(int(ok.sum()), phi)])
    b = max_pose_errors(name, clear, poses, details=True)
    G = b.generators
    A = wrench_rows(name, poses)          # the legs' wrenches: checked by virtual work in test_loads.py
    grid = np.linspace(-1.0, 1.0, 9)
    sample = np.array(np.meshgrid(grid, grid, grid)).reshape(3, -1).T * half + center
    lam = -np.einsum("nij,wj->nwi", np.linalg.inv(np.swapaxes(A, -1, -2)), sample)      # A^T lambda = -W
    lo, hi = ds[["dx_lo", "dy_lo", "dphi_lo"]], ds[["dx_hi", "dy_hi", "dphi_hi"]]
    lo = np.column_stack([lo.dx_lo.values[0][ok], lo.dy_lo.values[0][ok], np.radians(lo.dphi_lo.values[0][ok])])
    hi = np.column_stack([hi.dx_hi.values[0][ok], hi.dy_hi.values[0][ok], np.radians(hi.dphi_hi.values[0][ok])])
    flips = np.column_stack([ds[f"flip{i}"].values[0][ok] for i in (1, 2, 3)]).astype(bool)
    for k in range(len(poses)):
        t = -np.sign(lam[k])                                              # (w, 3) contact sides
        errs = t @ G[k].T                                                 # (w, 3)
        slo, shi = errs.min(axis=0), errs.max(axis=0)
        tol = 1e-12 + 1e-9 * np.abs(G[k]).sum(axis=1)
        assert np.all(lo[k] <= slo + tol) and np.all(shi <= hi[k] + tol), (k, lo[k], slo, hi[k], shi)
        # flips: the intensity's range over the box (extremes at its corners) reaches zero
        corners = VERTICES * half + center
        lc = -np.linalg.solve(A[k].T, corners.T).T                         # (8, 3)
        crosses = (lc.min(axis=0) <= 1e-6) & (lc.max(axis=0) >= -1e-6)
        np.testing.assert_array_equal(flips[k], crosses)
        # tight: the range is reached by the sample up to the legs that flip inside it
        if not np.any(crosses & ~((t > 0).any(axis=0) & (t < 0).any(axis=0))):
            np.testing.assert_allclose(lo[k], slo, rtol=1e-9, atol=1e-14)
            np.testing.assert_allclose(hi[k], shi, rtol=1e-9, atol=1e-14)
    np.testing.assert_array_equal(ds.flipping_legs.values[0][ok], flips.sum(axis=1))
    assert 0 < np.mean(flips) < 1                                         # the box flips some legs, not all


def lp_range(name, clear, poses, center, half, threshold=1e-6):
    """Reference range and flips by linear programming, written here: pattern ``s`` is possible at a pose iff
    ``max t`` s.t. ``s_i lambda_i(W) >= t``, ``W`` in the box, has ``t >= -threshold`` (scipy HiGHS)."""
    from scipy.optimize import linprog

    A = wrench_rows(name, poses)
    G = max_pose_errors(name, clear, poses, details=True).generators
    lo, hi = np.full((len(poses), 3), np.inf), np.full((len(poses), 3), -np.inf)
    sides = np.zeros((len(poses), 3, 2), dtype=bool)
    for n in range(len(poses)):
        Lm = -np.linalg.inv(A[n].T)                     # lambda = Lm W
        for s in VERTICES:
            A_ub = np.column_stack([-(s[:, None] * Lm), np.ones(3)])
            res = linprog([0, 0, 0, -1.0], A_ub=A_ub, b_ub=np.zeros(3),
                          bounds=[(c - h, c + h) for c, h in zip(center, half)] + [(None, 1e9)], method="highs")
            if res.status == 0 and -res.fun >= -threshold:
                e = G[n] @ (-s)
                lo[n], hi[n] = np.minimum(lo[n], e), np.maximum(hi[n], e)
                sides[n, :, 0] |= s > 0
                sides[n, :, 1] |= s < 0
    return lo, hi, sides.all(axis=-1)


@pytest.mark.parametrize("center, half", [([1.0, -8.0, 0.0], [3.0, 3.0, 40.0]), ([0.0, -5.0, 0.0], [0.0, 5.0, 0.0])])
def test_wrench_set_map_and_errors_agree_with_linear_programs(center, half):
    """The second box reaches every leg's zero on a face (fy = 0): every pattern is possible there."""
    center, half = np.array(center), np.array(half)
    ds = wrench_set_map("symmetric_3rrr", "rrr_typical", center, half, 0.1, n=6)
    X, Y = np.meshgrid(ds.x.values, ds.y.values)
    ok = np.isfinite(ds.dx_lo.values[0])
    poses = np.column_stack([X[ok], Y[ok], np.full(int(ok.sum()), 0.1)])
    lo, hi, flips_ref = lp_range("symmetric_3rrr", "rrr_typical", poses, center, half)
    got_lo = np.column_stack([ds.dx_lo.values[0][ok], ds.dy_lo.values[0][ok], np.radians(ds.dphi_lo.values[0][ok])])
    got_hi = np.column_stack([ds.dx_hi.values[0][ok], ds.dy_hi.values[0][ok], np.radians(ds.dphi_hi.values[0][ok])])
    np.testing.assert_allclose(got_lo, lo, rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(got_hi, hi, rtol=1e-9, atol=1e-14)
    flips = np.column_stack([ds[f"flip{i}"].values[0][ok] for i in (1, 2, 3)]).astype(bool)
    np.testing.assert_array_equal(flips, flips_ref)
    per_pose = wrench_set_errors("symmetric_3rrr", "rrr_typical", poses, center, half)
    np.testing.assert_allclose(per_pose.lower, lo, rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(per_pose.upper, hi, rtol=1e-9, atol=1e-14)
    np.testing.assert_array_equal(per_pose.flips, flips_ref)


def test_cli_load_and_preload_maps_write_the_library_maps(tmp_path, capsys):
    import csv
    import json

    import xarray as xr

    from pmaccuracy.cli import main

    out = tmp_path / "sub" / "l.nc"
    assert main(["load", "--map", "--grid", "7", "--phi-deg", "5", "--fx", "4", "--fy", "-7", "--m", "55",
                 "--robot", "symmetric_3rpr", "--clearances", "rpr_typical", "--out", str(out),
                 "--format", "json"]) == 0
    rows = {r["variable"]: r for r in json.loads(capsys.readouterr().out)}
    ref = loaded_error_map("symmetric_3rpr", "rpr_typical", Load(fx=4.0, fy=-7.0, m=55.0), math.radians(5.0), n=7)
    with xr.open_dataset(out, engine="scipy") as ds:
        np.testing.assert_array_equal(ds.dx.values, ref.dx.values)
        np.testing.assert_array_equal(ds.phi.values, [5.0])
    assert rows["dx"]["max"] == pytest.approx(float(ref.dx.max()))
    out = tmp_path / "w.csv"
    assert main(["preload", "--map", "--grid", "6", "--fx", "-2", "4", "--fy", "-17", "-7", "--m", "-40", "80",
                 "--robot", "symmetric_3rrr", "--clearances", "rrr_typical", "--out", str(out)]) == 0
    capsys.readouterr()
    ref = wrench_set_map("symmetric_3rrr", "rrr_typical", [1.0, -12.0, 20.0], [3.0, 5.0, 60.0], 0.0, n=6)
    with open(out, newline="") as fh:
        got = list(csv.DictReader(fh))
    assert len(got) == int(np.isfinite(ref.dx_lo.values).sum())
    assert float(got[0]["dx_lo"]) == pytest.approx(float(ref.dx_lo.values[np.isfinite(ref.dx_lo.values)][0]),
                                                   rel=1e-12)
    for argv, key in ((["load", "--map", "--fx", "1"], "--out"),
                      (["load", "--map", "--out", str(tmp_path / "a.nc")], "--fx"),
                      (["load", "--map", "--fx", "1", "--pose", "0", "0", "0", "--out", str(tmp_path / "a.nc")],
                       "--map"),
                      (["load", "--fx", "1", "--pose", "0", "0", "0", "--exact"], "--exact"),
                      (["load", "--map", "--fx", "1", "--out", str(tmp_path / "a.txt")], "--out"),
                      (["load", "--map", "--fx", "1", "--out", str(tmp_path / "a.nc"), "--disc", "1000", "0", "1"],
                       "--disc"),
                      (["preload", "--fx", "1", "2", "--pose", "0", "0", "0", "--disc", "0", "0", "5"], "--disc"),
                      (["preload", "--map", "--fx", "1", "2", "--grid", "1", "--out", str(tmp_path / "a.nc")],
                       "--grid")):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and key in err and "Traceback" not in err, (argv, err)
    assert not (tmp_path / "a.nc").exists()
