"""Independent brute-force reference for the error sources of the spatial robots (clearances, actuator errors,
geometric tolerances); tests only.

Written from ``docs/guide/spatial-errors.md`` and ``docs/guide/spatial.md`` alone (numpy, scipy, and the
independent kinematics reference :mod:`spatial_reference`); it does not import ``pmaccuracy``. Nothing here
uses the document's first-order law ``M = W^-1 [G | R]``: the sources are applied as FINITE rigid displacements
inside the legs' serial chains and the platform pose is found by solving the loop closures with
``scipy.optimize.least_squares``; the sensitivity matrix is then a central finite difference of that.

The nonlinear model
-------------------
Each leg is a serial chain of rigid bodies from the base to the platform (a Delta leg: two chains, one per rod,
sharing the arm). Its configuration is written as a product of exponentials about the NOMINAL configuration
(the given pose): with every factor expressed in the base frame at the nominal configuration,

    D_chain = prod_j  E_j(s) J_j(theta_j)          (base -> platform),

where ``J_j`` is the motion of the passive joint ``j`` away from its nominal value (an actuated joint is held at
its nominal value: identity) and ``E_j`` the finite displacement of the joint's distal part relative to its
proximal part made of all the sources of that joint:

    E_j : x -> c_j + Rot(omega_j) (x - c_j) + t_j,
    t_j = sum of the translation sources of the joint (vectors s, mm),
    omega_j = sum of the rotation sources of the joint (rotation vectors s, rad, ``Rot`` = exact Rodrigues),
    c_j = the joint centre (prismatic: the carriage centre).

The platform's displaced pose is ``Delta = (p + dp, Rot(dtheta) R)``; every chain must satisfy
``D_chain = Delta`` (6 equations per chain). Unknowns: ``dp, dtheta`` and all passive joint motions:
universal joint 2 (rotations about ``u1`` then ``u2``), revolute 1, spherical at the platform 3 (rotation
vector), a Delta's elbow ball 2 (rotation vector normal to the nominal rod: the rod's idle spin is left out).
6-UPS: 6 + 6*5 unknowns for 36 equations; 3-RPS, 3-PRS, 3-UPU: 6 + 3*4 for 18; Delta: 6 + 3*2*5 for 36.
The system is square and is solved by ``least_squares`` (``lm``) from zero (the nominal pose) with a residual
below 1e-13 (mm; rotations multiplied by a characteristic length). Transforms are stored as ``(R - I, t)``
so that all arithmetic is on the small displacements (no cancellation against the 1000 mm coordinates); the
nominal closure is then exact by construction, and the nominal pose is checked to be a valid pose of the robot
(3-RPS / 3-PRS constraints, 3-UPU / Delta orientation = identity) instead.

Joint frames (all at the nominal pose; ``d`` the unit leg from the base joint centre ``A`` to the platform
joint centre ``B = p + R b``; ``normals(a)`` = ``e1 = spatial_reference._perp_to(a)``, ``e2 = a x e1``; disc
and ball bases are rotation-invariant sets, so the basis choice changes the columns but not the error set):

* 6-UPS: universal at ``A`` (``u1`` = ``base_axis``; WITHOUT ``base_axis``: ``u1 = unit(z x d_home)``, the
  horizontal axis perpendicular to the leg at the robot's HOME pose, ``x`` if the leg is vertical there),
  ``u2 = unit(d x u1)`` (perpendicular to ``u1`` and to the leg at the given pose), cross normal
  ``n = u1 x u2`` (= ``d`` when ``u1`` is perpendicular to the leg); actuated prismatic along ``d`` with the
  carriage centre ``(A + B) / 2``; spherical at ``B``.
* 3-RPS: revolute at ``A`` about ``axis``; prismatic as above; spherical at ``B``.
* 3-PRS: actuated prismatic along ``slide``, carriage centre = the revolute centre ``C = base + q slide``;
  revolute at ``C`` about ``axis``; spherical at ``B``.
* 3-UPU: universal at ``A`` (``u1 = base_axis``, ``u2 = unit(d x u1)``, the inner axis); prismatic as above;
  universal at ``B`` whose first (leg-side) axis is the inner axis ``u2`` (parallel, Tsai) and whose second
  (platform-side) axis is ``R platform_axis``; its cross normal ``u2 x R platform_axis``.
* Delta: actuated revolute at ``A = base`` about ``axis``; elbow balls ``C +- spacing/2 axis``; platform balls
  ``B +- spacing/2 R axis``; chains ``[arm, elbow 1, platform 1]`` and ``[arm, elbow 2, platform 2]`` (rod 1 is
  ``+``).

Sources (the half-width ``h`` of each; a key with value 0 or absent gives no source):

* spherical ``radial``, any ``position``: ball, translation, basis ``e_x, e_y, e_z``.
* revolute ``radial``: disc, translation, ``normals(axis)``; ``axial``: segment along ``axis``; ``tilt`` and
  ``direction``: disc, rotation about ``normals(axis)`` at ``C``; actuated revolute ``actuator``: segment,
  rotation about ``axis`` at ``C`` (a Delta's arm also accepts the revolute keys).
* universal ``radial``: TWO discs of half-width ``h`` (pin 1: basis ``u2, n``; pin 2: basis ``u1, n``);
  ``axial``: TWO segments (along ``u1``, along ``u2``); ``tilt``: segment, rotation about ``n`` at ``C``;
  ``direction``: disc, rotation about the normals of the FIRST axis in base-to-platform order (``u2, n``; at
  a 3-UPU's platform joint the first axis is the inner axis, normals ``R platform_axis, n``). Rotations about
  a universal's own axes are free, so only the ``n`` component of ``direction`` matters at first order
  (the same for either axis of the joint).
* prismatic ``actuator``, ``backlash`` (two independent segments), ``length``: translation along the slide;
  ``lateral``: disc, translation, ``normals(slide)``; ``tilt``: disc, rotation about ``normals(slide)`` about
  the CARRIAGE CENTRE; ``direction``: the same rotations about the SLIDE'S ORIGIN (the document, as revised
  after this module was first written: the base joint centre of a leg, ``base`` of a 3-PRS), applied as the
  turn about the carriage centre plus the translation ``(Rot - I)(c - O)``.
* ``length``: segment, translation of the distal part along the link from this joint to the next one:
  6-UPS / 3-RPS / 3-UPU base joint and prismatic: along the leg; 3-PRS prismatic: along the slide, revolute:
  along the rod ``B - C``; Delta arm: along ``C - A`` (``C`` the elbow midpoint); Delta elbow ball: along its
  rod (elbow ball -> platform ball). A platform joint has no next link: ``length`` there raises ``ValueError``,
  as does ``direction`` at a spherical joint (no axis) and ``actuator``/``backlash`` at a passive joint.

Solver: the closure's Jacobian at the nominal configuration (central differences of the residual, computed
once per pose) is passed to ``least_squares(method="lm")``; a solution is accepted only when the largest
residual is <= 1e-13 (in practice ~1e-20, the arithmetic being on the small displacements), otherwise the
solver is restarted (finally with its own finite-difference Jacobian) or ``RuntimeError`` is raised.
:func:`sensitivity` is linear to ~1e-14 (h = 0.5e-7 .. 2e-7) and agrees to < 1e-6 with the document's
first-order law evaluated independently from screw theory (:func:`first_order_screw_theory`, for the self-tests).

Choices where the document leaves room (all second order unless said): the sources of a joint are summed into
one translation and one rotation vector (about one centre) and that displacement is applied BEFORE the joint's
own motion, its directions fixed in the proximal part (a universal's pin-2 play is thus expressed with the
cross at its nominal angle); the actuator error of a Delta arm is a rotation about the axis composed with the
other rotation sources of that joint in one rotation vector.
"""

