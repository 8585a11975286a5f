"""``load --details`` of a parallel robot prints every joint's contact state; ``preload`` rows carry the
unloaded worst case beside the constant offset (issue 24; ``load --map`` warning once: test_load_bad_input).

The contact states are checked against the physics, not against the code that prints them: each pin is
displaced by its full radial clearance opposite the force its joint transmits (the statics of
``pmaccuracy.accuracy.loads.statics``, to the O(c / L) turn of the reactions at the displaced
configuration), each actuator's backlash is taken up against the actuator's effort, a P block sits on a vertex
of its clearance rhombus.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.accuracy.loads import Load, statics
from pmaccuracy.cli import main


@pytest.mark.parametrize("robot, clear, radial, actuator, lateral", [
    ("symmetric_3rpr", "rpr_typical", 0.02, 0.005, None),
    ("symmetric_3prr", "prr_typical", 0.02, 0.005, (0.0015, 50.0)),
])
def test_details_print_each_joints_contact_state(robot, clear, radial, actuator, lateral, capsys):
    pose, load = [1.0, 2.0, 3.0], dict(fx=3.0, fy=-20.0, m=50.0)
    assert main(["load", "--robot", robot, "--clearances", clear, "--pose", *map(str, pose), "--fx", "3",
                 "--fy", "-20", "--m", "50", "--details", "--format", "json"]) == 0
    rec = json.loads(capsys.readouterr().out)[0]
    st = statics(robot, [pose[0], pose[1], math.radians(pose[2])], Load(**load))
    pins = backlashes = blocks = 0
    for i in range(3):
        for j in range(3):
            key = f"leg{i + 1}.joint{j + 1}"
            if f"{key}.pin_dx_mm" in rec:
                shift = rec[f"{key}.pin_dx_mm"] + 1j * rec[f"{key}.pin_dy_mm"]
                force = complex(st.force[i, j])
                assert abs(shift) == pytest.approx(radial, rel=1e-9)
                # opposite the force, to the reactions' turn at the displaced configuration (c / L ~ 1e-3 rad)
                assert abs(np.angle(-shift / force)) < 1e-2, (key, shift, force)
                assert rec[f"{key}.pin_deg"] == pytest.approx(math.degrees(np.angle(shift)), abs=1e-9)
                pins += 1
            for unit in ("mm", "rad"):
                if f"{key}.backlash_{unit}" in rec:
                    dq = rec[f"{key}.backlash_{unit}"]
                    assert abs(dq) == pytest.approx(actuator, rel=1e-12)
                    assert np.sign(dq) == -np.sign(st.actuator[i]), (key, dq, st.actuator[i])
                    backlashes += 1
            if f"{key}.sigma_mm" in rec:
                eps, length = lateral
                sigma, tau = rec[f"{key}.sigma_mm"], rec[f"{key}.tau_rad"]
                vertex = (abs(sigma) == pytest.approx(eps) and tau == 0) or \
                         (sigma == 0 and abs(tau) == pytest.approx(2 * eps / length))
                assert vertex, (key, sigma, tau)
                blocks += 1
    assert pins == 6 and backlashes == 3 and blocks == (3 if lateral else 0)


def test_details_of_an_unloaded_leg_read_zero(capsys):
    # pushing the paper's robot along -y leaves leg 3 unloaded: its pin state is undetermined (0)
    assert main(["load", "--clearances", "case2", "--pose", "0", "0", "0", "--fy", "-20", "--details", "--format",
                 "json"]) == 0
    rec = json.loads(capsys.readouterr().out)[0]
    assert rec["unloaded_legs"] == "3"
    assert rec["leg3.joint3.pin_dx_mm"] == 0 and rec["leg3.joint3.pin_dy_mm"] == 0
    assert math.isnan(rec["leg3.joint3.pin_deg"]) if isinstance(rec["leg3.joint3.pin_deg"], float) \
        else rec["leg3.joint3.pin_deg"] is None
    assert abs(rec["leg1.joint3.pin_dx_mm"] + 1j * rec["leg1.joint3.pin_dy_mm"]) > 0


def test_preload_rows_carry_the_unloaded_worst_case(capsys):
    assert main(["preload", "--robot", "symmetric_3rpr", "--clearances", "rpr_typical", "--pose", "1", "2", "3",
                 "--pose", "-4", "0", "0", "--fx", "-4", "6", "--m", "-50", "50", "--format", "json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    poses = np.array([[1.0, 2.0, math.radians(3.0)], [-4.0, 0.0, 0.0]])
    b = max_pose_errors("symmetric_3rpr", "rpr_typical", poses)
    for k, rec in enumerate(rows):
        assert rec["dx_max"] == pytest.approx(b.dx_max[k], rel=1e-12)
        assert rec["dy_max"] == pytest.approx(b.dy_max[k], rel=1e-12)
        assert rec["dphi_max_deg"] == pytest.approx(math.degrees(b.dphi_max[k]), rel=1e-12)
        # the constant offset is one point of the error set: inside the worst case
        assert abs(rec["offset_dx"]) <= rec["dx_max"] * (1 + 1e-12)
        assert abs(rec["offset_dphi_deg"]) <= rec["dphi_max_deg"] * (1 + 1e-12)
