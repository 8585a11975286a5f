"""Measurement files of the push protocol (paper Sec. 5.2): the :class:`Measurements` data and its CSV format.

Protocol (Sec. 5.2)
-------------------
The actuators are locked at a grid point ``(i, j)`` of the workspace and the
moving platform is pushed gently both ways along x (``+x``, ``-x``), along y
(``+y``, ``-y``) and in rotation about z (``+r``, ``-r``); a camera reads the
pose after each push. Each push takes up the joint clearances in one
direction, so the six readings scatter inside the set of poses the
clearances allow.

Measurement file
----------------
A CSV file, one row per reading, with exactly the columns::

    point,x_nom,y_nom,phi_nom_deg,push,x,y,phi_deg

``point`` is a label; ``x_nom, y_nom, phi_nom_deg`` the commanded pose (mm,
mm, deg), identical on the six rows of a point; ``push`` one of
:data:`PUSHES`; ``x, y, phi_deg`` the reading (mm, mm, deg). Every point
needs each of the six pushes exactly once. :func:`load_measurements` refuses,
with a :class:`~pmaccuracy.errors.MeasurementFileError` naming the file and
the line, any other header, missing or repeated pushes, non-numeric or
non-finite values, a nominal pose that changes within a point, and readings
further than :data:`MAX_DEVIATION_MM` from their nominal position or
:data:`MAX_DEVIATION_DEG` from their nominal orientation (a reading in metres,
inches or radians). No row is ever skipped, except wholly blank lines.

Units: mm and rad in the arrays; mm and degrees in the files.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._textfile import read_csv
from ..errors import ConfigError, MeasurementFileError
from ..model import plausibility

#: Push directions, in the order of the readings' second axis.
PUSHES = ("+x", "-x", "+y", "-y", "+r", "-r")
#: Push axes t of Eq. 23d; readings ``2k`` and ``2k + 1`` are ``+t`` and ``-t``.
PUSH_AXES = ("x", "y", "r")
#: Header of a measurement CSV file.
CSV_COLUMNS = ("point", "x_nom", "y_nom", "phi_nom_deg", "push", "x", "y", "phi_deg")
#: A reading further than this from its nominal position (mm) is refused as a unit error.
MAX_DEVIATION_MM = 5.0
#: A reading further than this from its nominal orientation (deg) is refused as a unit error.
MAX_DEVIATION_DEG = 5.0
#: Rows of one point must repeat the nominal pose to within this (mm and deg).
NOMINAL_TOLERANCE = 1e-6
#: Accuracy of the paper's camera (Sec. 5): 0.01 mm in position, 0.01 deg in orientation.
DEFAULT_ACCURACY_MM = 0.01
DEFAULT_ACCURACY_DEG = 0.01


def _wrap_deg(angle: np.ndarray | float) -> np.ndarray:
    """Angles (deg) wrapped to [-180, 180)."""
    return (np.asarray(angle, dtype=float) + 180.0) % 360.0 - 180.0


def _nominal_deg(phi: np.ndarray | float) -> np.ndarray:
    """Nominal orientations rad -> deg, rounded to 1e-12 deg so that 30 deg does not print as 29.999999999999996."""
    return np.round(np.degrees(phi), 12)


def _frozen(arr: np.ndarray) -> np.ndarray:
    arr = np.array(arr)
    arr.setflags(write=False)
    return arr


# ============================================================================ data
@dataclass(frozen=True, eq=False)
class Measurements:
    """Readings of the push protocol at ``n`` points (Sec. 5.2).

    Attributes
    ----------
    points : ``(n,)`` str, point labels (order of first appearance in the file)
    nominal : ``(n, 3)`` commanded poses ``[x mm, y mm, phi rad]``
    readings : ``(n, 6, 3)`` measured poses ``[x mm, y mm, phi rad]`` in push order
        :data:`PUSHES` (``+x, -x, +y, -y, +r, -r``). An orientation reading is
        stored as ``phi_nom + wrap(phi - phi_nom)``, so a point near +-180 deg
        never shows a spurious 360 deg range.
    source : where the data came from (a file path or a description)
    lines : ``(n, 6)`` int, line of each reading in the source file (0 when not from a file)
    """

    points: np.ndarray
    nominal: np.ndarray
    readings: np.ndarray
    source: str = "<memory>"
    lines: np.ndarray | None = None

    def __post_init__(self) -> None:
        points = np.asarray(self.points).astype(str)
        nominal = np.asarray(self.nominal, dtype=float)
        readings = np.asarray(self.readings, dtype=float)
        n = points.shape[0] if points.ndim == 1 else -1
        if points.ndim != 1 or nominal.shape != (n, 3) or readings.shape != (n, len(PUSHES), 3):
            raise ConfigError(f"expected points (n,), nominal (n, 3) and readings (n, 6, 3); got {points.shape}, "
                              f"{nominal.shape} and {readings.shape}", source=self.source)
        if not (np.all(np.isfinite(nominal)) and np.all(np.isfinite(readings))):
            raise ConfigError("poses must be finite", source=self.source)
        lines = np.zeros((n, len(PUSHES)), dtype=int) if self.lines is None else np.asarray(self.lines, dtype=int)
        object.__setattr__(self, "points", _frozen(points))
        object.__setattr__(self, "nominal", _frozen(nominal))
        object.__setattr__(self, "readings", _frozen(readings))
        object.__setattr__(self, "lines", _frozen(lines))

    def __len__(self) -> int:
        return int(self.points.shape[0])

    @property
    def phi_nom_deg(self) -> np.ndarray:
        """Nominal orientations ``(n,)`` in degrees (rounded to 1e-12 deg)."""
        return _nominal_deg(self.nominal[:, 2])

    def subset(self, index: np.ndarray | Sequence[int], source: str | None = None) -> "Measurements":
        """The points selected by an integer or boolean index."""
        index = np.asarray(index)
        return Measurements(self.points[index], self.nominal[index], self.readings[index],
                            source=source or self.source, lines=self.lines[index])

    def by_orientation(self, decimals: int = 6) -> dict[float, "Measurements"]:
        """Split into constant-orientation datasets, keyed by nominal phi in degrees (rounded to ``decimals``)."""
        keys = np.round(self.phi_nom_deg, decimals)
        return {float(k): self.subset(np.flatnonzero(keys == k), source=f"{self.source} (phi = {k:g} deg)")
                for k in dict.fromkeys(keys.tolist())}

    def line_of(self, index: int) -> str:
        """``"line N"`` of a point's first reading, or ``"point LABEL"`` when not from a file."""
        line = int(self.lines[index].min()) if self.lines.size else 0
        return f"point {self.points[index]} (line {line})" if line > 0 else f"point {self.points[index]}"


