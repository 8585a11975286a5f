"""Every architecture against the independent reference ``planar_reference.py`` (issue 8's judging).

The reference was written separately from the library, from the chain convention
and the designer formats only (see its docstring): closed-form and numeric IK, an
orientation-scan forward kinematics, finite-difference Jacobians and exact
slice-integrated workspace areas. Here random 3-RPR, 3-RRR, 3-PRR and mixed-chain
robots are compared with the library: IK to 1e-6 mm, every FK assembly mode,
``B^-1 A`` against finite differences, workspace areas to 1e-6 relative.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

import planar_reference as ref
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.kinematics import forward_kinematics, inverse_kinematics, regular_mask
from pmaccuracy.kinematics.workspace import constant_orientation_workspace

GENERATORS = {"3-RPR": ref.random_rpr, "3-RRR": ref.random_rrr, "3-PRR": ref.random_prr, "chain": ref.random_chain}
N_ROBOTS = 6


def _robots(kind, seed):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(N_ROBOTS):
        data, nominal = GENERATORS[kind](rng)
        out.append((data, nominal, Manipulator.from_dict(data, source=f"random {kind}"), ref.load(data)))
    return out


def _poses_near(nominal, rng, n, spread=20.0, dphi=0.25):
    return nominal + np.column_stack([rng.uniform(-spread, spread, (n, 2)), rng.uniform(-dphi, dphi, n)])


def _same_angle(a, b, atol):
    return np.abs(np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b))))) <= atol


@pytest.mark.parametrize("kind", sorted(GENERATORS))
def test_inverse_kinematics_agrees(kind):
    rng = np.random.default_rng(1)
    for data, nominal, robot, reference in _robots(kind, 10 + len(kind)):
        poses = _poses_near(nominal, rng, 300)
        ik = inverse_kinematics(robot, poses)
        q_ref, passive_ref, within_ref = ref.inverse_kinematics(reference, poses)
        np.testing.assert_array_equal(ik.within_limits, within_ref)
        both = np.isfinite(q_ref).all(-1)
        np.testing.assert_array_equal(ik.reachable, both)
        kinds = robot.actuated_kinds
        for i in range(3):
            if kinds[i] == "R":
                assert np.all(_same_angle(ik.q[both, i], q_ref[both, i], 1e-9))
            else:
                np.testing.assert_allclose(ik.q[both, i], q_ref[both, i], atol=1e-6)
        for i, chain in enumerate(robot.chains):
            for m, k in enumerate(chain.passive_indices):
                got, want = ik.passive[both, i, m], passive_ref[both, i, m]
                if chain.joints[k].kind == "R":
                    assert np.all(_same_angle(got, want, 1e-9))
                else:
                    np.testing.assert_allclose(got, want, atol=1e-6)


@pytest.mark.parametrize("kind", sorted(GENERATORS))
def test_every_assembly_mode_is_found(kind):
    """FK modes = the reference's orientation scan (same set, poses to 1e-6 mm / 1e-8 rad)."""
    rng = np.random.default_rng(2)
    for data, nominal, robot, reference in _robots(kind, 20 + len(kind))[:4]:
        poses = _poses_near(nominal, rng, 3)
        poses = poses[inverse_kinematics(robot, poses).reachable]
        q = inverse_kinematics(robot, poses).q
        fk = forward_kinematics(robot, q)
        for k in range(len(poses)):
            want = ref.forward_kinematics_scan(reference, q[k], n_phi=3600)
            got = fk.poses[k, fk.valid[k]]
            assert len(got) == len(want), (kind, got, want)
            for pose in want:
                d = np.abs(got[:, :2] - pose[:2]).max(axis=1)
                a = np.abs(np.angle(np.exp(1j * (got[:, 2] - pose[2]))))
                assert np.any((d < 1e-6) & (a < 1e-8)), (pose, got)


def test_six_real_assembly_modes():
    data = tomllib.loads((Path(__file__).resolve().parents[1] / "data" / "rpr_six_modes.toml").read_text())
    example = data.pop("fk_example")
    robot = Manipulator.from_dict(data, source="rpr_six_modes.toml")
    fk = forward_kinematics(robot, example["lengths"])
    assert fk.valid.sum() == 6
    got = fk.poses[fk.valid]
    want = np.column_stack([example["x"], example["y"], np.radians(example["phi_deg"])])
    for pose in want:
        d = np.abs(got[:, :2] - pose[:2]).max(axis=1)
        a = np.abs(np.angle(np.exp(1j * (got[:, 2] - pose[2]))))
        assert np.any((d < 1e-6) & (a < 1e-8))
    assert np.all(fk.within_limits[fk.valid])
    # and each mode reproduces the lengths through the IK
    np.testing.assert_allclose(inverse_kinematics(robot, got).q, np.tile(example["lengths"], (6, 1)), atol=1e-9)


@pytest.mark.parametrize("kind", sorted(GENERATORS))
def test_jacobians_against_finite_differences(kind):
    """dq/dX = B^-1 A from the legs' wrenches equals central differences of the reference IK."""
    rng = np.random.default_rng(3)
    for data, nominal, robot, reference in _robots(kind, 30 + len(kind))[:4]:
        poses = _poses_near(nominal, rng, 20, spread=8.0, dphi=0.1)
        ik = inverse_kinematics(robot, poses)
        poses = poses[ik.within_limits & regular_mask(robot, poses)]
        ik = inverse_kinematics(robot, poses)
        fd = ref.jacobian_fd(reference, poses)
        mine = np.linalg.solve(ik.B, ik.A)
        scale = np.max(np.abs(fd), axis=(-2, -1), keepdims=True)
        np.testing.assert_allclose(mine, fd, atol=1e-6 * scale.max(), rtol=1e-6)


@pytest.mark.parametrize("kind", sorted(GENERATORS))
def test_workspace_area_against_slice_integration(kind):
    for data, nominal, robot, reference in _robots(kind, 40 + len(kind))[:4]:
        for phi in (nominal[2], nominal[2] + 0.2):
            ws = constant_orientation_workspace(robot, phi)
            want = ref.workspace_area_slices(reference, phi)
            assert ws.area == pytest.approx(want["area"], rel=1e-6, abs=1e-6)
            if want["area"] > 0:
                xmin, xmax, ymin, ymax = want["bbox"]
                np.testing.assert_allclose(np.ravel(ws.bounds), [xmin, xmax, ymin, ymax], atol=1e-6)


def test_workspace_area_against_monte_carlo_and_polygon_clipping():
    rng = np.random.default_rng(5)
    for kind in ("3-RPR", "3-RRR", "3-PRR"):
        data, nominal, robot, reference = _robots(kind, 50)[0]
        ws = constant_orientation_workspace(robot, nominal[2])
        mc = ref.workspace_area_mc(reference, nominal[2], n=100_000, rng=rng)
        assert abs(ws.area - mc["area"]) <= 4 * mc["stderr"] + 1e-9
        sh = ref.workspace_area_shapely(reference, nominal[2])
        assert abs(ws.area - sh["area"]) <= sh["bound"] + 1e-9
