"""``load`` and ``preload`` on spatial robots: the library's numbers in degrees, the preload checked with the
independent member forces (tests/reference/spatial_load_reference.py), bad input in one line."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import spatial_load_reference as lref
import spatial_reference as ref
from conftest import run_cli

import pmaccuracy as pm
from pmaccuracy.kinematics import spatial as k


def test_load_hexapod_matches_the_library(capsys):
    argv = ["load", "--robot", "stewart_6ups", "--pose", 5, -3, 410, 2, -1, 4, "--fx", 20, "--fz", -100, "--my", 500,
            "--mass", 2, "--com", 0, 10, 50, "--details", "--format", "json"]
    status, out, err = run_cli(argv, capsys)
    assert status == 0, err
    rec = json.loads(out)[0]
    robot = pm.load_robot("stewart_6ups")
    pose = k.poses_from_coordinates([5, -3, 410, 2, -1, 4], degrees=True)
    load = pm.SpatialLoad(force=(20, 0, -100), moment=(0, 500, 0), mass=2.0, com=(0, 10, 50))
    lib = pm.loaded_pose_error(robot, "ups_typical", pose, load)
    assert rec["dz"] == pytest.approx(lib.error[2], rel=1e-12)
    assert rec["dry_deg"] == pytest.approx(math.degrees(lib.error[4]), rel=1e-12, abs=1e-15)
    assert [rec[f"lambda{i}"] for i in range(1, 7)] == pytest.approx(lib.statics.intensity, rel=1e-12)
    assert rec["leg1.joint3.fz_N"] == pytest.approx(lib.statics.reactions[0, 2, 2], rel=1e-12)
    assert rec["yaw_deg"] == pytest.approx(4.0) and rec["undetermined"] == "-"
    assert "clearances: ups_typical (default)" in err


def test_preload_holds_the_rows_signs_per_the_reference(capsys):
    argv = ["preload", "--robot", "rps_3", "--pose", 350, 2, -1, "--fz", -40, -10, "--mx", -800, 800,
            "--format", "json"]
    status, out, err = run_cli(argv, capsys)
    assert status == 0, err
    rec = json.loads(out)[0]
    keys = ("fx_N", "fy_N", "fz_N", "mx_Nmm", "my_Nmm", "mz_Nmm")
    P = np.array([rec[f"preload_{key}"] for key in keys])
    pattern = np.array([1.0 if c == "+" else -1.0 for c in rec["pattern"]])
    rdict = ref.load(Path(__file__).resolve().parents[2] / "src" / "pmaccuracy" / "data" / "robots" / "rps_3.toml")
    p = np.array([rec["x"], rec["y"], rec["z"]])
    R = ref.rotation([rec["roll_deg"], rec["pitch_deg"], rec["yaw_deg"]])
    lo = np.array([0, 0, -40, -800, 0, 0.0])
    hi = np.array([0, 0, -10, 800, 0, 0.0])
    for corner in np.array(np.meshgrid(*zip(lo, hi))).reshape(6, -1).T:
        lam = lref.member_forces(rdict, p, R, P + corner)
        assert np.all(lam * pattern >= 1e-6 * (1 - 1e-6)), lam


@pytest.mark.parametrize("argv, words", [
    (["load", "--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0, "--mass", -1], "--mass"),
    (["load", "--robot", "stewart_6ups", "--pose", 0, 0, 900, 0, 0, 0, "--fz", -1], "--pose: pose 1"),
    (["load", "--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0], "the load is zero"),
    (["load", "--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0, "--m", 3], "--m: stewart_6ups is a spatial"),
    (["load", "--robot", "stewart_6ups", "--pose", 0, 0, 400, "--fz", 1], "takes 6 values"),
    (["load", "--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0, "--fz", "nan"], "--fz"),
    (["load", "--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0, "--fz", 1, "--com", 1, 2], "--com"),
    (["load", "--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0, "--fz", 1, "--gravity", 0, 0, 0],
     "--gravity"),
    (["load", "--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0, "--fz", 1, "--map"], "--map"),
    (["load", "--robot", "symmetric_3rpr", "--pose", 0, 0, 0, "--fz", 1], "--fz: is for spatial robots"),
    (["load", "--robot", "symmetric_3rpr", "--pose", 0, 0, 0, 0, "--fx", 1], "three values"),
    (["preload", "--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0, "--fz", 1, -1], "--fz: needs LO <= HI"),
    (["preload", "--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0], "a single wrench"),
    (["preload", "--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0, "--fz", -1, 1, "--box=-1,1,-1,1,399,401"],
     "--pose"),
    (["preload", "--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0, "--fz", -1, 1, "--grid", 4], "--grid"),
    (["preload", "--robot", "stewart_6ups", "--fz", -1, 1, "--disc", 0, 0, 5], "--disc"),
    (["preload", "--robot", "stewart_6ups", "--fz", -1, 1, "--box", "1,2,3"], "--box"),
    (["preload", "--robot", "stewart_6ups", "--fz", -1, 1, "--direction", 0, 0, 1, 0, 0, 0], "--direction"),
    (["preload", "--robot", "stewart_6ups", "--fz", -1, 1, "--map"], "--out"),
    (["preload", "--robot", "rps_3", "--fz", -1, 1, "--map", "--out", "m.nc", "--orientation-deg", 0, 0, 0],
     "--orientation-deg"),
    (["load", "--robot", "stewart_6ups", "--fz", -1, "--map", "--out", "m.txt"], "--out"),
    (["preload", "--robot", "delta_clavel", "--pose", 0, 0, -900, "--fx", -10, 10, "--springs"], "--springs"),
    (["preload", "--robot", "rps_3", "--pose", 350, 2, -1, "--fx", -10, 10, "--springs"], "--springs: no springs"),
    (["preload", "--robot", "stewart_6ups", "--fz", -1, 1, "--springs"], "--springs"),
    (["preload", "--robot", "symmetric_3rpr", "--pose", 0, 0, 0, "--fx", -1, 1, "--springs"], "--springs"),
    (["load", "--robot", "stewart_6ups", "--fz", -1, "--map", "--out", "m.nc", "--grid", 1], "--grid"),
    (["load", "--robot", "stewart_6ups", "--fz", -1, "--map", "--out", "m.nc", "--details"], "--details"),
    (["load", "--robot", "stewart_6ups", "--fz", -1, "--map", "--out", "m.nc", "--box=0,1,0,1,400,401"],
     "--pose"),
    (["load", "--robot", "symmetric_3rpr", "--pose", 0, 0, 0, "--fx", 1, "--orientation-deg", 0, 0, 0],
     "--orientation-deg"),
    (["preload", "--robot", "upu_3", "--pose", 0, 0, 300, "--fz", -30, -10, "--direction", 0, 0, -1, 0, 0, 0],
     "--direction"),
    (["preload", "--robot", "symmetric_3rpr", "--pose", 0, 0, 0, "--fx", -1, 1, "--fz", -1, 1], "--fz"),
])
def test_bad_input_one_line(argv, words, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, out, err = run_cli(argv, capsys)
    lines = err.strip().splitlines()
    assert status == 2 and len(lines) == 1 and words in lines[0], err
    assert "Traceback" not in err


def test_load_map_matches_the_library(capsys, tmp_path):
    """``load --map`` on a Delta writes the library's map; its CSV has the rotations in degrees."""
    import pandas as pd

    out = tmp_path / "l.csv"
    status, _, err = run_cli(["load", "--robot", "delta_clavel", "--map", "--grid", 4, "--out", out, "--fz", -30,
                              "--mx", 200, "--format", "json"], capsys)
    assert status == 0, err
    df = pd.read_csv(out)
    lib = pm.spatial_loaded_error_map(pm.load_robot("delta_clavel"), "delta_typical",
                                      pm.SpatialLoad(force=(0, 0, -30.0), moment=(200.0, 0, 0)), n=4)
    flat = lib.to_dataframe().reset_index().dropna(subset=["dx"])
    assert len(df) == len(flat) > 0
    assert np.allclose(df["dz"], flat["dz"], rtol=1e-12, atol=1e-15)
    assert np.allclose(df["dry_deg"], np.degrees(flat["dry"]), rtol=1e-12, atol=1e-15)


