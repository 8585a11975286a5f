"""ISO 9283 pose accuracy and repeatability (iso9283.py) against independent computations.

References: a plain per-point loop written from the standard's formulas (below, pure Python), pandas
groupby on the raw CSV rows, hand-made cases with known answers, closed forms of the Rayleigh law (noise
only) and of the analytic std of a sum of uniforms (clearances only), computed from the finite-difference
Jacobian of the exact model (``error_reference``).
"""

from __future__ import annotations

import json
import math
import tomllib
from importlib import resources

import numpy as np
import pandas as pd
import pytest

import distribution_reference as dref
import error_reference as eref
from pmaccuracy.experiment import iso9283 as I
from pmaccuracy.errors import ConfigError, MeasurementFileError


def plain_iso(rows, commanded):
    """ISO 9283 figures of one point from a list of (x, y, phi) (mm, mm, rad), written straight from the
    standard: barycentre, AP, l_j, S_l and S_phi with n - 1."""
    n = len(rows)
    xb = sum(r[0] for r in rows) / n
    yb = sum(r[1] for r in rows) / n
    pb = sum(r[2] for r in rows) / n
    ls = [math.sqrt((r[0] - xb) ** 2 + (r[1] - yb) ** 2) for r in rows]
    lb = sum(ls) / n
    sl = math.sqrt(sum((v - lb) ** 2 for v in ls) / (n - 1))
    sp = math.sqrt(sum((r[2] - pb) ** 2 for r in rows) / (n - 1))
    return {"ap_x": xb - commanded[0], "ap_y": yb - commanded[1],
            "ap_p": math.hypot(xb - commanded[0], yb - commanded[1]), "ap_phi": pb - commanded[2],
            "l_bar": lb, "s_l": sl, "rp_l": lb + 3 * sl, "s_phi": sp, "rp_phi": 3 * sp}


def test_hand_made_cases():
    # four poses around the origin at distance 1, commanded at (0.5, 0): AP_p = 0.5, l = 1, RP_l = 1
    att = np.array([[1.0, 0, 0.1], [-1.0, 0, -0.1], [0, 1.0, 0.1], [0, -1.0, -0.1]])
    att[:, 2] = np.radians(att[:, 2])
    f = I.iso_figures(att, np.array([0.5, 0.0, 0.0]))
    assert float(f.ap_p) == pytest.approx(0.5) and float(f.ap_x) == pytest.approx(-0.5)
    assert float(f.l_bar) == pytest.approx(1.0) and float(f.s_l) == pytest.approx(0.0, abs=1e-15)
    assert float(f.rp_l) == pytest.approx(1.0)
    # phi: +-0.1 deg four times, S = sqrt(4 * 0.01 / 3) deg
    assert math.degrees(float(f.rp_phi)) == pytest.approx(3 * math.sqrt(0.04 / 3))
    # l = 1, 1, 3, 3: l_bar = 2, S_l = sqrt(4 / 3), RP_l = 2 + 3 sqrt(4/3)
    att = np.array([[1.0, 0, 0], [-1.0, 0, 0], [3.0, 0, 0], [-3.0, 0, 0]])
    f = I.iso_figures(att, np.zeros(3))
    assert float(f.rp_l) == pytest.approx(2 + 3 * math.sqrt(4 / 3))
    # orientations across +-180 deg are taken relative to the commanded one
    att = np.array([[0, 0, math.radians(179.9)], [0, 0, math.radians(-179.9)]])
    f = I.iso_figures(att, np.array([0, 0, math.pi]))
    assert math.degrees(float(f.ap_phi)) == pytest.approx(0.0, abs=1e-9)
    assert math.degrees(float(f.s_phi)) == pytest.approx(math.sqrt(2 * 0.01), rel=1e-9)


