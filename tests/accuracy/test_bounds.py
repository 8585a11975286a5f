"""Independent checks of the exact worst-case pose errors (paper Sec. 4.3, Eq. 16-22).

Reference computations written in this file and in ``reference_model`` (nothing
is taken from the library's internals; only ``ClearanceSet``/``ClearanceDisplacement``
are used as containers):

* ``FirstOrder``: the first-order map from the clearance variables of Eq. 20b
  (plus the revolute directions varphi_i) to ``[dx, dy, dphi]``, built from Eq. 8
  and Appendix A as the paper states them: ``A [dp; dphi] = e`` with rows
  ``A_i = [w_i^T E^T, -r_i w_i^T k_i]`` (Eq. 4a) and
  ``e_i = l_i dtau_b + (w^T E^T E u) dsigma_g + (d w^T v + l) dtau_g + (w^T E^T n) drho`` (the guide's
  lateral shift acts normal to the rail, issue 9; the paper's ``delta d`` along ``v`` is the same for
  gamma = +-90 deg)
  (H_theta, H_d, H_gamma, H_rho of A-1). ``l_i`` comes from a 2x2 solve of Eq. 1
  (``reference_model.own_ik``). It is itself validated against finite differences
  of the independent Newton loop-closure solver ``reference_model.solve_loop_closure``
  (``test_reference_first_order_map``).
* ``brute_force``: maximization by enumeration. The feasible set of each leg
  is the product of the bearing segment (2 vertices, Eq. 17), the guide rhombus
  (4 vertices, computed here by intersecting the lines of Eq. 16a/16b) and the
  revolute disk (0 <= drho <= eps_r, any varphi: boundary sampled at 720 angles
  and refined with ``minimize_scalar``). ``dx, dy, dphi`` (Eq. 21): every one of
  the 8^3 = 512 vertex combinations of the three legs, each combined with the
  extreme disk contributions. ``dp`` (Eq. 22): ``max_u h(u)`` of the support
  function ``h`` of the feasible error set over 2048 planar directions, the best
  directions refined with ``minimize_scalar``.
* Paper acceptance figures (Sec. 6.1, reference file): case 1, phi = 0.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize_scalar

from pmaccuracy.accuracy import bounds
from pmaccuracy.model.clearances import ClearanceDisplacement, ClearanceSet
from pmaccuracy.errors import ClearanceError, OutsideJointLimitsError, SingularPoseError
from pmaccuracy.model.manipulator import Manipulator
from reference_model import (directions, displace, leg_params, own_A, own_ik, random_poses, random_robot, rot90,
                             solve_loop_closure, vec)

AALBORG = Manipulator.preset("aalborg_3ppr")


# ------------------------------------------------------------------------------------ first-order reference map
class FirstOrder:
    """First-order clearance -> pose-error map at one pose, from Eq. 4a, 8 and Appendix A."""

    def __init__(self, robot, pose):
        p = leg_params(robot)
        _, u, v, w = directions(p)
        self.s, self.l = own_ik(p, pose)
        self.Ew = rot90(w)
        self.A = own_A(p, pose)
        self.A_inv = np.linalg.inv(self.A)
        self.H_theta = self.l
        self.H_d = np.sum(self.Ew * rot90(u), axis=1)   # guide shift normal to the rail: (E w) . (E u)
        self.H_gamma = p["d"] * np.sum(w * v, axis=1) + self.l

    def H_rho(self, i, varphi):
        return self.Ew[i, 0] * np.cos(varphi) + self.Ew[i, 1] * np.sin(varphi)

    def leg_scalar(self, i, tau_b, sigma_g, tau_g, rho, varphi):
        """Right-hand side e_i of A [dp; dphi] = e (Eq. 8) for leg i."""
        return (self.H_theta[i] * tau_b + self.H_d[i] * sigma_g + self.H_gamma[i] * tau_g
                + self.H_rho(i, varphi) * rho)

    def pose_error(self, disp: ClearanceDisplacement, index=()):
        e = np.array([self.leg_scalar(i, *(np.asarray(getattr(disp, f))[index + (i,)]
                                           for f in ("tau_b", "sigma_g", "tau_g", "rho", "varphi")))
                      for i in range(3)])
        return self.A_inv @ e


def rhombus_vertices(eps_g, L):
    """Vertices (sigma, tau) of Eq. 16: intersections of L tau + 2 sigma = +-2 eps and -L tau + 2 sigma = +-2 eps."""
    out = []
    for b1, b2 in itertools.product((-2 * eps_g, 2 * eps_g), repeat=2):
        sigma, tau = np.linalg.solve(np.array([[2.0, L], [2.0, -L]]), np.array([b1, b2]))
        out.append((sigma, tau))
    return out


def polytope_values(fo, clear, i):
    """e_i over the vertices of leg i's bearing segment x guide rhombus (2 x 4 = 8 values)."""
    eb = clear.bearing_angle[i]
    return np.array([fo.leg_scalar(i, tb, sg, tg, 0.0, 0.0)
                     for tb in (-eb, eb) for sg, tg in rhombus_vertices(clear.guide_lateral[i],
                                                                        clear.guide_block_length[i])])


