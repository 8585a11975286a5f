"""Flat synthetic images: disks seen through a plain scale or a 3x3 homography (no lens, no height).

These are the quick, idealised images of the first vision pipeline (kept for
the ``render-sheet`` / ``render-pose`` commands with ``--camera flat`` and for
unit tests of the detector). The physically modelled camera is in
:mod:`pmaccuracy.vision.camera_sim`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import VisionError
from ._util import DEFAULT_SPACING_MM, _positive, apply_homography, image_centre, scale_matrix
from .pose import platform_markers
from .._optional import require


def _finish(coverage: np.ndarray, background: float, foreground: float, blur_sigma: float, noise_sigma: float,
            seed: int | None) -> np.ndarray:
    """Coverage ``(H, W)`` in [0, 1] -> grey image: blend, Gaussian blur, additive Gaussian noise, clip to [0, 1]."""
    image = background + (foreground - background) * coverage
    if blur_sigma < 0 or noise_sigma < 0 or not (math.isfinite(blur_sigma) and math.isfinite(noise_sigma)):
        raise VisionError("blur_sigma and noise_sigma must be finite and non-negative")
    if blur_sigma > 0:
        filters = require("skimage.filters")

        image = filters.gaussian(image, sigma=blur_sigma, mode="nearest", preserve_range=True)
    if noise_sigma > 0:
        image = image + np.random.default_rng(seed).normal(0.0, noise_sigma, image.shape)
    return np.clip(image, 0.0, 1.0)


def _coverage(shape: tuple[int, int], centres_plane: np.ndarray, radius_plane: float, pixel_to_plane: np.ndarray,
              supersample: int) -> np.ndarray:
    """Fraction ``(H, W)`` of each pixel covered by disks of radius ``radius_plane`` seen through a homography.

    Each pixel is split into ``supersample^2`` sub-pixels; a sub-pixel at
    plane distance ``d`` from a centre covers ``clip((r - d) / h + 1/2, 0, 1)``
    with ``h`` the sub-pixel size in the plane, which turns the sub-pixel
    staircase into a ramp (unbiased for sub-pixel centre shifts). Disks are
    drawn in local windows; overlapping disks take the maximum.
    """
    cov = np.zeros(shape)
    n = int(supersample)
    if n < 1:
        raise VisionError(f"supersample must be at least 1, got {supersample}")
    offsets = (np.arange(n) + 0.5) / n - 0.5
    plane_to_pixel = np.linalg.inv(pixel_to_plane)
    circle = np.stack([np.cos(np.linspace(0, 2 * np.pi, 33)), np.sin(np.linspace(0, 2 * np.pi, 33))], axis=1)
    for centre in np.asarray(centres_plane, dtype=float).reshape(-1, 2):  # loop over dots, pixels vectorized
        outline = apply_homography(plane_to_pixel, centre + radius_plane * circle)
        if not np.all(np.isfinite(outline)):
            continue
        c_lo, r_lo = np.floor(outline.min(axis=0)).astype(int) - 2
        c_hi, r_hi = np.ceil(outline.max(axis=0)).astype(int) + 2
        c_lo, r_lo = max(c_lo, 0), max(r_lo, 0)
        c_hi, r_hi = min(c_hi, shape[1] - 1), min(r_hi, shape[0] - 1)
        if c_lo > c_hi or r_lo > r_hi:
            continue
        cols = (np.arange(c_lo, c_hi + 1)[:, None] + offsets).ravel()
        rows = (np.arange(r_lo, r_hi + 1)[:, None] + offsets).ravel()
        cc, rr = np.meshgrid(cols, rows)
        plane = apply_homography(pixel_to_plane, np.stack([cc.ravel(), rr.ravel()], axis=1))
        dist = np.linalg.norm(plane - centre, axis=1).reshape(cc.shape)
        centre_px = apply_homography(plane_to_pixel, centre[None])[0]
        local = apply_homography(pixel_to_plane, centre_px + np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]))
        plane_per_pixel = math.sqrt(abs(np.linalg.det(np.stack([local[1] - local[0], local[2] - local[0]]))))
        sub = np.clip((radius_plane - dist) / (plane_per_pixel / n) + 0.5, 0.0, 1.0)
        win = sub.reshape(r_hi - r_lo + 1, n, c_hi - c_lo + 1, n).mean(axis=(1, 3))
        region = cov[r_lo:r_hi + 1, c_lo:c_hi + 1]
        np.maximum(region, win, out=region)
    return cov


def render_dots(shape: tuple[int, int], centres_px: np.ndarray, radius_px: float, *, background: float = 0.85,
                foreground: float = 0.15, supersample: int = 8, blur_sigma: float = 0.0, noise_sigma: float = 0.0,
                seed: int | None = None) -> np.ndarray:
    """Grey image ``shape = (H, W)`` with filled, anti-aliased disks at sub-pixel centres ``(N, 2)`` ``[col, row]``.

    Pixel value = ``background + (foreground - background) * coverage`` with
    the covered fraction computed by ``supersample^2`` sub-pixels (see
    :func:`_coverage`); then an optional Gaussian blur of ``blur_sigma`` px
    (:func:`skimage.filters.gaussian`), additive Gaussian noise of standard
    deviation ``noise_sigma`` from ``numpy.random.default_rng(seed)``, and
    clipping to [0, 1].
    """
    shape = (int(shape[0]), int(shape[1]))
    radius = _positive(radius_px, "radius_px")
    cov = _coverage(shape, np.asarray(centres_px, dtype=float), radius, np.eye(3), supersample)
    return _finish(cov, background, foreground, blur_sigma, noise_sigma, seed)


def render_platform(x: float, y: float, phi: float, *, shape: tuple[int, int] = (600, 600),
                    mm_per_pixel: float | None = 0.1, pixel_to_mm: np.ndarray | None = None,
                    spacing_mm: float = DEFAULT_SPACING_MM, marker_radius_mm: float = 1.5, blur_sigma: float = 1.0,
                    noise_sigma: float = 0.01, seed: int | None = None, background: float = 0.85,
                    foreground: float = 0.15, supersample: int = 8) -> np.ndarray:
    """Image ``(H, W)`` of the platform's 2 x 2 markers for the pose ``(x, y, phi)`` (mm, mm, rad).

    The camera maps pixels to mm by a plain scale ``mm_per_pixel`` (origin at
    the image centre, y up) or, if given, by the 3x3 homography
    ``pixel_to_mm`` (e.g. ``Calibration.homography``), which overrides the scale.
    Markers are disks of radius ``marker_radius_mm`` at :func:`platform_markers`.
    """
    shape = (int(shape[0]), int(shape[1]))
    h = np.asarray(pixel_to_mm, dtype=float) if pixel_to_mm is not None else scale_matrix(mm_per_pixel, shape)
    centres = platform_markers(x, y, phi, spacing_mm)
    cov = _coverage(shape, centres, _positive(marker_radius_mm, "marker_radius_mm"), h, supersample)
    return _finish(cov, background, foreground, blur_sigma, noise_sigma, seed)


@dataclass(frozen=True, eq=False)
class SyntheticSheet:
    """A rendered calibration sheet and its ground truth.

    ``image`` ``(H, W)``; ``pixel_to_mm`` the 3x3 homography from pixels to the
    sheet's own frame (dots at ``spacing * (i, j)``); ``centres_mm`` ``(N, 2)``
    and ``centres_px`` ``(N, 2)`` the drawn dots.
    """

    image: np.ndarray = field(repr=False)
    pixel_to_mm: np.ndarray
    centres_mm: np.ndarray = field(repr=False)
    centres_px: np.ndarray = field(repr=False)


def sheet_homography(shape: tuple[int, int], *, mm_per_pixel: float = 0.25, rotation: float = 0.0,
                     offset_mm: tuple[float, float] = (0.0, 0.0), perspective: tuple[float, float] = (0.0, 0.0)
                     ) -> np.ndarray:
    """Homography pixel -> sheet mm of a sheet seen by a camera of scale ``mm_per_pixel``.

    In the camera's millimetre frame (:func:`scale_matrix`) the sheet's origin
    sits at ``offset_mm`` and its x-axis at angle ``rotation`` (rad, counter-
    clockwise), so ``sheet = R(-rotation) (camera - offset)``. ``perspective``
    ``(gx, gy)`` (1/px) adds a projective distortion about the image centre:
    the pixel offset ``d`` from the centre first becomes ``d / (1 + gx d_x + gy d_y)``.
    """
    cx, cy = image_centre(shape)
    gx, gy = perspective
    # pixel -> distorted pixel: translate to the centre, divide by the perspective factor, translate back
    to_c = np.array([[1.0, 0.0, -cx], [0.0, 1.0, -cy], [0.0, 0.0, 1.0]])
    persp = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [gx, gy, 1.0]])
    distort = np.linalg.inv(to_c) @ persp @ to_c
    c, s = math.cos(rotation), math.sin(rotation)
    ox, oy = offset_mm
    rigid = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.array([[1.0, 0.0, -ox], [0.0, 1.0, -oy],
                                                                                 [0.0, 0.0, 1.0]])
    h = rigid @ scale_matrix(mm_per_pixel, shape) @ distort
    return h / h[2, 2]


def render_calibration_sheet(shape: tuple[int, int] = (600, 600), *, pixel_to_mm: np.ndarray | None = None,
                             mm_per_pixel: float = 0.25, rotation: float = 0.0,
                             offset_mm: tuple[float, float] = (0.0, 0.0), spacing_mm: float = DEFAULT_SPACING_MM,
                             dot_radius_mm: float = 2.0, blur_sigma: float = 1.0, noise_sigma: float = 0.01,
                             seed: int | None = None, background: float = 0.85, foreground: float = 0.15,
                             supersample: int = 4) -> SyntheticSheet:
    """Render a calibration sheet: dots of radius ``dot_radius_mm`` at ``spacing_mm * (i, j)`` in the sheet frame.

    The camera is ``pixel_to_mm`` (3x3, pixel -> sheet mm) if given, else
    :func:`sheet_homography` of ``mm_per_pixel``, ``rotation`` (rad) and
    ``offset_mm``. Only dots whose whole disk (plus a 3-pixel margin) is inside
    the image are drawn.
    """
    shape = (int(shape[0]), int(shape[1]))
    spacing = _positive(spacing_mm, "spacing_mm")
    radius = _positive(dot_radius_mm, "dot_radius_mm")
    h = (np.asarray(pixel_to_mm, dtype=float) if pixel_to_mm is not None else
         sheet_homography(shape, mm_per_pixel=mm_per_pixel, rotation=rotation, offset_mm=offset_mm))
    corners = apply_homography(h, np.array([[0, 0], [shape[1] - 1, 0], [0, shape[0] - 1], [shape[1] - 1, shape[0] - 1]]))
    lo = np.floor(corners.min(axis=0) / spacing).astype(int) - 1
    hi = np.ceil(corners.max(axis=0) / spacing).astype(int) + 1
    ii, jj = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
    centres_mm = spacing * np.stack([ii.ravel(), jj.ravel()], axis=1).astype(float)
    # keep dots whose outline stays 3 px inside the frame
    circle = np.stack([np.cos(np.linspace(0, 2 * np.pi, 17)), np.sin(np.linspace(0, 2 * np.pi, 17))], axis=1)
    outlines = apply_homography(np.linalg.inv(h), (centres_mm[:, None, :] + radius * circle).reshape(-1, 2))
    outlines = outlines.reshape(len(centres_mm), -1, 2)
    inside = np.all((outlines >= 3) & (outlines <= np.array([shape[1] - 4, shape[0] - 4])), axis=(1, 2))
    centres_mm = centres_mm[inside]
    cov = _coverage(shape, centres_mm, radius, h, supersample)
    image = _finish(cov, background, foreground, blur_sigma, noise_sigma, seed)
    return SyntheticSheet(image=image, pixel_to_mm=h, centres_mm=centres_mm,
                          centres_px=apply_homography(np.linalg.inv(h), centres_mm))
