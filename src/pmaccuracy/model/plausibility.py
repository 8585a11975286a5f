"""Plausibility checks: values that are valid but almost surely in the wrong unit or outside the model's range.

These are warnings, not errors: the value is used as given. Each check is a
pure function returning a list of one-line messages (empty when all is well);
:func:`warn` issues them as :class:`PlausibilityWarning` (a :class:`UserWarning`)
through :mod:`warnings`, which is how the library reports them (loaders of
clearance and tolerance files, poses read from CSV). The command line prints
each as one line ``pmaccuracy CMD: warning: ...`` on stderr, or nothing with
``--quiet``; in Python, silence them with
``warnings.simplefilter("ignore", PlausibilityWarning)``.

Rules (the physical ranges of joint clearances and tolerances in precision
mechanisms are micrometres and milliradians):

* a clearance or tolerance **length** (mm) above :data:`MAX_LENGTH_MM` = 1 mm
  (``revolute_radial = 39`` is 39 um typed as mm);
* a clearance or tolerance **angle** (rad) above :data:`MAX_ANGLE_RAD` = 0.01
  rad = 0.57 deg (``bearing_angle = 0.0688`` is 0.0012 rad typed in degrees);
* a guide **block length** outside [1, 1000] mm;
* an **angle in degrees that looks like radians** (orientation options, the poses CSV's
  ``phi_deg``, the ``*_deg`` keys of a robot file): ``0 < |value| <=
  2 pi`` and within :data:`RADIAN_MATCH` = 5e-4 of a multiple of pi/12, pi/8
  or pi/18 (angles of 15, 22.5 or 10 deg written in radians: 0.2618, 0.5236,
  0.7854, 1.0472, 1.5708, 3.1416, ...). A degree value that short and that close
  to such a multiple is rare on purpose: 0.5, 1, 1.5, 2, 3 deg do not match;
  a *direction* (``--gravity-deg``), whose usual values are whole eighths of a turn, also
  matches a multiple of pi/4 typed with two decimals (:data:`DIRECTION_MATCH`: 1.57, 3.14, 6.28);
* (command line only) measurement noise or accuracy options above 1 mm or 1 deg, error targets and
  thresholds above 1 mm or 1 deg (``pmaccuracy.cli._size_messages``);
* (Python API) an **orientation in radians that looks like degrees**: ``|phi| > 2 pi`` (more than a
  full turn, :data:`MAX_ORIENTATION_RAD`), the one rule no legitimate orientation breaks: a planar platform's
  orientation never needs more than a turn, while 15, 30, 90 deg typed as radians all exceed it.
  :func:`check_orientations` issues it, once per call of a public function (the package's own calls and
  the command line, whose angles are degrees by construction, are not checked again);
* a **force** on the platform (N) above :data:`MAX_FORCE_N` = 1e4 N, or a moment (N mm) whose force at the
  robot's size ``L`` (``|m| / L``) is: a tonne-force on a planar precision robot is kN typed as N
  (:func:`force_messages`; loads, pushes and process wrenches);
* a **first-order result beyond the linear model's validity**: a worst-case
  ``dphi_max`` above :data:`MAX_LINEAR_DPHI_DEG` = 1 deg. The error model
  (Eq. 8, 19) keeps the first order of the rotation; its relative second-order
  term is about ``dphi / 2`` (``1 - cos dphi`` against ``dphi``), 0.9 % at
  1 deg, and the loop closures bend further near a singularity, which is where
  such values appear;
* a **first-order loaded error** (:mod:`pmaccuracy.accuracy.loads`) that the exact loop closure moves by
  more than :data:`MAX_LOADED_DIFFERENCE` = 5 % of its size (position or orientation,
  :func:`loaded_error_messages`): large clearances bend the loops well before ``dphi`` reaches 1 deg.

Example
-------
>>> clearance_messages({"legs[1].revolute_radial": (39.0, "mm")})
['legs[1].revolute_radial = 39 mm is above 1 mm: clearances are usually micrometres (is it in um?)']
>>> orientation_messages([0.5236], "--phi-deg")
['--phi-deg 0.5236 looks like radians (30 deg = 0.5236 rad); orientations are in degrees']
"""

from __future__ import annotations

import math
import sys
import warnings
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

