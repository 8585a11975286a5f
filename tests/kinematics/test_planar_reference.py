"""Self-tests of the independent planar reference (tests/reference/planar_reference.py).

The reference's methods are checked against each other (per-architecture IK vs chain IK in closed form
vs multi-start Newton; FK scan vs IK; finite-difference Jacobians vs constraint wrenches; workspace by
slices vs Monte Carlo vs shapely) and against closed forms written here from the conventions alone.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

import planar_reference as pr

DATA = Path(__file__).resolve().parents[1] / "data"
GENERATORS = {"rpr": pr.random_rpr, "rrr": pr.random_rrr, "prr": pr.random_prr, "chain": pr.random_chain}


def vec(t):
    return np.array([math.cos(t), math.sin(t)])


def rot(t, v):
    c, s = math.cos(t), math.sin(t)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def near_poses(pose, rng, n, xy=4.0, phi=0.04):
    return pose + rng.normal(0.0, [xy, xy, phi], (n, 3))


# ---- the brief's equivalences, written out by hand (not through planar_reference.to_chain_dict) ----

def chain_of(d):
    legs = []
    for L in d["legs"]:
        if d["architecture"] == "3-RPR":
            js = [dict(type="R"), dict(type="P", actuated=True, range=L["length_range"]), dict(type="R")]
            legs.append(dict(base=L["base"], base_deg=0.0, platform=L["platform"], platform_deg=0.0,
                             working_mode=1, joints=js))
        elif d["architecture"] == "3-RRR":
            js = [dict(type="R", actuated=True, link=[L["proximal"], 0.0], range=L["angle_range_deg"]),
                  dict(type="R", link=[L["distal"], 0.0]), dict(type="R")]
            legs.append(dict(base=L["base"], base_deg=0.0, platform=L["platform"], platform_deg=0.0,
                             working_mode=L["working_mode"], joints=js))
        elif d["architecture"] == "3-PRR":
            js = [dict(type="P", actuated=True, range=L["s_range"]), dict(type="R", link=[L["distal"], 0.0]),
                  dict(type="R")]
            legs.append(dict(base=L["guide_point"], base_deg=L["guide_deg"], platform=L["platform"],
                             platform_deg=0.0, working_mode=L["working_mode"], joints=js))
    return dict(architecture="chain", legs=legs)


@pytest.fixture(scope="module")
def robots():
    """Two random robots of each generator, with their nominal poses."""
    rng = np.random.default_rng(12345)
    return {name: [gen(rng) for _ in range(2)] for name, gen in GENERATORS.items()}


# ---- conventions ----------------------------------------------------------------------------------

def test_wrap_and_range_conventions():
    assert pr.wrap(np.pi) == pytest.approx(np.pi) and pr.wrap(-np.pi) == pytest.approx(np.pi)
    assert pr.wrap(3 * np.pi / 2) == pytest.approx(-np.pi / 2)
    lo, hi = np.radians(170.0), np.radians(200.0)
    assert pr.angle_in_range(np.radians(-170.0), lo, hi)        # -170 + 360 = 190
    assert not pr.angle_in_range(np.radians(-150.0), lo, hi)
    assert not pr.angle_in_range(np.nan, lo, hi)
    assert pr.nearest_to(np.radians(-170.0), np.radians(185.0)) == pytest.approx(np.radians(190.0))


def test_leg_fk_by_hand():
    """A chain R(offset 10 deg, link (100, 20)) P(offset -30 deg, link (0, 5)) R(link (7, 0)) evaluated by hand."""
    d = dict(architecture="chain", legs=[dict(base=[3.0, -4.0], base_deg=15.0, platform=[0.0, 0.0], joints=[
        dict(type="R", offset_deg=10.0, link=[100.0, 20.0]),
        dict(type="P", actuated=True, offset_deg=-30.0, link=[0.0, 5.0], range=[0.0, 100.0]),
        dict(type="R", link=[7.0, 0.0])])] * 3)
    leg = pr.load(d).legs[0]
    q = np.array([0.4, 55.0, -1.1])
    t1 = math.radians(25.0) + 0.4
    p1 = np.array([3.0, -4.0]) + rot(t1, [100.0, 20.0])
    t2 = t1 - math.radians(30.0)
    p2 = p1 + 55.0 * vec(t2) + rot(t2, [0.0, 5.0])
    t3 = t2 - 1.1
    p3 = p2 + rot(t3, [7.0, 0.0])
    P, T, C, AX = pr.leg_fk(leg, q)
    np.testing.assert_allclose(P, p3, atol=1e-12)
    assert T == pytest.approx(t3)
    np.testing.assert_allclose(C, [[3.0, -4.0], p1, p2], atol=1e-12)
    np.testing.assert_allclose(AX[1], vec(t2), atol=1e-15)


def test_load_rejects_bad_input():
    good = pr.random_rpr(np.random.default_rng(0))[0]
    with pytest.raises(ValueError):
        pr.load(dict(good, legs=good["legs"][:2]))
    with pytest.raises(ValueError):
        pr.load(dict(good, architecture="4-RPR"))
    bad = dict(good, legs=[dict(good["legs"][0], length_range=[300.0, 200.0])] + good["legs"][1:])
    with pytest.raises(ValueError):
        pr.load(bad)
    ch = pr.random_chain(np.random.default_rng(0))[0]
    two = [dict(j, actuated=True, range=j.get("range", [0.0, 1.0])) for j in ch["legs"][0]["joints"]]
    with pytest.raises(ValueError):
        pr.load(dict(ch, legs=[dict(ch["legs"][0], joints=two)] + ch["legs"][1:]))


# ---- working modes and wrenches ------------------------------------------------------------------

def test_wrench_is_reciprocal_to_passive_twists(robots):
    rng = np.random.default_rng(1)
    for name in GENERATORS:
        for d, pose in robots[name]:
            robot = pr.load(d)
            qf = pr.full_configurations(robot, near_poses(pose, rng, 50))
            for i, leg in enumerate(robot.legs):
                w = pr.leg_wrench(leg, qf[:, i])
                T = pr.leg_twists(leg, qf[:, i])
                for k in leg.passive:
                    assert np.nanmax(np.abs(pr.pairing(w, T[:, k, :]))) < 1e-9


def test_working_mode_definitions_agree(robots):
    """For 3-RRR and 3-PRR, sign(B_ii) (twists and wrenches) is the file's sign definition; B_ii also
    equals its closed form cross(B - A, D - B)/|D - B| (RRR) or u.(D - B)/|D - B| (PRR); RPR has B_ii = 1."""
    rng = np.random.default_rng(2)
    for name in ("rpr", "rrr", "prr"):
        for d, pose in robots[name]:
            robot = pr.load(d)
            poses = near_poses(pose, rng, 100)
            q, pas, within = pr.inverse_kinematics(robot, poses, "geometric")
            b = pr.b_diagonal(robot, poses, "geometric")
            for i, L in enumerate(d["legs"]):
                ok = np.isfinite(q[:, i])
                Dp = poses[ok, :2] + np.array([rot(p, L["platform"]) for p in poses[ok, 2]])
                if name == "rpr":
                    np.testing.assert_allclose(b[ok, i], 1.0, atol=1e-12)
                    continue
                if name == "rrr":
                    A = np.array(L["base"])
                    B = A + L["proximal"] * np.column_stack([np.cos(q[ok, i]), np.sin(q[ok, i])])
                    BD = Dp - B
                    ref = pr.cross(B - A, BD) / np.linalg.norm(BD, axis=1)
                else:
                    u = vec(math.radians(L["guide_deg"]))
                    B = np.array(L["guide_point"]) + q[ok, i, None] * u
                    BD = Dp - B
                    ref = BD @ u / np.linalg.norm(BD, axis=1)
                np.testing.assert_allclose(np.linalg.norm(BD, axis=1), L["distal"], rtol=1e-12)
                assert np.all(np.sign(ref) == L["working_mode"])
                np.testing.assert_allclose(b[ok, i], ref, rtol=1e-9, atol=1e-9)


# ---- inverse kinematics -----------------------------------------------------------------------------

def _compare_ik(a, b, tol=1e-8):
    qa, pa, wa = a
    qb, pb, wb = b
    assert np.array_equal(np.isnan(qa), np.isnan(qb))
    np.testing.assert_allclose(qa, qb, atol=tol, equal_nan=True)
    d = pa - pb
    d = np.where(np.abs(d) > np.pi, pr.wrap(d), d)           # R values compared modulo 2 pi
    assert np.nanmax(np.abs(d)) < tol
    assert np.array_equal(wa, wb)


def test_ik_geometric_chain_numeric_agree(robots):
    """Per-architecture geometry, the hand-written chain equivalent (closed form and numeric) agree."""
    rng = np.random.default_rng(3)
    for name in ("rpr", "rrr", "prr"):
        for d, pose in robots[name]:
            poses = near_poses(pose, rng, 150, xy=20.0, phi=0.3)
            geo = pr.inverse_kinematics(pr.load(d), poses, "geometric")
            ch = pr.load(chain_of(d))
            assert ch.legs[0].geom is None
            _compare_ik(geo, pr.inverse_kinematics(ch, poses, "chain"))
            _compare_ik(tuple(x[:60] for x in geo), pr.inverse_kinematics(ch, poses[:60], "numeric"))
            assert geo[2].any()
            # to_chain_dict builds the same chain
            _compare_ik(geo, pr.inverse_kinematics(pr.load(pr.to_chain_dict(d)), poses, "chain"))


def test_chain_ik_closed_form_vs_numeric(robots):
    """On mixed chains every closed-form branch is also a solution found by the multi-start Newton, and
    the working-mode choice agrees."""
    rng = np.random.default_rng(4)
    for d, pose in robots["chain"] + [pr.random_chain(rng, types=t) for t in
                                      (("RRP", "PRP", "RPP"), ("PPR", "RPR", "RRR"))]:
        robot = pr.load(d)
        poses = near_poses(pose, rng, 60, xy=10.0, phi=0.1)
        _compare_ik(pr.inverse_kinematics(robot, poses, "chain"), pr.inverse_kinematics(robot, poses, "numeric"))
        for leg in robot.legs:
            X, Th = pr._targets(leg, poses)
            qc, okc = pr._chain_ik_all(leg, X, Th)
            qn, okn = pr._numeric_ik_all(leg, X, Th)
            for b in range(qc.shape[1]):
                dist = np.abs(qc[:, b, None, :] - qn)
                isR = np.array([j.kind == "R" for j in leg.joints])
                dist[..., isR] = np.abs(pr.wrap(dist[..., isR]))
                found = np.any(okn & (np.max(dist, axis=-1) < 1e-8), axis=1)
                assert np.all(found[okc[:, b]])
            # closure: the chain reaches the target
            qf = pr.leg_ik(leg, poses, "chain")
            p3, t3, _, _ = pr.leg_fk(leg, qf)
            ok = np.isfinite(qf[:, 0])
            assert ok.mean() > 0.5
            assert np.max(np.abs(p3[ok] - X[ok])) < 1e-9
            assert np.max(np.abs(pr.wrap(t3[ok] - Th[ok]))) < 1e-12


def test_ik_3ppr_against_paper_loop_equation():
    """IK of the reference 3-PPR reproduces s, l through Eq. 1: p = a h + s u + d v + l w + r k."""
    d = pr.aalborg_3ppr()
    robot = pr.load(d)
    rng = np.random.default_rng(5)
    poses = np.column_stack([rng.uniform(-30, 30, 200), rng.uniform(-30, 30, 200), rng.uniform(-1, 1, 200)])
    q, pas, within = pr.inverse_kinematics(robot, poses)
    qc = pr.inverse_kinematics(pr.load(pr.to_chain_dict(d)), poses, "numeric")
    _compare_ik((q, pas, within), qc)
    for i, L in enumerate(d["legs"]):
        al, be, ga, th, ps = (math.radians(L[k]) for k in ("alpha_deg", "beta_deg", "gamma_deg", "theta_deg", "psi_deg"))
        for n in range(0, 200, 17):
            p = (L["a"] * vec(al) + q[n, i] * vec(al + be) + L["d"] * vec(al + be + ga)
                 + pas[n, i, 0] * vec(al + be + ga + th) + L["r"] * vec(poses[n, 2] + ps))
            np.testing.assert_allclose(p, poses[n, :2], atol=1e-10)
            assert pas[n, i, 1] == pytest.approx(pr.wrap(poses[n, 2] - (al + be + ga + th)), abs=1e-12)
    # the home pose of the document: phi = 0, square workspace [-25, 25]^2
    inside = np.abs(poses[:, :2]).max(1) < 25
    assert np.array_equal(pr.inverse_kinematics(robot, np.column_stack([poses[:, :2], 0 * poses[:, 2]]))[2], inside)


def test_ik_unreachable_is_nan():
    d, pose = pr.random_rrr(np.random.default_rng(6))
    q, pas, within = pr.inverse_kinematics(pr.load(d), pose + np.array([5000.0, 0.0, 0.0]))
    assert np.all(np.isnan(q)) and np.all(np.isnan(pas)) and not within[0]


# ---- forward kinematics -----------------------------------------------------------------------------

def test_fk_round_trip(robots):
    """The scan finds the pose the actuated values came from, every solution reproduces them, and the
    number of real solutions is even for these generic cases."""
    rng = np.random.default_rng(7)
    cases = [(d, pose) for name in GENERATORS for d, pose in robots[name][:1]]
    cases.append((pr.aalborg_3ppr(), np.array([5.0, -3.0, 0.2])))
    for d, pose in cases:
        robot = pr.load(d)
        for p in (pose, near_poses(pose, rng, 1)[0]):
            q = pr.inverse_kinematics(robot, p)[0][0]
            sols = pr.forward_kinematics_scan(robot, q)
            assert len(sols) % 2 == 0
            err = np.abs(sols - p)
            err[:, 2] = np.abs(pr.wrap(sols[:, 2] - p[2]))
            assert np.min(err.max(1)) < 1e-9
            assert np.max(pr.actuation_residual(robot, sols, q)) < 1e-9


def _rpr_newton_all(d, L, n_starts, rng):
    """All solutions of |P + Rot(phi) D_i - A_i| = L_i found by Newton from random starts (independent of
    the scan): (x, y, phi) uniform in [-300, 300]^2 x [-pi, pi]."""
    A = np.array([l["base"] for l in d["legs"]])
    D = np.array([l["platform"] for l in d["legs"]])
    sols = []
    for _ in range(n_starts):
        z = np.array([rng.uniform(-300, 300), rng.uniform(-300, 300), rng.uniform(-np.pi, np.pi)])
        for _ in range(50):
            c, s = math.cos(z[2]), math.sin(z[2])
            RD = D @ np.array([[c, s], [-s, c]])
            v = z[:2] + RD - A
            F = np.sum(v * v, 1) - np.asarray(L) ** 2
            J = np.column_stack([2 * v, 2 * np.sum(v * np.column_stack([-RD[:, 1], RD[:, 0]]), 1)])
            try:
                z = z - np.linalg.solve(J, F)
            except np.linalg.LinAlgError:
                break
            if not np.all(np.isfinite(z)) or np.abs(z[:2]).max() > 1e5:
                break
        else:
            if np.max(np.abs(F)) < 1e-8:
                z[2] = pr.wrap(z[2])
                if not any(np.abs(z - t).max() < 1e-6 for t in sols):
                    sols.append(z)
    return np.array(sorted(sols, key=lambda t: t[2]))


def test_six_modes_file():
    d = tomllib.loads((DATA / "rpr_six_modes.toml").read_text())
    robot = pr.load(d)
    ex = d["fk_example"]
    L = np.array(ex["lengths"])
    stored = np.column_stack([ex["x"], ex["y"], np.radians(ex["phi_deg"])])
    assert len(stored) == 6
    assert np.min(np.diff(np.r_[stored[:, 2], stored[0, 2] + 2 * np.pi])) > np.radians(1.0)
    q, _, within = pr.inverse_kinematics(robot, stored)
    assert np.max(np.abs(q - L)) < 1e-9 and within.all()
    sols = pr.forward_kinematics_scan(robot, L)
    assert sols.shape == (6, 3)
    np.testing.assert_allclose(sols, stored, atol=1e-9)
    newton = _rpr_newton_all(d, L, 300, np.random.default_rng(8))
    assert newton.shape == (6, 3)
    np.testing.assert_allclose(newton, stored, atol=1e-8)


def test_fk_close_pair_at_a_fold():
    """Across a parallel singularity the number of real solutions changes by two: just on one side the
    scan finds two solutions a fraction of a degree apart, on the other side none near the fold."""
    d = tomllib.loads((DATA / "rpr_six_modes.toml").read_text())
    robot = pr.load(d)
    base = np.array([d["fk_example"]["x"][4], d["fk_example"]["y"][4], math.radians(d["fk_example"]["phi_deg"][4])])

    from scipy.optimize import brentq
    for direction in ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.01], [1.0, 1.0, 0.0], [1.0, -1.0, 0.0]):
        def det(t):
            return np.linalg.det(pr.wrench_matrix(robot, base + t * np.array(direction))[0])

        ts = np.linspace(-150, 150, 601)
        vals = np.array([det(t) for t in ts])
        k = np.nonzero(np.sign(vals[:-1]) != np.sign(vals[1:]))[0]
        if len(k):
            break
    t_s = brentq(det, ts[k[0]], ts[k[0] + 1], xtol=1e-14)
    ps = base + t_s * np.array(direction)
    qs = pr.inverse_kinematics(robot, ps)[0][0]
    near = []
    for eps in (1e-3, -1e-3):
        q = qs + np.array([eps, 0.0, 0.0])
        sols = pr.forward_kinematics_scan(robot, q)
        assert np.max(pr.actuation_residual(robot, sols, q), initial=0) < 1e-9
        close = sols[(np.abs(pr.wrap(sols[:, 2] - ps[2])) < 0.05) & (np.hypot(*(sols[:, :2] - ps[:2]).T) < 20)]
        near.append(close)
    counts = sorted(len(c) for c in near)
    assert counts == [0, 2]
    pair = near[0] if len(near[0]) == 2 else near[1]
    sep = abs(pr.wrap(pair[0, 2] - pair[1, 2]))
    assert 1e-4 < sep < np.radians(1.0)          # closer than 20 grid steps of the scan


# ---- Jacobians --------------------------------------------------------------------------------------

def test_jacobian_fd_matches_wrenches(robots):
    """dq/dpose from central differences equals (f_x, f_y, m_P)/B_ii row by row (A = wrenches, B diagonal)."""
    rng = np.random.default_rng(9)
    for name in GENERATORS:
        for d, pose in robots[name]:
            robot = pr.load(d)
            poses = near_poses(pose, rng, 20)
            J = pr.jacobian_fd(robot, poses)
            ref = pr.wrench_matrix(robot, poses) / pr.b_diagonal(robot, poses)[..., None]
            ok = np.all(np.isfinite(ref), axis=(1, 2))
            assert ok.mean() > 0.8
            np.testing.assert_allclose(J[ok], ref[ok], rtol=1e-7, atol=1e-8 * np.abs(ref[ok]).max())


def test_jacobian_fd_rpr_closed_form(robots):
    """3-RPR: dL_i/d(x, y, phi) = [e_i, e_i . E Rot(phi) d_i] with e_i the unit vector A_i -> D_i."""
    d, pose = robots["rpr"][0]
    J = pr.jacobian_fd(pr.load(d), pose)[0]
    for i, L in enumerate(d["legs"]):
        rd = rot(pose[2], L["platform"])
        e = pose[:2] + rd - np.array(L["base"])
        e /= np.linalg.norm(e)
        np.testing.assert_allclose(J[i], [e[0], e[1], e @ np.array([-rd[1], rd[0]])], rtol=1e-8, atol=1e-9)


# ---- constant-orientation workspace -------------------------------------------------------------------

def test_workspace_3ppr_closed_form():
    """The document's workspaces: phi = 0, the square [-25, 25]^2; phi = 30 deg, x in [-10, 40] and
    y in [-40 + 15 sqrt 3, 10]. The 3-PPR region is a polygon, so shapely is exact here too."""
    robot = pr.load(pr.aalborg_3ppr())
    a = pr.workspace_area_slices(robot, 0.0)
    assert a["area"] == pytest.approx(2500.0, abs=1e-9)
    np.testing.assert_allclose(a["bbox"], [-25, 25, -25, 25], atol=1e-12)
    b = pr.workspace_area_slices(robot, math.radians(30.0))
    np.testing.assert_allclose(b["bbox"], [-10, 40, -40 + 15 * math.sqrt(3), 10], atol=1e-12)
    s = pr.workspace_area_shapely(robot, math.radians(30.0))
    assert s["area"] == pytest.approx(b["area"], abs=1e-9)
    mc = pr.workspace_area_mc(robot, math.radians(30.0), n=50_000, rng=10)
    assert abs(mc["area"] - b["area"]) < 4 * mc["stderr"]


def test_workspace_annulus_closed_form():
    """A 3-RPR whose legs 2 and 3 never bind: the workspace is leg 1's annulus pi (hi^2 - lo^2)."""
    d, pose = pr.random_rpr(np.random.default_rng(11))
    lo, hi = d["legs"][0]["length_range"]
    d["legs"][1]["base"] = d["legs"][2]["base"] = [9000.0, 9000.0]   # far away: lengths about 12700 mm
    d["legs"][1]["length_range"] = d["legs"][2]["length_range"] = [1.0, 20000.0]
    robot = pr.load(d)
    a = pr.workspace_area_slices(robot, pose[2])
    assert a["area"] == pytest.approx(math.pi * (hi ** 2 - lo ** 2), rel=1e-12)
    c = np.array(d["legs"][0]["base"]) - rot(pose[2], d["legs"][0]["platform"])
    np.testing.assert_allclose(a["bbox"], [c[0] - hi, c[0] + hi, c[1] - hi, c[1] + hi], atol=1e-9)


@pytest.mark.parametrize("name", ["rpr", "rrr", "prr", "chain"])
def test_workspace_three_methods_agree(robots, name):
    for n, (d, pose) in enumerate(robots[name]):
        robot = pr.load(d)
        phi = pose[2]
        sl = pr.workspace_area_slices(robot, phi)
        assert sl["area"] > 100.0
        mc = pr.workspace_area_mc(robot, phi, n=60_000, rng=100 + n)
        assert abs(sl["area"] - mc["area"]) < 4 * mc["stderr"]
        # the Monte Carlo inside points lie in the slice bounding box
        bb, mb = np.array(sl["bbox"]), np.array(mc["bbox"])
        assert mb[0] >= bb[0] and mb[1] <= bb[1] and mb[2] >= bb[2] and mb[3] <= bb[3]
        if name != "chain":
            sh = pr.workspace_area_shapely(robot, phi, step=2 * np.pi / 8000)
            assert abs(sl["area"] - sh["area"]) <= sh["bound"]
            np.testing.assert_allclose(sh["bbox"], sl["bbox"], atol=0.01)
