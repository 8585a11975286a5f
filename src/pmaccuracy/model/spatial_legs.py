"""Leg types of spatial parallel manipulators: 6-UPS, 3-RPS, 3-PRS, 3-UPU and the Delta's R(SS)2.

Each leg is a frozen description (lengths mm, angles rad, points and unit directions as tuples) with

* ``from_table`` / ``to_table``: its ``[[legs]]`` table of a robot file (format: ``docs/guide/spatial.md``);
* ``actuate(p, R)``: the actuated joint value in closed form (the leg's inverse kinematics), NaN where the leg
  cannot reach;
* ``closure(p, R, r, q)``: the leg's scalar closure equations at a pose for an actuated value ``q``: residuals
  ``e`` ``(..., k)``, their derivatives along a platform twist as wrenches ``W`` ``(..., k, 6)`` and their
  derivatives with respect to ``q`` as gains ``g`` ``(..., k)``, so that ``W t = g q_dot`` on the closure
  (:mod:`pmaccuracy.numerics.spatial` for the conventions);
* ``joint_angles`` and ``segments``: passive joint angles for limits and reports, the leg's bodies as capsules
  for interference.

``p`` is ``(..., 3)`` mm, ``R`` ``(..., 3, 3)``, ``r`` the rotation vector ``(..., 3)``; everything broadcasts over
the leading axes. Every leg has ``k`` closure equations with ``sum(k) = 6`` over the robot's legs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from . import _tomlio
from ..errors import ConfigError, GeometryError
from ..numerics.spatial import couple, line_wrench, normalize

#: |cos| above this between two directions that must be perpendicular (or below 1 - this for parallel) is refused.
ORTHOGONALITY_TOL = 1e-6


# ---------------------------------------------------------------------------------------------- reading
def vector(table: dict[str, Any], key: str, *, source: str, where: str, default=None, unit: bool = False
           ) -> tuple[float, float, float]:
    """A 3-vector ``[x, y, z]`` of finite numbers (normalized when ``unit``; a zero direction is refused)."""
    name = f"{where}.{key}"
    if key not in table:
        if default is None:
            raise ConfigError("missing", source=source, key=name)
        return tuple(float(v) for v in default)
    value = table[key]
    if not isinstance(value, list) or len(value) != 3:
        what = "a direction [x, y, z]" if unit else "a point [x, y, z] in mm"
        raise ConfigError(f"must be {what}, got {value!r}", source=source, key=name)
    out = np.array([_tomlio.number({"v": v}, "v", source=source, where=name) for v in value])
    if unit:
        norm = float(np.linalg.norm(out))
        if not norm > 1e-12:
            raise ConfigError("a direction must not be zero", source=source, key=name)
        out = out / norm
    return tuple(float(v) for v in out)


def _cone(table, key, *, source, where) -> float | None:
    if key not in table:
        return None
    value = _tomlio.number(table, key, source=source, where=where, positive=True)
    if value > 180.0:
        raise ConfigError(f"a cone half-angle must be at most 180 deg, got {value}", source=source,
                          key=f"{where}.{key}")
    return math.radians(value)


def _mode(table, *, source, where) -> int:
    value = table.get("mode")
    if value is None:
        raise ConfigError("missing: give mode = 1 or -1 (the branch of the leg's inverse kinematics)",
                          source=source, key=f"{where}.mode")
    if isinstance(value, bool) or value not in (1, -1):
        raise ConfigError(f"must be +1 or -1, got {value!r}", source=source, key=f"{where}.mode")
    return int(value)


def _angle_range(table, key, *, source, where) -> tuple[float, float] | None:
    if key not in table:
        return None
    lo, hi = _tomlio.interval(table, key, source=source, where=where)
    if hi - lo > 360.0:
        raise ConfigError(f"an angle range spans at most 360 deg, got [{lo}, {hi}]", source=source,
                          key=f"{where}.{key}")
    return math.radians(lo), math.radians(hi)


def _length_stroke(table, *, source, where) -> tuple[float, float]:
    """The ``stroke`` of an actuated leg length: an interval of lengths >= 0 (mm)."""
    stroke = _tomlio.interval(table, "stroke", source=source, where=where)
    if stroke[0] < 0:
        raise ConfigError(f"a leg length must not be negative, got {stroke[0]}", source=source,
                          key=f"{where}.stroke")
    return stroke


def _deg(angle: float) -> float:
    return _tomlio.round_trip_degrees(angle)


def _plain(v) -> list[float]:
    return [float(x) for x in v]


def _perpendicular(a, b, *, source, where, key, what) -> None:
    if abs(float(np.dot(a, b))) > ORTHOGONALITY_TOL:
        raise GeometryError(f"{what} (their angle is {math.degrees(math.acos(np.clip(np.dot(a, b), -1, 1))):.4g} "
                            "deg)", source=source, key=f"{where}.{key}")


def _apply(R: np.ndarray, b) -> np.ndarray:
    """``R b`` for rotations ``(..., 3, 3)`` and one vector ``b`` (3,)."""
    return R @ np.asarray(b, dtype=float)


def _angle_between(u: np.ndarray, n: np.ndarray) -> np.ndarray:
    return np.arccos(np.clip(np.sum(u * n, axis=-1), -1.0, 1.0))


def _signed_angle(n: np.ndarray, u: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Angle from ``n`` to ``u`` about ``axis`` (both perpendicular to it), in ``(-pi, pi]``."""
    return np.arctan2(np.sum(np.cross(n, u) * axis, axis=-1), np.sum(n * u, axis=-1))


