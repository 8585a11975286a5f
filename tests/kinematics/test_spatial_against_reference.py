"""The library's spatial kinematics against the independent reference (tests/reference/spatial_reference.py,
written from docs/guide/spatial.md without reading the library): IK, FK, Jacobians, constraint wrenches, joint
limits, singular poses and workspace volumes, on the reference's robot files and on random robots."""

from __future__ import annotations

import numpy as np
import pytest
import spatial_reference as ref

from pmaccuracy.kinematics import spatial as k
from pmaccuracy.kinematics.spatial_workspace import membership, spatial_workspace
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.numerics.spatial import rotvecs

ARCHS = ["6-UPS", "delta", "3-RPS", "3-PRS", "3-UPU"]


def _robots(arch):
    yield "file", ref.load_reference(arch)
    for seed in (1, 2):
        yield f"random{seed}", ref.random_robot(arch, seed)


def _lib(data, name="robot.toml"):
    return SpatialManipulator.from_dict(data, source=name)


def _pose(p, R):
    return np.concatenate([p, rotvecs(R)])


def _rel(a, b):
    return np.max(np.abs(np.asarray(a) - np.asarray(b))) / max(1.0, np.max(np.abs(b)))


def _same_rows(A, B, tol):
    """The row spaces of A and B coincide (each normalized; rank of the stack equals each's rank)."""
    def unit(M):
        return M / np.linalg.norm(M, axis=-1, keepdims=True)
    s = np.linalg.svd(np.vstack([unit(A), unit(B)]), compute_uv=False)
    return np.sum(s > tol) == np.linalg.matrix_rank(unit(A), tol=tol) == np.linalg.matrix_rank(unit(B), tol=tol)


@pytest.mark.parametrize("arch", ARCHS)
def test_ik_fk_and_jacobians_match_the_reference(arch):
    for label, data in _robots(arch):
        robot = _lib(data)
        for seed in (3, 4):
            p, R = ref.random_pose(data, seed)
            pose = _pose(p, R)
            # inverse kinematics
            q_ref = ref.actuators(data, p, R)
            ik = k.inverse_kinematics(robot, pose)
            assert _rel(ik.q, q_ref) < 1e-12, (label, ik.q, q_ref)
            assert bool(ik.within_limits) == ref.within_limits(data, p, R), (label, ik.violations(),
                                                                            ref.limit_report(data, p, R))
            # forward kinematics (Newton from the same guess)
            dq = 1e-3 * np.arange(1, robot.n_actuators + 1) * (0.01 if arch == "delta" else 1.0)
            p2, R2 = ref.forward(data, q_ref + dq, p, R)
            fk = k.forward_kinematics(robot, q_ref + dq, pose)
            assert np.max(np.abs(fk.poses[:3] - p2)) < 1e-9
            assert np.max(np.abs(k.rotations(fk.poses[3:]) - R2)) < 1e-12
            # forward Jacobian: finite differences of the reference's FK (central, h = 1e-6: ~1e-8 relative)
            jac = k.jacobians(robot, pose)
            J_ref = ref.jacobian_fd(data, p, R)
            assert _rel(jac.forward, J_ref) < 1e-6, (label, _rel(jac.forward, J_ref))
            # inverse Jacobian rows: the derivative of the reference's closed-form IK along any twist
            assert _rel(jac.actuation, ref.inverse_jacobian_fd(data, p, R)) < 1e-6
            # constraint wrenches: the same space as the derivatives of the reference's constraints
            if robot.mobility != "6":
                C_ref = ref.constraint_jacobian_fd(data, p, R)
                assert _same_rows(jac.constraint, C_ref, 1e-6), label


@pytest.mark.parametrize("arch", ARCHS)
def test_joint_limits_agree_with_the_reference_on_random_samples(arch):
    data = ref.load_reference(arch)
    robot = _lib(data)
    ws = spatial_workspace(robot, n=12, tilt=False)
    box = ws.region.box
    rng = np.random.default_rng(0)
    pts = box[:, 0] + (box[:, 1] - box[:, 0]) * rng.random((150, 3))
    ours = np.asarray(membership(robot)(pts))
    theirs = np.array([ref.sample_ok(data, _ref_coords(robot, c)) for c in pts])
    assert np.mean(ours == theirs) >= 0.99, (np.sum(ours != theirs), pts[ours != theirs][:3])
    assert ours.any() and (~ours).any()


def _ref_coords(robot, c):
    """Our grid coordinates -> the reference's sample coordinates ((roll deg, pitch deg, z) -> (z, roll, pitch))."""
    return (c[2], c[0], c[1]) if robot.mobility == "2R1T" else c


@pytest.mark.parametrize("arch", ["6-UPS", pytest.param("3-UPU", marks=pytest.mark.slow),
                                  pytest.param("delta", marks=pytest.mark.slow),
                                  pytest.param("3-RPS", marks=pytest.mark.slow)])
def test_workspace_volume_against_monte_carlo(arch):
    data = ref.load_reference(arch)
    robot = _lib(data)
    ws = spatial_workspace(robot, n=30, tilt=False)
    box = ws.region.box
    if robot.mobility == "2R1T":
        box = box[[2, 0, 1]]         # the reference samples (z, roll, pitch)
    vol, se = ref.monte_carlo_volume(data, None, box, 3000, seed=1)
    assert abs(ws.region.volume - vol) <= 4 * se + ws.region.volume_error, (ws.region.volume, vol, se)


def test_singular_poses_of_the_reference_are_singular_here():
    data = ref.load_reference("6-UPS")
    robot = _lib(data)
    p, _ = ref.home(data)
    R = ref.rotation([0.0, 0.0, 90.0])
    assert ref.screw_singularity_measure(data, p, R) < 1e-6
    assert k.singularity(robot, _pose(p, R)).parallel < 1e-8
    assert k.singularity(robot, _pose(p, np.eye(3))).parallel > 0.05
    # measures agree on being far from singular at random poses
    for seed in range(3):
        p, R = ref.random_pose(data, seed)
        assert ref.parallel_singularity_measure(data, p, R) > 1e-3
        assert k.singularity(robot, _pose(p, R)).parallel > 1e-3


@pytest.mark.parametrize("arch", ["6-UPS", "3-RPS", "3-PRS"])
def test_every_assembly_mode_closes_the_reference_legs(arch):
    data = ref.load_reference(arch)
    robot = _lib(data)
    p, R = ref.random_pose(data, 7)
    q = ref.actuators(data, p, R)
    modes = k.assembly_modes(robot, q)
    assert modes.complete
    assert np.min(np.linalg.norm(modes.poses - _pose(p, R), axis=-1)) < 1e-8
    for pose in modes.poses:
        Rm = k.rotations(pose[3:])
        assert np.all(np.abs(ref.constraint_residuals(data, pose[:3], Rm)) < 1e-8)
        if arch != "3-PRS":        # a 3-PRS mode may close on the other slide branch: check the rod instead
            assert _rel(ref.actuators(data, pose[:3], Rm), q) < 1e-9
