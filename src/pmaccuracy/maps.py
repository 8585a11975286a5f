"""Maximum pose errors over the constant-orientation workspace (paper Sec. 6, Figs. 9-12).

:func:`error_map` evaluates the exact bounds of :func:`pmaccuracy.bounds.max_pose_errors`
on a regular x-y grid at one or more orientations and returns an
``xarray.Dataset`` with dims ``(phi, y, x)``:

* coordinates ``x``, ``y`` in mm (one grid spanning the bounding box of every
  requested workspace) and ``phi`` in **degrees**;
* variables ``dx_max``, ``dy_max``, ``dp_max`` (mm) and ``dphi_max`` (deg), NaN
  at grid points outside that orientation's workspace (joint ranges);
* attributes: robot and clearance set (name and full TOML text), package
  version, method.

Large maps are evaluated in blocks of ``chunk_size`` grid points; with
``use_dask=True`` the blocks become a ``dask.array`` computed on whatever Dask
scheduler is active (threads by default, or a ``dask.distributed.Client`` the
caller created, on a cluster included).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import xarray as xr

from .bounds import max_pose_errors
from .clearances import ClearanceSet
from .errors import ConfigError, EmptyWorkspaceError
from .geometry import Manipulator, round_trip_degrees
from .kinematics import DEFAULT_MAX_CONDITION, inverse_kinematics, require_regular
from .workspace import constant_orientation_workspace

#: Map variables: name -> (units, long name).
MAP_VARIABLES = {
    "dx_max": ("mm", "maximum position error along x (Eq. 21)"),
    "dy_max": ("mm", "maximum position error along y (Eq. 21)"),
    "dphi_max": ("deg", "maximum orientation error (Eq. 21)"),
    "dp_max": ("mm", "maximum position error magnitude (Eq. 22)"),
}
DEFAULT_CHUNK = 1 << 18


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
    pose is outside the joint ranges. The block builds its own poses from the
    grid vectors, so a Dask task carries only two short vectors (picklable for
    dask.distributed).
    """
    X, Y = np.meshgrid(x, y_rows)
    poses = np.stack([X, Y, np.full_like(X, phi)], axis=-1)
    inside = inverse_kinematics(robot, poses).within_limits
    out = np.full(X.shape + (4,), np.nan)
    if inside.any():
        b = max_pose_errors(robot, clearances, poses[inside], allow_outside=True, max_condition=max_condition)
        out[inside] = np.column_stack([b.dx_max, b.dy_max, b.dphi_max_deg, b.dp_max])
    return out


def error_map(robot: Manipulator | str, clearances: ClearanceSet | str, phis: float | np.ndarray, n: int = 101, *,
              chunk_size: int = DEFAULT_CHUNK, use_dask: bool = False, progress: bool | None = None,
              max_condition: float = DEFAULT_MAX_CONDITION) -> xr.Dataset:
    """Exact maximum pose errors on an ``n x n`` grid at each orientation.

    Parameters
    ----------
    robot, clearances : objects, preset names or TOML paths
    phis : orientation(s) in **radians** (scalar or ``(k,)``)
    n : grid points per axis
    chunk_size : grid points per block
    use_dask : compute the blocks with Dask (needs ``pip install pmaccuracy[dask]``)
    progress : show a progress bar; default: only when stderr is a terminal

    Returns
    -------
    xarray.Dataset with dims ``(phi, y, x)``; ``phi`` coordinate in degrees.

    Raises
    ------
    SingularPoseError : an orientation at or near the parallel singularity (for a
        3-PPR det A depends on phi only, so a whole layer is singular or none is)
    EmptyWorkspaceError : an orientation without workspace
    """
    from . import __version__

    robot = Manipulator.load(robot)
    clearances = ClearanceSet.load(clearances)
    phis = np.atleast_1d(np.asarray(phis, dtype=float))
    if not np.all(np.isfinite(phis)):
        raise ConfigError("orientations must be finite", key="phi")
    if chunk_size < 1:
        raise ConfigError(f"chunk size must be positive, got {chunk_size}", key="chunk_size")
    require_regular(robot, np.column_stack([np.zeros_like(phis), np.zeros_like(phis), phis]), max_condition)
    x, y = map_grid(robot, phis, n)
    values = _evaluate(robot, clearances, x, y, phis, chunk_size, use_dask, progress, max_condition)
    for k, phi in enumerate(phis):
        if not np.isfinite(values[k, ..., 0]).any():
            raise EmptyWorkspaceError(f"no point of the {n} x {n} grid lies inside the workspace at phi = "
                                      f"{np.degrees(phi):g} deg: use a finer grid")
    data_vars = {name: (("phi", "y", "x"), values[..., j], {"units": units, "long_name": long_name})
                 for j, (name, (units, long_name)) in enumerate(MAP_VARIABLES.items())}
    return xr.Dataset(
        data_vars,
        coords={"phi": ("phi", np.array([round_trip_degrees(p) for p in phis]),
                        {"units": "deg", "long_name": "platform orientation"}),
                "y": ("y", y, {"units": "mm"}), "x": ("x", x, {"units": "mm"})},
        attrs={"title": f"Maximum pose errors of {robot.name} with clearances {clearances.name}",
               "robot": robot.name, "robot_toml": robot.to_toml(),
               "clearances": clearances.name, "clearances_toml": clearances.to_toml(),
               "method": "exact first-order worst case (zonotope support functions and vertices, Eq. 21-22)",
               "source": f"pmaccuracy {__version__}",
               "reference": "Wu, Bai, Kepler, Caro, ASME J. Mechanisms Robotics 4(4) 041011, 2012"})


