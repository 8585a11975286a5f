"""Experimental validation of the clearance model (paper Sec. 5.2 and 6, Eq. 23-24, Figs. 9-15).

This module compares measured pose errors with the model's maxima. The parts of
the validation live in focused modules, re-exported here so that
``from pmaccuracy.experiment import ...`` keeps working:

* :mod:`pmaccuracy.experiment.measurements` - the push protocol's readings and the measurement CSV file;
* this module - Eq. 23 and the comparison statistics (:func:`compare`, :class:`Comparison`);
* :mod:`pmaccuracy.experiment.virtual_rig` - the protocol played on a simulated rig;
* :mod:`pmaccuracy.report.experiment_plots` - figures (Figs. 9-15 analogues);
* :mod:`pmaccuracy.report.experiment_report` - ``comparison.json``, ``report.html`` and the report section.

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
The model's worst case (Eq. 21-22, :func:`pmaccuracy.accuracy.bounds.max_pose_errors`)
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

Units: mm and rad in the arrays; degrees in files, figures and JSON under names
ending in ``_deg``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..accuracy.bounds import PoseErrorBounds, max_pose_errors
from ..model.clearances import ClearanceSet
from ..errors import ConfigError, OutsideJointLimitsError
from ..model.manipulator import Manipulator
from ..model.plausibility import check_orientations
from ..kinematics import DEFAULT_MAX_CONDITION, check_within_limits, inverse_kinematics
from .measurements import CSV_COLUMNS, DEFAULT_ACCURACY_DEG, DEFAULT_ACCURACY_MM, MAX_DEVIATION_DEG, MAX_DEVIATION_MM, NOMINAL_TOLERANCE, PUSH_AXES, PUSHES, Measurements, _nominal_deg, _wrap_deg, load_measurements, write_measurements
from ..io.resolve import load_clearances
from .virtual_rig import MODELS, grid_poses, opposite, predict_pushes, push_configurations, simulate_experiment, simulate_readings
from ..io.resolve import robot_arg

#: Compared quantities and their units, in output order (``dphi`` in degrees outside the arrays).
QUANTITIES = ("dx", "dy", "dp", "dphi_deg")
UNITS = {"dx": "mm", "dy": "mm", "dp": "mm", "dphi_deg": "deg"}
LABELS = {"dx": r"$\delta x$", "dy": r"$\delta y$", "dp": r"$\delta p$", "dphi_deg": r"$\delta\phi$"}


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
    predicted : :func:`~pmaccuracy.accuracy.bounds.max_pose_errors` at the nominal poses
    robot, clearances : names of the model used
    accuracy_mm, accuracy_deg : ``A_meas`` of the camera (Fig. 15 band ``+- 2 A_meas``)
    pushes : with a known push force (``compare(..., push_n=N)``), each push's measured displacement beside
        the loaded model's prediction (:class:`PushComparison`); else None

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
    pushes: PushComparison | None = None

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
        and ``orientations`` (the same statistics per nominal orientation); with a push force also ``pushes``
        (:meth:`PushComparison.summary`).
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
        if self.pushes is not None:
            out["pushes"] = self.pushes.summary()
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


# ============================================================================ pushes from physics
#: Components of a push displacement and their units (``dphi_deg`` in degrees outside the arrays).
PUSH_COMPONENTS = (("dx", "mm"), ("dy", "mm"), ("dphi_deg", "deg"))


@dataclass(frozen=True, eq=False)
class PushComparison:
    """Measured push displacements against those the loaded model predicts for a push force (issue 24).

    Each push of the protocol (:data:`PUSHES`) is a load of ``push_n`` N (a moment of ``push_n`` times the
    robot's size for ``+-r``: :func:`~pmaccuracy.experiment.virtual_rig.push_loads`); the loaded model
    (:func:`~pmaccuracy.experiment.virtual_rig.predict_pushes`) predicts where it moves the platform.

    Attributes
    ----------
    push_n : the rig's push force (N)
    points : ``(n,)`` labels;  nominal : ``(n, 3)`` [mm, mm, rad]
    measured : ``(n, 6, 3)`` [mm, mm, rad]: reading minus nominal pose, push order :data:`PUSHES`
    predicted : ``(n, 6, 3)`` [mm, mm, rad]: the first-order loaded pose error of each push
    spread : ``(n, 6, 3)`` [mm, mm, rad]: half-width of the range the push's unloaded legs leave
    accuracy_mm, accuracy_deg : ``A_meas``; the predicted range of a reading is
        ``predicted +- (spread + 2 A_meas)`` (the Fig. 15 band widened by the unloaded legs)
    """

    push_n: float
    points: np.ndarray
    nominal: np.ndarray
    measured: np.ndarray
    predicted: np.ndarray
    spread: np.ndarray
    accuracy_mm: float = DEFAULT_ACCURACY_MM
    accuracy_deg: float = DEFAULT_ACCURACY_DEG

    @property
    def difference(self) -> np.ndarray:
        """``(n, 6, 3)`` measured minus predicted displacement [mm, mm, rad]."""
        return self.measured - self.predicted

    @property
    def halfwidth(self) -> np.ndarray:
        """``(n, 6, 3)`` half-width of the predicted range: ``spread + 2 A_meas`` [mm, mm, rad]."""
        band = np.array([2 * self.accuracy_mm, 2 * self.accuracy_mm, 2 * math.radians(self.accuracy_deg)])
        return self.spread + band

    @property
    def inside(self) -> np.ndarray:
        """``(n, 6)`` bool: every component of the measured displacement within the predicted range."""
        return np.all(np.abs(self.difference) <= self.halfwidth * (1 + 1e-12), axis=-1)

    def rms(self) -> dict[str, float]:
        """RMS of measured minus predicted over all points and pushes (mm; ``dphi_deg`` in deg)."""
        diff = self.difference.reshape(-1, 3)
        out = np.sqrt(np.mean(diff ** 2, axis=0))
        return {"dx": float(out[0]), "dy": float(out[1]), "dphi_deg": math.degrees(out[2])}

    def records(self) -> list[dict[str, Any]]:
        """One dict per point and push (mm, deg): nominal pose, measured, predicted, difference, the range's
        half-width (``*_range``) and ``inside``."""
        out = []
        scale = (1.0, 1.0, math.degrees(1.0))
        for k in range(self.points.shape[0]):
            for j, push in enumerate(PUSHES):
                rec: dict[str, Any] = {"point": str(self.points[k]), "x_nom": float(self.nominal[k, 0]),
                                       "y_nom": float(self.nominal[k, 1]),
                                       "phi_nom_deg": float(_nominal_deg(self.nominal[k, 2])), "push": push}
                for q, (name, _unit) in enumerate(PUSH_COMPONENTS):
                    rec[f"{name}_meas"] = float(self.measured[k, j, q] * scale[q])
                    rec[f"{name}_pred"] = float(self.predicted[k, j, q] * scale[q])
                    rec[f"{name}_diff"] = float(self.difference[k, j, q] * scale[q])
                    rec[f"{name}_range"] = float(self.halfwidth[k, j, q] * scale[q])
                rec["inside"] = bool(self.inside[k, j])
                out.append(rec)
        return out

    def summary(self) -> dict[str, Any]:
        """JSON-ready: ``push_n``, the convention, ``rms`` of the differences, ``share_inside`` and ``pushes``
        (:meth:`records`)."""
        return {"push_n": self.push_n,
                "convention": "each push a load of push_n N (+-r: a moment of push_n times the robot's size, N mm); "
                              "predicted: the first-order loaded pose error (clearances taken up along the joints' "
                              "reactions); range: predicted +- (unloaded legs' spread + 2 A_meas)",
                "rms": self.rms(), "share_inside": float(np.mean(self.inside)), "pushes": self.records()}

    def __repr__(self) -> str:
        rms = self.rms()
        return (f"PushComparison({self.points.shape[0]} points x 6 pushes at {self.push_n:g} N: rms of measured - "
                f"predicted dx {rms['dx']:.3g} mm, dy {rms['dy']:.3g} mm, dphi {rms['dphi_deg']:.3g} deg; "
                f"{100 * float(np.mean(self.inside)):.0f} % inside the predicted range)")


def compare_pushes(robot: Manipulator | str, clearances: ClearanceSet | str, measurements: Measurements | str | Path,
                   push_n: float, *, accuracy_mm: float = DEFAULT_ACCURACY_MM,
                   accuracy_deg: float = DEFAULT_ACCURACY_DEG, max_condition: float = DEFAULT_MAX_CONDITION,
                   limit_tolerance_mm: float = NOMINAL_LIMIT_TOLERANCE_MM) -> PushComparison:
    """Measured push displacements (reading minus nominal pose) beside the loaded model's prediction for a push
    force of ``push_n`` N (:class:`PushComparison`), at the measurements' nominal poses.

    Raises like :func:`compare`; :class:`~pmaccuracy.errors.ConfigError` for a push force that is not > 0.
    """
    if isinstance(measurements, Measurements):
        check_orientations(measurements.nominal, "measurements.nominal", poses=True)
    robot = robot_arg(robot)
    clearances = load_clearances(clearances, robot)
    if not isinstance(measurements, Measurements):
        measurements = load_measurements(measurements)
    _check_accuracy(accuracy_mm, accuracy_deg, limit_tolerance_mm)
    if not (math.isfinite(push_n) and push_n > 0):
        raise ConfigError(f"must be a force > 0 (N), got {push_n:g}", key="push_n")
    require_nominal_within_limits(robot, measurements, limit_tolerance_mm)
    predicted, spread = predict_pushes(robot, clearances, measurements.nominal, float(push_n), allow_outside=True,
                                       max_condition=max_condition)
    return PushComparison(push_n=float(push_n), points=measurements.points, nominal=measurements.nominal,
                          measured=measurements.readings - measurements.nominal[:, None, :], predicted=predicted,
                          spread=spread, accuracy_mm=float(accuracy_mm), accuracy_deg=float(accuracy_deg))


def compare(robot: Manipulator | str, clearances: ClearanceSet | str, measurements: Measurements | str | Path, *,
            accuracy_mm: float = DEFAULT_ACCURACY_MM, accuracy_deg: float = DEFAULT_ACCURACY_DEG,
            max_condition: float = DEFAULT_MAX_CONDITION,
            limit_tolerance_mm: float = NOMINAL_LIMIT_TOLERANCE_MM, push_n: float | None = None) -> Comparison:
    """Compare measurements with the model at the same nominal poses.

    Parameters
    ----------
    robot, clearances : objects, preset names or TOML paths
    measurements : a :class:`Measurements` or the path of a measurement CSV file
    accuracy_mm, accuracy_deg : camera accuracy ``A_meas`` (Sec. 5), > 0
    limit_tolerance_mm : how far outside the joint ranges a nominal pose may lie
        (default: the 5 um encoder accuracy); the model is evaluated there as is
    push_n : the rig's push force (N), if known: each push's displacement is then also compared with the
        loaded model's prediction (:func:`compare_pushes`, ``Comparison.pushes``)

    Raises
    ------
    MeasurementFileError : malformed file
    OutsideJointLimitsError : a nominal pose outside the joint ranges (names the point and line)
    SingularPoseError : a nominal pose at or near det A = 0
    """
    if isinstance(measurements, Measurements):   # a file's phi_nom_deg is checked by its reader
        check_orientations(measurements.nominal, "measurements.nominal", poses=True)
    robot = robot_arg(robot)
    clearances = load_clearances(clearances, robot)
    if not isinstance(measurements, Measurements):
        measurements = load_measurements(measurements)
    _check_accuracy(accuracy_mm, accuracy_deg, limit_tolerance_mm)
    if push_n is not None and not (math.isfinite(push_n) and push_n > 0):
        raise ConfigError(f"must be a force > 0 (N), got {push_n:g}", key="push_n")
    require_nominal_within_limits(robot, measurements, limit_tolerance_mm)
    predicted = max_pose_errors(robot, clearances, measurements.nominal, allow_outside=True,
                                max_condition=max_condition)
    pushes = None if push_n is None else compare_pushes(
        robot, clearances, measurements, push_n, accuracy_mm=accuracy_mm, accuracy_deg=accuracy_deg,
        max_condition=max_condition, limit_tolerance_mm=limit_tolerance_mm)
    return Comparison(measurements=measurements, measured=measured_errors(measurements), predicted=predicted,
                      robot=robot.name, clearances=clearances.name, accuracy_mm=float(accuracy_mm),
                      accuracy_deg=float(accuracy_deg), pushes=pushes)


def _check_accuracy(accuracy_mm: float, accuracy_deg: float, limit_tolerance_mm: float) -> None:
    for name, value in (("accuracy_mm", accuracy_mm), ("accuracy_deg", accuracy_deg)):
        if not (math.isfinite(value) and value > 0):
            raise ConfigError(f"must be a positive number, got {value}", key=name)
    if not (math.isfinite(limit_tolerance_mm) and limit_tolerance_mm >= 0):
        raise ConfigError(f"must be a length >= 0, got {limit_tolerance_mm}", key="limit_tolerance_mm")
