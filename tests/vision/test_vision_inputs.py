"""Bad and borderline inputs of ``pmaccuracy vision``, one table per channel (issue 12).

Every error case: exit 2, exactly one line on stderr naming the file / key / row / option and the problem, no
traceback, no RuntimeWarning line, nothing written. Borderline cases that are valid (16-bit, colour, no
residuals table) give the same pose as the plain case.
"""

from __future__ import annotations

import copy
import io
import json
import math
import struct
import tomllib
import zlib
from contextlib import redirect_stderr, redirect_stdout

import numpy as np
import pytest
import tomli_w

from pmaccuracy import vision
from pmaccuracy.cli import main
from pmaccuracy.vision import camera_sim
from pmaccuracy.vision.camera import plane_matrix

SCALE = 0.25
SHAPE = (240, 240)
TRUTH = (2.0, -1.0, 7.0)  # x mm, y mm, phi deg of the flat photo


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        try:
            status = main(argv)
        except SystemExit as exc:
            status = exc.code
    return int(status or 0), out.getvalue(), err.getvalue()


def assert_error(argv: list[str], *needles: str) -> str:
    """Exit 2 with one line containing every needle; returns the line."""
    status, _, err = run_cli(argv)
    lines = err.strip().splitlines()
    assert status == 2, err
    assert len(lines) == 1, err
    assert "Traceback" not in err and "RuntimeWarning" not in err and "internal error" not in err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def png_header_only(width: int, height: int) -> bytes:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\x00" * 64)) + chunk(b"IEND", b""))


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    folder = tmp_path_factory.mktemp("inputs")
    photo = folder / "photo.png"
    image = vision.render_platform(TRUTH[0], TRUTH[1], math.radians(TRUTH[2]), shape=SHAPE, mm_per_pixel=SCALE,
                                   seed=4)
    vision.save_image(photo, image)
    cal = vision.calibrate(vision.render_calibration_sheet(SHAPE, mm_per_pixel=SCALE, seed=5).image)
    cal_path = folder / "cal.toml"
    cal.to_toml(cal_path)
    # a multi-view calibration file of the simulated camera (exact, no fit): rotation, translation, homography
    sim = camera_sim.aalborg_camera()
    multi = vision.Calibration(sim.camera, plane_matrix(sim.rotation, sim.translation), model="multi-view",
                               rotation=sim.rotation, translation=sim.translation)
    multi_path = folder / "multi.toml"
    multi.to_toml(multi_path)
    return {"folder": folder, "photo": photo, "image": image, "cal": cal_path,
            "cal_dict": tomllib.loads(cal_path.read_text()), "multi": multi_path,
            "multi_dict": tomllib.loads(multi_path.read_text())}


def pose_json(argv: list[str]) -> dict:
    status, out, err = run_cli([*argv, "--format", "json"])
    assert status == 0, err
    return json.loads(out)


# ------------------------------------------------------------------------------------------------ calibration files
def _edit(table: dict, key: str, value) -> dict:
    table = copy.deepcopy(table)
    parts = key.split(".")
    parent = table
    for part in parts[:-1]:
        parent = parent[part]
    if value is KeyError:
        del parent[parts[-1]]
    else:
        parent[parts[-1]] = value
    return table


