"""Clearances under load (issue 24, deliverables 1-2): statics, joint reactions, loaded pose errors.

Independent references, written here from first principles and not from ``pmaccuracy.accuracy.loads``:
- actuator efforts from the principle of virtual work on the exact forward kinematics: ``tau = -J^T W`` with
  ``J = dX/dq`` by central differences of ``forward_kinematics``;
- each joint's reaction from virtual work on the exact loop closure (the virtual prototype
  ``joint_displaced_pose``): displacing joint ``k`` of leg ``i`` by a small translation ``h u`` moves the
  platform by ``dX``; the transmitted force's component along ``u`` is ``-W . dX / h`` (likewise a P joint's
  block shifted normal to its rail and tilted about its centre);
- the first-order loaded error is the support point of the error zonotope in the direction of ``W``:
  ``W . dX = sum_i |W . g_i|`` over its generators ``g_i`` (``max_pose_errors(details=True)``), and it attains
  the brute-force maximum of ``W . dX`` over the sign vertices of the error set.
"""

from __future__ import annotations

import itertools
import warnings

import numpy as np
import pytest

from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.accuracy.loads import Load, loaded_pose_error, statics
from pmaccuracy.accuracy.nonlinear import joint_displaced_pose
from pmaccuracy.errors import ConfigError, SingularPoseError
from pmaccuracy.io.resolve import load_clearances
from pmaccuracy.kinematics import forward_kinematics, inverse_kinematics, leg_states
from pmaccuracy.kinematics.workspace import constant_orientation_workspace
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.model.plausibility import PlausibilityWarning
from pmaccuracy.model.sources import ErrorSources, JointDisplacements, first_order_error, worst_configuration

ROBOTS = [("aalborg_3ppr", "case2"), ("symmetric_3rpr", "rpr_typical"), ("symmetric_3rrr", "rrr_typical"),
          ("symmetric_3prr", "prr_typical")]


def inner_poses(robot: Manipulator, n: int, seed: int) -> np.ndarray:
    """``n`` random poses well inside the phi = 5 deg workspace (its points pulled halfway to the centroid)."""
    rng = np.random.default_rng(seed)
    ws = constant_orientation_workspace(robot, np.radians(5.0))
    (x0, x1), (y0, y1) = ws.bounds
    pts = np.column_stack([rng.uniform(x0, x1, 50 * n), rng.uniform(y0, y1, 50 * n)])
    pts = pts[ws.contains(pts)][:n]
    pts = 0.5 * (pts + ws.vertices.mean(axis=0))       # convex workspace pieces: the midpoint stays inside
    pts = pts[ws.contains(pts)]
    assert len(pts) == n
    return np.column_stack([pts, np.full(n, np.radians(5.0))])


def random_load(seed: int) -> Load:
    rng = np.random.default_rng(seed)
    return Load(fx=rng.normal(0, 10), fy=rng.normal(0, 10), m=rng.normal(0, 300))


@pytest.mark.parametrize("name, clear", ROBOTS)
def test_actuator_efforts_by_virtual_work_on_the_exact_forward_kinematics(name, clear):
    robot = Manipulator.preset(name)
    poses = inner_poses(robot, 3, 1)
    load = random_load(2)
    st = statics(robot, poses, load)
    ik = inverse_kinematics(robot, poses)
    q = np.take_along_axis(ik.joints, ik.actuated_index[None, :, None], axis=-1)[..., 0]
    h = 1e-6
    J = np.empty(poses.shape[:1] + (3, 3))
    for i in range(3):
        dq = np.zeros(3)
        dq[i] = h
        plus = forward_kinematics(robot, q + dq).nearest(poses)
        minus = forward_kinematics(robot, q - dq).nearest(poses)
        J[:, :, i] = (plus - minus) / (2 * h)
    W = load.wrench(poses)
    tau = -np.einsum("nji,nj->ni", J, W)
    np.testing.assert_allclose(st.actuator, tau, rtol=1e-6, atol=1e-9 * np.abs(tau).max())


def _one_joint(shape, i: int, k: int, **values) -> JointDisplacements:
    z = JointDisplacements.zeros(shape)
    for field, v in values.items():
        getattr(z, field)[..., i, k] = v
    return z


