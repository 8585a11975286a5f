"""Exact first-order worst-case pose errors of spatial robots (issue 37, first part).

At a pose the legs' closure gives ``W t = G dq`` (:mod:`pmaccuracy.kinematics.spatial`). A small displacement
twist ``xi`` of a joint's distal part relative to its proximal part (a clearance, a tolerance) adds ``w . xi`` to
every closure row ``w`` of its leg (a Delta's ball: the row of its own rod), as any joint in series does, and an
actuator error adds like ``dq``. Each source ``s`` (``docs/guide/spatial-errors.md``) is a unit segment, disc or
ball scaled by its half-width ``h_s`` with generator twists ``Xi_s`` ``(6, d_s)`` (at P, base frame), so

    t = sum_s M_s x_s,   M_s = h_s W^-1 E_s,   E_s = rows_of_its_leg(W) Xi_s,   |x_s| <= 1          (1)

exactly at first order. The worst error of each twist component is the sum of the sources' support functions,
``dx_max = sum_s |M_s[0, :]|_2`` (and so on for dy, dz and the three small rotations), attained; the worst
position error ``|dp|`` and rotation angle ``|dtheta|`` are the largest norms of the Minkowski sums
``sum_s M_s[:3] B`` and ``sum_s M_s[3:] B``, computed by :func:`pmaccuracy.numerics.support.max_norm`: exact
for segments only (a zonotope), otherwise certified to a stated relative gap (default 0.1 %) with the
configuration that attains the lower value.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError, OutsideJointLimitsError, SingularPoseError
from ..kinematics.spatial import (LIMIT_TOLERANCE, as_spatial_poses, closure, inverse_kinematics, leg_interference,
                                  reference_pose)
from ..model.plausibility import check_angle_values, rotation_angles
from ..model.spatial import SpatialManipulator
from ..model.spatial_legs import DeltaLeg, PRSLeg, RPSLeg, UPSLeg, UPULeg
from ..model.spatial_chain import ChainLeg
from ..model.spatial_sources import JOINTS, SpatialErrorSources
from ..numerics.spatial import normalize, rotations, rotvec_to_euler_xyz
from ..numerics.support import max_norm

#: Names of the six error components: position (mm) then small rotations (rad) about the base axes.
COMPONENTS = ("dx", "dy", "dz", "drx", "dry", "drz")
#: Poses per chunk of a large batch without details (cache-sized arrays).
CHUNK = 1 << 15
#: Default relative gap of the certified |dp| and |dtheta| (0.1 %).
DEFAULT_GAP = 1e-3
#: Poses whose homogenized closure matrix has a larger (1-norm) condition number are refused as near-singular.
MAX_CONDITION = 1e4


@dataclass(frozen=True)
class Source:
    """One error source at the poses: where it is, its shape and its contribution ``M_s`` ``(..., 6, d)``
    (already scaled by its half-width)."""

    leg: int
    joint: int
    key: str
    shape: str            # "segment", "disc" or "ball"
    half_width: float
    rows: tuple[int, int]   # the closure rows of its leg (start, stop)
    E: np.ndarray = field(repr=False)      # (..., k, d) its image in its leg's closure rows, times h
    winv: np.ndarray = field(repr=False)   # (..., 6, 6) W^-1 at the poses
    part: int | None = None   # a universal joint's pin (1 or 2) for its radial and axial plays

    @property
    def matrix(self) -> np.ndarray:
        """``M_s`` ``(..., 6, d)`` of Eq. 1 (scaled by the half-width)."""
        return self.winv[..., :, self.rows[0]:self.rows[1]] @ self.E

    @property
    def label(self) -> str:
        pin = f"[pin {self.part}]" if self.part else ""
        return f"legs[{self.leg + 1}].joints[{self.joint + 1}].{self.key}{pin}"


@dataclass(frozen=True)
class SpatialPoseErrors:
    """Worst-case first-order errors at a batch of poses.

    Attributes
    ----------
    components : ``(..., 6)``
        The largest ``|dx|, |dy|, |dz|`` (mm) and ``|drx|, |dry|, |drz|`` (rad): exact.
    dp_upper, dp_lower : ``(...)``
        The largest position error ``|dp|`` (mm): an upper bound and an attained value (equal for a
        zonotope); ``dtheta_upper``, ``dtheta_lower`` (rad) the same for the rotation angle.
    dp_certified, dtheta_certified : bool ``(...)``
        Whether the gap was reached.
    dp_direction : ``(..., 3)``
        The direction of the attained worst position error.
    sources : list
        The :class:`Source` list (their matrices give per-source shares); empty without details.
    gap : float
        The relative gap asked for.
    """

    poses: np.ndarray
    components: np.ndarray
    dp_upper: np.ndarray
    dp_lower: np.ndarray
    dtheta_upper: np.ndarray
    dtheta_lower: np.ndarray
    dp_certified: np.ndarray
    dtheta_certified: np.ndarray
    dp_direction: np.ndarray
    sources: list = field(repr=False)
    gap: float = DEFAULT_GAP

    def shares(self) -> dict[str, np.ndarray]:
        """Each source's share of each component's worst case ``{label: (..., 6)}`` (they add up to
        :attr:`components`)."""
        return {s.label: np.linalg.norm(s.matrix, axis=-1) for s in self.sources}


# ---------------------------------------------------------------------------------------------- generators
def _normals(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors normal to ``axis`` ``(..., 3)`` and to each other."""
    axis = np.asarray(axis, dtype=float)
    helper = np.where(np.abs(axis[..., :1]) < 0.9, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
    e1 = normalize(np.cross(axis, helper))
    return e1, np.cross(axis, e1)


@dataclass(frozen=True)
class _Generators:
    """A source's generator twists ``xi_c = [v_c, w_c]`` (at P, base frame), kept as their parts:
    translations ``v_c = dirs[c]`` (``centre`` None) or rotations ``w_c = dirs[c]`` about an axis through
    ``centre``, ``v_c = w_c x (P - centre)``."""

    dirs: list
    centre: np.ndarray | None = None
    p: np.ndarray | None = None

    @property
    def d(self) -> int:
        return len(self.dirs)

    def rows(self, Wleg: np.ndarray) -> np.ndarray:
        """``Wleg xi`` ``(..., k, d)``: the closure rows' reciprocal products with each generator."""
        f, m = Wleg[..., :3], Wleg[..., 3:]
        cols = []
        for w in self.dirs:
            if self.centre is None:
                v, w_part = w, None
            else:
                v, w_part = np.cross(w, self.p - self.centre), w
            if isinstance(v, np.ndarray) and v.ndim == 1:
                col = f @ v
            else:
                col = np.einsum("...rk,...k->...r", f, v)
            if w_part is not None:
                col = col + (m @ w_part if np.ndim(w_part) == 1 else np.einsum("...rk,...k->...r", m, w_part))
            cols.append(col)
        return np.stack(cols, axis=-1)


def _translation(dirs: list[np.ndarray]) -> _Generators:
    """Translations along ``dirs`` (each ``(3,)`` or ``(..., 3)``)."""
    return _Generators(list(dirs))


def _rotation(dirs: list[np.ndarray], centre: np.ndarray, p: np.ndarray) -> _Generators:
    """Unit rotations about ``dirs`` through ``centre``: twists ``[w x (P - C), w]`` at P."""
    return _Generators(list(dirs), centre, p)


_SHAPES = {1: "segment", 2: "disc", 3: "ball"}
_BASIS = [np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), np.array([0, 0, 1.0])]


