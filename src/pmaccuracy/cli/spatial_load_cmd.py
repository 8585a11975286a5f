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
PLANAR_ONLY = {"m": "--mz (and --mx, --my)", "gravity_deg": "--gravity GX GY GZ", "map": "poses (--pose)",
               "plot": "the table or --format json", "magnify": "nothing (no drawing yet)", "exact": "nothing (first "
               "order)", "out": "poses (--pose)", "grid": "poses (--pose)", "phi_deg": "poses (--pose)",
               "joints": "--pose"}
#: Their values when not given.
_UNSET = {"m": (0.0, (0.0, 0.0)), "gravity_deg": (-90.0,), "map": (False,), "plot": (None,), "magnify": (None,),
          "exact": (False,), "out": (None,), "grid": (None,), "phi_deg": (None,), "joints": (None,)}
#: The spatial-only options and their values when not given.
SPATIAL_ONLY = {"fz": (0.0, (0.0, 0.0)), "mx": (0.0, (0.0, 0.0)), "my": (0.0, (0.0, 0.0)), "mz": (0.0, (0.0, 0.0)),
                "gravity": (None,), "direction": (None,)}


def refuse_planar_options(args: argparse.Namespace, robot) -> None:
    """One line for an option of the planar commands that has no meaning for the spatial robot."""
    for key, instead in PLANAR_ONLY.items():
        value = getattr(args, key, None)
        if hasattr(args, key) and _given(value, _UNSET[key]):
            raise ConfigError(f"{robot.name} is a spatial robot ({robot.architecture}): this option is for planar "
                              f"robots; use {instead}", key="--" + key.replace("_", "-"))
    if any(getattr(args, key, None) for key in ("workspace", "box", "disc", "polygon", "region")):
        raise ConfigError(f"{robot.name} is a spatial robot: `{args.command}` takes poses (--pose), not a region",
                          key="--pose")


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
    full = poses(robot, args.pose, args.poses_csv)
    warn(force_messages({"--fx/--fy/--fz": math.hypot(args.fx, args.fy, args.fz), "--mass (weight)": G0 * args.mass},
                        {"--mx/--my/--mz": math.hypot(args.mx, args.my, args.mz)}, robot.characteristic_length))
    load = SpatialLoad(force=(args.fx, args.fy, args.fz), moment=(args.mx, args.my, args.mz), mass=args.mass,
                       com=tuple(args.com), gravity=gravity)
    if load.is_zero:
        raise ConfigError("the load is zero: give --fx, --fy, --fz, --mx, --my, --mz or --mass (every clearance "
                          "state is then possible: see `pmaccuracy bounds`)", key="--fx")
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
    """``preload --robot SPATIAL --pose ...``: the smallest preload holding every closure row's sign over the box."""
    from ..accuracy.spatial_loads import spatial_design_preload
    from ..model.plausibility import force_messages, warn
    from .spatial_cmd import poses

    refuse_planar_options(args, robot)
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
    if not (args.pose or args.poses_csv):
        raise ConfigError("a spatial robot's preload is designed at poses: give --pose (or --poses-csv)", key="--pose")
    sources = _sources(args, robot)
    full = poses(robot, args.pose, args.poses_csv)
    center, half = (lo + hi) / 2, (hi - lo) / 2
    direction = None if args.direction is None else np.array(args.direction, dtype=float)
    rows = []
    from ..kinematics.spatial import coordinates

    for pose in full:
        with _pose_errors():
            try:
                pre = spatial_design_preload(robot, sources, pose, center, half, direction=direction)
            except ConfigError as exc:
                if exc.key != "direction":
                    raise
                raise ConfigError(exc.message, key="--direction") from None
        c = coordinates(pose, degrees=True)
        rec = {n: float(v) for n, v in zip(("x", "y", "z", "roll_deg", "pitch_deg", "yaw_deg"), c)}
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
