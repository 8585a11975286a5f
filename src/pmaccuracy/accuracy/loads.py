r"""Clearances under load: the statics of every architecture and the pose error a known wrench produces.

The worst case lets every clearance sit anywhere in its set. Under a load each
joint's clearance is taken up along its reaction (Venanzi and Parenti-Castelli
2005, the paper's ref. 10; the paper's own experiment pushes the platform to
take the clearances up, Sec. 5), so the pose error becomes a definite value.

**Statics.** Hold the actuators. With the passive joints' constraint wrench
``zeta_i = (f_i, m_P,i)`` of leg ``i`` (unit force, moment about the platform
centre ``P``: row ``i`` of ``A``, :attr:`pmaccuracy.model.chain.LegState.A_row`) the
legs push on the platform with ``lambda_i zeta_i``. Equilibrium with the external
wrench ``W = (f_x, f_y, m)`` (N, N, N mm about ``P``, base frame; what the
environment applies to the platform) gives

.. math::

    A^T \lambda = -W, \qquad \tau_i = \lambda_i B_{ii}

(``tau_i``: the actuator's force in N, or torque in N mm, on the part beyond it,
by virtual work with ``A dX = B dq``). Every joint of a massless leg carries the
same wrench ``lambda_i zeta_i``: an R joint at ``c_k`` the force ``lambda_i f_i``,
a P joint's block the normal force ``N = lambda_i f_i . E e_k`` and the moment
``M = lambda_i M_i(b_k)`` about its centre (:func:`pmaccuracy.model.sources.block_centre`),
i.e. the two end contact forces ``N / 2 -+ M / L`` of a block of length ``L``.

**Loaded pose error.** A clearance lets the platform yield in the direction
the load does work: the reached error maximizes the virtual work ``W . dX`` over
the error set. To first order ``dX = A^{-1} e`` with ``e_i`` in ``[-c_i, c_i]``, and
``W . A^{-1} e = -lambda . e``, so

.. math::

    e_i = -\operatorname{sign}(\lambda_i)\, c_i, \qquad
    \delta X_{\text{loaded}} = A^{-1} \operatorname{diag}(c)\, t, \quad t = -\operatorname{sign}(\lambda)

the vertex of the error zonotope that supports it in the direction ``W``; each
source sits at the extreme of its set along its joint's reaction (an R joint's
pin against the bore opposite the force, a P joint's block on the rhombus
vertex that ``N`` and ``M`` select, an actuator's backlash against its force:
:func:`pmaccuracy.model.sources.worst_configuration` with the signs ``t``). The
exact loaded pose closes the perturbed loops with those values
(:func:`pmaccuracy.accuracy.nonlinear.closure_state`). A leg whose wrench
intensity ``|lambda_i|`` is below ``threshold`` is **unloaded**: its state is
undetermined and the error is a range, the loaded value plus or minus that
leg's generator ``c_i A^{-1}[:, i]``.

**Exact loaded pose: a self-consistent equilibrium.** With frictionless
contacts and a conservative load the platform settles where ``W . X`` is
largest over the configurations the clearances allow (the potential ``-W . X``
least; with a weight, the work of ``G0 mass`` at the displaced centre of
mass). Its optimality condition puts each source at the extreme of its set
along the gradient of ``W . X`` *at the displaced configuration*, not at the
commanded one. With the closure unknowns ``z`` (pose and passive joints),
residual ``r(z, v) = 0`` and ``J = dr/dz`` there, that gradient is
``-(dr/dv)^T mu`` with the adjoint ``mu = J^{-T} [W(X), 0]``. A pin shift ``d``
(base frame) before any joint of leg ``i`` enters ``r`` as ``+d`` in the leg's
two position rows, so ``F'_i = mu_{3i} + j mu_{3i+1}`` is the force that leg
transmits in the displaced configuration (``F'_i -> lambda_i f_i`` as the
clearances vanish), and every radial/position clearance of a loaded leg sits
at ``d = c_k (-F'_i / |F'_i|)``: the pin against the bore opposite the actual
reaction. Likewise every vertex source takes the side of its own gradient
``g = -(dr/dv)^T mu`` (central differences of ``r`` in ``v``): an actuator's
backlash ``eps sign(g_dq)``, a block's tilt ``eps sign(g_tilt)`` and its
rhombus vertex, the shift ``(eps sign(g_sigma), 0)`` when
``eps |g_sigma| >= 2 eps |g_tilt| / L`` else the tilt ``(0, 2 eps sign(g_tilt) / L)``
(``g_sigma``, ``g_tilt``: the normal force and the moment about the block's
centre in the displaced configuration). This matters where the commanded
reaction component is zero, e.g. a 3-RPR's prismatic block, whose leg force
runs along the rail through the block's centre: the commanded statics leaves
its side undetermined, the displaced one selects it. The fixed point
``v -> closure -> (F', g) -> v`` (started at the commanded reactions)
contracts by ``O(c / L)`` per step; :data:`EXACT_STEPS` steps are taken. Taking
the reactions at the commanded pose instead errs by ``O(c (c / L)^2)`` in the
pose, ~1e-6 relative for clearances of 0.05 mm on 100 mm robots, and picks
the zero-reaction blocks' sides at random. Legs unloaded at the commanded pose
stay at zero.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import linprog

from .._display import html_table, summary, value_range
from ..errors import ConfigError
from ..io.resolve import clearances_arg, robot_arg
from ..kinematics import as_poses, inverse_kinematics, leg_states, regular_mask
from ..kinematics.workspace import constant_orientation_workspace
from ..model import plausibility
from ..model.manipulator import Manipulator
from ..model.sources import ErrorSources, JointErrors, block_centre, first_order_error, worst_configuration
from ..numerics.interval import Iv, t_parts, v_cv
from ..numerics.screws import cross, dot
from ..errors import EmptyWorkspaceError
from ..kinematics import DEFAULT_MAX_CONDITION
from . import maps as _maps
from .bounds import bounds_or_nan, max_pose_errors
from .nonlinear import _closure_residual, closure_state
from .global_worst import Region, SingularRegionError, _check_regular, leg_branches
from .interval import leg_box_state
from .regions import OUTSIDE, Disc, Polygon, Rect
from . import spatial_loads as _spatial
from ..model.plausibility import check_angle_values, rotation_angles
from ..model.spatial import is_spatial

#: Standard gravity (m/s^2): a mass in kg weighs ``G0 * mass`` N.
G0 = 9.80665
#: Default threshold (N) below which a leg's wrench intensity counts as no load.
DEFAULT_THRESHOLD_N = 1e-6
#: Fixed-point steps of the exact loaded pose (reactions recomputed at the displaced configuration).
EXACT_STEPS = 3
#: Forces above this (N) on a planar precision robot look like kN typed as N (a plausibility warning).
PLAUSIBLE_FORCE_N = plausibility.MAX_FORCE_N


@dataclass(frozen=True)
class Load:
    """A load on the platform: a wrench and optionally the platform's weight.

    Attributes
    ----------
    fx, fy : N, base frame;  m : N mm, about the platform centre ``P`` (counter-clockwise positive)
    mass : kg (0: no gravity);  com : ``(2,)`` mm, the centre of mass in the platform frame
    gravity_deg : direction of gravity in the base plane, deg from the base x-axis (-90: along -y)

    >>> Load(fx=10.0).wrench(np.array([0.0, 0.0, 0.0])).tolist()
    [10.0, 0.0, 0.0]
    >>> Load(mass=1.0, com=(10.0, 0.0)).wrench(np.array([0.0, 0.0, 0.0])).round(4).tolist()
    [0.0, -9.8066, -98.0665]
    """

    fx: float = 0.0
    fy: float = 0.0
    m: float = 0.0
    mass: float = 0.0
    com: tuple[float, float] = (0.0, 0.0)
    gravity_deg: float = -90.0

    def __post_init__(self) -> None:
        for key in ("fx", "fy", "m", "mass", "gravity_deg"):
            if not math.isfinite(getattr(self, key)):
                raise ConfigError(f"must be finite, got {getattr(self, key)}", key=key)
        if self.mass < 0:
            raise ConfigError(f"a mass cannot be negative, got {self.mass} kg", key="mass")
        if len(self.com) != 2 or not all(math.isfinite(c) for c in self.com):
            raise ConfigError(f"expected two finite values (mm), got {self.com}", key="com")

    def wrench(self, poses: np.ndarray) -> np.ndarray:
        """``(..., 3)`` [fx N, fy N, m N mm about P] at poses ``(..., 3)``: the given wrench plus the weight
        ``G0 mass`` along the gravity direction, applied at the centre of mass ``P + Rot(phi) com``."""
        poses = np.asarray(poses, dtype=float)
        weight = G0 * self.mass * np.exp(1j * math.radians(self.gravity_deg))
        arm = np.exp(1j * poses[..., 2]) * complex(*self.com)
        fx = np.full(poses.shape[:-1], self.fx) + weight.real
        fy = np.full(poses.shape[:-1], self.fy) + weight.imag
        m = self.m + cross(arm, weight)
        return np.stack([fx, fy, np.broadcast_to(m, fx.shape)], axis=-1)

    def check(self, what: str = "load", length_mm: float | None = None) -> "Load":
        """Warn (:class:`~pmaccuracy.model.plausibility.PlausibilityWarning`) for forces (and, given the robot's
        size ``length_mm``, moments) that look like kN typed as N
        (:func:`~pmaccuracy.model.plausibility.force_messages`); returns ``self``."""
        plausibility.warn(plausibility.force_messages(
            {f"{what}: force": math.hypot(self.fx, self.fy), f"{what}: weight": G0 * self.mass},
            {f"{what}: moment": self.m}, length_mm))
        return self


@dataclass(frozen=True)
class Statics:
    """Leg wrenches, actuator efforts and joint reactions at a batch of poses (:func:`statics`).

    Attributes (leading shape ``(...)`` of the poses)
    -------------------------------------------------
    poses : ``(..., 3)`` [mm, mm, rad];  wrench : ``(..., 3)`` [N, N, N mm], the external load on the platform
    intensity : ``(..., 3)`` N: ``lambda_i``, each leg's wrench ``lambda_i zeta_i`` on the platform
    actuator : ``(..., 3)``: ``tau_i = lambda_i B_ii``, N for a P actuator, N mm for an R one
    force : ``(..., 3 legs, 3 joints)`` complex N: the force each joint transmits (``lambda_i f_i``)
    normal : ``(..., 3, 3)`` N: a P joint's force normal to its rail (0 for R joints)
    moment : ``(..., 3, 3)`` N mm: a P joint's moment about its block's centre (0 for R joints)
    """

    poses: np.ndarray
    wrench: np.ndarray
    intensity: np.ndarray
    actuator: np.ndarray
    force: np.ndarray
    normal: np.ndarray
    moment: np.ndarray

    def contact_forces(self, block_length: float | np.ndarray) -> np.ndarray:
        """``(..., 3, 3, 2)`` N: the two end contact forces ``N / 2 -+ M / L`` of each P joint's block of length
        ``L`` (mm; a scalar or ``(3, 3)``), normal to the rail; zero for R joints."""
        L = np.asarray(block_length, dtype=float)
        return np.stack([self.normal / 2 - self.moment / L, self.normal / 2 + self.moment / L], axis=-1)

    def __repr__(self) -> str:
        return summary("Statics", int(np.prod(self.poses.shape[:-1])), [
            f"leg intensity {value_range(np.abs(self.intensity), 'N')}",
            f"actuators {value_range(np.abs(self.actuator), 'N or N mm')}"])


def statics(robot: Manipulator | str, poses, load: Load) -> Statics:
    """Leg wrench intensities, actuator efforts and joint reactions under ``load`` at ``poses`` ``(..., 3)``
    (module docstring: ``A^T lambda = -W``, ``tau = lambda B``).

    Poses outside the joint ranges or near a singularity are refused like
    :func:`~pmaccuracy.accuracy.bounds.max_pose_errors` (:class:`~pmaccuracy.errors.OutsideJointLimitsError`,
    :class:`~pmaccuracy.errors.SingularPoseError`): the statics is undefined at a singularity.

    >>> st = statics("symmetric_3rpr", [0.0, 0.0, 0.0], Load(fx=3.0))
    >>> bool(np.allclose(np.einsum("ij,i->j", wrench_rows("symmetric_3rpr", [0.0, 0.0, 0.0]), st.intensity), [-3, 0, 0]))
    True

    A spatial robot (:class:`~pmaccuracy.model.spatial.SpatialManipulator`) takes poses ``(..., 6)`` and a
    :class:`~pmaccuracy.accuracy.spatial_loads.SpatialLoad`: :func:`pmaccuracy.accuracy.spatial_loads.spatial_statics`.
    """
    robot = robot_arg(robot)
    if is_spatial(robot):
        check_angle_values(rotation_angles(poses), "poses[..., 3:] (rotation vectors)")
        return _spatial.spatial_statics(robot, poses, load)
    plausibility.check_orientations(poses, "poses", poses=True)
    poses = as_poses(poses)
    if not isinstance(load, Load):
        raise ConfigError(f"expected a Load, got {type(load).__name__}", key="load")
    _check_poses(robot, poses)
    return _statics(robot, poses, load)


def _statics(robot: Manipulator, poses: np.ndarray, load: Load) -> Statics:
    """:func:`statics` of poses already checked."""
    W = load.wrench(poses)
    states = leg_states(robot, poses)
    A = _rows(states, poses.shape[:-1])
    lam = -np.linalg.solve(np.swapaxes(A, -1, -2), W[..., None])[..., 0]
    shape = poses.shape[:-1]
    actuator = np.stack([lam[..., i] * np.broadcast_to(st.B, shape) for i, st in enumerate(states)], axis=-1)
    force = np.zeros(shape + (3, 3), dtype=complex)
    normal = np.zeros(shape + (3, 3))
    moment = np.zeros(shape + (3, 3))
    pz = poses[..., 0] + 1j * poses[..., 1]
    for i, (chain, st) in enumerate(zip(robot.chains, states)):
        li = lam[..., i]
        for k, joint in enumerate(chain.joints):
            force[..., i, k] = li * st.f
            if joint.kind == "P":
                normal[..., i, k] = li * dot(st.f, 1j * st.dirs[k])
                moment[..., i, k] = li * (st.m_P + cross(pz - block_centre(joint, st, k), st.f))
    return Statics(poses=poses, wrench=W, intensity=lam, actuator=actuator, force=force, normal=normal,
                   moment=moment)


def wrench_rows(robot: Manipulator | str, poses) -> np.ndarray:
    """``A`` ``(..., 3, 3)``: the legs' unit constraint wrenches ``[f_x, f_y, m_P]`` as rows (Eq. 4a in general
    form; :attr:`pmaccuracy.model.chain.LegState.A_row`)."""
    robot = robot_arg(robot)
    poses = as_poses(poses)
    return _rows(leg_states(robot, poses), poses.shape[:-1])


def _rows(states: tuple, shape: tuple) -> np.ndarray:
    """``A`` ``(*shape, 3, 3)`` from the legs' states."""
    return np.stack([np.broadcast_to(st.A_row, shape + (3,)) for st in states], axis=-2)


