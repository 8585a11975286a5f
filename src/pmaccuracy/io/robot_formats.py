"""Robot files of other tools: MuJoCo MJCF (loops closed by ``<equality><connect/>``) and URDF with loop closures.

Reading goes through the ecosystem's own parsers: the ``mujoco`` package compiles an MJCF file (frames,
``childclass``, quaternions, Euler angles, ``<compiler angle=...>`` are MuJoCo's business) and its kinematics at
the reference configuration ``qpos0`` give every joint's world anchor and axis; ``yourdfpy`` reads a URDF and its
forward kinematics at zero joint values give the link frames. Either becomes a neutral graph
(:class:`KinematicGraph`): rigid groups of bodies (bodies welded together or with no joint of their own are one
group), joined by joints (hinge, slide, ball) and loop closures (a closure is a ball joint at its anchor). The
legs are the connected pieces left when the base (the world's group) and the platform (the group that most
legs reach) are taken away; the joints along each leg, merged into kinematic pairs (two hinges through one point
make a universal joint ``U``, three or a ball a spherical joint ``S``), give its pattern: ``UPS`` or ``SPS``
(6-UPS), ``RPS``, ``PRS``, ``UPU``, or an actuated hinge with two ``SS`` rods (the Delta's R(SS)2).

Units: the files' metres become mm, radians stay radians inside (degrees in our TOML). The platform frame is
the platform body's frame, the home pose its pose at the reference configuration, the base frame the world's
(or that of the one fixed body under the world that carries the legs). Actuated joint values are MuJoCo's joint
values where our model has the same coordinate (a Delta's arm angle, a 3-PRS carriage); a leg length (6-UPS,
3-RPS, 3-UPU) is the reference length plus the slide's travel from its ``ref``.

Writing: :func:`write_mjcf` and :func:`write_urdf` give fresh files of any spatial robot (the exporter shapes:
a free platform closed by one connect per ball, URDF+ ``<loop>`` elements), :func:`export_into` writes a
calibrated robot into the file it came from, changing only positions, axes, joint references and the actuated
ranges. Non-kinematic data of our format (name, description, cones, radii, joint-cone axes) ride along in an
MJCF ``<custom><text name="pmaccuracy">`` (a URDF ``<pmaccuracy>`` element) as JSON.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import _optional
from ..errors import ConfigError, GeometryError
from ..model.chain import Chain
from ..model.chain import Joint as ChainJoint
from ..model.legs import ChainLeg
from ..model.manipulator import Manipulator
from ..model.spatial import SpatialManipulator
from ..model.spatial_legs import DeltaLeg, PRSLeg, RPSLeg, UPSLeg, UPULeg
from ..numerics.spatial import rotations, rotvecs

#: File suffixes of the robot files this module reads, and their format.
SUFFIXES = {".xml": "mjcf", ".mjcf": "mjcf", ".urdf": "urdf"}
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
    """True for a path (str or PathLike) ending in ``.xml``, ``.mjcf``, ``.urdf`` (:data:`SUFFIXES`) or ``.sdf``
    (refused by :func:`read_robot_file` with its reason)."""
    return isinstance(spec, (str, os.PathLike)) and Path(spec).suffix.lower() in (*SUFFIXES, ".sdf")


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


def read_mjcf(path: str | os.PathLike) -> KinematicGraph:
    """The kinematic graph of an MJCF file, compiled by MuJoCo and placed at its reference ``qpos0``.

    World anchors and axes are MuJoCo's ``xanchor``/``xaxis`` after ``mj_kinematics`` (metres -> mm); joint
    ranges ``jnt_range`` (rad or m -> mm, MuJoCo has converted degrees); a ``connect`` closes a loop with a
    ball at its ``anchor`` (in ``body1``'s frame), a ``weld`` makes two bodies one group; actuated joints are
    the ``joint`` transmissions of ``<actuator>`` elements. Raises :class:`ConfigError` naming the file and the
    element MuJoCo or this reader refuses.
    """
    mujoco = _optional.require("mujoco", "reading an MJCF file")
    source = os.fspath(path)
    try:
        m = mujoco.MjModel.from_xml_path(source)
    except ValueError as exc:
        lines = [s.strip() for s in str(exc).splitlines() if s.strip()]
        raise _error(source, None, "MuJoCo cannot read it: " + "; ".join(lines)) from None
    d = mujoco.MjData(m)
    d.qpos[:] = m.qpos0
    mujoco.mj_kinematics(m, d)
    obj = mujoco.mjtObj

    def name(kind, i, what):
        n = mujoco.mj_id2name(m, kind, i)
        return f"{what} '{n}'" if n else f"{what} #{i}"

    groups = _Groups(m.nbody)
    for b in range(1, m.nbody):
        if m.body_jntnum[b] == 0:
            groups.union(b, int(m.body_parentid[b]))
    for e in range(m.neq):
        if not m.eq_active0[e]:
            continue
        kind = int(m.eq_type[e])
        if kind == int(mujoco.mjtEq.mjEQ_WELD):
            b1, b2 = _eq_bodies(m, e, mujoco)
            groups.union(b1, b2)
        elif kind != int(mujoco.mjtEq.mjEQ_CONNECT):
            raise _error(source, name(obj.mjOBJ_EQUALITY, e, "equality"),
                         "only connect (a ball closing a loop) and weld constraints can be mapped to a leg's joints")
    floating_base = _floating_base(m, groups, mujoco)
    if floating_base is not None:          # an exporter's free root: the robot's base, taken as fixed
        groups.union(floating_base, 0)
    base_body = floating_base if floating_base is not None else _base_body(m, groups)
    p0 = d.xpos[base_body] * _M
    R0 = d.xmat[base_body].reshape(3, 3).copy()

    def here(point_m):
        return R0.T @ (np.asarray(point_m) * _M - p0)

    roots = sorted({groups.find(b) for b in range(m.nbody)})
    index = {r: i for i, r in enumerate(roots)}
    frames, names = [], []
    free = set()
    for r in roots:
        members = [b for b in range(m.nbody) if groups.find(b) == r]
        floating = [b for b in members if m.body_jntnum[b] == 1
                    and int(m.jnt_type[m.body_jntadr[b]]) == int(mujoco.mjtJoint.mjJNT_FREE)]
        if floating:
            free.add(index[r])
        frame_body = floating[0] if floating else members[0]
        frames.append((here(d.xpos[frame_body]), R0.T @ d.xmat[frame_body].reshape(3, 3)))
        names.append(mujoco.mj_id2name(m, obj.mjOBJ_BODY, frame_body) or f"body #{frame_body}")
    actuated, ctrl = set(), {}
    for a in range(m.nu):
        if int(m.actuator_trntype[a]) in (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT)):
            j = int(m.actuator_trnid[a, 0])
            actuated.add(j)
            # a position servo's control range is a range of joint values (used when the joint has none)
            servo = int(m.actuator_biastype[a]) == int(mujoco.mjtBias.mjBIAS_AFFINE) and m.actuator_ctrllimited[a] \
                and m.actuator_gear[a, 0] == 1.0
            if servo:
                ctrl[j] = (float(m.actuator_ctrlrange[a, 0]), float(m.actuator_ctrlrange[a, 1]))
    graph = KinematicGraph(source=source, names=names, frames=frames, free=free, any_actuator=bool(actuated))
    kinds = {int(mujoco.mjtJoint.mjJNT_HINGE): "hinge", int(mujoco.mjtJoint.mjJNT_SLIDE): "slide",
             int(mujoco.mjtJoint.mjJNT_BALL): "ball"}
    for b in range(1, m.nbody):
        if m.body_jntnum[b] == 0:
            continue
        child = index[groups.find(b)]
        parent = index[groups.find(int(m.body_parentid[b]))]
        joints = []
        for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b]):
            jt = int(m.jnt_type[j])
            if jt == int(mujoco.mjtJoint.mjJNT_FREE):
                continue
            scale = _M if kinds[jt] == "slide" else 1.0
            limited = bool(m.jnt_limited[j])
            rng = (float(m.jnt_range[j, 0]) * scale, float(m.jnt_range[j, 1]) * scale) if limited else None
            if rng is None and j in ctrl:
                rng = (ctrl[j][0] * scale, ctrl[j][1] * scale)
            ref = float(m.qpos0[m.jnt_qposadr[j]]) * scale if kinds[jt] != "ball" else 0.0
            axis = R0.T @ d.xaxis[j] if kinds[jt] != "ball" else np.zeros(3)
            joints.append(FileJoint(name=name(obj.mjOBJ_JOINT, j, "joint"), kind=kinds[jt], anchor=here(d.xanchor[j]),
                                    axis=axis, range=rng, ref=ref, actuated=j in actuated, parent=parent,
                                    child=child, ident=("joint", j)))
        if joints and parent != child:
            graph.edges.append(joints)
    for e in range(m.neq):
        if not m.eq_active0[e] or int(m.eq_type[e]) != int(mujoco.mjtEq.mjEQ_CONNECT):
            continue
        b1, b2 = _eq_bodies(m, e, mujoco)
        if int(m.eq_objtype[e]) == int(obj.mjOBJ_SITE):
            point = d.site_xpos[int(m.eq_obj1id[e])]
        else:
            point = d.xpos[b1] + d.xmat[b1].reshape(3, 3) @ m.eq_data[e, :3]
        g1, g2 = index[groups.find(b1)], index[groups.find(b2)]
        if g1 == g2:
            raise _error(source, name(obj.mjOBJ_EQUALITY, e, "connect"), "joins a body to itself (no loop)")
        graph.edges.append([FileJoint(name=name(obj.mjOBJ_EQUALITY, e, "connect"), kind="ball", anchor=here(point),
                                      axis=np.zeros(3), range=None, ref=0.0, actuated=False, parent=g1, child=g2,
                                      ident=("equality", e))])
    text = None
    for t in range(m.ntext):
        if mujoco.mj_id2name(m, obj.mjOBJ_TEXT, t) == EXTRAS_NAME:
            adr, size = int(m.text_adr[t]), int(m.text_size[t])
            text = bytes(m.text_data[adr:adr + size]).rstrip(b"\x00").decode()
    graph.extras = _extras(text, source)
    return graph


def _eq_bodies(m, e, mujoco) -> tuple[int, int]:
    """The two bodies of equality ``e`` (a site's body for site-based constraints; 0 for the world)."""
    o1, o2 = int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
    if int(m.eq_objtype[e]) == int(mujoco.mjtObj.mjOBJ_SITE):
        return int(m.site_bodyid[o1]), int(m.site_bodyid[o2])
    return o1, max(o2, 0)


def _floating_base(m, groups, mujoco) -> int | None:
    """The free body directly under the world that roots the robot's tree, when nothing else holds to the world.

    CAD exporters give a robot's root body a free joint by default; when no joint or constraint attaches any body
    to the world and exactly one free body under it carries moving bodies, that body is the base.
    """
    free = int(mujoco.mjtJoint.mjJNT_FREE)
    for b in range(1, m.nbody):
        if m.body_jntnum[b] and groups.find(b) == 0:
            return None
        if int(m.body_parentid[b]) == 0 and m.body_jntnum[b] and int(m.jnt_type[m.body_jntadr[b]]) != free:
            return None
    for e in range(m.neq):
        if m.eq_active0[e] and 0 in {groups.find(b) for b in _eq_bodies(m, e, mujoco)}:
            return None
    roots = [b for b in range(1, m.nbody) if int(m.body_parentid[b]) == 0 and m.body_jntnum[b] == 1
             and int(m.jnt_type[m.body_jntadr[b]]) == free
             and any(m.body_jntnum[c] for c in range(b + 1, m.nbody) if _descends(m, c, b))]
    return roots[0] if len(roots) == 1 else None


def _base_body(m, groups) -> int:
    """The world (0), or the one fixed body directly under the world whose subtree holds moving bodies."""
    carriers = []
    for b in range(1, m.nbody):
        if int(m.body_parentid[b]) == 0 and m.body_jntnum[b] == 0:
            sub = [c for c in range(b + 1, m.nbody) if _descends(m, c, b)]
            if any(m.body_jntnum[c] for c in sub):
                carriers.append(b)
    return carriers[0] if len(carriers) == 1 else 0


def _descends(m, c: int, b: int) -> bool:
    while c > 0:
        if c == b:
            return True
        c = int(m.body_parentid[c])
    return False


# ---------------------------------------------------------------------------------------------- URDF
def read_urdf(path: str | os.PathLike) -> KinematicGraph:
    """The kinematic graph of a URDF file read by ``yourdfpy`` at zero joint values, with its loop closures.

    Loops: Gazebo's ``<gazebo><joint name type="ball"|"revolute"><parent>L1</parent><child>L2</child>
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


# ---------------------------------------------------------------------------------------------- recognition
@dataclass(frozen=True)
class Pair:
    """A kinematic pair of a leg: ``letter`` R, P, U or S, its joints (base to platform), its centre (mm; R and
    P: a point of the first axis) and its axes.

    Attributes
    ----------
    letter : str
        ``"R"``, ``"P"``, ``"U"`` or ``"S"``.
    joints : tuple of FileJoint
        Its joints, base side first.
    point : numpy.ndarray
        Its centre (U, S) or a point of its axis (R, P), mm (3,).
    """

    letter: str
    joints: tuple[FileJoint, ...]
    point: np.ndarray

    @property
    def actuated(self) -> bool:
        return any(j.actuated for j in self.joints)


def _tol(*points) -> float:
    """Distance (mm) below which points count as one: 1e-6 of the coordinates (numbers typed with 7 digits)."""
    return 1e-6 * max(1.0, max(float(np.max(np.abs(p))) for p in points))


def _line_point(a0, u, b0, v):
    """The points of lines ``a0 + s u`` and ``b0 + t v`` closest to each other (None when parallel)."""
    w = a0 - b0
    b = float(u @ v)
    denom = 1.0 - b * b
    if denom < 1e-12:
        return None
    s = (b * (v @ w) - (u @ w)) / denom
    t = ((v @ w) - b * (u @ w)) / denom
    return a0 + s * u, b0 + t * v


def pairs_of(joints: list[FileJoint]) -> list[Pair]:
    """Consecutive rotations through one point merged: one hinge ``R``, two ``U``, three or a ball ``S``."""
    out: list[Pair] = []
    group: list[FileJoint] = []
    point = None

    def flush():
        nonlocal group, point
        if group:
            hinges = [j for j in group if j.kind == "hinge"]
            letter = "S" if any(j.kind == "ball" for j in group) or len(hinges) >= 3 else "RU"[len(hinges) - 1]
            out.append(Pair(letter, tuple(group), group[0].anchor if point is None else point))
        group, point = [], None

    for j in joints:
        if j.kind == "slide":
            flush()
            out.append(Pair("P", (j,), j.anchor))
            continue
        if not group:
            group, point = [j], (j.anchor if j.kind == "ball" else None)
            continue
        if point is None:                      # one hinge so far: a line
            h = group[0]
            if j.kind == "ball":
                off = j.anchor - h.anchor
                ok = np.linalg.norm(off - (off @ h.axis) * h.axis) <= _tol(j.anchor, h.anchor)
                cand = j.anchor
            else:
                near = _line_point(h.anchor, h.axis, j.anchor, j.axis)
                ok = near is not None and np.linalg.norm(near[0] - near[1]) <= _tol(h.anchor, j.anchor)
                cand = None if near is None else 0.5 * (near[0] + near[1])
        else:
            if j.kind == "ball":
                ok = np.linalg.norm(j.anchor - point) <= _tol(point)
            else:
                off = point - j.anchor
                ok = np.linalg.norm(off - (off @ j.axis) * j.axis) <= _tol(point, j.anchor)
            cand = point
        if ok:
            group.append(j)
            point = cand
        else:
            flush()
            group, point = [j], (j.anchor if j.kind == "ball" else None)
    flush()
    return out


def _legs(graph: KinematicGraph) -> tuple[int, list[list[list[FileJoint]]]]:
    """The platform group and, per leg, its paths from the base to the platform (lists of joints in order)."""
    n = len(graph.names)
    adj: dict[int, list[tuple[int, int]]] = {i: [] for i in range(n)}
    for k, edge in enumerate(graph.edges):
        a, b = edge[0].parent, edge[0].child
        adj[a].append((b, k))
        adj[b].append((a, k))

    def components(platform):
        seen, comps = {0, platform}, []
        for start in range(n):
            if start in seen or not adj[start]:
                continue
            comp, stack = {start}, [start]
            seen.add(start)
            while stack:
                u = stack.pop()
                for v, _ in adj[u]:
                    if v not in seen:
                        seen.add(v)
                        comp.add(v)
                        stack.append(v)
            touches = {v for u in comp for v, _ in adj[u]}
            if 0 in touches and platform in touches:
                comps.append(comp)
        return comps

    best = max(range(1, n), key=lambda g: (len(components(g)), g in graph.free, -g), default=None)
    if best is None or len(components(best)) < 3:
        raise _error(graph.source, None, "no platform found: a parallel robot needs a body that at least three legs "
                                         "from the base reach (closing loops with <equality><connect> in MJCF, "
                                         "<loop> in URDF)")
    platform = best
    dangling = _dangling(graph, adj, platform)
    if dangling is not None:
        raise _error(graph.source, dangling.name, f"a chain from the base ends at '{graph.names[dangling.child]}' "
                                                  f"without closing a loop to the platform '{graph.names[platform]}' "
                                                  "(a connect constraint or a loop element is missing)")
    legs = []
    for comp in sorted(components(platform), key=min):
        paths = []

        def walk(u, path, used):
            for v, k in adj[u]:
                if k in used:
                    continue
                edge = graph.edges[k]
                # against the file's tree a joint moves the parent side: the same value about the opposite axis
                joints = edge if edge[0].parent == u else [dataclasses.replace(j, axis=-j.axis, flipped=True)
                                                           for j in reversed(edge)]
                if v == platform:
                    paths.append(path + joints)
                elif v in comp:
                    walk(v, path + joints, used | {k})
        walk(0, [], frozenset())
        legs.append(paths)
    return platform, legs


def _dangling(graph, adj, platform):
    """A joint of a chain hanging from the base that never reaches the platform, or None."""
    seen = {0, platform}
    for start in range(len(graph.names)):
        if start in seen:
            continue
        comp, stack = {start}, [start]
        seen.add(start)
        while stack:
            u = stack.pop()
            for v, _ in adj[u]:
                if v not in seen:
                    seen.add(v)
                    comp.add(v)
                    stack.append(v)
        touches = {v for u in comp for v, _ in adj[u]}
        if 0 in touches and platform not in touches:
            edges = [graph.edges[k] for u in comp for _, k in adj[u]]
            return max((e[-1] for e in edges), key=lambda j: j.child)
    return None


def _unit(v):
    return v / np.linalg.norm(v)


def _signed_angle(n, u, axis) -> float:
    return float(np.arctan2(np.cross(n, u) @ axis, n @ u))


def _rotate(v, axis, angle):
    axis = _unit(axis)
    return v * math.cos(angle) + np.cross(axis, v) * math.sin(angle) + axis * (axis @ v) * (1 - math.cos(angle))


class _LegReader:
    """Builds one leg of our model from its pairs (messages name the file and the element)."""

    def __init__(self, graph: KinematicGraph, platform: int, index: int, extras: dict) -> None:
        self.g = graph
        self.p, self.R = graph.frames[platform]
        self.i = index
        self.extras = extras

    def fail(self, element, message) -> ConfigError:
        return _error(self.g.source, element, f"leg {self.i}: {message}")

    def local(self, X):
        return tuple(float(v) for v in self.R.T @ (X - self.p))

    def need_range(self, joint: FileJoint):
        if joint.range is None:
            raise self.fail(joint.name, "the actuated joint needs a range (limits) to give the leg's stroke")
        return joint.range

    def along(self, slide: FileJoint, A, B):
        d = B - A
        L = float(np.linalg.norm(d))
        if L <= _tol(A, B) or np.linalg.norm(np.cross(slide.axis, d / L)) > 1e-4:
            raise self.fail(slide.name, "the slide's axis is not along the leg (from its base joint to its platform "
                                        "joint)")
        sign = 1.0 if slide.axis @ d > 0 else -1.0
        lo, hi = self.need_range(slide)
        stroke = sorted((L + sign * (lo - slide.ref), L + sign * (hi - slide.ref)))
        return L, tuple(stroke)

    def normal(self, axis, u_ref):
        n = np.asarray(self.extras.get("base_normal", (0.0, 0.0, 1.0)), dtype=float)
        n = _unit(n)
        return n if abs(n @ axis) <= 1e-6 else _unit(u_ref - (u_ref @ axis) * axis)

    def angle_range(self, hinge: FileJoint, n, u_ref):
        if hinge.range is None:
            return None
        alpha = _signed_angle(n, u_ref, hinge.axis)
        return tuple(alpha + v - hinge.ref for v in hinge.range)

    def ups(self, pairs):
        U, P, S = pairs
        A, B = U.point, S.point
        L, stroke = self.along(P.joints[0], A, B)
        base_axis = tuple(float(v) for v in U.joints[0].axis) if U.letter == "U" else None
        return UPSLeg(base=tuple(map(float, A)), platform=self.local(B), length_range=stroke, base_axis=base_axis,
                      **self.common())

    def upu(self, pairs):
        U1, P, U2 = pairs
        A, B = U1.point, U2.point
        L, stroke = self.along(P.joints[0], A, B)
        u4 = self.R.T @ U2.joints[-1].axis
        return UPULeg(base=tuple(map(float, A)), platform=self.local(B), length_range=stroke,
                      base_axis=tuple(map(float, U1.joints[0].axis)), platform_axis=tuple(map(float, u4)),
                      **self.common())

    def rps(self, pairs):
        Rp, P, S = pairs
        h, slide, B = Rp.joints[0], P.joints[0], S.point
        near = _line_point(h.anchor, h.axis, B, slide.axis)
        if near is None or np.linalg.norm(near[0] - near[1]) > _tol(B, h.anchor):
            raise self.fail(slide.name, "the leg's line does not meet the revolute axis")
        A = near[0]
        L, stroke = self.along(slide, A, B)
        u = _unit(B - A)
        n = self.normal(h.axis, u)
        return RPSLeg(base=tuple(map(float, A)), platform=self.local(B), length_range=stroke,
                      axis=tuple(map(float, h.axis)), angle_range=self.angle_range(h, n, u),
                      **self.common(base_normal=n))

    def prs(self, pairs, home):
        P, Rp, S = pairs
        slide, h, B = P.joints[0], Rp.joints[0], S.point
        if abs(slide.axis @ h.axis) > 1e-6:
            raise self.fail(h.name, "the revolute axis must be perpendicular to the slide")
        C = h.anchor
        rod = float(np.linalg.norm(B - C))
        u = _unit(B - C)
        n = self.normal(h.axis, u)
        base = C - slide.ref * slide.axis
        common = self.common(base_normal=n)
        kw = dict(base=tuple(map(float, base)), platform=self.local(B), slide=tuple(map(float, slide.axis)),
                  slide_range=tuple(self.need_range(slide)), axis=tuple(map(float, h.axis)), rod=rod,
                  angle_range=self.angle_range(h, n, u), **common)
        return self.with_mode(PRSLeg, kw, home, slide.ref, slide.name)

    def delta(self, arm: Pair, rods: list[list[Pair]], home):
        h = arm.joints[0]
        if len(rods) != 2 or any(len(r) != 2 or any(p.letter not in "SU" for p in r) for r in rods):
            raise self.fail(h.name, "a Delta leg's arm carries two rods, each with a ball (or a universal joint) "
                                    "at both ends")
        (C1, B1), (C2, B2) = [(r[0].point, r[1].point) for r in rods]
        a = h.axis
        rod = 0.5 * float(np.linalg.norm(B1 - C1) + np.linalg.norm(B2 - C2))
        spacing = float(np.linalg.norm(C1 - C2))
        tol = 100 * _tol(B1, C1)     # 1e-4 of the size: files typed to 10 um are parallelograms, the model averages
        if abs(np.linalg.norm(B2 - C2) - rod) > tol or np.linalg.norm(np.cross(C1 - C2, a)) > tol \
                or np.linalg.norm((B1 - B2) - (C1 - C2)) > tol:
            raise self.fail(rods[1][0].joints[0].name, "the two rods must be equal and parallel, their elbow balls "
                                                        "on a line along the arm's axis (a parallelogram)")
        C, B = 0.5 * (C1 + C2), 0.5 * (B1 + B2)
        A = h.anchor + ((C - h.anchor) @ a) * a
        arm_len = float(np.linalg.norm(C - A))
        zero = _rotate(_unit(C - A), a, -h.ref)
        kw = dict(base=tuple(map(float, A)), platform=self.local(B), axis=tuple(map(float, a)),
                  zero=tuple(map(float, zero)), arm=arm_len, rod=rod, spacing=spacing,
                  angle_range=tuple(self.need_range(h)), **self.common(delta=True))
        return self.with_mode(DeltaLeg, kw, home, h.ref, h.name, angle=True)

    def with_mode(self, kind, kw, home, ref, element, angle=False):
        p, R = home
        best = None
        for mode in (1, -1):
            leg = kind(mode=mode, **kw)
            q = float(leg.actuate(p, R))
            diff = abs((q - ref + math.pi) % (2 * math.pi) - math.pi if angle else q - ref)
            if np.isfinite(q) and diff <= 1e-4 * max(1.0, abs(ref)) and (best is None or diff < best[0]):
                best = (diff, leg)
        if best is not None:
            return best[1]
        raise self.fail(element, "the reference configuration is not an assembly of this leg (no branch of its "
                                 "inverse kinematics gives the joint's reference value)")

    def common(self, base_normal=None, delta=False) -> dict[str, Any]:
        e = self.extras
        out: dict[str, Any] = {}
        if base_normal is not None:
            out["base_normal"] = tuple(float(v) for v in base_normal)
        elif "base_normal" in e and not delta:
            out["base_normal"] = tuple(float(v) for v in e["base_normal"])
        out["platform_normal"] = tuple(float(v) for v in e.get(
            "platform_normal", DeltaLeg.DEFAULT_PLATFORM_NORMAL if delta else UPSLeg.DEFAULT_PLATFORM_NORMAL))
        if "base_cone_deg" in e and not delta:
            out["base_cone"] = math.radians(e["base_cone_deg"])
        if "platform_cone_deg" in e:
            out["platform_cone"] = math.radians(e["platform_cone_deg"])
        for key in ("radius", "arm_radius", "rod_radius"):
            if key in e and (key == "radius") != delta:
                out[key] = float(e[key])
        return out


def _plane(graph: KinematicGraph, platform: int, legs) -> np.ndarray | None:
    """The rotation to plane coordinates (rows ``x', y', n``) when every hinge turns about one direction ``n``,
    every slide is normal to it and the platform turns about it only; else None.

    ``n`` is the base's z-axis when the hinges are vertical; otherwise ``x'`` is the base's x-axis (or y-axis)
    projected on the plane and ``n`` is signed so that ``y' = n x x'`` points up (a robot drawn in the
    base's x-z plane has plane coordinates ``(x, z)``).
    """
    joints = [j for paths in legs for path in paths for j in path]
    hinges = [j.axis for j in joints if j.kind == "hinge"]
    if len(legs) != 3 or any(len(paths) != 1 for paths in legs) or not hinges:
        return None
    n = _unit(hinges[0])
    if any(np.linalg.norm(np.cross(a, n)) > 1e-9 for a in hinges) or \
            any(j.kind == "slide" and abs(j.axis @ n) > 1e-9 for j in joints):
        return None
    R = graph.frames[platform][1]
    if np.linalg.norm(R @ n - n) > 1e-9:
        return None
    if abs(abs(n[2]) - 1) <= 1e-9:
        return np.eye(3)
    x = np.array([1.0, 0.0, 0.0]) - n[0] * n
    if np.linalg.norm(x) < 1e-6:
        x = np.array([0.0, 1.0, 0.0]) - n[1] * n
    x = _unit(x)
    if np.cross(n, x)[2] < 0:
        n = -n
    return np.vstack([x, np.cross(n, x), n])


def _to_plane(graph: KinematicGraph, Rn: np.ndarray) -> KinematicGraph:
    """The graph in plane coordinates (every anchor, axis and frame turned by ``Rn``)."""
    if np.allclose(Rn, np.eye(3)):
        return graph
    edges = [[dataclasses.replace(j, anchor=Rn @ j.anchor, axis=Rn @ j.axis) for j in edge] for edge in graph.edges]
    frames = [(Rn @ p, Rn @ R @ Rn.T) for p, R in graph.frames]
    return dataclasses.replace(graph, edges=edges, frames=frames)


def planar_from_graph(graph: KinematicGraph, platform: int, legs) -> Manipulator:
    """A planar robot (three :class:`~pmaccuracy.model.legs.ChainLeg` legs, ``architecture = "chain"``) of a
    graph whose joints all move in the base's xy-plane; the reference configuration is a pose ``(x, y, phi)``.

    Each leg's chain (module :mod:`pmaccuracy.model.chain`) is built from the joints' centres ``c_k`` and
    directions ``d_k`` at their reference values ``q_k``: zero offsets for R joints (``q`` is the file's angle,
    turned to the +z sense), a P joint's offset the angle of its direction, ``link_k`` the vector to the next
    centre in the frame after the joint; a loop closure is a revolute (value 0 at the reference), the end frame
    the last joint's frame. The working mode is the branch whose inverse kinematics gives the reference values.
    """
    src = graph.source
    p, R = graph.frames[platform]
    phi = math.atan2(R[1, 0], R[0, 0])
    pose = np.array([p[0], p[1], phi])
    built = []
    for i, paths in enumerate(legs, start=1):
        path = paths[0]
        if len(path) != 3:
            raise _error(src, path[0].name, f"leg {i} of a planar robot has {len(path)} joints "
                                            f"({', '.join(j.name for j in path)}); a planar leg has three")
        if graph.any_actuator and sum(j.actuated for j in path) != 1:
            raise _error(src, path[0].name, f"leg {i}: a planar leg needs exactly one actuated joint, found "
                                            f"{sum(j.actuated for j in path)}")
        act = [j.actuated for j in path] if graph.any_actuator else None
        if act is None:
            raise _error(src, path[0].name, "a planar robot file must name its actuated joints")
        angle = 0.0
        joints, centres, qs = [], [], []
        for j in path:
            if j.kind == "slide":
                d = complex(j.axis[0], j.axis[1])
                d /= abs(d)
                centres.append(complex(j.anchor[0], j.anchor[1]) - j.ref * d)
                qs.append(("P", d, j.ref, j.range))
            else:
                sign = 1.0 if j.kind == "ball" or j.axis[2] > 0 else -1.0
                rng = None if j.range is None else tuple(sorted(sign * v for v in j.range))
                centres.append(complex(j.anchor[0], j.anchor[1]))
                qs.append(("R", None, sign * j.ref, rng))
        base = centres[0]
        for k, (kind, d, q, rng) in enumerate(qs):
            if kind == "R":
                offset = 0.0
                angle = angle + q
                origin = centres[k]
            else:
                offset = math.atan2(d.imag, d.real) - angle
                angle = angle + offset
                origin = centres[k] + q * d
            nxt = centres[k + 1] if k < 2 else origin
            link = (nxt - origin) * complex(math.cos(-angle), math.sin(-angle))
            joints.append(ChainJoint(kind, actuated=act[k], offset=offset, link=(link.real, link.imag),
                                     range=(-math.inf, math.inf) if rng is None else rng))
        end = centres[2] if qs[2][0] == "R" else centres[2] + qs[2][2] * qs[2][1]
        local = R[:2, :2].T @ (np.array([end.real, end.imag]) - p[:2])
        chosen, closest = None, math.inf
        for mode in (1, -1):
            try:
                chain = Chain(joints=tuple(joints), base=(base.real, base.imag), base_angle=0.0,
                              platform=(float(local[0]), float(local[1])), platform_angle=angle - phi,
                              working_mode=mode)
            except GeometryError as exc:
                raise _error(src, path[0].name, f"leg {i}: {exc.message}") from None
            q = chain.state(pose).q
            ref = np.array([v[2] for v in qs])
            diff = np.array([(a - b + math.pi) % (2 * math.pi) - math.pi if kind[0] == "R" else a - b
                             for a, b, kind in zip(q, ref, qs)])
            if np.all(np.isfinite(q)) and np.max(np.abs(diff)) <= 1e-4 and np.max(np.abs(diff)) < closest:
                chosen, closest = chain, float(np.max(np.abs(diff)))
        if chosen is None:
            raise _error(src, path[0].name, f"leg {i}: the reference configuration is not an assembly of the leg")
        built.append(ChainLeg(spec=chosen))
    extras = graph.extras
    name = extras.get("name") if isinstance(extras.get("name"), str) else Path(src).stem
    try:
        return Manipulator(legs=tuple(built), name=name, description=str(extras.get("description", "")))
    except GeometryError as exc:
        raise GeometryError(exc.message, source=src, key=exc.key) from None


def robot_from_graph(graph: KinematicGraph):
    """The robot of a kinematic graph: a planar one when every joint moves in one plane (:func:`_plane`: the
    base's xy-plane, or the x-z plane of a robot drawn upright; :func:`planar_from_graph`), else spatial legs
    recognised by their pairs' pattern (:data:`PATTERNS`).

    Raises :class:`ConfigError` naming the file and the joint or loop that cannot be mapped, and why.
    """
    src = graph.source
    platform, legs = _legs(graph)
    Rn = _plane(graph, platform, legs)
    if Rn is not None:
        graph = _to_plane(graph, Rn)
        platform, legs = _legs(graph)
        return planar_from_graph(graph, platform, legs)
    p, R = graph.frames[platform]
    home_rotvec = rotvecs(R[None])[0]
    home = (p, rotations(home_rotvec[None])[0])
    extras = graph.extras
    leg_extras = extras.get("legs") if isinstance(extras.get("legs"), list) else []
    patterns, built = [], []
    for i, paths in enumerate(legs, start=1):
        extra = leg_extras[i - 1] if i - 1 < len(leg_extras) and isinstance(leg_extras[i - 1], dict) else {}
        reader = _LegReader(graph, platform, i, extra)
        if len(paths) == 1:
            pairs = pairs_of(paths[0])
            pattern = "".join(pr.letter for pr in pairs)
        elif len(paths) == 2:
            first = [pairs_of(path) for path in paths]
            heads = [pp[0] for pp in first]
            if not ([j.name for j in heads[0].joints] == [j.name for j in heads[1].joints]
                    and heads[0].letter == "R"):
                raise _error(src, paths[0][0].name, f"leg {i}: two branches that do not start at one actuated "
                                                    "revolute (a Delta arm)")
            # the arm's hinge is shared; the rest of each branch are the rods
            rods = [pairs_of(path[len(heads[0].joints):]) for path in paths]
            pattern = "R(SS)2"
        else:
            raise _error(src, paths[0][0].name if paths and paths[0] else None,
                         f"leg {i} has {len(paths)} branches from the base to the platform: not a leg of a known "
                         "architecture")
        if pattern not in PATTERNS:
            joints = ", ".join(j.name for path in paths for j in path)
            raise _error(src, paths[0][0].name, f"leg {i}: joints {pattern} ({joints}) are not a leg of a known "
                                                f"architecture ({', '.join(PATTERNS)})")
        actuated_pair = heads[0] if pattern == "R(SS)2" else pairs[ACTUATED_PAIR[pattern]]
        moving = [j for path in paths for j in path if j.actuated]
        if graph.any_actuator:
            names = ", ".join(j.name for j in actuated_pair.joints)
            if not actuated_pair.actuated:
                raise _error(src, actuated_pair.joints[0].name,
                             f"a {PATTERNS[pattern]} leg needs its actuated joint ({names}); leg {i} has "
                             f"{'none' if not moving else moving[0].name + ' instead'}")
            own = {j.name for j in actuated_pair.joints}
            extra_act = [j.name for j in moving if j.name not in own]
            if extra_act:
                raise _error(src, extra_act[0], f"leg {i}: only one joint per leg can be actuated ({names})")
        patterns.append(pattern)
        if pattern in ("UPS", "SPS"):
            built.append(reader.ups(pairs))
        elif pattern == "UPU":
            built.append(reader.upu(pairs))
        elif pattern == "RPS":
            built.append(reader.rps(pairs))
        elif pattern == "PRS":
            built.append(reader.prs(pairs, home))
        else:
            built.append(reader.delta(heads[0], rods, home))
    archs = {PATTERNS[pt] for pt in patterns}
    if len(archs) != 1:
        raise _error(src, None, f"the legs are of different kinds ({', '.join(patterns)}): one architecture only")
    name = extras.get("name") if isinstance(extras.get("name"), str) else Path(src).stem
    try:
        return SpatialManipulator(architecture=archs.pop(), legs=tuple(built), name=name,
                                  description=str(extras.get("description", "")),
                                  home=tuple(float(v) for v in np.concatenate([p, home_rotvec])))
    except GeometryError as exc:
        raise GeometryError(exc.message, source=src, key=exc.key) from None


def read_robot_file(path: str | os.PathLike):
    """The robot (spatial, or planar when every joint moves in one plane) of an MJCF (``.xml``, ``.mjcf``) or
    URDF (``.urdf``) file (:func:`read_mjcf`,
    :func:`read_urdf`, :func:`robot_from_graph`); lengths mm, angles rad.

    Raises :class:`ConfigError` (one line: the file, the element, the problem) for a file that is missing, not
    XML, refused by its parser, or whose loops or joints make no leg of a known architecture.
    """
    source = os.fspath(path)
    fmt = SUFFIXES.get(Path(source).suffix.lower())
    if Path(source).suffix.lower() == ".sdf":
        raise ConfigError("SDF files are not read: no maintained SDF reader is on PyPI (Gazebo's sdformat bindings come "
                          "with Gazebo); convert the model to MJCF or "
                          "URDF (with its loops as connect constraints or URDF+ <loop> elements)", source=source)
    if fmt is None:
        raise ConfigError(f"unknown robot file type (expected one of {', '.join(SUFFIXES)})", source=source)
    if not Path(source).is_file():
        raise ConfigError("no such file", source=source)
    graph = read_mjcf(source) if fmt == "mjcf" else read_urdf(source)
    return robot_from_graph(graph)


# ---------------------------------------------------------------------------------------------- writing
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


# ---------------------------------------------------------------------------------------------- calibrated export
def _frame(first, second) -> np.ndarray:
    """Orthonormal columns ``[e1, e2, e1 x e2]``: ``e1`` along ``first``, ``e2`` the part of ``second`` normal to it."""
    e1 = _unit(np.asarray(first, dtype=float))
    v = np.asarray(second, dtype=float) - (np.asarray(second) @ e1) * e1
    if np.linalg.norm(v) < 1e-12:
        v = np.cross(e1, [1.0, 0.0, 0.0]) if abs(e1[0]) < 0.9 else np.cross(e1, [0.0, 1.0, 0.0])
    e2 = _unit(v)
    return np.column_stack([e1, e2, np.cross(e1, e2)])


@dataclass
class _Target:
    """Where a joint of the file goes: its new anchor and axis (base frame, mm), reference value and range."""

    anchor: np.ndarray
    axis: np.ndarray | None = None
    ref: float | None = None
    range: tuple[float, float] | None = None


def _retarget(paths, old, new, old_home, new_home, normal) -> tuple[np.ndarray, dict, list]:
    """The rotation ``Q`` carrying the leg's bodies, the joints' targets by ``ident`` and the key points
    ``[(old, new)]`` of the leg (pair centres) for placing its bodies."""
    p1, R1 = new_home
    q1 = float(new.actuate(p1, R1))
    if not np.isfinite(q1):
        raise GeometryError("the calibrated leg does not reach the home pose", key="home")
    targets: dict = {}
    keys: list = []
    if isinstance(old, DeltaLeg):
        heads = pairs_of(paths[0])
        h = heads[0].joints[0]
        a0, a1 = np.asarray(old.axis), np.asarray(new.axis)
        p0, R0 = old_home
        q0 = float(old.actuate(p0, R0))
        C0, C1 = old.elbow(q0), new.elbow(q1)
        Q = _frame(a1, C1 - np.asarray(new.base)) @ _frame(a0, C0 - np.asarray(old.base)).T
        A0, A1 = np.asarray(old.base), np.asarray(new.base)
        targets[h.ident] = _Target(A1 + ((h.anchor - A0) @ a0) * a1, a1, q1, new.angle_range)
        keys.append((h.anchor, targets[h.ident].anchor))
        B0 = old.platform_point(p0, R0)
        B1 = new.platform_point(p1, R1)
        for path in paths:
            rods = pairs_of(path[len(heads[0].joints):])
            sign = 1.0 if (rods[0].point - C0) @ a0 > 0 else -1.0
            Cn = C1 + sign * 0.5 * new.spacing * a1
            Bn = B1 + sign * 0.5 * new.spacing * (R1 @ a1)
            for pair, new_point in zip(rods, (Cn, Bn)):
                for j in pair.joints:
                    targets[j.ident] = _Target(new_point + Q @ (j.anchor - pair.point), None if j.kind == "ball"
                                               else Q @ j.axis)
                keys.append((pair.point, new_point))
        del B0
        return Q, targets, keys
    pairs = pairs_of(paths[0])
    p0, R0 = old_home
    B0, B1 = old.platform_point(p0, R0), new.platform_point(p1, R1)
    if isinstance(old, PRSLeg):
        P, Rp, S = pairs
        s0, s1 = np.asarray(old.slide), np.asarray(new.slide)
        a0, a1 = np.asarray(old.axis), np.asarray(new.axis)
        Q = _frame(a1, s1) @ _frame(a0, s0).T
        C0 = Rp.joints[0].anchor
        C1 = new.carriage(q1)
        slide = P.joints[0]
        targets[slide.ident] = _Target(C1 + Q @ (slide.anchor - C0), s1, q1, new.slide_range)
        h = Rp.joints[0]
        u1 = _unit(B1 - C1)
        n = normal(a1, u1)
        rng = None if new.angle_range is None or h.range is None else \
            tuple(v - _signed_angle(n, u1, a1) + h.ref for v in new.angle_range)
        targets[h.ident] = _Target(C1, a1, None, rng)
        keys += [(C0, C1)]
    else:
        first, P, last = pairs
        A0, A1 = first.point, np.asarray(new.base)
        d0, d1 = B0 - A0, B1 - A1
        if first.letter == "U" and getattr(new, "base_axis", None) is not None:
            Q = _frame(new.base_axis, d1) @ _frame(first.joints[0].axis, d0).T
        elif first.letter == "R":
            Q = _frame(new.axis, d1) @ _frame(first.joints[0].axis, d0).T
        else:
            Q = _frame(d1, [0.0, 0.0, 1.0]) @ _frame(d0, [0.0, 0.0, 1.0]).T
        for j in first.joints:
            targets[j.ident] = _Target(A1 + Q @ (j.anchor - A0), None if j.kind == "ball" else Q @ j.axis)
        if first.letter == "R":
            h = first.joints[0]
            a1 = np.asarray(new.axis)
            targets[h.ident].axis = a1
            u1 = _unit(d1)
            n = normal(a1, u1)
            if new.angle_range is not None and h.range is not None:
                targets[h.ident].range = tuple(v - _signed_angle(n, u1, a1) + h.ref for v in new.angle_range)
        elif first.letter == "U" and getattr(new, "base_axis", None) is not None:
            targets[first.joints[0].ident].axis = np.asarray(new.base_axis)
        slide = P.joints[0]
        L1 = float(np.linalg.norm(d1))
        sign = 1.0 if slide.axis @ d0 > 0 else -1.0
        rng = tuple(sorted(slide.ref + sign * (v - L1) for v in new.stroke))
        targets[slide.ident] = _Target(B1 + Q @ (slide.anchor - B0), sign * _unit(d1), None, rng)
        keys += [(A0, A1)]
        if isinstance(new, UPULeg):
            targets[last.joints[-1].ident] = _Target(B1 + Q @ (last.joints[-1].anchor - B0),
                                                     R1 @ np.asarray(new.platform_axis))
    S = pairs[-1]
    for j in S.joints:
        if j.ident not in targets:
            targets[j.ident] = _Target(B1 + Q @ (j.anchor - S.point), None if j.kind == "ball" else Q @ j.axis)
    keys.append((S.point, B1))
    return Q, targets, keys


def _angle_unit(root: ET.Element) -> float:
    """Radians per unit of the file's angles: MJCF's ``<compiler angle>`` (degree unless said otherwise)."""
    unit = "degree"
    for comp in root.iter("compiler"):
        unit = comp.get("angle", unit)
    return math.pi / 180.0 if unit == "degree" else 1.0


def export_into(robot: SpatialManipulator, original: str | os.PathLike, out: str | os.PathLike) -> Path:
    """Write ``robot`` (e.g. a calibrated copy of the one imported from ``original``) into a copy of the MJCF or
    URDF file ``original`` at ``out``, changing only the geometry (URDF: joint origins and axes, limits, loop
    origins, and the reference values of a Delta's or 3-PRS's actuated joints in the ``<pmaccuracy>`` JSON).

    Each leg's bodies turn by one rotation ``Q`` (the old leg frame onto the new) about their leg's joint centres,
    which move to the robot's: body ``pos``/orientation, joint ``pos``/``axis``, the ``ref`` values of the actuated
    joints (the reference configuration becomes the robot's home pose), the actuated and passive ranges that our
    model holds, the platform body's pose and the ``connect`` anchors. Everything else (geoms, inertias, actuators,
    options, defaults) is kept. Angles follow the file's ``<compiler angle>``. Raises :class:`ConfigError` when the
    robot is not of the file's architecture and leg count or the file's bodies cannot be matched to its elements.
    """
    source = os.fspath(original)
    fmt = SUFFIXES.get(Path(source).suffix.lower())
    if fmt == "urdf":
        return _export_urdf_into(robot, source, out)
    if fmt != "mjcf":
        raise ConfigError(f"unknown robot file type (expected one of {', '.join(SUFFIXES)})", source=source)
    mujoco = _optional.require("mujoco", "writing into an MJCF file")
    graph = read_mjcf(source)
    old = robot_from_graph(graph)
    if not isinstance(old, SpatialManipulator) or not isinstance(robot, SpatialManipulator):
        raise ConfigError("writing into an existing file is done for spatial robots so far (write a planar robot "
                          "as a fresh file)", source=source)
    if old.architecture != robot.architecture or old.n_legs != robot.n_legs:
        raise ConfigError(f"the file holds a {old.architecture} with {old.n_legs} legs, the robot is a "
                          f"{robot.architecture} with {robot.n_legs}", source=source)
    platform, legs = _legs(graph)
    old_home = _home(old)
    new_home = _home(robot)
    m = mujoco.MjModel.from_xml_path(source)
    d = mujoco.MjData(m)
    d.qpos[:] = m.qpos0
    mujoco.mj_kinematics(m, d)
    tree = ET.parse(source)
    root = tree.getroot()
    bodies = [None] + list(root.find("worldbody").iter("body"))
    if len(bodies) != m.nbody:
        raise ConfigError(f"MuJoCo made {m.nbody - 1} bodies of the file's {len(bodies) - 1} <body> elements "
                          "(includes, frames or fused bodies): cannot match them", source=source)
    joint_el = {}
    for b, el in enumerate(bodies[1:], start=1):
        own = [c for c in el if c.tag in ("joint", "freejoint")]
        if len(own) != m.body_jntnum[b]:
            raise ConfigError(f"body {b}: cannot match its joints to MuJoCo's", source=source)
        for k, c in enumerate(own):
            joint_el[int(m.body_jntadr[b]) + k] = c
    eq_el = [c for eq in root.iter("equality") for c in eq]
    base_body = _base_body(m, _Groups(m.nbody))
    p0, Rb = d.xpos[base_body] * _M, d.xmat[base_body].reshape(3, 3)

    def world(x):                      # base frame (mm) -> world (m)
        return (p0 + Rb @ x) / _M

    targets: dict = {}
    flipped = {j.ident for paths in legs for path in paths for j in path if j.flipped}
    body_rot: dict[int, np.ndarray] = {}
    body_key: dict[int, tuple] = {}
    for i, (paths, lo, ln) in enumerate(zip(legs, old.legs, robot.legs), start=1):
        reader = _LegReader(graph, platform, i, graph.extras.get("legs", [{}] * old.n_legs)[i - 1]
                            if isinstance(graph.extras.get("legs"), list) else {})
        try:
            Q, tg, keys = _retarget(paths, lo, ln, old_home, new_home, reader.normal)
        except GeometryError as exc:
            raise GeometryError(exc.message, source=robot.name, key=f"legs[{i}]") from None
        targets.update(tg)
        for path in paths:
            for j in path:
                if j.ident[0] != "joint":
                    continue
                b = int(m.jnt_bodyid[j.ident[1]])
                body_rot[b] = Q
                # the key point of a body: its own joint's new anchor if a rotation, else the nearest pair centre
                if j.kind != "slide" and b not in body_key:
                    body_key[b] = (j.anchor, tg[j.ident].anchor)
        for path in paths:
            for j in path:
                if j.ident[0] == "joint":
                    b = int(m.jnt_bodyid[j.ident[1]])
                    if b not in body_key:
                        old_x = d.xpos[b] * _M
                        old_x = Rb.T @ (old_x - p0)
                        near = min(keys, key=lambda kv: np.linalg.norm(kv[0] - old_x))
                        body_key[b] = near
    # new world poses (base frame, mm) of the bodies that move
    new_pose: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for b in range(1, m.nbody):
        x = Rb.T @ (d.xpos[b] * _M - p0)
        R = Rb.T @ d.xmat[b].reshape(3, 3)
        if b in body_rot:
            Q = body_rot[b]
            k_old, k_new = body_key[b]
            new_pose[b] = (k_new + Q @ (x - k_old), Q @ R)
    pf, Rf = graph.frames[platform]
    frame_body = next(b for b in range(1, m.nbody) if np.allclose(Rb.T @ (d.xpos[b] * _M - p0), pf, atol=1e-9)
                      and np.allclose(Rb.T @ d.xmat[b].reshape(3, 3), Rf, atol=1e-12)
                      and graph.names[platform] == (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b)
                                                    or f"body #{b}"))
    new_pose[frame_body] = new_home
    # every body's new world pose: moved ones as set, the others rigid with their parent
    final: dict[int, tuple[np.ndarray, np.ndarray]] = {0: (Rb.T @ (-p0), Rb.T)}
    for b in range(1, m.nbody):
        parent = int(m.body_parentid[b])
        xp, Rp = final[parent]
        if b in new_pose:
            final[b] = new_pose[b]
        else:
            lq = m.body_quat[b]
            Rl = np.zeros(9)
            mujoco.mju_quat2Mat(Rl, lq)
            final[b] = (xp + Rp @ (m.body_pos[b] * _M), Rp @ Rl.reshape(3, 3))
        if b in new_pose:
            x, R = final[b]
            pos = Rp.T @ (x - xp) / _M
            Rl = Rp.T @ R
            el = bodies[b]
            el.set("pos", _f(pos))
            Rold = np.zeros(9)
            mujoco.mju_quat2Mat(Rold, m.body_quat[b])
            if np.max(np.abs(Rold.reshape(3, 3) - Rl)) > 1e-13:
                for attr in ("quat", "euler", "axisangle", "xyaxes", "zaxis"):
                    el.attrib.pop(attr, None)
                el.set("quat", _f(_quat(Rl)))
    unit = _angle_unit(root)
    for ident, t in targets.items():
        kind, idx = ident
        if kind == "joint":
            b = int(m.jnt_bodyid[idx])
            x, R = final[b]
            el = joint_el[idx]
            el.set("pos", _f(R.T @ (t.anchor - x) / _M))
            if t.axis is not None:
                el.set("axis", _f(R.T @ (-t.axis if ident in flipped else t.axis)))
            scale = _M if int(m.jnt_type[idx]) == int(mujoco.mjtJoint.mjJNT_SLIDE) else unit
            if t.ref is not None:
                el.set("ref", repr(t.ref / scale))
            if t.range is not None:
                el.set("range", _f(np.asarray(t.range) / scale))
    for e in range(m.neq):
        if int(m.eq_type[e]) != int(mujoco.mjtEq.mjEQ_CONNECT) or not m.eq_active0[e]:
            continue
        t = targets.get(("equality", e))
        if t is None:
            continue
        if int(m.eq_objtype[e]) == int(mujoco.mjtObj.mjOBJ_SITE):     # both sites move to the new point
            sites = {el.get("name"): el for el in root.find("worldbody").iter("site")}
            for attr, sid in (("site1", int(m.eq_obj1id[e])), ("site2", int(m.eq_obj2id[e]))):
                el = sites.get(eq_el[e].get(attr))
                if el is None:
                    raise ConfigError(f"site {eq_el[e].get(attr)!r} not found", source=source, key=f"equality #{e}")
                x, R = final[int(m.site_bodyid[sid])]
                el.set("pos", _f(R.T @ (t.anchor - x) / _M))
            continue
        x, R = final[int(m.eq_obj1id[e])]
        eq_el[e].set("anchor", _f(R.T @ (t.anchor - x) / _M))
    ET.indent(tree)
    out = Path(out)
    tree.write(out, encoding="unicode")
    return out


# ---------------------------------------------------------------------------------------------- URDF writing
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


def _export_urdf_into(robot, source: str, out) -> Path:
    """:func:`export_into` for a URDF file: every link of a leg turns with the leg's rotation ``Q`` about its
    joint centre, which moves to the robot's; joint origins are rewritten from the links' new poses at zero
    joint values (which stay the reference configuration)."""
    yourdfpy = _optional.require("yourdfpy", "writing into a URDF file")
    graph = read_urdf(source)
    old = robot_from_graph(graph)
    if not isinstance(old, SpatialManipulator) or not isinstance(robot, SpatialManipulator):
        raise ConfigError("writing into an existing file is done for spatial robots so far", source=source)
    if old.architecture != robot.architecture or old.n_legs != robot.n_legs:
        raise ConfigError(f"the file holds a {old.architecture} with {old.n_legs} legs, the robot is a "
                          f"{robot.architecture} with {robot.n_legs}", source=source)
    platform, legs = _legs(graph)
    old_home, new_home = _home(old), _home(robot)
    urdf = yourdfpy.URDF.load(source, build_scene_graph=True, load_meshes=False, build_collision_scene_graph=False)
    base_link = urdf.base_link
    tree = ET.parse(source)
    root = tree.getroot()
    joints_el = {el.get("name"): el for el in root.findall("joint")}
    child_of = {el.find("child").get("link"): el for el in root.findall("joint")}

    def pose(link):
        T = urdf.get_transform(link, base_link) if link != base_link else np.eye(4)
        return T[:3, 3] * _M, T[:3, :3]

    targets: dict = {}
    flipped = {j.ident for paths in legs for path in paths for j in path if j.flipped}
    link_rot, link_key = {}, {}
    leg_extras = graph.extras.get("legs") if isinstance(graph.extras.get("legs"), list) else []
    for i, (paths, lo, ln) in enumerate(zip(legs, old.legs, robot.legs), start=1):
        extra = leg_extras[i - 1] if i - 1 < len(leg_extras) and isinstance(leg_extras[i - 1], dict) else {}
        reader = _LegReader(graph, platform, i, extra)
        try:
            Q, tg, keys = _retarget(paths, lo, ln, old_home, new_home, reader.normal)
        except GeometryError as exc:
            raise GeometryError(exc.message, source=robot.name, key=f"legs[{i}]") from None
        targets.update(tg)
        for path in paths:
            for j in path:
                if j.ident[0] != "urdf":
                    continue
                link = joints_el[j.ident[1]].find("child").get("link")
                link_rot[link] = Q
                if j.kind != "slide":
                    link_key[link] = (j.anchor, tg[j.ident].anchor)
                else:
                    x = pose(link)[0]
                    link_key[link] = min(keys, key=lambda kv: np.linalg.norm(kv[0] - x))
    new_pose = {}
    for link, Q in link_rot.items():
        x, R = pose(link)
        k_old, k_new = link_key[link]
        new_pose[link] = (k_new + Q @ (x - k_old), Q @ R)
    new_pose[graph.names[platform]] = new_home
    final = {base_link: (np.zeros(3), np.eye(3))}
    order = [base_link]
    children: dict[str, list] = {}
    for el in root.findall("joint"):
        children.setdefault(el.find("parent").get("link"), []).append(el)
    while order:
        parent = order.pop()
        xp, Rp = final[parent]
        for el in children.get(parent, []):
            child = el.find("child").get("link")
            if child in new_pose:
                final[child] = new_pose[child]
                x, R = final[child]
                origin = el.find("origin")
                if origin is None:
                    origin = ET.SubElement(el, "origin")
                origin.set("xyz", _f(Rp.T @ (x - xp) / _M))
                origin.set("rpy", _f(_rpy(Rp.T @ R)))
            else:
                x, R = pose(child)
                xo, Ro = pose(parent)
                final[child] = (xp + Rp @ (Ro.T @ (x - xo)), Rp @ Ro.T @ R)
            order.append(child)
    refs = {}
    for ident, t in targets.items():
        kind, key = ident
        if kind == "urdf":
            el = joints_el[key]
            x, R = final[el.find("child").get("link")]
            if t.axis is not None:
                axis_el = el.find("axis")
                if axis_el is None:
                    axis_el = ET.SubElement(el, "axis")
                axis_el.set("xyz", _f(R.T @ (-t.axis if ident in flipped else t.axis)))
            scale = _M if el.get("type") == "prismatic" else 1.0
            if t.ref is not None:
                refs[key] = t.ref / scale
            if t.range is not None:
                limit = el.find("limit")
                if limit is None:
                    limit = ET.SubElement(el, "limit", effort="0", velocity="0")
                limit.set("lower", repr(t.range[0] / scale))
                limit.set("upper", repr(t.range[1] / scale))
        elif kind == "gazebo":
            el = _gazebo_joints(root)[key]
            child = (el.findtext("child") or "").strip()
            x, R = final[child]
            pose_el = el.find("pose")
            old_pose = _pose6(None if pose_el is None else pose_el.text, source, "gazebo joint")
            if pose_el is None:
                pose_el = ET.SubElement(el, "pose")
            pose_el.text = _f(np.concatenate([R.T @ (t.anchor - x) / _M, old_pose[3:]]))
        elif kind == "loop":
            el = (list(root.iter("loop")) + list(root.iter("loop_joint")))[key]
            links = _loop_links(el)
            if el.tag == "loop":
                succ = el.find("successor") if el.find("successor") is not None else el.find("sucessor")
                ends = [el.find("predecessor"), succ]
                for end, link in zip(ends, links):
                    x, R = final[link]
                    origin = end.find("origin")
                    if origin is None:
                        origin = ET.SubElement(end, "origin")
                    # the closure point is the origin of the end frames, in each link's frame
                    origin.set("xyz", _f(R.T @ (t.anchor - x) / _M))
            else:
                for end, link in zip((el.find("link1"), el.find("link2")), links):
                    x, R = final[link]
                    end.set("xyz", _f(R.T @ (t.anchor - x) / _M))
    if refs:
        extra = root.find(EXTRAS_NAME)
        if extra is None:
            extra = ET.SubElement(root, EXTRAS_NAME)
        data = graph.extras.copy()
        data["refs"] = {**(data.get("refs") or {}), **refs}
        extra.text = json.dumps(data)
    ET.indent(tree)
    out = Path(out)
    tree.write(out, encoding="unicode", xml_declaration=True)
    return out
