"""``pmaccuracy statistics``: the distribution of the pose error beside its worst case (Monte Carlo and RSS).

At one pose (``--pose X Y PHI_DEG``; a spatial robot: its own coordinates, see
:func:`pmaccuracy.cli.spatial_cmd.run_statistics`): mean, standard deviation, percentiles of
``|dq|`` with their 95 % order-statistic interval, exceedance probabilities with
their binomial standard error, the analytic RSS and the worst case, per
quantity. Over a region (``--phi-deg ... --grid N --out map.nc``): percentile
maps as NetCDF (or CSV), optionally a figure.
"""

from __future__ import annotations

import argparse
import math

from ..errors import ConfigError, EmptyWorkspaceError
from . import _common
from .bounds_cmd import add_clearances
from .spatial_cmd import POSE_HELP
from .worst_cmd import add_shape, parse_shape, shape_key

HELP = "distribution of the pose error (Monte Carlo, RSS) beside the worst case: at a pose or percentile maps"


#: Columns of the table at a pose (besides the percentiles; json and csv have every statistic).
_TABLE = ("quantity", "mean", "std", "rss", "max_abs", "worst", "exceed", "se_exceed", "threshold")


def _table_order(key: str) -> tuple[int, float]:
    if key[:1] == "p" and key[1:2].isdigit():
        return (3, float(key[1:]))
    order = {"quantity": 0, "mean": 1, "std": 1.5, "rss": 2, "max_abs": 4, "worst": 5, "exceed": 6,
             "se_exceed": 7, "threshold": 8}
    return (0 if order[key] < 3 else 4, order[key])


#: Quantities of a threshold: planar robots, spatial robots.
PLANAR_THRESHOLDS = ("dx", "dy", "dp", "dphi_deg")
SPATIAL_THRESHOLDS = ("dx", "dy", "dz", "drx_deg", "dry_deg", "drz_deg", "dp", "dtheta_deg")


def _threshold(text: str) -> tuple[str, float]:
    """argparse type: ``QUANTITY=VALUE`` (dx, dy, dp in mm; dphi_deg in deg; spatial robots: also dz mm and
    drx_deg, dry_deg, drz_deg, dtheta_deg in deg; each command checks its robot's quantities)."""
    key, sep, value = text.partition("=")
    if not sep:
        raise argparse.ArgumentTypeError(f"expected QUANTITY=VALUE (e.g. dp=0.2), got {text!r}")
    key = key.strip()
    if key not in PLANAR_THRESHOLDS + SPATIAL_THRESHOLDS:
        raise argparse.ArgumentTypeError(f"unknown quantity {key!r} (dx, dy, dp in mm; dphi_deg in deg; spatial "
                                         "robots: dx, dy, dz, dp in mm; drx_deg, dry_deg, drz_deg, dtheta_deg "
                                         "in deg)")
    return key, _common.finite_float(value)


