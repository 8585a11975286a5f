"""Constant-orientation workspace (paper Sec. 3, Fig. 3).

Expected figures come from the reference file (docs/guide/default-robot.md)
or are derived by hand from the leg geometry; the general checks compare the
polygon with the inverse kinematics (Eq. 2a, 2b) point by point.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings

from conftest import manipulators, random_manipulator
from pmaccuracy.errors import EmptyWorkspaceError
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.kinematics import inverse_kinematics, require_within_limits
from pmaccuracy.kinematics.workspace import Workspace, constant_orientation_workspace, grid_search_workspace, leg_box, plot_workspaces, save_comparison_figure, save_workspace_figure

SIN60 = np.sqrt(3) / 2


def shoelace(vertices):
    x, y = np.asarray(vertices).T
    return 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)


def _with_ranges(robot: Manipulator, leg: int, **ranges) -> Manipulator:
    legs = list(robot.legs)
    legs[leg] = dataclasses.replace(legs[leg], **ranges)
    return Manipulator(legs=tuple(legs), name=robot.name)


# ----------------------------------------------------------------------------------- reference figures
def test_aalborg_phi0_is_the_50mm_square(aalborg):
    ws = constant_orientation_workspace(aalborg, 0.0)
    assert not ws.is_empty
    assert ws.area == pytest.approx(2500.0, abs=1e-6)
    np.testing.assert_allclose(ws.bounds, [[-25, 25], [-25, 25]], atol=1e-9)
    assert ws.vertices.shape == (4, 2)
    np.testing.assert_allclose(np.sort(np.abs(ws.vertices), axis=0), np.full((4, 2), 25.0), atol=1e-9)


def test_aalborg_phi30_reference(aalborg):
    """Reference: x in [-10, 40], y in [-14.02, 10], about 1201 mm^2 (y_min = -40 + 30 sin 60)."""
    ws = constant_orientation_workspace(aalborg, np.radians(30))
    (xmin, xmax), (ymin, ymax) = ws.bounds
    assert (xmin, xmax) == (pytest.approx(-10, abs=1e-9), pytest.approx(40, abs=1e-9))
    assert ymin == pytest.approx(-14.02, abs=0.01)
    assert ymin == pytest.approx(-40 + 30 * SIN60, abs=1e-9)
    assert ymax == pytest.approx(10, abs=1e-9)
    assert ws.area == pytest.approx(1201, abs=1.0)
    assert ws.area == pytest.approx(50 * (50 - 30 * SIN60), abs=1e-6)


def test_aalborg_mirror_symmetry(aalborg):
    """Legs 1 and 2 are mirror images in the y-axis and leg 3 lies on it: W(-phi) = mirror of W(phi)."""
    for deg in (10, 30, 45):
        plus = constant_orientation_workspace(aalborg, np.radians(deg))
        minus = constant_orientation_workspace(aalborg, np.radians(-deg))
        assert minus.area == pytest.approx(plus.area, rel=1e-12)
        mirrored = plus.vertices * [-1, 1]
        d = np.linalg.norm(minus.vertices[:, None] - mirrored[None], axis=-1)
        assert np.all(d.min(axis=1) < 1e-9) and np.all(d.min(axis=0) < 1e-9)
    minus30 = constant_orientation_workspace(aalborg, np.radians(-30))
    np.testing.assert_allclose(minus30.bounds, [[-40, 10], [-40 + 30 * SIN60, 10]], atol=1e-9)


def test_aalborg_empty_at_singular_orientation(aalborg):
    """At phi = 90 deg legs 1 and 2 need y = s1 + 30 sin 120 >= -14.02 and y = s2 + 30 sin 240 <= -15.98."""
    for deg in (90, -90):
        ws = constant_orientation_workspace(aalborg, np.radians(deg))
        assert ws.is_empty
        assert ws.area == 0.0 and ws.vertices.shape == (0, 2)
        assert np.isnan(np.asarray(ws.bounds)).all()
        with pytest.raises(EmptyWorkspaceError, match="phi = 90 deg" if deg == 90 else "phi = -90 deg"):
            ws.require_nonempty()


def test_symmetric_phi0_is_a_regular_hexagon(symmetric):
    """Bearings normal to the guides: s_i = u_i . p with |s_i| <= 25 and u_i 60 deg apart (mod 180),
    three strips of half-width 25: a regular hexagon of apothem 25, area 2 sqrt(3) 25^2."""
    ws = constant_orientation_workspace(symmetric, 0.0)
    assert ws.vertices.shape == (6, 2)
    assert ws.area == pytest.approx(2 * np.sqrt(3) * 625, rel=1e-12)
    np.testing.assert_allclose(np.linalg.norm(ws.vertices, axis=1), 50 / np.sqrt(3), rtol=1e-12)
    # Invariant under the 120 deg rotation that permutes the legs.
    c, s = np.cos(2 * np.pi / 3), np.sin(2 * np.pi / 3)
    rotated = ws.vertices @ np.array([[c, -s], [s, c]]).T
    d = np.linalg.norm(rotated[:, None] - ws.vertices[None], axis=-1)
    assert np.all(d.min(axis=1) < 1e-9)
    assert ws.contains(np.zeros(2))


# ----------------------------------------------------------------------------------- half-planes
def ppr_halfplanes(robot, phi):
    """Independent 3-PPR reference: the 12 joint limits of Eq. 2a/2b as half-planes ``G p <= h``.

    With ``q_i = p - a_i h_i - d_i v_i - r_i k_i`` and ``E`` the right-angle rotation,
    ``s_i = (w^T E q)/(w^T E u)`` and ``l_i = (u^T E q)/(u^T E w)`` are affine in ``p``.
    """
    vec = lambda t: np.stack([np.cos(t), np.sin(t)], axis=-1)  # noqa: E731
    E = np.array([[0.0, -1.0], [1.0, 0.0]])
    G, h = [], []
    for leg in robot.legs:
        u = vec(leg.alpha + leg.beta)
        v = vec(leg.alpha + leg.beta + leg.gamma)
        w = vec(leg.alpha + leg.beta + leg.gamma + leg.theta)
        c = leg.a * vec(leg.alpha) + leg.d * v + leg.r * vec(phi + leg.psi)
        gs = (w @ E) / (w @ E @ u)                         # ds/dp = w^T E / (w^T E u)
        gl = (u @ E) / (u @ E @ w)                          # dl/dp = u^T E / (u^T E w)
        for grad, (lo, hi) in ((gs, leg.s_range), (gl, leg.l_range)):
            G += [grad, -grad]
            h += [hi + grad @ c, -lo - grad @ c]
    return np.array(G), np.array(h)


def reference_polygon(robot, phi):
    """Vertices (CCW) and area of the 12 half-planes by scipy's half-space intersection (independent)."""
    from scipy.optimize import linprog
    from scipy.spatial import ConvexHull, HalfspaceIntersection
    G, h = ppr_halfplanes(robot, phi)
    n = np.linalg.norm(G, axis=1)
    res = linprog([0, 0, -1], A_ub=np.column_stack([G / n[:, None], np.ones(12)]), b_ub=h / n,
                  bounds=[(None, None)] * 3, method="highs")
    if res.x[2] <= 1e-9:   # no inscribed disc: empty (or zero-area)
        return np.zeros((0, 2)), 0.0
    hsi = HalfspaceIntersection(np.column_stack([G / n[:, None], -h / n]), res.x[:2])
    hull = ConvexHull(hsi.intersections)
    return hull.points[hull.vertices], hull.volume


