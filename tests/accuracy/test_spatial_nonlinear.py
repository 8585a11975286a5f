"""Certified nonlinear bounds of a 6-UPS at a pose against the independent brute-force reference
(tests/reference/spatial_error_reference.py: every source a finite displacement in the legs' serial chains,
36 unknowns solved by least squares; it does not import pmaccuracy)."""

from __future__ import annotations

import numpy as np
import pytest
import spatial_error_reference as eref
import spatial_reference as ref

import pmaccuracy as pm
from pmaccuracy.accuracy.spatial_bounds import spatial_pose_errors
from pmaccuracy.accuracy.spatial_nonlinear import hexapod_error_twists, spatial_certified_bounds
from pmaccuracy.errors import UnsupportedArchitectureError
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.model.spatial_sources import SpatialErrorSources
from pmaccuracy.numerics.spatial import rotvecs

TOL = 1e-12


def _case(seed, scale):
    """A robot (ours, the reference's dict), its sources at ``scale`` (ours, dict), a pose, the reference model."""
    if seed is None:
        robot_d = ref.load_reference("6-UPS")
        cl = eref.load_clearances("6-UPS")
        p, R = eref.nominal_pose(robot_d)
    else:
        robot_d = ref.random_robot("6-UPS", seed)
        cl = eref.random_clearances(robot_d, seed)
        p, R = ref.random_pose(robot_d, seed)
    robot = SpatialManipulator.from_dict(robot_d, source="r.toml")
    src = SpatialErrorSources.from_dict(cl, robot, source="c.toml").scaled(scale)
    model = eref.ErrorModel(robot_d, src.to_dict(), p, R)
    return robot, src, np.concatenate([p, rotvecs(R)]), model


def _label(s):
    return f"legs[{s['leg'] + 1}].joints[{s['joint'] + 1}].{s['key']}" + (f"[{s['part']}]" if s["part"] else "")


def _to_reference(model, conf):
    """Our configuration (each source's displacement vector) as the reference's variables (its own bases)."""
    x = np.zeros(model.m)
    for s in model.sources:
        vec = conf.get(_label(s), np.zeros(3))
        D = np.array(s["directions"])
        x[s["columns"]] = D @ vec
        assert np.linalg.norm(D.T @ x[s["columns"]] - vec) <= 1e-12 * max(1.0, np.linalg.norm(vec))  # in its span
        assert np.linalg.norm(x[s["columns"]]) <= s["half_width"] * (1 + 1e-12)                     # in its set
    return x


def _from_reference(model, x):
    return {_label(s): sum(v * d for v, d in zip(x[s["columns"]], s["directions"])) for s in model.sources}


def _quantities(T):
    T = np.atleast_2d(T)
    return np.concatenate([np.abs(T), np.linalg.norm(T[:, :3], axis=1, keepdims=True),
                           np.linalg.norm(T[:, 3:], axis=1, keepdims=True)], axis=1)


def _vertex(model, rng):
    """A configuration at a vertex-like point: segments at +-h, discs and balls on a random axis direction."""
    x = np.zeros(model.m)
    for s in model.sources:
        k = s["columns"].stop - s["columns"].start
        v = np.zeros(k)
        v[rng.integers(k)] = rng.choice([-1.0, 1.0])
        x[s["columns"]] = s["half_width"] * v
    return x


@pytest.mark.parametrize("seed,scale", [(None, 1.0), (None, 100.0), (4, 10.0), (5, 40.0)])
def test_exact_model_is_the_reference_closure(seed, scale):
    robot, src, pose, model = _case(seed, scale)
    rng = np.random.default_rng(7)
    X = [eref.random_extreme(model.sources, rng) for _ in range(4)] + [_vertex(model, rng)]
    T = np.array([model.solve(x) for x in X])
    ours = hexapod_error_twists(robot, src, pose, [_from_reference(model, x) for x in X])
    assert np.max(np.abs(ours - T)) <= 1e-11 * np.max(np.abs(T))


