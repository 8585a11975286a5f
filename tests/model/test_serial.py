"""Planar serial arms (``pmaccuracy.model.serial``, ``bounds --joints``) against an independent brute force.

The reference here shares no code with the library: its forward kinematics
uses real cos/sin and inserts every error source as what it physically is
(a displaced joint centre, a turned slide, a longer link, a shifted and
tilted carriage, ...); the first-order effect of each source comes from
central finite differences of that forward kinematics, and the maxima from
enumerating each source's extreme values (interval ends, the rhombus's four
vertices), a dense direction search (disks, ``|dp|``) refined locally, and,
when few enough, every vertex of the whole error set.
"""

from __future__ import annotations

import itertools
import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import tomli_w
from scipy.optimize import minimize_scalar

from pmaccuracy.errors import ClearanceError, ConfigError, OutsideJointLimitsError, PoseError
from pmaccuracy.model.serial import SerialArm, SerialErrorSources, SerialJoint, load_serial_sources, max_serial_errors, zonotope_max_norm
from pmaccuracy.model.sources import JointErrors
from conftest import run_cli

QUANTITIES = ("dx", "dy", "dphi", "dp")
#: Sources that displace by a vector (two error variables each).
VECTOR_KEYS = ("radial", "position", "lateral")


# ---------------------------------------------------------------- independent reference

def ref_fk(spec, q, pert=None):
    """End-effector ``[x, y, phi]`` of the arm ``spec`` [(kind, length, offset rad[, block]), ...] with errors
    ``pert``.

    ``pert[(k, key)]``: ``position``/``radial`` (dx, dy) mm, ``lateral`` (sigma mm, tau rad), others a number.
    A slide's block (``"carriage"`` by default, or ``"bushing"``) shifts by sigma and tilts by tau + angular
    about its own centre: the carriage at the end of the slide, the bushing at the slide's origin.
    """
    pert = pert or {}
    x = y = a = 0.0
    for k, (kind, length, offset, *block) in enumerate(spec):
        px, py = pert.get((k, "position"), (0.0, 0.0))    # the joint's centre (and all beyond) moved
        x, y = x + px, y + py
        a += offset + pert.get((k, "direction"), 0.0)     # turned about its centre
        qk = q[k] + pert.get((k, "actuator"), 0.0)
        if kind == "R":
            a += qk
        else:
            sigma, tau = pert.get((k, "lateral"), (0.0, 0.0))
            tilt = tau + pert.get((k, "angular"), 0.0)
            bushing = block == ["bushing"]
            if not bushing:
                x, y = x + qk * math.cos(a), y + qk * math.sin(a)            # the carriage slides first
            x, y = x - sigma * math.sin(a), y + sigma * math.cos(a)          # the block shifted normal to the rail
            a += tilt                                                         # and tilted about its centre
            if bushing:
                x, y = x + qk * math.cos(a), y + qk * math.sin(a)            # the rod slides through the bushing
        rx, ry = pert.get((k, "radial"), (0.0, 0.0))                         # play: the distal part translates
        x, y = x + rx, y + ry
        link = length + pert.get((k, "length"), 0.0)
        x, y = x + link * math.cos(a), y + link * math.sin(a)
    return np.array([x, y, a])


def ref_columns(spec, q, sources, h=1e-5):
    """{(k, key): J (3, d)}: central finite differences of ``ref_fk`` per error variable."""
    out = {}
    for (k, key) in sources:
        d = 2 if key in VECTOR_KEYS else 1
        cols = []
        for c in range(d):
            step = [0.0, 0.0]
            step[c] = h
            plus = {(k, key): tuple(step) if d == 2 else h}
            minus = {(k, key): tuple(-s for s in step) if d == 2 else -h}
            cols.append((ref_fk(spec, q, plus) - ref_fk(spec, q, minus)) / (2 * h))
        out[(k, key)] = np.array(cols).T
    return out


def vertices(key, vals):
    """Extreme values of one source (not the disks): interval ends, or the guide rhombus's four vertices."""
    if key == "lateral":
        eps, L = vals
        return [np.array(v) for v in ((eps, 0.0), (-eps, 0.0), (0.0, 2 * eps / L), (0.0, -2 * eps / L))]
    return [np.array([vals]), np.array([-vals])]


