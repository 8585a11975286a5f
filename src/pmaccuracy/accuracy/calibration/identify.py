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

Fit: :func:`scipy.optimize.least_squares` (trust-region reflective) on the identified parameters (the
others fixed at nominal by :func:`~.identifiability.analyse`), first with the robust ``soft_l1`` loss
(``f_scale = 3``); points whose whitened residual norm squared exceeds the chi-square(3) 99.9 % quantile
times the robust scale are reported as outliers and dropped; a second, plain least-squares fit on the
inliers gives the estimate and its covariance ``s^2 (J^T J)^-1`` with ``s^2 = |e|^2 / (m - L)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats

from ...errors import ConfigError, GeometryError, MeasurementFileError
from ...model.manipulator import Manipulator
from .data import CalibrationData
from .identifiability import Identifiability, RTOL, analyse
from .parameters import ParameterVector, error_parameters, frame_apply, joint_values, leg_joint_value

#: Outlier threshold: the chi-square(3) quantile of a point's whitened residual norm squared.
OUTLIER_QUANTILE = 0.999
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


def whitening(pv: ParameterVector, values: np.ndarray, data: CalibrationData) -> np.ndarray:
    """``W (N, 3, 3) = Sigma^(-1/2) G^-1`` (module docstring)."""
    G = pose_sensitivity(pv, values, data.commands, data.poses)
    bad = ~np.all(np.isfinite(G.reshape(len(G), -1)), axis=1)
    if np.any(bad):
        n = int(np.flatnonzero(bad)[0])
        raise MeasurementFileError("the measured pose is out of the robot's reach", source=data.source,
                                   key=f"row {n + 1} (point {data.labels[n]})")
    with np.errstate(all="ignore"):
        Ginv = np.linalg.inv(G)
    return Ginv / data.sigmas[:, :, None]


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


def check_start(pv: ParameterVector, data: CalibrationData, frame: np.ndarray | None = None) -> None:
    """Refuse data the nominal robot (and frame) cannot explain: a pose it cannot reach, or more than half the
    points further than :data:`MAX_START_DEVIATION_MM` / :data:`MAX_START_DEVIATION_DEG` (first order) from where
    it puts the commands (a frame far from the robot's, poses in radians or metres, commands of other points).
    :class:`MeasurementFileError` naming the (first) row."""
    values = pv.nominal.copy()
    if frame is not None:
        values[-3:] = frame
    r = raw_residuals(pv, values, data.commands, data.poses)
    G = pose_sensitivity(pv, values, data.commands, data.poses)
    with np.errstate(all="ignore"):
        dm = np.linalg.solve(G, r[..., None])[..., 0]
    far = np.zeros(len(data), dtype=bool)
    for n in range(len(data)):
        where = f"row {n + 1} (point {data.labels[n]})"
        if not np.all(np.isfinite(dm[n])):
            raise MeasurementFileError("the nominal robot cannot reach the measured pose: a measurement frame far "
                                       "from the robot's (give its pose, --frame X Y PHI_DEG) or a pose in other "
                                       "units (x, y in mm, phi_deg in degrees)", source=data.source, key=where)
        far[n] = (np.hypot(*dm[n, :2]) > MAX_START_DEVIATION_MM or
                  np.degrees(abs(dm[n, 2])) > MAX_START_DEVIATION_DEG)
    if far.sum() > len(data) // 2:   # a single far point is left to the robust fit (an outlier)
        n = int(np.flatnonzero(far)[0])
        dxy, dphi = float(np.hypot(*dm[n, :2])), float(np.degrees(abs(dm[n, 2])))
        raise MeasurementFileError(
            f"the measured pose is {dxy:.3g} mm and {dphi:.3g} deg from where the nominal robot puts the commands "
            f"(more than {MAX_START_DEVIATION_MM:g} mm or {MAX_START_DEVIATION_DEG:g} deg, as are {far.sum()} of "
            f"{len(data)} points): a measurement frame far from the robot's (give --frame X Y PHI_DEG), poses in "
            "radians or metres, or commands of other points", source=data.source,
            key=f"row {n + 1} (point {data.labels[n]})")


