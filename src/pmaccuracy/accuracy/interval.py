"""Vectorized interval arithmetic and interval enclosures of the closed forms over pose boxes.

A real interval is a pair of arrays ``lo <= hi`` (:class:`Iv`), a complex one a
pair of real intervals (:class:`Cv`, a rectangle in the plane); every operation
works elementwise on arrays of boxes ``(n,)`` and returns an enclosure of every
value the operation takes over its arguments (inclusion property). Dependency
makes the enclosures wider than the true ranges, by a factor that shrinks
linearly with the boxes' widths, which is what branch and bound
(:mod:`pmaccuracy.accuracy.global_worst`) needs.

:func:`leg_box_state` runs a leg's closed-form inverse kinematics
(:meth:`pmaccuracy.model.legs.Chain.state`, same cases: one, two or three revolute
joints) on boxes of poses ``[x0, x1] x [y0, y1] x [phi0, phi1]`` (mm, rad):
joint values, directions, the vectors between joint centres, the constraint
wrench ``(f, m_P)`` and ``B_ii`` as intervals. Everything that holds at every
*feasible* pose of the box (leg reaches it, joints within their ranges, the
working mode's sign of ``B_ii``) is used to narrow the intervals, so the
enclosures bound the feasible part of a box straddling the workspace boundary;
a box proven to hold no feasible pose is flagged. Plane vectors are sums of
phasors (:class:`Vec`) and scalars built from them trigonometric polynomials
(:class:`Trig`), whose equal terms are merged before the interval evaluation,
which removes most of the dependency on phi. :func:`box_maxima` turns the
legs' enclosures into upper bounds of ``dx, dy, dphi, dp`` (Eq. 21-22, the
zonotope of :func:`pmaccuracy.accuracy.bounds.zonotope_maxima`) with ``A^-1 = adj(A) /
det(A)`` (``+inf`` where the determinant's interval contains 0).

Rounding: numpy rounds to nearest; callers widen the final bounds by a relative
``1e-9`` (far above the accumulated rounding of these few dozen operations).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..model.sources import ErrorSources

TWO_PI = 2.0 * np.pi


class Iv:
    """Real intervals ``[lo, hi]`` (arrays of one shape, or scalars), with the interval extensions of + - * /.

    >>> a = Iv(np.array([1.0]), np.array([2.0]))
    >>> p = a * (a - 3.0)
    >>> (float(p.lo[0]), float(p.hi[0]))
    (-4.0, -1.0)
    """

    __slots__ = ("lo", "hi")

    def __init__(self, lo, hi=None):
        self.lo = np.asarray(lo, dtype=float)
        self.hi = self.lo if hi is None else np.asarray(hi, dtype=float)

    @staticmethod
    def _wrap(other) -> "Iv":
        return other if isinstance(other, Iv) else Iv(other)

    def __add__(self, other):
        if isinstance(other, (Cv, complex)):
            return Cv._wrap(other) + self
        o = Iv._wrap(other)
        return Iv(self.lo + o.lo, self.hi + o.hi)

    __radd__ = __add__

    def __neg__(self):
        return Iv(-self.hi, -self.lo)

    def __sub__(self, other):
        o = Iv._wrap(other)
        return Iv(self.lo - o.hi, self.hi - o.lo)

    def __rsub__(self, other):
        return Iv._wrap(other) - self

    def __mul__(self, other):
        if isinstance(other, (Cv, complex)):
            return Cv(self, Iv(0.0)) * other
        if not isinstance(other, Iv):
            s = np.asarray(other, dtype=float)
            return Iv(np.where(s >= 0, s * self.lo, s * self.hi), np.where(s >= 0, s * self.hi, s * self.lo))
        p = (self.lo * other.lo, self.lo * other.hi, self.hi * other.lo, self.hi * other.hi)
        with np.errstate(invalid="ignore"):  # 0 * inf: the product's bound is then 0 or inf, see below
            lo = np.minimum(np.minimum(p[0], p[1]), np.minimum(p[2], p[3]))
            hi = np.maximum(np.maximum(p[0], p[1]), np.maximum(p[2], p[3]))
        return Iv(np.where(np.isnan(lo), -np.inf, lo), np.where(np.isnan(hi), np.inf, hi))

    __rmul__ = __mul__

    def reciprocal(self) -> "Iv":
        """``1 / x``; ``(-inf, inf)`` where the interval contains 0."""
        zero = self.contains_zero()
        with np.errstate(divide="ignore"):
            return Iv(np.where(zero, -np.inf, 1.0 / self.hi), np.where(zero, np.inf, 1.0 / self.lo))

    def __truediv__(self, other):
        if not isinstance(other, Iv):
            return self * (1.0 / np.asarray(other, dtype=float))
        return self * other.reciprocal()

    def contains_zero(self) -> np.ndarray:
        return (self.lo <= 0.0) & (self.hi >= 0.0)

    @property
    def width(self) -> np.ndarray:
        return self.hi - self.lo

    @property
    def mid(self) -> np.ndarray:
        return 0.5 * (self.lo + self.hi)

    def empty(self) -> np.ndarray:
        """True where ``lo > hi`` (an intersection found nothing)."""
        return self.lo > self.hi


def iv_abs(a: Iv) -> Iv:
    """``|x|``: ``[0, max]`` when the interval contains 0."""
    m = np.maximum(np.abs(a.lo), np.abs(a.hi))
    lo = np.where(a.lo >= 0, a.lo, np.where(a.hi <= 0, -a.hi, 0.0))
    return Iv(lo, m)


def iv_sqr(a: Iv) -> Iv:
    """``x^2`` (tighter than ``x * x``)."""
    b = iv_abs(a)
    return Iv(b.lo * b.lo, b.hi * b.hi)


def iv_sqrt(a: Iv) -> Iv:
    """``sqrt(x)`` over the part ``x >= 0`` of the interval (the caller checks ``hi >= 0``)."""
    return Iv(np.sqrt(np.maximum(a.lo, 0.0)), np.sqrt(np.maximum(a.hi, 0.0)))


def iv_max(a: Iv, b: Iv) -> Iv:
    """``max(x, y)`` elementwise."""
    return Iv(np.maximum(a.lo, b.lo), np.maximum(a.hi, b.hi))


def iv_intersect(a: Iv, lo, hi) -> Iv:
    """``a`` cut to ``[lo, hi]`` (empty where ``lo > hi`` afterwards: :meth:`Iv.empty`)."""
    return Iv(np.maximum(a.lo, lo), np.minimum(a.hi, hi))


def iv_cos(a: Iv) -> Iv:
    """``cos(x)``: the endpoint values, widened to 1 (-1) where a multiple of 2 pi (pi plus one) lies inside."""
    c0, c1 = np.cos(a.lo), np.cos(a.hi)
    lo, hi = np.minimum(c0, c1), np.maximum(c0, c1)
    has_max = TWO_PI * np.ceil(a.lo / TWO_PI) <= a.hi
    has_min = TWO_PI * np.ceil((a.lo - np.pi) / TWO_PI) + np.pi <= a.hi
    full = (a.hi - a.lo) >= TWO_PI
    return Iv(np.where(has_min | full, -1.0, lo), np.where(has_max | full, 1.0, hi))


def iv_sin(a: Iv) -> Iv:
    """``sin(x) = cos(x - pi/2)``."""
    return iv_cos(a - np.pi / 2)


def iv_arccos(a: Iv) -> Iv:
    """``arccos(x)`` on ``[-1, 1]`` (decreasing; the interval is cut to ``[-1, 1]``)."""
    return Iv(np.arccos(np.clip(a.hi, -1.0, 1.0)), np.arccos(np.clip(a.lo, -1.0, 1.0)))


class Cv:
    """Complex intervals (rectangles ``re x im``), plane vectors of :mod:`pmaccuracy.numerics.screws` over boxes."""

    __slots__ = ("re", "im")

    def __init__(self, re, im):
        self.re = re if isinstance(re, Iv) else Iv(re)
        self.im = im if isinstance(im, Iv) else Iv(im)

    @staticmethod
    def const(z: complex) -> "Cv":
        z = complex(z)
        return Cv(Iv(z.real), Iv(z.imag))

    @staticmethod
    def _wrap(other) -> "Cv":
        if isinstance(other, Cv):
            return other
        if isinstance(other, Iv):
            return Cv(other, Iv(0.0))
        return Cv.const(other)

    def __add__(self, other):
        o = Cv._wrap(other)
        return Cv(self.re + o.re, self.im + o.im)

    __radd__ = __add__

    def __neg__(self):
        return Cv(-self.re, -self.im)

    def __sub__(self, other):
        o = Cv._wrap(other)
        return Cv(self.re - o.re, self.im - o.im)

    def __rsub__(self, other):
        return Cv._wrap(other) - self

    def __mul__(self, other):
        if isinstance(other, Iv) or np.isrealobj(other) and not isinstance(other, Cv):
            return Cv(self.re * other, self.im * other)
        if not isinstance(other, Cv):  # a complex constant: each part is a linear form of re and im
            z = complex(other)
            return Cv(self.re * z.real - self.im * z.imag, self.re * z.imag + self.im * z.real)
        return Cv(self.re * other.re - self.im * other.im, self.re * other.im + self.im * other.re)

    __rmul__ = __mul__

    def conj(self) -> "Cv":
        return Cv(self.re, -self.im)

    def abs2(self) -> Iv:
        return iv_sqr(self.re) + iv_sqr(self.im)

    def abs(self) -> Iv:
        return iv_sqrt(self.abs2())

    def contains_zero(self) -> np.ndarray:
        return self.re.contains_zero() & self.im.contains_zero()


def cv_cross(a: Cv, b: Cv) -> Iv:
    """``a x b = a_x b_y - a_y b_x`` (:func:`pmaccuracy.numerics.screws.cross`)."""
    return a.re * b.im - a.im * b.re


def cv_dot(a: Cv, b: Cv) -> Iv:
    """``a . b`` (:func:`pmaccuracy.numerics.screws.dot`)."""
    return a.re * b.re + a.im * b.im


def cv_expi(t: Iv) -> Cv:
    """``exp(i t)`` as ``(cos t, sin t)`` intervals."""
    return Cv(iv_cos(t), iv_sin(t))


def cv_angle(z: Cv) -> Iv:
    """An interval of ``arg z`` (rad; not wrapped, width < 2 pi) over the rectangle, ``[-pi, 3 pi]`` wide
    (no information) where the rectangle contains 0.

    A rectangle off the origin sees its extreme rays through corners; if it
    crosses the negative real axis the corner angles are taken in ``[0, 2 pi)``.
    """
    xs = (z.re.lo, z.re.hi, z.re.lo, z.re.hi)
    ys = (z.im.lo, z.im.lo, z.im.hi, z.im.hi)
    ang = np.stack([np.arctan2(y + 0 * x, x + 0 * y) for x, y in zip(xs, ys)])
    crosses = (z.re.hi < 0) & (z.im.lo < 0) & (z.im.hi >= 0)
    ang = np.where(crosses, np.mod(ang, TWO_PI), ang)
    zero = z.contains_zero()
    return Iv(np.where(zero, -np.pi, ang.min(axis=0)), np.where(zero, 3 * np.pi, ang.max(axis=0)))


def unit_cv(z: Cv) -> Cv:
    """``z`` cut to the square ``[-1, 1]^2`` (for unit vectors)."""
    return Cv(iv_intersect(z.re, -1.0, 1.0), iv_intersect(z.im, -1.0, 1.0))


def angle_meets_range(t: Iv, lo: float, hi: float, tol: float) -> np.ndarray:
    """True where some angle of ``t`` lies in ``[lo, hi]`` modulo 2 pi (an R joint's range), slack ``tol``."""
    full = (t.hi - t.lo) >= TWO_PI - 1e-12
    shift = TWO_PI * np.floor((t.lo - (lo - tol)) / TWO_PI)  # t.lo - shift in [lo - tol, lo - tol + 2 pi)
    a = t.lo - shift
    b = t.hi - shift
    return full | (a <= hi + tol) | (b >= lo - tol + TWO_PI)


# ---------------------------------------------------------------------------------------------- phasors
class Vec:
    """A plane vector over boxes as a sum of phasor terms ``m * z * exp(i k . v)``.

    Each term has a multiplier ``m`` (an :class:`Iv`, or None for 1), a complex
    constant ``z`` and integer coefficients ``k`` of the leg's angle variables
    ``v`` (:class:`Iv`: ``phi``, the IK angles ``t``, ``u``, a force angle ``w``).
    Cross and dot products pair the terms and add the constants of pairs with
    the same multipliers and angle difference first: ``sum_j r_j sin(theta + c_j)
    = R sin(theta + C)`` exactly, so a sum of rotating constants (a rigid
    vector turning with phi) has its exact range, and ``x``, ``y`` (multipliers)
    enter once each.
    """

    __slots__ = ("terms",)

    def __init__(self, terms):
        self.terms = [t for t in terms if t[2] != 0]

    @staticmethod
    def const(z: complex, coef=(0, 0, 0, 0)) -> "Vec":
        return Vec([(None, tuple(coef), complex(z))])

    def __add__(self, other: "Vec") -> "Vec":
        return Vec(self.terms + (other.terms if isinstance(other, Vec) else Vec.const(other).terms))

    def __neg__(self) -> "Vec":
        return Vec([(m, k, -z) for m, k, z in self.terms])

    def __sub__(self, other: "Vec") -> "Vec":
        return self + (-other if isinstance(other, Vec) else Vec.const(-complex(other)))

    def scale(self, s) -> "Vec":
        """Times a complex constant or a real :class:`Iv`."""
        if isinstance(s, Iv):
            return Vec([(s if m is None else m * s, k, z) for m, k, z in self.terms])
        return Vec([(m, k, z * complex(s)) for m, k, z in self.terms])

    def turn(self, coef, z: complex = 1.0) -> "Vec":
        """Times the phasor ``z exp(i coef . v)``."""
        return Vec([(m, tuple(a + b for a, b in zip(k, coef)), w * complex(z)) for m, k, w in self.terms])


def _angle(coef, var) -> Iv | float:
    out = 0.0
    for c, v in zip(coef, var):
        if c:
            out = v * float(c) + out
    return out


class Trig:
    """A real scalar over boxes as a sum of terms ``m_1 m_2 ... Re(z exp(i k . v))`` (a trigonometric polynomial
    in the angle variables ``v`` with interval multipliers).

    Sums and products stay in this form (``Re a Re b = (Re(a b) + Re(a conj b)) / 2``); terms with the same
    multipliers and the same ``k`` (up to sign) are merged by adding their constants, so linear combinations
    of sinusoids of one angle are evaluated as one sinusoid (:meth:`iv`: exact range).
    """

    __slots__ = ("terms",)

    def __init__(self, terms, merge: bool = True):
        self.terms = _merge(terms) if merge else list(terms)

    @staticmethod
    def const(c: float) -> "Trig":
        return Trig([((), None, complex(c))])

    def __add__(self, other):
        o = other if isinstance(other, Trig) else Trig.const(other)
        return Trig(self.terms + o.terms)

    __radd__ = __add__

    def __neg__(self):
        return Trig([(m, k, -z) for m, k, z in self.terms], merge=False)

    def __sub__(self, other):
        return self + (-(other if isinstance(other, Trig) else Trig.const(other)))

    def __mul__(self, other):
        if not isinstance(other, Trig):
            c = float(other)
            return Trig([(m, k, z * c) for m, k, z in self.terms], merge=False)
        out = []
        for ma, ka, za in self.terms:
            for mb, kb, zb in other.terms:
                m = ma + mb
                out.append((m, _kadd(ka, kb, 1), 0.5 * za * zb))
                out.append((m, _kadd(ka, kb, -1), 0.5 * za * np.conj(zb)))
        return Trig(out)

    __rmul__ = __mul__

    def remap(self, index: tuple[int, ...], size: int) -> "Trig":
        """Coefficients moved to a larger variable list: entry ``j`` goes to ``index[j]`` of ``size``."""
        out = []
        for m, k, z in self.terms:
            if k is None:
                out.append((m, None, z))
                continue
            kk = [0] * size
            for j, c in enumerate(k):
                kk[index[j]] += c
            out.append((m, tuple(kk), z))
        return Trig(out)

    def iv(self, var) -> Iv:
        """The interval of the scalar: each merged term ``|m| ... |z| cos(k . v + arg z)``."""
        total = Iv(0.0)
        for m, k, z in self.terms:
            th = None if k is None else _angle(k, var)
            val = Iv(z.real) if not isinstance(th, Iv) else iv_cos(th + float(np.angle(z))) * abs(z)
            for factor in _powers(m):
                val = val * factor
            total = total + val
        return total


def _kadd(a, b, sign):
    if a is None:
        return None if b is None else tuple(sign * y for y in b)
    if b is None:
        return a
    return tuple(x + sign * y for x, y in zip(a, b))


def _merge(terms):
    """Terms with equal multipliers (as a multiset) and equal ``+-k`` merged; zero terms dropped."""
    groups: dict = {}
    for m, k, z in terms:
        if z == 0:
            continue
        m = tuple(sorted(m, key=id))
        if k is not None and not any(k):
            k = None
        if k is not None:
            first = next(c for c in k if c)
            if first < 0:   # Re(z e^{ikv}) = Re(conj z e^{-ikv})
                k, z = tuple(-c for c in k), np.conj(z)
        if k is None:
            z = complex(z.real)
        key = (tuple(id(x) for x in m), k)
        if key in groups:
            groups[key][2] += z
        else:
            groups[key] = [m, k, complex(z)]
    return [(m, k, z) for m, k, z in groups.values() if z != 0]


def _powers(m) -> list:
    """Interval factors of a multiplier multiset: a repeated interval squared once (tighter than x * x)."""
    out, seen = [], {}
    for x in m:
        seen.setdefault(id(x), [x, 0])[1] += 1
    for x, count in seen.values():
        while count >= 2:
            out.append(iv_sqr(x))
            count -= 2
        if count:
            out.append(x)
    return out


def _pair_trig(a: Vec, b: Vec, rot: complex) -> Trig:
    """``sum over term pairs of m_a m_b Re(rot conj(z_a) z_b exp(i (k_b - k_a) . v))``."""
    out = []
    for ma, ka, za in a.terms:
        for mb, kb, zb in b.terms:
            m = tuple(x for x in (ma, mb) if x is not None)
            out.append((m, tuple(q - p for p, q in zip(ka, kb)), rot * np.conj(za) * zb))
    return Trig(out)


def t_cross(a: Vec, b: Vec) -> Trig:
    """``a x b = Im(conj(a) b)`` as a :class:`Trig`."""
    return _pair_trig(a, b, -1j)


def t_dot(a: Vec, b: Vec) -> Trig:
    """``a . b = Re(conj(a) b)`` as a :class:`Trig`."""
    return _pair_trig(a, b, 1.0)


def t_parts(a: Vec) -> tuple[Trig, Trig]:
    """Real and imaginary parts of a :class:`Vec` as :class:`Trig`."""
    re = Trig([(() if m is None else (m,), k, z) for m, k, z in a.terms])
    im = Trig([(() if m is None else (m,), k, -1j * z) for m, k, z in a.terms])
    return re, im


def v_cross(a: Vec, b: Vec, var) -> Iv:
    """``a x b`` over the boxes (tight for sums of rotating constants)."""
    return t_cross(a, b).iv(var)


def v_dot(a: Vec, b: Vec, var) -> Iv:
    return t_dot(a, b).iv(var)


def v_cv(a: Vec, var) -> Cv:
    """The rectangle of ``a``: real and imaginary parts, each a grouped sum of ``m R cos/sin(k . v + C)``."""
    groups: dict = {}
    for m, k, z in a.terms:
        key = (id(m), k)
        if key in groups:
            groups[key][2] += z
        else:
            groups[key] = [m, k, z]
    re, im = Iv(0.0), Iv(0.0)
    for m, k, z in groups.values():
        th = _angle(k, var)
        if isinstance(th, Iv):
            cr, ci = iv_cos(th + float(np.angle(z))) * abs(z), iv_sin(th + float(np.angle(z))) * abs(z)
        else:
            cr, ci = Iv(z.real), Iv(z.imag)
        re = re + (cr if m is None else cr * m)
        im = im + (ci if m is None else ci * m)
    return Cv(re, im)


# ---------------------------------------------------------------------------------------------- legs
@dataclass(frozen=True)
class LegBox:
    """One leg's closed forms enclosed over boxes of poses ``(n,)``.

    q : three :class:`Iv` joint values (mm or rad; R values not wrapped)
    dirs : three :class:`Vec` unit directions of the joints (base frame)
    seg : four :class:`Vec` mm: ``seg[k]`` from joint centre ``k`` to the next (``seg[3] = 0``);
        centre 3 is the end frame's origin
    to_p : four :class:`Vec` mm: joint centre ``k`` (3: end origin) minus the platform centre P
    f : :class:`Vec` unit constraint force (0 for a pure couple); m_P : :class:`Iv` mm, its moment about P;
    B : :class:`Iv` ``B_ii``;  var : the angle variables of the phasors
    infeasible : bool ``(n,)``: no pose of the box is reachable within the joint ranges on the working mode
    line : the index of the joint centre on the constraint line (None for a couple)
    """

    q: tuple
    dirs: tuple
    seg: tuple
    to_p: tuple
    f: Vec
    m_P: Iv
    B: Iv
    var: tuple
    infeasible: np.ndarray
    line: int | None
    m_P_trig: Trig | None = None

    def between(self, a: int, b: int) -> Vec:
        """Centre ``b`` minus centre ``a`` (``0..3``), as a sum of segments (no absolute positions)."""
        lo, hi = min(a, b), max(a, b)
        total = Vec([])
        for k in range(lo, hi):
            total = total + self.seg[k]
        return total if a <= b else -total


PHI, T, U, W = (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1)
ZERO = (0, 0, 0, 0)


def _meet_angles(a: Iv, b: Iv) -> Iv:
    """Intersection of two enclosures of the same angle (mod 2 pi): ``b`` moved by whole turns onto ``a``'s
    middle; where either is wider than pi, ``a`` unchanged."""
    turns = np.round((a.mid - b.mid) / TWO_PI)
    lo, hi = b.lo + TWO_PI * turns, b.hi + TWO_PI * turns
    ok = (a.width < np.pi) & (b.width < np.pi) & np.isfinite(lo) & np.isfinite(hi)
    return Iv(np.where(ok, np.maximum(a.lo, lo), a.lo), np.where(ok, np.minimum(a.hi, hi), a.hi))


def leg_box_state(chain, x: Iv, y: Iv, phi: Iv, sigma: float, tol: float = 1e-9) -> LegBox:
    """Interval version of the leg's inverse kinematics on branch ``sigma`` (:meth:`Chain.state`) over boxes.

    Mirrors the closed forms of :meth:`pmaccuracy.model.legs.Chain.ik_branches` (one R:
    two slides from a 2x2 system; two R: a quadratic in the slide, then the
    turning angle ``t`` from the angles of the matched vectors; three R: law of
    cosines, angles ``t`` and ``u``), vectors as phasor sums (:class:`Vec`).
    Narrowing at feasible poses: slide values cut to their ranges (slack
    ``tol``), discriminants to ``>= 0``, the law-of-cosines argument to
    ``[-1, 1]``, ``B_ii`` to the working mode's sign; R values checked against
    their ranges modulo 2 pi. Where a cut leaves nothing the box is infeasible.
    """
    n = x.lo.shape[0]
    joints = chain.joints
    infeasible = np.zeros(n, dtype=bool)
    var = [phi, Iv(np.zeros(n)), Iv(np.zeros(n)), Iv(np.zeros(n))]
    eb = complex(np.exp(1j * chain.base_angle))
    base_z = complex(*chain.base)
    platform_z = complex(*chain.platform)
    pz = Vec([(x, ZERO, 1.0 + 0j), (y, ZERO, 1j)])
    att = Vec.const(platform_z, PHI)                       # exp(i phi) platform, base frame
    g = (pz + att - base_z).scale(eb.conjugate())            # end origin in the leg frame
    dang = chain.platform_angle - chain.base_angle
    oc = np.cumsum([j.offset for j in joints])
    links = [complex(*j.link) for j in joints]
    rot = [complex(np.exp(1j * o)) for o in oc]
    S = phi + (dang - oc[2])
    e_S = complex(np.exp(1j * (dang - oc[2])))             # exp(i S) = e_S exp(i phi)
    rs = [k for k, j in enumerate(joints) if j.kind == "R"]
    q: list = [None, None, None]

    def cut_slide(k: int, val: Iv) -> Iv:
        nonlocal infeasible
        lo, hi = joints[k].range
        out = iv_intersect(val, lo - tol, hi + tol)
        infeasible = infeasible | out.empty()
        return out

    def disc_root(disc: Iv) -> Iv:
        nonlocal infeasible
        infeasible = infeasible | (disc.hi < 0)
        return iv_sqrt(disc)

    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        if len(rs) == 1:
            m = rs[0]
            d = [Vec.const(rot[k] * e_S, PHI) if k >= m else Vec.const(rot[k]) for k in range(3)]
            rhs = g
            for k in range(3):
                rhs = rhs - d[k].scale(links[k])
            a, b = (k for k in range(3) if k != m)
            den = v_cross(d[a], d[b], var)
            q[a] = cut_slide(a, v_cross(rhs, d[b], var) / den)
            q[b] = cut_slide(b, v_cross(d[a], rhs, var) / den)
            q[m] = S
        elif len(rs) == 2:
            m, nn = rs
            k = 3 - m - nn
            fixed = Vec.const(sum(rot[j] * links[j] for j in range(m)) + 0j) + \
                Vec.const(sum(rot[j] * links[j] for j in range(nn, 3)) * e_S + 0j, PHI)
            V = complex(sum(np.exp(1j * oc[j]) * links[j] for j in range(m, nn)))
            Wv = g - fixed
            if m <= k < nn:
                ek = Vec.const(rot[k])
                root = disc_root(v_dot(Wv, Wv, var) - (V.real * rot[k].imag - V.imag * rot[k].real) ** 2)
                qk = cut_slide(k, root * sigma + (-(V.real * rot[k].real + V.imag * rot[k].imag)))
                t = cv_angle(v_cv(Wv, var)) - cv_angle(v_cv(Vec.const(V) + ek.scale(qk), var))
            else:
                ek = Vec.const(rot[k] * e_S, PHI) if k >= nn else Vec.const(rot[k])
                root = disc_root(abs(V) ** 2 - iv_sqr(v_cross(Wv, ek, var)))
                qk = cut_slide(k, v_dot(Wv, ek, var) + root * sigma)
                t = cv_angle(v_cv(Wv - ek.scale(qk), var)) - float(np.angle(V))
                # W - q e_k = e_k (i s - sigma sqrt(|V|^2 - s^2)) with s = e_k x W: its angle is
                # arg e_k + (arcsin(s/|V|) or pi - arcsin(s/|V|)), monotone in s (one occurrence)
                sv = iv_intersect(v_cross(ek, Wv, var), -abs(V), abs(V))
                infeasible = infeasible | sv.empty()
                a = Iv(np.arcsin(np.clip(sv.lo / abs(V), -1, 1)), np.arcsin(np.clip(sv.hi / abs(V), -1, 1)))
                a = a if sigma < 0 else Iv(np.pi - a.hi, np.pi - a.lo)
                arg_ek = phi + float(np.angle(rot[k] * e_S)) if k >= nn else float(np.angle(rot[k]))
                t = _meet_angles(a + arg_ek - float(np.angle(V)), t)
                infeasible = infeasible | t.empty()
            var[1] = t
            q[k] = qk
            q[m] = t
            q[nn] = S - t
            d = [Vec.const(rot[j]) if j < m else Vec.const(rot[j], T) if j < nn else Vec.const(rot[j] * e_S, PHI)
                 for j in range(3)]
        else:
            l1, l2, l3 = links
            L1, L2 = abs(l1), abs(l2)
            Wv = g - Vec.const(l3 * complex(np.exp(1j * dang)), PHI)
            c = (v_dot(Wv, Wv, var) - (L1 ** 2 + L2 ** 2)) / (2 * L1 * L2)
            c = iv_intersect(c, -1.0 - 1e-12, 1.0 + 1e-12)
            infeasible = infeasible | c.empty()
            ac = iv_arccos(c)
            rel = (ac if sigma > 0 else -ac) + (float(np.angle(l1)) - float(np.angle(l2)))
            var[2] = rel
            aW = cv_angle(v_cv(Wv, var))
            t1 = aW - cv_angle(v_cv(Vec.const(l1) + Vec.const(l2, U), var))
            # the second link's angle t1 + rel = arg W - arg(l1 exp(-i rel) + l2): rel enters once; both
            # enclosures hold (aligned to the same turn), so their intersection does
            t2 = aW - cv_angle(v_cv(Vec.const(l1, (0, 0, -1, 0)) + Vec.const(l2), var))
            t2 = _meet_angles(t2, t1 + rel)
            infeasible = infeasible | t2.empty()
            var[1] = t2
            q[0] = t1 - oc[0]
            q[1] = rel - joints[1].offset
            q[2] = S - q[0] - q[1]
            d = [Vec.const(1.0, (0, 1, -1, 0)), Vec.const(1.0, T), Vec.const(complex(np.exp(1j * dang)), PHI)]
        for k, joint in enumerate(joints):
            if joint.kind == "R" and joint.limited:
                lo, hi = joint.range
                infeasible = infeasible | ~angle_meets_range(q[k], lo, hi, tol)
        dirs = tuple(dk.scale(eb) for dk in d)
        seg = []
        for k, joint in enumerate(joints):
            if joint.kind == "P":
                seg.append(dirs[k].scale(q[k]) + dirs[k].scale(links[k]))
            else:
                seg.append(dirs[k].scale(links[k]))
        seg.append(Vec([]))
        to_p = [None, None, None, att]
        for k in (2, 1, 0):
            to_p[k] = to_p[k + 1] - seg[k]
        lb = LegBox(q=tuple(q), dirs=dirs, seg=tuple(seg), to_p=tuple(to_p), f=Vec([]), m_P=Iv(0.0), B=Iv(0.0),
                    var=tuple(var), infeasible=infeasible, line=None)
        return _wrench(chain, lb, n)


def _wrench(chain, lb: LegBox, n: int) -> LegBox:
    """The constraint wrench of the passive joints and ``B_ii`` (:meth:`Chain._screw_state` over boxes)."""
    i, j = chain.passive_indices
    ki, kj = chain.joints[i].kind, chain.joints[j].kind
    a = chain.actuated_index
    act_R = chain.joints[a].kind == "R"
    infeasible = lb.infeasible
    var = list(lb.var)
    if ki == "P" and kj == "P":
        return LegBox(q=lb.q, dirs=lb.dirs, seg=lb.seg, to_p=lb.to_p, f=Vec([]), m_P=Iv(np.ones(n)),
                      B=Iv(np.ones(n) if act_R else np.zeros(n)), var=lb.var, infeasible=infeasible, line=None,
                      m_P_trig=Trig.const(1.0))
    if ki == "R" and kj == "R":
        segs = [k for k in range(i, j) if lb.seg[k].terms]
        k = segs[0] if len(segs) == 1 else None
        slide = k is not None and chain.joints[k].kind == "P" and chain.joints[k].link == (0.0, 0.0)
        if k is not None and chain.joints[k].kind == "R":   # one rigid link: f along it
            f = lb.dirs[k].scale(links_unit(chain, k))
        elif slide and np.all((lb.q[k].lo > 0) | lb.infeasible):   # one slide of positive length: f along it
            f = lb.dirs[k]
        elif slide and np.all((lb.q[k].hi < 0) | lb.infeasible):
            f = lb.dirs[k].scale(-1.0)
        else:
            var[3] = cv_angle(v_cv(lb.between(i, j), var))
            f = Vec.const(1.0, W)
        line = i
    else:
        line = i if ki == "R" else j
        f = (lb.dirs[j] if ki == "R" else lb.dirs[i]).scale(1j)
    var = tuple(var)
    m_P_trig = t_cross(lb.to_p[line], f)
    m_P = m_P_trig.iv(var)
    B = v_cross(lb.between(a, line), f, var) if act_R else v_dot(f, lb.dirs[a], var)
    if chain.n_branches == 2:   # on the working mode's branch sign(B_ii) = working_mode
        B = iv_intersect(B, 0.0, np.inf) if chain.working_mode > 0 else iv_intersect(B, -np.inf, 0.0)
        infeasible = infeasible | B.empty()
    return LegBox(q=lb.q, dirs=lb.dirs, seg=lb.seg, to_p=lb.to_p, f=f, m_P=m_P, B=B, var=var,
                  infeasible=infeasible, line=line, m_P_trig=m_P_trig)


def links_unit(chain, k: int) -> complex:
    lz = complex(*chain.joints[k].link)
    return lz / abs(lz)


def leg_half_width_box(chain, leg_sources, lb: LegBox) -> Iv:
    """Interval of the leg's half-width ``c_i`` (mm): :func:`pmaccuracy.model.sources.states_half_widths` over boxes.

    Each joint moment ``m_P + (P - c) x f`` is written ``(line - c) x f`` with the
    vector between the two joint centres as a sum of segments.
    """
    n = lb.infeasible.shape[0]
    couple = lb.line is None
    var = lb.var
    c = Iv(np.zeros(n))
    abs_f = 0.0 if couple else 1.0
    for k, (joint, e) in enumerate(zip(chain.joints, leg_sources)):
        if e.radial or e.position:
            c = c + (e.radial + e.position) * abs_f
        if e.direction:
            mom = Iv(np.ones(n)) if couple else iv_abs(v_cross(lb.between(k, lb.line), lb.f, var))
            c = c + mom * e.direction
        if e.angular or e.lateral:
            # moment about the block's centre: a bushing at centre k, a carriage at b_k = centre k + q_k e_k
            if couple:
                tilt = Iv(np.ones(n))
            elif joint.block_kind == "bushing":
                tilt = iv_abs(v_cross(lb.between(k, lb.line), lb.f, var))
            else:
                tilt = iv_abs(v_cross(lb.between(k, lb.line) - lb.dirs[k].scale(lb.q[k]), lb.f, var))
            if e.angular:
                c = c + tilt * e.angular
            if e.lateral:
                shift = iv_abs(v_dot(lb.f, lb.dirs[k].scale(1j), var)) * e.lateral
                c = c + iv_max(shift, tilt * (2 * e.lateral / e.block_length))
        if e.actuator:
            c = c + iv_abs(lb.B) * e.actuator
        if e.length and joint.link != (0.0, 0.0):
            c = c + iv_abs(v_dot(lb.f, lb.dirs[k].scale(links_unit(chain, k)), var)) * e.length
    return c


#: Most pieces a leg's turning angle is split into by :func:`box_maxima` (near the leg's serial singularity).
MAX_ANGLE_PIECES = 32


def box_maxima(robot, sources: ErrorSources, boxes: np.ndarray, sigmas: tuple[float, float, float],
               tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Upper bounds of ``dx, dy, dphi, dp`` (mm, mm, rad, mm) over boxes of poses, refined near serial singularities.

    Same contract as :func:`box_maxima_once` (the bounds), evaluated once; then, in the boxes where a leg's
    turning angle ``t`` (its first angle variable, ``var[1]`` of :class:`LegBox`) has an enclosure much wider
    than the box (width ``w_t > 2 s / ell``, ``s`` the box's largest side with phi times the characteristic
    length ``ell``, mm): a box touching the leg's serial singularity (the workspace boundary where its distal
    link is normal to the guide, ``B_ii = 0``), where ``t`` varies like the square root of the distance and
    every enclosure using ``t`` as an independent interval stays loose. There the leg whose ratio
    ``w_t ell / s`` is largest has ``[t]`` cut into ``K = min(ceil(w_t ell / (2 s)),``
    :data:`MAX_ANGLE_PIECES` ``)`` equal pieces and the bounds are evaluated once per piece. Every feasible pose of
    the box has its ``t`` in one piece, so the largest bound over the pieces not proven infeasible encloses the
    maximum too; the smaller of the two enclosures is returned (both hold).
    """
    upper, infeasible, det_zero, t = box_maxima_once(robot, sources, boxes, sigmas, tol)
    ell = robot.characteristic_length
    side = np.max((boxes[:, 1::2] - boxes[:, 0::2]) * np.array([1.0, 1.0, ell]), axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(np.isfinite(t[:, :, 1] - t[:, :, 0]), (t[:, :, 1] - t[:, :, 0]) * ell, 0.0) / \
            np.maximum(side, 1e-300)[:, None]
    leg = np.argmax(ratio, axis=1)
    rows = np.arange(boxes.shape[0])
    pieces = np.minimum(np.ceil(ratio[rows, leg] / 2.0), MAX_ANGLE_PIECES)
    split = ~infeasible & (pieces >= 2)
    if not np.any(split):
        return upper, infeasible, det_zero
    idx = np.flatnonzero(split)
    k = pieces[idx].astype(int)
    rep = np.repeat(idx, k)                                      # one row per piece
    j = np.arange(rep.size) - np.repeat(np.cumsum(k) - k, k)     # piece number within its box
    kk = np.repeat(k, k).astype(float)
    lo, hi = t[rep, leg[rep], 0], t[rep, leg[rep], 1]
    width = (hi - lo) / kk
    limits = np.empty((rep.size, len(robot.chains), 2))
    limits[:, :, 0], limits[:, :, 1] = -np.inf, np.inf
    limits[np.arange(rep.size), leg[rep], 0] = np.where(j == 0, lo, lo + j * width)
    limits[np.arange(rep.size), leg[rep], 1] = np.where(j == kk - 1, hi, lo + (j + 1) * width)
    up_p, inf_p, dz_p, _ = box_maxima_once(robot, sources, boxes[rep], sigmas, tol, limits)
    up_p = np.where(inf_p[:, None], 0.0, up_p)                   # pieces holding no feasible pose
    up_s = np.zeros((idx.size, 4))
    np.maximum.at(up_s, np.searchsorted(idx, rep), up_p)
    all_inf = np.ones(idx.size, dtype=bool)
    np.logical_and.at(all_inf, np.searchsorted(idx, rep), inf_p)
    dz_s = np.zeros(idx.size, dtype=bool)
    np.logical_or.at(dz_s, np.searchsorted(idx, rep), dz_p & ~inf_p)
    upper, infeasible, det_zero = upper.copy(), infeasible.copy(), det_zero.copy()
    upper[idx] = np.minimum(upper[idx], up_s)
    infeasible[idx] = all_inf
    det_zero[idx] = det_zero[idx] & dz_s
    return upper, infeasible, det_zero


def box_maxima_once(robot, sources: ErrorSources, boxes: np.ndarray, sigmas: tuple[float, float, float],
                    tol: float = 1e-9, angle_limits: np.ndarray | None = None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Upper bounds of ``dx, dy, dphi, dp`` (mm, mm, rad, mm) over boxes of poses.

    Parameters
    ----------
    boxes : ``(n, 6)`` ``[x0, x1, y0, y1, phi0, phi1]`` mm, mm, rad
    sigmas : each leg's IK branch (the root sign of its working mode)
    angle_limits : optional ``(n, 3, 2)`` rad: only the poses whose leg ``i`` turning angle ``t`` (``var[1]``)
        lies in ``[lo, hi]`` count (``-inf, inf``: no limit); ``[t]`` is intersected with it

    Returns ``upper (n, 4)`` (``+inf`` where ``det A`` may vanish), ``infeasible (n,)``
    (no pose of the box, with the angle limits, is in the workspace), ``det_has_zero (n,)`` and each leg's
    ``[t]`` ``(n, 3, 2)`` rad.
    With ``c_i`` the half-width intervals and ``A^-1 = adj(A) / det A``::

        dx <= sum_i c_i^hi |A^-1[0, i]|^hi                  (likewise dy, dphi)
        dp <= max over t of sqrt(max v_x^2 + max v_y^2),  v = sum_i t_i c_i A^-1[:2, i]
    """
    x, y, phi = Iv(boxes[:, 0], boxes[:, 1]), Iv(boxes[:, 2], boxes[:, 3]), Iv(boxes[:, 4], boxes[:, 5])
    n = boxes.shape[0]
    infeasible = np.zeros(n, dtype=bool)
    rows, rows_iv, cs, t_encl = [], [], [], []
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        gvar = [phi]
        for i, (chain, leg, sigma) in enumerate(zip(robot.chains, sources.legs, sigmas)):
            lb = leg_box_state(chain, x, y, phi, sigma, tol)
            if angle_limits is not None:
                t = lb.var[1]
                t = Iv(np.maximum(t.lo, angle_limits[:, i, 0]), np.minimum(t.hi, angle_limits[:, i, 1]))
                lb = _wrench(chain, replace(lb, var=(lb.var[0], t) + tuple(lb.var[2:]),
                                            infeasible=lb.infeasible | t.empty()), n)
            t_encl.append((np.broadcast_to(lb.var[1].lo, (n,)), np.broadcast_to(lb.var[1].hi, (n,))))
            infeasible |= lb.infeasible
            index = (0, 1 + 3 * i, 2 + 3 * i, 3 + 3 * i)
            gvar.extend(lb.var[1:])
            fx, fy = t_parts(lb.f)
            rows.append(tuple(t.remap(index, 10) for t in (fx, fy, lb.m_P_trig)))
            fc = v_cv(lb.f, lb.var)
            rows_iv.append((fc.re, fc.im, lb.m_P))
            cs.append(leg_half_width_box(chain, leg, lb))
        A = rows

        def minor(r0, r1, c0, c1):   # a trigonometric polynomial: one interval evaluation at the end
            return A[r0][c0] * A[r1][c1] - A[r0][c1] * A[r1][c0]

        # adj(A)[r, i] = cofactor of A[i, r]
        adj = [[None] * 3 for _ in range(3)]
        for i in range(3):
            ri = [k for k in range(3) if k != i]
            for r in range(3):
                cc = [k for k in range(3) if k != r]
                m = minor(ri[0], ri[1], cc[0], cc[1])
                adj[r][i] = m if (i + r) % 2 == 0 else -m
        # the same with interval products; both enclose the true values, so their intersection does
        B_ = rows_iv
        adj_iv = [[None] * 3 for _ in range(3)]
        for i in range(3):
            ri = [k for k in range(3) if k != i]
            for r in range(3):
                cc = [k for k in range(3) if k != r]
                m = B_[ri[0]][cc[0]] * B_[ri[1]][cc[1]] - B_[ri[0]][cc[1]] * B_[ri[1]][cc[0]]
                adj_iv[r][i] = m if (i + r) % 2 == 0 else -m
        det_iv = B_[0][0] * adj_iv[0][0] + B_[0][1] * adj_iv[1][0] + B_[0][2] * adj_iv[2][0]

        def meet(a: Iv, b: Iv) -> Iv:
            return Iv(np.maximum(a.lo, b.lo), np.minimum(a.hi, b.hi))

        det = meet((A[0][0] * adj[0][0] + A[0][1] * adj[1][0] + A[0][2] * adj[2][0]).iv(gvar), det_iv)
        adj = [[meet(adj[r][i].iv(gvar), adj_iv[r][i]) for i in range(3)] for r in range(3)]
        det_zero = det.contains_zero() | ~np.isfinite(det.lo) | ~np.isfinite(det.hi)
        inv = [[adj[r][i] / det for i in range(3)] for r in range(3)]
        upper = np.zeros((n, 4))
        for r in range(3):
            total = np.zeros(n)
            for i in range(3):
                total = total + cs[i].hi * iv_abs(inv[r][i]).hi
            upper[:, r] = total
        best = np.zeros(n)
        for t in ((1, 1, 1), (1, 1, -1), (1, -1, 1), (1, -1, -1)):
            vx, vy = Iv(0.0), Iv(0.0)
            for i in range(3):
                vx = vx + cs[i] * inv[0][i] * float(t[i])
                vy = vy + cs[i] * inv[1][i] * float(t[i])
            best = np.maximum(best, np.sqrt(iv_sqr(vx).hi + iv_sqr(vy).hi))
        upper[:, 3] = best
    upper = np.where(det_zero[:, None] | np.isnan(upper), np.inf, upper)
    t_out = np.stack([np.stack(p, axis=-1) for p in t_encl], axis=1)
    return upper, infeasible, det_zero, t_out
