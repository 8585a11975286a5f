"""Robot descriptions: planar parallel manipulators with three legs (the paper's 3-PPR: Sec. 2, Eq. 1).

Notation of the paper, for leg ``i`` (``vec(t) = [cos t, sin t]``)::

    h_i = vec(alpha_i)                          base direction, A_i = a_i h_i
    u_i = vec(alpha_i + beta_i)                 actuated guide (joint s_i), A_i -> B_i
    v_i = vec(alpha_i + beta_i + gamma_i)       fixed offset d_i, B_i -> C_i
    w_i = vec(alpha_i + beta_i + gamma_i + theta_i)   passive bearing (joint l_i), C_i -> D_i
    k_i = vec(phi + psi_i)                      platform vector r_i, D_i -> P

    p = a_i h_i + s_i u_i + d_i v_i + l_i w_i + r_i k_i        (Eq. 1)

Lengths are in mm and angles in radians inside the code; TOML files give
angles in degrees under keys ending in ``_deg``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from . import _tomlio
from ._tomlio import round_trip_degrees  # noqa: F401 - re-exported (files and coordinates in degrees)
from ..errors import ConfigError, GeometryError, UnsupportedArchitectureError
from .legs import LEG_TYPES, Chain, ChainLeg, LegType, PPRLeg
from .spatial_legs import ARCHITECTURE_ALIASES as _SPATIAL_ALIASES, SPATIAL_LEG_TYPES as _SPATIAL_TYPES

#: Architectures of spatial robot files (:mod:`pmaccuracy.model.spatial`), refused here with a pointer there.
SPATIAL_ARCHITECTURES = set(_SPATIAL_TYPES) | set(_SPATIAL_ALIASES)

#: Keys of one ``[[legs]]`` table in a 3-PPR robot file.
LEG_KEYS = PPRLeg.KEYS
#: Names of the per-leg link parameters that the error model can vary (Eq. 6).
LINK_PARAMETERS = ("a", "alpha", "beta", "d", "gamma", "theta", "r", "psi")
#: |sin(gamma + theta)| below this makes the bearing parallel to the guide: B singular everywhere.
MIN_GUIDE_BEARING_SINE = 1e-6


def unit(angle: np.ndarray | float) -> np.ndarray:
    """``vec(t) = [cos t, sin t]``, shape ``(..., 2)`` for angles of shape ``(...)``."""
    angle = np.asarray(angle, dtype=float)
    return np.stack([np.cos(angle), np.sin(angle)], axis=-1)


def perp(vectors: np.ndarray) -> np.ndarray:
    """``E x`` with ``E = [[0, -1], [1, 0]]`` (right-angle rotation), over ``(..., 2)``."""
    return np.stack([-vectors[..., 1], vectors[..., 0]], axis=-1)


#: The paper's P-P-R leg (kept under its historical name).
Leg = PPRLeg


@dataclass(frozen=True)
class Manipulator(_tomlio.TomlPresets):
    """A planar parallel manipulator with three legs, each a chain of three one-DOF joints.

    ``legs`` are designer leg types (:class:`~pmaccuracy.model.legs.PPRLeg` of the
    paper, :class:`~pmaccuracy.model.legs.RPRLeg`, :class:`~pmaccuracy.model.legs.RRRLeg`,
    :class:`~pmaccuracy.model.legs.PRRLeg` or the general :class:`~pmaccuracy.model.legs.ChainLeg`,
    mixed as needed); every computation goes through their :attr:`chains`
    (:class:`~pmaccuracy.model.chain.Chain`), so nothing above the legs depends on
    the architecture.

    For a 3-PPR the paper's per-leg parameters are available as arrays of
    shape ``(3,)`` (``robot.a``, ``robot.alpha``, ...) and the directions of
    Eq. 1 as ``robot.h``, ``robot.u``, ``robot.v``, ``robot.w`` of shape ``(3, 2)``.

    Build one with :meth:`preset`, :meth:`from_toml`, :meth:`load` (either) or
    directly from three legs; :meth:`perturbed` returns a 3-PPR copy with small
    parameter changes (the error model's variations, Eq. 6).

    >>> robot = Manipulator.preset("symmetric_3rpr")
    >>> robot.architecture, [c.label for c in robot.chains]
    ('3-RPR', ['RP_R', 'RP_R', 'RP_R'])
    """

    legs: tuple[LegType, LegType, LegType]
    name: str = "custom"
    description: str = ""
    #: Twist dimension: 3 (``[dx, dy, dphi]``); a :class:`~pmaccuracy.model.spatial.SpatialManipulator` has 6.
    dimension: ClassVar[int] = 3
    KIND: ClassVar[str] = "robot"
    PRESET_FOLDER: ClassVar[str] = "robots"

    def __post_init__(self) -> None:
        if len(self.legs) != 3:
            raise GeometryError(f"a planar 3-DOF parallel manipulator needs exactly three legs, got "
                                f"{len(self.legs)}", source=self.name)
        for i, leg in enumerate(self.legs, start=1):
            where = f"legs[{i}]"
            if not isinstance(leg, LegType):
                raise GeometryError(f"not a leg type: {type(leg).__name__}", source=self.name, key=where)
            for name, value in _numbers(leg):
                if not np.all(np.isfinite(np.asarray(value, dtype=float))):
                    if not (name.endswith("range") and isinstance(leg, ChainLeg)):
                        raise GeometryError("must be finite", source=self.name, key=f"{where}.{name}")
            if isinstance(leg, PPRLeg):
                _check_ppr_leg(leg, self.name, where)
        chains = self.chains  # builds and checks every chain
        if all(isinstance(leg, PPRLeg) for leg in self.legs):
            bearing = np.array([leg.alpha + leg.beta + leg.gamma + leg.theta for leg in self.legs])
            if np.all(np.abs(np.sin(bearing - bearing[0])) < MIN_GUIDE_BEARING_SINE):
                raise GeometryError("all three bearings are parallel: the matrix A of Eq. 4a is singular at "
                                    "every pose (the platform can slide along them)", source=self.name, key="legs")
        both_p = [i for i, c in enumerate(chains, start=1)
                  if all(c.joints[k].kind == "P" for k in c.passive_indices)]
        if len(both_p) > 1:
            raise GeometryError(f"legs {both_p[0]} and {both_p[1]} both have two passive prismatic joints: they "
                                "fix the orientation twice and leave the platform a free translation",
                                source=self.name, key="legs")

    def _check_coincident(self, chains: tuple[Chain, ...]) -> None:
        """Two legs attached at the same base point and the same platform point constrain nothing new."""
        scale = max(1.0, *(abs(c.base_z) for c in chains), *(abs(c.platform_z) for c in chains))
        for i in range(3):
            for j in range(i + 1, 3):
                a, b = chains[i], chains[j]
                if (abs(a.base_z - b.base_z) <= 1e-9 * scale and abs(a.platform_z - b.platform_z) <= 1e-9 * scale
                        and a.pattern == b.pattern and a.actuated_index == b.actuated_index
                        and abs(np.sin(a.base_angle - b.base_angle)) < 1e-9):
                    raise GeometryError(f"legs {i + 1} and {j + 1} have coincident base and platform points",
                                        source=self.name, key=f"legs[{j + 1}]")

    # ------------------------------------------------------------------ structure
    @cached_property
    def chains(self) -> tuple[Chain, Chain, Chain]:
        """The legs in the general chain form (:class:`~pmaccuracy.model.chain.Chain`)."""
        out = []
        for i, leg in enumerate(self.legs, start=1):
            try:
                out.append(leg.chain)
            except GeometryError as exc:
                raise GeometryError(exc.message, source=self.name, key=f"legs[{i}].{exc.key}") from None
        return tuple(out)

    @property
    def architecture(self) -> str:
        """``"3-PPR"``, ``"3-RPR"``, ``"3-RRR"``, ``"3-PRR"`` for three legs of one designer type, else ``"chain"``."""
        kinds = {type(leg) for leg in self.legs}
        return next(iter(kinds)).ARCHITECTURE if len(kinds) == 1 else "chain"

    @property
    def is_3ppr(self) -> bool:
        """True when every leg is the paper's P-P-R leg (the error model of the paper applies)."""
        return all(isinstance(leg, PPRLeg) for leg in self.legs)

    def require_3ppr(self, what: str) -> "Manipulator":
        """Return self, or raise :class:`UnsupportedArchitectureError` naming ``what`` needs a 3-PPR."""
        if not self.is_3ppr:
            raise UnsupportedArchitectureError(
                f"{what} is implemented for 3-PPR robots only so far; {self.name!r} is a "
                f"{self.architecture} ({', '.join(c.label for c in self.chains)})", source=self.name)
        return self

    # ------------------------------------------------------------------ constructors
    @classmethod
    def preset(cls, name: str = "aalborg_3ppr") -> "Manipulator":
        """A built-in robot by name (see :meth:`preset_names`); default: the paper's prototype ``aalborg_3ppr``."""
        return super().preset(name)

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "<dict>") -> "Manipulator":
        """Build from the parsed TOML table (degrees in ``*_deg`` keys); ``architecture`` picks the leg type.

        Also refuses geometries that can reach no pose at all within their joint
        ranges (:func:`pmaccuracy.kinematics.check_reachable`, by :func:`pmaccuracy.kinematics.resolve_robot`:
        every public entry point that reads a robot file).
        """
        arch = data.get("architecture", "3-PPR")
        if not isinstance(arch, str):
            raise ConfigError(f"must be a name such as \"3-PPR\" or \"6-UPS\", got {arch!r}",
                              source=source, key="architecture")
        if arch == "serial":
            raise UnsupportedArchitectureError(
                "this is a planar serial arm: it works with 'pmaccuracy bounds --joints Q1 Q2 ...' "
                "(pmaccuracy.model.serial.SerialArm); the other commands take parallel robots", source=source,
                key="architecture")
        if arch in SPATIAL_ARCHITECTURES:
            raise UnsupportedArchitectureError(
                f"this is a spatial robot ({arch}): load it with pmaccuracy.load_robot or "
                "pmaccuracy.model.spatial.SpatialManipulator", source=source, key="architecture")
        _tomlio.reject_unknown(data, {"architecture", "name", "description", "legs"}, source=source, where="")
        leg_type = LEG_TYPES.get(arch) if isinstance(arch, str) else None
        if leg_type is None:
            raise ConfigError(f"unknown architecture {arch!r} (expected one of {', '.join(LEG_TYPES)})",
                              source=source, key="architecture")
        legs = []
        for i, table in enumerate(_tomlio.legs_table(data, source=source), start=1):
            where = f"legs[{i}]"
            _tomlio.reject_unknown(table, leg_type.KEYS, source=source, where=where)
            legs.append(leg_type.from_table(table, source=source, where=where))
        name = data.get("name", Path(source).stem if source.endswith(".toml") else source)
        if not isinstance(name, str):
            raise ConfigError("must be a string", source=source, key="name")
        try:
            robot = cls(legs=tuple(legs), name=name, description=str(data.get("description", "")))
            robot._check_coincident(robot.chains)
        except GeometryError as exc:
            raise GeometryError(exc.message, source=source, key=exc.key) from None
        return robot

    def to_dict(self) -> dict[str, Any]:
        """The TOML table of this robot (degrees in ``*_deg`` keys)."""
        arch = self.architecture
        legs = [leg.to_table() for leg in self.legs] if arch != "chain" else \
            [ChainLeg(leg.chain).to_table() for leg in self.legs]
        out: dict[str, Any] = {"architecture": arch, "name": self.name}
        if self.description:
            out["description"] = self.description
        out["legs"] = legs
        return out

    def perturbed(self, **changes: np.ndarray | list[float]) -> "Manipulator":
        """A copy with per-leg additive changes, e.g. ``perturbed(theta=[0, 1e-3, 0])`` (mm, rad); 3-PPR only.

        Keys are :data:`LINK_PARAMETERS`; each value has shape ``(3,)``. Used for
        assembly errors (Table 2) and for the finite-difference checks of Eq. 6-11.
        """
        self.require_3ppr("perturbed()")
        unknown = set(changes) - set(LINK_PARAMETERS)
        if unknown:
            raise ValueError(f"unknown link parameters {sorted(unknown)}; expected {LINK_PARAMETERS}")
        deltas = {k: np.broadcast_to(np.asarray(v, dtype=float), (3,)) for k, v in changes.items()}
        legs = tuple(
            dataclasses.replace(leg, **{k: getattr(leg, k) + float(dv[i]) for k, dv in deltas.items()})
            for i, leg in enumerate(self.legs)
        )
        return dataclasses.replace(self, legs=legs)

    # ------------------------------------------------------------------ per-leg arrays
    def _column(self, name: str) -> np.ndarray:
        self.require_3ppr(f"the paper's parameter {name!r}")
        return np.array([getattr(leg, name) for leg in self.legs], dtype=float)

    @cached_property
    def a(self) -> np.ndarray:
        """Base distances ``a_i`` (mm), shape (3,)."""
        return self._column("a")

    @cached_property
    def alpha(self) -> np.ndarray:
        """Base angles ``alpha_i`` (rad), shape (3,)."""
        return self._column("alpha")

    @cached_property
    def beta(self) -> np.ndarray:
        """Guide angles ``beta_i`` relative to ``h_i`` (rad), shape (3,)."""
        return self._column("beta")

    @cached_property
    def gamma(self) -> np.ndarray:
        """Offset angles ``gamma_i`` relative to ``u_i`` (rad), shape (3,)."""
        return self._column("gamma")

    @cached_property
    def theta(self) -> np.ndarray:
        """Bearing angles ``theta_i`` relative to ``v_i`` (rad), shape (3,)."""
        return self._column("theta")

    @cached_property
    def d(self) -> np.ndarray:
        """Offsets ``d_i = |B_i C_i|`` (mm), shape (3,)."""
        return self._column("d")

    @cached_property
    def r(self) -> np.ndarray:
        """Platform radii ``r_i = |D_i P|`` (mm), shape (3,)."""
        return self._column("r")

    @cached_property
    def psi(self) -> np.ndarray:
        """Platform angles ``psi_i`` (rad), shape (3,): ``k_i = vec(phi + psi_i)``."""
        return self._column("psi")

    @cached_property
    def s_range(self) -> np.ndarray:
        """Actuated joint ranges (mm, or rad for an actuated R), shape (3, 2) as ``[min, max]`` rows."""
        return np.array([c.actuated.range for c in self.chains], dtype=float)

    @cached_property
    def actuated_kinds(self) -> tuple[str, str, str]:
        """``"R"`` or ``"P"`` for each leg's actuated joint."""
        return tuple(c.actuated.kind for c in self.chains)

    @cached_property
    def l_range(self) -> np.ndarray:
        """Passive bearing ranges of a 3-PPR (mm), shape (3, 2) as ``[min, max]`` rows."""
        self.require_3ppr("l_range")
        return np.array([leg.l_range for leg in self.legs], dtype=float)

    @cached_property
    def h(self) -> np.ndarray:
        """``h_i = vec(alpha_i)``, shape (3, 2)."""
        return unit(self.alpha)

    @cached_property
    def u(self) -> np.ndarray:
        """Guide directions ``u_i = vec(beta'_i)``, shape (3, 2)."""
        return unit(self.alpha + self.beta)

    @cached_property
    def v(self) -> np.ndarray:
        """Offset directions ``v_i = vec(gamma'_i)``, shape (3, 2)."""
        return unit(self.alpha + self.beta + self.gamma)

    @cached_property
    def w(self) -> np.ndarray:
        """Bearing directions ``w_i = vec(theta'_i)``, shape (3, 2)."""
        return unit(self.alpha + self.beta + self.gamma + self.theta)

    @cached_property
    def base_points(self) -> np.ndarray:
        """Origins of the legs' base frames (mm), shape (3, 2); ``A_i = a_i h_i`` for a 3-PPR."""
        return np.array([c.base for c in self.chains], dtype=float)

    @cached_property
    def platform_attachments(self) -> np.ndarray:
        """The legs' end points in the platform frame (mm), shape (3, 2); ``-r_i vec(psi_i)`` for a 3-PPR."""
        return np.array([c.platform for c in self.chains], dtype=float)

    @property
    def characteristic_length(self) -> float:
        """Mean distance of the legs' platform points from P (mm; the platform radius of a 3-PPR).

        Turns the rotation column of A into a length for a dimensionally
        homogeneous condition number; falls back to the mean distance of the
        base points from the origin when the legs all end at P.
        """
        r = float(np.mean(np.hypot(*self.platform_attachments.T)))
        if r > 1e-9:
            return r
        return max(1.0, float(np.mean(np.hypot(*self.base_points.T))))

    def platform_points(self, poses: np.ndarray) -> np.ndarray:
        """The legs' platform points in the base frame, ``p + Rot(phi) d_i`` (mm): ``(..., 3)`` -> ``(..., 3, 2)``.

        For a 3-PPR these are the revolute centres ``D_i = p - r_i k_i``.
        """
        poses = np.asarray(poses, dtype=float)
        c, s = np.cos(poses[..., 2]), np.sin(poses[..., 2])
        d = self.platform_attachments
        rot = np.stack([c[..., None] * d[:, 0] - s[..., None] * d[:, 1],
                        s[..., None] * d[:, 0] + c[..., None] * d[:, 1]], axis=-1)
        return poses[..., None, :2] + rot


