"""Certified worst cases (issue 13, item 1): pmaccuracy.accuracy.certified and ``bounds --certified / --nonlinear``.

Independent references: the dense nonlinear search of ``nonlinear_search_reference.py`` (its own exact loop
closure from ``error_reference.py``, first-order vertices by finite differences, random and dense
coordinate-wise sampling of the error set), the library's separate virtual prototype
(:func:`pmaccuracy.accuracy.nonlinear.joint_displaced_pose`, Newton with a finite-difference Jacobian) for
re-inserted worst configurations, and brute-force sampling for the duality bound of a quadratic.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import nonlinear_search_reference as nsr
from pmaccuracy.accuracy import certified as C
from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.errors import CertificationError
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.accuracy.nonlinear import joint_displaced_pose
from pmaccuracy.model.sources import ErrorSources
from pmaccuracy.io.resolve import load_clearances

PAPER_POSE = np.array([10.0, 5.0, np.radians(3.0)])


def _paper_spec(name: str) -> dict:
    """The 3-PPR clearance preset as a per-joint dict (the paper's bearing = angular on joint 2, guide play =
    lateral on joint 1, revolute = radial on joint 3), written here from the preset's numbers."""
    robot = Manipulator.preset("aalborg_3ppr")
    cs = load_clearances(name, robot)
    legs = []
    for i in range(3):
        j1 = {"lateral": float(cs.guide_lateral[i]), "block_length": float(cs.guide_block_length[i])} \
            if cs.guide_lateral[i] > 0 else {}
        j2 = {"angular": float(cs.bearing_angle[i])} if cs.bearing_angle[i] > 0 else {}
        j3 = {"radial": float(cs.revolute_radial[i])} if cs.revolute_radial[i] > 0 else {}
        legs.append({"joints": [j1, j2, j3]})
    return {"legs": legs}


def _check_against_dense(robot_data, pose, spec, tight: float):
    robot = Manipulator.from_dict(robot_data, source="test")
    res = C.certified_pose_errors(robot, ErrorSources.from_dict(spec), pose)
    ref = nsr.dense_search(robot_data, pose, spec)
    for q in C.QUANTITIES:
        up, lo, dense = res.upper[q][0], res.lower[q][0], ref[q]
        assert up >= dense, (q, up, dense)  # never below the true maximum (the dense search attains dense)
        assert (up - dense) / dense <= tight, (q, up, dense)
        assert lo <= up
        # the best feasible value starts at the first-order worst vertex (ties of a zero coefficient broken either
        # way) and ascends wherever the bound is not yet within REFINE_FRACTION * split_gap of it: at least the
        # reference's vertex value, or a stated gap within that fraction
        assert lo >= ref["first_order_vertex"][q] * (1 - 1e-9) or (up - lo) / lo <= C.REFINE_FRACTION * 0.005
        # first-order maxima: the library's against the reference's finite differences
        np.testing.assert_allclose(res.first_order[q][0], ref["first_order"][q], rtol=1e-6)
        assert res.gap[q][0] == pytest.approx((up - lo) / lo, rel=1e-12)
    return res, ref


@pytest.mark.parametrize("name, factor, tight", [("case1", 1, 0.005), ("case2", 1, 0.005), ("all", 1, 0.005),
                                                 ("all", 10, 0.05)])
def test_paper_robot_against_dense_search(name, factor, tight):
    data = Manipulator.preset("aalborg_3ppr").to_dict()
    spec = nsr.scaled_spec(_paper_spec(name), factor)
    res, ref = _check_against_dense(data, PAPER_POSE, spec, tight)
    if factor == 1:  # the paper's clearances: first order below the truth by well under 0.5 %
        for q in C.QUANTITIES:
            assert 0 <= (ref[q] - ref["first_order"][q]) / ref["first_order"][q] < 0.005


