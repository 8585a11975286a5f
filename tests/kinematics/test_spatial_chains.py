"""Spatial legs given joint by joint (``spatial-chain``): the numeric product-of-exponentials engine against the
closed-form leg types of the presets, a C-P-S hexapod against its closed form, files and their errors."""

from __future__ import annotations

import numpy as np
import pytest
import tomli_w

import pmaccuracy as pm
from chain_builders import chain_table, cps_table
from pmaccuracy.errors import ConfigError, GeometryError
from pmaccuracy.kinematics.spatial import complete_poses, controlled_coordinates, reference_pose
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.numerics.spatial import displace, rotations

PRESETS = ["stewart_6ups", "rps_3", "prs_3", "upu_3", "delta_clavel"]


def _poses(robot, n=16, seed=1):
    home = reference_pose(robot)
    rng = np.random.default_rng(seed)
    scale = np.array([15.0 if name in "xyz" else 0.08 for name in robot.controlled])
    c = controlled_coordinates(robot, home) + rng.uniform(-1, 1, (n, len(robot.controlled))) * scale
    return complete_poses(robot, c)


@pytest.mark.parametrize("name", PRESETS)
def test_chain_equals_closed_form_legs(name):
    robot = SpatialManipulator.preset(name)
    chain = SpatialManipulator.from_dict(chain_table(robot), "chain.toml")
    assert chain.mobility == robot.mobility and chain.n_actuators == robot.n_actuators
    poses = _poses(robot)
    q = pm.inverse_kinematics(robot, poses).q
    ik = pm.inverse_kinematics(chain, poses)
    scale = np.maximum(1.0, np.abs(q))
    assert np.max(np.abs(ik.q - q) / scale) < 1e-9
    assert np.max(ik.constraint_residual) < 1e-9
    # forward kinematics from the home pose and the forward Jacobian (basis-free: t = J q_dot)
    fk = pm.forward_kinematics(chain, q, guess=reference_pose(chain))
    assert fk.converged.all() and np.max(np.abs(fk.poses - poses)) < 1e-8
    J1 = pm.jacobians(robot, poses).forward
    J2 = pm.jacobians(chain, poses).forward
    assert np.max(np.abs(J2 - J1)) <= 1e-9 * np.max(np.abs(J1))
    # the parasitic motions of lower-mobility robots from the chain's own constraint wrenches
    c = controlled_coordinates(robot, poses)
    assert np.max(np.abs(complete_poses(chain, c) - poses)) < 1e-8


def _cps():
    table = cps_table()
    lines = [leg.pop("line") for leg in table["legs"]]
    return SpatialManipulator.from_dict(table, "cps.toml"), lines


def _cps_lengths(robot, lines, poses):
    """Closed form: each leg is perpendicular to its base line, so its length is the distance from the platform
    point to that line."""
    R = rotations(poses[..., 3:])
    out = []
    for leg, (A, a) in zip(robot.legs, lines):
        d = poses[..., :3] + R @ np.asarray(leg.platform) - A
        out.append(np.linalg.norm(d - (d @ a)[..., None] * a, axis=-1))
    return np.stack(out, -1)


def test_cylindrical_joints_against_closed_form_and_finite_differences():
    robot, lines = _cps()
    assert robot.label == "6-CPS (joint chains)"
    rng = np.random.default_rng(3)
    poses = robot.home_pose + np.concatenate([rng.uniform(-30, 30, (12, 3)), rng.uniform(-0.1, 0.1, (12, 3))], -1)
    q = _cps_lengths(robot, lines, poses)
    assert np.max(np.abs(pm.inverse_kinematics(robot, poses).q - q)) < 1e-9
    fk = pm.forward_kinematics(robot, q)
    assert np.max(np.abs(fk.poses - poses)) < 1e-8
    # inverse Jacobian rows against central differences of the closed form along each twist direction
    J = pm.jacobians(robot, poses[:3]).forward
    h = 1e-4
    for k in range(6):
        t = np.zeros(6)
        t[k] = h
        dq = (_cps_lengths(robot, lines, displace(poses[:3], t))
              - _cps_lengths(robot, lines, displace(poses[:3], -t))) / (2 * h)
        # J maps q_dot to the twist: J @ dq/dt_k must give the unit twist e_k
        back = np.einsum("nij,nj->ni", J, dq)
        assert np.max(np.abs(back - np.eye(6)[k])) < 1e-6


@pytest.mark.slow
def test_chain_modes_include_the_home_pose():
    robot, lines = _cps()
    q = _cps_lengths(robot, lines, robot.home_pose)
    modes = pm.assembly_modes(robot, q)
    assert not modes.complete and "Newton" in modes.method
    assert np.min(np.max(np.abs(modes.poses - robot.home_pose), axis=-1)) < 1e-8
    # every mode found closes the loops with these actuator values
    assert np.max(np.abs(pm.inverse_kinematics(robot, modes.poses[modes.within_limits]).q - q)) < 1e-8


