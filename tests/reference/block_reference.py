"""Independent reference: clearances of planar parallel / serial chains as finite displacements.

Written WITHOUT ``pmaccuracy`` (numpy + scipy only) so that the library can be tested against it.
Units: mm and rad.  Plane vectors are complex numbers ``x + iy`` (tuples ``(x, y)`` accepted).

Chain model (one leg, or a serial arm).  A frame is a pair (origin z, angle a).  Joint k with value q:

* R: ``a += offset + q`` (turn about the joint centre c = z);
* P: ``a += offset``, ``e = exp(i a)``, ``z = c + q e`` (slide along the rail e from its origin c);

then the distal part (everything after joint k, as placed with q) gets the rigid displacement, written
in the base frame, ``z -> b + exp(i tau) (z - b) + delta``, ``a -> a + tau`` with block centre
``b = c + q e`` (carriage) or ``b = c`` (bushing), ``tau = tilt + tau_lateral`` and
``delta = shift + i e sigma``; finally ``z += exp(i a) link``.  Because the displacement is applied to the
current (already displaced) frame, a joint's displacement moves every later joint and block centre.
The actuator error replaces q by q + dq (before the block centre is computed).

Worst case (first order): pose error ``d = G s`` (G = Jacobian, central differences + Richardson) over
the product of the clearance sets; supports: interval ``eps |g|``, disk ``eps ||(g_x, g_y)||``,
rhombus ``{|L tau +- 2 sigma| <= 2 eps}`` -> ``max(eps |g_sigma|, 2 eps / L |g_tau|)``.
"""

from __future__ import annotations

import cmath
import math

import numpy as np
from scipy.optimize import minimize_scalar

TWO_PI = 2.0 * math.pi
NOMINAL_TOL = 1e-7   # mm / rad, allowed nominal closure residual
NEWTON_TOL = 1e-11   # required residual of the displaced closure
STEP_MM, STEP_RAD = 1e-3, 1e-4   # central-difference steps (Richardson with h and h/2)


def _cx(v) -> complex:
    """Complex number from a complex / real scalar or an (x, y) pair."""
    if isinstance(v, (tuple, list, np.ndarray)) and len(v) == 2:
        return complex(float(v[0]), float(v[1]))
    return complex(v)


def _wrap(a: float) -> float:
    """Angle wrapped to [-pi, pi]."""
    return math.remainder(a, TWO_PI)


def _chain(z: complex, a: float, joints, q, disp):
    """Displaced forward kinematics of a chain of joints.

    ``joints``: tuples (kind, offset, link complex, carriage bool); ``q``: joint values (3,);
    ``disp``: per joint [dq, shift (complex), rot = tilt + tau, sigma].  Returns the end frame (z, a).
    """
    for (kind, off, link, carriage), qk, (dq, shift, rot, sigma) in zip(joints, q, disp):
        qk = qk + dq
        c = z
        if kind == "R":
            a += off + qk
            b = c
        else:
            a += off
            e = cmath.exp(1j * a)
            z = c + qk * e
            b = z if carriage else c
            shift = shift + 1j * e * sigma
        if rot:
            z = b + cmath.exp(1j * rot) * (z - b)
            a += rot
        z += shift + cmath.exp(1j * a) * link
    return z, a


def _disp(values, keyfun, shape):
    """Per-joint displacement lists from ``values`` {key + (name,): value}; keyfun(index) -> key."""
    out = np.empty(shape, dtype=object)
    for idx in np.ndindex(*shape):
        out[idx] = [0.0, 0j, 0.0, 0.0]
    for key, v in (values or {}).items():
        *pos, name = key
        d = out[keyfun(tuple(pos))]
        if name == "shift":
            d[1] += _cx(v)
        elif name == "dq":
            d[0] += float(v)
        elif name in ("tilt", "tau"):
            d[2] += float(v)
        elif name == "sigma":
            d[3] += float(v)
        else:
            raise ValueError(f"unknown source name {name!r}")
    return out


def _parse_legs(legs):
    """Legs -> tuples (base, base_angle, platform, platform_angle, joints, index of the actuated joint)."""
    out = []
    for leg in legs:
        act = [bool(j["actuated"]) for j in leg["joints"]]
        if sum(act) != 1:
            raise ValueError("exactly one actuated joint per leg")
        js = []
        for j in leg["joints"]:
            blk = j.get("block") or ("carriage" if j["actuated"] else "bushing")
            js.append((j["kind"], float(j.get("offset", 0.0)), _cx(j.get("link", 0.0)), blk == "carriage"))
        out.append((_cx(leg["base"]), float(leg["base_angle"]), _cx(leg["platform"]),
                    float(leg["platform_angle"]), js, act.index(True)))
    return out


