"""Independent reference model of the spatial parallel robots (6-UPS, delta, 3-RPS, 3-PRS, 3-UPU); tests only.

Written from ``docs/guide/spatial.md`` alone (numpy, scipy); it does not import ``pmaccuracy``. The style
is deliberately plain: one pose at a time, loops over the legs, finite differences for every Jacobian and
``scipy.optimize`` for every implicit equation, so that the library's vectorized closed forms are checked
against something that shares none of their code.

A robot is the parsed TOML dictionary of the file format (``tomllib.load``). Inside Python lengths are in
mm and angles in rad; a pose is ``(position (3,), R (3, 3))`` with ``B = position + R b`` for a platform
point ``b``.

Conventions this module had to choose where the document is silent
---------------------------------------------------------------------
* **Defaults** (:func:`legs`): ``base_normal = [0, 0, 1]``; ``platform_normal = [0, 0, -1]`` except for the
  Delta (``[0, 0, 1]``); cones absent = no limit (stored as ``None``); ``radius`` (Delta: ``arm_radius``,
  ``rod_radius``) = 0. Every direction (``axis``, ``slide``, ``zero``, ``base_axis``, ``platform_axis``,
  ``base_normal``, ``platform_normal``) is normalized; a zero direction raises ``ValueError``. The Delta's
  ``zero`` is additionally made exactly perpendicular to ``axis`` (its component along ``axis`` removed, then
  normalized) so that the arm circle has radius ``arm``.
* **3-UPU parallel axes**: ``platform_axis`` must be parallel *or antiparallel* to ``base_axis`` (the joint
  axis is a line), both normalized, ``|base_axis x platform_axis| <= 1e-6``; otherwise ``ValueError``. The
  comparison is made in the platform's home orientation, i.e. with the platform frame aligned with the base
  frame (a 3-UPU's orientation is always the identity).
* **Leg segments and cones.** 6-UPS, 3-RPS, 3-UPU: the leg runs from the base joint centre ``A = base`` to the
  platform joint centre ``B``. 3-PRS: the leg is the rod from the revolute centre ``C = base + q slide`` to
  ``B`` (the base cone, if given, is at ``C``: the prismatic joint has no cone). Delta: both rods of a leg have
  the direction ``C - B`` (a parallelogram), so the platform cone is checked once per leg with ``C - B``.
  Base cone angle = ``angle(leg from base joint to platform joint, base_normal)``; platform cone angle =
  ``angle(leg from platform joint to base joint, R platform_normal)``; a limit holds when angle <= cone.
* **Revolute angle** (3-RPS, 3-PRS): ``atan2(axis . (n x d), n . d)`` with ``n = base_normal`` and ``d`` the
  leg (3-RPS: ``B - A``; 3-PRS: the rod ``B - C``). This is the signed angle of the projections onto the plane
  normal to ``axis`` when ``n`` is perpendicular to ``axis`` (the recommended use).
* **Delta arm angle**: in ``(-pi, pi]``; ``angle_range_deg`` is compared with this value (a range crossing
  +-180 deg would need wrapping, not supported). The closed form is
  ``theta = phi - mode * acos(K / rho)`` with ``e = B - A``, ``u = zero``, ``w = axis x zero``,
  ``rho = |(e.u, e.w)|``, ``phi = atan2(e.w, e.u)``, ``K = (|e|^2 + arm^2 - rod^2) / (2 arm)``;
  NaN when ``|K| > rho``.
* **3-PRS** ``q = s.e - mode sqrt((s.e)^2 - |e|^2 + rod^2)``; NaN when the square root's argument < 0.
* **Limits are inclusive** (``lo <= value <= hi``, angle <= cone). Strokes, ranges in the file units
  (mm, deg); the comparison is made in those units.
* **Interference**: segment pairs of *different* legs are checked only when *both* segments have a radius
  > 0 (a radius of 0 means "not checked"); they interfere when distance < r1 + r2 (strict). Delta segments:
  arm ``A -> C`` (``arm_radius``), rods ``C +- spacing/2 axis -> B +- spacing/2 axis`` (``rod_radius``).
  Segment-to-segment distance: the classic clamped closest-point formula (:func:`segment_distance`).
* **Unreachable**: an actuator value NaN makes :func:`within_limits` False (report line "unreachable").
* **Report lines**: ``"leg {i}: ..."`` with 1-based leg numbers and ``"legs {i} and {j}: interference ..."``.
* **complete_pose** takes roll and pitch in **radians** (Python convention); for a Delta / 3-UPU its three
  coordinates are ``x, y, z`` (mm). It is not defined for a 6-UPS.
* **forward** solves the closure equations (6-UPS, 3-RPS, 3-UPU: ``|B - A| - q``; 3-PRS:
  ``|B - base - q slide| - rod``; Delta: ``|B - C(q)| - rod``) together with the constraints, over the
  position and a rotation-vector increment ``d`` (``R = expm([d]x) R_guess``), then checks that
  ``actuators(solution) == q`` (this also checks the 3-PRS / Delta mode); a mismatch raises RuntimeError.
* **monte_carlo_volume** for 3-RPS / 3-PRS samples ``(z mm, roll deg, pitch deg)`` in ``box`` and completes
  the pose: the volume is in **mm deg^2**; ``orientation_R`` is then ignored. For the other architectures it
  samples positions ``(x, y, z)`` with the orientation fixed, volume in mm^3. A sample counts when the pose can
  be completed (3-RPS/3-PRS), no actuator is NaN and :func:`within_limits` holds. The standard error is
  ``V_box sqrt(f (1 - f) / n)``.
* **parallel_singularity_measure**: the matrix ``[inverse_jacobian_fd; constraint_jacobian_fd]`` (6 x 6),
  the angular columns divided by the characteristic length ``L = rms_i |b_i|`` (platform joint points; 1 mm
  if all zero), i.e. the twist is taken as ``[v, L w]``; each row then normalized to unit length; the measure
  is its smallest singular value (0 at a parallel singularity, <= 1). 6-UPS: the 6 actuator rows only.
  Because the Delta / 3-UPU constraint rows are the rotation vector (pure couples), this measure does not see
  constraint singularities of those robots; :func:`screw_singularity_measure` (below) does.
* **screw_singularity_measure**: a second derivation from screw theory, not from finite differences: per leg
  the wrenches reciprocal to its passive joint twists (6-UPS: U at A with axes ``base_axis`` (or any axis
  normal to the leg) and ``base_axis x leg``, S at B; 3-RPS: R at A about ``axis``, S at B; 3-PRS: R at C about
  ``axis``, S at B; 3-UPU: outer axis ``base_axis`` at A, inner axis ``base_axis x leg`` at A and at B, outer
  ``R platform_axis`` at B; Delta: the two rod forces, along ``(B +- R spacing/2 axis) - (C +- spacing/2 axis)``),
  stacked (6 x 6), moments over ``L``, rows unit, smallest singular value.
* **Delta actuators away from R = I** (used by the finite-difference inverse / constraint Jacobians): the arm
  angle of the leg's midpoint ``B = p + R b`` (the two rods are not separately closed when R != I).
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

ARCHITECTURES = ("6-UPS", "delta", "3-RPS", "3-PRS", "3-UPU")
DATA = Path(__file__).resolve().parents[1] / "data" / "spatial"
FILES = {
    "6-UPS": "ref_hexapod.toml",
    "delta": "ref_delta.toml",
    "3-RPS": "ref_3rps.toml",
    "3-PRS": "ref_3prs.toml",
    "3-UPU": "ref_3upu.toml",
}
N_LEGS = {"6-UPS": 6, "delta": 3, "3-RPS": 3, "3-PRS": 3, "3-UPU": 3}


# ----------------------------------------------------------------------------------------------------------
# rotations (own formulas; scipy only to convert in the helpers named so)
# ----------------------------------------------------------------------------------------------------------


def _rx(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rotation_rad(roll, pitch, yaw):
    """``Rz(yaw) Ry(pitch) Rx(roll)`` (extrinsic x-y-z), angles in rad."""
    return _rz(yaw) @ _ry(pitch) @ _rx(roll)


def rotation(orientation_deg_xyz):
    """3x3 matrix of ``[roll, pitch, yaw]`` in degrees, extrinsic x-y-z."""
    r, p, y = (math.radians(float(a)) for a in orientation_deg_xyz)
    return rotation_rad(r, p, y)


def orientation_deg(R):
    """``[roll, pitch, yaw]`` (deg, extrinsic x-y-z) of a matrix (scipy conversion)."""
    return Rotation.from_matrix(R).as_euler("xyz", degrees=True)


def skew(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def expm_so3(w):
    """Rodrigues: ``expm([w]x)``."""
    w = np.asarray(w, float)
    th = float(np.linalg.norm(w))
    K = skew(w)
    if th < 1e-8:
        return np.eye(3) + K + 0.5 * K @ K
    return np.eye(3) + math.sin(th) / th * K + (1.0 - math.cos(th)) / th**2 * K @ K


def rotvec(R):
    """Rotation vector of a rotation matrix (scipy conversion)."""
    return Rotation.from_matrix(np.asarray(R, float)).as_rotvec()


def from_rotvec(v):
    return expm_so3(v)


def pose_vector(position, R):
    """The library's pose array ``[x, y, z, rotvec]`` (6,)."""
    return np.concatenate([np.asarray(position, float), rotvec(R)])


