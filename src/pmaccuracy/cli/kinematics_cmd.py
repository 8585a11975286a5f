"""``pmaccuracy ik`` and ``pmaccuracy fk``: inverse and forward kinematics (Eq. 1-2)."""

from __future__ import annotations

import argparse

import numpy as np

from ..errors import NoSolutionError, OutsideJointLimitsError
from ..kinematics import forward_kinematics, inverse_kinematics
from . import _common


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("ik", help="inverse kinematics: joint values s, l of poses (Eq. 2a, 2b)",
                       description="Joint values of each pose. Lengths in mm, phi in degrees.")
    _common.add_robot(p)
    p.add_argument("--pose", nargs=3, type=_common.finite_float, action="append", metavar=("X", "Y", "PHI_DEG"),
                   help="a pose: x mm, y mm, phi deg (repeatable)")
    p.add_argument("--poses-csv", metavar="FILE", help="CSV with header x,y,phi_deg")
    _common.add_format(p)
    p.set_defaults(func=run_ik)

    p = sub.add_parser("fk", help="forward kinematics: every assembly mode for actuator values (analytic)",
                       description="Every pose (at most two assembly modes) for the actuated joint values s1 s2 s3 "
                                   "in mm.")
    _common.add_robot(p)
    p.add_argument("--joints", nargs=3, type=_common.finite_float, required=True, metavar=("S1", "S2", "S3"),
                   help="actuated joint values in mm")
    p.add_argument("--allow-outside", action="store_true",
                   help="accept actuator values outside their ranges (s_range of the robot)")
    _common.add_format(p)
    p.set_defaults(func=run_fk)


def run_ik(args: argparse.Namespace) -> int:
    robot = _common.load_robot(args)
    poses = _common.poses_from_args(args.pose, args.poses_csv)
    ik = inverse_kinematics(robot, poses)
    out = [{"x": x, "y": y, "phi_deg": np.degrees(phi), "s": s, "l": l, "within_limits": ok}
           for (x, y, phi), s, l, ok in zip(poses, ik.s, ik.l, ik.within_limits)]
    _common.emit(out, args.format)
    return 0


def run_fk(args: argparse.Namespace) -> int:
    robot = _common.load_robot(args)
    s = np.array(args.joints)
    outside = [f"s{i + 1}={v:g} mm not in [{lo:g}, {hi:g}]" for i, (v, (lo, hi)) in enumerate(zip(s, robot.s_range))
               if not lo <= v <= hi]
    if outside and not args.allow_outside:
        raise OutsideJointLimitsError("actuator values outside their ranges: " + ", ".join(outside)
                                      + " (--allow-outside to solve anyway)")
    fk = forward_kinematics(robot, s)
    if not fk.valid.any():
        raise NoSolutionError(f"no assembly mode: the legs cannot be closed with s = {args.joints} mm")
    out = [{"x": pose[0], "y": pose[1], "phi_deg": np.degrees(pose[2]), "l": l, "within_limits": ok}
           for pose, l, ok, valid in zip(fk.poses, fk.l, fk.within_limits, fk.valid) if valid]
    _common.emit(out, args.format)
    return 0
