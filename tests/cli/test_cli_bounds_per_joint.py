"""bounds --details and --tolerances with per-joint error sources (any architecture).

Checks: a tolerance file added with --tolerances gives the same maxima as one clearance file holding the
joint-by-joint sums (written here by hand); the configuration --details reports, put back into the exact
nonlinear loop closure, moves the platform by the reported maximum (to second order) and into the first-order
model by exactly the maximum.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from pmaccuracy import Manipulator
from pmaccuracy.cli import main
from pmaccuracy.kinematics import inverse_kinematics
from pmaccuracy.accuracy.nonlinear import joint_displaced_pose
from pmaccuracy.model.sources import JointDisplacements, first_order_error
from pmaccuracy.io.resolve import load_clearances

QUANTITIES = ("dx_max", "dy_max", "dphi_max_deg", "dp_max")


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)


@pytest.mark.parametrize("robot,clear,tol", [("symmetric_3rpr", "rpr_typical", "rpr_tolerances"),
                                             ("symmetric_3prr", "prr_typical", "prr_tolerances")])
def test_tolerances_add_joint_by_joint(capsys, tmp_path, robot, clear, tol):
    r = Manipulator.preset(robot)
    a, b = load_clearances(clear, r), load_clearances(tol, r)
    lines = ['name = "summed"']
    for la, lb in zip(a.legs, b.legs):
        cells = []
        for ja, jb in zip(la, lb):
            keys = {k: getattr(ja, k) + getattr(jb, k) for k in ("radial", "actuator", "angular", "lateral",
                                                                  "position", "direction", "length")}
            text = ", ".join(f"{k} = {v!r}" for k, v in keys.items() if v)
            if ja.lateral:
                text += f", block_length = {ja.block_length!r}"
            cells.append("{ " + text + " }")
        lines += ["[[legs]]", "joints = [" + ", ".join(cells) + "]"]
    summed = tmp_path / "summed.toml"
    summed.write_text("\n".join(lines) + "\n")
    pose = ["--pose", "3", "-4", "2"]
    both = _run(capsys, "bounds", "--robot", robot, "--clearances", clear, "--tolerances", tol, *pose,
                "--format", "json")[0]
    ref = _run(capsys, "bounds", "--robot", robot, "--clearances", str(summed), *pose, "--format", "json")[0]
    alone = _run(capsys, "bounds", "--robot", robot, "--clearances", clear, *pose, "--format", "json")[0]
    for q in QUANTITIES:
        assert both[q] == pytest.approx(ref[q], rel=1e-12)
        assert both[q] > alone[q]


def _configuration(robot, worst: dict) -> JointDisplacements:
    """The reported source values as a configuration (parsed from the keys, independently of the code)."""
    cfg = {k: np.zeros((1, 3, 3)) for k in ("turn", "sigma", "tau", "dq", "dl", "tilt")}
    shift = np.zeros((1, 3, 3), dtype=complex)
    for key, value in worst.items():
        leg, joint, what = key.split(".")
        i, k = int(leg[3:]) - 1, int(joint[5:]) - 1
        if what == "shift_x_mm":
            shift[0, i, k] += value
        elif what == "shift_y_mm":
            shift[0, i, k] += 1j * value
        elif what == "actuator_mm":
            cfg["dq"][0, i, k] = value
        elif what == "actuator_deg":
            cfg["dq"][0, i, k] = np.radians(value)
        elif what == "turn_deg":
            cfg["turn"][0, i, k] = np.radians(value)
        elif what == "tilt_deg":
            cfg["tau"][0, i, k] = np.radians(value)
        elif what == "angular_deg":
            cfg["tilt"][0, i, k] = np.radians(value)
        elif what == "lateral_shift_mm":
            cfg["sigma"][0, i, k] = value
        elif what == "length_mm":
            cfg["dl"][0, i, k] = value
        else:
            raise AssertionError(key)
    return JointDisplacements(shift=shift, **cfg)


@pytest.mark.parametrize("robot,clear", [("symmetric_3rpr", "rpr_typical"), ("symmetric_3rrr", "rrr_typical"),
                                         ("symmetric_3prr", "prr_typical")])
def test_details_configuration_attains_the_maximum(capsys, robot, clear):
    r = Manipulator.preset(robot)
    rec = _run(capsys, "bounds", "--robot", robot, "--clearances", clear, "--pose", "2", "-3", "4", "--details",
               "--format", "json")[0]
    pose = np.array([[2.0, -3.0, np.radians(4.0)]])
    joints = inverse_kinematics(r, pose).joints
    for q, row, key in (("dx", 0, "dx_max"), ("dy", 1, "dy_max"), ("dphi", 2, "dphi_max_deg"), ("dp", None, "dp_max")):
        cfg = _configuration(r, rec["worst"][q])
        lin = first_order_error(r, joints, pose, cfg)[0]
        exact = (joint_displaced_pose(r, pose, cfg) - pose)[0]
        if row is None:
            first, true = np.hypot(*lin[:2]), np.hypot(*exact[:2])
        else:
            first, true = abs(lin[row]), abs(exact[row])
            if row == 2:
                first, true = np.degrees(first), np.degrees(true)
        assert first == pytest.approx(rec[key], rel=1e-9)
        assert true == pytest.approx(rec[key], rel=2e-2)      # second-order difference at these clearances


def test_slsqp_refused_for_per_joint_sources(capsys):
    code = main(["bounds", "--robot", "symmetric_3rpr", "--clearances", "rpr_typical", "--pose", "0", "0", "0",
                 "--method", "slsqp"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "slsqp" in err