def _residual(P, q, u, disp):
    """Closure residual (9,): per leg (end point - platform point [mm, 2], wrapped angle [rad]).

    u = (x, y, phi, passive joint values of legs 0, 1, 2 in joint order) (9,)."""
    zp, phi = complex(u[0], u[1]), u[2]
    r, k = [], 3
    for i, (base, ba, plat, pa, js, ia) in enumerate(P):
        qi = list(q[i])
        for j in range(3):
            if j != ia:
                qi[j] = u[k]
                k += 1
        z, a = _chain(base, ba, js, qi, disp[i])
        d = z - (zp + cmath.exp(1j * phi) * plat)
        r += [d.real, d.imag, _wrap(a - phi - pa)]
    return np.array(r)


def _num_jac(f, u, h=1e-7):
    """Central-difference Jacobian of f at u."""
    cols = []
    for k in range(len(u)):
        du = np.zeros_like(u)
        du[k] = h
        cols.append((f(u + du) - f(u - du)) / (2 * h))
    return np.array(cols).T


def _solve(P, q, pose, disp, J=None):
    """Newton (chord, Jacobian refreshed when slow) on the 9 closure equations; returns pose error (3,)."""
    q = np.asarray(q, float)
    u = np.concatenate([np.asarray(pose, float),
                        [q[i, j] for i, leg in enumerate(P) for j in range(3) if j != leg[5]]])
    f = lambda v: _residual(P, q, v, disp)  # noqa: E731
    if J is None:
        J = _num_jac(f, u)
    r = f(u)
    n = np.linalg.norm(r)
    best = (n, u)
    for _ in range(60):
        u = u - np.linalg.solve(J, r)
        r = f(u)
        n_new = np.linalg.norm(r)
        if n_new < best[0]:
            best = (n_new, u)
        if n_new < NEWTON_TOL and (n_new > 0.1 * n or n_new < 1e-15):
            break
        if n_new > 0.25 * n:
            J = _num_jac(f, u)
        n = n_new
    if best[0] >= NEWTON_TOL:
        raise RuntimeError(f"closure Newton did not converge (residual {best[0]:.3g})")
    d = best[1][:3] - np.asarray(pose, float)
    d[2] = _wrap(d[2])
    return d


def _check_nominal(P, q, pose):
    """Nominal closure Jacobian (9, 9); raises ValueError if the nominal residual exceeds NOMINAL_TOL."""
    disp = _disp(None, lambda p: p, (3, 3))
    q = np.asarray(q, float)
    u = np.concatenate([np.asarray(pose, float),
                        [q[i, j] for i, leg in enumerate(P) for j in range(3) if j != leg[5]]])
    r = _residual(P, q, u, disp)
    if np.max(np.abs(r)) > NOMINAL_TOL:
        raise ValueError(f"nominal closure residual {np.max(np.abs(r)):.3g} (pose and q inconsistent)")
    return _num_jac(lambda v: _residual(P, q, v, disp), u)


def closure_pose_error(legs, pose, q, values) -> np.ndarray:
    """Exact pose error (dx mm, dy mm, dphi rad wrapped), shape (3,), actual minus commanded pose.

    legs: 3 leg dicts (see module doc); pose: (x, y, phi); q: nominal joint values (3 legs, 3 joints);
    values: {(leg, joint, name): value} with name "shift" (complex mm), "dq" (mm or rad), "tilt" (rad,
    angular), "sigma" (mm) and "tau" (rad, lateral).  Solves F0 J1 J2 J3 (displaced) = platform frame
    for (x, y, phi, 6 passive q) with the actuated q fixed (+ dq) by Newton to residual < 1e-11.
    """
    P = _parse_legs(legs)
    J = _check_nominal(P, q, pose)
    return _solve(P, q, pose, _disp(values, lambda p: p, (3, 3)), J)


def _joint_sources(key, kind, actuated, c):
    """Sources of one joint: list of (set kind, eps, L, [(values key, unit)])."""
    c = {k: v for k, v in (c or {}).items() if v is not None}
    src = []
    if c.get("radial", 0.0) > 0:
        src.append(("disk", c["radial"], None, [(key + ("shift",), 1.0), (key + ("shift",), 1j)]))
    if actuated and c.get("actuator", 0.0) > 0:
        src.append(("interval", c["actuator"], None, [(key + ("dq",), 1.0)]))
    if kind == "P":   # angular / lateral are ignored on R joints
        if c.get("angular", 0.0) > 0:
            src.append(("interval", c["angular"], None, [(key + ("tilt",), 1.0)]))
        if c.get("lateral", 0.0) > 0:
            L = float(c.get("block_length") or 50.0)
            src.append(("rhombus", c["lateral"], L, [(key + ("sigma",), 1.0), (key + ("tau",), 1.0)]))
    return src


def _jacobian(err, src, rad_names):
    """G (3, n params): d(pose error)/d(parameter), central differences with Richardson extrapolation."""
    cols = []
    for _, _, _, params in src:
        for key, unit in params:
            h = STEP_RAD if key[-1] in rad_names(key) else STEP_MM
            d = [(err({key: t * unit}) - err({key: -t * unit})) / (2 * t) for t in (h, h / 2)]
            cols.append((4 * d[1] - d[0]) / 3)
    return np.array(cols).T if cols else np.zeros((3, 0))