def _numbers(leg: LegType):
    """(name, value) of a leg's numeric parameters, for the finiteness check."""
    for f in dataclasses.fields(leg):
        value = getattr(leg, f.name)
        if isinstance(value, Chain):
            for j, joint in enumerate(value.joints, start=1):
                yield f"joints[{j}].link", joint.link
                yield f"joints[{j}].offset_deg", joint.offset
                yield f"joints[{j}].range", joint.range
            yield "base", value.base
            yield "platform", value.platform
        elif isinstance(value, (int, float, tuple)) and not isinstance(value, bool):
            yield f.name, value


def _check_ppr_leg(leg: PPRLeg, source: str, where: str) -> None:
    for length in ("a", "d"):
        if getattr(leg, length) < 0:
            raise GeometryError("a length must not be negative", source=source, key=f"{where}.{length}")
    if leg.r <= 0:
        raise GeometryError("the platform radius must be positive", source=source, key=f"{where}.r")
    for rng in ("s_range", "l_range"):
        lo, hi = getattr(leg, rng)
        if not lo < hi:
            raise GeometryError(f"empty range [{lo}, {hi}]", source=source, key=f"{where}.{rng}")
    if abs(np.sin(leg.gamma + leg.theta)) < MIN_GUIDE_BEARING_SINE:
        raise GeometryError(
            "bearing parallel to the guide (gamma + theta = 0 or 180 deg): the matrix B of Eq. 4b "
            "is singular everywhere", source=source, key=where)
