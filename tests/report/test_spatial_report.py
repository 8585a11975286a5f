"""The accuracy report of a spatial robot (``pmaccuracy reproduce --robot stewart_6ups``): its files, its numbers
(recomputed here from the library), the interactive 3D view offline, a failing section as a box, the CLI's
options."""

from __future__ import annotations

import json
import math
import re
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest
import spatial_error_reference as eref
import spatial_reference as sref
import xarray as xr
from scipy.spatial.transform import Rotation

from conftest import run_cli
from pmaccuracy.accuracy.spatial_bounds import spatial_pose_errors
from pmaccuracy.errors import ConfigError, SingularPoseError
from pmaccuracy.accuracy.spatial_maps import grid_poses
from pmaccuracy.kinematics.spatial import inverse_kinematics, reference_pose
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
                                                           "design", "statistics", "method"]
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
        results = sr.spatial_accuracy_report(tmp_path, "stewart_6ups", grid=6, design=False)
    assert results["failed_sections"] == [{"section": "Error maps", "reason": "the closure is singular at pose "
                                           "(1, 2, 3)", "error": "SingularPoseError"}]
    md = (tmp_path / "report.md").read_text()
    assert "## 4. Error maps" in md and "## 5. Error sources" in md
    assert "Error maps: not computed" in md
    assert "class='failed'" in (tmp_path / "report.html").read_text()
    with pytest.raises(SingularPoseError):
        sr.spatial_accuracy_report(tmp_path / "strict", "stewart_6ups", grid=6, strict=True)


def test_cli_report_strict_and_refusals(tmp_path, capsys, monkeypatch):
    status, out, err = run_cli(["reproduce", "--robot", "upu_3", "--grid", 6, "--target", "dp=0.05",
                                "--out", tmp_path / "r"], capsys)
    assert status == 0 and "wrote" in out and (tmp_path / "r" / "report.html").is_file()
    assert "clearances: upu_typical (default)" in err and "8 sections, estimated" in err
    results = json.loads((tmp_path / "r" / "results.json").read_text())
    assert results["grid"] == 6 and results["clearances"] == "upu_typical"
    assert results["design"]["targets"] == {"dp": 0.05} and results["design"]["binding"] == "dp"
    assert not results["design"]["global"]["certified"] and results["design"]["global"]["scale_certified"] is None

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

    for extra, option in ((["--phi-deg", 10], "--phi-deg"), (["--target", "dphi_deg=0.1"], "--target"),
                          (["--target", "dp=0.1", "--no-design"], "--target"), (["--target", "dp=-1"], "--target"),
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
                                "--no-design", "--out", tmp_path / "r"], capsys)
    assert status == 0, err
    results = json.loads((tmp_path / "r" / "results.json").read_text())
    assert results["robot"] == "my_6ups" and "failed_sections" not in results
    assert "design" not in results and "design" not in [s["section"] for s in results["sections"]]


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


# ------------------------------------------------------------------------------------ design and statistics
DATA = Path(sr.__file__).resolve().parents[1] / "data"


def _reference_hexapod():
    """The preset and its sources as the independent reference reads them (tests/reference: finite
    displacements in the legs' nonlinear chains, no pmaccuracy)."""
    robot = sref.load(DATA / "robots" / "stewart_6ups.toml")
    with open(DATA / "spatial_clearances" / "ups_typical.toml", "rb") as fh:
        return robot, tomllib.load(fh)


def _reference_at(pose):
    robot, cl = _reference_hexapod()
    pose = np.asarray(pose, dtype=float)
    return eref.sensitivity(robot, cl, pose[:3], Rotation.from_rotvec(pose[3:]).as_matrix())


def _scaled(sources, lam):
    return [{**src, "half_width": src["half_width"] * lam} for src in sources]