# ----------------------------------------------------------------------------------------------------------
# robot description
# ----------------------------------------------------------------------------------------------------------


def load(path) -> dict:
    with open(path, "rb") as fh:
        return tomllib.load(fh)


def load_reference(architecture) -> dict:
    return load(DATA / FILES[architecture])


def _unit(v, what):
    v = np.asarray(v, float)
    n = float(np.linalg.norm(v))
    if v.shape != (3,) or not n > 0.0:
        raise ValueError(f"{what} must be a nonzero 3-vector, got {v}")
    return v / n


def _opt(leg, key):
    return None if leg.get(key) is None else float(leg[key])


def legs(robot: dict) -> list[dict]:
    """The legs with the document's defaults applied and every direction normalized."""
    arch = robot["architecture"]
    if arch not in ARCHITECTURES:
        raise ValueError(f"unknown architecture {arch!r}")
    raw = robot["legs"]
    if len(raw) != N_LEGS[arch]:
        raise ValueError(f"{arch} needs {N_LEGS[arch]} legs, got {len(raw)}")
    out = []
    for i, lg in enumerate(raw):
        d = {
            "base": np.asarray(lg["base"], float),
            "platform": np.asarray(lg["platform"], float),
            "base_normal": _unit(lg.get("base_normal", [0.0, 0.0, 1.0]), f"leg {i + 1} base_normal"),
            "platform_normal": _unit(
                lg.get("platform_normal", [0.0, 0.0, 1.0] if arch == "delta" else [0.0, 0.0, -1.0]),
                f"leg {i + 1} platform_normal",
            ),
            "base_cone_deg": _opt(lg, "base_cone_deg"),
            "platform_cone_deg": _opt(lg, "platform_cone_deg"),
            "radius": float(lg.get("radius", 0.0)),
        }
        if arch in ("6-UPS", "3-RPS", "3-UPU"):
            d["stroke"] = tuple(float(x) for x in lg["stroke"])
        if arch == "6-UPS" and "base_axis" in lg:
            d["base_axis"] = _unit(lg["base_axis"], f"leg {i + 1} base_axis")
        if arch == "3-RPS":
            d["axis"] = _unit(lg["axis"], f"leg {i + 1} axis")
            d["angle_range_deg"] = tuple(float(x) for x in lg["angle_range_deg"]) if "angle_range_deg" in lg else None
        if arch == "3-PRS":
            d["slide"] = _unit(lg["slide"], f"leg {i + 1} slide")
            d["stroke"] = tuple(float(x) for x in lg["stroke"])
            d["axis"] = _unit(lg["axis"], f"leg {i + 1} axis")
            d["rod"] = float(lg["rod"])
            d["mode"] = int(lg["mode"])
            if d["mode"] not in (1, -1):
                raise ValueError("mode must be +1 or -1")
            d["angle_range_deg"] = tuple(float(x) for x in lg["angle_range_deg"]) if "angle_range_deg" in lg else None
        if arch == "3-UPU":
            d["base_axis"] = _unit(lg["base_axis"], f"leg {i + 1} base_axis")
            d["platform_axis"] = _unit(lg["platform_axis"], f"leg {i + 1} platform_axis")
            if np.linalg.norm(np.cross(d["base_axis"], d["platform_axis"])) > 1e-6:
                raise ValueError(f"leg {i + 1}: platform_axis not parallel to base_axis (Tsai's condition)")
        if arch == "delta":
            a = _unit(lg["axis"], f"leg {i + 1} axis")
            z = np.asarray(lg["zero"], float)
            z = _unit(z - (z @ a) * a, f"leg {i + 1} zero (perpendicular to axis)")
            d.update(
                axis=a,
                zero=z,
                arm=float(lg["arm"]),
                rod=float(lg["rod"]),
                spacing=float(lg["spacing"]),
                angle_range_deg=tuple(float(x) for x in lg["angle_range_deg"]),
                mode=int(lg["mode"]),
                arm_radius=float(lg.get("arm_radius", 0.0)),
                rod_radius=float(lg.get("rod_radius", 0.0)),
            )
            if d["mode"] not in (1, -1):
                raise ValueError("mode must be +1 or -1")
        out.append(d)
    return out