def test_halfplanes_are_the_joint_excesses(rng):
    """The reference half-planes give G p - h = [s - s_max, s_min - s, ...] with s, l from the library's IK."""
    for _ in range(8):
        rr = random_manipulator(rng)
        robot = rr.robot
        phi = rng.uniform(-np.pi, np.pi)
        G, h = ppr_halfplanes(robot, phi)
        p = rr.home[:2] + rng.uniform(-100, 100, (50, 2))
        ik = inverse_kinematics(robot, np.column_stack([p, np.full(50, phi)]))
        excess = p @ G.T - h
        np.testing.assert_allclose(excess[:, 0::4], ik.s - robot.s_range[:, 1], atol=1e-9)
        np.testing.assert_allclose(excess[:, 1::4], robot.s_range[:, 0] - ik.s, atol=1e-9)
        np.testing.assert_allclose(excess[:, 2::4], ik.l - robot.l_range[:, 1], atol=1e-9)
        np.testing.assert_allclose(excess[:, 3::4], robot.l_range[:, 0] - ik.l, atol=1e-9)


@pytest.mark.parametrize("name", ["aalborg_3ppr", "symmetric_3ppr"])
def test_3ppr_presets_equal_the_half_plane_polygon(name):
    """The generic arc/segment region of a 3-PPR is the paper's polygon: area and vertices to 1e-12."""
    robot = Manipulator.preset(name)
    for deg in (-45, -30, -10, 0, 10, 30, 45, 60):
        phi = np.radians(deg)
        ws = constant_orientation_workspace(robot, phi)
        verts, area = reference_polygon(robot, phi)
        assert ws.is_empty == (area == 0.0)
        assert ws.area == pytest.approx(area, rel=1e-12)
        assert ws.vertices.shape == verts.shape
        if area:
            d = np.linalg.norm(ws.vertices[:, None] - verts[None], axis=-1)
            assert np.all(d.min(axis=1) < 1e-12 * 200) and np.all(d.min(axis=0) < 1e-12 * 200)
            assert shoelace(ws.vertices) == pytest.approx(area, rel=1e-12)


