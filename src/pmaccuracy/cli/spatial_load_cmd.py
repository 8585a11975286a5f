"""``load`` and ``preload`` for spatial robots (called by those commands when the robot is spatial): forces in N,
moments in N mm about the platform reference point P, base frame; poses in the robot's controlled coordinates
(mm, deg, roll-pitch-yaw as extrinsic x-y-z); rotations of the error in deg."""

from __future__ import annotations

import argparse
import contextlib
import math

import numpy as np

from ..errors import ConfigError
from . import _common

#: Options of the planar commands that a spatial robot does not take (their spatial counterparts).
PLANAR_ONLY = {"m": "--mz (and --mx, --my)", "gravity_deg": "--gravity GX GY GZ", "phi_deg": "--orientation-deg "
               "(a 6-UPS's map or region orientation)", "plot": "the table or --format json",
               "magnify": "nothing (no drawing yet)", "exact": "nothing (first order)", "joints": "--pose"}
#: Their values when not given.
_UNSET = {"m": (0.0, (0.0, 0.0)), "gravity_deg": (-90.0,), "phi_deg": (None,), "plot": (None,), "magnify": (None,),
          "exact": (False,), "joints": (None,)}
#: The spatial-only options and their values when not given.
SPATIAL_ONLY = {"fz": (0.0, (0.0, 0.0)), "mx": (0.0, (0.0, 0.0)), "my": (0.0, (0.0, 0.0)), "mz": (0.0, (0.0, 0.0)),
                "gravity": (None,), "direction": (None,), "orientation_deg": (None,), "cylinder": (None,),
                "sphere": (None,), "springs": (False,)}
#: Default grids (points per axis) of the spatial maps and the region preload.
LOAD_MAP_GRID, PRELOAD_MAP_GRID, REGION_GRID = 10, 6, 5


def refuse_planar_options(args: argparse.Namespace, robot, *, region: bool = False) -> None:
    """One line for an option of the planar commands that has no meaning for the spatial robot (``region``: the
    command takes a region, ``--workspace``, ``--box``, ``--cylinder``, ``--sphere``)."""
    for key, instead in PLANAR_ONLY.items():
        value = getattr(args, key, None)
        if hasattr(args, key) and _given(value, _UNSET[key]):
            raise ConfigError(f"{robot.name} is a spatial robot ({robot.architecture}): this option is for planar "
                              f"robots; use {instead}", key="--" + key.replace("_", "-"))
    for key in ("disc", "polygon"):
        if getattr(args, key, None) is not None:
            raise ConfigError(f"{robot.name} is a spatial robot: its region is --box (six numbers), --cylinder, "
                              "--sphere or --workspace", key="--" + key)
    if getattr(args, "region", None) is not None and args.region.strip() != "workspace":
        raise ConfigError("a spatial robot's box is --box (six numbers)", key="--region")
    if not region and any(getattr(args, key, None) for key in ("workspace", "box", "cylinder", "sphere")):
        raise ConfigError(f"{robot.name} is a spatial robot: `{args.command}` takes poses (--pose) or --map over "
                          "the whole workspace, not a region", key="--pose")


def refuse_spatial_options(args: argparse.Namespace) -> None:
    """One line for a spatial-only option given with a planar robot."""
    for key, unset in SPATIAL_ONLY.items():
        if _given(getattr(args, key, None), unset):
            raise ConfigError("is for spatial robots (a planar load has --fx, --fy, --m)",
                              key="--" + key.replace("_", "-"))


def _given(value, unset) -> bool:
    if value is None:
        return False
    plain = tuple(value) if isinstance(value, (list, tuple)) else value
    return not any(plain == u for u in unset)


@contextlib.contextmanager
def _pose_errors():
    """The pose errors (outside the limits, singular) named after ``--pose``."""
    from ..errors import PoseError

    try:
        yield
    except PoseError as exc:
        raise type(exc)(f"--pose: {exc}") from None


def _sources(args, robot):
    from .spatial_cmd import _sources as sources

    return sources(args, robot)


def _error_columns(rec: dict, values: np.ndarray, suffix: str = "", prefix: str = "") -> None:
    from ..accuracy.spatial_bounds import COMPONENTS

    for c, name in enumerate(COMPONENTS):
        unit = "_deg" if c >= 3 else ""
        rec[f"{prefix}{name}{unit}{suffix}"] = float(values[c]) if c < 3 else math.degrees(float(values[c]))


