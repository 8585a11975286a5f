"""Maps computed straight into their file (:func:`pmaccuracy.accuracy.maps.write_map`, the ``map`` command's path).

The reference is the in-memory path, written independently of the streamed one: ``error_map`` builds the
whole ``xarray.Dataset`` and ``save_map`` hands it to xarray's own NetCDF-3 writer (through scipy) or to the
CSV writer. The streamed file must be the same bytes, read back the same through ``xarray.open_dataset`` and
scipy's reader, and give the same ranges as :func:`summarize`. No test here measures memory or time.
"""

from __future__ import annotations

import traceback

import numpy as np
import pytest
import xarray as xr
from scipy.io import netcdf_file

from pmaccuracy.accuracy import maps as M
from pmaccuracy.cli import main
from pmaccuracy.errors import ConfigError, EmptyWorkspaceError

CASES = [  # robot, clearances, orientations (deg), grid, chunk size (grid points a block)
    ("aalborg_3ppr", "case1", [0.0, 30.0], 23, 50),        # several rows a block, a last short block
    ("aalborg_3ppr", "case2", [30.0], 17, 1),              # one row a block, one orientation
    ("aalborg_3ppr", "case1", [0.0, 30.0, -30.0], 40, M.DEFAULT_CHUNK),  # the whole layer in one block
    ("symmetric_3rrr", "rrr_typical", [0.0, 10.0], 31, 100),  # NaN inside the workspace (singular curves)
]
IDS = ["3ppr-2phi", "3ppr-rows", "3ppr-3phi", "3rrr"]


@pytest.mark.parametrize("robot, clearances, phis_deg, n, chunk", CASES, ids=IDS)
def test_streamed_files_are_the_in_memory_writers_files(tmp_path, robot, clearances, phis_deg, n, chunk):
    phis = np.radians(phis_deg)
    ds = M.error_map(robot, clearances, phis, n, progress=False)
    for suffix in (".nc", ".csv"):
        reference = M.save_map(ds, tmp_path / f"reference{suffix}").read_bytes()
        ranges = M.write_map(tmp_path / f"streamed{suffix}", robot, clearances, phis, n, chunk_size=chunk,
                             progress=False)
        assert (tmp_path / f"streamed{suffix}").read_bytes() == reference, suffix
        assert ranges == M.summarize(ds)
    assert [p.name for p in tmp_path.iterdir() if "partial" in p.name] == []


def test_streamed_netcdf_reads_back_as_the_map(tmp_path):
    """Through xarray (values, NaN, coordinates, attributes, dtype and encoding) and through scipy's reader."""
    phis = np.radians([0.0, 30.0])
    ds = M.error_map("aalborg_3ppr", "case1", phis, 19, progress=False)
    M.save_map(ds, tmp_path / "reference.nc")
    M.write_map(tmp_path / "streamed.nc", "aalborg_3ppr", "case1", phis, 19, chunk_size=40, progress=False)
    assert M.load_map(tmp_path / "streamed.nc").identical(ds)
    with xr.open_dataset(tmp_path / "streamed.nc") as got, xr.open_dataset(tmp_path / "reference.nc") as ref:
        assert got.identical(ref)
        for name in ref.variables:
            assert got[name].dtype == ref[name].dtype == np.float64, name
            enc, ref_enc = got[name].encoding, ref[name].encoding
            assert enc["dtype"] == ref_enc["dtype"] == np.float64, name
            assert np.isnan(enc["_FillValue"]) and np.isnan(ref_enc["_FillValue"]), name
            assert set(enc) == set(ref_enc), name
    f = netcdf_file(tmp_path / "streamed.nc", "r", mmap=False)
    try:
        assert f.version_byte == 2
        assert dict(f.dimensions) == {"phi": 2, "y": 19, "x": 19}
        for name in M.MAP_VARIABLES:
            var = f.variables[name]
            assert var.dimensions == ("phi", "y", "x") and var.data.dtype == np.dtype(">f8")
            assert np.array_equal(var.data, ds[name].values, equal_nan=True)
            assert np.isnan(var._FillValue)
        assert np.array_equal(f.variables["phi"].data, [0.0, 30.0])
    finally:
        f.close()


