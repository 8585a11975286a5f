"""``pmaccuracy map`` and ``pmaccuracy reproduce``, run in-process through ``pmaccuracy.cli.main``.

The printed ranges are compared with the files the command wrote and with
:func:`pmaccuracy.accuracy.bounds.max_pose_errors` on the map's own grid; the phi = 0 ranges
with the paper's values (Sec. 6.1, case 1: dx_max 0.196-0.256 mm, dy_max 0.100 mm,
dphi_max 0.221 deg, within 1 %). Every user error ends with exit status 2, exactly
one line on stderr and no traceback.
"""

from __future__ import annotations

import csv
import io
import json
import traceback

import numpy as np
import pytest

from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.model.clearances import ClearanceSet
from pmaccuracy.cli import main
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.accuracy.maps import load_map

AALBORG = Manipulator.preset("aalborg_3ppr")
PNG = b"\x89PNG\r\n\x1a\n"
RANGE_KEYS = ("dx_max", "dy_max", "dphi_max_deg", "dp_max")


def run(argv, capsys):
    """Run the CLI; returns (status, stdout, stderr).

    argparse exits count as a status; any other exception is turned into status
    ``"exception"`` with its traceback on stderr, so the assertions below report it.
    """
    try:
        status = main([str(a) for a in argv])
    except SystemExit as exc:
        status = exc.code
    except Exception:  # noqa: BLE001 - reported through the assertions
        out = capsys.readouterr()
        return "exception", out.out, out.err + traceback.format_exc()
    out = capsys.readouterr()
    return status, out.out, out.err


def assert_user_error(status, out, err):
    assert status == 2, (status, err)
    assert "Traceback" not in err, err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert "error" in lines[0]
    assert out == ""


def _library_ranges(ds, case, phi_deg):
    """[min, max] of max_pose_errors over the inside points of the map's grid."""
    layer = ds.sel(phi=phi_deg, method="nearest")
    X, Y = np.meshgrid(layer.x.values, layer.y.values)
    inside = np.isfinite(layer.dx_max.values)
    poses = np.column_stack([X[inside], Y[inside], np.full(inside.sum(), np.radians(phi_deg))])
    b = max_pose_errors(AALBORG, ClearanceSet.load(case), poses)
    vals = {"dx_max": b.dx_max, "dy_max": b.dy_max, "dphi_max_deg": np.degrees(b.dphi_max), "dp_max": b.dp_max}
    return {k: [v.min(), v.max()] for k, v in vals.items()}


# ----------------------------------------------------------------------------- map
def test_map_json_netcdf_and_plots(tmp_path, capsys):
    out_nc, plot = tmp_path / "X.nc", tmp_path / "P.png"
    status, out, err = run(["map", "--phi-deg", 0, "--phi-deg", 30, "--grid", 21, "--out", out_nc,
                            "--plot", plot, "--format", "json"], capsys)
    assert status == 0, err
    rows = json.loads(out)
    assert [r["phi_deg"] for r in rows] == pytest.approx([0.0, 30.0], abs=1e-9)
    for row in rows:
        assert set(row) == {"phi_deg", *RANGE_KEYS}
        for k in RANGE_KEYS:
            lo, hi = row[k]
            assert 0 < lo <= hi, (row["phi_deg"], k)
    # files
    assert out_nc.is_file()
    for name in ("P-0deg.png", "P-30deg.png"):
        assert (tmp_path / name).read_bytes()[:8] == PNG, name
    assert not plot.exists()  # with two orientations: one file per orientation only
    ds = load_map(out_nc)
    assert ds.sizes == {"phi": 2, "y": 21, "x": 21}
    assert ds.attrs["clearances"] == "case1" and ds.attrs["robot"] == "aalborg_3ppr"
    for row, phi in zip(rows, (0.0, 30.0)):
        expected = _library_ranges(ds, "case1", phi)
        for k in RANGE_KEYS:
            assert row[k] == pytest.approx(expected[k], rel=1e-12), (phi, k)
    # paper, case 1 at phi = 0 (Sec. 6.1)
    assert rows[0]["dx_max"] == pytest.approx([0.196, 0.256], rel=0.01)
    assert rows[0]["dy_max"] == pytest.approx([0.100, 0.100], rel=0.01)
    assert rows[0]["dphi_max_deg"] == pytest.approx([0.221, 0.221], rel=0.01)