from __future__ import annotations

import math
import tomllib

import numpy as np
from scipy.optimize import least_squares

import spatial_reference as S

DATA = S.DATA
CLEARANCE_FILES = {arch: S.FILES[arch].replace(".toml", "_clearances.toml") for arch in S.ARCHITECTURES}

KIND_KEYS = {
    "spherical": ("radial", "position", "length"),
    "revolute": ("radial", "axial", "tilt", "position", "direction", "length"),
    "actuated revolute": ("actuator", "radial", "axial", "tilt", "position", "direction", "length"),
    "universal": ("radial", "axial", "tilt", "position", "direction", "length"),
    "prismatic": ("actuator", "backlash", "lateral", "tilt", "position", "direction", "length"),
}
SHAPE_DIM = {"segment": 1, "disc": 2, "ball": 3}


# ----------------------------------------------------------------------------------------------------------
# small-displacement rigid transforms stored as (A = R - I, t): x -> (I + A) x + t
# ----------------------------------------------------------------------------------------------------------

_ID = (np.zeros((3, 3)), np.zeros(3))


def _rot_minus_identity(w):
    w = np.asarray(w, float)
    th2 = float(w @ w)
    K = S.skew(w)
    if th2 < 1e-6:  # series, accurate to ~1e-20 relative
        a = 1.0 - th2 / 6.0 + th2 * th2 / 120.0 - th2**3 / 5040.0
        b = 0.5 - th2 / 24.0 + th2 * th2 / 720.0 - th2**3 / 40320.0
    else:
        th = math.sqrt(th2)
        a = math.sin(th) / th
        b = 2.0 * math.sin(0.5 * th) ** 2 / th2
    return a * K + b * (K @ K)


