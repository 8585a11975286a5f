"""Certified global worst case of a spatial robot's first-order pose errors over a 3D region (issue 37).

The worst errors at one pose (:func:`pmaccuracy.accuracy.spatial_bounds.spatial_pose_errors`) are maximized over a
region of the robot's controlled coordinates: a box, a cylinder (axis along z) or a sphere of positions (6-UPS,
Delta, 3-UPU), a box of ``z, roll, pitch`` (3-RPS, 3-PRS), or the workspace; for a 6-UPS the orientation is
fixed or ranges over a box of roll, pitch, yaw (extrinsic x-y-z). Poses outside the workspace (a leg cannot
reach, a limit is violated) are not part of the region. The quantities are the six components ``dx, dy, dz``
(mm) and ``drx, dry, drz`` (rad), the position error ``dp = |dp|`` (mm) and the rotation angle ``dtheta`` (rad).

**Lower bound** ``L``: the largest value at sampled poses of the region in the workspace (an initial grid, then
the centres of the branch-and-bound boxes), exact there (:func:`~pmaccuracy.accuracy.spatial_bounds.spatial_pose_errors`;
for ``dp`` and ``dtheta`` its attained value), so attained at the pose returned.

**Upper bound of a 6-UPS** (branch and bound on boxes of ``x, y, z`` and the orientation angles): a 6-UPS's error
set is six segments ``rho_i(c_i) W^-1 e_i`` (leg ``i``'s sources act through its length; ``c_i = |u_i . u1_i|``),
so over a box with centre pose ``c``, position half-widths ``r`` and angle half-widths ``a``:

* every rotation of the box is within the geodesic angle ``alpha = min(sum a, pi)`` of the centre's
  (``d(Rz Ry Rx, Rz' Ry' Rx') <= |dyaw| + |dpitch| + |droll|``), so ``|R b - R_c b| <= alpha |b|``;
* the leg vector ``d_i = p + R b_i - A_i`` is within ``delta_i = |r| + alpha |b_i|`` of its centre value, the
  unit leg ``u_i = d_i / |d_i|`` within ``r_u = min(2 delta / |d_c|, delta / (|d_c| - delta), 2)`` (the
  normalization's derivative has norm ``1 / |d|``), the moment ``R b_i x u_i`` within
  ``alpha |b_i| + |b_i| r_u``; so every ``W`` of the box lies in ``W_c +- Rad`` (entrywise) and ``c_i`` in
  ``c_c +- r_u``, giving ``rho_i in [rho_lo, rho_hi]`` (it is monotone in ``c``);
* with ``C = W_c^-1`` and ``D = |I - C W_c| + |C| Rad`` (``|I - C W| <= D`` for every ``W`` of the box) and
  weights ``w > 0`` (a few power iterations towards ``D``'s Perron vector), ``beta = max_i (D w)_i / w_i < 1``
  proves every ``W`` of the box regular (``D^k w <= beta^k w``) and, from ``W^-1 = sum_k (I - C W)^k C``,
  ``|W^-1 - C| <= Y = E + (D w) e^T`` with ``E = D|C|`` and ``e_j = max_i (E_ij / w_i) / (1 - beta)``;
* a tighter enclosure from the mean-value form of ``W``: with ``dW_l`` the derivative of ``W`` along coordinate
  ``l`` enclosed over the box (midpoint-radius arithmetic), ``W - W_c`` lies in ``sum_l dW_l (x_l - c_l)``, and
  ``W^-1 - C = W^-1 (R_0 - (W - W_c) C)`` (``R_0 = I - W_c C``) gives ``|W^-1 - C| <= Y`` with ``Y <= F + Y G``,
  ``F = |C||R_0| + sum_l r_l |C dW_l C|``, ``G = |R_0| + sum_l r_l |dW_l C|`` (signs cancel inside the
  products); left weights ``z G <= gamma z`` with ``gamma < 1`` prove every ``W`` of the box regular and give
  ``Y_ij <= F_ij + max_k (F_ik / z_k) gamma z_j / (1 - gamma)``; the smaller of the two enclosures is used
  (a box is regular when either test proves it);
* so each entry of ``M = W^-1 diag(rho)`` lies in a known interval: ``dx_max <= sum_j (|C_0j| + Y_0j) rho_hi_j``
  (and so on), and ``|dp|_max = max over the 32 sign vectors s of |sum_j s_j M[:3, j]|`` is bounded by the
  norm of the interval sums' magnitudes (``dtheta`` the same with rows 3-5);
* the mean-value form, used where smaller: ``Q(c) + sum_l r_l max |dQ/dx_l|``, the derivatives
  (``dW^-1 = -W^-1 dW W^-1``, ``d rho``) enclosed over the box; for ``dp`` per sign vector ``s``,
  ``|v_s(x)|^2 <= |v_s(c)|^2 + 2 sum_l r_l |v_s(c) . dv_s/dx_l| + (sum_l r_l |dv_s/dx_l|)^2``. Its
  overestimate shrinks with the square of the box's size.

Boxes that a leg certainly cannot reach (its length interval outside the stroke, or the leg outside its base
cone) are dropped; the other bounds hold over the whole box, hence over its part in the workspace. All bounds
are widened by a relative ``1e-9`` for rounding. A box whose bound is within ``gap`` of ``L`` is closed;
the others are bisected along the side with the largest share of their mean-value slack (else their widest
side, angles times the characteristic length) until none is left or the box budget is spent (``converged``
False, the bounds still hold). A box with ``beta >= 1`` smaller than ``min_size``, or a sampled pose
of the region with a condition number above
:data:`~pmaccuracy.accuracy.spatial_bounds.MAX_CONDITION`, means the region reaches a singularity:
:class:`SpatialSingularRegionError` (the errors are unbounded there), never a finite number.

**Upper bound of a 3-UPU, Delta, 3-RPS or 3-PRS** (boxes of the three region coordinates): over a box with
centre ``c`` and half-widths ``h``, ``x = c + h t`` with ``t`` in ``[-1, 1]^3``, every quantity is held as a
first-order affine form ``m + G t + e``, ``|e| <= r`` (entrywise): sums exactly; products keep the linear parts
and put ``(|G_a|_1 + r_a)(|G_b|_1 + r_b)`` into ``r``; a smooth function (``1/sqrt``, ``sqrt``, ``cos``,
``sin``) is linearized at ``m`` with the Taylor remainder ``max |f''| rad^2 / 2`` over the range. So the
remainders shrink with the square of the box. Built this way from the closed forms:

* the legs' closure rows (:mod:`pmaccuracy.model.spatial_legs`) and every source's generator twists, the same
  sets as :func:`~pmaccuracy.accuracy.spatial_bounds.error_sources_at` (a disc of translations or rotations
  normal to ``a`` as the image of the unit ball by ``I - a a^T``, which spans the same set);
* a Delta's arm direction without its angle: ``theta = psi - mode alpha`` with ``cos alpha = K / rho``,
  ``(cos psi, sin psi) = (e.x, e.y) / rho``, so ``cos theta = cos psi c + mode sin psi sqrt(1 - c^2)`` (and the
  sine); a box on which ``c`` is surely outside ``[-1, 1]``, or the arm angle (within
  ``asin(|rad| / |(cos, sin)|)`` of the centre's) surely outside its range, holds no pose of the workspace and
  is dropped; where ``1 - c^2`` may reach 0 its square root is the constant form of its range over the
  reachable poses;
* a 3-PRS's slide value from its closed form ``q = s.e - mode sqrt(disc)`` (the same square root);
* a 3-RPS's or 3-PRS's parasitic ``x, y, yaw``: the Krawczyk test on the three constraints around the solution
  at the box centre proves that every pose of the box has exactly one solution near it (the branch of the
  centre's), and the mean value theorem, ``dy/dt = -J^-1 dg/dt`` enclosed over that enclosure, gives the affine
  forms (:func:`_parasitic_box`); ``R = Rz(yaw) Ry(pitch) Rx(roll)`` from them.

Then ``W^-1`` over ``W``'s range by the Neumann enclosure above (``C = W_c^-1``, ``|W^-1 - C| <= Y``), and
each source's block ``M_s = W^-1 E_s`` (``E_s`` its image in its leg's rows, padded to six) by the residual:
``M_s(t) - M_c = W^-1 (E_s(t) - W(t) M_c)`` with ``M_c = C E_s(c)``, whose affine residual keeps the
cancellation of ``E``'s and ``W``'s variations: ``|M_s(t) - M_c| <= |C R_0| + sum_l |C D_l| + |C| e + Y |R|``.
So ``dx_max <= sum_s || |M_c| + Mr ||_2`` (and so on) and ``|dp|_max <= max_norm(M_c[:3]) + sum_s
||Mr[:3]||_F`` (:func:`~pmaccuracy.numerics.support.max_norm`'s certified upper value; ``dtheta`` the same).
A box on which a leg's length or slide value is surely outside its stroke is dropped. Over a 3-RPS's or
3-PRS's whole workspace the box of ``z, roll, pitch`` is sampled, not proven, so the upper bound there is not
certified (``inf``, with the reason); a robot of joint chains (``spatial-chain``) gets attained lower bounds
only (grid then local grid refinement around the best poses), ``upper = inf`` and ``certified = False``.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError, EmptyWorkspaceError, SingularPoseError
from ..io.resolve import robot_arg
from ..kinematics.spatial import LIMIT_TOLERANCE, complete_poses, inverse_kinematics, reference_pose
from ..kinematics.spatial_workspace import spatial_workspace
from ..model.plausibility import check_angle_values
from ..model.spatial import CONTROLLED, POSE_NAMES, SpatialManipulator
from ..model.spatial_legs import DeltaLeg, PRSLeg, UPULeg
from ..model.spatial_sources import JOINTS, SpatialErrorSources, default_preset
from ..numerics.spatial import euler_xyz_to_rotvec, rotations, rotvec_to_euler_xyz
from ..numerics.support import max_norm
from .spatial_bounds import COMPONENTS, MAX_CONDITION, hexapod_leg_terms, spatial_pose_errors

#: The quantities maximized, in order: the six components, then ``dp`` (mm) and ``dtheta`` (rad).
QUANTITIES = COMPONENTS + ("dp", "dtheta")
#: Default relative gap ``(upper - lower) / lower``.
DEFAULT_GAP = 1e-2
#: Default budget of evaluated boxes.
DEFAULT_MAX_BOXES = 400_000
#: Relative widening of every upper bound (floating-point rounding).
ROUNDING = 1e-9
#: Absolute tolerance (mm; rad times the characteristic length): bounds this small certify a maximum of 0.
ATOL = 1e-12
#: Boxes bounded per batch (memory: about 40 kB per box).
BOX_CHUNK = 4096
#: Power iterations for the weights of the regularity test of a box's W.
WEIGHT_ITERATIONS = 8
#: Region kinds.
KINDS = ("box", "cylinder", "sphere", "workspace")
#: The architectures whose upper bounds are certified (a robot of joint chains is not).
CERTIFIED = ("6-UPS", "3-UPU", "delta", "3-RPS", "3-PRS")
#: Why the upper bound of an architecture is not certified.
UNCERTIFIED = ("no enclosure of the error set of a {arch} built of joint chains over a box is implemented: the upper "
               "bound is not certified")
#: Why the upper bound over a 3-RPS's or 3-PRS's whole workspace is not certified.
UNBOUNDED = ("the box of z, roll, pitch holding a {arch}'s workspace is sampled, not proven: the upper bound over "
             "the workspace is not certified (give a box)")


class SpatialSingularRegionError(SingularPoseError):
    """The region reaches a singularity of the spatial robot: the worst-case errors are unbounded there."""


@dataclass(frozen=True)
class SpatialRegion:
    """A region of a spatial robot's controlled coordinates (mm and rad).

    Attributes
    ----------
    kind : str
        ``"box"``, ``"cylinder"``, ``"sphere"`` or ``"workspace"``.
    names : tuple of str
        The three region coordinates: ``x, y, z`` (6-UPS, Delta, 3-UPU) or ``z, roll, pitch`` (3-RPS, 3-PRS).
    bounds : ``(3, 2)``
        The bounding box of the region in those coordinates (mm, rad).
    orientation : ``(3, 2)`` or None
        A 6-UPS's roll, pitch, yaw ranges (rad, extrinsic x-y-z; ``lo == hi`` for a fixed angle); None otherwise.
    centre : ``(3,)`` or None
        A cylinder's ``(x, y)`` axis (third entry unused) or a sphere's centre (mm).
    radius : float
        A cylinder's or sphere's radius (mm).
    """

    kind: str
    names: tuple[str, str, str]
    bounds: np.ndarray
    orientation: np.ndarray | None = None
    centre: np.ndarray | None = None
    radius: float = 0.0

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Points ``(..., 3)`` of the region coordinates in the region (not checked against the workspace)."""
        pts = np.asarray(points, dtype=float)
        b = self.bounds
        ok = np.all((pts >= b[:, 0] - 1e-12) & (pts <= b[:, 1] + 1e-12), axis=-1)
        if self.kind == "cylinder":
            ok &= np.hypot(pts[..., 0] - self.centre[0], pts[..., 1] - self.centre[1]) <= self.radius * (1 + 1e-12)
        elif self.kind == "sphere":
            ok &= np.linalg.norm(pts - self.centre, axis=-1) <= self.radius * (1 + 1e-12)
        return ok

    def meets(self, boxes: np.ndarray) -> np.ndarray:
        """Whether boxes ``(n, 3, 2)`` may meet the region (False only where provably disjoint)."""
        lo, hi = boxes[:, :, 0], boxes[:, :, 1]
        ok = np.all((hi >= self.bounds[:, 0]) & (lo <= self.bounds[:, 1]), axis=-1)
        if self.kind in ("cylinder", "sphere"):
            k = 2 if self.kind == "cylinder" else 3
            near = np.clip(self.centre[:k], lo[:, :k], hi[:, :k])
            ok &= np.linalg.norm(near - self.centre[:k], axis=-1) <= self.radius * (1 + 1e-12)
        return ok

    def describe(self) -> str:
        """The region in words (mm, deg)."""
        units = ["deg" if n in ("roll", "pitch", "yaw") else "mm" for n in self.names]
        f = [np.degrees if u == "deg" else float for u in units]
        box = ", ".join(f"{n} in [{f[i](lo):g}, {f[i](hi):g}] {units[i]}"
                        for i, (n, (lo, hi)) in enumerate(zip(self.names, self.bounds)))
        if self.kind == "cylinder":
            text = (f"the cylinder of axis (x, y) = ({self.centre[0]:g}, {self.centre[1]:g}) mm, radius "
                    f"{self.radius:g} mm, z in [{self.bounds[2, 0]:g}, {self.bounds[2, 1]:g}] mm")
        elif self.kind == "sphere":
            text = (f"the sphere of centre ({', '.join(f'{v:g}' for v in self.centre)}) mm and radius "
                    f"{self.radius:g} mm")
        elif self.kind == "workspace":
            text = f"the workspace ({box})"
        else:
            text = box
        if self.orientation is not None:
            o = np.degrees(self.orientation)
            text += ", " + ", ".join(f"{n} {lo:g} deg" if lo == hi else f"{n} in [{lo:g}, {hi:g}] deg"
                                     for n, (lo, hi) in zip(("roll", "pitch", "yaw"), o))
        return text


