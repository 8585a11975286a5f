"""Benchmark: certified nonlinear worst cases against the first-order maxima of the same poses, same run.

For each preset robot with its typical clearances, at 1x and 10x the clearance set and each gap target
(``split_gap``: 0.5 %, the default, and 5 %), prints the cost per pose of
:func:`pmaccuracy.accuracy.certified.certified_pose_errors` (one batch of random poses of the workspace)
next to that of :func:`pmaccuracy.accuracy.bounds.max_pose_errors` on the same poses, their ratio, the
largest gap to the best feasible configuration, the poses not certified and the poses that went on to the
cut error set (split or branch and bound: the costly ones, near singularities or far from first order). With ``--map`` it also times a
certified map of the default robot (``pmaccuracy.accuracy.maps.certified_error_map``, 101 x 101 x 2).

    .venv/bin/python benchmarks/bench_certified.py [--poses 1000] [--factors 1 10] [--gaps-pct 0.5 5] [--map]
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.accuracy.certified import QUANTITIES
from pmaccuracy.io.resolve import load_clearances, robot_arg
from pmaccuracy.kinematics.workspace import constant_orientation_workspace
from pmaccuracy.model.sources import ErrorSources

PRESETS = (("aalborg_3ppr", "case2"), ("symmetric_3ppr", "case2"), ("symmetric_3prr", "prr_typical"),
           ("symmetric_3rpr", "rpr_typical"), ("symmetric_3rrr", "rrr_typical"))


def workspace_poses(robot, sources, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` poses inside the joint ranges at random orientations in [-10, 10] deg, away from singularities
    (those where the first-order model is defined: condition number below its default limit)."""
    out = []
    while sum(len(p) for p in out) < n:
        phi = rng.uniform(-np.pi / 18, np.pi / 18)
        ws = constant_orientation_workspace(robot, phi)
        (x0, x1), (y0, y1) = ws.bounds
        cand = np.column_stack([rng.uniform(x0, x1, 512), rng.uniform(y0, y1, 512), np.full(512, phi)])
        cand = cand[ws.contains(cand[:, :2])]
        if len(cand):
            fo = max_pose_errors(robot, sources, cand, singular="nan", allow_outside=True)
            out.append(cand[np.isfinite(np.asarray(fo.dx_max))])
    return np.concatenate(out)[:n]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=1000)
    parser.add_argument("--factors", type=float, nargs="*", default=[1.0, 10.0])
    parser.add_argument("--gaps-pct", type=float, nargs="*", default=[0.5, 5.0])
    parser.add_argument("--map", action="store_true", help="also time a certified 101 x 101 x 2 map of aalborg_3ppr")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    import pmaccuracy.accuracy.certified as C

    cut = {"_split_bounds": 0, "_branch_and_bound": 0}  # poses handed to the cut error set, per step
    for name in cut:
        f = getattr(C, name)

        def counted(*a, _f=f, _name=name, **kw):
            cut[_name] += a[0].z0.shape[0]
            return _f(*a, **kw)
        setattr(C, name, counted)
    print(f"{'robot':16s} {'clearances':12s} {'x':>4s} {'gap %':>5s} {'poses':>6s} {'certified ms/pose':>18s} "
          f"{'first-order us/pose':>20s} {'ratio':>8s} {'max gap %':>10s} {'refused':>8s} {'split/b&b':>10s}")
    for name, clear in PRESETS:
        robot = robot_arg(name)
        base = load_clearances(clear, robot)
        base = base if isinstance(base, ErrorSources) else ErrorSources.from_clearance_set(base)
        poses = workspace_poses(robot, base, args.poses, rng)
        for factor in args.factors:
            sources = base.scaled(factor)
            for gap_pct in args.gaps_pct:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    t = time.perf_counter()
                    max_pose_errors(robot, sources, poses, allow_outside=True)
                    t_first = time.perf_counter() - t
                    cut.update(dict.fromkeys(cut, 0))
                    t = time.perf_counter()
                    res = C.certified_pose_errors(robot, sources, poses, on_failure="nan", allow_outside=True,
                                                  split_gap=gap_pct / 100)
                    t_cert = time.perf_counter() - t
                gap = max(float(np.nanmax(res.gap[q])) if np.any(np.isfinite(res.gap[q])) else np.nan
                          for q in QUANTITIES)
                refused = int(sum(bool(r) for r in res.reason))
                n = len(poses)
                print(f"{name:16s} {clear:12s} {factor:4g} {gap_pct:5g} {n:6d} {t_cert / n * 1e3:18.3f} "
                      f"{t_first / n * 1e6:20.2f} {t_cert / t_first:8.0f} {gap * 100:10.3f} {refused:8d} "
                      f"{cut['_split_bounds']:5d}/{cut['_branch_and_bound']:<4d}", flush=True)
    if args.map:
        from pmaccuracy.accuracy.maps import certified_error_map

        t = time.perf_counter()
        ds = certified_error_map("aalborg_3ppr", "case2", np.radians([0.0, 5.0]), n=101)
        dt = time.perf_counter() - t
        print(f"certified map aalborg_3ppr case2 101 x 101 x 2: {dt:.1f} s "
              f"({int(np.sum(np.isfinite(ds['dx_max'].values)))} certified grid poses, largest gap "
              f"{float(np.nanmax([ds[q + '_gap'].values for q in QUANTITIES])) * 100:.3g} %)")


if __name__ == "__main__":
    main()
