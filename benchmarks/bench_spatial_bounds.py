"""Benchmark: first-order worst cases of a hexapod against the floor, a plain vectorized inverse kinematics.

The floor is the leg lengths ``|p + R b_i - A_i|`` of the same poses in plain numpy (rotation matrices from the
poses' rotation vectors with scipy), as in ``bench_spatial_kinematics.py``. Printed, in the same run (process
CPU time, best of ``--repeats``):

* the exact components (dx, dy, dz and the three small rotations) of ``--poses`` poses: the error set built
  from the legs' closure (issue 37's target: within 3x the floor);
* with ``|dp|`` and ``|dtheta|`` certified at 0.1 % (issue 37's target: within 10x the floor);
* a map of the hexapod's constant-orientation workspace on a ``--grid``^3 grid (issue 37: 100^3 in seconds).

    .venv/bin/python benchmarks/bench_spatial_bounds.py [--poses 1000000] [--grid 100] [--repeats 2]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bench_spatial_kinematics import _best, floor_leg_lengths   # the same floor, in the same folder


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=1_000_000)
    ap.add_argument("--grid", type=int, default=100)
    ap.add_argument("--repeats", type=int, default=2)
    args = ap.parse_args()

    import pmaccuracy as pm
    from pmaccuracy.accuracy.spatial_bounds import spatial_error_components, spatial_pose_errors
    from pmaccuracy.accuracy.spatial_maps import spatial_error_map
    from pmaccuracy.model.spatial_sources import SpatialErrorSources

    robot = pm.load_robot("stewart_6ups")
    sources = SpatialErrorSources.load("ups_typical", robot)
    base = np.array([leg.base for leg in robot.legs])
    platform = np.array([leg.platform for leg in robot.legs])
    rng = np.random.default_rng(0)
    n = args.poses
    poses = robot.home_pose + np.concatenate([rng.uniform(-30, 30, (n, 3)), rng.uniform(-0.05, 0.05, (n, 3))], 1)

    def components():
        return spatial_error_components(robot, sources, poses)

    t_floor = _best(lambda: floor_leg_lengths(base, platform, poses), args.repeats)
    t_comp = _best(components, args.repeats)
    t_all = _best(lambda: spatial_pose_errors(robot, sources, poses, details=False), 1)
    print(f"6-UPS stewart_6ups with ups_typical, {n:,} poses (CPU time)")
    print(f"  floor: leg lengths in plain numpy            {t_floor:7.3f} s")
    print(f"  exact components (dx ... drz)                {t_comp:7.3f} s   ratio {t_comp / t_floor:5.1f} x floor "
          "(target <= 3)")
    print(f"  + |dp|, |dtheta| certified at 0.1 %          {t_all:7.3f} s   ratio {t_all / t_floor:5.1f} x floor "
          "(target <= 10)")
    from pmaccuracy.kinematics.spatial import closure, inverse_kinematics
    parts = [poses[k:k + (1 << 15)] for k in range(0, n, 1 << 15)]
    W = np.concatenate([closure(robot, part, inverse_kinematics(robot, part).q).wrenches for part in parts])
    t_inv = _best(lambda: np.linalg.inv(W), args.repeats)
    print(f"  of which the batched LAPACK inverse of W    {t_inv:7.3f} s   ratio {t_inv / t_floor:5.1f} x floor "
          "(one 6x6 inverse per pose; the joint-limit checks, strokes, cones and leg capsules, are most of the rest)")
    t0 = time.perf_counter()
    ds = spatial_error_map(robot, sources, n=args.grid)
    t_map = time.perf_counter() - t0
    inside = int(ds.dp_max.notnull().sum())
    print(f"  map {args.grid}^3 grid ({inside:,} points inside)      {t_map:7.2f} s wall (workspace search and "
          "grid included)")


if __name__ == "__main__":
    main()