def _about(w, centre, t=None):
    """x -> centre + Rot(w) (x - centre) + t."""
    A = _rot_minus_identity(w)
    tt = -A @ np.asarray(centre, float)
    if t is not None:
        tt = tt + t
    return A, tt


def _compose(g1, g2):
    A1, t1 = g1
    A2, t2 = g2
    return A1 + A2 + A1 @ A2, t1 + t2 + A1 @ t2


def _vee_skew(A):
    return 0.5 * np.array([A[2, 1] - A[1, 2], A[0, 2] - A[2, 0], A[1, 0] - A[0, 1]])


# ----------------------------------------------------------------------------------------------------------
# joints of the legs at a nominal pose
# ----------------------------------------------------------------------------------------------------------


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def normals(a):
    a = _unit(a)
    e1 = S._perp_to(a)
    return e1, np.cross(a, e1)


def _home_u1(leg, robot):
    """6-UPS without base_axis: horizontal axis perpendicular to the leg at the HOME pose."""
    p0, R0 = S.home(robot)
    dh = _unit(p0 + R0 @ leg["platform"] - leg["base"])
    u = np.cross([0.0, 0.0, 1.0], dh)
    if np.linalg.norm(u) < 1e-9:
        return np.array([1.0, 0.0, 0.0])
    return _unit(u)


def _universal(centre, u1, d, ldir=None):
    u2 = _unit(np.cross(d, u1))
    return {"kind": "universal", "centre": centre, "rot_centre": centre, "u1": u1, "u2": u2,
            "n": np.cross(u1, u2), "passive": "U", "ldir": ldir}


