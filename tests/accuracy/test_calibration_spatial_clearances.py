"""Spatial calibration with clearances (issue 39, items 1-3): the clearance states of the virtual readings
against the covariance of the independent brute-force reference (tests/reference/spatial_error_reference.py:
central differences of the nonlinear closures, written without pmaccuracy), the clearance floor's RMS against
the same reference, the compensated residual down to the floor plus the parameters' uncertainty (hexapod and
Delta), and the D-optimal plan giving smaller parameter sigmas than random poses."""

from __future__ import annotations

import numpy as np
import pytest
import spatial_error_reference as eref
import spatial_reference as ref
from scipy.spatial.transform import Rotation

from pmaccuracy.accuracy.calibration.spatial_compensate import (clearance_floor, clearance_twists,
                                                                residuals_beside_floor)
from pmaccuracy.accuracy.calibration.spatial_parameters import spatial_error_parameters
from pmaccuracy.accuracy.calibration.spatial_simulate import (candidate_poses, measure_spatial,
                                                              simulate_spatial_calibration)
from pmaccuracy.kinematics.spatial import inverse_kinematics
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.model.spatial_sources import SpatialErrorSources


def _reference_covariance(M, sources):
    """Cov of t = M s, each source's variables uniform in its ball of radius h: h^2 I / (d + 2) (written here)."""
    cov = np.zeros((6, 6))
    for src in sources:
        d = eref.SHAPE_DIM[src["shape"]]
        Ms = M[:, src["columns"]]
        cov += src["half_width"] ** 2 / (d + 2) * Ms @ Ms.T
    return cov


@pytest.fixture(scope="module")
def hexapod_reference():
    robot_dict, cl_dict = ref.load_reference("6-UPS"), eref.load_clearances("6-UPS")
    robot = SpatialManipulator.from_dict(robot_dict, source="r.toml")
    sources = SpatialErrorSources.from_dict(cl_dict, robot, source="c.toml")
    p, R = eref.nominal_pose(robot_dict)
    pose = np.concatenate([p, Rotation.from_matrix(R).as_rotvec()])
    M, ref_sources = eref.sensitivity(robot_dict, cl_dict, p, R)
    return robot, sources, pose, R, _reference_covariance(M, ref_sources), M, ref_sources


def test_clearance_states_have_the_reference_covariance(hexapod_reference):
    """20000 states at one pose: each component's variance within 5 % of the reference's (the standard error
    of a sample variance is about 1 % here), the cross terms within 0.05 of a correlation."""
    robot, sources, pose, _, cov, _, _ = hexapod_reference
    t = clearance_twists(robot, sources, np.tile(pose, (20000, 1)), seed=4)
    sample = np.cov(t.T)
    np.testing.assert_allclose(np.diag(sample), np.diag(cov), rtol=0.05)
    sd = np.sqrt(np.diag(cov))
    assert np.max(np.abs(sample - cov) / np.outer(sd, sd)) < 0.05


def test_readings_clearance_covariance_against_the_reference(hexapod_reference):
    """The identification's clearance covariance of a reading: the reference covariance turned into the device's
    frame, diag(R_F, R_F) Cov diag(R_F, R_F)^T for a full pose, R_F [I, -[R s]x] Cov (...)^T at a target."""
    from pmaccuracy.accuracy.calibration.spatial_identify import SpatialCalibrationData, clearance_covariance

    robot, sources, pose, R, cov, _, _ = hexapod_reference
    s = np.array([40.0, -30.0, 20.0])
    rF = np.array([0.1, -0.2, 0.3])
    RF = Rotation.from_rotvec(rF).as_matrix()
    for targets in (None, [s]):
        pv = spatial_error_parameters(robot, targets=targets)
        values = pv.nominal.copy()
        values[pv.frame_index[3:]] = rF
        k = 6 if targets is None else 3
        data = SpatialCalibrationData(("1",), np.zeros((1, 6)), np.zeros((1, k)), np.ones((1, k)), np.zeros(1, int))
        C = clearance_covariance(pv, values, data, pose[None], sources)[0]
        if targets is None:
            A = np.kron(np.eye(2), RF)
        else:
            a = R @ s
            A = RF @ np.hstack([np.eye(3), -np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])])
        np.testing.assert_allclose(C, A @ cov @ A.T, rtol=0, atol=1e-6 * np.max(np.abs(A @ cov @ A.T)))


