"""Checks of the exact (nonlinear) virtual prototype :mod:`pmaccuracy.accuracy.nonlinear`.

Independent computations written in this file and in ``reference_model``:

* ``own_exact_error``: Newton's method on the six loop equations of Eq. 1
  (``reference_model.solve_loop_closure``) with the clearance displacements
  applied as the paper's Sec. 4.2 says (``reference_model.displace``:
  ``dsigma_g E u_i`` (normal to the rail), ``gamma_i + dtau_g``, ``theta_i + dtau_b``, platform point
  offset by ``drho vec(varphi)``) and the actuators locked; the library's
  analytic loop closure must agree with it to 1e-10.
* ``own_first_order``: ``A^-1 e`` with ``A`` from Eq. 4a and ``e_i`` from Eq. 8 /
  Appendix A (H_theta = l, H_d = w^T E^T v, H_gamma = d w^T v + l,
  H_rho = w^T E^T n).
* Admissible displacements are sampled in this file from Eq. 16-18 (rhombus
  sampled through its two diagonal coordinates).

The nonlinear-minus-first-order difference must be of second order: it shrinks
by a factor of about 4 when the displacement is halved; zero displacement
gives zero error (1e-12).
"""

from __future__ import annotations

import numpy as np
import pytest

from pmaccuracy.accuracy import bounds, nonlinear
from pmaccuracy.model.clearances import ClearanceDisplacement, ClearanceSet
from pmaccuracy.accuracy.error_model import assembly_errors
from pmaccuracy.model.manipulator import Manipulator
from reference_model import (directions, displace, leg_params, own_A, own_ik, random_poses, random_robot, rot90,
                             solve_loop_closure, vec)

AALBORG = Manipulator.preset("aalborg_3ppr")
FIELDS = ("tau_b", "sigma_g", "tau_g", "rho", "varphi")


def disp_at(disp, n):
    return {f: np.asarray(getattr(disp, f), float)[n] for f in FIELDS}


def own_exact_error(robot, pose, d=None, variations=None):
    """Exact pose error by Newton on Eq. 1 (actuators locked at the nominal s)."""
    p0 = leg_params(robot)
    s, l0 = own_ik(p0, pose)
    p = {k: v + np.asarray((variations or {}).get(k, 0.0), float) for k, v in p0.items()}
    s = s + np.asarray((variations or {}).get("s", 0.0), float)
    p, offsets = displace(p, d or {f: np.zeros(3) for f in FIELDS})
    return solve_loop_closure(p, s, pose, offsets, l0=l0, tol=1e-15) - pose


def own_first_order(robot, pose, d):
    p = leg_params(robot)
    _, u, v, w = directions(p)
    _, l = own_ik(p, pose)
    Ew = rot90(w)
    A = own_A(p, pose)
    e = (l * d["tau_b"] + np.sum(Ew * rot90(u), axis=1) * d["sigma_g"] + (p["d"] * np.sum(w * v, axis=1) + l) * d["tau_g"]
         + np.sum(Ew * vec(d["varphi"]), axis=1) * d["rho"])
    return np.linalg.solve(A, e)


def admissible(rng, clear, shape):
    """Random displacements inside Eq. 16-18, fields of shape ``shape + (3,)``."""
    sh = shape + (3,)
    eb, eg, er, L = clear.bearing_angle, clear.guide_lateral, clear.revolute_radial, clear.guide_block_length
    # rhombus coordinates a = (L tau + 2 sigma) / (2 eps), b = (-L tau + 2 sigma) / (2 eps), each in [-1, 1]
    a, b = rng.uniform(-1, 1, sh), rng.uniform(-1, 1, sh)
    return ClearanceDisplacement(tau_b=eb * rng.uniform(-1, 1, sh), sigma_g=eg * (a + b) / 2, tau_g=eg * (a - b) / L,
                                 rho=er * rng.uniform(0, 1, sh), varphi=rng.uniform(-np.pi, np.pi, sh))


def cases():
    rng = np.random.default_rng(77)
    # realistic magnitudes (random geometries amplify more than the preset: keep third-order terms small)
    big = ClearanceSet(bearing_angle=[2e-4, 3e-4, 1e-4], guide_lateral=[0.002, 0.001, 0.003],
                       guide_block_length=[40, 15, 90], revolute_radial=[0.005, 0.003, 0.004])
    out = [("aalborg-all", AALBORG, np.array([[0, 0, 0], [15, -20, 0], [-10, 5, np.radians(30)]]),
            ClearanceSet.load("all")),
           ("aalborg-case2", AALBORG, np.array([[-20, 20, 0], [5, -5, -0.3]]), ClearanceSet.load("case2"))]
    for k in range(3):
        robot = random_robot(rng)
        out.append((f"random{k}", robot, random_poses(robot, rng, 3), big))
    return out


CASES = cases()
WEIGHT = np.array([1.0, 1.0, 30.0])  # mm, mm, mm/rad: one norm for the pose-error vector


