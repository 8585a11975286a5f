"""Spatial loads over sets (issue 37): the loaded error over a box of process wrenches, the load and preload maps
over the 3D grid and the preload over a region, against the independent reference
(tests/reference/spatial_load_reference.py: the loaded error from finite differences of the nonlinear chains,
member forces from the joints' physics, its own linear programs for the preload)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import spatial_error_reference as eref
import spatial_load_reference as lref
import spatial_reference as ref

from pmaccuracy.accuracy.spatial_loads import SpatialLoad, spatial_design_region_preload, spatial_loaded_error_map, \
    spatial_wrench_set_errors, spatial_wrench_set_map
from pmaccuracy.accuracy.spatial_worst import spatial_region
from pmaccuracy.errors import ConfigError
from pmaccuracy.model.spatial import SpatialManipulator

DATA = Path(__file__).resolve().parents[2] / "src" / "pmaccuracy" / "data"
PRESETS = [("stewart_6ups", "ups_typical"), ("delta_clavel", "delta_typical"), ("rps_3", "rps_typical"),
           ("prs_3", "prs_typical"), ("upu_3", "upu_typical")]


def _reference(name, clearances, seed):
    rdict = ref.load(DATA / "robots" / f"{name}.toml")
    cl = ref.load(DATA / "spatial_clearances" / f"{clearances}.toml")
    p, R = eref.nominal_pose(rdict) if seed == 0 else ref.random_pose(rdict, seed)
    return rdict, cl, p, R, ref.pose_vector(p, R)


@pytest.mark.parametrize("name,clearances", PRESETS)
def test_wrench_set_ranges_against_brute_force(name, clearances):
    """The attained range is the reference's loaded error at the box's centre and corners; the enclosure holds
    the reference's loaded error at every corner and at random wrenches of the box."""
    rdict, cl, p, R, pose = _reference(name, clearances, 3)
    robot = SpatialManipulator.preset(name)
    center = np.array([5.0, -3.0, -40.0, 200.0, -100.0, 50.0])
    half = np.array([8.0, 8.0, 30.0, 600.0, 600.0, 600.0])
    ours = spatial_wrench_set_errors(robot, clearances, pose, center, half)
    M, sources = eref.sensitivity(rdict, cl, p, R)
    corners = lref.box_corners(center, half)
    err, spread = lref.loaded_errors(M, sources, np.vstack([center, corners]))
    scale = np.max(np.abs(ours.upper - ours.lower)) + 1e-12
    assert np.allclose(ours.attained_lower[0], np.min(err - spread, axis=0), atol=1e-6 * scale)
    assert np.allclose(ours.attained_upper[0], np.max(err + spread, axis=0), atol=1e-6 * scale)
    rng = np.random.default_rng(11)
    inside, _ = lref.loaded_errors(M, sources, center + rng.uniform(-1, 1, (150, 6)) * half)
    tol = 1e-6 * scale
    assert np.all(inside >= ours.lower[0] - tol) and np.all(inside <= ours.upper[0] + tol)
    assert np.all(err >= ours.lower[0] - tol) and np.all(err <= ours.upper[0] + tol)
    fixed = [s for s in sources if s["key"] not in lref.CLEARANCE_KEYS]
    support = sum(s["half_width"] * np.linalg.norm(M[:, s["columns"]], axis=1) for s in fixed) if fixed else 0.0
    assert np.allclose(ours.tolerance[0], support, rtol=1e-6, atol=1e-12)


