"""``experiment compare --push-n``: measured push displacements beside the loaded model's prediction (issue 24,
deliverable 3).

Independent references:
- the simulated rig reads the exact loop closure (``joint_displaced_pose``) of the pushed clearance state plus
  seeded Gaussian noise; the prediction is first order, so without noise the differences are second order in
  the clearances, and with noise of sd ``s`` their RMS is ``s`` (up to sampling error);
- each predicted push displacement of a push whose legs are all loaded is the brute-force maximizer of the
  push's virtual work ``W . dX`` over the eight sign vertices of the error zonotope (generators from
  ``max_pose_errors(details=True)``), written here without ``pmaccuracy.accuracy.loads``.
"""

from __future__ import annotations

import csv
import io
import itertools
import json
import math

import numpy as np
import pytest

from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.cli import main
from pmaccuracy.experiment import PUSHES, compare, compare_pushes, simulate_experiment
from pmaccuracy.experiment.virtual_rig import predict_pushes
from pmaccuracy.model.manipulator import Manipulator

ROBOTS = [("aalborg_3ppr", "case2"), ("symmetric_3rpr", "rpr_typical"), ("symmetric_3rrr", "rrr_typical")]


def push_wrenches(robot: Manipulator, push_n: float) -> np.ndarray:
    """The six pushes' wrenches [fx N, fy N, m N mm], written from the protocol (+-x, +-y forces, +-r moments of
    push_n times the robot's size)."""
    L = robot.characteristic_length
    return np.array([[push_n, 0, 0], [-push_n, 0, 0], [0, push_n, 0], [0, -push_n, 0], [0, 0, push_n * L],
                     [0, 0, -push_n * L]], dtype=float)


@pytest.mark.parametrize("name, clear", ROBOTS)
def test_noise_free_simulated_pushes_match_the_prediction_to_second_order(name, clear):
    robot = Manipulator.preset(name)
    m = simulate_experiment(robot, clear, math.radians(5.0), 4, noise_mm=0.0, noise_deg=0.0, push_n=10.0)
    pc = compare_pushes(robot, clear, m, 10.0)
    size = np.max(np.abs(pc.predicted[..., :2]))
    assert size > 1e-3                                       # the pushes do move the platform
    assert np.max(np.abs(pc.difference[..., :2])) < 1e-2 * size   # exact vs first order: second-order terms
    assert np.all(pc.inside)


@pytest.mark.parametrize("name, clear", ROBOTS)
def test_noisy_simulated_pushes_differ_from_the_prediction_by_the_noise(name, clear):
    robot = Manipulator.preset(name)
    m = simulate_experiment(robot, clear, math.radians(5.0), 6, noise_mm=0.01, noise_deg=0.01, seed=3, push_n=10.0)
    res = compare(robot, clear, m, push_n=10.0)
    rms = res.pushes.rms()
    n = res.pushes.difference[..., 0].size
    assert n >= 60
    # RMS of n N(0, s^2) draws: relative sd 1/sqrt(2n) < 10 %; the second-order model error is far below s
    assert rms["dx"] == pytest.approx(0.01, rel=0.3) and rms["dy"] == pytest.approx(0.01, rel=0.3)
    assert rms["dphi_deg"] == pytest.approx(0.01, rel=0.3)
    # per component |N(0, s^2)| <= 2 s with probability 95.4 %: all three about 87 %
    assert 0.75 <= float(np.mean(res.pushes.inside)) <= 0.97
    assert res.summary()["pushes"]["share_inside"] == pytest.approx(float(np.mean(res.pushes.inside)))


@pytest.mark.parametrize("name, clear", ROBOTS)
def test_predicted_push_is_the_vertex_of_the_error_set_maximizing_the_push_work(name, clear):
    robot = Manipulator.preset(name)
    poses = np.array([[1.0, -2.0, math.radians(5.0)], [-3.0, 1.5, math.radians(5.0)]])
    disp, spread = predict_pushes(robot, clear, poses, 7.0)
    G = max_pose_errors(robot, clear, poses, details=True).generators
    W = push_wrenches(robot, 7.0)
    vertices = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))        # (8, 3)
    checked = 0
    for n in range(len(poses)):
        points = vertices @ G[n].T                                             # (8, 3) error-set vertices
        for j in range(len(PUSHES)):
            work = points @ W[j]
            best = np.flatnonzero(work >= work.max() - 1e-12 * abs(work.max()))
            if len(best) == 1:                                                 # a unique vertex: every leg loaded
                np.testing.assert_allclose(disp[n, j], points[best[0]], rtol=1e-9, atol=1e-15)
                assert np.all(spread[n, j] == 0)
                checked += 1
            else:                                                              # a tie: the spread spans the face
                assert np.all(np.abs(points[best] - disp[n, j]) <= spread[n, j] * (1 + 1e-9) + 1e-15)
    assert checked >= 4                                 # the 3-PPR: only +-x load every leg


def test_cli_compare_with_push_force(tmp_path, capsys):
    m = tmp_path / "m.csv"
    assert main(["experiment", "simulate", "--push-n", "10", "--grid", "4", "--seed", "1", "--out", str(m)]) == 0
    capsys.readouterr()
    assert main(["experiment", "compare", "--measurements", str(m), "--push-n", "10", "--format", "json"]) == 0
    out = json.loads(capsys.readouterr().out)
    n = len(out["points"])
    pushes = out["pushes"]["pushes"]
    assert len(pushes) == 6 * n and out["pushes"]["push_n"] == 10.0
    for rec in pushes:
        for q in ("dx", "dy", "dphi_deg"):
            assert rec[f"{q}_diff"] == pytest.approx(rec[f"{q}_meas"] - rec[f"{q}_pred"], abs=1e-12)
    assert main(["experiment", "compare", "--measurements", str(m), "--push-n", "10", "--format", "csv"]) == 0
    rows = list(csv.DictReader(io.StringIO(capsys.readouterr().out)))
    assert len(rows) == 6 * n and [r["push"] for r in rows[:6]] == list(PUSHES)
    assert main(["experiment", "compare", "--measurements", str(m), "--push-n", "10"]) == 0
    text = capsys.readouterr().out
    assert "pushes of 10 N" in text and "dx_pred" in text
    # without --push-n the output is unchanged: no pushes
    assert main(["experiment", "compare", "--measurements", str(m), "--format", "json"]) == 0
    assert "pushes" not in json.loads(capsys.readouterr().out)
    for bad in ("0", "-5"):
        assert main(["experiment", "compare", "--measurements", str(m), "--push-n", bad]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and "--push-n" in err and "Traceback" not in err
