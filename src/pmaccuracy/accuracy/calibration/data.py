"""The calibration CSV: commanded actuator values and the measured pose of each point.

Columns (header names, any order; other columns are ignored)::

    point                      optional label (default: the row number)
    x, y, phi_deg              the measured pose in the measurement frame (mm, mm, deg)
    q1 | q1_deg, q2 | ..., q3  the commands of the three actuators: ``q{i}`` in mm for a prismatic
                               actuator, ``q{i}_deg`` in degrees for a revolute one
    sigma_x, sigma_y, sigma_phi_deg   optional 1-sigma uncertainties of the measured pose (mm, mm, deg);
                               default 0.01 mm and 0.01 deg (the paper's camera)

A file written by ``pmaccuracy experiment`` or ``pmaccuracy vision batch``
(``point,x_nom,y_nom,phi_nom_deg,push,x,y,phi_deg``) has no command columns: the commands are then those
that put the *nominal* robot at ``x_nom, y_nom, phi_nom_deg`` (its inverse kinematics), which is how
those measurements are taken. Units: mm and rad in the arrays, mm and degrees in the file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..._textfile import read_csv
from ...errors import MeasurementFileError
from ...io.csvio import write_csv_columns
from ...model import plausibility
from ...model.manipulator import Manipulator
from ...model.serial import SerialArm
from .parameters import ParameterVector, actuators, commands_for, wrap_commands

#: Default 1-sigma of a measured pose: the paper's camera, 0.01 mm and 0.01 deg (Sec. 5).
DEFAULT_ACCURACY_MM = 0.01
DEFAULT_ACCURACY_DEG = 0.01
#: Tolerance on a command outside its actuator's range (mm or deg): further out is refused.
RANGE_SLACK = 1e-6


@dataclass(frozen=True, eq=False)
class CalibrationData:
    """Calibration points: ``labels (N,)``, ``commands (N, 3)`` (mm / rad), measured ``poses (N, 3)``
    (mm, mm, rad, in the measurement frame), ``sigmas (N, 3)`` (mm, mm, rad) and the ``source`` file."""

    labels: tuple[str, ...]
    commands: np.ndarray
    poses: np.ndarray
    sigmas: np.ndarray
    source: str = "<data>"

    def __repr__(self) -> str:
        return f"CalibrationData({len(self.labels)} points from {self.source!r})"

    def __len__(self) -> int:
        return len(self.labels)

    def subset(self, keep: np.ndarray) -> "CalibrationData":
        keep = np.asarray(keep)
        return CalibrationData(tuple(np.asarray(self.labels, dtype=object)[keep]), self.commands[keep],
                               self.poses[keep], self.sigmas[keep], self.source)


def command_columns(robot: Manipulator) -> tuple[str, ...]:
    """``q{i}`` (prismatic actuator, mm) or ``q{i}_deg`` (revolute, deg) for the three legs (a serial arm:
    for each joint)."""
    return tuple(f"q{i}" if kind == "P" else f"q{i}_deg" for i, (kind, _) in enumerate(actuators(robot), start=1))


def _to_file_units(robot: Manipulator, commands: np.ndarray) -> np.ndarray:
    kinds = np.array([kind == "R" for kind, _ in actuators(robot)])
    return np.where(kinds, np.degrees(commands), commands)


def _who(robot, i: int) -> str:
    return f"joint {i}'s" if isinstance(robot, SerialArm) else f"leg {i}'s"


def write_calibration_csv(robot: Manipulator, commands: np.ndarray, poses: np.ndarray | None, path,
                          sigmas: np.ndarray | None = None, labels=None) -> None:
    """Write points as a calibration CSV (module docstring); ``poses`` None writes NaN readings (a plan)."""
    commands = np.asarray(commands, dtype=float)
    n = len(commands)
    cmd = _to_file_units(robot, commands)
    cols = {}
    cols["point"] = np.arange(1, n + 1, dtype=float) if labels is None else np.asarray(labels, dtype=float)
    for k, name in enumerate(command_columns(robot)):
        cols[name] = cmd[:, k]
    poses = np.full((n, 3), np.nan) if poses is None else np.asarray(poses, dtype=float)
    cols.update(x=poses[:, 0], y=poses[:, 1], phi_deg=np.degrees(poses[:, 2]))
    if sigmas is not None:
        sigmas = np.broadcast_to(np.asarray(sigmas, dtype=float), (n, 3))
        cols.update(sigma_x=sigmas[:, 0], sigma_y=sigmas[:, 1], sigma_phi_deg=np.degrees(sigmas[:, 2]))
    write_csv_columns(cols, path)


def read_calibration_csv(path, pv: ParameterVector) -> CalibrationData:
    """Read a calibration CSV (module docstring) for the robot of ``pv``.

    Raises :class:`~pmaccuracy.errors.MeasurementFileError` naming the file and the line: missing columns,
    a command column in the wrong unit (``q1`` for a revolute actuator), non-numeric or non-finite values,
    commands outside the actuators' ranges (a revolute command is compared modulo whole turns, and refused
    beyond [-360, 360] deg), non-positive sigmas.
    """
    robot = pv.robot
    src = str(path)
    lines = read_csv(path, MeasurementFileError)
    rows = [row for _, row in lines]
    if not rows:
        raise MeasurementFileError("empty file (expected a header x,y,phi_deg,q1...)", source=src)
    header = [h.strip() for h in rows[0]]
    missing = [c for c in ("x", "y", "phi_deg") if c not in header]
    if missing:
        raise MeasurementFileError(f"header must name the measured pose x,y,phi_deg (missing {','.join(missing)})",
                                   source=src, key="line 1")
    want = command_columns(robot)
    for i, name in enumerate(want, start=1):
        other = f"q{i}_deg" if name == f"q{i}" else f"q{i}"
        if other in header:
            unit_ = "mm (column q%d)" % i if name == f"q{i}" else "degrees (column q%d_deg)" % i
            raise MeasurementFileError(f"column {other}: {_who(robot, i)} actuator is "
                                       f"{'prismatic' if name == f'q{i}' else 'revolute'}: give its command in "
                                       f"{unit_}", source=src, key="line 1")
    has_cmd = [c in header for c in want]
    nominal = all(c in header for c in ("x_nom", "y_nom", "phi_nom_deg"))
    if not all(has_cmd) and nominal and isinstance(robot, SerialArm):
        raise MeasurementFileError(f"a serial arm's calibration CSV needs the commands {','.join(want)} (the nominal "
                                   "pose x_nom,y_nom,phi_nom_deg does not say which of the arm's configurations "
                                   "was commanded)", source=src, key="line 1")
    if not all(has_cmd) and not nominal:
        raise MeasurementFileError(f"header must name the commands {','.join(want)} (or the nominal pose "
                                   "x_nom,y_nom,phi_nom_deg of an experiment file)", source=src, key="line 1")
    use_cmd = all(has_cmd)
    names = (list(want) if use_cmd else ["x_nom", "y_nom", "phi_nom_deg"]) + ["x", "y", "phi_deg"]
    sig_names = ["sigma_x", "sigma_y", "sigma_phi_deg"]
    has_sig = [c in header for c in sig_names]
    if any(has_sig) and not all(has_sig):
        raise MeasurementFileError("give all three of sigma_x,sigma_y,sigma_phi_deg or none", source=src,
                                   key="line 1")
    if all(has_sig):
        names += sig_names
    cols = [header.index(c) for c in names]
    labels, values = [], []
    first_seen: dict[tuple[str, ...], int] = {}   # a row repeated verbatim -> the line it first appeared on
    repeated: list[tuple[int, int]] = []
    for line, row in lines[1:]:
        if not row or all(not c.strip() for c in row):
            continue
        key = tuple(c.strip() for c in row)
        if key in first_seen:
            repeated.append((line, first_seen[key]))
        first_seen.setdefault(key, line)
        if len(row) != len(header):
            raise MeasurementFileError(f"expected {len(header)} values, got {len(row)}", source=src,
                                       key=f"line {line}")
        vals = []
        for c, name in zip(cols, names):
            try:
                v = float(row[c])
            except ValueError:
                raise MeasurementFileError(f"{name}: not a number: {row[c]!r}", source=src,
                                           key=f"line {line}") from None
            if not math.isfinite(v):
                raise MeasurementFileError(f"{name}: must be finite, got {row[c]!r}", source=src,
                                           key=f"line {line}")
            vals.append(v)
        labels.append(row[header.index("point")].strip() if "point" in header else str(line - 1))
        values.append(vals)
    if not values:
        raise MeasurementFileError("no data rows", source=src)
    if repeated:
        shown = ", ".join(f"line {a} repeats line {b}" for a, b in repeated[:3])
        more = f" and {len(repeated) - 3} more" if len(repeated) > 3 else ""
        plausibility.warn([f"{src}: {shown}{more} verbatim: the same reading entered twice? (each row counts as "
                           f"one independent point)"], stacklevel=2)
    arr = np.array(values)
    na = len(want) if use_cmd else 3
    poses = np.column_stack([arr[:, na], arr[:, na + 1], np.radians(arr[:, na + 2])])
    kinds_r = np.array([kind == "R" for kind, _ in actuators(robot)])
    if use_cmd:
        commands = np.where(kinds_r, np.radians(arr[:, :na]), arr[:, :na])
    else:
        nom = np.column_stack([arr[:, 0], arr[:, 1], np.radians(arr[:, 2])])
        commands = commands_for(pv, pv.nominal, nom)
        bad = np.flatnonzero(~np.all(np.isfinite(commands), axis=1))
        if bad.size:
            raise MeasurementFileError("the nominal pose x_nom,y_nom,phi_nom_deg is out of the nominal robot's "
                                       "reach", source=src, key=f"row {bad[0] + 1}")
    rng = np.array([r for _, r in actuators(robot)])
    if use_cmd:   # a revolute command beyond a full turn either way is a slip (a sum of turns, or not degrees)
        beyond = np.argwhere(kinds_r & (np.abs(commands) > 2 * math.pi + 1e-12))
        if beyond.size:
            r, k = beyond[0]
            raise MeasurementFileError(
                f"{want[k]} = {math.degrees(commands[r, k]):.6g} deg is beyond a full turn (commands of a revolute "
                f"actuator lie within [-360, 360] deg, inside {_who(robot, k + 1)} range "
                f"[{math.degrees(rng[k, 0]):.6g}, {math.degrees(rng[k, 1]):.6g}] deg up to whole turns)",
                source=src, key=f"row {r + 1} (point {labels[r]})")
    in_turn = wrap_commands(robot, commands)  # a revolute command is checked modulo whole turns
    for k in range(len(want)):
        c = in_turn[:, k]
        out = np.flatnonzero((c < rng[k, 0] - RANGE_SLACK) | (c > rng[k, 1] + RANGE_SLACK))
        if out.size:
            r = out[0]
            f = np.degrees if kinds_r[k] else (lambda v: v)
            u = "deg" if kinds_r[k] else "mm"
            raise MeasurementFileError(
                f"{want[k]} = {f(commands[r, k]):.6g} {u} is outside {_who(robot, k + 1)} actuator range "
                f"[{f(rng[k, 0]):.6g}, {f(rng[k, 1]):.6g}] {u}", source=src, key=f"row {r + 1} (point {labels[r]})")
    if all(has_sig):
        sig = np.column_stack([arr[:, na + 3], arr[:, na + 4], np.radians(arr[:, na + 5])])
        bad = np.argwhere(sig <= 0)
        if bad.size:
            raise MeasurementFileError(f"{sig_names[bad[0][1]]} must be positive", source=src,
                                       key=f"row {bad[0][0] + 1}")
    else:
        sig = np.tile([DEFAULT_ACCURACY_MM, DEFAULT_ACCURACY_MM, math.radians(DEFAULT_ACCURACY_DEG)], (len(arr), 1))
    return CalibrationData(tuple(labels), commands, poses, sig, src)
