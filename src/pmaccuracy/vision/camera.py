"""Camera model: pinhole projection with Brown-Conrady lens distortion, planes at a height, disk images.

Frames and conventions
----------------------
*Camera frame* (OpenCV's): ``X`` right, ``Y`` down, ``Z`` forward along the
optical axis, mm. *Normalized coordinates* ``n = [X / Z, Y / Z]`` (``(N, 2)``,
dimensionless). *Pixels* ``[col, row]`` (``(N, 2)``), integer values at pixel
centres.

Projection (OpenCV's model and parameter order ``k1, k2, p1, p2, k3``)::

    r^2 = x^2 + y^2,   q = 1 + k1 r^2 + k2 r^4 + k3 r^6
    x_d = x q + 2 p1 x y + p2 (r^2 + 2 x^2)
    y_d = y q + p1 (r^2 + 2 y^2) + 2 p2 x y
    col = fx x_d + cx,  row = fy y_d + cy                        (K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]])

*Plane frame*: a plane point ``[x, y]`` (mm) at height ``h`` (mm, along the
plane normal toward the camera) sits at ``X = R [x, y, h] + t`` in the camera
frame (``R`` ``(3, 3)`` rotation, ``t`` ``(3,)`` mm). Its normalized image is
therefore the homography ``n ~ M_h [x, y, 1]`` with ``M_h = [r1, r2, t + h r3]``
(``r_k`` the columns of ``R``): exact ray-plane intersection, both ways.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import VisionError
from ._util import apply_homography

#: Names of the distortion coefficients, in OpenCV's order.
DISTORTION_NAMES = ("k1", "k2", "p1", "p2", "k3")


def _freeze(arr: np.ndarray) -> np.ndarray:
    arr = np.array(arr, dtype=float)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class CameraModel:
    """Intrinsics ``matrix`` ``K`` ``(3, 3)`` (px), ``distortion`` ``(5,)`` ``[k1, k2, p1, p2, k3]``, ``image_size``
    ``(width, height)`` px. See the module docstring for the equations."""

    matrix: np.ndarray
    distortion: np.ndarray
    image_size: tuple[int, int]

    def __post_init__(self) -> None:
        k = np.asarray(self.matrix, dtype=float)
        d = np.asarray(self.distortion, dtype=float).ravel()
        if k.shape != (3, 3) or not np.all(np.isfinite(k)):
            raise VisionError(f"camera matrix must be a finite 3 x 3 array, got shape {k.shape}")
        if not (k[0, 0] > 0 and k[1, 1] > 0) or np.any(k[1:, 0] != 0) or k[2, 1] != 0 or k[2, 2] != 1:
            raise VisionError("camera matrix must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0")
        if d.shape != (5,) or not np.all(np.isfinite(d)):
            raise VisionError(f"distortion must be 5 finite numbers (k1, k2, p1, p2, k3), got shape {d.shape}")
        w, h = (int(v) for v in self.image_size)
        if w < 3 or h < 3:
            raise VisionError(f"image size must be at least 3 x 3 pixels, got {w} x {h}")
        object.__setattr__(self, "matrix", _freeze(k))
        object.__setattr__(self, "distortion", _freeze(d))
        object.__setattr__(self, "image_size", (w, h))

    def distort(self, normalized: np.ndarray) -> np.ndarray:
        """Normalized coordinates ``(N, 2)`` -> pixels ``(N, 2)`` (distortion, then ``K``)."""
        n = np.asarray(normalized, dtype=float).reshape(-1, 2)
        return self._to_pixels(_distort_normalized(n, self.distortion))

    def _to_pixels(self, nd: np.ndarray) -> np.ndarray:
        k = self.matrix
        return np.stack([k[0, 0] * nd[:, 0] + k[0, 1] * nd[:, 1] + k[0, 2], k[1, 1] * nd[:, 1] + k[1, 2]], axis=1)

    def undistort(self, pixels: np.ndarray, *, tol: float = 1e-13, max_iter: int = 200) -> np.ndarray:
        """Pixels ``(N, 2)`` -> normalized coordinates ``(N, 2)``: inverse of :meth:`distort`.

        ``K^-1`` gives the distorted normalized point ``d``; the undistorted ``n``
        solves ``D(n) = d`` by Newton's method with the analytic 2 x 2 Jacobian of
        ``D`` (vectorized over the points), from ``n = d``, until every step is
        below ``tol``. Points where that fails (outside the region where the
        distortion polynomial is invertible) raise :class:`VisionError`.
        """
        px = np.asarray(pixels, dtype=float).reshape(-1, 2)
        k = self.matrix
        dy = (px[:, 1] - k[1, 2]) / k[1, 1]
        dx = (px[:, 0] - k[0, 2] - k[0, 1] * dy) / k[0, 0]
        target = np.stack([dx, dy], axis=1)
        n = target.copy()
        dist = self.distortion
        if not np.any(dist):
            return n
        for _ in range(max_iter):
            f, jac = _distort_with_jacobian(n, dist)
            r = target - f
            det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
            step = np.stack([jac[:, 1, 1] * r[:, 0] - jac[:, 0, 1] * r[:, 1],
                             jac[:, 0, 0] * r[:, 1] - jac[:, 1, 0] * r[:, 0]], axis=1) / det[:, None]
            n = n + step
            if np.all(np.abs(step) < tol):
                break
        else:
            raise VisionError("lens distortion cannot be inverted at some image points (outside the model's "
                              "valid region)")
        return n

    def project(self, points_camera: np.ndarray) -> np.ndarray:
        """Camera-frame points ``(N, 3)`` (mm, ``Z > 0``) -> pixels ``(N, 2)``."""
        p = np.asarray(points_camera, dtype=float).reshape(-1, 3)
        return self.distort(p[:, :2] / p[:, 2:3])


def _distort_normalized(n: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Brown-Conrady distortion of normalized points ``(N, 2)`` (module docstring), result ``(N, 2)``."""
    k1, k2, p1, p2, k3 = dist
    x, y = n[:, 0], n[:, 1]
    r2 = x * x + y * y
    q = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    return np.stack([x * q + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
                     y * q + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y], axis=1)