#: Largest plausible clearance / tolerance length, mm.
MAX_LENGTH_MM = 1.0
#: Largest plausible clearance / tolerance angle, rad (0.57 deg).
MAX_ANGLE_RAD = 0.01
#: Plausible guide block lengths, mm.
BLOCK_LENGTH_RANGE_MM = (1.0, 1000.0)
#: Distance (in the value's unit) to k pi/12, k pi/8 or k pi/18 below which a degree value looks like radians.
RADIAN_MATCH = 5e-4
#: Distance (deg) to a multiple of pi/4 below which a *direction* in degrees (gravity) looks like radians: half
#: a unit of the second decimal, so pi/2 typed as 1.57 and 2 pi as 6.28 match; 1.5 or 2 deg do not.
DIRECTION_MATCH = 5e-3
#: Largest relative difference between a first-order loaded error and the exact one without a warning.
MAX_LOADED_DIFFERENCE = 0.05
#: Largest worst-case dphi (deg) for which the first-order model is trusted (relative 2nd order ~ dphi/2).
MAX_LINEAR_DPHI_DEG = 1.0
#: Largest |orientation| (rad) the API takes without a warning: a full turn (module docstring).
MAX_ORIENTATION_RAD = 2 * math.pi
#: Largest plausible force on a planar precision robot's platform (N), and moment over its size (N mm / mm).
MAX_FORCE_N = 1e4
#: Largest share of the values listed in one message.
_SHOWN = 3


class PlausibilityWarning(UserWarning):
    """A value is accepted but is almost surely in the wrong unit or outside the model's range of validity."""


class LongRunWarning(PlausibilityWarning):
    """A computation is about to take long (the command line prints it at once, before computing)."""


def warn(messages: Iterable[str], stacklevel: int = 2) -> None:
    """Issue each message as a :class:`PlausibilityWarning`."""
    for message in messages:
        warnings.warn(message, PlausibilityWarning, stacklevel=stacklevel + 1)


def _g(value: float) -> str:
    return f"{value:.6g}"


def clearance_messages(values: Mapping[str, tuple[float, str]], what: str = "clearances") -> list[str]:
    """Messages for half-widths ``{name: (value, unit)}`` with unit ``"mm"``, ``"rad"`` or ``"block"`` (mm).

    ``what`` names the kind of value in the message (``"clearances"`` or ``"tolerances"``).
    """
    import re

    grouped: dict[tuple, list[str]] = {}  # the same value on several legs: one message "legs[1,2,3].key"
    for name, (value, unit) in values.items():
        m = re.match(r"^legs\[(\d+)\](.*)$", name)
        key = (m.group(2), float(value), unit) if m else (name, float(value), unit)
        grouped.setdefault(key, []).append(m.group(1) if m else "")
    values = {(f"legs[{','.join(legs)}]{rest}" if legs[0] else rest): (value, unit)
              for (rest, value, unit), legs in grouped.items()}
    out = []
    for name, (value, unit) in values.items():
        value = float(value)
        if not math.isfinite(value):
            continue
        if unit == "mm" and value > MAX_LENGTH_MM:
            out.append(f"{name} = {_g(value)} mm is above {_g(MAX_LENGTH_MM)} mm: {what} are usually micrometres "
                       f"(is it in um?)")
        elif unit == "rad" and value > MAX_ANGLE_RAD:
            out.append(f"{name} = {_g(value)} rad ({_g(math.degrees(value))} deg) is above {_g(MAX_ANGLE_RAD)} rad: "
                       f"{what} are usually milliradians (is it in degrees?)")
        elif unit == "block" and not BLOCK_LENGTH_RANGE_MM[0] <= value <= BLOCK_LENGTH_RANGE_MM[1]:
            lo, hi = BLOCK_LENGTH_RANGE_MM
            out.append(f"{name} = {_g(value)} mm is outside [{_g(lo)}, {_g(hi)}] mm, the range of guide blocks "
                       f"(is it in m or um?)")
    return out


def force_messages(forces: Mapping[str, float], moments: Mapping[str, float] | None = None,
                   length_mm: float | None = None) -> list[str]:
    """Messages for forces ``{name: N}`` above :data:`MAX_FORCE_N` and moments ``{name: N mm}`` whose force at
    the robot's size ``length_mm`` (``|m| / L``) is (kN typed as N; moments need ``length_mm``).

    >>> force_messages({"--fx": 2e4})
    ['--fx = 20000 N is above 10000 N on a planar precision robot (is it in kN, typed as N?)']
    >>> force_messages({"--fx": 50.0}, {"--m": 3e8}, length_mm=300.0)
    ["--m = 3e+08 N mm is above 10000 N at the robot's size 300 mm (kN typed as N?)"]
    """
    out = []
    for name, value in forces.items():
        if math.isfinite(value) and abs(value) > MAX_FORCE_N:
            out.append(f"{name} = {_g(value)} N is above {_g(MAX_FORCE_N)} N on a planar precision robot "
                       f"(is it in kN, typed as N?)")
    if length_mm and length_mm > 0:
        for name, value in (moments or {}).items():
            if math.isfinite(value) and abs(value) / length_mm > MAX_FORCE_N:
                out.append(f"{name} = {_g(value)} N mm is above {_g(MAX_FORCE_N)} N at the robot's size "
                           f"{_g(length_mm)} mm (kN typed as N?)")
    return out


