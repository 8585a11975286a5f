"""Benchmark: the certified global worst case of a 6-UPS over a 100 mm cube (fixed orientation) to a 1 % gap.

Times :func:`pmaccuracy.accuracy.spatial_worst.spatial_global_worst` on ``stewart_6ups`` with ``ups_typical``
over ``x, y in [-50, 50]``, ``z in [350, 450]`` mm, and prints the boxes it evaluated. The floor, measured in
the same run: the first-order worst case (:func:`pmaccuracy.accuracy.spatial_bounds.spatial_pose_errors`,
``details=False``) at as many poses as there were boxes, i.e. one point evaluation per box; ratio = ours / floor
(how much the certificate costs over sampling the same number of points). ``--others`` adds the 3-UPU and the
Delta over an 80 mm cube about their home poses, the 3-RPS and 3-PRS over ``z`` +-10 mm, roll and pitch
+-3 deg, each with its typical sources.

    .venv/bin/python benchmarks/bench_spatial_worst.py [--repeats 3] [--others]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from pmaccuracy.accuracy.spatial_bounds import spatial_pose_errors
from pmaccuracy.accuracy.spatial_worst import spatial_global_worst, spatial_region
from pmaccuracy.kinematics.spatial import complete_poses, reference_pose
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.model.spatial_sources import SpatialErrorSources, default_preset


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--others", action="store_true", help="also the 3-UPU, Delta, 3-RPS and 3-PRS")
    args = ap.parse_args()
    robot = SpatialManipulator.preset("stewart_6ups")
    sources = SpatialErrorSources.load("ups_typical", robot)
    region = spatial_region(robot, box=(-50, 50, -50, 50, 350, 450), orientation=(0.0, 0.0, 0.0))
    times, res = [], None
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        res = spatial_global_worst(robot, sources, region, gap=0.01)
        times.append(time.perf_counter() - t0)
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-50, 50, (res.boxes, 2)), rng.uniform(350, 450, res.boxes),
                           np.zeros((res.boxes, 3))])
    floor = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        spatial_pose_errors(robot, sources, pts, strict=False, details=False)
        floor.append(time.perf_counter() - t0)
    ours, base = float(np.median(times)), float(np.median(floor))
    gaps = max(w.gap for w in res.quantities.values())
    print(f"spatial_global_worst 6-UPS 100 mm cube to 1 %: {ours:.3f} s, {res.boxes} boxes, {res.iterations} rounds, "
          f"largest gap {100 * gaps:.3f} %, converged {all(w.converged for w in res.quantities.values())}")
    print(f"floor: spatial_pose_errors at {res.boxes} poses: {base:.3f} s; ratio ours / floor = {ours / base:.2f}")
    if args.others:
        for preset in ("upu_3", "delta_clavel", "rps_3", "prs_3"):
            others(preset, args.repeats)


def others(preset: str, repeats: int) -> None:
    """One of the other architectures (module text)."""
    robot = SpatialManipulator.preset(preset)
    sources = SpatialErrorSources.load(default_preset(robot), robot)
    home = reference_pose(robot)
    if robot.mobility == "2R1T":
        c, h = np.array([home[2], 0.0, 0.0]), np.array([10.0, np.radians(3.0), np.radians(3.0)])
    else:
        c, h = home[:3], np.full(3, 40.0)
    region = spatial_region(robot, box=np.column_stack([c - h, c + h]).ravel())
    times, res = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = spatial_global_worst(robot, sources, region, gap=0.01)
        times.append(time.perf_counter() - t0)
    pts = c - h + 2 * h * np.random.default_rng(0).random((res.boxes, 3))
    poses = complete_poses(robot, pts, strict=False)
    floor = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        spatial_pose_errors(robot, sources, poses, strict=False, details=False)
        floor.append(time.perf_counter() - t0)
    ours, base = float(np.median(times)), float(np.median(floor))
    gaps = max(w.gap for w in res.quantities.values())
    print(f"spatial_global_worst {robot.architecture} ({region.describe()}) to 1 %: {ours:.3f} s, {res.boxes} boxes, "
          f"largest gap {100 * gaps:.3f} %, converged {all(w.converged for w in res.quantities.values())}; "
          f"floor {base:.3f} s, ratio {ours / base:.2f}")


if __name__ == "__main__":
    main()
