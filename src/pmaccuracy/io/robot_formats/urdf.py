"""URDF files read by yourdfpy, with their loop closures, into a kinematic graph."""

from __future__ import annotations

import math
import os
import re
import xml.etree.ElementTree as ET

import numpy as np

from ... import _optional
from .graph import EXTRAS_NAME, _M, FileJoint, KinematicGraph, _Groups, _error, _extras, _unit


def read_urdf(path: str | os.PathLike) -> KinematicGraph:
    """The kinematic graph of a URDF file read by ``yourdfpy`` at zero joint values, with its loop closures.

    Loops: onshape-to-robot's closing frames (links ``closing_NAME_1`` and ``closing_NAME_2`` meeting at zero
    joint values, a ball at their origin), Gazebo's ``<gazebo><joint name type="ball"|"revolute"><parent>L1</parent><child>L2</child>
    <pose>x y z r p y</pose></joint></gazebo>`` (the SDFormat joint that closes a URDF's loop; its pose in the
    child link's frame), URDF+ ``<loop name type="spherical"><predecessor name=LINK><origin xyz rpy/></predecessor>
    <successor name=LINK>...</successor></loop>`` (the closure point is the predecessor's origin; ``type="fixed"``
    welds the two links) and
    ``<loop_joint name type="spherical"><link1 link=LINK xyz=.../><link2 .../></loop_joint>``. Actuated joints:
    those of ``<transmission>`` elements (none: the pattern's actuated joint). Ranges: ``<limit lower upper>``.
    URDF has no reference offsets: a joint's value at zero is its reference unless the ``<pmaccuracy>`` JSON
    gives ``refs`` (joint name -> value in m or rad, written by :func:`write_urdf`).
    """
    yourdfpy = _optional.require("yourdfpy", "reading a URDF file")
    source = os.fspath(path)
    try:
        tree = ET.parse(source)
    except (ET.ParseError, OSError) as exc:
        raise _error(source, None, f"not a readable XML file: {exc}") from None
    root = tree.getroot()
    if root.tag != "robot":
        raise _error(source, root.tag, "a URDF file's root element must be <robot>")
    link_names = {el.get("name") for el in root.findall("link")}
    for el in root.findall("joint"):
        label = f"joint '{el.get('name', '?')}'"
        for end in ("parent", "child"):
            node = el.find(end)
            if node is None or node.get("link") not in link_names:
                got = None if node is None else node.get("link")
                raise _error(source, label, f"its <{end} link=...> must name a link of the robot, got {got!r}")
    try:
        urdf = yourdfpy.URDF.load(source, build_scene_graph=True, load_meshes=False, build_collision_scene_graph=False)
    except Exception as exc:  # yourdfpy raises many kinds; one line naming the file
        first = str(exc).splitlines()[0] if str(exc) else repr(exc)
        raise _error(source, None, f"yourdfpy cannot read it: {first}") from None
    robot = urdf.robot
    links = [link.name for link in robot.links]
    base_link = urdf.base_link
    groups = _Groups(len(links))
    lid = {n: i for i, n in enumerate(links)}
    for joint in robot.joints:
        if joint.type == "fixed":
            groups.union(lid[joint.parent], lid[joint.child])
    for joint in robot.joints:
        if joint.type not in ("fixed", "revolute", "continuous", "prismatic", "floating"):
            raise _error(source, f"joint '{joint.name}'", f"a {joint.type} joint cannot be mapped to a leg's joint")
    loops = list(root.iter("loop")) + list(root.iter("loop_joint"))
    for el in loops:
        if el.get("type") == "fixed":
            ends = _loop_links(el)
            if any(n is None or n not in lid for n in ends):
                raise _error(source, f"{el.tag} '{el.get('name', '?')}'",
                             f"must name two links of the robot, got {ends}")
            groups.union(lid[ends[0]], lid[ends[1]])
    extra = root.find(EXTRAS_NAME)
    extras = _extras(extra.text if extra is not None else None, source)
    refs = extras.get("refs", {}) if isinstance(extras.get("refs"), dict) else {}
    # the base group first
    roots = sorted({groups.find(i) for i in range(len(links))}, key=lambda r: (r != groups.find(lid[base_link]), r))
    index = {r: i for i, r in enumerate(roots)}

    def world(link):
        T = urdf.get_transform(link, base_link) if link != base_link else np.eye(4)
        return T[:3, 3] * _M, T[:3, :3]

    frames, names, free = [], [], set()
    floating_children = {j.child for j in robot.joints if j.type == "floating"}
    for r in roots:
        members = [links[i] for i in range(len(links)) if groups.find(i) == r]
        fixed_children = {j.child for j in robot.joints if j.type == "fixed"
                          and groups.find(lid[j.parent]) == groups.find(lid[j.child])}
        roots_in_group = [n for n in members if n not in fixed_children]
        frame_link = next((n for n in members if n in floating_children),
                          roots_in_group[0] if roots_in_group else members[0])
        if frame_link in floating_children:
            free.add(index[r])
        frames.append(world(frame_link))
        names.append(frame_link)
    actuated = set()
    for tr in root.iter("transmission"):
        for jel in tr.iter("joint"):
            if jel.get("name"):
                actuated.add(jel.get("name"))
    graph = KinematicGraph(source=source, names=names, frames=frames, free=free, any_actuator=bool(actuated))
    for joint in robot.joints:
        if joint.type in ("fixed", "floating"):
            continue
        parent, child = index[groups.find(lid[joint.parent])], index[groups.find(lid[joint.child])]
        p, R = world(joint.child)
        axis = np.asarray(joint.axis if joint.axis is not None else (1.0, 0.0, 0.0), dtype=float)
        axis = R @ (axis / np.linalg.norm(axis))
        kind = "slide" if joint.type == "prismatic" else "hinge"
        scale = _M if kind == "slide" else 1.0
        rng = None
        if joint.type != "continuous" and joint.limit is not None and joint.limit.lower is not None \
                and joint.limit.upper is not None:
            rng = (float(joint.limit.lower) * scale, float(joint.limit.upper) * scale)
        graph.edges.append([FileJoint(name=f"joint '{joint.name}'", kind=kind, anchor=p, axis=axis, range=rng,
                                      ref=float(refs.get(joint.name, 0.0)) * scale, actuated=joint.name in actuated,
                                      parent=parent, child=child, ident=("urdf", joint.name))])
    for n_loop, el in enumerate(loops):
        label = f"{el.tag} '{el.get('name', '?')}'"
        if el.get("type") == "fixed":
            continue
        if el.get("type", "spherical") not in ("spherical", "ball"):
            raise _error(source, label, f"a {el.get('type')} loop closure cannot be mapped (spherical only)")
        if el.tag == "loop":
            ends = [el.find("predecessor"), el.find("successor") if el.find("successor") is not None
                    else el.find("sucessor")]
            ends_links = [None if e is None else (e.get("name") or e.get("link")) for e in ends]
            origins = [None if e is None else e.find("origin") for e in ends]
            offsets = [_xyz(o.get("xyz") if o is not None else None, source, label) for o in origins]
            rpys = [_xyz(o.get("rpy") if o is not None else None, source, label) for o in origins]
        else:
            ends = [el.find("link1"), el.find("link2")]
            ends_links = [None if e is None else e.get("link") for e in ends]
            offsets = [_xyz(None if e is None else e.get("xyz"), source, label) for e in ends]
            rpys = [np.zeros(3), np.zeros(3)]
        if any(n is None or n not in lid for n in ends_links):
            raise _error(source, label, f"must name two links of the robot, got {ends_links}")
        p1, R1 = world(ends_links[0])
        point = p1 + R1 @ offsets[0] * _M
        p2, R2 = world(ends_links[1])
        other = p2 + R2 @ offsets[1] * _M
        if np.linalg.norm(point - other) > 1e-6 * max(1.0, float(np.linalg.norm(point))):
            raise _error(source, label, f"its two ends are {np.linalg.norm(point - other):.6g} mm apart at zero "
                                        "joint values: the loop is not closed")
        del rpys
        g1, g2 = index[groups.find(lid[ends_links[0]])], index[groups.find(lid[ends_links[1]])]
        graph.edges.append([FileJoint(name=label, kind="ball", anchor=point, axis=np.zeros(3), range=None, ref=0.0,
                                      actuated=False, parent=g1, child=g2, ident=("loop", n_loop))])
    closing: dict[str, list[str]] = {}
    for name in links:   # onshape-to-robot's closing frames: links closing_NAME_1 and closing_NAME_2 meet
        match = re.fullmatch(r"closing_(.+)_([12])", name)
        if match:
            closing.setdefault(match.group(1), []).append(name)
    for key, ends in sorted(closing.items()):
        label = f"closing frames 'closing_{key}_1/2'"
        if len(ends) != 2:
            raise _error(source, label, f"a closing frame needs its pair, found only {ends[0]!r}")
        (pa, _), (pb, _) = world(ends[0]), world(ends[1])
        if np.linalg.norm(pa - pb) > 1e-6 * max(1.0, float(np.linalg.norm(pa))):
            raise _error(source, label, f"the two frames are {np.linalg.norm(pa - pb):.6g} mm apart at zero joint "
                                        "values: the loop is not closed")
        ga, gb = index[groups.find(lid[ends[0]])], index[groups.find(lid[ends[1]])]
        graph.edges.append([FileJoint(name=label, kind="ball", anchor=pa, axis=np.zeros(3), range=None, ref=0.0,
                                      actuated=False, parent=ga, child=gb, ident=("closing", key))])
    for n_gz, jel in enumerate(_gazebo_joints(root)):
        label = f"gazebo joint '{jel.get('name', '?')}'"
        kind = jel.get("type")
        if kind not in ("ball", "revolute"):
            raise _error(source, label, f"a {kind} loop closure cannot be mapped (ball or revolute)")
        ends = [(jel.findtext("parent") or "").strip(), (jel.findtext("child") or "").strip()]
        if any(n not in lid for n in ends):
            raise _error(source, label, f"must name two links of the robot as <parent> and <child>, got {ends}")
        pose = _pose6(jel.findtext("pose"), source, label)
        pc, Rc = world(ends[1])
        point = pc + Rc @ pose[:3] * _M
        axis = np.zeros(3)
        if kind == "revolute":
            xyz = _xyz(jel.findtext("axis/xyz") or "0 0 1", source, label)
            axis = _unit(Rc @ _rpy_matrix(pose[3:]) @ xyz)
        g1, g2 = index[groups.find(lid[ends[0]])], index[groups.find(lid[ends[1]])]
        graph.edges.append([FileJoint(name=label, kind="ball" if kind == "ball" else "hinge", anchor=point,
                                      axis=axis, range=None, ref=0.0, actuated=False, parent=g1, child=g2,
                                      ident=("gazebo", n_gz))])
    graph.extras = extras
    return graph