def home(robot: dict):
    h = robot.get("home", {})
    p = np.asarray(h.get("position", [0.0, 0.0, 0.0]), float)
    R = rotation(h.get("orientation_deg", [0.0, 0.0, 0.0]))
    return p, R


def n_actuators(robot):
    return N_LEGS[robot["architecture"]]


def n_constraints(robot):
    return {"6-UPS": 0, "3-RPS": 3, "3-PRS": 3, "delta": 3, "3-UPU": 3}[robot["architecture"]]


# ----------------------------------------------------------------------------------------------------------
# inverse kinematics, leg by leg
# ----------------------------------------------------------------------------------------------------------


def _B(leg, position, R):
    return np.asarray(position, float) + np.asarray(R, float) @ leg["platform"]


def _prs_q(leg, B):
    e = B - leg["base"]
    se = float(leg["slide"] @ e)
    disc = se * se - float(e @ e) + leg["rod"] ** 2
    if disc < 0.0:
        return math.nan
    return se - leg["mode"] * math.sqrt(disc)


def _delta_theta(leg, B):
    e = B - leg["base"]
    u = leg["zero"]
    w = np.cross(leg["axis"], u)
    eu, ew = float(e @ u), float(e @ w)
    rho = math.hypot(eu, ew)
    K = (float(e @ e) + leg["arm"] ** 2 - leg["rod"] ** 2) / (2.0 * leg["arm"])
    if rho == 0.0 or abs(K) > rho:
        return math.nan
    th = math.atan2(ew, eu) - leg["mode"] * math.acos(K / rho)
    # wrap into (-pi, pi]
    th = math.atan2(math.sin(th), math.cos(th))
    if th == -math.pi:
        th = math.pi
    return th


