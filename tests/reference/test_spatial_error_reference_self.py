"""Self-checks of the independent spatial error reference (``spatial_error_reference``): closed-form cases and
facts that can be written down by hand; no ``pmaccuracy``."""

from __future__ import annotations

import copy

import numpy as np
import pytest

import spatial_error_reference as E
import spatial_reference as S

ARCHS = S.ARCHITECTURES
DOC_KEYS = {"radial", "axial", "tilt", "actuator", "backlash", "lateral", "position", "direction", "length"}


def _robot_pose(arch):
    rob = S.load_reference(arch)
    p, R = E.nominal_pose(rob)
    return rob, p, R


def _only(robot, kind_key, value, legs=None, joints=None):
    """A clearance dict with only ``{key: value}`` at the joints of the given kind (or indices)."""
    kinds = E.joint_kinds(robot)
    kind, key = kind_key
    out = []
    for i in range(len(robot["legs"])):
        js = []
        for jj, k in enumerate(kinds):
            use = (k == kind if joints is None else jj in joints) and (legs is None or i in legs)
            js.append({key: value} if use else {})
        out.append({"joints": js})
    return {"name": "test", "legs": out}


def _columns(sources, **match):
    return [src["columns"] for src in sources if all(src[k] == v for k, v in match.items())]


# --- files -----------------------------------------------------------------------------------------------


def test_clearance_files_parse_match_robots_and_use_every_key():
    used = set()
    for arch in ARCHS:
        rob = S.load_reference(arch)
        cl = E.load_clearances(arch)
        assert len(cl["legs"]) == len(rob["legs"])
        for lg in cl["legs"]:
            assert len(lg["joints"]) == len(E.joint_kinds(rob))
            for j in lg["joints"]:
                used |= set(j)
        p, R = E.nominal_pose(rob)
        model = E.ErrorModel(rob, cl, p, R)  # every key is valid at its joint
        assert model.m > 0
    assert used == DOC_KEYS
    # the universal's three keys, the revolute's, the prismatic's and the actuated revolute's all appear
    assert {"radial", "axial", "tilt"} <= {k for j in E.load_clearances("3-UPU")["legs"][0]["joints"][::2] for k in j}


@pytest.mark.parametrize("arch", ARCHS)
def test_random_clearances_are_valid(arch):
    rob = S.random_robot(arch, 3)
    cl = E.random_clearances(rob, 5)
    p, R = S.random_pose(rob, 7)
    model = E.ErrorModel(rob, cl, p, R)
    assert model.m > 10
    shapes = {src["shape"] for src in model.sources}
    assert {"segment", "disc", "ball"} <= shapes


def test_invalid_keys_raise():
    rob, p, R = _robot_pose("6-UPS")
    with pytest.raises(ValueError):
        E.ErrorModel(rob, _only(rob, ("spherical", "direction"), 0.001), p, R)
    with pytest.raises(ValueError):
        E.ErrorModel(rob, _only(rob, ("spherical", "length"), 0.001), p, R)  # platform joint: no next link
    with pytest.raises(ValueError):
        E.ErrorModel(rob, _only(rob, ("universal", "actuator"), 0.001), p, R)
    with pytest.raises(ValueError):
        E.ErrorModel(rob, _only(rob, ("universal", "bogus"), 0.001), p, R)


def test_shapes_give_their_number_of_columns():
    rob, p, R = _robot_pose("3-UPU")
    M, src = E.sensitivity(rob, E.load_clearances("3-UPU"), p, R)
    for s in src:
        assert s["columns"].stop - s["columns"].start == {"segment": 1, "disc": 2, "ball": 3}[s["shape"]]
    # a universal's radial play is two discs, its axial play two segments
    assert len(_columns(src, leg=0, joint=0, key="radial")) == 2
    assert len(_columns(src, leg=0, joint=0, key="axial")) == 2
    assert M.shape == (6, E.n_variables(src))


# --- zero and linearity ----------------------------------------------------------------------------------


@pytest.mark.parametrize("arch", ARCHS)
def test_zero_clearances_give_zero_errors(arch):
    rob, p, R = _robot_pose(arch)
    empty = {"legs": [{"joints": [{} for _ in E.joint_kinds(rob)]} for _ in rob["legs"]]}
    M, src = E.sensitivity(rob, empty, p, R)
    assert M.shape == (6, 0) and src == []
    assert np.all(E.component_bounds(M, src) == 0.0)
    zeros = copy.deepcopy(E.load_clearances(arch))
    for lg in zeros["legs"]:
        for j in lg["joints"]:
            for k in j:
                j[k] = 0.0
    assert np.all(E.nonlinear_extremes(rob, zeros, p, R, 2) == 0.0)
    model = E.ErrorModel(rob, E.load_clearances(arch), p, R)
    assert np.all(model.solve(np.zeros(model.m)) == 0.0)


