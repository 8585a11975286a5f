"""Certified nonlinear bounds of the 3-RPS, 3-PRS, 3-UPU and Delta at a pose (issue 37) against the independent
brute-force reference (tests/reference/spatial_error_reference.py: every source a finite displacement in the legs'
serial chains, all the passive joints' motions and the pose solved by least squares; it does not import
pmaccuracy)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import spatial_error_reference as eref
import spatial_reference as ref
from chain_builders import chain_table
from conftest import run_cli

import pmaccuracy as pm
from pmaccuracy.accuracy import spatial_nonlinear as sn
from pmaccuracy.accuracy.spatial_bounds import spatial_pose_errors
from pmaccuracy.errors import UnsupportedArchitectureError
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.model.spatial_sources import SpatialErrorSources
from pmaccuracy.numerics.spatial import rotvecs

ARCHS = ("3-RPS", "3-PRS", "3-UPU", "delta")
TOL = 1e-12


def _case(arch, scale, seed=None):
    """The reference's robot and clearance file at its nominal pose, or (``seed``) a random robot, clearances and
    pose (a 3-RPS / 3-PRS pose then turned by about 0.1 rad)."""
    if seed is None:
        robot_d = ref.load_reference(arch)
        p, R = eref.nominal_pose(robot_d)
        cl = eref.load_clearances(arch)
    else:
        robot_d = ref.random_robot(arch, seed)
        p, R = ref.random_pose(robot_d, seed)
        cl = eref.random_clearances(robot_d, seed)
    robot = SpatialManipulator.from_dict(robot_d, source="r.toml")
    src = SpatialErrorSources.from_dict(cl, robot, source="c.toml").scaled(scale)
    return robot, src, np.concatenate([p, rotvecs(R)]), eref.ErrorModel(robot_d, src.to_dict(), p, R)


def _label(s):
    return f"legs[{s['leg'] + 1}].joints[{s['joint'] + 1}].{s['key']}" + (f"[{s['part']}]" if s["part"] else "")


def _to_reference(model, conf):
    x = np.zeros(model.m)
    for s in model.sources:
        vec = conf.get(_label(s), np.zeros(3))
        D = np.array(s["directions"])
        x[s["columns"]] = D @ vec
        assert np.linalg.norm(D.T @ x[s["columns"]] - vec) <= 1e-12 * max(1.0, np.linalg.norm(vec))   # in its span
        assert np.linalg.norm(x[s["columns"]]) <= s["half_width"] * (1 + 1e-12)                       # in its set
    return x


def _from_reference(model, x):
    return {_label(s): sum(v * d for v, d in zip(x[s["columns"]], s["directions"])) for s in model.sources}


def _to_ours(geo, model, X):
    """The reference's configurations ``X`` as our unit variables."""
    out = np.zeros((len(X), geo.offsets[-1]))
    for n, x in enumerate(X):
        conf = {_label(s): sum(v * d for v, d in zip(x[s["columns"]], s["directions"])) for s in model.sources}
        for k, s in enumerate(geo.sources):
            out[n, geo.offsets[k]:geo.offsets[k + 1]] = conf.get(s.label, np.zeros(3)) @ s.basis / s.half_width
    return out


def _quantities(T):
    T = np.atleast_2d(T)
    return np.concatenate([np.abs(T), np.linalg.norm(T[:, :3], axis=1, keepdims=True),
                           np.linalg.norm(T[:, 3:], axis=1, keepdims=True)], axis=1)


def _vertex(model, rng):
    x = np.zeros(model.m)
    for s in model.sources:
        k = s["columns"].stop - s["columns"].start
        v = np.zeros(k)
        v[rng.integers(k)] = rng.choice([-1.0, 1.0])
        x[s["columns"]] = s["half_width"] * v
    return x


@pytest.mark.parametrize("arch", ARCHS)
def test_exact_model_is_the_reference_closure(arch):
    robot, src, pose, model = _case(arch, 30.0)
    geo = sn._chain_geometry(robot, src, pose)
    A, _ = sn._chain_linear(geo)
    rng = np.random.default_rng(2)
    X = [eref.random_extreme(model.sources, rng) for _ in range(2)] + [_vertex(model, rng)]
    T = np.array([model.solve(x) for x in X])
    ours = sn.spatial_error_twists(robot, src, pose, [_from_reference(model, x) for x in X])
    assert np.max(np.abs(ours - T)) <= 1e-11 * np.max(np.abs(T))
    t2, ok = sn._chain_solve(geo, np.linalg.inv(A), _to_ours(geo, model, X))
    assert np.all(ok) and np.max(np.abs(t2 - ours)) <= 1e-12 * np.max(np.abs(T))
    # the closure's linear part: central differences of the exact residual
    E0 = sn._joint_displacements(geo, np.zeros((1, geo.offsets[-1])))
    h = 1e-6
    fd = np.array([(sn._chain_residual(geo, h * e[None], E0) - sn._chain_residual(geo, -h * e[None], E0))[0] / (2 * h)
                   for e in np.eye(geo.n)]).T
    assert np.max(np.abs(fd - A)) <= 1e-8 * np.max(np.abs(A))


@pytest.mark.parametrize("arch,scale,seed,gap", [("3-RPS", 1.0, 1, 0.005), ("3-PRS", 10.0, 2, 0.06),
                                                 ("3-UPU", 1.0, None, 0.04), ("delta", 10.0, None, 0.03)])
