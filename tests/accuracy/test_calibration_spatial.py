"""Spatial calibration: readings from the independent reference model (tests/reference), identification,
identifiability against the reference's null space, honest sigmas over seeds, a gross reading flagged."""

from __future__ import annotations

import numpy as np
import pytest

import spatial_calibration_reference as scr
import spatial_reference as sr
from pmaccuracy.accuracy.calibration.spatial_identify import (SpatialCalibrationData, identify_spatial,
                                                              platform_poses, predict, residual_jacobian, residuals,
                                                              spatial_identifiability)
from pmaccuracy.accuracy.calibration.spatial_parameters import spatial_error_parameters, spatial_robot_file
from pmaccuracy.accuracy.calibration.spatial_simulate import (PRACTICAL_MAX_SIGMA, candidate_poses,
                                                              simulate_spatial_calibration, spatial_true_parameters)
from pmaccuracy.kinematics.spatial import inverse_kinematics
from pmaccuracy.model.spatial import SpatialManipulator

SIG_MM, SIG_RAD = 0.01, np.radians(0.01)
TYPICAL = {"mm": 1.0, "rad": 1e-2, "1": 1e-2}


def _setup(name, targets, n, seed=0):
    pv = spatial_error_parameters(SpatialManipulator.preset(name), targets=targets)
    poses = candidate_poses(pv, 400, seed=seed)[:n]
    commands = inverse_kinematics(pv.robot, poses).q
    return pv, poses, commands


def _reference_data(pv, true, commands, poses):
    """Readings of the true robot computed by the reference model (no library code)."""
    robot = pv.robot.to_dict()
    guesses = [(p[:3], sr.from_rotvec(p[3:])) for p in poses]
    full, points = scr.readings(robot, pv.table(true), commands, guesses)
    if pv.kind == "pose":
        sig = np.tile([SIG_MM] * 3 + [SIG_RAD] * 3, (len(full), 1))
        return SpatialCalibrationData(tuple(map(str, range(len(full)))), commands, full, sig,
                                      np.zeros(len(full), dtype=int))
    T = pv.n_targets
    m = np.array([pt[k] for pt in points for k in range(T)])
    return SpatialCalibrationData(tuple(map(str, range(len(m)))), np.repeat(commands, T, axis=0), m,
                                  np.full(m.shape, SIG_MM), np.tile(np.arange(T), len(commands)))


def _probe(pv, commands):
    k = 6 if pv.kind == "pose" else 3
    T = max(pv.n_targets, 1)
    sig = np.tile([SIG_MM] * 3 + [SIG_RAD] * 3, (len(commands) * T, 1))[:, :k]
    return SpatialCalibrationData(tuple(map(str, range(len(sig)))), np.repeat(commands, T, axis=0),
                                  np.zeros(sig.shape), sig, np.tile(np.arange(T), len(commands)))


@pytest.mark.parametrize("name, targets, n", [
    ("stewart_6ups", None, 25),
    ("stewart_6ups", [[0.0, 0.0, 30.0], [60.0, 0.0, 10.0], [0.0, 60.0, 0.0]], 15),
    ("delta_clavel", None, 25),
    ("delta_clavel", [[0.0, 0.0, -20.0]], 20),
    ("rps_3", None, 15),
    ("prs_3", [[10.0, 0.0, 20.0], [0.0, 40.0, 0.0]], 15),
    ("upu_3", None, 15),
])
def test_noise_free_reference_readings_recovered(name, targets, n):
    pv, poses, commands = _setup(name, targets, n)
    fixed = spatial_identifiability(pv, _probe(pv, commands), max_sigma=PRACTICAL_MAX_SIGMA).fixed
    true = spatial_true_parameters(pv, seed=4, fixed=fixed)
    data = _reference_data(pv, true, commands, poses)
    ident = identify_spatial(data, pv)
    assert ident.identifiability.fixed == fixed
    assert not ident.outliers
    scale = np.array([TYPICAL[u] for u in pv.units])
    assert np.max(np.abs(ident.values - true) / scale) < 1e-8
    # the identified robot written back as a robot file reads back with the same geometry
    back = SpatialManipulator.from_dict(spatial_robot_file(pv, ident.values), source="identified")
    assert np.allclose([leg.base for leg in back.legs], [leg.base for leg in ident.robot.legs], atol=1e-12)


