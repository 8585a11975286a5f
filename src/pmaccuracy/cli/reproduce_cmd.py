"""``pmaccuracy reproduce``: the paper's reproduction report (the main job of ``make demo``)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from . import _common, spatial_cmd
from .worst_cmd import add_shape, parse_shape, shape_key


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "reproduce", help="reproduce the paper: workspace, error maps, paper check, sources, design comparison",
        description="Writes DIR/report.html (self-contained), DIR/report.md, DIR/results.json, PNG figures and "
                    "NetCDF maps for the robot (default: the paper's prototype, aalborg_3ppr); for a spatial robot "
                    "(stewart_6ups, delta_clavel, rps_3, prs_3, upu_3 or a spatial robot file) its accuracy report: "
                    "its legs, workspace with an interactive 3D view, error maps, error sources, design (tolerance "
                    "synthesis, global worst case) and statistics.")
    p.add_argument("--out", default="out", metavar="DIR", help="output folder (default: out); created with its missing parents")
    _common.add_robot(p)
    p.add_argument("--grid", type=_common.positive_int, default=None, metavar="N",
                   help="grid points per axis (default 101; a spatial robot: 30, at most 80)")
    p.add_argument("--seed", type=_common.nonnegative_int, default=0, help="seed of the virtual experiment's camera noise")
    p.add_argument("--no-experiment", action="store_true", help="skip the virtual experiment section")
    p.add_argument("--clearances", metavar="C",
                   help="clearances (preset or file): writes the accuracy report of ROBOT with C instead of the "
                        "paper's reproduction (for a 3-PPR); without it a robot other than a 3-PPR gets its "
                        "architecture's *_typical preset (printed on stderr)")
    p.add_argument("--phi-deg", type=_common.angle_deg, nargs="+", action="extend", metavar="PHI",
                   help="orientations of the accuracy report's maps (deg): several values (--phi-deg 0 15) and/or "
                        "the option repeated; default 0 and 30")
    p.add_argument("--target", action="append", metavar="NAME=VALUE",
                   help="design target of the design section's synthesis, repeatable: dx, dy, dp in mm, dphi_deg in "
                        "deg (e.g. --target dp=0.1 --target dphi_deg=0.1); default for the paper's robot dp=0.3 and "
                        "dphi_deg=0.3, for the accuracy report none (no synthesis); a spatial robot: dx, dy, dz, dp "
                        "in mm, drx_deg, dry_deg, drz_deg, dtheta_deg in deg, default dp=0.1 and dtheta_deg=0.05")
    p.add_argument("--phi-range-deg", type=_common.angle_deg, nargs=2, metavar=("LO", "HI"),
                   help="orientation interval (deg) of the design section's global worst case and synthesis "
                        "(default: -30 30 for the paper's robot, the range of --phi-deg otherwise)")
    p.add_argument("--no-design", action="store_true", help="skip the design section of the accuracy report")
    add_shape(p)   # the design section's region: --workspace (default), --box, --disc, --polygon
    p.add_argument("--strict", action="store_true",
                   help="a section that cannot be computed is an error (exit 2) instead of a box in the report "
                        "and a warning")
    p.set_defaults(func=run)


def _targets(items: list[str] | None) -> dict[str, float] | None:
    """``--target`` items as ``{name: value}`` (dx, dy, dp mm; dphi_deg deg), checked by the synthesis' parser."""
    from ..accuracy.synthesis import parse_targets

    if not items:
        return None
    parse_targets(items)   # ConfigError naming --target for a bad name or value
    return {name.strip(): float(value) for name, _, value in (str(i).partition("=") for i in items)}


def _check_region(robot, shape, args: argparse.Namespace) -> None:
    """Refuse (ConfigError naming --disc/--box/--polygon/--region) a design region without a reachable,
    well-conditioned pose, before anything is written: the design section could only box its failure."""
    from ..errors import ConfigError, EmptyWorkspaceError
    from ..report.design_report import reference_pose

    try:
        reference_pose(robot, shape)
    except EmptyWorkspaceError as exc:
        raise ConfigError(f"{exc}: the design section needs a region inside the workspace of {robot.name} "
                          f"(or --no-design)", key=shape_key(args)) from None


