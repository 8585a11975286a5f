"""Robust identification (issue 34): gross readings (a wrong position, orientation or command) are reported by
row and left out, and the parameters stay those of the clean data; readings the nominal robot cannot reach
are kept when the fitted robot explains them; data that cannot identify the robot are refused with counts.

The data come from the exact forward kinematics of a true random robot
(:func:`pmaccuracy.accuracy.calibration.simulate.measure`); the gross readings from
tests/reference/gross_readings.py; reachability from the closed-form R-R-R leg of
tests/reference/calibration_reference.py; the identifiable count from the rank of the exact forward kinematics'
finite differences. None of these goes through the identification's residuals."""

from __future__ import annotations

import math

import numpy as np
import pytest

from calibration_reference import rrr_actuated_angle
from gross_readings import SIGMA, calibration_case, corrupt
from pmaccuracy.accuracy.calibration.data import CalibrationData, read_calibration_csv, write_calibration_csv
from pmaccuracy.accuracy.calibration.identifiability import _terms
from pmaccuracy.accuracy.calibration.identify import identify
from pmaccuracy.accuracy.calibration.parameters import actuators, commands_for, error_parameters
from pmaccuracy.accuracy.calibration.simulate import measure
from pmaccuracy.errors import MeasurementFileError
from pmaccuracy.kinematics import forward_kinematics
from pmaccuracy.model.manipulator import Manipulator

ARCHITECTURES = ["symmetric_3rrr", "symmetric_3rpr", "symmetric_3prr", "aalborg_3ppr"]


def _with(data: CalibrationData, commands=None, poses=None, sigmas=None) -> CalibrationData:
    return CalibrationData(data.labels, data.commands if commands is None else commands,
                           data.poses if poses is None else poses, data.sigmas if sigmas is None else sigmas,
                           data.source)


def check_gross(name: str, seed: int, fraction: float = 0.1) -> None:
    """Every gross reading reported (by row), at most one good point with it; the parameters those of the
    plain fit of the clean readings of the points kept (within half a sigma: only the whitening, taken at
    other values, differs), and those of the fit of all the clean readings within one of the robust fit's
    sigmas where the points left out carry little information: beyond, within 4 sigmas of the difference
    of the two nested fits (variance ``sigma_kept^2 - sigma_all^2``)."""
    pv, true, data, reference = calibration_case(name, seed)
    clean = identify(data, pv)
    bad, made = corrupt(pv, true, data, reference, np.random.default_rng(1000 + seed), fraction=fraction)
    assert len(made) >= int(round(fraction * len(data))) - 1
    ident = identify(bad, pv)
    rows = {o.row - 1 for o in ident.flagged}
    assert set(made) <= rows, (made, [o.describe() for o in ident.flagged])
    assert len(rows - set(made)) <= 1
    assert [data.labels[r] for r in sorted(rows)] == list(ident.outliers)
    for o in ident.flagged:
        if o.row - 1 in made:
            assert o.normalized > ident.outlier_threshold
    assert ident.identifiability.identified == clean.identifiability.identified
    free = pv.index(clean.identifiability.identified)
    keep = np.ones(len(data), dtype=bool)
    keep[sorted(rows)] = False
    same = identify(data.subset(keep), pv, robust=False)
    assert np.max(np.abs(ident.values - same.values)[free] / same.sigma[free]) < 0.5
    diff = np.abs(ident.values - clean.values)[free]
    nested = np.sqrt(np.clip(ident.sigma[free] ** 2 - clean.sigma[free] ** 2, 0.0, None))
    assert np.all((diff < ident.sigma[free]) | (diff < 4.0 * nested)), np.max(diff / ident.sigma[free])


@pytest.mark.parametrize("name, seed", [("symmetric_3rrr", 0), ("symmetric_3rpr", 1), ("symmetric_3prr", 2),
                                        ("aalborg_3ppr", 3)])
def test_gross_readings_reported_and_parameters_kept(name, seed):
    check_gross(name, seed)


@pytest.mark.slow
@pytest.mark.parametrize("name", ARCHITECTURES)
@pytest.mark.parametrize("seed", range(4, 12))
def test_gross_readings_sweep(name, seed):
    check_gross(name, seed, fraction=[0.025, 0.05, 0.1][seed % 3])


# ------------------------------------------------------------------ the cases
@pytest.fixture(scope="module")
def rrr40():
    return calibration_case("symmetric_3rrr", 7, n=40)


def _flagged(ident):
    return [o.label for o in ident.flagged]


