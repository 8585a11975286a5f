"""Benchmark: calibration speed (issue 23's goals), wall clock, best of ``--repeats``.

* identify 100 poses of the symmetric 3-RRR (27 parameters, 24 identifiable) from simulated measurements
  (goal: under 2 s);
* plan 30 poses out of about 10^4 candidates (goal: under 10 s);

    PYTHONPATH=src .venv/bin/python benchmarks/bench_calibration.py [--repeats 2]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import pmaccuracy as pm
from pmaccuracy.accuracy.calibration.plan import candidate_poses
from pmaccuracy.accuracy.calibration.simulate import measure, true_parameters


def best(fn, repeats):
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=2)
    args = ap.parse_args()
    pv = pm.error_parameters(pm.Manipulator.preset("symmetric_3rrr"))
    cand = candidate_poses(pv, n=50, n_phi=21)
    idx = np.random.default_rng(0).choice(len(cand), 100, replace=False)
    poses = cand[idx]
    commands = pm.plan_poses.__globals__["commands_for"](pv, pv.nominal, poses)
    true = true_parameters(pv, seed=1, fixed=("frame.x", "frame.y", "frame.phi"))
    meas = measure(pv, true, commands, poses, seed=2)
    ok = np.all(np.isfinite(meas), axis=1)
    sig = np.tile([0.01, 0.01, np.radians(0.01)], (int(ok.sum()), 1))
    data = pm.CalibrationData(tuple(map(str, range(int(ok.sum())))), commands[ok], meas[ok], sig, "<bench>")
    t_id, ident = best(lambda: pm.identify(data, pv), args.repeats)
    print(f"identify: {len(data)} poses, {len(pv.names)} parameters ({len(ident.identifiability.identified)} "
          f"identifiable): {t_id:.3f} s (goal < 2 s)")
    big = candidate_poses(pv, n=60, n_phi=31)
    if len(big) > 10_000:
        big = big[np.random.default_rng(0).choice(len(big), 10_000, replace=False)]
    t_plan, plan = best(lambda: pm.plan_poses(pv, 30, big), args.repeats)
    print(f"plan: 30 of {len(big)} candidates: {t_plan:.3f} s (goal < 10 s); O1 {plan.index['O1']:.4g} vs random "
          f"{plan.random_index['O1']:.4g}, grid {plan.grid_index['O1']:.4g}")


if __name__ == "__main__":
    main()
