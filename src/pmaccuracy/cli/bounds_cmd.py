"""``pmaccuracy bounds``: exact maximum pose errors at given poses (Eq. 21, 22)."""

from __future__ import annotations

import argparse
import sys

import numpy as np

from ..errors import ConfigError, PmAccuracyError
from . import _common
from .spatial_cmd import POSE_HELP

#: Poses per call of the library when a progress bar is shown (a multiple of its internal block of 8192,
#: so the first pose outside the ranges or singular is still the one reported).
PROGRESS_BLOCK = 1 << 17
#: Output columns of the exact bounds (mm, mm, deg, mm, mm, deg, mm), as ``PoseErrorBounds.records``.
COLUMNS = ("x", "y", "phi_deg", "dx_max", "dy_max", "dphi_max_deg", "dp_max")


def add_clearances(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--clearances", default=None, help=_common.CLEARANCES_HELP)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "bounds", help="maximum pose errors due to joint clearances at poses (exact, Eq. 21-22)",
        description="Worst-case dx, dy (mm), dphi (deg) and |dp| (mm) that the clearances allow at each pose. "
                    "Poses: x mm, y mm, phi deg.")
    _common.add_robot(p)
    add_clearances(p)
    p.add_argument("--pose", nargs="+", type=_common.finite_float, action="append", metavar="V",
                   help=POSE_HELP)
    p.add_argument("--poses-csv", metavar="FILE", help="CSV with header x,y,phi_deg (spatial robots: their "
                   "coordinates, e.g. x,y,z,roll_deg,pitch_deg,yaw_deg for a 6-UPS)")
    p.add_argument("--joints", nargs="+", type=_common.finite_float, action="append", metavar="Q",
                   help="serial arms (architecture = \"serial\", preset planar_3r_arm) instead of --pose: the joint "
                        "values base to tip, deg for R, mm for P (repeatable)")
    p.add_argument("--tolerances", metavar="FILE",
                   help="tolerance half-widths: for the 3-PPR clearance format on link parameters (TOML with keys "
                        "like d_mm, theta_rad per leg, or preset example_tolerances; --clearances none for "
                        "tolerances alone); with a per-joint clearance file a per-joint file of position, "
                        "direction and length tolerances (presets rpr_tolerances, rrr_tolerances, "
                        "prr_tolerances), added joint by joint: worst case over both together (exact method only)")
    p.add_argument("--method", choices=("exact", "slsqp"), default="exact",
                   help="exact closed form (default) or the paper-style SLSQP baseline (slow, local)")
    p.add_argument("--certified", action="store_true",
                   help="certified upper bounds of the exact nonlinear loop closure's worst case (never below it) "
                        "with gap_pct.dx ... gap_pct.dp, the relative distance (percent) to the best feasible "
                        "configuration found; a 6-UPS: per pose and quantity first_order, lower (attained by the "
                        "exact model), upper (proven) and gap_pct")
    p.add_argument("--nonlinear", action="store_true",
                   help="the best feasible worst case of the exact nonlinear model (local ascent from the "
                        "first-order worst vertices), with the gap to the certified bound")
    p.add_argument("--max-pieces", type=_common.positive_int, metavar="N",
                   help="with --certified or --nonlinear: how many pieces of the error set the branch and bound may "
                        "certify per pose (default 256; more is tighter and slower, and may certify a pose whose "
                        "whole error set has no certificate; 1: no cutting beyond the first four pieces)")
    p.add_argument("--gap-pct", type=_common.finite_float, default=None, metavar="PCT",
                   help="with --certified: the gap to the best feasible configuration at which a bound is refined no "
                        "further (default 0.5; larger is faster and looser, e.g. 5 at large clearances)")
    p.add_argument("--allow-outside", action="store_true", help="also evaluate poses outside the joint ranges")
    p.add_argument("--details", action="store_true",
                   help="add the worst-case configuration of each quantity: the clearance displacements (3-PPR "
                        "format) or the value of every error source, leg<i>.joint<k>.<what> (per-joint files) "
                        "(exact method only)")
    p.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help="progress bar on stderr for long runs (default: when stderr is a terminal)")
    _common.add_format(p)
    p.set_defaults(func=_run_naming_poses)


