"""``pmaccuracy ik`` and ``pmaccuracy fk``: inverse and forward kinematics of any architecture."""

from __future__ import annotations

import argparse

import numpy as np

from ..errors import NoSolutionError, OutsideJointLimitsError, PoseError
from ..model.spatial import is_spatial
from . import _common, spatial_cmd

IK_HELP = "inverse kinematics: actuated and passive joint values of poses (any architecture)"
FK_HELP = "forward kinematics: every assembly mode for actuator values (any architecture)"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("ik", help=IK_HELP,
                       description="Joint values of each pose on the legs' working modes: the actuated joints q "
                                   "(mm for a slide, deg for a revolute) and the passive joints in chain order "
                                   "(for a 3-PPR also s and l as in the paper, Eq. 2a/2b). Lengths in mm, phi in "
                                   "degrees.")
    _common.add_robot(p)
    p.add_argument("--pose", nargs="+", type=_common.finite_float, action="append", metavar="V",
                   help=spatial_cmd.POSE_HELP)
    p.add_argument("--poses-csv", metavar="FILE", help="CSV with header x,y,phi_deg (planar) or the spatial robot's "
                   "coordinates x,y,z,roll_deg,pitch_deg,yaw_deg (6-UPS), x,y,z (Delta, 3-UPU), z,roll_deg,pitch_deg "
                   "(3-RPS, 3-PRS)")
    _common.add_format(p)
    p.set_defaults(func=run_ik)

    p = sub.add_parser("fk", help=FK_HELP,
                       description="Every pose (assembly mode) of the platform for the actuated joint values Q1 Q2 "
                                   "Q3 (mm for a slide, deg for a revolute), whatever the working modes: at most "
                                   "two for a 3-PPR, up to six for a 3-RPR. Each mode lists its pose, whether all "
                                   "joints are within their ranges, its passive joints and each leg's working "
                                   "mode (sign of B_ii).")
    _common.add_robot(p)
    p.add_argument("--joints", nargs="+", type=_common.finite_float, required=True, metavar="Q",
                   help="actuated joint values, one per leg (three for a planar robot, six for a 6-UPS): mm for "
                        "prismatic, deg for revolute actuators")
    p.add_argument("--allow-outside", action="store_true",
                   help="accept actuator values outside their ranges")
    _common.add_format(p)
    p.set_defaults(func=run_fk)


def _three(values, option: str, names: str) -> None:
    """A planar robot's ``--pose``/``--joints`` take three values each."""
    from ..errors import PmAccuracyError

    for k, v in enumerate(values or [], start=1):
        if len(v) != 3:
            raise PmAccuracyError(f"{option} (number {k}): a planar robot takes three values {names}, got {len(v)}")


def _to_file_units(robot, values: np.ndarray, kinds) -> list[float]:
    """Joint values in mm (P) or deg (R) for output."""
    return [float(np.degrees(v)) if k == "R" else float(v) for v, k in zip(values, kinds)]


def _shown(joints, values) -> list[float]:
    """Joint values in mm (P) or deg (R) for output, a revolute's turned into ``[lo, lo + 360)`` of its range
    (:meth:`pmaccuracy.model.chain.Joint.wrap`, the convention of ``calibrate compensate``)."""
    return [float(np.degrees(j.wrap(v))) if j.kind == "R" else float(v) for j, v in zip(joints, values)]


def _passive(robot, joints: np.ndarray) -> list[list[float]]:
    out = []
    for chain, q in zip(robot.chains, joints):
        i, j = chain.passive_indices
        out.append(_shown((chain.joints[i], chain.joints[j]), q[[i, j]]))
    return out


