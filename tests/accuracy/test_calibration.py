"""Kinematic calibration (issue 23): parameters, identification, identifiability, planning, compensation,
the virtual experiment and bad input. References: tests/reference/calibration_reference.py, the exact
forward kinematics (pmaccuracy.kinematics.forward_kinematics, a polynomial solve: independent of the
inverse-kinematic residual the identification uses) and rigid-motion invariances."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from calibration_reference import random_robot_dict, rrr_actuated_angle
from pmaccuracy.accuracy.calibration.data import CalibrationData, read_calibration_csv, write_calibration_csv
from pmaccuracy.accuracy.calibration.identify import identify
from pmaccuracy.accuracy.calibration.parameters import error_parameters, joint_values, robot_file
from pmaccuracy.accuracy.calibration.plan import candidate_poses, plan_poses
from pmaccuracy.accuracy.calibration.simulate import measure, simulate_calibration, true_parameters
from pmaccuracy.errors import ConfigError, MeasurementFileError
from pmaccuracy.model.legs import ChainLeg
from pmaccuracy.model.manipulator import Manipulator

PRESETS = ["symmetric_3rrr", "symmetric_3rpr", "symmetric_3prr", "aalborg_3ppr"]


def _robot(name, seed=0):
    if name == "chain_3rrr":
        base = Manipulator.preset("symmetric_3rrr")
        return Manipulator(legs=tuple(ChainLeg(leg.chain) for leg in base.legs), name="chain")
    table = Manipulator.preset(name).to_dict()
    return Manipulator.from_dict(random_robot_dict(table, np.random.default_rng(seed)))


def test_names_units_and_robot_file_round_trip():
    pv = error_parameters(Manipulator.preset("symmetric_3rrr"))
    assert len(pv.names) == 27 and len(set(pv.names)) == 27
    assert "leg2.base.x" in pv.names and "leg1.actuator.offset" in pv.names and pv.names[-1] == "frame.phi"
    assert dict(zip(pv.names, pv.units))["leg1.actuator.offset"] == "rad"
    table = robot_file(pv, pv.nominal)
    assert {k: v for k, v in table.items() if k not in ("name", "description")} == \
        {k: v for k, v in pv.robot.to_dict().items() if k not in ("name", "description")}
    v = pv.nominal.copy()
    v[pv.index(["leg2.distal"])[0]] += 0.25
    again = Manipulator.from_dict(robot_file(pv, v))
    assert again.legs[1].distal == pytest.approx(pv.robot.legs[1].distal + 0.25, abs=1e-12)
    with pytest.raises(ConfigError, match="leg9.base.x"):
        pv.index(["leg9.base.x"])


def test_joint_values_match_closed_form_rrr():
    robot = _robot("symmetric_3rrr", 3)
    pv = error_parameters(robot)
    poses = candidate_poses(pv)[::37]
    q = joint_values(pv, pv.nominal, poses)
    for n, pose in enumerate(poses):
        for i, leg in enumerate(robot.legs):
            ref = rrr_actuated_angle(leg.base, leg.platform, leg.proximal, leg.distal, leg.working_mode, pose)
            assert np.angle(np.exp(1j * (q[n, i] - ref))) == pytest.approx(0, abs=1e-9)


@pytest.mark.parametrize("name", PRESETS)
def test_noise_free_data_recovered_exactly(name):
    """Errors on the identifiable parameters, measured by the exact forward kinematics: recovered to 1e-8."""
    pv = error_parameters(_robot(name, 1))
    cand = candidate_poses(pv)
    plan = plan_poses(pv, 30, cand)
    from pmaccuracy.accuracy.calibration.identify import jacobian, whitening  # probing the nominal Jacobian
    probe = CalibrationData(tuple("x" * 30), plan.commands, plan.poses, np.full((30, 3), 0.01), "<p>")
    from pmaccuracy.accuracy.calibration.identifiability import PRACTICAL_MAX_SIGMA, analyse
    fixed = analyse(pv, jacobian(pv, pv.nominal.copy(), probe, whitening(pv, pv.nominal, probe)),
                    max_sigma=PRACTICAL_MAX_SIGMA).fixed
    true = true_parameters(pv, seed=4, fixed=fixed)
    meas = measure(pv, true, plan.commands, plan.poses, noise=(0, 0, 0))
    data = CalibrationData(tuple(map(str, range(30))), plan.commands, meas, np.full((30, 3), 0.01), "<sim>")
    data = data.subset(np.all(np.isfinite(meas), axis=1))
    assert len(data) >= 25
    ident = identify(data, pv)
    assert set(ident.identifiability.fixed) == set(fixed)
    scale = np.where(np.array(pv.units) == "mm", 1.0, 1.0)
    assert np.max(np.abs(ident.values - true) / scale) < 1e-8, np.abs(ident.values - true).max()
    assert ident.rms_after < 1e-6 < ident.rms_before


@pytest.mark.parametrize("name", ["symmetric_3rrr", "symmetric_3rpr"])
def test_frame_and_base_coupling_detected_exactly(name):
    """Moving every base point by t and the measurement frame by t leaves every measurement unchanged (the
    forward kinematics says so); the analysis must report exactly that combination."""
    pv = error_parameters(Manipulator.preset(name))
    plan = plan_poses(pv, 20, candidate_poses(pv))
    true = true_parameters(pv, seed=2)
    shifted = true.copy()
    for i in (1, 2, 3):
        shifted[pv.index([f"leg{i}.base.x"])[0]] += 0.7
    shifted[pv.index(["frame.x"])[0]] += 0.7
    m1 = measure(pv, true, plan.commands, plan.poses, noise=(0, 0, 0))
    m2 = measure(pv, shifted, plan.commands, plan.poses, noise=(0, 0, 0))
    assert np.max(np.abs(m1 - m2)) < 1e-9
    data = CalibrationData(tuple(map(str, range(20))), plan.commands, m1, np.full((20, 3), 0.01), "<sim>")
    ident = identify(data, pv).identifiability
    assert set(ident.fixed) == {"frame.x", "frame.y", "frame.phi"}
    row = ident.null_directions[list(ident.fixed).index("frame.x")]
    expected = np.zeros(len(pv.names))
    expected[pv.index(["frame.x", "leg1.base.x", "leg2.base.x", "leg3.base.x"])] = 1.0
    assert np.max(np.abs(row - expected)) < 1e-6
    assert "frame.x" in ident.combinations[0] and "leg1.base.x" in ident.combinations[0]


@pytest.mark.parametrize("name", PRESETS)
def test_planned_poses_beat_random_and_grid(name):
    pv = error_parameters(Manipulator.preset(name))
    plan = plan_poses(pv, 30)
    assert plan.index["O1"] > plan.random_index["O1"]
    assert plan.index["O1"] > plan.grid_index["O1"]
    assert np.all(np.isfinite(plan.commands))


@pytest.mark.parametrize("name, clearances, ratio", [("symmetric_3rrr", "rrr_typical", 0.2),
                                                     ("symmetric_3rpr", "rpr_typical", 0.2),
                                                     ("symmetric_3prr", "prr_typical", 0.2),
                                                     ("aalborg_3ppr", "case1", 0.35)])
def test_noisy_fit_within_three_sigma_and_compensation_within_floor(name, clearances, ratio):
    """Random robot, parameter errors, clearance states and noise: the identified parameters within 3.5 of their
    sigmas, the compensated errors within the clearances' worst case plus 4 predicted sigmas, and a fraction
    ``ratio`` of the error before (the 3-PPR's case1 floor is a quarter of its geometric error: 0.35)."""
    pv = error_parameters(_robot(name, 5))
    ex = simulate_calibration(pv, 40, seed=3, clearances=clearances, true_fixed=("frame.x", "frame.y", "frame.phi"))
    ident = ex.identification
    free = pv.index(ident.identifiability.identified)
    z = (ident.values - ex.true)[free] / ident.sigma[free]
    assert np.max(np.abs(z)) < 3.5
    comp = ex.compensation
    err_after = np.hypot(*ex.errors_after[:, :2].T)
    err_before = np.hypot(*ex.errors_before[:, :2].T)
    # floor: worst case of the clearances + 4 sigma of the identified parameters carried to the pose
    allowed = comp.floor_dp_max + 4 * np.hypot(*comp.predicted_sigma[:, :2].T)
    assert np.all(err_after <= allowed)
    assert err_after.max() < ratio * err_before.max()


def test_outlier_reported_by_point():
    pv = error_parameters(Manipulator.preset("symmetric_3rpr"))
    plan = plan_poses(pv, 30, candidate_poses(pv))
    true = true_parameters(pv, seed=1, fixed=("frame.x", "frame.y", "frame.phi"))
    meas = measure(pv, true, plan.commands, plan.poses, seed=3)
    meas[7, 0] += 0.5   # 50 sigma
    data = CalibrationData(tuple(f"p{i}" for i in range(30)), plan.commands, meas, np.full((30, 3), 0.01), "<s>")
    data = CalibrationData(data.labels, data.commands, data.poses,
                           np.tile([0.01, 0.01, math.radians(0.01)], (30, 1)), "<s>")
    ident = identify(data, pv)
    assert ident.outliers == ("p7",)


# ------------------------------------------------------------------ the CSV and bad input
def _csv(tmp_path, pv, n=20, seed=0):
    plan = plan_poses(pv, n, candidate_poses(pv))
    meas = measure(pv, pv.nominal, plan.commands, plan.poses, seed=seed)
    path = tmp_path / "cal.csv"
    write_calibration_csv(pv.robot, plan.commands, meas, path)
    return path, plan, meas


def test_csv_round_trip_and_experiment_format(tmp_path):
    pv = error_parameters(Manipulator.preset("symmetric_3rrr"))
    path, plan, meas = _csv(tmp_path, pv)
    assert path.read_text().splitlines()[0] == "point,q1_deg,q2_deg,q3_deg,x,y,phi_deg"
    data = read_calibration_csv(path, pv)
    assert np.allclose(data.commands, plan.commands, atol=1e-12) and np.allclose(data.poses, meas, atol=1e-12)
    # an experiment / vision batch file: commands from the nominal poses
    lines = ["point,x_nom,y_nom,phi_nom_deg,push,x,y,phi_deg"]
    for n, (p, m) in enumerate(zip(plan.poses, meas)):
        lines.append(",".join([str(n)] + [repr(float(v)) for v in (p[0], p[1], math.degrees(p[2]))] + ["+x"] + [repr(float(v)) for v in (m[0], m[1], math.degrees(m[2]))]))
    exp = tmp_path / "exp.csv"
    exp.write_text("\n".join(lines) + "\n")
    assert np.allclose(read_calibration_csv(exp, pv).commands, plan.commands, atol=1e-9)


def _rewrite(path, fn):
    lines = path.read_text().splitlines()
    path.write_text("\n".join(fn(lines)) + "\n")


def test_bad_input_names_file_and_row(tmp_path):
    pv = error_parameters(Manipulator.preset("symmetric_3rrr"))
    path, plan, meas = _csv(tmp_path, pv)
    # phi in radians where degrees are expected
    _rewrite(path, lambda L: [L[0]] + [",".join(r.split(",")[:6] + [str(math.radians(float(r.split(",")[6])) + 1)])
                                       for r in L[1:]])
    with pytest.raises(MeasurementFileError, match=r"cal\.csv: row [0-9]+ .*deg.*radians"):
        identify(read_calibration_csv(path, pv), pv)
    path, *_ = _csv(tmp_path, pv)
    _rewrite(path, lambda L: [L[0].replace("q2_deg", "q2")] + L[1:])
    with pytest.raises(MeasurementFileError, match="q2.*revolute"):
        read_calibration_csv(path, pv)
    path, *_ = _csv(tmp_path, pv)
    beyond = str(math.degrees(pv.robot.chains[0].actuated.range[1]) + 10.0)
    _rewrite(path, lambda L: L[:3] + [",".join(["3", beyond] + L[3].split(",")[2:])] + L[4:])
    with pytest.raises(MeasurementFileError, match=r"row 3 .*outside leg 1's actuator range"):
        read_calibration_csv(path, pv)
    path, *_ = _csv(tmp_path, pv, n=10)
    _rewrite(path, lambda L: L[:5])
    with pytest.raises(MeasurementFileError, match="4 points give 12 residuals"):
        identify(read_calibration_csv(path, pv), pv)
    path, *_ = _csv(tmp_path, pv)
    _rewrite(path, lambda L: [L[0]] + [",".join(r.split(",")[:4] + [str(float(r.split(",")[4]) + 60)] +
                                                r.split(",")[5:]) for r in L[1:]])
    with pytest.raises(MeasurementFileError, match="measurement frame far"):
        identify(read_calibration_csv(path, pv), pv)
    with pytest.raises(ConfigError, match="no parameter 'leg1.nothing'"):
        identify(read_calibration_csv(_csv(tmp_path, pv)[0], pv), pv, fixed=("leg1.nothing",))


@pytest.mark.slow
@pytest.mark.parametrize("name", PRESETS)
def test_sigmas_honest_over_seeds(name):
    """Over 20 seeds (random robot, parameter errors, camera noise), measured by the exact forward kinematics:
    the normalized errors (estimate - truth) / sigma of the identifiable parameters have unit spread within
    20 %, and 99 % of them lie within 3."""
    pv = error_parameters(_robot(name, 11))
    plan = plan_poses(pv, 30, candidate_poses(pv))
    sig = np.tile([0.01, 0.01, math.radians(0.01)], (30, 1))
    probe = CalibrationData(tuple(map(str, range(30))), plan.commands,
                            measure(pv, pv.nominal, plan.commands, plan.poses, seed=0), sig, "<p>")
    fixed = identify(probe, pv).identifiability.fixed
    zs = []
    for seed in range(20):
        true = true_parameters(pv, seed=100 + seed, fixed=fixed)
        m = measure(pv, true, plan.commands, plan.poses, noise=sig[0], seed=seed)
        ok = np.all(np.isfinite(m), axis=1)
        data = CalibrationData(tuple(map(str, range(int(ok.sum())))), plan.commands[ok], m[ok], sig[ok], "<s>")
        ident = identify(data, pv, robust=False)
        free = pv.index(ident.identifiability.identified)
        zs.append((ident.values - true)[free] / ident.sigma[free])
    z = np.concatenate(zs)
    assert abs(z.std() - 1.0) < 0.2, z.std()
    assert np.mean(np.abs(z) <= 3.0) >= 0.99 and np.max(np.abs(z)) < 4.5


def test_true_robot_from_named_errors_and_tolerances(tmp_path):
    """The virtual experiment's true robot: named errors added exactly, tolerances drawn uniformly within +-
    (seeded), everything else nominal; files in mm / deg / gain fraction; unknown names refused by name."""
    from pmaccuracy.accuracy.calibration.simulate import load_parameter_table

    pv = error_parameters(Manipulator.preset("symmetric_3rrr"))
    (tmp_path / "e.toml").write_text('"leg1.base.x" = 0.3\nleg2.actuator.offset = 0.2\nleg3.actuator.gain = 1e-3\n')
    errors = load_parameter_table(tmp_path / "e.toml", pv, "errors")
    assert errors == {"leg1.base.x": 0.3, "leg2.actuator.offset": pytest.approx(math.radians(0.2), abs=1e-15),
                      "leg3.actuator.gain": 1e-3}
    true = true_parameters(pv, seed=5, errors=errors)
    d = true - pv.nominal
    assert np.count_nonzero(d) == 3 and d[pv.index(["leg1.base.x"])[0]] == pytest.approx(0.3, abs=1e-12)
    tol = {"leg1.proximal": 0.1, "leg2.platform.y": 0.05}
    draws = np.array([true_parameters(pv, seed=s, tolerances=tol) - pv.nominal for s in range(200)])
    k = pv.index(list(tol))
    assert np.count_nonzero(np.delete(draws, k, axis=1)) == 0
    assert np.all(np.abs(draws[:, k]) <= [0.1, 0.05]) and np.all(np.abs(draws[:, k]).max(axis=0) > [0.09, 0.045])
    assert np.array_equal(true_parameters(pv, seed=3, tolerances=tol), true_parameters(pv, seed=3, tolerances=tol))
    (tmp_path / "bad.toml").write_text("leg1.nothing = 1\n")
    with pytest.raises(ConfigError, match=r"bad\.toml: leg1\.nothing: no parameter 'leg1\.nothing'"):
        load_parameter_table(tmp_path / "bad.toml", pv)
    with pytest.raises(ConfigError, match="leg4.base.x"):
        true_parameters(pv, errors={"leg4.base.x": 0.1})
    with pytest.raises(ConfigError, match=">= 0"):
        true_parameters(pv, tolerances={"leg1.proximal": -0.1})


# ------------------------------------------------------------------ covariance honesty (weak parameters)
def _slanted_3ppr_data(seed=5):
    """A random 3-PPR whose slides are turned off perpendicular (random_robot_dict turns beta, gamma, theta),
    its 40 planned poses measured with clearances case1 and camera noise; frame errors zero."""
    robot = _robot("aalborg_3ppr", seed)
    slant = [abs(leg["beta_deg"] + 90.0) + abs(leg["gamma_deg"] + 90.0) for leg in robot.to_dict()["legs"]]
    assert max(slant) > 1.0                                    # the slides really are turned
    pv = error_parameters(robot)
    true = true_parameters(pv, seed=3, fixed=("frame.x", "frame.y", "frame.phi"))
    plan = plan_poses(pv, 40, candidate_poses(pv), seed=3)
    sig = np.array([0.01, 0.01, math.radians(0.01)])
    m = measure(pv, true, plan.commands, plan.poses, noise=sig, clearances="case1", seed=4)
    ok = np.all(np.isfinite(m), axis=1)
    data = CalibrationData(tuple(map(str, range(int(ok.sum())))), plan.commands[ok], m[ok],
                           np.tile(sig, (int(ok.sum()), 1)), "<slanted>")
    return pv, true, data


def test_slanted_3ppr_weak_parameters_fixed_or_honest():
    """Slides a few degrees off perpendicular: a leg's ``a`` changes the residuals only through that turn
    (predicted sigma of metres). By default it is fixed and reported as practically unidentifiable, every
    identified sigma stays below the bound and the estimates lie within 4 sigma of the truth (the identified
    robot's use, compensation within the clearance floor, is the noisy-fit test's 3-PPR). With the rule off,
    ``a`` is kept, the fit wanders ~0.1 m along it and its sigma is honest: tens of metres, not the 4e-7 mm
    the pseudo-inverse of the unscaled ``J^T J`` gave."""
    from pmaccuracy.accuracy.calibration.identifiability import PRACTICAL_MAX_SIGMA, TYPICAL_CHANGE

    pv, true, data = _slanted_3ppr_data()
    ident = identify(data, pv, clearances="case1")
    idf = ident.identifiability
    assert set(idf.practical) == {"leg1.a", "leg2.a", "leg3.a"} and set(idf.practical) <= set(idf.fixed)
    assert min(idf.predicted_sigma) > PRACTICAL_MAX_SIGMA * TYPICAL_CHANGE["mm"]
    words = [c for c in idf.combinations if c.startswith("leg1.a ")]
    assert len(words) == 1 and "practically unidentifiable" in words[0] and "fixed at nominal" in words[0]
    free = pv.index(idf.identified)
    typical = np.array([TYPICAL_CHANGE[u] for u in pv.units])[free]
    assert np.all(ident.sigma[free] < PRACTICAL_MAX_SIGMA * typical)
    assert np.max(np.abs((ident.values - true)[free] / ident.sigma[free])) < 4.0
    kept = identify(data, pv, clearances="case1", max_sigma=None, robust=False)   # wanders: 200 evaluations
    assert {"leg1.a", "leg2.a", "leg3.a"} <= set(kept.identifiability.identified)
    a = pv.index(["leg1.a", "leg2.a", "leg3.a"])
    assert np.all(kept.sigma[a] > 100.0), kept.sigma[a]
    free = pv.index(kept.identifiability.identified)
    assert np.max(np.abs((kept.values - true)[free] / kept.sigma[free])) < 4.0


@functools.lru_cache(maxsize=1)
def _rpr_setup():
    pv = error_parameters(_robot("symmetric_3rpr", 2))
    plan = plan_poses(pv, 30, candidate_poses(pv))
    return pv, plan, true_parameters(pv, seed=1, fixed=("frame.x", "frame.y", "frame.phi"))


def _identified_rpr(seed):
    """A random 3-RPR (well conditioned) identified from 30 planned poses with camera noise ``seed``."""
    pv, plan, true = _rpr_setup()
    sig = np.array([0.01, 0.01, math.radians(0.01)])
    m = measure(pv, true, plan.commands, plan.poses, noise=sig, seed=seed)
    ok = np.all(np.isfinite(m), axis=1)
    data = CalibrationData(tuple(map(str, range(int(ok.sum())))), plan.commands[ok], m[ok],
                           np.tile(sig, (int(ok.sum()), 1)), "<rpr>")
    return pv, true, data, identify(data, pv, robust=False)


def _corr(C):
    return C / np.sqrt(np.outer(np.diag(C), np.diag(C)))


def test_covariance_matches_independent_lstsq():
    """The reported covariance against ``s^2 A A^T`` with ``A`` numpy's lstsq pseudo-inverse of the Jacobian of
    the *forward* residual ``(m - FK(theta; c)) / sigma``, taken in this test by central differences of the
    exact forward kinematics (not the identification's inverse-kinematic residual): equal to first order."""
    pv, _, data, ident = _identified_rpr(4)
    sig = data.sigmas[0]
    free = pv.index(ident.identifiability.identified)
    h = np.where(np.array(pv.units) == "mm", 1e-5, 1e-7)
    cols = []
    for j in free:
        vp, vm = ident.values.copy(), ident.values.copy()
        vp[j] += h[j]
        vm[j] -= h[j]
        d = (measure(pv, vp, data.commands, data.poses, noise=(0, 0, 0)) -
             measure(pv, vm, data.commands, data.poses, noise=(0, 0, 0))) / (2 * h[j])
        cols.append((-d / sig).ravel())
    J = np.stack(cols, axis=1)
    A = np.linalg.lstsq(J, np.eye(J.shape[0]), rcond=None)[0]
    ref = ident.scale ** 2 * A @ A.T
    assert np.max(np.abs(ident.sigma[free] / np.sqrt(np.diag(ref)) - 1.0)) < 0.02
    assert np.max(np.abs(_corr(ident.covariance) - _corr(ref))) < 0.02


@pytest.mark.slow
def test_covariance_matches_spread_over_noise_seeds():
    """One true robot, 150 noise seeds: the sample standard deviation of each identified parameter's estimate
    within 20 % of the (mean) reported sigma (3.5 standard errors of a 150-sample spread), and the sample
    correlations within 4 standard errors of the reported ones."""
    est, covs = [], []
    for seed in range(150):
        pv, _, _, ident = _identified_rpr(1000 + seed)
        free = pv.index(ident.identifiability.identified)
        est.append(ident.values[free])
        covs.append(ident.covariance)
    est, cov = np.array(est), np.mean(covs, axis=0)
    ratio = est.std(axis=0, ddof=1) / np.sqrt(np.diag(cov))
    assert np.all(np.abs(ratio - 1.0) < 0.2), ratio
    rep, smp = _corr(cov), _corr(np.cov(est.T))
    # a sample correlation's standard error is (1 - rho^2) / sqrt(n): within 4 of them
    assert np.all(np.abs(smp - rep) <= 4 * (1 - rep ** 2) / np.sqrt(len(est)) + 1e-3)
