"""The calibration report of a serial arm (issue 23): it used to crash on an arm (the parallel robot's
candidate grid, workspace outline and inverse-kinematic residual). Checked here: the residual maps' numbers
against the reference arm pose (tests/reference/serial_calibration_reference.py, the guide's convention (docs/guide/formats.md) written
apart), the clearance floor against :func:`pmaccuracy.model.serial.max_serial_errors` called directly at the
joint values ``offset + gain * command`` computed here from the parameter names, the indices against
:func:`plan_poses` of the arm, and the command line (``calibrate simulate --report``, ``calibrate report``).
"""

from __future__ import annotations

import html

import numpy as np
import pytest
from serial_calibration_reference import arm_poses

import pmaccuracy as pm
from pmaccuracy.accuracy.calibration.plan import plan_poses
from pmaccuracy.cli import main
from pmaccuracy.model.serial import SerialArm, max_serial_errors
from pmaccuracy.report.calibration_report import model_residuals

ARM, CLEARANCES, POSES, SEED = "planar_3r_arm", "arm_typical", 14, 3


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("calreport_arm")
    pv = pm.error_parameters(SerialArm.preset(ARM))
    ex = pm.simulate_calibration(pv, POSES, seed=SEED, clearances=CLEARANCES, n_targets=15)
    results = pm.calibration_report(out / "arm.html", ex.identification, ex.data, experiment=ex, seed=SEED)
    return pv, ex, results, html.unescape((out / "arm.html").read_text(encoding="utf-8"))


@pytest.mark.parametrize("which", ["before", "after"])
def test_arm_residuals_are_the_reference_forward_residuals(run, which):
    pv, ex, _, _ = run
    ident, data = ex.identification, ex.data
    values = pv.nominal if which == "before" else ident.values
    r = model_residuals(ident, data, values)
    ref = data.poses - arm_poses(pv.table(values), pv.robot.kinds, data.commands)
    ref[:, 2] = np.angle(np.exp(1j * ref[:, 2]))
    np.testing.assert_allclose(r, ref, atol=1e-9)
    assert np.hypot(*r[:, :2].T).max() > 0.3 if which == "before" else np.hypot(*r[:, :2].T).max() < 0.2


def test_arm_report_sections(run):
    pv, ex, results, page = run
    assert results["serial"] is True and results["points"] == len(ex.data)
    planned = plan_poses(pv, len(ex.data), seed=SEED)
    assert results["indices"]["planned"]["O1"] == pytest.approx(planned.index["O1"], rel=1e-9)
    if np.allclose(ex.data.commands, planned.commands):   # measured where planned: the same index, recomputed
        assert results["indices"]["poses"]["O1"] == pytest.approx(planned.index["O1"], rel=1e-6)
    assert results["indices"]["poses"]["O1"] > 0
    acc = results["accuracy"]
    assert acc["where"] == "targets" and acc["poses"] == len(ex.targets)
    np.testing.assert_allclose(acc["after_mm"], np.hypot(*ex.errors_after[:, :2].T), rtol=1e-12)
    assert acc["floor"] is not None and len(acc["floor"]["dp_max_mm"]) == len(ex.targets)
    assert "positions the nominal arm reaches within its joint ranges" in page
    assert "forward residual" in page and "Traceback" not in page


def test_arm_measured_data_floor_at_the_joint_values(run, tmp_path):
    pv, ex, _, _ = run
    ident, data = ex.identification, ex.data
    res = pm.calibration_report(tmp_path / "data.html", ident, data, clearances=CLEARANCES, seed=SEED)
    acc = res["accuracy"]
    assert acc["where"] == "measured poses"
    after = model_residuals(ident, data)
    keep = ~np.isin(np.asarray(data.labels), ident.outliers)
    t = pv.table(ident.values)
    n = pv.robot.n
    q = np.stack([t[f"joint{k}.actuator.offset"] + t[f"joint{k}.actuator.gain"] * data.commands[keep, k - 1]
                  for k in range(1, n + 1)], axis=-1)
    arm = pv.split(ident.values)[0]
    b = max_serial_errors(arm, CLEARANCES, q, allow_outside=True)
    np.testing.assert_allclose(acc["floor"]["dp_max_mm"], b.dp_max, rtol=1e-9)
    np.testing.assert_allclose(acc["floor"]["dphi_max_deg"], np.degrees(b.dphi_max), rtol=1e-9)
    np.testing.assert_allclose(acc["after_mm"], np.hypot(after[keep, 0], after[keep, 1]), rtol=1e-12)


def test_cli_arm_simulate_report_and_report(tmp_path, capsys):
    assert main(["calibrate", "simulate", "--robot", ARM, "--poses", "12", "--report", str(tmp_path / "s.html"),
                 "--data-out", str(tmp_path / "m.csv"), "--format", "csv"]) == 0
    assert main(["calibrate", "identify", "--robot", ARM, "--data", str(tmp_path / "m.csv"), "--out",
                 str(tmp_path / "id.json"), "--format", "csv"]) == 0
    assert main(["calibrate", "report", "--data", str(tmp_path / "m.csv"), "--identification",
                 str(tmp_path / "id.json"), "--clearances", CLEARANCES, "--out", str(tmp_path / "d.html")]) == 0
    assert main(["calibrate", "report", "--robot", ARM, "--poses", "12", "--clearances", CLEARANCES,
                 "--out", str(tmp_path / "r.html")]) == 0
    out = capsys.readouterr()
    assert "internal error" not in out.err
    for f in ("s.html", "r.html", "d.html"):
        assert (tmp_path / f).read_text(encoding="utf-8").startswith("<!DOCTYPE html>")
