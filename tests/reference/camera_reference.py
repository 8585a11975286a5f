"""An independent renderer of the paper's camera, written apart from pmaccuracy.vision to test it.

Nothing here imports pmaccuracy. The approach is deliberately different from
``pmaccuracy.vision.camera_sim`` (which maps pixels back onto the plane): every
disk is cut into a fine square lattice of area elements *on its plane*; each
element is projected forward (rotation by Euler angles from SciPy, pinhole,
Brown-Conrady distortion written out below) and its area is splatted into the
four nearest pixels with bilinear weights. No inverse distortion, no
homography. Then illumination (radial fall-off times a linear gradient),
Gaussian blur, Poisson + read noise and 8-bit quantization.

World frame: the reference plane is z = 0, z up toward the camera; the sheet
of the reference view has its dots at ``spacing * (i, j)``; the camera is put
so that dot (0, 0) is the one nearest the image centre and the world x axis
runs along increasing image columns (within a few degrees).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.spatial.transform import Rotation


@dataclass(frozen=True)
class RefCamera:
    width: int = 1280
    height: int = 1024
    pixel_mm: float = 0.0074
    focal_mm: float = 25.0
    height_mm: float = 340.0
    tilt_deg: float = 2.5          # optical axis vs plane normal
    tilt_toward_deg: float = 120.0  # direction of the tilt in the plane
    roll_deg: float = -4.0         # image x axis vs world x
    principal_offset_px: tuple = (-5.0, 7.0)
    k1: float = -0.09
    k2: float = 0.05
    p1: float = -1.2e-4
    p2: float = 2.0e-4
    falloff: float = 0.3
    blur_px: float = 0.9
    full_well: float = 6000.0
    read_noise: float = 10.0
    paper: float = 0.8
    ink: float = 0.1
    look_at_mm: tuple = (-2.6, 3.4)  # where the optical axis meets the plane

    @property
    def f_px(self) -> float:
        return self.focal_mm / self.pixel_mm

    @property
    def principal(self) -> np.ndarray:
        return np.array([(self.width - 1) / 2 + self.principal_offset_px[0],
                         (self.height - 1) / 2 + self.principal_offset_px[1]])

    def camera_to_world(self) -> tuple[np.ndarray, np.ndarray]:
        """Rotation (camera axes as world vectors, columns) and the camera centre in the world."""
        # camera looking straight down: camera x = world x, camera y = -world y, camera z = -world z
        down = np.diag([1.0, -1.0, -1.0])
        roll = Rotation.from_euler("z", self.roll_deg, degrees=True).as_matrix()
        axis = Rotation.from_euler("z", self.tilt_toward_deg, degrees=True).apply([1.0, 0.0, 0.0])
        tilt = Rotation.from_rotvec(np.radians(self.tilt_deg) * axis).as_matrix()
        cam_axes = tilt @ roll @ down  # columns: camera x, y, z in world coordinates
        optical = cam_axes[:, 2]
        s = self.height_mm / -optical[2]
        centre = np.array([self.look_at_mm[0], self.look_at_mm[1], 0.0]) - s * optical
        return cam_axes, centre

    def project(self, world: np.ndarray) -> np.ndarray:
        """World points (N, 3) -> pixels (N, 2) [col, row]."""
        axes, centre = self.camera_to_world()
        cam = (world - centre) @ axes  # coordinates along the camera axes
        x = cam[:, 0] / cam[:, 2]
        y = cam[:, 1] / cam[:, 2]
        rr = x * x + y * y
        radial = 1 + self.k1 * rr + self.k2 * rr * rr
        xd = x * radial + 2 * self.p1 * x * y + self.p2 * (rr + 2 * x * x)
        yd = y * radial + self.p1 * (rr + 2 * y * y) + 2 * self.p2 * x * y
        return np.stack([self.f_px * xd + self.principal[0], self.f_px * yd + self.principal[1]], axis=1)

    def corner_distortion_px(self) -> float:
        """How far the far image corner moves by the lens distortion (px)."""
        c = self.principal
        corner = np.array([0.0 if c[0] > self.width / 2 else self.width - 1.0,
                           0.0 if c[1] > self.height / 2 else self.height - 1.0])
        x, y = (corner - c) / self.f_px  # distorted normalized, undistort by fixed-point iteration
        xu, yu = x, y
        for _ in range(100):
            rr = xu * xu + yu * yu
            radial = 1 + self.k1 * rr + self.k2 * rr * rr
            xu = (x - 2 * self.p1 * xu * yu - self.p2 * (rr + 2 * xu * xu)) / radial
            yu = (y - self.p1 * (rr + 2 * yu * yu) - 2 * self.p2 * xu * yu) / radial
        return float(self.f_px * np.hypot(x - xu, y - yu))


def _disk_elements(radius: float, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Centres (M, 2) and areas (M,) of square elements of side ``step`` covering a disk about 0.

    Elements crossing the rim are split 4 x 4 and weighted by the share of their sub-elements inside.
    """
    n = int(np.ceil(radius / step)) + 1
    g = (np.arange(-n, n) + 0.5) * step
    xx, yy = np.meshgrid(g, g)
    pts = np.stack([xx.ravel(), yy.ravel()], axis=1)
    dist = np.hypot(pts[:, 0], pts[:, 1])
    share = (dist <= radius).astype(float)
    rim = np.abs(dist - radius) < 0.75 * step  # only elements near the rim can be partly inside
    sub = ((np.arange(4) + 0.5) / 4 - 0.5) * step
    sx, sy = np.meshgrid(sub, sub)
    share[rim] = (np.hypot(pts[rim, None, 0] + sx.ravel(), pts[rim, None, 1] + sy.ravel()) <= radius).mean(axis=1)
    keep = share > 0
    return pts[keep], share[keep] * step * step