def _finite(values, n: int, key: str, what: str) -> np.ndarray:
    a = np.asarray(values, dtype=float) if values is not None else None
    if a is None or a.shape != (n,) or not np.all(np.isfinite(a)):
        raise ConfigError(f"must be {n} finite numbers ({what}), got {values!r}", key=key)
    return a


def _workspace_bounds(robot: SpatialManipulator, orientation: np.ndarray | None) -> np.ndarray:
    """A box ``(3, 2)`` of the region coordinates holding the workspace: for legs with a length stroke (6-UPS,
    3-UPU) every position within ``max stroke`` of ``A_i - R b_i`` for every ``R`` of the orientation box, for a
    Delta within ``arm + rod`` of ``A_i - b_i`` (the rods' midpoints are ``rod`` apart; rigorous); otherwise
    (3-RPS, 3-PRS, chains) a sampled workspace's bounding box widened by two cells (lower bounds only)."""
    if robot.architecture == "delta" and not robot.is_chain:
        lo, hi = np.full(3, -np.inf), np.full(3, np.inf)
        for leg in robot.legs:
            c = np.asarray(leg.base, dtype=float) - np.asarray(leg.platform, dtype=float)
            lo, hi = np.maximum(lo, c - (leg.arm + leg.rod)), np.minimum(hi, c + (leg.arm + leg.rod))
        if np.any(lo > hi):
            raise EmptyWorkspaceError(f"no position of {robot.name} is reachable")
        return np.column_stack([lo, hi])
    if robot.architecture in ("6-UPS", "3-UPU"):
        o = np.zeros((3, 2)) if orientation is None else orientation
        Rc = rotations(euler_xyz_to_rotvec(o.mean(axis=1)))
        alpha = min(float(np.sum(o[:, 1] - o[:, 0]) / 2), np.pi)
        lo, hi = np.full(3, -np.inf), np.full(3, np.inf)
        for leg in robot.legs:
            b = np.asarray(leg.platform, dtype=float)
            reach = float(leg.stroke[1]) + min(alpha, 2.0) * np.linalg.norm(b)
            c = np.asarray(leg.base, dtype=float) - Rc @ b
            lo, hi = np.maximum(lo, c - reach), np.minimum(hi, c + reach)
        if np.any(lo > hi):
            raise EmptyWorkspaceError(f"no position of {robot.name} is reachable at these orientations")
        return np.column_stack([lo, hi])
    ws = spatial_workspace(robot, n=16, tilt=False).region
    bb = np.array(ws.bounding_box, dtype=float)
    cell = bb[:, 1] - bb[:, 0]
    bb = bb + np.column_stack([-cell / 8, cell / 8])
    if robot.mobility == "2R1T":    # the workspace's (roll deg, pitch deg, z mm) -> (z mm, roll rad, pitch rad)
        bb = np.array([bb[2], np.radians(bb[0]), np.radians(bb[1])])
    return bb


def spatial_region(robot: SpatialManipulator, *, box=None, cylinder=None, sphere=None,
                   orientation=None) -> SpatialRegion:
    """Check and build a :class:`SpatialRegion` (at most one of ``box``, ``cylinder``, ``sphere``; none: the
    workspace).

    Parameters
    ----------
    box : ``(lo0, hi0, lo1, hi1, lo2, hi2)``
        ``x, y, z`` (mm), or for a 3-RPS / 3-PRS ``z`` (mm), ``roll``, ``pitch`` (rad).
    cylinder : ``(x, y, radius, z0, z1)``
        mm, axis along z (not for 3-RPS / 3-PRS).
    sphere : ``(x, y, z, radius)``
        mm (not for 3-RPS / 3-PRS).
    orientation : ``(3,)`` or ``(3, 2)``
        A 6-UPS's roll, pitch, yaw (rad, extrinsic x-y-z), fixed or ranges ``(lo, hi)``; default the home
        pose's orientation. Other architectures take none.

    >>> robot = SpatialManipulator.preset("stewart_6ups")
    >>> spatial_region(robot, sphere=(0.0, 0.0, 400.0, 10.0), orientation=(0.0, 0.0, 0.0)).describe()
    'the sphere of centre (0, 0, 400) mm and radius 10 mm, roll 0 deg, pitch 0 deg, yaw 0 deg'
    """
    if orientation is not None:
        check_angle_values(orientation, "orientation (roll, pitch, yaw)")
    robot = robot_arg(robot)
    if box is not None and getattr(robot, "mobility", None) == "2R1T":
        check_angle_values(np.ravel(box)[2:] if np.size(box) == 6 else [], "box (roll, pitch)")
    if not isinstance(robot, SpatialManipulator):
        raise ConfigError(f"{robot.name} is a planar robot: its region is made by make_region", key="robot")
    given = [k for k, v in (("box", box), ("cylinder", cylinder), ("sphere", sphere)) if v is not None]
    if len(given) > 1:
        raise ConfigError(f"give one region, got {' and '.join(given)}", key=given[1])
    names = tuple(POSE_NAMES[i] for i in CONTROLLED[robot.mobility][:3]) if robot.mobility != "2R1T" else \
        ("z", "roll", "pitch")
    o = None
    if robot.mobility == "6":
        if orientation is None:
            home = robot.home_pose if robot.home_pose is not None else reference_pose(robot)
            o = np.repeat(rotvec_to_euler_xyz(home[3:])[:, None], 2, axis=1)
        else:
            o = np.asarray(orientation, dtype=float)
            if o.shape == (3,):
                o = np.repeat(o[:, None], 2, axis=1)
            if o.shape != (3, 2) or not np.all(np.isfinite(o)):
                raise ConfigError(f"must be roll, pitch, yaw (rad) or three (lo, hi) ranges, got {orientation!r}",
                                  key="orientation")
            if np.any(o[:, 0] > o[:, 1]):
                raise ConfigError("an orientation range is reversed (lo > hi)", key="orientation")
            if np.any(np.abs(o) > np.pi):
                raise ConfigError("roll, pitch, yaw must lie within [-180, 180] deg", key="orientation")
    elif orientation is not None:
        raise ConfigError(f"a {robot.architecture}'s orientation is not a coordinate of its region "
                          f"(its region is in {', '.join(names)})", key="orientation")
    if robot.mobility == "2R1T" and (cylinder is not None or sphere is not None):
        raise ConfigError(f"a {robot.architecture}'s region is a box of z (mm), roll, pitch: no cylinder or "
                          "sphere", key=given[0])
    if box is not None:
        b = _finite(box, 6, "box", f"{names[0]}0, {names[0]}1, {names[1]}0, {names[1]}1, {names[2]}0, {names[2]}1")
        b = b.reshape(3, 2)
        if np.any(b[:, 0] > b[:, 1]):
            raise ConfigError(f"the box is reversed: {b.tolist()}", key="box")
        if robot.mobility == "2R1T" and np.any(np.abs(b[1:]) >= np.pi / 2):
            raise ConfigError("roll and pitch must lie within (-90, 90) deg", key="box")
        return SpatialRegion("box", names, b, o)
    if cylinder is not None:
        c = _finite(cylinder, 5, "cylinder", "x, y, radius, z0, z1 in mm")
        if not c[2] > 0 or c[3] > c[4]:
            raise ConfigError(f"needs radius > 0 and z0 <= z1, got radius {c[2]:g}, z0 {c[3]:g}, z1 {c[4]:g}",
                              key="cylinder")
        b = np.array([[c[0] - c[2], c[0] + c[2]], [c[1] - c[2], c[1] + c[2]], [c[3], c[4]]])
        return SpatialRegion("cylinder", names, b, o, np.array([c[0], c[1], 0.0]), float(c[2]))
    if sphere is not None:
        s = _finite(sphere, 4, "sphere", "x, y, z, radius in mm")
        if not s[3] > 0:
            raise ConfigError(f"the radius must be > 0, got {s[3]:g}", key="sphere")
        b = np.column_stack([s[:3] - s[3], s[:3] + s[3]])
        return SpatialRegion("sphere", names, b, o, s[:3].copy(), float(s[3]))
    return SpatialRegion("workspace", names, _workspace_bounds(robot, o), o)


