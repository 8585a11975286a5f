"""SDFormat (``.sdf``) files read with the standard library's XML parser into a kinematic graph.

No maintained Python SDFormat reader is on PyPI (Gazebo's ``sdformat`` bindings come with Gazebo; the PyPI
package named ``sdformat`` is an unrelated data format), and SDF is XML: this module reads the one ``<model>``
with joints of a file (directly under ``<sdf>`` or inside ``<sdf><world>``) and resolves its frames itself.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from .graph import _M, FileJoint, KinematicGraph, _Groups, _error, _extras, _unit

#: XML namespace of our custom SDF elements (``xmlns:pmaccuracy="urn:pmaccuracy"`` on the ``<sdf>`` root).
SDF_NAMESPACE = "urn:pmaccuracy"
#: SDF joint types and the graph's joints they become (``None``: welds the two links).
_KINDS = {"revolute": "hinge", "continuous": "hinge", "prismatic": "slide", "ball": "ball", "universal": "hinge",
          "fixed": None}
#: Plugins (name or file name, lower case without ``-``, ``_``, ``:``) whose ``<joint_name>`` drive the joint.
_DRIVERS = ("jointpositioncontroller", "jointcontroller", "jointtrajectorycontroller", "applyjointforce")
_UNLIMITED = 1e15     # SDF's default limits are +-1e16: no limit


def _local(tag: str) -> tuple[str, str]:
    """``(namespace, local name)`` of an ElementTree tag."""
    if tag.startswith("{"):
        ns, _, name = tag[1:].partition("}")
        return ns, name
    return "", tag


def _ours(el: ET.Element, name: str) -> bool:
    if not isinstance(el.tag, str):       # a comment
        return False
    ns, local = _local(el.tag)
    return local == name and "pmaccuracy" in ns


def _version(root: ET.Element, source: str) -> tuple[int, int]:
    text = root.get("version")
    try:
        major, minor = (int(v) for v in (text or "").strip().split(".")[:2])
    except ValueError:
        raise _error(source, "<sdf>", f"needs its version attribute (e.g. version=\"1.9\"), got {text!r}") from None
    return major, minor


def rpy_matrix(rpy) -> np.ndarray:
    """``Rz(yaw) Ry(pitch) Rx(roll)`` of SDFormat's fixed-axis ``roll pitch yaw`` (rad), (3, 3)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def _quat_matrix(x, y, z, w) -> np.ndarray:
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _pose(el: ET.Element | None, source: str, label: str) -> tuple[np.ndarray, np.ndarray, str | None]:
    """A ``<pose>``: position (m), rotation and the frame it is relative to (None: the element's default).

    Six numbers ``x y z roll pitch yaw`` (rad, or degrees with ``degrees="true"``) or, with
    ``rotation_format="quat_xyzw"``, seven ``x y z qx qy qz qw``; SDF 1.6's ``frame`` attribute is read as
    ``relative_to``.
    """
    if el is None:
        return np.zeros(3), np.eye(3), None
    rel = el.get("relative_to") or el.get("frame") or None
    text = (el.text or "").strip()
    fmt = el.get("rotation_format", "euler_rpy")
    want = 7 if fmt == "quat_xyzw" else 6
    if fmt not in ("euler_rpy", "quat_xyzw"):
        raise _error(source, label, f"<pose rotation_format={fmt!r}>: expected euler_rpy or quat_xyzw")
    if not text:
        return np.zeros(3), np.eye(3), rel
    try:
        v = np.array([float(t) for t in text.split()])
    except ValueError:
        v = np.zeros(0)
    if v.shape != (want,) or not np.all(np.isfinite(v)):
        what = "x y z qx qy qz qw" if want == 7 else "x y z roll pitch yaw"
        raise _error(source, label, f"<pose> expects {want} numbers ({what}), got {text!r}")
    if want == 7:
        if np.linalg.norm(v[3:]) < 1e-12:
            raise _error(source, label, f"<pose>: a zero quaternion, got {text!r}")
        return v[:3], _quat_matrix(*v[3:]), rel
    angles = np.radians(v[3:]) if el.get("degrees", "false").strip().lower() in ("true", "1") else v[3:]
    return v[:3], rpy_matrix(angles), rel


def _vector(text: str | None, source: str, label: str, default=(0.0, 0.0, 1.0)) -> np.ndarray:
    if text is None or not text.strip():
        return np.array(default, dtype=float)
    try:
        v = np.array([float(t) for t in text.split()])
    except ValueError:
        v = np.zeros(0)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) == 0:
        raise _error(source, label, f"expected three numbers of a non-zero vector, got {text!r}")
    return v