def joints_at(robot, position, R):
    """Per leg: ``(joints, chains)``; each joint a dict (kind, centres, directions, passive motion) at the
    nominal pose; chains = lists of joint indices from the base to the platform. Checks the pose is valid."""
    arch = robot["architecture"]
    P = np.asarray(position, float)
    R = np.asarray(R, float)
    Ls = S.legs(robot)
    q = S.actuators(robot, P, R)
    if np.any(np.isnan(q)):
        raise ValueError("pose not reachable")
    if arch in ("3-RPS", "3-PRS") and np.max(np.abs(S.constraint_residuals(robot, P, R))) > 1e-7:
        raise ValueError(f"{arch} pose violates its constraints (use spatial_reference.complete_pose)")
    if arch in ("3-UPU", "delta") and np.linalg.norm(S.rotvec(R)) > 1e-12:
        raise ValueError(f"{arch} moves in pure translation: R must be the identity")
    out = []
    for k, leg in enumerate(Ls):
        B = P + R @ leg["platform"]
        A = leg["base"]
        if arch in ("6-UPS", "3-RPS", "3-UPU"):
            d = _unit(B - A)
            M = 0.5 * (A + B)
            pri = {"kind": "prismatic", "centre": M, "rot_centre": M, "slide": d, "passive": None, "ldir": d,
                   "origin": A}
            sph = {"kind": "spherical", "centre": B, "rot_centre": B, "passive": "S3", "ldir": None}
            if arch == "6-UPS":
                u1 = leg["base_axis"] if "base_axis" in leg else _home_u1(leg, robot)
                first = _universal(A, u1, d, d)
                last = sph
            elif arch == "3-RPS":
                first = {"kind": "revolute", "centre": A, "rot_centre": A, "axis": leg["axis"], "passive": "R",
                         "ldir": d}
                last = sph
            else:
                first = _universal(A, leg["base_axis"], d, d)
                w = first["u2"]
                v = R @ leg["platform_axis"]
                last = {"kind": "universal", "centre": B, "rot_centre": B, "u1": w, "u2": v,
                        "n": _unit(np.cross(w, v)), "passive": "U", "ldir": None}
            out.append(([first, pri, last], [[0, 1, 2]]))
        elif arch == "3-PRS":
            s = leg["slide"]
            C = A + q[k] * s
            pri = {"kind": "prismatic", "centre": C, "rot_centre": C, "slide": s, "passive": None, "ldir": s,
                   "origin": A}
            rev = {"kind": "revolute", "centre": C, "rot_centre": C, "axis": leg["axis"], "passive": "R",
                   "ldir": _unit(B - C)}
            sph = {"kind": "spherical", "centre": B, "rot_centre": B, "passive": "S3", "ldir": None}
            out.append(([pri, rev, sph], [[0, 1, 2]]))
        else:  # delta
            C = S._delta_elbow(leg, q[k])
            h = 0.5 * leg["spacing"] * leg["axis"]
            hp = 0.5 * leg["spacing"] * (R @ leg["axis"])
            arm = {"kind": "actuated revolute", "centre": A, "rot_centre": A, "axis": leg["axis"], "passive": None,
                   "ldir": _unit(C - A)}
            js = [arm]
            for sg in (1.0, -1.0):
                Ce, Bp = C + sg * h, B + sg * hp
                rod = _unit(Bp - Ce)
                if abs(np.linalg.norm(Bp - Ce) - leg["rod"]) > 1e-7:
                    raise ValueError("Delta rods not closed at this pose")
                js.append({"kind": "spherical", "centre": Ce, "rot_centre": Ce, "passive": "S2",
                           "plane": normals(rod), "ldir": rod})
                js.append({"kind": "spherical", "centre": Bp, "rot_centre": Bp, "passive": "S3", "ldir": None})
            out.append((js, [[0, 1, 2], [0, 3, 4]]))
    return out


def _n_passive(j):
    return {"U": 2, "R": 1, "S3": 3, "S2": 2, None: 0}[j["passive"]]


def _passive_transform(j, x):
    c = j["centre"]
    kind = j["passive"]
    if kind == "U":
        return _compose(_about(x[0] * j["u1"], c), _about(x[1] * j["u2"], c))
    if kind == "R":
        return _about(x[0] * _unit(j["axis"]), c)
    if kind == "S3":
        return _about(x[:3], c)
    if kind == "S2":
        e1, e2 = j["plane"]
        return _about(x[0] * e1 + x[1] * e2, c)
    return _ID


# ----------------------------------------------------------------------------------------------------------
# sources
# ----------------------------------------------------------------------------------------------------------