def _check_poses(robot: Manipulator, poses: np.ndarray) -> None:
    """Refuse poses outside the joint ranges or near a singularity (the checks of max_pose_errors)."""
    max_pose_errors(robot, ErrorSources(legs=tuple((JointErrors(),) * 3 for _ in range(3)), name="none"), poses)


@dataclass(frozen=True)
class LoadedError:
    """The pose error under a load (:func:`loaded_pose_error`), arrays with the poses' leading shape.

    Attributes
    ----------
    statics : the :class:`Statics` behind it
    first_order : ``(..., 3)`` [mm, mm, rad]: ``A^-1 diag(c) t`` with ``t = -sign(lambda)``
    exact : ``(..., 3)`` [mm, mm, rad]: the exact equilibrium, the loops closed with every pin against its
        bore along the reactions of the displaced configuration (module docstring; NaN without ``exact``)
    signs : ``(..., 3)``: ``t``, each leg's contact side (0 where the leg is unloaded)
    unloaded : ``(..., 3)`` bool: legs with ``|lambda_i| <= threshold``
    spread : ``(..., 3)`` [mm, mm, rad]: half-width of the range the unloaded legs still span around
        ``first_order`` (``sum over unloaded i of c_i |A^-1[:, i]|``; 0 when every leg is loaded)
    configuration : the source values of the first-order error
        (:class:`~pmaccuracy.model.sources.JointDisplacements`, the commanded reactions' sides)
    exact_configuration : the source values at the exact equilibrium (pins along the reactions of the
        displaced configuration: module docstring); None without ``exact``
    """

    statics: Statics
    first_order: np.ndarray
    exact: np.ndarray
    signs: np.ndarray
    unloaded: np.ndarray
    spread: np.ndarray
    configuration: object
    exact_configuration: object = None

    def records(self) -> list[dict]:
        """One dict per pose (mm, deg, N), the command line's columns; ``*_spread``: the half-width of the range
        the unloaded legs leave (0 when every leg is loaded)."""
        poses = self.statics.poses.reshape(-1, 3)
        fo = self.first_order.reshape(-1, 3)
        ex = self.exact.reshape(-1, 3)
        lam = self.statics.intensity.reshape(-1, 3)
        un = self.unloaded.reshape(-1, 3)
        sp = self.spread.reshape(-1, 3)
        out = []
        for k in range(poses.shape[0]):
            out.append({"x": float(poses[k, 0]), "y": float(poses[k, 1]), "phi_deg": math.degrees(poses[k, 2]),
                        "dx": float(fo[k, 0]), "dy": float(fo[k, 1]), "dphi_deg": math.degrees(fo[k, 2]),
                        "dx_exact": float(ex[k, 0]), "dy_exact": float(ex[k, 1]),
                        "dphi_deg_exact": math.degrees(ex[k, 2]),
                        **{f"lambda{i + 1}_N": float(lam[k, i]) for i in range(3)},
                        "unloaded_legs": ",".join(str(i + 1) for i in range(3) if un[k, i]) or "-",
                        "dx_spread": float(sp[k, 0]), "dy_spread": float(sp[k, 1]),
                        "dphi_deg_spread": math.degrees(sp[k, 2])})
        return out

    def __repr__(self) -> str:
        return summary("LoadedError", int(np.prod(self.first_order.shape[:-1])), [
            f"dx {value_range(self.first_order[..., 0], 'mm')}", f"dy {value_range(self.first_order[..., 1], 'mm')}",
            f"dphi {value_range(np.degrees(self.first_order[..., 2]), 'deg')}",
            f"{int(np.sum(self.unloaded))} unloaded legs"])

    def _repr_html_(self) -> str:
        return html_table("Loaded pose error (mm, deg, N)", self.records())