def _within_range(angle: np.ndarray, rng: tuple[float, float] | None, tol: float) -> np.ndarray:
    """``angle`` (mod 2 pi) inside ``[lo, hi]`` (True where no range)."""
    if rng is None:
        return np.ones(np.shape(angle), dtype=bool)
    lo, hi = rng
    wrapped = lo + np.mod(angle - lo + tol, 2 * np.pi) - tol
    return (wrapped >= lo - tol) & (wrapped <= hi + tol)


# ---------------------------------------------------------------------------------------------- common part
@dataclass(frozen=True, kw_only=True)
class SpatialLeg:
    """What every spatial leg has: its joint centres and the limits of its passive joints (see the guide)."""

    base: tuple[float, float, float]
    platform: tuple[float, float, float]
    base_normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    base_cone: float | None = None
    platform_normal: tuple[float, float, float] = (0.0, 0.0, -1.0)
    platform_cone: float | None = None
    radius: float = 0.0

    ARCHITECTURE: ClassVar[str]
    #: Number of closure equations of the leg (rows of its wrenches).
    ROWS: ClassVar[int]
    #: The actuated joint's kind: "P" (value in mm) or "R" (rad).
    ACTUATOR: ClassVar[str] = "P"
    COMMON_KEYS: ClassVar[set[str]] = {"base", "platform", "base_normal", "base_cone_deg", "platform_normal",
                                       "platform_cone_deg", "radius"}
    KEYS: ClassVar[set[str]]
    DEFAULT_PLATFORM_NORMAL: ClassVar[tuple[float, float, float]] = (0.0, 0.0, -1.0)

    @classmethod
    def common(cls, table, *, source, where) -> dict[str, Any]:
        return dict(
            base=vector(table, "base", source=source, where=where),
            platform=vector(table, "platform", source=source, where=where),
            base_normal=vector(table, "base_normal", source=source, where=where, default=(0.0, 0.0, 1.0),
                               unit=True),
            base_cone=_cone(table, "base_cone_deg", source=source, where=where),
            platform_normal=vector(table, "platform_normal", source=source, where=where,
                                   default=cls.DEFAULT_PLATFORM_NORMAL, unit=True),
            platform_cone=_cone(table, "platform_cone_deg", source=source, where=where),
            radius=_tomlio.number(table, "radius", source=source, where=where, default=0.0, nonnegative=True),
        )

    def common_table(self) -> dict[str, Any]:
        out: dict[str, Any] = {"base": _plain(self.base), "platform": _plain(self.platform)}
        if tuple(self.base_normal) != (0.0, 0.0, 1.0):
            out["base_normal"] = _plain(self.base_normal)
        if self.base_cone is not None:
            out["base_cone_deg"] = _deg(self.base_cone)
        if tuple(self.platform_normal) != self.DEFAULT_PLATFORM_NORMAL:
            out["platform_normal"] = _plain(self.platform_normal)
        if self.platform_cone is not None:
            out["platform_cone_deg"] = _deg(self.platform_cone)
        if self.radius:
            out["radius"] = self.radius
        return out

    # the parts every leg type defines
    def actuate(self, p: np.ndarray, R: np.ndarray) -> np.ndarray:  # pragma: no cover - interface
        raise NotImplementedError

    def closure(self, p, R, r, q):  # pragma: no cover - interface
        raise NotImplementedError

    @property
    def stroke(self) -> tuple[float, float]:  # pragma: no cover - interface
        raise NotImplementedError

    def platform_point(self, p: np.ndarray, R: np.ndarray) -> np.ndarray:
        """``B = p + R b`` (mm), ``(..., 3)``."""
        return p + _apply(R, self.platform)

    def _cones(self, u_base: np.ndarray, u_platform: np.ndarray, R: np.ndarray) -> dict[str, np.ndarray]:
        """Angles (rad) of the leg from the base joint's and the platform joint's cone axes."""
        return {"base_angle": _angle_between(u_base, np.asarray(self.base_normal)),
                "platform_angle": _angle_between(u_platform, _apply(R, self.platform_normal))}

    def limit_checks(self, p, R, q, tol: float) -> dict[str, np.ndarray]:
        """Each limit of the leg at the poses: ``{name: bool (...)}``, True where satisfied."""
        angles = self.joint_angles(p, R, q)
        lo, hi = self.stroke
        span = hi - lo
        out = {"reach": np.isfinite(q),
               "stroke": (q >= lo - tol * max(1.0, span)) & (q <= hi + tol * max(1.0, span))
               if self.ACTUATOR == "P" else _within_range(q, self.stroke, tol)}
        if self.base_cone is not None and "base_angle" in angles:
            out["base_cone"] = angles["base_angle"] <= self.base_cone + tol
        if self.platform_cone is not None and "platform_angle" in angles:
            out["platform_cone"] = angles["platform_angle"] <= self.platform_cone + tol
        rng = getattr(self, "angle_range", None)
        if rng is not None and "revolute_angle" in angles:
            out["revolute_range"] = _within_range(angles["revolute_angle"], rng, tol)
        return out

    def radii(self) -> tuple[float, ...]:
        """Radius of each segment of :meth:`segments` (mm)."""
        return (self.radius,)


