"""The ``pmaccuracy bounds`` command (Eq. 21-22 at given poses), run in-process.

Each call goes through ``pmaccuracy.cli.main([...])`` with ``capsys``. The
numbers printed are compared with :func:`pmaccuracy.accuracy.bounds.max_pose_errors`
(whose correctness is established independently in ``test_bounds.py``), and
the paper's case-1 values at phi = 0 (dy_max = 0.100 mm, dphi_max = 0.221 deg)
are checked directly on the output. Every user error must end with exit
status 2, exactly one line on stderr and no traceback.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.model.clearances import ClearanceSet
from pmaccuracy.model.manipulator import Manipulator
from conftest import run_cli

AALBORG = Manipulator.preset("aalborg_3ppr")
KEYS = ["x", "y", "phi_deg", "dx_max", "dy_max", "dphi_max_deg", "dp_max"]


def run(argv, capsys):
    return run_cli(argv, capsys)


def library(poses_deg, clearances="case1", **kw):
    poses = np.array(poses_deg, float)
    poses[:, 2] = np.radians(poses[:, 2])
    return max_pose_errors(AALBORG, ClearanceSet.load(clearances), poses, **kw)


def check_records(records, poses_deg, clearances="case1", rtol=1e-12):
    b = library(poses_deg, clearances)
    assert len(records) == len(poses_deg)
    for n, rec in enumerate(records):
        assert list(rec)[:7] == KEYS, list(rec)
        assert rec["x"] == pytest.approx(poses_deg[n][0], abs=1e-12)
        assert rec["y"] == pytest.approx(poses_deg[n][1], abs=1e-12)
        assert rec["phi_deg"] == pytest.approx(poses_deg[n][2], abs=1e-12)
        assert rec["dx_max"] == pytest.approx(b.dx_max[n], rel=rtol)
        assert rec["dy_max"] == pytest.approx(b.dy_max[n], rel=rtol)
        assert rec["dphi_max_deg"] == pytest.approx(np.degrees(b.dphi_max[n]), rel=rtol)
        assert rec["dp_max"] == pytest.approx(b.dp_max[n], rel=rtol)


def test_json_single_pose(capsys):
    status, out, err = run(["bounds", "--robot", "aalborg_3ppr", "--clearances", "case1", "--pose", "0", "0", "0",
                            "--format", "json"], capsys)
    assert status == 0, err
    records = json.loads(out)
    assert isinstance(records, list) and len(records) == 1
    check_records(records, [[0, 0, 0]])
    # the paper's case-1 figures at phi = 0 (Sec. 6.1)
    assert records[0]["dy_max"] == pytest.approx(0.100, rel=0.01)
    assert records[0]["dphi_max_deg"] == pytest.approx(0.221, rel=0.01)
    assert 0.196 * 0.99 <= records[0]["dx_max"] <= 0.256 * 1.01


def test_json_repeated_poses_and_case2(capsys):
    poses = [[0, 0, 0], [10, -20, 0], [15, -5, 30]]
    argv = ["bounds", "--clearances", "case2", "--format", "json"]
    for p in poses:
        argv += ["--pose", *map(str, p)]
    status, out, err = run(argv, capsys)
    assert status == 0, err
    check_records(json.loads(out), poses, "case2")


def test_poses_csv(tmp_path: Path, capsys):
    poses = [[0, 0, 0], [-25, 25, 0], [20, -3.5, 30], [5, 5, -10]]
    path = tmp_path / "poses.csv"
    path.write_text("x,y,phi_deg\n" + "".join(f"{x},{y},{p}\n" for x, y, p in poses), encoding="utf-8")
    status, out, err = run(["bounds", "--poses-csv", str(path), "--clearances", "all", "--format", "json"], capsys)
    assert status == 0, err
    check_records(json.loads(out), poses, "all")


def test_details(capsys):
    status, out, err = run(["bounds", "--pose", "10", "-5", "0", "--clearances", "all", "--details",
                            "--format", "json"], capsys)
    assert status == 0, err
    rec = json.loads(out)[0]
    b = library([[10, -5, 0]], "all", details=True)
    assert set(rec["worst"]) == {"dx", "dy", "dphi", "dp"}
    for q, disp in b.worst.items():
        w = rec["worst"][q]
        assert set(w) == {"tau_b_rad", "sigma_g_mm", "tau_g_rad", "rho_mm", "varphi_deg"}
        np.testing.assert_allclose(w["tau_b_rad"], disp.tau_b[0], rtol=1e-12, atol=1e-18)
        np.testing.assert_allclose(w["sigma_g_mm"], disp.sigma_g[0], rtol=1e-12, atol=1e-18)
        np.testing.assert_allclose(w["tau_g_rad"], disp.tau_g[0], rtol=1e-12, atol=1e-18)
        np.testing.assert_allclose(w["rho_mm"], disp.rho[0], rtol=1e-12, atol=1e-18)
        np.testing.assert_allclose(w["varphi_deg"], np.degrees(disp.varphi[0]), rtol=1e-12, atol=1e-12)
        # admissible per Eq. 16-18 as printed
        c = ClearanceSet.load("all")
        tb, sg, tg, rho = (np.array(w[k]) for k in ("tau_b_rad", "sigma_g_mm", "tau_g_rad", "rho_mm"))
        assert np.all(np.abs(tb) <= c.bearing_angle * (1 + 1e-12))
        assert np.all(np.abs(c.guide_block_length * tg + 2 * sg) <= 2 * c.guide_lateral * (1 + 1e-12))
        assert np.all(np.abs(-c.guide_block_length * tg + 2 * sg) <= 2 * c.guide_lateral * (1 + 1e-12))
        assert np.all((rho >= 0) & (rho <= c.revolute_radial * (1 + 1e-12)))


def test_slsqp_method_one_pose(capsys):
    status, out, err = run(["bounds", "--pose", "5", "-10", "0", "--method", "slsqp", "--format", "json"], capsys)
    assert status == 0, err
    check_records(json.loads(out), [[5, -10, 0]], rtol=1e-6)


def test_csv_format(capsys):
    poses = [[0, 0, 0], [10, -20, 0]]
    status, out, err = run(["bounds", "--pose", "0", "0", "0", "--pose", "10", "-20", "0", "--format", "csv"], capsys)
    assert status == 0, err
    rows = list(csv.DictReader(io.StringIO(out)))
    assert list(rows[0]) == KEYS
    check_records([{k: float(v) for k, v in r.items()} for r in rows], poses, rtol=1e-5)


def test_table_format(capsys):
    poses = [[0, 0, 0], [10, -20, 0], [-5, 7, 30]]
    argv = ["bounds", "--clearances", "case2"]
    for p in poses:
        argv += ["--pose", *map(str, p)]
    status, out, err = run(argv, capsys)  # table is the default format
    assert status == 0, err
    lines = [ln.split() for ln in out.strip().splitlines()]
    assert lines[0] == KEYS
    assert len(lines) == 1 + len(poses)
    records = [dict(zip(KEYS, map(float, ln))) for ln in lines[1:]]
    check_records(records, poses, "case2", rtol=1e-5)


# ------------------------------------------------------------------------------------ user errors
def assert_one_line_error(status, out, err, *fragments):
    assert status == 2, (status, out, err)
    lines = err.strip("\n").splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    assert lines[0].startswith("pmaccuracy bounds"), lines[0]
    for frag in fragments:
        assert frag.lower() in lines[0].lower(), (frag, lines[0])


def write_clearances(tmp_path: Path, key: str, value) -> Path:
    legs = [{"bearing_angle": 0.0012, "revolute_radial": 0.03} for _ in range(3)]
    legs[1][key] = value
    path = tmp_path / "clear.toml"
    path.write_text(tomli_w.dumps({"legs": legs}), encoding="utf-8")
    return path


def test_error_pose_outside(capsys):
    status, out, err = run(["bounds", "--pose", "100", "0", "0"], capsys)
    assert_one_line_error(status, out, err, "x=100", "outside")


def test_allow_outside(capsys):
    status, out, err = run(["bounds", "--pose", "100", "0", "0", "--allow-outside", "--format", "json"], capsys)
    assert status == 0, err
    b = max_pose_errors(AALBORG, ClearanceSet.load("case1"), [100.0, 0.0, 0.0], allow_outside=True)
    assert json.loads(out)[0]["dp_max"] == pytest.approx(float(b.dp_max), rel=1e-12)


def test_error_singular_pose(capsys):
    status, out, err = run(["bounds", "--pose", "0", "0", "90"], capsys)
    assert_one_line_error(status, out, err, "singular")


def test_error_negative_clearance_file(tmp_path: Path, capsys):
    path = write_clearances(tmp_path, "bearing_angle", -0.001)
    status, out, err = run(["bounds", "--pose", "0", "0", "0", "--clearances", str(path)], capsys)
    assert_one_line_error(status, out, err, str(path), "legs[2].bearing_angle", "negative")


def test_error_non_finite_clearance_file(tmp_path: Path, capsys):
    path = write_clearances(tmp_path, "revolute_radial", float("nan"))
    status, out, err = run(["bounds", "--pose", "0", "0", "0", "--clearances", str(path)], capsys)
    assert_one_line_error(status, out, err, str(path), "legs[2].revolute_radial", "finite")


def test_error_bad_csv_header(tmp_path: Path, capsys):
    path = tmp_path / "poses.csv"
    path.write_text("x,y,phi\n0,0,0\n", encoding="utf-8")
    status, out, err = run(["bounds", "--poses-csv", str(path)], capsys)
    assert_one_line_error(status, out, err, str(path), "header")


def test_error_non_numeric_csv(tmp_path: Path, capsys):
    path = tmp_path / "poses.csv"
    path.write_text("x,y,phi_deg\n0,0,0\n1,abc,0\n", encoding="utf-8")
    status, out, err = run(["bounds", "--poses-csv", str(path)], capsys)
    assert_one_line_error(status, out, err, str(path), "line 3")


def test_error_unknown_clearance_preset(capsys):
    status, out, err = run(["bounds", "--pose", "0", "0", "0", "--clearances", "case9"], capsys)
    assert_one_line_error(status, out, err, "case9")


def test_error_missing_csv_file(tmp_path: Path, capsys):
    status, out, err = run(["bounds", "--poses-csv", str(tmp_path / "none.csv")], capsys)
    assert_one_line_error(status, out, err, "none.csv")


def test_error_non_finite_pose_argument(capsys):
    status, out, err = run(["bounds", "--pose", "0", "nan", "0"], capsys)
    assert_one_line_error(status, out, err, "finite")


def test_error_details_with_slsqp(capsys):
    status, out, err = run(["bounds", "--pose", "0", "0", "0", "--method", "slsqp", "--details"], capsys)
    assert_one_line_error(status, out, err, "details")
