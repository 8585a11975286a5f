"""Spatial synthesis: the largest uniform scaling of a template meeting targets on the workspace grid, checked by
recomputing the map of the scaled sources independently of the scale's own computation."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import run_cli

import pmaccuracy as pm
from pmaccuracy.accuracy.spatial_synthesis import spatial_synthesize
from pmaccuracy.errors import ConfigError
from pmaccuracy.model.spatial_sources import SpatialErrorSources


@pytest.mark.parametrize("name, preset, targets", [
    ("stewart_6ups", "ups_typical", {"dp": 0.05, "dtheta_deg": 0.02}),
    ("rps_3", "rps_typical", {"dx": 0.02, "dz": 0.01}),
])
def test_scaled_sources_meet_the_targets_and_the_binding_one_exactly(name, preset, targets):
    robot = pm.load_robot(name)
    template = pm.load_clearances(preset, robot)
    res = spatial_synthesize(robot, template, targets, n=8)
    ds = pm.spatial_error_map(robot, res.sources, n=8)
    var = {"dp": "dp_max", "dtheta_deg": "dtheta_max", "dx": "dx_max", "dz": "dz_max"}
    for k, v in targets.items():
        worst = float(np.nanmax(ds[var[k]].values)) * (np.degrees(1.0) if k.endswith("_deg") else 1.0)
        assert worst <= v * (1 + 1e-9)
        if k == res.binding:
            assert worst == pytest.approx(v, rel=1e-9)
    # the scale is the ratio of each half-width
    assert res.sources.legs[0][0].radial == pytest.approx(res.scale * template.legs[0][0].radial, rel=1e-12)


def test_bad_targets():
    robot = pm.load_robot("upu_3")
    template = pm.load_clearances("upu_typical", robot)
    for targets in ({}, {"dphi_deg": 0.1}, {"dp": -1.0}, {"dp": float("nan")}):
        with pytest.raises(ConfigError):
            spatial_synthesize(robot, template, targets, n=5)
    with pytest.raises(ConfigError, match="no non-zero"):
        spatial_synthesize(robot, SpatialErrorSources.zero(robot), {"dp": 0.1}, n=5)


def test_cli_writes_a_file_that_bounds_reads(tmp_path, capsys):
    out = tmp_path / "syn.toml"
    status, text, err = run_cli(["synthesize", "--robot", "upu_3", "--target", "dp=0.1", "--out", out,
                                 "--format", "json"], capsys)
    assert status == 0, err
    data = json.loads(text)
    assert data["binding"] == "dp" and data["targets"][0]["worst"] == pytest.approx(0.1, rel=1e-9)
    status, text, err = run_cli(["bounds", "--robot", "upu_3", "--clearances", out, "--pose", 0, 0, 300,
                                 "--format", "json"], capsys)
    assert status == 0, err
    assert json.loads(text)[0]["dp_max"] <= 0.1 * (1 + 1e-9)
    for argv, words in ((["--target", "dq=1"], "--target: expected NAME=VALUE"),
                        (["--target", "dp=0.1", "--target", "dp=0.2"], "given twice"),
                        (["--target", "dp=0.1", "--cost", "c.toml"], "c.toml: no cost preset or file")):
        status, text, err = run_cli(["synthesize", "--robot", "upu_3", *argv], capsys)
        assert status == 2 and len(err.strip().splitlines()) == 1 and words in err, err
