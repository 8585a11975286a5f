"""Maximum pose errors over the constant-orientation workspace (paper Sec. 6, Figs. 9-12).

:func:`error_map` evaluates the exact bounds of :func:`pmaccuracy.accuracy.bounds.max_pose_errors`
on a regular x-y grid at one or more orientations and returns an
``xarray.Dataset`` with dims ``(phi, y, x)``:

* coordinates ``x``, ``y`` in mm (one grid spanning the bounding box of every
  requested workspace) and ``phi`` in **degrees**;
* variables ``dx_max``, ``dy_max``, ``dp_max`` (mm) and ``dphi_max`` (deg), NaN
  at grid points outside that orientation's workspace (joint ranges);
* attributes: robot and clearance set (name and full TOML text), package
  version, method.

Memory. :func:`error_map` preallocates the four result arrays and fills them
block by block (bands of about ``chunk_size`` grid points), so its peak memory is
the dataset plus one block's temporaries; with ``use_dask=True`` the blocks are
Dask tasks computed a few at a time on whatever scheduler is active (threads by
default, or a ``dask.distributed.Client`` the caller created, on a cluster
included). It refuses (:class:`~pmaccuracy.errors.ConfigError`) a map whose
result would not fit in the available memory.

Files without the map in memory. :func:`write_map` computes the same map straight into a NetCDF or CSV
file (the bytes :func:`save_map` writes): each block goes to its place in the file as soon as it is
computed, so memory holds one block whatever the grid; the ``map`` command writes ``.nc`` and ``.csv`` this
way.

Maps larger than memory. :func:`write_zarr_map` streams the same map into a
Zarr store chunked along ``(phi, y, x)``: every chunk is one Dask task that
computes its tile and writes it in place (a region write), so memory holds a
few tiles whatever the grid. After each tile the task records its statistics
(inside points, minima, maxima) in the store's ``_progress/chunks`` array; a
run that was interrupted resumes where it stopped, recomputing no finished tile.
The store opens with ``xarray.open_zarr`` and carries the NetCDF output's
attributes; ``_progress`` is a sub-group that xarray does not show.
"""

from __future__ import annotations

import os
import struct
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import xarray as xr

from .bounds import bounds_or_nan
from .certified import QUANTITIES, certified_pose_errors
from .regions import Disc, Polygon, Rect, Shape
from ..model.clearances import ClearanceSet
from ..model.sources import ErrorSources
from ..errors import ConfigError, EmptyWorkspaceError
from ..model.manipulator import Manipulator, round_trip_degrees
from ..model.plausibility import PlausibilityWarning, check_orientations
from ..kinematics import DEFAULT_MAX_CONDITION, require_regular
from ..kinematics.workspace import constant_orientation_workspace
from .._optional import require
from .. import __version__
from ..io.csvio import float_table
from ..io.resolve import clearances_arg, robot_arg

#: Map variables: name -> (units, long name).
MAP_VARIABLES = {
    "dx_max": ("mm", "maximum position error along x (Eq. 21)"),
    "dy_max": ("mm", "maximum position error along y (Eq. 21)"),
    "dphi_max": ("deg", "maximum orientation error (Eq. 21)"),
    "dp_max": ("mm", "maximum position error magnitude (Eq. 22)"),
}
#: Grid points per block of the in-memory map (its temporaries are about 0.3 kB per point: ~20 MB).
DEFAULT_CHUNK = 1 << 16
#: Tile side of a Zarr map along y and x (one orientation per tile): 4 x 8 MB of results per tile.
DEFAULT_ZARR_TILE = 1024
#: Bytes per grid point of a map: four float64 variables.
BYTES_PER_POINT = 8 * len(MAP_VARIABLES)
#: Peak memory of an in-memory map relative to its dataset (measured by benchmarks/bench_maps.py and
#: tests/accuracy/test_maps.py), used to refuse maps that would not fit.
MEMORY_FACTOR = 1.3