def test_jacobian_matches_finite_differences_of_the_forward_model():
    pv, poses, commands = _setup("stewart_6ups", [[10.0, 20.0, 30.0], [0.0, 0.0, 40.0]], 6)
    true = spatial_true_parameters(pv, seed=2)
    data = _reference_data(pv, true, commands, poses)
    v = pv.nominal + 1e-3 * np.random.default_rng(0).standard_normal(len(pv.names))
    at = platform_poses(pv, v, data.commands)
    J = residual_jacobian(pv, v, data, at)
    for j in range(len(v)):
        h = 1e-6
        up, dn = v.copy(), v.copy()
        up[j] += h
        dn[j] -= h
        fd = (residuals(pv, up, data, platform_poses(pv, up, data.commands, at))
              - residuals(pv, dn, data, platform_poses(pv, dn, data.commands, at))) / (2 * h)
        assert np.allclose(J[:, :, j], fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max()), pv.names[j]


@pytest.mark.parametrize("name, targets", [("rps_3", None), ("prs_3", [[10.0, 0.0, 20.0]]), ("delta_clavel", None),
                                           ("upu_3", None)])
def test_axis_jacobian_columns_match_finite_differences_of_the_forward_model(name, targets):
    """The columns of the axis angles (and of every other leg parameter) against central differences of the
    exact model: forward kinematics of the robot with the parameter moved, then the readings."""
    pv, poses, commands = _setup(name, targets, 3)
    true = spatial_true_parameters(pv, seed=2)
    data = _reference_data(pv, true, commands, poses)
    v = pv.nominal + 1e-3 * np.random.default_rng(0).standard_normal(len(pv.names))
    at = platform_poses(pv, v, data.commands)
    J = residual_jacobian(pv, v, data, at)
    cols = [j for j, n in enumerate(pv.names) if n.startswith("legs[")]
    assert any(pv.names[j].endswith((".a", ".b")) for j in cols)
    scale = np.abs(J[:, :, cols]).max()
    for j in cols:
        h = 1e-6
        up, dn = v.copy(), v.copy()
        up[j] += h
        dn[j] -= h
        fd = (residuals(pv, up, data, platform_poses(pv, up, data.commands, at))
              - residuals(pv, dn, data, platform_poses(pv, dn, data.commands, at))) / (2 * h)
        assert np.allclose(J[:, :, j], fd, rtol=1e-5, atol=1e-7 * scale), pv.names[j]


def test_axis_parameters_turn_the_directions_and_the_robot_file_keeps_them():
    """``tilt(d, a, b)`` turns a direction by ``sqrt(a^2 + b^2)`` about a normal of it; a 3-PRS's axis stays
    perpendicular to its slide; the identified robot written back reads back with the same directions."""
    pv = spatial_error_parameters(SpatialManipulator.preset("prs_3"))
    v = pv.nominal.copy()
    a, b, c = pv.index(["legs[2].slide.a", "legs[2].slide.b", "legs[2].axis.a"])
    v[[a, b, c]] = [0.003, -0.004, 0.002]
    nominal, moved = pv.robot.legs[1], pv.split(v)[0].legs[1]
    assert np.isclose(np.arccos(np.clip(np.dot(nominal.slide, moved.slide), -1, 1)), 0.005, rtol=1e-9)
    assert abs(np.dot(moved.slide, moved.axis)) < 1e-15
    assert np.isclose(np.linalg.norm(moved.axis), 1.0)
    back = SpatialManipulator.from_dict(spatial_robot_file(pv, v), source="identified")
    assert np.allclose(back.legs[1].slide, moved.slide, atol=1e-15)
    assert np.allclose(back.legs[1].axis, moved.axis, atol=1e-15)
    assert "legs[1].axis.a" not in spatial_error_parameters(SpatialManipulator.preset("stewart_6ups")).names


@pytest.mark.parametrize("name", ["rps_3", "prs_3", "upu_3"])
def test_axis_identifiability_matches_reference_null_space(name):
    """Full-pose data of the lower-mobility robots with their axis angles, against the reference's null space:
    its exact part (singular values below 1e-9) lies in the span of the reported combinations, and along each
    of them the reference's residuals change by less than 1e-5 of its largest singular value (a 3-PRS has three
    directions at 1e-7..1e-6 of which the analysis' own threshold fixes some); a 3-UPU's axes (Tsai's condition kept) move nothing, the reference says so too."""
    pv, poses, commands = _setup(name, None, 15)
    data = _reference_data(pv, pv.nominal, commands, poses)
    idf = spatial_identifiability(pv, data)
    J = scr.ik_residual_jacobian(pv.robot.to_dict(), pv.table(), pv.names, commands, data.measured)
    scale = np.array([TYPICAL[u] for u in pv.units])
    exact, near = scr.null_space(J, scale, rtol=1e-9), scr.null_space(J, scale, rtol=1e-5)
    assert exact.shape[1] <= len(idf.fixed) <= near.shape[1]
    ours, _ = np.linalg.qr(idf.null_directions.T)
    for d in exact.T:      # 1e-4: the reference's differences (1e-11) against the gap to the weak ones (4e-7)
        assert np.linalg.norm(d - ours @ (ours.T @ d)) < 1e-4
    Js = J * scale
    smax = np.linalg.norm(Js, 2)
    for row in idf.null_directions:       # the reference's readings barely move along each combination
        d = row / scale
        assert np.linalg.norm(Js @ d) < 1e-5 * smax * np.linalg.norm(d)
    axes = [n for n in pv.names if n.endswith((".a", ".b"))]
    if name == "upu_3":
        assert set(axes) <= set(idf.fixed)
        assert np.allclose(J[:, pv.index(axes)], 0.0, atol=1e-9)
    else:
        assert set(axes) & set(idf.identified)


