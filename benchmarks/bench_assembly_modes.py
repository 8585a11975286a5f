"""Benchmark: every real assembly mode of a general 6-UPS (Gough-Stewart) platform, one full solve.

Times :func:`pmaccuracy.kinematics.assembly_modes.assembly_modes` (128-path total-degree homotopy in Study
parameters, then Newton polishing of the real modes) on Dietmaier's 6-UPS with 40 real postures and on random
general 6-UPS robots, in a fresh interpreter:

1. the first call in that process (after its imports and inputs: nothing of the solver has run yet);
2. the steady state: the median of ``--repeats`` further calls.

Beside it, the baseline: the public Python solver martyushev/fkSGP (``solver_fkSGP``, Study-parameter
elimination to a univariate polynomial) at 0.67 s per solve, measured on this machine (not re-run here: it
is not a dependency). Ratio = baseline / ours. Times are wall-clock seconds of the child (CPU time alongside:
the solver is single-threaded numpy, so CPU time is the less disturbed figure on a shared machine).

    .venv/bin/python benchmarks/bench_assembly_modes.py [--repeats 9] [--random 5]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

#: martyushev/fkSGP's Python solver, seconds per solve of a general 6-6 platform, measured on this machine.
FKSGP_SECONDS = 0.67

ROOT = Path(__file__).resolve().parents[1]

CHILD = r"""
import json, sys, time
sys.path.insert(0, {src!r})
import numpy as np
from scipy.spatial.transform import Rotation
from pmaccuracy.kinematics.assembly_modes import assembly_modes

repeats, n_random = {args!r}
# Dietmaier (1998), 40 real postures (numbers as in martyushev/fkSGP python/test1_fkSGP.py)
A = np.array([[0, 0, 0], [1.107915, 0, 0], [0.549094, 0.756063, 0], [0.735077, -0.223935, 0.525991],
              [0.514188, -0.526063, -0.368418], [0.590473, 0.094733, -0.205018]])
b = np.array([[0, 0, 0], [0.542805, 0, 0], [0.956919, -0.528915, 0], [0.665885, -0.353482, 1.402538],
              [0.478359, 1.158742, 0.107672], [-0.137087, -0.235121, 0.353913]])
L = np.array([1, 0.645275, 1.086284, 1.503439, 1.281933, 0.771071])
cases = [("dietmaier", list(zip(A, b, L)))]
rng = np.random.default_rng(0)
for k in range(n_random):
    Ak = rng.uniform(-100, 100, (6, 3))
    bk = rng.uniform(-50, 50, (6, 3))
    p = np.array([0, 0, 100.0]) + rng.uniform(-30, 30, 3)
    R = Rotation.from_rotvec(rng.uniform(-0.6, 0.6, 3)).as_matrix()
    cases.append((f"random {{k}}", list(zip(Ak, bk, np.linalg.norm(p + bk @ R.T - Ak, axis=1)))))

def timed(fn):
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return time.perf_counter() - t0, time.process_time() - c0, out

out = {{}}
first = True
for name, legs in cases:
    wall, cpu, m = timed(lambda: assembly_modes(legs))
    row = {{"count": m.count, "finite": m.finite, "failed": m.failed, "paths": m.paths,
           "max_residual": float(m.residuals.max()) if m.count else 0.0}}
    if first:
        row["first"] = [wall, cpu]
        first = False
    runs = [timed(lambda: assembly_modes(legs))[:2] for _ in range(repeats)]
    row["median"] = [float(np.median([w for w, _ in runs])), float(np.median([c for _, c in runs]))]
    out[name] = row
print(json.dumps(out))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=9)
    parser.add_argument("--random", type=int, default=5, help="random general 6-UPS robots besides Dietmaier's")
    args = parser.parse_args()

    code = CHILD.format(src=str(ROOT / "src"), args=(args.repeats, args.random))
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    rows = json.loads(done.stdout.strip().splitlines()[-1])

    print(f"assembly_modes of a general 6-UPS: one full solve (128 paths), fresh process, "
          f"median of {args.repeats}")
    print(f"baseline: martyushev/fkSGP Python solver {FKSGP_SECONDS:.2f} s per solve (measured on this machine)")
    print(f"{'robot':<12} {'real':>4} {'finite':>6} {'failed':>6} {'first s':>8} {'median s':>9} "
          f"{'cpu s':>7} {'fkSGP/ours':>10}")
    for name, r in rows.items():
        first = f"{r['first'][0]:.3f}" if "first" in r else "-"
        wall, cpu = r["median"]
        print(f"{name:<12} {r['count']:>4} {r['finite']:>6} {r['failed']:>6} {first:>8} {wall:>9.3f} {cpu:>7.3f} "
              f"{FKSGP_SECONDS / wall:>9.1f}x")


if __name__ == "__main__":
    main()
