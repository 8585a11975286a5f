"""``pmaccuracy load``: the pose error a known platform load produces, with every joint's reaction."""

from __future__ import annotations

import argparse
import math

import numpy as np

from . import _common


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "load", help="pose error under a known platform load: statics, reactions, clearances taken up (any architecture)",
        description="Statics of the platform under a wrench (and optionally its weight): each leg's wrench "
                    "intensity, the actuator efforts and every joint's reaction; each clearance taken up along its "
                    "joint's reaction; the resulting pose error, first order and on the exact loop closure. Forces "
                    "in N, moments in N mm about the platform centre, base frame; poses x mm, y mm, phi deg.")
    add_robot_clearances_poses(p, serial=True)
    p.add_argument("--joints", nargs="+", type=_common.finite_float, action="append", metavar="Q",
                   help="serial arms (architecture = \"serial\", preset planar_3r_arm) instead of --pose: the joint "
                        "values base to tip, deg for R, mm for P (repeatable); the load then acts on the end link, "
                        "--m about the end point, --com in the end frame")
    p.add_argument("--fx", type=_common.finite_float, default=0.0, help="force on the platform along x (N)")
    p.add_argument("--fy", type=_common.finite_float, default=0.0, help="force on the platform along y (N)")
    p.add_argument("--m", type=_common.finite_float, default=0.0, metavar="M",
                   help="planar robots: moment on the platform about its centre (N mm, counter-clockwise)")
    p.add_argument("--fz", type=_common.finite_float, default=0.0, help="spatial robots: force along z (N)")
    for axis in "xyz":
        p.add_argument(f"--m{axis}", type=_common.finite_float, default=0.0,
                       help=f"spatial robots: moment about the base {axis}-axis through the platform's reference "
                            "point P (N mm)")
    p.add_argument("--mass", type=_common.finite_float, default=0.0, help="platform mass (kg; 0: no weight)")
    p.add_argument("--com", nargs="+", type=_common.finite_float, default=None, metavar="V",
                   help="centre of mass in the platform frame (mm): X Y (planar), X Y Z (spatial; default the "
                        "reference point)")
    p.add_argument("--gravity-deg", type=_common.finite_float, default=-90.0,
                   help="planar robots: direction of gravity in the base plane (deg from x; default -90: along -y)")
    p.add_argument("--gravity", nargs=3, type=_common.finite_float, default=None, metavar=("GX", "GY", "GZ"),
                   help="spatial robots: direction of gravity in the base frame (default 0 0 -1)")
    p.add_argument("--unloaded-below", type=_common.finite_float, default=1e-6, metavar="N",
                   help="a leg whose wrench intensity is at most this (N) is unloaded: its state is undetermined")
    p.add_argument("--details", action="store_true",
                   help="also every joint's reaction: force (R), normal force and moment about the block (P), and "
                        "the contact state the load selects: pin shift (R), rhombus vertex sigma/tau and tilt (P), "
                        "actuator backlash side")
    p.add_argument("--allow-outside", action="store_true", help=argparse.SUPPRESS)
    add_map_options(p, "instead of poses: the loaded error over the workspace grid at --phi-deg (NetCDF .nc or CSV "
                       ".csv): dx, dy, dp (mm), dphi (deg), the spread the unloaded legs leave, the legs' "
                       "intensities and the number of unloaded legs, NaN outside the workspace")
    p.add_argument("--exact", action="store_true", help="with --map: also the exact loop closure (dx_exact, ...)")
    _common.add_plot(p, "draw the robot at the (first) pose with the load, every joint's force (arrows at a stated "
                        "scale), each joint's contact state, unloaded legs greyed and the loaded platform magnified; "
                        "with --map: the map's panels (dx, dy, |dp| mm, dphi deg; unloaded legs' spread), one "
                        "figure per --phi-deg (FILE-<phi>deg.EXT when several)")
    p.add_argument("--magnify", type=_common.finite_float, metavar="K",
                   help="magnification of the loaded displacement in --plot (default: a round factor that makes it "
                        "visible)")
    _common.add_format(p)
    p.set_defaults(func=run)


#: Default grid of ``load --map`` and ``preload --map``.
MAP_GRID = 41


