"""Reading, writing and normalising images: gray float arrays ``(H, W)`` with values in [0, 1]."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from ..errors import VisionError
from ._util import IMAGE_SUFFIXES


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
    """Write a gray image ``(H, W)`` to a PNG, TIFF, JPEG or BMP file.

    ``uint8`` images (a camera's 8-bit output) are written unchanged. Float
    images with values in [0, 1] (clipped) are written with 16 bits per pixel
    to PNG and TIFF (which keeps the sub-pixel information of synthetic
    images), with 8 bits to JPEG and BMP.
    """
    from skimage import io, util

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in IMAGE_SUFFIXES:
        raise VisionError(f"{path}: unsupported image type {suffix or '(no extension)'!r}; use one of "
                          f"{', '.join(IMAGE_SUFFIXES)}")
    raw = np.asarray(image)
    if raw.dtype == np.uint8:  # an 8-bit camera image: written as it is
        data = raw
    else:
        arr = np.clip(raw.astype(float), 0.0, 1.0)
        data = util.img_as_uint(arr) if suffix in (".png", ".tif", ".tiff") else util.img_as_ubyte(arr)
    io.imsave(path, data, check_contrast=False)

