"""The calibration report (issue 23): its numbers against independent computations, a self-contained page,
and the command line (``calibrate report``, ``calibrate simulate --report``) with bad options exiting 2.

The residuals are checked against the 3-RPR's closed-form leg lengths (|platform point - base point| on the
identified geometry, written here from the parameter names, not through the chain code), the floor against
:func:`pmaccuracy.max_pose_errors` called directly, the indices against :func:`plan_poses`.
"""

from __future__ import annotations

import html
import re

import numpy as np
import pytest

import pmaccuracy as pm
from pmaccuracy.accuracy.calibration.parameters import frame_apply
from pmaccuracy.accuracy.calibration.plan import candidate_poses, plan_poses, pose_set_indices
from pmaccuracy.report.calibration_report import model_residuals, true_in_gauge
from conftest import run_cli

ROBOT, CLEARANCES, POSES, SEED = "symmetric_3rpr", "rpr_typical", 24, 2


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("calreport")
    pv = pm.error_parameters(pm.Manipulator.preset(ROBOT))
    ex = pm.simulate_calibration(pv, POSES, seed=SEED, clearances=CLEARANCES, n_targets=20)
    results = pm.calibration_report(out / "cal.html", ex.identification, ex.data, experiment=ex, seed=SEED)
    return pv, ex, results, (out / "cal.html").read_text(encoding="utf-8")


def rpr_leg_lengths(table: dict, pose: np.ndarray) -> np.ndarray:
    """Closed form: |D_i - A_i| of the three legs for a robot-frame pose (x, y, phi), geometry by name."""
    x, y, phi = pose
    c, s = np.cos(phi), np.sin(phi)
    out = []
    for i in (1, 2, 3):
        bx, by = table[f"leg{i}.base.x"], table[f"leg{i}.base.y"]
        px, py = table[f"leg{i}.platform.x"], table[f"leg{i}.platform.y"]
        out.append(np.hypot(x + c * px - s * py - bx, y + s * px + c * py - by))
    return np.array(out)


def rpr_model_pose(table: dict, measured: np.ndarray) -> np.ndarray:
    """Robot-frame pose of a measured-frame pose with the frame of ``table``."""
    fx, fy, fphi = table["frame.x"], table["frame.y"], table["frame.phi"]
    c, s = np.cos(fphi), np.sin(fphi)
    return np.array([fx + c * measured[0] - s * measured[1], fy + s * measured[0] + c * measured[1],
                     measured[2] + fphi])


@pytest.mark.parametrize("which", ["before", "after"])
def test_residuals_are_exact_forward_residuals(run, which):
    pv, ex, results, _ = run
    ident, data = ex.identification, ex.data
    values = pv.nominal if which == "before" else ident.values
    r = model_residuals(ident, data, values)
    table = pv.table(values)
    checked = 0
    for n in range(len(data)):
        if not np.all(np.isfinite(r[n])):
            continue
        model = rpr_model_pose(table, data.poses[n] - r[n])   # where the model robot is for the command
        joints = np.array([table[f"leg{i}.actuator.offset"] + table[f"leg{i}.actuator.gain"] * data.commands[n, i - 1]
                           for i in (1, 2, 3)])
        np.testing.assert_allclose(rpr_leg_lengths(table, model), joints, atol=1e-7)
        checked += 1
    assert checked >= len(data) - 1
    # the library's first-order pose residuals (G^-1 r) agree, up to their linearisation (a few % here)
    lib = ident.residuals_before if which == "before" else ident.residuals_after
    ok = np.all(np.isfinite(r), axis=1)
    size = np.hypot(lib[ok, 0], lib[ok, 1])
    assert np.all(np.hypot(*(r[ok, :2] - lib[ok, :2]).T) <= 0.1 * size + 1e-6)
    # the report's table: max and RMS of |dp| (outliers left out after the fit)
    keep = ok if which == "before" else ok & ~np.isin(np.asarray(data.labels), ident.outliers)
    p = np.hypot(r[keep, 0], r[keep, 1])
    got = results["residuals"][which]
    assert got["points"] == keep.sum()
    assert got["max_mm"] == pytest.approx(p.max(), rel=1e-12)
    assert got["rms_mm"] == pytest.approx(np.sqrt(np.mean(p ** 2)), rel=1e-12)
    assert got["max_deg"] == pytest.approx(np.degrees(np.abs(r[keep, 2])).max(), rel=1e-12)


def test_estimates_and_spectrum_are_the_identification(run):
    pv, ex, results, page = run
    ident = ex.identification
    rows = {e["parameter"]: e for e in results["estimates"]}
    assert list(rows) == list(pv.names)
    for name, unit, nominal, value, sigma in zip(pv.names, pv.units, pv.nominal, ident.values, ident.sigma):
        f = np.degrees if unit == "rad" else float
        e = rows[name]
        assert e["change"] == pytest.approx(f(value - nominal), abs=1e-12)
        assert e["identified"] == (name in ident.identifiability.identified)
        if e["identified"]:
            assert e["sigma"] == pytest.approx(f(sigma), rel=1e-12)
    np.testing.assert_array_equal(results["singular_values"], ident.identifiability.singular_values)
    assert results["fixed"] == list(ident.identifiability.fixed)
    for sentence in ident.identifiability.combinations:   # the unidentifiable directions, in words, on the page
        assert html.escape(sentence) in page


