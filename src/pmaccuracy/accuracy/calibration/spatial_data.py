"""The calibration CSV of a spatial robot: commanded actuator values and the reading of each point.

Columns (header names, any order; other columns are ignored)::

    point                          optional label (default: the row number)
    q1 | q1_deg, ..., qn           the commands: ``q{i}`` in mm for a prismatic actuator, ``q{i}_deg`` in degrees
                                   for a revolute one (a Delta's arms)
    full pose (a 6D tracker, a camera):
    x, y, z                        the platform's position in the device's frame (mm)
    roll_deg, pitch_deg, yaw_deg   its orientation, extrinsic x-y-z angles (deg)
    sigma_x, sigma_y, sigma_z      optional 1-sigma of the position (mm; default 0.01)
    sigma_rx_deg, sigma_ry_deg, sigma_rz_deg   optional 1-sigma of the orientation about the device's x, y, z
                                   axes (deg; default 0.01)
    position only (a laser tracker):
    target                         which target point was measured (1, 2, ...: the order of the targets given
                                   with the data); optional with one target
    x, y, z                        its position in the device's frame (mm)
    sigma_x, sigma_y, sigma_z      optional 1-sigma (mm; default 0.01): a tracker's distance-dependent
                                   uncertainty ``a + b * distance`` is written out per row

A file with the orientation columns is full-pose data; one without them is position-only data. mm and rad
in the arrays, mm and degrees in the file.
"""

from __future__ import annotations

import math

import numpy as np

from ..._textfile import read_csv
from ...errors import MeasurementFileError
from ...io.csvio import write_csv_columns
from ...numerics.spatial import euler_xyz_to_rotvec, rotvec_to_euler_xyz
from .spatial_identify import DEFAULT_SIGMA_MM, DEFAULT_SIGMA_RAD, SpatialCalibrationData
from .spatial_parameters import SpatialParameterVector

POSE_COLUMNS = ("x", "y", "z", "roll_deg", "pitch_deg", "yaw_deg")
POSE_SIGMAS = ("sigma_x", "sigma_y", "sigma_z", "sigma_rx_deg", "sigma_ry_deg", "sigma_rz_deg")


def spatial_command_columns(robot) -> tuple[str, ...]:
    """``q{i}`` (prismatic actuator, mm) or ``q{i}_deg`` (revolute, deg), one per leg."""
    return tuple(f"q{i}" if kind == "P" else f"q{i}_deg" for i, kind in enumerate(robot.actuated_kinds, start=1))


def write_spatial_csv(pv: SpatialParameterVector, data: SpatialCalibrationData, path) -> None:
    """Write ``data`` as a spatial calibration CSV (module docstring)."""
    kinds = np.array([k == "R" for k in pv.robot.actuated_kinds])
    cmd = np.where(kinds, np.degrees(data.commands), data.commands)
    cols: dict[str, np.ndarray] = {}
    try:
        cols["point"] = np.array([float(x) for x in data.labels])
    except ValueError:
        cols["point"] = np.arange(1, len(data) + 1, dtype=float)
    for k, name in enumerate(spatial_command_columns(pv.robot)):
        cols[name] = cmd[:, k]
    if data.kind == "position":
        cols["target"] = data.target + 1.0
    m = data.measured
    cols.update(x=m[:, 0], y=m[:, 1], z=m[:, 2])
    cols.update(sigma_x=data.sigmas[:, 0], sigma_y=data.sigmas[:, 1], sigma_z=data.sigmas[:, 2])
    if data.kind == "pose":
        angles = rotvec_to_euler_xyz(m[:, 3:], degrees=True)
        cols.update(roll_deg=angles[:, 0], pitch_deg=angles[:, 1], yaw_deg=angles[:, 2])
        s = np.degrees(data.sigmas[:, 3:])
        cols.update(sigma_rx_deg=s[:, 0], sigma_ry_deg=s[:, 1], sigma_rz_deg=s[:, 2])
    write_csv_columns(cols, path)


