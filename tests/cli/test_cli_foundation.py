"""Command line: ``pmaccuracy ik``, ``fk`` and ``workspace`` outputs, and bad input -> exit 2, one line.

Expected numbers are derived by hand from the reference geometry
(docs/guide/default-robot.md); see test_kinematics.py for the derivations.
"""

from __future__ import annotations

import csv
import io
import json
import subprocess
import sys

import numpy as np
import pytest

from conftest import run_cli

L12_HOME = 192.34 - 83.15 - 30 * np.cos(np.radians(30))   # l1 = l2 at the home pose (mm)
L3_HOME = 192.34 - 70.0 - 30.0


def run(argv, capsys):
    return run_cli(argv, capsys)


def assert_one_line_error(code, out, err, *needles):
    assert code == 2
    assert out == ""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    assert "error" in lines[0]
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])


# ----------------------------------------------------------------------------------- ik
def test_ik_json(capsys):
    code, out, err = run(["ik", "--pose", 0, 0, 0, "--pose", 30, 0, 0, "--format", "json"], capsys)
    assert code == 0 and err == ""
    data = json.loads(out)
    assert isinstance(data, list) and len(data) == 2
    assert set(data[0]) == {"x", "y", "phi_deg", "q", "passive", "s", "l", "within_limits"}
    home, outside = data
    assert (home["x"], home["y"], home["phi_deg"]) == (0, 0, 0)
    np.testing.assert_allclose(home["s"], [-15, -15, 0], atol=1e-9)
    np.testing.assert_allclose(home["l"], [L12_HOME, L12_HOME, L3_HOME], atol=1e-9)
    np.testing.assert_allclose(home["q"], home["s"], atol=0)
    # passive joints in chain order: the bearing l_i (mm) and the platform revolute (deg, phi - theta'_i)
    np.testing.assert_allclose([p[0] for p in home["passive"]], home["l"], atol=0)
    np.testing.assert_allclose([p[1] for p in home["passive"]], [0, 180, 90], atol=1e-9)   # wrapped to (-180, 180]
    assert home["within_limits"] is True
    np.testing.assert_allclose(outside["s"], [-15, -15, -30], atol=1e-9)   # x = -s3 at phi = 0
    assert outside["within_limits"] is False


def test_ik_degrees_on_the_command_line(capsys):
    """phi = 30 deg: s1 = y - 30 sin 60, s2 = y - 30 sin 180, s3 = 30 cos(-60) - x."""
    code, out, _ = run(["ik", "--pose", 5, 2, 30, "--format", "json"], capsys)
    assert code == 0
    rec = json.loads(out)[0]
    assert rec["phi_deg"] == pytest.approx(30)
    np.testing.assert_allclose(rec["s"], [2 - 30 * np.sqrt(3) / 2, 2, 15 - 5], atol=1e-9)


def test_ik_csv_file_and_formats(tmp_path, capsys):
    poses = tmp_path / "poses.csv"
    poses.write_text("x,y,phi_deg\n0,0,0\n10,-5,30\n", encoding="utf-8")
    code, out, _ = run(["ik", "--poses-csv", poses, "--format", "csv"], capsys)
    assert code == 0
    rows = list(csv.DictReader(io.StringIO(out)))
    assert len(rows) == 2
    assert {"x", "y", "phi_deg", "s1", "s2", "s3", "l1", "l2", "l3", "within_limits"} <= set(rows[0])
    assert float(rows[0]["s1"]) == pytest.approx(-15)
    code, out, _ = run(["ik", "--pose", 0, 0, 0], capsys)
    assert code == 0
    header, row = out.splitlines()
    assert header.split()[:3] == ["x", "y", "phi_deg"] and "True" in row


# ----------------------------------------------------------------------------------- fk
def test_fk_json_lists_every_assembly_mode(capsys):
    code, out, err = run(["fk", "--joints", -15, -15, 0, "--format", "json"], capsys)
    assert code == 0 and err == ""
    data = json.loads(out)
    assert len(data) == 2
    assert all(set(d) == {"x", "y", "phi_deg", "l", "passive", "working_modes", "within_limits"} for d in data)
    home = min(data, key=lambda d: abs(d["phi_deg"]))
    flipped = max(data, key=lambda d: abs(d["phi_deg"]))
    np.testing.assert_allclose([home["x"], home["y"], home["phi_deg"]], [0, 0, 0], atol=1e-9)
    np.testing.assert_allclose(home["l"], [L12_HOME, L12_HOME, L3_HOME], atol=1e-9)
    assert home["within_limits"] is True
    np.testing.assert_allclose([flipped["x"], flipped["y"], abs(flipped["phi_deg"])], [0, -30, 180], atol=1e-9)
    assert flipped["within_limits"] is False   # l3 = 182.34 mm > 160 mm


def test_fk_refuses_actuator_values_outside_their_range(capsys):
    code, out, err = run(["fk", "--joints", -40, 40, 0, "--format", "json"], capsys)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert "s2=40 mm not in [-40, 10]" in err and "Traceback" not in err


