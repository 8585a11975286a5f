"""``pmaccuracy reproduce``: the paper's reproduction report (the main job of ``make demo``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..report import reproduce
from . import _common


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "reproduce", help="reproduce the paper: workspace, error maps, paper check, sources, design comparison",
        description="Writes DIR/report.html (self-contained), DIR/report.md, DIR/results.json, PNG figures and "
                    "NetCDF maps for the robot (default: the paper's prototype, aalborg_3ppr).")
    p.add_argument("--out", default="out", metavar="DIR", help="output folder (default: out)")
    _common.add_robot(p)
    p.add_argument("--grid", type=_common.positive_int, default=101, metavar="N", help="grid points per axis")
    p.add_argument("--seed", type=int, default=0, help="seed of the virtual experiment's camera noise")
    p.add_argument("--no-experiment", action="store_true", help="skip the virtual experiment section")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    results = reproduce(Path(args.out), _common.load_robot(args), args.grid, seed=args.seed,
                        experiment=not args.no_experiment)
    ok = sum(c["pass"] for c in results["paper_check"])
    print(f"wrote {Path(args.out) / 'report.html'} ({results['elapsed_s']} s); paper check: {ok} of "
          f"{len(results['paper_check'])} values within 1 %")
    return 0