@pytest.mark.parametrize("arch", [a if a == "6-UPS" else pytest.param(a, marks=pytest.mark.slow) for a in ARCHS])
def test_fd_columns_are_linear(arch):
    rob, p, R = _robot_pose(arch)
    cl = E.load_clearances(arch)
    M1, _ = E.sensitivity(rob, cl, p, R, h=1e-7)
    M2, _ = E.sensitivity(rob, cl, p, R, h=0.5e-7)
    M3, _ = E.sensitivity(rob, cl, p, R, h=2e-7)
    scale = np.max(np.abs(M1))
    assert np.max(np.abs(M1 - M2)) < 1e-9 * scale
    assert np.max(np.abs(M1 - M3)) < 1e-9 * scale
    # and the response to a combination is the combination of the columns (first order)
    model = E.ErrorModel(rob, cl, p, R)
    rng = np.random.default_rng(0)
    s = 1e-9 * rng.normal(size=model.m)  # second-order terms ~ |s|^2 L: negligible
    assert np.allclose(model.solve(s), M1 @ s, rtol=0, atol=1e-6 * np.max(np.abs(M1 @ s)))


# --- closed forms ----------------------------------------------------------------------------------------


def _ups_inverse_jacobian(robot, p, R):
    """Rows [u_i, (R b_i) x u_i]: d L_i = u_i . dB_i with dB_i = dp + dtheta x (R b_i)."""
    rows = []
    for leg in S.legs(robot):
        rb = R @ leg["platform"]
        u = p + rb - leg["base"]
        u /= np.linalg.norm(u)
        rows.append(np.concatenate([u, np.cross(rb, u)]))
    return np.array(rows)


@pytest.mark.parametrize("pose_seed", [None, 1, 2])
def test_hexapod_ball_play_follows_the_leg_length_law(pose_seed):
    rob = S.load_reference("6-UPS")
    p, R = E.nominal_pose(rob) if pose_seed is None else S.random_pose(rob, pose_seed)
    cl = _only(rob, ("spherical", "radial"), 0.015)
    M, src = E.sensitivity(rob, cl, p, R)
    Jinv = _ups_inverse_jacobian(rob, p, R)
    assert len(src) == 6
    for i, s in enumerate(src):
        assert s["leg"] == i and s["shape"] == "ball" and s["half_width"] == 0.015
        u = Jinv[i, :3]
        # the platform's ball centre moves by s relative to the leg's end: |B - s - A| = L, so
        # u_i . dB_i = u_i . s_i and u_k . dB_k = 0 for the other legs
        Ms = M[:, s["columns"]]
        along_leg = Ms @ u  # ball displacement along the leg (basis e_x, e_y, e_z)
        rhs = np.zeros(6)
        rhs[i] = 1.0
        t = np.linalg.solve(Jinv, rhs)
        assert np.allclose(along_leg, t, rtol=0, atol=1e-7 * np.max(np.abs(t)))
        # a ball displacement normal to the leg does nothing at first order
        e1 = S._perp_to(u)
        e2 = np.cross(u, e1)
        assert np.max(np.abs(Ms @ e1)) < 1e-7 * np.max(np.abs(t))
        assert np.max(np.abs(Ms @ e2)) < 1e-7 * np.max(np.abs(t))
    # the whole set: Jinv t = [u_i . s_i]
    rng = np.random.default_rng(3)
    s = rng.normal(size=M.shape[1])
    rhs = np.array([Jinv[i, :3] @ s[src[i]["columns"]] for i in range(6)])
    assert np.allclose(Jinv @ (M @ s), rhs, atol=1e-8 * np.max(np.abs(rhs)))


def test_hexapod_actuator_error_is_the_forward_jacobian_column():
    rob = S.load_reference("6-UPS")
    for seed in (None, 4):
        p, R = E.nominal_pose(rob) if seed is None else S.random_pose(rob, seed)
        cl = _only(rob, ("prismatic", "actuator"), 0.005)
        M, src = E.sensitivity(rob, cl, p, R)
        J = S.jacobian_fd(rob, p, R)
        assert M.shape == (6, 6)
        assert [s["leg"] for s in src] == list(range(6))
        assert np.allclose(M, J, rtol=0, atol=1e-6 * np.max(np.abs(J)))
        # backlash and a leg's length tolerance act the same way
        Mb, _ = E.sensitivity(rob, _only(rob, ("prismatic", "backlash"), 0.003), p, R)
        assert np.allclose(Mb, M, atol=1e-9 * np.max(np.abs(J)))


