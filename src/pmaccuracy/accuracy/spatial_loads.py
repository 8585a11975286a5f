r"""Clearances under load for spatial robots: statics of every leg, the loaded pose error, preload (issue 37).

**Statics.** At a pose the six closure equations of the legs have the wrench rows ``W`` ``(6, 6)``
(:func:`pmaccuracy.kinematics.spatial.closure`: each row a unit line force ``[n, (B - P) x n]`` or a unit couple
``[0, m]``, moments about the platform reference point ``P``, base frame) and the gains ``G`` ``(6, n)`` with
``W t = G q_dot``. Hold the actuators: leg ``i`` pushes on the platform with the wrench
``w_i = sum_{k in leg i} lambda_k W_k``; equilibrium with the external wrench ``F = [f (N), m (N mm about P)]``
(what the environment applies to the platform: a payload's weight, a process wrench) gives

.. math::

    W^T \lambda = -F, \qquad \tau = G^T \lambda

``lambda_k`` in N for a force row (a 6-UPS leg's axial force, positive when the leg pushes the platform away
from its base; a Delta rod's force), N mm for a couple row (a 3-UPU leg's constraint couple). ``tau_i`` is the
actuator's effort on the part beyond it, by virtual work (``tau . dq + F . t = 0`` on every motion the closure
allows): N for a prismatic actuator, N mm for a Delta's arm. Legs are massless, so every joint of a serial leg
transmits the same wrench ``w_i``; it is given at the joint's centre ``C`` as ``[f, m_P + (P - C) x f]``
(6-UPS, 3-RPS, 3-UPU: base joint at ``A``, slide at the leg's midpoint, platform joint at ``B``; 3-PRS: slide
and revolute at the carriage ``C = base + q slide``, ball at ``B``; Delta: the arm's revolute at ``A`` carries
both rods' forces, each ball only its own rod's force ``lambda_j n_j``).

**Loaded pose error.** Each error source ``s`` (:mod:`pmaccuracy.accuracy.spatial_bounds`, Eq. 1) moves the
platform by ``M_s x_s`` with ``x_s`` in its unit segment, disc or ball. A clearance lets the platform yield
where the load does work: the reached error maximizes the virtual work ``F . dX`` over the error set. That
problem separates over the sources, so

.. math::

    x_s = \frac{M_s^T F}{|M_s^T F|}, \qquad \delta X = \sum_s M_s x_s

(a segment: ``sign``). Since ``F = -W^T lambda``, ``M_s^T F = -h_s Xi_s^T w_i``: the source's generator twists'
power with its leg's wrench, i.e. each clearance is taken up along its joint's reaction (a ball sits against
its socket opposite the force it transmits). Only clearances follow the load (keys ``radial``, ``axial``,
``tilt``, ``backlash``, ``lateral``); the geometric tolerances and the actuator's own error (``position``,
``direction``, ``length``, ``actuator``) are constant unknowns that no load moves: their worst case is given
apart as :attr:`SpatialLoadedError.tolerance`. Where the load does not select a point, ``|M_s^T F| / h_s`` at
or below ``threshold`` (N; for rotation sources ``threshold L`` N mm, ``L`` the robot's characteristic
length), the source's state is **undetermined**: it is left at its centre and its half-width is reported in
:attr:`SpatialLoadedError.spread` (the loaded error then lies in ``error +- spread`` componentwise) instead of
a point invented for it. Sources with no first-order effect at all (``M_s = 0``, e.g. a 6-UPS's base joint
tilt) are ignored. First order only: the error is exact to ``O(c^2 / L)``.

**Preload.** ``lambda = -W^{-T} F`` is linear in the wrench. :func:`spatial_design_preload` finds the smallest
constant wrench ``P`` (size ``max(|P_f|, |P_m| / L)``) such that every closure row's intensity keeps one sign,
with at least ``margin``, for every process wrench of a box ``center +- half`` (a linear program per sign
pattern, the best of the ``2^6``), or the smallest multiple ``alpha >= 0`` of a given preload direction. Every
source whose reaction then stays on one side is *held*: a segment's reaction keeps its sign, a disc's or ball's
keeps its direction within :attr:`SpatialPreload.max_angle_deg` (0 only for a one-dimensional reaction, e.g. a
6-UPS leg's or a Delta rod's balls, whose reaction is along the leg or rod).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linprog

from .._display import html_table, summary, value_range
from ..errors import ConfigError, UnsupportedArchitectureError
from ..io.resolve import robot_arg
from ..kinematics.spatial import as_spatial_poses, closure, coordinates, inverse_kinematics
from ..model.plausibility import check_angle_values, rotation_angles
from ..model.spatial import SpatialManipulator, is_spatial
from ..model.spatial_chain import ChainLeg
from ..model.spatial_legs import DeltaLeg, PRSLeg
from ..model.spatial_sources import SpatialErrorSources
from ..numerics.spatial import rotations
from .spatial_bounds import COMPONENTS, error_sources_at, spatial_pose_errors

#: Standard gravity (m/s^2), as :data:`pmaccuracy.accuracy.loads.G0`.
G0 = 9.80665
#: Default threshold (N; N mm over the characteristic length for rotation sources) of an undetermined source.
DEFAULT_THRESHOLD_N = 1e-6
#: The keys that a load takes up (clearances); the other keys are tolerances no load moves.
CLEARANCE_KEYS = ("radial", "axial", "tilt", "backlash", "lateral")


def _three(value, key: str) -> tuple[float, float, float]:
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ConfigError(f"expected three numbers, got {value!r}", key=key) from None
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ConfigError(f"expected three finite numbers, got {value!r}", key=key)
    return tuple(float(v) for v in arr)


@dataclass(frozen=True)
class SpatialLoad:
    """A load on a spatial robot's platform: a wrench and optionally a payload's weight.

    Attributes
    ----------
    force : ``(3,)`` N, base frame
    moment : ``(3,)`` N mm about the platform reference point ``P``, base frame
    mass : kg (0: no weight)
    com : ``(3,)`` mm, the centre of mass in the platform frame (from ``P``)
    gravity : ``(3,)`` the direction of gravity in the base frame (normalized; default ``-z``)

    >>> SpatialLoad(mass=1.0, com=(10.0, 0.0, 0.0)).wrench(np.zeros(6)).round(4).tolist()
    [0.0, 0.0, -9.8066, 0.0, 98.0665, 0.0]
    """

    force: tuple[float, float, float] = (0.0, 0.0, 0.0)
    moment: tuple[float, float, float] = (0.0, 0.0, 0.0)
    mass: float = 0.0
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gravity: tuple[float, float, float] = (0.0, 0.0, -1.0)

    def __post_init__(self) -> None:
        for key in ("force", "moment", "com", "gravity"):
            object.__setattr__(self, key, _three(getattr(self, key), key))
        if not (isinstance(self.mass, (int, float)) and math.isfinite(self.mass)):
            raise ConfigError(f"must be a finite number (kg), got {self.mass!r}", key="mass")
        if self.mass < 0:
            raise ConfigError(f"a mass cannot be negative, got {self.mass} kg", key="mass")
        g = np.array(self.gravity)
        if not np.linalg.norm(g) > 0:
            raise ConfigError("the direction of gravity must not be zero", key="gravity")
        object.__setattr__(self, "gravity", tuple(float(v) for v in g / np.linalg.norm(g)))

    def wrench(self, poses) -> np.ndarray:
        """``(..., 6)`` ``[f N, m N mm about P]`` at poses ``(..., 6)``: the given wrench plus the weight
        ``G0 mass gravity`` applied at the centre of mass ``P + R com``."""
        poses = np.asarray(poses, dtype=float)
        weight = G0 * self.mass * np.array(self.gravity)
        arm = np.einsum("...ij,j->...i", rotations(poses[..., 3:]), np.array(self.com))
        f = np.broadcast_to(np.array(self.force) + weight, arm.shape)
        m = np.array(self.moment) + np.cross(arm, weight)
        return np.concatenate([f, m], axis=-1)

    @property
    def is_zero(self) -> bool:
        """True when there is no force, moment or weight."""
        return not (any(self.force) or any(self.moment) or self.mass)


@dataclass(frozen=True)
class SpatialStatics:
    """Leg wrench intensities, actuator efforts and joint reactions at a batch of poses (:func:`spatial_statics`).

    The leading shape ``(...)`` is the poses'.

    Attributes
    ----------
    poses : ndarray, shape (..., 6)
        The poses [mm, rotation vector rad].
    wrench : ndarray, shape (..., 6)
        The external load [N, N mm about P].
    intensity : ndarray, shape (..., 6)
        ``lambda`` per closure row (N for a force row, N mm for a couple row).
    leg_of_row : ndarray, shape (6,)
        The leg (0-based) of each row.
    actuator : ndarray, shape (..., n)
        ``tau = G^T lambda``: N for a prismatic actuator, N mm for a Delta's arm.
    leg_wrench : ndarray, shape (..., n, 6)
        Each leg's wrench on the platform [f N, m N mm about P].
    centres : ndarray, shape (..., n, j, 3)
        Each joint's centre, mm (module docstring).
    reactions : ndarray, shape (..., n, j, 6)
        The wrench each joint transmits to the platform side [f N, m N mm about the joint's centre].
    """

    poses: np.ndarray
    wrench: np.ndarray
    intensity: np.ndarray
    leg_of_row: np.ndarray
    actuator: np.ndarray
    leg_wrench: np.ndarray
    centres: np.ndarray
    reactions: np.ndarray

    def __repr__(self) -> str:
        return summary("SpatialStatics", int(np.prod(self.poses.shape[:-1])), [
            f"row intensity {value_range(np.abs(self.intensity), 'N or N mm')}",
            f"actuators {value_range(np.abs(self.actuator), 'N or N mm')}"])


def _robot(robot) -> SpatialManipulator:
    robot = robot_arg(robot)
    if not is_spatial(robot):
        raise ConfigError(f"{getattr(robot, 'name', robot)} is a planar robot: use pmaccuracy.statics with a Load",
                          key="robot")
    return robot


def _sources(robot: SpatialManipulator, clearances) -> SpatialErrorSources:
    if isinstance(clearances, SpatialErrorSources):
        if clearances.architecture != robot.architecture:
            raise ConfigError(f"the error sources are of a {clearances.architecture}, the robot a "
                              f"{robot.architecture}", key="clearances")
        return clearances
    if clearances is None:
        raise ConfigError("missing: give a spatial clearance preset, a TOML path or a SpatialErrorSources",
                          key="clearances")
    return SpatialErrorSources.load(clearances, robot)


def _check_load(load) -> None:
    if not isinstance(load, SpatialLoad):
        raise ConfigError(f"expected a SpatialLoad, got {type(load).__name__}", key="load")


def _prepare(robot: SpatialManipulator, sources: SpatialErrorSources, poses):
    """Poses checked (limits, singularities: :func:`~pmaccuracy.accuracy.spatial_bounds.error_sources_at`), the
    closure there and the sources' matrices."""
    poses = as_spatial_poses(poses)
    _, info = error_sources_at(robot, sources, poses, keep=True)
    q = inverse_kinematics(robot, poses).q
    return poses, q, closure(robot, poses, q), info


def _statics(robot: SpatialManipulator, poses: np.ndarray, q: np.ndarray, cl, Winv: np.ndarray,
             F: np.ndarray) -> SpatialStatics:
    lam = -np.einsum("...ji,...j->...i", Winv, F)                  # W^T lambda = -F
    tau = np.einsum("...ki,...k->...i", cl.gains, lam)
    legs = cl.leg_of_row
    n = robot.n_legs
    rows = lam[..., :, None] * cl.wrenches                            # (..., 6, 6)
    leg_wrench = np.stack([np.sum(rows[..., legs == i, :], axis=-2) for i in range(n)], axis=-2)
    p, R = poses[..., :3], rotations(poses[..., 3:])
    centres, reactions = [], []
    for i, leg in enumerate(robot.legs):
        A = np.broadcast_to(np.asarray(leg.base, dtype=float), p.shape)
        B = leg.platform_point(p, R)
        w = leg_wrench[..., i, :]
        if isinstance(leg, ChainLeg):       # every joint of a massless serial leg carries the leg's wrench
            prefixes = leg.solve(p, R, q[..., i])[4]
            cs = [np.einsum("...ij,j->...i", Rp, np.asarray(j.centre, dtype=float)) + tp
                  for j, (Rp, tp) in zip(leg.joints, prefixes)]
            ws = [w] * len(cs)
        elif isinstance(leg, DeltaLeg):
            C, Bs = leg.balls(p, R, q[..., i])
            rod = rows[..., legs == i, :]                               # (..., 2, 6) each rod's wrench
            cs = [A, C[..., 0, :], Bs[..., 0, :], C[..., 1, :], Bs[..., 1, :]]
            ws = [w, rod[..., 0, :], rod[..., 0, :], rod[..., 1, :], rod[..., 1, :]]
        else:
            mid = leg.carriage(q[..., i]) if isinstance(leg, PRSLeg) else 0.5 * (A + B)
            cs = [mid, mid, B] if isinstance(leg, PRSLeg) else [A, mid, B]
            ws = [w, w, w]
        centres.append(np.stack(cs, axis=-2))
        reactions.append(np.stack([np.concatenate([wk[..., :3], wk[..., 3:] + np.cross(p - c, wk[..., :3])], -1)
                                   for c, wk in zip(cs, ws)], axis=-2))
    if len({c.shape for c in centres}) > 1:
        raise UnsupportedArchitectureError("joint reactions of chain legs with different numbers of joints are not "
                                           "tabulated yet", key="legs")
    return SpatialStatics(poses=poses, wrench=F, intensity=lam, leg_of_row=legs, actuator=tau,
                          leg_wrench=leg_wrench, centres=np.stack(centres, axis=-3),
                          reactions=np.stack(reactions, axis=-3))


def spatial_statics(robot: SpatialManipulator | str, poses, load: SpatialLoad) -> SpatialStatics:
    """Closure-row intensities, actuator efforts and joint reactions under ``load`` at ``poses`` ``(..., 6)``
    (module docstring: ``W^T lambda = -F``, ``tau = G^T lambda``).

    Raises :class:`~pmaccuracy.errors.OutsideJointLimitsError` for a pose outside the joint limits and
    :class:`~pmaccuracy.errors.SingularPoseError` near a singularity (the statics is undefined there), as
    :func:`~pmaccuracy.accuracy.spatial_bounds.spatial_pose_errors` does.

    >>> robot = SpatialManipulator.preset("stewart_6ups")
    >>> st = spatial_statics(robot, robot.home_pose, SpatialLoad(force=(0.0, 0.0, -100.0)))
    >>> bool(np.allclose(st.leg_wrench.sum(axis=-2), [0, 0, 100, 0, 0, 0]))
    True
    """
    check_angle_values(rotation_angles(poses), "poses[..., 3:] (rotation vectors)")
    robot = _robot(robot)
    _check_load(load)
    poses, q, cl, info = _prepare(robot, SpatialErrorSources.zero(robot), poses)
    return _statics(robot, poses, q, cl, info["Winv"], load.wrench(poses))


@dataclass(frozen=True)
class SpatialLoadedError:
    """The first-order pose error under a load (:func:`spatial_loaded_error`).

    Attributes
    ----------
    statics : the :class:`SpatialStatics` behind it
    error : ``(..., 6)`` [mm, rad]: ``sum_s M_s x_s`` over the clearances (twist ``[dp, dtheta]``, base frame)
    spread : ``(..., 6)`` [mm, rad]: half-width of the range the undetermined clearances leave around ``error``
    tolerance : ``(..., 6)`` [mm, rad]: the worst case of the sources no load moves (tolerances, actuator error),
        to add on either side
    labels : the clearances' labels (``legs[i].joints[j].key``, ``[pin k]`` for a universal joint's pins)
    points : ``{label: (..., d)}`` each clearance's point of its unit segment/disc/ball (0 where undetermined)
    undetermined : ``{label: (...) bool}`` where the load does not select the clearance's point
    """

    statics: SpatialStatics
    error: np.ndarray
    spread: np.ndarray
    tolerance: np.ndarray
    labels: list
    points: dict = field(repr=False)
    undetermined: dict = field(repr=False)

    def records(self) -> list[dict]:
        """One dict per pose (mm, deg, N): the pose, the loaded error (rotations in deg), its spread, the
        tolerances' worst case, the rows' intensities, the actuator efforts and the undetermined sources."""
        poses = self.statics.poses.reshape(-1, 6)
        coords = coordinates(poses, degrees=True)
        err, sp, tol = (a.reshape(-1, 6) for a in (self.error, self.spread, self.tolerance))
        lam = self.statics.intensity.reshape(-1, 6)
        tau = self.statics.actuator.reshape(poses.shape[0], -1)
        und = {k: np.asarray(v).reshape(-1) for k, v in self.undetermined.items()}
        out = []
        for k in range(poses.shape[0]):
            rec = {n: float(v) for n, v in zip(("x", "y", "z", "roll_deg", "pitch_deg", "yaw_deg"), coords[k])}
            for what, arr in (("", err), ("_spread", sp), ("_tolerance", tol)):
                for c, name in enumerate(COMPONENTS):
                    value = float(arr[k, c]) if c < 3 else math.degrees(arr[k, c])
                    rec[f"{name}{'_deg' if c >= 3 else ''}{what}"] = value
            rec.update({f"lambda{r + 1}": float(lam[k, r]) for r in range(6)})
            rec.update({f"tau{i + 1}": float(tau[k, i]) for i in range(tau.shape[1])})
            rec["undetermined"] = ",".join(name for name, v in und.items() if v[k]) or "-"
            out.append(rec)
        return out

    def __repr__(self) -> str:
        n = int(np.prod(self.error.shape[:-1]))
        return summary("SpatialLoadedError", n, [
            f"|dp| {value_range(np.linalg.norm(self.error[..., :3], axis=-1), 'mm')}",
            f"|dtheta| {value_range(np.degrees(np.linalg.norm(self.error[..., 3:], axis=-1)), 'deg')}",
            f"{sum(int(np.sum(v)) for v in self.undetermined.values())} undetermined sources"])

    def _repr_html_(self) -> str:
        return html_table("Loaded pose error of a spatial robot (mm, deg, N)", self.records())


def _is_rotation(robot: SpatialManipulator, src) -> bool:
    return src.key == "tilt" or (src.key == "backlash" and robot.actuated_kinds[src.leg] == "R")


def _selection(robot: SpatialManipulator, info: dict, F: np.ndarray, threshold: float):
    """Per clearance source: its matrix, the virtual-work-maximizing point and the undetermined mask; and the
    tolerances' worst case."""
    L = robot.characteristic_length
    chosen = []
    tolerance = np.zeros(F.shape)
    for src in info["sources"]:
        M = src.matrix
        if src.key not in CLEARANCE_KEYS:
            tolerance = tolerance + np.linalg.norm(M, axis=-1)
            continue
        scale = L if _is_rotation(robot, src) else 1.0
        h = src.half_width
        active = np.max(np.abs(src.E), axis=(-1, -2)) > 1e-9 * h * scale        # some first-order effect
        g = np.einsum("...ij,...i->...j", M, F)                                    # M_s^T F
        gn = np.linalg.norm(g, axis=-1)
        undetermined = active & (gn <= threshold * scale * h)
        selected = active & ~undetermined
        x = np.where(selected[..., None], g / np.where(selected, gn, 1.0)[..., None], 0.0)
        chosen.append((src, M, x, undetermined, active))
    return chosen, tolerance


def spatial_loaded_error(robot: SpatialManipulator | str, clearances, poses, load: SpatialLoad, *,
                         threshold: float = DEFAULT_THRESHOLD_N) -> SpatialLoadedError:
    """The first-order pose error that ``load`` produces at ``poses`` ``(..., 6)`` with every clearance taken up
    along its joint's reaction (module docstring: ``x_s = M_s^T F / |M_s^T F|``, ``dX = sum_s M_s x_s``).

    Parameters
    ----------
    robot : a :class:`~pmaccuracy.model.spatial.SpatialManipulator`, preset name or path
    clearances : a :class:`~pmaccuracy.model.spatial_sources.SpatialErrorSources`, preset name or path
    poses : ``(..., 6)`` [x, y, z mm, rotation vector rad];  load : a :class:`SpatialLoad`
    threshold : N; a source whose reaction ``|M_s^T F| / h_s`` is at most this (``threshold L`` N mm for a
        rotation source) is undetermined (:attr:`SpatialLoadedError.spread`)

    >>> robot = SpatialManipulator.preset("stewart_6ups")
    >>> r = spatial_loaded_error(robot, "ups_typical", robot.home_pose, SpatialLoad(force=(0.0, 0.0, -100.0)))
    >>> bool(r.error[2] < 0)      # the platform yields downwards under a downward push
    True
    """
    check_angle_values(rotation_angles(poses), "poses[..., 3:] (rotation vectors)")
    robot = _robot(robot)
    sources = _sources(robot, clearances)
    _check_load(load)
    if not (isinstance(threshold, (int, float)) and math.isfinite(threshold) and threshold >= 0):
        raise ConfigError(f"must be finite and >= 0 (N), got {threshold!r}", key="threshold")
    poses, q, cl, info = _prepare(robot, sources, poses)
    F = load.wrench(poses)
    st = _statics(robot, poses, q, cl, info["Winv"], F)
    chosen, tolerance = _selection(robot, info, F, threshold)
    error = np.zeros(F.shape)
    spread = np.zeros(F.shape)
    points, undetermined = {}, {}
    for src, M, x, und, _ in chosen:
        error = error + np.einsum("...ij,...j->...i", M, x)
        spread = spread + np.where(und[..., None], np.linalg.norm(M, axis=-1), 0.0)
        points[src.label] = x
        undetermined[src.label] = und
    return SpatialLoadedError(statics=st, error=error, spread=spread, tolerance=tolerance, labels=list(points),
                              points=points, undetermined=undetermined)


# ----------------------------------------------------------------------------------------------------- preload
def _box(center, half) -> tuple[np.ndarray, np.ndarray]:
    try:
        c = np.asarray(center, dtype=float).reshape(6)
        h = np.asarray(half, dtype=float).reshape(6)
    except (TypeError, ValueError):
        raise ConfigError(f"a wrench box needs a centre and half-widths of six numbers each [N x3, N mm x3], got "
                          f"{center!r}, {half!r}", key="wrench_set") from None
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(h)) and np.all(h >= 0)):
        raise ConfigError(f"a wrench box needs a finite centre and half-widths >= 0 [N x3, N mm x3], got {c}, {h}",
                          key="wrench_set")
    if not (np.any(c) or np.any(h)):
        raise ConfigError("the box of process wrenches is the zero wrench alone: no load to hold a contact "
                          "against (give a range)", key="half")
    return c, h


