"""Maps of the pose errors of spatial robots over their workspace (issue 37): worst case, percentiles, Dask, Zarr.

Grid. The workspace's grid (:func:`pmaccuracy.kinematics.spatial_workspace.spatial_workspace`: x, y, z at a
fixed orientation for a hexapod, the reachable x, y, z of a Delta or a 3-UPU, roll, pitch, z of a
3-RPS/3-PRS) has ``n`` points per axis; points outside the workspace or near a singularity are NaN.

Worst case (:func:`spatial_error_map`). At each grid point
:func:`pmaccuracy.accuracy.spatial_bounds.spatial_pose_errors`: ``dx_max, dy_max, dz_max`` mm,
``drx_max, dry_max, drz_max`` rad (exact first-order maxima), ``dp_max`` mm and ``dtheta_max`` rad (certified
upper bounds), ``dp_attained``/``dtheta_attained`` (attained values).

Percentiles (:func:`spatial_percentile_map`), as the planar percentile maps
(:func:`pmaccuracy.accuracy.distributions.region_statistics`): Monte Carlo of the first-order error twist
``t = sum_s M_s x_s`` (:mod:`pmaccuracy.accuracy.spatial_statistics`) with the SAME ``samples`` source states
``x_s`` (drawn once, seeded) at every grid point. Per quantity ``q`` in dx, dy, dz (mm), drx, dry, drz (rad),
dp (mm, ``|t[:3]|``) and dtheta (rad, ``|t[3:]|``): ``q_p{p}`` the ``p``-th percentile of ``|q|``, ``q_std``
(Monte Carlo standard deviation), ``q_rss`` (analytic: ``sqrt(Cov_qq)`` of a component, the root mean square
``sqrt(tr Cov)`` of dp, dtheta), ``q_exceed = P(|q| > threshold)`` with a threshold, and the worst case
``q_max`` of :func:`spatial_error_map`. Attributes ``q_p{p}_error``: the largest half-width over the map of the
percentile's 95 % order-statistic interval (units of ``q``).

Scale. The grid is cut into slabs of whole planes of its first axis (about :data:`ZARR_POINTS` points each),
each slab into blocks of grid points (:data:`BLOCK` for the worst case; a percentile map's blocks hold
:data:`MAX_VALUES` twist values); a block evaluates the workspace's membership
(:func:`~pmaccuracy.kinematics.spatial_workspace.workspace_box`) and the errors at its inside points, so the
whole grid's membership is never held. ``use_dask=True`` makes each block a Dask task on the active scheduler
(threads by default), ``use_dask=client`` (a ``dask.distributed.Client``) on that client: the same blocks, the
same numbers. :func:`write_spatial_map` streams a map into a Zarr store, one chunk per slab, each slab
computed and written in place as soon as it is done (a Dask task per slab with ``use_dask``), so memory holds
a few slabs whatever ``n``; the store reads back (``xarray.open_zarr``) as the in-memory map to the last bit.
A ``.nc`` file is computed in memory, which :func:`check_spatial_fits_in_memory` refuses (use a ``.zarr``
store) when the results and the working memory (:data:`WORKING_BYTES`) would not fit.
"""

from __future__ import annotations

import math
import os
import warnings
from pathlib import Path

import numpy as np
import xarray as xr

from .._optional import require
from ..errors import ConfigError
from ..kinematics.spatial import complete_poses, reference_pose
from ..kinematics.spatial_workspace import workspace_box
from ..kinematics.workspace3d import cell_centres
from ..model.plausibility import check_angle_values
from ..model.spatial import SpatialManipulator
from ..model.spatial_sources import SpatialErrorSources
from .maps import MEMORY_FACTOR, available_memory, format_bytes
from .distributions import sample_statistics
from .spatial_bounds import COMPONENTS, DEFAULT_GAP, error_sources_at, spatial_pose_errors
from .spatial_statistics import (CHUNK, DEFAULT_SIGMA, QUANTITIES, _DIMS, _check_inputs, sample_unit_set,
                                 unit_variance)

