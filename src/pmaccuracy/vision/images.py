"""Reading, writing and normalising images: gray float arrays ``(H, W)`` with values in [0, 1]."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from ..errors import VisionError
from ._util import IMAGE_SUFFIXES
from .._optional import require


def as_gray(image: np.ndarray) -> np.ndarray:
    """A grayscale float image ``(H, W)`` with values in [0, 1] from gray, gray+alpha, RGB or RGBA input.

    Integer images are scaled by their dtype's range (``uint8`` by 255, ``uint16``
    by 65535); float images are taken as they are. Colour images are reduced by
    the ITU-R 709 luminance weights of :func:`skimage.color.rgb2gray`; an alpha
    channel is dropped (composited on white for RGBA).
    """
    color, util = require("skimage.color"), require("skimage.util")

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


#: Largest image accepted, in pixels (width x height): 25 megapixels, e.g. 6000 x 4000. Detection needs about
#: 100 bytes per pixel of working memory, so this keeps one image below about 2.5 GB.
MAX_IMAGE_PIXELS = 25_000_000


def _short(exc: BaseException) -> str:
    """First line of an exception's message (at most 100 characters), for one-line error messages."""
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return text if len(text) <= 100 else text[:97] + "..."


def image_size(path: str | Path) -> tuple[int, int] | None:
    """``(width, height)`` in pixels from an image file's header, without decoding the pixels.

    Uses Pillow's lazy :func:`PIL.Image.open` (reads the header only). Returns
    None if Pillow does not know the format (the full decoder may still read
    it); raises :class:`VisionError` naming the file if the declared size is
    above :data:`MAX_IMAGE_PIXELS` (also when Pillow itself refuses it as a
    decompression bomb) or if the file holds more than one frame.
    """
    from PIL import Image

    path = Path(path)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with Image.open(path) as im:
                width, height = (int(v) for v in im.size)
                frames = int(getattr(im, "n_frames", 1))
    except Image.DecompressionBombError:
        raise VisionError(f"{path}: image larger than the limit of {MAX_IMAGE_PIXELS:,} pixels "
                          f"(declared in its header)") from None
    except Exception:  # not a format Pillow knows, or a broken header: left to the decoder
        return None
    _check_pixels(path, width, height, "declared in its header")
    if frames > 1:
        raise VisionError(f"{path}: holds {frames} frames (a stack or an animation); give one image per file")
    return width, height


def _check_pixels(path: Path, width: int, height: int, how: str) -> None:
    if width * height > MAX_IMAGE_PIXELS:
        raise VisionError(f"{path}: image of {width} x {height} pixels ({how}) is larger than the limit of "
                          f"{MAX_IMAGE_PIXELS:,} pixels")


def load_image(path: str | Path) -> np.ndarray:
    """Read an image file as a gray float array ``(H, W)`` in [0, 1] (:func:`skimage.io.imread`, then :func:`as_gray`).

    8- and 16-bit, grey, grey+alpha, RGB and RGBA images (PNG, TIFF, JPEG, BMP,
    anything imageio reads) are accepted. The size in the file's header is
    checked against :data:`MAX_IMAGE_PIXELS` before the pixels are decoded.
    A missing, empty, truncated or unreadable file, a multi-frame file, an image
    above the pixel limit or smaller than 3 x 3 pixels raises :class:`VisionError`
    whose message starts with the path.
    """
    io = require("skimage.io")

    path = Path(path)
    if path.is_dir():
        raise VisionError(f"{path}: is a folder, not an image file")
    if not path.is_file():
        raise VisionError(f"{path}: no such image file")
    try:
        if path.stat().st_size == 0:
            raise VisionError(f"{path}: empty file, not an image")
    except OSError as exc:
        raise VisionError(f"{path}: cannot read the image ({exc.strerror or exc})") from None
    image_size(path)
    try:
        with warnings.catch_warnings():  # imageio tries its plugins in turn and some warn on foreign files
            warnings.simplefilter("ignore")
            raw = io.imread(path)
    except MemoryError:
        raise VisionError(f"{path}: not enough memory to decode the image") from None
    except Exception as exc:  # imageio/Pillow raise many unrelated types for unreadable files
        raise VisionError(f"{path}: not a readable image, or truncated ({type(exc).__name__}: "
                          f"{_short(exc)})") from None
    shape = np.shape(raw)
    if len(shape) >= 2:
        _check_pixels(path, int(shape[1]), int(shape[0]), "decoded")
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
    io, util = require("skimage.io"), require("skimage.util")

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

