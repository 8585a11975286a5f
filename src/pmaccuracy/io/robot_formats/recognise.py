"""Legs recognised in a kinematic graph: spatial patterns of kinematic pairs, planar chains."""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import ConfigError, GeometryError
from ...model.chain import Chain
from ...model.chain import Joint as ChainJoint
from ...model.legs import ChainLeg
from ...model.manipulator import Manipulator
from ...model.spatial import CHAIN, CONTROLLED, POSE_NAMES, SpatialManipulator
from ...model.spatial_chain import ChainJoint as SpatialChainJoint, ChainLeg as SpatialChainLeg
from ...model.spatial_legs import DeltaLeg, PRSLeg, RPSLeg, UPSLeg, UPULeg
from ...numerics.spatial import euler_xyz_rates, rotations, rotvec_to_euler_xyz, rotvecs
from .graph import SUFFIXES, PATTERNS, ACTUATED_PAIR, FileJoint, KinematicGraph, _error, _unit, _signed_angle, _rotate
from .mjcf import read_mjcf
from .sdf import read_sdf
from .urdf import read_urdf


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


def _component(adj, start: int, seen: set) -> set:
    """The groups reachable from ``start`` through ``adj`` without entering ``seen`` (which they join)."""
    comp, stack = {start}, [start]
    seen.add(start)
    while stack:
        for v, _ in adj[stack.pop()]:
            if v not in seen:
                seen.add(v)
                comp.add(v)
                stack.append(v)
    return comp


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
            comp = _component(adj, start, seen)
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
        comp = _component(adj, start, seen)
        touches = {v for u in comp for v, _ in adj[u]}
        if 0 in touches and platform not in touches:
            edges = [graph.edges[k] for u in comp for _, k in adj[u]]
            return max((e[-1] for e in edges), key=lambda j: j.child)
    return None


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
            if len(paths) == 1:       # any other serial leg: a joint chain (pmaccuracy.model.spatial_chain)
                return _chain_robot(graph, legs, p, home_rotvec)
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
        if all(len(paths) == 1 for paths in legs):
            return _chain_robot(graph, legs, p, home_rotvec)
        raise _error(src, None, f"the legs are of different kinds ({', '.join(patterns)}): one architecture only")
    if archs == {"6-UPS"} and len(built) == 3:
        raise _error(src, None, f"three legs of joints {patterns[0]} (a spherical joint at the platform) leave the "
                                "platform free to turn: a 6-UPS needs six legs, and a 3-UPU's platform-side universal "
                                "joint (two hinges) ends in a weld to the platform, not a connect")
    name = extras.get("name") if isinstance(extras.get("name"), str) else Path(src).stem
    try:
        return SpatialManipulator(architecture=archs.pop(), legs=tuple(built), name=name,
                                  description=str(extras.get("description", "")),
                                  home=tuple(float(v) for v in np.concatenate([p, home_rotvec])))
    except GeometryError as exc:
        raise GeometryError(exc.message, source=src, key=exc.key) from None


def _chain_joint(pair: Pair, *, src: str) -> SpatialChainJoint:
    """A kinematic pair as a joint of a spatial chain leg: values and ranges as the file's (a joint taken against
    the file's tree turns the other way: its values change sign)."""
    def values(j: FileJoint):
        ref, rng = j.ref, j.range
        if j.flipped:
            ref, rng = -ref, (None if rng is None else (-rng[1], -rng[0]))
        return ref, rng

    centre = tuple(float(v) for v in pair.point)
    if pair.letter == "S":
        return SpatialChainJoint(kind="S", centre=centre)
    vals = [values(j) for j in pair.joints]
    axes = tuple(tuple(float(v) for v in j.axis) for j in pair.joints)
    if pair.letter == "U":
        if abs(float(np.dot(axes[0], axes[1]))) > 1e-6:
            raise _error(src, pair.joints[1].name, "two hinges through one point that are not perpendicular: not a "
                                                   "universal joint")
        return SpatialChainJoint(kind="U", centre=centre, axes=axes, home=tuple(v[0] for v in vals),
                                 ranges=tuple(v[1] for v in vals))
    return SpatialChainJoint(kind=pair.letter, centre=centre, axes=axes[:1], home=(vals[0][0],), ranges=(vals[0][1],),
                             actuated=pair.actuated)


