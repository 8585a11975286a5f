"""Kinematics (paper Sec. 3, Eq. 1-5) checked against independent computations.

The reference computations here are written from scratch from Eq. 1: the
chain points A_i, B_i, C_i, D_i are built from the leg angles, a 2x2 linear
solve replaces Eq. 2a/2b, scipy's fsolve solves the six closure equations,
and a fine scan of phi finds every assembly mode.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq, fsolve

from conftest import condition_of_a, manipulators, poses_inside, random_manipulator
from pmaccuracy.errors import OutsideJointLimitsError, PoseError, SingularPoseError
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.kinematics import DEFAULT_MAX_CONDITION, forward_kinematics, inverse_kinematics, jacobians, kinematic_jacobian, require_regular, require_within_limits, singularity

SETTINGS = settings(max_examples=40, deadline=None)


# ----------------------------------------------------------------------------------- independent model
def vec(t):
    t = np.asarray(t, dtype=float)
    return np.stack([np.cos(t), np.sin(t)], axis=-1)


def chain_points(robot: Manipulator, s, l, phi):
    """A_i, B_i, C_i, D_i and the platform centre reached through each leg (Eq. 1), each (3, 2)."""
    out = {k: np.zeros((3, 2)) for k in "ABCDP"}
    for i, leg in enumerate(robot.legs):
        b1 = leg.alpha + leg.beta
        g1 = b1 + leg.gamma
        t1 = g1 + leg.theta
        out["A"][i] = leg.a * vec(leg.alpha)
        out["B"][i] = out["A"][i] + s[i] * vec(b1)
        out["C"][i] = out["B"][i] + leg.d * vec(g1)
        out["D"][i] = out["C"][i] + l[i] * vec(t1)
        out["P"][i] = out["D"][i] + leg.r * vec(phi + leg.psi)
    return out


def ik_by_linear_solve(robot: Manipulator, pose):
    """(s_i, l_i) from the 2x2 system [u_i w_i] [s_i, l_i]^T = p - A_i - d_i v_i - r_i k_i."""
    s, l = np.zeros(3), np.zeros(3)
    for i, leg in enumerate(robot.legs):
        b1 = leg.alpha + leg.beta
        g1 = b1 + leg.gamma
        rhs = pose[:2] - leg.a * vec(leg.alpha) - leg.d * vec(g1) - leg.r * vec(pose[2] + leg.psi)
        s[i], l[i] = np.linalg.solve(np.column_stack([vec(b1), vec(g1 + leg.theta)]), rhs)
    return s, l


def closure_residual(robot: Manipulator, s, unknowns):
    """The six equations of Eq. 1 for unknowns (x, y, phi, l1, l2, l3)."""
    x, y, phi, *l = unknowns
    return (chain_points(robot, s, l, phi)["P"] - [x, y]).ravel()


def assembly_condition(robot: Manipulator, s, phi):
    """det [n_i, n_i . (C_i + r_i k_i(phi))], shape of phi: zero iff Eq. 1 has a solution at this phi.

    With n_i normal to the bearing, n_i . p = n_i . (C_i + r_i k_i) for all three legs: three equations
    in the two unknowns p, consistent iff this 3x3 determinant vanishes.
    """
    phi = np.asarray(phi, dtype=float)
    M = np.zeros(phi.shape + (3, 3))
    pts = chain_points(robot, s, np.zeros(3), 0.0)
    for i, leg in enumerate(robot.legs):
        t1 = leg.alpha + leg.beta + leg.gamma + leg.theta
        n = np.array([-np.sin(t1), np.cos(t1)])
        M[..., i, :2] = n
        M[..., i, 2] = n @ pts["C"][i] + leg.r * (vec(phi + leg.psi) @ n)
    return np.linalg.det(M)


def aalborg_ik_by_hand(poses):
    """Eq. 1 specialised by hand to the reference geometry (guides 1, 2 along y, guide 3 along x)."""
    x, y, phi = np.moveaxis(np.asarray(poses, float), -1, 0)
    a, d12, d3, r = 192.34, 83.15, 70.0, 30.0
    s = np.stack([y - r * np.sin(phi + np.pi / 6), y - r * np.sin(phi + 5 * np.pi / 6),
                  r * np.cos(phi - np.pi / 2) - x], axis=-1)
    l = np.stack([x + (a - d12) - r * np.cos(phi + np.pi / 6), (a - d12) - x + r * np.cos(phi + 5 * np.pi / 6),
                  (a - d3) - y + r * np.sin(phi - np.pi / 2)], axis=-1)
    return s, l


# ----------------------------------------------------------------------------------- inverse kinematics
def test_ik_home_pose_of_aalborg(aalborg):
    ik = inverse_kinematics(aalborg, [0.0, 0.0, 0.0])
    l12 = 192.34 - 83.15 - 30 * np.cos(np.radians(30))
    np.testing.assert_allclose(ik.s, [-15.0, -15.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(ik.l, [l12, l12, 192.34 - 70 - 30], atol=1e-12)
    assert ik.within_limits


def test_ik_matches_hand_formula_on_aalborg(aalborg, rng):
    poses = np.column_stack([rng.uniform(-60, 60, (50, 2)), rng.uniform(-np.pi, np.pi, 50)]).reshape(5, 10, 3)
    ik = inverse_kinematics(aalborg, poses)
    s, l = aalborg_ik_by_hand(poses)
    assert ik.s.shape == ik.l.shape == (5, 10, 3) and ik.within_limits.shape == (5, 10)
    np.testing.assert_allclose(ik.s, s, atol=1e-10)
    np.testing.assert_allclose(ik.l, l, atol=1e-10)
    inside = np.all((s >= aalborg.s_range[:, 0]) & (s <= aalborg.s_range[:, 1])
                    & (l >= aalborg.l_range[:, 0]) & (l <= aalborg.l_range[:, 1]), axis=-1)
    np.testing.assert_array_equal(ik.within_limits, inside)


@SETTINGS
@given(manipulators(), st.tuples(st.floats(-80, 80), st.floats(-80, 80), st.floats(-np.pi, np.pi)))
def test_ik_closes_every_chain(rr, pose):
    """Chain points built from the IK joint values all reach the pose (Eq. 1)."""
    pose = np.array(pose)
    ik = inverse_kinematics(rr.robot, pose)
    pts = chain_points(rr.robot, ik.s, ik.l, pose[2])
    np.testing.assert_allclose(pts["P"], np.broadcast_to(pose[:2], (3, 2)), atol=1e-9)
    s, l = ik_by_linear_solve(rr.robot, pose)
    np.testing.assert_allclose(ik.s, s, atol=1e-9)
    np.testing.assert_allclose(ik.l, l, atol=1e-9)


def test_ik_rejects_bad_poses(aalborg):
    with pytest.raises(PoseError, match="shape"):
        inverse_kinematics(aalborg, [1.0, 2.0])
    with pytest.raises(PoseError, match="not finite"):
        inverse_kinematics(aalborg, [[0.0, 0.0, 0.0], [np.nan, 0.0, 0.0]])


# ----------------------------------------------------------------------------------- forward kinematics
@SETTINGS
@given(manipulators(), st.integers(0, 2**32 - 1))
def test_fk_ik_round_trip(rr, seed):
    robot = rr.robot
    poses = poses_inside(robot, rr.home, np.random.default_rng(seed), 8, vary_phi=True)
    poses = poses[condition_of_a(robot, poses) < 100]
    ik = inverse_kinematics(robot, poses)
    fk = forward_kinematics(robot, ik.s)
    assert fk.poses.shape == (len(poses), 6, 3)
    assert np.all(fk.valid[:, 0])
    assert not np.any(fk.valid[:, 2:])  # a 3-PPR has at most two assembly modes
    # The pose we started from is one of the assembly modes ...
    err = np.abs(fk.poses - poses[:, None, :])
    err[..., 2] = np.abs(np.angle(np.exp(1j * (fk.poses[..., 2] - poses[:, None, 2]))))
    assert np.all(np.nanmin(np.max(err, axis=-1), axis=-1) < 1e-8)
    np.testing.assert_allclose(fk.nearest(poses)[:, :2], poses[:, :2], atol=1e-8)
    # ... and every returned mode closes all three chains with the same s, reporting its l.
    for k in range(len(poses)):
        for mode in np.flatnonzero(fk.valid[k]):
            pose = fk.poses[k, mode]
            pts = chain_points(robot, ik.s[k], fk.l[k, mode], pose[2])
            np.testing.assert_allclose(pts["P"], np.broadcast_to(pose[:2], (3, 2)), atol=1e-8)
            assert fk.within_limits[k, mode] == inverse_kinematics(robot, pose).within_limits


@pytest.mark.parametrize("seed", range(12))
def test_fk_finds_every_assembly_mode(seed):
    """A scan of phi over 36 000 points (0.01 deg) finds exactly the modes FK returns."""
    rng = np.random.default_rng(seed)
    rr = random_manipulator(rng)
    robot = rr.robot
    # Actuator values of a reachable pose, and random ones (often with no mode at all).
    for s in (inverse_kinematics(robot, rr.home).s, rng.uniform(robot.s_range[:, 0], robot.s_range[:, 1])):
        phis = np.linspace(-np.pi, np.pi, 36001)
        f = assembly_condition(robot, s, phis)
        roots = [brentq(lambda p: assembly_condition(robot, s, p), phis[j], phis[j + 1], xtol=1e-14)
                 for j in np.flatnonzero(np.sign(f[:-1]) * np.sign(f[1:]) < 0)]
        roots = np.array(roots)
        if len(roots) == 2 and abs(roots[0] - roots[1]) < 1e-3:
            continue  # a near-tangent double root: too close to call with a scan
        if len(roots) and roots[-1] > np.pi - 1e-9 and roots[0] < -np.pi + 1e-9:
            roots = roots[:-1]  # the same angle seen at both ends of the scan
        fk = forward_kinematics(robot, s)
        found = np.sort(fk.poses[fk.valid, 2])
        assert len(found) == len(roots)
        if len(roots):
            dphi = np.angle(np.exp(1j * (np.sort(roots)[:, None] - found[None, :])))
            assert np.all(np.min(np.abs(dphi), axis=1) < 1e-9)


def test_fk_agrees_with_fsolve(rng):
    """A generic Newton-type solver of the six closure equations lands on an FK mode."""
    for _ in range(10):
        rr = random_manipulator(rng)
        s = inverse_kinematics(rr.robot, rr.home).s
        fk = forward_kinematics(rr.robot, s)
        for mode in np.flatnonzero(fk.valid):
            pose, l = fk.poses[mode], fk.l[mode]
            start = np.concatenate([pose + [0.5, -0.5, 0.02], l + 0.5])
            sol, info, ier, msg = fsolve(lambda q: closure_residual(rr.robot, s, q), start, full_output=True)
            assert np.max(np.abs(info["fvec"])) < 1e-9, msg
            np.testing.assert_allclose(sol[:2], pose[:2], atol=1e-7)
            assert np.angle(np.exp(1j * (sol[2] - pose[2]))) == pytest.approx(0.0, abs=1e-9)
            np.testing.assert_allclose(sol[3:], l, atol=1e-7)


def test_fk_of_aalborg_home_joints(aalborg):
    """s = (-15, -15, 0): by hand, sin(phi + 30) = sin(phi + 150) gives phi = 0 or 180 deg;
    the second mode (0, -30, 180 deg) needs l3 = 182.34 mm > 160 mm."""
    fk = forward_kinematics(aalborg, [-15.0, -15.0, 0.0])
    assert fk.valid.tolist() == [True, True] + [False] * 4
    order = np.argsort(np.abs(fk.poses[:2, 2]))
    home, flipped = fk.poses[order]
    np.testing.assert_allclose(home, [0, 0, 0], atol=1e-10)
    np.testing.assert_allclose(flipped[:2], [0, -30], atol=1e-10)
    assert abs(flipped[2]) == pytest.approx(np.pi, abs=1e-10)
    np.testing.assert_allclose(fk.l[order[1], 2], 192.34 - 70 + 30 + 30, atol=1e-10)
    assert fk.within_limits[order].tolist() == [True, False]
    assert not fk.within_limits[2:].any()


def test_fk_without_solution(aalborg):
    """Legs 1 and 2 fix y - s_i = r sin(phi + psi_i): |s1 - s2| > 2 r cos 60 deg ... > 2r has no phi."""
    fk = forward_kinematics(aalborg, [-40.0, 40.0, 0.0])
    assert not fk.valid.any()
    assert np.isnan(fk.poses).all()
    with pytest.raises(PoseError):
        fk.nearest(np.zeros(3))


def test_fk_rejects_bad_input(aalborg):
    with pytest.raises(PoseError):
        forward_kinematics(aalborg, [0.0, 0.0])
    with pytest.raises(PoseError):
        forward_kinematics(aalborg, [0.0, np.inf, 0.0])


# ----------------------------------------------------------------------------------- Jacobians
def _central(fun, x, steps):
    cols = []
    for j, h in enumerate(steps):
        dx = np.zeros_like(x)
        dx[j] = h
        cols.append((fun(x + dx) - fun(x - dx)) / (2 * h))
    return np.stack(cols, axis=-1)


@SETTINGS
@given(manipulators())
def test_jacobians_against_finite_differences(rr):
    robot, pose = rr.robot, rr.home
    A, B = jacobians(robot, pose)
    # IK: ds/d(pose) = B^-1 A (Eq. 3).
    ds_dpose = _central(lambda q: inverse_kinematics(robot, q).s, pose, [1e-4, 1e-4, 1e-6])
    np.testing.assert_allclose(ds_dpose, np.linalg.solve(B, A), rtol=1e-6, atol=1e-6)
    # FK: d(pose)/ds = J = A^-1 B (Eq. 5).
    s0 = inverse_kinematics(robot, pose).s

    def fk_pose(s):   # the assembly mode of the home pose, phi unwrapped next to it (FK wraps to (-pi, pi])
        q = forward_kinematics(robot, s).nearest(pose)
        q[2] = pose[2] + np.angle(np.exp(1j * (q[2] - pose[2])))
        return q

    dpose_ds = _central(fk_pose, s0, [1e-5] * 3)
    J = kinematic_jacobian(robot, pose, max_condition=1e6)
    np.testing.assert_allclose(dpose_ds, J, rtol=1e-5, atol=1e-6 * np.max(np.abs(J)))
    np.testing.assert_allclose(J @ np.linalg.solve(B, A), np.eye(3), atol=1e-9)


def test_jacobians_broadcast(aalborg, rng):
    poses = np.column_stack([rng.uniform(-20, 20, (6, 2)), rng.uniform(-1, 1, 6)]).reshape(2, 3, 3)
    A, B = jacobians(aalborg, poses)
    assert A.shape == B.shape == (2, 3, 3, 3)
    assert kinematic_jacobian(aalborg, poses).shape == (2, 3, 3, 3)


def test_backward_jacobian_is_constant_and_regular(aalborg, rng):
    """B_ii = w_i^T E^T u_i = -sin(gamma_i + theta_i) (Eq. 4b): never singular, pose independent."""
    for _ in range(5):
        robot = random_manipulator(rng).robot
        _, B = jacobians(robot, rng.uniform(-1, 1, (4, 3)))
        np.testing.assert_allclose(B, np.broadcast_to(np.diag(-np.sin(robot.gamma + robot.theta)), (4, 3, 3)),
                                   atol=1e-14)
    _, B = jacobians(aalborg, np.zeros(3))
    np.testing.assert_allclose(np.abs(np.diag(B)), 1.0, atol=1e-15)


# ----------------------------------------------------------------------------------- singularity
def test_aalborg_det_a_by_hand(aalborg):
    """Rows of A for the reference geometry: [0, 1, -r cos(phi+30)], [0, -1, r cos(phi+150)], [1, 0, .]
    so det A = r (cos(phi+150) - cos(phi+30)) = -sqrt(3) r cos(phi): zero at phi = +-90 deg."""
    phi = np.radians(np.arange(-180.0, 180.0, 7.5))
    poses = np.column_stack([np.full_like(phi, 5.0), np.full_like(phi, -3.0), phi])
    np.testing.assert_allclose(singularity(aalborg, poses).det, -np.sqrt(3) * 30 * np.cos(phi), atol=1e-10)


@pytest.mark.parametrize("phi_deg", [90.0, -90.0])
def test_aalborg_singular_at_plus_minus_90(aalborg, phi_deg):
    pose = np.array([1.0, 2.0, np.radians(phi_deg)])
    assert singularity(aalborg, pose).condition > 1e12
    with pytest.raises(SingularPoseError, match="singular"):
        require_regular(aalborg, pose)
    with pytest.raises(SingularPoseError):
        kinematic_jacobian(aalborg, pose)
    with pytest.raises(SingularPoseError):
        kinematic_jacobian(aalborg, np.stack([np.zeros(3), pose]))   # one bad pose in a batch


def test_aalborg_regular_at_zero(aalborg):
    pose = np.zeros(3)
    cond = singularity(aalborg, pose).condition
    assert 1.0 <= cond < 10.0
    require_regular(aalborg, pose)
    assert np.all(np.isfinite(kinematic_jacobian(aalborg, pose)))
    # The condition number grows without bound towards phi = 90 deg.
    conds = singularity(aalborg, np.array([[0, 0, np.radians(p)] for p in (0, 60, 85, 89.9)])).condition
    assert np.all(np.diff(conds) > 0) and conds[-1] > 100 * conds[0]
    # The threshold decides: accepted below it, refused above it.
    near = np.array([0, 0, np.radians(89.9)])
    require_regular(aalborg, near, max_condition=2 * conds[-1])
    with pytest.raises(SingularPoseError):
        require_regular(aalborg, near, max_condition=conds[-1] / 2)
    assert DEFAULT_MAX_CONDITION < 1e12   # the default refuses the exact singularity


# ----------------------------------------------------------------------------------- joint limits
@pytest.mark.parametrize("pose, joints", [
    ([0.0, 30.0, 0.0], ["s1=15", "s2=15"]),      # y = s + 15 at phi = 0, s_max = 10
    ([30.0, 0.0, 0.0], ["s3=-30"]),              # x = -s3, s3 >= -25
    ([0.0, -26.0, 0.0], ["s1=-41", "s2=-41"]),
])
def test_require_within_limits_names_the_joint(aalborg, pose, joints):
    with pytest.raises(OutsideJointLimitsError) as info:
        require_within_limits(aalborg, np.array(pose))
    for joint in joints:
        assert joint in str(info.value)
    assert "l1" not in str(info.value)


def test_require_within_limits_passive_joint(aalborg):
    legs = list(aalborg.legs)
    legs[2] = dataclasses.replace(legs[2], l_range=(20.0, 90.0))   # home needs l3 = 92.34 mm
    robot = Manipulator(legs=tuple(legs))
    with pytest.raises(OutsideJointLimitsError, match=r"l3=92\.34 mm not in \[20, 90\]"):
        require_within_limits(robot, np.zeros(3))
    ik = require_within_limits(aalborg, np.array([[0.0, 0.0, 0.0], [24.0, -24.0, 0.0]]))
    assert ik.within_limits.all()


def test_boundary_pose_counts_as_inside(aalborg):
    """The corner (25, 25) at phi = 0 has s1 = s2 = 10 = s_max and s3 = -25 = s_min (up to rounding)."""
    corner = np.array([25.0, 25.0, 0.0])
    assert inverse_kinematics(aalborg, corner).within_limits
    require_within_limits(aalborg, corner)
    for outside in ([25.0 + 1e-6, 25.0, 0.0], [25.0, 25.0 + 1e-6, 0.0]):
        assert not inverse_kinematics(aalborg, outside).within_limits
