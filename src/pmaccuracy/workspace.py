"""Constant-orientation workspace of a 3-PPR manipulator (paper Sec. 3, Fig. 3).

At a fixed orientation ``phi`` every joint value of the inverse kinematics
(Eq. 2a, 2b) is an affine function of the position ``p = [x, y]``::

    c_i(phi) = a_i h_i + d_i v_i + r_i k_i(phi)                       (mm, Eq. 1)
    s_i = (w_i^T E u_i)^-1 w_i^T E (p - c_i(phi)) = sigma_i . (p - c_i(phi))   (Eq. 2a)
    l_i = (u_i^T E w_i)^-1 u_i^T E (p - c_i(phi)) = lambda_i . (p - c_i(phi))  (Eq. 2b)

    sigma_i  = E^T w_i / (w_i^T E u_i)        lambda_i = E^T u_i / (u_i^T E w_i)

(``x^T E y = x . (E y)``, so ``w^T E p = (E^T w) . p``). The twelve joint
limits ``s_min <= s_i <= s_max`` and ``l_min <= l_i <= l_max`` are therefore
twelve half-planes ``G p <= h`` and the workspace at constant ``phi`` is their
intersection: an exact convex polygon, bounded because each leg alone keeps
``p`` in the parallelogram ``c_i + [s range] u_i + [l range] w_i + r_i k_i``.
The paper obtains the same region by a "searching method" (IK on a grid);
:func:`grid_search_workspace` does that as a cross-check.

Lengths are in mm, angles in radians (the figure and the CLI use degrees).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import EmptyWorkspaceError
from .geometry import Manipulator, perp, unit
from .kinematics import LIMIT_TOLERANCE, inverse_kinematics

#: Names of the rows of :func:`joint_halfplanes`, in order.
CONSTRAINT_LABELS = tuple(
    [f"s{i} <= s{i}_max" for i in (1, 2, 3)] + [f"s{i} >= s{i}_min" for i in (1, 2, 3)]
    + [f"l{i} <= l{i}_max" for i in (1, 2, 3)] + [f"l{i} >= l{i}_min" for i in (1, 2, 3)]
)
#: A workspace whose largest inscribed disc is smaller than this radius (mm) is degenerate: treated as empty.
MIN_INRADIUS = 1e-6
#: Orientations of the paper's Fig. 3 (deg).
DEFAULT_PHIS_DEG = (0.0, 30.0, -30.0)


def joint_coefficients(robot: Manipulator) -> tuple[np.ndarray, np.ndarray]:
    """The constant gradients ``sigma_i = ds_i/dp`` and ``lambda_i = dl_i/dp`` at fixed phi.

    ``sigma_i = E^T w_i / (w_i^T E u_i)`` (Eq. 2a) and
    ``lambda_i = E^T u_i / (u_i^T E w_i)`` (Eq. 2b); both of shape ``(3, 2)``
    (mm/mm, dimensionless). ``E^T x = -E x``; the denominators are
    ``+-sin(gamma_i + theta_i)``, kept away from zero by the geometry checks.
    """
    w_E_u = np.sum(robot.w * perp(robot.u), axis=-1)  # w_i^T E u_i, (3,)
    sigma = -perp(robot.w) / w_E_u[:, None]
    lam = -perp(robot.u) / (-w_E_u)[:, None]          # u^T E w = -w^T E u
    return sigma, lam


def loop_origins(robot: Manipulator, phi: np.ndarray | float) -> np.ndarray:
    """``c_i(phi) = a_i h_i + d_i v_i + r_i k_i(phi)`` (mm), shape ``(..., 3, 2)`` for phi ``(...)``.

    The point ``P`` would occupy for ``s_i = l_i = 0`` (Eq. 1 with the joint terms removed).
    """
    phi = np.asarray(phi, dtype=float)
    k = unit(phi[..., None] + robot.psi)  # (..., 3, 2)
    return robot.base_points + robot.d[:, None] * robot.v + robot.r[:, None] * k


def joint_halfplanes(robot: Manipulator, phi: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """The 12 joint-limit constraints at orientation ``phi`` as half-planes ``G @ [x, y] <= h``.

    With ``sigma_i, lambda_i`` from :func:`joint_coefficients` and
    ``c_i = c_i(phi)`` from :func:`loop_origins` (Eq. 2a, 2b)::

        rows 0-2  :  sigma_i . p <= s_i,max + sigma_i . c_i
        rows 3-5  : -sigma_i . p <= -s_i,min - sigma_i . c_i
        rows 6-8  :  lambda_i . p <= l_i,max + lambda_i . c_i
        rows 9-11 : -lambda_i . p <= -l_i,min - lambda_i . c_i

    (labels in :data:`CONSTRAINT_LABELS`). The rows are *not* normalized:
    ``G @ p - h`` is the amount (mm of joint travel) by which each joint
    exceeds its limit, exactly what :func:`~pmaccuracy.kinematics.within_joint_limits`
    compares with its tolerance.

    Parameters
    ----------
    phi : float or array ``(...)``, rad

    Returns
    -------
    G : ``(12, 2)`` (independent of phi);  h : ``(..., 12)`` mm
    """
    sigma, lam = joint_coefficients(robot)
    c = loop_origins(robot, phi)  # (..., 3, 2)
    s_c = np.sum(sigma * c, axis=-1)  # (..., 3)
    l_c = np.sum(lam * c, axis=-1)
    G = np.concatenate([sigma, -sigma, lam, -lam], axis=0)
    h = np.concatenate([robot.s_range[:, 1] + s_c, -robot.s_range[:, 0] - s_c,
                        robot.l_range[:, 1] + l_c, -robot.l_range[:, 0] - l_c], axis=-1)
    return G, h


@dataclass(frozen=True, eq=False)
class Workspace:
    """The constant-orientation workspace at ``phi``: an exact convex polygon (paper Sec. 3).

    Attributes
    ----------
    phi : float, rad
    vertices : ``(M, 2)`` mm, counter-clockwise; ``(0, 2)`` when empty
    area : float, mm^2 (0.0 when empty)
    bounds : ``((xmin, xmax), (ymin, ymax))`` mm; NaN when empty
    G, h : ``(12, 2)`` and ``(12,)``: the joint-limit half-planes ``G p <= h`` (:func:`joint_halfplanes`)
    interior_point : ``(2,)`` mm, Chebyshev centre (centre of the largest inscribed disc); NaN when empty
    inradius : float, mm, radius of that disc in the Euclidean metric (<= 0 when empty)
    """

    phi: float
    vertices: np.ndarray
    area: float
    bounds: tuple[tuple[float, float], tuple[float, float]]
    G: np.ndarray = field(repr=False)
    h: np.ndarray = field(repr=False)
    interior_point: np.ndarray = field(repr=False)
    inradius: float = field(repr=False)

    @property
    def is_empty(self) -> bool:
        """True when no position (or only a zero-area set of them) is reachable at ``phi``."""
        return self.vertices.shape[0] == 0

    def require_nonempty(self) -> "Workspace":
        """Return self, or raise :class:`EmptyWorkspaceError` if the workspace is empty."""
        if self.is_empty:
            raise EmptyWorkspaceError(
                f"the constant-orientation workspace at phi = {np.degrees(self.phi):g} deg is empty: "
                "no position satisfies all twelve joint limits (Eq. 2a, 2b)")
        return self

    @property
    def centroid(self) -> np.ndarray:
        """Area centroid of the polygon ``(2,)`` mm (NaN when empty)."""
        if self.is_empty:
            return np.full(2, np.nan)
        x, y = self.vertices.T
        xn, yn = np.roll(x, -1), np.roll(y, -1)
        cross = x * yn - xn * y
        a = cross.sum() / 2
        return np.array([np.sum((x + xn) * cross), np.sum((y + yn) * cross)]) / (6 * a)

    def contains(self, points: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """True for positions ``(..., 2)`` mm inside the workspace; result shape ``(...)``.

        A point is inside when every joint is within its limits up to ``tol``
        mm of joint travel (``max(G p - h) <= tol``), the same test as
        :func:`~pmaccuracy.kinematics.inverse_kinematics`, so a pose computed
        on the boundary (e.g. a vertex) counts as inside. Always False when
        the workspace is empty.
        """
        points = np.asarray(points, dtype=float)
        if points.ndim == 0 or points.shape[-1] != 2:
            raise ValueError(f"points must have shape (..., 2), got {points.shape}")
        if self.is_empty:
            return np.zeros(points.shape[:-1], dtype=bool)
        excess = points @ self.G.T - self.h
        return np.all(excess <= tol, axis=-1)

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


def _empty(phi: float, G: np.ndarray, h: np.ndarray, inradius: float) -> Workspace:
    nan = float("nan")
    return Workspace(phi=phi, vertices=np.zeros((0, 2)), area=0.0, bounds=((nan, nan), (nan, nan)),
                     G=G, h=h, interior_point=np.full(2, nan), inradius=inradius)


def constant_orientation_workspace(robot: Manipulator, phi: float,
                                   min_inradius: float = MIN_INRADIUS) -> Workspace:
    """The exact workspace polygon of ``robot`` at orientation ``phi`` (rad), paper Sec. 3.

    1. Half-planes ``G p <= h`` from :func:`joint_halfplanes` (Eq. 2a, 2b).
    2. Chebyshev centre by linear programming (``scipy.optimize.linprog``)::

           max t  s.t.  (G_k / |G_k|) . p + t <= h_k / |G_k|,  k = 1..12

       ``t`` is the radius of the largest inscribed disc; ``t < min_inradius``
       (mm) means an empty or zero-area (segment/point) workspace, returned as
       an empty :class:`Workspace` rather than raising.
    3. Vertices by ``scipy.spatial.HalfspaceIntersection`` about that centre,
       ordered counter-clockwise and measured by ``scipy.spatial.ConvexHull``.
    """
    from scipy.optimize import linprog
    from scipy.spatial import ConvexHull, HalfspaceIntersection

    phi = float(phi)
    if not np.isfinite(phi):
        raise ValueError(f"phi must be finite, got {phi}")
    G, h = joint_halfplanes(robot, phi)
    norms = np.linalg.norm(G, axis=1)
    Gn, hn = G / norms[:, None], h / norms
    # Variables (x, y, t); maximize t.
    res = linprog(c=[0.0, 0.0, -1.0], A_ub=np.column_stack([Gn, np.ones(12)]), b_ub=hn,
                  bounds=[(None, None)] * 3, method="highs")
    if res.status != 0:  # pragma: no cover - the polygon is always bounded, t free keeps it feasible
        raise RuntimeError(f"linprog failed on the workspace half-planes: {res.message}")
    centre, radius = res.x[:2], float(res.x[2])
    if radius < min_inradius:
        return _empty(phi, G, h, radius)
    hsi = HalfspaceIntersection(np.column_stack([Gn, -hn]), centre)
    hull = ConvexHull(hsi.intersections)
    vertices = hull.points[hull.vertices]  # counter-clockwise in 2-D
    bounds = ((float(vertices[:, 0].min()), float(vertices[:, 0].max())),
              (float(vertices[:, 1].min()), float(vertices[:, 1].max())))
    return Workspace(phi=phi, vertices=vertices, area=float(hull.volume), bounds=bounds,
                     G=G, h=h, interior_point=centre, inradius=radius)


@dataclass(frozen=True, eq=False)
class GridWorkspace:
    """Result of the paper's "searching method": IK on a regular grid at constant phi.

    Attributes
    ----------
    phi : float, rad
    x, y : ``(n,)`` mm, grid coordinates
    inside : bool ``(n, n)`` indexed [y, x]: every joint within its limits (Eq. 2a, 2b)
    area : float, mm^2, ``count(inside) * dx * dy`` (a first-order estimate)
    """

    phi: float
    x: np.ndarray
    y: np.ndarray
    inside: np.ndarray
    area: float


def leg_box(robot: Manipulator, phi: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """A box ``((xmin, xmax), (ymin, ymax))`` (mm) that contains the workspace at ``phi``.

    Each leg alone keeps ``P`` in the parallelogram ``c_i + s u_i + l w_i``
    (s, l over their ranges); the box is the intersection of the three
    parallelograms' bounding boxes (the box of leg 1 if that is empty).
    """
    c = loop_origins(robot, phi)  # (3, 2)
    s = robot.s_range[:, :, None, None] * robot.u[:, None, None, :]  # (3, 2, 1, 2)
    l = robot.l_range[:, None, :, None] * robot.w[:, None, None, :]  # (3, 1, 2, 2)
    corners = (c[:, None, None, :] + s + l).reshape(3, 4, 2)
    lo, hi = corners.min(axis=1), corners.max(axis=1)  # (3, 2)
    box_lo, box_hi = lo.max(axis=0), hi.min(axis=0)
    if np.any(box_lo >= box_hi):
        box_lo, box_hi = lo[0], hi[0]
    return (float(box_lo[0]), float(box_hi[0])), (float(box_lo[1]), float(box_hi[1]))


def grid_search_workspace(robot: Manipulator, phi: float, n: int,
                          box: tuple[tuple[float, float], tuple[float, float]] | None = None,
                          tol: float = LIMIT_TOLERANCE) -> GridWorkspace:
    """The paper's searching method: inverse kinematics on an ``n x n`` grid at constant ``phi``.

    ``box = ((xmin, xmax), (ymin, ymax))`` mm defaults to :func:`leg_box`.
    A grid point is inside when :func:`~pmaccuracy.kinematics.inverse_kinematics`
    finds all twelve joint limits satisfied (tolerance ``tol`` mm).
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