def test_clearance_floor_rms_and_worst_case_against_the_reference(hexapod_reference):
    """The floor's RMS is exact: sqrt(trace) of the reference covariance's position block, or for a target
    point s of [I, -[R s]x] Cov [I, -[R s]x]^T; its worst case is the reference's largest |dp| over the error
    set (sampled support directions refined by ascent: a lower bound, met within 0.1 %); no sampled state
    exceeds it."""
    robot, sources, pose, R, cov, M, ref_sources = hexapod_reference
    s = np.array([40.0, -30.0, 20.0])
    pv = spatial_error_parameters(robot, targets=[s])
    fl = clearance_floor(pv, pv.nominal, sources, pose[None])
    assert fl["dp_rms"][0] == pytest.approx(np.sqrt(np.trace(cov[:3, :3])), rel=1e-5)
    assert fl["dtheta_rms"][0] == pytest.approx(np.sqrt(np.trace(cov[3:, 3:])), rel=1e-5)
    a = R @ s
    A = np.hstack([np.eye(3), -np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])])
    at_target = clearance_floor(pv, pv.nominal, sources, pose[None], target=np.array([0]))
    assert at_target["dp_rms"][0] == pytest.approx(np.sqrt(np.trace(A @ cov @ A.T)), rel=1e-5)
    lower = eref.max_norm_sampled(M, ref_sources, n=20000)
    assert lower * (1 - 1e-6) <= fl["dp_max"][0] <= lower * 1.001
    t = clearance_twists(robot, sources, np.tile(pose, (5000, 1)), seed=5)
    assert np.linalg.norm(t[:, :3], axis=1).max() <= fl["dp_max"][0] * (1 + 1e-9)


def test_readings_carry_one_clearance_state_each():
    """Noise-free readings with and without clearances differ by one state per command: within the floor at
    the true robot's pose, different from command to command, the same targets' state shared."""
    pv = spatial_error_parameters(SpatialManipulator.preset("stewart_6ups"), targets=[[0.0, 0.0, 30.0],
                                                                                        [60.0, 0.0, 10.0]])
    poses = candidate_poses(pv, 300, seed=2)[:20]
    commands = inverse_kinematics(pv.robot, poses).q
    clean = measure_spatial(pv, pv.nominal, commands, noise=(0.0, 0.0))
    moved = measure_spatial(pv, pv.nominal, commands, noise=(0.0, 0.0), clearances="ups_typical", seed=3)
    d = np.linalg.norm(moved.measured - clean.measured, axis=1)
    fl = clearance_floor(pv, pv.nominal, "ups_typical", np.repeat(poses, 2, axis=0), target=clean.target)
    assert np.all(d <= fl["dp_max"] * (1 + 1e-6))
    assert np.all(d > 0) and np.std(d) > 0.1 * np.mean(d)


@pytest.mark.parametrize("name, clearances", [("stewart_6ups", "ups_typical"), ("delta_clavel", "delta_typical")])
def test_compensated_error_reaches_the_clearance_floor(name, clearances):
    """With clearance states in the readings and in the checks, the true robot's error at the compensated
    commands is within the floor plus 3 predicted sigmas at every target, and the fit's residual at every
    reading within the floor plus 3 reading sigmas; the nominal commands' error is well above the floor."""
    pv = spatial_error_parameters(SpatialManipulator.preset(name))
    ex = simulate_spatial_calibration(pv, 40, seed=1, clearances=clearances, n_targets=20, n_candidates=2000)
    comp = ex.compensation
    ok = np.isfinite(ex.errors_after[:, 0])
    assert ok.sum() >= 18
    limit = comp.floor["dp_max"] + 3 * comp.predicted_sigma[:, 0]
    assert np.all(ex.errors_after[ok, 0] <= limit[ok])
    assert np.nanmax(ex.errors_before[:, 0]) > 2 * np.nanmax(comp.floor["dp_max"])
    r = residuals_beside_floor(ex.identification, ex.data, clearances)
    assert np.all(r["within"][~r["outlier"]])


