"""Columnar CSV input and output (:mod:`pmaccuracy.io.csvio`) and the lazy command line.

* Round trip: any finite doubles written by :func:`write_csv_columns` read back
  bit-identical through :func:`read_poses_csv` and through Python's own ``float``
  on the text (hypothesis);
* the table writer is compared with a reference written here (``f"{v:.6g}"``
  right-aligned to the widest cell of each column);
* malformed files name the file, the line and the column; the CLI turns that into
  exit status 2 and one line;
* ``pmaccuracy --help`` and a one-pose ``bounds`` import no plotting, table or Dask
  module (``sys.modules`` of a fresh interpreter).
"""

from __future__ import annotations

import csv
import io
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from pmaccuracy.cli import COMMANDS, build_parser, main
from pmaccuracy.io.csvio import read_poses_csv, write_csv_columns, write_table_columns
from pmaccuracy.errors import ConfigError

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)


@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(1, 40), st.just(3)), elements=finite))
def test_round_trip_is_exact(tmp_path_factory, poses):
    path = tmp_path_factory.mktemp("rt") / "poses.csv"
    write_csv_columns({"x": poses[:, 0], "y": poses[:, 1], "phi_deg": poses[:, 2]}, path)
    back = read_poses_csv(path)
    assert back.dtype == np.float64 and back.shape == poses.shape
    assert np.array_equal(back.view(np.int64), poses.view(np.int64))  # bit for bit (-0.0 included)
    with open(path, newline="") as fh:  # and any CSV reader gets the same doubles from the text
        rows = list(csv.reader(fh))
    assert rows[0] == ["x", "y", "phi_deg"]
    assert np.array_equal(np.array([[float(c) for c in r] for r in rows[1:]]), poses)


@settings(max_examples=40, deadline=None)
@given(arrays(np.float64, st.integers(0, 30), elements=st.floats(allow_infinity=False, width=64)))
def test_csv_text_stream_and_nan(values):
    buf = io.StringIO()
    write_csv_columns({"a": values, "b": -values}, buf)
    lines = buf.getvalue().splitlines()
    assert lines[0] == "a,b" and len(lines) == 1 + len(values)
    got = np.array([[float(c) for c in ln.split(",")] for ln in lines[1:]]).reshape(-1, 2)
    np.testing.assert_array_equal(got[:, 0], values)  # NaN written as nan and compared as NaN


@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, st.integers(1, 25), elements=st.floats(width=64)))
def test_table_matches_reference(values):
    cols = {"x": values, "long_name": values[::-1].copy()}
    buf = io.StringIO()
    write_table_columns(cols, buf)
    ref_cells = {k: [f"{v:.6g}" for v in v_.tolist()] for k, v_ in cols.items()}
    widths = {k: max([len(k)] + [len(c) for c in cells]) for k, cells in ref_cells.items()}
    expected = ["  ".join(k.rjust(widths[k]) for k in cols)]
    expected += ["  ".join(ref_cells[k][i].rjust(widths[k]) for k in cols) for i in range(len(values))]
    assert buf.getvalue().splitlines() == expected


def test_other_columns_whitespace_blank_lines_and_order(tmp_path):
    path = tmp_path / "p.csv"
    path.write_text(" phi_deg , note, y ,x\n30, a ,2.5,1\n\n 0.1 ,b, -3 ,1e-5\n", encoding="utf-8")
    np.testing.assert_array_equal(read_poses_csv(path), [[1.0, 2.5, 30.0], [1e-5, -3.0, 0.1]])


