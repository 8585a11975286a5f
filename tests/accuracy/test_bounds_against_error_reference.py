"""Exact bounds of every architecture against the independent brute force ``error_reference.py`` (issue 9).

The reference inserts every source into the legs' chains as a small rigid transform, solves the loop
closures exactly, differentiates them by central finite differences and maximizes support functions
source by source (a dense direction search for dp), without assuming any leg structure. Random
3-RPR, 3-RRR, 3-PRR, mixed-chain and general-gamma 3-PPR robots with random clearances, actuator errors
and tolerances: the library's dx, dy, dphi, dp maxima agree to 1e-6 relative.
"""

from __future__ import annotations

import numpy as np
import pytest

import error_reference as eref
import planar_reference as pref
from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.kinematics import inverse_kinematics, regular_mask
from pmaccuracy.model.sources import ErrorSources

GENERATORS = {"3-RPR": pref.random_rpr, "3-RRR": pref.random_rrr, "3-PRR": pref.random_prr,
              "chain": pref.random_chain}


def _merged(clearances, tolerances):
    legs = []
    for cl, tl in zip(clearances["legs"], tolerances["legs"]):
        legs.append({"joints": [{**c, **t} for c, t in zip(cl["joints"], tl["joints"])]})
    return {"legs": legs}


def _random_ppr(rng):
    """A 3-PPR with any gamma (not only +-90 deg), nominal pose at the origin inside its ranges."""
    from conftest import random_manipulator
    rr = random_manipulator(rng)
    return rr.robot.to_dict(), rr.home


def _check(data, nominal, rng, n_poses=2):
    robot = Manipulator.from_dict(data, source="random")
    clear, tol = eref.random_clearances(rng, eref.load_robot(data))
    sources = ErrorSources.from_dict(_merged(clear, tol), source="random clearances")
    poses = nominal + np.column_stack([rng.uniform(-5, 5, (6, 2)), rng.uniform(-0.05, 0.05, 6)])
    ok = inverse_kinematics(robot, poses).within_limits & regular_mask(robot, poses, 20.0)
    poses = poses[ok][:n_poses]
    assert len(poses), "no usable pose"
    b = max_pose_errors(robot, sources, poses)
    for k, pose in enumerate(poses):
        want = eref.worst_case(data, pose, clear, tol)
        got = [b.dx_max[k], b.dy_max[k], b.dphi_max[k], b.dp_max[k]]
        ref = [want["dx_max"], want["dy_max"], want["dphi_max"], want["dp_max"]]
        np.testing.assert_allclose(got, ref, rtol=1e-6)


@pytest.mark.parametrize("kind", sorted(GENERATORS))
def test_random_robots_of_every_architecture(kind):
    rng = np.random.default_rng(100 + len(kind))
    for _ in range(2):
        data, nominal = GENERATORS[kind](rng)
        _check(data, nominal, rng)


def test_general_gamma_3ppr():
    rng = np.random.default_rng(7)
    for _ in range(2):
        data, nominal = _random_ppr(rng)
        _check(data, nominal, rng)
