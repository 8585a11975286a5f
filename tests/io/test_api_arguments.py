"""Issue 12 item 3: the public entry points take preset names and files wherever they take objects, and a wrong
type or shape raises the library's own exception naming the parameter (never a numpy or attribute error)."""

from __future__ import annotations

import numpy as np
import pytest

from pmaccuracy.accuracy.bounds import bounds_or_nan, max_pose_errors, slsqp_max_pose_errors
from pmaccuracy.model.clearances import ClearanceSet
from pmaccuracy.accuracy.designs import compare_designs
from pmaccuracy.accuracy.error_model import load_variations, pose_error
from pmaccuracy.errors import ConfigError, PoseError
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.kinematics import forward_kinematics, inverse_kinematics
from pmaccuracy.accuracy.maps import error_map
from pmaccuracy.io.resolve import load_clearances
from pmaccuracy.kinematics.workspace import constant_orientation_workspace

ROBOT = Manipulator.preset("aalborg_3ppr")
POSES = np.array([[0.0, 0.0, 0.0], [5.0, -3.0, 0.2]])


def test_names_and_paths_equal_objects(tmp_path):
    by_object = max_pose_errors(ROBOT, ClearanceSet.load("case2"), POSES)
    by_name = max_pose_errors("aalborg_3ppr", "case2", POSES)
    path = tmp_path / "c.toml"
    ClearanceSet.load("case2").to_toml(path)
    by_path = max_pose_errors(ROBOT, path, POSES)
    for other in (by_name, by_path):
        np.testing.assert_array_equal(other.dp_max, by_object.dp_max)
    np.testing.assert_array_equal(bounds_or_nan("aalborg_3ppr", "case2", POSES)[:, 3], by_object.dp_max)
    tol = max_pose_errors(ROBOT, ClearanceSet(), POSES, tolerances="example_tolerances")
    from pmaccuracy.accuracy.bounds import load_tolerances
    np.testing.assert_array_equal(tol.dp_max, max_pose_errors(ROBOT, ClearanceSet(), POSES,
                                                              tolerances=load_tolerances("example_tolerances")).dp_max)
    np.testing.assert_array_equal(inverse_kinematics("aalborg_3ppr", POSES).q, inverse_kinematics(ROBOT, POSES).q)
    assert constant_orientation_workspace("aalborg_3ppr", 0.0).area == constant_orientation_workspace(ROBOT, 0.0).area
    assert load_clearances("case1", "aalborg_3ppr") == ClearanceSet.load("case1")
    np.testing.assert_array_equal(pose_error("aalborg_3ppr", POSES, "aalborg_table2"),
                                  pose_error(ROBOT, POSES, load_variations("aalborg_table2")))


@pytest.mark.parametrize("call, error, needles", [
    (lambda: max_pose_errors(ROBOT, "case1", POSES, tolerances={"theta": [1e-3] * 2}), ConfigError,
     ["tolerances.theta", "3 values", "got 2"]),
    (lambda: max_pose_errors(ROBOT, "case1", POSES, tolerances={"theta": "abc"}), ConfigError, ["tolerances.theta"]),
    (lambda: max_pose_errors(ROBOT, "case1", POSES, tolerances={"d": [[1, 2, 3]]}), ConfigError, ["tolerances.d"]),
    (lambda: max_pose_errors(ROBOT, "case1", POSES, tolerances=[1, 2]), ConfigError, ["tolerances"]),
    (lambda: max_pose_errors(ROBOT, 3, POSES), ConfigError, ["clearances", "int"]),
    (lambda: max_pose_errors(ROBOT, None, POSES), ConfigError, ["clearances"]),
    (lambda: max_pose_errors(None, "case1", POSES), ConfigError, ["robot"]),
    (lambda: max_pose_errors(ROBOT, "case1", "abc"), PoseError, ["poses"]),
    (lambda: max_pose_errors(ROBOT, "case1", [[0, 0]]), PoseError, ["shape"]),
    (lambda: max_pose_errors(ROBOT, "no_such_preset", POSES), ConfigError, ["no_such_preset"]),
    (lambda: slsqp_max_pose_errors(ROBOT, 2.0, POSES), ConfigError, ["clearances"]),
    (lambda: inverse_kinematics(ROBOT, [[1, 2, 3], [4, 5]]), PoseError, ["poses"]),
    (lambda: inverse_kinematics(42, POSES), ConfigError, ["robot"]),
    (lambda: forward_kinematics(ROBOT, "x"), PoseError, ["actuator"]),
    (lambda: constant_orientation_workspace(ROBOT, "x"), PoseError, ["phi"]),
    (lambda: compare_designs(["aalborg_3ppr", "symmetric_3ppr"], ["case1"], [0.0]), ConfigError, ["clearances"]),
    (lambda: compare_designs("aalborg_3ppr", "case1", [0.0]), ConfigError, ["one entry per robot"]),
    (lambda: ClearanceSet(bearing_angle=[1e-3, 2e-3]), ConfigError, ["bearing_angle", "3 values"]),
    (lambda: ClearanceSet(bearing_angle="x"), ConfigError, ["bearing_angle"]),
    (lambda: pose_error(ROBOT, POSES, {"theta": [1e-3] * 2}), ConfigError, ["variations.theta"]),
    (lambda: pose_error(ROBOT, POSES, {"nope": 1.0}), ConfigError, ["variations", "nope"]),
    (lambda: error_map(ROBOT, "case1", 0.0, "x"), ConfigError, ["n"]),
    (lambda: error_map(ROBOT, "case1", "x", 5), ConfigError, ["phi"]),
    (lambda: error_map(ROBOT, None, 0.0, 5), ConfigError, ["clearances"]),
])
def test_wrong_types_and_shapes_raise_named_errors(call, error, needles):
    with pytest.raises(error) as info:
        call()
    for needle in needles:
        assert needle in str(info.value)