def test_hexapod_free_directions_of_the_leg():
    """With base_axis normal to the leg the cross normal is the leg: turning the leg about itself (universal
    tilt), and, at first order, moving or tilting the leg's carriage normal to it, do not move the platform."""
    rob = copy.deepcopy(S.load_reference("6-UPS"))
    p, R = E.nominal_pose(rob)
    for lg in rob["legs"]:
        d = p + R @ np.asarray(lg["platform"]) - np.asarray(lg["base"])
        lg["base_axis"] = list(np.cross([0.0, 0.0, 1.0], d))
    scale = np.max(np.abs(E.sensitivity(rob, _only(rob, ("prismatic", "actuator"), 0.005), p, R)[0]))
    for key in (("universal", "tilt"), ("universal", "direction"), ("prismatic", "lateral"), ("prismatic", "tilt")):
        M, _ = E.sensitivity(rob, _only(rob, key, 0.001), p, R)
        assert np.max(np.abs(M)) < 1e-9 * scale, key
    # without base_axis (u1 horizontal and normal to the leg at home) the same holds at home
    for lg in rob["legs"]:
        del lg["base_axis"]
    M, _ = E.sensitivity(rob, _only(rob, ("universal", "tilt"), 0.001), p, R)
    assert np.max(np.abs(M)) < 1e-9 * scale
    # but the pins' radial play does move it (a translation of the whole leg)
    M, _ = E.sensitivity(rob, _only(rob, ("universal", "radial"), 0.01), p, R)
    assert np.max(np.abs(M)) > 0.1


def test_delta_single_ball_tilts_and_equal_rod_lengths_translate():
    rob, p, R = _robot_pose("delta")
    # one platform ball (leg 1, rod 1) alone: the parallelogram is broken, the platform turns
    cl = _only(rob, ("spherical", "radial"), 0.015, legs=[0], joints=[2])
    M, src = E.sensitivity(rob, cl, p, R)
    assert len(src) == 1 and src[0]["shape"] == "ball"
    b = E.component_bounds(M, src)
    assert np.max(b[3:]) > 1e-5  # rad: a tilt of order 0.015 mm / 100 mm spacing
    T = E.nonlinear_extremes(rob, cl, p, R, 5, seed=0)
    assert np.all(np.linalg.norm(T[:, 3:], axis=1) > 1e-6)
    # a length tolerance of both rods of one leg, equal: still a parallelogram, a pure translation
    cl = _only(rob, ("spherical", "length"), 0.01, legs=[1], joints=[1, 3])
    model = E.ErrorModel(rob, cl, p, R)
    assert model.m == 2
    for v in (0.01, -0.01, 0.5):
        t = model.solve(np.array([v, v]))
        assert np.linalg.norm(t[:3]) > 0.5 * abs(v)
        assert np.linalg.norm(t[3:]) < 1e-12
    # unequal rods tilt the platform
    t = model.solve(np.array([0.01, -0.01]))
    assert np.linalg.norm(t[3:]) > 1e-6
    M, _ = E.sensitivity(rob, cl, p, R)
    assert np.max(np.abs(M[3:, 0] + M[3:, 1])) < 1e-9 * np.max(np.abs(M[3:, 0]))
    # the arm's actuator error is the forward Jacobian's column
    M, _ = E.sensitivity(rob, _only(rob, ("actuated revolute", "actuator"), 1e-4), p, R)
    J = S.jacobian_fd(rob, p, R)
    assert np.allclose(M, J, atol=1e-6 * np.max(np.abs(J)))
    assert np.max(np.abs(M[3:])) < 1e-9 * np.max(np.abs(M[:3]))


def test_upu_cross_tilt_turns_the_platform():
    """A rotation about the base cross normal turns the whole distal leg about the joint centre; the
    platform universal joint cannot absorb it: the platform turns."""
    rob, p, R = _robot_pose("3-UPU")
    M, src = E.sensitivity(rob, _only(rob, ("universal", "tilt"), 0.0002, legs=[0], joints=[0]), p, R)
    assert np.linalg.norm(M[3:, 0]) > 0.05  # rad/rad
    # the leg-length law still holds: the tilt is a rotation about the leg, the length is unchanged
    Ma, _ = E.sensitivity(rob, _only(rob, ("prismatic", "actuator"), 0.005), p, R)
    assert np.max(np.abs(Ma[3:])) < 1e-9 * np.max(np.abs(Ma[:3]))  # actuators translate a 3-UPU


