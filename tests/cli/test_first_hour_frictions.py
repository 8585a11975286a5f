"""The small frictions a new user met in the first hour with their own robot (issue 33, item 4).

Each test runs the command (in-process, through ``pmaccuracy.cli.main``) or the library call the issue
names and checks the fixed behaviour against an independent value where there is a number: the library
function the command wraps, or the input itself.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re

import numpy as np
import pytest
import tomli_w

from pmaccuracy.errors import ConfigError
from pmaccuracy.model import _tomlio
from conftest import run_cli


def run(argv, capsys):
    return run_cli(argv, capsys)


def robot_file(tmp_path, preset: str, name: str, change=None) -> str:
    """The preset's robot file written to ``tmp_path/name``, after ``change(data)``."""
    data, _ = _tomlio.read_spec(preset, kind="robot", folder="robots")
    if change is not None:
        change(data)
    path = tmp_path / name
    path.write_bytes(tomli_w.dumps(data).encode())
    return str(path)


def test_map_takes_several_values_after_one_phi_deg(capsys, tmp_path):
    one = run(["map", "--clearances", "case1", "--grid", 4, "--out", tmp_path / "a.csv", "--phi-deg", 0, 15], capsys)
    repeated = run(["map", "--clearances", "case1", "--grid", 4, "--out", tmp_path / "b.csv", "--phi-deg", 0,
                    "--phi-deg", 15], capsys)
    assert one[0] == 0 and repeated[0] == 0, (one[2], repeated[2])
    assert one[1] == repeated[1] and (tmp_path / "a.csv").read_text() == (tmp_path / "b.csv").read_text()
    assert {float(r["phi_deg"]) for r in csv.DictReader(io.StringIO((tmp_path / "a.csv").read_text()))} == {0, 15}


def test_a_value_starting_with_a_dash_gets_the_equals_hint(capsys, tmp_path):
    status, out, err = run(["map", "--clearances", "case1", "--phi-deg", 0, "--grid", 3, "--out", tmp_path / "m.csv",
                            "--box", "-5,5,-5,5"], capsys)
    assert status == 2 and out == "" and len(err.splitlines()) == 1, err
    assert "--box=-5,5,-5,5" in err
    # the hinted form works
    status, _, err = run(["map", "--clearances", "case1", "--phi-deg", 0, "--grid", 3, "--out", tmp_path / "m.csv",
                          "--box=-5,5,-5,5"], capsys)
    assert status == 0, err
    # a missing value that does not start with '-' gets no such hint
    status, _, err = run(["worst", "--phi-deg", 0, 0, "--box"], capsys)
    assert status == 2 and "--box=" not in err


def test_a_missing_working_mode_names_file_leg_key_and_values(capsys, tmp_path):
    def drop(data):
        del data["legs"][1]["working_mode"]

    path = robot_file(tmp_path, "symmetric_3rrr", "no_mode.toml", drop)
    status, _, err = run(["bounds", "--robot", path, "--pose", 0, 0, 0], capsys)
    assert status == 2 and len(err.splitlines()) == 1, err
    assert path in err and "legs[2].working_mode" in err and "missing" in err and "1 or -1" in err
    assert "None" not in err


def test_experiment_simulate_refuses_a_grid_with_too_few_points(capsys, tmp_path):
    from pmaccuracy.experiment.virtual_rig import grid_poses

    inside = len(grid_poses("symmetric_3rrr", 0.0, 3))
    assert inside < 3   # the case: a 3 x 3 lattice over the bounding box of a round workspace
    status, out, err = run(["experiment", "simulate", "--robot", "symmetric_3rrr", "--clearances", "rrr_typical",
                            "--grid", 3, "--out", tmp_path / "s.csv"], capsys)
    assert status == 2 and out == "" and len(err.splitlines()) == 1, err
    assert "--grid" in err and f"{inside} of its 9 points" in err
    suggested = int(re.search(r"--grid (\d+) has enough", err).group(1))
    assert len(grid_poses("symmetric_3rrr", 0.0, suggested)) >= 3
    status, out, err = run(["experiment", "simulate", "--robot", "symmetric_3rrr", "--clearances", "rrr_typical",
                            "--grid", suggested, "--out", tmp_path / "s.csv", "--format", "json"], capsys)
    assert status == 0, err
    assert json.loads(out)["points"] == len(grid_poses("symmetric_3rrr", 0.0, suggested))
    status, out, err = run(["experiment", "compare", "--robot", "symmetric_3rrr", "--clearances", "rrr_typical",
                            "--measurements", tmp_path / "s.csv", "--format", "json"], capsys)
    assert status == 0 and all(v is not None for v in json.loads(out)["ssd"].values()), out


