"""First-order worst cases of spatial robots: closed-form cases, consistency, bad input. (The brute-force
comparison with the nonlinear loop closure is in test_spatial_bounds_reference.py.)"""

from __future__ import annotations

import numpy as np
import pytest

import pmaccuracy as pm
from pmaccuracy.accuracy.spatial_bounds import spatial_pose_errors
from pmaccuracy.errors import ConfigError, OutsideJointLimitsError, SingularPoseError
from pmaccuracy.kinematics import spatial as k
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.model.spatial_sources import JOINTS, SpatialErrorSources, SpatialJointErrors, allowed_keys, default_preset


def _sources(robot, per_joint):
    """The same ``{joint index: {key: value}}`` on every leg."""
    n = len(JOINTS[robot.architecture])
    return SpatialErrorSources(robot.architecture, tuple(tuple(SpatialJointErrors(**per_joint.get(j, {}))
                                                               for j in range(n)) for _ in robot.legs))


def _everything(robot, length=0.01, angle=2e-4):
    n = len(JOINTS[robot.architecture])
    per = {}
    for j in range(n):
        per[j] = {key: angle if key in ("tilt", "direction") or (key == "actuator" and robot.architecture == "delta")
                  else length for key in allowed_keys(robot.architecture, j)}
    return _sources(robot, per)


def test_hexapod_actuator_errors_are_the_forward_jacobian():
    robot = SpatialManipulator.preset("stewart_6ups")
    pose = k.reference_pose(robot) + np.array([10, -5, 3, 0.02, -0.01, 0.03])
    J = k.jacobians(robot, pose).forward
    b = spatial_pose_errors(robot, _sources(robot, {1: {"actuator": 0.005}}), pose)
    np.testing.assert_allclose(b.components, 0.005 * np.sum(np.abs(J), axis=1), rtol=1e-12)
    # a zonotope: |dp| exact (upper = attained), at least the largest component, at most their norm
    assert b.dp_upper == pytest.approx(b.dp_lower, rel=1e-9)
    assert max(b.components[:3]) <= b.dp_lower + 1e-12 <= np.linalg.norm(b.components[:3]) + 1e-12


def test_hexapod_ball_clearance_acts_like_an_actuator_error_along_its_leg():
    """Only the component of a platform ball's play along its leg moves the platform (the leg is a two-force
    member): a ball of radius e on every leg gives the same components as actuator errors of e."""
    robot = SpatialManipulator.preset("stewart_6ups")
    pose = k.reference_pose(robot)
    ball = spatial_pose_errors(robot, _sources(robot, {2: {"radial": 0.02}}), pose)
    act = spatial_pose_errors(robot, _sources(robot, {1: {"actuator": 0.02}}), pose)
    np.testing.assert_allclose(ball.components, act.components, rtol=1e-12)


def test_shares_add_up_and_scaling_is_linear():
    for name in ("stewart_6ups", "delta_clavel", "rps_3", "prs_3", "upu_3"):
        robot = SpatialManipulator.preset(name)
        pose = k.reference_pose(robot)
        src = _everything(robot)
        b = spatial_pose_errors(robot, src, pose)
        np.testing.assert_allclose(sum(b.shares().values()), b.components, rtol=1e-12)
        b3 = spatial_pose_errors(robot, src.scaled(3.0), pose)
        np.testing.assert_allclose(b3.components, 3 * b.components, rtol=1e-12)
        assert b3.dp_upper == pytest.approx(3 * b.dp_upper, rel=2e-3)
        assert b.dp_lower <= b.dp_upper * (1 + 1e-12)
        assert (b.dp_upper - b.dp_lower) <= 1e-3 * b.dp_lower * (1 + 1e-9)
        assert max(b.components[:3]) <= b.dp_upper * (1 + 1e-12)
        assert b.dp_lower <= np.linalg.norm(b.components[:3]) * (1 + 1e-12)
        assert max(b.components[3:]) <= b.dtheta_upper * (1 + 1e-12)


def test_delta_ball_plays_tilt_the_platform_but_rod_length_errors_of_one_leg_do_not():
    robot = SpatialManipulator.preset("delta_clavel")
    pose = k.reference_pose(robot)
    balls = spatial_pose_errors(robot, _sources(robot, {2: {"radial": 0.01}, 4: {"radial": 0.01}}), pose)
    assert np.all(balls.components[3:] > 1e-6)          # the parallelograms no longer hold the orientation
    # both rods of one leg longer by the same amount: a translation only (the legs keep the platform level)
    src = SpatialErrorSources("delta", (
        (SpatialJointErrors(), SpatialJointErrors(length=0.01), SpatialJointErrors(),
         SpatialJointErrors(length=0.01), SpatialJointErrors()),) + tuple((SpatialJointErrors(),) * 5
                                                                            for _ in range(2)))
    b = spatial_pose_errors(robot, src, pose)
    # each rod's own length is an independent segment: the tilt comes only from their difference
    m = b.sources[0].matrix + b.sources[1].matrix          # both rods longer together
    assert np.max(np.abs(m[3:])) < 1e-12 * np.max(np.abs(m[:3]))


