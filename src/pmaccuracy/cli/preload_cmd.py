"""``pmaccuracy preload``: the smallest constant platform wrench that keeps every joint's contact fixed over a box of
process wrenches, and the range of the loaded error without it."""

from __future__ import annotations

import argparse
import math

from . import _common
from .load_cmd import add_map_options, add_robot_clearances_poses, check_map_options, write_map


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "preload", help="smallest preload keeping every contact fixed over a box of process wrenches (any architecture)",
        description="For process wrenches anywhere in the box --fx/--fy/--m LO HI (N, N, N mm about the platform "
                    "centre, base frame), at each pose: the range of the loaded pose error and the legs whose "
                    "contact flips inside the box, then the smallest constant wrench (size max(|fx|, |fy|, |m| / L), "
                    "L the robot's size) that keeps every leg's contact on one side for every wrench of the box, so "
                    "the clearance error becomes a constant offset that calibration removes (linear programs).")
    add_robot_clearances_poses(p)
    for key, unit in (("fx", "N"), ("fy", "N"), ("m", "N mm; planar robots"), ("fz", "N; spatial robots"),
                      ("mx", "N mm about P; spatial robots"), ("my", "N mm about P; spatial robots"),
                      ("mz", "N mm about P; spatial robots")):
        p.add_argument(f"--{key}", nargs=2, type=_common.finite_float, default=(0.0, 0.0), metavar=("LO", "HI"),
                       help=f"range of the process {key} ({unit}; default 0 0)")
    p.add_argument("--direction", nargs=6, type=_common.finite_float, default=None,
                   metavar=("FX", "FY", "FZ", "MX", "MY", "MZ"),
                   help="spatial robots: the preload along this wrench (N, N mm about P): its smallest multiple")
    add_map_options(p, "instead of poses: over the workspace grid at --phi-deg, the range of the loaded error over the "
                       "box (dx_lo, dx_hi, ... mm and deg), which legs' contacts flip (flip1..3) and how many "
                       "(flipping_legs), written to --out (.nc or .csv)")
    p.add_argument("--springs", action="store_true",
                   help="spatial 6-UPS, 3-RPS, 3-UPU at poses: the preload as constant-force springs alongside the "
                        "legs (one per leg, base to platform joint centre) holding at every --pose at once, instead "
                        "of a platform wrench (spring1_N, ...: positive pushes the platform away from the base)")
    p.add_argument("--cylinder", nargs=5, type=_common.finite_float, metavar=("X", "Y", "R", "Z0", "Z1"),
                   help="spatial robots, without poses: the region is the cylinder of axis (X, Y), radius R and "
                        "heights Z0..Z1 (mm)")
    p.add_argument("--sphere", nargs=4, type=_common.finite_float, metavar=("X", "Y", "Z", "R"),
                   help="spatial robots, without poses: the region is the sphere of centre X, Y, Z, radius R (mm)")
    _common.add_plot(p, "draw the (first) pose: the legs whose contact flips over the box, the preload, and the "
                        "error's range without preload beside the constant offset with it and the worst case; with "
                        "--map: the ranges over the box and the flipping legs, one figure per --phi-deg")
    p.add_argument("--certify", action=argparse.BooleanOptionalAction, default=True,
                   help="without poses: prove the preload over the whole region by interval branch and bound "
                        "(certified_size_N; default: on)")
    p.add_argument("--phi-steps", type=_common.positive_int, default=5, metavar="K",
                   help="without poses: orientations sampled over the --phi-deg LO HI interval (default: 5)")
    _common.add_format(p)
    p.epilog = ((p.epilog or "") + " Without poses and without --map: the smallest constant preload for every "
                "process wrench of the box at every pose of the region (--workspace, default, --box, --disc, "
                "--polygon; --phi-deg PHI or LO HI): a linear program over a --grid N x N (default 21) by "
                "--phi-steps sample, checked on a twice denser sample and refined at its worst poses. Spatial robots "
                "(--fz, --mx, --my, --mz too): at poses the loaded error's range over the box (an enclosure and the "
                "range attained at its corners) and the preload; --map over the 3D workspace grid (--grid, "
                "--orientation-deg); without poses one preload for a region (--workspace, --box with six numbers, "
                "--cylinder, --sphere; checked on a sample, not proved); --springs: springs alongside the legs "
                "instead of a platform wrench.").strip()
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from ..accuracy.loads import design_preload, wrench_set_errors
    from ..errors import ConfigError
    from ..io.resolve import load_clearances
    from ..model.plausibility import force_messages, warn

    from .spatial_load_cmd import refuse_spatial_options

    robot = _common.load_robot(args)
    from ..model.spatial import is_spatial

    if is_spatial(robot):
        from . import spatial_load_cmd

        return spatial_load_cmd.run_preload(args, robot)
    if args.pose:
        from .kinematics_cmd import _three

        _three(args.pose, "--pose", "X Y PHI_DEG (mm, mm, deg)")
    refuse_spatial_options(args)
    check_map_options(args, region_design=True)
    if args.phi_deg is not None and not args.map and len(args.phi_deg) > 2:
        raise ConfigError(f"the region's orientations: expected PHI or LO HI in degrees, got {len(args.phi_deg)} "
                          "values", key="--phi-deg")
    plot = _common.check_plot(args)
    if plot and not (args.pose or args.poses_csv or args.map):
        raise ConfigError("draws one pose (--pose) or a map (--map), not a region's preload", key="--plot")
    clearances = load_clearances(_common.clearances_or_default(args, robot), robot)
    lo = np.array([args.fx[0], args.fy[0], args.m[0]])
    hi = np.array([args.fx[1], args.fy[1], args.m[1]])
    for k, key in enumerate(("--fx", "--fy", "--m")):
        if lo[k] > hi[k]:
            raise ConfigError(f"needs LO <= HI, got {lo[k]:g} {hi[k]:g}", key=key)
    if not np.any(hi - lo):
        raise ConfigError("the box of process wrenches is a single wrench: give a range LO HI", key="--fx")
    ends = np.maximum(np.abs(lo), np.abs(hi))
    warn(force_messages({"|--fx|": ends[0], "|--fy|": ends[1]}, {"|--m|": ends[2]}, robot.characteristic_length))
    center, half = (lo + hi) / 2, (hi - lo) / 2
    if args.map:
        return run_map(args, robot, clearances, center, half)
    if not (args.pose or args.poses_csv):
        return run_region(args, robot, clearances, center, half)
    poses = _common.poses_from_args(args.pose, args.poses_csv)
    ranges = wrench_set_errors(robot, clearances, poses, center, half)
    rows = []
    for k, pose in enumerate(poses):
        pre = design_preload(robot, clearances, pose, center, half)
        rows.append({"x": float(pose[0]), "y": float(pose[1]), "phi_deg": math.degrees(pose[2]),
                     "flipping_legs": ",".join(str(i + 1) for i in range(3) if ranges.flips[k, i]) or "-",
                     "dx_range": float(ranges.upper[k, 0] - ranges.lower[k, 0]),
                     "dy_range": float(ranges.upper[k, 1] - ranges.lower[k, 1]),
                     "dphi_deg_range": math.degrees(ranges.upper[k, 2] - ranges.lower[k, 2]),
                     "preload_fx_N": float(pre.wrench[0]) + 0.0, "preload_fy_N": float(pre.wrench[1]) + 0.0,
                     "preload_m_Nmm": float(pre.wrench[2]) + 0.0, "preload_size_N": pre.size,
                     "offset_dx": float(pre.offset[0]), "offset_dy": float(pre.offset[1]),
                     "offset_dphi_deg": math.degrees(pre.offset[2]),
                     "dx_max": float(pre.worst[0]), "dy_max": float(pre.worst[1]),
                     "dphi_max_deg": math.degrees(pre.worst[2])})
    if plot:
        from .._savefig import save_figure
        from ..report.load_figures import plot_preload

        save_figure(plot_preload(robot, clearances, poses[0], center, half), plot, dpi=args.dpi, option="--plot")
    _common.emit(rows, args.format)
    return 0


