"""``pmaccuracy synthesize``: the largest clearances / tolerances per joint meeting worst-case targets."""

from __future__ import annotations

import argparse

from . import _common
from .worst_cmd import add_region, add_spatial_region, parse_region, shape_key

HELP = "tolerance synthesis: largest clearances per joint meeting worst-case targets everywhere in a region"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "synthesize", help=HELP,
        description="Scales the template's non-zero clearances / tolerances (uniformly, or per joint at minimum "
                    "cost sum b_j eps0_j / eps_j with --cost) to the largest values whose certified worst cases "
                    "over the region meet every --target (dx, dy, dp in mm, dphi_deg in deg). Prints each source's "
                    "template and synthesized value (mm or rad) and the certified worst cases; --out writes the "
                    "per-joint clearance file that bounds and map read. --format csv prints the sources' table only. "
                    "A spatial robot (targets dx, dy, dz, dp mm; drx_deg, dry_deg, drz_deg, dtheta_deg deg): the "
                    "uniform scaling exact at the points of its workspace grid, or, with a region (--workspace, "
                    "--box with six numbers, --cylinder, --sphere, at --orientation-deg), certified over the "
                    "region by its certified worst case (architectures with a certified upper bound only).")
    _common.add_robot(p)
    p.add_argument("--clearances", default=None, metavar="TEMPLATE",
                   help="template clearance preset or file: its non-zero keys are the unknowns (default: case1 "
                        "for a 3-PPR, the architecture's *_typical preset otherwise, printed on stderr)")
    p.add_argument("--target", action="append", required=True, metavar="NAME=VALUE",
                   help="a target, repeatable: dx=MM, dy=MM, dp=MM, dphi_deg=DEG")
    add_region(p, phi_required=False)
    add_spatial_region(p)
    p.set_defaults(gap_pct=None)   # 0.1 % for a planar robot, 1 % for a spatial one
    p.add_argument("--cost", metavar="FILE",
                   help="per-joint cost weights b_j (TOML laid out like a per-joint clearance file, "
                        "[[legs]] joints = [{key = weight}]); implies --mode min-cost")
    p.add_argument("--mode", choices=("uniform", "min-cost"), default=None,
                   help="uniform scaling of the template or per-joint minimum cost (default: uniform, min-cost "
                        "with --cost)")
    p.add_argument("--out", metavar="FILE.toml", help="write the synthesized clearance file; missing parent folders are created")
    _common.add_format(p)
    p.set_defaults(func=run)


def _unit(robot, source) -> str:
    """The unit of a synthesized source's value: mm or rad (an actuator's by its joint type)."""
    from ..model.sources import UNITS

    if source.key == "actuator":
        return "mm" if robot.chains[source.leg].joints[source.joint].kind == "P" else "rad"
    return UNITS[source.key]


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    import numpy as np

    from ..errors import ConfigError
    from ..accuracy.synthesis import clearance_toml, parse_targets, synthesize

    from ..model.spatial import is_spatial

    robot0 = _common.load_robot(args)
    if is_spatial(robot0):
        from . import spatial_cmd

        return spatial_cmd.run_synthesize(args, robot0)
    for option in ("cylinder", "sphere", "orientation_deg", "max_boxes"):
        if getattr(args, option) is not None:
            raise ConfigError(f"is for spatial robots; {robot0.name} is planar", key="--" + option.replace("_", "-"))
    if args.gap_pct is None:
        args.gap_pct = 0.1
    targets = parse_targets(args.target)
    mode = args.mode or ("min-cost" if args.cost else "uniform")
    if args.cost and mode != "min-cost":
        raise ConfigError("a cost file needs --mode min-cost", key="--cost")
    out = Path(args.out) if args.out else None
    if out is not None:
        _common.prepare_output(out, "--out", (".toml",))
    robot = robot0
    _common.clearances_or_default(args, robot)
    region = parse_region(robot, args)
    from ..errors import EmptyWorkspaceError

    try:
        res = synthesize(robot, region, targets, clearances=args.clearances, costs=args.cost, mode=mode,
                         gap=args.gap_pct / 100)
    except EmptyWorkspaceError as exc:
        raise ConfigError(str(exc), key=shape_key(args)) from None
    if out is not None:
        out.write_text(clearance_toml(res, robot, region), encoding="utf-8")
    sources = [{"source": s.label, "unit": _unit(robot, s), "template": float(t), "synthesized": float(v),
                "ratio": float(v / t)} for s, t, v in zip(res.sources, res.template_values, res.values)]
    worst = []
    for q, w in res.worst.quantities.items():
        f = np.degrees if q == "dphi" else float
        target = targets.get(q)
        shown = None if target is None else f(target)
        if args.format == "table":   # only the targets given, no "nan"
            shown = "-" if target is None else f"{shown:g}"
        worst.append({"quantity": q + ("_deg" if q == "dphi" else ""), "unit": "deg" if q == "dphi" else "mm",
                      "target": shown, "lower": f(w.lower), "upper": f(w.upper), "gap_pct": 100 * w.gap,
                      "x": w.pose[0], "y": w.pose[1], "phi_deg": np.degrees(w.pose[2]), "certified": w.converged})
    if args.format == "json":
        _common.emit({"robot": robot.name, "mode": mode, "scale": res.scale, "cost": res.cost, "cuts": res.cuts,
                      "region": region.describe(), "sources": sources, "worst": worst}, "json")
    elif args.format == "csv":   # one CSV table: the synthesized values
        _common.emit(sources, "csv")
    else:
        _common.emit(sources, "table")
        print()
        _common.emit(worst, "table")
    return 0
