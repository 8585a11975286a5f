"""Fresh MJCF and URDF files of our robots (the shapes CAD exporters write)."""

from __future__ import annotations

import json
import math
import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ...errors import ConfigError, GeometryError
from ...model.manipulator import Manipulator
from ...model.spatial import SpatialManipulator
from ...model.spatial_legs import DeltaLeg, PRSLeg, RPSLeg, UPULeg
from ...numerics.spatial import rotations, rotvecs
from .graph import EXTRAS_NAME, EXTRA_KEYS, _M, _unit, _signed_angle
from .sdf import SDF_NAMESPACE


def _f(v) -> str:
    return " ".join(repr(float(x)) for x in np.atleast_1d(v))


def _quat(R) -> np.ndarray:
    r = rotvecs(np.asarray(R)[None])[0]
    angle = float(np.linalg.norm(r))
    axis = r / angle if angle > 0 else np.array([1.0, 0.0, 0.0])
    return np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * axis])


def _extras_json(robot: SpatialManipulator) -> str:
    legs = []
    for leg in robot.legs:
        table = leg.to_table()
        legs.append({k: table[k] for k in EXTRA_KEYS if k in table})
    return json.dumps({"name": robot.name, "description": robot.description, "legs": legs})


def _home(robot: SpatialManipulator) -> tuple[np.ndarray, np.ndarray]:
    if robot.home is None:
        raise ConfigError("a robot needs a home pose (its [home] table) to be written as a file: the files place "
                          "the platform at a reference configuration", source=robot.name, key="home")
    h = np.asarray(robot.home, dtype=float)
    return h[:3], rotations(h[3:][None])[0]


def _leg_chain(leg, home) -> list[dict]:
    """The leg's bodies at the home pose: dicts ``name, pos (mm, world), joints [(kind, axis, ref, range,
    actuated)]``, each the child of the one before, and the platform-side ball points ``(body index, point)``.

    Every body has the world's orientation; hinge and slide ``ref`` values make the body positions the home
    configuration.
    """
    p, R = home
    q = float(leg.actuate(p, R))
    if not np.isfinite(q):
        raise GeometryError("the leg does not reach the home pose: no file can place it there", key="home")
    B = leg.platform_point(p, R)
    A = np.asarray(leg.base)
    if isinstance(leg, DeltaLeg):
        a = np.asarray(leg.axis)
        C = leg.elbow(q)
        half = 0.5 * leg.spacing * a
        Bs = [B + 0.5 * leg.spacing * (R @ a), B - 0.5 * leg.spacing * (R @ a)]
        arm = dict(pos=A, joints=[("hinge", a, q, leg.angle_range, True)])
        rods = [dict(pos=C + half, joints=[("ball",)], parent=0, tip=Bs[0]),
                dict(pos=C - half, joints=[("ball",)], parent=0, tip=Bs[1])]
        return [arm] + rods
    if isinstance(leg, PRSLeg):
        s, a = np.asarray(leg.slide), np.asarray(leg.axis)
        Cq = leg.carriage(q)
        u = (B - Cq) / np.linalg.norm(B - Cq)
        alpha = _signed_angle(np.asarray(leg.base_normal), u, a)
        return [dict(pos=Cq, joints=[("slide", s, q, leg.slide_range, True)]),
                dict(pos=Cq, joints=[("hinge", a, alpha, leg.angle_range, False)], tip=B)]
    d = (B - A) / np.linalg.norm(B - A)
    L = float(np.linalg.norm(B - A))
    if isinstance(leg, RPSLeg):
        a = np.asarray(leg.axis)
        alpha = _signed_angle(np.asarray(leg.base_normal), d, a)
        first = [("hinge", a, alpha, leg.angle_range, False)]
    elif leg.base_axis is None:
        first = [("ball",)]
    else:
        u1 = np.asarray(leg.base_axis)
        u2 = np.cross(u1, d)
        if np.linalg.norm(u2) < 1e-9:
            raise GeometryError("the leg is along its universal joint's base axis at home", key="base_axis")
        first = [("hinge", u1, 0.0, None, False), ("hinge", _unit(u2), 0.0, None, False)]
    chain = [dict(pos=A, joints=first), dict(pos=A, joints=[("slide", d, L, leg.length_range, True)], tip=B)]
    if isinstance(leg, UPULeg):
        u2 = _unit(np.cross(np.asarray(leg.base_axis), d))
        chain[-1].pop("tip")
        chain.append(dict(pos=B, joints=[("hinge", u2, 0.0, None, False),
                                         ("hinge", R @ np.asarray(leg.platform_axis), 0.0, None, False)], weld=True))
    return chain