def loaded_pose_error(robot: Manipulator | str, clearances, poses, load: Load, *,
                      threshold: float = DEFAULT_THRESHOLD_N, exact: bool = True) -> LoadedError:
    """The pose error that ``load`` produces at ``poses`` ``(..., 3)`` with the clearances taken up along the
    joints' reactions (module docstring), first order and (with ``exact``) on the exact loop closure.

    Every source of ``clearances`` follows the load here, tolerances included (``position``, ``direction``,
    ``length`` and the polar keys go to the extreme the reactions select, like the clearances): right for a
    clearance file; with tolerances in the file the result is their worst state aligned with the load, a bound
    rather than a prediction (a load does not move a manufacturing error). Give the clearances alone and take
    the tolerances' worst case from :func:`~pmaccuracy.accuracy.bounds.max_pose_errors`.

    A spatial robot takes poses ``(..., 6)``, its error sources and a
    :class:`~pmaccuracy.accuracy.spatial_loads.SpatialLoad`
    (:func:`pmaccuracy.accuracy.spatial_loads.spatial_loaded_error`; ``exact`` does not apply: first order).
    It keeps the tolerances apart: only the clearances follow the load, the tolerances' worst case is given
    beside it (:attr:`~pmaccuracy.accuracy.spatial_loads.SpatialLoadedError.tolerance`).

    Parameters
    ----------
    robot, clearances : objects, preset names or paths (any architecture; the 3-PPR clearance format too)
    poses : ``(..., 3)`` [x mm, y mm, phi rad];  load : a :class:`Load`
    threshold : N; a leg with ``|lambda_i| <= threshold`` is unloaded (its state undetermined: see ``spread``)

    >>> r = loaded_pose_error("aalborg_3ppr", "case1", [0.0, 0.0, 0.0], Load(fx=5.0))
    >>> b = max_pose_errors("aalborg_3ppr", "case1", [0.0, 0.0, 0.0])
    >>> bool(np.isclose(r.first_order[0], b.dx_max))     # a push along +x reaches +dx_max
    True
    """
    robot = robot_arg(robot)
    if is_spatial(robot):
        check_angle_values(rotation_angles(poses), "poses[..., 3:] (rotation vectors)")
        return _spatial.spatial_loaded_error(robot, clearances, poses, load, threshold=threshold)
    plausibility.check_orientations(poses, "poses", poses=True)
    clearances = clearances_arg(clearances, robot)
    sources = clearances.check(robot) if isinstance(clearances, ErrorSources) else \
        ErrorSources.from_clearance_set(clearances)
    if not (math.isfinite(threshold) and threshold >= 0):
        raise ConfigError(f"must be finite and >= 0 (N), got {threshold}", key="threshold")
    poses = as_poses(poses)
    if not isinstance(load, Load):
        raise ConfigError(f"expected a Load, got {type(load).__name__}", key="load")
    b = max_pose_errors(robot, sources, poses, details=True)     # refuses poses outside the ranges or singular
    st = _statics(robot, poses, load)
    unloaded = np.abs(st.intensity) <= threshold
    signs = np.where(unloaded, 0.0, -np.sign(st.intensity))
    joints = inverse_kinematics(robot, poses).joints
    config = worst_configuration(robot, sources, joints, poses, signs)
    first = first_order_error(robot, joints, poses, config)
    spread = np.einsum("...ij,...j->...i", np.abs(b.generators), unloaded.astype(float))
    if exact:
        ex, exact_config = _equilibrium(robot, sources, poses, load, config, st, signs)
        plausibility.warn(plausibility.loaded_error_messages(first, ex, poses, robot.characteristic_length))
    else:
        ex, exact_config = np.full(first.shape, np.nan), None
    return LoadedError(statics=st, first_order=first, exact=ex, signs=signs, unloaded=unloaded, spread=spread,
                       configuration=config, exact_configuration=exact_config)


def _equilibrium(robot: Manipulator, sources: ErrorSources, poses: np.ndarray, load: Load, config, st: Statics,
                 signs: np.ndarray, steps: int = EXACT_STEPS):
    """The exact loaded pose error ``(..., 3)`` [mm, mm, rad] and its configuration: the self-consistent
    equilibrium of the module docstring, ``steps`` fixed-point steps from ``config`` (the commanded reactions'
    sides ``signs`` ``(..., 3)``; ``st`` their :class:`Statics`)."""
    c = np.array([[e.radial + e.position for e in leg] for leg in sources.legs])          # (3, 3) mm
    force = st.force[..., 0]                                                                # (..., 3) complex N
    loaded = signs != 0
    along = np.where(loaded, -force / np.where(loaded, np.abs(force), 1.0), 0.0)           # t_i f_i / |f_i|
    base = config.shift - c * along[..., None]              # the shifts that do not follow the reaction (tolerances)
    q_act = inverse_kinematics(robot, poses).q
    z = None
    for step in range(steps + 1):
        z, J = closure_state(robot, poses, config, start=z, with_jacobian=step < steps)
        if step == steps:
            break
        rhs = np.zeros(z.shape)
        rhs[..., :3] = load.wrench(z[..., :3])
        mu = np.linalg.solve(np.swapaxes(J, -1, -2), rhs[..., None])[..., 0]
        F = mu[..., 0::3] + 1j * mu[..., 1::3]              # (..., 3) N: each leg's force, displaced configuration
        u = np.where(loaded, -F / np.where(loaded, np.abs(F), 1.0), 0.0)
        config = _vertex_sides(robot, sources, z, q_act, replace(config, shift=base + c * u[..., None]), mu, loaded)
    ex = z[..., :3] - poses
    ex[..., 2] = np.angle(np.exp(1j * ex[..., 2]))
    return ex, config


def _vertex_sides(robot: Manipulator, sources: ErrorSources, z: np.ndarray, q_act: np.ndarray, config,
                  mu: np.ndarray, loaded: np.ndarray):
    """``config`` with every actuator backlash, block tilt and rhombus vertex of the loaded legs (``loaded``
    ``(..., 3)``) on the side of its gradient ``g = -(dr/dv)^T mu`` at the closed loops ``z`` ``(..., 9)``
    (module docstring; ``dr/dv`` by central differences of the residual, step 1e-7 mm or rad)."""
    sgn = lambda x: np.where(x < 0, -1.0, 1.0)  # noqa: E731
    h = 1e-7
    new = {key: getattr(config, key).copy() for key in ("sigma", "tau", "tilt", "dq")}

    def gradient(key: str, i: int, k: int) -> np.ndarray:
        step = np.zeros((3, 3))
        step[i, k] = h
        plus = _closure_residual(robot, z, q_act, replace(config, **{key: getattr(config, key) + step}))
        minus = _closure_residual(robot, z, q_act, replace(config, **{key: getattr(config, key) - step}))
        return -np.sum((plus - minus) / (2 * h) * mu, axis=-1)

    for i, leg in enumerate(sources.legs):
        on = loaded[..., i]
        for k, e in enumerate(leg):
            if e.actuator:
                new["dq"][..., i, k] = np.where(on, e.actuator * sgn(gradient("dq", i, k)), new["dq"][..., i, k])
            if e.angular or e.lateral:
                g_tilt = gradient("tilt", i, k)
                if e.angular:
                    new["tilt"][..., i, k] = np.where(on, e.angular * sgn(g_tilt), new["tilt"][..., i, k])
                if e.lateral:
                    g_sigma = gradient("sigma", i, k)
                    shift_wins = np.abs(g_sigma) >= 2 * np.abs(g_tilt) / e.block_length
                    new["sigma"][..., i, k] = np.where(on, np.where(shift_wins, e.lateral * sgn(g_sigma), 0.0),
                                                       new["sigma"][..., i, k])
                    new["tau"][..., i, k] = np.where(on, np.where(shift_wins, 0.0, 2 * e.lateral / e.block_length
                                                                  * sgn(g_tilt)), new["tau"][..., i, k])
    return replace(config, **new)


# ----------------------------------------------------------------------------- wrench sets and preload
def _intensity_map(robot: Manipulator, poses: np.ndarray) -> np.ndarray:
    """``L`` ``(n, 3, 3)`` with ``lambda = L W`` (``L = -A^{-T}``, module docstring), N per N (or per N mm)."""
    A = wrench_rows(robot, poses)
    return -np.linalg.inv(np.swapaxes(A, -1, -2))


def _box(center, half) -> tuple[np.ndarray, np.ndarray]:
    try:
        c = np.asarray(center, dtype=float).reshape(3)
        h = np.asarray(half, dtype=float).reshape(3)
    except (TypeError, ValueError):
        raise ConfigError(f"a wrench box needs a centre and half-widths of three numbers each [N, N, N mm], got "
                          f"{center!r}, {half!r}", key="wrench_set") from None
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(h)) and np.all(h >= 0)):
        raise ConfigError(f"a wrench box needs a finite centre and half-widths >= 0 [N, N, N mm], got {c}, {h}",
                          key="wrench_set")
    return c, h


#: The eight contact patterns ``s`` (the signs of the legs' intensities).
_PATTERNS = np.array([[a, b, c] for a in (1.0, -1.0) for b in (1.0, -1.0) for c in (1.0, -1.0)])


@dataclass(frozen=True)
class WrenchSetErrors:
    """The loaded pose error over a box of process wrenches at a batch of poses (:func:`wrench_set_errors`).

    Attributes
    ----------
    poses : ``(n, 3)``;  center, half : ``(3,)`` the box ``center +- half`` [N, N, N mm]
    patterns : ``(n, 8)`` bool: which contact patterns ``s`` (rows of ``_PATTERNS``, the signs of the legs'
        intensities) are possible: some wrench of the box loads every leg on its side of ``s`` or leaves it
        unloaded (``|lambda_i| <= threshold``, its state undetermined)
    lower, upper : ``(n, 3)`` [mm, mm, rad]: the range of the first-order loaded error over the box
    flips : ``(n, 3)`` bool: legs with both sides possible inside the box (the error jumps there)
    """

    poses: np.ndarray
    center: np.ndarray
    half: np.ndarray
    patterns: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    flips: np.ndarray