def test_fk_without_assembly_mode_is_an_error(capsys):
    # legs 1 and 2 (parallel bearings) fix y and phi: s1 - s2 = -2 r sin(60 deg) sin(phi) = -51.96 sin(phi) mm,
    # so s1 - s2 = -80 mm would need sin(phi) = 1.54
    code, out, err = run(["fk", "--joints", -40, 40, 0, "--allow-outside", "--format", "json"], capsys)
    assert code == 2 and out == "" and "no assembly mode" in err and len(err.strip().splitlines()) == 1


# ----------------------------------------------------------------------------------- workspace
def test_workspace_json_phi0(capsys):
    code, out, err = run(["workspace", "--phi-deg", 0, "--format", "json"], capsys)
    assert code == 0 and err == ""
    data = json.loads(out)
    assert set(data) == {"robot", "architecture", "phi_deg", "area", "bounds", "polygon"}
    assert data["phi_deg"] == 0
    assert data["area"] == pytest.approx(2500, abs=1e-6)
    np.testing.assert_allclose(data["bounds"]["x"], [-25, 25], atol=1e-9)
    np.testing.assert_allclose(data["bounds"]["y"], [-25, 25], atol=1e-9)
    assert np.array(data["polygon"]).shape == (4, 2)


def test_workspace_json_phi30_and_robot_option(capsys):
    code, out, _ = run(["workspace", "--robot", "aalborg_3ppr", "--phi-deg", 30, "--format", "json"], capsys)
    assert code == 0
    data = json.loads(out)
    assert data["area"] == pytest.approx(1201, abs=1)
    np.testing.assert_allclose(data["bounds"]["x"], [-10, 40], atol=1e-9)
    np.testing.assert_allclose(data["bounds"]["y"], [-14.02, 10], atol=0.01)
    code, out, _ = run(["workspace", "--robot", "symmetric_3ppr", "--format", "json"], capsys)
    assert json.loads(out)["area"] == pytest.approx(2 * np.sqrt(3) * 625)   # hexagon of apothem 25


def test_workspace_csv_table_and_empty(capsys):
    code, out, _ = run(["workspace", "--phi-deg", -30, "--format", "csv"], capsys)
    assert code == 0
    (row,) = list(csv.DictReader(io.StringIO(out)))
    assert float(row["phi_deg"]) == -30 and float(row["area"]) == pytest.approx(1201, abs=1)
    assert float(row["x_min"]) == pytest.approx(-40) and int(row["n_vertices"]) == 4
    code, out, _ = run(["workspace", "--phi-deg", 90], capsys)   # empty: no crash
    assert code == 0
    header, values = out.splitlines()
    assert dict(zip(header.split(), values.split()))["area"] == "0"
    code, out, _ = run(["workspace", "--phi-deg", 90, "--format", "json"], capsys)
    data = json.loads(out)
    assert data["area"] == 0 and data["polygon"] == [] and data["bounds"]["x"] == [None, None]


def test_workspace_plot(tmp_path, capsys):
    path = tmp_path / "ws.png"
    code, out, _ = run(["workspace", "--phi-deg", 15, "--plot", path, "--format", "json"], capsys)
    assert code == 0 and json.loads(out)["phi_deg"] == 15
    assert path.read_bytes()[:4] == b"\x89PNG"


# ----------------------------------------------------------------------------------- bad input
COMMANDS = {
    "ik": ["ik", "--pose", 0, 0, 0],
    "fk": ["fk", "--joints", -15, -15, 0],
    "workspace": ["workspace", "--phi-deg", 0],
}


@pytest.mark.parametrize("command", list(COMMANDS))
def test_bad_robot_file_exits_2(bad_robot, command, capsys):
    code, out, err = run(COMMANDS[command] + ["--robot", bad_robot.path], capsys)
    needles = [str(bad_robot.path)] + ([bad_robot.case.key] if bad_robot.case.key else [])
    assert_one_line_error(code, out, err, f"pmaccuracy {command}", *needles)


@pytest.mark.parametrize("argv, needles", [
    (["ik", "--robot", "no_such_robot", "--pose", 0, 0, 0], ["no_such_robot", "aalborg_3ppr"]),
    (["ik", "--pose", 0, 0, "nan"], ["--pose", "finite"]),
    (["ik", "--pose", 0, 0, "abc"], ["--pose", "abc"]),
    (["ik", "--pose", 0, 0], ["--pose"]),
    (["ik"], ["--pose", "--poses-csv"]),
    (["ik", "--pose", 0, 0, 0, "--format", "xml"], ["--format", "xml"]),
    (["fk"], ["--joints"]),
    (["fk", "--joints", 1, "inf", 0], ["--joints", "finite"]),
    (["workspace", "--phi-deg", "nan"], ["--phi-deg", "finite"]),
    (["workspace", "--phi-deg", "x"], ["--phi-deg"]),
    (["nonsense"], ["nonsense"]),
])
def test_bad_arguments_exit_2(argv, needles, capsys):
    assert_one_line_error(*run(argv, capsys), *needles)


