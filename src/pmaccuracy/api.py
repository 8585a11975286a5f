"""The public entry points that take names and paths as well as objects (re-exported by :mod:`pmaccuracy`).

Every computing function of the package already accepts a robot and its clearances as objects, preset
names or TOML paths; this module adds the two loaders a user starts from, so that a session reads::

    import pmaccuracy as pm
    robot = pm.load_robot("my_robot.toml")            # or a preset name: "aalborg_3ppr"
    clearances = pm.load_clearances("my_clearances.toml", robot)
    b = pm.max_pose_errors(robot, clearances, [[0.0, 0.0, 0.0]])   # poses: x mm, y mm, phi rad
"""

from __future__ import annotations

import os
from typing import Any

from .errors import ConfigError
from .io.resolve import load_clearances as _load_clearances
from .io.resolve import robot_arg
from .io.robot_formats import export_into, is_robot_file, write_mjcf, write_sdf, write_urdf
from .model.manipulator import Manipulator
from .model.serial import SerialArm, is_serial_spec, load_serial_sources
from .model.spatial import SpatialManipulator, is_spatial
from .model.spatial_sources import SpatialErrorSources

__all__ = ["load_robot", "load_clearances"]


def load_robot(spec: Any):
    """The robot of a preset name, a TOML path, an MJCF (``.xml``), URDF (``.urdf``) or SDFormat (``.sdf``) file,
    or an object
    (returned as it is).

    A parallel robot (any architecture) gives a :class:`~pmaccuracy.model.manipulator.Manipulator`, a robot file
    with ``architecture = "serial"`` a :class:`~pmaccuracy.model.serial.SerialArm`. Raises
    :class:`~pmaccuracy.errors.ConfigError` (or a subclass) naming the file and key of any mistake.

    >>> load_robot("aalborg_3ppr").architecture
    '3-PPR'
    >>> load_robot("planar_3r_arm").kinds
    'RRR'
    """
    if isinstance(spec, (Manipulator, SerialArm, SpatialManipulator)):
        return spec
    if not isinstance(spec, (str, os.PathLike)):
        raise ConfigError(f"expected a robot, a preset name or a robot TOML path, got {type(spec).__name__}",
                          key="robot")
    if is_robot_file(spec):   # MJCF, URDF or SDF: pmaccuracy.io.robot_formats
        return robot_arg(spec)
    return SerialArm.load(spec) if is_serial_spec(spec) else robot_arg(spec)


def export_robot(robot: Any, path: str | os.PathLike, like: str | os.PathLike | None = None):
    """Write a robot (object, preset name, TOML, MJCF, URDF or SDF path) as a robot file of another tool.

    ``path`` ending in ``.xml``/``.mjcf`` gives a fresh MJCF file (MuJoCo; loops closed by ``connect``
    constraints), ``.urdf`` a URDF file with URDF+ ``<loop>`` closures, ``.sdf`` an SDFormat 1.9 model (loops closed
    by ball joints); with ``like`` (the MJCF, URDF or SDF file the robot
    was imported from), a copy of it in which only the geometry becomes the robot's (body and joint positions,
    axes, references, actuated ranges: :func:`pmaccuracy.io.robot_formats.export_into`). A planar robot is
    written as a fresh MJCF file only. Files are in metres and radians; :func:`load_robot` reads them back to the
    same robot (1e-9 mm). Returns the path written.

    >>> import tempfile, pathlib
    >>> path = export_robot("delta_clavel", pathlib.Path(tempfile.mkdtemp()) / "delta.xml")
    >>> load_robot(path).architecture
    'delta'
    """
    robot = load_robot(robot)
    if like is not None:
        return export_into(robot, like, path)
    if os.fspath(path).lower().endswith(".urdf"):
        if not is_spatial(robot):
            raise ConfigError(f"{robot.name} is a planar robot: URDF files are written for spatial robots so far "
                              "(write an MJCF .xml)", key="path")
        return write_urdf(robot, path)
    if os.fspath(path).lower().endswith(".sdf"):
        if not is_spatial(robot):
            raise ConfigError(f"{robot.name} is a planar robot: SDF files are written for spatial robots so far "
                              "(write an MJCF .xml)", key="path")
        return write_sdf(robot, path)
    return write_mjcf(robot, path)


def load_clearances(spec: Any, robot: Any):
    """Clearances (or tolerances) for ``robot`` from a preset name, a TOML path or an object.

    A per-joint file gives :class:`~pmaccuracy.model.sources.ErrorSources` (any architecture; for a serial arm
    :class:`~pmaccuracy.model.serial.SerialErrorSources`), the paper's 3-PPR format a
    :class:`~pmaccuracy.model.clearances.ClearanceSet`; either is checked against the robot's joints.

    >>> load_clearances("case2", "aalborg_3ppr").name
    'case2'
    """
    robot = load_robot(robot)
    if isinstance(robot, SerialArm):
        return load_serial_sources(spec, robot)
    if is_spatial(robot):
        return SpatialErrorSources.load(spec, robot)
    return _load_clearances(spec, robot)
