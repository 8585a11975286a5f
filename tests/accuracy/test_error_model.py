"""Independent checks of the first-order error model (paper Sec. 4.1, Eq. 6-15, Appendix A).

Reference computation used here (written in this file and in ``reference_model``,
not taken from the library):

* ``solve_loop_closure`` (``reference_model``) closes the six loop equations of Eq. 1,
  ``p = a_i h_i + s_i u_i + d_i v_i + l_i w_i + rho_i n_i + r_i k_i`` (i = 1..3),
  for the unknowns ``x, y, phi, l_1, l_2, l_3`` by Newton's method (analytic 6x6
  Jacobian, started at the nominal pose), with the actuators ``s_i`` locked at
  their nominal values. The nominal ``s_i, l_i`` come from ``own_ik``, a 2x2 solve
  of ``s u + l w = p - a h - d v - r k``.
* Every column of every ``J_q`` is compared with a central finite difference
  (step 1e-6) of ``solve_loop_closure`` after perturbing that one parameter of that one
  leg (``robot.perturbed``), or the actuator (``s``), or adding the revolute
  offset ``t n_i`` (``rho``; ``n_i = E w_i`` by default, random ``varphi`` too).
* The Cartesian blocks ``J_A..J_D`` are checked by moving the joint points
  exactly as documented in :func:`pmaccuracy.accuracy.error_model.cartesian_jacobians`:
  the end point of a link, in the frame of the link it hangs from, moves by
  ``t e`` and the (length, angle) pair is recomputed exactly in polar form.
* ``pose_error`` for the assembly errors of Table 2 (values typed in from the
  reference file) differs from the exact loop closure by a second-order term:
  halving the errors divides the difference by about 4.

Geometries: the ``aalborg_3ppr`` preset and seeded random geometries with
``|sin(gamma + theta)| >= 0.3``, at random poses whose homogenized ``A`` has a
2-norm condition number below 30.
"""

from __future__ import annotations

import numpy as np
import pytest

from pmaccuracy.accuracy import error_model
from pmaccuracy.model.manipulator import Manipulator
from reference_model import (PARAMS, directions, leg_params, own_A, own_ik, random_poses, random_robot, rot90,
                             solve_loop_closure, vec)

STEP = 1e-6
RTOL = 2e-6