def _model(root: ET.Element, source: str) -> ET.Element:
    """The file's robot: the one ``<model>`` with joints under ``<sdf>`` or ``<sdf><world>``."""
    models = root.findall("model") + [m for w in root.findall("world") for m in w.findall("model")]
    includes = root.findall("include") + [i for w in root.findall("world") for i in w.findall("include")]
    robots = [m for m in models if m.find("joint") is not None or m.find("model") is not None
              or m.find("include") is not None]
    if not robots:
        more = " (<include> elements are not resolved: put the model itself in the file)" if includes else ""
        raise _error(source, "<model>", f"no <model> with joints in the file{more}")
    if len(robots) > 1:
        names = ", ".join(repr(m.get("name")) for m in robots)
        raise _error(source, "<model>", f"{len(robots)} models with joints ({names}): one robot per file")
    model = robots[0]
    label = f"model '{model.get('name', '?')}'"
    if model.find("model") is not None or model.find("include") is not None:
        raise _error(source, label, "nested models and <include> are not read: write the robot as one model")
    return model


class _Frames:
    """Poses in the model frame of the model's links, joints and ``<frame>`` elements (SDF 1.7 semantics)."""

    def __init__(self, model: ET.Element, source: str, version: tuple[int, int]) -> None:
        self.source = source
        self.els: dict[str, tuple[str, ET.Element]] = {}
        self.joint_key: dict[str, str] = {}       # a joint's key in els (SDF <= 1.6: it may share a link's name)
        for tag in ("link", "joint", "frame"):
            for el in model.findall(tag):
                name = el.get("name")
                if not name:
                    raise _error(source, f"<{tag}>", "needs a name attribute")
                key = name
                if tag == "joint" and version < (1, 7) and name in self.els and self.els[name][0] == "link":
                    key = f"{name}::joint"
                if key in self.els or name in ("__model__", "world"):
                    raise _error(source, f"{tag} '{name}'", "its name is taken by another link, joint or frame")
                if tag == "joint":
                    self.joint_key[name] = key
                self.els[key] = (tag, el)
        self.memo: dict[str, tuple[np.ndarray, np.ndarray]] = {"__model__": (np.zeros(3), np.eye(3))}
        self.version = version

    def default(self, tag: str, el: ET.Element) -> str:
        if tag == "joint":
            return (el.findtext("child") or "").strip()
        if tag == "frame":
            return el.get("attached_to") or "__model__"
        return "__model__"

    def pose(self, name: str, asked_by: str | None = None, stack: tuple = ()) -> tuple[np.ndarray, np.ndarray]:
        """Position (mm) and rotation of frame ``name`` in the model frame."""
        if name in self.memo:
            return self.memo[name]
        if name not in self.els:
            raise _error(self.source, asked_by, f"no link, joint or frame named {name!r} in the model")
        tag, el = self.els[name]
        label = f"{tag} '{el.get('name')}'"
        if name in stack:
            chain = " -> ".join([*stack[stack.index(name):], name])
            raise _error(self.source, label, f"its pose is relative to itself through {chain}")
        p, R, rel = _pose(el.find("pose"), self.source, label)
        rel = rel or self.default(tag, el)
        if tag == "joint" and rel not in self.els:
            raise _error(self.source, label, f"its <child> must name a link of the model, got {rel!r}")
        pr, Rr = self.pose(rel, f"{label} <pose relative_to={rel!r}>", (*stack, name))
        out = (pr + Rr @ (p * _M), Rr @ R)
        self.memo[name] = out
        return out

    def link_of(self, name: str, label: str, end: str) -> str:
        """The link that ``name`` (a link, or a frame attached to one) is, for a joint's ``<parent>``/``<child>``."""
        seen = set()
        current = name
        while current in self.els and self.els[current][0] == "frame" and current not in seen:
            seen.add(current)
            current = self.els[current][1].get("attached_to") or "__model__"
        if current in self.els and self.els[current][0] == "link":
            return current
        raise _error(self.source, label, f"its <{end}> must name a link of the model, got {name!r}")


def _limits(axis: ET.Element | None, scale: float) -> tuple[float, float] | None:
    if axis is None or axis.find("limit") is None:
        return None
    lim = axis.find("limit")
    try:
        lo = float(lim.findtext("lower", "-1e16"))
        hi = float(lim.findtext("upper", "1e16"))
    except ValueError:
        return ()
    if not (np.isfinite(lo) and np.isfinite(hi)) or lo > hi:
        return ()
    if abs(lo) >= _UNLIMITED or abs(hi) >= _UNLIMITED:
        return None
    return lo * scale, hi * scale


