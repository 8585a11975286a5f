"""Spatial robot and error-source files, mutated at random: every mutation is either read or refused with the
package's own error naming the file (never another exception, never a robot that cannot be evaluated)."""

from __future__ import annotations

import copy
import math
import warnings

import numpy as np
import pytest

from pmaccuracy.errors import PmAccuracyError
from pmaccuracy.kinematics import resolve_robot
from pmaccuracy.kinematics import spatial as k
from pmaccuracy.model import _tomlio
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.model.spatial_sources import DEFAULT_PRESET, SpatialErrorSources

PRESETS = ["stewart_6ups", "delta_clavel", "rps_3", "prs_3", "upu_3"]
BAD_VALUES = [None, "x", True, -1.0, 0.0, 1e308 * 10, float("nan"), [], [1.0], [0.0, 0.0, 0.0], [1, 2, 3, 4],
              {"a": 1}, 10 ** 400, -1e9, 3.14159]


def _mutations(data: dict, rng: np.random.Generator, count: int):
    keys = []
    for i, leg in enumerate(data["legs"]):
        keys.extend(("legs", i, key) for key in leg)
    keys.extend(("home", None, key) for key in data.get("home", {}))
    for _ in range(count):
        d = copy.deepcopy(data)
        where, i, key = keys[rng.integers(len(keys))]
        table = d["legs"][i] if where == "legs" else d["home"]
        action = rng.integers(3)
        if action == 0:
            del table[key]
        else:
            table[key] = copy.deepcopy(BAD_VALUES[rng.integers(len(BAD_VALUES))])
        yield d


@pytest.mark.parametrize("name", PRESETS)
def test_mutated_robot_files_are_read_or_refused_with_our_error(name, tmp_path):
    import tomli_w

    data, _ = _tomlio.read_spec(name, kind="robot", folder="robots")
    rng = np.random.default_rng(sum(name.encode()))
    for n, d in enumerate(_mutations(data, rng, 40)):
        path = tmp_path / f"m{n}.toml"
        try:
            path.write_text(tomli_w.dumps(d))
        except (TypeError, ValueError, OverflowError):   # not writable as TOML (None): not a file a user has
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                robot = resolve_robot(str(path))
            except PmAccuracyError as exc:
                assert str(path) in str(exc), str(exc)
                continue
            ik = k.inverse_kinematics(robot, k.reference_pose(robot))
            assert np.all(np.isfinite(ik.q)) and bool(ik.within_limits)


@pytest.mark.parametrize("name", PRESETS)
def test_mutated_error_source_files_are_read_or_refused(name):
    robot = SpatialManipulator.preset(name)
    base = SpatialErrorSources.load(DEFAULT_PRESET[robot.architecture], robot).to_dict()
    rng = np.random.default_rng(7)
    for _ in range(40):
        d = copy.deepcopy(base)
        leg = d["legs"][rng.integers(len(d["legs"]))]
        joint = leg["joints"][rng.integers(len(leg["joints"]))]
        key = ["radial", "axial", "tilt", "actuator", "bogus", "length", "direction"][rng.integers(7)]
        joint[key] = copy.deepcopy(BAD_VALUES[rng.integers(len(BAD_VALUES))])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                src = SpatialErrorSources.from_dict(d, robot, source="c.toml")
            except PmAccuracyError as exc:
                assert "c.toml" in str(exc)
                continue
        for leg in src.legs:
            for j in leg:
                for _, v in j.items():
                    assert math.isfinite(v) and v >= 0
