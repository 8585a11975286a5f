"""Self-tests of the independent worst-case error reference (``error_reference``).

Everything the reference computes is checked against something computed differently:

* exact poses with errors against hand-written loop equations of each architecture solved by
  ``scipy.optimize.fsolve`` (3-RPR actuators and base play, 3-RRR elbow play, 3-PPR bearing tilt and guide
  play);
* the FD Jacobian against Richardson extrapolation (accuracy of the step) and against Jacobian columns
  derived by hand (Aalborg 3-PPR at the origin);
* the worst cases against closed forms (symmetric 3-RPR with actuator errors, a single radial clearance,
  the Aalborg bearing and guide clearances, the reference document's figures), against SLSQP maximization
  over the whole error set, vertex enumeration and Monte Carlo sampling;
* the first-order maxima against the exact nonlinear errors of the arg-max configurations (the gap shrinks
  like the square of the error size).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy import optimize

import error_reference as er

# ------------------------------------------------------------------------------------------ robots

AALBORG_ROWS = [(192.34, 180, -90, -90, 0, 83.15, 30, 30, [-40.0, 10.0]),
                (192.34, 0, 90, 90, 0, 83.15, 30, 150, [-40.0, 10.0]),
                (192.34, 90, 90, 90, 0, 70.00, 30, -90, [-25.0, 25.0])]


def aalborg() -> dict:
    """The reconstructed Aalborg 3-PPR (reference document, Table 1 stand-in) as a "3-PPR" dict."""
    return dict(architecture="3-PPR", legs=[
        dict(a=a, alpha_deg=al, beta_deg=be, gamma_deg=ga, theta_deg=th, d=dd, r=r, psi_deg=ps, s_range=s,
             l_range=[20.0, 160.0]) for a, al, be, ga, th, dd, r, ps, s in AALBORG_ROWS])


def polar(radius, deg):
    return [radius * math.cos(math.radians(deg)), radius * math.sin(math.radians(deg))]


def symmetric_rpr(Rb=200.0, rp=50.0, twist_deg=40.0) -> dict:
    """3-RPR with base points on a circle of radius Rb at 90 + 120 i deg and platform points on a circle of
    radius rp turned by ``twist_deg`` (three-fold symmetric)."""
    return dict(architecture="3-RPR", legs=[
        dict(base=polar(Rb, 90 + 120 * i), platform=polar(rp, 90 + 120 * i + twist_deg), length_range=[50.0, 300.0])
        for i in range(3)])


def symmetric_rrr(wm=(1, -1, 1)) -> dict:
    return dict(architecture="3-RRR", legs=[
        dict(base=polar(200.0, 90 + 120 * i), platform=polar(50.0, 120 + 120 * i), proximal=110.0, distal=100.0,
             angle_range_deg=[-360.0, 360.0], working_mode=wm[i]) for i in range(3)])


def spec_of(entries) -> dict:
    """File-format spec from ``{(leg, joint): {source: value}}``."""
    return {"legs": [{"joints": [dict(entries.get((i, k), {})) for k in range(3)]} for i in range(3)]}


def in_set(spec, vars_, e, tol=1e-12):
    """Whether the flat configuration ``e`` lies in the error set of the merged ``spec``."""
    for kind, eps, cols, L in er._sources(spec, vars_):
        v = e[cols]
        if kind == "disk" and np.hypot(*v) > eps * (1 + tol):
            return False
        if kind == "interval" and abs(v[0]) > eps * (1 + tol):
            return False
        if kind == "rhombus" and max(abs(L * v[1] + 2 * v[0]), abs(L * v[1] - 2 * v[0])) > 2 * eps * (1 + tol):
            return False
    return True


# ------------------------------------------------------------------------------------------ kinematics

def test_zero_errors_give_the_commanded_pose():
    for d, pose in [(aalborg(), [3.0, -7.0, 0.2]), (symmetric_rpr(), [5.0, 2.0, -0.1]),
                    (symmetric_rrr(), [4.0, -3.0, 0.05])]:
        pose = np.array(pose)
        got = er.pose_with_errors(d, pose)
        np.testing.assert_allclose(got, pose, atol=1e-11)
        q = er.inverse_kinematics(d, pose)
        robot = er.load_robot(d)
        for leg, ql in zip(robot.legs, q):
            p3, t3, _, _ = er.chain_fk(leg, ql[None])
            np.testing.assert_allclose(p3[0], pose[:2] + er.rot(pose[2], np.array(leg.platform)), atol=1e-10)
            assert abs(er.wrap(t3[0] - pose[2] - leg.platform_angle)) < 1e-12


def test_rrr_working_modes_follow_the_elbow_sign():
    for wm in [(1, -1, 1), (-1, 1, -1)]:
        d = symmetric_rrr(wm)
        q = er.inverse_kinematics(d, np.array([3.0, 1.0, 0.1]))
        robot = er.load_robot(d)
        for leg, ql, w in zip(robot.legs, q, wm):
            _, _, c, _ = er.chain_fk(leg, ql[None])
            A, B, D = c[0]
            assert np.sign(er.cross(B - A, D - B)) == w


def _fsolve(fun, x0):
    x, info, ok, msg = optimize.fsolve(fun, x0, xtol=1e-13, full_output=True)
    # the residual is the criterion (fsolve may report slow progress once it is at the rounding level)
    assert np.max(np.abs(fun(x))) < 1e-11, msg
    return x


def test_rpr_actuator_and_base_play_match_hand_loop_equations(rng):
    d = symmetric_rpr()
    pose = np.array([4.0, -6.0, 0.15])
    A = np.array([L["base"] for L in d["legs"]])
    Dp = np.array([L["platform"] for L in d["legs"]])
    L0 = np.linalg.norm(pose[:2] + er.rot(pose[2], Dp) - A, axis=1)
    for _ in range(3):
        dl = rng.uniform(-0.3, 0.3, 3)
        dA = rng.uniform(-0.2, 0.2, (3, 2))
        cfg = [[{"radial": list(dA[i])}, {"actuator": dl[i]}, {}] for i in range(3)]
        got = er.pose_with_errors(d, pose, errors=cfg)
        # |P + Rot(phi) D_i - (A_i + dA_i)| = L_i + dl_i (the base frame is the world frame: base_angle 0)
        want = _fsolve(lambda X: np.linalg.norm(X[:2] + er.rot(X[2], Dp) - A - dA, axis=1) - L0 - dl, pose)
        np.testing.assert_allclose(got, want, atol=1e-10)


def test_rrr_elbow_play_matches_hand_loop_equations(rng):
    d = symmetric_rrr()
    pose = np.array([2.0, 5.0, -0.05])
    robot = er.load_robot(d)
    q = er.inverse_kinematics(d, pose)
    A = np.array([L["base"] for L in d["legs"]])
    Dp = np.array([L["platform"] for L in d["legs"]])
    for _ in range(3):
        delta = rng.uniform(-0.3, 0.3, (3, 2))
        cfg = [[{}, {"radial": list(delta[i])}, {}] for i in range(3)]
        got = er.pose_with_errors(robot, pose, q, cfg)
        # Tr(delta) before the elbow joint, in the proximal link's frame (angle q_1): distal starts at
        # B + Rot(q_1) delta, and |D - B'| = distal with the actuator locked.
        Bp = A + 110.0 * er.vec(q[:, 0]) + er.rot(q[:, 0], delta)
        want = _fsolve(lambda X: np.linalg.norm(X[:2] + er.rot(X[2], Dp) - Bp, axis=1) - 100.0, pose)
        np.testing.assert_allclose(got, want, atol=1e-10)


def _ppr_vectors():
    a, al, be, ga, th, dd, r, ps = (np.array([row[k] for row in AALBORG_ROWS], float) for k in range(8))
    al, be, ga, th, ps = (np.radians(x) for x in (al, be, ga, th, ps))
    return a, al, be, ga, th, dd, r, ps


def test_ppr_bearing_tilt_and_guide_play_match_eq1(rng):
    """Eq. 1 with the bearing turned by tau_b about C_i and the guide carriage shifted by sigma (normal to
    u_i) and turned by tau_g about B_i: D_i = P - r_i k_i must lie on the bearing line."""
    a, al, be, ga, th, dd, r, ps = _ppr_vectors()
    pose = np.array([6.0, -4.0, 0.1])
    q = er.inverse_kinematics(aalborg(), pose)
    s = q[:, 0]
    h, u = er.vec(al), er.vec(al + be)
    for _ in range(3):
        tb, tg = rng.uniform(-0.01, 0.01, 3), rng.uniform(-0.01, 0.01, 3)
        sg = rng.uniform(-0.1, 0.1, 3)
        cfg = [[{"lateral": [sg[i], tg[i]]}, {"angular": tb[i]}, {}] for i in range(3)]
        got = er.pose_with_errors(aalborg(), pose, q, cfg)
        C = a[:, None] * h + s[:, None] * u + sg[:, None] * er.perp(u) + dd[:, None] * er.vec(al + be + ga + tg)
        w = er.vec(al + be + ga + th + tg + tb)

        def F(X):
            D = X[:2] - r[:, None] * er.vec(X[2] + ps)
            return er.cross(w, D - C)

        np.testing.assert_allclose(got, _fsolve(F, pose), atol=1e-10)


# ------------------------------------------------------------------------------------------ FD Jacobian

def _richardson(d, pose, spec, h=1e-5):
    G1, _ = er.error_jacobian_fd(d, pose, spec, h=h)
    G2, _ = er.error_jacobian_fd(d, pose, spec, h=2 * h)
    return (4 * G1 - G2) / 3


@pytest.mark.parametrize("which", ["aalborg", "rpr", "rrr"])
def test_fd_jacobian_step_1e6_agrees_with_richardson(which, rng):
    d, pose = {"aalborg": (aalborg(), [5.0, -10.0, 0.3]), "rpr": (symmetric_rpr(), [4.0, 3.0, -0.2]),
               "rrr": (symmetric_rrr(), [2.0, -3.0, 0.1])}[which]
    pose = np.array(pose)
    c, t = er.random_clearances(rng, d, p_skip=0.0)
    spec = er.merge_specs(d, c, t)
    G, vars_ = er.error_jacobian_fd(d, pose, spec)
    Gr = _richardson(d, pose, spec)
    scale = np.max(np.abs(Gr), axis=1, keepdims=True)
    assert G.shape == (3, len(vars_)) and len(vars_) > 20
    assert np.max(np.abs(G - Gr) / scale) < 1e-9


def test_fd_jacobian_of_aalborg_bearings_matches_hand_columns():
    """At (0, 0, 0): D_1, D_2 = (-+r c30, -r/2), D_3 = (0, r); bearings 1, 2 along x, 3 along y with
    lengths l_1 = l_2 = a - d_1 - r cos 30, l_3 = a - d_3 - r. Tilting bearing i by tau moves D_i normally
    by l_i tau: dy - r c30 dphi = l_1 tau_1, dy + r c30 dphi = -l_2 tau_2, dx - r dphi = l_3 tau_3."""
    r, c30 = 30.0, math.cos(math.radians(30))
    l1 = 192.34 - 83.15 - r * c30
    l3 = 192.34 - 70.0 - r
    spec = spec_of({(i, 1): {"angular": 0.0012} for i in range(3)})
    G, vars_ = er.error_jacobian_fd(aalborg(), np.zeros(3), spec)
    assert vars_ == [(i, 1, "angular", 0) for i in range(3)]
    want = np.array([[-l1 / (2 * c30), -l1 / (2 * c30), l3],
                     [l1 / 2, -l1 / 2, 0.0],
                     [-l1 / (2 * r * c30), -l1 / (2 * r * c30), 0.0]])
    np.testing.assert_allclose(G, want, rtol=1e-8, atol=1e-8)


# ------------------------------------------------------------------------------------------ closed forms

def _rpr_geometry(d):
    A = np.array([L["base"] for L in d["legs"]])
    D = np.array([L["platform"] for L in d["legs"]])
    e = (D - A) / np.linalg.norm(D - A, axis=1, keepdims=True)
    m = er.cross(D, e)
    return e, m


def test_symmetric_rpr_actuators_closed_form():
    """e_i . dp + m dphi = dL_i with sum e_i = 0, sum e_i e_i^T = 3/2 I and equal m (three-fold symmetry):
    dp = 2/3 sum e_i dL_i, dphi = sum dL_i / (3 m); hence dx_max = 2/3 eps sum |e_ix|, dy_max likewise,
    dphi_max = eps / |m| and dp_max = 2/3 eps max_c sum |c . e_i| = 4/3 eps (hexagonal zonotope)."""
    d = symmetric_rpr()
    e, m = _rpr_geometry(d)
    np.testing.assert_allclose(m, m[0], rtol=1e-12)
    eps = 0.004
    wc = er.worst_case(d, np.zeros(3), spec_of({(i, 1): {"actuator": eps} for i in range(3)}))
    assert wc["dx_max"] == pytest.approx(2 / 3 * eps * np.sum(np.abs(e[:, 0])), rel=1e-8)
    assert wc["dy_max"] == pytest.approx(2 / 3 * eps * np.sum(np.abs(e[:, 1])), rel=1e-8)
    assert wc["dphi_max"] == pytest.approx(eps / abs(m[0]), rel=1e-8)
    assert wc["dp_max"] == pytest.approx(4 / 3 * eps, rel=1e-9)
    # the maximizing configurations attain the maxima, up to second order
    for k, row in (("dx", 0), ("dy", 1), ("dphi", 2)):
        nl = er.nonlinear_at(d, np.zeros(3), wc["argmax"][k])
        assert nl[row] == pytest.approx(wc[k + "_max"], rel=1e-4)
    nl = er.nonlinear_at(d, np.zeros(3), wc["argmax"]["dp"])
    assert np.hypot(*nl[:2]) == pytest.approx(wc["dp_max"], rel=1e-4)


@pytest.mark.parametrize("leg,joint", [(0, 0), (1, 2), (2, 0)])
def test_single_radial_clearance_on_rpr_closed_form(leg, joint):
    """A disk of radius eps at the base or platform joint of leg i changes that leg's effective length by
    -e_i . delta, so dX = -(e_i . delta) col_i(J^-1) with col_i = (2/3 e_i, 1/(3 m)): dx_max = 2/3 eps |e_ix|,
    dy_max = 2/3 eps |e_iy|, dphi_max = eps / (3 |m|), dp_max = 2/3 eps."""
    d = symmetric_rpr(twist_deg=25.0)
    e, m = _rpr_geometry(d)
    eps = 0.03
    wc = er.worst_case(d, np.zeros(3), spec_of({(leg, joint): {"radial": eps}}))
    assert wc["dx_max"] == pytest.approx(2 / 3 * eps * abs(e[leg, 0]), rel=1e-8)
    assert wc["dy_max"] == pytest.approx(2 / 3 * eps * abs(e[leg, 1]), rel=1e-8)
    assert wc["dphi_max"] == pytest.approx(eps / (3 * abs(m[leg])), rel=1e-8)
    assert wc["dp_max"] == pytest.approx(2 / 3 * eps, rel=1e-9)


def test_aalborg_bearing_clearance_closed_form_and_reference_figures():
    r, c30 = 30.0, math.cos(math.radians(30))
    l1 = 192.34 - 83.15 - r * c30
    l3 = 192.34 - 70.0 - r
    eps = 0.0012
    spec = spec_of({(i, 1): {"angular": eps} for i in range(3)})
    wc = er.worst_case(aalborg(), np.zeros(3), spec)
    assert wc["dy_max"] == pytest.approx(eps * l1, rel=1e-8)
    assert wc["dphi_max"] == pytest.approx(eps * l1 / (r * c30), rel=1e-8)
    assert wc["dx_max"] == pytest.approx(eps * (l3 + l1 / c30), rel=1e-8)
    cols = np.array([[-l1 / (2 * c30), l1 / 2], [-l1 / (2 * c30), -l1 / 2], [l3, 0.0]])
    dp = max(np.hypot(*(np.array(sg) @ cols)) for sg in itertools.product((-1, 1), repeat=3))
    assert wc["dp_max"] == pytest.approx(eps * dp, rel=1e-8)
    # the reference document's figures (Case 1, phi = 0)
    assert wc["dy_max"] == pytest.approx(0.0999, abs=5e-5)
    # the document quotes 0.2203 deg; the hand formula above gives 0.22020 deg (0.05 % lower)
    assert math.degrees(wc["dphi_max"]) == pytest.approx(0.2203, abs=1.5e-4)
    assert 0.196 <= wc["dx_max"] <= 0.256
    # over the workspace (y in [-25, 25] mm): dx_max from 0.196 to 0.256 mm, falling by eps * 50 mm along y
    # (l_3 = a - d_3 - r - y); the document's four-digit ends 0.1957 / 0.2557 are 0.0004 mm below these.
    lo = er.worst_case(aalborg(), np.array([10.0, 25.0, 0.0]), spec)
    hi = er.worst_case(aalborg(), np.array([-10.0, -25.0, 0.0]), spec)
    assert lo["dx_max"] == pytest.approx(0.196, abs=5e-4)
    assert hi["dx_max"] == pytest.approx(0.256, abs=5e-4)
    assert hi["dx_max"] - lo["dx_max"] == pytest.approx(eps * 50.0, rel=1e-8)
    for w in (lo, hi):
        assert w["dy_max"] == pytest.approx(wc["dy_max"], rel=1e-8)
        assert w["dphi_max"] == pytest.approx(wc["dphi_max"], rel=1e-8)


def test_aalborg_guide_play_closed_form():
    """Turning guide carriage i by tau about B_i turns the bearing and moves C_i by d_i tau normal to it, so
    D_i moves normally by (d_i + l_i) tau; the normal shift sigma is along the bearing (no effect). The
    rhombus maximum is at tau = 2 eps / L: leg 3 alone gives dx_max = 2 eps (d_3 + l_3) / L; leg 1 alone
    gives dy_max = eps (d_1 + l_1) / L, dphi_max = that / (r cos 30), dx_max = that / cos 30."""
    r, c30 = 30.0, math.cos(math.radians(30))
    eps, L = 0.0015, 50.0
    l1 = 192.34 - 83.15 - r * c30
    l3 = 192.34 - 70.0 - r
    w3 = er.worst_case(aalborg(), np.zeros(3), spec_of({(2, 0): {"lateral": eps, "block_length": L}}))
    assert w3["dx_max"] == pytest.approx(2 * eps * (70.0 + l3) / L, rel=1e-7)
    assert w3["dy_max"] < 1e-10 and w3["dphi_max"] < 1e-12
    np.testing.assert_allclose(w3["argmax_flat"]["dx"], [0.0, 2 * eps / L])
    w1 = er.worst_case(aalborg(), np.zeros(3), spec_of({(0, 0): {"lateral": eps, "block_length": L}}))
    t = eps * (83.15 + l1) / L
    assert w1["dy_max"] == pytest.approx(t, rel=1e-7)
    assert w1["dphi_max"] == pytest.approx(t / (r * c30), rel=1e-7)
    assert w1["dx_max"] == pytest.approx(t / c30, rel=1e-7)


# ------------------------------------------------------------------------------------------ brute force

def _cases(rng):
    out = [(aalborg(), np.array([5.0, -8.0, 0.25])), (symmetric_rpr(), np.array([3.0, 6.0, -0.1])),
           (symmetric_rrr(), np.array([-4.0, 2.0, 0.08]))]
    return out


def _scaled_problem(spec, vars_):
    """The error set in scaled variables ``e = S z``, written without the support formulas: scales ``S``
    ``(n,)``, bounds (intervals ``|z| <= 1``), and an SLSQP inequality constraint ``c(z) >= 0`` with its
    Jacobian: rhombus ``|z_tau +- z_sigma| <= 1`` (z_sigma = sigma/eps, z_tau = tau L/(2 eps)), disk
    ``z_a^2 + z_b^2 <= 1``."""
    n = len(vars_)
    S = np.ones(n)
    bounds = [(None, None)] * n
    lin, disks = [], []
    for kind, eps, cols, L in er._sources(spec, vars_):
        if kind == "disk":
            S[cols] = eps
            disks.append(cols)
        elif kind == "interval":
            S[cols] = eps
            bounds[cols[0]] = (-1.0, 1.0)
        else:
            S[cols[0]], S[cols[1]] = eps, 2 * eps / L
            for a, b in ((1, 1), (-1, -1), (1, -1), (-1, 1)):
                row = np.zeros(n)
                row[cols[0]], row[cols[1]] = a, b
                lin.append(row)
    A = np.array(lin).reshape(-1, n)
    D = np.array(disks, int).reshape(-1, 2)

    def fun(z):
        return np.concatenate([1 - A @ z, 1 - z[D[:, 0]] ** 2 - z[D[:, 1]] ** 2])

    def jac(z):
        Jd = np.zeros((len(D), n))
        Jd[np.arange(len(D)), D[:, 0]] = -2 * z[D[:, 0]]
        Jd[np.arange(len(D)), D[:, 1]] = -2 * z[D[:, 1]]
        return np.vstack([-A, Jd])

    return S, bounds, dict(type="ineq", fun=fun, jac=jac)


def test_support_sums_match_slsqp_over_the_whole_set(rng):
    """dx/dy/dphi maxima = maximum of a linear function over the (convex) error set, found by SLSQP with the
    constraints written directly; the arg-max configurations lie in the set and attain the maxima; and no
    point sampled in the set exceeds them."""
    for d, pose in _cases(rng):
        c, t = er.random_clearances(rng, d)
        wc = er.worst_case(d, pose, c, t)
        G, vars_, spec = wc["jacobian"], wc["variables"], wc["spec"]
        S, bounds, cons = _scaled_problem(spec, vars_)
        for row, key in enumerate(("dx", "dy", "dphi")):
            e_star = wc["argmax_flat"][key]
            assert in_set(spec, vars_, e_star)
            assert G[row] @ e_star == pytest.approx(wc[key + "_max"], rel=1e-12)
            g = G[row] * S
            res = optimize.minimize(lambda z: -(g @ z), np.zeros(len(S)), jac=lambda z: -g, method="SLSQP",
                                    bounds=bounds, constraints=[cons], options=dict(maxiter=1000, ftol=1e-15))
            assert np.min(cons["fun"](res.x)) > -1e-9
            assert -res.fun == pytest.approx(wc[key + "_max"], rel=1e-7)
        # Monte Carlo inside the set: every sampled point stays below the maxima
        n = 4000
        E = np.zeros((n, len(vars_)))
        for kind, eps, cols, L in er._sources(spec, vars_):
            if kind == "disk":
                rad = eps * np.sqrt(rng.uniform(0, 1, n))
                E[:, cols] = rad[:, None] * er.vec(rng.uniform(0, 2 * np.pi, n))
            elif kind == "interval":
                E[:, cols[0]] = rng.choice([-eps, eps], n) * rng.uniform(0.9, 1, n)
            else:
                a, b = rng.uniform(-1, 1, (2, n))
                w = np.abs(a) + np.abs(b)
                a, b = a / np.maximum(w, 1), b / np.maximum(w, 1)
                E[:, cols[0]], E[:, cols[1]] = eps * a, 2 * eps / L * b
        Y = E @ G.T
        assert np.all(np.abs(Y[:, 0]) <= wc["dx_max"] * (1 + 1e-12))
        assert np.all(np.abs(Y[:, 1]) <= wc["dy_max"] * (1 + 1e-12))
        assert np.all(np.abs(Y[:, 2]) <= wc["dphi_max"] * (1 + 1e-12))
        assert np.all(np.hypot(Y[:, 0], Y[:, 1]) <= wc["dp_max"] * (1 + 1e-9))


def test_dp_max_matches_vertex_enumeration(rng):
    """With only interval and rhombus sources the error set is a polytope: dp_max is the largest |(dx, dy)|
    over its vertices (all sign/vertex combinations)."""
    d, pose = aalborg(), np.array([-3.0, 7.0, 0.2])
    entries = {(0, 0): {"actuator": 0.004, "lateral": 0.003, "block_length": 40.0}, (1, 1): {"angular": 0.001},
               (2, 0): {"actuator": 0.006, "lateral": 0.002, "block_length": 25.0}, (2, 1): {"angular": 0.0015},
               (0, 1): {"angular": 0.0008}}
    tol = {(1, 0): {"direction": 0.0005, "length": 0.02}}
    wc = er.worst_case(d, pose, spec_of(entries), spec_of(tol))
    G, vars_ = wc["jacobian"], wc["variables"]
    choices = []
    for kind, eps, cols, L in er._sources(wc["spec"], vars_):
        if kind == "interval":
            choices.append([(cols, [eps]), (cols, [-eps])])
        else:
            choices.append([(cols, v) for v in ([eps, 0.0], [-eps, 0.0], [0.0, 2 * eps / L], [0.0, -2 * eps / L])])
    best = 0.0
    for combo in itertools.product(*choices):
        e = np.zeros(len(vars_))
        for cols, v in combo:
            e[cols] = v
        best = max(best, float(np.hypot(*(G[:2] @ e))))
    assert wc["dp_max"] == pytest.approx(best, rel=1e-10)
    e = wc["argmax_flat"]["dp"]
    assert in_set(wc["spec"], vars_, e)
    assert np.hypot(*(G[:2] @ e)) == pytest.approx(wc["dp_max"], rel=1e-10)


@pytest.mark.slow
def test_dp_max_with_disks_matches_multistart_slsqp(rng):
    """dp_max = max |G_xy e| over the set (non-convex maximization): the best of several SLSQP runs from
    random starts reaches the direction search's value and never exceeds it."""
    for d, pose in _cases(rng):
        c, t = er.random_clearances(rng, d)
        wc = er.worst_case(d, pose, c, t)
        G, vars_, spec = wc["jacobian"], wc["variables"], wc["spec"]
        S, bounds, cons = _scaled_problem(spec, vars_)
        M = G[:2] * S
        best = 0.0
        for _ in range(10):
            res = optimize.minimize(lambda z: -np.sum((M @ z) ** 2), rng.uniform(-0.7, 0.7, len(S)),
                                    jac=lambda z: -2 * M.T @ (M @ z), method="SLSQP", bounds=bounds,
                                    constraints=[cons], options=dict(maxiter=200, ftol=1e-16))
            if np.min(cons["fun"](res.x)) > -1e-9:
                best = max(best, float(np.linalg.norm(M @ res.x)))
        assert best <= wc["dp_max"] * (1 + 1e-8)
        assert best == pytest.approx(wc["dp_max"], rel=1e-7)


