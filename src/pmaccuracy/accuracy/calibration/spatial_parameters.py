"""The named error-parameter vector of a spatial parallel robot, and its measurement model.

Parameters (mm, rad, 1), leg ``i`` (1-based) of a :class:`~pmaccuracy.model.spatial.SpatialManipulator`:

===========================  ==================================================================
name                         meaning
===========================  ==================================================================
``legs[i].base.x|y|z``       the base joint centre (base frame, mm); a Delta's arm pivot
``legs[i].platform.x|y|z``   the platform joint centre (platform frame, mm)
``legs[i].arm``              a Delta's arm length (mm)
``legs[i].rod``              a Delta's or a 3-PRS's rod length (mm)
``legs[i].actuator.offset``  actuated joint value ``q = offset + gain * command`` (mm, or rad)
``legs[i].actuator.gain``    (1)
``frame.x|y|z``              the base frame's origin in the measuring device's frame (mm)
``frame.rx|ry|rz``           its orientation in the device's frame (rotation vector, rad)
``tool.x|y|z``               the target point on the platform (platform frame, mm), position-only data
                             with one target; ``tool[k].x|y|z`` (k = 1, 2, ...) with several
===========================  ==================================================================

Measurement model: commands ``c (n,)`` set the actuated values ``q = offset + gain * c``; the platform is
at the pose ``(p, R)`` the forward kinematics of the robot with these parameters gives (Newton on the legs'
closure equations, :func:`pmaccuracy.kinematics.spatial.forward_kinematics`); the device with the frame
``(t_F, R_F = exp([r_F]x))`` reads

* full pose: the position ``t_F + R_F p`` and the orientation ``R_F R``;
* position only, target ``k``: the point ``t_F + R_F (p + R s_k)``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ...errors import ConfigError
from ...model.spatial import SpatialManipulator
from ...model.spatial_legs import DeltaLeg, PRSLeg
from ...numerics.spatial import rotations

MM, RAD, ONE = "mm", "rad", "1"
AXES = ("x", "y", "z")
#: Names of the frame's six parameters after ``frame.``.
FRAME_NAMES = ("x", "y", "z", "rx", "ry", "rz")


def _leg_fields(leg) -> list[tuple[str, str, str, int | None]]:
    """``(name, unit, field, component)`` of one leg's geometric parameters."""
    out = [(f"base.{a}", MM, "base", k) for k, a in enumerate(AXES)]
    out += [(f"platform.{a}", MM, "platform", k) for k, a in enumerate(AXES)]
    if isinstance(leg, DeltaLeg):
        out += [("arm", MM, "arm", None), ("rod", MM, "rod", None)]
    elif isinstance(leg, PRSLeg):
        out += [("rod", MM, "rod", None)]
    return out


def set_leg_values(leg, fields, values) -> object:
    """``leg`` with its fields ``fields`` (:func:`_leg_fields` rows) set to ``values`` (same length)."""
    change: dict[str, object] = {}
    for (_, _, field, k), v in zip(fields, values):
        if k is None:
            change[field] = float(v)
        else:
            cur = list(change.get(field, getattr(leg, field)))
            cur[k] = float(v)
            change[field] = tuple(cur)
    return dataclasses.replace(leg, **change)


