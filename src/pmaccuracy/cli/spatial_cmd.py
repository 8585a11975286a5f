"""The ``ik``, ``fk`` and ``workspace`` commands for spatial robots (called by those commands when the robot file's
architecture is spatial): parse the robot's own coordinates, call the kinematics, print.

Coordinates on the command line: lengths in mm, angles in degrees, orientation as roll, pitch, yaw in the
**extrinsic x-y-z** convention (``docs/guide/spatial.md``).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from ..errors import NoSolutionError, OutsideJointLimitsError, PmAccuracyError, PoseError
from ..model.spatial import POSE_NAMES
from ..numerics.spatial import euler_xyz_to_rotvec
from . import _common

#: What ``--pose`` takes, in every help text.
POSE_HELP = ("a pose (repeatable). Planar robots: X Y PHI_DEG (mm, mm, deg). Spatial robots, their controlled "
             "coordinates: 6-UPS X Y Z ROLL PITCH YAW, Delta and 3-UPU X Y Z, 3-RPS and 3-PRS Z ROLL PITCH (mm; "
             "angles in deg, roll-pitch-yaw as extrinsic x-y-z rotations about the base axes)")

#: Column names of the controlled coordinates in CSV files and outputs.
COLUMN = {"x": "x", "y": "y", "z": "z", "roll": "roll_deg", "pitch": "pitch_deg", "yaw": "yaw_deg"}


def _angles(names) -> list[bool]:
    return [n in ("roll", "pitch", "yaw") for n in names]


def poses(robot, pose_args, csv_path) -> np.ndarray:
    """Full poses ``(N, 6)`` from ``--pose`` values or a CSV of the robot's controlled coordinates."""
    from ..kinematics.spatial import complete_poses

    names = robot.controlled
    if bool(pose_args) == bool(csv_path):
        raise PmAccuracyError(f"give poses with --pose {' '.join(n.upper() for n in names)} (repeatable) or "
                              "--poses-csv FILE" + (", not both" if pose_args else ""))
    if pose_args:
        bad = [k for k, v in enumerate(pose_args, start=1) if len(v) != len(names)]
        if bad:
            raise PmAccuracyError(f"--pose (number {bad[0]}): a {robot.architecture} takes {len(names)} values "
                                  f"{' '.join(n.upper() for n in names)} (mm, deg), got {len(pose_args[bad[0] - 1])}")
        arr = np.array(pose_args, dtype=float)
    else:
        from ..io.csvio import read_poses_csv

        arr = read_poses_csv(csv_path, tuple(COLUMN[n] for n in names))
    big = np.argwhere(np.abs(arr) > _common.MAX_POSE_VALUE)
    if len(big):
        k, c = (int(v) for v in big[0])
        raise PmAccuracyError(f"--pose (number {k + 1}): {names[c]} = {arr[k, c]:g} is beyond "
                              f"{_common.MAX_POSE_VALUE:g} in magnitude (a typing slip?)")
    arr[:, _angles(names)] = np.radians(arr[:, _angles(names)])
    try:
        return complete_poses(robot, arr)
    except NoSolutionError as exc:
        raise NoSolutionError(f"--pose: {exc}") from None


def _pose_record(robot, pose) -> dict:
    from ..kinematics.spatial import coordinates

    c = coordinates(pose, degrees=True)
    return {COLUMN[n]: float(v) for n, v in zip(POSE_NAMES, c)}


def _joint_values(robot, q) -> list[float]:
    return [float(np.degrees(v)) if k == "R" else float(v) for v, k in zip(q, robot.actuated_kinds)]


