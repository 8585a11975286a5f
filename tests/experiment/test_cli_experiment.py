"""``pmaccuracy experiment simulate|compare``: output shapes, files, and exit status 2 with one stderr line."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import pytest

from pmaccuracy.cli import main
from pmaccuracy.experiment import PUSHES, load_measurements

HAND = Path(__file__).resolve().parents[1] / "data" / "hand_measurements.csv"
HAND_LINES = HAND.read_text(encoding="utf-8").splitlines()
POINT_KEYS = {"point", "x_nom", "y_nom", "phi_nom_deg", "dx", "dy", "dphi_deg", "dp", "dx_max", "dy_max",
              "dphi_max_deg", "dp_max"}
RMSD_KEYS = {"dx", "dy", "dp", "dphi_deg"}


def run(argv: list[str], capsys) -> tuple[int, str, str]:
    """Exit status, stdout and stderr of ``pmaccuracy argv`` (argparse errors raise SystemExit)."""
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def fails_cleanly(argv: list[str], capsys, *needles: str) -> str:
    code, _, err = run(argv, capsys)
    assert code == 2, err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err
    for needle in needles:
        assert needle in err, (needle, err)
    return err


@pytest.fixture(scope="module")
def simulated(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("sim") / "m.csv"
    assert main(["experiment", "simulate", "--clearances", "case2", "--phi-deg", "30", "--grid", "4",
                 "--seed", "5", "--out", str(path), "--format", "json"]) == 0
    return path


def test_simulate_writes_a_valid_measurement_file(simulated, capsys):
    m = load_measurements(simulated)
    assert len(m) >= 10
    with open(simulated, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 6 * len(m)
    assert {r["push"] for r in rows} == set(PUSHES)
    assert {float(r["phi_nom_deg"]) for r in rows} == {30.0}


def test_simulate_summary_and_options(tmp_path, capsys):
    out = tmp_path / "deep" / "fo.csv"
    code, stdout, _ = run(["experiment", "simulate", "--clearances", "case1", "--grid", "3", "--take-up", "0.5",
                           "--noise-mm", "0", "--noise-deg", "0", "--model", "first_order", "--seed", "1",
                           "--out", str(out), "--format", "json"], capsys)
    assert code == 0
    summary = json.loads(stdout)
    assert summary["points"] == 9 and summary["rows"] == 54 and summary["model"] == "first_order"
    assert out.is_file()


def test_compare_json_shape(simulated, capsys):
    code, stdout, err = run(["experiment", "compare", "--clearances", "case2", "--measurements", str(simulated),
                             "--format", "json"], capsys)
    assert code == 0, err
    data = json.loads(stdout)
    assert set(data["points"][0]) == POINT_KEYS
    assert len(data["points"]) == len(load_measurements(simulated))
    assert set(data["rmsd"]) == RMSD_KEYS and set(data["rmsd_width_consistent"]) == RMSD_KEYS
    assert all(isinstance(v, float) for v in data["rmsd"].values())
    # Virtual experiment with full take-up: the width-consistent RMSD is at the noise level, the paper's is not.
    assert data["rmsd_width_consistent"]["dx"] < 0.05 < data["rmsd"]["dx"]
    assert data["points"][0]["phi_nom_deg"] == 30.0
    assert {"ssd", "accuracy_iso9283", "band", "orientations"} <= set(data)


def test_compare_hand_file_table_and_csv(capsys):
    code, stdout, _ = run(["experiment", "compare", "--clearances", "case1", "--measurements", str(HAND)], capsys)
    assert code == 0
    assert "rmsd (measured - max)" in stdout and "dphi_max_deg" in stdout
    code, stdout, _ = run(["experiment", "compare", "--clearances", "case1", "--measurements", str(HAND),
                           "--format", "csv"], capsys)
    assert code == 0
    rows = list(csv.DictReader(io.StringIO(stdout)))
    assert [r["point"] for r in rows] == ["A", "B", "C"]
    assert set(rows[0]) == POINT_KEYS
    assert float(rows[0]["dx"]) == pytest.approx(0.42)


def test_compare_out_writes_report(tmp_path, capsys):
    out = tmp_path / "report"
    code, stdout, err = run(["experiment", "compare", "--clearances", "case2", "--measurements", str(HAND),
                             "--out", str(out), "--map-grid", "11", "--format", "json"], capsys)
    assert code == 0, err
    data = json.loads(stdout)
    html = (out / "report.html").read_text()
    assert "data:image/png;base64," in html and "RMSD" in html
    saved = json.loads((out / "comparison.json").read_text())
    assert saved["rmsd"] == data["rmsd"]
    for name in ("map_phi0", "map_phi30", "boxplot", "accuracy", "regression", "regression_x2"):
        assert (out / f"{name}.png").is_file()


# ----------------------------------------------------------------------------------- exit status 2
def _write(tmp_path: Path, name: str, lines: list[str]) -> str:
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def _cell(lines: list[str], line: int, column: int, value: str) -> list[str]:
    lines = list(lines)
    cells = lines[line - 1].split(",")
    cells[column] = value
    lines[line - 1] = ",".join(cells)
    return lines


BAD_FILES = {
    "missing-push": (HAND_LINES[:3] + HAND_LINES[4:], ["point A", "missing", "-x"]),
    "duplicate": (HAND_LINES + [HAND_LINES[8]], ["line 20", "repeated"]),
    "non-numeric": (_cell(HAND_LINES, 12, 6, "0,1"), ["line 12"]),
    "not-a-number": (_cell(HAND_LINES, 12, 6, "zero"), ["line 12", "not a number"]),
    "metres": (_cell(HAND_LINES, 16, 5, "0.01003"), ["line 16", "units"]),
    "radians": (_cell(HAND_LINES, 14, 7, "0.5201"), ["line 14", "radians"]),
    "bad-header": (["point;x_nom;y_nom"] + HAND_LINES[1:], ["line 1", "header"]),
}


@pytest.mark.parametrize("case", BAD_FILES, ids=list(BAD_FILES))
def test_compare_malformed_file_exits_2(case, tmp_path, capsys):
    lines, needles = BAD_FILES[case]
    path = _write(tmp_path, f"{case}.csv", lines)
    fails_cleanly(["experiment", "compare", "--measurements", path], capsys, path, *needles)


def test_compare_nominal_outside_joint_ranges_exits_2(tmp_path, capsys):
    lines = list(HAND_LINES)
    for ln in range(2, 8):  # point A moved to y = -40 mm (readings too)
        cells = lines[ln - 1].split(",")
        cells[2] = "-40"
        cells[6] = str(float(cells[6]) - 40)
        lines[ln - 1] = ",".join(cells)
    path = _write(tmp_path, "outside.csv", lines)
    fails_cleanly(["experiment", "compare", "--measurements", path], capsys, "point A", "outside the joint ranges")


def test_compare_missing_file_exits_2(tmp_path, capsys):
    fails_cleanly(["experiment", "compare", "--measurements", str(tmp_path / "none.csv")], capsys, "no such file")


@pytest.mark.parametrize("extra, needle", [
    (["--take-up", "-0.2"], "--take-up"),
    (["--take-up", "2"], "--take-up"),
    (["--noise-mm", "-0.01"], "--noise-mm"),
    (["--noise-deg", "-0.01"], "--noise-deg"),
    (["--grid", "1"], "grid"),
    (["--grid", "0"], "grid"),
    (["--take-up", "nan"], "take-up"),
    (["--model", "quadratic"], "model"),
    (["--clearances", "case9"], "case9"),
])
def test_simulate_bad_options_exit_2(extra, needle, tmp_path, capsys):
    out = tmp_path / "x.csv"
    fails_cleanly(["experiment", "simulate", "--out", str(out), *extra], capsys, needle)
    assert not out.exists()


def test_simulate_without_out_exits_2(capsys):
    fails_cleanly(["experiment", "simulate"], capsys, "--out")
