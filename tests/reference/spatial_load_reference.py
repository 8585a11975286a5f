"""Independent reference for the statics and the loaded pose error of the spatial robots; tests only.

Written from the equations (``docs/guide/spatial-errors.md`` "Loads", the statics of massless legs and the
principle of virtual work); it does not import ``pmaccuracy``. It builds on :mod:`spatial_reference` (own
inverse kinematics per leg type from the TOML geometry, finite-difference Jacobians) and
:mod:`spatial_error_reference` (every error source applied as a finite displacement inside the legs'
nonlinear chains, the pose re-solved by least squares).

Statics, two ways that share no code
------------------------------------
1. **Member forces** (:func:`member_forces`): what each leg can push on the platform with, from the joints
   alone. A spherical joint transmits a force through its centre ``B``; the leg's passive joints then fix its
   direction: a 6-UPS leg (U-P-S, the prismatic's force along the leg only through the actuator) a force along
   ``u = (B - A) / |B - A|``; a 3-RPS leg a force in the plane of ``u`` and the revolute's axis ``a`` (no
   moment about the revolute axis); a 3-PRS leg a force in the plane of the rod ``n = (B - C) / |B - C|`` and
   ``a``, ``C = base + q slide``; a Delta rod (S-S, a two-force member) a force along the rod
   ``(B_j - C_j) / |B_j - C_j|`` through ``B_j``; a 3-UPU leg a force along the leg and a couple normal to
   both universal joints' crosses, i.e. normal to ``u1`` and to ``u2 = u1 x d``: along ``m = u1 x (u1 x d)``
   normalized (the sign the guide states). The six intensities solve ``sum_k lambda_k w_k = -F``.
2. **Virtual work** (:func:`actuator_efforts`): the actuators' efforts ``tau`` with ``tau . dq + F . t = 0``
   for every platform twist ``t`` the robot can make, ``dq = J_q t`` by central differences of the inverse
   kinematics, the admissible twists the null space of the constraint Jacobian (finite differences of the
   constraints: the revolute planes of the 3-RPS/3-PRS, the rotation vector of the Delta/3-UPU):
   ``tau = -(J_q N)^{-T} N^T F``. Independent of the member forces.

Loaded error
------------
:func:`loaded_first_order`: with the sensitivity ``M`` of every source variable by central differences of the
nonlinear error model, each clearance source's variables ``x_s`` (``|x_s| <= h_s``) maximize the virtual work
``F . M_s x_s``: ``x_s = h_s M_s^T F / |M_s^T F|`` (a linear function on a ball). Clearance keys only
(``radial``, ``axial``, ``tilt``, ``backlash``, ``lateral``); tolerances stay 0. :func:`loaded_nonlinear`: the
platform error with those values applied to the nonlinear chains (within ``O(c^2)`` of first order), and
:func:`random_clearance_states` for brute-force comparisons (no other state does more work to first order).
"""

from __future__ import annotations

import numpy as np

import spatial_error_reference as E
import spatial_reference as S

G0 = 9.80665
CLEARANCE_KEYS = ("radial", "axial", "tilt", "backlash", "lateral")


def load_wrench(force, moment, mass, com, gravity, R):
    """``F`` (6,): the force and moment (about P) plus the weight ``G0 mass g`` at ``P + R com``."""
    g = np.asarray(gravity, float)
    g = g / np.linalg.norm(g)
    weight = G0 * mass * g
    f = np.asarray(force, float) + weight
    m = np.asarray(moment, float) + np.cross(np.asarray(R, float) @ np.asarray(com, float), weight)
    return np.concatenate([f, m])


def _force(n, point, P):
    return np.concatenate([n, np.cross(point - P, n)])


def member_wrenches(robot, position, R):
    """(6, 6): columns the unit wrenches (about P) each member can push on the platform with, leg by leg."""
    arch = robot["architecture"]
    P = np.asarray(position, float)
    cols = []
    for leg in S.legs(robot):
        B = P + R @ leg["platform"]
        A = leg["base"]
        if arch == "6-UPS":
            cols.append(_force((B - A) / np.linalg.norm(B - A), B, P))
        elif arch == "3-RPS":
            cols += [_force((B - A) / np.linalg.norm(B - A), B, P), _force(leg["axis"], B, P)]
        elif arch == "3-PRS":
            C = A + S._prs_q(leg, B) * leg["slide"]
            cols += [_force((B - C) / np.linalg.norm(B - C), B, P), _force(leg["axis"], B, P)]
        elif arch == "3-UPU":
            d = B - A
            u1 = leg["base_axis"]
            u2 = np.cross(u1, d)
            m = np.cross(u1, u2)
            cols += [_force(d / np.linalg.norm(d), B, P), np.concatenate([np.zeros(3), m / np.linalg.norm(m)])]
        else:
            theta = S._delta_theta(leg, B)
            elbow = S._delta_elbow(leg, theta)
            for sign in (1.0, -1.0):
                Cj = elbow + sign * 0.5 * leg["spacing"] * leg["axis"]
                Bj = B + sign * 0.5 * leg["spacing"] * (R @ leg["axis"])
                cols.append(_force((Bj - Cj) / np.linalg.norm(Bj - Cj), Bj, P))
    return np.array(cols).T


def member_forces(robot, position, R, F):
    """(6,): the members' intensities (N; N mm for a 3-UPU couple) in equilibrium with the external wrench F."""
    return np.linalg.solve(member_wrenches(robot, position, R), -np.asarray(F, float))