def run_ik(args: argparse.Namespace, robot) -> int:
    from ..kinematics.spatial import inverse_kinematics

    full = poses(robot, args.pose, args.poses_csv)
    ik = inverse_kinematics(robot, full)
    out = []
    for k in range(full.shape[0]):
        record = _pose_record(robot, full[k])
        record["q"] = _joint_values(robot, ik.q[k])
        record["passive_deg"] = [{name: float(np.degrees(v[k])) for name, v in legs.items()}
                                 for legs in ik.joint_angles]
        record["within_limits"] = bool(ik.within_limits[k])
        record["violations"] = ik.violations((k,))
        out.append(record)
    rows = []
    for r in out:
        row = {key: r[key] for key in COLUMN.values()}
        row.update({f"q{i + 1}": v for i, v in enumerate(r["q"])})
        row["within_limits"] = r["within_limits"]
        row["violations"] = "; ".join(r["violations"])
        rows.append(row)
    _common.emit(out, args.format, records=rows)
    return 0


def run_fk(args: argparse.Namespace, robot) -> int:
    from ..kinematics.spatial import assembly_modes

    n = robot.n_actuators
    if len(args.joints) != n:
        raise PmAccuracyError(f"--joints: a {robot.architecture} has {n} actuators, got {len(args.joints)} values")
    kinds = robot.actuated_kinds
    q = np.array([np.radians(v) if k == "R" else v for v, k in zip(args.joints, kinds)])
    outside = []
    for i, (v, (lo, hi), k) in enumerate(zip(q, robot.strokes, kinds)):
        if not lo - 1e-12 <= v <= hi + 1e-12:
            unit, conv = ("deg", np.degrees) if k == "R" else ("mm", float)
            outside.append(f"q{i + 1}={args.joints[i]:g} {unit} not in [{conv(lo):g}, {conv(hi):g}]")
    if outside and not args.allow_outside:
        raise OutsideJointLimitsError("--joints: actuator values outside their ranges: " + ", ".join(outside)
                                      + " (--allow-outside to solve anyway)")
    try:
        modes = assembly_modes(robot, q)
    except PoseError as exc:
        raise PoseError(f"--joints: {exc}") from None
    if modes.poses.shape[0] == 0:
        raise NoSolutionError(f"no assembly mode: the legs cannot be closed with q = {list(args.joints)}")
    out = []
    for pose, ok, wm in zip(modes.poses, modes.within_limits, modes.working_modes):
        record = _pose_record(robot, pose)
        record["working_modes"] = [int(m) for m in wm]
        record["within_limits"] = bool(ok)
        out.append(record)
    rows = []
    for r in out:
        row = {key: r[key] for key in COLUMN.values()}
        row["working_modes"] = " ".join(f"{m:+d}" for m in r["working_modes"])
        row["within_limits"] = r["within_limits"]
        rows.append(row)
    if args.format == "json":
        _common.emit({"method": modes.method, "complete": modes.complete, "modes": out}, args.format)
    else:
        _common.emit(out, args.format, records=rows)
    return 0


def run_workspace(args: argparse.Namespace, robot) -> int:
    """The constant-orientation workspace (6-UPS: at ``--orientation-deg``; Delta, 3-UPU: the reachable one) or the
    (z, roll, pitch) workspace of a 3-RPS/3-PRS: volume, bounds, slices and the 3D view."""
    from pathlib import Path

    from ..kinematics.spatial_workspace import spatial_workspace

    if getattr(args, "phi_deg", None):
        raise PmAccuracyError(f"--phi-deg is the orientation of a planar robot; {robot.name} is a "
                              f"{robot.architecture}: give --orientation-deg ROLL PITCH YAW")
    if args.orientation_deg is not None and robot.mobility != "6":
        raise PmAccuracyError(f"--orientation-deg is for a 6-UPS; a {robot.architecture} "
                              f"{'keeps its orientation' if robot.mobility == '3T' else 'maps roll and pitch'} "
                              "in its workspace")
    plot = Path(args.plot) if args.plot else None
    _common.check_plot(args)
    html = Path(args.html) if getattr(args, "html", None) else None
    if html is not None and html.suffix.lower() not in (".html", ".htm"):
        raise PmAccuracyError(f"--html: {html} must end in .html")
    # roll, pitch, yaw (deg, extrinsic x-y-z) -> the rotation vector the library takes
    orientation = euler_xyz_to_rotvec(np.array(args.orientation_deg or [0.0, 0.0, 0.0], dtype=float), degrees=True)
    ws = spatial_workspace(robot, orientation=orientation, n=args.n)
    data = {"robot": robot.name, "architecture": robot.architecture, **ws.summary()}
    if plot is not None:
        from ..report.spatial_figures import save_spatial_workspace_figure

        save_spatial_workspace_figure(robot, ws, plot, dpi=args.dpi)
    if html is not None:
        from ..report.spatial_figures import write_spatial_workspace_page

        write_spatial_workspace_page(robot, ws, html)
    record = {k: v for k, v in data.items() if not isinstance(v, (dict, list))}
    _common.emit(data, args.format, records=[record])
    return 0