DISK_ANGLES = np.linspace(0.0, 2 * np.pi, 20000, endpoint=False)


def ref_support(J, sources, u):
    """Support function of the first-order error set in direction ``u (3,)`` (or ``(K, 3)``)."""
    u = np.atleast_2d(u)
    total = np.zeros(len(u))
    for (k, key), vals in sources.items():
        Jk = J[(k, key)]
        if key in ("radial", "position"):
            # dense directions of the disk for a few u; over the dense grid of u, the disk's exact support
            # eps |J^T u| (Cauchy-Schwarz) keeps the cost down
            disk = vals * np.stack([np.cos(DISK_ANGLES), np.sin(DISK_ANGLES)])
            total += np.max(u @ (Jk @ disk), axis=1) if len(u) < 50 else vals * np.linalg.norm(u @ Jk, axis=1)
        else:
            total += np.max(np.stack([u @ (Jk @ v) for v in vertices(key, vals)]), axis=0)
    return total


def ref_dp(J, sources, n_dir=8192):
    """max |dp| = max over in-plane directions of the support function: dense grid, then local refinement."""
    t = np.linspace(0.0, 2 * np.pi, n_dir, endpoint=False)
    u = np.stack([np.cos(t), np.sin(t), np.zeros_like(t)], axis=1)
    s = ref_support(J, sources, u)
    step = t[1]
    best = s.max()
    peaks = np.argsort(s)[-3:]
    for i in peaks:
        res = minimize_scalar(lambda a: -ref_support(J, sources, np.array([math.cos(a), math.sin(a), 0.0]))[0],
                              bounds=(t[i] - step, t[i] + step), method="bounded", options={"xatol": 1e-12})
        best = max(best, -res.fun)
    return best


def ref_bounds(spec, q, sources, dense=True):
    """Reference dx, dy, dphi, dp maxima at one configuration; also the vertex-enumeration dp when feasible."""
    J = ref_columns(spec, q, sources)
    out = {}
    for name, axis in (("dx", 0), ("dy", 1), ("dphi", 2)):
        u = np.zeros(3)
        u[axis] = 1.0
        out[name] = float(ref_support(J, sources, u)[0])
    if dense:
        out["dp"] = ref_dp(J, sources)
    finite = [(k, key) for (k, key) in sources if key not in ("radial", "position")]
    if all(key not in ("radial", "position") for (_, key) in sources) and \
            math.prod(4 if key == "lateral" else 2 for _, key in finite) <= 1 << 14:
        sums = np.zeros((1, 2))       # every combination of the sources' extreme values
        for s in finite:
            pts = np.array([(J[s] @ v)[:2] for v in vertices(s[1], sources[s])])
            sums = (sums[:, None, :] + pts[None, :, :]).reshape(-1, 2)
        out["dp_enum"] = float(np.hypot(sums[:, 0], sums[:, 1]).max())
    return out


# ---------------------------------------------------------------- random arms and sources

def random_arm(rng, n):
    joints, spec = [], []
    for k in range(n):
        kind = "R" if rng.random() < 0.6 else "P"
        length = float(rng.uniform(50, 400) if kind == "R" else rng.uniform(0, 200))
        offset = float(rng.uniform(-np.pi, np.pi))
        rng_ = (-np.pi, np.pi) if kind == "R" else (-100.0, 300.0)
        block = None if kind == "R" else str(rng.choice(["carriage", "bushing"]))
        joints.append(SerialJoint(kind, length, offset, rng_, name=f"j{k + 1}", block=block))
        spec.append((kind, length, offset, block or "carriage"))
    return SerialArm(tuple(joints), name="random"), spec


