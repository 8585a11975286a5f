"""``certified_error_map`` / ``map --certified`` (issue 27): the certified upper bounds and gaps on the grid of
``error_map``, checked against the independent dense nonlinear search (``nonlinear_search_reference``) at grid
points, against the first-order map (the same grid and NaN pattern; never below it) and through the CLI."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import xarray as xr

import nonlinear_search_reference as nsr
from pmaccuracy.accuracy.maps import certified_error_map, error_map
from pmaccuracy.model.manipulator import Manipulator
from test_certified import _paper_spec

PHIS = np.radians([0.0, 4.0])


@pytest.fixture(scope="module")
def maps():
    return certified_error_map("aalborg_3ppr", "case2", PHIS, n=5), error_map("aalborg_3ppr", "case2", PHIS, n=5)


def test_same_grid_and_workspace_as_the_first_order_map(maps):
    cert, first = maps
    assert cert.sizes == first.sizes
    for c in ("phi", "y", "x"):
        np.testing.assert_array_equal(cert[c].values, first[c].values)
    for v in ("dx_max", "dy_max", "dphi_max", "dp_max"):
        assert cert[v].attrs["units"] == first[v].attrs["units"]
        np.testing.assert_array_equal(np.isnan(cert[v].values), np.isnan(first[v].values))
        inside = np.isfinite(first[v].values)
        assert np.all(cert[v].values[inside] >= first[v].values[inside])
    for q in ("dx", "dy", "dphi", "dp"):  # the paper's clearances: within 0.5 % of the best feasible value
        g = cert[f"{q}_gap"].values
        assert np.all((g[np.isfinite(g)] >= 0) & (g[np.isfinite(g)] <= 0.005))
    assert "certified" in cert.attrs["method"]


def test_never_below_the_dense_search_at_grid_points(maps):
    cert, _ = maps
    data = Manipulator.preset("aalborg_3ppr").to_dict()
    spec = _paper_spec("case2")
    edge = np.argwhere(np.isfinite(cert.dx_max.values[1]))[0]  # a point on the workspace's boundary at 4 deg
    for k, iy, ix in ((0, 2, 2), (1, *edge)):
        pose = [float(cert.x[ix]), float(cert.y[iy]), float(PHIS[k])]
        ref = nsr.dense_search(data, pose, spec, n_random=200, dense=6)
        for q in ("dx", "dy", "dphi", "dp"):
            up = float(cert[f"{q}_max"].values[k, iy, ix])
            up = np.radians(up) if q == "dphi" else up
            assert ref[q] <= up <= ref[q] * 1.005, (q, pose, up, ref[q])


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "pmaccuracy.cli", "map", *args], capture_output=True, text=True)


def test_cli_certified_nc_and_zarr(tmp_path, maps):
    cert, _ = maps
    common = ["--robot", "aalborg_3ppr", "--clearances", "case2", "--phi-deg", "0", "--phi-deg", "4", "--grid", "5",
              "--certified", "--format", "json"]
    out = _cli(*common, "--out", str(tmp_path / "m.nc"))
    assert out.returncode == 0, out.stderr
    rows = json.loads(out.stdout)
    assert [r["phi_deg"] for r in rows] == [0.0, 4.0] and set(rows[0]["largest_gap"]) == {"dx", "dy", "dphi", "dp"}
    with xr.open_dataset(tmp_path / "m.nc", engine="scipy") as ds:
        np.testing.assert_allclose(ds.dp_max.values, cert.dp_max.values, rtol=1e-12)
        assert set(ds.data_vars) >= {"dx_gap", "dp_gap"}
    out = _cli(*common, "--dask", "--tile", "3", "--out", str(tmp_path / "m.zarr"))
    assert out.returncode == 0, out.stderr
    with xr.open_zarr(tmp_path / "m.zarr") as ds:
        assert ds.dx_max.encoding["chunks"] == (1, 3, 3)
        np.testing.assert_allclose(ds.dx_max.values, cert.dx_max.values, rtol=1e-12)


def test_cli_certified_refuses_csv(tmp_path):
    out = _cli("--phi-deg", "0", "--grid", "5", "--certified", "--out", str(tmp_path / "m.csv"))
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1 and "--out" in out.stderr
    assert not (tmp_path / "m.csv").exists()
