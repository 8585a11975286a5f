"""``pmaccuracy template`` for spatial architectures: the shipped commented file, which loads to the preset it copies."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import run_cli

from pmaccuracy.io.templates import SPATIAL_ARCHITECTURES, template_text
from pmaccuracy.kinematics import resolve_robot
from pmaccuracy.kinematics import spatial as k

PRESET = {"6-UPS": "stewart_6ups", "delta": "delta_clavel", "3-RPS": "rps_3", "3-PRS": "prs_3", "3-UPU": "upu_3"}


@pytest.mark.parametrize("arch", SPATIAL_ARCHITECTURES)
def test_template_is_the_preset_it_copies_and_reaches_home(arch, tmp_path, capsys):
    status, out, err = run_cli(["template", arch.lower()], capsys)
    assert status == 0 and out == template_text(arch)
    path = tmp_path / "mine.toml"
    path.write_text(out)
    mine, preset = resolve_robot(str(path)), resolve_robot(PRESET[arch])
    assert mine.name.startswith("my_") and mine.architecture == preset.architecture
    home = k.reference_pose(preset)
    np.testing.assert_allclose(k.inverse_kinematics(mine, home).q, k.inverse_kinematics(preset, home).q, rtol=1e-14)
    assert bool(k.inverse_kinematics(mine, k.reference_pose(mine)).within_limits)
    # every key of the first leg and of the top level is explained
    for line in out.splitlines():
        if line.startswith("[[legs]]"):
            break
        if "=" in line and not line.startswith("#"):
            assert "#" in line, line


@pytest.mark.parametrize("arch", SPATIAL_ARCHITECTURES)
def test_clearance_template_is_the_typical_preset(arch, tmp_path, capsys):
    from pmaccuracy.model.spatial_sources import DEFAULT_PRESET, SpatialErrorSources

    status, out, err = run_cli(["template", arch, "--clearances"], capsys)
    assert status == 0
    path = tmp_path / "c.toml"
    path.write_text(out)
    robot = resolve_robot(PRESET[arch])
    mine = SpatialErrorSources.load(str(path), robot)
    preset = SpatialErrorSources.load(DEFAULT_PRESET[arch], robot)
    assert mine.legs == preset.legs and mine.name.startswith("my_")
    assert any(v for leg in mine.legs for j in leg for _, v in j.items())
