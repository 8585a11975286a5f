"""``pmaccuracy import FILE`` and ``pmaccuracy export ROBOT --to FILE``: robots from and to MJCF, URDF and SDF files."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..io import robot_formats
from ..io.resolve import robot_arg
from ..model.spatial import is_spatial
from . import _common

IMPORT_HELP = "read a parallel robot from an MJCF, URDF or SDF file (loops closed by constraints) into a robot TOML"
EXPORT_HELP = "write a robot as an MJCF, URDF or SDF file, or its geometry into the file it came from (--like)"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "import", help=IMPORT_HELP,
        description="Reads FILE (MJCF .xml read by MuJoCo, loops closed by <equality><connect>; URDF .urdf read "
                    "by yourdfpy, loops closed by URDF+ <loop> elements; SDFormat .sdf, read as XML, loops closed "
                    "by the joints beyond a spanning tree, actuated joints those of joint-controller plugins), "
                    "recognises its legs and their actuated joints, converts metres to mm and radians to degrees, "
                    "prints the robot and, with --out, writes it as a robot TOML that every command reads. A joint "
                    "or loop that makes no leg of a known architecture is named in one line (exit 2).")
    p.add_argument("file", metavar="FILE",
                   help="the robot file: .xml / .mjcf (MJCF), .urdf (URDF) or .sdf (SDFormat)")
    p.add_argument("--out", metavar="ROBOT.toml", help="write the robot TOML; missing parent folders are created")
    p.add_argument("--format", choices=("table", "json"), default="table",
                   help="output format on stdout (default: table)")
    p.set_defaults(func=run_import)
    p = sub.add_parser(
        "export", help=EXPORT_HELP,
        description="Writes ROBOT (a preset name, a robot TOML, or an MJCF/URDF/SDF file) as a fresh MJCF (.xml), "
                    "URDF (.urdf) or SDFormat (.sdf) file at --to (a planar robot: MJCF only); with --like "
                    "ORIGINAL (the file the robot was imported from), writes a copy of ORIGINAL in which only the "
                    "geometry changes (body and joint positions, axes, the reference configuration and the "
                    "actuated ranges), so that simulation and control use the calibrated model.")
    p.add_argument("robot", metavar="ROBOT", help="preset name, robot TOML, or MJCF/URDF/SDF file")
    p.add_argument("--to", required=True, metavar="FILE",
                   help="the file to write: .xml (MJCF), .urdf (URDF) or .sdf (SDFormat)")
    p.add_argument("--like", metavar="ORIGINAL",
                   help="the robot's original MJCF, URDF or SDF file: keep everything but the geometry")
    p.set_defaults(func=run_export)


def run_import(args: argparse.Namespace) -> int:
    if args.out:
        _common.prepare_output(args.out, "--out", (".toml",))
    robot = robot_arg(args.file)
    if args.out:
        robot.to_toml(args.out)
    if args.format == "json":
        sys.stdout.write(json.dumps(robot.to_dict(), indent=2) + "\n")
        return 0
    if not is_spatial(robot):
        lines = [f"robot: {robot.name} (planar, legs {', '.join(c.pattern for c in robot.chains)}) from {args.file}"]
        for i, chain in enumerate(robot.chains, start=1):
            lo, hi = chain.actuated.range
            unit = "deg" if chain.actuated.kind == "R" else "mm"
            if unit == "deg":
                lo, hi = np.degrees([lo, hi])
            base, plat = complex(chain.base_z), complex(chain.platform_z)
            lines.append(f"leg {i}: {chain.pattern}, base [{base.real:.6g}, {base.imag:.6g}] mm, platform "
                         f"[{plat.real:.6g}, {plat.imag:.6g}] mm, actuated joint {chain.actuated_index + 1} "
                         f"range [{lo:.6g}, {hi:.6g}] {unit}")
        if args.out:
            lines.append(f"written: {args.out}")
        sys.stdout.write("\n".join(lines) + "\n")
        return 0
    home = robot.home_pose
    lines = [f"robot: {robot.name} ({robot.label}, {robot.n_legs} legs) from {args.file}",
             f"home: position {np.round(home[:3], 6).tolist()} mm" if home is not None else "home: none"]
    for i, leg in enumerate(robot.legs, start=1):
        lo, hi = leg.stroke
        unit = "deg" if leg.ACTUATOR == "R" else "mm"
        if leg.ACTUATOR == "R":
            lo, hi = np.degrees([lo, hi])
        lines.append(f"leg {i}: base {np.round(leg.base, 6).tolist()} mm, platform "
                     f"{np.round(leg.platform, 6).tolist()} mm, actuated range [{lo:.6g}, {hi:.6g}] {unit}")
    if args.out:
        lines.append(f"written: {args.out}")
    sys.stdout.write("\n".join(lines) + "\n")
    return 0


def run_export(args: argparse.Namespace) -> int:
    kinds = (".xml", ".mjcf", ".urdf", ".sdf")
    if args.like:   # into the original: the same format
        like = Path(args.like).suffix.lower()
        kinds = (like,) if like in (".urdf", ".sdf") else (".xml", ".mjcf")
    _common.prepare_output(args.to, "--to", kinds)
    robot = robot_arg(args.robot)
    if not is_spatial(robot) and (args.like or Path(args.to).suffix.lower() in (".urdf", ".sdf")):
        raise ConfigError(f"{robot.name} is a planar robot: it is written as a fresh MJCF file (.xml) only so far",
                          key="ROBOT")
    if args.like:
        robot_formats.export_into(robot, args.like, args.to)
    elif Path(args.to).suffix.lower() == ".urdf":
        robot_formats.write_urdf(robot, args.to)
    elif Path(args.to).suffix.lower() == ".sdf":
        robot_formats.write_sdf(robot, args.to)
    else:
        robot_formats.write_mjcf(robot, args.to)
    sys.stdout.write(f"written: {args.to}\n")
    return 0