PHI_SAMPLES = np.linspace(0, 2 * np.pi, 720, endpoint=False)


def maximize_over_circle(f):
    """max over varphi of f(varphi): 720 samples, then bounded Brent around the best."""
    vals = f(PHI_SAMPLES)
    j = int(np.argmax(vals))
    step = PHI_SAMPLES[1]
    res = minimize_scalar(lambda t: -f(t), bounds=(PHI_SAMPLES[j] - step, PHI_SAMPLES[j] + step),
                          method="bounded", options={"xatol": 1e-12})
    return max(float(vals[j]), float(-res.fun))


def disk_extremes(fo, clear, i, g):
    """(min, max) of g . (A^-1 column i) e_i over leg i's revolute disk (rho in {0, eps_r} and every varphi)."""
    er = clear.revolute_radial[i]
    if er == 0:
        return 0.0, 0.0
    gi = float(np.dot(g, fo.A_inv[:len(g), i]))
    f = lambda t: gi * er * fo.H_rho(i, t)  # noqa: E731
    return min(0.0, -maximize_over_circle(lambda t: -f(t))), max(0.0, maximize_over_circle(f))


def brute_force(robot, clear, pose):
    """[dx_max, dy_max, dphi_max, dp_max] by enumeration (see the module docstring)."""
    fo = FirstOrder(robot, pose)
    poly = [polytope_values(fo, clear, i) for i in range(3)]
    combos = np.array(list(itertools.product(*poly)))  # (512, 3) values of e from the polytopes
    out = []
    for row in range(3):
        g = np.eye(3)[row]
        lin = combos @ fo.A_inv[row]  # the 512 vertex combinations
        lo = sum(disk_extremes(fo, clear, i, g)[0] for i in range(3))
        hi = sum(disk_extremes(fo, clear, i, g)[1] for i in range(3))
        out.append(max(np.max(np.abs(lin + hi)), np.max(np.abs(lin + lo))))
    points = combos @ fo.A_inv[:2].T  # (512, 2): planar errors of the vertex combinations

    def support(angle):
        u = vec(angle)
        return float(np.max(points @ u)) + sum(disk_extremes(fo, clear, i, u)[1] for i in range(3))

    # coarse: all directions at once (disks sampled), then refine the best local maxima exactly
    angles = np.linspace(0, 2 * np.pi, 2048, endpoint=False)
    U = vec(angles)
    coarse = np.max(points @ U.T, axis=0)
    for i in range(3):
        er = clear.revolute_radial[i]
        if er:
            gi = U @ fo.A_inv[:2, i]
            coarse = coarse + np.maximum(0, np.max(gi[:, None] * er * fo.H_rho(i, PHI_SAMPLES)[None], axis=1))
    is_peak = (coarse >= np.roll(coarse, 1)) & (coarse >= np.roll(coarse, -1))
    candidates = np.argsort(np.where(is_peak, coarse, -np.inf))[::-1][:6]
    step = angles[1]
    best = float(np.max(coarse))
    for j in candidates:
        res = minimize_scalar(lambda t: -support(t), bounds=(angles[j] - 2 * step, angles[j] + 2 * step),
                              method="bounded", options={"xatol": 1e-11})
        best = max(best, -float(res.fun))
    out.append(best)
    return np.array(out)


