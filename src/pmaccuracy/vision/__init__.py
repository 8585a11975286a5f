"""Vision-based measurement of the moving platform's pose (paper Sec. 5).

The paper measures the platform with one calibrated camera above it: a sheet
with dots at 20 mm spacing defines the reference frame, and the platform
carries 2 x 2 markers at 20 mm whose images give its position and orientation
(0.01 mm and 0.01 deg). The package is split by job:

* :mod:`~pmaccuracy.vision.images` - reading/writing images as gray floats;
* :mod:`~pmaccuracy.vision.detection` - round dots with sub-pixel centres under
  uneven light, noise, blur and clutter (:func:`find_blobs`, :func:`detect_markers`);
* :mod:`~pmaccuracy.vision.camera` - pinhole + Brown-Conrady camera model,
  planes at a height, the perspective offset of a disk's centroid;
* :mod:`~pmaccuracy.vision.grid` - labelling sheet dots with lattice indices;
* :mod:`~pmaccuracy.vision.calibration` - Zhang's method (OpenCV) or a plane
  homography with radial distortion; :class:`Calibration` and its TOML file;
* :mod:`~pmaccuracy.vision.pose` - marker selection, rigid registration and the
  pose's 1-sigma uncertainty (:func:`measure_pose`);
* :mod:`~pmaccuracy.vision.batch` - photos + manifest -> measurement CSV;
* :mod:`~pmaccuracy.vision.render` - flat synthetic images (plain scale or homography);
* :mod:`~pmaccuracy.vision.camera_sim` - a physically modelled test camera.

Conventions: pixels are ``[col, row]`` (integer values at pixel centres),
millimetres ``[x, y]`` in the measurement frame (origin at the sheet dot
nearest the image centre, ``x`` along the dot rows toward increasing column,
right-handed seen from the camera, so ``y`` is up in the image and ``z`` points
to the camera). Angles in radians in the API, degrees in files and on the
command line.

The names below are imported on first use (so that ``import pmaccuracy.vision``
stays cheap for the command line).
"""

from __future__ import annotations

import importlib
from typing import Any

_NAMES = {
    "_util": ("PLATFORM_MARKERS", "DEFAULT_SPACING_MM", "DEFAULT_SIDE_TOLERANCE", "MIN_CALIBRATION_DOTS",
              "IMAGE_SUFFIXES", "apply_homography", "image_centre", "scale_matrix", "pixels_to_mm", "mm_to_pixels"),
    "images": ("as_gray", "load_image", "save_image"),
    "detection": ("Blobs", "find_blobs", "detect_markers"),
    "camera": ("CameraModel", "disk_image_bias", "plane_matrix", "rotation_matrix", "rotation_vector"),
    "grid": ("Grid", "find_grid"),
    "calibration": ("Calibration", "View", "calibrate", "calibrate_views", "calibrate_from_points",
                    "fit_multi_view", "fit_single_view", "nominal_matrix"),
    "pose": ("PlatformPose", "wrap_quarter_turn", "square_model", "platform_markers", "pose_from_markers_mm",
             "pose_from_markers", "measure_pose", "select_markers", "pose_uncertainty"),
    "batch": ("ManifestRow", "read_manifest", "measure_batch", "MANIFEST_COLUMNS"),
    "render": ("render_dots", "render_platform", "SyntheticSheet", "sheet_homography", "render_calibration_sheet"),
}
_WHERE = {name: module for module, names in _NAMES.items() for name in names}
_SUBMODULES = ("images", "detection", "camera", "grid", "calibration", "pose", "batch", "render", "camera_sim")

__all__ = sorted(_WHERE)


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        value = getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
        globals()[name] = value
        return value
    if name in _SUBMODULES:
        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_WHERE) | set(_SUBMODULES))
