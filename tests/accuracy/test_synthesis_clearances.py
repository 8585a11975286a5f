"""``synthesize`` scales the clearances the user gives (issue 25: it used the default template unless they
came as ``template=``). ``clearances=`` is the front door's name for them; the result is checked
independently: its sources are exactly the given file's non-zero keys, each scaled by one factor, its
certified worst case meets the target, and first-order maxima (``max_pose_errors``) on a grid of the region
stay within the target while 2 % larger clearances exceed it somewhere.
"""

from __future__ import annotations

import numpy as np
import pytest

import pmaccuracy as pm
from pmaccuracy.accuracy.synthesis import synthesize, targets_arg
from pmaccuracy.errors import ConfigError

ROBOT = pm.load_robot("aalborg_3ppr")
REGION = pm.make_region(ROBOT, (0.0, 0.0), (-10.0, 10.0, -10.0, 10.0))
MINE = """name = "mine"
[[legs]]
joints = [{}, { angular = 0.002 }, { radial = 0.004 }]
[[legs]]
joints = [{}, { angular = 0.001 }, { radial = 0.004 }]
[[legs]]
joints = [{}, { angular = 0.001 }, {}]
"""
X, Y = np.meshgrid(np.linspace(-10, 10, 41), np.linspace(-10, 10, 41))
GRID = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], axis=-1)


@pytest.fixture(scope="module")
def mine(tmp_path_factory):
    path = tmp_path_factory.mktemp("synth") / "mine.toml"
    path.write_text(MINE)
    return pm.load_clearances(str(path), ROBOT)


def test_the_given_clearances_are_scaled(mine):
    res = synthesize(ROBOT, REGION, {"dp": 0.1}, clearances=mine)
    assert [(s.label, s.value) for s in res.sources] == [
        ("legs[1].joints[2].angular", 0.002), ("legs[1].joints[3].radial", 0.004),
        ("legs[2].joints[2].angular", 0.001), ("legs[2].joints[3].radial", 0.004),
        ("legs[3].joints[2].angular", 0.001)]
    np.testing.assert_allclose(res.values / res.template_values, res.scale, rtol=1e-12)
    assert res.worst["dp"].upper <= 0.1 * (1 + 1e-12)
    dense = pm.max_pose_errors(ROBOT, res.clearances, GRID).dp_max.max()
    assert dense <= 0.1 * (1 + 1e-9)
    assert pm.max_pose_errors(ROBOT, res.clearances.scaled(1.02), GRID).dp_max.max() > 0.1
    # the same as the older keyword, and not the default template (case1: bearings only)
    old = synthesize(ROBOT, REGION, {"dp": 0.1}, template=mine)
    np.testing.assert_array_equal(old.values, res.values)
    default = synthesize(ROBOT, REGION, {"dp": 0.1})
    assert [s.key for s in default.sources] == ["angular"] * 3


def test_targets_in_any_documented_form():
    expected = {"dp": 0.1, "dphi": np.radians(0.2)}
    for given in ({"dp": 0.1, "dphi": np.radians(0.2)}, {"dp": 0.1, "dphi_deg": 0.2}, ["dp=0.1", "dphi_deg=0.2"]):
        got = targets_arg(given)
        assert got.keys() == expected.keys() and all(np.isclose(got[k], v, rtol=1e-15) for k, v in expected.items())


@pytest.mark.parametrize("call, words", [
    (lambda cl: synthesize(ROBOT, cl, {"dp": 0.1}), ["region", "Region", "clearances="]),
    (lambda cl: synthesize(ROBOT, REGION, {"dp": 0.1}, clearances=cl, template="case1"), ["clearances", "once"]),
    (lambda cl: synthesize(ROBOT, REGION, {"dq": 0.1}, clearances=cl), ["targets", "dq"]),
    (lambda cl: synthesize(ROBOT, REGION, {"dphi": 0.1, "dphi_deg": 1.0}, clearances=cl), ["targets", "not both"]),
    (lambda cl: synthesize(ROBOT, REGION, 0.1, clearances=cl), ["targets", "float"]),
    (lambda cl: synthesize(ROBOT, REGION, {"dphi": -1.0}, clearances=cl), ["targets", "dphi", "> 0 rad"]),
])
def test_mistakes_are_refused_by_name(mine, call, words):
    with pytest.raises(ConfigError) as err:
        call(mine)
    assert all(w in str(err.value) for w in words), str(err.value)