def random_clearances(rng):
    """Random bounds of every kind; each source of each leg is present with probability 0.75."""
    on = lambda: rng.random(3) < 0.75  # noqa: E731
    return ClearanceSet(bearing_angle=on() * rng.uniform(2e-4, 3e-3, 3),
                        guide_lateral=on() * rng.uniform(1e-3, 3e-2, 3),
                        guide_block_length=rng.uniform(5, 300, 3),
                        revolute_radial=on() * rng.uniform(5e-3, 5e-2, 3))


def brute_cases():
    rng = np.random.default_rng(2012)
    out = []
    for k in range(6):
        robot = random_robot(rng)
        out.append((f"random{k}", robot, random_poses(robot, rng, 3), random_clearances(rng)))
    full = ClearanceSet(bearing_angle=[1e-3, 2e-3, 1.5e-3], guide_lateral=[0.01, 0.02, 0.005],
                        guide_block_length=[50, 8, 120], revolute_radial=[0.02, 0.04, 0.03])
    robot = random_robot(rng)
    out.append(("random-all-sources", robot, random_poses(robot, rng, 3), full))
    aal = np.array([[0, 0, 0], [12, -20, 0], [-20, 7, 0], [15, -5, np.radians(30)]], float)
    for name in ("case1", "case2", "all"):
        out.append((f"aalborg-{name}", AALBORG, aal, ClearanceSet.load(name)))
    return out


BRUTE = brute_cases()


def assert_rel(actual, expected, rtol, what=""):
    actual, expected = np.asarray(actual, float), np.asarray(expected, float)
    err = np.max(np.abs(actual - expected) / np.maximum(np.abs(expected), 1e-300))
    assert err <= rtol, f"{what}: {actual} vs {expected} (relative error {err:.3g})"


# ------------------------------------------------------------------------------------ (a) paper acceptance
@pytest.fixture(scope="module")
def case1_grid():
    xs = np.linspace(-25, 25, 11)
    ys = np.linspace(-25, 25, 11)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    poses = np.stack([X, Y, np.zeros_like(X)], axis=-1)
    return xs, ys, bounds.max_pose_errors(AALBORG, ClearanceSet.load("case1"), poses)


def test_paper_dx_range_case1_phi0(case1_grid):
    """Sec. 6.1: dx_max between 0.196 and 0.256 mm (within 1 %)."""
    _, _, b = case1_grid
    assert b.dx_max.shape == (11, 11)
    assert abs(b.dx_max.min() / 0.196 - 1) < 0.01, b.dx_max.min()
    assert abs(b.dx_max.max() / 0.256 - 1) < 0.01, b.dx_max.max()


def test_paper_dx_constant_along_x_decreasing_with_y(case1_grid):
    _, _, b = case1_grid
    np.testing.assert_allclose(b.dx_max, np.broadcast_to(b.dx_max[:1], b.dx_max.shape), rtol=1e-9)
    assert np.all(np.diff(b.dx_max, axis=1) < 0), "dx_max must decrease with y"


def test_paper_dy_dphi_constant_case1_phi0(case1_grid):
    """Sec. 6.1: dy_max = 0.100 mm and dphi_max = 0.221 deg, constant over the workspace."""
    _, _, b = case1_grid
    assert abs(b.dy_max.mean() / 0.100 - 1) < 0.01, b.dy_max.mean()
    assert abs(np.degrees(b.dphi_max).mean() / 0.221 - 1) < 0.01, np.degrees(b.dphi_max).mean()
    np.testing.assert_allclose(b.dphi_max_deg, np.degrees(b.dphi_max), rtol=1e-15)
    assert np.ptp(b.dy_max) < 1e-9 * b.dy_max.mean()
    assert np.ptp(b.dphi_max) < 1e-9 * b.dphi_max.mean()


def test_dy_dphi_depend_on_legs_1_2_only():
    """Sec. 6.1: y and phi depend only on legs 1, 2 (partial decoupling): leg 3's clearance does not change them."""
    poses = np.array([[0, 0, 0], [10, -20, 0], [-25, 25, 0]], float)
    full = bounds.max_pose_errors(AALBORG, ClearanceSet.load("case1"), poses)
    no3 = bounds.max_pose_errors(AALBORG, ClearanceSet(bearing_angle=[0.0012, 0.0012, 0.0]), poses)
    np.testing.assert_allclose(no3.dy_max, full.dy_max, rtol=1e-12)
    np.testing.assert_allclose(no3.dphi_max, full.dphi_max, rtol=1e-12)
    assert np.all(no3.dx_max < full.dx_max)


