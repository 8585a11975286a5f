"""Independent reference model of the planar 3-PPR manipulator, shared by the tests.

An independent re-derivation of Eq. 1, 2, 4a and 6-8 of the paper, written from
the paper and deliberately not using the library's internals (only ``Leg`` and
``Manipulator`` are used, as containers of the geometry). ``test_bounds``,
``test_nonlinear`` and ``test_error_model`` use it as the reference the library
is checked against.

* Eq. 1, the loop equation of leg i:
  ``p = a_i h_i + s_i u_i + d_i v_i + l_i w_i + rho_i n_i + r_i k_i`` with
  ``h = vec(alpha)``, ``u = vec(alpha + beta)``, ``v = vec(alpha + beta + gamma)``,
  ``w = vec(alpha + beta + gamma + theta)``, ``k = vec(phi + psi)``
  (:func:`directions`, :func:`solve_loop_closure`).
* Eq. 2, the inverse kinematics ``s_i, l_i`` (:func:`own_ik`).
* Eq. 4a, the forward Jacobian ``A`` with rows ``[w_i^T E^T, -r_i w_i^T k_i]``
  (:func:`own_A`, :func:`well_conditioned`).
* Eq. 6-8 / Sec. 4.2, the clearance displacements entering the loop equations
  (:func:`displace`).

Units: lengths in mm, angles in rad; a pose is ``[x, y, phi]`` (mm, mm, rad).
Leg parameters are held in a dict ``p`` mapping each name of :data:`PARAMS` to
an array ``(3,)`` (:func:`leg_params`).
"""

from __future__ import annotations

import numpy as np

from pmaccuracy.model.manipulator import Leg, Manipulator

#: Names of the geometric parameters of one leg (a, d, r in mm; the angles in rad).
PARAMS = ("a", "alpha", "beta", "gamma", "theta", "d", "r", "psi")


def vec(t):
    """Unit vectors ``[cos t, sin t]``: angles ``(...)`` (rad) -> ``(..., 2)``."""
    t = np.asarray(t, float)
    return np.stack([np.cos(t), np.sin(t)], axis=-1)


def rot90(x):
    """E x with E = [[0, -1], [1, 0]]: vectors ``(..., 2)`` -> ``(..., 2)`` turned by +90 deg."""
    x = np.asarray(x, float)
    return np.stack([-x[..., 1], x[..., 0]], axis=-1)


def leg_params(robot: Manipulator) -> dict[str, np.ndarray]:
    """The parameters of :data:`PARAMS` of the three legs, each an array ``(3,)`` (mm, rad)."""
    return {k: np.array([getattr(leg, k) for leg in robot.legs], float) for k in PARAMS}


def directions(p):
    """Unit vectors ``h, u, v, w`` of Eq. 1, each ``(3, 2)`` (one row per leg), from the angles of ``p``."""
    h = vec(p["alpha"])
    u = vec(p["alpha"] + p["beta"])
    v = vec(p["alpha"] + p["beta"] + p["gamma"])
    w = vec(p["alpha"] + p["beta"] + p["gamma"] + p["theta"])
    return h, u, v, w


def own_ik(p, pose):
    """Inverse kinematics (Eq. 2) by a 2x2 linear solve of Eq. 1 per leg.

    ``s u + l w = p - a h - d v - r k`` for the pose ``(3,)`` (mm, mm, rad);
    returns ``s, l``, each ``(3,)`` (mm).
    """
    h, u, v, w = directions(p)
    k = vec(pose[2] + p["psi"])
    s, l = np.zeros(3), np.zeros(3)
    for i in range(3):
        q = pose[:2] - p["a"][i] * h[i] - p["d"][i] * v[i] - p["r"][i] * k[i]
        s[i], l[i] = np.linalg.solve(np.column_stack([u[i], w[i]]), q)
    return s, l


def own_A(p, pose):
    """Forward Jacobian A of Eq. 4a at the pose ``(3,)``: ``(3, 3)``, rows ``[w_i^T E^T, -r_i w_i^T k_i]``.

    The first two columns are dimensionless, the third is in mm (``A [dp; dphi] = e``, dp in mm, dphi in rad).
    """
    _, _, _, w = directions(p)
    k = vec(pose[2] + p["psi"])
    return np.column_stack([rot90(w), -p["r"] * np.sum(w * k, axis=1)])


def well_conditioned(p, pose, limit=30.0):
    """Whether the 2-norm condition number of A (Eq. 4a), third column divided by the mean r_i, is below ``limit``.

    ``pose`` ``(3,)`` (mm, mm, rad); the division by the mean r (mm) makes A dimensionless.
    """
    A = own_A(p, pose)
    A[:, 2] /= np.mean(p["r"])
    return np.linalg.cond(A) < limit


