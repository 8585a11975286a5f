"""Camera calibration from images of the dot sheet: Zhang's method or a plane homography with radial distortion.

Two models, chosen by the number of images:

* ``"multi-view"`` (three or more images: the reference view ``PLANE`` plus two
  or more views of the sheet moved and tilted): Zhang's method as implemented
  by OpenCV's ``calibrateCamera``: intrinsics ``fx, fy, cx, cy``, Brown-Conrady
  distortion ``k1, k2, p1, p2`` (``k3`` on request) and the pose ``R, t`` of the
  sheet in every view. The reference view's pose is the plane's: a point
  ``[x, y]`` of the measurement frame at height ``h`` images through
  ``M_h = [r1, r2, t + h r3]`` (:mod:`pmaccuracy.vision.camera`), so markers above
  the plane are measured exactly.
* ``"single-view"`` (``PLANE`` alone): a homography ``M`` from the plane to
  normalized coordinates together with radial distortion ``k1, k2`` about the
  image centre, for a nominal ``K`` (focal length = the image diagonal: a
  scale for the distortion coefficients, not an estimate). One view of a plane
  cannot separate the focal length from the distance, so this model measures
  on the plane itself only (marker height 0).

Both fits minimise the reprojection error in pixels. Dot centres are the
detector's area centroids; the offset between the centroid of a dot's image
and the image of its centre (perspective of tilted dots, lens distortion) is
computed from the fitted model (:func:`~pmaccuracy.vision.camera.disk_image_bias`)
and removed, and the fit is repeated (twice). The parameters' covariance is
``s^2 (J^T J)^-1`` with ``J`` the Jacobian of all reprojections (central
differences of the model) and ``s^2`` the residual variance per coordinate;
the block of the intrinsics, distortion and reference-plane pose is stored and
propagated into every measured pose (:mod:`pmaccuracy.vision.pose`).

Calibration file (TOML, written by :meth:`Calibration.to_toml`)::

    [calibration]
    model = "multi-view"            # or "single-view"
    spacing_mm = 20.0               # dot spacing of the sheet
    image_size = [1280, 1024]       # width, height in px
    n_views = 5                     # images used
    n_points = 160                  # dots used, all views
    dot_radius_mm = 2.0             # estimated from the dot areas (perspective correction)
    camera_matrix = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]      # px
    distortion = [k1, k2, p1, p2, k3]
    intrinsics_estimated = true     # false for "single-view": nominal K
    [calibration.plane]             # the reference plane = measurement frame
    homography = [[...], [...], [...]]     # M_0: plane mm -> normalized image coordinates
    rotation = [[...], [...], [...]]       # R, plane -> camera ("multi-view" only)
    translation_mm = [tx, ty, tz]          # t ("multi-view" only)
    [calibration.residuals]
    rms_px = 0.012                  # reprojection error, all views
    max_px = 0.04
    systematic_px = 0.006           # per coordinate: the part of the residuals the centre noise does not explain
    plane_rms_mm = 0.0011           # reference view: dots mapped onto the plane vs their grid positions
    plane_max_mm = 0.003
    [calibration.covariance]
    parameters = ["fx", "fy", ...]  # see Calibration.parameter_names
    matrix = [[...], ...]
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from .._textfile import read_text
from ..errors import ConfigError, VisionError
from ._util import DEFAULT_SPACING_MM, MIN_CALIBRATION_DOTS, _positive
from .camera import CameraModel, disk_image_bias, image_to_plane, local_scale, plane_matrix, plane_to_image, rotation_matrix, rotation_vector
from .detection import Blobs, find_blobs
from .grid import find_grid
from .._optional import require
from ..model import _tomlio

MODELS = ("multi-view", "single-view")
MULTI_VIEW_PARAMETERS = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "rx", "ry", "rz", "tx_mm", "ty_mm",
                         "tz_mm")
SINGLE_VIEW_PARAMETERS = ("k1", "k2", "m11", "m12", "m13", "m21", "m22", "m23", "m31", "m32")
#: Images needed for Zhang's method (the reference view counts).
MIN_VIEWS_ZHANG = 3
#: Refits with the perspective/lens correction of the dot centres.
BIAS_ITERATIONS = 2
#: Largest condition number of the calibration Jacobian (columns scaled to unit length) accepted; five good
#: views of the test camera give about 900, three identical views 1e5.
MAX_JACOBIAN_CONDITION = 1e4


def _frozen(arr: Any) -> np.ndarray:
    a = np.array(arr, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Calibration:
    """A calibrated camera over the reference plane (module docstring).

    ``camera``: intrinsics and distortion; ``plane``: ``M_0`` ``(3, 3)``, plane mm ->
    normalized coordinates; ``rotation`` ``(3, 3)`` / ``translation`` ``(3,)`` mm: the
    plane's pose in the camera frame (``None`` for the single-view model);
    ``residuals``: ``rms_px, max_px, plane_rms_mm, plane_max_mm``; ``covariance``
    over :meth:`parameter_names`.
    """

    camera: CameraModel
    plane: np.ndarray
    model: str = "single-view"
    spacing_mm: float = DEFAULT_SPACING_MM
    rotation: np.ndarray | None = None
    translation: np.ndarray | None = None
    residuals: dict[str, float] = field(default_factory=dict)
    covariance: np.ndarray | None = field(default=None, repr=False)
    n_views: int = 1
    n_points: int = 0
    dot_radius_mm: float = 0.0

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise ConfigError(f"must be one of {', '.join(MODELS)}, got {self.model!r}", key="model")
        m = np.asarray(self.plane, dtype=float)
        if m.shape != (3, 3) or not np.all(np.isfinite(m)):
            raise ConfigError("must be a finite 3 x 3 matrix", key="plane.homography")
        scale = float(np.max(np.abs(m)))
        if scale == 0.0 or abs(np.linalg.det(m / scale)) <= 1e-12 * np.linalg.norm(m / scale) ** 3:
            raise ConfigError("is singular (all zero, or maps the plane onto a line)", key="plane.homography")
        object.__setattr__(self, "plane", _frozen(m))
        if self.model == "multi-view":
            if self.rotation is None or self.translation is None:
                raise ConfigError("the multi-view model needs the plane's rotation and translation", key="plane")
            r = np.asarray(self.rotation, dtype=float)
            t = np.asarray(self.translation, dtype=float).ravel()
            if r.shape != (3, 3) or not np.allclose(r @ r.T, np.eye(3), atol=1e-9) or np.linalg.det(r) < 0:
                raise ConfigError("must be a 3 x 3 rotation matrix", key="plane.rotation")
            if t.shape != (3,) or not np.all(np.isfinite(t)):
                raise ConfigError("must be 3 finite numbers", key="plane.translation_mm")
            if not t[2] > 0:
                raise ConfigError(f"the plane's origin must lie in front of the camera (tz > 0), got tz = {t[2]:g}",
                                  key="plane.translation_mm")
            expected = plane_matrix(r, t)
            a, b = m / np.linalg.norm(m), expected / np.linalg.norm(expected)
            if min(np.max(np.abs(a - b)), np.max(np.abs(a + b))) > 1e-6:
                raise ConfigError("does not match plane.rotation and plane.translation_mm (must be "
                                  "[r1, r2, t] up to scale)", key="plane.homography")
            object.__setattr__(self, "rotation", _frozen(r))
            object.__setattr__(self, "translation", _frozen(t))
        spacing = float(self.spacing_mm)
        if not math.isfinite(spacing) or spacing <= 0:
            raise ConfigError(f"must be a positive finite number, got {spacing}", key="spacing_mm")
        object.__setattr__(self, "spacing_mm", spacing)
        if self.covariance is not None:
            cov = np.asarray(self.covariance, dtype=float)
            n = len(self.parameter_names)
            if cov.shape != (n, n) or not np.all(np.isfinite(cov)):
                raise ConfigError(f"must be a finite {n} x {n} matrix", key="covariance.matrix")
            if np.any(np.diag(cov) < 0) or np.max(np.abs(cov - cov.T)) > 1e-6 * np.max(np.abs(cov)):
                raise ConfigError("must be symmetric with a non-negative diagonal (a covariance matrix)",
                                  key="covariance.matrix")
            object.__setattr__(self, "covariance", _frozen(cov))
        object.__setattr__(self, "residuals", {k: float(v) for k, v in dict(self.residuals).items()})

    # ------------------------------------------------------------------------------------------------ geometry
    @property
    def has_intrinsics(self) -> bool:
        """True for the multi-view model (markers above the plane can be measured)."""
        return self.model == "multi-view"

    def plane_at(self, height_mm: float = 0.0) -> np.ndarray:
        """``M_h`` ``(3, 3)``: plane points at height ``h`` (mm, toward the camera) -> normalized coordinates.

        The single-view model has no intrinsics and refuses ``h != 0``.
        """
        h = float(height_mm)
        if not math.isfinite(h):
            raise VisionError(f"marker height must be finite, got {height_mm}")
        if h == 0.0:
            return self.plane
        if not self.has_intrinsics:
            raise VisionError(f"a single-view calibration (plane homography + radial distortion) has no intrinsics, "
                              f"so it cannot measure markers {h:g} mm above the plane; calibrate with {MIN_VIEWS_ZHANG} "
                              "or more views of the sheet")
        return plane_matrix(self.rotation, self.translation, h)

    def image_to_plane(self, pixels: np.ndarray, height_mm: float = 0.0) -> np.ndarray:
        """Pixels ``(N, 2)`` -> measurement-frame points ``(N, 2)`` mm at height ``h`` (ray-plane intersection)."""
        return image_to_plane(self.camera, self.plane_at(height_mm), pixels)

    def plane_to_image(self, points_mm: np.ndarray, height_mm: float = 0.0) -> np.ndarray:
        """Measurement-frame points ``(N, 2)`` mm at height ``h`` -> pixels ``(N, 2)``."""
        return plane_to_image(self.camera, self.plane_at(height_mm), points_mm)

    def pixel_to_mm(self, points_px: np.ndarray) -> np.ndarray:
        """Pixels ``(N, 2)`` -> points on the reference plane ``(N, 2)`` mm (height 0)."""
        return self.image_to_plane(points_px)

    def mm_to_pixel(self, points_mm: np.ndarray) -> np.ndarray:
        """Points on the reference plane ``(N, 2)`` mm -> pixels ``(N, 2)``."""
        return self.plane_to_image(points_mm)

    @property
    def mm_per_pixel(self) -> float:
        """Local scale at the frame origin: ``sqrt(|det J|)`` of the pixel -> mm map there (mm/px)."""
        origin = self.mm_to_pixel(np.zeros((1, 2)))
        return float(math.sqrt(local_scale(self.camera, self.plane, origin)[0]))

    @property
    def camera_height_mm(self) -> float | None:
        """Distance of the camera centre from the reference plane (multi-view only), mm: ``-r3 . t``."""
        if not self.has_intrinsics:
            return None
        return float(-self.rotation[:, 2] @ self.translation)

    # ------------------------------------------------------------------------------------------------ parameters
    @property
    def parameter_names(self) -> tuple[str, ...]:
        """Names of the parameters the covariance refers to (model-dependent)."""
        return MULTI_VIEW_PARAMETERS if self.has_intrinsics else SINGLE_VIEW_PARAMETERS

    def parameters(self) -> np.ndarray:
        """Parameter vector ``(P,)`` in the order of :meth:`parameter_names` (rotation as a rotation vector, rad)."""
        k, d = self.camera.matrix, self.camera.distortion
        if self.has_intrinsics:
            return np.concatenate([[k[0, 0], k[1, 1], k[0, 2], k[1, 2]], d, rotation_vector(self.rotation),
                                   self.translation])
        m = self.plane / self.plane[2, 2]
        return np.concatenate([d[:2], m.ravel()[:8]])

    def with_parameters(self, p: np.ndarray) -> "Calibration":
        """A copy with parameters ``p`` ``(P,)`` (for propagating the covariance by finite differences)."""
        p = np.asarray(p, dtype=float)
        if self.has_intrinsics:
            k = np.array([[p[0], 0.0, p[2]], [0.0, p[1], p[3]], [0.0, 0.0, 1.0]])
            cam = CameraModel(k, p[4:9], self.camera.image_size)
            rot = rotation_matrix(p[9:12])
            return replace(self, camera=cam, rotation=rot, translation=p[12:15],
                           plane=plane_matrix(rot, p[12:15]))
        cam = CameraModel(self.camera.matrix, np.array([p[0], p[1], 0.0, 0.0, 0.0]), self.camera.image_size)
        return replace(self, camera=cam, plane=np.append(p[2:10], 1.0).reshape(3, 3))

    # ------------------------------------------------------------------------------------------------ files
    def to_dict(self) -> dict[str, Any]:
        """Plain-Python content of the TOML file (module docstring)."""

        def rows(a: np.ndarray) -> list:
            return [[float(v) for v in r] for r in np.asarray(a)]

        plane: dict[str, Any] = {"homography": rows(self.plane)}
        if self.has_intrinsics:
            plane["rotation"] = rows(self.rotation)
            plane["translation_mm"] = [float(v) for v in self.translation]
        table: dict[str, Any] = {
            "model": self.model, "spacing_mm": self.spacing_mm, "image_size": list(self.camera.image_size),
            "n_views": int(self.n_views), "n_points": int(self.n_points), "dot_radius_mm": float(self.dot_radius_mm),
            "camera_matrix": rows(self.camera.matrix), "distortion": [float(v) for v in self.camera.distortion],
            "intrinsics_estimated": self.has_intrinsics, "plane": plane,
            "residuals": {k: float(v) for k, v in self.residuals.items()},
        }
        if self.covariance is not None:
            table["covariance"] = {"parameters": list(self.parameter_names), "matrix": rows(self.covariance)}
        return {"calibration": table}

    def to_toml(self, path: str | Path | None = None) -> str:
        """The calibration as TOML text; also written to ``path`` when given."""
        text = _toml_text(self.to_dict())
        if path is not None:
            Path(path).write_text(text, encoding="utf-8")
        return text

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "<dict>") -> "Calibration":
        """Build from the parsed TOML; every problem is a :class:`ConfigError` naming ``source`` and the key."""

        table = data.get("calibration")
        if not isinstance(table, dict):
            raise ConfigError("missing [calibration] table", source=source, key="calibration")
        _tomlio.reject_unknown(data, {"calibration"}, source=source, where="")
        _tomlio.reject_unknown(table, {"model", "spacing_mm", "image_size", "n_views", "n_points", "dot_radius_mm",
                                       "camera_matrix", "distortion", "intrinsics_estimated", "plane", "residuals",
                                       "covariance"}, source=source, where="calibration")
        model = table.get("model")
        if model not in MODELS:
            raise ConfigError(f"must be one of {', '.join(MODELS)}, got {model!r}", source=source,
                              key="calibration.model")
        spacing = _tomlio.number(table, "spacing_mm", source=source, where="calibration", positive=True)
        radius = _tomlio.number(table, "dot_radius_mm", source=source, where="calibration", nonnegative=True,
                                default=0.0)
        size = _array(table, "image_size", (2,), source, "calibration")
        if np.any(size < 3) or np.any(size != np.round(size)):
            raise ConfigError("must be two whole numbers >= 3 (width, height)", source=source,
                              key="calibration.image_size")
        counts = {}
        for key in ("n_views", "n_points"):
            value = table.get(key, 0)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise ConfigError(f"must be a non-negative whole number, got {value!r}", source=source,
                                  key=f"calibration.{key}")
            counts[key] = value
        matrix = _array(table, "camera_matrix", (3, 3), source, "calibration")
        dist = _array(table, "distortion", (5,), source, "calibration")
        try:
            camera = CameraModel(matrix, dist, (int(size[0]), int(size[1])))
        except VisionError as exc:
            raise ConfigError(str(exc), source=source, key="calibration.camera_matrix") from None
        w, h = camera.image_size
        border = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1], [(w - 1) / 2, 0], [0, (h - 1) / 2],
                           [(w - 1) / 2, h - 1], [w - 1, (h - 1) / 2]], dtype=float)
        try:
            with np.errstate(all="ignore"):
                back = camera.distort(camera.undistort(border))
        except VisionError:
            back = np.full_like(border, np.nan)
        if not (np.all(np.abs(back - border) < 1e-6) and _radial_monotone(camera, border)):
            raise ConfigError("cannot be inverted over the whole image (lens distortion too strong for "
                              "camera_matrix and image_size)", source=source, key="calibration.distortion")
        plane = table.get("plane")
        if not isinstance(plane, dict):
            raise ConfigError("missing [calibration.plane] table", source=source, key="calibration.plane")
        _tomlio.reject_unknown(plane, {"homography", "rotation", "translation_mm"}, source=source,
                               where="calibration.plane")
        homography = _array(plane, "homography", (3, 3), source, "calibration.plane")
        rotation = translation = None
        if model == "multi-view":
            rotation = _array(plane, "rotation", (3, 3), source, "calibration.plane")
            translation = _array(plane, "translation_mm", (3,), source, "calibration.plane")
        residuals = table.get("residuals", {})
        if not isinstance(residuals, dict):
            raise ConfigError("must be a table", source=source, key="calibration.residuals")
        res = {}
        for key in residuals:
            res[key] = _tomlio.number(residuals, key, source=source, where="calibration.residuals", nonnegative=True)
        covariance = None
        if "covariance" in table:
            cov = table["covariance"]
            if not isinstance(cov, dict):
                raise ConfigError("must be a table", source=source, key="calibration.covariance")
            names = MULTI_VIEW_PARAMETERS if model == "multi-view" else SINGLE_VIEW_PARAMETERS
            listed = cov.get("parameters", [])
            if not isinstance(listed, list) or listed != list(names):
                raise ConfigError(f"must list {', '.join(names)} for the {model} model", source=source,
                                  key="calibration.covariance.parameters")
            covariance = _array(cov, "matrix", (len(names), len(names)), source, "calibration.covariance")
        try:
            return cls(camera, homography, model=model, spacing_mm=spacing, rotation=rotation,
                       translation=translation, residuals=res, covariance=covariance, n_views=counts["n_views"],
                       n_points=counts["n_points"], dot_radius_mm=radius)
        except ConfigError as exc:
            raise ConfigError(exc.message, source=source, key=f"calibration.{exc.key}") from None

    @classmethod
    def from_toml(cls, path: str | Path) -> "Calibration":
        """Read a calibration TOML file written by :meth:`to_toml`."""

        path = Path(path)
        source = str(path)
        if not path.is_file():
            raise ConfigError("no such calibration file", source=source)
        text = read_text(source, what="calibration TOML file")
        return cls.from_dict(_tomlio.parse_text(text, source), source)

    @classmethod
    def from_homography(cls, pixel_to_mm: np.ndarray, *, image_size: tuple[int, int],
                        spacing_mm: float = DEFAULT_SPACING_MM) -> "Calibration":
        """A distortion-free single-view calibration from a pixel -> mm homography ``(3, 3)``.

        With the nominal ``K`` (:func:`nominal_matrix`), ``M_0 = (H K)^-1``.
        """
        h = np.asarray(pixel_to_mm, dtype=float)
        k = nominal_matrix(image_size)
        return cls(CameraModel(k, np.zeros(5), image_size), np.linalg.inv(h @ k), model="single-view",
                   spacing_mm=spacing_mm)


def _radial_monotone(camera: CameraModel, pixels: np.ndarray) -> bool:
    """True if the radial distortion ``r_d = r (1 + k1 r^2 + k2 r^4 + k3 r^6)`` increases with ``r`` until it
    reaches the largest distorted radius of ``pixels`` ``(N, 2)`` (so every image point has one undistorted
    point; a fold-over of the polynomial inside the image is a corrupt or impossible calibration)."""
    k = camera.matrix
    dy = (pixels[:, 1] - k[1, 2]) / k[1, 1]
    dx = (pixels[:, 0] - k[0, 2] - k[0, 1] * dy) / k[0, 0]
    r_max = float(np.max(np.hypot(dx, dy)))
    k1, k2, _, _, k3 = camera.distortion
    r = np.linspace(0.0, 3.0 * r_max + 1e-12, 3001)
    with np.errstate(all="ignore"):
        f = r * (1 + k1 * r**2 + k2 * r**4 + k3 * r**6)
    rising = np.concatenate([[True], np.diff(f) > 0])
    first_fall = int(np.argmin(rising)) if not np.all(rising) else len(r)
    return bool(np.any(f[:first_fall] >= r_max))


def _toml_text(data: dict[str, Any]) -> str:
    """TOML text of nested tables of numbers, strings, booleans and (nested) lists, matrices one row per line.

    Floats are written with ``repr`` (shortest round trip), so reading the file
    back gives the same numbers bit for bit.
    """
    import json

    def value(v: Any) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (int, float)):
            return repr(v)
        if isinstance(v, str):
            return json.dumps(v)
        if v and isinstance(v[0], list):
            return "[\n" + "".join(f"    {value(r)},\n" for r in v) + "]"
        return "[" + ", ".join(value(x) for x in v) + "]"

    lines: list[str] = []

    def table(name: str, t: dict[str, Any]) -> None:
        lines.append(f"[{name}]")
        lines.extend(f"{k} = {value(v)}" for k, v in t.items() if not isinstance(v, dict))
        for k, v in t.items():
            if isinstance(v, dict):
                lines.append("")
                table(f"{name}.{k}", v)

    for name, t in data.items():
        table(name, t)
    return "\n".join(lines) + "\n"


def _array(table: dict[str, Any], key: str, shape: tuple[int, ...], source: str, where: str) -> np.ndarray:
    """A finite numeric array of ``shape`` from a TOML table; otherwise ConfigError naming the key."""
    name = f"{where}.{key}"
    if key not in table:
        raise ConfigError("missing", source=source, key=name)

    def check(value: Any, path: str) -> Any:
        if isinstance(value, list):
            return [check(v, f"{path}[{i}]") for i, v in enumerate(value)]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"must be a number, got {value!r}", source=source, key=path)
        if not math.isfinite(value):
            raise ConfigError(f"must be finite, got {value}", source=source, key=path)
        return float(value)

    values = check(table[key], name)
    try:
        arr = np.array(values, dtype=float)
    except ValueError:
        arr = np.zeros(0)
    if arr.shape != shape:
        raise ConfigError(f"must be an array of shape {shape}", source=source, key=name)
    return arr


def nominal_matrix(image_size: tuple[int, int]) -> np.ndarray:
    """Nominal ``K`` of the single-view model: focal length = image diagonal (px), centre = image centre."""
    w, h = image_size
    f = math.hypot(w, h)
    return np.array([[f, 0.0, (w - 1) / 2.0], [0.0, f, (h - 1) / 2.0], [0.0, 0.0, 1.0]])


# ---------------------------------------------------------------------------------------------------- fitting
@dataclass(frozen=True, eq=False)
class View:
    """One calibration image's dots on the lattice: ``pixels`` ``(M, 2)`` (raw centroids), ``grid_mm`` ``(M, 2)``
    lattice positions in that view's sheet frame, ``area_px`` ``(M,)``, ``sigma_px`` ``(M,)``, ``name``."""

    pixels: np.ndarray
    grid_mm: np.ndarray
    area_px: np.ndarray
    sigma_px: np.ndarray
    name: str = "<image>"