def wrench_set_errors(robot: Manipulator | str, clearances, poses, center, half, *,
                      threshold: float = DEFAULT_THRESHOLD_N) -> WrenchSetErrors:
    """Range of the loaded pose error when the process wrench may be anywhere in the box ``center +- half``
    ([fx N, fy N, m N mm]), and the legs whose contact flips inside it.

    ``lambda = L W`` is linear. A contact pattern ``s`` is possible when some wrench of the box loads every leg
    on its side or leaves it unloaded (``s_i L_i W >= -threshold``: an unloaded leg's state is undetermined, so
    both its sides count); :func:`_reached_patterns` decides it for every pose and pattern at once from the
    vertices of the pattern's polytope of wrenches. The loaded error of pattern ``s`` is
    ``A^{-1} diag(c) (-s)`` (module docstring) and the range is taken over the possible patterns: the exact
    range of the loaded error over the box (the error set at one wrench is the convex hull of its possible
    patterns). A leg flips when both its sides are possible (its intensity's range over the box reaches zero).

    A spatial robot takes poses ``(..., 6)`` and a box of six-component wrenches
    (:func:`pmaccuracy.accuracy.spatial_loads.spatial_wrench_set_errors`: a guaranteed enclosure and the range
    attained at the box's centre and corners, since its discs and balls turn continuously with the wrench).
    """
    robot = robot_arg(robot)
    if is_spatial(robot):
        check_angle_values(rotation_angles(poses), "poses[..., 3:] (rotation vectors)")
        return _spatial.spatial_wrench_set_errors(robot, clearances, poses, center, half, threshold=threshold)
    plausibility.check_orientations(poses, "poses", poses=True)
    c, h = _box(center, half)
    if not (math.isfinite(threshold) and threshold >= 0):
        raise ConfigError(f"must be finite and >= 0 (N), got {threshold}", key="threshold")
    poses = as_poses(poses).reshape(-1, 3)
    b = max_pose_errors(robot, clearances, poses, details=True)     # refuses poses outside the ranges or singular
    reached = _reached_patterns(_intensity_map(robot, poses), c, h, threshold)
    errors = np.einsum("nij,kj->nki", b.generators, -_PATTERNS)          # (n, 8, 3): A^-1 diag(c) t
    masked = np.where(reached[..., None], errors, np.nan)
    lower, upper = np.nanmin(masked, axis=1), np.nanmax(masked, axis=1)
    signs = np.where(reached[..., None], _PATTERNS[None], np.nan)
    flips = np.nanmin(signs, axis=1) != np.nanmax(signs, axis=1)
    return WrenchSetErrors(poses=poses, center=c, half=h, patterns=reached, lower=lower, upper=upper, flips=flips)


@dataclass(frozen=True)
class Preload:
    """The smallest constant platform wrench that keeps every contact fixed over a box of process wrenches at
    one pose (:func:`design_preload`).

    Attributes
    ----------
    wrench : ``(3,)`` [fx N, fy N, m N mm]: the preload, added to every process wrench
    size : its size ``max(|fx|, |fy|, |m| / L)`` (N) with ``L`` the robot's characteristic length (mm)
    pattern : ``(3,)`` the legs' intensity signs it holds for every process wrench
    offset : ``(3,)`` [mm, mm, rad]: the then constant first-order pose error (calibration removes it)
    worst : ``(3,)`` [mm, mm, rad]: the unloaded worst case (dx_max, dy_max, dphi_max) beside it
    """

    wrench: np.ndarray
    size: float
    pattern: np.ndarray
    offset: np.ndarray
    worst: np.ndarray


def design_preload(robot: Manipulator | str, clearances, pose, center, half, *,
                   margin: float = DEFAULT_THRESHOLD_N) -> Preload:
    """The smallest preload ``P`` (a constant wrench on the platform, size ``max(|P_x|, |P_y|, |P_m| / L)``) such
    that every leg's intensity keeps its sign, with at least ``margin`` N, for every process wrench of the box
    ``center +- half``: for a pattern ``s`` the linear program ``min z`` subject to ``s_i L_i (P + W) >= margin for all
    W in the box`` (``s_i L_i P >= margin - s_i L_i center + sum_j |L_ij| half_j``, ``|P_j| / scale_j <= z``;
    scipy HiGHS), the best of the eight patterns.

    A spatial robot takes a pose ``(6,)`` and a box of six-component wrenches
    (:func:`pmaccuracy.accuracy.spatial_loads.spatial_design_preload`).
    """
    robot = robot_arg(robot)
    if is_spatial(robot):
        check_angle_values(rotation_angles(pose), "pose[3:] (rotation vector)")
        return _spatial.spatial_design_preload(robot, clearances, pose, center, half, margin=margin)
    plausibility.check_orientations(pose, "pose", poses=True)
    c, h = _box(center, half)
    if not (np.any(c) or np.any(h)):
        raise ConfigError("the box of process wrenches is the zero wrench alone: no load to hold a contact "
                          "against (give a range)", key="half")
    pose = as_poses(pose).reshape(1, 3)
    b = max_pose_errors(robot, clearances, pose, details=True)      # refuses a pose outside the ranges or singular
    L = _intensity_map(robot, pose)[0]
    scale = np.array([1.0, 1.0, robot.characteristic_length])
    best = None
    for s in _PATTERNS:
        rhs = margin - s * (L @ c) + np.abs(L) @ h
        # variables (P, z): minimize z; -s_i L_i P <= -rhs_i; +-P_j / scale_j - z <= 0
        A_ub = np.vstack([np.column_stack([-(s[:, None] * L), np.zeros(3)]),
                          np.column_stack([np.diag(1 / scale), -np.ones(3)]),
                          np.column_stack([-np.diag(1 / scale), -np.ones(3)])])
        b_ub = np.concatenate([-rhs, np.zeros(6)])
        res = linprog(np.array([0.0, 0.0, 0.0, 1.0]), A_ub=A_ub, b_ub=b_ub, bounds=[(None, None)] * 4,
                      method="highs")
        if res.status == 0 and (best is None or res.fun < best[0]):
            best = (res.fun, res.x[:3], s)
    if best is None:    # cannot happen for a regular pose (A invertible): any pattern is reachable
        raise ConfigError("no preload keeps the contacts fixed", key="preload")
    offset = b.generators[0] @ (-best[2])
    worst = np.array([float(b.dx_max[0]), float(b.dy_max[0]), float(b.dphi_max[0])])
    return Preload(wrench=best[1], size=float(best[0]), pattern=best[2], offset=offset, worst=worst)


# ----------------------------------------------------------------------------- maps over the workspace
#: Variables of a loaded error map (:func:`loaded_error_map`): name -> (units, long name).
LOADED_MAP_VARIABLES = {
    "dx": ("mm", "first-order loaded position error along x"),
    "dy": ("mm", "first-order loaded position error along y"),
    "dphi": ("deg", "first-order loaded orientation error"),
    "dp": ("mm", "magnitude of the first-order loaded position error"),
    "dx_spread": ("mm", "half-width of the x range the unloaded legs leave"),
    "dy_spread": ("mm", "half-width of the y range the unloaded legs leave"),
    "dphi_spread": ("deg", "half-width of the orientation range the unloaded legs leave"),
    "lambda1": ("N", "wrench intensity of leg 1"),
    "lambda2": ("N", "wrench intensity of leg 2"),
    "lambda3": ("N", "wrench intensity of leg 3"),
    "unloaded_legs": ("1", "number of legs with |lambda_i| <= threshold (state undetermined)"),
}
#: Variables of a wrench-set map (:func:`wrench_set_map`): name -> (units, long name).
WRENCH_SET_MAP_VARIABLES = {
    "dx_lo": ("mm", "lowest first-order loaded x error over the wrench box"),
    "dx_hi": ("mm", "highest first-order loaded x error over the wrench box"),
    "dy_lo": ("mm", "lowest first-order loaded y error over the wrench box"),
    "dy_hi": ("mm", "highest first-order loaded y error over the wrench box"),
    "dphi_lo": ("deg", "lowest first-order loaded orientation error over the wrench box"),
    "dphi_hi": ("deg", "highest first-order loaded orientation error over the wrench box"),
    "flip1": ("1", "1 where leg 1's contact flips (or is unloaded) for some wrench of the box"),
    "flip2": ("1", "1 where leg 2's contact flips (or is unloaded) for some wrench of the box"),
    "flip3": ("1", "1 where leg 3's contact flips (or is unloaded) for some wrench of the box"),
    "flipping_legs": ("1", "number of legs whose contact flips inside the wrench box (the error jumps there)"),
}