def test_d_optimal_plan_gives_smaller_sigmas_than_random_poses():
    """Same true robot, noise and number of readings: the D-optimal poses give the commonly identified
    parameters' sigmas smaller on (geometric) average by at least a fifth (0.69 here; 0.45-0.72 over seeds and
    presets), each taken without the residual scale s (sqrt of the diagonal of (J^T J)^-1: what the poses
    give, not the noise drawn)."""
    pv = spatial_error_parameters(SpatialManipulator.preset("stewart_6ups"))
    runs = {plan: simulate_spatial_calibration(pv, 30, seed=2, plan=plan, n_targets=5, n_candidates=2000)
            for plan in ("d-optimal", "random")}
    assert runs["d-optimal"].plan is not None and runs["random"].plan is None
    idents = {k: ex.identification for k, ex in runs.items()}
    common = sorted(set(idents["d-optimal"].identifiability.identified)
                    & set(idents["random"].identifiability.identified))
    idx = pv.index(common)
    unscaled = {k: ident.sigma[idx] / ident.scale for k, ident in idents.items()}
    assert len(common) > 40
    assert np.exp(np.mean(np.log(unscaled["d-optimal"] / unscaled["random"]))) < 0.8


def test_residual_beside_floor_against_the_reference_model():
    """The numbers the report sets side by side, from the reference: each reading's residual is the reading
    minus what the reference robot with the identified parameters reads at its commands (its own forward
    kinematics); the floor at a reading is the reference's largest |dp| of the identified geometry's error set
    there (sampled support directions refined by ascent, within 0.1 %)."""
    import spatial_calibration_reference as scr

    from pmaccuracy.accuracy.calibration.spatial_identify import platform_poses
    from pmaccuracy.accuracy.calibration.spatial_parameters import spatial_robot_file

    pv = spatial_error_parameters(SpatialManipulator.preset("delta_clavel"))
    cl_dict = eref.load_clearances("delta")
    sources = SpatialErrorSources.from_dict(cl_dict, pv.robot, source="c.toml")
    ex = simulate_spatial_calibration(pv, 20, seed=5, clearances=sources, n_targets=3, n_candidates=2000)
    ident = ex.identification
    r = residuals_beside_floor(ident, ex.data, sources)
    poses = platform_poses(pv, ident.values, ex.data.commands)
    guesses = [(p[:3], ref.from_rotvec(p[3:])) for p in poses]
    predicted, _ = scr.readings(pv.robot.to_dict(), pv.table(ident.values), ex.data.commands, guesses)
    np.testing.assert_allclose(r["residual_mm"], np.linalg.norm(ex.data.measured[:, :3] - predicted[:, :3], axis=1),
                               atol=1e-7)
    robot_dict = spatial_robot_file(pv, ident.values)
    k = int(np.argmax(r["residual_mm"]))
    M, ref_sources = eref.sensitivity(robot_dict, cl_dict, poses[k, :3],
                                      ref.from_rotvec(poses[k, 3:]))
    lower = eref.max_norm_sampled(M, ref_sources, n=20000)
    assert lower * (1 - 1e-6) <= r["floor"]["dp_max"][k] <= lower * 1.001


@pytest.mark.slow
def test_sigmas_honest_with_clearances_in_the_weights():
    """With a clearance state in every reading and the clearance covariance in the weights, the normalized
    errors (estimate - true) / sigma over 12 seeds have RMS within 20 % of 1 (1.06 here), none beyond 4.5, and
    the residual scale is about 1."""
    pv = spatial_error_parameters(SpatialManipulator.preset("stewart_6ups"))
    runs = [simulate_spatial_calibration(pv, 30, seed=s, clearances="ups_typical", n_targets=5, n_candidates=2000)
            for s in range(12)]
    z = np.concatenate([ex.normalized_errors() for ex in runs])
    assert np.all(np.abs(z) < 4.5) and 0.8 < np.sqrt(np.mean(z ** 2)) < 1.2
    assert 0.8 < np.mean([ex.identification.scale for ex in runs]) < 1.2


