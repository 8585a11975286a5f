"""Every real assembly mode of a spatial parallel manipulator whose closure equations are spheres and planes.

Forward kinematics of a Gough-Stewart platform (6-UPS: six spheres), a 3-RPS or a 3-PRS (three spheres and
three planes), or any mix of six such constraints, solved completely by a total-degree homotopy in Study
parameters: every isolated real pose is returned, not just the one a local solver happens to reach.

Constraints (lengths in mm, platform points ``b`` in the platform frame, base points ``A`` and unit normals
``n`` in the base frame, pose ``(p, R)`` maps platform to base: ``B = p + R b``)::

    sphere (A, b, L):   |p + R b - A|^2 - L^2 = 0          (a U-P-S or S-P-S leg of length L; a 3-PRS leg
                                                            with A its slider's centre)
    plane  (n, A, b):   n . (p + R b - A)     = 0          (the leg of a 3-RPS / 3-PRS stays in the plane
                                                            through A normal to its revolute axis n)

Study parameters (quaternions written ``q = (q0, q1, q2, q3)``, ``q~`` the conjugate, ``*`` the quaternion
product, ``.`` the Euclidean dot product of 4-vectors, ``a . b = Re(a * b~)``; a 3-vector ``v`` is the pure
quaternion ``(0, v)``). A pose is the point ``z = (e, g)`` of P^7 with::

    R v = e * v * e~ / (e . e)          (e: rotation quaternion, any nonzero scale)
    g   = 1/2 (0, p) * e                (so p = 2 vec(g * e~) / (e . e))
    e . g = e0 g0 + e1 g1 + e2 g2 + e3 g3 = 0         (the Study quadric: Re(g * e~) = 1/2 Re(p) (e.e) = 0)

Then ``(p + R b - A)(e . e) = (2 g + e * b - A * e) * e~ = (2 g + K e) * e~`` with the real 4x4 matrix
``K = right(b) - left(A)`` (``e * b = right(b) e``, ``A * e = left(A) e``). Since the quaternion norm is
multiplicative, ``|w * e~|^2 = (w . w)(e . e)``, so after multiplying by ``e . e``::

    sphere:  (2 g + K e) . (2 g + K e) - L^2 (e . e) = 0
             = z^T [[K^T K - L^2 I, 2 K^T], [2 K, 4 I]] z
    plane:   n . vec((2 g + K e) * e~) = Re((2 g + K e) * e~ * n~) = (2 g + K e) . (N e) = 0,  N = left(n)
             = z^T [[(K^T N + N^T K)/2, N^T], [N, 0]] z
    Study:   z^T [[0, I/2], [I/2, 0]] z = 0

Seven homogeneous quadrics ``F_k(z) = z^T Q_k z`` in P^7: Bezout number 2^7 = 128. Every pose gives a solution
with ``e . e != 0``. Solutions with ``e . e = 0`` are no poses and are discarded: the "exceptional generator"
``e = 0`` (there every plane quadric vanishes and every sphere quadric is ``4 g . g``, a 2-dimensional set of
solutions) and, once planes are present, complex isotropic rotations ``e != 0, e . e = 0``. For a general 6-UPS,
40 of the 128 paths end at poses (complex or real) and 88 at ``e = 0`` (Husty 1996); for a general 3-RPS, 16 end
at poses and 112 on ``e . e = 0``.

Homotopy (total degree, "gamma trick")::

    H(z, t) = (1 - t) F(z) + gamma t G(z),    G_k(z) = z_{k+1}^2 - z_0^2,   k = 0..6
    h . z = 1                                  (random complex affine patch of P^7)

``gamma`` (on the unit circle) and ``h`` are random complex (``seed``); t runs from 1 (the 128 start points
``z = (1, +-1, ..., +-1) / (h . (1, +-1, ..., +-1))``) to 0. All 128 paths are tracked together, vectorized:
batched 8x8 complex solves (``np.linalg.solve``), a Runge-Kutta-4 predictor on ``dz/dt = -H_z^-1 H_t``
(``H_t = gamma G - F``) and a Newton corrector at the new t, each path with its own adaptive step (halved when
three corrector iterations do not contract to ``1e-8`` relative, doubled after three accepted steps, at most
0.1). Lengths are divided by a characteristic length ``s`` (the largest |A|, |b| or L) before solving so the
quadrics are of order one, and multiplied back after.

Completeness. For every ``gamma`` outside a finite set of real curves through the origin of C (probability one
for a random ``gamma``) the solution set of ``H(z, t) = 0`` for ``t`` in (0, 1] consists of 128 smooth,
non-crossing paths, and every isolated solution of the target ``F`` (here: every isolated pose, real or
complex) is the limit of at least one of them as t -> 0 (Morgan & Sommese 1987; Sommese & Wampler, *The
Numerical Solution of Systems of Polynomials*, 2005, Thm 8.4.1). All 128 paths are tracked, so no isolated pose
is missed unless a path is lost.

Endpoints. With ``rho = |e . e| / ||z||^2`` (scale-invariant; a real pose has ``rho = 1 / (1 + |p|^2 / (4 s^2))``,
at least 0.3 when one constraint is a sphere since then ``|p| <= |A| + L + |b| <= 3 s``), a path stops as *not a
pose* when ``rho < 1e-7`` at ``t < 1e-6`` (along paths into ``e . e = 0`` rho falls like t or faster, and the
endpoint is singular so Newton cannot converge there), or when its step collapses (below ``1e-13``) with
``rho < 1e-2``. Paths that reach t = 0 get five Newton steps on ``F``; an endpoint is *finite* when they converge
(``max |F_k| / ||z||^2 < 1e-8``) and ``rho > 1e-12``, not a pose when ``rho <= 1e-12``. Every other path is
*failed* (step collapsed away from ``e . e = 0``, step budget exhausted, or no Newton convergence at t = 0): failed
paths are tracked again from t = 1 with a four-times smaller initial and maximum step and a tighter corrector,
twice, and what still fails is counted in :attr:`AssemblyModes.failed`. ``failed == 0`` (every case tested) means
every path was accounted for, so by the theorem above every isolated real pose is in the result; a non-zero count
means a pose may be missing (e.g. a singular, double assembly mode of a non-generic robot). A finite endpoint is
scaled so that ``e . e = 1`` (complex factor ``1/sqrt(e . e)``: a real pose then becomes real up to a sign); it is
*real* when its imaginary parts are below ``1e-6`` times its norm. Each real one becomes ``(p, R)``, is polished
by real Newton on the six original equations (:func:`polish`), is kept when its residual is below ``tol * s``,
and duplicates (the same pose from two paths: within ``max(1e-6 mm, 1e-12 s)`` in position and 1e-8 in each
entry of R, about 1e-8 rad) are removed.

References: M. L. Husty, "An algorithm for solving the direct kinematics of general Stewart-Gough platforms",
Mech. Mach. Theory 31 (1996); P. Dietmaier, "The Stewart-Gough platform of general geometry can have 40 real
postures", Advances in Robot Kinematics (1998); A. P. Morgan, A. J. Sommese, "Computing all solutions to
polynomial systems using homotopy continuation", Appl. Math. Comput. 24 (1987).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import NoSolutionError, PoseError

__all__ = ["AssemblyModes", "assembly_modes", "polish", "closure_residuals", "study_quadrics",
           "pose_to_study", "study_to_pose"]

#: A path ends on the non-pose set ``e . e = 0`` once ``rho = |e . e| / ||z||^2 <`` :data:`E_INF` at ``t <``
#: :data:`T_INF`, or when its step collapses with ``rho <`` :data:`E_LOST`. A real pose has
#: ``rho = 1 / (1 + |p|^2 / 4) >= 0.3`` for ``|p| <= 3`` characteristic lengths (true whenever one constraint is a
#: sphere: ``|p| <= |A| + L + |b|``); along paths into ``e . e = 0``, rho falls like t or faster (1e-9 at
#: t = 1e-6 for Dietmaier's platform), while a finite complex solution with a large complex translation can have
#: rho ~ 1e-5. At t = 0 a Newton-converged endpoint is finite when rho > :data:`E_FINITE`.
E_FINITE = 1e-12
E_INF = 1e-7
E_LOST = 1e-2
T_INF = 1e-6

#: Bezout number of the seven quadrics in P^7: the number of homotopy paths.
PATHS = 128


# --------------------------------------------------------------------------------------------------- input

def _vec3(value, what: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise PoseError(f"{what} must be 3 numbers, got {value!r}") from None
    if arr.shape != (3,):
        raise PoseError(f"{what} must have shape (3,), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise PoseError(f"{what} is not finite: {arr.tolist()}")
    return arr


def _parse(spheres, planes) -> tuple[list, list]:
    """Checked constraints: spheres ``[(A, b, L)]`` and planes ``[(n unit, A, b)]``; PoseError naming the bad one."""
    spheres = list(spheres or [])
    planes = list(planes or [])
    if len(spheres) + len(planes) != 6:
        raise PoseError(f"a spatial pose needs exactly six closure equations, got {len(spheres)} sphere(s) and "
                        f"{len(planes)} plane(s) ({len(spheres) + len(planes)} in all)")
    out_s, out_p = [], []
    for i, s in enumerate(spheres):
        try:
            A, b, L = s
        except (TypeError, ValueError):
            raise PoseError(f"sphere {i} must be (A (3,), b (3,), L), got {s!r}") from None
        A, b = _vec3(A, f"sphere {i}: base point A"), _vec3(b, f"sphere {i}: platform point b")
        try:
            L = float(L)
        except (TypeError, ValueError):
            raise PoseError(f"sphere {i}: length L must be a number, got {L!r}") from None
        if not np.isfinite(L) or L <= 0:
            raise PoseError(f"sphere {i}: length L must be finite and > 0 mm, got {L!r}")
        out_s.append((A, b, L))
    for i, pl in enumerate(planes):
        try:
            n, A, b = pl
        except (TypeError, ValueError):
            raise PoseError(f"plane {i} must be (n (3,), A (3,), b (3,)), got {pl!r}") from None
        n = _vec3(n, f"plane {i}: normal n")
        A, b = _vec3(A, f"plane {i}: base point A"), _vec3(b, f"plane {i}: platform point b")
        norm = float(np.linalg.norm(n))
        if not norm > 1e-12:
            raise PoseError(f"plane {i}: normal n must be nonzero, got {n.tolist()}")
        out_p.append((n / norm, A, b))
    return out_s, out_p


def _scale(spheres, planes) -> float:
    """Characteristic length (mm): the largest |A|, |b| or L, at least 1e-300."""
    vals = [0.0]
    for A, b, L in spheres:
        vals += [np.linalg.norm(A), np.linalg.norm(b), L]
    for _, A, b in planes:
        vals += [np.linalg.norm(A), np.linalg.norm(b)]
    return max(max(vals), 1e-300)


# --------------------------------------------------------------------------------------- Study parameters

def _left(q: np.ndarray) -> np.ndarray:
    """4x4 matrix of ``x -> q * x`` (q a quaternion (4,) or a 3-vector taken as pure)."""
    if len(q) == 3:
        q = np.concatenate([[0.0], q])
    a, b, c, d = q
    return np.array([[a, -b, -c, -d], [b, a, -d, c], [c, d, a, -b], [d, -c, b, a]])


def _right(q: np.ndarray) -> np.ndarray:
    """4x4 matrix of ``x -> x * q`` (q a quaternion (4,) or a 3-vector taken as pure)."""
    if len(q) == 3:
        q = np.concatenate([[0.0], q])
    a, b, c, d = q
    return np.array([[a, -b, -c, -d], [b, a, d, -c], [c, -d, a, b], [d, c, -b, a]])


def study_quadrics(spheres, planes) -> np.ndarray:
    """The seven symmetric 8x8 matrices ``Q_k`` with ``F_k(z) = z^T Q_k z``, ``z = (e, g)`` (see the module).

    Rows: the spheres in order, then the planes, then the Study quadric. Units as given (a sphere's entries
    are mm^2 for the ``e e`` block, mm for ``e g``, 1 for ``g g``); (7, 8, 8) float.

    >>> Q = study_quadrics([([0, 0, 0], [0, 0, 0], 1.0)] * 6, [])
    >>> Q.shape, float(Q[0, 4, 4]), float(Q[6, 0, 4])
    ((7, 8, 8), 4.0, 0.5)
    """
    I = np.eye(4)
    out = []
    for A, b, L in spheres:
        K = _right(np.asarray(b, float)) - _left(np.asarray(A, float))
        out.append(np.block([[K.T @ K - L * L * I, 2 * K.T], [2 * K, 4 * I]]))
    for n, A, b in planes:
        K = _right(np.asarray(b, float)) - _left(np.asarray(A, float))
        N = _left(np.asarray(n, float))
        out.append(np.block([[(K.T @ N + N.T @ K) / 2, N.T], [N, np.zeros((4, 4))]]))
    out.append(np.block([[np.zeros((4, 4)), I / 2], [I / 2, np.zeros((4, 4))]]))
    return np.array(out)


def pose_to_study(positions: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """Study parameters ``z = (e, g)`` ``(..., 8)`` of poses: ``e`` the unit quaternion (scalar first) of ``R``,
    ``g = 1/2 (0, p) * e``. positions ``(..., 3)`` mm, rotations ``(..., 3, 3)``."""
    p = np.asarray(positions, float)
    R = np.asarray(rotations, float)
    xyzw = Rotation.from_matrix(R.reshape(-1, 3, 3)).as_quat()
    e = np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1).reshape(R.shape[:-2] + (4,))
    pq = np.concatenate([np.zeros(p.shape[:-1] + (1,)), p], axis=-1)
    g = 0.5 * _qmul(pq, e)
    return np.concatenate([e, g], axis=-1)


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Quaternion product ``a * b`` over the last axis (scalar first), real or complex, broadcasting."""
    a0, a1, a2, a3 = np.moveaxis(a, -1, 0)
    b0, b1, b2, b3 = np.moveaxis(b, -1, 0)
    return np.stack([a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
                     a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
                     a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
                     a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0], axis=-1)


