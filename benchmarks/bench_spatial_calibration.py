"""Benchmark: spatial calibration speed (issue 39's goal), wall clock and process time, best of ``--repeats``.

* identify 200 position-only readings of the 6-UPS (one target: 57 parameters, 45 identifiable) simulated
  with noise and one gross reading (goal: under 3 s);
* floor, measured in the same run: one singular value decomposition of the whitened Jacobian of those readings
  (``(600, 45)``, what every trust-region step of the fit does once) and one evaluation of the model (forward
  kinematics of the 200 commands); the ratio says how many such steps the identification costs;
* plan 60 poses out of ``--candidates`` (10^5) candidates for the same readings (goal: under 20 s), beside the
  floor of one evaluation of every candidate's gain ``log det(I + B_c M^-1 B_c^T)`` (what the plain greedy
  does at each of its 60 steps).

The library runs these steps with one BLAS thread (threadpoolctl): on a loaded machine the default threads'
hand-offs made each decomposition about 100 times slower; the floor's SVD is shown both ways.

    PYTHONPATH=src .venv/bin/python benchmarks/bench_spatial_calibration.py [--readings 200] [--repeats 2]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from threadpoolctl import threadpool_limits

from pmaccuracy.accuracy.calibration.spatial_identify import (identify_spatial, platform_poses, residual_jacobian,
                                                              spatial_identifiability)
from pmaccuracy.accuracy.calibration.spatial_parameters import spatial_error_parameters
from pmaccuracy.accuracy.calibration.spatial_plan import candidate_blocks, plan_spatial_poses
from pmaccuracy.accuracy.calibration.spatial_simulate import (PRACTICAL_MAX_SIGMA, candidate_poses, measure_spatial,
                                                              spatial_true_parameters)
from pmaccuracy.kinematics.spatial import inverse_kinematics
from pmaccuracy.model.spatial import SpatialManipulator


def best(fn, repeats):
    wall, cpu, out = np.inf, np.inf, None
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        wall, cpu = min(wall, time.perf_counter() - t), min(cpu, time.process_time() - c)
    return wall, cpu, out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--readings", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--candidates", type=int, default=100_000)
    args = ap.parse_args(argv)
    pv = spatial_error_parameters(SpatialManipulator.preset("stewart_6ups"), targets=[[20.0, 10.0, 30.0]])
    poses = candidate_poses(pv, 5000, seed=0)[:args.readings]
    commands = inverse_kinematics(pv.robot, poses).q
    probe = measure_spatial(pv, pv.nominal, commands)
    fixed = spatial_identifiability(pv, probe, max_sigma=PRACTICAL_MAX_SIGMA).fixed
    true = spatial_true_parameters(pv, seed=1, fixed=fixed)
    data = measure_spatial(pv, true, commands, noise=(0.01, 0.0), ppm=5.0, seed=2)
    data.measured[7] += 1.0
    wall, cpu, ident = best(lambda: identify_spatial(data, pv), args.repeats)
    free = pv.index(ident.identifiability.identified)
    at = platform_poses(pv, ident.values, data.commands)
    J = (residual_jacobian(pv, ident.values, data, at) / data.sigmas[:, :, None]).reshape(-1, len(pv.names))[:, free]
    with threadpool_limits(limits=1, user_api="blas"):    # as identify_spatial runs
        f_wall, f_cpu, _ = best(lambda: np.linalg.svd(J, full_matrices=False), 5)
    t_wall, _, _ = best(lambda: np.linalg.svd(J, full_matrices=False), 5)
    m_wall, m_cpu, _ = best(lambda: platform_poses(pv, ident.values, data.commands, at), 5)
    print(f"identify: {len(data)} position readings, {len(pv.names)} parameters ({len(free)} identifiable), "
          f"{len(ident.outliers)} outlier(s), {ident.nfev} evaluations: {wall:.3f} s wall, {cpu:.3f} s cpu "
          f"(goal < 3 s)")
    print(f"  floor: one SVD of the ({J.shape[0]}, {J.shape[1]}) Jacobian {f_wall * 1e3:.2f} ms wall with one BLAS "
          f"thread ({t_wall * 1e3:.2f} ms with the default threads); one model evaluation {m_wall * 1e3:.2f} ms wall")
    print(f"  ratio: identify = {wall / (f_wall + m_wall):.0f} x (SVD + evaluation)")

    draws = candidate_poses(pv, int(3.5 * args.candidates), seed=1)[:args.candidates]
    p_wall, p_cpu, plan = best(lambda: plan_spatial_poses(pv, 60, draws), 1)
    B, _ = candidate_blocks(pv, draws)
    Minv = np.linalg.inv(np.einsum("cil,cim->lm", B[plan.indices], B[plan.indices]))
    with threadpool_limits(limits=1, user_api="blas"):
        g_wall, _, _ = best(lambda: np.linalg.slogdet(np.einsum("cil,cjl->cij", (B.reshape(-1, B.shape[2]) @ Minv)
                                                                .reshape(B.shape), B) + np.eye(B.shape[1]))[1], 3)
    print(f"plan: 60 of {len(draws)} candidates: {p_wall:.3f} s wall, {p_cpu:.3f} s cpu (goal < 20 s); O1 "
          f"{plan.index['O1']:.4g} vs random {plan.random_index['O1']:.4g}")
    print(f"  floor: every candidate's gain once {g_wall:.3f} s wall; ratio plan = {p_wall / g_wall:.1f} x floor "
          f"(the plain greedy: 60 x)")


if __name__ == "__main__":
    main()
