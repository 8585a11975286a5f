"""Kinematic calibration of robots whose legs are written in the general chain form ([[legs.joints]]).

Reference: tests/reference/chain_calibration_reference.py, a simulation of the chain convention written
from the guide, docs/guide/formats.md (its own end-frame formula, Newton on the closure equations, its own measurement frame
and its own measurement Jacobian): nothing of pmaccuracy's inverse kinematics or identification residual.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from chain_calibration_reference import (NAME, actuated_and_kinds, chain_end_frame, geometry_from_names,
                                         measure_chain_robot, measurement_jacobian, random_chain_robot_dict,
                                         solve_chain_robot)
from pmaccuracy.accuracy.calibration.data import CalibrationData
from pmaccuracy.accuracy.calibration.identify import identify
from pmaccuracy.accuracy.calibration.parameters import error_parameters
from pmaccuracy.accuracy.calibration.plan import plan_poses
from pmaccuracy.accuracy.calibration.simulate import true_parameters
from pmaccuracy.model.legs import ChainLeg
from pmaccuracy.model.manipulator import Manipulator

PRESETS = ["symmetric_3rrr", "symmetric_3rpr", "symmetric_3prr", "aalborg_3ppr"]
SIG = (0.01, 0.01, math.radians(0.01))


def _chain_dict(preset: str, seed: int) -> dict:
    base = Manipulator.preset(preset)
    table = Manipulator(legs=tuple(ChainLeg(leg.chain) for leg in base.legs), name="chain").to_dict()
    return random_chain_robot_dict(table, np.random.default_rng(seed))


class Setup:
    """A random chain robot, a plan of poses and the reference simulation's start values."""

    def __init__(self, preset: str, seed: int, n: int = 30):
        self.table = _chain_dict(preset, seed)
        self.robot = Manipulator.from_dict(self.table)
        self.pv = error_parameters(self.robot)
        self.kinds, self.act = actuated_and_kinds(self.table)
        self.plan = plan_poses(self.pv, n)
        q = [c.inverse_kinematics(self.plan.poses)[0] for c in self.robot.chains]   # Newton start only
        self.passive = np.stack([np.delete(qi, a, axis=1) for qi, a in zip(q, self.act)], axis=1)

    def values(self, v):
        return dict(zip(self.pv.names, (float(x) for x in v)))

    def measure(self, v, noise=None, seed=0):
        m = measure_chain_robot(self.values(v), self.kinds, self.act, self.plan.commands, self.plan.poses,
                                self.passive)
        if noise is not None:
            m = m + np.random.default_rng(seed).standard_normal(m.shape) * np.asarray(noise)
        return m

    def data(self, m):
        ok = np.all(np.isfinite(m), axis=1)
        n = int(ok.sum())
        return CalibrationData(tuple(map(str, range(n))), self.plan.commands[ok], m[ok], np.tile(SIG, (n, 1)), "<s>")


def test_names_follow_the_convention_of_the_readme():
    """The parameter names are the guide's (docs/guide/calibration.md); the reference's end frame at the package's joint values (its
    inverse kinematics) is the platform frame: both read the chain the same way."""
    s = Setup("symmetric_3rrr", 0, n=12)
    assert len(s.pv.names) == 3 * 17 + 3 and all(NAME.match(n) for n in s.pv.names)
    legs = geometry_from_names(s.values(s.pv.nominal), s.kinds)
    for i, chain in enumerate(s.robot.chains):
        q = chain.inverse_kinematics(s.plan.poses)[0]
        for pose, qn in zip(s.plan.poses, q):
            pos, ang = chain_end_frame(legs[i], qn)
            c, sn = math.cos(pose[2]), math.sin(pose[2])
            pl = legs[i]["platform"]
            assert np.allclose(pos, [pose[0] + c * pl[0] - sn * pl[1], pose[1] + sn * pl[0] + c * pl[1]], atol=1e-9)
            assert math.remainder(ang - pose[2] - legs[i]["platform_angle"], 2 * math.pi) == pytest.approx(0, abs=1e-12)


@pytest.mark.parametrize("preset", PRESETS)
def test_noise_free_chain_robot_recovered_to_1e8(preset):
    """Random chain robot, random errors on every identifiable parameter, measured by the reference
    simulation without noise or clearances: the identification returns the truth to 1e-8."""
    s = Setup(preset, 1)
    fixed = identify(s.data(s.measure(s.pv.nominal)), s.pv).identifiability.fixed
    true = true_parameters(s.pv, seed=4, fixed=fixed)
    data = s.data(s.measure(true))
    assert len(data) >= 25
    ident = identify(data, s.pv)
    assert set(ident.identifiability.fixed) == set(fixed)
    assert np.max(np.abs(ident.values - true)) < 1e-8, np.abs(ident.values - true).max()
    assert ident.rms_after < 1e-6 < ident.rms_before


