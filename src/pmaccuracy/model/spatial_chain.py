r"""Spatial legs as serial chains of R, P, U, S and C joints: any leg a designer can draw, one numeric engine.

A :class:`ChainLeg` is a list of joints from the base to the platform, each given **at the robot's home pose**
in base coordinates (mm, unit axes): its centre (a point on its axis), its axes, its range and whether it is
the leg's actuated joint. The file format is in ``docs/guide/spatial.md`` (architecture ``"spatial-chain"``).

**Product of exponentials** (Modern Robotics, Eq. 4.14, with the home configuration as the zero one). Each
joint displaces everything beyond it: an R joint by the rotation ``Rot(a, theta)`` about its axis through ``c``,
a P joint by ``d a``, a U joint by ``Rot(a1, theta1) Rot(a2, theta2)`` (``a2`` as it is at home), a C joint by
``Rot(a, theta)`` and ``d a`` along the same line, an S joint by any rotation ``Q`` about its centre. The leg's
last body moves by

.. math::  D(\theta) = D_1(\theta_1) D_2(\theta_2) \cdots D_n(\theta_n),

and the leg is closed when ``D(theta)`` equals the platform's displacement from its home pose,
``D_P = (R R_0^T, p - R R_0^T p_0)``. Its space Jacobian has one column per freedom,
``J_k = Ad(D_1 \cdots D_{k-1}) S_k`` (Eq. 5.11), with the twists ``S = [v_O, w]`` of the home screws (``v_O``
the velocity of the point at the base origin); an S joint contributes the three rotations about its centre.

**Closure equations.** For a pose and an actuated value ``q`` the passive freedoms are solved by Gauss-Newton
on the residual twist ``xi = [t_e, rotvec(R_e)]`` of ``D_P D(theta)^{-1} = (R_e, t_e)`` (rotations weighed by the
leg's length; steps by damped normal equations, :meth:`ChainLeg._step`), from the solution of the whole chain:
Gauss-Newton from home, and where that does not converge, continuation from the home pose. The leg's
``k = 6 - rank(J_passive)`` equations are the wrenches ``w`` reciprocal to every passive freedom
(``w . J_p = 0``, Modern Robotics Sec. 12.1: the passive joints transmit them), applied to ``xi``:
``e = W xi``. One row is the actuation wrench (its gain ``g = w . J_a`` is the actuated freedom's power), the
other ``k - 1`` are reciprocal to the actuated joint too (constraints, gain 0). On the closure ``e = 0`` and
``W t = g q_dot``, as for every other leg type (:mod:`pmaccuracy.model.spatial_legs`). Wrench moments are
taken about the platform's reference point ``P``, as everywhere (:mod:`pmaccuracy.numerics.spatial`).

Values of the joints are the file's home values plus the freedoms: a P joint's ``home`` (mm, e.g. the leg length
at home), an R joint's ``home_deg``. The actuated value ``q`` of a leg is its actuated joint's value (mm or rad).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any, ClassVar

import numpy as np

from . import _tomlio
from ..errors import ConfigError, GeometryError
from ..numerics.spatial import rotations, rotvecs, skew
from .spatial_legs import ORTHOGONALITY_TOL, SpatialLeg, _angle_range, _deg, _plain, vector

#: Number of freedoms of each joint kind (an S joint's three are a rotation).
JOINT_DOF = {"R": 1, "P": 1, "U": 2, "C": 2, "S": 3}
JOINT_KEYS = {"type", "centre", "axis", "axes", "range_deg", "stroke", "home", "home_deg", "actuated",
              "cone_deg", "normal", "stem"}
#: Gauss-Newton iterations per continuation stage, and the stages from the home pose.
STAGES = (0.25, 0.5, 0.75, 1.0)
STAGE_ITERATIONS = 4
POLISH_ITERATIONS = 12
#: Gauss-Newton stops when every step is below this times the leg's length.
STEP_TOL = 1e-13
#: A chain whose residual stays above this (mm, and rad times the leg's length) does not reach the pose.
REACH_TOL = 1e-7


@dataclass(frozen=True)
class ChainJoint:
    """One joint of a :class:`ChainLeg`, at the home pose (base frame).

    Attributes
    ----------
    kind : str
        ``"R"``, ``"P"``, ``"U"``, ``"C"`` or ``"S"``.
    centre : tuple
        A point on the joint's axis (the common point of a U joint's axes, an S joint's ball centre), mm.
    axes : tuple
        Unit axes: one for R, P and C, two for U (``a1`` on the proximal part, ``a2`` on the distal one, as
        they are at home), none for S.
    home : tuple
        The joint's values at home (rad for rotations, mm for translations), one per scalar freedom.
    ranges : tuple
        ``(lo, hi)`` or ``None`` per scalar freedom (rad or mm; absolute values, home included).
    actuated : bool
        The leg's actuated joint (R or P).
    cone : float or None
        An S joint's cone half-angle (rad): the largest angle between ``normal`` (on the proximal part) and
        ``stem`` (on the distal part, equal to ``normal`` at home unless given).
    normal, stem : tuple
        The S joint's socket axis and stem direction at home.
    """

    kind: str
    centre: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axes: tuple = ()
    home: tuple = ()
    ranges: tuple = ()
    actuated: bool = False
    cone: float | None = None
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    stem: tuple[float, float, float] | None = None

    @property
    def dof(self) -> int:
        return JOINT_DOF[self.kind]

    def screws(self) -> np.ndarray:
        """The home twists ``[v_O, w]`` of its freedoms ``(dof, 6)`` (rotations first for a C joint)."""
        c = np.asarray(self.centre, dtype=float)
        if self.kind == "S":
            w = np.eye(3)
            return np.concatenate([-np.cross(w, c), w], axis=-1)
        out = []
        for i, a in enumerate(self.axes if self.kind != "C" else (self.axes[0], self.axes[0])):
            a = np.asarray(a, dtype=float)
            prismatic = self.kind == "P" or (self.kind == "C" and i == 1)
            out.append(np.concatenate([a, np.zeros(3)]) if prismatic else np.concatenate([-np.cross(a, c), a]))
        return np.array(out)

    def prismatic(self) -> tuple[bool, ...]:
        """Which scalar freedoms are translations."""
        return {"R": (False,), "P": (True,), "U": (False, False), "C": (False, True), "S": ()}[self.kind]

    @classmethod
    def from_table(cls, table: dict[str, Any], *, source: str, where: str) -> "ChainJoint":
        """One ``[[legs.joints]]`` table (``docs/guide/spatial.md``)."""
        _tomlio.reject_unknown(table, JOINT_KEYS, source=source, where=where)
        kind = table.get("type")
        if kind not in JOINT_DOF:
            raise ConfigError(f"must be one of R, P, U, C, S, got {kind!r}", source=source, key=f"{where}.type")
        centre = vector(table, "centre", source=source, where=where)
        actuated = table.get("actuated", False)
        if not isinstance(actuated, bool):
            raise ConfigError(f"must be true or false, got {actuated!r}", source=source, key=f"{where}.actuated")
        if actuated and kind not in ("R", "P"):
            raise ConfigError(f"only an R or a P joint can be actuated, not a {kind} joint", source=source,
                              key=f"{where}.actuated")
        allowed = {"R": {"axis", "range_deg", "home_deg"}, "P": {"axis", "stroke", "home"},
                   "U": {"axes", "range_deg", "home_deg"}, "C": {"axis", "range_deg", "home_deg", "stroke", "home"},
                   "S": {"cone_deg", "normal", "stem"}}[kind] | {"type", "centre", "actuated"}
        for key in table:
            if key not in allowed:
                article = "an" if kind in "RS" else "a"
                raise ConfigError(f"{article} {kind} joint takes no {key!r} (keys: {', '.join(sorted(allowed))})",
                                  source=source, key=f"{where}.{key}")
        if kind == "S":
            cone = None
            if "cone_deg" in table:
                cone = math.radians(_tomlio.number(table, "cone_deg", source=source, where=where, positive=True))
            normal = vector(table, "normal", source=source, where=where, unit=True, default=(0.0, 0.0, 1.0))
            stem = vector(table, "stem", source=source, where=where, unit=True) if "stem" in table else None
            return cls(kind="S", centre=centre, actuated=False, cone=cone, normal=normal, stem=stem)
        if kind == "U":
            axes = table.get("axes")
            if not isinstance(axes, list) or len(axes) != 2:
                raise ConfigError("a U joint needs axes = [[x, y, z], [x, y, z]] (proximal, distal)", source=source,
                                  key=f"{where}.axes")
            a1 = vector({"a": axes[0]}, "a", source=source, where=f"{where}.axes[1]", unit=True)
            a2 = vector({"a": axes[1]}, "a", source=source, where=f"{where}.axes[2]", unit=True)
            if abs(float(np.dot(a1, a2))) > ORTHOGONALITY_TOL:
                raise GeometryError("the two axes of a U joint must be perpendicular", source=source,
                                    key=f"{where}.axes")
            home = _pair(table, "home_deg", source=source, where=where, default=(0.0, 0.0))
            ranges = _ranges(table, source=source, where=where, count=2)
            return cls(kind="U", centre=centre, axes=(a1, a2), home=tuple(math.radians(h) for h in home),
                       ranges=ranges)
        axis = vector(table, "axis", source=source, where=where, unit=True)
        if kind == "R":
            home = (math.radians(_tomlio.number(table, "home_deg", source=source, where=where, default=0.0)),)
            return cls(kind="R", centre=centre, axes=(axis,), home=home,
                       ranges=(_angle_range(table, "range_deg", source=source, where=where),), actuated=actuated)
        length = _tomlio.number(table, "home", source=source, where=where, default=0.0)
        stroke = _tomlio.interval(table, "stroke", source=source, where=where) if "stroke" in table else None
        if kind == "P":
            return cls(kind="P", centre=centre, axes=(axis,), home=(length,), ranges=(stroke,), actuated=actuated)
        angle = math.radians(_tomlio.number(table, "home_deg", source=source, where=where, default=0.0))
        return cls(kind="C", centre=centre, axes=(axis,), home=(angle, length),
                   ranges=(_angle_range(table, "range_deg", source=source, where=where), stroke))

    def to_table(self) -> dict[str, Any]:
        out: dict[str, Any] = {"type": self.kind, "centre": _plain(self.centre)}
        if self.kind == "S":
            if self.cone is not None:
                out["cone_deg"] = _deg(self.cone)
            if tuple(self.normal) != (0.0, 0.0, 1.0) or self.cone is not None:
                out["normal"] = _plain(self.normal)
            if self.stem is not None:
                out["stem"] = _plain(self.stem)
            return out
        if self.kind == "U":
            out["axes"] = [_plain(a) for a in self.axes]
            if any(self.home):
                out["home_deg"] = [_deg(h) for h in self.home]
            if self.ranges[0] is not None:
                out["range_deg"] = [[_deg(v) for v in r] for r in self.ranges]
            return out
        out["axis"] = _plain(self.axes[0])
        if self.kind in ("R", "C"):
            if self.home[0]:
                out["home_deg"] = _deg(self.home[0])
            if self.ranges[0] is not None:
                out["range_deg"] = [_deg(v) for v in self.ranges[0]]
        if self.kind in ("P", "C"):
            if self.home[-1]:
                out["home"] = float(self.home[-1])
            if self.ranges[-1] is not None:
                out["stroke"] = _plain(self.ranges[-1])
        if self.actuated:
            out["actuated"] = True
        return out


def _pair(table, key, *, source, where, default):
    if key not in table:
        return default
    value = table[key]
    if not isinstance(value, list) or len(value) != 2:
        raise ConfigError(f"must be two angles [deg, deg], got {value!r}", source=source, key=f"{where}.{key}")
    return tuple(_tomlio.number({"v": v}, "v", source=source, where=f"{where}.{key}") for v in value)


def _ranges(table, *, source, where, count):
    if "range_deg" not in table:
        return (None,) * count
    value = table["range_deg"]
    if not isinstance(value, list) or len(value) != count or not all(isinstance(v, list) for v in value):
        raise ConfigError(f"a U joint's range_deg is two ranges [[lo1, hi1], [lo2, hi2]] (deg), got {value!r}",
                          source=source, key=f"{where}.range_deg")
    out = []
    for i, v in enumerate(value, start=1):
        out.append(_angle_range({"r": v}, "r", source=source, where=f"{where}.range_deg[{i}]"))
    return tuple(out)


# ---------------------------------------------------------------------------------------------- displacements
def _rotation(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """``Rot(a, theta)`` ``(..., 3, 3)`` by Rodrigues' formula (Modern Robotics Eq. 3.51)."""
    K = skew(axis)
    s, c = np.sin(angle)[..., None, None], np.cos(angle)[..., None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def _compose(A, B):
    """``(R_A R_B, R_A t_B + t_A)`` of displacements ``(R, t)``."""
    return A[0] @ B[0], np.einsum("...ij,...j->...i", A[0], B[1]) + A[1]


def _adjoint(D, screws: np.ndarray) -> np.ndarray:
    """``Ad(D) S`` for twists ``[v_O, w]`` ``(..., m, 6)``: ``w' = R w``, ``v' = R v + t x w'`` (Eq. 3.83)."""
    R, t = D
    w = np.einsum("...ij,...mj->...mi", R, screws[..., 3:])
    v = np.einsum("...ij,...mj->...mi", R, screws[..., :3]) + np.cross(t[..., None, :], w)
    return np.concatenate([v, w], axis=-1)


# ---------------------------------------------------------------------------------------------- the leg
@dataclass(frozen=True, kw_only=True)
class ChainLeg(SpatialLeg):
    """A leg given as a serial chain of joints (module text). ``base`` is its first joint's centre and
    ``platform`` its last joint's centre in platform coordinates (from the home pose ``home_pose``)."""

    joints: tuple[ChainJoint, ...]
    home_pose: tuple[float, ...]

    ARCHITECTURE: ClassVar[str] = "spatial-chain"
    KEYS: ClassVar[set[str]] = {"joints", "radius"}

    # ------------------------------------------------------------------ structure
    def __post_init__(self) -> None:
        acts = [i for i, j in enumerate(self.joints) if j.actuated]
        if len(acts) != 1:
            raise GeometryError(f"a leg needs exactly one actuated joint, found {len(acts)}", key="joints")

    @property
    def ACTUATOR(self) -> str:  # noqa: N802 - the leg types' class attribute, per leg here
        return self.joints[self._actuated_joint].kind

    @cached_property
    def _actuated_joint(self) -> int:
        return next(i for i, j in enumerate(self.joints) if j.actuated)

    @cached_property
    def _columns(self) -> list[tuple[int, int]]:
        """``(joint, freedom)`` of each Jacobian column."""
        return [(i, k) for i, j in enumerate(self.joints) for k in range(j.dof)]

    @cached_property
    def _actuated_column(self) -> int:
        return self._columns.index((self._actuated_joint, 0))

    @cached_property
    def length_scale(self) -> float:
        """Weight of rotations in the residual (mm): the leg's span at home, at least 1."""
        pts = np.array([j.centre for j in self.joints])
        return max(1.0, float(np.max(np.linalg.norm(pts - pts[0], axis=-1))))

    @property
    def ROWS(self) -> int:  # noqa: N802 - the leg types' class attribute, per leg here
        """``6 - rank`` of the passive freedoms' twists at home."""
        return 6 - self._passive_rank

    @cached_property
    def _passive_rank(self) -> int:
        J = self._home_jacobian()
        keep = [c for c in range(J.shape[1]) if c != self._actuated_column]
        Jp = J[:, keep] * self._metric()[:, None]
        s = np.linalg.svd(Jp, compute_uv=False)
        return int(np.sum(s > 1e-9 * max(1.0, s[0])))

    def _column_weights(self) -> np.ndarray:
        """mm per unit of each freedom: 1 for translations, the leg's length for rotations."""
        out = []
        for j in self.joints:
            out.extend([1.0 if pr else self.length_scale for pr in j.prismatic()] if j.kind != "S"
                       else [self.length_scale] * 3)
        return np.array(out)

    def _metric(self) -> np.ndarray:
        return np.array([1.0, 1.0, 1.0] + [self.length_scale] * 3)

    def _home_jacobian(self) -> np.ndarray:
        return np.concatenate([j.screws() for j in self.joints], axis=0).T

    @property
    def stroke(self) -> tuple[float, float]:
        rng = self.joints[self._actuated_joint].ranges[0]
        if rng is None:
            return (-math.inf, math.inf)
        return rng

    # ------------------------------------------------------------------ files
    @classmethod
    def from_table(cls, table, *, source, where, home_pose=None):
        if home_pose is None:
            raise ConfigError("a spatial-chain robot needs a [home] pose: its joints are given at that pose",
                              source=source, key="home")
        joints = table.get("joints")
        if not isinstance(joints, list) or not joints or not all(isinstance(t, dict) for t in joints):
            raise ConfigError("must be an array of joint tables [[legs.joints]] from the base to the platform",
                              source=source, key=f"{where}.joints")
        parsed = tuple(ChainJoint.from_table(t, source=source, where=f"{where}.joints[{k}]")
                       for k, t in enumerate(joints, start=1))
        acts = [k for k, j in enumerate(parsed, start=1) if j.actuated]
        if len(acts) != 1:
            raise ConfigError(f"a leg needs exactly one joint with actuated = true, found {len(acts)}",
                              source=source, key=f"{where}.joints")
        home = np.asarray(home_pose, dtype=float)
        R0 = rotations(home[3:])
        last = np.asarray(parsed[-1].centre)
        platform = tuple(float(v) for v in R0.T @ (last - home[:3]))
        radius = _tomlio.number(table, "radius", source=source, where=where, default=0.0, nonnegative=True)
        return cls(base=parsed[0].centre, platform=platform, joints=parsed, home_pose=tuple(float(v) for v in home),
                   radius=radius)

    def to_table(self):
        out: dict[str, Any] = {"joints": [j.to_table() for j in self.joints]}
        if self.radius:
            out["radius"] = self.radius
        return out

    # ------------------------------------------------------------------ the chain
    def _chain(self, theta: np.ndarray, Q: list[np.ndarray]):
        """Displacement ``D(theta)`` of the last body, the Jacobian ``(..., 6, m)`` (space twists at O) and each
        joint's prefix displacement (before the joint)."""
        shape = theta.shape[:-1]
        D = (np.broadcast_to(np.eye(3), shape + (3, 3)), np.zeros(shape + (3,)))
        cols, prefixes = [], []
        col, s = 0, 0
        for j in self.joints:
            prefixes.append(D)
            S = j.screws()
            if j.kind == "S":
                cols.append(_adjoint(D, np.broadcast_to(S, shape + S.shape)))
                c = np.asarray(j.centre)
                D = _compose(D, (Q[s], c - np.einsum("...ij,j->...i", Q[s], c)))
                s += 1
                continue
            if j.kind == "U":
                cols.append(_adjoint(D, np.broadcast_to(S[:1], shape + (1, 6))))
                D = _compose(D, self._revolute(j.axes[0], j.centre, theta[..., col]))
                cols.append(_adjoint(D, np.broadcast_to(S[1:], shape + (1, 6))))
                D = _compose(D, self._revolute(j.axes[1], j.centre, theta[..., col + 1]))
            elif j.kind == "C":
                cols.append(_adjoint(D, np.broadcast_to(S, shape + S.shape)))
                D = _compose(D, self._revolute(j.axes[0], j.centre, theta[..., col]))
                D = _compose(D, (np.broadcast_to(np.eye(3), shape + (3, 3)),
                                 theta[..., col + 1, None] * np.asarray(j.axes[0])))
            elif j.kind == "R":
                cols.append(_adjoint(D, np.broadcast_to(S, shape + S.shape)))
                D = _compose(D, self._revolute(j.axes[0], j.centre, theta[..., col]))
            else:
                cols.append(_adjoint(D, np.broadcast_to(S, shape + S.shape)))
                D = _compose(D, (np.broadcast_to(np.eye(3), shape + (3, 3)),
                                 theta[..., col, None] * np.asarray(j.axes[0])))
            col += j.dof
        return D, np.swapaxes(np.concatenate(cols, axis=-2), -1, -2), prefixes

    @staticmethod
    def _revolute(axis, centre, angle):
        Rot = _rotation(np.asarray(axis, dtype=float), np.asarray(angle))
        c = np.asarray(centre, dtype=float)
        return Rot, c - np.einsum("...ij,j->...i", Rot, c)

    def _scalar_count(self) -> int:
        return sum(j.dof for j in self.joints if j.kind != "S")

    def _residual(self, target, D) -> np.ndarray:
        """``xi = [t_e, rotvec(R_e)]`` of ``target D^-1`` ``(..., 6)``."""
        Re = target[0] @ np.swapaxes(D[0], -1, -2)
        te = target[1] - np.einsum("...ij,...j->...i", Re, D[1])
        finite = np.all(np.isfinite(Re), axis=(-2, -1))
        r = np.full(te.shape, np.nan)
        if np.any(finite):            # a diverged configuration (NaN) has no rotation vector: NaN residual
            r[finite] = rotvecs(Re[finite])
        return np.concatenate([te, r], axis=-1)

    def _target(self, p, R):
        R0 = rotations(np.asarray(self.home_pose[3:]))
        Rd = R @ R0.T
        return Rd, p - np.einsum("...ij,j->...i", Rd, np.asarray(self.home_pose[:3]))

    def _step(self, theta, Q, target, free: np.ndarray):
        """One Gauss-Newton step on the ``free`` columns, ``(J^T J + mu I) delta = J^T xi`` with the columns
        scaled to mm and a damping ``mu`` of 1e-12 of the mean diagonal (Levenberg-Marquardt: a freedom that moves
        nothing, a rod spinning between two balls, gets no step); returns the new state and the step's size."""
        D, J, _ = self._chain(theta, Q)
        xi = self._residual(target, D)
        w = self._metric()
        cw = self._column_weights()[free]
        Jw = J[..., free] * w[:, None] / cw                      # columns per mm of motion
        JtJ = np.swapaxes(Jw, -1, -2) @ Jw
        mu = 1e-12 * np.trace(JtJ, axis1=-2, axis2=-1)[..., None, None] / JtJ.shape[-1] + 1e-300
        rhs = np.einsum("...ji,...j->...i", Jw, xi * w)
        with np.errstate(invalid="ignore", over="ignore"):
            ok = np.all(np.isfinite(JtJ), axis=(-2, -1)) & np.all(np.isfinite(rhs), axis=-1)
            A = np.where(ok[..., None, None], JtJ + mu * np.eye(JtJ.shape[-1]), np.eye(JtJ.shape[-1]))
            delta = np.linalg.solve(A, np.where(ok[..., None], rhs, 0.0)[..., None])[..., 0] / cw
            # a step larger than the leg itself is a divergence (near a singular configuration): NaN
            ok &= np.all(np.abs(delta) < 1e3 * self.length_scale / cw, axis=-1)
            delta = np.where(ok[..., None], delta, np.nan)
        full = np.zeros(theta.shape[:-1] + (J.shape[-1],))
        full[..., free] = np.where(np.isfinite(delta), delta, np.nan)
        size = np.max(np.abs(full * self._column_weights()), axis=-1)
        return self._apply(theta, Q, full), size

    def _apply(self, theta, Q, delta):
        theta = theta.copy()
        Q = list(Q)
        col, sc, s = 0, 0, 0
        for j in self.joints:
            if j.kind == "S":
                Q[s] = rotations(delta[..., col:col + 3]) @ Q[s]
                s += 1
            else:
                theta[..., sc:sc + j.dof] += delta[..., col:col + j.dof]
                sc += j.dof
            col += j.dof
        return theta, Q

    def _scalar_of_actuated(self) -> int:
        sc = 0
        for i, j in enumerate(self.joints):
            if i == self._actuated_joint:
                return sc
            if j.kind != "S":
                sc += j.dof
        raise AssertionError  # pragma: no cover

    def _newton(self, theta, Q, target, free, iterations: int):
        """Gauss-Newton steps until every step is below :data:`STEP_TOL` times the leg's length (or
        ``iterations``); returns the state and which rows converged."""
        done = np.zeros(theta.shape[:-1], dtype=bool)
        for _ in range(iterations):
            (theta, Q), size = self._step(theta, Q, target, free)
            done = size <= STEP_TOL * self.length_scale
            if np.all(done | ~np.isfinite(size)):
                break
        return theta, Q, done

    def solve(self, p: np.ndarray, R: np.ndarray, q: np.ndarray | None = None, *, continuation: bool = True):
        """The chain's freedoms at poses: ``theta`` ``(..., m)`` (scalar freedoms from home), ``Q`` (each S
        joint's rotation ``(..., 3, 3)``), the residual ``xi`` ``(..., 6)``, the Jacobian ``(..., 6, m)`` and each
        joint's prefix displacement; with ``q`` the actuated value is held there (passive freedoms only).

        Gauss-Newton from the home configuration; where it does not converge, again by continuation along the
        platform's displacement from home (:data:`STAGES`), so that the leg stays on the branch of its home
        (``continuation=False``: not, for the inner loops of iterations that start again anyway)."""
        p = np.asarray(p, dtype=float)
        R = np.asarray(R, dtype=float)
        shape = np.broadcast_shapes(p.shape[:-1], R.shape[:-2])
        N = int(np.prod(shape, dtype=int))
        p = np.broadcast_to(p, shape + (3,)).reshape(N, 3)
        R = np.broadcast_to(R, shape + (3, 3)).reshape(N, 3, 3)
        n_s = sum(j.kind == "S" for j in self.joints)

        def home(n):
            return np.zeros((n, self._scalar_count())), [np.tile(np.eye(3), (n, 1, 1)) for _ in range(n_s)]
        Rd, td = self._target(p, R)
        free = np.ones(len(self._columns), dtype=bool)
        theta, Q = home(N)
        theta, Q, done = self._newton(theta, Q, (Rd, td), free, POLISH_ITERATIONS)
        bad = np.flatnonzero(~done)
        if bad.size and continuation:
            tb, Qb = home(bad.size)
            r = rotvecs(Rd[bad])
            for s in STAGES:
                tb, Qb, _ = self._newton(tb, Qb, (rotations(s * r), s * td[bad]), free, STAGE_ITERATIONS)
            tb, Qb, _ = self._newton(tb, Qb, (Rd[bad], td[bad]), free, POLISH_ITERATIONS)
            theta[bad] = tb
            for k in range(n_s):
                Q[k][bad] = Qb[k]
        if q is not None:
            a = self._scalar_of_actuated()
            theta[:, a] = np.broadcast_to(np.asarray(q, dtype=float), shape).reshape(N) - \
                self.joints[self._actuated_joint].home[0]
            free[self._actuated_column] = False
            theta, Q, _ = self._newton(theta, Q, (Rd, td), free, POLISH_ITERATIONS)
        D, J, prefixes = self._chain(theta, Q)
        xi = self._residual((Rd, td), D)
        back = lambda a, tail: a.reshape(shape + tail)   # noqa: E731
        return (back(theta, theta.shape[1:]), [back(x, (3, 3)) for x in Q], back(xi, (6,)), back(J, J.shape[1:]),
                [(back(P[0], (3, 3)), back(P[1], (3,))) for P in prefixes])

    # ------------------------------------------------------------------ the leg's interface
    def actuate(self, p, R):
        theta, _, xi, _, _ = self.solve(p, R)
        return self._actuated_value(theta, xi)

    def _actuated_value(self, theta, xi):
        joint = self.joints[self._actuated_joint]
        q = theta[..., self._scalar_of_actuated()] + joint.home[0]
        # a residual left at the least-squares solution: the leg cannot reach the pose (for a leg of lower
        # mobility also where the pose breaks its constraints; its closure rows alone cannot tell at a stretched,
        # singular configuration)
        err = np.max(np.abs(xi * self._metric()), axis=-1)
        q = np.where(err <= REACH_TOL * self.length_scale, q, np.nan)
        if joint.kind == "R":
            rng = joint.ranges[0]
            lo = rng[0] if rng is not None else -math.pi
            q = lo + np.mod(q - lo + 1e-12, 2 * np.pi) - 1e-12
        return q

    def closure(self, p, R, r, q):
        _, _, xi, J, _ = self.solve(p, R, q)
        return self._rows(p, xi, J)

    def solve_closure(self, p, R, *, continuation: bool = True):
        """The inverse kinematics and the closure at the least-squares solution of the whole chain, from one
        solve: ``(q, e, W, g)``, ``q`` as :meth:`actuate` gives it (NaN where the leg does not reach) and
        ``e, W, g`` as :meth:`closure`."""
        theta, _, xi, J, _ = self.solve(p, R, continuation=continuation)
        return (self._actuated_value(theta, xi), *self._rows(p, xi, J))

    def variant_closures(self, p, R, q, variants) -> list[np.ndarray]:
        """The closure rows of legs ``variants`` (this leg's joints with other centres and axes, same kinds and
        home values) at this leg's passive solution: ``W_o xi_v`` ``(..., k)`` per variant, ``W_o`` this leg's
        rows (moments about the base origin) and ``xi_v`` the residual twist of the variant's chain at this leg's
        freedoms ``theta`` (actuated value ``q``). Where this leg is closed (``xi = 0``) their central differences
        are the derivatives of its closure rows with respect to its geometry: ``e = W_o xi``, ``W_o`` reciprocal
        to the passive freedoms, so their change (``J_p dtheta``) and that of ``W_o`` (times ``xi = 0``) drop out.
        One solve of this leg, one chain product per variant."""
        p = np.asarray(p, dtype=float)
        theta, Q, xi, J, _ = self.solve(p, R, q)
        _, W, _ = self._rows(p, xi, J)
        f = W[..., :3]
        Wo = np.concatenate([f, W[..., 3:] + np.cross(p[..., None, :], f)], axis=-1)
        target = self._target(p, np.asarray(R, dtype=float))
        return [np.einsum("...ji,...i->...j", Wo, v._residual(target, v._chain(theta, Q)[0])) for v in variants]

    def _rows(self, p, xi, J):
        """The closure rows ``(e, W, g)`` from the residual and the Jacobian at the solution (module text)."""
        k = self.ROWS
        a = self._actuated_column
        keep = [c for c in range(J.shape[-1]) if c != a]
        # reciprocal wrenches of the passive columns, found in coordinates where rotations are weighed by the
        # leg's length: n . (S J_p) = 0 with S = diag(1, 1, 1, L, L, L) gives w = S n, w . J_p = 0
        S = self._metric()
        bad = ~np.all(np.isfinite(J), axis=(-2, -1)) | ~np.all(np.isfinite(xi), axis=-1)
        if np.any(bad):            # a diverged solve: NaN rows (the SVD takes no NaN)
            J = np.where(bad[..., None, None], self._home_jacobian(), J)
            xi = np.where(bad[..., None], np.nan, xi)
        U = np.linalg.svd(J[..., keep] * S[:, None], full_matrices=True)[0]
        N = U[..., :, 6 - k:] * S[:, None]                       # (..., 6, k)
        sa = J[..., a]
        power = np.einsum("...ik,...i->...k", N, sa)            # (..., k)
        if k == 1:
            Wo = np.swapaxes(N, -1, -2)
        else:
            power = np.where(np.isfinite(power), power, 1.0)
            Vt = np.linalg.svd(power[..., None, :], full_matrices=True)[2]   # row 0 along power, rows 1.. orthogonal
            Wo = np.einsum("...ik,...jk->...ji", N, Vt)
        e = np.einsum("...ji,...i->...j", Wo, xi)
        g = np.einsum("...ji,...i->...j", Wo, sa)
        g = np.concatenate([g[..., :1], np.zeros_like(g[..., 1:])], axis=-1)
        f, mo = Wo[..., :3], Wo[..., 3:]
        W = np.concatenate([f, mo - np.cross(np.asarray(p)[..., None, :], f)], axis=-1)
        if np.any(bad):
            W = np.where(bad[..., None, None], np.nan, W)
            g = np.where(bad[..., None], np.nan, g)
        return e, W, g

    def joint_values(self, p, R, q=None) -> dict[str, np.ndarray]:
        """Every joint's values at poses: ``{"joints[k].value": (...), ...}`` (rad or mm; U: ``value1``,
        ``value2``; S: ``cone_angle``, the angle between its normal and its stem, rad)."""
        theta, Q, _, _, _ = self.solve(p, R, q)
        out = {}
        sc, s = 0, 0
        for k, j in enumerate(self.joints, start=1):
            if j.kind == "S":
                stem = np.asarray(j.stem if j.stem is not None else j.normal)
                moved = np.einsum("...ij,j->...i", Q[s], stem)
                out[f"joints[{k}].cone_angle"] = np.arccos(np.clip(moved @ np.asarray(j.normal), -1, 1))
                s += 1
                continue
            for d in range(j.dof):
                name = "value" if j.dof == 1 else f"value{d + 1}"
                out[f"joints[{k}].{name}"] = theta[..., sc + d] + j.home[d]
            sc += j.dof
        return out

    def joint_angles(self, p, R, q=None):
        return self.joint_values(p, R, q)

    def limit_checks(self, p, R, q, tol):
        values = self.joint_values(p, R, q)
        lo, hi = self.stroke
        span = hi - lo if np.isfinite(hi - lo) else 1.0
        out = {"reach": np.isfinite(q)}
        if self.ACTUATOR == "P":
            out["stroke"] = (q >= lo - tol * max(1.0, span)) & (q <= hi + tol * max(1.0, span))
        elif np.isfinite(lo):
            from_lo = np.mod(q - lo + tol, 2 * np.pi) - tol
            out["stroke"] = from_lo <= hi - lo + tol
        for k, j in enumerate(self.joints, start=1):
            if k - 1 == self._actuated_joint:
                continue
            if j.kind == "S":
                if j.cone is not None:
                    out[f"joints[{k}].cone"] = values[f"joints[{k}].cone_angle"] <= j.cone + tol
                continue
            for d, rng in enumerate(j.ranges):
                if rng is None:
                    continue
                name = "value" if j.dof == 1 else f"value{d + 1}"
                v = values[f"joints[{k}].{name}"]
                if j.prismatic()[d]:
                    out[f"joints[{k}].range{d + 1 if j.dof > 1 else ''}"] = (v >= rng[0] - tol) & (v <= rng[1] + tol)
                else:
                    wrapped = rng[0] + np.mod(v - rng[0] + tol, 2 * np.pi) - tol
                    out[f"joints[{k}].range{d + 1 if j.dof > 1 else ''}"] = (wrapped >= rng[0] - tol) & \
                        (wrapped <= rng[1] + tol)
        return out

    def segments(self, p, R, q=None):
        """Capsule axes between successive joint centres (P joints have none) ``(..., s, 2, 3)``."""
        _, _, _, _, prefixes = self.solve(p, R, q)
        pts = []
        for j, D in zip(self.joints, prefixes):
            if j.kind == "P":
                continue
            pts.append(np.einsum("...ij,j->...i", D[0], np.asarray(j.centre)) + D[1])
        if len(pts) < 2:
            pts = [np.broadcast_to(np.asarray(self.base), np.shape(p)), self.platform_point(p, R)]
        pts = np.stack(pts, axis=-2)
        return np.stack([pts[..., :-1, :], pts[..., 1:, :]], axis=-2)

    def radii(self):
        n = max(1, sum(j.kind != "P" for j in self.joints) - 1)
        return (self.radius,) * n
