"""Vision measurement on the flat (ideal) renderer: detection, single-view calibration, pose, files, CLI basics.

Synthetic images at 0.1 mm/px (markers of 1.5 mm radius, blur and noise) must
give the pose within the paper's measurement accuracy (0.01 mm, 0.01 deg).
The physically modelled camera is tested in test_vision_camera.py and
test_vision_accuracy.py.
"""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys

import numpy as np
import pytest

from pmaccuracy import vision
from pmaccuracy.cli import main
from pmaccuracy.errors import ConfigError, VisionError

SHAPE = (600, 600)
SCALE = 0.1  # mm per pixel


def _match(found: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Distance from each true point ``(N, 2)`` to the nearest found point."""
    return np.min(np.linalg.norm(truth[:, None, :] - found[None, :, :], axis=2), axis=1)


def _angle_diff_deg(a: float, b: float) -> float:
    """|a - b| in degrees modulo a quarter turn (a square's symmetry)."""
    return abs(math.degrees(math.remainder(a - b, math.pi / 2)))


# ------------------------------------------------------------------------------------------------ detection


def test_detect_markers_subpixel_dark_and_light() -> None:
    rng = np.random.default_rng(7)
    centres = np.array([[100.0, 120.0], [300.0, 90.0], [480.0, 300.0], [150.0, 450.0], [350.0, 400.0]])
    centres += rng.uniform(-0.5, 0.5, centres.shape)
    image = vision.render_dots(SHAPE, centres, 12.0, blur_sigma=1.0, noise_sigma=0.01, seed=1)
    found = vision.detect_markers(image)
    assert found.shape == (5, 2)
    assert np.max(_match(found, centres)) < 0.03  # px
    # the same dots, light on dark
    found_light = vision.detect_markers(1.0 - image, polarity="light")
    assert np.max(_match(found_light, centres)) < 0.03
    # looking for the wrong polarity finds no round dots of the expected kind
    assert len(vision.detect_markers(image, polarity="light")) == 0


def test_detect_markers_convention_col_row() -> None:
    # one dot right of centre and above it: col > cx, row < cy
    image = vision.render_dots((200, 300), np.array([[200.25, 60.5]]), 10.0)
    found = vision.detect_markers(image)
    np.testing.assert_allclose(found, [[200.25, 60.5]], atol=0.01)


def test_detect_filters_shapes_and_specks() -> None:
    image = vision.render_dots(SHAPE, np.array([[300.0, 300.0]]), 15.0)
    image[100:110, 50:250] = 0.15  # a long bar: not circular
    image[500:502, 500:502] = 0.15  # a speck below min_area
    image[200:240, 560:600] = 0.15  # a blob cut by the border
    found = vision.detect_markers(image)
    np.testing.assert_allclose(found, [[300.0, 300.0]], atol=0.01)


def test_detect_constant_and_bad_input() -> None:
    assert vision.detect_markers(np.full((50, 50), 0.5)).shape == (0, 2)
    with pytest.raises(VisionError):
        vision.detect_markers(np.full((50, 50), np.nan))
    with pytest.raises(VisionError, match="polarity"):
        vision.detect_markers(np.zeros((50, 50)), polarity="grey")
    with pytest.raises(VisionError):
        vision.detect_markers(np.zeros((4, 5, 6, 7)))


def test_as_gray_rgb_and_uint() -> None:
    gray = np.linspace(0, 1, 30 * 40).reshape(30, 40)
    rgb = np.repeat((gray * 255).astype(np.uint8)[..., None], 3, axis=2)
    np.testing.assert_allclose(vision.as_gray(rgb), (gray * 255).astype(np.uint8) / 255, atol=1e-6)
    rgba = np.concatenate([rgb, np.full((30, 40, 1), 255, np.uint8)], axis=2)
    np.testing.assert_allclose(vision.as_gray(rgba), vision.as_gray(rgb), atol=1e-6)
    u16 = (gray * 65535).astype(np.uint16)
    np.testing.assert_allclose(vision.as_gray(u16), gray, atol=1e-4)


# ------------------------------------------------------------------------------------------------ pose


POSES = [(float(x), float(y), float(p)) for x, y, p in
         zip(*np.random.default_rng(2012).uniform([[-10] * 8, [-10] * 8, [-40] * 8], [[10] * 8, [10] * 8, [40] * 8]))]


@pytest.mark.parametrize("k", range(len(POSES)))
def test_pose_accuracy_synthetic(k: int) -> None:
    x, y, phi_deg = POSES[k]
    image = vision.render_platform(x, y, math.radians(phi_deg), shape=SHAPE, mm_per_pixel=SCALE,
                                   marker_radius_mm=1.5, blur_sigma=1.0, noise_sigma=0.01, seed=100 + k)
    pose = vision.measure_pose(image, mm_per_pixel=SCALE)
    assert abs(pose.x - x) < 0.01 and abs(pose.y - y) < 0.01  # mm (paper: 0.01 mm)
    assert _angle_diff_deg(pose.phi, math.radians(phi_deg)) < 0.01  # deg (paper: 0.01 deg)
    assert pose.residual_mm < 0.01
    assert abs(pose.side_mm - 20.0) < 0.01
    assert -45.0 < pose.phi_deg <= 45.0


def test_pose_through_homography() -> None:
    h = vision.sheet_homography(SHAPE, mm_per_pixel=SCALE, rotation=math.radians(8.0), offset_mm=(1.5, -2.0),
                                perspective=(5e-5, -3e-5))
    cal = vision.Calibration.from_homography(h, image_size=SHAPE[::-1])
    image = vision.render_platform(4.0, -3.0, math.radians(17.0), shape=SHAPE, pixel_to_mm=h, seed=5)
    pose = vision.measure_pose(image, calibration=cal)
    assert abs(pose.x - 4.0) < 0.01 and abs(pose.y + 3.0) < 0.01
    assert _angle_diff_deg(pose.phi, math.radians(17.0)) < 0.01


def test_pose_order_free_and_folded() -> None:
    truth = vision.platform_markers(2.0, -1.0, math.radians(50.0))  # 50 deg looks like -40 deg
    rng = np.random.default_rng(0)
    for _ in range(5):
        pose = vision.pose_from_markers_mm(truth[rng.permutation(4)])
        assert pose.x == pytest.approx(2.0, abs=1e-9) and pose.y == pytest.approx(-1.0, abs=1e-9)
        assert pose.phi_deg == pytest.approx(-40.0, abs=1e-9)
        assert pose.residual_mm == pytest.approx(0.0, abs=1e-9)
    # the fold is (-45, 45]: exactly 45 deg stays, -45 deg becomes +45
    assert vision.pose_from_markers_mm(vision.platform_markers(0, 0, math.pi / 4)).phi_deg == pytest.approx(45.0)
    assert vision.pose_from_markers_mm(vision.platform_markers(0, 0, -math.pi / 4)).phi_deg == pytest.approx(45.0)
    np.testing.assert_allclose(vision.wrap_quarter_turn(np.radians([0.0, 44.0, 46.0, -46.0, 90.0, 135.0])),
                               np.radians([0.0, 44.0, -44.0, 44.0, 0.0, 45.0]), atol=1e-12)


def test_pose_least_squares_against_independent_fit() -> None:
    # noisy markers: compare with a Procrustes fit written out here (centroid + atan2 of the cross terms)
    rng = np.random.default_rng(3)
    model = vision.square_model(20.0)
    phi = math.radians(12.0)
    rot = np.array([[math.cos(phi), -math.sin(phi)], [math.sin(phi), math.cos(phi)]])
    q = model @ rot.T + [5.0, -7.0] + rng.normal(0, 0.05, (4, 2))
    pose = vision.pose_from_markers_mm(q)
    qc, mc = q - q.mean(axis=0), model - model.mean(axis=0)
    angle = math.atan2(np.sum(mc[:, 0] * qc[:, 1] - mc[:, 1] * qc[:, 0]), np.sum(mc * qc))
    assert pose.phi == pytest.approx(angle, abs=1e-12)
    np.testing.assert_allclose([pose.x, pose.y], q.mean(axis=0), atol=1e-12)
    r = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    rms = math.sqrt(np.mean(np.sum((mc @ r.T - qc) ** 2, axis=1)))
    assert pose.residual_mm == pytest.approx(rms, rel=1e-9)


def test_wrong_number_of_markers_and_stray_blobs() -> None:
    square = vision.platform_markers(0.0, 0.0, 0.1)
    three = vision.render_dots(SHAPE, vision.mm_to_pixels(square[:3], SCALE, SHAPE), 15.0, blur_sigma=1.0,
                               noise_sigma=0.01, seed=1)
    with pytest.raises(VisionError, match="found 3 markers"):
        vision.measure_pose(three, mm_per_pixel=SCALE)
    # a fifth round blob of the same size that is not on the square is ignored: one set of four forms it
    five = vision.render_dots(SHAPE, vision.mm_to_pixels(np.concatenate([square, [[18.0, 3.0]]]), SCALE, SHAPE),
                              15.0, blur_sigma=1.0, noise_sigma=0.01, seed=1)
    pose = vision.measure_pose(five, mm_per_pixel=SCALE)
    assert abs(pose.x) < 0.01 and abs(pose.y) < 0.01 and abs(pose.phi_deg - math.degrees(0.1)) < 0.01
    # two squares side by side: two candidate sets, which one is the platform is unknown
    two = np.concatenate([vision.platform_markers(-14.0, 0.0, 0.0), vision.platform_markers(14.0, 0.0, 0.0)])
    image = vision.render_dots(SHAPE, vision.mm_to_pixels(two, SCALE, SHAPE), 15.0, blur_sigma=1.0, seed=2)
    with pytest.raises(VisionError, match="found 8 round blobs and 2 sets of 4"):
        vision.measure_pose(image, mm_per_pixel=SCALE)


def test_pose_rejects_wrong_scale_and_non_square() -> None:
    with pytest.raises(VisionError, match="wrong scale"):
        vision.pose_from_markers_mm(vision.platform_markers(0, 0, 0.2, spacing_mm=20.0) * 2.54)
    kite = np.array([[10.0, 10.0], [-10.0, 10.0], [-10.0, -10.0], [14.0, -6.0]])
    with pytest.raises(VisionError):
        vision.pose_from_markers_mm(kite)
    with pytest.raises(VisionError, match="exactly one"):
        vision.pose_from_markers(np.zeros((4, 2)))
    with pytest.raises(VisionError, match="no markers"):
        vision.pose_from_markers_mm(np.zeros((0, 2)))


# ------------------------------------------------------------------------------------------------ calibration


def _check_calibration(cal: vision.Calibration, truth_pixel_to_mm: np.ndarray, tol_mm: float) -> None:
    grid = np.stack(np.meshgrid(np.linspace(60, 540, 7), np.linspace(60, 540, 7)), axis=-1).reshape(-1, 2)
    expected = vision.apply_homography(truth_pixel_to_mm / truth_pixel_to_mm[2, 2], grid)
    assert np.max(np.linalg.norm(cal.pixel_to_mm(grid) - expected, axis=1)) < tol_mm


def test_calibration_similarity() -> None:
    h = vision.sheet_homography(SHAPE, mm_per_pixel=0.25, rotation=math.radians(30.0), offset_mm=(-7.0, 5.0))
    sheet = vision.render_calibration_sheet(SHAPE, pixel_to_mm=h, seed=4)
    cal = vision.calibrate(sheet.image, spacing_mm=20.0)
    assert cal.n_points >= len(sheet.centres_mm) - 4  # dots touching the border may be dropped
    assert cal.residuals["plane_rms_mm"] < 0.01 and cal.model == "single-view"
    assert cal.mm_per_pixel == pytest.approx(0.25, rel=1e-3)
    _check_calibration(cal, h, 0.01)


def test_calibration_projective() -> None:
    h = vision.sheet_homography(SHAPE, mm_per_pixel=0.25, rotation=math.radians(-6.0), offset_mm=(2.0, 3.0),
                                perspective=(2e-4, -1e-4))
    sheet = vision.render_calibration_sheet(SHAPE, pixel_to_mm=h, seed=5)
    cal = vision.calibrate(sheet.image)
    assert cal.residuals["plane_rms_mm"] < 0.01
    _check_calibration(cal, h, 0.02)
    # the image has no lens distortion: the fitted radial terms move the image corner by less than 0.05 px
    corner = np.array([[0.0, 0.0], [599.0, 599.0]])
    n = cal.camera.undistort(corner)
    ideal = n * cal.camera.matrix[0, 0] + cal.camera.matrix[:2, 2]
    assert np.max(np.abs(ideal - corner)) < 0.05


def test_calibration_frame_convention() -> None:
    # sheet rotated 60 deg: its -y axis (at -30 deg) is the lattice direction closest to image +x
    h = vision.sheet_homography(SHAPE, mm_per_pixel=0.25, rotation=math.radians(60.0), offset_mm=(3.0, -4.0))
    sheet = vision.render_calibration_sheet(SHAPE, pixel_to_mm=h, seed=6)
    cal = vision.calibrate(sheet.image)
    quarter = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # (xs, ys) -> (-ys, xs)
    _check_calibration(cal, quarter @ h, 0.01)
    # a plain scale with no rotation reproduces the scale convention (origin at the centre dot, y up)
    sheet = vision.render_calibration_sheet(SHAPE, mm_per_pixel=0.1, seed=7)
    cal = vision.calibrate(sheet.image)
    assert cal.n_points == 9
    _check_calibration(cal, vision.scale_matrix(0.1, SHAPE), 0.01)


def test_calibration_ignores_spurious_blob_and_needs_a_grid() -> None:
    h = vision.sheet_homography(SHAPE, mm_per_pixel=0.25, rotation=0.2)
    sheet = vision.render_calibration_sheet(SHAPE, pixel_to_mm=h, seed=8, noise_sigma=0.0)
    extra = vision.render_dots(SHAPE, np.array([[337.0, 251.0]]), 7.0, blur_sigma=1.0)  # between grid nodes
    image = np.minimum(sheet.image, extra)
    centres = vision.detect_markers(image)
    cal = vision.calibrate_from_points(centres, SHAPE)
    assert cal.n_points == len(centres) - 1
    _check_calibration(cal, h, 0.01)
    with pytest.raises(VisionError, match="at least"):
        vision.calibrate_from_points(centres[:4], SHAPE)
    with pytest.raises(VisionError, match="single line"):
        vision.calibrate_from_points(np.stack([np.arange(8) * 50.0 + 100, np.full(8, 300.0)], axis=1), SHAPE)


def test_calibration_toml_round_trip(tmp_path) -> None:
    h = vision.sheet_homography(SHAPE, mm_per_pixel=0.25, rotation=0.3, perspective=(1e-4, 2e-4))
    sheet = vision.render_calibration_sheet(SHAPE, pixel_to_mm=h, seed=3)
    cal = vision.calibrate(sheet.image)
    path = tmp_path / "cal.toml"
    cal.to_toml(path)
    back = vision.Calibration.from_toml(path)
    for name in ("plane", "covariance"):
        np.testing.assert_array_equal(getattr(back, name), getattr(cal, name))
    np.testing.assert_array_equal(back.camera.matrix, cal.camera.matrix)
    np.testing.assert_array_equal(back.camera.distortion, cal.camera.distortion)
    assert back.residuals == cal.residuals and back.model == cal.model and back.n_points == cal.n_points
    with pytest.raises(Exception):
        back.spacing_mm = 10.0  # frozen


GOOD = vision.Calibration.from_homography(np.diag([0.1, -0.1, 1.0]), image_size=(600, 600)).to_toml()


@pytest.mark.parametrize("old, new, key", [
    ('model = "single-view"', 'model = "zoom"', "calibration.model"),
    ("spacing_mm = 20.0", "spacing_mm = -1", "calibration.spacing_mm"),
    ("image_size = [600, 600]", "image_size = [600]", "calibration.image_size"),
    ("distortion = [0.0, 0.0, 0.0, 0.0, 0.0]", "distortion = [0.0, 'a', 0.0, 0.0, 0.0]", "calibration.distortion[1]"),
    ("distortion = [0.0, 0.0, 0.0, 0.0, 0.0]", "distortion = [0.0, 0.0]", "calibration.distortion"),
    ("n_points = 0", "n_points = 9.5", "calibration.n_points"),
    ("spacing_mm = 20.0", "spacing = 20.0", "calibration.spacing"),
    ('model = "single-view"', 'model = "multi-view"', "calibration.plane.rotation"),
    ("[calibration.plane]\nhomography = [", "[calibration.plane]\nhomography = [[1, 2, 3],", "homography"),
])
def test_calibration_bad_files(tmp_path, old: str, new: str, key: str) -> None:
    assert old in GOOD
    path = tmp_path / "bad.toml"
    path.write_text(GOOD.replace(old, new, 1))
    with pytest.raises(ConfigError) as info:
        vision.Calibration.from_toml(path)
    assert str(path) in str(info.value) and key in str(info.value)


def test_calibration_singular_plane(tmp_path) -> None:
    path = tmp_path / "bad.toml"
    text, count = re.subn(r"homography = \[\n(.*\n){3}\]", "homography = [[1, 2, 0], [2, 4, 0], [0, 0, 1]]", GOOD)
    assert count == 1
    path.write_text(text)
    with pytest.raises(ConfigError, match="calibration.plane.homography: is singular"):
        vision.Calibration.from_toml(path)


def test_calibration_missing_and_malformed_file(tmp_path) -> None:
    with pytest.raises(ConfigError, match="no such"):
        vision.Calibration.from_toml(tmp_path / "nope.toml")
    path = tmp_path / "broken.toml"
    path.write_text("[calibration\n")
    with pytest.raises(ConfigError, match="malformed TOML"):
        vision.Calibration.from_toml(path)


def test_end_to_end_calibrate_then_measure() -> None:
    h = vision.sheet_homography(SHAPE, mm_per_pixel=0.1, rotation=math.radians(4.0), offset_mm=(0.5, -0.3),
                                perspective=(3e-5, 2e-5))
    cal = vision.calibrate(vision.render_calibration_sheet(SHAPE, pixel_to_mm=h, seed=9, supersample=4).image)
    image = vision.render_platform(-3.0, 6.0, math.radians(-22.0), shape=SHAPE, pixel_to_mm=h, seed=10)
    pose = vision.measure_pose(image, calibration=cal)
    assert abs(pose.x + 3.0) < 0.01 and abs(pose.y - 6.0) < 0.01
    assert _angle_diff_deg(pose.phi, math.radians(-22.0)) < 0.01


# ------------------------------------------------------------------------------------------------ files and CLI


@pytest.fixture(scope="module")
def images(tmp_path_factory):
    folder = tmp_path_factory.mktemp("vision")
    pose_png = folder / "pose.png"
    vision.save_image(pose_png, vision.render_platform(3.2, -4.1, math.radians(12.5), shape=SHAPE,
                                                       mm_per_pixel=SCALE, seed=1))
    sheet_png = folder / "sheet.png"
    vision.save_image(sheet_png, vision.render_calibration_sheet(SHAPE, mm_per_pixel=SCALE, seed=2).image)
    three_png = folder / "three.png"
    centres = vision.mm_to_pixels(vision.platform_markers(0, 0, 0)[:3], SCALE, SHAPE)
    vision.save_image(three_png, vision.render_dots(SHAPE, centres, 15.0, blur_sigma=1.0))
    blank_png = folder / "blank.png"
    vision.save_image(blank_png, np.full((100, 100), 0.8))
    text_png = folder / "text.png"
    text_png.write_text("not an image\n")
    return {"folder": folder, "pose": pose_png, "sheet": sheet_png, "three": three_png, "blank": blank_png,
            "text": text_png}


def test_load_image_rgb_png(tmp_path) -> None:
    from skimage import io

    rgb = np.zeros((40, 50, 3), np.uint8)
    rgb[..., 1] = 200
    io.imsave(tmp_path / "rgb.png", rgb, check_contrast=False)
    gray = vision.load_image(tmp_path / "rgb.png")
    assert gray.shape == (40, 50)
    assert np.allclose(gray, 0.7152 * 200 / 255, atol=1e-3)
    with pytest.raises(VisionError, match="no such image"):
        vision.load_image(tmp_path / "missing.png")
    with pytest.raises(VisionError, match="unsupported image type"):
        vision.save_image(tmp_path / "x.foo", gray)


def test_cli_calibrate_and_pose(images, capsys) -> None:
    cal_path = images["folder"] / "cal.toml"
    assert main(["vision", "calibrate", str(images["sheet"]), "--spacing-mm", "20", "--out", str(cal_path),
                 "--format", "json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["n_points"] == 9 and summary["plane_rms_mm"] < 0.01 and summary["model"] == "single-view"
    cal = vision.Calibration.from_toml(cal_path)
    assert cal.mm_per_pixel == pytest.approx(SCALE, rel=1e-3)

    for option in (["--calibration", str(cal_path)], ["--mm-per-pixel", str(SCALE)]):
        assert main(["vision", "pose", str(images["pose"]), *option, "--format", "json"]) == 0
        out = json.loads(capsys.readouterr().out)
        assert set(out) == {"x", "y", "phi_deg", "residual_mm", "uncertainty"}
        assert set(out["uncertainty"]) == {"x_mm", "y_mm", "phi_deg"}
        assert 0 < out["uncertainty"]["x_mm"] < 0.005
        assert out["x"] == pytest.approx(3.2, abs=0.01) and out["y"] == pytest.approx(-4.1, abs=0.01)
        assert out["phi_deg"] == pytest.approx(12.5, abs=0.01)


def test_cli_render_detect(images, capsys) -> None:
    out_png = images["folder"] / "rendered.png"
    assert main(["vision", "render-pose", "--camera", "flat", "--x", "1", "--y", "2", "--phi-deg", "-30",
                 "--mm-per-pixel", "0.1",
                 "--out", str(out_png), "--seed", "3", "--noise", "0.005"]) == 0
    assert main(["vision", "pose", str(out_png), "--mm-per-pixel", "0.1", "--format", "csv"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0] == "x,y,phi_deg,residual_mm,uncertainty.x_mm,uncertainty.y_mm,uncertainty.phi_deg"
    x, y, phi = (float(v) for v in lines[1].split(",")[:3])
    assert (x, y, phi) == pytest.approx((1.0, 2.0, -30.0), abs=0.01)
    assert main(["vision", "detect", str(out_png), "--format", "json"]) == 0
    assert len(json.loads(capsys.readouterr().out)) == 4
    sheet_png = images["folder"] / "rendered_sheet.png"
    assert main(["vision", "render-sheet", "--camera", "flat", "--out", str(sheet_png), "--rotation-deg", "10",
                 "--seed", "1"]) == 0
    assert vision.load_image(sheet_png).shape == SHAPE


@pytest.mark.parametrize("name, extra, message", [
    ("missing", ["--mm-per-pixel", "0.1"], "no such image file"),
    ("text", ["--mm-per-pixel", "0.1"], "not a readable image"),
    ("blank", ["--mm-per-pixel", "0.1"], "found no markers"),
    ("three", ["--mm-per-pixel", "0.1"], "found 3 markers"),
    ("sheet", ["--mm-per-pixel", "0.1"], "found 9 round blobs and 4 sets of 4 form the 20 mm marker square"),
    ("pose", ["--mm-per-pixel", "0.25"], "wrong scale"),
    ("pose", ["--calibration", "missing.toml"], "no such calibration file"),
])
def test_cli_pose_errors(images, capsys, name: str, extra: list[str], message: str) -> None:
    image = str(images[name]) if name in images else str(images["folder"] / "missing.png")
    assert main(["vision", "pose", image, *extra]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and message in err and "Traceback" not in err


@pytest.mark.parametrize("extra", [[], ["--mm-per-pixel", "0.1", "--calibration", "cal.toml"],
                                   ["--mm-per-pixel", "-1"]])
def test_cli_pose_scale_options(images, capsys, extra: list[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["vision", "pose", str(images["pose"]), *extra])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_cli_calibrate_errors(images, capsys) -> None:
    assert main(["vision", "calibrate", str(images["blank"]), "--out", str(images["folder"] / "c.toml")]) == 2
    assert main(["vision", "calibrate", str(images["three"]), "--out", str(images["folder"] / "c.toml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all("error:" in line for line in err)


def test_cli_subprocess(images) -> None:
    proc = subprocess.run([sys.executable, "-m", "pmaccuracy.cli", "vision", "pose", str(images["pose"]),
                           "--mm-per-pixel", "0.1", "--format", "json"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["x"] == pytest.approx(3.2, abs=0.01)
    proc = subprocess.run([sys.executable, "-m", "pmaccuracy.cli", "vision", "pose", str(images["text"]),
                           "--mm-per-pixel", "0.1"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1
