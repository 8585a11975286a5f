"""Self-check of tests/reference/block_reference.py against hand-derived closed forms (no pmaccuracy import)."""

from __future__ import annotations

import cmath
import math

import numpy as np
import pytest

from block_reference import (closure_pose_error, reference_maxima, serial_pose,
                             serial_reference_maxima)

POSE = (10.0, -5.0, 0.1)
GAMMA = [math.pi / 2 + 2 * math.pi * i / 3 for i in range(3)]


def _jt(kind, actuated, link=0.0, block=None, offset=0.0):
    return {"kind": kind, "actuated": actuated, "offset": offset, "link": link, "block": block}


def _attach(i, pose=POSE):
    """Platform point r_i (platform frame) and its world position A_i."""
    r = 50 * cmath.exp(1j * (GAMMA[i] + 0.2))
    return r, complex(pose[0], pose[1]) + cmath.exp(1j * pose[2]) * r


def rpr_robot():
    """3-RPR, actuated P, every link zero; IK: q1 = arg(A - B), q2 = |A - B|, q3 = phi - q1."""
    legs, q = [], []
    for i in range(3):
        B = 200 * cmath.exp(1j * GAMMA[i])
        r, A = _attach(i)
        legs.append({"base": B, "base_angle": 0.0, "platform": r, "platform_angle": 0.0,
                     "joints": [_jt("R", False), _jt("P", True), _jt("R", False)]})
        q.append([cmath.phase(A - B), abs(A - B), POSE[2] - cmath.phase(A - B)])
    return legs, np.array(q)


def prr_leg(i, s=0.0, block=None, l=200.0):
    """Actuated P on a tangent rail (origin moved by s along it), R (link l), R."""
    a = GAMMA[i] + math.pi / 2
    e = cmath.exp(1j * a)
    B = 200 * cmath.exp(1j * GAMMA[i]) + s * e
    r, A = _attach(i)
    w = (A - B) / e
    t = w.real - math.sqrt(l * l - w.imag ** 2)
    q2 = cmath.phase(A - B - t * e) - a
    leg = {"base": B, "base_angle": a, "platform": r, "platform_angle": 0.0,
           "joints": [_jt("P", True, block=block), _jt("R", False, (l, 0.0)), _jt("R", False)]}
    return leg, [t, q2, POSE[2] - a - q2]


def rpr_passive_leg(i, s=0.0, block="carriage", l=30.0):
    """Actuated R, passive P (rail origin moved by s along it: link of joint 1 = s), R."""
    B = 200 * cmath.exp(1j * GAMMA[i])
    r, A = _attach(i)
    th = cmath.phase(A - B)
    leg = {"base": B, "base_angle": 0.0, "platform": r, "platform_angle": 0.0,
           "joints": [_jt("R", True, (s, 0.0)), _jt("P", False, (l, 0.0), block), _jt("R", False)]}
    return leg, [th, abs(A - B) - l - s, POSE[2] - th]


def mixed_robot(s=0.0, passive_block="carriage", act_block=None):
    parts = [prr_leg(0, s, act_block), rpr_passive_leg(1, s, passive_block), prr_leg(2, s, act_block)]
    return [p[0] for p in parts], np.array([p[1] for p in parts])


def full_clearances(legs):
    out = []
    for leg in legs:
        row = []
        for j, jt in enumerate(leg["joints"]):
            c = {"radial": [0.01, 0.02, 0.015][j]}
            if jt["actuated"]:
                c["actuator"] = 0.005 if jt["kind"] == "P" else 1e-4
            if jt["kind"] == "P":
                c.update(angular=5e-4, lateral=0.003, block_length=40.0)
            row.append(c)
        out.append(row)
    return out


def _dp_bruteforce(vecs, weights, n=400001):
    """max over directions u of sum_i w_i |u . v_i| (dense grid)."""
    th = np.linspace(0, math.pi, n)
    u = np.stack([np.cos(th), np.sin(th)])
    return float(np.max(sum(w * np.abs(v @ u) for v, w in zip(vecs, weights))))


# ---------------------------------------------------------------- serial closed forms

def test_serial_rotation_and_translation():
    j = [{"kind": "R", "offset": 0.3, "length": 100.0}]
    m = serial_reference_maxima(j, [0.2], [{"actuator": 1e-3}])
    assert m["dp"] == pytest.approx(0.1, rel=1e-9)          # tau * distance
    assert m["dphi"] == pytest.approx(1e-3, rel=1e-9)
    assert m["dx"] == pytest.approx(0.1 * math.sin(0.5), rel=1e-9)
    assert m["dy"] == pytest.approx(0.1 * math.cos(0.5), rel=1e-9)
    m = serial_reference_maxima(j, [0.2], [{"radial": 0.02}])
    assert (m["dp"], m["dx"], m["dy"]) == pytest.approx((0.02,) * 3, rel=1e-9)
    assert m["dphi"] == pytest.approx(0.0, abs=1e-14)
    # exact: a finite dq is a rotation about the joint centre
    p = serial_pose(j, [0.2], {(0, "dq"): 0.05})
    assert p == pytest.approx([100 * math.cos(0.55), 100 * math.sin(0.55), 0.55], abs=1e-12)


