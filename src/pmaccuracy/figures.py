"""Figures of error maps like the paper's Figs. 9-12 (Sec. 6).

Figures are built on :class:`matplotlib.figure.Figure` objects (no pyplot state),
so they can be made in threads and saved with ``fig.savefig``. The map figures
place their axes at fixed positions (a grid of panels, each with its colour bar
attached by :func:`mpl_toolkits.axes_grid1.make_axes_locatable`) instead of
running a layout engine, which costs more than drawing them.

:class:`Renderer` builds and saves figures in worker processes
(``concurrent.futures.ProcessPoolExecutor``), for reports with many figures.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from concurrent.futures import Future, ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

#: Panels of a four-panel map: variable, measured-data key, title, units.
PANELS = (
    ("dx_max", "dx", r"$\delta x_{max}$", "mm"),
    ("dy_max", "dy", r"$\delta y_{max}$", "mm"),
    ("dp_max", "dp", r"$\delta p_{max}$", "mm"),
    ("dphi_max", "dphi_deg", r"$\delta\phi_{max}$", "deg"),
)


def _limits(values: np.ndarray, extra: np.ndarray | None) -> tuple[float, float]:
    """Colour range over the map (and measured values); a constant field gets a +-1 % band."""
    pool = values[np.isfinite(values)]
    if extra is not None:
        pool = np.concatenate([pool, extra[np.isfinite(extra)]])
    lo, hi = float(pool.min()), float(pool.max())
    if hi - lo <= 1e-9 * max(abs(hi), 1e-12):
        pad = max(0.01 * abs(hi), 1e-9)
        lo, hi = lo - pad, hi + pad
    return lo, hi


def plot_error_map(ds: xr.Dataset, phi_deg: float, *, measured: Mapping[str, np.ndarray] | None = None,
                   title: str | None = None, scale: float = 1.0) -> Figure:
    """Four panels (dx_max, dy_max, dp_max in mm; dphi_max in deg) over the workspace at ``phi_deg``.

    Parameters
    ----------
    ds : a map from :func:`pmaccuracy.maps.error_map`
    phi_deg : orientation layer to draw (deg)
    measured : optional measured points, arrays keyed ``x, y`` (mm) and ``dx, dy, dp`` (mm),
        ``dphi_deg`` (deg), drawn as dots coloured on the same scale with black rims
    scale : factor applied to the predicted maxima before drawing (e.g. 2 for the
        width-consistent comparison with measured ranges)
    """
    layer = ds.sel(phi=phi_deg, method="nearest")
    fig = Figure(figsize=(11, 8.5))
    axes = fig.subplots(2, 2)
    fig.subplots_adjust(left=0.07, right=0.93, bottom=0.07, top=0.9, wspace=0.5, hspace=0.3)
    X, Y = np.meshgrid(layer.x.values, layer.y.values)
    for ax, (var, mkey, label, units) in zip(axes.ravel(), PANELS):
        values = layer[var].values * scale
        extra = None if measured is None else np.asarray(measured[mkey], dtype=float)
        lo, hi = _limits(values, extra)
        mesh = ax.pcolormesh(X, Y, values, shading="auto", cmap="viridis", vmin=lo, vmax=hi)
        _crop(ax, layer.x.values, layer.y.values, values)
        if np.nanmax(values) - np.nanmin(values) > 1e-9 * np.nanmax(np.abs(values)):
            cs = ax.contour(X, Y, values, levels=6, colors="white", linewidths=0.6, alpha=0.8)
            ax.clabel(cs, fontsize=7, fmt="%.3g")
        else:
            ax.text(0.5, 0.5, f"constant {np.nanmax(values):.4g} {units}", transform=ax.transAxes,
                    ha="center", va="center", color="white", fontsize=10,
                    bbox={"facecolor": "black", "alpha": 0.4, "edgecolor": "none"})
        if measured is not None:
            ax.scatter(measured["x"], measured["y"], c=extra, cmap="viridis", vmin=lo, vmax=hi, s=36,
                       edgecolors="black", linewidths=1.0, label="measured")
            ax.legend(loc="upper right", fontsize=8)
        cbar = fig.colorbar(mesh, cax=_colorbar_axes(ax))
        cbar.set_label(f"{label} [{units}]")
        prefix = f"{scale:g} x " if scale != 1 else ""
        ax.set_title(f"{prefix}{label} [{units}]")
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.set_aspect("equal")
    fig.suptitle(title or f"{ds.attrs.get('robot', '')}, clearances {ds.attrs.get('clearances', '')}, "
                          f"$\\phi$ = {float(layer.phi):g} deg")
    return fig


def plot_layers(ds: xr.Dataset, var: str, *, title: str | None = None) -> Figure:
    """One variable of a map at every orientation, side by side on a common colour scale."""
    units = ds[var].attrs.get("units", "")
    n = ds.sizes["phi"]
    fig = Figure(figsize=(4.2 * n + 1, 4))
    axes = np.atleast_1d(fig.subplots(1, n))
    fig.subplots_adjust(left=0.08, right=0.88, bottom=0.13, top=0.84, wspace=0.3)
    lo, hi = _limits(ds[var].values, None)
    X, Y = np.meshgrid(ds.x.values, ds.y.values)
    mesh = None
    for ax, phi in zip(axes, ds.phi.values):
        mesh = ax.pcolormesh(X, Y, ds[var].sel(phi=phi).values, shading="auto", cmap="viridis", vmin=lo, vmax=hi)
        ax.set_title(f"$\\phi$ = {phi:g} deg")
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.set_aspect("equal")
    cax = fig.add_axes((0.9, 0.13, 0.02, 0.71))
    fig.colorbar(mesh, cax=cax).set_label(f"{var} [{units}]")
    fig.suptitle(title or f"{var} [{units}]")
    return fig


def _colorbar_axes(ax):
    """A colour-bar axes glued to the right of ``ax`` (follows ``ax`` when its aspect shrinks it)."""
    from mpl_toolkits.axes_grid1 import make_axes_locatable

    return make_axes_locatable(ax).append_axes("right", size="5%", pad=0.08)


def save(fig: Figure, path: str | Path, dpi: int = 110) -> Path:
    """Save a figure as PNG and return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    return path


