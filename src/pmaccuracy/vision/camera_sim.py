"""A physically modelled camera for tests and demonstrations: seeded, reproducible 8-bit images.

The scene is the paper's set-up (Sec. 5): one camera about 340 mm above a
reference plane, a dot sheet lying on that plane (or moved and tilted for the
calibration views) and the platform's 2 x 2 markers at a height ``h`` above it.
The *world frame* is the measurement frame the calibration is meant to recover:
the sheet of the reference view has its dots at ``spacing * (i, j)``, dot
``(0, 0)`` is the one nearest the image centre and ``x`` runs along the image
columns, ``z`` toward the camera.

Image formation, step by step (every step exact or physically modelled):

1. **Geometry.** For every sub-pixel sample (``supersample^2`` per pixel) the
   pixel is undistorted (Brown-Conrady, Newton inversion,
   :meth:`CameraModel.undistort`) and its viewing ray is intersected with the
   plane of the disk it might show (ray-plane intersection through the exact
   homography ``M_h^-1``, :func:`pmaccuracy.vision.camera.plane_matrix`), which
   handles tilt, lens distortion and marker height without approximation. A
   sample at plane distance ``d`` from a disk centre covers
   ``clip((r - d) / e + 1/2, 0, 1)`` of its footprint (``e`` the footprint's
   size in the plane), which removes the sub-sample staircase.
2. **Reflectance.** Background ``reflectance_background``, disks
   ``reflectance_dots`` (painted in order, later disks on top).
3. **Illumination and vignetting.** The irradiance is the reflectance times
   ``L(u, v) = (1 - a rho^2) (1 + g_x xi + g_y eta)``, ``rho`` the distance from
   the image centre relative to the corner's, ``xi, eta`` in [-1, 1] across the
   image; :func:`illumination` chooses ``a`` and ``g`` for a requested total
   fall-off ``1 - min L / max L``.
4. **Optics blur**: Gaussian point-spread function of ``blur_px``.
5. **Sensor**: ``full_well_e`` electrons at irradiance 1, Poisson shot noise
   (normal approximation ``sqrt(e)``), Gaussian read noise ``read_noise_e``,
   then 8-bit quantization ``round(255 e / full_well_e)`` clipped to [0, 255].

Nothing here is used by the measurement code: it is the test camera.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import VisionError
from ._util import DEFAULT_SPACING_MM, apply_homography
from .camera import CameraModel, plane_matrix, plane_to_image, rotation_matrix
from .pose import platform_markers

#: The paper's camera (Sec. 5): sensor size (px), pixel pitch (mm), focal length (mm), height above the plane (mm).
AALBORG_SIZE = (1280, 1024)
AALBORG_PIXEL_MM = 0.0074
AALBORG_FOCAL_MM = 25.0
AALBORG_HEIGHT_MM = 340.0


@dataclass(frozen=True, eq=False)
class SimulatedCamera:
    """A camera over the reference plane, with its lighting and sensor (module docstring).

    ``rotation`` ``(3, 3)`` and ``translation`` ``(3,)`` (mm) map world points to
    the camera frame: ``X = R w + t``.
    """

    camera: CameraModel
    rotation: np.ndarray
    translation: np.ndarray
    falloff: float = 0.3
    gradient_direction_deg: float = 30.0
    gradient_share: float = 0.4
    blur_px: float = 0.8
    full_well_e: float = 8000.0
    read_noise_e: float = 12.0
    reflectance_background: float = 0.85
    reflectance_dots: float = 0.12
    supersample: int = 4

    def plane(self, height_mm: float = 0.0) -> np.ndarray:
        """``M_h`` ``(3, 3)``: world plane points ``[x, y]`` at height ``h`` -> normalized image points."""
        return plane_matrix(self.rotation, self.translation, height_mm)

    def project(self, points_mm: np.ndarray, height_mm: float = 0.0) -> np.ndarray:
        """Exact pixel positions ``(N, 2)`` of world points ``(N, 2)`` at height ``h``."""
        return plane_to_image(self.camera, self.plane(height_mm), points_mm)

    @property
    def centre_px(self) -> np.ndarray:
        w, h = self.camera.image_size
        return np.array([(w - 1) / 2.0, (h - 1) / 2.0])


def aalborg_camera(*, tilt_deg: float = 2.0, tilt_azimuth_deg: float = 35.0, yaw_deg: float = 3.0,
                   corner_distortion_px: float = 4.0, k2_share: float = 0.2, tangential: tuple[float, float] = (
                       2e-4, -1.5e-4), principal_offset_px: tuple[float, float] = (6.0, -4.0),
                   axis_hit_mm: tuple[float, float] = (3.1, -2.4), height_mm: float = AALBORG_HEIGHT_MM,
                   size: tuple[int, int] = AALBORG_SIZE, pixel_mm: float = AALBORG_PIXEL_MM,
                   focal_mm: float = AALBORG_FOCAL_MM, **options) -> SimulatedCamera:
    """The paper's camera: ``size`` px of ``pixel_mm``, focal length ``focal_mm``, ``height_mm`` above the plane.

    The optical axis is tilted by ``tilt_deg`` from the plane normal (toward the
    azimuth ``tilt_azimuth_deg`` in the image), the image axes are turned by
    ``yaw_deg`` about the normal, and the axis meets the plane at
    ``axis_hit_mm``. Barrel distortion ``k1 r^2 + k2 r^4`` is scaled so that the
    image corner moves by ``corner_distortion_px`` (``k2`` carrying ``k2_share`` of
    it), plus decentring ``tangential = (p1, p2)``. Other keywords set the
    :class:`SimulatedCamera` fields (lighting, blur, sensor).
    """
    w, h = (int(v) for v in size)
    f = focal_mm / pixel_mm
    cx, cy = (w - 1) / 2.0 + principal_offset_px[0], (h - 1) / 2.0 + principal_offset_px[1]
    r_corner = math.hypot(max(cx, w - 1 - cx), max(cy, h - 1 - cy)) / f  # normalized radius of the far corner
    # barrel: the corner moves inward by corner_distortion_px = f r (k1 r^2 + k2 r^4)
    total = -corner_distortion_px / (f * r_corner)
    k1 = (1 - k2_share) * total / r_corner**2
    k2 = k2_share * total / r_corner**4
    camera = CameraModel(np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]]),
                         np.array([k1, k2, tangential[0], tangential[1], 0.0]), (w, h))
    az = math.radians(tilt_azimuth_deg)
    tilt = rotation_matrix(math.radians(tilt_deg) * np.array([-math.sin(az), math.cos(az), 0.0]))
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    yaw = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    rot = tilt @ np.diag([1.0, -1.0, -1.0]) @ yaw  # world -> camera; looking down -z of the world
    axis = rot.T @ np.array([0.0, 0.0, 1.0])  # optical axis in the world
    # camera centre C at height_mm such that C + s axis hits the plane at axis_hit_mm
    s_hit = height_mm / -axis[2]
    centre = np.array([axis_hit_mm[0] - s_hit * axis[0], axis_hit_mm[1] - s_hit * axis[1], height_mm])
    sim = SimulatedCamera(camera, rot, -rot @ centre, **options)
    _check_origin(sim)
    return sim


def _check_origin(sim: SimulatedCamera, spacing_mm: float = DEFAULT_SPACING_MM) -> None:
    """The world origin must be the dot nearest the image centre (else the truth is in another frame)."""
    nodes = spacing_mm * np.array([[0, 0], [1, 0], [-1, 0], [0, 1], [0, -1], [1, 1], [1, -1], [-1, 1], [-1, -1]])
    dist = np.linalg.norm(sim.project(nodes) - sim.centre_px, axis=1)
    if np.argmin(dist) != 0 or np.sort(dist)[1] - dist[0] < 10.0:
        raise VisionError("simulated camera: the world origin is not clearly the dot nearest the image centre")


def illumination(shape: tuple[int, int], falloff: float, direction_deg: float = 30.0,
                 gradient_share: float = 0.4) -> np.ndarray:
    """Relative illumination ``(H, W)`` in (0, 1] with total fall-off ``1 - min/max = falloff``.

    ``L = (1 - a rho^2) (1 + g (cos(d) xi + sin(d) eta))``: a radial vignetting
    ``a`` and a linear gradient ``g`` along ``direction_deg``, with the gradient
    taking ``gradient_share`` of the log fall-off; normalised to max 1.
    """
    if not 0.0 <= falloff < 1.0:
        raise VisionError(f"falloff must be in [0, 1), got {falloff}")
    h, w = shape
    d = math.radians(direction_deg)

    def parts(rows: int, cols: int) -> tuple[np.ndarray, np.ndarray]:
        xi = np.linspace(-1.0, 1.0, cols)[None, :]
        eta = np.linspace(-1.0, 1.0, rows)[:, None]
        rho2 = (xi**2 * (w / 2) ** 2 + eta**2 * (h / 2) ** 2) / ((w / 2) ** 2 + (h / 2) ** 2)
        return rho2, math.cos(d) * xi + math.sin(d) * eta

    log_total = -math.log(1.0 - falloff)
    g_ratio = math.exp(gradient_share * log_total)  # max/min of the gradient factor
    span = 2.0 * (abs(math.cos(d)) + abs(math.sin(d)))
    g = (g_ratio - 1) / (g_ratio + 1) * 2 / span
    # choose a so that the field's min/max equals 1 - falloff (bisection on a coarse grid: monotone in a)
    rho2, proj = parts(129, 129)
    lo, hi = 0.0, 0.999
    for _ in range(60):
        a = 0.5 * (lo + hi)
        coarse = (1.0 - a * rho2) * (1.0 + g * proj)
        if coarse.min() / coarse.max() > 1.0 - falloff:
            lo = a
        else:
            hi = a
    rho2, proj = parts(h, w)
    field_ = (1.0 - lo * rho2) * (1.0 + g * proj)
    return field_ / field_.max()


@dataclass(frozen=True)
class Disk:
    """A disk of radius ``radius_mm`` at plane point ``centre_mm`` on a plane ``plane`` (3x3, plane -> normalized),
    with reflectance ``reflectance``."""

    centre_mm: tuple[float, float]
    radius_mm: float
    plane: np.ndarray = field(repr=False)
    reflectance: float


EDGE_MARGIN_PX = 3.0  # rim half-width in pixel footprints (see _coverage)


def _coverage(sim: SimulatedCamera, disk: Disk, shape: tuple[int, int]) -> tuple[tuple[slice, slice], np.ndarray]:
    """Window (row, col slices) and covered fraction of each window pixel for one disk (module docstring, step 1)."""
    n = int(sim.supersample)
    t = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    outline = plane_to_image(sim.camera, disk.plane,
                             np.asarray(disk.centre_mm) + disk.radius_mm * np.stack([np.cos(t), np.sin(t)], 1))
    lo = np.floor(outline.min(axis=0)).astype(int) - 2
    hi = np.ceil(outline.max(axis=0)).astype(int) + 2
    c0, r0 = max(lo[0], 0), max(lo[1], 0)
    c1, r1 = min(hi[0], shape[1] - 1), min(hi[1], shape[0] - 1)
    if c0 > c1 or r0 > r1:
        return (slice(0, 0), slice(0, 0)), np.zeros((0, 0))
    inverse = np.linalg.inv(disk.plane)
    centre = np.asarray(disk.centre_mm)

    def plane_distance(cols: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """Plane distance from the disk centre of the pixel points ``(cols, rows)`` (any equal shapes)."""
        pts = sim.camera.undistort(np.stack([cols.ravel(), rows.ravel()], axis=1))
        return np.linalg.norm(apply_homography(inverse, pts) - centre, axis=1).reshape(cols.shape)

    # footprint of one pixel in the plane: sqrt of the local area scale at the centre
    centre_px = plane_to_image(sim.camera, disk.plane, centre[None])[0]
    probe = apply_homography(inverse, sim.camera.undistort(centre_px + np.array([[0.0, 0.0], [1.0, 0.0],
                                                                                   [0.0, 1.0]])))
    per_px = math.sqrt(abs(np.linalg.det(np.stack([probe[1] - probe[0], probe[2] - probe[0]]))))
    # Pixel centres first: a pixel whose centre lies more than EDGE_MARGIN_PX footprints inside (outside) the
    # rim has every sub-sample fully covered (uncovered), since its sub-samples lie within 0.53 px of its
    # centre; only the pixels of the rim are supersampled. Same image as supersampling every pixel.
    cc, rr = np.meshgrid(np.arange(c0, c1 + 1, dtype=float), np.arange(r0, r1 + 1, dtype=float))
    d0 = plane_distance(cc, rr)
    win = (d0 < disk.radius_mm).astype(float)
    rim = np.abs(d0 - disk.radius_mm) <= EDGE_MARGIN_PX * per_px
    offsets = (np.arange(n) + 0.5) / n - 0.5
    sub_c = cc[rim][:, None, None] + offsets[None, None, :]          # (m, 1, n): columns vary along axis 2
    sub_r = rr[rim][:, None, None] + offsets[None, :, None]          # (m, n, 1): rows along axis 1
    sub_c, sub_r = np.broadcast_arrays(sub_c, sub_r)
    sub = np.clip((disk.radius_mm - plane_distance(sub_c, sub_r)) / (per_px / n) + 0.5, 0.0, 1.0)
    win[rim] = sub.mean(axis=(1, 2))
    return (slice(r0, r1 + 1), slice(c0, c1 + 1)), win


def render(sim: SimulatedCamera, disks: list[Disk], *, seed: int | None) -> np.ndarray:
    """8-bit image ``(H, W)`` ``uint8`` of the disks over the background (module docstring, steps 1-5)."""
    w, h = sim.camera.image_size
    refl = np.full((h, w), float(sim.reflectance_background))
    for disk in disks:  # loop over disks; the pixels of each are vectorized
        window, cov = _coverage(sim, disk, (h, w))
        if cov.size:
            refl[window] = refl[window] * (1.0 - cov) + disk.reflectance * cov
    irradiance = refl * illumination((h, w), sim.falloff, sim.gradient_direction_deg, sim.gradient_share)
    if sim.blur_px > 0:
        from scipy import ndimage

        irradiance = ndimage.gaussian_filter(irradiance, sim.blur_px, mode="nearest")
    rng = np.random.default_rng(seed)
    electrons = irradiance * sim.full_well_e
    electrons = electrons + np.sqrt(electrons) * rng.standard_normal(electrons.shape)
    electrons = electrons + sim.read_noise_e * rng.standard_normal(electrons.shape)
    return np.clip(np.rint(255.0 * electrons / sim.full_well_e), 0, 255).astype(np.uint8)


@dataclass(frozen=True, eq=False)
class SheetView:
    """A rendered view of the dot sheet: ``image`` ``(H, W)`` uint8; the sheet's pose in the camera frame
    (``rotation`` ``(3, 3)``, ``translation`` ``(3,)`` mm, sheet points ``[x, y, 0]``); the drawn dots
    ``centres_mm`` ``(N, 2)`` (sheet frame) and ``centres_px`` ``(N, 2)`` (exact images of their centres)."""

    image: np.ndarray = field(repr=False)
    rotation: np.ndarray
    translation: np.ndarray
    centres_mm: np.ndarray = field(repr=False)
    centres_px: np.ndarray = field(repr=False)


def render_view(sim: SimulatedCamera, view: int, *, pose_seed: int = 0, seed: int | None = None,
                **options) -> SheetView:
    """:func:`render_sheet` of calibration view ``view`` (:func:`calibration_pose`; 0 = the reference plane)."""
    rs, ts = calibration_pose(view, seed=pose_seed)
    return render_sheet(sim, sheet_rotation=rs, sheet_translation=ts, seed=seed, **options)


def render_sheet(sim: SimulatedCamera, *, sheet_rotation: np.ndarray | None = None,
                 sheet_translation: np.ndarray | None = None, spacing_mm: float = DEFAULT_SPACING_MM,
                 dot_radius_mm: float = 2.0, seed: int | None = None) -> SheetView:
    """Image of a dot sheet (dots at ``spacing * (i, j)`` of radius ``dot_radius_mm``) large enough to fill the view.

    The sheet lies at ``w = R_s s + t_s`` in the world (default: on the reference
    plane, ``R_s = I``, ``t_s = 0``, i.e. the measurement frame). Dots cut by the
    image border are drawn cut, as a real camera sees them.
    """
    rs = np.eye(3) if sheet_rotation is None else np.asarray(sheet_rotation, dtype=float)
    ts = np.zeros(3) if sheet_translation is None else np.asarray(sheet_translation, dtype=float)
    rot = sim.rotation @ rs
    trans = sim.rotation @ ts + sim.translation
    m = plane_matrix(rot, trans)
    w, h = sim.camera.image_size
    corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1], [(w - 1) / 2, 0], [(w - 1) / 2, h - 1],
                        [0, (h - 1) / 2], [w - 1, (h - 1) / 2]], dtype=float)
    on_sheet = apply_homography(np.linalg.inv(m), sim.camera.undistort(corners))
    lo = np.floor(on_sheet.min(axis=0) / spacing_mm).astype(int) - 1
    hi = np.ceil(on_sheet.max(axis=0) / spacing_mm).astype(int) + 1
    ii, jj = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
    centres = spacing_mm * np.stack([ii.ravel(), jj.ravel()], axis=1).astype(float)
    px = plane_to_image(sim.camera, m, centres)
    margin = 3 * dot_radius_mm / spacing_mm * np.ptp(px, axis=0).max() / max(hi - lo)
    inside = np.all((px > -margin) & (px < np.array([w - 1, h - 1]) + margin), axis=1)
    centres, px = centres[inside], px[inside]
    disks = [Disk((float(c[0]), float(c[1])), dot_radius_mm, m, sim.reflectance_dots) for c in centres]
    return SheetView(render(sim, disks, seed=seed), rot, trans, centres, px)


def calibration_pose(view: int, *, seed: int = 0, tilt_range_deg: tuple[float, float] = (10.0, 30.0),
                     pivot_mm: tuple[float, float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Sheet pose ``(R_s (3, 3), t_s (3,) mm)`` of calibration view number ``view`` (0 = on the reference plane).

    View ``k >= 1`` turns the sheet by an angle in ``tilt_range_deg`` about an
    in-plane axis through ``pivot_mm`` whose azimuth advances by the golden
    angle from view to view (so any number of views spreads around the
    circle), spins it by up to 15 deg about its normal and shifts it by up to
    7 mm in the plane and 15 mm in height; the random parts come from
    ``numpy.random.default_rng([seed, k])``, so a view does not depend on how
    many others are drawn.
    """
    if view == 0:
        return np.eye(3), np.zeros(3)
    if view < 0:
        raise VisionError(f"view must be 0 (the reference plane) or a positive number, got {view}")
    rng = np.random.default_rng([int(seed), int(view)])
    az = math.radians(137.508 * view + rng.uniform(-20.0, 20.0))
    tilt = math.radians(rng.uniform(*tilt_range_deg))
    spin = math.radians(rng.uniform(-15.0, 15.0))
    rs = rotation_matrix(tilt * np.array([math.cos(az), math.sin(az), 0.0])) @ rotation_matrix([0.0, 0.0, spin])
    pivot = np.array([pivot_mm[0], pivot_mm[1], 0.0])
    shift = np.array([rng.uniform(-7, 7), rng.uniform(-7, 7), rng.uniform(-15, 15)])
    return rs, pivot - rs @ pivot + shift


