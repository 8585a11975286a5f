"""Experimental validation (paper Sec. 5.2, 6; Eq. 23-24): measurement files, Eq. 23, comparison, virtual rig.

The hand-made file ``tests/data/hand_measurements.csv`` has three points
(A and B at phi = 0, C at phi = 30 deg; C's rows are in scrambled push order).
Its Eq. 23 values were worked out by hand:

    A: dx = 0.20 - (-0.22) = 0.42, dy = 0.10 - (-0.12) = 0.22, dphi = 0.20 - (-0.21) = 0.41 deg,
       dp_t^2 = 0.42^2 + 0.03^2 = 0.1773 (x), 0.04^2 + 0.22^2 = 0.05 (y), 0.11^2 + 0.07^2 = 0.017 (r)
    B: dx = 10.25 - 9.80 = 0.45, dy = -4.90 - (-5.08) = 0.18, dphi = 0.25 - (-0.15) = 0.40 deg,
       dp_t^2 = 0.2034, 0.0333, 0.0068
    C: dx = 10.15 - 9.84 = 0.31, dy = 0.09 - (-0.08) = 0.17, dphi = 30.18 - 29.80 = 0.38 deg,
       dp_t^2 = 0.097, 0.0314, 0.0106
"""

from __future__ import annotations

import csv
import json
import math
import statistics
from pathlib import Path

import numpy as np
import pytest

from pmaccuracy import Manipulator
from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.model.clearances import ClearanceSet
from pmaccuracy.errors import ConfigError, MeasurementFileError, OutsideJointLimitsError
from pmaccuracy.experiment import PUSHES, Measurements, compare, grid_poses, load_measurements, measured_errors, push_configurations, simulate_experiment, simulate_readings, write_measurements
from pmaccuracy.report.experiment_plots import plot_boxplots
from pmaccuracy.report.experiment_report import virtual_experiment_section, write_report

DATA = Path(__file__).resolve().parents[1] / "data"
HAND = DATA / "hand_measurements.csv"
HAND_LINES = HAND.read_text(encoding="utf-8").splitlines()


# ----------------------------------------------------------------------------------- Eq. 23 by hand
def test_eq23_on_the_hand_made_file():
    m = load_measurements(HAND)
    assert list(m.points) == ["A", "B", "C"]
    assert m.readings.shape == (3, 6, 3) and m.nominal.shape == (3, 3)
    np.testing.assert_allclose(m.nominal[2], [10.0, 0.0, math.radians(30.0)], atol=1e-15)
    # C's rows are scrambled: the loader puts them in push order +x, -x, +y, -y, +r, -r.
    np.testing.assert_allclose(m.readings[2, :, 0], [10.15, 9.84, 10.03, 9.98, 10.04, 9.95], atol=1e-12)
    e = measured_errors(m)
    np.testing.assert_allclose(e.dx, [0.42, 0.45, 0.31], atol=1e-12)
    np.testing.assert_allclose(e.dy, [0.22, 0.18, 0.17], atol=1e-12)
    np.testing.assert_allclose(e.dphi_deg, [0.41, 0.40, 0.38], atol=1e-12)
    np.testing.assert_allclose(e.dp_axes ** 2, [[0.1773, 0.05, 0.017], [0.2034, 0.0333, 0.0068],
                                                [0.097, 0.0314, 0.0106]], atol=1e-12)
    np.testing.assert_allclose(e.dp, np.sqrt([0.1773, 0.2034, 0.097]), atol=1e-12)


