"""Every real assembly mode of six sphere / plane closure equations (pmaccuracy.kinematics.assembly_modes).

Known counts: Dietmaier's general 6-UPS with 40 real postures (P. Dietmaier, "The Stewart-Gough platform of
general geometry can have 40 real postures", Advances in Robot Kinematics: Analysis and Control, 1998, pp. 7-16;
the numbers as given in the public solver martyushev/fkSGP, python/test1_fkSGP.py, commented block
"40 real roots by P. Dietmaier", there with squared leg lengths). Robots built from a known pose must give that
pose back; the 3-RPS with a symmetric design has four modes known in closed form; an independent multi-start
Newton (scipy.optimize.least_squares) must find nothing the homotopy misses.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from pmaccuracy.errors import PoseError
from pmaccuracy.kinematics.assembly_modes import (AssemblyModes, assembly_modes, closure_residuals, polish,
                                                  pose_to_study, study_quadrics, study_to_pose)

# Dietmaier (1998), via martyushev/fkSGP python/test1_fkSGP.py: base points X, platform points x, leg lengths.
DIETMAIER_BASE = np.array([[0, 0, 0], [1.107915, 0, 0], [0.549094, 0.756063, 0], [0.735077, -0.223935, 0.525991],
                           [0.514188, -0.526063, -0.368418], [0.590473, 0.094733, -0.205018]])
DIETMAIER_PLATFORM = np.array([[0, 0, 0], [0.542805, 0, 0], [0.956919, -0.528915, 0],
                               [0.665885, -0.353482, 1.402538], [0.478359, 1.158742, 0.107672],
                               [-0.137087, -0.235121, 0.353913]])
DIETMAIER_LENGTHS = np.array([1, 0.645275, 1.086284, 1.503439, 1.281933, 0.771071])


def dietmaier() -> list:
    return list(zip(DIETMAIER_BASE, DIETMAIER_PLATFORM, DIETMAIER_LENGTHS))


def scale_of(spheres, planes=()) -> float:
    vals = [np.linalg.norm(A) for A, _, _ in spheres] + [np.linalg.norm(b) for _, b, _ in spheres]
    vals += [L for _, _, L in spheres] + [np.linalg.norm(A) for _, A, _ in planes]
    vals += [np.linalg.norm(b) for _, _, b in planes]
    return max(vals)


def random_ups(rng: np.random.Generator, size: float = 100.0):
    """A general 6-UPS (mm) and the pose it is assembled at."""
    A = rng.uniform(-1, 1, (6, 3)) * size
    b = rng.uniform(-1, 1, (6, 3)) * size / 2
    p = rng.uniform(-0.3, 0.3, 3) * size + np.array([0, 0, size])
    R = Rotation.from_rotvec(rng.uniform(-0.6, 0.6, 3)).as_matrix()
    L = np.linalg.norm(p + b @ R.T - A, axis=1)
    return list(zip(A, b, L)), p, R


def rps(rng: np.random.Generator, *, ra: float = 100.0, rb: float = 50.0, symmetric: bool = False, p=None, R=None):
    """A 3-RPS: base points on a circle (z = 0), revolute axes tangent to it (so each leg's plane holds the
    vertical through the base point and the radial line), platform points on a circle in the platform's z = 0.
    Lengths from a pose (random unless given); returns spheres, planes, p, R."""
    ang = np.radians([90.0, 210.0, 330.0])
    if not symmetric:
        ang = ang + rng.uniform(-0.3, 0.3, 3)
    pang = np.radians([90.0, 210.0, 330.0]) + (0 if symmetric else rng.uniform(-0.3, 0.3, 3))
    A = ra * np.column_stack([np.cos(ang), np.sin(ang), np.zeros(3)])
    axes = np.column_stack([-np.sin(ang), np.cos(ang), np.zeros(3)])
    b = rb * np.column_stack([np.cos(pang), np.sin(pang), np.zeros(3)])
    if p is None:
        # a random pose moved onto the three planes by minimum-norm Gauss-Newton on their residuals (new draws
        # until it converges)
        for _ in range(50):
            R = Rotation.from_rotvec(rng.uniform(-0.4, 0.4, 3)).as_matrix()
            p = np.array([*rng.uniform(-10, 10, 2), rng.uniform(60, 140)])
            for _ in range(40):
                Rb = b @ R.T
                f = np.sum(axes * (p + Rb - A), axis=1)
                J = np.hstack([axes, np.cross(Rb, axes)])
                step = -np.linalg.pinv(J) @ f
                p = p + step[:3]
                R = Rotation.from_rotvec(step[3:]).as_matrix() @ R
            if np.max(np.abs(np.sum(axes * (p + b @ R.T - A), axis=1))) < 1e-10 and p[2] > 20:
                break
        else:
            raise AssertionError("no 3-RPS pose")
    L = np.linalg.norm(p + b @ R.T - A, axis=1)
    spheres = list(zip(A, b, L))
    planes = list(zip(axes, A, b))
    return spheres, planes, p, R


def contains(modes: AssemblyModes, p, R, tol: float) -> bool:
    dp = np.max(np.abs(modes.positions - p), axis=1)
    dR = np.max(np.abs(modes.rotations - R), axis=(1, 2))
    return bool(np.any((dp < tol) & (dR < tol)))


def check_modes(modes: AssemblyModes, spheres, planes=()) -> None:
    s = scale_of(spheres, planes)
    assert modes.failed == 0
    assert modes.positions.shape == (modes.count, 3) and modes.rotations.shape == (modes.count, 3, 3)
    r = np.abs(closure_residuals(spheres, planes, modes.positions, modes.rotations))
    assert np.all(r < 1e-9 * s)
    assert np.all(modes.residuals < 1e-9 * s)
    assert np.allclose(np.linalg.det(modes.rotations), 1.0, atol=1e-12)
    assert np.allclose(modes.rotations @ np.swapaxes(modes.rotations, 1, 2), np.eye(3), atol=1e-12)
    # distinct
    for i in range(modes.count):
        for j in range(i):
            assert (np.max(np.abs(modes.positions[i] - modes.positions[j])) > 1e-6 * s
                    or np.max(np.abs(modes.rotations[i] - modes.rotations[j])) > 1e-8)


# ---------------------------------------------------------------------------------------- formulation

def test_study_quadrics_vanish_exactly_at_poses():
    """The seven quadrics at a pose's Study parameters equal the closure residuals times e.e (= 1 here)."""
    rng = np.random.default_rng(3)
    spheres, planes, p, R = rps(rng)
    R2 = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix()
    p2 = np.array([10.0, -20.0, 80.0])
    z = pose_to_study(p2[None], R2[None])[0]
    Q = study_quadrics(spheres, planes)
    F = np.einsum("kij,i,j->k", Q, z, z)
    B = [p2 + R2 @ b for _, b, _ in spheres]
    expect = [np.sum((Bi - A) ** 2) - L * L for Bi, (A, _, L) in zip(B, spheres)]
    expect += [n @ (p2 + R2 @ b - A) for n, A, b in planes] + [0.0]
    assert np.allclose(F, expect, rtol=1e-12, atol=1e-9)
    p3, R3 = study_to_pose(z * 2.5)
    assert np.allclose(p3, p2, atol=1e-12) and np.allclose(R3, R2, atol=1e-14)