def test_dp_max_mirror_symmetric_in_x(case1_grid):
    """dp_max(x, y) = dp_max(-x, y): the symmetry visible in the phi = 0 maps (mirror through the y-axis)."""
    _, _, b = case1_grid
    np.testing.assert_allclose(b.dp_max, b.dp_max[::-1, :], rtol=1e-12)


@pytest.mark.xfail(strict=True, reason=(
    "Paper Sec. 6.1 says dp_max is 'symmetrical with respect to the x-axis'. Read literally "
    "(dp_max(x, y) = dp_max(x, -y)) this contradicts the paper's own figures: dx_max decreases from "
    "0.256 mm (y = -25) to 0.196 mm (y = 25), so dp_max(x, -25) >= 0.25 while dp_max(x, 25) <= "
    "hypot(0.196, 0.100) = 0.22. The reconstructed geometry shows the mirror symmetry x -> -x instead."))
def test_dp_max_symmetric_about_x_axis_literal(case1_grid):
    _, _, b = case1_grid
    np.testing.assert_allclose(b.dp_max, b.dp_max[:, ::-1], rtol=1e-6)


def test_literal_x_axis_symmetry_excluded_by_paper_numbers(case1_grid):
    """Document the contradiction above with the library's own numbers (bounds valid for any convex set)."""
    _, _, b = case1_grid
    assert np.all(b.dp_max >= b.dx_max - 1e-15) and np.all(b.dp_max >= b.dy_max - 1e-15)
    assert np.all(b.dp_max <= np.hypot(b.dx_max, b.dy_max) + 1e-15)
    assert np.all(b.dp_max[:, 0] > b.dp_max[:, -1] + 0.02)


# ------------------------------------------------------------------------------------ (b) brute force
def test_reference_first_order_map():
    """The reference map of this file against FD of an exact (Newton) loop closure with clearance displacements."""
    rng = np.random.default_rng(99)
    robot = random_robot(rng)
    pose = random_poses(robot, rng, 1)[0]
    p = leg_params(robot)
    fo = FirstOrder(robot, pose)
    disp = dict(tau_b=rng.normal(0, 1, 3), sigma_g=rng.normal(0, 1, 3), tau_g=rng.normal(0, 1, 3),
                rho=rng.uniform(0, 1, 3), varphi=rng.uniform(-np.pi, np.pi, 3))

    def exact(t):
        q, offsets = displace(p, {f: (x if f == "varphi" else t * x) for f, x in disp.items()})
        return solve_loop_closure(q, fo.s, pose, offsets, l0=fo.l, tol=0.0, max_iter=50)

    fd = (exact(1e-6) - exact(-1e-6)) / 2e-6
    lin = fo.pose_error(ClearanceDisplacement(**disp))
    np.testing.assert_allclose(lin, fd, rtol=1e-6, atol=1e-6 * np.max(np.abs(fd)))


@pytest.mark.parametrize("case", BRUTE, ids=[c[0] for c in BRUTE])
def test_exact_bounds_match_brute_force(case):
    """max_pose_errors = exhaustive maximization of Eq. 21-22 (relative 1e-6)."""
    _, robot, poses, clear = case
    b = bounds.max_pose_errors(robot, clear, poses)
    assert b.method == "exact"
    for n, pose in enumerate(poses):
        ref = brute_force(robot, clear, pose)
        got = np.array([b.dx_max[n], b.dy_max[n], b.dphi_max[n], b.dp_max[n]])
        assert_rel(got, ref, 1e-6, f"pose {pose} clearances {clear.to_dict()}")


