"""MJCF files read by MuJoCo into a :class:`~pmaccuracy.io.robot_formats.graph.KinematicGraph`."""

from __future__ import annotations

import os

import numpy as np

from ... import _optional
from .graph import EXTRAS_NAME, _M, FileJoint, KinematicGraph, _Groups, _error, _extras


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
