"""Spatial maps at scale (issue 37): Dask blocks give the numpy path's numbers, a Zarr store and a NetCDF file
read back equal the in-memory map, the memory check sends the user to a .zarr store, and the percentile maps
(pmaccuracy.accuracy.spatial_maps.spatial_percentile_map) agree with an independent Monte Carlo: the sources'
variables drawn here and mapped through the first-order map of tests/reference/spatial_error_reference.py
(central differences of the exact nonlinear loop closures, no pmaccuracy code), within the order-statistic
intervals of both."""

from __future__ import annotations

import math

import numpy as np
import pytest
import spatial_error_reference as eref
import spatial_reference as ref
import xarray as xr

import pmaccuracy as pm
from pmaccuracy.accuracy import spatial_maps as sm
from pmaccuracy.errors import ConfigError
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.model.spatial_sources import SpatialErrorSources


def _preset(name, clearances):
    robot = pm.load_robot(name)
    return robot, pm.load_clearances(clearances, robot)


# ------------------------------------------------------------------------------------------------ Dask
@pytest.mark.parametrize("name, clearances, n", [("stewart_6ups", "ups_typical", 5), ("rps_3", "rps_typical", 4)])
def test_dask_blocks_give_the_numpy_numbers(name, clearances, n):
    robot, sources = _preset(name, clearances)
    a = sm.spatial_error_map(robot, sources, n=n, block=7)
    b = sm.spatial_error_map(robot, sources, n=n, block=7, use_dask=True)
    xr.testing.assert_identical(a, b)
    assert int(a.dp_max.notnull().sum()) > 14          # a real workspace, three blocks or more
    # the grid and the points inside are the workspace's (its membership evaluated block by block here)
    region = pm.spatial_workspace(robot, n=n, tilt=False).region
    for d, axis in zip(a.dp_max.dims, region.axes):
        np.testing.assert_array_equal(a[d].values, axis)
    assert not np.any(np.isfinite(a.dp_max.values) & ~region.inside)
    assert np.isfinite(a.dp_max.values).sum() >= 0.9 * region.inside.sum()   # only near-singular points lost
    if name == "stewart_6ups":
        p = sm.spatial_percentile_map(robot, sources, n=4, samples=1000, block=5)
        q = sm.spatial_percentile_map(robot, sources, n=4, samples=1000, block=5, use_dask=True)
        xr.testing.assert_identical(p, q)


def test_a_distributed_client_gives_the_numpy_numbers():
    distributed = pytest.importorskip("distributed")
    robot, sources = _preset("stewart_6ups", "ups_typical")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        b = sm.spatial_error_map(robot, sources, n=5, block=17, use_dask=client)
    xr.testing.assert_identical(sm.spatial_error_map(robot, sources, n=5, block=17), b)


# ------------------------------------------------------------------------------------------------ files
@pytest.mark.parametrize("dask", [False, True])
def test_zarr_store_streamed_plane_by_plane_reads_back_as_the_map(tmp_path, monkeypatch, dask):
    zarr = pytest.importorskip("zarr")
    monkeypatch.setattr(sm, "ZARR_POINTS", 40)           # one grid plane per chunk: six slabs for n = 6
    robot, sources = _preset("upu_3", "upu_typical")
    path = tmp_path / "m.zarr"
    ranges = sm.write_spatial_map(path, robot, sources, n=6, use_dask=dask, workers=2 if dask else None)
    mem = sm.spatial_error_map(robot, sources, n=6)
    with xr.open_zarr(path) as ds:
        xr.testing.assert_identical(ds.load(), mem)
    assert zarr.open_group(str(path), mode="r")["dp_max"].chunks == (1, 6, 6)
    for name, (lo, hi) in ranges.items():
        assert (lo, hi) == (float(mem[name].min()), float(mem[name].max())), name


def test_percentile_map_to_zarr_and_netcdf(tmp_path, monkeypatch):
    pytest.importorskip("zarr")
    monkeypatch.setattr(sm, "ZARR_POINTS", 40)
    robot, sources = _preset("upu_3", "upu_typical")
    kw = dict(n=4, samples=1000, seed=2, percentiles=(95.0, 99.0), thresholds={"dp": 0.05, "dtheta_deg": 0.01})
    mem = sm.spatial_percentile_map(robot, sources, **kw)
    sm.write_spatial_map(tmp_path / "p.zarr", robot, sources, use_dask=True, **kw)
    sm.write_spatial_map(tmp_path / "p.nc", robot, sources, **kw)
    with xr.open_zarr(tmp_path / "p.zarr") as z, xr.open_dataset(tmp_path / "p.nc") as c:
        xr.testing.assert_equal(z.load(), mem)
        xr.testing.assert_equal(c.load(), mem)
        for key in ("dp_p95_error", "dtheta_p99_error"):    # the Monte Carlo errors, gathered slab by slab
            assert z.attrs[key] == mem.attrs[key] == c.attrs[key] and mem.attrs[key] > 0
    assert {"dp_exceed", "dtheta_exceed", "drz_p99", "dz_rss", "dx_std", "dp_max"} <= set(mem.data_vars)
    assert "dx_exceed" not in mem.data_vars
    # the threshold is in deg on input, rad in the map: the exceedance counts |dtheta| > 0.01 deg
    assert mem.attrs["dtheta_threshold"] == pytest.approx(math.radians(0.01))


