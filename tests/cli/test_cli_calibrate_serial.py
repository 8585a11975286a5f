"""``pmaccuracy calibrate`` on a serial arm (``--robot planar_3r_arm`` or a serial robot file): the steps
chained through files, checked against the reference arm pose (tests/reference/serial_calibration_reference.py),
and bad input (exit 2, one line)."""

from __future__ import annotations

import csv
import json
import math

import numpy as np

from serial_calibration_reference import arm_poses
from pmaccuracy.cli import main


def run(argv, capsys):
    try:
        status = main([str(a) for a in argv])
    except SystemExit as exc:
        status = exc.code
    out = capsys.readouterr()
    return status, out.out, out.err


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_plan_simulate_identify_compensate_serial(tmp_path, capsys):
    status, out, _ = run(["calibrate", "plan", "--robot", "planar_3r_arm", "--poses", "12", "--out",
                          tmp_path / "plan.csv", "--format", "json"], capsys)
    assert status == 0
    planned, rand, _ = (r["O1"] for r in json.loads(out)["indices"])
    assert planned > rand
    assert list(_rows(tmp_path / "plan.csv")[0])[:4] == ["point", "q1_deg", "q2_deg", "q3_deg"]
    status, out, _ = run(["calibrate", "simulate", "--robot", "planar_3r_arm", "--poses", "20", "--seed", "3",
                          "--data-out", tmp_path / "m.csv", "--format", "json"], capsys)
    assert status == 0
    summary = json.loads(out)["summary"]
    assert summary["max_error_after_mm"] < 0.2 * summary["max_error_before_mm"]
    status, out, _ = run(["calibrate", "identify", "--robot", "planar_3r_arm", "--data", tmp_path / "m.csv",
                          "--out", tmp_path / "id.json", "--robot-out", tmp_path / "id.toml", "--format", "json"],
                         capsys)
    assert status == 0
    rec = json.loads(out)
    assert "frame.phi" in rec["identifiability"]["fixed"]
    est = {p["name"]: p["estimate"] for p in rec["parameters"]}
    status, out, err = run(["calibrate", "compensate", "--identification", tmp_path / "id.json", "--pose", 400, 100,
                            30, "--out", tmp_path / "cmd.csv", "--format", "json"], capsys)
    assert status == 0, err
    row = _rows(tmp_path / "cmd.csv")[0]
    q = np.radians([[float(row[f"q{k}_deg"]) for k in (1, 2, 3)]])
    reached = arm_poses(est, "RRR", q)[0]     # the identified arm at the compensated commands: the target
    assert np.allclose(reached, [400.0, 100.0, math.radians(30.0)], atol=1e-6)
    status, out, _ = run(["calibrate", "identify", "--robot", tmp_path / "id.toml", "--data", tmp_path / "m.csv",
                          "--format", "csv"], capsys)
    assert status == 0 and out.startswith("parameter,unit,nominal")


def test_bad_input_serial(tmp_path, capsys):
    status, _, err = run(["calibrate", "plan", "--robot", "planar_3r_arm", "--grid", "5"], capsys)
    assert status == 2 and "--grid" in err and len(err.strip().splitlines()) == 1
    path = tmp_path / "m.csv"
    assert run(["calibrate", "simulate", "--robot", "planar_3r_arm", "--poses", "12", "--data-out", path], capsys)[0] == 0
    path.write_text(path.read_text().replace("q2_deg", "q2", 1))
    status, _, err = run(["calibrate", "identify", "--robot", "planar_3r_arm", "--data", path], capsys)
    assert status == 2 and "m.csv" in err and "joint 2's actuator is revolute" in err
    assert len(err.strip().splitlines()) == 1
    path.write_text("point,x_nom,y_nom,phi_nom_deg,push,x,y,phi_deg\n1,0,0,0,+x,0,0,0\n")
    status, _, err = run(["calibrate", "identify", "--robot", "planar_3r_arm", "--data", path], capsys)
    assert status == 2 and "needs the commands q1_deg,q2_deg,q3_deg" in err
    status, _, err = run(["calibrate", "identify", "--robot", "planar_3r_arm", "--data", path, "--fix", "leg1.base.x"],
                         capsys)
    assert status == 2 and "leg1.base.x" in err
