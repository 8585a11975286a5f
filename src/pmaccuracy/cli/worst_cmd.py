"""``pmaccuracy worst``: certified global maxima of the pose errors over a region (branch and bound)."""

from __future__ import annotations

import argparse

from . import _common

HELP = "certified global worst case of dx, dy, dphi, dp over a region of poses (branch and bound)"


def add_region(p: argparse.ArgumentParser, *, phi_required: bool) -> None:
    """``--phi-deg LO HI`` and ``--region workspace|x0,x1,y0,y1`` (shared with ``synthesize``)."""
    p.add_argument("--phi-deg", nargs=2, type=_common.finite_float, metavar=("LO", "HI"),
                   required=phi_required, default=None if phi_required else [0.0, 0.0],
                   help="orientation interval in degrees, LO <= HI" + ("" if phi_required else " (default: 0 0)"))
    p.add_argument("--region", default="workspace", metavar="workspace|x0,x1,y0,y1",
                   help="'workspace' (every pose within the joint ranges) or a box in mm; poses of the box "
                        "outside the workspace are skipped; write --region=-10,10,-10,10 when x0 is negative "
                        "(default: workspace)")
    p.add_argument("--gap-pct", type=_common.finite_float, default=0.1, metavar="PCT",
                   help="certified relative gap (upper - lower) / lower in percent (default: 0.1)")


def parse_region(robot, args: argparse.Namespace):
    """The :class:`~pmaccuracy.accuracy.global_worst.Region` of ``--phi-deg`` and ``--region``; checks ``--gap-pct``."""
    import numpy as np

    from ..errors import ConfigError
    from ..accuracy.global_worst import make_region

    if not 0 < args.gap_pct < 100:
        raise ConfigError(f"must be in (0, 100) percent, got {args.gap_pct:g}", key="--gap-pct")
    box = None
    if args.region != "workspace":
        parts = args.region.split(",")
        try:
            box = tuple(float(v) for v in parts)
        except ValueError:
            box = ()
        if len(parts) != 4 or len(box) != 4:
            raise ConfigError(f"expected 'workspace' or x0,x1,y0,y1 in mm, got {args.region!r}", key="--region")
    return make_region(robot, tuple(np.radians(args.phi_deg)), box)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "worst", help=HELP,
        description="The maximum of each of dx, dy (mm), dphi (deg) and |dp| (mm) over a region of poses, with a "
                    "certificate: lower = the value at the pose shown (attained), upper = a rigorous bound over "
                    "the region (interval arithmetic on the closed forms, branch and bound), gap_pct = their "
                    "relative gap. grid_best is the best value on a GRID x GRID x NPHI grid of the region, for "
                    "comparison. A region touching a parallel singularity (unbounded errors) is refused.")
    _common.add_robot(p)
    p.add_argument("--clearances", default=None,
                   help="clearance preset or file (default: case1 for a 3-PPR, the architecture's *_typical preset "
                        "otherwise)")
    add_region(p, phi_required=True)
    p.add_argument("--grid", nargs=2, type=_common.positive_int, default=[101, 7], metavar=("GRID", "NPHI"),
                   help="comparison grid: GRID x GRID positions at NPHI orientations (default: 101 7)")
    _common.add_format(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from ..accuracy.global_worst import global_worst, grid_best
    from ..io.resolve import load_clearances
    from ..accuracy.synthesis import default_template

    _common.check_grid_memory(args.grid[1], args.grid[0], "--grid")
    robot = _common.load_robot(args)
    clearances = load_clearances(args.clearances or default_template(robot), robot)
    region = parse_region(robot, args)
    grid, grid_poses = grid_best(robot, clearances, region, *args.grid)
    res = global_worst(robot, clearances, region, gap=args.gap_pct / 100, candidates=grid_poses)
    records = []
    for i, (q, w) in enumerate(res.quantities.items()):
        f = np.degrees if q == "dphi" else float
        records.append({"quantity": q + ("_deg" if q == "dphi" else ""), "lower": f(w.lower), "upper": f(w.upper),
                        "gap_pct": 100 * w.gap, "x": w.pose[0], "y": w.pose[1], "phi_deg": np.degrees(w.pose[2]),
                        "grid_best": f(grid[i]), "certified": w.converged})
    from ..model.plausibility import linearity_messages, warn

    warn(linearity_messages([r["upper"] for r in records if r["quantity"] == "dphi_deg"],
                            what="the region's worst dphi"))
    data = {"robot": robot.name, "clearances": getattr(clearances, "name", str(args.clearances)),
            "region": region.describe(), "target_gap_pct": args.gap_pct, "boxes": res.boxes,
            "iterations": res.iterations, "seconds": res.seconds, "quantities": records}
    _common.emit(data, args.format, records=records)
    return 0
