"""The named error-parameter vector of a robot: geometry, actuators and the measurement frame.

Every designer leg type (:mod:`pmaccuracy.model.legs`) contributes the numbers of its robot-file table, the
actuator of each leg an ``offset`` and a ``gain``, and the measurement frame its pose in the robot frame:

====================  =========================================================================
leg type              parameters (``leg{i}.`` prefix; mm, rad)
====================  =========================================================================
3-PPR                 ``a, alpha, beta, gamma, theta, d, r, psi`` (paper Eq. 1)
3-RPR                 ``base.x, base.y, platform.x, platform.y``
3-RRR                 ``base.x, base.y, platform.x, platform.y, proximal, distal``
3-PRR                 ``guide.x, guide.y, guide.angle, platform.x, platform.y, distal``
chain                 ``base.x, base.y, base.angle, joint{k}.offset, joint{k}.link.x, joint{k}.link.y,
                      platform.x, platform.y, platform.angle``
every leg             ``actuator.offset`` (mm or rad), ``actuator.gain`` (1)
====================  =========================================================================

and ``frame.x, frame.y`` (mm), ``frame.phi`` (rad): the measurement frame in the robot frame.

Actuator model: the actuated joint value is ``q = offset + gain * command`` (nominal: ``offset = 0``,
``gain = 1``). Measurement model: a pose ``m`` read in the measurement frame is the robot-frame pose
``p = F * m``, ``p_xy = f_xy + Rot(f_phi) m_xy``, ``p_phi = f_phi + m_phi``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ...errors import ConfigError
from ...model.legs import ChainLeg, Joint, LegType, PPRLeg, PRRLeg, RPRLeg, RRRLeg
from ...model.manipulator import Manipulator
from ...model.serial import SerialArm

#: Units of the parameters by kind.
MM, RAD, ONE = "mm", "rad", "1"


def _pt(field: str, k: int):
    return (lambda leg: getattr(leg, field)[k],
            lambda leg, v: dataclasses.replace(leg, **{field: tuple(v if j == k else c
                                                                     for j, c in enumerate(getattr(leg, field)))}))


def _sc(field: str):
    return (lambda leg: getattr(leg, field), lambda leg, v: dataclasses.replace(leg, **{field: float(v)}))


def _chain_spec(leg: ChainLeg) -> list[tuple[str, str, Callable, Callable]]:
    def cfield(name, k=None):
        def get(lg):
            val = getattr(lg.spec, name)
            return val if k is None else val[k]

        def put(lg, v):
            old = getattr(lg.spec, name)
            new = float(v) if k is None else tuple(float(v) if j == k else c for j, c in enumerate(old))
            return ChainLeg(dataclasses.replace(lg.spec, **{name: new}))
        return get, put

    def jfield(i, name, k=None):
        def get(lg):
            val = getattr(lg.spec.joints[i], name)
            return val if k is None else val[k]

        def put(lg, v):
            joint = lg.spec.joints[i]
            old = getattr(joint, name)
            new = float(v) if k is None else tuple(float(v) if j == k else c for j, c in enumerate(old))
            joints = tuple(dataclasses.replace(joint, **{name: new}) if j == i else jt
                           for j, jt in enumerate(lg.spec.joints))
            return ChainLeg(dataclasses.replace(lg.spec, joints=joints))
        return get, put

    out = [("base.x", MM, *cfield("base", 0)), ("base.y", MM, *cfield("base", 1)),
           ("base.angle", RAD, *cfield("base_angle"))]
    for i in range(3):
        out += [(f"joint{i + 1}.offset", RAD, *jfield(i, "offset")),
                (f"joint{i + 1}.link.x", MM, *jfield(i, "link", 0)),
                (f"joint{i + 1}.link.y", MM, *jfield(i, "link", 1))]
    out += [("platform.x", MM, *cfield("platform", 0)), ("platform.y", MM, *cfield("platform", 1)),
            ("platform.angle", RAD, *cfield("platform_angle"))]
    return out


def _leg_spec(leg: LegType) -> list[tuple[str, str, Callable, Callable]]:
    """(name, unit, get, put) of one leg's geometric parameters."""
    if isinstance(leg, PPRLeg):
        units = dict(a=MM, alpha=RAD, beta=RAD, gamma=RAD, theta=RAD, d=MM, r=MM, psi=RAD)
        return [(n, u, *_sc(n)) for n, u in units.items()]
    if isinstance(leg, RPRLeg):
        return [("base.x", MM, *_pt("base", 0)), ("base.y", MM, *_pt("base", 1)),
                ("platform.x", MM, *_pt("platform", 0)), ("platform.y", MM, *_pt("platform", 1))]
    if isinstance(leg, RRRLeg):
        return [("base.x", MM, *_pt("base", 0)), ("base.y", MM, *_pt("base", 1)),
                ("platform.x", MM, *_pt("platform", 0)), ("platform.y", MM, *_pt("platform", 1)),
                ("proximal", MM, *_sc("proximal")), ("distal", MM, *_sc("distal"))]
    if isinstance(leg, PRRLeg):
        return [("guide.x", MM, *_pt("guide_point", 0)), ("guide.y", MM, *_pt("guide_point", 1)),
                ("guide.angle", RAD, *_sc("guide_angle")),
                ("platform.x", MM, *_pt("platform", 0)), ("platform.y", MM, *_pt("platform", 1)),
                ("distal", MM, *_sc("distal"))]
    if isinstance(leg, ChainLeg):
        return _chain_spec(leg)
    raise ConfigError(f"no calibration parameters for leg type {type(leg).__name__}")  # pragma: no cover