def test_memory_check_sends_to_a_zarr_store(tmp_path, monkeypatch):
    robot, sources = _preset("upu_3", "upu_typical")
    monkeypatch.setattr(sm, "available_memory", lambda: 10_000)      # 10 kB free
    for call in (lambda: sm.spatial_error_map(robot, sources, n=8),
                 lambda: sm.spatial_percentile_map(robot, sources, n=8, samples=1000),
                 lambda: sm.write_spatial_map(tmp_path / "m.nc", robot, sources, n=8)):
        with pytest.raises(ConfigError, match=r"8 x 8 x 8 spatial map needs about .* \(--out FILE\.zarr\)") as e:
            call()
        assert e.value.key == "grid"
    # a Zarr store streams: no whole-map allocation, no refusal
    pytest.importorskip("zarr")
    ranges = sm.write_spatial_map(tmp_path / "m.zarr", robot, sources, n=8)
    assert ranges["dp_max"][1] > 0
    monkeypatch.setattr(sm, "available_memory", lambda: None)         # unknown: no refusal
    sm.check_spatial_fits_in_memory(1000)


@pytest.mark.parametrize("call, key", [
    (lambda r, s, p: sm.write_spatial_map(p / "m.csv", r, s, n=4), None),
    (lambda r, s, p: sm.spatial_error_map(r, s, n=4, use_dask="yes"), "use_dask"),
    (lambda r, s, p: sm.spatial_error_map(r, s, n=4, block=0), "block"),
    (lambda r, s, p: sm.spatial_error_map(r, s, n=1), "n"),
    (lambda r, s, p: sm.spatial_percentile_map(r, s, n=4, percentiles=(100,)), "percentiles"),
    (lambda r, s, p: sm.spatial_percentile_map(r, s, n=4, samples=10), "samples"),
    (lambda r, s, p: sm.spatial_percentile_map(r, s, n=4, distribution="cauchy"), "distribution"),
    (lambda r, s, p: sm.spatial_percentile_map(r, s, n=4, thresholds={"dphi": 1.0}), "thresholds"),
    (lambda r, s, p: sm.spatial_error_map(r, pm.load_clearances("upu_typical", pm.load_robot("upu_3")), n=4),
     "sources"),
])
def test_bad_input(call, key, tmp_path):
    robot, sources = _preset("stewart_6ups", "ups_typical")
    with pytest.raises(ConfigError) as e:
        call(robot, sources, tmp_path)
    assert e.value.key == key


# ------------------------------------------------------------------------------------------------ percentiles
def _draw(srcs, n, rng):
    """The sources' variables ``(n, m)`` (mm, rad), each source uniform in its own set of radius h: a segment,
    a disc (by area) or a ball (by volume), independently (written here from the definition)."""
    m = sum(eref.SHAPE_DIM[s["shape"]] for s in srcs)
    X = np.zeros((n, m))
    for s in srcs:
        d, h = eref.SHAPE_DIM[s["shape"]], s["half_width"]
        if d == 1:
            X[:, s["columns"]] = rng.uniform(-h, h, (n, 1))
            continue
        g = rng.standard_normal((n, d))
        X[:, s["columns"]] = h * (rng.random(n) ** (1.0 / d))[:, None] * g / np.linalg.norm(g, axis=1)[:, None]
    return X


def _interval_half_width(sorted_abs, p):
    """Half-width of the distribution-free 95 % interval of the p-quantile (ranks n p -+ 1.96 sqrt(n p (1-p)))."""
    n = len(sorted_abs)
    r = 1.96 * math.sqrt(n * p * (1 - p))
    lo, hi = max(int(math.floor(n * p - r)), 0), min(int(math.ceil(n * p + r)), n - 1)
    return 0.5 * (sorted_abs[hi] - sorted_abs[lo])


def _pick(ds, count, var="dp_p95"):
    """Inside grid points: the first, the last and the middle ones (indices)."""
    idx = np.argwhere(np.isfinite(ds[var].values))
    return [tuple(idx[k]) for k in np.linspace(0, len(idx) - 1, count).round().astype(int)]


