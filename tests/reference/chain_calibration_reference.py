"""Independent reference for calibrating legs in the general chain form (written apart from pmaccuracy).

* :func:`random_chain_robot_dict`: a robot file whose legs are ``[[legs.joints]]`` chains, taken from a
  preset's chain and with every number of it moved at random (seeded): base point and angle, each joint's
  offset and link vector, platform point and angle. Robots nobody tuned, with generic (non-zero) links.
* :func:`chain_end_frame`: the end frame of one chain leg at joint values ``q``, from the convention of the
  guide (docs/guide/formats.md: R turns by ``offset + q`` then moves by the link; P turns by ``offset``, slides
  ``q`` along its x-axis, then moves by the link), written here from that text.
* :func:`measure_chain_robot`: the poses a robot with the parameters ``{name: value}`` reaches at commands,
  by Newton's method on the 9 closure equations ``end frame of leg i = Tr(p) Rot(phi) Tr(platform_i)
  Rot(platform_angle_i)`` in the 9 unknowns (pose, the 6 passive joint values), read in the measurement
  frame ``F``: ``m = F^-1 p``. The Newton start (pose and passive joints) is given by the caller: it only
  picks the assembly mode, the converged root is fixed by the equations here.
"""

from __future__ import annotations

import copy
import math
import re

import numpy as np


def random_chain_robot_dict(chain_table: dict, rng: np.random.Generator, move_mm: float = 2.0,
                            move_deg: float = 2.0) -> dict:
    """A copy of a chain-form robot-file table with every geometric number of its legs moved at random."""
    out = copy.deepcopy(chain_table)
    out["name"] = "random_chain"
    for leg in out["legs"]:
        leg["base"] = [float(v + rng.uniform(-move_mm, move_mm)) for v in leg.get("base", [0.0, 0.0])]
        leg["platform"] = [float(v + rng.uniform(-move_mm, move_mm)) for v in leg.get("platform", [0.0, 0.0])]
        leg["base_deg"] = float(leg.get("base_deg", 0.0) + rng.uniform(-move_deg, move_deg))
        leg["platform_deg"] = float(leg.get("platform_deg", 0.0) + rng.uniform(-move_deg, move_deg))
        for jt in leg["joints"]:
            jt["offset_deg"] = float(jt.get("offset_deg", 0.0) + rng.uniform(-move_deg, move_deg))
            jt["link"] = [float(v + rng.uniform(-move_mm, move_mm)) for v in jt.get("link", [0.0, 0.0])]
    return out


def geometry_from_names(values: dict, kinds: list[str]) -> list[dict]:
    """Per leg: ``base (2,), base_angle, offsets (3,), links (3, 2), platform (2,), platform_angle,
    act_offset, act_gain`` from the parameter names ``leg{i}.base.x`` ... (``kinds``: joint kinds per leg,
    e.g. ``"RRR"``; the actuated joint's index is given separately)."""
    legs = []
    for i in range(1, len(kinds) + 1):
        g = lambda key: float(values[f"leg{i}.{key}"])  # noqa: E731
        legs.append(dict(base=np.array([g("base.x"), g("base.y")]), base_angle=g("base.angle"),
                         offsets=np.array([g(f"joint{k}.offset") for k in (1, 2, 3)]),
                         links=np.array([[g(f"joint{k}.link.x"), g(f"joint{k}.link.y")] for k in (1, 2, 3)]),
                         platform=np.array([g("platform.x"), g("platform.y")]), platform_angle=g("platform.angle"),
                         act_offset=g("actuator.offset"), act_gain=g("actuator.gain"), kinds=kinds[i - 1]))
    return legs


def chain_end_frame(leg: dict, q) -> tuple[np.ndarray, float]:
    """Origin ``(2,)`` (mm) and angle (rad) of the end frame of a chain leg at joint values ``q (3,)``."""
    pos = np.array(leg["base"], dtype=float)
    ang = float(leg["base_angle"])
    for kind, off, link, qk in zip(leg["kinds"], leg["offsets"], leg["links"], q):
        if kind == "R":
            ang += off + qk
            slide = np.array(link, dtype=float)
        else:
            ang += off
            slide = np.array([qk + link[0], link[1]])
        c, s = math.cos(ang), math.sin(ang)
        pos = pos + np.array([c * slide[0] - s * slide[1], s * slide[0] + c * slide[1]])
    return pos, ang


def _closure(legs, actuated, commands, z):
    x, y, phi = z[:3]
    res = []
    for i, leg in enumerate(legs):
        q = list(z[3 + 2 * i: 5 + 2 * i])
        q.insert(actuated[i], leg["act_offset"] + leg["act_gain"] * commands[i])
        pos, ang = chain_end_frame(leg, q)
        c, s = math.cos(phi), math.sin(phi)
        want = np.array([x + c * leg["platform"][0] - s * leg["platform"][1],
                         y + s * leg["platform"][0] + c * leg["platform"][1]])
        d = ang - phi - leg["platform_angle"]
        res += [pos[0] - want[0], pos[1] - want[1], math.atan2(math.sin(d), math.cos(d)) * 100.0]
    return np.array(res)


