"""Statistics of the pose error drawn and reported: the percentile-map figure and the statistics section.

The numbers come from :mod:`pmaccuracy.accuracy.distributions` (Monte Carlo inside the error set, its
quadrature references); this module only draws and assembles them.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..accuracy.distributions import (Distribution, as_sources, pose_statistics, region_statistics,
                                      summarize_region)
from ..errors import ConfigError
from ..io.resolve import robot_arg
from . import figures
from ..accuracy.bounds import max_pose_errors


def save_percentile_map_figure(ds, path: str | Path, *, phi_deg: float | None = None,
                               percentile: float | None = None, dpi: float = figures.DEFAULT_DPI,
                               vmin: float | None = None, vmax: float | None = None, log: bool = False) -> Path:
    """Figure: for one orientation, the percentile of ``|dp|`` and of ``|dphi|`` beside their worst case and
    the ratio percentile / worst case (2 x 3 panels), then for each quantity with a threshold in ``ds``
    (``region_statistics(..., thresholds=...)``) the map of the probability of exceeding it (a third row),
    written in the format ``path``'s extension names.

    The percentile and ratio panels are drawn in colour bands no finer than the Monte Carlo error stated in
    ``ds.attrs`` (``dp_p95_error``, ``dp_p95_ratio_error``, ...; :func:`figures.monte_carlo_levels`), so
    sampling noise shows no stripes. ``vmin``/``vmax`` (mm) set the |dp| panels, ``log`` every scale.
    Returns the written path."""
    figures.figure_format(path)
    figures.check_dpi(dpi)

    if phi_deg is None:
        phi_deg = float(ds.phi.values[0])
    layer = ds.sel(phi=phi_deg, method="nearest")
    if percentile is None:
        names = [n for n in ds.data_vars if n.startswith("dp_p")]
        if not names:
            raise ConfigError("the dataset has no percentile map", key="percentile")
        key = names[0][len("dp_"):]
    else:
        key = f"p{percentile:g}"
    x, y = ds.x.values, ds.y.values
    panels, errors, limited = [], [], []
    for q, unit, label in (("dp", "mm", r"$|\delta p|$"), ("dphi", "deg", r"$|\delta\phi|$")):
        pv, mv = layer[f"{q}_{key}"].values, layer[f"{q}_max"].values
        panels += [(x, y, pv, f"{key[1:]}th percentile of {label}", unit),
                   (x, y, mv, f"worst case {figures.SYMBOLS[q + '_max'][0]}", unit),
                   (x, y, pv / mv, f"percentile / worst case, {label}", "ratio [1]")]
        errors += [_stated_error(ds, f"{q}_{key}_error"), None, _stated_error(ds, f"{q}_{key}_ratio_error")]
        limited += [unit == "mm", unit == "mm", False]
    for q, unit, label in (("dx", "mm", r"$|\delta x|$"), ("dy", "mm", r"$|\delta y|$"), ("dp", "mm", r"$|\delta p|$"),
                           ("dphi", "deg", r"$|\delta\phi|$")):
        if f"{q}_exceed" in layer:   # a threshold was given: the exceedance probability map
            threshold = float(ds.attrs.get(f"{q}_threshold", "nan"))
            panels.append((x, y, layer[f"{q}_exceed"].values, f"P({label} > {threshold:g} {unit})",
                           "probability [1]"))
            errors.append(_stated_error(ds, "exceed_se_max"))
            limited.append(False)
    fig = figures.plot_panels(panels, ncols=3, errors=errors, limited=limited, vmin=vmin, vmax=vmax, log=log,
                              shapes=[(figures._robot_of(ds), float(layer.phi))] * len(panels),
                              suptitle=f"{ds.attrs.get('robot', '')}, clearances {ds.attrs.get('clearances', '')}: "
                                       f"$\\phi$ = {float(layer.phi):g} deg, {ds.attrs.get('samples', '?')} "
                                       f"Monte Carlo samples")
    return figures.save_figure(fig, path, dpi=dpi)


def _stated_error(ds, name: str) -> float | None:
    """The Monte Carlo error ``ds.attrs[name]`` (float) or None when the dataset does not state it."""
    try:
        value = float(ds.attrs[name])
    except (KeyError, TypeError, ValueError):
        return None
    return value if np.isfinite(value) and value > 0 else None


def statistics_section(robot, clearances, phi: float = 0.0, *, grid: int = 21, samples: int = 10_000,
                       pose_samples: int = 100_000, seed: int | None = 0, pose=None,
                       distribution: Distribution | str | None = None, threshold_dp: float | None = None,
                       figure: str | Path | None = None, region=None) -> dict[str, Any]:
    """Everything a report section on the error statistics needs, JSON-ready.

    At ``pose`` ``(3,)`` [mm, mm, rad] (default: the commanded pose ``(0, 0, phi)``) the
    :func:`pose_statistics` with ``pose_samples`` samples; over the workspace at ``phi`` (rad) the
    :func:`summarize_region` of an ``grid x grid`` percentile map (95th percentile) with ``samples``
    samples; ``threshold_dp`` (mm, default: the worst case of dp at the pose, halved) for the exceedance
    probabilities; with ``figure`` the :func:`save_percentile_map_figure` written there. ``region`` (a shape of
    :mod:`pmaccuracy.accuracy.regions`, mm) limits the map to that shape (default: the whole workspace).
    Returns ``{"pose": ..., "region": ..., "figure": path or None}``.
    """
    pose = np.array([0.0, 0.0, phi]) if pose is None else np.asarray(pose, dtype=float)
    if threshold_dp is None:

        robot = robot_arg(robot)
        threshold_dp = round(0.5 * float(max_pose_errors(robot, as_sources(robot, clearances), pose).dp_max), 4)
    at_pose = pose_statistics(robot, clearances, pose, samples=pose_samples, seed=seed, distribution=distribution,
                              thresholds={"dp": threshold_dp}).to_dict()
    ds = region_statistics(robot, clearances, [phi], grid, samples=samples, seed=seed, distribution=distribution,
                           percentiles=(95.0,), thresholds={"dp": threshold_dp}, region=region)
    path = save_percentile_map_figure(ds, figure) if figure is not None else None
    return {"pose": at_pose, "region": summarize_region(ds), "threshold_dp": threshold_dp,
            "figure": None if path is None else str(path)}
