"""Property-based fuzzing of every input channel of ``pmaccuracy vision`` (hypothesis, deterministic, bounded).

Channels: image files (random bytes, truncated PNGs, PNG headers declaring any size, random arrays of every
dtype and channel count, constant images, noise), calibration TOML files (random deletions and replacements of
keys of a valid file), batch manifests (random rows) and options (random numbers for the renderers and the
pose). The invariant of every run, from the issue: exit 0 with finite output, or exit 2 with exactly one line
``pmaccuracy vision...: error: ...`` on stderr naming its source (the file, or the option), never a traceback
or an "internal error" (the CLI's last-resort line for an exception it did not expect).

The images are small (at most 160 x 160 px) so that the whole file runs in well under a minute.
"""

from __future__ import annotations

import copy
import io
import json
import math
import struct
import zlib
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import numpy as np
import pytest
import tomli_w
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from pmaccuracy import vision
from pmaccuracy.cli import main

SCALE = 0.25  # mm per pixel of the flat test camera
SHAPE = (160, 160)
FUZZ = settings(max_examples=25, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    """``main(argv)`` in process: exit status, stdout, stderr (argument errors come as SystemExit)."""
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        try:
            status = main(argv)
        except SystemExit as exc:
            status = exc.code
    return int(status or 0), out.getvalue(), err.getvalue()


def check_invariant(status: int, out: str, err: str, sources: list[str], *, fmt: str | None = "json") -> None:
    """Exit 0 with finite output, or exit 2 with one error line naming one of ``sources``; never a traceback."""
    assert "Traceback" not in err and "internal error" not in err, err
    event(f"exit {status}")
    lines = err.strip().splitlines()
    if status == 0:
        assert all(": warning: " in line for line in lines), err
        if fmt == "json":
            data = json.loads(out)
            values = data if isinstance(data, list) else [data]

            def numbers(v):
                if isinstance(v, dict):
                    for x in v.values():
                        yield from numbers(x)
                elif isinstance(v, list):
                    for x in v:
                        yield from numbers(x)
                elif isinstance(v, float):
                    yield v
            assert all(v is not None and math.isfinite(v) for v in numbers(values)), out
        return
    assert status == 2, (status, err)
    assert len(lines) == 1, err
    assert lines[0].startswith("pmaccuracy vision") and ": error: " in lines[0], err
    assert any(s in lines[0] for s in sources), (sources, err)


def png_bytes(width: int, height: int, rows: int = 4) -> bytes:
    """A PNG whose header declares ``width x height`` 8-bit grey pixels but whose data holds at most ``rows`` rows."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    body = zlib.compress(b"\x00" * (min(width, 4096) + 1) * min(height, rows))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0))
            + chunk(b"IDAT", body) + chunk(b"IEND", b""))


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A flat platform photo, a flat single-view calibration of the same camera, and its TOML as a dict."""
    import tomllib

    folder = tmp_path_factory.mktemp("fuzz")
    photo = folder / "photo.png"
    vision.save_image(photo, vision.render_platform(2.0, -1.0, math.radians(7.0), shape=SHAPE, mm_per_pixel=SCALE,
                                                    seed=1))
    sheet = vision.render_calibration_sheet((240, 240), mm_per_pixel=SCALE, seed=2)
    cal = vision.calibrate(sheet.image)
    cal_path = folder / "cal.toml"
    cal.to_toml(cal_path)
    # the photo is 160 x 160, the calibration 240 x 240: a second photo of the calibration's size
    photo_cal = folder / "photo_cal.png"
    vision.save_image(photo_cal, vision.render_platform(2.0, -1.0, math.radians(7.0), shape=(240, 240),
                                                        mm_per_pixel=SCALE, seed=3))
    return {"folder": folder, "photo": photo, "photo_cal": photo_cal, "cal": cal_path,
            "cal_dict": tomllib.loads(cal_path.read_text())}


# ------------------------------------------------------------------------------------------------ images
@FUZZ
@given(data=st.binary(max_size=3000), prefix=st.sampled_from([b"", b"\x89PNG\r\n\x1a\n", b"II*\x00", b"BM",
                                                                 b"\xff\xd8\xff"]),
       suffix=st.sampled_from([".png", ".tif", ".jpg", ".bmp", ".gif", ".dat"]))
def test_random_bytes_as_image(files, data: bytes, prefix: bytes, suffix: str) -> None:
    path = files["folder"] / f"random{suffix}"
    path.write_bytes(prefix + data)
    for argv in (["vision", "detect", str(path), "--format", "json"],
                 ["vision", "pose", str(path), "--mm-per-pixel", str(SCALE), "--format", "json"]):
        check_invariant(*run_cli(argv), [str(path)])


@FUZZ
@given(cut=st.floats(0.0, 0.999))
def test_truncated_png(files, cut: float) -> None:
    data = files["photo"].read_bytes()
    path = files["folder"] / "truncated.png"
    path.write_bytes(data[: int(cut * len(data))])
    check_invariant(*run_cli(["vision", "pose", str(path), "--mm-per-pixel", str(SCALE), "--format", "json"]),
                    [str(path)])


@FUZZ
@given(width=st.integers(1, 2**31 - 1), height=st.integers(1, 2**31 - 1))
def test_declared_dimensions(files, width: int, height: int) -> None:
    """Any size in a PNG header: refused from the header above the pixel limit, else the short data fails."""
    path = files["folder"] / "declared.png"
    path.write_bytes(png_bytes(width, height))
    status, out, err = run_cli(["vision", "detect", str(path), "--format", "json"])
    check_invariant(status, out, err, [str(path)])
    if width * height > vision.images.MAX_IMAGE_PIXELS:
        assert status == 2 and "limit" in err


@FUZZ
@given(height=st.integers(1, 120), width=st.integers(1, 120), channels=st.sampled_from([0, 2, 3, 4]),
       dtype=st.sampled_from(["uint8", "uint16", "float32"]), kind=st.sampled_from(["noise", "constant", "dots"]),
       seed=st.integers(0, 2**16))
def test_random_arrays(files, height, width, channels, dtype, kind, seed) -> None:
    """Noise, constant images and dot images of any size, dtype and channel count: 0 with finite output or 2."""
    from skimage import io as skio

    rng = np.random.default_rng(seed)
    shape = (height, width) + ((channels,) if channels else ())
    if kind == "noise":
        grey = rng.random(shape)
    elif kind == "constant":
        grey = np.full(shape, rng.random())
    else:
        base = vision.render_dots((height, width), rng.uniform(0, [width, height], (rng.integers(0, 8), 2)),
                                  rng.uniform(1.0, 8.0), seed=seed) if min(height, width) >= 3 else np.ones(
            (height, width))
        grey = base if not channels else np.repeat(base[..., None], channels, axis=2)
    if dtype == "float32":
        arr, suffix = grey.astype(np.float32), ".tif"
    else:
        arr, suffix = (grey * np.iinfo(dtype).max).astype(dtype), ".png" if channels != 2 else ".tif"
    path = files["folder"] / f"array{suffix}"
    try:
        skio.imsave(path, arr, check_contrast=False)
    except Exception:  # a combination the writer cannot store: nothing to test
        return
    for argv in (["vision", "detect", str(path), "--format", "json"],
                 ["vision", "pose", str(path), "--mm-per-pixel", str(SCALE), "--format", "json"],
                 ["vision", "calibrate", str(path), "--out", str(files["folder"] / "fuzz_cal.toml"),
                  "--format", "json"]):
        check_invariant(*run_cli(argv), [str(path)])


# ------------------------------------------------------------------------------------------------ calibration files
LEAVES = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**6, 10**6), st.booleans(),
                   st.text(max_size=5), st.lists(st.floats(-1e3, 1e3), max_size=4),
                   st.lists(st.lists(st.floats(allow_nan=False, allow_infinity=False), min_size=3, max_size=3),
                            min_size=3, max_size=3),
                   st.just([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]), st.just({}))