def run_load(args: argparse.Namespace, robot) -> int:
    """``load --robot SPATIAL --pose ...``: statics, the loaded error and (``--details``) every joint's reaction."""
    from ..accuracy.spatial_loads import G0, SpatialLoad, spatial_loaded_error
    from ..model.plausibility import force_messages, warn
    from .spatial_cmd import poses

    refuse_planar_options(args, robot)
    _map_only(args)
    if args.mass < 0:
        raise ConfigError(f"a mass cannot be negative, got {args.mass:g} kg", key="--mass")
    if args.unloaded_below < 0:
        raise ConfigError(f"must be >= 0 (N), got {args.unloaded_below:g}", key="--unloaded-below")
    if len(args.com) != 3:
        raise ConfigError(f"a spatial robot's centre of mass takes three values X Y Z (mm, platform frame), got "
                          f"{len(args.com)}", key="--com")
    gravity = (0.0, 0.0, -1.0) if args.gravity is None else tuple(args.gravity)
    if not any(gravity):
        raise ConfigError("the direction of gravity must not be zero", key="--gravity")
    sources = _sources(args, robot)
    if args.map:
        if args.details:
            raise ConfigError("goes with poses (--pose), not --map", key="--details")
        grid, orientation = _map_checks(args, robot, LOAD_MAP_GRID)
    else:
        full = poses(robot, args.pose, args.poses_csv)
    warn(force_messages({"--fx/--fy/--fz": math.hypot(args.fx, args.fy, args.fz), "--mass (weight)": G0 * args.mass},
                        {"--mx/--my/--mz": math.hypot(args.mx, args.my, args.mz)}, robot.characteristic_length))
    load = SpatialLoad(force=(args.fx, args.fy, args.fz), moment=(args.mx, args.my, args.mz), mass=args.mass,
                       com=tuple(args.com), gravity=gravity)
    if load.is_zero:
        raise ConfigError("the load is zero: give --fx, --fy, --fz, --mx, --my, --mz or --mass (every clearance "
                          "state is then possible: see `pmaccuracy bounds`)", key="--fx")
    if args.map:
        from ..accuracy.spatial_loads import spatial_loaded_error_map

        ds = spatial_loaded_error_map(robot, sources, load, n=grid, orientation=orientation,
                                      threshold=args.unloaded_below)
        _common.emit(write_map(ds, args.out), args.format)
        return 0
    with _pose_errors():
        res = spatial_loaded_error(robot, sources, full, load, threshold=args.unloaded_below)
    records = res.records()
    if args.details:
        st = res.statics
        joints = st.reactions.shape[-2]
        for k, rec in enumerate(records):
            for i in range(robot.n_legs):
                for j in range(joints):
                    key = f"leg{i + 1}.joint{j + 1}"
                    f, m = st.reactions[k, i, j, :3], st.reactions[k, i, j, 3:]
                    rec.update({f"{key}.f{a}_N": float(v) for a, v in zip("xyz", f)})
                    rec.update({f"{key}.m{a}_Nmm": float(v) + 0.0 for a, v in zip("xyz", m)})
            for label, x in res.points.items():
                rec[f"{label}.point"] = [float(v) for v in np.asarray(x).reshape(len(records), -1)[k]]
    _common.emit(records, args.format)
    return 0


