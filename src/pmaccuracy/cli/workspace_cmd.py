"""``pmaccuracy workspace``: the exact constant-orientation workspace (paper Sec. 3, Fig. 3)."""

from __future__ import annotations

import argparse

import numpy as np

from . import _common


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "workspace", help="constant-orientation workspace: exact polygon of the 12 joint limits (Sec. 3)",
        description="At a fixed orientation the joint limits of Eq. 2a/2b are half-planes in (x, y); prints their "
                    "intersection (a convex polygon): area in mm^2, bounds and vertices in mm (counter-clockwise). "
                    "An empty workspace prints area 0, null bounds and no vertices.")
    _common.add_robot(p)
    p.add_argument("--phi-deg", type=_common.finite_float, default=0.0, metavar="PHI",
                   help="platform orientation in degrees (default: 0)")
    p.add_argument("--plot", metavar="FILE.png",
                   help="also write a figure of the workspaces at PHI and at 0, 30, -30 deg with the robot")
    _common.add_format(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..workspace import DEFAULT_PHIS_DEG, constant_orientation_workspace, save_workspace_figure

    robot = _common.load_robot(args)
    ws = constant_orientation_workspace(robot, np.radians(args.phi_deg))
    (xmin, xmax), (ymin, ymax) = ws.bounds
    data = {"phi_deg": args.phi_deg, "area": ws.area,
            "bounds": {"x": [xmin, xmax], "y": [ymin, ymax]},
            "polygon": ws.vertices.tolist()}
    record = {"phi_deg": args.phi_deg, "area": ws.area, "x_min": xmin, "x_max": xmax,
              "y_min": ymin, "y_max": ymax, "n_vertices": int(ws.vertices.shape[0])}
    if args.plot:
        phis = [args.phi_deg] + [p for p in DEFAULT_PHIS_DEG if p != args.phi_deg]
        save_workspace_figure(robot, args.plot, phis_deg=tuple(phis))
    _common.emit(data, args.format, records=[record])
    return 0