def _support(s, g):
    """Support value(s) of the linear form g (..., n params of the source) over the source set s."""
    kind, eps, L, _ = s
    if kind == "interval":
        return eps * np.abs(g[..., 0])
    if kind == "disk":
        return eps * np.hypot(g[..., 0], g[..., 1])
    return np.maximum(eps * np.abs(g[..., 0]), 2 * eps / L * np.abs(g[..., 1]))


def _maxima(G, src):
    """{"dx", "dy", "dphi", "dp"} from G (3, n): sums of supports; dp = max over directions u."""
    spans, k = [], 0
    for s in src:
        spans.append((s, slice(k, k + len(s[3]))))
        k += len(s[3])

    def total(row):
        return float(sum(np.sum(_support(s, row[..., sl])) for s, sl in spans)) if spans else 0.0

    out = {n: total(G[r]) for r, n in enumerate(("dx", "dy", "dphi"))}

    def h(th):   # support of u . (dx, dy), th array (m,) -> (m,)
        th = np.atleast_1d(th)
        g = np.cos(th)[:, None] * G[0] + np.sin(th)[:, None] * G[1]
        return sum((_support(s, g[:, sl]) for s, sl in spans), np.zeros(len(th)))

    m = 2048
    th = np.arange(m) * math.pi / m           # h(th + pi) = h(th)
    hv = h(th)
    best = float(hv.max()) if spans else 0.0
    for i in np.flatnonzero((hv >= np.roll(hv, 1)) & (hv >= np.roll(hv, -1))):
        d = math.pi / m
        res = minimize_scalar(lambda t: -h(t)[0], bounds=(th[i] - d, th[i] + d), method="bounded",
                              options={"xatol": 1e-12})
        best = max(best, -float(res.fun))
    out["dp"] = best
    return out


def reference_maxima(legs, pose, q, clearances) -> dict:
    """First-order worst-case pose errors of the parallel robot: {"dx": mm, "dy": mm, "dphi": rad, "dp": mm}.

    clearances: 3 legs x 3 joint dicts with optional keys radial, actuator, angular, lateral, block_length.
    G = d closure_pose_error / d sources (central differences, steps 1e-3 mm / 1e-4 rad, Richardson);
    dx = sum of supports of row dx over the sets (likewise dy, dphi); dp = max_|u|=1 support of
    u . (dx, dy) (2048 directions, local maxima refined to 1e-12 rad).
    """
    P = _parse_legs(legs)
    J = _check_nominal(P, q, pose)
    src = [s for i, leg in enumerate(P) for j in range(3)
           for s in _joint_sources((i, j), leg[4][j][0], leg[5] == j, clearances[i][j])]

    def rad_names(key):
        return {"tilt", "tau"} | ({"dq"} if P[key[0]][4][key[1]][0] == "R" else set())

    G = _jacobian(lambda v: _solve(P, q, pose, _disp(v, lambda p: p, (3, 3)), J), src, rad_names)
    return _maxima(G, src)


def _parse_serial(joints):
    """Serial joints -> chain tuples (kind, offset, length + 0j, carriage: default True)."""
    return [(j["kind"], float(j.get("offset", 0.0)), complex(float(j.get("length", 0.0)), 0.0),
             (j.get("block") or "carriage") == "carriage") for j in joints]


def serial_pose(joints, q, values=None) -> np.ndarray:
    """Displaced forward kinematics of a serial arm: end frame (x mm, y mm, angle rad), shape (3,).

    joints: dicts {"kind", "offset", "length", "block"}; q: (n,); values: {(joint, name): value}.
    Starts at the origin with angle 0; R turns by offset + q then moves length; P turns by offset then
    slides q + length (carriage at c + q e, bushing at c).
    """
    js = _parse_serial(joints)
    z, a = _chain(0j, 0.0, js, np.asarray(q, float), _disp(values, lambda p: p[0], (len(js),)))
    return np.array([z.real, z.imag, a])


def serial_reference_maxima(joints, q, clearances) -> dict:
    """First-order worst-case end-effector errors of a serial arm (every joint actuated):
    {"dx": mm, "dy": mm, "dphi": rad, "dp": mm}; clearances: one dict per joint (same keys as above)."""
    js = _parse_serial(joints)
    src = [s for k, j in enumerate(js) for s in _joint_sources((k,), j[0], True, clearances[k])]
    p0 = serial_pose(joints, q)

    def err(v):
        d = serial_pose(joints, q, v) - p0
        d[2] = _wrap(d[2])
        return d

    def rad_names(key):
        return {"tilt", "tau"} | ({"dq"} if js[key[0]][0] == "R" else set())

    return _maxima(_jacobian(err, src, rad_names), src)