@pytest.mark.parametrize("name, count", [("stewart_6ups", 6), ("delta_clavel", 12)])
def test_unidentifiable_combinations_match_reference_null_space(name, count):
    """Full-pose data: the reference's null space (inverse-kinematic residuals at exact readings, central
    differences) has the dimension of the fixed set, and every combination reported spans it."""
    pv, poses, commands = _setup(name, None, 20)
    data = _reference_data(pv, pv.nominal, commands, poses)
    idf = spatial_identifiability(pv, data)
    table = pv.table()
    J = scr.ik_residual_jacobian(pv.robot.to_dict(), table, pv.names, commands, data.measured)
    scale = np.array([TYPICAL[u] for u in pv.units])
    basis = scr.null_space(J, scale)
    assert basis.shape[1] == len(idf.fixed) == count
    for row in idf.null_directions:
        d = row / np.linalg.norm(row)
        assert np.linalg.norm(d - basis @ (basis.T @ d)) < 1e-5
    assert all("cannot be separated" in s for s in idf.combinations)
    if name == "stewart_6ups":     # the classic result: the measurement frame is tied to the base joints
        assert set(idf.fixed) == {f"frame.{a}" for a in ("x", "y", "z", "rx", "ry", "rz")}


def test_position_only_single_target_ties_the_platform_frame():
    """One target: a rigid change of the platform frame (6) and of the base frame (6) are invisible."""
    pv, poses, commands = _setup("stewart_6ups", [[10.0, 20.0, 30.0]], 20)
    idf = spatial_identifiability(pv, _probe(pv, commands))
    assert len(idf.fixed) == 12
    assert {"tool.x", "tool.y", "tool.z"} <= set(idf.fixed)


def _normalized(pv, seeds, noise, n_poses=30):
    return np.concatenate([simulate_spatial_calibration(pv, n_poses, seed=seed, noise=noise, plan="random").normalized_errors()
                           for seed in seeds])


@pytest.mark.parametrize("name, targets", [
    ("stewart_6ups", None),
    pytest.param("stewart_6ups", [[0.0, 0.0, 30.0], [60.0, 0.0, 10.0]], marks=pytest.mark.slow),
    ("delta_clavel", [[0.0, 0.0, -20.0]]),
    pytest.param("delta_clavel", None, marks=pytest.mark.slow)])
def test_sigmas_honest_over_20_seeds(name, targets):
    """(estimate - true) / sigma of every identified parameter over 20 seeds: RMS within 15 % of 1 (the
    covariance scaled by the residual is honest), none beyond 4.5."""
    pv = spatial_error_parameters(SpatialManipulator.preset(name), targets=targets)
    z = _normalized(pv, range(20), (SIG_MM, SIG_RAD))
    assert np.all(np.abs(z) < 4.5)
    assert 0.85 < np.sqrt(np.mean(z ** 2)) < 1.15


def test_gross_reading_flagged():
    pv = spatial_error_parameters(SpatialManipulator.preset("stewart_6ups"), targets=[[0.0, 0.0, 30.0]])
    ex = simulate_spatial_calibration(pv, 40, seed=3, noise=(SIG_MM, 0.0), gross=1)
    moved = np.flatnonzero(np.any(np.abs(ex.data.measured - _clean(pv, ex)) > 0.5, axis=1))
    assert tuple(moved) == ex.identification.outliers
    assert np.all(np.abs(ex.normalized_errors()) < 4.5)


def _clean(pv, ex):
    poses = platform_poses(pv, ex.true, ex.data.commands)
    return predict(pv, ex.true, poses, ex.data.target)


