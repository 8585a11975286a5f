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
apart as :attr:`SpatialLoadedError.tolerance` (the planar :func:`pmaccuracy.accuracy.loads.loaded_pose_error`
takes every source of its file to the load's extreme, tolerances included: docs/guide/loads.md, "Tolerances
under load"). Where the load does not select a point, ``|M_s^T F| / h_s`` at
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

**Over sets** (issue 37): :func:`spatial_wrench_set_errors` (the loaded error over a box of process wrenches: a
guaranteed enclosure and the range attained at its corners), :func:`spatial_loaded_error_map` and
:func:`spatial_wrench_set_map` (the loaded error, its range over a box and the preload each point needs, over the
workspace's 3D grid), :func:`spatial_design_region_preload` (one preload for every sampled pose of a region:
guaranteed at the checked poses, not proved between them) and :func:`spatial_spring_preload` (constant-force
springs alongside the legs instead of a platform wrench).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
import xarray as xr
from scipy.optimize import linprog

from .._display import html_table, summary, value_range
from ..errors import ConfigError, EmptyWorkspaceError, UnsupportedArchitectureError
from ..io.resolve import robot_arg
from ..kinematics.spatial import as_spatial_poses, closure, coordinates, inverse_kinematics
from ..kinematics.spatial_workspace import spatial_workspace
from ..model.plausibility import check_angle_values, rotation_angles
from ..model.spatial import SpatialManipulator, is_spatial
from ..model.spatial_chain import ChainLeg
from ..model.spatial_legs import DeltaLeg, PRSLeg
from ..model.spatial_sources import SpatialErrorSources
from ..numerics.spatial import rotations
from .spatial_bounds import COMPONENTS, error_sources_at, spatial_pose_errors
from .spatial_maps import grid_poses
from .spatial_worst import SpatialRegion, SpatialSingularRegionError, _box_dims, _full_poses, _grid

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
    if direction is None:
        best = _preload_lp(Lmap[None], c, h, margin, scale)
    else:
        alpha, pat = _direction_alpha(Lmap, c, h, margin, d)
        best = (float(alpha), float(alpha) * d, pat) if np.isfinite(alpha) else None
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


def _pattern_lp(A: np.ndarray, rhs: np.ndarray, s: np.ndarray, scale: np.ndarray):
    """``(size, P)`` of ``min z`` s.t. ``s_k A_nk P >= rhs_nk``, ``|P_j| / scale_j <= z`` (``A`` ``(m, 6, v)``,
    ``P`` ``(v,)``; scipy HiGHS); ``(inf, None)`` when infeasible."""
    v = A.shape[-1]
    rows = (s[None, :, None] * A).reshape(-1, v)
    A_ub = np.vstack([np.column_stack([-rows, np.zeros(rows.shape[0])]),
                      np.column_stack([np.diag(1 / scale), -np.ones(v)]),
                      np.column_stack([-np.diag(1 / scale), -np.ones(v)])])
    b_ub = np.concatenate([-rhs.reshape(-1), np.zeros(2 * v)])
    res = linprog(np.r_[np.zeros(v), 1.0], A_ub=A_ub, b_ub=b_ub, bounds=[(None, None)] * (v + 1), method="highs")
    return (float(res.fun), res.x[:v]) if res.status == 0 else (math.inf, None)


#: Poses of the subsample whose per-pattern optima bound the full programs from below (:func:`_preload_lp`).
_SUBSAMPLE = 24


def _preload_lp(Lmaps: np.ndarray, c: np.ndarray, h: np.ndarray, margin: float, scale: np.ndarray, A=None):
    """Best pattern's ``(size, P, s)`` of ``min max_j |P_j| / scale_j`` subject to ``s_k L_nk (A_n P + W) >= margin``
    for every pose ``n`` of ``Lmaps`` ``(m, 6, 6)`` and every wrench ``W`` of the box (scipy HiGHS), or None.
    ``A`` ``(m, 6, v)`` maps the unknowns to a platform wrench (default the identity: ``P`` is the wrench).

    The 64 patterns are tried in increasing order of a lower bound of their optimum, and a pattern whose bound
    is not below the best size found is skipped (exact: it cannot do better). The bound: ``max_{n,k} rhs_nk /
    sum_j |(L A)_nkj| scale_j`` (``|s_k (L A)_k P| <= sum_j |(L A)_kj| scale_j z``; ``inf`` where a row that
    ``P`` cannot move needs moving), the same for the rows' combinations weighted by their needed moves ``d_k``
    and by ``d_k > 0`` (``sum mu_k d_k <= |sum mu_k s_k (L A)_k P|``), and, for more than :data:`_SUBSAMPLE` poses, the pattern's optimum over a
    subsample of them (fewer constraints; ``inf`` when infeasible there)."""
    LA = Lmaps if A is None else Lmaps @ A                                  # (m, 6, v)
    Lc = Lmaps @ c                                                          # (m, 6)
    Lh = np.abs(Lmaps) @ h
    norm1 = np.abs(LA) @ scale                                              # (m, 6)
    rhs = margin - _PATTERNS[:, None, :] * Lc[None] + Lh[None]             # (64, m, 6)
    d = np.maximum(rhs, 0.0)                                                # (64, m, 6) each row's needed move
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(norm1[None] > 0, d / norm1[None], np.where(rhs > 0, np.inf, 0.0))
        bound = np.max(ratio, axis=(1, 2))
        # rows combined (weights mu >= 0: z >= sum mu_k d_k / sum_j |sum_k mu_k s_k (L A)_kj| scale_j), per pose
        sLA = _PATTERNS[:, None, :, None] * LA[None]                        # (64, m, 6, v)
        for mu in (d, (d > 0).astype(float)):
            num = np.sum(mu * d, axis=-1)
            den = np.abs(np.einsum("pmk,pmkj->pmj", mu, sLA)) @ scale
            both = np.where(den > 0, num / den, np.where(num > 0, np.inf, 0.0))
            bound = np.maximum(bound, np.max(both, axis=1))
    m = Lmaps.shape[0]
    if m > _SUBSAMPLE:
        sub = np.unique(np.linspace(0, m - 1, _SUBSAMPLE).round().astype(int))
        bound = np.maximum(bound, [_pattern_lp(LA[sub], rhs[p, sub], _PATTERNS[p], scale)[0]
                                   if np.isfinite(bound[p]) else np.inf for p in range(64)])
    best = None
    for p in np.argsort(bound, kind="stable"):
        if not np.isfinite(bound[p]) or (best is not None and bound[p] >= best[0]):
            break
        size, P = _pattern_lp(LA, rhs[p], _PATTERNS[p], scale)
        if P is not None and (best is None or size < best[0]):
            best = (size, P, _PATTERNS[p])
    return best


def _direction_alpha(Lmaps: np.ndarray, c: np.ndarray, h: np.ndarray, margin: float, d: np.ndarray):
    """``(alpha (...), pattern (..., 6))``: the smallest ``alpha >= 0`` with ``s_k L_k (alpha d + W) >= margin`` for
    every wrench of the box, the best pattern, vectorized over poses ``Lmaps`` ``(..., 6, 6)`` (``inf`` where no
    multiple of ``d`` holds every row's sign)."""
    a = _PATTERNS * (Lmaps @ d)[..., None, :]                                       # (..., 64, 6)
    rhs = margin - _PATTERNS * (Lmaps @ c)[..., None, :] + (np.abs(Lmaps) @ h)[..., None, :]
    pos = a > 0
    need = np.where(pos, rhs / np.where(pos, a, 1.0), np.where(rhs > 0, np.inf, 0.0))
    alpha = np.maximum(np.max(need, axis=-1), 0.0)                                   # (..., 64)
    k = np.argmin(alpha, axis=-1)
    return np.take_along_axis(alpha, k[..., None], axis=-1)[..., 0], _PATTERNS[k]


# ----------------------------------------------------------------------------------------- wrench sets
@dataclass(frozen=True)
class SpatialWrenchSetErrors:
    """The first-order loaded error of a spatial robot when the process wrench ranges over a box
    (:func:`spatial_wrench_set_errors`), at a batch of ``n`` poses.

    Attributes
    ----------
    poses : ndarray, shape (n, 6)
        The poses [mm, rotation vector rad].
    center, half : ndarray, shape (6,)
        The box ``center +- half`` [N x3, N mm x3 about P].
    lower, upper : ndarray, shape (n, 6)
        [mm, rad]: an enclosure of the loaded error (clearances, with the undetermined ones' spread) over every
        wrench of the box: guaranteed to contain it (the sum of each clearance's own range).
    attained_lower, attained_upper : ndarray, shape (n, 6)
        [mm, rad]: the range over the box's centre and its 64 corners: values the loaded error does take.
        The exact range lies between the two ranges.
    tolerance : ndarray, shape (n, 6)
        [mm, rad]: the worst case of the sources no load moves (to add on either side, as
        :attr:`SpatialLoadedError.tolerance`).
    labels : list of str
        The clearances' labels.
    held : dict
        ``{label: (n,) bool}``: the clearance's reaction ``M_s^T F`` stays strictly on one side over the box
        (``u0 . M_s^T F > threshold`` at every corner, ``u0`` its direction at the centre wrench): a segment's sign
        is then constant (exact: False means it flips or vanishes in the box); a disc's or ball's direction stays
        within ``max_angle_deg`` of ``u0``. A clearance without first-order effect (``M_s = 0``) counts as held.
    max_angle_deg : dict
        ``{label: (n,)}``: the largest angle between the reaction and ``u0`` over the box (deg; 180 where not
        held).
    """

    poses: np.ndarray
    center: np.ndarray
    half: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    attained_lower: np.ndarray
    attained_upper: np.ndarray
    tolerance: np.ndarray
    labels: list
    held: dict = field(repr=False)
    max_angle_deg: dict = field(repr=False)

    @property
    def not_held(self) -> np.ndarray:
        """``(n,)`` the number of clearances not held over the box at each pose."""
        return sum((~v).astype(int) for v in self.held.values()) if self.held else np.zeros(len(self.poses), int)

    def records(self) -> list[dict]:
        """One dict per pose (mm, deg): the pose, the enclosure ``*_lo, *_hi``, the attained range
        ``*_attained_lo, *_attained_hi`` and the clearances not held."""
        coords = coordinates(self.poses, degrees=True)
        out = []
        for k in range(self.poses.shape[0]):
            rec = {n: float(v) for n, v in zip(("x", "y", "z", "roll_deg", "pitch_deg", "yaw_deg"), coords[k])}
            for what, arr in (("_lo", self.lower), ("_hi", self.upper), ("_attained_lo", self.attained_lower),
                              ("_attained_hi", self.attained_upper)):
                for c, name in enumerate(COMPONENTS):
                    rec[f"{name}{'_deg' if c >= 3 else ''}{what}"] = float(arr[k, c]) if c < 3 else \
                        math.degrees(arr[k, c])
            rec["not_held"] = ",".join(name for name, v in self.held.items() if not v[k]) or "-"
            out.append(rec)
        return out

    def __repr__(self) -> str:
        return summary("SpatialWrenchSetErrors", self.poses.shape[0], [
            f"dz range {value_range(self.upper[:, 2] - self.lower[:, 2], 'mm')} (enclosure)",
            f"{int(np.sum(self.not_held))} clearances not held"])


def _wrench_set(robot: SpatialManipulator, info: dict, c: np.ndarray, h: np.ndarray, threshold: float) -> dict:
    """The enclosure, the attained range, the tolerances and each clearance's hold over the box ``c +- h`` (``c``
    ``(6,)`` or one centre per pose) at the poses of ``info`` (:class:`SpatialWrenchSetErrors`; leading shape of ``info["Winv"]``).

    Per clearance ``s`` the reaction ``g = M_s^T F`` maps the box onto a zonotope, the hull of the 64 corners'
    images. When ``u0 . g_k > t`` at every corner (``u0`` the centre's direction, ``t`` the threshold), the whole
    zonotope lies in the convex cone ``angle(g, u0) <= theta``, ``theta`` the corners' largest angle (< 90 deg),
    so ``x_s = g / |g|`` lies in that cap and component ``c`` of ``M_s x_s`` (row ``m``, at the angle ``phi`` from
    ``u0``) in ``[-|m| cos(max(pi - phi - theta, 0)), |m| cos(max(phi - theta, 0))]`` (exact for a segment:
    ``theta = 0``); otherwise in ``[-|m|, |m|]``. The enclosure sums these ranges."""
    Lc = robot.characteristic_length
    shape = info["Winv"].shape[:-2]
    c = np.broadcast_to(c, shape + (6,))                                            # a centre per pose allowed
    F = np.concatenate([c[..., None, :], c[..., None, :] + _PATTERNS * h], axis=-2)  # (..., 65, 6)
    err = np.zeros(shape + (65, 6))
    spread = np.zeros(shape + (65, 6))
    tolerance = np.zeros(shape + (6,))
    lower = np.zeros(shape + (6,))
    upper = np.zeros(shape + (6,))
    held, angles, labels = {}, {}, []
    with np.errstate(invalid="ignore", divide="ignore"):
        for src in info["sources"]:
            M = src.matrix                                                          # (..., 6, d)
            rown = np.linalg.norm(M, axis=-1)                                       # (..., 6)
            if src.key not in CLEARANCE_KEYS:
                tolerance = tolerance + rown
                continue
            scale = Lc if _is_rotation(robot, src) else 1.0
            t = threshold * scale * src.half_width
            active = np.max(np.abs(src.E), axis=(-1, -2)) > 1e-9 * src.half_width * scale
            g = np.einsum("...id,...ki->...kd", M, F)                              # (..., 65, d)
            gn = np.linalg.norm(g, axis=-1)
            und = active[..., None] & (gn <= t)
            sel = active[..., None] & ~und
            x = np.where(sel[..., None], g / np.where(sel, gn, 1.0)[..., None], 0.0)
            err = err + np.einsum("...id,...kd->...ki", M, x)
            spread = spread + np.where(und[..., None], rown[..., None, :], 0.0)
            n0 = gn[..., 0]
            u0 = g[..., 0, :] / np.where(n0 > 0, n0, 1.0)[..., None]
            along = np.einsum("...kd,...d->...k", g[..., 1:, :], u0)               # (..., 64)
            ok = active & (n0 > 0) & (np.min(along, axis=-1) > t)
            cos = np.min(along / np.where(gn[..., 1:] > 0, gn[..., 1:], 1.0), axis=-1)
            theta = np.where(ok, np.arccos(np.clip(cos, -1.0, 1.0)), np.pi)
            mu = np.einsum("...id,...d->...i", M, u0)
            phi = np.arccos(np.clip(mu / np.where(rown > 0, rown, 1.0), -1.0, 1.0))
            th = theta[..., None]
            hi = np.where(ok[..., None], rown * np.cos(np.maximum(phi - th, 0.0)), rown)
            lo = np.where(ok[..., None], -rown * np.cos(np.maximum(np.pi - phi - th, 0.0)), -rown)
            upper, lower = upper + hi, lower + lo
            # a clearance without first-order effect (M_s = 0) is held trivially
            held[src.label] = ok | ~active
            angles[src.label] = np.where(active, np.degrees(theta), 0.0)
            labels.append(src.label)
    return {"lower": lower, "upper": upper, "attained_lower": np.min(err - spread, axis=-2),
            "attained_upper": np.max(err + spread, axis=-2), "tolerance": tolerance, "labels": labels,
            "held": held, "max_angle_deg": angles}


def _threshold(threshold) -> None:
    if not (isinstance(threshold, (int, float)) and math.isfinite(threshold) and threshold >= 0):
        raise ConfigError(f"must be finite and >= 0 (N), got {threshold!r}", key="threshold")


def spatial_wrench_set_errors(robot: SpatialManipulator | str, clearances, poses, center, half, *,
                              threshold: float = DEFAULT_THRESHOLD_N) -> SpatialWrenchSetErrors:
    """The first-order loaded error at ``poses`` ``(..., 6)`` when the process wrench may be anywhere in the box
    ``center +- half`` ``(6,)`` [N x3, N mm x3 about P]: an enclosure and the attained range of each component,
    and which clearances the box leaves on one side (the spatial counterpart of
    :func:`pmaccuracy.accuracy.loads.wrench_set_errors`).

    The loaded error at a wrench ``F`` is ``sum_s M_s x_s(F)``, ``x_s = M_s^T F / |M_s^T F|`` (module docstring).
    A planar robot's clearances are segments whose signs form finitely many contact patterns, so its range over
    the box is exact; a spatial robot's discs and balls turn continuously with ``F``, and the range of a sum of
    such terms over a box has no closed form. So two ranges are given: ``lower, upper``, guaranteed to contain
    the loaded error for every wrench of the box (each clearance's own range, summed: :func:`_wrench_set`), and
    ``attained_lower, attained_upper``, the loaded error (with the undetermined clearances' spread) at the box's
    centre and 64 corners, which it does reach. The exact range lies between them. The tolerances stay apart
    (``tolerance``).

    Parameters
    ----------
    robot : SpatialManipulator or str
        The robot, a preset name or a path.
    clearances : SpatialErrorSources or str
        The error sources, a preset name or a path.
    poses : array_like, shape (..., 6)
        [x, y, z mm, rotation vector rad], flattened to ``(n, 6)``.
    center, half : array_like, shape (6,)
        The box [N x3, N mm x3].
    threshold : float
        N (N mm over ``L`` for rotation sources), as :func:`spatial_loaded_error`.

    Examples
    --------
    >>> robot = SpatialManipulator.preset("stewart_6ups")
    >>> r = spatial_wrench_set_errors(robot, "ups_typical", robot.home_pose, [0, 0, -50, 0, 0, 0],
    ...                               [5, 5, 5, 0, 0, 0])
    >>> bool(np.all(r.lower <= r.attained_lower + 1e-12) and np.all(r.attained_upper <= r.upper + 1e-12))
    True
    """
    check_angle_values(rotation_angles(poses), "poses[..., 3:] (rotation vectors)")
    robot = _robot(robot)
    sources = _sources(robot, clearances)
    c, h = _box(center, half)
    _threshold(threshold)
    poses = as_spatial_poses(poses).reshape(-1, 6)
    _, info = error_sources_at(robot, sources, poses, keep=True)
    return SpatialWrenchSetErrors(poses=poses, center=c, half=h, **_wrench_set(robot, info, c, h, threshold))


# ----------------------------------------------------------------------------------------------------- maps
#: Poses per block of the maps (bounded memory).
MAP_BLOCK = 4096


def _map_grid(robot: SpatialManipulator, n: int, orientation):
    """The workspace grid of :func:`pmaccuracy.accuracy.spatial_maps.spatial_error_map`: ``(region, inside,
    poses (m, 6))`` with the poses of the grid points inside (NaN where a parasitic motion has no solution)."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
        raise ConfigError(f"must be a whole number >= 2, got {n!r}", key="n")
    region = spatial_workspace(robot, orientation=orientation, n=n, tilt=False).region
    grid = np.stack(np.meshgrid(*region.axes, indexing="ij"), axis=-1)
    return region, region.inside, grid_poses(robot, grid[region.inside], orientation)


def _valid(robot: SpatialManipulator, sources: SpatialErrorSources, poses: np.ndarray) -> np.ndarray:
    """``(m,)`` bool: poses that are finite, within the joint limits and away from singularities."""
    ok = np.all(np.isfinite(poses), axis=-1)
    if np.any(ok):
        _, info = error_sources_at(robot, sources, poses[ok], strict=False, keep=False)
        good = np.asarray(info["valid"]) & np.asarray(inverse_kinematics(robot, poses[ok]).within_limits)
        ok[ok] = good
    return ok


def _map_dataset(robot, sources, region, inside, values: dict, units: dict, attrs: dict) -> xr.Dataset:
    out = {}
    for name, col in values.items():
        arr = np.full(inside.shape, np.nan)
        arr[inside] = col
        out[name] = (region.names, arr, {"units": units[name]})
    ds = xr.Dataset(out, coords={d: (d, a, {"units": u}) for d, a, u in zip(region.names, region.axes, region.units)})
    ds.attrs.update(robot=robot.name, architecture=robot.architecture, clearances=sources.name, **attrs)
    return ds


def _components(arr: np.ndarray, suffix: str = "") -> tuple[dict, dict]:
    vals = {f"{c}{suffix}": arr[:, k] for k, c in enumerate(COMPONENTS)}
    units = {f"{c}{suffix}": "mm" if k < 3 else "rad" for k, c in enumerate(COMPONENTS)}
    return vals, units


def spatial_loaded_error_map(robot: SpatialManipulator | str, clearances, load: SpatialLoad, *, n: int = 10,
                             orientation=None, threshold: float = DEFAULT_THRESHOLD_N) -> xr.Dataset:
    """The loaded error (:func:`spatial_loaded_error`) under one ``load`` at every point of the workspace's
    ``n``-per-axis grid (the grid, dims and coordinates of
    :func:`pmaccuracy.accuracy.spatial_maps.spatial_error_map`: x, y, z mm at the fixed ``orientation`` (a
    rotation vector, rad) of a 6-UPS; roll, pitch deg and z mm for a 3-RPS/3-PRS), NaN outside the workspace and
    near singularities.

    Variables: ``dx, dy, dz`` (mm), ``drx, dry, drz`` (rad) the first-order loaded error, ``dp`` (mm) and
    ``dtheta`` (rad) its magnitudes, ``*_spread`` the half-width the undetermined clearances leave,
    ``*_tolerance`` the tolerances' worst case (kept apart, as in :class:`SpatialLoadedError`), ``lambda1..6``
    the closure rows' intensities (N, or N mm for a couple row) and ``undetermined`` the number of undetermined
    clearances. Vectorized over blocks of :data:`MAP_BLOCK` poses.

    >>> robot = SpatialManipulator.preset("upu_3")
    >>> ds = spatial_loaded_error_map(robot, "upu_typical", SpatialLoad(force=(0.0, 0.0, -50.0)), n=5)
    >>> sorted(ds.sizes.items()), bool(float(ds.dz.max()) < 0)
    ([('x', 5), ('y', 5), ('z', 5)], True)
    """
    if orientation is not None:
        check_angle_values(np.linalg.norm(np.asarray(orientation, dtype=float)), "orientation (rotation vector)")
    robot = _robot(robot)
    sources = _sources(robot, clearances)
    _check_load(load)
    _threshold(threshold)
    region, inside, poses = _map_grid(robot, n, orientation)
    names = ["error", "spread", "tolerance"]
    cols = {k: np.full((len(poses), 6), np.nan) for k in names + ["lambda"]}
    und = np.full(len(poses), np.nan)
    for start in range(0, len(poses), MAP_BLOCK):
        block = poses[start:start + MAP_BLOCK]
        ok = _valid(robot, sources, block)
        if not np.any(ok):
            continue
        res = spatial_loaded_error(robot, sources, block[ok], load, threshold=threshold)
        idx = np.arange(start, start + len(block))[ok]
        for k in names:
            cols[k][idx] = getattr(res, k)
        cols["lambda"][idx] = res.statics.intensity
        und[idx] = sum(np.asarray(v, dtype=float) for v in res.undetermined.values()) if res.undetermined else 0.0
    values, units = _components(cols["error"])
    for what in ("spread", "tolerance"):
        v, u = _components(cols[what], f"_{what}")
        values.update(v)
        units.update(u)
    values.update(dp=np.linalg.norm(cols["error"][:, :3], axis=-1), dtheta=np.linalg.norm(cols["error"][:, 3:], axis=-1))
    units.update(dp="mm", dtheta="rad")
    for r in range(6):
        values[f"lambda{r + 1}"], units[f"lambda{r + 1}"] = cols["lambda"][:, r], "N or N mm"
    values["undetermined"], units["undetermined"] = und, "1"
    F = load.wrench(np.zeros(6))
    return _map_dataset(robot, sources, region, inside, values, units,
                        {"load": f"force {F[:3].tolist()} N, moment {load.moment} N mm about P, mass {load.mass:g} kg "
                                 f"at {load.com} mm (platform frame), gravity {load.gravity}",
                         "threshold_N": threshold,
                         "description": "first-order loaded error (clearances taken up along the joints' "
                                        "reactions); tolerances apart; NaN outside the workspace or near a "
                                        "singularity"})


def spatial_wrench_set_map(robot: SpatialManipulator | str, clearances, center, half, *, n: int = 8,
                           orientation=None, threshold: float = DEFAULT_THRESHOLD_N, preload: bool = True,
                           direction=None, margin: float = DEFAULT_THRESHOLD_N) -> xr.Dataset:
    """For process wrenches anywhere in the box ``center +- half`` ``(6,)`` [N x3, N mm x3 about P], at every point
    of the workspace's ``n``-per-axis grid (as :func:`spatial_loaded_error_map`): the loaded error's enclosure
    ``d*_lo, d*_hi`` and attained range ``d*_attained_lo, d*_attained_hi`` (mm, rad;
    :func:`spatial_wrench_set_errors`), ``not_held`` the number of clearances the box does not keep on one side,
    and the preload each point needs (:func:`spatial_design_preload`): ``preload_size`` (N, the size
    ``max(|P_f|, |P_m| / L)`` of the smallest free preload: 64 linear programs per point pruned by lower bounds,
    about a third of them solved on a 6-UPS, ~0.1 s per point) or, with ``direction`` ``(6,)``, the smallest
    multiple ``preload_alpha`` of it (closed form, vectorized; ``inf`` where no multiple holds every row). ``preload=False`` skips the free
    preload. NaN outside the workspace and near singularities.

    >>> robot = SpatialManipulator.preset("stewart_6ups")
    >>> ds = spatial_wrench_set_map(robot, "ups_typical", [0, 0, -50, 0, 0, 0], [5, 5, 5, 100, 100, 100], n=4,
    ...                             orientation=[0.0, 0.0, 0.0], preload=False)
    >>> bool(float((ds.dz_hi - ds.dz_attained_hi).min()) >= 0)
    True
    """
    if orientation is not None:
        check_angle_values(np.linalg.norm(np.asarray(orientation, dtype=float)), "orientation (rotation vector)")
    robot = _robot(robot)
    sources = _sources(robot, clearances)
    c, h = _box(center, half)
    _threshold(threshold)
    if not (isinstance(margin, (int, float)) and math.isfinite(margin) and margin >= 0):
        raise ConfigError(f"must be finite and >= 0 (N), got {margin!r}", key="margin")
    if direction is not None:
        d = np.asarray(direction, dtype=float).reshape(-1)
        if d.shape != (6,) or not np.all(np.isfinite(d)) or not np.any(d):
            raise ConfigError(f"expected six finite numbers, not all zero, got {direction!r}", key="direction")
    region, inside, poses = _map_grid(robot, n, orientation)
    m = len(poses)
    keys = ("lower", "upper", "attained_lower", "attained_upper")
    cols = {k: np.full((m, 6), np.nan) for k in keys}
    not_held, size, alpha = np.full(m, np.nan), np.full(m, np.nan), np.full(m, np.nan)
    scale = np.array([1.0] * 3 + [robot.characteristic_length] * 3)
    for start in range(0, m, MAP_BLOCK):
        block = poses[start:start + MAP_BLOCK]
        ok = _valid(robot, sources, block)
        if not np.any(ok):
            continue
        idx = np.arange(start, start + len(block))[ok]
        _, info = error_sources_at(robot, sources, block[ok], keep=True)
        res = _wrench_set(robot, info, c, h, threshold)
        for k in keys:
            cols[k][idx] = res[k]
        not_held[idx] = sum((~v).astype(float) for v in res["held"].values()) if res["held"] else 0.0
        Lmaps = -np.swapaxes(info["Winv"], -1, -2)
        if direction is not None:
            alpha[idx] = _direction_alpha(Lmaps, c, h, margin, d)[0]
        if preload:
            for j, L in zip(idx, Lmaps):
                best = _preload_lp(L[None], c, h, margin, scale)
                size[j] = np.nan if best is None else best[0]
    values, units = {}, {}
    for k, suffix in zip(keys, ("_lo", "_hi", "_attained_lo", "_attained_hi")):
        v, u = _components(cols[k], suffix)
        values.update(v)
        units.update(u)
    values["not_held"], units["not_held"] = not_held, "1"
    if preload:
        values["preload_size"], units["preload_size"] = size, "N"
    if direction is not None:
        values["preload_alpha"], units["preload_alpha"] = alpha, "1"
    attrs = {"wrench_box_lo": (c - h).tolist(), "wrench_box_hi": (c + h).tolist(), "threshold_N": threshold,
             "margin_N": margin, "description": "loaded error over a box of process wrenches: a guaranteed "
             "enclosure (*_lo, *_hi) and the range at the box's centre and corners (*_attained_*); the preload "
             "each point needs; NaN outside the workspace or near a singularity"}
    if direction is not None:
        attrs["preload_direction"] = d.tolist()
    return _map_dataset(robot, sources, region, inside, values, units, attrs)


# ------------------------------------------------------------------------------------------ preload over a region
#: Absolute slack (N per N of preload) allowed to the linear programs' feasibility tolerance.
_LP_TOLERANCE = 1e-9
#: Most poses of the check sample of :func:`spatial_design_region_preload` (a seeded random sample beyond it).
MAX_CHECK = 20_000


@dataclass(frozen=True)
class SpatialRegionPreload:
    """One constant platform wrench holding every closure row's sign for every process wrench of a box at every
    sampled pose of a region (:func:`spatial_design_region_preload`).

    Attributes
    ----------
    region : str
        The region in words.
    center, half : ndarray, shape (6,)
        The process box [N x3, N mm x3 about P].
    wrench : ndarray, shape (6,)
        The preload [N x3, N mm x3 about P, base frame].
    size : float
        ``max(|P_f|, |P_m| / L)`` (N): the optimum over the design poses, so no smaller preload holds there (a
        lower bound of the smallest preload for the whole region).
    pattern : ndarray, shape (6,)
        The rows' intensity signs it holds.
    attaining : ndarray, shape (6,)
        The design pose whose constraint binds [mm, rotation vector rad].
    per_pose_size : float
        The size :func:`spatial_design_preload` needs at ``attaining`` alone (N).
    min_intensity : float
        The smallest ``s_k lambda_k`` (N, or N mm for a couple row) over the check poses and the box's worst
        wrench (``>= margin`` where the design holds).
    n_design, n_check : int
        Poses in the linear program; poses checked.
    offset_max : ndarray, shape (6,)
        [mm, rad]: the largest ``|loaded error|`` at ``P + center`` over the design grid's poses.
    worst_max : ndarray, shape (6,)
        [mm, rad]: the unloaded worst case over the same poses.
    not_held : list of str
        The clearances whose reaction is not kept strictly on one side at some pose of the design grid (discs and balls may turn
        by 90 deg or more although every row keeps its sign).
    """

    region: str
    center: np.ndarray
    half: np.ndarray
    wrench: np.ndarray
    size: float
    pattern: np.ndarray
    attaining: np.ndarray
    per_pose_size: float
    min_intensity: float
    n_design: int
    n_check: int
    offset_max: np.ndarray
    worst_max: np.ndarray
    not_held: list

    def record(self) -> dict:
        """The command line's record (N, N mm, mm, deg)."""
        keys = ("fx_N", "fy_N", "fz_N", "mx_Nmm", "my_Nmm", "mz_Nmm")
        rec = {"region": self.region, "pattern": "".join("+" if v > 0 else "-" for v in self.pattern)}
        rec.update({f"preload_{k}": float(v) + 0.0 for k, v in zip(keys, self.wrench)})
        rec["preload_size_N"] = self.size
        a = coordinates(self.attaining, degrees=True)
        rec.update({f"attaining_{n}": float(v) for n, v in zip(("x", "y", "z", "roll_deg", "pitch_deg", "yaw_deg"),
                                                               a)})
        rec.update(per_pose_size_N=self.per_pose_size, min_intensity=self.min_intensity, n_design=self.n_design,
                   n_check=self.n_check)
        for what, arr in (("offset_", self.offset_max), ("", self.worst_max)):
            for c, name in enumerate(COMPONENTS):
                rec[f"{what}{name}{'_deg' if c >= 3 else ''}_max"] = float(arr[c]) if c < 3 else \
                    math.degrees(arr[c])
        rec["not_held"] = ",".join(self.not_held) or "-"
        return rec

    def __repr__(self) -> str:
        return (f"SpatialRegionPreload({self.region}: preload size {self.size:.4g} N, holds on {self.n_check} "
                f"checked poses with min s_k lambda_k {self.min_intensity:.3g}; not proved between them)")


def _region_sample(robot: SpatialManipulator, region, n: int) -> np.ndarray:
    """Full poses ``(m, 6)`` of an ``n``-per-axis grid of the region's box (and a 6-UPS's orientation ranges;
    one value along a point interval), in the region's shape and the joint limits; raises
    :class:`~pmaccuracy.accuracy.spatial_worst.SpatialSingularRegionError` where one is near-singular."""
    root = _box_dims(robot, region)
    pts = _grid(root, n)
    if len(pts) > MAX_CHECK:
        rng = np.random.default_rng(0)
        pts = root[:, 0] + rng.random((MAX_CHECK, root.shape[0])) * (root[:, 1] - root[:, 0])
    pts = pts[region.contains(pts[:, :3])]
    full = _full_poses(robot, pts)
    full = full[np.all(np.isfinite(full), axis=1)]
    if not len(full):
        return full
    full = full[np.asarray(inverse_kinematics(robot, full).within_limits)]
    if len(full):
        _, info = error_sources_at(robot, SpatialErrorSources.zero(robot), full, strict=False, keep=False)
        bad = ~np.asarray(info["valid"])
        if np.any(bad):
            c = coordinates(full[int(np.argmax(bad))], degrees=True)
            raise SpatialSingularRegionError(
                f"{region.describe()} reaches a singularity of {robot.name} near (x, y, z, roll, pitch, yaw) = "
                f"({', '.join(f'{v:.4g}' for v in c)}): the rows' intensities, and the preload keeping their signs, "
                "are unbounded there; narrow the region")
    return full


def _intensity_maps(robot: SpatialManipulator, poses: np.ndarray) -> np.ndarray:
    _, info = error_sources_at(robot, SpatialErrorSources.zero(robot), poses, keep=False)
    return -np.swapaxes(info["Winv"], -1, -2)


def spatial_design_region_preload(robot: SpatialManipulator | str, clearances, region, center, half, *,
                                  grid: int = 5, margin: float = DEFAULT_THRESHOLD_N,
                                  rounds: int = 4) -> SpatialRegionPreload:
    """The smallest constant platform wrench ``P`` (size ``max(|P_f|, |P_m| / L)``) keeping every closure row's
    intensity on one side, with at least ``margin``, for every process wrench of the box ``center +- half``
    ``(6,)`` at the sampled poses of ``region`` (a :class:`~pmaccuracy.accuracy.spatial_worst.SpatialRegion`:
    :func:`~pmaccuracy.accuracy.spatial_worst.spatial_region`), the spatial counterpart of
    :func:`pmaccuracy.accuracy.loads.design_region_preload`.

    As for planar robots, a preload keeping every row loaded over a connected region keeps one sign pattern
    ``s`` there (the intensities are continuous and never cross ``(-margin, margin)``), so one linear program
    per pattern takes every design pose at once: ``s_k L_k(p) P >= margin - s_k L_k(p) center + |L_k(p)| half``
    (the box's worst wrench, exact: ``lambda`` is linear in the wrench), ``min max_j |P_j| / scale_j``
    (:func:`_preload_lp`), over a ``grid``-per-axis sample of the region's box (x, y, z or z, roll, pitch, and
    a 6-UPS's orientation ranges). Its optimum is a **lower bound** of the smallest preload for the region. The
    design is then checked on a sample twice as dense (``2 grid - 1`` per axis; a seeded random sample of
    :data:`MAX_CHECK` poses when that is larger) and the poses where it fails join the program, ``rounds``
    times at most (then every check pose joins it once more). **Guaranteed**: every ``s_k lambda_k >= margin``
    (to the linear programs' feasibility tolerance; ``min_intensity`` reports it) at every checked pose for every
    wrench of the box. **Weaker than the planar one**: nothing is proved between the checked poses (no interval certificate
    of a spatial ``W^-1`` over a box of poses is written here). A region reaching a singularity is refused
    (:class:`~pmaccuracy.accuracy.spatial_worst.SpatialSingularRegionError`).
    """
    robot = _robot(robot)
    sources = _sources(robot, clearances)
    c, h = _box(center, half)
    if not isinstance(region, SpatialRegion):
        raise ConfigError(f"expected a SpatialRegion (pmaccuracy.accuracy.spatial_worst.spatial_region), got "
                          f"{region!r}", key="region")
    for key, value, least in (("grid", grid, 2), ("rounds", rounds, 1)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
            raise ConfigError(f"must be a whole number >= {least}, got {value!r}", key=key)
    if not (isinstance(margin, (int, float)) and math.isfinite(margin) and margin > 0):
        raise ConfigError(f"must be > 0 (N), got {margin!r}", key="margin")
    design = _region_sample(robot, region, grid)
    if not len(design):
        raise EmptyWorkspaceError(f"no pose of the {grid}-per-axis grid of {region.describe()} is in the workspace")
    n_grid = len(design)
    check = np.vstack([design, _region_sample(robot, region, 2 * grid - 1)])
    Ld, Lk = _intensity_maps(robot, design), _intensity_maps(robot, check)
    scale = np.array([1.0] * 3 + [robot.characteristic_length] * 3)
    for k in range(rounds + 1):
        if k == rounds:                  # the exchange did not settle: every check pose joins the program
            design, Ld = np.vstack([design, check]), np.concatenate([Ld, Lk])
        best = _preload_lp(Ld, c, h, margin, scale)
        if best is None:
            raise ConfigError(f"no constant preload holds every row's sign over {region.describe()}: narrow the "
                              "region", key="region")
        size, P, s = best
        slack = np.min(s * (Lk @ (P + c)) - np.abs(Lk) @ h, axis=-1)
        bad = slack < margin * (1 - 1e-6) - _LP_TOLERANCE * (1.0 + np.max(np.abs(P)))
        if not np.any(bad):
            break
        design, Ld = np.vstack([design, check[bad]]), np.concatenate([Ld, Lk[bad]])
    binding = np.min(s * (Ld @ (P + c)) - np.abs(Ld) @ h, axis=-1)
    attaining = design[int(np.argmin(binding))]
    per_pose = spatial_design_preload(robot, sources, attaining, c, h, margin=margin).size
    grid_poses_ = design[:n_grid]                     # the statistics over the design grid (as the planar ones)
    _, info = error_sources_at(robot, sources, grid_poses_, keep=True)
    ws = _wrench_set(robot, info, P + c, h, 0.0) if np.any(h) else None
    chosen, _ = _selection(robot, info, np.broadcast_to(P + c, grid_poses_.shape), DEFAULT_THRESHOLD_N)
    offset = sum(np.einsum("...ij,...j->...i", M, x) for _, M, x, _, _ in chosen) if chosen else \
        np.zeros(grid_poses_.shape)
    worst = spatial_pose_errors(robot, sources, grid_poses_, strict=False, details=False).components
    not_held = [k for k, v in ws["held"].items() if not np.all(v)] if ws is not None else []
    return SpatialRegionPreload(region=region.describe(), center=c, half=h, wrench=np.asarray(P, dtype=float),
                                size=float(size), pattern=s, attaining=attaining, per_pose_size=float(per_pose),
                                min_intensity=float(np.min(slack)), n_design=int(len(design)),
                                n_check=int(len(check)), offset_max=np.max(np.abs(offset), axis=0),
                                worst_max=np.max(worst, axis=0), not_held=not_held)


# ------------------------------------------------------------------------------------ springs along the legs
#: Architectures whose actuated legs run from a base joint centre ``A_i`` to a platform joint centre ``B_i``
#: (a spring alongside the leg between those centres).
SPRING_ARCHITECTURES = ("6-UPS", "3-RPS", "3-UPU")


@dataclass(frozen=True)
class SpatialSpringPreload:
    """Constant-force springs alongside the legs holding every closure row's sign (:func:`spatial_spring_preload`).

    Attributes
    ----------
    forces : ndarray, shape (n,)
        Each leg's spring force (N), positive when it pushes the platform away from the base (compression).
    size : float
        ``max |forces|`` (N), the smallest possible; each force is then as weak as the others allow (least sum).
    pattern : ndarray, shape (6,)
        The rows' intensity signs held.
    poses : ndarray, shape (m, 6)
        The poses it holds at [mm, rotation vector rad].
    min_intensity : float
        The smallest ``s_k lambda_k`` over the poses and the box's worst wrench (N, or N mm for a couple row).
    offset : ndarray, shape (m, 6)
        [mm, rad]: the first-order loaded error at the box's centre plus the springs.
    held : dict
        ``{label: bool}``: the clearance's reaction stays strictly on one side at every pose for every wrench of
        the box (:class:`SpatialWrenchSetErrors` with a zero threshold).
    """

    forces: np.ndarray
    size: float
    pattern: np.ndarray
    poses: np.ndarray
    min_intensity: float
    offset: np.ndarray
    held: dict = field(repr=False)


def _spring_wrenches(robot: SpatialManipulator, poses: np.ndarray) -> np.ndarray:
    """``S`` ``(m, 6, n)``: column ``i`` the wrench about ``P`` of a unit force pushing the platform at ``B_i``
    along ``u_i = (B_i - A_i) / |B_i - A_i|``: ``[u_i, (B_i - P) x u_i]``."""
    p, R = poses[..., :3], rotations(poses[..., 3:])
    cols = []
    for leg in robot.legs:
        B = leg.platform_point(p, R)
        u = B - np.asarray(leg.base, dtype=float)
        u = u / np.linalg.norm(u, axis=-1, keepdims=True)
        cols.append(np.concatenate([u, np.cross(B - p, u)], axis=-1))
    return np.stack(cols, axis=-1)


def _weakest(LS: np.ndarray, c, h, margin: float, Lmaps: np.ndarray, s: np.ndarray, size: float,
             sigma: np.ndarray) -> np.ndarray:
    """The springs of pattern ``s`` with ``max |sigma_i| <= size`` and the least ``sum |sigma_i|`` (each as weak as
    the others allow; scipy HiGHS), or ``sigma`` when that program fails."""
    n = LS.shape[-1]
    rows = (s[None, :, None] * LS).reshape(-1, n)
    rhs = (margin - s[None] * (Lmaps @ c) + np.abs(Lmaps) @ h).reshape(-1)
    eye = np.eye(n)
    A_ub = np.vstack([np.column_stack([-rows, np.zeros(rows.shape)]),
                      np.column_stack([eye, -eye]), np.column_stack([-eye, -eye])])
    b_ub = np.concatenate([-rhs, np.zeros(2 * n)])
    res = linprog(np.r_[np.zeros(n), np.ones(n)], A_ub=A_ub, b_ub=b_ub,
                  bounds=[(-size, size)] * n + [(0, None)] * n, method="highs")
    return res.x[:n] if res.status == 0 else sigma


def spatial_spring_preload(robot: SpatialManipulator | str, clearances, poses, center, half, *,
                           margin: float = DEFAULT_THRESHOLD_N) -> SpatialSpringPreload:
    """The smallest constant-force springs alongside the legs (one per leg, between the leg's base and platform
    joint centres ``A_i``, ``B_i``, e.g. gas springs) keeping every closure row's intensity on one side, with at
    least ``margin``, for every process wrench of the box ``center +- half`` ``(6,)`` at every pose of ``poses``
    ``(..., 6)``: the preload as springs on the actuated legs instead of a constant platform wrench
    (:func:`spatial_design_preload`).

    A spring of force ``sigma_i`` pushes the platform with ``sigma_i S_i``, ``S_i = [u_i, (B_i - P) x u_i]``
    (:func:`_spring_wrenches`), a wrench that moves with the pose; it bypasses the leg, so the rows' intensities
    become ``lambda = L (F + S sigma)`` (``L = -W^{-T}``). Where ``S_i`` is leg ``i``'s axial row (a 6-UPS leg, a
    3-RPS or 3-UPU leg's force row), ``lambda_i = lambda_i(F) - sigma_i``: the spring only shifts its own leg's
    axial force, so it cannot hold a 3-RPS revolute row or a 3-UPU couple row that the box flips
    (:class:`~pmaccuracy.errors.ConfigError`, key ``half``). One linear program per sign pattern over the poses
    (:func:`_preload_lp` with ``A = S``): ``min max |sigma_i|`` subject to the box's worst wrench at every pose,
    then, at that size, the least ``sum |sigma_i|`` (:func:`_weakest`).
    Springs with a stiffness (force changing with the leg's length) are not modelled.
    Architectures: :data:`SPRING_ARCHITECTURES` (the others' actuators are not a leg between two joint centres:
    :class:`~pmaccuracy.errors.UnsupportedArchitectureError`).

    >>> robot = SpatialManipulator.preset("stewart_6ups")
    >>> sp = spatial_spring_preload(robot, "ups_typical", robot.home_pose, np.zeros(6), [10, 10, 10, 0, 0, 0],
    ...                             margin=1.0)
    >>> bool(sp.size > 0 and all(sp.held.values()))
    True
    """
    check_angle_values(rotation_angles(poses), "poses[..., 3:] (rotation vectors)")
    robot = _robot(robot)
    if robot.architecture not in SPRING_ARCHITECTURES or any(isinstance(leg, ChainLeg) for leg in robot.legs):
        raise UnsupportedArchitectureError(
            f"springs alongside the legs are modelled for {', '.join(SPRING_ARCHITECTURES)} (legs from a base to a "
            f"platform joint centre); {robot.name} is a {robot.architecture}: use a platform preload "
            "(spatial_design_preload)", key="robot")
    sources = _sources(robot, clearances)
    c, h = _box(center, half)
    if not (isinstance(margin, (int, float)) and math.isfinite(margin) and margin >= 0):
        raise ConfigError(f"must be finite and >= 0 (N), got {margin!r}", key="margin")
    poses = as_spatial_poses(poses).reshape(-1, 6)
    _, info = error_sources_at(robot, sources, poses, keep=True)
    Lmaps = -np.swapaxes(info["Winv"], -1, -2)
    S = _spring_wrenches(robot, poses)
    best = _preload_lp(Lmaps, c, h, margin, np.ones(robot.n_legs), A=S)
    if best is None:
        lam_lo = np.min(Lmaps @ c - np.abs(Lmaps) @ h, axis=0)
        lam_hi = np.max(Lmaps @ c + np.abs(Lmaps) @ h, axis=0)
        moved = np.any(np.abs(Lmaps @ S) > 1e-12, axis=(0, 2))
        rows = [str(k + 1) for k in range(6) if not moved[k] and lam_lo[k] < margin and lam_hi[k] > -margin]
        raise ConfigError("no springs alongside the legs hold every row's sign over the box"
                          + (f": rows {', '.join(rows)} (not along a leg) change sign with the process wrench and "
                             "no spring moves them" if rows else " at these poses"), key="half")
    size, sigma, pattern = best
    sigma = _weakest(Lmaps @ S, c, h, margin, Lmaps, pattern, size, sigma)
    P = np.einsum("mij,j->mi", S, sigma)                                          # the springs' wrench per pose
    slack = np.min(pattern * np.einsum("mij,mj->mi", Lmaps, P + c) - np.abs(Lmaps) @ h)
    ws = _wrench_set(robot, info, P + c, h, 0.0)
    chosen, _ = _selection(robot, info, P + c, DEFAULT_THRESHOLD_N)
    offset = sum(np.einsum("...ij,...j->...i", M, x) for _, M, x, _, _ in chosen) if chosen else np.zeros(P.shape)
    return SpatialSpringPreload(forces=np.asarray(sigma, dtype=float), size=float(size), pattern=pattern,
                                poses=poses, min_intensity=float(slack), offset=offset,
                                held={k: bool(np.all(v)) for k, v in ws["held"].items()})