def _independent_statistics(path: Path, clearances: str) -> dict:
    """RMSD, SSD and band shares recomputed from the CSV with the csv module and plain Python."""
    rows: dict[str, dict[str, list[float]]] = {}
    nominal: dict[str, tuple[float, float, float]] = {}
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            rows.setdefault(r["point"], {})[r["push"]] = [float(r["x"]), float(r["y"]), float(r["phi_deg"])]
            nominal[r["point"]] = (float(r["x_nom"]), float(r["y_nom"]), float(r["phi_nom_deg"]))
    names = list(rows)
    meas = {"dx": [], "dy": [], "dp": [], "dphi_deg": []}
    for name in names:
        p = rows[name]
        for key, col in (("dx", 0), ("dy", 1), ("dphi_deg", 2)):
            vals = [p[push][col] for push in PUSHES]
            meas[key].append(max(vals) - min(vals))
        meas["dp"].append(max(math.dist(p["+" + t][:2], p["-" + t][:2]) for t in "xyr"))
    poses = np.array([[nominal[n][0], nominal[n][1], math.radians(nominal[n][2])] for n in names])
    b = max_pose_errors(Manipulator.preset("aalborg_3ppr"), ClearanceSet.load(clearances), poses)
    pred = {"dx": b.dx_max.tolist(), "dy": b.dy_max.tolist(), "dp": b.dp_max.tolist(),
            "dphi_deg": np.degrees(b.dphi_max).tolist()}
    out = {"rmsd": {}, "rmsd2": {}, "ssd": {}, "share": {}}
    for q in meas:
        n = len(names)
        out["rmsd"][q] = math.sqrt(sum((m - p) ** 2 for m, p in zip(meas[q], pred[q])) / n)
        out["rmsd2"][q] = math.sqrt(sum((m - 2 * p) ** 2 for m, p in zip(meas[q], pred[q])) / n)
        out["ssd"][q] = statistics.stdev(meas[q])
        out["share"][q] = sum(abs(p - m) <= 0.02 for m, p in zip(meas[q], pred[q])) / n
    out["ap_p"] = [min(meas["dp"]), max(meas["dp"])]
    out["ap_phi"] = [min(meas["dphi_deg"]), max(meas["dphi_deg"])]
    return out


@pytest.mark.parametrize("clearances", ["case1", "case2"])
def test_comparison_statistics_match_an_independent_computation(clearances):
    c = compare("aalborg_3ppr", clearances, HAND)
    ref = _independent_statistics(HAND, clearances)
    for q in ("dx", "dy", "dp", "dphi_deg"):
        assert c.rmsd(1.0)[q] == pytest.approx(ref["rmsd"][q], abs=1e-12)
        assert c.rmsd(2.0)[q] == pytest.approx(ref["rmsd2"][q], abs=1e-12)
        assert c.sample_std()[q] == pytest.approx(ref["ssd"][q], abs=1e-12)
        assert c.band(1.0)[q]["share"] == pytest.approx(ref["share"][q])
    acc = c.accuracy()
    assert acc["position"] == pytest.approx(ref["ap_p"], abs=1e-12)
    assert acc["orientation_deg"] == pytest.approx(ref["ap_phi"], abs=1e-12)
    s = c.summary()
    assert s["rmsd"] == pytest.approx(ref["rmsd"], abs=1e-12)
    assert [o["phi_deg"] for o in s["orientations"]] == [0.0, 30.0]
    assert [o["n_points"] for o in s["orientations"]] == [2, 1]
    json.dumps(s)  # JSON-ready (NaN only where it is allowed)


def test_write_then_load_round_trips(tmp_path):
    m = load_measurements(HAND)
    back = load_measurements(write_measurements(tmp_path / "sub" / "copy.csv", m))
    assert list(back.points) == list(m.points)
    np.testing.assert_array_equal(back.nominal[:, :2], m.nominal[:, :2])
    np.testing.assert_array_equal(back.readings[..., :2], m.readings[..., :2])
    np.testing.assert_allclose(back.readings[..., 2], m.readings[..., 2], rtol=0, atol=1e-15)
    assert back.lines[0].tolist() == [2, 3, 4, 5, 6, 7]


def test_readings_near_180_deg_do_not_wrap(tmp_path):
    rows = ["point,x_nom,y_nom,phi_nom_deg,push,x,y,phi_deg"]
    for push, phi in zip(PUSHES, [179.9, -179.95, 180.0, 179.95, -179.9, 179.8]):
        rows.append(f"P,0,0,180,{push},0,0,{phi}")
    path = tmp_path / "wrap.csv"
    path.write_text("\n".join(rows) + "\n")
    assert measured_errors(load_measurements(path)).dphi_deg[0] == pytest.approx(0.3, abs=1e-9)  # +0.1 - (-0.2)