def study_to_pose(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Poses of real Study parameters ``z (..., 8)`` (any nonzero scale of ``e``): ``p = 2 vec(g * e~)/(e.e)``
    mm ``(..., 3)``, ``R`` ``(..., 3, 3)`` the rotation of ``e / |e|`` (det +1)."""
    z = np.asarray(z, float)
    e, g = z[..., :4], z[..., 4:]
    ee = np.sum(e * e, axis=-1)
    conj = e * np.array([1.0, -1.0, -1.0, -1.0])
    p = 2 * _qmul(g, conj)[..., 1:] / ee[..., None]
    en = e / np.sqrt(ee)[..., None]
    R = Rotation.from_quat(np.concatenate([en[..., 1:], en[..., :1]], axis=-1).reshape(-1, 4)).as_matrix()
    return p, R.reshape(e.shape[:-1] + (3, 3))


# ------------------------------------------------------------------------------------------------ residuals

def closure_residuals(spheres, planes, positions, rotations) -> np.ndarray:
    """The six closure equations at poses, ``(k, 6)`` mm: spheres first, ``(|B - A|^2 - L^2) / (2 L)``
    (to first order the length error ``|B - A| - L``), then planes ``n . (B - A)``; ``B = p + R b``.

    positions ``(k, 3)`` mm, rotations ``(k, 3, 3)``.
    """
    spheres, planes = _parse(spheres, planes)
    return _residuals(spheres, planes, np.asarray(positions, float), np.asarray(rotations, float))[0]


def _residuals(spheres, planes, p, R):
    """Residuals ``(k, 6)`` and Jacobian ``(k, 6, 6)`` w.r.t. ``(dv, dw)`` (``p += dv``, ``R = exp(dw^) R``)."""
    k = p.shape[0]
    f = np.empty((k, 6))
    J = np.empty((k, 6, 6))
    i = 0
    for A, b, L in spheres:
        Rb = R @ b
        d = p + Rb - A
        f[:, i] = (np.sum(d * d, axis=1) - L * L) / (2 * L)
        u = d / L
        J[:, i, :3] = u
        J[:, i, 3:] = np.cross(Rb, u)
        i += 1
    for n, A, b in planes:
        Rb = R @ b
        f[:, i] = (p + Rb - A) @ n
        J[:, i, :3] = n
        J[:, i, 3:] = np.cross(Rb, n)
        i += 1
    return f, J


def polish(spheres, planes, positions, rotations, iterations: int = 8):
    """Real Newton on the six closure equations, vectorized over ``k`` poses.

    With ``f(p, R)`` the residuals of :func:`closure_residuals` and ``J = df/d(v, w)`` (row of a sphere:
    ``[u, (R b) x u]`` with ``u = (B - A) / L``; of a plane: ``[n, (R b) x n]``), each iteration solves
    ``J [dv; dw] = -f`` and updates ``p += dv``, ``R = expm(skew(dw)) R`` (``Rotation.from_rotvec``).
    Stops early when every step is below 1e-15 times the characteristic length; a singular ``J`` keeps the pose
    (least-squares step).

    Parameters
    ----------
    positions : ``(k, 3)`` mm;  rotations : ``(k, 3, 3)``

    Returns
    -------
    positions ``(k, 3)`` mm, rotations ``(k, 3, 3)``, residuals ``(k,)`` mm: max |residual| of the six.
    """
    spheres, planes = _parse(spheres, planes)
    p = np.array(positions, float).reshape(-1, 3)
    R = np.array(rotations, float).reshape(-1, 3, 3)
    scale = _scale(spheres, planes)
    for _ in range(iterations):
        if len(p) == 0:
            break
        f, J = _residuals(spheres, planes, p, R)
        try:
            step = np.linalg.solve(J, -f[..., None])[..., 0]
        except np.linalg.LinAlgError:
            step = np.stack([np.linalg.lstsq(Jk, -fk, rcond=None)[0] for Jk, fk in zip(J, f)])
        p = p + step[:, :3]
        R = Rotation.from_rotvec(step[:, 3:]).as_matrix() @ R
        if np.max(np.abs(step[:, :3])) < 1e-15 * scale and np.max(np.abs(step[:, 3:])) < 1e-15:
            break
    f, _ = _residuals(spheres, planes, p, R)
    return p, R, np.max(np.abs(f), axis=1) if len(p) else np.zeros(0)


# ------------------------------------------------------------------------------------------------ homotopy

def _solve(J: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Batched ``J x = rhs`` ``(P, 8, 8) (P, 8)``; rows with a singular or non-finite ``J`` give NaN (a failed step)."""
    bad = ~np.all(np.isfinite(J), axis=(1, 2)) | ~np.all(np.isfinite(rhs), axis=1)
    if bad.any():
        J = J.copy()
        J[bad] = np.eye(8)
    try:
        x = np.linalg.solve(J, rhs[..., None])[..., 0]
    except np.linalg.LinAlgError:
        x = np.empty_like(rhs)
        for i in range(len(J)):
            try:
                x[i] = np.linalg.solve(J[i], rhs[i])
            except np.linalg.LinAlgError:
                x[i] = np.nan
    x[bad] = np.nan
    return x


def _rho(z: np.ndarray) -> np.ndarray:
    """``|e . e| / ||z||^2`` (Hermitian norm) ``(P,)``: 0 on the non-pose set ``e . e = 0``; for a real pose
    ``|e|^2 / (|e|^2 + |g|^2) = 1 / (1 + |p|^2 / 4)`` whatever the (complex) scale of ``z``."""
    e = z[:, :4]
    return np.abs(np.sum(e * e, axis=1)) / np.sum(z.real ** 2 + z.imag ** 2, axis=1)


class _System:
    """``H(z, t) = (1 - t) F(z) + gamma t G(z)`` and the patch ``h . z = 1``, evaluated for many paths."""

    def __init__(self, Q: np.ndarray, gamma: complex, h: np.ndarray):
        self.Qmat = Q.transpose(2, 0, 1).reshape(8, 56)   # z @ Qmat -> (P, 7*8): (Q_k z)_i
        self.gamma = gamma
        self.h = h

    def parts(self, z):
        """``Qz (P, 7, 8)``, ``F (P, 7)``, ``G (P, 7)`` and ``Gz (P, 7, 8)`` (half gradients)."""
        Qz = (z @ self.Qmat).reshape(-1, 7, 8)
        F = np.einsum("pki,pi->pk", Qz, z)
        z2 = z * z
        G = z2[:, 1:] - z2[:, :1]
        return Qz, F, G

    def jac(self, z, t, Qz):
        P = z.shape[0]
        J = np.empty((P, 8, 8), dtype=complex)
        a = (1 - t)[:, None, None]
        J[:, :7, :] = 2 * a * Qz
        gt = 2 * self.gamma * t
        idx = np.arange(7)
        J[:, idx, idx + 1] += gt[:, None] * z[:, 1:]
        J[:, :7, 0] -= gt[:, None] * z[:, :1]
        J[:, 7, :] = self.h
        return J

    def velocity(self, z, t):
        """``dz/dt = -H_z^-1 H_t`` with ``H_t = gamma G - F`` (patch row: 0)."""
        Qz, F, G = self.parts(z)
        J = self.jac(z, t, Qz)
        rhs = np.zeros((z.shape[0], 8), dtype=complex)
        rhs[:, :7] = -(self.gamma * G - F)
        return _solve(J, rhs)

    def newton(self, z, t):
        """One Newton step at fixed t: new z and the step's norm."""
        Qz, F, G = self.parts(z)
        J = self.jac(z, t, Qz)
        rhs = np.empty((z.shape[0], 8), dtype=complex)
        rhs[:, :7] = -((1 - t)[:, None] * F + (self.gamma * t)[:, None] * G)
        rhs[:, 7] = 1 - z @ self.h
        dz = _solve(J, rhs)
        return z + dz, np.linalg.norm(dz, axis=1)


def _track(system: _System, z: np.ndarray, *, h0: float, hmax: float, tol: float, max_steps: int,
           e_tol: float, t_inf: float):
    """Track paths from t = 1 to 0; returns z (P, 8), t (P,), steps (P,) and a status per path:
    0 reached t = 0, 1 lost (step too small or step budget), 2 stopped near ``e = 0``."""
    P = z.shape[0]
    z = z.copy()
    t = np.ones(P)
    dt = np.full(P, h0)
    ok_run = np.zeros(P, dtype=int)
    steps = np.zeros(P, dtype=int)
    status = np.full(P, -1)
    active = np.arange(P)
    while active.size:
        za, ta, ha = z[active], t[active], np.minimum(dt[active], t[active])
        # RK4 predictor in t (decreasing)
        k1 = system.velocity(za, ta)
        k2 = system.velocity(za - 0.5 * ha[:, None] * k1, ta - 0.5 * ha)
        k3 = system.velocity(za - 0.5 * ha[:, None] * k2, ta - 0.5 * ha)
        t1 = ta - ha
        k4 = system.velocity(za - ha[:, None] * k3, t1)
        zp = za - (ha / 6)[:, None] * (k1 + 2 * k2 + 2 * k3 + k4)
        # Newton corrector: three iterations, converged when the last step is tiny and they contracted
        zn = zp
        norms = []
        for _ in range(3):
            zn, dn = system.newton(zn, t1)
            norms.append(dn)
        scale = np.linalg.norm(zn, axis=1)
        good = (norms[2] < tol * scale) & (norms[1] < 0.1 * np.maximum(norms[0], tol * scale)) \
            & (norms[0] < 0.1 * scale) & np.all(np.isfinite(zn), axis=1)
        acc = active[good]
        rej = active[~good]
        z[acc] = zn[good]
        t[acc] = t1[good]
        ok_run[acc] += 1
        grow = acc[ok_run[acc] >= 3]
        dt[grow] = np.minimum(2 * dt[grow], hmax)
        ok_run[grow] = 0
        dt[rej] *= 0.5
        ok_run[rej] = 0
        steps[active] += 1
        done = acc[t[acc] <= 0.0]
        status[done] = 0
        rho = _rho(z[active])
        near0 = active[(rho < e_tol) & (t[active] < t_inf) & (status[active] < 0)]
        status[near0] = 2
        stuck = (dt[active] < 1e-13) | (steps[active] >= max_steps)
        lost = active[stuck & (status[active] < 0)]
        status[lost] = np.where(rho[stuck & (status[active] < 0)] < E_LOST, 2, 1)
        active = active[status[active] < 0]
    return z, t, steps, status


def _classify(system: _System, z: np.ndarray, status: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Endpoints of tracked paths: Newton (5 steps) at t = 0 on those that reached it; status becomes 3 (finite:
    converged, ``max |F_k| / ||z||^2 < 1e-8`` and ``rho >`` :data:`E_FINITE`), 2 (on ``e . e = 0``: no pose) or
    1 (failed: lost, or reached t = 0 but Newton does not converge there away from ``e . e = 0``)."""
    z, status = z.copy(), status.copy()
    idx = np.flatnonzero(status == 0)
    ze = z[idx]
    with np.errstate(all="ignore"):
        for _ in range(5):
            ze, _dn = system.newton(ze, np.zeros(len(ze)))
        rho = _rho(ze)
        _, F, _ = system.parts(ze)
        res = np.max(np.abs(F), axis=1) / np.sum(np.abs(ze) ** 2, axis=1)
    ok = np.all(np.isfinite(ze), axis=1) & np.isfinite(res)
    finite = ok & (rho > E_FINITE) & (res < 1e-8)
    status[idx] = np.where(finite, 3, np.where(ok & (rho <= E_FINITE), 2, 1))
    z[idx[ok]] = ze[ok]
    return z, status


@dataclass(frozen=True)
class AssemblyModes:
    """Every real assembly mode found by :func:`assembly_modes`.

    Attributes
    ----------
    positions : ``(k, 3)`` mm, every real solution, distinct, sorted lexicographically by position
    rotations : ``(k, 3, 3)`` rotation matrices platform -> base, det +1
    residuals : ``(k,)`` mm: max |residual| of the six equations after polishing (:func:`closure_residuals`:
        spheres as ``(|B - A|^2 - L^2) / (2 L)``, planes as ``n . (B - A)``)
    paths : homotopy paths tracked (128)
    finite : paths that ended at finite (pose, real or complex) solutions (before duplicates are removed)
    failed : paths that neither reached t = 0 nor ``e = 0`` after two re-trackings with smaller steps (a pose
        may then be missing); 0 normally
    method : one line naming the method
    """

    positions: np.ndarray
    rotations: np.ndarray
    residuals: np.ndarray
    paths: int
    finite: int
    failed: int
    method: str

    @property
    def count(self) -> int:
        """Number of real assembly modes."""
        return int(self.positions.shape[0])

    def nearest(self, position, rotation, length: float = 1.0) -> int:
        """Index of the mode nearest to a reference pose: least ``|dp|^2 + (length * angle(R_ref^T R))^2``.

        position ``(3,)`` mm, rotation ``(3, 3)``, length mm per rad. Raises :class:`NoSolutionError` when there is
        no real mode.
        """
        if self.count == 0:
            raise NoSolutionError("forward kinematics has no real assembly mode for these closure equations")
        dp = np.sum((self.positions - np.asarray(position, float)) ** 2, axis=1)
        rel = np.swapaxes(self.rotations, 1, 2) @ np.asarray(rotation, float)
        angle = np.arccos(np.clip((np.trace(rel, axis1=1, axis2=2) - 1) / 2, -1.0, 1.0))
        return int(np.argmin(dp + (length * angle) ** 2))


def assembly_modes(spheres: list[tuple] | None = None, planes: list[tuple] | None = None, *, seed: int = 0,
                   tol: float = 1e-9) -> AssemblyModes:
    """Every real assembly mode (forward kinematics) for six sphere / plane closure equations.

    Solves ``|p + R b_i - A_i|^2 = L_i^2`` (spheres) and ``n_j . (p + R b_j - A_j) = 0`` (planes), six in all,
    for the pose ``(p, R)`` by a total-degree homotopy on the seven Study-parameter quadrics in P^7 (128
    paths, see the module docstring), then polishes every real endpoint by Newton on these equations.

    Parameters
    ----------
    spheres : list of ``(A (3,) mm, b (3,) mm, L mm > 0)``: base point, platform point (platform frame), length
    planes : list of ``(n (3,), A (3,) mm, b (3,) mm)``: normal (base frame, normalized here), base point,
        platform point
    seed : seeds the random ``gamma`` and affine patch (any seed gives the same poses with probability one)
    tol : a real mode is kept when its residual is below ``tol`` times the characteristic length (largest |A|,
        |b|, L) after polishing

    Returns
    -------
    :class:`AssemblyModes`. Raises :class:`PoseError` for anything but six finite constraints with L > 0 and
    nonzero normals.

    Example
    -------
    An octahedral-like 6-UPS assembled at p = (0, 0, 1), R = I; the pose is among its modes:

    >>> import numpy as np
    >>> base = [[1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [0.5, 0.5, 0], [-0.3, 0.6, 0.1]]
    >>> plat = [[0.4, 0.3, 0], [-0.3, 0.5, 0], [-0.6, -0.1, 0], [0.2, -0.6, 0], [0.1, 0.1, 0.2], [0, 0.3, -0.1]]
    >>> p0 = np.array([0.0, 0.0, 1.0])
    >>> legs = [(np.array(A, float), np.array(b, float), float(np.linalg.norm(p0 + np.array(b) - np.array(A))))
    ...         for A, b in zip(base, plat)]
    >>> modes = assembly_modes(legs)
    >>> modes.paths, modes.failed
    (128, 0)
    >>> bool(np.any(np.all(np.abs(modes.positions - p0) < 1e-9, axis=1)))
    True
    """
    spheres, planes = _parse(spheres, planes)
    s = _scale(spheres, planes)
    sph = [(A / s, b / s, L / s) for A, b, L in spheres]
    pla = [(n, A / s, b / s) for n, A, b in planes]
    Q = study_quadrics(sph, pla)
    rng = np.random.default_rng(seed)
    gamma = np.exp(2j * np.pi * rng.random())
    h = rng.normal(size=8) + 1j * rng.normal(size=8)
    system = _System(Q, gamma, h)
    signs = np.array(np.meshgrid(*[[1.0, -1.0]] * 7, indexing="ij")).reshape(7, -1).T
    v = np.hstack([np.ones((PATHS, 1)), signs]).astype(complex)
    z0 = v / (v @ h)[:, None]

    z, _, _, status = _track(system, z0, h0=0.05, hmax=0.1, tol=1e-8, max_steps=4000, e_tol=E_INF, t_inf=T_INF)
    z, status = _classify(system, z, status)
    for k in range(2):   # failed paths again from t = 1, with smaller steps and a tighter corrector
        again = np.flatnonzero(status == 1)
        if not again.size:
            break
        z2, _, _, s2 = _track(system, z0[again], h0=0.05 / 4 ** (k + 1), hmax=0.1 / 4 ** (k + 1),
                              tol=1e-9, max_steps=8000, e_tol=E_INF, t_inf=T_INF)
        z[again], status[again] = _classify(system, z2, s2)
    failed = int(np.sum(status == 1))
    zf = z[status == 3]
    finite = int(zf.shape[0])
    # dehomogenize: e . e = 1
    lam = 1 / np.sqrt(np.sum(zf[:, :4] ** 2, axis=1))
    zf = zf * lam[:, None]
    real = np.max(np.abs(zf.imag), axis=1) < 1e-6 * np.linalg.norm(zf, axis=1)
    zr = zf[real].real
    zr[:, 4:] *= s
    p, R = study_to_pose(zr)
    p, R, r = polish(spheres, planes, p, R)
    keep = r < tol * s
    p, R, r = p[keep], R[keep], r[keep]
    # duplicates
    uniq = []
    for i in range(len(p)):
        if all(np.max(np.abs(p[i] - p[j])) > max(1e-6, 1e-12 * s) or np.max(np.abs(R[i] - R[j])) > 1e-8 for j in uniq):
            uniq.append(i)
    order = sorted(uniq, key=lambda i: tuple(p[i]))
    return AssemblyModes(positions=p[order].reshape(-1, 3), rotations=R[order].reshape(-1, 3, 3),
                         residuals=r[order], paths=PATHS, finite=finite, failed=failed,
                         method="total-degree homotopy (gamma trick, 128 paths) on 7 Study-parameter quadrics in P^7")
