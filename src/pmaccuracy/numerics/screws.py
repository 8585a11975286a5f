"""Planar screw theory: rigid transforms, joint twists, constraint wrenches and their pairing.

Plane vectors are complex numbers ``z = x + i y`` (mm), so that a rotation by
``a`` is ``exp(i a) z`` and ``E z`` (the right-angle rotation of the paper,
``E = [[0, -1], [1, 0]]``) is ``1j * z``. Every function broadcasts over
leading axes; angles in rad, lengths in mm.

Conventions (Modern Robotics, Ch. 3, restricted to the plane):

* a **twist** ``(omega, v)``: angular rate ``omega`` and the velocity ``v``
  of the point of the moving body that is at the base origin. A revolute
  joint at centre ``c`` has the unit twist ``(1, -E c)``; a prismatic joint
  with unit direction ``e`` has ``(0, e)``.
* a **wrench** ``(f, m)``: force ``f`` and its moment ``m`` about the base
  origin. A force along the line through ``c`` has ``m = c x f``.
* the **pairing** (reciprocal product, power) is ``m omega + f . v``.

A leg whose actuated joint is locked keeps two passive joints; the wrench
reciprocal to both of their twists is the leg's **constraint wrench**
(:func:`constraint_wrench`). Paired with the platform twist it gives one row
of ``A`` (paper Eq. 3-4a), paired with the actuated joint's twist the entry
``B_ii``: ``A [p_dot; phi_dot] = B q_dot``.
"""

from __future__ import annotations

import numpy as np


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Planar cross product ``a x b = a_x b_y - a_y b_x`` of complex vectors, shape ``(...)``.

    >>> float(cross(1 + 0j, 1j))
    1.0
    """
    return np.imag(np.conj(a) * b)


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Planar dot product ``a . b`` of complex vectors, shape ``(...)``.

    >>> float(dot(3 + 4j, 1 + 0j))
    3.0
    """
    return np.real(np.conj(a) * b)


def expi(angle: np.ndarray | float) -> np.ndarray:
    """The unit vector ``vec(t) = [cos t, sin t]`` as the complex number ``exp(i t)``."""
    return np.exp(1j * np.asarray(angle, dtype=float))


def wrap(angle: np.ndarray | float) -> np.ndarray:
    """Angles wrapped to ``(-pi, pi]`` (rad): ``a - 2 pi ceil(a / (2 pi) - 1/2)``.

    (``ceil`` rather than ``mod``: the same values, ten times faster on arrays.)

    >>> wrap(np.array([np.pi, -np.pi, 4.0])).round(6).tolist()
    [3.141593, 3.141593, -2.283185]
    """
    angle = np.asarray(angle, dtype=float)
    return angle - (2 * np.pi) * np.ceil(angle * (0.5 / np.pi) - 0.5)


def to_complex(xy: np.ndarray) -> np.ndarray:
    """``(..., 2)`` real array -> ``(...)`` complex."""
    xy = np.asarray(xy, dtype=float)
    return xy[..., 0] + 1j * xy[..., 1]


def to_xy(z: np.ndarray) -> np.ndarray:
    """``(...)`` complex -> ``(..., 2)`` real array."""
    z = np.asarray(z)
    return np.stack([z.real, z.imag], axis=-1)


# ---------------------------------------------------------------- rigid transforms
# A planar rigid transform is a pair (angle a, translation t): x -> t + exp(i a) x.

def compose(t1: tuple[np.ndarray, np.ndarray], t2: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """``T1 T2``: ``(a1 + a2, t1 + exp(i a1) t2)``.

    >>> a, t = compose((np.pi / 2, 0j), (0.0, 1 + 0j))
    >>> round(float(a), 6), complex(np.round(t, 12))
    (1.570796, 1j)
    """
    a1, p1 = t1
    a2, p2 = t2
    return a1 + a2, p1 + expi(a1) * p2


def invert(t: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """``T^-1 = (-a, -exp(-i a) t)``."""
    a, p = t
    return -a, -expi(-a) * p


def identity() -> tuple[float, complex]:
    """The identity transform ``(0, 0)``."""
    return 0.0, 0j


# ---------------------------------------------------------------- twists and wrenches

def revolute_twist(centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit twist ``(1, -E c)`` of a revolute joint at ``c`` (complex, mm).

    >>> w, v = revolute_twist(np.array(2 + 0j))
    >>> float(w), complex(v)
    (1.0, -2j)
    """
    centre = np.asarray(centre)
    return np.ones(centre.shape), -1j * centre


def prismatic_twist(direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit twist ``(0, e)`` of a prismatic joint with unit direction ``e`` (complex)."""
    direction = np.asarray(direction)
    return np.zeros(direction.shape), direction


def pairing(wrench: tuple[np.ndarray, np.ndarray], twist: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Reciprocal product ``m omega + f . v`` of a wrench ``(f, m)`` and a twist ``(omega, v)``.

    >>> f, m = np.array(1 + 0j), np.array(0.0)        # unit force along x through the origin
    >>> float(pairing((f, m), revolute_twist(np.array(1j))))  # joint 1 mm above the line: moment arm
    1.0
    """
    f, m = wrench
    omega, v = twist
    return m * omega + dot(f, v)


def force_through(point: np.ndarray, force: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Wrench ``(f, c x f)`` of the force ``f`` acting along the line through ``c``."""
    return force, cross(point, force)


def constraint_wrench(kinds: tuple[str, str], points: tuple[np.ndarray, np.ndarray],
                      directions: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The wrench reciprocal to two passive joint twists, normalized (a leg's constraint, 1-DOF planar).

    ``kinds`` are the joint types of the two passive joints in chain order
    (base to platform), ``points`` their centres (used for R) and
    ``directions`` their unit directions (used for P), complex, shape ``(...)``.

    * R at ``c1``, R at ``c2``: the force ``f = (c2 - c1) / |c2 - c1|`` along
      the line through both centres (NaN where they coincide);
    * R at ``c`` and P with direction ``e`` (either order): ``f = E e`` (the
      normal of the slide) through ``c``;
    * P, P: the pure couple ``f = 0, m = 1``.

    Each is reciprocal to both twists: a force through a revolute centre does
    no work on it, a force normal to a slide none on the slide, and a couple
    none on any translation.

    >>> f, m = constraint_wrench(("R", "R"), (np.array(0j), np.array(2 + 0j)), (None, None))
    >>> complex(f), float(m)
    ((1+0j), 0.0)
    """
    k1, k2 = kinds
    if k1 == "R" and k2 == "R":
        d = points[1] - points[0]
        with np.errstate(invalid="ignore", divide="ignore"):
            f = d / np.abs(d)
        return force_through(points[0], f)
    if k1 == "P" and k2 == "P":
        shape = np.shape(directions[0])
        return np.zeros(shape, dtype=complex), np.ones(shape)
    centre = points[0] if k1 == "R" else points[1]
    slide = directions[1] if k1 == "R" else directions[0]
    return force_through(centre, 1j * slide)