def run_map(args: argparse.Namespace, robot, clearances, center, half) -> int:
    """``preload --map``: the loaded error's range over the box and the flipping legs over the workspace grid."""
    import numpy as np

    from ..accuracy.loads import wrench_set_map
    from ..errors import ConfigError, EmptyWorkspaceError
    from .worst_cmd import parse_shape, shape_key

    shape = parse_shape(args)
    try:
        ds = wrench_set_map(robot, clearances, center, half, np.radians(args.phi_deg or [0.0]), args.grid,
                            region=shape)
    except EmptyWorkspaceError as exc:
        raise ConfigError(str(exc), key=shape_key(args)) from None
    _common.emit(write_map(ds, args.out), args.format)
    if args.plot:
        from ..report.load_figures import plot_wrench_set_map
        from .load_cmd import map_plots

        map_plots(ds, args.plot, args.dpi, plot_wrench_set_map)
    return 0


#: Default grid of the preload over a region.
REGION_GRID = 21


def run_region(args: argparse.Namespace, robot, clearances, center, half) -> int:
    """``preload`` over a region: one constant preload for every pose of it (``design_region_preload``)."""
    import numpy as np

    from ..accuracy.global_worst import make_region
    from ..accuracy.loads import design_region_preload
    from ..errors import ConfigError, EmptyWorkspaceError
    from .worst_cmd import cli_region, parse_shape, shape_key

    grid = REGION_GRID if args.grid is None else args.grid
    if grid < 2:
        raise ConfigError(f"needs at least 2 points per axis, got {grid}", key="--grid")
    phi = list(args.phi_deg or [0.0])
    phi = phi * 2 if len(phi) == 1 else phi
    _common.check_grid_memory(2 * args.phi_steps, 2 * grid, "--grid")
    region = cli_region(make_region, robot, phi, parse_shape(args), args)
    try:
        res = design_region_preload(robot, clearances, region, center, half, grid=grid, n_phi=args.phi_steps,
                                   certify=args.certify)
    except EmptyWorkspaceError as exc:
        raise ConfigError(str(exc), key=shape_key(args)) from None
    _common.emit([res.record()], args.format)
    return 0
