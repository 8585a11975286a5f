"""Assigning detected dots to the nodes of the calibration sheet's square lattice.

:func:`find_grid` labels dot centres with integer lattice indices in the
measurement frame: origin at the dot nearest the image centre, ``x`` along the
lattice direction closest to image ``+x`` (increasing column), ``y`` a quarter
turn counter-clockwise from it (up in the image), so ``z = x cross y`` points
toward the camera (right-handed seen from the camera). Dots off the lattice
(stray blobs) are left out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..errors import VisionError
from ._util import MIN_CALIBRATION_DOTS, _estimate, image_centre
from .._optional import require


def _lattice_angle(points: np.ndarray, d0: float, tree: cKDTree) -> float:
    """Direction (rad, y-up image frame) of the dot lattice, folded to (-pi/4, pi/4].

    Nearest-neighbour vectors of length within 30 % of ``d0`` have angles that
    agree modulo a quarter turn; the circular mean of ``4 angle`` averages them.
    """
    k = min(5, len(points))
    dist, idx = tree.query(points, k=k)
    vec = points[idx[:, 1:]] - points[:, None, :]
    ok = (dist[:, 1:] > 0.7 * d0) & (dist[:, 1:] < 1.3 * d0)
    v = vec[ok]
    ang = np.arctan2(-v[:, 1], v[:, 0])  # image rows point down: flip to y up
    mean = np.sum(np.exp(4j * ang))
    if abs(mean) < 1e-9 * max(len(ang), 1):  # no consistent directions at all
        raise VisionError("the dots do not form a square grid (no consistent neighbour directions)")
    theta = float(np.angle(mean)) / 4.0
    return theta if theta > -math.pi / 4 else theta + math.pi / 2


def _local_basis(points: np.ndarray, c0: int, theta: float, d0: float, tree: cKDTree) -> np.ndarray:
    """Pixel vectors ``(2, 2)`` of the lattice steps +i and +j at dot ``c0``, refined from its neighbours."""
    c, s = math.cos(theta), math.sin(theta)
    guess = d0 * np.array([[c, -s], [-s, -c]])  # +i along theta, +j a quarter turn counter-clockwise (up)
    near = tree.query_ball_point(points[c0], 1.45 * d0)
    vecs = points[near] - points[c0]
    basis = guess.copy()
    if len(vecs) > 1:
        for axis in range(2):
            steps = []
            for sign in (1.0, -1.0):
                err = np.linalg.norm(vecs - sign * guess[axis], axis=1)
                best = int(np.argmin(err))
                if err[best] < 0.35 * d0:
                    steps.append(sign * vecs[best])
            if steps:
                basis[axis] = np.mean(steps, axis=0)
    return basis


def _assign_indices(points: np.ndarray, model, radius: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Integer grid indices ``(M, 2)`` of the points that sit close to a grid node of ``model`` (index -> px).

    Returns (point indices, grid indices). A point is accepted when its
    fractional index is within 0.3 of an integer node (and within ``radius``
    nodes of the origin); two points claiming the same node keep the closer one.
    """
    with np.errstate(all="ignore"):
        frac = model.inverse(points)
    ij = np.rint(frac)
    err = np.linalg.norm(frac - ij, axis=1)
    ok = np.isfinite(err) & (err < 0.3)
    if radius is not None:
        ok &= np.max(np.abs(np.nan_to_num(ij, nan=np.inf)), axis=1) <= radius
    which = np.flatnonzero(ok)
    which = which[np.argsort(err[which], kind="stable")]
    _, first = np.unique(ij[which], axis=0, return_index=True)
    which = np.sort(which[first])
    return which, ij[which].astype(int)


def _fit_index_model(ij: np.ndarray, px: np.ndarray):
    """Index -> pixel model: projective with enough well-spread nodes, affine otherwise."""
    spread = len(np.unique(ij[:, 0])) >= 2 and len(np.unique(ij[:, 1])) >= 2
    if len(ij) >= MIN_CALIBRATION_DOTS and spread:
        model = _estimate(_transforms().ProjectiveTransform, ij.astype(float), px)
        if model is not None and np.all(np.isfinite(model.params)):
            return model
    if len(ij) >= 3 and spread:
        model = _estimate(_transforms().AffineTransform, ij.astype(float), px)
        if model is not None and np.all(np.isfinite(model.params)):
            return model
    return None




def _transforms():
    transform = require("skimage.transform")

    return transform


@dataclass(frozen=True, eq=False)
class Grid:
    """Dots on the lattice: ``which`` ``(M,)`` indices into the detected dots, ``ij`` ``(M, 2)`` their integer
    lattice coordinates in the measurement frame (``x = spacing i``, ``y = spacing j``)."""

    which: np.ndarray
    ij: np.ndarray

    def __len__(self) -> int:
        return int(self.which.shape[0])