def run_preload(args: argparse.Namespace, robot) -> int:
    """``preload --robot SPATIAL``: at poses, the loaded error's range over the box and the smallest preload
    holding every closure row's sign; with ``--map`` both over the workspace grid; without poses, one preload for
    a region (``--workspace``, ``--box``, ``--cylinder``, ``--sphere``)."""
    from ..accuracy.spatial_loads import spatial_design_preload, spatial_wrench_set_errors
    from ..model.plausibility import force_messages, warn
    from .spatial_cmd import poses

    at_poses = bool(args.pose or args.poses_csv)
    refuse_planar_options(args, robot, region=not at_poses and not args.map)
    if getattr(args, "phi_steps", 5) != 5:
        raise ConfigError(f"{robot.name} is a spatial robot: the region's orientations are --orientation-deg "
                          "(a 6-UPS's ranges) and --grid", key="--phi-steps")
    if at_poses:
        _map_only(args)
    keys = ("fx", "fy", "fz", "mx", "my", "mz")
    lo = np.array([getattr(args, k)[0] for k in keys])
    hi = np.array([getattr(args, k)[1] for k in keys])
    for k, key in enumerate(keys):
        if lo[k] > hi[k]:
            raise ConfigError(f"needs LO <= HI, got {lo[k]:g} {hi[k]:g}", key=f"--{key}")
    if not np.any(hi - lo):
        raise ConfigError("the box of process wrenches is a single wrench: give a range LO HI", key="--fx")
    ends = np.maximum(np.abs(lo), np.abs(hi))
    warn(force_messages({"|--fx/--fy/--fz|": float(np.linalg.norm(ends[:3]))},
                        {"|--mx/--my/--mz|": float(np.linalg.norm(ends[3:]))}, robot.characteristic_length))
    center, half = (lo + hi) / 2, (hi - lo) / 2
    direction = None if args.direction is None else np.array(args.direction, dtype=float)
    if args.springs and not at_poses:
        raise ConfigError("springs are designed at poses: give --pose (or --poses-csv)", key="--springs")
    if args.map:
        return _preload_map(args, robot, center, half, direction)
    if not at_poses:
        return _region_preload(args, robot, center, half, direction)
    sources = _sources(args, robot)
    full = poses(robot, args.pose, args.poses_csv)
    if args.springs:
        return _springs(args, robot, sources, full, center, half, direction)
    rows = []
    from ..kinematics.spatial import coordinates

    with _pose_errors():
        ranges = spatial_wrench_set_errors(robot, sources, full, center, half)
    for k, pose in enumerate(full):
        with _pose_errors():
            try:
                pre = spatial_design_preload(robot, sources, pose, center, half, direction=direction)
            except ConfigError as exc:
                if exc.key != "direction":
                    raise
                raise ConfigError(exc.message, key="--direction") from None
        c = coordinates(pose, degrees=True)
        rec = {n: float(v) for n, v in zip(("x", "y", "z", "roll_deg", "pitch_deg", "yaw_deg"), c)}
        rec["not_held_without"] = ",".join(n for n, v in ranges.held.items() if not v[k]) or "-"
        _error_columns(rec, ranges.upper[k] - ranges.lower[k], suffix="_range")
        _error_columns(rec, ranges.attained_upper[k] - ranges.attained_lower[k], suffix="_attained_range")
        rec.update({f"preload_{k}_{'N' if i < 3 else 'Nmm'}": float(pre.wrench[i]) + 0.0 for i, k in enumerate(keys)})
        rec["preload_size_N"] = pre.size
        rec["pattern"] = "".join("+" if s > 0 else "-" for s in pre.pattern)
        _error_columns(rec, pre.offset, prefix="offset_")
        _error_columns(rec, pre.worst, suffix="_max")
        rec["not_held"] = ",".join(k for k, v in pre.held.items() if not v) or "-"
        rec["max_turn_deg"] = max(pre.max_angle_deg.values(), default=0.0)
        rows.append(rec)
    _common.emit(rows, args.format)
    return 0


def _map_only(args: argparse.Namespace) -> None:
    """Refuse ``--out``, ``--grid`` and ``--orientation-deg`` with poses (they go with ``--map`` or a region)."""
    if getattr(args, "map", False):
        return
    for key in ("out", "grid", "orientation_deg"):
        if getattr(args, key, None) is not None:
            raise ConfigError("goes with --map (or, for preload without poses, the preload over a region)",
                              key="--" + key.replace("_", "-"))


def _map_checks(args: argparse.Namespace, robot, default: int):
    """``(grid, orientation)`` of a spatial ``--map`` (the orientation a rotation vector, rad, or None)."""
    from ..numerics.spatial import euler_xyz_to_rotvec

    if args.pose or args.poses_csv:
        raise ConfigError("a map covers the workspace grid: give --map or poses (--pose, --poses-csv), not both",
                          key="--map")
    if not args.out:
        raise ConfigError("--map needs --out FILE.nc or FILE.csv", key="--out")
    grid = default if args.grid is None else args.grid
    if not 2 <= grid <= 200:
        raise ConfigError(f"{grid} points per axis of a 3D grid; give 2 to 200", key="--grid")
    orientation = None
    if args.orientation_deg is not None:
        if robot.mobility != "6":
            raise ConfigError(f"is for a 6-UPS; a {robot.architecture}'s map covers its whole workspace",
                              key="--orientation-deg")
        if len(args.orientation_deg) != 3:
            raise ConfigError(f"a map's orientation is roll pitch yaw (3 numbers, deg), got "
                              f"{len(args.orientation_deg)}", key="--orientation-deg")
        orientation = euler_xyz_to_rotvec(np.radians(np.array(args.orientation_deg, dtype=float)))
    _common.prepare_output(args.out, "--out", (".nc", ".csv"))
    return grid, orientation