def test_map_single_orientation_plot_name(tmp_path, capsys):
    plot = tmp_path / "one.png"
    status, out, err = run(["map", "--phi-deg", -30, "--grid", 11, "--clearances", "case2",
                            "--out", tmp_path / "m.nc", "--plot", plot, "--format", "json"], capsys)
    assert status == 0, err
    assert plot.read_bytes()[:8] == PNG
    rows = json.loads(out)
    assert len(rows) == 1 and rows[0]["phi_deg"] == pytest.approx(-30.0)
    assert load_map(tmp_path / "m.nc").attrs["clearances"] == "case2"


def test_map_phi_printed_as_typed(tmp_path, capsys):
    """BUG: ``--phi-deg 30`` is printed back as 29.999999999999996 (degrees(radians(30))).

    Same cause as ``test_maps.py::test_phi_coordinate_is_the_requested_degrees``.
    """
    status, out, err = run(["map", "--phi-deg", 30, "--phi-deg", 60, "--grid", 5, "--out", tmp_path / "m.nc",
                            "--format", "json"], capsys)
    assert status == 0, err
    assert [r["phi_deg"] for r in json.loads(out)] == [30.0, 60.0]


def test_map_csv_output(tmp_path, capsys):
    path = tmp_path / "m.csv"
    status, out, err = run(["map", "--phi-deg", 0, "--phi-deg", 30, "--grid", 21, "--out", path,
                            "--format", "csv"], capsys)
    assert status == 0, err
    # stdout: one CSV row per orientation, ranges flattened to <key>1, <key>2
    summary = list(csv.DictReader(io.StringIO(out)))
    assert len(summary) == 2
    assert [float(r["phi_deg"]) for r in summary] == pytest.approx([0.0, 30.0])
    for r in summary:
        for k in RANGE_KEYS:
            assert float(r[f"{k}1"]) <= float(r[f"{k}2"])
    # file: one row per inside grid point
    with open(path, newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader)
        rows = np.array([[float(c) for c in r] for r in reader])
    assert header == ["x", "y", "phi_deg", "dx_max", "dy_max", "dphi_max_deg", "dp_max"]
    phi0 = rows[np.isclose(rows[:, 2], 0.0)]
    phi30 = rows[np.isclose(rows[:, 2], 30.0)]
    assert len(phi0) + len(phi30) == len(rows)
    # phi = 0: the 50 x 50 mm square; the union x grid (-25..40, 21 points) puts 17 columns in it
    xs = np.linspace(-25, 40, 21)
    assert len(phi0) == 21 * int(np.sum(xs <= 25 + 1e-9))
    # every printed range is the CSV's range (10 significant digits; stdout shows 6)
    for r, part in zip(summary, (phi0, phi30)):
        for j, k in enumerate(RANGE_KEYS, start=3):
            assert float(r[f"{k}1"]) == pytest.approx(part[:, j].min(), rel=1e-5)
            assert float(r[f"{k}2"]) == pytest.approx(part[:, j].max(), rel=1e-5)


def test_map_table_output(tmp_path, capsys):
    status, out, err = run(["map", "--phi-deg", 0, "--grid", 5, "--out", tmp_path / "m.nc"], capsys)
    assert status == 0, err
    lines = out.splitlines()
    assert len(lines) == 2 and "phi_deg" in lines[0] and "dx_max1" in lines[0]


def test_map_dask_option(tmp_path, capsys):
    pytest.importorskip("dask")
    a, b = tmp_path / "a.nc", tmp_path / "b.nc"
    s1, out1, err1 = run(["map", "--phi-deg", 30, "--grid", 15, "--out", a, "--format", "json"], capsys)
    s2, out2, err2 = run(["map", "--phi-deg", 30, "--grid", 15, "--out", b, "--format", "json", "--dask",
                          "--chunk-size", 17, "--no-progress"], capsys)
    assert (s1, s2) == (0, 0), err1 + err2
    assert json.loads(out1) == json.loads(out2)
    assert load_map(a).identical(load_map(b))


