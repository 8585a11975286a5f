"""``pmaccuracy worst``: certified global maxima of the pose errors over a region (branch and bound)."""

from __future__ import annotations

import argparse

from . import _common

HELP = "certified global worst case of dx, dy, dphi, dp over a region of poses (branch and bound)"


def add_region(p: argparse.ArgumentParser, *, phi_required: bool) -> None:
    """``--phi-deg LO HI`` and ``--region workspace|x0,x1,y0,y1`` (shared with ``synthesize``)."""
    p.add_argument("--phi-deg", nargs=2, type=_common.angle_deg, metavar=("LO", "HI"),
                   required=phi_required, default=None if phi_required else [0.0, 0.0],
                   help="orientation interval in degrees, LO <= HI" + ("" if phi_required else " (default: 0 0)"))
    add_shape(p)
    p.add_argument("--gap-pct", type=_common.finite_float, default=0.1, metavar="PCT",
                   help="certified relative gap (upper - lower) / lower in percent (default: 0.1)")


def add_shape(p: argparse.ArgumentParser) -> None:
    """The region's positions, one of ``--workspace`` (default), ``--box``, ``--disc``, ``--polygon`` and
    the older ``--region`` (shared with ``synthesize``, ``statistics`` and ``map``)."""
    g = p.add_mutually_exclusive_group()
    g.add_argument("--workspace", action="store_true",
                   help="every position within the joint ranges at the orientations (the default)")
    g.add_argument("--box", nargs="+", metavar="x0,x1,y0,y1",
                   help="a box in mm; write --box=-10,10,-10,10 when x0 is negative (or the numbers apart: --box "
                        "-10 10 -10 10); a spatial robot (worst): x0 x1 y0 y1 z0 z1 mm, a 3-RPS/3-PRS z0 z1 mm "
                        "roll0 roll1 pitch0 pitch1 deg")
    g.add_argument("--disc", nargs=3, type=_common.finite_float, metavar=("X", "Y", "R"),
                   help="the disc of centre X, Y and radius R > 0 (mm)")
    g.add_argument("--polygon", metavar="FILE|x1,y1,x2,y2,...",
                   help="a simple polygon (mm): a .csv file with columns x,y, a .toml file with vertices = "
                        "[[x, y], ...], or the vertices inline (write --polygon=-10,0,... when x1 is negative)")
    g.add_argument("--region", default=None, metavar="workspace|x0,x1,y0,y1",
                   help="'workspace' or a box in mm (as --workspace / --box)")
    p.epilog = ((p.epilog or "") + " Poses of the region outside the workspace are skipped.").strip()


def parse_shape(args: argparse.Namespace):
    """The shape of ``--box / --disc / --polygon / --region`` (None for the workspace)."""
    from pathlib import Path

    from ..errors import ConfigError
    from ..accuracy.regions import Disc, Polygon, Rect, load_polygon, parse_vertices

    if args.disc is not None:
        return Disc((args.disc[0], args.disc[1]), args.disc[2])
    if args.polygon is not None:
        text = args.polygon.strip()
        if Path(text).suffix.lower() in (".csv", ".toml") or Path(text).is_file():
            return load_polygon(text)
        return Polygon(parse_vertices(text))
    key, text = ("--box", box_text(args.box)) if args.box is not None else ("--region", args.region)
    if text is None or text.strip() == "workspace":
        return None
    parts = text.split(",")
    try:
        box = tuple(float(v) for v in parts)
    except ValueError:
        box = ()
    if len(parts) != 4 or len(box) != 4:
        raise ConfigError(f"expected x0,x1,y0,y1 in mm, got {text!r}", key=key)
    try:
        return Rect((box[0], box[1]), (box[2], box[3]))
    except ConfigError as exc:
        raise ConfigError(exc.message, key=key) from None


def box_text(box) -> str:
    """``--box``'s values as one comma-separated text (given as one ``x0,x1,...`` or as separate numbers)."""
    return ",".join(box) if isinstance(box, (list, tuple)) else box


def shape_key(args: argparse.Namespace) -> str:
    """The option that gave the region (for error messages)."""
    for key in ("disc", "polygon", "box", "region", "cylinder", "sphere"):
        if getattr(args, key, None) is not None:
            return "--" + key
    return "--workspace"


def parse_region(robot, args: argparse.Namespace):
    """The :class:`~pmaccuracy.accuracy.global_worst.Region` of ``--phi-deg`` and the shape options; checks
    ``--gap-pct``."""
    from ..accuracy.global_worst import make_region

    _common.check_gap_pct(args.gap_pct)
    return cli_region(make_region, robot, args.phi_deg, parse_shape(args), args)


