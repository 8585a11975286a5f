"""Interval arithmetic and the interval closed forms against brute-force sampling.

Every enclosure must contain the values of the function at random points of its
arguments (the points are evaluated with plain numpy, or with the legs' own
inverse kinematics :meth:`Chain.state` and :func:`max_pose_errors`, which the
interval code does not use).
"""

from __future__ import annotations

import numpy as np
import pytest

from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.accuracy.global_worst import as_sources, leg_branches
from pmaccuracy.accuracy.interval import box_maxima, leg_box_state
from pmaccuracy.numerics.interval import Cv, Iv, angle_meets_range, cv_angle, iv_abs, iv_arccos, iv_cos, iv_sin, iv_sqr, iv_sqrt, v_cv
from pmaccuracy.kinematics import inverse_kinematics
from pmaccuracy.io.resolve import load_clearances
from pmaccuracy.kinematics.workspace import home_pose

RNG = np.random.default_rng(7)


def random_intervals(n=400, scale=3.0):
    a = RNG.uniform(-scale, scale, n)
    b = a + RNG.exponential(scale / 2, n) * (RNG.uniform(size=n) > 0.1)   # some point intervals
    return Iv(a, b)


def samples(iv: Iv, k=200):
    t = RNG.uniform(size=(k,) + iv.lo.shape)
    t[0], t[1] = 0.0, 1.0
    return iv.lo + t * (iv.hi - iv.lo)


def contains(iv: Iv, values, rel=1e-12):
    pad = rel * (1 + np.maximum(np.abs(iv.lo), np.abs(iv.hi)))
    return np.all((values >= iv.lo - pad) & (values <= iv.hi + pad))


@pytest.mark.parametrize("op,fn", [
    (lambda a, b: a + b, lambda a, b: a + b),
    (lambda a, b: a - b, lambda a, b: a - b),
    (lambda a, b: a * b, lambda a, b: a * b),
    (lambda a, b: a / b, lambda a, b: a / b),
    (lambda a, b: iv_sqr(a) - b * 2.5, lambda a, b: a * a - 2.5 * b),
])
def test_binary_operations_enclose_samples(op, fn):
    a, b = random_intervals(), random_intervals()
    out = op(a, b)
    assert contains(out, fn(samples(a), samples(b)))


@pytest.mark.parametrize("op,fn,dom", [
    (iv_abs, np.abs, None), (iv_cos, np.cos, None), (iv_sin, np.sin, None),
    (iv_sqrt, np.sqrt, (0, 9)), (iv_arccos, np.arccos, (-1, 1)),
])
def test_unary_operations_enclose_samples(op, fn, dom):
    a = random_intervals(scale=8.0)
    if dom is not None:
        a = Iv(np.clip(a.lo, *dom), np.clip(a.hi, *dom))
    assert contains(op(a), fn(samples(a)))


def test_cos_is_exact_for_monotone_pieces_and_full_turns():
    out = iv_cos(Iv(np.array([0.1, -0.2, 0.0]), np.array([0.5, 0.2, 7.0])))
    assert np.allclose(out.lo, [np.cos(0.5), np.cos(0.2), -1.0]) and np.allclose(out.hi, [np.cos(0.1), 1.0, 1.0])


def test_complex_angle_encloses_samples_including_the_negative_real_axis():
    re, im = random_intervals(scale=2.0), random_intervals(scale=2.0)
    re = Iv(re.lo - 2.5, re.hi - 2.5)           # many rectangles left of the origin, crossing the -x axis
    ang = cv_angle(Cv(re, im))
    z = samples(re) + 1j * samples(im)
    a = np.angle(z)
    shifted = np.where(a < ang.lo - 1e-12, a + 2 * np.pi, a)   # the samples' angles, up to a turn
    assert contains(ang, shifted)
    off = ~(re.contains_zero() & im.contains_zero())
    assert off.sum() > 100 and np.all((ang.hi - ang.lo)[off] < 2 * np.pi)   # informative off the origin


def test_angle_range_test_is_modulo_two_pi():
    t = Iv(np.array([0.1, 3.0, -7.0]), np.array([0.2, 3.1, -6.9]))
    # [0.1, 0.2] meets [-0.5, 0.15]; [3, 3.1] + 2pi k never meets [-0.5, 0.15]; -7 + 2pi*1 = -0.72 .. -0.62: no
    assert angle_meets_range(t, -0.5, 0.15, 0.0).tolist() == [True, False, False]
    assert angle_meets_range(t, -0.75, -0.7, 0.0).tolist() == [False, False, True]