_INERTIAL = dict(pos="0 0 0", mass="0.1", diaginertia="0.0001 0.0001 0.0001")


def _planar_chains(robot: Manipulator) -> list[list[dict]]:
    """Each planar leg as bodies at the pose (0, 0, 0) (the shape of :func:`_leg_chain`, the last welded)."""
    pose = np.zeros(3)
    out = []
    for i, chain in enumerate(robot.chains, start=1):
        st = chain.state(pose)
        q = st.q
        if not np.all(np.isfinite(q)):
            raise GeometryError("the leg does not reach the pose (0, 0, 0), the files' reference configuration",
                                source=robot.name, key=f"legs[{i}]")
        centres, dirs, _, _ = chain.frames(q)
        bodies = []
        for k, joint in enumerate(chain.joints):
            c = complex(centres[k])
            d = complex(dirs[k])
            rng = joint.range if joint.limited else None
            if joint.kind == "R":
                bodies.append(dict(pos=np.array([c.real, c.imag, 0.0]),
                                   joints=[("hinge", np.array([0.0, 0.0, 1.0]), float(q[k]), rng, joint.actuated)]))
            else:
                at = c + q[k] * d
                bodies.append(dict(pos=np.array([at.real, at.imag, 0.0]),
                                   joints=[("slide", np.array([d.real, d.imag, 0.0]), float(q[k]), rng,
                                            joint.actuated)]))
        bodies[-1]["weld"] = True
        out.append(bodies)
    return out


def mjcf_tree(robot) -> ET.ElementTree:
    """A fresh MJCF document of a spatial or planar robot (see :func:`write_mjcf`)."""
    planar = not isinstance(robot, SpatialManipulator)
    home = (np.zeros(3), np.eye(3)) if planar else _home(robot)
    p, R = home
    root = ET.Element("mujoco", model=robot.name)
    ET.SubElement(root, "compiler", angle="radian", autolimits="true")
    custom = ET.SubElement(root, "custom")
    ET.SubElement(custom, "text", name=EXTRAS_NAME, data=json.dumps({"name": robot.name,
                  "description": robot.description}) if planar else _extras_json(robot))
    world = ET.SubElement(root, "worldbody")
    equality = ET.Element("equality")
    actuator = ET.Element("actuator")
    plat = ET.SubElement(world, "body", name="platform", pos=_f(p / _M), quat=_f(_quat(R)))
    ET.SubElement(plat, "freejoint", name="platform_free")
    ET.SubElement(plat, "inertial", **_INERTIAL)
    planar_chains = _planar_chains(robot) if planar else None
    for i, leg in enumerate(robot.legs, start=1):
        try:
            chain = planar_chains[i - 1] if planar else _leg_chain(leg, home)
        except GeometryError as exc:
            raise GeometryError(exc.message, source=robot.name, key=f"legs[{i}]") from None
        elements, positions = [], []
        for k, body in enumerate(chain):
            parent_k = body.get("parent", k - 1)
            parent_el = world if parent_k < 0 else elements[parent_k]
            parent_pos = np.zeros(3) if parent_k < 0 else positions[parent_k]
            el = ET.SubElement(parent_el, "body", name=f"leg{i}_b{k + 1}", pos=_f((body["pos"] - parent_pos) / _M))
            ET.SubElement(el, "inertial", **_INERTIAL)
            for n, jt in enumerate(body["joints"], start=1):
                jname = f"leg{i}_b{k + 1}_j{n}"
                if jt[0] == "ball":
                    ET.SubElement(el, "joint", name=jname, type="ball")
                    continue
                kind, axis, ref, rng, act = jt
                scale = _M if kind == "slide" else 1.0
                attrs = dict(name=jname, type=kind, axis=_f(axis), ref=repr(ref / scale))
                if rng is not None:
                    attrs["range"] = _f(np.asarray(rng) / scale)
                ET.SubElement(el, "joint", **attrs)
                if act:
                    ET.SubElement(actuator, "position", name=f"leg{i}_actuator", joint=jname)
            elements.append(el)
            positions.append(body["pos"])
            if "tip" in body:
                ET.SubElement(equality, "connect", name=f"leg{i}_b{k + 1}_platform", body1=el.get("name"),
                              body2="platform", anchor=_f((body["tip"] - body["pos"]) / _M))
            if body.get("weld"):
                ET.SubElement(equality, "weld", name=f"leg{i}_platform", body1=el.get("name"), body2="platform")
    root.append(equality)
    root.append(actuator)
    ET.indent(root)
    return ET.ElementTree(root)


