"""The pose-file path's per-value helpers, shortened for 10^6 poses (issue 35), against plain references.

``degrees_as_given`` now starts most values at 10 or 13 decimals and ``looks_like_radians`` tests only the values
that could be radians; both must give bit for bit what the plain passes over every value give (the
references below, the helpers as they were written before).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from pmaccuracy.cli._common import degrees_as_given
from pmaccuracy.model.plausibility import DIRECTION_MATCH, RADIAN_MATCH, looks_like_radians


def degrees_reference(angles_rad) -> np.ndarray:
    """Every finite value through 0, 1, ..., 15 decimals until its rounding converts back to the same radians."""
    rad = np.asarray(angles_rad, dtype=float)
    deg = np.degrees(rad)
    out = deg.copy()
    todo = np.flatnonzero(np.isfinite(rad))
    for digits in range(16):
        candidate = np.round(deg.flat[todo], digits)
        ok = np.radians(candidate) == rad.flat[todo]
        out.flat[todo[ok]] = candidate[ok]
        todo = todo[~ok]
    return out


def radians_reference(phi_deg, direction: bool = False) -> np.ndarray:
    v = np.abs(np.asarray(phi_deg, dtype=float))
    hit = np.zeros(v.shape, dtype=bool)
    steps = [(math.pi / 12, RADIAN_MATCH), (math.pi / 8, RADIAN_MATCH), (math.pi / 18, RADIAN_MATCH)]
    if direction:
        steps.append((math.pi / 4, DIRECTION_MATCH))
    with np.errstate(invalid="ignore"):
        for step, match in steps:
            k = np.rint(v / step)
            hit |= (k >= 1) & (np.abs(v - k * step) <= match)
        limit = 2 * math.pi + (DIRECTION_MATCH if direction else RADIAN_MATCH)
        return hit & (v > 0) & (v <= limit) & np.isfinite(v)


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and np.array_equal(a.view(np.int64), b.view(np.int64))


def _angle_sets() -> list[np.ndarray]:
    rng = np.random.default_rng(35)
    typed = np.concatenate([np.round(rng.uniform(-400, 400, 4000), k) for k in range(16)])
    near_grid = np.round(rng.uniform(-1000, 1000, 20000), 9) + rng.integers(-8, 9, 20000) * 1.2e-13
    near_grid_12 = np.round(rng.uniform(-64, 64, 20000), 12) + rng.integers(-8, 9, 20000) * 7.2e-15
    return [np.radians(rng.uniform(-30, 30, 50000)),          # a file of random 16-digit angles
            np.radians(typed),                                   # angles typed with 0-15 decimals
            np.radians(near_grid),                               # within a few ulp of a 9-decimal value
            np.radians(near_grid_12),                            # ... of a 12-decimal value
            np.radians(rng.uniform(-1e5, 1e5, 5000)),            # beyond the shortcut's 1000 deg
            rng.uniform(-7, 7, 20000),                           # radians read as such
            np.array([np.nan, np.inf, -np.inf, 0.0, -0.0, 1e-300, 5e-324, -5e-324, np.pi, -np.pi / 6])]


@pytest.mark.parametrize("k", range(7))
def test_degrees_as_given_matches_the_plain_passes(k):
    angles = _angle_sets()[k]
    assert same_bits(degrees_as_given(angles), degrees_reference(angles))


@settings(max_examples=200, deadline=None)
@given(arrays(np.float64, st.integers(1, 50), elements=st.floats(-1e4, 1e4, allow_nan=False)))
def test_degrees_as_given_matches_on_any_degrees(deg):
    rad = np.radians(deg)
    assert same_bits(degrees_as_given(rad), degrees_reference(rad))


@pytest.mark.parametrize("direction", [False, True])
def test_looks_like_radians_matches_the_plain_passes(direction):
    rng = np.random.default_rng(7)
    steps = np.concatenate([np.arange(1, 30) * math.pi / d for d in (12, 8, 18, 4)])
    edges = np.concatenate([steps, -steps, steps + 0.99 * RADIAN_MATCH, steps + 1.01 * RADIAN_MATCH,
                            steps + 0.99 * DIRECTION_MATCH, steps + 1.01 * DIRECTION_MATCH, np.round(steps, 2),
                            [np.nan, np.inf, -np.inf, 0.0, -0.0, 2 * math.pi + RADIAN_MATCH, 2 * math.pi + 1e-3,
                             2 * math.pi + DIRECTION_MATCH, 2 * math.pi + 6e-3]])
    for values in (rng.uniform(-30, 30, 100000), edges, rng.uniform(-30, 30, (40, 7))):
        got = looks_like_radians(values, direction=direction)
        assert got.shape == values.shape and np.array_equal(got, radians_reference(values, direction))
    for scalar in (math.pi / 2, 0.5236, 1.57, 30.0, float("nan"), 0.0):
        got = looks_like_radians(scalar, direction=direction)
        assert np.ndim(got) == 0 and bool(got) == bool(radians_reference(scalar, direction))
