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

from pmaccuracy.cli import main
from pmaccuracy.errors import ConfigError
from pmaccuracy.io.resolve import default_clearances
from pmaccuracy.model import _tomlio

#: robot -> the preset the rule names for it (the issue's statement of the rule)
EXPECTED = {"aalborg_3ppr": "case1", "symmetric_3ppr": "case1", "symmetric_3rrr": "rrr_typical",
            "symmetric_3prr": "prr_typical", "symmetric_3rpr": "rpr_typical"}
NOTE = re.compile(r"^clearances: (\S+) \(default\)$")


def run(argv, capsys):
    """``(status, stdout, stderr)`` of ``pmaccuracy ARGV`` in-process (argparse's exits count too)."""
    try:
        status = main([str(a) for a in argv])
    except SystemExit as exc:
        status = exc.code
    out = capsys.readouterr()
    return status, out.out, out.err


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