def _revolute(key: str, axis: np.ndarray, centre: np.ndarray, p: np.ndarray) -> _Generators:
    """A revolute's sources about its pin (axis ``axis`` through ``centre``): radial (a disc of translations
    normal to the axis), axial (along it), tilt and direction (rotations about the two normals)."""
    n1, n2 = _normals(axis)
    if key == "radial":
        return _translation([n1, n2])
    if key == "axial":
        return _translation([axis])
    if key in ("tilt", "direction"):
        return _rotation([n1, n2], centre, p)
    raise ConfigError(f"no {key!r} source on a revolute")


def _universal_axes(d, ref_dir, fixed_axis):
    """The axes of a universal joint on a leg along ``d`` ``(..., 3)``: ``u1`` (fixed to its body; without one,
    a 6-UPS's horizontal axis normal to the leg's direction ``ref_dir`` at the reference pose), ``u2`` normal to
    ``u1`` and to the leg, and the normal of the cross ``u1 x u2``."""
    if fixed_axis is None:      # a 6-UPS without base_axis: horizontal, normal to the leg at the reference pose
        u = np.cross([0.0, 0.0, 1.0], ref_dir)
        fixed_axis = u / np.linalg.norm(u) if np.linalg.norm(u) > 1e-9 else np.array([1.0, 0.0, 0.0])
    u1 = np.broadcast_to(np.asarray(fixed_axis, dtype=float), d.shape)
    u2 = normalize(np.cross(u1, d))
    return u1, u2, normalize(np.cross(u1, u2))