def _random_file(path, rng):
    lines = ["point,x_nom,y_nom,phi_nom_deg,cycle,x,y,phi_deg"]
    truth = {}
    for p in range(6):
        nom = (rng.uniform(-20, 20), rng.uniform(-20, 20), rng.uniform(-30, 30))
        n = int(rng.integers(2, 12))
        rows = []
        for c in rng.permutation(np.arange(1, n + 1)):
            x, y = nom[0] + rng.normal(0.05, 0.1), nom[1] + rng.normal(-0.02, 0.07)
            phi = nom[2] + rng.normal(0.01, 0.05)
            lines.append(f"P{p},{nom[0]!r},{nom[1]!r},{nom[2]!r},{c},{x!r},{y!r},{phi!r}")
            rows.append((x, y, math.radians(phi)))
        truth[f"P{p}"] = plain_iso(rows, (nom[0], nom[1], math.radians(nom[2])))
    path.write_text("\n".join(lines) + "\n")
    return truth


def test_file_figures_against_plain_loop_and_pandas(tmp_path):
    rng = np.random.default_rng(4)
    path = tmp_path / "r.csv"
    truth = _random_file(path, rng)
    rep = I.load_repeats(path)
    f = I.iso_figures(rep.attained, rep.nominal)
    for k, label in enumerate(rep.points):
        for key, want in truth[label].items():
            assert float(getattr(f, key)[k]) == pytest.approx(want, rel=1e-10, abs=1e-13), (label, key)
    # pandas groupby on the raw rows (degrees, no wrapping needed here)
    df = pd.read_csv(path)
    g = df.groupby("point")
    bar = g[["x", "y", "phi_deg"]].transform("mean")
    df["l"] = np.hypot(df.x - bar.x, df.y - bar.y)
    agg = df.groupby("point").agg(l_bar=("l", "mean"), s_l=("l", "std"), s_phi=("phi_deg", "std"),
                                  x=("x", "mean"), x_nom=("x_nom", "first"))
    for k, label in enumerate(rep.points):
        row = agg.loc[label]
        assert float(f.rp_l[k]) == pytest.approx(row.l_bar + 3 * row.s_l, rel=1e-10)
        assert math.degrees(float(f.rp_phi[k])) == pytest.approx(3 * row.s_phi, rel=1e-9)
        assert float(f.ap_x[k]) == pytest.approx(row.x - row.x_nom, rel=1e-9, abs=1e-12)


