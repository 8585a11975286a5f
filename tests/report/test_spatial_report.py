"""The accuracy report of a spatial robot (``pmaccuracy reproduce --robot stewart_6ups``): its files, its numbers
(recomputed here from the library), the interactive 3D view offline, a failing section as a box, the CLI's
options."""

from __future__ import annotations

import json
import re
import warnings

import numpy as np
import pytest
import xarray as xr

from conftest import run_cli
from pmaccuracy.accuracy.spatial_bounds import spatial_pose_errors
from pmaccuracy.errors import SingularPoseError
from pmaccuracy.kinematics.spatial import reference_pose
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.model.spatial_sources import SpatialErrorSources
from pmaccuracy.report import spatial_report as sr
from pmaccuracy.report.sections import SectionFailedWarning

GRID = 10


@pytest.fixture(scope="module")
def hexapod_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("stewart")
    results = sr.spatial_accuracy_report(out, "stewart_6ups", grid=GRID)
    return out, results


def _check_files(out, results):
    """Every file the report names exists, results.json is what was returned, the HTML is self-contained."""
    assert json.loads((out / "results.json").read_text()) == json.loads(json.dumps(results, default=float))
    for name in results["figures"]:
        assert (out / name).is_file() and (out / name).stat().st_size > 1000, name
    md = (out / "report.md").read_text()
    for ref in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md):
        assert (out / ref).is_file(), ref
    assert len(re.findall(r"!\[", md)) == len(results["figures"])
    page = (out / "report.html").read_text()
    assert "class=\"pm-view3d\"" in page and "<canvas" in page and "pm-view3d-data" in page
    assert not re.search(r"https?://", page), "the report must not load anything from the network"
    assert not re.search(r"""(src|href)=['"](?!data:|#)""", page), "every resource is embedded"
    assert page.count("<img") == len(results["figures"])
    assert (out / "map.nc").is_file() and (out / results["interactive_view"]).is_file()
    return md, page


def test_hexapod_report_files_and_sections(hexapod_report):
    out, results = hexapod_report
    md, page = _check_files(out, results)
    assert "failed_sections" not in results
    assert [s["section"] for s in results["sections"]] == ["map", "robot", "workspace", "map figures", "sources",
                                                           "method"]
    for title in sr.TITLES.values():
        assert re.search(rf"^## \d\. {title}$", md, re.M), title
    assert "class='failed'" not in page
    assert "Not included yet for spatial robots" in md
    # the tilt at the reference point (6-UPS) and the legs' table
    assert results["workspace"]["max_tilt_deg"] > 0 and len(results["legs"]) == 6
    assert f"{results['workspace']['max_tilt_deg']:.4g} deg" in md


def test_hexapod_numbers_are_the_librarys(hexapod_report):
    out, results = hexapod_report
    robot = SpatialManipulator.preset("stewart_6ups")
    sources = SpatialErrorSources.load("ups_typical", robot)
    b = spatial_pose_errors(robot, sources, reference_pose(robot)[None])
    assert results["reference"]["dp_max"] == pytest.approx(float(b.dp_upper[0]), rel=1e-12)
    assert results["reference"]["dtheta_max_deg"] == pytest.approx(float(np.degrees(b.dtheta_upper[0])), rel=1e-12)
    assert results["headline"]["dp_max_reference"] == results["reference"]["dp_max"]
    with xr.open_dataset(out / "map.nc") as ds:
        dp = float(ds["dp_max"].max())
        dth = float(np.degrees(ds["dtheta_max"].max()))
        assert ds.sizes == {"x": GRID, "y": GRID, "z": GRID}
        assert results["headline"]["map_points"] == int(np.isfinite(ds["dp_max"].values).sum())
    assert results["headline"]["dp_max_map"] == pytest.approx(dp, rel=1e-12)
    assert results["headline"]["dtheta_max_map_deg"] == pytest.approx(dth, rel=1e-12)
    assert results["map"]["ranges"]["dp_max"]["max"] == pytest.approx(dp, rel=1e-12)
    # the summary's sentences carry these numbers
    md = (out / "report.md").read_text()
    assert f"|dp| = {dp:.4g} mm" in md and f"|dp| = {results['reference']['dp_max']:.4g} mm" in md
    # the sources' shares add up to the components, sorted by the largest position component
    k = int(np.argmax(b.components[0, :3]))
    each = results["sources"]["each"]
    assert results["sources"]["sorted_by"] == ("dx", "dy", "dz")[k]
    key = ("dx", "dy", "dz")[k]
    assert [e[key] for e in each] == sorted((e[key] for e in each), reverse=True)
    assert sum(e[key] for e in each) == pytest.approx(b.components[0, k], rel=1e-9)
    assert len(each) == len(b.shares())
    top = results["sources"]["by_kind"][0]["kind"]
    assert f"**{top}** dominates" in md


@pytest.mark.slow
def test_delta_report(tmp_path):
    results = sr.spatial_accuracy_report(tmp_path, "delta_clavel", grid=8)
    md, _ = _check_files(tmp_path, results)
    assert "failed_sections" not in results
    assert "max_tilt_deg" not in results["workspace"]        # only a 6-UPS has an orientation workspace
    leg = SpatialManipulator.preset("delta_clavel").legs[0]
    assert f"arm {leg.arm:g}, rods {leg.rod:g}" in md
    assert results["legs"][0]["stroke_units"] == "deg"


