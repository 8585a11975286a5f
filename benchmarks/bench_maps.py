"""Benchmark: error-map throughput, single process vs Dask, and memory of a 1000 x 1000 x 3 map.

Both methods run in the same process on the same map; the Dask run uses the
local threaded scheduler (or ``--distributed`` for a local dask.distributed
cluster). Prints grid points per second and their ratio.

    .venv/bin/python benchmarks/bench_maps.py [--grid 1000] [--distributed]
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

import numpy as np

from pmaccuracy.accuracy.maps import error_map


def timed(label: str, n_points: int, **kwargs) -> tuple[float, object]:
    t0 = time.perf_counter()
    ds = error_map("aalborg_3ppr", "case2", np.radians([0.0, 30.0, -30.0]), **kwargs)
    dt = time.perf_counter() - t0
    inside = int(np.isfinite(ds.dp_max.values).sum())
    print(f"{label:<22s} {n_points:>10d} grid points ({inside} inside) in {dt:7.2f} s -> "
          f"{n_points / dt:12.0f} points/s")
    return dt, ds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", type=int, default=1000)
    parser.add_argument("--chunk", type=int, default=1 << 18)
    parser.add_argument("--distributed", action="store_true", help="also run on a local dask.distributed Client")
    args = parser.parse_args()
    n_points = 3 * args.grid**2
    error_map("aalborg_3ppr", "case2", 0.0, 21)  # warm-up

    tracemalloc.start()
    t_single, ds = timed("single process", n_points, n=args.grid, chunk_size=args.chunk)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    print(f"peak memory of the single-process map: {peak / 2**20:.0f} MiB; dataset {ds.nbytes / 2**20:.0f} MiB")

    t_dask, ds_dask = timed("dask (threads)", n_points, n=args.grid, chunk_size=args.chunk, use_dask=True)
    same = bool(np.array_equal(ds.dp_max.values, ds_dask.dp_max.values, equal_nan=True))
    print(f"dask / single speed ratio: {t_single / t_dask:.2f}; identical results: {same}")
    if args.distributed:
        from dask.distributed import Client, LocalCluster

        with LocalCluster(n_workers=2, threads_per_worker=1) as cluster, Client(cluster):
            t_dist, _ = timed("dask.distributed (2w)", n_points, n=args.grid, chunk_size=args.chunk,
                              use_dask=True)
        print(f"distributed / single speed ratio: {t_single / t_dist:.2f}")


if __name__ == "__main__":
    main()