def test_lazy_greedy_plan_is_the_plain_greedy_and_beats_random():
    """The lazy D-optimal choice equals the plain greedy (every gain recomputed at every step, written here)
    and its D-optimal index beats random choices of as many poses."""
    from pmaccuracy.accuracy.calibration.spatial_plan import candidate_blocks, lazy_d_optimal, plan_spatial_poses

    pv = spatial_error_parameters(SpatialManipulator.preset("stewart_6ups"), targets=[[0.0, 0.0, 30.0]])
    B, _ = candidate_blocks(pv, candidate_poses(pv, 1500, seed=5))
    B = B / np.sqrt(np.mean(B ** 2, axis=(0, 1)) * B.shape[1])
    C, k, L = B.shape
    M = 1e-6 * float(np.mean(np.sum(B ** 2, axis=(1, 2)))) * np.eye(L)
    plain = []
    for _ in range(20):
        Minv = np.linalg.inv(M)
        g = np.array([np.linalg.slogdet(np.eye(k) + b @ Minv @ b.T)[1] for b in B])
        g[plain] = -np.inf
        plain.append(int(np.argmax(g)))
        M = M + B[plain[-1]].T @ B[plain[-1]]
    assert list(lazy_d_optimal(B, 20)) == plain
    plan = plan_spatial_poses(pv, 20, n_candidates=1500, seed=5)
    assert plan.index["O1"] > 1.5 * plan.random_index["O1"]
    assert np.allclose(inverse_kinematics(pv.robot, plan.poses).q, plan.commands)


@pytest.mark.parametrize("name, targets", [("stewart_6ups", None), ("stewart_6ups", [[0.0, 0.0, 30.0]]),
                                           ("delta_clavel", None)])
def test_compensated_commands_reach_the_targets_on_the_reference_robot(name, targets):
    """Noise-free readings of the reference's true robot, identification, compensation at other poses: the
    reference robot driven by the compensated commands reaches the targets (1e-6 mm, 1e-8 rad for the
    hexapod; a Delta's position), the nominal commands miss them by the parameter errors."""
    from pmaccuracy.accuracy.calibration.spatial_compensate import compensate_spatial

    pv, poses, commands = _setup(name, targets, 20)
    fixed = spatial_identifiability(pv, _probe(pv, commands), max_sigma=PRACTICAL_MAX_SIGMA).fixed
    true = spatial_true_parameters(pv, seed=6, fixed=fixed)
    ident = identify_spatial(_reference_data(pv, true, commands, poses), pv)
    goal = candidate_poses(pv, 200, seed=11)[:6]
    comp = compensate_spatial(ident, goal)
    guesses = [(p[:3], sr.from_rotvec(p[3:])) for p in goal]
    reached, _ = scr.readings(pv.robot.to_dict(), pv.table(true), comp.commands, guesses)
    missed, _ = scr.readings(pv.robot.to_dict(), pv.table(true), comp.nominal_commands, guesses)
    assert np.max(np.abs(reached[:, :3] - goal[:, :3])) < 1e-6
    assert np.max(np.abs(missed[:, :3] - goal[:, :3])) > 0.05
    if name == "stewart_6ups":
        assert np.max(np.abs(reached[:, 3:] - goal[:, 3:])) < 1e-8


@pytest.mark.parametrize("name", ["stewart_6ups", "delta_clavel", "rps_3", "prs_3", "upu_3"])
def test_virtual_calibration_of_every_preset(name):
    """Every spatial preset: identified within 4.5 sigma, and the compensated commands leave a small part of
    the nominal commands' error at other poses (what each architecture commands: 3-RPS/3-PRS z, roll, pitch)."""
    pv = spatial_error_parameters(SpatialManipulator.preset(name))
    ex = simulate_spatial_calibration(pv, 40, seed=3, noise=(SIG_MM, SIG_RAD))
    assert np.all(np.abs(ex.normalized_errors()) < 4.5)
    # down to the noise: a quarter of the error before, or two reading sigmas where that was small already
    assert np.nanmax(ex.errors_after[:, 0]) < max(0.25 * np.nanmax(ex.errors_before[:, 0]), 2 * SIG_MM)


