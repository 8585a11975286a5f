"""Issue 12 (hardening): the CLI's error boundary, output paths, --quiet, negative numbers, plausibility warnings.

Every case of the issue's list is run in-process through ``pmaccuracy.cli.main``:
an error exits 2 with exactly one line on stderr naming its option/file, a
plausibility warning is one line ``pmaccuracy CMD: warning: ...`` (none with
``--quiet``), and no case prints a traceback.
"""

from __future__ import annotations

import json
import math
import os

import numpy as np
import pytest

from pmaccuracy.cli import NEGATIVE_NUMBER, main
from conftest import run_cli


def run(argv, capsys):
    """(status, stdout, stderr); an escaping exception is status "exception" with its traceback."""
    return run_cli(argv, capsys, catch=True)


def assert_error(result, command, *needles):
    status, out, err = result
    assert status == 2, (status, err)
    assert "Traceback" not in err, err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"pmaccuracy {command}: error:"), err
    for needle in needles:
        assert str(needle) in lines[0], (needle, err)
    assert out == ""


def warnings_of(err):
    return [line for line in err.splitlines() if ": warning: " in line]


# ----------------------------------------------------------------------------------- negative numbers
@pytest.mark.parametrize("text", ["-1", "-1.5", "-.5", "-2.", "-1.5e-3", "-2E+4", "-1e5", "-1_000.5", "-inf", "-NaN"])
def test_negative_number_forms_are_values(text):
    assert NEGATIVE_NUMBER.match(text)


@pytest.mark.parametrize("text", ["--pose", "-x", "--phi-deg", "-e5", "-1e", "-1.5e-"])
def test_options_are_not_numbers(text):
    assert not NEGATIVE_NUMBER.match(text)


def test_exponent_negative_numbers_on_the_command_line(capsys):
    status, out, err = run(["ik", "--pose", 1, "-2e-3", 0, "--format", "json"], capsys)
    assert status == 0, err
    assert json.loads(out)[0]["y"] == -2e-3
    status, out, err = run(["bounds", "--pose", "-1.5e-3", 0, 0, "--format", "json"], capsys)
    assert status == 0, err
    assert json.loads(out)[0]["x"] == -1.5e-3
    assert_error(run(["ik", "--pose", 1, "-inf", 0], capsys), "ik", "--pose", "finite")


# ----------------------------------------------------------------------------------- output paths
def test_map_duplicate_orientation_refused_with_or_without_plot(tmp_path, capsys):
    for extra in ([], ["--plot", tmp_path / "d.png"]):
        argv = ["map", "--phi-deg", 0, "--phi-deg", 0, "--grid", 11, "--out", tmp_path / "a.nc", *extra]
        assert_error(run(argv, capsys), "map", "--phi-deg", "twice")
    assert not (tmp_path / "a.nc").exists()


def test_map_unsupported_plot_format_refused_before_computing(tmp_path, capsys):
    argv = ["map", "--phi-deg", 0, "--grid", 11, "--out", tmp_path / "a.nc", "--plot", tmp_path / "p.xyz"]
    assert_error(run(argv, capsys), "map", "--plot", "p.xyz", ".png")
    assert not (tmp_path / "a.nc").exists()


def test_map_out_under_a_file(tmp_path, capsys):
    blocker = tmp_path / "hostname"
    blocker.write_text("x")
    argv = ["map", "--phi-deg", 0, "--grid", 11, "--out", blocker / "m.csv"]
    assert_error(run(argv, capsys), "map", "--out", str(blocker / "m.csv"), "is a file")


def test_map_missing_folders_are_created(tmp_path, capsys):
    out = tmp_path / "new" / "deeper" / "m.csv"
    status, _, err = run(["map", "--phi-deg", 0, "--grid", 5, "--out", out], capsys)
    assert status == 0, err
    assert out.read_text().startswith("x,y,phi_deg")


def test_map_zarr_larger_than_the_disk_refused(tmp_path, capsys):
    assert_error(run(["map", "--phi-deg", 0, "--grid", 10_000_000, "--out", tmp_path / "m.zarr"], capsys),
                 "map", "--grid", "disk")
    assert not (tmp_path / "m.zarr").exists()


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes anywhere")
def test_unwritable_folder(tmp_path, capsys):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        assert_error(run(["map", "--phi-deg", 0, "--grid", 5, "--out", locked / "m.nc"], capsys), "map",
                     "--out", "not writable")
    finally:
        locked.chmod(0o700)


# ----------------------------------------------------------------------------------- warnings and --quiet
def test_orientation_in_radians_warns_once_and_quiet_silences(capsys):
    status, out, err = run(["ik", "--pose", 10, -5, 0.5236], capsys)
    assert status == 0 and out
    (line,) = warnings_of(err)
    assert line.startswith("pmaccuracy ik: warning:") and "0.5236" in line and "radians" in line
    for argv in (["ik", "--pose", 10, -5, 0.5236, "--quiet"], ["--quiet", "ik", "--pose", 10, -5, 0.5236]):
        status, out, err = run(argv, capsys)
        assert status == 0 and out and err == ""


@pytest.mark.parametrize("phi", [0, 1, 1.5, 2, 3, 10, 30, -30, 0.5, 45])
def test_plain_degree_orientations_do_not_warn(phi, capsys):
    status, _, err = run(["ik", "--pose", 0, 0, phi], capsys)
    assert status == 0 and warnings_of(err) == []


