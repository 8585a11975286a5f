"""The accuracy report of any robot and clearance set (``reproduce --robot R --clearances C``)."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from pmaccuracy.cli import main
from pmaccuracy.accuracy.maps import error_map, summarize
from pmaccuracy.io.resolve import load_clearances

# The 3-RRR's report takes 12 s (its design section's certified map reaches the near-singular edge of its
# workspace): ``make test-all``; so does the 3-RPR's (test_report_sections.py builds its report section by
# section); the 3-PRR and the paper's robot run in ``make test``.
CASES = [pytest.param("symmetric_3rpr", "rpr_typical", marks=pytest.mark.slow),   # its report: test_report_sections
         pytest.param("symmetric_3rrr", "rrr_typical", marks=pytest.mark.slow), ("symmetric_3prr", "prr_typical"),
         ("aalborg_3ppr", "all")]


@pytest.mark.parametrize("robot,clear", CASES)
def test_reproduce_any_robot(robot, clear, tmp_path, capsys):
    out = tmp_path / "rep"
    code = main(["reproduce", "--robot", robot, "--clearances", clear, "--grid", "21", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    for name in ("report.html", "report.md", "results.json", "workspace.png", "map.nc", "map_phi0.png",
                 "map_phi30.png", "experiment/measurements.csv"):
        assert (out / name).is_file(), name
    res = json.loads((out / "results.json").read_text())
    assert res["robot"] == robot and res["grid"] == 21
    # the maps' summary is the library's error map
    from pmaccuracy.model.manipulator import Manipulator
    r = Manipulator.preset(robot)
    want = summarize(error_map(r, load_clearances(clear, r), np.radians([0.0, 30.0]), 21, progress=False))
    got = res["cases"][res["clearances"]]
    for phi in want:
        for q in want[phi]:
            np.testing.assert_allclose(got[phi][q], want[phi][q], rtol=1e-12)
    # the exact virtual prototype stays within a few % of the first-order maxima at well-conditioned points
    for c in res["nonlinear_check"]:
        assert abs(c["exact"] - c["first_order"]) <= 0.05 * c["first_order"]
    # the width-consistent RMSD of the virtual experiment is at the level of the camera noise (0.01 mm, deg)
    assert all(v < 0.05 for v in res["experiment"]["rmsd_width_consistent"].values())
    html = (out / "report.html").read_text()
    assert "Virtual experiment" in html and "nonlinear" in html
    # a source that does not move a quantity reads 0 in the per-source tables, not a rounding residue
    assert not re.search(r"<td>-?\d(\.\d+)?e-1\d</td>", html)


def test_reproduce_other_architecture_refuses_unfitting_clearances_first(tmp_path, capsys):
    # without --clearances a 3-RPR gets its default (tests/cli/test_default_clearances.py); clearances of
    # another architecture are refused before anything is written, naming the preset that fits
    code = main(["reproduce", "--robot", "symmetric_3rpr", "--clearances", "case1", "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert code == 2 and "rpr_typical" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()


def test_design_section_for_any_robot_uses_its_targets_range_and_clearances(tmp_path, capsys):
    """The design section of ``reproduce --robot R --clearances C --target ... --phi-range-deg ...``: its certified
    worst case is at least a brute-force grid over the same region (independent sampling of max_pose_errors), the
    synthesized clearances meet the target, and the verdict says what the numbers say."""
    from pmaccuracy.accuracy.bounds import max_pose_errors
    from pmaccuracy.kinematics.workspace import constant_orientation_workspace
    from pmaccuracy.model.manipulator import Manipulator

    out = tmp_path / "rep"
    code = main(["reproduce", "--robot", "symmetric_3rpr", "--clearances", "rpr_typical", "--grid", "21",
                 "--no-experiment", "--target", "dp=0.05", "--phi-range-deg", "-5", "5", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    d = json.loads((out / "results.json").read_text())["design_decisions"]
    assert d["settings"]["phi_range_deg"] == [-5.0, 5.0] and d["settings"]["targets"] == {"dp": 0.05}
    gw = d["global_worst"]["rpr_typical"]["quantities"]["dp"]
    robot = Manipulator.preset("symmetric_3rpr")
    best = 0.0
    for phi in np.radians([-5.0, 0.0, 5.0]):
        ws = constant_orientation_workspace(robot, phi)
        x, y, inside = ws.grid(41)
        X, Y = np.meshgrid(x, y)
        poses = np.stack([X, Y, np.full_like(X, phi)], axis=-1)[inside]
        best = max(best, float(np.nanmax(max_pose_errors(robot, "rpr_typical", poses, singular="nan").dp_max)))
    assert best <= gw["upper"] * (1 + 1e-9) and gw["lower"] <= gw["upper"]
    uni = d["synthesis"]["uniform"]
    assert uni["worst"]["dp"]["upper"] <= 0.05 * (1 + 1e-9) and uni["template"] == "rpr_typical"
    html = (out / "report.html").read_text()
    verdict = html[html.index("Verdict."):][:900]
    assert ("misses" if gw["upper"] > 0.05 else "meets") in verdict
    assert f"{uni['scale']:.3g}" in verdict


@pytest.mark.parametrize("args, key", [(["--target", "dq=1"], "--target"), (["--target", "dp=-1"], "--target"),
                                       (["--phi-range-deg", "5", "-5"], "--phi-range-deg")])
def test_reproduce_design_options_are_checked_first(args, key, tmp_path, capsys):
    code = main(["reproduce", "--robot", "symmetric_3rpr", "--clearances", "rpr_typical", "--out",
                 str(tmp_path / "x"), *args])
    err = capsys.readouterr().err
    assert code == 2 and key in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()


def test_design_section_over_a_disc_certifies_that_disc(tmp_path, capsys):
    """``reproduce ... --disc X Y R``: the design section's worst case is over that disc: its attaining pose lies
    in the disc and the certified bound is at least a brute-force sample of the disc (independent)."""
    from pmaccuracy.accuracy.bounds import max_pose_errors

    out = tmp_path / "rep"
    code = main(["reproduce", "--robot", "symmetric_3rpr", "--clearances", "rpr_typical", "--grid", "11",
                 "--no-experiment", "--phi-range-deg", "-1", "1", "--disc", "2", "-1", "6", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    d = json.loads((out / "results.json").read_text())["design_decisions"]
    assert "disc of centre (2, -1) mm and radius 6 mm" in d["settings"]["region"]
    w = d["global_worst"]["rpr_typical"]["quantities"]["dp"]
    assert np.hypot(w["x"] - 2.0, w["y"] + 1.0) <= 6.0 + 1e-9
    r, t = np.meshgrid(np.linspace(0, 6, 13), np.linspace(0, 2 * np.pi, 37))
    pts = np.column_stack([2 + (r * np.cos(t)).ravel(), -1 + (r * np.sin(t)).ravel()])
    best = max(float(np.max(max_pose_errors("symmetric_3rpr", "rpr_typical",
                                            np.column_stack([pts, np.full(len(pts), np.radians(p))])).dp_max))
               for p in (-1.0, 0.0, 1.0))
    assert best <= w["upper"] * (1 + 1e-9)