@dataclass(frozen=True)
class ParameterVector:
    """The error parameters of ``robot``: ``names`` (readable, e.g. ``leg2.base.x``), ``units`` and
    ``nominal`` values ``(P,)`` (mm, rad, 1), in the order of :func:`error_parameters`.

    >>> pv = error_parameters(Manipulator.preset("symmetric_3rrr"))
    >>> len(pv.names), pv.names[:3], pv.names[-3:]
    (27, ('leg1.base.x', 'leg1.base.y', 'leg1.platform.x'), ('frame.x', 'frame.y', 'frame.phi'))
    """

    robot: Manipulator
    names: tuple[str, ...]
    units: tuple[str, ...]
    nominal: np.ndarray

    def __repr__(self) -> str:
        return f"ParameterVector(robot={self.robot.name!r}, {len(self.names)} parameters)"

    def index(self, names) -> list[int]:
        """Positions of ``names`` in the vector; :class:`ConfigError` naming an unknown parameter."""
        out = []
        for n in names:
            if n not in self.names:
                raise ConfigError(f"no parameter {n!r} for this {self.robot.architecture} robot (names like "
                                  f"{self.names[0]}, leg1.actuator.offset, frame.phi)", key=n)
            out.append(self.names.index(n))
        return out

    @property
    def actuator_slices(self) -> tuple[np.ndarray, np.ndarray]:
        """Indices of ``leg{i}.actuator.offset`` and ``leg{i}.actuator.gain``, each shape ``(3,)``."""
        return (np.array(self.index([f"leg{i}.actuator.offset" for i in (1, 2, 3)])),
                np.array(self.index([f"leg{i}.actuator.gain" for i in (1, 2, 3)])))

    def split(self, values: np.ndarray) -> tuple[Manipulator, np.ndarray, np.ndarray, np.ndarray]:
        """``values (P,)`` -> (robot with that geometry, actuator offsets (3,), gains (3,), frame (3,) [mm, mm, rad]).

        The robot is built without the robot file's checks of :meth:`Manipulator.from_dict` (its legs' own
        checks apply); see :func:`robot_file` for the written-back file.
        """
        values = np.asarray(values, dtype=float)
        legs, k = [], 0
        for i, leg in enumerate(self.robot.legs):
            for _, _, _, put in _leg_spec(leg):
                leg = put(leg, values[k])
                k += 1
            legs.append(leg)
        robot = dataclasses.replace(self.robot, legs=tuple(legs))
        off_i, gain_i = self.actuator_slices
        return robot, values[off_i], values[gain_i], values[-3:]

    @property
    def leg_slices(self) -> tuple[slice, slice, slice]:
        """Positions of each leg's geometric parameters in the vector."""
        out, k = [], 0
        for leg in self.robot.legs:
            n = len(_leg_spec(leg))
            out.append(slice(k, k + n))
            k += n
        return tuple(out)

    def leg_chain(self, values: np.ndarray, i: int):
        """The chain (:class:`~pmaccuracy.model.chain.Chain`) of leg ``i`` (0-based) with the geometry in
        ``values``, without building the robot (fast path of the identification)."""
        leg = self.robot.legs[i]
        for v, (_, _, _, put) in zip(np.asarray(values, dtype=float)[self.leg_slices[i]], _leg_spec(leg)):
            leg = put(leg, v)
        return leg.chain

    def table(self, values: np.ndarray | None = None) -> dict[str, float]:
        """``{name: value}`` of ``values`` (default: the nominal)."""
        values = self.nominal if values is None else np.asarray(values, dtype=float)
        return dict(zip(self.names, (float(v) for v in values)))


