"""``pmaccuracy calibrate``: the steps chained through files, the formats, and bad input (exit 2, one line)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from pmaccuracy.model.manipulator import Manipulator
from conftest import run_cli


def run(argv, capsys):
    return run_cli(argv, capsys)


def test_plan_simulate_identify_compensate(tmp_path, capsys):
    status, out, _ = run(["calibrate", "plan", "--robot", "symmetric_3rpr", "--poses", "24", "--out",
                          tmp_path / "plan.csv", "--format", "json"], capsys)
    assert status == 0
    rec = json.loads(out)
    planned, rand, grid = (r["O1"] for r in rec["indices"])
    assert planned > rand and planned > grid and len(rec["poses"]) == 24
    header = (tmp_path / "plan.csv").read_text().splitlines()[0]
    assert header == "point,q1,q2,q3,x,y,phi_deg"
    status, out, _ = run(["calibrate", "simulate", "--robot", "symmetric_3rpr", "--poses", "30", "--seed", "1",
                          "--clearances", "rpr_typical", "--data-out", tmp_path / "m.csv", "--format", "json"], capsys)
    assert status == 0
    summary = json.loads(out)["summary"]
    assert summary["max_error_after_mm"] < min(0.2 * summary["max_error_before_mm"], summary["floor_dp_max_mm"])
    status, out, _ = run(["calibrate", "identify", "--robot", "symmetric_3rpr", "--data", tmp_path / "m.csv",
                          "--clearances", "rpr_typical", "--out", tmp_path / "id.json", "--robot-out",
                          tmp_path / "id.toml", "--format", "csv"], capsys)
    assert status == 0
    fit = json.loads((tmp_path / "id.json").read_text())["fit"]
    # the clearance covariance explains the scatter (scale ~ 1; 2.5 and a false outlier without --clearances)
    assert fit["clearances"] == "rpr_typical" and 0.7 < fit["scale"] < 1.4 and fit["outliers"] == []
    rows = list(csv.DictReader(out.splitlines()))
    assert {r["status"] for r in rows if r["parameter"].startswith("frame.")} == {"fixed"}
    identified = Manipulator.load(str(tmp_path / "id.toml"))
    assert identified.architecture == "3-RPR"
    status, out, _ = run(["calibrate", "compensate", "--identification", tmp_path / "id.json", "--pose", "0", "0",
                          "0", "--clearances", "rpr_typical", "--format", "json"], capsys)
    assert status == 0
    row = json.loads(out)[0]
    assert row["floor_dp_max"] > 0 and np.isfinite(row["q1"]) and row["predicted_sigma_p"] > 0
    # the fit's residual beside the floor: the inliers' RMS position residual of the identification record
    assert row["fit_rms_position"] == fit["fit_rms_position"] and 0 < fit["fit_rms_position"] < 0.1
    assert 0 < row["floor_dphi_rms_deg"] < row["floor_dphi_max_deg"]


@pytest.mark.parametrize("argv, needle", [
    (["calibrate", "identify", "--robot", "symmetric_3rrr", "--data", "missing.csv"], "missing.csv"),
    (["calibrate", "plan", "--robot", "symmetric_3rrr", "--poses", "3"], "--poses"),
    (["calibrate", "plan", "--robot", "symmetric_3rrr", "--out", "plan.txt"], "--out"),
    (["calibrate", "compensate", "--identification", "nothing.json", "--pose", "0", "0", "0"], "nothing.json"),
    (["calibrate", "simulate", "--robot", "symmetric_3rrr", "--noise-mm", "-1"], "--noise-mm"),
])
def test_bad_input_exits_2_with_one_line(argv, needle, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, _, err = run(argv, capsys)
    assert status == 2 and len(err.splitlines()) == 1 and needle in err and "Traceback" not in err


def test_unknown_parameter_named(capsys, tmp_path):
    run(["calibrate", "simulate", "--robot", "symmetric_3rrr", "--poses", "20", "--data-out", tmp_path / "m.csv"],
        capsys)
    status, _, err = run(["calibrate", "identify", "--robot", "symmetric_3rrr", "--data", tmp_path / "m.csv",
                          "--fix", "leg4.base.x"], capsys)
    assert status == 2 and "leg4.base.x" in err and len(err.splitlines()) == 1


def test_phi_in_radians_with_a_small_orientation_range_refused(tmp_path, capsys):
    """A +-5 deg plan whose phi_deg column holds radians (0.09 at most: a plausible reading in degrees, near
    the far-point checks' blind spot) is refused naming the file and the column; the same file in degrees
    is identified."""
    import math

    from pmaccuracy.accuracy.calibration.data import write_calibration_csv
    from pmaccuracy.accuracy.calibration.parameters import error_parameters
    from pmaccuracy.accuracy.calibration.plan import candidate_poses, plan_poses
    from pmaccuracy.accuracy.calibration.simulate import measure, true_parameters

    pv = error_parameters(Manipulator.preset("symmetric_3rrr"))
    plan = plan_poses(pv, 30, candidate_poses(pv, n=12, phi_range=(math.radians(-5), math.radians(5))))
    m = measure(pv, true_parameters(pv, seed=1, fixed=("frame.x", "frame.y", "frame.phi")), plan.commands,
                plan.poses, seed=2)
    write_calibration_csv(pv.robot, plan.commands, m, tmp_path / "deg.csv")
    rad = m.copy()
    rad[:, 2] = np.radians(m[:, 2])          # the file then holds phi in radians under phi_deg
    write_calibration_csv(pv.robot, plan.commands, rad, tmp_path / "rad.csv")
    status, _, err = run(["calibrate", "identify", "--robot", "symmetric_3rrr", "--data", tmp_path / "rad.csv"], capsys)
    assert status == 2 and len(err.splitlines()) == 1
    assert "rad.csv: column phi_deg: holds radians" in err
    status, _, err = run(["calibrate", "identify", "--robot", "symmetric_3rrr", "--data", tmp_path / "deg.csv"], capsys)
    assert status == 0, err


def test_simulate_with_named_errors_and_bad_names(tmp_path, capsys):
    """--errors FILE: the true robot is the nominal plus exactly those errors (the JSON's ``true`` column),
    recovered within 4 sigma; an unknown name in --errors / --tolerances: exit 2 naming it."""
    (tmp_path / "e.toml").write_text('"leg1.base.x" = 0.3\nleg2.actuator.offset = 0.2\n')
    status, out, err = run(["calibrate", "simulate", "--robot", "symmetric_3rrr", "--poses", "20", "--errors",
                            tmp_path / "e.toml", "--clearances", "none", "--format", "json"], capsys)
    assert status == 0, err
    rows = {r["parameter"]: r for r in json.loads(out)["estimates"]}
    moved = {n for n, r in rows.items() if r["true"] != r["nominal"]}
    assert moved == {"leg1.base.x", "leg2.actuator.offset"}
    assert rows["leg2.actuator.offset"]["true"] == pytest.approx(0.2, abs=1e-12)
    for n in moved:
        assert abs(rows[n]["estimate"] - rows[n]["true"]) < 4 * rows[n]["sigma"]
    (tmp_path / "bad.toml").write_text("leg1.base.z = 0.1\n")
    for opt in ("--errors", "--tolerances"):
        status, _, err = run(["calibrate", "simulate", "--robot", "symmetric_3rrr", opt, tmp_path / "bad.toml"], capsys)
        assert status == 2 and len(err.splitlines()) == 1 and "bad.toml: leg1.base.z: no parameter" in err
    status, _, err = run(["calibrate", "simulate", "--robot", "symmetric_3rrr", "--errors", tmp_path / "e.toml",
                          "--error-mm", "0.2"], capsys)
    assert status == 2 and "--error-mm" in err


def test_report_simulation_takes_named_errors_and_tolerances(tmp_path, capsys, monkeypatch):
    """``calibrate report`` simulating passes --errors / --tolerances on as ``calibrate simulate`` does (library
    units: deg -> rad), refuses them with --data or with --error-mm, and names an unknown parameter."""
    import math

    import pmaccuracy.accuracy.calibration.simulate as simulate

    seen = {}

    def spy(pv, n_poses, **kw):
        seen.update(kw)
        raise RuntimeError("spied")
    monkeypatch.setattr(simulate, "simulate_calibration", spy)
    (tmp_path / "e.toml").write_text('"leg1.base.x" = 0.3\nleg2.actuator.offset = 0.2\n')
    (tmp_path / "t.toml").write_text('leg3.proximal = 0.05\n')
    status, _, err = run(["calibrate", "report", "--robot", "symmetric_3rrr", "--out", tmp_path / "r.html",
                          "--errors", tmp_path / "e.toml", "--tolerances", tmp_path / "t.toml", "--seed", "4"], capsys)
    assert status != 0 and "spied" in err       # reached the simulation: what did it get?
    assert seen["errors"] == {"leg1.base.x": 0.3, "leg2.actuator.offset": pytest.approx(math.radians(0.2))}
    assert seen["tolerances"] == {"leg3.proximal": 0.05} and seen["error_sigma"] is None and seen["seed"] == 4
    (tmp_path / "m.csv").write_text("x,y,phi_deg,q1_deg,q2_deg,q3_deg\n")
    (tmp_path / "bad.toml").write_text("leg1.base.z = 0.1\n")
    for extra, needle in ((["--data", tmp_path / "m.csv", "--identification", tmp_path / "id.json", "--errors",
                            tmp_path / "e.toml"], "--errors"),
                          (["--tolerances", tmp_path / "t.toml", "--error-mm", "0.2"], "--error-mm"),
                          (["--errors", tmp_path / "bad.toml"], "bad.toml: leg1.base.z: no parameter")):
        status, _, err = run(["calibrate", "report", "--out", tmp_path / "r.html"] + extra, capsys)
        assert status == 2 and len(err.splitlines()) == 1 and needle in err, err
