"""Issue 34: the bad-input battery over the commands the first pass left out (experiment, fk,
compare-designs, statistics maps, reproduce).

Each case runs ``pmaccuracy.cli.main`` in-process and requires exit 2 with one error line on stderr that
names the option the user typed (not a Python keyword such as ``take_up``), no traceback, no "internal
error", and nothing written at the output path. Every case failed before its fix: the line named the
library's keyword, or nothing, or the run went on and wrote a report.
"""

from __future__ import annotations

import pytest

from conftest import run_cli


def run(argv, capsys):
    """(status, stderr); an escaping exception is status "exception" with its traceback."""
    status, _, err = run_cli(argv, capsys, catch=True)
    return status, err


def refused_line(argv, capsys, option):
    status, err = run(argv, capsys)
    lines = [line for line in err.splitlines() if ": warning: " not in line]
    assert status == 2, (status, err)
    assert len(lines) == 1, err
    assert "Traceback" not in err and "internal error" not in lines[0], err
    assert option in lines[0], (option, lines[0])
    return lines[0]


@pytest.mark.parametrize("extra, option, keyword", [
    (["--take-up", "2"], "--take-up", "take_up"),
    (["--noise-mm", "-1"], "--noise-mm", "noise_mm"),
    (["--noise-deg", "-0.1"], "--noise-deg", "noise_deg"),
    (["--grid", "0"], "--grid", "grid:"),
])
def test_experiment_simulate_names_the_option_and_keeps_the_output(tmp_path, capsys, extra, option, keyword):
    out = tmp_path / "m.csv"
    out.write_text("keep me\n", encoding="utf-8")
    line = refused_line(["experiment", "simulate", "--grid", "3", *extra, "--out", out], capsys, option)
    assert f"error: {keyword}" not in line, line
    assert out.read_text(encoding="utf-8") == "keep me\n"


def test_experiment_simulate_checks_before_making_the_output_folder(tmp_path, capsys):
    out = tmp_path / "new" / "m.csv"
    refused_line(["experiment", "simulate", "--grid", "3", "--take-up", "1.5", "--out", out], capsys, "--take-up")
    assert not out.parent.exists()


@pytest.mark.parametrize("extra, option", [
    (["--accuracy-mm", "-1"], "--accuracy-mm"),
    (["--accuracy-deg", "0"], "--accuracy-deg"),
    (["--limit-tolerance-mm", "-1"], "--limit-tolerance-mm"),
])
def test_experiment_compare_names_the_option(tmp_path, capsys, extra, option):
    # the values are checked before the measurement file is read: a missing one is not the error reported
    refused_line(["experiment", "compare", "--measurements", tmp_path / "m.csv", *extra], capsys, option)


@pytest.mark.parametrize("joints", [["5000", "0", "0"], ["1e300", "0", "0", "--allow-outside"]])
def test_fk_names_joints(capsys, joints):
    refused_line(["fk", "--joints", *joints], capsys, "--joints")


def test_compare_designs_checks_grid_without_clearances(capsys):
    line = refused_line(["compare-designs", "--robot", "aalborg_3ppr", "--robot", "symmetric_3ppr",
                         "--phi-deg", "0", "--grid", "1"], capsys, "--grid")
    assert not line.split("error: ", 1)[1].startswith("n:"), line


def test_statistics_map_too_large_names_grid_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "sub" / "s.csv"
    line = refused_line(["statistics", "--phi-deg", "0", "--grid", "100000", "--samples", "100", "--out", out],
                        capsys, "--grid")
    assert "error: grid:" not in line, line
    assert not out.parent.exists()


def test_reproduce_refuses_a_design_region_outside_the_workspace(tmp_path, capsys):
    out = tmp_path / "rep"
    refused_line(["reproduce", "--out", out, "--disc", "5000", "5000", "5"], capsys, "--disc")
    assert not out.exists()


@pytest.mark.parametrize("content", [None, b"", b"\xff\xfe\x00\x01binary\x00\n", "image,x\n\xe9t\xe9\n".encode("latin-1")],
                         ids=["missing", "empty", "binary", "latin-1"])
