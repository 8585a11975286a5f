"""Self-checks of the independent spatial reference (``spatial_reference``): closed-form cases only.

These tests check the reference against itself and against geometry that can be written down; they do not
touch the library (the comparison with ``pmaccuracy`` lives elsewhere)."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import spatial_reference as S

ARCHS = S.ARCHITECTURES


def _pose_home(robot):
    p, R = S.home(robot)
    if robot["architecture"] in ("3-RPS", "3-PRS"):
        p, R = S.complete_pose(robot, p[2], 0.0, 0.0)
    return p, R


def _exact_hexapod():
    """Semi-regular hexapod with exact (unrounded) joint points."""
    lg = []
    for k in range(3):
        for sgn in (-1, 1):
            ab, ap = math.radians(120 * k + sgn * 15), math.radians(120 * k + sgn * 45)
            lg.append({"base": [250 * math.cos(ab), 250 * math.sin(ab), 0.0],
                       "platform": [150 * math.cos(ap), 150 * math.sin(ap), 0.0], "stroke": [270.0, 420.0]})
    return {"architecture": "6-UPS", "legs": lg, "home": {"position": [0, 0, 300.0]}}


# --- rotations -------------------------------------------------------------------------------------------


def test_rotation_is_extrinsic_xyz_as_scipy():
    rng = np.random.default_rng(0)
    for _ in range(20):
        a = rng.uniform(-170, 170, 3)
        a[1] = rng.uniform(-85, 85)  # the Euler angles are unique with |pitch| < 90 deg
        R = S.rotation(a)
        assert np.allclose(R, Rotation.from_euler("xyz", a, degrees=True).as_matrix(), atol=1e-14)
        assert np.allclose(S.orientation_deg(R), a, atol=1e-10)
        w = rng.normal(size=3)
        assert np.allclose(S.expm_so3(w), Rotation.from_rotvec(w).as_matrix(), atol=1e-14)
        assert np.allclose(S.rotvec(S.expm_so3(w * 0.5)), w * 0.5, atol=1e-12)
    # roll first about base x, then pitch about base y: Rz Ry Rx
    assert np.allclose(S.rotation([30, 0, 0]) @ [0, 1, 0], [0, math.cos(math.pi / 6), math.sin(math.pi / 6)])


# --- legs and defaults -----------------------------------------------------------------------------------


def test_defaults_and_normalization():
    r = {"architecture": "3-RPS", "legs": [{"base": [0, 0, 0], "axis": [0, 2, 0], "platform": [1, 0, 0],
                                           "stroke": [1, 2]}] * 3}
    L = S.legs(r)
    assert np.allclose(L[0]["axis"], [0, 1, 0])
    assert np.allclose(L[0]["base_normal"], [0, 0, 1]) and np.allclose(L[0]["platform_normal"], [0, 0, -1])
    assert L[0]["base_cone_deg"] is None and L[0]["platform_cone_deg"] is None and L[0]["radius"] == 0.0
    d = S.load_reference("delta")
    for lg in d["legs"]:
        lg.pop("platform_normal", None)
    assert np.allclose(S.legs(d)[0]["platform_normal"], [0, 0, 1])
    assert S.legs(d)[0]["base_cone_deg"] is None


def test_3upu_requires_parallel_axes():
    r = S.load_reference("3-UPU")
    r["legs"][1]["platform_axis"] = [0.0, 0.1, 1.0]
    with pytest.raises(ValueError):
        S.legs(r)
    r = S.load_reference("3-UPU")
    r["legs"][1]["platform_axis"] = [-x for x in r["legs"][1]["base_axis"]]  # antiparallel: the same line
    S.legs(r)


def test_zero_direction_refused():
    r = S.load_reference("3-RPS")
    r["legs"][0]["axis"] = [0, 0, 0]
    with pytest.raises(ValueError):
        S.legs(r)


@pytest.mark.parametrize("arch", ARCHS)
def test_reference_home_within_limits(arch):
    r = S.load_reference(arch)
    p, R = _pose_home(r)
    assert S.limit_report(r, p, R) == []
    assert S.parallel_singularity_measure(r, p, R) > 0.15


# --- inverse kinematics, closed forms --------------------------------------------------------------------


def test_hexapod_symmetric_pose_equal_lengths():
    r = _exact_hexapod()
    for z in (300.0, 350.0, 280.0):
        q = S.actuators(r, [0, 0, z], np.eye(3))
        assert np.ptp(q) < 1e-10
    for z, yaw in ((350.0, 20.0), (280.0, -35.0)):  # a yaw keeps the 3-fold symmetry only: two lengths
        q = S.actuators(r, [0, 0, z], S.rotation([0, 0, yaw]))
        assert np.ptp(q[0::2]) < 1e-10 and np.ptp(q[1::2]) < 1e-10 and np.ptp(q) > 1.0
    # closed form at yaw 0: base (250, 15 deg) to platform (150, 45 deg) at height z
    z = 300.0
    a = np.array([250 * math.cos(math.radians(15)), 250 * math.sin(math.radians(15)), 0])
    b = np.array([150 * math.cos(math.radians(45)), 150 * math.sin(math.radians(45)), z])
    assert S.actuators(r, [0, 0, z], np.eye(3))[1] == pytest.approx(np.linalg.norm(b - a), abs=1e-12)
    # the rounded file: equal to 1e-3 mm
    f = S.load_reference("6-UPS")
    assert np.ptp(S.actuators(f, [0, 0, 300.0], np.eye(3))) < 1e-3


def test_3prs_slide_formula_and_mode():
    r = S.load_reference("3-PRS")
    for seed in range(5):
        p, R = S.random_pose(r, seed)
        q = S.actuators(r, p, R)
        for k, lg in enumerate(S.legs(r)):
            B = p + R @ lg["platform"]
            C = lg["base"] + q[k] * lg["slide"]
            assert np.linalg.norm(B - C) == pytest.approx(lg["rod"], abs=1e-10)
            assert np.sign(lg["slide"] @ (B - C)) == lg["mode"]
    # symmetric closed form: q = z + sqrt(rod^2 - (200 - 100)^2) * (-mode) ... with mode +1: z - sqrt(...)
    assert S.actuators(r, [0, 0, 400.0], np.eye(3))[0] == pytest.approx(400 - math.sqrt(250**2 - 100**2), abs=1e-9)
    # flipping the mode gives the other root
    r2 = copy.deepcopy(r)
    for lg in r2["legs"]:
        lg["mode"] = -1
    assert S.actuators(r2, [0, 0, 400.0], np.eye(3))[0] == pytest.approx(400 + math.sqrt(250**2 - 100**2), abs=1e-9)
    # out of reach
    assert np.isnan(S.actuators(r, [400.0, 0, 400.0], np.eye(3))[0])


def test_delta_home_elbow_rod_geometry():
    r = S.load_reference("delta")
    p, R = S.home(r)
    th = S.actuators(r, p, R)
    for k, lg in enumerate(S.legs(r)):
        A = lg["base"]
        C = A + lg["arm"] * (math.cos(th[k]) * lg["zero"] + math.sin(th[k]) * np.cross(lg["axis"], lg["zero"]))
        B = p + R @ lg["platform"]
        h = 0.5 * lg["spacing"] * lg["axis"]
        assert np.linalg.norm(B - C) == pytest.approx(lg["rod"], abs=1e-9)
        assert np.linalg.norm((B + h) - (C + h)) == pytest.approx(lg["rod"], abs=1e-9)
        assert np.sign(np.cross(C - A, B - A) @ lg["axis"]) == lg["mode"]
    # in-plane closed form of the symmetric Delta: (-140 - 350 c)^2 + (-800 + 350 s)^2 = 800^2, s > 0 (arm down)
    f = lambda t: (-140 - 350 * math.cos(t)) ** 2 + (-800 + 350 * math.sin(t)) ** 2 - 800**2
    from scipy.optimize import brentq

    t = brentq(f, 0.1, 1.0)
    assert th[0] == pytest.approx(t, abs=1e-6)  # file coordinates rounded to 1e-3 mm
    # other mode: the other root
    r2 = copy.deepcopy(r)
    for lg in r2["legs"]:
        lg["mode"] = -1
    t2 = S.actuators(r2, p, R)[0]
    assert abs(f(t2)) < 1e-6 and abs(t2 - t) > 0.5
    assert np.isnan(S.actuators(r, [0, 0, -1500.0], np.eye(3))[0])


# --- constraints and completion --------------------------------------------------------------------------


@pytest.mark.parametrize("arch", ["3-RPS", "3-PRS"])
def test_completed_pose_satisfies_constraints(arch):
    for seed in range(3):
        r = S.random_robot(arch, seed) if seed else S.load_reference(arch)
        z = S.home(r)[0][2]
        for roll, pitch in ((0.0, 0.0), (0.08, -0.05), (-0.1, 0.1)):
            p, R = S.complete_pose(r, z + 10, roll, pitch)
            assert np.abs(S.constraint_residuals(r, p, R)).max() < 1e-12
            assert p[2] == z + 10
            assert np.allclose(S.orientation_deg(R)[:2], np.degrees([roll, pitch]), atol=1e-10)
            for k, lg in enumerate(S.legs(r)):
                assert lg["axis"] @ (p + R @ lg["platform"] - lg["base"]) == pytest.approx(0, abs=1e-12)


def test_symmetric_3rps_has_no_parasitic_motion_at_level_pose():
    r = S.load_reference("3-RPS")
    p, R = S.complete_pose(r, 300.0, 0.0, 0.0)
    # the file's coordinates are rounded to 1e-3 mm
    assert np.abs(p[:2]).max() < 5e-3 and abs(S.orientation_deg(R)[2]) < 1e-3


def test_3rps_parasitic_motion_closed_form():
    """Symmetric 3-RPS (tangential axes): the classic result x = -r/2 (R11 - R22)... checked via its
    invariant R12 = R21 (yaw compensates roll and pitch so that the rotation matrix is symmetric in x-y)
    and y = -r R21 (Carretero, Podhorodeski, Nahon, Gosselin 2000: x = (r/2)(R11 - R22), y = -r R12)."""
    lg = []
    r_p = 100.0
    for k in range(3):
        g = math.radians(120 * k)
        lg.append({"base": [200 * math.cos(g), 200 * math.sin(g), 0], "axis": [-math.sin(g), math.cos(g), 0],
                   "platform": [r_p * math.cos(g), r_p * math.sin(g), 0], "stroke": [1, 1000]})
    rob = {"architecture": "3-RPS", "legs": lg}
    p, R = S.complete_pose(rob, 300.0, 0.15, -0.1)
    assert R[0, 1] == pytest.approx(R[1, 0], abs=1e-12)
    assert p[0] == pytest.approx(0.5 * r_p * (R[0, 0] - R[1, 1]), abs=1e-9)
    assert p[1] == pytest.approx(-r_p * R[0, 1], abs=1e-9)


@pytest.mark.parametrize("arch", ["delta", "3-UPU"])
def test_translational_constraints(arch):
    r = S.load_reference(arch)
    p, R = S.complete_pose(r, 10.0, -5.0, S.home(r)[0][2])
    assert np.allclose(R, np.eye(3)) and np.allclose(p, [10.0, -5.0, S.home(r)[0][2]])
    w = np.array([0.01, -0.02, 0.03])
    assert np.allclose(S.constraint_residuals(r, p, S.expm_so3(w)), w)


# --- forward kinematics and Jacobians --------------------------------------------------------------------


@pytest.mark.parametrize("arch", ARCHS)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_forward_inverts_actuators(arch, seed):
    r = S.load_reference(arch) if seed == 0 else S.random_robot(arch, seed)
    p, R = S.random_pose(r, seed + 10)
    q = S.actuators(r, p, R)
    p0, R0 = _pose_home(r)
    p2, R2 = S.forward(r, q, p0, R0)
    assert np.abs(p2 - p).max() < 1e-9
    assert np.abs(R2 - R).max() < 1e-11
    assert np.all(np.abs(S.constraint_residuals(r, p2, R2)) < 1e-10)


@pytest.mark.parametrize("arch", ARCHS)
def test_jacobians_consistent(arch):
    r = S.random_robot(arch, 3)
    p, R = S.random_pose(r, 4)
    J = S.jacobian_fd(r, p, R)
    Ji = S.inverse_jacobian_fd(r, p, R)
    n = S.n_actuators(r)
    assert J.shape == (6, n) and Ji.shape == (n, 6)
    assert np.abs(Ji @ J - np.eye(n)).max() < 1e-6
    if S.n_constraints(r):
        Jc = S.constraint_jacobian_fd(r, p, R)
        assert Jc.shape == (3, 6)
        scale = np.abs(Jc).max() * np.abs(J).max()
        assert np.abs(Jc @ J).max() < 1e-6 * scale
    if arch in ("delta", "3-UPU"):
        assert np.abs(J[3:]).max() < 1e-7  # pure translation


def test_hexapod_inverse_jacobian_closed_form():
    """Leg length rate = u . (v + w x R b) = [u, (R b) x u] . t."""
    r = S.load_reference("6-UPS")
    p, R = S.random_pose(r, 7)
    Ji = S.inverse_jacobian_fd(r, p, R)
    for k, lg in enumerate(S.legs(r)):
        rb = R @ lg["platform"]
        u = p + rb - lg["base"]
        u /= np.linalg.norm(u)
        assert np.allclose(Ji[k], np.concatenate([u, np.cross(rb, u)]), atol=1e-7)


def test_3rps_constraint_jacobian_closed_form():
    """d/dt axis . (p + R b - A) = [axis, (R b) x axis] . t: a force along the axis through B."""
    r = S.random_robot("3-RPS", 5)
    p, R = S.random_pose(r, 5)
    Jc = S.constraint_jacobian_fd(r, p, R)
    for k, lg in enumerate(S.legs(r)):
        rb = R @ lg["platform"]
        assert np.allclose(Jc[k], np.concatenate([lg["axis"], np.cross(rb, lg["axis"])]), atol=1e-7)


# --- singularities ---------------------------------------------------------------------------------------


def test_fichter_singularity_of_hexapod():
    """A semi-regular Gough-Stewart platform turned 90 deg about z is singular (Fichter 1986)."""
    r = _exact_hexapod()
    assert S.parallel_singularity_measure(r, [0, 0, 300.0], S.rotation([0, 0, 90])) < 1e-7
    assert S.parallel_singularity_measure(r, [0, 0, 300.0], S.rotation([0, 0, 80])) > 0.03
    assert S.parallel_singularity_measure(r, [0, 0, 300.0], np.eye(3)) > 0.3


def test_delta_singularity_with_horizontal_rods():
    """Rods of all three legs horizontal (coplanar): the platform can move vertically, a parallel singularity."""
    r = S.load_reference("delta")
    for lg in r["legs"]:
        lg["rod"], lg["angle_range_deg"] = 315.0, [-180.0, 180.0]  # 200 + 350 cos 60 - 60 = 315
    z = -350 * math.sin(math.radians(60))
    assert S.parallel_singularity_measure(r, [0, 0, z], np.eye(3)) < 1e-5
    assert S.parallel_singularity_measure(r, [0, 0, z - 100], np.eye(3)) > 0.3


# --- limits ----------------------------------------------------------------------------------------------


def _segment_distance_brute(p1, q1, p2, q2, n=801):
    s = np.linspace(0, 1, n)
    a = p1 + s[:, None] * (q1 - p1)
    b = p2 + s[:, None] * (q2 - p2)
    # coarse grid, then refine around the best pair
    d = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)
    i, j = np.unravel_index(np.argmin(d), d.shape)
    s2 = np.clip(np.linspace(s[i] - 2 / n, s[i] + 2 / n, 201), 0, 1)
    t2 = np.clip(np.linspace(s[j] - 2 / n, s[j] + 2 / n, 201), 0, 1)
    a = p1 + s2[:, None] * (q1 - p1)
    b = p2 + t2[:, None] * (q2 - p2)
    return float(np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2).min())


def test_segment_distance_against_brute_force():
    rng = np.random.default_rng(1)
    cases = [rng.normal(size=(4, 3)) * 100 for _ in range(60)]
    # parallel, collinear, crossing, degenerate
    cases.append(np.array([[0, 0, 0], [100, 0, 0], [20, 30, 0], [120, 30, 0]], float))
    cases.append(np.array([[0, 0, 0], [100, 0, 0], [150, 0, 0], [300, 0, 0]], float))
    cases.append(np.array([[0, 0, 0], [100, 0, 0], [50, -50, 0], [50, 50, 0]], float))
    cases.append(np.array([[0, 0, 0], [0, 0, 0], [50, -50, 10], [50, 50, 10]], float))
    cases.append(np.array([[1, 2, 3], [1, 2, 3], [4, 5, 6], [4, 5, 6]], float))
    for c in cases:
        d = S.segment_distance(*c)
        bf = _segment_distance_brute(*c)
        assert d <= bf + 1e-9
        assert bf - d < 1e-3 * max(1.0, np.abs(c).max() / 100)
    assert S.segment_distance(*cases[-3]) == pytest.approx(0.0, abs=1e-12)
    assert S.segment_distance(*cases[-4]) == pytest.approx(50.0, abs=1e-12)
    assert S.segment_distance(*cases[-5]) == pytest.approx(30.0, abs=1e-12)


def test_limit_reports():
    r = S.load_reference("6-UPS")
    p, R = S.home(r)
    assert S.within_limits(r, p, R)
    rep = S.limit_report(r, [0, 0, 500.0], R)
    assert any("stroke" in x for x in rep) and not S.within_limits(r, [0, 0, 500.0], R)
    r2 = copy.deepcopy(r)
    r2["legs"][0]["base_cone_deg"] = 10.0
    rep = S.limit_report(r2, p, R)
    assert rep and all(x.startswith("leg 1: base cone") for x in rep)
    r3 = copy.deepcopy(r)
    for lg in r3["legs"]:
        lg["radius"] = 60.0  # adjacent platform joints are 77.6 mm apart
    assert any("interference" in x for x in S.limit_report(r3, p, R))
    r4 = copy.deepcopy(r3)
    r4["legs"][1]["radius"] = 0.0
    r4["legs"][2]["radius"] = 0.0  # legs 2 and 3 are the close pair: radius 0 is never checked
    assert not any("legs 2 and 3" in x for x in S.limit_report(r4, p, R))
    # 3-RPS revolute angle: leg leaning inwards by atan(100/300), negative about the tangential axis
    rr = S.load_reference("3-RPS")
    rr["legs"][0]["angle_range_deg"] = [-18.0, 45.0]
    rep = S.limit_report(rr, [0, 0, 300.0], np.eye(3))
    assert rep and "revolute angle -18.43" in rep[0]
    # delta arm range and unreachable
    d = S.load_reference("delta")
    d["legs"][2]["angle_range_deg"] = [30.0, 90.0]
    assert any(x.startswith("leg 3: arm angle") for x in S.limit_report(d, [0, 0, -800.0], np.eye(3)))
    assert S.limit_report(d, [0, 0, -1500.0], np.eye(3))[0].endswith("unreachable")


def test_delta_platform_cone_uses_rod_direction():
    d = S.load_reference("delta")
    p, R = S.home(d)
    th = S.actuators(d, p, R)
    lg = S.legs(d)[0]
    C = lg["base"] + lg["arm"] * (math.cos(th[0]) * lg["zero"] + math.sin(th[0]) * np.cross(lg["axis"], lg["zero"]))
    ang = math.degrees(math.acos((C - (p + lg["platform"]))[2] / lg["rod"]))
    d["legs"][0]["platform_cone_deg"] = ang - 0.01
    assert S.limit_report(d, p, R)[0].startswith("leg 1: platform cone")
    d["legs"][0]["platform_cone_deg"] = ang + 0.01
    assert S.within_limits(d, p, R)


# --- random robots ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("arch", ARCHS)
def test_random_robots_respect_the_document(arch):
    for seed in range(4):
        r = S.random_robot(arch, seed)
        L = S.legs(r)
        for lg in L:
            if arch == "3-PRS":
                assert abs(lg["axis"] @ lg["slide"]) < 1e-12
            if arch in ("3-RPS", "3-PRS"):
                assert abs(lg["axis"] @ lg["base_normal"]) < 1e-12
            if arch == "3-UPU":
                assert np.allclose(lg["base_axis"], lg["platform_axis"])
            if arch == "delta":
                assert abs(lg["axis"] @ lg["zero"]) < 1e-12
        p, R = _pose_home(r)
        assert S.within_limits(r, p, R)
        p, R = S.random_pose(r, seed)
        assert S.within_limits(r, p, R) and not np.any(np.isnan(S.actuators(r, p, R)))


# --- Monte Carlo volume ----------------------------------------------------------------------------------


def _one_shell_3upu(lo, hi):
    """3-UPU whose leg 1 alone limits the workspace: the positions form a spherical shell about A1 - b1."""
    r = S.load_reference("3-UPU")
    for lg in r["legs"]:
        for key in ("base_cone_deg", "platform_cone_deg", "radius"):
            lg.pop(key, None)
        lg["stroke"] = [0.0, 1e6]
    r["legs"][0]["stroke"] = [lo, hi]
    centre = np.asarray(r["legs"][0]["base"]) - np.asarray(r["legs"][0]["platform"])
    return r, centre


@pytest.mark.slow
def test_monte_carlo_volume_of_a_spherical_shell():
    lo, hi = 100.0, 200.0
    r, c = _one_shell_3upu(lo, hi)
    box = np.column_stack([c - hi, c + hi])
    exact = 4.0 / 3.0 * math.pi * (hi**3 - lo**3)
    v, se = S.monte_carlo_volume(r, np.eye(3), box, 6000, seed=3)
    assert abs(v - exact) < 4 * se
    assert se / exact < 0.03


@pytest.mark.slow
def test_monte_carlo_standard_error_shrinks_like_sqrt_n():
    r = S.load_reference("3-UPU")
    box = np.array([[-150, 150], [-150, 150], [200, 450.0]])
    v1, se1 = S.monte_carlo_volume(r, np.eye(3), box, 400, seed=1)
    v2, se2 = S.monte_carlo_volume(r, np.eye(3), box, 3600, seed=2)
    assert 0 < v1 and 0 < v2
    assert se2 / se1 == pytest.approx(1 / 3, rel=0.25)
    assert abs(v1 - v2) < 4 * math.hypot(se1, se2)


def test_monte_carlo_3rps_in_z_roll_pitch():
    """3-RPS with only leg-length limits [lo, hi] on all legs at the level pose: the z-range with roll = pitch
    = 0 is exactly where sqrt(100^2 + z^2) is in [lo, hi]; the thin slab |roll|, |pitch| < 0.01 deg around it
    has volume ~ (z_hi - z_lo) * 0.02 * 0.02 mm deg^2."""
    lg = []
    for k in range(3):
        g = math.radians(120 * k)
        lg.append({"base": [200 * math.cos(g), 200 * math.sin(g), 0], "axis": [-math.sin(g), math.cos(g), 0],
                   "platform": [100 * math.cos(g), 100 * math.sin(g), 0], "stroke": [300.0, 400.0]})
    r = {"architecture": "3-RPS", "legs": lg}
    zlo, zhi = math.sqrt(300**2 - 100**2), math.sqrt(400**2 - 100**2)
    box = np.array([[250.0, 420.0], [-0.01, 0.01], [-0.01, 0.01]])
    v, se = S.monte_carlo_volume(r, None, box, 300, seed=5)
    exact = (zhi - zlo) * 0.02 * 0.02
    assert abs(v - exact) < 4 * se + 0.01 * exact


# --- screw-theory wrench systems (a second, non-FD derivation) -------------------------------------------


@pytest.mark.parametrize("arch", ARCHS)
def test_wrench_systems_are_reciprocal_to_the_motion(arch):
    """A leg's transmissible wrenches (reciprocal to its passive joints) do no work on any feasible motion of
    the robot that keeps that leg's actuator still: W_k . J[:, j] = 0 for j != k (J from finite differences
    of the forward kinematics; wrench [f, m] on twist [v, w]: f . v + m . w)."""
    r = S.random_robot(arch, 2)
    p, R = S.random_pose(r, 3)
    J = S.jacobian_fd(r, p, R)
    systems = S.leg_wrench_systems(r, p, R)
    assert np.vstack(systems).shape == (6, 6)
    for k, Wk in enumerate(systems):
        others = np.delete(J, k, axis=1)
        scale = np.abs(Wk).max() * np.abs(others).max()
        assert np.abs(Wk @ others).max() < 1e-6 * scale
        assert np.abs(Wk @ J[:, k]).max() > 1e-3 * scale  # the leg's own actuator does work


def test_screw_and_fd_measures_agree_on_the_hexapod():
    r = S.load_reference("6-UPS")
    for seed in range(3):
        p, R = S.random_pose(r, seed)
        assert S.screw_singularity_measure(r, p, R) == pytest.approx(S.parallel_singularity_measure(r, p, R), abs=1e-6)
    assert S.screw_singularity_measure(_exact_hexapod(), [0, 0, 300.0], S.rotation([0, 0, 90])) < 1e-9


def test_screw_measure_at_the_delta_singularity():
    r = S.load_reference("delta")
    for lg in r["legs"]:
        lg["rod"], lg["angle_range_deg"] = 315.0, [-180.0, 180.0]
    z = -350 * math.sin(math.radians(60))
    assert S.screw_singularity_measure(r, [0, 0, z], np.eye(3)) < 1e-5
    assert S.screw_singularity_measure(r, [0, 0, z - 100], np.eye(3)) > 0.2
