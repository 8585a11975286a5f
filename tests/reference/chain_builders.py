"""Spatial robots of the presets' architectures written joint by joint (architecture ``spatial-chain``).

The tables are built from the presets' geometry: a U-P-S leg from a 6-UPS leg, R-P-S, P-R-S, U-P-U and a Delta
leg's midline R-U-U (Tsai's condition: the elbow's first and the platform's last axes along the arm axis, the
middle ones parallel), so that the numeric chain engine can be checked against the closed-form leg types.
"""

from __future__ import annotations

import numpy as np

from pmaccuracy.kinematics.spatial import inverse_kinematics, reference_pose
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.numerics.spatial import rotations, rotvec_to_euler_xyz


def _unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)




def chain_table(robot: SpatialManipulator, home=None) -> dict:
    """The ``spatial-chain`` table of a preset's geometry at ``home`` (default its reference pose)."""
    home = reference_pose(robot) if home is None else np.asarray(home, dtype=float)
    p0, R0 = home[:3], rotations(home[3:])
    q0 = inverse_kinematics(robot, home).q
    legs = []
    for leg, q in zip(robot.legs, q0):
        A = np.asarray(leg.base, dtype=float)
        B = p0 + R0 @ np.asarray(leg.platform, dtype=float)
        arch = robot.architecture
        if arch in ("6-UPS", "3-UPU"):
            u = _unit(B - A)
            a1 = np.asarray(leg.base_axis if leg.base_axis is not None else _unit(np.cross(u, [0.0, 0.0, 1.0])))
            a2 = _unit(np.cross(u, a1))
            last = {"type": "S", "centre": B.tolist()} if arch == "6-UPS" else \
                {"type": "U", "centre": B.tolist(), "axes": [a2.tolist(), (R0 @ np.asarray(leg.platform_axis)).tolist()]}
            joints = [{"type": "U", "centre": A.tolist(), "axes": [a1.tolist(), a2.tolist()]},
                      {"type": "P", "centre": (0.5 * (A + B)).tolist(), "axis": u.tolist(), "home": float(q),
                       "stroke": list(leg.length_range), "actuated": True}, last]
        elif arch == "3-RPS":
            u = _unit(B - A)
            joints = [{"type": "R", "centre": A.tolist(), "axis": list(leg.axis)},
                      {"type": "P", "centre": (0.5 * (A + B)).tolist(), "axis": u.tolist(), "home": float(q),
                       "stroke": list(leg.length_range), "actuated": True},
                      {"type": "S", "centre": B.tolist()}]
        elif arch == "3-PRS":
            C = np.asarray(leg.base) + q * np.asarray(leg.slide)
            joints = [{"type": "P", "centre": C.tolist(), "axis": list(leg.slide), "home": float(q),
                       "stroke": list(leg.slide_range), "actuated": True},
                      {"type": "R", "centre": C.tolist(), "axis": list(leg.axis)},
                      {"type": "S", "centre": B.tolist()}]
        elif arch == "delta":
            a = np.asarray(leg.axis)
            C = leg.elbow(q)
            n = _unit(np.cross(a, B - C))
            joints = [{"type": "R", "centre": A.tolist(), "axis": a.tolist(), "home_deg": float(np.degrees(q)),
                       "range_deg": [float(np.degrees(v)) for v in leg.angle_range], "actuated": True},
                      {"type": "U", "centre": C.tolist(), "axes": [a.tolist(), n.tolist()]},
                      {"type": "U", "centre": B.tolist(), "axes": [n.tolist(), (R0 @ a).tolist()]}]
        else:  # pragma: no cover
            raise ValueError(arch)
        legs.append({"joints": joints})
    controlled = {"6": ["x", "y", "z", "roll", "pitch", "yaw"], "3T": ["x", "y", "z"],
                  "2R1T": ["z", "roll", "pitch"]}[robot.mobility]
    return {"architecture": "spatial-chain", "name": f"{robot.name}_chain", "controlled": controlled,
            "home": {"position": p0.tolist(), "orientation_deg": rotvec_to_euler_xyz(home[3:], degrees=True).tolist()},
            "legs": legs}


def cps_table(radius_base=300.0, radius_platform=150.0, height=400.0) -> dict:
    """A hexapod whose legs are C-P-S: a passive cylindrical joint on a horizontal base line, an actuated length
    perpendicular to that line, a spherical joint at the platform. Leg ``i``'s length is the distance from its
    platform point to its base line (closed form for the test)."""
    legs = []
    for i in range(6):
        t = np.radians(60 * i + (10 if i % 2 else -10))
        tb = np.radians(60 * i + (25 if i % 2 else -25))
        A = radius_base * np.array([np.cos(tb), np.sin(tb), 0.0])
        a = np.array([-np.sin(tb), np.cos(tb), 0.0])            # tangent of the base circle
        B = np.array([radius_platform * np.cos(t), radius_platform * np.sin(t), height])
        foot = A + ((B - A) @ a) * a
        u = _unit(B - foot)
        legs.append({"joints": [
            {"type": "C", "centre": foot.tolist(), "axis": a.tolist()},
            {"type": "P", "centre": foot.tolist(), "axis": u.tolist(), "home": float(np.linalg.norm(B - foot)),
             "actuated": True},
            {"type": "S", "centre": B.tolist()}], "line": (A, a)})
    return {"architecture": "spatial-chain", "name": "cps", "controlled": ["x", "y", "z", "roll", "pitch", "yaw"],
            "home": {"position": [0.0, 0.0, height], "orientation_deg": [0.0, 0.0, 0.0]}, "legs": legs}
