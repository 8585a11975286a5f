"""Issue 34, item 2: every bad file or option of the new commands is named, and unit slips are warned.

Each case runs ``pmaccuracy.cli.main`` in-process and checks the one line on stderr: exit 2, no traceback,
no "internal error", the file (and line) or the option at fault named; a plausibility warning is one line
``pmaccuracy CMD: warning: ...`` and the command still succeeds. Each test failed before its fix (the
message it checks named nothing, or the wrong option, or there was no warning).
"""

from __future__ import annotations

import json
import os

import pytest

from pmaccuracy.accuracy.calibration.data import write_calibration_csv
from pmaccuracy.accuracy.calibration.identify import identification_to_dict
from pmaccuracy.accuracy.calibration.parameters import error_parameters
from pmaccuracy.accuracy.calibration.simulate import simulate_calibration
from pmaccuracy.model.manipulator import Manipulator
from conftest import run_cli

#: A cell one character longer than the csv module's default field limit (131 072).
HUGE = "a" * 131_073


def run(argv, capsys):
    """(status, stdout, stderr); an escaping exception is status "exception" with its traceback."""
    return run_cli(argv, capsys, catch=True)


def refused(argv, capsys, *needles, absent=()):
    """Run ``argv``: exit 2 with one stderr line containing every needle and none of ``absent``; the line."""
    status, _, err = run(argv, capsys)
    lines = [line for line in err.splitlines() if ": warning: " not in line]
    assert status == 2, (status, err)
    assert len(lines) == 1, err
    line = lines[0]
    assert "Traceback" not in err and "internal error" not in line, err
    for needle in needles:
        assert str(needle) in line, (needle, line)
    for word in absent:
        assert word not in line, (word, line)
    return line


def warned(argv, capsys, *needles):
    """Run ``argv``: exit 0 with one warning line containing every needle; the line."""
    status, _, err = run(argv, capsys)
    assert status == 0, err
    hits = [line for line in err.splitlines() if ": warning: " in line and all(str(n) in line for n in needles)]
    assert len(hits) == 1, err
    return hits[0]


@pytest.fixture(scope="module")
def calibration(tmp_path_factory):
    """A simulated calibration CSV of the default robot and its identification JSON (as calibrate identify
    --out writes it)."""
    pv = error_parameters(Manipulator.preset("aalborg_3ppr"))
    ex = simulate_calibration(pv, 30, seed=3)
    folder = tmp_path_factory.mktemp("calibration")
    data = folder / "data.csv"
    write_calibration_csv(pv.robot, ex.data.commands, ex.data.poses, data, sigmas=ex.data.sigmas)
    ident = folder / "ident.json"
    ident.write_text(json.dumps(identification_to_dict(ex.identification)), encoding="utf-8")
    return data, ident


LATIN1 = "point,q1,q2,q3,x,y,phi_deg\n1,0,0,0,1,1,0\n# mesur\xe9 \xe0 20 \xb0C\n".encode("latin-1")
BINARY = bytes(range(256)) * 8


def _commands(kind, path, calibration, tmp_path):
    data, ident = calibration
    return {
        "calibration CSV": ["calibrate", "identify", "--data", path],
        "identification JSON": ["calibrate", "compensate", "--identification", path, "--pose", 0, 0, 0],
        "identification JSON (report)": ["calibrate", "report", "--data", data, "--identification", path,
                                         "--out", tmp_path / "r.html"],
        "polygon CSV": ["worst", "--polygon", path, "--phi-deg", 0, 0],
        "robot TOML": ["bounds", "--robot", path, "--pose", 0, 0, 0],
        "clearance TOML": ["bounds", "--clearances", path, "--pose", 0, 0, 0],
        "tolerance TOML": ["bounds", "--tolerances", path, "--pose", 0, 0, 0],
        "errors TOML": ["calibrate", "simulate", "--errors", path],
        "measurement CSV": ["experiment", "compare", "--measurements", path],
        "poses CSV": ["bounds", "--poses-csv", path],
    }[kind]


KINDS = ["calibration CSV", "identification JSON", "identification JSON (report)", "polygon CSV", "robot TOML",
         "clearance TOML", "tolerance TOML", "errors TOML", "measurement CSV", "poses CSV"]


@pytest.mark.parametrize("kind", KINDS)
def test_binary_file_is_named(kind, calibration, tmp_path, capsys):
    path = tmp_path / ("bad.csv" if "CSV" in kind else "bad.json" if "JSON" in kind else "bad.toml")
    path.write_bytes(BINARY)
    refused(_commands(kind, path, calibration, tmp_path), capsys, path, "binary")


@pytest.mark.parametrize("kind", KINDS)
def test_latin1_file_names_file_and_line(kind, calibration, tmp_path, capsys):
    path = tmp_path / ("latin.csv" if "CSV" in kind else "latin.json" if "JSON" in kind else "latin.toml")
    path.write_bytes(LATIN1)
    refused(_commands(kind, path, calibration, tmp_path), capsys, path, "line 3", "UTF-8")