def test_paper_format_and_presets_accepted():
    """Robot and clearances as preset names (3-PPR format) give the same numbers as the per-joint objects."""
    a = C.certified_pose_errors("aalborg_3ppr", "case2", PAPER_POSE, search=False)
    b = C.certified_pose_errors(Manipulator.preset("aalborg_3ppr"), ErrorSources.from_dict(_paper_spec("case2")),
                                PAPER_POSE, search=False)
    for q in C.QUANTITIES:
        np.testing.assert_allclose(a.upper[q], b.upper[q], rtol=1e-9)
        assert np.isnan(a.lower[q]).all() and np.isnan(a.gap[q]).all()


def test_worst_configurations_reinserted_in_the_virtual_prototype():
    """The nonlinear maxima are attained: the reported configurations lie in the error set and, closed by the
    library's separate virtual prototype (finite-difference Newton), give the same values."""
    robot = Manipulator.preset("symmetric_3rrr")
    sources = load_clearances("rrr_typical", robot).scaled(5.0)
    poses = np.array([[0.0, 0.0, 0.0], [15.0, -10.0, np.radians(10.0)]])
    res = C.nonlinear_pose_errors(robot, sources, poses)
    sets = res.sets
    for q in C.QUANTITIES:
        d = res.worst[q]
        np.testing.assert_allclose(C.project(sets, d), d, atol=1e-15)  # feasible
        X = joint_displaced_pose(robot, poses, C.to_displacements(sets, d), iterations=12)
        err = X - poses
        err[:, 2] = np.angle(np.exp(1j * err[:, 2]))
        val = np.hypot(err[:, 0], err[:, 1]) if q == "dp" else np.abs(err[:, C.QUANTITIES.index(q)])
        np.testing.assert_allclose(res.lower[q], val, rtol=1e-8)
        assert np.all(res.lower[q] >= res.first_order[q] * (1 - 1e-3))
        assert np.all(res.lower[q] <= res.upper[q])


def test_first_order_part_equals_bounds():
    """The linear part of the certificate is the exact first-order zonotope of pmaccuracy.accuracy.bounds."""
    robot = Manipulator.preset("symmetric_3prr")
    sources = load_clearances("prr_typical", robot)
    poses = np.array([[0.0, 0.0, 0.0], [5.0, 8.0, np.radians(-5.0)]])
    rb = C.remainder_bounds(robot, sources, poses)
    fo = max_pose_errors(robot, sources, poses)
    for q in ("dx", "dy", "dphi", "dp"):
        np.testing.assert_allclose(rb["first_order"][q], getattr(fo, f"{q}_max"), rtol=1e-9)
        assert np.all(rb["upper"][q] >= rb["first_order"][q])


@pytest.mark.slow  # 8-11 s; make test-all (the refusal path is also checked by the CLI test below, fast)
def test_too_large_errors_are_refused():
    """At 300x the paper's case2 some configurations cannot be closed (the independent search's own Newton
    fails on them): no finite bound is returned."""
    robot = Manipulator.preset("aalborg_3ppr")
    big = ErrorSources.from_dict(_paper_spec("case2")).scaled(300.0)
    with pytest.raises(RuntimeError, match="did not converge"):
        nsr.dense_search(robot.to_dict(), [0.0, 0.0, 0.0], nsr.scaled_spec(_paper_spec("case2"), 300), n_random=50,
                         dense=4)
    with pytest.raises(CertificationError, match="pose 0"):
        C.certified_pose_errors(robot, big, [0.0, 0.0, 0.0])
    # the NaN path (a smaller budget of pieces: the refusal above already used the default one)
    res = C.certified_pose_errors(robot, big, [[0.0, 0.0, 0.0]], on_failure="nan", search=False, max_pieces=16)
    assert all(np.isnan(res.upper[q][0]) for q in C.QUANTITIES)
    assert res.reason[0]