def render(path: str | Path, build: Callable[..., Any], *args: Any, dpi: int = 110, **kwargs: Any) -> Path:
    """``save(build(*args, **kwargs), path)``: one job of a :class:`Renderer` (runs in a worker process).

    A ``build`` that writes ``path`` itself (returns no Figure) is just called.
    """
    result = build(*args, **kwargs)
    if isinstance(result, Figure):
        save(result, path, dpi=dpi)
    return Path(path)


class Renderer:
    """Build and save figures in worker processes while the caller goes on computing.

    ``submit(path, build, *args, **kwargs)`` queues ``build(*args, **kwargs)``
    (a module-level function returning a Figure; its arguments are pickled) and
    returns the path at once; leaving the ``with`` block waits for every figure
    and re-raises the first error. ``on_done`` is called (in a helper thread)
    after each figure, e.g. to advance a progress bar. ``workers=0`` renders in
    the calling process (same results, no pool).
    """

    def __init__(self, workers: int = 2, on_done: Callable[[], None] | None = None):
        self.workers = workers
        self.on_done = on_done
        self._pool: ProcessPoolExecutor | None = None
        self._futures: list[Future] = []

    def __enter__(self) -> Renderer:
        if self.workers > 0:
            import multiprocessing as mp

            # fork (where available) starts workers with numpy and matplotlib already imported
            context = mp.get_context("fork") if "fork" in mp.get_all_start_methods() else None
            self._pool = ProcessPoolExecutor(max_workers=self.workers, mp_context=context)
        return self

    def submit(self, path: str | Path, build: Callable[..., Figure], *args: Any, **kwargs: Any) -> Path:
        path = Path(path)
        if self._pool is None:
            render(path, build, *args, **kwargs)
            if self.on_done:
                self.on_done()
            return path
        future = self._pool.submit(render, path, build, *args, **kwargs)
        if self.on_done:
            future.add_done_callback(lambda _: self.on_done())
        self._futures.append(future)
        return path

    def compute(self, function: Callable[..., Any], *args: Any, **kwargs: Any) -> Future:
        """Run any module-level ``function(*args, **kwargs)`` in a worker; a Future of its (pickled) result."""
        if self._pool is None:
            future: Future = Future()
            future.set_result(function(*args, **kwargs))
            return future
        return self._pool.submit(function, *args, **kwargs)

    def __exit__(self, exc_type, exc, tb) -> None:
        if self._pool is None:
            return
        try:
            if exc_type is None:
                for future in self._futures:
                    future.result()
        finally:
            self._pool.shutdown(wait=True, cancel_futures=exc_type is not None)


def plot_panels(panels: list[tuple[np.ndarray, np.ndarray, np.ndarray, str, str]], *, suptitle: str,
                shared_scale: bool = False, ncols: int | None = None) -> Figure:
    """Several scalar fields side by side: each panel is ``(x (n,), y (m,), Z (m, n), title, units)``.

    With ``shared_scale`` every panel uses one colour range (for comparing designs).
    """
    ncols = ncols or len(panels)
    nrows = int(np.ceil(len(panels) / ncols))
    fig = Figure(figsize=(4.4 * ncols + 0.8, 3.9 * nrows))
    axes = np.atleast_1d(fig.subplots(nrows, ncols)).ravel()
    fig.subplots_adjust(left=0.6 / (4.4 * ncols + 0.8), right=0.97, bottom=0.45 / (3.9 * nrows),
                        top=1 - 0.8 / (3.9 * nrows), wspace=0.45, hspace=0.35)
    common = _limits(np.concatenate([p[2].ravel() for p in panels]), None) if shared_scale else None
    for ax, (x, y, Z, title, units) in zip(axes, panels):
        lo, hi = common or _limits(Z, None)
        mesh = ax.pcolormesh(x, y, Z, shading="auto", cmap="viridis", vmin=lo, vmax=hi)
        _crop(ax, x, y, Z)
        fig.colorbar(mesh, cax=_colorbar_axes(ax)).set_label(units)
        ax.set_title(title)
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.set_aspect("equal")
    for ax in axes[len(panels):]:
        ax.set_visible(False)
    fig.suptitle(suptitle)
    return fig


def _crop(ax, x: np.ndarray, y: np.ndarray, Z: np.ndarray, margin: float = 0.05) -> None:
    """Limit the axes to the finite part of a field (its workspace) plus a margin."""
    finite = np.isfinite(Z)
    if not finite.any():
        return
    xs, ys = x[finite.any(axis=0)], y[finite.any(axis=1)]
    dx, dy = (xs.max() - xs.min()) * margin + 1e-9, (ys.max() - ys.min()) * margin + 1e-9
    ax.set_xlim(xs.min() - dx, xs.max() + dx)
    ax.set_ylim(ys.min() - dy, ys.max() + dy)
