"""Measurement helpers of paper Sec. 5.1: guide directions, assembly angle errors and clearances."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pmaccuracy.experiment import measure
from pmaccuracy.errors import ConfigError


def _holes(angle: float, n: int = 4, pitch: float = 60.0, start=(10.0, -5.0), noise: float = 0.0, seed: int = 0):
    """``n`` hole centres (mm) along direction ``angle`` with optional Gaussian noise."""
    t = np.arange(n) * pitch
    pts = np.asarray(start) + t[:, None] * np.array([math.cos(angle), math.sin(angle)])
    return pts + np.random.default_rng(seed).normal(0.0, noise, pts.shape)


def test_guide_direction_exact_line() -> None:
    for angle in np.radians([0.0, 30.0, 90.0, 135.0, 180.0, -60.0, -90.0]):
        got = measure.guide_direction(_holes(angle))
        assert math.remainder(got - angle, 2 * math.pi) == pytest.approx(0.0, abs=1e-12)
    # orientation follows the order of the holes
    holes = _holes(math.radians(20.0))
    assert measure.guide_direction(holes[::-1]) == pytest.approx(math.radians(20.0) - math.pi, abs=1e-12)
    # two points: the angle of the segment
    assert measure.guide_direction([[0.0, 0.0], [1.0, 1.0]]) == pytest.approx(math.pi / 4)


def test_guide_direction_against_polyfit_with_noise() -> None:
    for seed in range(5):
        angle = math.radians(10.0 + 7.0 * seed)
        holes = _holes(angle, n=6, noise=0.02, seed=seed)
        slope = np.polyfit(holes[:, 0], holes[:, 1], 1)[0]  # ordinary LS: close to TLS for small noise
        assert measure.guide_direction(holes) == pytest.approx(math.atan(slope), abs=2e-4)
        assert measure.guide_direction(holes) == pytest.approx(angle, abs=1e-3)
        endpoints = math.atan2(*(holes[-1] - holes[0])[::-1])
        assert measure.guide_direction(holes) == pytest.approx(endpoints, abs=1e-3)


def test_guide_direction_is_total_least_squares() -> None:
    # TLS minimises perpendicular distances: any other direction through the centroid does worse
    holes = _holes(math.radians(75.0), n=5, noise=0.3, seed=11)
    fit = measure.fit_line(holes)
    c = holes - holes.mean(axis=0)

    def rms(a: float) -> float:
        return float(np.sqrt(np.mean((c @ np.array([-math.sin(a), math.cos(a)])) ** 2)))

    assert fit.rms_mm == pytest.approx(rms(fit.angle), rel=1e-9)
    for delta in (-1e-2, -1e-3, 1e-3, 1e-2):
        assert rms(fit.angle + delta) > fit.rms_mm
    # a vertical guide, where y = f(x) fits fail
    assert measure.guide_direction([[5.0, 0.0], [5.0, 10.0], [5.0, 20.0]]) == pytest.approx(math.pi / 2)


@settings(max_examples=50, deadline=None)
@given(angle=st.floats(-math.pi + 1e-6, math.pi), n=st.integers(2, 8),
       x0=st.floats(-500, 500), y0=st.floats(-500, 500), pitch=st.floats(1.0, 100.0))
def test_guide_direction_property(angle: float, n: int, x0: float, y0: float, pitch: float) -> None:
    got = measure.guide_direction(_holes(angle, n=n, pitch=pitch, start=(x0, y0)))
    assert abs(math.remainder(got - angle, 2 * math.pi)) < 1e-9


def test_assembly_angle_error_table2() -> None:
    # Aalborg geometry: guides 1 and 2 both along +y, guide 3 along -x (nominal +90 deg from guide 1)
    ref = _holes(math.pi / 2, start=(-83.15, -60.0), noise=0.0)
    guide2 = _holes(math.pi / 2 + 0.014, start=(83.15, -60.0))
    guide3 = _holes(math.pi - 0.010, start=(60.0, -120.0))
    assert measure.assembly_angle_error(ref, ref) == 0.0  # dbeta_1 = 0 by definition
    assert measure.assembly_angle_error(guide2, ref) == pytest.approx(0.014, abs=1e-12)
    assert measure.assembly_angle_error(guide3, ref, math.pi / 2) == pytest.approx(-0.010, abs=1e-12)
    # hole order of either guide does not matter
    assert measure.assembly_angle_error(guide2[::-1], ref) == pytest.approx(0.014, abs=1e-12)
    assert measure.assembly_angle_error(guide3, ref[::-1], math.pi / 2) == pytest.approx(-0.010, abs=1e-12)
    # a frame rotation leaves the relative error unchanged
    rot = np.array([[math.cos(0.4), -math.sin(0.4)], [math.sin(0.4), math.cos(0.4)]])
    assert measure.assembly_angle_error(guide2 @ rot.T, ref @ rot.T) == pytest.approx(0.014, abs=1e-12)


def test_assembly_angle_error_noise_and_wrap() -> None:
    ref = _holes(math.radians(90.0), noise=0.005, seed=1)
    guide = _holes(math.radians(90.0) + 0.02, noise=0.005, seed=2)
    independent = math.atan2(*(guide[-1] - guide[0])[::-1]) - math.atan2(*(ref[-1] - ref[0])[::-1])
    assert measure.assembly_angle_error(guide, ref) == pytest.approx(independent, abs=3e-4)
    assert measure.wrap_half_turn(math.pi / 2) == pytest.approx(math.pi / 2)
    assert measure.wrap_half_turn(-math.pi / 2) == pytest.approx(math.pi / 2)
    assert measure.wrap_half_turn(math.pi) == pytest.approx(0.0, abs=1e-15)
    assert measure.wrap_half_turn(3.0) == pytest.approx(3.0 - math.pi)
    with pytest.raises(ConfigError, match="nominal_angle"):
        measure.assembly_angle_error(guide, ref, float("nan"))


def test_clearances() -> None:
    # paper Sec. 5.1.2: eps_theta = 0.0012 rad, eps_r = 0.039 mm
    assert measure.bearing_angular_clearance(0.06, 50.0) == pytest.approx(0.0012)
    assert measure.bearing_angular_clearance(0.0, 50.0) == 0.0
    assert isinstance(measure.bearing_angular_clearance(0.06, 50.0), float)
    np.testing.assert_allclose(measure.bearing_angular_clearance([0.06, 0.12], 50.0), [0.0012, 0.0024])
    assert measure.revolute_radial_clearance(8.078, 8.0) == pytest.approx(0.039)
    assert measure.revolute_radial_clearance(8.0, 8.0) == 0.0
    np.testing.assert_allclose(measure.revolute_radial_clearance([8.078, 8.072, 8.074], 8.0),
                               [0.039, 0.036, 0.037], atol=1e-12)


@pytest.mark.parametrize("call, key", [
    (lambda: measure.bearing_angular_clearance(-0.01, 50.0), "delta_lb_mm"),
    (lambda: measure.bearing_angular_clearance(float("nan"), 50.0), "delta_lb_mm"),
    (lambda: measure.bearing_angular_clearance(0.01, 0.0), "shaft_length_mm"),
    (lambda: measure.bearing_angular_clearance(0.01, float("inf")), "shaft_length_mm"),
    (lambda: measure.bearing_angular_clearance("a", 1.0), "delta_lb_mm"),
    (lambda: measure.revolute_radial_clearance(8.0, 8.01), "pin_diameter_mm"),
    (lambda: measure.revolute_radial_clearance(-8.0, 7.0), "hole_diameter_mm"),
    (lambda: measure.revolute_radial_clearance(8.0, float("nan")), "pin_diameter_mm"),
    (lambda: measure.guide_direction([[1.0, 2.0]]), "hole_centres"),
    (lambda: measure.guide_direction([[1.0, 2.0], [1.0, 2.0], [1.0, 2.0]]), "hole_centres"),
    (lambda: measure.guide_direction([[0.0, 0.0], [1.0, 0.0], [0.0, 0.0]]), "hole_centres"),
    (lambda: measure.guide_direction([[0.0, 0.0], [float("nan"), 1.0]]), "hole_centres"),
    (lambda: measure.guide_direction([1.0, 2.0, 3.0]), "hole_centres"),
    (lambda: measure.assembly_angle_error([[0, 0], [1, 1]], [[2, 2], [2, 2]]), "reference_holes"),
])
def test_invalid_inputs(call, key: str) -> None:
    with pytest.raises(ConfigError) as info:
        call()
    assert isinstance(info.value, ValueError)
    assert key in str(info.value)