def _configuration(disp) -> dict:
    return {"tau_b_rad": disp.tau_b, "sigma_g_mm": disp.sigma_g, "tau_g_rad": disp.tau_g,
            "rho_mm": disp.rho, "varphi_deg": np.degrees(disp.varphi)}


def _columns(result) -> dict[str, np.ndarray]:
    """The output columns of a :class:`~pmaccuracy.accuracy.bounds.PoseErrorBounds` (same values as its ``records``)."""
    poses = result.poses.reshape(-1, 3)
    return {"x": poses[:, 0], "y": poses[:, 1], "phi_deg": _common.degrees_as_given(poses[:, 2]),
            "dx_max": result.dx_max.reshape(-1), "dy_max": result.dy_max.reshape(-1),
            "dphi_max_deg": result.dphi_max_deg.reshape(-1), "dp_max": result.dp_max.reshape(-1)}


def _exact_columns(robot, clearances, poses: np.ndarray, tolerances, allow_outside: bool,
                   progress: bool | None) -> dict[str, np.ndarray]:
    """Exact bounds of ``poses`` ``(N, 3)`` [mm, mm, rad] as output columns; with a progress bar block by block.

    Without a bar, one library call (it builds only its four result arrays, 32 bytes a pose). With one, the
    columns are preallocated and filled per block of :data:`PROGRESS_BLOCK` poses.
    """
    from ..accuracy.bounds import max_pose_errors

    n = poses.shape[0]
    show = (sys.stderr.isatty() if progress is None else progress) and n > PROGRESS_BLOCK
    if not show:   # one call: the library builds only its four result arrays (no block's columns copied)
        return _columns(max_pose_errors(robot, clearances, poses, tolerances=tolerances,
                                        allow_outside=allow_outside))
    from tqdm import tqdm

    out = {name: np.empty(n) for name in COLUMNS}
    with tqdm(total=n, disable=not show, desc="bounds", unit="pose", unit_scale=True, file=sys.stderr) as bar:
        for start in range(0, n, PROGRESS_BLOCK):
            block = max_pose_errors(robot, clearances, poses[start:start + PROGRESS_BLOCK], tolerances=tolerances,
                                    allow_outside=allow_outside)
            for name, values in _columns(block).items():
                out[name][start:start + len(values)] = values
            bar.update(len(block.dp_max))
    return out


def _run_naming_poses(args: argparse.Namespace) -> int:
    """:func:`run`, with a pose error (outside the ranges, singular) prefixed by where the poses came from."""
    from ..errors import PoseError

    try:
        return run(args)
    except PoseError as exc:
        if not (args.pose or args.poses_csv) or str(exc).startswith(("--pose", str(args.poses_csv))):
            raise
        source = f"{args.poses_csv}" if args.poses_csv else "--pose"
        raise type(exc)(f"{source}: {exc}") from None


