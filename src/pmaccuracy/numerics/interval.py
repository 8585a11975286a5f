"""Vectorized interval arithmetic: real intervals, complex rectangles, phasor sums and trigonometric polynomials.

A real interval is a pair of arrays ``lo <= hi`` (:class:`Iv`), a complex one a
pair of real intervals (:class:`Cv`, a rectangle in the plane); every operation
works elementwise on arrays of boxes ``(n,)`` and returns an enclosure of every
value the operation takes over its arguments (inclusion property). Dependency
makes the enclosures wider than the true ranges, by a factor that shrinks
linearly with the boxes' widths, which is what branch and bound
(:mod:`pmaccuracy.accuracy.global_worst`) needs. Plane vectors are sums of
phasors (:class:`Vec`) and scalars built from them trigonometric polynomials
(:class:`Trig`), whose equal terms are merged before the interval evaluation,
which removes most of the dependency on an angle.

Rounding: numpy rounds to nearest; callers widen the final bounds by a relative
``1e-9`` (far above the accumulated rounding of these few dozen operations).
"""

from __future__ import annotations


import numpy as np

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
        with np.errstate(invalid="ignore"):  # 0 * inf: the product's bound is then 0 or inf, see below
            p = (self.lo * other.lo, self.lo * other.hi, self.hi * other.lo, self.hi * other.hi)
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
    if not isinstance(a, GIv):
        return Iv(lo, m)
    pos, neg = a.lo > 0, a.hi < 0
    return GIv(lo, m, tuple(Iv(np.where(pos, d.lo, np.where(neg, -d.hi, h.lo)), np.where(pos, d.hi, np.where(neg, -d.lo, h.hi)))
                           for d, h in ((d, _hull_sym(d)) for d in a.d)))


def iv_sqr(a: Iv) -> Iv:
    """``x^2`` (tighter than ``x * x``)."""
    b = iv_abs(_plain(a))
    val = Iv(b.lo * b.lo, b.hi * b.hi)
    return _chain(a, val, _plain(a) * 2.0) if isinstance(a, GIv) else val


def iv_sqrt(a: Iv) -> Iv:
    """``sqrt(x)`` over the part ``x >= 0`` of the interval (the caller checks ``hi >= 0``)."""
    val = Iv(np.sqrt(np.maximum(a.lo, 0.0)), np.sqrt(np.maximum(a.hi, 0.0)))
    return _chain(a, val, (val * 2.0).reciprocal()) if isinstance(a, GIv) else val


def iv_max(a: Iv, b: Iv) -> Iv:
    """``max(x, y)`` elementwise."""
    val = Iv(np.maximum(a.lo, b.lo), np.maximum(a.hi, b.hi))
    if not isinstance(a, GIv) and not isinstance(b, GIv):
        return val
    da, db = _ders(a), _ders(b)
    first, second = a.lo > b.hi, b.lo > a.hi
    return GIv.make(val, tuple(Iv(np.where(first, x.lo, np.where(second, y.lo, np.minimum(x.lo, y.lo))),
                                  np.where(first, x.hi, np.where(second, y.hi, np.maximum(x.hi, y.hi))))
                               for x, y in zip(da, db)))


def iv_intersect(a: Iv, lo, hi) -> Iv:
    """``a`` cut to ``[lo, hi]`` (empty where ``lo > hi`` afterwards: :meth:`Iv.empty`). With derivatives
    (:class:`GIv`): unknown (``(-inf, inf)``) where the cut removes part of ``a``."""
    val = Iv(np.maximum(a.lo, lo), np.minimum(a.hi, hi))
    if not isinstance(a, GIv):
        return val
    bite = (val.lo > a.lo) | (val.hi < a.hi)
    return GIv.make(val, tuple(Iv(np.where(bite, -np.inf, d.lo), np.where(bite, np.inf, d.hi)) for d in a.d))


