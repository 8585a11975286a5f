"""``pmaccuracy bounds``: exact maximum pose errors at given poses (Eq. 21, 22)."""

from __future__ import annotations

import argparse

import numpy as np

from ..bounds import load_tolerances, max_pose_errors, slsqp_max_pose_errors
from ..clearances import ClearanceSet
from ..errors import PmAccuracyError
from . import _common


def add_clearances(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--clearances", default="case1",
                        help="clearance preset (case1, case2, all) or path to a clearance TOML file "
                             "(default: case1)")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "bounds", help="maximum pose errors due to joint clearances at poses (exact, Eq. 21-22)",
        description="Worst-case dx, dy (mm), dphi (deg) and |dp| (mm) that the clearances allow at each pose. "
                    "Poses: x mm, y mm, phi deg.")
    _common.add_robot(p)
    add_clearances(p)
    p.add_argument("--pose", nargs=3, type=_common.finite_float, action="append", metavar=("X", "Y", "PHI_DEG"),
                   help="a pose: x mm, y mm, phi deg (repeatable)")
    p.add_argument("--poses-csv", metavar="FILE", help="CSV with header x,y,phi_deg")
    p.add_argument("--tolerances", metavar="FILE",
                   help="tolerance half-widths on link parameters (TOML with keys like d_mm, theta_rad per leg, "
                        "or preset example_tolerances): worst case over clearances and tolerances together; "
                        "use --clearances none for tolerances alone (exact method only)")
    p.add_argument("--method", choices=("exact", "slsqp"), default="exact",
                   help="exact closed form (default) or the paper-style SLSQP baseline (slow, local)")
    p.add_argument("--allow-outside", action="store_true", help="also evaluate poses outside the joint ranges")
    p.add_argument("--details", action="store_true",
                   help="add the worst-case clearance configurations (exact method only)")
    _common.add_format(p)
    p.set_defaults(func=run)


def _configuration(disp) -> dict:
    return {"tau_b_rad": disp.tau_b, "sigma_g_mm": disp.sigma_g, "tau_g_rad": disp.tau_g,
            "rho_mm": disp.rho, "varphi_deg": np.degrees(disp.varphi)}


def run(args: argparse.Namespace) -> int:
    robot = _common.load_robot(args)
    clearances = ClearanceSet.load(args.clearances)
    poses = _common.poses_from_args(args.pose, args.poses_csv)
    tolerances = load_tolerances(args.tolerances) if args.tolerances else None
    if args.method == "slsqp":
        if args.details or tolerances:
            raise PmAccuracyError("--details and --tolerances need --method exact")
        result = slsqp_max_pose_errors(robot, clearances, poses, allow_outside=args.allow_outside)
    else:
        result = max_pose_errors(robot, clearances, poses, tolerances=tolerances, allow_outside=args.allow_outside,
                                 details=args.details)
    records = result.records()
    if args.details:
        for k, rec in enumerate(records):
            rec["worst"] = {q: _configuration(type(d)(*(np.asarray(f)[k] for f in
                                                       (d.tau_b, d.sigma_g, d.tau_g, d.rho, d.varphi))))
                            for q, d in result.worst.items()}
            if result.worst_variations:
                rec["worst_variations"] = {q: {name: np.asarray(v)[k] for name, v in var.items()}
                                           for q, var in result.worst_variations.items()}
    _common.emit(records, args.format)
    return 0
