"""Benchmark: the public calls as users make them, in wall time, against the floor (issue 26's measurement).

For each preset with its clearance preset, measured in the same run (wall clock, best of ``--repeats``):

* ``pm.error_map(robot, clearances, two orientations, n)`` (defaults otherwise) against two floors: a plain
  numpy inverse kinematics (:func:`bench_floor.plain_ik`, checked against the library there) of the same
  ``2 n^2`` grid points with trig per pose, and the same with one cosine and sine per layer (goal: 5x the
  per-pose floor);
* ``pmaccuracy.accuracy.maps.write_map`` of the same map into a NetCDF file (the ``map`` command's path, minus
  the command's start-up) against the per-pose floor (goal: 5x);
* ``pm.max_pose_errors`` of ``--poses`` poses inside the workspace against the per-pose floor (goal: 3x);
* ``pmaccuracy map --grid G`` (NetCDF and CSV output): the peak resident memory of the command (every process,
  ``getrusage`` of the children) above the same command at ``--grid 11``, divided by the map's dataset size
  (goal: 1.3).

    .venv/bin/python benchmarks/bench_public.py [--grid 1000] [--poses 1000000] [--map-grid 1500] [--repeats 2]
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import pmaccuracy as pm  # noqa: E402
from bench_floor import inside_poses, plain_ik  # noqa: E402
from pmaccuracy.accuracy.maps import write_map  # noqa: E402

CASES = (("aalborg_3ppr", "case1", (0.0, 30.0)), ("symmetric_3rpr", "rpr_typical", (0.0, 10.0)),
         ("symmetric_3rrr", "rrr_typical", (0.0, 10.0)), ("symmetric_3prr", "prr_typical", (0.0, 10.0)))


def best_wall(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def child_peak_mib(argv: list[str]) -> float:
    """Peak resident memory (MiB) of a command run in a fresh process (its largest child, via a wrapper)."""
    code = ("import resource, subprocess, sys; subprocess.run(sys.argv[1:], check=True, stdout=subprocess.DEVNULL); "
            "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    out = subprocess.run([sys.executable, "-c", code, *argv], check=True, capture_output=True, text=True).stdout
    return int(out.strip().splitlines()[-1]) / 1024   # ru_maxrss is in KiB on Linux


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", type=int, default=1000)
    parser.add_argument("--poses", type=int, default=1_000_000)
    parser.add_argument("--map-grid", type=int, default=1500)
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    print(f"{'robot':<16} {'floor/pose':>10} {'floor/layer':>11} {'error_map':>9} {'ratio':>6} {'(layer)':>7}   "
          f"{'to .nc':>7} {'ratio':>6}   {'floor':>7} {'bounds':>7} {'ratio':>6}")
    for name, clear, phis_deg in CASES:
        robot = pm.load_robot(name)
        cl = pm.load_clearances(clear, robot)
        phis = np.radians(phis_deg)
        probe = pm.error_map(robot, cl, phis, 21, progress=False)
        xs = np.linspace(float(probe.x[0]), float(probe.x[-1]), args.grid)
        ys = np.linspace(float(probe.y[0]), float(probe.y[-1]), args.grid)
        X, Y = np.meshgrid(xs, ys)
        layers = [np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, p)]) for p in phis]
        grid = np.concatenate(layers)
        with np.errstate(invalid="ignore"):
            f_pose = best_wall(lambda: plain_ik(robot, grid), args.repeats)
            f_layer = best_wall(lambda: [plain_ik(robot, layer, constant_phi=True) for layer in layers], args.repeats)
        t_map = best_wall(lambda: pm.error_map(robot, cl, phis, args.grid), args.repeats)
        with tempfile.TemporaryDirectory() as tmp:   # the map command's path: computed straight into the file
            t_file = best_wall(lambda: write_map(Path(tmp) / "m.nc", robot, cl, phis, args.grid, progress=False),
                               args.repeats)
        poses = inside_poses(robot, phis_deg, args.poses, rng)
        f_b = best_wall(lambda: plain_ik(robot, poses), args.repeats)
        t_b = best_wall(lambda: pm.max_pose_errors(robot, cl, poses, singular="nan"), args.repeats)
        print(f"{name:<16} {f_pose:9.3f}s {f_layer:10.3f}s {t_map:8.3f}s {t_map / f_pose:5.2f}x {t_map / f_layer:6.2f}x"
              f"   {t_file:6.3f}s {t_file / f_pose:5.2f}x   {f_b:6.3f}s {t_b:6.3f}s {t_b / f_b:5.2f}x", flush=True)
    print(f"(maps: 2 x {args.grid}^2 grid points, 'to .nc': maps.write_map, the map command's path; bounds: {args.poses} poses inside the workspace; wall time, "
          f"best of {args.repeats})")

    exe = str(Path(sys.executable).with_name("pmaccuracy"))
    with tempfile.TemporaryDirectory() as tmp:
        for suffix in (".nc", ".csv"):
            def run(g: int) -> float:
                return child_peak_mib([exe, "map", "--robot", "aalborg_3ppr", "--clearances", "case1", "--grid",
                                       str(g), "--phi-deg", "0", "--phi-deg", "30", "--out",
                                       str(Path(tmp) / f"m{g}{suffix}"), "--quiet"])
            small, big = run(11), run(args.map_grid)
            dataset = pm.load_map(Path(tmp) / f"m{args.map_grid}.nc").nbytes / 2**20 if suffix == ".nc" else dataset
            print(f"map --grid {args.map_grid} {suffix:<4}: peak {big:7.1f} MiB, --grid 11 {small:6.1f} MiB, dataset "
                  f"{dataset:6.1f} MiB: (peak - small) / dataset = {(big - small) / dataset:4.2f}", flush=True)


if __name__ == "__main__":
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    main()
