"""A virtual calibration of a spatial robot: a true robot drawn within tolerances, readings of it, identification.

The true robot is the nominal plus seeded normal errors (1-sigma per unit: :data:`DEFAULT_ERROR_SIGMA`), the
parameters the data cannot separate left at nominal (so the truth is in the gauge the identification
reports). Commands are those that put the *nominal* robot at the D-optimal poses of
:func:`~.spatial_plan.plan_spatial_poses` (``plan="d-optimal"``, the default) or at the first of the random
candidates (``plan="random"``), both out of poses drawn in a box around its home pose (:func:`candidate_poses`:
the controlled coordinates uniform, the rest completed, kept where every leg is within its limits); the true
robot goes where its forward kinematics says; with ``clearances`` (:class:`~pmaccuracy.model.spatial_sources
.SpatialErrorSources`) every reading gets its own clearance state (:func:`clearance_twists`: each source's
variables uniform in its unit segment, disc or ball, independent from reading to reading and between sources,
the law of :mod:`pmaccuracy.accuracy.spatial_statistics`) which moves the platform by the FIRST-ORDER twist
``t = sum_s M_s x_s`` of :mod:`pmaccuracy.accuracy.spatial_bounds` (Eq. 1 there, on the true robot at the
reached pose; as the planar experiment does, :mod:`.simulate`): ``p + v``, ``exp([w]x) R``; the device reads
it in the true frame with normal noise: position ``N(0, sigma_mm^2)`` per axis, orientation ``exp([eta]x) R``
with ``eta ~ N(0, sigma_rad^2)`` per axis, or for a laser tracker ``sigma = sigma_mm + ppm 1e-6 |x|`` with
``|x|`` the target's distance from the device.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import ConfigError
from ...kinematics.spatial import inverse_kinematics
from ...model.spatial_sources import SpatialErrorSources
from ...numerics.spatial import rotations, rotvecs
from .spatial_identify import (DEFAULT_SIGMA_MM, DEFAULT_SIGMA_RAD, SpatialCalibrationData, SpatialIdentification,
                               identify_spatial, platform_poses, predict, spatial_identifiability)
from .identifiability import PRACTICAL_MAX_SIGMA
from .spatial_compensate import (SpatialCompensation, clearance_floor, clearance_twists,  # noqa: F401
                                 compensate_spatial, displaced, pose_errors)
from .spatial_parameters import SpatialParameterVector
from .spatial_plan import BOX_DEG, BOX_SHARE, SpatialPlan, candidate_poses, plan_spatial_poses  # noqa: F401

#: 1-sigma errors of the true robot per unit (mm, rad, gain).
DEFAULT_ERROR_SIGMA = {"mm": 0.1, "rad": np.radians(0.1), "1": 5e-4}
def spatial_true_parameters(pv: SpatialParameterVector, seed: int = 0, error_sigma: dict | None = None,
                            fixed: tuple[str, ...] = ()) -> np.ndarray:
    """The nominal plus seeded normal errors (1-sigma per unit, :data:`DEFAULT_ERROR_SIGMA` overridden by
    ``error_sigma``); the parameters ``fixed`` stay nominal."""
    sig = {**DEFAULT_ERROR_SIGMA, **(error_sigma or {})}
    rng = np.random.default_rng(seed)
    v = pv.nominal + rng.standard_normal(len(pv.names)) * np.array([sig[u] for u in pv.units])
    idx = pv.index(fixed)
    v[idx] = pv.nominal[idx]
    return v


def measure_spatial(pv: SpatialParameterVector, true_values, commands, *, noise=(0.01, np.radians(0.01)),
                    ppm: float = 0.0, seed: int = 0, labels=None, clearances=None) -> SpatialCalibrationData:
    """Readings of the true robot ``true_values`` at ``commands (N, n)`` (module docstring): full poses
    ``(N, 6)``, or for position-only ``pv`` every target at every command (``N T`` rows). ``noise``:
    ``(sigma_mm, sigma_rad)``; ``ppm``: the tracker's distance-dependent part (1e-6 per mm of distance);
    ``clearances`` (:class:`~pmaccuracy.model.spatial_sources.SpatialErrorSources`, a preset or a file): one
    clearance state per command (:func:`~.spatial_compensate.clearance_twists`, first order, drawn from its own
    stream ``default_rng([seed, 1])``: the same states with or without noise), shared by the targets read at it.
    The stated sigmas are those of ``noise`` (where 0: :data:`~.spatial_identify.DEFAULT_SIGMA_MM`, ``_RAD``, so
    noise-free readings can be weighted). Commands the true robot cannot take (no forward kinematics, or near
    a singularity with clearances) are dropped."""
    commands = np.asarray(commands, dtype=float)
    rng = np.random.default_rng(seed)
    poses = platform_poses(pv, true_values, commands, _nominal_guess(pv, commands))
    if clearances is not None:
        poses = displaced(poses, clearance_twists(pv.split(true_values)[0], clearances, poses,
                                                  np.random.default_rng([seed, 1])))
    ok = np.all(np.isfinite(poses), axis=1)
    commands, poses = commands[ok], poses[ok]
    labels = np.arange(1, len(ok) + 1)[ok] if labels is None else np.asarray(labels)[ok]
    s_mm, s_rad = noise
    w_mm, w_rad = (s_mm or DEFAULT_SIGMA_MM), (s_rad or DEFAULT_SIGMA_RAD)
    if pv.kind == "pose":
        m = predict(pv, true_values, poses)
        sig = np.tile([w_mm] * 3 + [w_rad] * 3, (len(m), 1))
        m[:, :3] += rng.standard_normal((len(m), 3)) * s_mm
        m[:, 3:] = rotvecs(rotations(rng.standard_normal((len(m), 3)) * s_rad) @ rotations(m[:, 3:]))
        target = np.zeros(len(m), dtype=int)
        lab = [str(x) for x in labels]
    else:
        T = pv.n_targets
        target = np.tile(np.arange(T), len(poses))
        commands = np.repeat(commands, T, axis=0)
        poses = np.repeat(poses, T, axis=0)
        lab = [f"{x}" for x in np.repeat(labels, T)]
        m = predict(pv, true_values, poses, target)
        s = s_mm + ppm * 1e-6 * np.linalg.norm(m, axis=1)
        m = m + rng.standard_normal(m.shape) * s[:, None]
        sig = np.repeat(np.where(s > 0, s, w_mm)[:, None], 3, axis=1)
    return SpatialCalibrationData(tuple(lab), commands, m, sig, target, "<simulated>")


def _nominal_guess(pv: SpatialParameterVector, commands) -> np.ndarray:
    """Poses of the nominal robot at ``commands`` (the guess that keeps the true robot in the same mode)."""
    return platform_poses(pv, pv.nominal, commands)


@dataclass(frozen=True)
class SpatialExperiment:
    """Result of :func:`simulate_spatial_calibration`.

    Attributes
    ----------
    true : ndarray ``(P,)``
        The true parameters.
    data : SpatialCalibrationData
        The readings.
    identification : SpatialIdentification
        What the identification found.
    targets : ndarray ``(T, 6)``
        Poses (device frame) where the compensation is checked, none of them a calibration pose.
    errors_before, errors_after : ndarray ``(T, 2)``
        Position (mm) and orientation (rad) errors of the true robot there with the nominal and the compensated
        commands (:func:`~.spatial_compensate.pose_errors`; no noise; with clearances, one clearance state per
        target).
    compensation : SpatialCompensation or None
        The compensated commands at the targets, their predicted sigma and the clearance floor there.
    plan : SpatialPlan or None
        The D-optimal plan of the readings' poses (None: random poses).
    clearances : SpatialErrorSources or None
        The clearances of the readings and the checks.
    """

    true: np.ndarray
    data: SpatialCalibrationData
    identification: SpatialIdentification
    targets: np.ndarray | None = None
    errors_before: np.ndarray | None = None
    errors_after: np.ndarray | None = None
    compensation: SpatialCompensation | None = None
    plan: SpatialPlan | None = None
    clearances: object = None

    def normalized_errors(self) -> np.ndarray:
        """``(estimate - true) / sigma`` of the identified parameters ``(L,)``."""
        ident = self.identification
        idx = ident.parameters.index(ident.identifiability.identified)
        return (ident.values[idx] - self.true[idx]) / ident.sigma[idx]


#: Ways of choosing the readings' poses in :func:`simulate_spatial_calibration`.
PLANS = ("d-optimal", "random")


def simulate_spatial_calibration(pv: SpatialParameterVector, n_poses: int = 60, *, seed: int = 0,
                                 error_sigma: dict | None = None, noise=(0.01, np.radians(0.01)),
                                 ppm: float = 0.0, gross: int = 0, n_targets: int = 30, clearances=None,
                                 plan: str = "d-optimal", n_candidates: int = 4000, true=None) -> SpatialExperiment:
    """Virtual calibration (module docstring): ``n_poses`` poses out of ``n_candidates`` random candidates
    (``plan``: ``"d-optimal"``, :func:`~.spatial_plan.plan_spatial_poses`, or ``"random"``: the first ones),
    readings of the true robot (with ``clearances``: a clearance state per reading),
    :func:`~.spatial_identify.identify_spatial` (given the same clearances, as the planar experiment does);
    ``gross`` readings get a 100-sigma error; then the
    compensation (:func:`~.spatial_compensate.compensate_spatial`, with the clearance floor) at ``n_targets``
    other candidate poses, checked on the true robot (with a clearance state per target). ``true (P,)``: the true
    robot's parameters (e.g. :func:`~.simulate.true_parameters` of named errors and tolerances) instead of the
    seeded errors of :func:`spatial_true_parameters` (``error_sigma`` is then not used)."""
    if plan not in PLANS:
        raise ConfigError(f"unknown plan {plan!r} (choose from {', '.join(PLANS)})", key="plan")
    if true is not None:
        true = np.asarray(true, dtype=float)
        if true.shape != (len(pv.names),) or not np.all(np.isfinite(true)):
            raise ConfigError(f"must be {len(pv.names)} finite parameter values", key="true")
    sources = None if clearances is None else SpatialErrorSources.load(clearances, pv.robot)
    cand = candidate_poses(pv, max(n_candidates, 20 * n_poses, 2000), seed=seed)
    if len(cand) < n_poses + n_targets:
        raise ConfigError(f"only {len(cand)} candidate poses within the limits around home for {n_poses} readings "
                          f"and {n_targets} checks", key="n_poses")
    chosen = None
    if plan == "d-optimal":
        chosen = plan_spatial_poses(pv, n_poses, cand, seed=seed)
        poses, used = chosen.poses, chosen.indices
    else:
        used = np.arange(n_poses)
        poses = cand[used]
    commands = inverse_kinematics(pv.robot, poses).q
    if true is None:
        probe = measure_spatial(pv, pv.nominal, commands, noise=(0.0, 0.0))
        probe = SpatialCalibrationData(probe.labels, probe.commands, probe.measured,
                                       np.tile([noise[0] or DEFAULT_SIGMA_MM] * 3 + [noise[1] or DEFAULT_SIGMA_RAD] * 3,
                                               (len(probe), 1))[:, :probe.measured.shape[1]], probe.target)
        fixed = spatial_identifiability(pv, probe, max_sigma=PRACTICAL_MAX_SIGMA).fixed
        true = spatial_true_parameters(pv, seed, error_sigma, fixed)
    data = measure_spatial(pv, true, commands, noise=noise, ppm=ppm, seed=seed + 1, clearances=sources)
    if gross:
        rng = np.random.default_rng(seed + 2)
        rows = rng.choice(len(data), gross, replace=False)
        data.measured[rows, :3] += 100.0 * data.sigmas[rows, :3] * rng.choice([-1.0, 1.0], (gross, 3))
    ident = identify_spatial(data, pv, clearances=sources)
    rest = np.setdiff1d(np.arange(len(cand)), used)
    targets = cand[rest[:n_targets]]
    comp = compensate_spatial(ident, targets, clearances=sources)
    return SpatialExperiment(true=true, data=data, identification=ident, targets=targets,
                             errors_before=pose_errors(pv, true, comp.nominal_commands, targets, clearances=sources,
                                                       seed=seed + 3),
                             errors_after=pose_errors(pv, true, comp.commands, targets, clearances=sources,
                                                      seed=seed + 3),
                             compensation=comp, plan=chosen, clearances=sources)