def error_parameters(robot: Manipulator | SerialArm) -> ParameterVector:
    """The named error-parameter vector of any parallel robot (module docstring for the names and units);
    a serial arm's is a :class:`SerialParameterVector`.

    >>> pv = error_parameters(Manipulator.preset("aalborg_3ppr"))
    >>> pv.names[:3], pv.units[:3], len(pv.names)
    (('leg1.a', 'leg1.alpha', 'leg1.beta'), ('mm', 'rad', 'rad'), 33)
    """
    if isinstance(robot, SerialArm):
        return serial_error_parameters(robot)
    names, units, values = [], [], []
    for i, leg in enumerate(robot.legs, start=1):
        for name, unit_, get, _ in _leg_spec(leg):
            names.append(f"leg{i}.{name}")
            units.append(unit_)
            values.append(float(get(leg)))
    for i, chain in enumerate(robot.chains, start=1):
        names += [f"leg{i}.actuator.offset", f"leg{i}.actuator.gain"]
        units += [MM if chain.actuated.kind == "P" else RAD, ONE]
        values += [0.0, 1.0]
    names += ["frame.x", "frame.y", "frame.phi"]
    units += [MM, MM, RAD]
    values += [0.0, 0.0, 0.0]
    nominal = np.array(values)
    nominal.setflags(write=False)
    return ParameterVector(robot=robot, names=tuple(names), units=tuple(units), nominal=nominal)