def map_grid(robot: Manipulator, phis: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Grid coordinates x, y ``(n,)`` (mm) spanning the bounding box of every workspace at ``phis`` (rad).

    Raises :class:`EmptyWorkspaceError` if one of the orientations has no workspace.
    """
    if n < 2:
        raise ConfigError(f"the grid needs at least 2 points per axis, got {n}", key="grid")
    boxes = []
    for phi in np.atleast_1d(phis):
        ws = constant_orientation_workspace(robot, float(phi)).require_nonempty()
        boxes.append(ws.bounds)
    boxes = np.array(boxes)  # (k, 2, 2): [[xmin, xmax], [ymin, ymax]]
    x = np.linspace(boxes[:, 0, 0].min(), boxes[:, 0, 1].max(), n)
    y = np.linspace(boxes[:, 1, 0].min(), boxes[:, 1, 1].max(), n)
    return x, y


def _rows_block(robot: Manipulator, clearances: ClearanceSet, x: np.ndarray, y_rows: np.ndarray, phi: float,
                max_condition: float) -> np.ndarray:
    """One block of a map: grid rows ``y_rows`` at orientation ``phi`` (rad) -> ``(rows, len(x), 4)``.

    Values ``[dx_max mm, dy_max mm, dphi_max deg, dp_max mm]``, NaN where the
    pose is outside the joint ranges or near a singularity (other architectures
    than the 3-PPR have singular curves inside their workspaces). The block builds its own poses from the
    grid vectors, so a Dask task carries only two short vectors (picklable for
    dask.distributed).
    """
    X, Y = np.meshgrid(x, y_rows)
    poses = np.stack([X.ravel(), Y.ravel(), np.full(X.size, phi)], axis=-1)
    return bounds_or_nan(robot, clearances, poses, max_condition).reshape(X.shape + (4,))


def _as_sources(clearances):
    """Per-joint :class:`~pmaccuracy.model.sources.ErrorSources` of a map's clearances (the kernel's form)."""
    return clearances if isinstance(clearances, ErrorSources) else ErrorSources.from_clearance_set(clearances)


def _fill_rows(robot: Manipulator, clearances, x: np.ndarray, y_rows: np.ndarray, phi: float,
               max_condition: float, out: list[np.ndarray]) -> None:
    """:func:`_rows_block` written straight into ``out``: four C-contiguous ``(len(y_rows), len(x))`` arrays (a
    map's final arrays, or a buffer reused from band to band), in the order of :data:`MAP_VARIABLES`;
    ``clearances`` best already as :func:`_as_sources`."""
    X, Y = np.meshgrid(x, y_rows)
    poses = np.stack([X.ravel(), Y.ravel(), np.full(X.size, phi)], axis=-1)
    bounds_or_nan(robot, clearances, poses, max_condition, out=out)


def map_nbytes(n_phi: int, n: int) -> int:
    """Bytes of the four float64 result arrays of an ``n_phi x n x n`` map."""
    return BYTES_PER_POINT * n_phi * n * n


def available_memory() -> int | None:
    """Memory the system can give this process now, in bytes (``MemAvailable`` on Linux); ``None`` if unknown."""
    try:
        import psutil  # a dependency of dask.distributed; optional here

        return int(psutil.virtual_memory().available)
    except ImportError:
        pass
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def format_bytes(nbytes: float) -> str:
    """``1.47 GB`` or ``30.6 MB``."""
    return f"{nbytes / 1e9:.3g} GB" if nbytes >= 1e8 else f"{nbytes / 1e6:.3g} MB"


def check_fits_in_memory(n_phi: int, n: int) -> None:
    """Refuse (ConfigError) an in-memory map whose peak (``MEMORY_FACTOR`` x its dataset) exceeds free memory."""
    need = MEMORY_FACTOR * map_nbytes(n_phi, n)
    free = available_memory()
    if free is not None and need > free:
        raise ConfigError(f"a {n_phi} x {n} x {n} map needs about {format_bytes(need)} of memory but only "
                          f"{format_bytes(free)} is available: write it to a Zarr store instead (--out FILE.zarr)",
                          key="grid")


def estimate_seconds(robot: Manipulator, clearances: ClearanceSet, phis: np.ndarray, x: np.ndarray, y: np.ndarray,
                     max_condition: float = DEFAULT_MAX_CONDITION, workers: int = 1) -> float:
    """Rough single-run time of a whole map, s: a sparse sub-grid of about 1000 points per orientation, timed.

    Small batches carry more overhead per point than the real blocks, so the
    estimate errs on the long side.
    """
    sx, sy = max(1, len(x) // 32), max(1, len(y) // 32)
    t0 = time.perf_counter()
    points = 0
    for phi in phis:
        _rows_block(robot, clearances, x[::sx], y[::sy], float(phi), max_condition)
        points += len(x[::sx]) * len(y[::sy])
    per_point = (time.perf_counter() - t0) / points
    return per_point * len(phis) * len(x) * len(y) / max(1, workers)


def _prepare(robot, clearances, phis, n: int, max_condition: float):
    """Load and check the inputs of a map; returns ``robot, clearances, phis (rad), x, y``."""

    robot = robot_arg(robot)
    clearances = clearances_arg(clearances, robot)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        raise ConfigError(f"the grid size must be a whole number, got {n!r}", key="n")
    try:
        phis = np.atleast_1d(np.asarray(phis, dtype=float))
    except (TypeError, ValueError):
        raise ConfigError(f"orientations must be numbers (rad), got {phis!r}", key="phi") from None
    if phis.ndim != 1 or phis.size == 0:
        raise ConfigError(f"orientations must be a number or a non-empty list of numbers (rad), got shape "
                          f"{phis.shape}", key="phis")
    if not np.all(np.isfinite(phis)):
        raise ConfigError("orientations must be finite", key="phi")
    if robot.is_3ppr:  # A depends on phi only: a whole layer is singular or none is
        require_regular(robot, np.column_stack([np.zeros_like(phis), np.zeros_like(phis), phis]), max_condition)
    x, y = map_grid(robot, phis, n)
    return robot, clearances, phis, x, y


def _coords(phis: np.ndarray, x: np.ndarray, y: np.ndarray) -> dict:
    return {"phi": ("phi", np.array([round_trip_degrees(p) for p in phis]),
                    {"units": "deg", "long_name": "platform orientation"}),
            "y": ("y", y, {"units": "mm"}), "x": ("x", x, {"units": "mm"})}


def map_dataset(data_vars: dict, phis: np.ndarray, x: np.ndarray, y: np.ndarray, attrs: dict) -> xr.Dataset:
    """``xr.Dataset(data_vars, coords=_coords(phis, x, y), attrs=attrs)`` of numpy variables ``{name: (dims,
    values, attrs)}``: the same Dataset, built without xarray's probes for dask arrays.

    Built the ordinary way from numpy arrays, a Dataset asks whether each array is a dask array, and the
    first such question of a process imports ``dask`` and ``dask.array`` when they are installed (about
    0.6 s; issue 35). Here each variable is a :class:`xarray.Variable` built on the fast path (the values
    are numpy arrays already) and each coordinate a :class:`pandas.Index`, which xarray takes as it is.
    """
    import pandas as pd   # (xarray's own dependency, imported with it)

    try:
        variables = {name: xr.Variable(dims, np.asarray(values), dict(vattrs), fastpath=True)
                     for name, (dims, values, vattrs) in data_vars.items()}
    except TypeError:     # an xarray without the fast path: the ordinary construction (same Dataset)
        return xr.Dataset(data_vars, coords=_coords(phis, x, y), attrs=attrs)
    coords = {name: xr.Variable(dim, pd.Index(np.asarray(values), name=name), dict(vattrs))
              for name, (dim, values, vattrs) in _coords(phis, x, y).items()}
    return xr.Dataset(variables, coords=coords, attrs=attrs)


def _attrs(robot: Manipulator, clearances: ClearanceSet) -> dict[str, str]:
    """Provenance attributes of a map (every value a string, as NetCDF-3 stores them)."""

    return {"title": f"Maximum pose errors of {robot.name} with clearances {clearances.name}",
            "robot": robot.name, "robot_toml": robot.to_toml(),
            "clearances": clearances.name, "clearances_toml": clearances.to_toml(),
            "method": "exact first-order worst case (zonotope support functions and vertices, Eq. 21-22)",
            "source": f"pmaccuracy {__version__}",
            "reference": "Wu, Bai, Kepler, Caro, ASME J. Mechanisms Robotics 4(4) 041011, 2012"}


def _empty_layer_error(phi: float, n: int) -> EmptyWorkspaceError:
    return EmptyWorkspaceError(f"no point of the {n} x {n} grid lies inside the workspace at phi = "
                               f"{np.degrees(phi):g} deg: use a finer grid")


def error_map(robot: Manipulator | str, clearances: ClearanceSet | str, phis: float | np.ndarray, n: int = 101, *,
              chunk_size: int = DEFAULT_CHUNK, use_dask: bool = False, progress: bool | None = None,
              max_condition: float = DEFAULT_MAX_CONDITION, region: Shape | None = None) -> xr.Dataset:
    """Exact maximum pose errors on an ``n x n`` grid at each orientation, in memory.

    The four result arrays ``(len(phis), n, n)`` are allocated once and filled
    block by block, so the peak memory stays within :data:`MEMORY_FACTOR` times
    the dataset (``4 x 8 x len(phis) x n^2`` bytes) for maps of a few MB and up.

    Parameters
    ----------
    robot, clearances : objects, preset names or TOML paths
    phis : orientation(s) in **radians** (scalar or ``(k,)``)
    n : grid points per axis
    chunk_size : grid points per block at most (blocks are also kept below 1/80 of the map)
    use_dask : compute the blocks as Dask tasks, a few at a time (needs ``pip install pmaccuracy[dask]``)
    progress : show a progress bar; default: only when stderr is a terminal
    region : a shape of :mod:`pmaccuracy.accuracy.regions` (disc, polygon, rectangle; mm) or None (the
        workspace): the grid is cut to the shape's bounding box and the points outside the shape are NaN;
        the attribute ``region`` describes it

    Returns
    -------
    xarray.Dataset with dims ``(phi, y, x)``; ``phi`` coordinate in degrees.

    Raises
    ------
    SingularPoseError : an orientation at or near the parallel singularity (for a
        3-PPR det A depends on phi only, so a whole layer is singular or none is)
    EmptyWorkspaceError : an orientation without workspace
    ConfigError : bad arguments, or a result that would not fit in the available
        memory (use :func:`write_zarr_map`)

    Orientations beyond a full turn warn (:func:`pmaccuracy.model.plausibility.check_orientations`):
    ``error_map(robot, cl, 15.0)`` is almost surely 15 deg typed as radians.
    """
    check_orientations(phis, "phis")
    if chunk_size < 1:
        raise ConfigError(f"chunk size must be positive, got {chunk_size}", key="chunk_size")
    robot, clearances, phis, x, y = _prepare(robot, clearances, phis, n, max_condition)
    check_fits_in_memory(len(phis), n)
    attrs = _attrs(robot, clearances)
    if region is not None:
        if not isinstance(region, (Disc, Polygon, Rect)):
            raise ConfigError(f"expected a Disc, Polygon or Rect of pmaccuracy.accuracy.regions, got {region!r}",
                              key="region")
        x, y = _cut(region, x, y, n)
        attrs["region"] = f"{region.describe()}: grid cut to its bounding box, NaN outside it"
    values = {name: np.empty((len(phis), len(y), len(x))) for name in MAP_VARIABLES}
    _evaluate(robot, clearances, x, y, phis, chunk_size, use_dask, progress, max_condition, values)
    if region is not None:
        outside = ~region.contains(*np.meshgrid(x, y))
        for name in MAP_VARIABLES:
            values[name][:, outside] = np.nan
    for k, phi in enumerate(phis):
        if not np.isfinite(values["dx_max"][k]).any():
            if region is not None:
                raise EmptyWorkspaceError(f"no point of the {n} x {n} grid lies in both {region.describe()} and "
                                          f"the workspace at phi = {np.degrees(phi):g} deg")
            raise _empty_layer_error(phi, n)
    data_vars = {name: (("phi", "y", "x"), values[name], {"units": units, "long_name": long_name})
                 for name, (units, long_name) in MAP_VARIABLES.items()}
    return map_dataset(data_vars, phis, x, y, attrs)


#: Certified map variables: name -> (units, long name); the bounds keep the names of :data:`MAP_VARIABLES`.
CERTIFIED_VARIABLES = {
    "dx_max": ("mm", "certified upper bound of the exact maximum |dx| over the error set"),
    "dy_max": ("mm", "certified upper bound of the exact maximum |dy| over the error set"),
    "dphi_max": ("deg", "certified upper bound of the exact maximum |dphi| over the error set"),
    "dp_max": ("mm", "certified upper bound of the exact maximum |dp| over the error set"),
    "dx_gap": ("1", "(certified bound - best feasible value) / best feasible value of |dx|"),
    "dy_gap": ("1", "(certified bound - best feasible value) / best feasible value of |dy|"),
    "dphi_gap": ("1", "(certified bound - best feasible value) / best feasible value of |dphi|"),
    "dp_gap": ("1", "(certified bound - best feasible value) / best feasible value of |dp|"),
}
#: Grid points per band of a certified map (one batch of :func:`certified_pose_errors`; several bands a layer, so
#: ``use_dask`` spreads them).
CERTIFIED_CHUNK = 2048


class _CertifiedKernel:
    """A band of a certified map (picklable for dask.distributed): ``(rows, len(x), 8)`` = the upper bounds
    ``[dx mm, dy mm, dphi deg, dp mm]`` and their gaps, NaN outside the joint ranges, near a singularity (as
    :func:`_rows_block`) or where the bound is not certified."""

    def __init__(self, split_gap: float, max_pieces: int, split: int = 2, refine: bool = True):
        self.split_gap, self.max_pieces, self.split, self.refine = split_gap, max_pieces, split, refine

    def __call__(self, robot, clearances, x, y_rows, phi, max_condition):
        X, Y = np.meshgrid(x, y_rows)
        poses = np.stack([X.ravel(), Y.ravel(), np.full(X.size, phi)], axis=-1)
        out = np.full((poses.shape[0], 8), np.nan)
        ok = np.isfinite(bounds_or_nan(robot, clearances, poses, max_condition)[:, 0])
        if np.any(ok):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", PlausibilityWarning)
                res = certified_pose_errors(robot, clearances, poses[ok], on_failure="nan", split_gap=self.split_gap,
                                            max_pieces=self.max_pieces, split=self.split, refine=self.refine)
            for v, q in enumerate(QUANTITIES):
                out[ok, v] = np.degrees(res.upper[q]) if q == "dphi" else res.upper[q]
                out[ok, 4 + v] = np.where(np.isfinite(res.upper[q]), res.gap[q], np.nan)
        return out.reshape(X.shape + (8,))


def certified_error_map(robot: Manipulator | str, clearances: ClearanceSet | str, phis: float | np.ndarray,
                        n: int = 101, *, chunk_size: int = CERTIFIED_CHUNK, use_dask: bool = False,
                        progress: bool | None = None, max_condition: float = DEFAULT_MAX_CONDITION,
                        region: Shape | None = None, split_gap: float = 0.005, max_pieces: int = 256,
                        split: int = 2, refine: bool = True) -> xr.Dataset:
    """Certified upper bounds of the exact (nonlinear) worst-case pose errors on the grid of :func:`error_map`.

    The same dims ``(phi, y, x)``, coordinates and attributes as :func:`error_map` (``method`` says certified);
    ``dx_max``, ``dy_max``, ``dp_max`` (mm), ``dphi_max`` (deg) are the upper bounds of
    :func:`pmaccuracy.accuracy.certified.certified_pose_errors` (never below the exact maximum over the error
    set) and ``dx_gap`` ... ``dp_gap`` their relative gaps to the best feasible configuration. NaN outside the
    workspace, near a singularity, and where the continuation of the commanded assembly is not certified.
    Computed in bands of about ``chunk_size`` grid points (each one batch; Dask tasks with ``use_dask``);
    ``split_gap``, ``max_pieces``, ``split``, ``refine`` as in ``certified_pose_errors`` (``split=0, max_pieces=1,
    refine=False``: one batched pass, the error set not cut: fast near singular edges, looser there). Other
    arguments as :func:`error_map`.

    >>> ds = certified_error_map("aalborg_3ppr", "case2", 0.0, n=5)
    >>> bool((ds.dx_max >= error_map("aalborg_3ppr", "case2", 0.0, n=5).dx_max).sum() > 0)
    True
    """
    check_orientations(phis, "phis")
    if chunk_size < 1:
        raise ConfigError(f"chunk size must be positive, got {chunk_size}", key="chunk_size")
    robot, clearances, phis, x, y = _prepare(robot, clearances, phis, n, max_condition)
    check_fits_in_memory(2 * len(phis), n)
    attrs = _attrs(robot, clearances)
    attrs["title"] = f"Certified maximum pose errors of {robot.name} with clearances {clearances.name}"
    attrs["method"] = ("certified upper bound of the exact loop closure's worst case (first order plus a rigorous "
                       "remainder bound, pmaccuracy.accuracy.certified) and its gap to the best feasible configuration")
    if region is not None:
        if not isinstance(region, (Disc, Polygon, Rect)):
            raise ConfigError(f"expected a Disc, Polygon or Rect of pmaccuracy.accuracy.regions, got {region!r}",
                              key="region")
        x, y = _cut(region, x, y, n)
        attrs["region"] = f"{region.describe()}: grid cut to its bounding box, NaN outside it"
    values = {name: np.empty((len(phis), len(y), len(x))) for name in CERTIFIED_VARIABLES}
    _evaluate(robot, clearances, x, y, phis, chunk_size, use_dask, progress, max_condition, values,
              kernel=_CertifiedKernel(split_gap, max_pieces, split, refine), rows=max(1, chunk_size // len(x)))
    if region is not None:
        outside = ~region.contains(*np.meshgrid(x, y))
        for name in CERTIFIED_VARIABLES:
            values[name][:, outside] = np.nan
    data_vars = {name: (("phi", "y", "x"), values[name], {"units": units, "long_name": long_name})
                 for name, (units, long_name) in CERTIFIED_VARIABLES.items()}
    return map_dataset(data_vars, phis, x, y, attrs)


def _cut(region: Shape, x: np.ndarray, y: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The grid vectors ``(n,)`` over the part of the workspaces' bounding box in the shape's bounding box."""
    x0, x1, y0, y1 = region.bounds
    lo_x, hi_x, lo_y, hi_y = max(x[0], x0), min(x[-1], x1), max(y[0], y0), min(y[-1], y1)
    if lo_x > hi_x or lo_y > hi_y:
        raise EmptyWorkspaceError(f"{region.describe()} lies outside the workspace")
    return np.linspace(lo_x, hi_x, n), np.linspace(lo_y, hi_y, n)


def _block_rows(n_phi: int, ny: int, nx: int, chunk_size: int) -> int:
    """Grid rows per computed block of an ``n_phi x ny x nx`` map (bands of about ``chunk_size`` points at most)."""
    # A block's temporaries take about 0.9 kB per point, the result 32 B per point: blocks of at most 1/200 of
    # the map keep the peak within MEMORY_FACTOR x the dataset for maps of 20 MB and more; never below 8192
    # points (the kernel's block), where a block's fixed cost (~0.3 ms of numpy calls) would dominate.
    block = min(chunk_size, max(8192, n_phi * ny * nx // 200))
    return max(1, block // nx)


def _evaluate(robot: Manipulator, clearances: ClearanceSet, x: np.ndarray, y: np.ndarray, phis: np.ndarray,
              chunk_size: int, use_dask: bool, progress: bool | None, max_condition: float,
              out: dict[str, np.ndarray], kernel=None, rows: int | None = None) -> None:
    """Fill ``out[name]`` ``(len(phis), len(y), len(x))`` band by band (bands of about ``chunk_size`` points).

    ``kernel(robot, clearances, x, y_rows, phi, max_condition) -> (rows, len(x), len(out))`` computes a band
    (default :func:`_rows_block`); ``rows``: grid rows per band (default :func:`_block_rows`)."""
    show = sys.stderr.isatty() if progress is None else progress
    kernel = _rows_block if kernel is None else kernel
    rows = _block_rows(len(phis), len(y), len(x), chunk_size) if rows is None else rows
    blocks = [(k, j) for k in range(len(phis)) for j in range(0, len(y), rows)]
    names = list(out)

    def store(k: int, j: int, block: np.ndarray) -> None:
        for v, name in enumerate(names):
            out[name][k, j:j + block.shape[0]] = block[..., v]

    from tqdm import tqdm

    bar = tqdm(total=len(blocks), disable=not show, desc="error map", unit="block", file=sys.stderr)
    with bar:
        if not use_dask:
            direct = kernel is _rows_block and names == list(MAP_VARIABLES)
            sources = _as_sources(clearances) if direct else None
            for k, j in blocks:
                if direct:   # written straight into the final arrays: no band copied
                    _fill_rows(robot, sources, x, y[j:j + rows], float(phis[k]), max_condition,
                               [out[name][k, j:j + rows] for name in names])
                else:
                    store(k, j, kernel(robot, clearances, x, y[j:j + rows], float(phis[k]), max_condition))
                bar.update()
            return
        try:
            dask = require("dask")
        except ImportError:  # pragma: no cover - depends on the installation
            raise ConfigError("use_dask needs Dask: pip install 'pmaccuracy[dask]'", key="use_dask") from None
        task = dask.delayed(kernel, pure=True)
        # A window of tasks at a time: every worker stays busy, and at most `window` blocks wait to be copied.
        window = 4 * max(1, os.cpu_count() or 1)
        for start in range(0, len(blocks), window):
            part = blocks[start:start + window]
            results = dask.compute(*[task(robot, clearances, x, y[j:j + rows], float(phis[k]), max_condition)
                                     for k, j in part])
            for (k, j), block in zip(part, results):
                store(k, j, block)
            bar.update(len(part))
            del results


# ------------------------------------------------------------------------------------------------ Zarr
def _signature(robot: Manipulator, clearances: ClearanceSet, phis: np.ndarray, n: int, tile: int,
               max_condition: float) -> dict:
    """What a resumed run must match: inputs, grid and tiling (JSON-able)."""
    return {"robot_toml": robot.to_toml(), "clearances_toml": clearances.to_toml(),
            "phi_rad": [float(p).hex() for p in phis], "n": int(n), "tile": int(tile),
            "max_condition": float(max_condition).hex()}


def _tiles(n: int, tile: int) -> int:
    return -(-n // tile)


def _zarr_tile(path: str, k: int, iy: int, ix: int, tile: int, robot: Manipulator, clearances: ClearanceSet,
               x: np.ndarray, y: np.ndarray, phi: float, block_size: int, max_condition: float) -> int:
    """Compute tile ``(k, iy, ix)`` of a Zarr map, write it in place, then record it as done; returns its inside points.

    The tile covers ``y[iy*tile : (iy+1)*tile]`` and ``x[ix*tile : (ix+1)*tile]``
    at orientation ``k`` (``phi`` rad); it is computed in bands of about
    ``block_size`` points into one ``(4, rows, cols)`` buffer. The record in
    ``_progress/chunks[k, iy, ix]`` is ``[inside points, 4 minima, 4 maxima]``
    (order of :data:`MAP_VARIABLES`; NaN extremes for a tile with no inside point).
    """
    zarr = require("zarr")

    xs = x[ix * tile:(ix + 1) * tile]
    ys = y[iy * tile:(iy + 1) * tile]
    buf = np.empty((len(MAP_VARIABLES), len(ys), len(xs)))
    rows = max(1, block_size // len(xs))
    for j in range(0, len(ys), rows):
        block = _rows_block(robot, clearances, xs, ys[j:j + rows], phi, max_condition)
        buf[:, j:j + block.shape[0]] = np.moveaxis(block, -1, 0)
    region = (k, slice(iy * tile, iy * tile + len(ys)), slice(ix * tile, ix * tile + len(xs)))
    for v, name in enumerate(MAP_VARIABLES):
        zarr.open_array(store=path, path=name, mode="r+")[region] = buf[v]
    finite = np.isfinite(buf[0])
    count = int(finite.sum())
    stats = np.full(1 + 2 * len(MAP_VARIABLES), np.nan)
    stats[0] = count
    if count:
        stats[1:5] = np.nanmin(buf.reshape(len(MAP_VARIABLES), -1), axis=1)
        stats[5:9] = np.nanmax(buf.reshape(len(MAP_VARIABLES), -1), axis=1)
    zarr.open_array(store=path, path="_progress/chunks", mode="r+")[k, iy, ix] = stats
    return count


def _open_progress(path: Path, signature: dict):
    """The progress array of an existing store made with the same inputs, or a ConfigError."""
    zarr = require("zarr")

    try:
        progress = zarr.open_array(store=str(path), path="_progress/chunks", mode="r+")
    except Exception:  # noqa: BLE001 - zarr raises several kinds for "not there"
        raise ConfigError("exists but is not a resumable pmaccuracy Zarr map: remove it or choose another path",
                          source=str(path)) from None
    if dict(progress.attrs).get("signature") != signature:
        raise ConfigError("is a Zarr map of another robot, clearance set, grid or tiling: remove it to start "
                          "afresh or choose another path", source=str(path))
    return progress


def _create_store(path: Path, robot: Manipulator, clearances: ClearanceSet, phis: np.ndarray, x: np.ndarray,
                  y: np.ndarray, tile: int, signature: dict):
    """Write the store's metadata, coordinates and attributes (no data yet) and an empty progress array."""
    da = require("dask.array")
    zarr = require("zarr")

    shape = (len(phis), len(y), len(x))
    chunks = (1, min(tile, len(y)), min(tile, len(x)))
    data_vars = {name: (("phi", "y", "x"), da.full(shape, np.nan, chunks=chunks),
                        {"units": units, "long_name": long_name})
                 for name, (units, long_name) in MAP_VARIABLES.items()}
    template = xr.Dataset(data_vars, coords=_coords(phis, x, y), attrs=_attrs(robot, clearances))
    encoding = {name: {"chunks": chunks, "_FillValue": np.nan} for name in MAP_VARIABLES}
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*[Cc]onsolidated metadata.*")
        template.to_zarr(path, mode="w-", compute=False, encoding=encoding, consolidated=True)
    zarr.open_group(str(path / "_progress"), mode="w")
    progress = zarr.open_array(store=str(path), path="_progress/chunks", mode="w",
                               shape=(len(phis), _tiles(len(y), tile), _tiles(len(x), tile), 9),
                               chunks=(1, 1, 1, 9), dtype="f8", fill_value=np.nan)
    progress.attrs.update({"signature": signature,
                           "description": "per tile [phi, y, x]: inside points, minima and maxima of "
                                          + ", ".join(MAP_VARIABLES) + "; NaN = not computed yet"})
    return progress


def write_zarr_map(path: str | Path, robot: Manipulator | str, clearances: ClearanceSet | str,
                   phis: float | np.ndarray, n: int = 101, *, tile: int = DEFAULT_ZARR_TILE,
                   chunk_size: int = DEFAULT_CHUNK, scheduler: str | None = None, workers: int | None = None,
                   progress: bool | None = None, max_condition: float = DEFAULT_MAX_CONDITION) -> dict:
    """Stream the map of :func:`error_map` into the Zarr store ``path``, tile by tile, resuming an unfinished one.

    Each tile ``(1, tile, tile)`` of ``(phi, y, x)`` is one Dask task that
    computes it (bands of ``chunk_size`` points) and writes it into the store, so
    memory holds about one tile (4 x 8 x tile^2 bytes, 32 MB by default) per worker
    whatever ``n``. Finished tiles are recorded in ``_progress/chunks``; if
    ``path`` already holds an unfinished map of the same inputs, only the missing
    tiles are computed. Open the result with ``xarray.open_zarr(path)``.

    Parameters
    ----------
    scheduler : ``None`` (Dask's local threads), a Dask scheduler name
        (``"threads"``, ``"synchronous"``, ``"processes"``) or the address of a
        ``dask.distributed`` scheduler (``"tcp://host:8786"``); on a cluster every
        worker must see ``path`` (a shared file system)
    workers : threads or processes of a local scheduler (default: one per core)

    Returns
    -------
    ``{"summary": {phi_deg: {var: [min, max]}}`` (as :func:`summarize`),
    ``"tiles": total, "computed": tiles computed by this call, "resumed": tiles found done}``

    Raises
    ------
    ConfigError : ``path`` holds something else, or a map of other inputs
    EmptyWorkspaceError : a layer with no grid point inside its workspace
    """
    check_orientations(phis, "phis")
    dask = require("dask")

    if chunk_size < 1 or tile < 1:
        raise ConfigError("chunk size and tile must be positive", key="chunk_size")
    robot, clearances, phis, x, y = _prepare(robot, clearances, phis, n, max_condition)
    path = Path(path)
    signature = _signature(robot, clearances, phis, n, tile, max_condition)
    if path.exists():
        record = _open_progress(path, signature)
    else:
        record = _create_store(path, robot, clearances, phis, x, y, tile, signature)
    counts = record[..., 0]
    todo = [(k, iy, ix) for k, iy, ix in np.argwhere(np.isnan(counts)).tolist()]
    tiles = int(counts.size)
    task = dask.delayed(_zarr_tile, pure=False)
    tasks = [task(str(path), k, iy, ix, tile, robot, clearances, x, y, float(phis[k]), chunk_size, max_condition)
             for k, iy, ix in todo]
    show = sys.stderr.isatty() if progress is None else progress
    _run_tasks(tasks, scheduler, workers, show, resumed=tiles - len(todo), total=tiles)
    record = zarr_progress(path)
    for k, phi in enumerate(phis):
        if not np.nansum(record[k, ..., 0]):
            raise _empty_layer_error(phi, n)
    return {"summary": _summary_from_record(record, phis), "tiles": tiles, "computed": len(todo),
            "resumed": tiles - len(todo)}


def zarr_progress(path: str | Path) -> np.ndarray:
    """The per-tile record ``(n_phi, tiles_y, tiles_x, 9)`` of a Zarr map (NaN rows: tiles not computed yet)."""
    zarr = require("zarr")

    return zarr.open_array(store=str(path), path="_progress/chunks", mode="r")[...]


def _summary_from_record(record: np.ndarray, phis: np.ndarray) -> dict[str, dict[str, list[float]]]:
    """:func:`summarize` of a whole map from the tiles' minima and maxima."""
    out = {}
    for k, phi in enumerate(phis):
        rec = record[k].reshape(-1, record.shape[-1])
        rec = rec[rec[:, 0] > 0]
        key = f"{round_trip_degrees(phi):g}"
        out[key] = {("dphi_max_deg" if v == "dphi_max" else v): [float(rec[:, 1 + j].min()),
                                                                 float(rec[:, 5 + j].max())]
                    for j, v in enumerate(MAP_VARIABLES)}
    return out


def _run_tasks(tasks: list, scheduler: str | None, workers: int | None, show: bool, *, resumed: int,
               total: int) -> None:
    """Compute Dask tasks that return nothing big, with one tqdm bar; on a distributed scheduler via futures."""
    dask = require("dask")
    from tqdm import tqdm

    with tqdm(total=total, initial=resumed, disable=not show, desc="zarr map", unit="tile",
              file=sys.stderr) as bar:
        if scheduler and "://" in scheduler:
            _distributed = require("distributed")
            Client, as_completed = _distributed.Client, _distributed.as_completed

            with Client(scheduler) as client:
                futures = client.compute(tasks)
                for future in as_completed(futures):
                    future.result()  # re-raises a task's error here
                    bar.update()
                    future.release()
            return
        Callback = require("dask.callbacks").Callback

        class _Bar(Callback):
            def _posttask(self, key, result, dsk, state, worker_id):
                if "_zarr_tile" in str(key):
                    bar.update()

        # Waves of a few tasks per worker: an interruption (Ctrl-C) stops after the current wave instead of
        # waiting for every queued tile, and a wave's tiles are recorded as soon as they are written.
        wave = 4 * (workers or os.cpu_count() or 1)
        with _Bar():
            for start in range(0, len(tasks), wave):
                dask.compute(*tasks[start:start + wave], scheduler=scheduler or "threads", num_workers=workers)


def save_map(ds: xr.Dataset, path: str | Path) -> Path:
    """Write a map as NetCDF (``.nc``), Zarr (``.zarr``) or CSV (``.csv``, one row per grid point inside the workspace).

    The CSV columns are ``x,y,phi_deg,dx_max,dy_max,dphi_max_deg,dp_max`` (mm,
    mm, deg, mm, mm, deg, mm), the same as ``pmaccuracy bounds --format csv``,
    with exact floats (the shortest decimal of each double); it is written one
    orientation at a time.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".nc":
        # NetCDF-3 through scipy: no extra dependency; every attribute is a string.
        ds.to_netcdf(path, engine="scipy")
    elif suffix == ".zarr":
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=".*[Cc]onsolidated metadata.*")
            ds.to_zarr(path, mode="w", consolidated=True)
    elif suffix == ".csv":
        _save_csv(ds, path)
    else:
        raise ConfigError(f"unknown map file type {path.suffix!r}: use .nc, .zarr or .csv", source=str(path))
    return path


#: Grid points of one block of :func:`_save_csv` (the peak memory of the CSV writer beyond the map: a few MiB).
CSV_BLOCK_POINTS = 1 << 17


#: Columns of a CSV map (mm, mm, deg, mm, mm, deg, mm).
CSV_COLUMNS = ("x", "y", "phi_deg", "dx_max", "dy_max", "dphi_max_deg", "dp_max")


def _csv_options():
    pcsv = require("pyarrow.csv")
    return pcsv.WriteOptions(include_header=False, quoting_style="none", batch_size=1 << 16)


def _write_csv_rows(fh, options, xs: np.ndarray, ys: np.ndarray, phi_deg: float, block: list[np.ndarray]) -> None:
    """Append the CSV lines of the inside points of grid rows ``ys`` ``(r,)`` (mm): ``block`` holds the four
    ``(r, len(xs))`` layers of :data:`MAP_VARIABLES`; pyarrow writes the floats (shortest round-trip decimals)."""
    pcsv = require("pyarrow.csv")

    inside = np.ones(block[0].shape, dtype=bool)
    for b in block:
        inside &= np.isfinite(b)
    iy, ix = np.nonzero(inside)
    values = [xs[ix], ys[iy], np.full(ix.size, float(phi_deg))]
    values += [np.asarray(b[inside], dtype=float) for b in block]
    pcsv.write_csv(float_table(dict(zip(CSV_COLUMNS, values))), fh, options)


def _save_csv(ds: xr.Dataset, path: Path) -> None:
    """CSV of the inside points, layer after layer and block of grid rows after block (rows in (phi, y, x)
    order)."""
    options = _csv_options()
    xs, ys = ds.x.values, ds.y.values
    rows = max(1, CSV_BLOCK_POINTS // max(1, xs.size))   # grid rows a block: its columns stay a few MiB
    with open(path, "wb") as fh:
        fh.write((",".join(CSV_COLUMNS) + "\n").encode())
        for k, phi in enumerate(ds.phi.values):
            layers = [ds[name].values[k] for name in MAP_VARIABLES]
            for r0 in range(0, ys.size, rows):
                _write_csv_rows(fh, options, xs, ys[r0:r0 + rows], float(phi), [layer[r0:r0 + rows] for layer in layers])


# ------------------------------------------------------------------------------- streamed NetCDF-3 / CSV files
# The NetCDF-3 64-bit-offset format ("CDF-2", the one xarray writes through scipy): a header, then each
# variable's values contiguous and big-endian at the offset ("begin") the header gives. scipy's writer keeps
# every variable whole in memory until it closes; the header is written here instead, so that the values can
# go to their place in the file block by block as they are computed.
_NC_DIMENSION, _NC_VARIABLE, _NC_ATTRIBUTE = 10, 11, 12
_NC_CHAR, _NC_DOUBLE = 2, 6
#: Largest variable of a NetCDF-3 file (its size field is 32 bits), bytes.
NETCDF3_MAX_VARIABLE = 2**32 - 4


def _nc_pad(raw: bytes) -> bytes:
    return raw + b"\0" * (-len(raw) % 4)


def _nc_name(name: str) -> bytes:
    raw = name.encode("utf-8")
    return struct.pack(">i", len(raw)) + _nc_pad(raw)


def _nc_attributes(attrs: dict) -> bytes:
    """An attribute list: text as characters (UTF-8), numbers as one double."""
    if not attrs:
        return b"\0" * 8
    out = [struct.pack(">ii", _NC_ATTRIBUTE, len(attrs))]
    for name, value in attrs.items():
        out.append(_nc_name(name))
        if isinstance(value, str):
            raw = value.encode("utf-8")
            out.append(struct.pack(">ii", _NC_CHAR, len(raw)) + _nc_pad(raw))
        else:
            out.append(struct.pack(">iid", _NC_DOUBLE, 1, float(value)))
    return b"".join(out)


def _nc_layout(dims: dict[str, int], attrs: dict, variables: dict[str, tuple[tuple[str, ...], dict]]
               ) -> tuple[bytes, dict[str, int], int]:
    """Header of a NetCDF-3 64-bit-offset file of float64 variables, their data offsets (bytes) and the file size.

    ``variables``: name -> (dims, attributes), in the header's order; the values are laid out after the header
    largest shape first (as scipy's writer does, so the file is the one ``Dataset.to_netcdf(engine="scipy")``
    writes).
    """
    order = list(dims)
    nbytes = {name: 8 * int(np.prod([dims[d] for d in vdims], dtype=np.int64)) for name, (vdims, _) in
              variables.items()}
    shapes = {name: tuple(dims[d] for d in vdims) for name, (vdims, _) in variables.items()}
    laid = sorted(variables, key=lambda name: shapes[name], reverse=True)

    def header(begins: dict[str, int]) -> bytes:
        out = [b"CDF\x02", struct.pack(">i", 0), struct.pack(">ii", _NC_DIMENSION, len(dims))]
        out += [_nc_name(d) + struct.pack(">i", size) for d, size in dims.items()]
        out.append(_nc_attributes(attrs))
        out.append(struct.pack(">ii", _NC_VARIABLE, len(variables)))
        for name, (vdims, vattrs) in variables.items():
            out.append(_nc_name(name) + struct.pack(">i", len(vdims))
                       + b"".join(struct.pack(">i", order.index(d)) for d in vdims))
            out.append(_nc_attributes(vattrs))
            out.append(struct.pack(">iiq", _NC_DOUBLE, nbytes[name], begins.get(name, 0)))
        return b"".join(out)

    start = len(header({}))   # every field has a fixed width: the offsets do not change the header's length
    begins, at = {}, start
    for name in laid:
        begins[name] = at
        at += nbytes[name]
    return header(begins), begins, at


def _nc_map_layout(robot: Manipulator, clearances: ClearanceSet, phis: np.ndarray, x: np.ndarray, y: np.ndarray):
    """The layout of :func:`save_map`'s NetCDF file for this map: header, offsets, size, coordinate values."""
    coords = _coords(phis, x, y)
    fill = {"_FillValue": np.nan}
    variables = {"y": (("y",), {**coords["y"][2], **fill}), "x": (("x",), {**coords["x"][2], **fill})}
    variables.update({name: (("phi", "y", "x"), {"units": units, "long_name": long_name, **fill})
                      for name, (units, long_name) in MAP_VARIABLES.items()})
    variables["phi"] = (("phi",), {**coords["phi"][2], **fill})
    header, begins, size = _nc_layout({"phi": len(phis), "y": len(y), "x": len(x)}, _attrs(robot, clearances),
                                      variables)
    return header, begins, size, {name: coords[name][1] for name in ("phi", "y", "x")}


def check_netcdf_size(n_phi: int, n: int) -> None:
    """Refuse (ConfigError) a NetCDF-3 map with a variable of 4 GiB or more (the format's limit)."""
    if 8 * n_phi * n * n > NETCDF3_MAX_VARIABLE:
        raise ConfigError(f"a {n_phi} x {n} x {n} map has variables of {format_bytes(8 * n_phi * n * n)}, beyond "
                          f"NetCDF-3's 4 GiB: write it to a Zarr store instead (--out FILE.zarr)", key="grid")


def write_map(path: str | Path, robot: Manipulator | str, clearances: ClearanceSet | str,
              phis: float | np.ndarray, n: int = 101, *, chunk_size: int = DEFAULT_CHUNK,
              progress: bool | None = None, max_condition: float = DEFAULT_MAX_CONDITION
              ) -> dict[str, dict[str, list[float]]]:
    """Compute the map of :func:`error_map` straight into a NetCDF (``.nc``) or CSV (``.csv``) file, block by block.

    The file is the one ``save_map(error_map(...), path)`` writes (the same bytes), but the map is never held
    whole: each band of grid rows (the blocks of :func:`error_map`) goes to its place in the file as soon as
    it is computed, so memory holds one block's temporaries (a few tens of MB) whatever ``n``. For NetCDF the
    header is written first and each variable's rows at their offset; for CSV the inside points' lines are
    appended in ``(phi, y, x)`` order.

    Returns the ranges ``{phi_deg: {var: [min, max]}}`` of :func:`summarize`, gathered block by block.

    Raises
    ------
    ConfigError : an unknown file type, a NetCDF variable beyond 4 GiB, or errors that overflow (infinite:
        clearances far outside any physical range; key ``clearances``)
    EmptyWorkspaceError : a layer with no grid point inside its workspace

    The file is written under a temporary name beside ``path`` and renamed when complete: after an error or
    an interruption, ``path`` is untouched (a file already there stays as it was).
    SingularPoseError : as :func:`error_map`

    Example
    -------
    >>> import tempfile, pathlib
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     ranges = write_map(pathlib.Path(tmp) / "m.nc", "aalborg_3ppr", "case1", 0.0, n=21, progress=False)
    ...     ds = load_map(pathlib.Path(tmp) / "m.nc")
    >>> ds.dx_max.dims, round(ranges["0"]["dy_max"][1], 4)
    (('phi', 'y', 'x'), 0.0999)
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".nc", ".csv"):
        raise ConfigError(f"unknown streamed map file type {path.suffix!r}: use .nc or .csv", source=str(path))
    if chunk_size < 1:
        raise ConfigError(f"chunk size must be positive, got {chunk_size}", key="chunk_size")
    robot, clearances, phis, x, y = _prepare(robot, clearances, phis, n, max_condition)
    if suffix == ".nc":
        check_netcdf_size(len(phis), n)
    phis_deg = [round_trip_degrees(p) for p in phis]
    record = np.full((len(phis), 1, 1, 1 + 2 * len(MAP_VARIABLES)), np.nan)
    record[..., 0] = 0
    rows = _block_rows(len(phis), len(y), len(x), chunk_size)
    blocks = [(k, j) for k in range(len(phis)) for j in range(0, len(y), rows)]
    show = sys.stderr.isatty() if progress is None else progress
    from tqdm import tqdm

    partial = path.with_name(f".{path.name}.partial-{os.getpid()}")   # renamed to ``path`` once complete
    try:
        with open(partial, "wb") as fh, tqdm(total=len(blocks), disable=not show, desc="error map", unit="block",
                                          file=sys.stderr) as bar:
            if suffix == ".nc":
                header, begins, size, coords = _nc_map_layout(robot, clearances, phis, x, y)
                fh.write(header)
                fh.truncate(size)
                for name, values in coords.items():
                    fh.seek(begins[name])
                    fh.write(np.asarray(values, dtype=">f8").tobytes())
            else:
                options = _csv_options()
                fh.write((",".join(CSV_COLUMNS) + "\n").encode())
            # one band's results and their big-endian copy, reused band to band
            buffer = np.empty((len(MAP_VARIABLES), rows, len(x)))
            big_endian = np.empty((rows, len(x)), dtype=">f8") if suffix == ".nc" else None
            sources = _as_sources(clearances)   # converted once, not per band
            for k, j in blocks:
                r = len(y[j:j + rows])
                layers = [buffer[v, :r] for v in range(len(MAP_VARIABLES))]
                _fill_rows(robot, sources, x, y[j:j + rows], float(phis[k]), max_condition, layers)
                count, lo, hi = _band_extremes(layers)
                if np.isinf(lo).any() or np.isinf(hi).any():
                    raise ConfigError("the errors overflow: the clearances are far outside any physical range; "
                                      "nothing written", key="clearances")
                if suffix == ".nc":
                    for name, layer in zip(MAP_VARIABLES, layers):
                        fh.seek(begins[name] + 8 * (k * len(y) + j) * len(x))
                        np.copyto(big_endian[:r], layer)
                        fh.write(big_endian[:r])
                else:
                    _write_csv_rows(fh, options, x, y[j:j + rows], phis_deg[k], layers)
                _record_block(record[k, 0, 0], count, lo, hi)
                bar.update()
        for k, phi in enumerate(phis):
            if not record[k, 0, 0, 0]:
                raise _empty_layer_error(phi, n)
        os.replace(partial, path)
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    return _summary_from_record(record, phis)


def _band_extremes(layers: list[np.ndarray]) -> tuple[int, np.ndarray, np.ndarray]:
    """A band's four layers ``(rows, nx)`` -> (inside points, the four minima, the four maxima); NaN extremes
    when no point is inside. (bounds_or_nan blanks the four together, so NaN-ignoring reductions see the
    inside points only; an overflow shows as an infinite extreme.)"""
    count = int(np.count_nonzero(~np.isnan(layers[0])))
    lo = np.array([np.fmin.reduce(layer, axis=None) for layer in layers])
    hi = np.array([np.fmax.reduce(layer, axis=None) for layer in layers])
    return count, lo, hi


def _record_block(rec: np.ndarray, count: int, lo: np.ndarray, hi: np.ndarray) -> None:
    """Fold a band's :func:`_band_extremes` into a record ``[inside points, 4 minima, 4 maxima]`` (NaN
    extremes: none yet)."""
    if not count:
        return
    nv = len(MAP_VARIABLES)
    rec[1:1 + nv] = lo if not rec[0] else np.fmin(rec[1:1 + nv], lo)
    rec[1 + nv:] = hi if not rec[0] else np.fmax(rec[1 + nv:], hi)
    rec[0] += count


def load_map(path: str | Path) -> xr.Dataset:
    """Read a map written by :func:`save_map` as NetCDF."""
    try:
        with xr.open_dataset(path, engine="scipy") as ds:
            return ds.load()
    except (OSError, ValueError, TypeError) as exc:
        raise ConfigError(f"not a pmaccuracy NetCDF map ({exc})", source=str(path)) from None


def summarize(ds: xr.Dataset) -> dict[str, dict[str, list[float]]]:
    """``{phi_deg: {var: [min, max]}}`` over each layer (NaN-aware); keys as in ``results.json``."""
    out = {}
    for phi in ds.phi.values:
        layer = ds.sel(phi=phi)
        key = f"{phi:g}"
        out[key] = {("dphi_max_deg" if v == "dphi_max" else v): [float(layer[v].min()), float(layer[v].max())]
                    for v in MAP_VARIABLES}
    return out