def test_one_reading_five_mm_off_reported(rrr40):
    pv, _, data, _ = rrr40
    poses = data.poses.copy()
    poses[12, 0] += 5.0
    ident = identify(_with(data, poses=poses), pv)
    assert _flagged(ident) == [data.labels[12]]
    o = ident.flagged[0]
    assert o.row == 13 and o.residual[0] == pytest.approx(5.0, abs=0.1) and o.normalized > 400
    assert 0.7 < ident.scale < 1.4     # the stated noise, not a scale the outlier inflated


def test_one_command_half_a_degree_off_reported(rrr40):
    pv, _, data, _ = rrr40
    commands = data.commands.copy()
    commands[20, 0] += math.radians(0.5)
    ident = identify(_with(data, commands=commands), pv)
    assert _flagged(ident) == [data.labels[20]] and 0.7 < ident.scale < 1.4


def test_command_moved_on_noise_free_data_reported():
    """Noise-free readings (stated sigmas 0.01 mm / deg) and one command moved by 22.7 deg inside its range:
    that point reported, the rest fitted to the noise-free level."""
    pv, true, data, reference = calibration_case("symmetric_3rrr", 8, n=40)
    exact = measure(pv, true, data.commands, reference, noise=(0, 0, 0))
    commands = data.commands.copy()
    lo, hi = actuators(pv.robot)[1][1]
    step = math.radians(22.7)
    row = next(n for n in range(len(data)) if lo <= commands[n, 1] + step <= hi)
    commands[row, 1] += step
    ident = identify(_with(data, commands=commands, poses=exact), pv)
    assert _flagged(ident) == [data.labels[row]]
    assert ident.fit_rms_position < 1e-6


def test_reading_out_of_the_nominal_reach_accepted():
    """The measurement frame 3 mm off: a reading of the true robot that the nominal robot cannot reach (the
    closed-form leg says so) joins the fit instead of refusing the file, and is not reported."""
    pv, true, data, reference = calibration_case("symmetric_3rrr", 0)
    true = true.copy()
    true[pv.index(["frame.x"])[0]] += 3.0
    true[pv.index(["frame.y"])[0]] -= 2.0
    meas = measure(pv, true, data.commands, reference, noise=SIGMA, seed=5)
    robot = pv.robot
    rng = np.random.default_rng(0)
    lo, hi = robot.base_points.min(axis=0) - 50, robot.base_points.max(axis=0) + 50
    poses = np.column_stack([rng.uniform(lo[0], hi[0], 6000), rng.uniform(lo[1], hi[1], 6000),
                             rng.uniform(-0.3, 0.3, 6000)])
    cmd = commands_for(pv, pv.nominal, poses)
    limits = np.array([r for _, r in actuators(robot)])
    ok = np.all(np.isfinite(cmd) & (cmd >= limits[:, 0]) & (cmd <= limits[:, 1]), axis=1)
    reading = measure(pv, true, cmd[ok], poses[ok], noise=(0, 0, 0))

    def nominal_reaches(pose):
        return all(np.isfinite(rrr_actuated_angle(leg.base, leg.platform, leg.proximal, leg.distal,
                                                  leg.working_mode, pose)) for leg in robot.legs)
    k = next(k for k in range(len(reading)) if np.all(np.isfinite(reading[k])) and not nominal_reaches(reading[k]))
    both = CalibrationData(data.labels + ("extra",), np.vstack([data.commands, cmd[ok][k]]),
                           np.vstack([meas, reading[k]]), np.vstack([data.sigmas, SIGMA]), "<s>")
    ident = identify(both, pv)
    assert ident.outliers == () and ident.n_points == len(data) + 1
    # most points out of reach: the frame / units message naming a row
    far = both.poses.copy()
    far[:, 0] += 400.0
    with pytest.raises(MeasurementFileError, match=r"row 1 .*cannot reach.*--frame"):
        identify(_with(both, poses=far), pv)


# ------------------------------------------------------------------ refusals and words
def test_revolute_command_beyond_a_turn_refused(tmp_path):
    pv, _, data, _ = calibration_case("symmetric_3rrr", 0, n=12)
    path = tmp_path / "cal.csv"
    cmd = data.commands.copy()
    cmd[4, 0] += 4 * math.pi          # 720 deg more: the same joint position modulo turns
    write_calibration_csv(pv.robot, cmd, data.poses, path)
    with pytest.raises(MeasurementFileError, match=r"cal\.csv: row 5 .*q1_deg = .* beyond a full turn"):
        read_calibration_csv(path, pv)
    write_calibration_csv(pv.robot, data.commands, data.poses, path)
    assert np.allclose(read_calibration_csv(path, pv).commands, data.commands, atol=1e-12)


