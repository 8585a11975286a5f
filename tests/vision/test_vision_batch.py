"""``vision batch`` manifests: checked before any image is measured, failures name the photo; ``render-batch``."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from pmaccuracy import experiment, vision
from pmaccuracy.cli import main
from pmaccuracy.vision import camera_sim

SCALE = 0.1
SHAPE = (600, 600)
HEADER = ["image", "point", "x_nom", "y_nom", "phi_nom_deg", "push"]


@pytest.fixture(scope="module")
def flat(tmp_path_factory):
    """Six flat photos of one point, a calibration of that flat camera, and a blank photo."""
    folder = tmp_path_factory.mktemp("batch")
    rows = []
    for j, push in enumerate(experiment.PUSHES):
        name = f"p{j}.png"
        vision.save_image(folder / name, vision.render_platform(1.0 + 0.01 * j, -2.0, math.radians(5.0 + 0.02 * j),
                                                                shape=SHAPE, mm_per_pixel=SCALE, seed=j))
        rows.append([name, "A", "1", "-2", "5", push])
    vision.save_image(folder / "blank.png", np.full(SHAPE, 0.8))
    cal = folder / "cal.toml"
    vision.Calibration.from_homography(vision.scale_matrix(SCALE, SHAPE), image_size=SHAPE).to_toml(cal)
    return folder, rows, cal


def _write(path, rows, header=HEADER):
    with open(path, "w", newline="") as fh:
        csv.writer(fh).writerows([header, *rows])
    return path


def test_batch_writes_the_measurement_csv(flat, capsys) -> None:
    folder, rows, cal = flat
    out = folder / "m.csv"
    assert main(["vision", "batch", str(_write(folder / "ok.csv", rows)), "--calibration", str(cal), "--out",
                 str(out), "--format", "csv"]) == 0
    assert len(capsys.readouterr().out.strip().splitlines()) == 7  # header + one line per photo
    m = experiment.load_measurements(out)
    expected = np.array([[1.0 + 0.01 * j, -2.0, math.radians(5.0 + 0.02 * j)] for j in range(6)])
    assert np.all(np.abs(m.readings[0] - expected) < [0.01, 0.01, math.radians(0.01)])
    assert out.read_text().splitlines()[0] == ",".join(experiment.CSV_COLUMNS)


@pytest.mark.parametrize("change, needles", [
    (lambda r: r[:5], ["line 2", "point A: missing push(es) -r"]),
    (lambda r: r + [r[0]], ["line 8", "push +x repeated (already on line 2)"]),
    (lambda r: [r[0][:4] + ["nan", "+x"]] + r[1:], ["line 2", "column phi_nom_deg: must be finite"]),
    (lambda r: [r[0][:5] + ["+z"]] + r[1:], ["line 2", "push '+z'"]),
    (lambda r: [r[0][:2] + ["x", "-2", "5", "+x"]] + r[1:], ["line 2", "x_nom: not a number"]),
    (lambda r: r[:1] + [r[1][:2] + ["1.5"] + r[1][3:]] + r[2:], ["line 3", "nominal pose differs"]),
    (lambda r: [["missing.png"] + r[0][1:]] + r[1:], ["line 2", "no such image file"]),
    (lambda r: [r[0][:3]] + r[1:], ["line 2", "expected 6 values"]),
])
def test_bad_manifest_exits_2_naming_the_line(flat, capsys, change, needles) -> None:
    folder, rows, cal = flat
    rows = [list(r) for r in rows]
    bad = _write(folder / "bad.csv", change(rows))
    out = folder / "never.csv"
    assert main(["vision", "batch", str(bad), "--calibration", str(cal), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0] and all(n in err[0] for n in needles), err
    assert not out.exists()


def test_bad_header_and_missing_manifest(flat, capsys) -> None:
    folder, rows, cal = flat
    bad = _write(folder / "hdr.csv", rows, header=HEADER[::-1])
    assert main(["vision", "batch", str(bad), "--calibration", str(cal), "--out", str(folder / "x.csv")]) == 2
    assert "header must be" in capsys.readouterr().err
    assert main(["vision", "batch", str(folder / "none.csv"), "--calibration", str(cal), "--out",
                 str(folder / "x.csv")]) == 2
    assert "no such manifest" in capsys.readouterr().err


def test_failing_photo_is_named_and_nothing_is_written(flat, capsys) -> None:
    folder, rows, cal = flat
    rows = [list(r) for r in rows]
    rows[3][0] = "blank.png"
    out = folder / "partial.csv"
    assert main(["vision", "batch", str(_write(folder / "blank.csv", rows)), "--calibration", str(cal), "--out",
                 str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "blank.png (manifest line 5)" in err[0] and "found no markers" in err[0]
    assert not out.exists()


def test_single_view_calibration_with_height_refused_before_measuring(flat, capsys) -> None:
    folder, rows, cal = flat
    assert main(["vision", "batch", str(_write(folder / "ok2.csv", rows)), "--calibration", str(cal),
                 "--marker-height-mm", "10", "--out", str(folder / "h.csv")]) == 2
    err = capsys.readouterr().err
    assert str(cal) in err and "single-view" in err


def test_render_batch_photographs_a_measurement_file(tmp_path, capsys) -> None:
    truth = experiment.simulate_experiment("aalborg_3ppr", "case1", 0.0, grid=2, seed=1).subset([0])
    path = experiment.write_measurements(tmp_path / "truth.csv", truth)
    photos = tmp_path / "photos"
    assert main(["vision", "render-batch", "--measurements", str(path), "--out-dir", str(photos),
                 "--marker-height-mm", "8", "--seed", "3"]) == 0
    rows = vision.read_manifest(photos / "manifest.csv")
    assert [r.push for r in rows] == list(experiment.PUSHES)
    # measure one photo with the simulator's own (exact) camera: the truth comes back
    sim = camera_sim.aalborg_camera()
    cal = vision.Calibration(sim.camera, sim.plane(0.0), model="multi-view", rotation=sim.rotation,
                             translation=sim.translation)
    pose = vision.measure_pose(vision.load_image(rows[2].path), calibration=cal, height_mm=8.0)
    x, y, phi = truth.readings[0, 2]
    assert abs(pose.x - x) < 0.005 and abs(pose.y - y) < 0.005
    assert abs(math.degrees(math.remainder(pose.phi - phi, math.pi / 2))) < 0.01