@pytest.mark.slow
@pytest.mark.parametrize("name", ["rps_3", "prs_3", "upu_3"])
def test_every_spatial_preset_has_a_report(tmp_path, name):
    results = sr.spatial_accuracy_report(tmp_path, name, grid=8)
    _check_files(tmp_path, results)
    assert "failed_sections" not in results


def test_a_failing_section_becomes_a_box(tmp_path, monkeypatch):
    def broken(*args, **kwargs):
        raise SingularPoseError("the closure is singular at pose (1, 2, 3)")
    monkeypatch.setattr(sr, "_maps_section", broken)
    with pytest.warns(SectionFailedWarning, match="'Error maps'"):
        results = sr.spatial_accuracy_report(tmp_path, "stewart_6ups", grid=6)
    assert results["failed_sections"] == [{"section": "Error maps", "reason": "the closure is singular at pose "
                                           "(1, 2, 3)", "error": "SingularPoseError"}]
    md = (tmp_path / "report.md").read_text()
    assert "## 4. Error maps" in md and "## 5. Error sources" in md
    assert "Error maps: not computed" in md
    assert "class='failed'" in (tmp_path / "report.html").read_text()
    with pytest.raises(SingularPoseError):
        sr.spatial_accuracy_report(tmp_path / "strict", "stewart_6ups", grid=6, strict=True)


def test_cli_report_strict_and_refusals(tmp_path, capsys, monkeypatch):
    status, out, err = run_cli(["reproduce", "--robot", "stewart_6ups", "--grid", 6, "--out", tmp_path / "r"],
                               capsys)
    assert status == 0 and "wrote" in out and (tmp_path / "r" / "report.html").is_file()
    assert "clearances: ups_typical (default)" in err and "6 sections, estimated" in err
    results = json.loads((tmp_path / "r" / "results.json").read_text())
    assert results["grid"] == 6 and results["clearances"] == "ups_typical"

    def broken(*args, **kwargs):
        raise SingularPoseError("the closure is singular")
    monkeypatch.setattr(sr, "_sources_section", broken)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        status, out, err = run_cli(["reproduce", "--robot", "delta_clavel", "--grid", 6, "--strict",
                                    "--out", tmp_path / "s"], capsys)
    assert status == 2
    lines = [line for line in err.strip().splitlines() if "error" in line]
    assert len(lines) == 1 and "the closure is singular" in lines[0]
    monkeypatch.undo()

    for extra, option in ((["--phi-deg", 10], "--phi-deg"), (["--target", "dp=0.1"], "--target"),
                          (["--phi-range-deg", -5, 5], "--phi-range-deg"), (["--disc", 0, 0, 10], "--disc"),
                          (["--grid", 81], "--grid"), (["--clearances", "no_such_preset"], "--clearances")):
        status, out, err = run_cli(["reproduce", "--robot", "delta_clavel", "--out", tmp_path / "x", *extra], capsys)
        assert status == 2, extra
        assert len(err.strip().splitlines()) == 1 and option in err, err
    assert not (tmp_path / "x").exists()


def test_cli_report_of_a_users_robot_file(tmp_path, capsys):
    status, template, _ = run_cli(["template", "6-UPS"], capsys)
    assert status == 0
    path = tmp_path / "my_6ups.toml"
    path.write_text(template)
    status, out, err = run_cli(["reproduce", "--robot", path, "--grid", 6, "--clearances", "ups_typical",
                                "--out", tmp_path / "r"], capsys)
    assert status == 0, err
    results = json.loads((tmp_path / "r" / "results.json").read_text())
    assert results["robot"] == "my_6ups" and "failed_sections" not in results


@pytest.mark.parametrize("width", [1280, 400])
def test_the_page_fits_the_screen_with_readable_text(hexapod_report, width, tmp_path):
    """As the planar reports (tests/report/test_report_layout.py): no horizontal page scroll at 1280 and 400 px,
    no text under 12 px, the interactive view included."""
    from test_report_layout import CHROMIUM, measure

    if CHROMIUM is None:
        pytest.skip("Chromium is not installed")
    out, _ = hexapod_report
    got = measure((out / "report.html").read_text(encoding="utf-8"), width, tmp_path)
    assert got["width"] == width
    assert got["scroll"] <= width, got
    assert got["font"] >= 12.0, got


def test_raw_html_is_embedded_as_is_and_the_markdown_gets_its_note():
    from pmaccuracy.report.document import Document

    doc = Document("t")
    doc.raw_html("<div id='x'><canvas></canvas></div>", markdown="The view is in `report.html`.")
    doc.raw_html("<p>only in html</p>")
    assert "<div id='x'><canvas></canvas></div>" in doc.to_html() and "<p>only in html</p>" in doc.to_html()
    md = doc.to_markdown()
    assert "The view is in `report.html`." in md and "canvas" not in md and "only in html" not in md
