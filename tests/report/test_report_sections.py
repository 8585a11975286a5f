"""A report is never all-or-nothing: sections run one by one, a failing one becomes a box (issue 33), and every
sentence of the design section is computed over the region the user gave."""

from __future__ import annotations

import json
import re
import warnings

import numpy as np
import pytest

from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.accuracy.regions import Disc
from pmaccuracy.cli import main
from pmaccuracy.errors import ConfigError, NoSolutionError
from pmaccuracy.report import accuracy_report as ar
from pmaccuracy.report import design_report as dr
from pmaccuracy.report.document import Document
from pmaccuracy.report.sections import Section, SectionFailedWarning, SectionRunner, format_seconds


def _doc_with_sections(fail: BaseException):
    doc, results = Document("t"), {}

    def ok():
        doc.heading("First")
        doc.paragraph("one")

    def bad():
        doc.heading("Second")
        doc.paragraph("partial text that must not stay")
        raise fail

    def after():
        doc.heading("Third")
        doc.paragraph("three")
    return doc, results, [Section("First", ok, 1.0), Section("Second", bad, 2.0), Section("Third", after, 90.0)]


def test_a_failing_section_becomes_a_box_and_the_rest_is_written():
    doc, results, sections = _doc_with_sections(NoSolutionError("the loops cannot be closed at pose (1, 2, 3 deg)"))
    runner = SectionRunner(doc, results)
    with pytest.warns(SectionFailedWarning, match="'Second'.*pose \\(1, 2, 3 deg\\)"):
        runner.run(sections)
    md = doc.to_markdown()
    assert "partial text" not in md
    assert "## 2. Second" in md and "## 3. Third" in md and "three" in md     # numbering continues
    assert re.search(r"> \*\*Second: not computed \(after [\d.]+ s\)\.\*\* Reason: the loops cannot be closed at pose", md)
    assert "class='failed'" in doc.to_html()
    assert results["failed_sections"] == [{"section": "Second", "reason": "the loops cannot be closed at pose "
                                           "(1, 2, 3 deg)", "error": "NoSolutionError"}]


def test_strict_raises_the_failure_and_a_defect_is_named_internal():
    doc, results, sections = _doc_with_sections(ConfigError("bad", key="--x"))
    with pytest.raises(ConfigError):
        SectionRunner(doc, results, strict=True).run(sections)
    doc, results, sections = _doc_with_sections(TypeError("None > None"))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        SectionRunner(doc, results).run(sections)
    assert [w.category for w in caught] == [SectionFailedWarning]
    assert results["failed_sections"][0]["reason"].startswith("internal error (TypeError: None > None)")


def test_the_plan_line_lists_each_section_and_the_total(capsys):
    import sys

    doc, results, sections = _doc_with_sections(NoSolutionError("x"))
    runner = SectionRunner(doc, results, stream=sys.stderr, progress=False)
    line = runner.plan_text(sections)
    assert line == "report: 3 sections, estimated ~2 min in all (First ~1 s, Second ~2 s, Third ~2 min)"
    assert format_seconds(0.2) == "~1 s" and format_seconds(59.6) == "~60 s"