def _delta_elbow(leg, theta):
    u = leg["zero"]
    w = np.cross(leg["axis"], u)
    return leg["base"] + leg["arm"] * (math.cos(theta) * u + math.sin(theta) * w)


def actuators(robot, position, R) -> np.ndarray:
    """Actuated joint values: lengths (mm), 3-PRS slide q (mm), Delta arm angles (rad); NaN if unreachable."""
    arch = robot["architecture"]
    out = []
    for leg in legs(robot):
        B = _B(leg, position, R)
        if arch in ("6-UPS", "3-RPS", "3-UPU"):
            out.append(float(np.linalg.norm(B - leg["base"])))
        elif arch == "3-PRS":
            out.append(_prs_q(leg, B))
        else:
            out.append(_delta_theta(leg, B))
    return np.array(out)


def constraint_residuals(robot, position, R) -> np.ndarray:
    arch = robot["architecture"]
    if arch == "6-UPS":
        return np.zeros(0)
    if arch in ("delta", "3-UPU"):
        return rotvec(R)
    return np.array([float(leg["axis"] @ (_B(leg, position, R) - leg["base"])) for leg in legs(robot)])


def _closure(robot, q, position, R):
    arch = robot["architecture"]
    res = []
    for k, leg in enumerate(legs(robot)):
        B = _B(leg, position, R)
        if arch in ("6-UPS", "3-RPS", "3-UPU"):
            res.append(np.linalg.norm(B - leg["base"]) - q[k])
        elif arch == "3-PRS":
            res.append(np.linalg.norm(B - leg["base"] - q[k] * leg["slide"]) - leg["rod"])
        else:
            res.append(np.linalg.norm(B - _delta_elbow(leg, q[k])) - leg["rod"])
    return np.array(res)


# ----------------------------------------------------------------------------------------------------------
# poses
# ----------------------------------------------------------------------------------------------------------


def complete_pose(robot, c1, c2, c3):
    """3-RPS / 3-PRS: ``(z, roll, pitch)`` (mm, rad, rad) -> pose with the parasitic x, y, yaw solved from
    x = y = yaw = 0. Delta / 3-UPU: ``(x, y, z)`` -> ``(position, I)``. Raises RuntimeError if not solved."""
    arch = robot["architecture"]
    if arch in ("delta", "3-UPU"):
        return np.array([c1, c2, c3], float), np.eye(3)
    if arch not in ("3-RPS", "3-PRS"):
        raise ValueError(f"complete_pose is not defined for {arch}")
    z, roll, pitch = float(c1), float(c2), float(c3)

    def f(u):
        x, y, yaw = u
        return constraint_residuals(robot, [x, y, z], rotation_rad(roll, pitch, yaw))

    sol = least_squares(f, np.zeros(3), method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15, x_scale=[100.0, 100.0, 1.0])
    x, y, yaw = sol.x
    if np.max(np.abs(f(sol.x))) > 1e-9:
        raise RuntimeError("parasitic motion not solved")
    return np.array([x, y, z]), rotation_rad(roll, pitch, yaw)


def forward(robot, q, guess_position, guess_R):
    """Forward kinematics from a guess by least squares over (position, rotation-vector increment)."""
    q = np.asarray(q, float)
    p0 = np.asarray(guess_position, float)
    R0 = np.asarray(guess_R, float)
    # closures in mm and 3-RPS/3-PRS constraints in mm are scaled by 1/100 mm; rotation vectors stay in rad
    cscale = 0.01 if robot["architecture"] in ("3-RPS", "3-PRS") else 1.0

    def pose(u):
        return u[:3], expm_so3(u[3:]) @ R0

    def f(u):
        p, R = pose(u)
        return np.concatenate([0.01 * _closure(robot, q, p, R), cscale * constraint_residuals(robot, p, R)])

    u0 = np.concatenate([p0, np.zeros(3)])
    sol = least_squares(f, u0, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15, x_scale=[100.0] * 3 + [1.0] * 3)
    p, R = pose(sol.x)
    qq = actuators(robot, p, R)
    if not np.all(np.abs(qq - q) < 1e-8) or np.max(np.abs(f(sol.x))) > 1e-9:
        raise RuntimeError(f"forward kinematics not solved: {qq - q}")
    return np.array(p), R