def test_segments_are_exact_and_held_ones_constant():
    """A 6-UPS's clearances act through its legs' axial forces (segments): where the box keeps every leg's sign,
    the loaded error is one value (enclosure = attained = the reference at any wrench); where a leg flips, the
    enclosure of each component is still attained by the reference at some corner when one leg alone flips."""
    rdict, cl, p, R, pose = _reference("stewart_6ups", "ups_typical", 2)
    robot = SpatialManipulator.preset("stewart_6ups")
    M, sources = eref.sensitivity(rdict, cl, p, R)
    center, half = np.array([0.0, 0.0, -200.0, 0.0, 0.0, 0.0]), np.array([5.0, 5.0, 5.0, 100.0, 100.0, 100.0])
    lam = np.array([lref.member_forces(rdict, p, R, F) for F in lref.box_corners(center, half)])
    assert np.all(np.abs(np.sign(lam).sum(axis=0)) == 64)          # every leg keeps its sign over the box
    ours = spatial_wrench_set_errors(robot, "ups_typical", pose, center, half)
    one, _ = lref.loaded_errors(M, sources, center)
    assert np.allclose(ours.lower[0], one[0], atol=1e-7 * np.abs(one).max())
    assert np.allclose(ours.upper[0], one[0], atol=1e-7 * np.abs(one).max())
    assert int(ours.not_held[0]) == 0
    # a box along leg 1's wrench direction only: leg 1 alone flips
    W = lref.member_wrenches(rdict, p, R)
    center = -W @ np.array([0.0, 30.0, 30.0, 30.0, 30.0, 30.0])
    half = np.abs(W[:, 0]) * 20.0
    lam = np.array([lref.member_forces(rdict, p, R, F) for F in lref.box_corners(center, half)])
    flips = np.abs(np.sign(lam).sum(axis=0)) < 64
    assert flips[0]
    ours = spatial_wrench_set_errors(robot, "ups_typical", pose, center, half)
    err, _ = lref.loaded_errors(M, sources, lref.box_corners(center, half))
    assert not np.any(flips[1:])
    assert np.allclose(ours.lower[0], err.min(axis=0), atol=1e-6 * np.abs(err).max())
    assert np.allclose(ours.upper[0], err.max(axis=0), atol=1e-6 * np.abs(err).max())
    leg1 = [k for k, v in ours.held.items() if k.startswith("legs[1].") and not v[0]]
    assert leg1 and all(v[0] for k, v in ours.held.items() if not k.startswith(tuple(
        f"legs[{i + 1}]." for i in np.flatnonzero(flips))))