@pytest.mark.parametrize("arch, points", [("6-UPS", 2), ("3-RPS", 1)])
def test_percentile_map_against_an_independent_monte_carlo(arch, points):
    robot_dict, cl_dict = ref.load_reference(arch), eref.load_clearances(arch)
    robot = SpatialManipulator.from_dict(robot_dict, source="r.toml")
    sources = SpatialErrorSources.from_dict(cl_dict, robot, source="c.toml")
    n_samples = 4000
    ds = sm.spatial_percentile_map(robot, sources, n=5, samples=n_samples, seed=11, percentiles=(95.0, 99.0))
    rng = np.random.default_rng(2024)
    for where in _pick(ds, points):
        c = [float(ds[d].values[i]) for d, i in zip(ds.dp_p95.dims, where)]
        if arch == "3-RPS":    # (roll deg, pitch deg, z mm): the parasitic x, y, yaw by the reference
            p, R = ref.complete_pose(robot_dict, c[2], math.radians(c[0]), math.radians(c[1]))
        else:
            p, R = np.array(c), np.eye(3)
        M, srcs = eref.sensitivity(robot_dict, cl_dict, p, R)
        T = _draw(srcs, n_samples, rng) @ M.T
        values = {"dx": T[:, 0], "dz": T[:, 2], "drz": T[:, 5], "dp": np.linalg.norm(T[:, :3], axis=1),
                  "dtheta": np.linalg.norm(T[:, 3:], axis=1)}
        # the exact root mean squares from the reference's first-order map (uniform: Var = h^2 / (d + 2))
        var = np.zeros(6)
        for s in srcs:
            var += s["half_width"] ** 2 / (eref.SHAPE_DIM[s["shape"]] + 2) * (M[:, s["columns"]] ** 2).sum(axis=1)
        exact = {"dx": math.sqrt(var[0]), "dz": math.sqrt(var[2]), "drz": math.sqrt(var[5]),
                 "dp": math.sqrt(var[:3].sum()), "dtheta": math.sqrt(var[3:].sum())}
        for q, v in values.items():
            a = np.sort(np.abs(v))
            assert float(ds[f"{q}_rss"].values[where]) == pytest.approx(exact[q], rel=1e-5), (arch, q)
            for pc in (95, 99):
                mine, theirs = float(ds[f"{q}_p{pc}"].values[where]), float(np.quantile(a, pc / 100))
                tol = 2 * _interval_half_width(a, pc / 100)      # both intervals (the same n)
                assert abs(mine - theirs) <= tol, (arch, where, q, pc, mine, theirs, tol)
            assert float(ds[f"{q}_p99"].values[where]) <= float(ds[f"{q}_max"].values[where])


def test_percentile_map_is_the_pose_statistics_at_each_point():
    # the same source states at every point: the numbers of spatial_pose_statistics there with the same seed
    robot, sources = _preset("prs_3", "prs_typical")
    ds = sm.spatial_percentile_map(robot, sources, n=4, samples=1500, seed=5, percentiles=(90.0,))
    where = _pick(ds, 1, "dp_p90")[0]
    c = np.array([float(ds[d].values[i]) for d, i in zip(ds.dp_p90.dims, where)])
    pose = pm.complete_poses(robot, np.array([c[2], math.radians(c[0]), math.radians(c[1])]))
    st = pm.spatial_pose_statistics(robot, sources, pose, samples=1500, seed=5, percentiles=(90.0,)).quantities
    for q, key, scale in (("dp", "dp", 1.0), ("dtheta", "dtheta_deg", math.degrees(1)), ("dy", "dy", 1.0)):
        assert float(ds[f"{q}_p90"].values[where]) * scale == pytest.approx(st[key]["p90"], rel=1e-9)
        assert float(ds[f"{q}_std"].values[where]) * scale == pytest.approx(st[key]["std"], rel=1e-9)


@pytest.mark.slow
def test_a_chain_robots_map_with_dask_and_its_percentiles():
    # a 3-UPU written as joint chains (tests/reference/chain_builders.py): the same machinery, slower kernels
    from chain_builders import chain_table

    upu = pm.load_robot("upu_3")
    chain = SpatialManipulator.from_dict(chain_table(upu), "chain.toml")
    sources = SpatialErrorSources.from_dict(pm.load_clearances("upu_typical", upu).to_dict(), chain)
    a = sm.spatial_error_map(chain, sources, n=4, block=20)
    xr.testing.assert_identical(a, sm.spatial_error_map(chain, sources, n=4, block=20, use_dask=True))
    assert int(a.dp_max.notnull().sum()) > 0
    p = sm.spatial_percentile_map(chain, sources, n=4, samples=1000)
    inside = np.isfinite(p.dp_max.values)
    assert np.all(p.dp_p95.values[inside] <= p.dp_max.values[inside])
