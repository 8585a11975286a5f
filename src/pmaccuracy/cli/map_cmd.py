"""``pmaccuracy map``: maximum pose errors over the workspace (Figs. 9-12)."""

from __future__ import annotations

import argparse
import os
import re
import sys
from pathlib import Path

from ..errors import ConfigError, EmptyWorkspaceError
from . import _common
from .bounds_cmd import add_clearances
from .statistics_cmd import _percentile, _threshold
from .worst_cmd import add_shape, parse_shape, shape_key
from .._optional import require

#: Output types of ``--out`` by extension.
OUT_TYPES = (".nc", ".csv", ".zarr")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "map", help="error maps over constant-orientation workspaces (NetCDF, Zarr or CSV, optional figure)",
        description="Exact maximum pose errors on an N x N grid spanning the workspaces at the given orientations. "
                    "Writes NetCDF (.nc) or CSV (.csv), each block of grid rows written to the file as soon as it "
                    "is computed (assembled in memory first with --dask, --scheduler, or a .csv with --plot), or a "
                    "Zarr store (.zarr), streamed tile by tile with Dask in bounded memory and resumable: run the "
                    "same command again after an interruption and only the missing tiles are computed. Before "
                    "computing it prints the size and an estimated time (with --progress or on a terminal) and "
                    "refuses a map that would not fit on disk (or, assembled in memory, in the available memory). "
                    "Missing parent folders of --out and --plot are created. "
                    "Prints the ranges.")
    _common.add_robot(p)
    add_clearances(p)
    p.add_argument("--phi-deg", type=_common.angle_deg, nargs="+", action="extend", default=None, metavar="PHI",
                   help="platform orientation(s) in degrees: several values (--phi-deg 0 15) and/or the option "
                        "repeated, each value once (required for planar robots)")
    p.add_argument("--orientation-deg", type=_common.angle_deg, nargs=3, metavar=("ROLL", "PITCH", "YAW"),
                   help="spatial 6-UPS: the orientation of its constant-orientation workspace map, roll pitch yaw "
                        "in deg as extrinsic x-y-z rotations (default 0 0 0); spatial robots map their whole "
                        "workspace on a --grid^3 grid (.nc or .zarr)")
    p.add_argument("--grid", type=_common.positive_int, default=101, metavar="N", help="grid points per axis")
    add_shape(p)
    p.add_argument("--out", required=True, metavar="FILE",
                   help="output map: .nc or .csv (written block by block) or .zarr (streamed, resumable; open with "
                        "xarray.open_zarr); missing parent folders are created")
    _common.add_plot(p, "four-panel figure (dx_max, dy_max, dp_max in mm; dphi_max in deg); with several "
                        "orientations one file per orientation, FILE-<phi>deg.png (large maps are drawn from every "
                        "k-th grid point); --vmin/--vmax set the mm panels, the deg panel keeps its own range",
                     maps=True)
    p.add_argument("--chunk-size", type=_common.positive_int, default=None, metavar="K",
                   help="grid points per computed block (default: 65536)")
    p.add_argument("--tile", type=_common.positive_int, default=None, metavar="T",
                   help="Zarr chunk side along y and x, one orientation per chunk (default: 1024)")
    p.add_argument("--dask", action="store_true", help="compute an in-memory map's blocks with Dask (a spatial "
                                                       "map: also a .zarr store's slabs)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="dask.distributed scheduler to compute on, e.g. tcp://10.0.0.1:8786 (implies --dask; with "
                        ".zarr every worker must see --out)")
    p.add_argument("--workers", type=_common.positive_int, default=None, metavar="W",
                   help="threads of the local Dask scheduler for .zarr (default: one per core)")
    p.add_argument("--certified", action="store_true",
                   help="certified upper bounds of the exact (nonlinear) worst case instead of the first-order "
                        "maxima, with the gap to the best feasible configuration per quantity (dx_gap, dy_gap, "
                        "dphi_gap, dp_gap); NaN where not certified; computed in memory (bands of --chunk-size "
                        "points, default 2048; Dask tasks with --dask), .zarr written chunked like map")
    p.add_argument("--gap-pct", type=_common.finite_float, default=None, metavar="PCT",
                   help="with --certified: the gap to the best feasible configuration at which a point's bound is "
                        "refined no further (default 0.5; e.g. 5 for a fast map at large clearances)")
    p.add_argument("--percentile", type=_percentile, action="append", metavar="P",
                   help="spatial robots: a percentile map instead, the P-th percentile of |dq| over random error "
                        "states at every grid point, in (0, 100), repeatable (as statistics; planar robots' "
                        "percentile maps: statistics --phi-deg ... --out)")
    p.add_argument("--samples", type=_common.positive_int, default=None, metavar="N",
                   help="with --percentile: Monte Carlo samples, the same at every point (default: 10000)")
    p.add_argument("--seed", type=_common.nonnegative_int, default=None,
                   help="with --percentile: seed of numpy.random.default_rng (default: 0)")
    p.add_argument("--distribution", metavar="LAW",
                   help="with --percentile: law of every source inside its set, uniform or normal (default: "
                        "uniform)")
    p.add_argument("--threshold", type=_threshold, action="append", metavar="Q=V",
                   help="with --percentile: also the map of P(|Q| > V), Q one of dx, dy, dz, dp (mm), drx_deg, "
                        "dry_deg, drz_deg, dtheta_deg (deg) (repeatable)")
    p.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help="estimate and progress bar on stderr (default: when stderr is a terminal)")
    _common.add_format(p)
    p.set_defaults(func=run)


