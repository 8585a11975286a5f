"""Constant-orientation workspace of any planar 3-leg manipulator, exact (paper Sec. 3, Fig. 3).

At a fixed orientation ``phi`` each joint limit ``q_k = lo`` or ``hi`` locks
one joint of a leg; the two joints left make a dyad, whose platform point
runs on a **circle** (two passive revolutes) or a **line** (a revolute and a
slide) in ``(x, y)`` (:meth:`pmaccuracy.model.chain.Chain.locked`). Where a leg's
two inverse-kinematics branches merge (``B_ii = 0``) the working mode's
branch ends, again on circles or lines (:meth:`pmaccuracy.model.chain.Chain.boundary_curves`).
The workspace is therefore a region bounded by circular arcs and segments:

1. split every candidate curve at its intersections with all the others;
2. test a point just to the left and just to the right of each piece's
   midpoint with the inverse kinematics (every joint in range, on the
   working mode): a piece with the workspace on exactly one side is boundary,
   oriented with the workspace on its left;
3. the area is Green's theorem over the oriented pieces,
   ``A = 1/2 sum (x dy - y dx)``, in closed form for segments
   (``1/2 a x b``) and arcs (``1/2 [R^2 dt + R (c_x (sin t1 - sin t0) - c_y (cos t1 - cos t0))]``),
   exact to rounding; pieces chained end to start give the boundary loops.

For the 3-PPR every curve is a line and the region is the paper's convex
polygon (the 12 half-planes of Eq. 2a/2b). The paper's "searching method"
(IK on a grid) is :func:`grid_search_workspace`, the cross-check.

Lengths in mm, angles in rad (figures and the CLI use degrees).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._savefig import DEFAULT_DPI, min_font_pt, save_figure
from ..errors import EmptyWorkspaceError, GeometryError, PoseError
from ..model.manipulator import Manipulator
from ..model.plausibility import check_orientations
from . import LIMIT_TOLERANCE, inverse_kinematics, resolve_robot
from ..model.legs import Curve

#: Orientations of the paper's Fig. 3 (deg).
DEFAULT_PHIS_DEG = (0.0, 30.0, -30.0)
#: A workspace whose area is below this (mm^2) is treated as empty (a segment or a point).
MIN_AREA = 1e-9


@dataclass(frozen=True)
class Piece:
    """An oriented piece of the workspace boundary (workspace on its left), mm.

    ``kind`` is ``"segment"`` (from ``start`` to ``end``) or ``"arc"`` (centre
    ``centre``, radius ``radius``, from angle ``t0`` through the signed sweep
    ``sweep`` rad: positive counter-clockwise). ``label`` names the joint limit.
    """

    kind: str
    start: complex
    end: complex
    centre: complex = 0j
    radius: float = 0.0
    t0: float = 0.0
    sweep: float = 0.0
    label: str = ""
    curve: int = -1

    def green(self) -> float:
        """``1/2 integral (x dy - y dx)`` along the piece (mm^2)."""
        if self.kind == "segment":
            return 0.5 * float(np.imag(np.conj(self.start) * self.end))
        t0, t1 = self.t0, self.t0 + self.sweep
        c, R = self.centre, self.radius
        return 0.5 * (R * R * self.sweep + R * (c.real * (np.sin(t1) - np.sin(t0))
                                                - c.imag * (np.cos(t1) - np.cos(t0))))

    def sample(self, step: float = 0.5) -> np.ndarray:
        """Points along the piece ``(K, 2)`` mm (arcs at most ``step`` mm apart, at least 8 per arc)."""
        if self.kind == "segment":
            z = np.array([self.start, self.end])
        else:
            n = max(8, int(np.ceil(abs(self.sweep) * self.radius / step)) + 1)
            t = self.t0 + np.linspace(0.0, self.sweep, min(n, 2000))
            z = self.centre + self.radius * np.exp(1j * t)
        return np.column_stack([z.real, z.imag])

    def extremes(self) -> np.ndarray:
        """End points and, for arcs, the axis-extreme points within the sweep: ``(K,)`` complex."""
        pts = [self.start, self.end]
        if self.kind == "arc":
            lo, hi = sorted((self.t0, self.t0 + self.sweep))
            for k in range(int(np.floor(lo / (np.pi / 2))), int(np.ceil(hi / (np.pi / 2))) + 1):
                t = k * np.pi / 2
                if lo <= t <= hi:
                    pts.append(self.centre + self.radius * np.exp(1j * t))
        return np.array(pts)


@dataclass(frozen=True, eq=False)
class Workspace:
    """The constant-orientation workspace of ``robot`` at ``phi``: a region bounded by segments and arcs.

    Attributes
    ----------
    robot : the manipulator (its inverse kinematics decides :meth:`contains`)
    phi : float, rad
    pieces : the oriented boundary pieces (:class:`Piece`, workspace on the left)
    loops : list of ``(K, 2)`` mm closed boundary polylines (arcs sampled), outer loops
        counter-clockwise, holes clockwise
    vertices : ``(M, 2)`` mm, the corners of the boundary in loop order (where one curve meets
        another); for a 3-PPR the polygon's vertices, counter-clockwise; ``(0, 2)`` when empty
    area : float, mm^2 (0.0 when empty), exact (Green's theorem)
    bounds : ``((xmin, xmax), (ymin, ymax))`` mm; NaN when empty
    """

    robot: Manipulator = field(repr=False)
    phi: float
    pieces: tuple[Piece, ...] = field(repr=False)
    loops: tuple[np.ndarray, ...] = field(repr=False)
    vertices: np.ndarray
    area: float
    bounds: tuple[tuple[float, float], tuple[float, float]]

    @property
    def is_empty(self) -> bool:
        """True when no position (or only a zero-area set of them) is reachable at ``phi``."""
        return self.area <= MIN_AREA

    def require_nonempty(self) -> "Workspace":
        """Return self, or raise :class:`EmptyWorkspaceError` if the workspace is empty."""
        if self.is_empty:
            raise EmptyWorkspaceError(
                f"the constant-orientation workspace at phi = {np.degrees(self.phi):g} deg is empty: "
                "no position satisfies every joint limit on the legs' working modes")
        return self

    @property
    def centroid(self) -> np.ndarray:
        """Area centroid ``(2,)`` mm (NaN when empty), from the sampled boundary loops."""
        if self.is_empty:
            return np.full(2, np.nan)
        m = np.zeros(2)
        a_tot = 0.0
        for loop in self.loops:
            x, y = loop[:-1, 0], loop[:-1, 1]
            xn, yn = loop[1:, 0], loop[1:, 1]
            cross = x * yn - xn * y
            a_tot += cross.sum() / 2
            m += np.array([np.sum((x + xn) * cross), np.sum((y + yn) * cross)]) / 6
        return m / a_tot

    @property
    def interior_point(self) -> np.ndarray:
        """A point inside the workspace ``(2,)`` mm: the centroid if inside, else the inside grid point
        farthest from the boundary samples; NaN when empty."""
        if self.is_empty:
            return np.full(2, np.nan)
        c = self.centroid
        if self.contains(c):
            return c
        x, y, inside = self.grid(61)
        X, Y = np.meshgrid(x, y)
        pts = np.column_stack([X[inside], Y[inside]])
        boundary = np.vstack(self.loops)
        d = np.min(np.hypot(pts[:, None, 0] - boundary[None, :, 0], pts[:, None, 1] - boundary[None, :, 1]), axis=1)
        return pts[int(np.argmax(d))]

    def contains(self, points: np.ndarray, tol: float = LIMIT_TOLERANCE) -> np.ndarray:
        """True for positions ``(..., 2)`` mm inside the workspace; result shape ``(...)``.

        The same test as the inverse kinematics: every leg reaches the pose on
        its working mode and every joint is within its range up to ``tol`` (mm
        or rad), so a pose computed on the boundary counts as inside.
        """
        points = np.asarray(points, dtype=float)
        if points.ndim == 0 or points.shape[-1] != 2:
            raise ValueError(f"points must have shape (..., 2), got {points.shape}")
        if self.is_empty:
            return np.zeros(points.shape[:-1], dtype=bool)
        return _inside(self.robot, self.phi, points, tol)

    def grid(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A regular ``n x n`` grid over the bounds: ``x (n,)``, ``y (n,)`` mm and ``inside (n, n)`` [y, x].

        ``inside[j, i]`` is :meth:`contains` of ``(x[i], y[j])``. Raises
        :class:`EmptyWorkspaceError` for an empty workspace.
        """
        n = int(n)
        if n < 2:
            raise ValueError(f"a grid needs n >= 2 points per axis, got {n}")
        self.require_nonempty()
        (xmin, xmax), (ymin, ymax) = self.bounds
        x = np.linspace(xmin, xmax, n)
        y = np.linspace(ymin, ymax, n)
        X, Y = np.meshgrid(x, y)  # (n, n) indexed [y, x]
        return x, y, self.contains(np.stack([X, Y], axis=-1))


def _inside(robot: Manipulator, phi: float, points: np.ndarray, tol: float) -> np.ndarray:
    poses = np.concatenate([points, np.full(points.shape[:-1] + (1,), float(phi))], axis=-1)
    return inverse_kinematics(robot, poses, tol).within_limits


# ---------------------------------------------------------------------------------------- arrangement
def _line_frame(c: Curve) -> tuple[complex, complex]:
    """A point and the unit direction of a line ``n . p + o = 0`` (direction ``E n``)."""
    return -c.offset * c.normal, 1j * c.normal


def _intersections(a: Curve, b: Curve) -> list[complex]:
    """Intersection points of two curves (circles and lines), complex mm."""
    if a.kind == "line" and b.kind == "line":
        det = a.normal.real * b.normal.imag - a.normal.imag * b.normal.real
        if abs(det) < 1e-12:
            return []
        x = (-a.offset * b.normal.imag + b.offset * a.normal.imag) / det
        y = (-a.normal.real * b.offset + b.normal.real * a.offset) / det
        return [complex(x, y)]
    if a.kind == "circle" and b.kind == "line":
        a, b = b, a
    if a.kind == "line":
        p0, d = _line_frame(a)
        w = p0 - b.centre
        bq = 2 * (d.conjugate() * w).real
        cq = abs(w) ** 2 - b.radius ** 2
        disc = bq * bq - 4 * cq
        # a tangency (e.g. a leg's limit circle touching its own branch line) computed a hair apart is kept
        if disc < -1e-10 * (4 * b.radius ** 2 + bq * bq):
            return []
        r = np.sqrt(max(disc, 0.0))
        return [p0 + d * (-bq + r) / 2, p0 + d * (-bq - r) / 2]
    dz = b.centre - a.centre
    dist = abs(dz)
    tol = 1e-10 * (a.radius + b.radius)
    if dist < 1e-12 or dist > a.radius + b.radius + tol or dist < abs(a.radius - b.radius) - tol:
        return []
    along = (a.radius ** 2 - b.radius ** 2 + dist ** 2) / (2 * dist)
    h = np.sqrt(max(a.radius ** 2 - along ** 2, 0.0))
    u = dz / dist
    m = a.centre + along * u
    return [m + 1j * u * h, m - 1j * u * h]


def _dedupe(curves: list[Curve], scale: float) -> list[Curve]:
    out: list[Curve] = []
    tol = 1e-9 * scale
    for c in curves:
        same = False
        for o in out:
            if c.kind != o.kind:
                continue
            if c.kind == "circle":
                same = abs(c.centre - o.centre) < tol and abs(c.radius - o.radius) < tol
            else:
                same = (abs(c.normal - o.normal) < 1e-12 and abs(c.offset - o.offset) < tol) or \
                       (abs(c.normal + o.normal) < 1e-12 and abs(c.offset + o.offset) < tol)
            if same:
                break
        if not same:
            out.append(c)
    return out


def boundary_curves(robot: Manipulator, phi: float) -> list[Curve]:
    """Every circle and line that can bound the workspace at ``phi`` (rad), labelled ``leg i: ...``."""
    curves = []
    for i, chain in enumerate(robot.chains, start=1):
        for c in chain.boundary_curves(phi):
            curves.append(Curve(c.kind, centre=c.centre, radius=c.radius, normal=c.normal, offset=c.offset,
                                label=f"leg {i}: {c.label}"))
    return curves


def constant_orientation_workspace(robot: Manipulator, phi: float, tol: float = LIMIT_TOLERANCE) -> Workspace:
    """The exact workspace of ``robot`` at orientation ``phi`` (rad), paper Sec. 3 (module docstring).

    Raises :class:`GeometryError` when the region is unbounded (passive slides
    without ranges); an empty workspace is returned as such (``is_empty``). An orientation beyond a full
    turn warns (:func:`pmaccuracy.model.plausibility.check_orientations`: degrees typed as radians).
    """
    check_orientations(phi, "phi")
    robot = resolve_robot(robot)  # a preset name or a TOML path too
    try:
        phi = float(phi)
    except (TypeError, ValueError):
        raise PoseError(f"phi must be a number (rad), got {phi!r}") from None
    if not np.isfinite(phi):
        raise PoseError(f"phi must be finite, got {phi}")
    scale = max(1.0, float(np.max(np.hypot(*robot.base_points.T))),
                float(np.max(np.hypot(*robot.platform_attachments.T))))
    curves = _dedupe(boundary_curves(robot, phi), scale)
    # a box that holds every bounded region: all intersection points and circle extremes
    pts = []
    for i in range(len(curves)):
        if curves[i].kind == "circle":
            c, r = curves[i].centre, curves[i].radius
            pts += [c + r, c - r, c + 1j * r, c - 1j * r]
        for j in range(i + 1, len(curves)):
            pts += _intersections(curves[i], curves[j])
    if not pts:
        return _empty(robot, phi)
    pts = np.array(pts)
    lo = complex(pts.real.min(), pts.imag.min())
    hi = complex(pts.real.max(), pts.imag.max())
    size = max(abs(hi - lo), 1e-3 * scale)
    margin = 0.05 * size + 1e-3 * scale
    lo -= complex(margin, margin)
    hi += complex(margin, margin)
    box = [Curve("line", normal=1 + 0j, offset=-hi.real, label="box"),
           Curve("line", normal=-1 + 0j, offset=lo.real, label="box"),
           Curve("line", normal=1j, offset=-hi.imag, label="box"),
           Curve("line", normal=-1j, offset=lo.imag, label="box")]
    everything = curves + box
    raw = _split(everything, lo, hi)
    if not raw:
        return _empty(robot, phi)
    mids = np.array([p[0] for p in raw])
    normals = np.array([p[1] for p in raw])
    # probe each side closer than any other curve, so that a sliver thinner than the probe is never jumped
    delta = np.minimum(1e-7 * max(size, 1.0), 0.25 * _clearance(mids, np.array([p[2].curve for p in raw]),
                                                                   everything))
    probe = np.concatenate([mids + delta * normals, mids - delta * normals])
    inside = _inside(robot, phi, np.column_stack([probe.real, probe.imag]), 0.0)
    left, right = inside[:len(raw)], inside[len(raw):]
    pieces = []
    for (mid, normal, piece), l_in, r_in in zip(raw, left, right):
        if l_in == r_in:
            continue
        if everything[piece.curve].label == "box":
            raise GeometryError(f"the workspace at phi = {np.degrees(phi):g} deg is unbounded: give the passive "
                                "prismatic joints ranges", source=robot.name, key="legs")
        pieces.append(piece if l_in else _reverse(piece))
    if not pieces:
        return _empty(robot, phi)
    area = float(sum(p.green() for p in pieces))
    if area <= MIN_AREA:
        return _empty(robot, phi)
    ext = np.concatenate([p.extremes() for p in pieces])
    bounds = ((float(ext.real.min()), float(ext.real.max())), (float(ext.imag.min()), float(ext.imag.max())))
    loops, vertices = _loops(pieces, 1e-6 * max(size, 1.0))
    return Workspace(robot=robot, phi=phi, pieces=tuple(pieces), loops=tuple(loops), vertices=vertices,
                     area=area, bounds=bounds)


def _clearance(points: np.ndarray, own: np.ndarray, curves: list[Curve]) -> np.ndarray:
    """Distance from each point ``(n,)`` complex to the nearest curve other than its own (mm)."""
    out = np.full(points.shape, np.inf)
    for j, c in enumerate(curves):
        if c.kind == "line":
            d = np.abs(c.normal.real * points.real + c.normal.imag * points.imag + c.offset)
        else:
            d = np.abs(np.abs(points - c.centre) - c.radius)
        out = np.where(own == j, out, np.minimum(out, d))
    return out


def _empty(robot: Manipulator, phi: float) -> Workspace:
    nan = float("nan")
    return Workspace(robot=robot, phi=phi, pieces=(), loops=(), vertices=np.zeros((0, 2)), area=0.0,
                     bounds=((nan, nan), (nan, nan)))


def _split(curves: list[Curve], lo: complex, hi: complex) -> list[tuple[complex, complex, Piece]]:
    """Cut every curve at its intersections (lines clipped to the box): ``(midpoint, left normal, piece)``."""
    out = []
    for i, c in enumerate(curves):
        cuts = []
        for j, o in enumerate(curves):
            if j != i:
                cuts += _intersections(c, o)
        if c.kind == "line":
            p0, d = _line_frame(c)
            ts = sorted({round(float((d.conjugate() * (z - p0)).real), 12) for z in cuts})
            tmin, tmax = _clip(p0, d, lo, hi)
            if tmin is None:
                continue
            ts = [tmin] + [t for t in ts if tmin < t < tmax] + [tmax]
            for t0, t1 in zip(ts[:-1], ts[1:]):
                if t1 - t0 <= 1e-12 * max(1.0, abs(t1)):
                    continue
                a, b = p0 + t0 * d, p0 + t1 * d
                out.append(((a + b) / 2, 1j * d, Piece("segment", a, b, label=c.label, curve=i)))
        else:
            angles = sorted({float(np.mod(np.angle(z - c.centre), 2 * np.pi)) for z in cuts})
            if not angles:
                angles = [0.0]
            angles = angles + [angles[0] + 2 * np.pi]
            for t0, t1 in zip(angles[:-1], angles[1:]):
                if t1 - t0 <= 1e-12:
                    continue
                tm = (t0 + t1) / 2
                mid = c.centre + c.radius * np.exp(1j * tm)
                a = c.centre + c.radius * np.exp(1j * t0)
                b = c.centre + c.radius * np.exp(1j * t1)
                # counter-clockwise travel: the inside of the circle is on the left
                out.append((mid, -np.exp(1j * tm), Piece("arc", a, b, centre=c.centre, radius=c.radius, t0=t0,
                                                         sweep=t1 - t0, label=c.label, curve=i)))
    return out


def _clip(p0: complex, d: complex, lo: complex, hi: complex) -> tuple[float | None, float | None]:
    """Parameter interval of the line ``p0 + t d`` inside the box ``[lo, hi]``."""
    tmin, tmax = -np.inf, np.inf
    for p, dd, a, b in ((p0.real, d.real, lo.real, hi.real), (p0.imag, d.imag, lo.imag, hi.imag)):
        if abs(dd) < 1e-15:
            if not a <= p <= b:
                return None, None
            continue
        t1, t2 = (a - p) / dd, (b - p) / dd
        tmin, tmax = max(tmin, min(t1, t2)), min(tmax, max(t1, t2))
    if tmin >= tmax:
        return None, None
    return float(tmin), float(tmax)


def _reverse(p: Piece) -> Piece:
    if p.kind == "segment":
        return Piece("segment", p.end, p.start, label=p.label, curve=p.curve)
    return Piece("arc", p.end, p.start, centre=p.centre, radius=p.radius, t0=p.t0 + p.sweep, sweep=-p.sweep,
                 label=p.label, curve=p.curve)


def _loops(pieces: list[Piece], tol: float) -> tuple[list[np.ndarray], np.ndarray]:
    """Chain the oriented pieces end to start into closed loops; corners where the curve changes."""
    remaining = list(pieces)
    loops, corners = [], []
    while remaining:
        chain = [remaining.pop(0)]
        while True:
            end = chain[-1].end
            if not remaining or abs(chain[0].start - end) <= min(abs(p.start - end) for p in remaining):
                break  # closed (the loop's own start is the nearest)
            k = int(np.argmin([abs(p.start - end) for p in remaining]))
            if abs(remaining[k].start - end) > tol:
                break
            chain.append(remaining.pop(k))
        pts = np.vstack([p.sample()[:-1] for p in chain] + [chain[0].sample()[:1]])
        loops.append(pts)
        for a, b in zip(chain, chain[1:] + chain[:1]):
            if a.curve != b.curve:
                corners.append([b.start.real, b.start.imag])
    # the largest loop first
    order = sorted(range(len(loops)), key=lambda i: -abs(_shoelace(loops[i])))
    loops = [loops[i] for i in order]
    return loops, np.array(corners) if corners else np.zeros((0, 2))


def _shoelace(loop: np.ndarray) -> float:
    x, y = loop[:, 0], loop[:, 1]
    return 0.5 * float(np.sum(x[:-1] * y[1:] - x[1:] * y[:-1]))


@dataclass(frozen=True, eq=False)
class GridWorkspace:
    """Result of the paper's "searching method": IK on a regular grid at constant phi.

    Attributes
    ----------
    phi : float, rad
    x, y : ``(n,)`` mm, grid coordinates
    inside : bool ``(n, n)`` indexed [y, x]: every joint within its limits
    area : float, mm^2, ``count(inside) * dx * dy`` (a first-order estimate: its error is about the
        boundary length times half a grid step)
    """

    phi: float
    x: np.ndarray
    y: np.ndarray
    inside: np.ndarray
    area: float


def leg_box(robot: Manipulator, phi: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """A box ``((xmin, xmax), (ymin, ymax))`` (mm) around the workspace at ``phi``: its bounds plus 5 %.

    Falls back to the extent of the legs' boundary curves when the workspace is empty.
    """
    ws = constant_orientation_workspace(robot, phi)
    if ws.is_empty:
        pts = [p for c in boundary_curves(robot, phi) if c.kind == "circle"
               for p in (c.centre + c.radius, c.centre - c.radius, c.centre + 1j * c.radius,
                         c.centre - 1j * c.radius)]
        pts = np.array(pts) if pts else np.array([0j])
        return (float(pts.real.min()), float(pts.real.max())), (float(pts.imag.min()), float(pts.imag.max()))
    (x0, x1), (y0, y1) = ws.bounds
    mx, my = 0.05 * (x1 - x0) + 1e-6, 0.05 * (y1 - y0) + 1e-6
    return (x0 - mx, x1 + mx), (y0 - my, y1 + my)


def grid_search_workspace(robot: Manipulator, phi: float, n: int,
                          box: tuple[tuple[float, float], tuple[float, float]] | None = None,
                          tol: float = LIMIT_TOLERANCE) -> GridWorkspace:
    """The paper's searching method: inverse kinematics on an ``n x n`` grid at constant ``phi``.

    ``box = ((xmin, xmax), (ymin, ymax))`` mm defaults to :func:`leg_box`.
    A grid point is inside when :func:`~pmaccuracy.kinematics.inverse_kinematics`
    finds every joint within its limits (tolerance ``tol``).
    """
    n = int(n)
    if n < 2:
        raise ValueError(f"a grid needs n >= 2 points per axis, got {n}")
    (xmin, xmax), (ymin, ymax) = leg_box(robot, phi) if box is None else box
    x = np.linspace(xmin, xmax, n)
    y = np.linspace(ymin, ymax, n)
    X, Y = np.meshgrid(x, y)
    poses = np.stack([X, Y, np.full_like(X, float(phi))], axis=-1)
    inside = inverse_kinematics(robot, poses, tol).within_limits
    area = float(np.count_nonzero(inside) * (x[1] - x[0]) * (y[1] - y[0]))
    return GridWorkspace(phi=float(phi), x=x, y=y, inside=inside, area=area)


# ---------------------------------------------------------------------------------------- figures
_COLORS = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown"]


def home_pose(robot: Manipulator) -> np.ndarray:
    """A representative pose ``(3,)`` [mm, mm, rad] for drawing: an interior point of the phi = 0 workspace.

    Falls back to the origin when that workspace is empty.
    """
    ws = constant_orientation_workspace(robot, 0.0)
    if ws.is_empty:
        return np.zeros(3)
    return np.array([*ws.interior_point, 0.0])


def draw_robot(robot: Manipulator, pose: np.ndarray, ax, *, label: bool = True,
               leg_colors: tuple[str, str, str] | None = None) -> None:
    """Draw the legs (joints and links), the base frames and the platform assembled at ``pose`` (mm, rad).

    Revolute joints are circles, prismatic joints squares at the middle of their
    slide; the actuated joint of each leg is filled red and an actuated slide's
    range is drawn as a grey rail. With ``label`` each leg's number is written beside its base and the
    legend gets one entry per symbol drawn, in the symbol's own shape (a 3-PRR's actuated joint a red
    square, a 3-RRR's a red circle). Coordinates in mm. ``leg_colors`` (one matplotlib colour per leg,
    default dark grey) colours the legs' links and joint outlines (e.g. light grey for unloaded legs).
    """
    from matplotlib.patches import Polygon

    ik = inverse_kinematics(robot, pose)
    pts_platform = robot.platform_points(pose)
    bases = np.array([c.base for c in robot.chains])
    robot_span = float(np.hypot(*np.ptp(np.vstack([bases, pts_platform]), axis=0))) or 1.0
    for i, chain in enumerate(robot.chains):
        q = ik.joints[i]
        if not np.all(np.isfinite(q)):
            continue
        centres, dirs, _, end = chain.frames(q)
        # the leg as drawn: each joint's centre, a slide's moving end (centre + q e), then the link to the next
        origins = [complex(*chain.base)]
        for k, joint in enumerate(chain.joints):
            if joint.kind == "P":
                origins.append(centres[k] + q[k] * dirs[k])
            origins.append(centres[k + 1] if k < 2 else end)
        path = np.array(origins)
        colour = "0.25" if leg_colors is None else leg_colors[i]
        ax.plot(path.real, path.imag, color=colour, linewidth=1.6, zorder=3,
                label="legs" if (label and i == 0) else None)
        a = chain.actuated_index
        if chain.actuated.kind == "P" and a == 0:  # a guide fixed on the base
            lo, hi = chain.actuated.range
            e = dirs[a]
            rail = np.array([centres[a] + lo * e, centres[a] + hi * e])
            ax.plot(rail.real, rail.imag, color="0.55", linewidth=5, alpha=0.6, solid_capstyle="butt", zorder=1,
                    label="actuated rails (range)" if (label and i == 0) else None)
        for k, joint in enumerate(chain.joints):
            actuated = k == a
            face = "tab:red" if actuated else "white"
            if joint.kind == "R":
                ax.plot(centres[k].real, centres[k].imag, "o", markersize=6, markerfacecolor=face,
                        markeredgecolor="k" if leg_colors is None else colour, zorder=5)
            else:
                # the block: a bushing at the slide's origin; a carriage at the end of the slide when a link
                # follows it, else half-way along it (the next joint's marker sits at its end)
                mid = centres[k] if joint.block_kind == "bushing" else \
                    centres[k] + q[k] * dirs[k] * (1.0 if joint.link != (0.0, 0.0) else 0.5)
                ax.plot(mid.real, mid.imag, "s", markersize=6, markerfacecolor=face,
                        markeredgecolor="k" if leg_colors is None else colour, zorder=5)
        ax.plot(chain.base[0], chain.base[1], "k^", markersize=7, zorder=4,
                label="leg base frames" if (label and i == 0) else None)
        if label:                                  # the leg's number beside its base, away from the robot
            away = complex(*chain.base) - complex(pose[0], pose[1])
            at = complex(*chain.base) + 0.07 * robot_span * away / max(abs(away), 1e-9)
            ax.text(at.real, at.imag, str(i + 1), ha="center", va="center", fontsize="large", fontweight="bold",
                    color=colour, zorder=6, gid=f"leg {i + 1}")
            ax.update_datalim([(at.real, at.imag)])     # the number inside the frame
    tri = pts_platform
    ax.add_patch(Polygon(tri, closed=True, facecolor="0.6", alpha=0.5, edgecolor="k", zorder=4,
                         label=f"platform ($\\phi$ = {np.degrees(pose[2]):g} deg)" if label else None))
    ax.plot(pose[0], pose[1], "k+", markersize=8, zorder=6, label="platform centre P (the pose)" if label else None)
    if label:                                      # one legend entry per joint symbol drawn, in its shape
        kinds = {(j.kind, k == c.actuated_index) for c in robot.chains for k, j in enumerate(c.joints)}
        names = {"R": ("o", "revolute joint"), "P": ("s", "prismatic joint")}
        for kind in ("R", "P"):
            for actuated in (True, False):
                if (kind, actuated) in kinds:
                    marker, name = names[kind]
                    ax.plot([], [], marker, markersize=6, markerfacecolor="tab:red" if actuated else "white",
                            markeredgecolor="k", label=f"{'actuated' if actuated else 'passive'} {name}")
        ax.plot([], [], linestyle="none", marker="$1$", markersize=7, color="k", label="leg number")


def fill_workspace(ws: Workspace, ax, color: str, label: str | None) -> None:
    """Fill a workspace (holes left open) and outline its boundary."""
    from matplotlib.patches import PathPatch
    from matplotlib.path import Path as MplPath

    if ws.is_empty:
        ax.plot([], [], color=color, label=f"{label}: empty" if label else None)
        return
    verts, codes = [], []
    for loop in ws.loops:
        verts.append(loop)
        codes += [MplPath.MOVETO] + [MplPath.LINETO] * (len(loop) - 2) + [MplPath.CLOSEPOLY]
    path = MplPath(np.vstack(verts), codes)
    ax.add_patch(PathPatch(path, facecolor=color, alpha=0.25, edgecolor=color, linewidth=1.5, zorder=2,
                           label=f"{label}, {ws.area:.0f} mm$^2$" if label else None))


def plot_workspaces(robot: Manipulator, phis: tuple[float, ...] | np.ndarray | None = None, ax=None,
                    pose: np.ndarray | None = None, zoom: bool = False):
    """Draw constant-orientation workspaces for several orientations (paper Fig. 3 analogue).

    Each workspace at ``phis`` (rad; default 0, 30 and -30 deg) is filled and
    outlined; the robot is drawn assembled at ``pose`` (default
    :func:`home_pose`) unless ``zoom``, which frames the workspaces alone.
    Without ``ax`` a new :class:`matplotlib.figure.Figure` is made (no pyplot
    state); returns the axes. Coordinates in mm.
    """
    from matplotlib.figure import Figure

    phis = np.radians(DEFAULT_PHIS_DEG) if phis is None else np.atleast_1d(np.asarray(phis, dtype=float))
    if ax is None:
        ax = Figure(figsize=(7.5, 7.0)).add_subplot()
    spaces = [constant_orientation_workspace(robot, phi) for phi in phis]
    for j, (phi, ws) in enumerate(zip(phis, spaces)):
        fill_workspace(ws, ax, _COLORS[j % len(_COLORS)], f"$\\phi$ = {np.degrees(phi):g} deg")
    if not zoom:
        draw_robot(robot, home_pose(robot) if pose is None else np.asarray(pose, float), ax)
    else:
        boxes = [ws.bounds for ws in spaces if not ws.is_empty]
        if boxes:
            x0 = min(b[0][0] for b in boxes)
            x1 = max(b[0][1] for b in boxes)
            y0 = min(b[1][0] for b in boxes)
            y1 = max(b[1][1] for b in boxes)
            m = 0.08 * max(x1 - x0, y1 - y0)
            ax.set_xlim(x0 - m, x1 + m)
            ax.set_ylim(y0 - m, y1 + m)
    ax.set_aspect("equal", adjustable="datalim" if not zoom else "box")
    ax.autoscale_view()
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.grid(True, alpha=0.3)
    return ax


def save_workspace_figure(robot: Manipulator, path: str | Path,
                          phis_deg: tuple[float, ...] = DEFAULT_PHIS_DEG, dpi: int = DEFAULT_DPI) -> Path:
    """Write :func:`workspace_figure` to ``path`` in the format its extension names (``.png`` at ``dpi``,
    ``.pdf``, ``.svg``, ...: :func:`pmaccuracy._savefig.save_figure`); returns the path."""
    fig = workspace_figure(robot, phis_deg)
    path = save_figure(fig, path, dpi=dpi)
    fig.clear()
    return path


def workspace_figure(robot: Manipulator, phis_deg: tuple[float, ...] = DEFAULT_PHIS_DEG, width: float = 7.5):
    """The workspaces at ``phis_deg`` (deg) as a :class:`matplotlib.figure.Figure` (with an Agg canvas).

    Top, large: the workspaces, zoomed to their union (8 % margin) at equal scales, their areas in the
    legend under the axes. Below: the whole robot assembled at :func:`home_pose` with the same workspaces,
    the zoomed region outlined (dashed) and its legs numbered, and beside it the legend of its symbols, each
    in the shape drawn. Nothing is drawn over the data. ``width`` inches wide (the report's width), text
    large enough to read at 400 px (:func:`pmaccuracy._savefig.min_font_pt`). Lengths in mm.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    font = math.ceil(2 * min_font_pt(width)) / 2
    fig = Figure(figsize=(width, 8.0))
    FigureCanvasAgg(fig)
    phis = np.radians(np.asarray(phis_deg, dtype=float))
    ax_zoom = fig.add_axes((0.15, 0.5, 0.8, 0.4))
    plot_workspaces(robot, phis, ax=ax_zoom, zoom=True)
    (x0, x1), (y0, y1) = ax_zoom.get_xlim(), ax_zoom.get_ylim()
    aspect = (y1 - y0) / max(x1 - x0, 1e-9)
    left, right = 1.0, 0.3
    w_in = width - left - right
    h_in = w_in * aspect
    if h_in > 5.0:
        h_in, w_in = 5.0, 5.0 / aspect
    n_ws = len(phis)
    ws_rows = math.ceil(n_ws / 2)
    side = min(3.2, width - left - 3.3)
    top, under_zoom = 0.5, 0.7 + 0.3 * ws_rows
    height = top + h_in + under_zoom + 0.45 + side + 0.7
    fig.set_size_inches(width, height)
    ax_zoom.set_position((left / width, (height - top - h_in) / height, w_in / width, h_in / height))
    ax_full = fig.add_axes((left / width, 0.7 / height, side / width, side / height))
    ax_zoom.set_title(f"{robot.name} ({robot.architecture}): constant-orientation workspaces", fontsize=font + 1)
    ax_zoom.legend(loc="upper center", bbox_to_anchor=(0.5, -0.62 / h_in), ncol=min(n_ws, 2), fontsize=font,
                   frameon=False)
    plot_workspaces(robot, phis, ax=ax_full)
    (x0, x1), (y0, y1) = ax_zoom.get_xlim(), ax_zoom.get_ylim()
    ax_full.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, linestyle="--", linewidth=1.0,
                                edgecolor="k", zorder=7, label="zoomed region (above)"))
    ax_full.set_title("whole robot at a pose inside", fontsize=font + 1)
    for ax in (ax_zoom, ax_full):
        ax.tick_params(labelsize=font)
        ax.xaxis.label.set_fontsize(font)
        ax.yaxis.label.set_fontsize(font)
    for t in ax_full.texts:
        t.set_fontsize(font + 1)
    handles, labels = ax_full.get_legend_handles_labels()
    keep = [k for k, text in enumerate(labels) if "mm$^2$" not in text and not text.endswith(": empty")]
    ax_full.legend([handles[k] for k in keep], [labels[k] for k in keep], loc="center left",
                   bbox_to_anchor=(1.0 + 0.25 / side, 0.5), ncol=1, fontsize=font, frameon=False)
    return fig


def save_comparison_figure(robots: list[Manipulator], path: str | Path,
                           phis_deg: tuple[float, ...] = DEFAULT_PHIS_DEG, dpi: int = DEFAULT_DPI) -> Path:
    """Write :func:`comparison_figure` to ``path`` in the format its extension names (``.png`` at ``dpi``,
    ``.pdf``, ``.svg``, ...: :func:`pmaccuracy._savefig.save_figure`); returns the path."""
    fig = comparison_figure(robots, phis_deg)
    path = save_figure(fig, path, dpi=dpi)
    fig.clear()
    return path


#: At most this many robots side by side in :func:`comparison_figure` (more go to further blocks of rows), so
#: the figure stays at most 7.0 in wide and its text readable at 400 px.
COMPARISON_COLUMNS = 2


def comparison_figure(robots: list[Manipulator], phis_deg: tuple[float, ...] = DEFAULT_PHIS_DEG):
    """One column per robot, at most :data:`COMPARISON_COLUMNS` side by side (a
    :class:`matplotlib.figure.Figure`, Agg canvas; lengths in mm).

    Robot row: the robot at its home pose with its workspaces, every panel spanning the same width and
    height (the largest robot's), so the robots' sizes compare at a glance. Under it, the workspaces
    alone, zoomed, again on one common scale (the largest workspace's span), so the workspaces' sizes
    compare too; their areas are in the legends under the panels. The symbols of every robot drawn (joints,
    rails, platform) share one legend above the panels. The layout is measured (legends, titles) in inches,
    with text at least 8 px high when the figure is shown 400 px wide.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    n = len(robots)
    cols = max(1, min(n, COMPARISON_COLUMNS))
    blocks = math.ceil(n / cols)
    width = 3.3 * cols + 0.4
    font = max(9.0, math.ceil(2 * min_font_pt(width)) / 2)
    line = 1.3 * font / 72.0                                  # one line of text (in)
    left, right, gap = 0.95, 0.3, 0.25
    side = (width - cols * left - right - (cols - 1) * gap) / cols
    fig = Figure(figsize=(width, 8.0))
    FigureCanvasAgg(fig)
    renderer = fig.canvas.get_renderer()
    phis = np.radians(np.asarray(phis_deg, dtype=float))
    tops, zooms, area_legends = [], [], []
    for b in range(blocks):
        chunk = robots[b * cols:(b + 1) * cols]
        row = [fig.add_axes((0, 0, 0.1, 0.1)) for _ in chunk]
        for ax, robot in zip(row, chunk):
            plot_workspaces(robot, phis, ax=ax)
            ax.set_title(f"{robot.name}\n{robot.architecture}", fontsize=font + 1)
            for t in ax.texts:
                t.set_fontsize(font + 1)
        zrow = [fig.add_axes((0, 0, 0.1, 0.1)) for _ in chunk]
        for zax, robot in zip(zrow, chunk):
            plot_workspaces(robot, phis, ax=zax, zoom=True)
            zax.set_title("workspaces (common scale)", fontsize=font + 1)
            area_legends.append(zax.legend(*zax.get_legend_handles_labels(), loc="upper center",
                                           bbox_transform=fig.transFigure, fontsize=font, frameon=False))
        tops += row
        zooms += zrow
    for row in (tops, zooms):                                # one span per row kind: sizes compare
        spans = [max(np.ptp(ax.get_xlim()), np.ptp(ax.get_ylim())) for ax in row]
        span = max(spans)
        for ax in row:
            cx, cy = np.mean(ax.get_xlim()), np.mean(ax.get_ylim())
            ax.set_xlim(cx - span / 2, cx + span / 2)
            ax.set_ylim(cy - span / 2, cy + span / 2)
            ax.set_aspect("equal", adjustable="box")
            ax.tick_params(labelsize=font)
            ax.xaxis.label.set_fontsize(font)
            ax.yaxis.label.set_fontsize(font)
    handles, labels = {}, []                                 # every robot's symbols, once each
    for ax in tops:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if "mm$^2$" not in lab and not lab.endswith(": empty") and lab not in handles:
                handles[lab] = h
                labels.append(lab)
    legend = None
    for ncol in range(min(3, len(labels)), 0, -1):          # as many columns as fit the width
        if legend is not None:
            legend.remove()
        legend = fig.legend([handles[lab] for lab in labels], labels, loc="upper center", ncol=ncol,
                            fontsize=font, frameon=False)
        if legend.get_window_extent(renderer).width / fig.dpi <= width - 0.2:
            break
    legend_h = 0.0 if legend is None else legend.get_window_extent(renderer).height / fig.dpi
    area_h = max((leg.get_window_extent(renderer).height / fig.dpi for leg in area_legends), default=0.0)
    under = 2 * line + 0.25                                  # x tick labels and x label
    robot_row = 2 * line + 0.15 + side + under
    zoom_row = line + 0.15 + side + under - 0.1 + area_h + 0.2
    height = 0.1 + legend_h + 0.15 + blocks * (robot_row + zoom_row) + 0.1
    fig.set_size_inches(width, height)
    if legend is not None:
        legend.set_bbox_to_anchor((0.5, 1 - 0.1 / height), transform=fig.transFigure)
    y = height - 0.1 - legend_h - 0.15
    for b in range(blocks):
        chunk = range(b * cols, min((b + 1) * cols, n))
        for k in chunk:
            x0 = left + (k - b * cols) * (left + side + gap)
            tops[k].set_position((x0 / width, (y - 2 * line - 0.15 - side) / height, side / width, side / height))
            z_top = y - robot_row - line - 0.15
            zooms[k].set_position((x0 / width, (z_top - side) / height, side / width, side / height))
            area_legends[k].set_bbox_to_anchor(((x0 + side / 2) / width, (z_top - side - under + 0.1) / height),
                                               transform=fig.transFigure)
        y -= robot_row + zoom_row
    return fig
