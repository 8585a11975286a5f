"""The neutral kinematic graph of a robot file: joints, loop closures, rigid groups of bodies."""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import ConfigError


#: File suffixes of the robot files this module reads, and their format.
SUFFIXES = {".xml": "mjcf", ".mjcf": "mjcf", ".urdf": "urdf", ".sdf": "sdf"}
#: Name of the JSON text that carries the non-kinematic keys of our format.
EXTRAS_NAME = "pmaccuracy"
#: Patterns of kinematic pairs (base to platform) and the architecture they make.
PATTERNS = {"UPS": "6-UPS", "SPS": "6-UPS", "RPS": "3-RPS", "PRS": "3-PRS", "UPU": "3-UPU", "R(SS)2": "delta"}
#: Which pair of each pattern is actuated.
ACTUATED_PAIR = {"UPS": 1, "SPS": 1, "RPS": 1, "PRS": 0, "UPU": 1, "R(SS)2": 0}
#: Keys of a leg table that no kinematic file holds (kept in the extras text).
EXTRA_KEYS = ("base_normal", "base_cone_deg", "platform_normal", "platform_cone_deg", "radius", "arm_radius",
              "rod_radius")
_M = 1000.0  # mm per metre


def is_robot_file(spec: Any) -> bool:
    """True for a path (str or PathLike) ending in ``.xml``, ``.mjcf``, ``.urdf`` or ``.sdf`` (:data:`SUFFIXES`)."""
    return isinstance(spec, (str, os.PathLike)) and Path(spec).suffix.lower() in SUFFIXES


# ---------------------------------------------------------------------------------------------- neutral graph
@dataclass(frozen=True)
class FileJoint:
    """One joint (or loop closure, as a ``ball``) of a robot file, at the reference configuration.

    Attributes
    ----------
    name : str
        What a message calls it: ``joint 'leg1_slide'`` or ``connect 'tip3'``.
    kind : str
        ``"hinge"``, ``"slide"`` or ``"ball"``.
    anchor : numpy.ndarray
        A point of its axis (ball: its centre) in the base frame (mm), (3,).
    axis : numpy.ndarray
        Unit direction in the base frame (3,) (zeros for a ball).
    range : tuple of float or None
        Limits of the joint value (mm or rad), None if unlimited.
    ref : float
        The joint value at the reference configuration (mm or rad).
    actuated : bool
        Driven by an actuator (MJCF ``<actuator>``, URDF ``<transmission>``).
    parent, child : int
        Groups it joins (in the file's tree order).
    ident : tuple
        ``("joint", id)`` or ``("equality", id)`` in the compiled MJCF model (empty for URDF).
    flipped : bool
        Taken against the file's tree (base to platform): ``axis`` is the file's axis reversed.
    """

    name: str
    kind: str
    anchor: np.ndarray
    axis: np.ndarray
    range: tuple[float, float] | None
    ref: float
    actuated: bool
    parent: int
    child: int
    ident: tuple = ()
    flipped: bool = False


@dataclass
class KinematicGraph:
    """Rigid groups of bodies joined by joints (edges hold the joints between two groups in tree order).

    Attributes
    ----------
    source : str
        The file (for messages).
    names : list of str
        A name per group (its first body).
    frames : list of tuple
        ``(position mm (3,), rotation (3, 3))`` of each group's frame in the base frame at the reference.
    edges : list of list of FileJoint
        The joints between two groups, parent to child.
    free : set of int
        Groups with a free joint (a floating platform).
    any_actuator : bool
        Whether the file names actuated joints at all.
    extras : dict
        The JSON of our non-kinematic keys, if the file has it.
    """

    source: str
    names: list[str]
    frames: list[tuple[np.ndarray, np.ndarray]]
    edges: list[list[FileJoint]] = field(default_factory=list)
    free: set[int] = field(default_factory=set)
    any_actuator: bool = False
    extras: dict = field(default_factory=dict)


class _Groups:
    """Union-find over body ids."""

    def __init__(self, n: int) -> None:
        self.up = list(range(n))

    def find(self, i: int) -> int:
        while self.up[i] != i:
            self.up[i] = self.up[self.up[i]]
            i = self.up[i]
        return i

    def union(self, a: int, b: int) -> None:
        a, b = self.find(a), self.find(b)
        if a != b:
            self.up[max(a, b)] = min(a, b)


def _error(source: str, element: str | None, message: str) -> ConfigError:
    return ConfigError(message, source=source, key=element)


def _extras(text: str | None, source: str) -> dict:
    if not text:
        return {}
    try:
        data = json.loads(text)
    except ValueError as exc:
        raise _error(source, f"text '{EXTRAS_NAME}'", f"not JSON: {exc}") from None
    if not isinstance(data, dict):
        raise _error(source, f"text '{EXTRAS_NAME}'", "must be a JSON object")
    return data


def _unit(v):
    return v / np.linalg.norm(v)


def _signed_angle(n, u, axis) -> float:
    return float(np.arctan2(np.cross(n, u) @ axis, n @ u))


def _rotate(v, axis, angle):
    axis = _unit(axis)
    return v * math.cos(angle) + np.cross(axis, v) * math.sin(angle) + axis * (axis @ v) * (1 - math.cos(angle))