# ---------------------------------------------------------------------------------------- figure
def plot_workspaces(robot: Manipulator, phis: tuple[float, ...] | np.ndarray | None = None, ax=None):
    """Draw constant-orientation workspaces for several orientations (paper Fig. 3 analogue).

    Draws each workspace polygon at ``phis`` (rad; default 0, 30 and -30 deg),
    the base points ``A_i``, the guides ``A_i + s u_i`` over each ``s`` range,
    and the robot assembled at the centroid of the ``phi = 0`` workspace:
    sliders ``B_i``, offset links ``B_i C_i`` (``d_i v_i``), bearings
    ``C_i D_i`` (``l_i w_i``) and the platform triangle ``D_1 D_2 D_3``.
    Without ``ax`` a new :class:`matplotlib.figure.Figure` is made (no
    pyplot state); returns the axes. Coordinates in mm.
    """
    from matplotlib.figure import Figure

    phis = np.radians(DEFAULT_PHIS_DEG) if phis is None else np.atleast_1d(np.asarray(phis, dtype=float))
    if ax is None:
        ax = Figure(figsize=(7.5, 7.0)).add_subplot()
    colors = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown"]
    for j, phi in enumerate(phis):
        ws = constant_orientation_workspace(robot, phi)
        deg = np.degrees(phi)
        color = colors[j % len(colors)]
        if ws.is_empty:
            ax.plot([], [], color=color, label=f"$\\phi$ = {deg:g}°: empty")
            continue
        ax.fill(ws.vertices[:, 0], ws.vertices[:, 1], facecolor=color, alpha=0.25, edgecolor=color,
                linewidth=1.5, label=f"$\\phi$ = {deg:g}°, {ws.area:.0f} mm$^2$")

    A = robot.base_points
    ax.plot(A[:, 0], A[:, 1], "k^", markersize=8, label="base points $A_i$")
    for i in range(3):
        ax.annotate(f"$A_{i + 1}$", A[i], textcoords="offset points", xytext=(6, 6))
    guides = A[:, None, :] + robot.s_range[:, :, None] * robot.u[:, None, :]  # (3, 2, 2)
    for i in range(3):
        ax.plot(guides[i, :, 0], guides[i, :, 1], color="0.35", linewidth=5, solid_capstyle="butt",
                alpha=0.6, label="guides (s range)" if i == 0 else None)

    ws0 = constant_orientation_workspace(robot, 0.0)
    if not ws0.is_empty:
        pose = np.array([*ws0.centroid, 0.0])
        ik = inverse_kinematics(robot, pose)
        B = A + ik.s[:, None] * robot.u
        C = B + robot.d[:, None] * robot.v
        D = robot.platform_points(pose)
        ax.plot(B[:, 0], B[:, 1], "ks", markersize=5, label="sliders $B_i$")
        for i in range(3):
            ax.plot(*np.stack([B[i], C[i]]).T, color="tab:brown", linewidth=2,
                    label="offset links $d_i$" if i == 0 else None)
            ax.plot(*np.stack([C[i], D[i]]).T, color="tab:cyan", linewidth=2,
                    label="bearings $l_i$" if i == 0 else None)
        tri = np.vstack([D, D[:1]])
        ax.fill(tri[:, 0], tri[:, 1], facecolor="0.6", alpha=0.5, edgecolor="k",
                label="platform $D_1D_2D_3$ ($\\phi$ = 0)")
        ax.plot(pose[0], pose[1], "k+", markersize=8)

    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(f"Constant-orientation workspaces, {robot.name}")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    return ax


def save_workspace_figure(robot: Manipulator, path: str | Path,
                          phis_deg: tuple[float, ...] = DEFAULT_PHIS_DEG, dpi: int = 150) -> Path:
    """Write :func:`plot_workspaces` for ``phis_deg`` (deg) to ``path`` as a PNG (Agg canvas); returns the path.

    The file is PNG whatever its extension.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.5, 7.0))
    FigureCanvasAgg(fig)
    plot_workspaces(robot, np.radians(np.asarray(phis_deg, dtype=float)), ax=fig.add_subplot())
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=dpi, format="png")
    fig.clear()
    return path