def test_true_parameters_in_the_fits_gauge_explain_the_same_measurements(run):
    """The true robot moved along the unidentifiable directions puts every command where the true robot does
    (the exact forward kinematics of both), and its fixed parameters are nominal."""
    pv, ex, _, _ = run
    ident = ex.identification
    gauge = true_in_gauge(ident, ex.true)
    fixed = pv.index(ident.identifiability.fixed)
    np.testing.assert_allclose(gauge[fixed], pv.nominal[fixed], atol=1e-12)
    r_true = model_residuals(ident, ex.data, ex.true)
    r_gauge = model_residuals(ident, ex.data, gauge)
    ok = np.all(np.isfinite(r_true) & np.isfinite(r_gauge), axis=1)
    assert np.max(np.abs(r_true[ok] - r_gauge[ok])) < 1e-3   # second order in the frame error (mm, rad)
    assert np.max(np.abs(ex.true - pv.nominal)[pv.index(("leg1.base.x",))]) > 0  # something was moved


def test_indices_are_the_plans(run):
    pv, ex, results, _ = run
    plan = plan_poses(pv, len(ex.data), candidate_poses(pv), seed=SEED)
    for key, ref in (("planned", plan.index), ("random", plan.random_index), ("grid", plan.grid_index)):
        for k, v in ref.items():
            assert results["indices"][key][k] == pytest.approx(v, rel=1e-12)
    # the same poses through the report's path give the plan's own index (two code paths, one number)
    own = pose_set_indices(pv, plan.poses, seed=SEED)["poses"]
    for k, v in plan.index.items():
        assert own[k] == pytest.approx(v, rel=1e-9)


def test_accuracy_beside_the_floor(run):
    pv, ex, results, page = run
    acc = results["accuracy"]
    assert acc["where"] == "targets" and acc["poses"] == len(ex.targets)
    np.testing.assert_allclose(acc["before_mm"], np.hypot(*ex.errors_before[:, :2].T), rtol=1e-12)
    np.testing.assert_allclose(acc["after_deg"], np.degrees(np.abs(ex.errors_after[:, 2])), rtol=1e-12)
    robot = pv.split(ex.identification.values)[0]
    b = pm.max_pose_errors(robot, CLEARANCES, frame_apply(ex.identification.values[-3:], ex.targets))
    np.testing.assert_allclose(acc["floor"]["dp_max_mm"], b.dp_max, rtol=1e-9)
    np.testing.assert_allclose(acc["floor"]["dphi_max_deg"], np.degrees(b.dphi_max), rtol=1e-9)
    sigma = np.hypot(*ex.compensation.predicted_sigma[:, :2].T)
    inside = (np.hypot(*ex.errors_after[:, :2].T) <= b.dp_max + 3 * sigma) & \
             (np.abs(ex.errors_after[:, 2]) <= b.dphi_max + 3 * ex.compensation.predicted_sigma[:, 2])
    assert acc["within_floor"] == inside.sum()
    assert f"{inside.sum()} of {len(ex.targets)} poses are within it" in html.unescape(page)
    # the verdict's numbers are the experiment's
    assert f"from {np.hypot(*ex.errors_before[:, :2].T).max():.3g} mm to " \
           f"{np.hypot(*ex.errors_after[:, :2].T).max():.3g} mm" in results["verdict"][0]


def test_measured_data_report_floor_at_the_measured_poses(run, tmp_path):
    pv, ex, _, _ = run
    ident, data = ex.identification, ex.data
    res = pm.calibration_report(tmp_path / "data.html", ident, data, clearances=CLEARANCES, seed=SEED)
    acc = res["accuracy"]
    assert acc["where"] == "measured poses"
    after = model_residuals(ident, data)
    before = model_residuals(ident, data, pv.nominal)
    keep = (~np.isin(np.asarray(data.labels), ident.outliers) & np.all(np.isfinite(after), axis=1)
            & np.all(np.isfinite(before), axis=1))
    robot = pv.split(ident.values)[0]
    b = pm.max_pose_errors(robot, CLEARANCES, frame_apply(ident.values[-3:], data.poses[keep]))
    np.testing.assert_allclose(acc["floor"]["dp_max_mm"], b.dp_max, rtol=1e-9)
    np.testing.assert_allclose(acc["after_mm"], np.hypot(after[keep, 0], after[keep, 1]), rtol=1e-12)
    assert "the fit's own residuals" in res["verdict"][0]


