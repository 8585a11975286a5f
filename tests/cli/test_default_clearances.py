"""One default clearance rule for every command (issue 33, item 3).

Without ``--clearances`` every command that takes clearances uses
:func:`pmaccuracy.io.resolve.default_clearances` of its robot and says so once on
stderr, ``clearances: NAME (default)``. Each command is run twice in-process,
without ``--clearances`` and with ``--clearances NAME`` for the name it printed: the
two outputs must agree (the default really is that preset), and every command must
print the same name for the same robot. The expected names come from the rule's
statement (the paper's case 1 for a 3-PPR, the architecture's typical preset
otherwise), not from a previous run.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import tomli_w

from pmaccuracy.errors import ConfigError
from pmaccuracy.io.resolve import default_clearances
from pmaccuracy.model import _tomlio
from conftest import run_cli

#: robot -> the preset the rule names for it (the issue's statement of the rule)
EXPECTED = {"aalborg_3ppr": "case1", "symmetric_3ppr": "case1", "symmetric_3rrr": "rrr_typical",
            "symmetric_3prr": "prr_typical", "symmetric_3rpr": "rpr_typical"}
NOTE = re.compile(r"^clearances: (\S+) \(default\)$")


def run(argv, capsys):
    return run_cli(argv, capsys)


def user_file(robot: str, folder: Path) -> str:
    """The preset's robot file copied to ``folder/my_<robot>.toml``: a user's own file of that architecture."""
    data, _ = _tomlio.read_spec(robot, kind="robot", folder="robots")
    target = folder / f"my_{robot}.toml"
    target.write_bytes(tomli_w.dumps(data).encode())
    return str(target)


def commands(tmp: Path) -> dict[str, list[str]]:
    """Short runs of every command that takes clearances (the robot is added by the test)."""
    return {
        "bounds": ["bounds", "--pose", 0, 0, 0],
        "map": ["map", "--phi-deg", 0, "--grid", 3, "--out", tmp / "m.csv", "--format", "json"],
        "statistics": ["statistics", "--pose", 0, 0, 0, "--samples", 200, "--format", "json"],
        "load": ["load", "--pose", 0, 0, 0, "--fx", 1, "--format", "json"],
        "preload": ["preload", "--pose", 0, 0, 0, "--fx", -1, 1, "--format", "json"],
        "worst": ["worst", "--phi-deg", 0, 0, "--disc", 0, 0, 1, "--grid", 5, 1, "--format", "csv"],
        "synthesize": ["synthesize", "--phi-deg", 0, 0, "--disc", 0, 0, 1, "--target", "dp=0.2", "--format", "csv"],
        "experiment simulate": ["experiment", "simulate", "--grid", 5, "--out", tmp / "sim.csv", "--format", "csv"],
    }



@pytest.mark.parametrize("robot", sorted(EXPECTED))
def test_every_command_uses_and_names_the_same_default(robot, capsys, tmp_path):
    spec = user_file(robot, tmp_path) if robot == "symmetric_3rrr" else robot   # a user's file too
    assert default_clearances(spec) == EXPECTED[robot]
    named = {}
    for name, argv in commands(tmp_path).items():
        status, out, err = run([*argv, "--robot", spec], capsys)
        assert status == 0, (name, err)
        notes = [line for line in err.splitlines() if line.startswith("clearances:")]
        assert len(notes) == 1 and NOTE.match(notes[0]), (name, err)
        named[name] = NOTE.match(notes[0]).group(1)
        # the same run with that preset given explicitly: the same output, and no note
        status2, out2, err2 = run([*argv, "--robot", spec, "--clearances", named[name]], capsys)
        assert status2 == 0 and "clearances:" not in err2, (name, err2)
        assert out == out2, name
    assert set(named.values()) == {EXPECTED[robot]}, named


def test_compare_designs_names_each_robots_default(capsys):
    status, out, err = run(["compare-designs", "--robot", "symmetric_3rrr", "--robot", "aalborg_3ppr", "--phi-deg", 0,
                            "--grid", 5, "--format", "json"], capsys)
    assert status == 0, err
    assert "clearances: symmetric_3rrr: rrr_typical, aalborg_3ppr: case1 (default)" in err.splitlines()
    explicit = run(["compare-designs", "--robot", "symmetric_3rrr", "--robot", "aalborg_3ppr", "--phi-deg", 0,
                    "--grid", 5, "--format", "json", "--clearances", "rrr_typical", "--clearances", "case1"], capsys)
    assert explicit[0] == 0 and explicit[1] == out


def test_serial_arm_default_in_bounds_and_load(capsys):
    for argv in (["bounds", "--joints", 10, 20, 30], ["load", "--joints", 10, 20, 30, "--fy", -5]):
        status, out, err = run([*argv, "--robot", "planar_3r_arm"], capsys)
        assert status == 0 and err.splitlines() == ["clearances: arm_typical (default)"], err
        assert run([*argv, "--robot", "planar_3r_arm", "--clearances", "arm_typical"], capsys)[1] == out


def test_quiet_and_failing_runs_print_no_note(capsys):
    status, out, err = run(["bounds", "--robot", "symmetric_3rpr", "--pose", 0, 0, 0, "--quiet"], capsys)
    assert status == 0 and out and err == ""
    status, out, err = run(["bounds", "--robot", "symmetric_3rpr", "--pose", 1e4, 0, 0], capsys)
    assert status == 2 and len(err.splitlines()) == 1 and "clearances:" not in err


def test_a_wrong_format_suggests_only_presets_of_the_architecture(capsys, tmp_path):
    for robot, valid in (("symmetric_3rrr", "rrr_typical"), ("symmetric_3prr", "prr_typical"),
                         ("symmetric_3rpr", "rpr_typical")):
        status, _, err = run(["bounds", "--robot", user_file(robot, tmp_path), "--clearances", "case1", "--pose", 0, 0,
                              0], capsys)
        assert status == 2 and len(err.splitlines()) == 1, err
        others = {"rrr_typical", "prr_typical", "rpr_typical"} - {valid}
        assert valid in err and not any(o in err for o in others), err
        # the suggested joints are those of the valid preset: that preset passes on the same robot
        assert run(["bounds", "--robot", robot, "--clearances", valid, "--pose", 0, 0, 0], capsys)[0] == 0


def test_mixed_legs_have_no_default(tmp_path):
    from dataclasses import replace

    from pmaccuracy.kinematics import resolve_robot

    robot = resolve_robot(user_file("symmetric_3rpr", tmp_path))

    other = resolve_robot("symmetric_3rrr")
    mixed_robot = replace(robot, legs=(robot.legs[0], other.legs[1], robot.legs[2]))
    assert mixed_robot.architecture == "chain"
    with pytest.raises(ConfigError, match="per-joint clearance file") as info:
        default_clearances(mixed_robot)
    assert info.value.key == "clearances"


@pytest.mark.parametrize("robot", ["symmetric_3rrr", "symmetric_3prr", "symmetric_3rpr"])
def test_reproduce_on_another_architecture_uses_the_default(robot, capsys, monkeypatch, tmp_path):
    """``reproduce --robot R`` (no --clearances) writes R's accuracy report with R's default; the report itself is
    replaced by a stub that records what it was given (the report is tested in tests/report)."""
    import pmaccuracy.report.accuracy_report as report

    given = {}

    def stub(out, robot_obj, clearances, grid, **kwargs):
        given["clearances"] = clearances
        return {"elapsed_s": 0, "clearances": clearances}

    monkeypatch.setattr(report, "accuracy_report", stub)
    status, out, err = run(["reproduce", "--robot", robot, "--out", tmp_path / "out", "--grid", 5], capsys)
    assert status == 0, err
    assert given["clearances"] == EXPECTED[robot] == default_clearances(robot)
    assert err.splitlines() == [f"clearances: {EXPECTED[robot]} (default)"]


@pytest.mark.parametrize("robot", [pytest.param("symmetric_3rrr", marks=pytest.mark.slow), "aalborg_3ppr"])
def test_calibrate_steps_name_the_same_default_as_bounds(robot, capsys, tmp_path):
    """Every calibrate step that takes clearances (simulate, identify, compensate, report from a simulation and
    from measurements) uses the default that bounds names for the same robot, says it once on stderr, and gives
    the output of the same run with that preset given explicitly."""
    status, _, err = run(["bounds", "--robot", robot, "--pose", 0, 0, 0], capsys)
    assert status == 0 and err.splitlines() == [f"clearances: {EXPECTED[robot]} (default)"], err
    default = NOTE.match(err.splitlines()[0]).group(1)
    data, ident = tmp_path / "data.csv", tmp_path / "id.json"
    status, _, err = run(["calibrate", "simulate", "--robot", robot, "--poses", 12, "--clearances", "none",
                          "--data-out", data], capsys)
    assert status == 0 and "clearances:" not in err, err
    steps = {
        "simulate": ["calibrate", "simulate", "--robot", robot, "--poses", 12, "--format", "json"],
        "identify": ["calibrate", "identify", "--robot", robot, "--data", data, "--format", "json"],
        "compensate": ["calibrate", "compensate", "--identification", ident, "--pose", 0, 0, 0, "--format", "json"],
        "report (simulation)": ["calibrate", "report", "--robot", robot, "--poses", 12, "--out", tmp_path / "s.html"],
        "report (measured)": ["calibrate", "report", "--data", data, "--identification", ident,
                              "--out", tmp_path / "m.html"],
    }
    for name, argv in steps.items():
        if name == "compensate":   # the identification of the same data, written by identify
            assert run(["calibrate", "identify", "--robot", robot, "--data", data, "--out", ident], capsys)[0] == 0
        status, out, err = run(argv, capsys)
        assert status == 0, (name, err)
        assert [ln for ln in err.splitlines() if ln.startswith("clearances:")] == \
            [f"clearances: {default} (default)"], (name, err)
        status2, out2, err2 = run([*argv, "--clearances", default], capsys)
        assert status2 == 0 and "clearances:" not in err2, (name, err2)
        assert out == out2, name


@pytest.mark.parametrize("robot", ["symmetric_3rrr", "symmetric_3rpr", "symmetric_3prr", "aalborg_3ppr",
                                   "planar_3r_arm"])
def test_clearances_none_fits_every_architecture(robot, capsys):
    """The preset ``none`` is read as the all-zero set of the robot's own architecture (not the 3-PPR file refused
    elsewhere): zero bounds where the default gives nonzero ones, and calibrate simulate runs without a clearance
    floor and without a default note."""
    from pmaccuracy.io.resolve import load_clearances, no_clearances
    from pmaccuracy.model.clearances import ClearanceSet
    from pmaccuracy.model.serial import SerialArm, SerialErrorSources, load_serial_sources
    from pmaccuracy.model.sources import ErrorSources, JointErrors

    serial = robot == "planar_3r_arm"
    sources = load_serial_sources("none", SerialArm.load(robot)) if serial else load_clearances("none", robot)
    assert sources == no_clearances(robot) and sources.name == "none"
    if serial:
        assert isinstance(sources, SerialErrorSources) and sources.joints == (JointErrors(),) * 3
    elif robot == "aalborg_3ppr":
        assert isinstance(sources, ClearanceSet) and not sources.bearing_angle.any() and \
            not sources.guide_lateral.any() and not sources.revolute_radial.any()
    else:
        assert isinstance(sources, ErrorSources)
        assert all(joint == JointErrors() for leg in sources.legs for joint in leg)
    where = ["--joints", 10, 20, 30] if serial else ["--pose", 0, 0, 0]
    columns = ("dx_max", "dy_max", "dphi_max_deg", "dp_max")
    for given, zero in ((["--clearances", "none"], True), ([], False)):
        status, out, err = run(["bounds", "--robot", robot, *where, "--format", "json", *given], capsys)
        assert status == 0, err
        import json
        row = json.loads(out)[0]
        assert all((row[c] == 0) == zero for c in columns), (given, row)
    status, out, err = run(["calibrate", "simulate", "--robot", robot, "--poses", 12, "--clearances", "none"], capsys)
    assert status == 0 and "clearances:" not in err, err
    assert "floor_dp_max_mm" not in out and "max_error_after_mm" in out
