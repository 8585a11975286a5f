"""The exact loop closure as a sum of rotated terms (package docstring, "Exact closure as a sum of rotated
terms"): the affine pieces, the model of a batch of poses, and the exact change of the configuration
for given source values."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import NoSolutionError
from .error_set import QUANTITIES, SourceSet
from ...kinematics import inverse_kinematics


# ============================================================================ closure as rotated terms
class _Aff:
    """An affine function ``c + g . Delta`` of ``Delta = (Dz (9), delta (n))``: ``c (N,)``, ``g (N, nv)``
    (complex or real)."""

    __slots__ = ("c", "g")

    def __init__(self, c, g):
        self.c, self.g = c, g

    def __add__(self, other):
        if isinstance(other, _Aff):
            return _Aff(self.c + other.c, self.g + other.g)
        return _Aff(self.c + other, self.g)

    def scale(self, k):
        return _Aff(self.c * k, self.g * k)


@dataclass(frozen=True)
class _Model:
    """The closure terms of a batch of ``N`` poses (module docstring, "Exact closure").

    r0, t0 : ``(N, m)`` nominal radius (complex mm) and angle (rad) of each term;  rg, tg : ``(N, m, nv)``
    their coefficients;  leg_of : ``(m,)`` leg of each term;  aff0, affg : ``(N, 3)``, ``(N, 3, nv)`` the
    affine part of each leg's F;  ang0, angg : ``(N, 3)``, ``(N, 3, nv)`` each leg's G;  n : parameters
    """

    r0: np.ndarray
    t0: np.ndarray
    rg: np.ndarray
    tg: np.ndarray
    leg_of: np.ndarray
    aff0: np.ndarray
    affg: np.ndarray
    ang0: np.ndarray
    angg: np.ndarray
    n: int
    z0: np.ndarray

    def residual(self, D: np.ndarray) -> np.ndarray:
        """The nine real residuals ``(..., N, 9)`` (Re F_i, Im F_i, G_i per leg) at ``Delta`` ``(..., N, nv)``."""
        r = self.r0 + np.einsum("nmv,...nv->...nm", self.rg, D)
        t = self.t0 + np.einsum("nmv,...nv->...nm", self.tg, D)
        terms = r * np.exp(1j * t)
        F = self.aff0 + np.einsum("niv,...nv->...ni", self.affg, D)
        F = F + terms @ self.onehot
        G = self.ang0 + np.einsum("niv,...nv->...ni", self.angg, D)
        return np.stack([F.real, F.imag, G], axis=-1).reshape(F.shape[:-1] + (9,))

    @property
    def onehot(self) -> np.ndarray:
        """``(m, 3)``: 1 where term ``m`` belongs to leg ``i``."""
        return (self.leg_of[:, None] == np.arange(3)[None, :]).astype(float)

    def jacobian(self, D: np.ndarray, z_only: bool = False) -> np.ndarray:
        """``d residual / d Delta`` ``(..., N, 9, nv)`` (only the 9 columns of ``z`` with ``z_only``)."""
        r = self.r0 + np.einsum("nmv,...nv->...nm", self.rg, D)
        t = self.t0 + np.einsum("nmv,...nv->...nm", self.tg, D)
        e = np.exp(1j * t)
        cols = slice(0, 9) if z_only else slice(None)
        rg, tg, affg, angg = self.rg[..., cols], self.tg[..., cols], self.affg[..., cols], self.angg[..., cols]
        dterm = e[..., None] * (rg + 1j * r[..., None] * tg)  # (..., N, m, nv)
        dF = affg + np.stack([dterm[..., self.leg_of == i, :].sum(axis=-2) for i in range(3)], axis=-2)
        dG = np.broadcast_to(angg, dF.shape)
        out = np.stack([dF.real, dF.imag, dG], axis=-2)  # (..., N, 3, 3, nv)
        return out.reshape(out.shape[:-3] + (9, out.shape[-1]))


def _build_model(robot, sets: tuple[SourceSet, ...], poses: np.ndarray) -> _Model:
    """Walk each leg's chain with the sources inserted (as :func:`pmaccuracy.accuracy.nonlinear._perturbed_end`) and
    collect the rotated terms and affine parts at the commanded configuration of ``poses`` ``(N, 3)``."""

    N = poses.shape[0]
    n = sum(len(s.cols) for s in sets)
    nv = 9 + n
    ik = inverse_kinematics(robot, poses)
    if not np.all(ik.reachable):
        bad = int(np.flatnonzero(~ik.reachable)[0])
        raise NoSolutionError(f"pose {bad} cannot be reached by every leg")
    joints = ik.joints
    where = {(s.leg, s.joint, s.field): s for s in sets}

    def const(c, dtype=float):
        return _Aff(np.broadcast_to(np.asarray(c, dtype=dtype), (N,)).copy(), np.zeros((N, nv), dtype=dtype))

    def var(index, c, dtype=float):
        a = const(c, dtype)
        a.g[:, index] = 1.0
        return a

    r0, t0, rg, tg, leg_of = [], [], [], [], []
    aff0, affg, ang0, angg = [], [], [], []
    for i, chain in enumerate(robot.chains):
        passive = dict(zip(chain.passive_indices, (3 + 2 * i, 4 + 2 * i)))
        angle = const(chain.base_angle)
        pos = const(chain.base_z, complex)
        terms = []
        for k, joint in enumerate(chain.joints):
            s = where.get((i, k, "shift"))
            if s:
                pos = pos + _Aff(0.0, np.zeros((N, nv), complex))
                pos.g[:, 9 + s.cols[0]] += 1.0
                pos.g[:, 9 + s.cols[1]] += 1j
            s = where.get((i, k, "turn"))
            if s:
                angle = angle + var(9 + s.cols[0], 0.0)
            if joint.actuated:
                value = const(joints[:, i, k])
                s = where.get((i, k, "dq"))
                if s:
                    value = value + var(9 + s.cols[0], 0.0)
            else:
                value = var(passive[k], joints[:, i, k])
            if joint.kind == "R":
                angle = angle + value + joint.offset
            else:
                # the block (sources.block_centre) shifts by sigma normal to the rail and tilts by tau + tilt:
                # a bushing before the slide (the rod slides along the tilted direction), a carriage after it
                angle = angle + joint.offset
                r = _Aff(value.c.astype(complex), value.g.astype(complex))
                lat, tilt = where.get((i, k, "lateral")), where.get((i, k, "tilt"))
                bushing = joint.block_kind == "bushing"
                if lat:
                    sh = r if not bushing else _Aff(np.zeros(N, complex), np.zeros((N, nv), complex))
                    sh.g[:, 9 + lat.cols[0]] += 1j
                    if bushing:
                        terms.append((sh, angle))
                turned = angle
                for col in ([lat.cols[1]] if lat else []) + ([tilt.cols[0]] if tilt else []):
                    turned = turned + var(9 + col, 0.0)
                terms.append((r, turned if bushing else angle))
                angle = turned
            if abs(joint.link_z) > 0:
                r = const(joint.link_z, complex)
                s = where.get((i, k, "dl"))
                if s:
                    r.g[:, 9 + s.cols[0]] += joint.link_z / abs(joint.link_z)
                terms.append((r, angle))
        # platform side: - p - exp(i phi) platform
        pos = pos + _Aff(np.zeros(N, complex), np.zeros((N, nv), complex))
        pos.c = pos.c - (poses[:, 0] + 1j * poses[:, 1])
        pos.g[:, 0] -= 1.0
        pos.g[:, 1] -= 1j
        if abs(chain.platform_z) > 0:
            terms.append((const(-chain.platform_z, complex), var(2, poses[:, 2])))
        for r, t in _merge_terms(terms):
            r0.append(r.c); rg.append(r.g); t0.append(t.c); tg.append(t.g); leg_of.append(i)
        aff0.append(pos.c); affg.append(pos.g)
        g = angle + var(2, poses[:, 2]).scale(-1.0)
        ang0.append(np.angle(np.exp(1j * (g.c - chain.platform_angle))))  # nominal residual, wrapped
        angg.append(g.g)
    z0 = np.concatenate([poses, ik.passive.reshape(N, 6)], axis=-1)
    return _Model(r0=np.stack(r0, -1), t0=np.stack(t0, -1), rg=np.stack(rg, 1), tg=np.stack(tg, 1),
                  leg_of=np.array(leg_of), aff0=np.stack(aff0, -1), affg=np.stack(affg, 1),
                  ang0=np.stack(ang0, -1), angg=np.stack(angg, 1), n=n, z0=z0)


def _merge_terms(terms: list) -> list:
    """One leg's rotated terms ``(r, theta)`` with those whose angles have the same variable part merged.

    ``r_a exp(i theta_a) + r_b exp(i theta_b) = (r_a exp(i (theta_a - theta_b)) + r_b) exp(i theta_b)``
    exactly when ``theta_a - theta_b`` is a constant, and the merged ``r`` is still affine. The remainder (1)
    of the sum is then bounded once, with ``|r_a + r_b|`` instead of ``|r_a| + |r_b|``: a rail's origin
    moved along the rail (the link before it shorter, the slide longer by as much) leaves the bound as it
    is.
    """
    out: list = []
    for r, t in terms:
        for j, (r2, t2) in enumerate(out):
            if np.array_equal(t.g, t2.g):
                turn = np.exp(1j * (t.c - t2.c))
                out[j] = (_Aff(r2.c + r.c * turn, r2.g + r.g * turn[:, None]), t2)
                break
        else:
            out.append((r, t))
    return out


# ============================================================================ exact model and local ascent
def _take(model: _Model, k: int) -> _Model:
    """The model of pose ``k`` alone (``N = 1``)."""
    sl = slice(k, k + 1)
    return _Model(r0=model.r0[sl], t0=model.t0[sl], rg=model.rg[sl], tg=model.tg[sl], leg_of=model.leg_of,
                  aff0=model.aff0[sl], affg=model.affg[sl], ang0=model.ang0[sl], angg=model.angg[sl], n=model.n,
                  z0=model.z0[sl])


def _take_many(model: _Model, idx: np.ndarray) -> _Model:
    """The model of the poses ``idx`` (indices)."""
    return _Model(r0=model.r0[idx], t0=model.t0[idx], rg=model.rg[idx], tg=model.tg[idx], leg_of=model.leg_of,
                  aff0=model.aff0[idx], affg=model.affg[idx], ang0=model.ang0[idx], angg=model.angg[idx],
                  n=model.n, z0=model.z0[idx])


#: Chord steps of :func:`exact_change` before Newton's method takes over (where they have not converged).
CHORD_STEPS = 8


def exact_change(model: _Model, M: np.ndarray, delta: np.ndarray, iterations: int = 20,
                 gradient: bool = False):
    """Exact change ``Dz`` ``(..., N, 9)`` of pose and passive joints for source values ``delta`` ``(..., N, n)``.

    Newton's method on the closure residuals (module docstring) from the first-order solution ``M delta``
    (the commanded assembly's continuation); NaN where it does not converge to ``|residual| < 1e-9 *
    scale``. With ``gradient`` also ``dDz / ddelta = -J_z^-1 J_delta`` at the solution ``(..., N, 9, n)``.
    """
    delta = np.asarray(delta, dtype=float)
    dz = np.einsum("nij,...nj->...ni", M, delta)
    scale = max(1.0, float(np.max(np.abs(model.r0)))) if model.r0.size else 1.0
    # the chord method first (the Jacobian J_z of the expansion point, the same for every delta of a pose,
    # inverted once: each step a residual and a product), then Newton's method where it has not converged (the
    # same solution: both start at M delta and stay in its contraction region where the chord steps converge)
    N = model.z0.shape[0]
    with np.errstate(all="ignore"):
        J0 = model.jacobian(np.zeros((N, 9 + model.n)), z_only=True)  # (N, 9, 9)
        try:
            J0inv = np.linalg.inv(J0)
        except np.linalg.LinAlgError:
            J0inv = np.full_like(J0, np.nan)
    converged = False
    for _ in range(CHORD_STEPS):
        r = model.residual(np.concatenate([dz, delta], axis=-1))
        with np.errstate(all="ignore"):
            step = np.einsum("nij,...nj->...ni", J0inv, r)
        dz = dz - step
        if np.all((np.abs(step) <= 1e-14 * scale) | ~np.isfinite(step)):
            converged = True
            break
    for _ in range(0 if converged else iterations):
        D = np.concatenate([dz, delta], axis=-1)
        r = model.residual(D)
        J = model.jacobian(D, z_only=True)
        with np.errstate(all="ignore"):
            try:
                step = np.linalg.solve(J, r[..., None])[..., 0]
            except np.linalg.LinAlgError:
                step = np.full_like(dz, np.nan)
        dz = dz - step
        if np.all((np.abs(step) <= 1e-14 * scale) | ~np.isfinite(step)):  # converged (quadratically) or NaN
            break
    D = np.concatenate([dz, delta], axis=-1)
    r = model.residual(D)
    good = np.all(np.abs(r) < 1e-9 * scale, axis=-1) & np.all(np.isfinite(dz), axis=-1)
    dz = np.where(good[..., None], dz, np.nan)
    if not gradient:
        return dz
    J = model.jacobian(D)
    with np.errstate(all="ignore"):
        try:
            G = -np.linalg.solve(J[..., :9], J[..., 9:])
        except np.linalg.LinAlgError:
            G = np.full(dz.shape + (model.n,), np.nan)
    return dz, G


def _objective(q: str, dz: np.ndarray) -> np.ndarray:
    """The quantity ``q`` of pose changes ``dz (..., 9)``: ``|dx|``, ``|dy|``, ``|dphi|`` or ``|dp|``."""
    if q == "dp":
        return np.hypot(dz[..., 0], dz[..., 1])
    return np.abs(dz[..., QUANTITIES.index(q)])
