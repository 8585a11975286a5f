"""Benchmark: the first call in a fresh process against the steady state, both against the floor (issue 35).

For each preset with its clearance preset, and for each of ``error_map`` (two orientations, ``n x n`` grid),
``write_map`` (the same map into a NetCDF file, the ``map`` command's path) and ``max_pose_errors``
(``--poses`` poses inside the workspace), one fresh interpreter measures, after its imports and inputs:

1. the first call of the function (nothing of the library has run yet in that process);
2. the floor, best of ``--repeats``: a plain vectorized inverse kinematics of the same poses
   (:func:`bench_floor.plain_ik`, checked against the library there), per layer with one cosine and sine for
   the maps (as the map computes them), per pose for the bounds;
3. the same call again, best of 4 (the steady state).

It prints ``first / floor``, ``best / floor`` and ``first / best`` side by side (goals: maps at most 5x
and bounds at most 3x the floor, first and steady alike; the first call within 1.5x of the steady one).
Times are the child's CPU time (every kernel is single-threaded; other work on the machine disturbs CPU
time less than the wall clock), page faults included; the wall times are printed too.

Then the command line's pose-file path: ``pmaccuracy bounds --poses-csv FILE --format csv`` on ``--poses``
poses (a whole process, start-up and imports included) against its text-I/O floor measured in this
process after a warm-up: ``pyarrow.csv.read_csv`` of the file, ``max_pose_errors`` of its poses and
``pyarrow.csv.write_csv`` of the seven output columns to a file (goal: 1.5x). Best of ``--repeats``; CPU time
of the command from ``getrusage`` of the children, wall time alongside.

    .venv/bin/python benchmarks/bench_first_call.py [--grid 1000] [--poses 1000000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

CASES = (("aalborg_3ppr", "case1", (0.0, 30.0)), ("symmetric_3rpr", "rpr_typical", (0.0, 10.0)),
         ("symmetric_3rrr", "rrr_typical", (0.0, 10.0)), ("symmetric_3prr", "prr_typical", (0.0, 10.0)))
CALLS = ("error_map", "write_map", "max_pose_errors")

CHILD = r"""
import json, sys, tempfile, time
from pathlib import Path
sys.path.insert(0, {here!r})
import numpy as np
import pmaccuracy as pm
from pmaccuracy.accuracy.maps import error_map, map_grid, write_map
from pmaccuracy.accuracy.bounds import max_pose_errors
from bench_floor import inside_poses, plain_ik

name, clear, phis_deg, call, n, n_poses, repeats = {args!r}
robot = pm.load_robot(name)
cl = pm.load_clearances(clear, robot)
phis = np.radians(phis_deg)
tmp = Path(tempfile.mkdtemp(prefix="pm_first_"))
if call == "max_pose_errors":
    poses = inside_poses(robot, phis_deg, n_poses, np.random.default_rng(0))
    run = lambda: max_pose_errors(robot, cl, poses, singular="nan")
    floor = lambda: plain_ik(robot, poses)
else:
    xs, ys = map_grid(robot, phis, n)   # the map's grid (no kernel call)
    X, Y = np.meshgrid(xs, ys)
    layers = [np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, p)]) for p in phis]
    floor = lambda: [plain_ik(robot, layer, constant_phi=True) for layer in layers]
    if call == "error_map":
        run = lambda: error_map(robot, cl, phis, n, progress=False)
    else:
        run = lambda: write_map(tmp / "m.nc", robot, cl, phis, n, progress=False)

def timed(fn):
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return time.process_time() - c0, time.perf_counter() - t0, out

first_cpu, first_wall, out = timed(run)
del out
with np.errstate(invalid="ignore"):   # the grid's corners lie out of reach: NaN, as they should
    floors = [timed(floor)[:2] for _ in range(repeats)]
steady = []
for _ in range(4):
    cpu, wall, out = timed(run)
    del out
    steady.append((cpu, wall))
print(json.dumps({{"first": [first_cpu, first_wall], "floor": [min(c for c, _ in floors), min(w for _, w in floors)],
                  "best": [min(c for c, _ in steady), min(w for _, w in steady)]}}))