def _splat(shape: tuple[int, int], px: np.ndarray, area: np.ndarray) -> np.ndarray:
    """Accumulate ``area`` at sub-pixel positions (N, 2) into an image by bilinear weights."""
    h, w = shape
    c0 = np.floor(px[:, 0]).astype(int)
    r0 = np.floor(px[:, 1]).astype(int)
    fc = px[:, 0] - c0
    fr = px[:, 1] - r0
    out = np.zeros(h * w)
    for dc, dr, wt in ((0, 0, (1 - fc) * (1 - fr)), (1, 0, fc * (1 - fr)), (0, 1, (1 - fc) * fr), (1, 1, fc * fr)):
        c, r = c0 + dc, r0 + dr
        ok = (c >= 0) & (c < w) & (r >= 0) & (r < h)
        out += np.bincount(r[ok] * w + c[ok], weights=(area * wt)[ok], minlength=h * w)
    return out.reshape(h, w)


def render(cam: RefCamera, disks: list[tuple[np.ndarray, np.ndarray, np.ndarray, float]], seed: int) -> np.ndarray:
    """8-bit image of disks. Each disk: (centre_world (3,), plane x axis (3,), plane y axis (3,), radius mm)."""
    shape = (cam.height, cam.width)
    pix_mm = cam.height_mm / cam.f_px  # rough plane size of a pixel, for the element size
    all_px, all_area = [np.zeros((0, 2))], [np.zeros(0)]
    for centre, ex, ey, radius in disks:
        local, area = _disk_elements(radius, pix_mm / 4)
        world = centre + local[:, :1] * ex + local[:, 1:] * ey
        px = cam.project(world)
        # area of an element in pixels: plane area times the local magnification (from the projected frame)
        d = 1e-3
        jac_x = (cam.project(world + d * ex) - px) / d
        jac_y = (cam.project(world + d * ey) - px) / d
        mag = np.abs(jac_x[:, 0] * jac_y[:, 1] - jac_x[:, 1] * jac_y[:, 0])
        all_px.append(px)
        all_area.append(area * mag)
    cover = np.clip(_splat(shape, np.concatenate(all_px), np.concatenate(all_area)), 0.0, 1.0)
    reflect = cam.paper + (cam.ink - cam.paper) * cover
    yy, xx = np.mgrid[0:cam.height, 0:cam.width]
    u = (xx - (cam.width - 1) / 2) / (cam.width / 2)
    v = (yy - (cam.height - 1) / 2) / (cam.height / 2)
    light = (1 - 0.16 * (u * u + v * v) / 2) * (1 + 0.09 * (0.6 * u - 0.8 * v))
    light = 1 - (1 - light / light.max()) * cam.falloff / (1 - light.min() / light.max())  # scale to the fall-off
    signal = ndimage.gaussian_filter(reflect * light, cam.blur_px)
    rng = np.random.default_rng(seed)
    electrons = rng.poisson(signal * cam.full_well).astype(float) + rng.normal(0, cam.read_noise, shape)
    return np.clip(np.round(electrons / cam.full_well * 255), 0, 255).astype(np.uint8)