def test_reference_samples_never_above_the_upper_and_the_lower_is_attained(arch, scale, seed, gap):
    robot, src, pose, model = _case(arch, scale, seed)
    res = pm.spatial_certified_bounds(robot, src, pose)
    assert res.certified, res.reason
    rng = np.random.default_rng(11)
    X = [eref.random_extreme(model.sources, rng) for _ in range(6)] + [_vertex(model, rng) for _ in range(6)]
    Q = _quantities(np.array([model.solve(x) for x in X]))
    assert np.all(Q <= res.upper * (1 + TOL)), (Q.max(axis=0), res.upper)
    for k in range(8):
        value = _quantities(model.solve(_to_reference(model, res.configurations[k])))[0, k]
        assert value == pytest.approx(res.lower[k], rel=1e-9, abs=1e-14)
    assert np.all(Q.max(axis=0) <= res.lower * (1 + 1e-9))
    assert np.all(res.lower <= res.upper) and np.all(res.gap < gap), res.gap
    # the first-order part is the first-order model's
    first = spatial_pose_errors(robot, src, pose)
    assert np.allclose(res.first_order[:6], first.components, rtol=1e-9, atol=0)
    assert res.first_order[6] == pytest.approx(first.dp_upper, rel=2e-3)


@pytest.mark.parametrize("name,preset,gap", [("rps_3", "rps_typical", 0.01), ("prs_3", "prs_typical", 0.01),
                                             ("upu_3", "upu_typical", 0.01), ("delta_clavel", "delta_typical", 0.01)])
def test_typical_presets_gap(name, preset, gap):
    robot = pm.load_robot(name)
    res = pm.spatial_certified_bounds(robot, preset, robot.home_pose)
    assert res.certified and np.all(res.gap < gap), res.gap
    # dense sampling of the validated exact model (vertices and random points of the sets)
    geo = sn._chain_geometry(robot, SpatialErrorSources.load(preset, robot), robot.home_pose)
    A, _ = sn._chain_linear(geo)
    rng = np.random.default_rng(4)
    n, m = 400, geo.offsets[-1]
    x = np.zeros((n, m))
    for k in range(len(geo.sources)):
        a, b = geo.offsets[k], geo.offsets[k + 1]
        u = rng.normal(size=(n, b - a))
        x[:, a:b] = u / np.linalg.norm(u, axis=1, keepdims=True)
    t, ok = sn._chain_solve(geo, np.linalg.inv(A), x)
    assert np.all(ok)
    assert np.all(_quantities(t) <= res.upper * (1 + TOL))


def test_remainder_scales_like_the_square_of_the_half_widths():
    robot, src, pose, _ = _case("3-RPS", 1.0)
    rem, first = [], []
    for scale in (1.0, 0.1, 0.01):
        res = pm.spatial_certified_bounds(robot, src.scaled(scale), pose, ascent_steps=0)
        assert res.certified
        rem.append(res.upper - res.first_order)
        first.append(res.first_order)
    rem, first = np.array(rem), np.array(first)
    ratios = rem[:-1] / rem[1:]                      # h^2: 100 per decade (first order: 10)
    assert np.all((ratios > 85) & (ratios < 115)), ratios
    assert np.allclose(first[:-1, :6] / first[1:, :6], 10.0, rtol=1e-9)


def test_refusals_and_cli(capsys):
    robot, src, pose, _ = _case("3-RPS", 100.0)
    res = pm.spatial_certified_bounds(robot, src, pose, ascent_steps=0)
    assert not res.certified and res.reason and np.all(np.isinf(res.upper)) and np.all(np.isfinite(res.lower))
    hexapod = pm.load_robot("stewart_6ups")
    chain = SpatialManipulator.from_dict(chain_table(hexapod), "chain.toml")
    with pytest.raises(UnsupportedArchitectureError, match="6-UPS, 3-RPS"):
        pm.spatial_certified_bounds(chain, "none", hexapod.home_pose)
    upu = pm.load_robot("upu_3")
    with pytest.raises(pm.PoseError, match="constraints"):
        pm.spatial_certified_bounds(upu, "upu_typical", upu.home_pose + np.r_[0, 0, 0, 0, 0, 0.01])
    src = pm.load_clearances("upu_typical", upu)
    with pytest.raises(pm.ConfigError, match="outside its disc"):
        sn.spatial_error_twists(upu, src, upu.home_pose, [{"legs[1].joints[1].radial[pin 1]": [0.0, 0, 1.0]}])
    with pytest.raises(pm.ConfigError, match="no such source"):
        sn.spatial_error_twists(upu, src, upu.home_pose, [{"legs[1].joints[1].position": [0.0, 0, 0.0]}])
    delta = pm.load_robot("delta_clavel")
    status, text, _ = run_cli(["bounds", "--robot", "delta_clavel", "--pose", 0, 0, -800, "--certified",
                               "--format", "json"], capsys)
    assert status == 0
    api = pm.spatial_certified_bounds(delta, "delta_typical", [0, 0, -800.0, 0, 0, 0])
    for row, rec in zip(json.loads(text), api.records()):
        assert row["upper"] == pytest.approx(rec["upper"], rel=1e-12) and row["certified"] is True
