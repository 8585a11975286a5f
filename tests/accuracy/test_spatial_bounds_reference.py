"""Spatial first-order worst cases against the independent brute-force reference
(tests/reference/spatial_error_reference.py: every source applied as a finite displacement in the legs'
nonlinear chains, the pose re-solved by least squares, central differences, each source's own support function),
on the reference's robots and clearance files and on random robots and clearances of every architecture."""

from __future__ import annotations

import numpy as np
import pytest
import spatial_error_reference as eref
import spatial_reference as ref

from pmaccuracy.accuracy.spatial_bounds import spatial_pose_errors
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.model.spatial_sources import SpatialErrorSources
from pmaccuracy.numerics.spatial import rotvecs

ARCHS = ["6-UPS", "delta", "3-RPS", "3-PRS", "3-UPU"]


def _ours(robot_dict, cl_dict, p, R):
    robot = SpatialManipulator.from_dict(robot_dict, source="r.toml")
    sources = SpatialErrorSources.from_dict(cl_dict, robot, source="c.toml")
    return spatial_pose_errors(robot, sources, np.concatenate([p, rotvecs(R)]))


def _check(robot_dict, cl_dict, p, R, label, nonlinear=0):
    ours = _ours(robot_dict, cl_dict, p, R)
    M, sources = eref.sensitivity(robot_dict, cl_dict, p, R)
    comp = eref.component_bounds(M, sources)
    scale = np.max(comp[:3]), np.max(comp[3:])
    # components: to the finite differences' accuracy (~1e-8 relative)
    assert np.max(np.abs(ours.components[:3] - comp[:3])) <= 1e-6 * scale[0], (label, ours.components, comp)
    assert np.max(np.abs(ours.components[3:] - comp[3:])) <= 1e-6 * scale[1], (label, ours.components, comp)
    # |dp| and |dtheta|: never below the reference's attained values, within the stated gap above them
    for rows, upper, lower in ((slice(0, 3), ours.dp_upper, ours.dp_lower),
                               (slice(3, 6), ours.dtheta_upper, ours.dtheta_lower)):
        sampled = eref.max_norm_sampled(M, sources, rows=rows, n=20000, seed=1)
        assert upper >= sampled * (1 - 1e-6), (label, upper, sampled)
        assert upper <= sampled * (1 + ours.gap + 1e-5), (label, upper, sampled)
        assert lower <= upper * (1 + 1e-12)
    if nonlinear:
        T = eref.nonlinear_extremes(robot_dict, cl_dict, p, R, nonlinear, seed=2)
        assert np.all(np.abs(T) <= ours.components * 1.01 + 1e-12), label
        assert np.max(np.linalg.norm(T[:, :3], axis=1)) <= ours.dp_upper * 1.01


@pytest.mark.parametrize("arch", ARCHS)
def test_reference_files_at_home_and_a_random_pose(arch):
    robot = ref.load_reference(arch)
    cl = eref.load_clearances(arch)
    p, R = eref.nominal_pose(robot)
    _check(robot, cl, p, R, f"{arch} home", nonlinear=3)
    p, R = ref.random_pose(robot, 5)
    _check(robot, cl, p, R, f"{arch} random pose")


@pytest.mark.parametrize("arch", ARCHS)
def test_random_robots_and_clearances(arch):
    for seed in (11, 12):
        robot = ref.random_robot(arch, seed)
        cl = eref.random_clearances(robot, seed)
        p, R = ref.random_pose(robot, seed)
        _check(robot, cl, p, R, f"{arch} random {seed}")