@dataclass(frozen=True)
class SpatialQuantityWorst:
    """The worst case of one quantity over the region (mm; rad for ``drx, dry, drz, dtheta``).

    Attributes
    ----------
    name : str
    lower : float
        Attained at ``pose`` (full pose ``(6,)``: mm, rotation vector rad).
    upper : float
        Certified bound over the region (``inf`` when not certified).
    gap : float
        ``(upper - lower) / lower`` (0 when both are 0).
    converged : bool
        The requested gap was reached.
    """

    name: str
    lower: float
    upper: float
    pose: np.ndarray
    gap: float
    converged: bool


@dataclass(frozen=True)
class SpatialGlobalWorst:
    """Result of :func:`spatial_global_worst`.

    Attributes
    ----------
    quantities : dict
        One :class:`SpatialQuantityWorst` per name of :data:`QUANTITIES`.
    certified : bool
        Whether the upper bounds are certified (all but robots of joint chains and a 3-RPS's or 3-PRS's whole
        workspace); False: ``upper`` is ``inf``, see ``reason``.
    reason : str
        Why the upper bounds are not certified ("" when they are).
    boxes, iterations : int
        Boxes evaluated and rounds of the branch and bound.
    seconds : float
        Wall time.
    target_gap : float
        The requested relative gap.
    region : SpatialRegion
    """

    quantities: dict
    certified: bool
    reason: str
    boxes: int
    iterations: int
    seconds: float
    target_gap: float
    region: SpatialRegion = field(repr=False)

    def __getitem__(self, name: str) -> SpatialQuantityWorst:
        return self.quantities[name]

    def records(self) -> list[dict]:
        """One dict per quantity: attained and upper values (mm; deg for rotations), gap, pose (mm, deg)."""
        out = []
        for name, w in self.quantities.items():
            k = 180 / np.pi if name in ("drx", "dry", "drz", "dtheta") else 1.0
            e = rotvec_to_euler_xyz(w.pose[3:], degrees=True) if np.all(np.isfinite(w.pose)) else np.full(3, np.nan)
            out.append({"quantity": name + ("_deg" if k != 1.0 else ""), "lower": w.lower * k,
                        "upper": w.upper * k, "gap_pct": 100 * w.gap,
                        "x": float(w.pose[0]), "y": float(w.pose[1]), "z": float(w.pose[2]),
                        "roll_deg": float(e[0]), "pitch_deg": float(e[1]), "yaw_deg": float(e[2]),
                        "certified": bool(w.converged)})
        return out


def _sources(robot: SpatialManipulator, clearances) -> SpatialErrorSources:
    if clearances is None:
        clearances = default_preset(robot)
    if isinstance(clearances, SpatialErrorSources):
        if clearances.architecture != robot.architecture:
            raise ConfigError(f"the error sources are of a {clearances.architecture}, the robot a "
                              f"{robot.architecture}", key="clearances")
        return clearances
    return SpatialErrorSources.load(clearances, robot)


def _full_poses(robot: SpatialManipulator, pts: np.ndarray) -> np.ndarray:
    """Full poses ``(m, 6)`` of points ``(m, 3 or 6)`` (region coordinates, then for a 6-UPS roll, pitch, yaw);
    NaN where a 3-RPS / 3-PRS's parasitic motions do not exist."""
    if robot.mobility == "6":
        return np.concatenate([pts[:, :3], euler_xyz_to_rotvec(pts[:, 3:6])], axis=1)
    if pts.shape[0] == 0:
        return np.zeros((0, 6))
    return complete_poses(robot, pts[:, :3], strict=False)


def _evaluate(robot, sources, region: SpatialRegion, pts: np.ndarray, gap: float):
    """Values ``(m, 8)`` at points of the region (NaN outside the region or the workspace) and their full poses.
    Raises :class:`SpatialSingularRegionError` at a pose of the region in the workspace that is near-singular."""
    values = np.full((pts.shape[0], len(QUANTITIES)), np.nan)
    poses = np.full((pts.shape[0], 6), np.nan)
    if pts.shape[0] == 0:
        return values, poses
    keep = region.contains(pts[:, :3])
    full = _full_poses(robot, pts[keep])
    ok = np.all(np.isfinite(full), axis=1)
    idx = np.flatnonzero(keep)[ok]
    full = full[ok]
    if not idx.size:
        return values, poses
    inside = np.asarray(inverse_kinematics(robot, full).within_limits)
    idx, full = idx[inside], full[inside]
    if not idx.size:
        return values, poses
    res = spatial_pose_errors(robot, sources, full, gap=gap, strict=False, details=False)
    vals = np.column_stack([res.components, res.dp_lower, res.dtheta_lower])
    bad = ~np.all(np.isfinite(vals), axis=1)
    if np.any(bad):
        k = int(np.argmax(bad))
        c = np.concatenate([full[k, :3], rotvec_to_euler_xyz(full[k, 3:], degrees=True)])
        raise SpatialSingularRegionError(
            f"{region.describe()} reaches a singularity of {robot.name} near (x, y, z, roll, pitch, yaw) = "
            f"({', '.join(f'{v:.4g}' for v in c)}) (condition number above {MAX_CONDITION:g}): the worst-case "
            "errors are unbounded there; narrow the region")
    values[idx] = vals
    poses[idx] = full
    return values, poses


def _box_dims(robot: SpatialManipulator, region: SpatialRegion) -> np.ndarray:
    """The root box ``(k, 2)``: the region's bounds, then a 6-UPS's orientation ranges."""
    if robot.mobility == "6":
        return np.vstack([region.bounds, region.orientation])
    return region.bounds.copy()


def _grid(root: np.ndarray, n: int) -> np.ndarray:
    axes = [np.linspace(lo, hi, n if hi > lo else 1) for lo, hi in root]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, root.shape[0])


def _hexapod_box_bounds(robot: SpatialManipulator, terms, boxes: np.ndarray):
    """Certified upper bounds ``(n, 8)`` of the quantities over boxes ``(n, 6, 2)`` of a 6-UPS (module text;
    ``inf`` where ``W`` is not proven regular), whether each box is provably outside the workspace, and whether
    its ``W`` is not proven regular."""
    n = boxes.shape[0]
    const, radial, axial, u1 = terms
    mid = 0.5 * (boxes[:, :, 0] + boxes[:, :, 1])
    half = 0.5 * (boxes[:, :, 1] - boxes[:, :, 0])
    rpos = np.linalg.norm(half[:, :3], axis=1)                                        # (n,)
    alpha = np.minimum(np.sum(half[:, 3:], axis=1), np.pi)
    Rc = rotations(euler_xyz_to_rotvec(mid[:, 3:]))                                    # (n, 3, 3)
    b = np.array([leg.platform for leg in robot.legs], dtype=float)                    # (6, 3)
    A = np.array([leg.base for leg in robot.legs], dtype=float)
    nb = np.linalg.norm(b, axis=1)
    Rb = np.einsum("nij,kj->nki", Rc, b)                                               # (n, 6, 3)
    d = mid[:, None, :3] + Rb - A                                                      # (n, 6, 3)
    Ld = np.linalg.norm(d, axis=2)
    delta = rpos[:, None] + np.minimum(alpha, 2.0)[:, None] * nb                       # (n, 6)
    with np.errstate(divide="ignore", invalid="ignore"):
        uc = d / Ld[..., None]
        ru = np.minimum(2.0 * delta / Ld, np.where(Ld > delta, delta / (Ld - delta), 2.0))
    ru = np.minimum(np.where(np.isfinite(ru), ru, 2.0), 2.0)
    mc = np.cross(Rb, uc)
    rm = np.minimum(alpha, 2.0)[:, None] * nb + nb * ru
    # the workspace: a length interval outside the stroke, or the leg outside the base cone, on the whole box
    # (with twice the tolerances of the limit checks, kinematics.spatial.LIMIT_TOLERANCE)
    out = np.zeros(n, dtype=bool)
    for i, leg in enumerate(robot.legs):
        lo, hi = leg.stroke
        tol = 2 * LIMIT_TOLERANCE * max(1.0, hi - lo, abs(hi), abs(lo))
        out |= (Ld[:, i] - delta[:, i] > hi + tol) | (Ld[:, i] + delta[:, i] < lo - tol)
        if leg.base_cone is not None:
            cosmax = uc[:, i] @ np.asarray(leg.base_normal, dtype=float) + ru[:, i]
            out |= cosmax < np.cos(leg.base_cone) - 2 * LIMIT_TOLERANCE
    Wc = np.concatenate([uc, mc], axis=2)                                              # (n, 6, 6)
    Rad = np.concatenate([np.repeat(ru[..., None], 3, axis=2), np.repeat(rm[..., None], 3, axis=2)], axis=2)
    cc = np.abs(np.einsum("nki,ki->nk", uc, u1))
    clo, chi = np.clip(cc - ru, 0.0, 1.0), np.clip(cc + ru, 0.0, 1.0)
    rho_hi = const + radial * (np.sqrt(1.0 - clo ** 2) + 1.0) + axial * chi               # (n, 6)
    rho_lo = const + radial * (np.sqrt(1.0 - chi ** 2) + 1.0) + axial * clo
    ok = np.all(np.isfinite(Wc), axis=(1, 2)) & (np.abs(np.linalg.det(np.where(
        np.isfinite(Wc), Wc, 0.0))) > 1e-300)
    C = np.zeros_like(Wc)
    C[ok] = np.linalg.inv(Wc[ok])
    absC = np.abs(C)
    D = np.abs(np.eye(6) - C @ Wc) + absC @ Rad
    # weights w > 0 near D's Perron vector (power iterations from the twist's units): beta = max_i (D w)_i / w_i
    # bounds D's spectral radius, and beta < 1 proves every W of the box regular
    w0 = np.array([1.0, 1.0, 1.0] + [1.0 / robot.characteristic_length] * 3)
    w = np.broadcast_to(w0, (n, 6)).copy()
    for _ in range(WEIGHT_ITERATIONS):
        w = np.einsum("nij,nj->ni", D, w) + 1e-6 * np.max(w, axis=1, keepdims=True) * w0
        w = w / np.max(w, axis=1, keepdims=True)
    Dw = np.einsum("nij,nj->ni", D, w)
    beta = np.max(Dw / w, axis=1)
    regular = ok & (beta < 1.0) & np.all(np.isfinite(D), axis=(1, 2))
    DC = D @ absC                                                                      # E = D |C|
    with np.errstate(divide="ignore", invalid="ignore"):
        e = np.max(DC / w[:, :, None], axis=1) / (1.0 - beta)[:, None]                 # (n, 6)
    Y = DC + Dw[:, :, None] * e[:, None, :]
    mag = absC + Y
    upper = np.full((n, len(QUANTITIES)), np.inf)
    comp = np.einsum("nkj,nj->nk", mag, rho_hi)
    # interval entries of M = W^-1 diag(rho) (rho >= 0)
    Mlo = np.minimum((C - Y) * rho_lo[:, None, :], (C - Y) * rho_hi[:, None, :])
    Mhi = np.maximum((C + Y) * rho_lo[:, None, :], (C + Y) * rho_hi[:, None, :])
    norms = []
    for rows in (slice(0, 3), slice(3, 6)):
        lo_, hi_ = Mlo[:, rows], Mhi[:, rows]                                            # (n, 3, 6)
        pos = _SIGNS > 0                                                                # (32, 6)
        slo = np.where(pos[None, :, None, :], lo_[:, None], -hi_[:, None]).sum(-1)      # (n, 32, 3)
        shi = np.where(pos[None, :, None, :], hi_[:, None], -lo_[:, None]).sum(-1)
        m = np.maximum(np.abs(slo), np.abs(shi))
        norms.append(np.max(np.sqrt(np.sum(m * m, axis=2)), axis=1))
    vals = np.where(regular[:, None], np.column_stack([comp, norms[0], norms[1]]), np.inf)
    share = np.full((n, 6), np.nan)
    sel = np.flatnonzero(ok & np.all(Ld > delta, axis=1))
    if sel.size:
        g = (uc, ru, Ld, delta, Rb, np.minimum(alpha, 2.0)[:, None] * nb, C,
             np.where(regular[:, None, None], Y, np.inf),
             const + radial * (np.sqrt(1.0 - cc ** 2) + 1.0) + axial * cc,
             _of_interval(rho_lo, rho_hi), cc, clo, chi)
        with np.errstate(invalid="ignore", over="ignore"):   # inf * 0 in unproven boxes: masked below
            mv, share[sel], proven = _mean_value_bounds(robot, terms, boxes[sel], tuple(x[sel] for x in g[:9]) + (
                (g[9][0][sel], g[9][1][sel]),) + tuple(x[sel] for x in g[10:]))
        vals[sel] = np.minimum(vals[sel], mv)
        regular[sel] |= proven
    vals = vals * (1 + ROUNDING)
    upper[regular] = vals[regular]
    return upper, out, ~regular, share


