"""Independent reference of the spatial calibration's measurement model; tests only.

Written from the equations of ``docs/guide/calibration.md`` (spatial section) and the robot-file format; it
does not import ``pmaccuracy``. The kinematics are those of :mod:`spatial_reference` (one pose at a time,
``scipy.optimize`` for the forward kinematics). A parameter table is ``{name: value}`` with the library's
names (``legs[2].base.x``, ``legs[1].arm``, ``legs[3].actuator.gain``, ``frame.rx``, ``tool.z`` or
``tool[2].z``), parsed here from the names alone.

Axis parameters (angles, 0 at nominal; ``docs/guide/calibration.md``): ``legs[i].axis.a|b`` (3-RPS revolute axis;
Delta arm axis, its ``zero`` turned with it), ``legs[i].base_axis.a|b`` (3-UPU, ``platform_axis`` turned with
it), ``legs[i].slide.a|b`` and ``legs[i].axis.a`` (3-PRS: the slide and the revolute axis turned together by
the tilt, the axis first turned about the slide by ``axis.a``). A tilt ``(a, b)`` of a nominal direction
``d`` is the rotation ``expm(a n1 + b n2)``, ``n1`` the unit ``d x e`` with ``e`` the coordinate axis of the
smallest ``|d_k|`` (first one on ties), ``n2 = d x n1``.

Model: actuated ``q_i = offset_i + gain_i c_i``; the platform pose ``(p, R)`` solves the robot's closure
with those ``q``; the device (frame ``t``, ``R_F = exp([r]x)``) reads ``(t + R_F p, R_F R)`` or the target
``t + R_F (p + R s_k)``.
"""

from __future__ import annotations

import copy
import re

import numpy as np

import spatial_reference as sr

_NAME = re.compile(r"^legs\[(\d+)\]\.(base|platform)\.([xyz])$")


def _normals(d):
    d = np.asarray(d, float) / np.linalg.norm(d)
    k = min(range(3), key=lambda j: (abs(d[j]), j))
    e = np.eye(3)[k]
    n1 = np.cross(d, e)
    n1 /= np.linalg.norm(n1)
    return n1, np.cross(d, n1)


#: Per architecture: the direction the angles tilt and the directions turned with it.
_TILTED = {"3-RPS": ("axis", ("axis",)), "delta": ("axis", ("axis", "zero")),
           "3-UPU": ("base_axis", ("base_axis", "platform_axis")), "3-PRS": ("slide", ("slide", "axis"))}


def _turn_axes(robot: dict, angles: dict) -> None:
    """Apply ``{(leg index, which): angle}`` (which: "a", "b", "spin") to the robot dict's directions."""
    first, turned = _TILTED[robot["architecture"]]
    for i in {i for i, _ in angles}:
        leg = robot["legs"][i]
        d = np.asarray(leg[first], float) / np.linalg.norm(leg[first])
        n1, n2 = _normals(d)
        tilt = sr.expm_so3(angles.get((i, "a"), 0.0) * n1 + angles.get((i, "b"), 0.0) * n2)
        spin = sr.expm_so3(angles.get((i, "spin"), 0.0) * d)
        for key in turned:
            leg[key] = list(tilt @ spin @ np.asarray(leg[key], float))


