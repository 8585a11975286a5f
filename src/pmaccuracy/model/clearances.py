"""Joint-clearance model (paper Sec. 4.2, Eq. 16-18).

Per leg ``i`` the clearances let three joints move within bounds:

* linear guide of the actuated joint (lateral clearance ``eps_g``, block length
  ``L_g``): lateral shift ``dsigma_g`` and tilt ``dtau_g`` in the rhombus
  ``|L_g dtau_g +- 2 dsigma_g| <= 2 eps_g`` (Eq. 16a, 16b). They enter the error
  model as ``delta d_i`` and ``delta gamma_i`` (Sec. 4.2): the paper's
  parameterization, in which the shift acts along ``v_i`` (the guide's normal
  when ``gamma_i = +-90 deg``, as on both presets);
* linear bearing of the passive joint (angular clearance ``eps_theta``): tilt
  ``|dtau_b| <= eps_theta`` (Eq. 17), entering as ``delta theta_i``;
* revolute joint between leg and platform (radial clearance ``eps_r``): the
  platform's hole centre ``D'_i`` lies within ``eps_r`` of the pin ``D_i``,
  ``D'_i = D_i + drho n_i``, ``n_i = vec(varphi_i)``, ``0 <= drho <= eps_r`` (Eq. 18).

File format (TOML; every key optional and 0 by default, ``guide_block_length``
50 mm by default)::

    name = "case2"
    [[legs]]                  # exactly three
    bearing_angle = 0.0012    # eps_theta, rad
    guide_lateral = 0.0       # eps_g, mm (half the catalogue's lateral clearance 2 eps_g)
    guide_block_length = 50.0 # L_g, mm
    revolute_radial = 0.039   # eps_r, mm
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from . import _tomlio
from ..errors import ClearanceError, ConfigError
from . import plausibility
from .sources import JointDisplacements, is_per_joint

#: Keys of one ``[[legs]]`` table of a clearance file.
CLEARANCE_KEYS = {"bearing_angle", "guide_lateral", "guide_block_length", "revolute_radial"}
DEFAULT_GUIDE_BLOCK_LENGTH = 50.0


def _as3(name: str, value: Any, *, positive: bool = False) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ClearanceError(f"{name} must be a number or 3 numbers (one per leg), got {value!r}") from None
    if arr.ndim > 1 or arr.ndim == 1 and arr.shape[0] != 3:
        raise ClearanceError(f"{name}: expected 3 values (one per leg), got shape {arr.shape}")
    arr = np.broadcast_to(arr, (3,)).copy()
    if not np.all(np.isfinite(arr)):
        raise ClearanceError(f"{name} must be finite, got {arr.tolist()}")
    if positive and np.any(arr <= 0):
        raise ClearanceError(f"{name} must be positive, got {arr.tolist()}")
    if np.any(arr < 0):
        raise ClearanceError(f"{name} must not be negative (a clearance is a bound), got {arr.tolist()}")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class ClearanceSet(_tomlio.TomlPresets):
    """Clearance bounds of the three legs (arrays of shape (3,)).

    Attributes
    ----------
    bearing_angle : rad, ``eps_theta_i`` of the linear bearings (Eq. 17)
    guide_lateral : mm, ``eps_g_i`` of the linear guides (Eq. 16)
    guide_block_length : mm, ``L_g`` (Eq. 16)
    revolute_radial : mm, ``eps_r_i`` of the revolute joints (Eq. 18)
    """

    bearing_angle: np.ndarray
    guide_lateral: np.ndarray
    guide_block_length: np.ndarray
    revolute_radial: np.ndarray
    name: str = "custom"
    description: str = ""
    KIND: ClassVar[str] = "clearance"
    PRESET_FOLDER: ClassVar[str] = "clearances"

    def __init__(self, bearing_angle: Any = 0.0, guide_lateral: Any = 0.0,
                 guide_block_length: Any = DEFAULT_GUIDE_BLOCK_LENGTH, revolute_radial: Any = 0.0,
                 name: str = "custom", description: str = "") -> None:
        object.__setattr__(self, "bearing_angle", _as3("bearing_angle", bearing_angle))
        object.__setattr__(self, "guide_lateral", _as3("guide_lateral", guide_lateral))
        object.__setattr__(self, "guide_block_length",
                           _as3("guide_block_length", guide_block_length, positive=True))
        object.__setattr__(self, "revolute_radial", _as3("revolute_radial", revolute_radial))
        object.__setattr__(self, "name", name)
        object.__setattr__(self, "description", description)
        if plausibility.called_by_user():   # built in Python (files are checked by their reader): units
            plausibility.warn(plausibility.clearance_set_messages(self, "ClearanceSet"))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ClearanceSet):
            return NotImplemented
        return all(np.array_equal(getattr(self, k), getattr(other, k)) for k in CLEARANCE_KEYS) and \
            self.name == other.name

    __hash__ = None  # type: ignore[assignment]

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "<dict>") -> "ClearanceSet":
        """Build from the parsed TOML table."""

        if is_per_joint(data):
            raise ClearanceError("this file lists each leg's joints (the per-joint format of any architecture): "
                                 "read it with pmaccuracy.load_clearances(spec, robot)",
                                 source=source, key="legs")
        _tomlio.reject_unknown(data, {"name", "description", "legs"}, source=source, where="")
        columns: dict[str, list[float]] = {k: [] for k in CLEARANCE_KEYS}
        for i, table in enumerate(_tomlio.legs_table(data, source=source), start=1):
            where = f"legs[{i}]"
            _tomlio.reject_unknown(table, CLEARANCE_KEYS, source=source, where=where)
            for key in CLEARANCE_KEYS:
                default = DEFAULT_GUIDE_BLOCK_LENGTH if key == "guide_block_length" else 0.0
                try:
                    columns[key].append(_tomlio.number(table, key, source=source, where=where, default=default,
                                                       nonnegative=True, positive=key == "guide_block_length"))
                except ConfigError as exc:
                    raise ClearanceError(exc.message, source=source, key=exc.key) from None
        name = data.get("name", Path(source).stem)
        result = cls(**columns, name=str(name), description=str(data.get("description", "")))

        plausibility.warn(plausibility.clearance_set_messages(result, source), stacklevel=2)
        return result

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"name": self.name}
        if self.description:
            out["description"] = self.description
        out["legs"] = [{k: float(getattr(self, k)[i]) for k in sorted(CLEARANCE_KEYS)} for i in range(3)]
        return out

    def only(self, *sources: str) -> "ClearanceSet":
        """A copy keeping only some sources (``"bearing"``, ``"guide"``, ``"revolute"``), others set to 0."""
        unknown = set(sources) - {"bearing", "guide", "revolute"}
        if unknown:
            raise ValueError(f"unknown clearance sources {sorted(unknown)}")
        return ClearanceSet(
            bearing_angle=self.bearing_angle if "bearing" in sources else 0.0,
            guide_lateral=self.guide_lateral if "guide" in sources else 0.0,
            guide_block_length=self.guide_block_length,
            revolute_radial=self.revolute_radial if "revolute" in sources else 0.0,
            name=f"{self.name}[{'+'.join(sources)}]")

    def scaled(self, factor: float) -> "ClearanceSet":
        """All clearance bounds multiplied by ``factor`` (>= 0); the block length is kept."""
        return ClearanceSet(self.bearing_angle * factor, self.guide_lateral * factor, self.guide_block_length,
                            self.revolute_radial * factor, name=f"{self.name}x{factor:g}")


@dataclass(frozen=True)
class ClearanceDisplacement:
    """Joint displacements inside the clearances (Eq. 16-18, the variables of Eq. 20b).

    Every field has shape ``(..., 3)`` (legs last):
    ``tau_b`` bearing tilt (rad), ``sigma_g`` guide lateral shift (mm),
    ``tau_g`` guide tilt (rad), ``rho`` revolute offset |D_i D'_i| (mm),
    ``varphi`` its direction in the base frame (rad), ``n_i = vec(varphi_i)``.
    """

    tau_b: np.ndarray
    sigma_g: np.ndarray
    tau_g: np.ndarray
    rho: np.ndarray
    varphi: np.ndarray

    @classmethod
    def zeros(cls, shape: tuple[int, ...] = ()) -> "ClearanceDisplacement":
        z = np.zeros(shape + (3,))
        return cls(z, z.copy(), z.copy(), z.copy(), z.copy())

    def scaled(self, factor: float) -> "ClearanceDisplacement":
        """Every displacement times ``factor`` (the direction ``varphi`` is kept)."""
        return ClearanceDisplacement(self.tau_b * factor, self.sigma_g * factor, self.tau_g * factor,
                                     self.rho * factor, self.varphi)

    def to_joint_displacements(self) -> JointDisplacements:
        """The same displacements as values of the 3-PPR chain's per-joint sources
        (:class:`~pmaccuracy.model.sources.JointDisplacements`, ``(..., 3 legs, 3 joints)``): the bearing tilt
        about ``C_i`` is the second joint's ``tilt``, the guide's shift and tilt its first joint's ``sigma`` and
        ``tau``, the revolute's offset ``rho vec(varphi)`` the third joint's ``shift``.

        >>> d = ClearanceDisplacement.zeros((2,))
        >>> d.to_joint_displacements().tilt.shape
        (2, 3, 3)
        """
        fields = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in
                                       (self.tau_b, self.sigma_g, self.tau_g, self.rho, self.varphi)))
        out = JointDisplacements.zeros(fields[0].shape[:-1])
        out.tilt[..., 1] = fields[0]
        out.sigma[..., 0] = fields[1]
        out.tau[..., 0] = fields[2]
        out.shift[..., 2] = fields[3] * np.exp(1j * fields[4])
        return out

    def violation(self, clearances: ClearanceSet) -> np.ndarray:
        """Largest relative violation of Eq. 16-18 (<= 0 inside the clearances), shape ``(...)``."""
        eps_b = np.maximum(clearances.bearing_angle, 1e-300)
        eps_g = np.maximum(clearances.guide_lateral, 1e-300)
        eps_r = np.maximum(clearances.revolute_radial, 1e-300)
        L = clearances.guide_block_length
        parts = [
            np.abs(self.tau_b) / eps_b - 1,
            np.abs(L * self.tau_g + 2 * self.sigma_g) / (2 * eps_g) - 1,
            np.abs(-L * self.tau_g + 2 * self.sigma_g) / (2 * eps_g) - 1,
            np.abs(self.rho) / eps_r - 1,
        ]
        return np.max(np.stack(parts, axis=-1), axis=(-1, -2))