def _map_poses(robot, clearances, phis, n: int, region, max_condition: float):
    """Grid poses ``(k, ny, nx, 3)`` of a map (the grid of :func:`pmaccuracy.accuracy.maps.error_map`) and the
    mask of those inside the workspace (joint ranges), away from singularities and inside ``region``."""
    robot, clearances, phis, x, y = _maps._prepare(robot, clearances, phis, n, max_condition)
    sources = clearances.check(robot) if isinstance(clearances, ErrorSources) else \
        ErrorSources.from_clearance_set(clearances)
    if region is not None:
        if not isinstance(region, (Disc, Polygon, Rect)):
            raise ConfigError(f"expected a Disc, Polygon or Rect of pmaccuracy.accuracy.regions, got {region!r}",
                              key="region")
        x, y = _maps._cut(region, x, y, n)
    X, Y = np.meshgrid(x, y)
    poses = np.stack(np.broadcast_arrays(X[None], Y[None], phis[:, None, None]), axis=-1)
    ok = np.isfinite(bounds_or_nan(robot, sources, poses.reshape(-1, 3), max_condition)[:, 0]).reshape(
        poses.shape[:-1])
    if region is not None:
        ok &= region.contains(X, Y)[None]
    for k, phi in enumerate(phis):
        if not ok[k].any():
            raise EmptyWorkspaceError(f"no point of the {n} x {n} grid lies inside the workspace"
                                      + (f" and {region.describe()}" if region is not None else "")
                                      + f" at phi = {np.degrees(phi):g} deg: use a finer grid")
    return robot, clearances, sources, phis, x, y, poses, ok


def _dataset(values: dict, variables: dict, phis, x, y, attrs: dict):
    data_vars = {name: (("phi", "y", "x"), values[name], {"units": u, "long_name": ln})
                 for name, (u, ln) in variables.items() if name in values}
    return _maps.map_dataset(data_vars, phis, x, y, attrs)


def _describe_load(load: Load) -> str:
    text = f"fx = {load.fx:g} N, fy = {load.fy:g} N, m = {load.m:g} N mm about the platform centre (base frame)"
    if load.mass:
        text += (f", weight of {load.mass:g} kg at ({load.com[0]:g}, {load.com[1]:g}) mm (platform frame), gravity "
                 f"along {load.gravity_deg:g} deg")
    return text


def loaded_error_map(robot: Manipulator | str, clearances, load: Load, phis, n: int = 41, *,
                     threshold: float = DEFAULT_THRESHOLD_N, exact: bool = False, region=None,
                     max_condition: float = DEFAULT_MAX_CONDITION):
    """The loaded pose error (:func:`loaded_pose_error`) under one ``load`` over the workspace, as a map.

    Same grid, dims ``(phi, y, x)`` and coordinates as :func:`pmaccuracy.accuracy.maps.error_map` (``x, y`` mm,
    ``phi`` deg; ``region``: a Disc, Polygon or Rect cuts the grid to its bounding box), NaN outside the
    workspace, near singularities and outside the region. Variables (:data:`LOADED_MAP_VARIABLES`): the
    first-order loaded error ``dx, dy`` (mm), ``dphi`` (deg), ``dp = |(dx, dy)|`` (mm); with ``exact`` also
    ``dx_exact, dy_exact, dphi_exact`` on the exact loop closure; ``*_spread`` the half-width of the range the
    unloaded legs leave; ``lambda1..3`` (N) the legs' intensities and ``unloaded_legs`` their count.
    Vectorized over the grid's poses.

    >>> ds = loaded_error_map("aalborg_3ppr", "case1", Load(fx=5.0), 0.0, n=5)
    >>> b = max_pose_errors("aalborg_3ppr", "case1", [0.0, 0.0, 0.0])
    >>> bool(np.isclose(float(ds.dx.sel(x=0.0, y=0.0, method="nearest").max()), b.dx_max))
    True
    """
    if not isinstance(load, Load):
        raise ConfigError(f"expected a Load, got {type(load).__name__}", key="load")
    if not (math.isfinite(threshold) and threshold >= 0):
        raise ConfigError(f"must be finite and >= 0 (N), got {threshold}", key="threshold")
    plausibility.check_orientations(phis, "phis")
    robot, clearances, sources, phis, x, y, poses, ok = _map_poses(robot, clearances, phis, n, region, max_condition)
    res = loaded_pose_error(robot, sources, poses[ok], load, threshold=threshold, exact=exact)
    cols = {"dx": res.first_order[:, 0], "dy": res.first_order[:, 1], "dphi": np.degrees(res.first_order[:, 2]),
            "dp": np.hypot(res.first_order[:, 0], res.first_order[:, 1]),
            "dx_spread": res.spread[:, 0], "dy_spread": res.spread[:, 1], "dphi_spread": np.degrees(res.spread[:, 2]),
            **{f"lambda{i + 1}": res.statics.intensity[:, i] for i in range(3)},
            "unloaded_legs": np.sum(res.unloaded, axis=1).astype(float)}
    variables = dict(LOADED_MAP_VARIABLES)
    if exact:
        cols.update({"dx_exact": res.exact[:, 0], "dy_exact": res.exact[:, 1],
                     "dphi_exact": np.degrees(res.exact[:, 2])})
        variables.update({"dx_exact": ("mm", "loaded x error on the exact loop closure"),
                          "dy_exact": ("mm", "loaded y error on the exact loop closure"),
                          "dphi_exact": ("deg", "loaded orientation error on the exact loop closure")})
    values = {}
    for name, col in cols.items():
        values[name] = np.full(ok.shape, np.nan)
        values[name][ok] = col
    attrs = _maps._attrs(robot, clearances)
    attrs.update({"title": f"Loaded pose error of {robot.name} with clearances {clearances.name}",
                  "load": _describe_load(load), "threshold_N": f"{threshold:g}",
                  "method": "clearances taken up along the joints' reactions: the vertex of the error set maximizing "
                            "the load's virtual work (first order)" + ("; exact loop closure" if exact else "")})
    if region is not None:
        attrs["region"] = f"{region.describe()}: grid cut to its bounding box, NaN outside it"
    return _dataset(values, variables, phis, x, y, attrs)


#: The 84 triples of the nine constraint planes of :func:`_reached_patterns`.
_TRIPLES = np.array(list(itertools.combinations(range(9), 3)))
#: Poses per block of :func:`_reached_patterns` (its temporaries are about 150 kB per pose).
_PATTERN_BLOCK = 256


def _reached_patterns(L: np.ndarray, center: np.ndarray, half: np.ndarray, threshold: float) -> np.ndarray:
    """``(n, 8)`` bool: the contact patterns ``s`` (:data:`_PATTERNS`) compatible with some wrench of the box.

    Pattern ``s`` is compatible with ``W`` when every leg is loaded on its side or unloaded:
    ``s_i L_i W >= -threshold``. The set of such ``W`` in the box is a polytope (nine half-spaces in 3-D); it
    is non-empty iff it has a vertex, the intersection of three independent planes satisfying all nine: every
    triple is solved at once (vectorized over poses, patterns and triples).
    """
    n = L.shape[0]
    out = np.zeros((n, 8), dtype=bool)
    eye = np.eye(3)
    box_a = np.concatenate([eye, -eye])                               # (6, 3): a . W >= b
    box_b = np.concatenate([center - half, -(center + half)])
    for start in range(0, n, _PATTERN_BLOCK):
        Lb = L[start:start + _PATTERN_BLOCK]
        m = Lb.shape[0]
        a = np.empty((m, 8, 9, 3))
        a[:, :, :3] = _PATTERNS[None, :, :, None] * Lb[:, None]
        a[:, :, 3:] = box_a
        b = np.empty((m, 8, 9))
        b[:, :, :3] = -threshold
        b[:, :, 3:] = box_b
        M = a[:, :, _TRIPLES]                                          # (m, 8, 84, 3, 3)
        r = b[:, :, _TRIPLES]                                          # (m, 8, 84, 3)
        norms = np.prod(np.linalg.norm(M, axis=-1), axis=-1)
        det = np.linalg.det(M)
        good = np.abs(det) > 1e-12 * norms
        M = np.where(good[..., None, None], M, eye)
        W = np.linalg.solve(M, r[..., None])[..., 0]                  # (m, 8, 84, 3)
        slack = np.einsum("mpkj,mptj->mptk", a, W) - b[:, :, None]     # (m, 8, 84, 9)
        scale = np.einsum("mpkj,mptj->mptk", np.abs(a), np.abs(W)) + np.abs(b[:, :, None])
        feasible = np.all(slack >= -1e-9 * scale - 1e-300, axis=-1) & good
        out[start:start + m] = np.any(feasible, axis=-1)
    return out


