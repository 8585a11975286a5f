"""Geometry of a planar 3-PPR parallel manipulator (paper Sec. 2, Eq. 1).

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
from .errors import ConfigError, GeometryError

#: Keys of one ``[[legs]]`` table in a robot file.
LEG_KEYS = {"a", "alpha_deg", "beta_deg", "gamma_deg", "theta_deg", "d", "r", "psi_deg", "s_range", "l_range"}
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


def round_trip_degrees(angle: float) -> float:
    """Degrees for a file or a coordinate: the shortest rounding that converts back to exactly ``angle`` rad.

    ``degrees(radians(210))`` is 209.99999999999997; writing 210.0 instead keeps
    the TOML round trip exact.
    """
    deg = float(np.degrees(angle))
    for digits in range(0, 16):
        candidate = round(deg, digits)
        if float(np.radians(candidate)) == float(angle):
            return candidate
    return deg


@dataclass(frozen=True)
class Leg:
    """One P-P-R leg (paper Fig. 2 and 4). Lengths in mm, angles in rad.

    ``s_range`` is the actuated prismatic joint's range, ``l_range`` the
    passive prismatic joint's (linear bearing) range.
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


@dataclass(frozen=True)
class Manipulator(_tomlio.TomlPresets):
    """A planar 3-PPR manipulator: three :class:`Leg` and a name.

    Per-leg parameters are available as arrays of shape ``(3,)`` (``robot.a``,
    ``robot.alpha``, ...); the directions of Eq. 1 as ``robot.h``, ``robot.u``,
    ``robot.v``, ``robot.w`` of shape ``(3, 2)``.

    Build one with :meth:`preset`, :meth:`from_toml`, :meth:`load` (either) or
    directly from three legs; :meth:`perturbed` returns a copy with small
    parameter changes (the error model's variations, Eq. 6).
    """

    legs: tuple[Leg, Leg, Leg]
    name: str = "custom"
    description: str = ""
    KIND: ClassVar[str] = "robot"
    PRESET_FOLDER: ClassVar[str] = "robots"

    def __post_init__(self) -> None:
        if len(self.legs) != 3:
            raise GeometryError(f"a 3-PPR needs exactly three legs, got {len(self.legs)}", source=self.name)
        for i, leg in enumerate(self.legs, start=1):
            where = f"legs[{i}]"
            for field in dataclasses.fields(Leg):
                value = np.asarray(getattr(leg, field.name), dtype=float)
                if not np.all(np.isfinite(value)):
                    raise GeometryError("must be finite", source=self.name, key=f"{where}.{field.name}")
            for length in ("a", "d"):
                if getattr(leg, length) < 0:
                    raise GeometryError("a length must not be negative", source=self.name, key=f"{where}.{length}")
            if leg.r <= 0:
                raise GeometryError("the platform radius must be positive", source=self.name, key=f"{where}.r")
            for rng in ("s_range", "l_range"):
                lo, hi = getattr(leg, rng)
                if not lo < hi:
                    raise GeometryError(f"empty range [{lo}, {hi}]", source=self.name, key=f"{where}.{rng}")
            if abs(np.sin(leg.gamma + leg.theta)) < MIN_GUIDE_BEARING_SINE:
                raise GeometryError(
                    "bearing parallel to the guide (gamma + theta = 0 or 180 deg): the matrix B of Eq. 4b "
                    "is singular everywhere",
                    source=self.name, key=where)

        bearing = np.array([leg.alpha + leg.beta + leg.gamma + leg.theta for leg in self.legs])
        if np.all(np.abs(np.sin(bearing - bearing[0])) < MIN_GUIDE_BEARING_SINE):
            raise GeometryError("all three bearings are parallel: the matrix A of Eq. 4a is singular at every "
                                "pose (the platform can slide along them)", source=self.name, key="legs")

    # ------------------------------------------------------------------ constructors
    @classmethod
    def preset(cls, name: str = "aalborg_3ppr") -> "Manipulator":
        """A built-in robot by name (``aalborg_3ppr``, ``symmetric_3ppr``); default: the paper's prototype."""
        return super().preset(name)

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "<dict>") -> "Manipulator":
        """Build from the parsed TOML table (degrees in ``*_deg`` keys)."""
        _tomlio.reject_unknown(data, {"architecture", "name", "description", "legs"}, source=source, where="")
        arch = data.get("architecture", "3-PPR")
        if arch != "3-PPR":
            raise ConfigError(f"unsupported architecture {arch!r} (only '3-PPR')", source=source, key="architecture")
        legs = []
        for i, table in enumerate(_tomlio.legs_table(data, source=source), start=1):
            where = f"legs[{i}]"
            _tomlio.reject_unknown(table, LEG_KEYS, source=source, where=where)
            num = lambda key, **kw: _tomlio.number(table, key, source=source, where=where, **kw)  # noqa: E731
            legs.append(Leg(
                a=num("a", nonnegative=True),
                alpha=np.radians(num("alpha_deg")),
                beta=np.radians(num("beta_deg")),
                gamma=np.radians(num("gamma_deg")),
                theta=np.radians(num("theta_deg")),
                d=num("d", nonnegative=True),
                r=num("r", positive=True),
                psi=np.radians(num("psi_deg")),
                s_range=_tomlio.interval(table, "s_range", source=source, where=where),
                l_range=_tomlio.interval(table, "l_range", source=source, where=where),
            ))
        name = data.get("name", Path(source).stem if source.endswith(".toml") else source)
        if not isinstance(name, str):
            raise ConfigError("must be a string", source=source, key="name")
        try:
            return cls(legs=tuple(legs), name=name, description=str(data.get("description", "")))
        except GeometryError as exc:
            raise GeometryError(exc.message, source=source, key=exc.key) from None

    def to_dict(self) -> dict[str, Any]:
        """The TOML table of this robot (degrees in ``*_deg`` keys)."""
        legs = []
        for leg in self.legs:
            legs.append({
                "a": float(leg.a),
                "alpha_deg": round_trip_degrees(leg.alpha),
                "beta_deg": round_trip_degrees(leg.beta),
                "gamma_deg": round_trip_degrees(leg.gamma),
                "theta_deg": round_trip_degrees(leg.theta),
                "d": float(leg.d),
                "r": float(leg.r),
                "psi_deg": round_trip_degrees(leg.psi),
                "s_range": [float(v) for v in leg.s_range],
                "l_range": [float(v) for v in leg.l_range],
            })
        out: dict[str, Any] = {"architecture": "3-PPR", "name": self.name}
        if self.description:
            out["description"] = self.description
        out["legs"] = legs
        return out

    def perturbed(self, **changes: np.ndarray | list[float]) -> "Manipulator":
        """A copy with per-leg additive changes, e.g. ``perturbed(theta=[0, 1e-3, 0])`` (mm, rad).

        Keys are :data:`LINK_PARAMETERS`; each value has shape ``(3,)``. Used for
        assembly errors (Table 2) and for the finite-difference checks of Eq. 6-11.
        """
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
        """Offsets ``d_i`` = |B_i C_i| (mm), shape (3,)."""
        return self._column("d")

    @cached_property
    def r(self) -> np.ndarray:
        """Platform radii ``r_i`` = |D_i P| (mm), shape (3,)."""
        return self._column("r")

    @cached_property
    def psi(self) -> np.ndarray:
        """Platform angles ``psi_i`` (rad), shape (3,): ``k_i = vec(phi + psi_i)``."""
        return self._column("psi")

    @cached_property
    def s_range(self) -> np.ndarray:
        """Actuated joint ranges (mm), shape (3, 2) as ``[min, max]`` rows."""
        return np.array([leg.s_range for leg in self.legs], dtype=float)

    @cached_property
    def l_range(self) -> np.ndarray:
        """Passive joint ranges (mm), shape (3, 2) as ``[min, max]`` rows."""
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
        """Points ``A_i = a_i h_i`` (mm), shape (3, 2)."""
        return self.a[:, None] * self.h

    @property
    def characteristic_length(self) -> float:
        """Mean platform radius (mm): turns the rotation column of A into a length for conditioning."""
        return float(np.mean(self.r))

    def platform_points(self, poses: np.ndarray) -> np.ndarray:
        """Revolute centres ``D_i = p - r_i k_i`` (mm) for poses ``(..., 3)`` -> ``(..., 3, 2)``."""
        poses = np.asarray(poses, dtype=float)
        k = unit(poses[..., None, 2] + self.psi)
        return poses[..., None, :2] - self.r[:, None] * k