# ----------------------------------------------------------------------------------- random geometries
@settings(max_examples=30, deadline=None)
@given(manipulators())
def test_polygon_properties_on_random_geometries(rr):
    robot, home = rr.robot, rr.home
    ws = constant_orientation_workspace(robot, home[2])
    assert not ws.is_empty                         # the home pose is strictly inside the ranges
    assert ws.contains(home[:2])
    assert ws.vertices.ndim == 2 and ws.vertices.shape[1] == 2 and len(ws.vertices) >= 3
    assert shoelace(ws.vertices) == pytest.approx(ws.area, rel=1e-9)   # counter-clockwise, area matches
    (xmin, xmax), (ymin, ymax) = ws.bounds
    assert xmin == pytest.approx(ws.vertices[:, 0].min(), abs=1e-9)
    assert ymax == pytest.approx(ws.vertices[:, 1].max(), abs=1e-9)
    # Every vertex is reachable (boundary counts as inside) and lies on at least two joint limits.
    poses = np.column_stack([ws.vertices, np.full(len(ws.vertices), home[2])])
    require_within_limits(robot, poses)
    G, h = ppr_halfplanes(robot, home[2])
    excess = ws.vertices @ G.T - h
    assert np.all(np.sum(np.abs(excess) < 1e-7, axis=1) >= 2)
    verts, area = reference_polygon(robot, home[2])
    assert ws.area == pytest.approx(area, rel=1e-9)
    assert ws.contains(ws.interior_point)
    assert np.all(ws.contains(ws.vertices))
    assert ws.contains(ws.centroid)


def test_contains_agrees_with_inverse_kinematics(rng):
    for _ in range(10):
        rr = random_manipulator(rng)
        ws = constant_orientation_workspace(rr.robot, rr.home[2])
        (xmin, xmax), (ymin, ymax) = ws.bounds
        pts = np.column_stack([rng.uniform(xmin - 5, xmax + 5, 4000), rng.uniform(ymin - 5, ymax + 5, 4000)])
        ik = inverse_kinematics(rr.robot, np.column_stack([pts, np.full(len(pts), rr.home[2])]))
        np.testing.assert_array_equal(ws.contains(pts), ik.within_limits)
        assert 0 < ik.within_limits.sum() < len(pts)