@pytest.mark.slow  # about 8 s; make test-all
def test_whole_set_refused_but_pieces_certified_at_100x():
    """At 100x case2 (dx 7.5 % above first order) the whole error set has no certificate, but every configuration
    can be closed: the cut pieces certify it, never below the independent dense search (1.5 % above it at most
    here, with the budget of a refused pose, 3 x 256 pieces)."""
    robot = Manipulator.preset("aalborg_3ppr")
    big = ErrorSources.from_dict(_paper_spec("case2")).scaled(100.0)
    assert C.remainder_bounds(robot, big, np.zeros((1, 3)))["reason"][0]
    res = C.certified_pose_errors(robot, big, [0.0, 0.0, 0.0])
    ref = nsr.dense_search(robot.to_dict(), [0.0, 0.0, 0.0], nsr.scaled_spec(_paper_spec("case2"), 100),
                           n_random=300, dense=8)
    for q in C.QUANTITIES:
        assert ref[q] <= res.upper[q][0] <= 1.05 * ref[q], q


def test_dual_bound_of_a_quadratic_against_sampling():
    """max over S of g.delta + delta^T H delta <= dual_bound (S: interval, disk, rhombus), exact at H = 0."""
    rng = np.random.default_rng(3)
    sets = (C.SourceSet("interval", 0, 0, "turn", 0.002, (0,)), C.SourceSet("disk", 0, 1, "shift", 0.03, (1, 2)),
            C.SourceSet("rhombus", 1, 0, "lateral", 0.004, (3, 4), 30.0),
            C.SourceSet("interval", 2, 0, "dq", 0.01, (5,)))
    eps = np.array([0.002, 0.03, 0.03, 0.004, 2 * 0.004 / 30.0, 0.01])
    # samples: random boundary points of each source (disk circle, rhombus edges, interval ends)
    n = 40000
    d = np.zeros((n, 6))
    d[:, 0] = 0.002 * rng.choice([-1.0, 1.0], n)
    a = rng.uniform(0, 2 * np.pi, n)
    d[:, 1], d[:, 2] = 0.03 * np.cos(a), 0.03 * np.sin(a)
    v = np.array([[0.004, 0.0], [0.0, 2 * 0.004 / 30.0], [-0.004, 0.0], [0.0, -2 * 0.004 / 30.0]])
    k, t = rng.integers(0, 4, n), rng.uniform(size=(n, 1))
    d[:, 3:5] = v[k] + t * (v[(k + 1) % 4] - v[k])
    d[:, 5] = 0.01 * rng.choice([-1.0, 1.0], n)
    for trial in range(4):
        g = rng.normal(size=6) / eps
        np.testing.assert_allclose(C.dual_bound(sets, g[None], np.zeros((1, 6, 6)))[0], C.support(sets, g[None])[0],
                                   rtol=1e-6)
        A = rng.normal(size=(6, 6)) / np.outer(eps, eps) * 10 ** (-trial)
        H = (A + A.T) / 2
        f = lambda x: x @ g + np.einsum("...i,ij,...j->...", x, H, x)  # noqa: E731
        sampled = np.max(f(d))
        # coordinate ascent from the first-order vertex: each source over its dense boundary and interior
        best = C.argsupport(sets, g[None])[0]
        for _ in range(6):
            for cols, pts in (((0,), np.linspace(-0.002, 0.002, 201)[:, None]),
                              ((1, 2), np.concatenate([0.03 * np.column_stack([np.cos(b), np.sin(b)])
                                                       for b in [np.linspace(0, 2 * np.pi, 4000)]])),
                              ((3, 4), np.concatenate([v[i] + np.linspace(0, 1, 1000)[:, None] * (v[(i + 1) % 4] - v[i])
                                                       for i in range(4)])),
                              ((5,), np.linspace(-0.01, 0.01, 201)[:, None])):
                cand = np.repeat(best[None], len(pts), axis=0)
                cand[:, list(cols)] = pts
                best = cand[np.argmax(f(cand))]
        attained = max(sampled, f(best))
        bound = C.dual_bound(sets, g[None], H[None])[0]
        assert bound >= attained
        if trial >= 2:  # small H: tight to second order
            assert bound - attained <= 1e-4 * attained
        # stop values (the branch and bound's targets): still bounds; below a stop above the optimum, and at the
        # first feasible multipliers for a stop below nothing reached
        rough = C.dual_bound(sets, g[None], H[None], refine=False)[0]
        stops = np.array([np.inf, bound * 1.01, (bound + rough) / 2, bound * (1 - 1e-3), -np.inf])
        early = C.dual_bound(sets, np.repeat(g[None], 5, 0), np.repeat(H[None], 5, 0), stop=stops, rtol=1e-5)
        assert np.all(early >= attained) and early[0] == rough
        assert early[1] <= stops[1] and early[2] <= stops[2] and early[4] == pytest.approx(bound, rel=1e-5)


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "pmaccuracy.cli", "bounds", *args], capture_output=True, text=True)