# ----------------------------------------------------------------------------------- malformed files
def _edit(lines: list[str], line: int, column: str, value: str) -> None:
    cols = lines[0].split(",")
    cells = lines[line - 1].split(",")
    cells[cols.index(column)] = value
    lines[line - 1] = ",".join(cells)


def _case(change):
    lines = list(HAND_LINES)
    out = change(lines)
    return "\n".join(out if out is not None else lines) + "\n"


MALFORMED = {
    # id: (file text, substrings the message must contain)
    "wrong-header": (_case(lambda ls: ["point,x,y,phi,push,x_meas,y_meas,phi_meas"] + ls[1:]), ["line 1", "header"]),
    "empty-file": ("", ["line 1", "empty"]),
    "header-only": (HAND_LINES[0] + "\n", ["no readings"]),
    "missing-push": (_case(lambda ls: ls[:16] + ls[17:]), ["point C", "line 14", "missing", "+y"]),
    "missing-two-pushes": (_case(lambda ls: ls[:2] + ls[4:]), ["point A", "+x", "-x"]),
    "duplicate-row": (_case(lambda ls: ls + [ls[1]]), ["line 20", "point A", "+x", "repeated", "line 2"]),
    "duplicate-push-other-values": (_case(lambda ls: ls[:7] + ["A,0,0,0,+r,0.01,0.02,0.19"] + ls[7:]),
                                    ["line 8", "+r", "repeated", "line 6"]),
    "unknown-push": (_case(lambda ls: _edit(ls, 5, "push", "+z")), ["line 5", "+z"]),
    "non-numeric": (_case(lambda ls: _edit(ls, 3, "x", "abc")), ["line 3", "column x", "not a number"]),
    "non-numeric-nominal": (_case(lambda ls: _edit(ls, 9, "y_nom", "-5mm")), ["line 9", "y_nom"]),
    "empty-value": (_case(lambda ls: _edit(ls, 10, "phi_deg", "")), ["line 10", "phi_deg"]),
    "nan": (_case(lambda ls: _edit(ls, 4, "y", "nan")), ["line 4", "not finite"]),
    "inf": (_case(lambda ls: _edit(ls, 11, "x_nom", "inf")), ["line 11", "not finite"]),
    "inconsistent-nominal": (_case(lambda ls: _edit(ls, 9, "y_nom", "-5.5")), ["line 9", "point B", "nominal",
                                                                               "line 8"]),
    "too-few-columns": (_case(lambda ls: ls[:5] + [ls[5].rsplit(",", 1)[0]] + ls[6:]), ["line 6", "got 7"]),
    "empty-label": (_case(lambda ls: _edit(ls, 7, "point", "")), ["line 7", "label"]),
    "reading-in-metres": (_case(lambda ls: _edit(ls, 8, "x", "0.01025")), ["line 8", "point B", "units", "mm"]),
    "orientation-in-radians": (_case(lambda ls: _edit(ls, 15, "phi_deg", "0.5239")),
                               ["line 15", "point C", "radians"]),
}


@pytest.mark.parametrize("case", MALFORMED, ids=list(MALFORMED))
def test_malformed_files_raise_naming_the_row(case, tmp_path):
    text, needles = MALFORMED[case]
    path = tmp_path / f"{case}.csv"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(MeasurementFileError) as info:
        load_measurements(path)
    message = str(info.value)
    assert str(path) in message
    for needle in needles:
        assert needle in message, (needle, message)
    assert isinstance(info.value, ConfigError)


def test_missing_file_raises(tmp_path):
    with pytest.raises(MeasurementFileError, match="no such file"):
        load_measurements(tmp_path / "nope.csv")


def test_blank_lines_are_the_only_thing_skipped(tmp_path):
    path = tmp_path / "blank.csv"
    path.write_text("\n".join(HAND_LINES[:4] + ["", "  ,  ,,,,,,"] + HAND_LINES[4:]) + "\n")
    m = load_measurements(path)
    assert len(m) == 3 and m.lines[0].tolist() == [2, 3, 4, 7, 8, 9]


