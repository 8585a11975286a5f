"""Benchmark: spatial kinematics against the floor, a plain vectorized leg-length computation in numpy.

The floor is what any user would write first for a hexapod: rotation matrices from the poses' rotation vectors
(scipy ``Rotation``, as the library takes them) and ``|p + R b_i - A_i|`` over the whole array, written here from
the robot file's points, independently of the library, and checked against ``pm.inverse_kinematics`` before
anything is timed.

Printed, measured in the same run (best of ``--repeats``, process CPU time; the kernels are single-threaded):

* inverse kinematics of ``--poses`` hexapod poses (issue 36: within 2x the floor), the actuated values only
  (the joint limits and leg interference are computed when asked for; their time is printed too);
* Newton forward kinematics of ``--fk-poses`` poses from the home pose (issue 36: under a second for 10^5);
* every assembly mode of a general 6-UPS (when the homotopy solver is installed) beside the public fkSGP
  Python solver's 0.67 s a solve, measured on this machine (martyushev/fkSGP; not run here);
* the first call of each in a fresh process (``--first-call``): what a user who calls once waits.

    .venv/bin/python benchmarks/bench_spatial_kinematics.py [--poses 1000000] [--fk-poses 100000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time

import numpy as np
from scipy.spatial.transform import Rotation

#: fkSGP (martyushev/fkSGP, Python) on this machine: seconds for every assembly mode of one general 6-SPS.
FKSGP_SECONDS = 0.67


def floor_leg_lengths(base: np.ndarray, platform: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """``|p + R b_i - A_i|`` ``(N, 6)`` in plain numpy: the floor."""
    R = Rotation.from_rotvec(poses[:, 3:]).as_matrix()
    B = poses[:, None, :3] + np.einsum("nij,kj->nki", R, platform)
    return np.sqrt(np.sum((B - base) ** 2, axis=-1))


def _best(fn, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def _poses(robot, n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    home = robot.home_pose
    return home + np.concatenate([rng.uniform(-40, 40, (n, 3)), rng.uniform(-0.1, 0.1, (n, 3))], axis=1)


def first_call() -> None:
    """Time the first IK, FK and Jacobian call in fresh processes (imports included)."""
    snippets = {
        "import + first inverse_kinematics (1 pose)":
            "import pmaccuracy as pm; r = pm.load_robot('stewart_6ups'); pm.inverse_kinematics(r, r.home_pose).q",
        "import + first forward_kinematics (Newton, 1 pose)":
            "import pmaccuracy as pm; r = pm.load_robot('stewart_6ups'); "
            "pm.forward_kinematics(r, [[460.0] * 6])",
        "import + first jacobians (1 pose)":
            "import pmaccuracy as pm; r = pm.load_robot('stewart_6ups'); pm.jacobians(r, r.home_pose).forward",
    }
    for label, code in snippets.items():
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-c", code], check=True)
        print(f"  {label:55s} {time.perf_counter() - t0:6.2f} s wall (fresh process)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=1_000_000)
    ap.add_argument("--fk-poses", type=int, default=100_000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--first-call", action="store_true", help="also time first calls in fresh processes")
    args = ap.parse_args()

    import pmaccuracy as pm
    from pmaccuracy.kinematics import spatial

    robot = pm.load_robot("stewart_6ups")
    base = np.array([leg.base for leg in robot.legs])
    platform = np.array([leg.platform for leg in robot.legs])
    poses = _poses(robot, args.poses)
    floor_q = floor_leg_lengths(base, platform, poses)
    lib_q = pm.inverse_kinematics(robot, poses).q
    assert np.allclose(lib_q, floor_q, rtol=0, atol=1e-9), "library and floor disagree"

    t_floor = _best(lambda: floor_leg_lengths(base, platform, poses), args.repeats)
    t_ik = _best(lambda: pm.inverse_kinematics(robot, poses).q, args.repeats)
    small = poses[: max(1, args.poses // 10)]
    t_limits = _best(lambda: pm.inverse_kinematics(robot, small).within_limits, 1) * (len(poses) / len(small))
    print(f"6-UPS stewart_6ups, {args.poses:,} poses (CPU time, best of {args.repeats})")
    print(f"  floor: leg lengths in plain numpy          {t_floor:7.3f} s")
    print(f"  pm.inverse_kinematics (actuated values)    {t_ik:7.3f} s   ratio {t_ik / t_floor:5.2f} x floor "
          "(target <= 2)")
    print(f"  + every joint limit and leg interference   {t_limits:7.3f} s   (extrapolated from "
          f"{len(small):,} poses)")

    fk_poses = _poses(robot, args.fk_poses, seed=1)
    q = floor_leg_lengths(base, platform, fk_poses)
    t_fk = _best(lambda: spatial.forward_kinematics(robot, q), args.repeats)
    fk = spatial.forward_kinematics(robot, q)
    err = float(np.max(np.abs(fk.poses[:, :3] - fk_poses[:, :3])))
    print(f"  Newton forward kinematics, {args.fk_poses:,} poses  {t_fk:7.3f} s   (target < 1 s; "
          f"{fk.iterations} iterations, {int(fk.converged.sum()):,} converged, max position error {err:.1e} mm)")

    try:
        from pmaccuracy.kinematics.assembly_modes import assembly_modes  # noqa: F401
    except ImportError:
        print("  every assembly mode: the homotopy solver is not installed in this checkout")
    else:
        rng = np.random.default_rng(7)
        A = rng.uniform(-300, 300, (6, 3)) * [1, 1, 0.2]
        b = rng.uniform(-150, 150, (6, 3)) * [1, 1, 0.2]
        p = np.array([10.0, -20.0, 400.0])
        R = Rotation.from_rotvec([0.1, -0.05, 0.2]).as_matrix()
        L = np.linalg.norm(p + b @ R.T - A, axis=-1)
        spheres = list(zip(A, b, L))
        from pmaccuracy.kinematics.assembly_modes import assembly_modes as solve

        solve(spheres)          # warm
        t_modes = _best(lambda: solve(spheres), args.repeats)
        found = solve(spheres)
        print(f"  every assembly mode, general 6-UPS         {t_modes:7.3f} s   ratio {t_modes / FKSGP_SECONDS:5.2f} "
              f"x fkSGP's {FKSGP_SECONDS} s (target < 1); {found.count} real modes, {found.paths} paths, "
              f"{found.failed} failed")
    if args.first_call:
        first_call()


if __name__ == "__main__":
    main()