def wrench_set_map(robot: Manipulator | str, clearances, center, half, phis, n: int = 41, *,
                   threshold: float = DEFAULT_THRESHOLD_N, region=None, max_condition: float = DEFAULT_MAX_CONDITION):
    """For process wrenches anywhere in the box ``center +- half`` ([fx N, fy N, m N mm]): the range of the
    first-order loaded error at each grid pose and where contacts flip, as a map (grid, dims and coordinates of
    :func:`pmaccuracy.accuracy.maps.error_map`; NaN outside the workspace, near singularities and outside
    ``region``).

    At a pose the legs' intensities are ``lambda = L W`` (``L = -A^{-T}``, module docstring). A contact pattern
    ``s`` (each leg's side) is possible when some wrench of the box loads every leg on its side or leaves it
    unloaded (``s_i lambda_i >= -threshold``: an unloaded leg's state is undetermined, so both of its sides
    count); its error is ``A^{-1} diag(c) (-s)``. The range ``*_lo, *_hi`` is taken over the possible
    patterns: it is the exact range of the loaded error over the box (the error set at one wrench is the
    convex hull of its possible patterns). ``flip1..3`` mark the legs with both sides possible (their
    intensity's range over the box, ``L_i c +- |L_i| h``, reaches zero) and ``flipping_legs`` counts them:
    where it is positive, the loaded error jumps inside the box. Variables: :data:`WRENCH_SET_MAP_VARIABLES`.
    Vectorized over the grid's poses (every pattern's polytope by its vertices).

    >>> ds = wrench_set_map("aalborg_3ppr", "case1", [0.0, 0.0, 0.0], [5.0, 5.0, 0.0], 0.0, n=5)
    >>> int(ds.flipping_legs.max())            # every force direction: every leg flips somewhere
    3
    """
    c, h = _box(center, half)
    if not (math.isfinite(threshold) and threshold >= 0):
        raise ConfigError(f"must be finite and >= 0 (N), got {threshold}", key="threshold")
    plausibility.check_orientations(phis, "phis")
    robot, clearances, sources, phis, x, y, poses, ok = _map_poses(robot, clearances, phis, n, region, max_condition)
    pts = poses[ok]
    reached = _reached_patterns(_intensity_map(robot, pts), c, h, threshold)
    G = max_pose_errors(robot, sources, pts, details=True, max_condition=max_condition).generators
    errors = np.einsum("nij,kj->nki", G, -_PATTERNS)                  # (n, 8, 3)
    masked = np.where(reached[..., None], errors, np.nan)
    lo, hi = np.nanmin(masked, axis=1), np.nanmax(masked, axis=1)
    signs = np.where(reached[..., None], _PATTERNS[None], np.nan)
    flips = np.nanmin(signs, axis=1) != np.nanmax(signs, axis=1)
    cols = {"dx_lo": lo[:, 0], "dx_hi": hi[:, 0], "dy_lo": lo[:, 1], "dy_hi": hi[:, 1],
            "dphi_lo": np.degrees(lo[:, 2]), "dphi_hi": np.degrees(hi[:, 2]),
            **{f"flip{i + 1}": flips[:, i].astype(float) for i in range(3)},
            "flipping_legs": np.sum(flips, axis=1).astype(float)}
    values = {}
    for name, col in cols.items():
        values[name] = np.full(ok.shape, np.nan)
        values[name][ok] = col
    attrs = _maps._attrs(robot, clearances)
    attrs.update({"title": f"Loaded pose error over a wrench box of {robot.name} with clearances {clearances.name}",
                  "wrench_box": f"fx {c[0] - h[0]:g} .. {c[0] + h[0]:g} N, fy {c[1] - h[1]:g} .. {c[1] + h[1]:g} N, "
                                f"m {c[2] - h[2]:g} .. {c[2] + h[2]:g} N mm (about the platform centre, base frame)",
                  "threshold_N": f"{threshold:g}",
                  "method": "range of the first-order loaded error over the contact patterns some wrench of the box "
                            "allows (vertex enumeration of each pattern's polytope of wrenches)"})
    if region is not None:
        attrs["region"] = f"{region.describe()}: grid cut to its bounding box, NaN outside it"
    return _dataset(values, WRENCH_SET_MAP_VARIABLES, phis, x, y, attrs)


# ----------------------------------------------------------------------------- preload over a region
@dataclass(frozen=True)
class RegionPreload:
    """The smallest constant platform wrench that keeps every contact fixed for every process wrench of a box at
    every pose of a region (:func:`design_region_preload`).

    Attributes
    ----------
    region : description of the region;  center, half : ``(3,)`` the process box [N, N, N mm]
    wrench : ``(3,)`` [fx N, fy N, m N mm]: the preload (a constant wrench on the platform, base frame)
    size : its size ``max(|fx|, |fy|, |m| / L)`` (N), the optimum of the linear program over the poses used:
        no smaller preload keeps the contacts fixed at those poses (a lower bound for the region)
    pattern : ``(3,)`` the legs' intensity signs it holds everywhere
    attaining : ``(3,)`` [mm, mm, rad]: the pose whose constraint binds (the region's hardest pose)
    per_pose_size : the size :func:`design_preload` needs at ``attaining`` alone (N): a preload adjusted pose
        by pose could be this small there; the constant one must serve the whole region
    min_intensity : the smallest ``s_i lambda_i`` (N) over the check poses and every wrench of the box with the
        preload (``>= margin`` when the design holds there)
    n_design, n_check : poses in the linear program, poses checked (grid, midpoints, local searches)
    offset_max : ``(3,)`` [mm, mm, rad]: the largest ``|offset|`` over the check poses; with the preload the loaded
        error at a pose is this constant offset ``A^{-1} diag(c) (-s)`` whatever the process wrench (range 0),
        which calibration removes
    worst_max : ``(3,)`` [mm, mm, rad]: the unloaded worst case (dx_max, dy_max, dphi_max) over the same poses
    range_without : ``(3,)`` [mm, mm, rad]: the largest range (hi - lo) of the loaded error over the process box
        without the preload, over the same poses (:func:`wrench_set_map`'s range)
    certified_wrench : ``(3,)`` a preload **proved** (:func:`certify_preload`) to keep every contact strictly on its
        side at every pose of the region for every wrench of the box (NaN when no proof was found)
    certified_size : its size (N): ``size <= smallest preload <= certified_size`` (NaN without a proof)
    certified_boxes : pose boxes the proofs evaluated
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
    range_without: np.ndarray
    certified_wrench: np.ndarray = None
    certified_size: float = float("nan")
    certified_boxes: int = 0

    def record(self) -> dict:
        """The command line's record (N, N mm, mm, deg)."""
        d = math.degrees
        return {"region": self.region, "pattern": ",".join("+" if v > 0 else "-" for v in self.pattern),
                "preload_fx_N": float(self.wrench[0]) + 0.0, "preload_fy_N": float(self.wrench[1]) + 0.0,
                "preload_m_Nmm": float(self.wrench[2]) + 0.0, "preload_size_N": self.size,
                "attaining_x": float(self.attaining[0]), "attaining_y": float(self.attaining[1]),
                "attaining_phi_deg": d(self.attaining[2]), "per_pose_size_N": self.per_pose_size,
                "min_intensity_N": self.min_intensity, "n_design": self.n_design, "n_check": self.n_check,
                "offset_dx_max": float(self.offset_max[0]), "offset_dy_max": float(self.offset_max[1]),
                "offset_dphi_deg_max": d(self.offset_max[2]),
                "dx_max": float(self.worst_max[0]), "dy_max": float(self.worst_max[1]),
                "dphi_deg_max": d(self.worst_max[2]),
                "dx_range_without": float(self.range_without[0]), "dy_range_without": float(self.range_without[1]),
                "dphi_deg_range_without": d(self.range_without[2]),
                "certified_size_N": self.certified_size if math.isfinite(self.certified_size) else None,
                "certified_fx_N": _plain(self.certified_wrench, 0), "certified_fy_N": _plain(self.certified_wrench, 1),
                "certified_m_Nmm": _plain(self.certified_wrench, 2), "certified_boxes": self.certified_boxes}

    def __repr__(self) -> str:
        return (f"RegionPreload({self.region}: preload ({self.wrench[0]:.4g} N, {self.wrench[1]:.4g} N, "
                f"{self.wrench[2]:.4g} N mm), size {self.size:.4g} N, set by the pose ({self.attaining[0]:.4g} mm, "
                f"{self.attaining[1]:.4g} mm, {math.degrees(self.attaining[2]):.4g} deg); holds on {self.n_check} "
                f"checked poses with min s_i lambda_i {self.min_intensity:.3g} N; "
                + (f"{self.certified_size:.4g} N proved for the whole region)" if math.isfinite(self.certified_size)
                   else "no proof for the whole region)"))


def _plain(values, k: int):
    """``values[k]`` as a float, None when missing or NaN."""
    if values is None or not math.isfinite(float(values[k])):
        return None
    return float(values[k]) + 0.0


#: Factors of the designed preload tried, in turn, by the proof of :func:`design_region_preload`.
CERTIFY_FACTORS = (1.0, 1.005, 1.01, 1.02, 1.05, 1.1, 1.25, 1.5)


def _region_poses(robot: Manipulator, region, n: int, n_phi: int) -> np.ndarray:
    """Poses ``(m, 3)`` of an ``n x n`` grid over the region's box at ``n_phi`` orientations (1 for a point
    interval), inside the region's shape and the workspace (joint ranges)."""
    phis = np.linspace(*region.phi, 1 if region.phi[0] == region.phi[1] else n_phi)
    out = [np.zeros((0, 3))]
    for phi in phis:
        ws = constant_orientation_workspace(robot, float(phi))
        if ws.is_empty:
            continue
        (wx0, wx1), (wy0, wy1) = ws.bounds
        x0, x1 = max(region.x[0], wx0), min(region.x[1], wx1)
        y0, y1 = max(region.y[0], wy0), min(region.y[1], wy1)
        if x0 > x1 or y0 > y1:
            continue
        X, Y = np.meshgrid(np.linspace(x0, x1, n), np.linspace(y0, y1, n))
        pts = np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, phi)])
        out.append(pts[region.contains(pts[:, 0], pts[:, 1])])
    pts = np.vstack(out)
    return pts[inverse_kinematics(robot, pts).within_limits] if pts.shape[0] else pts


def _slack(robot: Manipulator, poses: np.ndarray, P: np.ndarray, s: np.ndarray, c: np.ndarray,
           h: np.ndarray) -> np.ndarray:
    """``(m,)`` N: ``min_i min_{W in box} s_i lambda_i(P + W)`` at poses ``(m, 3)``."""
    L = _intensity_map(robot, poses)
    return np.min(s * (L @ (P + c)) - np.abs(L) @ h, axis=-1)


