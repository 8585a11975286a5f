"""``pmaccuracy reproduce``: the paper's reproduction report (the main job of ``make demo``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from . import _common


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "reproduce", help="reproduce the paper: workspace, error maps, paper check, sources, design comparison",
        description="Writes DIR/report.html (self-contained), DIR/report.md, DIR/results.json, PNG figures and "
                    "NetCDF maps for the robot (default: the paper's prototype, aalborg_3ppr).")
    p.add_argument("--out", default="out", metavar="DIR", help="output folder (default: out); created with its missing parents")
    _common.add_robot(p)
    p.add_argument("--grid", type=_common.positive_int, default=101, metavar="N", help="grid points per axis")
    p.add_argument("--seed", type=_common.nonnegative_int, default=0, help="seed of the virtual experiment's camera noise")
    p.add_argument("--no-experiment", action="store_true", help="skip the virtual experiment section")
    p.add_argument("--clearances", metavar="C",
                   help="clearances (preset or file): writes the accuracy report of ROBOT with C instead of the "
                        "paper's reproduction (needed for robots other than a 3-PPR; e.g. rpr_typical)")
    p.add_argument("--phi-deg", type=_common.finite_float, action="append", metavar="PHI",
                   help="orientations of the accuracy report's maps (deg, repeatable; default 0 and 30)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..errors import ConfigError

    _common.check_grid_memory(1, args.grid, "--grid")  # (the library checks again with every orientation)
    robot = _common.load_robot(args)
    if args.clearances is not None or not robot.is_3ppr:
        from ..report.accuracy_report import REPORT_PHIS_DEG, accuracy_report
        from ..io.resolve import load_clearances

        if args.clearances is None:
            raise ConfigError(f"{robot.name} is a {robot.architecture}: give its clearances with --clearances (e.g. "
                              "a preset rpr_typical, rrr_typical, prr_typical or a per-joint file)", key="--clearances")
        load_clearances(args.clearances, robot)  # checked before anything is computed
        _common.prepare_output(args.out, "--out", folder=True)   # inputs first: a refused run leaves no folder
        phis = tuple(args.phi_deg) if args.phi_deg else REPORT_PHIS_DEG
        results = accuracy_report(Path(args.out), robot, args.clearances, args.grid, phis_deg=phis, seed=args.seed,
                                  experiment=not args.no_experiment)
        print(f"wrote {Path(args.out) / 'report.html'} ({results['elapsed_s']} s): {robot.name} with "
              f"{results['clearances']}")
        return 0
    if args.phi_deg:
        raise ConfigError("--phi-deg applies to the accuracy report (with --clearances)", key="--phi-deg")
    _common.prepare_output(args.out, "--out", folder=True)
    from ..report import reproduce

    results = reproduce(Path(args.out), robot, args.grid, seed=args.seed,
                        experiment=not args.no_experiment)
    ok = sum(c["pass"] for c in results["paper_check"])
    print(f"wrote {Path(args.out) / 'report.html'} ({results['elapsed_s']} s); paper check: {ok} of "
          f"{len(results['paper_check'])} values within 1 %")
    return 0