def looks_like_degrees(phi_rad: np.ndarray | float) -> np.ndarray:
    """True where an angle given in radians looks like degrees: ``|phi| > 2 pi`` (:data:`MAX_ORIENTATION_RAD`
    plus 1e-9 of rounding), same shape; NaN and infinities are left to the callers' own checks."""
    v = np.abs(np.asarray(phi_rad, dtype=float))
    with np.errstate(invalid="ignore"):
        return np.isfinite(v) & (v > MAX_ORIENTATION_RAD + 1e-9)


def degree_slip_messages(phi_rad: np.ndarray | float, where: str, what: str = "orientations") -> list[str]:
    """One message if some angles (rad, any shape) look like degrees (:func:`looks_like_degrees`); ``where``
    names the argument, ``what`` the kind of angle.

    >>> degree_slip_messages(15.0, "phi")
    ['phi = 15 rad = 859.4 deg: pass radians, e.g. np.radians(15)']
    """
    values = np.asarray(phi_rad, dtype=float).reshape(-1)
    hits = values[looks_like_degrees(values)]
    if hits.size == 0:
        return []
    first = float(hits[0])
    example = f"{_g(first)} rad = {_g(round(math.degrees(first), 1))} deg: pass radians, e.g. np.radians({_g(first)})"
    if values.size == 1:
        return [f"{where} = {example}"]
    return [f"{where}: {hits.size} of {values.size} {what} beyond a full turn (2 pi rad), e.g. {example}"]


def _called_from_package(depth: int) -> bool:
    """Whether the frame ``depth`` levels above the caller belongs to this package (its own calls, the CLI)."""
    try:
        frame = sys._getframe(depth + 1)
    except ValueError:
        return False
    name = frame.f_globals.get("__name__", "")
    return name == "pmaccuracy" or name.startswith("pmaccuracy.")


def called_by_user(skip: int = 0) -> bool:
    """Whether the function calling this was called from outside the package (user code), ``skip`` package
    frames (a dataclass's generated ``__init__``) further up; the package's own calls and the command line
    have checked their values already (:func:`check_orientations`)."""
    return not _called_from_package(2 + skip)


def warn_caller(messages: Iterable[str]) -> None:
    """Issue ``messages`` as :class:`PlausibilityWarning` pointing at the caller of the public function that
    calls this, only when that caller is outside the package (as :func:`check_orientations`)."""
    if _called_from_package(2):
        return
    for message in messages:
        warnings.warn(message, PlausibilityWarning, stacklevel=3)


def check_orientations(phi_rad, where: str, what: str = "orientations", *, poses: bool = False) -> None:
    """Warn (:class:`PlausibilityWarning`, one line) when angles passed in radians look like degrees.

    The rule: ``|phi| > 2 pi`` (:func:`looks_like_degrees`): a full turn, which no planar orientation needs and
    which 15, 30, 90 deg typed as radians all exceed. ``phi_rad``: angles of any shape (rad), or with
    ``poses=True`` poses ``(..., 3)`` [mm, mm, rad] whose last column is checked (``where`` then names the
    argument, the message says ``where[..., 2]``). Malformed input is left to the caller's own checks.

    Call it first thing in a public function: it checks only when that function was called from outside the
    package (user code), so the package's own calls, and the command line (which converts degrees itself
    and checks them with :func:`orientation_messages`), never warn twice for one slip. The warning points
    at the user's line.

    >>> import warnings
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     check_orientations([[0.0, 0.0, 15.0]], "poses", poses=True)
    >>> print(caught[0].message)
    poses[..., 2] = 15 rad = 859.4 deg: pass radians, e.g. np.radians(15)
    """
    if _called_from_package(2):
        return
    try:
        values = np.asarray(phi_rad, dtype=float)
        if poses:
            if values.ndim == 0 or values.shape[-1] != 3:
                return
            values, where = values[..., 2], f"{where}[..., 2]"
        messages = degree_slip_messages(values, where, what)
    except (TypeError, ValueError):
        return
    for message in messages:
        warnings.warn(message, PlausibilityWarning, stacklevel=3)


