"""Independent reference model of planar 3-DOF parallel manipulators with three legs (tests only).

Written from the kinematic conventions alone (numpy, scipy, shapely); it does not import
``pmaccuracy``. It serves as the reference the library's general planar kinematics is checked
against.

Conventions
-----------
Lengths in mm and angles in rad inside the code; the robot dictionaries (parsed TOML) hold angles in
degrees in keys ending in ``deg`` (and the ``range`` of an R joint of a chain, in degrees).
A pose is ``[x, y, phi]`` (mm, mm, rad): the platform frame has origin ``P = (x, y)`` and is turned
by ``phi``; a platform point ``d`` (platform frame) is at ``P + Rot(phi) d`` in the base frame.
``E = [[0, -1], [1, 0]]`` turns a vector by +90 deg; ``cross(a, b) = a_x b_y - a_y b_x``.

Every robot is converted by :func:`load` to three serial *chains* of one-DOF joints (R or P), base to
platform, exactly one actuated per leg. Chain convention: start from the frame F0 (origin ``base``,
angle ``base_angle``); joint j with value q_j turns the frame by ``offset_j`` (+ ``q_j`` for an R joint,
about the current origin, which is the joint's centre); a P joint then slides the origin by ``q_j``
along the new x-axis; every joint then moves the origin by ``Rot(angle) link_j``. The end frame F3 must
equal the platform attachment frame (origin ``P + Rot(phi) platform``, angle ``phi + platform_angle``).

The working mode of a leg is the sign of ``B_ii = zeta . T_a`` (:func:`leg_b`): ``T_a`` the unit twist
of the actuated joint and ``zeta`` the leg's constraint wrench, reciprocal to the two passive twists
(planar screws: twist ``(omega, v_O)``, R at c: ``(1, -E c)``, P along e: ``(0, e)``; wrench
``(f, m_O)``, pairing ``m_O omega + f . v_O``).

Several independent methods are provided so that they can check each other:

* inverse kinematics per architecture from plane geometry (``method="geometric"``), for every chain in
  closed form from a decomposition of the chain into circles and lines (``"chain"``), and by a generic
  multi-start Newton solver on the chain's loop equations (``"numeric"``): :func:`inverse_kinematics`;
* forward kinematics by a dense scan of the orientation (:func:`forward_kinematics_scan`);
* Jacobians by central differences of the IK (:func:`jacobian_fd`);
* the constant-orientation workspace by exact vertical slices (:func:`workspace_area_slices`),
  Monte Carlo (:func:`workspace_area_mc`) and shapely polygon clipping (:func:`workspace_area_shapely`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import integrate, optimize

TWO_PI = 2.0 * np.pi
#: Slide (mm) used to read the direction of a P joint off the chain (large enough to keep rounding small).
_SLIDE = 256.0
_E = np.array([[0.0, -1.0], [1.0, 0.0]])


# --------------------------------------------------------------------------------------------------
# small planar helpers
# --------------------------------------------------------------------------------------------------

def vec(t):
    """Unit vectors ``[cos t, sin t]``: angles ``(...)`` (rad) -> ``(..., 2)``."""
    t = np.asarray(t, float)
    return np.stack([np.cos(t), np.sin(t)], axis=-1)


def rot(t, v):
    """``Rot(t) v``: angles ``(...)`` (rad) and vectors ``(..., 2)`` (broadcast) -> ``(..., 2)``."""
    t = np.asarray(t, float)
    v = np.asarray(v, float)
    c, s = np.cos(t), np.sin(t)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


def perp(v):
    """``E v`` (v turned by +90 deg): ``(..., 2)`` -> ``(..., 2)``."""
    v = np.asarray(v, float)
    return np.stack([-v[..., 1], v[..., 0]], axis=-1)


def cross(a, b):
    """``a_x b_y - a_y b_x`` of ``(..., 2)`` arrays -> ``(...)``."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def wrap(a):
    """Angles (rad) wrapped to ``(-pi, pi]``, any shape."""
    return np.pi - np.mod(np.pi - np.asarray(a, float), TWO_PI)


def angle_in_range(q, lo, hi):
    """Whether ``q + 2 pi k`` lies in ``[lo, hi]`` for some integer k (all rad, broadcast); False for NaN."""
    q = np.asarray(q, float)
    k = np.ceil((lo - q) / TWO_PI)          # smallest k with q + 2 pi k >= lo
    with np.errstate(invalid="ignore"):
        return np.isfinite(q) & (q + TWO_PI * k <= hi)


def nearest_to(q, centre):
    """The representative ``q + 2 pi k`` nearest to ``centre`` (rad, broadcast)."""
    return centre + wrap(np.asarray(q, float) - centre)


# --------------------------------------------------------------------------------------------------
# robot description
# --------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Joint:
    """One joint of a chain: ``kind`` "R" or "P", ``offset`` (rad), ``link`` (mm, 2-tuple), ``range``
    ``(lo, hi)`` (rad for R, mm for P) or None (unlimited)."""

    kind: str
    actuated: bool
    offset: float
    link: tuple
    range: tuple | None


@dataclass(frozen=True)
class Leg:
    """A leg as a chain: ``base`` (mm), ``base_angle`` (rad), ``platform`` (mm, platform frame),
    ``platform_angle`` (rad), ``working_mode`` (+1/-1), three :class:`Joint` base to platform, and
    ``geom``: the architecture's own parameters (a dict, see :func:`load`) or None for a chain."""

    base: tuple
    base_angle: float
    platform: tuple
    platform_angle: float
    working_mode: int
    joints: tuple
    geom: Any = None

    @property
    def kinds(self) -> str:
        return "".join(j.kind for j in self.joints)

    @property
    def act(self) -> int:
        return next(i for i, j in enumerate(self.joints) if j.actuated)

    @property
    def passive(self) -> tuple:
        return tuple(i for i, j in enumerate(self.joints) if not j.actuated)

    @property
    def n_branches(self) -> int:
        """Number of inverse-kinematics branches: 1 for a leg with one R joint, else 2."""
        return 1 if self.kinds.count("R") == 1 else 2


@dataclass(frozen=True)
class Robot:
    """Architecture name and three :class:`Leg`."""

    architecture: str
    legs: tuple

    @property
    def scale(self) -> float:
        """A length scale (mm) of the robot: the largest base distance, link, platform radius or P limit."""
        vals = [1.0]
        for leg in self.legs:
            vals += [np.hypot(*leg.base), np.hypot(*leg.platform)]
            for j in leg.joints:
                vals.append(np.hypot(*j.link))
                if j.kind == "P" and j.range is not None:
                    vals += [abs(j.range[0]), abs(j.range[1])]
        return float(max(vals))


