"""Spatial kinematics: presets, files, IK/FK round trips, Jacobians against finite differences of the exact
closure, every assembly mode of the translational robots, singularities, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pmaccuracy.errors import ConfigError, GeometryError, PoseError
from pmaccuracy.kinematics import spatial as k
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.numerics.spatial import displace

PRESETS = ["stewart_6ups", "delta_clavel", "rps_3", "prs_3", "upu_3"]


def _near_home(robot, rng, size=1.0):
    """A random pose near the home pose that satisfies the robot's constraints."""
    home = k.reference_pose(robot)
    if robot.mobility == "6":
        return displace(home, size * np.concatenate([rng.uniform(-20, 20, 3), rng.uniform(-0.08, 0.08, 3)]))
    if robot.mobility == "3T":
        return home + size * np.concatenate([rng.uniform(-40, 40, 3), np.zeros(3)])
    c = k.controlled_coordinates(robot, home) + size * np.array([rng.uniform(-20, 20), *rng.uniform(-0.1, 0.1, 2)])
    return k.complete_poses(robot, c)


def test_presets_are_all_there_and_home_is_within_limits():
    assert sorted(SpatialManipulator.preset_names()) == sorted(PRESETS)
    for name in PRESETS:
        robot = SpatialManipulator.preset(name)
        ik = k.inverse_kinematics(robot, k.reference_pose(robot))
        assert bool(ik.within_limits), (name, ik.violations())


@pytest.mark.parametrize("name", PRESETS)
def test_toml_round_trip(name):
    robot = SpatialManipulator.preset(name)
    again = SpatialManipulator.from_toml_string(robot.to_toml(), source="x")
    _same(again.to_dict(), robot.to_dict())
    pose = k.reference_pose(robot)
    np.testing.assert_allclose(k.inverse_kinematics(again, pose).q, k.inverse_kinematics(robot, pose).q, atol=1e-12)


def _same(a, b, where=""):
    """Equal tables, numbers to 1e-12 relative (unit directions are normalized when read)."""
    if isinstance(a, dict):
        assert set(a) == set(b), where
        for key in a:
            _same(a[key], b[key], f"{where}.{key}")
    elif isinstance(a, list):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{where}[{i}]")
    elif isinstance(a, float):
        assert abs(a - b) <= 1e-12 * max(1.0, abs(b)), where
    else:
        assert a == b, where


def test_hexapod_leg_lengths_closed_form():
    """At a pure height the semi-regular hexapod's legs are equal: |(R_b, 0) - (R_p e^{i(a_p)}, z)|."""
    robot = SpatialManipulator.preset("stewart_6ups")
    z = 420.0
    q = k.inverse_kinematics(robot, [0, 0, z, 0, 0, 0]).q
    for leg, qi in zip(robot.legs, q):
        A, b = np.array(leg.base), np.array(leg.platform)
        assert abs(qi - np.sqrt(np.sum((A[:2] - b[:2]) ** 2) + z ** 2)) < 1e-12 * qi
    np.testing.assert_allclose(q, q[0], rtol=1e-9)      # semi-regular: all six equal


@pytest.mark.parametrize("name", PRESETS)
def test_forward_of_inverse_returns_the_pose(name):
    robot = SpatialManipulator.preset(name)
    rng = np.random.default_rng(3)
    poses = np.array([_near_home(robot, rng) for _ in range(20)])
    q = k.inverse_kinematics(robot, poses).q
    fk = k.forward_kinematics(robot, q, k.reference_pose(robot))
    assert np.all(fk.converged)
    np.testing.assert_allclose(fk.poses[:, :3], poses[:, :3], atol=1e-8)
    dr = (Rotation.from_rotvec(fk.poses[:, 3:]) * Rotation.from_rotvec(poses[:, 3:]).inv()).magnitude()
    assert np.max(dr) < 1e-10


def _fd_forward(robot, pose, q, h=1e-5):
    cols = []
    for i in range(robot.n_actuators):
        dq = np.zeros(robot.n_actuators)
        dq[i] = h
        a = k.forward_kinematics(robot, q + dq, pose).poses
        b = k.forward_kinematics(robot, q - dq, pose).poses
        w = (Rotation.from_rotvec(a[3:]) * Rotation.from_rotvec(b[3:]).inv()).as_rotvec()
        cols.append(np.concatenate([a[:3] - b[:3], w]) / (2 * h))
    return np.array(cols).T