def write_mjcf(robot, path: str | os.PathLike) -> Path:
    """Write a spatial or planar robot as a fresh MJCF file (metres, radians) that :func:`read_robot_file` reads
    back (a planar robot as three chains of hinges about z and slides in the xy-plane, placed at the pose
    (0, 0, 0), each welded to the platform after its third joint).

    The shape CAD exporters write: every leg a chain of bodies from the world (a universal joint as two hinges,
    the actuated joint driven by a ``<position>`` actuator), the platform a free body placed at the home pose,
    each platform ball an ``<equality><connect>`` (a 3-UPU's platform-side universal joint a ``<weld>``). Joint
    ``ref`` values are the joint values at home (a leg length, an arm angle), so the bodies are drawn at home.
    Returns the path.
    """
    out = Path(path)
    mjcf_tree(robot).write(out, encoding="unicode", xml_declaration=False)
    return out


def urdf_tree(robot: SpatialManipulator) -> ET.ElementTree:
    """A fresh URDF document of a spatial robot (see :func:`write_urdf`)."""
    home = _home(robot)
    p, R = home
    root = ET.Element("robot", name=robot.name)
    ET.SubElement(root, "link", name="base_link")
    ET.SubElement(root, "link", name="platform")
    j = ET.SubElement(root, "joint", name="platform_float", type="floating")
    ET.SubElement(j, "parent", link="base_link")
    ET.SubElement(j, "child", link="platform")
    ET.SubElement(j, "origin", xyz=_f(p / _M), rpy=_f(_rpy(R)))
    refs: dict[str, float] = {}
    loops, transmissions = [], []
    for i, leg in enumerate(robot.legs, start=1):
        try:
            chain = _leg_chain(leg, home)
        except GeometryError as exc:
            raise GeometryError(exc.message, source=robot.name, key=f"legs[{i}]") from None
        last_link, last_pos = [], []
        for k, body in enumerate(chain):
            parent_k = body.get("parent", k - 1)
            parent, parent_pos = (("base_link", np.zeros(3)) if parent_k < 0
                                  else (last_link[parent_k], last_pos[parent_k]))
            offset = body["pos"] - parent_pos
            for n, jt in enumerate(body["joints"], start=1):
                axes = [("hinge", e, 0.0, None, False) for e in np.eye(3)] if jt[0] == "ball" else [jt]
                for m_, (kind, axis, ref, rng, act) in enumerate(axes, start=1):
                    name = f"leg{i}_b{k + 1}_j{n}" + (f"_{m_}" if jt[0] == "ball" else "")
                    link = name + "_link"
                    ET.SubElement(root, "link", name=link)
                    el = ET.SubElement(root, "joint", name=name, type="prismatic" if kind == "slide" else "revolute")
                    ET.SubElement(el, "parent", link=parent)
                    ET.SubElement(el, "child", link=link)
                    ET.SubElement(el, "origin", xyz=_f(offset / _M), rpy="0.0 0.0 0.0")
                    ET.SubElement(el, "axis", xyz=_f(axis))
                    scale = _M if kind == "slide" else 1.0
                    lo, hi = (-math.pi, math.pi) if rng is None else rng
                    # zero joint values are the home configuration: ranges relative to it unless refs say otherwise
                    if act and isinstance(leg, (DeltaLeg, PRSLeg)):
                        refs[name] = ref / scale
                        limits = (lo / scale, hi / scale)
                    else:
                        limits = ((lo - ref) / scale, (hi - ref) / scale) if rng is not None else (-math.pi, math.pi)
                        if kind == "hinge" and rng is not None:
                            refs[name] = ref
                            limits = (lo, hi)
                    ET.SubElement(el, "limit", lower=repr(limits[0]), upper=repr(limits[1]), effort="100.0",
                                  velocity="1.0")
                    if act:
                        tr = ET.Element("transmission", name=f"leg{i}_transmission")
                        ET.SubElement(tr, "type").text = "transmission_interface/SimpleTransmission"
                        tj = ET.SubElement(tr, "joint", name=name)
                        ET.SubElement(tj, "hardwareInterface").text = "hardware_interface/EffortJointInterface"
                        ta = ET.SubElement(tr, "actuator", name=f"leg{i}_motor")
                        ET.SubElement(ta, "mechanicalReduction").text = "1"
                        transmissions.append(tr)
                    parent, offset = link, np.zeros(3)
            last_link.append(parent)
            last_pos.append(body["pos"])
            if "tip" in body or body.get("weld"):
                loop = ET.Element("loop", name=f"leg{i}_b{k + 1}_platform",
                                  type="fixed" if body.get("weld") else "spherical")
                pred = ET.SubElement(loop, "predecessor", name=parent)
                tip = body.get("tip", body["pos"])
                ET.SubElement(pred, "origin", xyz=_f((tip - body["pos"]) / _M), rpy="0.0 0.0 0.0")
                succ = ET.SubElement(loop, "successor", name="platform")
                ET.SubElement(succ, "origin", xyz=_f(R.T @ (tip - p) / _M), rpy="0.0 0.0 0.0")
                loops.append(loop)
    for el in loops + transmissions:
        root.append(el)
    data = json.loads(_extras_json(robot))
    data["refs"] = refs
    ET.SubElement(root, EXTRAS_NAME).text = json.dumps(data)
    ET.indent(root)
    return ET.ElementTree(root)