def iv_cos(a: Iv) -> Iv:
    """``cos(x)``: the endpoint values, widened to 1 (-1) where a multiple of 2 pi (pi plus one) lies inside."""
    c0, c1 = np.cos(a.lo), np.cos(a.hi)
    lo, hi = np.minimum(c0, c1), np.maximum(c0, c1)
    has_max = TWO_PI * np.ceil(a.lo / TWO_PI) <= a.hi
    has_min = TWO_PI * np.ceil((a.lo - np.pi) / TWO_PI) + np.pi <= a.hi
    full = (a.hi - a.lo) >= TWO_PI
    val = Iv(np.where(has_min | full, -1.0, lo), np.where(has_max | full, 1.0, hi))
    return _chain(a, val, -iv_sin(_plain(a))) if isinstance(a, GIv) else val


def iv_sin(a: Iv) -> Iv:
    """``sin(x) = cos(x - pi/2)``."""
    return iv_cos(a - np.pi / 2)


def iv_arccos(a: Iv) -> Iv:
    """``arccos(x)`` on ``[-1, 1]`` (decreasing; the interval is cut to ``[-1, 1]``)."""
    val = Iv(np.arccos(np.clip(a.hi, -1.0, 1.0)), np.arccos(np.clip(a.lo, -1.0, 1.0)))
    return _chain(a, val, -_inv_sqrt_one_minus_sqr(_plain(a))) if isinstance(a, GIv) else val


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
    val = Iv(np.where(zero, -np.pi, ang.min(axis=0)), np.where(zero, 3 * np.pi, ang.max(axis=0)))
    if not isinstance(z.re, GIv) and not isinstance(z.im, GIv):
        return val
    # d arg z = (re d im - im d re) / |z|^2
    re, im = _plain(z.re), _plain(z.im)
    inv = (iv_sqr(re) + iv_sqr(im)).reciprocal()
    return GIv.make(val, tuple((re * di - im * dr) * inv for dr, di in zip(_ders(z.re), _ders(z.im))))


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


# ---------------------------------------------------------------------------------------------- derivatives
#: Number of pose variables ``(x, y, phi)`` whose partial derivatives :class:`GIv` carries.
NV = 3


def _plain(a) -> Iv:
    return Iv(a.lo, a.hi) if isinstance(a, Iv) else Iv(a)


def _ders(a) -> tuple:
    """Derivative enclosures of an operand: a :class:`GIv`'s own; a plain :class:`Iv` of zero width is a
    constant over the box (derivative 0), one of positive width was computed without derivatives
    (``(-inf, inf)``: nothing known); a number is a constant."""
    if isinstance(a, GIv):
        return a.d
    if isinstance(a, Iv):
        unknown = np.where(a.lo == a.hi, 0.0, np.inf)
        return (Iv(-unknown, unknown),) * NV
    return (Iv(0.0),) * NV


def _hull_sym(d: Iv) -> Iv:
    m = np.maximum(np.abs(d.lo), np.abs(d.hi))
    return Iv(-m, m)


