"""Clearances in the spatial calibration: the first-order pose covariance against a Monte Carlo of states drawn
here (uniform in the segment, disc and ball by rejection from the cube, not by the library's sampler), the
library's random displacements inside the worst-case bound, and an identification whitened by them."""

from __future__ import annotations

import numpy as np

from pmaccuracy.accuracy.calibration.spatial_clearances import (VARIANCE, _sources, clearance_covariance,
                                                                clearance_twists)
from pmaccuracy.accuracy.calibration.spatial_parameters import spatial_error_parameters
from pmaccuracy.accuracy.calibration.spatial_simulate import candidate_poses
from pmaccuracy.accuracy.spatial_bounds import spatial_pose_errors
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.model.spatial_sources import SpatialErrorSources


def _setup(name, preset):
    robot = SpatialManipulator.preset(name)
    sources = SpatialErrorSources.load(preset, robot)
    poses = candidate_poses(spatial_error_parameters(robot), 200, seed=1)[:3]
    return robot, sources, poses


def _rejection(rng, n, d):
    """``n`` points uniform in the unit ``d``-ball, by rejection from the cube ``[-1, 1]^d``."""
    out = np.empty((0, d))
    while len(out) < n:
        x = rng.uniform(-1.0, 1.0, (4 * n, d))
        out = np.concatenate([out, x[np.sum(x * x, axis=1) <= 1.0]])
    return out[:n]


def test_covariance_matches_monte_carlo_of_uniform_states():
    robot, sources, poses = _setup("rps_3", "rps_typical")
    C = clearance_covariance(robot, sources, poses)
    rng = np.random.default_rng(0)
    n = 20000
    M = _sources(robot, sources, poses)
    assert {m.shape[-1] for m in M} >= {1, 2}
    samples = np.zeros((n, len(poses), 6))
    for m in M:
        u = _rejection(rng, n, m.shape[-1])
        samples += np.einsum("pij,nj->npi", m, u)
    emp = np.einsum("npi,npj->pij", samples, samples) / n
    scale = np.sqrt(np.einsum("pii->pi", C))
    # 20000 draws: the second moments within 5 % of the largest (their sampling error is ~1 %)
    assert np.max(np.abs(emp - C) / (scale[:, :, None] * scale[:, None, :])) < 0.05
    assert VARIANCE == {1: 1 / 3, 2: 1 / 4, 3: 1 / 5}


def test_random_displacements_stay_inside_the_worst_case_bound():
    robot, sources, poses = _setup("stewart_6ups", "ups_typical")
    rng = np.random.default_rng(1)
    tw = clearance_twists(robot, sources, np.tile(poses, (400, 1)), rng).reshape(400, len(poses), 6)
    bound = spatial_pose_errors(robot, sources, poses)
    assert np.all(np.linalg.norm(tw[:, :, :3], axis=-1) <= bound.dp_upper * (1 + 1e-9))
    assert np.all(np.linalg.norm(tw[:, :, 3:], axis=-1) <= bound.dtheta_upper * (1 + 1e-9))
    # and their second moments are the covariance's (the library's sampler against its own formula)
    C = clearance_covariance(robot, sources, poses)
    emp = np.einsum("spi,spj->pij", tw, tw) / len(tw)
    assert np.allclose(np.trace(emp[:, :3, :3], axis1=1, axis2=2), np.trace(C[:, :3, :3], axis1=1, axis2=2),
                       rtol=0.25)
