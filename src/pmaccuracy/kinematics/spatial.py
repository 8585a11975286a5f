"""Kinematics of spatial parallel manipulators: poses, inverse and forward kinematics, Jacobians, singularities.

Every leg contributes scalar closure equations (:mod:`pmaccuracy.model.spatial_legs`); together they are six,
``e(pose, q) = 0``, with derivatives ``W t = G q_dot`` along a platform twist ``t = [v, w]``: ``W`` ``(..., 6, 6)``
stacks the equations' wrenches (forces along legs, rods and revolute axes, couples of a 3-UPU) and ``G``
``(..., 6, n)`` their gains on the actuated joints. Everything follows from it:

* the forward Jacobian ``J = W^-1 G`` (``t = J q_dot``), the inverse one (actuation wrenches
  ``a_i . t = q_dot_i``) and the constraint wrenches of lower-mobility robots (``c . t = 0``), which together
  give the overall 6 x 6 Jacobian ``J_x t = [q_dot; 0]`` (Joshi and Tsai 2002);
* forward kinematics by Newton: ``W dt = -e``, ``pose <- pose (+) dt`` (:func:`pmaccuracy.numerics.spatial.displace`);
* singularities: serial (a leg's gain vanishes), parallel (``W`` rank-deficient) and constraint (the constraint
  wrenches alone rank-deficient), measured on ``W`` homogenized by the characteristic length.

Poses are ``(..., 6)`` ``[x, y, z mm, rotation vector rad]`` (base frame); twists ``[v, w]``; actuated values mm
(slides, lengths) or rad (a Delta's arms). Conventions: ``docs/guide/spatial.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from itertools import combinations

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import GeometryError, NoSolutionError, PoseError
from ..model.plausibility import check_angle_values
from ..model.spatial import CONTROLLED, SpatialManipulator
from ..model.spatial_legs import DeltaLeg, UPSLeg
from .assembly_modes import assembly_modes as solve_modes
from ..numerics.spatial import (displace, euler_xyz_rates, euler_xyz_to_rotvec, rotations, rotvec_to_euler_xyz,
                                rotvecs, segment_distance)

#: Slack of every joint limit (mm or rad): a pose computed on the workspace boundary counts as inside.
LIMIT_TOLERANCE = 1e-9
#: A full pose of a lower-mobility robot counts as attainable when its constraint residuals are below this (mm).
CONSTRAINT_TOLERANCE = 1e-6
#: Newton iterations of forward kinematics and of the parasitic motions.
NEWTON_ITERATIONS = 30
#: Newton iterations of a chain robot's parasitic motions (they converge in a few where the legs close).
CHAIN_ITERATIONS = 12
#: Newton stops when every residual is below this (mm, mm or rad).
NEWTON_TOL = 1e-11


# ---------------------------------------------------------------------------------------------- poses
def as_spatial_poses(poses, *, name: str = "pose") -> np.ndarray:
    """Check and convert poses to a float array ``(..., 6)`` ``[x, y, z mm, rotation vector rad]``.

    Non-finite values raise :class:`~pmaccuracy.errors.PoseError` naming the pose.
    """
    try:
        arr = np.asarray(poses, dtype=float)
    except (TypeError, ValueError):
        raise PoseError(f"{name}s must be numbers of shape (..., 6) = [x, y, z mm, rotation vector rad], got "
                        f"{type(poses).__name__}") from None
    if arr.ndim == 0 or arr.shape[-1] != 6:
        raise PoseError(f"{name}s of a spatial robot must have shape (..., 6) = [x, y, z mm, rotation vector rad], "
                        f"got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.all(np.isfinite(arr), axis=-1))[0]
        raise PoseError(f"{name} {tuple(int(i) for i in bad)} is not finite: {arr[tuple(bad)].tolist()}")
    return arr


def poses_from(positions, orientations=None) -> np.ndarray:
    """Poses ``(..., 6)`` from positions ``(..., 3)`` mm and orientations: a scipy ``Rotation`` (a batch or one),
    rotation vectors ``(..., 3)`` rad, or ``None`` (identity).

    >>> from scipy.spatial.transform import Rotation
    >>> poses_from([[0.0, 0.0, 500.0]], Rotation.from_euler("z", [90], degrees=True)).round(4).tolist()
    [[0.0, 0.0, 500.0, 0.0, 0.0, 1.5708]]
    """
    if orientations is not None and not isinstance(orientations, Rotation):
        try:
            check_angle_values(np.linalg.norm(np.asarray(orientations, dtype=float), axis=-1),
                               "orientations (rotation vectors)")
        except (TypeError, ValueError):
            pass
    p = np.asarray(positions, dtype=float)
    if orientations is None:
        r = np.zeros_like(p)
    elif isinstance(orientations, Rotation):
        r = orientations.as_rotvec()
    else:
        r = np.asarray(orientations, dtype=float)
    shape = np.broadcast_shapes(p.shape, r.shape)
    return np.concatenate([np.broadcast_to(p, shape), np.broadcast_to(r, shape)], axis=-1)


def poses_from_coordinates(coordinates, *, degrees: bool = False) -> np.ndarray:
    """Poses ``(..., 6)`` from ``[x, y, z, roll, pitch, yaw]`` (mm; extrinsic x-y-z angles, rad or deg)."""
    c = np.asarray(coordinates, dtype=float)
    if not degrees and c.ndim and c.shape[-1] == 6:
        check_angle_values(c[..., 3:], "coordinates[..., 3:] (roll, pitch, yaw)")
    return np.concatenate([c[..., :3], euler_xyz_to_rotvec(c[..., 3:], degrees=degrees)], axis=-1)


def coordinates(poses, *, degrees: bool = False) -> np.ndarray:
    """``[x, y, z, roll, pitch, yaw]`` (extrinsic x-y-z) of poses ``(..., 6)``: the inverse of
    :func:`poses_from_coordinates`."""
    poses = np.asarray(poses, dtype=float)
    return np.concatenate([poses[..., :3], rotvec_to_euler_xyz(poses[..., 3:], degrees=degrees)], axis=-1)


def _split(poses: np.ndarray):
    return poses[..., :3], rotations(poses[..., 3:]), poses[..., 3:]


def platform_points(robot: SpatialManipulator, poses: np.ndarray) -> np.ndarray:
    """The legs' platform joint centres ``p + R b_i`` in the base frame, ``(..., 6) -> (..., n, 3)`` mm."""
    p, R, _ = _split(np.asarray(poses, dtype=float))
    b = np.array([leg.platform for leg in robot.legs])
    return p[..., None, :] + np.einsum("...ij,kj->...ki", R, b)