def find_grid(points_px: np.ndarray, image_shape: tuple[int, ...]) -> Grid:
    """Lattice indices of dot centres ``(N, 2)`` ``[col, row]`` px (module docstring for the frame).

    1. ``d0`` = median nearest-neighbour distance; the lattice direction closest
       to image ``+x`` comes from the circular mean of the neighbour directions
       modulo a quarter turn; the dot nearest the image centre is node (0, 0)
       and its neighbours refine the two step vectors.
    2. The grid is grown ring by ring: dots within ``k`` nodes of the origin are
       assigned to the nearest integer node of the current index -> pixel model
       (affine, then projective once six or more nodes are known; lens
       distortion of a few pixels is far below the 0.3-node acceptance) and the
       model is refitted, until no new dot joins. Spurious blobs off the grid
       are ignored.
    3. The indices are re-labelled: origin at the assigned dot nearest the image
       centre, ``+i`` the lattice step closest to image ``+x``, ``+j`` the step a
       quarter turn counter-clockwise from it in the y-up image frame.

    Fewer than six assigned dots, or dots all in one row, raise :class:`VisionError`.
    """
    pts = np.asarray(points_px, dtype=float).reshape(-1, 2)
    if not np.all(np.isfinite(pts)):
        raise VisionError("dot centres must be finite")
    if len(pts) < MIN_CALIBRATION_DOTS:
        raise VisionError(f"found {len(pts)} calibration dot(s), at least {MIN_CALIBRATION_DOTS} are needed")
    tree = cKDTree(pts)
    nn_dist = tree.query(pts, k=2)[0][:, 1]
    d0 = float(np.median(nn_dist))
    if d0 <= 0:  # duplicated centres
        raise VisionError("calibration dots coincide; cannot find the grid")
    centre = image_centre(image_shape)
    c0 = int(np.argmin(np.linalg.norm(pts - centre, axis=1)))
    theta = _lattice_angle(pts, d0, tree)
    basis = _local_basis(pts, c0, theta, d0, tree)
    model = _transforms().AffineTransform(matrix=np.array([[basis[0, 0], basis[1, 0], pts[c0, 0]],
                                                            [basis[0, 1], basis[1, 1], pts[c0, 1]],
                                                            [0.0, 0.0, 1.0]]))
    previous: tuple[int, ...] = ()
    radius = 1
    with np.errstate(all="ignore"):
        extent0 = float(np.max(np.abs(model.inverse(pts))))  # grid extent in nodes under the first guess
    if not math.isfinite(extent0):  # degenerate first guess: fall back to the number of dots
        extent0 = float(len(pts))
    for _ in range(2 * int(extent0) + 10):  # each pass widens the radius by one node
        which, ij = _assign_indices(pts, model, radius)
        fitted = _fit_index_model(ij, pts[which])
        if fitted is not None:
            model = fitted
        current = tuple(which)
        with np.errstate(all="ignore"):
            extent = np.nanmax(np.abs(model.inverse(pts)))
        if current == previous and (not np.isfinite(extent) or radius > extent + 1):
            break
        previous = current
        radius += 1
    which, ij = _assign_indices(pts, model, None)
    if len(which) < MIN_CALIBRATION_DOTS:
        raise VisionError(f"only {len(which)} dot(s) lie on a regular grid, at least {MIN_CALIBRATION_DOTS} are "
                          "needed")
    if len(np.unique(ij[:, 0])) < 2 or len(np.unique(ij[:, 1])) < 2:
        raise VisionError("the calibration dots lie on a single line; a 2-D grid is needed")

    # frame: origin at the assigned dot nearest the image centre, axes by the local steps there
    px = pts[which]
    origin = ij[int(np.argmin(np.linalg.norm(px - centre, axis=1)))]
    ij = ij - origin
    fitted = _fit_index_model(ij, px)
    if fitted is None:
        raise VisionError("cannot fit a grid model to the calibration dots")
    p0 = fitted(np.zeros((1, 2)))[0]
    steps = np.stack([fitted(np.array([[1.0, 0.0]]))[0] - p0, fitted(np.array([[0.0, 1.0]]))[0] - p0])
    steps_up = steps * np.array([1.0, -1.0])  # to a y-up frame
    candidates = np.concatenate([steps_up, -steps_up])  # +i, +j, -i, -j
    pick = int(np.argmax(candidates[:, 0] / np.linalg.norm(candidates, axis=1)))  # closest to +x
    ex = np.eye(2)[pick % 2] * (1.0 if pick < 2 else -1.0)  # index direction that becomes +x
    ey_options = np.array([[-ex[1], ex[0]], [ex[1], -ex[0]]])  # the two perpendicular index directions
    step_x = ex @ steps_up
    cross = step_x[0] * (ey_options @ steps_up)[:, 1] - step_x[1] * (ey_options @ steps_up)[:, 0]
    ey = ey_options[int(np.argmax(cross))]  # counter-clockwise from x (right-handed, y up)
    # new coordinates (X, Y) of an old index vector n: X = ex.n, Y = ey.n
    new_ij = np.rint(ij @ np.stack([ex, ey]).T).astype(int)
    return Grid(which=which, ij=new_ij)
