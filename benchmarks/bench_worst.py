"""Benchmark: the certified worst case over regions (``pmaccuracy worst``), time and boxes per region.

Well-conditioned random 3-RPR and 3-RRR robots (the test suite's generators, ``tests/reference``) over boxes
of +-6 mm and a few degrees about their nominal pose, with random clearances of every joint; and the
presets' regions quoted in the guide (docs/guide/commands.md, docs/guide/methods.md). Prints, per region, the wall time, the boxes evaluated and the gaps
reached at the default 0.1 % (issue 27: certified in under 10 s). With ``--exact GAP_PCT`` each region is also
certified for the exact loop closure (``worst --certified``, ``global_worst(..., exact=True)``) at that gap,
with its time as a ratio to the first-order run measured just before.

    .venv/bin/python benchmarks/bench_worst.py [--seeds 8] [--max-boxes 2000000] [--exact 1]
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import warnings

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tests" / "reference")]

import error_reference as eref  # noqa: E402
import planar_reference as pref  # noqa: E402

from pmaccuracy.accuracy.global_worst import global_worst, make_region  # noqa: E402
from pmaccuracy.io.resolve import load_clearances  # noqa: E402
from pmaccuracy.kinematics import singularity  # noqa: E402
from pmaccuracy.model.manipulator import Manipulator  # noqa: E402
from pmaccuracy.model.sources import ErrorSources  # noqa: E402


def line(label, res, extra=""):
    gaps = " ".join(f"{q} {w.gap * 100:.3f}%" for q, w in res.quantities.items())
    ok = all(w.converged for w in res.quantities.values())
    print(f"{label:<34} {res.seconds:6.2f} s {res.boxes:>9} boxes  certified {str(ok):<5}  {gaps}{extra}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--max-boxes", type=int, default=2_000_000)
    ap.add_argument("--exact", type=float, default=None, metavar="GAP_PCT",
                    help="also the exact model's worst case at this gap (percent)")
    args = ap.parse_args()

    def exact(robot, clearances, region, first):
        if args.exact is None:
            return
        res = global_worst(robot, clearances, region, exact=True, gap=args.exact / 100)
        line("  exact model", res, f"  ({res.seconds / first.seconds:.3g}x the first-order run)")

    warnings.simplefilter("ignore")
    for kind, gen, half_mm, half_deg in (("3-RPR", pref.random_rpr, 6, 3), ("3-RRR", pref.random_rrr, 6, 2)):
        for seed in range(args.seeds):
            rng = np.random.default_rng(seed)
            data, nom = gen(rng)
            robot = Manipulator.from_dict(data, source="random")
            clear, _ = eref.random_clearances(rng, eref.load_robot(data))
            phi = (nom[2] - np.radians(half_deg), nom[2] + np.radians(half_deg))
            box = (nom[0] - half_mm, nom[0] + half_mm, nom[1] - half_mm, nom[1] + half_mm)
            region = make_region(robot, phi, box)
            g = np.linspace(-1, 1, 9)
            pts = np.stack(np.meshgrid(nom[0] + half_mm * g, nom[1] + half_mm * g, np.linspace(*phi, 5),
                                       indexing="ij"), -1).reshape(-1, 3)
            cond = float(np.max(singularity(robot, pts).condition))
            res = global_worst(robot, ErrorSources.from_dict(clear), region, max_boxes=args.max_boxes)
            line(f"{kind} seed {seed} +-{half_mm} mm +-{half_deg} deg", res, f"  (condition <= {cond:.3g})")
            exact(robot, ErrorSources.from_dict(clear), region, res)
    for rname, cname, lo, hi in (("aalborg_3ppr", "case1", -30, 30), ("aalborg_3ppr", "case1", 0, 0),
                                 ("aalborg_3ppr", "case1", -10, 10), ("symmetric_3rpr", "rpr_typical", -5, 5),
                                 ("symmetric_3ppr", "all", -5, 5), ("symmetric_3prr", "prr_typical", -5, 5)):
        robot = Manipulator.preset(rname)
        clearances = load_clearances(cname, robot)
        region = make_region(robot, (np.radians(lo), np.radians(hi)), None)
        res = global_worst(robot, clearances, region, max_boxes=args.max_boxes)
        line(f"{rname} {cname} workspace [{lo}, {hi}] deg", res)
        exact(robot, clearances, region, res)


if __name__ == "__main__":
    main()
