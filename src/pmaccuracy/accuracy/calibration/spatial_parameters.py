"""The named error-parameter vector of a spatial parallel robot, and its measurement model.

Parameters (mm, rad, 1), leg ``i`` (1-based) of a :class:`~pmaccuracy.model.spatial.SpatialManipulator`:

================================================  ====================================================================
name                                              meaning
================================================  ====================================================================
``legs[i].base.x|y|z``                            the base joint centre (base frame, mm); a Delta's arm pivot
``legs[i].platform.x|y|z``                        the platform joint centre (platform frame, mm)
``legs[i].arm``                                   a Delta's arm length (mm)
``legs[i].rod``                                   a Delta's or a 3-PRS's rod length (mm)
``legs[i].axis.a|b``                              3-RPS: the revolute axis turned by ``tilt(axis, a, b)`` (rad,
                                                  below), with its base normal; Delta: the arm's axis, with its zero
                                                  direction
``legs[i].base_axis.a|b``                         3-UPU: the base universal joint's outer axis, with the platform's
                                                  (Tsai's condition kept: the model's platform then stays in pure
                                                  translation whatever these are, so no data identify them; the
                                                  analysis finds that)
``legs[i].slide.a|b``                             3-PRS: the slide direction turned by ``tilt(slide, a, b)``, the
                                                  revolute axis and the base normal with it (they stay perpendicular
                                                  to the slide)
``legs[i].axis.a`` (3-PRS)                        the revolute axis turned about the slide first (its other tilt is
                                                  ``slide``'s)
``legs[i].joints[k].centre.x|y|z``                chain legs (``spatial-chain``): joint ``k``'s centre at home (base
                                                  frame, mm; not a P joint's: a translation has no line)
``legs[i].joints[k].axis.a|b``                    its axis (R, P, C joints) turned by ``tilt``
``legs[i].joints[k].axes[1].a|b``, ``axes[2].a``  a U joint: the proximal axis tilted (the distal one with it), then
                                                  the distal one turned about the proximal one
``legs[i].actuator.offset``                       actuated joint value ``q = offset + gain * command`` (mm, or rad)
``legs[i].actuator.gain``                         (1)
``frame.x|y|z``                                   the base frame's origin in the measuring device's frame (mm)
``frame.rx|ry|rz``                                its orientation in the device's frame (rotation vector, rad)
``tool.x|y|z``                                    the target point on the platform (platform frame, mm), position-only
                                                  data with one target; ``tool[k].x|y|z`` (k = 1, 2, ...) with several
================================================  ====================================================================

Angle parameters are 0 at nominal: ``tilt(d, a, b) = exp([a n1 + b n2]x)`` turns the nominal unit direction
``d`` about its normals ``n1 = (d x e)/|d x e|`` (``e`` the coordinate axis least aligned with ``d``: the first
of x, y, z with the smallest ``|d_k|``) and ``n2 = d x n1`` (:func:`axis_normals`); a second direction turned
"about" the first by ``c`` is ``tilt(d, a, b) exp(c [d]x)`` applied to it. A 6-UPS leg has no axis
parameters: its universal joint's axes do not enter its kinematics (an ideal U-P-S leg only sets the distance
of its joint centres).

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
from ...model.spatial_chain import ChainLeg
from ...model.spatial_legs import DeltaLeg, PRSLeg, RPSLeg, UPULeg
from ...numerics.spatial import rotations

MM, RAD, ONE = "mm", "rad", "1"
AXES = ("x", "y", "z")
#: Names of the frame's six parameters after ``frame.``.
FRAME_NAMES = ("x", "y", "z", "rx", "ry", "rz")


def axis_normals(d) -> tuple[np.ndarray, np.ndarray]:
    """The two unit normals ``(n1, n2)`` of a unit direction ``d`` (3,) about which its angle parameters turn it:
    ``n1 = (d x e) / |d x e|`` with ``e`` the coordinate axis least aligned with ``d`` (the first of x, y, z
    with the smallest ``|d_k|``), ``n2 = d x n1``."""
    d = np.asarray(d, dtype=float)
    e = np.zeros(3)
    e[int(np.argmin(np.abs(d)))] = 1.0
    n1 = np.cross(d, e)
    n1 = n1 / np.linalg.norm(n1)
    return n1, np.cross(d, n1)


def tilt(d, a: float, b: float) -> np.ndarray:
    """The rotation ``exp([a n1 + b n2]x)`` ``(3, 3)`` of a direction ``d``'s angle parameters ``a, b`` (rad;
    :func:`axis_normals`)."""
    n1, n2 = axis_normals(d)
    return rotations(a * n1 + b * n2)


def _spin(d, angle: float) -> np.ndarray:
    """The rotation by ``angle`` (rad) about the unit direction ``d``, ``(3, 3)``."""
    return rotations(angle * np.asarray(d, dtype=float))


#: Directions of each leg type that carry angle parameters: ``(name, directions it turns)``; the first
#: direction's two normals (:func:`axis_normals`) are the axes of its two small rotations, and the others turn
#: with it (they must stay perpendicular to it: a Delta's zero, a 3-RPS's base normal, a 3-UPU's platform axis
#: parallel to the base axis). A 6-UPS leg has none: its universal joint's axes do not enter its kinematics.
_TURNED = {RPSLeg: ("axis", ("axis", "base_normal")), DeltaLeg: ("axis", ("axis", "zero")),
           UPULeg: ("base_axis", ("base_axis", "platform_axis")),
           PRSLeg: ("slide", ("slide", "axis", "base_normal"))}


def _leg_fields(leg) -> list[tuple[str, str, str, object]]:
    """``(name, unit, field, component)`` of one leg's geometric parameters (component: the coordinate, None for
    a length, ``"a"``/``"b"``/``"spin"`` for an angle parameter)."""
    if isinstance(leg, ChainLeg):
        return _chain_fields(leg)
    out = [(f"base.{a}", MM, "base", k) for k, a in enumerate(AXES)]
    out += [(f"platform.{a}", MM, "platform", k) for k, a in enumerate(AXES)]
    if isinstance(leg, DeltaLeg):
        out += [("arm", MM, "arm", None), ("rod", MM, "rod", None)]
    elif isinstance(leg, PRSLeg):
        out += [("rod", MM, "rod", None)]
    turned = _TURNED.get(type(leg))
    if turned is not None:
        out += [(f"{turned[0]}.{c}", RAD, turned[0], c) for c in ("a", "b")]
    if isinstance(leg, PRSLeg):
        out += [("axis.a", RAD, "axis", "spin")]
    return out


def _chain_fields(leg: ChainLeg) -> list[tuple[str, str, str, object]]:
    """A chain leg's parameters: each joint's centre (not a P joint's: a translation has no line) and axes.
    Component ``(joint, what, k)``."""
    out = []
    for j, joint in enumerate(leg.joints):
        pre = f"joints[{j + 1}]"
        if joint.kind != "P":
            out += [(f"{pre}.centre.{a}", MM, "joints", (j, "centre", k)) for k, a in enumerate(AXES)]
        if joint.kind in ("R", "P", "C"):
            out += [(f"{pre}.axis.{c}", RAD, "joints", (j, "axis", c)) for c in ("a", "b")]
        elif joint.kind == "U":
            out += [(f"{pre}.axes[1].{c}", RAD, "joints", (j, "axis", c)) for c in ("a", "b")]
            out += [(f"{pre}.axes[2].a", RAD, "joints", (j, "axis", "spin"))]
    return out


def _set_chain_values(leg: ChainLeg, fields, values) -> ChainLeg:
    centres = [np.array(j.centre, dtype=float) for j in leg.joints]
    angles = [{"a": 0.0, "b": 0.0, "spin": 0.0} for _ in leg.joints]
    for (_, _, _, (j, what, k)), v in zip(fields, values):
        if what == "centre":
            centres[j][k] = float(v)
        else:
            angles[j][k] = float(v)
    joints = []
    for joint, c, ang in zip(leg.joints, centres, angles):
        change: dict[str, object] = {"centre": tuple(float(x) for x in c)}
        if joint.axes:
            first = np.asarray(joint.axes[0], dtype=float)
            Q = tilt(first, ang["a"], ang["b"]) @ _spin(first, ang["spin"])
            change["axes"] = tuple(tuple(float(x) for x in Q @ np.asarray(a, dtype=float)) for a in joint.axes)
        joints.append(dataclasses.replace(joint, **change))
    home = np.asarray(leg.home_pose, dtype=float)
    platform = rotations(home[3:]).T @ (np.asarray(joints[-1].centre) - home[:3])
    return dataclasses.replace(leg, joints=tuple(joints), base=joints[0].centre,
                               platform=tuple(float(x) for x in platform))


def set_leg_values(leg, fields, values) -> object:
    """The nominal ``leg`` with its fields ``fields`` (:func:`_leg_fields` rows) set to ``values`` (same length):
    points and lengths replaced, angle parameters turning the leg's directions from the nominal ones
    (``tilt(d, a, b)``; a 3-PRS's ``axis.a`` first turns its revolute axis about its slide)."""
    if isinstance(leg, ChainLeg):
        return _set_chain_values(leg, fields, values)
    change: dict[str, object] = {}
    angles = {"a": 0.0, "b": 0.0, "spin": 0.0}
    for (_, _, field, k), v in zip(fields, values):
        if k is None:
            change[field] = float(v)
        elif isinstance(k, str):
            angles[k] = float(v)
        else:
            cur = list(change.get(field, getattr(leg, field)))
            cur[k] = float(v)
            change[field] = tuple(cur)
    turned = _TURNED.get(type(leg))
    if turned is not None and any(angles.values()):
        first = np.asarray(getattr(leg, turned[0]), dtype=float)
        Q = tilt(first, angles["a"], angles["b"]) @ _spin(first, angles["spin"])
        for name in turned[1]:
            change[name] = tuple(float(x) for x in Q @ np.asarray(getattr(leg, name), dtype=float))
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
    names, units, values = [], [], []
    for i, leg in enumerate(robot.legs, start=1):
        for name, unit, field, k in _leg_fields(leg):
            names.append(f"legs[{i}].{name}")
            units.append(unit)
            values.append(_nominal_value(leg, field, k))
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


def _nominal_value(leg, field, k) -> float:
    """The nominal value of one :func:`_leg_fields` row (0 for an angle parameter)."""
    if isinstance(k, str) or (isinstance(k, tuple) and k[1] == "axis"):
        return 0.0
    if isinstance(k, tuple):
        return float(getattr(leg.joints[k[0]], k[1])[k[2]])
    v = getattr(leg, field)
    return float(v if k is None else v[k])


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