def _paths(table: dict, prefix: tuple = ()) -> list[tuple]:
    out = []
    for key, value in table.items():
        out.append(prefix + (key,))
        if isinstance(value, dict):
            out.extend(_paths(value, prefix + (key,)))
    return out


@FUZZ
@given(data=st.data())
def test_random_calibration_files(files, data) -> None:
    """A valid calibration with 1-3 keys deleted or replaced by random values: 0 with finite output or 2 naming
    the calibration or the photo."""
    table = copy.deepcopy(files["cal_dict"])
    for _ in range(data.draw(st.integers(1, 3))):
        paths = _paths(table)
        if not paths:
            break
        path = data.draw(st.sampled_from(paths))
        parent = table
        for key in path[:-1]:
            parent = parent[key]
        if data.draw(st.booleans()):
            del parent[path[-1]]
        else:
            parent[path[-1]] = data.draw(LEAVES)
    cal = files["folder"] / "fuzz.toml"
    try:
        cal.write_text(tomli_w.dumps(table))
    except (TypeError, ValueError):  # not representable in TOML
        return
    status, out, err = run_cli(["vision", "pose", str(files["photo_cal"]), "--calibration", str(cal),
                                "--format", "json"])
    check_invariant(status, out, err, [str(cal), str(files["photo_cal"])])


