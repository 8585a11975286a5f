"""Independent brute-force reference of the worst-case pose errors of planar parallel manipulators (tests only).

Written from the kinematic and error conventions alone (numpy and scipy); it imports nothing from
``pmaccuracy``. It serves as the reference the library's first-order worst-case error bounds are checked
against: every error source is inserted into the legs' serial chains as a small rigid transform, the three
loop closures are solved exactly by Newton's method, the error Jacobian is obtained by central finite
differences of that exact solution, and the worst cases are support functions of the error set summed
source by source -- nothing assumes the structure of a leg.

Conventions
-----------
Lengths in mm and angles in rad in the code; robot dictionaries (parsed TOML) hold angles in degrees in keys
ending in ``deg`` (and in the ``range`` of an R joint of a chain). A pose is ``[x, y, phi]`` (mm, mm, rad).
``Rot(t)`` is the planar rotation by ``t``, ``Tr(v)`` the translation by ``v`` (in the current frame),
``E = Rot(pi/2)``.

A leg is a chain of three one-DOF joints (R or P), base to platform, exactly one actuated. With the joint
transforms ``J_k(q) = Rot(offset_k) M_k(q) Tr(link_k)``, ``M = Rot(q)`` (R) or ``Tr(q e_x)`` (P), the end
frame ``F3 = F0 J_0 J_1 J_2`` (``F0``: origin ``base``, angle ``base_angle``) must equal the platform
attachment frame ``Tr(p) Rot(phi) Tr(platform) Rot(platform_angle)``. Joints are indexed 0, 1, 2 here
(base to platform).

Error sources of joint k (the *variables* of a source, their constraint set, and where they enter):

===========  =================  ==================  ======================  ===============================
source       joints             variables           set                     insertion
===========  =================  ==================  ======================  ===============================
radial       R                  (dx, dy) mm         disk ``|d| <= eps``      ``Tr(d)`` before ``J_k``
position     any (tolerance)    (dx, dy) mm         disk ``|d| <= t``        ``Tr(d)`` before ``J_k``
angular      P                  tau rad             ``|tau| <= eps``         ``Rot(tau)`` of the block (below)
direction    any (tolerance)    tau rad             ``|tau| <= t``           ``Rot(tau)`` before ``J_k``
actuator     the actuated one   delta (mm or rad)   ``|delta| <= eps``       ``q_k -> q_k + delta``
length       any, link != 0     delta mm            ``|delta| <= t``         ``link_k -> link_k (1 + delta/|link_k|)``
lateral      P                  (sigma mm, tau rad) rhombus                  ``Tr(sigma e_y) Rot(tau)`` of the block
===========  =================  ==================  ======================  ===============================

The *block* of a P joint is the short member its clearances shift and tilt about its own centre: a
carriage travels with the joint value (``J_k = Rot(off) Tr(q e_x) Tr(sigma e_y) Rot(tau) Tr(link)``, the
default of an actuated P joint), a bushing sits at the joint's origin (``J_k = Rot(off) Tr(sigma e_y)
Rot(tau) Tr(q e_x) Tr(link)``, the default of a passive one); ``tau`` is the sum of the angular and the
lateral tilts. Robot dicts may name it: ``block`` (3-PRR, 3-RPR legs and chain joints), ``guide_block`` and
``bearing_block`` (3-PPR legs).

The rhombus of a lateral source with block length ``L`` is ``|L tau + 2 sigma| <= 2 eps`` and
``|L tau - 2 sigma| <= 2 eps``; its vertices are ``(sigma, tau) = (+-eps, 0)`` and ``(0, +-2 eps / L)``.
The displacement ``d`` of radial/position sources is expressed in the *local* frame before ``J_k`` (the
frame whose origin is the joint's centre, turned by ``base_angle`` plus the turns of the joints before
``k``); the disk is the same set in any frame. With several sources on one joint the inserted transform is
``Tr(d_radial + d_position) Rot(tau_direction)`` followed by ``J_k`` with the actuator, block and length
errors (the order only matters at second order).

Formats
-------
* clearance / tolerance specification (the file format, parsed):
  ``{"legs": [{"joints": [j0, j1, j2]}, x3]}`` with ``j`` dicts such as ``{"radial": 0.02}``,
  ``{"actuator": 0.005, "angular": 0.0005}``, ``{"lateral": 0.0015, "block_length": 50.0}``, or for
  tolerances ``{"position": 0.01, "direction": 1e-4, "length": 0.02}``; ``{}`` for no source. Magnitudes
  are >= 0 (mm or rad).
* an error *configuration* (one point of the error set): ``[[dict, dict, dict], x3]`` (leg, joint) with
  ``{"radial": [dx, dy], "position": [dx, dy], "angular": tau, "direction": tau, "actuator": delta,
  "length": delta, "lateral": [sigma, tau]}`` (any subset).
* a variable: a tuple ``(leg, joint, source, component)``; component 0/1 are dx/dy of radial/position and
  sigma/tau of lateral, 0 for the scalar sources.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

TWO_PI = 2.0 * np.pi
#: pi in extended precision (``np.longdouble``: 64-bit mantissa on x86-64 Linux, else plain double).
_PI_L = 4 * np.arctan(np.longdouble(1))

#: Number of scalar variables of each source.
SOURCE_SIZE = {"radial": 2, "position": 2, "angular": 1, "direction": 1, "actuator": 1, "length": 1, "lateral": 2}
#: Sources of the clearance file and of the tolerance file.
CLEARANCE_SOURCES = ("radial", "angular", "lateral", "actuator")
TOLERANCE_SOURCES = ("position", "direction", "length")


# --------------------------------------------------------------------------------------------------
# planar helpers
# --------------------------------------------------------------------------------------------------

def _fl(x):
    """``x`` as a floating array, keeping an extended (``np.longdouble``) precision."""
    x = np.asarray(x)
    return x if np.issubdtype(x.dtype, np.floating) else x.astype(float)


def vec(t):
    """Unit vectors ``[cos t, sin t]``: angles ``(...)`` (rad) -> ``(..., 2)`` (dtype kept)."""
    t = _fl(t)
    return np.stack([np.cos(t), np.sin(t)], axis=-1)


def rot(t, v):
    """``Rot(t) v``: angles ``(...)`` (rad), vectors ``(..., 2)`` (broadcast) -> ``(..., 2)``."""
    t = _fl(t)
    v = _fl(v)
    c, s = np.cos(t), np.sin(t)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


def perp(v):
    """``E v`` (turned by +90 deg): ``(..., 2)`` -> ``(..., 2)``."""
    v = _fl(v)
    return np.stack([-v[..., 1], v[..., 0]], axis=-1)


def cross(a, b):
    """``a_x b_y - a_y b_x`` of ``(..., 2)`` arrays -> ``(...)``."""
    a = _fl(a)
    b = _fl(b)
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def wrap(a):
    """Angles (rad) wrapped to ``(-pi, pi]``, any shape (with pi in the angles' own precision)."""
    a = _fl(a)
    pi = np.asarray(_PI_L, dtype=a.dtype)
    return pi - np.mod(pi - a, 2 * pi)


# --------------------------------------------------------------------------------------------------
# robots
# --------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Joint:
    """One joint: ``kind`` "R"/"P", ``actuated``, ``offset`` (rad), ``link`` (mm, 2-tuple, in the frame after
    the joint's motion), ``block`` of a P joint ("carriage", "bushing"; None: carriage if actuated)."""

    kind: str
    actuated: bool
    offset: float
    link: tuple
    block: str | None = None

    @property
    def bushing(self) -> bool:
        return self.kind == "P" and (self.block == "bushing" or (self.block is None and not self.actuated))


@dataclass(frozen=True)
class Leg:
    """A leg: ``base`` (mm), ``base_angle`` (rad), ``platform`` (mm, platform frame), ``platform_angle`` (rad),
    ``working_mode`` (+1/-1, sign of B_ii, see :func:`leg_b`) and three :class:`Joint`, base to platform."""

    base: tuple
    base_angle: float
    platform: tuple
    platform_angle: float
    working_mode: int
    joints: tuple

    @property
    def act(self) -> int:
        """Index (0-2) of the actuated joint."""
        return next(k for k, j in enumerate(self.joints) if j.actuated)

    @property
    def passive(self) -> tuple:
        """Indices of the two passive joints, in chain order."""
        return tuple(k for k, j in enumerate(self.joints) if not j.actuated)


@dataclass(frozen=True)
class Robot:
    """Architecture name and three :class:`Leg`."""

    architecture: str
    legs: tuple


def _pair(v, what):
    a = np.asarray(v, float)
    if a.shape != (2,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be two finite numbers, got {v!r}")
    return (float(a[0]), float(a[1]))


def load_robot(d: dict) -> Robot:
    """:class:`Robot` from a parsed robot file of architecture "3-RPR", "3-RRR", "3-PRR", "3-PPR" or "chain".

    Chains (joints base to platform, ``a`` = actuated):

    * 3-RPR ``base`` A, ``platform`` D: ``[R(0, link 0), P_a(0, link 0), R(0, link 0)]``, base angle 0,
      working mode +1 (positive length).
    * 3-RRR: ``[R_a(link (proximal, 0)), R(link (distal, 0)), R(link 0)]``, base angle 0.
    * 3-PRR: base ``guide_point``, base angle ``guide_deg``: ``[P_a(link 0), R(link (distal, 0)), R(link 0)]``.
    * 3-PPR (Wu et al. 2012, Eq. 1): base ``a vec(alpha)``, base angle ``alpha + beta``;
      ``[P_a(offset 0, link d vec(gamma)), P(offset gamma + theta, link 0), R(link 0)]``, platform
      ``-r vec(psi)``, platform angle 0 (one branch; working mode +1).
    * chain: ``base``, ``base_deg``, ``platform``, ``platform_deg``, ``working_mode`` and three
      ``joints`` with ``type``, ``actuated``, ``offset_deg``, ``link``.

    Ranges are not needed here (the reference works at given poses) and are ignored.
    """
    arch = d.get("architecture")
    legs_in = d.get("legs")
    if not isinstance(legs_in, list) or len(legs_in) != 3:
        raise ValueError("a robot needs exactly three legs")
    legs = []
    z = (0.0, 0.0)
    for i, L in enumerate(legs_in):
        w = f"legs[{i}]"
        if arch == "3-RPR":
            js = (Joint("R", False, 0.0, z), Joint("P", True, 0.0, z, L.get("block")), Joint("R", False, 0.0, z))
            leg = Leg(_pair(L["base"], w + ".base"), 0.0, _pair(L["platform"], w + ".platform"), 0.0, 1, js)
        elif arch == "3-RRR":
            js = (Joint("R", True, 0.0, (float(L["proximal"]), 0.0)), Joint("R", False, 0.0, (float(L["distal"]), 0.0)),
                  Joint("R", False, 0.0, z))
            leg = Leg(_pair(L["base"], w + ".base"), 0.0, _pair(L["platform"], w + ".platform"), 0.0,
                      int(L["working_mode"]), js)
        elif arch == "3-PRR":
            js = (Joint("P", True, 0.0, z, L.get("block")), Joint("R", False, 0.0, (float(L["distal"]), 0.0)),
                  Joint("R", False, 0.0, z))
            leg = Leg(_pair(L["guide_point"], w + ".guide_point"), math.radians(float(L["guide_deg"])),
                      _pair(L["platform"], w + ".platform"), 0.0, int(L["working_mode"]), js)
        elif arch == "3-PPR":
            a, dd, r = float(L["a"]), float(L["d"]), float(L["r"])
            al, be, ga, th, ps = (math.radians(float(L[k])) for k in
                                  ("alpha_deg", "beta_deg", "gamma_deg", "theta_deg", "psi_deg"))
            js = (Joint("P", True, 0.0, (dd * math.cos(ga), dd * math.sin(ga)), L.get("guide_block")),
                  Joint("P", False, ga + th, z, L.get("bearing_block")), Joint("R", False, 0.0, z))
            leg = Leg((a * math.cos(al), a * math.sin(al)), al + be, (-r * math.cos(ps), -r * math.sin(ps)), 0.0, 1, js)
        elif arch == "chain":
            jl = L.get("joints")
            if not isinstance(jl, list) or len(jl) != 3:
                raise ValueError(f"{w}: a chain leg needs exactly three joints")
            js = []
            for k, J in enumerate(jl):
                if J.get("type") not in ("R", "P"):
                    raise ValueError(f"{w}.joints[{k}].type must be 'R' or 'P'")
                js.append(Joint(J["type"], bool(J.get("actuated", False)), math.radians(float(J.get("offset_deg", 0.0))),
                                _pair(J.get("link", [0.0, 0.0]), f"{w}.joints[{k}].link"), J.get("block")))
            leg = Leg(_pair(L["base"], w + ".base"), math.radians(float(L.get("base_deg", 0.0))),
                      _pair(L["platform"], w + ".platform"), math.radians(float(L.get("platform_deg", 0.0))),
                      int(L.get("working_mode", 1)), tuple(js))
        else:
            raise ValueError(f"unknown architecture {arch!r}")
        if sum(j.actuated for j in leg.joints) != 1:
            raise ValueError(f"{w}: exactly one joint must be actuated")
        if leg.working_mode not in (1, -1):
            raise ValueError(f"{w}.working_mode must be +1 or -1")
        legs.append(leg)
    return Robot(str(arch), tuple(legs))


def as_robot(robot) -> Robot:
    """A robot dict (parsed robot file) loaded by :func:`load_robot`; any object with ``legs`` (each with
    ``base, base_angle, platform, platform_angle, working_mode, joints`` of ``kind, actuated, offset, link``,
    e.g. ``planar_reference.Robot``) is converted field by field."""
    if isinstance(robot, Robot):
        return robot
    if isinstance(robot, dict):
        return load_robot(robot)
    legs = tuple(Leg(tuple(map(float, L.base)), float(L.base_angle), tuple(map(float, L.platform)),
                     float(L.platform_angle), int(L.working_mode),
                     tuple(Joint(J.kind, bool(J.actuated), float(J.offset), tuple(map(float, J.link)),
                                 getattr(J, "block", None))
                           for J in L.joints)) for L in robot.legs)
    return Robot(str(getattr(robot, "architecture", "chain")), legs)


# --------------------------------------------------------------------------------------------------
# chain kinematics with inserted errors (batched)
# --------------------------------------------------------------------------------------------------

_ARRAYS = ("T", "R", "dq", "sig", "tl", "dl", "ang")


def _zero_errors(B):
    """Error arrays of a batch of ``B`` configurations, all zero: ``T`` ``(B, 3, 3, 2)`` (mm, local
    translation before each joint), ``R`` (rad, turn before each joint), ``dq`` (actuator, mm/rad), ``sig``
    (mm) and ``tl`` (rad) (lateral), ``dl`` (mm, link lengthening), ``ang`` (rad, angular: the block's
    tilt), each ``(B, 3, 3)`` (leg, joint)."""
    out = {k: np.zeros((B, 3, 3)) for k in _ARRAYS}
    out["T"] = np.zeros((B, 3, 3, 2))
    return out


def chain_fk(leg: Leg, q, err=None):
    """End frame of a leg with inserted errors, and its joints' centres and axes.

    ``q`` ``(B, 3)`` joint values (rad for R, mm for P); ``err`` a dict of this leg's error arrays ``T``
    ``(B, 3, 2)``, ``R``, ``dq``, ``sig``, ``tl``, ``dl`` ``(B, 3)`` (see :func:`_zero_errors`; None: no
    errors). Joint k maps the frame (origin ``p``, angle ``t``) as
    ``p += Rot(t) T_k; t += R_k + offset_k (+ q_k + dq_k for R)``; for P with a carriage ``p += (q_k + dq_k)
    vec(t) + sig_k E vec(t); t += tl_k + ang_k``, with a bushing ``p += sig_k E vec(t); t += tl_k + ang_k;
    p += (q_k + dq_k) vec(t)``; then ``p += Rot(t) link_k (1 + dl_k / |link_k|)``.

    Returns ``p3`` ``(B, 2)`` (mm), ``t3`` ``(B,)`` (rad, unwrapped), ``centres`` ``(B, 3, 2)`` (origin where the
    joint's motion happens: the rotation centre of an R) and ``axes`` ``(B, 3, 2)`` (slide direction of a P).
    """
    q = np.asarray(q, float)
    B = q.shape[0]
    if err is None:
        err = {k: v[:, 0] for k, v in _zero_errors(B).items()}
    p = np.broadcast_to(np.asarray(leg.base, q.dtype), (B, 2)).copy()
    t = np.full(B, leg.base_angle, q.dtype)
    centres, axes = [], []
    for k, J in enumerate(leg.joints):
        p = p + rot(t, err["T"][:, k])
        t = t + err["R"][:, k] + J.offset
        qk = q[:, k] + err["dq"][:, k]
        centres.append(p)
        axes.append(vec(t))
        if J.kind == "R":
            t = t + qk
        elif J.bushing:
            p = p + err["sig"][:, k, None] * perp(vec(t))
            t = t + err["tl"][:, k] + err["ang"][:, k]
            p = p + qk[:, None] * vec(t)
        else:
            e = vec(t)
            p = p + qk[:, None] * e + err["sig"][:, k, None] * perp(e)
            t = t + err["tl"][:, k] + err["ang"][:, k]
        link = np.asarray(J.link, float)
        n = float(np.hypot(*link))
        scale = 1.0 + (err["dl"][:, k] / n if n > 0 else 0.0 * err["dl"][:, k])
        p = p + scale[:, None] * rot(t, link)
    return p, t, np.stack(centres, 1), np.stack(axes, 1)


def leg_b(leg: Leg, q):
    """``B_ii`` of a leg at the configuration ``q`` ``(3,)``: the pairing ``m_O omega_a + f . v_a`` of the
    constraint wrench ``(f, m_O)`` with the actuated unit twist ``(omega_a, v_a)``.

    Twists: R at centre c ``(1, -E c)``, P along e ``(0, e)``. Wrench (reciprocal to both passive twists):
    passive R at c_m and R at c_n (m < n) ``f = (c_n - c_m)/|c_n - c_m|`` through c_m; passive R at c and P
    along e: ``f = E e`` through c; two passive P: ``f = 0, m_O = 1``. (3-RRR: ``sign cross(B - A, D - B)``;
    3-PRR: ``sign u . (D - B)``; 3-RPR: the sign of the length.)
    """
    _, _, c, ax = chain_fk(leg, np.asarray(q, float)[None])
    c, ax = c[0], ax[0]
    m, n = leg.passive
    km, kn = leg.joints[m].kind, leg.joints[n].kind
    if km == "P" and kn == "P":
        f, mo = np.zeros(2), 1.0
    else:
        if km == "R" and kn == "R":
            f = (c[n] - c[m]) / np.linalg.norm(c[n] - c[m])
            pt = c[m]
        else:
            r, s = (m, n) if km == "R" else (n, m)
            f, pt = perp(ax[s]), c[r]
        mo = float(cross(pt, f))
    a = leg.act
    if leg.joints[a].kind == "R":
        return mo + float(f @ (-perp(c[a])))
    return float(f @ ax[a])


def leg_ik(leg: Leg, pose, n_starts: int = 48):
    """Chain configuration ``(3,)`` of one leg at ``pose`` ``(3,)`` in its working mode.

    Damped Newton on ``[p3(q) - X, wrap(t3(q) - Th)]`` (X, Th: the platform attachment frame) from
    ``n_starts`` deterministic starts (R values spread over the circle, P values over +-2 S, S the leg's
    span); the converged solutions (residual < 1e-10) whose ``sign(B_ii)`` (:func:`leg_b`) equals the
    working mode are kept (any solution for a leg with a single R, whose configuration is unique); the one
    with the smallest |P values| is returned. Raises ValueError if none.
    """
    pose = np.asarray(pose, float)
    X = pose[:2] + rot(pose[2], np.asarray(leg.platform))
    Th = pose[2] + leg.platform_angle
    S = float(np.linalg.norm(X - np.asarray(leg.base)) + sum(np.hypot(*j.link) for j in leg.joints) + 1.0)
    isR = np.array([j.kind == "R" for j in leg.joints])
    i = np.arange(n_starts)
    q = np.zeros((n_starts, 3))
    for k in range(3):
        frac = np.mod(i * (0.6180339887 + 0.1 * k) + 0.37 * k, 1.0)
        q[:, k] = (frac * TWO_PI - np.pi) if isR[k] else (4 * frac - 2) * S
    for _ in range(80):
        p3, t3, c, ax = chain_fk(leg, q)
        F = np.concatenate([p3 - X, wrap(t3 - Th)[:, None]], 1)
        J = np.zeros((n_starts, 3, 3))
        for k in range(3):
            if isR[k]:
                J[:, :2, k] = perp(p3 - c[:, k])
                J[:, 2, k] = 1.0
            else:
                J[:, :2, k] = ax[:, k]
        JT = np.swapaxes(J, 1, 2)
        A = JT @ J + 1e-12 * np.eye(3) * (1 + np.trace(JT @ J, axis1=1, axis2=2))[:, None, None]
        dq = -np.linalg.solve(A, JT @ F[:, :, None])[:, :, 0]
        lim = np.where(isR, 0.5, 0.25 * S)
        sc = np.max(np.abs(dq) / lim, axis=1, keepdims=True)
        q = q + np.where(sc > 1, dq / np.maximum(sc, 1e-300), dq)
    p3, t3, _, _ = chain_fk(leg, q)
    res = np.max(np.abs(np.concatenate([p3 - X, wrap(t3 - Th)[:, None]], 1)), axis=1)
    q[:, isR] = wrap(q[:, isR])
    good = [qq for qq, r in zip(q, res) if r < 1e-10]
    if int(isR.sum()) >= 2:
        good = [qq for qq in good if np.sign(leg_b(leg, qq)) == leg.working_mode]
    if not good:
        raise ValueError("the leg cannot reach the pose in its working mode")
    return min(good, key=lambda qq: float(np.sum(np.abs(qq[~isR]))))


def inverse_kinematics(robot, pose):
    """Chain configurations ``(3, 3)`` (leg, joint; rad for R, mm for P) of the robot at ``pose`` ``(3,)``
    (mm, mm, rad) in its working modes (:func:`leg_ik`)."""
    robot = as_robot(robot)
    return np.stack([leg_ik(leg, pose) for leg in robot.legs])


def _solve(robot: Robot, pose, q0, err, tol=1e-9):
    """Exact platform poses ``(B, 3)`` with the actuators held at ``q0`` and the error arrays ``err`` (batch B).

    Unknowns ``z = [x, y, phi, passive joints of legs 0, 1, 2]`` ``(B, 9)``; residual of leg i
    ``[p3_i - P - Rot(phi) platform_i, wrap(t3_i - phi - platform_angle_i)]``; Newton's method with the
    analytic Jacobian (passive R at centre c: ``[E (p3 - c), 1]``; passive P along e: ``[e, 0]``; pose:
    ``[-I, -E Rot(phi) platform; 0, 0, -1]``) started at the commanded configuration, the step halved while
    |F| grows. The unknowns and the residual are kept in extended precision (``np.longdouble``, eps 1e-19 on
    x86-64; the Jacobian solve in double, i.e. Newton with iterative refinement), so that the solution is
    accurate to ~1e-17 mm and central differences with small steps stay accurate. Stops three iterations
    after the step falls below 1e-12 of the unknowns. Returns ``(B, 3)`` in ``np.longdouble``. Raises
    RuntimeError if a residual stays above ``tol``.
    """
    B = err["T"].shape[0]
    LD = np.longdouble
    pose = np.asarray(pose, float)
    z = np.zeros((B, 9), LD)
    z[:, :3] = pose
    for i, leg in enumerate(robot.legs):
        z[:, 3 + 2 * i:5 + 2 * i] = q0[i, list(leg.passive)]
    legerr = [{k: v[:, i].astype(LD) for k, v in err.items()} for i in range(3)]

    def residual(z):
        F = np.zeros((B, 9), LD)
        Jm = np.zeros((B, 9, 9))
        for i, leg in enumerate(robot.legs):
            q = np.repeat(np.asarray(q0[i], LD)[None], B, 0)
            pas = list(leg.passive)
            q[:, pas] = z[:, 3 + 2 * i:5 + 2 * i]
            p3, t3, c, ax = chain_fk(leg, q, legerr[i])
            d = rot(z[:, 2], np.asarray(leg.platform))
            r = slice(3 * i, 3 * i + 3)
            F[:, r] = np.concatenate([p3 - z[:, :2] - d, wrap(t3 - z[:, 2] - leg.platform_angle)[:, None]], 1)
            Jm[:, 3 * i:3 * i + 2, 0:2] = -np.eye(2)
            Jm[:, 3 * i:3 * i + 2, 2] = -perp(d)
            Jm[:, 3 * i + 2, 2] = -1.0
            for col, k in zip((3 + 2 * i, 4 + 2 * i), pas):
                if leg.joints[k].kind == "R":
                    Jm[:, 3 * i:3 * i + 2, col] = perp(p3 - c[:, k])
                    Jm[:, 3 * i + 2, col] = 1.0
                else:
                    Jm[:, 3 * i:3 * i + 2, col] = ax[:, k]
        return F, Jm

    extra = None
    for _ in range(60):
        F, Jm = residual(z)
        dz = -np.linalg.solve(Jm, F.astype(float)[:, :, None])[:, :, 0]
        # backtracking on |F| (only away from convergence, where |F| is not rounding noise)
        f0 = np.linalg.norm(F, axis=1)
        lam = np.ones(B)
        for _ in range(40):
            f1 = np.linalg.norm(residual(z + lam[:, None] * dz)[0], axis=1)
            bad = (f1 > f0) & (f0 > 1e-10)
            if not np.any(bad):
                break
            lam[bad] *= 0.5
        dz = lam[:, None] * dz
        z = z + dz
        small = np.max(np.abs(dz)) <= 1e-12 * (1.0 + np.max(np.abs(z)))
        if extra is None and small:
            extra = 3
        if extra is not None:
            extra -= 1
            if extra < 0:
                break
    F, _ = residual(z)
    if not np.all(np.isfinite(F)) or np.max(np.abs(F)) > tol:
        raise RuntimeError(f"loop closure did not converge (residual {np.max(np.abs(F)):.3g})")
    return z[:, :3]


# --------------------------------------------------------------------------------------------------
# specifications, variables, configurations
# --------------------------------------------------------------------------------------------------

def _check_spec(robot: Robot, spec, allowed, what):
    """Validated spec ``[[dict, x3], x3]`` (leg, joint) of source magnitudes from a file-format dict."""
    if spec is None:
        return [[{} for _ in range(3)] for _ in range(3)]
    legs = spec.get("legs") if isinstance(spec, dict) else None
    if not isinstance(legs, list) or len(legs) != 3:
        raise ValueError(f"{what}: needs exactly three legs")
    out = []
    for i, (L, leg) in enumerate(zip(legs, robot.legs)):
        js = L.get("joints") if isinstance(L, dict) else None
        if not isinstance(js, list) or len(js) != 3:
            raise ValueError(f"{what}: legs[{i}].joints needs exactly three entries")
        row = []
        for k, (J, joint) in enumerate(zip(js, leg.joints)):
            w = f"{what}: legs[{i}].joints[{k}]"
            if not isinstance(J, dict):
                raise ValueError(f"{w} must be a table")
            d = {}
            for key, val in J.items():
                if key == "block_length":
                    continue
                if key not in allowed:
                    raise ValueError(f"{w}: unknown source {key!r}")
                val = float(val)
                if not (np.isfinite(val) and val >= 0):
                    raise ValueError(f"{w}.{key} must be a finite number >= 0")
                if key == "radial" and joint.kind != "R":
                    raise ValueError(f"{w}: radial clearance needs an R joint")
                if key in ("angular", "lateral") and joint.kind != "P":
                    raise ValueError(f"{w}: {key} clearance needs a P joint")
                if key == "actuator" and not joint.actuated:
                    raise ValueError(f"{w}: actuator error on a passive joint")
                if key == "length" and np.hypot(*joint.link) == 0:
                    raise ValueError(f"{w}: length tolerance on a zero link")
                if key == "lateral":
                    Lb = float(J.get("block_length", np.nan))
                    if not (np.isfinite(Lb) and Lb > 0):
                        raise ValueError(f"{w}: lateral clearance needs block_length > 0")
                    d["block_length"] = Lb
                d[key] = val
            if "block_length" in J and "lateral" not in J:
                raise ValueError(f"{w}: block_length without lateral")
            row.append(d)
        out.append(row)
    return out


def merge_specs(robot, clearances, tolerances=None):
    """One spec ``[[dict, x3], x3]`` (leg, joint) of source magnitudes from the clearance and tolerance
    dicts (file format); ValueError naming leg/joint/source on a bad entry."""
    robot = as_robot(robot)
    a = _check_spec(robot, clearances, CLEARANCE_SOURCES, "clearances")
    b = _check_spec(robot, tolerances, TOLERANCE_SOURCES, "tolerances")
    return [[{**a[i][k], **b[i][k]} for k in range(3)] for i in range(3)]


def variables(spec):
    """The scalar variables ``[(leg, joint, source, component), ...]`` of a merged spec (:func:`merge_specs`),
    in leg, joint, source (sorted), component order; sources with magnitude 0 are skipped."""
    out = []
    for i in range(3):
        for k in range(3):
            for src in sorted(s for s in spec[i][k] if s in SOURCE_SIZE):
                if spec[i][k][src] > 0:
                    out += [(i, k, src, c) for c in range(SOURCE_SIZE[src])]
    return out


def _to_arrays(vars_, values):
    """Error arrays (:func:`_zero_errors`) of a batch of flat configurations ``values`` ``(B, n)`` over
    ``vars_``."""
    values = np.atleast_2d(np.asarray(values, float))
    err = _zero_errors(values.shape[0])
    for j, (i, k, src, c) in enumerate(vars_):
        v = values[:, j]
        if src in ("radial", "position"):
            err["T"][:, i, k, c] += v
        elif src == "direction":
            err["R"][:, i, k] += v
        elif src == "angular":
            err["ang"][:, i, k] += v
        elif src == "actuator":
            err["dq"][:, i, k] += v
        elif src == "length":
            err["dl"][:, i, k] += v
        elif src == "lateral":
            err["sig" if c == 0 else "tl"][:, i, k] += v
        else:  # pragma: no cover
            raise ValueError(src)
    return err


def config_to_flat(config):
    """A configuration ``[[dict, x3], x3]`` -> ``(vars, values (n,))`` (see the module's formats)."""
    vars_, vals = [], []
    for i in range(3):
        for k in range(3):
            for src, v in sorted(config[i][k].items()):
                if src not in SOURCE_SIZE:
                    raise ValueError(f"errors[{i}][{k}]: unknown source {src!r}")
                v = np.atleast_1d(np.asarray(v, float))
                if v.shape != (SOURCE_SIZE[src],):
                    raise ValueError(f"errors[{i}][{k}].{src} needs {SOURCE_SIZE[src]} value(s)")
                vars_ += [(i, k, src, c) for c in range(SOURCE_SIZE[src])]
                vals += list(v)
    return vars_, np.array(vals, float)


def flat_to_config(vars_, values):
    """Flat values ``(n,)`` over ``vars_`` -> configuration ``[[dict, x3], x3]`` (2-lists for two-variable
    sources, floats otherwise)."""
    cfg = [[{} for _ in range(3)] for _ in range(3)]
    for (i, k, src, c), v in zip(vars_, values):
        if SOURCE_SIZE[src] == 2:
            cfg[i][k].setdefault(src, [0.0, 0.0])[c] = float(v)
        else:
            cfg[i][k][src] = float(v)
    return cfg


def _validate_config(robot: Robot, vars_):
    for i, k, src, _ in vars_:
        J = robot.legs[i].joints[k]
        if src == "radial" and J.kind != "R" or src in ("angular", "lateral") and J.kind != "P":
            raise ValueError(f"errors[{i}][{k}]: {src} does not apply to a {J.kind} joint")
        if src == "actuator" and not J.actuated:
            raise ValueError(f"errors[{i}][{k}]: actuator error on a passive joint")
        if src == "length" and np.hypot(*J.link) == 0:
            raise ValueError(f"errors[{i}][{k}]: length error on a zero link")


# --------------------------------------------------------------------------------------------------
# public API
# --------------------------------------------------------------------------------------------------

def pose_with_errors(robot, pose, joints0=None, errors=None):
    """Exact platform pose ``(3,)`` (mm, mm, rad) with the actuators held at their commanded values and the
    error configuration ``errors`` (``[[dict, x3], x3]``, see the module's formats; None: no errors) inserted.

    ``joints0`` ``(3, 3)`` (leg, joint): the commanded chain configuration at ``pose`` (default
    :func:`inverse_kinematics`); its actuated values are held, its passive values start Newton's method
    (which picks that assembly branch). The loop closures are solved to machine precision (:func:`_solve`).
    """
    robot = as_robot(robot)
    pose = np.asarray(pose, float)
    q0 = inverse_kinematics(robot, pose) if joints0 is None else np.asarray(joints0, float)
    if errors is None:
        vars_, vals = [], np.zeros(0)
    else:
        vars_, vals = config_to_flat(errors)
        _validate_config(robot, vars_)
    return _solve(robot, pose, q0, _to_arrays(vars_, vals[None]))[0].astype(float)


def nonlinear_at(robot, pose, config, joints0=None):
    """Exact pose error ``[dx, dy, dphi]`` ``(3,)`` (mm, mm, rad) of the error configuration ``config``
    (``[[dict, x3], x3]``): :func:`pose_with_errors` minus ``pose`` (dphi wrapped)."""
    robot = as_robot(robot)
    pose = np.asarray(pose, float)
    q0 = inverse_kinematics(robot, pose) if joints0 is None else np.asarray(joints0, float)
    vars_, vals = config_to_flat(config)
    _validate_config(robot, vars_)
    d = _solve(robot, pose, q0, _to_arrays(vars_, vals[None]))[0] - pose
    d[2] = wrap(d[2])
    return d.astype(float)


def error_jacobian_fd(robot, pose, spec, tolerances=None, joints0=None, h=1e-6):
    """Error Jacobian by central differences of the exact pose: ``(G (3, n), vars)``.

    ``G[:, j] = (X(+h e_j) - X(-h e_j)) / (2 h)`` with ``X`` the exact pose (:func:`pose_with_errors`, all
    2n configurations solved as one batch), rows dx (mm), dy (mm), dphi (rad) per unit of variable j
    (mm or rad, ``vars`` as in :func:`variables`). ``spec``: the clearance dict (file format) or an already
    merged spec (list, :func:`merge_specs`); ``tolerances``: the tolerance dict or None. Step ``h`` in the
    variable's unit (mm or rad). Accuracy: truncation ``h^2 X'''/6`` plus rounding ``~1e-17 mm / h`` (the
    poses are solved in extended precision); measured against Richardson extrapolation, h = 1e-6 gives a
    relative error (per row) of ~1e-11 on typical robots and ~1e-9 on strongly nonlinear ones.
    """
    robot = as_robot(robot)
    pose = np.asarray(pose, float)
    merged = spec if isinstance(spec, list) else merge_specs(robot, spec, tolerances)
    vars_ = variables(merged)
    n = len(vars_)
    q0 = inverse_kinematics(robot, pose) if joints0 is None else np.asarray(joints0, float)
    if n == 0:
        return np.zeros((3, 0)), vars_
    steps = np.concatenate([h * np.eye(n), -h * np.eye(n)])
    X = _solve(robot, pose, q0, _to_arrays(vars_, steps))
    D = X[:n] - X[n:]
    D[:, 2] = wrap(D[:, 2])
    return (D / (2 * h)).T.astype(float), vars_


def _sources(spec, vars_):
    """Group the variables by source: list of ``(kind, eps, cols, block_length)`` with kind "disk",
    "interval" or "rhombus" and ``cols`` the indices of its variables in ``vars_``."""
    out = []
    j = 0
    while j < len(vars_):
        i, k, src, _ = vars_[j]
        m = SOURCE_SIZE[src]
        eps = spec[i][k][src]
        kind = "disk" if src in ("radial", "position") else "rhombus" if src == "lateral" else "interval"
        out.append((kind, eps, list(range(j, j + m)), spec[i][k].get("block_length")))
        j += m
    return out


def support(G, sources, C):
    """Support function of the image of the error set and its maximizers.

    ``G`` ``(3, n)``, ``sources`` (:func:`_sources`), directions ``C`` ``(N, 3)`` (weights of dx, dy, dphi).
    Returns ``h`` ``(N,)`` = ``sum_s max_{e_s in set_s} C (G_s e_s)``: disk ``eps |C G_s|``, interval
    ``eps |C g|``, rhombus the best of its four vertices ``(+-eps, 0), (0, +-2 eps/L)``; and the maximizing
    flat configurations ``(N, n)``.
    """
    C = np.atleast_2d(np.asarray(C, float))
    N, n = C.shape[0], G.shape[1]
    h = np.zeros(N)
    arg = np.zeros((N, n))
    proj = C @ G                                     # (N, n): C . g_j
    for kind, eps, cols, L in sources:
        P = proj[:, cols]
        if kind == "disk":
            nrm = np.linalg.norm(P, axis=1)
            h += eps * nrm
            arg[:, cols] = eps * P / np.where(nrm > 0, nrm, 1.0)[:, None]
        elif kind == "interval":
            h += eps * np.abs(P[:, 0])
            arg[:, cols[0]] = eps * np.where(P[:, 0] >= 0, 1.0, -1.0)
        else:
            V = np.array([[eps, 0.0], [-eps, 0.0], [0.0, 2 * eps / L], [0.0, -2 * eps / L]])
            vals = P @ V.T                               # (N, 4)
            b = np.argmax(vals, axis=1)
            h += vals[np.arange(N), b]
            arg[:, cols] = V[b]
    return h, arg


def worst_case(robot, pose, clearances, tolerances=None, joints0=None, h=1e-6, n_dir=20000):
    """First-order worst-case pose errors by brute force over the error set.

    ``clearances``/``tolerances``: file-format dicts (or None). With the FD error Jacobian ``G`` (3, n)
    (:func:`error_jacobian_fd`, step ``h``) and the support function ``h_S(c)`` of the error set's image
    (:func:`support`):

    * ``dx_max = h_S(e_x)``, ``dy_max = h_S(e_y)`` (mm), ``dphi_max = h_S(e_phi)`` (rad);
    * ``dp_max = max_a h_S(cos a, sin a, 0)`` (mm): ``n_dir`` directions on [0, 2 pi), then a bounded
      (Brent) scalar maximization within +-2 grid steps of the best one.

    Returns a dict: ``dx_max, dy_max, dphi_max, dp_max`` (floats), ``dp_angle`` (rad, direction of the
    maximal displacement), ``argmax`` (dict dx/dy/dphi/dp -> configuration ``[[dict, x3], x3]`` attaining the
    first-order maximum, with positive sign), ``argmax_flat`` (same, ``(n,)`` arrays), ``jacobian`` (G),
    ``variables`` and ``spec`` (the merged spec).
    """
    robot = as_robot(robot)
    spec = merge_specs(robot, clearances, tolerances)
    G, vars_ = error_jacobian_fd(robot, pose, spec, joints0=joints0, h=h)
    src = _sources(spec, vars_)
    hx, ax = support(G, src, np.eye(3))
    a = np.linspace(0.0, TWO_PI, n_dir, endpoint=False)

    def dirs(t):
        t = np.atleast_1d(t)
        return np.stack([np.cos(t), np.sin(t), np.zeros_like(t)], 1)

    hp, _ = support(G, src, dirs(a))
    b = int(np.argmax(hp))
    da = TWO_PI / n_dir
    res = optimize.minimize_scalar(lambda t: -support(G, src, dirs(t))[0][0], bounds=(a[b] - 2 * da, a[b] + 2 * da),
                                   method="bounded", options=dict(xatol=1e-13))
    best = float(res.x) if -res.fun >= hp[b] else float(a[b])
    hbest, abest = support(G, src, dirs(best))
    flat = {"dx": ax[0], "dy": ax[1], "dphi": ax[2], "dp": abest[0]}
    return dict(dx_max=float(hx[0]), dy_max=float(hx[1]), dphi_max=float(hx[2]), dp_max=float(hbest[0]),
                dp_angle=float(wrap(best)), argmax={k: flat_to_config(vars_, v) for k, v in flat.items()},
                argmax_flat=flat, jacobian=G, variables=vars_, spec=spec)


def random_clearances(rng, robot, p_skip: float = 0.15):
    """Random ``(clearances, tolerances)`` dicts (file format) for every joint of ``robot``.

    Clearances: R ``radial`` U(0.005, 0.05) mm; P ``angular`` U(1e-4, 2e-3) rad and ``lateral``
    U(0.001, 0.005) mm with ``block_length`` U(20, 60) mm; the actuated joint ``actuator`` U(0.001, 0.01) mm
    (P) or U(1e-4, 1e-3) rad (R). Tolerances: ``position`` U(0.005, 0.05) mm, ``direction`` U(1e-4, 2e-3)
    rad, ``length`` U(0.005, 0.05) mm on non-zero links. Each source is left out with probability
    ``p_skip``.
    """
    robot = as_robot(robot)
    cl, tol = [], []
    for leg in robot.legs:
        cj, tj = [], []
        for J in leg.joints:
            c, t = {}, {}
            if J.kind == "R":
                c["radial"] = rng.uniform(0.005, 0.05)
            else:
                c["angular"] = rng.uniform(1e-4, 2e-3)
                c["lateral"] = rng.uniform(0.001, 0.005)
            if J.actuated:
                c["actuator"] = rng.uniform(0.001, 0.01) if J.kind == "P" else rng.uniform(1e-4, 1e-3)
            t["position"] = rng.uniform(0.005, 0.05)
            t["direction"] = rng.uniform(1e-4, 2e-3)
            if np.hypot(*J.link) > 0:
                t["length"] = rng.uniform(0.005, 0.05)
            c = {k: float(v) for k, v in c.items() if rng.uniform() >= p_skip}
            t = {k: float(v) for k, v in t.items() if rng.uniform() >= p_skip}
            if "lateral" in c:
                c["block_length"] = float(rng.uniform(20, 60))
            cj.append(c)
            tj.append(t)
        cl.append({"joints": cj})
        tol.append({"joints": tj})
    return {"legs": cl}, {"legs": tol}