def add_map_options(p: argparse.ArgumentParser, what: str) -> None:
    """``--map``, ``--grid``, ``--phi-deg``, ``--out`` and the region (``--workspace``, ``--box``, ``--disc``,
    ``--polygon``) of ``load --map`` and ``preload``."""
    from .worst_cmd import add_shape

    p.add_argument("--map", action="store_true", help=what)
    p.add_argument("--grid", type=_common.positive_int, default=None, metavar="N",
                   help="with --map: N x N grid over the workspace's bounding box (default: 41; spatial robots: N x N x N, "
                        "default 10 for load, 6 for preload, and 5 per axis for the preload over a region)")
    p.add_argument("--phi-deg", type=_common.angle_deg, nargs="+", default=None, metavar="PHI",
                   help="platform orientation(s) in degrees of the map (default: 0)")
    p.add_argument("--out", metavar="FILE", help="with --map: the map file, .nc or .csv (missing folders are created)")
    p.add_argument("--orientation-deg", nargs="+", type=_common.angle_deg, default=None, metavar="DEG",
                   help="spatial 6-UPS: roll pitch yaw (deg, extrinsic x-y-z) of the map's constant orientation "
                        "(default 0 0 0) or, for the preload over a region, three fixed angles or six R0 R1 P0 P1 "
                        "Y0 Y1 ranges (default: the home orientation)")
    add_shape(p)


def check_map_options(args: argparse.Namespace, *, region_design: bool = False) -> None:
    """Refuse map options without ``--map`` (and poses with it) before anything is computed."""
    from ..errors import ConfigError
    from .worst_cmd import shape_key

    poses = bool(args.pose) or bool(args.poses_csv)
    if args.map:
        if poses:
            raise ConfigError("a map covers the workspace grid: give --map or poses (--pose, --poses-csv), not both",
                              key="--map")
        if not args.out:
            raise ConfigError("--map needs --out FILE.nc or FILE.csv", key="--out")
        args.grid = MAP_GRID if args.grid is None else args.grid
        if args.grid < 2:
            raise ConfigError(f"needs at least 2 points per axis, got {args.grid}", key="--grid")
        _common.check_grid_memory(len(args.phi_deg or [0.0]), args.grid, "--grid")
        _common.prepare_output(args.out, "--out", (".nc", ".csv"))
        return
    if region_design and not poses:
        return
    for key, given in (("--out", args.out), ("--phi-deg", args.phi_deg), ("--grid", args.grid),
                       (shape_key(args), shape_key(args) != "--workspace" or args.workspace)):
        if given:
            raise ConfigError("goes with --map" + (" (or, without poses, the preload over a region)"
                                                   if region_design else ""), key=key)


def write_map(ds, out: str) -> list[dict]:
    """Write a load map (.nc: NetCDF through scipy; .csv: one row per grid point inside, phi in degrees) and
    return the ranges of its variables (one record per variable, min and max over the grid)."""
    from pathlib import Path

    path = Path(out)
    if path.suffix.lower() == ".nc":
        ds.to_netcdf(path, engine="scipy")
    else:
        df = ds.to_dataframe().reset_index().rename(columns={"phi": "phi_deg"})
        first = next(iter(ds.data_vars))
        df = df[np.isfinite(df[first])]
        df[["x", "y", "phi_deg", *ds.data_vars]].to_csv(path, index=False, float_format="%.17g")
    rows = []
    for name, var in ds.data_vars.items():
        lo, hi = float(var.min(skipna=True)), float(var.max(skipna=True))
        rows.append({"variable": name, "units": var.attrs.get("units", ""), "min": lo if math.isfinite(lo) else None,
                     "max": hi if math.isfinite(hi) else None})
    return rows


def add_robot_clearances_poses(p: argparse.ArgumentParser, serial: bool = False) -> None:
    """``--robot``, ``--clearances`` (the default rule of every command:
    :func:`pmaccuracy.io.resolve.default_clearances`) and the poses (``--pose``, ``--poses-csv``) of ``load`` and
    ``preload`` (``serial``: the command also takes serial arms)."""
    _common.add_robot(p)
    p.add_argument("--clearances", default=None, help=_common.CLEARANCES_HELP)
    from .spatial_cmd import POSE_HELP

    p.add_argument("--pose", nargs="+", type=_common.finite_float, action="append", metavar="V",
                   help="a commanded pose: " + POSE_HELP)
    p.add_argument("--poses-csv", metavar="FILE", help="CSV with header x,y,phi_deg (spatial robots: their "
                   "controlled coordinates, e.g. x,y,z,roll_deg,pitch_deg,yaw_deg)")


