"""Normalization of the arguments of the public entry points: names and files wherever objects are taken.

Every public function that takes a robot, clearances or tolerances calls these
at its top, so ``max_pose_errors("aalborg_3ppr", "case2", poses)`` works like
the command line, and a wrong type or shape raises the library's own
:class:`~pmaccuracy.errors.ConfigError` (or :class:`~pmaccuracy.errors.PoseError`)
naming the parameter, e.g. ``tolerances.theta: expected 3 values (one per
leg), got 2``, instead of a numpy or attribute error.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from .errors import ConfigError

_SPEC = (str, os.PathLike)


def _kind(value: Any) -> str:
    return type(value).__name__


def robot_arg(robot: Any, name: str = "robot"):
    """A :class:`~pmaccuracy.geometry.Manipulator` from an instance, a preset name or a TOML path."""
    if isinstance(robot, _SPEC):
        from .geometry import Manipulator

        return Manipulator.load(robot)
    if not hasattr(robot, "chains"):
        raise ConfigError(f"expected a Manipulator, a preset name or a robot TOML path, got {_kind(robot)}",
                          key=name)
    return robot


def clearances_arg(clearances: Any, robot, name: str = "clearances"):
    """Clearances for ``robot`` from an object (:class:`~pmaccuracy.clearances.ClearanceSet`,
    :class:`~pmaccuracy.sources.ErrorSources`), a preset name or a TOML path
    (:func:`pmaccuracy.sources.load_clearances`); objects are returned as they are."""
    from .clearances import ClearanceSet
    from .sources import ErrorSources, load_clearances

    if isinstance(clearances, _SPEC):
        return load_clearances(os.fspath(clearances), robot)
    if not isinstance(clearances, (ClearanceSet, ErrorSources)):
        raise ConfigError(f"expected a ClearanceSet, ErrorSources, a preset name or a clearance TOML path, got "
                          f"{_kind(clearances)}", key=name)
    return clearances


def tolerances_arg(tolerances: Any, name: str = "tolerances") -> dict[str, np.ndarray] | None:
    """Tolerance half-widths ``{parameter: (3,)}`` (mm or rad) from a mapping, a preset name or a TOML path
    (:func:`pmaccuracy.bounds.load_tolerances`); ``None`` (or an empty mapping) stays as it is.

    Each value is a number (all three legs) or three numbers, finite and >= 0.
    """
    if tolerances is None:
        return None
    if isinstance(tolerances, _SPEC):
        from .bounds import load_tolerances

        return load_tolerances(os.fspath(tolerances))
    if not isinstance(tolerances, Mapping):
        raise ConfigError(f"expected a mapping {{parameter: half-widths}}, a preset name or a TOML path, got "
                          f"{_kind(tolerances)}", key=name)
    return {key: legs_values(value, f"{name}.{key}") for key, value in tolerances.items()}


def legs_values(value: Any, name: str, *, nonnegative: bool = True) -> np.ndarray:
    """Three finite per-leg numbers ``(3,)`` from a number or a sequence of three (ConfigError naming ``name``)."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"expected a number or 3 numbers (one per leg), got {value!r}", key=name) from None
    if arr.ndim > 1 or arr.ndim == 1 and arr.shape[0] != 3:
        got = f"{arr.shape[0]} values" if arr.ndim == 1 else f"shape {arr.shape}"
        raise ConfigError(f"expected 3 values (one per leg), got {got}", key=name)
    arr = np.broadcast_to(arr, (3,)).copy()
    if not np.all(np.isfinite(arr)) or nonnegative and np.any(arr < 0):
        raise ConfigError(f"must be finite{' and >= 0' if nonnegative else ''}, got {arr.tolist()}", key=name)
    return arr