def test_area_against_monte_carlo(rng):
    """Uniform samples in the joint-range box (leg_box) tested with the IK: fraction x box area ~ area."""
    for _ in range(5):
        rr = random_manipulator(rng)
        phi = rr.home[2]
        ws = constant_orientation_workspace(rr.robot, phi)
        (x0, x1), (y0, y1) = leg_box(rr.robot, phi)
        assert x0 <= ws.bounds[0][0] + 1e-9 and ws.bounds[0][1] <= x1 + 1e-9
        assert y0 <= ws.bounds[1][0] + 1e-9 and ws.bounds[1][1] <= y1 + 1e-9
        n = 200_000
        pts = np.column_stack([rng.uniform(x0, x1, n), rng.uniform(y0, y1, n), np.full(n, phi)])
        frac = inverse_kinematics(rr.robot, pts).within_limits.mean()
        box = (x1 - x0) * (y1 - y0)
        sigma = box * np.sqrt(frac * (1 - frac) / n)
        assert ws.area == pytest.approx(frac * box, abs=5 * sigma + 1e-9)


def test_grid_search_cross_check(aalborg, symmetric):
    """The paper's searching method on a fine grid agrees with the exact polygon."""
    for robot, deg in ((aalborg, 30), (symmetric, 0), (symmetric, 30)):
        phi = np.radians(deg)
        ws = constant_orientation_workspace(robot, phi)
        gs = grid_search_workspace(robot, phi, 301)
        assert gs.x.shape == gs.y.shape == (301,) and gs.inside.shape == (301, 301)
        X, Y = np.meshgrid(gs.x, gs.y)
        np.testing.assert_array_equal(gs.inside, ws.contains(np.stack([X, Y], axis=-1)))
        dx, dy = gs.x[1] - gs.x[0], gs.y[1] - gs.y[0]
        perimeter = np.sum(np.linalg.norm(np.roll(ws.vertices, -1, axis=0) - ws.vertices, axis=1))
        assert abs(gs.area - ws.area) <= perimeter * max(dx, dy)


def test_grid_search_with_given_box(aalborg):
    gs = grid_search_workspace(aalborg, 0.0, 11, box=((-30, 30), (-30, 30)))
    np.testing.assert_allclose(gs.x, np.arange(-30, 31, 6))
    expected = (np.abs(gs.x[None, :]) <= 25) & (np.abs(gs.y[:, None]) <= 25)
    np.testing.assert_array_equal(gs.inside, expected)
    with pytest.raises(ValueError):
        grid_search_workspace(aalborg, 0.0, 1)


# ----------------------------------------------------------------------------------- Workspace API
def test_workspace_is_frozen(aalborg):
    ws = constant_orientation_workspace(aalborg, 0.0)
    assert isinstance(ws, Workspace)
    with pytest.raises(dataclasses.FrozenInstanceError):
        ws.area = 1.0  # type: ignore[misc]
    assert ws.require_nonempty() is ws


def test_contains_is_vectorized_and_checks_shape(aalborg):
    ws = constant_orientation_workspace(aalborg, 0.0)
    pts = np.array([[[0, 0], [25, 25], [25 + 1e-6, 0]], [[-25, -25], [30, 0], [0, -25.1]]], dtype=float)
    np.testing.assert_array_equal(ws.contains(pts), [[True, True, False], [True, False, False]])
    assert ws.contains(np.array([25 + 1e-6, 0]), tol=1e-5)
    with pytest.raises(ValueError):
        ws.contains(np.zeros(3))