def _evaluate(robot: Manipulator, clearances: ClearanceSet, x: np.ndarray, y: np.ndarray, phis: np.ndarray,
              chunk_size: int, use_dask: bool, progress: bool | None, max_condition: float) -> np.ndarray:
    """All blocks of the map -> ``(len(phis), len(y), len(x), 4)``; blocks are bands of about ``chunk_size`` points."""
    show = sys.stderr.isatty() if progress is None else progress
    rows = max(1, chunk_size // len(x))
    blocks = [(k, y[j:j + rows]) for k in range(len(phis)) for j in range(0, len(y), rows)]
    if use_dask:
        try:
            import dask
            import dask.array as da
            from dask.diagnostics import ProgressBar
        except ImportError:  # pragma: no cover - depends on the installation
            raise ConfigError("use_dask needs Dask: pip install 'pmaccuracy[dask]'", key="use_dask") from None
        task = dask.delayed(_rows_block, pure=True)
        parts = [da.from_delayed(task(robot, clearances, x, yr, float(phis[k]), max_condition),
                                 shape=(len(yr), len(x), 4), dtype=float) for k, yr in blocks]
        per_phi = len(parts) // len(phis)
        stacked = da.stack([da.concatenate(parts[k * per_phi:(k + 1) * per_phi]) for k in range(len(phis))])
        if show:
            with ProgressBar(out=sys.stderr):
                return stacked.compute()
        return stacked.compute()
    from tqdm import tqdm

    out = [_rows_block(robot, clearances, x, yr, float(phis[k]), max_condition)
           for k, yr in tqdm(blocks, disable=not show, desc="error map", unit="block", file=sys.stderr)]
    per_phi = len(out) // len(phis)
    return np.stack([np.concatenate(out[k * per_phi:(k + 1) * per_phi]) for k in range(len(phis))])


def save_map(ds: xr.Dataset, path: str | Path) -> Path:
    """Write a map as NetCDF (``.nc``) or CSV (``.csv``, one row per grid point inside the workspace).

    The CSV columns are ``x,y,phi_deg,dx_max,dy_max,dphi_max_deg,dp_max`` (mm,
    mm, deg, mm, mm, deg, mm), the same as ``pmaccuracy bounds --format csv``.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".nc":
        # NetCDF-3 through scipy: no extra dependency; every attribute is a string.
        ds.to_netcdf(path, engine="scipy")
    elif suffix == ".csv":
        df = ds.to_dataframe().dropna(subset=list(MAP_VARIABLES)).reset_index()
        df = df.rename(columns={"phi": "phi_deg", "dphi_max": "dphi_max_deg"})
        df[["x", "y", "phi_deg", "dx_max", "dy_max", "dphi_max_deg", "dp_max"]].to_csv(
            path, index=False)  # shortest round-trip floats: boundary points stay exactly on the boundary
    else:
        raise ConfigError(f"unknown map file type {path.suffix!r}: use .nc or .csv", source=str(path))
    return path


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
