"""Issue 34, item 2, in the library: repeated calibration rows warned, first-order loaded errors that the exact
model moves by more than 5 % warned, NaN (not an exception) where no leg reaches a pose with
``allow_outside=True, singular="nan"``."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import error_reference as eref
import planar_reference as pref
from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.accuracy.calibration.data import read_calibration_csv, write_calibration_csv
from pmaccuracy.accuracy.calibration.parameters import error_parameters
from pmaccuracy.accuracy.calibration.plan import plan_poses
from pmaccuracy.accuracy.loads import Load, loaded_pose_error
from pmaccuracy.errors import OutsideJointLimitsError
from pmaccuracy.kinematics import inverse_kinematics, regular_mask
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.model.plausibility import PlausibilityWarning
from pmaccuracy.model.sources import ErrorSources


def _caught(fn):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = fn()
    return result, [str(w.message) for w in caught if issubclass(w.category, PlausibilityWarning)]


def test_repeated_calibration_rows_are_warned_with_their_lines(tmp_path):
    pv = error_parameters(Manipulator.preset("aalborg_3ppr"))
    plan = plan_poses(pv, 8)
    path = tmp_path / "data.csv"
    write_calibration_csv(pv.robot, plan.commands, plan.poses, path)
    clean, messages = _caught(lambda: read_calibration_csv(path, pv))
    assert not [m for m in messages if "repeat" in m]
    lines = path.read_text().splitlines()
    path.write_text("\n".join(lines + [lines[3], lines[5]]) + "\n")   # data rows 3 and 5 entered again
    data, messages = _caught(lambda: read_calibration_csv(path, pv))
    hits = [m for m in messages if "repeat" in m]
    assert len(hits) == 1, messages
    assert str(path) in hits[0] and "line 10 repeats line 4" in hits[0] and "line 11 repeats line 6" in hits[0]
    assert len(data) == len(clean) + 2      # a warning, not a refusal


def _random_rpr_case(rng):
    """A random 3-RPR (tests/reference generator), its random clearances and a regular pose near home."""
    for _ in range(20):
        data, nominal = pref.random_rpr(rng)
        robot = Manipulator.from_dict(data, source="random")
        clear, _ = eref.random_clearances(rng, eref.load_robot(data), p_skip=0.15)
        poses = nominal + np.column_stack([rng.uniform(-3, 3, (8, 2)), rng.uniform(-0.03, 0.03, 8)])
        ok = inverse_kinematics(robot, poses).within_limits & regular_mask(robot, poses, 20.0)
        if np.any(ok):
            return robot, ErrorSources.from_dict(clear, source="random"), poses[ok][0]
    raise AssertionError("no usable pose")


def test_first_order_loaded_error_far_from_the_exact_one_is_warned():
    """Random 3-RPRs with their clearances scaled up to 4 times: the warning comes exactly where the exact
    model moves the first-order error (position or orientation, the larger part) by clearly more than 5 %,
    and never where both differ by clearly less."""
    rng = np.random.default_rng(3407)
    seen = {"warned": 0, "quiet": 0}
    for _ in range(24):
        robot, sources, pose = _random_rpr_case(rng)
        load = Load(fx=float(rng.normal(0, 10)), fy=float(rng.normal(0, 10)), m=float(rng.normal(0, 300)))
        for factor in (1.0, 4.0):
            r, messages = _caught(lambda: loaded_pose_error(robot, sources.scaled(factor), pose, load))
            fo, ex = r.first_order, r.exact
            pos, rot = np.hypot(*ex[:2]), abs(ex[2])
            size = np.hypot(pos, robot.characteristic_length * rot)
            rel = [np.hypot(*(fo[:2] - ex[:2])) / pos if pos >= 0.1 * size else 0.0,
                   abs(fo[2] - ex[2]) / rot if robot.characteristic_length * rot >= 0.1 * size else 0.0]
            hit = [m for m in messages if "first-order loaded error differs" in m]
            if max(rel) > 0.06:
                assert len(hit) == 1, (rel, messages)
                seen["warned"] += 1
            elif max(rel) < 0.04:
                assert not hit, (rel, messages)
                seen["quiet"] += 1
    assert seen["warned"] >= 1 and seen["quiet"] >= 10, seen


@pytest.mark.parametrize("robot, clearances", [("symmetric_3rrr", "rrr_typical"), ("symmetric_3prr", "prr_typical"),
                                               ("symmetric_3rpr", "rpr_typical")])
def test_unreachable_pose_is_nan_with_allow_outside_and_singular_nan(robot, clearances):
    poses = np.array([[0.0, 0.0, 0.0], [1e4, 0.0, 0.0]])      # the second: no leg reaches it
    b = max_pose_errors(robot, clearances, poses, allow_outside=True, singular="nan", details=True)
    for q in (b.dx_max, b.dy_max, b.dphi_max, b.dp_max):
        assert np.isfinite(q[0]) and np.isnan(q[1])
    assert np.all(np.isnan(b.generators[1]))
    with pytest.raises(OutsideJointLimitsError):      # without both, still refused
        max_pose_errors(robot, clearances, poses, singular="nan")