def test_vision_batch_names_a_bad_manifest_before_blaming_the_scale(tmp_path, capsys, content):
    manifest = tmp_path / "manifest.csv"
    if content is not None:
        manifest.write_bytes(content)
    out = tmp_path / "m.csv"
    out.write_text("keep me\n", encoding="utf-8")
    line = refused_line(["vision", "batch", manifest, "--mm-per-pixel", "0.1", "--out", out], capsys, "manifest.csv")
    assert "--mm-per-pixel" not in line, line
    assert out.read_text(encoding="utf-8") == "keep me\n"


@pytest.mark.parametrize("argv, needle", [
    (["ik", "--pose", "1e300", "0", "0"], "--pose (number 1)"),
    (["ik", "--pose", "0", "0", "0", "--pose", "0", "1e12", "0"], "--pose (number 2)"),
    (["ik", "--pose", "0", "0", "1e12"], "phi_deg"),
    (["load", "--pose", "1e20", "0", "0", "--fx", "1"], "--pose"),
    (["workspace", "--phi-deg", "1e300"], "--phi-deg"),
])
def test_absurd_pose_values_are_refused_not_answered(capsys, argv, needle):
    # before: exit 0 with overflowed joint values (1e+300, 1.2e+284) or an empty workspace of nan bounds
    refused_line(argv, capsys, needle)


def test_absurd_value_in_poses_csv_names_file_and_row(tmp_path, capsys):
    poses = tmp_path / "poses.csv"
    poses.write_text("x,y,phi_deg\n0,0,0\n0,-1e300,0\n", encoding="utf-8")
    line = refused_line(["ik", "--poses-csv", poses], capsys, "poses.csv")
    assert "data row 2" in line and "column y" in line, line


def test_ordinary_angles_beyond_a_turn_still_answer(capsys):
    # the bound is on magnitude, not on turns: 720 deg is a legitimate way to write 0
    status, err = run(["ik", "--pose", "0", "0", "720"], capsys)
    assert status == 0, err


@pytest.mark.parametrize("argv, needle", [
    (["bounds", "--robot", "planar_3r_arm", "--joints", "400", "0", "0"], "--joints"),
    (["bounds", "--robot", "planar_3r_arm", "--joints", "1e300", "0", "0", "--allow-outside"], "--joints"),
    (["load", "--robot", "planar_3r_arm", "--joints", "400", "0", "0", "--fx", "1"], "--joints"),
])
def test_serial_joint_values_name_joints(capsys, argv, needle):
    # before: "configuration 1: joint 1 ..." without the option, or exit 0 with errors at phi = 1e300 deg
    refused_line(argv, capsys, needle)


@pytest.mark.parametrize("content", ["", "# laws\n", 'name = "mine"\n'], ids=["empty", "comment", "name-only"])
def test_distribution_file_without_a_law_is_refused(tmp_path, capsys, content):
    # before: read as "uniform for every source" without a word
    law = tmp_path / "laws.toml"
    law.write_text(content, encoding="utf-8")
    line = refused_line(["statistics", "--pose", "0", "0", "0", "--samples", "1000", "--distribution", law],
                        capsys, "laws.toml")
    assert "no law" in line, line


@pytest.mark.parametrize("argv", [
    ["worst", "--phi-deg", "1e300", "1e300", "--disc", "0", "0", "5"],
    ["experiment", "simulate", "--grid", "3", "--phi-deg", "1e300", "--out", "{tmp}/m.csv"],
    ["compare-designs", "--robot", "aalborg_3ppr", "--robot", "symmetric_3ppr", "--phi-deg", "-1e20"],
])
def test_orientation_beyond_any_turn_count_names_phi_deg(tmp_path, capsys, argv):
    # before: blamed on --disc, or "the workspace at phi = 1e+300 deg is empty" without the option
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    refused_line(argv, capsys, "--phi-deg")
    assert not (tmp_path / "m.csv").exists()