def actuator_efforts(robot, position, R, F, h=1e-3):
    """(n,): the actuators' efforts by virtual work on the admissible twists (central differences with steps
    ``h`` and ``h / 2`` combined by Richardson extrapolation: ~1e-10 relative)."""
    return (4 * _efforts(robot, position, R, F, h / 2) - _efforts(robot, position, R, F, h)) / 3


def _efforts(robot, position, R, F, h):
    F = np.asarray(F, float)
    Jq = S.inverse_jacobian_fd(robot, position, R, h)
    if S.n_constraints(robot) == 0:
        return -np.linalg.solve(Jq.T, F)
    Jc = S.constraint_jacobian_fd(robot, position, R, h)
    _, sv, Vt = np.linalg.svd(Jc)
    N = Vt[Jc.shape[0]:].T                            # (6, 3) admissible twists
    return -np.linalg.solve((Jq @ N).T, N.T @ F)


def clearance_sources(sources):
    return [src for src in sources if src["key"] in CLEARANCE_KEYS]


def loaded_first_order(robot, clearances, position, R, F, h=1e-7):
    """``(dX (6,), s (m,), sources)``: the first-order loaded error and the source variables that give it."""
    M, sources = E.sensitivity(robot, clearances, position, R, h)
    F = np.asarray(F, float)
    s = np.zeros(M.shape[1])
    for src in clearance_sources(sources):
        cols = src["columns"]
        g = M[:, cols].T @ F
        if np.linalg.norm(g) > 0:
            s[cols] = src["half_width"] * g / np.linalg.norm(g)
    return M @ s, s, sources


def loaded_nonlinear(robot, clearances, position, R, s):
    """The nonlinear platform error twist with the source variables ``s`` applied."""
    return E.error_twist(robot, clearances, position, R, s)


def random_clearance_states(sources, n, seed=0):
    """(n, m): random states of the clearances on the boundary of their sets (tolerances 0)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        s = E.random_extreme(sources, rng)
        for src in sources:
            if src["key"] not in CLEARANCE_KEYS:
                s[src["columns"]] = 0.0
        out.append(s)
    return np.array(out)


# ---------------------------------------------------------------------------------------- wrench boxes, preload
def box_corners(center, half):
    """(64, 6): the corners of the box ``center +- half`` (every sign combination, own enumeration)."""
    signs = np.array(np.meshgrid(*[[-1.0, 1.0]] * 6, indexing="ij")).reshape(6, -1).T
    return np.asarray(center, float) + signs * np.asarray(half, float)


def loaded_errors(M, sources, Fs, threshold=0.0):
    """``(k, 6)``: the first-order loaded error (clearances only) at each wrench of ``Fs`` ``(k, 6)`` from the
    sensitivities ``M`` (6, m) of :func:`spatial_error_reference.sensitivity`: each clearance source's variables
    ``h_s g / |g|``, ``g = M_s^T F`` (undetermined sources, ``|g| <= threshold``, at 0), and ``(k, 6)`` the spread
    those undetermined sources leave (``h_s |M_s rows|``)."""
    out, spread = [], []
    for F in np.atleast_2d(Fs):
        s = np.zeros(M.shape[1])
        sp = np.zeros(6)
        for src in clearance_sources(sources):
            cols = src["columns"]
            g = M[:, cols].T @ F
            if np.linalg.norm(g) > threshold:
                s[cols] = src["half_width"] * g / np.linalg.norm(g)
            else:
                sp += src["half_width"] * np.linalg.norm(M[:, cols], axis=1)
        out.append(M @ s)
        spread.append(sp)
    return np.array(out), np.array(spread)


def smallest_preload(robot, positions_and_rotations, center, half, margin, length, direction=None):
    """``(size, P, pattern)``: the smallest constant wrench ``P`` (size ``max(|P_f|, |P_m| / length)``, or the
    smallest multiple of ``direction``) such that every member's intensity (:func:`member_forces`) keeps one sign
    with at least ``margin`` for every corner of the box, at every pose ``(p, R)`` given; own linear programs per
    sign pattern over the member wrenches (the intensities are linear in the wrench, so the corners suffice)."""
    from scipy.optimize import linprog

    corners = np.unique(box_corners(center, half), axis=0)     # a flat box repeats corners
    Ls = [-np.linalg.inv(member_wrenches(robot, p, R)) for p, R in positions_and_rotations]   # lambda = L F
    scale = np.array([1.0, 1.0, 1.0, length, length, length])
    best = None
    for pattern in np.array(np.meshgrid(*[[1.0, -1.0]] * 6, indexing="ij")).reshape(6, -1).T:
        A, b = [], []
        for L in Ls:
            for F in corners:          # pattern_k (L (P + F))_k >= margin
                A.append(-(pattern[:, None] * L))
                b.append(-(margin - pattern * (L @ F)))
        A, b = np.vstack(A), np.concatenate(b)
        if direction is None:
            n = 7
            A_ub = np.vstack([np.column_stack([A, np.zeros(len(A))]),
                              np.column_stack([np.diag(1 / scale), -np.ones(6)]),
                              np.column_stack([-np.diag(1 / scale), -np.ones(6)])])
            b_ub = np.concatenate([b, np.zeros(12)])
        else:
            n = 1
            A_ub, b_ub = A @ np.asarray(direction, float)[:, None], b
        res = linprog(np.eye(n)[-1], A_ub=A_ub, b_ub=b_ub,
                      bounds=[(None, None)] * 6 + [(0, None)] if n == 7 else [(0, None)], method="highs")
        if res.status == 0 and (best is None or res.fun < best[0] - 1e-12):
            P = res.x[:6] if n == 7 else res.x[0] * np.asarray(direction, float)
            best = (float(res.fun), P, pattern)
    return best