def displace(p, d):
    """Clearance displacements applied to the loop equations (Sec. 4.2, Eq. 6-8).

    ``d`` maps tau_b (rad), sigma_g (mm), tau_g (rad), rho (mm) and varphi (rad) to arrays ``(3,)``.
    Returns the displaced parameters (``gamma_i + dtau_g``, ``theta_i + dtau_b``; the others
    unchanged) and the offsets ``drho_i vec(varphi_i) + dsigma_g,i E u_i`` ``(3, 2)`` (mm, base frame)
    for :func:`solve_loop_closure`: the guide's lateral play shifts the carriage normal to the rail
    (issue 9; the paper's ``delta d_i`` along ``v_i`` is the same only for gamma_i = +-90 deg).
    """
    q = dict(p)
    q["gamma"] = p["gamma"] + d["tau_g"]
    q["theta"] = p["theta"] + d["tau_b"]
    u = vec(p["alpha"] + p["beta"])
    return q, d["rho"][:, None] * vec(d["varphi"]) + d["sigma_g"][:, None] * rot90(u)


def solve_loop_closure(p, s, pose0, offsets=None, l0=None, tol=1e-14, max_iter=60):
    """Pose ``(3,)`` (mm, mm, rad) closing the six loop equations of Eq. 1, actuators locked at ``s`` ``(3,)`` (mm).

    Newton's method on the unknowns ``x, y, phi, l_1, l_2, l_3`` (analytic 6x6
    Jacobian) started at ``pose0`` and ``l0`` (default: :func:`own_ik` of ``p`` at
    ``pose0``); ``offsets`` ``(3, 2)`` (mm, base frame) are extra per-leg vectors
    added to each loop (e.g. the revolute offsets ``rho_i n_i``). Stops when a step
    is below ``tol`` relative to the unknowns (``tol=0``: always ``max_iter``
    steps); asserts that the loop equations are then closed to 1e-10 mm.
    """
    h, u, v, w = directions(p)
    c = p["a"][:, None] * h + s[:, None] * u + p["d"][:, None] * v
    if offsets is not None:
        c = c + offsets
    z = np.concatenate([pose0, own_ik(p, pose0)[1] if l0 is None else l0])
    for _ in range(max_iter):
        k = vec(z[2] + p["psi"])
        F = (c + z[3:, None] * w + p["r"][:, None] * k - z[None, :2]).reshape(6)
        J = np.zeros((6, 6))
        for i in range(3):
            J[2 * i:2 * i + 2, 0:2] = -np.eye(2)
            J[2 * i:2 * i + 2, 2] = p["r"][i] * rot90(k[i])
            J[2 * i:2 * i + 2, 3 + i] = w[i]
        dz = np.linalg.solve(J, -F)
        z = z + dz
        if np.max(np.abs(dz)) < tol * (1 + np.max(np.abs(z))):
            break
    k = vec(z[2] + p["psi"])
    F = c + z[3:, None] * w + p["r"][:, None] * k - z[None, :2]
    assert np.max(np.abs(F)) < 1e-10, "independent loop-closure solver did not converge"
    return z[:3]


def random_robot(rng) -> Manipulator:
    """Random valid geometry, |sin(gamma + theta)| >= 0.3, ranges wide enough to never bind.

    a in [80, 250] mm, d in [0, 100] mm, r in [10, 60] mm, every angle uniform (rad);
    joint ranges [-1e4, 1e4] mm.
    """
    legs = []
    for _ in range(3):
        gamma = rng.uniform(-np.pi, np.pi)
        gt = rng.choice([-1, 1]) * rng.uniform(np.arcsin(0.3), np.pi - np.arcsin(0.3))
        legs.append(Leg(a=rng.uniform(80, 250), alpha=rng.uniform(-np.pi, np.pi), beta=rng.uniform(-np.pi, np.pi),
                        gamma=gamma, theta=gt - gamma, d=rng.uniform(0, 100), r=rng.uniform(10, 60),
                        psi=rng.uniform(-np.pi, np.pi), s_range=(-1e4, 1e4), l_range=(-1e4, 1e4)))
    return Manipulator(legs=tuple(legs), name="random")


def random_poses(robot, rng, n, xy=30.0, phi=np.pi, limit=30.0):
    """``n`` random poses ``(n, 3)`` (mm, mm, rad) where :func:`well_conditioned` (condition below ``limit``).

    x, y uniform in [-xy, xy] mm and phi uniform in [-phi, phi] rad, rejected
    until the homogenized A of Eq. 4a is well conditioned (the default limit 30 keeps
    the 1-norm condition number below 90, well inside the library's limit of 100).
    """
    p = leg_params(robot)
    out = []
    while len(out) < n:
        pose = np.array([rng.uniform(-xy, xy), rng.uniform(-xy, xy), rng.uniform(-phi, phi)])
        if well_conditioned(p, pose, limit):
            out.append(pose)
    return np.array(out)
