"""Reading and checking TOML parameter files (robots, clearance sets, calibrations).

Every problem raises :class:`~pmaccuracy.errors.ConfigError` naming the file,
the key (``legs[2].d``) and what is wrong, so that the CLI can print one line.
"""

from __future__ import annotations

import numpy as np

import math
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any, ClassVar

import tomli_w

from .._textfile import read_text
from ..errors import ConfigError
from . import plausibility


def preset_names(folder: str) -> list[str]:
    """Names of the packaged presets ``data/<folder>/<name>.toml`` (folders: robots, clearances, variations)."""
    return sorted(p.name[: -len(".toml")] for p in (resources.files("pmaccuracy") / "data" / folder).iterdir()
                  if p.name.endswith(".toml"))


def read_spec(spec: str | Path, *, kind: str, folder: str | None) -> tuple[dict[str, Any], str]:
    """Parse a preset name (``data/<folder>/<name>.toml``) or a TOML file path; ``folder=None``: files only.

    Returns the parsed table and a short name of its source for messages.
    """
    text_spec = str(spec)
    presets = preset_names(folder) if folder is not None else []
    if text_spec in presets:
        data = (resources.files("pmaccuracy") / "data" / folder / f"{text_spec}.toml").read_text()
        source = f"preset {text_spec}"
    else:
        path = Path(text_spec)
        if not text_spec.strip():
            known = f" (presets: {', '.join(presets)})" if presets else ""
            raise ConfigError(f"empty {kind} name: give a preset name or a TOML file{known}")
        if path.is_dir():
            raise ConfigError(f"is a folder, not a {kind} TOML file", source=text_spec)
        if path.exists() and not path.is_file():
            raise ConfigError(f"is not a regular file (a {kind} TOML file is needed)", source=text_spec)
        if not path.is_file():
            known = f" (presets: {', '.join(presets)})" if presets else ""
            raise ConfigError(f"no {kind} preset or file of that name{known}", source=text_spec)
        if kind == "robot" and path.suffix.lower() in (".xml", ".mjcf", ".urdf", ".sdf"):
            # the readers of robot files are in the io layer, above the kinematics that call this
            raise ConfigError("an MJCF/URDF/SDF robot file: read it with pm.load_robot(path) and pass the robot "
                              "(every command's --robot reads it directly)", source=text_spec)
        data = read_text(text_spec, what=f"{kind} TOML file")
        source = text_spec
    parsed = parse_text(data, source)
    if kind == "robot" and source == text_spec:  # a user's robot file: angles typed in radians? (a warning)

        plausibility.warn([f"{source}: {m}" for m in plausibility.degree_key_messages(parsed)], stacklevel=3)
    return parsed, source


