"""Benchmark: exact worst-case pose errors vs the paper-style SLSQP baseline, measured in the same run.

Prints poses per second of :func:`pmaccuracy.accuracy.bounds.max_pose_errors` on 10^6 poses,
the SLSQP baseline's poses per second on a small sample, their ratio, and the
peak memory of the exact run (tracemalloc, numpy allocations included).

    .venv/bin/python benchmarks/bench_bounds.py [--poses 1000000] [--slsqp-poses 20]
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

import numpy as np

from pmaccuracy import Manipulator
from pmaccuracy.accuracy.bounds import max_pose_errors, slsqp_max_pose_errors
from pmaccuracy.model.clearances import ClearanceSet
from pmaccuracy.kinematics.workspace import constant_orientation_workspace


def random_poses(robot: Manipulator, n: int, rng: np.random.Generator) -> np.ndarray:
    """n poses inside the workspace at random orientations in [-30, 30] deg (rejection sampling)."""
    out = []
    while sum(len(p) for p in out) < n:
        phi = rng.uniform(-np.pi / 6, np.pi / 6)
        ws = constant_orientation_workspace(robot, phi)
        (x0, x1), (y0, y1) = ws.bounds
        cand = np.column_stack([rng.uniform(x0, x1, 4096), rng.uniform(y0, y1, 4096), np.full(4096, phi)])
        out.append(cand[ws.contains(cand[:, :2])])
    return np.concatenate(out)[:n]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=1_000_000)
    parser.add_argument("--slsqp-poses", type=int, default=20)
    parser.add_argument("--clearances", default="all")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    robot = Manipulator.preset("aalborg_3ppr")
    clearances = ClearanceSet.load(args.clearances)
    rng = np.random.default_rng(args.seed)
    poses = random_poses(robot, args.poses, rng)
    max_pose_errors(robot, clearances, poses[:1000])  # warm-up

    tracemalloc.start()
    t0 = time.perf_counter()
    exact = max_pose_errors(robot, clearances, poses)
    t_exact = time.perf_counter() - t0
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()

    sample = poses[:: max(1, len(poses) // args.slsqp_poses)][: args.slsqp_poses]
    t0 = time.perf_counter()
    base = slsqp_max_pose_errors(robot, clearances, sample)
    t_slsqp = time.perf_counter() - t0

    idx = np.arange(0, len(poses), max(1, len(poses) // args.slsqp_poses))[: args.slsqp_poses]
    gap = max(float(np.max(getattr(base, q) - getattr(exact, q)[idx])) for q in ("dx_max", "dy_max", "dphi_max", "dp_max"))
    rate_exact = len(poses) / t_exact
    rate_slsqp = len(sample) / t_slsqp
    print(f"robot {robot.name}, clearances {clearances.name}")
    print(f"exact : {len(poses):>9d} poses in {t_exact:8.3f} s -> {rate_exact:12.0f} poses/s "
          f"({1e6 * t_exact / len(poses):.2f} us/pose), peak memory {peak / 2**20:.0f} MiB")
    print(f"slsqp : {len(sample):>9d} poses in {t_slsqp:8.3f} s -> {rate_slsqp:12.1f} poses/s "
          f"({1e3 * t_slsqp / len(sample):.1f} ms/pose)")
    print(f"speed-up exact / slsqp: {rate_exact / rate_slsqp:,.0f}x per pose")
    print(f"largest excess of slsqp over exact on the sample: {gap:.2e} (never positive beyond rounding)")


if __name__ == "__main__":
    main()
