"""Independent reference of planar parallel manipulators under load: statics by virtual work and the loaded
pose as the equilibrium of the exact loop closures (tests only; imports nothing from ``pmaccuracy``).

Built on ``error_reference.py`` (every source inserted into the legs' chains as a small rigid transform, the
loops closed exactly by Newton's method in extended precision, derivatives by central differences):

* **Load.** ``wrench(load, pose)``: ``[fx, fy, m]`` (N, N, N mm about the platform centre, base frame) plus
  the weight ``9.80665 mass`` along ``gravity_deg`` acting at ``Rot(phi) com`` from the centre.
* **Statics by virtual work.** A small translation ``d`` of joint k of leg i (inserted before the joint)
  moves the platform by ``dX = G_d d``; the force that joint transmits is ``F = -G_d^T W`` (its work balances
  the load's). A P joint's block: the normal force ``N = -G_sigma^T W`` and the moment ``M = -G_tau^T W``
  about the block's tilt point; an actuator's effort ``tau = -G_dq^T W``.
* **Loaded pose (exact).** With frictionless contacts the platform settles where ``W . X`` is largest over
  the configurations the clearances allow (``W`` evaluated at the displaced pose when the platform has a
  weight). Found as a KKT point: every disk source (pin in bore) along the gradient ``g = d(W . X)/dv`` at
  the current configuration, iterated to convergence with the vertex sources held (inner loop); then every
  vertex source (actuator backlash, block tilt, rhombus vertex) at the support of ``g`` (outer loop) until
  no vertex changes (a vertex moves only if that gains more than 1e-10 of ``sum |g v|``: at a tie either
  side is the same equilibrium). Holding the vertices while the disks converge matters: a block tilt that only turns
  the frame of the next pin's displacement is a reparametrization of the same physical set (``g_tau ~ 0``)
  and a simultaneous update lets it flip every step with the pin lagging ``2 tau`` behind (a 2-cycle off
  the maximum).
"""

from __future__ import annotations

import math

import numpy as np

import error_reference as eref

G0 = 9.80665


def wrench(load: dict, pose) -> np.ndarray:
    """``(3,)`` [N, N, N mm] of ``load`` (keys fx, fy, m, mass kg, com (2,) mm platform frame, gravity_deg) at
    ``pose`` ``(3,)``."""
    fx, fy, m = load.get("fx", 0.0), load.get("fy", 0.0), load.get("m", 0.0)
    mass = load.get("mass", 0.0)
    g = math.radians(load.get("gravity_deg", -90.0))
    wx, wy = G0 * mass * math.cos(g), G0 * mass * math.sin(g)
    cx, cy = load.get("com", (0.0, 0.0))
    c, s = math.cos(pose[2]), math.sin(pose[2])
    ax, ay = c * cx - s * cy, s * cx + c * cy
    return np.array([fx + wx, fy + wy, m + ax * wy - ay * wx])


def _jacobian_at(robot, pose, q0, vars_, v, h=1e-7, cols=None):
    """``dX/dv`` ``(3, n)`` at the configuration ``v`` ``(n,)`` (central differences of the exact closure);
    only the columns ``cols`` (others zero)."""
    n = len(vars_)
    cols = list(range(n)) if cols is None else list(cols)
    E = np.zeros((len(cols), n))
    E[np.arange(len(cols)), cols] = h
    X = eref._solve(robot, pose, q0, eref._to_arrays(vars_, np.concatenate([v + E, v - E])))
    D = X[:len(cols)] - X[len(cols):]
    D[:, 2] = eref.wrap(D[:, 2])
    G = np.zeros((3, n))
    G[:, cols] = (D / (2 * h)).T.astype(float)
    return G


def _pose(robot, pose, q0, vars_, v) -> np.ndarray:
    return eref._solve(robot, pose, q0, eref._to_arrays(vars_, v[None]))[0].astype(float)


