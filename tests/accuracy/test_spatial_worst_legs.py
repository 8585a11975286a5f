"""The certified spatial global worst case of the 3-UPU, Delta, 3-RPS and 3-PRS (pmaccuracy.accuracy.spatial_worst,
interval enclosures of their closure rows and sources over boxes): the upper values are never below the pointwise
first-order worst case (spatial_pose_errors, checked against the independent screw-theory reference elsewhere) at
a dense grid and random points of the region, and the lower values are attained: at the returned pose the
component maxima equal those of the reference's finite differences of the exact nonlinear closure
(tests/reference/spatial_error_reference.py, which does not import pmaccuracy)."""

from __future__ import annotations

import numpy as np
import pytest
import spatial_error_reference as eref
import spatial_reference as ref

from pmaccuracy.accuracy.spatial_bounds import spatial_pose_errors
from pmaccuracy.accuracy.spatial_worst import QUANTITIES, SpatialRegion, spatial_global_worst, spatial_region
from pmaccuracy.kinematics.spatial import complete_poses, inverse_kinematics
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.model.spatial_sources import SpatialErrorSources
from pmaccuracy.numerics.spatial import rotvec_to_euler_xyz


def _robot(arch, seed=None):
    """The reference robot with its typical error sources, or (``seed``) random ones of every applicable key."""
    robot_dict = ref.load_reference(arch)
    cl = eref.load_clearances(arch) if seed is None else eref.random_clearances(robot_dict, seed)
    robot = SpatialManipulator.from_dict(robot_dict, source="r.toml")
    return robot_dict, cl, robot, SpatialErrorSources.from_dict(cl, robot, source="c.toml")


def _centre(robot_dict):
    p, R = eref.nominal_pose(robot_dict)
    if robot_dict["architecture"] in ("3-RPS", "3-PRS"):
        return np.array([p[2], *np.radians(ref.orientation_deg(R)[:2])])
    return p


def _coordinates(robot, pose):
    """The region coordinates of a full pose."""
    if robot.mobility == "2R1T":
        return np.array([pose[2], *rotvec_to_euler_xyz(pose[3:])[:2]])
    return pose[:3]


def _sampled(robot, sources, region, n, rng):
    """The pointwise worst values ``(m, 8)`` on an n^3 grid and 200 random points of the region's box."""
    b = region.bounds
    axes = [np.linspace(lo, hi, n) for lo, hi in b]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    pts = np.vstack([pts, b[:, 0] + (b[:, 1] - b[:, 0]) * rng.random((200, 3))])
    poses = complete_poses(robot, pts)
    assert np.all(inverse_kinematics(robot, poses).within_limits)     # the region is in the workspace
    r = spatial_pose_errors(robot, sources, poses, gap=1e-4, details=False)
    return np.column_stack([r.components, r.dp_lower, r.dtheta_lower])


# half-widths (mm; rad for roll, pitch) of the regions about the home pose
SMALL = {"3-UPU": (5.0, 5.0, 5.0), "delta": (5.0, 5.0, 5.0), "3-RPS": (5.0, 0.02, 0.02), "3-PRS": (5.0, 0.02, 0.02)}


@pytest.mark.parametrize("arch", sorted(SMALL))
def test_certified_upper_never_below_the_region_and_lower_attained(arch):
    """Random error sources of every key the joints take (every kind of generator), 1 % gap."""
    robot_dict, cl, robot, sources = _robot(arch, seed=1)
    c, h = _centre(robot_dict), np.array(SMALL[arch])
    region = spatial_region(robot, box=np.column_stack([c - h, c + h]).ravel())
    res = spatial_global_worst(robot, sources, region, gap=0.01)
    upper = np.array([res[q].upper for q in QUANTITIES])
    lower = np.array([res[q].lower for q in QUANTITIES])
    assert res.certified and not res.reason
    assert all(res[q].converged for q in QUANTITIES), res.quantities
    assert np.all(lower <= upper) and np.all(upper <= lower * 1.01 * (1 + 1e-9))
    sampled = _sampled(robot, sources, region, 8, np.random.default_rng(7))
    assert np.all(sampled <= upper * (1 + 1e-12)), (sampled.max(axis=0), upper)
    assert np.all(sampled.max(axis=0) >= lower * (1 - 0.011))      # near the maximum (gap 1 %)
    # attained: each lower value is the pointwise value at its pose, and at the pose of dp the first-order map by
    # finite differences of the exact nonlinear closure gives those pointwise values and dp
    for k, name in enumerate(QUANTITIES):
        pose = res[name].pose
        assert region.contains(_coordinates(robot, pose)), name
        r = spatial_pose_errors(robot, sources, pose, gap=1e-4)
        value = np.concatenate([r.components, [r.dp_upper, r.dtheta_upper]])[k]
        assert res[name].lower <= value * (1 + 1e-12) and value <= res[name].lower * (1 + 2e-3), name
    pose = res["dp"].pose
    M, src = eref.sensitivity(robot_dict, cl, pose[:3], ref.from_rotvec(pose[3:]))
    r = spatial_pose_errors(robot, sources, pose)
    assert eref.component_bounds(M, src) == pytest.approx(r.components, rel=1e-5)
    dp = eref.max_norm_sampled(M, src, rows=slice(0, 3), n=2000, refine=15, n_best=5)
    assert res["dp"].lower * (1 - 2e-3) <= dp <= res["dp"].lower * (1 + 2e-3)