def test_bad_poses_csv_exit_2(tmp_path, capsys):
    cases = {
        "header.csv": ("x,y,phi\n0,0,0\n", "header"),
        "short.csv": ("x,y,phi_deg\n0,0\n", "line 2"),
        "text.csv": ("x,y,phi_deg\n0,zero,0\n", "line 2"),
        "nan.csv": ("x,y,phi_deg\n0,0,0\n1,nan,0\n", "line 3"),
        "empty.csv": ("x,y,phi_deg\n", "no poses"),
    }
    for name, (text, needle) in cases.items():
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        assert_one_line_error(*run(["ik", "--poses-csv", path], capsys), str(path), needle)
    missing = tmp_path / "missing.csv"
    assert_one_line_error(*run(["ik", "--poses-csv", missing], capsys), str(missing))
    both = ["ik", "--pose", 0, 0, 0, "--poses-csv", tmp_path / "header.csv"]
    assert_one_line_error(*run(both, capsys), "not both")


def test_workspace_plot_creates_missing_folders(tmp_path, capsys):
    target = tmp_path / "no" / "such" / "dir" / "ws.png"
    code, out, err = run(["workspace", "--plot", target], capsys)
    assert code == 0 and err == "" and target.read_bytes()[:4] == b"\x89PNG"


def test_workspace_plot_into_a_file_exits_2(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert_one_line_error(*run(["workspace", "--plot", blocker / "ws.png"], capsys), "ws.png")


# ----------------------------------------------------------------------------------- real process
def _console(*args):
    return subprocess.run([sys.executable, "-m", "pmaccuracy.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=120)


def test_console_script_subprocess(tmp_path):
    done = _console("ik", "--pose", 0, 0, 0, "--format", "json")
    assert done.returncode == 0, done.stderr
    np.testing.assert_allclose(json.loads(done.stdout)[0]["s"], [-15, -15, 0], atol=1e-9)
    done = _console("workspace", "--phi-deg", 30, "--format", "json")
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["area"] == pytest.approx(1201, abs=1)
    bad = tmp_path / "bad.toml"
    bad.write_text("name = 'x'\n[[legs]]\na = -1\n", encoding="utf-8")
    done = _console("workspace", "--robot", bad)
    assert done.returncode == 2 and done.stdout == ""
    assert len(done.stderr.splitlines()) == 1 and "Traceback" not in done.stderr
    assert str(bad) in done.stderr and "legs" in done.stderr


def test_workspace_several_orientations(tmp_path, capsys, monkeypatch):
    """``--phi-deg 0 30 --phi-deg -30`` reports (and draws) every orientation, not only the last (issue 25).
    Areas: the Aalborg robot's 50 x 50 mm square at 0 deg, and its workspace at +-30 deg measured by brute
    force (the share of a fine grid whose inverse kinematics lies in the joint ranges)."""
    from pmaccuracy.kinematics import inverse_kinematics
    from pmaccuracy.kinematics import workspace as ws_module

    g = np.linspace(-60.0, 60.0, 601)
    X, Y = np.meshgrid(g, g)
    cell = (g[1] - g[0]) ** 2

    def brute_area(phi_deg):
        poses = np.stack([X, Y, np.full(X.shape, np.radians(phi_deg))], axis=-1)
        return inverse_kinematics("aalborg_3ppr", poses).within_limits.sum() * cell

    code, out, err = run(["workspace", "--phi-deg", 0, 30, "--phi-deg", -30, "--format", "json"], capsys)
    assert code == 0 and err == ""
    data = json.loads(out)
    assert [d["phi_deg"] for d in data] == [0, 30, -30]
    for d in data:
        assert d["area"] == pytest.approx(brute_area(d["phi_deg"]), rel=0.02)
    assert data[0]["area"] == pytest.approx(2500, abs=1e-6) and data[1]["area"] != pytest.approx(data[0]["area"])
    code, out, _ = run(["workspace", "--phi-deg", 0, 30, "--format", "csv"], capsys)
    assert [float(r["phi_deg"]) for r in csv.DictReader(io.StringIO(out))] == [0, 30]
    code, out, _ = run(["workspace", "--compare", "aalborg_3ppr", "symmetric_3ppr", "--phi-deg", 0, 30,
                        "--format", "json"], capsys)
    assert [(d["robot"], d["phi_deg"]) for d in json.loads(out)] == [
        ("aalborg_3ppr", 0), ("aalborg_3ppr", 30), ("symmetric_3ppr", 0), ("symmetric_3ppr", 30)]
    drawn = {}
    monkeypatch.setattr(ws_module, "save_workspace_figure",
                        lambda robot, path, phis_deg, **kw: drawn.setdefault("phis", phis_deg))
    code, _, _ = run(["workspace", "--phi-deg", 10, "--phi-deg", -20, 10, "--plot", tmp_path / "w.png"], capsys)
    assert code == 0 and drawn["phis"] == (10.0, -20.0)   # exactly the requested ones, each once
