"""Error sources of every joint type and the exact bounds of every architecture (issue 9, items 1-3).

* On the 3-PPR the per-joint sources paired with the legs' wrenches give the paper's
  half-widths exactly: the generic path equals the 3-PPR path (itself checked against the
  independent ``reference_model``) on the presets and on random geometries with any gamma.
* Closed form: a symmetric 3-RPR at its centre with actuator errors only.
* The worst configurations attain the maxima, and the exact nonlinear loop closure
  (:func:`pmaccuracy.accuracy.nonlinear.joint_displaced_pose`) differs from the first-order model by a
  second-order amount (the difference shrinks four-fold when the errors are halved).
* Bad clearance files exit 2 naming leg, joint and key.
"""

from __future__ import annotations

import numpy as np
import pytest
import tomli_w

from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.cli import main
from pmaccuracy.model.clearances import ClearanceDisplacement, ClearanceSet
from pmaccuracy.errors import ClearanceError
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.kinematics import inverse_kinematics
from pmaccuracy.model.legs import RPRLeg
from pmaccuracy.accuracy.nonlinear import displaced_pose, joint_displaced_pose
from pmaccuracy.model.sources import ErrorSources, JointErrors, first_order_error, worst_configuration
from pmaccuracy.io.resolve import load_clearances
from reference_model import random_poses, random_robot

QUANTITIES = ("dx", "dy", "dphi", "dp")
PAIRS = [("symmetric_3rpr", "rpr_typical"), ("symmetric_3rrr", "rrr_typical"), ("symmetric_3prr", "prr_typical")]


def _maxima(b):
    return np.stack([b.dx_max, b.dy_max, b.dphi_max, b.dp_max], axis=-1)


def _inside_poses(robot, rng, n, spread=25.0, dphi=0.3):
    poses = np.column_stack([rng.uniform(-spread, spread, (4 * n, 2)), rng.uniform(-dphi, dphi, 4 * n)])
    return poses[inverse_kinematics(robot, poses).within_limits][:n]


@pytest.mark.parametrize("name", ["aalborg_3ppr", "symmetric_3ppr"])
@pytest.mark.parametrize("clear", ["case1", "case2", "all"])
def test_per_joint_sources_reproduce_the_3ppr_model(name, clear):
    robot = Manipulator.preset(name)
    poses = _inside_poses(robot, np.random.default_rng(0), 200)
    cs = ClearanceSet.load(clear)
    a = _maxima(max_pose_errors(robot, cs, poses))
    b = _maxima(max_pose_errors(robot, ErrorSources.from_clearance_set(cs), poses))
    np.testing.assert_allclose(b, a, rtol=1e-12)


def test_guide_play_normal_to_the_rail_on_any_gamma():
    """Random 3-PPR geometries (any gamma) with guide play only: both paths agree (the paper's
    delta d along v would differ by -54 % to x4.3 in dx_max when gamma != +-90 deg)."""
    rng = np.random.default_rng(4)
    for _ in range(10):
        robot = random_robot(rng)
        poses = random_poses(robot, rng, 20)
        cs = ClearanceSet.from_dict({"legs": [{"guide_lateral": float(g), "guide_block_length": 40.0}
                                              for g in rng.uniform(0.001, 0.004, 3)]})
        a = _maxima(max_pose_errors(robot, cs, poses, allow_outside=True))
        b = _maxima(max_pose_errors(robot, ErrorSources.from_clearance_set(cs), poses, allow_outside=True))
        np.testing.assert_allclose(b, a, rtol=1e-10)