# ------------------------------------------------------------------------------------------ second order

def test_first_order_maxima_attained_up_to_second_order(rng):
    """The exact error of the arg-max configuration e* scaled by s differs from s * max by O(s^2):
    c(s) = (nl(s e*) - s max) / s^2 stays bounded (|c| <= 0.1 max) and nearly constant for s = 1, 1/2, 1/4
    (it varies only by the third-order term), and the odd part (nl(s e*) - nl(-s e*)) / (2 s), which has no
    second-order term, equals max to 1e-3 at s = 1/4."""
    for d, pose in _cases(rng):
        c, t = er.random_clearances(rng, d)
        wc = er.worst_case(d, pose, c, t)
        vars_ = wc["variables"]
        for row, key in enumerate(("dx", "dy", "dphi")):
            e, m = wc["argmax_flat"][key], wc[key + "_max"]
            cs = []
            for s in (1.0, 0.5, 0.25):
                nl = er.nonlinear_at(d, pose, er.flat_to_config(vars_, s * e))[row]
                cs.append((nl - s * m) / s ** 2)
            cs = np.array(cs)
            assert np.max(np.abs(cs)) <= 0.1 * m
            assert np.ptp(cs) <= 0.2 * np.max(np.abs(cs)) + 5e-4 * m
            minus = er.nonlinear_at(d, pose, er.flat_to_config(vars_, -0.25 * e))[row]
            assert (nl - minus) / 0.5 == pytest.approx(m, rel=1e-3)


