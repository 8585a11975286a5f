"""Detection of circular dots with sub-pixel centres under uneven light, noise, blur and clutter.

:func:`find_blobs` works in four steps:

1. **Flat field.** The background ``B`` (the illumination times the sheet's
   reflectance) is a grey-level closing (dark dots) or opening (light dots) of
   the image, on a 4x reduced copy with a structuring element wider than the
   largest dot (``max_diameter_px``), smoothed and interpolated back. The
   relative contrast ``S = 1 - I / B`` (dark) or ``I / B - 1`` (light) is then
   independent of vignetting and gradients.
2. **Local threshold.** ``S > t`` with ``t`` Otsu's threshold of ``S`` but at least
   six robust standard deviations (MAD) of ``S`` above its median, so that an
   image of pure noise finds nothing. Regions (8-connectivity) are kept when
   ``min_area <= area <= pi (max_diameter_px / 2)^2``, circularity
   ``4 pi area / perimeter^2 >= min_circularity``, eccentricity
   ``<= max_eccentricity`` and solidity ``>= 0.9``. A region whose support
   (below) reaches the image border is *cut* and dropped.
3. **Local background.** Each kept region is grown by ``m = 3 + r / 4`` px (its
   *support*, holding the blurred rim; ``r`` the equivalent radius) and a ring of
   width ``3 + r / 6`` px around that, free of other regions, gets a least-squares
   plane ``b(x) = a0 + a1 col + a2 row`` of the raw grey levels (the local
   illumination, linear at the scale of a dot).
4. **Weighted centroid.** Over the support, the weights
   ``w = 1 - I / b(x)`` (dark) or ``I / b(x) - 1`` (light), not clipped (zero-mean
   noise stays unbiased), give ``c = sum w p / sum w``. Because ``w`` is the
   covered fraction times a constant contrast, ``c`` is the area centroid of the
   dot's (blurred) image, free of the illumination gradient; the perspective and
   lens offset of that centroid from the image of the dot's centre is handled
   by the calibration (:func:`pmaccuracy.vision.camera.disk_image_bias`).

Each centre carries its 1-sigma noise per coordinate (the mean of the two coordinates' variances), the
first-order propagation of the pixel noise ``s`` (the RMS residual of the ring's plane fit, ``n - 3``
degrees of freedom) through the centroid: the support's own pixels,
``sum (p - c)^2 / b^2 / (sum w)^2``, and the ring's plane ``a = (a0, a1, a2)``, fitted from the ring's
pixels (covariance ``s^2 (X^T X)^-1``), whose error changes every weight of the support
(``dw/db = I / b^2``, dark) and so the centre, ``dc/da = sum (I / b^2) (p - c) (1, col, row) / sum w``:

``sigma_c^2 = s^2 [sum (p - c)^2 / b^2 / (sum w)^2 + (dc/da) (X^T X)^-1 (dc/da)^T]``

(the plane's gradient error tilts the weights across the support: leaving it out made the centres'
sigmas about 15 % optimistic on rendered dots of 6 px radius). Each centre also carries its area
``sum w / k`` (px^2, ``k`` the contrast in the dot's interior) and contrast ``k``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import VisionError
from .images import as_gray
from .._optional import require

#: Default largest dot diameter as a fraction of the shorter image side.
MAX_DIAMETER_FRACTION = 0.12
#: Largest dot diameter accepted at all, as a fraction of the shorter image side.
MAX_DIAMETER_LIMIT = 0.5


@dataclass(frozen=True, eq=False)
class Blobs:
    """Dots found in an image: ``centres`` ``(N, 2)`` ``[col, row]`` px, ``sigma_px`` ``(N,)`` 1-sigma noise of each
    coordinate, ``area_px`` ``(N,)``, ``contrast`` ``(N,)`` (relative to the local background); ``cut``: regions
    dropped because the image border cuts them; ``rejected``: regions dropped for their shape or size."""

    centres: np.ndarray = field(repr=False)
    sigma_px: np.ndarray = field(repr=False)
    area_px: np.ndarray = field(repr=False)
    contrast: np.ndarray = field(repr=False)
    cut: int = 0
    rejected: int = 0

    def __len__(self) -> int:
        return int(self.centres.shape[0])

    def subset(self, index: np.ndarray) -> "Blobs":
        """The blobs selected by an integer or boolean index (``cut``/``rejected`` unchanged)."""
        return Blobs(self.centres[index], self.sigma_px[index], self.area_px[index], self.contrast[index],
                     self.cut, self.rejected)

    def describe(self) -> str:
        """``"N dots"`` plus what was dropped, for messages."""
        extra = []
        if self.cut:
            extra.append(f"{self.cut} cut by the image border")
        if self.rejected:
            extra.append(f"{self.rejected} not round or off-size")
        return f"{len(self)} round blob{'s' if len(self) != 1 else ''}" + (f" ({', '.join(extra)} ignored)"
                                                                           if extra else "")


def _empty() -> Blobs:
    return Blobs(np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0))


def flat_field(image: np.ndarray, polarity: str, max_diameter_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Background ``B`` ``(H, W)`` and relative contrast ``S`` ``(H, W)`` (module docstring, step 1)."""
    from scipy import ndimage

    factor = 4 if min(image.shape) >= 64 else 1
    h, w = image.shape
    hh, ww = -(-h // factor) * factor, -(-w // factor) * factor
    padded = np.pad(image, ((0, hh - h), (0, ww - w)), mode="edge")
    small = padded.reshape(hh // factor, factor, ww // factor, factor).mean(axis=(1, 3))
    size = int(math.ceil(1.3 * max_diameter_px / factor)) | 1
    op = ndimage.grey_closing if polarity == "dark" else ndimage.grey_opening
    back = op(small, size=(size, size), mode="nearest")
    back = ndimage.uniform_filter(back, size=size, mode="nearest")
    # bilinear interpolation back to full size, pixel centres aligned
    rows = (np.arange(h) + 0.5) / factor - 0.5
    cols = (np.arange(w) + 0.5) / factor - 0.5
    rr, cc = np.meshgrid(rows, cols, indexing="ij")
    big = ndimage.map_coordinates(back, [rr, cc], order=1, mode="nearest")
    floor = 0.02 * float(np.max(big)) if np.max(big) > 0 else 1e-6
    big = np.maximum(big, floor)
    contrast = 1.0 - image / big if polarity == "dark" else image / big - 1.0
    return big, contrast


def find_blobs(image: np.ndarray, *, polarity: str = "dark", max_diameter_px: float | None = None,
               min_area: float = 12.0, min_circularity: float = 0.7, max_eccentricity: float = 0.85) -> Blobs:
    """Round dots of an image ``(H, W)`` with sub-pixel centres and their noise (module docstring).

    ``polarity``: ``"dark"`` dots on a light background or ``"light"`` ones on a
    dark background. ``max_diameter_px``: largest dot diameter (default: 12 % of
    the shorter image side; at most half of it, else :class:`VisionError`). An
    image without contrast gives no blobs.
    """
    from scipy import ndimage
    measure, segmentation = require("skimage.measure"), require("skimage.segmentation")

    img = as_gray(image)
    if polarity not in ("dark", "light"):
        raise VisionError(f"polarity must be 'dark' or 'light', got {polarity!r}")
    if max_diameter_px is None:
        max_diameter_px = MAX_DIAMETER_FRACTION * min(img.shape)
    if not (math.isfinite(max_diameter_px) and max_diameter_px > 2):
        raise VisionError(f"max_diameter_px must be a number above 2, got {max_diameter_px}")
    if max_diameter_px > MAX_DIAMETER_LIMIT * min(img.shape):
        raise VisionError(f"max_diameter_px {max_diameter_px:g} is more than half the shorter image side "
                          f"({min(img.shape)} px)")
    if float(np.ptp(img)) <= 1e-9:
        return _empty()
    _, s = flat_field(img, polarity, max_diameter_px)
    med = float(np.median(s))
    mad = 1.4826 * float(np.median(np.abs(s - med)))
    filters = require("skimage.filters")

    level = max(float(filters.threshold_otsu(s)), med + 6.0 * max(mad, 1e-4))
    mask = s > level
    labels = measure.label(mask, connectivity=2)
    if labels.max() == 0:
        return _empty()
    max_area = math.pi * (max_diameter_px / 2) ** 2
    areas = np.bincount(labels.ravel())
    plausible = (areas >= min_area) & (areas <= max_area)
    plausible[0] = False
    # regions that reach the image border are cut by the frame (their shape and centroid are not the dot's)
    on_border = np.zeros(labels.max() + 1, dtype=bool)
    on_border[np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]])] = True
    on_border[0] = False
    cut_early = int(np.count_nonzero(on_border & (areas >= min_area) & (areas <= max_area)))
    plausible &= ~on_border
    rejected = int(np.count_nonzero((areas[1:] >= min_area) & ~on_border[1:]) - np.count_nonzero(plausible))
    keep = np.zeros(labels.max() + 1, dtype=bool)
    radius = np.zeros(labels.max() + 1)
    for region in measure.regionprops(np.where(plausible[labels], labels, 0)):  # loop over candidate regions
        area = float(region.area)
        perimeter = float(region.perimeter)
        circularity = 4.0 * math.pi * area / perimeter**2 if perimeter > 0 else 1.0
        if (circularity < min_circularity or float(region.eccentricity) > max_eccentricity
                or float(region.solidity) < 0.9):
            rejected += 1
            continue
        keep[region.label] = True
        radius[region.label] = math.sqrt(area / math.pi)
    kept = np.where(keep[labels], labels, 0)
    if kept.max() == 0:
        return Blobs(np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0), cut_early, rejected)

    # support and ring: grown by distances that depend on each blob's radius -> grow by the largest, then cut
    margin = 3.0 + radius / 4.0
    width = 3.0 + radius / 6.0
    reach = float(np.max((margin + width)[keep]))
    # work in the window holding the kept blobs and their rings (a platform image: a small part of the frame)
    h, w = img.shape
    pad = int(math.ceil(reach)) + 6
    rows = np.flatnonzero(kept.any(axis=1))
    cols = np.flatnonzero(kept.any(axis=0))
    r0, r1 = max(rows[0] - pad, 0), min(rows[-1] + pad + 1, h)
    c0, c1 = max(cols[0] - pad, 0), min(cols[-1] + pad + 1, w)
    kept, mask, img = kept[r0:r1, c0:c1], mask[r0:r1, c0:c1], img[r0:r1, c0:c1]
    grown = segmentation.expand_labels(kept, distance=reach)
    dist = ndimage.distance_transform_edt(kept == 0)
    lab = grown
    support = (lab > 0) & (dist <= margin[lab])
    others = ndimage.binary_dilation(mask & (kept == 0), iterations=4)  # rejected regions and their rims
    ring = (lab > 0) & ~support & (dist <= (margin + width)[lab]) & ~others
    # blobs whose support or ring reaches the border are cut by the frame
    edge = np.zeros_like(support)
    edge[0, :], edge[-1, :] = r0 == 0, r1 == h
    edge[:, 0] |= c0 == 0
    edge[:, -1] |= c1 == w
    border_ids = np.unique(lab[edge & (lab > 0)])
    ids = np.setdiff1d(np.flatnonzero(keep), border_ids)
    cut = cut_early + (int(np.count_nonzero(keep[border_ids])) if border_ids.size else 0)
    if ids.size == 0:
        return Blobs(np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0), cut, rejected)

    n_lab = labels.max() + 1
    rr, cc = np.nonzero(ring & np.isin(lab, ids))
    lr = lab[rr, cc]
    # local coordinates around each blob's rough centre, for conditioning
    com = np.array(ndimage.center_of_mass(kept > 0, kept, ids)).reshape(-1, 2)
    origin = np.zeros((n_lab, 2))
    origin[ids] = com
    y = rr - origin[lr, 0]
    x = cc - origin[lr, 1]
    v = img[rr, cc]

    def sums(values: np.ndarray) -> np.ndarray:
        return np.bincount(lr, weights=values, minlength=n_lab)[ids]

    one, sx, sy, sxx, sxy, syy = sums(np.ones_like(x)), sums(x), sums(y), sums(x * x), sums(x * y), sums(y * y)
    sv, svx, svy = sums(v), sums(v * x), sums(v * y)
    normal = np.stack([np.stack([one, sx, sy], -1), np.stack([sx, sxx, sxy], -1), np.stack([sy, sxy, syy], -1)], 1)
    rhs = np.stack([sv, svx, svy], -1)
    enough = one >= 12
    coef = np.zeros((n_lab, 3))
    safe = np.where(enough[:, None, None], normal, np.eye(3))
    coef[ids] = np.linalg.solve(safe, np.where(enough[:, None], rhs, 0.0)[..., None])[..., 0]
    fit = coef[lr, 0] + coef[lr, 1] * x + coef[lr, 2] * y
    noise = np.sqrt(sums((v - fit) ** 2) / np.maximum(one - 3, 1))

    sr, sc = np.nonzero(support & np.isin(lab, ids))
    ls = lab[sr, sc]
    ys = sr - origin[ls, 0]
    xs = sc - origin[ls, 1]
    back = coef[ls, 0] + coef[ls, 1] * xs + coef[ls, 2] * ys
    with np.errstate(divide="ignore", invalid="ignore"):
        wts = 1.0 - img[sr, sc] / back if polarity == "dark" else img[sr, sc] / back - 1.0
    wts = np.where(np.isfinite(wts), wts, 0.0)

    def ssum(values: np.ndarray) -> np.ndarray:
        return np.bincount(ls, weights=values, minlength=n_lab)[ids]

    total = ssum(wts)
    cx = ssum(wts * xs) / total
    cy = ssum(wts * ys) / total
    cxl = np.zeros(n_lab)
    cyl = np.zeros(n_lab)
    cxl[ids], cyl[ids] = cx, cy
    dx, dy = xs - cxl[ls], ys - cyl[ls]
    # the centre's noise (module docstring): the support's pixel noise, and the ring's plane fit, whose error
    # moves every weight of the support (dw/db = I / b^2, dark; -I / b^2, light) and so the centroid
    direct = ssum((dx ** 2 + dy ** 2) / back ** 2)                       # sum |p - c|^2 / b^2, both coordinates
    u = (img[sr, sc] / back ** 2) * (1.0 if polarity == "dark" else -1.0)
    basis = np.stack([np.ones_like(xs), xs, ys], axis=-1)                # db / da of each support pixel
    g = np.stack([np.stack([ssum(u * d * basis[:, k]) for k in range(3)], axis=-1) for d in (dx, dy)], 1)
    plane = np.einsum("nci,nij,ncj->n", g, np.linalg.inv(safe), g)       # g^T (X^T X)^-1 g, both coordinates
    sigma = noise * np.sqrt(np.maximum(direct + plane, 0.0) / 2.0) / np.abs(total)   # per coordinate
    # contrast from the dot's interior (pixels > 2.5 px inside the thresholded region)
    inner = ndimage.distance_transform_edt(kept > 0) > 2.5
    in_support = inner[sr, sc]
    n_in = ssum(in_support.astype(float))
    contrast = np.where(n_in >= 5, ssum(np.where(in_support, wts, 0.0)) / np.maximum(n_in, 1), np.nan)
    if np.any(n_in < 5):  # tiny dots: the peak weight
        small_ids = n_in < 5
        contrast[small_ids] = np.array([np.max(wts[ls == i]) for i in ids[small_ids]])
    centres = np.stack([cx + origin[ids, 1] + c0, cy + origin[ids, 0] + r0], axis=1)
    good = enough & np.isfinite(centres).all(axis=1) & (total > 0) & (contrast > 0)
    rejected += int(np.count_nonzero(~good))
    return Blobs(centres[good], sigma[good], (total / contrast)[good], contrast[good], cut, rejected)


def detect_markers(image: np.ndarray, *, polarity: str = "dark", **options) -> np.ndarray:
    """Centres ``(N, 2)`` ``[col, row]`` px of the round dots of an image: :func:`find_blobs` ``.centres``."""
    return find_blobs(image, polarity=polarity, **options).centres