# ----------------------------------------------------------------------------------------------------------
# Jacobians by finite differences
# ----------------------------------------------------------------------------------------------------------


def jacobian_fd(robot, position, R, h=1e-6):
    """(6, n_act): twist [v, w] per unit actuator rate, by central differences of :func:`forward`."""
    position = np.asarray(position, float)
    R = np.asarray(R, float)
    q0 = actuators(robot, position, R)
    n = len(q0)
    J = np.zeros((6, n))
    for k in range(n):
        dq = np.zeros(n)
        dq[k] = h
        pp, Rp = forward(robot, q0 + dq, position, R)
        pm, Rm = forward(robot, q0 - dq, position, R)
        J[:3, k] = (pp - pm) / (2 * h)
        J[3:, k] = rotvec(Rp @ Rm.T) / (2 * h)
    return J


def _twist_fd(fun, position, R, h):
    position = np.asarray(position, float)
    R = np.asarray(R, float)
    cols = []
    for j in range(6):
        t = np.zeros(6)
        t[j] = h
        fp = fun(position + t[:3], expm_so3(t[3:]) @ R)
        fm = fun(position - t[:3], expm_so3(-t[3:]) @ R)
        cols.append((fp - fm) / (2 * h))
    return np.array(cols).T


def inverse_jacobian_fd(robot, position, R, h=1e-6):
    """(n_act, 6): d q / d t by central differences of :func:`actuators` along the six unit twists."""
    return _twist_fd(lambda p, RR: actuators(robot, p, RR), position, R, h).reshape(n_actuators(robot), 6)


def constraint_jacobian_fd(robot, position, R, h=1e-6):
    """(n_constraints, 6): d constraint_residuals / d t."""
    return _twist_fd(lambda p, RR: constraint_residuals(robot, p, RR), position, R, h).reshape(n_constraints(robot), 6)


def characteristic_length(robot):
    pts = np.array([leg["platform"] for leg in legs(robot)])
    L = float(np.sqrt(np.mean(np.sum(pts**2, axis=1))))
    return L if L > 0 else 1.0


def singularity_matrix(robot, position, R, h=1e-6):
    M = np.vstack([inverse_jacobian_fd(robot, position, R, h), constraint_jacobian_fd(robot, position, R, h)])
    M = M.copy()
    M[:, 3:] /= characteristic_length(robot)
    for i in range(M.shape[0]):
        M[i] /= np.linalg.norm(M[i])
    return M


def parallel_singularity_measure(robot, position, R, h=1e-6):
    """Smallest singular value of the row-normalized stacked [actuation; constraint] matrix (see module)."""
    return float(np.linalg.svd(singularity_matrix(robot, position, R, h), compute_uv=False)[-1])


def _null_rows(T, tol=1e-9):
    """Orthonormal basis (rows) of the wrenches [f, m] reciprocal to the twists [v, w] in the rows of ``T``:
    ``f . v + m . w = 0``, i.e. the null space of ``T @ swap`` with the pairing matrix swap = identity here
    because twists are stored as [v, w] and wrenches as [f, m] (power f.v + m.w is the plain dot product)."""
    T = np.atleast_2d(np.asarray(T, float))
    _, sv, Vt = np.linalg.svd(T)
    rank = int(np.sum(sv > tol * max(1.0, sv[0])))
    return Vt[rank:]


def _rot_twist(point, direction, P):
    """Unit twist [v_P, w] of a rotation about the line through ``point`` along ``direction``."""
    s = np.asarray(direction, float) / np.linalg.norm(direction)
    return np.concatenate([np.cross(s, P - point), s])


def _perp_to(d):
    d = d / np.linalg.norm(d)
    a = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    a = a - (a @ d) * d
    return a / np.linalg.norm(a)


