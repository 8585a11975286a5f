"""Experimental validation of the clearance model (paper Sec. 5.2 and 6, Eq. 23-24, Figs. 9-15).

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

Measured errors (Eq. 23a-d)
---------------------------
With ``(x, y, phi)_{+t}`` and ``(x, y, phi)_{-t}`` the readings of the pushes
along ``t in {x, y, r}``::

    dx   = max{x_{+-t}} - min{x_{+-t}}                    (Eq. 23a, over all six readings)
    dy   = max{y_{+-t}} - min{y_{+-t}}                    (Eq. 23b)
    dphi = max{phi_{+-t}} - min{phi_{+-t}}                (Eq. 23c)
    dp   = max_t |(x, y)_{+t} - (x, y)_{-t}|              (Eq. 23d)

Comparing with the model: two conventions
-----------------------------------------
The model's worst case (Eq. 21-22, :func:`pmaccuracy.bounds.max_pose_errors`)
is one-sided: the error of x lies in ``[-dx_max, +dx_max]``, a set symmetric
about the nominal pose. A measured *range* (max - min) therefore spans up to
``2 dx_max``, and a distance between two readings is bounded by the diameter
of the set of position errors, ``2 dp_max`` (for a centrally symmetric set
the diameter is twice the largest radius). The paper nevertheless compares
the measured ranges with ``dzeta_max`` directly; both are computed here:

* ``rmsd`` (the paper's convention, Sec. 6): ``sqrt(mean((d_meas - d_max)^2))``;
* ``rmsd_width_consistent``: ``sqrt(mean((d_meas - 2 d_max)^2))``.

Other statistics: sample standard deviations of the measured errors (Sec. 6.3,
``ddof = 1``), the ISO 9283 accuracy ``AP_p = dp, AP_phi = dphi`` (Eq. 24) and
the regression band of Fig. 15: the share of predictions inside the band
``d_meas +- 2 A_meas`` (``A_meas`` the accuracy of the camera, 0.01 mm and
0.01 deg in Sec. 5).

Virtual experiment
------------------
:func:`simulate_readings` plays the protocol on a simulated rig (see its
docstring); :func:`virtual_experiment_section` runs it end to end for a report.

Units: mm and rad in the arrays; degrees in files, figures and JSON under names
ending in ``_deg``.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from . import figures
from .bounds import PoseErrorBounds, first_order_pose_error, max_pose_errors
from .clearances import ClearanceDisplacement, ClearanceSet
from .sources import ErrorSources, load_clearances
from .document import Document
from .error_model import pose_state
from .errors import ConfigError, MeasurementFileError, OutsideJointLimitsError
from .geometry import Manipulator
from .maps import error_map
from .kinematics import DEFAULT_MAX_CONDITION, as_poses, check_within_limits, inverse_kinematics, regular_mask

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
#: Compared quantities and their units, in output order (``dphi`` in degrees outside the arrays).
QUANTITIES = ("dx", "dy", "dp", "dphi_deg")
UNITS = {"dx": "mm", "dy": "mm", "dp": "mm", "dphi_deg": "deg"}
LABELS = {"dx": r"$\delta x$", "dy": r"$\delta y$", "dp": r"$\delta p$", "dphi_deg": r"$\delta\phi$"}
#: Reading models of the virtual experiment.
MODELS = ("exact", "first_order")


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
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            rows = list(_read_rows(csv.reader(fh), src))
    except FileNotFoundError:
        raise _fail(src, "no such file") from None
    except IsADirectoryError:
        raise _fail(src, "is a directory, not a CSV file") from None
    except UnicodeDecodeError:
        raise _fail(src, "not a UTF-8 text file") from None
    except csv.Error as exc:
        raise _fail(src, f"malformed CSV: {exc}") from None
    except OSError as exc:
        raise _fail(src, exc.strerror or str(exc)) from None
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

    nominal_rad = nominal_arr.copy()
    nominal_rad[:, 2] = np.radians(nominal_arr[:, 2])
    readings_rad = readings.copy()
    readings_rad[..., 2] = nominal_rad[:, None, 2] + np.radians(_wrap_deg(readings[..., 2] - nominal_arr[:, None, 2]))
    return Measurements(points=np.array(list(order), dtype=str), nominal=nominal_rad, readings=readings_rad,
                        source=src, lines=lines)


def _read_rows(reader: Any, src: str):
    """Yield ``(line, label, [x_nom, y_nom, phi_nom_deg], push, [x, y, phi_deg])`` for every non-blank row."""
    header = next(reader, None)
    if header is None:
        raise _fail(src, f"empty file: expected the header {','.join(CSV_COLUMNS)}", 1)
    if [h.strip() for h in header] != list(CSV_COLUMNS):
        raise _fail(src, f"header must be {','.join(CSV_COLUMNS)!r}, got {','.join(header)!r}", 1)
    for row in reader:
        line = reader.line_num
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


# ============================================================================ Eq. 23
@dataclass(frozen=True)
class MeasuredErrors:
    """Measured pose errors of Eq. 23a-d at ``n`` points.

    dx, dy : ``(n,)`` mm, ranges of the six x and y readings (Eq. 23a, 23b)
    dphi : ``(n,)`` rad, range of the six orientation readings (Eq. 23c)
    dp : ``(n,)`` mm, the largest of ``dp_axes`` (Eq. 23d)
    dp_axes : ``(n, 3)`` mm, ``|(x, y)_{+t} - (x, y)_{-t}|`` for t = x, y, r
    """

    dx: np.ndarray
    dy: np.ndarray
    dphi: np.ndarray
    dp: np.ndarray
    dp_axes: np.ndarray

    @property
    def dphi_deg(self) -> np.ndarray:
        """``dphi`` in degrees, ``(n,)``."""
        return np.degrees(self.dphi)

    def values(self) -> dict[str, np.ndarray]:
        """``{"dx", "dy", "dp" (mm), "dphi_deg" (deg)}``, each ``(n,)``."""
        return {"dx": self.dx, "dy": self.dy, "dp": self.dp, "dphi_deg": self.dphi_deg}


def measured_errors(measurements: Measurements | np.ndarray) -> MeasuredErrors:
    """Eq. 23a-d from the readings ``(n, 6, 3)`` [mm, mm, rad] in push order :data:`PUSHES`.

    ``dx, dy, dphi`` are the max - min of the six readings of x, y and phi (the
    paper's ``max{.}-min{.}`` over all ``+t`` and ``-t`` readings); ``dp`` is the
    largest distance between the ``+t`` and ``-t`` positions of one push axis t.
    """
    readings = measurements.readings if isinstance(measurements, Measurements) else np.asarray(measurements, float)
    span = np.ptp(readings, axis=1)  # (n, 3)
    diff = readings[:, 0::2, :2] - readings[:, 1::2, :2]  # (n, 3 axes, 2): +t minus -t
    dp_axes = np.hypot(diff[..., 0], diff[..., 1])
    return MeasuredErrors(dx=span[:, 0], dy=span[:, 1], dphi=span[:, 2], dp=np.max(dp_axes, axis=1), dp_axes=dp_axes)


def _predicted_values(bounds: PoseErrorBounds) -> dict[str, np.ndarray]:
    return {"dx": np.asarray(bounds.dx_max), "dy": np.asarray(bounds.dy_max), "dp": np.asarray(bounds.dp_max),
            "dphi_deg": np.asarray(bounds.dphi_max_deg)}


def rmsd(measured: np.ndarray, predicted: np.ndarray) -> float:
    """Root-mean-square deviation ``sqrt(mean((measured - predicted)^2))`` over points (same units)."""
    diff = np.asarray(measured, float) - np.asarray(predicted, float)
    return float(np.sqrt(np.mean(diff ** 2))) if diff.size else float("nan")


# ============================================================================ comparison
@dataclass(frozen=True, eq=False)
class Comparison:
    """Measured errors (Eq. 23) against the model's maxima (Eq. 21-22) at the same nominal poses.

    Attributes
    ----------
    measurements : the readings
    measured : Eq. 23 at each point
    predicted : :func:`~pmaccuracy.bounds.max_pose_errors` at the nominal poses
    robot, clearances : names of the model used
    accuracy_mm, accuracy_deg : ``A_meas`` of the camera (Fig. 15 band ``+- 2 A_meas``)

    ``factor`` arguments select the convention: 1 compares measured ranges with
    the one-sided maxima directly (the paper, Sec. 6), 2 with the full widths
    ``2 d_max`` of the error set (module docstring).
    """

    measurements: Measurements
    measured: MeasuredErrors
    predicted: PoseErrorBounds
    robot: str
    clearances: str
    accuracy_mm: float = DEFAULT_ACCURACY_MM
    accuracy_deg: float = DEFAULT_ACCURACY_DEG

    def measured_values(self) -> dict[str, np.ndarray]:
        """Measured dx, dy, dp (mm) and dphi_deg (deg), each ``(n,)``."""
        return self.measured.values()

    def predicted_values(self, factor: float = 1.0) -> dict[str, np.ndarray]:
        """``factor`` x the predicted maxima: dx, dy, dp (mm), dphi_deg (deg), each ``(n,)``."""
        return {k: factor * v for k, v in _predicted_values(self.predicted).items()}

    def rmsd(self, factor: float = 1.0) -> dict[str, float]:
        """RMSD between measured errors and ``factor`` x predicted maxima (mm; ``dphi_deg`` in deg)."""
        meas, pred = self.measured_values(), self.predicted_values(factor)
        return {q: rmsd(meas[q], pred[q]) for q in QUANTITIES}

    def sample_std(self) -> dict[str, float]:
        """Sample standard deviation (``ddof = 1``) of each measured error over the points (Sec. 6.3)."""
        n = len(self.measurements)
        return {q: float(np.std(v, ddof=1)) if n > 1 else float("nan") for q, v in self.measured_values().items()}

    def mean(self) -> dict[str, float]:
        """Mean of each measured error over the points (mm, deg)."""
        return {q: float(np.mean(v)) for q, v in self.measured_values().items()}

    def accuracy(self) -> dict[str, list[float]]:
        """ISO 9283 accuracy (Eq. 24): ``AP_p = dp`` (mm) and ``AP_phi = dphi`` (deg), ``[min, max]`` over points."""
        ap_p, ap_phi = self.measured.dp, self.measured.dphi_deg
        return {"position": [float(ap_p.min()), float(ap_p.max())],
                "orientation_deg": [float(ap_phi.min()), float(ap_phi.max())]}

    def band_halfwidths(self) -> dict[str, float]:
        """``2 A_meas`` of each quantity (mm; deg for dphi_deg): the half-width of the Fig. 15 band."""
        return {q: 2 * (self.accuracy_deg if q == "dphi_deg" else self.accuracy_mm) for q in QUANTITIES}

    def band(self, factor: float = 1.0) -> dict[str, dict[str, float]]:
        """Regression-band check of Fig. 15 for ``factor`` x the predictions.

        For each quantity: ``share`` of points with ``|factor d_max - d_meas| <= 2 A_meas``
        and ``max_excess``, the largest distance of a prediction outside the band (0 when all inside).
        """
        meas, pred, half = self.measured_values(), self.predicted_values(factor), self.band_halfwidths()
        out = {}
        for q in QUANTITIES:
            gap = np.abs(pred[q] - meas[q]) - half[q]
            out[q] = {"share": float(np.mean(gap <= 1e-12)), "max_excess": float(max(gap.max(), 0.0))}
        return out

    def regression(self, factor: float = 1.0) -> dict[str, dict[str, float]]:
        """Least-squares line ``factor d_max = slope d_meas + intercept`` and Pearson ``r`` per quantity.

        NaN where a quantity does not vary over the points (e.g. dy_max of the
        Aalborg robot at constant orientation), as a line is then undefined.
        """
        meas, pred = self.measured_values(), self.predicted_values(factor)
        out = {}
        for q in QUANTITIES:
            x, y = meas[q], pred[q]
            sx, sy = float(np.std(x)), float(np.std(y))
            if x.size >= 2 and sx > 1e-12 * max(float(np.max(np.abs(x))), 1e-300):
                slope, intercept = np.polyfit(x, y, 1)
            else:
                slope, intercept = float("nan"), float("nan")
            r = float(np.corrcoef(x, y)[0, 1]) if sx > 0 and sy > 1e-12 * max(float(np.max(np.abs(y))), 1e-300) \
                else float("nan")
            out[q] = {"slope": float(slope), "intercept": float(intercept), "r": r}
        return out

    def records(self) -> list[dict[str, Any]]:
        """One dict per point: nominal pose (mm, deg), measured errors and predicted maxima (mm, deg)."""
        meas, pred = self.measured_values(), self.predicted_values()
        nominal = self.measurements.nominal
        return [{"point": str(self.measurements.points[k]), "x_nom": float(nominal[k, 0]),
                 "y_nom": float(nominal[k, 1]), "phi_nom_deg": float(_nominal_deg(nominal[k, 2])),
                 "dx": float(meas["dx"][k]), "dy": float(meas["dy"][k]), "dphi_deg": float(meas["dphi_deg"][k]),
                 "dp": float(meas["dp"][k]), "dx_max": float(pred["dx"][k]), "dy_max": float(pred["dy"][k]),
                 "dphi_max_deg": float(pred["dphi_deg"][k]), "dp_max": float(pred["dp"][k])}
                for k in range(len(self.measurements))]

    def subset(self, index: np.ndarray) -> "Comparison":
        """The comparison restricted to some points."""
        index = np.asarray(index)
        m = self.measured
        p = self.predicted
        return Comparison(
            measurements=self.measurements.subset(index),
            measured=MeasuredErrors(m.dx[index], m.dy[index], m.dphi[index], m.dp[index], m.dp_axes[index]),
            predicted=PoseErrorBounds(poses=p.poses[index], dx_max=p.dx_max[index], dy_max=p.dy_max[index],
                                      dphi_max=p.dphi_max[index], dp_max=p.dp_max[index]),
            robot=self.robot, clearances=self.clearances, accuracy_mm=self.accuracy_mm,
            accuracy_deg=self.accuracy_deg)

    def by_orientation(self, decimals: int = 6) -> dict[float, "Comparison"]:
        """Split into constant-orientation comparisons keyed by nominal phi (deg), as in Figs. 9-12."""
        keys = np.round(self.measurements.phi_nom_deg, decimals)
        return {float(k): self.subset(np.flatnonzero(keys == k)) for k in dict.fromkeys(keys.tolist())}

    def _statistics(self) -> dict[str, Any]:
        return {"n_points": len(self.measurements), "rmsd": self.rmsd(1.0), "rmsd_width_consistent": self.rmsd(2.0),
                "mean": self.mean(), "ssd": self.sample_std(), "accuracy_iso9283": self.accuracy(),
                "band": {"halfwidth": self.band_halfwidths(), "direct": self.band(1.0),
                         "width_consistent": self.band(2.0)},
                "regression": {"direct": self.regression(1.0), "width_consistent": self.regression(2.0)}}

    def summary(self) -> dict[str, Any]:
        """Everything as JSON-ready Python values (mm and deg); the ``compare`` command's output.

        Keys: ``source, robot, clearances, accuracy_mm, accuracy_deg, conventions,
        points`` (see :meth:`records`), ``n_points, rmsd`` (paper convention),
        ``rmsd_width_consistent, mean, ssd, accuracy_iso9283, band, regression``
        and ``orientations`` (the same statistics per nominal orientation).
        """
        out: dict[str, Any] = {
            "source": self.measurements.source, "robot": self.robot, "clearances": self.clearances,
            "accuracy_mm": self.accuracy_mm, "accuracy_deg": self.accuracy_deg,
            "conventions": {
                "rmsd": "measured range (Eq. 23) minus the predicted one-sided maximum (Eq. 21-22), as in the paper",
                "rmsd_width_consistent": "measured range minus twice the predicted maximum (the full width of the "
                                         "symmetric error set; 2 dp_max bounds the +t/-t distance of Eq. 23d)"},
            "points": self.records()}
        out.update(self._statistics())
        out["orientations"] = [{"phi_deg": phi, **sub._statistics()} for phi, sub in self.by_orientation().items()]
        return out


#: Nominal poses of a measurement file may lie this far outside the joint ranges (mm): the
#: actuators' encoder accuracy (5 um, Sec. 2). A grid printed with finite precision can put
#: boundary points a fraction of a micrometre outside (e.g. y = -14.02 mm at phi = 30 deg).
NOMINAL_LIMIT_TOLERANCE_MM = 0.005


def require_nominal_within_limits(robot: Manipulator, measurements: Measurements,
                                  tol: float = NOMINAL_LIMIT_TOLERANCE_MM) -> None:
    """Raise :class:`OutsideJointLimitsError` naming the first point whose nominal pose is outside the joint
    ranges by more than ``tol`` mm."""
    ik = inverse_kinematics(robot, measurements.nominal, tol)
    bad = np.flatnonzero(~np.asarray(ik.within_limits))
    if bad.size:
        k = int(bad[0])
        pose = measurements.nominal[k:k + 1]
        try:
            check_within_limits(robot, pose, inverse_kinematics(robot, pose, tol), tol)
        except OutsideJointLimitsError as exc:
            raise OutsideJointLimitsError(f"{measurements.source}: {measurements.line_of(k)}: nominal {exc}") from None


def compare(robot: Manipulator | str, clearances: ClearanceSet | str, measurements: Measurements | str | Path, *,
            accuracy_mm: float = DEFAULT_ACCURACY_MM, accuracy_deg: float = DEFAULT_ACCURACY_DEG,
            max_condition: float = DEFAULT_MAX_CONDITION,
            limit_tolerance_mm: float = NOMINAL_LIMIT_TOLERANCE_MM) -> Comparison:
    """Compare measurements with the model at the same nominal poses.

    Parameters
    ----------
    robot, clearances : objects, preset names or TOML paths
    measurements : a :class:`Measurements` or the path of a measurement CSV file
    accuracy_mm, accuracy_deg : camera accuracy ``A_meas`` (Sec. 5), > 0
    limit_tolerance_mm : how far outside the joint ranges a nominal pose may lie
        (default: the 5 um encoder accuracy); the model is evaluated there as is

    Raises
    ------
    MeasurementFileError : malformed file
    OutsideJointLimitsError : a nominal pose outside the joint ranges (names the point and line)
    SingularPoseError : a nominal pose at or near det A = 0
    """
    robot = Manipulator.load(robot)
    clearances = load_clearances(clearances, robot)
    if not isinstance(measurements, Measurements):
        measurements = load_measurements(measurements)
    for name, value in (("accuracy_mm", accuracy_mm), ("accuracy_deg", accuracy_deg)):
        if not (math.isfinite(value) and value > 0):
            raise ConfigError(f"must be a positive number, got {value}", key=name)
    if not (math.isfinite(limit_tolerance_mm) and limit_tolerance_mm >= 0):
        raise ConfigError(f"must be a length >= 0, got {limit_tolerance_mm}", key="limit_tolerance_mm")
    require_nominal_within_limits(robot, measurements, limit_tolerance_mm)
    predicted = max_pose_errors(robot, clearances, measurements.nominal, allow_outside=True,
                                max_condition=max_condition)
    return Comparison(measurements=measurements, measured=measured_errors(measurements), predicted=predicted,
                      robot=robot.name, clearances=clearances.name, accuracy_mm=float(accuracy_mm),
                      accuracy_deg=float(accuracy_deg))


# ============================================================================ virtual experiment
def opposite(displacement: ClearanceDisplacement) -> ClearanceDisplacement:
    """The mirror configuration: tilts and shifts negated, revolute offset turned by pi.

    The clearance sets (Eq. 16-18) are symmetric, so it is feasible, and its
    first-order pose error (Eq. 19) is exactly the negative of the original's.
    """
    return ClearanceDisplacement(tau_b=-displacement.tau_b, sigma_g=-displacement.sigma_g,
                                 tau_g=-displacement.tau_g, rho=displacement.rho, varphi=displacement.varphi + np.pi)


def push_configurations(bounds: PoseErrorBounds, take_up: float = 1.0) -> tuple[ClearanceDisplacement, ...]:
    """Clearance displacements of the six pushes :data:`PUSHES`, fields ``(n, 3)``.

    A push along ``+x`` drives every clearance to the configuration moving the
    platform furthest in +x, i.e. the argmax of Eq. 21 for x
    (``bounds.worst["dx"]``, from ``max_pose_errors(..., details=True)``); ``-x``
    to its mirror (:func:`opposite`); likewise ``+-y`` with ``worst["dy"]`` and
    ``+-r`` with ``worst["dphi"]``. ``take_up`` in [0, 1] scales every
    displacement (a push that only partly takes up the clearances).
    """
    if not bounds.worst:
        raise ValueError("push_configurations needs max_pose_errors(..., details=True)")
    out = []
    for q in ("dx", "dy", "dphi"):
        worst = bounds.worst[q].scaled(take_up)
        out += [worst, opposite(worst)]
    return tuple(out)


def _check_simulation(take_up: float, noise_mm: float, noise_deg: float, model: str) -> None:
    if not (math.isfinite(take_up) and 0.0 <= take_up <= 1.0):
        raise ConfigError(f"must be a fraction in [0, 1] (share of the clearance a push takes up), got {take_up:g}",
                          key="take_up")
    for name, value in (("noise_mm", noise_mm), ("noise_deg", noise_deg)):
        if not (math.isfinite(value) and value >= 0.0):
            raise ConfigError(f"must be a finite standard deviation >= 0, got {value:g}", key=name)
    if model not in MODELS:
        raise ConfigError(f"unknown reading model {model!r} (choose from {', '.join(MODELS)})", key="model")


def simulate_readings(robot: Manipulator | str, clearances: ClearanceSet | str, poses: np.ndarray, *,
                      take_up: float = 1.0, noise_mm: float = DEFAULT_ACCURACY_MM,
                      noise_deg: float = DEFAULT_ACCURACY_DEG, model: str = "exact",
                      seed: int | np.random.Generator | None = None, labels: Sequence[str] | None = None,
                      source: str = "virtual experiment") -> Measurements:
    """Play the push protocol of Sec. 5.2 on a simulated rig at nominal poses ``(n, 3)`` [mm, mm, rad].

    For each pose and push (:func:`push_configurations`) the clearances sit in
    the worst-case configuration of that push direction, scaled by ``take_up``;
    the reading is then

    * ``model="exact"`` (default): the pose closing the perturbed loops exactly
      with the actuators locked (:func:`pmaccuracy.nonlinear.displaced_pose`).
      This is the default because it plays the role of the physical prototype:
      the rig should not share the linearization of the model it validates;
    * ``model="first_order"``: nominal pose + ``J^c_err delta^c`` (Eq. 19,
      :func:`pmaccuracy.bounds.first_order_pose_error`),

    plus independent Gaussian camera noise on every reading, standard deviations
    ``noise_mm`` on x and y and ``noise_deg`` on phi (Sec. 5: 0.01 mm, 0.01 deg),
    drawn from ``numpy.random.default_rng(seed)``.

    What to expect (derived; checked in ``tests/test_experiment.py``).
    With ``take_up = 1`` and no noise, the first-order readings of ``+x`` and
    ``-x`` are ``x_nom +- dx_max`` and every other reading lies in between (all
    are points of the symmetric error set), so the range of Eq. 23a is exactly
    ``2 dx_max``; likewise dy and dphi; ``dp = 2 max_t |e_xy(worst_t)| <= 2 dp_max``.
    The exact readings differ by second-order terms; the even ones shift ``+t``
    and ``-t`` alike and cancel in a range, so the relative difference is far
    below the clearance size (~1e-5 for the presets). With noise ``sigma``, when
    each extreme is attained by a single reading with a margin of several
    ``sigma`` over the others, ``range - 2 d_max = eps_a - eps_b ~ N(0, 2 sigma^2)``:
    the RMSD of (measured - 2 predicted) tends to ``sqrt(2) sigma``. If ``k``
    readings tie at an extreme (the Aalborg robot's ``+x`` push also attains
    ``+dphi_max``, so dphi has ``k = 2`` at both ends), that end is the maximum of
    ``k`` noises, of mean ``sigma / sqrt(pi)`` for ``k = 2`` and mean square
    ``sigma^2``, and the RMSD becomes ``sigma sqrt(2 (1 + 1/pi))`` for ``k = 2``
    at both ends.

    Parameters
    ----------
    labels : point labels (default ``"1"``, ``"2"``, ...)

    Raises
    ------
    ConfigError : take_up outside [0, 1], negative noise, unknown model
    OutsideJointLimitsError, SingularPoseError : unusable nominal poses
    """
    from .nonlinear import displaced_pose

    robot = Manipulator.load(robot)
    clearances = load_clearances(clearances, robot)
    _check_simulation(float(take_up), float(noise_mm), float(noise_deg), model)
    poses = as_poses(poses).reshape(-1, 3)
    if isinstance(clearances, ErrorSources):  # any architecture: per-joint sources
        readings = _generic_pushes(robot, clearances, poses, float(take_up), model)
    else:
        bounds = max_pose_errors(robot, clearances, poses, details=True)
        pushes = push_configurations(bounds, float(take_up))
        if model == "first_order":
            state = pose_state(robot, poses)
            readings = np.stack([poses + first_order_pose_error(robot, state, d) for d in pushes], axis=1)
        else:
            readings = np.stack([displaced_pose(robot, poses, d) for d in pushes], axis=1)
    if model != "first_order":
        # Keep phi next to the nominal value (displaced_pose wraps to (-pi, pi]).
        readings[..., 2] = poses[:, None, 2] + np.angle(np.exp(1j * (readings[..., 2] - poses[:, None, 2])))
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    sigma = np.array([noise_mm, noise_mm, math.radians(noise_deg)])
    readings = readings + rng.standard_normal(readings.shape) * sigma
    if labels is None:
        labels = [str(k + 1) for k in range(poses.shape[0])]
    return Measurements(points=np.asarray(labels, dtype=str), nominal=poses, readings=readings, source=source)


def _generic_pushes(robot: Manipulator, sources: ErrorSources, poses: np.ndarray, take_up: float,
                    model: str) -> np.ndarray:
    """Readings ``(n, 6, 3)`` of the six pushes with per-joint sources (any architecture).

    A push along ``+x`` puts every source at the extreme that moves the platform
    furthest in +x (:func:`pmaccuracy.sources.worst_configuration` with the signs
    of ``max_pose_errors(...).worst_signs["dx"]``), ``-x`` at the opposite one
    (the sets are symmetric), likewise y and the rotation; scaled by ``take_up``.
    """
    from .kinematics import inverse_kinematics
    from .nonlinear import joint_displaced_pose
    from .sources import first_order_error, worst_configuration

    bounds = max_pose_errors(robot, sources, poses)
    joints = inverse_kinematics(robot, poses).joints
    readings = []
    for q in ("dx", "dy", "dphi"):
        cfg = worst_configuration(robot, sources, joints, poses, bounds.worst_signs[q]).scaled(take_up)
        for c in (cfg, -cfg):
            if model == "first_order":
                readings.append(poses + first_order_error(robot, joints, poses, c))
            else:
                readings.append(joint_displaced_pose(robot, poses, c))
    return np.stack(readings, axis=1)


def grid_poses(robot: Manipulator, phi: float, grid: int) -> np.ndarray:
    """Nominal poses ``(m, 3)`` [mm, mm, rad] of the virtual experiment (the paper's i x j points).

    The points of a ``grid x grid`` lattice over the bounding box of the
    constant-orientation workspace at ``phi`` that lie inside it
    (:meth:`pmaccuracy.workspace.Workspace.grid`) and are not near a singularity
    (:func:`pmaccuracy.kinematics.regular_mask`), ordered by y, then x;
    coordinates rounded to 1e-10 mm.
    """
    from .workspace import constant_orientation_workspace

    if int(grid) != grid or grid < 2:
        raise ConfigError(f"the grid needs at least 2 points per axis, got {grid}", key="grid")
    x, y, inside = constant_orientation_workspace(robot, float(phi)).require_nonempty().grid(int(grid))
    X, Y = np.meshgrid(np.round(x, 10), np.round(y, 10))  # tidy -2e-14 into 0; 5e-11 mm is far below the limit slack
    poses = np.column_stack([X[inside], Y[inside], np.full(int(inside.sum()), float(phi))])
    # points on a singular curve inside the workspace (other architectures than the 3-PPR) cannot be measured
    return poses[regular_mask(robot, poses)]


def simulate_experiment(robot: Manipulator | str, clearances: ClearanceSet | str, phi: float, grid: int = 5, *,
                        take_up: float = 1.0, noise_mm: float = DEFAULT_ACCURACY_MM,
                        noise_deg: float = DEFAULT_ACCURACY_DEG, model: str = "exact",
                        seed: int | np.random.Generator | None = None) -> Measurements:
    """Virtual experiment at orientation ``phi`` (rad) on the grid points of :func:`grid_poses`.

    See :func:`simulate_readings` for the readings; write them with :func:`write_measurements`.
    """
    robot = Manipulator.load(robot)
    clearances = load_clearances(clearances, robot)
    _check_simulation(float(take_up), float(noise_mm), float(noise_deg), model)
    poses = grid_poses(robot, phi, grid)
    return simulate_readings(robot, clearances, poses, take_up=take_up, noise_mm=noise_mm, noise_deg=noise_deg,
                             model=model, seed=seed,
                             source=f"virtual experiment ({robot.name}, {clearances.name}, phi = "
                                    f"{math.degrees(phi):g} deg, {model}, take-up {take_up:g})")


# ============================================================================ figures
def plot_boxplots(datasets: Mapping[str, MeasuredErrors | Measurements], *, title: str | None = None) -> Figure:
    """Box plots of the measured errors as in Fig. 13: one panel per quantity, one box per dataset.

    ``datasets`` maps a label (e.g. ``"case 1, phi = 0"``) to measured errors or measurements.
    """
    names = list(datasets)
    values = [(d if isinstance(d, MeasuredErrors) else measured_errors(d)).values() for d in datasets.values()]
    fig = Figure(figsize=(10, 7.5))
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.08, top=0.92, wspace=0.28, hspace=0.3)  # no layout engine
    for ax, q in zip(fig.subplots(2, 2).ravel(), QUANTITIES):
        ax.boxplot([v[q] for v in values])
        ax.set_xticks(range(1, len(names) + 1))
        ax.set_xticklabels(names, rotation=15 if len(names) > 2 else 0, fontsize=8)
        ax.set_ylabel(f"measured {LABELS[q]} [{UNITS[q]}]")
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle(title or "Measured pose errors (Eq. 23), cf. paper Fig. 13")
    return fig


def plot_accuracy(measurements: Measurements | Comparison, *, title: str | None = None) -> Figure:
    """Position and orientation accuracy per point as bars (ISO 9283, Eq. 24; paper Fig. 14).

    ``AP_p = dp`` in mm and ``AP_phi = dphi`` in deg, one bar per measured point.
    """
    m = measurements.measurements if isinstance(measurements, Comparison) else measurements
    errors = measured_errors(m)
    n = len(m)
    fig = Figure(figsize=(max(6.0, min(0.28 * n + 3, 18.0)), 6))
    fig.subplots_adjust(left=0.1, right=0.98, bottom=0.13, top=0.9, hspace=0.12)
    ax_p, ax_r = fig.subplots(2, 1, sharex=True)
    pos = np.arange(n)
    ax_p.bar(pos, errors.dp, color="tab:blue")
    ax_p.set_ylabel(r"$AP_p = \delta p$ [mm]")
    ax_r.bar(pos, errors.dphi_deg, color="tab:orange")
    ax_r.set_ylabel(r"$AP_\phi = \delta\phi$ [deg]")
    ax_r.set_xticks(pos)
    ax_r.set_xticklabels(m.points, rotation=90 if n > 12 else 0, fontsize=7 if n > 24 else 9)
    ax_r.set_xlabel("measured point")
    for ax in (ax_p, ax_r):
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle(title or f"Accuracy at {n} poses (ISO 9283, Eq. 24), cf. paper Fig. 14")
    return fig


def plot_regression(comparison: Comparison, factor: float = 1.0, *, title: str | None = None) -> Figure:
    """Predicted vs measured errors with the band ``d_meas +- 2 A_meas`` (paper Fig. 15).

    One panel per quantity: points ``(d_meas, factor d_max)``, the line of
    equality with the shaded band, and the least-squares line when defined.
    """
    meas, pred = comparison.measured_values(), comparison.predicted_values(factor)
    half, band, reg = comparison.band_halfwidths(), comparison.band(factor), comparison.regression(factor)
    fig = Figure(figsize=(10, 9))
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.07, top=0.92, wspace=0.3, hspace=0.3)
    for ax, q in zip(fig.subplots(2, 2).ravel(), QUANTITIES):
        x, y = meas[q], pred[q]
        lo = float(min(x.min(), y.min())) - 2 * half[q]
        hi = float(max(x.max(), y.max())) + 2 * half[q]
        line = np.array([lo, hi])
        ax.fill_between(line, line - half[q], line + half[q], color="tab:green", alpha=0.2,
                        label=rf"$\delta_{{mea}} \pm 2A_{{mea}}$ ($\pm${half[q]:g} {UNITS[q]})")
        ax.plot(line, line, color="tab:green", lw=1)
        if math.isfinite(reg[q]["slope"]):
            ax.plot(line, reg[q]["slope"] * line + reg[q]["intercept"], "--", color="tab:red", lw=1,
                    label=f"least squares (r = {reg[q]['r']:.2f})" if math.isfinite(reg[q]["r"]) else "least squares")
        ax.scatter(x, y, s=18, color="black", zorder=3, label="points")
        ax.set_xlim(lo, hi)
        ax.set_ylim(lo, hi)
        ax.set_aspect("equal")
        pre = f"{factor:g} x " if factor != 1 else ""
        ax.set_xlabel(f"measured {LABELS[q]} [{UNITS[q]}]")
        ax.set_ylabel(f"{pre}predicted {LABELS[q]}" + r"$_{max}$" + f" [{UNITS[q]}]")
        ax.set_title(f"{100 * band[q]['share']:.0f} % inside the band")
        ax.legend(fontsize=7, loc="upper left")
    conv = "direct (paper)" if factor == 1 else f"{factor:g} x maxima (width-consistent)"
    fig.suptitle(title or f"Simulation vs measurement, {conv}, cf. paper Fig. 15")
    return fig


def plot_measured_maps(robot: Manipulator | str, clearances: ClearanceSet | str, comparison: Comparison, *,
                       grid: int = 41, scale: float = 1.0) -> dict[float, Figure]:
    """Four-panel error maps with the measured points overlaid (Figs. 9-12), one figure per orientation.

    Calls :func:`pmaccuracy.maps.error_map` at each nominal orientation of the
    measurements and :func:`pmaccuracy.figures.plot_error_map` with the measured
    errors; ``scale`` multiplies the drawn maxima (2 for the width-consistent view).
    Returns ``{phi_deg: Figure}``.
    """
    robot = Manipulator.load(robot)
    clearances = load_clearances(clearances, robot)
    out = {}
    for phi_deg, sub in comparison.by_orientation().items():
        ds = error_map(robot, clearances, math.radians(phi_deg), n=grid, progress=False)
        measured = {"x": sub.measurements.nominal[:, 0], "y": sub.measurements.nominal[:, 1],
                    **sub.measured_values()}
        conv = "measured ranges vs maxima (paper)" if scale == 1 else f"measured ranges vs {scale:g} x maxima"
        out[phi_deg] = figures.plot_error_map(
            ds, phi_deg, measured=measured, scale=scale,
            title=f"{robot.name}, clearances {clearances.name}, $\\phi$ = {phi_deg:g} deg: {conv}")
    return out


def write_figures(robot: Manipulator | str, clearances: ClearanceSet | str, comparison: Comparison,
                  out_dir: str | Path, *, prefix: str = "", map_grid: int = 41,
                  box_datasets: Mapping[str, MeasuredErrors | Measurements] | None = None) -> dict[str, Path]:
    """Write every figure of a comparison as PNG into ``out_dir``; returns ``{name: path}``.

    Names: ``map_phi{deg}`` and ``map_phi{deg}_x2`` (maps with measured points,
    direct and width-consistent), ``boxplot`` (Fig. 13; one box per orientation
    unless ``box_datasets`` is given), ``accuracy`` (Fig. 14), ``regression`` and
    ``regression_x2`` (Fig. 15).
    """
    out_dir = Path(out_dir)
    paths: dict[str, Path] = {}
    for scale, suffix in ((1.0, ""), (2.0, "_x2")):
        for phi_deg, fig in plot_measured_maps(robot, clearances, comparison, grid=map_grid, scale=scale).items():
            name = f"map_phi{phi_deg:g}{suffix}"
            paths[name] = figures.save(fig, out_dir / f"{prefix}{name}.png")
    if box_datasets is None:
        box_datasets = {f"phi = {phi:g} deg": sub.measured for phi, sub in comparison.by_orientation().items()}
    paths["boxplot"] = figures.save(plot_boxplots(box_datasets), out_dir / f"{prefix}boxplot.png")
    paths["accuracy"] = figures.save(plot_accuracy(comparison), out_dir / f"{prefix}accuracy.png")
    paths["regression"] = figures.save(plot_regression(comparison, 1.0), out_dir / f"{prefix}regression.png")
    paths["regression_x2"] = figures.save(plot_regression(comparison, 2.0), out_dir / f"{prefix}regression_x2.png")
    return paths


# ============================================================================ report
def _json_ready(value: Any) -> Any:
    """numpy values and paths to JSON; NaN and infinities become None."""
    if isinstance(value, dict):
        return {str(k): _json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    if isinstance(value, np.ndarray):
        return _json_ready(value.tolist())
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value


_CAPTIONS = {
    "boxplot": "Measured errors per orientation (cf. Fig. 13).",
    "accuracy": "ISO 9283 accuracy per point, AP_p = dp and AP_phi = dphi (Eq. 24, cf. Fig. 14).",
    "regression": "Predicted maxima vs measured ranges with the band +-2 A_meas, paper convention (cf. Fig. 15).",
    "regression_x2": "Twice the predicted maxima vs measured ranges (width-consistent), band +-2 A_meas.",
}


def render_html(summary: Mapping[str, Any], figure_paths: Mapping[str, Path], *, title: str) -> str:
    """A self-contained HTML report (figures embedded as base64 PNG) of a :meth:`Comparison.summary`."""
    q_head = ["", "dx [mm]", "dy [mm]", "dp [mm]", "dphi [deg]"]

    def qrow(name: str, d: Mapping[str, Any], key: str | None = None) -> list[Any]:
        return [name] + [(d[q][key] if key else d[q]) for q in QUANTITIES]

    doc = Document(title)
    doc.paragraph(
        f"Measurements: `{summary['source']}`; robot **{summary['robot']}**, clearances "
        f"**{summary['clearances']}**; {summary['n_points']} points. Measured errors by Eq. 23a-d (ranges over "
        f"the six push readings), predicted maxima by Eq. 21-22 at the nominal poses. Camera accuracy A_meas = "
        f"{summary['accuracy_mm']:g} mm, {summary['accuracy_deg']:g} deg.")
    doc.heading("Conventions")
    conv = summary["conventions"]
    doc.bullets([f"**rmsd**: {conv['rmsd']}.", f"**rmsd_width_consistent**: {conv['rmsd_width_consistent']}."])
    doc.heading("Statistics over all points")
    doc.table(q_head, [qrow("RMSD, measured - max (paper)", summary["rmsd"]),
                       qrow("RMSD, measured - 2 max (width-consistent)", summary["rmsd_width_consistent"]),
                       qrow("mean of measured", summary["mean"]),
                       qrow("SSD of measured", summary["ssd"]),
                       qrow("share inside +-2A, direct", summary["band"]["direct"], "share"),
                       qrow("share inside +-2A, 2 x max", summary["band"]["width_consistent"], "share"),
                       qrow("largest excess beyond the band, direct", summary["band"]["direct"], "max_excess"),
                       qrow("Pearson r, direct", summary["regression"]["direct"], "r")])
    acc = summary["accuracy_iso9283"]
    doc.paragraph(f"ISO 9283 accuracy (Eq. 24): position AP_p from {acc['position'][0]:.4g} to "
                  f"{acc['position'][1]:.4g} mm, orientation AP_phi from {acc['orientation_deg'][0]:.4g} to "
                  f"{acc['orientation_deg'][1]:.4g} deg.")
    doc.heading("RMSD per orientation")
    doc.table(["phi [deg]", "points", "dx", "dy", "dp", "dphi [deg]", "dx (2x)", "dy (2x)", "dp (2x)",
               "dphi (2x) [deg]"],
              [[o["phi_deg"], o["n_points"], *(o["rmsd"][q] for q in QUANTITIES),
                *(o["rmsd_width_consistent"][q] for q in QUANTITIES)] for o in summary["orientations"]])
    doc.heading("Figures")
    for name, path in figure_paths.items():
        if name.startswith("map_"):
            caption = (f"Maximum pose errors over the workspace with the measured points (cf. Figs. 9-12), "
                       f"{'twice the maxima' if name.endswith('_x2') else 'paper convention'}.")
        else:
            caption = _CAPTIONS.get(name, name)
        doc.figure(path, caption)
    doc.heading("Points")
    point_cols = ["point", "x_nom", "y_nom", "phi_nom_deg", "dx", "dx_max", "dy", "dy_max", "dp", "dp_max",
                  "dphi_deg", "dphi_max_deg"]
    doc.table(point_cols, [[p[c] for c in point_cols] for p in summary["points"]])
    return doc.to_html()


def write_report(robot: Manipulator | str, clearances: ClearanceSet | str, comparison: Comparison,
                 out_dir: str | Path, *, map_grid: int = 41, title: str | None = None) -> dict[str, Path]:
    """Write the figures, ``comparison.json`` (:meth:`Comparison.summary` plus file names) and a
    self-contained ``report.html`` into ``out_dir``; returns ``{name: path}`` of every file written."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    figure_paths = write_figures(robot, clearances, comparison, out_dir, map_grid=map_grid)
    summary = comparison.summary()
    summary["figures"] = {k: p.name for k, p in figure_paths.items()}
    json_path = out_dir / "comparison.json"
    json_path.write_text(json.dumps(_json_ready(summary), indent=2) + "\n", encoding="utf-8")
    report = out_dir / "report.html"
    report.write_text(render_html(_json_ready(summary), figure_paths,
                                  title=title or f"Experimental validation: {comparison.robot}, "
                                                 f"clearances {comparison.clearances}"), encoding="utf-8")
    return {"report": report, "json": json_path, **figure_paths}


def virtual_experiment_section(robot: Manipulator | str, clearances: ClearanceSet | str,
                               phi: float | Sequence[float], out_dir: str | Path, *, grid: int = 7,
                               take_up: float = 1.0, noise_mm: float = DEFAULT_ACCURACY_MM,
                               noise_deg: float = DEFAULT_ACCURACY_DEG, model: str = "exact", seed: int = 0,
                               map_grid: int = 41, prefix: str = "virtual_") -> dict[str, Any]:
    """Simulate the experiment at one or more orientations, compare with the model, write files for a report.

    Parameters
    ----------
    phi : orientation(s) in rad (e.g. ``(0, pi/6)`` as in the paper)
    out_dir : folder for the CSV, JSON and PNG files (created)
    grid, take_up, noise_mm, noise_deg, model, seed : see :func:`simulate_experiment`
        (orientation ``k`` uses seed ``seed + k``)
    map_grid : grid of the background error maps
    prefix : file-name prefix

    Returns
    -------
    JSON-ready dict: ``robot, clearances, model, take_up, noise_mm, noise_deg,
    seed, grid``; ``expected_noise_rmsd`` ``{"dx", "dy", "dphi_deg"}`` =
    ``sqrt(2) sigma``, the RMSD of (measured - 2 max) that noise alone produces
    when each extreme reading is unique (see :func:`simulate_readings`; with
    ``take_up = 1`` the Aalborg robot's dphi has two tied readings at each end,
    which raises it to ``sigma sqrt(2 (1 + 1/pi))``, 1.15 times more);
    ``orientations``: per orientation ``phi_deg, n_points, rmsd,
    rmsd_width_consistent, mean, ssd, accuracy_iso9283, band, regression``;
    ``files``: ``{name: path}`` (``measurements``, ``comparison_json``,
    ``boxplot`` (Fig. 13, one box per orientation), and per orientation
    ``map_phi{deg}``, ``map_phi{deg}_x2``, ``accuracy_phi{deg}``,
    ``regression_phi{deg}``, ``regression_phi{deg}_x2``), paths as strings;
    the JSON file also lists every point (:meth:`Comparison.records`).
    """
    robot = Manipulator.load(robot)
    clearances = load_clearances(clearances, robot)
    phis = [float(p) for p in np.atleast_1d(np.asarray(phi, dtype=float))]
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    parts = [simulate_experiment(robot, clearances, p, grid, take_up=take_up, noise_mm=noise_mm, noise_deg=noise_deg,
                                 model=model, seed=seed + k) for k, p in enumerate(phis)]
    offset = np.cumsum([0] + [len(m) for m in parts])
    everything = Measurements(
        points=np.concatenate([[str(int(lbl) + offset[k]) for lbl in m.points] for k, m in enumerate(parts)]),
        nominal=np.concatenate([m.nominal for m in parts]), readings=np.concatenate([m.readings for m in parts]),
        source=f"virtual experiment ({robot.name}, {clearances.name}, {model}, take-up {take_up:g}, "
               f"noise {noise_mm:g} mm / {noise_deg:g} deg, seed {seed})")
    files: dict[str, Path] = {"measurements": write_measurements(out_dir / f"{prefix}measurements.csv", everything)}
    comparison = compare(robot, clearances, everything)
    by_phi = comparison.by_orientation()
    for scale, suffix in ((1.0, ""), (2.0, "_x2")):
        for phi_deg, fig in plot_measured_maps(robot, clearances, comparison, grid=map_grid, scale=scale).items():
            files[f"map_phi{phi_deg:g}{suffix}"] = figures.save(fig, out_dir / f"{prefix}map_phi{phi_deg:g}{suffix}.png")
    files["boxplot"] = figures.save(plot_boxplots({f"phi = {p:g} deg": c.measured for p, c in by_phi.items()}),
                             out_dir / f"{prefix}boxplot.png")
    for phi_deg, sub in by_phi.items():
        tag = f"phi{phi_deg:g}"
        files[f"accuracy_{tag}"] = figures.save(plot_accuracy(sub), out_dir / f"{prefix}accuracy_{tag}.png")
        files[f"regression_{tag}"] = figures.save(plot_regression(sub, 1.0), out_dir / f"{prefix}regression_{tag}.png")
        files[f"regression_{tag}_x2"] = figures.save(plot_regression(sub, 2.0), out_dir / f"{prefix}regression_{tag}_x2.png")
    result: dict[str, Any] = {
        "robot": robot.name, "clearances": clearances.name, "model": model, "take_up": take_up,
        "noise_mm": noise_mm, "noise_deg": noise_deg, "seed": seed, "grid": grid,
        "expected_noise_rmsd": {"dx": math.sqrt(2) * noise_mm, "dy": math.sqrt(2) * noise_mm,
                                "dphi_deg": math.sqrt(2) * noise_deg},
        "orientations": [{"phi_deg": p, **c._statistics()} for p, c in by_phi.items()],
    }
    json_path = out_dir / f"{prefix}comparison.json"
    files["comparison_json"] = json_path
    result["files"] = files
    payload = _json_ready({**result, "points": comparison.records()})
    json_path.write_text(json.dumps(payload, indent=2) + "\n", encoding="utf-8")
    return _json_ready(result)