def _rpy(R) -> np.ndarray:
    """URDF roll, pitch, yaw (``R = Rz(y) Ry(p) Rx(r)``) of a rotation matrix (rad)."""
    R = np.asarray(R)
    pitch = math.asin(-max(-1.0, min(1.0, R[2, 0])))
    if abs(R[2, 0]) < 1 - 1e-12:
        roll, yaw = math.atan2(R[2, 1], R[2, 2]), math.atan2(R[1, 0], R[0, 0])
    else:
        roll, yaw = math.atan2(-R[1, 2], R[1, 1]), 0.0
    return np.array([roll, pitch, yaw])


def write_urdf(robot: SpatialManipulator, path: str | os.PathLike) -> Path:
    """Write a spatial robot as a fresh URDF file with URDF+ loop closures that :func:`read_robot_file` reads
    back.

    The platform is a ``floating`` link at the home pose; every leg a chain of links from ``base_link`` (a ball
    joint as three revolutes through one point, a universal joint as two), each platform ball a spherical
    ``<loop>`` (a 3-UPU's platform-side universal joint ends in a ``fixed`` loop); the actuated joints have
    ``<transmission>`` elements. Zero joint values are the home configuration; the ``<pmaccuracy>`` JSON keeps
    our non-kinematic keys and the joints' reference values. Returns the path.
    """
    out = Path(path)
    urdf_tree(robot).write(out, encoding="unicode", xml_declaration=True)
    return out