def leg_wrench_systems(robot, position, R):
    """Per leg, an orthonormal basis (rows, moments about P) of the wrenches the leg can transmit to the
    platform with its actuator locked: the reciprocal screws of its passive joint twists (Delta: the two rod
    forces). Written from screw theory, independently of the finite-difference Jacobians."""
    arch = robot["architecture"]
    P = np.asarray(position, float)
    q = actuators(robot, P, R)
    out = []
    for k, leg in enumerate(legs(robot)):
        B = _B(leg, P, R)
        if arch == "delta":
            C = _delta_elbow(leg, q[k])
            h = 0.5 * leg["spacing"] * leg["axis"]
            rows = []
            for sg in (1.0, -1.0):
                Bi, Ci = B + sg * (R @ (0.5 * leg["spacing"] * leg["axis"])), C + sg * h
                u = (Bi - Ci) / np.linalg.norm(Bi - Ci)
                rows.append(np.concatenate([u, np.cross(Bi - P, u)]))
            out.append(np.array(rows))
            continue
        twists = []
        for e in np.eye(3):  # spherical joint at B (3-UPU: replaced below)
            twists.append(_rot_twist(B, e, P))
        if arch == "6-UPS":
            A = leg["base"]
            d = B - A
            a = leg.get("base_axis", _perp_to(d))
            if np.linalg.norm(np.cross(a, d)) < 1e-9:
                a = _perp_to(d)
            c = np.cross(a, d)
            twists += [_rot_twist(A, a, P), _rot_twist(A, c, P)]
        elif arch == "3-RPS":
            twists.append(_rot_twist(leg["base"], leg["axis"], P))
        elif arch == "3-PRS":
            C = leg["base"] + q[k] * leg["slide"]
            twists.append(_rot_twist(C, leg["axis"], P))
        elif arch == "3-UPU":
            A = leg["base"]
            d = B - A
            a = leg["base_axis"]
            c = np.cross(a, d)  # the inner axes (parallel) are normal to the outer axis and to the leg
            twists = [_rot_twist(A, a, P), _rot_twist(A, c, P), _rot_twist(B, c, P),
                      _rot_twist(B, R @ leg["platform_axis"], P)]
        out.append(_null_rows(np.array(twists)))
    return out


def screw_singularity_measure(robot, position, R):
    """Smallest singular value of all legs' transmissible wrenches stacked (moments divided by the
    characteristic length, rows unit): 0 when the platform can move with every actuator locked. Unlike
    :func:`parallel_singularity_measure` it also sees the constraint singularities of the lower-mobility
    robots (e.g. a Delta whose rods are vertical can turn about z; a 3-UPU whose constraint couples are
    coplanar)."""
    W = np.vstack(leg_wrench_systems(robot, position, R)).copy()
    W[:, 3:] /= characteristic_length(robot)
    W /= np.linalg.norm(W, axis=1)[:, None]
    return float(np.linalg.svd(W, compute_uv=False)[min(W.shape) - 1])


# ----------------------------------------------------------------------------------------------------------
# limits
# ----------------------------------------------------------------------------------------------------------


def segment_distance(p1, q1, p2, q2):
    """Distance between segments [p1, q1] and [p2, q2] (clamped closest points, Ericson 5.1.9)."""
    p1, q1, p2, q2 = (np.asarray(v, float) for v in (p1, q1, p2, q2))
    d1 = q1 - p1
    d2 = q2 - p2
    r = p1 - p2
    a = float(d1 @ d1)
    e = float(d2 @ d2)
    f = float(d2 @ r)
    eps = 1e-300
    if a <= eps and e <= eps:
        return float(np.linalg.norm(p1 - p2))
    if a <= eps:
        s = 0.0
        t = min(max(f / e, 0.0), 1.0)
    else:
        c = float(d1 @ r)
        if e <= eps:
            t = 0.0
            s = min(max(-c / a, 0.0), 1.0)
        else:
            b = float(d1 @ d2)
            denom = a * e - b * b
            s = min(max((b * f - c * e) / denom, 0.0), 1.0) if denom > 1e-12 * a * e else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                t = 0.0
                s = min(max(-c / a, 0.0), 1.0)
            elif t > 1.0:
                t = 1.0
                s = min(max((b - c) / a, 0.0), 1.0)
    return float(np.linalg.norm((p1 + s * d1) - (p2 + t * d2)))


def _angle_deg(u, v):
    c = float(u @ v) / (np.linalg.norm(u) * np.linalg.norm(v))
    return math.degrees(math.acos(min(1.0, max(-1.0, c))))


def _signed_deg(n, d, axis):
    return math.degrees(math.atan2(float(axis @ np.cross(n, d)), float(n @ d)))


def segments(robot, position, R):
    """Per leg, a list of ``(start, end, radius)`` capsules (needs reachable actuators)."""
    arch = robot["architecture"]
    q = actuators(robot, position, R)
    out = []
    for k, leg in enumerate(legs(robot)):
        B = _B(leg, position, R)
        if arch in ("6-UPS", "3-RPS", "3-UPU"):
            out.append([(leg["base"], B, leg["radius"])])
        elif arch == "3-PRS":
            out.append([(leg["base"] + q[k] * leg["slide"], B, leg["radius"])])
        else:
            C = _delta_elbow(leg, q[k])
            h = 0.5 * leg["spacing"] * leg["axis"]
            out.append([(leg["base"], C, leg["arm_radius"]), (C + h, B + h, leg["rod_radius"]),
                        (C - h, B - h, leg["rod_radius"])])
    return out