ROBOTS = [("aalborg_3ppr", "case2"), ("symmetric_3ppr", "all"), ("symmetric_3rpr", "rpr_typical"),
          ("symmetric_3rrr", "rrr_typical"), ("symmetric_3prr", "prr_typical")]


def _boxes_and_points(robot, half=(3.0, 3.0, np.radians(1.0)), n_boxes=40, k=60):
    home = home_pose(robot)
    centres = home + RNG.uniform(-1, 1, (n_boxes, 3)) * np.array([25.0, 25.0, np.radians(8)])
    h = np.array(half)
    boxes = np.column_stack([centres[:, 0] - h[0], centres[:, 0] + h[0], centres[:, 1] - h[1],
                             centres[:, 1] + h[1], centres[:, 2] - h[2], centres[:, 2] + h[2]])
    pts = centres[:, None, :] + RNG.uniform(-1, 1, (n_boxes, k, 3)) * h
    pts[:, 0] = centres - h          # a corner of every box
    return boxes, pts


@pytest.mark.parametrize("rname,cname", ROBOTS)
def test_leg_enclosures_contain_the_legs_state(rname, cname):
    robot = Manipulator.preset(rname)
    boxes, pts = _boxes_and_points(robot)
    sigmas = leg_branches(robot, home_pose(robot))
    x, y, phi = Iv(boxes[:, 0], boxes[:, 1]), Iv(boxes[:, 2], boxes[:, 3]), Iv(boxes[:, 4], boxes[:, 5])
    inside = inverse_kinematics(robot, pts.reshape(-1, 3)).within_limits.reshape(pts.shape[:2])
    for chain, sigma in zip(robot.chains, sigmas):
        lb = leg_box_state(chain, x, y, phi, sigma)
        st = chain.state(pts.reshape(-1, 3))
        f = np.broadcast_to(st.f, (inside.size,)).reshape(inside.shape)
        m_P = np.broadcast_to(st.m_P, (inside.size,)).reshape(inside.shape)
        fc = v_cv(lb.f, lb.var)
        for b in range(boxes.shape[0]):
            ok = inside[b]
            if not ok.any():
                continue
            assert not lb.infeasible[b]
            sub = lambda iv: Iv(np.broadcast_to(iv.lo, (boxes.shape[0],))[b],  # noqa: E731
                                np.broadcast_to(iv.hi, (boxes.shape[0],))[b])
            assert contains(sub(fc.re), f[b, ok].real, 1e-9) and contains(sub(fc.im), f[b, ok].imag, 1e-9)
            assert contains(sub(lb.m_P), m_P[b, ok], 1e-9)
            q = st.q.reshape(inside.shape + (3,))[b, ok]
            for k, joint in enumerate(chain.joints):
                if joint.kind == "P":
                    assert contains(sub(lb.q[k]), q[:, k], 1e-9)


@pytest.mark.parametrize("rname,cname", ROBOTS)
def test_box_maxima_bound_every_sample_and_flag_only_empty_boxes(rname, cname):
    robot = Manipulator.preset(rname)
    cl = load_clearances(cname, robot)
    boxes, pts = _boxes_and_points(robot)
    upper, infeasible, _ = box_maxima(robot, as_sources(robot, cl), boxes, leg_branches(robot, home_pose(robot)))
    flat = pts.reshape(-1, 3)
    inside = inverse_kinematics(robot, flat).within_limits
    vals = np.full((flat.shape[0], 4), -np.inf)
    b = max_pose_errors(robot, cl, flat[inside], singular="nan", max_condition=np.inf)
    vals[inside] = np.column_stack([b.dx_max, b.dy_max, b.dphi_max, b.dp_max])
    best = np.max(vals.reshape(pts.shape[:2] + (4,)), axis=1)
    has = np.isfinite(best[:, 0])
    assert has.sum() >= 10
    assert not np.any(infeasible & has)
    assert np.all(upper[has] >= best[has] * (1 - 1e-9))


