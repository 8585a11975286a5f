"""How loose may a spatial robot's joints be? The largest uniform scaling of its error sources that keeps the
worst first-order errors within targets at every point of its workspace grid (issue 37, synthesis, first part).

Every worst-case quantity is positively homogeneous of degree one in the half-widths: scaling every source by
``lam`` scales ``dx_max ... drz_max`` exactly and the certified ``|dp|``, ``|dtheta|`` upper bounds too. So with
``q_k(x)`` the quantity ``k`` of the template sources at the grid point ``x`` (:func:`pmaccuracy.accuracy.
spatial_maps.spatial_error_map`),

    lam = min over k and x of  T_k / q_k(x)                                                          (1)

is the largest scale meeting every target ``T_k`` at every grid point, attained at the binding point. It is
exact on the grid (upper bounds of ``|dp|``, ``|dtheta|``: conservative by at most their gap); between grid
points it is not certified (the planar ``synthesize`` certifies a whole region; for spatial robots that comes
next).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, EmptyWorkspaceError
from ..model.plausibility import check_angle_values
from ..model.spatial import SpatialManipulator
from ..model.spatial_sources import SpatialErrorSources
from .spatial_maps import spatial_error_map

#: Targets a spatial synthesis takes, and the map variable and unit conversion of each (mm, or deg -> rad).
TARGETS = {"dx": ("dx_max", 1.0), "dy": ("dy_max", 1.0), "dz": ("dz_max", 1.0),
           "drx_deg": ("drx_max", np.pi / 180), "dry_deg": ("dry_max", np.pi / 180),
           "drz_deg": ("drz_max", np.pi / 180), "dp": ("dp_max", 1.0), "dtheta_deg": ("dtheta_max", np.pi / 180)}


@dataclass(frozen=True)
class SpatialSynthesis:
    """The result of :func:`spatial_synthesize`.

    Attributes
    ----------
    scale : float
        ``lam`` of Eq. 1: every half-width of the template times it meets every target at every grid point.
    sources : :class:`~pmaccuracy.model.spatial_sources.SpatialErrorSources`
        The synthesized sources (the template scaled).
    binding : str
        The target that binds (its name, e.g. ``"dp"``).
    binding_point : ``(3,)``
        The grid point where it binds, in the grid's coordinates (x, y, z mm; roll, pitch deg and z mm for a
        3-RPS/3-PRS).
    worst : dict
        The synthesized sources' worst value of each targeted quantity over the grid (mm or deg).
    targets : dict
        The targets (mm or deg).
    points : int
        Grid points evaluated.
    """

    scale: float
    sources: SpatialErrorSources
    binding: str
    binding_point: np.ndarray
    worst: dict
    targets: dict
    points: int


def spatial_synthesize(robot: SpatialManipulator, template: SpatialErrorSources, targets: dict[str, float], *,
                       n: int = 20, orientation=None, error_map=None) -> SpatialSynthesis:
    """The largest uniform scaling of ``template`` meeting ``targets`` (``{"dp": mm, "dtheta_deg": deg, ...}``,
    names in :data:`TARGETS`) at every point of the workspace's ``n``-per-axis grid (Eq. 1).

    ``error_map``: the template's map already computed (:func:`~pmaccuracy.accuracy.spatial_maps.spatial_error_map`
    of ``robot`` and ``template`` at ``orientation``, e.g. by a report), used instead of computing it again; its
    grid replaces ``n``.

    >>> import pmaccuracy as pm
    >>> robot = pm.load_robot("upu_3")
    >>> res = spatial_synthesize(robot, pm.load_clearances("upu_typical", robot), {"dp": 0.1}, n=6)
    >>> res.binding, round(res.worst["dp"], 9)
    ('dp', 0.1)
    """
    if orientation is not None:
        check_angle_values(np.linalg.norm(np.asarray(orientation, dtype=float)), "orientation (rotation vector)")
    if not targets:
        raise ConfigError(f"give at least one target ({', '.join(TARGETS)})", key="targets")
    for name, value in targets.items():
        if name not in TARGETS:
            raise ConfigError(f"unknown target {name!r} for a spatial robot; targets: {', '.join(TARGETS)}",
                              key="targets")
        if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
            raise ConfigError(f"{name} must be finite and > 0, got {value!r}", key="targets")
    if not any(v for leg in template.legs for j in leg for _, v in j.items()):
        raise ConfigError("the template has no non-zero error source to scale", key="clearances")
    if error_map is None:
        ds = spatial_error_map(robot, template, n=n, orientation=orientation)
    else:
        ds = error_map
        if ds.attrs.get("robot") != robot.name or ds.attrs.get("clearances") != template.name:
            raise ConfigError(f"the error map is of {ds.attrs.get('robot')!r} with {ds.attrs.get('clearances')!r}, "
                              f"not of {robot.name!r} with {template.name!r}", key="error_map")
    best, binding, point = np.inf, None, None
    for name, target in targets.items():
        var, unit = TARGETS[name]
        values = ds[var].values
        finite = np.isfinite(values)
        if not finite.any():
            raise EmptyWorkspaceError("no grid point of the workspace could be evaluated")
        ratio = np.where(finite & (values > 0), target * unit / np.where(values > 0, values, 1.0), np.inf)
        k = np.unravel_index(np.argmin(ratio), ratio.shape)
        if ratio[k] < best:
            best, binding = float(ratio[k]), name
            point = np.array([float(ds[d].values[i]) for d, i in zip(ds[var].dims, k)])
    if not np.isfinite(best):
        raise ConfigError("the template's sources move none of the targeted quantities: no scale bounds them",
                          key="targets")
    worst = {name: float(np.nanmax(ds[TARGETS[name][0]].values)) * best / TARGETS[name][1] for name in targets}
    scaled = template.scaled(best)
    return SpatialSynthesis(scale=best, sources=scaled, binding=binding, binding_point=point, worst=worst,
                            targets=dict(targets), points=int(np.isfinite(ds.dp_max.values).sum()))
