"""Design comparison (pmaccuracy.accuracy.designs, ``pmaccuracy compare-designs``) against separately written references.

The references below walk the grids point by point with plain Python loops,
calling the workspace's ``contains``, ``regular_mask`` and ``max_pose_errors``
on one pose at a time; the library works on whole arrays.
"""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from pmaccuracy.accuracy import designs
from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.cli import main
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.kinematics import regular_mask
from pmaccuracy.io.resolve import load_clearances
from pmaccuracy.kinematics.workspace import constant_orientation_workspace

TRIO = (("symmetric_3rpr", "rpr_typical"), ("symmetric_3rrr", "rrr_typical"), ("symmetric_3prr", "prr_typical"))
N = 17  # grid points per axis in the brute-force comparisons (the references loop in Python)


@pytest.fixture(scope="module")
def trio():
    robots = [Manipulator.load(r) for r, _ in TRIO]
    clearances = [load_clearances(c, r) for (_, c), r in zip(TRIO, robots)]
    return robots, clearances


@pytest.fixture(scope="module")
def result(trio):
    robots, clearances = trio
    return designs.compare_designs(robots, clearances, np.radians([0.0, 30.0]), N)


# ---------------------------------------------------------------------------------- independent references
def _one_pose(robot, clearances, x, y, phi):
    """[dx, dy, dphi, dp] at one pose, or None when the pose is near a singularity."""
    pose = np.array([[x, y, phi]])
    if not bool(regular_mask(robot, pose)[0]):
        return None
    b = max_pose_errors(robot, clearances, pose, allow_outside=True)
    return [float(b.dx_max[0]), float(b.dy_max[0]), float(b.dphi_max[0]), float(b.dp_max[0])]


def _brute_statistics(robot, clearances, phi, n):
    """Loop over the n x n grid of the workspace's bounds; mean, max and position of the max per quantity."""
    ws = constant_orientation_workspace(robot, phi)
    (x0, x1), (y0, y1) = ws.bounds
    xs = [x0 + (x1 - x0) * i / (n - 1) for i in range(n)]
    ys = [y0 + (y1 - y0) * j / (n - 1) for j in range(n)]
    total, count, inside, singular = [0.0] * 4, 0, 0, 0
    best = [(-math.inf, None)] * 4
    for y in ys:          # row-major [y, x] like the library's meshgrid, so ties resolve the same way
        for x in xs:
            if not bool(ws.contains(np.array([x, y]))):
                continue
            inside += 1
            e = _one_pose(robot, clearances, x, y, phi)
            if e is None:
                singular += 1
                continue
            count += 1
            for q in range(4):
                total[q] += e[q]
                if e[q] > best[q][0]:
                    best[q] = (e[q], (x, y))
    return ws.area, inside, singular, [t / count for t in total], best


def _brute_shared(robots, clearances, phi, n):
    """Shared region by testing every grid point of the intersected boxes against each workspace, and ratios."""
    spaces = [constant_orientation_workspace(r, phi) for r in robots]
    x0 = max(ws.bounds[0][0] for ws in spaces)
    x1 = min(ws.bounds[0][1] for ws in spaces)
    y0 = max(ws.bounds[1][0] for ws in spaces)
    y1 = min(ws.bounds[1][1] for ws in spaces)
    xs = np.linspace(x0, x1, n)
    ys = np.linspace(y0, y1, n)
    inside = np.zeros((n, n), dtype=bool)
    ratios = {}
    for j, y in enumerate(ys):
        for i, x in enumerate(xs):
            inside[j, i] = all(bool(ws.contains(np.array([x, y]))) for ws in spaces)
            if inside[j, i]:
                errs = [_one_pose(r, c, x, y, phi) for r, c in zip(robots, clearances)]
                if all(e is not None for e in errs):
                    ratios[(j, i)] = [[e[q] / errs[0][q] for q in range(4)] for e in errs]
    return xs, ys, inside, ratios