def test_no_sources_no_error():
    robot = SpatialManipulator.preset("rps_3")
    b = spatial_pose_errors(robot, SpatialErrorSources.zero(robot), k.reference_pose(robot))
    assert np.all(b.components == 0) and b.dp_upper == 0


def test_bad_sources_and_poses():
    robot = SpatialManipulator.preset("stewart_6ups")
    good = _sources(robot, {0: {"radial": 0.01}}).to_dict()
    import copy

    for change, key in [
        (lambda d: d["legs"].pop(), "legs"),
        (lambda d: d["legs"][0]["joints"].pop(), "legs[1].joints"),
        (lambda d: d["legs"][1]["joints"][2].__setitem__("tilt", 0.001), "legs[2].joints[3].tilt"),
        (lambda d: d["legs"][1]["joints"][0].__setitem__("radial", -0.01), "legs[2].joints[1].radial"),
        (lambda d: d["legs"][1]["joints"][2].__setitem__("actuator", 0.01), "legs[2].joints[3].actuator"),
    ]:
        d = copy.deepcopy(good)
        change(d)
        with pytest.raises(ConfigError) as exc:
            SpatialErrorSources.from_dict(d, robot, source="c.toml")
        assert exc.value.key == key and "c.toml" in str(exc.value)
    src = SpatialErrorSources.from_dict(good, robot, source="c.toml")
    with pytest.raises(SingularPoseError):
        spatial_pose_errors(robot, src, [0, 0, 400, 0, 0, np.pi / 2], allow_outside=True)   # Fichter
    with pytest.raises(OutsideJointLimitsError):
        spatial_pose_errors(SpatialManipulator.preset("delta_clavel"), _sources(SpatialManipulator.preset(
            "delta_clavel"), {}), [0, 0, -5000, 0, 0, 0])


def test_hexapod_closed_form_blocks_equal_the_general_construction():
    """The 6-UPS's closed-form segments (used for large batches) against the general source-by-source
    construction, on random poses and every key of every joint."""
    from pmaccuracy.accuracy.spatial_bounds import error_sources_at

    robot = SpatialManipulator.preset("stewart_6ups")
    rng = np.random.default_rng(4)
    per = {j: {key: float(rng.uniform(0.001, 0.02)) for key in allowed_keys("6-UPS", j)} for j in range(3)}
    src = _sources(robot, per)
    poses = k.reference_pose(robot) + np.concatenate([rng.uniform(-30, 30, (50, 3)), rng.uniform(-0.08, 0.08, (50, 3))],
                                                     axis=1)
    fast, _ = error_sources_at(robot, src, poses, keep=False)
    general, info = error_sources_at(robot, src, poses, keep=True)
    comp_fast = sum(np.linalg.norm(b, axis=-1) for b in fast)
    comp_general = sum(np.linalg.norm(s.matrix, axis=-1) for s in info["sources"])
    np.testing.assert_allclose(comp_fast, comp_general, rtol=1e-10)
    a = spatial_pose_errors(robot, src, poses, details=False)
    b = spatial_pose_errors(robot, src, poses, details=True)
    np.testing.assert_allclose(a.components, b.components, rtol=1e-10)
    np.testing.assert_allclose(a.dp_upper, b.dp_upper, rtol=2e-3)


@pytest.mark.parametrize("name", ["stewart_6ups", "delta_clavel"])
def test_error_components_alone_equal_the_full_evaluation(name):
    """The components without the norms (the hexapod's one-pass path, the general one for a Delta) equal the
    components of the full evaluation with per-source data; a singular or out-of-limits pose raises, or is NaN
    with ``strict=False``."""
    robot = SpatialManipulator.preset(name)
    src = SpatialErrorSources.load(default_preset(robot), robot)
    rng = np.random.default_rng(11)
    ref = k.reference_pose(robot)
    if robot.mobility == "6":
        poses = ref + np.concatenate([rng.uniform(-20, 20, (40, 3)), rng.uniform(-0.05, 0.05, (40, 3))], axis=1)
    else:                                          # a Delta: positions around the reference, identity orientation
        poses = k.complete_poses(robot, ref[:3] + rng.uniform(-20, 20, (40, 3)))
    full = spatial_pose_errors(robot, src, poses, details=True)
    np.testing.assert_allclose(pm.spatial_error_components(robot, src, poses), full.components, rtol=1e-12)
    if name == "stewart_6ups":
        far = np.array([0.0, 0.0, 400.0, 0.0, 0.0, np.pi / 2])    # Fichter's singularity (any length reaches)
    else:
        far = np.array(ref, dtype=float)
        far[2] += 1e4                                              # no arm reaches
    with pytest.raises((OutsideJointLimitsError, SingularPoseError)):
        pm.spatial_error_components(robot, src, np.vstack([poses[:3], far]))
    loose = pm.spatial_error_components(robot, src, np.vstack([poses[:3], far]), strict=False)
    assert np.all(np.isnan(loose[3])) and np.allclose(loose[:3], full.components[:3], rtol=1e-12)