def test_point_boxes_reproduce_the_exact_maxima():
    robot = Manipulator.preset("aalborg_3ppr")
    cl = load_clearances("case2", robot)
    p = home_pose(robot) + RNG.uniform(-1, 1, (50, 3)) * np.array([20, 20, 0.2])
    p = p[inverse_kinematics(robot, p).within_limits]
    boxes = np.repeat(p, 2, axis=1)
    upper, infeasible, _ = box_maxima(robot, as_sources(robot, cl), boxes, (1.0, 1.0, 1.0))
    b = max_pose_errors(robot, cl, p)
    ref = np.column_stack([b.dx_max, b.dy_max, b.dphi_max, b.dp_max])
    assert not infeasible.any()
    np.testing.assert_allclose(upper, ref, rtol=1e-9)


def test_boxes_outside_the_workspace_are_proven_empty():
    robot = Manipulator.preset("aalborg_3ppr")
    boxes = np.array([[300.0, 310.0, 300.0, 310.0, 0.0, 0.1], [-5.0, 5.0, -5.0, 5.0, 0.0, 0.0]])
    _, infeasible, _ = box_maxima(robot, as_sources(robot, load_clearances("case1", robot)), boxes, (1.0, 1.0, 1.0))
    assert infeasible.tolist() == [True, False]


def _serial_singular_poses(phi):
    """3-PRR poses where a distal link is normal to its guide (the leg's serial singularity, a workspace
    boundary), built from the robot file's numbers: carriage C = G + s u, revolute A = C + 180 n (n normal to
    u), and P = A - R(phi) b for the platform point b; both normals, a few carriage positions."""
    guides = [((-173.20508075688772, -100.0), 300.0, (-43.30127018922193, -25.0)),
              ((173.20508075688772, -100.0), 60.0, (43.30127018922193, -25.0)),
              ((0.0, 200.0), 180.0, (0.0, 50.0))]
    out = []
    for (gx, gy), deg, (bx, by) in guides:
        u = np.exp(1j * np.radians(deg))
        for s in (-190.0, -150.0, -100.0, -50.0, -13.0, -1.0):
            for sign in (1j, -1j):
                a = complex(gx, gy) + s * u + 180.0 * sign * u
                p = a - np.exp(1j * phi) * complex(bx, by)
                out.append((p.real, p.imag, phi))
    return np.array(out)


def test_box_maxima_tight_and_valid_at_the_serial_singular_boundary():
    # boxes of 4 um straddling a leg's serial singularity: the turning angle varies like the square root of
    # the distance there; the bounds must still enclose every sampled value and, split in that angle, stay
    # within 0.5 % of the best sample (they were 1-2 % above it, which stalled the branch and bound)
    robot = Manipulator.preset("symmetric_3prr")
    cl = load_clearances("prr_typical", robot)
    phi = np.radians(-5.0)
    c = _serial_singular_poses(phi)
    h, hp = 0.002, 4e-5
    boxes = np.column_stack([c[:, 0] - h, c[:, 0] + h, c[:, 1] - h, c[:, 1] + h, c[:, 2] - hp, c[:, 2] + hp])
    g = np.stack(np.meshgrid(np.linspace(-1, 1, 15), np.linspace(-1, 1, 15), np.linspace(-1, 1, 3),
                             indexing="ij"), -1).reshape(-1, 3) * np.array([h, h, hp])
    pts = c[:, None, :] + g[None]
    flat = pts.reshape(-1, 3)
    inside = inverse_kinematics(robot, flat).within_limits
    vals = np.full((flat.shape[0], 4), -np.inf)
    b = max_pose_errors(robot, cl, flat[inside], singular="nan", max_condition=np.inf)
    vals[inside] = np.column_stack([b.dx_max, b.dy_max, b.dphi_max, b.dp_max])
    best = np.max(vals.reshape(pts.shape[:2] + (4,)), axis=1)
    part = inside.reshape(pts.shape[:2]).mean(axis=1)
    straddle = (part > 0.05) & (part < 0.95)
    assert straddle.sum() >= 4
    upper, infeasible, _ = box_maxima(robot, as_sources(robot, cl), boxes,
                                      leg_branches(robot, np.array([20.0, 5.0, phi])))
    has = np.isfinite(best[:, 0])
    assert not np.any(infeasible & has)
    assert np.all(upper[has] >= best[has] * (1 - 1e-9))
    assert np.all(upper[straddle] <= best[straddle] * 1.005)


# ------------------------------------------------------------------- derivatives (mean-value form)
from pmaccuracy.numerics.interval import GIv, iv_arcsin, iv_max  # noqa: E402


