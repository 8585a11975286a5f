"""Vision-based measurement of the moving platform's pose (paper Sec. 5).

The paper measures the pose of the moving platform (MP) with one camera fixed
above it: a calibration sheet with dots at 20 mm spacing defines the
reference frame, and the MP carries 2 x 2 markers at 20 mm separation whose
blobs give the position and orientation (accuracy 0.01 mm and 0.01 deg).
This module does the same with scikit-image:

* :func:`detect_markers` finds circular dots with sub-pixel, intensity-weighted
  centroids;
* :func:`calibrate` / :func:`calibrate_from_points` fit a homography from
  pixels to millimetres on an image of a calibration sheet;
* :func:`pose_from_markers` / :func:`measure_pose` register the four platform
  markers with a square of known side (least-squares rigid fit);
* :func:`render_dots`, :func:`render_platform` and
  :func:`render_calibration_sheet` draw synthetic, anti-aliased images with
  known ground truth for tests and demonstrations.

Coordinate conventions
----------------------
Pixel coordinates are ``[col, row]`` pairs (``x`` to the right, ``y`` down),
arrays of shape ``(N, 2)``; integer values are pixel *centres*, so the first
pixel covers ``[-0.5, 0.5] x [-0.5, 0.5]`` and the image centre of a
``(H, W)`` image is ``[(W - 1) / 2, (H - 1) / 2]``.

Millimetre coordinates are ``[x, y]`` in a right-handed frame as seen by the
camera: ``x`` to the right and ``y`` *up* in the image (so the image's
downward row axis is flipped). With a plain scale ``s`` in mm per pixel the
frame has its origin at the image centre::

    x = (col - (W - 1) / 2) * s,        y = -(row - (H - 1) / 2) * s

With a :class:`Calibration` the frame is the calibration sheet's: origin at
the grid dot nearest the image centre, ``x`` along the lattice direction that
is closest to the image's ``+x`` direction, ``y`` a quarter turn
counter-clockwise from ``x`` (up in the image).

Angles are in radians in the API; degrees only in files and on the command line.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w
from scipy import ndimage
from scipy.spatial import cKDTree
from skimage import filters, measure, segmentation, transform

from . import _tomlio
from .errors import ConfigError, VisionError

#: Number of markers on the moving platform (a 2 x 2 square, paper Sec. 6).
PLATFORM_MARKERS = 4
#: Nominal side of the platform's marker square and spacing of the calibration sheet, mm (paper Sec. 5.1, 6).
DEFAULT_SPACING_MM = 20.0
#: A marker square whose side differs from the nominal one by more than this fraction is refused.
DEFAULT_SIDE_TOLERANCE = 0.1
#: At least this many grid dots are needed to fit a calibration homography.
MIN_CALIBRATION_DOTS = 6
#: Keys of the ``[calibration]`` table of a calibration TOML file.
CALIBRATION_KEYS = {"homography", "spacing_mm", "residual_mm", "n_points"}
#: File types :func:`save_image` writes.
IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".jpg", ".jpeg", ".bmp")


# --------------------------------------------------------------------------------------------------------------
# images


def as_gray(image: np.ndarray) -> np.ndarray:
    """A grayscale float image ``(H, W)`` with values in [0, 1] from gray, gray+alpha, RGB or RGBA input.

    Integer images are scaled by their dtype's range (``uint8`` by 255, ``uint16``
    by 65535); float images are taken as they are. Colour images are reduced by
    the ITU-R 709 luminance weights of :func:`skimage.color.rgb2gray`; an alpha
    channel is dropped (composited on white for RGBA).
    """
    from skimage import color, util

    arr = np.asarray(image)
    if arr.dtype == bool:
        arr = arr.astype(float)
    if arr.dtype.kind not in "uif":
        raise VisionError(f"image must hold numbers, got dtype {arr.dtype}")
    if arr.ndim == 3 and arr.shape[-1] == 2:  # gray + alpha
        arr = arr[..., 0]
    if arr.dtype.kind in "ui":
        arr = util.img_as_float(arr)
    else:
        arr = arr.astype(float, copy=False)
    if arr.ndim == 3 and arr.shape[-1] == 4:
        arr = color.rgba2rgb(arr)
    if arr.ndim == 3 and arr.shape[-1] == 3:
        arr = color.rgb2gray(arr)
    if arr.ndim != 2:
        raise VisionError(f"expected a 2-D grayscale or an RGB(A) image, got an array of shape {np.shape(image)}")
    if arr.shape[0] < 3 or arr.shape[1] < 3:
        raise VisionError(f"image of {arr.shape[1]} x {arr.shape[0]} pixels is too small")
    if not np.all(np.isfinite(arr)):
        raise VisionError("image contains NaN or infinite values")
    return arr


def load_image(path: str | Path) -> np.ndarray:
    """Read an image file with :func:`skimage.io.imread` as a gray float array ``(H, W)`` in [0, 1].

    A missing file or one that is not a readable image raises :class:`VisionError`.
    """
    from skimage import io

    path = Path(path)
    if not path.is_file():
        raise VisionError(f"{path}: no such image file")
    try:
        with warnings.catch_warnings():  # imageio tries its plugins in turn and some warn on foreign files
            warnings.simplefilter("ignore")
            raw = io.imread(path)
    except Exception as exc:  # imageio/Pillow raise many unrelated types for unreadable files
        raise VisionError(f"{path}: not a readable image ({type(exc).__name__})") from None
    try:
        return as_gray(raw)
    except VisionError as exc:
        raise VisionError(f"{path}: {exc}") from None


def save_image(path: str | Path, image: np.ndarray) -> None:
    """Write a gray float image ``(H, W)`` with values in [0, 1] (clipped) to a PNG, TIFF, JPEG or BMP file.

    PNG and TIFF are written with 16 bits per pixel (which keeps the sub-pixel
    information of synthetic images), JPEG and BMP with 8 bits.
    """
    from skimage import io, util

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in IMAGE_SUFFIXES:
        raise VisionError(f"{path}: unsupported image type {suffix or '(no extension)'!r}; use one of "
                          f"{', '.join(IMAGE_SUFFIXES)}")
    arr = np.clip(np.asarray(image, dtype=float), 0.0, 1.0)
    data = util.img_as_uint(arr) if suffix in (".png", ".tif", ".tiff") else util.img_as_ubyte(arr)
    io.imsave(path, data, check_contrast=False)


# --------------------------------------------------------------------------------------------------------------
# marker detection


def detect_markers(image: np.ndarray, *, polarity: str = "dark", threshold: float | None = None,
                   min_area: float = 9.0, max_area: float | None = None, min_circularity: float = 0.6,
                   max_eccentricity: float = 0.8, margin_px: float = 3.0) -> np.ndarray:
    """Centres of the circular dots of an image, with sub-pixel accuracy; shape ``(N, 2)`` as ``[col, row]`` px.

    Steps:

    1. threshold at ``threshold`` (default: Otsu's threshold); ``polarity="dark"``
       looks for dots darker than the background, ``"light"`` for brighter ones;
    2. label the connected dot regions (8-connectivity) and keep those with
       ``min_area <= area <= max_area`` (px^2; default maximum: 1/20 of the image),
       circularity ``4 pi area / perimeter^2 >= min_circularity`` and eccentricity
       of the fitted ellipse ``<= max_eccentricity``; a region whose grown support
       touches the image border is dropped (its centroid would be biased);
    3. grow each kept region by ``margin_px`` pixels so that the blurred,
       anti-aliased rim belongs to it, take the local background level as the
       median of a 2-pixel ring around that, and return the centroid weighted by
       the contrast ``w = max(background - I, 0)`` (dark dots) or
       ``max(I - background, 0)`` (light dots).

    The weighted centroid uses the grey levels of the rim pixels, hence its
    sub-pixel accuracy (a few hundredths of a pixel on dots of ~15 px radius).
    Centres are listed in the raster order of the regions. An image without
    contrast gives an empty ``(0, 2)`` array.
    """
    img = as_gray(image)
    if polarity not in ("dark", "light"):
        raise VisionError(f"polarity must be 'dark' or 'light', got {polarity!r}")
    sign = 1.0 if polarity == "light" else -1.0
    signal = sign * img  # dots are bright in `signal`
    empty = np.zeros((0, 2))
    if float(np.ptp(signal)) <= 1e-9:  # constant image: Otsu is undefined, there is nothing to find
        return empty
    if threshold is None:
        level = float(filters.threshold_otsu(signal))
    else:
        if not math.isfinite(threshold):
            raise VisionError(f"threshold must be finite, got {threshold}")
        level = sign * float(threshold)
    labels = measure.label(signal > level, connectivity=2)
    if labels.max() == 0:
        return empty
    if max_area is None:
        max_area = img.size / 20.0

    # area filter first, vectorized, so that the per-region loop below only sees plausible dots (noisy
    # images can have thousands of specks)
    areas = np.bincount(labels.ravel())
    plausible = (areas >= min_area) & (areas <= max_area)
    plausible[0] = False
    props = measure.regionprops(np.where(plausible[labels], labels, 0))
    keep = np.zeros(labels.max() + 1, dtype=bool)
    for region in props:  # loop over regions, not pixels
        area = float(region.area)
        if not (min_area <= area <= max_area):
            continue
        perimeter = float(region.perimeter)
        # tiny regions have a perimeter estimate of 0: treat them as round
        circularity = 4.0 * math.pi * area / perimeter**2 if perimeter > 0 else 1.0
        if circularity < min_circularity or float(region.eccentricity) > max_eccentricity:
            continue
        keep[region.label] = True
    kept = np.where(keep[labels], labels, 0)
    if kept.max() == 0:
        return empty

    grown = segmentation.expand_labels(kept, distance=margin_px)
    outer = segmentation.expand_labels(kept, distance=margin_px + 2.0)
    ring = np.where(grown == 0, outer, 0)
    # a grown region that reaches the border is cut off by the frame: its centroid would be biased
    border = np.unique(np.concatenate([outer[0], outer[-1], outer[:, 0], outer[:, -1]]))
    ids = np.setdiff1d(np.unique(kept), np.concatenate([[0], border]))
    if ids.size == 0:
        return empty
    ring_ids = np.unique(ring)
    background = np.zeros(labels.max() + 1)
    have_ring = np.isin(ids, ring_ids)
    background[ids[have_ring]] = ndimage.median(signal, ring, ids[have_ring])
    # no ring at all (dots packed edge to edge): fall back to the global background level
    background[ids[~have_ring]] = float(np.median(signal[signal <= level]))
    weights = np.clip(signal - background[grown], 0.0, None)
    weights[~np.isin(grown, ids)] = 0.0
    centres_rc = np.array(ndimage.center_of_mass(weights, grown, ids), dtype=float).reshape(-1, 2)
    good = np.all(np.isfinite(centres_rc), axis=1)  # zero total weight (contrast below the ring level)
    return centres_rc[good][:, ::-1].copy()


# --------------------------------------------------------------------------------------------------------------
# geometric helpers


def _estimate(kind: type[transform.ProjectiveTransform], src: np.ndarray, dst: np.ndarray):
    """Least-squares transform of class ``kind`` mapping ``src`` to ``dst`` (both ``(N, 2)``); None if it fails.

    Uses ``from_estimate`` (scikit-image >= 0.26) or the older in-place ``estimate``.
    """
    if hasattr(kind, "from_estimate"):
        result = kind.from_estimate(src, dst)
        return result if result else None
    model = kind()
    return model if model.estimate(src, dst) else None


def _apply_h(h: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a 3x3 homography to points ``(N, 2)``; points on the line at infinity give inf."""
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
    return _apply_h(scale_matrix(mm_per_pixel, shape), points_px)


def mm_to_pixels(points_mm: np.ndarray, mm_per_pixel: float, shape: tuple[int, ...]) -> np.ndarray:
    """Inverse of :func:`pixels_to_mm`: mm points ``(N, 2)`` to pixel ``[col, row]``."""
    return _apply_h(np.linalg.inv(scale_matrix(mm_per_pixel, shape)), points_mm)


def _positive(value: float, name: str) -> float:
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise VisionError(f"{name} must be a positive finite number, got {value!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise VisionError(f"{name} must be a positive finite number, got {value}")
    return value


# --------------------------------------------------------------------------------------------------------------
# calibration


@dataclass(frozen=True, eq=False)
class Calibration:
    """A pixel -> mm calibration from an image of a dot grid (see the module docstring for the frame).

    ``homography`` is the 3x3 matrix ``H`` (normalised to ``H[2, 2] = 1``) with
    ``[x, y, 1] ~ H [col, row, 1]``; ``spacing_mm`` the grid spacing of the
    sheet; ``residual_mm`` the RMS distance between the mapped dot centres and
    their ideal grid positions; ``n_points`` the number of dots used.
    """

    homography: np.ndarray
    spacing_mm: float = DEFAULT_SPACING_MM
    residual_mm: float = 0.0
    n_points: int = 0

    def __post_init__(self) -> None:
        h = np.array(self.homography, dtype=float)
        if h.shape != (3, 3):
            raise ConfigError(f"must be a 3 x 3 matrix, got shape {h.shape}", key="homography")
        if not np.all(np.isfinite(h)):
            raise ConfigError("must contain finite numbers only", key="homography")
        # H[2, 2] = 0 means the pixel origin maps to infinity: normalise by the Frobenius norm instead
        h = h / h[2, 2] if abs(h[2, 2]) > 1e-12 * np.linalg.norm(h) else h / np.linalg.norm(h)
        if abs(np.linalg.det(h)) <= 1e-12 * np.linalg.norm(h) ** 3:
            raise ConfigError("is singular (maps the image onto a line)", key="homography")
        h.setflags(write=False)
        object.__setattr__(self, "homography", h)
        spacing = float(self.spacing_mm)
        if not math.isfinite(spacing) or spacing <= 0:
            raise ConfigError(f"must be a positive finite number, got {spacing}", key="spacing_mm")
        object.__setattr__(self, "spacing_mm", spacing)
        residual = float(self.residual_mm)
        if not math.isfinite(residual) or residual < 0:
            raise ConfigError(f"must be a non-negative finite number, got {residual}", key="residual_mm")
        object.__setattr__(self, "residual_mm", residual)
        if isinstance(self.n_points, bool) or int(self.n_points) != self.n_points or self.n_points < 0:
            raise ConfigError(f"must be a non-negative whole number, got {self.n_points!r}", key="n_points")
        object.__setattr__(self, "n_points", int(self.n_points))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Calibration):
            return NotImplemented
        return (np.array_equal(self.homography, other.homography) and self.spacing_mm == other.spacing_mm
                and self.residual_mm == other.residual_mm and self.n_points == other.n_points)

    __hash__ = None  # type: ignore[assignment]  # holds an array

    def pixel_to_mm(self, points_px: np.ndarray) -> np.ndarray:
        """Pixel points ``(N, 2)`` ``[col, row]`` to sheet millimetres ``(N, 2)`` ``[x, y]``."""
        return _apply_h(self.homography, points_px)

    def mm_to_pixel(self, points_mm: np.ndarray) -> np.ndarray:
        """Sheet millimetres ``(N, 2)`` to pixel points ``(N, 2)`` ``[col, row]``."""
        return _apply_h(np.linalg.inv(self.homography), points_mm)

    @property
    def mm_per_pixel(self) -> float:
        """Local scale at the frame origin: ``sqrt(|det J|)`` of the pixel -> mm map there (mm/px)."""
        origin_px = self.mm_to_pixel(np.zeros((1, 2)))[0]
        h = self.homography
        w = h[2, :2] @ origin_px + h[2, 2]
        xy = self.pixel_to_mm(origin_px[None])[0]
        # Jacobian of (h0.p / h2.p, h1.p / h2.p) at p
        jac = (h[:2, :2] - np.outer(xy, h[2, :2])) / w
        return float(math.sqrt(abs(np.linalg.det(jac))))

    def to_dict(self) -> dict[str, Any]:
        """Plain-Python content of the TOML file (table ``[calibration]``)."""
        return {"calibration": {"spacing_mm": self.spacing_mm, "residual_mm": self.residual_mm,
                                "n_points": self.n_points,
                                "homography": [[float(v) for v in row] for row in self.homography]}}

    def to_toml(self, path: str | Path | None = None) -> str:
        """The calibration as TOML text; also written to ``path`` when given."""
        text = tomli_w.dumps(self.to_dict())
        if path is not None:
            Path(path).write_text(text, encoding="utf-8")
        return text

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "<dict>") -> "Calibration":
        """Build from the parsed TOML table; every problem is a :class:`ConfigError` naming source and key."""
        table = data.get("calibration")
        if not isinstance(table, dict):
            raise ConfigError("missing [calibration] table", source=source, key="calibration")
        _tomlio.reject_unknown(data, {"calibration"}, source=source, where="")
        _tomlio.reject_unknown(table, CALIBRATION_KEYS, source=source, where="calibration")
        spacing = _tomlio.number(table, "spacing_mm", source=source, where="calibration", positive=True)
        residual = _tomlio.number(table, "residual_mm", source=source, where="calibration", nonnegative=True)
        if "n_points" not in table:
            raise ConfigError("missing", source=source, key="calibration.n_points")
        n_points = table["n_points"]
        if isinstance(n_points, bool) or not isinstance(n_points, int) or n_points < 0:
            raise ConfigError(f"must be a non-negative whole number, got {n_points!r}", source=source,
                              key="calibration.n_points")
        if "homography" not in table:
            raise ConfigError("missing", source=source, key="calibration.homography")
        rows = table["homography"]
        if not (isinstance(rows, list) and len(rows) == 3
                and all(isinstance(r, list) and len(r) == 3 for r in rows)):
            raise ConfigError("must be a 3 x 3 array of numbers [[..], [..], [..]]", source=source,
                              key="calibration.homography")
        matrix = np.zeros((3, 3))
        for i, row in enumerate(rows):
            for j, value in enumerate(row):
                key = f"calibration.homography[{i}][{j}]"
                if isinstance(value, bool) or not isinstance(value, (int, float)):
                    raise ConfigError(f"must be a number, got {value!r}", source=source, key=key)
                if not math.isfinite(value):
                    raise ConfigError(f"must be finite, got {value}", source=source, key=key)
                matrix[i, j] = value
        try:
            return cls(matrix, spacing_mm=spacing, residual_mm=residual, n_points=n_points)
        except ConfigError as exc:
            raise ConfigError(str(exc).split(": ", 1)[-1], source=source, key=f"calibration.{exc.key}") from None

    @classmethod
    def from_toml(cls, path: str | Path) -> "Calibration":
        """Read a calibration TOML file written by :meth:`to_toml`."""
        path = Path(path)
        source = str(path)
        if not path.is_file():
            raise ConfigError("no such calibration file", source=source)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise ConfigError(f"cannot read file ({exc})", source=source) from None
        return cls.from_dict(_tomlio.parse_text(text, source), source)