def _chain_generators(leg: ChainLeg, joint: int, key: str, p, ctx) -> _Generators:
    """Generator twists of a source on joint ``joint`` of a chain leg, at the leg's solved configuration
    (``ctx["chain"]``: :meth:`~pmaccuracy.model.spatial_chain.ChainLeg.solve`): the joint's centre moved by the
    joints before it, its current axes from the leg's Jacobian columns. The sets are the designer types' (module
    text): an R, U or C pin's radial disc(s), axial play and tilt, a slide's lateral disc, tilt and axial
    actuator error, a ball, position and direction tolerances (a U joint's direction: its proximal axis); an
    actuated R joint's ``actuator``/``backlash`` a rotation about its axis."""
    _, _, _, J, prefixes = ctx["chain"]
    spec = leg.joints[joint]
    Rp, tp = prefixes[joint]
    centre = np.einsum("...ij,j->...i", Rp, np.asarray(spec.centre, dtype=float)) + tp
    first = sum(j.dof for j in leg.joints[:joint])
    cols = J[..., :, first:first + spec.dof]                 # (..., 6, dof) twists [v_O, w]
    if key == "position" or spec.kind == "S":
        return _Generators(_BASIS)
    if spec.kind == "P":                    # the block rides with the slide: its centre moves with the joint
        if joint + 1 < len(prefixes):
            Rn, tn = prefixes[joint + 1]
            centre = np.einsum("...ij,j->...i", Rn, np.asarray(spec.centre, dtype=float)) + tn
        axis = normalize(cols[..., :3, 0])
        if key in ("actuator", "backlash"):
            return _translation([axis])
        n1, n2 = _normals(axis)
        if key == "lateral":
            return _translation([n1, n2])
        return _rotation([n1, n2], centre, p)                 # tilt, direction: about the block's centre
    axis = normalize(cols[..., 3:, 0])
    if key in ("actuator", "backlash"):
        return _rotation([axis], centre, p)
    if spec.kind in ("R", "C"):
        return _revolute(key, axis, centre, p)
    u1, u2 = axis, normalize(cols[..., 3:, 1])                # a universal joint's two pins
    if key == "radial":
        n11, n12 = _normals(u1)
        n21, n22 = _normals(u2)
        return _translation([n11, n12, n21, n22])
    if key == "axial":
        return _translation([u1, u2])
    if key == "tilt":
        return _rotation([normalize(np.cross(u1, u2))], centre, p)
    n1, n2 = _normals(u1)
    return _rotation([n1, n2], centre, p)