def test_grid_orientation(symmetric):
    """inside[j, i] refers to (x[i], y[j]): checked on the triangle of symmetric_3ppr at phi = 30 deg."""
    ws = constant_orientation_workspace(symmetric, np.radians(30))
    x, y, inside = ws.grid(41)
    assert x.shape == y.shape == (41,) and inside.shape == (41, 41)
    assert (x[0], x[-1], y[0], y[-1]) == (ws.bounds[0][0], ws.bounds[0][1], ws.bounds[1][0], ws.bounds[1][1])
    poses = np.array([[xi, yj, np.radians(30)] for yj in y for xi in x])
    np.testing.assert_array_equal(inside.ravel(), inverse_kinematics(symmetric, poses).within_limits)
    assert not np.array_equal(inside, inside.T)
    with pytest.raises(ValueError):
        ws.grid(1)


def _empty_robot(aalborg):
    """Leg 1 alone needs y in [35, 45] at phi = 0, leg 2 allows y in [-25, 25]."""
    return _with_ranges(aalborg, 0, s_range=(20.0, 30.0))


def _segment_robot(aalborg):
    """Leg 2 needs y in [25, 35]: with leg 1 (y <= 25) only the segment y = 25 remains (zero area)."""
    return _with_ranges(aalborg, 1, s_range=(10.0, 20.0))


@pytest.mark.parametrize("make", [_empty_robot, _segment_robot], ids=["disjoint", "zero-area"])
def test_empty_workspace_does_not_crash(aalborg, make):
    ws = constant_orientation_workspace(make(aalborg), 0.0)
    assert ws.is_empty and ws.area == 0.0 and ws.vertices.shape == (0, 2)
    assert np.isnan(np.asarray(ws.bounds, dtype=float)).all()
    assert np.isnan(ws.centroid).all()
    assert not ws.contains(np.array([0.0, 25.0]))
    assert ws.contains(np.zeros((3, 4, 2))).shape == (3, 4)
    with pytest.raises(EmptyWorkspaceError):
        ws.require_nonempty()
    with pytest.raises(EmptyWorkspaceError):
        ws.grid(10)


def test_thin_but_real_workspace_is_kept(aalborg):
    """Legs 1 and 2 overlapping over 0.01 mm in y: a 50 x 0.01 mm strip."""
    ws = constant_orientation_workspace(_with_ranges(aalborg, 1, s_range=(9.99, 20.0)), 0.0)
    assert ws.area == pytest.approx(50 * 0.01, rel=1e-6)
    np.testing.assert_allclose(ws.bounds[1], [24.99, 25.0], atol=1e-9)


# ----------------------------------------------------------------------------------- figure
def test_plot_workspaces_draws_each_orientation(aalborg):
    ax = plot_workspaces(aalborg)
    labels = ax.get_legend_handles_labels()[1]
    for deg in ("0", "30", "-30"):
        assert any(f"= {deg} deg" in lab for lab in labels), labels
    assert any("base" in lab for lab in labels) and any("rails" in lab for lab in labels)
    assert any("platform" in lab for lab in labels) and any("actuated" in lab for lab in labels)
    assert "mm" in ax.get_xlabel() and "mm" in ax.get_ylabel()
    assert ax.get_aspect() == 1.0
    # The platform triangle is drawn around the centre of the phi = 0 workspace (the origin here).
    tri = [p for p in ax.patches if "platform" in p.get_label()][0]
    np.testing.assert_allclose(tri.get_xy()[:3].mean(axis=0), [0.0, 0.0], atol=1e-9)


def test_plot_handles_an_empty_orientation(aalborg):
    ax = plot_workspaces(aalborg, np.radians([0.0, 90.0]))
    assert any("empty" in lab for lab in ax.get_legend_handles_labels()[1])


def test_save_workspace_figure(aalborg, tmp_path):
    path = save_workspace_figure(aalborg, tmp_path / "fig3.png")
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000


def test_save_comparison_figure(tmp_path):
    robots = [Manipulator.preset(n) for n in ("aalborg_3ppr", "symmetric_3rpr", "symmetric_3rrr", "symmetric_3prr")]
    path = save_comparison_figure(robots, tmp_path / "cmp.png")
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000
