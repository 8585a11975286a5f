"""``pmaccuracy workspace``: the exact constant-orientation workspace of any architecture (paper Sec. 3, Fig. 3)."""

from __future__ import annotations

import argparse

from . import _common
from ..io.resolve import robot_arg

HELP = "constant-orientation workspace: exact region bounded by segments and arcs (Sec. 3, any architecture)"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "workspace", help=HELP,
        description="At a fixed orientation the joint limits bound the platform centre by lines and circles; prints "
                    "the exact region: area in mm^2 (Green's theorem over its arcs and segments), bounds and the "
                    "corners of its boundary in mm. An empty workspace prints area 0, null bounds and no corners. "
                    "With --compare, one row per robot and a side-by-side figure (--plot).")
    _common.add_robot(p)
    p.add_argument("--phi-deg", type=_common.finite_float, default=0.0, metavar="PHI",
                   help="platform orientation in degrees (default: 0)")
    p.add_argument("--compare", nargs="+", metavar="ROBOT",
                   help="compare several robots (preset names or files) instead of --robot")
    _common.add_plot(p, "also write a figure: the robot with its workspaces at PHI and at 0, 30, -30 deg and a "
                        "zoom on them (with --compare: the robots side by side, to one scale)")
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

    robots = [robot_arg(spec) for spec in args.compare] if args.compare else [_common.load_robot(args)]
    from pathlib import Path

    plot = Path(args.plot) if args.plot else None
    _common.check_plot(args)
    results = [_summary(robot, args.phi_deg, constant_orientation_workspace(robot, np.radians(args.phi_deg)))
               for robot in robots]
    phis = tuple([args.phi_deg] + [p for p in DEFAULT_PHIS_DEG if p != args.phi_deg])
    if plot is not None:
        from ..kinematics.workspace import save_comparison_figure, save_workspace_figure
        if args.compare:
            save_comparison_figure(robots, plot, phis_deg=phis, dpi=args.dpi)
        else:
            save_workspace_figure(robots[0], plot, phis_deg=phis, dpi=args.dpi)
    data = [d for d, _ in results] if args.compare else results[0][0]
    _common.emit(data, args.format, records=[r for _, r in results])
    return 0