def limit_report(robot, position, R) -> list[str]:
    """Every limit that the pose violates, one line each (empty: within limits)."""
    arch = robot["architecture"]
    position = np.asarray(position, float)
    R = np.asarray(R, float)
    q = actuators(robot, position, R)
    lines = []
    if np.any(np.isnan(q)):
        return [f"leg {k + 1}: unreachable" for k in range(len(q)) if math.isnan(q[k])]
    L = legs(robot)
    for k, leg in enumerate(L):
        i = k + 1
        B = _B(leg, position, R)
        if arch == "delta":
            lo, hi = leg["angle_range_deg"]
            th = math.degrees(q[k])
            if not lo <= th <= hi:
                lines.append(f"leg {i}: arm angle {th:.6g} deg outside [{lo:g}, {hi:g}]")
            C = _delta_elbow(leg, q[k])
            if leg["platform_cone_deg"] is not None:
                ang = _angle_deg(C - B, R @ leg["platform_normal"])
                if ang > leg["platform_cone_deg"]:
                    lines.append(f"leg {i}: platform cone {ang:.6g} deg > {leg['platform_cone_deg']:g}")
            continue
        lo, hi = leg["stroke"]
        if not lo <= q[k] <= hi:
            lines.append(f"leg {i}: stroke {q[k]:.6g} mm outside [{lo:g}, {hi:g}]")
        A = leg["base"] + q[k] * leg["slide"] if arch == "3-PRS" else leg["base"]
        d = B - A
        if leg.get("angle_range_deg") is not None:
            lo, hi = leg["angle_range_deg"]
            ang = _signed_deg(leg["base_normal"], d, leg["axis"])
            if not lo <= ang <= hi:
                lines.append(f"leg {i}: revolute angle {ang:.6g} deg outside [{lo:g}, {hi:g}]")
        if leg["base_cone_deg"] is not None:
            ang = _angle_deg(d, leg["base_normal"])
            if ang > leg["base_cone_deg"]:
                lines.append(f"leg {i}: base cone {ang:.6g} deg > {leg['base_cone_deg']:g}")
        if leg["platform_cone_deg"] is not None:
            ang = _angle_deg(-d, R @ leg["platform_normal"])
            if ang > leg["platform_cone_deg"]:
                lines.append(f"leg {i}: platform cone {ang:.6g} deg > {leg['platform_cone_deg']:g}")
    segs = segments(robot, position, R)
    for a in range(len(segs)):
        for b in range(a + 1, len(segs)):
            for s1 in segs[a]:
                for s2 in segs[b]:
                    if s1[2] > 0 and s2[2] > 0:
                        dist = segment_distance(s1[0], s1[1], s2[0], s2[1])
                        if dist < s1[2] + s2[2]:
                            lines.append(f"legs {a + 1} and {b + 1}: interference, "
                                         f"distance {dist:.6g} mm < {s1[2] + s2[2]:g}")
    return lines


def within_limits(robot, position, R) -> bool:
    return not limit_report(robot, position, R)


# ----------------------------------------------------------------------------------------------------------
# workspace
# ----------------------------------------------------------------------------------------------------------


def sample_ok(robot, coords, orientation_R=None) -> bool:
    """Whether a workspace sample counts (see :func:`monte_carlo_volume`)."""
    arch = robot["architecture"]
    if arch in ("3-RPS", "3-PRS"):
        z, roll_deg, pitch_deg = coords
        try:
            p, R = complete_pose(robot, z, math.radians(roll_deg), math.radians(pitch_deg))
        except RuntimeError:
            return False
    else:
        p, R = np.asarray(coords, float), (np.eye(3) if orientation_R is None else np.asarray(orientation_R, float))
    q = actuators(robot, p, R)
    if np.any(np.isnan(q)):
        return False
    return within_limits(robot, p, R)


def monte_carlo_volume(robot, orientation_R, box, n_samples, seed):
    """(volume, standard error) of the constant-orientation workspace (3-RPS/3-PRS: over (z, roll, pitch))."""
    box = np.asarray(box, float)
    rng = np.random.default_rng(seed)
    lo, hi = box[:, 0], box[:, 1]
    vbox = float(np.prod(hi - lo))
    pts = lo + (hi - lo) * rng.random((int(n_samples), 3))
    hits = sum(1 for c in pts if sample_ok(robot, c, orientation_R))
    f = hits / n_samples
    return vbox * f, vbox * math.sqrt(f * (1 - f) / n_samples)


# ----------------------------------------------------------------------------------------------------------
# random robots and poses
# ----------------------------------------------------------------------------------------------------------


def _tilt(v, rng, max_deg):
    """``v`` turned by up to ``max_deg`` about a random axis."""
    v = np.asarray(v, float) / np.linalg.norm(v)
    ax = rng.normal(size=3)
    ax -= (ax @ v) * v
    ax /= np.linalg.norm(ax)
    return expm_so3(math.radians(rng.uniform(0, max_deg)) * ax) @ v