def test_symmetric_3rpr_with_actuator_errors_in_closed_form():
    """Legs at 120 deg with unit directions f_i and equal moments m about P: A^-1 has rows
    (2/3) f_i . e_x, (2/3) f_i . e_y and 1 / (3 m), so dphi = eps / |m|, dx = (2/3) eps sum |f_ix|,
    and dp = (2/3) eps max |sum t_i f_i| = 4 eps / 3."""
    eps = 0.005
    robot = Manipulator.preset("symmetric_3rpr")
    sources = ErrorSources(legs=tuple((JointErrors(), JointErrors(actuator=eps), JointErrors()) for _ in range(3)))
    b = max_pose_errors(robot, sources, [[0.0, 0.0, 0.0]])
    A = np.array([c.base for c in robot.chains])
    D = np.array([c.platform for c in robot.chains])
    f = (D - A) / np.linalg.norm(D - A, axis=1, keepdims=True)
    m = D[0, 0] * f[0, 1] - D[0, 1] * f[0, 0]
    assert b.dphi_max[0] == pytest.approx(eps / abs(m), rel=1e-12)
    assert b.dx_max[0] == pytest.approx(2 / 3 * eps * np.abs(f[:, 0]).sum(), rel=1e-12)
    assert b.dy_max[0] == pytest.approx(2 / 3 * eps * np.abs(f[:, 1]).sum(), rel=1e-12)
    assert b.dp_max[0] == pytest.approx(4 * eps / 3, rel=1e-12)


@pytest.mark.parametrize("name,clear", PAIRS + [("aalborg_3ppr", "all")])
def test_worst_configurations_attain_the_maxima_and_close_to_second_order(name, clear):
    robot = Manipulator.preset(name)
    sources = load_clearances(clear, robot)
    if not isinstance(sources, ErrorSources):
        sources = ErrorSources.from_clearance_set(sources)
    poses = _inside_poses(robot, np.random.default_rng(1), 6, spread=15.0, dphi=0.2)
    b = max_pose_errors(robot, sources, poses, details=True)
    ik = inverse_kinematics(robot, poses)
    for row, q in enumerate(QUANTITIES):
        cfg = worst_configuration(robot, sources, ik.joints, poses, b.worst_signs[q])
        lin = first_order_error(robot, ik.joints, poses, cfg)
        value = np.hypot(lin[:, 0], lin[:, 1]) if q == "dp" else lin[:, row]
        np.testing.assert_allclose(value, _maxima(b)[:, row], rtol=1e-10)
        exact = joint_displaced_pose(robot, poses, cfg) - poses
        half = joint_displaced_pose(robot, poses, cfg.scaled(0.5)) - poses
        scale = _maxima(b)[:, :3]                                 # dx, dy, dphi maxima at each pose
        d1 = np.abs(exact - lin) / scale
        d2 = np.abs(half - 0.5 * lin) / scale
        assert np.all(d1 < 0.01)                                  # small: second order at these clearances
        assert np.all((d1 / np.maximum(d2, 1e-300) > 3.0) | (d1 < 1e-7))   # and shrinking 4x as the errors halve


def test_generic_virtual_prototype_equals_the_3ppr_one():
    """The chain-based loop closure reproduces pmaccuracy.accuracy.nonlinear.displaced_pose of the 3-PPR."""
    robot = Manipulator.preset("aalborg_3ppr")
    rng = np.random.default_rng(2)
    poses = _inside_poses(robot, rng, 5, spread=20.0)
    n = len(poses)
    d = ClearanceDisplacement(tau_b=rng.uniform(-1e-3, 1e-3, (n, 3)), sigma_g=rng.uniform(-2e-3, 2e-3, (n, 3)),
                              tau_g=rng.uniform(-1e-4, 1e-4, (n, 3)), rho=rng.uniform(0, 0.04, (n, 3)),
                              varphi=rng.uniform(-np.pi, np.pi, (n, 3)))
    from pmaccuracy.model.sources import JointDisplacements
    cfg = JointDisplacements.zeros((n,))
    cfg.sigma[:, :, 0] = d.sigma_g
    cfg.tau[:, :, 0] = d.tau_g
    cfg.turn[:, :, 1] = d.tau_b
    cfg.shift[:, :, 2] = d.rho * np.exp(1j * d.varphi)
    np.testing.assert_allclose(joint_displaced_pose(robot, poses, cfg), displaced_pose(robot, poses, d), atol=1e-10)