@FUZZ
@given(text=st.text(max_size=300))
def test_random_calibration_text(files, text: str) -> None:
    cal = files["folder"] / "text.toml"
    cal.write_text(text, encoding="utf-8")
    check_invariant(*run_cli(["vision", "pose", str(files["photo_cal"]), "--calibration", str(cal)]), [str(cal)],
                    fmt=None)


# ------------------------------------------------------------------------------------------------ manifests
FIELD = st.one_of(st.sampled_from(["photo.png", "missing.png", "A", "B", "+x", "-x", "+y", "-y", "+r", "-r", "0", "1.5",
                                   "nan", "inf", "-1e308", "", " ", "x"]), st.text(max_size=6))


PUSHES = ("+x", "-x", "+y", "-y", "+r", "-r")


@st.composite
def manifest_rows(draw) -> list[list[str]]:
    """Random rows, or a complete manifest of one point (the calibration's photo six times) with one field
    replaced and some rows dropped or repeated."""
    if draw(st.booleans()):
        return draw(st.lists(st.lists(FIELD, min_size=0, max_size=8), max_size=8))
    rows = [["photo_cal.png", "A", "2", "-1", "7", push] for push in PUSHES]
    if draw(st.booleans()):
        i, j = draw(st.integers(0, 5)), draw(st.integers(0, 5))
        rows[i][j] = draw(FIELD)
    if draw(st.booleans()):
        del rows[draw(st.integers(0, 5))]
    if draw(st.booleans()):
        rows.append(list(rows[0]))
    return rows


@FUZZ
@given(rows=manifest_rows(),
       header=st.sampled_from(["image,point,x_nom,y_nom,phi_nom_deg,push"] * 4 + ["image,point", ""]))
def test_random_manifests(files, rows, header) -> None:
    import csv

    manifest = files["folder"] / "manifest.csv"
    with open(manifest, "w", newline="", encoding="utf-8") as fh:
        fh.write(header + "\n")
        csv.writer(fh).writerows(rows)
    status, out, err = run_cli(["vision", "batch", str(manifest), "--calibration", str(files["cal"]),
                                "--out", str(files["folder"] / "measured.csv"), "--format", "json"])
    check_invariant(status, out, err, [str(manifest), str(files["folder"])])


# ------------------------------------------------------------------------------------------------ options
NUMBER = st.one_of(st.floats(-1e6, 1e6, allow_nan=False), st.sampled_from([0.0, 1e-300, 1e300, -1e300, 3.0, 40.0]))


@FUZZ
@given(x=NUMBER, y=NUMBER, phi=NUMBER, radius=NUMBER, spacing=NUMBER, scale=NUMBER, seed=st.integers(-5, 2**70),
       size=st.integers(-2, 400))
def test_render_pose_wild_options(files, x, y, phi, radius, spacing, scale, seed, size) -> None:
    """Any numbers for the options of render-pose (flat camera): exit 2 naming an option, or an image."""
    test_render_pose_options.hypothesis.inner_test(files, x, y, phi, radius, spacing, scale, seed, size)


@FUZZ
@given(x=st.floats(-12, 12), y=st.floats(-12, 12), phi=st.floats(-400, 400), radius=st.floats(0.3, 4),
       spacing=st.floats(8, 30), scale=st.floats(0.1, 0.4), seed=st.integers(0, 2**70), size=st.integers(100, 300))
