"""Benchmark: exact bounds and error maps against the floor, a plain vectorized inverse kinematics.

The floor is what any user would write first: for every leg, the joint values of
its working-mode branch from the closed forms of its type (3-PPR: Eq. 2a/2b;
3-RPR: distance and direction; 3-RRR: law of cosines; 3-PRR: a quadratic),
plain numpy over the whole array of poses. It is written here from the leg
types' parameters, independently of the library, and checked against the
library's inverse kinematics before anything is timed.

For each preset with its clearance preset it prints, measured in the same run
(best of ``--repeats``):

* the floor (IK of 10^6 poses inside the workspace) and ``max_pose_errors`` of
  the same poses, their ratio (issue 9: at most 3x), and the peak memory of the
  bounds beyond the inputs and the four result arrays (at most 100 MiB);
* an error map (``error_map``, 3 orientations x n^2 grid) against the floor IK of
  the same grid points, layer by layer with one cosine and sine per layer (at most 5x).

Times are the process's CPU time (every kernel is single-threaded), so other work
on the machine disturbs them less than a wall clock; ratios still vary by about
+-10 % between runs on a loaded machine.

    .venv/bin/python benchmarks/bench_floor.py [--poses 1000000] [--grid 1000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

import numpy as np

from pmaccuracy import Manipulator
from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.kinematics import inverse_kinematics
from pmaccuracy.model.legs import PPRLeg, PRRLeg, RPRLeg, RRRLeg
from pmaccuracy.accuracy.maps import error_map
from pmaccuracy.io.resolve import load_clearances
from pmaccuracy.kinematics.workspace import constant_orientation_workspace

#: (robot preset, clearance preset, orientations of the poses and maps in deg)
CASES = (("aalborg_3ppr", "case1", (-30.0, 0.0, 30.0)),
         ("symmetric_3rpr", "rpr_typical", (-10.0, 0.0, 10.0)),
         ("symmetric_3rrr", "rrr_typical", (-10.0, 0.0, 10.0)),
         ("symmetric_3prr", "prr_typical", (-10.0, 0.0, 10.0)))


def _wrap(a: np.ndarray) -> np.ndarray:
    return np.pi - np.mod(np.pi - a, 2 * np.pi)


def plain_ik(robot: Manipulator, poses: np.ndarray, constant_phi: bool = False) -> list[tuple[np.ndarray, ...]]:
    """Every joint value of every leg (working mode), ``[(q1, q2, q3) per leg]`` each ``(n,)`` mm / rad.

    ``constant_phi``: every pose has the orientation of the first (a map's layer): its cosine and sine once.
    """
    x, y, phi = poses[:, 0], poses[:, 1], poses[:, 2]
    if constant_phi:
        phi = float(phi[0])
    c, s = np.cos(phi), np.sin(phi)
    out = []
    for leg in robot.legs:
        if isinstance(leg, PPRLeg):          # D = A + s u + d v + l w  (Eq. 1, 2a, 2b)
            px, py = -leg.r * np.cos(leg.psi), -leg.r * np.sin(leg.psi)
            bu = leg.alpha + leg.beta
            ux, uy = np.cos(bu), np.sin(bu)
            vx, vy = np.cos(bu + leg.gamma), np.sin(bu + leg.gamma)
            wx, wy = np.cos(bu + leg.gamma + leg.theta), np.sin(bu + leg.gamma + leg.theta)
            rx = x + c * px - s * py - leg.a * np.cos(leg.alpha) - leg.d * vx
            ry = y + s * px + c * py - leg.a * np.sin(leg.alpha) - leg.d * vy
            den = ux * wy - uy * wx
            q = ((rx * wy - ry * wx) / den, (ux * ry - uy * rx) / den, _wrap(phi - (bu + leg.gamma + leg.theta)))
        elif isinstance(leg, RPRLeg):        # A -> D: direction and length
            dx = x + c * leg.platform[0] - s * leg.platform[1] - leg.base[0]
            dy = y + s * leg.platform[0] + c * leg.platform[1] - leg.base[1]
            t = np.arctan2(dy, dx)
            q = (t, np.hypot(dx, dy), _wrap(phi - t))
        elif isinstance(leg, RRRLeg):        # law of cosines, elbow by the working mode
            dx = x + c * leg.platform[0] - s * leg.platform[1] - leg.base[0]
            dy = y + s * leg.platform[0] + c * leg.platform[1] - leg.base[1]
            L1, L2 = leg.proximal, leg.distal
            cb = (dx * dx + dy * dy - L1 * L1 - L2 * L2) / (2 * L1 * L2)
            b = leg.working_mode * np.arccos(cb)
            t1 = np.arctan2(dy, dx) - np.arctan2(L2 * np.sin(b), L1 + L2 * np.cos(b))
            q = (_wrap(t1), b, _wrap(phi - t1 - b))
        elif isinstance(leg, PRRLeg):        # carriage on the guide at distance `distal` from D
            ga = leg.guide_angle
            dx = x + c * leg.platform[0] - s * leg.platform[1] - leg.guide_point[0]
            dy = y + s * leg.platform[0] + c * leg.platform[1] - leg.guide_point[1]
            lx = np.cos(ga) * dx + np.sin(ga) * dy
            ly = -np.sin(ga) * dx + np.cos(ga) * dy
            sl = lx - leg.working_mode * np.sqrt(leg.distal ** 2 - ly * ly)
            t2 = np.arctan2(ly, lx - sl)
            q = (sl, t2, _wrap(phi - ga - t2))
        else:
            raise TypeError(f"no plain IK for {type(leg).__name__}")
        out.append(q)
    return out


def check_floor(robot: Manipulator, poses: np.ndarray) -> None:
    """The floor computes the same joint values as the library (so the comparison is fair)."""
    ref = inverse_kinematics(robot, poses).joints
    for i, q in enumerate(plain_ik(robot, poses)):
        mine = np.stack(q, axis=-1)
        diff = np.abs(_wrap(mine - ref[:, i, :]))
        assert np.nanmax(diff) < 1e-8, (robot.name, i, np.nanmax(diff))


def inside_poses(robot: Manipulator, phis_deg, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` poses inside the workspace at orientations drawn uniformly from ``[min, max]`` of ``phis_deg``
    (rejection sampling, 64 orientations a batch; shuffled, so no block of poses shares one orientation)."""
    out, have = [], 0
    lo, hi = min(phis_deg), max(phis_deg)
    while have < n:
        phi = np.radians(rng.uniform(lo, hi))
        ws = constant_orientation_workspace(robot, phi)
        (x0, x1), (y0, y1) = ws.bounds
        cand = np.column_stack([rng.uniform(x0, x1, 1 << 14), rng.uniform(y0, y1, 1 << 14), np.full(1 << 14, phi)])
        keep = cand[ws.contains(cand[:, :2])]
        out.append(keep)
        have += len(keep)
    poses = np.concatenate(out)[:n]
    return poses[rng.permutation(n)]


def best_time(fn, repeats: int) -> float:
    """Best CPU time of this process over ``repeats`` calls (s): on a shared machine the CPU time, unlike the
    wall clock, does not count the time other processes hold the cores (every kernel here is single-threaded)."""
    times = []
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        times.append(time.process_time() - t0)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=1_000_000)
    parser.add_argument("--grid", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    print(f"{'robot':<16} {'clearances':<12} {'floor IK':>10} {'bounds':>10} {'ratio':>6} {'extra MiB':>9}   "
          f"{'map floor':>10} {'map':>9} {'ratio':>6}")
    for name, clear, phis_deg in CASES:
        robot = Manipulator.preset(name)
        sources = load_clearances(clear, robot)
        poses = inside_poses(robot, phis_deg, args.poses, rng)
        check_floor(robot, poses[:2000])
        max_pose_errors(robot, sources, poses[:1000], singular="nan")  # warm-up

        t_floor = best_time(lambda: plain_ik(robot, poses), args.repeats)
        t_bounds = best_time(lambda: max_pose_errors(robot, sources, poses, singular="nan"), args.repeats)
        tracemalloc.start()
        max_pose_errors(robot, sources, poses, singular="nan")
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        extra = (peak - 4 * 8 * len(poses)) / 2**20   # beyond the four result arrays (inputs were allocated before)

        phis = np.radians(phis_deg)
        probe = error_map(robot, sources, phis, 21)     # grid coordinates, and a warm-up
        xs = np.linspace(float(probe.x[0]), float(probe.x[-1]), args.grid)
        ys = np.linspace(float(probe.y[0]), float(probe.y[-1]), args.grid)
        X, Y = np.meshgrid(xs, ys)
        layers = [np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, p)]) for p in phis]
        with np.errstate(invalid="ignore"):   # the grid's corners lie out of reach: NaN, as they should
            t_map_floor = best_time(lambda: [plain_ik(robot, layer, constant_phi=True) for layer in layers],
                                    args.repeats)
        t_map = best_time(lambda: error_map(robot, sources, phis, args.grid, progress=False), args.repeats)
        print(f"{name:<16} {clear:<12} {t_floor:9.3f}s {t_bounds:9.3f}s {t_bounds / t_floor:5.2f}x {extra:9.1f}   "
              f"{t_map_floor:9.3f}s {t_map:8.3f}s {t_map / t_map_floor:5.2f}x", flush=True)
    print(f"({args.poses} poses inside the workspace; maps of 3 x {args.grid}^2 grid points; best of {args.repeats})")


if __name__ == "__main__":
    main()
