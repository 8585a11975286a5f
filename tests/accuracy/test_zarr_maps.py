"""Maps streamed to Zarr (:func:`pmaccuracy.accuracy.maps.write_zarr_map`, ``pmaccuracy map --out X.zarr``).

The store is compared with the in-memory map of :func:`pmaccuracy.accuracy.maps.error_map`
(itself checked point by point against the bounds in ``test_maps.py``) and with
the NetCDF file of the same map (attributes). Resumption: a run killed by a
failing tile leaves the finished tiles recorded; the next run computes only the
others (counted through the tile function) and the store equals the in-memory map.
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from pmaccuracy.accuracy import maps
from pmaccuracy.errors import ConfigError
from pmaccuracy.accuracy.maps import error_map, load_map, save_map, write_zarr_map, zarr_progress
from conftest import run_cli

PHIS = np.radians([0.0, 30.0])
N, TILE = 23, 8  # 2 x 3 x 3 = 18 tiles, the last row and column of tiles partial


@pytest.fixture(scope="module")
def memory_map() -> xr.Dataset:
    return error_map("aalborg_3ppr", "case2", PHIS, N)


def test_store_equals_in_memory_map_and_netcdf_attributes(tmp_path, memory_map):
    result = write_zarr_map(tmp_path / "m.zarr", "aalborg_3ppr", "case2", PHIS, N, tile=TILE,
                            scheduler="synchronous")
    assert result["tiles"] == 18 and result["computed"] == 18 and result["resumed"] == 0
    with xr.open_zarr(tmp_path / "m.zarr") as z:
        assert z.chunks["phi"] == (1, 1) and z.chunks["y"] == (8, 8, 7) and z.chunks["x"] == (8, 8, 7)
        xr.testing.assert_identical(z.load(), memory_map)
    nc = load_map(save_map(memory_map, tmp_path / "m.nc"))
    with xr.open_zarr(tmp_path / "m.zarr") as z:
        assert z.attrs == nc.attrs
        for name in maps.MAP_VARIABLES:
            assert z[name].attrs == nc[name].attrs
    assert result["summary"] == maps.summarize(memory_map)  # ranges from the tiles' records


def test_interrupted_run_resumes_without_recomputing(tmp_path, memory_map, monkeypatch):
    path = tmp_path / "m.zarr"
    real = maps._zarr_tile
    calls = []

    def failing_after_five(*args, **kwargs):
        if len(calls) == 5:
            raise KeyboardInterrupt("simulated interruption")
        calls.append(args[1:4])
        return real(*args, **kwargs)

    monkeypatch.setattr(maps, "_zarr_tile", failing_after_five)
    with pytest.raises(KeyboardInterrupt):
        write_zarr_map(path, "aalborg_3ppr", "case2", PHIS, N, tile=TILE, scheduler="synchronous")
    record = zarr_progress(path)
    done = {tuple(t) for t in np.argwhere(~np.isnan(record[..., 0])).tolist()}
    assert done == set(calls) and len(done) == 5

    resumed = []

    def counting(*args, **kwargs):
        resumed.append(args[1:4])
        return real(*args, **kwargs)

    monkeypatch.setattr(maps, "_zarr_tile", counting)
    result = write_zarr_map(path, "aalborg_3ppr", "case2", PHIS, N, tile=TILE, scheduler="synchronous")
    assert result["resumed"] == 5 and result["computed"] == 13
    assert len(resumed) == 13 and not done & set(resumed)  # no finished tile computed twice
    with xr.open_zarr(path) as z:
        xr.testing.assert_identical(z.load(), memory_map)
    # a finished store: nothing left to compute
    assert write_zarr_map(path, "aalborg_3ppr", "case2", PHIS, N, tile=TILE, scheduler="synchronous")["computed"] == 0


def test_other_inputs_or_foreign_folder_refused(tmp_path):
    path = tmp_path / "m.zarr"
    write_zarr_map(path, "aalborg_3ppr", "case1", 0.0, 9, tile=4, scheduler="synchronous")
    with pytest.raises(ConfigError, match="another"):
        write_zarr_map(path, "aalborg_3ppr", "case2", 0.0, 9, tile=4, scheduler="synchronous")
    with pytest.raises(ConfigError, match="another"):
        write_zarr_map(path, "aalborg_3ppr", "case1", 0.0, 9, tile=5, scheduler="synchronous")
    other = tmp_path / "other.zarr"
    other.mkdir()
    with pytest.raises(ConfigError, match="not a resumable"):
        write_zarr_map(other, "aalborg_3ppr", "case1", 0.0, 9, tile=4)


def _run(argv, capsys):
    return run_cli(argv, capsys)


def test_cli_zarr_threads_in_new_folder(tmp_path, capsys, memory_map):
    out = tmp_path / "new" / "deeper" / "m.zarr"
    status, stdout, err = _run(["map", "--clearances", "case2", "--phi-deg", 0, "--phi-deg", 30, "--grid", N,
                                "--tile", TILE, "--workers", 2, "--out", out, "--format", "json", "--no-progress"],
                               capsys)
    assert status == 0, err
    with xr.open_zarr(out) as z:
        xr.testing.assert_identical(z.load(), memory_map)
    assert '"phi_deg": 30.0' in stdout


def test_cli_refuses_in_memory_map_that_does_not_fit(tmp_path, capsys):
    """50 GB would not fit on a test machine's memory in any case: refused at once, nothing written."""
    status, stdout, err = _run(["map", "--phi-deg", 0, "--phi-deg", 30, "--phi-deg", -30, "--grid", 400_000,
                                "--out", tmp_path / "sub" / "big.nc"], capsys)
    assert status == 2 and stdout == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and ".zarr" in lines[0] and "GB" in lines[0], err
    assert not (tmp_path / "sub").exists()


def test_cli_unwritable_output(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    status, stdout, err = _run(["map", "--phi-deg", 0, "--grid", 5, "--out", blocker / "m.nc"], capsys)
    assert status == 2 and len(err.strip().splitlines()) == 1 and "folder" in err, err