def platform_disks(sim: SimulatedCamera, x: float, y: float, phi: float, height_mm: float, *,
                   spacing_mm: float = DEFAULT_SPACING_MM, marker_radius_mm: float = 1.5) -> list[Disk]:
    """The 2 x 2 markers of the platform pose ``(x, y, phi)`` (mm, mm, rad), ``height_mm`` above the plane."""

    m = sim.plane(height_mm)
    return [Disk((float(p[0]), float(p[1])), marker_radius_mm, m, sim.reflectance_dots)
            for p in platform_markers(x, y, phi, spacing_mm)]


def stray_blobs(sim: SimulatedCamera, *, seed: int, count: int = 4, avoid_mm: tuple[float, float] = (0.0, 0.0),
                avoid_radius_mm: float = 25.0) -> list[Disk]:
    """Seeded distractors on the reference plane: dust specks (0.3-0.5 mm) and large round spots (4-6 mm radius),
    kept ``avoid_radius_mm`` away from ``avoid_mm``."""
    rng = np.random.default_rng(seed)
    w, h = sim.camera.image_size
    out: list[Disk] = []
    m = sim.plane(0.0)
    while len(out) < count:
        px = rng.uniform([60, 60], [w - 60, h - 60])
        p = apply_homography(np.linalg.inv(m), sim.camera.undistort(px[None]))[0]
        if np.hypot(*(p - np.asarray(avoid_mm))) < avoid_radius_mm:
            continue
        radius = rng.uniform(0.3, 0.5) if len(out) % 2 == 0 else rng.uniform(4.0, 6.0)
        out.append(Disk((float(p[0]), float(p[1])), radius, m, sim.reflectance_dots))
    return out


def render_platform(sim: SimulatedCamera, x: float, y: float, phi: float, height_mm: float = 0.0, *,
                    spacing_mm: float = DEFAULT_SPACING_MM, marker_radius_mm: float = 1.5,
                    distractors: int = 0, seed: int | None = None) -> np.ndarray:
    """8-bit image ``(H, W)`` of the platform markers at pose ``(x, y, phi)`` (world frame), ``height_mm`` up.

    ``distractors`` adds :func:`stray_blobs` (seeded by ``seed``) on the plane.
    """
    disks = []
    if distractors:
        disks += stray_blobs(sim, seed=0 if seed is None else seed + 7919, count=distractors, avoid_mm=(x, y))
    disks += platform_disks(sim, x, y, phi, height_mm, spacing_mm=spacing_mm, marker_radius_mm=marker_radius_mm)
    return render(sim, disks, seed=seed)