def _independent_rank(robot: Manipulator, n: int = 40) -> int:
    """Rank of d(measured pose)/d(parameter) by central differences of the exact forward kinematics over
    ``n`` poses: every geometric number of the robot file, the actuator offsets and gains, and the
    measurement frame (a rigid motion of the readings)."""
    pv = error_parameters(robot)
    rng = np.random.default_rng(3)
    from pmaccuracy.accuracy.calibration.plan import candidate_poses
    cand = candidate_poses(pv)
    poses = cand[rng.choice(len(cand), n, replace=False)]
    cmd = commands_for(pv, pv.nominal, poses)
    cols = []
    for j, unit in enumerate(pv.units):
        h = 1e-4 if unit == "mm" else 1e-6
        out = []
        for sign in (1, -1):
            v = pv.nominal.copy()
            v[j] += sign * h
            r, off, gain, frame = pv.split(v)
            fk = forward_kinematics(r, off + gain * cmd).nearest(poses)
            c, s = math.cos(frame[2]), math.sin(frame[2])
            d = fk[:, :2] - frame[:2]
            out.append(np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1],
                                        fk[:, 2] - frame[2]]))
        cols.append(((out[0] - out[1]) / (2 * h) / np.array([1.0, 1.0, 0.01])).ravel())
    J = np.stack(cols, axis=1)
    J = J / np.linalg.norm(J, axis=0)
    s = np.linalg.svd(J, compute_uv=False)
    return int(np.sum(s > 1e-7 * s[0]))


def test_too_few_points_and_copies_counted(tmp_path):
    pv, _, data, _ = calibration_case("symmetric_3rrr", 0, n=12)
    L = _independent_rank(pv.robot)
    assert L < len(pv.names)
    with pytest.raises(MeasurementFileError, match=rf"4 points give 12 residuals for the {L} identifiable "
                                                   rf"parameters.*at least {L // 3 + 1} distinct poses"):
        identify(data.subset(np.arange(12) < 4), pv)
    copies = CalibrationData(tuple(map(str, range(40))), np.repeat(data.commands[:1], 40, axis=0),
                             np.repeat(data.poses[:1], 40, axis=0), np.repeat(data.sigmas[:1], 40, axis=0), "<c>")
    with pytest.raises(MeasurementFileError, match=rf"40 points at only 1 distinct pose give 3 .*for the {L} "):
        identify(copies, pv)


def test_combination_names_every_tied_term():
    names = [f"t{k}" for k in range(9)]
    coef = np.array([5.0, -4.0, 3.0, 2.5, 2.0, 1.0, 1.0, -1.0, 0.5])
    shown, more, count = _terms(names, coef)
    assert count == 9
    for k in range(8):      # the three of magnitude 1 all written out
        assert f"t{k}" in shown
    assert "t8" not in shown and more == " (+1 smaller term)"
    shown, more, _ = _terms(names[:3], np.array([1.0, 1.0, 1.0]))
    assert more == "" and all(n in shown for n in names[:3])


def test_cli_prints_the_flagged_rows(tmp_path, capsys):
    """``calibrate identify`` names the flagged point by its data row with its normalized residual (table),
    and the JSON record keeps it (fit.outlier_points)."""
    import csv
    import json

    from pmaccuracy.cli import main

    pv, _, data, _ = calibration_case("symmetric_3rpr", 2, n=30)
    poses = data.poses.copy()
    poses[6, 1] -= 3.0
    path = tmp_path / "cal.csv"
    write_calibration_csv(pv.robot, data.commands, poses, path)
    robot = tmp_path / "robot.toml"
    import tomli_w
    robot.write_text(tomli_w.dumps(pv.robot.to_dict()))
    assert main(["calibrate", "identify", "--robot", str(robot), "--data", str(path), "--clearances", "none", "--out",
                 str(tmp_path / "id.json")]) == 0
    lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("outlier:")]
    assert len(lines) == 1 and lines[0].startswith("outlier: row 7 (point 7): ") and "sigma" in lines[0]
    said = float(lines[0].split(": ")[2].split(" sigma")[0])
    rec = json.loads((tmp_path / "id.json").read_text())["fit"]["outlier_points"]
    assert [r["row"] for r in rec] == [7] and rec[0]["dy_mm"] == pytest.approx(-3.0, abs=0.05)
    assert said == pytest.approx(rec[0]["normalized_residual"], rel=2e-3) and said > 200
    assert list(csv.reader(path.open()))[7][0] == "7"