# ------------------------------------------------------------------------------------ tests
@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_zero_displacement_zero_error(case):
    _, robot, poses, _ = case
    for disp in (None, ClearanceDisplacement.zeros(), ClearanceDisplacement.zeros((len(poses),))):
        err = nonlinear.displaced_pose_error(robot, poses, disp)
        assert err.shape == poses.shape
        np.testing.assert_allclose(err, 0.0, atol=1e-12)
    np.testing.assert_allclose(nonlinear.displaced_pose(robot, poses), poses, atol=1e-12)


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_nonlinear_matches_independent_newton_solver(case):
    _, robot, poses, clear = case
    disp = admissible(np.random.default_rng(11), clear.scaled(100.0), (len(poses),))  # large: nonlinear visible
    lib = nonlinear.displaced_pose_error(robot, poses, disp)
    for n, pose in enumerate(poses):
        np.testing.assert_allclose(lib[n], own_exact_error(robot, pose, disp_at(disp, n)), rtol=0, atol=1e-10)


def test_nonlinear_with_assembly_variations_matches_newton():
    var = assembly_errors()
    var = dict(var, s=np.array([0.05, -0.02, 0.01]), r=np.array([0.01, 0.0, -0.02]), psi=np.array([0, 1e-3, 0]))
    poses = np.array([[0, 0, 0], [20, -10, 0], [-5, 5, np.radians(30)]])
    lib = nonlinear.displaced_pose_error(AALBORG, poses, variations=var)
    for n, pose in enumerate(poses):
        np.testing.assert_allclose(lib[n], own_exact_error(AALBORG, pose, variations=var), rtol=0, atol=1e-10)
    with pytest.raises(ValueError):
        nonlinear.displaced_pose_error(AALBORG, poses, variations={"rho": np.ones(3)})


def second_order_ratios(robot, poses, disp, f=1.0):
    """|nonlinear - first order| at scale f over the same at f/2, per pose (weighted norm)."""
    out = []
    for scale in (f, f / 2):
        d = disp.scaled(scale)
        exact = nonlinear.displaced_pose_error(robot, poses, d)
        lin = bounds.first_order_pose_error(robot, poses, d)
        ref = np.array([own_first_order(robot, pose, disp_at(d, n)) for n, pose in enumerate(poses)])
        np.testing.assert_allclose(lin, ref, rtol=1e-9, atol=1e-16)
        out.append(np.linalg.norm((exact - lin) * WEIGHT, axis=-1))
    assert np.all(out[1] > 1e-11), "second-order term too small to measure"
    return out[0] / out[1]


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_worst_case_displacements_second_order(case):
    """Nonlinear vs first order at the worst configurations of Eq. 21-22: quadratic convergence."""
    _, robot, poses, clear = case
    b = bounds.max_pose_errors(robot, clear, poses, details=True, allow_outside=True)
    for q in ("dx", "dy", "dphi", "dp"):
        ratios = second_order_ratios(robot, poses, b.worst[q])
        assert np.all((ratios > 3.8) & (ratios < 4.2)), f"{q}: ratios {ratios}"
        # and the nonlinear error of the worst configuration is close to the first-order maximum
        exact = nonlinear.displaced_pose_error(robot, poses, b.worst[q])
        got = np.hypot(exact[:, 0], exact[:, 1]) if q == "dp" else exact[:, "dx dy dphi".split().index(q)]
        target = getattr(b, f"{q}_max")
        np.testing.assert_allclose(got, target, rtol=0.02)


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_random_admissible_displacements_second_order(case):
    _, robot, poses, clear = case
    rng = np.random.default_rng(21)
    for _ in range(3):
        disp = admissible(rng, clear, (len(poses),))
        ratios = second_order_ratios(robot, poses, disp)
        assert np.all((ratios > 3.8) & (ratios < 4.2)), f"ratios {ratios}"


def test_nonlinear_errors_stay_within_first_order_bounds_up_to_second_order():
    """Random admissible displacements never exceed the exact first-order bounds by more than a 2nd-order margin."""
    rng = np.random.default_rng(8)
    clear = ClearanceSet.load("all")
    poses = np.column_stack([rng.uniform(-25, 25, (40, 2)), np.zeros(40)])
    b = bounds.max_pose_errors(AALBORG, clear, poses)
    disp = admissible(rng, clear, (40,))
    err = nonlinear.displaced_pose_error(AALBORG, poses, disp)
    margin = 1e-3  # relative; second-order terms are ~eps_theta = 1.2e-3 of the first-order ones at most
    assert np.all(np.abs(err[:, 0]) <= b.dx_max * (1 + margin))
    assert np.all(np.abs(err[:, 1]) <= b.dy_max * (1 + margin))
    assert np.all(np.abs(err[:, 2]) <= b.dphi_max * (1 + margin))
    assert np.all(np.hypot(err[:, 0], err[:, 1]) <= b.dp_max * (1 + margin))