def test_compare_designs_says_how_long_a_large_grid_takes_before_computing(capsys, monkeypatch):
    import pmaccuracy.accuracy.designs as designs

    def never(*args, **kwargs):   # the estimate must come first: stop where the computation would start
        raise KeyboardInterrupt

    monkeypatch.setattr(designs, "compare_designs", never)
    status, _, err = run(["compare-designs", "--robot", "aalborg_3ppr", "--robot", "symmetric_3rrr", "--phi-deg", 0,
                          "--grid", 5000], capsys)
    lines = err.splitlines()
    if status == 2:   # a machine without the memory: refused up front, naming --grid
        assert len(lines) == 1 and "--grid" in lines[0] and "memory" in lines[0]
    else:
        assert status == 130 and "--grid 5000" in lines[0] and "min of computing" in lines[0], err


def test_synthesize_prints_units_and_only_the_targets_given(capsys):
    status, out, err = run(["synthesize", "--robot", "symmetric_3rrr", "--clearances", "rrr_typical", "--phi-deg", 0,
                            0, "--disc", 0, 0, 1, "--target", "dp=0.2"], capsys)
    assert status == 0, err
    assert "nan" not in out
    sources, worst = out.strip().split("\n\n")
    rows = [line.split() for line in sources.splitlines()]
    assert rows[0][:2] == ["source", "unit"]
    for row in rows[1:]:   # an actuated revolute's clearance is an angle (rad), the others lengths
        assert row[1] == ("rad" if row[0].endswith("actuator") else "mm"), row
    table = {line.split()[0]: line.split() for line in worst.splitlines()}
    assert table["quantity"][:3] == ["quantity", "unit", "target"]
    assert table["dp"][1:3] == ["mm", "0.2"] and table["dphi_deg"][1:3] == ["deg", "-"]
    assert table["dx"][2] == "-" and table["dy"][2] == "-"


def test_calibrate_identify_names_the_units_of_its_summary(capsys, tmp_path):
    data = tmp_path / "m.csv"
    assert run(["calibrate", "simulate", "--robot", "symmetric_3rpr", "--poses", 20, "--data-out", data], capsys)[0] == 0
    status, out, err = run(["calibrate", "identify", "--robot", "symmetric_3rpr", "--data", data], capsys)
    assert status == 0, err
    header = out.strip().split("\n\n")[1].splitlines()[0].split()
    assert "rms_before_sigmas" in header and "rms_after_sigmas" in header and "fit_rms_position_mm" in header
    assert "rms_before" not in header and "fit_rms_position" not in header


def test_bounds_details_table_is_readable_and_json_complete(capsys):
    argv = ["bounds", "--robot", "symmetric_3rrr", "--clearances", "rrr_typical", "--pose", 0, 0, 0, "--pose", 5, 5,
            0, "--details"]
    status, out, err = run(argv, capsys)
    assert status == 0, err
    assert max(len(line) for line in out.splitlines()) < 100
    status, text, _ = run([*argv, "--format", "json"], capsys)
    records = json.loads(text)
    blocks = out.strip().split("\n\n")
    assert len(blocks) == len(records) == 2
    for block, rec in zip(blocks, records):
        lines = block.splitlines()
        assert [float(v) for v in lines[1].split()] == pytest.approx(
            [rec[k] for k in ("x", "y", "phi_deg", "dx_max", "dy_max", "dphi_max_deg", "dp_max")], rel=1e-5)
        sources = {line.split()[0]: [float(v) for v in line.split()[1:]] for line in lines[4:]}
        assert set(sources) == set(rec["worst"]["dx"])      # every source of the JSON, one row each
        for name, values in sources.items():
            assert values == pytest.approx([rec["worst"][q][name] for q in ("dx", "dy", "dphi", "dp")], rel=1e-5)
    status, text, _ = run([*argv, "--format", "csv"], capsys)
    header = text.splitlines()[0].split(",")
    assert len(header) == 7 + 4 * len(records[0]["worst"]["dx"])   # the CSV keeps every column


