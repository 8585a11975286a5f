"""``pmaccuracy map``: maximum pose errors over the workspace (Figs. 9-12)."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from .. import figures
from ..clearances import ClearanceSet
from ..errors import ConfigError
from ..maps import error_map, save_map, summarize
from . import _common
from .bounds_cmd import add_clearances


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "map", help="error maps over constant-orientation workspaces (NetCDF or CSV, optional figure)",
        description="Exact dx_max, dy_max, dp_max (mm) and dphi_max (deg) on an N x N grid over the workspace at "
                    "each orientation. Writes NetCDF (.nc) or CSV (.csv) by extension and prints the ranges.")
    _common.add_robot(p)
    add_clearances(p)
    p.add_argument("--phi-deg", type=_common.finite_float, action="append", required=True, metavar="PHI",
                   help="platform orientation in degrees (repeatable)")
    p.add_argument("--grid", type=_common.positive_int, default=101, metavar="N", help="grid points per axis")
    p.add_argument("--out", required=True, metavar="FILE", help="output map, .nc or .csv")
    p.add_argument("--plot", metavar="FILE.png",
                   help="four-panel figure; with several orientations one file per orientation, FILE-<phi>deg.png")
    p.add_argument("--chunk-size", type=_common.positive_int, default=1 << 18, metavar="K",
                   help="grid points per block")
    p.add_argument("--dask", action="store_true", help="compute the blocks with Dask (pmaccuracy[dask])")
    p.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help="progress bar (default: when stderr is a terminal)")
    _common.add_format(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    robot = _common.load_robot(args)
    clearances = ClearanceSet.load(args.clearances)
    out = Path(args.out)
    if out.suffix.lower() not in (".nc", ".csv"):
        raise ConfigError(f"unknown map file type {out.suffix!r}: use .nc or .csv", source=args.out)
    if args.grid < 2:
        raise ConfigError("--grid needs at least 2 points per axis")
    ds = error_map(robot, clearances, np.radians(args.phi_deg), args.grid, chunk_size=args.chunk_size,
                   use_dask=args.dask, progress=args.progress)
    save_map(ds, out)
    if args.plot:
        plot = Path(args.plot)
        for phi in ds.phi.values:
            path = plot if ds.sizes["phi"] == 1 else plot.with_name(f"{plot.stem}-{phi:g}deg{plot.suffix}")
            figures.save(figures.plot_error_map(ds, float(phi)), path)
    rows = [{"phi_deg": float(phi), **{k: v for k, v in ranges.items()}} for phi, ranges in
            zip(ds.phi.values, summarize(ds).values())]
    _common.emit(rows, args.format)
    return 0