# ----------------------------------------------------------------------------- reproduce
@pytest.mark.slow        # the same report as tests/report/test_report.py's, through the command line
def test_reproduce_command(tmp_path, capsys):
    out_dir = tmp_path / "rep"
    status, out, err = run(["reproduce", "--out", out_dir, "--grid", 21, "--no-experiment"], capsys)
    assert status == 0, err
    assert str(out_dir / "report.html") in out
    assert "3 of 3" in out
    for name in ("report.html", "report.md", "results.json", "workspace.png"):
        assert (out_dir / name).is_file(), name
    results = json.loads((out_dir / "results.json").read_text())
    assert results["grid"] == 21 and "experiment" not in results
    assert all(r["pass"] for r in results["paper_check"])


# ----------------------------------------------------------------------------- errors
def _negative_clearances(tmp_path):
    path = tmp_path / "neg.toml"
    path.write_text("name = 'neg'\n[[legs]]\nbearing_angle = -0.001\n[[legs]]\nbearing_angle = 0.001\n"
                    "[[legs]]\nbearing_angle = 0.001\n")
    return path


@pytest.mark.parametrize("args, needle", [
    (["--phi-deg", "90"], "singular"),
    (["--phi-deg", "-90"], "singular"),
    (["--phi-deg", "0", "--out-name", "file.txt"], ".txt"),
    (["--phi-deg", "0", "--grid", "1"], "grid"),
    (["--phi-deg", "0", "--grid", "0"], "grid"),
    (["--phi-deg", "0", "--robot", "no_such_robot"], "no_such_robot"),
    (["--phi-deg", "0", "--clearances", "NEGATIVE"], "negative"),
    (["--phi-deg", "0", "--clearances", "no_such_set"], "no_such_set"),
    (["--phi-deg", "nan"], "finite"),
    (["--phi-deg", "inf"], "finite"),
    (["--phi-deg", "abc"], "number"),
    ([], "--phi-deg"),
], ids=["phi90", "phi-90", "out-txt", "grid1", "grid0", "unknown-robot", "negative-clearance",
        "unknown-clearances", "phi-nan", "phi-inf", "phi-text", "no-phi"])
def test_map_user_errors(tmp_path, capsys, args, needle):
    args = list(args)
    out_file = tmp_path / "m.nc"
    if "--out-name" in args:
        i = args.index("--out-name")
        out_file = tmp_path / args[i + 1]
        del args[i:i + 2]
    args = [str(_negative_clearances(tmp_path)) if a == "NEGATIVE" else a for a in args]
    status, out, err = run(["map", *args, "--out", out_file], capsys)
    assert_user_error(status, out, err)
    assert needle.lower() in err.lower(), err
    assert not out_file.exists()


def test_map_grid_missing_an_orientation(tmp_path, capsys):
    """BUG: --grid 2 with phi = 0 and 30 deg: no grid point in the phi = 30 workspace.

    Currently the phi = 30 layer is silently all NaN and ``--plot`` crashes with a
    ValueError traceback in ``figures._limits`` (see ``test_maps.py::
    test_orientation_without_grid_points_is_an_error``). Expected: exit 2, one line.
    """
    status, out, err = run(["map", "--phi-deg", 0, "--phi-deg", 30, "--grid", 2, "--out", tmp_path / "m.nc",
                            "--plot", tmp_path / "p.png"], capsys)
    assert_user_error(status, out, err)


@pytest.mark.parametrize("args", [["--grid", "1"], ["--grid", "0"], ["--robot", "no_such_robot"],
                                  ["--grid", "2"]], ids=["grid1", "grid0", "unknown-robot", "grid2"])
def test_reproduce_user_errors(tmp_path, capsys, args):
    """``--grid 2`` fails for the same reason as test_map_grid_missing_an_orientation (BUG)."""
    status, out, err = run(["reproduce", "--out", tmp_path / "rep", "--no-experiment", *args], capsys)
    assert_user_error(status, out, err)