def run(args: argparse.Namespace) -> int:
    from ..accuracy.loads import G0, Load, loaded_pose_error
    from ..errors import ConfigError
    from ..io.resolve import load_clearances
    from ..model.plausibility import force_messages, orientation_messages, warn

    from . import serial_cmd

    if serial_cmd.is_serial_robot(args.robot):   # architecture = "serial": joint values instead of poses
        _planar_com(args)
        return run_serial(args)
    robot = _common.load_robot(args)
    if _spatial(robot):
        from . import spatial_load_cmd

        args.com = (0.0, 0.0, 0.0) if args.com is None else args.com
        return spatial_load_cmd.run_load(args, robot)
    _planar_com(args)
    serial_cmd.refuse_joints(args)
    check_map_options(args)
    if args.exact and not args.map:
        raise ConfigError("goes with --map (the poses' output always has the exact columns)", key="--exact")
    plot = _common.check_plot(args)
    if args.magnify is not None and args.map:
        raise ConfigError("goes with --plot of a pose, not --map", key="--magnify")
    if args.magnify is not None and not args.magnify > 0:
        raise ConfigError(f"must be a factor > 0, got {args.magnify:g}", key="--magnify")
    if args.magnify is not None and not plot:
        raise ConfigError("goes with --plot", key="--magnify")
    clearances = load_clearances(_common.clearances_or_default(args, robot), robot)
    warn(force_messages({"--fx": args.fx, "--fy": args.fy, "--mass (weight)": G0 * args.mass}, {"--m": args.m},
                        robot.characteristic_length))
    if args.mass:
        warn(orientation_messages([args.gravity_deg], "--gravity-deg", "directions", direction=True))
    if args.map:
        return run_map(args, robot, clearances)
    poses = _common.poses_from_args(args.pose, args.poses_csv)
    if args.mass < 0:
        raise ConfigError(f"a mass cannot be negative, got {args.mass:g} kg", key="--mass")
    if args.unloaded_below < 0:
        raise ConfigError(f"must be >= 0 (N), got {args.unloaded_below:g}", key="--unloaded-below")
    load = Load(fx=args.fx, fy=args.fy, m=args.m, mass=args.mass, com=tuple(args.com), gravity_deg=args.gravity_deg)
    if not np.any(load.wrench(poses)):
        raise ConfigError("the load is zero: give --fx, --fy, --m or --mass (every clearance state is then "
                          "possible: see `pmaccuracy bounds`)", key="--fx")
    res = loaded_pose_error(robot, clearances, poses, load, threshold=args.unloaded_below)
    records = res.records()
    if args.details:
        from ..model.sources import ErrorSources

        st = res.statics
        sources = clearances if isinstance(clearances, ErrorSources) else ErrorSources.from_clearance_set(clearances)
        for k, rec in enumerate(records):
            for i, chain in enumerate(robot.chains):
                unit = "N" if chain.actuated.kind == "P" else "Nmm"
                rec[f"leg{i + 1}.actuator_{unit}"] = float(st.actuator[k, i])
                for j, joint in enumerate(chain.joints):
                    key = f"leg{i + 1}.joint{j + 1}"
                    if joint.kind == "R":
                        rec[f"{key}.force_x_N"] = float(st.force[k, i, j].real)
                        rec[f"{key}.force_y_N"] = float(st.force[k, i, j].imag)
                    else:
                        rec[f"{key}.normal_N"] = float(st.normal[k, i, j])
                        rec[f"{key}.moment_Nmm"] = float(st.moment[k, i, j])
            rec.update(contact_states(robot, sources, res.exact_configuration, k))
    if plot:
        from .._savefig import save_figure
        from ..report.load_figures import plot_load

        save_figure(plot_load(robot, clearances, poses[0], load, threshold=args.unloaded_below,
                              magnify=args.magnify), plot, dpi=args.dpi, option="--plot")
    _common.emit(records, args.format)
    return 0


def _spatial(robot) -> bool:
    from ..model.spatial import is_spatial

    return is_spatial(robot)


