"""The template robot and clearance files (``pmaccuracy template ARCH``): shipped, printed verbatim, loadable,
at home at their home pose, explained key by key, and giving the numbers of the robots they copy."""

from __future__ import annotations

import fnmatch
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

import pmaccuracy as pm
from pmaccuracy.cli import main
from pmaccuracy.errors import ConfigError
from pmaccuracy.io.templates import ARCHITECTURES, template_text

ROOT = Path(__file__).resolve().parents[2]
TEMPLATES = ROOT / "src" / "pmaccuracy" / "data" / "templates"
#: The preset robot and clearances each template copies, and a paper-format preset the 3-PPR's per-joint file
#: must agree with (a different code path: the paper's clearance model, Eq. 16-18).
SAME_AS = {"3-PPR": ("aalborg_3ppr", "all"), "3-RPR": ("symmetric_3rpr", "rpr_typical"),
           "3-RRR": ("symmetric_3rrr", "rrr_typical"), "3-PRR": ("symmetric_3prr", "prr_typical"),
           "serial": ("planar_3r_arm", "arm_typical")}


def files(arch: str) -> tuple[Path, Path]:
    folder = TEMPLATES / arch.lower()
    return folder / "robot.toml", folder / "clearances.toml"


def run(argv, capsys):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def test_every_architecture_has_both_files_and_they_are_packaged():
    from pmaccuracy.io.templates import SPATIAL_ARCHITECTURES

    assert sorted(p.name for p in TEMPLATES.iterdir()) == sorted(a.lower() for a in ARCHITECTURES
                                                                 + SPATIAL_ARCHITECTURES)
    data = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    globs = data["tool"]["setuptools"]["package-data"]["pmaccuracy"]
    for arch in ARCHITECTURES:
        for path in files(arch):
            rel = path.relative_to(ROOT / "src" / "pmaccuracy").as_posix()
            assert any(fnmatch.fnmatch(rel, g) and rel.count("/") == g.count("/") for g in globs), rel


@pytest.mark.parametrize("arch", ARCHITECTURES)
@pytest.mark.parametrize("clearances", [False, True])
def test_printed_text_is_the_shipped_file(arch, clearances, capsys):
    robot, cl = files(arch)
    shipped = (cl if clearances else robot).read_text(encoding="utf-8")
    code, out, err = run(["template", arch.upper() if arch != "serial" else arch]
                         + (["--clearances"] if clearances else []), capsys)
    assert (code, err) == (0, "") and out == shipped
    assert template_text(arch.lower(), clearances) == shipped     # case does not matter


@pytest.mark.parametrize("arch", ARCHITECTURES)
def test_template_loads_and_reaches_its_home_pose(arch):
    robot_path, cl_path = files(arch)
    robot = pm.load_robot(str(robot_path))
    clearances = pm.load_clearances(str(cl_path), robot)
    if arch == "serial":
        assert isinstance(robot, pm.SerialArm)
        q = np.zeros(len(robot.joints))
        assert all(lo <= 0.0 <= hi for lo, hi in (j.range for j in robot.joints))
        pose = robot.forward(q)
        assert np.isclose(pose[0], sum(j.length for j in robot.joints)) and np.isclose(pose[1], 0.0)
        b = pm.max_serial_errors(robot, clearances, q[None, :])
    else:
        assert robot.architecture == arch
        ik = pm.inverse_kinematics(robot, np.zeros((1, 3)))
        assert bool(np.all(ik.within_limits))
        b = pm.max_pose_errors(robot, clearances, np.zeros((1, 3)))
    assert np.all(np.isfinite(b.dp_max)) and np.all(b.dp_max > 0)


@pytest.mark.parametrize("arch", ARCHITECTURES)
def test_bounds_runs_on_the_template_and_agrees_with_the_preset_it_copies(arch, tmp_path, capsys):
    """The CLI as a user runs it on the printed files; the numbers are those of the preset robot and clearances
    the template says it copies (for the 3-PPR, the paper-format preset ``all`` read by the paper's model)."""
    robot_path, cl_path = tmp_path / "robot.toml", tmp_path / "clearances.toml"
    for path, extra in ((robot_path, []), (cl_path, ["--clearances"])):
        code, out, _ = run(["template", arch, *extra], capsys)
        assert code == 0
        path.write_text(out, encoding="utf-8")
    where = ["--joints", "0", "0", "0", "--joints", "30", "-60", "45"] if arch == "serial" else \
        ["--pose", "0", "0", "0", "--pose", "10", "-5", "5"]
    preset_robot, preset_cl = SAME_AS[arch]
    outputs = []
    for robot, cl in ((robot_path, cl_path), (preset_robot, preset_cl)):
        code, out, err = run(["bounds", "--robot", robot, "--clearances", cl, *where, "--format", "csv"], capsys)
        assert (code, err) == (0, ""), err
        outputs.append(np.array([[float(v) for v in line.split(",")] for line in out.splitlines()[1:]]))
    assert outputs[0].shape == (2, 7)
    np.testing.assert_allclose(outputs[0], outputs[1], rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("arch", ARCHITECTURES)
def test_every_key_is_explained(arch):
    """Each key of a template is either commented on its first line or named in a comment."""
    for path in files(arch):
        text = path.read_text(encoding="utf-8")
        comments = " ".join(line.partition("#")[2] for line in text.splitlines())
        seen = set()
        for line in text.splitlines():
            code, _, comment = line.partition("#")
            for key in re.findall(r"(\w+)\s*=", code):
                if key in seen:
                    continue
                seen.add(key)
                assert comment.strip() or re.search(rf"\b{key}\b", comments), f"{path}: {key} is not explained"
        assert seen, path


def test_unknown_architecture_is_one_line_naming_the_valid_ones(capsys):
    code, out, err = run(["template", "3-RRP"], capsys)
    assert code == 2 and out == "" and err.count("\n") == 1
    assert err.startswith("pmaccuracy template: error:") and "3-RRP" in err
    assert all(a in err for a in ARCHITECTURES)
    with pytest.raises(ConfigError, match="3-PPR, 3-RPR, 3-RRR, 3-PRR, serial, 6-UPS, delta"):
        template_text("hexapod")