def _joint_sources(j, key, h):
    """List of (shape, type, directions, part) for one key of one joint."""
    kind = j["kind"]
    ex = list(np.eye(3))
    if key not in KIND_KEYS[kind]:
        raise ValueError(f"key {key!r} not defined for a {kind} joint")
    if key == "position":
        return [("ball", "translation", ex, None)]
    if key == "length":
        if j["ldir"] is None:
            raise ValueError(f"'length' has no link after this {kind} joint (platform joint)")
        return [("segment", "translation", [j["ldir"]], None)]
    if kind == "spherical":
        return [("ball", "translation", ex, None)]  # radial
    if kind in ("revolute", "actuated revolute"):
        a = _unit(j["axis"])
        nn = list(normals(a))
        return {"radial": [("disc", "translation", nn, None)], "axial": [("segment", "translation", [a], None)],
                "tilt": [("disc", "rotation", nn, None)], "direction": [("disc", "rotation", nn, None)],
                "actuator": [("segment", "rotation", [a], None)]}[key]
    if kind == "universal":
        u1, u2, n = j["u1"], j["u2"], j["n"]
        return {"radial": [("disc", "translation", [u2, n], "pin 1"), ("disc", "translation", [u1, n], "pin 2")],
                "axial": [("segment", "translation", [u1], "pin 1"), ("segment", "translation", [u2], "pin 2")],
                "tilt": [("segment", "rotation", [n], None)],
                "direction": [("disc", "rotation", [u2, n], None)]}[key]
    s = j["slide"]
    nn = list(normals(s))
    return {"actuator": [("segment", "translation", [s], None)], "backlash": [("segment", "translation", [s], None)],
            "lateral": [("disc", "translation", nn, None)], "tilt": [("disc", "rotation", nn, None)],
            "direction": [("disc", "rotation about origin", nn, None)]}[key]


def build_sources(robot, clearances, joints):
    """The list of sources: dicts with leg, joint, key, part, shape, type, half_width, directions, centre,
    columns (slice of the source vector)."""
    cl_legs = clearances.get("legs", [])
    if len(cl_legs) != len(joints):
        raise ValueError(f"clearances have {len(cl_legs)} legs, the robot {len(joints)}")
    sources = []
    col = 0
    for i, (cl, (js, _chains)) in enumerate(zip(cl_legs, joints)):
        jl = cl.get("joints", [])
        if len(jl) != len(js):
            raise ValueError(f"leg {i + 1}: {len(jl)} joints in the clearances, {len(js)} expected")
        for jj, (entry, j) in enumerate(zip(jl, js)):
            for key, h in entry.items():
                h = float(h)
                if h < 0:
                    raise ValueError("negative half-width")
                subs = _joint_sources(j, key, h)
                if h == 0.0:
                    continue
                for shape, typ, dirs, part in subs:
                    m = SHAPE_DIM[shape]
                    sources.append({"leg": i, "joint": jj, "key": key, "part": part, "shape": shape, "type": typ,
                                    "half_width": h, "directions": [np.asarray(d, float) for d in dirs],
                                    "centre": j["origin"] if typ == "rotation about origin" else j["rot_centre"],
                                    "columns": slice(col, col + m)})
                    col += m
    return sources


def n_variables(sources):
    return sources[-1]["columns"].stop if sources else 0


# ----------------------------------------------------------------------------------------------------------
# the nonlinear closure
# ----------------------------------------------------------------------------------------------------------


