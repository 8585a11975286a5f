"""``pmaccuracy worst`` on spatial robots: the certified worst case of a 6-UPS and a Delta in the output, bad input in one
line."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import run_cli

from pmaccuracy.accuracy.spatial_bounds import spatial_pose_errors
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.model.spatial_sources import SpatialErrorSources
from pmaccuracy.numerics.spatial import euler_xyz_to_rotvec


def test_hexapod_box_json_attained_at_its_pose(capsys):
    argv = ["worst", "--robot", "stewart_6ups", "--clearances", "ups_typical", "--box", -5, 5, -5, 5, 395, 405,
            "--orientation-deg", 0, 0, 0, "--format", "json"]
    status, out, err = run_cli(argv, capsys)
    assert status == 0, err
    data = json.loads(out)
    assert data["upper_certified"] and len(data["quantities"]) == 8
    robot = SpatialManipulator.preset("stewart_6ups")
    sources = SpatialErrorSources.load("ups_typical", robot)
    for row in data["quantities"]:
        assert row["certified"] and row["lower"] <= row["upper"] <= row["lower"] * 1.01 * (1 + 1e-9)
        assert -5 <= row["x"] <= 5 and -5 <= row["y"] <= 5 and 395 <= row["z"] <= 405
        pose = np.concatenate([[row["x"], row["y"], row["z"]],
                               euler_xyz_to_rotvec(np.radians([row["roll_deg"], row["pitch_deg"], row["yaw_deg"]]))])
        b = spatial_pose_errors(robot, sources, pose)
        values = dict(zip(("dx", "dy", "dz", "drx_deg", "dry_deg", "drz_deg", "dp", "dtheta_deg"),
                          [*b.components[:3], *np.degrees(b.components[3:]), b.dp_upper,
                           np.degrees(b.dtheta_upper)]))
        assert values[row["quantity"]] == pytest.approx(row["lower"], rel=2e-3)


def test_delta_sphere_json_certified(capsys):
    argv = ["worst", "--robot", "delta_clavel", "--sphere", 0, 0, -800, 10, "--format", "json"]
    status, out, err = run_cli(argv, capsys)
    assert status == 0, err
    data = json.loads(out)
    assert data["upper_certified"] and "not certified" not in err
    for row in data["quantities"]:
        assert row["certified"] and row["lower"] <= row["upper"] <= row["lower"] * 1.01 * (1 + 1e-9)
        assert np.linalg.norm([row["x"], row["y"], row["z"] + 800]) <= 10 * (1 + 1e-12)


@pytest.mark.parametrize("argv, words", [
    (["worst", "--robot", "stewart_6ups", "--box", 0, 1, 0, 1, 400], "--box: expected six numbers"),
    (["worst", "--robot", "stewart_6ups", "--box", 1, 0, 0, 1, 400, 401], "--box: the box is reversed"),
    (["worst", "--robot", "stewart_6ups", "--sphere", 0, 0, 400, -1], "--sphere: the radius must be > 0"),
    (["worst", "--robot", "stewart_6ups", "--phi-deg", 0, 0], "--phi-deg: is not available for spatial"),
    (["worst", "--robot", "stewart_6ups", "--orientation-deg", 0, 0], "--orientation-deg: give roll pitch yaw"),
    (["worst", "--robot", "stewart_6ups", "--box", 0, 1, 0, 1, 400, 401, "--gap-pct", 0], "--gap-pct"),
    (["worst", "--robot", "stewart_6ups", "--box", 0, 1, 0, 1, 900, 901], "--box: "),
    (["worst", "--robot", "rps_3", "--cylinder", 0, 0, 5, 300, 310], "--cylinder: a 3-RPS's region is a box"),
    (["worst", "--robot", "delta_clavel", "--orientation-deg", 0, 0, 0], "--orientation-deg: a delta"),
    (["worst", "--robot", "aalborg_3ppr", "--sphere", 0, 0, 0, 1], "--sphere: is for spatial robots"),
    (["worst", "--robot", "aalborg_3ppr"], "required: --phi-deg"),
])
def test_bad_input_one_line(argv, words, capsys):
    status, out, err = run_cli(argv, capsys)
    lines = err.strip().splitlines()
    assert status == 2 and len(lines) == 1 and words in lines[0], err