def run_bounds(args: argparse.Namespace, robot) -> int:
    """``bounds`` on a spatial robot: exact worst components, certified |dp| and |dtheta| at poses."""
    from ..accuracy.spatial_bounds import spatial_pose_errors

    for option, value in (("--method", args.method != "exact"),
                          ("--nonlinear", args.nonlinear), ("--tolerances", args.tolerances),
                          ("--details", args.details), ("--max-pieces", args.max_pieces is not None)):
        if value:
            raise PmAccuracyError(f"{option} is not available for spatial robots yet ({robot.name} is a "
                                  f"{robot.architecture}): their first-order bounds are exact, |dp| certified"
                                  + ("; --certified gives the exact nonlinear model's bounds (6-UPS)"
                                     if option == "--nonlinear" else ""))
    if args.certified:
        return _certified_bounds(args, robot)
    sources = _sources(args, robot)
    gap = 1e-3 if args.gap_pct is None else args.gap_pct / 100.0
    if not 0 < gap < 1:
        raise PmAccuracyError(f"--gap-pct: {args.gap_pct} must be above 0 and below 100")
    full = poses(robot, args.pose, args.poses_csv)
    try:
        b = spatial_pose_errors(robot, sources, full, gap=gap, allow_outside=args.allow_outside)
    except PoseError as exc:
        raise type(exc)(f"--pose: {exc}" + ("" if args.allow_outside or "outside" not in str(exc) else
                                             " (--allow-outside to evaluate it anyway)")) from None
    rows = []
    for k in range(full.shape[0]):
        row = _pose_record(robot, full[k])
        comp = b.components[k]
        row.update({"dx_max": comp[0], "dy_max": comp[1], "dz_max": comp[2],
                    "drx_max_deg": float(np.degrees(comp[3])), "dry_max_deg": float(np.degrees(comp[4])),
                    "drz_max_deg": float(np.degrees(comp[5])),
                    "dp_max": float(b.dp_upper[k]), "dp_attained": float(b.dp_lower[k]),
                    "dtheta_max_deg": float(np.degrees(b.dtheta_upper[k])),
                    "dtheta_attained_deg": float(np.degrees(b.dtheta_lower[k]))})
        rows.append(row)
    _common.emit(rows, args.format)
    return 0


def _certified_bounds(args: argparse.Namespace, robot) -> int:
    """``bounds --certified`` (6-UPS, 3-RPS, 3-PRS, 3-UPU, Delta): per pose and quantity the first-order maximum, the exact nonlinear
    model's attained ``lower`` value and proven ``upper`` bound, and their gap in percent
    (:func:`pmaccuracy.accuracy.spatial_nonlinear.spatial_certified_bounds`)."""
    from ..accuracy.spatial_nonlinear import CERTIFIED_ARCHITECTURES, spatial_certified_bounds

    if robot.architecture not in CERTIFIED_ARCHITECTURES:
        raise PmAccuracyError(f"--certified: certified nonlinear bounds are available for the "
                              f"{', '.join(CERTIFIED_ARCHITECTURES)} only ({robot.name} is a {robot.architecture}; "
                              "its first-order bounds are exact without --certified)")
    if args.gap_pct is not None:
        raise PmAccuracyError("--gap-pct does not apply with --certified on a spatial robot (its bound is not refined)")
    sources = _sources(args, robot)
    full = poses(robot, args.pose, args.poses_csv)
    rows = []
    for k in range(full.shape[0]):
        try:
            res = spatial_certified_bounds(robot, sources, full[k], allow_outside=args.allow_outside)
        except PoseError as exc:
            raise type(exc)(f"--pose: {exc}" + ("" if args.allow_outside or "outside" not in str(exc) else
                                                 " (--allow-outside to evaluate it anyway)")) from None
        if not res.certified:
            print(f"warning: pose {k + 1} not certified: {res.reason}", file=sys.stderr)
        base = _pose_record(robot, full[k])
        for rec in res.records():
            rows.append({**base, **rec})
    _common.emit(rows, args.format)
    return 0