@dataclass(frozen=True)
class Identification:
    """Result of :func:`identify`.

    ``values (P,)``: all parameters (fixed ones at nominal), ``sigma (P,)``: 1-sigma (0 for fixed),
    ``covariance (L, L)`` of the identified ones (in the order of ``identifiability.identified``),
    ``rms_before`` / ``rms_after``: RMS of the whitened residuals at nominal and at the estimate (inliers),
    ``residuals_before`` / ``residuals_after`` ``(N, 3)``: pose residuals ``G^-1 r`` (mm, mm, rad),
    ``outliers``: labels of the points dropped, ``scale``: the residual scale ``s``, ``cost``, ``nfev``.
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
             rtol: float = RTOL) -> Identification:
    """Identify the error parameters from calibration ``data`` (module docstring for the method).

    ``parameters`` (or ``robot``): the nominal; ``fixed``: names kept at nominal; ``frame``: a starting
    measurement frame ``(x mm, y mm, phi rad)`` when the camera's frame is far from the robot's.
    Raises :class:`~pmaccuracy.errors.ConfigError` for an unknown parameter name or fewer residuals than
    parameters, :class:`~pmaccuracy.errors.MeasurementFileError` naming the row of an implausible point.
    """
    pv = parameters if parameters is not None else error_parameters(robot)
    pv.index(fixed)
    x0 = pv.nominal.copy()
    if frame is not None:
        x0[-3:] = np.asarray(frame, dtype=float)
    check_start(pv, data, x0[-3:])
    W = whitening(pv, x0, data)
    J = jacobian(pv, x0, data, W)
    ident = analyse(pv, J, rtol=rtol, fixed=tuple(fixed))
    free = np.array(pv.index(ident.identified), dtype=int)
    L = len(free)
    if 3 * len(data) <= L:
        raise MeasurementFileError(f"{len(data)} points give {3 * len(data)} residuals for {L} identifiable "
                                   f"parameters: measure at least {L // 3 + 1} points (better 3 times as many)",
                                   source=data.source)
    before = _pose_residuals(pv, x0, data)
    e0 = whitened(pv, x0, data, W)
    rms_before = float(np.sqrt(np.mean(e0 ** 2)))

    def fun(z, d, w):
        v = x0.copy()
        v[free] = z
        return whitened(pv, v, d, w).ravel()

    def jac(z, d, w):
        v = x0.copy()
        v[free] = z
        return jacobian(pv, v, d, w, free)

    nfev = 0
    z = x0[free]
    keep = np.ones(len(data), dtype=bool)
    if robust:
        sol = optimize.least_squares(fun, z, jac=jac, args=(data, W), loss="soft_l1", f_scale=3.0, x_scale="jac")
        nfev += sol.nfev
        z = sol.x
        e = sol.fun.reshape(-1, 3)
        chi = np.sum(e ** 2, axis=1)
        robust_scale = max(1.0, float(np.median(chi) / stats.chi2.median(3)))
        keep = chi <= stats.chi2.ppf(OUTLIER_QUANTILE, 3) * robust_scale
        if 3 * keep.sum() <= L:
            keep[:] = True
    d_in = data.subset(keep)
    v = x0.copy()
    v[free] = z
    W_in = whitening(pv, v, d_in)
    sol = optimize.least_squares(fun, z, jac=jac, args=(d_in, W_in), x_scale="jac", xtol=1e-15, ftol=1e-15,
                                 gtol=1e-15, max_nfev=200)
    nfev += sol.nfev
    v[free] = sol.x
    Jf = jacobian(pv, v, d_in, W_in, free)
    m = Jf.shape[0]
    s2 = float(np.sum(sol.fun ** 2) / (m - L))
    cov = s2 * np.linalg.pinv(Jf.T @ Jf)
    sigma = np.zeros(len(pv.names))
    sigma[free] = np.sqrt(np.clip(np.diag(cov), 0.0, None))   # exact data: s = 0 up to rounding
    after = _pose_residuals(pv, v, data)
    return Identification(parameters=pv, values=v, sigma=sigma, covariance=cov, identifiability=ident,
                          residuals_before=before, residuals_after=after, rms_before=rms_before,
                          rms_after=float(np.sqrt(np.mean(sol.fun ** 2))),
                          outliers=tuple(np.asarray(data.labels, dtype=object)[~keep]), scale=float(np.sqrt(s2)),
                          nfev=int(nfev), n_points=len(data))


def identification_to_dict(ident: Identification) -> dict:
    """A JSON-ready record of ``ident``: the nominal robot file, every parameter (nominal, estimate, sigma;
    angles in rad, as in the code, units stated), the covariance of the identified ones, the
    identifiability (fixed parameters and their combinations in words, singular values, O1-O4) and the fit."""
    idf = ident.identifiability
    return {"robot": ident.parameters.robot.to_dict(), "parameters": ident.estimates(),
            "covariance": ident.covariance.tolist(),
            "identifiability": {"identified": list(idf.identified), "fixed": list(idf.fixed),
                                "combinations": list(idf.combinations),
                                "singular_values": idf.singular_values.tolist(), "condition": idf.condition,
                                "O1": idf.O1, "O2": idf.O2, "O3": idf.O3, "O4": idf.O4},
            "fit": {"points": ident.n_points, "rms_before": ident.rms_before, "rms_after": ident.rms_after,
                    "scale": ident.scale, "outliers": list(ident.outliers), "nfev": ident.nfev,
                    "rms_position_before_mm": _rms_mm(ident.residuals_before),
                    "rms_position_after_mm": _rms_mm(ident.residuals_after)}}


def _rms_mm(res: np.ndarray) -> float:
    return float(np.sqrt(np.nanmean(np.sum(res[:, :2] ** 2, axis=1))))


def identification_from_dict(record: dict, source: str = "<identification>") -> Identification:
    """Rebuild an :class:`Identification` from :func:`identification_to_dict` (for compensation); raises
    :class:`~pmaccuracy.errors.ConfigError` naming the key of a malformed record."""
    try:
        pv = error_parameters(Manipulator.from_dict(record["robot"], source=source))
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
                                O3=float(idf["O3"]), O4=float(idf["O4"]))
        pv.index(ident.identified)
    except (KeyError, TypeError, ValueError) as exc:
        if isinstance(exc, ConfigError):
            raise ConfigError(exc.message, source=source, key=exc.key) from None
        raise ConfigError(f"not an identification record ({exc.__class__.__name__}: {exc})", source=source) from None
    empty = np.zeros((0, 3))
    return Identification(parameters=pv, values=values, sigma=sigma, covariance=cov, identifiability=ident,
                          residuals_before=empty, residuals_after=empty, rms_before=float(fit["rms_before"]),
                          rms_after=float(fit["rms_after"]), outliers=tuple(fit["outliers"]),
                          scale=float(fit["scale"]), nfev=int(fit["nfev"]), n_points=int(fit["points"]))
