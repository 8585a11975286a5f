"""Independent reference for calibrating planar serial arms (written apart from pmaccuracy).

* :func:`random_arm_dict`: a serial robot file with random joint types, lengths, offsets and ranges (seeded).
* :func:`arm_pose`: the end pose of an arm with the parameters ``{name: value}`` at commands, from the guide's
  convention (docs/guide/formats.md, "Planar serial arms": joint k turns the frame by its offset, an R joint also by its value;
  the frame's origin then moves along the new x-axis by the link length, plus the value for a P joint), each
  joint value ``offset + gain * command``, read in the measurement frame ``F``: ``m = F^-1 p``. A plain
  loop over the joints with 2x2 rotation matrices, per configuration.
* :func:`arm_jacobian`: ``dm/dtheta`` by central differences of :func:`arm_pose`.
"""

from __future__ import annotations

import math

import numpy as np


def random_arm_dict(rng: np.random.Generator, n: int | None = None) -> dict:
    """A serial arm of 2-5 joints (at least two R), random lengths 50-300 mm, offsets within 30 deg."""
    n = int(rng.integers(3, 6)) if n is None else n
    kinds = list(rng.choice(["R", "P"], size=n, p=[0.7, 0.3]))
    for k in rng.choice(n, size=min(2, n), replace=False):
        kinds[k] = "R"
    joints = []
    for k, kind in enumerate(kinds):
        t = {"type": kind, "length": float(rng.uniform(50, 300)), "offset_deg": float(rng.uniform(-30, 30))}
        t["range"] = [-150.0, 150.0] if kind == "R" else [0.0, float(rng.uniform(50, 200))]
        joints.append(t)
    return {"architecture": "serial", "name": "random_arm", "joints": joints}


def arm_pose(values: dict, kinds: str, command) -> np.ndarray:
    """Measured pose ``(3,)`` (mm, mm, rad) of the arm ``values`` at one ``command (n,)`` (rad / mm)."""
    R = np.eye(2)
    p = np.zeros(2)
    phi = 0.0
    for k, kind in enumerate(kinds, start=1):
        q = values[f"joint{k}.actuator.offset"] + values[f"joint{k}.actuator.gain"] * command[k - 1]
        turn = values[f"joint{k}.offset"] + (q if kind == "R" else 0.0)
        phi += turn
        c, s = math.cos(turn), math.sin(turn)
        R = R @ np.array([[c, -s], [s, c]])
        p = p + R @ np.array([values[f"joint{k}.length"] + (q if kind == "P" else 0.0), 0.0])
    fc, fs = math.cos(values["frame.phi"]), math.sin(values["frame.phi"])
    d = p - np.array([values["frame.x"], values["frame.y"]])
    return np.array([fc * d[0] + fs * d[1], -fs * d[0] + fc * d[1], phi - values["frame.phi"]])


def arm_poses(values: dict, kinds: str, commands: np.ndarray) -> np.ndarray:
    return np.array([arm_pose(values, kinds, c) for c in np.asarray(commands, dtype=float)])


def arm_jacobian(values: dict, kinds: str, commands: np.ndarray, names: list[str], h: float = 1e-6) -> np.ndarray:
    """``dm/dtheta (3N, P)`` by central differences of :func:`arm_poses`."""
    cols = []
    for name in names:
        vp, vm = dict(values), dict(values)
        vp[name] += h
        vm[name] -= h
        cols.append(((arm_poses(vp, kinds, commands) - arm_poses(vm, kinds, commands)) / (2 * h)).ravel())
    return np.stack(cols, axis=-1)
