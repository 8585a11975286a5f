"""Spatial loads (issue 37): statics, loaded error and preload against the independent reference
(tests/reference/spatial_load_reference.py: member forces from the joints' physics, actuator efforts by virtual
work with finite differences of the inverse kinematics, the loaded error from the nonlinear chains), on every
spatial preset at its home pose and random poses."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import spatial_error_reference as eref
import spatial_load_reference as lref
import spatial_reference as ref

from pmaccuracy.accuracy import spatial_loads as sl
from pmaccuracy.accuracy.spatial_loads import SpatialLoad, spatial_design_preload, spatial_loaded_error, \
    spatial_statics
from pmaccuracy.errors import ConfigError, OutsideJointLimitsError, SingularPoseError
from pmaccuracy.model.spatial import SpatialManipulator
from pmaccuracy.numerics.spatial import rotvecs

DATA = Path(__file__).resolve().parents[2] / "src" / "pmaccuracy" / "data"
PRESETS = [("stewart_6ups", "ups_typical"), ("delta_clavel", "delta_typical"), ("rps_3", "rps_typical"),
           ("prs_3", "prs_typical"), ("upu_3", "upu_typical")]


def _case(name, clearances, seed):
    """The preset as the reference reads it, its clearances, a pose (home for seed 0, else random) and a random
    load (force, moment, a payload off-centre, gravity slightly off -z)."""
    robot = ref.load(DATA / "robots" / f"{name}.toml")
    cl = ref.load(DATA / "spatial_clearances" / f"{clearances}.toml")
    p, R = eref.nominal_pose(robot) if seed == 0 else ref.random_pose(robot, seed)
    rng = np.random.default_rng(seed + 100)
    load = SpatialLoad(force=tuple(rng.uniform(-50, 50, 3)), moment=tuple(rng.uniform(-3000, 3000, 3)),
                       mass=float(rng.uniform(0.5, 3)), com=tuple(rng.uniform(-20, 20, 3)),
                       gravity=(0.1, -0.05, -1.0))
    F = lref.load_wrench(load.force, load.moment, load.mass, load.com, load.gravity, R)
    return SpatialManipulator.preset(name), robot, cl, p, R, np.concatenate([p, rotvecs(R)]), load, F


@pytest.mark.parametrize("name,clearances", PRESETS)
def test_statics_against_member_forces_and_virtual_work(name, clearances):
    for seed in (0, 1, 2):
        robot, rdict, _, p, R, pose, load, F = _case(name, clearances, seed)
        st = spatial_statics(robot, pose, load)
        assert np.allclose(st.wrench, F, rtol=0, atol=1e-9 * np.abs(F).max())
        lam = lref.member_forces(rdict, p, R, F)
        assert np.max(np.abs(st.intensity - lam)) <= 1e-9 * np.max(np.abs(lam)), (name, seed)
        tau = lref.actuator_efforts(rdict, p, R, F)
        assert np.max(np.abs(st.actuator - tau)) <= 1e-9 * np.max(np.abs(tau)), (name, seed, st.actuator, tau)
        # equilibrium: the legs' wrenches balance the load
        assert np.max(np.abs(st.leg_wrench.sum(axis=0) + F)) <= 1e-10 * np.max(np.abs(F))


@pytest.mark.parametrize("name,clearances", PRESETS)
def test_joints_transmit_no_moment_about_their_free_axes(name, clearances):
    """A ball transmits no moment about its centre; a revolute none about its axis; a 6-UPS/3-UPU leg's force
    passes through its base joint's centre along the leg; the reactions are the legs' wrenches moved."""
    robot, rdict, _, p, R, pose, load, F = _case(name, clearances, 1)
    st = spatial_statics(robot, pose, load)
    scale = np.max(np.abs(st.reactions[..., :3])) * robot.characteristic_length
    legs = ref.legs(rdict)
    for i, leg in enumerate(legs):
        m = st.reactions[i, :, 3:]
        if name == "delta_clavel":
            assert np.all(np.abs(m[1:]) <= 1e-10 * scale)                       # the four balls
            assert abs(m[0] @ leg["axis"] - st.actuator[i]) <= 1e-9 * scale      # the arm: the motor's torque
        elif name == "upu_3":       # each universal joint: no moment about either of its axes
            u1 = leg["base_axis"]
            u2 = np.cross(u1, p + R @ leg["platform"] - leg["base"])
            u2 /= np.linalg.norm(u2)
            for k, axes in ((0, (u1, u2)), (2, (u2, R @ leg["platform_axis"]))):
                assert all(abs(m[k] @ a) <= 1e-10 * scale for a in axes)
        else:
            assert np.all(np.abs(m[-1]) <= 1e-10 * scale)                        # the platform's ball
            if name in ("rps_3", "prs_3"):
                assert abs(m[1 if name == "prs_3" else 0] @ leg["axis"]) <= 1e-10 * scale
        # every reaction is the leg's wrench about P moved to the joint's centre: the same force
        assert np.allclose(st.reactions[i, :, :3] if name != "delta_clavel" else st.reactions[i, :1, :3],
                           st.leg_wrench[i, :3], atol=1e-12 * scale)


def test_statics_is_vectorized_over_poses():
    robot = SpatialManipulator.preset("rps_3")
    rdict = ref.load(DATA / "robots" / "rps_3.toml")
    poses = np.array([np.concatenate([p, rotvecs(R)]) for p, R in (ref.random_pose(rdict, s) for s in (4, 5, 6))])
    load = SpatialLoad(force=(5.0, 1.0, -20.0), mass=1.0, com=(0.0, 10.0, 5.0))
    batch = spatial_statics(robot, poses.reshape(3, 1, 6), load)
    assert batch.intensity.shape == (3, 1, 6) and batch.reactions.shape == (3, 1, 3, 3, 6)
    for k in range(3):
        one = spatial_statics(robot, poses[k], load)
        assert np.allclose(batch.intensity[k, 0], one.intensity, rtol=1e-13, atol=1e-12)
        assert np.allclose(batch.reactions[k, 0], one.reactions, rtol=1e-13, atol=1e-9)


@pytest.mark.parametrize("name,clearances", PRESETS)
def test_loaded_error_against_the_nonlinear_chains(name, clearances):
    """First order against the reference's sensitivities; the nonlinear chains with those clearance states
    within O(c^2) (their difference shrinks 4x when the clearances halve); no sampled clearance state does
    more virtual work (beyond O(c^2))."""
    robot, rdict, cl, p, R, pose, load, F = _case(name, clearances, 2)
    ours = spatial_loaded_error(robot, clearances, pose, load)
    dX, s, sources = lref.loaded_first_order(rdict, cl, p, R, F)
    assert np.max(np.abs(ours.error - dX)) <= 1e-6 * np.max(np.abs(dX)), (ours.error, dX)
    assert not np.any(ours.spread)
    nl = lref.loaded_nonlinear(rdict, cl, p, R, s)
    gap = np.max(np.abs(nl - dX))
    assert gap <= 3e-3 * np.max(np.abs(dX))
    nl_half = lref.loaded_nonlinear(rdict, cl, p, R, s / 2)
    assert np.max(np.abs(nl_half - dX / 2)) <= gap / 4 * 1.2 + 1e-14
    work = F @ nl
    for state in lref.random_clearance_states(sources, 6, seed=3):
        assert F @ lref.loaded_nonlinear(rdict, cl, p, R, state) <= work + 2 * abs(F) @ np.abs(nl - dX) + 1e-12


def test_tolerances_are_not_moved_by_the_load():
    robot, rdict, cl, p, R, pose, load, F = _case("rps_3", "rps_typical", 1)
    ours = spatial_loaded_error(robot, "rps_typical", pose, load)
    M, sources = eref.sensitivity(rdict, cl, p, R)
    fixed = [src for src in sources if src["key"] not in lref.CLEARANCE_KEYS]
    assert fixed
    support = sum(src["half_width"] * np.linalg.norm(M[:, src["columns"]], axis=1) for src in fixed)
    assert np.allclose(ours.tolerance, support, rtol=1e-6, atol=1e-12)


def test_undetermined_sources_are_reported_not_invented():
    """A load that leaves a 6-UPS leg unloaded (lambda_1 = 0): its clearances are undetermined; the error holds
    the other legs' vertex and the spread is leg 1's support, both from the reference."""
    robot, rdict, cl, p, R, pose, _, _ = _case("stewart_6ups", "ups_typical", 1)
    W = lref.member_wrenches(rdict, p, R)
    F = -W @ np.array([0.0, 30.0, -20.0, 10.0, 25.0, -5.0])
    load = SpatialLoad(force=tuple(F[:3]), moment=tuple(F[3:]))
    ours = spatial_loaded_error(robot, "ups_typical", pose, load)
    M, sources = eref.sensitivity(rdict, cl, p, R)
    leg1 = [src for src in sources if src["leg"] == 0 and src["key"] in lref.CLEARANCE_KEYS]
    spread = sum(src["half_width"] * np.linalg.norm(M[:, src["columns"]], axis=1) for src in leg1)
    assert np.allclose(ours.spread, spread, rtol=1e-6, atol=1e-12)
    dX, _, _ = lref.loaded_first_order(rdict, cl, p, R, F)     # leg 1's reaction ~ 0: its sources ~ random there
    others = sum(M[:, src["columns"]] @ (src["half_width"] * _unit(M[:, src["columns"]].T @ F))
                 for src in sources if src["leg"] != 0 and src["key"] in lref.CLEARANCE_KEYS)
    assert np.max(np.abs(ours.error - others)) <= 1e-6 * np.max(np.abs(others))
    labels = [k for k, v in ours.undetermined.items() if v]
    assert labels and all(k.startswith("legs[1].") for k in labels)
    assert all(not np.any(ours.points[k]) for k in labels)


def _unit(v):
    n = np.linalg.norm(v)
    return v / n if n > 0 else 0 * v


@pytest.mark.parametrize("name,clearances", PRESETS)
def test_preload_holds_every_row_sign_over_the_box(name, clearances):
    robot, rdict, _, p, R, pose, _, _ = _case(name, clearances, 0)
    center = np.array([0.0, 0.0, -20.0, 0.0, 0.0, 0.0])
    half = np.array([10.0, 10.0, 10.0, 500.0, 500.0, 500.0])
    pre = spatial_design_preload(robot, clearances, pose, center, half, margin=1.0)
    rng = np.random.default_rng(7)
    samples = np.vstack([center + sl._PATTERNS * half, center + rng.uniform(-1, 1, (40, 6)) * half])
    lam = np.array([lref.member_forces(rdict, p, R, pre.wrench + w) for w in samples])
    assert np.all(lam * pre.pattern >= 1.0 - 1e-6), (name, pre.pattern)
    # smallest: with a free preload 0.99 x is not enough (the LP's optimum is on a corner of the box)
    small = np.array([lref.member_forces(rdict, p, R, 0.99 * pre.wrench + w) for w in center + sl._PATTERNS * half])
    assert not np.all(small * pre.pattern >= 1.0 - 1e-9)
    # along a direction (the free preload's): the smallest multiple, at most the free one, and 0.999 of it
    # leaves some row unheld
    d = pre.wrench / np.linalg.norm(pre.wrench)
    along = spatial_design_preload(robot, clearances, pose, center, half, margin=1.0, direction=d)
    assert np.allclose(along.wrench / along.size, d)
    assert along.size <= np.linalg.norm(pre.wrench) * (1 + 1e-9)
    lam = np.array([lref.member_forces(rdict, p, R, along.wrench + w) for w in samples])
    assert np.all(lam * along.pattern >= 1.0 - 1e-6)
    corners = center + sl._PATTERNS * half
    short = np.array([lref.member_forces(rdict, p, R, 0.999 * along.wrench + w) for w in corners])
    one_signed = np.all(short >= 1.0 - 1e-9, axis=0) | np.all(short <= -1.0 + 1e-9, axis=0)
    assert not np.all(one_signed)


def test_preload_on_a_hexapod_makes_the_loaded_error_a_constant_offset():
    """Every 6-UPS clearance acts through its leg's axial force: once the rows' signs are held the loaded error
    is the same vertex for every wrench of the box."""
    robot, _, _, _, _, pose, _, _ = _case("stewart_6ups", "ups_typical", 0)
    center, half = np.zeros(6), np.array([20.0, 20.0, 20.0, 1000.0, 1000.0, 1000.0])
    pre = spatial_design_preload(robot, "ups_typical", pose, center, half)
    assert all(pre.held.values()) and max(pre.max_angle_deg.values()) <= 1e-6   # rank one: rounding only
    rng = np.random.default_rng(8)
    for w in center + rng.uniform(-1, 1, (10, 6)) * half:
        w = w + pre.wrench
        err = spatial_loaded_error(robot, "ups_typical", pose, SpatialLoad(force=tuple(w[:3]), moment=tuple(w[3:])))
        assert np.allclose(err.error, pre.offset, rtol=1e-12, atol=1e-15)
    assert np.all(np.abs(pre.offset) <= pre.worst * (1 + 1e-12))


def _singular_hexapod():
    d = SpatialManipulator.preset("stewart_6ups").to_dict()
    for leg in d["legs"]:
        leg["stroke"] = [1.0, 5000.0]
        for key in ("base_cone_deg", "platform_cone_deg", "radius"):
            leg.pop(key, None)
    return SpatialManipulator.from_dict(d)


def test_bad_input_is_refused_with_the_package_errors():
    robot = SpatialManipulator.preset("stewart_6ups")
    home = robot.home_pose
    with pytest.raises(ConfigError) as exc:
        SpatialLoad(mass=-1.0)
    assert exc.value.key == "mass"
    with pytest.raises(ConfigError) as exc:
        SpatialLoad(force=(math.nan, 0.0, 0.0))
    assert exc.value.key == "force"
    with pytest.raises(ConfigError):
        SpatialLoad(gravity=(0.0, 0.0, 0.0))
    with pytest.raises(ConfigError):
        spatial_statics(robot, home, object())
    with pytest.raises(OutsideJointLimitsError):
        spatial_statics(robot, [0, 0, 900, 0, 0, 0], SpatialLoad(force=(0.0, 0.0, -1.0)))
    with pytest.raises(SingularPoseError):
        spatial_loaded_error(_singular_hexapod(), "ups_typical", [0, 0, 400, 0, 0, np.pi / 2],
                             SpatialLoad(force=(0.0, 0.0, -1.0)))
    with pytest.raises(ConfigError) as exc:
        spatial_loaded_error(robot, "ups_typical", home, SpatialLoad(force=(0.0, 0.0, -1.0)), threshold=-1.0)
    assert exc.value.key == "threshold"
    with pytest.raises(ConfigError):
        spatial_loaded_error(robot, "delta_typical", home, SpatialLoad(force=(0.0, 0.0, -1.0)))
    with pytest.raises(ConfigError) as exc:
        spatial_design_preload(robot, "ups_typical", home, np.zeros(6), np.zeros(6))
    with pytest.raises(ConfigError):
        spatial_design_preload(robot, "ups_typical", home, np.zeros(6), [1, 1, 1, 1, 1, -1])
    with pytest.raises(ConfigError) as exc:
        spatial_design_preload(robot, "ups_typical", home, np.zeros(6), np.ones(6), direction=[np.nan] * 6)
    assert exc.value.key == "direction"


@pytest.mark.parametrize("arch", ["6-UPS", "delta", "3-RPS", "3-PRS", "3-UPU"])
def test_random_robots_every_key(arch):
    """Random robots with every applicable key of every joint (reference generators): intensities, efforts,
    the loaded error and the tolerances' worst case against the reference."""
    rdict = ref.random_robot(arch, 21)
    cl = eref.random_clearances(rdict, 21)
    p, R = ref.random_pose(rdict, 21)
    robot = SpatialManipulator.from_dict(rdict, source="r.toml")
    from pmaccuracy.model.spatial_sources import SpatialErrorSources

    sources = SpatialErrorSources.from_dict(cl, robot, source="c.toml")
    load = SpatialLoad(force=(12.0, -7.0, -40.0), moment=(900.0, -400.0, 250.0), mass=1.5, com=(3.0, -4.0, 20.0))
    F = lref.load_wrench(load.force, load.moment, load.mass, load.com, load.gravity, R)
    pose = np.concatenate([p, rotvecs(R)])
    ours = spatial_loaded_error(robot, sources, pose, load)
    lam = lref.member_forces(rdict, p, R, F)
    assert np.max(np.abs(ours.statics.intensity - lam)) <= 1e-9 * np.max(np.abs(lam))
    tau = lref.actuator_efforts(rdict, p, R, F)
    assert np.max(np.abs(ours.statics.actuator - tau)) <= 1e-9 * np.max(np.abs(tau))
    dX, s, src = lref.loaded_first_order(rdict, cl, p, R, F)
    assert np.max(np.abs(ours.error - dX)) <= 1e-6 * np.max(np.abs(dX))
    M, _ = eref.sensitivity(rdict, cl, p, R)
    fixed = [x for x in src if x["key"] not in lref.CLEARANCE_KEYS]
    support = sum(x["half_width"] * np.linalg.norm(M[:, x["columns"]], axis=1) for x in fixed)
    assert np.allclose(ours.tolerance, support, rtol=1e-6, atol=1e-12)