@pytest.mark.slow
@pytest.mark.parametrize("arch", sorted(SMALL))
@pytest.mark.parametrize("seed", [2, 3])
def test_tight_gap_never_exceeded(arch, seed):
    """A 0.3 % gap with random sources: the dense samples come within 0.3 % of the upper values, never above."""
    robot_dict, _, robot, sources = _robot(arch, seed=seed)
    c, h = _centre(robot_dict), 0.5 * np.array(SMALL[arch])
    region = spatial_region(robot, box=np.column_stack([c - h, c + h]).ravel())
    res = spatial_global_worst(robot, sources, region, gap=0.003)
    upper = np.array([res[q].upper for q in QUANTITIES])
    assert all(res[q].converged for q in QUANTITIES)
    sampled = _sampled(robot, sources, region, 9, np.random.default_rng(seed))
    assert np.all(sampled <= upper * (1 + 1e-12)), (sampled.max(axis=0), upper)


@pytest.mark.parametrize("arch, half", [("3-UPU", (40.0, 40.0, 40.0)), ("delta", (40.0, 40.0, 40.0)),
                                        ("3-RPS", (10.0, 0.05, 0.05)), ("3-PRS", (10.0, 0.05, 0.05))])
def test_wider_regions_never_exceeded(arch, half):
    """A wider region on a small box budget: the bounds are looser but hold."""
    robot_dict, cl, robot, sources = _robot(arch)
    c, h = _centre(robot_dict), np.array(half)
    region = spatial_region(robot, box=np.column_stack([c - h, c + h]).ravel())
    res = spatial_global_worst(robot, sources, region, gap=0.01, max_boxes=150)
    upper = np.array([res[q].upper for q in QUANTITIES])
    assert res.certified and np.all(np.isfinite(upper))
    sampled = _sampled(robot, sources, region, 6, np.random.default_rng(8))
    assert np.all(sampled <= upper * (1 + 1e-12)), (sampled.max(axis=0), upper)


def test_whole_workspace_of_a_3rps_is_not_certified_and_the_delta_box_holds_its_workspace():
    """Over a 3-RPS's workspace (its box of z, roll, pitch is sampled, not proven) the upper values are inf with
    the reason; a Delta's workspace box (rods' midpoints within arm + rod of the base joints) holds every
    reachable position, checked by sampling positions and the inverse kinematics."""
    robot_dict, _, robot, sources = _robot("3-RPS")
    c = _centre(robot_dict)          # a workspace region (its box as spatial_region would sample it, smaller)
    region = SpatialRegion("workspace", ("z", "roll", "pitch"), np.column_stack([c - 1e-3, c + 1e-3]))
    res = spatial_global_worst(robot, sources, region, grid=2)
    assert not res.certified and "workspace" in res.reason
    assert all(np.isinf(res[q].upper) and res[q].lower > 0 for q in QUANTITIES)
    _, _, delta, _ = _robot("delta")
    b = spatial_region(delta).bounds
    rng = np.random.default_rng(9)
    pts = rng.uniform(-2500.0, 2500.0, (50_000, 3))
    reach = np.asarray(inverse_kinematics(delta, np.column_stack([pts, np.zeros_like(pts)])).reachable)
    assert reach.sum() > 100
    assert np.all((pts[reach] >= b[:, 0]) & (pts[reach] <= b[:, 1]))