def _jz(legs, actuated, cmd, z):
    J = np.empty((9, 9))
    for k in range(9):
        dz = np.zeros(9)
        dz[k] = 1e-7
        J[:, k] = (_closure(legs, actuated, cmd, z + dz) - _closure(legs, actuated, cmd, z - dz)) / 2e-7
    return J


def solve_chain_robot(values: dict, kinds: list[str], actuated: list[int], commands: np.ndarray,
                      start: np.ndarray, start_passive: np.ndarray) -> np.ndarray:
    """Solutions ``z (N, 9)`` (pose mm, mm, rad; then the passive joint values of legs 1-3) of the closure
    equations of the robot ``values`` at ``commands (N, 3)``; Newton from ``start (N, 3)`` poses and
    ``start_passive (N, 3, 2)``; NaN rows where it does not converge to 1e-10."""
    legs = geometry_from_names(values, kinds)
    out = np.full((len(commands), 9), np.nan)
    for n, cmd in enumerate(np.asarray(commands, dtype=float)):
        z = np.concatenate([start[n], np.asarray(start_passive[n], dtype=float).ravel()])
        for _ in range(40):
            r = _closure(legs, actuated, cmd, z)
            if np.max(np.abs(r)) < 1e-12:
                break
            z = z - np.linalg.solve(_jz(legs, actuated, cmd, z), r)
        if np.max(np.abs(_closure(legs, actuated, cmd, z))) < 1e-10:
            out[n] = z
    return out


def measure_chain_robot(values: dict, kinds: list[str], actuated: list[int], commands: np.ndarray,
                        start: np.ndarray, start_passive: np.ndarray) -> np.ndarray:
    """Measured poses ``(N, 3)`` (mm, mm, rad) of the robot ``values`` (parameter names -> values; the
    frame ``frame.x, frame.y, frame.phi``) at ``commands (N, 3)``: :func:`solve_chain_robot` read in the
    measurement frame."""
    z = solve_chain_robot(values, kinds, actuated, commands, start, start_passive)
    return _in_frame(values, z[:, :3])


def measurement_jacobian(values: dict, kinds: list[str], actuated: list[int], commands: np.ndarray,
                         z: np.ndarray, names: list[str], h: float = 1e-6) -> np.ndarray:
    """``dm/dtheta (3N, P)`` of the measured poses in the parameters ``names`` at the solutions ``z (N, 9)``:
    central differences, each side one Newton step from ``z`` (error O(h^2))."""
    legs0 = geometry_from_names(values, kinds)
    Jz = [_jz(legs0, actuated, c, zn) for c, zn in zip(commands, z)]
    cols = []
    for name in names:
        side = []
        for sgn in (1.0, -1.0):
            v = dict(values)
            v[name] = v[name] + sgn * h
            legs = geometry_from_names(v, kinds)
            p = np.array([(zn - np.linalg.solve(J, _closure(legs, actuated, c, zn)))[:3]
                          for c, zn, J in zip(commands, z, Jz)])
            side.append(_in_frame(v, p))
        d = side[0] - side[1]
        d[:, 2] = np.arctan2(np.sin(d[:, 2]), np.cos(d[:, 2]))
        cols.append((d / (2 * h)).ravel())
    return np.stack(cols, axis=-1)


def _in_frame(values: dict, out: np.ndarray) -> np.ndarray:
    fx, fy, fphi = (float(values[k]) for k in ("frame.x", "frame.y", "frame.phi"))
    c, s = math.cos(fphi), math.sin(fphi)
    dx, dy = out[:, 0] - fx, out[:, 1] - fy
    return np.stack([c * dx + s * dy, -s * dx + c * dy, out[:, 2] - fphi], axis=-1)


def actuated_and_kinds(robot_dict: dict) -> tuple[list[str], list[int]]:
    """Joint kinds (``"RRR"``, ...) and the actuated joint's index per leg of a chain-form robot file."""
    kinds = ["".join(j["type"] for j in leg["joints"]) for leg in robot_dict["legs"]]
    act = [next(k for k, j in enumerate(leg["joints"]) if j.get("actuated")) for leg in robot_dict["legs"]]
    return kinds, act


NAME = re.compile(r"^(leg[123]\.(base\.(x|y|angle)|joint[123]\.(offset|link\.x|link\.y)|platform\.(x|y|angle)|"
                  r"actuator\.(offset|gain))|frame\.(x|y|phi))$")