@dataclass(frozen=True)
class SerialParameterVector:
    """The error parameters of a planar serial arm ``robot`` (:class:`~pmaccuracy.model.serial.SerialArm`):
    per joint ``k`` its ``joint{k}.offset`` (rad) and ``joint{k}.length`` (mm) of the robot file, its
    actuator's ``joint{k}.actuator.offset`` (rad for R, mm for P) and ``joint{k}.actuator.gain`` (joint value
    ``q_k = offset + gain * command``), then ``frame.x, frame.y`` (mm), ``frame.phi`` (rad): the
    measurement frame in the arm's base frame. ``names``, ``units``, ``nominal (P,)`` as
    :class:`ParameterVector`.

    >>> pv = error_parameters(SerialArm.preset("planar_3r_arm"))
    >>> len(pv.names), pv.names[:4], pv.units[:4]
    (15, ('joint1.offset', 'joint1.length', 'joint1.actuator.offset', 'joint1.actuator.gain'), ('rad', 'mm', 'rad', '1'))
    """

    robot: SerialArm
    names: tuple[str, ...]
    units: tuple[str, ...]
    nominal: np.ndarray

    def __repr__(self) -> str:
        return f"SerialParameterVector(robot={self.robot.name!r}, {len(self.names)} parameters)"

    def index(self, names) -> list[int]:
        """Positions of ``names`` in the vector; :class:`ConfigError` naming an unknown parameter."""
        out = []
        for n in names:
            if n not in self.names:
                raise ConfigError(f"no parameter {n!r} for this serial arm (names like joint1.length, "
                                  "joint2.actuator.offset, frame.phi)", key=n)
            out.append(self.names.index(n))
        return out

    def arrays(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``values (P,)`` -> joint offsets (n,) rad, lengths (n,) mm, actuator offsets (n,), gains (n,),
        frame (3,) [mm, mm, rad]."""
        v = np.asarray(values, dtype=float)
        table = v[:-3].reshape(-1, 4)
        return table[:, 0], table[:, 1], table[:, 2], table[:, 3], v[-3:]

    def split(self, values: np.ndarray) -> tuple[SerialArm, np.ndarray, np.ndarray, np.ndarray]:
        """``values`` -> (arm with those offsets and lengths, actuator offsets, gains, frame)."""
        off, length, a_off, gain, frame = self.arrays(values)
        joints = tuple(dataclasses.replace(j, offset=float(o), length=float(ln))
                       for j, o, ln in zip(self.robot.joints, off, length))
        return dataclasses.replace(self.robot, joints=joints), a_off, gain, frame

    def table(self, values: np.ndarray | None = None) -> dict[str, float]:
        """``{name: value}`` of ``values`` (default: the nominal)."""
        values = self.nominal if values is None else np.asarray(values, dtype=float)
        return dict(zip(self.names, (float(v) for v in values)))


def serial_error_parameters(arm: SerialArm) -> SerialParameterVector:
    """The :class:`SerialParameterVector` of ``arm`` (nominal: the file's offsets and lengths, actuator offset
    0 and gain 1, the measurement frame at the base)."""
    names, units, values = [], [], []
    for k, j in enumerate(arm.joints, start=1):
        names += [f"joint{k}.offset", f"joint{k}.length", f"joint{k}.actuator.offset", f"joint{k}.actuator.gain"]
        units += [RAD, MM, RAD if j.kind == "R" else MM, ONE]
        values += [j.offset, j.length, 0.0, 1.0]
    names += ["frame.x", "frame.y", "frame.phi"]
    units += [MM, MM, RAD]
    values += [0.0, 0.0, 0.0]
    nominal = np.array(values, dtype=float)
    nominal.setflags(write=False)
    return SerialParameterVector(robot=arm, names=tuple(names), units=tuple(units), nominal=nominal)


def serial_poses(pv: SerialParameterVector, values: np.ndarray, commands: np.ndarray) -> np.ndarray:
    """Measured poses ``(N, 3)`` (mm, mm, rad; measurement frame) of the arm ``values`` at ``commands (N, n)``:
    its forward kinematics (:meth:`~pmaccuracy.model.serial.SerialArm.frames`: ``a_k = a_{k-1} + offset_k +
    (q_k if R)``, ``c_{k+1} = c_k + exp(i a_k) (length_k + (q_k if P))``) at ``q = offset + gain * command``,
    read in the frame: ``F^-1 p``. Vectorized; lengths are not checked (a trial step of a fit may pass 0).

    >>> pv = error_parameters(SerialArm.preset("planar_3r_arm"))
    >>> serial_poses(pv, pv.nominal, np.radians([[90.0, -90.0, 0.0]])).round(9).tolist()
    [[350.0, 300.0, 0.0]]
    """
    off, length, a_off, gain, frame = pv.arrays(values)
    q = a_off + gain * np.asarray(commands, dtype=float)
    angle = np.zeros(q.shape[:-1])
    pos = np.zeros(q.shape[:-1], dtype=complex)
    for k, j in enumerate(pv.robot.joints):
        angle = angle + off[k] + (q[..., k] if j.kind == "R" else 0.0)
        pos = pos + np.exp(1j * angle) * (length[k] + (q[..., k] if j.kind == "P" else 0.0))
    return frame_inverse(frame, np.stack([pos.real, pos.imag, angle], axis=-1))


def robot_file(pv: ParameterVector | SerialParameterVector, values: np.ndarray, name: str | None = None) -> dict:
    """The robot-file table (:meth:`Manipulator.to_dict`) of the identified geometry in ``values``.

    The actuator offsets and gains and the measurement frame are not part of a robot file: they stay in
    the identification result (and :func:`pmaccuracy.accuracy.calibration.compensate` uses them).

    >>> pv = error_parameters(Manipulator.preset("symmetric_3rpr"))
    >>> v = pv.nominal.copy(); v[0] += 0.5
    >>> Manipulator.from_dict(robot_file(pv, v)).legs[0].base[0] - pv.robot.legs[0].base[0]
    0.5
    """
    robot, _, _, _ = pv.split(values)
    out = robot.to_dict()
    out["name"] = name or f"{pv.robot.name}_identified"
    out["description"] = f"{pv.robot.name} with its geometry identified by kinematic calibration"

    return out


def frame_apply(frame: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Robot-frame poses ``F * m`` of measured poses ``m (N, 3)`` for the frame ``(x, y, phi)`` (mm, rad).

    >>> frame_apply(np.array([1.0, 2.0, np.pi / 2]), np.array([[1.0, 0.0, 0.1]])).round(6).tolist()
    [[1.0, 3.0, 1.670796]]
    """
    poses = np.asarray(poses, dtype=float)
    c, s = np.cos(frame[2]), np.sin(frame[2])
    return np.stack([frame[0] + c * poses[:, 0] - s * poses[:, 1], frame[1] + s * poses[:, 0] + c * poses[:, 1],
                     poses[:, 2] + frame[2]], axis=-1)


def frame_inverse(frame: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Measured poses ``F^-1 * p`` of robot-frame poses ``p (N, 3)`` (the inverse of :func:`frame_apply`)."""
    poses = np.asarray(poses, dtype=float)
    c, s = np.cos(frame[2]), np.sin(frame[2])
    dx, dy = poses[:, 0] - frame[0], poses[:, 1] - frame[1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy, poses[:, 2] - frame[2]], axis=-1)


def joint_values(pv: ParameterVector, values: np.ndarray, measured: np.ndarray) -> np.ndarray:
    """Actuated joint values ``(N, 3)`` (mm / rad) of the robot ``values`` at measured poses ``(N, 3)``: its
    exact inverse kinematics on each leg's working mode; NaN where a leg cannot reach the pose."""
    values = np.asarray(values, dtype=float)
    poses = frame_apply(values[-3:], measured)
    return np.stack([leg_joint_value(pv, values, i, poses) for i in range(3)], axis=-1)


def leg_joint_value(pv: ParameterVector, values: np.ndarray, i: int, poses: np.ndarray) -> np.ndarray:
    """Actuated joint value ``(N,)`` of leg ``i`` (0-based) at robot-frame poses ``(N, 3)``."""
    c = pv.leg_chain(values, i)
    return c.inverse_kinematics(poses)[0][:, c.actuated_index]


def commands_for(pv: ParameterVector, values: np.ndarray, measured: np.ndarray) -> np.ndarray:
    """Actuator commands ``(N, 3)`` that put the robot ``values`` at measured-frame poses ``(N, 3)``:
    ``(q - offset) / gain`` of :func:`joint_values`, a revolute joint value ``q`` first turned by whole turns
    so that ``q - offset`` lies in ``[lo, lo + 2 pi)`` of the actuator's range."""
    _, off, gain, _ = pv.split(values)
    q = joint_values(pv, values, measured)
    return (off + wrap_commands(pv.robot, q - off) - off) / gain


def actuators(robot: Manipulator | SerialArm) -> list[tuple[str, tuple[float, float]]]:
    """``(kind, range)`` of each actuator: the actuated joint of each leg of a parallel robot, every joint of
    a serial arm (``"R"``: rad, ``"P"``: mm).

    >>> [k for k, _ in actuators(Manipulator.preset("symmetric_3rpr"))]
    ['P', 'P', 'P']
    """
    if isinstance(robot, SerialArm):
        return [(j.kind, tuple(j.range)) for j in robot.joints]
    return [(c.actuated.kind, tuple(c.actuated.range)) for c in robot.chains]


def wrap_commands(robot: Manipulator | SerialArm, commands: np.ndarray) -> np.ndarray:
    """Revolute commands ``(N, A)`` (rad) turned by whole turns into ``[lo, lo + 2 pi)`` of their range."""
    commands = np.array(commands, dtype=float)
    for k, (kind, (lo, _)) in enumerate(actuators(robot)):
        if kind == "R" and np.isfinite(lo):
            commands[:, k] = lo + np.mod(commands[:, k] - lo, 2 * np.pi)
    return commands
