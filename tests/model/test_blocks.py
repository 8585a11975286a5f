"""A P joint's clearances act about its block (issue 21): a carriage at ``c_k + q_k e_k`` or a bushing at ``c_k``.

Checked against :mod:`block_reference` (written without ``pmaccuracy``: each clearance a finite rigid
displacement of the distal part about the block's centre, the loops closed exactly, first-order maxima from
finite differences of that closure), on random robots of every architecture with P joints and random
blocks; and the invariance that motivated the change: the same physical robot written with each rail's
origin moved along the rail (its range shifted to match) gives the same numbers in every layer.
"""

from __future__ import annotations

import copy
import math
import warnings

import numpy as np
import pytest

import block_reference as bref
import planar_reference as pref
from pmaccuracy.accuracy import certified as C
from pmaccuracy.accuracy.bounds import max_pose_errors
from pmaccuracy.errors import GeometryError
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.accuracy.global_worst import global_worst, make_region
from pmaccuracy.kinematics import inverse_kinematics
from pmaccuracy.model.legs import ChainLeg
from pmaccuracy.accuracy.nonlinear import joint_displaced_pose
from pmaccuracy.model.serial import SerialArm, SerialErrorSources, SerialJoint, max_serial_errors
from pmaccuracy.model.sources import ErrorSources, JointDisplacements, JointErrors, worst_configuration

QUANTITIES = ("dx", "dy", "dphi", "dp")


def _random_ppr(rng):
    from conftest import random_manipulator
    rr = random_manipulator(rng)
    return rr.robot.to_dict(), rr.home


GENERATORS = {
    "3-PPR": _random_ppr,
    "3-PRR": pref.random_prr,
    "3-RPR": pref.random_rpr,
    "3-PRP": lambda rng: pref.random_chain(rng, types=("PRP", "PRP", "PRP")),
    "mixed": lambda rng: pref.random_chain(rng, types=("RPP", "PRP", "RRP")),
}


def as_chain_dict(robot: Manipulator) -> dict:
    """The robot in the general chain form of a robot file (degrees; the blocks it names)."""
    return {"architecture": "chain", "name": robot.name,
            "legs": [ChainLeg(chain).to_table() for chain in robot.chains]}


def random_case(kind: str, seed: int):
    """A random robot of ``kind`` (chain form) with random blocks on its P joints, its nominal pose and random
    clearances on every joint (radial everywhere, actuator on the actuated joint, angular and lateral on P)."""
    rng = np.random.default_rng(seed)
    data, pose = GENERATORS[kind](rng)
    chain_data = as_chain_dict(Manipulator.from_dict(data, source="random"))
    legs = []
    for leg in chain_data["legs"]:
        joints = []
        for jt in leg["joints"]:
            c = {"radial": float(rng.uniform(0.005, 0.05))}
            if jt.get("actuated"):
                c["actuator"] = float(rng.uniform(0.001, 0.01) if jt["type"] == "P" else rng.uniform(1e-4, 1e-3))
            if jt["type"] == "P":
                block = rng.choice(["default", "carriage", "bushing"])
                if block != "default":
                    jt["block"] = str(block)
                c |= {"angular": float(rng.uniform(1e-4, 2e-3)), "lateral": float(rng.uniform(0.001, 0.005)),
                      "block_length": float(rng.uniform(20, 60))}
            joints.append(c)
        legs.append({"joints": joints})
    return chain_data, np.asarray(pose, float), {"legs": legs}


def reference_legs(robot: Manipulator) -> list[dict]:
    """The robot's legs in :mod:`block_reference`'s plain form (mm, rad)."""
    return [{"base": c.base, "base_angle": c.base_angle, "platform": c.platform, "platform_angle": c.platform_angle,
             "joints": [{"kind": j.kind, "actuated": j.actuated, "offset": j.offset, "link": j.link, "block": j.block}
                        for j in c.joints]} for c in robot.chains]