# ------------------------------------------------- the covariance and the states against a Monte Carlo drawn here


def _setup(name, preset):
    robot = SpatialManipulator.preset(name)
    sources = SpatialErrorSources.load(preset, robot)
    poses = candidate_poses(spatial_error_parameters(robot), 200, seed=1)[:3]
    return robot, sources, poses


def _rejection(rng, n, d):
    """``n`` points uniform in the unit ``d``-ball, by rejection from the cube ``[-1, 1]^d``."""
    out = np.empty((0, d))
    while len(out) < n:
        x = rng.uniform(-1.0, 1.0, (4 * n, d))
        out = np.concatenate([out, x[np.sum(x * x, axis=1) <= 1.0]])
    return out[:n]


def _base_covariance(robot, sources, poses):
    """The identification's clearance covariance of full-pose readings in a device frame at the base frame."""
    from pmaccuracy.accuracy.calibration.spatial_identify import SpatialCalibrationData, clearance_covariance

    pv = spatial_error_parameters(robot)
    n = len(poses)
    data = SpatialCalibrationData(tuple(map(str, range(n))), np.zeros((n, 6)), np.zeros((n, 6)), np.ones((n, 6)),
                                  np.zeros(n, int))
    return clearance_covariance(pv, pv.nominal, data, poses, sources)


def test_covariance_matches_monte_carlo_of_uniform_states():
    """A 3-RPS (segments and discs among its sources): the covariance against 20000 states drawn here, uniform
    in the segment, disc and ball by rejection from the cube (not by the library's sampler)."""
    from pmaccuracy.accuracy.spatial_bounds import error_sources_at

    robot, sources, poses = _setup("rps_3", "rps_typical")
    C = _base_covariance(robot, sources, poses)
    rng = np.random.default_rng(0)
    n = 20000
    _, info = error_sources_at(robot, sources, poses, strict=False, keep=True, allow_outside=True)
    M = [s.matrix for s in info["sources"]]
    assert {m.shape[-1] for m in M} >= {1, 2}
    samples = np.zeros((n, len(poses), 6))
    for m in M:
        u = _rejection(rng, n, m.shape[-1])
        samples += np.einsum("pij,nj->npi", m, u)
    emp = np.einsum("npi,npj->pij", samples, samples) / n
    scale = np.sqrt(np.einsum("pii->pi", C))
    # 20000 draws: the second moments within 5 % of the largest (their sampling error is ~1 %)
    assert np.max(np.abs(emp - C) / (scale[:, :, None] * scale[:, None, :])) < 0.05


def test_random_displacements_stay_inside_the_worst_case_bound():
    from pmaccuracy.accuracy.spatial_bounds import spatial_pose_errors

    robot, sources, poses = _setup("stewart_6ups", "ups_typical")
    rng = np.random.default_rng(1)
    tw = clearance_twists(robot, sources, np.tile(poses, (400, 1)), rng).reshape(400, len(poses), 6)
    bound = spatial_pose_errors(robot, sources, poses)
    assert np.all(np.linalg.norm(tw[:, :, :3], axis=-1) <= bound.dp_upper * (1 + 1e-9))
    assert np.all(np.linalg.norm(tw[:, :, 3:], axis=-1) <= bound.dtheta_upper * (1 + 1e-9))
    # and their second moments are the covariance's (the library's sampler against its own formula)
    C = _base_covariance(robot, sources, poses)
    emp = np.einsum("spi,spj->pij", tw, tw) / len(tw)
    assert np.allclose(np.trace(emp[:, :3, :3], axis1=1, axis2=2), np.trace(C[:, :3, :3], axis1=1, axis2=2),
                       rtol=0.25)