def write_map(ds, out: str) -> list[dict]:
    """Write a spatial load map (.nc: NetCDF through scipy, rotations in rad as the spatial error maps; .csv: one
    row per grid point inside the workspace, rotations as ``*_deg``) and return each variable's range (deg)."""
    from pathlib import Path

    path = Path(out)
    if path.suffix.lower() == ".nc":
        ds.to_netcdf(path, engine="scipy")
    else:                       # degrees in a table: rad variables become *_deg
        df = ds.to_dataframe().reset_index()
        df = df[np.isfinite(df[next(iter(ds.data_vars))])]
        for name, var in ds.data_vars.items():
            if var.attrs.get("units") == "rad":
                df.insert(df.columns.get_loc(name), f"{name}_deg", np.degrees(df.pop(name)))
        df = df.rename(columns={n: f"{n}_deg" for n, c in ds.coords.items() if c.attrs.get("units") == "deg"})
        df.to_csv(path, index=False, float_format="%.17g")
    rows = []
    for name, var in ds.data_vars.items():
        unit = var.attrs.get("units", "")
        k = math.degrees(1.0) if unit == "rad" else 1.0
        lo, hi = float(var.min(skipna=True)) * k, float(var.max(skipna=True)) * k
        rows.append({"variable": f"{name}_deg" if unit == "rad" else name, "units": "deg" if unit == "rad" else unit,
                     "min": lo if math.isfinite(lo) else None, "max": hi if math.isfinite(hi) else None})
    return rows


def _preload_map(args: argparse.Namespace, robot, center, half, direction) -> int:
    """``preload --map``: the loaded error's ranges over the box and the preload each grid point needs."""
    from ..accuracy.spatial_loads import spatial_wrench_set_map

    grid, orientation = _map_checks(args, robot, PRELOAD_MAP_GRID)
    sources = _sources(args, robot)
    try:
        ds = spatial_wrench_set_map(robot, sources, center, half, n=grid, orientation=orientation,
                                    direction=direction)
    except ConfigError as exc:
        if exc.key != "direction":
            raise
        raise ConfigError(exc.message, key="--direction") from None
    _common.emit(write_map(ds, args.out), args.format)
    return 0


def _region_preload(args: argparse.Namespace, robot, center, half, direction) -> int:
    """``preload`` without poses: one preload for every sampled pose of a region."""
    from ..accuracy.spatial_loads import spatial_design_region_preload
    from ..errors import EmptyWorkspaceError
    from .worst_cmd import parse_spatial_region, shape_key

    if direction is not None:
        raise ConfigError("goes with poses (--pose) or --map; the preload over a region is a free wrench",
                          key="--direction")
    if args.out is not None:
        raise ConfigError("goes with --map", key="--out")
    grid = REGION_GRID if args.grid is None else args.grid
    if not 2 <= grid <= 50:
        raise ConfigError(f"{grid} points per axis of the region's grid; give 2 to 50", key="--grid")
    region = parse_spatial_region(robot, args)
    sources = _sources(args, robot)
    try:
        res = spatial_design_region_preload(robot, sources, region, center, half, grid=grid)
    except EmptyWorkspaceError as exc:
        raise ConfigError(str(exc), key=shape_key(args)) from None
    _common.emit([res.record()], args.format)
    return 0


def _springs(args: argparse.Namespace, robot, sources, full, center, half, direction) -> int:
    """``preload --springs``: constant-force springs alongside the legs holding every row at every pose."""
    from ..accuracy.spatial_loads import spatial_spring_preload
    from ..errors import UnsupportedArchitectureError

    if direction is not None:
        raise ConfigError("a spring acts along its leg: --direction is for a platform preload", key="--direction")
    with _pose_errors():
        try:
            sp = spatial_spring_preload(robot, sources, full, center, half)
        except UnsupportedArchitectureError as exc:
            raise ConfigError(exc.message, key="--springs") from None
        except ConfigError as exc:
            if exc.key != "half":
                raise
            raise ConfigError(exc.message, key="--springs") from None
    rec = {f"spring{i + 1}_N": float(v) + 0.0 for i, v in enumerate(sp.forces)}
    rec.update(springs_size_N=sp.size, pattern="".join("+" if s > 0 else "-" for s in sp.pattern),
               min_intensity=sp.min_intensity, poses=len(full),
               not_held=",".join(k for k, v in sp.held.items() if not v) or "-")
    for k in range(len(full)):
        _error_columns(rec, sp.offset[k], prefix=f"pose{k + 1}.offset_")
    _common.emit([rec], args.format)
    return 0