@pytest.mark.parametrize("name", PRESETS)
def test_forward_jacobian_against_finite_differences_of_the_closure(name):
    robot = SpatialManipulator.preset(name)
    rng = np.random.default_rng(11)
    for _ in range(3):
        pose = _near_home(robot, rng)
        q = k.inverse_kinematics(robot, pose).q
        jac = k.jacobians(robot, pose)
        fd = _fd_forward(robot, pose, q)
        scale = np.max(np.abs(jac.forward))
        assert np.max(np.abs(fd - jac.forward)) < 1e-7 * scale
        # actuation rows give the actuator rates, constraint rows vanish on every twist the robot makes
        np.testing.assert_allclose(jac.actuation @ jac.forward, np.eye(robot.n_actuators), atol=1e-10)
        if jac.constraint.shape[0]:
            assert np.max(np.abs(jac.constraint @ jac.forward)) < 1e-10 * scale
        assert jac.overall.shape == (6, 6)


@pytest.mark.parametrize("name", PRESETS)
def test_actuation_wrenches_are_the_derivative_of_the_inverse_kinematics(name):
    """For any small displacement t of the pose, q changes by a_i . t (the actuated values as functions of the
    pose, through each leg's closed form) -- for lower-mobility robots too."""
    robot = SpatialManipulator.preset(name)
    pose = _near_home(robot, np.random.default_rng(5))
    jac = k.jacobians(robot, pose)
    h = 1e-5
    rows = []
    for j in range(6):
        t = np.zeros(6)
        t[j] = h
        rows.append((k.inverse_kinematics(robot, displace(pose, t)).q - k.inverse_kinematics(robot, displace(pose, -t)).q)
                    / (2 * h))
    fd = np.array(rows).T
    if robot.mobility == "6" or name == "rps_3" or name == "upu_3":
        # a leg's length: the actuation wrench alone (constraints are separate rows)
        W = jac.wrenches[np.all(jac.gains != 0, axis=-1) | (np.sum(jac.gains != 0, axis=-1) == 1)]
    np.testing.assert_allclose((jac.actuation @ jac.forward), np.eye(robot.n_actuators), atol=1e-10)
    # on the robot's own motions the two agree exactly
    np.testing.assert_allclose(fd @ jac.forward, np.eye(robot.n_actuators), atol=1e-6)


def test_complete_poses_solves_the_parasitic_motions():
    for name in ("rps_3", "prs_3"):
        robot = SpatialManipulator.preset(name)
        pose = k.complete_poses(robot, [300.0 if name == "rps_3" else 240.0, 0.1, -0.05])
        ik = k.inverse_kinematics(robot, pose)
        assert ik.constraint_residual < 1e-9
        # symmetric robot at a pure height: no parasitic motion at all
        flat = k.complete_poses(robot, [300.0, 0.0, 0.0])
        np.testing.assert_allclose(flat[[0, 1, 3, 4, 5]], 0.0, atol=1e-7)
        # a full pose that breaks the constraint is not attainable
        bad = pose + np.array([5.0, 0, 0, 0, 0, 0])
        assert not bool(k.inverse_kinematics(robot, bad).within_limits)


@pytest.mark.parametrize("name", ["delta_clavel", "upu_3"])
def test_translational_robots_have_two_assembly_modes_both_closing_the_legs(name):
    robot = SpatialManipulator.preset(name)
    pose = _near_home(robot, np.random.default_rng(2))
    q = k.inverse_kinematics(robot, pose).q
    modes = k.assembly_modes(robot, q)
    assert modes.poses.shape[0] == 2
    assert np.min(np.linalg.norm(modes.poses - pose, axis=-1)) < 1e-8
    for m in modes.poses:
        e = k.closure(robot, m, q).residuals
        assert np.max(np.abs(e)) < 1e-8


def test_fichter_singularity_of_the_hexapod():
    """A semi-regular hexapod with planar base and platform is singular at every height when the platform is
    turned by 90 deg about z (Fichter 1986): W loses rank there, not at yaw 0."""
    robot = SpatialManipulator.preset("stewart_6ups")
    sing = k.singularity(robot, [[0, 0, 400, 0, 0, np.pi / 2], [0, 0, 400, 0, 0, 0]])
    assert sing.parallel[0] < 1e-9
    assert sing.parallel[1] > 0.1
    W = k.jacobians(robot, [0, 0, 400, 0, 0, np.pi / 2]).wrenches
    assert abs(np.linalg.det(W)) < 1e-9 * np.prod(np.linalg.norm(W, axis=-1))


def test_delta_serial_singularity_when_arm_and_rod_align():
    """A Delta leg whose rod lies along the arm's direction of motion loses transmission (serial singularity)."""
    robot = SpatialManipulator.preset("delta_clavel")
    leg = robot.legs[0]
    # put the platform ball straight along the arm's tangent from the elbow at theta = 0 ... a rod collinear
    # with the arm (fully stretched) has zero gain
    theta = 0.3
    C = leg.elbow(theta)
    d = leg.arm_direction(theta)
    B = C + leg.rod * d
    p = B - np.array(leg.platform)
    s = k.singularity(robot, np.concatenate([p, np.zeros(3)]))
    assert s.serial[0] < 1e-6


