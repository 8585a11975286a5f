"""No refusal while the assembly holds (issue 27): a valid but loose bound is returned with its gap and a
PlausibilityWarning, never NaN; a refusal says why (the closure fails inside the set, a singularity, or the
budget), checked against the independent dense search (``nonlinear_search_reference``)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import nonlinear_search_reference as nsr
from pmaccuracy.accuracy import certified as C
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.model.plausibility import PlausibilityWarning
from pmaccuracy.model.sources import ErrorSources
from test_certified import _paper_spec


def test_loose_bound_is_returned_with_its_gap_and_a_warning():
    """At 50x case2 without cutting the set (split=0) the whole set's certificate holds but is 10-20 % loose: the
    bound is returned (never below the dense search, which attains its values) with a warning naming the gap."""
    robot = Manipulator.preset("aalborg_3ppr")
    spec = nsr.scaled_spec(_paper_spec("case2"), 50)
    with pytest.warns(PlausibilityWarning, match=r"% above the best feasible configuration \(valid, but loose"):
        res = C.certified_pose_errors(robot, ErrorSources.from_dict(spec), [0.0, 0.0, 0.0], split=0)
    assert res.reason[0] == ""
    assert max(res.gap[q][0] for q in C.QUANTITIES) > C.GAP_WARNING
    ref = nsr.dense_search(robot.to_dict(), [0.0, 0.0, 0.0], spec, n_random=200, dense=6)
    for q in C.QUANTITIES:
        assert np.isfinite(res.upper[q][0]) and res.upper[q][0] >= ref[q], q


def test_tight_bounds_do_not_warn():
    with warnings.catch_warnings():
        warnings.simplefilter("error", PlausibilityWarning)
        C.certified_pose_errors("aalborg_3ppr", "case2", [[0.0, 0.0, 0.0], [10.0, 5.0, 0.05]])


def test_refusal_says_the_closure_fails_inside_the_set():
    """At 300x case2 the independent search's own Newton fails at some configurations (test_certified): the reason
    says the commanded assembly does not continue over the set."""
    robot = Manipulator.preset("aalborg_3ppr")
    big = ErrorSources.from_dict(_paper_spec("case2")).scaled(300.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PlausibilityWarning)
        res = C.certified_pose_errors(robot, big, [[0.0, 0.0, 0.0]], on_failure="nan", search=False, max_pieces=4)
    assert "does not continue over the whole error set" in res.reason[0]
    assert all(np.isnan(res.upper[q][0]) for q in C.QUANTITIES)


def test_refusal_for_the_budget_says_so():
    """At 100x every configuration closes (test_certified) but the whole set has no certificate: without cutting
    the reason names the budget and the option, not a failure of the assembly."""
    robot = Manipulator.preset("aalborg_3ppr")
    big = ErrorSources.from_dict(_paper_spec("case2")).scaled(100.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PlausibilityWarning)
        res = C.certified_pose_errors(robot, big, [[0.0, 0.0, 0.0]], on_failure="nan", search=False, max_pieces=1)
    assert "max_pieces" in res.reason[0] and "uncut" in res.reason[0]