def test_reproduce_writes_the_report_when_a_section_fails(tmp_path, capsys, monkeypatch):
    """The virtual experiment of a user's robot meets a pose where the loops cannot close: the report is still
    written, with a box naming the section, the pose and the reason; one warning; exit 0 (``--strict``: exit 2)."""
    def fail(doc, robot, *args, **kwargs):
        doc.heading(ar.TITLES["experiment"])
        raise NoSolutionError("the perturbed loops cannot be closed at pose (12, -3, 0 deg): the errors are too "
                              "large there (or the pose is near a singularity)")
    monkeypatch.setattr(ar, "_experiment_section", fail)
    out = tmp_path / "rep"
    args = ["reproduce", "--robot", "symmetric_3rpr", "--clearances", "rpr_typical", "--grid", "11", "--no-design",
            "--out", str(out)]
    assert main(args) == 0
    err = capsys.readouterr().err
    warned = [ln for ln in err.splitlines() if "warning" in ln]
    assert len(warned) == 1 and "'Virtual experiment" in warned[0] and "(12, -3, 0 deg)" in warned[0]
    assert err.splitlines()[0].startswith("report: 6 sections, estimated ~")
    res = json.loads((out / "results.json").read_text())
    assert [f["section"] for f in res["failed_sections"]] == [ar.TITLES["experiment"]]
    html = (out / "report.html").read_text()
    assert "not computed" in html and "(12, -3, 0 deg)" in html and "Exact nonlinear check" in html
    assert main(args[:-2] + ["--out", str(tmp_path / "strict"), "--strict"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "error:" in err[-1] and "(12, -3, 0 deg)" in err[-1]


def test_span_and_ranges_print_one_value_when_both_ends_agree():
    assert dr.span([0.2412, 0.2398]) == "0.24" and dr.span([0.1, 0.25]) == "0.10-0.25"
    assert ar._range([0.123441, 0.123449]) == "0.1234" and ar._range([1.0, 2.0]) == "1 - 2"


@pytest.fixture(scope="module")
def disc_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("disc")
    code = main(["reproduce", "--robot", "symmetric_3rpr", "--clearances", "rpr_typical", "--grid", "21",
                 "--no-experiment", "--phi-deg", "0", "--phi-deg", "3", "--phi-range-deg", "-2", "3",
                 "--disc", "2", "-1", "6", "--target", "dp=0.05", "--out", str(out)])
    assert code == 0
    return out, json.loads((out / "results.json").read_text())


def test_design_section_numbers_are_over_the_users_region(disc_report):
    """Grid maxima over the disc (independent: max_pose_errors on the disc's grid points), the certified map
    over the disc only, the headline over the disc, no orientation that was not asked for."""
    out, res = disc_report
    d = res["design_decisions"]
    disc = Disc((2.0, -1.0), 6.0)
    x0, x1, y0, y1 = disc.bounds
    X, Y = np.meshgrid(np.linspace(x0, x1, 21), np.linspace(y0, y1, 21))
    inside = disc.contains(X, Y)
    want = {}
    for phi in (0.0, 3.0):                     # the map orientations inside [-2, 3] deg
        poses = np.column_stack([X[inside], Y[inside], np.full(int(inside.sum()), np.radians(phi))])
        b = max_pose_errors("symmetric_3rpr", "rpr_typical", poses, allow_outside=True, singular="nan")
        for q, v in (("dx", b.dx_max), ("dy", b.dy_max), ("dp", b.dp_max), ("dphi_deg", np.degrees(b.dphi_max))):
            want[q] = max(want.get(q, 0.0), float(np.nanmax(v)))
    gw = d["global_worst"]["rpr_typical"]
    assert gw["grid_orientations_deg"] == [0.0, 3.0]
    for q, v in want.items():
        w = gw["quantities"][q]
        assert w["grid_best"] == pytest.approx(v, rel=1e-9)
        assert w["grid_best"] <= w["upper"] * (1 + 1e-9)           # a grid of the region never beats its bound
    cm = d["certified_map"]
    assert "disc of centre (2, -1) mm" in cm["region"]
    for layer in cm["layers"].values():
        assert layer["points"] <= int(inside.sum())
    head = res["headline"]
    assert "disc of centre (2, -1)" in head["over"]
    assert max(v["dp_max"][1] for v in head["orientations"].values()) == pytest.approx(
        max(float(np.nanmax(max_pose_errors("symmetric_3rpr", "rpr_typical", np.column_stack(
            [X[inside], Y[inside], np.full(int(inside.sum()), np.radians(p))]), allow_outside=True,
            singular="nan").dp_max)) for p in (0.0, 3.0)), rel=1e-9)
    assert set(res["workspace"]) == {"0", "3"}                    # no -30 deg workspace nobody asked for
    md = (out / "report.md").read_text()
    assert "-30" not in md.split("## 2.")[0]
    for lab in ("home", "worst point of the region, phi = 0", "worst point of the region, phi = -2 or 3"):
        assert any(r["label"] == lab for r in d["certified"]), lab


def test_the_verdict_says_what_the_tables_say(disc_report):
    """Each number of the verdict read back from the results it summarizes."""
    out, res = disc_report
    d = res["design_decisions"]
    md = (out / "report.md").read_text()
    verdict = next(line for line in md.splitlines() if line.startswith("**Verdict.**"))
    gw = d["global_worst"]["rpr_typical"]["quantities"]
    m = re.search(r"errs by more than dp = ([\d.]+) mm or dphi = ([\d.]+) deg \(certified; attained ([\d.]+) mm",
                  verdict)
    assert m and [float(v) for v in m.groups()] == [round(gw["dp"]["upper"], 4), round(gw["dphi_deg"]["upper"], 4),
                                                     round(gw["dp"]["lower"], 4)]
    t = dr.trust(d)
    m = re.search(r"by at most ([\d.]+) % at the poses of \(a\).*at most ([\d.]+) % above first order .*up to "
                  r"([\d.]+) %\)", verdict)
    assert m and [float(v) for v in m.groups()] == [round(100 * t["poses_excess"], 2), round(100 * t["map_excess"], 2),
                                                     round(100 * t["map_gap"], 2)]
    # the maps' excess over the certified map and over the poses of (a) recomputed from the tables themselves
    assert t["map_excess"] == max(L["dp"]["excess"] for L in d["certified_map"]["layers"].values())
    at1 = [r for r in d["certified"] if r["scale"] == 1.0]
    assert t["poses_excess"] == pytest.approx(max(r["quantities"]["dp"]["certified"] / r["quantities"]["dp"]
                                                  ["first_order"] - 1 for r in at1), rel=1e-12)
    usable = max(t["poses_excess"], t["map_excess"]) < 0.01
    assert ("can be used as they are" in verdict) == usable
    uni = d["synthesis"]["uniform"]
    assert f"scaled by {uni['scale']:.3g}" in verdict
    assert ("meets" if gw["dp"]["upper"] <= 0.05 else "misses") in verdict
    assert not re.search(r"\b(\d+\.\d+)-\1\b", md)                  # no "0.24-0.24"


def test_a_failing_part_of_the_design_section_is_boxed_and_warned(tmp_path, monkeypatch):
    """A part of the design section that raises (here the synthesis, as cvxpy's solver does near a singularity)
    becomes a box in that section with one warning; the other parts and the verdict are still written."""
    def fail(*args, **kwargs):
        raise RuntimeError("solver failed")
    monkeypatch.setattr(dr, "synthesis_job", fail)
    out = tmp_path / "rep"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = ar.accuracy_report(out, "symmetric_3rpr", "rpr_typical", 11, experiment=False, workers=0,
                                 region=Disc((0.0, 0.0), 4.0), phi_range_deg=(-1.0, 1.0), targets={"dp": 0.05})
    warned = [str(w.message) for w in caught if issubclass(w.category, SectionFailedWarning)]
    assert len(warned) == 2 and all("(c) Tolerance synthesis" in w for w in warned)   # uniform and min-cost
    assert all("internal error (RuntimeError: solver failed)" in w for w in warned)
    assert [f["section"] for f in res["failed_sections"]] == ["Design decisions: (c) Tolerance synthesis, min-cost",
                                                             "Design decisions: (c) Tolerance synthesis, uniform"]
    md = (out / "report.md").read_text()
    assert "**(c) Tolerance synthesis: not computed.** Reason: internal error (RuntimeError: solver failed)" in md
    assert "**(b) Global maximum" in md and "**Verdict.**" in md and "could not be sized" in md


def test_reproduce_takes_several_orientations_after_one_phi_deg(tmp_path, capsys):
    """``--phi-deg 0 3`` as ``--phi-deg 0 --phi-deg 3`` (like map, workspace, worst); a repeated one is refused
    before any folder is made."""
    out = tmp_path / "rep"
    assert main(["reproduce", "--robot", "symmetric_3rpr", "--clearances", "rpr_typical", "--grid", "11",
                 "--no-experiment", "--no-design", "--phi-deg", "0", "3", "--out", str(out)]) == 0
    res = json.loads((out / "results.json").read_text())
    assert set(res["workspace"]) == {"0", "3"} and set(res["cases"]["rpr_typical"]) == {"0", "3"}
    capsys.readouterr()
    assert main(["reproduce", "--robot", "symmetric_3rpr", "--clearances", "rpr_typical", "--phi-deg", "0", "3",
                 "--phi-deg", "3", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--phi-deg" in err[0] and "twice" in err[0] and not (tmp_path / "x").exists()