def test_calibration_csv_with_a_huge_cell_in_an_ignored_column(calibration, tmp_path, capsys):
    data, _ = calibration
    lines = data.read_text().splitlines()
    lines[0] += ",comment"
    lines[1:] = [line + ",ok" for line in lines[1:]]
    lines[4] = lines[4][:-2] + HUGE
    path = tmp_path / "huge.csv"
    path.write_text("\n".join(lines) + "\n")
    refused(["calibrate", "identify", "--data", path], capsys, path, "line 5", absent=("field limit",))


def test_measurement_csv_with_a_huge_cell_names_the_line(tmp_path, capsys):
    path = tmp_path / "m.csv"
    path.write_text("point,x_nom,y_nom,phi_nom_deg,push,x,y,phi_deg\nA,0,0,0,+x,0.2,0.01,0.05\n"
                    f"A,0,0,0,-x,{HUGE},0,0\n")
    refused(["experiment", "compare", "--measurements", path], capsys, path, "line 3")


def test_simulate_with_errors_no_pose_reaches_names_the_file(tmp_path, capsys):
    path = tmp_path / "errors.toml"
    path.write_text('"leg1.base.x" = 200.0\n')
    refused(["calibrate", "simulate", "--robot", "symmetric_3rpr", "--errors", path], capsys, path,
            "planned poses", "too large")


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs /proc (a folder where nothing can be created)")
def test_map_out_in_a_folder_that_cannot_be_created_blames_out(capsys):
    refused(["map", "--out", "/proc/pmaccuracy-sub/m.nc", "--phi-deg", 0], capsys, "--out", "/proc/pmaccuracy-sub",
            absent=("--grid", "free"))


def test_plan_without_candidates_names_phi_range(capsys):
    refused(["calibrate", "plan", "--phi-range-deg", 80, 89], capsys, "--phi-range-deg", "no candidate pose")


def test_report_of_too_few_points_blames_data(calibration, tmp_path, capsys):
    data, ident = calibration
    few = tmp_path / "few.csv"
    few.write_text("\n".join(data.read_text().splitlines()[:5]) + "\n")
    refused(["calibrate", "report", "--data", few, "--identification", ident, "--out", tmp_path / "r.html"], capsys,
            "--data", few, absent=("--poses",))


def test_identify_frame_in_radians_is_warned(calibration, capsys):
    data, _ = calibration
    warned(["calibrate", "identify", "--data", data, "--frame", 0, 0, 1.5708], capsys, "--frame", "radians")


def test_plan_phi_range_in_radians_is_warned(capsys):
    warned(["calibrate", "plan", "--poses", 12, "--phi-range-deg", -0.3491, 0.3491], capsys,
           "--phi-range-deg", "radians")


@pytest.mark.parametrize("gravity", [1.57, 6.28])
def test_gravity_in_radians_is_warned(gravity, capsys):
    warned(["load", "--pose", 0, 0, 0, "--mass", 1, "--gravity-deg", gravity], capsys, "--gravity-deg", "radians")


@pytest.mark.parametrize("gravity", [-90, 1.5, 2, 45])
def test_gravity_in_degrees_is_not_warned(gravity, capsys):
    status, _, err = run(["load", "--pose", 0, 0, 0, "--mass", 1, "--gravity-deg", gravity], capsys)
    assert status == 0, err
    assert "radians" not in err, err


def test_revolute_actuator_error_in_degrees_is_warned(tmp_path, capsys):
    path = tmp_path / "rrr.toml"
    joints = "joints = [{{ actuator = {a} }}, {{ radial = 0.01 }}, {{ radial = 0.01 }}]"
    path.write_text("name = \"slip\"\n" + "".join(f"[[legs]]\n{joints.format(a=a)}\n" for a in (0.05, 5e-4, 5e-4)))
    line = warned(["bounds", "--robot", "symmetric_3rrr", "--clearances", path, "--pose", 0, 0, 0], capsys,
                  "legs[1].joints[1].actuator", "rad")
    assert "legs[2]" not in line


def test_revolute_actuator_error_in_radians_is_not_warned(tmp_path, capsys):
    path = tmp_path / "rrr.toml"
    path.write_text("name = \"ok\"\n" + "[[legs]]\njoints = [{ actuator = 0.0005 }, { radial = 0.01 }, "
                    "{ radial = 0.01 }]\n" * 3)
    status, _, err = run(["bounds", "--robot", "symmetric_3rrr", "--clearances", path, "--pose", 0, 0, 0], capsys)
    assert status == 0 and "actuator" not in err, err


@pytest.mark.parametrize("bad", ["binary", "latin1", "huge"])
def test_a_failing_command_leaves_an_existing_output_untouched(bad, calibration, tmp_path, capsys):
    data, _ = calibration
    path = tmp_path / "data.csv"
    path.write_bytes({"binary": BINARY, "latin1": LATIN1, "huge": data.read_bytes() + HUGE.encode() + b"\n"}[bad])
    out = tmp_path / "ident.json"
    out.write_text("keep me")
    refused(["calibrate", "identify", "--data", path, "--out", out], capsys, path)
    assert out.read_text() == "keep me"
