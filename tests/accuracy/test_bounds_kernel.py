"""The lean evaluation behind bounds and maps (issue 9, speed) against the slower, direct forms.

* ``Chain.state`` (one IK branch, joint directions from the solution's vectors) equals ``Chain.state_at``
  (the chain's frames built from ``exp(i angle)`` of its joint values) and the branch with
  ``sign(B_ii) = working_mode`` among ``Chain.ik_branches``, on random robots of every leg type;
* the kernel's maxima (columns of ``A^-1`` as cross products of rows) equal the zonotope support functions
  and vertex norms of ``np.linalg.inv(A)``;
* poses sharing one orientation (a map layer: scalar rotation, constant rows) give the same numbers as
  the same poses evaluated among others.
"""

from __future__ import annotations

import numpy as np
import pytest

import planar_reference as ref
from pmaccuracy.accuracy.bounds import bounds_kernel, bounds_or_nan, max_pose_errors
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.kinematics import inverse_kinematics
from pmaccuracy.model.sources import ErrorSources
from pmaccuracy.io.resolve import load_clearances

GENERATORS = {"3-RPR": ref.random_rpr, "3-RRR": ref.random_rrr, "3-PRR": ref.random_prr, "chain": ref.random_chain}
PRESETS = [("aalborg_3ppr", "all"), ("symmetric_3rpr", "rpr_typical"), ("symmetric_3rrr", "rrr_typical"),
           ("symmetric_3prr", "prr_typical")]


def _wrapped(a):
    return np.angle(np.exp(1j * a))


@pytest.mark.parametrize("kind", sorted(GENERATORS))
def test_state_equals_frames_and_the_working_branch(kind):
    rng = np.random.default_rng(7)
    for _ in range(5):
        data, nominal = GENERATORS[kind](rng)
        robot = Manipulator.from_dict(data, source="random")
        poses = nominal + np.column_stack([rng.uniform(-15, 15, (200, 2)), rng.uniform(-0.2, 0.2, 200)])
        for chain in robot.chains:
            st = chain.state(poses)
            ok = np.isfinite(st.q).all(-1)
            ref_st = chain.state_at(np.where(ok[:, None], st.q, 0.0), poses)
            for a, b in zip(st.centres, ref_st.centres):
                np.testing.assert_allclose(np.broadcast_to(a, ok.shape)[ok], b[ok], atol=1e-8)
            for a, b in zip(st.dirs, ref_st.dirs):
                np.testing.assert_allclose(np.broadcast_to(a, ok.shape)[ok], b[ok], atol=1e-10)
            np.testing.assert_allclose(st.A_row[ok], ref_st.A_row[ok], atol=1e-8)
            np.testing.assert_allclose(np.broadcast_to(st.B, ok.shape)[ok], ref_st.B[ok], atol=1e-8)
            # the branch: one of the two IK solutions, the one whose B_ii has the working mode's sign
            branches = chain.ik_branches(poses)
            match = [np.all(np.abs(_wrapped(branches[:, b, :] - st.q)) < 1e-7, axis=-1) for b in (0, 1)]
            assert np.all((match[0] | match[1])[ok])
            B = np.broadcast_to(st.B, ok.shape)
            assert np.all(np.sign(B[ok & (np.abs(B) > 1e-9)]) == chain.working_mode)


@pytest.mark.parametrize("name,clear", PRESETS)
def test_kernel_equals_the_zonotope_of_the_inverse(name, clear):
    robot = Manipulator.preset(name)
    sources = load_clearances(clear, robot)
    sources = sources if isinstance(sources, ErrorSources) else ErrorSources.from_clearance_set(sources)
    rng = np.random.default_rng(3)
    poses = np.column_stack([rng.uniform(-10, 10, (100, 2)), rng.uniform(-0.1, 0.1, 100)])
    block = bounds_kernel(robot, sources, poses, details=True)
    A_inv = np.linalg.inv(inverse_kinematics(robot, poses).A)
    G = A_inv * block.details["c"][:, None, :]
    np.testing.assert_allclose(block.dx, np.abs(G[:, 0]).sum(-1), rtol=1e-9)
    np.testing.assert_allclose(block.dy, np.abs(G[:, 1]).sum(-1), rtol=1e-9)
    np.testing.assert_allclose(block.dphi, np.abs(G[:, 2]).sum(-1), rtol=1e-9)
    signs = np.array([[a, b, c] for a in (1, -1) for b in (1, -1) for c in (1, -1)], dtype=float)
    vertices = np.einsum("nij,vj->nvi", G[:, :2], signs)
    np.testing.assert_allclose(block.dp, np.linalg.norm(vertices, axis=-1).max(-1), rtol=1e-9)


@pytest.mark.parametrize("name,clear", PRESETS)
def test_one_orientation_equals_mixed_orientations(name, clear):
    robot = Manipulator.preset(name)
    sources = load_clearances(clear, robot)
    rng = np.random.default_rng(5)
    layer = np.column_stack([rng.uniform(-12, 12, (64, 2)), np.full(64, 0.05)])
    mixed = np.concatenate([layer, layer + [0.0, 0.0, 0.02]])[rng.permutation(128)]
    one = bounds_or_nan(robot, sources, layer)
    many = bounds_or_nan(robot, sources, mixed)
    same = np.isclose(mixed[:, 2], 0.05)
    order = np.lexsort(layer[:, :2].T)
    order_m = np.lexsort(mixed[same][:, :2].T)
    np.testing.assert_allclose(one[order], many[same][order_m], rtol=1e-12, equal_nan=True)
    # and the maps' kernel equals the public bounds where the poses are regular and inside
    ok = np.isfinite(one[:, 3])
    if ok.any():
        b = max_pose_errors(robot, sources, layer[ok])
        np.testing.assert_allclose(one[ok, 3], b.dp_max, rtol=1e-12)
        np.testing.assert_allclose(one[ok, 2], b.dphi_max_deg, rtol=1e-12)