#: Grid points evaluated per block (one Dask task with ``use_dask``).
BLOCK = 65536
#: Grid points per block of a percentile map are at most this many values over ``6 x samples`` (memory).
MAX_VALUES = 1 << 22
#: Grid points per Zarr chunk (whole planes of the first axis, at least one).
ZARR_POINTS = 1 << 18
#: Variables of the worst-case map: name -> unit.
WORST_VARIABLES = {**{f"{c}_max": "mm" for c in COMPONENTS[:3]}, **{f"{c}_max": "rad" for c in COMPONENTS[3:]},
                   "dp_max": "mm", "dp_attained": "mm", "dtheta_max": "rad", "dtheta_attained": "rad"}
#: Quantities of a percentile map (units: mm, rad).
MAP_QUANTITIES = (*COMPONENTS, "dp", "dtheta")
_UNITS = {**{c: "mm" for c in COMPONENTS[:3]}, **{c: "rad" for c in COMPONENTS[3:]}, "dp": "mm", "dtheta": "rad"}
#: Threshold keys (those of :func:`pmaccuracy.accuracy.spatial_statistics.spatial_pose_statistics`, angles in
#: deg) -> map quantity.
_THRESHOLD_KEYS = dict(zip(QUANTITIES, MAP_QUANTITIES))


def grid_poses(robot: SpatialManipulator, coords: np.ndarray, orientation=None) -> np.ndarray:
    """Poses ``(..., 6)`` of grid points ``(..., 3)`` in the workspace's coordinates (x, y, z mm; a 3-RPS/3-PRS:
    roll deg, pitch deg, z mm). Points whose parasitic motions cannot be solved are NaN."""
    coords = np.asarray(coords, dtype=float)
    if robot.mobility == "2R1T":
        c = np.stack([coords[..., 2], np.radians(coords[..., 0]), np.radians(coords[..., 1])], axis=-1)
        return complete_poses(robot, c, strict=False)
    r = np.zeros(3) if orientation is None or robot.mobility == "3T" else np.asarray(orientation, dtype=float)
    return np.concatenate([coords, np.broadcast_to(r, coords.shape)], axis=-1)


# ------------------------------------------------------------------------------------------------ the kernels
def _worst_block(robot, sources, pts: np.ndarray, orientation, gap: float) -> np.ndarray:
    """The worst-case variables ``(k, 10)`` (order of :data:`WORST_VARIABLES`) at grid points ``pts`` ``(k, 3)``."""
    return _worst_values(robot, sources, grid_poses(robot, pts, orientation), gap)


def _worst_values(robot, sources, poses: np.ndarray, gap: float) -> np.ndarray:
    """:func:`_worst_block` at poses ``(k, 6)`` (NaN rows: no pose)."""
    ok = np.all(np.isfinite(poses), axis=-1)
    out = np.full((len(poses), len(WORST_VARIABLES)), np.nan)
    if np.any(ok):
        b = spatial_pose_errors(robot, sources, poses[ok], gap=gap, strict=False, details=False)
        out[ok] = np.column_stack([b.components, b.dp_upper, b.dp_lower, b.dtheta_upper, b.dtheta_lower])
    return out


def _draw_variables(dims: list[int], n: int, seed, distribution: str, sigma: float) -> np.ndarray:
    """The sources' variables ``(n, sum d_s)`` drawn as :func:`~pmaccuracy.accuracy.spatial_statistics.sample_twists`
    draws them (the same numbers for the same ``seed``), columns grouped by dimension ``d`` (ascending), each
    group the sources of that ``d`` in their order."""
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    counts = {d: dims.count(d) for d in sorted(set(dims))}
    parts = {d: np.empty((n, k * d)) for d, k in counts.items()}
    for start in range(0, n, CHUNK):
        m = min(CHUNK, n - start)
        for d, k in counts.items():
            parts[d][start:start + m] = sample_unit_set(rng, d, m * k, distribution, sigma).reshape(m, k * d)
    return np.concatenate([parts[d] for d in counts], axis=1) if parts else np.zeros((n, 0))


