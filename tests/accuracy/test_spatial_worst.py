"""The spatial global worst case (pmaccuracy.accuracy.spatial_worst) against brute force with the independent
first-order model of tests/reference/spatial_error_reference.py (screw theory, written from the guide; it does not
import pmaccuracy): the certified upper values are never below any value of the region, the lower values are
attained at the returned poses."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import spatial_error_reference as eref
import spatial_reference as ref

import pmaccuracy as pm
from pmaccuracy.accuracy.spatial_worst import (QUANTITIES, SpatialSingularRegionError, spatial_global_worst,
                                               spatial_region)
from pmaccuracy.errors import ConfigError
from pmaccuracy.kinematics.spatial import inverse_kinematics
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.model.spatial_sources import SpatialErrorSources
from pmaccuracy.numerics.spatial import rotvecs


def _robot(arch, robot_dict=None):
    robot_dict = robot_dict or ref.load_reference(arch)
    cl = eref.load_clearances(arch)
    robot = SpatialManipulator.from_dict(robot_dict, source="r.toml")
    return robot_dict, cl, robot, SpatialErrorSources.from_dict(cl, robot, source="c.toml")


def _reference(robot_dict, cl, p, R, n_dirs=4000):
    """(8,): the reference's six components (exact first order), and attained |dp|, |dtheta| (sampled support)."""
    model = eref.ErrorModel(robot_dict, cl, p, R)
    src = eref.describe(model.sources)
    M = eref.first_order_screw_theory(robot_dict, p, R, model.sources)
    comp = eref.component_bounds(M, src)
    dp = eref.max_norm_sampled(M, src, rows=slice(0, 3), n=n_dirs, refine=15, n_best=5)
    dth = eref.max_norm_sampled(M, src, rows=slice(3, 6), n=n_dirs, refine=15, n_best=5)
    return np.concatenate([comp, [dp, dth]])


def _brute(robot_dict, cl, poses, n_dirs=300):
    return np.array([_reference(robot_dict, cl, p[:3], ref.from_rotvec(p[3:]), n_dirs) for p in poses])


def _check_attained(robot_dict, cl, res):
    for name in QUANTITIES:
        w = res[name]
        k = QUANTITIES.index(name)
        value = _reference(robot_dict, cl, w.pose[:3], ref.from_rotvec(w.pose[3:]), n_dirs=4000)[k]
        if k < 6:      # exact
            assert value == pytest.approx(w.lower, rel=1e-9), name
        else:          # both attained: the true maximum at the pose is within the point gap (0.1 %) of ``lower``
            assert value <= w.lower * (1 + 1e-3) * (1 + 1e-9) and value >= w.lower * (1 - 2e-3), (name, value, w.lower)


def _hexapod_poses(robot, lo, hi, rng, n_grid, n_random):
    axes = [np.linspace(a, b, n_grid if b > a else 1) for a, b in zip(lo, hi)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 6)
    pts = np.vstack([grid, lo + (hi - lo) * rng.random((n_random, 6))])
    poses = np.column_stack([pts[:, :3], rotvecs(np.array([ref.rotation_rad(*a) for a in pts[:, 3:]]))])
    assert np.all(inverse_kinematics(robot, poses).within_limits)   # the region is inside the workspace
    return poses


def test_hexapod_position_box_never_exceeded_and_attained():
    robot_dict, cl, robot, sources = _robot("6-UPS")
    region = spatial_region(robot, box=(-15, 15, -15, 15, 290, 320), orientation=(0.0, 0.0, 0.0))
    res = spatial_global_worst(robot, sources, region, gap=0.01)
    assert res.certified and all(w.converged for w in res.quantities.values())
    lo, hi = np.array([-15, -15, 290, 0, 0, 0.0]), np.array([15, 15, 320, 0, 0, 0.0])
    poses = _hexapod_poses(robot, lo, hi, np.random.default_rng(3), 5, 40)
    brute = _brute(robot_dict, cl, poses).max(axis=0)
    upper = np.array([res[q].upper for q in QUANTITIES])
    lower = np.array([res[q].lower for q in QUANTITIES])
    assert np.all(brute <= upper * (1 + 1e-9)), (brute, upper)
    assert np.all(upper <= lower * 1.01 * (1 + 1e-9))
    assert np.all(lower <= upper)
    _check_attained(robot_dict, cl, res)


