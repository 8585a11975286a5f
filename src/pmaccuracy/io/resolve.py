"""The one resolver of names and paths: preset names and TOML files into model objects, at every public entry point.

Every public function that takes a robot or its clearances calls these
at its top, so ``max_pose_errors("aalborg_3ppr", "case2", poses)`` works like
the command line, and a wrong type or shape raises the library's own
:class:`~pmaccuracy.errors.ConfigError` (or :class:`~pmaccuracy.errors.PoseError`)
naming the parameter, e.g. ``tolerances.theta: expected 3 values (one per
leg), got 2``, instead of a numpy or attribute error.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from ..errors import ClearanceError, ConfigError
from ..kinematics import check_reachable, resolve_robot
from ..kinematics.spatial import check_reachable as _spatial_reachable
from ..model import _tomlio, plausibility
from ..model.clearances import ClearanceSet
from ..model.serial import SerialArm, SerialErrorSources, is_serial_spec
from ..model.spatial import is_spatial
from ..model.sources import ErrorSources, JointErrors, is_per_joint
from .robot_formats import is_robot_file, read_robot_file

_SPEC = (str, os.PathLike)

#: The default clearances of every command and report, by architecture: the paper's case 1 for a 3-PPR, the
#: architecture's typical per-joint preset otherwise (:func:`default_clearances`).
DEFAULT_CLEARANCES = {"3-PPR": "case1", "3-RPR": "rpr_typical", "3-RRR": "rrr_typical", "3-PRR": "prr_typical",
                      "serial": "arm_typical"}
#: The clearance presets that fit each architecture (shown in suggestions); a per-joint file fits any robot.
ARCHITECTURE_PRESETS = {"3-PPR": ("case1", "case2", "all", "none"), "3-RPR": ("rpr_typical",),
                        "3-RRR": ("rrr_typical",), "3-PRR": ("prr_typical",), "serial": ("arm_typical",)}


def _architecture(robot: Any) -> tuple[str, str]:
    """``(architecture, name)`` of a robot object, preset name or TOML path (a serial arm's is ``"serial"``)."""
    if not hasattr(robot, "architecture"):
        robot = SerialArm.load(robot) if is_serial_spec(robot) else robot_arg(robot)
    return robot.architecture, robot.name


def default_clearances(robot: Any) -> str:
    """The clearance preset used when none is given, the same for every command and report.

    ``case1`` (the paper's first case) for a 3-PPR, ``rpr_typical``, ``rrr_typical``,
    ``prr_typical`` for a 3-RPR, 3-RRR, 3-PRR, ``arm_typical`` for a serial arm
    (:data:`DEFAULT_CLEARANCES`). ``robot``: an object, a preset name or a TOML path. A robot whose legs
    mix types (architecture ``chain``) has no default: :class:`ConfigError` naming ``clearances``.

    >>> default_clearances("symmetric_3rrr"), default_clearances("aalborg_3ppr")
    ('rrr_typical', 'case1')
    """
    architecture, name = _architecture(robot)
    try:
        return DEFAULT_CLEARANCES[architecture]
    except KeyError:
        raise ConfigError(f"{name!r} mixes leg types ({architecture}): no preset fits it, give a per-joint "
                          "clearance file listing each leg's joints, e.g. joints = [{actuator = 0.005}, "
                          "{radial = 0.02}, {radial = 0.02}]", key="clearances") from None


def clearance_examples(robot: Any) -> str:
    """The presets that fit ``robot``'s architecture, for messages: ``"rrr_typical or a per-joint file"``."""
    architecture, _ = _architecture(robot)
    names = ARCHITECTURE_PRESETS.get(architecture, ())
    return ", ".join(names) + " or a per-joint file" if names else "a per-joint file"


def _kind(value: Any) -> str:
    return type(value).__name__


def robot_arg(robot: Any, name: str = "robot"):
    """A :class:`~pmaccuracy.model.manipulator.Manipulator` from an instance, a preset name or a TOML path
    (:func:`pmaccuracy.kinematics.resolve_robot`: a file's robot must also assemble somewhere), or a
    :class:`~pmaccuracy.model.spatial.SpatialManipulator` from an MJCF (``.xml``), URDF (``.urdf``) or SDF (``.sdf``)
    file
    (:func:`pmaccuracy.io.robot_formats.read_robot_file`; its home pose must be within its limits)."""
    if is_robot_file(robot):
        loaded = read_robot_file(robot)
        if is_spatial(loaded):
            _spatial_reachable(loaded, os.fspath(robot))
        else:
            check_reachable(loaded)
        return loaded
    return resolve_robot(robot, name)


def clearances_arg(clearances: Any, robot, name: str = "clearances"):
    """Clearances for ``robot`` from an object (:class:`~pmaccuracy.model.clearances.ClearanceSet`,
    :class:`~pmaccuracy.model.sources.ErrorSources`), a preset name or a TOML path
    (:func:`load_clearances`); objects are returned as they are."""
    if isinstance(clearances, _SPEC):
        return load_clearances(os.fspath(clearances), robot)
    if not isinstance(clearances, (ClearanceSet, ErrorSources)):
        raise ConfigError(f"expected a ClearanceSet, ErrorSources, a preset name or a clearance TOML path, got "
                          f"{_kind(clearances)}", key=name)
    return clearances


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


#: The preset name meaning "no joint clearance", accepted for every architecture (:func:`no_clearances`).
NO_CLEARANCES = "none"


def no_clearances(robot: Any):
    """The all-zero clearance set of ``robot``'s own architecture, named ``none``: an empty
    :class:`~pmaccuracy.model.clearances.ClearanceSet` for a 3-PPR, :class:`ErrorSources` of three legs of
    three zero :class:`~pmaccuracy.model.sources.JointErrors` for another parallel robot (mixed legs too),
    :class:`~pmaccuracy.model.serial.SerialErrorSources` of one zero entry per joint for a serial arm.
    ``robot``: an object, a preset name or a TOML path."""
    if not hasattr(robot, "architecture"):
        robot = SerialArm.load(robot) if is_serial_spec(robot) else robot_arg(robot)
    if isinstance(robot, SerialArm):
        return SerialErrorSources(joints=(JointErrors(),) * robot.n, name=NO_CLEARANCES)
    if robot.is_3ppr:
        return ClearanceSet.load(NO_CLEARANCES)
    return ErrorSources(legs=tuple((JointErrors(),) * 3 for _ in range(3)), name=NO_CLEARANCES)


def load_clearances(spec, robot):
    """Clearances for ``robot`` from a preset name, a TOML file, or an object.

    A file listing each leg's ``joints`` gives :class:`ErrorSources` (any
    architecture); the 3-PPR format (``bearing_angle``, ``guide_lateral``,
    ``revolute_radial`` per leg) gives a :class:`~pmaccuracy.model.clearances.ClearanceSet`
    and needs a 3-PPR robot. Either is checked against the robot's joints. The preset ``none`` fits every
    robot: the 3-PPR format's empty set for a 3-PPR, all-zero :class:`ErrorSources` otherwise
    (:func:`no_clearances`).
    """
    robot = robot_arg(robot)  # a preset name or a TOML path too
    if isinstance(spec, ErrorSources):
        return spec.check(robot)
    if isinstance(spec, ClearanceSet):
        robot.require_3ppr("the 3-PPR clearance format (guide, bearing, revolute per leg)")
        return spec
    if isinstance(spec, str) and spec == NO_CLEARANCES and not robot.is_3ppr:
        return no_clearances(robot)
    data, source = _tomlio.read_spec(spec, kind="clearance", folder="clearances")
    if is_per_joint(data):
        sources = ErrorSources.from_dict(data, source=source)
        try:
            sources.check(robot)
        except ClearanceError as exc:
            raise ClearanceError(exc.message, source=source, key=exc.key) from None
        plausibility.warn(plausibility.actuator_messages(
            ((f"legs[{i}].joints[{k}].actuator", errs.actuator, joint.actuated and joint.kind == "R")
             for i, (chain, leg) in enumerate(zip(robot.chains, sources.legs), start=1)
             for k, (joint, errs) in enumerate(zip(chain.joints, leg), start=1)), source))
        return sources
    if not robot.is_3ppr:
        raise ClearanceError(
            f"this file uses the 3-PPR clearance format (bearing_angle, guide_lateral, revolute_radial per leg) but "
            f"{robot.name!r} is a {robot.architecture}: use {clearance_examples(robot)} listing each leg's joints"
            f"{_joints_example(robot)}", source=source, key="legs")
    return ClearanceSet.from_dict(data, source=source)


def _joints_example(robot) -> str:
    """``, e.g. joints = [...]`` from the first leg of the architecture's default preset ('' without one)."""
    name = DEFAULT_CLEARANCES.get(robot.architecture)
    if name is None or robot.is_3ppr:
        return ""
    data, _ = _tomlio.read_spec(name, kind="clearance", folder="clearances")
    joints = ", ".join("{" + ", ".join(f"{k} = {v:g}" for k, v in joint.items()) + "}"
                       for joint in data["legs"][0]["joints"])
    return f", e.g. (as {name}) joints = [{joints}]"