def test_an_empty_layer_leaves_the_existing_file_untouched(tmp_path):
    for suffix in (".nc", ".csv"):
        path = tmp_path / f"m{suffix}"
        path.write_text("an older map")
        with pytest.raises(EmptyWorkspaceError, match="phi = 30 deg"):
            M.write_map(path, "aalborg_3ppr", "case1", np.radians([0.0, 30.0]), 2, progress=False)
        assert path.read_text() == "an older map"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.csv", "m.nc"]


@pytest.mark.filterwarnings("ignore::pmaccuracy.model.plausibility.PlausibilityWarning")
def test_overflowing_errors_write_nothing(tmp_path):
    huge = tmp_path / "huge.toml"
    huge.write_text("name = 'huge'\n" + "[[legs]]\nbearing_angle = 1e305\n" * 3)
    for suffix in (".nc", ".csv"):
        with pytest.raises(ConfigError, match="overflow") as info:
            M.write_map(tmp_path / f"m{suffix}", "aalborg_3ppr", str(huge), 0.0, 5, progress=False)
        assert info.value.key == "clearances"
    assert [p.name for p in tmp_path.iterdir()] == ["huge.toml"]


def _no_computing(monkeypatch):
    def explode(*args, **kwargs):
        raise AssertionError("computed before the inputs were checked")

    monkeypatch.setattr(M, "_rows_block", explode)


def test_refusals_before_computing(tmp_path, monkeypatch):
    _no_computing(monkeypatch)
    with pytest.raises(ConfigError, match="use .nc or .csv"):
        M.write_map(tmp_path / "m.txt", "aalborg_3ppr", "case1", 0.0, 5)
    with pytest.raises(ConfigError, match="4 GiB"):
        M.write_map(tmp_path / "m.nc", "aalborg_3ppr", "case1", np.radians([0.0, 30.0]), 20_000)
    with pytest.raises(ConfigError, match="chunk size"):
        M.write_map(tmp_path / "m.csv", "aalborg_3ppr", "case1", 0.0, 5, chunk_size=0)
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------------------------- the command
def run(argv, capsys):
    try:
        status = main([str(a) for a in argv])
    except SystemExit as exc:
        status = exc.code
    except Exception:  # noqa: BLE001 - reported through the assertions
        out = capsys.readouterr()
        return "exception", out.out, out.err + traceback.format_exc()
    out = capsys.readouterr()
    return status, out.out, out.err


def test_map_command_writes_the_in_memory_writers_files(tmp_path, capsys):
    """``map --out FILE.nc|.csv`` streams; ``.csv`` with ``--plot`` is assembled in memory: all the same bytes."""
    ds = M.error_map("aalborg_3ppr", "case1", np.radians([0.0, 30.0]), 21, progress=False)
    base = ["map", "--robot", "aalborg_3ppr", "--clearances", "case1", "--phi-deg", 0, "--phi-deg", 30,
            "--grid", 21, "--chunk-size", 60]
    for suffix, extra in ((".nc", []), (".csv", []), (".csv", ["--plot", tmp_path / "p.png"]),
                          (".nc", ["--plot", tmp_path / "q.png"])):
        out = tmp_path / f"cli{len(extra)}{suffix}"
        status, _, err = run([*base, "--out", out, *extra, "--format", "json"], capsys)
        assert status == 0, err
        assert out.read_bytes() == M.save_map(ds, tmp_path / f"ref{suffix}").read_bytes(), (suffix, extra)
    assert (tmp_path / "p-0deg.png").read_bytes()[:4] == b"\x89PNG"
    assert (tmp_path / "q-30deg.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("out, extra, needle", [
    ("blocker/m.nc", [], "is a file"),
    ("folder.nc", [], "folder"),
    ("m.txt", [], ".txt"),
    ("m.nc", ["--grid", "20000"], "4 GiB"),
    ("m.nc", ["--plot", "p.xyz"], "p.xyz"),
], ids=["parent-is-a-file", "out-is-a-folder", "out-type", "netcdf-too-large", "plot-type"])
def test_map_command_bad_outputs_exit_2_before_computing(tmp_path, capsys, monkeypatch, out, extra, needle):
    _no_computing(monkeypatch)
    (tmp_path / "blocker").write_text("x")
    (tmp_path / "folder.nc").mkdir()
    extra = [str(tmp_path / e) if e.endswith(".xyz") else e for e in extra]
    status, stdout, err = run(["map", "--phi-deg", 0, "--phi-deg", 30, "--grid", 11, "--out", tmp_path / out,
                               *extra], capsys)
    assert status == 2, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err and stdout == ""
    assert needle in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["blocker", "folder.nc"]