# midpoint-radius arithmetic: a pair (m, r) stands for every value within r of m (entrywise)
def _mul(a, b):
    return a[0] * b[0], np.abs(a[0]) * b[1] + a[1] * np.abs(b[0]) + a[1] * b[1]


def _add(a, b):
    return a[0] + b[0], a[1] + b[1]


def _matmul(a, b):
    return a[0] @ b[0], np.abs(a[0]) @ b[1] + a[1] @ np.abs(b[0]) + a[1] @ b[1]


def _cross(a, b):
    """Cross products of midpoint-radius 3-vectors (last axis)."""
    out_m, out_r = [], []
    for i, j in ((1, 2), (2, 0), (0, 1)):
        p = _mul((a[0][..., i], a[1][..., i]), (b[0][..., j], b[1][..., j]))
        q = _mul((a[0][..., j], a[1][..., j]), (b[0][..., i], b[1][..., i]))
        out_m.append(p[0] - q[0])
        out_r.append(p[1] + q[1])
    return np.stack(out_m, axis=-1), np.stack(out_r, axis=-1)


def _dot(a, b):
    p = _mul(a, b)
    return np.sum(p[0], axis=-1), np.sum(p[1], axis=-1)


def _sgn(a):
    """An enclosure of the sign (the derivative of ``|x|``, ``[-1, 1]`` where ``a`` may contain 0)."""
    fixed = np.abs(a[0]) > a[1]
    return np.where(fixed, np.sign(a[0]), 0.0), np.where(fixed, 0.0, 1.0)


def _of_interval(lo, hi):
    return 0.5 * (lo + hi), 0.5 * (hi - lo)


def _mag(a):
    return np.abs(a[0]) + a[1]