# ---------------------------------------------------------------------------------- library
def test_areas_are_the_exact_workspace_areas(trio, result):
    robots, _ = trio
    for p, phi in enumerate(result.phis):
        for k, robot in enumerate(robots):
            assert result.row(p, k).area == constant_orientation_workspace(robot, phi).area
            assert result.workspaces[p][k].area == constant_orientation_workspace(robot, phi).area


def test_statistics_equal_a_pose_by_pose_loop(trio, result):
    robots, clearances = trio
    for p, phi in enumerate(result.phis):
        for k, (robot, cl) in enumerate(zip(robots, clearances)):
            area, inside, singular, mean, best = _brute_statistics(robot, cl, float(phi), N)
            row = result.row(p, k)
            assert (row.n_points, row.n_singular) == (inside, singular)
            np.testing.assert_allclose(row.mean, mean, rtol=1e-12)
            np.testing.assert_allclose(row.max, [b[0] for b in best], rtol=1e-13)
            np.testing.assert_allclose(row.argmax, [b[1] for b in best], rtol=0, atol=1e-9)
    # the grid reaches near-singular points somewhere, so the exclusion is exercised
    assert sum(r.n_singular for r in result.rows) > 0


def test_shared_region_and_ratios_against_contains(trio, result):
    robots, clearances = trio
    for p, phi in enumerate(result.phis):
        xs, ys, inside, ratios = _brute_shared(robots, clearances, float(phi), N)
        region = result.shared[p]
        np.testing.assert_allclose(region.x, xs, rtol=0, atol=1e-12)
        np.testing.assert_allclose(region.y, ys, rtol=0, atol=1e-12)
        assert np.array_equal(region.inside, inside) and inside.any()
        assert set(zip(*np.nonzero(region.regular))) == set(ratios)
        for (j, i), expected in ratios.items():
            np.testing.assert_allclose(region.ratios[:, j, i, :], expected, rtol=1e-12)
        for k in range(len(robots)):
            row = result.row(p, k)
            pool = np.array([ratios[key][k] for key in ratios])
            np.testing.assert_allclose(row.ratio_mean, pool.mean(axis=0), rtol=1e-12)
            np.testing.assert_allclose(row.ratio_min, pool.min(axis=0), rtol=1e-12)
            np.testing.assert_allclose(row.ratio_max, pool.max(axis=0), rtol=1e-12)
            assert row.n_shared == len(ratios)


def test_robot_against_itself_gives_ratio_one_and_identical_statistics():
    robot = Manipulator.load("symmetric_3rrr")
    cl = load_clearances("rrr_typical", robot)
    res = designs.compare_designs([robot, robot], [cl, cl], np.radians([0.0, -30.0]), 31)
    assert res.labels[0] != res.labels[1]  # repeated robot: still told apart
    for p in range(2):
        a, b = res.row(p, 0), res.row(p, 1)
        for name in ("mean", "max", "argmax", "ratio_mean", "ratio_min", "ratio_max"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
        assert (a.area, a.n_points, a.n_singular) == (b.area, b.n_points, b.n_singular)
        r = res.shared[p].ratios
        finite = np.isfinite(r)
        assert finite.any() and np.all(r[finite] == 1.0)
        assert np.all(a.ratio_min == 1.0) and np.all(b.ratio_max == 1.0) and np.all(b.ratio_mean == 1.0)
        # the shared region of a robot with itself is its own workspace's grid
        ws = res.workspaces[p][0]
        x, y, inside = ws.grid(31)
        assert np.array_equal(res.shared[p].inside, inside)


def test_empty_workspace_gives_null_statistics_and_no_shared_region():
    robots = [Manipulator.load("symmetric_3rpr"), Manipulator.load("symmetric_3prr")]
    cls = [load_clearances("rpr_typical", robots[0]), load_clearances("prr_typical", robots[1])]
    res = designs.compare_designs(robots, cls, [np.radians(60.0)], 11)  # the 3-PRR reaches nothing at 60 deg
    empty = res.row(0, 1)
    assert empty.area == 0.0 and empty.n_points == 0 and np.all(np.isnan(empty.mean)) and np.all(np.isnan(empty.max))
    assert res.shared[0].is_empty
    for k in range(2):
        assert np.all(np.isnan(res.row(0, k).ratio_mean)) and res.row(0, k).n_shared == 0
    assert np.isfinite(res.row(0, 0).mean).all()


def test_array_helpers_refuse_to_invent_numbers():
    values = np.array([[[np.nan, 1.0], [2.0, 0.0]], [[5.0, 3.0], [4.0, 7.0]]])  # (K=2, 2 points, Q=2)
    r = designs.ratio_fields(values)
    assert np.isnan(r[:, 0, 0]).all()       # reference not evaluated
    assert np.isnan(r[:, 1, 1]).all()       # reference error 0: undefined
    assert r[1, 0, 1] == 3.0 and r[1, 1, 0] == 2.0 and r[0, 1, 0] == 1.0
    mean, vmax, at = designs.field_statistics(np.array([[np.nan, np.nan], [1.0, np.nan], [3.0, np.nan]]),
                                              np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 5.0]]))
    assert mean[0] == 2.0 and vmax[0] == 3.0 and at[0].tolist() == [2.0, 5.0]
    assert np.isnan(mean[1]) and np.isnan(vmax[1]) and np.isnan(at[1]).all()
    m, lo, hi = designs.ratio_statistics(np.full((3, 2), np.nan))
    assert np.isnan(m).all() and np.isnan(lo).all() and np.isnan(hi).all()


