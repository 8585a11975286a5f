"""Benchmark: ``pmaccuracy reproduce`` on a user's own robot, as a new user runs it (issue 33's walk-through).

For each of the 3-RPR, 3-RRR and 3-PRR presets a "user's robot" is made by moving every base and platform
point by up to ``--move-mm`` and every link length by up to ``--move-pct`` % (seeded), written to a TOML
file, and ``pmaccuracy reproduce --robot FILE --disc CX CY R --target dp=T`` runs in a fresh process: the
disc is centred on the phi = 0 workspace's centroid with 40 % of its equivalent radius, the target is 80 %
of the worst dp at that centre (so the synthesis has work to do). Printed per robot: the wall time of the
whole command (goal: under 60 s on the project's 2-core machine), each section's estimate and measured
seconds (``results.json`` ``sections``) and the sections that failed. The paper's robot (``make demo``) runs
last for comparison.

    .venv/bin/python benchmarks/bench_reproduce.py [--seed 1] [--move-mm 5] [--move-pct 3]
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np
import tomli_w

import pmaccuracy as pm
from pmaccuracy.kinematics.workspace import constant_orientation_workspace

PRESETS = (("symmetric_3rpr", "rpr_typical"), ("symmetric_3rrr", "rrr_typical"), ("symmetric_3prr", "prr_typical"))
DATA = Path(pm.__file__).resolve().parent / "data" / "robots"
POINTS = ("base", "platform", "guide_point")
LENGTHS = ("proximal", "distal")


def users_robot(preset: str, rng: np.random.Generator, move_mm: float, move_pct: float) -> dict:
    """The preset's TOML table with its points moved by up to ``move_mm`` and its lengths by ``move_pct`` %."""
    table = tomllib.loads((DATA / f"{preset}.toml").read_text())
    table["name"] = f"users_{preset.split('_')[1]}"
    table.pop("description", None)
    for leg in table["legs"]:
        for key in POINTS:
            if key in leg:
                leg[key] = [float(v + rng.uniform(-move_mm, move_mm)) for v in leg[key]]
        for key in LENGTHS:
            if key in leg:
                leg[key] = float(leg[key] * (1 + rng.uniform(-move_pct, move_pct) / 100))
    return table


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--move-mm", type=float, default=5.0)
    ap.add_argument("--move-pct", type=float, default=3.0)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    exe = str(Path(sys.executable).with_name("pmaccuracy"))
    with tempfile.TemporaryDirectory() as tmp:
        runs = []
        for preset, clearances in PRESETS:
            path = Path(tmp) / f"{preset}.toml"
            path.write_text(tomli_w.dumps(users_robot(preset, rng, args.move_mm, args.move_pct)))
            robot = pm.load_robot(str(path))
            ws = constant_orientation_workspace(robot, 0.0)
            cx, cy = ws.vertices.mean(axis=0)
            radius = 0.4 * math.sqrt(ws.area / math.pi)
            dp = float(pm.max_pose_errors(robot, clearances, np.array([[cx, cy, 0.0]]), allow_outside=True).dp_max[0])
            runs.append((preset, ["--robot", str(path), "--clearances", clearances, "--disc", f"{cx:.3f}",
                                  f"{cy:.3f}", f"{radius:.3f}", "--target", f"dp={0.8 * dp:.4g}"]))
        runs.append(("aalborg_3ppr (make demo)", []))
        print(f"{'robot':26s} {'wall [s]':>9s}  sections: measured / estimated [s]; failed")
        for name, extra in runs:
            out = Path(tmp) / f"out_{len(name)}_{abs(hash(name)) % 1000}"
            t = time.perf_counter()
            done = subprocess.run([exe, "reproduce", "--out", str(out), *extra], capture_output=True, text=True)
            wall = time.perf_counter() - t
            if done.returncode != 0:
                print(f"{name:26s} {wall:9.1f}  exit {done.returncode}: {done.stderr.strip().splitlines()[-1]}")
                continue
            res = json.loads((out / "results.json").read_text())
            parts = ", ".join(f"{s['section']} {s['seconds']:.1f}/{s['estimate_s']:.0f}" for s in res.get("sections", []))
            failed = [f["section"] for f in res.get("failed_sections", [])]
            print(f"{name:26s} {wall:9.1f}  {parts}; failed: {failed or 'none'}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