def run(args: argparse.Namespace) -> int:
    from ..accuracy.bounds import load_tolerances, max_pose_errors, slsqp_max_pose_errors
    from ..model.sources import ErrorSources
    from ..io.resolve import load_clearances

    from . import serial_cmd
    if serial_cmd.is_serial_robot(args.robot):  # architecture = "serial": joint values instead of poses
        return serial_cmd.run(args)
    serial_cmd.refuse_joints(args)
    robot = _common.load_robot(args)
    from ..model.spatial import is_spatial

    if is_spatial(robot):
        from . import spatial_cmd

        return spatial_cmd.run_bounds(args, robot)
    from .kinematics_cmd import _three

    _three(args.pose, "--pose", "X Y PHI_DEG (mm, mm, deg)")
    clearances = load_clearances(_common.clearances_or_default(args, robot), robot)
    poses = _common.poses_from_args(args.pose, args.poses_csv)
    per_joint = isinstance(clearances, ErrorSources)
    if per_joint:
        if args.method == "slsqp":
            raise PmAccuracyError("--method slsqp takes the 3-PPR clearance format (the paper's baseline)")
        if args.tolerances:  # a per-joint file of position / direction / length tolerances, added joint by joint
            try:
                tolerances = load_clearances(args.tolerances, robot)
            except ConfigError as exc:
                raise ConfigError(f"{exc} (with a per-joint clearance file --tolerances takes a per-joint file of "
                                  "position, direction and length tolerances, e.g. rpr_tolerances)",
                                  key="--tolerances") from None
            if not isinstance(tolerances, ErrorSources):
                raise ConfigError(f"{args.tolerances}: the 3-PPR clearance format; with a per-joint clearance file "
                                  "give per-joint tolerances (position, direction, length)", key="--tolerances")
            clearances = with_tolerances(clearances, tolerances)
        tolerances = None
    else:
        tolerances = load_tolerances(args.tolerances) if args.tolerances else None
    if args.certified or args.nonlinear:
        return _certified_run(args, robot, clearances, poses, tolerances)
    if args.max_pieces is not None:
        raise PmAccuracyError("--max-pieces needs --certified or --nonlinear")
    if args.gap_pct is not None:
        raise PmAccuracyError("--gap-pct needs --certified")
    if args.method == "slsqp":
        if args.details or tolerances:
            raise PmAccuracyError("--details and --tolerances need --method exact")
        result = slsqp_max_pose_errors(robot, clearances, poses, allow_outside=args.allow_outside)
        _columnar_output(_linear_checked(_columns(result), poses), args.format)
        return 0
    if not args.details:
        _columnar_output(_linear_checked(_exact_columns(robot, clearances, poses, tolerances, args.allow_outside,
                                                        args.progress), poses), args.format)
        return 0
    result = max_pose_errors(robot, clearances, poses, tolerances=tolerances, allow_outside=args.allow_outside,
                             details=True)
    _linear_checked(_columns(result), poses)
    if per_joint:
        _emit_details(_per_joint_details(robot, clearances, result), args.format)
        return 0
    records = result.records()
    shown = _common.degrees_as_given(poses[:, 2])
    for k, rec in enumerate(records):
        rec["phi_deg"] = float(shown[k])
        rec["worst"] = {q: _configuration(type(d)(*(np.asarray(f)[k] for f in
                                                   (d.tau_b, d.sigma_g, d.tau_g, d.rho, d.varphi))))
                        for q, d in result.worst.items()}
        if result.worst_variations:
            rec["worst_variations"] = {q: {name: np.asarray(v)[k] for name, v in var.items()}
                                       for q, var in result.worst_variations.items()}
    _emit_details(records, args.format)
    return 0


def _emit_details(records: list[dict], fmt: str) -> None:
    """``bounds --details``: JSON and CSV complete (one record or row per pose, every source a key or column);
    the table one block per pose, its bounds on one line, then one row per error source (a 3-PPR per-leg
    value one row per leg) with its value in the worst configuration of each quantity, one column each."""
    if fmt != "table":
        _common.emit(records, fmt)
        return
    for n, rec in enumerate(records):
        if n:
            sys.stdout.write("\n")
        _common.emit([{k: v for k, v in rec.items() if not isinstance(v, dict)}], "table")
        rows: dict[str, dict] = {}
        for group, prefix in (("worst", ""), ("worst_variations", "variation.")):
            for q, values in (rec.get(group) or {}).items():
                for name, value in values.items():
                    value = _common._plain(value)
                    items = ([(f"leg{i}.{name}", v) for i, v in enumerate(value, start=1)]
                             if isinstance(value, list) else [(name, value)])
                    for key, v in items:
                        rows.setdefault(prefix + key, {"source": prefix + key})[f"worst_{q}"] = v
        if rows:
            sys.stdout.write("value of each source in the worst-case configuration of each quantity:\n")
            _common.emit(list(rows.values()), "table")


def _linear_checked(columns: dict[str, np.ndarray], poses: np.ndarray) -> dict[str, np.ndarray]:
    """Warn (one line) when a dphi_max is beyond the first-order model's validity; returns ``columns``."""
    from ..model.plausibility import linearity_messages, warn

    _common.check_finite_results(columns, poses, ("dx_max", "dy_max", "dphi_max_deg", "dp_max"))
    warn(linearity_messages(columns["dphi_max_deg"], poses))
    return columns


def with_tolerances(clearances, tolerances):
    """Per-joint sources with the half-widths of a per-joint tolerance file added joint by joint (the two
    sets are independent, so their shares add; the clearance file's guide block length is kept)."""
    from dataclasses import fields, replace

    from ..model.sources import ErrorSources

    legs = tuple(tuple(replace(c, **{f.name: getattr(c, f.name) + getattr(t, f.name) for f in fields(c)
                                     if f.name != "block_length"})
                       for c, t in zip(cl, tl)) for cl, tl in zip(clearances.legs, tolerances.legs))
    return ErrorSources(legs=legs, name=f"{clearances.name} + {tolerances.name}")


