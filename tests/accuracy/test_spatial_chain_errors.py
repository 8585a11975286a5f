"""Error sources of joint-chain legs (``spatial-chain``): the same physical sources on the same joints give the
same worst cases as the closed-form leg types (their generators are built independently: from the chain's
solved screws here, from each leg type's geometry there)."""

from __future__ import annotations

import numpy as np
import pytest
import tomli_w

from chain_builders import chain_table
from conftest import run_cli
from pmaccuracy.accuracy.spatial_bounds import spatial_pose_errors
from pmaccuracy.errors import ClearanceError
from pmaccuracy.kinematics.spatial import complete_poses, controlled_coordinates, reference_pose
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.model.spatial_sources import JOINTS, SpatialErrorSources, allowed_keys


def _sources_table(arch, n_legs, seed, skip=()):
    rng = np.random.default_rng(seed)
    legs = []
    for _ in range(n_legs):
        joints = []
        for j, kind in enumerate(JOINTS[arch]):
            keys = sorted(allowed_keys(arch, j) - {"length"} - ({"direction"} if kind == "P" else set())
                          - {k for (jj, k) in skip if jj == j})
            joints.append({k: float(rng.uniform(0.001, 0.01)) for k in keys})
        legs.append({"joints": joints})
    return {"name": "random", "legs": legs}


@pytest.mark.parametrize("name", ["stewart_6ups", "rps_3", "prs_3", "upu_3"])
def test_chain_sources_equal_the_leg_types(name):
    robot = SpatialManipulator.preset(name)
    chain = SpatialManipulator.from_dict(chain_table(robot), "chain.toml")
    # a 3-RPS's slide tilts about its block's midpoint (it moves as the leg extends): compared at home only;
    # a 3-UPU's platform joint's direction tolerance is about its platform-side axis there, its proximal one here
    skip = {(2, "direction")} if name == "upu_3" else set()
    table = _sources_table(robot.architecture, robot.n_legs, seed=1, skip=skip)
    a = SpatialErrorSources.from_dict(table, robot)
    b = SpatialErrorSources.from_dict(table, chain)
    home = reference_pose(robot)
    rng = np.random.default_rng(2)
    scale = np.array([10.0 if n in "xyz" else 0.05 for n in robot.controlled])
    c = controlled_coordinates(robot, home) + rng.uniform(-1, 1, (4, len(scale))) * scale
    poses = np.concatenate([home[None], complete_poses(robot, c)])
    if name == "rps_3":
        poses = home[None]
    ea, eb = spatial_pose_errors(robot, a, poses), spatial_pose_errors(chain, b, poses)
    assert np.max(np.abs(ea.components - eb.components)) <= 1e-9 * np.max(ea.components)
    assert np.max(np.abs(ea.dp_upper - eb.dp_upper)) <= 1e-6 * np.max(ea.dp_upper)
    sa, sb = ea.shares(), eb.shares()
    assert sa.keys() == sb.keys()
    for key in sa:
        assert np.max(np.abs(sa[key] - sb[key])) <= 1e-9 * np.max(ea.components), key


def test_chain_sources_are_checked_per_joint_and_have_no_default(tmp_path, capsys):
    robot = SpatialManipulator.preset("rps_3")
    chain = SpatialManipulator.from_dict(chain_table(robot), "chain.toml")
    table = _sources_table("3-RPS", 3, seed=3)
    table["legs"][0]["joints"][2]["lateral"] = 0.01        # a spherical joint has no slide
    with pytest.raises(ClearanceError, match="spherical joint") as info:
        SpatialErrorSources.from_dict(table, chain, source="c.toml")
    assert info.value.key == "legs[1].joints[3].lateral"
    path = tmp_path / "chain.toml"
    path.write_bytes(tomli_w.dumps(chain.to_dict()).encode())
    status, _, err = run_cli(["bounds", "--robot", path, "--pose", 300, 2, 1], capsys)
    assert status == 2 and len(err.strip().splitlines()) == 1 and "no default error sources" in err
    good = tmp_path / "sources.toml"
    good.write_bytes(tomli_w.dumps(_sources_table("3-RPS", 3, seed=3)).encode())
    status, out, err = run_cli(["bounds", "--robot", path, "--clearances", good, "--pose", 300, 2, 1], capsys)
    assert status == 0, err
    assert "dp" in out


def test_chain_statics_carry_the_leg_wrench_through_every_joint():
    import pmaccuracy as pm
    robot = SpatialManipulator.preset("stewart_6ups")
    chain = SpatialManipulator.from_dict(chain_table(robot), "chain.toml")
    load = pm.SpatialLoad(force=(3.0, -2.0, -50.0), moment=(100.0, 0.0, 40.0))
    a = pm.spatial_statics(robot, robot.home_pose, load)
    b = pm.spatial_statics(chain, chain.home_pose, load)
    assert np.allclose(a.actuator, b.actuator, rtol=1e-9, atol=1e-9)
    # the chain's joint centres are where the closed-form leg's are (U at the base, S at the platform)
    assert np.allclose(b.centres[..., [0, 2], :], a.centres[..., [0, 2], :], atol=1e-9)
    assert np.allclose(b.reactions[..., [0, 2], :], a.reactions[..., [0, 2], :], atol=1e-9)
    table = _sources_table("6-UPS", 6, seed=5)
    ea = pm.spatial_loaded_error(robot, SpatialErrorSources.from_dict(table, robot), robot.home_pose, load)
    eb = pm.spatial_loaded_error(chain, SpatialErrorSources.from_dict(table, chain), chain.home_pose, load)
    assert np.allclose(ea.error, eb.error, atol=1e-12)
