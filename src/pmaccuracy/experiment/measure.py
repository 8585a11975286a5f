"""Measurement helpers for assembly errors and joint clearances (paper Sec. 5.1.1 and 5.1.2).

* Assembly errors of the actuated guides (Sec. 5.1.1): four holes along each
  linear guide are located by the camera; a straight line fitted through them
  gives the guide's direction. The first guide serves as the reference (the
  paper takes it as the y-axis, so ``dbeta_1 = 0``) and ``dbeta_i`` is the
  deviation of guide ``i`` from its nominal angle relative to guide 1.
* Joint clearances (Sec. 5.1.2): the angular clearance of a linear bearing is
  ``delta_LB / L_s`` (the change of a dial reading at the end of the shaft
  when it is pushed back and forth, over the shaft length); the radial
  clearance of a revolute joint is half the difference of the hole and pin
  diameters.

Lengths in mm, angles in rad. Invalid input raises
:class:`~pmaccuracy.errors.ConfigError` (a ``ValueError``) naming the argument.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError

#: Points closer together than this fraction of their magnitude (plus 1e-12 mm) count as identical.
_DEGENERATE_RTOL = 1e-12


@dataclass(frozen=True)
class LineFit:
    """A total-least-squares line through points.

    ``angle``: direction of the line in rad, in (-pi, pi], oriented from the
    first point towards the last; ``centroid``: a point of the line ``(2,)``, mm;
    ``rms_mm``: RMS perpendicular distance of the points from the line
    (straightness of the holes); ``n_points``: number of points.
    """

    angle: float
    centroid: tuple[float, float]
    rms_mm: float
    n_points: int

    @property
    def direction(self) -> np.ndarray:
        """Unit vector ``(2,)`` ``[cos angle, sin angle]``."""
        return np.array([math.cos(self.angle), math.sin(self.angle)])


def _points(points: np.ndarray, name: str) -> np.ndarray:
    """Check an ``(N, 2)`` array of finite coordinates with N >= 2."""
    try:
        arr = np.asarray(points, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError("must be an (N, 2) array of numbers", key=name) from None
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ConfigError(f"must have shape (N, 2), got {arr.shape}", key=name)
    if arr.shape[0] < 2:
        raise ConfigError(f"needs at least 2 points to define a line, got {arr.shape[0]}", key=name)
    if not np.all(np.isfinite(arr)):
        raise ConfigError("contains NaN or infinite coordinates", key=name)
    return arr


def fit_line(points: np.ndarray, *, name: str = "points") -> LineFit:
    """Total-least-squares line through ``points`` ``(N, 2)`` mm, N >= 2.

    With ``c`` the centroid and ``U S V^T`` the SVD of ``points - c``, the
    line's direction is the first right singular vector ``V[0]`` (it minimises
    the sum of squared *perpendicular* distances, unlike ``np.polyfit`` which
    minimises vertical ones and fails for vertical lines). The direction is
    oriented so that the last point projects ahead of the first. The RMS
    perpendicular distance is ``S[1] / sqrt(N)``.

    Raises :class:`ConfigError` if the points coincide (no direction) or the
    first and last points project to the same place (no orientation).
    """
    arr = _points(points, name)
    centroid = arr.mean(axis=0)
    centred = arr - centroid
    _, sing, vt = np.linalg.svd(centred, full_matrices=False)
    scale = float(np.max(np.abs(arr))) + 1e-12
    # all points identical (to rounding): the line has no direction
    if sing[0] <= _DEGENERATE_RTOL * scale * math.sqrt(len(arr)) + 1e-12:
        raise ConfigError("points are all identical; a line needs distinct points", key=name)
    direction = vt[0]
    along = float((arr[-1] - arr[0]) @ direction)
    # first and last points at the same position along the line: orientation undefined
    if abs(along) <= _DEGENERATE_RTOL * scale + 1e-12:
        raise ConfigError("first and last points project to the same place; the line's orientation is undefined",
                          key=name)
    if along < 0:
        direction = -direction
    rms = float(sing[1] / math.sqrt(len(arr))) if len(sing) > 1 else 0.0
    angle = math.atan2(direction[1], direction[0])
    return LineFit(angle=angle, centroid=(float(centroid[0]), float(centroid[1])), rms_mm=rms, n_points=len(arr))


def guide_direction(hole_centres: np.ndarray) -> float:
    """Angle (rad, in (-pi, pi]) of a linear guide from its hole centres ``(N, 2)`` mm, N >= 2.

    The total-least-squares line of :func:`fit_line`, oriented from the first
    hole towards the last.
    """
    return fit_line(hole_centres, name="hole_centres").angle


def wrap_half_turn(angle: float) -> float:
    """Angle (rad) folded into (-pi/2, pi/2] modulo pi: ``pi/2 - ((pi/2 - a) mod pi)``.

    Lines have no orientation, so their angles are defined modulo pi.
    """
    q = math.pi / 2
    return q - math.fmod(math.fmod(q - angle, math.pi) + math.pi, math.pi)


def assembly_angle_error(holes: np.ndarray, reference_holes: np.ndarray, nominal_angle: float | None = None) -> float:
    """Assembly angle error ``dbeta`` (rad) of a guide relative to the reference guide.

    ``holes`` and ``reference_holes`` are hole centres ``(N, 2)`` and ``(M, 2)``
    (mm, N, M >= 2) along the guide and along the reference guide (guide 1 in
    the paper, which makes ``dbeta_1 = 0``). With fitted line angles ``a`` and
    ``a_ref`` (:func:`guide_direction`) and the nominal angle ``n`` from the
    reference guide to this one (e.g. ``(alpha_i + beta_i) - (alpha_1 + beta_1)``;
    0 when not given, i.e. parallel guides)::

        dbeta = wrap(a - a_ref - n)    folded into (-pi/2, pi/2]

    The fold makes the result independent of the order in which the holes of
    either guide are listed; ``dbeta > 0`` is a counter-clockwise deviation.
    """
    angle = guide_direction(holes)
    reference = fit_line(reference_holes, name="reference_holes").angle
    nominal = 0.0 if nominal_angle is None else float(nominal_angle)
    if not math.isfinite(nominal):
        raise ConfigError(f"must be finite, got {nominal}", key="nominal_angle")
    return wrap_half_turn(angle - reference - nominal)


def _nonnegative(value: float | np.ndarray, name: str, *, positive: bool = False) -> np.ndarray:
    """Array of finite values >= 0 (> 0 with ``positive``) or ConfigError naming ``name``."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"must be a number, got {value!r}", key=name) from None
    if not np.all(np.isfinite(arr)):
        raise ConfigError(f"must be finite, got {value!r}", key=name)
    if positive and np.any(arr <= 0):
        raise ConfigError(f"must be positive, got {value!r}", key=name)
    if np.any(arr < 0):
        raise ConfigError(f"must not be negative, got {value!r}", key=name)
    return arr