# ----------------------------------------------------------------------------------- files and CLI
def run(args, capsys):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("name,clear", PAIRS)
def test_bounds_cli_every_architecture(name, clear, capsys):
    import json
    code, out, err = run(["bounds", "--robot", name, "--clearances", clear, "--pose", 0, 0, 0, "--pose", 5, -5, 10,
                          "--format", "json"], capsys)
    assert code == 0 and err == ""
    data = json.loads(out)
    assert set(data[0]) == {"x", "y", "phi_deg", "dx_max", "dy_max", "dphi_max_deg", "dp_max"}
    robot = Manipulator.preset(name)
    b = max_pose_errors(robot, load_clearances(clear, robot), np.array([[0, 0, 0], [5, -5, np.radians(10)]]))
    np.testing.assert_allclose([d["dp_max"] for d in data], b.dp_max, rtol=1e-12)


BAD = {
    "angular on R": ([{"angular": 0.001}, {"actuator": 0.005}, {"radial": 0.02}], "legs[1].joints[1].angular"),
    "actuator on passive": ([{"radial": 0.02}, {"actuator": 0.005}, {"actuator": 0.02}],
                            "legs[1].joints[3].actuator"),
    "negative": ([{"radial": -0.02}, {"actuator": 0.005}, {"radial": 0.02}], "legs[1].joints[1].radial"),
    "two joints": ([{"radial": 0.02}, {"actuator": 0.005}], "legs[1].joints"),
    "unknown key": ([{"radius": 0.02}, {"actuator": 0.005}, {"radial": 0.02}], "legs[1].joints[1].radius"),
    "zero block": ([{"radial": 0.02}, {"actuator": 0.005, "block_length": 0.0}, {"radial": 0.02}],
                   "legs[1].joints[2].block_length"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_clearance_files_name_leg_joint_key(case, tmp_path, capsys):
    joints, key = BAD[case]
    good = [{"radial": 0.02}, {"actuator": 0.005}, {"radial": 0.02}]
    path = tmp_path / "c.toml"
    path.write_text(tomli_w.dumps({"legs": [{"joints": joints}, {"joints": good}, {"joints": good}]}))
    code, out, err = run(["bounds", "--robot", "symmetric_3rpr", "--clearances", path, "--pose", 0, 0, 0], capsys)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert "c.toml" in err and key in err, err


def test_3ppr_format_on_another_architecture_is_refused(capsys):
    code, out, err = run(["bounds", "--robot", "symmetric_3rpr", "--clearances", "case2", "--pose", 0, 0, 0], capsys)
    assert code == 2 and "listing each leg's joints" in err and len(err.strip().splitlines()) == 1
    # the suggestion names the preset of the robot's own architecture, never a 3-PPR case
    assert "rpr_typical" in err and "use case" not in err and "rrr_typical" not in err


def test_sources_check_names_the_joint():
    robot = Manipulator.preset("symmetric_3rpr")
    bad = ErrorSources(legs=tuple((JointErrors(lateral=0.001), JointErrors(), JointErrors()) for _ in range(3)))
    with pytest.raises(ClearanceError, match=r"legs\[1\]\.joints\[1\]\.lateral"):
        bad.check(robot)


def test_aligned_3rpr_singular_points_are_nan_in_maps_not_errors():
    legs = tuple(RPRLeg(base=tuple(200 * np.array([np.cos(t), np.sin(t)])),
                        platform=tuple(50 * np.array([np.cos(t), np.sin(t)])), length_range=(100.0, 250.0))
                 for t in np.radians([210, 330, 90]))
    robot = Manipulator(legs=legs)
    sources = ErrorSources(legs=tuple((JointErrors(), JointErrors(actuator=0.005), JointErrors()) for _ in range(3)))
    b = max_pose_errors(robot, sources, [[0.0, 0.0, 0.0], [0.0, 0.0, 0.5]], singular="nan")
    assert np.isnan(b.dx_max[0]) and np.isfinite(b.dx_max[1])
