"""Platform pose from its 2 x 2 markers: marker selection, rigid registration, 1-sigma uncertainty.

Markers are detected (:func:`~pmaccuracy.vision.detection.find_blobs`), mapped
onto the plane at the markers' height ``h`` (ray-plane intersection through
the calibration, :meth:`~pmaccuracy.vision.calibration.Calibration.image_to_plane`),
corrected for the offset between a tilted or distorted disk's area centroid and
the image of its centre, and registered with a square of side ``spacing_mm``
(least-squares rigid fit). When more than four round blobs are found, the one
set of four with equal sizes that forms the square is used; none or several
such sets is an error naming what was found.

Uncertainty: the pose ``f(c, p)`` depends on the eight marker-centre
coordinates ``c`` (noise ``sigma_k`` px each: the detector's estimate plus, in
quadrature, the calibration's ``systematic_px``, the part of its dot residuals
that the detector's noise does not explain) and on the
calibration parameters ``p`` (covariance ``C`` from the calibration fit). With
the Jacobians ``J_c`` ``(3, 8)`` and ``J_p`` ``(3, P)`` (central differences),
``Cov(x, y, phi) = J_c diag(sigma^2) J_c^T + J_p C J_p^T``; the reported
1-sigma values are the square roots of its diagonal (mm, mm, deg in files).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from ..errors import VisionError
from ._util import DEFAULT_SIDE_TOLERANCE, DEFAULT_SPACING_MM, PLATFORM_MARKERS, _estimate, _positive, pixels_to_mm
from .detection import Blobs, find_blobs
from .images import as_gray
from .._optional import require
from .camera import disk_image_bias, local_scale

#: Largest ratio between marker areas accepted within one set of four.
MAX_AREA_RATIO = 1.5
#: Most round blobs searched for the marker square (C(12, 4) = 495 sets).
MAX_CANDIDATES = 12


@dataclass(frozen=True, eq=False)
class PlatformPose:
    """Pose of the moving platform measured from its 2 x 2 markers.

    ``x``, ``y``: centre P of the marker square, mm; ``phi``: orientation of the
    square, rad, in (-pi/4, pi/4] (a square is symmetric under quarter turns);
    ``residual_mm``: RMS distance between the measured markers and the fitted
    model square; ``side_mm``: measured side of the square (mean over the four
    sides); ``markers_mm``: the marker centres ``(4, 2)``, counter-clockwise;
    ``sigma``: 1-sigma uncertainty ``(x mm, y mm, phi rad)`` or None;
    ``height_mm``: the markers' height above the reference plane used.
    """

    x: float
    y: float
    phi: float
    residual_mm: float
    side_mm: float
    markers_mm: np.ndarray = field(repr=False)
    sigma: tuple[float, float, float] | None = None
    height_mm: float = 0.0

    @property
    def phi_deg(self) -> float:
        """Orientation in degrees, in (-45, 45]."""
        return math.degrees(self.phi)

    def as_dict(self) -> dict[str, Any]:
        """``{"x", "y", "phi_deg", "residual_mm"}`` in mm and degrees, plus ``"uncertainty": {"x_mm", "y_mm",
        "phi_deg"}`` (1 sigma) when known (the CLI's output)."""
        out: dict[str, Any] = {"x": self.x, "y": self.y, "phi_deg": self.phi_deg, "residual_mm": self.residual_mm}
        if self.sigma is not None:
            out["uncertainty"] = {"x_mm": self.sigma[0], "y_mm": self.sigma[1],
                                  "phi_deg": math.degrees(self.sigma[2])}
        return out


def wrap_quarter_turn(angle: float | np.ndarray) -> float | np.ndarray:
    """Angle (rad) folded into (-pi/4, pi/4] modulo pi/2: ``pi/4 - ((pi/4 - a) mod pi/2)``."""
    q = math.pi / 4
    out = q - np.mod(q - np.asarray(angle, dtype=float), 2 * q)
    return float(out) if np.ndim(out) == 0 else out


def square_model(spacing_mm: float = DEFAULT_SPACING_MM) -> np.ndarray:
    """Marker positions ``(4, 2)`` in the platform frame (mm): ``(+-h, +-h)``, h = spacing/2, counter-clockwise."""
    h = spacing_mm / 2.0
    return np.array([[h, h], [-h, h], [-h, -h], [h, -h]])


def platform_markers(x: float, y: float, phi: float, spacing_mm: float = DEFAULT_SPACING_MM) -> np.ndarray:
    """Marker centres ``(4, 2)`` in mm for platform pose ``(x, y, phi)`` (mm, mm, rad): ``p + R(phi) m_k``."""
    c, s = math.cos(phi), math.sin(phi)
    return square_model(spacing_mm) @ np.array([[c, s], [-s, c]]) + np.array([x, y])


def pose_from_markers_mm(markers_mm: np.ndarray, *, spacing_mm: float = DEFAULT_SPACING_MM,
                         side_tolerance: float = DEFAULT_SIDE_TOLERANCE) -> PlatformPose:
    """Least-squares rigid registration of four marker centres ``(4, 2)`` (mm, any order) with the model square.

    The markers are ordered counter-clockwise by their angle around their
    centroid and matched with the model square's corners in the four cyclic
    ways; each gives a :class:`skimage.transform.EuclideanTransform` fit (the
    Kabsch/Umeyama solution minimising ``sum |R m_k + p - q_k|^2``) and the
    one whose angle lies in (-pi/4, pi/4] is kept (all four have the same
    residual by symmetry).

    Raises :class:`VisionError` if there are not exactly four markers, if the
    measured side differs from ``spacing_mm`` by more than ``side_tolerance``
    (relative; usually a wrong scale or unit), or if the residual exceeds 10 %
    of the side (the markers do not form a square).
    """
    q = np.asarray(markers_mm, dtype=float)
    if q.ndim != 2 or q.shape[1] != 2:
        raise VisionError(f"marker centres must have shape (N, 2), got {q.shape}")
    if len(q) != PLATFORM_MARKERS:
        what = "no markers" if len(q) == 0 else f"{len(q)} marker{'s' if len(q) != 1 else ''}"
        raise VisionError(f"found {what}, expected exactly {PLATFORM_MARKERS} (the 2 x 2 platform markers)")
    if not np.all(np.isfinite(q)):
        raise VisionError("marker centres must be finite")
    spacing = _positive(spacing_mm, "spacing_mm")
    centroid = q.mean(axis=0)
    rel = q - centroid
    order = np.argsort(np.arctan2(rel[:, 1], rel[:, 0]), kind="stable")
    q = q[order]
    side = float(np.mean(np.linalg.norm(q - np.roll(q, -1, axis=0), axis=1)))
    if not abs(side / spacing - 1.0) <= side_tolerance:
        raise VisionError(f"the marker square has a side of {side:.4g} mm instead of {spacing:g} mm "
                          "(wrong scale or units?)")
    transform = require("skimage.transform")

    model = square_model(spacing)
    fits = []  # (needs folding, rms, x, y, phi) of each cyclic correspondence
    for shift in range(4):
        src = np.roll(model, shift, axis=0)
        fit = _estimate(transform.EuclideanTransform, src, q)
        if fit is None:
            continue
        rms = float(np.sqrt(np.mean(np.sum((fit(src) - q) ** 2, axis=1))))
        phi = float(fit.rotation)
        wrapped = wrap_quarter_turn(phi)
        # all four have the same rms up to rounding: prefer the one whose angle is already in (-pi/4, pi/4]
        folded = abs(math.remainder(phi - wrapped, 2 * math.pi)) > 1e-9
        fits.append((folded, rms, float(fit.translation[0]), float(fit.translation[1]), wrapped))
    if not fits:
        raise VisionError("cannot register the markers with a square")
    _, rms, x, y, phi = min(fits)
    if rms > 0.1 * spacing:
        raise VisionError(f"the four markers do not form a square (fit residual {rms:.3g} mm)")
    return PlatformPose(x=x, y=y, phi=phi, residual_mm=rms, side_mm=side, markers_mm=q)


def _square_fit(q: np.ndarray) -> tuple[float, float, float]:
    """Closed-form rigid fit of markers ``(4, 2)`` (counter-clockwise, any start) with the model square.

    ``p`` = centroid; ``phi = atan2(sum m x q, sum m . q)`` over centred points
    (the 2-D Procrustes angle), with the model's corners in the same cyclic order.
    """
    m = square_model(1.0)
    qc = q - q.mean(axis=0)
    angle = math.atan2(float(np.sum(m[:, 0] * qc[:, 1] - m[:, 1] * qc[:, 0])), float(np.sum(m * qc)))
    c = q.mean(axis=0)
    return float(c[0]), float(c[1]), angle


def _ccw(q: np.ndarray) -> np.ndarray:
    """Order ``(4,)`` that sorts points ``(4, 2)`` counter-clockwise about their centroid."""
    rel = q - q.mean(axis=0)
    return np.argsort(np.arctan2(rel[:, 1], rel[:, 0]), kind="stable")


def select_markers(blobs: Blobs, to_mm: Callable[[np.ndarray], np.ndarray], *,
                   spacing_mm: float = DEFAULT_SPACING_MM,
                   side_tolerance: float = DEFAULT_SIDE_TOLERANCE) -> np.ndarray:
    """Indices ``(4,)`` of the platform markers among the blobs (module docstring).

    Exactly four blobs are taken as they are (:func:`pose_from_markers_mm`
    checks them). With more, every set of four whose areas agree within
    :data:`MAX_AREA_RATIO` and whose mapped centres form a square of side
    ``spacing_mm`` (within ``side_tolerance``, fit residual below 2 % of the side)
    is a candidate; exactly one must exist. Fewer than four blobs, none or
    several candidate sets raise :class:`VisionError` saying what was found.
    """
    n = len(blobs)
    if n < PLATFORM_MARKERS:
        what = "no markers" if n == 0 else f"{n} marker{'s' if n != 1 else ''}"
        extra = blobs.describe().partition(" (")[2]
        raise VisionError(f"found {what}{' (' + extra if extra else ''}, expected exactly {PLATFORM_MARKERS} "
                          "(the 2 x 2 platform markers)")
    if n == PLATFORM_MARKERS:
        return np.arange(n)
    if n > MAX_CANDIDATES:
        raise VisionError(f"found {blobs.describe()}, expected {PLATFORM_MARKERS} markers (too many to choose from)")
    mm = to_mm(blobs.centres)
    found = []
    for combo in itertools.combinations(range(n), PLATFORM_MARKERS):  # at most 495 small sets
        idx = np.array(combo)
        area = blobs.area_px[idx]
        if area.max() > MAX_AREA_RATIO * area.min() or not np.all(np.isfinite(mm[idx])):
            continue
        q = mm[idx][_ccw(mm[idx])]
        side = float(np.mean(np.linalg.norm(q - np.roll(q, -1, axis=0), axis=1)))
        if abs(side / spacing_mm - 1.0) > side_tolerance:
            continue
        x, y, phi = _square_fit(q)
        c, s = math.cos(phi), math.sin(phi)
        model = square_model(spacing_mm) @ np.array([[c, s], [-s, c]]) + [x, y]
        if np.sqrt(np.mean(np.sum((model - q) ** 2, axis=1))) <= 0.02 * spacing_mm:
            found.append(idx)
    if len(found) != 1:
        why = "none" if not found else f"{len(found)} sets"
        raise VisionError(f"found {blobs.describe()} and {why} of {PLATFORM_MARKERS} form the {spacing_mm:g} mm "
                          "marker square")
    return found[0]


def pose_uncertainty(markers_px: np.ndarray, sigma_px: np.ndarray, to_mm: Callable[..., np.ndarray], *,
                     calibration: Any | None = None, height_mm: float = 0.0) -> tuple[float, float, float]:
    """1-sigma ``(x mm, y mm, phi rad)`` of the pose of markers ``(4, 2)`` px with centre noise ``sigma_px`` ``(4,)``.

    ``to_mm(pixels)`` maps pixels to the plane; with ``calibration`` its
    parameter covariance is propagated too (module docstring).
    """
    px = np.asarray(markers_px, dtype=float).reshape(4, 2)
    order = _ccw(to_mm(px))
    px = px[order]
    sig = np.asarray(sigma_px, dtype=float).reshape(4)[order]
    base = np.array(_square_fit(to_mm(px)))

    def diff(pose: tuple[float, float, float]) -> np.ndarray:
        d = np.array(pose) - base
        d[2] = math.remainder(d[2], math.pi / 2)
        return d

    step = 1e-3
    jc = np.zeros((3, 8))
    for k in range(8):  # eight centre coordinates
        dp = np.zeros(8)
        dp[k] = step
        jc[:, k] = (diff(_square_fit(to_mm(px + dp.reshape(4, 2)))) -
                    diff(_square_fit(to_mm(px - dp.reshape(4, 2))))) / (2 * step)
    cov = jc @ np.diag(np.repeat(sig**2, 2)) @ jc.T
    if calibration is not None and calibration.covariance is not None:
        p = calibration.parameters()
        steps = 1e-6 * np.maximum(np.abs(p), 1e-3)
        jp = np.zeros((3, p.size))
        for j in np.flatnonzero(np.diag(calibration.covariance) > 0):  # one column per free parameter
            dp = np.zeros_like(p)
            dp[j] = steps[j]
            hi = calibration.with_parameters(p + dp).image_to_plane(px, height_mm)
            lo = calibration.with_parameters(p - dp).image_to_plane(px, height_mm)
            jp[:, j] = (diff(_square_fit(hi)) - diff(_square_fit(lo))) / (2 * steps[j])
        cov = cov + jp @ calibration.covariance @ jp.T
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return float(sd[0]), float(sd[1]), float(sd[2])


def pose_from_markers(markers_px: np.ndarray, *, calibration: Any | None = None,
                      mm_per_pixel: float | None = None, image_shape: tuple[int, ...] | None = None,
                      height_mm: float = 0.0, sigma_px: np.ndarray | None = None, area_px: np.ndarray | None = None,
                      spacing_mm: float = DEFAULT_SPACING_MM,
                      side_tolerance: float = DEFAULT_SIDE_TOLERANCE) -> PlatformPose:
    """Platform pose from four marker centres in pixels ``(4, 2)`` ``[col, row]``.

    Pixels go to mm with ``calibration`` (onto the plane at ``height_mm``) or
    with a plain scale ``mm_per_pixel`` (origin at the centre of an image of
    shape ``image_shape``, y up, height 0); exactly one of the two must be given.
    With a calibration and the marker areas ``area_px`` ``(4,)``, the offset of
    each marker's area centroid from the image of its centre is removed first.
    Then :func:`pose_from_markers_mm`; with ``sigma_px`` ``(4,)`` the pose carries
    its uncertainty (:func:`pose_uncertainty`).
    """
    if (calibration is None) == (mm_per_pixel is None):
        raise VisionError("give either a calibration or mm_per_pixel (exactly one)")
    pts = np.asarray(markers_px, dtype=float).reshape(-1, 2)
    if calibration is not None:
        def to_mm(p: np.ndarray) -> np.ndarray:
            return calibration.image_to_plane(p, height_mm)

        if area_px is not None and len(pts) == PLATFORM_MARKERS:

            plane = calibration.plane_at(height_mm)
            radius = np.sqrt(np.asarray(area_px, float) * local_scale(calibration.camera, plane, pts) / math.pi)
            bias = disk_image_bias(calibration.camera, plane, to_mm(pts), float(np.median(radius)))
            pts = pts - bias
    else:
        if image_shape is None:
            raise VisionError("mm_per_pixel needs the image shape (its centre is the origin)")
        if height_mm != 0.0:
            raise VisionError("a plain mm-per-pixel scale cannot measure markers above the plane; use a calibration")

        def to_mm(p: np.ndarray) -> np.ndarray:
            return pixels_to_mm(p, mm_per_pixel, image_shape)  # type: ignore[arg-type]

    pose = pose_from_markers_mm(to_mm(pts), spacing_mm=spacing_mm, side_tolerance=side_tolerance)
    sigma = None
    if sigma_px is not None:
        sigma = pose_uncertainty(pts, sigma_px, to_mm, calibration=calibration, height_mm=height_mm)
    return PlatformPose(pose.x, pose.y, pose.phi, pose.residual_mm, pose.side_mm, pose.markers_mm, sigma,
                        float(height_mm))


def measure_pose(image: np.ndarray, *, calibration: Any | None = None, mm_per_pixel: float | None = None,
                 height_mm: float = 0.0, spacing_mm: float = DEFAULT_SPACING_MM,
                 side_tolerance: float = DEFAULT_SIDE_TOLERANCE, polarity: str = "dark",
                 max_diameter_px: float | None = None) -> PlatformPose:
    """Pose of the platform in an image ``(H, W)``: :func:`find_blobs`, :func:`select_markers`, then
    :func:`pose_from_markers` with the centres' noise and areas."""
    if (calibration is None) == (mm_per_pixel is None):
        raise VisionError("give either a calibration or mm_per_pixel (exactly one)")
    spacing = _positive(spacing_mm, "spacing_mm")
    img = as_gray(image)
    if calibration is not None:
        plane_ok = calibration.plane_at(height_mm)  # refuses a height the calibration cannot measure, early
        del plane_ok
        if tuple(calibration.camera.image_size) != (img.shape[1], img.shape[0]):
            w, h = calibration.camera.image_size
            raise VisionError(f"image of {img.shape[1]} x {img.shape[0]} px, but the calibration is for {w} x {h} px")
    blobs = find_blobs(img, polarity=polarity, max_diameter_px=max_diameter_px)

    def to_mm(p: np.ndarray) -> np.ndarray:
        if calibration is not None:
            return calibration.image_to_plane(p, height_mm)
        return pixels_to_mm(p, mm_per_pixel, img.shape)  # type: ignore[arg-type]

    idx = select_markers(blobs, to_mm, spacing_mm=spacing, side_tolerance=side_tolerance)
    chosen = blobs.subset(idx)
    # centre noise of each marker plus the calibration's unexplained per-centre error (see the module docstring)
    systematic = calibration.residuals.get("systematic_px", 0.0) if calibration is not None else 0.0
    sigma = np.sqrt(chosen.sigma_px**2 + systematic**2)
    return pose_from_markers(chosen.centres, calibration=calibration, mm_per_pixel=mm_per_pixel,
                             image_shape=img.shape, height_mm=height_mm, sigma_px=sigma,
                             area_px=chosen.area_px if calibration is not None else None, spacing_mm=spacing,
                             side_tolerance=side_tolerance)