#: The 64 sign patterns of the six closure rows' intensities.
_PATTERNS = np.array(list(itertools.product((1.0, -1.0), repeat=6)))


@dataclass(frozen=True)
class SpatialPreload:
    """The smallest constant platform wrench holding every closure row's sign over a box of process wrenches
    at one pose (:func:`spatial_design_preload`).

    Attributes
    ----------
    wrench : ``(6,)`` [N x3, N mm x3 about P]: the preload, added to every process wrench
    size : ``max(|P_f|, |P_m| / L)`` (N), ``L`` the robot's characteristic length (with a direction: ``alpha``)
    pattern : ``(6,)`` the rows' intensity signs held for every wrench of the box
    offset : ``(6,)`` [mm, rad]: the first-order loaded error at the preload plus the box's centre
    worst : ``(6,)`` [mm, rad]: the unloaded worst case of each component beside it
    held : ``{label: bool}`` the clearances whose reaction keeps one side (segments: one sign) over the box
    max_angle_deg : ``{label: float}`` the largest turn of a disc's or ball's reaction over the box (deg; 0 for a
        segment held, 180 where not held)
    """

    wrench: np.ndarray
    size: float
    pattern: np.ndarray
    offset: np.ndarray
    worst: np.ndarray
    held: dict = field(repr=False)
    max_angle_deg: dict = field(repr=False)