def _mean_value_bounds(robot, terms, boxes, geo):
    """Mean-value upper bounds ``(n, 8)`` over 6-UPS boxes: ``Q(c) + sum_l r_l max |dQ/dx_l|`` with the
    derivatives enclosed over the box in midpoint-radius arithmetic (``dW^-1 = -W^-1 dW W^-1``, ``W^-1`` in its
    enclosure); for ``dp`` and ``dtheta``, per sign vector ``s`` with ``v_s = W^-1 (s rho)`` rows 0-2 (3-5):
    ``|v_s(x)|^2 <= |v_s(c)|^2 + 2 sum_l r_l |v_s(c) . dv_s/dx_l| + (sum_l r_l |dv_s/dx_l|)^2``."""
    const, radial, axial, u1 = terms
    n = boxes.shape[0]
    half = 0.5 * (boxes[:, :, 1] - boxes[:, :, 0])
    mid = 0.5 * (boxes[:, :, 0] + boxes[:, :, 1])
    uc, ru, Ld, delta, Rb, rRb, C, Y, rho_c, rho_iv, cc, clo, chi = geo
    u = (uc, np.repeat(ru[..., None], 3, axis=2))
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_L = (1.0 / Ld, np.where(Ld > delta, delta / (Ld * (Ld - delta)), np.inf))
    Rbv = (Rb, np.repeat(rRb[..., None], 3, axis=2))
    Wcen = np.concatenate([uc, np.cross(Rb, uc)], axis=2)                          # W at the centre
    rho = rho_iv
    uu1 = (np.einsum("nki,ki->nk", uc, u1), ru * 1.0)    # |u1| = 1
    sg = _sgn(uu1)
    with np.errstate(divide="ignore", invalid="ignore"):
        f = lambda c: c / np.sqrt(1.0 - c * c)             # noqa: E731  d sqrt(1 - c^2) / dc = -f(c)
        fc = _of_interval(f(clo), f(chi))
    fc = (np.where(chi < 1 - 1e-9, fc[0], 0.0), np.where(chi < 1 - 1e-9, fc[1], np.inf))
    # the angle axes: yaw about z, pitch about Rz(yaw) y, roll about Rz(yaw) Ry(pitch) x
    roll, pitch, yaw = mid[:, 3], mid[:, 4], mid[:, 5]
    cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
    zeros = np.zeros(n)
    axes = {5: (np.column_stack([zeros, zeros, zeros + 1.0]), zeros),
            4: (np.column_stack([-sy, cy, zeros]), half[:, 5]),
            3: (np.column_stack([cy * cp, sy * cp, -sp]), half[:, 5] + half[:, 4])}
    # dW/dx_l over the box (rows [du, dm]: du = (I - u u^T) dd / |d|, dm = dRb x u + Rb x du)
    dWs = {}
    for l in range(6):
        if not np.any(half[:, l] > 0):
            continue
        if l < 3:
            e = np.zeros((n, 6, 3))
            e[:, :, l] = 1.0
            dd, dRb = (e, np.zeros((n, 6, 3))), None
        else:
            w, rw = axes[l]
            wv = (np.repeat(w[:, None, :], 6, axis=1), np.repeat(np.repeat(rw[:, None, None], 6, axis=1), 3, axis=2))
            dd = dRb = _cross(wv, Rbv)
        t = _dot(u, dd)
        ut = _mul(u, (t[0][..., None], t[1][..., None]))
        du = _mul(_add(dd, (-ut[0], ut[1])), (inv_L[0][..., None], inv_L[1][..., None]))
        dm = _cross(Rbv, du)
        if dRb is not None:
            dm = _add(dm, _cross(dRb, u))
        dWs[l] = (du, (np.concatenate([du[0], dm[0]], axis=2), np.concatenate([du[1], dm[1]], axis=2)))
    # a tighter enclosure of W^-1 from the mean-value form of W: W(x) - W_c in sum_l dW_l (x_l - c_l), so
    # W^-1 - C = W^-1 (R0 - (W - W_c) C) with R0 = I - W_c C: |W^-1 - C| <= Y where Y <= F + Y G,
    # F = |C| |R0| + sum_l r_l |C dW_l C|, G = |R0| + sum_l r_l |dW_l C| (signs cancel inside the products);
    # left weights z with z G <= gamma z, gamma < 1 prove every W of the box regular and
    # Y_ij <= F_ij + max_k (F_ik / z_k) gamma z_j / (1 - gamma)
    Cp = (C, np.zeros_like(C))
    F = np.zeros_like(C)
    G = np.zeros_like(C)
    for l, (_, dW) in dWs.items():
        r_l = half[:, l][:, None, None]
        F += r_l * _mag(_matmul(_matmul(Cp, dW), Cp))
        G += r_l * _mag(_matmul(dW, Cp))
    R0 = np.abs(np.eye(6) - Wcen @ C)
    F += np.abs(C) @ R0
    G += R0
    z = np.ones((n, 6))
    for _ in range(WEIGHT_ITERATIONS):
        z = np.einsum("ni,nij->nj", z, G) + 1e-6 * np.max(z, axis=1, keepdims=True)
        z = z / np.max(z, axis=1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        gamma = np.max(np.einsum("ni,nij->nj", z, G) / z, axis=1)
        proven = np.isfinite(gamma) & (gamma < 1.0) & np.all(np.isfinite(F), axis=(1, 2))
        a = np.max(F / z[:, None, :], axis=2)
        Ymv = F + (a * (gamma / (1.0 - gamma))[:, None])[:, :, None] * z[:, None, :]
    Y = np.where(proven[:, None, None], np.minimum(np.where(np.isfinite(Y), Y, np.inf), Ymv), Y)
    Winv = (C, Y)
    SIG = _SIGNS.T                                                                  # (6, 32)
    comp_var = np.zeros((n, 6))
    share = np.zeros((n, 6))
    qc = np.einsum("nkj,nj->nk", np.abs(C), rho_c)
    norm_lin = [np.zeros((n, 32)), np.zeros((n, 32))]
    norm_quad = [np.zeros((n, 32)), np.zeros((n, 32))]
    vc = C @ (rho_c[:, :, None] * SIG)                                              # (n, 6, 32)
    for l, (du, dW) in dWs.items():
        r_l = half[:, l]
        dWinv = _matmul(_matmul(Winv, dW), Winv)
        dWinv = (-dWinv[0], dWinv[1])
        dc = _mul(sg, _dot((np.broadcast_to(u1, du[0].shape), np.zeros_like(du[1])), du))
        ds = _mul(fc, dc)
        drho = (-radial * ds[0] + axial * dc[0], radial * ds[1] + axial * dc[1])
        # components: d/dx sum_j |Winv_kj| rho_j
        a = _mul(_mul(_sgn(Winv), dWinv), (rho[0][:, None, :], rho[1][:, None, :]))
        absW = _of_interval(np.maximum(np.abs(C) - Y, 0.0), np.abs(C) + Y)
        b = _mul(absW, (drho[0][:, None, :], drho[1][:, None, :]))
        dq = (np.sum(a[0] + b[0], axis=2), np.sum(a[1] + b[1], axis=2))
        comp_var += r_l[:, None] * _mag(dq)
        with np.errstate(divide="ignore", invalid="ignore"):
            share[:, l] = np.max(r_l[:, None] * _mag(dq) / qc, axis=1)
        # sign vectors: dv = dWinv (s rho) + Winv (s drho)
        srho = (rho[0][:, :, None] * SIG, rho[1][:, :, None] * np.abs(SIG))
        sdrho = (drho[0][:, :, None] * SIG, drho[1][:, :, None] * np.abs(SIG))
        dv = _add(_matmul(dWinv, srho), _matmul(Winv, sdrho))                       # (n, 6, 32)
        for k, rows in enumerate((slice(0, 3), slice(3, 6))):
            proj = (np.sum(vc[:, rows] * dv[0][:, rows], axis=1), np.sum(np.abs(vc[:, rows]) * dv[1][:, rows], axis=1))
            norm_lin[k] += r_l[:, None] * _mag(proj)
            norm_quad[k] += r_l[:, None] * np.linalg.norm(_mag((dv[0][:, rows], dv[1][:, rows])), axis=1)
    out = [qc + comp_var]
    for k, rows in enumerate((slice(0, 3), slice(3, 6))):
        v2 = np.sum(vc[:, rows] ** 2, axis=1)
        out.append(np.max(np.sqrt(v2 + 2 * norm_lin[k] + norm_quad[k] ** 2), axis=1)[:, None])
    res = np.concatenate(out, axis=1)
    res = np.where(proven[:, None], res, np.inf)
    return np.where(np.isfinite(res), res, np.inf), np.where(np.isfinite(share), share, np.nan), proven


# ---------------------------------------------------------------------------------------------- other architectures
# Boxes of a 3-UPU, Delta, 3-RPS or 3-PRS in first-order affine arithmetic: over a box with centre c and
# half-widths h, x = c + h t with t in [-1, 1]^3, every quantity is a triple (m, G, r) standing for
# m + G t + e with |e| <= r (entrywise; G's last axis is t's). Sums are exact, products keep the linear parts and
# put (|G_a|_1 + r_a)(|G_b|_1 + r_b) into r, a smooth f is linearized at m with the Taylor remainder
# max |f''| rad^2 / 2 over the range. So the closure rows W(t) and each source's image E_s(t) in its leg's rows
# are affine forms whose remainders shrink with the square of the box (module text).
_EYE3 = np.eye(3)


def _af(m):
    """A constant affine form."""
    m = np.asarray(m, dtype=float)
    return m, np.zeros(m.shape + (3,)), np.zeros(m.shape)


def _arad(a):
    """Largest deviation of an affine form from its centre."""
    return np.sum(np.abs(a[1]), axis=-1) + a[2]


def _aadd(a, b):
    return a[0] + b[0], a[1] + b[1], a[2] + b[2]


def _asub(a, b):
    return a[0] - b[0], a[1] - b[1], a[2] + b[2]


def _ascale(a, k: float):
    return a[0] * k, a[1] * k, a[2] * abs(k)


def _amul(a, b):
    return (a[0] * b[0], a[0][..., None] * b[1] + b[0][..., None] * a[1],
            np.abs(a[0]) * b[2] + np.abs(b[0]) * a[2] + _arad(a) * _arad(b))


def _acomp(a, k: int):
    """Component ``k`` of affine 3-vectors."""
    return a[0][..., k], a[1][..., k, :], a[2][..., k]


def _astack(parts):
    return (np.stack([p[0] for p in parts], -1), np.stack([p[1] for p in parts], -2),
            np.stack([p[2] for p in parts], -1))


def _aexpand(a):
    """A scalar form broadcast over a vector's last axis."""
    return a[0][..., None], a[1][..., None, :], a[2][..., None]


def _adot(a, b):
    p = _amul(a, b)
    return np.sum(p[0], -1), np.sum(p[1], -2), np.sum(p[2], -1)


def _across(a, b):
    return _astack([_asub(_amul(_acomp(a, i), _acomp(b, j)), _amul(_acomp(a, j), _acomp(b, i)))
                    for i, j in ((1, 2), (2, 0), (0, 1))])


def _amatmul(a, b):
    """Batched products ``(n, i, k) @ (n, k, j)`` of affine matrices."""
    return (a[0] @ b[0], np.einsum("nik,nkjl->nijl", a[0], b[1]) + np.einsum("nikl,nkj->nijl", a[1], b[0]),
            np.abs(a[0]) @ b[2] + a[2] @ np.abs(b[0]) + _arad(a) @ _arad(b))


def _aunivariate(a, f, df, d2max):
    """``f`` of an affine form: ``f(m) + f'(m) (x - m)`` plus ``|f'(m)| r + max|f''| rad^2 / 2``."""
    rad = _arad(a)
    d1 = df(a[0])
    return f(a[0]), d1[..., None] * a[1], np.abs(d1) * a[2] + 0.5 * d2max(a[0] - rad, a[0] + rad) * rad * rad


def _ainv_sqrt(a):
    """``1 / sqrt(x)`` (infinite remainder where ``x`` may reach 0)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        out = _aunivariate(a, lambda m: m ** -0.5, lambda m: -0.5 * m ** -1.5,
                           lambda lo, hi: np.where(lo > 0, 0.75 * lo ** -2.5, np.inf))
    ok = (a[0] - _arad(a) > 0) & np.isfinite(out[2])
    return (np.where(ok, out[0], 0.0), np.where(ok[..., None], out[1], 0.0), np.where(ok, out[2], np.inf))


def _asqrt_feasible(a):
    """``sqrt(x)`` where ``x >= 0`` (the poses that exist): linearized where the whole range is positive, else
    the constant form of ``[sqrt(max(lo, 0)), sqrt(max(hi, 0))]``."""
    rad = _arad(a)
    lo, hi = a[0] - rad, a[0] + rad
    with np.errstate(divide="ignore", invalid="ignore"):
        out = _aunivariate(a, lambda m: np.sqrt(np.maximum(m, 0.0)), lambda m: 0.5 / np.sqrt(m),
                           lambda lo_, hi_: np.where(lo_ > 0, 0.25 * lo_ ** -1.5, np.inf))
    ok = (lo > 0) & np.isfinite(out[2]) & np.all(np.isfinite(out[1]), axis=-1)
    s_lo, s_hi = np.sqrt(np.maximum(lo, 0.0)), np.sqrt(np.maximum(hi, 0.0))
    return (np.where(ok, out[0], 0.5 * (s_lo + s_hi)), np.where(ok[..., None], out[1], 0.0),
            np.where(ok, out[2], 0.5 * (s_hi - s_lo)))


def _acos_sin(a):
    """``cos`` and ``sin`` of an affine angle (``|f''| <= 1``)."""
    one = lambda lo, hi: np.ones_like(lo)      # noqa: E731
    return (_aunivariate(a, np.cos, lambda m: -np.sin(m), one), _aunivariate(a, np.sin, np.cos, one))


def _aunit(a):
    """``d / |d|`` of affine 3-vectors."""
    return _amul(a, _aexpand(_ainv_sqrt(_adot(a, a))))


def _aconst_vec(v, n: int):
    return _af(np.broadcast_to(np.asarray(v, dtype=float), (n, 3)))


def _aproj_cols(a):
    """The three columns of ``I - a a^T`` (a unit): they map the unit ball onto the unit disc normal to ``a``."""
    n = a[0].shape[0]
    return [_asub(_aconst_vec(_EYE3[k], n), _amul(a, _aexpand(_acomp(a, k)))) for k in range(3)]


def _rot_gens(ws, centre, p):
    """Rotation generators: twists ``[w x (P - c), w]``."""
    arm = _asub(p, centre)
    return [(_across(w, arm), w) for w in ws]


def _tr_gens(vs):
    return [(v, None) for v in vs]


def _revolute_af(key, axis, centre, p):
    if key == "radial":
        return [_tr_gens(_aproj_cols(axis))]
    if key == "axial":
        return [_tr_gens([axis])]
    if key in ("tilt", "direction"):
        return [_rot_gens(_aproj_cols(axis), centre, p)]
    raise ConfigError(f"no {key!r} source on a revolute")


def _stroke_out(q, stroke):
    """Boxes on which the affine value ``q`` is surely outside ``stroke`` (with twice the limits' tolerance)."""
    lo, hi = stroke
    tol = 2 * LIMIT_TOLERANCE * max(1.0, hi - lo, abs(hi), abs(lo))
    rad = _arad(q)
    return (q[0] - rad > hi + tol) | (q[0] + rad < lo - tol)


def _leg_box(leg, p, R, n):
    """Leg ``i``'s affine forms over the boxes: its closure rows ``[(f, m)]``, a context for its sources, and
    whether no pose of the box is reachable by it within its stroke. ``R``: the affine rotation of a 3-RPS /
    3-PRS, None for the identity."""
    A = _aconst_vec(leg.base, n)
    b = np.asarray(leg.platform, dtype=float)
    if R is None:
        Rb = _aconst_vec(b, n)
    else:
        Rb = _amatmul(R, _af(np.broadcast_to(b[:, None], (n, 3, 1))))
        Rb = (Rb[0][..., 0], Rb[1][..., 0, :], Rb[2][..., 0])
    B = _aadd(p, Rb)
    raw = _asub(B, A)
    ctx = {"A": A, "B": B, "p": p, "Rb": Rb, "R": R}
    out = np.zeros(n, dtype=bool)
    if isinstance(leg, DeltaLeg):
        # theta = psi - mode alpha, cos alpha = K / rho, so d(theta) = cos(theta) x + sin(theta) y with
        # cos(theta) = cos(psi) c + mode sin(psi) sqrt(1 - c^2), sin(theta) = sin(psi) c - mode cos(psi) sqrt(1 - c^2)
        a, x, y = (np.asarray(v, dtype=float) for v in leg._frame())
        ex, ey = _adot(raw, _aconst_vec(x, n)), _adot(raw, _aconst_vec(y, n))
        inv_rho = _ainv_sqrt(_aadd(_amul(ex, ex), _amul(ey, ey)))
        K = _ascale(_aadd(_adot(raw, raw), _af(np.full(n, leg.arm ** 2 - leg.rod ** 2))), 1.0 / (2 * leg.arm))
        c = _amul(K, inv_rho)
        rad_c = _arad(c)
        out |= (c[0] - rad_c > 1.0 + 1e-12) | (c[0] + rad_c < -1.0 - 1e-12)     # the arm cannot reach
        sa = _asqrt_feasible(_asub(_af(np.ones(n)), _amul(c, c)))
        cpsi, spsi = _amul(ex, inv_rho), _amul(ey, inv_rho)
        cos_t = _aadd(_amul(cpsi, c), _ascale(_amul(spsi, sa), leg.mode))
        sin_t = _asub(_amul(spsi, c), _ascale(_amul(cpsi, sa), leg.mode))
        arm_dir = _aadd(_amul(_aexpand(cos_t), _aconst_vec(x, n)), _amul(_aexpand(sin_t), _aconst_vec(y, n)))
        # the arm angle within asin(|rad| / |(cos, sin)|) of the centre's: a box surely outside the angle range
        # (mod 2 pi, with twice the limits' tolerance) holds no pose of the workspace
        norm = np.hypot(cos_t[0], sin_t[0])
        with np.errstate(divide="ignore", invalid="ignore"):
            dth = np.where(np.hypot(_arad(cos_t), _arad(sin_t)) < norm,
                           np.arcsin(np.minimum(np.hypot(_arad(cos_t), _arad(sin_t)) / norm, 1.0)), np.inf)
        lo_a, hi_a = leg.angle_range
        tol = 2 * LIMIT_TOLERANCE
        w = lo_a + np.mod(np.arctan2(sin_t[0], cos_t[0]) - lo_a, 2 * np.pi)
        out |= np.isfinite(dth) & (w - dth > hi_a + tol) & (w + dth < lo_a + 2 * np.pi - tol)
        Cm = _aadd(A, _ascale(arm_dir, leg.arm))
        Cs, Bs, rows = [], [], []
        for s in (0.5 * leg.spacing, -0.5 * leg.spacing):
            Cj = _aadd(Cm, _aconst_vec(s * a, n))
            Bj = _aadd(B, _aconst_vec(s * a, n))
            nj = _aunit(_asub(Bj, Cj))
            Cs.append(Cj)
            Bs.append(Bj)
            rows.append((nj, _across(_aadd(Rb, _aconst_vec(s * a, n)), nj)))
        ctx.update(C=Cs, Bs=Bs, arm_dir=arm_dir)
        return rows, ctx, out
    if isinstance(leg, PRSLeg):
        s_ = _aconst_vec(leg.slide, n)
        se = _adot(raw, s_)
        disc = _aadd(_asub(_amul(se, se), _adot(raw, raw)), _af(np.full(n, leg.rod ** 2)))
        out |= disc[0] + _arad(disc) < 0
        q = _asub(se, _ascale(_asqrt_feasible(disc), leg.mode))
        out |= _stroke_out(q, leg.slide_range)
        carriage = _aadd(A, _amul(_aexpand(q), s_))
        nvec = _aunit(_asub(B, carriage))
        ax = _aconst_vec(leg.axis, n)
        ctx.update(carriage=carriage, rod_dir=nvec, d=_aunit(raw))
        return [(nvec, _across(Rb, nvec)), (ax, _across(Rb, ax))], ctx, out
    # 3-UPU, 3-RPS: a leg of actuated length
    L = _asqrt_feasible(_adot(raw, raw))
    out |= _stroke_out(L, leg.stroke)
    d = _aunit(raw)
    ctx["d"] = d
    rows = [(d, _across(Rb, d))]
    if isinstance(leg, UPULeg):
        u1 = _aconst_vec(leg.base_axis, n)
        rows.append((_aconst_vec(np.zeros(3), n), _aunit(_across(u1, _across(u1, raw)))))
    else:
        ax = _aconst_vec(leg.axis, n)
        rows.append((ax, _across(Rb, ax)))
    return rows, ctx, out


def _source_gens_af(robot, leg, joint, key, ctx, n):
    """A source's generator groups (each a list of twists ``(v, w)``, ``None`` for zero parts) over the boxes, and
    the leg's rows it acts on (None: all); the same sets as ``spatial_bounds._joint_generators``."""
    kind = JOINTS[robot.architecture][joint]
    A, B, p = ctx["A"], ctx["B"], ctx["p"]
    basis = [_tr_gens([_aconst_vec(e, n) for e in _EYE3])]
    if isinstance(leg, DeltaLeg):
        rows = None
        axis = _aconst_vec(leg.axis, n)
        if joint == 0:
            centre = A
        else:
            rod = (joint - 1) // 2
            rows = [rod]
            centre = ctx["C"][rod] if joint in (1, 3) else ctx["Bs"][rod]
        if key == "position" or (kind == "S" and key == "radial"):
            return basis, rows
        if key == "actuator":
            return [_rot_gens([axis], centre, p)], rows
        if key == "length":
            if joint == 0:
                return [_tr_gens([ctx["arm_dir"]])], rows
            return [_tr_gens([_aunit(_asub(ctx["Bs"][rod], ctx["C"][rod]))])], rows
        return _revolute_af(key, axis, centre, p), rows
    d = ctx["d"]
    if key == "length":
        if isinstance(leg, PRSLeg):
            return [_tr_gens([ctx["rod_dir"] if kind == "R" else _aconst_vec(leg.slide, n)])], None
        return [_tr_gens([d])], None
    if kind == "S" or key == "position":
        return basis, None
    if kind == "P":
        if isinstance(leg, PRSLeg):
            axis, centre, origin = _aconst_vec(leg.slide, n), ctx["carriage"], A
        else:
            axis, centre, origin = d, _ascale(_aadd(A, B), 0.5), A
        if key in ("actuator", "backlash"):
            return [_tr_gens([axis])], None
        if key == "lateral":
            return [_tr_gens(_aproj_cols(axis))], None
        if key == "tilt":
            return [_rot_gens(_aproj_cols(axis), centre, p)], None
        if key == "direction":
            return [_rot_gens(_aproj_cols(axis), origin, p)], None
    if kind == "R":
        centre = ctx["carriage"] if isinstance(leg, PRSLeg) else A
        return _revolute_af(key, _aconst_vec(leg.axis, n), centre, p), None
    if kind == "U":
        if joint == 0:
            centre = A
            u1 = _aconst_vec(leg.base_axis, n)
            u2 = _aunit(_across(u1, d))
            m, fixed = _aunit(_across(u1, u2)), u1
        else:
            centre = B
            u4 = _aconst_vec(leg.platform_axis, n)      # a 3-UPU's platform does not turn
            u1 = _aunit(_across(u4, d))
            u2, fixed = u4, u4
            m = _aunit(_across(u1, u2))
        if key == "radial":
            return [_tr_gens(_aproj_cols(u1)), _tr_gens(_aproj_cols(u2))], None
        if key == "axial":
            return [_tr_gens([u1]), _tr_gens([u2])], None
        if key == "tilt":
            return [_rot_gens([m], centre, p)], None
        if key == "direction":
            return [_rot_gens(_aproj_cols(fixed), centre, p)], None
    raise ConfigError(f"no {key!r} source on joint {joint + 1} of a {robot.architecture} leg")


def _inverse_enclosure(robot, Wm, Wr):
    """``W^-1`` over ``Wm +- Wr`` ``(n, 6, 6)``: ``C = Wm^-1`` and ``Y >= |W^-1 - C|`` (the Neumann enclosure of
    the module text), and whether every ``W`` of the boxes is proven regular."""
    n = Wm.shape[0]
    ok = np.all(np.isfinite(Wm), axis=(1, 2)) & np.all(np.isfinite(Wr), axis=(1, 2))
    Wm0 = np.where(ok[:, None, None], Wm, np.eye(6))
    ok &= np.abs(np.linalg.det(Wm0)) > 1e-300
    C = np.zeros_like(Wm)
    C[ok] = np.linalg.inv(Wm0[ok])
    absC = np.abs(C)
    with np.errstate(invalid="ignore", over="ignore"):
        D = np.abs(np.eye(6) - C @ Wm0) + absC @ np.where(ok[:, None, None], Wr, 0.0)
    w0 = np.array([1.0, 1.0, 1.0] + [1.0 / robot.characteristic_length] * 3)
    w = np.broadcast_to(w0, (n, 6)).copy()
    for _ in range(WEIGHT_ITERATIONS):
        w = np.einsum("nij,nj->ni", D, w) + 1e-6 * np.max(w, axis=1, keepdims=True) * w0
        w = w / np.max(w, axis=1, keepdims=True)
    Dw = np.einsum("nij,nj->ni", D, w)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        beta = np.max(Dw / w, axis=1)
        regular = ok & (beta < 1.0) & np.all(np.isfinite(D), axis=(1, 2))
        DC = D @ absC
        e = np.max(DC / w[:, :, None], axis=1) / (1.0 - beta)[:, None]
        Y = DC + Dw[:, :, None] * e[:, None, :]
    Y = np.where(regular[:, None, None], Y, np.inf)
    return C, Y, regular


def _iv(m, r=None):
    """A midpoint-radius pair (radius 0 by default)."""
    m = np.asarray(m, dtype=float)
    return m, (np.zeros_like(m) if r is None else np.asarray(r, dtype=float))


def _sub(a, b):
    return a[0] - b[0], a[1] + b[1]


#: Krawczyk iterations (with inflation) enclosing a 3-RPS / 3-PRS's parasitic motions over a box.
PARASITIC_ITERATIONS = 6


def _cos_sin(mid, half):
    """``cos``, ``sin`` of angles ``mid +- half`` (midpoint-radius, Taylor with remainder ``half^2 / 2``)."""
    c, s = np.cos(mid), np.sin(mid)
    rem = 0.5 * half * half
    return (c, np.abs(s) * half + rem), (s, np.abs(c) * half + rem)


def _elementary(k, c, s, n, zero, one):
    """``Rx``, ``Ry`` or ``Rz`` (``k`` = 0, 1, 2) from forms of its cosine and sine (tuples of arrays)."""
    i, j = [(1, 2), (0, 2), (0, 1)][k]
    other = 3 - i - j
    sign = -1.0 if k != 1 else 1.0        # Rx, Rz: [[c, -s], [s, c]] on (i, j); Ry: [[c, s], [-s, c]]
    entries = [[zero] * 3 for _ in range(3)]
    entries[other][other] = one
    entries[i][i] = entries[j][j] = c
    entries[i][j] = tuple(sign * x if t == 0 or (t == 1 and len(c) == 3) else x for t, x in enumerate(s))
    entries[j][i] = tuple(-sign * x if t == 0 or (t == 1 and len(c) == 3) else x for t, x in enumerate(s))
    return tuple(np.stack([np.stack([entries[r][q][t] for q in range(3)], 1) for r in range(3)], 1)
                 for t in range(len(c)))


def _rotation_iv(angles_m, angles_r):
    """``R = Rz(yaw) Ry(pitch) Rx(roll)`` (extrinsic x-y-z) over midpoint-radius angles ``(n, 3)``."""
    n = angles_m.shape[0]
    mats = []
    for k in range(3):
        c, s = _cos_sin(angles_m[:, k], angles_r[:, k])
        mats.append(_elementary(k, c, s, n, (np.zeros(n), np.zeros(n)), (np.ones(n), np.zeros(n))))
    return _matmul(_matmul(mats[2], mats[1]), mats[0])


def _parasitic_box(robot, mid, half):
    """A 3-RPS / 3-PRS's parasitic ``x, y, yaw`` over boxes of ``z, roll, pitch`` ``(n, 3)``, as affine forms in
    ``t`` (module text): the Krawczyk test on ``g_i = axis_i . (p + R b_i - base_i) = 0`` around the solution
    ``s`` at the box centre (:func:`~pmaccuracy.kinematics.spatial.complete_poses`), ``Y`` the inverse of its
    Jacobian there: where ``K = s - Y g(s, box) + (I - Y J(X, box)) (X - s)`` lies inside ``X = s +- rho``, every
    pose of the box has exactly one solution in ``X`` (the branch of the centre's). Then by the mean value
    theorem ``y(t) - y(0)`` is in ``[A] t`` with ``[A] = -J(X, box)^-1 dg/dt(X, box)``, ``J^-1`` within
    ``Z`` of ``Y`` (``|I - Y J| <= mag``, ``||mag||_inf = beta < 1``), and ``|y(0) - s| <= (|Y| + Z) |g(s, c)|``.
    Returns the affine position ``(n, 3)`` and ``R`` ``(n, 3, 3)``; where the test fails their remainders are
    infinite (``W`` is then not proven regular, and the box is split)."""
    n = mid.shape[0]
    axes = np.array([leg.axis for leg in robot.legs], dtype=float)
    bases = np.array([leg.base for leg in robot.legs], dtype=float)
    b = np.array([leg.platform for leg in robot.legs], dtype=float)
    full = complete_poses(robot, mid, strict=False)
    bad = ~np.all(np.isfinite(full), axis=1)
    s = np.zeros((n, 3))
    s[~bad] = np.column_stack([full[~bad, :2], rotvec_to_euler_xyz(full[~bad, 3:])[:, 2]])
    ez = np.array([0.0, 0.0, 1.0])
    A3 = _iv(np.broadcast_to(axes, (n, 3, 3)))

    def evaluate(xm, xr, hv):
        """``g`` (n, 3), ``J`` (n, 3, 3) and ``dg/dt`` (n, 3, 3) (midpoint-radius) for parameters ``mid +- hv``
        and ``x`` in ``xm +- xr``."""
        R = _rotation_iv(np.column_stack([mid[:, 1], mid[:, 2], xm[:, 2]]),
                         np.column_stack([hv[:, 1], hv[:, 2], xr[:, 2]]))
        Rb = _matmul(R, _iv(np.broadcast_to(b.T, (n, 3, 3))))          # columns R b_i
        Rb = (np.swapaxes(Rb[0], 1, 2), np.swapaxes(Rb[1], 1, 2))      # (n, 3 legs, 3)
        p = (np.column_stack([xm[:, :2], mid[:, 0]]), np.column_stack([xr[:, :2], hv[:, 0]]))
        e = _sub(_add((p[0][:, None], p[1][:, None]), Rb), _iv(np.broadcast_to(bases, (n, 3, 3))))
        g = _dot(A3, e)
        dyaw = _dot(A3, _cross(_iv(np.broadcast_to(ez, (n, 3, 3))), Rb))
        J = (np.concatenate([np.broadcast_to(axes[:, :2], (n, 3, 2)), dyaw[0][..., None]], axis=2),
             np.concatenate([np.zeros((n, 3, 2)), dyaw[1][..., None]], axis=2))
        # dg/dt: z (axis_i[2] h_z), roll ((R e_x) x R b_i), pitch ((Rz e_y) x R b_i), times the half-widths
        Rex = (np.repeat(R[0][:, None, :, 0], 3, axis=1), np.repeat(R[1][:, None, :, 0], 3, axis=1))
        (cy, cyr), (sy, syr) = _cos_sin(xm[:, 2], xr[:, 2])
        ey = (np.repeat(np.column_stack([-sy, cy, np.zeros(n)])[:, None], 3, axis=1),
              np.repeat(np.column_stack([syr, cyr, np.zeros(n)])[:, None], 3, axis=1))
        droll, dpitch = _dot(A3, _cross(Rex, Rb)), _dot(A3, _cross(ey, Rb))
        Gt = (np.stack([axes[None, :, 2] * hv[:, 0:1], droll[0] * hv[:, 1:2], dpitch[0] * hv[:, 2:3]], axis=2),
              np.stack([np.zeros((n, 3)), droll[1] * hv[:, 1:2], dpitch[1] * hv[:, 2:3]], axis=2))
        return g, J, Gt

    g0, (J0, _), _ = evaluate(s, np.zeros((n, 3)), np.zeros((n, 3)))
    ok = ~bad & (np.abs(np.linalg.det(np.where(bad[:, None, None], np.eye(3), J0))) > 1e-12)
    Y = np.zeros((n, 3, 3))
    Y[ok] = np.linalg.inv(J0[ok])
    absY = np.abs(Y)
    gc, _, _ = evaluate(s, np.zeros((n, 3)), half)              # the parameters vary, x = s fixed
    rho = 2.0 * (absY @ gc[1][..., None])[..., 0] + 2.0 * np.abs(np.einsum("nij,nj->ni", Y, gc[0])) \
        + 1e-12 * (1.0 + np.abs(s))
    proven = np.zeros(n, dtype=bool)
    X = np.zeros((n, 3))
    with np.errstate(invalid="ignore", over="ignore"):
        for _ in range(PARASITIC_ITERATIONS):
            _, (Jm, Jr), _ = evaluate(s, rho, half)
            mag = np.abs(np.eye(3) - Y @ Jm) + absY @ Jr
            km = s - np.einsum("nij,nj->ni", Y, gc[0])
            kr = np.einsum("nij,nj->ni", absY, gc[1]) + np.einsum("nij,nj->ni", mag, rho)
            inside = np.all(np.abs(km - s) + kr < rho, axis=1) & ok & ~proven
            X[inside] = rho[inside]
            proven |= inside
            if np.all(proven | ~ok):
                break
            rho = np.where(proven[:, None], rho, 1.5 * (np.abs(km - s) + kr) + 1e-12)
        X = np.where(proven[:, None], X, 0.0)
        _, (Jm, Jr), (Gm, Gr) = evaluate(s, X, half)
        mag = np.abs(np.eye(3) - Y @ Jm) + absY @ Jr
        beta = np.max(np.sum(mag, axis=2), axis=1)
        proven &= beta < 1.0
        MY = mag @ absY
        with np.errstate(divide="ignore"):
            Z = MY + (beta / (1.0 - beta))[:, None, None] * np.max(MY, axis=1, keepdims=True)
        Am = -(Y @ Gm)
        Ar = absY @ Gr + Z @ (np.abs(Gm) + Gr)
        g_c, _, _ = evaluate(s, np.zeros((n, 3)), np.zeros((n, 3)))
        eps0 = ((absY + Z) @ (np.abs(g_c[0]) + g_c[1])[..., None])[..., 0]
        rem = np.sum(Ar, axis=2) + eps0
    rem = np.where(proven[:, None] & np.isfinite(rem), rem * (1 + ROUNDING), np.inf)
    Am = np.where(proven[:, None, None] & np.isfinite(Am), Am, 0.0)
    # affine forms in t: z = c_z + h_z t_0, roll = c + h t_1, pitch = c + h t_2; x, y, yaw = s + Am t +- rem
    eye = np.eye(3)
    z = (mid[:, 0], half[:, 0:1] * eye[0], np.zeros(n))
    x_, y_, yaw = ((s[:, k], Am[:, k], rem[:, k]) for k in range(3))
    p = _astack([x_, y_, z])
    mats = []
    for k, ang in enumerate(((mid[:, 1], half[:, 1:2] * eye[1], np.zeros(n)),
                             (mid[:, 2], half[:, 2:3] * eye[2], np.zeros(n)), yaw)):
        c, s_ = _acos_sin(ang)
        mats.append(_elementary(k, c, s_, n, _af(np.zeros(n)), _af(np.ones(n))))
    R = _amatmul(_amatmul(mats[2], mats[1]), mats[0])
    return p, R


def _legs_box_bounds(robot, sources, boxes, point_gap):
    """Certified upper bounds ``(n, 8)`` over boxes ``(n, 3, 2)`` of a 3-UPU, Delta, 3-RPS or 3-PRS (the affine
    forms above; ``inf`` where ``W`` is not proven regular), whether each box provably holds no pose of the
    workspace, whether its ``W`` is not proven regular, and (NaN) split shares. An infinite remainder times 0
    gives NaN, which every test reads as unproven (never as a finite bound)."""
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        return _legs_box_bounds_of(robot, sources, boxes, point_gap)


def _legs_box_bounds_of(robot, sources, boxes, point_gap):
    n = boxes.shape[0]
    mid = 0.5 * (boxes[:, :, 0] + boxes[:, :, 1])
    half = 0.5 * (boxes[:, :, 1] - boxes[:, :, 0])
    R = None
    if robot.mobility == "2R1T":
        p, R = _parasitic_box(robot, mid, half)
    else:
        p = (mid, half[:, :, None] * np.eye(3), np.zeros((n, 3)))
    out = np.zeros(n, dtype=bool)
    rows, ctxs = [], []
    with np.errstate(invalid="ignore", over="ignore"):
        for leg in robot.legs:
            r, c, o = _leg_box(leg, p, R, n)
            rows.append(r)
            ctxs.append(c)
            out |= o
        flat = [_astack([_acomp(f, 0), _acomp(f, 1), _acomp(f, 2), _acomp(m, 0), _acomp(m, 1), _acomp(m, 2)])
                for r in rows for f, m in r]
        W = (np.stack([f[0] for f in flat], 1), np.stack([f[1] for f in flat], 1),
             np.stack([f[2] for f in flat], 1))                            # (n, 6, 6), G (n, 6, 6, 3)
    C, Y, regular = _inverse_enclosure(robot, W[0], _arad(W))
    absC = np.abs(C)
    Mm, Mr = [], []
    row0 = 0
    for i, leg in enumerate(robot.legs):
        k = len(rows[i])
        for j, joint in enumerate(sources.legs[i]):
            for key, h in joint.items():
                if h == 0:
                    continue
                kind = "actuator" if key == "backlash" and robot.actuated_kinds[i] == "R" else key
                groups, which = _source_gens_af(robot, leg, j, kind, ctxs[i], n)
                for gens in groups:
                    d = len(gens)
                    Em, EG, Er = np.zeros((n, 6, d)), np.zeros((n, 6, d, 3)), np.zeros((n, 6, d))
                    with np.errstate(invalid="ignore", over="ignore"):
                        for r_, (f, m) in enumerate(rows[i]):
                            if which is not None and r_ not in which:
                                continue
                            for c_, (v, w) in enumerate(gens):
                                e = _adot(f, v)
                                if w is not None:
                                    e = _aadd(e, _adot(m, w))
                                Em[:, row0 + r_, c_], EG[:, row0 + r_, c_], Er[:, row0 + r_, c_] = \
                                    h * e[0], h * e[1], h * e[2]
                        # M(t) = W(t)^-1 E(t) (E padded to the six rows), Mc = C E(0):
                        # M(t) - Mc = W(t)^-1 Res(t), Res(t) = E(t) - W(t) Mc = Res0 + D t + e,
                        # |e| <= Er + Wr |Mc|; |W^-1 Res| <= |C Res0| + sum_l |C D_l| + |C| |e| + Y |Res|
                        Mc = C @ Em
                        res0 = Em - W[0] @ Mc
                        D = EG - np.einsum("nikl,nkj->nijl", W[1], Mc)
                        e_r = Er + W[2] @ np.abs(Mc)
                        res_mag = np.abs(res0) + np.sum(np.abs(D), axis=-1) + e_r
                        lin = np.abs(C @ res0) + np.sum(np.abs(np.einsum("nik,nkjl->nijl", C, D)), axis=-1)
                        Mm.append(Mc)
                        Mr.append(lin + absC @ e_r + Y @ res_mag)
        row0 += k
    upper = np.full((n, len(QUANTITIES)), np.inf)
    sel = regular & ~out
    if Mm and np.any(sel):
        with np.errstate(invalid="ignore", over="ignore"):
            comp = sum(np.linalg.norm(np.abs(a) + b, axis=-1) for a, b in zip(Mm, Mr))
            vals = [comp]
            for rs in (slice(0, 3), slice(3, 6)):
                extra = sum(np.linalg.norm(b[:, rs], axis=(1, 2)) for b in Mr)
                mn = np.zeros(n)
                mn[sel] = max_norm([a[sel][:, rs] for a in Mm], gap=point_gap).upper
                vals.append((mn + extra)[:, None])
        vals = np.concatenate(vals, axis=1) * (1 + ROUNDING)
        upper[sel] = np.where(np.isfinite(vals[sel]), vals[sel], np.inf)
    elif not Mm:
        upper[regular] = 0.0
    return upper, out, ~regular, np.full((n, 3), np.nan)


#: The 32 sign vectors of six segments up to a global sign.
_SIGNS = np.array([s for s in itertools.product((1.0, -1.0), repeat=6) if s[0] > 0])


def spatial_global_worst(robot: SpatialManipulator, clearances, region: SpatialRegion, *,
                         gap: float = DEFAULT_GAP, max_boxes: int = DEFAULT_MAX_BOXES, grid: int = 7,
                         min_size: float | None = None, point_gap: float = 1e-3) -> SpatialGlobalWorst:
    """The worst first-order errors of a spatial robot over ``region`` (:func:`spatial_region`): attained lower
    bounds and certified upper bounds within ``gap`` (module text; not for a robot of joint chains, nor over a
    3-RPS's or 3-PRS's whole workspace: ``inf`` there, with the reason).

    Returns :class:`SpatialGlobalWorst` (``dp`` in mm, rotations in rad). Raises
    :class:`~pmaccuracy.errors.EmptyWorkspaceError` when no sampled pose of the region is in the workspace.

    Parameters
    ----------
    clearances : SpatialErrorSources, str or path
        The error sources, a preset name or a file (None: the architecture's typical preset).
    gap : float
        Requested relative gap ``(upper - lower) / lower`` (default 1 %).
    max_boxes : int
        Budget of evaluated boxes; when spent the bounds so far are returned, ``converged`` False.
    grid : int
        Initial samples per coordinate (a 6-UPS's orientation ranges: 3 per angle).
    min_size : float
        mm: boxes are not split below it (default ``1e-6`` of the characteristic length); a box that small not
        proven regular raises :class:`SpatialSingularRegionError`.
    point_gap : float
        The relative gap of ``dp`` and ``dtheta`` at each sampled pose (their attained values are used).

    >>> robot = SpatialManipulator.preset("stewart_6ups")
    >>> region = spatial_region(robot, box=(-5, 5, -5, 5, 395, 405), orientation=(0.0, 0.0, 0.0))
    >>> res = spatial_global_worst(robot, "ups_typical", region)
    >>> res.certified and res["dp"].lower <= res["dp"].upper <= 1.01 * res["dp"].lower
    True
    """
    robot = robot_arg(robot)
    if not isinstance(robot, SpatialManipulator):
        raise ConfigError(f"{robot.name} is a planar robot (global_worst)", key="robot")
    if not isinstance(region, SpatialRegion):
        raise ConfigError(f"the region of a spatial robot is a SpatialRegion (spatial_region), got "
                          f"{type(region).__name__}", key="region")
    if not (isinstance(gap, (int, float)) and 0 < gap < 1):
        raise ConfigError(f"must be a fraction in (0, 1), got {gap!r}", key="gap")
    if not (isinstance(max_boxes, (int, np.integer)) and max_boxes > 0):
        raise ConfigError(f"must be a positive integer, got {max_boxes!r}", key="max_boxes")
    if not (isinstance(grid, (int, np.integer)) and grid >= 2):
        raise ConfigError(f"must be an integer >= 2, got {grid!r}", key="grid")
    t0 = time.perf_counter()
    sources = _sources(robot, clearances)
    L = robot.characteristic_length
    min_size = 1e-6 * L if min_size is None else float(min_size)
    root = _box_dims(robot, region)
    k = root.shape[0]
    scale = np.array([1.0 if n not in ("roll", "pitch") else L for n in region.names] + [L] * (k - 3))
    atol = ATOL * np.array([1.0, 1.0, 1.0, 1 / L, 1 / L, 1 / L, 1.0, 1 / L])
    samples = _grid(root[:3], grid)
    if k == 6:
        orients = _grid(root[3:], 3)
        samples = np.concatenate([np.repeat(samples, orients.shape[0], axis=0),
                                  np.tile(orients, (samples.shape[0], 1))], axis=1)
    values, poses = _evaluate(robot, sources, region, samples, point_gap)
    lower = np.zeros(len(QUANTITIES))
    lower_pose = np.full((len(QUANTITIES), 6), np.nan)
    lower_pt = np.full((len(QUANTITIES), k), np.nan)

    def take(vals, full, pts):
        nonlocal lower, lower_pose, lower_pt
        if not np.any(np.isfinite(vals)):
            return
        j = np.argmax(np.where(np.isnan(vals), -np.inf, vals), axis=0)
        best = vals[j, range(len(QUANTITIES))]
        better = np.isfinite(best) & ((best > lower) | np.isnan(lower_pose[:, 0]))
        lower = np.where(better, best, lower)
        lower_pose = np.where(better[:, None], full[j], lower_pose)
        lower_pt = np.where(better[:, None], pts[j], lower_pt)

    take(values, poses, samples)
    certified = robot.architecture in CERTIFIED and not robot.is_chain
    reason = "" if certified else UNCERTIFIED.format(arch=robot.architecture)
    if certified and region.kind == "workspace" and robot.mobility == "2R1T":
        certified, reason = False, UNBOUNDED.format(arch=robot.architecture)
    n_boxes = iterations = 0
    converged = np.zeros(len(QUANTITIES), dtype=bool)
    closed = np.zeros(len(QUANTITIES))
    if certified:
        if robot.architecture == "6-UPS":
            terms = hexapod_leg_terms(robot, sources)
            bound = lambda b: _hexapod_box_bounds(robot, terms, b)      # noqa: E731
        else:
            bound = lambda b: _legs_box_bounds(robot, sources, b, point_gap)      # noqa: E731
        boxes = root[None].copy()
        active = np.ones((1, len(QUANTITIES)), dtype=bool)
        converged[:] = True
        while boxes.shape[0]:
            iterations += 1
            keep = region.meets(boxes[:, :3])
            boxes, active = boxes[keep], active[keep]
            if not boxes.shape[0]:
                break
            n_boxes += boxes.shape[0]
            parts = [bound(boxes[k:k + BOX_CHUNK])
                     for k in range(0, boxes.shape[0], BOX_CHUNK)]   # bounded memory
            upper, outside, unproven, share = (np.concatenate([part[i] for part in parts]) for i in range(4))
            keep = ~outside
            boxes, active, upper, unproven, share = (boxes[keep], active[keep], upper[keep], unproven[keep],
                                                     share[keep])
            if not boxes.shape[0]:
                break
            centres = 0.5 * (boxes[:, :, 0] + boxes[:, :, 1])
            vals, full = _evaluate(robot, sources, region, centres, point_gap)
            take(vals, full, centres)
            sizes = (boxes[:, :, 1] - boxes[:, :, 0]) * scale
            small = np.max(sizes, axis=1) <= min_size
            if np.any(small & unproven):
                b = centres[np.argmax(small & unproven)]
                raise SpatialSingularRegionError(
                    f"{region.describe()} reaches a singularity of {robot.name} near (x, y, z) = "
                    f"({b[0]:.4g}, {b[1]:.4g}, {b[2]:.4g}) mm (W may be singular there): the worst-case errors "
                    "are unbounded; narrow the region")
            done = active & (upper <= lower * (1 + gap) + atol)
            closed = np.maximum(closed, np.max(np.where(done, upper, 0.0), axis=0))
            active &= ~done
            alive = np.any(active, axis=1)
            boxes, active, sizes, upper, share = (boxes[alive], active[alive], sizes[alive], upper[alive],
                                                  share[alive])
            if not boxes.shape[0]:
                break
            if n_boxes + 2 * boxes.shape[0] > max_boxes:
                closed = np.maximum(closed, np.max(np.where(active, upper, 0.0), axis=0))
                converged = ~np.any(active, axis=0)
                break
            # split the side with the largest share of the mean-value bound's slack, else the widest
            known = np.all(np.isfinite(share), axis=1) & np.any(share > 0, axis=1)
            axis = np.where(known, np.argmax(np.where(np.isfinite(share), share, 0.0), axis=1),
                            np.argmax(sizes, axis=1))
            rows = np.arange(boxes.shape[0])
            m = 0.5 * (boxes[rows, axis, 0] + boxes[rows, axis, 1])
            left, right = boxes.copy(), boxes.copy()
            left[rows, axis, 1] = m
            right[rows, axis, 0] = m
            boxes = np.concatenate([left, right])
            active = np.concatenate([active, active])
    else:
        # lower bounds only: local grids around the best points, shrinking
        span = (root[:, 1] - root[:, 0]) / max(grid - 1, 1)
        for _ in range(6):
            pts = []
            for q in range(len(QUANTITIES)):
                if np.all(np.isfinite(lower_pt[q])):
                    box = np.column_stack([np.maximum(lower_pt[q] - span, root[:, 0]),
                                           np.minimum(lower_pt[q] + span, root[:, 1])])
                    pts.append(_grid(box, 5))
            if not pts:
                break
            pts = np.unique(np.vstack(pts), axis=0)
            vals, full = _evaluate(robot, sources, region, pts, point_gap)
            take(vals, full, pts)
            span = span / 2.5
        converged[:] = False
    if not np.any(np.isfinite(lower_pose)):
        raise EmptyWorkspaceError(f"{region.describe()}: no sampled pose of the region is in the workspace of "
                                  f"{robot.name}")
    out = {}
    for i, name in enumerate(QUANTITIES):
        lo = float(lower[i])
        up = float(max(closed[i], lo)) if certified else np.inf
        g = (up - lo) / lo if lo > 0 else (0.0 if up <= atol[i] else np.inf)
        out[name] = SpatialQuantityWorst(name=name, lower=lo, upper=up, pose=lower_pose[i].copy(), gap=g,
                                         converged=bool(certified and converged[i]
                                                        and up <= lo * (1 + gap) + atol[i]))
    return SpatialGlobalWorst(quantities=out, certified=certified, reason=reason, boxes=n_boxes,
                              iterations=iterations, seconds=time.perf_counter() - t0, target_gap=gap,
                              region=region)