# --- first order against screw theory --------------------------------------------------------------------


@pytest.mark.parametrize("arch", ARCHS)
@pytest.mark.parametrize("seed", [0, 1])
def test_sensitivity_matches_screw_theory(arch, seed):
    if seed == 0:
        rob, p, R = _robot_pose(arch)
        cl = E.load_clearances(arch)
    else:
        rob = S.random_robot(arch, 10 + seed)
        p, R = S.random_pose(rob, 20 + seed)
        cl = E.random_clearances(rob, 30 + seed)
    M, src = E.sensitivity(rob, cl, p, R)
    M2 = E.first_order_screw_theory(rob, p, R, src)
    for rows in (slice(0, 3), slice(3, 6)):
        scale = np.max(np.abs(M[rows]))
        assert np.max(np.abs(M[rows] - M2[rows])) < 1e-6 * scale


# --- bounds ----------------------------------------------------------------------------------------------


def test_component_bounds_and_norm_by_hand():
    # one ball and one segment: |dp_x| <= h1 |row| + h2 |m|; the norm bound of a ball + segment sum
    M = np.zeros((6, 4))
    M[:3, :3] = np.diag([1.0, 2.0, 3.0])
    M[:3, 3] = [0.0, 0.0, 1.0]
    src = [{"columns": slice(0, 3), "half_width": 0.1, "shape": "ball"},
           {"columns": slice(3, 4), "half_width": 0.5, "shape": "segment"}]
    assert np.allclose(E.component_bounds(M, src), [0.1, 0.2, 0.3 + 0.5, 0, 0, 0])
    v, x = E.max_norm_sampled(M, src, n=20000, seed=1, return_point=True)
    assert v == pytest.approx(0.8, rel=1e-9)  # an ellipsoid (semi-axes .1 .2 .3) plus a segment along z
    assert np.allclose(np.abs(x), [0, 0, 0.8], atol=1e-6)


@pytest.mark.parametrize("arch", ARCHS)
def test_nonlinear_extremes_within_first_order_bounds(arch):
    rob, p, R = _robot_pose(arch)
    cl = E.load_clearances(arch)
    M, src = E.sensitivity(rob, cl, p, R)
    b = E.component_bounds(M, src)
    np_ = E.max_norm_sampled(M, src, slice(0, 3), n=50000, seed=2)
    nr = E.max_norm_sampled(M, src, slice(3, 6), n=50000, seed=2)
    assert np.max(b[:3]) <= np_ * (1 + 1e-12) <= np.linalg.norm(b[:3]) * (1 + 1e-12)
    assert np.max(b[3:]) <= nr * (1 + 1e-12) <= np.linalg.norm(b[3:]) * (1 + 1e-12)
    T, Ss = E.nonlinear_extremes(rob, cl, p, R, 40, seed=1, return_sources=True)
    lin = Ss @ M.T
    # second-order terms only: |nonlinear - M s| ~ |s|^2 / L (relative ~ 1e-3 at these clearances)
    dev = np.abs(T - lin)
    assert np.max(dev[:, :3]) < 1e-2 * np_
    assert np.max(dev[:, 3:]) < 1e-2 * nr
    assert np.all(np.abs(T) <= 1.01 * b)
    assert np.max(np.linalg.norm(T[:, :3], axis=1)) <= 1.01 * np_
    assert np.max(np.linalg.norm(T[:, 3:], axis=1)) <= 1.01 * nr
    # and the extremes really are large: the set is explored
    assert np.max(np.linalg.norm(T[:, :3], axis=1)) > 0.3 * np_


def test_second_order_scaling():
    """The nonlinear deviation from M s shrinks like |s|^2 (the FD matrix is the true derivative)."""
    rob, p, R = _robot_pose("3-RPS")
    cl = E.load_clearances("3-RPS")
    model = E.ErrorModel(rob, cl, p, R)
    M, _ = E.sensitivity(rob, cl, p, R)
    s = E.random_extreme(model.sources, np.random.default_rng(0)) * 50
    d1 = np.linalg.norm(model.solve(s) - M @ s)
    d2 = np.linalg.norm(model.solve(s / 10) - M @ (s / 10))
    assert d1 > 0
    assert d2 == pytest.approx(d1 / 100, rel=0.05)