def _planar_com(args: argparse.Namespace) -> None:
    """A planar robot's ``--pose`` (three values) and ``--com`` (two, default the centre); no spatial options."""
    from ..errors import ConfigError
    from .kinematics_cmd import _three
    from .spatial_load_cmd import refuse_spatial_options

    if getattr(args, "pose", None):
        _three(args.pose, "--pose", "X Y PHI_DEG (mm, mm, deg)")
    refuse_spatial_options(args)
    if args.com is None:
        args.com = (0.0, 0.0)
    elif len(args.com) != 2:
        raise ConfigError(f"a planar robot's centre of mass takes two values X Y (mm), got {len(args.com)}",
                          key="--com")


def contact_states(robot, sources, config, k: int) -> dict:
    """Columns of ``load --details``: the state the load selects for every clearance of pose ``k`` at the exact
    equilibrium (:attr:`pmaccuracy.accuracy.loads.LoadedError.exact_configuration`; 0 where the leg is unloaded):
    an R joint's pin shift ``pin_dx_mm, pin_dy_mm`` and its direction ``pin_deg`` (opposite the force), a P
    block's rhombus vertex ``sigma_mm`` (shift normal to the rail) and ``tau_rad`` (tilt) and its angular tilt
    ``tilt_rad``, an actuator's backlash ``backlash_mm`` (P) or ``backlash_rad`` (R), taken up against the
    actuator's effort. ``sources``: the per-joint :class:`~pmaccuracy.model.sources.ErrorSources` of the run."""
    rec = {}
    for i, (chain, leg) in enumerate(zip(robot.chains, sources.legs)):
        for j, (joint, e) in enumerate(zip(chain.joints, leg)):
            key = f"leg{i + 1}.joint{j + 1}"
            if e.radial or e.position:
                shift = complex(config.shift[k, i, j])
                rec[f"{key}.pin_dx_mm"], rec[f"{key}.pin_dy_mm"] = shift.real, shift.imag
                rec[f"{key}.pin_deg"] = math.degrees(math.atan2(shift.imag, shift.real)) if shift else float("nan")
            if e.lateral:
                rec[f"{key}.sigma_mm"] = float(config.sigma[k, i, j])
                rec[f"{key}.tau_rad"] = float(config.tau[k, i, j])
            if e.angular:
                rec[f"{key}.tilt_rad"] = float(config.tilt[k, i, j])
            if e.actuator:
                rec[f"{key}.backlash_{'mm' if joint.kind == 'P' else 'rad'}"] = float(config.dq[k, i, j])
    return rec


def _load(args: argparse.Namespace):
    from ..accuracy.loads import Load
    from ..errors import ConfigError

    if args.mass < 0:
        raise ConfigError(f"a mass cannot be negative, got {args.mass:g} kg", key="--mass")
    if args.unloaded_below < 0:
        raise ConfigError(f"must be >= 0 (N), got {args.unloaded_below:g}", key="--unloaded-below")
    # no Load.check(): run() has warned once already (with the robot's size for the moment)
    return Load(fx=args.fx, fy=args.fy, m=args.m, mass=args.mass, com=tuple(args.com),
                gravity_deg=args.gravity_deg)


def run_map(args: argparse.Namespace, robot, clearances) -> int:
    """``load --map``: the loaded error over the workspace grid, written to ``--out``; prints the ranges."""
    from ..accuracy.loads import loaded_error_map
    from ..errors import ConfigError, EmptyWorkspaceError
    from .worst_cmd import parse_shape, shape_key

    load = _load(args)
    if not (load.fx or load.fy or load.m or load.mass):
        raise ConfigError("the load is zero: give --fx, --fy, --m or --mass (every clearance state is then "
                          "possible: see `pmaccuracy map`)", key="--fx")
    shape = parse_shape(args)
    try:
        ds = loaded_error_map(robot, clearances, load, np.radians(args.phi_deg or [0.0]), args.grid,
                              threshold=args.unloaded_below, exact=args.exact, region=shape)
    except EmptyWorkspaceError as exc:
        raise ConfigError(str(exc), key=shape_key(args)) from None
    _common.emit(write_map(ds, args.out), args.format)
    if args.plot:
        from ..report.load_figures import plot_loaded_map

        map_plots(ds, args.plot, args.dpi, plot_loaded_map)
    return 0


