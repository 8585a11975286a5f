"""Clearances in a spatial calibration: the platform's first-order pose covariance and random displacements.

Each error source ``s`` of :class:`~pmaccuracy.model.spatial_sources.SpatialErrorSources` displaces the platform
by ``M_s u`` (:class:`~pmaccuracy.accuracy.spatial_bounds.Source`: ``M_s = W^-1 E_s`` ``(6, d)``, scaled by its
half-width, twists ``[v_P, w]``: the platform point's translation, mm, and the rotation, rad) with its state
``u`` in the unit segment, disc or ball (``d`` = 1, 2, 3). With the states uniform in their sets and independent
(as the planar calibration takes them), the pose covariance is

.. math::  C = \\sum_s c_d M_s M_s^T, \\qquad c_1 = 1/3,\\ c_2 = 1/4,\\ c_3 = 1/5

(the second moments of the uniform unit segment, disc and ball per axis). A reading sees it through the
device's frame: a full pose ``[R_F dp, R_F dtheta]``, a target point ``R_F (dp + dtheta x R s_k)``.
"""

from __future__ import annotations

import numpy as np

from ...model.spatial import SpatialManipulator
from ...model.spatial_sources import SpatialErrorSources
from ...numerics.spatial import rotations, rotvecs, skew
from ..spatial_bounds import error_sources_at
from .spatial_parameters import SpatialParameterVector

#: Second moment per axis of a state uniform in the unit segment (1), disc (2) and ball (3).
VARIANCE = {1: 1.0 / 3.0, 2: 1.0 / 4.0, 3: 1.0 / 5.0}


def _sources(robot: SpatialManipulator, sources: SpatialErrorSources, poses):
    """Each source's ``M_s`` ``(N, 6, d)`` at ``poses (N, 6)``; NaN rows where a pose is unreachable or singular."""
    _, info = error_sources_at(robot, sources, np.asarray(poses, dtype=float), strict=False, keep=True,
                               allow_outside=True)
    return [s.matrix for s in info["sources"]]


def clearance_covariance(robot: SpatialManipulator, sources: SpatialErrorSources, poses) -> np.ndarray:
    """The platform's pose covariance ``C`` ``(N, 6, 6)`` (module text; ``[dp mm, dtheta rad]`` in the base frame)
    at base-frame ``poses (N, 6)`` ``[p mm, rotation vector rad]``; NaN where the first-order model is undefined
    (unreachable or near-singular poses)."""
    poses = np.asarray(poses, dtype=float)
    C = np.zeros((len(poses), 6, 6))
    for M in _sources(robot, sources, poses):
        C = C + VARIANCE[M.shape[-1]] * (M @ np.swapaxes(M, -1, -2))
    return C


def _unit_states(rng: np.random.Generator, n: int, d: int) -> np.ndarray:
    """``(n, d)`` states uniform in the unit segment, disc or ball."""
    if d == 1:
        return rng.uniform(-1.0, 1.0, (n, 1))
    v = rng.standard_normal((n, d))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return v * rng.uniform(0.0, 1.0, (n, 1)) ** (1.0 / d)


def clearance_twists(robot: SpatialManipulator, sources: SpatialErrorSources, poses,
                     rng: np.random.Generator) -> np.ndarray:
    """Random platform displacements ``sum_s M_s u_s`` ``(N, 6)`` ``[dp mm, dtheta rad]`` (base frame) at
    ``poses (N, 6)``: every source's state drawn uniformly in its set, independently per pose (NaN where the
    first-order model is undefined)."""
    poses = np.asarray(poses, dtype=float)
    out = np.zeros((len(poses), 6))
    for M in _sources(robot, sources, poses):
        out = out + np.einsum("nij,nj->ni", M, _unit_states(rng, len(poses), M.shape[-1]))
    return out


def reading_map(pv: SpatialParameterVector, values, poses, target=None) -> np.ndarray:
    """``A`` ``(N, k, 6)``: a platform displacement ``[dp, dtheta]`` (base frame) moves the device's reading by
    ``A [dp, dtheta]``: ``blockdiag(R_F, R_F)`` for full poses, ``R_F [I, -[R s_k]x]`` for target ``k``
    (``target (N,)`` 0-based) of position-only data, with the frame and targets of ``values (P,)``."""
    values = np.asarray(values, dtype=float)
    poses = np.asarray(poses, dtype=float)
    RF = rotations(values[pv.frame_index][3:])
    N = len(poses)
    if pv.kind == "pose":
        A = np.zeros((N, 6, 6))
        A[:, :3, :3] = RF
        A[:, 3:, 3:] = RF
        return A
    R = rotations(np.where(np.isfinite(poses[:, 3:]), poses[:, 3:], 0.0))
    arm = np.einsum("nij,nj->ni", R, values[pv.tool_index][np.asarray(target, dtype=int)])
    return RF @ np.concatenate([np.broadcast_to(np.eye(3), (N, 3, 3)), -skew(arm)], axis=2)


def with_clearance_states(pv: SpatialParameterVector, values, poses, measured, target, sources: SpatialErrorSources,
                          rng: np.random.Generator) -> np.ndarray:
    """``measured`` ``(N, k)`` readings of the robot ``values (P,)`` at base-frame ``poses (N, 6)`` moved by random
    clearance states (:func:`clearance_twists` of that robot's geometry, a new draw per reading): a full pose's
    position by ``R_F dp`` and its orientation to ``exp([R_F dtheta]x) R_m``, a target point by
    ``R_F (dp + dtheta x R s_k)``."""
    values = np.asarray(values, dtype=float)
    poses = np.asarray(poses, dtype=float)
    robot = pv.split(values)[0]
    tw = clearance_twists(robot, sources, np.where(np.isfinite(poses), poses, 0.0), rng)
    tw = np.where(np.isfinite(tw), tw, 0.0)
    A = reading_map(pv, values, poses, target)
    out = np.array(measured, dtype=float)
    if pv.kind == "position":
        return out + np.einsum("nij,nj->ni", A, tw)
    d = np.einsum("nij,nj->ni", A, tw)
    out[:, :3] += d[:, :3]
    out[:, 3:] = rotvecs(rotations(d[:, 3:]) @ rotations(out[:, 3:]))
    return out