ZERO = [[0.0, 0.0, 0.0]] * 3
CAL_CASES = [  # (base, key edited, new value or KeyError = deleted, key named in the message, words)
    ("cal", "calibration.plane.homography", ZERO, "calibration.plane.homography", "singular"),
    ("cal", "calibration.plane.homography", [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 0.0, 1.0]],
     "calibration.plane.homography", "singular"),
    ("cal", "calibration.plane.homography", [[1.0, 0.0], [0.0, 1.0]], "calibration.plane.homography", "shape"),
    ("cal", "calibration.plane.homography", [[1.0, 0.0, 0.0], [0.0, math.nan, 0.0], [0.0, 0.0, 1.0]],
     "calibration.plane.homography[1][1]", "finite"),
    ("cal", "calibration.plane.homography", [[1e300, 0.0, 0.0], [0.0, 1e300, 0.0], [0.0, 0.0, 1e-300]],
     "calibration.plane.homography", "singular"),
    ("cal", "calibration.plane.homography", KeyError, "calibration.plane.homography", "missing"),
    ("cal", "calibration.plane", KeyError, "calibration.plane", "missing"),
    ("cal", "calibration.camera_matrix", KeyError, "calibration.camera_matrix", "missing"),
    ("cal", "calibration.camera_matrix", [[0.0, 0.0, 1.0], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]],
     "calibration.camera_matrix", "fx"),
    ("cal", "calibration.distortion", [1.0, 2.0], "calibration.distortion", "shape"),
    ("cal", "calibration.distortion", [-50.0, 0.0, 0.0, 0.0, 0.0], "calibration.distortion", "inverted"),
    ("cal", "calibration.image_size", [0, 10], "calibration.image_size", "whole numbers"),
    ("cal", "calibration.spacing_mm", -20.0, "calibration.spacing_mm", "positive"),
    ("cal", "calibration.spacing_mm", KeyError, "calibration.spacing_mm", "missing"),
    ("cal", "calibration.model", "stereo", "calibration.model", "single-view"),
    ("cal", "calibration.residuals.rms_px", "big", "calibration.residuals.rms_px", "number"),
    ("cal", "calibration.residuals.systematic_px", -1.0, "calibration.residuals.systematic_px", "negative"),
    ("cal", "calibration.covariance.parameters", ["a"], "calibration.covariance.parameters", "must list"),
    ("cal", "calibration.covariance.parameters", 3.0, "calibration.covariance.parameters", "must list"),
    ("cal", "calibration.covariance.matrix", [[1.0] * 10] * 9, "calibration.covariance.matrix", "shape"),
    ("cal", "calibration.colour", 1, "colour", "unknown"),
    ("multi", "calibration.plane.rotation", [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 2.0]],
     "calibration.plane.rotation", "rotation"),
    ("multi", "calibration.plane.rotation", KeyError, "calibration.plane.rotation", "missing"),
    ("multi", "calibration.plane.translation_mm", [0.0, 0.0, -340.0], "calibration.plane.translation_mm",
     "in front of the camera"),
    ("multi", "calibration.plane.homography", [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
     "calibration.plane.homography", "does not match"),
]


@pytest.mark.parametrize("base, key, value, named, words", CAL_CASES,
                         ids=[f"{c[0]}-{c[1].split('.')[-1]}-{i}" for i, c in enumerate(CAL_CASES)])
def test_bad_calibration_file(env, base, key, value, named, words) -> None:
    """Refused when loaded (library: ConfigError naming the key, no RuntimeWarning from numpy on the way; CLI:
    one line naming the file and the key)."""
    import warnings

    from pmaccuracy.errors import ConfigError

    path = env["folder"] / f"bad_{base}.toml"
    path.write_text(tomli_w.dumps(_edit(env[f"{base}_dict"], key, value)))
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        with pytest.raises(ConfigError) as info:
            vision.Calibration.from_toml(path)
    assert named in str(info.value) and str(path) in str(info.value)
    assert_error(["vision", "pose", str(env["photo"]), "--calibration", str(path)], str(path), named, words)


@pytest.mark.parametrize("drop", ["calibration.residuals", "calibration.covariance", "calibration.dot_radius_mm",
                                  "calibration.n_views"])
def test_optional_calibration_keys(env, drop) -> None:
    """residuals (systematic_px: 0), covariance (no calibration term in the uncertainty), dot_radius_mm and the
    counts are optional: the pose is the same, to the bit, as with the full file."""
    path = env["folder"] / "optional.toml"
    path.write_text(tomli_w.dumps(_edit(env["cal_dict"], drop, KeyError)))
    full = pose_json(["vision", "pose", str(env["photo"]), "--calibration", str(env["cal"])])
    part = pose_json(["vision", "pose", str(env["photo"]), "--calibration", str(path)])
    assert (part["x"], part["y"], part["phi_deg"]) == (full["x"], full["y"], full["phi_deg"])
    assert abs(part["x"] - TRUTH[0]) < 0.01 and abs(part["y"] - TRUTH[1]) < 0.01  # 1/25 px
    assert abs(part["phi_deg"] - TRUTH[2]) < 0.03  # markers 80 px apart: 0.03 deg = 0.04 px
    assert all(math.isfinite(v) and v >= 0 for v in part["uncertainty"].values())


