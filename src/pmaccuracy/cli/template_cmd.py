"""``pmaccuracy template ARCH``: print a commented robot file (or clearance file) to start one's own robot from."""

from __future__ import annotations

import argparse
import sys

from ..io.templates import ARCHITECTURES, SPATIAL_ARCHITECTURES, architecture_name, template_text

HELP = "print a commented template robot file (or, with --clearances, clearance file) of an architecture"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "template", help=HELP,
        description="Prints a robot file of the architecture ARCH in which every key is explained with its unit, "
                    "to be saved and edited: pmaccuracy template 3-RRR > my_3rrr.toml. With --clearances, prints "
                    "the per-joint clearance file of that architecture instead. The templates' robots reach "
                    "their home pose (0, 0, 0; for the serial arm, every joint at 0).")
    p.add_argument("arch", metavar="ARCH",
                   help=f"the architecture: {', '.join(ARCHITECTURES + SPATIAL_ARCHITECTURES)} (upper or lower case)")
    p.add_argument("--clearances", action="store_true",
                   help="print the per-joint clearance template (mm and rad) instead of the robot template")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    text = template_text(architecture_name(args.arch, "ARCH"), clearances=args.clearances)
    sys.stdout.write(text)
    return 0