def _actuate(robot: SpatialManipulator, p: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Every leg's actuated value ``(..., n)`` in closed form (NaN where a leg cannot reach)."""
    if all(type(leg) is UPSLeg or leg.ARCHITECTURE in ("3-RPS", "3-UPU") for leg in robot.legs):
        b = np.array([leg.platform for leg in robot.legs])
        A = np.array([leg.base for leg in robot.legs])
        B = p[..., None, :] + np.einsum("...ij,kj->...ki", R, b)
        return np.linalg.norm(B - A, axis=-1)
    return np.stack([leg.actuate(p, R) for leg in robot.legs], axis=-1)


# ---------------------------------------------------------------------------------------------- closure
@dataclass(frozen=True)
class Closure:
    """The six closure equations at poses for actuated values ``q``.

    Attributes
    ----------
    residuals : ``(..., 6)``
        ``e`` (mm, or rad for a 3-UPU's orientation equations), leg by leg.
    wrenches : ``(..., 6, 6)``
        ``W``: row ``k`` is the derivative of ``e_k`` along a twist (``de = W t``).
    gains : ``(..., 6, n)``
        ``G``: ``-de_k/dq_i`` so that ``W t = G q_dot`` keeps ``e = 0``.
    leg_of_row : ``(6,)``
        The leg (0-based) of each equation.
    """

    residuals: np.ndarray
    wrenches: np.ndarray
    gains: np.ndarray
    leg_of_row: np.ndarray


def closure(robot: SpatialManipulator, poses: np.ndarray, q: np.ndarray) -> Closure:
    """The closure equations ``e(pose, q)``, their wrenches ``W`` and gains ``G`` (see :class:`Closure`).

    ``poses`` ``(..., 6)``, ``q`` ``(..., n)`` broadcast together.
    """
    poses = np.asarray(poses, dtype=float)
    q = np.asarray(q, dtype=float)
    shape = np.broadcast_shapes(poses.shape[:-1], q.shape[:-1])
    poses = np.broadcast_to(poses, shape + (6,))
    q = np.broadcast_to(q, shape + (robot.n_actuators,))
    p, R, r = _split(poses)
    es, Ws, gs, legs = [], [], [], []
    for i, leg in enumerate(robot.legs):
        e, W, g = leg.closure(p, R, r, q[..., i])
        es.append(e)
        Ws.append(W)
        gs.append(g)
        legs.extend([i] * e.shape[-1])
    e = np.concatenate(es, axis=-1)
    W = np.concatenate(Ws, axis=-2)
    G = np.zeros(shape + (6, robot.n_actuators))
    row = 0
    for i, g in enumerate(gs):
        G[..., row:row + g.shape[-1], i] = g
        row += g.shape[-1]
    return Closure(residuals=e, wrenches=W, gains=G, leg_of_row=np.array(legs))


# ---------------------------------------------------------------------------------------------- IK
@dataclass(frozen=True)
class SpatialIK:
    """Inverse kinematics of a batch of poses.

    Attributes
    ----------
    poses : ``(..., 6)``
        The poses.
    q : ``(..., n)``
        Actuated joint values (mm; rad for a Delta's arms), NaN where a leg cannot reach.
    constraint_residual : ``(...)``
        Largest absolute constraint equation of a lower-mobility robot at the pose (mm or rad; 0 for a
        6-UPS): a full pose that the legs' constraints forbid is not attainable.
    limits : dict
        ``{(leg, name): bool (...)}`` for each joint limit (``reach``, ``stroke``, ``base_cone``,
        ``platform_cone``, ``revolute_range``) and ``{((i, j), "interference"): ...}`` for pairs of legs;
        computed on first use.
    within_limits : bool ``(...)``
        Attainable and every limit satisfied (first use computes :attr:`limits`).
    """

    robot: SpatialManipulator = field(repr=False)
    poses: np.ndarray
    q: np.ndarray
    constraint_residual: np.ndarray
    tol: float = LIMIT_TOLERANCE

    @cached_property
    def _pRr(self):
        return _split(self.poses)

    @cached_property
    def joint_angles(self) -> list[dict[str, np.ndarray]]:
        """Per leg: ``base_angle``, ``platform_angle`` (rad, from the cone axes), ``revolute_angle`` where there is
        a revolute (rad)."""
        p, R, _ = self._pRr
        return [leg.joint_angles(p, R, self.q[..., i]) for i, leg in enumerate(self.robot.legs)]

    @cached_property
    def limits(self) -> dict:
        p, R, _ = self._pRr
        out = {}
        for i, leg in enumerate(self.robot.legs):
            for name, ok in leg.limit_checks(p, R, self.q[..., i], self.tol).items():
                out[(i, name)] = ok
        for (i, j), ok in leg_interference(self.robot, self.poses, self.q).items():
            out[((i, j), "interference")] = ok
        return out

    @cached_property
    def within_limits(self) -> np.ndarray:
        ok = self.constraint_residual <= CONSTRAINT_TOLERANCE
        for value in self.limits.values():
            ok = ok & value
        return ok

    @property
    def reachable(self) -> np.ndarray:
        """Every leg reaches the pose (ignoring the ranges) and the constraints hold."""
        return np.all(np.isfinite(self.q), axis=-1) & (self.constraint_residual <= CONSTRAINT_TOLERANCE)

    def violations(self, index: tuple = ()) -> list[str]:
        """The limits violated at one pose, in words (``"leg 3: stroke"``, ``"legs 1 and 2 interfere"``)."""
        out = []
        if self.constraint_residual[index] > CONSTRAINT_TOLERANCE:
            out.append(f"the legs' constraints (residual {float(self.constraint_residual[index]):.3g})")
        for key, ok in self.limits.items():
            if not bool(np.asarray(ok)[index]):
                who, name = key
                if name == "interference":
                    out.append(f"legs {who[0] + 1} and {who[1] + 1} interfere")
                else:
                    out.append(f"leg {who + 1}: {LIMIT_WORDS.get(name, name)}")
        return out


#: Words for each limit in messages.
LIMIT_WORDS = {"reach": "cannot reach (no real inverse kinematics)", "stroke": "actuated joint outside its range",
               "base_cone": "base joint beyond its cone", "platform_cone": "platform joint beyond its cone",
               "revolute_range": "revolute outside its angle range"}


def leg_interference(robot: SpatialManipulator, poses: np.ndarray, q: np.ndarray, segments: list | None = None
                     ) -> dict:
    """``{(i, j): bool (...)}`` for every pair of legs with radii: True where their capsules do not intersect
    (the distance between their segments is at least the sum of their radii). ``segments``: the legs'
    :meth:`segments` at the poses when the caller has them (each ``(..., k, 2, 3)``)."""
    if not any(max(leg.radii()) > 0 for leg in robot.legs):
        return {}
    if segments is None:
        p, R, _ = _split(poses)
        segments = [leg.segments(p, R, q[..., i]) for i, leg in enumerate(robot.legs)]
    segs = segments
    pairs = [(i, j, a, b, ra + rb) for i, j in combinations(range(robot.n_legs), 2)
             for a, ra in enumerate(robot.legs[i].radii()) for b, rb in enumerate(robot.legs[j].radii()) if ra + rb > 0]
    out = {(i, j): np.ones(poses.shape[:-1], dtype=bool) for i, j in combinations(range(robot.n_legs), 2)}
    if pairs and poses.ndim > 1 and poses.size:
        # screen: a segment's points move at most as far as its farther end, so the distance at a pose is at
        # least the distance at the batch's first pose minus both segments' largest end displacements
        # (1-Lipschitz); only the pairs this leaves undecided get the exact distance
        first = (0,) * (poses.ndim - 1)
        moved = [np.max(np.sqrt(np.sum((sg - sg[first]) ** 2, axis=-1)), axis=-1) for sg in segs]   # (..., nseg)
        for i, j, a, b, reach in pairs:
            si, sj = segs[i][..., a, :, :], segs[j][..., b, :, :]
            d0 = float(segment_distance(si[first][0], si[first][1], sj[first][0], sj[first][1]))
            near = ~(d0 - moved[i][..., a] - moved[j][..., b] >= reach)
            if np.count_nonzero(near) > near.size // 2:      # mostly undecided: every pose, without gathering
                out[(i, j)] &= ~(segment_distance(si[..., 0, :], si[..., 1, :], sj[..., 0, :], sj[..., 1, :]) < reach)
            elif np.any(near):
                d = segment_distance(si[near][..., 0, :], si[near][..., 1, :], sj[near][..., 0, :], sj[near][..., 1, :])
                out[(i, j)][near] = ~(d < reach)
    elif pairs:
        for i, j, a, b, reach in pairs:
            si, sj = segs[i][..., a, :, :], segs[j][..., b, :, :]
            out[(i, j)] &= ~(segment_distance(si[..., 0, :], si[..., 1, :], sj[..., 0, :], sj[..., 1, :]) < reach)
    return out


def _constraint_residual(robot: SpatialManipulator, poses: np.ndarray, q: np.ndarray) -> np.ndarray:
    if robot.mobility == "6":
        return np.zeros(poses.shape[:-1])
    cl = closure(robot, poses, np.nan_to_num(q))
    constraint_rows = np.all(cl.gains == 0, axis=-1)   # equations with no actuator: the constraints
    e = np.where(constraint_rows, np.abs(cl.residuals), 0.0)
    return np.max(e, axis=-1)


def inverse_kinematics(robot: SpatialManipulator, poses, tol: float = LIMIT_TOLERANCE) -> SpatialIK:
    """Actuated joint values of poses ``(..., 6)`` in closed form, leg by leg (:class:`SpatialIK`).

    6-UPS, 3-RPS, 3-UPU: the leg length ``|p + R b_i - A_i|``; 3-PRS: the slide from the rod's sphere; Delta: the
    arm angle from ``e . d(theta) = K`` (:mod:`pmaccuracy.model.spatial_legs`); a chain robot's legs numerically
    (:mod:`pmaccuracy.model.spatial_chain`: one solve per leg gives both its value and its constraint rows). A
    lower-mobility robot's pose must also satisfy its constraints (:func:`complete_poses` gives such poses from
    the controlled coordinates).

    >>> robot = SpatialManipulator.preset("stewart_6ups")
    >>> ik = inverse_kinematics(robot, robot.home_pose)
    >>> bool(ik.within_limits), ik.q.shape
    (True, (6,))
    """
    poses = as_spatial_poses(poses)
    p, R, _ = _split(poses)
    if robot.is_chain and robot.mobility != "6":
        parts = [leg.solve_closure(p, R) for leg in robot.legs]
        q = np.stack([part[0] for part in parts], axis=-1)
        e = np.concatenate([part[1] for part in parts], axis=-1)[..., _chain_constraint_rows(robot)]
        residual = np.max(np.abs(np.nan_to_num(e)), axis=-1, initial=0.0)     # an unreachable leg: q is NaN
        return SpatialIK(robot=robot, poses=poses, q=q, constraint_residual=residual, tol=tol)
    q = _actuate(robot, p, R)
    return SpatialIK(robot=robot, poses=poses, q=q, constraint_residual=_constraint_residual(robot, poses, q), tol=tol)


def _chain_constraint_rows(robot: SpatialManipulator) -> np.ndarray:
    """Which of a chain robot's six closure rows are constraints: each leg's first row is its actuation row."""
    return np.concatenate([[False] + [True] * (leg.ROWS - 1) for leg in robot.legs])


# ---------------------------------------------------------------------------------------------- parasitic motions
def complete_poses(robot: SpatialManipulator, controlled, *, iterations: int = NEWTON_ITERATIONS,
                   strict: bool = True) -> np.ndarray:
    """Full poses ``(..., 6)`` from the controlled coordinates ``(..., m)`` (mm and rad; extrinsic x-y-z angles).

    6-UPS: ``[x, y, z, roll, pitch, yaw]``; Delta and 3-UPU: ``[x, y, z]`` with the identity orientation; 3-RPS and
    3-PRS: ``[z, roll, pitch]``, the parasitic ``x, y, yaw`` solved by Newton from 0 on the three constraint
    equations ``axis_i . (p + R b_i - base_i) = 0`` (derivatives: ``axis_i[:2]`` for x, y and
    ``axis_i . (e_z x R b_i)`` for yaw). A chain robot (``spatial-chain``): Newton on its legs' constraint rows
    for whichever coordinates it does not command (:func:`_complete_chain`). Raises :class:`~pmaccuracy.errors.NoSolutionError` where Newton does not
    converge (``strict=False``: NaN poses there instead).
    """
    c = np.asarray(controlled, dtype=float)
    m = len(CONTROLLED[robot.mobility])
    angles = [k for k, i in enumerate(CONTROLLED[robot.mobility]) if i >= 3]
    if angles and c.ndim and c.shape[-1] == m:
        check_angle_values(c[..., angles], "controlled coordinates (angles)")
    if c.ndim == 0 or c.shape[-1] != m:
        raise PoseError(f"a {robot.architecture} takes {m} coordinates ({', '.join(robot.controlled)}), got shape "
                        f"{c.shape}")
    if not np.all(np.isfinite(c)):
        raise PoseError("coordinates must be finite")
    if robot.mobility == "6":
        return poses_from_coordinates(c)
    if robot.is_chain:
        return _complete_chain(robot, c, iterations=min(iterations, CHAIN_ITERATIONS), strict=strict)
    if robot.mobility == "3T":
        return np.concatenate([c, np.zeros_like(c)], axis=-1)
    z, roll, pitch = c[..., 0], c[..., 1], c[..., 2]
    xyw = np.zeros(c.shape[:-1] + (3,))
    axes = np.array([leg.axis for leg in robot.legs])
    bases = np.array([leg.base for leg in robot.legs])
    b = np.array([leg.platform for leg in robot.legs])
    ez = np.array([0.0, 0.0, 1.0])
    for _ in range(iterations):
        angles = np.stack([roll, pitch, xyw[..., 2]], axis=-1)
        R = Rotation.from_euler("xyz", angles.reshape(-1, 3)).as_matrix().reshape(angles.shape[:-1] + (3, 3))
        Rb = np.einsum("...ij,kj->...ki", R, b)
        p = np.stack([xyw[..., 0], xyw[..., 1], z], axis=-1)
        g = np.sum(axes * (p[..., None, :] + Rb - bases), axis=-1)                 # (..., 3)
        if np.all(np.abs(g) < NEWTON_TOL):
            break
        Jac = np.concatenate([np.broadcast_to(axes[:, :2], g.shape + (2,)),
                              np.sum(axes * np.cross(ez, Rb), axis=-1)[..., None]], axis=-1)
        with np.errstate(invalid="ignore"):
            Jac = np.where(np.isfinite(Jac), Jac, 0.0)
            singular = np.abs(np.linalg.det(Jac)) < 1e-12
            Jac = np.where(singular[..., None, None], np.eye(3), Jac)
            xyw = xyw - np.linalg.solve(Jac, np.where(np.isfinite(g), g, 0.0)[..., None])[..., 0]
            xyw = np.where(np.abs(xyw) < 1e9, xyw, np.nan)
    bad = ~np.all(np.abs(g) < 1e-8, axis=-1)
    if not strict:
        xyw = np.where(bad[..., None], np.nan, xyw)
    elif np.any(bad):
        idx = tuple(int(i) for i in np.argwhere(bad)[0])
        raise NoSolutionError(f"no pose with the coordinates {np.round(c[idx], 6).tolist()} satisfies the legs' "
                              "constraints (the parasitic motions did not converge)")
    angles = np.stack([roll, pitch, xyw[..., 2]], axis=-1)
    return np.concatenate([np.stack([xyw[..., 0], xyw[..., 1], z], -1), euler_xyz_to_rotvec(angles)], axis=-1)


def _complete_chain(robot: SpatialManipulator, c: np.ndarray, *, iterations: int, strict: bool) -> np.ndarray:
    """Parasitic coordinates of a chain robot by Newton on its constraint equations (the closure rows with no
    actuator gain, reciprocal to every joint of their leg), from the home pose's values: the derivative of a
    constraint row ``w`` along coordinate ``k`` is ``w . t_k`` with ``t_k`` the twist of a unit rate of ``k``
    (``[e_k, 0]`` for x, y, z; ``[0, omega_k]`` for the angles,
    :func:`~pmaccuracy.numerics.spatial.euler_xyz_rates`). Only the poses not yet converged are iterated; the
    legs follow their branch from home (continuation) from the third step on, and a pose whose residual grows
    after it is given up (the legs cannot close there)."""
    fixed = list(CONTROLLED[robot.mobility])
    free = [k for k in range(6) if k not in fixed]
    shape = c.shape[:-1]
    coords = np.array(np.broadcast_to(coordinates(_home_or_zero(robot)), shape + (6,))).reshape(-1, 6)
    coords[:, fixed] = c.reshape(-1, len(fixed))
    converged = np.zeros(coords.shape[0], dtype=bool)
    active = np.arange(coords.shape[0])
    previous = np.full(coords.shape[0], np.inf)
    for k in range(iterations):
        if not active.size:
            break
        p, R, _ = _split(poses_from_coordinates(coords[active]))
        # one solve per leg; continuation (the leg's branch from home) once the first steps have settled the pose
        parts = [leg.solve_closure(p, R, continuation=k >= 2) for leg in robot.legs]
        rows = _chain_constraint_rows(robot)
        e = np.concatenate([part[1] for part in parts], axis=-1)[:, rows]
        wrenches = np.concatenate([part[2] for part in parts], axis=-2)
        done = np.all(np.abs(e) < NEWTON_TOL, axis=-1) & np.all([np.isfinite(part[0]) for part in parts], axis=0)
        finite = np.all(np.isfinite(e), axis=-1)
        size = np.max(np.abs(e), axis=-1)
        # Newton's residual falls fast where the legs can close: one that grows after the first steps cannot
        finite &= (k < 3) | (size < previous[active])
        previous[active] = size
        converged[active[done]] = True
        keep = ~done & finite
        T = np.zeros((keep.sum(), 6, 6))
        T[:, :3, :3] = np.eye(3)
        T[:, 3:, 3:] = euler_xyz_rates(coords[active[keep]][:, 3:])
        Jac = (wrenches[keep][:, rows, :] @ T)[..., free]
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            step = _solve_rows(Jac, e[keep])
        coords[active[keep][:, None], free] -= np.where(np.isfinite(step), step, 0.0)
        active = active[keep]
    bad = ~converged.reshape(shape)
    out = poses_from_coordinates(coords.reshape(shape + (6,)))
    if not strict:
        return np.where(bad[..., None], np.nan, out)
    if np.any(bad):
        idx = tuple(int(i) for i in np.argwhere(np.atleast_1d(bad))[0]) if np.ndim(bad) else ()
        shown = np.round(np.asarray(c)[idx], 6).tolist()
        raise NoSolutionError(f"the parasitic motions at the controlled coordinates {shown} do not converge (the "
                              "legs' constraints cannot be met there)")
    return out


def _solve_rows(Jac: np.ndarray, e: np.ndarray) -> np.ndarray:
    """``Jac^-1 e`` batched, NaN where ``Jac`` is singular."""
    singular = ~(np.abs(np.linalg.det(Jac)) > 1e-300)
    safe = np.where(singular[..., None, None], np.eye(Jac.shape[-1]), Jac)
    return np.where(singular[..., None], np.nan, np.linalg.solve(safe, e[..., None])[..., 0])


def _home_or_zero(robot: SpatialManipulator) -> np.ndarray:
    """The file's home pose, else zero ``(6,)``."""
    return robot.home_pose if robot.home_pose is not None else np.zeros(6)


def controlled_coordinates(robot: SpatialManipulator, poses) -> np.ndarray:
    """The controlled coordinates ``(..., m)`` of full poses (the inverse of :func:`complete_poses`)."""
    return coordinates(poses)[..., list(CONTROLLED[robot.mobility])]


# ---------------------------------------------------------------------------------------------- FK: Newton
@dataclass(frozen=True)
class SpatialFK:
    """Forward kinematics by Newton from guesses.

    Attributes
    ----------
    poses : ``(..., 6)``
        The poses reached (NaN where Newton did not converge).
    converged : bool ``(...)``
        Whether Newton converged.
    residual : ``(...)``
        Largest absolute closure equation at the end (mm or rad).
    iterations : int
        Newton steps taken.
    """

    poses: np.ndarray
    converged: np.ndarray
    residual: np.ndarray
    iterations: int


def forward_kinematics(robot: SpatialManipulator, q, guess=None, *, iterations: int = NEWTON_ITERATIONS,
                       tol: float = NEWTON_TOL) -> SpatialFK:
    """The pose near ``guess`` (default: the home pose) with the actuated values ``q`` ``(..., n)``: Newton's
    method on the closure, ``W dt = -e``, ``pose <- pose (+) dt``, vectorized over the batch.

    Converges to the assembly mode whose basin holds the guess; :func:`assembly_modes` finds every mode.

    >>> robot = SpatialManipulator.preset("stewart_6ups")
    >>> q = inverse_kinematics(robot, robot.home_pose).q
    >>> fk = forward_kinematics(robot, q + 1.0)
    >>> bool(fk.converged), bool(np.allclose(inverse_kinematics(robot, fk.poses).q, q + 1.0))
    (True, True)
    """
    q = np.asarray(q, dtype=float)
    if q.ndim == 0 or q.shape[-1] != robot.n_actuators:
        raise PoseError(f"a {robot.architecture} takes {robot.n_actuators} actuator values, got shape {q.shape}")
    if not np.all(np.isfinite(q)):
        raise PoseError("actuator values must be finite")
    if guess is None:
        guess = robot.home_pose if robot.home_pose is not None else np.zeros(6)
    pose = np.array(np.broadcast_to(as_spatial_poses(guess, name="guess"), q.shape[:-1] + (6,)))
    step = 0
    res = np.full(q.shape[:-1], np.inf)
    for step in range(1, iterations + 1):
        cl = closure(robot, pose, q)
        res = np.max(np.abs(cl.residuals), axis=-1)
        if np.all(res < tol):
            break
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            try:
                dt = -np.linalg.solve(cl.wrenches, cl.residuals[..., None])[..., 0]
            except np.linalg.LinAlgError:
                dt = -np.einsum("...ij,...j->...i", np.linalg.pinv(cl.wrenches), cl.residuals)
        dt = np.where(np.isfinite(dt), dt, 0.0)
        pose = displace(pose, dt)
    ok = res < 1e-8
    return SpatialFK(poses=np.where(ok[..., None], pose, np.nan), converged=ok, residual=res, iterations=step)


# ---------------------------------------------------------------------------------------------- FK: every mode
@dataclass(frozen=True)
class SpatialModes:
    """Every real assembly mode for one set of actuator values.

    Attributes
    ----------
    poses : ``(k, 6)``
        The modes, by increasing z.
    within_limits : bool ``(k,)``
        Every leg on the file's working mode and every joint limit satisfied.
    working_modes : ``(k, n)``
        Each leg's branch (:func:`working_modes`).
    method : str
        How they were found (one line).
    complete : bool
        The method finds every mode (``False`` only if a homotopy path failed, said in ``method``).
    """

    poses: np.ndarray
    within_limits: np.ndarray
    working_modes: np.ndarray
    method: str
    complete: bool = True


def _three_spheres(centres: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Both intersections ``(2, 3)`` of three spheres (NaN when they do not meet): trilateration in the frame of
    the centres (``x`` along ``c1 - c0``, ``y`` in their plane, ``z`` normal)."""
    c0, c1, c2 = centres
    ex = c1 - c0
    d = np.linalg.norm(ex)
    ex = ex / d
    i = ex @ (c2 - c0)
    ey = c2 - c0 - i * ex
    j = np.linalg.norm(ey)
    if d < 1e-12 or j < 1e-12:
        raise NoSolutionError("the three spheres' centres are collinear: forward kinematics is degenerate")
    ey = ey / j
    ez = np.cross(ex, ey)
    r0, r1, r2 = radii
    x = (r0 ** 2 - r1 ** 2 + d ** 2) / (2 * d)
    y = (r0 ** 2 - r2 ** 2 + i ** 2 + j ** 2 - 2 * i * x) / (2 * j)
    z2 = r0 ** 2 - x ** 2 - y ** 2
    if z2 < -1e-9 * max(1.0, r0 ** 2):
        return np.full((0, 3), np.nan)
    z = np.sqrt(max(z2, 0.0))
    base = c0 + x * ex + y * ey
    return np.array([base + z * ez, base - z * ez]) if z > 0 else base[None]


def assembly_modes(robot: SpatialManipulator, q) -> SpatialModes:
    """Every real assembly mode of the actuated values ``q`` ``(n,)``.

    Delta and 3-UPU (pure translation): the point ``p`` lies on three spheres (for leg ``i`` centred at
    ``C_i(theta_i) - b_i`` with radius ``rod``, or at ``A_i - b_i`` with radius ``q_i``): at most two modes, in
    closed form. 6-UPS, 3-RPS, 3-PRS: the six closure equations are spheres and planes in the pose, solved for
    every real solution by a total-degree homotopy in Study parameters
    (:func:`pmaccuracy.kinematics.assembly_modes.assembly_modes`; up to 40 modes for a 6-UPS, 16 for a 3-RPS).
    """
    q = np.asarray(q, dtype=float)
    if q.shape == (robot.n_actuators,):
        check_angle_values(q[[k == "R" for k in robot.actuated_kinds]], "q (revolute actuators)", "arm angles")
    if q.shape != (robot.n_actuators,) or not np.all(np.isfinite(q)):
        raise PoseError(f"a {robot.architecture} takes {robot.n_actuators} finite actuator values, got "
                        f"{q.tolist() if q.size < 20 else q.shape}")
    complete = True
    if robot.is_chain:
        poses, method = _chain_modes(robot, q)
        complete = False
    elif robot.mobility == "3T":
        centres, radii = [], []
        for leg, qi in zip(robot.legs, q):
            if isinstance(leg, DeltaLeg):
                centres.append(leg.elbow(qi) - np.asarray(leg.platform))
                radii.append(leg.rod)
            else:
                if qi <= 0:
                    raise PoseError(f"a leg length must be positive, got {qi}")
                centres.append(np.asarray(leg.base) - np.asarray(leg.platform))
                radii.append(qi)
        p = _three_spheres(np.array(centres), np.array(radii))
        poses = np.concatenate([p, np.zeros_like(p)], axis=-1)
        method = "intersection of three spheres (closed form)"
    else:
        spheres, planes = [], []
        for leg, qi in zip(robot.legs, q):
            if leg.ARCHITECTURE == "3-PRS":
                if not np.isfinite(qi):
                    raise PoseError("actuator values must be finite")
                spheres.append((leg.carriage(qi), np.asarray(leg.platform), leg.rod))
            else:
                if qi <= 0:
                    raise PoseError(f"a leg length must be positive, got {qi}")
                spheres.append((np.asarray(leg.base), np.asarray(leg.platform), qi))
            if leg.ARCHITECTURE in ("3-RPS", "3-PRS"):
                planes.append((np.asarray(leg.axis), np.asarray(leg.base), np.asarray(leg.platform)))
        found = solve_modes(spheres, planes or None)
        poses = np.concatenate([found.positions, rotvecs(found.rotations)], axis=-1) if found.count else \
            np.zeros((0, 6))
        method = found.method
        if found.failed:
            method += f" ({found.failed} of {found.paths} paths failed: modes may be missing)"
            complete = False
        if poses.shape[0]:
            # the homotopy's modes satisfy the geometric equations; keep those on the actuators' own branch
            # (a 3-PRS slide has two solutions per rod sphere) and polish them on the robot's own closure
            fk = forward_kinematics(robot, np.broadcast_to(q, (poses.shape[0], robot.n_actuators)), poses)
            poses = fk.poses[fk.converged]
    if poses.shape[0] == 0:
        return SpatialModes(poses=np.zeros((0, 6)), within_limits=np.zeros(0, dtype=bool),
                            working_modes=np.zeros((0, robot.n_legs), dtype=int), method=method,
                            complete=complete)
    modes = working_modes(robot, poses, q)
    ik = inverse_kinematics(robot, poses)
    own = np.all(modes == np.array([getattr(leg, "mode", 1) for leg in robot.legs]), axis=-1)
    if robot.is_chain:
        # a chain's inverse kinematics follows its legs' branch from home: other branches give other values
        scale = np.maximum(1.0, np.abs(q))
        own &= np.all(np.abs(np.nan_to_num(ik.q, nan=np.inf) - q) <= 1e-6 * scale, axis=-1)
    within = own & np.asarray(ik.within_limits)
    order = np.lexsort((poses[:, 0], poses[:, 1], poses[:, 2]))
    return SpatialModes(poses=poses[order], within_limits=within[order], working_modes=modes[order], method=method,
                        complete=complete)


#: Starts of the Newton search for a chain robot's assembly modes.
CHAIN_MODE_STARTS = 32


def _chain_modes(robot: SpatialManipulator, q: np.ndarray) -> tuple[np.ndarray, str]:
    """Assembly modes of a chain robot: Newton from :data:`CHAIN_MODE_STARTS` starts (the home pose, its mirror
    image through the base plane and seeded random poses within the legs' reach), distinct converged poses kept.
    Not a proof of completeness (the designer leg types have one; chains have no closed-form equations)."""
    home = _home_or_zero(robot)
    reach = max(float(np.max(np.linalg.norm(np.array([leg.base for leg in robot.legs]), axis=-1))),
                float(np.linalg.norm(home[:3])), 1.0)
    rng = np.random.default_rng(0)
    m = len(CONTROLLED[robot.mobility])
    starts = np.zeros((CHAIN_MODE_STARTS, 6))
    starts[0] = home
    starts[1] = home * np.array([1, 1, -1, -1, -1, 1])
    starts[2:, :3] = home[:3] + rng.uniform(-reach, reach, (CHAIN_MODE_STARTS - 2, 3))
    if m > 3 or robot.mobility == "2R1T":
        starts[2:, 3:] = rng.normal(0.0, 0.5, (CHAIN_MODE_STARTS - 2, 3))
    fk = forward_kinematics(robot, np.broadcast_to(q, (CHAIN_MODE_STARTS, robot.n_actuators)), starts)
    found = fk.poses[fk.converged]
    kept: list[np.ndarray] = []
    for pose in found:
        if all(np.max(np.abs(pose[:3] - k[:3])) > 1e-6 * reach or
               np.max(np.abs(rotations(pose[3:]) - rotations(k[3:]))) > 1e-6 for k in kept):
            kept.append(pose)
    poses = np.array(kept) if kept else np.zeros((0, 6))
    return poses, (f"Newton from {CHAIN_MODE_STARTS} starts ({len(kept)} distinct modes; not a proof that none is "
                   "missing)")


def working_modes(robot: SpatialManipulator, poses: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Each leg's working mode ``(..., n)`` at poses with actuated values ``q``: a Delta's sign of
    ``((C - A) x (B - A)) . axis``, a 3-PRS's sign of ``slide . (B - C)``, +1 for the legs with one branch."""
    p, R, _ = _split(np.asarray(poses, dtype=float))
    out = []
    for i, leg in enumerate(robot.legs):
        qi = np.asarray(q, dtype=float)[..., i]
        B = leg.platform_point(p, R)
        if isinstance(leg, DeltaLeg):
            v = np.sum(np.cross(leg.elbow(qi) - np.asarray(leg.base), B - np.asarray(leg.base)) * np.asarray(leg.axis),
                       axis=-1)
        elif leg.ARCHITECTURE == "3-PRS":
            v = np.sum(np.asarray(leg.slide) * (B - leg.carriage(qi)), axis=-1)
        else:
            v = np.ones(B.shape[:-1])
        out.append(np.where(v >= 0, 1, -1))
    return np.stack(out, axis=-1)


# ---------------------------------------------------------------------------------------------- Jacobians
@dataclass(frozen=True)
class SpatialJacobians:
    """Jacobians of poses from the legs' wrenches (screw theory).

    Attributes
    ----------
    wrenches, gains : ``(..., 6, 6)`` and ``(..., 6, n)``
        ``W`` and ``G`` of the closure (:class:`Closure`).
    actuation : ``(..., n, 6)``
        Actuation wrenches ``a_i``: ``a_i . t = q_dot_i`` for every twist the robot can make (the rows of the
        inverse Jacobian).
    constraint : ``(..., 6 - n, 6)``
        Constraint wrenches ``c``: ``c . t = 0`` for every twist it can make (none for a 6-UPS).
    overall : ``(..., 6, 6)``
        ``J_x = [actuation; constraint]``, ``J_x t = [q_dot; 0]``.
    forward : ``(..., 6, n)``
        ``J = W^-1 G``: the platform twist ``t = J q_dot`` (NaN at a parallel singularity).
    """

    wrenches: np.ndarray
    gains: np.ndarray
    actuation: np.ndarray
    constraint: np.ndarray
    overall: np.ndarray
    forward: np.ndarray

    @property
    def inverse(self) -> np.ndarray:
        """``(..., n, 6)``: ``q_dot = J_inv t`` (the actuation wrenches)."""
        return self.actuation


def _split_leg_rows(W: np.ndarray, G: np.ndarray, legs: np.ndarray, n: int):
    """Per leg with rows ``r_k`` and gains ``g_k`` (on its own actuator): the actuation wrench
    ``sum g_k r_k / sum g_k^2`` and, for two rows, the constraint wrench ``g_2 r_1 - g_1 r_2`` (reciprocal to
    every twist the leg allows)."""
    act, con = [], []
    for i in range(n):
        rows = np.flatnonzero(legs == i)
        g = G[..., rows, i]
        r = W[..., rows, :]
        with np.errstate(invalid="ignore", divide="ignore"):
            act.append(np.sum(g[..., None] * r, axis=-2) / np.sum(g * g, axis=-1)[..., None])
        if len(rows) == 2:
            con.append(g[..., 1, None] * r[..., 0, :] - g[..., 0, None] * r[..., 1, :])
    a = np.stack(act, axis=-2)
    c = np.stack(con, axis=-2) if con else np.zeros(W.shape[:-2] + (0, 6))
    if c.shape[-2]:
        c = c / np.linalg.norm(c, axis=-1, keepdims=True)
    return a, c


def jacobians(robot: SpatialManipulator, poses) -> SpatialJacobians:
    """The Jacobians of poses ``(..., 6)`` (:class:`SpatialJacobians`), from the closure wrenches at the poses'
    own actuated values.

    >>> robot = SpatialManipulator.preset("delta_clavel")
    >>> jac = jacobians(robot, robot.home_pose)
    >>> jac.forward.shape, jac.constraint.shape
    ((6, 3), (3, 6))
    """
    poses = as_spatial_poses(poses)
    p, R, _ = _split(poses)
    cl = closure(robot, poses, _actuate(robot, p, R))   # the actuated values only: no constraint residuals
    a, c = _split_leg_rows(cl.wrenches, cl.gains, cl.leg_of_row, robot.n_actuators)
    with np.errstate(invalid="ignore", divide="ignore"):
        try:
            J = np.linalg.solve(cl.wrenches, cl.gains)
        except np.linalg.LinAlgError:
            J = _solve_or_nan(cl.wrenches, cl.gains)
    return SpatialJacobians(wrenches=cl.wrenches, gains=cl.gains, actuation=a, constraint=c,
                            overall=np.concatenate([a, c], axis=-2), forward=J)


def _solve_or_nan(W: np.ndarray, G: np.ndarray) -> np.ndarray:
    flatW = W.reshape(-1, 6, 6)
    flatG = G.reshape(-1, 6, G.shape[-1])
    out = np.full(flatG.shape, np.nan)
    ok = np.all(np.isfinite(flatW), axis=(-1, -2)) & (np.abs(np.linalg.det(np.nan_to_num(flatW))) > 0)
    if np.any(ok):
        try:
            out[ok] = np.linalg.solve(flatW[ok], flatG[ok])
        except np.linalg.LinAlgError:
            for k in np.flatnonzero(ok):
                try:
                    out[k] = np.linalg.solve(flatW[k], flatG[k])
                except np.linalg.LinAlgError:
                    pass
    return out.reshape(G.shape)


# ---------------------------------------------------------------------------------------------- singularities
@dataclass(frozen=True)
class SpatialSingularity:
    """Distances to the three kinds of singularity at poses, each dimensionless, 0 at the singularity.

    Attributes
    ----------
    parallel : ``(...)``
        Smallest singular value of the homogenized, row-normalized ``W`` (moments divided by the
        characteristic length ``L``): 0 where the platform gains a motion with the actuators locked.
    constraint : ``(...)``
        The same for the constraint wrenches alone (lower-mobility robots; 1 for a 6-UPS): 0 where the legs'
        constraints lose rank (the platform gains a motion it should not have).
    serial : ``(..., n)``
        Each leg's transmission ``|g| / g_max`` in [0, 1] (a Delta arm's gain over its length, a 3-PRS rod's
        sine to the slide): 0 where an actuator loses control of its leg.
    condition : ``(...)``
        Condition number of the homogenized ``W`` (>= 1, ``inf`` when singular); :attr:`dexterity` is its
        inverse.
    """

    parallel: np.ndarray
    constraint: np.ndarray
    serial: np.ndarray
    condition: np.ndarray

    @property
    def dexterity(self) -> np.ndarray:
        return 1.0 / self.condition

    @property
    def distance(self) -> np.ndarray:
        """The smallest of the three measures, ``(...)``."""
        return np.minimum(np.minimum(self.parallel, self.constraint), np.min(self.serial, axis=-1))


def _homogenized(robot: SpatialManipulator, W: np.ndarray) -> np.ndarray:
    H = W * np.array([1.0, 1.0, 1.0] + [1.0 / robot.characteristic_length] * 3)
    with np.errstate(invalid="ignore", divide="ignore"):
        return H / np.linalg.norm(H, axis=-1, keepdims=True)


def singularity(robot: SpatialManipulator, poses) -> SpatialSingularity:
    """The distances of poses ``(..., 6)`` to the serial, parallel and constraint singularities
    (:class:`SpatialSingularity`). NaN-free: a pose no leg reaches gives 0 everywhere."""
    poses = as_spatial_poses(poses)
    jac = jacobians(robot, poses)
    H = _homogenized(robot, jac.wrenches)
    ok = np.all(np.isfinite(H), axis=(-1, -2))
    s = np.linalg.svd(np.where(ok[..., None, None], H, 0.0), compute_uv=False)
    parallel = np.where(ok, s[..., -1], 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        cond = np.where(ok & (s[..., -1] > 0), s[..., 0] / s[..., -1], np.inf)
    if jac.constraint.shape[-2]:
        C = _homogenized(robot, jac.constraint)
        okc = np.all(np.isfinite(C), axis=(-1, -2))
        sc = np.linalg.svd(np.where(okc[..., None, None], C, 0.0), compute_uv=False)
        constraint = np.where(okc, sc[..., -1], 0.0)
    else:
        constraint = np.ones(poses.shape[:-1])
    serial = _transmission(robot, jac)
    return SpatialSingularity(parallel=parallel, constraint=constraint, serial=serial, condition=cond)


def _transmission(robot: SpatialManipulator, jac: SpatialJacobians) -> np.ndarray:
    out = []
    row = 0
    for i, leg in enumerate(robot.legs):
        g = jac.gains[..., row:row + leg.ROWS, i]
        row += leg.ROWS
        scale = leg.arm if isinstance(leg, DeltaLeg) else 1.0
        with np.errstate(invalid="ignore"):
            t = np.sqrt(np.sum(g * g, axis=-1) / leg.ROWS) / scale if isinstance(leg, DeltaLeg) else \
                np.max(np.abs(g), axis=-1) / scale
        out.append(np.where(np.isfinite(t), np.minimum(t, 1.0), 0.0))
    return np.stack(out, axis=-1)


# ---------------------------------------------------------------------------------------------- checks
def reference_pose(robot: SpatialManipulator) -> np.ndarray:
    """A pose to start from ``(6,)``: the file's home pose (its parasitic motions solved for a 3-RPS/3-PRS), else
    the pose within the joint limits on the base's z-axis with zero orientation nearest the middle of the
    reachable heights (:func:`check_reachable` finds it)."""
    if robot.home_pose is not None:
        home = robot.home_pose
        if robot.is_chain:
            return home
        if robot.mobility == "2R1T":
            return complete_poses(robot, controlled_coordinates(robot, home))
        if robot.mobility == "3T":
            return np.concatenate([home[:3], np.zeros(3)])
        return home
    return _axis_search(robot)


def _axis_search(robot: SpatialManipulator) -> np.ndarray:
    size = max(max(np.linalg.norm(leg.base), np.linalg.norm(leg.platform)) for leg in robot.legs)
    reach = max(float(np.max(np.abs(robot.strokes))) if robot.actuated_kinds[0] == "P" else 0.0,
                sum(getattr(robot.legs[0], k, 0.0) for k in ("arm", "rod")), size)
    z = np.linspace(-3 * reach, 3 * reach, 2401)
    if robot.mobility == "2R1T":
        try:
            poses = complete_poses(robot, np.stack([z, 0 * z, 0 * z], -1))
        except NoSolutionError:
            poses = np.stack([0 * z, 0 * z, z, 0 * z, 0 * z, 0 * z], -1)
    else:
        poses = np.stack([0 * z, 0 * z, z, 0 * z, 0 * z, 0 * z], -1)
    ok = inverse_kinematics(robot, poses).within_limits
    if not np.any(ok):
        return poses[len(z) // 2] * np.nan
    idx = np.flatnonzero(ok)
    return poses[idx[len(idx) // 2]]


def check_reachable(robot: SpatialManipulator, source: str | None = None) -> None:
    """Raise :class:`~pmaccuracy.errors.GeometryError` naming the file when the robot's home pose (if given)
    violates a joint limit, or when no pose on the base's z-axis with zero orientation lies within them."""
    where = source or robot.name
    if robot.home_pose is not None:
        try:
            home = reference_pose(robot)
        except NoSolutionError as exc:
            raise GeometryError(f"the home pose cannot be assembled ({exc})", source=where, key="home") from None
        ik = inverse_kinematics(robot, home)
        if not bool(ik.within_limits):
            raise GeometryError("the home pose is outside the joint limits: " + "; ".join(ik.violations()),
                                source=where, key="home")
        return
    if not np.all(np.isfinite(_axis_search(robot))):
        raise GeometryError("unreachable geometry: no pose on the base's z-axis with zero orientation lies within "
                            "the joint limits (check the points, strokes and cones, or give a [home] pose)",
                            source=where, key="legs")