def random_sources(rng, arm, p=0.45):
    """Random half-widths: (SerialErrorSources, {(k, key): value or (eps, L)})."""
    joints, flat = [], {}
    for k, j in enumerate(arm.joints):
        vals = {}
        ranges = {"radial": (1e-3, 0.05), "position": (1e-3, 0.05), "direction": (1e-4, 1e-3),
                  "length": (1e-3, 0.05), "actuator": (1e-4, 1e-3) if j.kind == "R" else (1e-3, 0.02)}
        if j.kind == "P":
            ranges |= {"angular": (1e-4, 1e-3), "lateral": (1e-3, 0.01)}
        for key, (lo, hi) in ranges.items():
            if rng.random() < p:
                vals[key] = float(rng.uniform(lo, hi))
        if "lateral" in vals:
            vals["block_length"] = float(rng.uniform(20, 100))
        joints.append(JointErrors(**vals))
        for key, v in vals.items():
            if key == "lateral":
                flat[(k, key)] = (v, vals["block_length"])
            elif key != "block_length":
                flat[(k, key)] = v
    return SerialErrorSources(tuple(joints), name="random"), flat


def random_q(rng, arm, size):
    lo = np.array([j.range[0] for j in arm.joints])
    hi = np.array([j.range[1] for j in arm.joints])
    return rng.uniform(lo, hi, size=(size, arm.n))


CASES = list(range(30))


@pytest.mark.parametrize("seed", CASES)
def test_random_arms_against_brute_force(seed):
    rng = np.random.default_rng(1000 + seed)
    arm, spec = random_arm(rng, int(rng.integers(2, 6)))
    sources, flat = random_sources(rng, arm)
    q = random_q(rng, arm, 3)
    b = max_serial_errors(arm, sources, q, details=True)      # vectorized over the 3 configurations
    for i in range(len(q)):
        pose = ref_fk(spec, q[i])
        np.testing.assert_allclose(b.poses[i], pose, rtol=0, atol=1e-9)
        ref = ref_bounds(spec, q[i], flat)
        got = {"dx": b.dx_max[i], "dy": b.dy_max[i], "dphi": b.dphi_max[i], "dp": b.dp_max[i]}
        for name in QUANTITIES:
            assert got[name] == pytest.approx(ref[name], rel=1e-6, abs=1e-12), (name, flat)
    # the zonotope alone (disks dropped) against every vertex of the error set
    no_disks = SerialErrorSources(tuple(replace(j, radial=0.0, position=0.0) for j in sources.joints))
    flat_nd = {s: v for s, v in flat.items() if s[1] not in ("radial", "position")}
    b_nd = max_serial_errors(arm, no_disks, q)
    for i in range(len(q)):
        ref = ref_bounds(spec, q[i], flat_nd, dense=False)
        if "dp_enum" in ref:
            assert b_nd.dp_max[i] == pytest.approx(ref["dp_enum"], rel=1e-6, abs=1e-12)


def _insert(worst, i, s):
    """The worst-case source values of configuration ``i``, times ``s``, as ``ref_fk`` perturbations."""
    pert = {}
    for key, value in worst.items():
        k = int(key[len("joints["):key.index("]")]) - 1
        name = key.split(".", 1)[1]
        v = np.asarray(value)[i] * s
        pert[(k, name)] = tuple(v) if np.ndim(v) else float(v)
    return pert


@pytest.mark.parametrize("seed", range(12))
def test_worst_configurations_attain_the_maxima(seed):
    """Each quantity's worst-case source values, inserted in the reference FK, give that maximum (first order)."""
    rng = np.random.default_rng(2000 + seed)
    arm, spec = random_arm(rng, int(rng.integers(2, 6)))
    sources, flat = random_sources(rng, arm, p=0.6)
    q = random_q(rng, arm, 2)
    b = max_serial_errors(arm, sources, q, details=True)
    s = 1e-3
    for i in range(len(q)):
        for name, axis, target in (("dx", 0, b.dx_max), ("dy", 1, b.dy_max), ("dphi", 2, b.dphi_max)):
            d = (ref_fk(spec, q[i], _insert(b.worst[name], i, s)) - ref_fk(spec, q[i], _insert(b.worst[name], i, -s)))
            assert d[axis] / (2 * s) == pytest.approx(target[i], rel=1e-6, abs=1e-12)
        d = ref_fk(spec, q[i], _insert(b.worst["dp"], i, s)) - ref_fk(spec, q[i], _insert(b.worst["dp"], i, -s))
        assert math.hypot(d[0], d[1]) / (2 * s) == pytest.approx(b.dp_max[i], rel=1e-6, abs=1e-12)
        # every value lies in its source's set
        for name in QUANTITIES:
            for (k, key), vals in flat.items():
                v = np.asarray(b.worst[name][f"joints[{k + 1}].{key}"])[i]
                if key in ("radial", "position"):
                    assert np.hypot(*v) <= vals * (1 + 1e-12)
                elif key == "lateral":
                    eps, L = vals
                    assert abs(L * v[1] + 2 * v[0]) <= 2 * eps * (1 + 1e-12)
                    assert abs(L * v[1] - 2 * v[0]) <= 2 * eps * (1 + 1e-12)
                else:
                    assert abs(v) <= vals * (1 + 1e-12)