def _result(arr: np.ndarray) -> float | np.ndarray:
    return float(arr) if arr.ndim == 0 else arr


def bearing_angular_clearance(delta_lb_mm: float | np.ndarray, shaft_length_mm: float | np.ndarray
                              ) -> float | np.ndarray:
    """Angular clearance bound of a linear bearing, ``eps_theta = delta_LB / L_s`` (rad; paper Sec. 5.1.2).

    ``delta_lb_mm`` (>= 0) is the difference of the two readings at the end of
    the shaft when it is pushed back and forth, ``shaft_length_mm`` (> 0) the
    lever arm ``L_s``. This is the small-angle form of ``atan(delta_LB / L_s)``
    (relative difference below 1e-6 for clearances under 1e-3 rad). Scalars or
    broadcastable arrays; a float for scalar input.
    """
    delta = _nonnegative(delta_lb_mm, "delta_lb_mm")
    length = _nonnegative(shaft_length_mm, "shaft_length_mm", positive=True)
    return _result(delta / length)


def revolute_radial_clearance(hole_diameter_mm: float | np.ndarray, pin_diameter_mm: float | np.ndarray
                              ) -> float | np.ndarray:
    """Radial clearance bound of a pin joint, ``eps_r = (D - d) / 2`` in mm (paper Sec. 5.1.2).

    ``hole_diameter_mm`` ``D`` and ``pin_diameter_mm`` ``d`` must be positive
    with ``d <= D`` (a pin larger than its hole is an interference fit, not a
    clearance). Scalars or broadcastable arrays; a float for scalar input.
    """
    hole = _nonnegative(hole_diameter_mm, "hole_diameter_mm", positive=True)
    pin = _nonnegative(pin_diameter_mm, "pin_diameter_mm", positive=True)
    if np.any(pin > hole):
        raise ConfigError(f"pin diameter {pin_diameter_mm!r} mm exceeds hole diameter {hole_diameter_mm!r} mm",
                          key="pin_diameter_mm")
    return _result((hole - pin) / 2.0)