def _leg_line(A, B):
    d = B - A
    L = np.linalg.norm(d, axis=-1)
    return d, L, normalize(d)


# ---------------------------------------------------------------------------------------------- 6-UPS
@dataclass(frozen=True, kw_only=True)
class UPSLeg(SpatialLeg):
    """A Gough-Stewart leg: universal joint at ``base``, actuated length, spherical joint at ``platform``.

    Inverse kinematics ``L = |p + R b - A|``; closure ``e = L(p, R) - q`` with the wrench of a unit force along
    the leg through ``B`` (the leg's actuation wrench: ``u . (v + w x (B - p)) = L_dot``).
    """

    length_range: tuple[float, float]
    base_axis: tuple[float, float, float] | None = None

    ARCHITECTURE: ClassVar[str] = "6-UPS"
    ROWS: ClassVar[int] = 1
    KEYS: ClassVar[set[str]] = SpatialLeg.COMMON_KEYS | {"stroke", "base_axis"}

    @property
    def stroke(self) -> tuple[float, float]:
        return self.length_range

    @classmethod
    def from_table(cls, table, *, source, where):
        c = cls.common(table, source=source, where=where)
        stroke = _length_stroke(table, source=source, where=where)
        axis = vector(table, "base_axis", source=source, where=where, unit=True) if "base_axis" in table else None
        return cls(length_range=stroke, base_axis=axis, **c)

    def to_table(self):
        out = self.common_table()
        out["stroke"] = _plain(self.length_range)
        if self.base_axis is not None:
            out["base_axis"] = _plain(self.base_axis)
        return out

    def actuate(self, p, R):
        return np.linalg.norm(self.platform_point(p, R) - np.asarray(self.base), axis=-1)

    def closure(self, p, R, r, q):
        B = self.platform_point(p, R)
        d, L, u = _leg_line(np.asarray(self.base), B)
        return (L - q)[..., None], line_wrench(u, B - p)[..., None, :], np.ones(L.shape + (1,))

    def joint_angles(self, p, R, q=None):
        B = self.platform_point(p, R)
        _, _, u = _leg_line(np.asarray(self.base), B)
        return self._cones(u, -u, R)

    def segments(self, p, R, q=None):
        B = self.platform_point(p, R)
        return np.stack([np.broadcast_to(np.asarray(self.base), B.shape), B], axis=-2)[..., None, :, :]