def test_loaded_error_map_against_the_reference():
    robot = SpatialManipulator.preset("upu_3")
    rdict = ref.load(DATA / "robots" / "upu_3.toml")
    cl = ref.load(DATA / "spatial_clearances" / "upu_typical.toml")
    load = SpatialLoad(force=(10.0, -5.0, -60.0), moment=(300.0, 0.0, -200.0), mass=1.0, com=(0.0, 5.0, 10.0))
    ds = spatial_loaded_error_map(robot, "upu_typical", load, n=5)
    pts = np.argwhere(np.isfinite(ds.dz.values))
    assert len(pts) >= 2
    for idx in pts[:: max(1, len(pts) // 2)][:2]:
        p = np.array([float(ds[d][i]) for d, i in zip(("x", "y", "z"), idx)])
        R = np.eye(3)
        F = lref.load_wrench(load.force, load.moment, load.mass, load.com, load.gravity, R)
        dX, _, _ = lref.loaded_first_order(rdict, cl, p, R, F)
        got = np.array([float(ds[c].values[tuple(idx)]) for c in ("dx", "dy", "dz", "drx", "dry", "drz")])
        assert np.max(np.abs(got - dX)) <= 1e-6 * np.max(np.abs(dX))
        lam = lref.member_forces(rdict, p, R, F)
        assert np.allclose([float(ds[f"lambda{k + 1}"].values[tuple(idx)]) for k in range(6)], lam,
                           rtol=1e-9, atol=1e-9 * np.abs(lam).max())


def test_preload_map_against_the_reference_programs():
    """At grid points of a 6-UPS map: the free preload's size equals the reference's own linear programs; the
    smallest multiple of a direction too."""
    robot = SpatialManipulator.preset("stewart_6ups")
    rdict = ref.load(DATA / "robots" / "stewart_6ups.toml")
    center, half = np.array([0.0, 0.0, -10.0, 0.0, 0.0, 0.0]), np.array([5.0, 0.0, 10.0, 0.0, 300.0, 0.0])
    d = np.array([0.0, 0.0, -1.0, 0.0, 0.0, 0.0])
    ds = spatial_wrench_set_map(robot, "ups_typical", center, half, n=4, orientation=[0.0, 0.0, 0.0], direction=d,
                                margin=0.5)
    pts = np.argwhere(np.isfinite(ds.preload_size.values))
    assert len(pts) >= 2
    L = robot.characteristic_length
    for idx in pts[:2]:
        p = np.array([float(ds[k][i]) for k, i in zip(("x", "y", "z"), idx)])
        size, _, _ = lref.smallest_preload(rdict, [(p, np.eye(3))], center, half, 0.5, L)
        assert float(ds.preload_size.values[tuple(idx)]) == pytest.approx(size, rel=1e-6, abs=1e-9)
        alpha = lref.smallest_preload(rdict, [(p, np.eye(3))], center, half, 0.5, L, direction=d)
        got = float(ds.preload_alpha.values[tuple(idx)])
        if alpha is None:
            assert np.isinf(got)
        else:
            assert got == pytest.approx(alpha[0], rel=1e-6, abs=1e-9)
        assert float(ds.dz_lo.values[tuple(idx)]) <= float(ds.dz_attained_lo.values[tuple(idx)]) + 1e-12


def test_region_preload_holds_on_the_grid_and_is_the_grid_optimum():
    """A 3-UPU over a small box: the preload keeps every member's sign with the margin at every pose of the
    twice denser grid for every corner of the process box (reference member forces), its size is at least the
    reference's optimum over the design grid, and the attaining pose's own preload is the reference's."""
    robot = SpatialManipulator.preset("upu_3")
    rdict = ref.load(DATA / "robots" / "upu_3.toml")
    region = spatial_region(robot, box=(-20.0, 20.0, -20.0, 20.0, 280.0, 320.0))
    center, half = np.array([0.0, 0.0, -30.0, 0.0, 0.0, 0.0]), np.array([10.0, 0.0, 10.0, 500.0, 0.0, 0.0])
    res = spatial_design_region_preload(robot, "upu_typical", region, center, half, grid=2, margin=1.0)
    axes = [np.linspace(-20, 20, 3), np.linspace(-20, 20, 3), np.linspace(280, 320, 3)]
    dense = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    corners = lref.box_corners(center, half)
    for p in dense:
        lam = np.linalg.solve(lref.member_wrenches(rdict, p, np.eye(3)), -(res.wrench + corners).T).T
        assert np.all(lam * res.pattern >= 1.0 - 1e-6), p
    coarse = np.stack(np.meshgrid(*[a[::2] for a in axes], indexing="ij"), -1).reshape(-1, 3)
    size, _, _ = lref.smallest_preload(rdict, [(p, np.eye(3)) for p in coarse], center, half, 1.0,
                                       robot.characteristic_length)
    assert res.size >= size * (1 - 1e-6) - 1e-9
    one, _, _ = lref.smallest_preload(rdict, [(res.attaining[:3], np.eye(3))], center, half, 1.0,
                                      robot.characteristic_length)
    assert res.per_pose_size == pytest.approx(one, rel=1e-6, abs=1e-9)
    assert res.n_check == len(coarse) + len(dense) and res.min_intensity >= 1.0 * (1 - 1e-9)


def test_bad_input():
    robot = SpatialManipulator.preset("stewart_6ups")
    with pytest.raises(ConfigError) as exc:
        spatial_wrench_set_errors(robot, "ups_typical", robot.home_pose, np.zeros(6), np.zeros(6))
    assert exc.value.key == "half"
    with pytest.raises(ConfigError) as exc:
        spatial_wrench_set_errors(robot, "ups_typical", robot.home_pose, np.zeros(6), np.ones(6), threshold=-1.0)
    assert exc.value.key == "threshold"
    with pytest.raises(ConfigError) as exc:
        spatial_wrench_set_map(robot, "ups_typical", np.zeros(6), np.ones(6), n=1)
    assert exc.value.key == "n"
    with pytest.raises(ConfigError) as exc:
        spatial_design_region_preload(robot, "ups_typical", "workspace", np.zeros(6), np.ones(6))
    assert exc.value.key == "region"


def _spring_columns(rdict, p, R):
    """(6, n): a unit spring force along each leg from A_i to B_i, pushing the platform at B_i (about P)."""
    cols = []
    for leg in ref.legs(rdict):
        B = p + R @ leg["platform"]
        u = (B - leg["base"]) / np.linalg.norm(B - leg["base"])
        cols.append(np.concatenate([u, np.cross(B - p, u)]))
    return np.array(cols).T


def test_springs_on_a_hexapod_per_leg_closed_form():
    """A 6-UPS's spring only shifts its own leg's force (lambda_i - sigma_i): the smallest springs follow per leg
    from the reference's member forces at the box's corners."""
    from pmaccuracy.accuracy.spatial_loads import spatial_spring_preload

    rdict, cl, p, R, pose = _reference("stewart_6ups", "ups_typical", 4)
    robot = SpatialManipulator.preset("stewart_6ups")
    center, half = np.array([3.0, 0.0, -20.0, 0.0, 100.0, 0.0]), np.array([10.0, 10.0, 15.0, 400.0, 400.0, 400.0])
    sp = spatial_spring_preload(robot, "ups_typical", pose, center, half, margin=1.0)
    corners = lref.box_corners(center, half)
    lam = np.array([lref.member_forces(rdict, p, R, F) for F in corners])
    lo, hi = lam.min(axis=0), lam.max(axis=0)
    cost = np.minimum(np.maximum(0.0, hi + 1.0), np.maximum(0.0, 1.0 - lo))
    assert sp.size == pytest.approx(cost.max(), rel=1e-7)
    want = np.where(sp.pattern > 0, np.minimum(0.0, lo - 1.0), np.maximum(0.0, hi + 1.0))
    assert np.allclose(sp.forces, want, rtol=1e-7, atol=1e-7)
    S = _spring_columns(rdict, p, R)
    with_springs = np.array([lref.member_forces(rdict, p, R, F + S @ sp.forces) for F in corners])
    assert np.all(with_springs * sp.pattern >= 1.0 - 1e-6)
    assert np.allclose(with_springs, lam - sp.forces, rtol=0, atol=1e-8 * np.abs(lam).max())
    assert all(sp.held.values())


def test_springs_on_a_3rps_cannot_hold_its_revolute_rows():
    """A 3-RPS spring moves its leg's axial row only: a box flipping a revolute row is refused; a box that keeps
    them is held per the reference's member forces with the springs' wrenches built from the geometry."""
    from pmaccuracy.accuracy.spatial_loads import spatial_spring_preload

    rdict, cl, p, R, pose = _reference("rps_3", "rps_typical", 5)
    robot = SpatialManipulator.preset("rps_3")
    with pytest.raises(ConfigError) as exc:
        spatial_spring_preload(robot, "rps_typical", pose, np.zeros(6), [20.0, 20.0, 20.0, 800.0, 800.0, 800.0])
    assert exc.value.key == "half" and "rows" in str(exc.value)
    W = lref.member_wrenches(rdict, p, R)           # a box loading the revolute rows, flipping the legs' forces
    center = -W @ np.array([0.0, 40.0, 0.0, 40.0, 0.0, 40.0])
    half = np.abs(W[:, [0, 2, 4]]).sum(axis=1) * 10.0
    lam = np.array([lref.member_forces(rdict, p, R, F) for F in lref.box_corners(center, half)])
    assert np.all(lam[:, 1::2] > 1.0) and np.all(lam[:, 0::2].min(axis=0) < 0) and np.all(lam[:, 0::2].max(axis=0) > 0)
    sp = spatial_spring_preload(robot, "rps_typical", pose, center, half, margin=0.5)
    S = _spring_columns(rdict, p, R)
    lam = np.array([lref.member_forces(rdict, p, R, F + S @ sp.forces) for F in lref.box_corners(center, half)])
    assert np.all(lam * sp.pattern >= 0.5 - 1e-6)
    weaker = np.array([lref.member_forces(rdict, p, R, F + S @ (0.99 * sp.forces))
                       for F in lref.box_corners(center, half)])
    assert sp.size > 0 and not np.all(weaker * sp.pattern >= 0.5 - 1e-9)


def test_region_preload_refuses_a_singular_region():
    """A hexapod whose legs reach the yaw-90-deg singularity: the rows' intensities are unbounded there, so no
    finite preload is returned."""
    from pmaccuracy.accuracy.spatial_worst import SpatialSingularRegionError

    d = SpatialManipulator.preset("stewart_6ups").to_dict()
    for leg in d["legs"]:
        leg["stroke"] = [1.0, 5000.0]
        for key in ("base_cone_deg", "platform_cone_deg", "radius"):
            leg.pop(key, None)
    robot = SpatialManipulator.from_dict(d)
    region = spatial_region(robot, box=(-1.0, 1.0, -1.0, 1.0, 399.0, 401.0),
                            orientation=np.radians([[0.0, 0.0], [0.0, 0.0], [80.0, 100.0]]))
    with pytest.raises(SpatialSingularRegionError):
        spatial_design_region_preload(robot, "ups_typical", region, np.zeros(6), np.ones(6), grid=3)