def looks_like_radians(phi_deg: np.ndarray | float, *, direction: bool = False) -> np.ndarray:
    """True where a value given in degrees looks like an angle in radians (module docstring), same shape.

    ``direction``: the value is a direction in the plane (gravity), whose usual values are whole eighths of a
    turn (0, 45, -90, 180 deg): then also a multiple of pi/4 rounded to two decimals (:data:`DIRECTION_MATCH`:
    0.79, 1.57, 3.14, 4.71, 6.28) looks like radians.
    """
    v = np.abs(np.asarray(phi_deg, dtype=float))
    limit = 2 * math.pi + (DIRECTION_MATCH if direction else RADIAN_MATCH)
    with np.errstate(invalid="ignore"):
        candidates = (v > 0) & (v <= limit)       # (NaN compares False: never a candidate)
    where = np.flatnonzero(candidates)            # usually a small part of a file of degrees: tested alone
    w = v.reshape(-1)[where]
    hit = np.zeros(w.shape, dtype=bool)
    for step, match in ((math.pi / 12, RADIAN_MATCH), (math.pi / 8, RADIAN_MATCH), (math.pi / 18, RADIAN_MATCH),
                        *(((math.pi / 4, DIRECTION_MATCH),) if direction else ())):
        k = np.rint(w / step)
        hit |= (k >= 1) & (np.abs(w - k * step) <= match)
    out = np.zeros(v.shape, dtype=bool)
    out.reshape(-1)[where[hit]] = True
    return out[()] if v.ndim == 0 else out


def orientation_messages(phi_deg: Sequence[float] | np.ndarray, where: str, what: str = "orientations", *,
                         direction: bool = False) -> list[str]:
    """One message if some of the angles (deg) look like radians; ``where`` names the option or file, ``what``
    the kind of angle; ``direction``: directions in the plane (:func:`looks_like_radians`)."""
    values = np.asarray(phi_deg, dtype=float).reshape(-1)
    hits = values[looks_like_radians(values, direction=direction)]
    if hits.size == 0:
        return []
    first = float(hits[0])
    example = f"{_g(first)} looks like radians ({_g(round(math.degrees(first), 1))} deg = {_g(first)} rad)"
    if values.size == 1 or hits.size == 1 and values.size <= _SHOWN:
        return [f"{where} {example}; {what} are in degrees"]
    return [f"{where}: {hits.size} of {values.size} {what} look like radians, e.g. {example}; {what} are in degrees"]


def linearity_messages(dphi_max_deg: np.ndarray, poses: np.ndarray | None = None, what: str = "dphi_max") -> list[str]:
    """One message if a worst-case ``dphi_max`` (deg) exceeds :data:`MAX_LINEAR_DPHI_DEG`.

    ``poses`` ``(N, 3)`` [mm, mm, rad], if given, names the worst pose.
    """
    d = np.asarray(dphi_max_deg, dtype=float).reshape(-1)
    finite = np.isfinite(d)
    if not finite.any() or d[finite].max() <= MAX_LINEAR_DPHI_DEG:
        return []
    k = int(np.nanargmax(np.where(finite, d, -np.inf)))
    count = int((d[finite] > MAX_LINEAR_DPHI_DEG).sum())
    at = ""
    if poses is not None:
        p = np.asarray(poses, dtype=float).reshape(-1, 3)[k]
        at = f" at x = {_g(p[0])} mm, y = {_g(p[1])} mm, phi = {_g(math.degrees(p[2]))} deg"
    many = f" ({count} of {d.size} values)" if d.size > 1 else ""
    return [f"{what} = {_g(d[k])} deg{at}{many} is beyond the first-order model's validity (about "
            f"{_g(MAX_LINEAR_DPHI_DEG)} deg; relative second-order error ~ dphi/2): the worst case is only "
            f"indicative there (near a singularity or clearances too large)"]