def _sources(args: argparse.Namespace, robot):
    """The error sources of ``--clearances`` (default: the architecture's typical preset, said on stderr)."""
    from ..model.spatial_sources import SpatialErrorSources, default_preset

    if args.clearances is None:
        args.clearances = default_preset(robot)
        _common.announce_default_clearances(args.clearances, args)
    try:
        return SpatialErrorSources.load(args.clearances, robot)
    except PmAccuracyError as exc:
        if "--clearances" in str(exc):
            raise
        raise type(exc)(f"--clearances: {exc}") from None


#: Output types of a spatial map.
MAP_TYPES = (".nc", ".zarr")


def run_map(args: argparse.Namespace, robot) -> int:
    """``map`` on a spatial robot: the worst first-order errors over its workspace's grid, or with
    ``--percentile`` its percentile map (:mod:`pmaccuracy.accuracy.spatial_maps`), written as NetCDF (in memory)
    or streamed into a Zarr store; Dask with ``--dask``, ``--scheduler``, ``--workers`` (.zarr)."""
    import re
    from pathlib import Path

    import xarray as xr

    from ..accuracy import spatial_maps
    from ..accuracy.spatial_statistics import MIN_SAMPLES
    from ..errors import ConfigError

    for option, value in (("--phi-deg", args.phi_deg), ("--certified", args.certified), ("--tile", args.tile),
                          ("--gap-pct", args.gap_pct)):
        if value:
            raise PmAccuracyError(f"{option} is not available for spatial robots' maps yet ({robot.name} is a "
                                  f"{robot.architecture})")
    if getattr(args, "shape", None) or any(getattr(args, k, None) for k in ("disc", "box", "polygon")):
        raise PmAccuracyError("a region (--disc, --box, --polygon) applies to planar maps; a spatial map covers "
                              "the whole workspace")
    out = Path(args.out)
    suffix = out.suffix.lower()
    if suffix not in MAP_TYPES:
        raise PmAccuracyError(f"--out: {out}: a spatial map is written as .nc or .zarr")
    if not 4 <= args.grid <= 200:
        raise PmAccuracyError(f"--grid: {args.grid} points per axis of a 3D grid; give 4 to 200")
    if args.workers and suffix != ".zarr":
        raise PmAccuracyError("--workers: applies to .zarr maps (use --dask for a .nc map)")
    if args.scheduler is not None and not re.fullmatch(r"[a-z]+://\S+", args.scheduler):
        raise PmAccuracyError(f"--scheduler: expected a dask.distributed scheduler address like "
                              f"tcp://10.0.0.1:8786, got {args.scheduler!r}")
    percentile = args.percentile is not None
    for option in ("samples", "seed", "distribution", "threshold"):
        if getattr(args, option) is not None and not percentile:
            raise PmAccuracyError(f"--{option}: goes with --percentile P (a percentile map)")
    samples = 10_000 if args.samples is None else args.samples
    if percentile and samples < MIN_SAMPLES:
        raise PmAccuracyError(f"--samples: {samples} is too few for a percentile map; give at least {MIN_SAMPLES}")
    law, thresholds = _law_and_thresholds(args)
    if args.orientation_deg is not None and robot.mobility != "6":
        raise PmAccuracyError(f"--orientation-deg is for a 6-UPS; a {robot.architecture}'s map covers its whole "
                              "workspace")
    pct = tuple(args.percentile) if percentile else None
    # the worst case; with --percentile per quantity std, rss, the percentiles (and exceedances)
    n_variables = len(spatial_maps.WORST_VARIABLES) + (8 * (2 + len(pct)) + len(thresholds) if percentile else 0)
    if suffix == ".nc":
        try:
            spatial_maps.check_spatial_fits_in_memory(args.grid, n_variables)
        except ConfigError as exc:
            raise PmAccuracyError(f"--grid: {exc.message}") from None
    _common.prepare_output(out, "--out", MAP_TYPES)
    _common.check_plot_options(args)
    _common.check_plot(args)
    if percentile:   # rough rate: 2e6 point-samples per second (a 6-UPS on 2 cores, outside points included)
        _common.warn_long_run(args.grid ** 3 * samples / 2e6, f"--grid {args.grid} with --samples {samples}")
    sources = _sources(args, robot)
    # roll, pitch, yaw (deg, extrinsic x-y-z) -> the rotation vector the library takes
    orientation = euler_xyz_to_rotvec(np.array(args.orientation_deg or [0.0, 0.0, 0.0], dtype=float), degrees=True)
    options = dict(n=args.grid, orientation=orientation, block=args.chunk_size, workers=args.workers)
    if percentile:
        options.update(percentiles=pct, samples=samples, seed=0 if args.seed is None else args.seed,
                       distribution=law, thresholds=thresholds)
    if args.scheduler:
        from .._optional import require

        Client = require("distributed").Client
        try:
            with Client(args.scheduler) as client:
                ranges = spatial_maps.write_spatial_map(out, robot, sources, use_dask=client, **options)
        except OSError as exc:  # e.g. the scheduler cannot be reached
            if exc.filename:
                raise
            raise PmAccuracyError(f"--scheduler: {args.scheduler}: {exc}") from None
    else:
        ranges = spatial_maps.write_spatial_map(out, robot, sources, use_dask=bool(args.dask), **options)
    with (xr.open_zarr(out) if suffix == ".zarr" else xr.open_dataset(out)) as ds:
        units = {name: var.attrs.get("units", "") for name, var in ds.data_vars.items()}
        if args.plot:
            from ..report.spatial_figures import save_map_slices_figure

            save_map_slices_figure(robot, ds.load(), args.plot, dpi=args.dpi, vmin=args.vmin, vmax=args.vmax)
    rows = []
    for name, (lo, hi) in ranges.items():
        unit = units[name]
        scale = np.degrees(1.0) if unit == "rad" else 1.0
        rows.append({"quantity": name if unit != "rad" else f"{name}_deg", "min": lo * scale, "max": hi * scale,
                     "unit": "deg" if unit == "rad" else unit})
    _common.emit(rows, args.format)
    return 0