@pytest.mark.parametrize("name, clear", ROBOTS)
def test_joint_reactions_by_virtual_work_on_the_exact_loop_closure(name, clear):
    robot = Manipulator.preset(name)
    poses = inner_poses(robot, 2, 3)
    load = random_load(4)
    st = statics(robot, poses, load)
    W = load.wrench(poses)
    h = 1e-5

    def work(config_plus, config_minus) -> np.ndarray:
        dX = joint_displaced_pose(robot, poses, config_plus) - joint_displaced_pose(robot, poses, config_minus)
        dX[:, 2] = np.angle(np.exp(1j * dX[:, 2]))
        return -np.sum(W * dX, axis=-1) / (2 * h)

    scale = np.abs(st.intensity).max()
    for i, chain in enumerate(robot.chains):
        for k, joint in enumerate(chain.joints):
            fx = work(_one_joint((2,), i, k, shift=h), _one_joint((2,), i, k, shift=-h))
            fy = work(_one_joint((2,), i, k, shift=1j * h), _one_joint((2,), i, k, shift=-1j * h))
            np.testing.assert_allclose(fx + 1j * fy, st.force[:, i, k], rtol=1e-6, atol=1e-6 * scale)
            if joint.kind == "P":
                n = work(_one_joint((2,), i, k, sigma=h), _one_joint((2,), i, k, sigma=-h))
                m = work(_one_joint((2,), i, k, tilt=h), _one_joint((2,), i, k, tilt=-h))
                np.testing.assert_allclose(n, st.normal[:, i, k], rtol=1e-6, atol=1e-6 * scale)
                np.testing.assert_allclose(m, st.moment[:, i, k], rtol=1e-6, atol=1e-4 * scale)


@pytest.mark.parametrize("name, clear", ROBOTS)
@pytest.mark.parametrize("seed", [0, 1])
def test_loaded_error_is_the_support_point_of_the_error_set_in_the_direction_of_the_load(name, clear, seed):
    robot = Manipulator.preset(name)
    poses = inner_poses(robot, 4, 10 + seed)
    load = random_load(20 + seed)
    res = loaded_pose_error(robot, clear, poses, load, exact=False)
    W = load.wrench(poses)
    b = max_pose_errors(robot, clear, poses, details=True)
    support = np.sum(np.abs(np.einsum("ni,nij->nj", W, b.generators)), axis=-1)
    np.testing.assert_allclose(np.sum(W * res.first_order, axis=-1), support, rtol=1e-10)
    # brute force over the sign vertices of the legs (each source at its extreme of that leg's sign)
    sources = load_clearances(clear, robot)
    sources = sources if isinstance(sources, ErrorSources) else ErrorSources.from_clearance_set(sources)
    joints = inverse_kinematics(robot, poses).joints
    best = np.full(len(poses), -np.inf)
    for t in itertools.product((-1.0, 1.0), repeat=3):
        signs = np.broadcast_to(np.array(t), (len(poses), 3))
        e = first_order_error(robot, joints, poses, worst_configuration(robot, sources, joints, poses, signs))
        best = np.maximum(best, np.sum(W * e, axis=-1))
    np.testing.assert_allclose(np.sum(W * res.first_order, axis=-1), best, rtol=1e-10)


def test_exact_loaded_error_is_first_order_plus_a_second_order_remainder():
    robot = Manipulator.preset("symmetric_3rpr")
    poses = inner_poses(robot, 3, 5)
    load = random_load(6)
    clear = load_clearances("rpr_typical", robot)
    gaps = []
    for f in (1.0, 0.5):
        res = loaded_pose_error(robot, clear.scaled(f), poses, load)
        gaps.append(np.abs(res.exact - res.first_order).max())
    assert 3.0 < gaps[0] / gaps[1] < 5.0


def test_pushes_along_the_axes_reach_the_worst_cases():
    robot = Manipulator.preset("aalborg_3ppr")
    poses = inner_poses(robot, 3, 7)
    b = max_pose_errors(robot, "case2", poses)
    for load, row, top in ((Load(fx=5.0), 0, b.dx_max), (Load(fy=-5.0), 1, -b.dy_max), (Load(m=50.0), 2, b.dphi_max)):
        res = loaded_pose_error(robot, "case2", poses, load, exact=False)
        np.testing.assert_allclose(res.first_order[:, row], top, rtol=1e-10)