def _preload_lp(L: np.ndarray, c: np.ndarray, h: np.ndarray, margin: float, scale: np.ndarray):
    """Best pattern's ``(size, P, s)`` of ``min max_j |P_j| / scale_j`` s.t. ``s_i L_ni (P + W) >= margin`` for
    every pose ``n`` and wrench ``W`` of the box (scipy HiGHS), or None."""
    best = None
    for s in _PATTERNS:
        rows = (s[None, :, None] * L).reshape(-1, 3)                                # (3m, 3): s_i L_ni
        rhs = (margin - (s[None] * (L @ c)) + np.abs(L) @ h).reshape(-1)
        A_ub = np.vstack([np.column_stack([-rows, np.zeros(rows.shape[0])]),
                          np.column_stack([np.diag(1 / scale), -np.ones(3)]),
                          np.column_stack([-np.diag(1 / scale), -np.ones(3)])])
        b_ub = np.concatenate([-rhs, np.zeros(6)])
        res = linprog(np.array([0.0, 0.0, 0.0, 1.0]), A_ub=A_ub, b_ub=b_ub, bounds=[(None, None)] * 4,
                      method="highs")
        if res.status == 0 and (best is None or res.fun < best[0]):
            best = (float(res.fun), res.x[:3], s)
    return best