def _fail(path: str, message: str, line: int | None = None) -> MeasurementFileError:
    return MeasurementFileError(message, source=path, key=None if line is None else f"line {line}")


def _parse_float(text: str, column: str, path: str, line: int) -> float:
    try:
        value = float(text)
    except ValueError:
        raise _fail(path, f"column {column}: not a number: {text!r}", line) from None
    if not math.isfinite(value):
        raise _fail(path, f"column {column}: not finite: {text!r}", line)
    return value


def load_measurements(path: str | Path, *, max_deviation_mm: float = MAX_DEVIATION_MM,
                      max_deviation_deg: float = MAX_DEVIATION_DEG) -> Measurements:
    """Read and validate a measurement CSV file (format in the module docstring).

    Parameters
    ----------
    path : the CSV file (UTF-8, a byte-order mark is accepted)
    max_deviation_mm, max_deviation_deg : largest plausible distance of a reading
        from its nominal position (mm) and orientation (deg); clearance errors are
        tenths of a millimetre and of a degree, so anything beyond is taken as a
        unit error (metres, inches, radians) or a mislabelled point.

    Returns
    -------
    :class:`Measurements` with points in order of first appearance.

    Raises
    ------
    MeasurementFileError : naming the file and the line (or the point) of the first problem.
    """
    src = str(path)
    rows = list(_read_rows(read_csv(path, MeasurementFileError), src))
    if not rows:
        raise _fail(src, "no readings: the file has a header but no data rows")

    order: dict[str, int] = {}          # label -> index, in order of first appearance
    nominal: list[list[float]] = []     # per point: [x_nom, y_nom, phi_nom_deg]
    first_line: list[int] = []
    blocks_r: list[np.ndarray] = []     # per point: (6, 3) readings [mm, mm, deg]
    blocks_l: list[np.ndarray] = []     # per point: (6,) line numbers, 0 = not seen yet
    for line, label, nom, push, reading in rows:
        if label not in order:
            order[label] = len(order)
            nominal.append(nom)
            first_line.append(line)
            blocks_r.append(np.full((len(PUSHES), 3), np.nan))
            blocks_l.append(np.zeros(len(PUSHES), dtype=int))
        k = order[label]
        ref = nominal[k]
        if (abs(nom[0] - ref[0]) > NOMINAL_TOLERANCE or abs(nom[1] - ref[1]) > NOMINAL_TOLERANCE
                or abs(_wrap_deg(nom[2] - ref[2])) > NOMINAL_TOLERANCE):
            raise _fail(src, f"point {label}: nominal pose ({nom[0]:g}, {nom[1]:g}, {nom[2]:g} deg) differs from "
                             f"({ref[0]:g}, {ref[1]:g}, {ref[2]:g} deg) on line {first_line[k]}", line)
        j = PUSHES.index(push)
        if blocks_l[k][j]:
            raise _fail(src, f"point {label}: push {push} repeated (already on line {blocks_l[k][j]})", line)
        blocks_l[k][j] = line
        blocks_r[k][j] = reading
    for k, label in enumerate(order):
        missing = [p for p, ln in zip(PUSHES, blocks_l[k]) if not ln]
        if missing:
            raise _fail(src, f"point {label}: missing push(es) "
                             f"{', '.join(missing)}; every point needs {', '.join(PUSHES)}", first_line[k])
    readings = np.stack(blocks_r)
    lines = np.stack(blocks_l)
    nominal_arr = np.array(nominal, dtype=float)

    # Units: distance of every reading from its nominal pose.
    dpos = np.hypot(readings[..., 0] - nominal_arr[:, None, 0], readings[..., 1] - nominal_arr[:, None, 1])
    dang = np.abs(_wrap_deg(readings[..., 2] - nominal_arr[:, None, 2]))
    for bad, what in ((dpos > max_deviation_mm, "position"), (dang > max_deviation_deg, "orientation")):
        if np.any(bad):
            k, j = np.argwhere(bad)[0]
            label = list(order)[k]
            if what == "position":
                msg = (f"point {label}, push {PUSHES[j]}: reading ({readings[k, j, 0]:g}, {readings[k, j, 1]:g}) is "
                       f"{dpos[k, j]:.4g} mm from the nominal position ({nominal_arr[k, 0]:g}, {nominal_arr[k, 1]:g}), "
                       f"more than {max_deviation_mm:g} mm: wrong units (x, y must be in mm) or wrong point")
            else:
                msg = (f"point {label}, push {PUSHES[j]}: orientation {readings[k, j, 2]:g} deg is "
                       f"{dang[k, j]:.4g} deg from the nominal {nominal_arr[k, 2]:g} deg, more than {max_deviation_deg:g} deg: wrong "
                       f"units (phi_deg and phi_nom_deg must be in degrees, not radians) or wrong point")
            raise _fail(src, msg, int(lines[k, j]))


    plausibility.warn(plausibility.orientation_messages(nominal_arr[:, 2], f"{src}: column phi_nom_deg"))
    nominal_rad = nominal_arr.copy()
    nominal_rad[:, 2] = np.radians(nominal_arr[:, 2])
    readings_rad = readings.copy()
    readings_rad[..., 2] = nominal_rad[:, None, 2] + np.radians(_wrap_deg(readings[..., 2] - nominal_arr[:, None, 2]))
    return Measurements(points=np.array(list(order), dtype=str), nominal=nominal_rad, readings=readings_rad,
                        source=src, lines=lines)