# ----------------------------------------------------------------------------------- the plausibility rules
@pytest.mark.parametrize("value", [math.pi / 12, math.pi / 6, 0.5236, 0.7854, 1.0472, 1.5708, 3.1416, -0.5236,
                                   2 * math.pi, math.pi / 18, 0.3927])
def test_radian_looking_values(value):
    from pmaccuracy.model.plausibility import looks_like_radians

    assert looks_like_radians(value)


@pytest.mark.parametrize("value", [0, 0.5, 1, 1.5, 2, 2.5, 3, 5, 10, 15, 30, 45, 90, -30, 0.52, 1.57, 7.0, 0.25])
def test_degree_values_do_not_look_like_radians(value):
    from pmaccuracy.model.plausibility import looks_like_radians

    assert not looks_like_radians(value)


def test_clearance_and_linearity_thresholds():
    from pmaccuracy.model.plausibility import MAX_ANGLE_RAD, MAX_LENGTH_MM, clearance_messages, linearity_messages

    assert clearance_messages({"a": (MAX_LENGTH_MM, "mm"), "b": (MAX_ANGLE_RAD, "rad"), "c": (50.0, "block")}) == []
    out = clearance_messages({"a": (1.001, "mm"), "b": (0.0688, "rad"), "c": (0.05, "block"), "d": (2e3, "block")})
    assert [m.split(" ")[0] for m in out] == ["a", "b", "c", "d"]
    assert linearity_messages(np.array([0.2, 1.0])) == []
    (msg,) = linearity_messages(np.array([0.2, 15.0, np.nan]), np.array([[0, 0, 0], [1, 2, 1.5], [0, 0, 0]]))
    assert "15 deg" in msg and "x = 1 mm" in msg and "1 of 3" in msg


def test_library_issues_plausibility_warnings(tmp_path):
    from pmaccuracy.model.plausibility import PlausibilityWarning
    from pmaccuracy.io.resolve import load_clearances
    from pmaccuracy.model.manipulator import Manipulator

    path = tmp_path / "c.toml"
    path.write_text("[[legs]]\nrevolute_radial = 39\n[[legs]]\n[[legs]]\n")
    with pytest.warns(PlausibilityWarning, match=r"legs\[1\]\.revolute_radial = 39 mm"):
        load_clearances(path, Manipulator.preset("aalborg_3ppr"))
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_clearances("case2", Manipulator.preset("aalborg_3ppr"))  # the presets are plausible


def test_failing_command_prints_only_its_error(tmp_path, capsys):
    path = tmp_path / "c.toml"
    path.write_text("[[legs]]\nbearing_angle = 0.0688\n[[legs]]\n[[legs]]\n")
    status, out, err = run(["bounds", "--pose", 1000, 0, 0, "--clearances", path], capsys)  # outside: an error
    assert status == 2 and len(err.splitlines()) == 1 and ": error: " in err
    status, out, err = run(["bounds", "--pose", 0, 0, 0, "--clearances", path], capsys)
    assert status == 0 and "bearing_angle" in err and "warning" in err


def test_debug_variable_reraises_internal_errors(monkeypatch, capsys):
    import pmaccuracy.cli.kinematics_cmd as kc

    def boom(args):
        raise RuntimeError("a bug")

    monkeypatch.setattr(kc, "run_ik", boom)
    monkeypatch.setattr("pmaccuracy.cli.kinematics_cmd.run_ik", boom)
    from pmaccuracy.cli import build_parser  # noqa: F401  (the parser binds run_ik at registration)

    status, out, err = run(["ik", "--pose", 0, 0, 0], capsys)
    assert status == 2 and "internal error (RuntimeError: a bug)" in err and len(err.splitlines()) == 1
    monkeypatch.setenv("PMACCURACY_DEBUG", "1")
    with pytest.raises(RuntimeError):
        main(["ik", "--pose", "0", "0", "0"])


def test_robot_file_angles_in_radians_warn(tmp_path, capsys):
    import tomli_w

    from pmaccuracy.model.manipulator import Manipulator

    data = Manipulator.preset("aalborg_3ppr").to_dict()
    data["legs"][0]["psi_deg"] = 0.5236
    path = tmp_path / "robot.toml"
    path.write_text(tomli_w.dumps(data))
    status, out, err = run(["ik", "--robot", path, "--pose", 0, 0, 0], capsys)
    (line,) = warnings_of(err)
    assert status == 0 and "legs[1].psi_deg = 0.5236" in line and "radians" in line
    data["legs"][0]["psi_deg"] = 30.0
    path.write_text(tomli_w.dumps(data))
    status, out, err = run(["ik", "--robot", path, "--pose", 0, 0, 0], capsys)
    assert status == 0 and err == ""


@pytest.mark.parametrize("argv, needle", [
    (["statistics", "--pose", 0, 0, 0, "--threshold", "dp=39", "--samples", 50], "--threshold dp=39"),
    (["experiment", "simulate", "--grid", 2, "--noise-mm", 10], "--noise-mm 10"),
])
def test_small_options_in_wrong_units_warn(tmp_path, argv, needle, capsys):
    if "simulate" in argv:
        argv = [*argv, "--out", tmp_path / "s.csv"]
    status, out, err = run(argv, capsys)
    (line,) = warnings_of(err)
    assert status == 0 and needle in line and "wrong unit" in line
