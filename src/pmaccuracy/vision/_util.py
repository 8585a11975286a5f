"""Constants and small planar helpers shared by the vision modules.

Pixel coordinates are ``[col, row]`` pairs (``x`` to the right, ``y`` down),
arrays of shape ``(N, 2)``; integer values are pixel *centres*, so the image
centre of a ``(H, W)`` image is ``[(W - 1) / 2, (H - 1) / 2]``. Millimetre
coordinates are ``[x, y]`` in a right-handed frame seen from the camera
(``x`` right, ``y`` up in the image, ``z`` toward the camera).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import VisionError

#: Number of markers on the moving platform (a 2 x 2 square, paper Sec. 6).
PLATFORM_MARKERS = 4
#: Nominal side of the platform's marker square and spacing of the calibration sheet, mm (paper Sec. 5.1, 6).
DEFAULT_SPACING_MM = 20.0
#: A marker square whose side differs from the nominal one by more than this fraction is refused.
DEFAULT_SIDE_TOLERANCE = 0.1
#: At least this many grid dots are needed in every calibration image.
MIN_CALIBRATION_DOTS = 6
#: File types :func:`save_image` writes.
IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".jpg", ".jpeg", ".bmp")


def _estimate(kind, src: np.ndarray, dst: np.ndarray):
    """Least-squares transform of class ``kind`` mapping ``src`` to ``dst`` (both ``(N, 2)``); None if it fails.

    Uses ``from_estimate`` (scikit-image >= 0.26) or the older in-place ``estimate``.
    """
    if hasattr(kind, "from_estimate"):
        result = kind.from_estimate(src, dst)
        return result if result else None
    model = kind()
    return model if model.estimate(src, dst) else None


def apply_homography(h: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a 3x3 homography ``h`` to points ``(N, 2)``: ``[u, v, w] = h [x, y, 1]``, result ``[u / w, v / w]``.

    Points mapped onto the line at infinity (``w = 0``) give inf or NaN.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    hom = pts @ h[:, :2].T + h[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        return hom[:, :2] / hom[:, 2:3]


def image_centre(shape: tuple[int, ...]) -> np.ndarray:
    """Pixel coordinates ``[col, row]`` of the centre of an image of shape ``(H, W[, C])``: ``[(W-1)/2, (H-1)/2]``."""
    return np.array([(shape[1] - 1) / 2.0, (shape[0] - 1) / 2.0])


def scale_matrix(mm_per_pixel: float, shape: tuple[int, ...]) -> np.ndarray:
    """The 3x3 homography pixel -> mm of a plain scale ``s`` (mm/px) with the module's axis convention.

    ``x = (col - cx) s``, ``y = -(row - cy) s`` with ``[cx, cy]`` the image centre.
    """
    s = _positive(mm_per_pixel, "mm_per_pixel")
    cx, cy = image_centre(shape)
    return np.array([[s, 0.0, -cx * s], [0.0, -s, cy * s], [0.0, 0.0, 1.0]])


def pixels_to_mm(points_px: np.ndarray, mm_per_pixel: float, shape: tuple[int, ...]) -> np.ndarray:
    """Pixel points ``(N, 2)`` ``[col, row]`` to mm ``[x, y]`` with a plain scale (origin at the image centre, y up)."""
    return apply_homography(scale_matrix(mm_per_pixel, shape), points_px)


def mm_to_pixels(points_mm: np.ndarray, mm_per_pixel: float, shape: tuple[int, ...]) -> np.ndarray:
    """Inverse of :func:`pixels_to_mm`: mm points ``(N, 2)`` to pixel ``[col, row]``."""
    return apply_homography(np.linalg.inv(scale_matrix(mm_per_pixel, shape)), points_mm)


def _positive(value: float, name: str) -> float:
    """``value`` as a float if it is finite and > 0, else :class:`VisionError` naming ``name``."""
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise VisionError(f"{name} must be a positive finite number, got {value!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise VisionError(f"{name} must be a positive finite number, got {value}")
    return value

