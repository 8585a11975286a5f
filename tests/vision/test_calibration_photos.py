"""The photos path of kinematic calibration (issue 23): the planned poses rendered as photos, measured as
``vision pose`` does, identified. The truth is the true robot's parameters and its exact forward
kinematics (pmaccuracy.kinematics.forward_kinematics, a polynomial solve apart from the vision code)."""

from __future__ import annotations

import numpy as np
import pytest

from pmaccuracy.accuracy.calibration.identify import identify
from pmaccuracy.accuracy.calibration.parameters import error_parameters
from pmaccuracy.accuracy.calibration.plan import plan_poses
from pmaccuracy.accuracy.calibration.simulate import simulate_calibration, true_parameters
from pmaccuracy.cli import main
from pmaccuracy.errors import MeasurementFileError, VisionError
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.vision.calibration_photos import measure_calibration_photos, photo_measurer, render_calibration_photos

FRAME = ("frame.x", "frame.y", "frame.phi")


def test_photo_readings_agree_with_the_true_poses_within_their_sigmas(tmp_path):
    pv = error_parameters(Manipulator.preset("symmetric_3rpr"))
    plan = plan_poses(pv, 8)
    true = true_parameters(pv, seed=1, fixed=FRAME)
    manifest, poses = render_calibration_photos(pv, true, plan.commands[:4], plan.poses[:4], tmp_path,
                                                mm_per_pixel=0.5, seed=3)
    data = measure_calibration_photos(manifest, pv, mm_per_pixel=0.5)
    assert data.labels == ("1", "2", "3", "4") and np.allclose(data.commands, plan.commands[:4])
    z = (data.poses - poses) / data.sigmas
    assert np.max(np.abs(z)) < 4.0, z
    assert np.all(data.sigmas[:, :2] < 0.01)          # a 0.5 mm/px photo still reads a pose to microns


def test_bad_manifest_and_options(tmp_path, capsys):
    pv = error_parameters(Manipulator.preset("symmetric_3rpr"))
    bad = tmp_path / "manifest.csv"
    bad.write_text("image,point,q1,q2,q3,x_nom,y_nom,phi_nom_deg\n1.png,1,abc,1,1,0,0,0\n")
    with pytest.raises(MeasurementFileError, match=r"manifest\.csv: line 2"):
        measure_calibration_photos(bad, pv)
    bad.write_text("image,point,q1,q2,q3,x_nom,y_nom,phi_nom_deg\nnothere.png,1,150,150,150,0,0,0\n")
    with pytest.raises(VisionError, match="nothere.png"):
        measure_calibration_photos(bad, pv)
    status = main(["calibrate", "simulate", "--robot", "symmetric_3rpr", "--mm-per-pixel", "0.5"])
    err = capsys.readouterr().err
    assert status == 2 and "--mm-per-pixel" in err and len(err.strip().splitlines()) == 1
    status = main(["calibrate", "simulate", "--robot", "symmetric_3rpr", "--photos", str(tmp_path / "p"),
                   "--mm-per-pixel", "0"])
    assert status == 2 and "--mm-per-pixel" in capsys.readouterr().err


@pytest.mark.slow
def test_parameters_identified_from_photos_agree_with_the_truth(tmp_path):
    """Photos of 10 planned poses of a 3-RPR with errors on every parameter (the measurement frame is the
    camera's, known): every identified parameter within 3.5 of its stated sigma of the truth, and the
    compensation brings the true robot within the photos' accuracy."""
    pv = error_parameters(Manipulator.preset("symmetric_3rpr"))
    ex = simulate_calibration(pv, 10, seed=2, true_fixed=FRAME, measure_with=photo_measurer(tmp_path), n_targets=20)
    ident = ex.identification
    assert len(list(tmp_path.glob("*.png"))) == ident.n_points == 10
    free = pv.index(ident.identifiability.identified)
    z = (ident.values - ex.true)[free] / ident.sigma[free]
    assert np.all(np.isfinite(z)) and np.max(np.abs(z)) < 3.5, z
    after = np.hypot(*ex.errors_after[:, :2].T)
    assert after.max() < 0.05 * np.hypot(*ex.errors_before[:, :2].T).max()