def test_brute_force_exercises_both_rhombus_vertices():
    """Sanity of the test data: the guide's best vertex is a pure shift at some legs and a pure tilt at others."""
    kinds = set()
    for _, robot, poses, clear in BRUTE:
        for pose in poses:
            fo = FirstOrder(robot, pose)
            for i in range(3):
                if clear.guide_lateral[i] > 0:
                    shift = clear.guide_lateral[i] * abs(fo.H_d[i])
                    tilt = 2 * clear.guide_lateral[i] * abs(fo.H_gamma[i]) / clear.guide_block_length[i]
                    kinds.add("shift" if shift > tilt else "tilt")
    assert kinds == {"shift", "tilt"}


# ------------------------------------------------------------------------------------ (c) details
def constraint_violation(disp, clear, index):
    """Largest violation of Eq. 16-18 (relative to the bounds); <= ~1e-12 when admissible."""
    tb, sg, tg, rho = (np.asarray(getattr(disp, f))[index] for f in ("tau_b", "sigma_g", "tau_g", "rho"))
    eb, eg, er, L = clear.bearing_angle, clear.guide_lateral, clear.revolute_radial, clear.guide_block_length
    tiny = 1e-300
    v = [np.abs(tb) - eb * (1 + 1e-12) - tiny,
         np.abs(L * tg + 2 * sg) - 2 * eg * (1 + 1e-12) - tiny,
         np.abs(-L * tg + 2 * sg) - 2 * eg * (1 + 1e-12) - tiny,
         -rho - tiny,
         rho - er * (1 + 1e-12) - tiny]
    return max(float(np.max(x)) for x in v)


@pytest.mark.parametrize("case", BRUTE, ids=[c[0] for c in BRUTE])
def test_worst_configurations_are_admissible_and_attain_the_maxima(case):
    _, robot, poses, clear = case
    b = bounds.max_pose_errors(robot, clear, poses, details=True)
    assert set(b.worst) == {"dx", "dy", "dphi", "dp"}
    for n, pose in enumerate(poses):
        fo = FirstOrder(robot, pose)
        for q, row, target in (("dx", 0, b.dx_max), ("dy", 1, b.dy_max), ("dphi", 2, b.dphi_max)):
            disp = b.worst[q]
            assert np.asarray(disp.tau_b).shape == poses.shape
            assert constraint_violation(disp, clear, n) <= 0, f"{q} configuration violates Eq. 16-18"
            err = fo.pose_error(disp, (n,))
            # documented: the configuration moves the platform by +dzeta_max
            assert_rel(err[row], target[n], 1e-9, f"{q} at pose {pose}")
        disp = b.worst["dp"]
        assert constraint_violation(disp, clear, n) <= 0, "dp configuration violates Eq. 16-18"
        err = fo.pose_error(disp, (n,))
        assert_rel(np.hypot(err[0], err[1]), b.dp_max[n], 1e-9, f"dp at pose {pose}")
        # the library's own first-order evaluation of its configuration agrees with the reference map
        lib = bounds.first_order_pose_error(robot, pose[None], ClearanceDisplacement(
            *(np.asarray(getattr(disp, f))[n][None] for f in ("tau_b", "sigma_g", "tau_g", "rho", "varphi"))))
        np.testing.assert_allclose(lib[0], err, rtol=1e-9, atol=1e-15)


def test_first_order_pose_error_matches_reference_for_random_displacements():
    rng = np.random.default_rng(5)
    for _, robot, poses, _ in BRUTE[:4]:
        disp = ClearanceDisplacement(*(rng.normal(0, 1e-3, poses.shape) for _ in range(4)),
                                     rng.uniform(-np.pi, np.pi, poses.shape))
        lib = bounds.first_order_pose_error(robot, poses, disp)
        for n, pose in enumerate(poses):
            np.testing.assert_allclose(lib[n], FirstOrder(robot, pose).pose_error(disp, (n,)), rtol=1e-9,
                                       atol=1e-15)


# ------------------------------------------------------------------------------------ (d) SLSQP baseline
@pytest.mark.parametrize("case", [BRUTE[0], BRUTE[6], BRUTE[8], BRUTE[9]], ids=lambda c: c[0])
def test_slsqp_never_above_exact(case):
    _, robot, poses, clear = case
    exact = bounds.max_pose_errors(robot, clear, poses)
    local = bounds.slsqp_max_pose_errors(robot, clear, poses, n_starts=3)
    assert local.method == "slsqp"
    for k in ("dx_max", "dy_max", "dphi_max", "dp_max"):
        assert np.all(getattr(local, k) <= getattr(exact, k) * (1 + 1e-9)), k
        assert np.all(getattr(local, k) > 0), k