def shift_origins(chain_data: dict, rng) -> dict:
    """The same physical robot with every P joint's long member re-referenced by 20-100 mm along its rail.

    A carriage's rail origin moves back by ``t`` (the link before it, or the base, ends ``t`` earlier; the
    joint value and range grow by ``t``); a bushing's rod gets ``t`` more link after the joint (its value and
    range shrink by ``t``). The blocks stay where they physically are.
    """
    out = copy.deepcopy(chain_data)
    for leg in out["legs"]:
        angle = math.radians(leg.get("base_deg", 0.0))
        for k, jt in enumerate(leg["joints"]):
            if jt["type"] != "P":
                continue
            t = float(rng.uniform(20, 100))
            off = math.radians(jt.get("offset_deg", 0.0))
            carriage = jt.get("block", "carriage" if jt.get("actuated") else "bushing") == "carriage"
            if carriage:
                if k == 0:
                    leg["base"] = [leg["base"][0] - t * math.cos(angle + off), leg["base"][1] - t * math.sin(angle + off)]
                else:
                    prev = leg["joints"][k - 1]
                    link = prev.get("link", [0.0, 0.0])
                    prev["link"] = [link[0] - t * math.cos(off), link[1] - t * math.sin(off)]
            else:
                link = jt.get("link", [0.0, 0.0])
                jt["link"] = [link[0] + t, link[1]]
                t = -t
            if "range" in jt:
                jt["range"] = [jt["range"][0] + t, jt["range"][1] + t]
    return out


def load(data, source="random") -> Manipulator:
    return Manipulator.from_dict(data, source=source)


def sources_of(spec) -> ErrorSources:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ErrorSources.from_dict(spec)


CASES = [(kind, seed) for kind in GENERATORS for seed in (1, 2)]


@pytest.mark.parametrize("kind,seed", CASES)
def test_maxima_against_block_reference(kind, seed):
    """dx, dy, dphi, dp maxima (first order) equal the finite differences of the independent exact closure
    with each clearance a finite displacement of its block, to 1e-6 relative."""
    data, pose, spec = random_case(kind, seed)
    robot = load(data)
    res = max_pose_errors(robot, sources_of(spec), pose)
    q = inverse_kinematics(robot, pose).joints
    ref = bref.reference_maxima(reference_legs(robot), pose, q, [leg["joints"] for leg in spec["legs"]])
    for name in QUANTITIES:
        assert float(getattr(res, f"{name}_max")) == pytest.approx(ref[name], rel=1e-6), (kind, name)


@pytest.mark.parametrize("kind", sorted(GENERATORS))
def test_virtual_prototype_against_block_reference(kind):
    """The library's exact closure with finite block displacements (the virtual prototype of every layer:
    nonlinear maxima, statistics, experiment simulate) equals the reference's closure."""
    data, pose, spec = random_case(kind, 3)
    robot = load(data)
    q = inverse_kinematics(robot, pose).joints
    rng = np.random.default_rng(4)
    cfg = JointDisplacements.zeros()
    values = {}
    for i, chain in enumerate(robot.chains):
        for k, joint in enumerate(chain.joints):
            shift = complex(*rng.uniform(-0.05, 0.05, 2))
            cfg.shift[i, k] = values[(i, k, "shift")] = shift
            if joint.actuated:
                cfg.dq[i, k] = values[(i, k, "dq")] = rng.uniform(-0.01, 0.01) * (1 if joint.kind == "P" else 0.1)
            if joint.kind == "P":
                cfg.tilt[i, k] = values[(i, k, "tilt")] = rng.uniform(-2e-3, 2e-3)
                cfg.sigma[i, k] = values[(i, k, "sigma")] = rng.uniform(-0.005, 0.005)
                cfg.tau[i, k] = values[(i, k, "tau")] = rng.uniform(-2e-4, 2e-4)
    got = joint_displaced_pose(robot, pose, cfg) - pose
    ref = bref.closure_pose_error(reference_legs(robot), pose, q, values)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-10)