def run_spatial(args: argparse.Namespace, robot) -> int:
    """``reproduce`` on a spatial robot: its accuracy report (:mod:`pmaccuracy.report.spatial_report`)."""
    from ..errors import ConfigError
    from ..report.spatial_report import DEFAULT_GRID, MAX_GRID, spatial_accuracy_report

    planar_only = (("--phi-deg", args.phi_deg), ("--phi-range-deg", args.phi_range_deg),
                   ("--box", args.box), ("--disc", args.disc), ("--polygon", args.polygon),
                   ("--region", args.region), ("--workspace", args.workspace))
    for option, value in planar_only:
        if value:
            raise ConfigError(f"applies to planar robots' reports; {robot.name} is a spatial {robot.architecture} "
                              "(its report covers its whole workspace)", key=option)
    grid = DEFAULT_GRID if args.grid is None else args.grid
    if not 4 <= grid <= MAX_GRID:
        raise ConfigError(f"{grid} points per axis of a 3D grid: give 4 to {MAX_GRID} for a spatial robot",
                          key="--grid")
    targets = spatial_cmd.parse_targets(args.target) if args.target else None
    if targets and args.no_design:
        raise ConfigError("has no effect with --no-design (the targets are the design section's)", key="--target")
    sources = spatial_cmd._sources(args, robot)   # default: the architecture's preset, said on stderr
    _common.prepare_output(args.out, "--out", folder=True)
    results = spatial_accuracy_report(Path(args.out), robot, sources, grid=grid, targets=targets,
                                      design=not args.no_design, strict=args.strict,
                                      command=_common.command_line(args), stream=sys.stderr)
    print(f"wrote {Path(args.out) / 'report.html'} ({results['elapsed_s']} s): {robot.name} with "
          f"{results['clearances']}")
    return 0


def run(args: argparse.Namespace) -> int:
    from ..errors import ConfigError
    from ..model.spatial import is_spatial

    robot = _common.load_robot(args)
    if is_spatial(robot):
        return run_spatial(args, robot)
    if args.grid is None:
        args.grid = 101
    _common.check_grid_memory(1, args.grid, "--grid")  # (the library checks again with every orientation)
    targets = _targets(args.target)
    shape = parse_shape(args)
    phi_range = tuple(args.phi_range_deg) if args.phi_range_deg else None
    if phi_range is not None and not phi_range[0] < phi_range[1]:
        raise ConfigError(f"needs LO < HI, got {phi_range[0]:g} {phi_range[1]:g}", key="--phi-range-deg")
    if shape is not None and not args.no_design:
        _check_region(robot, shape, args)
    if args.clearances is not None or not robot.is_3ppr:
        from ..report.accuracy_report import REPORT_PHIS_DEG, accuracy_report
        from ..io.resolve import load_clearances

        # without --clearances: the default rule of every command (a 3-PPR gets the paper's reproduction below)
        load_clearances(_common.clearances_or_default(args, robot), robot)  # checked before anything is computed
        phis = tuple(args.phi_deg) if args.phi_deg else REPORT_PHIS_DEG
        if len(set(phis)) < len(phis):
            raise ConfigError(f"an orientation is given twice: {' '.join(f'{v:g}' for v in phis)}", key="--phi-deg")
        _common.prepare_output(args.out, "--out", folder=True)   # inputs first: a refused run leaves no folder
        results = accuracy_report(Path(args.out), robot, args.clearances, args.grid, phis_deg=phis, seed=args.seed,
                                  experiment=not args.no_experiment, design=not args.no_design, targets=targets,
                                  phi_range_deg=phi_range, command=_common.command_line(args), region=shape,
                                  strict=args.strict, stream=sys.stderr)
        print(f"wrote {Path(args.out) / 'report.html'} ({results['elapsed_s']} s): {robot.name} with "
              f"{results['clearances']}")
        return 0
    if args.phi_deg:
        raise ConfigError("--phi-deg applies to the accuracy report (with --clearances)", key="--phi-deg")
    _common.prepare_output(args.out, "--out", folder=True)
    from ..report import reproduce

    if args.no_design:
        raise ConfigError("--no-design applies to the accuracy report (with --clearances)", key="--no-design")
    results = reproduce(Path(args.out), robot, args.grid, seed=args.seed,
                        experiment=not args.no_experiment, command=_common.command_line(args), targets=targets,
                        phi_range_deg=phi_range, region=shape, strict=args.strict, stream=sys.stderr)
    ok = sum(c["pass"] for c in results["paper_check"])
    print(f"wrote {Path(args.out) / 'report.html'} ({results['elapsed_s']} s); paper check: {ok} of "
          f"{len(results['paper_check'])} values within 1 %")
    return 0
