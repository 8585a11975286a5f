"""A virtual calibration experiment: a "true" robot, its measurements on the exact model, identification and
compensation, and the accuracy measured again.

The true robot is the nominal plus seeded parameter errors (``error_sigma``: 1-sigma per unit, mm / rad /
gain, drawn normal). A command ``c`` puts it where its exact forward kinematics
(:func:`pmaccuracy.kinematics.forward_kinematics`, the assembly mode nearest the nominal pose) says, for the
joint values ``offset + gain * c``; the joint clearances displace that pose by a random state inside their
sets (:func:`pmaccuracy.accuracy.distributions.sample_pose_errors`, first order, each source uniform in its
set and independent from pose to pose: the law :func:`.identify.identify` assumes when it is given the same
clearances, as the experiment does); the camera reads it in the true measurement frame with normal noise
``noise`` (mm, mm, rad). Nothing of this goes through the inverse-kinematic residual of :mod:`.identify`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ...errors import ConfigError
from ...kinematics import FKSolution, forward_kinematics
from ...model import _tomlio
from ..distributions import sample_pose_errors
from .compensate import SERIAL_PHI_WEIGHT, Compensation, compensate, sample_serial_errors, serial_pose_jacobian
from .data import CalibrationData
from .identify import Identification, identify
from .parameters import (ParameterVector, SerialParameterVector, actuators, commands_for, frame_apply, frame_inverse,
                         serial_poses)
from .plan import candidate_commands, candidate_poses, plan_poses

#: A true pose further than this (mm, deg) from the nominal one counts as not reached (a singularity between).
MAX_JUMP_MM = 5.0
MAX_JUMP_DEG = 5.0
#: Default 1-sigma parameter errors of the true robot: mm, rad, gain.
#: A serial arm's target configurations keep the smallest singular value of their weighted pose Jacobian
#: (mm per rad or mm per mm) above this: away from its singularities (a stretched elbow).
MIN_SERIAL_SINGULAR_MM = 20.0
DEFAULT_ERROR_SIGMA = {"mm": 0.1, "rad": np.radians(0.1), "1": 5e-4}


def true_parameters(pv: ParameterVector, seed: int = 0, error_sigma: dict | None = None,
                    fixed: tuple[str, ...] = (), *, errors: dict | None = None,
                    tolerances: dict | None = None) -> np.ndarray:
    """The true parameters ``(P,)``: the nominal plus seeded errors; ``fixed`` names stay nominal.

    By default every parameter gets a normal error of 1-sigma ``error_sigma`` per unit (mm, rad, gain:
    :data:`DEFAULT_ERROR_SIGMA`). Given ``errors {name: value}`` (mm / rad / gain, added as they are) and/or
    ``tolerances {name: t}`` (a uniform draw in ``[-t, t]``, seeded, per named parameter), the true robot is
    the nominal plus those, and the parameters they do not name stay nominal (``error_sigma`` is then not
    used: :class:`~pmaccuracy.errors.ConfigError` if given). Raises ConfigError naming an unknown parameter
    or a value that is not a finite number (a tolerance: >= 0)."""
    if errors is None and tolerances is None:
        sig = {**DEFAULT_ERROR_SIGMA, **(error_sigma or {})}
        rng = np.random.default_rng(seed)
        v = pv.nominal + rng.standard_normal(len(pv.names)) * np.array([sig[u] for u in pv.units])
    else:
        if error_sigma is not None:
            raise ConfigError("not with named errors or tolerances (they say the true robot's errors)",
                              key="error_sigma")
        v = pv.nominal.copy()
        for table, what in ((errors, "errors"), (tolerances, "tolerances")):
            for name, value in (table or {}).items():
                pv.index([name])
                if not (isinstance(value, (int, float, np.floating, np.integer)) and np.isfinite(value)
                        and (what == "errors" or value >= 0)):
                    raise ConfigError(f"must be a finite number{'' if what == 'errors' else ' >= 0'}, got {value!r}",
                                      key=name)
        for name, value in (errors or {}).items():
            v[pv.index([name])[0]] += float(value)
        if tolerances:
            names = list(tolerances)
            half = np.array([float(tolerances[n]) for n in names])
            v[pv.index(names)] += np.random.default_rng(seed).uniform(-1.0, 1.0, len(names)) * half
    v[pv.index(fixed)] = pv.nominal[pv.index(fixed)]
    return v


def _finite(value: int | float) -> bool:
    """Whether a number read from TOML is a finite double (an integer beyond 1e308 is not)."""
    try:
        return math.isfinite(float(value))
    except OverflowError:
        return False


def load_parameter_table(spec, pv: ParameterVector, kind: str = "errors") -> dict[str, float]:
    """Read a TOML file of ``name = value`` per error parameter (``kind``: ``"errors"``, the parameter errors
    of the true robot, or ``"tolerances"``, the half-widths of their uniform draws) into library units.

    File format (mm, degrees, and a gain's error as a fraction; dotted names may be quoted or not)::

        "leg1.base.x" = 0.2          # mm
        leg2.actuator.offset = 0.05  # deg (a revolute actuator)
        leg3.actuator.gain = 5e-4    # 1 + 5e-4 times the command

    Raises :class:`~pmaccuracy.errors.ConfigError` naming the file and the parameter: an unknown name, a
    value that is not a finite number (a tolerance: >= 0)."""
    data, source = _tomlio.read_spec(spec, kind=f"parameter {kind}", folder=None)
    flat: dict[str, object] = {}

    def walk(table: dict, prefix: str) -> None:
        for key, value in table.items():
            if isinstance(value, dict):
                walk(value, f"{prefix}{key}.")
            else:
                flat[f"{prefix}{key}"] = value
    walk(data, "")
    units = dict(zip(pv.names, pv.units))
    out = {}
    for name, value in flat.items():
        if name not in units:
            try:
                pv.index([name])
            except ConfigError as exc:
                raise ConfigError(exc.message, source=source, key=name) from None
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not _finite(value) or \
                (kind == "tolerances" and value < 0):
            raise ConfigError(f"must be a finite number{' >= 0' if kind == 'tolerances' else ''} "
                              f"({'deg' if units[name] == 'rad' else units[name]}), got {value!r}",
                              source=source, key=name)
        out[name] = float(np.radians(value)) if units[name] == "rad" else float(value)
    return out


def measure(pv: ParameterVector, true_values: np.ndarray, commands: np.ndarray, reference: np.ndarray, *,
            noise=(0.01, 0.01, np.radians(0.01)), clearances=None, seed: int = 0) -> np.ndarray:
    """Measured poses ``(N, 3)`` (measurement frame; mm, mm, rad) of the true robot at ``commands (N, 3)``.

    ``reference (N, 3)``: robot-frame poses near which the assembly mode is taken (the nominal poses).
    NaN rows where the true robot has no assembly mode for the commands or none within :data:`MAX_JUMP_MM`
    / :data:`MAX_JUMP_DEG` of the reference (it would have to pass a singularity: a real robot jams there).
    """
    if isinstance(pv, SerialParameterVector):
        return measure_serial(pv, true_values, commands, noise=noise, clearances=clearances, seed=seed)
    reference = np.asarray(reference, dtype=float)
    robot, off, gain, frame = pv.split(true_values)
    fk = forward_kinematics(robot, off + gain * np.asarray(commands, dtype=float))
    reach = np.any(fk.valid, axis=-1)
    poses = np.full((len(reach), 3), np.nan)
    if np.any(reach):
        poses[reach] = FKSolution(fk.poses[reach], fk.valid[reach], fk.joints[reach], fk.within_limits[reach]
                                  ).nearest(np.asarray(reference, dtype=float)[reach])
    jump = np.hypot(*(poses[:, :2] - reference[:, :2]).T) > MAX_JUMP_MM
    jump |= np.abs(np.angle(np.exp(1j * (poses[:, 2] - reference[:, 2])))) > np.radians(MAX_JUMP_DEG)
    reach &= ~jump
    poses[~reach] = np.nan
    rng = np.random.default_rng(seed)
    if clearances is not None and np.any(reach):
        n = int(reach.sum())   # one independent clearance state per pose: the diagonal of (state, pose)
        e = sample_pose_errors(robot, clearances, poses[reach], n, seed=rng)
        poses[reach] = poses[reach] + e[np.arange(n), np.arange(n)]
    m = frame_inverse(frame, poses)
    return m + rng.standard_normal(m.shape) * np.asarray(noise, dtype=float)


def measure_serial(pv: SerialParameterVector, true_values: np.ndarray, commands: np.ndarray, *,
                   noise=(0.01, 0.01, np.radians(0.01)), clearances=None, seed: int = 0) -> np.ndarray:
    """Measured poses ``(N, 3)`` of the true serial arm at ``commands (N, n)``: its explicit forward
    kinematics, one clearance state per pose drawn uniformly in the sets of its sources
    (:func:`~.compensate.sample_serial_errors`, first order, base frame), read in the true measurement frame
    with normal ``noise`` (mm, mm, rad)."""
    rng = np.random.default_rng(seed)
    base = true_values.copy()
    base[-3:] = 0.0
    poses = serial_poses(pv, base, commands)
    if clearances is not None:
        arm, off, gain, _ = pv.split(true_values)
        e = sample_serial_errors(arm, clearances, off + gain * np.asarray(commands, dtype=float), 1, seed=rng)[0]
        poses = poses + e
    m = frame_inverse(np.asarray(true_values)[-3:], poses)
    return m + rng.standard_normal(m.shape) * np.asarray(noise, dtype=float)


@dataclass(frozen=True)
class Experiment:
    """Result of :func:`simulate_calibration`: the ``true`` parameters, the measured ``data``, the ``identification``, the ``compensation`` at the
    targets, and the pose errors measured on the true robot at the targets before (nominal commands) and after
    (compensated commands): ``errors_before`` / ``errors_after`` ``(T, 3)`` (mm, mm, rad, measurement frame)."""

    true: np.ndarray
    data: CalibrationData
    identification: Identification
    compensation: Compensation
    targets: np.ndarray
    errors_before: np.ndarray
    errors_after: np.ndarray

    def __repr__(self) -> str:
        b = np.hypot(*self.errors_before[:, :2].T).max()
        a = np.hypot(*self.errors_after[:, :2].T).max()
        return f"Experiment(max position error {b:.4g} mm -> {a:.4g} mm at {len(self.targets)} targets)"


def simulate_calibration(pv: ParameterVector, n_poses: int = 30, *, seed: int = 0, error_sigma: dict | None = None,
             noise=(0.01, 0.01, np.radians(0.01)), clearances=None, n_targets: int = 50,
             true_fixed: tuple[str, ...] = (), measure_with: Callable | None = None, errors: dict | None = None,
             tolerances: dict | None = None) -> Experiment:
    """Run the virtual calibration experiment (module docstring): plan ``n_poses``, measure, identify,
    compensate at ``n_targets`` random candidate poses, measure again.

    The true robot (:func:`true_parameters`): normal errors of 1-sigma ``error_sigma`` per unit on every
    parameter, or the named ``errors {name: value}`` and/or ``tolerances {name: half-width}`` (a seeded
    uniform draw), library units (mm, rad, gain); :func:`load_parameter_table` reads them from a file.

    ``measure_with(pv, true, commands, reference, seed) -> CalibrationData`` replaces the measurement of the
    planned poses (e.g. :func:`pmaccuracy.vision.calibration_photos.photo_measurer`: photos rendered and
    measured); ``noise`` then applies to the compensation's check only (there without noise).
    """
    true = true_parameters(pv, seed, error_sigma, true_fixed, errors=errors, tolerances=tolerances)
    if isinstance(pv, SerialParameterVector):
        return _simulate_serial(pv, true, n_poses, seed=seed, noise=noise, clearances=clearances, n_targets=n_targets,
                                measure_with=measure_with, errors=errors, tolerances=tolerances)
    cand = candidate_poses(pv)
    plan = plan_poses(pv, n_poses, cand, seed=seed)
    data = _measured(pv, true, plan, noise, clearances, seed, measure_with)
    _check_reached(len(data), len(plan.commands), errors, tolerances)
    ident = identify(data, pv, clearances=clearances)
    rng = np.random.default_rng(seed + 2)
    lim = np.array([c.actuated.range for c in pv.robot.chains])
    ok = np.ones(len(cand), dtype=bool)
    for values in (pv.nominal, ident.values):   # targets both robots reach within the actuator ranges
        q = commands_for(pv, values, cand)
        ok &= np.all(np.isfinite(q) & (q >= lim[:, 0]) & (q <= lim[:, 1]), axis=1)
    pool = cand[ok]
    targets = pool[rng.choice(len(pool), min(n_targets, len(pool)), replace=False)]
    comp = compensate(ident, targets, clearances=clearances)
    before = measure(pv, true, comp.nominal_commands, targets, noise=(0, 0, 0), clearances=clearances,
                     seed=seed + 3) - targets
    after = measure(pv, true, comp.commands, frame_apply(ident.values[-3:], targets), noise=(0, 0, 0),
                    clearances=clearances, seed=seed + 3) - targets
    for e in (before, after):
        e[:, 2] = np.angle(np.exp(1j * e[:, 2]))
    return Experiment(true=true, data=data, identification=ident, compensation=comp, targets=targets, errors_before=before,
                      errors_after=after)


#: Smallest share of the planned poses the true robot must reach for a virtual calibration to go on.
MIN_REACHED_SHARE = 0.5


def _check_reached(reached: int, planned: int, errors, tolerances) -> None:
    """Refuse a true robot that reaches fewer than :data:`MIN_REACHED_SHARE` of the planned poses: its
    parameter errors are too large for a calibration (often a unit slip: metres or degrees given as mm).
    The :class:`~pmaccuracy.errors.ConfigError`'s key names what gave the errors: ``errors``, ``tolerances``
    or ``error_sigma``."""
    if reached >= MIN_REACHED_SHARE * planned:
        return
    key = " and ".join(k for k, v in (("errors", errors), ("tolerances", tolerances)) if v is not None) or "error_sigma"
    count = "none" if reached == 0 else f"only {reached}"
    raise ConfigError(f"the true robot reaches {count} of the {planned} planned poses (out of its reach or past a "
                      f"singularity): its parameter errors are too large for a calibration (mm, deg and gain "
                      f"fractions expected)", key=key)


def _measured(pv, true, plan, noise, clearances, seed, measure_with) -> CalibrationData:
    """The planned poses of the true robot measured (camera noise, clearance states) or by ``measure_with``."""
    if measure_with is not None:
        return measure_with(pv, true, plan.commands, plan.poses, seed + 1)
    n_poses = len(plan.commands)
    sig = np.broadcast_to(np.asarray(noise, dtype=float), (n_poses, 3)).copy()
    meas = measure(pv, true, plan.commands, plan.poses, noise=noise, clearances=clearances, seed=seed + 1)
    data = CalibrationData(tuple(str(i + 1) for i in range(n_poses)), plan.commands, meas,
                           np.maximum(sig, 1e-12), "<simulation>")
    return data.subset(np.all(np.isfinite(meas), axis=1))   # poses the true robot cannot reach are not measured


def _simulate_serial(pv: SerialParameterVector, true: np.ndarray, n_poses: int, *, seed, noise, clearances,
                     n_targets, measure_with=None, errors=None, tolerances=None) -> Experiment:
    plan = plan_poses(pv, n_poses, seed=seed)
    data = _measured(pv, true, plan, noise, clearances, seed, measure_with)
    _check_reached(len(data), len(plan.commands), errors, tolerances)
    ident = identify(data, pv, clearances=clearances)
    # targets: where the nominal arm goes at random commands inside the ranges with a margin (so that the
    # identified arm reaches them within the ranges too)
    lim = np.array([r for _, r in actuators(pv.robot)])
    cand = candidate_commands(pv, n=20 * n_targets, seed=seed + 2)
    span = np.where(np.isfinite(lim[:, 1] - lim[:, 0]), lim[:, 1] - lim[:, 0], 2 * np.pi)
    inner = np.all((cand > lim[:, 0] + 0.05 * span) & (cand < lim[:, 1] - 0.05 * span), axis=1)
    cand = cand[inner]
    sv = np.linalg.svd(serial_pose_jacobian(pv, pv.nominal, cand) * np.array([1.0, 1.0, SERIAL_PHI_WEIGHT])[:, None],
                       compute_uv=False)
    nominal_cmd = cand[sv[:, -1] > MIN_SERIAL_SINGULAR_MM][:n_targets]   # away from singularities
    targets = serial_poses(pv, pv.nominal, nominal_cmd)
    comp = compensate(ident, targets, clearances=clearances, start=nominal_cmd)
    before = measure_serial(pv, true, comp.nominal_commands, noise=(0, 0, 0), clearances=clearances,
                            seed=seed + 3) - targets
    after = measure_serial(pv, true, comp.commands, noise=(0, 0, 0), clearances=clearances, seed=seed + 3) - targets
    for e in (before, after):
        e[:, 2] = np.angle(np.exp(1j * e[:, 2]))
    return Experiment(true=true, data=data, identification=ident, compensation=comp, targets=targets,
                      errors_before=before, errors_after=after)