def test_design_synthesis_meets_its_target_and_binds(hexapod_report):
    """The grid scale meets the targets at every grid point of map.nc (Eq. 1 recomputed from the file) and binds:
    at the binding point the independent reference's largest |dp| of the scaled sources is the target."""
    out, results = hexapod_report
    d = results["design"]
    targets, lam = d["targets"], d["scale_grid"]
    assert targets == {"dp": 0.1, "dtheta_deg": 0.05}
    with xr.open_dataset(out / "map.nc") as ds:
        worst = {"dp": float(ds["dp_max"].max()), "dtheta_deg": math.degrees(float(ds["dtheta_max"].max()))}
    assert lam == pytest.approx(min(t / worst[n] for n, t in targets.items()), rel=1e-12)
    assert all(worst[n] * lam <= t * (1 + 1e-12) for n, t in targets.items())
    # the reference at the binding point (first order by central differences of the nonlinear closures)
    M, src = _reference_at(d["binding_pose"])
    rows, conv = (slice(0, 3), 1.0) if d["binding"] == "dp" else (slice(3, 6), math.degrees(1.0))
    value = eref.max_norm_sampled(M, _scaled(src, lam), rows=rows, n=20000) * conv
    assert targets[d["binding"]] * (1 - 5e-3) <= value <= targets[d["binding"]] * (1 + 1e-5)
    # the kinds' shares of the binding component: the reference's support functions grouped by joint and key
    k = ("dx", "dy", "dz", "drx", "dry", "drz").index(d["binding_component"])
    by_kind = {}
    for s in src:
        key = (s["joint"], s["key"])
        by_kind[key] = by_kind.get(key, 0.0) + s["half_width"] * float(np.linalg.norm(M[k, s["columns"]]))
    total = sum(by_kind.values())
    got = sorted(rec[f"share_of_{d['binding_component']}_pct"] for rec in d["kinds"])
    np.testing.assert_allclose(got, sorted(100 * v / total for v in by_kind.values()), atol=1e-3)
    assert {rec["kind"] for rec in d["kinds"] if rec[f"share_of_{d['binding_component']}_pct"] < 1e-6} == \
        set(d["idle_kinds"])
    md = (out / "report.md").read_text()
    assert f"at most **{lam:.4g}**" in md and "## 6. Design: how loose may the joints be" in md


def test_design_certified_scale_holds_off_the_grid(hexapod_report):
    """The certified scale of a 6-UPS meets the targets at random poses of the workspace between the grid
    points, and the attained worst pose does reach its value."""
    out, results = hexapod_report
    g = results["design"]["global"]
    lam_cert, lam_att = g["scale_certified"], g["scale_attained_limit"]
    assert g["certified"] and lam_cert <= lam_att and lam_cert <= results["design"]["scale_grid"] * (1 + 1e-12)
    robot = SpatialManipulator.preset("stewart_6ups")
    sources = SpatialErrorSources.load("ups_typical", robot)
    with xr.open_dataset(out / "map.nc") as ds:
        lo = np.array([float(ds[c].min()) for c in ("x", "y", "z")])
        hi = np.array([float(ds[c].max()) for c in ("x", "y", "z")])
    pts = np.random.default_rng(7).uniform(lo, hi, (600, 3))
    poses = grid_poses(robot, pts)
    poses = poses[np.asarray(inverse_kinematics(robot, poses).within_limits)]
    assert len(poses) > 50
    b = spatial_pose_errors(robot, sources.scaled(lam_cert), poses, strict=False, details=False)
    ok = np.isfinite(b.dp_upper)
    assert np.all(b.dp_upper[ok] <= 0.1 * (1 + 1e-9))
    assert np.all(np.degrees(b.dtheta_upper[ok]) <= 0.05 * (1 + 1e-9))
    rec = g["quantities"]["dp"]
    at = spatial_pose_errors(robot, sources, np.asarray(rec["pose"])[None])
    assert rec["attained"] * (1 - 1e-3) <= float(at.dp_upper[0]) <= rec["upper"] * (1 + 1e-9)
    assert rec["grid_max"] <= rec["upper"]