# ---------------------------------------------------------------------------------------------- 3-UPU
@dataclass(frozen=True, kw_only=True)
class UPULeg(UPSLeg):
    """Tsai's U-P-U leg: like :class:`UPSLeg` plus a constraint couple ``m = u1 x u2`` (reciprocal to both
    universal joints when the outer axes ``u1``, ``R u4`` are parallel and the inner ones ``u2 = u1 x d`` are
    too), which keeps the platform from turning: closure ``e2 = m . r`` (``r`` the rotation vector)."""

    platform_axis: tuple[float, float, float] = (1.0, 0.0, 0.0)

    ARCHITECTURE: ClassVar[str] = "3-UPU"
    ROWS: ClassVar[int] = 2
    KEYS: ClassVar[set[str]] = SpatialLeg.COMMON_KEYS | {"stroke", "base_axis", "platform_axis"}

    @classmethod
    def from_table(cls, table, *, source, where):
        c = cls.common(table, source=source, where=where)
        stroke = _length_stroke(table, source=source, where=where)
        u1 = vector(table, "base_axis", source=source, where=where, unit=True)
        u4 = vector(table, "platform_axis", source=source, where=where, unit=True)
        if abs(abs(float(np.dot(u1, u4))) - 1.0) > ORTHOGONALITY_TOL:
            raise GeometryError("Tsai's condition: platform_axis must be parallel to base_axis, or the platform "
                                "does not stay in pure translation", source=source, key=f"{where}.platform_axis")
        return cls(length_range=stroke, base_axis=u1, platform_axis=u4, **c)

    def to_table(self):
        out = super().to_table()
        out["platform_axis"] = _plain(self.platform_axis)
        return out

    def couple_axis(self, p, R):
        """The constraint couple's unit direction ``u1 x (u1 x d)`` normalized, ``(..., 3)``."""
        B = self.platform_point(p, R)
        d = B - np.asarray(self.base)
        u1 = np.asarray(self.base_axis)
        return normalize(np.cross(u1, np.cross(u1, d)))

    def closure(self, p, R, r, q):
        e1, w1, g1 = super().closure(p, R, r, q)
        m = self.couple_axis(p, R)
        e2 = np.sum(m * r, axis=-1)[..., None]
        return (np.concatenate([e1, e2], -1), np.concatenate([w1, couple(m)[..., None, :]], -2),
                np.concatenate([g1, np.zeros_like(g1)], -1))


# ---------------------------------------------------------------------------------------------- 3-RPS
@dataclass(frozen=True, kw_only=True)
class RPSLeg(UPSLeg):
    """A revolute at ``base`` (axis ``axis``), actuated length, spherical joint at ``platform``.

    Closure: ``e1 = |B - A| - q`` (a force along the leg) and ``e2 = axis . (B - A)`` (a force along the revolute
    axis through ``B``: the leg stays in the plane normal to the axis).
    """

    axis: tuple[float, float, float] = (1.0, 0.0, 0.0)
    angle_range: tuple[float, float] | None = None

    ARCHITECTURE: ClassVar[str] = "3-RPS"
    ROWS: ClassVar[int] = 2
    KEYS: ClassVar[set[str]] = SpatialLeg.COMMON_KEYS | {"stroke", "axis", "angle_range_deg"}

    @classmethod
    def from_table(cls, table, *, source, where):
        c = cls.common(table, source=source, where=where)
        stroke = _length_stroke(table, source=source, where=where)
        axis = vector(table, "axis", source=source, where=where, unit=True)
        _perpendicular(axis, c["base_normal"], source=source, where=where, key="base_normal",
                       what="base_normal must be perpendicular to the revolute axis")
        return cls(length_range=stroke, axis=axis, angle_range=_angle_range(table, "angle_range_deg",
                                                                             source=source, where=where), **c)

    def to_table(self):
        out = self.common_table()
        out["stroke"] = _plain(self.length_range)
        out["axis"] = _plain(self.axis)
        if self.angle_range is not None:
            out["angle_range_deg"] = [_deg(a) for a in self.angle_range]
        return out

    def closure(self, p, R, r, q):
        e1, w1, g1 = UPSLeg.closure(self, p, R, r, q)
        B = self.platform_point(p, R)
        a = np.asarray(self.axis)
        e2 = np.sum(a * (B - np.asarray(self.base)), axis=-1)[..., None]
        w2 = line_wrench(np.broadcast_to(a, B.shape), B - p)[..., None, :]
        return np.concatenate([e1, e2], -1), np.concatenate([w1, w2], -2), np.concatenate([g1, 0 * g1], -1)

    def joint_angles(self, p, R, q=None):
        out = super().joint_angles(p, R, q)
        B = self.platform_point(p, R)
        u = normalize(B - np.asarray(self.base))
        out["revolute_angle"] = _signed_angle(np.asarray(self.base_normal), u, np.asarray(self.axis))
        return out