@pytest.mark.parametrize("preset", PRESETS)
def test_unidentifiable_combinations_detected_exactly(preset):
    """Against the reference's own measurement Jacobian dm/dtheta: every reported combination leaves every
    measurement unchanged (to first order), the identified parameters are independent, and every fixed
    parameter is really dependent on them (rank does not grow)."""
    s = Setup(preset, 2, n=20)
    true = true_parameters(s.pv, seed=3)
    z = solve_chain_robot(s.values(true), s.kinds, s.act, s.plan.commands, s.plan.poses, s.passive)
    assert np.all(np.isfinite(z))
    m = s.measure(true)
    idf = identify(s.data(m), s.pv, frame=None).identifiability
    # the analysis is made at the nominal: redo it at the truth to compare with the reference there
    from pmaccuracy.accuracy.calibration.identifiability import analyse
    from pmaccuracy.accuracy.calibration.identify import jacobian, whitening
    d = s.data(m)
    idf = analyse(s.pv, jacobian(s.pv, true, d, whitening(s.pv, true, d)))
    Jref = measurement_jacobian(s.values(true), s.kinds, s.act, s.plan.commands, z, list(s.pv.names))
    Jref = Jref / np.tile(SIG, len(z))[:, None]
    norms = np.linalg.norm(Jref, axis=0)
    scale = np.where(norms > 0, norms, 1.0)
    for f, row in zip(idf.fixed, idf.null_directions):
        # relative to the columns it combines, or (a parameter without effect) to a typical column; 1e-5: the
        # reference's central differences (h = 1e-6 on coordinates of ~200 mm) carry a rounding error of ~1e-6 of
        # a column (a 3-PPR's frame.y reached 1.02e-6 with this venv's numpy/scipy), a dependent direction leaves 0
        # and an independent one O(1)
        assert np.linalg.norm(Jref @ row) < 1e-5 * max(np.max(np.abs(row) * norms), np.median(norms)), f
    keep = s.pv.index(idf.identified)
    sv = np.linalg.svd(Jref[:, keep] / scale[keep], compute_uv=False)
    assert sv[-1] > 1e-5 * sv[0]   # independent (the analysis drops below 1e-6; a 3-PPR chain has 2.5e-4)
    for f in s.pv.index(idf.fixed):
        if norms[f] < 1e-6 * np.median(norms):   # no effect at all
            continue
        sv_f = np.linalg.svd(Jref[:, keep + [f]] / scale[keep + [f]], compute_uv=False)
        assert sv_f[-1] < 1e-6 * sv_f[0], s.pv.names[f]
    # the classic couplings are among them, in words
    assert any(c.startswith("frame.x cannot be separated") and "leg1.base.x" in c for c in idf.combinations)


def test_noisy_chain_fit_within_three_sigma():
    s = Setup("symmetric_3rrr", 5)
    fixed = identify(s.data(s.measure(s.pv.nominal)), s.pv).identifiability.fixed
    true = true_parameters(s.pv, seed=6, fixed=fixed)
    ident = identify(s.data(s.measure(true, noise=SIG, seed=7)), s.pv)
    free = s.pv.index(ident.identifiability.identified)
    zn = (ident.values - true)[free] / ident.sigma[free]
    assert np.all(np.isfinite(zn)) and np.max(np.abs(zn)) < 4.0


@pytest.mark.slow
@pytest.mark.parametrize("preset", ["symmetric_3rrr", "symmetric_3prr"])
def test_chain_sigmas_honest_over_seeds(preset):
    """Over 20 seeds (parameter errors, camera noise) on a random chain robot: the normalized errors of the
    identifiable parameters have unit spread within 20 % and 99 % lie within 3."""
    s = Setup(preset, 11)
    fixed = identify(s.data(s.measure(s.pv.nominal)), s.pv).identifiability.fixed
    zs = []
    for seed in range(20):
        true = true_parameters(s.pv, seed=100 + seed, fixed=fixed)
        ident = identify(s.data(s.measure(true, noise=SIG, seed=seed)), s.pv, robust=False)
        free = s.pv.index(ident.identifiability.identified)
        zs.append((ident.values - true)[free] / ident.sigma[free])
    z = np.concatenate(zs)
    assert abs(z.std() - 1.0) < 0.2, z.std()
    assert np.mean(np.abs(z) <= 3.0) >= 0.99 and np.max(np.abs(z)) < 4.5