@pytest.mark.parametrize("body, fragments", [
    ("x,y,phi_deg\n0,0,0\n1,abc,0\n", ["line 3", "column y", "abc"]),
    ("x,y,phi_deg\n0,0,0\n1,2\n", ["line 3", "expected 3 values"]),
    ("x,y,phi_deg\n0,0,nan\n", ["line 2", "column phi_deg", "non-finite"]),
    ("x,y,phi_deg\n0,,0\n", ["line 2", "column y"]),
    ("x,y,phi\n0,0,0\n", ["missing phi_deg"]),
    ("x,y,phi_deg\n\n", ["no poses"]),
    ("", ["missing x,y,phi_deg"]),
])
def test_errors_name_file_line_and_column(tmp_path, body, fragments):
    path = tmp_path / "bad.csv"
    path.write_text(body, encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        read_poses_csv(path)
    message = str(info.value)
    assert str(path) in message
    for frag in fragments:
        assert frag in message, message


def test_cli_error_is_one_line(tmp_path, capsys):
    path = tmp_path / "bad.csv"
    path.write_text("x,y,phi_deg\n0,0,0\n1,2,zz\n", encoding="utf-8")
    assert main(["bounds", "--poses-csv", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "line 3" in err[0] and "phi_deg" in err[0] and str(path) in err[0]


def test_bounds_csv_output_round_trips(tmp_path, capsys):
    """bounds --format csv prints exact floats: feeding its x,y,phi_deg back gives the same lines."""
    src = tmp_path / "p.csv"
    src.write_text("x,y,phi_deg\n0.1,-0.2,0.30000000000000004\n-7.25,3,10\n", encoding="utf-8")
    assert main(["bounds", "--poses-csv", str(src), "--format", "csv"]) == 0
    first = capsys.readouterr().out
    again = tmp_path / "again.csv"
    again.write_text(first, encoding="utf-8")
    assert main(["bounds", "--poses-csv", str(again), "--format", "csv"]) == 0
    assert capsys.readouterr().out == first


# ------------------------------------------------------------------------------------- lazy command line
def test_help_lines_match_the_modules():
    """The help lines listed without importing the command modules are the ones the modules register."""
    lazy = build_parser(["--help"])
    full = build_parser(load_all=True)

    def listing(parser):
        sub = next(a for a in parser._actions if a.dest == "command")
        return [(a.dest, a.help) for a in sub._choices_actions]

    assert listing(lazy) == listing(full)
    assert [name for name, _ in listing(full)] == list(COMMANDS)


_PROBE = """
import json, sys
from pmaccuracy.cli import main
try:
    status = main(sys.argv[1:])
except SystemExit as exc:
    status = exc.code
sys.stderr.write("MODULES " + json.dumps(sorted(sys.modules)) + "\\n")
sys.exit(status)
"""


def _imported(*argv: str) -> set[str]:
    """Every module loaded by ``pmaccuracy ARGV`` run in a fresh interpreter."""
    import json

    proc = subprocess.run([sys.executable, "-c", _PROBE, *argv], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    line = next(ln for ln in proc.stderr.splitlines() if ln.startswith("MODULES "))
    return set(json.loads(line[len("MODULES "):]))


HEAVY = ("matplotlib", "xarray", "dask", "pandas", "pyarrow", "distributed", "zarr")


def test_help_imports_nothing_heavy():
    modules = _imported("--help")
    assert not [m for m in modules if m.split(".")[0] in HEAVY or m.startswith("scipy.optimize")]
    assert not [m for m in modules if m.startswith("pmaccuracy.cli.") and m.endswith("_cmd")]


def test_one_pose_bounds_imports_no_plotting_or_tables():
    modules = _imported("bounds", "--pose", "0", "0", "0")
    assert not [m for m in modules if m.split(".")[0] in HEAVY]
    assert "pmaccuracy.cli.bounds_cmd" in modules and "pmaccuracy.cli.map_cmd" not in modules


def test_poses_csv_bounds_reads_and_writes_without_pandas(tmp_path):
    """The pose-file path loads pyarrow's CSV reader and writer but not pandas, which pyarrow's numpy
    conversions (``to_numpy``, ``pyarrow.array``) would import on their first call (about 0.4 s)."""
    rng = np.random.default_rng(5)
    path = tmp_path / "poses.csv"
    write_csv_columns({"x": rng.uniform(-5, 5, 50), "y": rng.uniform(-5, 5, 50), "phi_deg": rng.uniform(-5, 5, 50)},
                      path)
    modules = _imported("bounds", "--poses-csv", str(path), "--format", "csv")
    assert "pyarrow.csv" in modules
    assert not [m for m in modules if m.split(".")[0] in HEAVY and m.split(".")[0] != "pyarrow"]


def test_float_table_holds_the_values_bit_for_bit():
    from pmaccuracy.io.csvio import float_table

    values = np.array([0.1, -0.0, 1e-300, np.nan, np.inf, 5e-324, 1 / 3])
    strided = np.arange(10.0)[::3]
    table = float_table({"a": values, "b": np.arange(7), "c": np.concatenate([strided, strided[:3]])})
    assert table.column_names == ["a", "b", "c"]
    back = np.frombuffer(table.column("a").chunks[0].buffers()[1], dtype="<f8")
    assert np.array_equal(back.view(np.int64), values.view(np.int64))
    assert table.column("b").to_pylist() == list(range(7))
    assert table.column("c").to_pylist() == [0.0, 3.0, 6.0, 9.0, 0.0, 3.0, 6.0]