def test_cli_certified_and_nonlinear_json():
    pose = ["--pose", "10", "5", "3"]
    up = json.loads(_cli("--certified", *pose, "--format", "json").stdout)[0]
    lo = json.loads(_cli("--nonlinear", *pose, "--format", "json").stdout)[0]
    keys = ["x", "y", "phi_deg", "dx_max", "dy_max", "dphi_max_deg", "dp_max", "gap_pct"]
    assert list(up) == keys and list(lo) == keys
    assert set(up["gap_pct"]) == {"dx", "dy", "dphi", "dp"}
    res = C.certified_pose_errors("aalborg_3ppr", "case1", PAPER_POSE)
    for key, q in (("dx_max", "dx"), ("dy_max", "dy"), ("dp_max", "dp")):
        assert up[key] == pytest.approx(res.upper[q][0], rel=1e-12)
        assert lo[key] == pytest.approx(res.lower[q][0], rel=1e-12)
        # in percent, as worst prints its gap
        assert up["gap_pct"][q] == pytest.approx(100 * (up[key] - lo[key]) / lo[key], rel=1e-9)
    assert up["dphi_max_deg"] == pytest.approx(np.degrees(res.upper["dphi"][0]), rel=1e-12)
    csv = _cli("--certified", *pose, "--format", "csv").stdout.splitlines()[0].split(",")
    assert csv[-4:] == ["gap_pct.dx", "gap_pct.dy", "gap_pct.dphi", "gap_pct.dp"]


@pytest.mark.parametrize("extra, word", [(["--method", "slsqp"], "slsqp"), (["--nonlinear"], "exclude"),
                                         (["--details"], "details")])
def test_cli_refusals(extra, word):
    out = _cli("--certified", "--pose", "0", "0", "0", *extra)
    assert out.returncode == 2
    assert len(out.stderr.strip().splitlines()) == 1 and word in out.stderr


def _scaled_file(tmp_path, factor: float):
    """The paper's case2 times ``factor`` as a per-joint clearance file."""
    spec = nsr.scaled_spec(_paper_spec("case2"), factor)
    lines = ['name = "huge"']
    for leg in spec["legs"]:
        joints = ", ".join("{" + ", ".join(f"{k} = {v!r}" for k, v in j.items()) + "}" for j in leg["joints"])
        lines += ["[[legs]]", f"joints = [{joints}]"]
    path = tmp_path / f"huge{factor:g}.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_cli_max_pieces(tmp_path):
    """At 100x only the cut pieces certify the pose: without the branch and bound (``--max-pieces 1``) exit 2
    with one line, with it (3 x 32 pieces: enough) the certified values; the option needs --certified or
    --nonlinear."""
    path = _scaled_file(tmp_path, 100.0)
    base = ("--clearances", str(path), "--pose", "0", "0", "0", "--format", "json")
    out = _cli("--certified", "--max-pieces", "1", *base)
    errors = [line for line in out.stderr.strip().splitlines() if ": warning: " not in line]
    assert out.returncode == 2 and len(errors) == 1 and "pose 0" in errors[0]
    out = _cli("--certified", "--max-pieces", "32", *base)
    assert out.returncode == 0, out.stderr
    rec = json.loads(out.stdout)[0]
    assert all(np.isfinite(rec[k]) for k in ("dx_max", "dy_max", "dphi_max_deg", "dp_max"))
    out = _cli("--max-pieces", "5", *base)
    assert out.returncode == 2 and "--max-pieces needs --certified" in out.stderr
    out = _cli("--certified", "--max-pieces", "0", *base)
    assert out.returncode == 2 and "--max-pieces" in out.stderr