class GIv(Iv):
    """Intervals with enclosures ``d`` of their partial derivatives with respect to the pose ``(x, y, phi)``
    over the box (forward-mode differentiation in interval arithmetic), for the mean-value form
    ``f(X) <= f(c) + sum_j max |df/dX_j| |X_j - c_j|`` (:func:`pmaccuracy.accuracy.interval.box_maxima`).

    Every operation of :class:`Iv` and the functions of this module (``iv_abs``, ``iv_sqr``, ``iv_sqrt``,
    ``iv_max``, ``iv_intersect``, ``iv_cos``, ``iv_sin``, ``iv_arccos``, ``iv_arcsin``, ``cv_angle``) carry the
    derivatives by the chain rule (``|x|`` and ``max`` by the hull of their one-sided derivatives, Clarke's
    generalized gradient). Where a value is unbounded in slope (``sqrt`` at 0, ``1/x`` at 0, ``arccos`` at
    +-1, the angle of a rectangle holding 0) or a cut of :func:`iv_intersect` removes part of the enclosure
    (the formula then only holds at part of the box), the derivative is ``(-inf, inf)``.

    >>> x = GIv(np.array([1.0]), np.array([2.0]), d=(Iv(1.0), Iv(0.0), Iv(0.0)))
    >>> p = x * x
    >>> (float(p.d[0].lo[0]), float(p.d[0].hi[0]))
    (2.0, 4.0)
    """

    __slots__ = ("d",)

    def __init__(self, lo, hi=None, d=None):
        super().__init__(lo, hi)
        self.d = tuple(d) if d is not None else _ders(Iv(self.lo, self.hi))

    @staticmethod
    def make(val: Iv, d) -> "GIv":
        return GIv(val.lo, val.hi, d)

    def __add__(self, other):
        if isinstance(other, (Cv, complex)):
            return Cv._wrap(other) + self
        return GIv.make(_plain(self) + _plain(other), tuple(a + b for a, b in zip(self.d, _ders(other))))

    __radd__ = __add__

    def __neg__(self):
        return GIv.make(-_plain(self), tuple(-a for a in self.d))

    def __sub__(self, other):
        if isinstance(other, (Cv, complex)):
            return Cv._wrap(self) - other
        return GIv.make(_plain(self) - _plain(other), tuple(a - b for a, b in zip(self.d, _ders(other))))

    def __rsub__(self, other):
        return (-self) + other

    def __mul__(self, other):
        if isinstance(other, (Cv, complex)):
            return Cv(self, Iv(0.0)) * other
        a = _plain(self)
        if not isinstance(other, Iv):
            s = np.asarray(other, dtype=float)
            return GIv.make(a * s, tuple(d * s for d in self.d))
        b = _plain(other)
        return GIv.make(a * b, tuple(da * b + a * db for da, db in zip(self.d, _ders(other))))

    __rmul__ = __mul__

    def reciprocal(self) -> "GIv":
        r = _plain(self).reciprocal()
        r2 = iv_sqr(r)
        return GIv.make(r, tuple(-(d * r2) for d in self.d))

    def __truediv__(self, other):
        if not isinstance(other, Iv):
            return self * (1.0 / np.asarray(other, dtype=float))
        return self * (other.reciprocal() if isinstance(other, GIv) else GIv(other.lo, other.hi).reciprocal())

    def magnitude(self) -> np.ndarray:
        """``(..., NV)`` the largest ``|df/dX_j|`` over the box (inf where unknown)."""
        out = [np.maximum(np.abs(d.lo), np.abs(d.hi)) for d in self.d]
        out = [np.where(np.isnan(m), np.inf, m) for m in out]
        return np.stack(np.broadcast_arrays(*out, self.lo), axis=-1)[..., :NV]


def _chain(a, val: Iv, slope: Iv) -> Iv:
    """``val`` with derivative ``slope * a'`` when ``a`` carries derivatives."""
    if not isinstance(a, GIv):
        return val
    return GIv.make(val, tuple(d * slope for d in a.d))


def iv_arcsin(a: Iv) -> Iv:
    """``arcsin(x)`` on ``[-1, 1]`` (increasing; the interval is cut to ``[-1, 1]``)."""
    val = Iv(np.arcsin(np.clip(a.lo, -1.0, 1.0)), np.arcsin(np.clip(a.hi, -1.0, 1.0)))
    if not isinstance(a, GIv):
        return val
    return _chain(a, val, _inv_sqrt_one_minus_sqr(_plain(a)))


def _inv_sqrt_one_minus_sqr(a: Iv) -> Iv:
    w = 1.0 - iv_sqr(a)
    return Iv(np.sqrt(np.maximum(w.lo, 0.0)), np.sqrt(np.maximum(w.hi, 0.0))).reciprocal()