# ------------------------------------------------------------------------------------------ formats

@pytest.mark.parametrize("entry,message", [
    ({(0, 1): {"radial": 0.01}}, "radial"),               # radial on the prismatic joint of a 3-RPR
    ({(0, 0): {"angular": 0.001}}, "angular"),            # angular on a revolute
    ({(0, 0): {"actuator": 0.001}}, "actuator"),          # actuator on a passive joint
    ({(0, 1): {"lateral": 0.001}}, "block_length"),       # lateral without a block length
    ({(1, 2): {"radial": -0.01}}, ">= 0"),
    ({(2, 2): {"radil": 0.01}}, "unknown"),
])
def test_bad_clearances_are_refused(entry, message):
    with pytest.raises(ValueError, match=message):
        er.merge_specs(symmetric_rpr(), spec_of(entry))


def test_bad_tolerances_and_shapes_are_refused():
    with pytest.raises(ValueError, match="zero link"):
        er.merge_specs(symmetric_rpr(), None, spec_of({(0, 1): {"length": 0.01}}))
    with pytest.raises(ValueError, match="unknown"):
        er.merge_specs(symmetric_rpr(), None, spec_of({(0, 1): {"radial": 0.01}}))
    with pytest.raises(ValueError, match="three legs"):
        er.merge_specs(symmetric_rpr(), {"legs": [{"joints": [{}, {}, {}]}] * 2})
    with pytest.raises(ValueError, match="three entries"):
        er.merge_specs(symmetric_rpr(), {"legs": [{"joints": [{}, {}]}] * 3})
    with pytest.raises(ValueError, match="does not apply"):
        er.pose_with_errors(symmetric_rpr(), np.zeros(3), errors=[[{"angular": 0.1}, {}, {}], [{}] * 3, [{}] * 3])


