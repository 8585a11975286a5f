"""``calibrate`` options on spatial robots with the planar meaning: ``--errors`` / ``--tolerances`` (the true
robot of ``simulate``), ``--clearances`` (states in the readings, the identification's covariance, the floor),
``--frame`` (the device frame's starting pose)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from conftest import run_cli
from pmaccuracy.accuracy.calibration.spatial_parameters import spatial_error_parameters
from pmaccuracy.model.spatial import SpatialManipulator


def test_simulate_true_robot_from_errors_and_tolerances(tmp_path, capsys):
    (tmp_path / "e.toml").write_text('"legs[1].base.x" = 0.2\n"legs[2].axis.a" = 0.05\n'
                                     '"legs[3].actuator.gain" = 5e-4\n')
    (tmp_path / "t.toml").write_text('"legs[1].platform.y" = 0.1\n"legs[2].axis.b" = 0.1\n')
    status, out, _ = run_cli(["calibrate", "simulate", "--robot", "rps_3", "--poses", "20", "--errors",
                              tmp_path / "e.toml", "--tolerances", tmp_path / "t.toml", "--format", "json"], capsys)
    assert status == 0
    true = json.loads(out)["true"]
    pv = spatial_error_parameters(SpatialManipulator.preset("rps_3"))
    nominal = pv.table()
    assert true["legs[1].base.x"] - nominal["legs[1].base.x"] == pytest.approx(0.2, abs=1e-12)
    assert true["legs[2].axis.a"] == pytest.approx(np.radians(0.05), abs=1e-15)
    assert true["legs[3].actuator.gain"] == pytest.approx(1.0005, abs=1e-15)
    assert 0 < abs(true["legs[1].platform.y"] - nominal["legs[1].platform.y"]) <= 0.1
    assert 0 < abs(true["legs[2].axis.b"]) <= np.radians(0.1)
    named = {"legs[1].base.x", "legs[2].axis.a", "legs[3].actuator.gain", "legs[1].platform.y", "legs[2].axis.b"}
    assert all(true[n] == nominal[n] for n in nominal if n not in named)
    (tmp_path / "bad.toml").write_text('"legs[1].axis.c" = 0.1\n')
    status, _, err = run_cli(["calibrate", "simulate", "--robot", "rps_3", "--errors", tmp_path / "bad.toml"],
                             capsys)
    assert status == 2 and len(err.splitlines()) == 1 and "legs[1].axis.c" in err


def test_clearances_in_the_readings_and_in_the_identification(tmp_path, capsys):
    """Readings with clearance states well above the noise: identified with the clearances' covariance the
    residual scale is about 1; the same file identified without it (``--clearances none``: the default is the
    architecture's typical preset) shows a scale far above 1."""
    common = ["--robot", "stewart_6ups", "--clearances", "ups_typical"]
    status, out, _ = run_cli(["calibrate", "simulate", *common, "--poses", "30", "--noise-mm", "0.002",
                              "--noise-deg", "0.002", "--data-out", tmp_path / "m.csv", "--format", "json"], capsys)
    assert status == 0
    rec = json.loads(out)
    assert 0.6 < rec["fit"]["scale"] < 1.5 and rec["floor_dp_max_mm"] > 0.01
    status, out, _ = run_cli(["calibrate", "identify", "--robot", "stewart_6ups", "--data", tmp_path / "m.csv",
                              "--clearances", "none", "--no-robust", "--format", "json"], capsys)
    assert status == 0 and json.loads(out)["fit"]["scale"] > 3
    status, out, _ = run_cli(["calibrate", "identify", *common, "--data", tmp_path / "m.csv", "--out",
                              tmp_path / "id.json", "--format", "json"], capsys)
    assert status == 0 and json.loads(out)["fit"]["scale"] == pytest.approx(rec["fit"]["scale"], rel=1e-6)
    (tmp_path / "goal.csv").write_text("x,y,z,roll_deg,pitch_deg,yaw_deg\n10,20,420,3,-2,5\n")
    status, out, _ = run_cli(["calibrate", "compensate", "--identification", tmp_path / "id.json", "--poses-csv",
                              tmp_path / "goal.csv", *common[2:], "--format", "json"], capsys)
    assert status == 0
    row = json.loads(out)[0]
    assert 0 < row["floor_dp_rms"] < row["floor_dp_max"] < 1.0
    assert 0 < row["floor_dtheta_rms_deg"] < row["floor_dtheta_max_deg"]


def test_frame_starts_the_device_frame(tmp_path, capsys):
    """Readings of a device turned 90 deg about z and moved: with ``--frame`` (the device's pose in the robot's
    base frame) the identification finds the same legs as from the original readings, and the frame parameters
    (the base frame in the device's) are the inverse of that pose."""
    status, _, _ = run_cli(["calibrate", "simulate", "--robot", "stewart_6ups", "--poses", "25", "--seed", "5",
                            "--data-out", tmp_path / "m.csv", "--format", "csv"], capsys)
    assert status == 0
    rows = list(csv.DictReader((tmp_path / "m.csv").open()))
    D = Rotation.from_euler("xyz", [0.0, 0.0, 90.0], degrees=True)          # the device in the base frame
    t = np.array([500.0, -200.0, 50.0])
    for r in rows:                           # m' = D^-1 (m - t): the readings in the device's frame
        m = np.array([float(r[k]) for k in ("x", "y", "z")])
        R = Rotation.from_euler("xyz", [float(r[k]) for k in ("roll_deg", "pitch_deg", "yaw_deg")], degrees=True)
        r.update(zip(("x", "y", "z"), (str(float(v)) for v in D.inv().apply(m - t))))
        r.update(zip(("roll_deg", "pitch_deg", "yaw_deg"), (str(float(v)) for v in (D.inv() * R).as_euler("xyz", degrees=True))))
    with (tmp_path / "moved.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    est = {}
    for name, extra in (("m", []), ("moved", ["--frame", *map(str, t), "0", "0", "90"])):
        status, out, err = run_cli(["calibrate", "identify", "--robot", "stewart_6ups", "--data",
                                    tmp_path / f"{name}.csv", *extra, "--format", "json"], capsys)
        assert status == 0, err
        est[name] = {p["name"]: p["estimate"] for p in json.loads(out)["parameters"]}
    for k, v in est["m"].items():
        if k.startswith("legs["):
            assert est["moved"][k] == pytest.approx(v, abs=1e-6), k
    F = np.array([est["moved"][f"frame.{a}"] for a in ("x", "y", "z")])
    assert np.allclose(F, D.inv().apply(-t), atol=1e-6)
    status, _, err = run_cli(["calibrate", "identify", "--robot", "stewart_6ups", "--data", tmp_path / "m.csv",
                              "--frame", "1", "2", "3"], capsys)
    assert status == 2 and len(err.splitlines()) == 1 and "--frame" in err


def test_compensate_floor_of_a_lower_mobility_robot(tmp_path, capsys):
    """A 3-RPS's targets give z, roll, pitch; the floor is taken where the compensated commands put it (x, y, yaw
    completed), a finite worst case and RMS; at home (the nominal robot identified from its own noise-free readings)
    the worst case of the error model there."""
    from pmaccuracy.accuracy.calibration.spatial_identify import identify_spatial, spatial_identification_to_dict
    from pmaccuracy.accuracy.calibration.spatial_simulate import candidate_poses, measure_spatial
    from pmaccuracy.kinematics.spatial import inverse_kinematics
    from pmaccuracy.accuracy.spatial_bounds import spatial_pose_errors
    from pmaccuracy.kinematics.spatial import reference_pose
    from pmaccuracy.model.spatial_sources import SpatialErrorSources

    pv = spatial_error_parameters(SpatialManipulator.preset("rps_3"))
    commands = inverse_kinematics(pv.robot, candidate_poses(pv, 100, seed=1)[:12]).q
    ident = identify_spatial(measure_spatial(pv, pv.nominal, commands, noise=(0.0, 0.0)), pv)
    record = spatial_identification_to_dict(ident)
    (tmp_path / "id.json").write_text(json.dumps(record))
    # a record written before the axis angles were parameters still reads, with them at nominal
    from pmaccuracy.accuracy.calibration.spatial_identify import spatial_identification_from_dict
    old = dict(record, parameters=[p for p in record["parameters"] if not p["name"].endswith((".a", ".b"))])
    back = spatial_identification_from_dict(old)
    axes = pv.index([n for n in pv.names if n.endswith((".a", ".b"))])
    assert len(axes) == 6 and np.all(back.values[axes] == 0.0) and np.all(back.sigma[axes] == 0.0)
    home = reference_pose(ident.robot)
    z = float(home[2])
    (tmp_path / "goal.csv").write_text(f"x,y,z,roll_deg,pitch_deg,yaw_deg\n5,5,{z},1,2,0\n0,0,{z},0,0,0\n")
    status, out, err = run_cli(["calibrate", "compensate", "--identification", tmp_path / "id.json", "--poses-csv",
                                tmp_path / "goal.csv", "--clearances", "rps_typical", "--format", "json"], capsys)
    assert status == 0, err
    rows = json.loads(out)
    assert all(0 < r["floor_dp_rms"] < r["floor_dp_max"] < 1.0 for r in rows)
    robot = ident.robot
    at_home = spatial_pose_errors(robot, SpatialErrorSources.load("rps_typical", robot), home[None])
    assert np.allclose(ident.values[pv.frame_index], 0.0, atol=1e-9)   # noise-free readings of the nominal
    assert rows[1]["floor_dp_max"] == pytest.approx(float(at_home.dp_upper[0]), rel=1e-6)


def test_chain_robot_without_clearances_runs_on_the_readings_alone(tmp_path, capsys):
    """A chain robot has no typical error-source preset: without ``--clearances`` the calibration runs with none
    (said on stderr; no floor in the output) instead of failing."""
    import tomli_w
    from chain_builders import chain_table

    (tmp_path / "chain.toml").write_text(tomli_w.dumps(chain_table(SpatialManipulator.preset("rps_3"))))
    status, out, err = run_cli(["calibrate", "simulate", "--robot", tmp_path / "chain.toml", "--poses", "15",
                                "--format", "json"], capsys)
    assert status == 0, err
    assert "clearances: none, no preset for a spatial-chain robot (default)" in err
    rec = json.loads(out)
    assert "floor_dp_max_mm" not in rec and "readings_within_floor" not in rec and rec["fit"]["clearances"] is None


def test_report_of_a_virtual_experiment_takes_the_true_robot(tmp_path, capsys):
    """``calibrate report --errors`` builds the experiment's true robot as ``simulate`` does: a bad name is one
    line naming it; a large base error shows in the report's 'before' residuals (none without it)."""
    (tmp_path / "e.toml").write_text('"legs[1].base.x" = 3.0\n')
    (tmp_path / "bad.toml").write_text('"legs[1].nope" = 3.0\n')
    status, _, err = run_cli(["calibrate", "report", "--robot", "rps_3", "--errors", tmp_path / "bad.toml",
                              "--out", tmp_path / "x.html"], capsys)
    assert status == 2 and len(err.splitlines()) == 1 and "legs[1].nope" in err
    pages = {}
    for name, extra in (("with", ["--errors", tmp_path / "e.toml"]), ("without", [])):
        status, _, err = run_cli(["calibrate", "report", "--robot", "rps_3", *extra, "--out",
                                  tmp_path / f"{name}.html"], capsys)
        assert status == 0, err
        pages[name] = (tmp_path / f"{name}.html").read_text()
    assert pages["with"] != pages["without"]
