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
        return run_spatial(args, robot0)
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


def run_spatial(args: argparse.Namespace, robot) -> int:
    """``synthesize`` on a spatial robot: the largest uniform scaling of the template's sources (or per-source
    values at minimum cost, ``--mode min-cost`` / ``--cost``) meeting every ``--target`` at every point of the
    workspace grid (20 points per axis), or, with a region (``--workspace``, ``--box``, ``--cylinder``,
    ``--sphere``), at every pose of the region, certified by the global worst case."""
    from pathlib import Path

    import tomli_w

    from ..accuracy.spatial_synthesis import spatial_synthesize
    from ..errors import ConfigError, EmptyWorkspaceError, PmAccuracyError, UnsupportedArchitectureError
    from .spatial_cmd import _sources, parse_targets
    from .worst_cmd import parse_spatial_region

    if getattr(args, "phi_deg", None) not in (None, [0.0, 0.0]):
        raise PmAccuracyError("--phi-deg is a planar robot's orientation; a 6-UPS's is --orientation-deg (with a "
                              "region)")
    mode = args.mode or ("min-cost" if args.cost else "uniform")
    if args.cost and mode != "min-cost":
        raise ConfigError("a cost file needs --mode min-cost", key="--cost")
    for option in ("disc", "polygon"):
        if getattr(args, option, None) is not None:
            raise PmAccuracyError(f"--{option} applies to planar robots; a spatial robot's region is --workspace, "
                                  "--box (six numbers), --cylinder or --sphere")
    certified = any(getattr(args, k, None) for k in ("workspace", "box", "region", "cylinder", "sphere"))
    if not certified:
        for option in ("orientation_deg", "gap_pct", "max_boxes"):
            if getattr(args, option, None) is not None:
                raise ConfigError("needs a region to certify over (--workspace, --box, --cylinder or --sphere); "
                                  "without one the synthesis covers the workspace grid",
                                  key="--" + option.replace("_", "-"))
    targets = parse_targets(args.target)
    grid = 20
    out = Path(args.out) if args.out else None
    if out is not None:
        _common.prepare_output(out, "--out", (".toml",))
    kw = {}
    if certified:
        gap_pct = 1.0 if args.gap_pct is None else args.gap_pct
        _common.check_gap_pct(gap_pct)
        kw["region"] = parse_spatial_region(robot, args)
        kw["gap"] = gap_pct / 100
        if args.max_boxes is not None:
            kw["max_boxes"] = args.max_boxes
    template = _sources(args, robot)
    try:
        res = spatial_synthesize(robot, template, targets, n=grid, mode=mode, costs=args.cost, **kw)
    except (EmptyWorkspaceError, UnsupportedArchitectureError) as exc:
        if not certified:
            raise
        raise ConfigError(getattr(exc, "message", str(exc)), key=shape_key(args)) from None
    if certified and res.uncertified:
        from ..model.plausibility import warn

        warn([f"the certified worst case is not within --gap-pct {100 * kw['gap']:g} for "
              + ", ".join(f"{k} ({100 * g:.3g} %)" for k, g in res.uncertified.items())
              + ": the sources meet the targets but may be that much tighter than needed; raise --max-boxes"])
    if out is not None:
        text = tomli_w.dumps(res.sources.to_dict())
        if certified:
            text = (f"# Synthesized by pmaccuracy synthesize for {robot.name} over {res.region.describe()}, "
                    f"certified: " + ", ".join(f"{r['target']} <= {r['upper']:.6g} {r['unit']} (target "
                                              f"{r['value']:g})" for r in res.records()) + ".\n" + text)
        out.write_text(text, encoding="utf-8")
    rows = res.records()
    data = {"scale": res.scale, "binding": res.binding, "binding_point": res.binding_point.tolist(),
            "points": res.points, "targets": rows,
            "sources": [{"leg": i + 1, "joint": j + 1, "key": key, "value": value}
                        for i, leg in enumerate(res.sources.legs) for j, joint in enumerate(leg)
                        for key, value in joint.items()]}
    if mode == "min-cost":
        data = {"mode": mode, "cost": res.cost, "cuts": res.cuts, "certified": res.certified,
                "region": None if res.region is None else res.region.describe(), "binding": res.binding,
                "binding_point": res.binding_point.tolist(), "targets": rows,
                "factors": res.factors, "sources": data["sources"]}
    elif certified:
        data = {"scale": res.scale, "scale_upper": res.scale_upper, "certified": res.certified,
                "region": res.region.describe(), "binding": res.binding,
                "binding_point": res.binding_point.tolist(), "boxes": res.points, "targets": rows,
                "sources": data["sources"]}
    if args.format == "json":
        _common.emit(data, "json")
        return 0
    if mode == "min-cost":
        where = f"certified over {res.region.describe()}" if certified else \
            f"at the {res.points} points of the workspace grid (not certified between them)"
        print(f"minimum cost {res.cost:.6g} (sum of weight / factor), {where}; binding target {res.binding}; "
              f"{res.cuts} rounds of cuts")
        srcs = [{"source": label, "template": tv, "synthesized": tv * f, "factor": f}
                for (label, f), tv in zip(res.factors.items(),
                                          (v for leg in template.legs for j in leg for _, v in j.items()))]
        _common.emit(srcs, args.format)
        print()
    elif certified:
        names = ", ".join(res.region.names)
        print(f"scale {res.scale:.6g} of the template's half-widths, certified over {res.region.describe()} "
              f"(the largest scale is below {res.scale_upper:.6g}); binding target {res.binding}, attained at "
              f"({names}) = ({', '.join(f'{v:.4g}' for v in res.binding_point)})")
    else:
        print(f"scale {res.scale:.6g} of the template's half-widths; binding target {res.binding} at the grid "
              f"point {', '.join(f'{v:.4g}' for v in res.binding_point)} ({res.points} grid points of the "
              "workspace; exact at the grid points, not certified between them)")
    if certified and args.format == "table":   # worst is upper there: shown once
        rows = [{k: v for k, v in r.items() if k != "worst"} for r in rows]
    _common.emit(rows, args.format)
    return 0