def prepare_output(path: Path, option: str) -> None:
    """:func:`pmaccuracy.cli._common.prepare_output` (kept here for the commands importing it from this module)."""
    _common.prepare_output(path, option)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from ..accuracy import maps
    from ..io.resolve import load_clearances

    from ..model.spatial import is_spatial

    robot = _common.load_robot(args)
    if is_spatial(robot):
        from . import spatial_cmd

        return spatial_cmd.run_map(args, robot)
    for option in ("percentile", "samples", "seed", "distribution", "threshold"):
        if getattr(args, option) is not None:
            raise ConfigError(f"is for spatial robots' percentile maps; {robot.name}'s: pmaccuracy statistics "
                              f"--phi-deg PHI --out FILE --{option} ...", key=f"--{option}")
    if args.phi_deg is None:
        raise ConfigError("the following arguments are required: --phi-deg")
    if args.orientation_deg is not None:
        raise ConfigError(f"is for spatial robots; {robot.name} is planar (use --phi-deg)", key="--orientation-deg")
    out = Path(args.out)
    suffix = out.suffix.lower()
    if suffix not in OUT_TYPES:
        raise ConfigError(f"unsupported file type {out.suffix or 'none'!r}: use .nc, .csv or .zarr", source=args.out,
                          key="--out")
    _common.check_plot_options(args)
    if args.grid < 2:
        raise ConfigError(f"needs at least 2 points per axis, got {args.grid}", key="--grid")
    if args.workers and suffix != ".zarr":
        raise ConfigError("--workers applies to .zarr maps (use --dask for an in-memory map)", key="--workers")
    _check_unique(args.phi_deg)
    local = ("synchronous", "sync", "single-threaded", "threads", "processes")  # dask's own, for .zarr
    if args.scheduler is not None and not (re.fullmatch(r"[a-z]+://\S+", args.scheduler)
                                           or suffix == ".zarr" and args.scheduler in local):
        raise ConfigError(f"expected a dask.distributed scheduler address like tcp://10.0.0.1:8786"
                          f"{' (or ' + ', '.join(local) + ')' if suffix == '.zarr' else ''}, got {args.scheduler!r}",
                          key="--scheduler")
    shape = parse_shape(args)
    if shape is not None and suffix == ".zarr":
        raise ConfigError("a region applies to in-memory maps (.nc, .csv), not to .zarr maps", key=shape_key(args))
    args.shape = shape
    clearances = load_clearances(_common.clearances_or_default(args, robot), robot)
    phis = np.radians(args.phi_deg)
    n_phi = len(phis)
    # .nc and .csv are written block by block as they are computed (maps.write_map) unless the blocks come from
    # Dask or a CSV map is also drawn: then the map is assembled in memory first.
    # a region's map is cut to its bounding box and computed in memory (write_map takes the whole workspace)
    streamed = (suffix != ".zarr" and not args.dask and not args.scheduler and not (suffix == ".csv" and args.plot)
                and shape is None and not args.certified)
    if args.gap_pct is not None and not args.certified:
        raise ConfigError("needs --certified", key="--gap-pct")
    if args.certified:
        _common.check_gap_pct(args.gap_pct)
        if suffix == ".csv":
            raise ConfigError("a certified map is written as .nc or .zarr (it has eight variables)", key="--out")
        if args.workers:
            raise ConfigError("--workers applies to first-order .zarr maps (use --dask with --certified)",
                              key="--workers")
    if suffix == ".nc":
        maps.check_netcdf_size(n_phi, args.grid)
    # the output path first (a folder that cannot be created is the path's fault, not the grid's), then its disk
    _common.prepare_output(out, "--out", OUT_TYPES)
    if suffix == ".zarr" or streamed:   # before anything is computed
        _check_disk(maps, out, n_phi * (2 if args.certified else 1), args.grid)
    if not streamed and (suffix != ".zarr" or args.certified):
        maps.check_fits_in_memory(n_phi * (2 if args.certified else 1), args.grid)
    _common.check_plot(args)
    chunk = args.chunk_size or maps.DEFAULT_CHUNK
    show = sys.stderr.isatty() if args.progress is None else args.progress
    if args.certified:
        return _certified(maps, robot, clearances, phis, args, out, show)
    if show:
        _announce(maps, robot, clearances, phis, args, suffix, streamed)
    elif args.grid > LONG_GRID:
        _warn_if_long(maps, robot, clearances, phis, args, suffix)
    if suffix == ".zarr":
        result = maps.write_zarr_map(out, robot, clearances, phis, args.grid, tile=args.tile or maps.DEFAULT_ZARR_TILE,
                                     chunk_size=chunk, scheduler=args.scheduler, workers=args.workers,
                                     progress=show)
        summary = result["summary"]
        if args.plot:
            import xarray as xr

            with xr.open_zarr(out) as ds:
                _plots(_thinned(ds), Path(args.plot), args)
    elif streamed:
        try:
            summary = maps.write_map(out, robot, clearances, phis, args.grid, chunk_size=chunk, progress=show)
        except ConfigError as exc:
            if exc.key != "clearances":
                raise
            raise ConfigError(exc.message, source=str(args.clearances), key="--clearances") from None
        if args.plot:  # .nc: read back lazily, every k-th point of a large map
            import xarray as xr

            with xr.open_dataset(out, engine="scipy") as ds:
                _plots(_thinned(ds), Path(args.plot), args)
    else:
        try:
            ds = _in_memory(maps, robot, clearances, phis, args, chunk, show)
        except EmptyWorkspaceError as exc:
            if shape is None:
                raise
            raise ConfigError(str(exc), key=shape_key(args)) from None
        except OSError as exc:  # e.g. the scheduler cannot be reached
            if not args.scheduler or exc.filename:
                raise
            raise ConfigError(f"{args.scheduler}: {exc}", key="--scheduler") from None
        if any(bool(np.isinf(ds[v].values).any()) for v in ds.data_vars):
            raise ConfigError("the errors overflow: the clearances are far outside any physical range; nothing "
                              "written", source=str(args.clearances), key="--clearances")
        maps.save_map(ds, out)
        if args.plot:
            _plots(_thinned(ds), Path(args.plot), args)
        summary = maps.summarize(ds)
    rows = [{"phi_deg": float(key), **ranges} for key, ranges in summary.items()]
    from ..model.plausibility import linearity_messages, warn

    warn(linearity_messages([r["dphi_max_deg"][1] for r in rows], what="the map's largest dphi_max"))
    _common.emit(rows, args.format)
    return 0


