"""Honest centre and pose sigmas (issue 23, the photos path): the 1-sigma noise that find_blobs reports for a
dot's centre, and that measure_pose carries to the platform pose, against the errors of rendered photos whose
true geometry is known (pmaccuracy.vision.render draws the disks from the pose; the truth is that pose, not
anything the detector computes). The centre's sigma counts the support's pixel noise and the error of the
ring's background plane (module docstring of pmaccuracy.vision.detection); without the plane the sigmas were
about 15 % optimistic (normalized errors with spread ~1.17, measured over 300 noise draws of one photo)."""

from __future__ import annotations

import numpy as np
import pytest

from pmaccuracy.vision._util import mm_to_pixels
from pmaccuracy.vision.detection import find_blobs
from pmaccuracy.vision.pose import measure_pose, platform_markers
from pmaccuracy.vision.render import render_platform

MM_PER_PIXEL, SHAPE = 0.25, (200, 200)     # the calibration photos' flat camera; markers of 1.5 mm = 6 px


def _photos(n: int, seed: int, same_pose: bool = False):
    """``n`` rendered photos at random poses (or one pose, fresh noise): (true pose, true centres px, image)."""
    rng = np.random.default_rng(seed)
    pose = (rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-0.3, 0.3))
    for k in range(n):
        if not same_pose:
            pose = (rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-0.3, 0.3))
        image = render_platform(*pose, shape=SHAPE, mm_per_pixel=MM_PER_PIXEL, marker_radius_mm=1.5,
                                noise_sigma=0.01, seed=seed * 1000 + k)
        yield pose, mm_to_pixels(platform_markers(*pose), MM_PER_PIXEL, SHAPE), image


def _normalized(photos):
    """Per photo: the centres' and the pose's errors divided by their reported sigmas."""
    zc, zp = [], []
    for (x, y, phi), true_px, image in photos:
        blobs = find_blobs(image)
        match = [int(np.argmin(np.linalg.norm(true_px - c, axis=1))) for c in blobs.centres]
        zc.append((blobs.centres - true_px[match]) / blobs.sigma_px[:, None])
        p = measure_pose(image, mm_per_pixel=MM_PER_PIXEL)
        dphi = np.remainder(p.phi - phi + np.pi / 4, np.pi / 2) - np.pi / 4
        zp.append(np.array([p.x - x, p.y - y, dphi]) / np.array(p.sigma))
    return np.vstack(zc), np.array(zp)


def test_centre_and_pose_sigmas_have_unit_spread_over_rendered_photos():
    zc, zp = _normalized(_photos(30, seed=1))
    assert zc.shape == (120, 2)
    assert 0.8 < zc.std() < 1.2, zc.std()               # 240 centre coordinates (measured 1.10; 1.25 before)
    assert 0.8 < np.sqrt(np.mean(zp ** 2)) < 1.2, np.sqrt(np.mean(zp ** 2, axis=0))   # 90 pose coordinates (1.14)
    assert np.all(np.abs(zp) < 4.5)


def test_centre_sigma_is_the_spread_over_noise_draws_of_one_photo():
    """One pose, 60 noise draws: the empirical spread of each centre coordinate against the reported sigma."""
    errs, sig = [], []
    for _, true_px, image in _photos(60, seed=4, same_pose=True):
        blobs = find_blobs(image)
        match = [int(np.argmin(np.linalg.norm(blobs.centres - t, axis=1))) for t in true_px]
        errs.append((blobs.centres[match] - true_px).ravel())
        sig.append(blobs.sigma_px[match])
    ratio = np.sqrt(np.mean(np.var(np.array(errs), axis=0))) / np.mean(sig)
    assert 0.9 < ratio < 1.1, ratio                     # measured 0.98 (1.12 without the plane's error)


@pytest.mark.slow
def test_pose_sigmas_per_coordinate_over_many_photos():
    """200 photos at random poses: x, y and phi each with normalized errors of unit spread within 20 %."""
    _, zp = _normalized(_photos(200, seed=7))
    spread = np.sqrt(np.mean(zp ** 2, axis=0))          # measured 0.93, 0.97, 1.05
    assert np.all((spread > 0.8) & (spread < 1.2)), spread
