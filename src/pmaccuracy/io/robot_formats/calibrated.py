"""A calibrated robot written into the MJCF or URDF file it came from, changing only the geometry."""

from __future__ import annotations

import json
import math
import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ... import _optional
from ...errors import ConfigError, GeometryError
from ...model.spatial import SpatialManipulator
from ...model.spatial_legs import DeltaLeg, PRSLeg, UPULeg
from .graph import SUFFIXES, EXTRAS_NAME, _M, _Groups, _unit, _signed_angle
from .mjcf import _base_body, read_mjcf
from .recognise import _LegReader, _legs, pairs_of, robot_from_graph
from .sdf import SDF_NAMESPACE, _read
from .urdf import _gazebo_joints, _loop_links, _pose6, read_urdf
from .write import _f, _home, _quat, _rpy


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


def _retargeted_legs(graph, platform, legs, old, robot, old_home, new_home):
    """Per leg ``(paths, Q, targets, keys)`` of :func:`_retarget` (its extras read as the reader reads them; a leg
    that cannot be moved raises :class:`GeometryError` naming it)."""
    extras = graph.extras.get("legs") if isinstance(graph.extras.get("legs"), list) else []
    for i, (paths, lo, ln) in enumerate(zip(legs, old.legs, robot.legs), start=1):
        extra = extras[i - 1] if i - 1 < len(extras) and isinstance(extras[i - 1], dict) else {}
        reader = _LegReader(graph, platform, i, extra)
        try:
            Q, tg, keys = _retarget(paths, lo, ln, old_home, new_home, reader.normal)
        except GeometryError as exc:
            raise GeometryError(exc.message, source=robot.name, key=f"legs[{i}]") from None
        yield paths, Q, tg, keys


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
    """Write ``robot`` (e.g. a calibrated copy of the one imported from ``original``) into a copy of the MJCF,
    URDF or SDF file ``original`` at ``out``, changing only the geometry (URDF: joint origins and axes, limits, loop
    origins, and the reference values of a Delta's or 3-PRS's actuated joints in the ``<pmaccuracy>`` JSON; SDF:
    :func:`_export_sdf_into`).

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
    if fmt == "sdf":
        return _export_sdf_into(robot, source, out)
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
    for paths, Q, tg, keys in _retargeted_legs(graph, platform, legs, old, robot, old_home, new_home):
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

    def pose(link):
        T = urdf.get_transform(link, base_link) if link != base_link else np.eye(4)
        return T[:3, 3] * _M, T[:3, :3]

    targets: dict = {}
    flipped = {j.ident for paths in legs for path in paths for j in path if j.flipped}
    link_rot, link_key = {}, {}
    for paths, Q, tg, keys in _retargeted_legs(graph, platform, legs, old, robot, old_home, new_home):
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
        elif kind == "closing":     # both frames' fixed joints put their origin at the new point
            for n in (1, 2):
                el = next(j for j in root.findall("joint") if j.find("child").get("link") == f"closing_{key}_{n}")
                xp, Rp = final[el.find("parent").get("link")]
                origin = el.find("origin")
                if origin is None:
                    origin = ET.SubElement(el, "origin", rpy="0 0 0")
                origin.set("xyz", _f(Rp.T @ (t.anchor - xp) / _M))
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


def _export_sdf_into(robot, source: str, out) -> Path:
    """:func:`export_into` for an SDFormat file: the links of each leg (a rigid group at a time) turn with the
    leg's rotation ``Q`` about a joint centre, which moves to the robot's; the platform's links move to the new
    home pose, the base's stay; a ``<frame>`` moves with the link it is attached to. Every ``<pose>`` that changes
    is rewritten (``x y z roll pitch yaw`` in m and rad, keeping its ``relative_to``) and joint poses put the joints
    at the robot's centres; ``<axis>``/``<axis2>`` ``<xyz>`` are rewritten in their ``expressed_in`` frame and
    ``<limit>`` in m or rad; the reference values of a Delta's or 3-PRS's actuated joints go into the model's
    ``<pmaccuracy:extras>`` JSON. Zero joint values stay the drawn configuration; everything else is kept."""
    graph, ctx = _read(source)
    old = robot_from_graph(graph)
    if not isinstance(old, SpatialManipulator) or not isinstance(robot, SpatialManipulator):
        raise ConfigError("writing into an existing file is done for spatial robots so far", source=source)
    if old.architecture != robot.architecture or old.n_legs != robot.n_legs:
        raise ConfigError(f"the file holds a {old.architecture} with {old.n_legs} legs, the robot is a "
                          f"{robot.architecture} with {robot.n_legs}", source=source)
    platform, legs = _legs(graph)
    old_home, new_home = _home(old), _home(robot)
    frames, model = ctx.frames, ctx.model
    bp, bR = ctx.base

    def here(name):                       # a frame's pose in the base frame (mm) in the file as it is
        p, R = frames.pose(name)
        return bR.T @ (p - bp), bR.T @ R

    def moved(T, x, R):                   # x, R carried by T = (k_old, k_new, Q)
        k_old, k_new, Q = T
        return k_new + Q @ (x - k_old), Q @ R

    links = [el.get("name") for el in model.findall("link")]
    group_T: dict[int, tuple] = {}
    pf, Rf = graph.frames[platform]
    p1, R1 = new_home
    group_T[platform] = (pf, p1, R1 @ Rf.T)
    targets: dict = {}
    flipped = {j.ident for paths in legs for path in paths for j in path if j.flipped}
    for paths, Q, tg, keys in _retargeted_legs(graph, platform, legs, old, robot, old_home, new_home):
        targets.update(tg)
        touched: dict[int, tuple | None] = {}
        for path in paths:
            for j in path:
                for g in (j.parent, j.child):
                    if g in (0, platform):
                        continue
                    if touched.get(g) is None:
                        touched[g] = (j.anchor, tg[j.ident].anchor, Q) if j.kind != "slide" else None
        for g, T in touched.items():
            if T is None:                 # only slides touch it: the nearest pair centre
                x = graph.frames[g][0]
                k_old, k_new = min(keys, key=lambda kv: np.linalg.norm(kv[0] - x))
                T = (k_old, k_new, Q)
            group_T[g] = T
    identity = (np.zeros(3), np.zeros(3), np.eye(3))
    new: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for name in links:
        new[name] = moved(group_T.get(ctx.group_of[name], identity), *here(name))
    for el in model.findall("frame"):                 # rigid with the link it is attached to
        name, link = el.get("name"), el.get("attached_to") or "__model__"
        seen = set()
        while link in frames.els and frames.els[link][0] != "link" and link not in seen:
            seen.add(link)
            tag, fel = frames.els[link]
            link = (fel.findtext("child") or "").strip() if tag == "joint" else (fel.get("attached_to") or "__model__")
        if link in new:
            xo, Ro = here(link)
            xn, Rn = new[link]
            x, R = here(name)
            new[name] = (xn + Rn @ Ro.T @ (x - xo), Rn @ Ro.T @ R)
        else:
            new[name] = here(name)
    by_joint = {ident[1]: {} for ident in targets if ident[0] == "sdf"}
    for ident, t in targets.items():
        if ident[0] == "sdf":
            by_joint[ident[1]][ident[2]] = t
    for el in model.findall("joint"):                 # rigid with the child, at the robot's centre
        name = el.get("name")
        child = ctx.ends[name][1]
        xo, Ro = here(child)
        xn, Rn = new[child]
        x, R = here(frames.joint_key[name])
        x, R = xn + Rn @ Ro.T @ (x - xo), Rn @ Ro.T @ R
        if name in by_joint:
            x = by_joint[name][0].anchor
        new[frames.joint_key[name]] = (x, R)
    model_frame = (bR.T @ (-bp), bR.T)
    new["__model__"] = model_frame
    for name, (tag, el) in frames.els.items():        # rewrite the poses that change, in their own frames
        pose_el = el.find("pose")
        rel = (pose_el.get("relative_to") or pose_el.get("frame")) if pose_el is not None else None
        rel = rel or frames.default(tag, el)
        xr, Rr = new[rel] if rel in new else here(rel)
        x, R = new[name]
        loc_x, loc_R = Rr.T @ (x - xr), Rr.T @ R
        xo_r, Ro_r = here(rel)
        xo, Ro = here(name)
        if np.linalg.norm(loc_x - Ro_r.T @ (xo - xo_r)) <= 1e-9 and np.max(np.abs(loc_R - Ro_r.T @ Ro)) <= 1e-13:
            continue
        if pose_el is None:
            pose_el = ET.Element("pose")
            el.insert(0, pose_el)
        for attr in ("degrees", "rotation_format"):
            pose_el.attrib.pop(attr, None)
        pose_el.text = _f(np.concatenate([loc_x / _M, _rpy(loc_R)]))
    refs = {}
    for el in model.findall("joint"):
        name = el.get("name")
        for k, t in sorted(by_joint.get(name, {}).items()):
            tag = "axis" if k == 0 else "axis2"
            ax = el.find(tag)
            slide = el.get("type") == "prismatic"
            scale = _M if slide else 1.0
            if t.axis is not None:
                if ax is None:
                    ax = ET.SubElement(el, tag)
                xyz = ax.find("xyz")
                if xyz is None:
                    xyz = ET.SubElement(ax, "xyz")
                expressed = xyz.get("expressed_in")
                upm = (ax.findtext("use_parent_model_frame") or "").strip().lower() in ("true", "1")
                if expressed:
                    Re = new[expressed][1] if expressed in new else here(expressed)[1]
                elif upm or frames.version < (1, 5):
                    Re = model_frame[1]
                else:
                    Re = new[frames.joint_key[name]][1]
                xyz.text = _f(Re.T @ (-t.axis if ("sdf", name, k) in flipped else t.axis))
            if t.ref is not None:
                refs[name if k == 0 else f"{name}:axis2"] = t.ref / scale
            if t.range is not None:
                if ax is None:
                    ax = ET.SubElement(el, tag)
                limit = ax.find("limit")
                if limit is None:
                    limit = ET.SubElement(ax, "limit")
                for end, v in (("lower", t.range[0]), ("upper", t.range[1])):
                    node = limit.find(end)
                    if node is None:
                        node = ET.SubElement(limit, end)
                    node.text = repr(v / scale)
    if refs:
        extra = next((c for c in model if c.tag == f"{{{SDF_NAMESPACE}}}extras"), None)
        if extra is None:
            extra = ET.SubElement(model, f"{{{SDF_NAMESPACE}}}extras")
        data = graph.extras.copy()
        data["refs"] = {**(data.get("refs") or {}), **refs}
        extra.text = json.dumps(data)
    for prefix, uri in _namespaces(source):        # the file's own prefixes, not ns0
        try:
            ET.register_namespace(prefix, uri)
        except ValueError:
            pass
    text = Path(source).read_text(encoding="utf-8")
    start = re.search(r"<sdf[\s>/]", text)
    prolog = text[:start.start()] if start else ""          # the XML declaration and comments before <sdf>
    out = Path(out)
    out.write_text(prolog + ET.tostring(ctx.tree.getroot(), encoding="unicode") + "\n", encoding="utf-8")
    return out


def _namespaces(source: str) -> list[tuple[str, str]]:
    """The ``(prefix, uri)`` namespace declarations of an XML file."""
    return [ns for _, ns in ET.iterparse(source, events=("start-ns",)) if ns[0]]