@pytest.mark.parametrize("seed,scale,samples", [(None, 1.0, 60), (None, 10.0, 60), (None, 40.0, 60),
                                                (3, 1.0, 30), (4, 10.0, 30), (5, 40.0, 30)])
def test_reference_sampling_never_above_the_certified_upper_and_lower_is_attained(seed, scale, samples):
    robot, src, pose, model = _case(seed, scale)
    res = spatial_certified_bounds(robot, src, pose)
    assert res.certified, res.reason
    rng = np.random.default_rng(11)
    X = [eref.random_extreme(model.sources, rng) for _ in range(samples // 2)] + \
        [_vertex(model, rng) for _ in range(samples // 2)]
    Q = _quantities(np.array([model.solve(x) for x in X]))
    assert np.all(Q <= res.upper * (1 + TOL)), (Q.max(axis=0), res.upper)
    # lower: the returned configurations, re-solved by the reference, attain it
    for k in range(8):
        x = _to_reference(model, res.configurations[k])
        value = _quantities(model.solve(x))[0, k]
        assert value == pytest.approx(res.lower[k], rel=1e-9, abs=1e-14)
        assert res.lower[k] <= res.upper[k]
    # near the first-order maximum (the exact values differ from it at second order)
    assert np.all(np.abs(res.lower - res.first_order) <= 0.5 * res.first_order)


def test_dense_sampling_of_the_validated_model_and_the_first_order_limit():
    """20,000 random and vertex configurations through the exact model (equal to the reference's, tests above)
    stay below the certified bounds; the first-order part equals spatial_pose_errors and the reference's
    finite-difference sensitivities."""
    robot, src, pose, model = _case(None, 10.0)
    res = spatial_certified_bounds(robot, src, pose)
    rng = np.random.default_rng(3)
    n = 20000
    conf = {}
    for s in model.sources:
        k = s["columns"].stop - s["columns"].start
        u = rng.normal(size=(n, k))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        axis = np.zeros((n, k))
        axis[np.arange(n), rng.integers(k, size=n)] = rng.choice([-1.0, 1.0], size=n)
        x = np.where((np.arange(n) % 2 == 0)[:, None], u, axis) * s["half_width"]
        conf[_label(s)] = conf.get(_label(s), 0.0) + x @ np.array(s["directions"])
    Q = _quantities(hexapod_error_twists(robot, src, pose, conf))
    assert np.all(np.isfinite(Q))
    assert np.all(Q <= res.upper * (1 + TOL))
    assert np.all(Q.max(axis=0) <= res.lower * (1 + 1e-9))         # the ascent found at least the sampled maxima
    first = spatial_pose_errors(robot, src, pose)
    assert np.allclose(res.first_order[:6], first.components, rtol=1e-12, atol=0)
    assert res.first_order[6] == pytest.approx(first.dp_upper, rel=1e-12)
    assert res.first_order[7] == pytest.approx(first.dtheta_upper, rel=1e-12)
    M, sources = eref.sensitivity(model.robot, src.scaled(0.1).to_dict(), model.position, model.R)
    comp = eref.component_bounds(M, sources) * 10.0
    assert np.allclose(res.first_order[:6], comp, rtol=1e-6)


def test_hexapod_preset_at_100x_and_a_refusal():
    hexapod = pm.load_robot("stewart_6ups")
    sources = pm.load_clearances("ups_typical", hexapod).scaled(100.0)
    res = spatial_certified_bounds(hexapod, sources, hexapod.home_pose)
    assert res.certified and np.all(res.gap < 0.25)
    # the reference's own model of this robot and preset (the robot's and the sources' tables as written)
    assert np.all(hexapod.home_pose[3:] == 0)
    model = eref.ErrorModel(hexapod.to_dict(), sources.to_dict(), hexapod.home_pose[:3], np.eye(3))
    rng = np.random.default_rng(5)
    X = [eref.random_extreme(model.sources, rng) for _ in range(20)] + [_vertex(model, rng) for _ in range(20)]
    Q = _quantities(np.array([model.solve(x) for x in X]))
    assert np.all(Q <= res.upper * (1 + TOL))
    for k in (0, 6, 7):
        assert _quantities(model.solve(_to_reference(model, res.configurations[k])))[0, k] == \
            pytest.approx(res.lower[k], rel=1e-9)
    # the random robot's clearances at 100x (errors 8 % of its legs): refused, never a finite upper value
    robot, src, pose, _ = _case(5, 100.0)
    res = spatial_certified_bounds(robot, src, pose)
    assert not res.certified and res.reason and np.all(np.isinf(res.upper)) and np.all(np.isfinite(res.lower))


def test_remainder_scales_like_the_square_of_the_half_widths():
    robot, src, pose, model = _case(6, 1.0)
    rem, nl = [], []
    for scale in (1.0, 0.1, 0.01):
        res = spatial_certified_bounds(robot, src.scaled(scale), pose, ascent_steps=0)
        assert res.certified
        rem.append(res.upper - res.first_order)
        nl.append(res.first_order)
    rem, nl = np.array(rem), np.array(nl)
    assert np.all(rem > 0)
    ratios = rem[:-1] / rem[1:]                      # h^2: 100 per decade (first order: 10)
    assert np.all((ratios > 90) & (ratios < 110)), ratios
    assert np.allclose(nl[:-1] / nl[1:], 10.0, rtol=1e-9)
    # the reference's exact errors at the returned configuration minus first order also shrink like h^2
    gaps = []
    for scale in (1.0, 0.1):
        r2, s2, p2, m2 = _case(6, scale)
        res = spatial_certified_bounds(r2, s2, p2)
        twist = m2.solve(_to_reference(m2, res.configurations[0]))
        gaps.append(abs(twist[0]) - res.first_order[0])
    assert gaps[1] > 0 and 50 < gaps[0] / gaps[1] < 200, gaps


def test_refusals():
    hexapod = pm.load_robot("stewart_6ups")
    res = spatial_certified_bounds(hexapod, pm.load_clearances("ups_typical", hexapod).scaled(3000.0),
                                   hexapod.home_pose)
    assert not res.certified and res.reason and np.all(np.isinf(res.upper))
    with pytest.raises(UnsupportedArchitectureError, match="6-UPS only"):
        hexapod_error_twists(pm.load_robot("delta_clavel"), "delta_typical", [0, 0, -800.0, 0, 0, 0], [{}])
    with pytest.raises(pm.PoseError, match="one pose"):
        spatial_certified_bounds(hexapod, "ups_typical", [hexapod.home_pose] * 2)
    with pytest.raises(pm.SingularPoseError):
        spatial_certified_bounds(hexapod, "ups_typical", [0, 0, 400.0, 0, 0, np.pi / 2], allow_outside=True)
    src = pm.load_clearances("ups_typical", hexapod)
    with pytest.raises(pm.ConfigError, match="outside its ball"):
        hexapod_error_twists(hexapod, src, hexapod.home_pose, [{"legs[1].joints[3].radial": [0.011, 0, 0]}])
    with pytest.raises(pm.ConfigError, match="outside its segment"):     # the actuator error is along the leg
        hexapod_error_twists(hexapod, src, hexapod.home_pose, [{"legs[1].joints[2].actuator": [0.001, 0, 0]}])
    with pytest.raises(pm.ConfigError, match="no such source"):
        hexapod_error_twists(hexapod, src, hexapod.home_pose, [{"legs[1].joints[3].axial": [0.0, 0, 0]}])
    none = spatial_certified_bounds(hexapod, "none", hexapod.home_pose)
    assert none.certified and np.all(none.upper == 0)