class ErrorModel:
    """The robot at a nominal pose with its error sources; :meth:`solve` gives the platform error twist."""

    def __init__(self, robot, clearances, position, R):
        self.robot = robot
        self.position = np.asarray(position, float)
        self.R = np.asarray(R, float)
        self.joints = joints_at(robot, self.position, self.R)
        self.sources = build_sources(robot, clearances, self.joints)
        self.m = n_variables(self.sources)
        self.Lc = S.characteristic_length(robot)
        # passive variable layout
        self.offsets = []
        off = 6
        for js, _ in self.joints:
            o = []
            for j in js:
                o.append(off)
                off += _n_passive(j)
            self.offsets.append(o)
        self.n_unknowns = off

    def nominal_jacobian(self, h=1e-6):
        if getattr(self, "_J0", None) is None:
            E = self.joint_errors(np.zeros(self.m))
            n = self.n_unknowns
            cols = []
            for c in range(n):
                e = np.zeros(n)
                e[c] = h
                cols.append((self.residual(e, E) - self.residual(-e, E)) / (2 * h))
            self._J0 = np.array(cols).T
        return self._J0

    def joint_errors(self, s):
        """Per leg, per joint: the displacement E_j (A, t) of all its sources with variables ``s``."""
        s = np.asarray(s, float)
        trans = [[np.zeros(3) for _ in js] for js, _ in self.joints]
        rot = [[np.zeros(3) for _ in js] for js, _ in self.joints]
        for src in self.sources:
            v = sum(x * d for x, d in zip(s[src["columns"]], src["directions"]))
            tgt = trans if src["type"] == "translation" else rot
            tgt[src["leg"]][src["joint"]] = tgt[src["leg"]][src["joint"]] + v
            if src["type"] == "rotation about origin":
                # a turn about the slide's origin O = the same turn about the joint's centre c plus the
                # translation (Rot - I)(c - O)
                c = self.joints[src["leg"]][0][src["joint"]]["rot_centre"]
                trans[src["leg"]][src["joint"]] = trans[src["leg"]][src["joint"]] + \
                    _rot_minus_identity(v) @ (c - src["centre"])
        out = []
        for i, (js, _) in enumerate(self.joints):
            out.append([_about(rot[i][jj], j["rot_centre"], trans[i][jj]) for jj, j in enumerate(js)])
        return out

    def residual(self, x, E):
        dp, dth = x[:3], x[3:6]
        Ad, td = _about(dth, self.position, dp)
        res = []
        for i, (js, chains) in enumerate(self.joints):
            T = [_compose(E[i][jj], _passive_transform(j, x[self.offsets[i][jj]:self.offsets[i][jj] + _n_passive(j)]))
                 for jj, j in enumerate(js)]
            for chain in chains:
                D = _ID
                for jj in chain:
                    D = _compose(D, T[jj])
                res.append(D[1] - td)
                res.append(self.Lc * _vee_skew(D[0] - Ad))
        return np.concatenate(res)

    def solve(self, s, tol=1e-13, full=False):
        """Platform error twist ``[dp, dtheta]`` (dtheta the rotation vector of ``R_err R_nom^T``)."""
        E = self.joint_errors(s)
        x0 = np.zeros(self.n_unknowns)
        if not np.any(np.asarray(s, float)):
            return (np.zeros(6), x0) if full else np.zeros(6)
        fun = lambda x: self.residual(x, E)  # noqa: E731
        xs = np.ones(self.n_unknowns) / self.Lc
        xs[:3] = 1.0
        J0 = self.nominal_jacobian()
        x = x0
        for attempt in range(6):
            # the closure's Jacobian at the nominal configuration (central differences, computed once) is
            # given to the solver: the displacements are small, so it is a near-exact Newton matrix; the
            # solution is judged only by its residual
            jac = (lambda x: J0) if attempt < 3 else "2-point"
            sol = least_squares(fun, x, jac=jac, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15, x_scale=xs)
            x = sol.x
            r = np.max(np.abs(fun(x)))
            if r <= tol:
                break
        else:
            raise RuntimeError(f"closure not solved: residual {r:.3g}")
        twist = x[:6].copy()
        return (twist, x) if full else twist


def error_twist(robot, clearances, position, R, s):
    """Nonlinear platform error twist for one vector of source variables ``s``."""
    return ErrorModel(robot, clearances, position, R).solve(s)


# ----------------------------------------------------------------------------------------------------------
# first order by finite differences, bounds
# ----------------------------------------------------------------------------------------------------------


