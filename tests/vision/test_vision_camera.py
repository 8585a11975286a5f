"""Camera model, perspective centroid offset, test camera and detector, each against an independent computation.

OpenCV's projectPoints is the independent reference of the distortion model;
brute-force ray-plane intersection checks the plane homographies; a fine area
sampling checks the centroid offset of tilted disks; the simulated camera's
exact projections check the detector under uneven light, noise, blur, stray and
cut blobs.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from pmaccuracy import vision
from pmaccuracy.vision import camera_sim
from pmaccuracy.vision.camera import CameraModel, disk_image_bias, plane_matrix, plane_to_image, rotation_matrix, rotation_vector

K = np.array([[3378.4, 0.0, 645.5], [0.0, 3377.9, 507.5], [0.0, 0.0, 1.0]])
DIST = np.array([-0.09, 0.05, -1.2e-4, 2.0e-4, 0.01])


def test_distortion_matches_opencv() -> None:
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-0.2, 0.2, (200, 2)), np.ones(200)])
    cam = CameraModel(K, DIST, (1280, 1024))
    ours = cam.project(pts)
    theirs, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), K, DIST)
    np.testing.assert_allclose(ours, theirs.reshape(-1, 2), atol=1e-9)
    # undistortion inverts it to rounding
    np.testing.assert_allclose(cam.undistort(ours), pts[:, :2], atol=1e-12)


def test_rotation_vector_round_trip_and_rodrigues() -> None:
    rvec = np.array([0.3, -0.2, 0.9])
    r = rotation_matrix(rvec)
    np.testing.assert_allclose(r, cv2.Rodrigues(rvec)[0], atol=1e-12)
    np.testing.assert_allclose(rotation_vector(r), rvec, atol=1e-12)


def test_plane_matrix_is_ray_plane_intersection() -> None:
    rng = np.random.default_rng(1)
    rot = rotation_matrix([0.04, -0.03, 0.2]) @ np.diag([1.0, -1.0, -1.0])
    t = np.array([3.0, -2.0, 340.0])
    for h in (0.0, 12.5):
        pts = rng.uniform(-50, 50, (20, 2))
        n = vision.apply_homography(plane_matrix(rot, t, h), pts)
        # brute force: the ray s [n, 1] meets the plane {R [x, y, h] + t}: normal r3, offset r3 . (t + h r3)
        normal = rot[:, 2]
        rays = np.column_stack([n, np.ones(len(n))])
        s = (normal @ (t + h * normal)) / (rays @ normal)
        world = rot.T @ ((s[:, None] * rays) - t).T
        np.testing.assert_allclose(world[:2].T, pts, atol=1e-9)
        np.testing.assert_allclose(world[2], h, atol=1e-9)


def test_disk_bias_against_area_sampling() -> None:
    cam = CameraModel(K, DIST, (1280, 1024))
    rot = rotation_matrix([math.radians(28.0), 0.1, 0.0]) @ np.diag([1.0, -1.0, -1.0])
    m = plane_matrix(rot, np.array([20.0, 10.0, 330.0]))
    centre, radius = np.array([40.0, -30.0]), 2.0
    # brute force: fine lattice of area elements over the disk, projected, weighted by their image area
    step = 0.008
    g = np.arange(-radius, radius, step) + step / 2
    xx, yy = np.meshgrid(g, g)
    inside = xx**2 + yy**2 <= radius**2
    pts = centre + np.column_stack([xx[inside], yy[inside]])
    px = plane_to_image(cam, m, pts)
    jx = (plane_to_image(cam, m, pts + [1e-4, 0]) - px) / 1e-4
    jy = (plane_to_image(cam, m, pts + [0, 1e-4]) - px) / 1e-4
    w = np.abs(jx[:, 0] * jy[:, 1] - jx[:, 1] * jy[:, 0])
    brute = (px * w[:, None]).sum(axis=0) / w.sum() - plane_to_image(cam, m, centre[None])[0]
    ours = disk_image_bias(cam, m, centre[None], radius)[0]
    assert np.linalg.norm(brute) > 0.02  # a 28 deg tilt: a real offset, not a rounding effect
    np.testing.assert_allclose(ours, brute, atol=2e-4)


def test_illumination_falloff() -> None:
    light = camera_sim.illumination((200, 300), 0.3)
    assert light.max() == pytest.approx(1.0) and light.min() == pytest.approx(0.7, abs=1e-3)


@pytest.fixture(scope="module")
def sim_views():
    sim = camera_sim.aalborg_camera(falloff=0.3, corner_distortion_px=5.0, tilt_deg=3.0)
    return sim, [camera_sim.render_view(sim, k, seed=k) for k in (0, 2)]


def test_detector_on_the_physical_camera(sim_views) -> None:
    """Vignetting + gradient (30 %), noise, blur, 8 bit, distortion, 10-30 deg tilt: centres within 0.05 px."""
    sim, views = sim_views
    for view in views:
        blobs = vision.find_blobs(view.image)
        m = plane_matrix(view.rotation, view.translation)
        exact = view.centres_px + disk_image_bias(sim.camera, m, view.centres_mm, 2.0)  # area centroids
        d = np.linalg.norm(blobs.centres[:, None] - exact[None], axis=2)
        err = d.min(axis=1)
        assert np.max(err) < 0.05
        # every dot wholly inside the frame is found; the cut ones are not reported
        w, h = sim.camera.image_size
        whole = np.all((view.centres_px > 30) & (view.centres_px < [w - 31, h - 31]), axis=1)
        assert np.all(d[:, whole].min(axis=0) < 0.05)
        assert blobs.cut >= 1 and len(blobs) <= len(view.centres_px) - blobs.cut


def test_global_threshold_failure_of_the_issue_is_gone() -> None:
    """20-30 % fall-off with 2 x 2 markers in a corner region and stray blobs: exactly the four markers."""
    sim = camera_sim.aalborg_camera(falloff=0.3)
    image = camera_sim.render_platform(sim, -30.0, 25.0, 0.3, 10.0, distractors=4, seed=3)
    blobs = vision.find_blobs(image)
    cal = vision.Calibration(sim.camera, sim.plane(0.0), model="multi-view", rotation=sim.rotation,
                             translation=sim.translation)
    idx = vision.select_markers(blobs, lambda p: cal.image_to_plane(p, 10.0))
    truth = sim.project(vision.platform_markers(-30.0, 25.0, 0.3), 10.0)
    found = blobs.centres[idx]
    assert np.max(np.min(np.linalg.norm(found[:, None] - truth[None], axis=2), axis=0)) < 0.05


def test_centre_noise_estimate_matches_the_scatter() -> None:
    """The stated sigma_px of a centre against the scatter of the same dot over 24 noise draws."""
    sim = camera_sim.aalborg_camera(size=(160, 128), principal_offset_px=(0.0, 0.0), axis_hit_mm=(2.0, 3.0),
                                    tilt_deg=1.0, falloff=0.2, corner_distortion_px=0.0)
    disks = [camera_sim.Disk((0.0, 0.0), 1.5, sim.plane(0.0), sim.reflectance_dots)]
    runs = [vision.find_blobs(camera_sim.render(sim, disks, seed=s), max_diameter_px=60) for s in range(24)]
    centres = np.array([r.centres[0] for r in runs])
    stated = np.mean([r.sigma_px[0] for r in runs])
    scatter = np.std(centres, axis=0, ddof=1).mean()
    assert 0.6 < scatter / stated < 1.5


def test_calibration_from_the_simulator_truth_measures_exactly() -> None:
    """A Calibration built from the simulator's own camera measures its images (checks frames and heights)."""
    sim = camera_sim.aalborg_camera()
    cal = vision.Calibration(sim.camera, sim.plane(0.0), model="multi-view", rotation=sim.rotation,
                             translation=sim.translation)
    assert cal.camera_height_mm == pytest.approx(camera_sim.AALBORG_HEIGHT_MM, abs=1e-9)
    image = camera_sim.render_platform(sim, 7.0, -11.0, math.radians(-23.0), 17.0, seed=2)
    pose = vision.measure_pose(image, calibration=cal, height_mm=17.0)
    assert abs(pose.x - 7.0) < 0.005 and abs(pose.y + 11.0) < 0.005 and abs(pose.phi_deg + 23.0) < 0.01
