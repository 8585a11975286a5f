"""Clearance sets (paper Sec. 4.2, 5.1.2; reference file aalborg_3ppr.md).

Expected values are typed in from the reference file: eps_theta = 0.0012 rad
(all legs), eps_r = 0.039 / 0.036 / 0.037 mm, eps_g = 0.0015 mm (2 eps_g = 3 um),
L_g = 50 mm. File handling is checked with TOML files written here; every
malformed file must raise ClearanceError/ConfigError whose message names the
file and the offending key. The constraint check of ``ClearanceDisplacement``
is compared with Eq. 16-18 evaluated in this file.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import tomli_w
from hypothesis import given, settings
from hypothesis import strategies as st

from pmaccuracy.model.clearances import ClearanceDisplacement, ClearanceSet
from pmaccuracy.errors import ClearanceError, ConfigError


def test_preset_names():
    assert {"case1", "case2", "all"} <= set(ClearanceSet.preset_names())


def test_case1_preset():
    c = ClearanceSet.load("case1")
    np.testing.assert_array_equal(c.bearing_angle, [0.0012] * 3)
    np.testing.assert_array_equal(c.revolute_radial, [0.0] * 3)
    np.testing.assert_array_equal(c.guide_lateral, [0.0] * 3)
    np.testing.assert_array_equal(c.guide_block_length, [50.0] * 3)
    assert c == ClearanceSet.preset("case1")
    assert c.name == "case1"


def test_case2_preset():
    c = ClearanceSet.load("case2")
    np.testing.assert_array_equal(c.bearing_angle, [0.0012] * 3)
    np.testing.assert_array_equal(c.revolute_radial, [0.039, 0.036, 0.037])
    np.testing.assert_array_equal(c.guide_lateral, [0.0] * 3)


def test_all_preset():
    c = ClearanceSet.load("all")
    np.testing.assert_array_equal(c.bearing_angle, [0.0012] * 3)
    np.testing.assert_array_equal(c.revolute_radial, [0.039, 0.036, 0.037])
    np.testing.assert_array_equal(c.guide_lateral, [0.0015] * 3)
    np.testing.assert_array_equal(c.guide_block_length, [50.0] * 3)


def test_unknown_preset_or_missing_file():
    with pytest.raises(ConfigError, match="case9"):
        ClearanceSet.load("case9")
    with pytest.raises(ConfigError, match="case9"):
        ClearanceSet.preset("case9")
    with pytest.raises(ConfigError, match="nothere.toml"):
        ClearanceSet.from_toml("/nonexistent/nothere.toml")


def test_load_passes_a_set_through():
    c = ClearanceSet(bearing_angle=1e-3)
    assert ClearanceSet.load(c) is c


def test_constructor_broadcasts_and_freezes():
    c = ClearanceSet(bearing_angle=1e-3, revolute_radial=[0.01, 0.02, 0.03])
    np.testing.assert_array_equal(c.bearing_angle, [1e-3] * 3)
    np.testing.assert_array_equal(c.guide_block_length, [50.0] * 3)
    with pytest.raises(ValueError):
        c.bearing_angle[0] = 5.0


def test_toml_round_trip(tmp_path: Path):
    for c in (ClearanceSet.load("all"), ClearanceSet.load("case2"),
              ClearanceSet([1e-3, 2e-3, 3e-3], [0.1, 0.2, 0.3], [10.0, 20.0, 30.5], [0.004, 0.005, 0.006],
                           name="mine", description="a test set")):
        path = tmp_path / f"{c.name}.toml"
        text = c.to_toml(path)
        assert path.read_text(encoding="utf-8") == text
        back = ClearanceSet.from_toml(path)
        assert back == c
        assert back.description == c.description
        for k in ("bearing_angle", "guide_lateral", "guide_block_length", "revolute_radial"):
            np.testing.assert_array_equal(getattr(back, k), getattr(c, k))
        assert ClearanceSet.load(path) == c
        assert ClearanceSet.load(str(path)) == c


_value = st.floats(0.0, 10.0, allow_nan=False, allow_infinity=False)
_triple = st.lists(_value, min_size=3, max_size=3)


@settings(max_examples=25, deadline=None)
@given(b=_triple, g=_triple, L=st.lists(st.floats(0.01, 500.0), min_size=3, max_size=3), r=_triple)
def test_toml_round_trip_property(b, g, L, r, tmp_path_factory):
    c = ClearanceSet(b, g, L, r, name="prop")
    path = tmp_path_factory.mktemp("rt") / "c.toml"
    c.to_toml(path)
    assert ClearanceSet.from_toml(path) == c


def test_missing_keys_default(tmp_path: Path):
    path = tmp_path / "sparse.toml"
    path.write_text("[[legs]]\nbearing_angle = 0.002\n[[legs]]\n[[legs]]\nrevolute_radial = 0.01\n", encoding="utf-8")
    c = ClearanceSet.from_toml(path)
    np.testing.assert_array_equal(c.bearing_angle, [0.002, 0, 0])
    np.testing.assert_array_equal(c.guide_lateral, [0, 0, 0])
    np.testing.assert_array_equal(c.guide_block_length, [50, 50, 50])
    np.testing.assert_array_equal(c.revolute_radial, [0, 0, 0.01])


def test_integer_values_accepted(tmp_path: Path):
    path = tmp_path / "ints.toml"
    path.write_text("[[legs]]\nguide_block_length = 40\n[[legs]]\n[[legs]]\n", encoding="utf-8")
    np.testing.assert_array_equal(ClearanceSet.from_toml(path).guide_block_length, [40, 50, 50])


GOOD_LEG = {"bearing_angle": 0.0012, "guide_lateral": 0.0015, "guide_block_length": 50.0, "revolute_radial": 0.03}


def _with(leg: int, key: str, value) -> str:
    legs = [dict(GOOD_LEG) for _ in range(3)]
    legs[leg][key] = value
    return tomli_w.dumps({"name": "bad", "legs": legs})


BAD_FILES = [
    ("negative", _with(1, "bearing_angle", -0.001), "legs[2].bearing_angle", ClearanceError),
    ("negative-guide", _with(0, "guide_lateral", -1e-4), "legs[1].guide_lateral", ClearanceError),
    ("negative-revolute", _with(2, "revolute_radial", -0.03), "legs[3].revolute_radial", ClearanceError),
    ("zero-block-length", _with(2, "guide_block_length", 0.0), "legs[3].guide_block_length", ClearanceError),
    ("inf", _with(2, "revolute_radial", float("inf")), "legs[3].revolute_radial", ClearanceError),
    ("nan", _with(0, "bearing_angle", float("nan")), "legs[1].bearing_angle", ClearanceError),
    ("non-numeric", _with(0, "guide_lateral", "0.0015"), "legs[1].guide_lateral", ConfigError),
    ("boolean", _with(1, "revolute_radial", True), "legs[2].revolute_radial", ConfigError),
    ("array", _with(1, "bearing_angle", [0.001, 0.002]), "legs[2].bearing_angle", ConfigError),
    ("unknown-key", _with(1, "bearing", 0.001), "legs[2].bearing", ConfigError),
    ("unknown-top", "colour = 'red'\n" + _with(0, "bearing_angle", 0.001), "colour", ConfigError),
    ("two-legs", tomli_w.dumps({"legs": [GOOD_LEG, GOOD_LEG]}), "legs", ConfigError),
    ("four-legs", tomli_w.dumps({"legs": [GOOD_LEG] * 4}), "legs", ConfigError),
    ("no-legs", "name = 'x'\n", "legs", ConfigError),
    ("legs-not-tables", "legs = [1, 2, 3]\n", "legs", ConfigError),
    ("malformed", "name = 'x'\n[[legs]\nbearing_angle = 0.001\n", None, ConfigError),
]


@pytest.mark.parametrize("name,text,key,error", BAD_FILES, ids=[c[0] for c in BAD_FILES])
@pytest.mark.parametrize("reader", ["from_toml", "load"])
def test_bad_files_raise_naming_file_and_key(tmp_path: Path, name, text, key, error, reader):
    path = tmp_path / f"clearance-{name}.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(error) as info:
        getattr(ClearanceSet, reader)(path)
    message = str(info.value)
    assert str(path) in message, message
    if key is not None:
        assert key in message, message
    assert "\n" not in message.strip()


def test_non_finite_and_negative_file_errors_are_clearance_errors(tmp_path: Path):
    """Negative and non-finite clearances are ClearanceError (the subclass), with the source and key attached."""
    path = tmp_path / "neg.toml"
    path.write_text(_with(1, "bearing_angle", -0.001), encoding="utf-8")
    with pytest.raises(ClearanceError) as info:
        ClearanceSet.from_toml(path)
    assert info.value.source == str(path)
    assert info.value.key == "legs[2].bearing_angle"


@pytest.mark.parametrize("value", ["1.5e-3: mm", {"a": 1}], ids=["string-with-colon", "inline-table"])
def test_error_message_keeps_the_problem_when_value_contains_colon(tmp_path: Path, value):
    """The message must still say what is wrong ('must be a number') even if the bad value's repr contains ': '."""
    path = tmp_path / "colon.toml"
    path.write_text(_with(0, "guide_lateral", value), encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        ClearanceSet.from_toml(path)
    message = str(info.value)
    assert str(path) in message and "legs[1].guide_lateral" in message, message
    assert "must be a number" in message, f"problem description lost: {message!r}"


@pytest.mark.parametrize("kwargs", [dict(bearing_angle=-1e-3), dict(revolute_radial=[0, 0, np.nan]),
                                    dict(guide_lateral=np.inf), dict(guide_block_length=0.0),
                                    dict(guide_block_length=[50, -1, 50])])
def test_constructor_rejects_bad_values(kwargs):
    with pytest.raises(ClearanceError):
        ClearanceSet(**kwargs)


def test_only_and_scaled():
    c = ClearanceSet.load("all")
    b = c.only("bearing")
    np.testing.assert_array_equal(b.bearing_angle, c.bearing_angle)
    np.testing.assert_array_equal(b.guide_lateral, 0)
    np.testing.assert_array_equal(b.revolute_radial, 0)
    r = c.only("revolute", "guide")
    np.testing.assert_array_equal(r.bearing_angle, 0)
    np.testing.assert_array_equal(r.revolute_radial, c.revolute_radial)
    s = c.scaled(2.5)
    np.testing.assert_allclose(s.bearing_angle, 2.5 * c.bearing_angle, rtol=1e-15)
    np.testing.assert_allclose(s.guide_lateral, 2.5 * c.guide_lateral, rtol=1e-15)
    np.testing.assert_allclose(s.revolute_radial, 2.5 * c.revolute_radial, rtol=1e-15)
    np.testing.assert_array_equal(s.guide_block_length, c.guide_block_length)
    with pytest.raises(ValueError):
        c.only("gearbox")


def own_violation(d: ClearanceDisplacement, c: ClearanceSet) -> float:
    """max over Eq. 16a, 16b, 17, 18 of (|lhs| - bound) / bound."""
    L, eg = c.guide_block_length, c.guide_lateral
    parts = [np.abs(d.tau_b) / c.bearing_angle - 1,
             np.abs(L * d.tau_g + 2 * d.sigma_g) / (2 * eg) - 1,
             np.abs(-L * d.tau_g + 2 * d.sigma_g) / (2 * eg) - 1,
             np.abs(d.rho) / c.revolute_radial - 1]
    return float(np.max(parts))


def test_displacement_violation_matches_eq16_18():
    c = ClearanceSet.load("all")
    rng = np.random.default_rng(0)
    eg, L = c.guide_lateral[0], c.guide_block_length[0]
    vertices = [(eg, 0.0), (-eg, 0.0), (0.0, 2 * eg / L), (0.0, -2 * eg / L)]
    for sg, tg in vertices:  # rhombus vertices: exactly on the boundary
        d = ClearanceDisplacement(np.zeros(3), np.full(3, sg), np.full(3, tg), np.zeros(3), np.zeros(3))
        assert abs(float(d.violation(c))) < 1e-12
    # a point just outside the rhombus but inside the bounding box of the tilt alone
    d = ClearanceDisplacement(np.zeros(3), np.full(3, 0.6 * eg), np.full(3, 0.6 * 2 * eg / L), np.zeros(3), np.zeros(3))
    assert float(d.violation(c)) > 0
    for _ in range(50):
        d = ClearanceDisplacement(rng.uniform(-1.3, 1.3, 3) * c.bearing_angle,
                                  rng.uniform(-1.3, 1.3, 3) * eg, rng.uniform(-1.3, 1.3, 3) * 2 * eg / L,
                                  rng.uniform(0, 1.3, 3) * c.revolute_radial, rng.uniform(-np.pi, np.pi, 3))
        assert float(d.violation(c)) == pytest.approx(own_violation(d, c), rel=1e-12, abs=1e-15)


def test_displacement_zeros_and_scaled():
    z = ClearanceDisplacement.zeros((4,))
    for f in ("tau_b", "sigma_g", "tau_g", "rho", "varphi"):
        assert getattr(z, f).shape == (4, 3)
        np.testing.assert_array_equal(getattr(z, f), 0)
    d = ClearanceDisplacement(np.ones(3), 2 * np.ones(3), 3 * np.ones(3), 4 * np.ones(3), np.full(3, 0.7))
    s = d.scaled(0.5)
    np.testing.assert_array_equal(s.tau_b, 0.5)
    np.testing.assert_array_equal(s.rho, 2.0)
    np.testing.assert_array_equal(s.varphi, 0.7)