def _lattice_angle(points: np.ndarray, d0: float, tree: cKDTree) -> float:
    """Direction (rad, y-up image frame) of the dot lattice, folded to (-pi/4, pi/4].

    Nearest-neighbour vectors of length within 30 % of ``d0`` have angles that
    agree modulo a quarter turn; the circular mean of ``4 angle`` averages them.
    """
    k = min(5, len(points))
    dist, idx = tree.query(points, k=k)
    vec = points[idx[:, 1:]] - points[:, None, :]
    ok = (dist[:, 1:] > 0.7 * d0) & (dist[:, 1:] < 1.3 * d0)
    v = vec[ok]
    ang = np.arctan2(-v[:, 1], v[:, 0])  # image rows point down: flip to y up
    mean = np.sum(np.exp(4j * ang))
    if abs(mean) < 1e-9 * max(len(ang), 1):  # no consistent directions at all
        raise VisionError("the dots do not form a square grid (no consistent neighbour directions)")
    theta = float(np.angle(mean)) / 4.0
    return theta if theta > -math.pi / 4 else theta + math.pi / 2


def _local_basis(points: np.ndarray, c0: int, theta: float, d0: float, tree: cKDTree) -> np.ndarray:
    """Pixel vectors ``(2, 2)`` of the lattice steps +i and +j at dot ``c0``, refined from its neighbours."""
    c, s = math.cos(theta), math.sin(theta)
    guess = d0 * np.array([[c, -s], [-s, -c]])  # +i along theta, +j a quarter turn counter-clockwise (up)
    near = tree.query_ball_point(points[c0], 1.45 * d0)
    vecs = points[near] - points[c0]
    basis = guess.copy()
    if len(vecs) > 1:
        for axis in range(2):
            steps = []
            for sign in (1.0, -1.0):
                err = np.linalg.norm(vecs - sign * guess[axis], axis=1)
                best = int(np.argmin(err))
                if err[best] < 0.35 * d0:
                    steps.append(sign * vecs[best])
            if steps:
                basis[axis] = np.mean(steps, axis=0)
    return basis


