"""Clearances under load (issue 24, deliverable 7): bad input to ``load``, ``preload`` and the pushes.

Forces that look like kN typed as N warn (one line on the command line, a PlausibilityWarning in Python);
a zero wrench where a direction is needed, negative masses or push forces and non-finite options exit 2 with
one line naming the option (the library raises ConfigError).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from pmaccuracy.accuracy.loads import Load, design_preload
from pmaccuracy.cli import main
from pmaccuracy.errors import ConfigError
from pmaccuracy.experiment.virtual_rig import predict_pushes
from pmaccuracy.model.plausibility import MAX_FORCE_N, PlausibilityWarning

# explicit clearances: without them a run also notes the default it used on stderr
POSE = ["--clearances", "case2", "--pose", "0", "0", "0"]


def run(argv: list[str]) -> int:
    """``main(argv)``'s exit status, also when argparse exits (SystemExit)."""
    try:
        return main(argv)
    except SystemExit as exc:
        return exc.code


@pytest.mark.parametrize("argv, option", [
    (["load", *POSE, "--fx", "1", "--gravity-deg", "nan"], "--gravity-deg"),
    (["load", *POSE, "--fx", "inf"], "--fx"),
    (["load", *POSE, "--mass", "-2"], "--mass"),
    (["load", *POSE, "--fx", "1", "--com", "nan", "0"], "--com"),
    (["load", *POSE, "--fx", "1", "--unloaded-below", "-1"], "--unloaded-below"),
    (["load", *POSE], "--fx"),                                          # zero wrench: no direction
    (["load", *POSE, "--mass", "0", "--gravity-deg", "0"], "--fx"),
    (["preload", *POSE], "--fx"),                                       # all-zero box
    (["preload", *POSE, "--fy", "3", "3"], "--fx"),                     # a single wrench, no range
    (["preload", *POSE, "--m", "5", "-5"], "--m"),
    (["preload", *POSE, "--fx", "nan", "1"], "--fx"),
    (["experiment", "simulate", "--push-n", "0"], "--push-n"),
    (["experiment", "simulate", "--push-n", "-3"], "--push-n"),
    (["experiment", "simulate", "--push-n", "nan"], "--push-n"),
])
def test_cli_refuses_with_one_line_naming_the_option(argv, option, capsys, tmp_path):
    if argv[0] == "experiment":
        argv = [*argv, "--out", str(tmp_path / "sim.csv")]
    assert run(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and option in err[0] and "Traceback" not in err[0], err
    assert not (tmp_path / "sim.csv").exists()


@pytest.mark.parametrize("argv, option", [
    (["load", *POSE, "--fx", "2e4"], "--fx"),
    (["load", *POSE, "--fy", "-3e4"], "--fy"),
    (["load", *POSE, "--mass", "2000"], "--mass"),                     # 19.6 kN of weight
    (["load", *POSE, "--fx", "1", "--m", "1e9"], "--m"),               # 1e9 N mm over a 30 mm robot
    (["load", *POSE, "--mass", "1", "--gravity-deg", "-1.5708"], "--gravity-deg"),     # -90 deg in radians
    (["preload", *POSE, "--fx", "-5e4", "5e4"], "--fx"),
    (["load", "--map", "--grid", "3", "--out", "{tmp}/m.nc", "--fx", "2e4", "--clearances", "case2"], "--fx"),
])
def test_cli_warns_once_for_a_force_in_the_wrong_unit_and_still_answers(argv, option, capsys, tmp_path):
    assert main([a.replace("{tmp}", str(tmp_path)) for a in argv]) == 0
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and "warning" in err[0] and option in err[0], err
    assert captured.out.strip()


def test_plausible_forces_do_not_warn(capsys):
    assert main(["load", *POSE, "--fx", "9000", "--m", "-2e5", "--mass", "50", "--gravity-deg", "-90"]) == 0
    assert main(["preload", *POSE, "--fx", "-900", "900", "--m", "-2e4", "2e4"]) == 0
    assert capsys.readouterr().err == ""


def test_push_force_in_the_wrong_unit_warns(capsys, tmp_path):
    assert main(["experiment", "simulate", "--grid", "3", "--push-n", "5e4", "--clearances", "case1", "--out",
                 str(tmp_path / "s.csv")]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--push-n" in err[0] and "kN" in err[0]


def test_library_warns_and_refuses():
    length = 300.0
    with warnings.catch_warnings():
        warnings.simplefilter("error", PlausibilityWarning)
        Load(fx=0.99 * MAX_FORCE_N, m=0.99 * MAX_FORCE_N * length).check(length_mm=length)     # no warning
        with pytest.raises(PlausibilityWarning, match="kN"):
            Load(fx=0.8 * MAX_FORCE_N, fy=0.8 * MAX_FORCE_N).check()     # |f| = 1.13 * the bound
        with pytest.raises(PlausibilityWarning, match="moment"):
            Load(m=1.01 * MAX_FORCE_N * length).check(length_mm=length)
        with pytest.raises(PlausibilityWarning, match="weight"):
            Load(mass=1.1 * MAX_FORCE_N / 9.80665).check()
    with pytest.raises(ConfigError, match="zero wrench"):
        design_preload("aalborg_3ppr", "case2", [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    with pytest.raises(ConfigError, match="half-widths >= 0"):
        design_preload("aalborg_3ppr", "case2", [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [-1.0, 0.0, 0.0])
    for push in (0.0, -1.0, float("nan")):
        with pytest.raises(ConfigError, match="push_n"):
            predict_pushes("aalborg_3ppr", "case2", np.zeros((1, 3)), push)
    with pytest.raises(ConfigError, match="gravity_deg"):
        Load(mass=1.0, gravity_deg=float("nan"))