# ---------------------------------------------------------------------------------------------- 3-PRS
@dataclass(frozen=True, kw_only=True)
class PRSLeg(SpatialLeg):
    """An actuated slide along ``slide`` from ``base``, a revolute on the carriage (axis ``axis``), a rod of
    length ``rod`` to the spherical joint at ``platform``.

    Inverse kinematics ``q = s.e - mode sqrt((s.e)^2 - |e|^2 + rod^2)``, ``e = B - base``; closure
    ``e1 = (|B - C(q)|^2 - rod^2) / (2 rod)`` with ``C = base + q s`` (a force along the rod ``n``, gain
    ``n . s``) and ``e2 = axis . (B - base)`` (a force along the axis through ``B``).
    """

    slide: tuple[float, float, float]
    slide_range: tuple[float, float]
    axis: tuple[float, float, float]
    rod: float
    mode: int
    angle_range: tuple[float, float] | None = None

    ARCHITECTURE: ClassVar[str] = "3-PRS"
    ROWS: ClassVar[int] = 2
    KEYS: ClassVar[set[str]] = SpatialLeg.COMMON_KEYS | {"slide", "stroke", "axis", "rod", "mode",
                                                         "angle_range_deg"}

    @property
    def stroke(self) -> tuple[float, float]:
        return self.slide_range

    @classmethod
    def from_table(cls, table, *, source, where):
        c = cls.common(table, source=source, where=where)
        slide = vector(table, "slide", source=source, where=where, unit=True)
        axis = vector(table, "axis", source=source, where=where, unit=True)
        _perpendicular(axis, slide, source=source, where=where, key="axis",
                       what="the revolute axis must be perpendicular to the slide")
        _perpendicular(axis, c["base_normal"], source=source, where=where, key="base_normal",
                       what="base_normal must be perpendicular to the revolute axis")
        return cls(slide=slide, slide_range=_tomlio.interval(table, "stroke", source=source, where=where),
                   axis=axis, rod=_tomlio.number(table, "rod", source=source, where=where, positive=True),
                   mode=_mode(table, source=source, where=where),
                   angle_range=_angle_range(table, "angle_range_deg", source=source, where=where), **c)

    def to_table(self):
        out = self.common_table()
        out.update(slide=_plain(self.slide), stroke=_plain(self.slide_range), axis=_plain(self.axis),
                   rod=self.rod, mode=self.mode)
        if self.angle_range is not None:
            out["angle_range_deg"] = [_deg(a) for a in self.angle_range]
        return out

    def actuate(self, p, R):
        e = self.platform_point(p, R) - np.asarray(self.base)
        se = e @ np.asarray(self.slide)
        disc = se ** 2 - np.sum(e * e, axis=-1) + self.rod ** 2
        with np.errstate(invalid="ignore"):
            return np.where(disc >= 0, se - self.mode * np.sqrt(disc), np.nan)

    def carriage(self, q):
        """The revolute centre ``C = base + q s`` (mm), ``(..., 3)``."""
        return np.asarray(self.base) + np.asarray(q)[..., None] * np.asarray(self.slide)

    def closure(self, p, R, r, q):
        B = self.platform_point(p, R)
        C = self.carriage(q)
        d = B - C
        n = normalize(d)
        s = np.asarray(self.slide)
        a = np.asarray(self.axis)
        e1 = (np.sum(d * d, -1) - self.rod ** 2) / (2 * self.rod)
        e2 = np.sum(a * (B - np.asarray(self.base)), -1)
        W = np.stack([line_wrench(n, B - p), line_wrench(np.broadcast_to(a, B.shape), B - p)], -2)
        g = np.stack([n @ s, np.zeros_like(e1)], -1)
        return np.stack([e1, e2], -1), W, g

    def joint_angles(self, p, R, q=None):
        q = self.actuate(p, R) if q is None else q
        B = self.platform_point(p, R)
        u = normalize(B - self.carriage(q))
        out = self._cones(u, -u, R)
        out["revolute_angle"] = _signed_angle(np.asarray(self.base_normal), u, np.asarray(self.axis))
        return out

    def segments(self, p, R, q=None):
        q = self.actuate(p, R) if q is None else q
        B = self.platform_point(p, R)
        return np.stack([self.carriage(q), B], axis=-2)[..., None, :, :]