def sdf_tree(robot: SpatialManipulator) -> ET.ElementTree:
    """A fresh SDFormat 1.9 document of a spatial robot (see :func:`write_sdf`)."""
    home = _home(robot)
    p, R = home
    root = ET.Element("sdf", {"version": "1.9", "xmlns:pmaccuracy": SDF_NAMESPACE})
    model = ET.SubElement(root, "model", name=robot.name)
    ET.SubElement(model, "link", name="base_link")
    j = ET.SubElement(model, "joint", name="base_fixed", type="fixed")
    ET.SubElement(j, "parent").text = "world"
    ET.SubElement(j, "child").text = "base_link"
    plat = ET.SubElement(model, "link", name="platform")
    ET.SubElement(plat, "pose", relative_to="base_link").text = _f(np.concatenate([p / _M, _rpy(R)]))
    refs: dict[str, float] = {}
    plugins = []
    for i, leg in enumerate(robot.legs, start=1):
        try:
            chain = _leg_chain(leg, home)
        except GeometryError as exc:
            raise GeometryError(exc.message, source=robot.name, key=f"legs[{i}]") from None
        names = []
        for k, body in enumerate(chain):
            parent_k = body.get("parent", k - 1)
            parent = "base_link" if parent_k < 0 else names[parent_k]
            link = f"leg{i}_b{k + 1}"
            el = ET.SubElement(model, "link", name=link)
            ET.SubElement(el, "pose", relative_to="base_link").text = _f(np.concatenate([body["pos"] / _M,
                                                                                         np.zeros(3)]))
            jts = body["joints"]
            jel = ET.SubElement(model, "joint", name=f"{link}_j")
            ET.SubElement(jel, "parent").text = parent
            ET.SubElement(jel, "child").text = link
            if jts[0][0] == "ball":
                jel.set("type", "ball")
            else:
                jel.set("type", "universal" if len(jts) == 2 else ("prismatic" if jts[0][0] == "slide" else "revolute"))
                for n, (kind, axis, ref, rng, act) in enumerate(jts):
                    ax = ET.SubElement(jel, "axis" if n == 0 else "axis2")
                    ET.SubElement(ax, "xyz", expressed_in="__model__").text = _f(axis)
                    scale = _M if kind == "slide" else 1.0
                    key = jel.get("name") if n == 0 else f"{jel.get('name')}:axis2"
                    # zero joint values are the drawn (home) configuration and limits relative to it, as a
                    # simulator reads them; a Delta's arm angle and a 3-PRS carriage keep our coordinate (refs)
                    own = act and isinstance(leg, (DeltaLeg, PRSLeg))
                    if own:
                        refs[key] = ref / scale
                    if rng is not None:
                        lo, hi = (rng[0], rng[1]) if own else (rng[0] - ref, rng[1] - ref)
                        lim = ET.SubElement(ax, "limit")
                        ET.SubElement(lim, "lower").text = repr(lo / scale)
                        ET.SubElement(lim, "upper").text = repr(hi / scale)
                    if act:
                        plugins.append((i, jel.get("name")))
            names.append(link)
            if "tip" in body:
                c = ET.SubElement(model, "joint", name=f"{link}_platform", type="ball")
                ET.SubElement(c, "parent").text = link
                ET.SubElement(c, "child").text = "platform"
                ET.SubElement(c, "pose").text = _f(np.concatenate([R.T @ (body["tip"] - p) / _M, np.zeros(3)]))
            if body.get("weld"):
                w = ET.SubElement(model, "joint", name=f"{link}_platform", type="fixed")
                ET.SubElement(w, "parent").text = "platform"
                ET.SubElement(w, "child").text = link
    for i, joint in plugins:
        pl = ET.SubElement(model, "plugin", filename="gz-sim-joint-position-controller-system",
                           name="gz::sim::systems::JointPositionController")
        ET.SubElement(pl, "joint_name").text = joint
    data = json.loads(_extras_json(robot))
    data["refs"] = refs
    ET.SubElement(model, "pmaccuracy:extras").text = json.dumps(data)
    ET.indent(root)
    return ET.ElementTree(root)


def write_sdf(robot: SpatialManipulator, path: str | os.PathLike) -> Path:
    """Write a spatial robot as a fresh SDFormat 1.9 file that :func:`read_robot_file` reads back.

    A ``base_link`` fixed to the world; the platform a link at the home pose (no joint of its own); every leg a
    chain of links from ``base_link`` (a universal joint one ``universal`` joint, a ball one ``ball`` joint),
    its last link joined to the platform by a ``ball`` joint (a 3-UPU's by a ``fixed`` joint after its
    platform-side ``universal``) that closes the loop; the actuated joints are driven by Gazebo
    ``JointPositionController`` plugins. Zero joint values are the drawn (home) configuration and the limits are
    relative to it (as a simulator reads them), except a Delta's arm angles and a 3-PRS's carriage positions,
    whose values at home go into the model's ``<pmaccuracy:extras>`` JSON (with our non-kinematic keys) and whose
    limits stay in our coordinates. Returns the path.
    """
    out = Path(path)
    sdf_tree(robot).write(out, encoding="unicode", xml_declaration=True)
    return out