def test_region_preload_holds_per_the_reference(capsys):
    """``preload`` without poses on a 3-UPU box: the preload keeps every member's sign at the box's corners of
    poses for every corner of the process box (reference member forces)."""
    argv = ["preload", "--robot", "upu_3", "--box=-10,10,-10,10,290,310", "--grid", 2, "--fz", -40, -20,
            "--mx", -300, 300, "--format", "json"]
    status, out, err = run_cli(argv, capsys)
    assert status == 0, err
    rec = json.loads(out)[0]
    keys = ("fx_N", "fy_N", "fz_N", "mx_Nmm", "my_Nmm", "mz_Nmm")
    P = np.array([rec[f"preload_{key}"] for key in keys])
    pattern = np.array([1.0 if c == "+" else -1.0 for c in rec["pattern"]])
    rdict = ref.load(Path(__file__).resolve().parents[2] / "src" / "pmaccuracy" / "data" / "robots" / "upu_3.toml")
    corners = lref.box_corners([0, 0, -30, 0, 0, 0], [0, 0, 10, 300, 0, 0])
    for p in np.array(np.meshgrid([-10, 10], [-10, 10], [290, 310])).reshape(3, -1).T:
        lam = np.linalg.solve(lref.member_wrenches(rdict, p, np.eye(3)), -(P + corners).T).T
        assert np.all(lam * pattern >= 1e-6 * (1 - 1e-6)), (p, lam)
    assert rec["n_check"] >= 8 and rec["preload_size_N"] > 0


def test_springs_hold_every_leg_per_the_reference(capsys):
    """``preload --springs`` on a 6-UPS at two poses: with the springs' forces along the legs every member keeps
    its sign at every corner of the process box at both poses (reference member forces)."""
    argv = ["preload", "--robot", "stewart_6ups", "--pose", 0, 0, 400, 0, 0, 0, "--pose", 5, 5, 420, 1, 2, 3,
            "--fx", -10, 10, "--fz", -30, 10, "--springs", "--format", "json"]
    status, out, err = run_cli(argv, capsys)
    assert status == 0, err
    rec = json.loads(out)[0]
    sigma = np.array([rec[f"spring{i}_N"] for i in range(1, 7)])
    pattern = np.array([1.0 if c == "+" else -1.0 for c in rec["pattern"]])
    rdict = ref.load(Path(__file__).resolve().parents[2] / "src" / "pmaccuracy" / "data" / "robots" /
                     "stewart_6ups.toml")
    corners = lref.box_corners([0, 0, -10, 0, 0, 0], [10, 0, 20, 0, 0, 0])
    for coords in ([0, 0, 400, 0, 0, 0], [5, 5, 420, 1, 2, 3]):
        p, R = np.array(coords[:3], float), ref.rotation(coords[3:])
        lam = np.array([lref.member_forces(rdict, p, R, F) for F in corners]) - sigma   # a spring along each leg
        assert np.all(lam * pattern >= 1e-6 * (1 - 1e-6)), lam
    assert rec["springs_size_N"] == pytest.approx(np.abs(sigma).max())
