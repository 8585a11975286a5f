"""Benchmark of issue 11 (scale), every number measured in this run, side by side:

1. ``pmaccuracy bounds --poses-csv`` on 10^6 poses (csv and table output) / the library call on the same poses;
2. ``pmaccuracy --help`` and a one-pose ``bounds`` / ``python -c "import numpy"`` (best of 5 runs each);
3. peak memory of an in-memory map (tracemalloc) / its dataset;
4. Zarr map throughput with 1 and 2 local workers (threads);
5. ``pmaccuracy reproduce`` now / at the commit before this work (``--before`` a source tree of it,
   e.g. ``git worktree add /tmp/pm_before 478cb1a``; skipped if missing).

    .venv/bin/python benchmarks/bench_scale.py [--poses 1000000] [--before /tmp/pm_before/src]
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_bounds import random_poses  # noqa: E402

HERE = Path(__file__).resolve().parents[1]


def wall(cmd: list[str], env: dict | None = None, repeat: int = 1) -> float:
    """Best wall time of ``repeat`` runs of a command (stdout discarded), s."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=1_000_000)
    parser.add_argument("--map-grid", type=int, default=1000)
    parser.add_argument("--zarr-grid", type=int, default=1500)
    parser.add_argument("--before", default="/tmp/pm_before/src")
    args = parser.parse_args()
    py = sys.executable
    cli = [py, "-m", "pmaccuracy.cli"]
    tmp = Path(tempfile.mkdtemp(prefix="pm_bench_"))
    try:
        from pmaccuracy import Manipulator
        from pmaccuracy.accuracy.bounds import max_pose_errors
        from pmaccuracy.model.clearances import ClearanceSet
        from pmaccuracy.io.csvio import write_csv_columns
        from pmaccuracy.accuracy.maps import error_map, write_zarr_map

        # 1. bounds --poses-csv vs the library
        robot = Manipulator.preset("aalborg_3ppr")
        poses = random_poses(robot, args.poses, np.random.default_rng(0))
        csv_path = tmp / "poses.csv"
        write_csv_columns({"x": poses[:, 0], "y": poses[:, 1], "phi_deg": np.degrees(poses[:, 2])}, csv_path)
        case1 = ClearanceSet.load("case1")
        max_pose_errors(robot, case1, poses[:1000])
        t0 = time.perf_counter()
        max_pose_errors(robot, case1, poses)
        t_lib = time.perf_counter() - t0
        t_csv = wall(cli + ["bounds", "--poses-csv", str(csv_path), "--format", "csv"])
        t_table = wall(cli + ["bounds", "--poses-csv", str(csv_path)])
        print(f"[1] {args.poses} poses: library {t_lib:.2f} s; CLI --format csv {t_csv:.2f} s "
              f"(ratio {t_csv / t_lib:.2f}); CLI table {t_table:.2f} s (ratio {t_table / t_lib:.2f})")

        # 2. start-up
        t_np = wall([py, "-c", "import numpy"], repeat=5)
        t_help = wall(cli + ["--help"], repeat=5)
        t_one = wall(cli + ["bounds", "--pose", "0", "0", "0"], repeat=5)
        print(f"[2] python -c 'import numpy' {t_np:.3f} s; pmaccuracy --help {t_help:.3f} s "
              f"(ratio {t_help / t_np:.2f}); one-pose bounds {t_one:.3f} s (ratio {t_one / t_np:.2f})")

        # 3. map peak memory / dataset
        phis = np.radians([0.0, 30.0, -30.0])
        error_map(robot, "case2", phis, 21)
        tracemalloc.start()
        t0 = time.perf_counter()
        ds = error_map(robot, "case2", phis, args.map_grid)
        t_map = time.perf_counter() - t0
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        print(f"[3] in-memory map 3 x {args.map_grid}^2 in {t_map:.2f} s: peak {peak / 2**20:.0f} MiB, dataset "
              f"{ds.nbytes / 2**20:.0f} MiB, ratio {peak / ds.nbytes:.3f}")
        del ds

        # 4. Zarr throughput, 1 and 2 workers (local threads)
        points = 3 * args.zarr_grid**2
        rates = {}
        for workers in (1, 2):
            store = tmp / f"w{workers}.zarr"
            t0 = time.perf_counter()
            write_zarr_map(store, robot, "case2", phis, args.zarr_grid, workers=workers, progress=False)
            rates[workers] = points / (time.perf_counter() - t0)
            shutil.rmtree(store)
        print(f"[4] Zarr map 3 x {args.zarr_grid}^2: 1 worker {rates[1]:,.0f} points/s, 2 workers "
              f"{rates[2]:,.0f} points/s (x{rates[2] / rates[1]:.2f})")

        # 5. reproduce now vs before
        t_now = wall(cli + ["reproduce", "--out", str(tmp / "now")])
        if Path(args.before).is_dir():
            env = {**os.environ, "PYTHONPATH": args.before}
            t_before = wall(cli + ["reproduce", "--out", str(tmp / "before")], env=env)
            same = sorted(p.name for p in (tmp / "now").rglob("*.png"))
            print(f"[5] reproduce: before {t_before:.1f} s, now {t_now:.1f} s, speed-up x{t_before / t_now:.2f} "
                  f"({len(list((tmp / 'before').rglob('*.png')))} PNGs before, {len(same)} now)")
        else:
            print(f"[5] reproduce now {t_now:.1f} s (no --before tree at {args.before})")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