def _read_rows(lines: list[tuple[int, list[str]]], src: str):
    """Yield ``(line, label, [x_nom, y_nom, phi_nom_deg], push, [x, y, phi_deg])`` for every non-blank row of
    the file's rows ``(line, cells)`` (:func:`pmaccuracy._textfile.read_csv`)."""
    if not lines:
        raise _fail(src, f"empty file: expected the header {','.join(CSV_COLUMNS)}", 1)
    header = lines[0][1]
    if [h.strip() for h in header] != list(CSV_COLUMNS):
        raise _fail(src, f"header must be {','.join(CSV_COLUMNS)!r}, got {','.join(header)!r}", 1)
    for line, row in lines[1:]:
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) != len(CSV_COLUMNS):
            raise _fail(src, f"expected {len(CSV_COLUMNS)} values ({','.join(CSV_COLUMNS)}), got {len(row)}", line)
        cells = [c.strip() for c in row]
        label, push = cells[0], cells[4]
        if not label:
            raise _fail(src, "empty point label", line)
        if push not in PUSHES:
            raise _fail(src, f"column push: {push!r} is not one of {', '.join(PUSHES)}", line)
        values = [_parse_float(cells[i], CSV_COLUMNS[i], src, line) for i in (1, 2, 3, 5, 6, 7)]
        yield line, label, values[:3], push, values[3:]


def write_measurements(path: str | Path, measurements: Measurements) -> Path:
    """Write measurements as CSV (:data:`CSV_COLUMNS`; mm and deg), one row per reading, point by point.

    Numbers are written with Python's shortest round-trip representation, so
    :func:`load_measurements` reads back the same millimetres exactly (angles to
    the rounding of one deg -> rad conversion). Parent folders are created.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    nom_deg = measurements.nominal.copy()
    nom_deg[:, 2] = _nominal_deg(nom_deg[:, 2])
    read_deg = measurements.readings.copy()
    read_deg[..., 2] = np.degrees(read_deg[..., 2])
    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(CSV_COLUMNS)
        for k, label in enumerate(measurements.points):
            nom = [repr(float(v)) for v in nom_deg[k]]
            for j, push in enumerate(PUSHES):
                writer.writerow([label, *nom, push, *(repr(float(v)) for v in read_deg[k, j])])
    return path