def test_slsqp_reaches_exact_on_a_few_poses():
    poses = np.array([[0, 0, 0], [10, -20, 0], [-15, 5, 0.3]], float)
    clear = ClearanceSet.load("case1")
    exact = bounds.max_pose_errors(AALBORG, clear, poses)
    local = bounds.slsqp_max_pose_errors(AALBORG, clear, poses)
    for k in ("dx_max", "dy_max", "dphi_max", "dp_max"):
        assert_rel(getattr(local, k), getattr(exact, k), 1e-6, k)


# ------------------------------------------------------------------------------------ (e) errors and shapes
def test_singular_pose_raises():
    with pytest.raises(SingularPoseError):
        bounds.max_pose_errors(AALBORG, ClearanceSet.load("case1"), [0.0, 0.0, np.pi / 2])
    with pytest.raises(SingularPoseError):
        bounds.max_pose_errors(AALBORG, ClearanceSet.load("case1"), [[0, 0, 0], [0.0, 0.0, -np.pi / 2]])
    with pytest.raises(SingularPoseError):
        bounds.slsqp_max_pose_errors(AALBORG, ClearanceSet.load("case1"), [0.0, 0.0, np.pi / 2])


def test_outside_joint_limits_raises_unless_allowed():
    clear = ClearanceSet.load("case1")
    pose = np.array([100.0, 0.0, 0.0])  # s_3 = 100 mm, far outside [-25, 25]
    with pytest.raises(OutsideJointLimitsError, match="x=100"):
        bounds.max_pose_errors(AALBORG, clear, pose)
    with pytest.raises(OutsideJointLimitsError):
        bounds.max_pose_errors(AALBORG, clear, [[0, 0, 0], [0, 60.0, 0]])
    b = bounds.max_pose_errors(AALBORG, clear, pose, allow_outside=True)
    assert np.isfinite(b.dx_max) and b.dx_max > 0
    assert_rel(b.dp_max, brute_force(AALBORG, clear, pose)[3], 1e-6, "outside pose")


@pytest.mark.parametrize("kwargs", [dict(bearing_angle=-1e-3), dict(guide_lateral=[0, -1e-3, 0]),
                                    dict(revolute_radial=[0.01, 0.02, -0.01]), dict(bearing_angle=np.nan),
                                    dict(revolute_radial=[0, np.inf, 0]), dict(guide_lateral=-np.inf),
                                    dict(guide_block_length=0.0), dict(guide_block_length=[50, 50, -5])])
def test_bad_clearances_raise(kwargs):
    with pytest.raises(ClearanceError):
        ClearanceSet(**kwargs)


def test_batch_shapes():
    rng = np.random.default_rng(1)
    poses = np.zeros((4, 5, 3))
    poses[..., :2] = rng.uniform(-25, 25, (4, 5, 2))
    clear = ClearanceSet.load("all")
    b = bounds.max_pose_errors(AALBORG, clear, poses, details=True)
    for k in ("dx_max", "dy_max", "dphi_max", "dp_max", "dphi_max_deg"):
        assert getattr(b, k).shape == (4, 5), k
    assert b.poses.shape == (4, 5, 3)
    for q in ("dx", "dy", "dphi", "dp"):
        for f in ("tau_b", "sigma_g", "tau_g", "rho", "varphi"):
            assert np.asarray(getattr(b.worst[q], f)).shape == (4, 5, 3)
    flat = bounds.max_pose_errors(AALBORG, clear, poses.reshape(-1, 3))
    np.testing.assert_array_equal(b.dp_max.reshape(-1), flat.dp_max)
    single = bounds.max_pose_errors(AALBORG, clear, poses[2, 3])
    assert np.shape(single.dx_max) == ()
    assert float(single.dx_max) == pytest.approx(b.dx_max[2, 3], rel=1e-14)
    recs = b.records()
    assert len(recs) == 20 and recs[7]["dp_max"] == pytest.approx(b.dp_max.reshape(-1)[7], rel=1e-15)


