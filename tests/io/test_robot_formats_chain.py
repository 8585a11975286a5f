"""A robot file whose legs are none of the designer types comes in as joint chains (``spatial-chain``).

``pus_hexapod.xml`` is written by hand: six vertical lifts (actuated slides) carrying rods on cardans, closed to
the platform by connects. Its inverse kinematics has a closed form, computed here from the file's numbers:
the carriage of leg ``i`` sits at the height ``B_z - sqrt(rod^2 - |B_xy - A_xy|^2)`` below the ball ``B``.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

import pmaccuracy as pm
from conftest import run_cli
from pmaccuracy.errors import ConfigError
from pmaccuracy.numerics.spatial import rotations

pytest.importorskip("mujoco")
DATA = Path(__file__).resolve().parents[1] / "data" / "formats"
FILE = DATA / "pus_hexapod.xml"


def _file_geometry():
    """Slide points A (mm), carriage heights at the reference, rod tips (mm, base frame), from the XML text."""
    root = ET.parse(FILE).getroot()
    A, s0, tips = [], [], []
    for i in range(1, 7):
        slider = root.find(f".//body[@name='slider{i}']")
        rod = slider.find("body")
        A.append([1000 * float(v) for v in slider.get("pos").split()])
        s0.append(1000 * float(rod.get("pos").split()[2]))
        tips.append([1000 * float(v) for v in rod.find("site").get("pos").split()])
    A, s0, tips = np.array(A), np.array(s0), np.array(tips)
    rods = np.linalg.norm(tips, axis=-1)
    balls = A + np.array([0.0, 0.0, 1.0]) * s0[:, None] + tips
    return A, s0, rods, balls


def _closed_form(poses):
    A, s0, rods, balls = _file_geometry()
    home = np.array([0.0, 0.0, 450.0])
    b = balls - home                                   # platform points at the identity orientation
    R = rotations(poses[..., 3:])
    B = poses[..., None, :3] + np.einsum("...ij,kj->...ki", R, b)
    horiz = np.sum((B[..., :2] - A[:, :2]) ** 2, axis=-1)
    carriage = B[..., 2] - np.sqrt(rods ** 2 - horiz)
    return carriage - s0                               # the slides' values (0 at the reference)


def test_unknown_legs_come_in_as_chains_with_the_closed_form_kinematics():
    robot = pm.load_robot(str(FILE))
    assert robot.is_chain and robot.label == "6-PUS (joint chains)" and robot.mobility == "6"
    rng = np.random.default_rng(4)
    poses = robot.home_pose + np.concatenate([rng.uniform(-20, 20, (10, 3)), rng.uniform(-0.08, 0.08, (10, 3))], -1)
    assert np.max(np.abs(pm.inverse_kinematics(robot, poses).q - _closed_form(poses))) < 1e-9
    assert robot.strokes.tolist() == [[-80.0, 80.0]] * 6
    # the cardans' ranges came along (50 deg each way)
    assert robot.legs[0].joints[1].ranges == ((math.radians(-50), math.radians(50)),) * 2


def test_imported_chain_round_trips_through_toml(tmp_path, capsys):
    out = tmp_path / "pus.toml"
    status, stdout, err = run_cli(["import", FILE, "--out", out], capsys)
    assert status == 0, err
    assert "6-PUS (joint chains)" in stdout
    again = pm.load_robot(str(out))
    robot = pm.load_robot(str(FILE))
    poses = robot.home_pose + np.array([[5.0, -3.0, 8.0, 0.02, -0.01, 0.03]])
    assert np.max(np.abs(pm.inverse_kinematics(again, poses).q - pm.inverse_kinematics(robot, poses).q)) < 1e-9


def test_a_chain_leg_without_its_actuator_is_named(tmp_path, capsys):
    text = FILE.read_text().replace('<position name="motor3" joint="lift3" kp="500"/>', "")
    path = tmp_path / "no_motor.xml"
    path.write_text(text)
    with pytest.raises(ConfigError, match="leg 3 .*exactly one actuated joint"):
        pm.load_robot(str(path))
    status, _, err = run_cli(["import", path, "--out", tmp_path / "x.toml"], capsys)
    assert status == 2 and len(err.strip().splitlines()) == 1 and "no_motor.xml" in err