def _certified(maps, robot, clearances, phis, args, out: Path, show: bool) -> int:
    """``map --certified``: :func:`pmaccuracy.accuracy.maps.certified_error_map` in memory, written as .nc or
    as .zarr chunked like ``map`` (one orientation, ``--tile`` x ``--tile`` points per chunk); prints each layer's
    ranges and largest gaps."""
    import numpy as np

    from ..model.plausibility import warn

    chunk = args.chunk_size or maps.CERTIFIED_CHUNK
    gap = (0.5 if args.gap_pct is None else args.gap_pct) / 100
    try:
        if args.scheduler:
            Client = require("distributed").Client
            with Client(args.scheduler):
                ds = maps.certified_error_map(robot, clearances, phis, args.grid, chunk_size=chunk, use_dask=True,
                                              progress=show, region=args.shape, split_gap=gap)
        else:
            ds = maps.certified_error_map(robot, clearances, phis, args.grid, chunk_size=chunk, use_dask=args.dask,
                                          progress=show, region=args.shape, split_gap=gap)
    except EmptyWorkspaceError as exc:
        if args.shape is None:
            raise
        raise ConfigError(str(exc), key=shape_key(args)) from None
    if out.suffix.lower() == ".zarr":
        tile = args.tile or maps.DEFAULT_ZARR_TILE
        ds = ds.chunk({"phi": 1, "y": min(tile, ds.sizes["y"]), "x": min(tile, ds.sizes["x"])})
    maps.save_map(ds, out)
    if args.plot:
        _plots(_thinned(ds), Path(args.plot), args)
    rows = []
    for key, ranges in maps.summarize(ds).items():
        layer = ds.sel(phi=float(key))
        gaps = {q: float(np.nanmax(layer[f"{q}_gap"].values)) if np.isfinite(layer[f"{q}_gap"].values).any()
                else float("nan") for q in ("dx", "dy", "dphi", "dp")}
        rows.append({"phi_deg": float(key), **ranges, "largest_gap": gaps,
                     "certified_points": int(np.isfinite(layer["dx_max"].values).sum())})
    worst = max((g for r in rows for g in r["largest_gap"].values() if np.isfinite(g)), default=0.0)
    if worst > GAP_WARNING:
        warn([f"certified bounds up to {worst * 100:.3g} % above the best feasible configuration (loose where the "
              f"error set is large for the pose)"])
    _common.emit(rows, args.format)
    return 0