def _percentile(text: str) -> float:
    value = _common.finite_float(text)
    if not 0 < value < 100:
        raise argparse.ArgumentTypeError(f"must lie strictly between 0 and 100: {text!r}")
    return value


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "statistics", help=HELP,
        description="Every error source takes independent random values inside its set (uniform by default: "
                    "disks uniform by area, guide rhombi uniform, intervals uniform; other laws per source with "
                    "--distribution). The first-order pose error of each sample gives Monte Carlo statistics "
                    "(with their Monte Carlo error) beside the analytic RSS and the worst case. Lengths mm, angles "
                    "deg. Percentiles are of |dq|.")
    _common.add_robot(p)
    add_clearances(p)
    p.add_argument("--pose", nargs="+", type=_common.finite_float, metavar="V",
                   help="one pose, not repeatable: " + POSE_HELP.removeprefix("a pose (repeatable). "))
    p.add_argument("--phi-deg", type=_common.angle_deg, nargs="+", action="extend", metavar="PHI",
                   help="orientation(s) of a percentile map in degrees: several values and/or the option repeated "
                        "(needs --out)")
    p.add_argument("--grid", type=_common.positive_int, default=21, metavar="N",
                   help="grid points per axis of a map (default: 21)")
    add_shape(p)
    p.add_argument("--out", metavar="FILE", help="percentile map to write: .nc (NetCDF) or .csv; missing parent "
                                                 "folders are created")
    _common.add_plot(p, "figure of a map's first orientation: percentile, worst case and their ratio for |dp| "
                        "(mm) and |dphi| (deg), with --threshold also the map of P(|Q| > V) per threshold, in "
                        "colour steps no finer than the Monte Carlo error; --vmin/--vmax set the mm panels, --log "
                        "the worst-case panels", maps=True)
    p.add_argument("--samples", type=_common.positive_int, default=None, metavar="N",
                   help="Monte Carlo samples (default: 100000 at a pose, 10000 for a map)")
    p.add_argument("--seed", type=_common.nonnegative_int, default=0, help="seed of numpy.random.default_rng (default: 0)")
    p.add_argument("--threshold", type=_threshold, action="append", metavar="Q=V",
                   help="P(|Q| > V) with Q one of dx, dy, dp (mm), dphi_deg (deg), e.g. dp=0.2 (repeatable)")
    p.add_argument("--percentile", type=_percentile, action="append", metavar="P",
                   help="percentile of |dq| in (0, 100) (repeatable; default: 95 and 99 at a pose, 95 for a map)")
    p.add_argument("--distribution", metavar="FILE",
                   help="laws of the sources: uniform, truncnormal or boundary for every source, or a TOML file "
                        "with one law per source key (default: uniform)")
    p.add_argument("--exact-samples", type=int, default=0, metavar="M",
                   help="at a pose: also close the loops exactly for M samples and report the largest difference "
                        "from the first-order errors (default: 0)")
    _common.add_format(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from ..accuracy import distributions
    from ..model.spatial import is_spatial
    from ..report import statistics_report
    from .kinematics_cmd import _three

    robot = _common.load_robot(args)
    if is_spatial(robot):
        from . import spatial_cmd

        return spatial_cmd.run_statistics(args, robot)
    _three([args.pose] if args.pose is not None else None, "--pose", "X Y PHI_DEG (mm, mm, deg)")
    if (args.pose is None) == (args.phi_deg is None):
        raise ConfigError("give either --pose X Y PHI_DEG or --phi-deg PHI (with --out) for a map",
                          key="--pose/--phi-deg")
    if args.pose is not None and (args.out or args.plot):
        raise ConfigError("--out and --plot go with a map (--phi-deg), not with --pose", key="--out")
    if args.phi_deg is not None and not args.out:
        raise ConfigError("a map needs --out FILE (.nc or .csv)", key="--out")
    if args.grid < 2:
        raise ConfigError(f"the grid needs at least 2 points per axis, got {args.grid}", key="--grid")
    if args.exact_samples < 0 or (args.exact_samples and args.pose is None):
        raise ConfigError("must be a whole number >= 0, with --pose", key="--exact-samples")
    _common.check_plot_options(args)
    shape = parse_shape(args)
    if shape is not None and args.pose is not None:
        raise ConfigError("a region goes with a map (--phi-deg), not with --pose", key=shape_key(args))
    thresholds = dict(args.threshold or [])
    for key in thresholds:
        if key not in PLANAR_THRESHOLDS:
            raise ConfigError(f"{key} is a quantity of spatial robots; a planar robot's: "
                              f"{', '.join(PLANAR_THRESHOLDS)}", key="--threshold")
    distribution = distributions.Distribution.load(args.distribution)
    _common.clearances_or_default(args, robot)
    if args.pose is not None:
        pose = np.array([args.pose[0], args.pose[1], math.radians(args.pose[2])])
        result = distributions.pose_statistics(
            robot, args.clearances, pose, samples=args.samples or 100_000, seed=args.seed,
            distribution=distribution, percentiles=args.percentile or (95.0, 99.0), thresholds=thresholds,
            exact_samples=args.exact_samples).to_dict()
        if args.format == "json":
            _common.emit(result, "json")
        else:
            rows = [{"quantity": q, **stats} for q, stats in result["quantities"].items()]
            if args.format == "table":
                rows = [{k: v for k, v in r.items() if k in _TABLE or (k[:1] == "p" and k[1:2].isdigit()
                                                                       and "_" not in k)} for r in rows]
                rows = [{k: r[k] for k in sorted(r, key=_table_order)} for r in rows]
            _common.emit(rows, args.format)
        return 0

    _common.check_grid_memory(len(args.phi_deg), args.grid, "--grid")   # before the output and the long-run warning
    out = _common.prepare_output(args.out, "--out", (".nc", ".csv"))
    # rough rate: 2e6 point-samples per second (measured on a 2-core machine; points outside the workspace skipped)
    _common.warn_long_run(len(args.phi_deg) * args.grid ** 2 * (args.samples or 10_000) / 2e6,
                          f"--grid {args.grid} with --samples {args.samples or 10_000}")
    _common.check_plot(args)
    try:
        ds = distributions.region_statistics(
            robot, args.clearances, np.radians(args.phi_deg), args.grid, samples=args.samples or 10_000,
            seed=args.seed, distribution=distribution, percentiles=args.percentile or (95.0,), thresholds=thresholds,
            region=shape)
    except EmptyWorkspaceError as exc:
        if shape is None:
            raise
        raise ConfigError(str(exc), key=shape_key(args)) from None
    distributions.save_region_statistics(ds, out)
    if args.plot:
        statistics_report.save_percentile_map_figure(ds, args.plot, dpi=args.dpi, vmin=args.vmin, vmax=args.vmax,
                                                     log=args.log)
    summary = distributions.summarize_region(ds)
    rows = [{"phi_deg": float(phi), "quantity": q, **stats} for phi, layer in summary["orientations"].items()
            for q, stats in layer.items()]
    _common.emit(rows if args.format != "json" else {**summary, "out": str(out)}, args.format)
    return 0