@pytest.mark.parametrize("kind", sorted(GENERATORS))
def test_shifted_origin_gives_identical_bounds_and_details(kind):
    data, pose, spec = random_case(kind, 5)
    shifted = shift_origins(data, np.random.default_rng(6))
    a, b = load(data), load(shifted)
    qa, qb = inverse_kinematics(a, pose).joints, inverse_kinematics(b, pose).joints
    assert not np.allclose(qa, qb)  # the files do differ
    sources = sources_of(spec)
    ra, rb = (max_pose_errors(r, sources, pose, details=True) for r in (a, b))
    for name in QUANTITIES:
        assert float(getattr(rb, f"{name}_max")) == pytest.approx(float(getattr(ra, f"{name}_max")), rel=1e-9)
        ca = worst_configuration(a, sources, qa, pose, ra.worst_signs[name])
        cb = worst_configuration(b, sources, qb, pose, rb.worst_signs[name])
        for f in JointDisplacements.FIELDS:
            np.testing.assert_allclose(getattr(cb, f), getattr(ca, f), rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("kind", ["3-PRR", "3-RPR", "3-PPR", "mixed"])
def test_shifted_origin_gives_identical_certified_and_nonlinear_maxima(kind):
    data, pose, spec = random_case(kind, 7)
    shifted = shift_origins(data, np.random.default_rng(8))
    sources = sources_of(spec)
    ra, rb = (C.certified_pose_errors(load(d), sources, pose, on_failure="nan") for d in (data, shifted))
    assert not ra.reason[0], ra.reason[0]
    for name in QUANTITIES:
        assert rb.upper[name][0] == pytest.approx(ra.upper[name][0], rel=1e-9), name
        assert rb.lower[name][0] == pytest.approx(ra.lower[name][0], rel=1e-9), name


def test_shifted_origin_gives_identical_worst_case_over_a_region():
    data, pose, spec = random_case("3-PRR", 9)
    shifted = shift_origins(data, np.random.default_rng(10))
    sources = sources_of(spec)
    box = (pose[0] - 3, pose[0] + 3, pose[1] - 3, pose[1] + 3)
    wa, wb = (global_worst(r, sources, make_region(r, (pose[2], pose[2]), box))
              for r in (load(data), load(shifted)))
    xs, ys = np.meshgrid(np.linspace(*box[:2], 41), np.linspace(*box[2:], 41))
    grid = np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, pose[2])], axis=-1)
    dense = max_pose_errors(load(shifted), sources, grid, allow_outside=True)
    for name in QUANTITIES:
        assert wb[name].lower == pytest.approx(wa[name].lower, rel=1e-9), name
        assert wa[name].converged and wb[name].converged
        # the interval enclosures (about each block's centre) bound every grid pose's value
        assert np.nanmax(getattr(dense, f"{name}_max")) <= wb[name].upper * (1 + 1e-12), name


def test_block_changes_the_result_only_through_the_block_centre():
    """The preset 3-PRR with only an angular clearance on the guides: carriage (default) and bushing differ, and
    the bushing equals the old model (a turn about the rail's origin: the direction tolerance's centre)."""
    robot = Manipulator.preset("symmetric_3prr")
    pose = np.array([10.0, 5.0, math.radians(5)])
    carriage = max_pose_errors(robot, ErrorSources(legs=((JointErrors(angular=5e-4), JointErrors(), JointErrors()),)
                                                   * 3), pose)
    data = robot.to_dict()
    for leg in data["legs"]:
        leg["block"] = "bushing"
    bushing = max_pose_errors(load(data), ErrorSources(legs=((JointErrors(angular=5e-4), JointErrors(),
                                                              JointErrors()),) * 3), pose)
    turned = max_pose_errors(robot, ErrorSources(legs=((JointErrors(direction=5e-4), JointErrors(),
                                                        JointErrors()),) * 3), pose)
    assert float(bushing.dp_max) == pytest.approx(float(turned.dp_max), rel=1e-12)
    assert abs(float(carriage.dp_max) - float(bushing.dp_max)) > 0.1 * float(carriage.dp_max)


def test_paper_3ppr_blocks_are_the_defaults():
    """The 3-PPR's guide is a carriage (tilt about B_i) and its bearing a bushing (tilt about C_i): naming
    them in the file changes nothing; swapping them changes the numbers."""
    robot = Manipulator.preset("aalborg_3ppr")
    poses = np.array([[0.0, 0.0, 0.0], [10.0, -5.0, math.radians(20)]])
    base = max_pose_errors(robot, "case2", poses)
    data = robot.to_dict()
    for leg in data["legs"]:
        leg |= {"guide_block": "carriage", "bearing_block": "bushing"}
    named = max_pose_errors(load(data), "case2", poses)
    sources = ErrorSources(legs=((JointErrors(lateral=0.0015), JointErrors(angular=0.0012), JointErrors(radial=0.04)),)
                           * 3)
    per_joint = max_pose_errors(load(data), sources, poses)
    for leg in data["legs"]:
        leg |= {"bearing_block": "carriage"}
    swapped = max_pose_errors(load(data), sources, poses)
    np.testing.assert_array_equal(named.dp_max, base.dp_max)
    np.testing.assert_allclose(per_joint.dp_max, max_pose_errors(robot, sources, poses).dp_max, rtol=1e-12)
    assert np.all(np.abs(swapped.dp_max - per_joint.dp_max) > 1e-3 * per_joint.dp_max)


@pytest.mark.parametrize("table,key,message", [
    ({"block": "slider"}, "legs[1].block", "carriage.*bushing"),
    ({"block": 3}, "legs[1].block", "carriage.*bushing"),
])
def test_bad_block_is_refused_naming_the_key(table, key, message):
    data = Manipulator.preset("symmetric_3prr").to_dict()
    data["legs"][0] |= table
    with pytest.raises(GeometryError, match=message) as info:
        load(data, source="bad.toml")
    assert info.value.key == key and "bad.toml" in str(info.value)