#: Columns of the statistics table (json and csv have every statistic), after the percentiles' place.
_STAT_TABLE = ("quantity", "unit", "mean_abs", "rms", "rss", "max_abs", "worst", "exceed", "se_exceed", "threshold")


def _law_and_thresholds(args: argparse.Namespace) -> tuple[str, dict]:
    """``--distribution`` (one law for every source: uniform or normal) and ``--threshold`` of a spatial robot's
    statistics or percentile map, checked."""
    from ..accuracy.spatial_statistics import LAWS, QUANTITIES

    law = args.distribution or "uniform"
    if law not in LAWS:
        raise PmAccuracyError(f"--distribution: spatial robots take one law for every source, uniform or normal "
                              f"(truncated Gaussian, sigma = half-width / 3), got {law!r}")
    thresholds = dict(args.threshold or [])
    for key in thresholds:
        if key not in QUANTITIES:
            raise PmAccuracyError(f"--threshold: {key} is a planar quantity; a spatial robot's: "
                                  f"{', '.join(QUANTITIES)}")
    return law, thresholds


def run_statistics(args: argparse.Namespace, robot) -> int:
    """``statistics`` on a spatial robot at one pose (its own coordinates): Monte Carlo statistics of the
    first-order error twist beside the exact RSS and the worst case
    (:func:`pmaccuracy.accuracy.spatial_statistics.spatial_pose_statistics`); one row per quantity, with its
    ``unit`` (mm or deg)."""
    from ..accuracy.spatial_statistics import MIN_SAMPLES, spatial_pose_statistics

    unavailable = (("--phi-deg", args.phi_deg), ("--out", args.out), ("--plot", args.plot),
                   ("--exact-samples", args.exact_samples),
                   ("--box/--disc/--polygon/--region", any(getattr(args, k, None) is not None
                                                           for k in ("box", "disc", "polygon", "region"))))
    for option, value in unavailable:
        if value:
            maps = (f"; percentile maps of a spatial robot: pmaccuracy map --robot {robot.name} --percentile P "
                    f"--out FILE.nc|.zarr" if option in ("--phi-deg", "--out", "--plot") else "")
            raise PmAccuracyError(f"{option} is not available for spatial robots' statistics yet ({robot.name} is "
                                  f"a {robot.architecture}): give one --pose{maps}")
    names = robot.controlled
    if args.pose is None:
        raise PmAccuracyError(f"--pose: give one pose {' '.join(n.upper() for n in names)} (mm, deg) of the "
                              f"{robot.architecture}")
    samples = 100_000 if args.samples is None else args.samples
    if samples < MIN_SAMPLES:
        raise PmAccuracyError(f"--samples: {samples} is too few for a spatial robot's statistics; give at least "
                              f"{MIN_SAMPLES}")
    law, thresholds = _law_and_thresholds(args)
    full = poses(robot, [args.pose], None)[0]
    sources = _sources(args, robot)
    try:
        result = spatial_pose_statistics(robot, sources, full, samples=samples, seed=args.seed, distribution=law,
                                         percentiles=args.percentile or (95.0, 99.0), thresholds=thresholds)
    except PoseError as exc:    # unreachable, near-singular: name the option, plain numbers
        import re

        raise type(exc)("--pose: " + re.sub(r"np\.float64\(([^)]*)\)", r"\1", str(exc))) from None
    data = result.to_dict()
    data["pose"] = _pose_record(robot, full)
    if args.format == "json":
        _common.emit(data, "json")
        return 0
    rows = [{"quantity": q, "unit": "deg" if q.endswith("_deg") else "mm", **stats}
            for q, stats in data["quantities"].items()]
    if args.format == "table":
        def order(key):
            if key[:1] == "p" and key[1:2].isdigit():
                return (1, float(key[1:]))
            k = _STAT_TABLE.index(key)
            return (0 if k < 5 else 2, k)

        rows = [{k: r[k] for k in sorted((k for k in r if k in _STAT_TABLE or (k[:1] == "p" and k[1:2].isdigit()
                                                                                 and "_" not in k)), key=order)}
                for r in rows]
    _common.emit(rows, args.format)
    return 0


def parse_targets(items) -> dict[str, float]:
    """``--target NAME=VALUE`` items of a spatial robot as ``{name: value}`` (names of
    :data:`pmaccuracy.accuracy.spatial_synthesis.TARGETS`: mm, deg); a bad item raises naming ``--target``."""
    from ..accuracy.spatial_synthesis import TARGETS

    targets = {}
    for item in items:
        name, sep, value = str(item).partition("=")
        name = name.strip()
        if not sep or name not in TARGETS:
            raise PmAccuracyError(f"--target: expected NAME=VALUE with NAME one of {', '.join(TARGETS)} (mm, deg), "
                                  f"got {item!r}")
        if name in targets:
            raise PmAccuracyError(f"--target: {name} given twice")
        try:
            v = float(value)
        except ValueError:
            raise PmAccuracyError(f"--target: {name}: not a number: {value!r}") from None
        if not (np.isfinite(v) and v > 0):
            raise PmAccuracyError(f"--target: {name} must be finite and > 0, got {value}")
        targets[name] = v
    return targets