def test_map_plot_names_each_orientations_file(capsys, tmp_path):
    status, _, err = run(["map", "--clearances", "case1", "--phi-deg", 0, 15, "--grid", 4, "--out", tmp_path / "m.nc",
                          "--plot", tmp_path / "f.png"], capsys)
    assert status == 0, err
    for phi in (0, 15):
        path = tmp_path / f"f-{phi}deg.png"
        assert path.is_file() and f"wrote {path}" in err
    assert not (tmp_path / "f.png").exists()


def test_statistics_threshold_draws_the_exceedance_map(monkeypatch, tmp_path):
    from pmaccuracy.accuracy.distributions import region_statistics
    from pmaccuracy.report import figures, statistics_report

    ds = region_statistics("aalborg_3ppr", "case1", [0.0], 5, samples=400, seed=1, thresholds={"dp": 0.15})
    drawn = {}

    def keep(fig, path, **kwargs):
        drawn["fig"] = fig
        return path

    monkeypatch.setattr(figures, "save_figure", keep)
    statistics_report.save_percentile_map_figure(ds, tmp_path / "s.png")
    titles = [ax.get_title() for ax in drawn["fig"].axes]
    assert any(t.startswith("P(") and "0.15 mm" in t for t in titles), titles
    ds = region_statistics("aalborg_3ppr", "case1", [0.0], 5, samples=400, seed=1)
    statistics_report.save_percentile_map_figure(ds, tmp_path / "s.png")
    assert not any(ax.get_title().startswith("P(") for ax in drawn["fig"].axes)   # no threshold, no panel


def test_ik_prints_a_revolute_angle_inside_its_range(capsys, tmp_path):
    from pmaccuracy.accuracy.calibration.parameters import wrap_commands
    from pmaccuracy.kinematics import inverse_kinematics, resolve_robot

    def turn(data):   # the same joint range, written one turn up: [130, 310] deg instead of [-230, -50]
        data["legs"][2]["angle_range_deg"] = [130.0, 310.0]

    path = robot_file(tmp_path, "symmetric_3rrr", "turned.toml", turn)
    status, out, err = run(["ik", "--robot", path, "--pose", 0, 0, 0, "--format", "json"], capsys)
    assert status == 0, err
    q3 = json.loads(out)[0]["q"][2]
    assert 130.0 <= q3 <= 310.0
    robot = resolve_robot(path)
    raw = inverse_kinematics(robot, np.zeros((1, 3))).q[0, 2]
    assert math.isclose(math.remainder(math.radians(q3) - raw, 2 * math.pi), 0.0, abs_tol=1e-12)
    # the convention of calibrate compensate's commands
    assert q3 == pytest.approx(math.degrees(wrap_commands(robot, inverse_kinematics(robot, np.zeros((1, 3))).q)[0, 2]),
                               abs=1e-9)


def test_make_region_names_its_argument_and_the_cli_its_option(capsys):
    import pmaccuracy as pm
    from pmaccuracy.accuracy.regions import Disc

    with pytest.warns(Warning):   # -10 rad is also beyond a full turn: the plausibility warning
        with pytest.raises(ConfigError) as info:
            pm.make_region("aalborg_3ppr", (-10.0, 10.0), Disc((0.0, 0.0), 5.0))
    assert info.value.key == "phi" and "--phi-deg" not in str(info.value)
    status, _, err = run(["worst", "--clearances", "case1", "--phi-deg", 30, -30], capsys)
    assert status == 2 and "--phi-deg" in err and "reversed" in err


def test_clearance_toml_takes_a_robot_path(tmp_path):
    import pmaccuracy as pm
    from pmaccuracy.accuracy.regions import Disc
    from pmaccuracy.accuracy.synthesis import clearance_toml

    path = robot_file(tmp_path, "symmetric_3rrr", "my_3rrr.toml")
    region = pm.make_region(path, (0.0, 0.0), Disc((0.0, 0.0), 1.0))
    result = pm.synthesize(path, region, {"dp": 0.2})
    text = clearance_toml(result, path, region)
    assert text == clearance_toml(result, pm.load_robot(path), region)
    assert pm.load_clearances(_write(tmp_path / "c.toml", text), path).name == result.clearances.name
    with pytest.raises(ConfigError) as info:
        clearance_toml(result, path, None)
    assert info.value.key == "region"


def _write(path, text):
    path.write_text(text)
    return str(path)
