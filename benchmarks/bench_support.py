"""Benchmark: certified largest norm of a Minkowski sum (pmaccuracy.numerics.support.max_norm).

Two random hexapod-like mixes per pose, timed in process CPU time (the kernels are single-threaded numpy):

* general: 6 balls (ellipsoids, d = 3) and 12 segments, branch and bound at ``--gap`` (default 1e-3);
* zonotope: 12 segments only, solved exactly by vertex enumeration;
* isotropic: 6 true balls ``r_j I`` and 12 segments (exact: the balls come out, then the zonotope).

Printed: total seconds, microseconds per pose, the share of certified poses and the largest relative gap.

    .venv/bin/python benchmarks/bench_support.py [--poses 1000000 100000] [--gap 1e-3] [--repeats 1]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from pmaccuracy.numerics.support import max_norm


def hexapod_like(n: int, seed: int = 0) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """6 random ellipsoids (joint clearances of size ~0.3) and 12 random segments (~1), per pose."""
    rng = np.random.default_rng(seed)
    balls = [0.3 * rng.normal(size=(n, 3, 3)) for _ in range(6)]
    segs = [rng.normal(size=(n, 3, 1)) for _ in range(12)]
    return balls, segs


def _time(fn, repeats: int):
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.process_time()
        out = fn()
        best = min(best, time.process_time() - t0)
    return best, out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, nargs="+", default=[100_000, 1_000_000])
    ap.add_argument("--gap", type=float, default=1e-3)
    ap.add_argument("--repeats", type=int, default=1)
    args = ap.parse_args(argv)
    for n in args.poses:
        balls, segs = hexapod_like(n)
        t, r = _time(lambda: max_norm(balls + segs, gap=args.gap), args.repeats)
        rel = np.max((r.upper - r.lower) / r.lower)
        print(f"general  6 balls + 12 segments, N = {n:>8}: {t:8.2f} s  {1e6 * t / n:8.2f} us/pose  "
              f"certified {r.certified.mean():.4f}  max gap {rel:.2e}")
        t, r = _time(lambda: max_norm(segs), args.repeats)
        print(f"zonotope 12 segments (exact),      N = {n:>8}: {t:8.2f} s  {1e6 * t / n:8.2f} us/pose  "
              f"exact {r.exact.mean():.4f}")
        iso = [np.broadcast_to(0.3 * np.eye(3), (n, 3, 3)) for _ in range(6)]
        t, r = _time(lambda: max_norm(iso + segs), args.repeats)
        print(f"isotropic 6 r I + 12 segments,     N = {n:>8}: {t:8.2f} s  {1e6 * t / n:8.2f} us/pose  "
              f"exact {r.exact.mean():.4f}")


if __name__ == "__main__":
    main()
