"""``ik`` and ``fk`` on spatial robots: the robot's own coordinates in, JSON/CSV/table out, bad input in one line."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import run_cli

import pmaccuracy as pm
from pmaccuracy.kinematics import spatial as k


def test_ik_hexapod_matches_the_library_in_degrees(capsys):
    status, out, err = run_cli(["ik", "--robot", "stewart_6ups", "--pose", 5, -3, 410, 2, -1, 4, "--format", "json"],
                               capsys)
    assert status == 0, err
    rec = json.loads(out)[0]
    robot = pm.load_robot("stewart_6ups")
    pose = k.poses_from_coordinates([5, -3, 410, 2, -1, 4], degrees=True)
    np.testing.assert_allclose(rec["q"], pm.inverse_kinematics(robot, pose).q, rtol=1e-12)
    assert rec["within_limits"] is True and rec["violations"] == []
    assert rec["yaw_deg"] == pytest.approx(4.0)


def test_ik_3rps_reports_the_parasitic_motions(capsys):
    status, out, err = run_cli(["ik", "--robot", "rps_3", "--pose", 350, 5, -3, "--format", "json"], capsys)
    assert status == 0, err
    rec = json.loads(out)[0]
    assert rec["z"] == pytest.approx(350.0) and rec["roll_deg"] == pytest.approx(5.0)
    assert abs(rec["x"]) > 1e-3 and abs(rec["yaw_deg"]) > 1e-3      # parasitic, not zero


def test_ik_csv_of_controlled_coordinates(tmp_path, capsys):
    path = tmp_path / "p.csv"
    path.write_text("x,y,z\n0,0,-800\n30,10,-750\n")
    status, out, err = run_cli(["ik", "--robot", "delta_clavel", "--poses-csv", path, "--format", "csv"], capsys)
    assert status == 0, err
    lines = out.strip().splitlines()
    assert lines[0].startswith("x,y,z,roll_deg,pitch_deg,yaw_deg,q1,q2,q3") and len(lines) == 3


def test_fk_hexapod_lists_every_mode_and_the_home_pose_among_them(capsys):
    robot = pm.load_robot("stewart_6ups")
    q = pm.inverse_kinematics(robot, robot.home_pose).q
    status, out, err = run_cli(["fk", "--robot", "stewart_6ups", "--joints", *q, "--format", "json"], capsys)
    assert status == 0, err
    data = json.loads(out)
    assert data["complete"] is True and "homotopy" in data["method"]
    homes = [m for m in data["modes"] if abs(m["z"] - 400.0) < 1e-6 and abs(m["x"]) < 1e-6]
    assert len(homes) == 1 and homes[0]["within_limits"] is True
    assert len(data["modes"]) % 2 == 0


def test_fk_delta_in_degrees(capsys):
    status, out, err = run_cli(["fk", "--robot", "delta_clavel", "--joints", 20, 25, 30], capsys)
    assert status == 0, err
    assert "+1 +1 +1" in out and "-1 -1 -1" in out


@pytest.mark.parametrize("argv, words", [
    (["ik", "--robot", "stewart_6ups", "--pose", 0, 0, 400], "--pose (number 1): a 6-UPS takes 6 values"),
    (["ik", "--robot", "rps_3", "--pose", 0, 0, 400, 0], "--pose (number 1): a 3-RPS takes 3 values"),
    (["fk", "--robot", "stewart_6ups", "--joints", 450, 450, 450], "--joints: a 6-UPS has 6 actuators"),
    (["fk", "--robot", "delta_clavel", "--joints", 100, 20, 20], "--joints: actuator values outside their ranges"),
    (["fk", "--robot", "stewart_6ups", "--joints", 100, 100, 100, 100, 100, 100, "--allow-outside"],
     "no assembly mode"),
    (["ik", "--robot", "stewart_6ups", "--pose", 0, 0, 1e12, 0, 0, 0], "beyond"),
    (["workspace", "--robot", "stewart_6ups", "--phi-deg", 10], "--phi-deg is the orientation of a planar robot"),
    (["workspace", "--robot", "aalborg_3ppr", "--orientation-deg", 1, 2, 3], "--orientation-deg is for spatial"),
    (["workspace", "--robot", "rps_3", "--orientation-deg", 1, 2, 3], "--orientation-deg is for a 6-UPS"),
])
def test_bad_input_one_line_status_2(argv, words, capsys):
    status, out, err = run_cli(argv, capsys)
    assert status == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and words in lines[0], err
    assert "Traceback" not in err


def test_bad_robot_file_one_line(tmp_path, capsys):
    text = (pm.load_robot("upu_3").to_toml()).replace("stroke = [", "stroke = [900.0, ", 1)
    path = tmp_path / "bad.toml"
    path.write_text(text)
    status, out, err = run_cli(["ik", "--robot", path, "--pose", 0, 0, 300], capsys)
    assert status == 2 and len(err.strip().splitlines()) == 1 and "bad.toml" in err and "legs[1].stroke" in err, err


def test_bounds_on_a_spatial_robot_with_its_default_sources(capsys):
    status, out, err = run_cli(["bounds", "--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0, "--pose",
                                10, 5, 390, 2, -1, 5, "--format", "json"], capsys)
    assert status == 0, err
    assert "clearances: ups_typical (default)" in err
    rows = json.loads(out)
    from pmaccuracy.accuracy.spatial_bounds import spatial_pose_errors
    from pmaccuracy.model.spatial_sources import SpatialErrorSources

    robot = pm.load_robot("stewart_6ups")
    b = spatial_pose_errors(robot, SpatialErrorSources.load("ups_typical", robot),
                            k.poses_from_coordinates([[0, 0, 400, 0, 0, 0], [10, 5, 390, 2, -1, 5]], degrees=True))
    for row, comp, dp in zip(rows, b.components, b.dp_upper):
        assert row["dx_max"] == pytest.approx(comp[0], rel=1e-12)
        assert row["drz_max_deg"] == pytest.approx(np.degrees(comp[5]), rel=1e-12)
        assert row["dp_max"] == pytest.approx(dp, rel=1e-12) and row["dp_attained"] <= row["dp_max"]


def test_map_of_a_spatial_robot_writes_netcdf_and_a_figure(tmp_path, capsys):
    import xarray as xr

    out, fig = tmp_path / "m.nc", tmp_path / "m.png"
    status, text, err = run_cli(["map", "--robot", "upu_3", "--grid", 8, "--out", out, "--plot", fig,
                                 "--format", "json"], capsys)
    assert status == 0, err
    ds = xr.open_dataset(out)
    assert set(ds.sizes) == {"x", "y", "z"} and ds.dp_max.attrs["units"] == "mm"
    rows = {r["quantity"]: r for r in json.loads(text)}
    assert rows["dp_max"]["max"] == pytest.approx(float(ds.dp_max.max()))
    assert fig.stat().st_size > 10_000
    ds.close()


@pytest.mark.parametrize("argv, words", [
    (["bounds", "--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0, "--nonlinear"], "--nonlinear is not"),
    (["bounds", "--robot", "stewart_6ups", "--clearances", "nope.toml", "--pose", 0, 0, 400, 0, 0, 0],
     "--clearances: nope.toml"),
    (["bounds", "--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 90, "--allow-outside"], "singularity"),
    (["bounds", "--robot", "aalborg_3ppr", "--pose", 0, 0], "a planar robot takes three values"),
    (["map", "--robot", "upu_3", "--grid", 8, "--out", "x.csv"], "a spatial map is written as .nc or .zarr"),
    (["map", "--robot", "upu_3", "--grid", 500, "--out", "x.nc"], "--grid: 500"),
    (["map", "--robot", "aalborg_3ppr", "--grid", 8, "--out", "x.nc"], "required: --phi-deg"),
])
def test_bad_accuracy_input_one_line(argv, words, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, out, err = run_cli(argv, capsys)
    assert status == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and words in lines[0], err


@pytest.mark.parametrize("argv", [
    ["compare-designs", "--robot", "aalborg_3ppr", "stewart_6ups"],
    ["experiment", "simulate", "--robot", "prs_3", "--out", "x.csv"],
])
def test_commands_without_spatial_support_refuse_in_one_line(argv, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, out, err = run_cli(argv, capsys)
    lines = err.strip().splitlines()
    assert status == 2 and len(lines) == 1, err
    assert "spatial robot" in lines[0] or "error:" in lines[0], err
    assert "internal error" not in err and "Traceback" not in err


def test_bounds_refuses_a_pose_outside_the_strokes_unless_asked(capsys):
    argv = ["bounds", "--robot", "stewart_6ups", "--pose", 0, 0, 560, 0, 0, 0]
    status, out, err = run_cli(argv, capsys)
    assert status == 2 and len(err.strip().splitlines()) == 1
    assert "--pose: pose 1 (x, y, z, roll, pitch, yaw) = (0, 0, 560, 0, 0, 0) is outside the joint limits" in err
    assert "np.float64" not in err and "--allow-outside" in err
    status, out, err = run_cli(argv + ["--allow-outside"], capsys)
    assert status == 0, err


def test_certified_bounds_of_a_hexapod_match_the_api_and_refuse_in_one_line(capsys, tmp_path):
    status, text, err = run_cli(["bounds", "--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0, "--pose", 10, 5,
                                 390, 2, -1, 5, "--certified", "--format", "json"], capsys)
    assert status == 0, err
    rows = json.loads(text)
    assert len(rows) == 16 and [r["quantity"] for r in rows[:8]] == ["dx", "dy", "dz", "drx_deg", "dry_deg",
                                                                      "drz_deg", "dp", "dtheta_deg"]
    robot = pm.load_robot("stewart_6ups")
    pose = k.poses_from_coordinates([10, 5, 390, 2, -1, 5], degrees=True)
    res = pm.spatial_certified_bounds(robot, "ups_typical", pose)
    for row, rec in zip(rows[8:], res.records()):
        assert row["upper"] == pytest.approx(rec["upper"], rel=1e-12) and row["certified"] is True
        assert row["first_order"] <= row["lower"] * (1 + 1e-3) and row["lower"] <= row["upper"]
        assert row["gap_pct"] == pytest.approx(100 * (row["upper"] - row["lower"]) / row["lower"], rel=1e-9)
    big = tmp_path / "big.toml"
    import tomli_w
    big.write_bytes(tomli_w.dumps(pm.load_clearances("ups_typical", robot).scaled(3000.0).to_dict()).encode())
    status, text, err = run_cli(["bounds", "--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0, "--certified",
                                 "--clearances", big, "--format", "json"], capsys)
    assert status == 0 and "not certified" in err
    assert all(r["upper"] is None and r["certified"] is False for r in json.loads(text))   # inf: null in JSON


@pytest.mark.parametrize("robot", ["stewart_6ups", "aalborg_3ppr"])
def test_missing_poses_are_asked_for_in_one_line(tmp_path, capsys, robot):
    status, out, err = run_cli(["bounds", "--robot", robot], capsys)
    assert status == 2 and "--pose" in err and "not both" not in err and len(err.strip().splitlines()) == 1
    path = tmp_path / "p.csv"
    path.write_text("x\n")
    pose = [0, 0, 400, 0, 0, 0] if robot == "stewart_6ups" else [0, 0, 0]
    status, out, err = run_cli(["bounds", "--robot", robot, "--pose", *pose, "--poses-csv", path], capsys)
    assert status == 2 and "not both" in err
