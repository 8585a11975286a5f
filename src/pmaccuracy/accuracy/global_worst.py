"""Certified global worst case of the pose errors over a region of poses (branch and bound).

The maxima ``dx, dy, dphi, dp`` of Eq. 21-22 (:func:`pmaccuracy.accuracy.bounds.max_pose_errors`)
are maximized over a region ``R`` of poses: a box ``[x0, x1] x [y0, y1]`` (mm)
times an orientation interval ``[phi0, phi1]`` (rad), intersected with the
workspace (every leg reaches the pose on its working mode with every joint in
its range, as :func:`pmaccuracy.kinematics.inverse_kinematics`). Poses of the box
outside the workspace are skipped: the result is the maximum over
``box ∩ workspace``. Region ``"workspace"`` takes a box that provably holds
every reachable position (each leg's reach, from its link lengths and slide
ranges).

Branch and bound, for each quantity ``Q``:

* **lower bound** ``L``: the largest ``Q`` at the centres and corners of the
  boxes (and an initial grid) that are in the workspace, exact at those poses
  (:func:`~pmaccuracy.accuracy.bounds.max_pose_errors`); the pose attaining it is kept;
* **upper bound** of a box: the smaller of the natural interval enclosure of the closed forms and
  their mean-value form ``Q(c) + sum_j G_j r_j`` (centre ``c``, half-widths ``r``, slope bounds ``G`` from
  the closed forms differentiated in interval arithmetic; :func:`pmaccuracy.accuracy.interval.box_bounds`),
  rigorous over the box's part in the workspace, widened by a relative ``1e-9`` for rounding. The natural
  enclosure overestimates by a fraction proportional to the box's width, the mean-value form by one
  proportional to its square, so boxes near a flat maximum (over an orientation interval, or inside the box)
  close without being split down to the gap;
* a box whose upper bound is ``<= L (1 + gap)`` is closed (its bound is kept in
  ``U``); the others are bisected along the side whose term ``G_j r_j`` is the largest share of their open
  bounds where the mean-value form binds, else along their widest side (phi scaled by the characteristic
  length), until none is left; while at most ``SMALL_BATCH / 4`` boxes are open each half is bisected once
  more in the same round (fewer rounds of small batches).

At the end ``U = max`` of the closed boxes' bounds, so ``L <= max_R Q <= U``
and ``(U - L) / L <= gap``. Boxes whose ``det A`` interval keeps containing 0 down
to a side of ``min_size`` mm, or any sampled pose of the region with a
condition number above ``max_condition``, mean the region touches a parallel
singularity where the maxima are unbounded: :class:`SingularRegionError`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .bounds import QUANTITIES, max_pose_errors
from ..model.clearances import ClearanceSet
from .._display import html_table
from ..errors import ConfigError, EmptyWorkspaceError, PoseError, SingularPoseError
from ..model.manipulator import Manipulator
from ..model.plausibility import check_orientations
from ..model.spatial import is_spatial
from .spatial_worst import spatial_global_worst
from .certified.error_set import error_set
from .certified.region import box_remainder, exact_lower
from .interval import Iv, box_bounds, leg_box_state
from .regions import OUTSIDE, Disc, Polygon, Rect, Shape
from ..kinematics import DEFAULT_MAX_CONDITION, inverse_kinematics, singularity
from ..model.sources import ErrorSources, refuse_first_order_only
from ..io.resolve import robot_arg
from ..io.resolve import load_clearances
from ..kinematics.workspace import constant_orientation_workspace
from ..numerics.interval import cv_expi

#: Default relative gap ``(upper - lower) / lower`` of the certificate.
DEFAULT_GAP = 1e-3
#: Relative widening of every interval upper bound (covers floating-point rounding).
ROUNDING = 1e-9
#: Absolute tolerance (mm; rad times the characteristic length for dphi): a bound this small certifies a
#: maximum of 0 (a quantity the sources do not move at first order leaves rounding-level bounds).
ATOL = 1e-12
#: Characteristic lengths per radian that turn a box's phi width into mm when choosing the side to split.
PHI_SCALE = 1.0
#: Below this many boxes a round of the branch and bound splits each open box in four (two bisections).
SMALL_BATCH = 512
#: Default relative gap of the exact model's worst case (``exact=True``): its remainder bound over a box
#: overestimates the nonlinear part by a factor of a few (:mod:`pmaccuracy.accuracy.certified.region`).
DEFAULT_EXACT_GAP = 1e-2
#: With ``exact=True``, the best feasible exact values are computed at this many poses per quantity and round
#: (those of largest first-order value).
EXACT_CANDIDATES = 8
#: With ``exact=True`` a box gets the second-order bound only where its first-order bound plus this many times
#: that bound's first-order change over the box stays within the gap (elsewhere it could not close the box).
TIGHT_SLACK = 2.0


class SingularRegionError(SingularPoseError):
    """The region reaches a parallel singularity: the worst-case errors are unbounded there."""


@dataclass(frozen=True)
class Region:
    """A region of poses: positions in a box ``x (x0, x1)``, ``y (y0, y1)`` mm, or in ``shape`` (a
    :class:`~pmaccuracy.accuracy.regions.Disc` or :class:`~pmaccuracy.accuracy.regions.Polygon`, whose
    bounding box ``x, y`` is), times ``phi (phi0, phi1)`` rad; ``workspace`` when the box was derived from
    the legs' reach (the whole workspace over the orientation interval). Poses outside the workspace are
    never part of it."""

    x: tuple[float, float]
    y: tuple[float, float]
    phi: tuple[float, float]
    workspace: bool = False
    shape: Shape | None = None

    def contains(self, x, y) -> np.ndarray:
        """Positions ``(x, y)`` (mm, any broadcastable shapes) in the region's box or shape (not checked
        against the workspace)."""
        if self.shape is not None:
            return self.shape.contains(x, y)
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        return (x >= self.x[0]) & (x <= self.x[1]) & (y >= self.y[0]) & (y <= self.y[1])

    def describe(self) -> str:
        ang = f"phi in [{np.degrees(self.phi[0]):g}, {np.degrees(self.phi[1]):g}] deg"
        if self.workspace:
            return f"the workspace at {ang}"
        if self.shape is not None:
            return f"{self.shape.describe()}, {ang}"
        return f"x in [{self.x[0]:g}, {self.x[1]:g}] mm, y in [{self.y[0]:g}, {self.y[1]:g}] mm, {ang}"


@dataclass(frozen=True)
class QuantityWorst:
    """The certified maximum of one quantity (mm; rad for ``dphi``).

    lower : attained value at ``pose`` ``(3,)`` [mm, mm, rad]
    upper : rigorous bound over the region;  gap : ``(upper - lower) / lower`` (0 when both are 0)
    converged : the gap reached the requested one (or ``upper - lower`` is below :data:`ATOL`)
    """

    name: str
    lower: float
    upper: float
    pose: np.ndarray
    gap: float
    converged: bool


@dataclass(frozen=True)
class GlobalWorst:
    """Result of :func:`global_worst`: one :class:`QuantityWorst` per quantity (``dx, dy, dphi, dp``),
    boxes evaluated, iterations, wall time (s), the requested gap, the region and whether the values are the
    exact loop closure's (``exact``) or the first-order model's."""

    quantities: dict[str, QuantityWorst]
    boxes: int
    iterations: int
    seconds: float
    target_gap: float
    region: Region = field(repr=False)
    exact: bool = False

    def __getitem__(self, name: str) -> QuantityWorst:
        return self.quantities[name]

    def records(self) -> list[dict]:
        """One dict per quantity: attained value, certified upper bound (mm; deg for dphi), gap, pose."""
        out = []
        for name, w in self.quantities.items():
            k = 180 / np.pi if name == "dphi" else 1.0
            out.append({"quantity": name, "unit": "deg" if name == "dphi" else "mm", "attained": w.lower * k,
                        "upper": w.upper * k, "gap_percent": w.gap * 100, "x": float(w.pose[0]),
                        "y": float(w.pose[1]), "phi_deg": float(np.degrees(w.pose[2])), "converged": w.converged})
        return out

    def __repr__(self) -> str:
        parts = [f"{r['quantity']} {r['attained']:.6g} {r['unit']} (upper {r['upper']:.6g}, gap {r['gap_percent']:.2g} %, "
                 f"at {r['x']:.4g}, {r['y']:.4g} mm, {r['phi_deg']:.4g} deg)" for r in self.records()]
        model = "exact model: " if self.exact else ""
        return f"GlobalWorst({model}{', '.join(parts)}; {self.boxes} boxes, {self.seconds:.2g} s)"

    def _repr_html_(self) -> str:
        title = "Certified worst case over the region" + (" (exact loop closure)" if self.exact else "")
        return html_table(title, self.records())


def as_sources(robot: Manipulator, clearances) -> ErrorSources:
    """Per-joint :class:`~pmaccuracy.model.sources.ErrorSources` of a clearance object (3-PPR format converted)."""
    if not isinstance(clearances, (ClearanceSet, ErrorSources)):   # a preset name or a file

        clearances = load_clearances(clearances, robot)
    if isinstance(clearances, ClearanceSet):
        return ErrorSources.from_clearance_set(clearances)
    return refuse_first_order_only(clearances.check(robot), "the global worst case (interval enclosures)")


def reach_region(robot: Manipulator, phi: tuple[float, float]) -> Region:
    """A box holding every reachable position for ``phi`` in the interval (mm): each leg's end frame lies
    within ``sum |link_k| + max |q_k|`` (slides) of its base, so ``p`` lies in that disc moved by
    ``-exp(i phi) platform``; the boxes of the three legs intersected.

    Raises :class:`ConfigError` when every leg has an unlimited slide (give a box).
    """
    ph = Iv(np.array([phi[0]]), np.array([phi[1]]))
    e = cv_expi(ph)
    xs, ys = [-np.inf, np.inf], [-np.inf, np.inf]
    for chain in robot.chains:
        reach = 0.0
        for joint in chain.joints:
            reach += abs(complex(*joint.link))
            if joint.kind == "P":
                reach += max(abs(joint.range[0]), abs(joint.range[1]))
        if not np.isfinite(reach):
            continue
        att = e * complex(*chain.platform)
        bx, by = chain.base
        xs = [max(xs[0], bx - reach - att.re.hi[0]), min(xs[1], bx + reach - att.re.lo[0])]
        ys = [max(ys[0], by - reach - att.im.hi[0]), min(ys[1], by + reach - att.im.lo[0])]
    if not np.all(np.isfinite(xs + ys)):
        raise ConfigError("the legs' reach is unbounded (unlimited slides): give a box x0,x1,y0,y1",
                          key="--region")
    if xs[0] >= xs[1] or ys[0] >= ys[1]:
        raise EmptyWorkspaceError(f"no position is reachable for phi in [{np.degrees(phi[0]):g}, "
                                  f"{np.degrees(phi[1]):g}] deg")
    return Region(x=(float(xs[0]), float(xs[1])), y=(float(ys[0]), float(ys[1])), phi=phi, workspace=True)


def make_region(robot: Manipulator, phi: tuple[float, float],
                box: tuple[float, float, float, float] | Shape | None) -> Region:
    """Check and build a region: ``phi (lo, hi)`` rad with ``lo <= hi``; ``box (x0, x1, y0, y1)`` mm, a shape
    (:class:`~pmaccuracy.accuracy.regions.Disc`, :class:`~pmaccuracy.accuracy.regions.Polygon` or
    :class:`~pmaccuracy.accuracy.regions.Rect`) or None for the whole workspace. ``robot``: an object, a
    preset name or a robot file.

    >>> from pmaccuracy.accuracy.regions import Disc
    >>> make_region("aalborg_3ppr", (0.0, 0.0), Disc((0.0, 0.0), 20.0)).describe()
    'the disc of centre (0, 0) mm and radius 20 mm, phi in [0, 0] deg'

    Orientations beyond a full turn warn (:func:`pmaccuracy.model.plausibility.check_orientations`);
    :func:`global_worst` and :func:`~pmaccuracy.accuracy.synthesis.synthesize` take the region as made here.
    """
    check_orientations(phi, "phi")
    robot = robot_arg(robot)
    if is_spatial(robot):
        raise ConfigError(f"{robot.name} is a spatial robot: its region is made by spatial_region(robot, box=..., "
                          "cylinder=..., sphere=..., orientation=...)", key="robot")
    if np.shape(phi) != (2,):
        raise ConfigError(f"the orientation interval must be two numbers (lo, hi) in rad, got {phi!r}",
                          key="phi")
    if box is not None and not isinstance(box, (Disc, Polygon, Rect)) and np.shape(box) != (4,):
        raise ConfigError(f"the box must be four numbers (x0, x1, y0, y1) in mm or None, got {box!r}",
                          key="box")
    lo, hi = (float(v) for v in phi)
    if not (np.isfinite(lo) and np.isfinite(hi)):
        raise ConfigError(f"the orientation interval must be finite, got [{lo}, {hi}] rad", key="phi")
    if lo > hi:
        raise ConfigError(f"the orientation interval is reversed: {np.degrees(lo):g} > {np.degrees(hi):g} deg "
                          f"({lo:g} > {hi:g} rad)", key="phi")
    if hi - lo >= np.pi:
        raise ConfigError(f"the orientation interval must be shorter than pi rad (180 deg), got [{lo:g}, {hi:g}] "
                          f"rad ({np.degrees(hi - lo):g} deg wide; angles are in rad)", key="phi")
    if box is None:
        return reach_region(robot, (lo, hi))
    if isinstance(box, Rect):
        box = box.bounds
    if isinstance(box, (Disc, Polygon)):
        x0, x1, y0, y1 = box.bounds
        return Region(x=(x0, x1), y=(y0, y1), phi=(lo, hi), shape=box)
    x0, x1, y0, y1 = (float(v) for v in box)
    if not np.all(np.isfinite([x0, x1, y0, y1])):
        raise ConfigError("the box must be finite", key="box")
    if x0 > x1 or y0 > y1:
        raise ConfigError(f"the box is empty or reversed: x0={x0:g} > x1={x1:g} or y0={y0:g} > y1={y1:g}",
                          key="box")
    return Region(x=(x0, x1), y=(y0, y1), phi=(lo, hi))


def leg_branches(robot: Manipulator, pose: np.ndarray) -> tuple[float, float, float]:
    """Each leg's IK root sign on its working mode: the one whose point evaluation by
    :func:`pmaccuracy.accuracy.interval.leg_box_state` gives the joint values of :meth:`Chain.state` at ``pose``."""
    out = []
    p = np.asarray(pose, dtype=float).reshape(1, 3)
    x, y, ph = Iv(p[:, 0]), Iv(p[:, 1]), Iv(p[:, 2])
    for chain in robot.chains:
        if chain.n_branches == 1:
            out.append(1.0)
            continue
        q = chain.state(p).q[0]
        errs = []
        for sigma in (1.0, -1.0):
            lb = leg_box_state(chain, x, y, ph, sigma)
            err = 0.0
            for k, joint in enumerate(chain.joints):
                d = lb.q[k].lo[0] - q[k]
                err += abs(d) if joint.kind == "P" else abs(np.angle(np.exp(1j * d)))
            errs.append(err if np.isfinite(err) else np.inf)
        out.append(1.0 if errs[0] <= errs[1] else -1.0)
    return tuple(out)


def _exact(robot, clearances, poses: np.ndarray, sources: ErrorSources | None = None
           ) -> tuple[np.ndarray, np.ndarray]:
    """Exact maxima ``(m, 4)`` at the poses of the workspace (NaN elsewhere) and the in-workspace mask.

    With ``sources`` (the exact model's worst case): the best feasible values of the exact model
    (:func:`~pmaccuracy.accuracy.certified.region.exact_lower`, attained, so lower bounds) at the
    :data:`EXACT_CANDIDATES` poses of largest first-order value per quantity, NaN at the others."""
    values = np.full((poses.shape[0], 4), np.nan)
    if poses.shape[0] == 0:
        return values, np.zeros(0, dtype=bool)
    inside = inverse_kinematics(robot, poses).within_limits
    if np.any(inside):
        b = max_pose_errors(robot, clearances, poses[inside], singular="nan", max_condition=np.inf)
        values[inside] = np.column_stack([b.dx_max, b.dy_max, b.dphi_max, b.dp_max])
    if sources is not None and np.any(inside):
        order = np.argsort(np.where(np.isnan(values), np.inf, -values), axis=0)[:EXACT_CANDIDATES]
        pick = np.unique(order.ravel())
        pick = pick[inside[pick]]
        exact = np.full_like(values, np.nan)
        exact[pick] = exact_lower(robot, sources, poses[pick])
        values = exact
    return values, inside


def _check_regular(robot: Manipulator, poses: np.ndarray, region: Region, max_condition: float) -> None:
    if poses.shape[0] == 0:
        return
    cond = singularity(robot, poses).condition
    bad = cond > max_condition
    if np.any(bad):
        k = int(np.argmax(cond))
        x, y, phi = poses[k]
        raise SingularRegionError(
            f"{region.describe()} reaches a parallel singularity (near x={x:g} mm, y={y:g} mm, "
            f"phi={np.degrees(phi):g} deg: condition number {cond[k]:.3g} > {max_condition:g}); the worst-case "
            "errors are unbounded there: narrow --phi-deg or --region")


def _vertices(robot: Manipulator, region: Region, phis, seen: set) -> np.ndarray:
    """Corners of the constant-orientation workspaces at the orientations ``phis`` not in ``seen`` (which
    they are added to), inside the region's box: maxima often sit there (for a 3-PPR at fixed phi the
    half-widths are affine in the position, the maxima convex, so a maximum is at a corner)."""

    out = [np.zeros((0, 3))]
    for phi in np.asarray(phis, dtype=float).ravel():
        if not np.isfinite(phi) or float(phi) in seen:
            continue
        seen.add(float(phi))
        ws = constant_orientation_workspace(robot, float(phi))
        v = ws.vertices
        if v.shape[0]:
            keep = region.contains(v[:, 0], v[:, 1])
            out.append(np.column_stack([v[keep], np.full(int(keep.sum()), float(phi))]))
    return np.vstack(out)


def global_worst(robot: Manipulator, clearances, region: Region, *, gap: float | None = None,
                 max_condition: float = DEFAULT_MAX_CONDITION, max_boxes: int | None = None,
                 min_size: float | None = None, grid: int = 21, candidates: np.ndarray | None = None,
                 exact: bool = False) -> GlobalWorst:
    """Certified maxima of ``dx, dy, dphi, dp`` over ``region`` (module docstring), within relative ``gap``.

    Parameters
    ----------
    clearances : a :class:`~pmaccuracy.model.clearances.ClearanceSet` (3-PPR) or
        :class:`~pmaccuracy.model.sources.ErrorSources` (any architecture)
    region : :func:`make_region`
    gap : requested ``(upper - lower) / lower`` (> 0), default 0.1 % (1 % with ``exact``)
    max_boxes : budget of evaluated boxes (default 2,000,000; 100,000 with ``exact``); when spent, the bounds
        so far are returned with ``converged = False`` (still valid, wider gap)
    min_size : mm, boxes are not split below it (default ``1e-7`` of the
        characteristic length); a singular box that small raises
    grid : ``grid x grid x (grid or 1)`` initial samples for the lower bounds and the singularity check
    candidates : optional poses ``(k, 3)`` of the region also tried for the lower bounds (e.g. the best
        poses of a grid, :func:`grid_best`)
    exact : certify the worst case of the exact (nonlinear) loop closure instead of the first-order model
        (after a first-order run to half the gap, whose worst poses seed the lower bounds):
        every box's upper bound adds a remainder bound that holds at every pose of the box
        (:func:`~pmaccuracy.accuracy.certified.region.box_remainder`; ``inf`` until the box is small enough for
        it, so such boxes are split) and the lower bounds are best feasible configurations of the exact model
        (:func:`~pmaccuracy.accuracy.certified.region.exact_lower`) at the sampled poses of largest first-order
        value. The result's values are then the exact model's: ``lower`` attained by a configuration of the
        error set at ``pose``, ``upper`` never below the exact maximum over the region.

    Notes
    -----
    A spatial robot (:class:`~pmaccuracy.model.spatial.SpatialManipulator`) takes a
    :class:`~pmaccuracy.accuracy.spatial_worst.SpatialRegion` (:func:`~pmaccuracy.accuracy.spatial_worst.spatial_region`)
    and gives a :class:`~pmaccuracy.accuracy.spatial_worst.SpatialGlobalWorst`
    (:func:`~pmaccuracy.accuracy.spatial_worst.spatial_global_worst`: ``gap`` default 1 %).

    Returns :class:`GlobalWorst`. Raises :class:`EmptyWorkspaceError` when no
    sampled pose of the region lies in the workspace and the bounds cannot prove
    it empty, :class:`SingularRegionError` near a parallel singularity.

    >>> robot = Manipulator.preset("aalborg_3ppr")
    >>> from pmaccuracy.model.clearances import ClearanceSet
    >>> res = global_worst(robot, ClearanceSet.preset("case1"), make_region(robot, (0.0, 0.0), None))
    >>> res["dy"].gap <= 1e-3
    True
    """
    robot = robot_arg(robot)
    if is_spatial(robot):   # a spatial robot: its own region (spatial_region) and quantities
        if exact or candidates is not None:
            raise ConfigError("a spatial robot's worst case is the first-order model's (no exact=, candidates=)",
                              key="exact" if exact else "candidates")
        kw = {k: v for k, v in (("gap", gap), ("max_boxes", max_boxes), ("min_size", min_size)) if v is not None}
        return spatial_global_worst(robot, clearances, region, grid=min(grid, 7), **kw)
    if candidates is not None:
        check_orientations(candidates, "candidates", poses=True)
    if gap is None:
        gap = DEFAULT_EXACT_GAP if exact else DEFAULT_GAP
    if max_boxes is None:
        max_boxes = 100_000 if exact else 2_000_000
    if not (gap > 0 and np.isfinite(gap)):
        raise ConfigError(f"must be > 0, got {gap}", key="gap")
    t0 = time.perf_counter()
    sources = as_sources(robot, clearances)
    if exact:
        refuse_first_order_only(sources, "the exact worst case")
        sets = error_set(robot, sources)
        # the first-order worst poses (to half the gap) seed the exact model's lower bounds: its maxima are
        # near them, and a good lower bound from the start closes most boxes in the first rounds
        seed = global_worst(robot, clearances, region, gap=gap / 2, max_condition=max_condition,
                            max_boxes=max_boxes, min_size=min_size, grid=grid, candidates=candidates)
        best = np.array([w.pose for w in seed.quantities.values()])
        seed_boxes = seed.boxes
        candidates = best if candidates is None else np.vstack([np.asarray(candidates, float).reshape(-1, 3), best])
    exact_sources = sources if exact else None
    L = robot.characteristic_length
    min_size = 1e-7 * L if min_size is None else float(min_size)
    scale = np.array([1.0, 1.0, L * PHI_SCALE])
    atol = ATOL * np.array([1.0, 1.0, 1.0 / L, 1.0])
    # Initial samples: lower bounds, a pose for the branches, the singularity check.
    nphi = 1 if region.phi[0] == region.phi[1] else grid
    gx, gy, gp = (np.linspace(*region.x, grid), np.linspace(*region.y, grid), np.linspace(*region.phi, nphi))
    samples = np.stack(np.meshgrid(gx, gy, gp, indexing="ij"), axis=-1).reshape(-1, 3)
    if region.shape is not None:   # the grid's points in the shape, and points on its boundary
        edge = region.shape.boundary(4 * grid)
        samples = np.vstack([samples[region.contains(samples[:, 0], samples[:, 1])],
                             np.column_stack([np.tile(edge, (nphi, 1)), np.repeat(gp, edge.shape[0])])])
    if candidates is not None:
        c = np.asarray(candidates, dtype=float)
        if c.ndim == 0 or c.shape[-1] != 3:
            raise PoseError(f"candidates must have shape (k, 3) = [x mm, y mm, phi rad], got shape {c.shape}")
        c = c.reshape(-1, 3)
        c = c[np.all(np.isfinite(c), axis=1)]   # (a grid without a pose inside gives NaN: no candidate)
        lo = np.array([region.x[0], region.y[0], region.phi[0]])
        hi = np.array([region.x[1], region.y[1], region.phi[1]])
        c = c[np.all((c >= lo) & (c <= hi), axis=1)]
        samples = np.vstack([samples, c[region.contains(c[:, 0], c[:, 1])]])
    values, inside = _exact(robot, clearances, samples, exact_sources)
    _check_regular(robot, samples[inside], region, max_condition)
    seen: set[float] = set()
    extra = _vertices(robot, region, gp, seen)
    ev, ei = _exact(robot, clearances, extra, exact_sources)
    samples, values, inside = np.vstack([samples, extra]), np.vstack([values, ev]), np.concatenate([inside, ei])
    lower = np.zeros(4)
    lower_pose = np.full((4, 3), np.nan)
    if np.any(np.isfinite(values)):
        k = np.argmax(np.where(np.isnan(values), -np.inf, values), axis=0)
        lower = np.where(np.isfinite(values[k, range(4)]), values[k, range(4)], 0.0)
        lower_pose = np.where(np.isfinite(values[k, range(4)])[:, None], samples[k], np.nan)
    if np.any(inside):
        sigmas = leg_branches(robot, samples[np.flatnonzero(inside)[0]])
    else:
        sigmas = leg_branches(robot, np.array([region.x[0], region.y[0], region.phi[0]]))
    boxes = np.array([[*region.x, *region.y, *region.phi]])
    active = np.ones((1, 4), dtype=bool)
    closed_upper = np.zeros(4)
    n_boxes = 0
    iterations = 0
    converged = np.ones(4, dtype=bool)
    while boxes.shape[0]:
        iterations += 1
        if region.shape is not None:   # boxes outside the shape are pruned; straddling ones stay (sound)
            keep = region.shape.classify(boxes[:, :4]) != OUTSIDE
            boxes, active = boxes[keep], active[keep]
            if not boxes.shape[0]:
                break
        n_boxes += boxes.shape[0]
        threshold = np.where(active, lower * (1 + gap) + atol, np.inf) / (1 + ROUNDING)
        rem, slack = box_remainder(robot, sets, boxes, sigmas) if exact else (0.0, None)
        upper, infeasible, det_zero, share = box_bounds(robot, sources, boxes, sigmas, threshold=threshold - rem)
        fo_upper = upper * (1 + ROUNDING)
        upper = (upper + rem) * (1 + ROUNDING)
        if exact:   # the second-order bound where the first-order part leaves room but its sum does not close
            limit = lower * (1 + gap) + atol
            slack4 = np.column_stack([slack, np.hypot(slack[:, 0], slack[:, 1])])
            room = (active & (upper > limit) & (fo_upper + TIGHT_SLACK * slack4 * (1 + ROUNDING) <= limit)
                    & ~infeasible[:, None])
            tight = np.flatnonzero(np.any(room, axis=1))
            if tight.size:
                _, total = box_remainder(robot, sets, boxes[tight], sigmas, tight=room[tight])
                upper[tight] = np.minimum(upper[tight], total * (1 + ROUNDING))
        keep = ~infeasible
        boxes, active, upper, det_zero, share = boxes[keep], active[keep], upper[keep], det_zero[keep], share[keep]
        if not boxes.shape[0]:
            break
        pts = 0.5 * (boxes[:, 0::2] + boxes[:, 1::2])   # centres, and the workspace's corners at the best phis
        if region.shape is not None:   # a centre outside the shape moves to the nearest point of the shape
            pts[:, :2] = region.shape.nearest(pts[:, 0], pts[:, 1])
        pts = np.vstack([pts, _vertices(robot, region, lower_pose[:, 2], seen)])
        vals, ins = _exact(robot, clearances, pts, exact_sources)
        if np.any(np.isfinite(vals)):
            k = np.nanargmax(np.where(np.isnan(vals), -np.inf, vals), axis=0)
            better = vals[k, range(4)] > lower
            # a new maximum at a pose the maps leave blank (condition above max_condition) is the singularity
            # coming into the region, as for the first samples: refused, never returned as a finite worst case
            _check_regular(robot, pts[k[better]], region, max_condition)
            lower = np.where(better, vals[k, range(4)], lower)
            lower_pose = np.where(better[:, None], pts[k], lower_pose)
        sizes = np.column_stack([boxes[:, 1] - boxes[:, 0], boxes[:, 3] - boxes[:, 2],
                                 boxes[:, 5] - boxes[:, 4]]) * scale
        small = np.max(sizes, axis=1) <= min_size
        if np.any(small & det_zero):
            b = boxes[np.argmax(small & det_zero)]
            raise SingularRegionError(
                f"{region.describe()} reaches a parallel singularity near x={b[0]:g} mm, y={b[2]:g} mm, "
                f"phi={np.degrees(b[4]):g} deg (det A may vanish there); the worst-case errors are unbounded: "
                "narrow --phi-deg or --region")
        done = active & ((upper <= lower * (1 + gap) + atol) | small[:, None])
        closed_upper = np.maximum(closed_upper, np.max(np.where(done, upper, 0.0), axis=0))
        active = active & ~done
        alive = np.any(active, axis=1)
        boxes, active, sizes, share = boxes[alive], active[alive], sizes[alive], share[alive]
        if not boxes.shape[0]:
            break
        if n_boxes + (4 if 4 * boxes.shape[0] <= SMALL_BATCH else 2) * boxes.shape[0] > max_boxes:
            upper = upper[alive]
            closed_upper = np.maximum(closed_upper, np.max(np.where(active, upper, 0.0), axis=0))
            converged = ~np.any(active, axis=0)
            break
        # bisect each box along the side responsible for most of its open bounds (mean-value form), else
        # along its widest (scaled) side; while few boxes are open, each half is bisected again (along the side
        # that is then the largest) in the same round: fewer rounds of small batches
        smear = np.max(np.where(active[:, :, None], share, 0.0), axis=1)
        known = np.all(np.isfinite(smear), axis=1) & np.any(smear > 0, axis=1)
        weight = np.where(known[:, None], np.where(np.isfinite(smear), smear, 0.0), sizes)
        rounds = 2 if 4 * boxes.shape[0] <= SMALL_BATCH else 1
        for _ in range(rounds):
            axis = np.argmax(weight, axis=1)
            lo_idx, hi_idx = 2 * axis, 2 * axis + 1
            rows = np.arange(boxes.shape[0])
            mid = 0.5 * (boxes[rows, lo_idx] + boxes[rows, hi_idx])
            left, right = boxes.copy(), boxes.copy()
            left[rows, hi_idx] = mid
            right[rows, lo_idx] = mid
            weight = weight.copy()
            weight[rows, axis] *= 0.5   # the split side's share (or width) halves
            boxes = np.concatenate([left, right])
            active = np.concatenate([active, active])
            weight = np.concatenate([weight, weight])
    if not np.any(np.isfinite(lower_pose)):
        raise EmptyWorkspaceError(f"{region.describe()}: no pose of the region is in the workspace")
    out = {}
    for i, q in enumerate(QUANTITIES):
        lo, up = float(lower[i]), float(max(closed_upper[i], lower[i]))
        g = (up - lo) / lo if lo > 0 else (0.0 if up == 0 else np.inf)
        within = up <= lo * (1 + gap) + atol[i]
        out[q] = QuantityWorst(name=q, lower=lo, upper=up, pose=lower_pose[i].copy(), gap=g,
                               converged=bool(converged[i] and within))
    if exact:   # the seeding first-order run's boxes count too
        n_boxes += seed_boxes
    return GlobalWorst(quantities=out, boxes=n_boxes, iterations=iterations, seconds=time.perf_counter() - t0,
                       target_gap=gap, region=region, exact=exact)


def grid_best(robot: Manipulator, clearances, region: Region, n: int = 101, n_phi: int = 7
              ) -> tuple[np.ndarray, np.ndarray]:
    """The best values on a grid of the region, for comparison with the certificate.

    At ``n_phi`` orientations evenly spaced over the interval (1 if it is a
    point), an ``n x n`` grid over the region's box cut to the workspace's
    bounds at that orientation; poses outside the workspace or the region's shape are skipped. Returns
    the maxima ``(4,)`` (``dx, dy, dphi, dp``; mm, rad) and their poses ``(4, 3)``
    (NaN when no grid pose is in the workspace).
    """

    phis = np.linspace(*region.phi, 1 if region.phi[0] == region.phi[1] else n_phi)
    best = np.full(4, -np.inf)
    poses = np.full((4, 3), np.nan)
    for phi in phis:
        ws = constant_orientation_workspace(robot, float(phi))
        if ws.is_empty:
            continue
        (wx0, wx1), (wy0, wy1) = ws.bounds
        x0, x1 = max(region.x[0], wx0), min(region.x[1], wx1)
        y0, y1 = max(region.y[0], wy0), min(region.y[1], wy1)
        if x0 > x1 or y0 > y1:
            continue
        X, Y = np.meshgrid(np.linspace(x0, x1, n), np.linspace(y0, y1, n), indexing="ij")
        pts = np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, phi)])
        pts = pts[region.contains(pts[:, 0], pts[:, 1])]
        vals, _ = _exact(robot, clearances, pts)
        if not pts.shape[0]:
            continue
        vals = np.where(np.isnan(vals), -np.inf, vals)
        k = np.argmax(vals, axis=0)
        better = vals[k, range(4)] > best
        best = np.where(better, vals[k, range(4)], best)
        poses = np.where(better[:, None], pts[k], poses)
    return np.where(np.isfinite(best), best, np.nan), poses


@dataclass(frozen=True)
class LargestDisc:
    """Result of :func:`largest_disc`: the targets (mm; rad for ``dphi``) hold, certified, over the disc of
    radius ``radius_lower`` (mm) around ``centre`` (mm) at every ``phi`` of the interval (rad); over the disc
    of radius ``radius_upper`` some target certifiably fails (or the disc reaches a parallel singularity,
    ``singular_above``); ``radius_upper`` is ``inf`` when the targets hold over the whole reachable part.
    ``holds`` is the certified worst case over the ``radius_lower`` disc (None when it is 0), ``fails`` the
    one over the ``radius_upper`` disc (None when singular or infinite)."""

    centre: tuple[float, float]
    phi: tuple[float, float]
    targets: dict[str, float]
    radius_lower: float
    radius_upper: float
    evaluations: int
    singular_above: bool = False
    holds: GlobalWorst | None = field(default=None, repr=False)
    fails: GlobalWorst | None = field(default=None, repr=False)


def largest_disc(robot: Manipulator, clearances, centre: tuple[float, float], phi: tuple[float, float],
                 targets: dict[str, float], *, tol: float = 0.1, gap: float = DEFAULT_GAP, **kwargs) -> LargestDisc:
    """The largest disc around ``centre`` (mm) on which every target holds, by bisection on the radius.

    For a radius ``r`` the region is the disc ``D(centre, r)`` times ``phi (lo, hi)`` rad, intersected with
    the workspace (as every region); :func:`global_worst` certifies ``L_q <= max_D q <= U_q``. The targets
    hold for ``r`` when ``U_q <= target_q`` for every targeted ``q``, and fail when ``L_q > target_q`` for one
    (``L_q`` is attained at a pose of the disc); ``max_D q`` grows with ``r``, so bisection keeps
    ``radius_lower`` (holds) and ``radius_upper`` (fails) until they are within ``tol`` mm. Radii the
    certificate cannot decide (a target within ``gap`` of the worst case) are skipped: each decided end is
    then brought within ``tol / 2`` of them, so the interval is at most ``tol`` wider than that undecided
    band (about ``gap * target / slope`` mm). ``targets``: ``{"dx"|"dy"|"dphi"|"dp": value}``
    in mm / rad (:func:`pmaccuracy.accuracy.synthesis.parse_targets`). Other keyword arguments go to
    :func:`global_worst`.

    Raises :class:`ConfigError` when the centre is outside the workspace at ``phi`` or ``tol <= 0``.

    >>> robot = Manipulator.preset("aalborg_3ppr")
    >>> res = largest_disc(robot, "case1", (0.0, 0.0), (0.0, 0.0), {"dp": 0.2}, tol=1.0)
    >>> res.radius_upper - res.radius_lower <= 1.0
    True
    """
    check_orientations(phi, "phi")
    robot = robot_arg(robot)
    if not (tol > 0 and np.isfinite(tol)):
        raise ConfigError(f"must be > 0 mm, got {tol}", key="tol")
    unknown = set(targets) - set(QUANTITIES)
    if unknown or not targets:
        raise ConfigError(f"targets must be some of {', '.join(QUANTITIES)}, got {sorted(targets)}", key="--target")
    cx, cy = (float(v) for v in centre)
    box = make_region(robot, phi, None)   # checks phi; the reach box bounds every disc that matters
    ends = np.array([[cx, cy, box.phi[0]], [cx, cy, box.phi[1]]])
    if not (np.all(np.isfinite([cx, cy])) and np.all(inverse_kinematics(robot, ends).within_limits)):
        raise ConfigError(f"the centre ({cx:g}, {cy:g}) mm is outside the workspace at phi = "
                          f"{np.degrees(box.phi[0]):g} or {np.degrees(box.phi[1]):g} deg", key="--largest-disc")
    far = float(max(np.hypot(x - cx, y - cy) for x in box.x for y in box.y))
    idx = [QUANTITIES.index(q) for q in targets]
    count = 0

    def evaluate(r):
        nonlocal count
        count += 1
        try:
            res = global_worst(robot, clearances, make_region(robot, box.phi, Disc((cx, cy), r)), gap=gap, **kwargs)
        except SingularRegionError:
            return "fails", None
        up = [res.quantities[QUANTITIES[i]].upper for i in idx]
        lo = [res.quantities[QUANTITIES[i]].lower for i in idx]
        t = [targets[QUANTITIES[i]] for i in idx]
        if all(u <= v for u, v in zip(up, t)):
            return "holds", res
        if any(lv > v for lv, v in zip(lo, t)):
            return "fails", res
        return "unknown", res

    state, res = evaluate(far)
    if state == "holds":
        return LargestDisc((cx, cy), box.phi, dict(targets), far, np.inf, count, holds=res)
    r_lo, r_hi, held, failed, singular = 0.0, far, None, res, res is None
    u_lo, u_hi = (far, far) if state == "unknown" else (np.nan, np.nan)   # radii the certificate left open
    if state == "unknown":
        failed = None
        r_hi = np.inf
    while True:
        if np.isnan(u_lo):
            if r_hi - r_lo <= tol:
                break
            mid = 0.5 * (r_lo + r_hi)
        else:   # shrink the two decided ends towards the undecided radii
            below, above = u_lo - r_lo, (r_hi - u_hi) if np.isfinite(r_hi) else 0.0
            if max(below, above) <= 0.5 * tol:
                break
            mid = 0.5 * (r_lo + u_lo) if below >= above else 0.5 * (u_hi + r_hi)
        state, res = evaluate(mid)
        if state == "holds":
            r_lo, held = mid, res
        elif state == "fails":
            r_hi, failed, singular = mid, res, res is None
        else:
            u_lo, u_hi = np.nanmin([u_lo, mid]), np.nanmax([u_hi, mid])
    return LargestDisc((cx, cy), box.phi, dict(targets), r_lo, float(r_hi), count, singular_above=singular,
                       holds=held, fails=failed)