def test_zonotope_max_norm_against_enumeration():
    rng = np.random.default_rng(7)
    for m in range(0, 9):
        h = rng.normal(size=(20, m)) + 1j * rng.normal(size=(20, m))
        if m >= 3:   # parallel, opposite and zero generators
            h[:, 1] = -2.5 * h[:, 0]
            h[:5, 2] = 0
        best, signs = zonotope_max_norm(h)
        combos = np.array(list(itertools.product((-1.0, 1.0), repeat=m)), dtype=float).reshape(2 ** m, m)
        brute = np.abs(h @ combos.T).max(axis=1)
        np.testing.assert_allclose(best, brute, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(np.abs(np.sum(signs * h, axis=-1)), best, rtol=1e-12, atol=1e-15)


def test_vectorized_over_any_shape():
    rng = np.random.default_rng(3)
    arm, _ = random_arm(rng, 4)
    sources, _ = random_sources(rng, arm, p=0.7)
    q = random_q(rng, arm, 6).reshape(2, 3, 4)
    b = max_serial_errors(arm, sources, q)
    assert b.dp_max.shape == (2, 3) and b.poses.shape == (2, 3, 3)
    for idx in np.ndindex(2, 3):
        one = max_serial_errors(arm, sources, q[idx])
        for name in ("dx_max", "dy_max", "dphi_max", "dp_max"):
            assert getattr(one, name) == pytest.approx(getattr(b, name)[idx], rel=1e-14)


# ---------------------------------------------------------------- closed forms

def two_r(L1=300.0, L2=200.0):
    return SerialArm((SerialJoint("R", L1, 0.0, (-3.0, 3.0)), SerialJoint("R", L2, 0.0, (-3.0, 3.0))), name="2r")


def test_2r_stretched_actuators_closed_form():
    e1, e2, L1, L2 = 2e-4, 5e-4, 300.0, 200.0
    src = SerialErrorSources((JointErrors(actuator=e1), JointErrors(actuator=e2)))
    b = max_serial_errors(two_r(L1, L2), src, np.zeros(2))
    assert b.dphi_max == pytest.approx(e1 + e2, rel=1e-15)
    assert b.dp_max == pytest.approx(e1 * (L1 + L2) + e2 * L2, rel=1e-15)
    assert b.dy_max == pytest.approx(e1 * (L1 + L2) + e2 * L2, rel=1e-15)
    assert b.dx_max == pytest.approx(0.0, abs=1e-15)


def test_single_radial_clearance_is_a_disk():
    rng = np.random.default_rng(5)
    eps = 0.013
    for k in range(2):
        joints = [JointErrors(), JointErrors()]
        joints[k] = JointErrors(radial=eps)
        b = max_serial_errors(two_r(), SerialErrorSources(tuple(joints)), rng.uniform(-3, 3, size=(4, 2)))
        np.testing.assert_allclose(b.dx_max, eps, rtol=1e-15)
        np.testing.assert_allclose(b.dy_max, eps, rtol=1e-15)
        np.testing.assert_allclose(b.dp_max, eps, rtol=1e-15)
        np.testing.assert_allclose(b.dphi_max, 0.0, atol=0)


def test_single_prismatic_guide_play_closed_form():
    """A P joint along x with a tool link l: guide play eps, block L -> dy = max(eps, 2 eps l / L), dphi = 2 eps / L."""
    eps, L, length, q = 0.004, 40.0, 120.0, 30.0
    arm = SerialArm((SerialJoint("P", length, 0.0, (0.0, 100.0)),), name="p")
    b = max_serial_errors(arm, SerialErrorSources((JointErrors(lateral=eps, block_length=L),)), np.array([q]))
    assert b.dphi_max == pytest.approx(2 * eps / L, rel=1e-15)
    assert b.dy_max == pytest.approx(max(eps, 2 * eps * length / L), rel=1e-15)
    assert b.dx_max == pytest.approx(0.0, abs=1e-15)
    assert b.dp_max == pytest.approx(b.dy_max, rel=1e-15)


def test_preset_arm_stretched_closed_form(capsys):
    """planar_3r_arm stretched along x with arm_typical: dy = sum e_k (distance to the tip) + 3 radial."""
    status, out, err = run(["bounds", "--robot", "planar_3r_arm", "--clearances", "arm_typical", "--joints", "0", "0",
                            "0", "--format", "json"], capsys)
    assert status == 0, err
    rec = json.loads(out)[0]
    assert list(rec) == ["x", "y", "phi_deg", "dx_max", "dy_max", "dphi_max_deg", "dp_max"]
    assert (rec["x"], rec["y"], rec["phi_deg"]) == (650.0, 0.0, 0.0)
    dy = 3e-4 * 650 + 3e-4 * 350 + 5e-4 * 100 + 3 * 0.005
    assert rec["dy_max"] == pytest.approx(dy, rel=1e-14)
    assert rec["dp_max"] == pytest.approx(dy, rel=1e-14)
    assert rec["dx_max"] == pytest.approx(3 * 0.005, rel=1e-14)
    assert rec["dphi_max_deg"] == pytest.approx(math.degrees(3e-4 + 3e-4 + 5e-4), rel=1e-14)


# ---------------------------------------------------------------- CLI

def run(argv, capsys):
    return run_cli(argv, capsys)


def write(path: Path, data) -> str:
    path.write_text(tomli_w.dumps(data))
    return str(path)


ARM = {"architecture": "serial", "name": "rpr_arm",
       "joints": [{"type": "R", "length": 200.0, "offset_deg": 10.0, "range": [-120.0, 120.0], "name": "base"},
                  {"type": "P", "length": 50.0, "offset_deg": -30.0, "range": [0.0, 150.0]},
                  {"type": "R", "length": 80.0, "range": [-180.0, 180.0]}]}
CLEAR = {"name": "c", "legs": [{"joints": [{"radial": 0.01, "actuator": 2e-4, "direction": 1e-4},
                                           {"actuator": 0.005, "angular": 3e-4, "lateral": 0.003, "block_length": 40.0,
                                            "length": 0.01},
                                           {"radial": 0.01, "actuator": 5e-4, "position": 0.002}]}]}


def test_cli_matches_library_in_every_format(tmp_path, capsys):
    robot, clear = write(tmp_path / "arm.toml", ARM), write(tmp_path / "c.toml", CLEAR)
    joints_cli = [[20.0, 40.0, -35.0], [-60.0, 120.0, 90.0]]
    arm = SerialArm.load(robot)
    q = np.array(joints_cli)
    q[:, [0, 2]] = np.radians(q[:, [0, 2]])
    lib = max_serial_errors(arm, load_serial_sources(clear, arm), q)
    argv = ["bounds", "--robot", robot, "--clearances", clear]
    for j in joints_cli:
        argv += ["--joints", *j]
    status, out, err = run(argv + ["--format", "json"], capsys)
    assert status == 0, err
    recs = json.loads(out)
    for name, col in lib.columns().items():
        np.testing.assert_allclose([r[name] for r in recs], col, rtol=1e-15)
    status, out, _ = run(argv + ["--format", "csv"], capsys)
    lines = out.strip().splitlines()
    assert lines[0] == "x,y,phi_deg,dx_max,dy_max,dphi_max_deg,dp_max" and len(lines) == 3
    assert [float(v) for v in lines[2].split(",")] == [float(c[1]) for c in lib.columns().values()]
    status, out, _ = run(argv + ["--format", "table"], capsys)
    assert status == 0 and out.split()[:7] == list(lib.columns())
    status, out, _ = run(argv + ["--format", "json", "--details"], capsys)
    rec = json.loads(out)[1]
    assert rec["joints"] == {"q1_deg": -60.0, "q2_mm": 120.0, "q3_deg": 90.0}
    assert set(rec["worst"]) == set(QUANTITIES)
    assert set(rec["worst"]["dp"]["joints[2].lateral"]) == {"sigma_mm", "tau_rad"}
    assert set(rec["worst"]["dx"]["joints[1].radial"]) == {"dx_mm", "dy_mm"}


def one_line_error(status, out, err, *needles):
    assert status == 2, (status, out, err)
    assert out == "" and err.count("\n") == 1 and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err


BAD_ARMS = {
    "no joints": (lambda d: d.update(joints=[]), "joints"),
    "missing joints": (lambda d: d.pop("joints"), "joints"),
    "bad type": (lambda d: d["joints"][1].update(type="Q"), "joints[2].type"),
    "missing type": (lambda d: d["joints"][0].pop("type"), "joints[1].type"),
    "empty range": (lambda d: d["joints"][2].update(range=[30.0, -30.0]), "joints[3].range"),
    "range not a pair": (lambda d: d["joints"][2].update(range=[30.0]), "joints[3].range"),
    "infinite length": (lambda d: d["joints"][0].update(length=math.inf), "joints[1].length"),
    "nan offset": (lambda d: d["joints"][1].update(offset_deg=math.nan), "joints[2].offset_deg"),
    "negative length": (lambda d: d["joints"][0].update(length=-5.0), "joints[1].length"),
    "unknown joint key": (lambda d: d["joints"][0].update(offset=3.0), "joints[1].offset"),
    "unknown top key": (lambda d: d.update(legs=[]), "legs"),
    "missing range": (lambda d: d["joints"][1].pop("range"), "joints[2].range"),
}


@pytest.mark.parametrize("case", BAD_ARMS)
def test_bad_robot_files_exit_2_naming_the_key(case, tmp_path, capsys):
    change, key = BAD_ARMS[case]
    data = json.loads(json.dumps(ARM))
    change(data)
    robot = tmp_path / "arm.toml"
    robot.write_text(tomli_w.dumps(data))
    clear = write(tmp_path / "c.toml", CLEAR)
    status, out, err = run(["bounds", "--robot", robot, "--clearances", clear, "--joints", 0, 10, 0], capsys)
    one_line_error(status, out, err, str(robot), key)
    with pytest.raises(ConfigError):
        SerialArm.load(str(robot))


BAD_CLEARANCES = {
    "angular on R": (lambda d: d["legs"][0]["joints"][0].update(angular=1e-3), "legs[1].joints[1].angular"),
    "lateral on R": (lambda d: d["legs"][0]["joints"][2].update(lateral=1e-3), "legs[1].joints[3].lateral"),
    "block_length on R": (lambda d: d["legs"][0]["joints"][0].update(block_length=30.0),
                          "legs[1].joints[1].block_length"),
    "too few joints": (lambda d: d["legs"][0]["joints"].pop(), "legs[1].joints"),
    "too many joints": (lambda d: d["legs"][0]["joints"].append({}), "legs[1].joints"),
    "negative": (lambda d: d["legs"][0]["joints"][1].update(actuator=-0.001), "legs[1].joints[2].actuator"),
    "nan": (lambda d: d["legs"][0]["joints"][2].update(radial=math.nan), "legs[1].joints[3].radial"),
    "zero block": (lambda d: d["legs"][0]["joints"][1].update(block_length=0.0), "legs[1].joints[2].block_length"),
    "unknown key": (lambda d: d["legs"][0]["joints"][1].update(backlash=0.1), "legs[1].joints[2].backlash"),
    "two legs": (lambda d: d["legs"].append({"joints": [{}, {}, {}]}), "legs"),
    "no legs": (lambda d: d.pop("legs"), "legs"),
    "3-PPR format": (lambda d: d.update(legs=[{"bearing_angle": 1e-3}]), "legs"),
}


@pytest.mark.parametrize("case", BAD_CLEARANCES)
def test_bad_clearance_files_exit_2_naming_the_key(case, tmp_path, capsys):
    change, key = BAD_CLEARANCES[case]
    data = json.loads(json.dumps(CLEAR))
    change(data)
    robot = write(tmp_path / "arm.toml", ARM)
    clear = write(tmp_path / "c.toml", data)
    status, out, err = run(["bounds", "--robot", robot, "--clearances", clear, "--joints", 0, 10, 0], capsys)
    one_line_error(status, out, err, str(clear), key)


def test_sources_object_checked_against_the_arm():
    arm = two_r()
    with pytest.raises(ClearanceError, match=r"legs\[1\]\.joints\[2\]\.angular"):
        max_serial_errors(arm, SerialErrorSources((JointErrors(), JointErrors(angular=1e-3))), np.zeros(2))
    with pytest.raises(ClearanceError, match=r"legs\[1\]\.joints"):
        max_serial_errors(arm, SerialErrorSources((JointErrors(),)), np.zeros(2))
    with pytest.raises(ClearanceError, match="radial"):
        max_serial_errors(arm, SerialErrorSources((JointErrors(radial=-1.0), JointErrors())), np.zeros(2))


def test_cli_refusals(tmp_path, capsys):
    robot, clear = write(tmp_path / "arm.toml", ARM), write(tmp_path / "c.toml", CLEAR)
    base = ["bounds", "--robot", robot, "--clearances", clear]
    one_line_error(*run(base + ["--pose", 0, 0, 0], capsys), "--pose", "--joints")
    one_line_error(*run(base + ["--joints", 0, 0, 0, "--poses-csv", "p.csv"], capsys), "--poses-csv")
    one_line_error(*run(base, capsys), "--joints Q1_DEG Q2_MM Q3_DEG")
    one_line_error(*run(base + ["--joints", 0, 0], capsys), "--joints", "3 joints")
    one_line_error(*run(base + ["--joints", 0, 200, 0], capsys), "joint 2", "outside")
    one_line_error(*run(base + ["--joints", 0, 0, 0, "--tolerances", "example_tolerances"], capsys), "--tolerances")
    one_line_error(*run(base + ["--joints", 0, 0, 0, "--method", "slsqp"], capsys), "slsqp")
    one_line_error(*run(["bounds", "--robot", robot, "--clearances", "case1", "--joints", 0, 0, 0], capsys), "case1",
                   "3-PPR")
    one_line_error(*run(["bounds", "--robot", "symmetric_3rpr", "--clearances", "rpr_typical", "--joints", 0, 0, 0],
                        capsys), "--joints", "parallel robot")
    status, out, err = run(base + ["--joints", 0, 200, 0, "--allow-outside", "--format", "json"], capsys)
    assert status == 0, err
    arm = SerialArm.load(robot)
    assert json.loads(out)[0]["x"] == pytest.approx(ref_fk([(j.kind, j.length, j.offset) for j in arm.joints],
                                                           [0.0, 200.0, 0.0])[0], abs=1e-9)


def test_library_refusals():
    arm = two_r()
    src = SerialErrorSources((JointErrors(actuator=1e-4), JointErrors()))
    with pytest.raises(OutsideJointLimitsError, match=r"configuration 2: joint 1"):
        max_serial_errors(arm, src, np.array([[0.0, 0.0], [3.5, 0.0]]))
    with pytest.raises(PoseError, match="not finite"):
        max_serial_errors(arm, src, np.array([0.0, np.nan]))
    with pytest.raises(PoseError, match="expected 2 joint values"):
        max_serial_errors(arm, src, np.zeros(3))


def test_robot_file_round_trip_and_presets(tmp_path):
    arm = SerialArm.from_dict(ARM, source="arm.toml")
    again = SerialArm.from_toml_string(arm.to_toml(), source="again.toml")
    assert again == arm
    preset = SerialArm.preset("planar_3r_arm")
    assert preset.kinds == "RRR" and [j.length for j in preset.joints] == [300.0, 250.0, 100.0]
    src = load_serial_sources("arm_typical", preset)
    assert len(src.joints) == 3
