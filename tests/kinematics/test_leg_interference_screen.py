"""The capsule distance and the screened interference test of many poses against brute force and the unscreened
per-pose test."""

from dataclasses import replace

import numpy as np

from pmaccuracy.kinematics import spatial as k
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.numerics.spatial import segment_distance



def _segment_distance_brute(p1, q1, p2, q2, n=801):
    """The smallest distance over a fine grid of both segments' parameters, refined once around the best pair."""
    s = np.linspace(0, 1, n)
    d = np.linalg.norm((p1 + s[:, None] * (q1 - p1))[:, None] - (p2 + s[:, None] * (q2 - p2))[None], axis=2)
    i, j = np.unravel_index(np.argmin(d), d.shape)
    s2 = np.clip(np.linspace(s[i] - 2 / n, s[i] + 2 / n, 201), 0, 1)
    t2 = np.clip(np.linspace(s[j] - 2 / n, s[j] + 2 / n, 201), 0, 1)
    a, b = p1 + s2[:, None] * (q1 - p1), p2 + t2[:, None] * (q2 - p2)
    return float(np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2).min())


def test_segment_distance_against_brute_force_batched():
    rng = np.random.default_rng(7)
    cases = [rng.normal(size=(4, 3)) * 100 for _ in range(40)]
    cases += [np.array([[0, 0, 0], [100, 0, 0], [20, 30, 0], [120, 30, 0]], float),     # parallel
              np.array([[0, 0, 0], [100, 0, 0], [150, 0, 0], [300, 0, 0]], float),     # collinear apart
              np.array([[0, 0, 0], [100, 0, 0], [50, -50, 0], [50, 50, 0]], float),    # crossing
              np.array([[0, 0, 0], [0, 0, 0], [50, -50, 10], [50, 50, 10]], float),    # a point
              np.array([[1, 2, 3], [1, 2, 3], [4, 5, 6], [4, 5, 6]], float)]           # two points
    c = np.array(cases)                                                               # (n, 4, 3)
    batched = segment_distance(c[:, 0], c[:, 1], c[:, 2], c[:, 3])
    for case, d in zip(cases, batched):
        bf = _segment_distance_brute(*case)
        assert d <= bf + 1e-9
        assert bf - d < 1e-3 * max(1.0, np.abs(case).max() / 100)
        assert float(segment_distance(*case)) == d                                    # one at a time: the same
    np.testing.assert_allclose(batched[-3:], [0.0, np.hypot(50.0, 10.0), np.sqrt(27.0)], atol=1e-12)


def test_screened_interference_equals_the_pose_by_pose_test():
    robot = SpatialManipulator.preset("stewart_6ups")
    fat = replace(robot, legs=tuple(replace(leg, radius=45.0) for leg in robot.legs))   # some poses interfere
    rng = np.random.default_rng(3)
    poses = k.reference_pose(fat) + np.concatenate([rng.uniform(-60, 60, (150, 3)), rng.uniform(-0.3, 0.3, (150, 3))],
                                                   axis=1)
    q = k.inverse_kinematics(fat, poses).q
    batch = k.leg_interference(fat, poses, q)
    one = [k.leg_interference(fat, poses[n], q[n]) for n in range(len(poses))]      # no screen for one pose
    clash = 0
    for key, ok in batch.items():
        np.testing.assert_array_equal(ok, [o[key] for o in one])
        clash += int(np.sum(~ok))
    assert 0 < clash < 15 * len(poses)