def map_plots(ds, plot: str, dpi: int, draw) -> None:
    """``--plot`` of a map: one figure per orientation (``FILE-<phi>deg.EXT`` when there are several)."""
    from pathlib import Path

    from .._savefig import save_figure

    plot = Path(plot)
    for phi in ds["phi"].values:
        path = plot if ds.sizes["phi"] == 1 else plot.with_name(f"{plot.stem}-{float(phi):g}deg{plot.suffix}")
        save_figure(draw(ds, float(phi)), path, dpi=dpi, option="--plot")


def run_serial(args: argparse.Namespace) -> int:
    """``load`` for a serial arm: statics and loaded end-effector error at ``--joints`` configurations."""
    from ..accuracy.loads import G0, Load
    from ..accuracy.serial_loads import loaded_serial_error
    from ..errors import ConfigError
    from ..model.plausibility import force_messages, orientation_messages, warn
    from ..model.serial import SerialArm, load_serial_sources
    from .serial_cmd import _joint_values
    from .worst_cmd import shape_key

    for option, given in (("--pose", args.pose), ("--poses-csv", args.poses_csv), ("--map", args.map),
                          ("--plot", args.plot), ("--magnify", args.magnify is not None), ("--exact", args.exact),
                          ("--out", args.out), ("--grid", args.grid), ("--phi-deg", args.phi_deg),
                          (shape_key(args), shape_key(args) != "--workspace" or args.workspace)):
        if given:
            raise ConfigError(f"{args.robot} is a serial arm: `load` takes its joint values (--joints Q1 Q2 ..., deg "
                              "for R, mm for P) and prints the loaded error there (no map or drawing for serial "
                              "arms)", key=option)
    if args.mass < 0:
        raise ConfigError(f"a mass cannot be negative, got {args.mass:g} kg", key="--mass")
    if args.unloaded_below < 0:
        raise ConfigError(f"must be >= 0 (N or N mm), got {args.unloaded_below:g}", key="--unloaded-below")
    arm = SerialArm.load(args.robot)
    q = _joint_values(arm, args.joints, allow_outside=args.allow_outside)
    sources = load_serial_sources(_common.clearances_or_default(args, arm), arm)
    warn(force_messages({"--fx": args.fx, "--fy": args.fy, "--mass (weight)": G0 * args.mass}, {"--m": args.m},
                        sum(j.length for j in arm.joints) or None))
    if args.mass:
        warn(orientation_messages([args.gravity_deg], "--gravity-deg", "directions", direction=True))
    load = Load(fx=args.fx, fy=args.fy, m=args.m, mass=args.mass, com=tuple(args.com), gravity_deg=args.gravity_deg)
    if not (load.fx or load.fy or load.m or load.mass):
        raise ConfigError("the load is zero: give --fx, --fy, --m or --mass (every clearance state is then "
                          "possible: see `pmaccuracy bounds`)", key="--fx")
    res = loaded_serial_error(arm, sources, q, load, threshold=args.unloaded_below, allow_outside=args.allow_outside)
    records = res.records()
    shown = np.array(args.joints, dtype=float)
    for i, rec in enumerate(records):
        joints = {f"q{k}_{j.unit}": float(shown[i, k - 1]) for k, j in enumerate(arm.joints, start=1)}
        records[i] = {**joints, **rec}
    if args.details:
        st = res.statics
        for i, rec in enumerate(records):
            for k, joint in enumerate(arm.joints):
                key = f"joint{k + 1}"
                rec[f"{key}.force_x_N"] = float(st.force[i, k].real)
                rec[f"{key}.force_y_N"] = float(st.force[i, k].imag)
                rec[f"{key}.moment_Nmm"] = float(st.moment[i, k])
                if joint.kind == "P":
                    rec[f"{key}.normal_N"] = float(st.normal[i, k])
                    rec[f"{key}.block_moment_Nmm"] = float(st.block_moment[i, k])
            for name, value in res.values.items():    # every source's state: its value (0: unloaded)
                v = np.asarray(value).reshape(len(records), -1)[i]
                if name.endswith(".lateral"):
                    rec[f"{name}.sigma_mm"], rec[f"{name}.tau_rad"] = float(v[0]), float(v[1])
                elif v.size == 2:
                    rec[f"{name}.dx_mm"], rec[f"{name}.dy_mm"] = float(v[0]), float(v[1])
                else:
                    rec[name] = float(v[0])
    _common.emit(records, args.format)
    return 0
