"""``pmaccuracy workspace``: the exact constant-orientation workspace of any architecture (paper Sec. 3, Fig. 3)."""

from __future__ import annotations

import argparse

from . import _common
from ..errors import PmAccuracyError
from ..io.resolve import robot_arg

HELP = "constant-orientation workspace: exact region bounded by segments and arcs (Sec. 3, any architecture)"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "workspace", help=HELP,
        description="At a fixed orientation the joint limits bound the platform centre by lines and circles; prints "
                    "the exact region: area in mm^2 (Green's theorem over its arcs and segments), bounds and the "
                    "corners of its boundary in mm. An empty workspace prints area 0, null bounds and no corners. "
                    "Several orientations (--phi-deg 0 30, or the option repeated) print one row each (JSON: a "
                    "list). With --compare, one row per robot and orientation and a side-by-side figure (--plot).")
    _common.add_robot(p)
    p.add_argument("--phi-deg", type=_common.angle_deg, nargs="+", action="extend", default=None,
                   metavar="PHI",
                   help="platform orientation(s) in degrees, several values and/or the option repeated (default: "
                        "0)")
    p.add_argument("--orientation-deg", type=_common.angle_deg, nargs=3, metavar=("ROLL", "PITCH", "YAW"),
                   help="spatial 6-UPS: the fixed orientation of its constant-orientation workspace, roll pitch yaw "
                        "in deg as extrinsic x-y-z rotations (default: 0 0 0)")
    p.add_argument("--n", type=int, default=40, metavar="N",
                   help="spatial robots: grid points per axis of the workspace (default 40; 8 to 200)")
    p.add_argument("--html", metavar="FILE.html",
                   help="spatial robots: also write an interactive 3D view of the workspace (one HTML page that "
                        "works offline)")
    p.add_argument("--compare", nargs="+", metavar="ROBOT",
                   help="compare several robots (preset names or files) instead of --robot")
    _common.add_plot(p, "also write a figure: the robot with its workspaces at PHI and at 0, 30, -30 deg (at "
                        "exactly the PHIs when several are given) and a zoom on them (with --compare: the robots "
                        "side by side, to one scale)")
    _common.add_format(p)
    p.set_defaults(func=run)


def _summary(robot, phi_deg: float, ws) -> tuple[dict, dict]:
    (xmin, xmax), (ymin, ymax) = ws.bounds
    data = {"robot": robot.name, "architecture": robot.architecture, "phi_deg": phi_deg, "area": ws.area,
            "bounds": {"x": [xmin, xmax], "y": [ymin, ymax]}, "polygon": ws.vertices.tolist()}
    record = {"robot": robot.name, "phi_deg": phi_deg, "area": ws.area, "x_min": xmin, "x_max": xmax,
              "y_min": ymin, "y_max": ymax, "n_vertices": int(ws.vertices.shape[0])}
    return data, record


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from ..kinematics.workspace import DEFAULT_PHIS_DEG, constant_orientation_workspace

    from ..model.spatial import is_spatial

    robots = [robot_arg(spec) for spec in args.compare] if args.compare else [_common.load_robot(args)]
    if any(is_spatial(r) for r in robots):
        if len(robots) > 1:
            raise PmAccuracyError("--compare takes planar robots only so far")
        if not 8 <= args.n <= 200:
            raise PmAccuracyError(f"--n: {args.n} grid points per axis; give 8 to 200")
        from . import spatial_cmd

        return spatial_cmd.run_workspace(args, robots[0])
    for option, value in (("--orientation-deg", args.orientation_deg), ("--html", args.html)):
        if value is not None:
            raise PmAccuracyError(f"{option} is for spatial robots; {robots[0].name} is planar (use --phi-deg)")
    from pathlib import Path

    plot = Path(args.plot) if args.plot else None
    _common.check_plot(args)
    requested = list(dict.fromkeys(args.phi_deg or [0.0]))    # in the given order, each once
    results = [_summary(robot, phi, constant_orientation_workspace(robot, np.radians(phi)))
               for robot in robots for phi in requested]
    if len(requested) == 1:   # the orientation asked for, then the usual three for context
        phis = tuple(requested + [p for p in DEFAULT_PHIS_DEG if p != requested[0]])
    else:
        phis = tuple(requested)
    if plot is not None:
        from ..kinematics.workspace import save_comparison_figure, save_workspace_figure
        if args.compare:
            save_comparison_figure(robots, plot, phis_deg=phis, dpi=args.dpi)
        else:
            save_workspace_figure(robots[0], plot, phis_deg=phis, dpi=args.dpi)
    data = [d for d, _ in results] if args.compare or len(results) > 1 else results[0][0]
    _common.emit(data, args.format, records=[r for _, r in results])
    return 0