def cli_region(make_region, robot, phi_deg, shape, args: argparse.Namespace):
    """``make_region`` of the options: its errors name the options (``--phi-deg``, the shape's), not the
    library's arguments (``phi``, ``box``)."""
    import numpy as np

    from ..errors import ConfigError

    try:
        return make_region(robot, tuple(np.radians(phi_deg)), shape)
    except ConfigError as exc:
        option = {"phi": "--phi-deg", "box": shape_key(args)}.get(exc.key)
        if option is None:
            raise
        raise ConfigError(exc.message, source=exc.source, key=option) from None


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "worst", help=HELP,
        description="The maximum of each of dx, dy (mm), dphi (deg) and |dp| (mm) over a region of poses, with a "
                    "certificate: lower = the value at the pose shown (attained), upper = a rigorous bound over "
                    "the region (interval arithmetic on the closed forms, branch and bound), gap_pct = their "
                    "relative gap. grid_best is the best value on a GRID x GRID x NPHI grid of the region, for "
                    "comparison. A region touching a parallel singularity (unbounded errors) is refused.")
    _common.add_robot(p)
    p.add_argument("--clearances", default=None, help=_common.CLEARANCES_HELP)
    add_region(p, phi_required=False)
    p.set_defaults(phi_deg=None)
    add_spatial_region(p)
    p.add_argument("--certified", action="store_true",
                   help="the worst case of the exact (nonlinear) loop closure instead of the first-order model: "
                        "lower = a configuration of the error set attains it, upper = a rigorous bound at every "
                        "pose of the region (default --gap-pct 1 with it)")
    p.add_argument("--grid", nargs=2, type=_common.positive_int, default=[101, 7], metavar=("GRID", "NPHI"),
                   help="comparison grid (first-order model): GRID x GRID positions at NPHI orientations "
                        "(default: 101 7)")
    p.set_defaults(gap_pct=None)
    p.add_argument("--largest-disc", nargs=2, type=_common.finite_float, metavar=("X", "Y"),
                   help="instead: the largest disc around X, Y (mm) where every --target holds (bisection on "
                        "the radius with the certified worst case over the disc at the --phi-deg interval)")
    p.add_argument("--target", action="append", metavar="NAME=VALUE",
                   help="with --largest-disc, repeatable: dx=MM, dy=MM, dp=MM, dphi_deg=DEG")
    p.add_argument("--tol-mm", type=_common.finite_float, default=0.1, metavar="MM",
                   help="with --largest-disc: width of the certified radius interval (default: 0.1)")
    _common.add_format(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from ..accuracy.global_worst import global_worst, grid_best
    from ..io.resolve import load_clearances
    from ..errors import ConfigError, EmptyWorkspaceError

    robot = _common.load_robot(args)
    from ..model.spatial import is_spatial

    if is_spatial(robot):
        return run_spatial(args, robot)
    for option in ("cylinder", "sphere", "orientation_deg", "max_boxes"):
        if getattr(args, option) is not None:
            raise ConfigError(f"is for spatial robots; {robot.name} is planar", key="--" + option.replace("_", "-"))
    if args.phi_deg is None:
        raise ConfigError("the following arguments are required: --phi-deg")
    if args.gap_pct is None:
        args.gap_pct = 1.0 if args.certified else 0.1
    if args.largest_disc is not None:
        if args.certified:
            raise ConfigError("--largest-disc certifies the first-order model only", key="--certified")
        return run_largest_disc(args)
    if args.target:
        raise ConfigError("targets need --largest-disc X Y (or use the synthesize command)", key="--target")
    _common.check_grid_memory(args.grid[1], args.grid[0], "--grid")
    clearances = load_clearances(_common.clearances_or_default(args, robot), robot)
    region = parse_region(robot, args)
    try:
        grid, grid_poses = grid_best(robot, clearances, region, *args.grid)
        res = global_worst(robot, clearances, region, gap=args.gap_pct / 100, candidates=grid_poses,
                           exact=args.certified)
    except EmptyWorkspaceError as exc:
        raise ConfigError(str(exc), key=shape_key(args)) from None
    records = []
    for i, (q, w) in enumerate(res.quantities.items()):
        f = np.degrees if q == "dphi" else float
        records.append({"quantity": q + ("_deg" if q == "dphi" else ""), "lower": f(w.lower), "upper": f(w.upper),
                        "gap_pct": 100 * w.gap, "x": w.pose[0], "y": w.pose[1], "phi_deg": np.degrees(w.pose[2]),
                        "grid_best": f(grid[i]), "certified": w.converged})
    from ..model.plausibility import linearity_messages, warn

    warn(linearity_messages([r["upper"] for r in records if r["quantity"] == "dphi_deg"],
                            what="the region's worst dphi"))
    if args.certified and not all(r["certified"] for r in records):
        worst_gap = max(r["gap_pct"] for r in records)
        warn([f"the exact worst case is not certified within --gap-pct {args.gap_pct:g} (budget spent): the "
              f"bounds hold, {worst_gap:.3g} % apart"])
    data = {"robot": robot.name, "clearances": getattr(clearances, "name", str(args.clearances)),
            "model": "exact" if args.certified else "first-order",
            "region": region.describe(), "target_gap_pct": args.gap_pct, "boxes": res.boxes,
            "iterations": res.iterations, "seconds": res.seconds, "quantities": records}
    if args.certified and args.format == "table":
        print(f"exact loop closure over {region.describe()}: lower attained by a configuration of the error set, "
              "upper a rigorous bound at every pose")
    _common.emit(data, args.format, records=records)
    return 0


def run_largest_disc(args: argparse.Namespace) -> int:
    """``--largest-disc X Y --target ...``: the certified radius interval."""
    import numpy as np

    from ..errors import ConfigError
    from ..accuracy.global_worst import largest_disc
    from ..accuracy.synthesis import parse_targets
    from ..io.resolve import load_clearances

    if shape_key(args) != "--workspace":
        raise ConfigError(f"--largest-disc takes no other region ({shape_key(args)})", key="--largest-disc")
    if not args.target:
        raise ConfigError("give at least one --target NAME=VALUE", key="--largest-disc")
    if not args.tol_mm > 0:
        raise ConfigError(f"must be > 0 mm, got {args.tol_mm:g}", key="--tol-mm")
    _common.check_gap_pct(args.gap_pct)
    targets = parse_targets(args.target)
    robot = _common.load_robot(args)
    clearances = load_clearances(_common.clearances_or_default(args, robot), robot)
    res = largest_disc(robot, clearances, tuple(args.largest_disc), tuple(np.radians(args.phi_deg)), targets,
                       tol=args.tol_mm, gap=args.gap_pct / 100)
    records = []
    for label, w in (("holds", res.holds), ("fails", res.fails)):
        if w is None:
            continue
        for q in targets:
            f = np.degrees if q == "dphi" else float
            qw = w.quantities[q]
            records.append({"disc": label, "radius_mm": res.radius_lower if label == "holds" else res.radius_upper,
                            "quantity": q + ("_deg" if q == "dphi" else ""), "target": f(targets[q]),
                            "lower": f(qw.lower), "upper": f(qw.upper), "x": qw.pose[0], "y": qw.pose[1],
                            "phi_deg": np.degrees(qw.pose[2])})
    data = {"robot": robot.name, "clearances": getattr(clearances, "name", str(args.clearances)),
            "centre_mm": list(res.centre), "phi_deg": [float(np.degrees(v)) for v in res.phi],
            "radius_lower_mm": res.radius_lower,
            "radius_upper_mm": None if not np.isfinite(res.radius_upper) else res.radius_upper,
            "singular_above": res.singular_above, "evaluations": res.evaluations, "discs": records}
    if args.format == "table":
        upper = ("the whole reachable part" if not np.isfinite(res.radius_upper)
                 else f"{res.radius_upper:.6g} mm" + (" (reaches a singularity)" if res.singular_above else ""))
        print(f"largest disc around ({res.centre[0]:g}, {res.centre[1]:g}) mm: every target holds up to radius "
              f"{res.radius_lower:.6g} mm (certified) and fails at {upper}")
        _common.emit(records, "table")
    else:
        _common.emit(data, args.format, records=records)
    return 0


def add_spatial_region(p: argparse.ArgumentParser) -> None:
    """The spatial robots' region options besides ``--box`` and ``--workspace``: ``--cylinder``, ``--sphere``,
    ``--orientation-deg`` and the branch and bound's ``--max-boxes`` (shared by ``worst`` and ``synthesize``)."""
    p.add_argument("--cylinder", nargs=5, type=_common.finite_float, metavar=("X", "Y", "R", "Z0", "Z1"),
                   help="spatial robots: the cylinder of axis (X, Y), radius R and heights Z0..Z1 (mm)")
    p.add_argument("--sphere", nargs=4, type=_common.finite_float, metavar=("X", "Y", "Z", "R"),
                   help="spatial robots: the sphere of centre X, Y, Z and radius R (mm)")
    p.add_argument("--orientation-deg", nargs="+", type=_common.angle_deg, metavar="DEG",
                   help="a 6-UPS: roll pitch yaw (deg, extrinsic x-y-z) fixed, or six numbers R0 R1 P0 P1 Y0 Y1 "
                        "for ranges (default: its home orientation)")
    p.add_argument("--max-boxes", type=_common.positive_int, default=None, metavar="N",
                   help="spatial robots: budget of boxes of the branch and bound (default: 400000)")


def parse_spatial_region(robot, args: argparse.Namespace):
    """The :class:`~pmaccuracy.accuracy.spatial_worst.SpatialRegion` of ``--box`` (six numbers),
    ``--cylinder``, ``--sphere`` or the workspace, at ``--orientation-deg``; errors name the option."""
    import numpy as np

    from ..accuracy.spatial_worst import spatial_region
    from ..errors import ConfigError

    if args.region is not None and args.region.strip() != "workspace":
        raise ConfigError("a spatial robot's box is --box (six numbers)", key="--region")
    kw = {}
    if args.box is not None:
        text = box_text(args.box)
        try:
            box = [float(v) for v in text.split(",")]
        except ValueError:
            box = []
        if len(box) != 6 or not np.all(np.isfinite(box)):
            what = "z0 z1 mm, roll0 roll1 deg, pitch0 pitch1 deg" if robot.mobility == "2R1T" else \
                "x0 x1 y0 y1 z0 z1 mm"
            raise ConfigError(f"expected six numbers ({what}), got {text!r}", key="--box")
        if robot.mobility == "2R1T":
            box[2:] = np.radians(box[2:]).tolist()
        kw["box"] = box
    elif args.cylinder is not None:
        kw["cylinder"] = args.cylinder
    elif args.sphere is not None:
        kw["sphere"] = args.sphere
    if args.orientation_deg is not None:
        o = np.radians(args.orientation_deg)
        if o.size not in (3, 6):
            raise ConfigError(f"give roll pitch yaw (3 numbers) or R0 R1 P0 P1 Y0 Y1 (6), got {o.size}",
                              key="--orientation-deg")
        kw["orientation"] = o.reshape(3, 2) if o.size == 6 else o
    try:
        region = spatial_region(robot, **kw)
    except ConfigError as exc:
        key = {"box": "--box", "cylinder": "--cylinder", "sphere": "--sphere",
               "orientation": "--orientation-deg"}.get(exc.key, exc.key)
        raise ConfigError(exc.message, source=exc.source, key=key) from None
    return region


def run_spatial(args: argparse.Namespace, robot) -> int:
    """``worst`` on a spatial robot: the worst first-order errors over a 3D region
    (:func:`pmaccuracy.accuracy.spatial_worst.spatial_global_worst`): attained lower values and certified upper
    values (``inf`` with certified false for a robot of joint chains and over a 3-RPS's or 3-PRS's whole
    workspace)."""
    import numpy as np

    from ..accuracy.spatial_worst import spatial_global_worst
    from ..errors import ConfigError, EmptyWorkspaceError
    from ..model.plausibility import warn
    from .spatial_cmd import _sources

    planar_only = (("--phi-deg", args.phi_deg), ("--disc", args.disc), ("--polygon", args.polygon),
                   ("--largest-disc", args.largest_disc), ("--target", args.target),
                   ("--certified", args.certified))
    for option, value in planar_only:
        if value:
            raise ConfigError(f"is not available for spatial robots' worst case yet ({robot.name} is a spatial "
                              f"{robot.architecture})", key=option)
    gap_pct = 1.0 if args.gap_pct is None else args.gap_pct
    _common.check_gap_pct(gap_pct)
    region = parse_spatial_region(robot, args)
    sources = _sources(args, robot)
    max_boxes = {} if args.max_boxes is None else {"max_boxes": args.max_boxes}
    try:
        res = spatial_global_worst(robot, sources, region, gap=gap_pct / 100, **max_boxes)
    except EmptyWorkspaceError as exc:
        raise ConfigError(str(exc), key=shape_key(args)) from None
    records = res.records()
    for r in records:
        if not np.isfinite(r["upper"]):
            r["upper"], r["gap_pct"] = None, None
    if not res.certified:
        warn([f"{res.reason}; the lower values are attained"])
    elif not all(r["certified"] for r in records):
        gaps = [r["gap_pct"] for r in records if r["gap_pct"] is not None]
        apart = f"{max(gaps):.3g} % apart" if len(gaps) == len(records) else \
            "some upper values empty (boxes whose W could not be proven regular: near a singularity?)"
        warn([f"the worst case is not certified within --gap-pct {gap_pct:g} (box budget spent): the bounds hold, "
              f"{apart}; raise --max-boxes or narrow the region"])
    data = {"robot": robot.name, "architecture": robot.architecture, "clearances": sources.name,
            "model": "first-order", "region": region.describe(), "target_gap_pct": gap_pct,
            "upper_certified": res.certified, "boxes": res.boxes, "iterations": res.iterations,
            "seconds": res.seconds, "quantities": records}
    _common.emit(data, args.format, records=records)
    return 0