def view_from_blobs(blobs: Blobs, image_shape: tuple[int, ...], spacing_mm: float, name: str = "<image>") -> View:
    """Assign detected dots to the sheet's lattice (:func:`~pmaccuracy.vision.grid.find_grid`); errors name ``name``."""
    if len(blobs) < MIN_CALIBRATION_DOTS:
        raise VisionError(f"{name}: found {blobs.describe()}, at least {MIN_CALIBRATION_DOTS} calibration dots "
                          "are needed")
    try:
        grid = find_grid(blobs.centres, image_shape)
    except VisionError as exc:
        raise VisionError(f"{name}: {exc}") from None
    b = blobs.subset(grid.which)
    return View(b.centres, spacing_mm * grid.ij.astype(float), b.area_px, b.sigma_px, name)


def _dot_radius(camera: CameraModel, planes: Sequence[np.ndarray], views: Sequence[View]) -> float:
    """Dot radius (mm): median over all dots of ``sqrt(area_px * mm^2 per px^2 / pi)``."""
    radii = [np.sqrt(v.area_px * local_scale(camera, m, v.pixels) / math.pi) for v, m in zip(views, planes)]
    radius = float(np.median(np.concatenate(radii)))
    return radius if math.isfinite(radius) else 0.0


def _corrected(camera: CameraModel, planes: Sequence[np.ndarray], views: Sequence[View],
               radius_mm: float) -> list[np.ndarray]:
    """Dot centres with the perspective/lens offset of their area centroid removed, per view."""
    if not radius_mm > 0:  # dot areas unknown (centres given as points): nothing to correct
        return [v.pixels for v in views]
    return [v.pixels - disk_image_bias(camera, m, v.grid_mm, radius_mm) for v, m in zip(views, planes)]