def test_nominal_pose_outside_the_joint_ranges_names_the_point(tmp_path):
    lines = list(HAND_LINES)
    for ln in range(8, 14):  # point B moved to x = 60 mm: outside the 50 mm square at phi = 0
        _edit(lines, ln, "x_nom", "60")
        cells = lines[ln - 1].split(",")
        cells[5] = str(float(cells[5]) + 50)
        lines[ln - 1] = ",".join(cells)
    path = tmp_path / "outside.csv"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(OutsideJointLimitsError, match=r"point B \(line 8\).*outside the joint ranges"):
        compare("aalborg_3ppr", "case1", path)


# ----------------------------------------------------------------------------------- virtual experiment
PHIS = (0.0, math.radians(30.0))


@pytest.mark.parametrize("clearances", ["case1", "case2", "all"])
@pytest.mark.parametrize("phi", PHIS, ids=["phi0", "phi30"])
def test_first_order_full_take_up_gives_exactly_twice_the_maxima(aalborg, clearances, phi):
    m = simulate_experiment(aalborg, clearances, phi, 7, noise_mm=0, noise_deg=0, model="first_order")
    b = max_pose_errors(aalborg, ClearanceSet.load(clearances), m.nominal)
    e = measured_errors(m)
    assert len(m) >= 20
    np.testing.assert_allclose(e.dx, 2 * b.dx_max, rtol=0, atol=1e-12)
    np.testing.assert_allclose(e.dy, 2 * b.dy_max, rtol=0, atol=1e-12)
    np.testing.assert_allclose(e.dphi, 2 * b.dphi_max, rtol=0, atol=1e-12)
    assert np.all(e.dp <= 2 * b.dp_max + 1e-12)
    # The paper's direct RMSD is then simply the RMS of the maxima themselves; the width-consistent one vanishes.
    c = compare(aalborg, clearances, m)
    assert c.rmsd(2.0)["dx"] < 1e-12 and c.rmsd(2.0)["dphi_deg"] < 1e-10
    assert c.rmsd(1.0)["dx"] == pytest.approx(float(np.sqrt(np.mean(b.dx_max ** 2))), rel=1e-12)


@pytest.mark.parametrize("take_up", [0.0, 0.35, 1.0])
def test_take_up_scales_the_ranges(aalborg, take_up):
    m = simulate_experiment(aalborg, "case2", 0.0, 5, take_up=take_up, noise_mm=0, noise_deg=0, model="first_order")
    b = max_pose_errors(aalborg, ClearanceSet.preset("case2"), m.nominal)
    e = measured_errors(m)
    np.testing.assert_allclose(e.dx, 2 * take_up * b.dx_max, rtol=0, atol=1e-12)
    np.testing.assert_allclose(e.dphi, 2 * take_up * b.dphi_max, rtol=0, atol=1e-12)


@pytest.mark.parametrize("phi", PHIS, ids=["phi0", "phi30"])
def test_exact_readings_agree_to_second_order(aalborg, phi):
    cl = ClearanceSet.preset("all")
    m = simulate_experiment(aalborg, cl, phi, 7, noise_mm=0, noise_deg=0)  # default model: exact
    b = max_pose_errors(aalborg, cl, m.nominal)
    e = measured_errors(m)
    for meas, pred in ((e.dx, b.dx_max), (e.dy, b.dy_max), (e.dphi, b.dphi_max)):
        rel = np.abs(meas / (2 * pred) - 1)
        assert rel.max() < 1e-3          # the brief's bound; measured ~2e-5
        assert rel.max() > 0             # it really is the nonlinear model
    assert np.all(e.dp <= 2 * b.dp_max * (1 + 1e-3))