def _gazebo_joints(root: ET.Element) -> list[ET.Element]:
    """Gazebo's loop closures in a URDF: SDFormat ``<joint>`` elements inside ``<gazebo>`` extensions."""
    return [j for gz in root.findall("gazebo") for j in gz.findall("joint")]


def _pose6(text: str | None, source: str, label: str) -> np.ndarray:
    """An SDFormat ``<pose>`` ``x y z roll pitch yaw`` (m, rad; zeros when absent), relative to the child link."""
    if not text or not text.strip():
        return np.zeros(6)
    try:
        out = np.array([float(v) for v in text.split()])
    except ValueError:
        raise _error(source, label, f"<pose> expects six numbers, got {text!r}") from None
    if out.shape != (6,) or not np.all(np.isfinite(out)):
        raise _error(source, label, f"<pose> expects six numbers, got {text!r}")
    return out


def _rpy_matrix(rpy) -> np.ndarray:
    """``Rz(yaw) Ry(pitch) Rx(roll)`` (URDF's and SDFormat's fixed-axis roll, pitch, yaw)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def _loop_links(el) -> list:
    if el.tag == "loop":
        succ = el.find("successor") if el.find("successor") is not None else el.find("sucessor")
        ends = [el.find("predecessor"), succ]
        return [None if e is None else (e.get("name") or e.get("link")) for e in ends]
    return [None if e is None else e.get("link") for e in (el.find("link1"), el.find("link2"))]


def _xyz(text: str | None, source: str, label: str) -> np.ndarray:
    if text is None:
        return np.zeros(3)
    try:
        out = np.array([float(v) for v in text.split()])
    except ValueError:
        raise _error(source, label, f"expected three numbers, got {text!r}") from None
    if out.shape != (3,) or not np.all(np.isfinite(out)):
        raise _error(source, label, f"expected three numbers, got {text!r}")
    return out
