"""``pmaccuracy calibrate`` on a serial arm (``--robot planar_3r_arm`` or a serial robot file): the steps
chained through files, checked against the reference arm pose (tests/reference/serial_calibration_reference.py),
and bad input (exit 2, one line)."""

from __future__ import annotations

import csv
import json
import math

import numpy as np

from serial_calibration_reference import arm_poses
from conftest import run_cli


def run(argv, capsys):
    return run_cli(argv, capsys)


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


def test_phi_in_radians_with_a_small_orientation_range_refused_serial(tmp_path, capsys):
    """A serial arm's calibration CSV whose phi_deg column holds radians, the configurations keeping the
    orientation within +-5 deg (0.09 at most: within the far-point checks) is refused naming the file and
    the column; the same file in degrees is identified."""
    from pmaccuracy.accuracy.calibration.data import write_calibration_csv
    from pmaccuracy.accuracy.calibration.parameters import error_parameters
    from pmaccuracy.accuracy.calibration.simulate import measure_serial, true_parameters
    from pmaccuracy.model.serial import SerialArm

    arm = SerialArm.preset("planar_3r_arm")
    pv = error_parameters(arm)
    rng = np.random.default_rng(3)
    q12 = rng.uniform(np.radians([-150.0, -130.0]), np.radians([150.0, 130.0]), size=(30, 2))
    q12 = q12[np.abs(q12.sum(axis=1)) < np.radians(170.0)][:20]
    q = np.column_stack([q12, -q12.sum(axis=1) + rng.uniform(-np.radians(5.0), np.radians(5.0), len(q12))])
    m = measure_serial(pv, true_parameters(pv, seed=1, fixed=("frame.x", "frame.y", "frame.phi")), q, seed=2)
    assert len(q) == 20 and np.degrees(np.abs(m[:, 2])).max() < 5.1
    write_calibration_csv(arm, q, m, tmp_path / "deg.csv")
    rad = m.copy()
    rad[:, 2] = np.radians(m[:, 2])          # the file then holds phi in radians under phi_deg
    write_calibration_csv(arm, q, rad, tmp_path / "rad.csv")
    status, _, err = run(["calibrate", "identify", "--robot", "planar_3r_arm", "--data", tmp_path / "rad.csv"], capsys)
    assert status == 2 and len(err.strip().splitlines()) == 1
    assert "rad.csv: column phi_deg: holds radians" in err
    status, _, err = run(["calibrate", "identify", "--robot", "planar_3r_arm", "--data", tmp_path / "deg.csv"], capsys)
    assert status == 0, err