def _joint_generators(robot, leg_index, leg, joint, key, p, R, q, ref, ctx):
    """Generator twists of one source (:class:`_Generators`) and the leg's closure rows it acts on (indices into
    the leg's rows; ``None``: all). ``ctx``: the leg's platform point ``B`` and direction ``d`` at the poses."""
    if isinstance(leg, ChainLeg):
        return _chain_generators(leg, joint, key, p, ctx), None
    kind = JOINTS[robot.architecture][joint]
    A = np.asarray(leg.base, dtype=float)
    B = ctx["B"]
    rows = None
    if isinstance(leg, DeltaLeg):
        a = np.asarray(leg.axis)
        C, Bs = leg.balls(p, R, q)
        rod = (joint - 1) // 2 if joint > 0 else None
        if joint == 0:
            centre = np.broadcast_to(A, B.shape)
            axis = np.broadcast_to(a, B.shape)
        else:
            rows = [rod]
            centre = C[..., rod, :] if joint in (1, 3) else Bs[..., rod, :]
        if key == "position" or (kind == "S" and key == "radial"):
            return _Generators(_BASIS), rows
        if key == "actuator":
            return _rotation([axis], centre, p), rows
        if key == "length":
            if joint == 0:
                return _translation([leg.arm_direction(q)]), rows
            return _translation([normalize(Bs[..., rod, :] - C[..., rod, :])]), rows
        return _revolute(key, axis, centre, p), rows
    d = ctx["d"]
    ref_dir = normalize(leg.platform_point(ref[:3], rotations(ref[3:])) - A)
    if key == "length":          # the link after a base joint or a slide: the leg (a 3-PRS: the slide, the rod)
        if isinstance(leg, PRSLeg):
            return _translation([normalize(B - leg.carriage(q)) if kind == "R" else
                                 np.broadcast_to(np.asarray(leg.slide), B.shape)]), rows
        return _translation([d]), rows
    if kind == "S":
        return _Generators(_BASIS), rows
    if key == "position":
        return _Generators(_BASIS), rows
    if kind == "P":
        if isinstance(leg, PRSLeg):
            axis = np.broadcast_to(np.asarray(leg.slide), B.shape)
            centre = leg.carriage(q)
            origin = np.broadcast_to(A, B.shape)
        else:
            axis, centre, origin = d, 0.5 * (A + B), np.broadcast_to(A, B.shape)
        if key in ("actuator", "backlash"):
            return _translation([axis]), rows
        n1, n2 = _normals(axis)
        if key == "lateral":
            return _translation([n1, n2]), rows
        if key == "tilt":
            return _rotation([n1, n2], centre, p), rows
        if key == "direction":
            return _rotation([n1, n2], origin, p), rows
    if kind == "R":
        centre = leg.carriage(q) if isinstance(leg, PRSLeg) else np.broadcast_to(A, B.shape)
        return _revolute(key, np.broadcast_to(np.asarray(leg.axis), B.shape), centre, p), rows
    if kind == "U":
        at_base = joint == 0
        if at_base:
            centre = np.broadcast_to(A, B.shape)
            u1, u2, m = _universal_axes(d, ref_dir, leg.base_axis)
            fixed = u1
        else:   # the platform joint of a 3-UPU: its leg-side axis u3 normal to the leg and the platform's u4
            centre = B
            u4 = R @ np.asarray(leg.platform_axis)
            u3 = normalize(np.cross(u4, d))
            u1, u2, m, fixed = u3, u4, normalize(np.cross(u3, u4)), u4
        if key == "radial":
            n11, n12 = _normals(u1)
            n21, n22 = _normals(u2)
            return _translation([n11, n12, n21, n22]), rows      # two discs (split below)
        if key == "axial":
            return _translation([u1, u2]), rows                  # two segments
        if key == "tilt":
            return _rotation([m], centre, p), rows
        if key == "direction":
            n1, n2 = _normals(fixed)
            return _rotation([n1, n2], centre, p), rows
    raise ConfigError(f"no {key!r} source on joint {joint + 1} of a {robot.architecture} leg")