# ---------------------------------------------------------------------------------- CLI
def _cli(capsys, *argv):
    status = main(["compare-designs", *argv])
    out, err = capsys.readouterr()
    return status, out, err


def _trio_args(*extra):
    args = []
    for r, c in TRIO:
        args += ["--robot", r]
    for r, c in TRIO:
        args += ["--clearances", c]
    return args + list(extra)


def test_cli_json_csv_plot_match_the_library(capsys, tmp_path, trio):
    robots, clearances = trio
    plot, out = tmp_path / "figs" / "cmp.png", tmp_path / "tables" / "cmp.csv"
    status, text, err = _cli(capsys, *_trio_args("--phi-deg", "0", "--phi-deg", "30", "--grid", str(N),
                                                 "--plot", str(plot), "--out", str(out), "--format", "json"))
    assert status == 0, err
    records = json.loads(text)
    expected = designs.compare_designs(robots, clearances, np.radians([0.0, 30.0]), N).records()
    assert [r["robot"] for r in records] == [r for r, _ in TRIO] * 2
    assert [r["phi_deg"] for r in records] == [0.0] * 3 + [30.0] * 3
    assert records == expected  # JSON floats round-trip exactly; no NaN here
    assert all(r["dphi_max_deg"] == math.degrees(row.max[2]) for r, row in
               zip(records, designs.compare_designs(robots, clearances, np.radians([0.0, 30.0]), N).rows))
    with open(out, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [float(r["dp_ratio_mean"]) for r in rows] == [r["dp_ratio_mean"] for r in records]
    assert [float(r["area_mm2"]) for r in rows] == [r["area_mm2"] for r in records]
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_table_has_three_blocks_and_one_clearance_for_all(capsys):
    status, text, err = _cli(capsys, "--robot", "symmetric_3rrr", "--robot", "symmetric_3rrr", "--clearances",
                             "rrr_typical", "--phi-deg", "0", "--grid", "9")
    assert status == 0, err
    blocks = text.strip().split("\n\n")
    assert len(blocks) == 3
    assert blocks[0].splitlines()[0].split()[:4] == ["robot", "clearances", "phi_deg", "area_mm2"]
    assert "dp_ratio_max" in blocks[2].splitlines()[0]
    assert all(v == "1" for line in blocks[2].splitlines()[1:] for v in line.split()[3:])


def test_cli_empty_shared_region_says_so_in_one_line(capsys, tmp_path):
    # at 60 deg the 3-PRR reaches nothing; at -30 deg the symmetric 3-RPR is singular at every position
    # (--quiet: the first-order validity warning of the grid's near-singular points is not the subject here)
    plot = tmp_path / "empty.png"
    status, text, err = _cli(capsys, "--robot", "symmetric_3rpr", "--robot", "symmetric_3prr", "--clearances",
                             "rpr_typical", "--clearances", "prr_typical", "--phi-deg", "60", "--phi-deg", "-30",
                             "--grid", "9", "--format", "json", "--plot", str(plot), "--quiet")
    assert status == 0 and plot.exists()
    lines = err.strip().splitlines()
    assert len(lines) == 2
    assert "60 deg" in lines[0] and "share no region" in lines[0]
    assert "-30 deg" in lines[1] and "near a singularity" in lines[1]
    records = json.loads(text)
    assert all(r["dp_ratio_mean"] is None and r["shared_points"] == 0 for r in records)
    assert records[1]["area_mm2"] == 0.0 and records[1]["dp_max"] is None
    rpr = records[2]
    assert rpr["area_mm2"] > 0 and rpr["points"] > 0 and rpr["singular"] == rpr["points"] and rpr["dp_mean"] is None
    # and the 3-RPR is indeed singular there (condition number of A, not the grid mask)
    robot = Manipulator.load("symmetric_3rpr")
    from pmaccuracy.kinematics import singularity
    poses = np.array([[0.0, 0.0, math.radians(-30)], [20.0, -10.0, math.radians(-30)]])
    assert np.all(singularity(robot, poses).condition > 100)


@pytest.fixture
def no_compute(monkeypatch):
    """Bad options must be refused before anything is computed."""
    def refuse(*args, **kwargs):
        raise AssertionError("compare_designs was called")
    monkeypatch.setattr(designs, "compare_designs", refuse)


@pytest.mark.parametrize("argv, words", [
    (["--robot", "symmetric_3rpr", "--robot", "symmetric_3rrr", "--robot", "symmetric_3prr",
      "--clearances", "rpr_typical", "--clearances", "rrr_typical", "--phi-deg", "0"], ["--clearances", "3 robots"]),
    (["--robot", "symmetric_3rpr", "--robot", "no_such_robot", "--clearances", "rpr_typical", "--phi-deg", "0"],
     ["no_such_robot"]),
    (["--robot", "symmetric_3rpr", "--robot", "symmetric_3rrr", "--clearances", "rpr_typical",
      "--phi-deg", "0"], ["rpr_typical", "legs[1].joints[2].actuator", "--robot symmetric_3rrr"]),
    (["--robot", "symmetric_3rpr", "--robot", "aalborg_3ppr", "--clearances", "case1", "--phi-deg", "0"],
     ["case1", "3-RPR", "--robot symmetric_3rpr"]),
    (["--robot", "symmetric_3rpr", "--clearances", "rpr_typical", "--phi-deg", "0"], ["at least two"]),
    (["--robot", "symmetric_3rpr", "--robot", "symmetric_3rrr", "--clearances", "rpr_typical",
      "--clearances", "rrr_typical", "--phi-deg", "0", "--phi-deg", "0"], ["--phi-deg", "twice"]),
])
def test_cli_bad_options_exit_2_with_one_line(capsys, no_compute, argv, words):
    status, text, err = _cli(capsys, *argv)
    assert status == 2 and text == ""
    assert len(err.strip().splitlines()) == 1 and err.startswith("pmaccuracy compare-designs: error:")
    for w in words:
        assert w in err


@pytest.mark.parametrize("option", ["--plot", "--out"])
def test_cli_unwritable_output_refused_before_computing(capsys, tmp_path, no_compute, option):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    target = blocker / ("x.png" if option == "--plot" else "x.csv")
    status, text, err = _cli(capsys, "--robot", "symmetric_3rpr", "--robot", "symmetric_3rrr", "--clearances",
                             "rpr_typical", "--clearances", "rrr_typical", "--phi-deg", "0", option, str(target))
    assert status == 2 and text == ""
    assert len(err.strip().splitlines()) == 1 and option in err and "a_file" in err