def _f2(v, what):
    a = np.asarray(v, float)
    if a.shape != (2,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be two finite numbers, got {v!r}")
    return (float(a[0]), float(a[1]))


def _rng2(v, what):
    lo, hi = _f2(v, what)
    if not lo < hi:
        raise ValueError(f"{what} must be [lo, hi] with lo < hi, got {v!r}")
    return (lo, hi)


def load(d: dict) -> Robot:
    """Robot from a parsed robot file (dict) of architecture "3-RPR", "3-RRR", "3-PRR", "3-PPR" or "chain".

    Every leg becomes a chain (the equivalences of the brief):

    * 3-RPR: ``[R(q1 = angle of A->D), P actuated (q2 = |AD|), R(q3 = phi - q1)]``, base A, platform D,
      working mode +1 (the length is positive); ``geom = {"type": "RPR", A, D, range}``.
    * 3-RRR: ``[R actuated, link (proximal, 0); R, link (distal, 0); R]``, base A;
      ``geom = {"type": "RRR", A, D, l1, l2, range (rad)}``.
    * 3-PRR: ``[P actuated; R, link (distal, 0); R]``, base = guide point, base angle = guide angle;
      ``geom = {"type": "PRR", G, u_angle, D, l2, range}``.
    * 3-PPR (the paper's Eq. 1, keys a, alpha_deg, beta_deg, gamma_deg, theta_deg, d, r, psi_deg,
      s_range, l_range): ``[P actuated s along u, link d (cos gamma, sin gamma);
      P passive l (offset gamma + theta, range l_range); R]``, base ``a h``, base angle alpha + beta,
      platform ``-r vec(psi)``; ``geom = {"type": "PPR", ...}``.
    """
    arch = d.get("architecture")
    legs_in = d.get("legs")
    if not isinstance(legs_in, list) or len(legs_in) != 3:
        raise ValueError("a robot needs exactly three [[legs]]")
    legs = []
    for i, L in enumerate(legs_in):
        w = f"legs[{i}]"
        if arch == "3-RPR":
            A, D = _f2(L["base"], w + ".base"), _f2(L["platform"], w + ".platform")
            rg = _rng2(L["length_range"], w + ".length_range")
            joints = (Joint("R", False, 0.0, (0.0, 0.0), None), Joint("P", True, 0.0, (0.0, 0.0), rg),
                      Joint("R", False, 0.0, (0.0, 0.0), None))
            legs.append(Leg(A, 0.0, D, 0.0, 1, joints, dict(type="RPR", A=A, D=D, range=rg)))
        elif arch == "3-RRR":
            A, D = _f2(L["base"], w + ".base"), _f2(L["platform"], w + ".platform")
            l1, l2 = float(L["proximal"]), float(L["distal"])
            rg = tuple(np.radians(_rng2(L["angle_range_deg"], w + ".angle_range_deg")))
            wm = int(L["working_mode"])
            joints = (Joint("R", True, 0.0, (l1, 0.0), rg), Joint("R", False, 0.0, (l2, 0.0), None),
                      Joint("R", False, 0.0, (0.0, 0.0), None))
            legs.append(Leg(A, 0.0, D, 0.0, wm, joints, dict(type="RRR", A=A, D=D, l1=l1, l2=l2, range=rg)))
        elif arch == "3-PRR":
            G, D = _f2(L["guide_point"], w + ".guide_point"), _f2(L["platform"], w + ".platform")
            g = math.radians(float(L["guide_deg"]))
            l2 = float(L["distal"])
            rg = _rng2(L["s_range"], w + ".s_range")
            wm = int(L["working_mode"])
            joints = (Joint("P", True, 0.0, (0.0, 0.0), rg), Joint("R", False, 0.0, (l2, 0.0), None),
                      Joint("R", False, 0.0, (0.0, 0.0), None))
            legs.append(Leg(G, g, D, 0.0, wm, joints, dict(type="PRR", G=G, g=g, D=D, l2=l2, range=rg)))
        elif arch == "3-PPR":
            a = float(L["a"])
            al, be, ga, th, ps = (math.radians(float(L[k])) for k in
                                  ("alpha_deg", "beta_deg", "gamma_deg", "theta_deg", "psi_deg"))
            dd, r = float(L["d"]), float(L["r"])
            srg = _rng2(L["s_range"], w + ".s_range")
            lrg = _rng2(L["l_range"], w + ".l_range") if "l_range" in L else None
            base = (a * math.cos(al), a * math.sin(al))
            D = (-r * math.cos(ps), -r * math.sin(ps))
            joints = (Joint("P", True, 0.0, (dd * math.cos(ga), dd * math.sin(ga)), srg),
                      Joint("P", False, ga + th, (0.0, 0.0), lrg),
                      Joint("R", False, 0.0, (0.0, 0.0), None))
            geom = dict(type="PPR", A=base, u=al + be, v=al + be + ga, w=al + be + ga + th, d=dd, D=D,
                        range=srg, l_range=lrg)
            legs.append(Leg(base, al + be, D, 0.0, 1, joints, geom))
        elif arch == "chain":
            js = L.get("joints")
            if not isinstance(js, list) or len(js) != 3:
                raise ValueError(f"{w}: a chain leg needs exactly three [[legs.joints]]")
            joints = []
            for k, J in enumerate(js):
                kind = J["type"]
                if kind not in ("R", "P"):
                    raise ValueError(f"{w}.joints[{k}].type must be 'R' or 'P'")
                act = bool(J.get("actuated", False))
                rg = J.get("range")
                if rg is not None:
                    rg = _rng2(rg, f"{w}.joints[{k}].range")
                    if kind == "R":
                        rg = (math.radians(rg[0]), math.radians(rg[1]))
                elif act:
                    raise ValueError(f"{w}.joints[{k}]: the actuated joint needs a range")
                joints.append(Joint(kind, act, math.radians(float(J.get("offset_deg", 0.0))),
                                    _f2(J.get("link", [0.0, 0.0]), f"{w}.joints[{k}].link"), rg))
            if sum(j.actuated for j in joints) != 1:
                raise ValueError(f"{w}: exactly one joint must be actuated")
            if not any(j.kind == "R" for j in joints):
                raise ValueError(f"{w}: a leg needs at least one R joint")
            wm = int(L.get("working_mode", 1))
            legs.append(Leg(_f2(L["base"], w + ".base"), math.radians(float(L.get("base_deg", 0.0))),
                            _f2(L["platform"], w + ".platform"), math.radians(float(L.get("platform_deg", 0.0))),
                            wm, tuple(joints)))
        else:
            raise ValueError(f"unknown architecture {arch!r}")
        if legs[-1].working_mode not in (1, -1):
            raise ValueError(f"{w}.working_mode must be +1 or -1")
    return Robot(arch, tuple(legs))


def to_chain_dict(d: dict) -> dict:
    """The "chain" robot dict equivalent to a 3-RPR / 3-RRR / 3-PRR / 3-PPR dict (the brief's equivalences)."""
    robot = load(d)
    legs = []
    for leg in robot.legs:
        js = []
        for j in leg.joints:
            J = dict(type=j.kind, actuated=j.actuated, offset_deg=math.degrees(j.offset), link=list(j.link))
            if j.range is not None:
                J["range"] = [math.degrees(v) for v in j.range] if j.kind == "R" else list(j.range)
            js.append(J)
        legs.append(dict(base=list(leg.base), base_deg=math.degrees(leg.base_angle), platform=list(leg.platform),
                         platform_deg=math.degrees(leg.platform_angle), working_mode=leg.working_mode, joints=js))
    return dict(architecture="chain", legs=legs)


def aalborg_3ppr() -> dict:
    """The reconstructed Aalborg 3-PPR of the reference document, as a "3-PPR" robot dict."""
    rows = [(192.34, 180, -90, -90, 0, 83.15, 30, 30, [-40.0, 10.0]),
            (192.34, 0, 90, 90, 0, 83.15, 30, 150, [-40.0, 10.0]),
            (192.34, 90, 90, 90, 0, 70.00, 30, -90, [-25.0, 25.0])]
    legs = [dict(a=a, alpha_deg=al, beta_deg=be, gamma_deg=ga, theta_deg=th, d=dd, r=r, psi_deg=ps,
                 s_range=s, l_range=[20.0, 160.0]) for a, al, be, ga, th, dd, r, ps, s in rows]
    return dict(architecture="3-PPR", legs=legs)


# --------------------------------------------------------------------------------------------------
# chain kinematics
# --------------------------------------------------------------------------------------------------

def leg_fk(leg: Leg, q):
    """Forward kinematics of one chain.

    ``q`` ``(..., 3)`` joint values (rad for R, mm for P) -> ``(p3, theta3, centres, axes)``:
    end-frame origin ``(..., 2)`` (mm) and angle ``(...)`` (rad, not wrapped), the frame origin *before*
    each joint ``(..., 3, 2)`` (the centre of an R joint) and the frame x-axis after each joint's turn
    ``(..., 3, 2)`` (the direction of a P joint).
    """
    q = np.asarray(q, float)
    shp = q.shape[:-1]
    theta = np.full(shp, leg.base_angle)
    p = np.broadcast_to(np.asarray(leg.base, float), shp + (2,)).copy()
    centres, axes = [], []
    for k, J in enumerate(leg.joints):
        theta = theta + J.offset + (q[..., k] if J.kind == "R" else 0.0)
        centres.append(p)
        ax = vec(theta)
        axes.append(ax)
        if J.kind == "P":
            p = p + q[..., k, None] * ax
        p = p + rot(theta, np.asarray(J.link, float))
    return p, theta, np.stack(centres, axis=-2), np.stack(axes, axis=-2)


def leg_twists(leg: Leg, q):
    """Unit joint twists ``(omega, v_O)`` of the chain at ``q`` ``(..., 3)``: ``(..., 3, 3)`` (joint, component).

    R at centre c: ``(1, -E c)`` (``v_O`` in mm per rad); P along e: ``(0, e)``.
    """
    _, _, c, ax = leg_fk(leg, q)
    out = np.zeros(c.shape[:-1] + (3,))
    for k, J in enumerate(leg.joints):
        if J.kind == "R":
            out[..., k, 0] = 1.0
            out[..., k, 1:] = -perp(c[..., k, :])
        else:
            out[..., k, 1:] = ax[..., k, :]
    return out


def leg_wrench(leg: Leg, q):
    """Normalized constraint wrench ``(f_x, f_y, m_O)`` ``(..., 3)`` reciprocal to the two passive twists.

    Passive R at c1 and R at c2 (c1 earlier): ``f = (c2 - c1)/|c2 - c1|``, line through c1
    (``m_O = cross(c1, f)``); passive R at c and P along e: ``f = E e`` through c; two passive P:
    ``f = 0, m_O = 1``.
    """
    _, _, c, ax = leg_fk(leg, q)
    m, n = leg.passive
    km, kn = leg.joints[m].kind, leg.joints[n].kind
    out = np.zeros(c.shape[:-2] + (3,))
    if km == "R" and kn == "R":
        f = c[..., n, :] - c[..., m, :]
        f = f / np.linalg.norm(f, axis=-1, keepdims=True)
        pt = c[..., m, :]
    elif km == "P" and kn == "P":
        out[..., 2] = 1.0
        return out
    else:
        r, p = (m, n) if km == "R" else (n, m)
        f = perp(ax[..., p, :])
        pt = c[..., r, :]
    out[..., :2] = f
    out[..., 2] = cross(pt, f)
    return out


def pairing(wrench, twist):
    """Reciprocal product ``m_O omega + f . v_O`` of wrenches ``(..., 3)`` and twists ``(..., 3)``."""
    return wrench[..., 2] * twist[..., 0] + wrench[..., 0] * twist[..., 1] + wrench[..., 1] * twist[..., 2]


def leg_b(leg: Leg, q):
    """``B_ii = zeta . T_a`` at the chain configuration ``q`` ``(..., 3)`` -> ``(...)`` (mm for an actuated R,
    dimensionless for an actuated P)."""
    return pairing(leg_wrench(leg, q), leg_twists(leg, q)[..., leg.act, :])


def _targets(leg: Leg, poses):
    """End-frame targets of a leg: origin ``P + Rot(phi) platform`` ``(N, 2)`` and angle ``phi + platform_angle``."""
    return poses[:, :2] + rot(poses[:, 2], np.asarray(leg.platform)), poses[:, 2] + leg.platform_angle


# ---- closed form for every chain (decomposition into circles and lines) -------------------------

def _chain_ik_all(leg: Leg, X, Th):
    """All inverse-kinematics branches of a chain in closed form.

    ``X`` ``(N, 2)`` end-frame origin (mm), ``Th`` ``(N,)`` end-frame angle (rad) -> ``q`` ``(N, nb, 3)`` and
    ``ok`` ``(N, nb)`` (nb = :attr:`Leg.n_branches`; NaN where unreachable). The sum of the R values is
    ``C = Th - base_angle - sum(offsets)``. One R: the R value is C and the two P slides solve a 2x2
    linear system. Two R (at m < n, P at s): with ``q_m = t``, ``q_n = C - t``, ``q_s = sigma`` the end point
    is ``K + sigma a_out + Rot(t)(U + sigma a_in)`` (a_out or a_in zero), all read off the chain at
    t in {0, pi}, sigma in {0, 1}; ``|X - K - sigma a_out| = |U + sigma a_in|`` is a quadratic in sigma.
    Three R: ``K + Rot(t1)(U + Rot(t2) V)``: a circle-circle intersection for ``Rot(t1) U``.
    """
    N = len(X)
    C = Th - leg.base_angle - sum(j.offset for j in leg.joints)
    R = [k for k in range(3) if leg.joints[k].kind == "R"]
    P = [k for k in range(3) if leg.joints[k].kind == "P"]

    def f(assign):
        q = np.zeros((N, 3))
        for k, v in assign.items():
            q[:, k] = v
        return leg_fk(leg, q)[0]

    if len(R) == 1:
        r = R[0]
        base = {r: C}
        p0 = f({**base})
        a1 = (f({**base, P[0]: _SLIDE}) - p0) / _SLIDE
        a2 = (f({**base, P[1]: _SLIDE}) - p0) / _SLIDE
        M = np.stack([a1, a2], axis=-1)
        sig = np.linalg.solve(M, (X - p0)[..., None])[..., 0]
        q = np.zeros((N, 1, 3))
        q[:, 0, r] = C
        q[:, 0, P[0]] = sig[:, 0]
        q[:, 0, P[1]] = sig[:, 1]
        ok = np.ones((N, 1), bool)
    elif len(R) == 2:
        m, n = R
        s = P[0]
        f00 = f({m: 0.0, n: C, s: 0.0})
        fp0 = f({m: np.pi, n: C - np.pi, s: 0.0})
        f01 = f({m: 0.0, n: C, s: _SLIDE})
        fp1 = f({m: np.pi, n: C - np.pi, s: _SLIDE})
        K = (f00 + fp0) / 2
        U = (f00 - fp0) / 2
        a_out = ((f01 + fp1) / 2 - K) / _SLIDE
        a_in = ((f01 - fp1) / 2 - U) / _SLIDE
        Z = X - K
        A2 = np.sum(a_out ** 2, -1) - np.sum(a_in ** 2, -1)
        B2 = -(np.sum(Z * a_out, -1) + np.sum(U * a_in, -1))
        C2 = np.sum(Z ** 2, -1) - np.sum(U ** 2, -1)
        disc = B2 ** 2 - A2 * C2
        with np.errstate(invalid="ignore"):
            sq = np.sqrt(disc)
        # numerically stable roots of A2 s^2 + 2 B2 s + C2 = 0
        qq = -(B2 + np.where(B2 >= 0, 1.0, -1.0) * sq)
        with np.errstate(invalid="ignore", divide="ignore"):
            roots = (qq / A2, np.where(qq != 0, C2 / np.where(qq != 0, qq, 1.0), qq / A2))
        q = np.full((N, 2, 3), np.nan)
        for b, sig in enumerate(roots):
            w_out = Z - sig[:, None] * a_out
            w_in = U + sig[:, None] * a_in
            t = np.arctan2(w_out[:, 1], w_out[:, 0]) - np.arctan2(w_in[:, 1], w_in[:, 0])
            q[:, b, m] = wrap(t)
            q[:, b, n] = wrap(C - t)
            q[:, b, s] = sig
        ok = np.repeat((disc >= 0)[:, None], 2, 1)
    else:
        f00 = f({0: 0.0, 1: 0.0, 2: C})
        fp0 = f({0: np.pi, 1: 0.0, 2: C - np.pi})
        f0p = f({0: 0.0, 1: np.pi, 2: C - np.pi})
        K = (f00 + fp0) / 2
        UpV = (f00 - fp0) / 2
        UmV = f0p - K
        U, V = (UpV + UmV) / 2, (UpV - UmV) / 2
        Z = X - K
        r1, r2 = np.linalg.norm(U, axis=-1), np.linalg.norm(V, axis=-1)
        dist = np.linalg.norm(Z, axis=-1)
        a = (r1 ** 2 - r2 ** 2 + dist ** 2) / (2 * dist)
        h2 = r1 ** 2 - a ** 2
        with np.errstate(invalid="ignore"):
            h = np.sqrt(h2)
        zh = Z / dist[:, None]
        q = np.full((N, 2, 3), np.nan)
        for b, sg in enumerate((1.0, -1.0)):
            w1 = a[:, None] * zh + sg * h[:, None] * perp(zh)
            w2 = Z - w1
            t1 = np.arctan2(w1[:, 1], w1[:, 0]) - np.arctan2(U[:, 1], U[:, 0])
            t2 = np.arctan2(w2[:, 1], w2[:, 0]) - np.arctan2(V[:, 1], V[:, 0]) - t1
            q[:, b, 0] = wrap(t1)
            q[:, b, 1] = wrap(t2)
            q[:, b, 2] = wrap(C - t1 - t2)
        ok = np.repeat((h2 >= 0)[:, None], 2, 1)
    for k in R:
        q[..., k] = wrap(q[..., k])
    q[~ok] = np.nan
    return q, ok


# ---- generic numerical solver ---------------------------------------------------------------------

def _numeric_ik_all(leg: Leg, X, Th, n_starts=12, iters=60):
    """Solutions of the chain's loop equations by damped Newton from ``n_starts`` starts per pose.

    Residual ``[p3(q) - X, wrap(theta3(q) - Th)]`` (mm, mm, rad) with the analytic Jacobian of the chain
    (column of an R joint at c: ``[E (p3 - c), 1]``, of a P joint along e: ``[e, 0]``), solved by
    ``(J^T J + mu I) dq = -J^T F`` with steps clipped to 1 rad / 200 mm. Starts: R joints on a grid of
    angles (shifted per joint), P joints at the middle of their range (0 if unlimited) plus spread.
    Returns ``q`` ``(N, n_starts, 3)`` and ``ok`` ``(N, n_starts)`` (converged to 1e-10 mm / rad).
    """
    N = len(X)
    S = n_starts
    q = np.zeros((N, S, 3))
    phases = (0.0, 0.37, 0.81)
    for k, J in enumerate(leg.joints):
        if J.kind == "R":
            q[:, :, k] = (np.arange(S) * TWO_PI / S + phases[k] * np.arange(S) ** 2)[None, :]
        else:
            mid = 0.0 if J.range is None else 0.5 * (J.range[0] + J.range[1])
            q[:, :, k] = mid + 100.0 * np.cos(np.arange(S) * 1.3)[None, :]
    q = q.reshape(N * S, 3)
    Xb = np.repeat(X, S, axis=0)
    Tb = np.repeat(Th, S)
    isR = np.array([J.kind == "R" for J in leg.joints])
    lim = np.where(isR, 1.0, 200.0)

    def residual(q, idx):
        p3, t3, c, ax = leg_fk(leg, q)
        return np.concatenate([p3 - Xb[idx], wrap(t3 - Tb[idx])[:, None]], axis=-1), p3, c, ax

    active = np.arange(N * S)
    for _ in range(iters):
        if active.size == 0:
            break
        qa = q[active]
        F, p3, c, ax = residual(qa, active)
        done = np.max(np.abs(F), axis=1) < 1e-13
        Jm = np.zeros((len(qa), 3, 3))
        for k in range(3):
            if isR[k]:
                Jm[:, :2, k] = perp(p3 - c[:, k, :])
                Jm[:, 2, k] = 1.0
            else:
                Jm[:, :2, k] = ax[:, k, :]
        JT = np.swapaxes(Jm, 1, 2)
        JtJ = JT @ Jm
        mu = 1e-12 * (JtJ[:, 0, 0] + JtJ[:, 1, 1] + JtJ[:, 2, 2]) + 1e-300
        JtJ[:, [0, 1, 2], [0, 1, 2]] += mu[:, None]
        dq = -np.linalg.solve(JtJ, (JT @ F[:, :, None]))[:, :, 0]
        sc = np.max(np.abs(dq) / lim, axis=-1, keepdims=True)
        dq = np.where(sc > 1, dq / np.maximum(sc, 1e-300), dq)
        qa = qa + dq
        qa[:, isR] = wrap(qa[:, isR])
        q[active] = qa
        active = active[~done]
    F = residual(q, np.arange(N * S))[0]
    ok = np.max(np.abs(F), axis=-1) < 1e-10
    return q.reshape(N, S, 3), ok.reshape(N, S)


def _pick_branch(leg: Leg, q, ok):
    """From candidate configurations ``q`` ``(N, S, 3)`` with flags ``ok`` ``(N, S)``, the one of the leg's
    working mode (sign of :func:`leg_b`; any valid candidate for a one-branch leg) -> ``(N, 3)``, NaN if none."""
    if leg.n_branches == 2:
        with np.errstate(invalid="ignore"):
            sel = ok & (np.sign(leg_b(leg, np.where(ok[..., None], q, 0.0))) == leg.working_mode)
    else:
        sel = ok
    idx = np.argmax(sel, axis=1)
    out = np.take_along_axis(q, idx[:, None, None], axis=1)[:, 0, :]
    out[~np.any(sel, axis=1)] = np.nan
    return out


# ---- per-architecture plane geometry ----------------------------------------------------------------

def _geometric_ik_leg(leg: Leg, poses):
    """IK of one leg of a 3-RPR / 3-RRR / 3-PRR / 3-PPR from plane geometry -> full chain ``q`` ``(N, 3)``.

    With ``D = P + Rot(phi) D_platform`` (mm):

    * RPR: ``L = |D - A|``, ``q1 = angle(D - A)``, ``q3 = phi - q1``.
    * RRR: B is an intersection of the circles (A, l1) and (D, l2): with ``e = (D - A)/|D - A|``,
      ``a = (l1^2 - l2^2 + |D - A|^2) / (2 |D - A|)``, ``h = sqrt(l1^2 - a^2)``, the point
      ``B = A + a e - wm h E e`` has ``sign cross(B - A, D - B) = wm``; ``q1 = angle(B - A)``,
      ``q2 = angle(D - B) - q1``, ``q3 = phi - angle(D - B)``.
    * PRR: ``B = G + s u`` with ``|D - B| = l2`` and ``sign u.(D - B) = wm``:
      ``s = u.(D - G) - wm sqrt(l2^2 - (E u . (D - G))^2)``; ``q2 = angle(D - B) - g``, ``q3 = phi - angle(D - B)``.
    * PPR (Eq. 2): ``s u + l w = P - a h - d v - r k`` solved by Cramer's rule; ``q3 = phi - angle(w)``.
    """
    g = leg.geom
    D = poses[:, :2] + rot(poses[:, 2], np.asarray(g["D"]))
    phi = poses[:, 2]
    N = len(poses)
    q = np.full((N, 3), np.nan)
    if g["type"] == "RPR":
        dv = D - np.asarray(g["A"])
        q1 = np.arctan2(dv[:, 1], dv[:, 0])
        q[:, 0], q[:, 1], q[:, 2] = q1, np.hypot(dv[:, 0], dv[:, 1]), wrap(phi - q1)
    elif g["type"] == "RRR":
        A = np.asarray(g["A"])
        dv = D - A
        dist = np.hypot(dv[:, 0], dv[:, 1])
        e = dv / dist[:, None]
        a = (g["l1"] ** 2 - g["l2"] ** 2 + dist ** 2) / (2 * dist)
        with np.errstate(invalid="ignore"):
            h = np.sqrt(g["l1"] ** 2 - a ** 2)
        B = A + a[:, None] * e - leg.working_mode * h[:, None] * perp(e)
        ab, bd = B - A, D - B
        q1 = np.arctan2(ab[:, 1], ab[:, 0])
        t2 = np.arctan2(bd[:, 1], bd[:, 0])
        q[:, 0], q[:, 1], q[:, 2] = q1, wrap(t2 - q1), wrap(phi - t2)
    elif g["type"] == "PRR":
        u = vec(g["g"])
        dv = D - np.asarray(g["G"])
        along, across = dv @ u, dv @ perp(u)
        with np.errstate(invalid="ignore"):
            s = along - leg.working_mode * np.sqrt(g["l2"] ** 2 - across ** 2)
        bd = dv - s[:, None] * u
        t2 = np.arctan2(bd[:, 1], bd[:, 0])
        q[:, 0], q[:, 1], q[:, 2] = s, wrap(t2 - g["g"]), wrap(phi - t2)
    elif g["type"] == "PPR":
        u, v, w = vec(g["u"]), vec(g["v"]), vec(g["w"])
        rhs = D - np.asarray(g["A"]) - g["d"] * v
        det = cross(u, w)
        q[:, 0] = cross(rhs, w) / det
        q[:, 1] = cross(u, rhs) / det
        q[:, 2] = wrap(phi - g["w"])
    else:  # pragma: no cover
        raise ValueError(g["type"])
    return q


# ---- public IK ----------------------------------------------------------------------------------------

def leg_ik(leg: Leg, poses, method: str = "auto"):
    """Full chain configuration ``(N, 3)`` of one leg in its working mode at ``poses`` ``(N, 3)``.

    ``method``: "geometric" (architecture's plane geometry), "chain" (closed form of any chain),
    "numeric" (multi-start Newton on the loop equations), "auto" (geometric when available, else chain).
    R values are wrapped to (-pi, pi]; NaN where the leg cannot reach.
    """
    poses = np.atleast_2d(np.asarray(poses, float))
    if method == "auto":
        method = "geometric" if leg.geom is not None else "chain"
    if method == "geometric":
        if leg.geom is None:
            raise ValueError("geometric IK needs a 3-RPR/3-RRR/3-PRR/3-PPR leg")
        q = _geometric_ik_leg(leg, poses)
        for k, J in enumerate(leg.joints):
            if J.kind == "R":
                q[:, k] = wrap(q[:, k])
        return q
    X, Th = _targets(leg, poses)
    if method == "chain":
        qa, ok = _chain_ik_all(leg, X, Th)
    elif method == "numeric":
        qa, ok = _numeric_ik_all(leg, X, Th)
    else:
        raise ValueError(f"unknown method {method!r}")
    return _pick_branch(leg, qa, ok)


def within_joint_limits(leg: Leg, q):
    """Whether every joint of the chain configuration ``q`` ``(N, 3)`` lies in its range (R: modulo 2 pi)."""
    ok = np.all(np.isfinite(q), axis=-1)
    for k, J in enumerate(leg.joints):
        if J.range is None:
            continue
        if J.kind == "R":
            ok &= angle_in_range(q[..., k], *J.range)
        else:
            with np.errstate(invalid="ignore"):
                ok &= (q[..., k] >= J.range[0]) & (q[..., k] <= J.range[1])
    return ok


def inverse_kinematics(robot: Robot, poses, method: str = "auto"):
    """Inverse kinematics of the robot in its working modes.

    ``poses`` ``(N, 3)`` or ``(3,)`` (mm, mm, rad) ->

    * ``q`` ``(N, 3)``: actuated joint of each leg (mm for P; rad for R, the representative ``+ 2 pi k``
      nearest to the middle of its range);
    * ``passive`` ``(N, 3, 2)``: the two passive joints of each leg in chain order (mm for P, rad for R
      wrapped to (-pi, pi]);
    * ``within`` ``(N,)``: every joint within its range (passive ones only where a range is given).

    NaN (and ``within`` False) where a leg cannot reach. ``method`` as in :func:`leg_ik`.
    """
    poses = np.atleast_2d(np.asarray(poses, float))
    N = len(poses)
    q = np.full((N, 3), np.nan)
    pas = np.full((N, 3, 2), np.nan)
    within = np.ones(N, bool)
    for i, leg in enumerate(robot.legs):
        ql = leg_ik(leg, poses, method)
        within &= within_joint_limits(leg, ql)
        a = leg.act
        J = leg.joints[a]
        q[:, i] = nearest_to(ql[:, a], 0.5 * (J.range[0] + J.range[1])) if J.kind == "R" else ql[:, a]
        pas[:, i, :] = ql[:, list(leg.passive)]
    return q, pas, within


def full_configurations(robot: Robot, poses, method: str = "auto"):
    """Chain configurations of the three legs ``(N, 3, 3)`` (leg, joint) in their working modes."""
    poses = np.atleast_2d(np.asarray(poses, float))
    return np.stack([leg_ik(leg, poses, method) for leg in robot.legs], axis=1)


def b_diagonal(robot: Robot, poses, method: str = "auto"):
    """``B_ii = zeta_i . T_a,i`` ``(N, 3)`` of the legs at ``poses`` ``(N, 3)`` in their working modes."""
    qf = full_configurations(robot, poses, method)
    return np.stack([leg_b(leg, qf[:, i]) for i, leg in enumerate(robot.legs)], axis=1)


def wrench_matrix(robot: Robot, poses, method: str = "auto"):
    """Constraint wrenches of the legs about the platform origin, rows ``(f_x, f_y, m_P)`` ``(N, 3, 3)``.

    ``m_P = m_O - cross(P, f)``; the robot is at a parallel singularity where this matrix is singular.
    """
    poses = np.atleast_2d(np.asarray(poses, float))
    qf = full_configurations(robot, poses, method)
    W = np.stack([leg_wrench(leg, qf[:, i]) for i, leg in enumerate(robot.legs)], axis=1)
    W[..., 2] -= cross(poses[:, None, :2], W[..., :2])
    return W


def jacobian_fd(robot: Robot, poses, h_mm: float = 1e-3, h_rad: float = 1e-5, method: str = "auto"):
    """``dq/d(x, y, phi)`` ``(N, 3, 3)`` by central differences of :func:`inverse_kinematics`.

    Row i is leg i's actuated joint (mm or rad), columns x, y (per mm) and phi (per rad). Steps
    ``h_mm`` and ``h_rad``; differences of R joints are wrapped. Accuracy about 1e-9 relative (the
    truncation ``h^2 q'''/6`` and the rounding ``eps |q| / h`` are both about 1e-10 mm for robots of a few
    hundred mm).
    """
    poses = np.atleast_2d(np.asarray(poses, float))
    N = len(poses)
    isR = np.array([leg.joints[leg.act].kind == "R" for leg in robot.legs])
    J = np.zeros((N, 3, 3))
    for c, h in enumerate((h_mm, h_mm, h_rad)):
        dp = np.zeros(3)
        dp[c] = h
        qp = inverse_kinematics(robot, poses + dp, method)[0]
        qm = inverse_kinematics(robot, poses - dp, method)[0]
        d = qp - qm
        d[:, isR] = wrap(d[:, isR])
        J[:, :, c] = d / (2 * h)
    return J


# --------------------------------------------------------------------------------------------------
# curves of one leg at a fixed orientation
# --------------------------------------------------------------------------------------------------

def locked_curve(leg: Leg, j: int, v, phi):
    """Where the platform origin P can be with joint ``j`` locked at ``v`` and the orientation fixed at
    ``phi`` ``(n,)`` (rad), the two other joints free.

    Returns ``("circle", centre (n, 2), radius (n,))`` when both free joints are R (the end point is
    ``K + Rot(t) W``, read off the chain at t = 0 and pi), ``("line", point (n, 2), unit direction (n, 2))``
    when one free joint is R (its value is fixed by the orientation) and one is P, and
    ``("none", locked_phi)`` when both are P (the leg then fixes the orientation to ``locked_phi``
    (rad) and leaves P free). Everything is in P-space: the end point minus ``Rot(phi) platform``.
    """
    phi = np.atleast_1d(np.asarray(phi, float))
    n = len(phi)
    free = [k for k in range(3) if k != j]
    Rf = [k for k in free if leg.joints[k].kind == "R"]
    lockR = leg.joints[j].kind == "R"
    S = phi + leg.platform_angle - leg.base_angle - sum(J.offset for J in leg.joints) - (v if lockR else 0.0)
    shift = rot(phi, np.asarray(leg.platform))
    q = np.zeros((n, 3))
    q[:, j] = v
    if len(Rf) == 2:
        m, k2 = Rf
        q0, q1 = q.copy(), q.copy()
        q0[:, m], q0[:, k2] = 0.0, S
        q1[:, m], q1[:, k2] = np.pi, S - np.pi
        f0, f1 = leg_fk(leg, q0)[0], leg_fk(leg, q1)[0]
        return "circle", (f0 + f1) / 2 - shift, np.linalg.norm(f0 - f1, axis=-1) / 2
    if len(Rf) == 1:
        r = Rf[0]
        s = next(k for k in free if k != r)
        q0, q1 = q.copy(), q.copy()
        q0[:, r] = S
        q1[:, r] = S
        q1[:, s] = _SLIDE
        f0, f1 = leg_fk(leg, q0)[0], leg_fk(leg, q1)[0]
        return "line", f0 - shift, (f1 - f0) / _SLIDE
    locked = leg.base_angle + sum(J.offset for J in leg.joints) + (v if lockR else 0.0) - leg.platform_angle
    return "none", float(wrap(locked))


def singular_curves(leg: Leg, phi: float):
    """Boundary of the set of P reachable by the leg at orientation ``phi`` with unlimited joints (where
    its two inverse-kinematics branches meet), as lists of circles ``(cx, cy, r)`` and lines
    ``(px, py, ex, ey)`` (unit e).

    Two R and one P: the end point is ``K + sigma a_out + Rot(t)(U + sigma a_in)``; with a_in = 0 the set is
    the strip of half-width |U| about the line ``K + sigma a_out``, with a_out = 0 the outside of the circle
    of radius ``|cross(U, a_in)|/|a_in|`` about K. Three R: ``K + Rot(t1)(U + Rot(t2) V)``, the annulus
    ``||U| - |V|| <= |X - K| <= |U| + |V|``. One R: the whole plane (no curve).
    """
    circles, lines = [], []
    R = [k for k in range(3) if leg.joints[k].kind == "R"]
    if len(R) == 1:
        return circles, lines
    C = phi + leg.platform_angle - leg.base_angle - sum(J.offset for J in leg.joints)
    shift = rot(phi, np.asarray(leg.platform))

    def f(assign):
        q = np.zeros(3)
        for k, v in assign.items():
            q[k] = v
        return leg_fk(leg, q)[0] - shift

    if len(R) == 2:
        m, n = R
        s = next(k for k in range(3) if k not in R)
        f00, fp0 = f({m: 0.0, n: C}), f({m: np.pi, n: C - np.pi})
        f01, fp1 = f({m: 0.0, n: C, s: _SLIDE}), f({m: np.pi, n: C - np.pi, s: _SLIDE})
        K, U = (f00 + fp0) / 2, (f00 - fp0) / 2
        a_out, a_in = ((f01 + fp1) / 2 - K) / _SLIDE, ((f01 - fp1) / 2 - U) / _SLIDE
        if np.linalg.norm(a_in) < 1e-12:
            e = a_out / np.linalg.norm(a_out)
            for sg in (1.0, -1.0):
                p = K + sg * np.linalg.norm(U) * perp(e)
                lines.append((p[0], p[1], e[0], e[1]))
        else:
            rho = abs(cross(U, a_in)) / np.linalg.norm(a_in)
            if rho > 1e-9:
                circles.append((K[0], K[1], rho))
    else:
        f00, fp0 = f({0: 0.0, 1: 0.0, 2: C}), f({0: np.pi, 1: 0.0, 2: C - np.pi})
        f0p = f({0: 0.0, 1: np.pi, 2: C - np.pi})
        K = (f00 + fp0) / 2
        UpV, UmV = (f00 - fp0) / 2, f0p - K
        r1, r2 = np.linalg.norm((UpV + UmV) / 2), np.linalg.norm((UpV - UmV) / 2)
        circles.append((K[0], K[1], r1 + r2))
        if abs(r1 - r2) > 1e-9:
            circles.append((K[0], K[1], abs(r1 - r2)))
    return circles, lines


def boundary_curves(robot: Robot, phi: float):
    """All curves on which membership of the constant-orientation workspace at ``phi`` can change: for
    every joint with a range, its locked curves at both limits (:func:`locked_curve`), and every leg's
    :func:`singular_curves`. Returns (circles ``[(cx, cy, r)]``, lines ``[(px, py, ex, ey)]``)."""
    circles, lines = [], []
    for leg in robot.legs:
        c, l = singular_curves(leg, phi)
        circles += c
        lines += l
        for k, J in enumerate(leg.joints):
            if J.range is None:
                continue
            for v in J.range:
                kind, a, b = (*locked_curve(leg, k, v, phi), None)[:3]
                if kind == "circle" and b[0] > 1e-9:
                    circles.append((a[0, 0], a[0, 1], b[0]))
                elif kind == "line":
                    lines.append((a[0, 0], a[0, 1], b[0, 0], b[0, 1]))
    return circles, lines


# --------------------------------------------------------------------------------------------------
# forward kinematics by an orientation scan
# --------------------------------------------------------------------------------------------------

def _curve_eval(leg, j, v):
    """Closure ``phi (n,) -> locked_curve(leg, j, v, phi)``."""
    return lambda phi: locked_curve(leg, j, v, phi)


def _intersect(c1, c2):
    """Intersections of two locked curves evaluated on the same orientations (n,).

    Returns points ``(n, nb, 2)`` (nb = 2 for circle-circle / circle-line, branch sign +, -; nb = 1 for
    line-line) and ``h2`` ``(n,)``: the squared half-chord (negative: no intersection; for line-line
    the squared sine between the lines).
    """
    k1, a1, b1 = c1
    k2, a2, b2 = c2
    if k1 == "line" and k2 == "circle":
        return _intersect(c2, c1)
    if k1 == "circle" and k2 == "circle":
        dv = a2 - a1
        dist = np.linalg.norm(dv, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            e = dv / dist[:, None]
            a = (b1 ** 2 - b2 ** 2 + dist ** 2) / (2 * dist)
        h2 = b1 ** 2 - a ** 2
        h = np.sqrt(np.maximum(h2, 0.0))
        mid = a1 + a[:, None] * e
        pts = np.stack([mid + h[:, None] * perp(e), mid - h[:, None] * perp(e)], axis=1)
        return pts, np.where(np.isfinite(h2), h2, -1.0)
    if k1 == "circle" and k2 == "line":
        e = b2 / np.linalg.norm(b2, axis=-1, keepdims=True)
        foot = a2 + np.sum((a1 - a2) * e, -1)[:, None] * e
        h2 = b1 ** 2 - np.sum((a1 - foot) ** 2, -1)
        h = np.sqrt(np.maximum(h2, 0.0))
        pts = np.stack([foot + h[:, None] * e, foot - h[:, None] * e], axis=1)
        return pts, h2
    e1 = b1 / np.linalg.norm(b1, axis=-1, keepdims=True)
    e2 = b2 / np.linalg.norm(b2, axis=-1, keepdims=True)
    den = cross(e1, e2)
    with np.errstate(invalid="ignore", divide="ignore"):
        s1 = cross(a2 - a1, e2) / den
    return (a1 + s1[:, None] * e1)[:, None, :], den ** 2 - 1e-24


def _curve_residual(c, P):
    """Signed residual of points ``P`` ``(n, nb, 2)`` on a locked curve: ``|P - c| - r`` for a circle,
    ``cross(e, P - p)`` for a line -> ``(n, nb)`` (mm)."""
    kind, a, b = c
    if kind == "circle":
        return np.linalg.norm(P - a[:, None, :], axis=-1) - b[:, None]
    e = b / np.linalg.norm(b, axis=-1, keepdims=True)
    return cross(e[:, None, :], P - a[:, None, :])


def actuation_residual(robot: Robot, poses, q):
    """For each pose ``(N, 3)``, the largest over the legs of the distance (mm or rad, R wrapped) from the
    given actuated values ``q`` ``(3,)`` to the nearest inverse-kinematics branch (closed-form chain IK,
    every branch, working modes ignored) -> ``(N,)``."""
    poses = np.atleast_2d(np.asarray(poses, float))
    out = np.zeros(len(poses))
    for i, leg in enumerate(robot.legs):
        X, Th = _targets(leg, poses)
        qa, ok = _chain_ik_all(leg, X, Th)
        a = leg.act
        d = qa[..., a] - q[i]
        if leg.joints[a].kind == "R":
            d = wrap(d)
        d = np.where(ok, np.abs(d), np.inf)
        out = np.maximum(out, np.min(d, axis=1))
    return out


def _brentq(f, a, b):
    """Root of f in [a, b] to 1e-15 rad, or None if f is not finite there (e.g. parallel lines)."""
    try:
        return optimize.brentq(f, a, b, xtol=1e-15, rtol=4 * np.finfo(float).eps)
    except ValueError:
        return None


def _scan_pair(ci, cj, ck, grid, scale, tol_double):
    """Candidate solutions (phi, x, y) on the intersections of curves ``ci``, ``cj`` (functions of phi)
    where the residual of ``ck`` vanishes; see :func:`forward_kinematics_scan`."""
    def ev(phi):
        phi = np.atleast_1d(phi)
        A, B, Ck = ci(phi), cj(phi), ck(phi)
        pts, h2 = _intersect(A, B)
        return pts, h2, _curve_residual(Ck, pts)

    pts, h2, res = ev(grid)
    nb = pts.shape[1]
    valid = (h2 >= 0) & np.all(np.isfinite(res), axis=1)
    out = []

    def res_b(b):
        return lambda phi: float(ev(phi)[2][0, b])

    def h2f(phi):
        return float(ev(phi)[1][0])

    # refine the ends of the runs of valid samples (where the two curves stop meeting)
    ends = {}
    for i in np.nonzero(valid[:-1] != valid[1:])[0]:
        try:
            pe = optimize.brentq(h2f, grid[i], grid[i + 1], xtol=1e-15, rtol=4 * np.finfo(float).eps)
        except ValueError:
            pe = grid[i] if valid[i] else grid[i + 1]
        ends[i] = pe
    for b in range(nb):
        f = res_b(b)
        # samples of runs, with refined end points
        runs = []
        i = 0
        n = len(grid)
        while i < n:
            if not valid[i]:
                i += 1
                continue
            i0 = i
            while i < n and valid[i]:
                i += 1
            ph = list(grid[i0:i])
            rr = list(res[i0:i, b])
            if i0 > 0 and (i0 - 1) in ends:
                pe = ends[i0 - 1]
                ph.insert(0, pe)
                rr.insert(0, f(pe))
            if i < n and (i - 1) in ends:
                pe = ends[i - 1]
                ph.append(pe)
                rr.append(f(pe))
            runs.append((np.array(ph), np.array(rr)))
        for ph, rr in runs:
            m = len(ph)
            if m == 0:
                continue
            sgn = np.sign(rr)
            for i in np.nonzero(sgn[:-1] * sgn[1:] < 0)[0]:
                out.append(_brentq(f, ph[i], ph[i + 1]))
            out += list(ph[rr == 0])
            a = np.abs(rr)
            if m == 1:
                if a[0] < tol_double:
                    out.append(ph[0])
                continue
            left = np.concatenate([[np.inf], a[:-1]])
            right = np.concatenate([a[1:], [np.inf]])
            # second difference: the function can dip below the samples by about |d2|/8 between them
            d2 = np.abs(np.concatenate([[0.0], rr[2:] - 2 * rr[1:-1] + rr[:-2], [0.0]]))
            d2 = np.maximum(d2, np.abs(np.concatenate([[0.0], d2[:-1]])))
            d2 = np.maximum(d2, np.abs(np.concatenate([d2[1:], [0.0]])))
            edge = np.zeros(m, bool)
            edge[[0, -1]] = True
            cand = (a <= left) & (a <= right) & ((a <= 4 * d2 + tol_double) | edge)
            for i in np.nonzero(cand)[0]:
                lo, hi = ph[max(i - 1, 0)], ph[min(i + 1, m - 1)]
                if hi <= lo:
                    continue
                s = 1.0 if rr[i] >= 0 else -1.0
                mres = optimize.minimize_scalar(lambda p: s * f(p), bounds=(lo, hi), method="bounded",
                                                options=dict(xatol=1e-12))
                pstar, vstar = mres.x, s * mres.fun
                if not np.isfinite(vstar):
                    continue
                if s * vstar < 0:
                    for x0, x1, far in ((lo, pstar, lo), (pstar, hi, hi)):
                        if np.sign(f(far)) != np.sign(vstar):
                            out.append(_brentq(f, x0, x1))
                elif abs(vstar) < tol_double:
                    out.append(pstar)
    cands = []
    for p in out:
        if p is None:
            continue
        P = ev(p)[0][0]
        r = ev(p)[2][0]
        b = int(np.argmin(np.abs(r)))
        cands.append((wrap(p), P[b, 0], P[b, 1]))
    return cands


def forward_kinematics_scan(robot: Robot, q, n_phi: int = 7200, tol: float = 1e-8):
    """Every assembly mode (real solution of the forward kinematics) at actuated values ``q`` ``(3,)``.

    Method: with each leg's actuated joint locked, at a fixed orientation phi the platform origin P lies
    on a circle or a line (:func:`locked_curve`). For each of the three pairs of legs and a grid of
    ``n_phi`` orientations over a full turn (plus a small overlap; default 7200, i.e. 0.05 deg), the
    two curves are intersected (both branches) and the third leg's signed residual is evaluated. Roots
    are bracketed by sign changes (brentq to 1e-15 rad), including the refined ends of the phi-intervals
    where the two curves meet (where the branches join); every discrete local minimum of |residual| is
    refined by a bounded minimization, and if the residual changes sign there the two roots on either side
    are bracketed too; a non-crossing minimum below ``1e-10 * scale`` mm counts as a double root. So a
    pair of roots is split as long as the residual between them dips beyond rounding: measured across a
    fold of the 3-RPR in ``tests/data/rpr_six_modes.toml``, pairs 7.8e-7 rad apart (lengths 1e-11 mm
    from the singularity) are still found as two. Conversely, actuated values within about
    ``1e-10 * scale`` of a singularity on the side without a real pair give one spurious (double)
    solution at the near-miss. The three pair-scans are merged.

    A leg whose two passive joints are P fixes the orientation; then the other two legs' curves are
    intersected at that orientation.

    Every candidate is verified with the closed-form chain IK (all branches): kept when
    :func:`actuation_residual` is below ``tol * max(1, scale)`` (one threshold for mm and rad residuals;
    accepted solutions have residuals around 1e-12).
    Candidates closer than 1e-7 rad in phi and 1e-6 scale in P are merged.

    Returns ``(M, 3)`` poses (mm, mm, rad), phi in (-pi, pi], sorted by phi.
    """
    q = np.asarray(q, float)
    scale = robot.scale
    legs = robot.legs
    curves = [_curve_eval(leg, leg.act, q[i]) for i, leg in enumerate(legs)]
    kinds = [c(np.zeros(1))[0] for c in curves]
    cands = []
    if kinds.count("none") >= 2:
        raise ValueError("two legs fix the orientation: the forward kinematics is not finite")
    if kinds.count("none") == 1:
        k = kinds.index("none")
        phi0 = curves[k](np.zeros(1))[1]
        i, j = [m for m in range(3) if m != k]
        pts, h2 = _intersect(curves[i](np.array([phi0])), curves[j](np.array([phi0])))
        if h2[0] >= -1e-12 * scale ** 2:
            cands += [(phi0, p[0], p[1]) for p in pts[0]]
    else:
        d = TWO_PI / n_phi
        grid = -np.pi + d * np.arange(-3, n_phi + 4)
        for i, j, k in ((0, 1, 2), (0, 2, 1), (1, 2, 0)):
            cands += _scan_pair(curves[i], curves[j], curves[k], grid, scale, 1e-10 * scale)
    if not cands:
        return np.zeros((0, 3))
    C = np.array([(x, y, p) for p, x, y in cands])
    C[:, 2] = wrap(C[:, 2])
    r = actuation_residual(robot, C, q)
    keep = r < tol * max(1.0, scale)
    C, r = C[keep], r[keep]
    order = np.argsort(r)
    sols = []
    for idx in order:
        c = C[idx]
        if not any(abs(wrap(c[2] - s[2])) < 1e-7 and np.hypot(*(c[:2] - s[:2])) < 1e-6 * scale for s in sols):
            sols.append(c)
    sols = np.array(sols) if sols else np.zeros((0, 3))
    return sols[np.argsort(sols[:, 2])]


# --------------------------------------------------------------------------------------------------
# constant-orientation workspace
# --------------------------------------------------------------------------------------------------

def within_at(robot: Robot, phi: float, xy, method: str = "auto"):
    """Whether the poses ``(x, y, phi)`` for points ``xy`` ``(N, 2)`` (mm) are inside every joint range."""
    xy = np.atleast_2d(np.asarray(xy, float))
    poses = np.column_stack([xy, np.full(len(xy), phi)])
    return inverse_kinematics(robot, poses, method)[2]


def _vertical_hits(circles, lines, x):
    """y of the crossings of the vertical line at ``x`` with the curves, labelled:
    ``[(y, ("c", index, +1/-1) or ("l", index))]``."""
    hits = []
    for ci, (cx, cy, r) in enumerate(circles):
        dd = r * r - (x - cx) ** 2
        if dd > 0:
            s = math.sqrt(dd)
            hits += [(cy + s, ("c", ci, 1)), (cy - s, ("c", ci, -1))]
    for li, (px, py, ex, ey) in enumerate(lines):
        if abs(ex) > 1e-14:
            hits.append((py + (x - px) * ey / ex, ("l", li)))
    return hits


def _y_of(label, circles, lines, x):
    if label[0] == "c":
        cx, cy, r = circles[label[1]]
        return cy + label[2] * math.sqrt(max(r * r - (x - cx) ** 2, 0.0))
    px, py, ex, ey = lines[label[1]]
    return py + (x - px) * ey / ex


#: Relative size of h^2 (squared half-chord over radius^2) below which two curves count as tangent.
_TANGENT = 1e-9


def _x_breakpoints(circles, lines):
    """x of circle extremes and centres, vertical lines, all pairwise curve intersections, and the
    touching points of (nearly) tangent pairs -- in a 3-RRR the limit circle of an actuated joint touches
    the reach circle where the leg is stretched, and the region's boundary switches there."""
    xs = []
    for cx, cy, r in circles:
        xs += [cx - r, cx, cx + r]
    for px, py, ex, ey in lines:
        if abs(ex) <= 1e-14:
            xs.append(px)
    for a in range(len(circles)):
        for b in range(a + 1, len(circles)):
            (x1, y1, r1), (x2, y2, r2) = circles[a], circles[b]
            dv = np.array([x2 - x1, y2 - y1])
            dist = np.hypot(*dv)
            if dist < 1e-12:
                continue
            aa = (r1 ** 2 - r2 ** 2 + dist ** 2) / (2 * dist)
            h2 = r1 ** 2 - aa ** 2
            e = dv / dist
            if h2 >= 0:
                for sg in (1, -1):
                    xs.append(x1 + aa * e[0] - sg * math.sqrt(h2) * e[1])
            if abs(h2) <= _TANGENT * max(r1, r2) ** 2:    # (nearly) tangent: the curves touch and the
                xs.append(x1 + aa * e[0])                   # region may switch between them there
    for (cx, cy, r) in circles:
        for (px, py, ex, ey) in lines:
            t = (cx - px) * ex + (cy - py) * ey
            fx, fy = px + t * ex, py + t * ey
            h2 = r * r - (cx - fx) ** 2 - (cy - fy) ** 2
            if h2 >= 0:
                xs += [fx + math.sqrt(h2) * ex, fx - math.sqrt(h2) * ex]
            if abs(h2) <= _TANGENT * r * r:
                xs.append(fx)
    for a in range(len(lines)):
        for b in range(a + 1, len(lines)):
            p1, e1 = np.array(lines[a][:2]), np.array(lines[a][2:])
            p2, e2 = np.array(lines[b][:2]), np.array(lines[b][2:])
            den = cross(e1, e2)
            if abs(den) > 1e-12:
                xs.append(float((p1 + cross(p2 - p1, e2) / den * e1)[0]))
    return np.array(xs)


def workspace_area_slices(robot: Robot, phi: float, method: str = "auto", epsabs: float = 1e-11):
    """Area (mm^2) and bounding box of the constant-orientation workspace at ``phi`` (rad) by exact vertical
    slices.

    The workspace is the set of P where every leg, in its working mode, has every joint in its range;
    its boundary lies on the curves of :func:`boundary_curves` (circles and lines). The x-axis is cut at
    every circle extreme and centre, vertical line and pairwise curve intersection; within one piece the
    curves keep their vertical order, so the slice ``{y : (x, y) inside}`` is a union of intervals between
    known curves, found once per piece by testing the middle of every gap at the piece's middle x with
    the IK (:func:`within_at`). Its length ``l(x)`` is then a sum of closed-form ``+-sqrt`` and linear
    terms, integrated per piece with ``scipy.integrate.quad`` (epsabs per piece ``epsabs * scale^2``).
    Accuracy about 1e-9 mm^2 (limited by rounding).

    Returns ``dict(area, bbox=(xmin, xmax, ymin, ymax), pieces)`` (bbox NaN when empty).
    """
    circles, lines = boundary_curves(robot, phi)
    xs = np.unique(_x_breakpoints(circles, lines))
    xs = xs[np.isfinite(xs)]
    if len(xs) < 2:
        return dict(area=0.0, bbox=(np.nan,) * 4, pieces=0)
    pieces = []
    tests = []
    for xa, xb in zip(xs[:-1], xs[1:]):
        if xb - xa < 1e-12:
            continue
        xm = 0.5 * (xa + xb)
        hits = sorted(_vertical_hits(circles, lines, xm), key=lambda t: t[0])
        if not hits:
            continue
        ys = [h[0] for h in hits]
        mids = [ys[0] - 1.0] + [0.5 * (ys[k] + ys[k + 1]) for k in range(len(ys) - 1)] + [ys[-1] + 1.0]
        pieces.append((xa, xb, hits, len(tests)))
        tests += [(xm, y) for y in mids]
    if not pieces:
        return dict(area=0.0, bbox=(np.nan,) * 4, pieces=0)
    inside = within_at(robot, phi, np.array(tests), method)
    area = 0.0
    bb = [np.inf, -np.inf, np.inf, -np.inf]
    scale2 = robot.scale ** 2
    for xa, xb, hits, t0 in pieces:
        ins = inside[t0:t0 + len(hits) + 1]
        if ins[0] or ins[-1]:
            raise ValueError("the workspace is unbounded at this orientation")
        ivs = [(hits[k][1], hits[k + 1][1]) for k in range(len(hits) - 1) if ins[k + 1]]
        if not ivs:
            continue

        def length(x, ivs=ivs):
            return sum(_y_of(b, circles, lines, x) - _y_of(a, circles, lines, x) for a, b in ivs)

        val, _ = integrate.quad(length, xa, xb, epsabs=epsabs * scale2, epsrel=1e-13, limit=200)
        area += val
        bb[0] = min(bb[0], xa)
        bb[1] = max(bb[1], xb)
        for x in (xa, xb):
            bb[2] = min(bb[2], min(_y_of(a, circles, lines, x) for a, _ in ivs))
            bb[3] = max(bb[3], max(_y_of(b, circles, lines, x) for _, b in ivs))
    if not np.isfinite(bb[0]):
        return dict(area=0.0, bbox=(np.nan,) * 4, pieces=len(pieces))
    return dict(area=area, bbox=tuple(bb), pieces=len(pieces))


def _coarse_bbox(robot: Robot, phi: float, n: int = 301, method: str = "auto"):
    """A box (xmin, xmax, ymin, ymax) containing the workspace at ``phi``, found on an ``n x n`` grid over a
    square of half-width 2 * scale, widened by two grid cells (independent of the boundary curves)."""
    h = 2.0 * robot.scale
    g = np.linspace(-h, h, n)
    X, Y = np.meshgrid(g, g)
    ins = within_at(robot, phi, np.column_stack([X.ravel(), Y.ravel()]), method).reshape(X.shape)
    if not ins.any():
        return None
    st = g[1] - g[0]
    return (X[ins].min() - 2 * st, X[ins].max() + 2 * st, Y[ins].min() - 2 * st, Y[ins].max() + 2 * st)


def workspace_area_mc(robot: Robot, phi: float, n: int = 200_000, rng=None, bbox=None, method: str = "auto"):
    """Area (mm^2) of the constant-orientation workspace at ``phi`` by Monte Carlo.

    ``n`` uniform points in ``bbox`` (default: :func:`_coarse_bbox`) tested with the IK; area =
    box area * fraction inside, standard error ``box area * sqrt(p (1 - p) / n)``. The bounding box of
    the inside samples is also returned (an inner estimate). Returns ``dict(area, stderr, bbox, box)``.
    """
    rng = np.random.default_rng(rng)
    if bbox is None:
        bbox = _coarse_bbox(robot, phi, method=method)
        if bbox is None:
            return dict(area=0.0, stderr=0.0, bbox=(np.nan,) * 4, box=None)
    x0, x1, y0, y1 = bbox
    pts = np.column_stack([rng.uniform(x0, x1, n), rng.uniform(y0, y1, n)])
    ins = within_at(robot, phi, pts, method)
    box = (x1 - x0) * (y1 - y0)
    p = ins.mean()
    bb = ((pts[ins, 0].min(), pts[ins, 0].max(), pts[ins, 1].min(), pts[ins, 1].max()) if ins.any()
          else (np.nan,) * 4)
    return dict(area=box * p, stderr=box * math.sqrt(p * (1 - p) / n), bbox=bb, box=bbox)


def _arc_points(f, t0, t1, step):
    k = max(int(math.ceil(abs(t1 - t0) / step)), 1)
    t = np.linspace(t0, t1, k + 1)
    return np.broadcast_to(f(t), (k + 1, 2))


def leg_region_polygon(leg: Leg, phi: float, step: float = TWO_PI / 20000):
    """The set of platform origins P reachable by one leg within its ranges at orientation ``phi``, as a
    shapely polygon with arcs cut in angular steps of ``step`` (vertices on the arcs), and an upper bound
    (mm^2) of the area lost or gained by the chords: the sum over arcs of ``r^2 step^2 span / 12``.

    Built as the image of the boundary of the leg's parameter rectangle (the map is one-to-one within a
    working mode): RRR ``D = A + l1 vec(t) + l2 vec(t + a)``, t in the actuated range, a in [0, pi]
    (wm = +1) or [-pi, 0]; PRR ``D = G + s u + l2 vec(g + a)``, a in [-pi/2, pi/2] (wm = +1) or
    [pi/2, 3 pi/2]; RPR: the annulus about A; PPR: the parallelogram ``A + d v + s u + l w``. Then
    ``P = D - Rot(phi) D_platform``. Supports legs loaded from 3-RPR, 3-RRR, 3-PRR and 3-PPR files.
    """
    import shapely
    from shapely.geometry import Polygon

    g = leg.geom
    if g is None:
        raise NotImplementedError("shapely regions are built for 3-RPR, 3-RRR, 3-PRR and 3-PPR legs only")
    sh = rot(phi, np.asarray(g["D"]))
    bound = 0.0
    if g["type"] == "RPR":
        A = np.asarray(g["A"]) - sh
        lo, hi = g["range"]
        ts = np.arange(0.0, TWO_PI, step)
        outer = A + hi * vec(ts)
        poly = Polygon(outer, [A + max(lo, 0) * vec(ts)] if lo > 0 else None)
        bound = TWO_PI * step ** 2 * (hi ** 2 + max(lo, 0) ** 2) / 12
    elif g["type"] == "RRR":
        A = np.asarray(g["A"]) - sh
        l1, l2 = g["l1"], g["l2"]
        lo, hi = g["range"]
        if hi - lo >= TWO_PI:
            ts = np.arange(0.0, TWO_PI, step)
            poly = Polygon(A + (l1 + l2) * vec(ts), [A + abs(l1 - l2) * vec(ts)])
            bound = TWO_PI * step ** 2 * ((l1 + l2) ** 2 + (l1 - l2) ** 2) / 12
        else:
            a0, a1 = (0.0, np.pi) if leg.working_mode == 1 else (-np.pi, 0.0)

            def D(t, a):
                return A + l1 * vec(t) + l2 * vec(t + a)

            pts = np.vstack([_arc_points(lambda a: D(lo, a), a0, a1, step),
                             _arc_points(lambda t: D(t, a1), lo, hi, step),
                             _arc_points(lambda a: D(hi, a), a1, a0, step),
                             _arc_points(lambda t: D(t, a0), hi, lo, step)])
            poly = Polygon(pts)
            bound = step ** 2 / 12 * (2 * np.pi * l2 ** 2 + (hi - lo) * ((l1 + l2) ** 2 + (l1 - l2) ** 2))
    elif g["type"] == "PRR":
        G = np.asarray(g["G"]) - sh
        u, l2 = vec(g["g"]), g["l2"]
        lo, hi = g["range"]
        a0, a1 = (-np.pi / 2, np.pi / 2) if leg.working_mode == 1 else (np.pi / 2, 3 * np.pi / 2)

        def D(s, a):
            return G + s * u + l2 * vec(g["g"] + a)

        pts = np.vstack([_arc_points(lambda a: D(lo, a), a0, a1, step),
                         _arc_points(lambda a: D(hi, a), a1, a0, step)])
        poly = Polygon(pts)
        bound = step ** 2 / 12 * 2 * np.pi * l2 ** 2
    else:
        A = np.asarray(g["A"]) + g["d"] * vec(g["v"]) - sh
        u, w = vec(g["u"]), vec(g["w"])
        (s0, s1), lr = g["range"], g["l_range"] or (-1e5, 1e5)
        poly = Polygon([A + s * u + l * w for s, l in ((s0, lr[0]), (s1, lr[0]), (s1, lr[1]), (s0, lr[1]))])
    if not poly.is_valid:
        poly = shapely.make_valid(poly)
    return poly, bound


def workspace_area_shapely(robot: Robot, phi: float, step: float = TWO_PI / 20000):
    """Area (mm^2) and bounding box of the constant-orientation workspace at ``phi`` by intersecting the
    three legs' :func:`leg_region_polygon`. Returns ``dict(area, bbox, bound, polygon)`` where ``bound``
    (mm^2) is the sum of the three chord-error bounds (the error is below it)."""
    polys, bound = [], 0.0
    for leg in robot.legs:
        p, b = leg_region_polygon(leg, phi, step)
        polys.append(p)
        bound += b
    inter = polys[0].intersection(polys[1]).intersection(polys[2])
    bb = inter.bounds if not inter.is_empty else (np.nan,) * 4
    return dict(area=inter.area, bbox=(bb[0], bb[2], bb[1], bb[3]), bound=bound, polygon=inter)


# --------------------------------------------------------------------------------------------------
# random robots
# --------------------------------------------------------------------------------------------------

def conditioning(robot: Robot, pose) -> float:
    """2-norm condition number of the wrench matrix (:func:`wrench_matrix`) at ``pose`` ``(3,)`` with its
    rows scaled to unit norm and the moment column divided by the mean platform radius (inf if undefined)."""
    W = wrench_matrix(robot, np.asarray(pose, float)[None])[0]
    if not np.all(np.isfinite(W)):
        return np.inf
    rp = np.mean([np.hypot(*leg.platform) for leg in robot.legs]) or 1.0
    W = W.copy()
    W[:, 2] /= rp
    W /= np.linalg.norm(W, axis=1, keepdims=True)
    return float(np.linalg.cond(W))


def _nominal(rng):
    return np.array([rng.uniform(-20, 20), rng.uniform(-20, 20), rng.uniform(-0.3, 0.3)])


def _triangles(rng):
    """Base points (radius 100-400 mm) and platform points (radius 20-80 mm), about 120 deg apart."""
    Rb, rp = rng.uniform(150, 350), rng.uniform(20, 80)
    ab = np.radians(90 + 120 * np.arange(3) + rng.uniform(-20, 20, 3))
    ap = np.radians(90 + 120 * np.arange(3) + rng.uniform(-25, 25, 3))
    return Rb * vec(ab) * rng.uniform(0.8, 1.15, (3, 1)), rp * vec(ap) * rng.uniform(0.8, 1.2, (3, 1))


def _accept(d, pose, max_cond=8.0):
    robot = load(d)
    q, _, within = inverse_kinematics(robot, pose)
    return bool(within[0]) and conditioning(robot, pose) < max_cond


def random_rpr(rng, max_tries: int = 1000):
    """Random 3-RPR robot dict and nominal pose ``(3,)`` (mm, mm, rad): lengths at the nominal pose, range
    margins 20-80 mm on each side, wrench matrix condition number below 8 at the nominal pose."""
    for _ in range(max_tries):
        pose = _nominal(rng)
        A, d = _triangles(rng)
        D = pose[:2] + rot(pose[2], d)
        L = np.linalg.norm(D - A, axis=1)
        legs = [dict(base=A[i].tolist(), platform=d[i].tolist(),
                     length_range=[float(max(L[i] - rng.uniform(20, 80), 5.0)), float(L[i] + rng.uniform(20, 80))])
                for i in range(3)]
        dct = dict(architecture="3-RPR", legs=legs)
        if _accept(dct, pose):
            return dct, pose
    raise RuntimeError("no acceptable random 3-RPR")


def random_rrr(rng, max_tries: int = 1000):
    """Random 3-RRR robot dict and nominal pose: knee angles 40-140 deg, random working modes, actuated
    ranges 15-45 deg on each side of the nominal angle."""
    for _ in range(max_tries):
        pose = _nominal(rng)
        A, d = _triangles(rng)
        D = pose[:2] + rot(pose[2], d)
        legs = []
        for i in range(3):
            dist = np.linalg.norm(D[i] - A[i])
            knee = np.radians(rng.uniform(40, 140))          # angle at B between BA and BD
            ratio = rng.uniform(0.6, 1.4)                    # l1 / l2
            # dist^2 = l1^2 + l2^2 - 2 l1 l2 cos(knee)
            l2 = dist / math.sqrt(ratio ** 2 + 1 - 2 * ratio * math.cos(knee))
            l1 = ratio * l2
            wm = int(rng.choice([-1, 1]))
            leg = Leg(tuple(A[i]), 0.0, tuple(d[i]), 0.0, wm, (), dict(type="RRR", A=tuple(A[i]), D=tuple(d[i]),
                                                                        l1=l1, l2=l2))
            th = _geometric_ik_leg(leg, pose[None])[0, 0]
            lo, hi = math.degrees(th) - rng.uniform(15, 45), math.degrees(th) + rng.uniform(15, 45)
            legs.append(dict(base=A[i].tolist(), platform=d[i].tolist(), proximal=float(l1), distal=float(l2),
                             angle_range_deg=[lo, hi], working_mode=wm))
        dct = dict(architecture="3-RRR", legs=legs)
        if _accept(dct, pose):
            return dct, pose
    raise RuntimeError("no acceptable random 3-RRR")


def random_prr(rng, max_tries: int = 1000):
    """Random 3-PRR robot dict and nominal pose: B at distal length (80-250 mm) from D, the guide through B
    at 20-70 deg from BD (so |u . (D - B)|/l2 >= 0.34), s ranges 20-60 mm on each side."""
    for _ in range(max_tries):
        pose = _nominal(rng)
        A, d = _triangles(rng)
        D = pose[:2] + rot(pose[2], d)
        legs = []
        for i in range(3):
            l2 = rng.uniform(80, 250)
            dirBD = math.atan2(*(D[i] - A[i])[::-1]) + rng.uniform(-0.5, 0.5)
            B = D[i] - l2 * vec(dirBD)
            wm = int(rng.choice([-1, 1]))
            g = dirBD + rng.choice([-1, 1]) * np.radians(rng.uniform(20, 70)) + (0 if wm == 1 else np.pi)
            s0 = rng.uniform(-50, 150)
            G = B - s0 * vec(g)
            legs.append(dict(guide_point=G.tolist(), guide_deg=float(np.degrees(g)), platform=d[i].tolist(),
                             distal=float(l2), s_range=[s0 - rng.uniform(20, 60), s0 + rng.uniform(20, 60)],
                             working_mode=wm))
        dct = dict(architecture="3-PRR", legs=legs)
        if _accept(dct, pose):
            return dct, pose
    raise RuntimeError("no acceptable random 3-PRR")


LEG_TYPES = ("RPR", "RRR", "PRR", "PPR", "PRP", "RRP", "RPP")


def _random_chain_leg(rng, kinds, A_des, D, pose):
    """One random chain leg of type ``kinds`` from ``A_des`` (its base point) to the platform point ``D``."""
    nR = kinds.count("R")
    cand = [k for k in range(3) if not (nR == 1 and kinds[k] == "R")]   # never the only R (it would lock phi)
    act = int(rng.choice(cand))
    offs = rng.uniform(-np.pi, np.pi, 3)
    links = []
    for k in range(3):
        ln = rng.uniform(40, 150) if rng.uniform() < 0.7 or k == 0 else 0.0
        links.append(ln * vec(rng.uniform(-np.pi, np.pi)))
    qn = np.array([rng.uniform(-np.pi, np.pi) if t == "R" else rng.uniform(40, 150) for t in kinds])
    joints = tuple(Joint(t, k == act, float(offs[k]), tuple(links[k]), None) for k, t in enumerate(kinds))
    leg0 = Leg((0.0, 0.0), 0.0, (0.0, 0.0), 0.0, 1, joints)
    p3, t3, _, _ = leg_fk(leg0, qn)
    target = np.linalg.norm(D - A_des)
    sc = target / max(np.linalg.norm(p3), 1e-9)
    if not 0.3 < sc < 3.0:
        return None
    joints = tuple(Joint(J.kind, J.actuated, J.offset, tuple(np.asarray(J.link) * sc), None) for J in joints)
    qn = np.where(np.array([t == "P" for t in kinds]), qn * sc, qn)
    leg0 = Leg((0.0, 0.0), 0.0, (0.0, 0.0), 0.0, 1, joints)
    p3, t3, _, _ = leg_fk(leg0, qn)
    beta = math.atan2(*(D - A_des)[::-1]) - math.atan2(p3[1], p3[0])
    base = D - rot(beta, p3)
    pd = wrap(beta + t3 - pose[2])
    return act, joints, qn, base, beta, pd


def random_chain(rng, types=None, max_tries: int = 1000):
    """Random "chain" robot dict (legs of mixed types from :data:`LEG_TYPES`, or ``types``) and nominal pose.

    Each leg: random offsets, links 40-150 mm (some zero), joint values at the nominal pose chosen at
    random, all lengths scaled so that the chain spans from a base point (radius 150-350 mm) to its
    platform point (radius 20-80 mm); platform_deg follows. The actuated joint is never the only R of a
    leg. Working mode = sign of B_ii at the nominal pose, |B_ii| (divided by the leg's span for an actuated
    R) at least 0.25, passive R centres at least 20 mm apart. Ranges: actuated +-(15-45) deg or
    +-(15-50) mm about the nominal value; each passive joint has a range (+-(40-100) deg or mm) with
    probability 1/2. Accepted when the nominal pose is within every range and the wrench matrix's
    condition number is below 8.
    """
    for _ in range(max_tries):
        pose = _nominal(rng)
        A, d = _triangles(rng)
        D = pose[:2] + rot(pose[2], d)
        legs = []
        good = True
        for i in range(3):
            kinds = types[i] if types is not None else str(rng.choice(LEG_TYPES))
            built = _random_chain_leg(rng, kinds, A[i], D[i], pose)
            if built is None:
                good = False
                break
            act, joints, qn, base, beta, pd = built
            leg = Leg(tuple(base), beta, tuple(d[i]), pd, 1, joints)
            b = float(leg_b(leg, qn))
            span = np.linalg.norm(D[i] - base)
            bn = b / span if joints[act].kind == "R" else b
            _, _, c, ax = leg_fk(leg, qn)
            m, n = leg.passive
            if joints[m].kind == "R" and joints[n].kind == "R" and np.linalg.norm(c[n] - c[m]) < 20:
                good = False
            if not abs(bn) >= 0.25:          # also rejects NaN (coincident passive R centres)
                good = False
                break
            js = []
            for k, J in enumerate(joints):
                JD = dict(type=J.kind, actuated=J.actuated, offset_deg=math.degrees(J.offset), link=list(J.link))
                if J.kind == "R":
                    val = math.degrees(qn[k])
                    if J.actuated:
                        JD["range"] = [val - rng.uniform(15, 45), val + rng.uniform(15, 45)]
                    elif rng.uniform() < 0.5:
                        JD["range"] = [val - rng.uniform(40, 100), val + rng.uniform(40, 100)]
                else:
                    if J.actuated:
                        JD["range"] = [qn[k] - rng.uniform(15, 50), qn[k] + rng.uniform(15, 50)]
                    elif rng.uniform() < 0.5:
                        JD["range"] = [qn[k] - rng.uniform(40, 100), qn[k] + rng.uniform(40, 100)]
                js.append(JD)
            legs.append(dict(base=list(map(float, base)), base_deg=math.degrees(beta), platform=d[i].tolist(),
                             platform_deg=math.degrees(pd), working_mode=int(np.sign(b)) or 1, joints=js))
        if not good:
            continue
        dct = dict(architecture="chain", legs=legs)
        robot = load(dct)
        qf = full_configurations(robot, pose)[0]
        if not np.all(np.isfinite(qf)):
            continue
        if _accept(dct, pose):
            return dct, pose
    raise RuntimeError("no acceptable random chain robot")


# --------------------------------------------------------------------------------------------------
# a 3-RPR with six assembly modes
# --------------------------------------------------------------------------------------------------

def search_six_modes(rng, n_designs: int = 300, min_sep_deg: float = 1.0, n_phi: int = 1440):
    """Search random 3-RPR designs for actuated lengths with six real, well separated assembly modes.

    Designs: base points uniform in [-200, 200]^2 mm, platform points uniform in [-120, 120]^2 mm,
    lengths = IK at a random pose (|x|, |y| <= 50 mm, any phi); rounded to 0.01 mm. Each design is
    scanned with :func:`forward_kinematics_scan` at ``n_phi``; among those with six modes at least
    ``min_sep_deg`` apart in phi, the one with the largest smallest separation is confirmed with the
    default and a 5x finer scan and returned as ``(robot dict, lengths (3,), poses (6, 3))``
    (length ranges: +-50 mm about the lengths), or None.
    """
    best = None
    for _ in range(n_designs):
        A = np.round(rng.uniform(-200, 200, (3, 2)), 2)
        d = np.round(rng.uniform(-120, 120, (3, 2)), 2)
        pose = np.array([rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(-np.pi, np.pi)])
        dct = dict(architecture="3-RPR", legs=[dict(base=A[i].tolist(), platform=d[i].tolist(),
                                                    length_range=[1.0, 1000.0]) for i in range(3)])
        robot = load(dct)
        q = np.round(inverse_kinematics(robot, pose)[0][0], 2)
        s = forward_kinematics_scan(robot, q, n_phi=n_phi)
        if len(s) != 6:
            continue
        sep = np.min(np.abs(wrap(np.diff(np.r_[s[:, 2], s[0, 2] + TWO_PI]))))
        if sep >= np.radians(min_sep_deg) and (best is None or sep > best[0]):
            best = (sep, dct, q)
    if best is None:
        return None
    _, dct, q = best
    for i, L in enumerate(dct["legs"]):
        L["length_range"] = [float(q[i] - 50.0), float(q[i] + 50.0)]
    robot = load(dct)
    s = forward_kinematics_scan(robot, q)
    s5 = forward_kinematics_scan(robot, q, n_phi=5 * 7200)
    if len(s) != 6 or len(s5) != 6 or np.max(np.abs(s - s5)) > 1e-9:
        return None
    return dct, q, s