def test_cli_uncertifiable_pose_exits_2(tmp_path):
    path = _scaled_file(tmp_path, 300.0)  # cannot be closed everywhere (test above)
    out = _cli("--certified", "--clearances", str(path), "--pose", "0", "0", "0", "--max-pieces", "16")
    assert out.returncode == 2
    errors = [line for line in out.stderr.strip().splitlines() if ": warning: " not in line]  # plausibility
    assert len(errors) == 1 and "pose 0" in errors[0] and "Traceback" not in out.stderr


def test_batch_with_certified_and_refused_poses():
    """At 50x case2 some poses are certified and others not: NaN with a reason only where refused, the
    certified ones as computed alone, and the nonlinear maxima below every certified bound."""
    from pmaccuracy.model.clearances import ClearanceSet

    poses = np.array([[0.0, 0.0, 0.0], [-30.0, -20.0, np.radians(-20.0)], [-10.0, 0.0, np.radians(10.0)]])
    cs = ClearanceSet.load("case2").scaled(50.0)
    res = C.certified_pose_errors("aalborg_3ppr", cs, poses, on_failure="nan", allow_outside=True, split=0)
    refused = res.reason != ""
    assert refused.tolist() == [False, True, False]
    for q in C.QUANTITIES:
        assert np.isnan(res.upper[q][refused]).all()
        assert np.all(res.upper[q][~refused] >= res.lower[q][~refused])
        assert np.all(res.lower[q] >= res.first_order[q] * (1 - 1e-6))  # attained even where not certified
    alone = C.certified_pose_errors("aalborg_3ppr", cs, poses[[0]], allow_outside=True, split=0)
    for q in C.QUANTITIES:
        np.testing.assert_allclose(res.upper[q][0], alone.upper[q][0], rtol=1e-3)
    # cutting the error set in pieces (the default) certifies more, and never raises a bound
    cut = C.certified_pose_errors("aalborg_3ppr", cs, poses, on_failure="nan", allow_outside=True)
    assert not (cut.reason != "")[~refused].any()
    for q in C.QUANTITIES:
        ok = cut.reason == ""
        assert np.all(cut.upper[q][ok] >= cut.lower[q][ok])
        assert np.all(cut.upper[q][~refused] <= res.upper[q][~refused])


def test_no_error_source_gives_zero():
    res = C.certified_pose_errors("aalborg_3ppr", "none", PAPER_POSE)
    for q in C.QUANTITIES:
        assert res.upper[q][0] == 0.0 and res.lower[q][0] == 0.0 and res.gap[q][0] == 0.0


def test_cut_pieces_cover_the_source_sets():
    """The branch and bound's cuts: every sampled point of an interval or a lateral rhombus ``|L tau +- 2 sigma|
    <= 2 eps`` lies in one of the children (same kind, the children's half-width, about their centres)."""
    rng = np.random.default_rng(5)
    eps, L = 0.004, 30.0
    for s in (C.SourceSet("interval", 0, 0, "turn", eps, (0,)),
              C.SourceSet("rhombus", 0, 0, "lateral", eps, (0, 1), L)):
        kids = C._children(s, np.zeros(len(s.cols)))
        centres, half = np.array([c for _, c in kids]), kids[0][0].eps
        assert all(k.kind == s.kind and k.eps == half for k, _ in kids)
        if s.kind == "interval":
            pts = rng.uniform(-eps, eps, (5000, 1))
            inside = np.abs(pts[:, None, 0] - centres[None, :, 0]) <= half * (1 + 1e-12)
        else:
            # uniform in the square of the edge coordinates a = (2 sigma + L tau) / (2 eps), b = (2 sigma - L tau)
            # / (2 eps), mapped back to (sigma, tau)
            ab = rng.uniform(-1, 1, (5000, 2))
            pts = np.column_stack([eps * (ab[:, 0] + ab[:, 1]) / 2, eps * (ab[:, 0] - ab[:, 1]) / L])
            d = pts[:, None, :] - centres[None, :, :]
            inside = ((np.abs(L * d[..., 1] + 2 * d[..., 0]) <= 2 * half * (1 + 1e-12))
                      & (np.abs(L * d[..., 1] - 2 * d[..., 0]) <= 2 * half * (1 + 1e-12)))
        assert np.all(np.any(inside, axis=1)), s.kind
        assert half == eps / 2