def run_ik(args: argparse.Namespace) -> int:
    from ..model.manipulator import round_trip_degrees
    from ..kinematics import inverse_kinematics

    robot = _common.load_robot(args)
    if is_spatial(robot):
        return spatial_cmd.run_ik(args, robot)
    _three(args.pose, "--pose", "X Y PHI_DEG (mm, mm, deg)")
    poses = _common.poses_from_args(args.pose, args.poses_csv)
    ik = inverse_kinematics(robot, poses)
    out = []
    for k, (x, y, phi) in enumerate(poses):
        record = {"x": x, "y": y, "phi_deg": round_trip_degrees(phi),
                  "q": _shown([c.actuated for c in robot.chains], ik.q[k]),
                  "passive": _passive(robot, ik.joints[k])}
        if robot.is_3ppr:
            record["s"] = ik.s[k]
            record["l"] = ik.l[k]
        record["within_limits"] = ik.within_limits[k]
        out.append(record)
    _common.emit(out, args.format, records=[_table_row(r) for r in out])
    return 0


def _table_row(record: dict) -> dict:
    """The table/CSV row: q1..q3, then the passive joints as p<leg>.<1|2>, without the 3-PPR duplicates."""
    row = {k: record[k] for k in ("x", "y", "phi_deg")}
    if "s" in record:
        row.update({f"s{i + 1}": v for i, v in enumerate(record["s"])})
        row.update({f"l{i + 1}": v for i, v in enumerate(record["l"])})
    else:
        row.update({f"q{i + 1}": v for i, v in enumerate(record["q"])})
        for i, pair in enumerate(record["passive"], start=1):
            row.update({f"p{i}.{m}": v for m, v in enumerate(pair, start=1)})
    row["within_limits"] = record["within_limits"]
    if "working_modes" in record:
        row["working_modes"] = " ".join(f"{m:+d}" for m in record["working_modes"])
    return row


def run_fk(args: argparse.Namespace) -> int:
    from ..kinematics import forward_kinematics

    robot = _common.load_robot(args)
    if is_spatial(robot):
        return spatial_cmd.run_fk(args, robot)
    _three([args.joints], "--joints", "Q1 Q2 Q3 (mm or deg)")
    kinds = robot.actuated_kinds
    from ..model.plausibility import orientation_messages, warn

    warn(orientation_messages([v for v, k in zip(args.joints, kinds) if k == "R" and v], "--joints", "revolute joint values"))
    q = np.array([np.radians(v) if k == "R" else v for v, k in zip(args.joints, kinds)])
    outside = []
    for i, (v, (lo, hi), k) in enumerate(zip(q, robot.s_range, kinds)):
        inside = robot.chains[i].actuated.within(v, 0.0)
        if not inside:
            unit, conv = ("deg", np.degrees) if k == "R" else ("mm", float)
            name = f"s{i + 1}" if robot.is_3ppr else f"q{i + 1}"
            outside.append(f"{name}={args.joints[i]:g} {unit} not in [{conv(lo):g}, {conv(hi):g}]")
    if outside and not args.allow_outside:
        raise OutsideJointLimitsError("--joints: actuator values outside their ranges: " + ", ".join(outside)
                                      + " (--allow-outside to solve anyway)")
    try:
        fk = forward_kinematics(robot, q)
    except PoseError as exc:        # e.g. values beyond any length: name the option they came from
        raise PoseError(f"--joints: {exc}") from None
    if not fk.valid.any():
        raise NoSolutionError(f"no assembly mode: the legs cannot be closed with q = {args.joints}")
    out = []
    for pose, joints, ok, valid, modes in zip(fk.poses, fk.joints, fk.within_limits, fk.valid, fk.working_modes):
        if not valid:
            continue
        record = {"x": pose[0], "y": pose[1], "phi_deg": float(np.degrees(pose[2])),
                  "passive": _passive(robot, joints), "working_modes": [int(m) for m in modes]}
        if robot.is_3ppr:
            record["l"] = joints[:, 1]
        record["within_limits"] = ok
        out.append(record)
    rows = []
    for r in out:
        row = {k: r[k] for k in ("x", "y", "phi_deg")}
        if "l" in r:
            row.update({f"l{i + 1}": v for i, v in enumerate(r["l"])})
        else:
            for i, pair in enumerate(r["passive"], start=1):
                row.update({f"p{i}.{m}": v for m, v in enumerate(pair, start=1)})
        row["working_modes"] = " ".join(f"{m:+d}" for m in r["working_modes"])
        row["within_limits"] = r["within_limits"]
        rows.append(row)
    _common.emit(out, args.format, records=rows)
    return 0