def _corners(c: np.ndarray, h: np.ndarray) -> np.ndarray:
    return c + _PATTERNS * h


def spatial_design_preload(robot: SpatialManipulator | str, clearances, pose, center, half, *,
                           margin: float = DEFAULT_THRESHOLD_N, direction=None) -> SpatialPreload:
    """The smallest preload ``P`` such that every closure row's intensity keeps its sign, with at least
    ``margin`` (N, or N mm for a couple row), for every process wrench of the box ``center +- half`` ``(6,)``
    [N x3, N mm x3 about P] at ``pose`` ``(6,)``.

    With ``lambda = L F``, ``L = -W^{-T}``, a pattern ``s`` needs ``s_k L_k P >= margin - s_k L_k center +
    sum_j |L_kj| half_j`` (the box's worst corner). Free preload: ``min z`` subject to that and
    ``|P_j| / scale_j <= z`` (scale 1 for forces, ``L`` for moments; scipy HiGHS), the best of the 64 patterns.
    With ``direction`` ``(6,)``: ``P = alpha direction``, the smallest ``alpha >= 0`` (closed form per pattern).
    Then each clearance is checked over the box's 64 corners (:class:`SpatialPreload`).
    """
    check_angle_values(rotation_angles(pose), "pose[3:] (rotation vector)")
    robot = _robot(robot)
    sources = _sources(robot, clearances)
    c, h = _box(center, half)
    if not (isinstance(margin, (int, float)) and math.isfinite(margin) and margin >= 0):
        raise ConfigError(f"must be finite and >= 0 (N), got {margin!r}", key="margin")
    pose = np.asarray(pose, dtype=float)
    if pose.shape != (6,):
        raise ConfigError(f"expected one pose (6,), got shape {pose.shape}", key="pose")
    poses, q, cl, info = _prepare(robot, sources, pose)
    Lmap = -info["Winv"].T                                          # lambda = Lmap F
    scale = np.array([1.0] * 3 + [robot.characteristic_length] * 3)
    if direction is not None:
        d = np.asarray(direction, dtype=float).reshape(-1)
        if d.shape != (6,) or not np.all(np.isfinite(d)) or not np.any(d):
            raise ConfigError(f"expected six finite numbers, not all zero, got {direction!r}", key="direction")
    best = None
    for s in _PATTERNS:
        rhs = margin - s * (Lmap @ c) + np.abs(Lmap) @ h
        if direction is None:
            A_ub = np.vstack([np.column_stack([-(s[:, None] * Lmap), np.zeros(6)]),
                              np.column_stack([np.diag(1 / scale), -np.ones(6)]),
                              np.column_stack([-np.diag(1 / scale), -np.ones(6)])])
            b_ub = np.concatenate([-rhs, np.zeros(12)])
            res = linprog(np.r_[np.zeros(6), 1.0], A_ub=A_ub, b_ub=b_ub, bounds=[(None, None)] * 7, method="highs")
            if res.status == 0 and (best is None or res.fun < best[0]):
                best = (float(res.fun), res.x[:6], s)
        else:
            a = s * (Lmap @ d)
            if np.any((a <= 0) & (rhs > 0)):
                continue
            alpha = max(0.0, float(np.max(np.where(a > 0, rhs / np.where(a > 0, a, 1.0), 0.0))))
            if best is None or alpha < best[0]:
                best = (alpha, alpha * d, s)
    if best is None:
        raise ConfigError("no multiple of this direction keeps every closure row's sign over the box", key="direction")
    size, P, pattern = best
    chosen, _ = _selection(robot, info, P + c, DEFAULT_THRESHOLD_N)
    offset = sum(M @ x for _, M, x, _, _ in chosen) if chosen else np.zeros(6)
    corners = P + _corners(c, h)
    held, angles = {}, {}
    for src, M, x, _, active in chosen:
        if not active:
            continue
        g = corners @ M                                                   # (64, d) reactions at the corners
        g0 = M.T @ (P + c)
        gn = np.linalg.norm(g, axis=-1)
        if not np.linalg.norm(g0) > 0 or np.any(gn == 0):
            angles[src.label], held[src.label] = 180.0, False
            continue
        u0 = g0 / np.linalg.norm(g0)
        along = g @ u0
        ang = float(np.degrees(np.max(np.arctan2(np.linalg.norm(g - along[:, None] * u0, axis=-1), along))))
        angles[src.label] = ang
        held[src.label] = bool(ang < 90.0)
    worst = spatial_pose_errors(robot, sources, pose).components
    return SpatialPreload(wrench=np.asarray(P, dtype=float), size=size, pattern=pattern, offset=offset, worst=worst,
                          held=held, max_angle_deg=angles)
