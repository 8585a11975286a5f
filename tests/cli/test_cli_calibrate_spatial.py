"""``pmaccuracy calibrate simulate|identify`` on spatial robots: the steps chained through the spatial
calibration CSV, the robot file written back, and bad input (exit 2, one line)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import run_cli
from pmaccuracy.model.spatial import SpatialManipulator


def test_simulate_then_identify_position_only(tmp_path, capsys):
    status, out, _ = run_cli(["calibrate", "simulate", "--robot", "stewart_6ups", "--poses", "25", "--seed", "2",
                              "--target", "0", "0", "30", "--target", "60", "0", "10", "--noise-ppm", "5",
                              "--data-out", tmp_path / "m.csv", "--format", "json"], capsys)
    assert status == 0
    rec = json.loads(out)
    assert rec["fit"]["kind"] == "position" and rec["fit"]["readings"] == 50
    assert rec["max_abs_normalized_error"] < 4.5
    header = (tmp_path / "m.csv").read_text().splitlines()[0].split(",")
    assert header[:8] == ["point", "q1", "q2", "q3", "q4", "q5", "q6", "target"]
    status, out, _ = run_cli(["calibrate", "identify", "--robot", "stewart_6ups", "--data", tmp_path / "m.csv",
                              "--target", "0", "0", "30", "--target", "60", "0", "10", "--out", tmp_path / "id.json",
                              "--robot-out", tmp_path / "id.toml", "--format", "json"], capsys)
    assert status == 0
    again = json.loads(out)
    # the file holds what the simulation measured: the same estimates come out of it
    est = {p["name"]: p["estimate"] for p in again["parameters"]}
    for p in rec["parameters"]:
        assert est[p["name"]] == pytest.approx(p["estimate"], abs=1e-6)
    robot = SpatialManipulator.load(str(tmp_path / "id.toml"))
    assert np.allclose(robot.legs[0].base, [est[f"legs[1].base.{a}"] for a in "xyz"], atol=1e-9)
    assert json.loads((tmp_path / "id.json").read_text())["identifiability"]["fixed"] == again["identifiability"]["fixed"]


def test_simulate_full_pose_delta_table(capsys):
    status, out, _ = run_cli(["calibrate", "simulate", "--robot", "delta_clavel", "--poses", "30"], capsys)
    assert status == 0
    assert "legs[1].arm" in out and "note: " in out and "cannot be separated" in out


@pytest.mark.parametrize("argv, needle", [
    (["calibrate", "simulate", "--robot", "symmetric_3rpr", "--target", "0", "0", "1"], "--target"),
    (["calibrate", "simulate", "--robot", "stewart_6ups", "--noise-ppm", "3"], "--noise-ppm"),
    (["calibrate", "simulate", "--robot", "stewart_6ups", "--clearances", "rpr_typical"], "--clearances"),
    (["calibrate", "simulate", "--robot", "symmetric_3rpr", "--plan", "random"], "--plan"),
    (["calibrate", "report", "--robot", "stewart_6ups", "--out", "r.html", "--clearances", "rpr_typical"],
     "--clearances"),
    (["calibrate", "plan", "--robot", "symmetric_3rpr", "--target", "0", "0", "1"], "--target"),
    (["calibrate", "plan", "--robot", "stewart_6ups", "--grid", "5"], "--grid"),
])
def test_bad_input_exits_2_with_one_line(argv, needle, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, _, err = run_cli(argv, capsys)
    assert status == 2 and len(err.splitlines()) == 1 and needle in err and "Traceback" not in err


def test_bad_csv_exits_2_naming_the_file(tmp_path, capsys):
    path = tmp_path / "m.csv"
    path.write_text("point,q1,q2,q3,q4,q5,q6,x,y,z,roll_deg,pitch_deg,yaw_deg\n1,400,400,400,400,400,400,0,0,1,0,0,x\n")
    status, _, err = run_cli(["calibrate", "identify", "--robot", "stewart_6ups", "--data", path], capsys)
    assert status == 2 and len(err.splitlines()) == 1 and "m.csv" in err and "yaw_deg" in err
    status, _, err = run_cli(["calibrate", "identify", "--robot", "stewart_6ups", "--data", path, "--target", "0",
                              "0", "1"], capsys)
    assert status == 2 and "targets were given" in err


def test_plan_writes_the_csv_to_fill(tmp_path, capsys):
    status, out, _ = run_cli(["calibrate", "plan", "--robot", "delta_clavel", "--poses", "20", "--candidates", "2000",
                              "--target", "0", "0", "-20", "--target", "30", "0", "-20", "--out", tmp_path / "p.csv",
                              "--format", "json"], capsys)
    assert status == 0
    rec = json.loads(out)
    assert rec["indices"][0]["O1"] > rec["indices"][1]["O1"] and len(rec["poses"]) == 20
    lines = (tmp_path / "p.csv").read_text().splitlines()
    assert lines[0].startswith("point,q1_deg,q2_deg,q3_deg,target,x,y,z") and len(lines) == 41
    # the commands are the nominal robot's at the planned poses (its inverse kinematics, in degrees)
    robot = SpatialManipulator.preset("delta_clavel")
    from pmaccuracy.kinematics.spatial import inverse_kinematics, poses_from_coordinates
    c = np.array([[p[k] for k in ("x", "y", "z", "roll_deg", "pitch_deg", "yaw_deg")] for p in rec["poses"]])
    q = inverse_kinematics(robot, poses_from_coordinates(c, degrees=True)).q
    first = [float(v) for v in lines[1].split(",")[1:4]]
    assert np.allclose(np.degrees(q[0]), first, atol=1e-9)


def test_identify_record_then_compensate(tmp_path, capsys):
    """identify --out writes the record compensate reads; the compensated commands are the identified robot's
    inverse kinematics of the target in the base frame (here: through the leg lengths written out)."""
    status, _, _ = run_cli(["calibrate", "simulate", "--robot", "stewart_6ups", "--poses", "25", "--seed", "4",
                            "--data-out", tmp_path / "m.csv", "--format", "csv"], capsys)
    assert status == 0
    status, out, _ = run_cli(["calibrate", "identify", "--robot", "stewart_6ups", "--data", tmp_path / "m.csv",
                              "--out", tmp_path / "id.json", "--format", "json"], capsys)
    assert status == 0
    est = {p["name"]: p["estimate"] for p in json.loads(out)["parameters"]}
    (tmp_path / "goal.csv").write_text("x,y,z,roll_deg,pitch_deg,yaw_deg\n10,20,420,3,-2,5\n")
    status, out, _ = run_cli(["calibrate", "compensate", "--identification", tmp_path / "id.json", "--poses-csv",
                              tmp_path / "goal.csv", "--format", "json"], capsys)
    assert status == 0
    row = json.loads(out)[0]
    from scipy.spatial.transform import Rotation
    R = Rotation.from_euler("xyz", [3, -2, 5], degrees=True).as_matrix()
    for i in range(1, 7):   # frame fixed at the identity (unidentifiable with full poses): base frame = device's
        A = np.array([est[f"legs[{i}].base.{a}"] for a in "xyz"])
        b = np.array([est[f"legs[{i}].platform.{a}"] for a in "xyz"])
        length = np.linalg.norm(np.array([10.0, 20.0, 420.0]) + R @ b - A)
        q = (length - est[f"legs[{i}].actuator.offset"]) / est[f"legs[{i}].actuator.gain"]
        assert row[f"q{i}"] == pytest.approx(q, abs=1e-9)
    # beside them the clearance floor of the default preset there and the compensated pose's predicted sigma
    assert 0 < row["floor_dp_rms"] < row["floor_dp_max"] < 1.0 and 0 < row["predicted_sigma_p"] < 0.1


def _simulate_with_report(tmp_path, capsys):
    return run_cli(["calibrate", "simulate", "--robot", "delta_clavel", "--poses", "25", "--seed", "1",
                    "--target", "0", "0", "-20", "--data-out", tmp_path / "m.csv",
                    "--report", tmp_path / "sim.html", "--format", "json"], capsys)


def test_simulate_with_clearances_writes_the_report(tmp_path, capsys):
    """simulate on the D-optimal plan with the default clearances (said on stderr): every kept reading within
    the floor plus 3 sigmas, the plan's O1 above random choices', the report written."""
    status, out, err = _simulate_with_report(tmp_path, capsys)
    assert status == 0 and "clearances: delta_typical (default)" in err
    rec = json.loads(out)
    assert rec["plan"] == "d-optimal"
    assert rec["observability"]["planned"]["O1"] > rec["observability"]["random"]["O1"]
    k, n = map(int, rec["readings_within_floor"].split(" of "))
    assert k == n and n >= 20
    html = (tmp_path / "sim.html").read_text()
    assert "beside the clearance floor" in html and html.count("data:image/png;base64") == 4


@pytest.mark.slow
def test_report_of_identified_readings(tmp_path, capsys):
    """The readings of a simulation identified and reported from the files: residuals beside the floor, no
    experiment (three figures)."""
    assert _simulate_with_report(tmp_path, capsys)[0] == 0
    status, _, _ = run_cli(["calibrate", "identify", "--robot", "delta_clavel", "--data", tmp_path / "m.csv",
                            "--target", "0", "0", "-20", "--out", tmp_path / "id.json"], capsys)
    assert status == 0
    status, out, _ = run_cli(["calibrate", "report", "--data", tmp_path / "m.csv", "--identification",
                              tmp_path / "id.json", "--clearances", "delta_typical", "--out", tmp_path / "r.html"],
                             capsys)
    assert status == 0 and "25 readings" in out
    html = (tmp_path / "r.html").read_text()
    assert "readings are within the floor" in html and html.count("data:image/png;base64") == 3