def aalborg_poses(rng, n):
    """Random poses of the preset's workspace (phi = 0 square, and small orientations)."""
    out = [np.array([x, y, 0.0]) for x, y in rng.uniform(-25, 25, (n // 2, 2))]
    out += [np.array([rng.uniform(-10, 10), rng.uniform(-10, 10), rng.uniform(-0.6, 0.6)])
            for _ in range(n - len(out))]
    return np.array(out)


def cases():
    """(id, robot, poses): the preset and five random geometries."""
    rng = np.random.default_rng(12345)
    out = [("aalborg", Manipulator.preset("aalborg_3ppr"), aalborg_poses(rng, 6))]
    for k in range(5):
        robot = random_robot(rng)
        out.append((f"random{k}", robot, random_poses(robot, rng, 3)))
    return out


CASES = cases()


def fd_column(robot, pose, leg, q, varphi=None):
    """Central finite difference of the exact pose w.r.t. variation q of one leg."""
    p0 = leg_params(robot)
    s0, _ = own_ik(p0, pose)
    results = []
    for sign in (1.0, -1.0):
        t = sign * STEP
        delta = np.zeros(3)
        delta[leg] = t
        s = s0.copy()
        offsets = None
        p = p0
        if q == "s":
            s = s0 + delta
        elif q == "rho":
            _, _, _, w = directions(p0)
            n = rot90(w[leg]) if varphi is None else vec(varphi[leg])
            offsets = np.zeros((3, 2))
            offsets[leg] = t * n
        else:
            p = leg_params(robot.perturbed(**{q: delta}))
        results.append(solve_loop_closure(p, s, pose, offsets))
    d = (results[0] - results[1]) / (2 * STEP)
    return d


def assert_close_fd(lib, fd, what):
    scale = max(1.0, float(np.max(np.abs(fd))))
    err = np.max(np.abs(lib - fd))
    assert err <= RTOL * scale, f"{what}: library {lib} vs finite difference {fd} (max error {err:.3g})"


# ------------------------------------------------------------------------------------ tests
def test_own_solver_reproduces_nominal_pose():
    """Sanity of the reference: the nominal actuators give back the nominal pose."""
    for _, robot, poses in CASES:
        p = leg_params(robot)
        for pose in poses:
            s, _ = own_ik(p, pose)
            np.testing.assert_allclose(solve_loop_closure(p, s, pose + [0.3, -0.2, 0.01]), pose, atol=1e-10)


def test_perturbed_changes_one_parameter():
    robot = Manipulator.preset("aalborg_3ppr")
    for q in PARAMS:
        pert = robot.perturbed(**{q: [0.0, 1e-3, 0.0]})
        a, b = leg_params(robot), leg_params(pert)
        for k in PARAMS:
            expected = a[k] + (np.array([0, 1e-3, 0]) if k == q else 0.0)
            np.testing.assert_allclose(b[k], expected, rtol=0, atol=1e-15)


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
@pytest.mark.parametrize("q", ["a", "alpha", "s", "beta", "d", "gamma", "theta", "rho", "r", "psi"])
def test_sensitivity_jacobian_columns_match_finite_differences(case, q):
    """J_q[:, i] = d pose / d q_i of the exact model (Eq. 10-11), every leg, every pose."""
    _, robot, poses = case
    J = error_model.sensitivity_jacobians(robot, poses)
    assert set(J) == {"a", "alpha", "s", "beta", "d", "gamma", "theta", "rho", "r", "psi"}
    assert J[q].shape == (len(poses), 3, 3)
    for n, pose in enumerate(poses):
        for leg in range(3):
            assert_close_fd(J[q][n, :, leg], fd_column(robot, pose, leg, q), f"J_{q} pose {pose} leg {leg + 1}")


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_rho_jacobian_with_random_directions(case):
    """J_rho with n_i = vec(varphi_i), random varphi: FD of the exact model with the offset t n_i."""
    _, robot, poses = case
    rng = np.random.default_rng(7)
    for pose in poses:
        varphi = rng.uniform(-np.pi, np.pi, 3)
        J = error_model.sensitivity_jacobians(robot, pose[None], varphi=varphi[None])["rho"][0]
        for leg in range(3):
            assert_close_fd(J[:, leg], fd_column(robot, pose, leg, "rho", varphi), f"J_rho varphi leg {leg + 1}")


def test_rho_direction_along_bearing_has_no_effect():
    """A revolute offset along w_i is absorbed by the passive joint (H_rho = w^T E^T n = 0)."""
    _, robot, poses = CASES[1]
    p = leg_params(robot)
    _, _, _, w = directions(p)
    varphi = np.arctan2(w[:, 1], w[:, 0])
    J = error_model.sensitivity_jacobians(robot, poses, varphi=np.broadcast_to(varphi, (len(poses), 3)))
    np.testing.assert_allclose(J["rho"], 0.0, atol=1e-12)


def test_kinematic_jacobian_is_A_inv_B():
    """J_s is the kinematic Jacobian of Eq. 5, A^-1 B with A, B built here from Eq. 4a-4b."""
    for _, robot, poses in CASES:
        p = leg_params(robot)
        _, u, _, w = directions(p)
        J = error_model.sensitivity_jacobians(robot, poses)["s"]
        for n, pose in enumerate(poses):
            B = np.diag(np.sum(rot90(w) * u, axis=1))
            np.testing.assert_allclose(J[n], np.linalg.solve(own_A(p, pose), B), rtol=1e-10, atol=1e-12)


def test_link_form_is_concatenation():
    order = ("a", "alpha", "s", "beta", "d", "gamma", "theta", "rho", "r", "psi")
    for _, robot, poses in CASES[:3]:
        J = error_model.sensitivity_jacobians(robot, poses)
        J_err, names = error_model.error_jacobian(robot, poses, form="link")
        assert J_err.shape == (len(poses), 3, 30)
        assert names == [f"{q}{i}" for q in order for i in (1, 2, 3)]
        np.testing.assert_array_equal(J_err, np.concatenate([J[q] for q in order], axis=-1))


def test_unknown_form_raises():
    robot = Manipulator.preset("aalborg_3ppr")
    with pytest.raises(ValueError):
        error_model.error_jacobian(robot, np.zeros(3), form="polar")


def polar(x, sign=1.0):
    """(length, angle) with length * vec(angle) = x and the sign of the length kept (s_i may be negative)."""
    x = sign * np.asarray(x, float)
    return sign * float(np.hypot(x[0], x[1])), float(np.arctan2(x[1], x[0]))


def fd_point(robot, pose, leg, block, axis):
    """Central FD of the exact pose when joint point ``block`` of ``leg`` moves by t e_axis (documented frames)."""
    p0 = leg_params(robot)
    s0, _ = own_ik(p0, pose)
    e = np.eye(2)[axis]
    res = []
    for t in (STEP, -STEP):
        p = {k: v.copy() for k, v in p0.items()}
        s = s0.copy()
        if block == "A":      # A_i = a vec(alpha), base frame
            p["a"][leg], p["alpha"][leg] = polar(p0["a"][leg] * vec(p0["alpha"][leg]) + t * e)
        elif block == "B":    # B_i - A_i = s vec(beta) in the frame of h_i (actuator takes the part along u)
            s[leg], p["beta"][leg] = polar(s0[leg] * vec(p0["beta"][leg]) + t * e, np.sign(s0[leg]))
        elif block == "C":    # C_i - B_i = d vec(gamma) in the frame of u_i
            p["d"][leg], p["gamma"][leg] = polar(p0["d"][leg] * vec(p0["gamma"][leg]) + t * e)
        elif block == "D":    # D_i - P = -r vec(psi) in the platform frame
            p["r"][leg], p["psi"][leg] = polar(p0["r"][leg] * vec(p0["psi"][leg]) - t * e)
        res.append(solve_loop_closure(p, s, pose))
    return (res[0] - res[1]) / (2 * STEP)


@pytest.mark.parametrize("case", CASES[:4], ids=[c[0] for c in CASES[:4]])
def test_cartesian_blocks_match_point_displacements(case):
    """J_A..J_D (Eq. 13, A-2) against FD of exact point displacements (frames of cartesian_jacobians)."""
    _, robot, poses = case
    p = leg_params(robot)
    blocks = error_model.cartesian_jacobians(robot, poses)
    J = error_model.sensitivity_jacobians(robot, poses)
    checked = 0
    for n, pose in enumerate(poses):
        s0, _ = own_ik(p, pose)
        for leg in range(3):
            for block in "ABCD":
                if block == "B" and abs(s0[leg]) < 1.0:
                    continue  # the angle beta cannot be moved by a displacement of B when s = 0
                if block == "C" and p["d"][leg] < 1.0:
                    continue
                for axis in (0, 1):
                    fd = fd_point(robot, pose, leg, block, axis)
                    lib = blocks[block][n, :, 2 * leg + axis]
                    if block == "B":
                        # the actuated component of dB_i (along u'_i) is carried by J ds (Eq. 13)
                        lib = lib + J["s"][n, :, leg] * vec(p["beta"][leg])[axis]
                    assert_close_fd(lib, fd, f"J_{block} leg {leg + 1} axis {'xy'[axis]} pose {pose}")
                    checked += 1
    assert checked > 0


def test_cartesian_form_is_concatenation():
    _, robot, poses = CASES[2]
    blocks = error_model.cartesian_jacobians(robot, poses)
    J_err, names = error_model.error_jacobian(robot, poses, form="cartesian")
    assert J_err.shape == (len(poses), 3, 33)
    assert len(names) == 33
    assert names[:9] == [f"{q}{i}" for q in ("s", "theta", "rho") for i in (1, 2, 3)]
    assert names[9:] == [f"{P}{i}{ax}" for P in "ABCD" for i in (1, 2, 3) for ax in "xy"]
    expected = np.concatenate([blocks[b] for b in ("s", "theta", "rho", "A", "B", "C", "D")], axis=-1)
    np.testing.assert_array_equal(J_err, expected)
    for b in "ABCD":
        assert blocks[b].shape == (len(poses), 3, 6)


def test_assembly_errors_are_table2():
    """Paper Table 2 (reference file): dbeta, dgamma_a, dtheta_a (rad), dd_a (mm)."""
    var = error_model.assembly_errors()
    expected = {"beta": [0.0, 0.014, -0.010], "gamma": [0.016, 0.020, 0.020],
                "theta": [-0.028, -0.022, 0.034], "d": [-0.12, -0.08, 0.15]}
    for q, values in expected.items():
        np.testing.assert_allclose(var[q], values, rtol=0, atol=1e-15)
    for q, values in var.items():
        if q not in expected:
            np.testing.assert_array_equal(values, 0.0)


def test_pose_error_table2_is_second_order_accurate():
    """Halving the Table 2 errors divides (exact - first order) by ~4 (Eq. 10 is a linearization)."""
    robot = Manipulator.preset("aalborg_3ppr")
    var = error_model.assembly_errors()
    p0 = leg_params(robot)
    poses = np.array([[0, 0, 0], [20, -15, 0], [-20, 20, 0], [5, 5, np.radians(30)], [-8, 3, -0.4]], float)
    diffs = []
    for f in (1.0, 0.5, 0.25):
        scaled = {q: f * np.asarray(v) for q, v in var.items()}
        lin = error_model.pose_error(robot, poses, scaled)
        assert lin.shape == poses.shape
        pert = leg_params(robot.perturbed(**scaled))
        exact = np.array([solve_loop_closure(pert, own_ik(p0, pose)[0], pose) - pose for pose in poses])
        # first order is close: the difference is a small fraction of the error itself
        assert np.max(np.abs(exact - lin)) < 0.1 * np.max(np.abs(exact))
        diffs.append(exact - lin)
    for a, b in zip(diffs[:-1], diffs[1:]):
        for n in range(len(poses)):
            ratio = np.linalg.norm(a[n]) / np.linalg.norm(b[n])
            assert 3.4 < ratio < 4.6, f"pose {poses[n]}: second-order ratio {ratio}"


def test_pose_error_equals_sum_of_jacobian_columns():
    """pose_error = sum_q J_q dq (Eq. 10) for random variations of every kind."""
    rng = np.random.default_rng(3)
    for _, robot, poses in CASES[:3]:
        var = {q: rng.normal(0, 1e-3, 3) for q in ("a", "alpha", "s", "beta", "d", "gamma", "theta", "r", "psi")}
        J = error_model.sensitivity_jacobians(robot, poses)
        expected = sum(J[q] @ var[q] for q in var)
        np.testing.assert_allclose(error_model.pose_error(robot, poses, var), expected, rtol=1e-10, atol=1e-15)
    with pytest.raises(ValueError):
        error_model.pose_error(robot, poses, {"zeta": np.zeros(3)})