def test_block_on_a_revolute_is_refused():
    data = as_chain_dict(Manipulator.preset("symmetric_3rrr"))
    data["legs"][1]["joints"][0]["block"] = "bushing"
    with pytest.raises(GeometryError, match="only a prismatic joint") as info:
        load(data, source="bad.toml")
    assert info.value.key == "legs[2].joints[1].block"


def test_blocks_round_trip_through_files():
    for name, key in (("symmetric_3prr", "block"), ("symmetric_3rpr", "block")):
        data = Manipulator.preset(name).to_dict()
        data["legs"][2][key] = "bushing"
        robot = load(data)
        assert robot.chains[2].joints[0 if name.endswith("prr") else 1].block_kind == "bushing"
        assert load(robot.to_dict()) == robot
    data = Manipulator.preset("aalborg_3ppr").to_dict()
    data["legs"][0] |= {"guide_block": "bushing", "bearing_block": "carriage"}
    robot = load(data)
    assert [j.block_kind for j in robot.chains[0].joints] == ["bushing", "carriage", None]
    assert load(robot.to_dict()) == robot


# ---------------------------------------------------------------- serial arms
def _random_serial(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 5))
    joints, ref_joints, clear = [], [], []
    for k in range(n):
        kind = "P" if k == 0 or rng.random() < 0.5 else "R"
        length = float(rng.uniform(50, 200))
        offset = 0.0 if kind == "P" and rng.random() < 0.5 else float(rng.uniform(-np.pi, np.pi))
        block = str(rng.choice(["carriage", "bushing"])) if kind == "P" else None
        joints.append(SerialJoint(kind, length, offset, (-np.pi, np.pi) if kind == "R" else (-300.0, 300.0),
                                  block=block))
        ref_joints.append({"kind": kind, "offset": offset, "length": length, "block": block})
        c = {"radial": float(rng.uniform(0.005, 0.05)),
             "actuator": float(rng.uniform(1e-4, 1e-3) if kind == "R" else rng.uniform(0.001, 0.01))}
        if kind == "P":
            c |= {"angular": float(rng.uniform(1e-4, 2e-3)), "lateral": float(rng.uniform(0.001, 0.005)),
                  "block_length": float(rng.uniform(20, 60))}
        clear.append(c)
    q = np.array([rng.uniform(-1, 1) if j.kind == "R" else rng.uniform(-100, 100) for j in joints])
    return SerialArm(tuple(joints), name="random"), ref_joints, clear, q


@pytest.mark.parametrize("seed", range(6))
def test_serial_arm_against_block_reference(seed):
    arm, ref_joints, clear, q = _random_serial(seed)
    got = max_serial_errors(arm, SerialErrorSources(tuple(JointErrors(**c) for c in clear)), q)
    ref = bref.serial_reference_maxima(ref_joints, q, clear)
    for name in QUANTITIES:
        assert float(np.squeeze(getattr(got, f"{name}_max"))) == pytest.approx(ref[name], rel=1e-6), name


@pytest.mark.parametrize("seed", range(4))
def test_serial_arm_shifted_origin(seed):
    """A carriage's origin moved back along its rail (the link before it shorter), a bushing's rod longer."""
    arm, _, clear, q = _random_serial(seed)
    joints, q2 = list(arm.joints), q.copy()
    for k, j in enumerate(arm.joints):
        if j.kind != "P":
            continue
        if j.block_kind == "bushing":
            joints[k] = SerialJoint("P", j.length + 30.0, j.offset, j.range, block=j.block)
            q2[k] -= 30.0
        elif k > 0 and j.offset == 0.0 and joints[k - 1].length > 30.0:
            p = joints[k - 1]
            joints[k - 1] = SerialJoint(p.kind, p.length - 30.0, p.offset, p.range, block=p.block)
            q2[k] += 30.0
    sources = SerialErrorSources(tuple(JointErrors(**c) for c in clear))
    a = max_serial_errors(arm, sources, q)
    b = max_serial_errors(SerialArm(tuple(joints), name="shifted"), sources, q2)
    np.testing.assert_allclose(b.poses, a.poses, rtol=0, atol=1e-9)
    for name in QUANTITIES:
        assert float(np.squeeze(getattr(b, f"{name}_max"))) == pytest.approx(
            float(np.squeeze(getattr(a, f"{name}_max"))), rel=1e-9), name