#: Output keys of a per-joint worst configuration: JointDisplacements field -> (key, to output unit).
_SOURCE_KEYS = {"turn": ("turn_deg", np.degrees), "tilt": ("angular_deg", np.degrees),
                "sigma": ("lateral_shift_mm", None), "tau": ("tilt_deg", np.degrees), "dl": ("length_mm", None)}


def _per_joint_details(robot, sources, result) -> list[dict]:
    """Records of ``bounds --details`` for per-joint sources: per quantity, the value of every non-zero source
    at the maximizing configuration, keyed ``leg<i>.joint<k>.<what>`` (mm, deg; an actuated R's error in
    deg), from :func:`pmaccuracy.model.sources.worst_configuration` at the maximizing signs."""
    from ..kinematics import inverse_kinematics
    from ..model.sources import worst_configuration

    poses = result.poses.reshape(-1, 3)
    joints = inverse_kinematics(robot, poses).joints
    records = result.records()
    for q, signs in result.worst_signs.items():
        cfg = worst_configuration(robot, sources, joints, poses, signs.reshape(-1, 3))
        for k, rec in enumerate(records):
            out = {}
            for i, (chain, leg) in enumerate(zip(robot.chains, sources.legs)):
                for j, (joint, e) in enumerate(zip(chain.joints, leg)):
                    where = f"leg{i + 1}.joint{j + 1}"
                    if e.radial or e.position:
                        out[f"{where}.shift_x_mm"] = cfg.shift[k, i, j].real
                        out[f"{where}.shift_y_mm"] = cfg.shift[k, i, j].imag
                    if e.actuator:
                        value = cfg.dq[k, i, j]
                        out[f"{where}.actuator_{'deg' if joint.kind == 'R' else 'mm'}"] = \
                            np.degrees(value) if joint.kind == "R" else value
                    for field, (key, unit) in _SOURCE_KEYS.items():
                        value = getattr(cfg, field)[k, i, j]
                        if value != 0:
                            out[f"{where}.{key}"] = unit(value) if unit else value
            rec.setdefault("worst", {})[q] = out
    return records


def _columnar_output(columns: dict[str, np.ndarray], fmt: str) -> None:
    """One row per pose on stdout: CSV and table written column-wise (pyarrow for CSV), JSON as records."""
    from ..io.csvio import format_columns

    format_columns(columns, fmt, sys.stdout)


def _certified_run(args: argparse.Namespace, robot, clearances, poses: np.ndarray, tolerances) -> int:
    """``bounds --certified`` / ``--nonlinear``: the ``bounds`` keys with the certified upper bounds (or the
    nonlinear maxima) and ``gap_pct`` per quantity, in percent (:mod:`pmaccuracy.accuracy.certified`)."""
    from ..accuracy.certified import certified_pose_errors

    if args.certified and args.nonlinear:
        raise PmAccuracyError("--certified and --nonlinear exclude each other (both report the gap between them)")
    flag = "--certified" if args.certified else "--nonlinear"
    if args.method == "slsqp":
        raise PmAccuracyError(f"{flag} excludes --method slsqp")
    if args.details:
        raise PmAccuracyError(f"{flag} excludes --details (the worst configurations are in the Python API)")
    if tolerances:
        raise PmAccuracyError(f"{flag} takes per-joint sources: give tolerances per joint (position, direction, "
                              "length) with a per-joint clearance file")
    pieces = {} if args.max_pieces is None else {"max_pieces": args.max_pieces}
    if args.gap_pct is not None:
        if args.nonlinear:
            raise PmAccuracyError("--gap-pct needs --certified (--nonlinear always runs the local ascent)")
        _common.check_gap_pct(args.gap_pct)
        pieces["split_gap"] = args.gap_pct / 100
    result = certified_pose_errors(robot, clearances, poses, allow_outside=args.allow_outside,
                                   ascent=bool(args.nonlinear), **pieces)
    records = result.records("upper" if args.certified else "lower")
    for rec, shown in zip(records, _common.degrees_as_given(poses[:, 2])):
        rec["phi_deg"] = float(shown)
        rec["gap_pct"] = {q: 100 * g for q, g in rec.pop("gap").items()}   # percent, as worst prints it
    _common.emit(records, args.format)
    return 0