def test_chain_robot_identification_agrees_with_the_designer_type():
    """A 3-RPS written joint by joint (R-P-S chains, tests/reference/chain_builders.py): its parameters (joint
    centres, axis angles, actuators) identified through the chain's numeric closure from noise-free readings
    of the reference's true 3-RPS fit them, as the designer type's identification does, and both identified
    robots predict the same readings at other commands: to 1e-4 mm against the nominal's error of ~1 mm (the
    chain's R joint heights are practically unidentifiable there, fixed at nominal: they leave ~3e-5 mm). The
    two are compared by their readings, not their parameters: each fixes its own gauge (frame or base)."""
    from chain_builders import chain_table

    pvd, poses, commands = _setup("rps_3", None, 10)
    fixed = spatial_identifiability(pvd, _probe(pvd, commands), max_sigma=PRACTICAL_MAX_SIGMA).fixed
    true = spatial_true_parameters(pvd, seed=4, fixed=fixed)
    data = _reference_data(pvd, true, commands, poses)
    chain = SpatialManipulator.from_dict(chain_table(pvd.robot), source="chain")
    pvc = spatial_error_parameters(chain)
    assert {"legs[1].joints[1].centre.x", "legs[1].joints[1].axis.a", "legs[1].joints[2].axis.b",
            "legs[1].joints[3].centre.z", "legs[3].actuator.gain"} <= set(pvc.names)
    designer, chained = identify_spatial(data, pvd), identify_spatial(data, pvc)
    assert designer.rms_after < 1e-6 and chained.rms_after < 1e-2 < 10 < chained.rms_before
    assert {"legs[1].joints[1].axis.a", "legs[1].joints[1].axis.b"} <= set(chained.identifiability.identified)
    other = inverse_kinematics(pvd.robot, candidate_poses(pvd, 200, seed=9)[:5]).q
    pd = predict(pvd, designer.values, platform_poses(pvd, designer.values, other))
    pc = predict(pvc, chained.values, platform_poses(pvc, chained.values, other))
    pn = predict(pvc, pvc.nominal, platform_poses(pvc, pvc.nominal, other))
    assert np.max(np.abs(pd - pn)[:, :3]) > 0.1
    assert np.max(np.abs(pd - pc)[:, :3]) < 1e-4 and np.max(np.abs(pd - pc)[:, 3:]) < 1e-6
    back = SpatialManipulator.from_dict(spatial_robot_file(pvc, chained.values), source="identified")
    moved = pvc.split(chained.values)[0]
    for b, m in zip(back.legs, moved.legs):
        assert np.allclose([j.centre for j in b.joints], [j.centre for j in m.joints], atol=1e-12)
        assert np.allclose(b.joints[0].axes[0], m.joints[0].axes[0], atol=1e-15)


def test_chain_jacobian_columns_match_finite_differences_of_the_forward_model():
    """The columns of a chain leg's joint centres and axis angles (closure derivatives at the chain's own passive
    solution) against central differences of the chain robot's forward kinematics."""
    from chain_builders import chain_table

    pvd, poses, commands = _setup("rps_3", None, 1)
    pv = spatial_error_parameters(SpatialManipulator.from_dict(chain_table(pvd.robot), source="chain"))
    data = _probe(pv, commands)
    v = pv.nominal + 1e-3 * np.random.default_rng(0).standard_normal(len(pv.names))
    at = platform_poses(pv, v, data.commands)
    J = residual_jacobian(pv, v, data, at)
    cols = [j for j, n in enumerate(pv.names) if n.startswith("legs[2].")]
    scale = np.abs(J[:, :, cols]).max()
    for j in cols:
        h = 1e-6
        up, dn = v.copy(), v.copy()
        up[j] += h
        dn[j] -= h
        fd = (residuals(pv, up, data, platform_poses(pv, up, data.commands, at))
              - residuals(pv, dn, data, platform_poses(pv, dn, data.commands, at))) / (2 * h)
        assert np.allclose(J[:, :, j], fd, rtol=1e-5, atol=1e-7 * scale), pv.names[j]


def test_simulation_takes_a_given_true_robot():
    """``true=``: the experiment's true robot is the one given (not seeded errors), its readings those of that
    robot (noise-free here: the identified base x within 1e-6 mm of the 0.3 mm error given); a wrong length is
    refused."""
    from pmaccuracy.errors import ConfigError

    pv = spatial_error_parameters(SpatialManipulator.preset("stewart_6ups"))
    true = pv.nominal.copy()
    k = pv.index(["legs[1].base.x"])[0]
    true[k] += 0.3
    ex = simulate_spatial_calibration(pv, 30, seed=0, true=true, noise=(0.0, 0.0), n_targets=3, n_candidates=2000)
    assert np.array_equal(ex.true, true)
    assert ex.identification.values[k] == pytest.approx(true[k], abs=1e-6)
    with pytest.raises(ConfigError):
        simulate_spatial_calibration(pv, 30, true=true[:-1], n_targets=3, n_candidates=2000)
