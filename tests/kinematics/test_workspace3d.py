"""3D workspaces from a membership function, checked against regions with closed-form volumes and surfaces:
a ball, an aligned box, a lens (two balls), a spherical shell, a translated cylinder; orientation workspaces
of cone limits whose largest tilts follow from spherical geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pmaccuracy.errors import ConfigError, EmptyWorkspaceError
from pmaccuracy.kinematics.workspace3d import (Workspace3D, find_box, grid_workspace, orientation_workspace,
                                               tilt_torsion_matrix)


def ball(c, r):
    c = np.asarray(c, float)
    return lambda p: np.sum((p - c) ** 2, axis=-1) <= r * r


def lens(c1, c2, r):
    a, b = ball(c1, r), ball(c2, r)
    return lambda p: a(p) & b(p)


def lens_volume(r, d):
    """Two balls of radius r whose centres are d apart: pi (4r + d)(2r - d)^2 / 12."""
    return math.pi * (4 * r + d) * (2 * r - d) ** 2 / 12


def shell(c, r_in, r_out):
    c = np.asarray(c, float)
    return lambda p: (np.sum((p - c) ** 2, -1) <= r_out ** 2) & (np.sum((p - c) ** 2, -1) >= r_in ** 2)


def cylinder(c, r, half_length):
    """Axis along z through c."""
    c = np.asarray(c, float)
    return lambda p: ((p[..., 0] - c[0]) ** 2 + (p[..., 1] - c[1]) ** 2 <= r * r) & (np.abs(p[..., 2] - c[2])
                                                                                    <= half_length)


def aligned_box(lo, hi):
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return lambda p: np.all((p >= lo) & (p <= hi), axis=-1)


CASES = {
    # name: (membership, box, exact volume, largest relative error allowed at n = 40)
    "ball": (ball([3.0, -2.0, 1.0], 50.0), [[-50, 56], [-55, 51], [-52, 54]], 4 / 3 * math.pi * 50 ** 3, 0.005),
    "box": (aligned_box([-13.3, 2.1, 5.7], [21.9, 40.2, 17.45]), [[-20, 30], [0, 45], [0, 25]],
            35.2 * 38.1 * 11.75, 0.01),
    "lens": (lens([0, 0, 0], [60, 10, 0], 50.0), [[5, 55], [-45, 55], [-50, 50]],
             lens_volume(50.0, math.hypot(60, 10)), 0.005),
    "shell": (shell([0.5, 0.2, -0.3], 0.5, 1.0), [[-0.7, 1.7], [-1.0, 1.4], [-1.5, 0.9]],
              4 / 3 * math.pi * (1.0 - 0.125), 0.01),
    "cylinder": (cylinder([120.0, -40.0, 300.0], 30.0, 45.0), [[85, 155], [-75, -5], [250, 350]],
                 math.pi * 30 ** 2 * 90, 0.01),
}


@pytest.fixture(scope="module")
def spaces():
    return {name: grid_workspace(f, box, 40) for name, (f, box, _, _) in CASES.items()}


@pytest.mark.parametrize("name", list(CASES))
def test_volume_within_its_error_and_the_error_small(name, spaces):
    _, _, exact, allowed = CASES[name]
    ws = spaces[name]
    assert abs(ws.volume - exact) <= ws.volume_error, (ws.volume, exact, ws.volume_error)
    assert abs(ws.volume - exact) <= allowed * exact
    assert ws.volume_error <= 0.03 * exact                    # the stated error is useful too
    assert ws.to_dict()["volume"] == ws.volume and ws.to_dict()["cells"] == ws.cells


def test_volume_converges_and_beats_counting_cells():
    f, box, exact, _ = CASES["lens"]
    errors = [abs(grid_workspace(f, box, n).volume - exact) / exact for n in (20, 40)]
    ws = grid_workspace(f, box, 40)
    counted = abs(ws.cells * np.prod(ws.cell) - exact) / exact
    assert errors[1] < errors[0] and errors[1] < counted


def _distance_to_surface(name: str, p: np.ndarray) -> np.ndarray:
    """|signed distance-like function| (1-Lipschitz, zero on the surface) of the analytic regions."""
    if name == "ball":
        return np.abs(np.linalg.norm(p - [3.0, -2.0, 1.0], axis=1) - 50.0)
    if name == "lens":
        return np.abs(np.maximum(np.linalg.norm(p, axis=1) - 50, np.linalg.norm(p - [60, 10, 0], axis=1) - 50))
    if name == "shell":
        q = np.linalg.norm(p - [0.5, 0.2, -0.3], axis=1)
        return np.minimum(np.abs(q - 0.5), np.abs(q - 1.0))
    if name == "box":
        lo, hi = np.array([-13.3, 2.1, 5.7]), np.array([21.9, 40.2, 17.45])
        return np.abs(np.max(np.maximum(lo - p, p - hi), axis=1))
    if name == "cylinder":
        rad = np.hypot(p[:, 0] - 120, p[:, 1] + 40) - 30
        return np.abs(np.maximum(rad, np.abs(p[:, 2] - 300) - 45))
    raise KeyError(name)


@pytest.mark.parametrize("name", list(CASES))
def test_boundary_points_lie_on_the_surface_to_the_tolerance(name, spaces):
    ws = spaces[name]
    box = np.asarray(CASES[name][1], float)
    assert len(ws.boundary_points) > 500
    # each point is within half the last bisection bracket of the crossing on its edge: tol x box width / 2
    limit = ws.tol * (box[:, 1] - box[:, 0]).max() / 2
    assert _distance_to_surface(name, ws.boundary_points).max() <= limit * (1 + 1e-9)


def test_unrefined_boundary_points_are_edge_midpoints():
    ws = grid_workspace(ball([0, 0, 0], 1.0), [[-1.2, 1.2]] * 3, 12, refine=False)
    assert ws.volume == pytest.approx(ws.cells * np.prod(ws.cell))
    assert np.abs(np.linalg.norm(ws.boundary_points, axis=1) - 1.0).max() <= 0.1 + 1e-12     # half a cell


def test_slice_of_a_ball_is_a_disc_of_the_right_radius():
    c, r = np.array([1.0, 2.0, -3.0]), 10.0
    ws = grid_workspace(ball(c, r), [[-10, 12], [-9, 13], [-14, 8]], 44)
    grid, a, b = ws.slice(2, 3.2)
    zl = ws.slice_value(2, 3.2)
    assert abs(zl - 3.2) <= ws.cell[2] / 2
    rho = math.sqrt(r * r - (zl - c[2]) ** 2)
    A, B = np.meshgrid(a, b, indexing="ij")
    np.testing.assert_array_equal(grid, (A - c[0]) ** 2 + (B - c[1]) ** 2 <= rho ** 2)
    area = grid.sum() * ws.cell[0] * ws.cell[1]
    assert area == pytest.approx(math.pi * rho ** 2, rel=0.05)
    edge = ws.slice_boundary(2, 3.2)
    assert len(edge) > 40 and np.allclose(edge[:, 2], zl)
    np.testing.assert_allclose(np.hypot(edge[:, 0] - c[0], edge[:, 1] - c[1]), rho, atol=ws.tol * 22)
    with pytest.raises(ConfigError):
        ws.slice(2, 50.0)
    with pytest.raises(ConfigError):
        ws.slice(3, 0.0)


def test_bounding_box_centroid_extent_and_contains(spaces):
    ws = spaces["ball"]
    c = np.array([3.0, -2.0, 1.0])
    np.testing.assert_allclose(ws.bounding_box, np.column_stack([c - 50, c + 50]), atol=2.0)
    np.testing.assert_allclose(ws.extent, 100.0, atol=4.0)
    np.testing.assert_allclose(ws.centroid, c, atol=0.5)
    rng = np.random.default_rng(3)
    p = rng.uniform(-60, 60, size=(5000, 3)) + c
    d = np.linalg.norm(p - c, axis=1)
    far = np.abs(d - 50) > np.linalg.norm(ws.cell)
    np.testing.assert_array_equal(ws.contains(p)[far], (d <= 50)[far])
    assert not ws.contains([1e6, 0, 0])


@pytest.mark.parametrize("name", ["ball", "lens", "shell", "cylinder", "box"])
def test_find_box_holds_the_whole_region(name):
    f, box, _, _ = CASES[name]
    box = np.asarray(box, float)
    rng = np.random.default_rng(7)
    wide = np.column_stack([box[:, 0] - (box[:, 1] - box[:, 0]), box[:, 1] + (box[:, 1] - box[:, 0])])
    p = rng.uniform(wide[:, 0], wide[:, 1], size=(400_000, 3))
    p = p[f(p)]
    seed = p[0]
    found = find_box(f, seed, (box[:, 1] - box[:, 0]) / 20, 10 * (box[:, 1] - box[:, 0]))
    assert found.shape == (3, 2)
    assert (found[:, 0] <= p.min(axis=0)).all() and (found[:, 1] >= p.max(axis=0)).all()
    # and not much bigger than the region
    assert ((found[:, 1] - found[:, 0]) <= 1.6 * (p.max(axis=0) - p.min(axis=0))).all()


def test_empty_region_and_seed_outside():
    ws = grid_workspace(lambda p: np.zeros(p.shape[:-1], bool), [[0, 1]] * 3, 8)
    assert ws.is_empty and ws.volume == 0 and len(ws.boundary_points) == 0
    assert np.isnan(ws.bounding_box).all() and ws.to_dict()["bounding_box"] is None
    with pytest.raises(EmptyWorkspaceError):
        ws.require_nonempty()
    with pytest.raises(EmptyWorkspaceError):
        find_box(ball([0, 0, 0], 1.0), [5.0, 0, 0], [1, 1, 1], [10, 10, 10])
    for bad in ([1, 1], [0, 1, 1], "wide"):
        with pytest.raises(ConfigError):
            find_box(ball([0, 0, 0], 1.0), [0, 0, 0], bad, [10, 10, 10])


@pytest.mark.parametrize("inside", [
    lambda p: np.linalg.norm(p) <= 1.0,                                      # one answer for all points
    lambda p: bool(p[0] < 0.5),                                              # a Python if on an array
    lambda p: np.sum(p ** 2, axis=-1),                                       # not a bool
    lambda p: (np.sum(p ** 2, axis=-1) <= 1)[..., None],                     # wrong shape
])
def test_a_membership_function_that_is_not_vectorized_is_refused(inside):
    with pytest.raises(ConfigError, match="inside|vectorized|bools"):
        grid_workspace(inside, [[-1, 1]] * 3, 6)


@pytest.mark.parametrize("box", [[[0, 1], [0, 1]], [[0, 1], [1, 0], [0, 1]], [[0, np.nan], [0, 1], [0, 1]],
                                 "abc", [[0, 1, 2]] * 3])
def test_a_bad_box_is_refused(box):
    with pytest.raises(ConfigError):
        grid_workspace(ball([0, 0, 0], 1.0), box, 6)


@pytest.mark.parametrize("kwargs", [{"n": 1}, {"n": 2.5}, {"n": (4, 4)}, {"n": "many"}, {"tol": 0},
                                    {"names": ("x", "y")}])
def test_bad_options_are_refused(kwargs):
    with pytest.raises(ConfigError):
        grid_workspace(ball([0, 0, 0], 1.0), [[-1, 1]] * 3, **{"n": 6, **kwargs})


def test_integer_answers_and_big_grids_in_chunks(monkeypatch):
    import pmaccuracy.kinematics.workspace3d as w3

    calls = []

    def counted(p):
        calls.append(len(p))
        return (np.sum(p ** 2, axis=-1) <= 1).astype(int)

    monkeypatch.setattr(w3, "CHUNK", 1000)
    ws = grid_workspace(counted, [[-1.1, 1.1]] * 3, 20)
    assert max(calls) <= 1000 and sum(c for c in calls if c == 1000) >= 8
    assert abs(ws.volume - 4 / 3 * math.pi) <= ws.volume_error


@settings(max_examples=25, deadline=None)
@given(st.floats(-0.4, 0.4), st.floats(-0.4, 0.4), st.floats(-0.4, 0.4), st.floats(0.25, 0.6))
def test_random_ball_volume_within_its_error(x, y, z, r):
    ws = grid_workspace(ball([x, y, z], r), [[-1, 1]] * 3, 30)
    assert abs(ws.volume - 4 / 3 * math.pi * r ** 3) <= ws.volume_error


def _angle_to(R: np.ndarray, axis: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(R[..., :, 2] @ axis, -1, 1)))


def test_tilt_torsion_convention():
    phi, theta, sigma = np.radians([35.0, 20.0, 10.0])
    R = tilt_torsion_matrix(phi, theta, sigma)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    # R e_z: tilted by theta towards azimuth phi
    np.testing.assert_allclose(R[:, 2], [np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                                         np.cos(theta)], atol=1e-12)
    # untilted: a pure rotation by the torsion about z
    R0 = tilt_torsion_matrix(phi, 0.0, sigma)
    np.testing.assert_allclose(R0[:2, :2], [[np.cos(sigma), -np.sin(sigma)], [np.sin(sigma), np.cos(sigma)]],
                               atol=1e-12)


def test_cone_limit_gives_its_half_angle_in_every_direction():
    ow = orientation_workspace(lambda R: _angle_to(R, np.array([0, 0, 1.0])) <= 30.0, n_azimuth=36,
                               torsions_deg=(-20.0, 0.0, 20.0))
    np.testing.assert_allclose(ow.tilt_deg, 30.0, atol=2e-3)
    np.testing.assert_allclose(ow.max_tilt_deg, 30.0, atol=2e-3)
    np.testing.assert_allclose(ow.guaranteed_tilt_deg, 30.0, atol=2e-3)
    # a regular 36-gon of radius 30 deg
    np.testing.assert_allclose(ow.area_deg2, 0.5 * 36 * 30 ** 2 * math.sin(2 * math.pi / 36), rtol=1e-4)
    assert not ow.capped.any() and ow.to_dict()["max_tilt_deg"] == pytest.approx([30.0] * 3, abs=2e-3)


def test_tilted_cone_reaches_further_on_its_side():
    a = np.array([math.sin(math.radians(10)), 0.0, math.cos(math.radians(10))])   # cone axis tilted 10 deg to +x
    ow = orientation_workspace(lambda R: _angle_to(R, a) <= 30.0, n_azimuth=4)
    np.testing.assert_allclose(ow.tilt_deg[0, [0, 2]], [40.0, 20.0], atol=2e-3)    # azimuth 0 and 180 deg
    assert ow.max_tilt_deg[0] == pytest.approx(40.0, abs=2e-3)
    assert ow.guaranteed_tilt_deg[0] == pytest.approx(20.0, abs=2e-3)


def test_reach_stops_at_the_first_gap_and_caps_at_the_scan():
    # inside below 15 deg and again from 25 deg: the reach from tilt 0 stops at 15
    ow = orientation_workspace(lambda R: (_angle_to(R, np.array([0, 0, 1.0])) <= 15)
                               | (_angle_to(R, np.array([0, 0, 1.0])) >= 25), n_azimuth=6, max_tilt_deg=60)
    np.testing.assert_allclose(ow.tilt_deg, 15.0, atol=2e-3)
    everywhere = orientation_workspace(lambda R: np.ones(R.shape[:-2], bool), n_azimuth=6, max_tilt_deg=45)
    assert everywhere.capped.all() and (everywhere.tilt_deg == 45).all()


def test_orientation_workspace_empty_and_bad_input():
    ow = orientation_workspace(lambda R: R[..., 0, 0] < 0, n_azimuth=6)           # identity is outside
    assert ow.is_empty and np.isnan(ow.tilt_deg).all()
    with pytest.raises(EmptyWorkspaceError):
        ow.require_nonempty()
    with pytest.raises(ConfigError):
        orientation_workspace(lambda R: bool(R[0, 2, 2] > 0.5))
    with pytest.raises(ConfigError):
        orientation_workspace(lambda R: R[..., 2, 2] > 0.5, max_tilt_deg=0)


def test_workspace_is_frozen(spaces):
    assert isinstance(spaces["ball"], Workspace3D)
    with pytest.raises(AttributeError):
        spaces["ball"].volume = 1.0