def _stats_names(pct, thr) -> dict[str, str]:
    """Variables of a percentile map (besides the worst case) -> unit."""
    names = {}
    for q in MAP_QUANTITIES:
        names[f"{q}_std"] = _UNITS[q]
        names[f"{q}_rss"] = _UNITS[q]
        for p in pct:
            names[f"{q}_p{p:g}"] = _UNITS[q]
        if q in thr:
            names[f"{q}_exceed"] = "1"
    return names


def _stats_block(robot, sources, pts: np.ndarray, orientation, gap: float, X: np.ndarray, variances: np.ndarray,
                 pct: tuple, thr: dict) -> np.ndarray:
    """A percentile map's variables at grid points ``pts`` ``(k, 3)``: the worst case (:func:`_worst_block`),
    then :func:`_stats_names` in order, then each percentile's order-statistic half-width (module text)."""
    poses = grid_poses(robot, pts, orientation)
    worst = _worst_values(robot, sources, poses, gap)
    names = _stats_names(pct, thr)
    stats = np.full((len(pts), len(names) + len(MAP_QUANTITIES) * len(pct)), np.nan)
    ok = np.all(np.isfinite(poses), axis=-1) & np.isfinite(worst[:, 0])
    if np.any(ok):
        _, info = error_sources_at(robot, sources, poses[ok], strict=False, keep=True)
        kept = info["sources"]
        dims = [_DIMS[s.shape] for s in kept]
        # the blocks M_s (k, 6, d) side by side in the order of the drawn variables (grouped by d)
        order = [i for d in sorted(set(dims)) for i in range(len(kept)) if dims[i] == d]
        M = (np.concatenate([kept[i].matrix for i in order], axis=-1) if kept
             else np.zeros((int(ok.sum()), 6, 0)))
        T = np.einsum("sk,pik->spi", X, M)               # (samples, k, 6) twists
        values = {**{c: T[..., i] for i, c in enumerate(COMPONENTS)},
                  "dp": np.linalg.norm(T[..., :3], axis=-1), "dtheta": np.linalg.norm(T[..., 3:], axis=-1)}
        var = np.einsum("pik,k->pi", M * M, variances)     # the diagonal of the exact covariance (k, 6)
        rss = {**{c: np.sqrt(var[:, i]) for i, c in enumerate(COMPONENTS)},
               "dp": np.sqrt(var[:, :3].sum(axis=1)), "dtheta": np.sqrt(var[:, 3:].sum(axis=1))}
        cols, half = {}, []
        for q in MAP_QUANTITIES:
            st = sample_statistics(values[q], percentiles=pct, thresholds=thr.get(q))
            cols[f"{q}_std"], cols[f"{q}_rss"] = st["std"], rss[q]
            for p in pct:
                cols[f"{q}_p{p:g}"] = st[f"p{p:g}"]
                half.append(0.5 * (st[f"p{p:g}_hi"] - st[f"p{p:g}_lo"]))
            if q in thr:
                cols[f"{q}_exceed"] = st["exceed"]
        stats[ok] = np.column_stack([cols[name] for name in names] + half)
    return np.concatenate([worst, stats], axis=1)


# ------------------------------------------------------------------------------------------------ the engine
def _run_block(kernel, inside, m: int, robot, sources, pts: np.ndarray, orientation, gap: float, *args
               ) -> np.ndarray:
    """One block of grid points ``(k, 3)``: the workspace's membership, then ``kernel`` at the inside points;
    ``(k, m)`` columns, NaN outside (one Dask task)."""
    ok = np.asarray(inside(pts), dtype=bool)
    out = np.full((len(pts), m), np.nan)
    if np.any(ok):
        out[ok] = kernel(robot, sources, pts[ok], orientation, gap, *args)
    return out