def _uniform_in_sets(sources, n, rng):
    """Source variables ``(n, m)`` uniform in each source's own set of radius h (segment, disc, ball), written
    here: radius ``h U^(1/d)`` times a uniform direction."""
    m = sum(eref.SHAPE_DIM[s["shape"]] for s in sources)
    x = np.zeros((n, m))
    for s in sources:
        d = eref.SHAPE_DIM[s["shape"]]
        g = rng.standard_normal((n, d))
        u = g / np.linalg.norm(g, axis=1)[:, None]
        x[:, s["columns"]] = s["half_width"] * (rng.random(n) ** (1.0 / d))[:, None] * u
    return x


def test_statistics_against_an_independent_monte_carlo(hexapod_report):
    """At the reference pose: the analytic RMS against the exact covariance of the reference's first-order map,
    the percentiles against a Monte Carlo drawn here with another seed (within their intervals), the
    statistical scale likewise."""
    out, results = hexapod_report
    st = results["statistics"]
    first = st["poses"][0]
    assert first["label"] == "reference pose" and len(st["poses"]) == 2
    M, src = _reference_at(first["pose"])
    cov = sum(src_["half_width"] ** 2 / (eref.SHAPE_DIM[src_["shape"]] + 2) * M[:, src_["columns"]]
              @ M[:, src_["columns"]].T for src_ in src)
    q = first["quantities"]
    assert q["dp"]["rss"] == pytest.approx(math.sqrt(np.trace(cov[:3, :3])), rel=1e-5)
    assert q["dtheta_deg"]["rss"] == pytest.approx(math.degrees(math.sqrt(np.trace(cov[3:, 3:]))), rel=1e-5)
    t = _uniform_in_sets(src, 50_000, np.random.default_rng(2024)) @ M.T
    mine = {"dp": np.linalg.norm(t[:, :3], axis=1), "dtheta_deg": np.degrees(np.linalg.norm(t[:, 3:], axis=1))}
    for name, v in mine.items():
        for p in (95, 99):
            rec = q[name]
            assert abs(np.percentile(v, p) - rec[f"p{p}"]) <= 1.5 * (rec[f"p{p}_hi"] - rec[f"p{p}_lo"]), (name, p)
        assert v.max() <= q[name]["worst"] * (1 + 1e-6)
    scale = min(t_ / np.percentile(mine[n], 99) for n, t_ in st["thresholds"].items())
    assert first["scale_p99"] == pytest.approx(scale, rel=0.02)
    assert (out / "statistics.png").is_file() and "statistics.png" in results["figures"]


def test_design_targets_are_checked_before_anything_is_written(tmp_path):
    for bad in ({"dphi_deg": 0.1}, {"dp": 0.0}, {"dp": float("nan")}, {}):
        with pytest.raises(ConfigError, match="target"):
            sr.spatial_accuracy_report(tmp_path / "x", "stewart_6ups", targets=bad)
    assert not (tmp_path / "x").exists()


def test_a_failing_global_worst_case_is_a_box_and_the_rest_is_written(tmp_path, monkeypatch):
    from pmaccuracy.accuracy.spatial_worst import SpatialSingularRegionError
    from pmaccuracy.report import spatial_design as sd

    def singular(*args, **kwargs):
        raise SpatialSingularRegionError("the region reaches a singularity near (1, 2, 3) mm")
    monkeypatch.setattr(sd, "spatial_global_worst", singular)
    with pytest.warns(SectionFailedWarning, match="global worst case"):
        results = sr.spatial_accuracy_report(tmp_path, "upu_3", grid=5)
    assert results["failed_sections"] == [{"section": "Design: global worst case",
                                           "reason": "the region reaches a singularity near (1, 2, 3) mm"}]
    assert "global" not in results["design"] and results["design"]["scale_grid"] > 0
    md = (tmp_path / "report.md").read_text()
    assert "Global worst case over the workspace: not computed" in md
    # the statistics fall back to the synthesis' binding grid point for their second pose
    assert [p["label"] for p in results["statistics"]["poses"]] == ["reference pose",
                                                                    "binding grid point of the synthesis"]
    assert "at the map's grid points only" in md     # the summary claims no certified or global scale