def test_random_clearances_follow_the_joint_types(rng):
    for d in (aalborg(), symmetric_rpr(), symmetric_rrr()):
        robot = er.load_robot(d)
        c, t = er.random_clearances(rng, d, p_skip=0.0)
        er.merge_specs(d, c, t)                     # valid
        for leg, cl, tl in zip(robot.legs, c["legs"], t["legs"]):
            for J, cj, tj in zip(leg.joints, cl["joints"], tl["joints"]):
                keys = {"radial"} if J.kind == "R" else {"angular", "lateral", "block_length"}
                if J.actuated:
                    keys.add("actuator")
                    lo, hi = (0.001, 0.01) if J.kind == "P" else (1e-4, 1e-3)
                    assert lo <= cj["actuator"] <= hi
                assert set(cj) == keys
                assert set(tj) == {"position", "direction"} | ({"length"} if np.hypot(*J.link) > 0 else set())
                if J.kind == "R":
                    assert 0.005 <= cj["radial"] <= 0.05
                else:
                    assert 1e-4 <= cj["angular"] <= 2e-3 and 0.001 <= cj["lateral"] <= 0.005
                    assert 20 <= cj["block_length"] <= 60


# ------------------------------------------------------------------------------------------ other references

def test_agrees_with_planar_reference_ik_on_random_robots(rng):
    """My chain loader and multi-start IK reproduce the other independent reference (if present), and the
    worst cases do not depend on which of the two supplies the commanded configuration."""
    pr = pytest.importorskip("planar_reference")
    for make in (pr.random_rpr, pr.random_rrr, pr.random_prr, pr.random_chain):
        d, pose = make(rng)
        q_mine = er.inverse_kinematics(d, pose)
        q_theirs = pr.full_configurations(pr.load(d), pose)[0]
        robot = er.load_robot(d)
        for leg, a, b in zip(robot.legs, q_mine, q_theirs):
            for k, J in enumerate(leg.joints):
                diff = er.wrap(a[k] - b[k]) if J.kind == "R" else a[k] - b[k]
                assert abs(diff) < 1e-9
        c, t = er.random_clearances(rng, d)
        w1 = er.worst_case(d, pose, c, t, n_dir=2000)
        w2 = er.worst_case(pr.load(d), pose, c, t, joints0=q_theirs, n_dir=2000)
        for k in ("dx_max", "dy_max", "dphi_max", "dp_max"):
            assert w1[k] == pytest.approx(w2[k], rel=1e-7)
