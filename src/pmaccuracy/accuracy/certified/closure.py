"""The exact loop closure as a sum of rotated terms (package docstring, "Exact closure as a sum of rotated
terms"): the affine pieces, the model of a batch of poses, and the exact change of the configuration
for given source values."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

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
        m = self.r0.shape[-1]
        lin = _apply(self._coefficients, D)  # (..., N, 3m + 9): Re dr, Im dr, dt, Re dF, Im dF, dG
        r = self.r0 + (lin[..., :m] + 1j * lin[..., m:2 * m])
        t = self.t0 + lin[..., 2 * m:3 * m]
        terms = r * np.exp(1j * t)
        F = self.aff0 + (lin[..., 3 * m:3 * m + 3] + 1j * lin[..., 3 * m + 3:3 * m + 6]) + terms @ self.onehot
        G = self.ang0 + lin[..., 3 * m + 6:]
        return np.stack([F.real, F.imag, G], axis=-1).reshape(F.shape[:-1] + (9,))

    @cached_property
    def onehot(self) -> np.ndarray:
        """``(m, 3)``: 1 where term ``m`` belongs to leg ``i``."""
        return (self.leg_of[:, None] == np.arange(3)[None, :]).astype(float)

    @cached_property
    def _coefficients(self) -> np.ndarray:
        """The affine coefficients as one real array ``(N, nv, 3m + 9)``: columns ``Re rg, Im rg, tg`` of the terms,
        then ``Re affg, Im affg, angg`` of the legs (one real product evaluates them all: complex einsum over the
        batch is about 10x slower)."""
        parts = [self.rg.real, self.rg.imag, self.tg, self.affg.real, self.affg.imag, self.angg]
        return np.ascontiguousarray(np.concatenate(parts, axis=1).transpose(0, 2, 1))

    @cached_property
    def _term_coefficients(self) -> np.ndarray:
        """``(N, 3m, nv)``: ``Re rg, Im rg, tg`` stacked (:meth:`jacobian`)."""
        return np.ascontiguousarray(np.concatenate([self.rg.real, self.rg.imag, self.tg], axis=1))

    def jacobian(self, D: np.ndarray, z_only: bool = False) -> np.ndarray:
        """``d residual / d Delta`` ``(..., N, 9, nv)`` (only the 9 columns of ``z`` with ``z_only``).

        With ``e = exp(i t)`` the derivative of a term ``r e`` is ``e (rg + i r tg)``: its real and imaginary parts
        are ``(Re e, -Im e, -Im(e r))`` and ``(Im e, Re e, Re(e r))`` times ``(Re rg, Im rg, tg)``, summed per leg."""
        m = self.r0.shape[-1]
        lin = _apply(self._coefficients[..., :3 * m], D)
        r = self.r0 + (lin[..., :m] + 1j * lin[..., m:2 * m])
        e = np.exp(1j * (self.t0 + lin[..., 2 * m:]))
        er = e * r
        cre = np.concatenate([e.real, -e.imag, -er.imag], axis=-1)  # (..., N, 3m)
        cim = np.concatenate([e.imag, e.real, er.real], axis=-1)
        oh = np.tile(self.onehot.T, 3)  # (3, 3m)
        W = self._term_coefficients if not z_only else self._term_coefficients[..., :9]
        # (..., N, 3 legs, 3m) @ (N, 3m, nv')
        dre = (cre[..., None, :] * oh) @ W
        dim = (cim[..., None, :] * oh) @ W
        cols = slice(0, 9) if z_only else slice(None)
        dre = dre + self.affg.real[..., cols]
        dim = dim + self.affg.imag[..., cols]
        dG = np.broadcast_to(self.angg[..., cols], dre.shape)
        out = np.stack([dre, dim, dG], axis=-2)  # (..., N, 3, 3, nv)
        return out.reshape(out.shape[:-3] + (9, out.shape[-1]))


def _apply(W: np.ndarray, D: np.ndarray) -> np.ndarray:
    """``W^T D`` per pose: ``W`` ``(N, nv, k)``, ``D`` ``(..., N, nv)`` -> ``(..., N, k)`` (real)."""
    return np.einsum("nvk,...nv->...nk", W, D, optimize=True)


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
    return _take_many(model, slice(k, k + 1))


def _take_many(model: _Model, idx) -> _Model:
    """The model of the poses ``idx`` (indices or a slice); the real coefficient arrays already built are taken
    along."""
    out = _Model(r0=model.r0[idx], t0=model.t0[idx], rg=model.rg[idx], tg=model.tg[idx], leg_of=model.leg_of,
                 aff0=model.aff0[idx], affg=model.affg[idx], ang0=model.ang0[idx], angg=model.angg[idx],
                 n=model.n, z0=model.z0[idx])
    _share_coefficients(model, out, idx)
    return out


def _share_coefficients(model: _Model, out: _Model, idx=slice(None)) -> None:
    """Give ``out`` the cached coefficient arrays of ``model`` (rows ``idx``) when their affine parts agree (a
    selection of poses, or the same model expanded about another point: :func:`_recentre` keeps them)."""
    for name in ("_coefficients", "_term_coefficients", "onehot"):
        if name in model.__dict__:
            val = model.__dict__[name]
            out.__dict__[name] = val if name == "onehot" else val[idx]


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
    return dz, _source_gradient(model, dz, delta)


def _source_gradient(model: _Model, dz: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """``dDz / ddelta = -J_z^-1 J_delta`` ``(..., N, 9, n)`` at the exact solution ``dz`` ``(..., N, 9)`` of
    ``delta`` ``(..., N, n)`` (implicit function theorem; NaN where ``J_z`` is singular)."""
    J = model.jacobian(np.concatenate([dz, delta], axis=-1))
    with np.errstate(all="ignore"):
        try:
            return -np.linalg.solve(J[..., :9], J[..., 9:])
        except np.linalg.LinAlgError:
            return np.full(dz.shape + (model.n,), np.nan)


def _objective(q: str, dz: np.ndarray) -> np.ndarray:
    """The quantity ``q`` of pose changes ``dz (..., 9)``: ``|dx|``, ``|dy|``, ``|dphi|`` or ``|dp|``."""
    if q == "dp":
        return np.hypot(dz[..., 0], dz[..., 1])
    return np.abs(dz[..., QUANTITIES.index(q)])