def parse_text(text: str, source: str) -> dict[str, Any]:
    """Parse TOML text; a syntax error becomes a ConfigError with the parser's line and column."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"malformed TOML ({exc})", source=source) from None
    except RecursionError:  # tables or arrays nested thousands deep
        raise ConfigError("malformed TOML (nested too deeply)", source=source) from None


def number(table: dict[str, Any], key: str, *, source: str, where: str, default: float | None = None,
           nonnegative: bool = False, positive: bool = False) -> float:
    """A finite real number from ``table[key]`` (a missing key takes ``default`` if given)."""
    name = f"{where}.{key}" if where else key
    if key not in table:
        if default is None:
            raise ConfigError("missing", source=source, key=name)
        return float(default)
    value = table[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"must be a number, got {value!r}", source=source, key=name)
    try:
        value = float(value)
    except OverflowError:   # an integer beyond the largest double
        raise ConfigError("must be finite, got an integer beyond 1e308", source=source, key=name) from None
    if not math.isfinite(value):
        raise ConfigError(f"must be finite, got {value}", source=source, key=name)
    if positive and value <= 0:
        raise ConfigError(f"must be positive, got {value}", source=source, key=name)
    if nonnegative and value < 0:
        raise ConfigError(f"must not be negative, got {value}", source=source, key=name)
    return value


def interval(table: dict[str, Any], key: str, *, source: str, where: str) -> tuple[float, float]:
    """A non-empty interval ``[lo, hi]`` of finite numbers with lo < hi."""
    name = f"{where}.{key}" if where else key
    if key not in table:
        raise ConfigError("missing", source=source, key=name)
    value = table[key]
    if not isinstance(value, list) or len(value) != 2:
        raise ConfigError(f"must be a list [min, max], got {value!r}", source=source, key=name)
    lo = number({"min": value[0]}, "min", source=source, where=name)
    hi = number({"max": value[1]}, "max", source=source, where=name)
    if not lo < hi:
        raise ConfigError(f"empty range [{lo}, {hi}] (min must be below max)", source=source, key=name)
    return lo, hi


def legs_table(data: dict[str, Any], *, source: str) -> list[dict[str, Any]]:
    """The ``[[legs]]`` array of tables; exactly three are required for a 3-PPR."""
    legs = data.get("legs")
    if legs is None:
        raise ConfigError("missing [[legs]] tables (exactly three are needed)", source=source, key="legs")
    if not isinstance(legs, list) or not all(isinstance(leg, dict) for leg in legs):
        raise ConfigError("must be an array of tables [[legs]]", source=source, key="legs")
    if len(legs) != 3:
        raise ConfigError(f"exactly three [[legs]] are needed, found {len(legs)}", source=source, key="legs")
    return legs


def reject_unknown(table: dict[str, Any], allowed: set[str], *, source: str, where: str) -> None:
    """Unknown keys are almost always typos (``alpha`` for ``alpha_deg``): refuse them."""
    for key in table:
        if key not in allowed:
            name = f"{where}.{key}" if where else key
            hint = " (angles are given in degrees as <name>_deg)" if f"{key}_deg" in allowed else ""
            raise ConfigError(f"unknown key{hint}; expected one of {', '.join(sorted(allowed))}",
                              source=source, key=name)


class TomlPresets:
    """Mixin of the TOML constructors shared by robots and clearance sets.

    A subclass sets ``KIND`` (a word for messages) and ``PRESET_FOLDER``
    (``data/<folder>/<name>.toml``) and defines ``from_dict`` and ``to_dict``.
    """

    KIND: ClassVar[str]
    PRESET_FOLDER: ClassVar[str]

    @classmethod
    def preset_names(cls) -> list[str]:
        """Names of the built-in presets."""
        return preset_names(cls.PRESET_FOLDER)

    @classmethod
    def preset(cls, name: str):
        """A built-in preset by name (see :meth:`preset_names`)."""
        if name not in cls.preset_names():
            raise ConfigError(f"unknown {cls.KIND} preset (presets: {', '.join(cls.preset_names())})", source=name)
        return cls.load(name)

    @classmethod
    def load(cls, spec):
        """A preset name, a path to a TOML file, or an instance (returned as is)."""
        if isinstance(spec, cls):
            return spec
        data, source = read_spec(spec, kind=cls.KIND, folder=cls.PRESET_FOLDER)
        return cls.from_dict(data, source=source)

    @classmethod
    def from_toml(cls, path: str | Path):
        """Read a TOML file (format in the guide, docs/guide/formats.md, and the module docstring)."""
        data, source = read_spec(path, kind=cls.KIND, folder=None)
        return cls.from_dict(data, source=source)

    @classmethod
    def from_toml_string(cls, text: str, source: str = "<string>"):
        """Parse TOML text."""
        return cls.from_dict(parse_text(text, source), source=source)

    def to_toml(self, path: str | Path | None = None) -> str:
        """The object as TOML text; also written to ``path`` when given."""
        text = tomli_w.dumps(self.to_dict())
        if path is not None:
            Path(path).write_text(text, encoding="utf-8")
        return text


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