"""


def child(name: str, clear: str, phis_deg, call: str, n: int, n_poses: int, repeats: int) -> dict:
    code = CHILD.format(here=str(HERE), args=(name, clear, tuple(phis_deg), call, n, n_poses, repeats))
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def io_floor(csv_path: Path, out_path: Path, robot, clearances) -> tuple[float, float]:
    """(CPU, wall) s of reading the poses with pyarrow, the library call and writing the 7 columns with pyarrow."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.csv as pcsv

    from pmaccuracy.accuracy.bounds import max_pose_errors

    t0, c0 = time.perf_counter(), time.process_time()
    table = pcsv.read_csv(csv_path)
    poses = np.column_stack([table.column(c).to_numpy() for c in ("x", "y", "phi_deg")])
    poses[:, 2] = np.radians(poses[:, 2])
    b = max_pose_errors(robot, clearances, poses)
    out = pa.table({"x": poses[:, 0], "y": poses[:, 1], "phi_deg": np.degrees(poses[:, 2]), "dx_max": b.dx_max,
                    "dy_max": b.dy_max, "dphi_max_deg": b.dphi_max_deg, "dp_max": b.dp_max})
    pcsv.write_csv(out, out_path)
    return time.process_time() - c0, time.perf_counter() - t0


def cli_run(argv: list[str], out_path: Path) -> tuple[float, float]:
    """(CPU, wall) s of one command in a fresh process (CPU: user + system of the child)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    with open(out_path, "wb") as fh:
        subprocess.run(argv, check=True, stdout=fh)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", type=int, default=1000)
    parser.add_argument("--poses", type=int, default=1_000_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--skip-cli", action="store_true", help="only the library calls")
    parser.add_argument("--cli-only", action="store_true", help="only the command line's pose-file path")
    args = parser.parse_args()
    if not args.cli_only:
        library_calls(args)
    if not args.skip_cli:
        command_line(args)


def library_calls(args: argparse.Namespace) -> None:
    print(f"{'robot':<16} {'call':<16} {'floor':>7} {'first':>7} {'best':>7} {'first/floor':>11} {'best/floor':>10} "
          f"{'first/best':>10}   {'wall: first/best':>16}")
    for name, clear, phis_deg in CASES:
        for call in CALLS:
            r = child(name, clear, phis_deg, call, args.grid, args.poses, args.repeats)
            (f_cpu, f_wall), (fl_cpu, _), (b_cpu, b_wall) = r["first"], r["floor"], r["best"]
            print(f"{name:<16} {call:<16} {fl_cpu:6.3f}s {f_cpu:6.3f}s {b_cpu:6.3f}s {f_cpu / fl_cpu:10.2f}x "
                  f"{b_cpu / fl_cpu:9.2f}x {f_cpu / b_cpu:9.2f}x   {f_wall:6.3f}/{b_wall:6.3f}s", flush=True)
    print(f"(maps: 2 orientations x {args.grid}^2 grid points, floor per layer; bounds: {args.poses} poses inside "
          f"the workspace, floor per pose; CPU time of a fresh process per row, imports excluded; floor best of "
          f"{args.repeats}, steady best of 4)")


def command_line(args: argparse.Namespace) -> None:
    import numpy as np

    sys.path.insert(0, str(HERE))
    from bench_bounds import random_poses

    import pmaccuracy as pm
    from pmaccuracy.io.csvio import write_csv_columns

    robot = pm.load_robot("aalborg_3ppr")
    clearances = pm.load_clearances("case1", robot)
    with tempfile.TemporaryDirectory() as tmp:
        csv_path, out_path = Path(tmp) / "poses.csv", Path(tmp) / "out.csv"
        poses = random_poses(robot, args.poses, np.random.default_rng(0))
        write_csv_columns({"x": poses[:, 0], "y": poses[:, 1], "phi_deg": np.degrees(poses[:, 2])}, csv_path)
        io_floor(csv_path, out_path, robot, clearances)   # warm-up (imports, pandas included, and the library)
        floors = [io_floor(csv_path, out_path, robot, clearances) for _ in range(args.repeats)]
        argv = [sys.executable, "-m", "pmaccuracy.cli", "bounds", "--poses-csv", str(csv_path), "--format", "csv"]
        env_path = os.environ.get("PYTHONPATH")
        runs = [cli_run(argv, out_path) for _ in range(args.repeats)]
        f_cpu, f_wall = min(c for c, _ in floors), min(w for _, w in floors)
        c_cpu, c_wall = min(c for c, _ in runs), min(w for _, w in runs)
        print(f"bounds --poses-csv, {args.poses} poses, --format csv: command {c_cpu:.3f} s CPU ({c_wall:.3f} s wall); "
              f"text-I/O floor {f_cpu:.3f} s CPU ({f_wall:.3f} s wall): {c_cpu / f_cpu:.2f}x CPU, {c_wall / f_wall:.2f}x "
              f"wall (best of {args.repeats}{'' if env_path is None else ', PYTHONPATH=' + env_path})")


if __name__ == "__main__":
    main()