def test_chain_file_round_trip(tmp_path):
    robot = SpatialManipulator.preset("delta_clavel")
    chain = SpatialManipulator.from_dict(chain_table(robot), "chain.toml")
    path = tmp_path / "chain.toml"
    path.write_bytes(tomli_w.dumps(chain.to_dict()).encode())
    again = pm.load_robot(str(path))
    assert again.is_chain and again.controlled == chain.controlled
    poses = _poses(robot, n=4)
    assert np.max(np.abs(pm.inverse_kinematics(again, poses).q - pm.inverse_kinematics(chain, poses).q)) < 1e-12


def test_chain_limits():
    robot = SpatialManipulator.preset("stewart_6ups")
    table = chain_table(robot)
    table["legs"][0]["joints"][0]["range_deg"] = [[-1.0, 1.0], [-1.0, 1.0]]
    table["legs"][1]["joints"][2].update(cone_deg=2.0, normal=[0.0, 0.0, 1.0])
    chain = SpatialManipulator.from_dict(table, "chain.toml")
    home = chain.home_pose
    moved = home + np.array([30.0, 0, 0, 0, 0, 0])
    ik = pm.inverse_kinematics(chain, np.stack([home, moved]))
    assert bool(ik.within_limits[0]) and not bool(ik.within_limits[1])
    words = " ".join(ik.violations((1,)))
    assert "leg 1: joints[1].range" in words and "leg 2: joints[3].cone" in words
    # the U joint's angles: rotating leg 1 about its first axis by the measured value reproduces the direction
    values = chain.legs[0].joint_values(moved[:3], rotations(moved[3:]))
    assert abs(values["joints[1].value1"]) > np.radians(1.0) or abs(values["joints[1].value2"]) > np.radians(1.0)


def _broken(mutate):
    table = chain_table(SpatialManipulator.preset("rps_3"))
    mutate(table)
    return table


@pytest.mark.parametrize("mutate, key, words", [
    (lambda t: t["legs"][0]["joints"][1].pop("actuated"), "legs[1].joints", "exactly one joint with actuated"),
    (lambda t: t["legs"][0]["joints"][0].update(actuated=True), "legs[1].joints", "exactly one joint"),
    (lambda t: t["legs"][0]["joints"][2].update(actuated=True), "legs[1].joints[3].actuated", "only an R or a P"),
    (lambda t: t["legs"][0]["joints"][0].update(type="X"), "legs[1].joints[1].type", "one of R, P, U, C, S"),
    (lambda t: t["legs"][0]["joints"][0].update(stroke=[0, 1]), "legs[1].joints[1].stroke", "an R joint takes no"),
    (lambda t: t.pop("home"), "home", "[home]"),
    (lambda t: t.update(controlled=["x", "z", "y"]), "controlled", "must be one of"),
    (lambda t: t["legs"][0]["joints"].pop(0), "legs", "closure equations"),
])
def test_chain_errors_name_the_key(mutate, key, words):
    with pytest.raises((ConfigError, GeometryError)) as info:
        SpatialManipulator.from_dict(_broken(mutate), "bad.toml")
    assert info.value.key == key and info.value.source == "bad.toml"
    assert words in info.value.message


def test_u_joint_axes_must_be_perpendicular():
    def mutate(t):
        t["legs"][0]["joints"][0]["axes"][1] = t["legs"][0]["joints"][0]["axes"][0]
    table = chain_table(SpatialManipulator.preset("stewart_6ups"))
    mutate(table)
    with pytest.raises(GeometryError, match="perpendicular") as info:
        SpatialManipulator.from_dict(table, "bad.toml")
    assert info.value.key == "legs[1].joints[1].axes"


def test_unreachable_points_are_outside_not_errors():
    """Points a Delta's arms cannot reach: the chain's parasitic motions give NaN (not a crash, not a pose), its
    inverse kinematics NaN, as the closed-form legs say."""
    robot = SpatialManipulator.preset("delta_clavel")
    chain = SpatialManipulator.from_dict(chain_table(robot), "chain.toml")
    rng = np.random.default_rng(7)
    pts = reference_pose(robot)[:3] + rng.uniform(-1, 1, (200, 3)) * np.repeat([[250.0], [900.0]], 100, axis=0)
    ik = pm.inverse_kinematics(robot, np.concatenate([pts, 0 * pts], -1))
    reach = np.all(np.isfinite(ik.q), axis=-1)
    inside = np.asarray(ik.within_limits)
    assert 10 < inside.sum() and reach.sum() < 190
    poses = complete_poses(chain, pts, strict=False)
    closes = np.all(np.isfinite(poses), axis=-1)
    # never a pose where the legs cannot reach; every pose within the arms' ranges found (the numeric inverse
    # kinematics follows each leg's branch from home: far outside the ranges it may miss a reachable point)
    assert not np.any(closes & ~reach) and np.all(closes[inside])
    assert np.max(np.abs(poses[closes, 3:])) < 1e-9         # pure translation where it closes
    q = pm.inverse_kinematics(chain, np.concatenate([pts, 0 * pts], -1)).q
    assert not np.any(np.all(np.isfinite(q), axis=-1) & ~reach)