def _chain_robot(graph: KinematicGraph, legs, p: np.ndarray, home_rotvec: np.ndarray) -> SpatialManipulator:
    """Legs of no designer type as joint chains (``spatial-chain``): each leg's pairs from the base to the platform,
    its actuated pair marked; the controlled coordinates are the first set (all six; x, y, z; z, roll, pitch) that
    the legs' constraint wrenches determine at home (:func:`controlled_at_home`)."""
    src = graph.source
    home = tuple(float(v) for v in np.concatenate([p, home_rotvec]))
    built = []
    for i, paths in enumerate(legs, start=1):
        pairs = pairs_of(paths[0])
        acts = [pr for pr in pairs if pr.actuated]
        if len(acts) != 1:
            what = "none" if not acts else ", ".join(pr.joints[0].name for pr in acts)
            raise _error(src, paths[0][0].name, f"leg {i} ({''.join(pr.letter for pr in pairs)}): a leg needs exactly "
                                                f"one actuated joint (an actuator on a hinge or a slide); found {what}")
        if acts[0].letter not in ("R", "P"):
            raise _error(src, acts[0].joints[0].name, f"leg {i}: only a single hinge or slide can be actuated")
        joints = tuple(_chain_joint(pr, src=src) for pr in pairs)
        R0 = rotations(home_rotvec[None])[0]
        platform = tuple(float(v) for v in R0.T @ (np.asarray(joints[-1].centre) - p))
        try:
            built.append(SpatialChainLeg(base=joints[0].centre, platform=platform, joints=joints, home_pose=home))
        except GeometryError as exc:
            raise _error(src, paths[0][0].name, f"leg {i}: {exc.message}") from None
    extras = graph.extras
    name = extras.get("name") if isinstance(extras.get("name"), str) else Path(src).stem
    rows = [leg.ROWS for leg in built]
    if sum(rows) != 6:
        raise _error(src, None, f"the legs' passive joints leave {sum(rows)} closure equations (per leg: "
                                f"{', '.join(map(str, rows))}); a parallel robot needs 6")
    controlled = controlled_at_home(built, home)
    if controlled is None:
        raise _error(src, None, f"{len(built)} legs whose constraints fix none of the coordinate sets pmaccuracy "
                                "commands (all six; x, y, z; z, roll, pitch)")
    try:
        return SpatialManipulator(architecture=CHAIN, legs=tuple(built), name=name,
                                  description=str(extras.get("description", "")), home=home,
                                  controlled_names=controlled)
    except (GeometryError, ConfigError) as exc:
        raise type(exc)(exc.message, source=src, key=exc.key) from None


def controlled_at_home(legs, home) -> tuple[str, ...] | None:
    """The controlled coordinates of chain legs: the first of :data:`CONTROLLED`'s sets with one coordinate per
    leg whose complement the constraint wrenches at home fix (their block of ``W_c T`` is regular, ``T`` the
    coordinates' unit twists at home)."""
    home = np.asarray(home, dtype=float)
    p, R = home[:3], rotations(home[3:][None])[0]
    Wc = []
    for leg in legs:
        _, W, g = leg.closure(p, R, home[3:], leg.actuate(p, R))
        Wc.extend(W[k] for k in range(W.shape[0]) if g[k] == 0)
    T = np.eye(6)       # x, y, z translations of P; roll, pitch, yaw rates at zero angles: base-axis rotations
    angles = rotvec_to_euler_xyz(home[3:])
    T[3:, 3:] = euler_xyz_rates(angles)
    for idx in CONTROLLED.values():
        if len(idx) != len(legs):
            continue
        free = [k for k in range(6) if k not in idx]
        if not free:
            return tuple(POSE_NAMES[k] for k in idx)
        block = np.array(Wc) @ T[:, free] if Wc else np.zeros((0, len(free)))
        if block.shape[0] == len(free):
            s = np.linalg.svd(block * np.linalg.norm(block, axis=1, keepdims=True) ** -1, compute_uv=False)
            if s[-1] > 1e-6:
                return tuple(POSE_NAMES[k] for k in idx)
    return None


def read_robot_file(path: str | os.PathLike):
    """The robot (spatial, or planar when every joint moves in one plane) of an MJCF (``.xml``, ``.mjcf``),
    URDF (``.urdf``) or SDFormat (``.sdf``) file (:func:`read_mjcf`, :func:`read_urdf`, :func:`read_sdf`,
    :func:`robot_from_graph`); lengths mm, angles rad.

    Raises :class:`ConfigError` (one line: the file, the element, the problem) for a file that is missing, not
    XML, refused by its parser, or whose loops or joints make no leg of a known architecture.
    """
    source = os.fspath(path)
    fmt = SUFFIXES.get(Path(source).suffix.lower())
    if fmt is None:
        raise ConfigError(f"unknown robot file type (expected one of {', '.join(SUFFIXES)})", source=source)
    if not Path(source).is_file():
        raise ConfigError("no such file", source=source)
    graph = {"mjcf": read_mjcf, "urdf": read_urdf, "sdf": read_sdf}[fmt](source)
    return robot_from_graph(graph)