def _gx(a: Iv) -> GIv:
    return GIv(a.lo, a.hi, (Iv(1.0), Iv(0.0), Iv(0.0)))


def _fd(fn, x, h=1e-6):
    return (fn(x + h) - fn(x - h)) / (2 * h)


@pytest.mark.parametrize("op,fn,dom", [
    (lambda a: iv_sqr(a) - a * 2.5, lambda x: x * x - 2.5 * x, None),
    (lambda a: a * iv_cos(a * 3.0) + iv_sin(a), lambda x: x * np.cos(3 * x) + np.sin(x), None),
    (lambda a: iv_sqrt(a) / (a + 1.0), lambda x: np.sqrt(x) / (x + 1), (0.5, 9)),
    (lambda a: iv_arccos(a * 0.5) + iv_arcsin(a * 0.3), lambda x: np.arccos(x / 2) + np.arcsin(0.3 * x), (-1.5, 1.5)),
    (lambda a: iv_abs(a - 0.3) + iv_max(a, 1.0 - a), lambda x: np.abs(x - 0.3) + np.maximum(x, 1 - x), None),
    (lambda a: cv_angle(Cv(a, iv_sqr(a) + 2.0)), lambda x: np.arctan2(x * x + 2, x), None),
])
def test_derivative_enclosures_contain_finite_differences(op, fn, dom):
    a = random_intervals(scale=4.0)
    if dom is not None:
        a = Iv(np.clip(a.lo, *dom), np.clip(a.hi, *dom))
    out = op(_gx(a))
    assert contains(Iv(out.lo, out.hi), fn(samples(a)))                  # values still enclosed
    x = samples(a, 50)
    d = out.d[0]
    # finite differences at interior points (abs and max have kinks: their one-sided slopes are in the hull)
    assert contains(Iv(d.lo - 1e-5, d.hi + 1e-5), _fd(fn, x))
    assert np.all(out.d[1].lo == 0) and np.all(out.d[2].hi == 0)


def test_a_cut_or_a_square_root_at_zero_makes_the_derivative_unknown():
    from pmaccuracy.numerics.interval import iv_intersect
    a = _gx(Iv(np.array([0.0, 1.0, -1.0]), np.array([2.0, 2.0, 0.5])))
    cut = iv_intersect(a, 0.5, 10.0)
    assert np.isinf(cut.d[0].hi[0]) and np.isfinite(cut.d[0].hi[1])      # [0, 2] was cut, [1, 2] was not
    root = iv_sqrt(a)
    assert np.isinf(root.d[0].hi[0]) and np.isfinite(root.d[0].hi[1])


def _random_robot(kind, seed):
    import error_reference as eref
    import planar_reference as pref
    from pmaccuracy.model.sources import ErrorSources
    rng = np.random.default_rng(seed)
    data, nominal = {"rpr": pref.random_rpr, "rrr": pref.random_rrr, "prr": pref.random_prr}[kind](rng)
    clear, _ = eref.random_clearances(rng, eref.load_robot(data))
    return Manipulator.from_dict(data, source="random"), ErrorSources.from_dict(clear), nominal


@pytest.mark.parametrize("kind,seed", [("rpr", 7), ("rrr", 1), ("prr", 2)])
def test_box_slopes_bound_finite_differences_of_the_exact_maxima(kind, seed):
    from pmaccuracy.accuracy.interval import box_maxima_once
    robot, src, nom = _random_robot(kind, seed)
    half = np.array([0.5, 0.5, np.radians(0.5)])
    centres = nom + RNG.uniform(-4, 4, (12, 3)) * np.array([1, 1, np.radians(1)])
    boxes = np.column_stack([centres - half, centres + half])[:, [0, 3, 1, 4, 2, 5]]
    sig = leg_branches(robot, nom)
    _, infeasible, _, _, slopes, _, _ = box_maxima_once(robot, src, boxes, sig, gradients=True)
    assert np.isfinite(slopes).all() and not infeasible.any()
    pts = centres[:, None, :] + RNG.uniform(-0.9, 0.9, (12, 20, 3)) * half
    for j, h in enumerate((1e-5, 1e-5, 1e-7)):
        step = np.zeros(3)
        step[j] = h
        plus = max_pose_errors(robot, src, (pts + step).reshape(-1, 3))
        minus = max_pose_errors(robot, src, (pts - step).reshape(-1, 3))
        fd = np.column_stack([(getattr(plus, f) - getattr(minus, f)) / (2 * h)
                              for f in ("dx_max", "dy_max", "dphi_max", "dp_max")]).reshape(12, 20, 4)
        bound = slopes[:, None, :, j]
        assert np.all(np.abs(fd) <= bound * (1 + 1e-4) + 1e-9), (kind, j)