def test_write_and_read_back(tmp_path):
    att = np.random.default_rng(1).normal(0, 0.05, (3, 4, 3)) + np.array([1.0, 2.0, 0.1])
    rep = I.RepeatedPoses.from_arrays(np.tile([1.0, 2.0, 0.1], (3, 1)), att)
    back = I.load_repeats(I.write_repeats(tmp_path / "r.csv", rep))
    np.testing.assert_allclose(back.attained, rep.attained, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(back.cycles, rep.cycles)


HEADER = "point,x_nom,y_nom,phi_nom_deg,cycle,x,y,phi_deg\n"


@pytest.mark.parametrize("body,line,word", [
    ("a,0,0,0,1,0.1,0,0\n", 2, "at least 2"),
    ("a,0,0,0,1,0.1,0,0\na,0,0,0,1,0.1,0,0\n", 3, "cycle 1 repeated"),
    ("a,0,0,0,0,0.1,0,0\n", 2, "cycle"),
    ("a,0,0,0,1.5,0.1,0,0\n", 2, "cycle"),
    ("a,0,0,0,1,x,0,0\n", 2, "column x"),
    ("a,0,0,0,1,0.1,0,nan\n", 2, "not finite"),
    ("a,0,0,0,1,0.1,0,0\na,1,0,0,2,0.1,0,0\n", 3, "differs"),
    ("a,0,0,0,1,10,0,0\n", 2, "wrong units"),
    ("a,0,0,30,1,0,0,0.52\n", 2, "degrees"),
    ("a,0,0,0,1,0.1,0\n", 2, "expected 8 values"),
])
def test_bad_files_name_the_line(tmp_path, body, line, word):
    path = tmp_path / "r.csv"
    path.write_text(HEADER + body)
    with pytest.raises(MeasurementFileError) as exc:
        I.load_repeats(path)
    assert f"line {line}" in str(exc.value) and word in str(exc.value)


def test_bad_header_and_missing_file(tmp_path):
    path = tmp_path / "r.csv"
    path.write_text("point,x_nom,y_nom,phi_nom_deg,push,x,y,phi_deg\n")
    with pytest.raises(MeasurementFileError, match="line 1.*header"):
        I.load_repeats(path)
    with pytest.raises(MeasurementFileError, match="no such file"):
        I.load_repeats(tmp_path / "missing.csv")


# ------------------------------------------------------------------ model prediction
def test_noise_only_prediction_is_the_rayleigh_law():
    """No clearance, Gaussian noise sigma: l is Rayleigh, E l = sigma sqrt(pi/2), sd l = sigma sqrt(2 - pi/2);
    phi normal: RP_phi -> 3 sigma (many cycles)."""
    s, sd = 0.01, 0.02
    p = I.predicted_repeatability("aalborg_3ppr", "none", [[0.0, 0.0, 0.0]], 4000, tests=25, noise_mm=s,
                                  noise_deg=sd, seed=2)
    want = s * (math.sqrt(math.pi / 2) + 3 * math.sqrt(2 - math.pi / 2))
    assert abs(p.rp_l[0] - want) <= 4 * p.rp_l_se[0] + 1e-3 * want
    assert abs(math.degrees(p.rp_phi[0]) - 3 * sd) <= 4 * math.degrees(p.rp_phi_se[0]) + 1e-3 * 3 * sd


def _robot_dict(name):
    return tomllib.loads((resources.files("pmaccuracy") / "data" / "robots" / f"{name}.toml").read_text())


def test_clearance_prediction_against_the_exact_law():
    """case1 at the origin: dphi is a sum of three uniforms (half-widths from the FD Jacobian of the exact
    model), so RP_phi -> 3 sd; l = |(dx, dy)| with dx, dy linear in the same three uniforms: E l and sd l by
    a midpoint rule over the cube of the three bearing states."""
    spec = {"legs": [{"joints": [{}, {"angular": 0.0012}, {}]} for _ in range(3)]}
    merged = eref.merge_specs(_robot_dict("aalborg_3ppr"), spec)
    G, vars_ = eref.error_jacobian_fd(_robot_dict("aalborg_3ppr"), np.zeros(3), merged)
    sd_phi = math.sqrt(dref.variance(*dref.projections(G[2], eref._sources(merged, vars_))))
    m = 120
    u = (np.arange(m) + 0.5) / m * 2 - 1  # midpoints on [-1, 1]
    U = np.stack(np.meshgrid(u, u, u, indexing="ij"), -1).reshape(-1, 3) * 0.0012
    dxy = U @ G[:2].T
    l = np.hypot(dxy[:, 0], dxy[:, 1])
    rp_l_pop = l.mean() + 3 * l.std()
    p = I.predicted_repeatability("aalborg_3ppr", "case1", [[0.0, 0.0, 0.0]], 4000, tests=25, seed=5)
    assert abs(p.rp_phi[0] - 3 * sd_phi) <= 4 * p.rp_phi_se[0] + 2e-3 * 3 * sd_phi
    assert abs(p.rp_l[0] - rp_l_pop) <= 4 * p.rp_l_se[0] + 2e-3 * rp_l_pop


def test_virtual_iso_test_agrees_with_the_prediction():
    """Exact loop closures on the virtual rig vs the first-order prediction: the measured RP lies in the
    model's 5-95 % range of one test at most points, and the mean over points agrees closely."""
    from pmaccuracy.model.manipulator import Manipulator
    from pmaccuracy.experiment.virtual_rig import grid_poses

    robot = Manipulator.load("aalborg_3ppr")
    poses = grid_poses(robot, 0.0, 3)
    rep = I.simulate_repeats(robot, "all", poses, 60, noise_mm=0.005, noise_deg=0.005, seed=3)
    out = I.compare_repeatability(robot, "all", rep, noise_mm=0.005, noise_deg=0.005, tests=500, seed=4)
    assert out["share_rp_l_in_model_range"] >= 6 / 9 and out["share_rp_phi_in_model_range"] >= 6 / 9
    meas = np.array([r["rp_l"] for r in out["points"]])
    model = np.array([r["rp_l_model"] for r in out["points"]])
    assert abs(meas.mean() / model.mean() - 1) < 0.08
    ap = np.array([r["ap_p"] for r in out["points"]])
    assert np.all(ap < 0.5 * model)  # symmetric sets: no systematic offset beyond the scatter of the mean


def test_prediction_refuses_bad_arguments():
    with pytest.raises(ConfigError, match="cycles"):
        I.predicted_repeatability("aalborg_3ppr", "case1", [[0, 0, 0]], 1)
    with pytest.raises(ConfigError, match="noise_mm"):
        I.predicted_repeatability("aalborg_3ppr", "case1", [[0, 0, 0]], 5, noise_mm=-1)
    with pytest.raises(ConfigError, match="model"):
        I.simulate_repeats("aalborg_3ppr", "case1", [[0, 0, 0]], 5, model="nope")


# ------------------------------------------------------------------ CLI
def _run(capsys, *args):
    from pmaccuracy.cli import main
    try:
        code = main(list(args))
    except SystemExit as exc:
        code = exc.code
    out = capsys.readouterr()
    return code, out.out, out.err


def test_cli_simulate_and_compare_with_repeats(tmp_path, capsys):
    m = tmp_path / "m.csv"
    code, out, err = _run(capsys, "experiment", "simulate", "--grid", "3", "--out", str(m), "--repeats", "5",
                          "--model", "first_order", "--format", "json")
    assert code == 0, err
    rec = json.loads(out)
    rpath = tmp_path / "m_repeats.csv"
    assert rec["repeats_out"] == str(rpath) and rec["repeat_rows"] == 9 * 5
    code, out, err = _run(capsys, "experiment", "compare", "--measurements", str(m), "--repeats", str(rpath),
                          "--format", "json")
    assert code == 0, err
    iso = json.loads(out)["iso9283"]
    rep = I.load_repeats(rpath)
    f = I.iso_figures(rep.attained, rep.nominal)
    assert [r["rp_l"] for r in iso["points"]] == pytest.approx(f.rp_l.tolist(), rel=1e-12)
    code, out, err = _run(capsys, "experiment", "compare", "--measurements", str(m), "--repeats", str(rpath))
    assert code == 0 and "ISO 9283" in out and "rp_l_model" in out
    # refusals: one line, exit 2
    bad = tmp_path / "bad.csv"
    bad.write_text(HEADER + "a,0,0,0,1,0.1,0,0\n")
    far = tmp_path / "far.csv"
    far.write_text(HEADER + "a,0,0,0,1,0.1,0,0\nb,100,0,0,1,100,0,0\nb,100,0,0,2,100.1,0,0\na,0,0,0,2,0,0,0\n")
    for args, word in ((("experiment", "compare", "--measurements", str(m), "--repeats", str(bad)), "line 2"),
                       (("experiment", "compare", "--measurements", str(m), "--repeats", str(far)),
                        "line 3: point b: the commanded pose is outside the joint ranges"),
                       (("experiment", "simulate", "--out", str(m), "--repeats", "1"), "--repeats"),
                       (("experiment", "simulate", "--out", str(m), "--repeats-out", str(bad)), "--repeats-out")):
        code, out, err = _run(capsys, *args)
        assert code == 2 and len(err.strip().splitlines()) == 1 and word in err, err
