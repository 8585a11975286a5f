"""Independent reference laws of linear combinations of bounded random sources (tests only).

Imports nothing from ``pmaccuracy``. A first-order pose error is ``sum_s g_s . X_s`` with independent
sources ``X_s``; projected on one quantity each source contributes a scalar with a known law:

* an interval value uniform on ``[-eps, eps]`` times a coefficient ``g``: uniform on ``[-a, a]``,
  ``a = eps |g|``;
* a point uniform in a disk of radius ``eps`` (by area) dotted with ``g`` (2,): the semicircle
  (Wigner) law of radius ``R = eps |g|``, density ``2 sqrt(R^2 - x^2) / (pi R^2)``;
* a point uniform in the rhombus ``|L tau +- 2 sigma| <= 2 eps`` (the linear image of the square
  ``(u, v) in [-1, 1]^2`` with ``L tau + 2 sigma = 2 eps u`` and ``L tau - 2 sigma = 2 eps v``)
  dotted with ``(a, b)``: ``u (a eps / 2 + b eps / L) + v (b eps / L - a eps / 2)``, the sum of two
  independent uniforms.

The CDF of a sum of independent uniforms is the piecewise polynomial of :func:`cdf_sum_uniforms`
(inclusion-exclusion over the corners of the box); any mix of uniforms and semicircles is
inverted from its characteristic function (Gil-Pelaez, :func:`cdf_mixture`), with
``phi_uniform(t) = sin(a t) / (a t)`` and ``phi_semicircle(t) = 2 J1(R t) / (R t)``.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from scipy import integrate, optimize, special, stats


def cdf_sum_uniforms(x, half_widths):
    """``P(sum_i U_i <= x)``, ``U_i`` uniform on ``[-a_i, a_i]`` (``a_i >= 0``), exactly.

    Shifted to ``W_i = U_i + a_i`` on ``[0, w_i]``, ``w_i = 2 a_i``:
    ``F(y) = sum_{S} (-1)^{|S|} (y - sum_{i in S} w_i)_+^n / (n! prod w_i)`` with ``y = x + sum a_i``.
    """
    a = np.asarray(half_widths, float)
    # a uniform narrower than 1e-9 of the widest shifts the CDF by less than that: dropped, since the
    # inclusion-exclusion sum divides by the product of the widths (cancellation)
    a = a[a > 1e-9 * a.max()]
    x = np.asarray(x, float)
    n = a.size
    w = 2 * a
    y = x + a.sum()
    total = np.zeros_like(y)
    for subset in itertools.product((0, 1), repeat=n):
        s = np.array(subset, bool)
        total += (-1) ** s.sum() * np.maximum(y - w[s].sum(), 0.0) ** n
    return np.clip(total / (math.factorial(n) * np.prod(w)), 0.0, 1.0)


def semicircle_cdf(x, R):
    """CDF of the projection of a point uniform in a disk of radius ``R`` on a unit direction."""
    x = np.clip(np.asarray(x, float) / R, -1.0, 1.0)
    return 0.5 + (x * np.sqrt(1 - x * x) + np.arcsin(x)) / np.pi


def characteristic(t, uniforms=(), disks=()):
    """Characteristic function of ``sum U_i + sum S_j`` (uniform half-widths ``uniforms``, semicircle
    radii ``disks``) at ``t`` (real, the law is symmetric)."""
    t = np.asarray(t, float)
    out = np.ones_like(t)
    for a in uniforms:
        out = out * np.sinc(a * t / np.pi)
    for R in disks:
        z = R * t
        safe = np.where(z == 0, 1.0, z)
        out = out * np.where(z == 0, 1.0, 2 * special.j1(safe) / safe)
    return out


def cdf_mixture(x, uniforms=(), disks=(), points_per_period: int = 40, tail: float = 1e-10):
    """``P(sum <= x)`` by Gil-Pelaez: ``1/2 + (1/pi) int_0^T sin(t x) phi(t) / t dt`` (symmetric law).

    Simpson's rule with ``points_per_period`` points per period ``pi / sum(widths)`` of the fastest
    oscillation; ``T`` where the envelope of the integrand's tail, ``prod 1 / (a t) prod sqrt(8 / pi)
    (R t)^-1.5`` integrated from ``T`` on, falls below ``tail`` (needs at least two sources)."""
    uniforms = [a for a in uniforms if a > 0]
    disks = [R for R in disks if R > 0]
    scale = sum(uniforms) + sum(disks)
    order = len(uniforms) + 1.5 * len(disks)
    if order < 2:
        raise ValueError("cdf_mixture needs at least two sources (use the closed forms for one)")

    def envelope(t):
        return float(np.prod([1 / (a * t) for a in uniforms]) * np.prod([math.sqrt(8 / math.pi) * (R * t) ** -1.5
                                                                        for R in disks]))
    T = math.pi / scale
    while envelope(T) / order > tail:
        T *= 1.25
    n = int(T * scale / math.pi * points_per_period) | 1
    t = np.linspace(0.0, T, n)[1:]
    phi = characteristic(t, uniforms, disks)
    x = np.atleast_1d(np.asarray(x, float))
    integrand = np.sin(np.outer(x, t)) * phi / t
    # the integrand tends to x at t = 0
    integrand = np.concatenate([x[:, None], integrand], axis=1)
    total = integrate.simpson(integrand, x=np.linspace(0.0, T, n), axis=1)
    return np.clip(0.5 + total / math.pi, 0.0, 1.0)


def quantile_abs(p, cdf, upper):
    """``x`` with ``P(|X| <= x) = p`` for a symmetric law of CDF ``cdf`` supported in ``[-upper, upper]``."""
    return optimize.brentq(lambda x: 2 * cdf(np.array([x]))[0] - 1 - p, 0.0, upper, xtol=1e-14)


def truncnorm_unit_variance(sigma):
    """Variance of ``N(0, sigma^2)`` cut to ``[-1, 1]`` (scipy.stats.truncnorm)."""
    return float(stats.truncnorm(-1 / sigma, 1 / sigma, scale=sigma).var())


def truncated_disk_component_variance(sigma):
    """Variance of one component of an isotropic ``N(0, sigma^2 I)`` point cut to the unit disk:
    ``E r^2 / 2`` by quadrature over the Rayleigh density ``r exp(-r^2 / 2 sigma^2)``."""
    num = integrate.quad(lambda r: r ** 3 * math.exp(-r * r / (2 * sigma ** 2)), 0, 1)[0]
    den = integrate.quad(lambda r: r * math.exp(-r * r / (2 * sigma ** 2)), 0, 1)[0]
    return num / den / 2


def projections(G_row, sources):
    """Split one row ``G_row`` (n,) of an error Jacobian into the scalar laws of each source.

    ``sources``: ``[(kind, eps, cols, block_length)]`` with kind ``"interval"``, ``"disk"`` or
    ``"rhombus"`` (as ``error_reference._sources``). Returns ``(uniform half-widths, disk radii)``.
    """
    uniforms, disks = [], []
    for kind, eps, cols, L in sources:
        g = G_row[cols]
        if kind == "interval":
            uniforms.append(eps * abs(g[0]))
        elif kind == "disk":
            disks.append(eps * math.hypot(g[0], g[1]))
        else:
            a, b = g
            uniforms += [abs(a * eps / 2 + b * eps / L), abs(b * eps / L - a * eps / 2)]
    return uniforms, disks


def variance(uniforms, disks):
    """Variance of the mix: ``a^2 / 3`` per uniform, ``R^2 / 4`` per semicircle."""
    return sum(a * a / 3 for a in uniforms) + sum(R * R / 4 for R in disks)
