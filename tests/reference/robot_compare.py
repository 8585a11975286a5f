"""Two spatial robots compared leg by leg and by their inverse kinematics (robot-file round trips)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from pmaccuracy.kinematics.spatial import inverse_kinematics


def random_poses(robot, n=25, seed=0):
    """Random poses around home: +-15 mm, +-3 deg (pure translations for a 3T robot)."""
    rng = np.random.default_rng(seed)
    poses = np.tile(np.asarray(robot.home, dtype=float), (n, 1))
    poses[:, :3] += rng.uniform(-15, 15, (n, 3))
    if robot.mobility != "3T":
        poses[:, 3:] = (Rotation.from_rotvec(poses[:, 3:]) * Rotation.from_rotvec(
            rng.uniform(-0.05, 0.05, (n, 3)))).as_rotvec()
    return poses


def assert_same_robot(a, b, tol=1e-9):
    assert a.architecture == b.architecture and a.n_legs == b.n_legs
    np.testing.assert_allclose(a.home, b.home, atol=tol, rtol=0)
    for i, (la, lb) in enumerate(zip(a.legs, b.legs), start=1):
        ta, tb = la.to_table(), lb.to_table()
        assert set(ta) == set(tb), (i, set(ta) ^ set(tb))
        for key in ta:
            np.testing.assert_allclose(ta[key], tb[key], atol=tol, rtol=0, err_msg=f"leg {i} {key}")
    poses = random_poses(a)
    qa, qb = inverse_kinematics(a, poses).q, inverse_kinematics(b, poses).q
    assert np.all(np.isfinite(qa))
    np.testing.assert_allclose(qb, qa, atol=tol, rtol=0)