def _condition(robot: SpatialManipulator, W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The 1-norm condition number of ``W`` homogenized (moments over the characteristic length ``L``) with its
    rows normalized, ``||H||_1 ||H^-1||_1`` (``inf`` where singular), and ``W^-1``: ``H = N W D`` so
    ``H^-1 = D^-1 W^-1 N^-1`` costs no second inversion."""
    D = np.array([1.0, 1.0, 1.0] + [1.0 / robot.characteristic_length] * 3)
    absWD = np.abs(W) * D
    norms = np.sqrt(np.einsum("...ij,...ij->...i", absWD, absWD))   # (..., 6) row norms: N = diag(1 / norms)
    try:
        Winv = np.linalg.inv(W)
    except np.linalg.LinAlgError:
        ok = np.abs(np.linalg.det(W)) > 0
        Winv = np.full(W.shape, np.nan)
        Winv[ok] = np.linalg.inv(W[ok])
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        # ||H||_1: column sums of |W_kj| D_j / norms_k; ||H^-1||_1: column sums of |Winv_ik| / D_i times norms_k
        h = np.max(np.einsum("...kj,...k->...j", absWD, 1.0 / norms), axis=-1)
        hinv = np.max(np.einsum("...ik,i->...k", np.abs(Winv), 1.0 / D) * norms, axis=-1)
        cond = h * hinv
    return np.where(np.isfinite(cond), cond, np.inf), Winv


def _shown(pose: np.ndarray) -> str:
    """A pose in words: ``(x, y, z mm, roll, pitch, yaw deg)``."""
    c = np.concatenate([pose[:3], rotvec_to_euler_xyz(pose[3:], degrees=True)])
    return "(x, y, z, roll, pitch, yaw) = (" + ", ".join(f"{float(v):.6g}" for v in c) + ")"


def _hexapod_fast(robot: SpatialManipulator, sources: SpatialErrorSources, poses: np.ndarray, strict: bool,
                  allow_outside: bool):
    """A 6-UPS's error set without per-source data in one pass over all legs (the same numbers as the general
    construction, which :func:`error_sources_at` falls back to for its messages): leg lengths ``L_i = |B_i - A_i|``,
    directions ``u_i``, the stroke and cone limits as ``lo <= L_i <= hi`` and ``u . n >= cos(cone)`` (a margin of
    1e-12 sends boundary cases to the general check), the legs' capsules apart, ``W`` rows ``[u_i, (B_i - p) x
    u_i]``, :func:`_condition` and the segments ``rho_i`` of :func:`_hexapod_blocks`. Returns ``(blocks, info)``
    or ``None`` where the general path must decide (a strict call with a pose outside the limits or singular)."""
    lead = poses.shape[:-1]
    P = poses.reshape(-1, 6)
    p, R = P[:, :3], rotations(P[:, 3:])
    legs = robot.legs
    A = np.array([leg.base for leg in legs])                               # (6, 3)
    Bp = np.einsum("nij,kj->nki", R, np.array([leg.platform for leg in legs]))
    B = p[:, None, :] + Bp                                                 # (N, 6, 3)
    d = B - A
    L = np.sqrt(np.einsum("nki,nki->nk", d, d))
    u = d / L[..., None]
    if strict and not allow_outside:
        tol = LIMIT_TOLERANCE
        lo = np.array([leg.stroke[0] - tol * max(1.0, leg.stroke[1] - leg.stroke[0]) for leg in legs])
        hi = np.array([leg.stroke[1] + tol * max(1.0, leg.stroke[1] - leg.stroke[0]) for leg in legs])
        ok = np.all((L >= lo) & (L <= hi), axis=-1)
        margin = 1e-12
        base = [k for k, leg in enumerate(legs) if leg.base_cone is not None]
        if base:
            nb = np.array([legs[k].base_normal for k in base])
            cmin = np.array([np.cos(min(legs[k].base_cone + tol, np.pi)) for k in base]) + margin
            ok &= np.all(np.einsum("nki,ki->nk", u[:, base], nb) >= cmin, axis=-1)
        plat = [k for k, leg in enumerate(legs) if leg.platform_cone is not None]
        if plat:
            npf = np.einsum("nij,kj->nki", R, np.array([legs[k].platform_normal for k in plat]))
            cmin = np.array([np.cos(min(legs[k].platform_cone + tol, np.pi)) for k in plat]) + margin
            ok &= np.all(np.einsum("nki,nki->nk", -u[:, plat], npf) >= cmin, axis=-1)
        segs = [np.stack([np.broadcast_to(A[k], B[:, k].shape), B[:, k]], axis=-2)[:, None] for k in range(len(legs))]
        for apart in leg_interference(robot, P, L, segments=segs).values():
            ok &= apart
        if not np.all(ok):
            return None
    W = np.concatenate([u, np.cross(Bp, u)], axis=-1)                      # (N, 6, 6)
    cond, Winv = _condition(robot, W)
    valid = cond <= MAX_CONDITION
    if not np.all(valid):
        if strict:
            return None
        Winv = np.linalg.inv(np.where(valid[:, None, None], W, np.eye(6)))
        Winv = np.where(valid[:, None, None], Winv, np.nan)
    const, radial, axial, u1s = hexapod_leg_terms(robot, sources)
    c = np.abs(np.einsum("nki,ki->nk", u, u1s))
    rho = const + radial * (np.sqrt(np.maximum(1.0 - c * c, 0.0)) + 1.0) + axial * c   # (N, 6)
    M = (Winv * rho[:, None, :]).reshape(lead + (6, 6))
    blocks = [M[..., :, i:i + 1] for i in range(6)]
    return blocks, {"Winv": Winv.reshape(lead + (6, 6)), "condition": cond.reshape(lead),
                    "valid": valid.reshape(lead), "sources": []}


def error_sources_at(robot: SpatialManipulator, sources: SpatialErrorSources, poses, *, strict: bool = True,
                     keep: bool = True, allow_outside: bool = False) -> tuple[list, dict]:
    """The error set at the poses, as blocks of Eq. 1, and the closure data used.

    Returns ``(blocks, info)``: ``blocks`` a list of ``(..., 6, d)`` matrices whose unit-ball images sum to the
    error set (a leg with one closure equation, a 6-UPS leg, has all its sources merged into one segment along
    its column of ``W^-1``: they can only change that equation); ``info`` holds ``Winv`` ``(..., 6, 6)``,
    ``condition``, ``valid`` (reachable and regular) and, with ``keep``, the :class:`Source` list (each
    source's own contribution, for shares and configurations). ``strict``: raise for a pose that is
    unreachable, outside the joint limits (unless ``allow_outside``: then only unreachable ones) or
    near-singular; else its blocks are NaN and ``valid`` False.
    """
    poses = as_spatial_poses(poses)
    if robot.architecture == "6-UPS" and not keep and poses.ndim > 1 and poses.size:
        fast = _hexapod_fast(robot, sources, poses, strict, allow_outside)
        if fast is not None:
            return fast
    ik = inverse_kinematics(robot, poses)
    reach = np.asarray(ik.reachable)
    if not strict and not np.all(reach):
        # evaluate the unreachable poses at a reachable one and blank them at the end
        poses = np.where(reach[..., None], poses, reference_pose(robot))
        ik = inverse_kinematics(robot, poses)
    if strict and not np.all(ik.reachable if allow_outside else ik.within_limits):
        ok = np.asarray(ik.reachable if allow_outside else ik.within_limits)
        bad = tuple(int(i) for i in np.argwhere(~ok)[0]) if poses.ndim > 1 else ()
        where = f"pose {bad[0] + 1} " if bad else "the pose "
        raise OutsideJointLimitsError(f"{where}{_shown(poses[bad])} is outside the joint limits: "
                                      + "; ".join(ik.violations(bad)))
    cl = closure(robot, poses, ik.q)
    W = cl.wrenches
    cond, Winv = _condition(robot, W)
    valid = reach & (cond <= MAX_CONDITION)
    if strict and np.any(~valid):
        bad = tuple(int(v) for v in np.argwhere(~valid)[0]) if poses.ndim > 1 else ()
        where = f"pose {bad[0] + 1} " if bad else "the pose "
        raise SingularPoseError(f"{where}{_shown(poses[bad])} is at or near a parallel or constraint "
                                f"singularity (condition number {float(np.asarray(cond)[bad]):.3g} > {MAX_CONDITION:g})")
    if not np.all(valid):
        Winv = np.linalg.inv(np.where(valid[..., None, None], W, np.eye(6)))
    if not strict:
        Winv = np.where(valid[..., None, None], Winv, np.nan)
    p, R = poses[..., :3], rotations(poses[..., 3:])
    ref = reference_pose(robot)
    if robot.architecture == "6-UPS" and not keep:
        return _hexapod_blocks(robot, sources, p, R, ref, Winv), {"Winv": Winv, "condition": cond, "valid": valid,
                                                                  "sources": []}
    blocks, kept = [], []
    row0 = 0
    for i, leg in enumerate(robot.legs):
        nrows = leg.ROWS
        Wleg = W[..., row0:row0 + nrows, :]
        cols = Winv[..., :, row0:row0 + nrows]
        B = leg.platform_point(p, R)
        ctx = {"B": B, "d": normalize(B - np.asarray(leg.base, dtype=float))}
        if isinstance(leg, ChainLeg):
            ctx["chain"] = leg.solve(p, R, ik.q[..., i])
        kinds = sources.spec(i)[0]
        merged = None
        for j, joint in enumerate(sources.legs[i]):
            for key, h in joint.items():
                kind = "actuator" if key == "backlash" and robot.actuated_kinds[i] == "R" else key
                gens, rows = _joint_generators(robot, i, leg, j, kind, p, R, ik.q[..., i], ref, ctx)
                if gens.centre is None and gens.dirs is _BASIS:
                    E = Wleg[..., :, :3].copy()
                else:
                    E = gens.rows(Wleg)
                if rows is not None:
                    E[..., [r for r in range(nrows) if r not in rows], :] = 0.0
                groups = [(0, 2), (2, 4)] if (key == "radial" and kinds[j] == "U") else \
                    [(0, 1), (1, 2)] if (key == "axial" and kinds[j] == "U") else \
                    [(0, gens.d)]
                for part, (a, b) in enumerate(groups, start=1):
                    Es = h * E[..., a:b]
                    if keep:
                        kept.append(Source(leg=i, joint=j, key=key, shape=_SHAPES[b - a], half_width=h,
                                           rows=(row0, row0 + nrows), E=Es, winv=Winv,
                                           part=part if len(groups) > 1 else None))
                    if nrows == 1:
                        norm = np.linalg.norm(Es[..., 0, :], axis=-1)
                        merged = norm if merged is None else merged + norm
                    else:
                        blocks.append(cols @ Es)
        if nrows == 1 and merged is not None:
            blocks.append(cols * merged[..., None, None])
        row0 += nrows
    return blocks, {"Winv": Winv, "condition": cond, "valid": valid, "sources": kept}


def hexapod_leg_terms(robot: SpatialManipulator, sources: SpatialErrorSources
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A 6-UPS's per-leg segment half-length ``rho_i = const_i + radial_i (sqrt(1 - c_i^2) + 1) + axial_i c_i``
    (mm) with ``c_i = |u_i . u1_i|`` (:func:`_hexapod_blocks`): returns ``const, radial, axial`` ``(6,)`` (mm) and
    the universal joints' fixed axes ``u1`` ``(6, 3)``."""
    ref = reference_pose(robot)
    n = robot.n_legs
    const, radial, axial, u1s = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros((n, 3))
    for i, leg in enumerate(robot.legs):
        A = np.asarray(leg.base, dtype=float)
        ref_dir = normalize(leg.platform_point(ref[:3], rotations(ref[3:])) - A)
        u1s[i] = _universal_axes(ref_dir[None], ref_dir, leg.base_axis)[0][0]
        for j, joint in enumerate(sources.legs[i]):
            for key, h in joint.items():
                if j == 0 and key == "radial":
                    radial[i] += h
                elif j == 0 and key == "axial":
                    axial[i] += h
                elif key in ("radial", "position", "actuator", "backlash", "length"):
                    const[i] += h
    return const, radial, axial, u1s


def _hexapod_blocks(robot, sources, p, R, ref, Winv) -> list[np.ndarray]:
    """The six segments of a 6-UPS's error set in closed form: leg ``i``'s sources act only through its length
    ``u . (B - A)``, so each adds ``h |u . xi|`` (maximized over its own set) to the segment ``rho_i`` along
    column ``i`` of ``W^-1``. With ``c = |u . u1|`` (``u1`` the universal joint's fixed axis): a universal
    joint's radial plays give ``h (sqrt(1 - c^2) + 1)`` (the disc normal to ``u1``, and the one normal to
    ``u2``, which contains the leg), its axial plays ``h c``; every ball, position tolerance, actuator error,
    backlash and length ``h``; rotations about the base joint centre (tilt, direction) and the slide's lateral
    play and tilt 0 (they move ``B`` normal to the leg, or turn the rod about its own line). The same as the
    general construction (``keep=True``), which the tests compare with it."""
    const, radial, axial, u1s = hexapod_leg_terms(robot, sources)
    blocks = []
    for i, leg in enumerate(robot.legs):
        A = np.asarray(leg.base, dtype=float)
        u = normalize(leg.platform_point(p, R) - A)
        c = np.abs(u @ u1s[i])
        rho = const[i] + radial[i] * (np.sqrt(np.maximum(1.0 - c * c, 0.0)) + 1.0) + axial[i] * c
        blocks.append(Winv[..., :, i:i + 1] * np.asarray(rho)[..., None, None])
    return blocks


def spatial_error_components(robot: SpatialManipulator, sources: SpatialErrorSources, poses, *, strict: bool = True,
                             allow_outside: bool = False) -> np.ndarray:
    """The exact worst first-order error components ``(..., 6)`` at ``poses`` ``(..., 6)``: ``|dx|, |dy|, |dz|``
    (mm) and ``|drx|, |dry|, |drz|`` (rad), each the sum of the sources' support functions (Eq. 1) without the
    certified norms ``|dp|``, ``|dtheta|`` (:func:`spatial_pose_errors` gives both). The same checks: poses outside the
    joint limits or near a singularity raise (``strict=False``: NaN there).

    >>> import pmaccuracy as pm
    >>> robot = pm.load_robot("stewart_6ups")
    >>> c = spatial_error_components(robot, pm.load_clearances("ups_typical", robot), robot.home_pose)
    >>> c.shape, bool(np.all(c > 0))
    ((6,), True)
    """
    check_angle_values(rotation_angles(poses), "poses[..., 3:] (rotation vectors)")
    if sources.architecture != robot.architecture:
        raise ConfigError(f"the error sources are of a {sources.architecture}, the robot a {robot.architecture}",
                          key="clearances")
    poses = as_spatial_poses(poses)
    if poses.ndim == 2 and poses.shape[0] > CHUNK:
        return np.concatenate([spatial_error_components(robot, sources, poses[k:k + CHUNK], strict=strict,
                                                        allow_outside=allow_outside)
                               for k in range(0, poses.shape[0], CHUNK)])
    blocks, _ = error_sources_at(robot, sources, poses, strict=strict, keep=False, allow_outside=allow_outside)
    if not blocks:
        return np.zeros(poses.shape[:-1] + (6,))
    return sum(np.abs(b[..., 0]) if b.shape[-1] == 1 else np.linalg.norm(b, axis=-1) for b in blocks)


def spatial_pose_errors(robot: SpatialManipulator, sources: SpatialErrorSources, poses, *,
                        gap: float = DEFAULT_GAP, strict: bool = True, details: bool = True,
                        allow_outside: bool = False) -> SpatialPoseErrors:
    """The worst first-order pose errors of ``robot`` with its error ``sources`` at ``poses`` ``(..., 6)``
    (Eq. 1 and the module text): exact components, ``|dp|`` and ``|dtheta|`` certified to ``gap``.

    Raises :class:`~pmaccuracy.errors.OutsideJointLimitsError` for a pose outside the joint limits (with
    ``allow_outside``: only where a leg cannot reach at all) and
    :class:`~pmaccuracy.errors.SingularPoseError` near a singularity (the first-order model is undefined there);
    ``strict=False`` gives NaN at those poses instead (maps). ``details=False`` keeps no per-source data
    (:attr:`SpatialPoseErrors.sources` empty, :meth:`~SpatialPoseErrors.shares` unavailable): large batches.
    """
    check_angle_values(rotation_angles(poses), "poses[..., 3:] (rotation vectors)")
    if not (isinstance(gap, (int, float)) and 0 < gap < 1):
        raise ConfigError(f"gap must be a fraction in (0, 1), got {gap!r}", key="gap")
    if sources.architecture != robot.architecture:
        raise ConfigError(f"the error sources are of a {sources.architecture}, the robot a {robot.architecture}",
                          key="clearances")
    poses = as_spatial_poses(poses)
    if not details and poses.ndim == 2 and poses.shape[0] > CHUNK:
        # large batches in cache-sized chunks (the same numbers)
        parts = [spatial_pose_errors(robot, sources, poses[k:k + CHUNK], gap=gap, strict=strict, details=False,
                                     allow_outside=allow_outside) for k in range(0, poses.shape[0], CHUNK)]
        cat = {f: np.concatenate([getattr(part, f) for part in parts]) for f in
               ("components", "dp_upper", "dp_lower", "dtheta_upper", "dtheta_lower", "dp_certified",
                "dtheta_certified", "dp_direction")}
        return SpatialPoseErrors(poses=poses, sources=[], gap=gap, **cat)
    blocks, info = error_sources_at(robot, sources, poses, strict=strict, keep=details, allow_outside=allow_outside)
    shape = poses.shape[:-1]
    if not blocks:
        z = np.zeros(shape)
        return SpatialPoseErrors(poses=poses, components=np.zeros(shape + (6,)), dp_upper=z, dp_lower=z,
                                 dtheta_upper=z, dtheta_lower=z, dp_certified=np.ones(shape, bool),
                                 dtheta_certified=np.ones(shape, bool), dp_direction=np.zeros(shape + (3,)),
                                 sources=info["sources"], gap=gap)
    components = sum(np.abs(b[..., 0]) if b.shape[-1] == 1 else np.linalg.norm(b, axis=-1) for b in blocks)
    valid = info["valid"]
    blocks = [np.where(valid[..., None, None], b, 0.0) for b in blocks] if not np.all(valid) else blocks
    dp = max_norm([b[..., :3, :] for b in blocks], gap=gap)
    dth = max_norm([b[..., 3:, :] for b in blocks], gap=gap)
    if not np.all(valid):
        nan = np.where(valid, 1.0, np.nan)
        dp = type(dp)(**{**dp.__dict__, "upper": dp.upper * nan, "lower": dp.lower * nan})
        dth = type(dth)(**{**dth.__dict__, "upper": dth.upper * nan, "lower": dth.lower * nan})
    return SpatialPoseErrors(poses=poses, components=components, dp_upper=dp.upper, dp_lower=dp.lower,
                             dtheta_upper=dth.upper, dtheta_lower=dth.lower, dp_certified=dp.certified,
                             dtheta_certified=dth.certified, dp_direction=dp.direction, sources=info["sources"],
                             gap=gap)