def test_an_unloaded_leg_leaves_its_generator_as_a_range():
    robot = Manipulator.preset("symmetric_3rpr")
    pose = np.array([[2.0, -1.0, np.radians(3.0)]])
    A = np.stack([np.broadcast_to(st.A_row, (1, 3)) for st in leg_states(robot, pose)], axis=-2)[0]
    lam = np.array([0.0, 2.0, -3.0])           # leg 1 carries nothing
    W = -A.T @ lam
    res = loaded_pose_error(robot, "rpr_typical", pose, Load(fx=W[0], fy=W[1], m=W[2]), threshold=1e-9,
                            exact=False)
    assert res.unloaded[0].tolist() == [True, False, False] and res.signs[0, 0] == 0
    b = max_pose_errors(robot, "rpr_typical", pose, details=True)
    np.testing.assert_allclose(res.spread[0], np.abs(b.generators[0][:, 0]), rtol=1e-12)


def test_weight_is_a_force_at_the_centre_of_mass():
    load = Load(mass=2.0, com=(10.0, 5.0), gravity_deg=-90.0)
    phi = np.radians(30.0)
    W = load.wrench(np.array([1.0, 2.0, phi]))
    weight = np.array([0.0, -2.0 * 9.80665])
    arm = np.array([[np.cos(phi), -np.sin(phi)], [np.sin(phi), np.cos(phi)]]) @ np.array([10.0, 5.0])
    np.testing.assert_allclose(W, [weight[0], weight[1], arm[0] * weight[1] - arm[1] * weight[0]], rtol=1e-12, atol=1e-12)