def loaded_error_messages(first_order: np.ndarray, exact: np.ndarray, poses: np.ndarray,
                          length_mm: float) -> list[str]:
    """One message if a first-order loaded error differs from the exact one by more than
    :data:`MAX_LOADED_DIFFERENCE` (relative), at any of the poses.

    ``first_order``, ``exact``, ``poses`` ``(..., 3)`` [mm, mm, rad]. The position part ``(dx, dy)`` and the
    orientation part ``dphi`` are compared separately, each relative to its exact size; a part smaller than a
    tenth of the whole error (``|(dx, dy, L dphi)|``, ``L = length_mm`` the robot's size) is not judged (its
    relative difference says nothing about the figures a user reads). Poses without an exact value are skipped.
    """
    f = np.asarray(first_order, dtype=float).reshape(-1, 3)
    e = np.asarray(exact, dtype=float).reshape(-1, 3)
    p = np.asarray(poses, dtype=float).reshape(-1, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        pos, rot = np.hypot(e[:, 0], e[:, 1]), np.abs(e[:, 2])
        size = np.hypot(pos, length_mm * rot)
        rel_pos = np.where(pos >= 0.1 * size, np.hypot(f[:, 0] - e[:, 0], f[:, 1] - e[:, 1]) / pos, 0.0)
        rel_rot = np.where(length_mm * rot >= 0.1 * size, np.abs(f[:, 2] - e[:, 2]) / rot, 0.0)
    ok = np.isfinite(size) & (size > 0) & np.all(np.isfinite(f), axis=1)
    rel = np.where(ok, np.maximum(np.nan_to_num(rel_pos), np.nan_to_num(rel_rot)), 0.0)
    bad = rel > MAX_LOADED_DIFFERENCE
    if not np.any(bad):
        return []
    k = int(np.argmax(rel))
    part = "position" if rel_pos[k] >= rel_rot[k] else "orientation"
    many = f" ({int(bad.sum())} of {rel.size} poses)" if rel.size > 1 else ""
    return [f"the first-order loaded error differs from the exact one by {_g(100 * rel[k])} % ({part}) at x = "
            f"{_g(p[k, 0])} mm, y = {_g(p[k, 1])} mm, phi = {_g(math.degrees(p[k, 2]))} deg{many}, above "
            f"{_g(100 * MAX_LOADED_DIFFERENCE)} %: the first-order figures are only indicative there (use the exact "
            f"ones)"]


def _prefixed(source: str | None, messages: list[str]) -> list[str]:
    return [f"{source}: {m}" for m in messages] if source else messages


#: Units of the 3-PPR clearance keys and of the per-joint keys (``actuator``: mm or rad, so the looser 1).
_SET_UNITS = {"bearing_angle": "rad", "guide_lateral": "mm", "revolute_radial": "mm", "guide_block_length": "block"}
_JOINT_UNITS = {"radial": "mm", "angular": "rad", "lateral": "mm", "block_length": "block", "position": "mm",
                "direction": "rad", "length": "mm", "actuator": "mm", "base_radius": "mm", "base_turn": "rad",
                "link_turn": "rad", "platform_radius": "mm", "platform_turn": "rad"}


def clearance_set_messages(clearances, source: str | None = None) -> list[str]:
    """Messages for a 3-PPR :class:`~pmaccuracy.model.clearances.ClearanceSet` (keys ``legs[i].<key>``)."""
    values = {f"legs[{i + 1}].{key}": (float(getattr(clearances, key)[i]), unit)
              for i in range(3) for key, unit in _SET_UNITS.items()}
    return _prefixed(source, clearance_messages(values))


def error_sources_messages(sources, source: str | None = None, what: str = "clearances") -> list[str]:
    """Messages for per-joint :class:`~pmaccuracy.model.sources.ErrorSources` (keys ``legs[i].joints[k].<key>``).

    An ``actuator`` error is mm or rad by the joint: it is held to the mm limit (1), a looser test.
    """
    values = {}
    for i, leg in enumerate(sources.legs, start=1):
        for k, joint in enumerate(leg, start=1):
            for key, unit in _JOINT_UNITS.items():
                value = float(getattr(joint, key, 0.0))
                if key == "block_length" and not getattr(joint, "lateral", 0.0):
                    continue  # the default block length is only used with a lateral clearance
                if value:
                    values[f"legs[{i}].joints[{k}].{key}"] = (value, unit)
    return _prefixed(source, clearance_messages(values, what))


def actuator_messages(actuators: Iterable[tuple[str, float, bool]], source: str | None = None,
                      what: str = "clearances") -> list[str]:
    """Messages for ``actuator`` half-widths ``(name, value, revolute)`` once the joint types are known: a
    revolute actuator's error is in rad and held to :data:`MAX_ANGLE_RAD` (``actuator = 0.05`` on a motor is
    almost surely degrees); a prismatic one's, in mm, is checked by :func:`error_sources_messages` already.

    >>> actuator_messages([("legs[1].joints[1].actuator", 0.05, True)])
    ['legs[1].joints[1].actuator = 0.05 rad (2.86479 deg) is above 0.01 rad: clearances are usually milliradians (is it in degrees?)']
    """
    values = {name: (float(value), "rad") for name, value, revolute in actuators if revolute and value}
    return _prefixed(source, clearance_messages(values, what))


def tolerance_messages(tolerances: Mapping[str, object], units: Mapping[str, str],
                       source: str | None = None) -> list[str]:
    """Messages for tolerance half-widths ``{name: (3,)}`` with ``units[name]`` ``"mm"`` or ``"rad"``."""
    values = {}
    for name, t in tolerances.items():
        arr = np.broadcast_to(np.asarray(t, dtype=float), (3,))
        for i, v in enumerate(arr, start=1):
            values[f"legs[{i}].{name}_{units.get(name, 'mm')}"] = (float(v), units.get(name, "mm"))
    return _prefixed(source, clearance_messages(values, "tolerances"))


def degree_key_messages(data: object, where: str = "") -> list[str]:
    """Messages for values of ``*_deg`` keys of a parsed file (any depth) that look like radians.

    A robot file's angles are degrees (``alpha_deg = 180``); ``alpha_deg = 3.1416`` is almost surely pi
    typed in radians. One message per key (``legs[2].angle_range_deg``).
    """
    out: list[str] = []
    if isinstance(data, dict):
        for key, value in data.items():
            name = f"{where}.{key}" if where else str(key)
            if str(key).endswith("_deg"):
                values = value if isinstance(value, list) else [value]
                numbers = [float(v) for v in values if isinstance(v, (int, float)) and not isinstance(v, bool)
                           and abs(v) < 1e300]   # an integer beyond a float is refused by the reader, not here
                hits = [v for v in numbers if v and bool(looks_like_radians(v))]
                if hits:
                    out.append(f"{name} = {_g(hits[0])} looks like radians ({_g(round(math.degrees(hits[0]), 1))} "
                               f"deg = {_g(hits[0])} rad); the file's angles are in degrees")
            else:
                out.extend(degree_key_messages(value, name))
    elif isinstance(data, list):
        for i, item in enumerate(data, start=1):
            out.extend(degree_key_messages(item, f"{where}[{i}]"))
    return out


#: A spatial robot whose every length is below this (mm) was almost surely written in metres.
METRES_SLIP_MM = 5.0


def spatial_robot_messages(robot, source: str | None = None) -> list[str]:
    """Warnings for a spatial robot file whose numbers look like a unit slip: every joint centre, stroke and
    link length below :data:`METRES_SLIP_MM` (a hexapod of 0.3 mm: metres typed for millimetres)."""
    sizes = []
    for leg in robot.legs:
        sizes.extend(abs(float(v)) for v in (*leg.base, *leg.platform))
        if leg.ACTUATOR == "P":
            sizes.extend(abs(float(v)) for v in leg.stroke)
        sizes.extend(float(getattr(leg, key)) for key in ("rod", "arm") if hasattr(leg, key))
    largest = max(sizes) if sizes else 0.0
    if 0 < largest < METRES_SLIP_MM:
        return _prefixed(source, [f"every length of the robot is below {METRES_SLIP_MM:g} mm (largest {_g(largest)}): "
                                  "robot files are in mm, were these metres?"])
    return []


def check_angle_values(values, where: str, what: str = "rotation angles") -> None:
    """:func:`check_orientations` for spatial angles: warn when the given angles (rad, any shape: rotation
    angles ``|r|`` of rotation vectors, roll/pitch/yaw, a Delta's arm angles) look like degrees (beyond a full
    turn). Call it first thing in a public function (it checks only calls from user code)."""
    if _called_from_package(2):
        return
    try:
        messages = degree_slip_messages(np.asarray(values, dtype=float), where, what)
    except (TypeError, ValueError):
        return
    for message in messages:
        warnings.warn(message, PlausibilityWarning, stacklevel=3)


def rotation_angles(poses) -> np.ndarray:
    """``|r|`` (rad) of the rotation vectors of poses ``(..., 6)``; empty for anything else (left to the callers'
    own checks)."""
    try:
        arr = np.asarray(poses, dtype=float)
    except (TypeError, ValueError):
        return np.zeros(0)
    if arr.ndim == 0 or arr.shape[-1] != 6:
        return np.zeros(0)
    return np.linalg.norm(arr[..., 3:], axis=-1)