def actuated_joints(model: ET.Element) -> set[str]:
    """Names of the joints the file drives: the ``<joint_name>`` of joint-controller plugins inside the model
    (Gazebo's ``JointPositionController``, ``JointController``, ``JointTrajectoryController``, ``ApplyJointForce``,
    recognised by the plugin's ``name`` or ``filename``) and the joints holding a ``<pmaccuracy:actuated/>``
    element (text empty, true or 1)."""
    out = set()
    for plugin in model.iter("plugin"):
        key = (plugin.get("name", "") + " " + plugin.get("filename", "")).lower()
        key = key.replace("-", "").replace("_", "").replace(":", "")
        if any(d in key for d in _DRIVERS):
            out |= {(j.text or "").strip() for j in plugin.iter("joint_name") if (j.text or "").strip()}
    for joint in model.findall("joint"):
        for child in joint:
            if _ours(child, "actuated") and (child.text or "true").strip().lower() in ("true", "1"):
                out.add(joint.get("name"))
    return out


def read_sdf(path: str | os.PathLike) -> KinematicGraph:
    """The kinematic graph of an SDFormat file (versions 1.4 to 1.11), read with :mod:`xml.etree`.

    The robot is the one ``<model>`` with joints (under ``<sdf>`` or ``<sdf><world>``). Frames: a ``<pose>``
    ``x y z roll pitch yaw`` (m, rad; ``R = Rz(yaw) Ry(pitch) Rx(roll)``; ``degrees="true"`` and
    ``rotation_format="quat_xyzw"`` of SDF 1.9 are read) is relative to its ``relative_to`` frame (SDF 1.6's
    ``frame`` attribute), by default the model frame for a link, the child link for a joint, the
    ``attached_to`` frame for a ``<frame>``; chains of such frames are followed. A joint's ``<axis><xyz>`` is in
    the joint frame, or in the frame named by ``expressed_in`` (``__model__``: the model frame); with SDF 1.5-1.6's
    ``<use_parent_model_frame>true`` and in SDF 1.4, in the model frame. Joint types: ``revolute``,
    ``continuous`` (hinges), ``prismatic`` (a slide, metres -> mm), ``ball``, ``universal`` (a hinge about
    ``<axis>`` on the parent side, then one about ``<axis2>``, through the joint origin) and ``fixed`` (welds two
    links; to ``world`` it fixes a link). Ranges: ``<limit><lower><upper>`` (SDF's +-1e16 defaults: unlimited).

    The tree and its loops need no marking: every joint is an edge between rigid groups of links, the loops
    being the joints beyond any spanning tree. The base is the world with the links fixed to it (its frame:
    the one link fixed to ``world``, else the model frame); when nothing holds to the world, the model's
    ``canonical_link`` (else its first link). Actuated joints: :func:`actuated_joints`. SDF has no reference
    offsets: a joint's value in the drawn configuration is zero unless the model's ``<pmaccuracy:extras>`` JSON
    gives ``refs`` (joint name -> m or rad, written by :func:`~pmaccuracy.io.robot_formats.write_sdf`).
    Raises :class:`ConfigError` naming the file and element.
    """
    return _read(os.fspath(path))[0]


@dataclass
class _Context:
    """What :func:`_read` learnt of a file beside its graph (for writing a calibrated robot into it)."""

    tree: ET.ElementTree
    model: ET.Element
    frames: _Frames
    ends: dict[str, tuple[str, str]]
    group_of: dict[str, int]
    base: tuple[np.ndarray, np.ndarray]