def test_large_batch_consistent_across_internal_blocks():
    """More poses than one internal block: every pose equals its single evaluation, worst cases too."""
    rng = np.random.default_rng(4)
    n = 9000
    poses = np.column_stack([rng.uniform(-25, 25, n), rng.uniform(-25, 25, n), np.zeros(n)])
    clear = ClearanceSet.load("all")
    b = bounds.max_pose_errors(AALBORG, clear, poses, details=True)
    assert b.dx_max.shape == (n,)
    for j in (0, 8191, 8192, 8999):
        one = bounds.max_pose_errors(AALBORG, clear, poses[j:j + 1], details=True)
        assert b.dp_max[j] == pytest.approx(one.dp_max[0], rel=1e-14)
        assert b.dx_max[j] == pytest.approx(one.dx_max[0], rel=1e-14)
        np.testing.assert_allclose(b.worst["dp"].tau_b[j], one.worst["dp"].tau_b[0], rtol=1e-14)
        fo = FirstOrder(AALBORG, poses[j])
        assert_rel(np.hypot(*fo.pose_error(b.worst["dp"], (j,))[:2]), b.dp_max[j], 1e-9, f"pose {j}")


# ------------------------------------------------------------------------------------ (f) scaling, dominance
@settings(max_examples=15, deadline=None)
@given(factor=st.floats(0.05, 20.0), seed=st.integers(0, 10_000))
def test_bounds_are_linear_in_the_clearances(factor, seed):
    """Scaling every clearance bound by f scales every bound by f (the feasible set scales, Eq. 16-18)."""
    rng = np.random.default_rng(seed)
    clear = random_clearances(rng)
    poses = np.column_stack([rng.uniform(-25, 25, (5, 2)), rng.uniform(-0.3, 0.3, 5)])
    poses[:, :2] *= 0.4  # stay inside the rotated workspaces
    base = bounds.max_pose_errors(AALBORG, clear, poses, allow_outside=True)
    scaled = ClearanceSet(clear.bearing_angle * factor, clear.guide_lateral * factor, clear.guide_block_length,
                          clear.revolute_radial * factor)
    b2 = bounds.max_pose_errors(AALBORG, scaled, poses, allow_outside=True)
    for k in ("dx_max", "dy_max", "dphi_max", "dp_max"):
        np.testing.assert_allclose(getattr(b2, k), factor * getattr(base, k), rtol=1e-12, atol=1e-300)


def test_doubling_clearances_doubles_bounds_on_presets():
    poses = np.array([[0, 0, 0], [20, -20, 0], [-10, 5, np.radians(30)]], float)
    for name in ("case1", "case2", "all"):
        c = ClearanceSet.load(name)
        b1 = bounds.max_pose_errors(AALBORG, c, poses)
        b2 = bounds.max_pose_errors(AALBORG, c.scaled(2.0), poses)
        for k in ("dx_max", "dy_max", "dphi_max", "dp_max"):
            np.testing.assert_allclose(getattr(b2, k), 2 * getattr(b1, k), rtol=1e-12)


def test_more_clearances_dominate_pointwise():
    """case2 adds revolute clearances to case1, all adds the guides: bounds can only grow (monotone sets)."""
    xs = np.linspace(-25, 25, 9)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    grid0 = np.stack([X, Y, 0 * X], -1)
    grid30 = np.stack([0.5 * X + 15, 0.45 * Y - 2, np.full_like(X, np.radians(30))], -1)
    for grid in (grid0, grid30):
        res = {n: bounds.max_pose_errors(AALBORG, ClearanceSet.load(n), grid) for n in ("case1", "case2", "all")}
        for k in ("dx_max", "dy_max", "dphi_max", "dp_max"):
            assert np.all(getattr(res["case2"], k) > getattr(res["case1"], k)), k
            assert np.all(getattr(res["all"], k) >= getattr(res["case2"], k)), k


def test_zero_clearances_give_zero_bounds():
    b = bounds.max_pose_errors(AALBORG, ClearanceSet(), np.array([[0, 0, 0], [5, 5, 0.2]]), details=True)
    for k in ("dx_max", "dy_max", "dphi_max", "dp_max"):
        np.testing.assert_array_equal(getattr(b, k), 0.0)
