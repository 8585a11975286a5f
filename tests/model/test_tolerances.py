"""Worst-case pose errors under tolerance intervals on link parameters (issue: geometric errors, Eq. 9-14).

Independent checks: the maximum over the tolerance box is found by brute force
over every vertex of the box, with the first-order pose error of
``pose_error`` (Eq. 10), itself checked column by column against finite
differences of an independent loop-closure solver in ``test_error_model.py``;
the worst vertex is also fed to the exact nonlinear model (second-order gap).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from pmaccuracy import Manipulator
from pmaccuracy.accuracy.bounds import load_tolerances, max_pose_errors
from pmaccuracy.cli import main
from pmaccuracy.model.clearances import ClearanceSet
from pmaccuracy.accuracy.error_model import pose_error
from pmaccuracy.errors import ConfigError
from pmaccuracy.accuracy.nonlinear import displaced_pose_error
from pmaccuracy.kinematics.workspace import constant_orientation_workspace

PARAMS = ("a", "alpha", "beta", "d", "gamma", "theta", "r", "psi", "s")


def poses_in(robot: Manipulator, phi: float, n: int, rng: np.random.Generator) -> np.ndarray:
    ws = constant_orientation_workspace(robot, phi)
    (x0, x1), (y0, y1) = ws.bounds
    pts = np.column_stack([rng.uniform(x0, x1, 50 * n), rng.uniform(y0, y1, 50 * n)])
    pts = pts[ws.contains(pts)][:n]
    return np.column_stack([pts, np.full(len(pts), phi)])


def brute_force(robot: Manipulator, poses: np.ndarray, tol: dict[str, np.ndarray]) -> np.ndarray:
    """Max over all 2^(3k) vertices of |dx|, |dy|, |dphi|, |dp| -> (n, 4)."""
    names = list(tol)
    best = np.zeros((len(poses), 4))
    for signs in itertools.product((-1.0, 1.0), repeat=3 * len(names)):
        s = np.array(signs).reshape(len(names), 3)
        e = pose_error(robot, poses, {q: s[j] * tol[q] for j, q in enumerate(names)})
        vals = np.column_stack([np.abs(e[:, 0]), np.abs(e[:, 1]), np.abs(e[:, 2]), np.hypot(e[:, 0], e[:, 1])])
        best = np.maximum(best, vals)
    return best


@pytest.mark.parametrize("robot_name", ["aalborg_3ppr", "symmetric_3ppr"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_tolerance_bounds_equal_brute_force_over_box_vertices(robot_name, seed):
    rng = np.random.default_rng(seed)
    robot = Manipulator.preset(robot_name)
    poses = poses_in(robot, rng.uniform(-0.5, 0.5), 6, rng)
    chosen = rng.choice(PARAMS, size=3, replace=False)
    tol = {q: rng.uniform(0, 1e-3 if q in ("alpha", "beta", "gamma", "theta", "psi") else 0.05, 3) for q in chosen}
    b = max_pose_errors(robot, ClearanceSet(), poses, tolerances=tol)
    expected = brute_force(robot, poses, tol)
    got = np.column_stack([b.dx_max, b.dy_max, b.dphi_max, b.dp_max])
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-15)


def test_clearances_and_tolerances_add_for_axis_bounds():
    """Half-widths add, so the support functions (dx, dy, dphi) are additive; dp is sub-additive."""
    robot = Manipulator.preset("aalborg_3ppr")
    poses = poses_in(robot, 0.3, 20, np.random.default_rng(5))
    tol = load_tolerances("example_tolerances")
    both = max_pose_errors(robot, ClearanceSet.load("case2"), poses, tolerances=tol)
    clear = max_pose_errors(robot, ClearanceSet.load("case2"), poses)
    only = max_pose_errors(robot, ClearanceSet.load("none"), poses, tolerances=tol)
    for q in ("dx_max", "dy_max", "dphi_max"):
        np.testing.assert_allclose(getattr(both, q), getattr(clear, q) + getattr(only, q), rtol=1e-12)
    assert np.all(both.dp_max <= clear.dp_max + only.dp_max + 1e-12)
    assert np.all(both.dp_max >= np.maximum(clear.dp_max, only.dp_max) - 1e-12)


def test_worst_variations_attain_the_bounds_and_match_exact_model_to_second_order():
    robot = Manipulator.preset("aalborg_3ppr")
    poses = poses_in(robot, 0.0, 8, np.random.default_rng(3))
    tol = {"theta": np.full(3, 1e-3), "d": np.array([0.05, 0.02, 0.03]), "psi": np.full(3, 2e-3)}
    b = max_pose_errors(robot, ClearanceSet(), poses, tolerances=tol, details=True)
    for row, q in enumerate(("dx", "dy", "dphi")):
        e = pose_error(robot, poses, b.worst_variations[q])
        np.testing.assert_allclose(e[:, row], getattr(b, f"{q}_max"), rtol=1e-12)
    var = b.worst_variations["dp"]
    for q, v in var.items():
        assert np.all(np.isclose(np.abs(v), tol[q]))
    lin = pose_error(robot, poses, var)
    np.testing.assert_allclose(np.hypot(lin[:, 0], lin[:, 1]), b.dp_max, rtol=1e-12)
    gaps = []
    for f in (1.0, 0.5):
        exact = displaced_pose_error(robot, poses, variations={q: f * v for q, v in var.items()})
        gaps.append(np.max(np.abs(exact - f * lin)))
    assert 3.0 < gaps[0] / gaps[1] < 5.0  # second order: halving the errors quarters the gap


@pytest.mark.parametrize("tol, match", [({"nope": [1, 1, 1]}, "unknown parameter"),
                                        ({"d": [-0.1, 0, 0]}, ">= 0"),
                                        ({"theta": [np.nan, 0, 0]}, "finite")])
def test_bad_tolerances_raise(tol, match):
    with pytest.raises(ConfigError, match=match):
        max_pose_errors(Manipulator.preset(), ClearanceSet(), [0.0, 0.0, 0.0], tolerances=tol)


def test_cli_tolerances_json_matches_library(capsys):
    status = main(["bounds", "--clearances", "none", "--tolerances", "example_tolerances", "--pose", "5", "-3",
                   "10", "--format", "json"])
    out = capsys.readouterr().out
    assert status == 0
    import json

    rec = json.loads(out)[0]
    b = max_pose_errors(Manipulator.preset(), ClearanceSet(), [5.0, -3.0, np.radians(10)],
                        tolerances=load_tolerances("example_tolerances"))
    assert rec["dp_max"] == pytest.approx(float(b.dp_max), rel=1e-12)
    assert rec["dphi_max_deg"] == pytest.approx(float(b.dphi_max_deg), rel=1e-12)


def test_cli_negative_tolerance_file_exits_2_naming_file(tmp_path, capsys):
    path = tmp_path / "tol.toml"
    path.write_text('name = "t"\n[[legs]]\nd_mm = -1\n[[legs]]\n[[legs]]\n', encoding="utf-8")
    status = main(["bounds", "--tolerances", str(path), "--pose", "0", "0", "0"])
    err = capsys.readouterr().err
    assert status == 2 and str(path) in err and "tolerances.d" in err and len(err.strip().splitlines()) == 1


def _measurement_file(path, y_nom: float) -> None:
    rows = ["point,x_nom,y_nom,phi_nom_deg,push,x,y,phi_deg"]
    for push, (dx, dy, dphi) in {"+x": (0.3, 0, 0), "-x": (-0.3, 0, 0), "+y": (0, 0.12, 0), "-y": (0, -0.12, 0),
                                 "+r": (0, 0, 0.3), "-r": (0, 0, -0.3)}.items():
        rows.append(f"1,40.0,{y_nom},30,{push},{40.0 + dx},{y_nom + dy},{30 + dphi}")
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")


def test_compare_accepts_nominal_pose_printed_on_the_boundary(tmp_path, capsys):
    """y = -14.02 mm at phi = 30 deg is the reference's rounded boundary, 0.8 um beyond the stroke."""
    path = tmp_path / "m.csv"
    _measurement_file(path, -14.02)
    assert main(["experiment", "compare", "--measurements", str(path), "--format", "json"]) == 0
    _measurement_file(path, -14.2)  # 0.18 mm outside: refused
    assert main(["experiment", "compare", "--measurements", str(path)]) == 2
    assert "outside the joint ranges" in capsys.readouterr().err