def sheet_disks(cam: RefCamera, rotation: np.ndarray, offset: np.ndarray, spacing: float = 20.0,
                radius: float = 2.0) -> list:
    """Dots of a sheet whose point (a, b) lies at ``offset + a R[:, 0] + b R[:, 1]`` (world), as far as visible."""
    disks = []
    for i in range(-8, 9):
        for j in range(-8, 9):
            c = offset + spacing * (i * rotation[:, 0] + j * rotation[:, 1])
            p = cam.project(c[None])[0]
            if -30 < p[0] < cam.width + 30 and -30 < p[1] < cam.height + 30:
                disks.append((c, rotation[:, 0], rotation[:, 1], radius))
    return disks


def view_pose(k: int) -> tuple[np.ndarray, np.ndarray]:
    """Sheet pose of calibration view k (0: on the reference plane; else tilted 12-28 deg, moved)."""
    if k == 0:
        return np.eye(3), np.zeros(3)
    rng = np.random.default_rng(1000 + k)
    tilt = rng.uniform(12, 28)
    toward = 360.0 * k / 5 + rng.uniform(-15, 15)
    axis = Rotation.from_euler("z", toward, degrees=True).apply([1.0, 0.0, 0.0])
    rot = (Rotation.from_rotvec(np.radians(tilt) * axis) * Rotation.from_euler("z", rng.uniform(-12, 12),
                                                                                degrees=True)).as_matrix()
    return rot, np.array([rng.uniform(-6, 6), rng.uniform(-6, 6), rng.uniform(-12, 12)])


def sheet_image(cam: RefCamera, k: int, seed: int) -> np.ndarray:
    rot, off = view_pose(k)
    return render(cam, sheet_disks(cam, rot, off), seed)


def platform_image(cam: RefCamera, x: float, y: float, phi: float, height: float, seed: int,
                   spacing: float = 20.0, radius: float = 1.5, clutter: bool = False) -> np.ndarray:
    """Markers at (x, y) + R(phi) (+-s/2, +-s/2), ``height`` mm above the plane; ``clutter`` adds stray blobs."""
    c, s = np.cos(phi), np.sin(phi)
    h = spacing / 2
    disks = []
    for a, b in ((h, h), (-h, h), (-h, -h), (h, -h)):
        centre = np.array([x + c * a - s * b, y + s * a + c * b, height])
        disks.append((centre, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), radius))
    if clutter:  # a dust speck, a big round spot and a small one, on the plane
        for cx, cy, r in ((-50.0, 35.0, 0.35), (45.0, -38.0, 5.0), (-45.0, -30.0, 0.8)):
            disks.append((np.array([cx, cy, 0.0]), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), r))
    return render(cam, disks, seed)
