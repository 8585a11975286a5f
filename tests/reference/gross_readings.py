"""Gross readings for the robust-identification tests (written apart from pmaccuracy.accuracy.calibration):
a calibration data set of a random robot measured by the exact forward kinematics, and a seeded corruption
of up to a tenth of its points by a wrong position, orientation or command reading.

The size of a command error is judged by its effect on the true robot's pose (its exact forward kinematics,
:func:`pmaccuracy.accuracy.calibration.simulate.measure` without noise): at least ``min_sigma`` stated
sigmas, the command kept within its actuator's range.
"""

from __future__ import annotations

import math

import numpy as np

from calibration_reference import random_robot_dict
from pmaccuracy.accuracy.calibration.data import CalibrationData
from pmaccuracy.accuracy.calibration.parameters import actuators, error_parameters
from pmaccuracy.accuracy.calibration.plan import candidate_poses, plan_poses
from pmaccuracy.accuracy.calibration.simulate import measure, true_parameters
from pmaccuracy.model.manipulator import Manipulator

SIGMA = np.array([0.01, 0.01, math.radians(0.01)])
MAX_MM = 50.0
MAX_RAD = math.radians(20.0)


def calibration_case(name: str, seed: int, n: int = 40):
    """``(pv, true, data, reference)``: a random robot of preset ``name`` (seed ``seed``), ``n`` planned
    points of the true robot measured with noise :data:`SIGMA` (the stated sigmas), the nominal poses."""
    table = random_robot_dict(Manipulator.preset(name).to_dict(), np.random.default_rng(seed))
    pv = error_parameters(Manipulator.from_dict(table))
    plan = plan_poses(pv, n, candidate_poses(pv), seed=seed)
    true = true_parameters(pv, seed=seed + 1, fixed=("frame.x", "frame.y", "frame.phi"))
    meas = measure(pv, true, plan.commands, plan.poses, noise=SIGMA, seed=seed + 2)
    ok = np.all(np.isfinite(meas), axis=1)
    data = CalibrationData(tuple(f"p{i + 1}" for i in range(int(ok.sum()))), plan.commands[ok], meas[ok],
                           np.tile(SIGMA, (int(ok.sum()), 1)), "<sim>")
    return pv, true, data, plan.poses[ok]


def _loguniform(rng, lo, hi):
    return float(np.exp(rng.uniform(math.log(lo), math.log(hi))))


def corrupt(pv, true, data: CalibrationData, reference, rng, fraction: float = 0.1, min_sigma: float = 10.0,
            kinds=("position", "orientation", "command")):
    """A copy of ``data`` with ``round(fraction * N)`` points made gross (a kind drawn from ``kinds`` for
    each): a position reading moved by 10 sigma to 50 mm in a random direction, an orientation reading turned
    by 10 sigma to 20 deg, or one command moved by up to 20 deg / 50 mm (at least ``min_sigma`` sigmas of
    pose effect on the true robot), within its actuator's range. Returns the data and the rows (0-based)
    made gross with their kinds."""
    n_bad = int(round(fraction * len(data)))
    rows = rng.choice(len(data), n_bad, replace=False)
    poses, cmds = data.poses.copy(), data.commands.copy()
    acts = actuators(pv.robot)
    made = {}
    for row in rows:
        kind = kinds[int(rng.integers(len(kinds)))]
        if kind == "position":
            d = _loguniform(rng, min_sigma * SIGMA[0], MAX_MM)
            a = rng.uniform(0, 2 * math.pi)
            poses[row, :2] += d * np.array([math.cos(a), math.sin(a)])
        elif kind == "orientation":
            poses[row, 2] += rng.choice([-1.0, 1.0]) * _loguniform(rng, min_sigma * SIGMA[2], MAX_RAD)
        else:
            k = int(rng.integers(cmds.shape[1]))
            kind_k, (lo, hi) = acts[k]
            top = MAX_RAD if kind_k == "R" else MAX_MM
            for _ in range(40):
                step = rng.choice([-1.0, 1.0]) * _loguniform(rng, top * 1e-4, top)
                c = cmds[row].copy()
                c[k] += step
                if not lo <= c[k] <= hi:
                    continue
                p = measure(pv, true, c[None], reference[row][None], noise=(0, 0, 0))[0]
                q = measure(pv, true, cmds[row][None], reference[row][None], noise=(0, 0, 0))[0]
                effect = np.abs(p - q) / SIGMA
                if not np.all(np.isfinite(effect)) or np.sqrt(np.sum(effect ** 2)) >= min_sigma:
                    cmds[row] = c
                    break
            else:
                continue
        made[int(row)] = kind
    return CalibrationData(data.labels, cmds, poses, data.sigmas, data.source), made