def reactions(robot, pose, clearances, load: dict) -> dict:
    """Virtual-work statics at ``pose`` (commanded, no clearance displaced). Returns a dict
    ``(leg, joint) -> {"force": complex N (base frame), "normal": N, "moment": N mm, "actuator": N or N mm}``
    (entries only for the sources ``clearances`` has: radial -> force, lateral -> normal and moment,
    angular -> moment, actuator -> actuator)."""
    robot = eref.as_robot(robot)
    pose = np.asarray(pose, float)
    spec = eref.merge_specs(robot, clearances)
    G, vars_ = eref.error_jacobian_fd(robot, pose, spec)
    W = wrench(load, pose)
    g = W @ G
    q0 = eref.inverse_kinematics(robot, pose)
    out: dict = {}
    for j, (i, k, src, c) in enumerate(vars_):
        entry = out.setdefault((i, k), {})
        if src == "radial" and c == 0:
            # the translation is in the joint's local frame: angle of the frame before the joint
            _, _, _, axes = eref.chain_fk(robot.legs[i], q0[i][None])
            t = math.atan2(axes[0, k, 1], axes[0, k, 0]) - robot.legs[i].joints[k].offset
            gl = g[j] + 1j * g[j + 1]
            entry["force"] = -gl * np.exp(1j * t)
        elif src == "lateral":
            entry["normal" if c == 0 else "moment"] = -g[j]
        elif src == "angular":
            entry["moment"] = -g[j]
        elif src == "actuator":
            entry["actuator"] = -g[j]
    return out


def loaded_error(robot, pose, clearances, load: dict, inner: int = 8, outer: int = 6, tol: float = 1e-13):
    """The exact loaded pose error ``(3,)`` [mm, mm, rad] at ``pose`` (module docstring), the first-order one
    ``(3,)`` (the support point of the commanded error set in the direction ``W``) and the final
    configuration ``[[dict, x3], x3]``."""
    robot = eref.as_robot(robot)
    pose = np.asarray(pose, float)
    spec = eref.merge_specs(robot, clearances)
    G0_, vars_ = eref.error_jacobian_fd(robot, pose, spec)
    src = eref._sources(spec, vars_)
    _, arg = eref.support(G0_, src, wrench(load, pose)[None])
    first = G0_ @ arg[0]
    v = arg[0]
    q0 = eref.inverse_kinematics(robot, pose)
    disks = [s for s in src if s[0] == "disk"]
    disk_cols = [c for s in disks for c in s[2]]

    def converge_disks(v):
        for _ in range(inner):
            X = _pose(robot, pose, q0, vars_, v)
            g = wrench(load, X) @ _jacobian_at(robot, pose, q0, vars_, v, cols=disk_cols)
            new = v.copy()
            for _, eps, cols, _ in disks:
                nrm = np.hypot(*g[cols])
                new[cols] = eps * g[cols] / nrm if nrm > 0 else v[cols]
            step = np.max(np.abs(new - v)) if len(v) else 0.0
            v = new
            if step <= tol:
                break
        return v

    for _ in range(outer):
        v = converge_disks(v)
        X = _pose(robot, pose, q0, vars_, v)
        G = _jacobian_at(robot, pose, q0, vars_, v)
        _, arg = eref.support(G, src, wrench(load, X)[None])
        g = wrench(load, X) @ G
        new = v.copy()
        for kind, _, cols, _ in src:       # a vertex moves only if that gains work (ties, g ~ 0, keep theirs)
            if kind != "disk" and g[cols] @ (arg[0][cols] - v[cols]) > 1e-10 * np.sum(np.abs(g * v)):
                new[cols] = arg[0][cols]
        if np.array_equal(new, v):
            break
        v = converge_disks(new)
    ex = _pose(robot, pose, q0, vars_, v) - pose
    ex[2] = eref.wrap(ex[2])
    return ex, first, eref.flat_to_config(vars_, v)
