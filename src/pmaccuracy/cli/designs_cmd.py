"""``pmaccuracy compare-designs``: workspace areas, errors over each workspace and ratios over the shared region."""

from __future__ import annotations

import argparse
import sys

from . import _common
from ..io.resolve import robot_arg

HELP = "compare designs of any architectures: workspace areas, mean/max errors, error ratios on the shared region"
#: Columns of the three blocks of the table format (JSON and CSV carry every column in one record).
TABLE_BLOCKS = (
    ("robot", "clearances", "phi_deg", "area_mm2", "points", "singular", "dx_mean", "dx_max", "dy_mean", "dy_max",
     "dphi_mean_deg", "dphi_max_deg", "dp_mean", "dp_max"),
    ("robot", "phi_deg", "dx_argmax_x", "dx_argmax_y", "dy_argmax_x", "dy_argmax_y", "dphi_argmax_x",
     "dphi_argmax_y", "dp_argmax_x", "dp_argmax_y"),
    ("robot", "phi_deg", "shared_points", "dx_ratio_mean", "dx_ratio_min", "dx_ratio_max", "dy_ratio_mean",
     "dy_ratio_min", "dy_ratio_max", "dphi_ratio_mean", "dphi_ratio_min", "dphi_ratio_max", "dp_ratio_mean",
     "dp_ratio_min", "dp_ratio_max"),
)


#: Rough rate of the comparison, grid points per second: 1.5e5 measured (--grid 1001 and 2001, two robots, one
#: orientation: 32 s and 110 s) on a loaded 2-core machine.
POINTS_PER_SECOND = 1.5e5
#: Runs estimated longer than this (s) are announced before computing.
LONG_RUN_S = 60.0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "compare-designs", help=HELP,
        description="For each robot and orientation: the exact workspace area (mm^2) and, over an N x N grid of "
                    "the workspace (points near a singularity excluded and counted), the mean and max of the exact "
                    "worst-case dx_max, dy_max, dp_max (mm) and dphi_max (deg) with the position of each max; then, "
                    "over the region shared by every workspace (N x N grid of the shared bounding box), the ratios "
                    "of each robot's errors to the first robot's (mean, min, max). The table format prints three "
                    "blocks (errors, positions of the maxima, ratios); json and csv one record per robot and "
                    "orientation.")
    p.add_argument("--robot", action="append", required=True, metavar="ROBOT",
                   help="preset name or robot TOML file (repeat: at least two; the first is the reference)")
    p.add_argument("--clearances", action="append", metavar="C",
                   help="clearance preset or file: once for every robot, or once per robot in the order of --robot "
                        "(default: each robot's default, case1 for a 3-PPR, the architecture's *_typical preset "
                        "otherwise, printed on stderr)")
    p.add_argument("--phi-deg", type=_common.angle_deg, nargs="+", action="extend", required=True, metavar="PHI",
                   help="platform orientation(s) in degrees: several values and/or the option repeated")
    p.add_argument("--grid", type=_common.positive_int, default=101, metavar="N",
                   help="grid points per axis over each workspace and over the shared region (default: 101)")
    _common.add_plot(p, "figure: per orientation the workspaces overlaid, the dp_max ratio maps and bars of the "
                        "mean/max errors")
    p.add_argument("--out", metavar="FILE.csv", help="also write the full table as CSV (exact floats); missing parent folders are created")
    _common.add_format(p)
    p.set_defaults(func=run)


def _check_options(args: argparse.Namespace) -> list[str | None]:
    """Refuse inconsistent options before loading anything; returns one clearance spec per robot (None: the
    robot's default)."""
    from ..errors import ConfigError

    if len(args.robot) < 2:
        raise ConfigError("give at least two robots (--robot A --robot B ...); the first is the reference",
                          key="--robot")
    if args.grid < 2:      # checked with or without --clearances
        raise ConfigError(f"needs at least 2 points per axis, got {args.grid}", key="--grid")
    if args.clearances is None:
        return [None] * len(args.robot)
    if len(args.clearances) not in (1, len(args.robot)):
        raise ConfigError(f"give --clearances once (for every robot) or once per robot: {len(args.robot)} robots, "
                          f"{len(args.clearances)} --clearances", key="--clearances")
    seen = set()
    for phi in args.phi_deg:
        if phi in seen:
            raise ConfigError(f"orientation {phi:g} deg given twice", key="--phi-deg")
        seen.add(phi)
    if args.out is not None and not args.out.lower().endswith(".csv"):
        raise ConfigError("the table is written as CSV: give a .csv file", source=args.out, key="--out")
    return list(args.clearances) * len(args.robot) if len(args.clearances) == 1 else list(args.clearances)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    import numpy as np

    from ..accuracy.designs import compare_designs, save_comparison_figure
    from ..errors import ConfigError
    from ..io.resolve import load_clearances
    specs = _check_options(args)
    _common.check_grid_memory(len(args.robot) * len(args.phi_deg), args.grid, "--grid")
    # each robot's workspace grid and the shared region's grid, per orientation
    _common.warn_long_run(2 * len(args.robot) * len(args.phi_deg) * args.grid ** 2 / POINTS_PER_SECOND,
                          f"--grid {args.grid} ({len(args.robot)} robots x {len(args.phi_deg)} orientations)",
                          limit=LONG_RUN_S)
    robots = [robot_arg(spec) for spec in args.robot]
    for robot in robots:
        _common.refuse_spatial(robot, args)
    if args.clearances is None:   # the default rule, robot by robot, said once
        from ..io.resolve import default_clearances

        try:
            specs = [default_clearances(robot) for robot in robots]
        except ConfigError as exc:
            raise ConfigError(exc.message, key="--clearances") from None
        _common.announce_default_clearances(specs[0] if len(set(specs)) == 1 else ", ".join(
            f"{robot.name}: {spec}" for robot, spec in zip(robots, specs)), args)
    clearances = []
    for spec, robot in zip(specs, robots):
        try:
            clearances.append(load_clearances(spec, robot))
        except ConfigError as exc:  # several robots: say which one the file does not fit
            raise type(exc)(f"{exc.message} (--robot {robot.name})", source=exc.source, key=exc.key) from None
    _common.check_plot(args)   # inputs first: a refused run creates no folder
    if args.out is not None:
        _common.prepare_output(Path(args.out), "--out", (".csv",))
    result = compare_designs(robots, clearances, np.radians(args.phi_deg), args.grid)
    for phi_deg, region in zip(args.phi_deg, result.shared):
        if region.is_empty:
            why = (f"all {int(region.inside.sum())} grid points they share are near a singularity of some robot"
                   if region.inside.any() else "the workspaces share no region")
            print(f"pmaccuracy compare-designs: at phi = {phi_deg:g} deg {why}: ratios are null", file=sys.stderr)
    records = result.records()
    from ..model.plausibility import linearity_messages, warn

    warn(linearity_messages([r["dphi_max_deg"] for r in records], what="the largest dphi_max of a design"))
    if args.out is not None:
        with open(args.out, "w", encoding="utf-8", newline="") as fh:
            _common.emit(records, "csv", stream=fh)
    if args.plot is not None:
        save_comparison_figure(result, args.plot, dpi=args.dpi)
    if args.format == "table":
        for b, columns in enumerate(TABLE_BLOCKS):
            if b:
                sys.stdout.write("\n")
            _common.emit(None, "table", records=[{k: r[k] for k in columns} for r in records])
    else:
        _common.emit(records, args.format)
    return 0