def apply(robot: dict, table: dict):
    """``(robot dict with the geometry of table, offsets, gains, t, R_F, targets {k: s})``."""
    robot = copy.deepcopy(robot)
    n = len(robot["legs"])
    off, gain = np.zeros(n), np.ones(n)
    t, r = np.zeros(3), np.zeros(3)
    targets: dict[int, np.ndarray] = {}
    angles: dict = {}
    prs = robot["architecture"] == "3-PRS"
    for name, value in table.items():
        m = re.match(r"^legs\[(\d+)\]\.(axis|base_axis|slide)\.(a|b)$", name)
        if m:
            which = "spin" if prs and m.group(2) == "axis" else m.group(3)
            angles[(int(m.group(1)) - 1, which)] = float(value)
            continue
        m = _NAME.match(name)
        if m:
            leg = robot["legs"][int(m.group(1)) - 1]
            pt = list(leg[m.group(2)])
            pt["xyz".index(m.group(3))] = float(value)
            leg[m.group(2)] = pt
            continue
        m = re.match(r"^legs\[(\d+)\]\.(arm|rod|actuator\.offset|actuator\.gain)$", name)
        if m:
            i = int(m.group(1)) - 1
            if m.group(2) == "actuator.offset":
                off[i] = value
            elif m.group(2) == "actuator.gain":
                gain[i] = value
            else:
                robot["legs"][i][m.group(2)] = float(value)
            continue
        m = re.match(r"^frame\.(x|y|z|rx|ry|rz)$", name)
        if m:
            k = ["x", "y", "z", "rx", "ry", "rz"].index(m.group(1))
            (t if k < 3 else r)[k % 3] = value
            continue
        m = re.match(r"^tool(?:\[(\d+)\])?\.([xyz])$", name)
        if m:
            k = int(m.group(1) or 1) - 1
            targets.setdefault(k, np.zeros(3))["xyz".index(m.group(2))] = value
            continue
        raise ValueError(f"unknown parameter {name}")
    if angles:
        _turn_axes(robot, angles)
    return robot, off, gain, t, sr.expm_so3(r), targets


def readings(robot: dict, table: dict, commands, guesses):
    """Per command row ``(n,)``: the full pose ``(6,)`` ``[t + R_F p, rotvec(R_F R)]`` and the target points
    ``{k: (3,)}``; ``guesses``: ``[(p, R)]`` starting poses of the forward kinematics."""
    rob, off, gain, t, RF, targets = apply(robot, table)
    poses, points = [], []
    for c, (p0, R0) in zip(np.asarray(commands, float), guesses):
        p, R = sr.forward(rob, off + gain * c, p0, R0)
        poses.append(np.concatenate([t + RF @ p, sr.rotvec(RF @ R)]))
        points.append({k: t + RF @ (p + R @ s) for k, s in targets.items()})
    return np.array(poses), points


def ik_residual_jacobian(robot: dict, table: dict, names, commands, poses, h=1e-4) -> np.ndarray:
    """Full-pose data: the Jacobian ``(N (n + c), P)`` (central differences) of the inverse-kinematic residuals
    ``q_i(theta; F^-1 m) - offset_i - gain_i c_i`` and of a lower-mobility robot's ``c`` constraint residuals
    (:func:`spatial_reference.constraint_residuals`: a pose its legs forbid) at the device readings
    ``poses (N, 6)``; it has the null space of the forward-residual Jacobian wherever the robot is not singular (``dm = -(dF/dm)^-1 dF/dtheta``
    with ``dF/dm`` invertible)."""
    def res(tab):
        rob, off, gain, t, RF, _ = apply(robot, tab)
        out = []
        for c, m in zip(np.asarray(commands, float), poses):
            p = RF.T @ (m[:3] - t)
            R = RF.T @ sr.from_rotvec(m[3:])
            out.append(sr.actuators(rob, p, R) - off - gain * c)
            out.append(sr.constraint_residuals(rob, p, R))
        return np.concatenate(out)
    cols = []
    for name in names:
        up, dn = dict(table), dict(table)
        up[name] = table[name] + h
        dn[name] = table[name] - h
        cols.append((res(up) - res(dn)) / (2 * h))
    return np.array(cols).T


def null_space(J: np.ndarray, scale: np.ndarray, rtol: float = 1e-7) -> np.ndarray:
    """An orthonormal basis ``(P, d)`` of the null space of ``J D`` (``D = diag(scale)``: columns in typical
    units) from its SVD, mapped back to parameter units and orthonormalized."""
    _, s, Vt = np.linalg.svd(J * scale, full_matrices=True)
    rank = int(np.sum(s > rtol * s[0]))
    basis = (Vt[rank:].T) * scale[:, None]
    q, _ = np.linalg.qr(basis)
    return q
