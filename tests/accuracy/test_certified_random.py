"""Certified worst cases on random robots of every architecture against the independent dense search.

Random 3-RPR, 3-RRR, 3-PRR, mixed-chain (``planar_reference``) and general-gamma 3-PPR (``conftest``) robots
at their nominal pose, with random clearances of every joint (``error_reference.random_clearances``:
radial, angular, lateral, actuator) at 1x and 10x. The dense search
(``nonlinear_search_reference.dense_search``, its own exact closure) attains its values, so the certified
bound must never be below it; tightness: within 0.5 % at 1x and 5 % at 10x on every robot (the first 3-PPR
is 12 % nonlinear at 10x: the adaptive cutting of the error set brings its bound from 12-23 % to below 4 %
over the dense search). Where the errors are too large for a certificate the library must return NaN with a
reason, never a finite number. Three more robots 21-44 % nonlinear at 10x (one whose whole error set has no
certificate) must be certified within 5 % too; the one refusal tested is 75 % nonlinear.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import error_reference as eref
import nonlinear_search_reference as nsr
import planar_reference as pref
from pmaccuracy.accuracy import certified as C
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.model.sources import ErrorSources


def _random_ppr(rng):
    from conftest import random_manipulator
    rr = random_manipulator(rng)
    return rr.robot.to_dict(), rr.home


GENERATORS = {"3-RPR": pref.random_rpr, "3-RRR": pref.random_rrr, "3-PRR": pref.random_prr,
              "chain": pref.random_chain, "3-PPR": _random_ppr}


#: The 10x cases of these two take 10-15 s each (the branch and bound uses its whole budget): ``make test-all``.
SLOW_AT_10X = ("3-PRR", "3-RPR")
CASES = [pytest.param(kind, factor, marks=[pytest.mark.slow] if factor == 10 and kind in SLOW_AT_10X else [])
         for kind in sorted(GENERATORS) for factor in (1, 10)]


@pytest.mark.slow
@pytest.mark.parametrize("kind", sorted(GENERATORS))
def test_random_robot_at_30x_never_below_the_dense_search(kind):
    """30x the clearance sets (issue 27): a certified bound is never below the dense search; a refusal is NaN
    with a reason, and only where the search finds the exact worst case far from first order (above 50 %) or
    cannot close the loop itself."""
    rng = np.random.default_rng(1)
    data, nominal = GENERATORS[kind](rng)
    robot = Manipulator.from_dict(data, source="random")
    clear, _ = eref.random_clearances(rng, eref.load_robot(data))
    spec = nsr.scaled_spec(clear, 30)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = C.certified_pose_errors(robot, ErrorSources.from_dict(spec), nominal, on_failure="nan", max_pieces=64)
    try:
        ref = nsr.dense_search(data, nominal, spec, n_random=200, dense=6)
    except RuntimeError:  # the search's own Newton fails: the assembly does not continue over the set
        assert res.reason[0] and all(np.isnan(res.upper[q][0]) for q in C.QUANTITIES)
        return
    if res.reason[0]:
        assert all(np.isnan(res.upper[q][0]) for q in C.QUANTITIES)
        assert max((ref[q] - ref["first_order"][q]) / ref["first_order"][q] for q in C.QUANTITIES) > 0.5
        return
    for q in C.QUANTITIES:
        assert res.upper[q][0] >= ref[q], (kind, q, res.upper[q][0], ref[q])


@pytest.mark.parametrize("kind,factor", CASES)
def test_random_robot_against_dense_search(kind, factor):
    rng = np.random.default_rng(1)  # the same rule for every architecture: the first robot of seed 1
    data, nominal = GENERATORS[kind](rng)
    robot = Manipulator.from_dict(data, source="random")
    clear, _ = eref.random_clearances(rng, eref.load_robot(data))
    tight = {1: 0.005, 10: 0.05}[factor]
    spec = nsr.scaled_spec(clear, factor)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # plausibility warnings on 10x clearances
        res = C.certified_pose_errors(robot, ErrorSources.from_dict(spec), nominal, on_failure="nan")
    ref = nsr.dense_search(data, nominal, spec, n_random=300, dense=8)
    if res.reason[0]:
        # no certificate: NaN, never a finite number (allowed only at 10x, where the exact worst case is far
        # from the first-order one: more than 50 %, test_refusal_only_far_outside_first_order)
        assert factor == 10 and all(np.isnan(res.upper[q][0]) for q in C.QUANTITIES)
        assert max((ref[q] - ref["first_order"][q]) / ref["first_order"][q] for q in C.QUANTITIES) > 0.5
        return
    effect = max((ref[q] - ref["first_order"][q]) / ref["first_order"][q] for q in C.QUANTITIES)
    for q in C.QUANTITIES:
        up, lo, dense = res.upper[q][0], res.lower[q][0], ref[q]
        assert up >= dense, (kind, factor, q, up, dense)
        assert (up - dense) / dense <= tight, (kind, factor, q, up, dense, effect)
        assert lo <= up
        # the best feasible value ascends from the first-order worst vertex wherever the bound is not yet within
        # REFINE_FRACTION * split_gap of it: at least the reference's vertex value, or a stated gap within that
        assert lo >= ref["first_order_vertex"][q] * (1 - 1e-9) or (up - lo) / lo <= C.REFINE_FRACTION * 0.005


# Strongly nonlinear robots at 10x (seeds of the same generators): before the branch and bound cut disks and
# took refused poses, the chain was refused and the other two were 7-10 % above the dense search.
# 10-20 s each: ``make test-all`` (test_certified's 100x case also needs the pieces where the whole set fails).
# The 3-PRR of seed 5 is only 8 % above first order since its guides' angular clearance tilts the carriage
# (issue 21); seed 8 (28 % above first order) was certified 6 % above the dense search with the budget of 96
# pieces, 3.6 % with today's 256 (issue 27).
HARD = [pytest.param(kind, seed, marks=pytest.mark.slow) for kind, seed in (("chain", 3), ("3-RPR", 5),
                                                                             ("3-PRR", 8))]


@pytest.mark.parametrize("kind,seed", HARD)
def test_strongly_nonlinear_robots_at_10x(kind, seed):
    rng = np.random.default_rng(seed)
    data, nominal = GENERATORS[kind](rng)
    robot = Manipulator.from_dict(data, source="random")
    clear, _ = eref.random_clearances(rng, eref.load_robot(data))
    spec = nsr.scaled_spec(clear, 10)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        es = ErrorSources.from_dict(spec)
        res = C.certified_pose_errors(robot, es, nominal, on_failure="nan")
        whole = C.remainder_bounds(robot, es, np.asarray(nominal, float)[None])
    if kind == "chain":  # the whole set has no certificate: only the pieces give one
        assert whole["reason"][0] != ""
    ref = nsr.dense_search(data, nominal, spec, n_random=300, dense=8)
    effect = max((ref[q] - ref["first_order"][q]) / ref["first_order"][q] for q in C.QUANTITIES)
    assert effect > 0.2  # far from first order: the whole set has no certificate or a loose one
    assert res.reason[0] == ""
    for q in C.QUANTITIES:
        up, dense = res.upper[q][0], ref[q]
        assert dense <= up <= 1.05 * dense, (kind, seed, q, up, dense)
        assert res.lower[q][0] >= dense * (1 - 0.005)  # the pieces' extreme points find the worst case too


def test_refusal_only_far_outside_first_order():
    """The 3-RRR of seed 2 at 10x: the exact worst case is 75 % above first order (dense search); no certificate
    within a small budget (the former default of 8 x 96 pieces took 36 s and did not suffice either; about 1200
    pieces certify it, 23 % loose), so NaN with a reason -- never a finite number. (A budget of 8 x 4 pieces:
    3 s.)"""
    rng = np.random.default_rng(2)
    data, nominal = GENERATORS["3-RRR"](rng)
    robot = Manipulator.from_dict(data, source="random")
    clear, _ = eref.random_clearances(rng, eref.load_robot(data))
    spec = nsr.scaled_spec(clear, 10)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = C.certified_pose_errors(robot, ErrorSources.from_dict(spec), nominal, on_failure="nan", max_pieces=4)
        ref = nsr.dense_search(data, nominal, spec, n_random=100, dense=6)
    effect = max((ref[q] - ref["first_order"][q]) / ref["first_order"][q] for q in C.QUANTITIES)
    assert effect > 0.5
    if res.reason[0]:
        assert all(np.isnan(res.upper[q][0]) for q in C.QUANTITIES)
    else:  # certified after all (a larger budget): then it must hold
        assert all(res.upper[q][0] >= ref[q] for q in C.QUANTITIES)
