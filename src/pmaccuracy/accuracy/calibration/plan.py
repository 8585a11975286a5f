"""Planning the calibration poses: N poses out of a candidate grid that maximize the D-optimal index.

Candidates: a grid of ``(x, y, phi)`` over the box of the robot's base points (with margin) and the
orientation range, kept where every joint of the nominal robot is within its range, the pose is regular
(:func:`pmaccuracy.kinematics.regular_mask`: condition number of ``A`` and transmission of each leg within
``max_condition``) and the pose moved by :data:`REACH_MARGIN_MM` / :data:`REACH_MARGIN_DEG` stays reachable. Each candidate's block ``J_c (3, L)`` of the whitened identification Jacobian
(:mod:`.identify`, default camera sigmas) is taken at the nominal robot for the parameters identifiable
from all candidates, columns scaled by their RMS over the candidates. Greedy D-optimal selection adds the
candidate maximizing ``log det(I_3 + J_c M^-1 J_c^T)`` (``M = sum J^T J + eps I``, the determinant
lemma), then a Fedorov exchange sweep swaps a chosen pose for a candidate while ``log det M`` grows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import ConfigError, EmptyWorkspaceError
from ...kinematics import inverse_kinematics, regular_mask
#: Calibration poses stay this far from singularities (condition number and 1/transmission): a pose near
#: one is where a small parameter error moves the platform out of the nominal robot's reach.
PLAN_MAX_CONDITION = 20.0
#: ... and every pose moved by this much (mm, deg) along x, y or phi stays within the nominal legs' reach.
REACH_MARGIN_MM = 3.0
REACH_MARGIN_DEG = 2.0
from .data import DEFAULT_ACCURACY_DEG, DEFAULT_ACCURACY_MM, CalibrationData
from .identifiability import analyse, observability_indices
from .identify import jacobian, serial_jacobian, whitening
from .parameters import ParameterVector, SerialParameterVector, commands_for, serial_poses
from ...model.plausibility import check_orientations


def candidate_poses(pv: ParameterVector, n: int = 22, phi_range: tuple[float, float] = (-0.35, 0.35),
                    n_phi: int = 21, max_condition: float = PLAN_MAX_CONDITION) -> np.ndarray:
    """Candidate poses ``(C, 3)`` (mm, mm, rad): an ``n x n x n_phi`` grid kept within the joint limits and
    away from singularities (module docstring)."""
    robot = pv.robot
    pts = np.vstack([robot.base_points])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    margin = 0.1 * max(1.0, float(np.max(hi - lo)))
    xs = np.linspace(lo[0] - margin, hi[0] + margin, n)
    ys = np.linspace(lo[1] - margin, hi[1] + margin, n)
    ph = np.linspace(phi_range[0], phi_range[1], n_phi)
    X, Y, P = np.meshgrid(xs, ys, ph, indexing="ij")
    poses = np.stack([X.ravel(), Y.ravel(), P.ravel()], axis=-1)
    ik = inverse_kinematics(robot, poses)
    ok = np.asarray(ik.within_limits)
    poses = poses[ok]
    if len(poses):
        poses = poses[regular_mask(robot, poses, max_condition)]
    for k, h in ((0, REACH_MARGIN_MM), (1, REACH_MARGIN_MM), (2, np.radians(REACH_MARGIN_DEG))):
        for sign in (1.0, -1.0):
            moved = poses.copy()
            moved[:, k] += sign * h
            q = commands_for(pv, pv.nominal, moved)
            poses = poses[np.all(np.isfinite(q), axis=1)]
    if len(poses) == 0:
        raise EmptyWorkspaceError("no candidate pose within the joint ranges and away from singularities")
    return poses


@dataclass(frozen=True)
class Plan:
    """Chosen poses ``(N, 3)`` (robot frame = nominal measurement frame; mm, mm, rad), their ``commands
    (N, 3)``, the ``indices`` into the candidates, the D-optimal index ``O1`` of the plan, and the same for
    ``random`` (mean over 20 draws) and ``grid`` (evenly spaced candidates) choices of the same N; ``O2``-
    ``O4`` and ``condition`` of the plan."""

    poses: np.ndarray
    commands: np.ndarray
    indices: np.ndarray
    index: dict
    random_index: dict
    grid_index: dict
    n_candidates: int

    def __repr__(self) -> str:
        return (f"Plan({len(self.poses)} poses of {self.n_candidates}: O1 {self.index['O1']:.4g} vs random "
                f"{self.random_index['O1']:.4g}, grid {self.grid_index['O1']:.4g})")


def _blocks(pv: ParameterVector, candidates: np.ndarray) -> tuple[np.ndarray, list[int]]:
    cmd = commands_for(pv, pv.nominal, candidates)
    sig = np.tile([DEFAULT_ACCURACY_MM, DEFAULT_ACCURACY_MM, np.radians(DEFAULT_ACCURACY_DEG)], (len(cmd), 1))
    data = CalibrationData(tuple(map(str, range(len(cmd)))), cmd, candidates, sig, "<candidates>")
    W = whitening(pv, pv.nominal, data)
    J = jacobian(pv, pv.nominal.copy(), data, W)
    ident = analyse(pv, J)
    free = pv.index(ident.identified)
    J = J[:, free]
    J = J / np.sqrt(np.mean(J ** 2, axis=0) * 3)
    return J.reshape(len(cmd), 3, -1), free


def _indices(B: np.ndarray, sel: np.ndarray) -> dict:
    J = B[sel].reshape(-1, B.shape[-1])
    s = np.linalg.svd(J, compute_uv=False)
    o = observability_indices(s, J.shape[0])
    return dict(O1=o[0], O2=o[1], O3=o[2], O4=o[3], condition=float(s[0] / s[-1]) if s[-1] > 0 else float("inf"))


def d_optimal(B: np.ndarray, n_poses: int, exchange: bool = True) -> np.ndarray:
    """Indices ``(n_poses,)`` of the candidates (blocks ``B (C, 3, L)``) chosen greedily D-optimally, then
    improved by Fedorov exchange sweeps (module docstring); :class:`ConfigError` for too few or too many."""
    C, _, L = B.shape
    if not 3 * n_poses > L:
        raise ConfigError(f"{n_poses} poses give {3 * n_poses} residuals for {L} identifiable parameters: plan at "
                          f"least {L // 3 + 1} poses", key="--poses")
    if n_poses > C:
        raise ConfigError(f"only {C} candidate poses for {n_poses} poses asked", key="--poses")
    eps = 1e-6 * float(np.mean(np.einsum("cij,cij->c", B, B)))
    M = eps * np.eye(L)
    chosen: list[int] = []
    avail = np.ones(C, dtype=bool)
    for _ in range(n_poses):
        Minv = np.linalg.inv(M)
        S = np.einsum("cil,cjl->cij", B @ Minv, B) + np.eye(3)
        gain = np.linalg.slogdet(S)[1]
        gain[~avail] = -np.inf
        c = int(np.argmax(gain))
        chosen.append(c)
        avail[c] = False
        M = M + B[c].T @ B[c]
    if exchange:
        for _ in range(2):
            improved = False
            for k in range(n_poses):
                c_old = chosen[k]
                M_minus = M - B[c_old].T @ B[c_old]
                Minv = np.linalg.inv(M_minus)
                S = np.einsum("cil,cjl->cij", B @ Minv, B) + np.eye(3)
                gain = np.linalg.slogdet(S)[1]
                gain[~avail] = -np.inf
                c = int(np.argmax(gain))
                old_gain = np.linalg.slogdet(np.eye(3) + B[c_old] @ Minv @ B[c_old].T)[1]
                if gain[c] > old_gain + 1e-9:
                    chosen[k] = c
                    avail[c], avail[c_old] = False, True
                    M = M_minus + B[c].T @ B[c]
                    improved = True
            if not improved:
                break
    return np.array(chosen)


def plan_poses(pv: ParameterVector, n_poses: int, candidates: np.ndarray | None = None, *, seed: int = 0,
               exchange: bool = True) -> Plan:
    """Choose ``n_poses`` of ``candidates`` (default :func:`candidate_poses`) D-optimally (module docstring).

    Raises :class:`~pmaccuracy.errors.ConfigError` when fewer poses than needed for the identifiable
    parameters are asked or more than the candidates.
    """
    if isinstance(pv, SerialParameterVector):   # candidates: the arm's commands (C, n)
        return _plan_serial(pv, n_poses, candidates, seed=seed, exchange=exchange)
    if candidates is not None:
        check_orientations(candidates, "candidates", poses=True)
    cand = candidate_poses(pv) if candidates is None else np.asarray(candidates, dtype=float)
    B, free = _blocks(pv, cand)
    sel = d_optimal(B, n_poses, exchange)
    C = len(B)
    random_index, grid_index = _compared(B, n_poses, seed)
    poses = cand[sel]
    return Plan(poses=poses, commands=commands_for(pv, pv.nominal, poses), indices=sel, index=_indices(B, sel),
                random_index=random_index, grid_index=grid_index, n_candidates=C)


def _compared(B: np.ndarray, n_poses: int, seed: int) -> tuple[dict, dict]:
    """Indices of random (mean of 20 draws) and evenly spaced choices of ``n_poses`` candidates."""
    C = len(B)
    rng = np.random.default_rng(seed)
    rand = [_indices(B, rng.choice(C, n_poses, replace=False)) for _ in range(20)]
    random_index = {k: float(np.mean([r[k] for r in rand])) for k in rand[0]}
    grid = np.unique(np.linspace(0, C - 1, n_poses).round().astype(int))
    return random_index, _indices(B, grid)


def candidate_commands(pv: SerialParameterVector, n: int = 4000, seed: int = 0) -> np.ndarray:
    """Candidate commands ``(n, J)`` of a serial arm: seeded uniform draws within each joint's range (an R
    joint without limits: a full turn), rad / mm. :class:`ConfigError` for a P joint without limits."""
    lo, hi = [], []
    for k, j in enumerate(pv.robot.joints, start=1):
        a, b = j.range
        if j.kind == "R":
            a, b = (a, b) if np.isfinite(a) and np.isfinite(b) and b - a < 2 * np.pi else (-np.pi, np.pi)
        elif not (np.isfinite(a) and np.isfinite(b)):
            raise ConfigError(f"{pv.robot.label(k)}: a prismatic joint needs a finite range to plan poses",
                              key=f"joints[{k}].range")
        lo.append(a)
        hi.append(b)
    return np.random.default_rng(seed).uniform(lo, hi, size=(n, len(lo)))


def _plan_serial(pv: SerialParameterVector, n_poses: int, candidates=None, *, seed: int = 0,
                 exchange: bool = True) -> Plan:
    cand = candidate_commands(pv, seed=seed) if candidates is None else np.asarray(candidates, dtype=float)
    if cand.ndim != 2 or cand.shape[1] != pv.robot.n:
        raise ConfigError(f"candidates of a serial arm are its commands, shape (C, {pv.robot.n})", key="candidates")
    sig = np.tile([DEFAULT_ACCURACY_MM, DEFAULT_ACCURACY_MM, np.radians(DEFAULT_ACCURACY_DEG)], (len(cand), 1))
    data = CalibrationData(tuple(map(str, range(len(cand)))), cand, serial_poses(pv, pv.nominal, cand), sig,
                           "<candidates>")
    J = serial_jacobian(pv, pv.nominal, data)
    free = pv.index(analyse(pv, J).identified)
    J = J[:, free]
    B = (J / np.sqrt(np.mean(J ** 2, axis=0) * 3)).reshape(len(cand), 3, -1)
    sel = d_optimal(B, n_poses, exchange)
    random_index, grid_index = _compared(B, n_poses, seed)
    return Plan(poses=serial_poses(pv, pv.nominal, cand[sel]), commands=cand[sel], indices=sel,
                index=_indices(B, sel), random_index=random_index, grid_index=grid_index, n_candidates=len(cand))


def _compared_plan(pv, n: int, candidates: np.ndarray, seed: int) -> Plan:
    """The plan of as many poses as a measured set (:func:`pose_set_indices`); too few measured points is a
    :class:`ConfigError` with the key ``poses`` (the measured set's, not the plan's ``--poses``)."""
    try:
        return plan_poses(pv, n, candidates, seed=seed)
    except ConfigError as exc:
        if exc.key != "--poses":
            raise
        raise ConfigError(f"{n} measured points are too few to be judged beside a plan of as many ({exc.message})",
                          key="poses") from None


def pose_set_indices(pv: ParameterVector | SerialParameterVector, poses: np.ndarray,
                     candidates: np.ndarray | None = None, *, seed: int = 0, commands: np.ndarray | None = None) -> dict:
    """Observability indices of the measured ``poses (N, 3)`` (robot frame; mm, mm, rad) beside those of the
    choices :func:`plan_poses` compares, for the same N out of ``candidates`` (default
    :func:`candidate_poses`).

    Every set is judged on the plan's scale: the whitened identification Jacobian at the nominal robot with
    the default camera sigmas, restricted to the parameters identifiable from all candidates, columns scaled by
    their RMS over the candidates (module docstring), so the indices of the measured poses compare with
    :attr:`Plan.index` as they are. Returns ``{"poses": {...}, "planned": {...}, "random": {...}, "grid": {...}}``,
    each ``{"O1", "O2", "O3", "O4", "condition"}`` (``random``: the mean of 20 draws); ``planned`` etc. are
    those of ``plan_poses(pv, N, candidates, seed=seed)``.

    A serial arm (:class:`SerialParameterVector`): its pose does not say which configuration the arm was in,
    so the set is given by its ``commands (N, n)`` (rad / mm; ``poses`` is then not used) and judged on the
    scale of :func:`plan_poses` for the arm (candidates: :func:`candidate_commands`); :class:`ConfigError`
    without ``commands``.
    """
    if isinstance(pv, SerialParameterVector):   # a serial arm: judged by its commands, not its poses
        if commands is None:
            raise ConfigError("a serial arm's pose set is judged by its commands: give commands (N, n)",
                              key="commands")
        return _serial_pose_set_indices(pv, commands, candidates, seed=seed)
    check_orientations(poses, "poses", poses=True)
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    cand = candidate_poses(pv) if candidates is None else np.asarray(candidates, dtype=float)
    plan = _compared_plan(pv, len(poses), cand, seed)
    allp = np.vstack([cand, poses])
    cmd = commands_for(pv, pv.nominal, allp)
    sig = np.tile([DEFAULT_ACCURACY_MM, DEFAULT_ACCURACY_MM, np.radians(DEFAULT_ACCURACY_DEG)], (len(cmd), 1))
    data = CalibrationData(tuple(map(str, range(len(cmd)))), cmd, allp, sig, "<poses>")
    W = whitening(pv, pv.nominal, data)
    J = jacobian(pv, pv.nominal.copy(), data, W)        # rows of a point depend on that point only
    rows = 3 * len(cand)
    free = pv.index(analyse(pv, J[:rows]).identified)
    scale = np.sqrt(np.mean(J[:rows, free] ** 2, axis=0) * 3)
    B = (J[rows:, free] / scale).reshape(len(poses), 3, -1)
    return {"poses": _indices(B, np.arange(len(poses))), "planned": dict(plan.index),
            "random": dict(plan.random_index), "grid": dict(plan.grid_index)}


def _serial_pose_set_indices(pv: SerialParameterVector, commands: np.ndarray, candidates=None, *, seed: int = 0) -> dict:
    """:func:`pose_set_indices` of a serial arm at ``commands (N, n)`` (candidates: commands too)."""
    commands = np.atleast_2d(np.asarray(commands, dtype=float))
    cand = candidate_commands(pv, seed=seed) if candidates is None else np.asarray(candidates, dtype=float)
    if commands.shape[1:] != (pv.robot.n,) or cand.ndim != 2 or cand.shape[1] != pv.robot.n:
        raise ConfigError(f"commands of a serial arm have shape (N, {pv.robot.n})", key="commands")
    plan = _compared_plan(pv, len(commands), cand, seed)
    allc = np.vstack([cand, commands])
    sig = np.tile([DEFAULT_ACCURACY_MM, DEFAULT_ACCURACY_MM, np.radians(DEFAULT_ACCURACY_DEG)], (len(allc), 1))
    data = CalibrationData(tuple(map(str, range(len(allc)))), allc, serial_poses(pv, pv.nominal, allc), sig,
                           "<poses>")
    J = serial_jacobian(pv, pv.nominal, data)           # rows of a point depend on that point only
    rows = 3 * len(cand)
    free = pv.index(analyse(pv, J[:rows]).identified)
    scale = np.sqrt(np.mean(J[:rows, free] ** 2, axis=0) * 3)
    B = (J[rows:, free] / scale).reshape(len(commands), 3, -1)
    return {"poses": _indices(B, np.arange(len(commands))), "planned": dict(plan.index),
            "random": dict(plan.random_index), "grid": dict(plan.grid_index)}
