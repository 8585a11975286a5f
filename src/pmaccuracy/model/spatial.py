"""Spatial parallel manipulators: one frozen description with twist dimension 6 (the planar ones have 3).

A :class:`SpatialManipulator` holds its legs (:mod:`pmaccuracy.model.spatial_legs`), its name and its home pose;
it computes nothing about poses itself (that is :mod:`pmaccuracy.kinematics.spatial`). Its mobility says which
coordinates a user commands:

=========  ==========================  ================================  ==============================
mobility   architectures               controlled coordinates            the rest of the pose
=========  ==========================  ================================  ==============================
``6``      6-UPS                       x, y, z, roll, pitch, yaw         --
``3T``     delta, 3-UPU                x, y, z                           orientation fixed (identity)
``2R1T``   3-RPS, 3-PRS                z, roll, pitch                    x, y, yaw (parasitic motions)
=========  ==========================  ================================  ==============================

Angles are extrinsic x-y-z roll, pitch, yaw (``docs/guide/spatial.md``): degrees in files and on the command
line, radians in Python.

>>> robot = SpatialManipulator.preset("stewart_6ups")
>>> robot.architecture, robot.n_legs, robot.mobility
('6-UPS', 6, '6')
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from . import _tomlio
from ..errors import ConfigError, GeometryError
from ..numerics.spatial import euler_xyz_to_rotvec, rotvec_to_euler_xyz
from .spatial_chain import ChainLeg
from .spatial_legs import ARCHITECTURE_ALIASES, LEG_COUNT, SPATIAL_LEG_TYPES, SpatialLeg, vector

#: Names of the six pose coordinates in files and on the command line (lengths mm, angles deg).
POSE_NAMES = ("x", "y", "z", "roll", "pitch", "yaw")
#: Mobility of each architecture and the coordinates it takes (indices into :data:`POSE_NAMES`).
MOBILITY = {"6-UPS": "6", "delta": "3T", "3-UPU": "3T", "3-RPS": "2R1T", "3-PRS": "2R1T"}
CONTROLLED = {"6": (0, 1, 2, 3, 4, 5), "3T": (0, 1, 2), "2R1T": (2, 3, 4)}
#: The architecture of robots whose legs are joint chains (:mod:`pmaccuracy.model.spatial_chain`).
CHAIN = "spatial-chain"
#: Leg type of every spatial architecture, chains included.
LEG_TYPES = {**SPATIAL_LEG_TYPES, CHAIN: ChainLeg}
#: Display names of the architectures.
LABELS = {"6-UPS": "6-UPS (Gough-Stewart)", "delta": "Delta 3-R(SS)2", "3-UPU": "3-UPU (Tsai)",
          "3-RPS": "3-RPS", "3-PRS": "3-PRS"}


def is_spatial_architecture(name: object) -> bool:
    """True for an ``architecture`` value of a spatial robot file (aliases included)."""
    return isinstance(name, str) and (name in LEG_TYPES or name in ARCHITECTURE_ALIASES)


@dataclass(frozen=True)
class SpatialManipulator(_tomlio.TomlPresets):
    """A spatial parallel manipulator: legs of one architecture, a name, a home pose ``[p mm, rotvec rad]``.

    Build one with :meth:`preset`, :meth:`load` (a preset name or a TOML path) or :meth:`from_dict`.
    """

    architecture: str
    legs: tuple[SpatialLeg, ...]
    name: str = "custom"
    description: str = ""
    home: tuple[float, ...] | None = None
    #: The coordinates a chain robot's user commands (:data:`POSE_NAMES`); fixed by the architecture otherwise.
    controlled_names: tuple[str, ...] | None = None

    #: Twist dimension: 6 (the planar :class:`~pmaccuracy.model.manipulator.Manipulator` has 3).
    dimension: ClassVar[int] = 6
    KIND: ClassVar[str] = "robot"
    PRESET_FOLDER: ClassVar[str] = "robots"

    def __post_init__(self) -> None:
        kind = LEG_TYPES.get(self.architecture)
        if kind is None:
            raise ConfigError(f"unknown spatial architecture {self.architecture!r} (expected one of "
                              f"{', '.join(LEG_TYPES)})", source=self.name, key="architecture")
        if self.architecture == CHAIN:
            self._check_chain()
        elif len(self.legs) != LEG_COUNT[self.architecture]:
            raise GeometryError(f"a {self.architecture} needs exactly {LEG_COUNT[self.architecture]} legs, got "
                                f"{len(self.legs)}", source=self.name, key="legs")
        for i, leg in enumerate(self.legs, start=1):
            if type(leg) is not kind:
                raise GeometryError(f"not a {self.architecture} leg: {type(leg).__name__}", source=self.name,
                                    key=f"legs[{i}]")
        self._check_distinct()

    def _check_chain(self) -> None:
        """Chain legs: one actuator per controlled coordinate, six closure equations in all."""
        for i, leg in enumerate(self.legs, start=1):
            if type(leg) is not ChainLeg:
                raise GeometryError(f"not a chain leg: {type(leg).__name__}", source=self.name, key=f"legs[{i}]")
        names = self.controlled_names
        mobility = next((m for m, idx in CONTROLLED.items() if names == tuple(POSE_NAMES[i] for i in idx)), None)
        if mobility is None:
            allowed = "; ".join(", ".join(POSE_NAMES[i] for i in idx) for idx in CONTROLLED.values())
            raise ConfigError(f"must be one of [{allowed}] (in this order), got {list(names) if names else names}",
                              source=self.name, key="controlled")
        if len(self.legs) != len(names):
            raise GeometryError(f"{len(names)} controlled coordinates need {len(names)} legs (one actuator each), "
                                f"got {len(self.legs)}", source=self.name, key="legs")
        rows = [leg.ROWS for leg in self.legs]
        if sum(rows) != 6:
            raise GeometryError(f"the legs' passive joints leave {sum(rows)} closure equations (per leg: "
                                f"{', '.join(map(str, rows))}); a robot needs 6: check the joints' axes",
                                source=self.name, key="legs")
        if self.home is None:
            raise ConfigError("missing: a spatial-chain robot's joints are given at its [home] pose", source=self.name,
                              key="home")

    def _check_distinct(self) -> None:
        """Two legs with the same base and platform points constrain nothing new."""
        pts = np.array([np.concatenate([leg.base, leg.platform]) for leg in self.legs])
        scale = max(1.0, float(np.max(np.abs(pts))))
        for i in range(len(pts)):
            for j in range(i + 1, len(pts)):
                if np.max(np.abs(pts[i] - pts[j])) <= 1e-9 * scale:
                    raise GeometryError(f"legs {i + 1} and {j + 1} have the same base and platform points",
                                        source=self.name, key=f"legs[{j + 1}]")

    # ------------------------------------------------------------------ structure
    @property
    def label(self) -> str:
        """``"6-UPS (Gough-Stewart)"``, ``"Delta 3-R(SS)2"``, ... for titles."""
        if self.architecture == CHAIN:
            kinds = {"".join(j.kind for j in leg.joints) for leg in self.legs}
            return f"{self.n_legs}-{kinds.pop()} (joint chains)" if len(kinds) == 1 else "joint chains"
        return LABELS[self.architecture]

    @property
    def n_legs(self) -> int:
        return len(self.legs)

    @property
    def n_actuators(self) -> int:
        """One actuated joint per leg."""
        return len(self.legs)

    @property
    def mobility(self) -> str:
        """``"6"``, ``"3T"`` (pure translation) or ``"2R1T"`` (z and two tilts; x, y, yaw parasitic)."""
        if self.architecture == CHAIN:
            return next(m for m, idx in CONTROLLED.items()
                        if self.controlled_names == tuple(POSE_NAMES[i] for i in idx))
        return MOBILITY[self.architecture]

    @property
    def controlled(self) -> tuple[str, ...]:
        """Names of the coordinates a user commands (``("z", "roll", "pitch")`` for a 3-RPS)."""
        return tuple(POSE_NAMES[i] for i in CONTROLLED[self.mobility])

    @property
    def actuated_kinds(self) -> tuple[str, ...]:
        """``"P"`` (mm) or ``"R"`` (rad) for each leg's actuated joint."""
        return tuple(leg.ACTUATOR for leg in self.legs)

    @property
    def is_chain(self) -> bool:
        """Legs given joint by joint (architecture ``"spatial-chain"``)."""
        return self.architecture == CHAIN

    @property
    def strokes(self) -> np.ndarray:
        """Actuated joint ranges ``(n, 2)`` (mm, or rad for a Delta's arms)."""
        return np.array([leg.stroke for leg in self.legs], dtype=float)

    @property
    def characteristic_length(self) -> float:
        """Mean distance of the platform joint centres from P (mm): turns moments into forces in conditioning."""
        r = float(np.mean([np.linalg.norm(leg.platform) for leg in self.legs]))
        return r if r > 1e-9 else max(1.0, float(np.mean([np.linalg.norm(leg.base) for leg in self.legs])))

    @property
    def home_pose(self) -> np.ndarray:
        """The file's home pose ``[p mm, rotvec rad]`` (6,), or ``None``."""
        return None if self.home is None else np.array(self.home, dtype=float)

    # ------------------------------------------------------------------ files
    @classmethod
    def preset(cls, name: str = "stewart_6ups") -> "SpatialManipulator":
        """A built-in spatial robot by name (``stewart_6ups``, ``delta_clavel``, ``rps_3``, ``prs_3``, ``upu_3``)."""
        return super().preset(name)

    @classmethod
    def preset_names(cls) -> list[str]:
        """Names of the built-in spatial robots."""
        out = []
        for name in _tomlio.preset_names(cls.PRESET_FOLDER):
            data, _ = _tomlio.read_spec(name, kind="robot", folder=cls.PRESET_FOLDER)
            if is_spatial_architecture(data.get("architecture")):
                out.append(name)
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "<dict>") -> "SpatialManipulator":
        """Build from the parsed TOML table (format: ``docs/guide/spatial.md``)."""
        arch = data.get("architecture")
        arch = ARCHITECTURE_ALIASES.get(arch, arch) if isinstance(arch, str) else arch
        if arch not in LEG_TYPES:
            raise ConfigError(f"unknown spatial architecture {data.get('architecture')!r} (expected one of "
                              f"{', '.join(LEG_TYPES)})", source=source, key="architecture")
        chain = arch == CHAIN
        _tomlio.reject_unknown(data, {"architecture", "name", "description", "legs", "home"} |
                               ({"controlled"} if chain else set()), source=source, where="")
        kind = LEG_TYPES[arch]
        legs = data.get("legs")
        count = None if chain else LEG_COUNT[arch]
        if legs is None:
            raise ConfigError(f"missing [[legs]] tables ({count or 'one per actuator'} are needed for a {arch})",
                              source=source, key="legs")
        if not isinstance(legs, list) or not all(isinstance(t, dict) for t in legs):
            raise ConfigError("must be an array of tables [[legs]]", source=source, key="legs")
        if count is not None and len(legs) != count:
            raise ConfigError(f"a {arch} needs exactly {count} [[legs]], found {len(legs)}", source=source,
                              key="legs")
        name = data.get("name", Path(source).stem if source.endswith(".toml") else source)
        if not isinstance(name, str):
            raise ConfigError("must be a string", source=source, key="name")
        home = _home(data, source)
        controlled = None
        if chain:
            controlled = data.get("controlled")
            if not (isinstance(controlled, list) and all(isinstance(c, str) for c in controlled)):
                raise ConfigError("missing or not a list of names: give controlled = [\"x\", \"y\", \"z\"], "
                                  "[\"z\", \"roll\", \"pitch\"] or all six", source=source, key="controlled")
            controlled = tuple(controlled)
            if home is None:
                raise ConfigError("missing: a spatial-chain robot's joints are given at its [home] pose",
                                  source=source, key="home")
        parsed = []
        for i, table in enumerate(legs, start=1):
            where = f"legs[{i}]"
            _tomlio.reject_unknown(table, kind.KEYS, source=source, where=where)
            extra = {"home_pose": home} if chain else {}
            try:
                parsed.append(kind.from_table(table, source=source, where=where, **extra))
            except GeometryError as exc:
                if exc.source is not None:
                    raise
                raise GeometryError(exc.message, source=source, key=f"{where}.{exc.key}" if exc.key else where) \
                    from None
        try:
            return cls(architecture=arch, legs=tuple(parsed), name=name, description=str(data.get("description", "")),
                       home=home, controlled_names=controlled)
        except (GeometryError, ConfigError) as exc:
            raise type(exc)(exc.message, source=source, key=exc.key) from None

    def to_dict(self) -> dict[str, Any]:
        """The TOML table of this robot (degrees in ``*_deg`` keys)."""
        out: dict[str, Any] = {"architecture": self.architecture, "name": self.name}
        if self.description:
            out["description"] = self.description
        if self.controlled_names is not None:
            out["controlled"] = list(self.controlled_names)
        if self.home is not None:
            angles = rotvec_to_euler_xyz(np.array(self.home[3:]), degrees=True)
            out["home"] = {"position": [float(v) for v in self.home[:3]],
                           "orientation_deg": [_tomlio.round_trip_degrees(np.radians(a)) for a in angles]}
        out["legs"] = [leg.to_table() for leg in self.legs]
        return out


def _home(data: dict[str, Any], source: str):
    """The ``[home]`` table as a pose ``[p mm, rotvec rad]``, or ``None``."""
    if "home" not in data:
        return None
    table = data["home"]
    if not isinstance(table, dict):
        raise ConfigError("must be a table [home] with position and orientation_deg", source=source, key="home")
    _tomlio.reject_unknown(table, {"position", "orientation_deg"}, source=source, where="home")
    position = vector(table, "position", source=source, where="home")
    angles = vector(table, "orientation_deg", source=source, where="home", default=(0.0, 0.0, 0.0))
    return tuple(float(v) for v in np.concatenate([position, euler_xyz_to_rotvec(angles, degrees=True)]))


def is_spatial(robot: object) -> bool:
    """True for a :class:`SpatialManipulator` (twist dimension 6)."""
    return getattr(robot, "dimension", 3) == 6