@pytest.mark.slow
def test_identified_parameters_from_photos_have_honest_sigmas_over_seeds(tmp_path):
    """12 seeds of 10 photographed poses of a 3-RPR (18 identified parameters each): the parameter errors
    against the truth, normalized by the identification's sigmas, have unit spread within 20 % (pooled;
    measured 1.07; t-distributed with 12 degrees of freedom since the covariance is scaled by the fit's s^2),
    and, normalized by the covariance of the photos' own sigmas alone ((J^T J)^-1 = covariance / s^2, which
    only honest reading sigmas make right), chi^2 / L averages 1 within 20 % (measured 0.93; 1.22 when the
    centres' sigmas left out the background plane's error)."""
    pv = error_parameters(Manipulator.preset("symmetric_3rpr"))
    z, chi = [], []
    for seed in range(12):
        folder = tmp_path / str(seed)
        ex = simulate_calibration(pv, 10, seed=seed, true_fixed=FRAME, measure_with=photo_measurer(folder),
                                  n_targets=5)
        ident = ex.identification
        free = pv.index(ident.identifiability.identified)
        e = (ident.values - ex.true)[free]
        z.extend(e / ident.sigma[free])
        own = ident.covariance / ident.scale ** 2
        chi.append(float(e @ np.linalg.solve(own, e)) / len(free))
    z = np.array(z)
    assert 0.8 < np.sqrt(np.mean(z ** 2)) < 1.2, np.sqrt(np.mean(z ** 2))
    assert 0.8 < np.mean(chi) < 1.2, chi
    assert np.max(np.abs(z)) < 4.5


def test_vision_batch_reads_a_calibration_manifest_and_identify_recovers_the_truth(tmp_path, capsys):
    """The photos path through the command line: photos of a known true robot (rendered here), `vision batch`
    of their manifest writes the calibration CSV, `calibrate identify --data` reads it as it is and recovers
    the truth (in the fit's gauge) within 3.5 of its sigmas."""
    import json

    from pmaccuracy.accuracy.calibration.identify import identification_from_dict
    from pmaccuracy.report.calibration_report import true_in_gauge

    pv = error_parameters(Manipulator.preset("symmetric_3rpr"))
    plan = plan_poses(pv, 10, seed=0)
    true = true_parameters(pv, seed=5, fixed=FRAME)
    manifest, _ = render_calibration_photos(pv, true, plan.commands, plan.poses, tmp_path / "photos", seed=5)
    readings = tmp_path / "readings.csv"
    assert main(["vision", "batch", str(manifest), "--mm-per-pixel", "0.25", "--out", str(readings),
                 "--format", "csv"]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0].startswith("point,q1,q2,q3,x,y,phi_deg,sigma_x") and len(out.splitlines()) == 11
    # the same readings as the library's own measurement of the manifest
    lib = measure_calibration_photos(manifest, pv)
    header = readings.read_text().splitlines()[0].split(",")
    rows = np.loadtxt(readings, delimiter=",", skiprows=1)
    np.testing.assert_allclose(rows[:, header.index("x")], lib.poses[:, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(rows[:, header.index("sigma_phi_deg")], np.degrees(lib.sigmas[:, 2]), rtol=1e-12)
    # the photos were rendered without clearances: identify with the same model (the default would add rpr_typical)
    assert main(["calibrate", "identify", "--robot", "symmetric_3rpr", "--data", str(readings), "--clearances", "none",
                 "--out", str(tmp_path / "id.json"), "--format", "csv"]) == 0
    capsys.readouterr()
    ident = identification_from_dict(json.loads((tmp_path / "id.json").read_text()), source="id.json")
    free = pv.index(ident.identifiability.identified)
    z = (ident.values - true_in_gauge(ident, true))[free] / ident.sigma[free]
    assert len(free) >= 15 and np.all(np.isfinite(z)) and np.max(np.abs(z)) < 3.5, z


@pytest.mark.parametrize("manifest, options, where", [
    ("image,point,q1,q2,q3,x_nom,y_nom,phi_nom_deg\n1.png,1,abc,1,1,0,0,0\n", ["--mm-per-pixel", "0.25"],
     "line 2: column q1: not a number"),
    ("image,point,q1,q2,q3,x_nom,y_nom,phi_nom_deg\nmissing.png,1,1,1,1,0,0,0\n", ["--mm-per-pixel", "0.25"],
     "line 2: no such image file"),
    ("image,point,q1,q2,q3,x_nom,y_nom,phi_nom_deg\n1.png,1,1,1,1,0,0,0\n1.png,1,1,1,1,0,0,0\n",
     ["--mm-per-pixel", "0.25"], "line 3: point 1 repeated"),
    ("image,point,x_nom,y_nom,phi_nom_deg,push\n" + "".join(f"1.png,P1,0,0,0,{p}\n" for p in ("+x", "-x", "+y", "-y",
                                                                                            "+r", "-r")),
     ["--mm-per-pixel", "0.25"], "--calibration"),
])
def test_vision_batch_bad_calibration_manifest_exits_2_with_one_line(manifest, options, where, tmp_path, capsys):
    (tmp_path / "1.png").write_bytes(b"")
    (tmp_path / "m.csv").write_text(manifest)
    status = main(["vision", "batch", str(tmp_path / "m.csv"), *options, "--out", str(tmp_path / "r.csv")])
    err = capsys.readouterr().err
    assert status == 2 and where in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "r.csv").exists()