@pytest.mark.slow
def test_hexapod_orientation_box_never_exceeded():
    robot_dict, cl, robot, sources = _robot("6-UPS")
    o = np.radians([[0.0, 0.0], [0.0, 0.0], [-2.0, 2.0]])
    region = spatial_region(robot, box=(-4, 4, -4, 4, 300, 306), orientation=o)
    res = spatial_global_worst(robot, sources, region, gap=0.02)
    lo = np.array([-4, -4, 300, o[0, 0], 0, o[2, 0]])
    hi = np.array([4, 4, 306, o[0, 1], 0, o[2, 1]])
    poses = _hexapod_poses(robot, lo, hi, np.random.default_rng(4), 3, 30)
    brute = _brute(robot_dict, cl, poses).max(axis=0)
    upper = np.array([res[q].upper for q in QUANTITIES])
    assert np.all(np.isfinite(upper)) and np.all(brute <= upper * (1 + 1e-9)), (brute, upper)
    _check_attained(robot_dict, cl, res)


def test_hexapod_sphere_and_cylinder_contain_their_brute_force():
    robot_dict, cl, robot, sources = _robot("6-UPS")
    rng = np.random.default_rng(5)
    for kw, sample in (
            ({"sphere": (5.0, -5.0, 305.0, 12.0)},
             lambda u: np.array([5.0, -5.0, 305.0]) + 12.0 * u[:, :3] / np.linalg.norm(u[:, :3], axis=1)[:, None]
             * u[:, 3:4] ** (1 / 3)),
            ({"cylinder": (0.0, 5.0, 10.0, 295.0, 310.0)},
             lambda u: np.column_stack([10.0 * np.sqrt(u[:, 3]) * np.cos(2 * np.pi * u[:, 0]),
                                        5.0 + 10.0 * np.sqrt(u[:, 3]) * np.sin(2 * np.pi * u[:, 0]),
                                        295.0 + 15.0 * u[:, 1]]))):
        region = spatial_region(robot, orientation=(0.0, 0.0, 0.0), **kw)
        res = spatial_global_worst(robot, sources, region)
        u = rng.random((40, 4))
        u[:, :3] = rng.normal(size=(40, 3)) if "sphere" in kw else u[:, :3]
        pts = sample(u)
        assert np.all(region.contains(pts))
        poses = np.column_stack([pts, np.zeros((40, 3))])
        brute = _brute(robot_dict, cl, poses).max(axis=0)
        upper = np.array([res[q].upper for q in QUANTITIES])
        assert np.all(brute <= upper * (1 + 1e-9)), (kw, brute, upper)
        for q in QUANTITIES:   # the attaining poses are in the region
            p = res[q].pose
            assert region.contains(p[:3]) and res[q].lower <= res[q].upper


@pytest.mark.parametrize("arch, box", [
    ("3-RPS", (290.0, 310.0, np.radians(-3.0), np.radians(3.0), np.radians(-3.0), np.radians(3.0))),
])
def test_lower_bounds_attained_and_not_below_a_coarse_grid(arch, box):
    """3-RPS on a small box budget: the lower values are attained and at least the reference's maxima over a
    4 x 4 x 4 grid of the region (its points are among the initial samples), and the upper values above them."""
    robot_dict, cl, robot, sources = _robot(arch)
    region = spatial_region(robot, box=box)
    res = spatial_global_worst(robot, sources, region, max_boxes=600)
    assert res.certified and not res.reason
    _check_attained(robot_dict, cl, res)
    b = np.array(box).reshape(3, 2)
    axes = [np.linspace(lo, hi, 4) for lo, hi in b]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    if arch == "delta":
        poses = [(pt, np.eye(3)) for pt in pts]
    else:
        poses = [ref.complete_pose(robot_dict, *pt) for pt in pts]
    brute = np.array([_reference(robot_dict, cl, p, R, 600) for p, R in poses]).max(axis=0)
    lower = np.array([res[q].lower for q in QUANTITIES])
    assert np.all(lower[:6] >= brute[:6] * (1 - 1e-9)), (lower, brute)
    # |dp|, |dtheta|: the reference's sampled values are attained, ours within the point gap of the maximum
    assert np.all(lower[6:] >= brute[6:] * (1 - 1e-3)), (lower, brute)
    upper = np.array([res[q].upper for q in QUANTITIES])
    assert np.all(upper >= brute * (1 - 1e-9)) and np.all(np.isfinite(upper))


