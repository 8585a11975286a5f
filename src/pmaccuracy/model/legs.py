"""Designer leg types: a robot file's leg table (3-PPR, 3-RPR, 3-RRR, 3-PRR or the general chain form) in, a
:class:`~pmaccuracy.model.chain.Chain` out; the one place where architectures differ.

The chain convention, the joints' blocks and the per-leg closed forms are in :mod:`pmaccuracy.model.chain`
(its public names are re-exported here).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, ClassVar

import numpy as np

from . import _tomlio
from ..errors import ConfigError, GeometryError

from .chain import (  # noqa: F401 (re-exported: the chain's public names)
    BLOCKS,
    Chain,
    Curve,
    DEGENERATE,
    Dyad,
    INF,
    Joint,
    LegState,
    N_BRANCHES,
    check_block,
)


def _block(table: dict[str, Any], key: str, kind: str, *, source: str, where: str) -> str | None:
    """The optional ``block`` key of a P joint in a robot file (checked)."""
    value = table.get(key)
    check_block(kind, value, source=source, key=f"{where}.{key}" if where else key)
    return value


def _blocks(**blocks) -> dict[str, str]:
    """The ``block`` keys given (not ``None``), for a robot file."""
    return {k: v for k, v in blocks.items() if v is not None}


def _deg(angle: float) -> float:
    return _tomlio.round_trip_degrees(angle)


def _point(table: dict[str, Any], key: str, *, source: str, where: str) -> tuple[float, float]:
    name = f"{where}.{key}"
    if key not in table:
        raise ConfigError("missing", source=source, key=name)
    value = table[key]
    if not isinstance(value, list) or len(value) != 2:
        raise ConfigError(f"must be a point [x, y] in mm, got {value!r}", source=source, key=name)
    x = _tomlio.number({"x": value[0]}, "x", source=source, where=name)
    y = _tomlio.number({"y": value[1]}, "y", source=source, where=name)
    return x, y


def _mode(table: dict[str, Any], *, source: str, where: str, default: int | None = None) -> int:
    if "working_mode" not in table and default is not None:
        return default
    if "working_mode" not in table:
        raise ConfigError("missing: give working_mode = 1 or -1 (the branch of the leg's inverse kinematics)",
                          source=source, key=f"{where}.working_mode")
    value = table.get("working_mode")
    if value not in (1, -1) or isinstance(value, bool):
        raise ConfigError(f"must be +1 or -1, got {value!r}", source=source, key=f"{where}.working_mode")
    return int(value)


def _angle_range(table: dict[str, Any], key: str, *, source: str, where: str) -> tuple[float, float]:
    lo, hi = _tomlio.interval(table, key, source=source, where=where)
    return math.radians(lo), math.radians(hi)


class LegType:
    """Interface of the designer leg types: a TOML table in, a :class:`Chain` out."""

    ARCHITECTURE: ClassVar[str]
    KEYS: ClassVar[set[str]]

    @property
    def chain(self) -> Chain:  # pragma: no cover - interface
        raise NotImplementedError

    @classmethod
    def from_table(cls, table: dict[str, Any], *, source: str, where: str) -> "LegType":  # pragma: no cover
        raise NotImplementedError

    def to_table(self) -> dict[str, Any]:  # pragma: no cover
        raise NotImplementedError


@dataclass(frozen=True)
class PPRLeg(LegType):
    """One P-P-R leg of the paper (Fig. 2 and 4). Lengths in mm, angles in rad.

    ``p = a h + s u + d v + l w + r k`` (Eq. 1). As a chain: base frame at
    ``A = a h`` along ``u``; the actuated guide ``s`` with the link ``d v``;
    the passive bearing ``l`` turned by ``gamma + theta`` onto ``w``; the
    revolute at ``D = P - r k``, i.e. the platform point ``-r vec(psi)``.
    ``s_range`` is the actuated joint's range, ``l_range`` the bearing's.
    """

    a: float
    alpha: float
    beta: float
    gamma: float
    theta: float
    d: float
    r: float
    psi: float
    s_range: tuple[float, float]
    l_range: tuple[float, float]
    guide_block: str | None = None
    bearing_block: str | None = None

    ARCHITECTURE: ClassVar[str] = "3-PPR"
    KEYS: ClassVar[set[str]] = {"a", "alpha_deg", "beta_deg", "gamma_deg", "theta_deg", "d", "r", "psi_deg",
                                "s_range", "l_range", "guide_block", "bearing_block"}

    @cached_property
    def chain(self) -> Chain:
        base = self.a * np.exp(1j * self.alpha)
        link = self.d * np.exp(1j * self.gamma)
        plat = -self.r * np.exp(1j * self.psi)
        return Chain(
            joints=(Joint("P", actuated=True, link=(link.real, link.imag), range=tuple(self.s_range),
                          block=self.guide_block),
                    Joint("P", offset=self.gamma + self.theta, range=tuple(self.l_range), block=self.bearing_block),
                    Joint("R")),
            base=(base.real, base.imag), base_angle=self.alpha + self.beta,
            platform=(plat.real, plat.imag))

    @classmethod
    def from_table(cls, table: dict[str, Any], *, source: str, where: str) -> "PPRLeg":
        num = lambda key, **kw: _tomlio.number(table, key, source=source, where=where, **kw)  # noqa: E731
        return cls(
            a=num("a", nonnegative=True),
            alpha=math.radians(num("alpha_deg")),
            beta=math.radians(num("beta_deg")),
            gamma=math.radians(num("gamma_deg")),
            theta=math.radians(num("theta_deg")),
            d=num("d", nonnegative=True),
            r=num("r", positive=True),
            psi=math.radians(num("psi_deg")),
            s_range=_tomlio.interval(table, "s_range", source=source, where=where),
            l_range=_tomlio.interval(table, "l_range", source=source, where=where),
            guide_block=_block(table, "guide_block", "P", source=source, where=where),
            bearing_block=_block(table, "bearing_block", "P", source=source, where=where),
        )

    def to_table(self) -> dict[str, Any]:
        return {"a": float(self.a), "alpha_deg": _deg(self.alpha), "beta_deg": _deg(self.beta),
                "gamma_deg": _deg(self.gamma), "theta_deg": _deg(self.theta), "d": float(self.d),
                "r": float(self.r), "psi_deg": _deg(self.psi), "s_range": [float(v) for v in self.s_range],
                "l_range": [float(v) for v in self.l_range], **_blocks(guide_block=self.guide_block,
                                                                       bearing_block=self.bearing_block)}


@dataclass(frozen=True)
class RPRLeg(LegType):
    """3-RPR leg: passive R at ``A`` (base), actuated length ``|A D|``, passive R at ``D`` (platform frame).

    Chain: R (``q1`` = direction of ``A -> D``), P actuated (``q2 = |A D|``), R (``q3 = phi - q1``).
    """

    base: tuple[float, float]
    platform: tuple[float, float]
    length_range: tuple[float, float]
    block: str | None = None

    ARCHITECTURE: ClassVar[str] = "3-RPR"
    KEYS: ClassVar[set[str]] = {"base", "platform", "length_range", "block"}

    @cached_property
    def chain(self) -> Chain:
        return Chain(joints=(Joint("R"), Joint("P", actuated=True, range=self.length_range, block=self.block),
                             Joint("R")),
                     base=self.base, platform=self.platform)

    @classmethod
    def from_table(cls, table, *, source, where):
        rng = _tomlio.interval(table, "length_range", source=source, where=where)
        if rng[0] < 0:
            raise ConfigError(f"a length cannot be negative, got [{rng[0]:g}, {rng[1]:g}]", source=source,
                              key=f"{where}.length_range")
        return cls(base=_point(table, "base", source=source, where=where),
                   platform=_point(table, "platform", source=source, where=where), length_range=rng,
                   block=_block(table, "block", "P", source=source, where=where))

    def to_table(self):
        return {"base": list(self.base), "platform": list(self.platform), "length_range": list(self.length_range),
                **_blocks(block=self.block)}


@dataclass(frozen=True)
class RRRLeg(LegType):
    """3-RRR leg: actuated R at ``A``, passive R at ``B`` (``|AB|`` = proximal), passive R at ``D``.

    Chain: R actuated (``q1`` = angle of ``A -> B`` from the base x-axis, link
    ``[proximal, 0]``), R (``q2``, link ``[distal, 0]``), R (``q3``).
    ``working_mode = sign(cross(B - A, D - B))``.
    """

    base: tuple[float, float]
    platform: tuple[float, float]
    proximal: float
    distal: float
    angle_range: tuple[float, float]
    working_mode: int = 1

    ARCHITECTURE: ClassVar[str] = "3-RRR"
    KEYS: ClassVar[set[str]] = {"base", "platform", "proximal", "distal", "angle_range_deg", "working_mode"}

    @cached_property
    def chain(self) -> Chain:
        return Chain(joints=(Joint("R", actuated=True, link=(self.proximal, 0.0), range=self.angle_range),
                             Joint("R", link=(self.distal, 0.0)), Joint("R")),
                     base=self.base, platform=self.platform, working_mode=self.working_mode)

    @classmethod
    def from_table(cls, table, *, source, where):
        num = lambda key: _tomlio.number(table, key, source=source, where=where, positive=True)  # noqa: E731
        return cls(base=_point(table, "base", source=source, where=where),
                   platform=_point(table, "platform", source=source, where=where),
                   proximal=num("proximal"), distal=num("distal"),
                   angle_range=_angle_range(table, "angle_range_deg", source=source, where=where),
                   working_mode=_mode(table, source=source, where=where))

    def to_table(self):
        return {"base": list(self.base), "platform": list(self.platform), "proximal": self.proximal,
                "distal": self.distal, "angle_range_deg": [_deg(v) for v in self.angle_range],
                "working_mode": self.working_mode}


@dataclass(frozen=True)
class PRRLeg(LegType):
    """3-PRR leg: actuated slide ``s`` along the guide ``u`` from ``guide_point``, passive R at ``B``, R at ``D``.

    ``B = guide_point + s u``, ``|B D|`` = distal. Chain: P actuated (base
    frame at the guide point along the guide), R (``q2`` = angle of ``B -> D``
    from ``u``, link ``[distal, 0]``), R. ``working_mode = sign(dot(u, D - B))``.
    """

    guide_point: tuple[float, float]
    guide_angle: float
    platform: tuple[float, float]
    distal: float
    s_range: tuple[float, float]
    working_mode: int = 1
    block: str | None = None

    ARCHITECTURE: ClassVar[str] = "3-PRR"
    KEYS: ClassVar[set[str]] = {"guide_point", "guide_deg", "platform", "distal", "s_range", "working_mode", "block"}

    @cached_property
    def chain(self) -> Chain:
        return Chain(joints=(Joint("P", actuated=True, range=self.s_range, block=self.block),
                             Joint("R", link=(self.distal, 0.0)),
                             Joint("R")),
                     base=self.guide_point, base_angle=self.guide_angle, platform=self.platform,
                     working_mode=self.working_mode)

    @classmethod
    def from_table(cls, table, *, source, where):
        return cls(guide_point=_point(table, "guide_point", source=source, where=where),
                   guide_angle=math.radians(_tomlio.number(table, "guide_deg", source=source, where=where)),
                   platform=_point(table, "platform", source=source, where=where),
                   distal=_tomlio.number(table, "distal", source=source, where=where, positive=True),
                   s_range=_tomlio.interval(table, "s_range", source=source, where=where),
                   working_mode=_mode(table, source=source, where=where),
                   block=_block(table, "block", "P", source=source, where=where))

    def to_table(self):
        return {"guide_point": list(self.guide_point), "guide_deg": _deg(self.guide_angle),
                "platform": list(self.platform), "distal": self.distal, "s_range": list(self.s_range),
                "working_mode": self.working_mode, **_blocks(block=self.block)}


@dataclass(frozen=True)
class ChainLeg(LegType):
    """A leg in the general chain form of the robot file (``architecture = "chain"``)."""

    spec: Chain = field()

    ARCHITECTURE: ClassVar[str] = "chain"
    KEYS: ClassVar[set[str]] = {"base", "base_deg", "platform", "platform_deg", "working_mode", "joints"}
    JOINT_KEYS: ClassVar[set[str]] = {"type", "actuated", "offset_deg", "link", "range", "block"}

    @property
    def chain(self) -> Chain:
        return self.spec

    @classmethod
    def from_table(cls, table, *, source, where):
        joints_t = table.get("joints")
        if not isinstance(joints_t, list) or not all(isinstance(j, dict) for j in joints_t):
            raise ConfigError("must be three [[legs.joints]] tables (base to platform)", source=source,
                              key=f"{where}.joints")
        if len(joints_t) != 3:
            raise ConfigError(f"exactly three joints are needed, found {len(joints_t)}", source=source,
                              key=f"{where}.joints")
        joints = []
        for n, jt in enumerate(joints_t, start=1):
            jw = f"{where}.joints[{n}]"
            _tomlio.reject_unknown(jt, cls.JOINT_KEYS, source=source, where=jw)
            kind = jt.get("type")
            if kind not in ("R", "P"):
                raise ConfigError(f"must be \"R\" or \"P\", got {kind!r}", source=source, key=f"{jw}.type")
            actuated = jt.get("actuated", False)
            if not isinstance(actuated, bool):
                raise ConfigError(f"must be true or false, got {actuated!r}", source=source, key=f"{jw}.actuated")
            offset = math.radians(_tomlio.number(jt, "offset_deg", source=source, where=jw, default=0.0))
            link = _point(jt, "link", source=source, where=jw) if "link" in jt else (0.0, 0.0)
            if "range" in jt:
                lo, hi = _tomlio.interval(jt, "range", source=source, where=jw)
                rng = (math.radians(lo), math.radians(hi)) if kind == "R" else (lo, hi)
            elif actuated:
                raise ConfigError("the actuated joint needs a range (deg for R, mm for P)", source=source,
                                  key=f"{jw}.range")
            else:
                rng = (-INF, INF)
            joints.append(Joint(kind, actuated=actuated, offset=offset, link=link, range=rng,
                                block=_block(jt, "block", kind, source=source, where=jw)))
        n_act = sum(j.actuated for j in joints)
        if n_act != 1:
            raise ConfigError(f"exactly one joint must have actuated = true, found {n_act}", source=source,
                              key=f"{where}.joints")
        base = _point(table, "base", source=source, where=where) if "base" in table else (0.0, 0.0)
        platform = _point(table, "platform", source=source, where=where) if "platform" in table else (0.0, 0.0)
        deg = lambda key: math.radians(_tomlio.number(table, key, source=source, where=where, default=0.0))  # noqa
        try:
            spec = Chain(joints=tuple(joints), base=base, base_angle=deg("base_deg"), platform=platform,
                         platform_angle=deg("platform_deg"), working_mode=_mode(table, source=source, where=where,
                                                                                default=1))
        except GeometryError as exc:
            raise GeometryError(exc.message, source=source, key=f"{where}.{exc.key}") from None
        return cls(spec=spec)

    def to_table(self):
        c = self.spec
        joints = []
        for j in c.joints:
            jt: dict[str, Any] = {"type": j.kind}
            if j.actuated:
                jt["actuated"] = True
            if j.offset:
                jt["offset_deg"] = _deg(j.offset)
            if j.link != (0.0, 0.0):
                jt["link"] = [float(v) for v in j.link]
            if j.limited or (np.isfinite(j.range[0]) and np.isfinite(j.range[1])):
                jt["range"] = [_deg(v) for v in j.range] if j.kind == "R" else [float(v) for v in j.range]
            jt.update(_blocks(block=j.block))
            joints.append(jt)
        return {"base": list(c.base), "base_deg": _deg(c.base_angle), "platform": list(c.platform),
                "platform_deg": _deg(c.platform_angle), "working_mode": c.working_mode, "joints": joints}


#: Designer leg types by the ``architecture`` key of a robot file.
LEG_TYPES: dict[str, type[LegType]] = {t.ARCHITECTURE: t for t in (PPRLeg, RPRLeg, RRRLeg, PRRLeg, ChainLeg)}
