"""Statics and loaded error of planar serial arms (issue 24, deliverable 1 for serial arms), against the
independent reference tests/reference/serial_load_reference.py: statics from virtual work (finite differences
of SerialArm.forward and of a homogeneous-matrix rigid-motion composition), the loaded error by brute force over
each source's extreme values, the exact loaded pose by that composition."""

from __future__ import annotations

import itertools
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from pmaccuracy.accuracy.loads import Load
from pmaccuracy.accuracy.serial_loads import displaced_serial_pose, loaded_serial_error, serial_statics
from pmaccuracy.errors import ConfigError, PmAccuracyError
from pmaccuracy.model.serial import SerialArm, SerialErrorSources, SerialJoint, error_generators
from pmaccuracy.model.sources import JointErrors

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "reference"))
import serial_load_reference as ref  # noqa: E402

R_KEYS = ("radial", "position", "actuator", "direction", "length")
P_KEYS = ("position", "actuator", "direction", "length", "angular", "lateral")
DISKS = ("radial", "position")


def random_case(seed: int):
    """A random arm of 2-5 R/P joints, random sources (2-4 keys per joint), joint values and wrench."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 6))
    joints, table, errs = [], [], []
    for k in range(n):
        kind = str(rng.choice(["R", "P"]))
        length = float(rng.uniform(20, 300))
        offset = float(rng.uniform(-1.0, 1.0))
        block = str(rng.choice(["carriage", "bushing"])) if kind == "P" else None
        joints.append(SerialJoint(kind, length, offset, block=block))
        table.append({"type": kind, "length": length, "offset": offset, "block": block or "carriage"})
        keys = rng.choice(R_KEYS if kind == "R" else P_KEYS, size=int(rng.integers(2, 5)), replace=False)
        values = {}
        for key in keys:
            values[str(key)] = float(rng.uniform(0.001, 0.02)) if key in ("radial", "position", "length", "lateral") \
                or (key == "actuator" and kind == "P") else float(rng.uniform(1e-4, 1e-3))
        if "lateral" in values:
            values["block_length"] = float(rng.uniform(20, 80))
        errs.append(values)
    q = np.array([rng.uniform(-2.5, 2.5) if j.kind == "R" else rng.uniform(0, 200) for j in joints])
    load = Load(fx=float(rng.normal(0, 20)), fy=float(rng.normal(0, 20)), m=float(rng.normal(0, 2000)))
    arm = SerialArm(tuple(joints), name="random")
    sources = SerialErrorSources(tuple(JointErrors(**e) for e in errs), name="random")
    return arm, table, errs, sources, q, load


def reference_loaded(table, errs, q, W):
    """Per source the extreme value maximizing W . dX (brute force over its vertices; a disk: r f / |f|), the
    first-order dX (sum of the sources' effects) and the exact end pose error with those values."""
    nominal = ref.pose(ref.frames(table, q)[1])
    f = np.array(W[:2])
    best, dX = {}, np.zeros(3)
    for k, e in enumerate(errs):
        for key, half in e.items():
            if key == "block_length":
                continue
            if key in DISKS:
                v = half * f / np.linalg.norm(f)
                best[(k, key)] = v
                dX += np.array([v[0], v[1], 0.0])
                continue
            verts = ref.source_vertices(key, half, e.get("block_length", 50.0))
            effects = [ref.first_order_effect(table, q, (k, key), v) for v in verts]
            works = [float(W @ d) for d in effects]
            i = int(np.argmax(works))
            best[(k, key)] = verts[i]
            dX += effects[i]
    exact = ref.displaced_end(table, q, best) - nominal
    return dX, exact, best


@pytest.mark.parametrize("seed", range(12))
def test_statics_against_virtual_work(seed):
    arm, table, errs, sources, q, load = random_case(seed)
    st = serial_statics(arm, q, load)
    W = st.wrench
    J = ref.jacobian(arm.forward, q, step=1e-5)
    tau = -J.T @ W
    scale = np.abs(W[:2]).sum() * 1000 + abs(W[2])
    np.testing.assert_allclose(st.actuator, tau, rtol=1e-6, atol=1e-6 * scale)
    for k in range(arm.n):     # every reaction from the virtual work of a unit rigid motion of the part beyond k
        fx = -W @ ref.first_order_effect(table, q, (k, "radial"), np.array([1.0, 0.0]), step=1e-6)
        fy = -W @ ref.first_order_effect(table, q, (k, "radial"), np.array([0.0, 1.0]), step=1e-6)
        mk = -W @ ref.first_order_effect(table, q, (k, "direction"), 1.0, step=1e-6)
        np.testing.assert_allclose([st.force[k].real, st.force[k].imag], [fx, fy], rtol=1e-6, atol=1e-9 * scale)
        np.testing.assert_allclose(st.moment[k], mk, rtol=1e-6, atol=1e-9 * scale)
        if arm.joints[k].kind == "P":
            N = -W @ ref.first_order_effect(table, q, (k, "lateral"), np.array([1.0, 0.0]), step=1e-6)
            M = -W @ ref.first_order_effect(table, q, (k, "lateral"), np.array([0.0, 1.0]), step=1e-6)
            np.testing.assert_allclose([st.normal[k], st.block_moment[k]], [N, M], rtol=1e-6, atol=1e-9 * scale)
            L = 40.0
            np.testing.assert_allclose(st.contact_forces(L)[k], [N / 2 - M / L, N / 2 + M / L], rtol=1e-6,
                                       atol=1e-9 * scale)
        else:
            assert st.normal[k] == 0 and st.block_moment[k] == 0


@pytest.mark.parametrize("seed", range(12))
def test_loaded_error_against_brute_force_and_exact_composition(seed):
    arm, table, errs, sources, q, load = random_case(seed)
    r = loaded_serial_error(arm, sources, q, load)
    W = r.statics.wrench
    dX, exact, best = reference_loaded(table, errs, q, W)
    size = np.abs(dX).max()
    np.testing.assert_allclose(r.first_order, dX, rtol=1e-6, atol=1e-6 * size)
    np.testing.assert_allclose(W @ r.first_order, W @ dX, rtol=1e-6)
    np.testing.assert_allclose(r.exact, exact, rtol=1e-6, atol=1e-9 * size)
    assert not r.unloaded.any() and not r.disk_unloaded.any()
    np.testing.assert_array_equal(r.spread, 0.0)
    for (k, key), v in best.items():           # the same source values
        np.testing.assert_allclose(r.values[f"joints[{k + 1}].{key}"], v, rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("seed", range(6))
def test_first_order_is_the_support_point_of_the_error_set(seed):
    """Max of W . dX over all 2^m vertices of the zonotope plus the disk's support r |f|."""
    arm, table, errs, sources, q, load = random_case(100 + seed)
    r = loaded_serial_error(arm, sources, q, load, exact=False)
    G, layout = error_generators(arm, sources, q)
    W = r.statics.wrench
    m = G.shape[0]
    assert m <= 14
    signs = np.array(list(itertools.product((-1.0, 1.0), repeat=m)))
    vertices = signs @ G
    i = int(np.argmax(vertices @ W))
    R = sum(e.get(k, 0.0) for e in errs for k in DISKS)
    f = W[:2]
    support = vertices[i] + np.r_[R * f / np.linalg.norm(f), 0.0]
    np.testing.assert_allclose(r.first_order, support, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(W @ r.first_order, vertices[i] @ W + R * np.linalg.norm(f), rtol=1e-12)
    assert np.all(np.isnan(r.exact))


@pytest.mark.parametrize("seed", range(6))
def test_exact_converges_to_first_order(seed):
    """Sources scaled by s: (exact - first order) / s shrinks like s (second-order remainder)."""
    arm, table, errs, sources, q, load = random_case(200 + seed)
    gaps = []
    for s in (1.0, 0.1):
        scaled = SerialErrorSources(tuple(JointErrors(**{k: (v if k == "block_length" else s * v)
                                                         for k, v in e.items()}) for e in errs))
        r = loaded_serial_error(arm, scaled, q, load)
        gaps.append(np.abs(r.exact - r.first_order).max() / np.abs(r.first_order).max())
    assert gaps[1] < 0.2 * gaps[0] + 1e-12


def test_actuator_direction_length_errors_are_a_modified_arm():
    """With actuator, direction and length sources only, the exact pose is SerialArm.forward of the arm with
    q_k, offset_k and length_k changed by the source values."""
    rng = np.random.default_rng(7)
    for _ in range(5):
        n = int(rng.integers(2, 6))
        kinds = rng.choice(["R", "P"], size=n)
        arm = SerialArm(tuple(SerialJoint(str(k), float(rng.uniform(20, 300)), float(rng.uniform(-1, 1)))
                              for k in kinds))
        q = np.array([rng.uniform(-2, 2) if k == "R" else rng.uniform(0, 100) for k in kinds])
        values = {}
        dq, doff, dlen = np.zeros(n), np.zeros(n), np.zeros(n)
        for k in range(n):
            dq[k] = rng.uniform(-1e-2, 1e-2) if kinds[k] == "R" else rng.uniform(-1, 1)
            doff[k], dlen[k] = rng.uniform(-1e-2, 1e-2), rng.uniform(-1, 1)
            values.update({f"joints[{k + 1}].actuator": dq[k], f"joints[{k + 1}].direction": doff[k],
                           f"joints[{k + 1}].length": dlen[k]})
        modified = SerialArm(tuple(SerialJoint(j.kind, j.length + dlen[k], j.offset + doff[k])
                                   for k, j in enumerate(arm.joints)))
        np.testing.assert_allclose(displaced_serial_pose(arm, q, values), modified.forward(q + dq), rtol=1e-12,
                                   atol=1e-9)


def test_unloaded_sources_give_a_spread():
    """A force along the stretched 3R arm: no joint carries a moment (actuators unloaded: their whole range is
    the spread), the radial plays take up along the force."""
    arm = SerialArm.load("planar_3r_arm")
    q = np.zeros(3)
    r = loaded_serial_error(arm, "arm_typical", q, Load(fx=5.0))
    table = [{"type": "R", "length": j.length, "offset": j.offset} for j in arm.joints]
    assert r.unloaded.all() and not r.disk_unloaded
    np.testing.assert_allclose(r.first_order, [0.015, 0.0, 0.0], atol=1e-12)
    spread = sum(np.abs(ref.first_order_effect(table, q, (k, "actuator"), eps))
                 for k, eps in enumerate((0.0003, 0.0003, 0.0005)))
    np.testing.assert_allclose(r.spread, spread, rtol=1e-6)
    assert r.records()[0]["unloaded_sources"] == "joints[1].actuator,joints[2].actuator,joints[3].actuator"
    # a pure moment: the disks are unloaded (spread 3 x 5 um in x and y), every actuator loaded
    r = loaded_serial_error(arm, "arm_typical", [0.2, 0.4, 0.1], Load(m=100.0))
    assert r.disk_unloaded and not r.unloaded.any()
    np.testing.assert_allclose(r.spread, [0.015, 0.015, 0.0], atol=1e-15)
    assert "joints[1].radial" in r.records()[0]["unloaded_sources"]


def test_weight_of_the_end_link():
    """1 kg hanging 50 mm beyond the tip of the stretched arm (650 mm): 700, 400, 150 mm lever arms."""
    arm = SerialArm.load("planar_3r_arm")
    st = serial_statics(arm, [0.0, 0.0, 0.0], Load(mass=1.0, com=(50.0, 0.0)))
    np.testing.assert_allclose(st.actuator, 9.80665 * np.array([700.0, 400.0, 150.0]), rtol=1e-12)


def test_bad_input():
    arm = SerialArm.load("planar_3r_arm")
    with pytest.raises(ConfigError, match="Load"):
        serial_statics(arm, [0.0, 0.0, 0.0], (1.0, 0.0, 0.0))
    with pytest.raises(ConfigError, match="threshold"):
        loaded_serial_error(arm, "arm_typical", [0.0, 0.0, 0.0], Load(fx=1.0), threshold=-1.0)
    with pytest.raises(PmAccuracyError, match="3 joint values"):
        serial_statics(arm, [0.0, 0.0], Load(fx=1.0))
    with pytest.raises(PmAccuracyError, match="outside its range"):
        serial_statics(arm, [3.1, 0.0, 0.0], Load(fx=1.0))
    with pytest.raises(PmAccuracyError, match="not finite"):
        loaded_serial_error(arm, "arm_typical", [math.nan, 0.0, 0.0], Load(fx=1.0))
    assert "SerialStatics(1 pose" in repr(serial_statics(arm, [0.0, 0.0, 0.0], Load(fx=1.0)))
    assert "SerialLoadedError(1 pose" in repr(loaded_serial_error(arm, "arm_typical", [0.0, 0.0, 0.0], Load(fx=1.0)))


def test_cli_serial_load_matches_the_library(capsys):
    import json

    from pmaccuracy.cli import main

    assert main(["load", "--robot", "planar_3r_arm", "--joints", "30", "45", "-20", "--joints", "10", "20", "30",
                 "--fx", "3", "--fy", "-20", "--m", "150", "--details", "--format", "json"]) == 0
    recs = json.loads(capsys.readouterr().out)
    q = np.radians([[30.0, 45.0, -20.0], [10.0, 20.0, 30.0]])
    res = loaded_serial_error("planar_3r_arm", "arm_typical", q, Load(fx=3.0, fy=-20.0, m=150.0))
    for i, rec in enumerate(recs):
        assert rec["q2_deg"] == pytest.approx(np.degrees(q[i, 1]), rel=1e-12)
        assert rec["dy"] == pytest.approx(float(res.first_order[i, 1]), rel=1e-12)
        assert rec["dphi_deg_exact"] == pytest.approx(float(np.degrees(res.exact[i, 2])), rel=1e-12)
        assert rec["tau1_Nmm"] == pytest.approx(float(res.statics.actuator[i, 0]), rel=1e-12)
        assert rec["joint2.moment_Nmm"] == pytest.approx(float(res.statics.moment[i, 1]), rel=1e-12)
        assert rec["joints[3].actuator"] == pytest.approx(float(res.values["joints[3].actuator"][i]), rel=1e-12)


@pytest.mark.parametrize("argv, key", [
    (["--joints", "30", "45", "-20"], "--fx"),                                          # zero load
    (["--joints", "30", "45", "--fx", "1"], "--joints"),                                 # wrong count
    (["--pose", "0", "0", "0", "--fx", "1"], "--pose"),
    (["--joints", "30", "45", "-20", "--fx", "1", "--plot", "a.png"], "--plot"),
    (["--joints", "30", "45", "-20", "--fx", "1", "--map"], "--map"),
    (["--joints", "30", "45", "-20", "--fx", "1", "--mass", "-2"], "--mass"),
    (["--joints", "30", "45", "-20", "--fx", "1", "--unloaded-below", "-1"], "--unloaded-below"),
    (["--joints", "30", "45", "-20", "--fx", "1", "--clearances", "case1"], "case1"),
    (["--joints", "300", "45", "-20", "--fx", "1"], "outside its range"),
])
def test_cli_serial_bad_input_one_line(capsys, argv, key):
    from pmaccuracy.cli import main

    assert main(["load", "--robot", "planar_3r_arm", *argv]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and key in err and "Traceback" not in err


def test_cli_joints_with_a_parallel_robot(capsys):
    from pmaccuracy.cli import main

    assert main(["load", "--robot", "aalborg_3ppr", "--joints", "1", "2", "3", "--fx", "1"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "--joints" in err and "serial" in err


def test_threshold_is_the_generalized_reaction():
    """A P block's two segments are unloaded exactly when its end contact forces (statics, checked above against
    virtual work) are at most the threshold; an R actuator when its torque is."""
    arm = SerialArm((SerialJoint("R", 200.0), SerialJoint("P", 50.0), SerialJoint("R", 100.0)))
    sources = SerialErrorSources((JointErrors(actuator=1e-3), JointErrors(lateral=0.01, block_length=40.0),
                                  JointErrors(actuator=1e-3)))
    q = np.array([0.4, 80.0, -0.7])
    load = Load(fx=3.0, fy=-5.0, m=200.0)
    st = serial_statics(arm, q, load)
    contacts = np.abs(st.contact_forces(40.0)[1])
    torque = abs(st.actuator[0])
    for t, unloaded in ((0.999 * contacts.min(), 0), (1.001 * contacts.min(), 1), (1.001 * contacts.max(), 2)):
        r = loaded_serial_error(arm, sources, q, load, threshold=t)
        assert int(r.unloaded[1:3].sum()) == unloaded
    r = loaded_serial_error(arm, sources, q, load, threshold=0.999 * torque)
    assert not r.unloaded[0]
    r = loaded_serial_error(arm, sources, q, load, threshold=1.001 * torque)
    assert r.unloaded[0]


@pytest.mark.parametrize("seed", range(4))
def test_weight_from_its_potential(seed):
    """The end link's weight: tau_k = dV/dq_k with V = -m g . r_com(q) (finite differences of SerialArm.forward
    and the centre of mass turned with the end frame), plus the wrench's own -J^T W."""
    arm, table, errs, sources, q, _ = random_case(300 + seed)
    rng = np.random.default_rng(seed)
    mass, com, gdeg = float(rng.uniform(0.1, 3)), tuple(rng.uniform(-80, 80, 2)), float(rng.uniform(-180, 180))
    g = 9.80665 * mass * np.array([math.cos(math.radians(gdeg)), math.sin(math.radians(gdeg))])

    def potential(qq):
        x, y, phi = arm.forward(qq)
        r = np.array([x, y]) + np.array([[math.cos(phi), -math.sin(phi)], [math.sin(phi), math.cos(phi)]]) @ com
        return -g @ r

    tau = np.array([(potential(q + h) - potential(q - h)) / 2e-5 for h in np.eye(arm.n) * 1e-5])
    st = serial_statics(arm, q, Load(mass=mass, com=com, gravity_deg=gdeg))
    np.testing.assert_allclose(st.actuator, tau, rtol=1e-6, atol=1e-6 * np.abs(tau).max())