def _in_rect(piece, centre, pts):
    """Plain test of ``pts`` ``(P, 2)`` inside a rect piece: its axes written out here."""
    d = pts - centre
    ur = np.array([np.cos(piece.angle), np.sin(piece.angle)])
    ut = np.array([-np.sin(piece.angle), np.cos(piece.angle)])
    return (np.abs(d @ ur) <= piece.eps * (1 + 1e-12)) & (np.abs(d @ ut) <= piece.eps_t * (1 + 1e-12))


def _in_sector(piece, pts):
    theta, half, r1, r2, ox, oy = piece.sector
    d = pts - np.array([ox, oy])
    r = np.hypot(d[:, 0], d[:, 1])
    t = np.angle(np.exp(1j * (np.arctan2(d[:, 1], d[:, 0]) - theta)))
    return (r >= r1 * (1 - 1e-12)) & (r <= r2 * (1 + 1e-12)) & (np.abs(t) <= half * (1 + 1e-12))


def test_cut_disks_are_covered_by_sector_rectangles():
    """A disk's cut: every point of the disk lies in one child's sector and every sector point in the child's
    rectangle (the set that is certified); three more levels of cuts keep covering (uniform sampling)."""
    rng = np.random.default_rng(8)
    eps = 0.3
    disk = C.SourceSet("disk", 0, 0, "shift", eps, (0, 1))
    r, t = eps * np.sqrt(rng.uniform(size=20000)), rng.uniform(0, 2 * np.pi, 20000)
    pts = np.column_stack([r * np.cos(t), r * np.sin(t)])
    level = C._children(disk, np.zeros(2))
    assert len(level) == C.DISK_SECTORS and all(k.kind == "rect" for k, _ in level)
    for depth in range(4):
        in_sector = np.stack([_in_sector(k, pts) for k, _ in level])
        assert np.all(in_sector.any(axis=0)), depth  # the sectors cover the disk
        for (k, c), mask in zip(level, in_sector):
            assert np.all(_in_rect(k, c, pts[mask])), depth  # each rectangle holds its sector
            assert k.eps <= eps and k.eps_t <= eps
        level = [kid for k, c in level for kid in C._children(k, c)]
    # the pieces shrink: after four levels no rectangle is wider than half the radius
    assert max(max(k.eps, k.eps_t) for k, _ in level) <= eps / 2


def test_rect_support_constraints_and_projection():
    """A rect piece's support function and maximizer, quadratic constraints and projection against sampling."""
    rng = np.random.default_rng(9)
    disk = C.SourceSet("disk", 0, 0, "shift", 0.2, (0, 1))
    piece, centre = C.sector_rect(disk, 0.7, np.pi / 8, 0.05, 0.2, (0.0, 0.0))
    sets = (piece,)
    ur = np.array([np.cos(piece.angle), np.sin(piece.angle)])
    ut = np.array([-np.sin(piece.angle), np.cos(piece.angle)])
    a, b = rng.uniform(-1, 1, (20000, 1)), rng.uniform(-1, 1, (20000, 1))
    a, b = np.concatenate([a, [[1], [1], [-1], [-1]]]), np.concatenate([b, [[1], [-1], [1], [-1]]])  # + corners
    inside = a * piece.eps * ur + b * piece.eps_t * ut  # about the piece's centre
    for c in rng.normal(size=(20, 2)):
        h = C.support(sets, c[None])[0]
        assert abs(h - np.max(inside @ c)) <= 1e-12
        arg = C.argsupport(sets, c[None])[0]
        assert abs(arg @ c - h) <= 1e-12 and np.all(_in_rect(piece, np.zeros(2), arg[None]))
    P = C.constraint_matrices(sets)
    q = np.einsum("pi,kij,pj->pk", inside, P, inside)
    assert np.all(q <= 1 + 1e-9)
    outside = inside * 1.05
    far = ~_in_rect(piece, np.zeros(2), outside)
    assert np.all(np.max(np.einsum("pi,kij,pj->pk", outside[far], P, outside[far]), axis=1) > 1)
    proj = C.project(sets, rng.normal(scale=0.5, size=(500, 2)))
    assert np.all(_in_rect(piece, np.zeros(2), proj))
    assert C._contains_zero(sets, np.zeros((1, 2)))[0] and not C._contains_zero(sets, (2 * piece.eps * ur)[None])[0]