def _perp(v, to):
    v = np.asarray(v, float) - (np.asarray(v) @ to) * to
    return v / np.linalg.norm(v)


def _lst(v):
    return [float(x) for x in v]


def random_robot(architecture, seed) -> dict:
    """A perturbed copy of the reference file of ``architecture``; its home pose is within every limit and
    not near a singularity (strokes / ranges are re-centred on the home values)."""
    rng = np.random.default_rng(seed)
    base = load_reference(architecture)
    size = {"6-UPS": 250.0, "delta": 200.0, "3-RPS": 200.0, "3-PRS": 200.0, "3-UPU": 200.0}[architecture]
    for _attempt in range(200):
        rob = {k: v for k, v in base.items() if k != "legs"}
        rob["name"] = f"random_{architecture}_{seed}"
        rob["home"] = dict(base["home"])
        new_legs = []
        for lg in base["legs"]:
            lg = dict(lg)
            lg["base"] = _lst(np.asarray(lg["base"]) + rng.uniform(-0.1, 0.1, 3) * size)
            lg["platform"] = _lst(np.asarray(lg["platform"]) + rng.uniform(-0.1, 0.1, 3) * size * 0.6)
            if architecture == "3-RPS":
                ax = _tilt(lg["axis"], rng, 5.0)
                lg["axis"] = _lst(ax)
                lg["base_normal"] = _lst(_perp([0.0, 0.0, 1.0], ax))
            elif architecture == "3-PRS":
                s = _tilt(lg["slide"], rng, 5.0)
                ax = _perp(_tilt(lg["axis"], rng, 5.0), s)
                lg["slide"], lg["axis"] = _lst(s), _lst(ax)
                lg["base_normal"] = _lst(_perp([0.0, 0.0, 1.0], ax))
                lg["rod"] = float(lg["rod"] * rng.uniform(0.95, 1.05))
            elif architecture == "3-UPU":
                ax = _tilt(lg["base_axis"], rng, 5.0)
                lg["base_axis"] = lg["platform_axis"] = _lst(ax)
            elif architecture == "delta":
                ax = _tilt(lg["axis"], rng, 4.0)
                lg["axis"] = _lst(ax)
                lg["zero"] = _lst(_perp(_tilt(lg["zero"], rng, 4.0), ax))
                lg["arm"] = float(lg["arm"] * rng.uniform(0.95, 1.05))
                lg["rod"] = float(lg["rod"] * rng.uniform(0.97, 1.03))
            new_legs.append(lg)
        rob["legs"] = new_legs
        try:
            if architecture in ("3-RPS", "3-PRS"):
                z = base["home"]["position"][2]
                p, R = complete_pose(rob, z, 0.0, 0.0)
            elif architecture in ("delta", "3-UPU"):
                p, R = np.asarray(base["home"]["position"], float), np.eye(3)
            else:
                p, R = home(base)
        except RuntimeError:
            continue
        rob["home"] = {"position": _lst(p), "orientation_deg": _lst(orientation_deg(R))}
        q = actuators(rob, p, R)
        if np.any(np.isnan(q)):
            continue
        for k, lg in enumerate(new_legs):
            if architecture == "delta":
                th = math.degrees(q[k])
                lg["angle_range_deg"] = [th - 55.0, th + 60.0]
            elif architecture == "3-PRS":
                lg["stroke"] = [q[k] - 120.0, q[k] + 120.0]
            else:
                lg["stroke"] = [q[k] - 0.2 * q[k], q[k] + 0.25 * q[k]]
        try:
            legs(rob)
        except ValueError:
            continue
        if not within_limits(rob, p, R):
            continue
        if parallel_singularity_measure(rob, p, R) < 0.1:
            continue
        return rob
    raise RuntimeError("no acceptable random robot")


def random_pose(robot, seed, max_tries=200):
    """A reachable pose within the limits near home: ``(position, R)``."""
    rng = np.random.default_rng(seed)
    arch = robot["architecture"]
    p0, R0 = home(robot)
    for _ in range(max_tries):
        try:
            if arch == "6-UPS":
                p = p0 + rng.uniform(-20, 20, 3)
                R = rotation(rng.uniform(-5, 5, 3)) @ R0
            elif arch in ("3-RPS", "3-PRS"):
                p, R = complete_pose(robot, p0[2] + rng.uniform(-20, 20), *np.radians(rng.uniform(-5, 5, 2)))
            else:
                p, R = p0 + rng.uniform(-30, 30, 3), np.eye(3)
        except RuntimeError:
            continue
        if not np.any(np.isnan(actuators(robot, p, R))) and within_limits(robot, p, R):
            return p, R
    raise RuntimeError("no reachable pose found near home")