def test_bad_loads_and_poses_are_refused():
    with pytest.raises(ConfigError, match="mass"):
        Load(mass=-1.0)
    with pytest.raises(ConfigError, match="finite"):
        Load(fx=float("nan"))
    with pytest.raises(SingularPoseError):
        statics("symmetric_3rrr", [0.0, 126.80403, 0.0], Load(fx=1.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error", PlausibilityWarning)
        with pytest.raises(PlausibilityWarning, match="kN"):
            Load(fx=2e6).check()


def test_cli_load_matches_the_library_and_refuses_a_zero_load(capsys):
    import json

    from pmaccuracy.cli import main

    assert main(["load", "--robot", "symmetric_3rpr", "--clearances", "rpr_typical", "--pose", "2", "-1", "3",
                 "--fx", "4", "--m", "-20", "--details", "--format", "json"]) == 0
    rec = json.loads(capsys.readouterr().out)[0]
    res = loaded_pose_error("symmetric_3rpr", "rpr_typical", [2.0, -1.0, np.radians(3.0)], Load(fx=4.0, m=-20.0))
    assert rec["dx"] == pytest.approx(float(res.first_order[0]), rel=1e-12)
    assert rec["leg1.actuator_N"] == pytest.approx(float(res.statics.actuator[0]), rel=1e-12)
    assert main(["load", "--pose", "0", "0", "0"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "zero" in err


def test_virtual_rig_pushes_as_loads_reach_the_support_points_of_the_error_set():
    """experiment simulate --push-n: each push's first-order reading is the support point of the error set in
    the push's direction (sum of |W . g_i| over the generators), and a push whose legs are all loaded gives the
    worst-case push of that direction."""
    from pmaccuracy.experiment.measurements import PUSHES
    from pmaccuracy.experiment.virtual_rig import push_loads, simulate_readings

    robot = Manipulator.preset("aalborg_3ppr")
    poses = inner_poses(robot, 3, 8)
    loaded = simulate_readings(robot, "case2", poses, noise_mm=0.0, noise_deg=0.0, model="first_order", push_n=10.0)
    plain = simulate_readings(robot, "case2", poses, noise_mm=0.0, noise_deg=0.0, model="first_order")
    b = max_pose_errors(robot, "case2", poses, details=True)
    for k, (push, load) in enumerate(zip(PUSHES, push_loads(robot, 10.0))):
        W = load.wrench(poses)
        d = loaded.readings[:, k] - poses
        support = np.sum(np.abs(np.einsum("ni,nij->nj", W, b.generators)), axis=-1)
        np.testing.assert_allclose(np.sum(W * d, axis=-1), support, rtol=1e-9)
        if push in ("+x", "-x"):                   # every leg loaded by a push along x
            np.testing.assert_allclose(loaded.readings[:, k], plain.readings[:, k], rtol=0, atol=1e-12)


@pytest.mark.parametrize("name, clear", ROBOTS)
def test_wrench_set_range_and_flips_against_a_dense_sample_of_the_box(name, clear):
    from pmaccuracy.accuracy.loads import wrench_set_errors

    robot = Manipulator.preset(name)
    poses = inner_poses(robot, 2, 30)
    center, half = np.array([2.0, -3.0, 40.0]), np.array([4.0, 4.0, 150.0])
    res = wrench_set_errors(robot, clear, poses, center, half)
    grid = np.linspace(-1.0, 1.0, 7)
    sample = np.array(np.meshgrid(grid, grid, grid)).reshape(3, -1).T * half + center
    seen = np.zeros((len(poses), 3))
    lo, hi = np.full((len(poses), 3), np.inf), np.full((len(poses), 3), -np.inf)
    sides = [set() for _ in poses]
    for W in sample:
        r = loaded_pose_error(robot, clear, poses, Load(fx=W[0], fy=W[1], m=W[2]), exact=False)
        lo, hi = np.minimum(lo, r.first_order), np.maximum(hi, r.first_order)
        for n in range(len(poses)):
            sides[n].add(tuple(r.signs[n]))
    tol = 1e-12 + 1e-9 * np.abs(hi)
    assert np.all(res.lower <= lo + tol) and np.all(hi <= res.upper + tol)
    for n in range(len(poses)):
        flipped = [len({s[i] for s in sides[n]}) > 1 for i in range(3)]
        assert all(res.flips[n][i] or not flipped[i] for i in range(3)), (n, flipped, res.flips[n])


@pytest.mark.parametrize("name, clear", ROBOTS)
def test_designed_preload_holds_every_contact_and_two_percent_less_flips_one(name, clear):
    from pmaccuracy.accuracy.loads import design_preload

    robot = Manipulator.preset(name)
    pose = inner_poses(robot, 1, 40)[0]
    center, half = np.array([0.0, 0.0, 0.0]), np.array([5.0, 5.0, 100.0])
    pre = design_preload(robot, clear, pose, center, half)
    grid = np.linspace(-1.0, 1.0, 5)
    sample = np.array(np.meshgrid(grid, grid, grid)).reshape(3, -1).T * half + center

    def signs(P):
        return np.array([np.sign(statics(robot, pose, Load(fx=P[0] + W[0], fy=P[1] + W[1], m=P[2] + W[2]))
                                 .intensity) for W in sample])

    held = signs(pre.wrench)
    assert np.all(held == pre.pattern)
    assert np.any(signs(0.98 * pre.wrench) != pre.pattern)
    b = max_pose_errors(robot, clear, pose[None])
    assert np.all(np.abs(pre.offset) <= np.array([b.dx_max[0], b.dy_max[0], b.dphi_max[0]]) * (1 + 1e-9))


def test_cli_preload_matches_the_library_and_checks_its_box(capsys):
    import json

    from pmaccuracy.accuracy.loads import design_preload, wrench_set_errors
    from pmaccuracy.cli import main

    assert main(["preload", "--robot", "symmetric_3rpr", "--clearances", "rpr_typical", "--pose", "1", "2", "3",
                 "--fx", "-4", "6", "--m", "-50", "50", "--format", "json"]) == 0
    rec = json.loads(capsys.readouterr().out)[0]
    pose = np.array([1.0, 2.0, np.radians(3.0)])
    center, half = np.array([1.0, 0.0, 0.0]), np.array([5.0, 0.0, 50.0])
    pre = design_preload("symmetric_3rpr", "rpr_typical", pose, center, half)
    rng = wrench_set_errors("symmetric_3rpr", "rpr_typical", pose[None], center, half)
    assert rec["preload_size_N"] == pytest.approx(pre.size, rel=1e-9)
    assert rec["dx_range"] == pytest.approx(float(rng.upper[0, 0] - rng.lower[0, 0]), rel=1e-9)
    for argv, key in ((["--fx", "5", "-5"], "--fx"), ([], "--fx")):
        assert main(["preload", "--pose", "0", "0", "0", *argv]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and key in err