def describe(sources):
    """Plain description of each source (JSON-able except the numpy arrays)."""
    return [{k: v for k, v in src.items()} for src in sources]


def sensitivity(robot, clearances, position, R, h=1e-7):
    """``(M (6, m), sources)``: platform error twist per unit source variable, central differences of the
    nonlinear closure (step ``h`` in mm or rad)."""
    model = ErrorModel(robot, clearances, position, R)
    M = np.zeros((6, model.m))
    for c in range(model.m):
        e = np.zeros(model.m)
        e[c] = h
        M[:, c] = (model.solve(e) - model.solve(-e)) / (2.0 * h)
    return M, describe(model.sources)


def component_bounds(M, sources):
    """(6,): max |component| of the first-order error twist over the error set (sum of support functions)."""
    M = np.asarray(M, float)
    out = np.zeros(M.shape[0])
    for src in sources:
        out += src["half_width"] * np.linalg.norm(M[:, src["columns"]], axis=1)
    return out


def _support(Mr, sources, U):
    """f(u) = sum_s h_s |M_s^T u| for the rows of U (k, d); and the attaining points (k, d)."""
    f = np.zeros(U.shape[0])
    X = np.zeros_like(U)
    for src in sources:
        Ms = Mr[:, src["columns"]]
        y = U @ Ms  # (k, m_s) = (M_s^T u)^T
        ny = np.linalg.norm(y, axis=1)
        f += src["half_width"] * ny
        safe = np.where(ny > 0, ny, 1.0)
        X += src["half_width"] * (y / safe[:, None]) @ Ms.T
    return f, X


def max_norm_sampled(M, sources, rows=slice(0, 3), n=200000, seed=0, refine=30, n_best=20, return_point=False):
    """Lower bound of max |M[rows] s| over the error set: the largest support value over ``n`` random unit
    directions, refined by fixed-point ascent ``u <- grad f(u) / |grad f(u)|`` (monotone for this convex,
    homogeneous f) from the best ones; each value is attained by the point ``x(u)`` of the set (returned
    with ``return_point``), whose norm is also a lower bound."""
    Mr = np.asarray(M, float)[rows]
    d = Mr.shape[0]
    rng = np.random.default_rng(seed)
    best_f = np.empty(0)
    best_u = np.empty((0, d))
    chunk = 50000
    done = 0
    while done < n:
        k = min(chunk, n - done)
        U = rng.normal(size=(k, d))
        U /= np.linalg.norm(U, axis=1)[:, None]
        f, _ = _support(Mr, sources, U)
        allf = np.concatenate([best_f, f])
        allu = np.vstack([best_u, U])
        idx = np.argsort(allf)[-n_best:]
        best_f, best_u = allf[idx], allu[idx]
        done += k
    U = best_u.copy()
    for _ in range(refine):
        _, X = _support(Mr, sources, U)
        nx = np.linalg.norm(X, axis=1)
        ok = nx > 0
        U[ok] = X[ok] / nx[ok, None]
    f, X = _support(Mr, sources, np.vstack([best_u, U]))
    vals = np.maximum(f, np.linalg.norm(X, axis=1))
    i = int(np.argmax(vals))
    if return_point:
        return float(vals[i]), X[i]
    return float(vals[i])


def random_extreme(sources, rng):
    """Source variables with every source on the boundary of its own set, random direction."""
    s = np.zeros(n_variables(sources))
    for src in sources:
        m = SHAPE_DIM[src["shape"]]
        if m == 1:
            v = np.array([rng.choice([-1.0, 1.0])])
        else:
            v = rng.normal(size=m)
            v /= np.linalg.norm(v)
        s[src["columns"]] = src["half_width"] * v
    return s


def nonlinear_extremes(robot, clearances, position, R, n, seed=0, return_sources=False):
    """(n, 6) nonlinear platform error twists for ``n`` random extreme configurations of the sources."""
    model = ErrorModel(robot, clearances, position, R)
    rng = np.random.default_rng(seed)
    S_ = np.array([random_extreme(model.sources, rng) for _ in range(n)])
    T = np.array([model.solve(s) for s in S_])
    return (T, S_) if return_sources else T


