"""Independent references for the calibration tests (written apart from pmaccuracy.accuracy.calibration).

* :func:`rrr_actuated_angle`: closed-form inverse kinematics of one R-R-R leg from its geometry, from the
  circle-circle intersection (no chain code).
* :func:`random_robot_dict`: a robot file of a preset with its points and lengths moved at random (seeded),
  so the tests run on robots nobody tuned.
"""

from __future__ import annotations

import copy
import math

import numpy as np


def rrr_actuated_angle(base, platform, proximal, distal, mode, pose):
    """Angle (rad) of A->B for the leg with base point A, platform point d (platform frame), link lengths and
    working mode sign(cross(B - A, D - B)), at pose (x, y, phi); NaN out of reach."""
    x, y, phi = pose
    c, s = math.cos(phi), math.sin(phi)
    D = np.array([x + c * platform[0] - s * platform[1], y + s * platform[0] + c * platform[1]])
    A = np.array(base, dtype=float)
    v = D - A
    L = math.hypot(*v)
    cos_a = (proximal ** 2 + L ** 2 - distal ** 2) / (2 * proximal * L)
    if abs(cos_a) > 1:
        return math.nan
    a = math.acos(cos_a)
    base_dir = math.atan2(v[1], v[0])
    for cand in (base_dir + a, base_dir - a):
        B = A + proximal * np.array([math.cos(cand), math.sin(cand)])
        u, w = B - A, D - B
        if np.sign(u[0] * w[1] - u[1] * w[0]) == mode:
            return math.atan2(math.sin(cand), math.cos(cand))
    return math.nan


def random_robot_dict(table: dict, rng: np.random.Generator, move_mm: float = 3.0, move_deg: float = 3.0) -> dict:
    """A copy of a robot-file table with every point and length of its legs moved by up to ``move_mm`` (the
    3-PPR's ``a``, ``d``, ``r`` too) and every angle of its legs (``*_deg``: a 3-PPR's ``alpha_deg``,
    ``psi_deg`` and slide angles ``beta_deg``, ``gamma_deg``, ``theta_deg``, a guide's ``guide_deg``) turned
    by up to ``move_deg``. Turned slides are no longer perpendicular: a 3-PPR leg's ``a`` then changes the
    residuals only through that small turn, and the identification must fix it as practically
    unidentifiable (a predicted sigma of metres) rather than let the fit wander along it."""
    out = copy.deepcopy(table)
    out["name"] = "random"
    for leg in out["legs"]:
        for key, value in leg.items():
            if key in ("base", "platform", "guide_point"):
                leg[key] = [float(v + rng.uniform(-move_mm, move_mm)) for v in value]
            elif key in ("proximal", "distal", "a", "d", "r"):
                leg[key] = float(value + rng.uniform(-move_mm, move_mm))
            elif key.endswith("_deg") and isinstance(value, (int, float)):
                leg[key] = float(value + rng.uniform(-move_deg, move_deg))
    return out