def design_region_preload(robot: Manipulator | str, clearances, region, center, half, *, grid: int = 21,
                          n_phi: int = 5, margin: float = DEFAULT_THRESHOLD_N, rounds: int = 8,
                          certify: bool = True, max_boxes: int = 400_000,
                          max_condition: float = DEFAULT_MAX_CONDITION) -> RegionPreload:
    """The smallest constant platform wrench ``P`` (size ``max(|P_x|, |P_y|, |P_m| / L)``) keeping every leg's
    intensity on one side, with at least ``margin`` N, for every process wrench of the box ``center +- half``
    at every pose of ``region`` (a :class:`pmaccuracy.accuracy.global_worst.Region`: positions in a box or
    shape times an orientation interval, intersected with the workspace; ``make_region``).

    Over a connected region a preload that keeps every contact loaded keeps one pattern ``s`` everywhere (the
    intensities are continuous in the pose and the wrench and never cross ``(-margin, margin)``), so for each
    of the eight patterns one linear program (scipy HiGHS) takes every pose at once:
    ``min z`` s.t. ``s_i L_i(p) P >= margin - s_i L_i(p) center + |L_i(p)| half`` (the box's worst wrench,
    module docstring) and ``|P_j| / scale_j <= z``, over a ``grid x grid`` sample at ``n_phi`` orientations.
    Its optimum is a **lower bound** of the smallest preload over the region (the sample is part of it).
    Exchange: the design is checked on a sample twice as dense (the grid and its midpoints) and at the local
    minima of the slack found around its five worst poses (:func:`_refine`); poses where it fails join the
    program, ``rounds`` times at most. **Guaranteed**: the preload holds (every ``s_i lambda_i >= margin``) at
    every checked pose (``n_check``) and every wrench of the box (the box's worst wrench is exact, the
    intensities being linear in the wrench). **Certified** (``certify``): :func:`certify_preload` then tries to
    prove it over the whole region by interval branch and bound; a counterexample pose joins the program (the
    lower bound rises), and when the design itself cannot be proved, the designed wrench times
    :data:`CERTIFY_FACTORS` is tried in turn: the first proved one is ``certified_wrench``, so that
    ``size <= smallest preload for the region <= certified_size`` (``max_boxes`` per proof).
    Regions reaching a parallel singularity (where no finite preload suffices) are refused like ``worst``;
    poses at an actuator's serial singularity (the workspace's edge for some architectures) are skipped.
    The offsets, worst cases and ranges of the result are taken over the ``grid x grid`` sample.

    >>> from pmaccuracy.accuracy.global_worst import make_region
    >>> from pmaccuracy.accuracy.regions import Disc
    >>> r = design_region_preload("symmetric_3rpr", "rpr_typical", make_region("symmetric_3rpr", (0.0, 0.0),
    ...                           Disc((0.0, 0.0), 5.0)), [0.0, 0.0, 0.0], [2.0, 2.0, 0.0], grid=7)
    >>> bool(r.size >= r.per_pose_size - 1e-9 and r.min_intensity >= 1e-6 * (1 - 1e-6))
    True
    """
    robot = robot_arg(robot)
    clearances = clearances_arg(clearances, robot)
    sources = clearances.check(robot) if isinstance(clearances, ErrorSources) else \
        ErrorSources.from_clearance_set(clearances)
    c, h = _box(center, half)
    if not isinstance(region, Region):
        raise ConfigError(f"expected a Region (pmaccuracy.accuracy.global_worst.make_region), got {region!r}",
                          key="region")
    for key, value, least in (("grid", grid, 2), ("n_phi", n_phi, 1), ("rounds", rounds, 1)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
            raise ConfigError(f"must be a whole number >= {least}, got {value!r}", key=key)
    if not (math.isfinite(margin) and margin > 0):
        raise ConfigError(f"must be a force > 0 (N), got {margin}", key="margin")
    base = _region_poses(robot, region, grid, n_phi)
    if base.shape[0] == 0:
        raise EmptyWorkspaceError(f"no pose of the {grid} x {grid} grid lies in {region.describe()} and the workspace")
    dense = _region_poses(robot, region, 2 * grid - 1, 2 * n_phi - 1)
    try:
        _check_regular(robot, np.vstack([base, dense]), region, max_condition)
    except SingularRegionError as exc:
        raise SingularRegionError(str(exc).split("; the worst-case")[0] + "; the legs' intensities, and the preload "
                                  "keeping them on one side, are unbounded there: narrow --phi-deg or the region"
                                  ) from None
    # serial singularities at the workspace's edge (an actuator's B_ii = 0) are skipped like worst's grid does
    base = base[regular_mask(robot, base, max_condition)]
    check = np.vstack([base, dense[regular_mask(robot, dense, max_condition)]])
    design = base
    scale = np.array([1.0, 1.0, robot.characteristic_length])
    n_steps = 1 if region.phi[0] == region.phi[1] else 2 * n_phi - 2
    step = np.array([(region.x[1] - region.x[0]) / (2 * grid - 2), (region.y[1] - region.y[0]) / (2 * grid - 2),
                     (region.phi[1] - region.phi[0]) / n_steps])
    for _ in range(rounds):
        best = _preload_lp(_intensity_map(robot, design), c, h, margin, scale)
        if best is None:
            raise ConfigError(f"no constant preload keeps the contacts fixed over {region.describe()} (a leg's "
                              "intensity changes sign whatever the preload: the region reaches or crosses a "
                              "singularity?): narrow the region", key="region")
        size, P, pattern = best
        slack = _slack(robot, check, P, pattern, c, h)
        worst = np.argsort(slack)[:5]
        check = np.vstack([check, _refine(robot, region, check[worst], step, P, pattern, c, h, max_condition)])
        slack = _slack(robot, check, P, pattern, c, h)
        bad = slack < margin * (1 - 1e-9)
        if not np.any(bad):
            break
        design = np.vstack([design, check[bad]])
    cert_wrench, cert_size, cert_boxes = np.full(3, np.nan), float("nan"), 0
    if certify:
        for factor in CERTIFY_FACTORS:
            for _ in range(3 if factor == 1.0 else 1):
                proved, used, counter = certify_preload(robot, region, factor * P, pattern, c, h, max_boxes=max_boxes,
                                                        max_condition=max_condition)
                cert_boxes += used
                if proved or counter is None or factor != 1.0:
                    break
                design = np.vstack([design, counter[None]])          # a pose the design missed: solve again
                best = _preload_lp(_intensity_map(robot, design), c, h, margin, scale)
                if best is None:
                    raise ConfigError(f"no constant preload keeps the contacts fixed over {region.describe()}",
                                      key="region")
                size, P, pattern = best
                check = np.vstack([check, counter[None]])
                slack = _slack(robot, check, P, pattern, c, h)
            if proved:
                cert_wrench, cert_size = factor * P, factor * size
                break
    L = _intensity_map(robot, design)
    binding = np.min(pattern * (L @ (P + c)) - np.abs(L) @ h, axis=-1)
    attaining = design[int(np.argmin(binding))]
    per_pose = design_preload(robot, sources, attaining, c, h, margin=margin).size
    b = max_pose_errors(robot, sources, base, details=True)
    offsets = np.einsum("nij,j->ni", b.generators, -pattern)
    reached = _reached_patterns(_intensity_map(robot, base), c, h, margin)
    errors = np.einsum("nij,kj->nki", b.generators, -_PATTERNS)
    masked = np.where(reached[..., None], errors, np.nan)
    width = np.nanmax(masked, axis=1) - np.nanmin(masked, axis=1)
    return RegionPreload(region=region.describe(), center=c, half=h, wrench=P, size=size, pattern=pattern,
                         attaining=attaining, per_pose_size=float(per_pose), min_intensity=float(np.min(slack)),
                         n_design=int(design.shape[0]), n_check=int(check.shape[0]),
                         offset_max=np.max(np.abs(offsets), axis=0),
                         worst_max=np.array([np.max(b.dx_max), np.max(b.dy_max), np.max(b.dphi_max)]),
                         range_without=np.max(width, axis=0), certified_wrench=cert_wrench,
                         certified_size=cert_size, certified_boxes=int(cert_boxes))


def _refine(robot: Manipulator, region, starts: np.ndarray, step: np.ndarray, P, s, c, h,
            max_condition: float) -> np.ndarray:
    """Local minima ``(k, 3)`` of the slack (:func:`_slack`) near ``starts`` ``(k, 3)``: a 7 x 7 x 7 pattern of
    poses ``+- step`` around each (``step`` ``(3,)`` mm, mm, rad), kept inside the region, the joint ranges and
    away from singularities, the best taken and the pattern shrunk by 3, five times (vectorized)."""
    lo = np.array([region.x[0], region.y[0], region.phi[0]])
    hi = np.array([region.x[1], region.y[1], region.phi[1]])
    offsets = np.stack(np.meshgrid(*[np.linspace(-1.0, 1.0, 7)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    best = starts.copy()
    value = _slack(robot, best, P, s, c, h)
    step = np.asarray(step, dtype=float).copy()
    for _ in range(5):
        cand = (best[:, None, :] + offsets[None] * step).reshape(-1, 3)
        cand = np.clip(cand, lo, hi)
        owner = np.repeat(np.arange(best.shape[0]), offsets.shape[0])
        ok = region.contains(cand[:, 0], cand[:, 1]) & inverse_kinematics(robot, cand).within_limits
        ok[ok] = regular_mask(robot, cand[ok], max_condition)
        if np.any(ok):
            vals = _slack(robot, cand[ok], P, s, c, h)
            for k in range(best.shape[0]):
                mine = owner[ok] == k
                if np.any(mine) and vals[mine].min() < value[k]:
                    j = int(np.argmin(np.where(mine, vals, np.inf)))
                    best[k], value[k] = cand[ok][j], vals[j]
        step /= 3.0
    return best


# ----------------------------------------------------------------------------- certificate of a region preload
#: Relative widening of interval lower bounds of the certificate (covers floating-point rounding).
_ROUNDING = 1e-9


def _box_intensities(robot: Manipulator, boxes: np.ndarray, sigmas, P: np.ndarray, s: np.ndarray, c: np.ndarray,
                     h: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lower bounds ``(n,)`` (N) of ``min_i s_i lambda_i`` over boxes of poses ``(n, 6)`` ``[x0, x1, y0, y1, phi0,
    phi1]`` and every wrench ``P + W``, ``W`` in the box ``c +- h``; also ``infeasible (n,)`` (no pose of the box
    is in the workspace) and ``det_zero (n,)`` (``det A`` may vanish: no bound).

    ``lambda = -A^{-T} (P + W)``, i.e. ``lambda_i = -sum_r adj(A)[r, i] (P + W)_r / det A``, with the rows of
    ``A`` over the box from the closed forms of :func:`pmaccuracy.accuracy.interval.leg_box_state` (the
    adjugate and determinant enclosed as in :func:`pmaccuracy.accuracy.interval.box_maxima_once`: trigonometric
    polynomials and interval products, intersected); ``P + W`` is an interval vector, which each term uses once.
    """
    x, y, phi = Iv(boxes[:, 0], boxes[:, 1]), Iv(boxes[:, 2], boxes[:, 3]), Iv(boxes[:, 4], boxes[:, 5])
    n = boxes.shape[0]
    infeasible = np.zeros(n, dtype=bool)
    rows, rows_iv = [], []
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        gvar = [phi]
        for i, (chain, sigma) in enumerate(zip(robot.chains, sigmas)):
            lb = leg_box_state(chain, x, y, phi, sigma, 1e-9)
            infeasible |= lb.infeasible
            index = (0, 1 + 3 * i, 2 + 3 * i, 3 + 3 * i)
            gvar.extend(lb.var[1:])
            fx, fy = t_parts(lb.f)
            rows.append(tuple(t.remap(index, 10) for t in (fx, fy, lb.m_P_trig)))
            fc = v_cv(lb.f, lb.var)
            rows_iv.append((fc.re, fc.im, lb.m_P))

        def meet(a: Iv, b: Iv) -> Iv:
            return Iv(np.maximum(a.lo, b.lo), np.minimum(a.hi, b.hi))

        adj = [[None] * 3 for _ in range(3)]        # adj[r][i] = cofactor of A[i, r]
        for i in range(3):
            ri = [k for k in range(3) if k != i]
            for r in range(3):
                cc = [k for k in range(3) if k != r]
                m = rows[ri[0]][cc[0]] * rows[ri[1]][cc[1]] - rows[ri[0]][cc[1]] * rows[ri[1]][cc[0]]
                mi = rows_iv[ri[0]][cc[0]] * rows_iv[ri[1]][cc[1]] - rows_iv[ri[0]][cc[1]] * rows_iv[ri[1]][cc[0]]
                sign = 1.0 if (i + r) % 2 == 0 else -1.0
                adj[r][i] = (m * sign, mi * sign)
        det_t = rows[0][0] * adj[0][0][0] + rows[0][1] * adj[1][0][0] + rows[0][2] * adj[2][0][0]
        det_i = rows_iv[0][0] * adj[0][0][1] + rows_iv[0][1] * adj[1][0][1] + rows_iv[0][2] * adj[2][0][1]
        det = meet(det_t.iv(gvar), det_i)
        adj_iv = [[meet(adj[r][i][0].iv(gvar), adj[r][i][1]) for i in range(3)] for r in range(3)]
        det_zero = det.contains_zero() | ~np.isfinite(det.lo) | ~np.isfinite(det.hi)
        V = [Iv(np.full(n, P[r] + c[r] - h[r]), np.full(n, P[r] + c[r] + h[r])) for r in range(3)]
        lower = np.full(n, np.inf)
        for i in range(3):
            num = adj_iv[0][i] * V[0] + adj_iv[1][i] * V[1] + adj_iv[2][i] * V[2]
            q = (num * float(-s[i])) / det
            lower = np.minimum(lower, q.lo - _ROUNDING * np.maximum(np.abs(q.lo), np.abs(q.hi)))
    lower = np.where(det_zero | np.isnan(lower), -np.inf, lower)
    return lower, infeasible, det_zero


def certify_preload(robot: Manipulator | str, region, wrench, pattern, center, half, *, max_boxes: int = 400_000,
                    max_condition: float = DEFAULT_MAX_CONDITION) -> tuple[bool, int, np.ndarray | None]:
    """Prove that the preload ``wrench`` ``(3,)`` [N, N, N mm] keeps every leg's intensity strictly on the side
    ``pattern`` ``(3,)`` for every process wrench of the box ``center +- half`` at every pose of ``region`` (a
    :class:`~pmaccuracy.accuracy.global_worst.Region`, intersected with the workspace), by branch and bound on
    interval enclosures of the intensities over boxes of poses (:func:`_box_intensities`, rigorous up to a
    relative ``1e-9`` for rounding). A box is closed when its lower bound of ``min_i s_i lambda_i`` is positive,
    or when it is proved outside the workspace or the region's shape; the others are bisected along their
    widest side (phi times the robot's size).

    Returns ``(certified, boxes evaluated, counterexample)``: ``certified`` False with a pose ``(3,)`` of the
    region where a contact does flip (the box centres are evaluated exactly), or with None when ``max_boxes``
    was spent first.
    """
    robot = robot_arg(robot)
    c, h = _box(center, half)
    P = np.asarray(wrench, dtype=float).reshape(3)
    s = np.asarray(pattern, dtype=float).reshape(3)
    sample = _region_poses(robot, region, 5, 3)
    sample = sample[regular_mask(robot, sample, max_condition)] if sample.shape[0] else sample
    start = sample[0] if sample.shape[0] else np.array([region.x[0], region.y[0], region.phi[0]])
    sigmas = leg_branches(robot, start)
    scale = np.array([1.0, 1.0, robot.characteristic_length])
    boxes = np.array([[*region.x, *region.y, *region.phi]])
    n_boxes = 0
    while boxes.shape[0]:
        if region.shape is not None:
            boxes = boxes[region.shape.classify(boxes[:, :4]) != OUTSIDE]
            if not boxes.shape[0]:
                break
        n_boxes += boxes.shape[0]
        lower, infeasible, _ = _box_intensities(robot, boxes, sigmas, P, s, c, h)
        boxes = boxes[~infeasible & ~(lower > 0)]
        if not boxes.shape[0]:
            break
        pts = 0.5 * (boxes[:, 0::2] + boxes[:, 1::2])
        ok = region.contains(pts[:, 0], pts[:, 1]) & inverse_kinematics(robot, pts).within_limits
        ok[ok] = regular_mask(robot, pts[ok], max_condition)
        if np.any(ok):
            slack = _slack(robot, pts[ok], P, s, c, h)
            if np.any(slack <= 0):
                return False, n_boxes, pts[ok][int(np.argmin(slack))]
        if n_boxes + 2 * boxes.shape[0] > max_boxes:
            return False, n_boxes, None
        sizes = np.column_stack([boxes[:, 1] - boxes[:, 0], boxes[:, 3] - boxes[:, 2],
                                 boxes[:, 5] - boxes[:, 4]]) * scale
        axis = np.argmax(sizes, axis=1)
        rows = np.arange(boxes.shape[0])
        mid = 0.5 * (boxes[rows, 2 * axis] + boxes[rows, 2 * axis + 1])
        left, right = boxes.copy(), boxes.copy()
        left[rows, 2 * axis + 1] = mid
        right[rows, 2 * axis] = mid
        boxes = np.concatenate([left, right])
    return True, n_boxes, None


__all__ = ["DEFAULT_THRESHOLD_N", "G0", "LOADED_MAP_VARIABLES", "Load", "LoadedError", "Preload", "RegionPreload",
           "Statics", "WRENCH_SET_MAP_VARIABLES", "WrenchSetErrors", "certify_preload", "design_preload",
           "design_region_preload",
           "loaded_error_map", "loaded_pose_error", "statics", "wrench_rows", "wrench_set_errors", "wrench_set_map"]
