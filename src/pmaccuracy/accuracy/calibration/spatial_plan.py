"""D-optimal calibration poses of a spatial robot out of many candidates.

Candidates: poses around the home pose within every leg's limits (:func:`candidate_poses`).
Each candidate's block ``B_c (k, L)`` of the whitened Jacobian (:func:`.spatial_identify.measurement_jacobian`
at the nominal robot, divided by the stated sigmas; ``k`` = 6 for full poses, 3 per target for position-only
data) is taken for the parameters identifiable from a sample of the candidates, columns scaled by their RMS.
The plan maximizes ``log det M``, ``M = sum_c B_c^T B_c + eps I``, greedily: each step adds the candidate
with the largest gain ``log det(I + B_c M^-1 B_c^T)`` (the determinant lemma). ``log det`` is submodular, so a
candidate's gain can only shrink as poses are added: the gains of earlier steps are upper bounds, and only the
candidates whose bound beats the best exact gain found are evaluated again (lazy greedy: the same choice as
the plain greedy, at a fraction of its cost over 10^5 candidates).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from ...errors import ConfigError
from ...kinematics.spatial import complete_poses, inverse_kinematics
from ...model.spatial import CONTROLLED
from ...numerics.spatial import euler_xyz_to_rotvec, rotations, rotvecs
from .identifiability import analyse, observability_indices
from .spatial_identify import DEFAULT_SIGMA_MM, DEFAULT_SIGMA_RAD, SpatialCalibrationData, measurement_jacobian
from .spatial_parameters import SpatialParameterVector

#: Half-widths of the box of candidate poses: a share of the base joints' mean distance from the origin (mm)
#: and degrees.
BOX_SHARE = 0.4
BOX_DEG = 10.0


def candidate_poses(pv: SpatialParameterVector, n: int = 2000, seed: int = 0) -> np.ndarray:
    """Poses ``(<=n, 6)`` around the home pose, every leg within its limits: the controlled coordinates uniform in
    ``home +- BOX_SHARE * mean |base joint|`` (mm) and ``+- BOX_DEG`` (angles); the uncontrolled ones
    completed (:func:`~pmaccuracy.kinematics.spatial.complete_poses`)."""
    robot = pv.robot
    rng = np.random.default_rng(seed)
    home = robot.home_pose if robot.home_pose is not None else np.zeros(6)
    idx = CONTROLLED[robot.mobility]
    reach = float(np.mean([np.linalg.norm(leg.base) for leg in robot.legs]))
    half = np.array([BOX_SHARE * reach] * 3 + [np.radians(BOX_DEG)] * 3)[list(idx)]
    centre = np.concatenate([home[:3], np.zeros(3)])[list(idx)]
    c = centre + rng.uniform(-1.0, 1.0, (n, len(idx))) * half
    if robot.mobility == "6":
        poses = np.concatenate([c[:, :3], euler_xyz_to_rotvec(c[:, 3:])], axis=1)
        poses[:, 3:] = rotvecs(rotations(poses[:, 3:]) @ rotations(home[3:]))
    else:
        poses = complete_poses(robot, c, strict=False)
    ik = inverse_kinematics(robot, poses)
    ok = np.all(np.isfinite(poses), axis=1) & ik.within_limits
    return poses[ok]



#: Candidates whose Jacobian blocks are computed at once (memory: CHUNK * k * P * 8 bytes a few times).
CHUNK = 5000
#: Candidates used to decide which parameters are identifiable before the blocks are built.
SAMPLE = 1000
#: Candidates re-evaluated together in a lazy-greedy step.
BATCH = 256


def _probe(pv: SpatialParameterVector, commands: np.ndarray) -> SpatialCalibrationData:
    """Readings-to-be at ``commands``: one full pose, or every target, per command, default sigmas."""
    T = max(pv.n_targets, 1)
    k = 6 if pv.kind == "pose" else 3
    sig = np.tile([DEFAULT_SIGMA_MM] * 3 + [DEFAULT_SIGMA_RAD] * 3, (len(commands) * T, 1))[:, :k]
    return SpatialCalibrationData(tuple(map(str, range(len(sig)))), np.repeat(commands, T, axis=0),
                                  np.zeros(sig.shape), sig, np.tile(np.arange(T), len(commands)), "<candidates>")


def candidate_blocks(pv: SpatialParameterVector, poses: np.ndarray, free=None) -> tuple[np.ndarray, list[int]]:
    """Whitened Jacobian blocks ``(C, k T, L)`` of candidate ``poses (C, 6)`` for the parameters ``free``
    (default: those :func:`~.identifiability.analyse` keeps on the first :data:`SAMPLE` candidates), unscaled."""
    poses = np.asarray(poses, dtype=float)
    commands = inverse_kinematics(pv.robot, poses).q
    T = max(pv.n_targets, 1)
    if free is None:
        s = slice(0, min(SAMPLE, len(poses)))
        d = _probe(pv, commands[s])
        J = measurement_jacobian(pv, pv.nominal, d, np.repeat(poses[s], T, axis=0)) / d.sigmas[:, :, None]
        free = pv.index(analyse(pv, J.reshape(-1, len(pv.names))).identified)
    out = []
    for a in range(0, len(poses), CHUNK):
        c = commands[a:a + CHUNK]
        d = _probe(pv, c)
        J = measurement_jacobian(pv, pv.nominal, d, np.repeat(poses[a:a + CHUNK], T, axis=0))[:, :, free]
        J = J / d.sigmas[:, :, None]
        out.append(J.reshape(len(c), -1, len(free)))
    return np.concatenate(out), list(free)


def lazy_d_optimal(B: np.ndarray, n_poses: int) -> np.ndarray:
    """Indices ``(n_poses,)`` of blocks ``B (C, k, L)`` chosen greedily for ``log det(sum B^T B + eps I)``
    (module docstring: lazy evaluation of the gains, the same choice as the plain greedy)."""
    C, k, L = B.shape
    if not k * n_poses > L:
        raise ConfigError(f"{n_poses} poses give {k * n_poses} residuals for {L} identifiable parameters: plan at "
                          f"least {L // k + 1} poses", key="n_poses")
    if n_poses > C:
        raise ConfigError(f"only {C} candidate poses for {n_poses} poses asked", key="n_poses")
    eps = 1e-6 * float(np.mean(np.einsum("cij,cij->c", B, B)))
    M = eps * np.eye(L)
    eye = np.eye(k)

    def gains(idx, Minv):
        out = np.empty(len(idx))
        for a in range(0, len(idx), CHUNK):
            Bi = B[idx[a:a + CHUNK]]
            P = (Bi.reshape(-1, L) @ Minv).reshape(Bi.shape)
            out[a:a + CHUNK] = np.linalg.slogdet(np.einsum("cil,cjl->cij", P, Bi) + eye)[1]
        return out

    bound = np.full(C, np.inf)
    chosen: list[int] = []
    taken = np.zeros(C, dtype=bool)
    for _ in range(n_poses):
        Minv = np.linalg.inv(M)
        open_ = np.flatnonzero(~taken)
        top = open_[np.argsort(-bound[open_])[:BATCH]]
        exact = gains(top, Minv)
        bound[top] = exact
        rest = np.setdiff1d(open_, top, assume_unique=True)
        if rest.size and exact.max() < bound[rest].max():     # inconclusive: refresh every bound
            bound[open_] = gains(open_, Minv)
            best = int(open_[np.argmax(bound[open_])])
        else:
            best = int(top[np.argmax(exact)])
        chosen.append(best)
        taken[best] = True
        bound[best] = -np.inf
        M = M + B[best].T @ B[best]
    return np.array(chosen)


@dataclass(frozen=True)
class SpatialPlan:
    """Result of :func:`plan_spatial_poses`.

    Attributes
    ----------
    poses : ndarray ``(N, 6)``
        Chosen poses (base frame, ``[p mm, rotvec rad]``).
    commands : ndarray ``(N, n)``
        The nominal robot's actuator values there.
    indices : ndarray ``(N,)``
        Into the candidates.
    index : dict
        ``O1``-``O4`` and ``condition`` of the plan (:func:`~.identifiability.observability_indices`).
    random_index : dict
        The same for random choices of N candidates (mean of 5 draws).
    n_candidates : int
        Candidates considered.
    """

    poses: np.ndarray
    commands: np.ndarray
    indices: np.ndarray
    index: dict
    random_index: dict
    n_candidates: int


def _indices(B: np.ndarray, sel) -> dict:
    J = B[sel].reshape(-1, B.shape[-1])
    s = np.linalg.svd(J, compute_uv=False)
    o = observability_indices(s, J.shape[0])
    return dict(O1=o[0], O2=o[1], O3=o[2], O4=o[3], condition=float(s[0] / s[-1]) if s[-1] > 0 else float("inf"))


def plan_spatial_poses(pv: SpatialParameterVector, n_poses: int, candidates=None, *, n_candidates: int = 20000,
                       seed: int = 0) -> SpatialPlan:
    """Choose ``n_poses`` of ``candidates (C, 6)`` (default: ``n_candidates`` drawn by
    :func:`candidate_poses`) D-optimally (module docstring) for the readings of ``pv``'s kind."""
    cand = candidate_poses(pv, n_candidates, seed=seed) if candidates is None else np.asarray(candidates, float)
    with threadpool_limits(limits=1, user_api="blas"):   # see identify_spatial
        return _plan(pv, n_poses, cand, seed)


def _plan(pv, n_poses, cand, seed) -> SpatialPlan:
    B, _ = candidate_blocks(pv, cand)
    B = B / np.sqrt(np.mean(B ** 2, axis=(0, 1)) * B.shape[1])
    sel = lazy_d_optimal(B, n_poses)
    rng = np.random.default_rng(seed)
    draws = [_indices(B, rng.choice(len(B), n_poses, replace=False)) for _ in range(5)]
    random_index = {key: float(np.mean([d[key] for d in draws])) for key in draws[0]}
    poses = cand[sel]
    return SpatialPlan(poses=poses, commands=inverse_kinematics(pv.robot, poses).q, indices=sel,
                       index=_indices(B, sel), random_index=random_index, n_candidates=len(B))
