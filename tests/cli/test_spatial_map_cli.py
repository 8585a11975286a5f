"""``pmaccuracy map`` on spatial robots at scale (issue 37): .zarr streamed, --dask, percentile maps with the
planar statistics command's option names (--percentile, --samples, --seed, --distribution, --threshold), and
bad input in one line with status 2. The files are compared with the library's maps (whose numbers
tests/accuracy/test_spatial_maps_scale.py checks against independent references)."""

from __future__ import annotations

import json
import math

import pytest
import xarray as xr
from conftest import run_cli

import pmaccuracy as pm
from pmaccuracy.accuracy import spatial_maps as sm


def test_map_streams_a_zarr_store_with_dask(tmp_path, capsys):
    pytest.importorskip("zarr")
    out = tmp_path / "sub" / "m.zarr"
    status, text, err = run_cli(["map", "--robot", "stewart_6ups", "--grid", 5, "--out", out, "--dask",
                                 "--format", "json"], capsys)
    assert status == 0, err
    robot = pm.load_robot("stewart_6ups")
    mem = sm.spatial_error_map(robot, pm.load_clearances("ups_typical", robot), n=5)
    with xr.open_zarr(out) as ds:
        xr.testing.assert_equal(ds.load(), mem)
    rows = {r["quantity"]: r for r in json.loads(text)}
    assert rows["dp_max"]["max"] == float(mem.dp_max.max()) and rows["dp_max"]["unit"] == "mm"
    assert rows["drz_max_deg"]["min"] == pytest.approx(math.degrees(float(mem.drz_max.min())), rel=1e-12)


def test_map_percentile_map_as_netcdf(tmp_path, capsys):
    out = tmp_path / "p.nc"
    status, text, err = run_cli(["map", "--robot", "upu_3", "--grid", 4, "--out", out, "--percentile", 95,
                                 "--percentile", 99, "--samples", 1000, "--seed", 3, "--threshold", "dp=0.05",
                                 "--format", "json"], capsys)
    assert status == 0, err
    robot = pm.load_robot("upu_3")
    mem = sm.spatial_percentile_map(robot, pm.load_clearances("upu_typical", robot), n=4, samples=1000, seed=3,
                                    percentiles=(95, 99), thresholds={"dp": 0.05})
    with xr.open_dataset(out) as ds:
        xr.testing.assert_equal(ds.load(), mem)
    rows = {r["quantity"]: r for r in json.loads(text)}
    assert rows["dp_p99"]["max"] == float(mem.dp_p99.max())
    assert rows["dtheta_p95_deg"]["unit"] == "deg" and "dp_exceed" in rows


@pytest.mark.parametrize("argv, words", [
    (["--out", "x.nc", "--samples", 2000], "--samples: goes with --percentile"),
    (["--out", "x.nc", "--percentile", 95, "--samples", 10], "--samples: 10 is too few"),
    (["--out", "x.nc", "--percentile", 95, "--distribution", "cauchy"], "--distribution: spatial robots take"),
    (["--out", "x.nc", "--percentile", 95, "--threshold", "dphi_deg=1"], "--threshold: dphi_deg is a planar"),
    (["--out", "x.nc", "--percentile", 100], "--percentile: must lie strictly between 0 and 100"),
    (["--out", "x.nc", "--workers", 2], "--workers: applies to .zarr maps"),
    (["--out", "x.nc", "--scheduler", "nowhere"], "--scheduler: expected a dask.distributed scheduler address"),
    (["--out", "x.nc", "--tile", 4], "--tile is not available for spatial robots"),
    (["--out", "x.csv", "--percentile", 95], "a spatial map is written as .nc or .zarr"),
])
def test_bad_spatial_map_options_one_line(argv, words, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, out, err = run_cli(["map", "--robot", "stewart_6ups", "--grid", 5, *argv], capsys)
    lines = err.strip().splitlines()
    assert status == 2 and len(lines) == 1 and words in lines[0], err


def test_planar_map_refuses_the_percentile_options(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, out, err = run_cli(["map", "--robot", "aalborg_3ppr", "--phi-deg", 0, "--grid", 5, "--out", "x.nc",
                                "--percentile", 95], capsys)
    lines = err.strip().splitlines()
    assert status == 2 and len(lines) == 1 and "--percentile" in lines[0] and "statistics --phi-deg" in lines[0], err


def test_map_too_large_for_memory_says_zarr(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sm, "available_memory", lambda: 10_000)
    status, out, err = run_cli(["map", "--robot", "upu_3", "--grid", 8, "--out", "x.nc"], capsys)
    lines = err.strip().splitlines()
    assert status == 2 and len(lines) == 1, err
    assert "--grid:" in lines[0] and "--out FILE.zarr" in lines[0], err
    assert not (tmp_path / "x.nc").exists()


def test_spatial_statistics_with_out_points_to_the_percentile_map(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, out, err = run_cli(["statistics", "--robot", "upu_3", "--out", "p.nc"], capsys)
    lines = err.strip().splitlines()
    assert status == 2 and len(lines) == 1 and "pmaccuracy map --robot upu_3 --percentile P" in lines[0], err


def test_orientation_deg_is_roll_pitch_yaw_not_a_rotation_vector(tmp_path, capsys):
    """``map --orientation-deg R P Y`` maps at R = Rz(yaw) Ry(pitch) Rx(roll) (built here with scipy), the
    angles the option names, not at the rotation vector (R, P, Y)."""
    import numpy as np
    from scipy.spatial.transform import Rotation

    out = tmp_path / "m.nc"
    status, _, err = run_cli(["map", "--robot", "stewart_6ups", "--grid", 6, "--orientation-deg", 4, 3, 10,
                              "--out", out], capsys)
    assert status == 0, err
    robot = pm.load_robot("stewart_6ups")
    rotvec = Rotation.from_euler("xyz", [4, 3, 10], degrees=True).as_rotvec()
    assert not np.allclose(rotvec, np.radians([4, 3, 10]), atol=1e-4)       # the two readings differ here
    expected = sm.spatial_error_map(robot, pm.load_clearances("ups_typical", robot), n=6, orientation=rotvec)
    with xr.open_dataset(out) as got:
        np.testing.assert_allclose(got.dp_max.values, expected.dp_max.values, rtol=1e-12, equal_nan=True)