def _assign_indices(points: np.ndarray, model, radius: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Integer grid indices ``(M, 2)`` of the points that sit close to a grid node of ``model`` (index -> px).

    Returns (point indices, grid indices). A point is accepted when its
    fractional index is within 0.3 of an integer node (and within ``radius``
    nodes of the origin); two points claiming the same node keep the closer one.
    """
    with np.errstate(all="ignore"):
        frac = model.inverse(points)
    ij = np.rint(frac)
    err = np.linalg.norm(frac - ij, axis=1)
    ok = np.isfinite(err) & (err < 0.3)
    if radius is not None:
        ok &= np.max(np.abs(np.nan_to_num(ij, nan=np.inf)), axis=1) <= radius
    which = np.flatnonzero(ok)
    which = which[np.argsort(err[which], kind="stable")]
    _, first = np.unique(ij[which], axis=0, return_index=True)
    which = np.sort(which[first])
    return which, ij[which].astype(int)


def _fit_index_model(ij: np.ndarray, px: np.ndarray):
    """Index -> pixel model: projective with enough well-spread nodes, affine otherwise."""
    spread = len(np.unique(ij[:, 0])) >= 2 and len(np.unique(ij[:, 1])) >= 2
    if len(ij) >= MIN_CALIBRATION_DOTS and spread:
        model = _estimate(transform.ProjectiveTransform, ij.astype(float), px)
        if model is not None and np.all(np.isfinite(model.params)):
            return model
    if len(ij) >= 3 and spread:
        model = _estimate(transform.AffineTransform, ij.astype(float), px)
        if model is not None and np.all(np.isfinite(model.params)):
            return model
    return None


def calibrate_from_points(points_px: np.ndarray, image_shape: tuple[int, ...], *,
                          spacing_mm: float = DEFAULT_SPACING_MM) -> Calibration:
    """Fit the pixel -> mm homography of a dot grid from dot centres ``(N, 2)`` ``[col, row]`` px.

    1. ``d0`` = median nearest-neighbour distance; the lattice direction closest
       to image ``+x`` comes from the circular mean of the neighbour directions
       modulo a quarter turn; the dot nearest the image centre is node (0, 0)
       and its neighbours refine the two step vectors.
    2. The grid is grown ring by ring: dots within ``k`` nodes of the origin are
       assigned to the nearest integer node of the current index -> pixel model
       (affine, then projective once six or more nodes are known) and the model
       is refitted, until no new dot joins. Spurious blobs off the grid are ignored.
    3. The frame is normalised (origin at the dot nearest the image centre,
       ``x`` along the step closest to image ``+x``, ``y`` a quarter turn
       counter-clockwise, i.e. up) and the homography pixel -> ``spacing_mm *
       (i, j)`` is fitted by least squares (:class:`skimage.transform.ProjectiveTransform`).

    ``residual_mm`` is the RMS distance between mapped centres and ideal nodes.
    Fewer than six assigned dots, or dots all in one row, raise :class:`VisionError`.
    """
    spacing = _positive(spacing_mm, "spacing_mm")
    pts = np.asarray(points_px, dtype=float).reshape(-1, 2)
    if not np.all(np.isfinite(pts)):
        raise VisionError("dot centres must be finite")
    if len(pts) < MIN_CALIBRATION_DOTS:
        raise VisionError(f"found {len(pts)} calibration dot(s), at least {MIN_CALIBRATION_DOTS} are needed")
    tree = cKDTree(pts)
    nn_dist = tree.query(pts, k=2)[0][:, 1]
    d0 = float(np.median(nn_dist))
    if d0 <= 0:  # duplicated centres
        raise VisionError("calibration dots coincide; cannot find the grid")
    centre = image_centre(image_shape)
    c0 = int(np.argmin(np.linalg.norm(pts - centre, axis=1)))
    theta = _lattice_angle(pts, d0, tree)
    basis = _local_basis(pts, c0, theta, d0, tree)
    model = transform.AffineTransform(matrix=np.array([[basis[0, 0], basis[1, 0], pts[c0, 0]],
                                                       [basis[0, 1], basis[1, 1], pts[c0, 1]],
                                                       [0.0, 0.0, 1.0]]))

    previous: tuple[int, ...] = ()
    radius = 1
    with np.errstate(all="ignore"):
        extent0 = float(np.max(np.abs(model.inverse(pts))))  # grid extent in nodes under the first guess
    if not math.isfinite(extent0):  # degenerate first guess: fall back to the number of dots
        extent0 = float(len(pts))
    for _ in range(2 * int(extent0) + 10):  # each pass widens the radius by one node
        which, ij = _assign_indices(pts, model, radius)
        fitted = _fit_index_model(ij, pts[which])
        if fitted is not None:
            model = fitted
        current = tuple(which)
        with np.errstate(all="ignore"):
            extent = np.nanmax(np.abs(model.inverse(pts)))
        if current == previous and (not np.isfinite(extent) or radius > extent + 1):
            break
        previous = current
        radius += 1
    which, ij = _assign_indices(pts, model, None)
    if len(which) < MIN_CALIBRATION_DOTS:
        raise VisionError(f"only {len(which)} dot(s) lie on a regular grid, at least {MIN_CALIBRATION_DOTS} are "
                          "needed")
    if len(np.unique(ij[:, 0])) < 2 or len(np.unique(ij[:, 1])) < 2:
        raise VisionError("the calibration dots lie on a single line; a 2-D grid is needed")

    # frame: origin at the assigned dot nearest the image centre, axes by the local steps there
    px = pts[which]
    origin = ij[int(np.argmin(np.linalg.norm(px - centre, axis=1)))]
    ij = ij - origin
    fitted = _fit_index_model(ij, px)
    if fitted is None:
        raise VisionError("cannot fit a grid model to the calibration dots")
    p0 = fitted(np.zeros((1, 2)))[0]
    steps = np.stack([fitted(np.array([[1.0, 0.0]]))[0] - p0, fitted(np.array([[0.0, 1.0]]))[0] - p0])
    steps_up = steps * np.array([1.0, -1.0])  # to a y-up frame
    candidates = np.concatenate([steps_up, -steps_up])  # +i, +j, -i, -j
    pick = int(np.argmax(candidates[:, 0] / np.linalg.norm(candidates, axis=1)))  # closest to +x
    ex = np.eye(2)[pick % 2] * (1.0 if pick < 2 else -1.0)  # index direction that becomes +x
    ey_options = np.array([[-ex[1], ex[0]], [ex[1], -ex[0]]])  # the two perpendicular index directions
    step_x = ex @ steps_up
    cross = step_x[0] * (ey_options @ steps_up)[:, 1] - step_x[1] * (ey_options @ steps_up)[:, 0]
    ey = ey_options[int(np.argmax(cross))]  # counter-clockwise from x (right-handed, y up)
    # new coordinates (X, Y) of an old index vector n: X = ex.n, Y = ey.n
    xy_mm = spacing * (ij @ np.stack([ex, ey]).T).astype(float)

    model = _estimate(transform.ProjectiveTransform, px, xy_mm)
    if model is None or not np.all(np.isfinite(model.params)):
        raise VisionError("the calibration homography is degenerate")
    residual = float(np.sqrt(np.mean(np.sum((model(px) - xy_mm) ** 2, axis=1))))
    return Calibration(model.params, spacing_mm=spacing, residual_mm=residual, n_points=len(px))


def calibrate(image: np.ndarray, *, spacing_mm: float = DEFAULT_SPACING_MM, polarity: str = "dark",
              **detect_options: Any) -> Calibration:
    """Calibrate from an image ``(H, W)`` of a dot sheet: :func:`detect_markers` then :func:`calibrate_from_points`."""
    img = as_gray(image)
    centres = detect_markers(img, polarity=polarity, **detect_options)
    if len(centres) == 0:
        raise VisionError("no calibration dots found in the image")
    return calibrate_from_points(centres, img.shape, spacing_mm=spacing_mm)


# --------------------------------------------------------------------------------------------------------------
# platform pose


@dataclass(frozen=True, eq=False)
class PlatformPose:
    """Pose of the moving platform measured from its 2 x 2 markers.

    ``x``, ``y``: centre P of the marker square, mm; ``phi``: orientation of the
    square, rad, in (-pi/4, pi/4] (a square is symmetric under quarter turns);
    ``residual_mm``: RMS distance between the measured markers and the fitted
    model square; ``side_mm``: measured side of the square (mean over the four
    sides); ``markers_mm``: the marker centres ``(4, 2)``, counter-clockwise.
    """

    x: float
    y: float
    phi: float
    residual_mm: float
    side_mm: float
    markers_mm: np.ndarray = field(repr=False)

    @property
    def phi_deg(self) -> float:
        """Orientation in degrees, in (-45, 45]."""
        return math.degrees(self.phi)

    def as_dict(self) -> dict[str, float]:
        """``{"x", "y", "phi_deg", "residual_mm"}`` in mm and degrees (the CLI's output)."""
        return {"x": self.x, "y": self.y, "phi_deg": self.phi_deg, "residual_mm": self.residual_mm}


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


def pose_from_markers(markers_px: np.ndarray, *, calibration: Calibration | None = None,
                      mm_per_pixel: float | None = None, image_shape: tuple[int, ...] | None = None,
                      spacing_mm: float = DEFAULT_SPACING_MM,
                      side_tolerance: float = DEFAULT_SIDE_TOLERANCE) -> PlatformPose:
    """Platform pose from four marker centres in pixels ``(4, 2)`` ``[col, row]``.

    Pixels go to mm with ``calibration`` (its homography and frame) or with a
    plain scale ``mm_per_pixel`` (origin at the centre of an image of shape
    ``image_shape``, y up); exactly one of the two must be given. Then
    :func:`pose_from_markers_mm`.
    """
    if (calibration is None) == (mm_per_pixel is None):
        raise VisionError("give either a calibration or mm_per_pixel (exactly one)")
    pts = np.asarray(markers_px, dtype=float).reshape(-1, 2)
    if calibration is not None:
        mm = calibration.pixel_to_mm(pts)
    else:
        if image_shape is None:
            raise VisionError("mm_per_pixel needs the image shape (its centre is the origin)")
        mm = pixels_to_mm(pts, mm_per_pixel, image_shape)  # type: ignore[arg-type]
    return pose_from_markers_mm(mm, spacing_mm=spacing_mm, side_tolerance=side_tolerance)


def measure_pose(image: np.ndarray, *, calibration: Calibration | None = None, mm_per_pixel: float | None = None,
                 spacing_mm: float = DEFAULT_SPACING_MM, side_tolerance: float = DEFAULT_SIDE_TOLERANCE,
                 polarity: str = "dark", **detect_options: Any) -> PlatformPose:
    """Pose of the platform in an image ``(H, W)``: :func:`detect_markers` then :func:`pose_from_markers`."""
    if (calibration is None) == (mm_per_pixel is None):
        raise VisionError("give either a calibration or mm_per_pixel (exactly one)")
    img = as_gray(image)
    centres = detect_markers(img, polarity=polarity, **detect_options)
    return pose_from_markers(centres, calibration=calibration, mm_per_pixel=mm_per_pixel, image_shape=img.shape,
                             spacing_mm=spacing_mm, side_tolerance=side_tolerance)


# --------------------------------------------------------------------------------------------------------------
# synthetic images


def _finish(coverage: np.ndarray, background: float, foreground: float, blur_sigma: float, noise_sigma: float,
            seed: int | None) -> np.ndarray:
    """Coverage ``(H, W)`` in [0, 1] -> grey image: blend, Gaussian blur, additive Gaussian noise, clip to [0, 1]."""
    image = background + (foreground - background) * coverage
    if blur_sigma < 0 or noise_sigma < 0 or not (math.isfinite(blur_sigma) and math.isfinite(noise_sigma)):
        raise VisionError("blur_sigma and noise_sigma must be finite and non-negative")
    if blur_sigma > 0:
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
        outline = _apply_h(plane_to_pixel, centre + radius_plane * circle)
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
        plane = _apply_h(pixel_to_plane, np.stack([cc.ravel(), rr.ravel()], axis=1))
        dist = np.linalg.norm(plane - centre, axis=1).reshape(cc.shape)
        centre_px = _apply_h(plane_to_pixel, centre[None])[0]
        local = _apply_h(pixel_to_plane, centre_px + np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]))
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
    corners = _apply_h(h, np.array([[0, 0], [shape[1] - 1, 0], [0, shape[0] - 1], [shape[1] - 1, shape[0] - 1]]))
    lo = np.floor(corners.min(axis=0) / spacing).astype(int) - 1
    hi = np.ceil(corners.max(axis=0) / spacing).astype(int) + 1
    ii, jj = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
    centres_mm = spacing * np.stack([ii.ravel(), jj.ravel()], axis=1).astype(float)
    # keep dots whose outline stays 3 px inside the frame
    circle = np.stack([np.cos(np.linspace(0, 2 * np.pi, 17)), np.sin(np.linspace(0, 2 * np.pi, 17))], axis=1)
    outlines = _apply_h(np.linalg.inv(h), (centres_mm[:, None, :] + radius * circle).reshape(-1, 2))
    outlines = outlines.reshape(len(centres_mm), -1, 2)
    inside = np.all((outlines >= 3) & (outlines <= np.array([shape[1] - 4, shape[0] - 4])), axis=(1, 2))
    centres_mm = centres_mm[inside]
    cov = _coverage(shape, centres_mm, radius, h, supersample)
    image = _finish(cov, background, foreground, blur_sigma, noise_sigma, seed)
    return SyntheticSheet(image=image, pixel_to_mm=h, centres_mm=centres_mm,
                          centres_px=_apply_h(np.linalg.inv(h), centres_mm))