def test_calibration_file_errors(env, tmp_path) -> None:
    assert_error(["vision", "pose", str(env["photo"]), "--calibration", str(tmp_path / "none.toml")],
                 "none.toml", "no such calibration file")
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\xff\xfe\x00 junk")
    assert_error(["vision", "pose", str(env["photo"]), "--calibration", str(binary)], "binary.toml", "binary file")
    broken = tmp_path / "broken.toml"
    broken.write_text("[calibration\nmodel = ")
    assert_error(["vision", "pose", str(env["photo"]), "--calibration", str(broken)], "broken.toml", "malformed")


def test_marker_height_against_the_calibration(env) -> None:
    """Markers at or above the camera are refused before the image is read (the file need not exist)."""
    assert_error(["vision", "pose", "nowhere.png", "--calibration", str(env["multi"]), "--marker-height-mm", "400"],
                 "--marker-height-mm 400", "camera", str(env["multi"]))
    assert_error(["vision", "pose", "nowhere.png", "--calibration", str(env["cal"]), "--marker-height-mm", "5"],
                 str(env["cal"]), "single-view")


# ------------------------------------------------------------------------------------------------ images
def _write(kind: str, env, path):
    """Write the image case ``kind`` to ``path`` (a folder for "folder")."""
    from skimage import io as skio

    data = env["photo"].read_bytes()
    if kind == "empty":
        path.write_bytes(b"")
    elif kind == "text":
        path.write_text("not an image\n")
    elif kind == "random":
        path.write_bytes(np.random.default_rng(0).bytes(4000))
    elif kind == "truncated":
        path.write_bytes(data[: len(data) // 2])
    elif kind == "header only":
        path.write_bytes(data[:40])
    elif kind == "huge header":
        path.write_bytes(png_header_only(12000, 12000))
    elif kind == "bomb header":
        path.write_bytes(png_header_only(100000, 100000))
    elif kind == "folder":
        path.mkdir()
    elif kind == "tiny":
        skio.imsave(path, np.full((2, 2), 128, np.uint8), check_contrast=False)
    elif kind == "frames":  # a three-page TIFF
        from PIL import Image

        pages = [Image.fromarray(np.full((20, 20), 40 * k, np.uint8)) for k in range(3)]
        pages[0].save(path, save_all=True, append_images=pages[1:])


IMAGE_CASES = [  # (kind, suffix, words)
    ("missing", ".png", "no such image file"),
    ("empty", ".png", "empty file"),
    ("text", ".png", "not a readable image"),
    ("random", ".jpg", "not a readable image"),
    ("truncated", ".png", "truncated"),
    ("header only", ".png", "not a readable image"),
    ("huge header", ".png", "limit of 25,000,000 pixels"),
    ("bomb header", ".png", "limit of 25,000,000 pixels"),
    ("folder", ".png", "is a folder"),
    ("tiny", ".png", "too small"),
    ("frames", ".tif", "3 frames"),
]


@pytest.mark.parametrize("kind, suffix, words", IMAGE_CASES, ids=[c[0] for c in IMAGE_CASES])
@pytest.mark.parametrize("command", ["pose", "detect", "calibrate"])
def test_bad_image(env, tmp_path, kind, suffix, words, command) -> None:
    path = tmp_path / f"img_{kind.replace(' ', '_')}{suffix}"
    _write(kind, env, path)
    argv = {"pose": ["vision", "pose", str(path), "--mm-per-pixel", str(SCALE)],
            "detect": ["vision", "detect", str(path)],
            "calibrate": ["vision", "calibrate", str(path), "--out", str(tmp_path / "c.toml")]}[command]
    assert_error(argv, str(path), words)
    assert not (tmp_path / "c.toml").exists()


def test_pixel_limit_checked_before_decoding(env, tmp_path, monkeypatch) -> None:
    """A header declaring 12000 x 12000 pixels is refused without calling the decoder."""
    import skimage.io

    def no_decoding(*args, **kwargs):
        raise AssertionError("the pixels were decoded")

    monkeypatch.setattr(skimage.io, "imread", no_decoding)
    path = tmp_path / "huge.png"
    path.write_bytes(png_header_only(12000, 12000))
    from pmaccuracy.errors import VisionError

    with pytest.raises(VisionError, match="12000 x 12000"):
        vision.load_image(path)


@pytest.mark.parametrize("variant", ["16-bit", "rgb", "rgba", "grey+alpha", "float tiff"])
def test_image_formats_give_the_same_pose(env, tmp_path, variant) -> None:
    """16-bit, colour (equal channels), alpha and float TIFF copies of the photo: the pose of the 8-bit original
    within 1e-3 mm / deg (the grey levels differ by the 8-bit rounding only)."""
    from skimage import io as skio

    grey8 = (np.clip(env["image"], 0, 1) * 255).round().astype(np.uint8)
    base = tmp_path / "base.png"
    skio.imsave(base, grey8, check_contrast=False)
    arr = {"16-bit": grey8.astype(np.uint16) * 257, "rgb": np.dstack([grey8] * 3),
           "rgba": np.dstack([grey8] * 3 + [np.full_like(grey8, 255)]),
           "grey+alpha": np.dstack([grey8, np.full_like(grey8, 255)]),
           "float tiff": grey8.astype(np.float32) / 255}[variant]
    path = tmp_path / ("variant.tif" if variant == "float tiff" else "variant.png")
    skio.imsave(path, arr, check_contrast=False)
    ref = pose_json(["vision", "pose", str(base), "--mm-per-pixel", str(SCALE)])
    got = pose_json(["vision", "pose", str(path), "--mm-per-pixel", str(SCALE)])
    for key in ("x", "y", "phi_deg"):
        assert got[key] == pytest.approx(ref[key], abs=1e-3)


def _markers_image(tmp_path, name, centres_mm, *, radius=1.5):
    """Flat image of disks at plane points ``centres_mm`` (the plain scale of the tests)."""
    px = vision.mm_to_pixels(np.asarray(centres_mm, float), SCALE, SHAPE)
    path = tmp_path / name
    vision.save_image(path, vision.render_dots(SHAPE, px, radius / SCALE, blur_sigma=1.0, noise_sigma=0.005, seed=1))
    return path


@pytest.mark.parametrize("case, words", [
    ("three", "found 3 markers"),
    ("cut", "cut by the image border"),
    ("extra", "sets of 4 form"),
    ("none", "found no markers"),
])
def test_markers_missing_cut_extra(env, tmp_path, case, words) -> None:
    square = vision.platform_markers(0.0, 0.0, 0.0)
    half = SHAPE[1] * SCALE / 2  # the image edge, mm from the centre
    centres = {"three": square[:3],
               "cut": np.vstack([square[:3] - [half - 12, 0], [[-half, 0.0]]]),
               "extra": np.vstack([square - [12.0, 0.0], square + [12.0, 0.0]]),
               "none": np.zeros((0, 2))}[case]
    path = _markers_image(tmp_path, f"{case}.png", centres)
    assert_error(["vision", "pose", str(path), "--mm-per-pixel", str(SCALE)], str(path), words)


def test_detect_names_the_image_and_prints_a_header_when_empty(env, tmp_path) -> None:
    blank = tmp_path / "blank.png"
    vision.save_image(blank, np.full((50, 60), 0.7))
    for fmt, expected in (("csv", "col,row,sigma_px\n"), ("table", "col  row  sigma_px\n"), ("json", "[]\n")):
        status, out, err = run_cli(["vision", "detect", str(blank), "--format", fmt])
        assert status == 0 and out == expected and err == ""


def test_max_dot_px_checked_against_the_image(env, tmp_path) -> None:
    assert_error(["vision", "calibrate", str(env["photo"]), "--max-dot-px", "1e9", "--out", str(tmp_path / "c.toml")],
                 "--max-dot-px", str(env["photo"]), "half the shorter side")
    assert_error(["vision", "calibrate", str(env["photo"]), "--max-dot-px", "1", "--out", str(tmp_path / "c.toml")],
                 "--max-dot-px", "above 2")
    assert not (tmp_path / "c.toml").exists()


# ------------------------------------------------------------------------------------------------ renderers
RENDER_CASES = [  # (extra options of render-pose, words)
    (["--x", "1000"], "--x 1000"),
    (["--y", "-1e300"], "not lie wholly inside"),
    (["--spacing-mm", "1e9"], "not lie wholly inside"),
    (["--marker-height-mm", "339"], "camera"),
    (["--marker-height-mm=-1e6"], "px in radius"),
    (["--marker-radius-mm", "1e-9"], "px in radius"),
    (["--marker-radius-mm", "11"], "--marker-radius-mm 11"),
    (["--seed", "-1"], "--seed"),
    (["--distractors", "100000"], "--distractors"),
    (["--tilt-deg", "89"], "--tilt-deg"),
    (["--distortion-px", "1e6"], "--distortion-px"),
    (["--falloff", "0.95"], "--falloff"),
    (["--camera", "flat", "--size", "100000", "100000"], "--size 100000 100000"),
    (["--camera", "flat", "--size", "1", "1"], "--size 1 1"),
    (["--camera", "flat", "--blur", "1e9"], "--blur"),
    (["--camera", "flat", "--noise", "2"], "--noise"),
    (["--camera", "flat", "--mm-per-pixel", "1e-9"], "--mm-per-pixel 1e-09"),
    (["--camera", "flat", "--x", "1000"], "--x 1000"),
    (["--mm-per-pixel", "0.1"], "--mm-per-pixel applies to --camera flat"),
]


@pytest.mark.parametrize("extra, words", RENDER_CASES, ids=[" ".join(c[0]) for c in RENDER_CASES])
def test_render_pose_refusals(tmp_path, extra, words) -> None:
    out = tmp_path / "r.png"
    assert_error(["vision", "render-pose", *extra, "--out", str(out)], words)
    assert not out.exists()


@pytest.mark.parametrize("extra, words", [
    (["--dot-radius-mm", "15"], "--dot-radius-mm 15"),
    (["--spacing-mm", "1e-3"], "--dot-radius-mm 2"),
    (["--spacing-mm", "1e9"], "only 1 dot"),
    (["--camera", "flat", "--mm-per-pixel", "1e6"], "px in radius"),
    (["--camera", "flat", "--mm-per-pixel", "1e-6"], "only 0 dot"),
    (["--pose-seed=-3", "--view", "2"], "--pose-seed"),
    (["--camera", "flat", "--view", "1"], "--view"),
])
def test_render_sheet_refusals(tmp_path, extra, words) -> None:
    out = tmp_path / "s.png"
    assert_error(["vision", "render-sheet", *extra, "--out", str(out)], words)
    assert not out.exists()


def test_render_is_reproducible_and_creates_folders(tmp_path) -> None:
    """The default seed is 0: two runs give the same pixels; missing folders of --out are created."""
    from skimage import io as skio

    a, b = tmp_path / "new" / "deeper" / "a.png", tmp_path / "b.png"
    for out in (a, b):
        status, _, err = run_cli(["vision", "render-pose", "--camera", "flat", "--x", "1", "--out", str(out)])
        assert status == 0, err
    assert np.array_equal(skio.imread(a), skio.imread(b))
    status, _, err = run_cli(["vision", "render-pose", "--camera", "flat", "--x", "1", "--seed", "1", "--out",
                              str(b)])
    assert status == 0 and not np.array_equal(skio.imread(a), skio.imread(b))


def test_output_path_refusals(env, tmp_path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert_error(["vision", "render-pose", "--out", str(blocker / "r.png")], "--out", "is a file")
    assert_error(["vision", "render-pose", "--out", str(tmp_path / "r.gif")], "--out", ".gif")
    assert_error(["vision", "render-pose", "--out", str(tmp_path)], "--out", str(tmp_path))
    assert_error(["vision", "calibrate", str(env["photo"]), "--out", str(blocker / "c.toml")], "--out", "is a file")
    assert_error(["vision", "render-batch", "--measurements", "m.csv", "--out-dir", str(blocker)], "--out-dir")


def test_render_batch_refuses_readings_off_the_image(tmp_path) -> None:
    """A point far outside the camera's field is named by the file, point, push and line before any photo exists."""
    rows = ["point,x_nom,y_nom,phi_nom_deg,push,x,y,phi_deg"]
    for point, x in (("P0", 0.0), ("P1", 900.0)):
        for push in ("+x", "-x", "+y", "-y", "+r", "-r"):
            rows.append(f"{point},{x},0,0,{push},{x + 0.01},0,0")
    truth = tmp_path / "truth.csv"
    truth.write_text("\n".join(rows) + "\n")
    line = assert_error(["vision", "render-batch", "--measurements", str(truth), "--out-dir",
                         str(tmp_path / "photos")], str(truth), "point P1 push +x (line 8)", "not lie wholly inside")
    assert line
    assert not list((tmp_path / "photos").glob("*.png"))


# ------------------------------------------------------------------------------------------------ manifests
@pytest.mark.parametrize("body, words", [
    ("photo.png,A,1,2\n", "line 2: expected 6 values"),
    ("photo.png,A,x,0,0,+x\n", "line 2: column x_nom: not a number"),
    ("photo.png,A,nan,0,0,+x\n", "line 2: column x_nom: must be finite"),
    ("photo.png,A,0,0,0,+z\n", "line 2: push '+z'"),
    (",A,0,0,0,+x\n", "line 2: empty image path"),
    ("photo.png,A,0,0,0,+x\nphoto.png,A,0,0,0,+x\n", "line 3: point A: push +x repeated"),
    ("photo.png,A,0,0,0,+x\n", "missing push(es)"),
    ("".join(f"gone.png,A,0,0,0,{p}\n" for p in ("+x", "-x", "+y", "-y", "+r", "-r")),
     "line 2: no such image file"),
])
def test_bad_manifest_rows(env, body, words) -> None:
    manifest = env["folder"] / "manifest.csv"
    manifest.write_text("image,point,x_nom,y_nom,phi_nom_deg,push\n" + body)
    out = env["folder"] / "measured.csv"
    line = assert_error(["vision", "batch", str(manifest), "--calibration", str(env["cal"]), "--out", str(out)],
                        str(manifest), words)
    assert "gone.png" in line if "gone.png" in body else True
    assert not out.exists()


# ------------------------------------------------------------------------------------------------ warnings
def test_plausibility_warnings_and_quiet(tmp_path) -> None:
    """Implausible but valid values: one warning line each on stderr, exit 0; none with --quiet; appended to the
    single error line when the command then fails."""
    argv = ["vision", "render-pose", "--marker-height-mm=-3", "--spacing-mm", "0.9", "--marker-radius-mm", "0.1",
            "--out", str(tmp_path / "w.png")]
    status, _, err = run_cli(argv)
    lines = err.strip().splitlines()
    assert status == 2 and len(lines) == 1  # 0.3 mm markers are below 2 px: refused, with the notes appended
    assert "(note: " in lines[0] and "--marker-height-mm -3 puts" in lines[0] and "--spacing-mm 0.9 is" in lines[0]
    argv = ["vision", "render-pose", "--camera", "flat", "--mm-per-pixel", "0.5", "--spacing-mm", "210",
            "--marker-radius-mm", "3", "--noise", "0", "--out", str(tmp_path / "w.png")]
    status, _, err = run_cli(argv)
    lines = err.strip().splitlines()
    assert status == 0 and len(lines) == 1 and ": warning: --spacing-mm 210 is outside" in lines[0], err
    status, _, err = run_cli([*argv, "--quiet"])
    assert status == 0 and err == ""


def test_degenerate_calibration_views_are_named(env, tmp_path) -> None:
    """Three identical views cannot determine the intrinsics (Zhang): refused, naming the images, no file."""
    sheet = tmp_path / "sheet.png"
    vision.save_image(sheet, vision.render_calibration_sheet(SHAPE, mm_per_pixel=SCALE, seed=6).image)
    out = tmp_path / "c.toml"
    assert_error(["vision", "calibrate", str(sheet), str(sheet), str(sheet), "--out", str(out)], str(sheet),
                 "degenerate")
    assert not out.exists()