def read_spatial_csv(path, pv: SpatialParameterVector) -> SpatialCalibrationData:
    """Read a spatial calibration CSV (module docstring) for ``pv`` (its kind says which readings are expected).

    Raises :class:`~pmaccuracy.errors.MeasurementFileError` naming the file and the line: missing columns, a
    command column in the wrong unit, full-pose readings for position-only parameters or the other way round,
    non-numeric or non-finite values, a target number out of range, non-positive sigmas.
    """
    src = str(path)
    lines = read_csv(path, MeasurementFileError)
    rows = [row for _, row in lines]
    if not rows:
        raise MeasurementFileError("empty file (expected a header q1..., x, y, z...)", source=src)
    header = [h.strip() for h in rows[0]]
    want = spatial_command_columns(pv.robot)
    for i, name in enumerate(want, start=1):
        other = f"q{i}_deg" if name == f"q{i}" else f"q{i}"
        if other in header:
            raise MeasurementFileError(f"column {other}: leg {i}'s actuator is "
                                       f"{'prismatic: give its command in mm (column q%d)' % i if name == f'q{i}' else 'revolute: give its command in degrees (column q%d_deg)' % i}",
                                       source=src, key="line 1")
    missing = [c for c in want + ("x", "y", "z") if c not in header]
    if missing:
        raise MeasurementFileError(f"header must name {','.join(missing)}", source=src, key="line 1")
    full = any(c in header for c in POSE_COLUMNS[3:])
    if full and not all(c in header for c in POSE_COLUMNS[3:]):
        raise MeasurementFileError("give all three of roll_deg,pitch_deg,yaw_deg (full pose) or none (position "
                                   "only)", source=src, key="line 1")
    if full != (pv.kind == "pose"):
        raise MeasurementFileError("full-pose readings (roll_deg, pitch_deg, yaw_deg) but targets were given"
                                   if full else "position-only readings (no roll_deg, pitch_deg, yaw_deg): give "
                                   "the target points on the platform", source=src, key="line 1")
    if not full and pv.n_targets > 1 and "target" not in header:
        raise MeasurementFileError(f"{pv.n_targets} targets: a column 'target' must say which one each row "
                                   "measured", source=src, key="line 1")
    names = list(want) + list(POSE_COLUMNS if full else POSE_COLUMNS[:3])
    sig_names = list(POSE_SIGMAS if full else POSE_SIGMAS[:3])
    has_sig = [c in header for c in sig_names]
    if any(has_sig) and not all(has_sig):
        raise MeasurementFileError(f"give all of {','.join(sig_names)} or none", source=src, key="line 1")
    if all(has_sig):
        names += sig_names
    if not full and "target" in header:
        names.append("target")
    cols = [header.index(c) for c in names]
    labels, values = [], []
    for line, row in lines[1:]:
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) != len(header):
            raise MeasurementFileError(f"expected {len(header)} values, got {len(row)}", source=src,
                                       key=f"line {line}")
        vals = []
        for c, name in zip(cols, names):
            try:
                v = float(row[c])
            except ValueError:
                raise MeasurementFileError(f"{name}: not a number: {row[c]!r}", source=src, key=f"line {line}") \
                    from None
            if not math.isfinite(v):
                raise MeasurementFileError(f"{name}: must be finite, got {row[c]!r}", source=src, key=f"line {line}")
            if name.startswith("sigma") and v <= 0:
                raise MeasurementFileError(f"{name} must be positive, got {row[c]!r}", source=src, key=f"line {line}")
            if name == "target" and (v != int(v) or not 1 <= v <= pv.n_targets):
                raise MeasurementFileError(f"target must be one of 1..{pv.n_targets} (the targets given), got "
                                           f"{row[c]!r}", source=src, key=f"line {line}")
            vals.append(v)
        labels.append(row[header.index("point")].strip() if "point" in header else str(line - 1))
        values.append(vals)
    if not values:
        raise MeasurementFileError("no data rows", source=src)
    arr = np.array(values)
    n = len(want)
    kinds = np.array([k == "R" for k in pv.robot.actuated_kinds])
    commands = np.where(kinds, np.radians(arr[:, :n]), arr[:, :n])
    k = 6 if full else 3
    measured = arr[:, n:n + k].copy()
    if full:
        measured[:, 3:] = euler_xyz_to_rotvec(measured[:, 3:], degrees=True)
    if all(has_sig):
        sig = arr[:, n + k:n + 2 * k].copy()
        if full:
            sig[:, 3:] = np.radians(sig[:, 3:])
    else:
        sig = np.tile([DEFAULT_SIGMA_MM] * 3 + [DEFAULT_SIGMA_RAD] * 3, (len(arr), 1))[:, :k]
    target = (arr[:, -1].astype(int) - 1) if (not full and "target" in header) else np.zeros(len(arr), dtype=int)
    return SpatialCalibrationData(tuple(labels), commands, measured, sig, target, src)
