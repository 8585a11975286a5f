"""Identification with joint clearances (issue 23): each point's clearance covariance (first order, the
clearance states uniform in their sets) added to its measurement covariance makes the stated sigmas honest.

The data come from :func:`pmaccuracy.accuracy.calibration.simulate.measure`: the exact forward kinematics of
the true robot plus one clearance state per point drawn by the statistics' sampler, independent of the
covariance the identification computes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from calibration_reference import random_robot_dict
from pmaccuracy.accuracy.calibration.data import CalibrationData
from pmaccuracy.accuracy.calibration.identify import ClearanceModel, clearance_covariance, identify
from pmaccuracy.accuracy.calibration.parameters import error_parameters, frame_inverse
from pmaccuracy.accuracy.calibration.plan import candidate_poses, plan_poses
from pmaccuracy.accuracy.calibration.simulate import measure, true_parameters
from pmaccuracy.accuracy.distributions import sample_pose_errors
from pmaccuracy.model.manipulator import Manipulator

CASES = [("symmetric_3rrr", "rrr_typical"), ("symmetric_3rpr", "rpr_typical"), ("symmetric_3prr", "prr_typical"),
         ("aalborg_3ppr", "case1"), ("aalborg_3ppr", "case2")]
SIGMA = (0.01, 0.01, math.radians(0.01))


def normalized_errors(name: str, clearances: str, seeds, *, model: bool = True) -> np.ndarray:
    """``(estimate - truth) / sigma`` of the identified parameters of a random robot over ``seeds`` (plain
    least squares, 30 planned points, camera noise :data:`SIGMA`, a clearance state per point)."""
    pv = error_parameters(Manipulator.from_dict(random_robot_dict(Manipulator.preset(name).to_dict(),
                                                                  np.random.default_rng(11))))
    plan = plan_poses(pv, 30, candidate_poses(pv))
    sig = np.tile(SIGMA, (30, 1))
    probe = CalibrationData(tuple(map(str, range(30))), plan.commands,
                            measure(pv, pv.nominal, plan.commands, plan.poses, seed=0), sig, "<p>")
    fixed = identify(probe, pv).identifiability.fixed
    zs = []
    for seed in seeds:
        true = true_parameters(pv, seed=100 + seed, fixed=fixed)
        m = measure(pv, true, plan.commands, plan.poses, noise=SIGMA, seed=seed, clearances=clearances)
        ok = np.all(np.isfinite(m), axis=1)
        data = CalibrationData(tuple(map(str, range(int(ok.sum())))), plan.commands[ok], m[ok], sig[ok], "<s>")
        ident = identify(data, pv, robust=False, clearances=clearances if model else None)
        free = pv.index(ident.identifiability.identified)
        zs.append((ident.values - true)[free] / ident.sigma[free])
    return np.concatenate(zs)


def test_clearance_covariance_matches_sampled_states():
    """The covariance the identification adds equals the sample covariance of the simulation's clearance
    states (robot frame turned into a measurement frame 30 deg off) within the Monte Carlo error."""
    pv = error_parameters(Manipulator.preset("symmetric_3rrr"))
    values = pv.nominal.copy()
    values[-3:] = (5.0, -3.0, math.radians(30.0))
    poses = candidate_poses(pv)[::400][:4]
    data = CalibrationData(tuple("abcd"), np.zeros((4, 3)), frame_inverse(values[-3:], poses),
                           np.ones((4, 3)), "<c>")
    C = clearance_covariance(pv, values, data, ClearanceModel("rrr_typical"))
    e = sample_pose_errors(pv.robot, "rrr_typical", poses, 40_000, seed=3)             # (S, 4, 3) robot frame
    c, s = math.cos(values[-1]), math.sin(values[-1])
    e = e @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])                             # rows R^T e: measurement frame
    sample = np.einsum("sni,snj->nij", e, e) / len(e)
    scale = np.sqrt(np.einsum("nii->ni", C))
    assert np.max(np.abs(sample - C) / (scale[:, :, None] * scale[:, None, :])) < 0.03


def test_sigmas_honest_with_clearances_few_seeds():
    """Six seeds of the (slides-turned) random 3-PPR with case2: normalized errors of unit spread within 25 %
    and none beyond 4 (1.00 and 2.4); without the clearance covariance the spread is 0.68, which fails the
    same bound (case1: 1.11 with, 0.74 without; too close to tell apart over six seeds)."""
    z = normalized_errors("aalborg_3ppr", "case2", range(6))
    assert abs(z.std() - 1.0) < 0.25 and np.max(np.abs(z)) < 4.0, (z.std(), np.abs(z).max())
    z_old = normalized_errors("aalborg_3ppr", "case2", range(6), model=False)
    assert abs(z_old.std() - 1.0) >= 0.25   # what the test guards against


@pytest.mark.slow
@pytest.mark.parametrize("name, clearances", CASES)
def test_sigmas_honest_with_clearances_over_seeds(name, clearances):
    """Over 20 seeds (random robot, parameter errors, clearance states, camera noise): unit spread within 20 %,
    99 % of the normalized errors within 3 and none beyond 4."""
    z = normalized_errors(name, clearances, range(20))
    assert abs(z.std() - 1.0) < 0.2, z.std()
    assert np.mean(np.abs(z) <= 3.0) >= 0.99 and np.max(np.abs(z)) < 4.0, np.abs(z).max()
