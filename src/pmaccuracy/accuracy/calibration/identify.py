"""Identification of the error parameters from a calibration CSV by nonlinear least squares.

Residual: the inverse-kinematic residual of each leg,
``r_n = q(theta; F * m_n) - (offset + gain * c_n)`` (3 per point: the exact IK of the model robot at the
measured pose, minus the joint value the command gives). It is chosen over the forward residual
``m_n - FK(theta; c_n)`` because the inverse kinematics is closed-form and single-valued on each leg's
working mode, so every evaluation is exact, vectorised and free of the assembly-mode choice of the forward
kinematics (a polynomial solve). It is weighted so that it is statistically equivalent to the forward
residual: with ``G_n = dr_n/dm_n`` (3x3, the inverse-kinematic Jacobian at the measured pose) and the pose
uncertainty ``Sigma_n = diag(sigma_n^2)``, the whitened residual is ``e_n = Sigma_n^(-1/2) G_n^-1 r_n``,
to first order ``Sigma_n^(-1/2) (m_n - FK(theta; c_n))``: unit variance per component.

Clearances: a joint clearance moves the platform off the pose the commands give by a state that changes from
one measured point to the next, which no parameter can absorb. With ``clearances`` given, each point's
measurement covariance is ``Sigma_n = diag(sigma_n^2) + C_n`` with the first-order clearance covariance
``C_n = Q J_n V J_n^T Q^T`` (3x3, mm^2 / mm rad / rad^2): ``J_n (3, K)`` the pose error per unit value of
every clearance variable at the point's robot-frame pose (:func:`pmaccuracy.accuracy.distributions.error_jacobian`
on the current model robot), ``V = diag(var z_k)`` their variances
(:func:`pmaccuracy.accuracy.distributions.variable_variances`) and ``Q = diag(R(-phi_F), 1)`` the rotation into
the measurement frame. The assumed law: every clearance variable independent from point to point and
between joints, **uniform in its set** by default (``distribution``: another law of
:class:`~pmaccuracy.accuracy.distributions.Distribution`). Why uniform: the robot is driven to each point
anew, and where a joint settles in its clearance depends on loads and the approach, unknown to the
calibration; the uniform law is the maximum-entropy law on the set and the one the statistics
(``pmaccuracy statistics``) and the virtual experiment (:func:`.simulate.measure`) draw from. A serial
arm's covariance is that of :func:`.compensate.sample_serial_errors` (its segment coefficients uniform in
``[-1, 1]``: ``G^T G / 3``; one uniform disk of the summed radius ``R``: ``R^2 / 4`` per axis). The
whitening is then ``W_n = L_n^-1 G_n^-1`` with ``L_n`` the Cholesky factor of ``Sigma_n``. Without
``clearances`` a clearance scatter is only absorbed, on average, by the residual scale ``s`` below, and
the sigmas of the parameters are then too small where the clearance effect is large and too large where
it is small (over 20 seeds with clearances: normalized-error spreads 0.65 to 1.2 instead of 1).

Fit: :func:`scipy.optimize.least_squares` (trust-region reflective) on the identified parameters (the
others fixed at nominal by :func:`~.identifiability.analyse`), in three steps (:func:`fit`):

1. a robust pass with the ``soft_l1`` loss, its scale :data:`ROBUST_F_SCALE` (3) *stated* sigmas: the
   residuals are whitened by the stated uncertainties, so the scale is fixed before the data are seen and a
   gross reading cannot widen it (a scale taken from the residuals grows with the outlier it should catch).
   Points whose measured pose the starting model cannot reach (no inverse kinematics) sit this pass out;
2. an outlier test of every point at the robust estimate on its *forward* residual
   ``m_n - F^-1 FK(theta; offset + gain * c_n)`` (the exact forward kinematics of its commands, the assembly
   mode nearest the reading: :func:`point_test`), normalized by its predicted covariance ``Sigma_n``:
   ``chi2_n = r^T Sigma_n^-1 r``, the three components jointly. A point is flagged when ``chi2_n`` exceeds
   the chi-square(3) quantile :data:`OUTLIER_QUANTILE` (99.9 %: 16.3, a normalized residual of 4.03). Only
   when the median point scatters more than :data:`UNDERSTATED` times (in ``chi2``) what the stated sigmas
   predict (the sigmas are understated: clearances not given) is the bound multiplied by that ratio; a few
   gross readings move the median little and never widen the test. The forward residual catches a wrong reading and a wrong command
   alike, and a point whose commands the model cannot assemble, or whose reading it cannot reach, is
   flagged (normalized residual ``inf``). A reading the *nominal* robot could not reach is kept when the
   fitted one reaches it and explains it;
3. a plain least-squares fit on the points kept, then the test again at its estimate; repeated (at most
   :data:`MAX_ROUNDS` times) until the points kept no longer change. The flagged points are reported
   (:class:`Outlier`: row, label, normalized residual at the final estimate) and left out. The estimate's
   covariance is ``s^2 (J^T J)^-1`` of the kept points with ``s^2 = |e|^2 / (m - L)``, the inverse taken
   through the SVD of the column-scaled Jacobian (:func:`~.identifiability.inverse_normal_matrix`: every
   direction kept, so a weakly determined parameter gets its large sigma, not the tiny one a pseudo-inverse
   of the unscaled ``J^T J`` gives).

Without the robust pass (``robust=False``) every point is fitted; one the nominal robot cannot reach joins
after a first fit, and one the fitted robot still cannot reach is refused naming its row.

Parameters the data determine too weakly (predicted sigma above :data:`~.identifiability.PRACTICAL_MAX_SIGMA`
typical changes) are fixed at nominal before the fit and reported like the unidentifiable ones
(:mod:`.identifiability`). Data with too few *distinct* poses for the identifiable parameters (repeated
points add no information) are refused with the count of distinct poses and of the parameters this robot
has (:func:`identifiable_count`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats

from ...errors import ConfigError, GeometryError, MeasurementFileError, PoseError
from ...kinematics import FKSolution, forward_kinematics
from ...model.manipulator import Manipulator
from .data import CalibrationData
from .identifiability import PRACTICAL_MAX_SIGMA, RTOL, Identifiability, analyse, inverse_normal_matrix
from ...model.serial import SerialArm, error_generators, load_serial_sources
from ..distributions import as_sources, error_jacobian, variable_variances
from .parameters import (ParameterVector, SerialParameterVector, commands_for, error_parameters, frame_apply,
                         frame_inverse, joint_values, leg_joint_value, serial_poses)

#: Outlier threshold: the chi-square(3) quantile of a point's normalized forward residual squared.
OUTLIER_QUANTILE = 0.999
#: Scale of the robust pass's soft_l1 loss, in stated sigmas (the residuals are whitened by them).
ROBUST_F_SCALE = 3.0
#: The outlier test keeps the stated sigmas unless the median point's chi-square exceeds this many times that
#: of chi-square(3): the sigmas are then understated (clearances not given) and the test widens by that ratio.
UNDERSTATED = 2.0
#: Most fits on the kept points, each followed by the outlier test at its estimate (module docstring).
MAX_ROUNDS = 4
#: A measured pose further than this (mm, or deg) from where the nominal robot puts the commands is refused.
MAX_START_DEVIATION_MM = 10.0
MAX_START_DEVIATION_DEG = 10.0
#: Penalty (whitened units) of a residual where the model cannot reach a measured pose during the fit.
UNREACHABLE = 1e6


def _steps(pv: ParameterVector) -> np.ndarray:
    return np.array([1e-4 if u == "mm" else 1e-6 for u in pv.units])


def raw_residuals(pv: ParameterVector, values: np.ndarray, commands: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """``r (N, 3)``: exact IK actuated values at the measured poses minus ``offset + gain * command`` (mm/rad;
    revolute differences wrapped to (-pi, pi]); NaN where a leg cannot reach."""
    off_i, gain_i = pv.actuator_slices
    r = joint_values(pv, values, poses) - (values[off_i] + values[gain_i] * commands)
    rev = np.array([c.actuated.kind == "R" for c in pv.robot.chains])
    return np.where(rev, np.angle(np.exp(1j * r)), r)


def pose_sensitivity(pv: ParameterVector, values: np.ndarray, commands: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """``G (N, 3, 3) = dr/dm``: central differences of :func:`raw_residuals` in the measured pose."""
    h = np.array([1e-5, 1e-5, 1e-7])
    cols = []
    for k in range(3):
        dp = np.zeros(3)
        dp[k] = h[k]
        cols.append((raw_residuals(pv, values, commands, poses + dp) -
                     raw_residuals(pv, values, commands, poses - dp)) / (2 * h[k]))
    return np.stack(cols, axis=-1)


@dataclass(frozen=True)
class ClearanceModel:
    """The clearances of the identification's measurement model (module docstring): ``clearances`` (a preset
    name, a file or a clearance object, as :func:`pmaccuracy.accuracy.distributions.as_sources` or, for a
    serial arm, :func:`pmaccuracy.model.serial.load_serial_sources` reads) and the ``distribution`` of their
    states (None: uniform in the sets)."""

    clearances: object
    distribution: object = None


def clearance_covariance(pv, values: np.ndarray, data: CalibrationData, model: ClearanceModel) -> np.ndarray:
    """``C (N, 3, 3)``: first-order covariance of the pose error the clearance states give at each measured
    point, in the measurement frame (mm^2, mm rad, rad^2; module docstring), for the robot ``values (P,)``."""
    values = np.asarray(values, dtype=float)
    if isinstance(pv, SerialParameterVector):
        arm, off, gain, frame = pv.split(values)
        G, layout = error_generators(arm, load_serial_sources(model.clearances, arm), off + gain * data.commands)
        C = np.einsum("nmi,nmj->nij", G, G) / 3.0
        C[:, :2, :2] += np.eye(2) * layout.disk_radius ** 2 / 4.0
    else:
        robot, _, _, frame = pv.split(values)
        sources = as_sources(robot, model.clearances)
        J = error_jacobian(robot, sources, frame_apply(frame, data.poses))          # (N, 3, K)
        C = np.einsum("nik,k,njk->nij", J, variable_variances(sources, model.distribution), J)
    c, s = np.cos(frame[2]), np.sin(frame[2])
    Q = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])                      # robot -> measurement frame
    return Q @ C @ Q.T


def measurement_covariance(pv, values: np.ndarray, data: CalibrationData,
                           model: ClearanceModel | None = None) -> np.ndarray:
    """``Sigma (N, 3, 3) = diag(sigma^2) + C`` (module docstring; ``C = 0`` without ``model``)."""
    S = np.einsum("ni,ij->nij", data.sigmas ** 2, np.eye(3))
    if model is None or model.clearances is None:
        return S
    C = clearance_covariance(pv, values, data, model)
    return S + np.where(np.isfinite(C), C, 0.0)


def whitening(pv: ParameterVector, values: np.ndarray, data: CalibrationData,
              model: ClearanceModel | None = None) -> np.ndarray:
    """``W (N, 3, 3) = L^-1 G^-1`` with ``L L^T = Sigma`` (:func:`measurement_covariance`; module docstring)."""
    G = pose_sensitivity(pv, values, data.commands, data.poses)
    bad = ~np.all(np.isfinite(G.reshape(len(G), -1)), axis=1)
    if np.any(bad):
        n = int(np.flatnonzero(bad)[0])
        raise MeasurementFileError("the measured pose is out of the robot's reach", source=data.source,
                                   key=f"row {n + 1} (point {data.labels[n]})")
    with np.errstate(all="ignore"):
        Ginv = np.linalg.inv(G)
    if model is None or model.clearances is None:
        return Ginv / data.sigmas[:, :, None]
    L = np.linalg.cholesky(measurement_covariance(pv, values, data, model))
    return np.linalg.solve(L, Ginv)


def whitened(pv, values, data, W) -> np.ndarray:
    """Whitened residuals ``e (N, 3)``; :data:`UNREACHABLE` where the model cannot reach."""
    try:
        r = raw_residuals(pv, values, data.commands, data.poses)
    except GeometryError:  # a trial step of the optimizer left the valid geometries (a negative length)
        return np.full(data.poses.shape, UNREACHABLE)
    e = np.einsum("nij,nj->ni", W, r)
    return np.where(np.isfinite(e), e, UNREACHABLE)


def _leg_of(pv: ParameterVector, j: int) -> int | None:
    """The leg (0-based) whose residual alone parameter ``j`` changes; None for the frame."""
    name = pv.names[j]
    return int(name[3]) - 1 if name.startswith("leg") else None


def jacobian(pv, values, data, W, cols=None) -> np.ndarray:
    """``de/dtheta (3N, len(cols))`` by central differences of the exact model (a leg's parameter changes only
    that leg's residual ``r_i``: ``de/dtheta_j = W[:, :, i] dr_i/dtheta_j``, one leg's inverse kinematics)."""
    cols = range(len(pv.names)) if cols is None else cols
    h = _steps(pv)
    values = np.asarray(values, dtype=float)
    poses = frame_apply(values[-3:], data.poses)
    off_i, gain_i = pv.actuator_slices
    rev = [c.actuated.kind == "R" for c in pv.robot.chains]
    out = []
    for j in cols:
        i = _leg_of(pv, j)
        if i is not None:
            vp, vm = values.copy(), values.copy()
            vp[j] += h[j]
            vm[j] -= h[j]
            try:
                d = [leg_joint_value(pv, v, i, poses) - (v[off_i[i]] + v[gain_i[i]] * data.commands[:, i])
                     for v in (vp, vm)]
            except GeometryError:
                out.append(np.zeros(3 * len(data)))
                continue
            dr = d[0] - d[1]
            if rev[i]:
                dr = np.angle(np.exp(1j * dr))
            col = W[:, :, i] * (dr / (2 * h[j]))[:, None]
            out.append(np.where(np.isfinite(col), col, 0.0).ravel())
            continue
        vp, vm = values.copy(), values.copy()
        vp[j] += h[j]
        vm[j] -= h[j]
        out.append(((whitened(pv, vp, data, W) - whitened(pv, vm, data, W)) / (2 * h[j])).ravel())
    return np.stack(out, axis=-1)


def reachable(pv: ParameterVector, values: np.ndarray, data: CalibrationData) -> np.ndarray:
    """``(N,)`` bool: the points whose measured pose the robot ``values`` reaches (every leg's inverse
    kinematics, and its pose sensitivity, finite): those its inverse-kinematic residual can take."""
    r = raw_residuals(pv, values, data.commands, data.poses)
    G = pose_sensitivity(pv, values, data.commands, data.poses)
    return np.all(np.isfinite(r), axis=1) & np.all(np.isfinite(G.reshape(len(G), -1)), axis=1)


def check_start(pv: ParameterVector, data: CalibrationData, frame: np.ndarray | None = None) -> np.ndarray:
    """Refuse data the nominal robot (and frame) cannot explain: more than half the points out of its reach,
    or more than half of them out of reach or further than :data:`MAX_START_DEVIATION_MM` /
    :data:`MAX_START_DEVIATION_DEG` (first order) from where it puts the commands (a frame far from the
    robot's, poses in radians or metres, commands of other points). :class:`MeasurementFileError` naming
    the (first) row. Returns the points within the nominal robot's reach ``(N,)`` bool: the others are left
    to the fit (:func:`fit`), which keeps those the fitted robot explains."""
    values = pv.nominal.copy()
    if frame is not None:
        values[-3:] = frame
    ok = reachable(pv, values, data)
    n_out = int((~ok).sum())
    if n_out > len(data) // 2:
        n = int(np.flatnonzero(~ok)[0])
        raise MeasurementFileError(f"the nominal robot cannot reach the measured pose, nor those of {n_out - 1} other "
                                   f"of the {len(data)} points: a measurement frame far from the robot's (give its "
                                   "pose, --frame X Y PHI_DEG) or poses in other units (x, y in mm, phi_deg in "
                                   "degrees)", source=data.source, key=f"row {n + 1} (point {data.labels[n]})")
    inside = data.subset(ok)
    r = raw_residuals(pv, values, inside.commands, inside.poses)
    G = pose_sensitivity(pv, values, inside.commands, inside.poses)
    with np.errstate(all="ignore"):
        dm = np.linalg.solve(G, r[..., None])[..., 0]
    far = np.ones(len(data), dtype=bool)
    far[ok] = ((np.hypot(dm[:, 0], dm[:, 1]) > MAX_START_DEVIATION_MM) |
               (np.degrees(np.abs(dm[:, 2])) > MAX_START_DEVIATION_DEG))
    if far.sum() > len(data) // 2:   # a few far points are left to the robust fit (outliers)
        k = int(np.flatnonzero(far[ok])[0]) if far[ok].any() else None
        if k is None:       # pragma: no cover - every far point is out of reach: caught above
            raise MeasurementFileError("the nominal robot cannot reach the measured poses", source=data.source)
        n = int(np.flatnonzero(ok)[k])
        dxy, dphi = float(np.hypot(*dm[k, :2])), float(np.degrees(abs(dm[k, 2])))
        also = f", {n_out} out of its reach" if n_out else ""
        raise MeasurementFileError(
            f"the measured pose is {dxy:.3g} mm and {dphi:.3g} deg from where the nominal robot puts the commands "
            f"(more than {MAX_START_DEVIATION_MM:g} mm or {MAX_START_DEVIATION_DEG:g} deg, as are {far.sum()} of "
            f"{len(data)} points{also}): a measurement frame far from the robot's (give --frame X Y PHI_DEG), poses "
            "in radians or metres, or commands of other points", source=data.source,
            key=f"row {n + 1} (point {data.labels[n]})")
    alt = inside.poses.copy()
    alt[:, 2] = np.degrees(inside.poses[:, 2])           # the phi_deg column read as radians
    r_alt = raw_residuals(pv, values, inside.commands, alt)
    G_alt = pose_sensitivity(pv, values, inside.commands, alt)
    with np.errstate(all="ignore"):
        dphi_alt = np.linalg.solve(G_alt, r_alt[..., None])[:, 2, 0]
    check_phi_units(dm[:, 2], dphi_alt, data)
    return ok


#: ``phi_deg`` is refused as radians when its orientation deviations, read as degrees, spread more than this
#: (deg) and, read as radians, less than :data:`RADIANS_RATIO` times as much.
RADIANS_MIN_SPREAD_DEG = 0.5
RADIANS_RATIO = 0.25


def check_phi_units(dphi: np.ndarray, dphi_alt: np.ndarray, data: CalibrationData) -> None:
    """Refuse a ``phi_deg`` column that holds radians: ``dphi (N,)`` are the orientation deviations (rad) of
    the measured poses from where the nominal model puts the commands, the column read as degrees, and
    ``dphi_alt (N,)`` the same with the column read as radians (NaN where out of reach). The spread of each
    is ``median |d - median d|`` (a constant offset is the frame's turn, not a unit); the radians reading
    fitting :data:`RADIANS_RATIO` times better, with the degrees reading's spread above
    :data:`RADIANS_MIN_SPREAD_DEG`, raises :class:`MeasurementFileError` naming the file and the column.
    A small orientation range (a +-5 deg plan) written in radians stays within the far-point checks of
    :func:`check_start` (0.09 read as deg is a plausible reading near 0) and is caught only here."""
    if not np.all(np.isfinite(dphi_alt)):
        return
    def spread(d):
        d = np.angle(np.exp(1j * d))
        return float(np.degrees(np.median(np.abs(d - np.median(d)))))
    as_deg, as_rad = spread(dphi), spread(dphi_alt)
    if as_deg > RADIANS_MIN_SPREAD_DEG and as_rad < RADIANS_RATIO * as_deg:
        raise MeasurementFileError(
            f"holds radians, not degrees: read as degrees the measured orientations are {as_deg:.3g} deg (median) off "
            f"the commanded ones, read as radians {as_rad:.3g} deg: write phi_deg (and sigma_phi_deg) in degrees",
            source=data.source, key="column phi_deg")


@dataclass(frozen=True)
class Outlier:
    """A point the outlier test left out of the fit (module docstring): its ``row`` (1-based, in the order of
    the data: the calibration CSV's data row) and ``label``; ``normalized``: its forward residual normalized
    by its predicted covariance, ``sqrt(r^T Sigma^-1 r)`` (predicted sigmas, the three components jointly;
    ``inf`` where the identified robot cannot assemble its commands or reach its reading) and ``residual``
    ``(dx mm, dy mm, dphi rad)``: measured minus the forward kinematics of its commands on the identified
    robot (NaN where there is none)."""

    row: int
    label: str
    normalized: float
    residual: tuple[float, float, float]
    unreachable: bool = False

    def describe(self) -> str:
        """One line: ``row 7 (point p7): 512 sigma (dx 5 mm, dy 0.01 mm, dphi 0.002 deg)``."""
        where = f"row {self.row} (point {self.label})"
        if not np.isfinite(self.normalized):
            return f"{where}: the identified robot has no assembly mode for its commands"
        dx, dy, dphi = self.residual
        said = (f"{where}: {self.normalized:.3g} sigma (dx {dx:.3g} mm, dy {dy:.3g} mm, "
                f"dphi {np.degrees(dphi):.3g} deg)")
        return said + (", its reading out of the identified robot's reach" if self.unreachable else "")


@dataclass(frozen=True)
class Identification:
    """Result of :func:`identify`.

    ``values (P,)``: all parameters (fixed ones at nominal), ``sigma (P,)``: 1-sigma (0 for fixed),
    ``covariance (L, L)`` of the identified ones (in the order of ``identifiability.identified``),
    ``rms_before`` / ``rms_after``: RMS of the whitened residuals at nominal and at the estimate (inliers),
    ``residuals_before`` / ``residuals_after`` ``(N, 3)``: pose residuals ``G^-1 r`` (mm, mm, rad),
    ``outliers``: labels of the points dropped, ``scale``: the residual scale ``s``, ``cost``, ``nfev``,
    ``clearances``: the clearance model of the measurement covariance (None: camera noise only),
    ``fit_rms_position``: RMS position residual ``sqrt(mean(dx^2 + dy^2))`` (mm) of the inliers at the
    estimate: what the fitted model leaves at the measured points (clearances and noise, if the model is right);
    ``flagged``: the :class:`Outlier` record of each point left out (same order as ``outliers``),
    ``outlier_threshold``: the normalized forward residual above which a point is flagged (NaN without the
    robust pass).
    """

    parameters: ParameterVector
    values: np.ndarray
    sigma: np.ndarray
    covariance: np.ndarray
    identifiability: Identifiability
    residuals_before: np.ndarray
    residuals_after: np.ndarray
    rms_before: float
    rms_after: float
    outliers: tuple[str, ...]
    scale: float
    nfev: int
    n_points: int
    clearances: ClearanceModel | None = None
    fit_rms_position: float = float("nan")
    flagged: tuple["Outlier", ...] = ()
    outlier_threshold: float = float("nan")

    def __repr__(self) -> str:
        return (f"Identification({len(self.identifiability.identified)} parameters from {self.n_points} points, "
                f"rms {self.rms_before:.4g} -> {self.rms_after:.4g}, outliers={list(self.outliers)})")

    def estimates(self) -> list[dict]:
        """One record per parameter: name, unit, nominal, estimate, sigma, identified (bool)."""
        pv = self.parameters
        ident = set(self.identifiability.identified)
        return [dict(name=n, unit=u, nominal=float(a), estimate=float(v), sigma=float(s), identified=n in ident)
                for n, u, a, v, s in zip(pv.names, pv.units, pv.nominal, self.values, self.sigma)]


def _pose_residuals(pv, values, data) -> np.ndarray:
    r = raw_residuals(pv, values, data.commands, data.poses)
    G = pose_sensitivity(pv, values, data.commands, data.poses)
    with np.errstate(all="ignore"):
        return np.linalg.solve(G, r[..., None])[..., 0]


def identify(data: CalibrationData, parameters: ParameterVector | None = None, *, robot=None,
             fixed: tuple[str, ...] = (), frame: np.ndarray | None = None, robust: bool = True,
             rtol: float = RTOL, clearances=None, distribution=None,
             max_sigma: float | None = PRACTICAL_MAX_SIGMA) -> Identification:
    """Identify the error parameters from calibration ``data`` (module docstring for the method).

    ``parameters`` (or ``robot``): the nominal; ``fixed``: names kept at nominal; ``frame``: a starting
    measurement frame ``(x mm, y mm, phi rad)`` when the camera's frame is far from the robot's;
    ``clearances`` (preset, file or object) and ``distribution`` (their states' law, default uniform): the
    clearance covariance added to each point's measurement covariance (module docstring); ``max_sigma``:
    the bound of the practically unidentifiable parameters in typical changes (None: only the exactly
    unidentifiable ones are fixed; :mod:`.identifiability`).
    Raises :class:`~pmaccuracy.errors.ConfigError` for an unknown parameter name or fewer residuals than
    parameters, :class:`~pmaccuracy.errors.MeasurementFileError` naming the row of an implausible point.
    """
    pv = parameters if parameters is not None else error_parameters(robot)
    pv.index(fixed)
    model = None if clearances is None else ClearanceModel(clearances, distribution)
    if isinstance(pv, SerialParameterVector):
        return _identify_serial(data, pv, tuple(fixed), frame, robust, rtol, model, max_sigma)
    x0 = pv.nominal.copy()
    if frame is not None:
        x0[-3:] = np.asarray(frame, dtype=float)
    use = check_start(pv, data, x0[-3:])
    start = data.subset(use)
    W = whitening(pv, x0, start, model)
    J = jacobian(pv, x0, start, W)
    ident = analyse(pv, J, rtol=rtol, fixed=tuple(fixed), max_sigma=max_sigma)
    free = np.array(pv.index(ident.identified), dtype=int)
    check_count(pv, data, start, len(free), x0, tuple(fixed), rtol)
    before = _pose_residuals(pv, x0, data)
    rms_before = float(np.sqrt(np.mean(whitened(pv, x0, start, W) ** 2)))

    def problem(d, v):
        W = whitening(pv, v, d, model)

        def fun(z):
            u = x0.copy()
            u[free] = z
            return whitened(pv, u, d, W).ravel()

        def jac(z):
            u = x0.copy()
            u[free] = z
            return jacobian(pv, u, d, W, free)
        return fun, jac

    def test(v):
        return point_test(pv, v, data, model)

    def usable(v):
        return reachable(pv, v, data)

    out = fit(data, x0, free, problem, robust, test=test, usable=usable, start=use)
    if not out.keep.all():   # the points kept may identify other parameters than all of them (a weak 3-PPR's a)
        kept = data.subset(out.keep & use)
        again = analyse(pv, jacobian(pv, x0, kept, whitening(pv, x0, kept, model)), rtol=rtol, fixed=tuple(fixed),
                        max_sigma=max_sigma)
        if again.identified != ident.identified:
            ident, free = again, np.array(pv.index(again.identified), dtype=int)
            check_count(pv, data, kept, len(free), x0, tuple(fixed), rtol)
            out = fit(data, x0, free, problem, robust, test=test, usable=usable, start=use, keep=out.keep,
                      v0=_refixed(out.values, x0, free))
    cov, sigma, s2 = covariance(out.residuals, out.jacobian, free, len(pv.names))
    after = _pose_residuals(pv, out.values, data)
    return _result(pv, data, out, ident, cov, sigma, s2, before, after, rms_before, model)


def _result(pv, data, out: "FitResult", ident, cov, sigma, s2, before, after, rms_before, model) -> Identification:
    keep = out.keep
    flagged = tuple(Outlier(row=int(n) + 1, label=str(data.labels[n]), normalized=float(np.sqrt(out.chi2[n])),
                            residual=tuple(float(x) for x in out.forward[n]),
                            unreachable=bool(out.chi2[n] <= out.threshold))
                    for n in np.flatnonzero(~keep))
    return Identification(parameters=pv, values=out.values, sigma=sigma, covariance=cov, identifiability=ident,
                          residuals_before=before, residuals_after=after, rms_before=rms_before,
                          rms_after=float(np.sqrt(np.mean(out.residuals ** 2))),
                          outliers=tuple(o.label for o in flagged), scale=float(np.sqrt(s2)),
                          nfev=int(out.nfev), n_points=len(data), clearances=model,
                          fit_rms_position=_rms_mm(after[keep]), flagged=flagged,
                          outlier_threshold=float(np.sqrt(out.threshold)))


def distinct_poses(data: CalibrationData) -> int:
    """The number of distinct commanded poses of ``data`` (rows of commands equal to 1e-9 mm / rad counted
    once): a point measured again at the same commands adds no information on the geometry."""
    key = np.round(np.asarray(data.commands, dtype=float), 9)
    return int(len(np.unique(key, axis=0))) if len(key) else 0


def identifiable_count(pv, frame: np.ndarray, fixed: tuple[str, ...] = (), rtol: float = RTOL) -> int:
    """The number of parameters of this robot that poses *can* identify (exact rank, fixed ones left out),
    whatever the data: the identifiability (:func:`~.identifiability.analyse`) of 60 seeded random poses the
    nominal robot reaches, in a box around its base points (a serial arm: 60 seeded random commands, a
    revolute joint's in a full turn, a prismatic one's in its range or 0 to 100 mm)."""
    rng = np.random.default_rng(0)
    sig = np.tile([0.01, 0.01, np.radians(0.01)], (60, 1))
    if isinstance(pv, SerialParameterVector):
        cols = []
        for j in pv.robot.joints:
            lo, hi = j.range
            if j.kind == "R" or not (np.isfinite(lo) and np.isfinite(hi)):
                lo, hi = (-np.pi, np.pi) if j.kind == "R" else (0.0, 100.0)
            cols.append(rng.uniform(lo, hi, 60))
        cmd = np.stack(cols, axis=-1)
        probe = CalibrationData(tuple(map(str, range(60))), cmd, serial_poses(pv, pv.nominal, cmd), sig, "<probe>")
        J = serial_jacobian(pv, pv.nominal, probe)
    else:
        pts = np.asarray(pv.robot.base_points, dtype=float)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        values = pv.nominal.copy()
        values[-3:] = frame
        found = np.zeros((0, 3))
        for _ in range(20):
            robot_poses = np.column_stack([rng.uniform(lo[0], hi[0], 400), rng.uniform(lo[1], hi[1], 400),
                                           rng.uniform(-0.35, 0.35, 400)])
            poses = frame_inverse(frame, robot_poses)
            ok = np.all(np.isfinite(commands_for(pv, values, poses)), axis=1)
            found = np.vstack([found, poses[ok]])
            if len(found) >= 60:
                break
        poses = found[:60]
        n = len(poses)
        probe = CalibrationData(tuple(map(str, range(n))), commands_for(pv, values, poses), poses, sig[:n], "<probe>")
        probe = probe.subset(reachable(pv, values, probe))
        J = jacobian(pv, values, probe, whitening(pv, values, probe))
    return len(analyse(pv, J, rtol=rtol, fixed=fixed).identified)


def check_count(pv, data: CalibrationData, start: CalibrationData, n_free: int, x0: np.ndarray,
                fixed: tuple[str, ...], rtol: float) -> None:
    """Refuse data whose distinct poses (:func:`distinct_poses`, of the points the fit starts with) give no
    more residuals than the parameters they identify: the message counts the parameters this robot has
    (:func:`identifiable_count`) and the distinct poses to measure."""
    k = distinct_poses(start)
    if 3 * k > n_free:
        return
    L = identifiable_count(pv, x0[-3:], fixed, rtol)
    n = len(data)
    if k == n:
        said = f"{n} points give {3 * n} residuals"
    elif len(start) < n:
        said = f"{len(start)} points within the nominal robot's reach, at {k} distinct poses, give {3 * k} residuals"
    else:
        said = f"{n} points at only {k} distinct pose{'s' if k != 1 else ''} give {3 * k} independent residuals"
    raise MeasurementFileError(f"{said} for the {L} identifiable parameters of this robot: measure at least "
                               f"{L // 3 + 1} distinct poses (better 3 times as many)", source=data.source)


# ------------------------------------------------------------------ serial arms: the forward residual
def serial_residuals(pv: SerialParameterVector, values: np.ndarray, data: CalibrationData) -> np.ndarray:
    """Pose residuals ``m - F^-1 FK(theta; offset + gain * c)`` ``(N, 3)`` (mm, mm, rad; phi wrapped) of a
    serial arm: its forward kinematics is explicit and single-valued, so the residual is the forward one
    (no inverse kinematics, which for a serial arm has several branches, or none for n != 3 joints)."""
    r = data.poses - serial_poses(pv, values, data.commands)
    r[:, 2] = np.angle(np.exp(1j * r[:, 2]))
    return r


def serial_whitening(pv: SerialParameterVector, values: np.ndarray, data: CalibrationData,
                     model: ClearanceModel | None = None) -> np.ndarray:
    """``W (N, 3, 3) = L^-1`` with ``L L^T = Sigma`` (:func:`measurement_covariance`): ``e = W r``."""
    if model is None or model.clearances is None:
        return np.einsum("ni,ij->nij", 1.0 / data.sigmas, np.eye(3))
    return np.linalg.inv(np.linalg.cholesky(measurement_covariance(pv, values, data, model)))


def serial_jacobian(pv: SerialParameterVector, values: np.ndarray, data: CalibrationData, cols=None,
                    W: np.ndarray | None = None) -> np.ndarray:
    """``de/dtheta (3N, len(cols))`` of the whitened forward residual ``e = W r`` (default ``W = diag(1 /
    sigma)``) by central differences."""
    W = serial_whitening(pv, values, data) if W is None else W
    cols = range(len(pv.names)) if cols is None else cols
    h = _steps(pv)
    out = []
    for j in cols:
        vp, vm = np.array(values, dtype=float), np.array(values, dtype=float)
        vp[j] += h[j]
        vm[j] -= h[j]
        d = serial_residuals(pv, vp, data) - serial_residuals(pv, vm, data)
        d[:, 2] = np.angle(np.exp(1j * d[:, 2]))
        out.append((np.einsum("nij,nj->ni", W, d) / (2 * h[j])).ravel())
    return np.stack(out, axis=-1)


def _check_start_serial(pv: SerialParameterVector, data: CalibrationData, values: np.ndarray) -> None:
    r = serial_residuals(pv, values, data)
    far = (np.hypot(r[:, 0], r[:, 1]) > MAX_START_DEVIATION_MM) | (np.degrees(np.abs(r[:, 2])) > MAX_START_DEVIATION_DEG)
    if far.sum() > len(data) // 2:
        n = int(np.flatnonzero(far)[0])
        raise MeasurementFileError(
            f"the measured pose is {np.hypot(*r[n, :2]):.3g} mm and {np.degrees(abs(r[n, 2])):.3g} deg from where the "
            f"nominal arm puts the commands (more than {MAX_START_DEVIATION_MM:g} mm or {MAX_START_DEVIATION_DEG:g} "
            f"deg, as are {far.sum()} of {len(data)} points): a measurement frame far from the arm's base (give "
            "--frame X Y PHI_DEG), poses in radians or metres, or commands of other points", source=data.source,
            key=f"row {n + 1} (point {data.labels[n]})")
    alt = data.poses.copy()
    alt[:, 2] = np.degrees(data.poses[:, 2])           # the phi_deg column read as radians
    check_phi_units(r[:, 2], serial_residuals(pv, values, CalibrationData(data.labels, data.commands, alt,
                                                                          data.sigmas, data.source))[:, 2], data)


def _identify_serial(data, pv, fixed, frame, robust, rtol, model=None,
                     max_sigma=PRACTICAL_MAX_SIGMA) -> Identification:
    n = pv.robot.n
    if data.commands.shape[1] != n:
        raise MeasurementFileError(f"{data.commands.shape[1]} commands per point for an arm of {n} joints",
                                   source=data.source)
    x0 = pv.nominal.copy()
    if frame is not None:
        x0[-3:] = np.asarray(frame, dtype=float)
    _check_start_serial(pv, data, x0)
    W0 = serial_whitening(pv, x0, data, model)
    ident = analyse(pv, serial_jacobian(pv, x0, data, W=W0), rtol=rtol, fixed=fixed, max_sigma=max_sigma)
    free = np.array(pv.index(ident.identified), dtype=int)
    check_count(pv, data, data, len(free), x0, tuple(fixed), rtol)
    before = serial_residuals(pv, x0, data)

    def problem(d, v):
        W = serial_whitening(pv, v, d, model)

        def fun(z):
            u = x0.copy()
            u[free] = z
            return np.einsum("nij,nj->ni", W, serial_residuals(pv, u, d)).ravel()

        def jac(z):
            u = x0.copy()
            u[free] = z
            return serial_jacobian(pv, u, d, free, W)
        return fun, jac

    def test(v):
        return point_test(pv, v, data, model)

    out = fit(data, x0, free, problem, robust, test=test)
    if not out.keep.all():   # the identifiability of the points kept
        kept = data.subset(out.keep)
        again = analyse(pv, serial_jacobian(pv, x0, kept, W=serial_whitening(pv, x0, kept, model)), rtol=rtol,
                        fixed=fixed, max_sigma=max_sigma)
        if again.identified != ident.identified:
            ident, free = again, np.array(pv.index(again.identified), dtype=int)
            check_count(pv, data, kept, len(free), x0, tuple(fixed), rtol)
            out = fit(data, x0, free, problem, robust, test=test, keep=out.keep, v0=_refixed(out.values, x0, free))
    cov, sigma, s2 = covariance(out.residuals, out.jacobian, free, len(pv.names))
    after = serial_residuals(pv, out.values, data)
    rms_before = float(np.sqrt(np.mean(np.einsum("nij,nj->ni", W0, before) ** 2)))
    return _result(pv, data, out, ident, cov, sigma, s2, before, after, rms_before, model)


def forward_residuals(pv, values: np.ndarray, data: CalibrationData) -> np.ndarray:
    """``(N, 3)`` (mm, mm, rad; phi wrapped): each measured pose minus where the robot ``values`` puts its
    commands, ``m - F^-1 FK(theta; offset + gain * c)``, read in the measurement frame. A parallel robot's
    forward kinematics is the exact polynomial solve (:func:`pmaccuracy.kinematics.forward_kinematics`),
    its assembly mode the one nearest the reading; NaN rows where it has none. A serial arm's:
    :func:`serial_residuals`."""
    if isinstance(pv, SerialParameterVector):
        return serial_residuals(pv, values, data)
    robot, off, gain, frame = pv.split(values)
    out = np.full((len(data), 3), np.nan)
    try:
        fk = forward_kinematics(robot, off + gain * np.asarray(data.commands, dtype=float))
    except (PoseError, GeometryError):      # pragma: no cover - commands are finite and within a turn
        return out
    has = np.any(fk.valid, axis=-1)
    if np.any(has):
        sub = FKSolution(fk.poses[has], fk.valid[has], fk.joints[has], fk.within_limits[has])
        out[has] = data.poses[has] - frame_inverse(frame, sub.nearest(frame_apply(frame, data.poses[has])))
    out[:, 2] = np.angle(np.exp(1j * out[:, 2]))
    return out


def point_test(pv, values: np.ndarray, data: CalibrationData, model: ClearanceModel | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
    """The outlier statistic of each point at ``values``: ``(chi2 (N,), r (N, 3))`` with ``r`` the forward
    residual (:func:`forward_residuals`) and ``chi2 = r^T Sigma^-1 r``, ``Sigma`` the point's predicted
    covariance (:func:`measurement_covariance`, the clearance part at the pose the model predicts);
    ``chi2 = inf`` where there is no forward residual."""
    r = forward_residuals(pv, values, data)
    ok = np.all(np.isfinite(r), axis=1)
    predicted = data.poses - np.where(ok[:, None], r, 0.0)
    at = CalibrationData(data.labels, data.commands, predicted, data.sigmas, data.source)
    S = measurement_covariance(pv, values, at, model)
    with np.errstate(all="ignore"):
        e = np.linalg.solve(np.linalg.cholesky(S), np.where(ok[:, None], r, 0.0)[..., None])[..., 0]
    chi2 = np.sum(e ** 2, axis=1)
    return np.where(ok & np.isfinite(chi2), chi2, np.inf), r


def outlier_threshold(chi2: np.ndarray) -> float:
    """The flagging bound of ``chi2`` (module docstring): the chi-square(3) :data:`OUTLIER_QUANTILE` quantile,
    times ``k = median(chi2) / median(chi2(3))`` when ``k`` exceeds :data:`UNDERSTATED` (``inf`` when most
    points have no forward residual)."""
    k = float(np.median(chi2)) / stats.chi2.median(3)
    return float(stats.chi2.ppf(OUTLIER_QUANTILE, 3) * (k if k > UNDERSTATED else 1.0))


@dataclass(frozen=True)
class FitResult:
    """What :func:`fit` returns: the ``values (P,)``, the final whitened ``residuals (3 n_kept,)`` and their
    ``jacobian (3 n_kept, L)``, the points kept ``keep (N,)``, the function evaluations ``nfev``, the outlier
    statistic ``chi2 (N,)`` and forward residuals ``forward (N, 3)`` at the estimate, and the ``threshold``
    of ``chi2`` (NaN without the robust pass)."""

    values: np.ndarray
    residuals: np.ndarray
    jacobian: np.ndarray
    keep: np.ndarray
    nfev: int
    chi2: np.ndarray
    forward: np.ndarray
    threshold: float


def _refixed(values: np.ndarray, x0: np.ndarray, free: np.ndarray) -> np.ndarray:
    """``values`` with the parameters not in ``free`` back at ``x0``."""
    out = x0.copy()
    out[free] = values[free]
    return out


def fit(data: CalibrationData, x0: np.ndarray, free: np.ndarray, problem, robust: bool = True, *, test,
        usable=None, start: np.ndarray | None = None, keep: np.ndarray | None = None,
        v0: np.ndarray | None = None) -> FitResult:
    """The fit of the module docstring on the parameters ``free`` (the others stay at ``x0``).

    ``problem(d, v) -> (fun, jac)``: the whitened residual ``(3 n,)`` and its Jacobian ``(3 n, L)`` of the
    free values ``z`` for the points ``d``, whitened at the values ``v``; ``test(v) -> (chi2 (N,), r (N, 3))``:
    the outlier statistic of every point (:func:`point_test`); ``usable(v) -> (N,)`` bool: the points
    ``problem`` can take at ``v`` (default: all); ``start (N,)``: those it can take at ``x0``.
    Given ``keep (N,)`` bool (the points an earlier fit kept) and ``v0`` (its values), the robust pass is
    skipped: the rounds of fit and test start there.
    Raises :class:`MeasurementFileError` when the points left are too few for the parameters.
    """
    L = len(free)
    N = len(data)
    everywhere = np.ones(N, dtype=bool)
    usable = usable or (lambda v: everywhere)
    use = everywhere.copy() if start is None else np.asarray(start, dtype=bool)
    v = x0.copy() if v0 is None else np.array(v0, dtype=float)
    nfev = 0
    threshold = float("nan")
    if keep is not None:
        keep = np.asarray(keep, dtype=bool) & usable(v)
    elif robust:
        fun, jac = problem(data.subset(use), x0)
        sol = optimize.least_squares(fun, x0[free], jac=jac, loss="soft_l1", f_scale=ROBUST_F_SCALE, x_scale="jac")
        nfev += sol.nfev
        v[free] = sol.x
        chi2, _ = test(v)
        threshold = outlier_threshold(chi2)
        keep = (chi2 <= threshold) & usable(v)
    else:
        keep = use
    def refit(keep: np.ndarray):
        """Least squares on the points ``keep`` from ``v`` (updated in place); returns the solution and the
        Jacobian function of its problem."""
        _enough(data, keep, L)
        fun, jac = problem(data.subset(keep), v)
        sol = optimize.least_squares(fun, v[free], jac=jac, x_scale="jac", xtol=1e-15, ftol=1e-15, gtol=1e-15,
                                     max_nfev=200)
        v[free] = sol.x
        return sol, jac

    for _ in range(MAX_ROUNDS):
        sol, jac = refit(keep)
        nfev += sol.nfev
        reach = usable(v)
        if robust:
            chi2, _ = test(v)
            threshold = outlier_threshold(chi2)
            again = (chi2 <= threshold) & reach
        else:
            again = reach
        if np.array_equal(again, keep):
            break
        keep = again
    else:
        sol, jac = refit(keep)
        nfev += sol.nfev
    chi2, r = test(v)
    if not robust and not keep.all():
        n = int(np.flatnonzero(~keep)[0])
        raise MeasurementFileError("neither the nominal robot nor the one fitted to the other points reaches the "
                                   "measured pose (without --no-robust it would be left out as an outlier)",
                                   source=data.source, key=f"row {n + 1} (point {data.labels[n]})")
    return FitResult(values=v, residuals=sol.fun, jacobian=jac(sol.x), keep=keep, nfev=nfev, chi2=chi2, forward=r,
                     threshold=threshold)


def _enough(data: CalibrationData, keep: np.ndarray, L: int) -> None:
    """Refuse a fit whose kept points give no more residuals than its ``L`` parameters."""
    if 3 * int(keep.sum()) > L:
        return
    n = int(np.flatnonzero(~keep)[0])
    raise MeasurementFileError(f"only {int(keep.sum())} of {len(data)} points agree with one robot (the others are "
                               f"outliers of it, {3 * int(keep.sum())} residuals for {L} parameters): a measurement "
                               "frame far from the robot's, poses in other units or commands of other points",
                               source=data.source, key=f"row {n + 1} (point {data.labels[n]})")


def covariance(res: np.ndarray, Jf: np.ndarray, free, P: int) -> tuple[np.ndarray, np.ndarray, float]:
    """``(s^2 (J^T J)^-1 (L, L), sigma (P,) (0 where not free), s^2)`` with ``s^2 = |e|^2 / (m - L)``; the
    inverse through the column-scaled SVD (:func:`~.identifiability.inverse_normal_matrix`), so a weakly
    determined direction keeps its large variance."""
    m, L = Jf.shape
    s2 = float(np.sum(res ** 2) / (m - L))
    cov = s2 * inverse_normal_matrix(Jf)
    sigma = np.zeros(P)
    sigma[free] = np.sqrt(np.clip(np.diag(cov), 0.0, None))   # exact data: s = 0 up to rounding
    return cov, sigma, s2


def identification_to_dict(ident: Identification) -> dict:
    """A JSON-ready record of ``ident``: the nominal robot file, every parameter (nominal, estimate, sigma;
    angles in rad, as in the code, units stated), the covariance of the identified ones, the
    identifiability (fixed parameters and their combinations in words, singular values, O1-O4) and the fit."""
    idf = ident.identifiability
    return {"robot": ident.parameters.robot.to_dict(), "parameters": ident.estimates(),
            "covariance": ident.covariance.tolist(),
            "identifiability": {"identified": list(idf.identified), "fixed": list(idf.fixed),
                                "combinations": list(idf.combinations),
                                "practical": list(idf.practical), "predicted_sigma": list(idf.predicted_sigma),
                                "singular_values": idf.singular_values.tolist(), "condition": idf.condition,
                                "O1": idf.O1, "O2": idf.O2, "O3": idf.O3, "O4": idf.O4},
            "fit": {"points": ident.n_points, "rms_before": ident.rms_before, "rms_after": ident.rms_after,
                    "scale": ident.scale, "outliers": list(ident.outliers), "nfev": ident.nfev,
                    "outlier_threshold": _finite_or_none(ident.outlier_threshold),
                    "outlier_points": [_outlier_record(o) for o in ident.flagged],
                    "rms_position_before_mm": _rms_mm(ident.residuals_before),
                    "rms_position_after_mm": _rms_mm(ident.residuals_after),
                    "fit_rms_position": ident.fit_rms_position,
                    "clearances": _clearance_label(ident.clearances)}}


def _finite_or_none(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def _outlier_record(o: Outlier) -> dict:
    """A flagged point in the record: row, point, normalized residual (None: no forward residual) and the
    forward residual in mm and degrees."""
    dx, dy, dphi = o.residual
    return {"row": o.row, "point": o.label, "normalized_residual": _finite_or_none(o.normalized),
            "dx_mm": _finite_or_none(dx), "dy_mm": _finite_or_none(dy), "dphi_deg": _finite_or_none(np.degrees(dphi))}


def _outlier_from_record(rec: dict) -> Outlier:
    def num(key, f=float):
        return float("nan") if rec.get(key) is None else f(float(rec[key]))
    norm = rec.get("normalized_residual")
    return Outlier(row=int(rec["row"]), label=str(rec["point"]), normalized=float("inf") if norm is None else float(norm),
                   residual=(num("dx_mm"), num("dy_mm"), num("dphi_deg", np.radians)))


def _clearance_label(model: ClearanceModel | None) -> str | None:
    """The clearances of the measurement covariance as written in the record: the preset name or file path
    (an object: its name), None without."""
    if model is None or model.clearances is None:
        return None
    c = model.clearances
    return str(c) if isinstance(c, (str, bytes)) or hasattr(c, "__fspath__") else str(getattr(c, "name", "<object>"))


def _rms_mm(res: np.ndarray) -> float:
    return float(np.sqrt(np.nanmean(np.sum(res[:, :2] ** 2, axis=1))))


def identification_from_dict(record: dict, source: str = "<identification>") -> Identification:
    """Rebuild an :class:`Identification` from :func:`identification_to_dict` (for compensation); raises
    :class:`~pmaccuracy.errors.ConfigError` naming the key of a malformed record."""
    try:
        table = record["robot"]
        robot = (SerialArm.from_dict(table, source=source) if table.get("architecture") == "serial"
                 else Manipulator.from_dict(table, source=source))
        pv = error_parameters(robot)
        by_name = {p["name"]: p for p in record["parameters"]}
        values = np.array([float(by_name[n]["estimate"]) for n in pv.names])
        sigma = np.array([float(by_name[n]["sigma"]) for n in pv.names])
        idf = record["identifiability"]
        fit = record["fit"]
        cov = np.array(record["covariance"], dtype=float).reshape(len(idf["identified"]), len(idf["identified"]))
        ident = Identifiability(identified=tuple(idf["identified"]), fixed=tuple(idf["fixed"]),
                                combinations=tuple(idf["combinations"]),
                                null_directions=np.zeros((len(idf["fixed"]), len(pv.names))),
                                singular_values=np.array(idf["singular_values"], dtype=float),
                                condition=float(idf["condition"]), O1=float(idf["O1"]), O2=float(idf["O2"]),
                                O3=float(idf["O3"]), O4=float(idf["O4"]),
                                practical=tuple(idf.get("practical", ())),
                                predicted_sigma=tuple(float(x) for x in idf.get("predicted_sigma", ())))
        pv.index(ident.identified)
        flagged = tuple(_outlier_from_record(o) for o in fit.get("outlier_points", ()))
        threshold = fit.get("outlier_threshold")
        threshold = float("nan") if threshold is None else float(threshold)
    except (KeyError, TypeError, ValueError) as exc:
        if isinstance(exc, ConfigError):
            raise ConfigError(exc.message, source=source, key=exc.key) from None
        raise ConfigError(f"not an identification record ({exc.__class__.__name__}: {exc})", source=source) from None
    empty = np.zeros((0, 3))
    return Identification(parameters=pv, values=values, sigma=sigma, covariance=cov, identifiability=ident,
                          residuals_before=empty, residuals_after=empty, rms_before=float(fit["rms_before"]),
                          rms_after=float(fit["rms_after"]), outliers=tuple(fit["outliers"]),
                          scale=float(fit["scale"]), nfev=int(fit["nfev"]), n_points=int(fit["points"]),
                          clearances=None if fit.get("clearances") is None else ClearanceModel(fit["clearances"]),
                          fit_rms_position=float(fit.get("fit_rms_position", fit.get("rms_position_after_mm", "nan"))),
                          flagged=flagged, outlier_threshold=threshold)
