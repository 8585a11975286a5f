"""Independent reference for a planar serial arm under load (written apart from pmaccuracy.accuracy.serial_loads).

Everything here uses 3x3 homogeneous matrices and plain loops over one configuration at a time.

* :func:`frames`: the nominal joint geometry from the joint table (guide, docs/guide/formats.md "Planar serial arms": joint k turns
  the frame by its offset, an R joint also by its value; the origin then moves along the new x-axis by the
  link length, plus the value for a P joint). Returns per joint the centre ``c_k``, the direction ``d_k``,
  the block centre ``b_k`` (carriage: ``c_k + q_k d_k``; bushing: ``c_k``) and the end frame matrix.
* :func:`displaced_end`: the end pose with the error sources at given values, each a rigid motion of the part
  beyond its joint defined on the nominal geometry, ``T = D_1 D_2 ... D_n`` applied to the nominal end frame;
  joint k's motion ``D_k = M_radial M_position M_direction M_actuator M_angular M_shift M_tilt M_length``
  (rightmost acts first: the order stated in the module under test).
* :func:`first_order_effect`: ``dX`` per unit of a source value, by central differences of :func:`displaced_end`.
* :func:`source_vertices`: the extreme values of one source's set (segment: ``+-eps``; guide: the rhombus
  vertices ``(+-eps, 0)``, ``(0, +-2 eps / L)``).
"""

from __future__ import annotations

import math

import numpy as np


def rot(t: float) -> np.ndarray:
    return np.array([[math.cos(t), -math.sin(t), 0.0], [math.sin(t), math.cos(t), 0.0], [0.0, 0.0, 1.0]])


def trans(x: float, y: float) -> np.ndarray:
    return np.array([[1.0, 0.0, x], [0.0, 1.0, y], [0.0, 0.0, 1.0]])


def rot_about(c: np.ndarray, t: float) -> np.ndarray:
    return trans(c[0], c[1]) @ rot(t) @ trans(-c[0], -c[1])


def frames(joints: list[dict], q: np.ndarray):
    """``joints``: dicts with ``type``, ``length``, ``offset`` (rad), ``block`` (``carriage``/``bushing``)."""
    H = np.eye(3)
    out = []
    for jt, qk in zip(joints, q):
        c = H[:2, 2].copy()
        H = H @ rot(jt["offset"] + (qk if jt["type"] == "R" else 0.0))
        d = H[:2, 0].copy()
        b = c + qk * d if (jt["type"] == "P" and jt.get("block", "carriage") == "carriage") else c
        out.append((c, d, b))
        H = H @ trans(jt["length"] + (qk if jt["type"] == "P" else 0.0), 0.0)
    return out, H


def pose(H: np.ndarray) -> np.ndarray:
    return np.array([H[0, 2], H[1, 2], math.atan2(H[1, 0], H[0, 0])])


def displaced_end(joints: list[dict], q: np.ndarray, values: dict) -> np.ndarray:
    """End pose [mm, mm, rad] with sources ``values[(k, key)]`` (k 0-based; lateral ``(sigma, tau)``, disks
    ``(dx, dy)``, others scalars)."""
    geo, H = frames(joints, q)
    T = np.eye(3)
    for k, (jt, (c, d, b)) in enumerate(zip(joints, geo)):
        e = np.array([-d[1], d[0]])
        D = np.eye(3)
        v = lambda key: values.get((k, key))     # noqa: E731
        if v("radial") is not None:
            D = D @ trans(*v("radial"))
        if v("position") is not None:
            D = D @ trans(*v("position"))
        if v("direction") is not None:
            D = D @ rot_about(c, v("direction"))
        if v("actuator") is not None:
            D = D @ (rot_about(c, v("actuator")) if jt["type"] == "R" else trans(*(v("actuator") * d)))
        if v("angular") is not None:
            D = D @ rot_about(b, v("angular"))
        if v("lateral") is not None:
            sigma, tau = v("lateral")
            D = D @ trans(*(sigma * e)) @ rot_about(b, tau)
        if v("length") is not None:
            D = D @ trans(*(v("length") * d))
        T = T @ D
    out = pose(T @ H)
    nominal = pose(H)
    out[2] = nominal[2] + math.remainder(out[2] - nominal[2], 2 * math.pi)
    return out


def first_order_effect(joints, q, key: tuple, value, step: float = 1e-3) -> np.ndarray:
    """``dX`` of the source ``key`` at ``value`` to first order: central differences of :func:`displaced_end`
    in the scale ``s`` of ``s * value`` (``(X(s v) - X(-s v)) / (2 s)``)."""
    v = np.asarray(value, dtype=float)
    plus = displaced_end(joints, q, {key: step * v})
    minus = displaced_end(joints, q, {key: -step * v})
    return (plus - minus) / (2 * step)


def source_vertices(key: str, half: float, block_length: float) -> list:
    """The extreme values of one source's set (disks excluded)."""
    if key == "lateral":
        return [np.array([half, 0.0]), np.array([-half, 0.0]), np.array([0.0, 2 * half / block_length]),
                np.array([0.0, -2 * half / block_length])]
    return [half, -half]


def jacobian(forward, q: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """``(3, n)``: central differences of ``forward(q)`` (an end pose [mm, mm, rad])."""
    cols = []
    for k in range(len(q)):
        dq = np.zeros(len(q))
        dq[k] = step
        cols.append((forward(q + dq) - forward(q - dq)) / (2 * step))
    return np.stack(cols, axis=-1)