@pytest.mark.parametrize("kind,seed", [("rpr", 7), ("rrr", 0)])
def test_mean_value_form_is_second_order_and_valid(kind, seed):
    # boxes of width w inside the region: the natural enclosure is ~0.7-0.8 % above the sampled maximum per
    # 0.1 mm (and 0.1 deg), linear in w; the mean-value form is far below that and shrinks like w^2
    robot, src, nom = _random_robot(kind, seed)
    sig = leg_branches(robot, nom)
    over = []
    for w in (0.4, 0.1):
        h = np.array([w, w, np.radians(w)])
        lo = nom + np.array([1.0, -2.0, 0.01])
        box = np.array([[lo[0], lo[0] + h[0], lo[1], lo[1] + h[1], lo[2], lo[2] + h[2]]])
        up, inf, _ = box_maxima(robot, src, box, sig)
        g = np.linspace(0, 1, 7)
        pts = np.stack(np.meshgrid(*(lo[j] + g * h[j] for j in range(3)), indexing="ij"), -1).reshape(-1, 3)
        b = max_pose_errors(robot, src, pts)
        best = np.max(np.column_stack([b.dx_max, b.dy_max, b.dphi_max, b.dp_max]), axis=0)
        assert np.all(up[0] >= best * (1 - 1e-12))
        over.append(np.max(up[0] / best - 1))
    assert over[1] < 3e-4 and over[1] < over[0] / 8


@pytest.mark.parametrize("kind,seed", [("rpr", 3), ("rrr", 4), ("prr", 1), ("chain", 2), ("chain", 5)])
def test_box_bounds_never_below_samples_on_random_robots(kind, seed):
    # boxes of 0.05-8 mm and 0.05-8 deg about random poses near the nominal one, many straddling the edge of
    # the workspace: the bound (the smaller of the natural enclosure and the mean-value form) must never be
    # below the exact maxima at sampled reachable poses of the box
    import error_reference as eref
    import planar_reference as pref
    from pmaccuracy.accuracy.interval import box_bounds
    from pmaccuracy.model.sources import ErrorSources
    rng = np.random.default_rng(100 + seed)
    gen = {"rpr": pref.random_rpr, "rrr": pref.random_rrr, "prr": pref.random_prr, "chain": pref.random_chain}
    data, nom = gen[kind](np.random.default_rng(seed))
    robot = Manipulator.from_dict(data, source="random")
    src = ErrorSources.from_dict(eref.random_clearances(np.random.default_rng(seed), eref.load_robot(data))[0])
    n = 60
    half = np.exp(rng.uniform(np.log(0.025), np.log(4.0), (n, 1))) * np.array([1.0, 1.0, np.radians(1.0)])
    centres = nom + rng.uniform(-1, 1, (n, 3)) * np.array([25.0, 25.0, np.radians(12)])
    boxes = np.column_stack([centres - half, centres + half])[:, [0, 3, 1, 4, 2, 5]]
    upper, infeasible, _, share = box_bounds(robot, src, boxes, leg_branches(robot, nom))
    pts = centres[:, None, :] + rng.uniform(-1, 1, (n, 150, 3)) * half[:, None, :]
    pts[:, :8] = centres[:, None, :] + np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T * half[:, None, :]
    flat = pts.reshape(-1, 3)
    inside = inverse_kinematics(robot, flat).within_limits
    vals = np.full((flat.shape[0], 4), -np.inf)
    b = max_pose_errors(robot, src, flat[inside], singular="nan", max_condition=np.inf)
    vals[inside] = np.nan_to_num(np.column_stack([b.dx_max, b.dy_max, b.dphi_max, b.dp_max]), nan=-np.inf)
    best = np.max(vals.reshape(n, 150, 4), axis=1)
    has = np.isfinite(best[:, 0])
    assert has.sum() >= 10
    assert not np.any(infeasible & has)
    assert np.all(upper[has] >= best[has] * (1 - 1e-9))
    assert np.any(np.isfinite(share))   # the mean-value form took part
