"""Maps of the worst first-order errors of spatial robots over their workspace (issue 37, part 3).

The workspace's grid (:func:`pmaccuracy.kinematics.spatial_workspace.spatial_workspace`: x, y, z at a fixed
orientation for a hexapod, the reachable x, y, z of a Delta or a 3-UPU, roll, pitch, z of a 3-RPS/3-PRS) is
evaluated point by point with :func:`pmaccuracy.accuracy.spatial_bounds.spatial_pose_errors`; points outside
the workspace or near a singularity are NaN. The result is an :class:`xarray.Dataset` with one variable per
quantity (``dx_max, dy_max, dz_max`` mm, ``drx_max, dry_max, drz_max`` rad, ``dp_max`` mm and ``dtheta_max``
rad certified upper bounds, ``dp_attained``/``dtheta_attained`` the attained values) over the grid's three
coordinates, written with ``Dataset.to_netcdf`` or ``to_zarr``.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from ..kinematics.spatial import complete_poses
from ..kinematics.spatial_workspace import spatial_workspace
from ..model.plausibility import check_angle_values
from ..model.spatial import SpatialManipulator
from ..model.spatial_sources import SpatialErrorSources
from .spatial_bounds import COMPONENTS, DEFAULT_GAP, spatial_pose_errors

#: Grid points evaluated per call (bounded memory).
BLOCK = 65536


def grid_poses(robot: SpatialManipulator, coords: np.ndarray, orientation=None) -> np.ndarray:
    """Poses ``(..., 6)`` of grid points ``(..., 3)`` in the workspace's coordinates (x, y, z mm; a 3-RPS/3-PRS:
    roll deg, pitch deg, z mm). Points whose parasitic motions cannot be solved are NaN."""
    coords = np.asarray(coords, dtype=float)
    if robot.mobility == "2R1T":
        c = np.stack([coords[..., 2], np.radians(coords[..., 0]), np.radians(coords[..., 1])], axis=-1)
        return complete_poses(robot, c, strict=False)
    r = np.zeros(3) if orientation is None or robot.mobility == "3T" else np.asarray(orientation, dtype=float)
    return np.concatenate([coords, np.broadcast_to(r, coords.shape)], axis=-1)


def spatial_error_map(robot: SpatialManipulator, sources: SpatialErrorSources, *, n: int = 30, orientation=None,
                      gap: float = DEFAULT_GAP) -> xr.Dataset:
    """The worst first-order errors over the workspace's ``n``-point-per-axis grid (module text).

    >>> import pmaccuracy as pm
    >>> robot = pm.load_robot("upu_3")
    >>> ds = spatial_error_map(robot, SpatialErrorSources.load("upu_typical", robot), n=8)
    >>> sorted(ds.sizes.items()), float(ds.dp_max.max()) > 0
    ([('x', 8), ('y', 8), ('z', 8)], True)
    """
    if orientation is not None:
        check_angle_values(np.linalg.norm(np.asarray(orientation, dtype=float)), "orientation (rotation vector)")
    ws = spatial_workspace(robot, orientation=orientation, n=n, tilt=False)
    region = ws.region
    axes = region.axes
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    inside = region.inside
    flat = grid[inside]
    out = {name: np.full(inside.shape, np.nan) for name in
           (*(f"{c}_max" for c in COMPONENTS), "dp_max", "dp_attained", "dtheta_max", "dtheta_attained")}
    for start in range(0, len(flat), BLOCK):
        pts = flat[start:start + BLOCK]
        poses = grid_poses(robot, pts, orientation)
        ok = np.all(np.isfinite(poses), axis=-1)
        vals = {k: np.full(len(pts), np.nan) for k in out}
        if np.any(ok):
            b = spatial_pose_errors(robot, sources, poses[ok], gap=gap, strict=False, details=False)
            for i, c in enumerate(COMPONENTS):
                vals[f"{c}_max"][ok] = b.components[:, i]
            vals["dp_max"][ok], vals["dp_attained"][ok] = b.dp_upper, b.dp_lower
            vals["dtheta_max"][ok], vals["dtheta_attained"][ok] = b.dtheta_upper, b.dtheta_lower
        idx = tuple(a[start:start + BLOCK] for a in np.nonzero(inside))
        for k in out:
            out[k][idx] = vals[k]
    dims = region.names
    units = {**{f"{c}_max": "mm" for c in COMPONENTS[:3]}, **{f"{c}_max": "rad" for c in COMPONENTS[3:]},
             "dp_max": "mm", "dp_attained": "mm", "dtheta_max": "rad", "dtheta_attained": "rad"}
    ds = xr.Dataset({k: (dims, v, {"units": units[k]}) for k, v in out.items()},
                    coords={d: (d, a, {"units": u}) for d, a, u in zip(dims, axes, region.units)})
    ds.attrs.update(robot=robot.name, architecture=robot.architecture, clearances=sources.name,
                    workspace=ws.kind, gap=gap,
                    description="worst first-order pose errors (exact components; |dp|, |dtheta| certified "
                                "upper bounds); NaN outside the workspace or near a singularity")
    return ds