# ---------------------------------------------------------------------------------------------- Delta
@dataclass(frozen=True, kw_only=True)
class DeltaLeg(SpatialLeg):
    """A Delta leg R(SS)2: an actuated arm turning about ``axis`` at ``base``, two parallel rods of length
    ``rod`` spaced ``spacing`` along the axis, from the elbow balls ``C +- spacing/2 axis`` to the platform balls
    ``B +- spacing/2 R axis``.

    Inverse kinematics (midpoints, ``e = p + R b - A``): ``e . d(theta) = K`` with ``d(theta) = cos(theta) x +
    sin(theta) y`` (``x = zero``, ``y = axis x zero``) and ``K = (|e|^2 + arm^2 - rod^2) / (2 arm)``, so
    ``theta = psi - mode acos(K / rho)``, ``rho e^(i psi) = e.x + i e.y``. Closure: per rod ``j``
    ``e_j = (|B_j - C_j|^2 - rod^2) / (2 rod)``, a force along the rod ``n_j`` through ``B_j`` with gain
    ``n_j . (axis x (C_j - A))`` (the elbow's velocity per unit arm rate).
    """

    axis: tuple[float, float, float]
    zero: tuple[float, float, float]
    arm: float
    rod: float
    spacing: float
    angle_range: tuple[float, float]
    mode: int
    arm_radius: float = 0.0
    rod_radius: float = 0.0

    ARCHITECTURE: ClassVar[str] = "delta"
    ROWS: ClassVar[int] = 2
    ACTUATOR: ClassVar[str] = "R"
    KEYS: ClassVar[set[str]] = {"base", "platform", "platform_normal", "platform_cone_deg", "axis", "zero", "arm",
                                "rod", "spacing", "angle_range_deg", "mode", "arm_radius", "rod_radius"}
    DEFAULT_PLATFORM_NORMAL: ClassVar[tuple[float, float, float]] = (0.0, 0.0, 1.0)

    @property
    def stroke(self) -> tuple[float, float]:
        return self.angle_range

    @classmethod
    def from_table(cls, table, *, source, where):
        c = cls.common(table, source=source, where=where)
        axis = vector(table, "axis", source=source, where=where, unit=True)
        zero = vector(table, "zero", source=source, where=where, unit=True)
        _perpendicular(axis, zero, source=source, where=where, key="zero",
                       what="the arm's zero direction must be perpendicular to the revolute axis")
        rng = _angle_range(table, "angle_range_deg", source=source, where=where)
        if rng is None:
            raise ConfigError("missing", source=source, key=f"{where}.angle_range_deg")
        return cls(axis=axis, zero=zero, arm=_tomlio.number(table, "arm", source=source, where=where, positive=True),
                   rod=_tomlio.number(table, "rod", source=source, where=where, positive=True),
                   spacing=_tomlio.number(table, "spacing", source=source, where=where, nonnegative=True),
                   angle_range=rng, mode=_mode(table, source=source, where=where),
                   arm_radius=_tomlio.number(table, "arm_radius", source=source, where=where, default=0.0,
                                             nonnegative=True),
                   rod_radius=_tomlio.number(table, "rod_radius", source=source, where=where, default=0.0,
                                             nonnegative=True), **c)

    def to_table(self):
        out = self.common_table()
        out.update(axis=_plain(self.axis), zero=_plain(self.zero), arm=self.arm, rod=self.rod, spacing=self.spacing,
                   angle_range_deg=[_deg(a) for a in self.angle_range], mode=self.mode)
        if self.arm_radius:
            out["arm_radius"] = self.arm_radius
        if self.rod_radius:
            out["rod_radius"] = self.rod_radius
        return out

    def _frame(self):
        a = np.asarray(self.axis)
        x = np.asarray(self.zero)
        return a, x, np.cross(a, x)

    def arm_direction(self, theta):
        """``d(theta) = cos(theta) x + sin(theta) y``, ``(..., 3)``."""
        _, x, y = self._frame()
        theta = np.asarray(theta, dtype=float)[..., None]
        return np.cos(theta) * x + np.sin(theta) * y

    def elbow(self, theta):
        """Midpoint ``C = A + arm d(theta)`` of the elbow balls (mm)."""
        return np.asarray(self.base) + self.arm * self.arm_direction(theta)

    def actuate(self, p, R):
        _, x, y = self._frame()
        e = self.platform_point(p, R) - np.asarray(self.base)
        K = (np.sum(e * e, -1) + self.arm ** 2 - self.rod ** 2) / (2 * self.arm)
        ex, ey = e @ x, e @ y
        rho = np.hypot(ex, ey)
        with np.errstate(invalid="ignore", divide="ignore"):
            c = K / rho
            theta = np.arctan2(ey, ex) - self.mode * np.arccos(np.where(np.abs(c) <= 1, c, np.nan))
        lo = self.angle_range[0]
        return lo + np.mod(theta - lo + 1e-12, 2 * np.pi) - 1e-12

    def balls(self, p, R, theta):
        """Elbow and platform balls of both rods: ``C_j, B_j`` each ``(..., 2, 3)`` (j = +, -)."""
        a = np.asarray(self.axis)
        half = 0.5 * self.spacing * np.array([1.0, -1.0])[:, None]
        C = self.elbow(theta)[..., None, :] + half * a
        B = self.platform_point(p, R)[..., None, :] + half * _apply(R, a)[..., None, :]
        return C, B

    def closure(self, p, R, r, q):
        a = np.asarray(self.axis)
        C, B = self.balls(p, R, q)
        d = B - C
        n = normalize(d)
        e = (np.sum(d * d, -1) - self.rod ** 2) / (2 * self.rod)
        W = line_wrench(n, B - p[..., None, :])
        g = np.sum(n * np.cross(a, C - np.asarray(self.base)), -1)
        return e, W, g

    def joint_angles(self, p, R, q=None):
        q = self.actuate(p, R) if q is None else q
        C, B = self.balls(p, R, q)
        u = normalize(C - B)
        n = _apply(R, self.platform_normal)[..., None, :]
        return {"platform_angle": np.max(_angle_between(u, n), axis=-1), "revolute_angle": q}

    def limit_checks(self, p, R, q, tol):
        out = super().limit_checks(p, R, q, tol)
        out.pop("revolute_range", None)   # the actuated angle is the stroke
        return out

    def segments(self, p, R, q=None):
        q = self.actuate(p, R) if q is None else q
        C, B = self.balls(p, R, q)
        A = np.broadcast_to(np.asarray(self.base), C.shape[:-2] + (3,))
        arm = np.stack([A, self.elbow(q)], -2)[..., None, :, :]
        rods = np.stack([C, B], -2)
        return np.concatenate([arm, rods], -3)

    def radii(self):
        return (self.arm_radius, self.rod_radius, self.rod_radius)


#: Leg type of each spatial architecture named in a robot file.
SPATIAL_LEG_TYPES: dict[str, type[SpatialLeg]] = {
    "6-UPS": UPSLeg, "3-RPS": RPSLeg, "3-PRS": PRSLeg, "3-UPU": UPULeg, "delta": DeltaLeg}
#: Other spellings accepted for an architecture.
ARCHITECTURE_ALIASES = {"3-R(SS)2": "delta", "Delta": "delta", "6-SPS": "6-UPS", "gough-stewart": "6-UPS"}
#: Number of legs of each architecture.
LEG_COUNT = {"6-UPS": 6, "3-RPS": 3, "3-PRS": 3, "3-UPU": 3, "delta": 3}