# ---------------------------------------------------------------------------------------- Dietmaier

def test_dietmaier_has_40_real_assembly_modes():
    """Dietmaier (1998): this general 6-SPS has 40 real postures, all of the 40 complex ones."""
    spheres = dietmaier()
    modes = assembly_modes(spheres)
    assert modes.paths == 128
    assert modes.finite == 40
    assert modes.count == 40
    check_modes(modes, spheres)
    assert "homotopy" in modes.method


@pytest.mark.parametrize("seed", [1, 2])
def test_dietmaier_same_modes_for_another_gamma(seed):
    a = assembly_modes(dietmaier())
    b = assembly_modes(dietmaier(), seed=seed)
    assert b.count == 40 and b.failed == 0
    for p, R in zip(a.positions, a.rotations):
        assert contains(b, p, R, 1e-9)


def test_dietmaier_in_mm_and_moved():
    """Units and frames do not matter: scaled to mm and the base frame moved, the same 40 modes."""
    shift = np.array([120.0, -40.0, 15.0])
    spheres = [(1000 * A + shift, 1000 * b, 1000 * L) for A, b, L in dietmaier()]
    modes = assembly_modes(spheres)
    assert modes.count == 40
    check_modes(modes, spheres)
    ref = assembly_modes(dietmaier())
    for p, R in zip(ref.positions, ref.rotations):
        assert contains(modes, 1000 * p + shift, R, 1e-6)