def test_a_region_reaching_a_singularity_is_refused():
    robot_dict = copy.deepcopy(ref.load_reference("6-UPS"))
    for leg in robot_dict["legs"]:         # no limit hides the singularity at yaw = 90 deg
        leg["stroke"] = [1.0, 2000.0]
        leg.pop("base_cone_deg", None)
        leg.pop("platform_cone_deg", None)
    _, _, robot, sources = _robot("6-UPS", robot_dict)
    for o in ((0.0, 0.0, np.radians(90.0)), np.radians([[0.0, 0.0], [0.0, 0.0], [80.0, 100.0]])):
        region = spatial_region(robot, box=(-5, 5, -5, 5, 295, 305), orientation=o)
        with pytest.raises(SpatialSingularRegionError, match="singularity"):
            spatial_global_worst(robot, sources, region)


def test_front_door_dispatches_and_bad_input_is_refused():
    robot = pm.load_robot("stewart_6ups")
    region = pm.spatial_region(robot, box=(-2, 2, -2, 2, 398, 402), orientation=(0.0, 0.0, 0.0))
    res = pm.global_worst(robot, "ups_typical", region)
    assert isinstance(res, pm.SpatialGlobalWorst) and res["dp"].upper <= res["dp"].lower * 1.01
    with pytest.raises(ConfigError, match="spatial_region"):
        pm.make_region(robot, (0.0, 0.0), None)
    for kw, key in (({"box": (1, 0, 0, 1, 0, 1)}, "box"), ({"box": (0, 1, 0, 1)}, "box"),
                    ({"sphere": (0, 0, 400, -1)}, "sphere"), ({"cylinder": (0, 0, 5, 410, 400)}, "cylinder"),
                    ({"box": (0, 1, 0, 1, 0, 1), "sphere": (0, 0, 0, 1)}, "sphere"),
                    ({"orientation": [[0.1, 0.0], [0, 0], [0, 0]]}, "orientation")):
        with pytest.raises(ConfigError) as exc:
            spatial_region(robot, **kw)
        assert exc.value.key == key
    with pytest.raises(ConfigError):
        spatial_region(pm.load_robot("rps_3"), sphere=(0, 0, 300, 5))
    with pytest.raises(ConfigError):
        spatial_region(pm.load_robot("delta_clavel"), box=(0, 1, 0, 1, -801, -800), orientation=(0, 0, 0))


@pytest.mark.slow
@pytest.mark.parametrize("seed", [11, 13, 14, 15])
def test_random_hexapods_and_clearances_never_exceeded(seed):
    """Random 6-UPS robots and clearances of the reference, random boxes (odd seeds: with roll, pitch, yaw ranges):
    the reference's values at random poses and the corners of the region never exceed the certified bounds."""
    robot_dict = ref.random_robot("6-UPS", seed)
    cl = eref.random_clearances(robot_dict, seed)
    robot = SpatialManipulator.from_dict(robot_dict, source="r.toml")
    sources = SpatialErrorSources.from_dict(cl, robot, source="c.toml")
    p, R = ref.random_pose(robot_dict, seed)
    e = ref.orientation_deg(R)
    rng = np.random.default_rng(seed)
    h, a = rng.uniform(2, 15), (rng.uniform(0, 1.5) if seed % 2 else 0.0)
    o = np.radians(np.column_stack([e - a, e + a]))
    region = spatial_region(robot, box=(p[0] - h, p[0] + h, p[1] - h, p[1] + h, p[2] - h, p[2] + h), orientation=o)
    res = spatial_global_worst(robot, sources, region, gap=0.01, max_boxes=60_000)
    lo, hi = np.concatenate([p - h, o[:, 0]]), np.concatenate([p + h, o[:, 1]])
    pts = np.vstack([lo + (hi - lo) * rng.random((120, 6)),
                     np.array(np.meshgrid(*[[a_, b_] for a_, b_ in zip(lo, hi)], indexing="ij")).reshape(6, -1).T])
    poses = np.column_stack([pts[:, :3], rotvecs(np.array([ref.rotation_rad(*x) for x in pts[:, 3:]]))])
    poses = poses[inverse_kinematics(robot, poses).within_limits]
    assert len(poses) > 20
    brute = _brute(robot_dict, cl, poses).max(axis=0)
    upper = np.array([res[q].upper for q in QUANTITIES])
    assert np.all(brute <= upper * (1 + 1e-9)), (brute, upper)