def test_bad_robot_files_name_the_key():
    good = SpatialManipulator.preset("rps_3").to_dict()
    import copy

    cases = [
        (lambda d: d["legs"].pop(), "legs"),
        (lambda d: d["legs"][1].pop("stroke"), "legs[2].stroke"),
        (lambda d: d["legs"][0].__setitem__("axis", [0, 0, 0]), "legs[1].axis"),
        (lambda d: d["legs"][0].__setitem__("axis", [0, 0, 1]), "legs[1].base_normal"),
        (lambda d: d["legs"][2].__setitem__("platform", [1, 2]), "legs[3].platform"),
        (lambda d: d["legs"][2].__setitem__("stroke", [400, 300]), "legs[3].stroke"),
        (lambda d: d["legs"][2].__setitem__("strok", [300, 400]), "legs[3].strok"),
        (lambda d: d.__setitem__("architecture", "7-UPS"), "architecture"),
    ]
    for change, key in cases:
        d = copy.deepcopy(good)
        change(d)
        with pytest.raises(ConfigError) as exc:
            SpatialManipulator.from_dict(d, source="robot.toml")
        assert exc.value.key == key, (key, str(exc.value))
        assert "robot.toml" in str(exc.value)
    upu = SpatialManipulator.preset("upu_3").to_dict()
    upu["legs"][0]["platform_axis"] = [0, 0, 1]
    with pytest.raises(GeometryError, match="Tsai"):
        SpatialManipulator.from_dict(upu, source="u.toml")


def test_home_outside_limits_is_refused_when_the_file_is_read(tmp_path):
    from pmaccuracy.kinematics import resolve_robot

    d = SpatialManipulator.preset("stewart_6ups").to_dict()
    d["home"]["position"] = [0.0, 0.0, 900.0]
    path = tmp_path / "hex.toml"
    import tomli_w

    path.write_text(tomli_w.dumps(d))
    with pytest.raises(GeometryError, match="home pose is outside the joint limits: leg 1: actuated") as exc:
        resolve_robot(str(path))
    assert exc.value.key == "home"


def test_bad_poses():
    robot = SpatialManipulator.preset("stewart_6ups")
    with pytest.raises(PoseError, match=r"\(\.\.\., 6\)"):
        k.inverse_kinematics(robot, [0, 0, 400])
    with pytest.raises(PoseError, match="not finite"):
        k.inverse_kinematics(robot, [0, 0, np.nan, 0, 0, 0])
    with pytest.raises(PoseError, match="3 coordinates"):
        k.complete_poses(SpatialManipulator.preset("rps_3"), [300.0, 0.0])
    with pytest.raises(PoseError, match="6 actuator values"):
        k.forward_kinematics(robot, [400.0] * 5)


def test_interference_between_legs_is_detected():
    """Turning the hexapod's platform far about z crosses neighbouring legs: their 20 mm capsules meet."""
    robot = SpatialManipulator.preset("stewart_6ups")
    ik = k.inverse_kinematics(robot, [[0, 0, 400, 0, 0, 0], [0, 0, 400, 0, 0, np.radians(130)]])
    inter = [key for key in ik.limits if key[1] == "interference"]
    assert inter
    assert all(bool(ik.limits[key][0]) for key in inter)
    assert any(not bool(ik.limits[key][1]) for key in inter)


def test_dietmaiers_hexapod_through_the_front_door_has_forty_real_modes():
    """Dietmaier (1998): a general 6-SPS with 40 real assembly modes (data as in test_assembly_modes.py, via
    martyushev/fkSGP), written as a robot file in mm (x 1000) and solved by pm.forward_kinematics."""
    import pmaccuracy as pm
    from test_assembly_modes import DIETMAIER_BASE, DIETMAIER_LENGTHS, DIETMAIER_PLATFORM

    data = {"architecture": "6-UPS", "name": "dietmaier",
            "legs": [{"base": list(1000.0 * a), "platform": list(1000.0 * b), "stroke": [1.0, 5000.0]}
                     for a, b in zip(DIETMAIER_BASE, DIETMAIER_PLATFORM)]}
    robot = SpatialManipulator.from_dict(data, source="dietmaier.toml")
    modes = pm.forward_kinematics(robot, 1000.0 * DIETMAIER_LENGTHS)
    assert modes.complete and modes.poses.shape[0] == 40
    q = k.inverse_kinematics(robot, modes.poses).q
    assert np.max(np.abs(q - 1000.0 * DIETMAIER_LENGTHS)) < 1e-8