def test_push_configurations_are_feasible_and_mirrored(aalborg):
    cl = ClearanceSet.preset("all")
    poses = grid_poses(aalborg, 0.0, 4)
    b = max_pose_errors(aalborg, cl, poses, details=True)
    pushes = push_configurations(b, 1.0)
    assert len(pushes) == len(PUSHES)
    for d in pushes:
        assert np.all(d.violation(cl) <= 1e-9)
    np.testing.assert_array_equal(pushes[1].tau_b, -pushes[0].tau_b)


def _expected_noise_rms(noiseless: np.ndarray, sigma: float, tol: float) -> float:
    """RMS of (noisy range - noiseless range) predicted from the tie structure of the noiseless readings.

    With k readings tied at an extreme and the others several sigma away, that end
    of the range moves by the maximum M_k of k independent N(0, sigma^2) noises
    (the minimum, mirrored, at the other end). E[M_1] = 0, E[M_2] = sigma/sqrt(pi),
    E[M_k^2] = sigma^2 for k = 1, 2 (max^2 and min^2 of two symmetric variables are
    equally distributed). So E[(R - R0)^2] = 2 sigma^2 + 2 E[M_top] E[M_bottom].
    """
    top = np.sum(noiseless >= noiseless.max(axis=1, keepdims=True) - tol, axis=1)
    bottom = np.sum(noiseless <= noiseless.min(axis=1, keepdims=True) + tol, axis=1)
    assert set(top.tolist()) | set(bottom.tolist()) <= {1, 2}
    mean_max = np.where(top == 2, sigma / math.sqrt(math.pi), 0.0)
    mean_min = np.where(bottom == 2, sigma / math.sqrt(math.pi), 0.0)
    return float(np.sqrt(np.mean(2 * sigma ** 2 + 2 * mean_max * mean_min)))


def test_noise_level_is_recovered_statistically(aalborg):
    """With noise sigma, the RMSD of (measured - 2 predicted) is sqrt(2) sigma for unique extremes.

    A range of two noisy readings is (mu_a + e_a) - (mu_b + e_b), so range - 2 d_max = e_a - e_b ~ N(0, 2 sigma^2)
    and m RMSD^2 / (2 sigma^2) is chi-square with m degrees of freedom (relative sd of the RMSD ~ 1/sqrt(2m),
    3.4 % for m = 441). For dx and dy of the Aalborg robot the extremes are unique (+x/-x and +y/-y, with margins
    above 7 sigma); for dphi the +x push ties with +r at both ends, which gives sigma sqrt(2 (1 + 1/pi)).
    The paired difference of Eq. 23d-style readings (+t minus -t) is exactly N(2 d_max, 2 sigma^2).
    """
    sigma_mm, sigma_deg = 0.01, 0.01
    clean = simulate_experiment(aalborg, "case2", 0.0, 21, noise_mm=0, noise_deg=0, model="first_order")
    noisy = simulate_experiment(aalborg, "case2", 0.0, 21, noise_mm=sigma_mm, noise_deg=sigma_deg,
                                model="first_order", seed=7)
    m = len(noisy)
    assert m == 441
    c = compare(aalborg, "case2", noisy)
    rmsd2 = c.rmsd(2.0)
    expected = {"dx": _expected_noise_rms(clean.readings[..., 0], sigma_mm, 1e-9),
                "dy": _expected_noise_rms(clean.readings[..., 1], sigma_mm, 1e-9),
                "dphi_deg": _expected_noise_rms(np.degrees(clean.readings[..., 2]), sigma_deg, 1e-9)}
    assert expected["dx"] == pytest.approx(math.sqrt(2) * sigma_mm)
    assert expected["dphi_deg"] == pytest.approx(sigma_deg * math.sqrt(2 * (1 + 1 / math.pi)))
    for q, value in expected.items():
        assert rmsd2[q] == pytest.approx(value, rel=0.15), (q, rmsd2[q], value)
    # Paired +t/-t differences: exactly 2 d_max + N(0, 2 sigma^2); chi-square 99.99 % bounds for 441 dof.
    b = c.predicted
    paired = noisy.readings[:, 0, 0] - noisy.readings[:, 1, 0] - 2 * b.dx_max
    ratio = float(np.mean(paired ** 2)) / (2 * sigma_mm ** 2)
    assert 0.75 < ratio < 1.28
    assert abs(float(np.mean(paired))) < 4 * math.sqrt(2) * sigma_mm / math.sqrt(m)