class _Plan:
    """A map to compute: its grid, kernel and variables (internal). The grid is the one of
    :func:`~pmaccuracy.kinematics.spatial_workspace.spatial_workspace` (``n`` cell centres per axis of its
    box); its membership is evaluated block by block with the errors, never for the whole grid at once."""

    def __init__(self, robot, sources, n, orientation, gap, kernel, kernel_args, names, extra, attrs):
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
            raise ConfigError(f"the grid needs a whole number >= 2 of points per axis, got {n!r}", key="n")
        if not (isinstance(gap, (int, float)) and 0 < gap < 1):
            raise ConfigError(f"gap must be a fraction in (0, 1), got {gap!r}", key="gap")
        if sources.architecture != robot.architecture:
            raise ConfigError(f"the error sources are of a {sources.architecture}, the robot a "
                              f"{robot.architecture}", key="sources")
        if orientation is not None:
            orientation = np.asarray(orientation, dtype=float)
        self.robot, self.sources, self.orientation, self.gap = robot, sources, orientation, gap
        wb = workspace_box(robot, orientation)
        self.inside = wb.inside
        self.axes, self.dims, self.units = cell_centres(wb.box, (n, n, n)), wb.names, wb.units
        self.shape = (int(n),) * 3
        self.kernel, self.kernel_args = kernel, kernel_args
        self.names, self.extra = names, extra       # variables -> units; trailing kernel columns (not stored)
        self.attrs = {"robot": robot.name, "architecture": robot.architecture, "clearances": sources.name,
                      "workspace": wb.kind, "gap": gap, **attrs}

    def slabs(self) -> list[slice]:
        """The partition of the grid: slabs of whole planes of the first axis, about :data:`ZARR_POINTS` grid
        points each (a Zarr chunk; the in-memory map is computed in the same slabs and blocks, so both give
        the same numbers to the last bit)."""
        n0, n1, n2 = self.shape
        planes = max(1, ZARR_POINTS // (n1 * n2))
        return [slice(i0, min(i0 + planes, n0)) for i0 in range(0, n0, planes)]

    def points(self, index: slice) -> np.ndarray:
        """The grid points ``(k, 3)`` of planes ``index`` of the first axis, in C order."""
        g = np.meshgrid(self.axes[0][index], self.axes[1], self.axes[2], indexing="ij")
        return np.stack(g, axis=-1).reshape(-1, 3)

    def compute(self, slabs: list[slice], block: int, use_dask) -> list[np.ndarray]:
        """The columns ``(planes, n, n, m)`` of each slab, in blocks of ``block`` grid points (Dask tasks with
        ``use_dask``)."""
        m = len(self.names) + self.extra
        jobs = []
        for k, index in enumerate(slabs):
            pts = self.points(index)
            jobs += [(k, pts[s:s + block]) for s in range(0, len(pts), block)]
        head = (self.kernel, self.inside, m, self.robot, self.sources)
        if use_dask is False or use_dask is None:
            results = [_run_block(*head, pts, self.orientation, self.gap, *self.kernel_args) for _, pts in jobs]
        else:
            dask = _dask()
            task = dask.delayed(_run_block, pure=True)
            shared = [dask.delayed(a, pure=True) if isinstance(a, np.ndarray) else a for a in self.kernel_args]
            results = dask.compute(*[task(*head, pts, self.orientation, self.gap, *shared) for _, pts in jobs],
                                   scheduler=_scheduler(use_dask))
        out = [[] for _ in slabs]
        for (k, _), r in zip(jobs, results):
            out[k].append(r)
        return [np.concatenate(o).reshape((index.stop - index.start,) + self.shape[1:] + (m,))
                for o, index in zip(out, slabs)]

    def dataset(self, columns: np.ndarray, coords: dict | None) -> xr.Dataset:
        """The variables of ``columns`` ``(..., m)`` (the trailing ``extra`` columns left out)."""
        return xr.Dataset({name: (self.dims, np.ascontiguousarray(columns[..., v]), {"units": unit})
                           for v, (name, unit) in enumerate(self.names.items())}, coords=coords)

    def coords(self) -> dict:
        return {d: (d, a, {"units": u}) for d, a, u in zip(self.dims, self.axes, self.units)}

    def in_memory(self, block: int, use_dask) -> xr.Dataset:
        """The whole map, slab after slab (each slab's blocks as Dask tasks with ``use_dask``): memory holds the
        result arrays and one slab's columns."""
        arrays = {name: np.empty(self.shape) for name in self.names}
        largest = None
        for index in self.slabs():
            columns = self.compute([index], block, use_dask)[0]
            for v, name in enumerate(self.names):
                arrays[name][index] = columns[..., v]
            top = np.fmax.reduce(columns.reshape(-1, columns.shape[-1]), axis=0)
            largest = top if largest is None else np.fmax(largest, top)
        ds = xr.Dataset({name: (self.dims, a, {"units": unit}) for (name, unit), a in
                         zip(self.names.items(), arrays.values())}, coords=self.coords())
        ds.attrs.update(self.attrs)
        self.finish(ds.attrs, largest)
        return ds

    def finish(self, attrs: dict, largest: np.ndarray) -> None:
        """Attributes from the trailing columns' largest values ``largest`` ``(m,)``: each percentile's largest
        Monte Carlo half-width."""
        keys = attrs.pop("_percentile_keys", None)
        for k, key in enumerate(keys or ()):
            attrs[f"{key}_error"] = float(largest[len(self.names) + k])


def _dask():
    try:
        return require("dask")
    except ImportError:  # pragma: no cover - depends on the installation
        raise ConfigError("use_dask needs Dask: pip install 'pmaccuracy[dask]'", key="use_dask") from None


def _scheduler(use_dask):
    """``True``: the active scheduler (threads by default); a ``dask.distributed.Client``: that client."""
    if use_dask is True:
        return None
    if hasattr(use_dask, "get") and hasattr(use_dask, "submit"):
        return use_dask
    raise ConfigError(f"use_dask must be True, False or a dask.distributed Client, got {use_dask!r}",
                      key="use_dask")


def _orientation_angle(orientation) -> float:
    """The rotation angle (rad) of a 6-UPS's rotation vector ``(3,)``, for the degree-slip warning."""
    try:
        return float(np.linalg.norm(np.asarray(orientation, dtype=float)))
    except (TypeError, ValueError):
        raise ConfigError(f"must be a rotation vector of 3 numbers (rad), got {orientation!r}",
                          key="orientation") from None


def _check_block(block) -> int:
    if isinstance(block, bool) or not isinstance(block, (int, np.integer)) or block < 1:
        raise ConfigError(f"the block size must be a positive whole number, got {block!r}", key="block")
    return int(block)


def _worst_plan(robot, sources, n, orientation, gap) -> _Plan:
    return _Plan(robot, sources, n, orientation, gap, _worst_block, (), dict(WORST_VARIABLES), 0,
                 {"description": "worst first-order pose errors (exact components; |dp|, |dtheta| certified "
                                 "upper bounds); NaN outside the workspace or near a singularity"})


def _percentile_plan(robot, sources, n, orientation, gap, samples, seed, distribution, sigma, percentiles,
                     thresholds) -> _Plan:
    n_samples, pct, thr_deg = _check_inputs(samples, distribution, sigma, percentiles, thresholds)
    thr = {_THRESHOLD_KEYS[k]: (math.radians(v) if k.endswith("_deg") else v) for k, v in thr_deg.items()}
    # the sources' structure (one Source per variable group) at the reference pose: their dimensions
    _, info = error_sources_at(robot, sources, reference_pose(robot), strict=False, keep=True)
    dims = [_DIMS[s.shape] for s in info["sources"]]
    X = _draw_variables(dims, n_samples, seed, distribution, sigma)
    variances = np.concatenate([np.full(d, unit_variance(d, distribution, sigma))
                                for d in sorted(set(dims)) for _ in range(dims.count(d))]) if dims else np.zeros(0)
    names = {**WORST_VARIABLES, **_stats_names(pct, thr)}
    label = distribution if distribution == "uniform" else f"normal(sigma={sigma:g})"
    attrs = {"description": "percentiles of the first-order pose error (Monte Carlo, the same source states at "
                            "every point), its analytic RSS and worst case; NaN outside the workspace or near a "
                            "singularity",
             "distribution": label, "samples": n_samples, "seed": "none" if seed is None else str(seed),
             "percentile_interval": "95 % order-statistic interval, ranks n p -+ 1.96 sqrt(n p (1 - p))",
             "_percentile_keys": [f"{q}_p{p:g}" for q in MAP_QUANTITIES for p in pct]}
    for q, t in thr.items():
        attrs[f"{q}_threshold"] = t
    return _Plan(robot, sources, n, orientation, gap, _stats_block, (X, variances, pct, thr), names,
                 len(MAP_QUANTITIES) * len(pct), attrs)


# ------------------------------------------------------------------------------------------------ public
def spatial_error_map(robot: SpatialManipulator, sources: SpatialErrorSources, *, n: int = 30, orientation=None,
                      gap: float = DEFAULT_GAP, use_dask=False, block: int = BLOCK) -> xr.Dataset:
    """The worst first-order errors over the workspace's ``n``-point-per-axis grid (module text): an
    ``xarray.Dataset`` of ``(n, n, n)`` variables (mm, rad) over the grid's three coordinates.

    ``orientation``: a 6-UPS's rotation vector (rad, default 0). ``use_dask``: ``True`` (blocks of ``block``
    grid points as Dask tasks on the active scheduler) or a ``dask.distributed.Client``; the same numbers as
    without. Raises :class:`~pmaccuracy.errors.ConfigError` naming ``n``, ``gap``, ``block``, ``use_dask`` or
    ``sources`` (of another architecture).

    >>> import pmaccuracy as pm
    >>> robot = pm.load_robot("upu_3")
    >>> ds = spatial_error_map(robot, SpatialErrorSources.load("upu_typical", robot), n=8)
    >>> sorted(ds.sizes.items()), float(ds.dp_max.max()) > 0
    ([('x', 8), ('y', 8), ('z', 8)], True)
    """
    if orientation is not None:
        check_angle_values(_orientation_angle(orientation), "orientation (rotation vector)")
    block = _check_block(block)
    plan = _worst_plan(robot, sources, n, orientation, gap)
    check_spatial_fits_in_memory(n, len(plan.names))
    return plan.in_memory(block, use_dask)


def spatial_percentile_map(robot: SpatialManipulator, sources: SpatialErrorSources, *, n: int = 20,
                           orientation=None, samples: int = 10_000, seed: int | None = 0,
                           distribution: str = "uniform", sigma: float = DEFAULT_SIGMA, percentiles=(95.0,),
                           thresholds: dict[str, float] | None = None, gap: float = DEFAULT_GAP, use_dask=False,
                           block: int | None = None) -> xr.Dataset:
    """Percentile maps of a spatial robot over its workspace's ``n``-point-per-axis grid (module text): the
    ``p``-th percentile of ``|q|`` (``q_p{p}``), ``q_std``, ``q_rss``, ``q_exceed`` (with a threshold) and the
    worst case ``q_max`` of :func:`spatial_error_map`, for q in dx, dy, dz, dp (mm) and drx, dry, drz, dtheta
    (rad); ``(n, n, n)`` arrays, NaN outside the workspace.

    ``samples`` (>= 1000) source states drawn once with ``seed`` under ``distribution`` (``uniform`` or
    ``normal``: truncated isotropic Gaussian of standard deviation ``sigma`` half-widths), the same at every
    grid point (the numbers of :func:`~pmaccuracy.accuracy.spatial_statistics.spatial_pose_statistics` at the
    point with the same seed). ``thresholds``: ``{"dx" | "dy" | "dz" | "dp": mm, "drx_deg" | "dry_deg" |
    "drz_deg" | "dtheta_deg": deg}``. ``block``: grid points per block (default: as many as hold
    :data:`MAX_VALUES` twist values); ``use_dask`` as in :func:`spatial_error_map`.

    >>> import pmaccuracy as pm
    >>> robot = pm.load_robot("upu_3")
    >>> ds = spatial_percentile_map(robot, SpatialErrorSources.load("upu_typical", robot), n=5, samples=1000)
    >>> bool((ds.dp_p95 <= ds.dp_max).sum() == ds.dp_max.notnull().sum())
    True
    """
    if orientation is not None:
        check_angle_values(_orientation_angle(orientation), "orientation (rotation vector)")
    plan = _percentile_plan(robot, sources, n, orientation, gap, samples, seed, distribution, sigma, percentiles,
                            thresholds)
    block = _check_block(_percentile_block(samples) if block is None else block)
    check_spatial_fits_in_memory(n, len(plan.names))
    return plan.in_memory(block, use_dask)


def _percentile_block(samples: int) -> int:
    return max(1, MAX_VALUES // (6 * int(samples)))


def spatial_map_nbytes(n: int, n_variables: int) -> int:
    """Bytes of an ``n x n x n`` map of ``n_variables`` float64 variables."""
    return 8 * n_variables * n ** 3


#: Memory of an in-memory map beyond its result arrays, bytes: one slab's columns and one block's temporaries
#: (measured with tracemalloc: a 3-UPU's worst-case map at n = 80 peaked at 216 MB with 41 MB of results,
#: default blocks; a block of 4096 points: 120 MB).
WORKING_BYTES = 256 * 10**6


def check_spatial_fits_in_memory(n: int, n_variables: int = len(WORST_VARIABLES)) -> None:
    """Refuse (:class:`~pmaccuracy.errors.ConfigError`, key ``grid``) an in-memory ``n x n x n`` map whose peak,
    ``MEMORY_FACTOR`` x its ``n_variables`` float64 arrays plus :data:`WORKING_BYTES`, exceeds the available
    memory; the message says to write a ``.zarr`` store."""
    need = MEMORY_FACTOR * spatial_map_nbytes(n, n_variables) + WORKING_BYTES
    free = available_memory()
    if free is not None and need > free:
        raise ConfigError(f"a {n} x {n} x {n} spatial map needs about {format_bytes(need)} of memory but only "
                          f"{format_bytes(free)} is available: write it to a Zarr store instead (--out FILE.zarr)",
                          key="grid")


def write_spatial_map(path: str | Path, robot: SpatialManipulator, sources: SpatialErrorSources, *, n: int = 30,
                      orientation=None, gap: float = DEFAULT_GAP, percentiles=None, samples: int = 10_000,
                      seed: int | None = 0, distribution: str = "uniform", sigma: float = DEFAULT_SIGMA,
                      thresholds: dict[str, float] | None = None, use_dask=False, block: int | None = None,
                      workers: int | None = None) -> dict[str, list[float]]:
    """Write the map of :func:`spatial_error_map` (``percentiles=None``) or of :func:`spatial_percentile_map`
    (``percentiles`` a list, the other arguments as there) to ``path``: a Zarr store (``.zarr``, streamed: slabs
    of whole planes of the first axis, :data:`ZARR_POINTS` points a chunk, each computed and written in place;
    Dask tasks with ``use_dask``, ``workers`` threads of the local scheduler) or NetCDF (``.nc``, computed in
    memory, refused by :func:`check_spatial_fits_in_memory` when it would not fit). ``xarray.open_zarr`` reads
    the store back as the in-memory map.

    Returns ``{variable: [min, max]}`` over the map (NaN-ignoring; mm, rad, 1).
    """
    if orientation is not None:
        check_angle_values(_orientation_angle(orientation), "orientation (rotation vector)")
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".zarr", ".nc"):
        raise ConfigError(f"a spatial map is written as .nc or .zarr, got {path.suffix or 'no extension'!r}",
                          source=str(path))
    if percentiles is None:
        plan = _worst_plan(robot, sources, n, orientation, gap)
        block = _check_block(BLOCK if block is None else block)
    else:
        plan = _percentile_plan(robot, sources, n, orientation, gap, samples, seed, distribution, sigma,
                                percentiles, thresholds)
        block = _check_block(_percentile_block(samples) if block is None else block)
    if suffix == ".nc":
        check_spatial_fits_in_memory(n, len(plan.names))
        ds = plan.in_memory(block, use_dask if not workers else True)
        ds.attrs.update({k: (v if isinstance(v, (str, int, float)) else str(v)) for k, v in ds.attrs.items()})
        ds.to_netcdf(path)
        return _ranges(ds)
    return _write_zarr(plan, path, block, use_dask, workers)


def _ranges(ds: xr.Dataset) -> dict[str, list[float]]:
    out = {}
    for name, var in ds.data_vars.items():
        v = var.values
        finite = np.isfinite(v)
        out[name] = [float(v[finite].min()), float(v[finite].max())] if finite.any() else [math.nan, math.nan]
    return out


def _write_zarr(plan: _Plan, path: Path, block: int, use_dask, workers) -> dict[str, list[float]]:
    dask = require("dask")
    da = require("dask.array")
    shape = plan.shape
    slabs = plan.slabs()
    chunks = (slabs[0].stop,) + shape[1:]
    template = xr.Dataset({name: (plan.dims, da.full(shape, np.nan, chunks=chunks), {"units": unit})
                           for name, unit in plan.names.items()}, coords=plan.coords())
    attrs = dict(plan.attrs)
    keys = attrs.pop("_percentile_keys", None)
    template.attrs.update(attrs)
    encoding = {name: {"chunks": chunks} for name in plan.names}

    def slab(index: slice) -> np.ndarray:
        """Compute planes ``index`` and write them in place; returns the slab's minima and maxima ``(2, m)``
        (NaN-ignoring)."""
        columns = plan.compute([index], block, False)[0]
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=".*[Cc]onsolidated metadata.*")
            plan.dataset(columns, None).to_zarr(path, region={plan.dims[0]: index})
        flat = columns.reshape(-1, columns.shape[-1])
        return np.stack([np.fmin.reduce(flat, axis=0), np.fmax.reduce(flat, axis=0)])

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*[Cc]onsolidated metadata.*")
        template.to_zarr(path, mode="w", compute=False, encoding=encoding)   # metadata and coordinates
    if use_dask is False and not workers:
        records = [slab(index) for index in slabs]
    else:
        scheduler = _scheduler(True if use_dask is False else use_dask)
        task = dask.delayed(slab, pure=False)
        if scheduler is None:
            records = dask.compute(*[task(index) for index in slabs], scheduler="threads",
                                   num_workers=workers or os.cpu_count() or 1)
        else:
            records = dask.compute(*[task(index) for index in slabs], scheduler=scheduler)
    rec = np.array(records)
    lo, hi = np.fmin.reduce(rec[:, 0], axis=0), np.fmax.reduce(rec[:, 1], axis=0)
    if keys:   # the Monte Carlo half-widths' largest values, as attributes of the store
        zarr = require("zarr")
        group = zarr.open_group(str(path), mode="r+")
        extra = {"_percentile_keys": keys}
        plan.finish(extra, hi)
        group.attrs.update(extra)
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=".*[Cc]onsolidated metadata.*")
            zarr.consolidate_metadata(str(path))
    return {name: [float(lo[v]), float(hi[v])] for v, name in enumerate(plan.names)}
