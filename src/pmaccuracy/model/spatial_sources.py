"""Error sources of spatial robots: per-joint clearances, actuator errors and geometric tolerances.

The format and the physical meaning of every key are in ``docs/guide/spatial-errors.md``: each source is a
segment, a disc or a ball of small displacements (translations in mm, rotations in rad) of a joint's distal
part relative to its proximal part, about the physical part. :class:`SpatialErrorSources` holds the half-widths
(a frozen description, no geometry); :mod:`pmaccuracy.accuracy.spatial_bounds` turns them into the platform's
error at poses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, ClassVar

from . import _tomlio, plausibility
from ..errors import ClearanceError, ConfigError

#: Joint kinds of each spatial architecture's leg, base to platform, and the actuated joint's index.
JOINTS = {"6-UPS": ("U", "P", "S"), "3-RPS": ("R", "P", "S"), "3-PRS": ("P", "R", "S"), "3-UPU": ("U", "P", "U"),
          "delta": ("R", "S", "S", "S", "S")}
ACTUATED = {"6-UPS": 1, "3-RPS": 1, "3-PRS": 0, "3-UPU": 1, "delta": 0}
#: The joints followed by a link whose length can be off (``length``): every joint but the platform's.
LENGTH_JOINTS = {"6-UPS": (0, 1), "3-RPS": (0, 1), "3-PRS": (0, 1), "3-UPU": (0, 1), "delta": (0, 1, 3)}
#: Keys each joint kind takes (``actuator``/``backlash`` on the actuated joint only; ``length`` on
#: :data:`LENGTH_JOINTS`).
KEYS = {"S": {"radial", "position"}, "R": {"radial", "axial", "tilt", "position", "direction"},
        "U": {"radial", "axial", "tilt", "position", "direction"},
        "P": {"lateral", "tilt", "position", "direction"}, "C": {"radial", "tilt", "position", "direction"}}
#: The architecture of robots whose legs are joint chains: their joints are read from the robot.
CHAIN = "spatial-chain"
#: Unit of each key (for messages and plausibility).
UNITS = {"radial": "mm", "axial": "mm", "tilt": "rad", "actuator": "mm or rad", "backlash": "mm", "lateral": "mm",
         "position": "mm", "direction": "rad", "length": "mm"}


def allowed_keys(architecture: str, joint: int, spec: tuple | None = None) -> set[str]:
    """The keys of joint ``joint`` (0-based) of a leg of ``architecture`` (a chain leg: of its ``spec``,
    :func:`leg_spec`)."""
    kinds, actuated, lengths = spec if spec is not None else leg_spec(architecture)
    keys = set(KEYS[kinds[joint]])
    if joint == actuated:
        keys |= {"actuator", "backlash"}
    if joint in lengths:
        keys.add("length")
    return keys


def leg_spec(architecture: str, leg=None) -> tuple[tuple[str, ...], int, tuple[int, ...]]:
    """``(joint kinds, actuated joint, joints followed by a link with a length source)`` of a leg: the
    architecture's (:data:`JOINTS`), or a chain leg's own joints (no ``length`` sources)."""
    if architecture == CHAIN:
        kinds = tuple(j.kind for j in leg.joints)
        return kinds, next(k for k, j in enumerate(leg.joints) if j.actuated), ()
    return JOINTS[architecture], ACTUATED[architecture], LENGTH_JOINTS[architecture]


@dataclass(frozen=True)
class SpatialJointErrors:
    """Half-widths of one joint's error sources (``docs/guide/spatial-errors.md``); all 0 by default.
    Lengths in mm, angles in rad (``actuator`` of a Delta's arm: rad)."""

    radial: float = 0.0
    axial: float = 0.0
    tilt: float = 0.0
    actuator: float = 0.0
    backlash: float = 0.0
    lateral: float = 0.0
    position: float = 0.0
    direction: float = 0.0
    length: float = 0.0

    def items(self):
        """``(key, half-width)`` of the non-zero sources."""
        return [(f.name, getattr(self, f.name)) for f in fields(self) if getattr(self, f.name)]

    def scaled(self, factor: float) -> "SpatialJointErrors":
        return SpatialJointErrors(**{f.name: getattr(self, f.name) * factor for f in fields(self)})


@dataclass(frozen=True)
class SpatialErrorSources:
    """The error sources of a spatial robot: one tuple of :class:`SpatialJointErrors` per leg, base to platform
    (:data:`JOINTS` gives each architecture's joints)."""

    architecture: str
    legs: tuple[tuple[SpatialJointErrors, ...], ...]
    name: str = "custom"
    description: str = ""
    #: A chain robot's legs: each leg's :func:`leg_spec` (``None`` for the designer architectures).
    specs: tuple | None = None
    KIND: ClassVar[str] = "clearance"

    def __post_init__(self) -> None:
        if self.architecture not in JOINTS and self.architecture != CHAIN:
            raise ConfigError(f"no spatial error model for architecture {self.architecture!r}", key="architecture")
        if self.architecture == CHAIN and (self.specs is None or len(self.specs) != len(self.legs)):
            raise ConfigError("a chain robot's error sources need its legs' joints (build them with "
                              "SpatialErrorSources.from_dict(data, robot))", key="legs")
        for i, leg in enumerate(self.legs, start=1):
            spec = self.spec(i - 1)
            n = len(spec[0])
            if len(leg) != n:
                raise ClearanceError(f"a {self.architecture} leg has {n} joints, got {len(leg)}",
                                     key=f"legs[{i}].joints")
            for j, joint in enumerate(leg):
                for key, value in joint.items():
                    if not (math.isfinite(value) and value >= 0):
                        raise ClearanceError(f"must be a finite number >= 0, got {value}",
                                             key=f"legs[{i}].joints[{j + 1}].{key}")
                    allowed = allowed_keys(self.architecture, j, spec)
                    if key not in allowed:
                        raise ClearanceError(f"a {JOINT_WORDS[spec[0][j]]} of a {self.architecture} takes no "
                                             f"{key!r} (keys: {', '.join(sorted(allowed))})",
                                             key=f"legs[{i}].joints[{j + 1}].{key}")

    def spec(self, leg: int) -> tuple:
        """Leg ``leg``'s (0-based) :func:`leg_spec`."""
        return self.specs[leg] if self.specs is not None else leg_spec(self.architecture)

    @classmethod
    def zero(cls, robot) -> "SpatialErrorSources":
        """No error at all (``none``)."""
        specs = _specs(robot)
        return cls(architecture=robot.architecture,
                   legs=tuple((SpatialJointErrors(),) * len(spec[0]) for spec in specs), name="none",
                   specs=specs if robot.architecture == CHAIN else None)

    def scaled(self, factor: float) -> "SpatialErrorSources":
        """Every half-width times ``factor``."""
        return SpatialErrorSources(self.architecture, tuple(tuple(j.scaled(factor) for j in leg)
                                                            for leg in self.legs), f"{self.name} x {factor:g}",
                                   self.description, self.specs)

    @classmethod
    def from_dict(cls, data: dict[str, Any], robot, source: str = "<dict>") -> "SpatialErrorSources":
        """Read the parsed TOML table for ``robot`` (a :class:`~pmaccuracy.model.spatial.SpatialManipulator`)."""
        arch = robot.architecture
        _tomlio.reject_unknown(data, {"name", "description", "legs"}, source=source, where="")
        legs = data.get("legs")
        count = robot.n_legs
        if not isinstance(legs, list) or not all(isinstance(t, dict) for t in legs):
            raise ClearanceError(f"missing or malformed [[legs]] tables ({count} are needed for {robot.name})",
                                 source=source, key="legs")
        if len(legs) != count:
            raise ClearanceError(f"{robot.name} has {count} legs, the file lists {len(legs)}", source=source,
                                 key="legs")
        specs = _specs(robot)
        out = []
        for i, table in enumerate(legs, start=1):
            spec = specs[i - 1]
            n = len(spec[0])
            _tomlio.reject_unknown(table, {"joints"}, source=source, where=f"legs[{i}]")
            joints = table.get("joints")
            if not isinstance(joints, list) or len(joints) != n or not all(isinstance(j, dict) for j in joints):
                raise ClearanceError(f"must list the leg's {n} joints ({', '.join(JOINT_WORDS[k] for k in spec[0])}"
                                     ") as tables", source=source, key=f"legs[{i}].joints")
            parsed = []
            for j, joint in enumerate(joints):
                where = f"legs[{i}].joints[{j + 1}]"
                allowed = allowed_keys(arch, j, spec)
                for key in joint:
                    if key not in allowed:
                        raise ClearanceError(f"unknown key for a {JOINT_WORDS[spec[0][j]]}; expected one of "
                                             f"{', '.join(sorted(allowed))}", source=source, key=f"{where}.{key}")
                parsed.append(SpatialJointErrors(**{key: _tomlio.number(joint, key, source=source, where=where,
                                                                        nonnegative=True) for key in joint}))
            out.append(tuple(parsed))
        name = data.get("name", Path(source).stem if source.endswith(".toml") else source)
        result = cls(architecture=arch, legs=tuple(out), name=str(name), description=str(data.get("description", "")),
                     specs=specs if arch == CHAIN else None)
        plausibility.warn(spatial_sources_messages(result, source), stacklevel=3)
        return result

    @classmethod
    def load(cls, spec, robot) -> "SpatialErrorSources":
        """From a TOML path (or an instance, returned as it is; ``"none"``: no error)."""
        if isinstance(spec, cls):
            return spec
        if str(spec) == "none":
            return cls.zero(robot)
        data, source = _tomlio.read_spec(spec, kind="clearance", folder=PRESET_FOLDER)
        return cls.from_dict(data, robot, source=source)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"name": self.name}
        if self.description:
            out["description"] = self.description
        out["legs"] = [{"joints": [dict(j.items()) for j in leg]} for leg in self.legs]
        return out