def test_dual_bound_reaches_the_sdp_optimum_on_badly_scaled_sets():
    """The dual bound of max g.delta + delta^T H delta over sets whose half-widths span 0.0007 rad to 0.45 mm
    against the same Lagrangian dual solved here as an SDP (cvxpy with SCS, a first-order solver the library
    does not use, in parameters scaled here) and against sampling: never below the sampled maximum, never more
    than 0.1 % above the SDP optimum. Among these cases is the hard one (the optimum's Lambda - H singular),
    where the interior-point steps alone stopped 5.5 % above the optimum."""
    import cvxpy as cp

    rng = np.random.default_rng(11)
    sets = (C.SourceSet("disk", 0, 0, "shift", 0.4, (0, 1)), C.SourceSet("interval", 0, 0, "dq", 0.002, (2,)),
            C.SourceSet("disk", 1, 1, "shift", 0.3, (3, 4)), C.SourceSet("interval", 1, 0, "turn", 0.004, (5,)),
            C.SourceSet("disk", 2, 2, "shift", 0.2, (6, 7)), C.SourceSet("disk", 2, 1, "shift", 0.45, (8, 9)),
            C.SourceSet("interval", 2, 0, "dq", 0.0007, (10,)))
    n = 11
    scale = np.array([0.4, 0.4, 0.002, 0.3, 0.3, 0.004, 0.2, 0.2, 0.45, 0.45, 0.0007])
    P = C.constraint_matrices(sets)
    Ps = scale[None, :, None] * P * scale[None, None, :]
    for trial in range(6):
        gs = rng.normal(size=n)
        A = rng.normal(size=(n, n))
        Hs = 0.2 * (A + A.T)  # indefinite, comparable to the linear part: far from first order
        g, H = gs / scale, Hs / scale[:, None] / scale[None, :]
        ours = C.dual_bound(sets, g[None], H[None])[0]
        lam, t = cp.Variable(P.shape[0], nonneg=True), cp.Variable()
        L = sum(lam[k] * Ps[k] for k in range(P.shape[0])) - Hs
        col = gs[:, None] / 2
        Mx = cp.bmat([[L, -col], [-col.T, cp.reshape(t, (1, 1), order="C")]])
        prob = cp.Problem(cp.Minimize(cp.sum(lam) + t), [(Mx + Mx.T) / 2 >> 0])
        prob.solve(solver="SCS", eps=1e-9, max_iters=200000)
        assert prob.status in ("optimal", "optimal_inaccurate")
        # successive linearization from many extreme points: attained values of the quadratic
        best = -np.inf
        for _ in range(100):
            x = C.argsupport(sets, rng.normal(size=(1, n)))[0]
            for _ in range(30):
                x = C.argsupport(sets, (g + 2 * H @ x)[None])[0]
            best = max(best, g @ x + x @ H @ x)
        assert best <= ours * (1 + 1e-9), trial
        assert ours <= prob.value * (1 + 1e-3) + 1e-9, (trial, ours, prob.value)