#: ``map --certified`` warns (one line) where a certified bound exceeds the best feasible value by more than this.
GAP_WARNING = 0.05
#: Grids above this many points per axis get a time estimate before computing (a warning when long).
LONG_GRID = 500
#: Estimated run time (s) above which ``map`` warns before computing.
LONG_SECONDS = 600.0


def _check_unique(phis_deg: list[float]) -> None:
    """Refuse an orientation given twice (the map would have two layers of the same coordinate)."""
    seen = set()
    for phi in phis_deg:
        if phi in seen:
            raise ConfigError(f"orientation {phi:g} deg given twice", key="--phi-deg")
        seen.add(phi)


def _check_disk(maps, out: Path, n_phi: int, n: int) -> None:
    """Refuse a Zarr store that cannot fit on its disk (the results uncompressed; checked before writing)."""
    import shutil

    need = maps.map_nbytes(n_phi, n)
    where = out.resolve()
    while not where.exists() and where != where.parent:
        where = where.parent
    try:
        free = shutil.disk_usage(where).free
    except OSError:
        return
    if need > free:
        raise ConfigError(f"a {n_phi} x {n} x {n} map needs up to {maps.format_bytes(need)} on disk but only "
                          f"{maps.format_bytes(free)} is free at {where}: use a smaller --grid", key="--grid")


def _warn_if_long(maps, robot, clearances, phis, args, suffix: str) -> None:
    """A plausibility warning before a long run (the estimate is timed on a sparse sub-grid)."""
    import warnings

    from ..model.plausibility import LongRunWarning

    x, y = maps.map_grid(robot, phis, args.grid)
    workers = (args.workers or os.cpu_count() or 1) if suffix == ".zarr" else 1
    seconds = maps.estimate_seconds(robot, clearances, phis, x, y, workers=workers)
    if seconds > LONG_SECONDS:
        size = maps.format_bytes(maps.map_nbytes(len(phis), args.grid))
        warnings.warn(f"--grid {args.grid}: about {_duration(seconds)} of computing for {size} of results "
                      f"(estimate); Ctrl-C stops it" + (" and the same command resumes it" if suffix == ".zarr"
                                                        else ""), LongRunWarning)


def _in_memory(maps, robot, clearances, phis, args, chunk, show):
    if not args.scheduler:
        return maps.error_map(robot, clearances, phis, args.grid, chunk_size=chunk, use_dask=args.dask,
                              progress=show, region=args.shape)
    Client = require("distributed").Client

    with Client(args.scheduler):
        return maps.error_map(robot, clearances, phis, args.grid, chunk_size=chunk, use_dask=True, progress=show,
                              region=args.shape)


def _announce(maps, robot, clearances, phis, args, suffix: str, streamed: bool) -> None:
    """One line on stderr: size of the result and a rough time, before computing."""
    x, y = maps.map_grid(robot, phis, args.grid)
    size = maps.map_nbytes(len(phis), args.grid)
    workers = (args.workers or os.cpu_count() or 1) if suffix == ".zarr" else 1
    seconds = maps.estimate_seconds(robot, clearances, phis, x, y, workers=workers)
    where = "streamed to Zarr" if suffix == ".zarr" else "written block by block" if streamed else "in memory"
    print(f"map: {len(phis)} x {args.grid} x {args.grid} grid, {maps.format_bytes(size)} of results {where}, "
          f"about {_duration(seconds)}", file=sys.stderr)


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def _thinned(ds, max_points: int = 1001):
    """Every k-th grid point so that a figure draws at most ``max_points`` per axis (a figure shows no more)."""
    step = max(1, -(-max(ds.sizes["x"], ds.sizes["y"]) // max_points))
    return ds.isel(x=slice(None, None, step), y=slice(None, None, step)).load() if step > 1 else ds.load()


def _plots(ds, plot: Path, args: argparse.Namespace) -> None:
    from ..report import figures

    for phi in ds.phi.values:
        path = plot if ds.sizes["phi"] == 1 else plot.with_name(f"{plot.stem}-{phi:g}deg{plot.suffix}")
        fig = figures.plot_error_map(ds, float(phi), vmin=args.vmin, vmax=args.vmax, log=args.log)
        figures.save_figure(fig, path, dpi=args.dpi, option="--plot")
        if path != plot:   # one file per orientation: say where each went (stderr, after a successful run)
            args.__dict__.setdefault("notes", []).append(f"pmaccuracy map: wrote {path}")