# ---------------------------------------------------------------------------------------- random 6-UPS

@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_random_ups_known_pose_is_found(seed):
    spheres, p, R = random_ups(np.random.default_rng(seed))
    modes = assembly_modes(spheres, seed=seed)
    check_modes(modes, spheres)
    assert contains(modes, p, R, 1e-7)
    assert modes.count % 2 == 0 and modes.count <= 40
    assert modes.finite == 40     # a general 6-UPS: 40 complex assembly modes (Husty 1996)


# ---------------------------------------------------------------------------------------- 3-RPS

@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_3rps_known_pose_is_found(seed):
    spheres, planes, p, R = rps(np.random.default_rng(seed))
    modes = assembly_modes(spheres, planes)
    check_modes(modes, spheres, planes)
    assert contains(modes, p, R, 1e-7)
    assert modes.count % 2 == 0 and modes.count <= 16
    assert modes.finite == 16     # a general 3-RPS: 16 complex assembly modes


def test_symmetric_3rps_closed_form_modes():
    """Equal legs L on a symmetric 3-RPS (base radius ra, platform radius rb): the platform parallel to the base
    at z = +-sqrt(L^2 - (ra - rb)^2) (R = I), and turned half a turn about z at z = +-sqrt(L^2 - (ra + rb)^2)
    (each platform point then lies on the other side of the same radial line, still in its leg's plane)."""
    ra, rb, L = 100.0, 50.0, 200.0
    h1, h2 = np.sqrt(L ** 2 - (ra - rb) ** 2), np.sqrt(L ** 2 - (ra + rb) ** 2)
    spheres, planes, _, _ = rps(None, ra=ra, rb=rb, symmetric=True, p=np.array([0, 0, h1]), R=np.eye(3))
    assert np.allclose([l for _, _, l in spheres], L)
    modes = assembly_modes(spheres, planes)
    check_modes(modes, spheres, planes)
    Rz = np.diag([-1.0, -1.0, 1.0])
    for p, R in [((0, 0, h1), np.eye(3)), ((0, 0, -h1), np.eye(3)), ((0, 0, h2), Rz), ((0, 0, -h2), Rz)]:
        assert contains(modes, np.array(p), R, 1e-7), (p, R)
    # all 16 (the number of complex solutions of a general 3-RPS, Nanua, Waldron & Murthy 1990) are real here,
    # and the design's symmetries map modes to modes: a third of a turn about z, and the mirror z -> -z
    assert modes.count == 16 and modes.finite == 16
    Rz3 = Rotation.from_euler("z", 120, degrees=True).as_matrix()
    M = np.diag([1.0, 1.0, -1.0])
    for p, R in zip(modes.positions, modes.rotations):
        assert contains(modes, Rz3 @ p, Rz3 @ R @ Rz3.T, 1e-7)
        assert contains(modes, M @ p, M @ R @ M, 1e-7)


# ---------------------------------------------------------------------------------------- multi-start

def multistart(spheres, planes, rng, starts: int) -> list:
    """Distinct real solutions found by least_squares from random poses (rotation vector, position)."""
    s = scale_of(spheres, planes)
    nS = len(spheres)
    A = np.array([a for a, _, _ in spheres] + [a for _, a, _ in planes]) / s
    b = np.array([c for _, c, _ in spheres] + [c for _, _, c in planes]) / s
    L = np.array([l for _, _, l in spheres]) / s
    n = np.array([m / np.linalg.norm(m) for m, _, _ in planes]).reshape(-1, 3)

    def fun(x):
        d = x[:3] + b @ Rotation.from_rotvec(x[3:]).as_matrix().T - A
        return np.concatenate([(np.sum(d[:nS] ** 2, axis=1) - L ** 2) / (2 * L), np.sum(n * d[nS:], axis=1)])

    found = []
    for _ in range(starts):
        w = Rotation.random(random_state=rng).as_rotvec()
        x0 = np.concatenate([rng.uniform(-2, 2, 3), w])
        sol = least_squares(fun, x0, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=300)
        if np.max(np.abs(sol.fun)) < 1e-10:
            p, R = sol.x[:3] * s, Rotation.from_rotvec(sol.x[3:]).as_matrix()
            if not any(np.max(np.abs(p - q)) < 1e-6 * s and np.max(np.abs(R - Q)) < 1e-6 for q, Q in found):
                found.append((p, R))
    return found