def test_seed_reproducibility(aalborg):
    a = simulate_experiment(aalborg, "case1", 0.0, 4, seed=3)
    b = simulate_experiment(aalborg, "case1", 0.0, 4, seed=3)
    c = simulate_experiment(aalborg, "case1", 0.0, 4, seed=4)
    np.testing.assert_array_equal(a.readings, b.readings)
    assert not np.array_equal(a.readings, c.readings)


@pytest.mark.parametrize("kwargs, key", [
    ({"take_up": -0.1}, "take_up"), ({"take_up": 1.5}, "take_up"), ({"noise_mm": -0.01}, "noise_mm"),
    ({"noise_deg": -1.0}, "noise_deg"), ({"noise_mm": float("nan")}, "noise_mm"), ({"model": "linear"}, "model"),
])
def test_simulation_refuses_bad_parameters(aalborg, kwargs, key):
    with pytest.raises(ConfigError, match=key):
        simulate_experiment(aalborg, "case1", 0.0, 4, **kwargs)


@pytest.mark.parametrize("grid", [1, 0, -3])
def test_grid_below_two_is_refused(aalborg, grid):
    with pytest.raises(ConfigError, match="at least 2"):
        simulate_experiment(aalborg, "case1", 0.0, grid)


def test_simulate_readings_at_arbitrary_poses(aalborg):
    poses = np.array([[0.0, 0.0, 0.0], [5.0, -3.0, 0.1]])
    m = simulate_readings(aalborg, "case2", poses, noise_mm=0, noise_deg=0, labels=["p", "q"])
    assert list(m.points) == ["p", "q"]
    with pytest.raises(OutsideJointLimitsError):
        simulate_readings(aalborg, "case2", np.array([[80.0, 0.0, 0.0]]))


def test_measurements_are_frozen():
    m = load_measurements(HAND)
    with pytest.raises(ValueError):
        m.readings[0, 0, 0] = 1.0
    with pytest.raises(ConfigError):
        Measurements(points=["a"], nominal=np.zeros((1, 3)), readings=np.zeros((1, 5, 3)))


# ----------------------------------------------------------------------------------- figures and report
def test_report_and_section(tmp_path, aalborg):
    files = write_report(aalborg, "case2", compare(aalborg, "case2", HAND), tmp_path / "rep", map_grid=11)
    html = files["report"].read_text()
    assert html.count("data:image/png;base64,") == len(files) - 2
    assert 'src="http' not in html and "<script" not in html
    saved = json.loads(files["json"].read_text())
    assert set(saved["figures"]) >= {"map_phi0", "map_phi30", "map_phi0_x2", "boxplot", "accuracy", "regression"}

    out = virtual_experiment_section(aalborg, "case2", PHIS, tmp_path / "section", grid=5, map_grid=11, seed=1)
    assert [o["phi_deg"] for o in out["orientations"]] == [0.0, 30.0]
    for name in ("measurements", "comparison_json", "boxplot", "map_phi0", "map_phi30_x2", "accuracy_phi30",
                 "regression_phi0", "regression_phi0_x2"):
        assert Path(out["files"][name]).is_file(), name
    json.dumps(out)
    for o in out["orientations"]:
        assert o["rmsd_width_consistent"]["dx"] < 5 * out["expected_noise_rmsd"]["dx"]
        assert o["rmsd"]["dx"] > 0.1  # the paper's convention leaves a whole maximum of difference
    assert len(load_measurements(out["files"]["measurements"])) == sum(o["n_points"] for o in out["orientations"])


def test_boxplot_has_one_box_per_dataset():
    m = load_measurements(HAND)
    fig = plot_boxplots({f"phi = {phi:g} deg": sub for phi, sub in m.by_orientation().items()})
    assert len(fig.axes) == 4
    assert len(fig.axes[0].get_xticklabels()) == 2