@pytest.mark.parametrize("block,dist", [("carriage", 30.0), ("bushing", 50.0)])
def test_serial_prismatic_tilt_about_block(block, dist):
    j = [{"kind": "P", "offset": 0.4, "length": 30.0, "block": block}]
    m = serial_reference_maxima(j, [20.0], [{"angular": 1e-3}])
    assert m["dp"] == pytest.approx(1e-3 * dist, rel=1e-9)
    assert m["dphi"] == pytest.approx(1e-3, rel=1e-9)
    m = serial_reference_maxima(j, [20.0], [{"actuator": 0.01, "radial": 0.02}])
    assert m["dp"] == pytest.approx(0.03, rel=1e-9)        # both along the rail at the worst direction


@pytest.mark.parametrize("length,factor", [(25.0, 1.0), (100.0, 4.0), (10.0, 1.0)])
def test_serial_lateral_rhombus(length, factor):
    # shift sigma n + tau * length n: support over the rhombus = max(eps, 2 eps length / L)
    j = [{"kind": "P", "offset": -0.7, "length": length}]
    m = serial_reference_maxima(j, [0.0], [{"lateral": 0.004, "block_length": 50.0}])
    assert m["dp"] == pytest.approx(0.004 * factor, rel=1e-9)
    assert m["dphi"] == pytest.approx(2 * 0.004 / 50.0, rel=1e-9)


@pytest.mark.parametrize("q2", [0.0, math.pi / 2, 1.0])
def test_serial_two_r_direction_search(q2):
    j = [{"kind": "R", "offset": 0.0, "length": 100.0}, {"kind": "R", "offset": 0.0, "length": 60.0}]
    q = [0.3, q2]
    m = serial_reference_maxima(j, q, [{"actuator": 1e-3}, {"actuator": 2e-3}])
    p = complex(*serial_pose(j, q)[:2])
    c2 = 100 * cmath.exp(0.3j)
    v1, v2 = 1j * p * 1e-3, 1j * (p - c2) * 2e-3
    assert m["dp"] == pytest.approx(max(abs(v1 + v2), abs(v1 - v2)), rel=1e-9)
    assert m["dphi"] == pytest.approx(3e-3, rel=1e-9)


# ---------------------------------------------------------------- parallel: 3-RPR closed form

def _rpr_inverse_map(legs, q):
    """Hand first-order map: n_i . (dp + dphi i R r_i) = d rho_i  =>  dpose = M^-1 d rho."""
    M = []
    for leg, qi in zip(legs, q):
        n = cmath.exp(1j * qi[0])
        Rr = cmath.exp(1j * POSE[2]) * leg["platform"]
        M.append([n.real, n.imag, (n.conjugate() * 1j * Rr).real])
    return np.linalg.inv(np.array(M))


def test_rpr_nominal_and_exact_translation():
    legs, q = rpr_robot()
    assert closure_pose_error(legs, POSE, q, {}) == pytest.approx(np.zeros(3), abs=1e-12)
    for j in (0, 2):   # same shift of every leg's distal part at its first / last joint: pure translation
        d = closure_pose_error(legs, POSE, q, {(i, j, "shift"): 0.3 - 0.2j for i in range(3)})
        assert d == pytest.approx([0.3, -0.2, 0.0], abs=1e-12)
    dq = np.array([1e-4, -2e-4, 3e-4])
    d = closure_pose_error(legs, POSE, q, {(i, 1, "dq"): dq[i] for i in range(3)})
    assert d == pytest.approx(_rpr_inverse_map(legs, q) @ dq, abs=1e-9)
    with pytest.raises(ValueError):
        closure_pose_error(legs, POSE, q + 1e-3, {})


def test_rpr_maxima_against_hand_map():
    legs, q = rpr_robot()
    Minv = _rpr_inverse_map(legs, q)
    rad, act = [0.01, 0.02, 0.015], [0.005, 0.007, 0.003]
    cl = [[{"radial": rad[0]}, {"radial": rad[1], "actuator": act[i], "angular": 1e-3},
           {"radial": rad[2]}] for i in range(3)]
    m = reference_maxima(legs, POSE, q, cl)
    w = np.array([sum(rad) + a for a in act])     # all sources of leg i act through n_i . (.)
    for r, k in enumerate(("dx", "dy", "dphi")):
        assert m[k] == pytest.approx(float(np.sum(w * np.abs(Minv[r]))), rel=1e-8)
    assert m["dp"] == pytest.approx(_dp_bruteforce(Minv[:2].T, w), rel=1e-8)


# ---------------------------------------------------------------- parallel: invariances

def test_rail_origin_moved_along_rail_is_the_same_robot():
    legs, q = mixed_robot()
    assert closure_pose_error(legs, POSE, q, {}) == pytest.approx(np.zeros(3), abs=1e-11)
    ref = reference_maxima(legs, POSE, q, full_clearances(legs))
    legs2, q2 = mixed_robot(s=7.5)
    moved = reference_maxima(legs2, POSE, q2, full_clearances(legs2))
    for k in ref:
        assert moved[k] == pytest.approx(ref[k], rel=1e-9)
    vals = {(1, 1, "tilt"): 2e-3, (0, 0, "tau"): 1e-3, (2, 0, "sigma"): 0.05, (1, 1, "sigma"): 0.02}
    assert closure_pose_error(legs2, POSE, q2, vals) == pytest.approx(
        closure_pose_error(legs, POSE, q, vals), abs=1e-11)
    # a bushing sits at the rail origin: moving the origin changes the robot
    lb, qb = mixed_robot(passive_block="bushing")
    lb2, qb2 = mixed_robot(s=7.5, passive_block="bushing")
    assert reference_maxima(lb2, POSE, qb2, full_clearances(lb2))["dp"] != pytest.approx(
        reference_maxima(lb, POSE, qb, full_clearances(lb))["dp"], rel=1e-6)
