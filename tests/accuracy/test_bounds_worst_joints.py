"""``max_pose_errors(..., details=True)`` with per-joint sources (any architecture) returns the maximizing
configurations in ``.worst`` (issue 25), checked against two independent models:

* the first-order model :func:`pmaccuracy.model.sources.first_order_error` (the sources' twists paired with
  the legs' wrenches, solved through ``A^-1``): each configuration moves the platform by exactly ``+max`` in
  its quantity (``|(dx, dy)| = dp_max`` for ``dp``) and its negative by ``-max``;
* the exact nonlinear model (:func:`pmaccuracy.accuracy.nonlinear.joint_displaced_pose`, Newton on the
  perturbed loop closures): the exact displacement of the configuration scaled by ``s`` agrees with ``s``
  times the first-order one up to a remainder that is second order (it shrinks about 4 times when ``s``
  halves).
"""

from __future__ import annotations

import numpy as np
import pytest

import pmaccuracy as pm
from pmaccuracy.accuracy.nonlinear import joint_displaced_pose
from pmaccuracy.model.sources import JointDisplacements, first_order_error

CASES = [("symmetric_3rrr", "rrr_typical"), ("symmetric_3rpr", "rpr_typical"), ("symmetric_3prr", "prr_typical"),
         ("symmetric_3rrr", "rrr_tolerances")]
POSES = np.array([[0.0, 0.0, 0.0], [8.0, -5.0, 0.15], [-6.0, 4.0, -0.1]])
QUANTITY_INDEX = {"dx": 0, "dy": 1, "dphi": 2}


def _bounds(robot, clearances):
    return pm.max_pose_errors(robot, clearances, POSES, details=True)


@pytest.mark.parametrize("robot, clearances", CASES)
def test_worst_configurations_attain_the_first_order_maxima(robot, clearances):
    b = _bounds(robot, clearances)
    assert set(b.worst) == {"dx", "dy", "dphi", "dp"}
    joints = pm.inverse_kinematics(robot, POSES).joints
    r = pm.load_robot(robot)
    for q, config in b.worst.items():
        assert isinstance(config, JointDisplacements) and config.dq.shape == (3, 3, 3)
        plus = first_order_error(r, joints, POSES, config)
        minus = first_order_error(r, joints, POSES, -config)
        if q == "dp":
            np.testing.assert_allclose(np.hypot(plus[:, 0], plus[:, 1]), b.dp_max, rtol=1e-9)
        else:
            expected = getattr(b, f"{q}_max")
            np.testing.assert_allclose(plus[:, QUANTITY_INDEX[q]], expected, rtol=1e-9)
            np.testing.assert_allclose(minus[:, QUANTITY_INDEX[q]], -expected, rtol=1e-9)


def test_shape_follows_the_poses():
    b = pm.max_pose_errors("symmetric_3rpr", "rpr_typical", POSES.reshape(3, 1, 3), details=True)
    assert b.worst["dp"].shift.shape == (3, 1, 3, 3)
    assert pm.max_pose_errors("symmetric_3rpr", "rpr_typical", POSES).worst == {}   # only with details


@pytest.mark.parametrize("robot, clearances", CASES[:3])
def test_worst_configurations_match_the_exact_model_to_second_order(robot, clearances):
    b = _bounds(robot, clearances)
    r = pm.load_robot(robot)
    joints = pm.inverse_kinematics(robot, POSES).joints
    for q in ("dx", "dy", "dphi", "dp"):
        config = b.worst[q]
        fo = first_order_error(r, joints, POSES, config)
        remainders = []
        for s in (1.0, 0.5):
            exact = joint_displaced_pose(r, POSES, config.scaled(s)) - POSES
            remainders.append(np.max(np.abs(exact - s * fo) / np.array([1.0, 1.0, 1e-2])))
        size = np.max(np.abs(fo) / np.array([1.0, 1.0, 1e-2]))
        assert remainders[0] < 0.05 * size            # the first order carries the displacement
        assert 3.0 < remainders[0] / remainders[1] < 5.0, remainders   # and what is left is second order