def first_order_screw_theory(robot, position, R, sources):
    """(6, m): the document's first-order law written independently: each source variable is a twist xi at P
    (translation e: [e, 0]; rotation e about c: [e x (P - c), e]) that adds W_leg xi to the rows of its leg's
    transmissible wrenches (spatial_reference.leg_wrench_systems, from screw theory); a Delta's ball only to
    its own rod's row. A cross-check of :func:`sensitivity`
    (not used by it)."""
    P = np.asarray(position, float)
    Wl = S.leg_wrench_systems(robot, P, R)
    W = np.vstack(Wl)
    starts = np.cumsum([0] + [w.shape[0] for w in Wl])
    m = n_variables(sources)
    rhs = np.zeros((W.shape[0], m))
    delta = robot["architecture"] == "delta"
    for src in sources:
        i = src["leg"]
        rows = list(range(starts[i], starts[i + 1]))
        if delta and src["joint"] in (1, 2):
            rows = [starts[i]]
        elif delta and src["joint"] in (3, 4):
            rows = [starts[i] + 1]
        for col, e in zip(range(src["columns"].start, src["columns"].stop), src["directions"]):
            if src["type"] == "translation":
                xi = np.concatenate([e, np.zeros(3)])
            else:
                xi = np.concatenate([np.cross(e, P - src["centre"]), e])
            rhs[rows, col] = W[rows] @ xi
    return np.linalg.solve(W, rhs)


# ----------------------------------------------------------------------------------------------------------
# clearance files
# ----------------------------------------------------------------------------------------------------------


def load_clearances(architecture):
    with open(DATA / CLEARANCE_FILES[architecture], "rb") as fh:
        return tomllib.load(fh)


def joint_kinds(robot):
    arch = robot["architecture"]
    return {"6-UPS": ["universal", "prismatic", "spherical"], "3-RPS": ["revolute", "prismatic", "spherical"],
            "3-PRS": ["prismatic", "revolute", "spherical"], "3-UPU": ["universal", "prismatic", "universal"],
            "delta": ["actuated revolute"] + ["spherical"] * 4}[arch]


_SCALE = {"radial": 0.01, "axial": 0.005, "tilt": 0.0002, "actuator": 0.005, "backlash": 0.003, "lateral": 0.005,
          "position": 0.01, "direction": 0.0002, "length": 0.01}


def random_clearances(robot, seed):
    """Every applicable key of every joint, with random realistic half-widths (some left out)."""
    rng = np.random.default_rng(seed)
    kinds = joint_kinds(robot)
    arch = robot["architecture"]
    legs = []
    for _ in S.legs(robot):
        joints = []
        for jj, kind in enumerate(kinds):
            e = {}
            last = jj == len(kinds) - 1 or (arch == "delta" and jj in (2, 4))
            for key in KIND_KEYS[kind]:
                if key == "length" and last:
                    continue
                if key == "actuator" and arch == "delta":
                    e[key] = float(0.0001 * rng.uniform(0.5, 1.5))
                    continue
                if key == "radial" and kind == "spherical":
                    e[key] = float(rng.uniform(0.01, 0.02))
                    continue
                if rng.random() < 0.2:
                    continue
                e[key] = float(_SCALE[key] * rng.uniform(0.5, 1.5))
            joints.append(e)
        legs.append({"joints": joints})
    return {"name": f"random_clearances_{seed}", "legs": legs}


def nominal_pose(robot):
    """The robot's home pose, completed for a 3-RPS / 3-PRS (x, y, yaw from the constraints)."""
    p, R = S.home(robot)
    if robot["architecture"] in ("3-RPS", "3-PRS"):
        p, R = S.complete_pose(robot, p[2], *np.radians(S.orientation_deg(R)[:2]))
    return p, R