def _systematic(residual: np.ndarray, n_free: int, views: Sequence[View]) -> float:
    """Per-coordinate centre error (px) that the detector's noise estimate does not explain.

    ``sqrt(max(s^2 - mean(sigma_k^2), 0))`` with ``s^2 = sum r^2 / (n - p)`` the
    residual variance per coordinate of the fit and ``sigma_k`` the detector's
    noise of each dot centre: what is left is detection bias and model misfit,
    added to every marker centre's noise when a pose's uncertainty is stated.
    """
    s2 = float(np.sum(residual**2)) / max(residual.size - n_free, 1)
    noise2 = float(np.mean(np.concatenate([v.sigma_px for v in views]) ** 2))
    return math.sqrt(max(s2 - noise2, 0.0))


def _fit_zhang(views: Sequence[View], centres: Sequence[np.ndarray], image_size: tuple[int, int], flags: int,
               guess: tuple[np.ndarray, np.ndarray] | None) -> tuple[CameraModel, list[np.ndarray], list[np.ndarray]]:
    """OpenCV ``calibrateCamera`` on the views; returns the camera and per-view rotation matrices and translations."""
    cv2 = require("cv2")

    obj = [np.column_stack([v.grid_mm, np.zeros(len(v.grid_mm))]).astype(np.float32) for v in views]
    img = [c.astype(np.float32).reshape(-1, 1, 2) for c in centres]
    criteria = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 300, 1e-12)
    if guess is not None:
        flags |= cv2.CALIB_USE_INTRINSIC_GUESS
        k0, d0 = guess[0].copy(), guess[1].copy()
    else:
        k0, d0 = None, None
    try:
        _, k, d, rvecs, tvecs = cv2.calibrateCamera(obj, img, image_size, k0, d0, flags=flags, criteria=criteria)
    except cv2.error as exc:
        raise VisionError(f"camera calibration failed ({str(exc).strip().splitlines()[-1]})") from None
    dist = np.zeros(5)
    dist[:min(5, d.size)] = d.ravel()[:5]
    camera = CameraModel(k, dist, image_size)
    return camera, [rotation_matrix(r) for r in rvecs], [np.asarray(t, float).ravel() for t in tvecs]