def _specs(robot) -> tuple:
    """Every leg's :func:`leg_spec`."""
    return tuple(leg_spec(robot.architecture, leg) for leg in robot.legs)


#: Folder of the spatial error-source presets (``data/spatial_clearances``).
PRESET_FOLDER = "spatial_clearances"
#: The preset of each architecture that commands use when none is given.
DEFAULT_PRESET = {"6-UPS": "ups_typical", "delta": "delta_typical", "3-RPS": "rps_typical",
                  "3-PRS": "prs_typical", "3-UPU": "upu_typical"}

def default_preset(robot) -> str:
    """The preset a command uses when no error sources are given (:data:`DEFAULT_PRESET`); a chain robot has
    none (:class:`~pmaccuracy.errors.ClearanceError` says to give a file)."""
    if robot.architecture not in DEFAULT_PRESET:
        raise ClearanceError(f"a {robot.architecture} robot has no default error sources: give a file with one "
                             "[[legs]] table per leg and one {...} per joint (docs/guide/spatial-errors.md)",
                             key="clearances")
    return DEFAULT_PRESET[robot.architecture]


#: Words for the joint kinds in messages.
JOINT_WORDS = {"S": "spherical joint", "R": "revolute", "U": "universal joint", "P": "prismatic joint",
               "C": "cylindrical joint"}


def spatial_sources_messages(sources: SpatialErrorSources, source: str | None = None) -> list[str]:
    """Plausibility warnings: angles that look like degrees (a tilt of 0.5 'rad' is 29 deg), lengths that look
    like metres or microns are left to the shared rules of :func:`pmaccuracy.model.plausibility.clearance_messages`."""
    values = {}
    for i, leg in enumerate(sources.legs, start=1):
        kinds, actuated, _ = sources.spec(i - 1)
        for j, joint in enumerate(leg, start=1):
            for key, value in joint.items():
                angular_actuator = key == "actuator" and (sources.architecture == "delta" or
                                                          (j - 1 == actuated and kinds[j - 1] == "R"))
                unit = "rad" if key in ("tilt", "direction") or angular_actuator else "mm"
                values[f"legs[{i}].joints[{j}].{key}"] = (value, unit)
    messages = plausibility.clearance_messages(values)
    return [f"{source}: {m}" for m in messages] if source else messages
