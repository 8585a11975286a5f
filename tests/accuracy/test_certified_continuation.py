"""The continuation check of the cut error set (certified.py, "Continuation check"): a piece whose exact centre
solution lies on another solution branch of the closure must not be used.

The other branch is a genuine solution of the closure, built here independently: on the 3-PPR every leg's last
joint is a passive revolute, so turning the platform by 2 pi and each leg's revolute by 2 pi leaves every
rotated term and every leg's angle equation unchanged (checked below on the residual) -- the same physical
configuration but a different point of the nine unknowns, not the continuation of the commanded one.
"""

from __future__ import annotations

import warnings

import numpy as np

import nonlinear_search_reference as nsr
from pmaccuracy.accuracy import certified as C
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.model.sources import ErrorSources
from test_certified import PAPER_POSE, _paper_spec

# unknowns: x, y, phi, then per leg (prismatic, revolute) passive joints -> phi and the three revolutes
BRANCH = np.zeros(9)
BRANCH[[2, 4, 6, 8]] = 2 * np.pi


def _setup():
    robot = Manipulator.preset("aalborg_3ppr")
    assert [c.passive_indices for c in robot.chains] == [(1, 2)] * 3  # prismatic then revolute, per leg
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # plausibility warning on 10x clearances
        return robot, ErrorSources.from_dict(nsr.scaled_spec(_paper_spec("all"), 10))


def test_other_branch_is_a_solution_of_the_closure():
    robot, es = _setup()
    sets = C.error_set(robot, es)
    model = C._build_model(robot, sets, PAPER_POSE[None])
    delta = np.full((1, model.n), 0.3) * np.array([s.eps for s in sets for _ in s.cols])
    M = C.remainder_bounds(robot, es, PAPER_POSE[None])["M"]
    dz = C.exact_change(model, M, delta)
    scale = robot.characteristic_length
    for z in (dz, dz + BRANCH):
        assert np.max(np.abs(model.residual(np.concatenate([z, delta], axis=-1)))) < 1e-9 * scale


def test_pieces_on_another_branch_are_rejected(monkeypatch):
    robot, es = _setup()
    kw = dict(search=False, split_gap=1e-6, max_pieces=12)  # force the 4-piece cut and the branch and bound
    honest = C.certified_pose_errors(robot, es, PAPER_POSE, **kw)
    uncut = C.certified_pose_errors(robot, es, PAPER_POSE, search=False, split=0, max_pieces=0)
    assert honest.rejected[0] == 0
    assert all(honest.upper[q][0] < uncut.upper[q][0] for q in C.QUANTITIES)  # the cut pieces were used

    real = C.exact_change

    def other_branch(model, M, delta, *a, **k):
        return real(model, M, delta, *a, **k) + BRANCH

    monkeypatch.setattr(C.branch, "exact_change", other_branch)  # where the continuation check calls it
    wrong = C.certified_pose_errors(robot, es, PAPER_POSE, **kw)
    assert wrong.rejected[0] >= 4 + 1  # the four pieces of the cut and the branch and bound's root at least
    assert wrong.reason[0] == ""
    for q in C.QUANTITIES:  # no piece used: the whole set's (uncut) bound is kept
        assert wrong.upper[q][0] == uncut.upper[q][0]


def test_point_certificate_of_the_commanded_assembly():
    robot, es = _setup()
    sets = C.error_set(robot, es)
    model = C._build_model(robot, sets, PAPER_POSE[None])
    b0 = C._point_box(model, robot.characteristic_length)
    assert np.all(np.isfinite(b0)) and np.all(b0 < 1e-9)  # rounding-size box about the commanded configuration
    assert C._contains_zero(sets, np.zeros((1, model.n)))[0]
    far = np.zeros((1, model.n))
    far[0, sets[0].cols[0]] = 1.5 * sets[0].eps
    assert not C._contains_zero(sets, far)[0]