@pytest.mark.slow
@pytest.mark.parametrize("kind, seed", [("ups", 28), ("ups", 14), ("rps", 16)])
def test_multistart_finds_nothing_the_homotopy_misses(kind, seed):
    rng = np.random.default_rng(seed)
    if kind == "ups":
        spheres, _, _ = random_ups(rng)
        planes = []
    else:
        spheres, planes, _, _ = rps(rng)
    modes = assembly_modes(spheres, planes)
    found = multistart(spheres, planes, rng, starts=700)
    assert found
    for p, R in found:
        p2, R2, _ = polish(spheres, planes, p[None], R[None])
        assert contains(modes, p2[0], R2[0], 1e-6 * scale_of(spheres, planes)), (p, R)
    assert len(found) <= modes.count
    assert modes.count >= 6       # the robots are chosen with several real modes, so the check has teeth


def test_polish_converges_quadratically_from_nearby():
    spheres, p, R = random_ups(np.random.default_rng(7))
    p0 = p + 0.01
    R0 = Rotation.from_rotvec([1e-3, -2e-3, 1e-3]).as_matrix() @ R
    p1, R1, r = polish(spheres, [], p0[None], R0[None])
    assert r[0] < 1e-10 and np.allclose(p1[0], p, atol=1e-9) and np.allclose(R1[0], R, atol=1e-12)


# ---------------------------------------------------------------------------------------- bad input

GOOD = dietmaier()


@pytest.mark.parametrize("spheres, planes, match", [
    (GOOD[:5], None, "exactly six"),
    (GOOD, [(np.array([0, 0, 1.0]), np.zeros(3), np.zeros(3))], "exactly six"),
    (None, None, "exactly six"),
    (GOOD[:5] + [(np.array([np.nan, 0, 0]), np.zeros(3), 1.0)], None, "not finite"),
    (GOOD[:5] + [(np.zeros(3), np.array([0, np.inf, 0]), 1.0)], None, "not finite"),
    (GOOD[:5] + [(np.zeros(3), np.zeros(3), 0.0)], None, "L must be finite and > 0"),
    (GOOD[:5] + [(np.zeros(3), np.zeros(3), -1.0)], None, "L must be finite and > 0"),
    (GOOD[:5] + [(np.zeros(3), np.zeros(3), np.nan)], None, "L must be finite and > 0"),
    (GOOD[:5] + [(np.zeros(2), np.zeros(3), 1.0)], None, "shape"),
    (GOOD[:5] + [(np.zeros(3), np.zeros(3))], None, "must be"),
    (GOOD[:5], [(np.zeros(3), np.zeros(3), np.zeros(3))], "normal n must be nonzero"),
    (GOOD[:5], [(np.array([0, 0, np.nan]), np.zeros(3), np.zeros(3))], "not finite"),
])
def test_bad_input_raises_pose_error(spheres, planes, match):
    with pytest.raises(PoseError, match=match):
        assembly_modes(spheres, planes)


def test_no_real_mode_and_nearest():
    """Legs far too short for the base and platform: 40 complex modes, none real; nearest() then raises."""
    from pmaccuracy.errors import NoSolutionError
    spheres = [(A, b, 0.05) for A, b, _ in dietmaier()]
    modes = assembly_modes(spheres)
    assert modes.count == 0 and modes.failed == 0
    assert modes.positions.shape == (0, 3) and modes.rotations.shape == (0, 3, 3)
    with pytest.raises(NoSolutionError, match="no real assembly mode"):
        modes.nearest(np.zeros(3), np.eye(3))
    ref = assembly_modes(dietmaier())
    k = 17
    assert ref.nearest(ref.positions[k] + 1e-3, ref.rotations[k]) == k
