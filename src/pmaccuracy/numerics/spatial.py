"""Screws in space: twists, wrenches, line wrenches, rotations and segment distances, over batches.

Conventions (one vocabulary for every spatial module, stated in the guide, ``docs/guide/spatial.md``):

* a **twist** is ``t = [v, w]``, shape ``(..., 6)``: the velocity of the platform's reference point P (mm/s) and
  the angular velocity (rad/s), both in the base frame; position first, as the planar ``[dx, dy, dphi]``;
* a **wrench** is ``[f, m]``, shape ``(..., 6)``: a force and its moment about P; its power on a twist is
  ``f . v + m . w`` (:func:`power`);
* a **pose** is ``[p, r]``, shape ``(..., 6)``: the position of P (mm) and the rotation vector ``r`` (rad) of the
  platform's orientation ``R = exp([r]x)`` (``scipy.spatial.transform.Rotation.from_rotvec``);
* a small displacement ``eps t`` moves ``p -> p + eps v`` and ``R -> exp(eps [w]x) R`` (:func:`displace`).

A scalar closure equation ``g(pose) = 0`` that involves a platform point ``B = p + R b`` only through
``n . B`` has the derivative ``dg = n . (v + w x (B - p)) = line_wrench(n, B - p) . t`` along a twist: the
wrench of a unit force along ``n`` through ``B`` (:func:`line_wrench`). Every Jacobian of the spatial
kinematics is a stack of such wrenches (Modern Robotics, Ch. 8 and 7: reciprocal screws).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def skew(v: np.ndarray) -> np.ndarray:
    """The matrix ``[v]x`` with ``[v]x u = v x u``: ``(..., 3) -> (..., 3, 3)``.

    >>> skew([0.0, 0.0, 1.0]) @ [1.0, 0.0, 0.0]
    array([0., 1., 0.])
    """
    v = np.asarray(v, dtype=float)
    z = np.zeros_like(v[..., 0])
    return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1),
                     np.stack([v[..., 2], z, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], z], -1)], -2)


def normalize(v: np.ndarray, axis: int = -1) -> np.ndarray:
    """``v / |v|`` along ``axis`` (NaN where ``|v| = 0``)."""
    v = np.asarray(v, dtype=float)
    n = np.linalg.norm(v, axis=axis, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / n


def line_wrench(direction: np.ndarray, arm: np.ndarray) -> np.ndarray:
    """The wrench ``[n, r x n]`` of a force ``n`` acting along a line through the point ``P + r``.

    ``direction``: ``(..., 3)`` the force ``n``; ``arm``: ``(..., 3)`` the vector ``r`` from P to any point of the
    line (mm). Returns ``(..., 6)``. Its power on a twist ``[v, w]`` is ``n . (v + w x r)``: the rate of change of
    ``n . B`` for the platform point ``B = P + r``.

    >>> line_wrench([0.0, 0.0, 1.0], [100.0, 0.0, 0.0])
    array([   0.,    0.,    1.,    0., -100.,    0.])
    """
    n = np.asarray(direction, dtype=float)
    r = np.asarray(arm, dtype=float)
    return np.concatenate([np.broadcast_to(n, np.broadcast_shapes(n.shape, r.shape)), np.cross(r, n)], axis=-1)


def couple(direction: np.ndarray) -> np.ndarray:
    """The wrench ``[0, m]`` of a pure moment ``m`` (a couple): ``(..., 3) -> (..., 6)``."""
    m = np.asarray(direction, dtype=float)
    return np.concatenate([np.zeros_like(m), m], axis=-1)


def power(wrench: np.ndarray, twist: np.ndarray) -> np.ndarray:
    """The reciprocal product (power) ``f . v + m . w`` of wrenches and twists ``(..., 6)`` -> ``(...)``."""
    return np.sum(np.asarray(wrench, dtype=float) * np.asarray(twist, dtype=float), axis=-1)


def rotations(rotvec: np.ndarray) -> np.ndarray:
    """Rotation matrices ``exp([r]x)`` of rotation vectors: ``(..., 3) -> (..., 3, 3)`` (scipy ``Rotation``)."""
    r = np.asarray(rotvec, dtype=float)
    return Rotation.from_rotvec(np.array(r.reshape(-1, 3))).as_matrix().reshape(r.shape[:-1] + (3, 3))


def rotvecs(matrices: np.ndarray) -> np.ndarray:
    """Rotation vectors of rotation matrices: ``(..., 3, 3) -> (..., 3)`` (scipy ``Rotation``)."""
    m = np.asarray(matrices, dtype=float)
    return Rotation.from_matrix(np.array(m.reshape(-1, 3, 3))).as_rotvec().reshape(m.shape[:-2] + (3,))


def euler_xyz_to_rotvec(angles: np.ndarray, degrees: bool = False) -> np.ndarray:
    """Rotation vectors of roll, pitch, yaw as **extrinsic x-y-z** angles: ``(..., 3) -> (..., 3)``.

    ``R = Rz(yaw) Ry(pitch) Rx(roll)``, scipy's ``Rotation.from_euler("xyz", ...)`` (lower case: extrinsic).

    >>> np.round(euler_xyz_to_rotvec([0.0, 0.0, 90.0], degrees=True), 6)
    array([0.      , 0.      , 1.570796])
    """
    a = np.asarray(angles, dtype=float)
    return Rotation.from_euler("xyz", np.array(a.reshape(-1, 3)), degrees=degrees).as_rotvec().reshape(a.shape)


def rotvec_to_euler_xyz(rotvec: np.ndarray, degrees: bool = False) -> np.ndarray:
    """Roll, pitch, yaw (extrinsic x-y-z) of rotation vectors: the inverse of :func:`euler_xyz_to_rotvec`."""
    r = np.asarray(rotvec, dtype=float)
    return Rotation.from_rotvec(np.array(r.reshape(-1, 3))).as_euler("xyz", degrees=degrees).reshape(r.shape)


def euler_xyz_rates(angles: np.ndarray) -> np.ndarray:
    """Angular velocities per unit rate of extrinsic x-y-z roll, pitch, yaw, as the columns of ``(..., 3, 3)``:
    ``R = Rz(yaw) Ry(pitch) Rx(roll)`` turns with ``Rz Ry e_x``, ``Rz e_y`` and ``e_z`` (base frame).

    >>> euler_xyz_rates(np.zeros(3))
    array([[ 1., -0.,  0.],
           [ 0.,  1.,  0.],
           [-0.,  0.,  1.]])
    """
    angles = np.asarray(angles, dtype=float)
    pitch, yaw = angles[..., 1], angles[..., 2]
    cp, sp, cy, sy = np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    z, o = np.zeros_like(pitch), np.ones_like(pitch)
    return np.stack([np.stack([cy * cp, sy * cp, -sp], -1), np.stack([-sy, cy, z], -1), np.stack([z, z, o], -1)],
                    axis=-1)


def displace(poses: np.ndarray, twists: np.ndarray) -> np.ndarray:
    """Poses moved by small displacements: ``p + v``, ``R -> exp([w]x) R`` (both ``(..., 6)``)."""
    poses = np.asarray(poses, dtype=float)
    twists = np.asarray(twists, dtype=float)
    shape = np.broadcast_shapes(poses.shape, twists.shape)
    poses = np.array(np.broadcast_to(poses, shape).reshape(-1, 6))
    twists = np.array(np.broadcast_to(twists, shape).reshape(-1, 6))
    rot = Rotation.from_rotvec(twists[:, 3:]) * Rotation.from_rotvec(poses[:, 3:])
    return np.concatenate([poses[:, :3] + twists[:, :3], rot.as_rotvec()], axis=-1).reshape(shape)


def segment_distance(p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
    """Shortest distance between the segments ``p0 p1`` and ``q0 q1``, ``(..., 3)`` each -> ``(...)``.

    Minimizes ``|r + s d1 - t d2|`` (``d1 = p1 - p0``, ``d2 = q1 - q0``, ``r = p0 - q0``) over ``s, t`` in
    ``[0, 1]`` by the classic clamped construction (Ericson, *Real-Time Collision Detection*, Sec. 5.1.9): ``s``
    the lines' closest parameter clamped to ``[0, 1]`` (0 for parallel lines), ``t = (b s + f) / e``; where
    ``t`` leaves ``[0, 1]`` it is clamped and ``s`` recomputed for it and clamped (``a = d1.d1``, ``b = d1.d2``,
    ``c = d1.r``, ``e = d2.d2``, ``f = d2.r``). The quadratic is convex, so this is the minimum; written over
    arrays with one norm at the end (degenerate segments are points).

    >>> float(segment_distance([0, 0, 0], [1, 0, 0], [0.5, 1, -1], [0.5, 1, 1]))
    1.0
    """
    # components first (3, ...): every operation below runs along contiguous arrays
    p0, p1, q0, q1 = (np.moveaxis(x, -1, 0) for x in np.broadcast_arrays(*(np.asarray(x, dtype=float)
                                                                           for x in (p0, p1, q0, q1))))
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0

    def dot(x, y):
        return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]

    a, e, b, c, f = dot(d1, d1), dot(d2, d2), dot(d1, d2), dot(d1, r), dot(d2, r)
    tiny = 1e-300
    with np.errstate(invalid="ignore", divide="ignore"):
        a_ok, e_ok = a > tiny, e > tiny
        a1, e1 = np.where(a_ok, a, 1.0), np.where(e_ok, e, 1.0)
        denom = a * e - b * b
        s = np.where(denom > 1e-12 * np.maximum(a * e, tiny), np.clip((b * f - c * e) / np.where(denom > 0, denom, 1.0),
                                                                      0.0, 1.0), 0.0)
        t = np.where(e_ok, (b * s + f) / e1, 0.0)
        t_c = np.clip(t, 0.0, 1.0)
        s = np.where(t_c != t, np.clip(np.where(a_ok, (b * t_c - c) / a1, 0.0), 0.0, 1.0), s)
        s = np.where(a_ok, s, 0.0)
    gap = r + s * d1 - t_c * d2
    return np.sqrt(dot(gap, gap))