def _distort_with_jacobian(n: np.ndarray, dist: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distortion ``D(n)`` ``(N, 2)`` and its Jacobian ``dD/dn`` ``(N, 2, 2)``."""
    k1, k2, p1, p2, k3 = dist
    x, y = n[:, 0], n[:, 1]
    r2 = x * x + y * y
    q = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    dq = k1 + r2 * (2 * k2 + 3 * k3 * r2)  # dq / d(r^2)
    f = np.stack([x * q + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
                  y * q + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y], axis=1)
    jac = np.empty((len(n), 2, 2))
    jac[:, 0, 0] = q + 2 * x * x * dq + 2 * p1 * y + 6 * p2 * x
    jac[:, 0, 1] = 2 * x * y * dq + 2 * p1 * x + 2 * p2 * y
    jac[:, 1, 0] = 2 * x * y * dq + 2 * p1 * x + 2 * p2 * y
    jac[:, 1, 1] = q + 2 * y * y * dq + 6 * p1 * y + 2 * p2 * x
    return f, jac


def rotation_matrix(rvec: np.ndarray) -> np.ndarray:
    """Rotation ``(3, 3)`` of a rotation vector ``(3,)`` (axis * angle, rad): Rodrigues' formula.

    ``R = I + sin(a) [u]x + (1 - cos(a)) [u]x^2`` with ``a = |rvec|``, ``u = rvec / a``.
    """
    r = np.asarray(rvec, dtype=float).ravel()
    a = float(np.linalg.norm(r))
    if a < 1e-15:
        return np.eye(3)
    u = r / a
    ux = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    return np.eye(3) + math.sin(a) * ux + (1.0 - math.cos(a)) * ux @ ux


def rotation_vector(rotation: np.ndarray) -> np.ndarray:
    """Rotation vector ``(3,)`` (rad) of a rotation matrix ``(3, 3)``: inverse of :func:`rotation_matrix`."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(np.asarray(rotation, dtype=float)).as_rotvec()


def plane_matrix(rotation: np.ndarray, translation: np.ndarray, height_mm: float = 0.0) -> np.ndarray:
    """Homography ``M_h`` ``(3, 3)`` from plane points ``[x, y, 1]`` at height ``h`` to normalized image points.

    ``M_h = [r1, r2, t + h r3]`` (columns), so that ``[X, Y, Z] = M_h [x, y, 1]`` is
    the camera-frame position of the plane point ``[x, y, h]`` (module docstring).
    """
    r = np.asarray(rotation, dtype=float)
    t = np.asarray(translation, dtype=float).ravel()
    return np.column_stack([r[:, 0], r[:, 1], t + float(height_mm) * r[:, 2]])


def image_to_plane(camera: CameraModel, plane_to_normalized: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """Pixels ``(N, 2)`` -> plane points ``(N, 2)`` mm: undistort, then ``M^-1`` (ray-plane intersection)."""
    return apply_homography(np.linalg.inv(plane_to_normalized), camera.undistort(pixels))


def plane_to_image(camera: CameraModel, plane_to_normalized: np.ndarray, points_mm: np.ndarray) -> np.ndarray:
    """Plane points ``(N, 2)`` mm -> pixels ``(N, 2)``: ``M``, then distortion and ``K``."""
    return camera.distort(apply_homography(plane_to_normalized, points_mm))


def disk_image_bias(camera: CameraModel, plane_to_normalized: np.ndarray, centres_mm: np.ndarray,
                    radius_mm: float, vertices: int = 96) -> np.ndarray:
    """Offset ``(N, 2)`` px between the area centroid of a disk's image and the image of its centre.

    A disk of radius ``radius_mm`` around each plane point ``centres_mm`` ``(N, 2)``
    is imaged through ``M`` and the lens; its outline (``vertices`` points) is
    projected and the area centroid of that polygon (shoelace formula)
    ``c = sum (p_k + p_k+1)(p_k x p_k+1) / (6 A)`` is compared with the projected
    centre. A tilted circle images as an ellipse whose centre is not the image
    of the circle's centre (perspective), and lens distortion bends it further;
    an intensity-weighted centroid of a uniformly dark disk is the area centroid
    (blur by a symmetric point-spread function keeps it), so subtracting this
    offset from a measured centroid gives the image of the true centre.
    """
    c = np.asarray(centres_mm, dtype=float).reshape(-1, 2)
    t = np.linspace(0.0, 2 * np.pi, int(vertices), endpoint=False)
    circle = float(radius_mm) * np.stack([np.cos(t), np.sin(t)], axis=1)
    outline = plane_to_image(camera, plane_to_normalized, (c[:, None, :] + circle).reshape(-1, 2))
    p = outline.reshape(len(c), len(t), 2)
    q = np.roll(p, -1, axis=1)
    cross = p[..., 0] * q[..., 1] - q[..., 0] * p[..., 1]
    area = 0.5 * np.sum(cross, axis=1)
    centroid = np.sum((p + q) * cross[..., None], axis=1) / (6.0 * area[:, None])
    return centroid - plane_to_image(camera, plane_to_normalized, c)


def local_scale(camera: CameraModel, plane_to_normalized: np.ndarray, pixels: np.ndarray,
                step: float = 0.5) -> np.ndarray:
    """Plane area per pixel area ``(N,)`` (mm^2/px^2) at pixels ``(N, 2)``: ``|det J|`` of pixel -> plane.

    ``J`` by central differences of :func:`image_to_plane` with ``step`` px.
    """
    px = np.asarray(pixels, dtype=float).reshape(-1, 2)
    offsets = np.array([[step, 0.0], [-step, 0.0], [0.0, step], [0.0, -step]])
    mapped = image_to_plane(camera, plane_to_normalized, (px[:, None, :] + offsets).reshape(-1, 2))
    mapped = mapped.reshape(len(px), 4, 2)
    jx = (mapped[:, 0] - mapped[:, 1]) / (2 * step)
    jy = (mapped[:, 2] - mapped[:, 3]) / (2 * step)
    return np.abs(jx[:, 0] * jy[:, 1] - jx[:, 1] * jy[:, 0])