def test_page_is_self_contained_with_numbered_sections(run):
    _, _, results, page = run
    links = re.findall(r"""(?:src|href)\s*=\s*['"]([^'"]*)['"]""", page)
    assert links and all(v.startswith("data:image/png;base64,") or v.startswith("#") for v in links)
    assert "http://" not in page and "https://" not in page and "<script" not in page
    assert page.count("<figure>") == 5 and "Figure 5." in page
    assert "<nav class='toc'>" in page and "5. Accuracy before and after" in page
    assert "Written by pmaccuracy" in page                       # the provenance footer
    for line in results["verdict"]:
        assert html.escape(line).replace("`", "") in page.replace("<code>", "").replace("</code>", "")


def test_report_path_must_be_html(run, tmp_path):
    _, ex, _, _ = run
    with pytest.raises(pm.ConfigError, match="html"):
        pm.calibration_report(tmp_path / "r.pdf", ex.identification, ex.data)


# ----------------------------------------------------------------------------------------------- command line
def cli(argv, capsys):
    return run_cli(argv, capsys)


def test_cli_simulate_report_and_data_report(tmp_path, capsys):
    status, out, _ = cli(["calibrate", "simulate", "--robot", ROBOT, "--poses", "20", "--seed", "1",
                          "--data-out", tmp_path / "m.csv", "--report", tmp_path / "sim.html", "--format", "csv"],
                         capsys)
    assert status == 0 and (tmp_path / "sim.html").read_text().startswith("<!DOCTYPE html>")
    status, _, _ = cli(["calibrate", "identify", "--robot", ROBOT, "--data", tmp_path / "m.csv", "--out",
                        tmp_path / "id.json", "--format", "csv"], capsys)
    assert status == 0
    status, out, err = cli(["calibrate", "report", "--data", tmp_path / "m.csv", "--identification",
                            tmp_path / "id.json", "--clearances", CLEARANCES, "--out", tmp_path / "r" / "data.html"],
                           capsys)
    assert status == 0, err
    page = (tmp_path / "r" / "data.html").read_text()
    assert "the fit&#x27;s own residuals" in page and "measured poses" in page


@pytest.mark.parametrize("argv, where", [
    (["--out", "{tmp}/r.pdf"], "--out"),
    (["--out", "{tmp}/afile/r.html"], "--out"),
    (["--out", "{tmp}/r.html", "--data", "{tmp}/m.csv"], "--identification"),
    (["--out", "{tmp}/r.html", "--identification", "{tmp}/id.json"], "--data"),
    (["--out", "{tmp}/r.html", "--data", "{tmp}/m.csv", "--identification", "{tmp}/id.json", "--poses", "30"],
     "--poses"),
    (["--out", "{tmp}/r.html", "--data", "{tmp}/m.csv", "--identification", "{tmp}/id.json", "--robot",
      "symmetric_3rrr"], "--robot"),
    (["--out", "{tmp}/r.html", "--noise-mm", "-1"], "--noise-mm"),
    (["--out", "{tmp}/r.html", "--data", "{tmp}/m.csv", "--identification", "{tmp}/missing.json"], "missing.json"),
])
def test_cli_bad_options_exit_2_with_one_line_before_computing(argv, where, tmp_path, capsys, monkeypatch):
    import pmaccuracy.accuracy.calibration.simulate as simulate

    def boom(*a, **k):  # nothing is computed before the options are checked
        raise AssertionError("computed before checking the options")

    monkeypatch.setattr(simulate, "simulate_calibration", boom)
    (tmp_path / "afile").write_text("")
    (tmp_path / "m.csv").write_text("x,y,phi_deg,q1,q2,q3\n")
    status, out, err = cli(["calibrate", "report"] + [a.format(tmp=tmp_path) for a in argv], capsys)
    assert status == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and where in lines[0], err
    assert not (tmp_path / "r.html").exists()


def test_cli_simulate_report_checked_before_computing(tmp_path, capsys, monkeypatch):
    import pmaccuracy.accuracy.calibration.simulate as simulate

    monkeypatch.setattr(simulate, "simulate_calibration", lambda *a, **k: (_ for _ in ()).throw(AssertionError))
    status, _, err = cli(["calibrate", "simulate", "--robot", ROBOT, "--report", tmp_path / "r.txt"], capsys)
    assert status == 2 and "--report" in err and len(err.strip().splitlines()) == 1


def test_before_robot_keeps_the_fits_fixed_parameters(run):
    """A measurement frame given to ``identify --frame`` stays fixed in the fit: the robot "before calibration"
    is the nominal seen through that frame, not through the robot's own."""
    import dataclasses

    from pmaccuracy.report.calibration_report import start_values

    pv, ex, _, _ = run
    ident = ex.identification
    assert set(ident.identifiability.fixed) >= {"frame.x", "frame.y", "frame.phi"}
    values = ident.values.copy()
    values[-3:] = (1.5, -2.0, 0.01)
    moved = dataclasses.replace(ident, values=values)
    start = start_values(moved)
    np.testing.assert_array_equal(start[-3:], (1.5, -2.0, 0.01))
    free = pv.index(ident.identifiability.identified)
    np.testing.assert_array_equal(start[free], pv.nominal[free])