def _read(source: str) -> tuple[KinematicGraph, _Context]:
    """:func:`read_sdf` and its context."""
    try:           # comments kept: a calibrated robot is written into a copy of the file
        tree = ET.parse(source, parser=ET.XMLParser(target=ET.TreeBuilder(insert_comments=True)))
    except (ET.ParseError, OSError) as exc:
        raise _error(source, None, f"not a readable XML file: {exc}") from None
    root = tree.getroot()
    if root.tag != "sdf":
        raise _error(source, root.tag, "an SDF file's root element must be <sdf>")
    version = _version(root, source)
    model = _model(root, source)
    frames = _Frames(model, source, version)
    links = [el.get("name") for el in model.findall("link")]
    if not links:
        raise _error(source, f"model '{model.get('name', '?')}'", "has no <link>")
    lid = {n: i + 1 for i, n in enumerate(links)}        # 0: the world
    groups = _Groups(len(links) + 1)
    joints = model.findall("joint")
    ends: dict[str, tuple[str, str]] = {}
    for el in joints:
        name = el.get("name")
        label = f"joint '{name}'"
        kind = el.get("type")
        if kind not in _KINDS:
            raise _error(source, label, f"a {kind!r} joint cannot be mapped to a leg's joint (types: "
                                        f"{', '.join(_KINDS)})")
        parent = (el.findtext("parent") or "").strip()
        child = (el.findtext("child") or "").strip()
        parent = "world" if parent == "world" else frames.link_of(parent, label, "parent")
        child = frames.link_of(child, label, "child")
        ends[name] = (parent, child)
        if kind == "fixed":
            groups.union(lid.get(parent, 0), lid[child])
    fixed_to_world = [ends[el.get("name")][1] for el in joints
                      if ends[el.get("name")][0] == "world" and el.get("type") == "fixed"]
    if not any(p == "world" for p, _ in ends.values()):
        canonical = model.get("canonical_link") or links[0]
        if canonical not in lid:
            raise _error(source, f"model '{model.get('name')}'", f"canonical_link {canonical!r} is not a link")
        groups.union(0, lid[canonical])
        fixed_to_world = [canonical]
    base_p, base_R = (frames.pose(fixed_to_world[0]) if len(fixed_to_world) == 1 else (np.zeros(3), np.eye(3)))

    def here(p, R):
        return base_R.T @ (p - base_p), base_R.T @ R

    roots = sorted({groups.find(i) for i in range(len(links) + 1)})
    index = {r: i for i, r in enumerate(roots)}
    fixed_children = {ends[el.get("name")][1] for el in joints if el.get("type") == "fixed"}
    names, group_frames = ["world"], [(np.zeros(3), np.eye(3))]
    for r in roots[1:]:
        members = [n for n in links if groups.find(lid[n]) == r]
        frame_link = next((n for n in members if n not in fixed_children), members[0])
        names.append(frame_link)
        group_frames.append(here(*frames.pose(frame_link)))
    actuated = actuated_joints(model)
    extras = None
    for child in model:
        if _ours(child, "extras"):
            extras = child.text
    graph = KinematicGraph(source=source, names=names, frames=group_frames, any_actuator=bool(actuated))
    graph.extras = _extras(extras, source)
    refs = graph.extras.get("refs", {}) if isinstance(graph.extras.get("refs"), dict) else {}
    for el in joints:
        name, kind = el.get("name"), el.get("type")
        label = f"joint '{name}'"
        if kind == "fixed":
            continue
        parent, child = ends[name]
        g1, g2 = index[groups.find(lid.get(parent, 0))], index[groups.find(lid[child])]
        if g1 == g2:
            raise _error(source, label, f"joins '{parent}' and '{child}', which fixed joints weld together")
        pj, Rj = frames.pose(frames.joint_key[name])
        anchor = here(pj, Rj)[0]
        if kind == "ball":
            graph.edges.append([FileJoint(name=label, kind="ball", anchor=anchor, axis=np.zeros(3), range=None,
                                          ref=0.0, actuated=name in actuated, parent=g1, child=g2,
                                          ident=("sdf", name, 0))])
            continue
        edge = []
        for k, tag in enumerate(("axis", "axis2") if kind == "universal" else ("axis",)):
            ax = el.find(tag)
            where = f"{label} <{tag}>"
            xyz_el = None if ax is None else ax.find("xyz")
            vec = _unit(_vector(None if xyz_el is None else xyz_el.text, source, where + "<xyz>"))
            expressed = None if xyz_el is None else xyz_el.get("expressed_in")
            upm = (ax.findtext("use_parent_model_frame") or "").strip().lower() in ("true", "1") \
                if ax is not None else False
            if expressed:
                Rf = frames.pose(expressed, f"{where}<xyz expressed_in={expressed!r}>")[1]
            elif upm or version < (1, 5):
                Rf = np.eye(3)
            else:
                Rf = Rj
            axis = base_R.T @ (Rf @ vec)
            slide = _KINDS[kind] == "slide"
            scale = _M if slide else 1.0
            rng = None if kind == "continuous" else _limits(ax, scale)
            if rng == ():
                raise _error(source, where + "<limit>", "expects numbers <lower> <= <upper>")
            edge.append(FileJoint(name=label, kind=_KINDS[kind], anchor=anchor, axis=axis, range=rng,
                                  ref=float(refs.get(name if k == 0 else f"{name}:axis2", 0.0)) * scale,
                                  actuated=name in actuated and k == 0, parent=g1, child=g2,
                                  ident=("sdf", name, k)))
        graph.edges.append(edge)
    unknown = sorted(actuated - {el.get("name") for el in joints})
    if unknown:
        raise _error(source, "<plugin>", f"drives joint {unknown[0]!r}, which is not a joint of the model")
    group_of = {n: index[groups.find(lid[n])] for n in links}
    return graph, _Context(tree, model, frames, ends, group_of, (base_p, base_R))