def test_render_pose_options(files, x, y, phi, radius, spacing, scale, seed, size) -> None:
    """Plausible, borderline numbers for every option of render-pose (flat camera): an image whose pose comes
    back, or exit 2 naming an option (markers off the image, too small, overlapping)."""
    out = files["folder"] / "opts" / "render.png"
    if out.exists():
        out.unlink()
    argv = ["vision", "render-pose", "--camera", "flat", f"--x={x!r}", f"--y={y!r}", f"--phi-deg={phi!r}",
            f"--marker-radius-mm={radius!r}", f"--spacing-mm={spacing!r}", f"--mm-per-pixel={scale!r}",
            f"--seed={seed}", "--size", str(size), str(size), "--out", str(out)]
    status, stdout, err = run_cli(argv)
    check_invariant(status, stdout, err, ["--"], fmt=None)
    if status == 0:  # the markers are in the image: the pose comes back
        status, stdout, err = run_cli(["vision", "pose", str(out), f"--mm-per-pixel={scale!r}",
                                       f"--spacing-mm={spacing!r}", "--format", "json"])
        check_invariant(status, stdout, err, [str(out)])
    else:
        assert not out.exists()


@settings(FUZZ, max_examples=10)
@given(spacing=st.floats(19.0, 21.0), scale=st.one_of(st.none(), st.floats(0.24, 0.26)))
def test_pose_plausible_options(files, spacing, scale) -> None:
    """Options close to the truth: the pose comes back, finite."""
    test_pose_options.hypothesis.inner_test(files, 0.0, spacing, scale, "dark")


@FUZZ
@given(height=st.one_of(st.just(0.0), NUMBER), spacing=st.one_of(st.floats(17, 23), NUMBER),
       scale=st.one_of(st.none(), NUMBER, st.floats(0.23, 0.27)), polarity=st.sampled_from(["dark", "light"]))
def test_pose_options(files, height, spacing, scale, polarity) -> None:
    scale_opt = ["--calibration", str(files["cal"])] if scale is None else [f"--mm-per-pixel={scale!r}"]
    photo = files["photo_cal"] if scale is None else files["photo"]
    status, out, err = run_cli(["vision", "pose", str(photo), *scale_opt, f"--marker-height-mm={height!r}",
                                f"--spacing-mm={spacing!r}", "--polarity", polarity, "--format", "json"])
    check_invariant(status, out, err, [str(photo), str(files["cal"]), "--"])


@settings(max_examples=5, deadline=None, derandomize=True, database=None,  # each in-range case renders (2 s)
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(tilt=st.floats(0, 35), distortion=st.floats(0, 60), falloff=st.floats(0, 0.95), dot=st.floats(0.05, 8),
       spacing=st.floats(0.5, 60))
def test_render_sheet_aalborg_options(files, tilt, distortion, falloff, dot, spacing) -> None:
    """The simulated camera's options: refused (exit 2 naming an option) unless in range; in range, an image."""
    out = files["folder"] / "sheet_opts.png"
    status, stdout, err = run_cli(["vision", "render-sheet", f"--tilt-deg={tilt!r}", f"--distortion-px={distortion!r}",
                                   f"--falloff={falloff!r}", f"--dot-radius-mm={dot!r}", f"--spacing-mm={spacing!r}",
                                   "--out", str(out)])
    check_invariant(status, stdout, err, ["--"], fmt=None)


def test_no_traceback_in_a_separate_process(files, tmp_path) -> None:
    """The process as a user runs it: a PNG declaring 12000 x 12000 pixels and an all-zero homography."""
    import subprocess
    import sys

    huge = tmp_path / "huge.png"
    huge.write_bytes(png_bytes(12000, 12000))
    table = copy.deepcopy(files["cal_dict"])
    table["calibration"]["plane"]["homography"] = [[0.0] * 3] * 3
    zero = tmp_path / "zero.toml"
    zero.write_text(tomli_w.dumps(table))
    for argv, needle in ((["detect", str(huge)], str(huge)),
                         (["pose", str(files["photo_cal"]), "--calibration", str(zero)], str(zero))):
        proc = subprocess.run([sys.executable, "-m", "pmaccuracy.cli", "vision", *argv], capture_output=True,
                              text=True, timeout=120)
        assert proc.returncode == 2 and "Traceback" not in proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1 and needle in proc.stderr, proc.stderr
        assert "RuntimeWarning" not in proc.stderr