@dataclass(frozen=True)
class SpatialParameterVector:
    """The error parameters of a spatial robot (module docstring).

    Attributes
    ----------
    robot : SpatialManipulator
        The nominal robot.
    names, units : tuple of str
        Readable names (``legs[2].base.x``, ``frame.rx``, ``tool.z``) and units (mm, rad, 1), ``(P,)``.
    nominal : ndarray ``(P,)``
        Nominal values (offsets 0, gains 1, frame at the identity, targets as given).
    n_targets : int
        Number of target points on the platform (0: full-pose data).

    >>> pv = spatial_error_parameters(SpatialManipulator.preset("stewart_6ups"))
    >>> len(pv.names), pv.names[:2], pv.names[-1]
    (54, ('legs[1].base.x', 'legs[1].base.y'), 'frame.rz')
    """

    robot: SpatialManipulator
    names: tuple[str, ...]
    units: tuple[str, ...]
    nominal: np.ndarray
    n_targets: int = 0

    def __repr__(self) -> str:
        return f"SpatialParameterVector(robot={self.robot.name!r}, {len(self.names)} parameters)"

    @property
    def kind(self) -> str:
        """``"pose"`` (full-pose data) or ``"position"`` (targets)."""
        return "position" if self.n_targets else "pose"

    def index(self, names) -> list[int]:
        """Positions of ``names``; :class:`~pmaccuracy.errors.ConfigError` naming an unknown parameter."""
        out = []
        for n in names:
            if n not in self.names:
                raise ConfigError(f"no parameter {n!r} for this {self.robot.architecture} robot (names like "
                                  f"{self.names[0]}, legs[1].actuator.offset, frame.rx)", key=n)
            out.append(self.names.index(n))
        return out

    @property
    def leg_slices(self) -> tuple[slice, ...]:
        """Positions of each leg's geometric parameters."""
        out, k = [], 0
        for leg in self.robot.legs:
            n = len(_leg_fields(leg))
            out.append(slice(k, k + n))
            k += n + 2
        return tuple(out)

    @property
    def actuator_index(self) -> tuple[np.ndarray, np.ndarray]:
        """Positions of the legs' actuator offsets and gains, each ``(n,)``."""
        off = np.array([s.stop for s in self.leg_slices])
        return off, off + 1

    @property
    def frame_index(self) -> np.ndarray:
        """Positions of ``frame.x .. frame.rz`` ``(6,)``."""
        start = self.leg_slices[-1].stop + 2
        return np.arange(start, start + 6)

    @property
    def tool_index(self) -> np.ndarray:
        """Positions of the targets' coordinates, ``(T, 3)``."""
        start = self.leg_slices[-1].stop + 8
        return np.arange(start, start + 3 * self.n_targets).reshape(-1, 3)

    def split(self, values) -> tuple[SpatialManipulator, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``values (P,)`` -> (robot with that geometry, offsets (n,), gains (n,), frame (6,), targets (T, 3)).

        The robot keeps the nominal's name, strokes and limits; its legs' geometry is replaced."""
        values = np.asarray(values, dtype=float)
        legs = tuple(set_leg_values(leg, _leg_fields(leg), values[s])
                     for leg, s in zip(self.robot.legs, self.leg_slices))
        off, gain = self.actuator_index
        robot = dataclasses.replace(self.robot, legs=legs)
        return robot, values[off], values[gain], values[self.frame_index], values[self.tool_index]

    def table(self, values=None) -> dict[str, float]:
        """``{name: value}`` of ``values`` (default: the nominal)."""
        values = self.nominal if values is None else np.asarray(values, dtype=float)
        return dict(zip(self.names, (float(v) for v in values)))


def spatial_error_parameters(robot: SpatialManipulator, targets=None) -> SpatialParameterVector:
    """The :class:`SpatialParameterVector` of ``robot``; ``targets (T, 3)`` (platform frame, mm): the nominal
    target points of position-only data (``None``: full-pose data, no tool parameters).

    >>> pv = spatial_error_parameters(SpatialManipulator.preset("delta_clavel"), targets=[[0.0, 0.0, -20.0]])
    >>> pv.kind, pv.names[6:8], pv.names[-3:]
    ('position', ('legs[1].arm', 'legs[1].rod'), ('tool.x', 'tool.y', 'tool.z'))
    """
    if robot.is_chain:
        raise ConfigError("calibration of spatial-chain robots is not available yet", key="architecture")
    names, units, values = [], [], []
    for i, leg in enumerate(robot.legs, start=1):
        for name, unit, field, k in _leg_fields(leg):
            names.append(f"legs[{i}].{name}")
            units.append(unit)
            v = getattr(leg, field)
            values.append(float(v if k is None else v[k]))
        names += [f"legs[{i}].actuator.offset", f"legs[{i}].actuator.gain"]
        units += [MM if leg.ACTUATOR == "P" else RAD, ONE]
        values += [0.0, 1.0]
    names += [f"frame.{a}" for a in FRAME_NAMES]
    units += [MM] * 3 + [RAD] * 3
    values += [0.0] * 6
    n_targets = 0
    if targets is not None:
        t = np.asarray(targets, dtype=float).reshape(-1, 3)
        if len(t) == 0 or not np.all(np.isfinite(t)):
            raise ConfigError("targets must be finite points [x, y, z] (mm, platform frame)", key="targets")
        n_targets = len(t)
        for k, pt in enumerate(t, start=1):
            pre = "tool" if n_targets == 1 else f"tool[{k}]"
            names += [f"{pre}.{a}" for a in AXES]
            units += [MM] * 3
            values += [float(c) for c in pt]
    nominal = np.array(values)
    nominal.setflags(write=False)
    return SpatialParameterVector(robot=robot, names=tuple(names), units=tuple(units), nominal=nominal,
                                  n_targets=n_targets)


def spatial_robot_file(pv: SpatialParameterVector, values, name: str | None = None) -> dict:
    """The robot-file table (:meth:`SpatialManipulator.to_dict`) of the robot with the geometry in ``values``
    (actuator offsets, gains, the frame and the targets are not part of a robot file)."""
    robot = pv.split(values)[0]
    if name is not None:
        robot = dataclasses.replace(robot, name=name)
    return robot.to_dict()


def frame_rotation(frame) -> np.ndarray:
    """``R_F = exp([r_F]x)`` ``(3, 3)`` of a frame ``(6,)`` ``[t mm, r rad]``."""
    return rotations(np.asarray(frame, dtype=float)[3:])