def _reprojection(p: np.ndarray, views: Sequence[View], image_size: tuple[int, int]) -> np.ndarray:
    """Predicted pixels of all views, stacked ``(sum M, 2)``, for multi-view parameters
    ``p = [fx, fy, cx, cy, k1, k2, p1, p2, k3, (rvec, t) per view]``."""
    cam = CameraModel(np.array([[p[0], 0.0, p[2]], [0.0, p[1], p[3]], [0.0, 0.0, 1.0]]), p[4:9], image_size)
    out = []
    for i, v in enumerate(views):
        q = p[9 + 6 * i: 15 + 6 * i]
        out.append(plane_to_image(cam, plane_matrix(rotation_matrix(q[:3]), q[3:]), v.grid_mm))
    return np.concatenate(out)


def _covariance(func, p: np.ndarray, free: np.ndarray, residual: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """``s^2 (J^T J)^-1`` over the ``free`` parameters (central differences of ``func``), restricted to ``keep``.

    ``s^2 = sum r^2 / (n - p_free)`` with ``r`` the residuals ``(n,)``. Rows and
    columns of fixed parameters are zero. A Jacobian whose column-normalised
    condition number exceeds :data:`MAX_JACOBIAN_CONDITION` (parameters the
    data do not determine) raises :class:`VisionError`.
    """
    steps = 1e-6 * np.maximum(np.abs(p), 1e-3)
    cols = []
    for j in np.flatnonzero(free):  # one column per free parameter
        dp = np.zeros_like(p)
        dp[j] = steps[j]
        cols.append(((func(p + dp) - func(p - dp)) / (2 * steps[j])).ravel())
    jac = np.stack(cols, axis=1)
    dof = residual.size - jac.shape[1]
    if dof <= 0:
        raise VisionError("too few calibration dots for the number of parameters")
    norms = np.linalg.norm(jac, axis=0)
    sv = np.linalg.svd(jac / np.where(norms > 0, norms, 1.0), compute_uv=False)
    if not (np.all(norms > 0) and sv[-1] > sv[0] / MAX_JACOBIAN_CONDITION):
        raise VisionError("the calibration is degenerate: the images do not determine every parameter (identical "
                          "views, or views not tilted enough against each other)")
    s2 = float(np.sum(residual**2)) / dof
    inv = np.linalg.pinv(jac.T @ jac)
    inv = 0.5 * (inv + inv.T)  # symmetric to the last bit
    full = np.zeros((p.size, p.size))
    idx = np.flatnonzero(free)
    full[np.ix_(idx, idx)] = s2 * inv
    return full[np.ix_(keep, keep)]


def fit_multi_view(views: Sequence[View], image_size: tuple[int, int], *, spacing_mm: float,
                   fit_k3: bool = False, fit_tangential: bool = True) -> Calibration:
    """Zhang calibration of ``views`` (the first is the reference plane), with the dot-centre correction.

    See the module docstring. ``fit_k3`` frees the sixth-order radial term,
    ``fit_tangential`` the decentring terms ``p1, p2``.
    """
    cv2 = require("cv2")

    if len(views) < MIN_VIEWS_ZHANG:
        raise VisionError(f"Zhang's method needs at least {MIN_VIEWS_ZHANG} views, got {len(views)}")
    flags = 0 if fit_k3 else cv2.CALIB_FIX_K3
    if not fit_tangential:
        flags |= cv2.CALIB_ZERO_TANGENT_DIST
    centres = [v.pixels for v in views]
    camera, rots, trans = _fit_zhang(views, centres, image_size, flags, None)
    radius = 0.0
    for _ in range(BIAS_ITERATIONS):
        planes = [plane_matrix(r, t) for r, t in zip(rots, trans)]
        radius = _dot_radius(camera, planes, views)
        centres = _corrected(camera, planes, views, radius)
        camera, rots, trans = _fit_zhang(views, centres, image_size, flags,
                                         (camera.matrix, camera.distortion))
    k, d = camera.matrix, camera.distortion
    p = np.concatenate([[k[0, 0], k[1, 1], k[0, 2], k[1, 2]], d]
                       + [np.concatenate([rotation_vector(r), t]) for r, t in zip(rots, trans)])
    measured = np.concatenate(centres)
    residual = measured - _reprojection(p, views, image_size)
    free = np.ones(p.size, dtype=bool)
    free[8] = fit_k3
    free[6:8] = fit_tangential
    keep = np.arange(15)
    cov = _covariance(lambda q: _reprojection(q, views, image_size), p, free, residual.ravel(), keep)
    plane = plane_matrix(rots[0], trans[0])
    on_plane = image_to_plane(camera, plane, centres[0])
    plane_err = np.linalg.norm(on_plane - views[0].grid_mm, axis=1)
    err = np.linalg.norm(residual, axis=1)
    residuals = {"rms_px": float(np.sqrt(np.mean(err**2))), "max_px": float(np.max(err)),
                 "plane_rms_mm": float(np.sqrt(np.mean(plane_err**2))), "plane_max_mm": float(np.max(plane_err)),
                 "systematic_px": _systematic(residual, int(np.count_nonzero(free)), views)}
    return Calibration(camera, plane, model="multi-view", spacing_mm=spacing_mm, rotation=rots[0],
                       translation=trans[0], residuals=residuals, covariance=cov, n_views=len(views),
                       n_points=int(sum(len(v.grid_mm) for v in views)), dot_radius_mm=radius)


def _single_predict(p: np.ndarray, grid_mm: np.ndarray, k: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """Pixels ``(M, 2)`` of the single-view model ``p = [k1, k2, m11 .. m32]`` (``m33 = 1``)."""
    cam = CameraModel(k, np.array([p[0], p[1], 0.0, 0.0, 0.0]), image_size)
    return plane_to_image(cam, np.append(p[2:10], 1.0).reshape(3, 3), grid_mm)


def fit_single_view(view: View, image_size: tuple[int, int], *, spacing_mm: float) -> Calibration:
    """Plane homography + radial distortion ``k1, k2`` of one view (module docstring), with the centre correction.

    The radial terms are fitted only when the dots can constrain them: ``k1``
    and ``k2`` from 20 dots on, ``k1`` alone from 12, none with fewer (then
    they stay 0 and the model is the plain homography).

    Least squares in pixels (:func:`scipy.optimize.least_squares`, Levenberg-
    Marquardt) from the distortion-free homography (OpenCV ``findHomography``,
    all points, least squares).
    """
    cv2 = require("cv2")
    from scipy.optimize import least_squares

    k = nominal_matrix(image_size)
    if len(view.grid_mm) < 8:
        raise VisionError(f"{view.name}: {len(view.grid_mm)} dots on the grid; the single-view model needs 8")
    nominal = CameraModel(k, np.zeros(5), image_size)
    m0, _ = cv2.findHomography(view.grid_mm, nominal.undistort(view.pixels), 0)
    if m0 is None or not np.all(np.isfinite(m0)):
        raise VisionError(f"{view.name}: the calibration homography is degenerate")
    p = np.concatenate([[0.0, 0.0], (m0 / m0[2, 2]).ravel()[:8]])
    centres = view.pixels
    radius = 0.0

    # radial terms need dots spread over the image: k1 and k2 from 20 dots on, k1 alone from 12, none below
    free = np.ones(p.size, dtype=bool)
    free[:2] = [len(view.grid_mm) >= 12, len(view.grid_mm) >= 20]

    def fit(p0: np.ndarray, target: np.ndarray) -> np.ndarray:
        def residual(q: np.ndarray) -> np.ndarray:
            full = p0.copy()
            full[free] = q
            return (_single_predict(full, view.grid_mm, k, image_size) - target).ravel()

        res = least_squares(residual, p0[free], method="lm", x_scale="jac", xtol=1e-14, ftol=1e-14, gtol=1e-14)
        out = p0.copy()
        out[free] = res.x
        return out

    p = fit(p, centres)
    for _ in range(BIAS_ITERATIONS):
        cal = Calibration(CameraModel(k, np.array([p[0], p[1], 0, 0, 0]), image_size),
                          np.append(p[2:10], 1.0).reshape(3, 3))
        radius = _dot_radius(cal.camera, [cal.plane], [view])
        centres = _corrected(cal.camera, [cal.plane], [view], radius)[0]
        p = fit(p, centres)
    residual = centres - _single_predict(p, view.grid_mm, k, image_size)
    cov = _covariance(lambda q: _single_predict(q, view.grid_mm, k, image_size), p, free,
                      residual.ravel(), np.arange(p.size))
    cam = CameraModel(k, np.array([p[0], p[1], 0.0, 0.0, 0.0]), image_size)
    plane = np.append(p[2:10], 1.0).reshape(3, 3)
    plane_err = np.linalg.norm(image_to_plane(cam, plane, centres) - view.grid_mm, axis=1)
    err = np.linalg.norm(residual, axis=1)
    residuals = {"rms_px": float(np.sqrt(np.mean(err**2))), "max_px": float(np.max(err)),
                 "plane_rms_mm": float(np.sqrt(np.mean(plane_err**2))), "plane_max_mm": float(np.max(plane_err)),
                 "systematic_px": _systematic(residual, int(np.count_nonzero(free)), [view])}
    return Calibration(cam, plane, model="single-view", spacing_mm=spacing_mm, residuals=residuals, covariance=cov,
                       n_views=1, n_points=len(view.grid_mm), dot_radius_mm=radius)


def calibrate_views(images: Sequence[np.ndarray], *, names: Sequence[str] | None = None,
                    spacing_mm: float = DEFAULT_SPACING_MM, polarity: str = "dark",
                    max_diameter_px: float | None = None, fit_k3: bool = False) -> Calibration:
    """Calibrate from images ``(H, W)`` of the dot sheet; the first one lies on the reference plane.

    One image: :func:`fit_single_view`; three or more: :func:`fit_multi_view`;
    two: refused (too few for Zhang's method, one more than the single-view
    model uses). Every image must have the same size and show at least six dots
    on the lattice; errors name the image (``names``, default ``image 1`` ...).
    """
    spacing = _positive(spacing_mm, "spacing_mm")
    names = list(names) if names is not None else [f"image {i + 1}" for i in range(len(images))]
    if len(images) == 0:
        raise VisionError("no calibration images given")
    if len(images) == 2:
        raise VisionError(f"2 calibration images: give the plane image alone (homography + radial distortion) or "
                          f"it and at least {MIN_VIEWS_ZHANG - 1} more views (Zhang's method)")
    shape = np.shape(images[0])[:2]
    views = []
    for image, name in zip(images, names):
        if np.shape(image)[:2] != shape:
            raise VisionError(f"{name}: image size {np.shape(image)[1]} x {np.shape(image)[0]} differs from the plane "
                              f"image's {shape[1]} x {shape[0]}")
        blobs = find_blobs(image, polarity=polarity, max_diameter_px=max_diameter_px)
        views.append(view_from_blobs(blobs, shape, spacing, name))
    size = (int(shape[1]), int(shape[0]))
    if len(views) == 1:
        return fit_single_view(views[0], size, spacing_mm=spacing)
    return fit_multi_view(views, size, spacing_mm=spacing, fit_k3=fit_k3)


def calibrate(image: np.ndarray, *, spacing_mm: float = DEFAULT_SPACING_MM, polarity: str = "dark",
              **options: Any) -> Calibration:
    """Single-view calibration from one image of the sheet on the reference plane (see :func:`calibrate_views`)."""
    return calibrate_views([image], spacing_mm=spacing_mm, polarity=polarity, **options)


def calibrate_from_points(points_px: np.ndarray, image_shape: tuple[int, ...], *,
                          spacing_mm: float = DEFAULT_SPACING_MM) -> Calibration:
    """Single-view calibration from dot centres ``(N, 2)`` px (areas unknown: no centroid correction)."""
    pts = np.asarray(points_px, dtype=float).reshape(-1, 2)
    blobs = Blobs(pts, np.zeros(len(pts)), np.zeros(len(pts)), np.ones(len(pts)))
    view = view_from_blobs(blobs, image_shape, _positive(spacing_mm, "spacing_mm"), "points")
    return fit_single_view(view, (int(image_shape[1]), int(image_shape[0])), spacing_mm=spacing_mm)
