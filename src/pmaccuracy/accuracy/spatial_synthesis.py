"""How loose may a spatial robot's joints be? The largest uniform scaling of its error sources that keeps the
worst first-order errors within targets, at every point of its workspace grid or certified over a whole region
(issue 37, synthesis).

Every worst-case quantity is positively homogeneous of degree one in the half-widths: the first-order error set
is the Minkowski sum of one set per source, each proportional to the source's half-width, so its support
function in any direction, hence every component's maximum and the largest ``|dp|``, ``|dtheta|``, scales by
``lam`` when every source does. With ``q_k(x)`` the quantity ``k`` of the template sources at the pose ``x``,

    lam = min over k of  T_k / max over x of q_k(x)                                                   (1)

is the largest scale meeting every target ``T_k``.

**Grid mode** (``region=None``): the maxima of Eq. 1 over the points of the workspace's ``n``-per-axis grid
(:func:`pmaccuracy.accuracy.spatial_maps.spatial_error_map`). Exact on the grid (upper bounds of ``|dp|``,
``|dtheta|``: conservative by at most their gap), attained at the binding point; between grid points nothing
is guaranteed.

**Certified mode** (``region`` a :class:`~pmaccuracy.accuracy.spatial_worst.SpatialRegion`): the certified
global worst case of the template over the region
(:func:`~pmaccuracy.accuracy.spatial_worst.spatial_global_worst`, one branch and bound) gives, for each targeted
quantity, an attained value ``L_k`` and an upper bound ``U_k`` over the whole region. Then

    lam = min over k of T_k / U_k        and        lam* <= lam_hi = min over k of T_k / L_k           (2)

``lam`` sources meet every target at every pose of the region (their maxima are at most ``lam U_k <= T_k``;
the certificate of the template scaled, as the planar :func:`pmaccuracy.accuracy.synthesis.synthesize` does);
the largest admissible scale ``lam*`` is below ``lam_hi``, since beyond it the sources exceed target ``k`` at
the pose attaining ``L_k``. ``lam_hi / lam <= 1 + gap`` when the binding quantity's certificate reached its gap.
The certified margin of target ``k`` is ``T_k - lam U_k >= 0`` (zero for the binding target). Architectures
whose global worst case gives no finite upper bound are refused (:class:`~pmaccuracy.errors.
UnsupportedArchitectureError`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np

from ..errors import CertificationError, ConfigError, EmptyWorkspaceError, UnsupportedArchitectureError
from ..model.plausibility import PlausibilityWarning, check_angle_values
from ..model.spatial import SpatialManipulator
from ..model.spatial_sources import SpatialErrorSources
from ..numerics.spatial import rotvec_to_euler_xyz
from .spatial_maps import spatial_error_map
from .spatial_worst import DEFAULT_GAP, DEFAULT_MAX_BOXES, SpatialGlobalWorst, SpatialRegion, spatial_global_worst

#: Targets a spatial synthesis takes, and the map variable and unit conversion of each (mm, or deg -> rad).
TARGETS = {"dx": ("dx_max", 1.0), "dy": ("dy_max", 1.0), "dz": ("dz_max", 1.0),
           "drx_deg": ("drx_max", np.pi / 180), "dry_deg": ("dry_max", np.pi / 180),
           "drz_deg": ("drz_max", np.pi / 180), "dp": ("dp_max", 1.0), "dtheta_deg": ("dtheta_max", np.pi / 180)}
#: A quantity of the template whose certified bound is below this fraction of its largest source (angles times
#: the characteristic length) is not moved by the sources (rounding noise of an exact zero).
NO_EFFECT = 1e-9


@dataclass(frozen=True)
class SpatialSynthesis:
    """The result of :func:`spatial_synthesize`.

    Attributes
    ----------
    scale : float
        ``lam`` of Eq. 1 (grid) or Eq. 2 (certified): every half-width of the template times it meets every
        target (at every grid point, or at every pose of the region).
    sources : :class:`~pmaccuracy.model.spatial_sources.SpatialErrorSources`
        The synthesized sources (the template scaled).
    binding : str
        The target that binds (its name, e.g. ``"dp"``).
    binding_point : ``(3,)``
        Where it binds. Grid mode: the grid point, in the grid's coordinates (x, y, z mm; roll, pitch deg and
        z mm for a 3-RPS/3-PRS). Certified mode: the pose attaining the binding quantity's lower value, in the
        region's coordinates (x, y, z mm; z mm, roll, pitch deg for a 3-RPS/3-PRS).
    worst : dict
        The synthesized sources' worst value of each targeted quantity (mm or deg): over the grid (grid mode),
        the certified upper bound over the region (certified mode, ``<= target``).
    targets : dict
        The targets (mm or deg).
    points : int
        Grid points evaluated (grid mode); boxes of the branch and bound (certified mode).
    region : :class:`~pmaccuracy.accuracy.spatial_worst.SpatialRegion` or None
        The region of a certified synthesis; None in grid mode.
    certificate : :class:`~pmaccuracy.accuracy.spatial_worst.SpatialGlobalWorst` or None
        Certified mode: the synthesized sources' global worst case (the template's, scaled by ``scale``).
    lower : dict or None
        Certified mode: each targeted quantity's value attained in the region by the synthesized sources
        (mm or deg).
    margin : dict or None
        Certified mode: ``target - worst`` per target (mm or deg), ``>= 0``.
    scale_upper : float or None
        Certified mode: ``lam_hi`` of Eq. 2, the largest admissible scale is at most this (a larger one exceeds a
        target at an attained pose).
    binding_pose : ``(6,)`` or None
        Certified mode: the full pose of ``binding_point`` (mm, rotation vector rad).
    """

    scale: float
    sources: SpatialErrorSources
    binding: str
    binding_point: np.ndarray
    worst: dict
    targets: dict
    points: int
    region: SpatialRegion | None = None
    certificate: SpatialGlobalWorst | None = None
    lower: dict | None = None
    margin: dict | None = None
    scale_upper: float | None = None
    binding_pose: np.ndarray | None = None

    @property
    def uncertified(self) -> dict[str, float]:
        """``{target: relative gap}`` of the targeted quantities whose certificate stopped short of its gap
        (certified mode; the targets still hold, the scale may be that much smaller than the largest)."""
        if self.certificate is None:
            return {}
        return {name: self.certificate[_quantity(name)].gap for name in self.targets
                if not self.certificate[_quantity(name)].converged}

    @property
    def certified(self) -> bool:
        """The targets are certified over a region and every targeted quantity's certificate reached its gap."""
        return self.certificate is not None and not self.uncertified

    def records(self) -> list[dict]:
        """One dict per target: ``target`` (name), ``value`` (the target), ``worst``, ``unit`` (mm or deg),
        ``binding``; certified mode adds ``lower`` (attained), ``upper`` (= ``worst``), ``margin``, ``gap_pct``
        and ``certified`` (the certificate reached its gap)."""
        out = []
        for name, value in self.targets.items():
            row = {"target": name, "value": float(value), "worst": float(self.worst[name]),
                   "unit": "deg" if name.endswith("_deg") else "mm", "binding": name == self.binding}
            if self.certificate is not None:
                w = self.certificate[_quantity(name)]
                row.update(lower=float(self.lower[name]), upper=float(self.worst[name]),
                           margin=float(self.margin[name]), gap_pct=100 * float(w.gap), certified=bool(w.converged))
            out.append(row)
        return out


def _quantity(name: str) -> str:
    """The :data:`~pmaccuracy.accuracy.spatial_worst.QUANTITIES` name of a target (``"drx_deg"`` -> ``"drx"``)."""
    return TARGETS[name][0][:-len("_max")]


def scaled_spatial_worst(worst: SpatialGlobalWorst, factor: float) -> SpatialGlobalWorst:
    """The certificate of the sources times ``factor > 0``: every quantity is homogeneous of degree 1 in the
    half-widths (module docstring), so its lower and upper bounds scale by ``factor`` at the same poses, with
    the same gaps (no second branch and bound)."""
    out = {q: replace(w, lower=w.lower * factor, upper=w.upper * factor, pose=w.pose.copy())
           for q, w in worst.quantities.items()}
    return replace(worst, quantities=out)


def _check_targets(targets) -> None:
    if not isinstance(targets, dict) or not targets:
        raise ConfigError(f"give at least one target ({', '.join(TARGETS)})", key="targets")
    for name, value in targets.items():
        if name not in TARGETS:
            raise ConfigError(f"unknown target {name!r} for a spatial robot; targets: {', '.join(TARGETS)}",
                              key="targets")
        if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
            raise ConfigError(f"{name} must be finite and > 0, got {value!r}", key="targets")


def _region_point(robot: SpatialManipulator, region: SpatialRegion, pose: np.ndarray) -> np.ndarray:
    """A full pose's coordinates in the region (mm; roll, pitch in deg for a 3-RPS/3-PRS)."""
    if region.names[0] == "z":
        e = rotvec_to_euler_xyz(pose[3:], degrees=True)
        return np.array([pose[2], e[0], e[1]])
    return np.asarray(pose[:3], dtype=float).copy()


def spatial_synthesize(robot: SpatialManipulator, template, targets: dict[str, float], *, n: int = 20,
                       orientation=None, region: SpatialRegion | None = None, gap: float = DEFAULT_GAP,
                       max_boxes: int = DEFAULT_MAX_BOXES) -> SpatialSynthesis:
    """The largest uniform scaling of ``template`` meeting ``targets`` (``{"dp": mm, "dtheta_deg": deg, ...}``,
    names in :data:`TARGETS`): at every point of the workspace's ``n``-per-axis grid (Eq. 1, ``region=None``;
    ``orientation`` a 6-UPS's rotation vector, rad), or certified at every pose of ``region``
    (:func:`~pmaccuracy.accuracy.spatial_worst.spatial_region`; Eq. 2, with the branch and bound's ``gap`` and
    ``max_boxes``).

    ``template``: :class:`~pmaccuracy.model.spatial_sources.SpatialErrorSources`, a preset name or a file.
    Certified mode raises :class:`~pmaccuracy.errors.UnsupportedArchitectureError` when the architecture's
    global worst case has no certified upper bound, :class:`~pmaccuracy.errors.CertificationError` when a
    targeted quantity's bound stays infinite (budget spent near a singularity), and warns
    (:class:`~pmaccuracy.model.plausibility.PlausibilityWarning`) when a certificate stops short of ``gap``
    (the targets hold; the scale may be smaller than the largest by that gap).

    >>> import pmaccuracy as pm
    >>> robot = pm.load_robot("upu_3")
    >>> res = spatial_synthesize(robot, pm.load_clearances("upu_typical", robot), {"dp": 0.1}, n=6)
    >>> res.binding, round(res.worst["dp"], 9)
    ('dp', 0.1)
    >>> hexapod = pm.load_robot("stewart_6ups")
    >>> region = pm.spatial_region(hexapod, box=(-5, 5, -5, 5, 395, 405), orientation=(0.0, 0.0, 0.0))
    >>> res = spatial_synthesize(hexapod, "ups_typical", {"dp": 0.05}, region=region)
    >>> res.worst["dp"] <= 0.05 and res.scale <= res.scale_upper <= 1.01 * res.scale
    True
    """
    if orientation is not None:
        check_angle_values(np.linalg.norm(np.asarray(orientation, dtype=float)), "orientation (rotation vector)")
    _check_targets(targets)
    if not isinstance(template, SpatialErrorSources):
        template = SpatialErrorSources.load(template, robot)
    if not any(v for leg in template.legs for j in leg for _, v in j.items()):
        raise ConfigError("the template has no non-zero error source to scale", key="clearances")
    if region is not None:
        if orientation is not None:
            raise ConfigError("a certified synthesis takes its orientation from the region (spatial_region)",
                              key="orientation")
        return _certified(robot, template, dict(targets), region, gap, max_boxes)
    ds = spatial_error_map(robot, template, n=n, orientation=orientation)
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


def _largest_source(robot: SpatialManipulator, template: SpatialErrorSources) -> float:
    """The template's largest half-width as a length (mm; every value, angles times the characteristic length,
    an upper bound of the scale of a noise-level effect)."""
    values = [abs(float(v)) for leg in template.legs for j in leg for _, v in j.items()]
    return max(values) * max(1.0, robot.characteristic_length)


def _certified(robot, template: SpatialErrorSources, targets: dict, region: SpatialRegion, gap: float,
               max_boxes: int) -> SpatialSynthesis:
    """Eq. 2: one certificate of the template over the region, scaled."""
    if not isinstance(region, SpatialRegion):
        raise ConfigError(f"the region of a spatial robot is a SpatialRegion (spatial_region), got "
                          f"{type(region).__name__}", key="region")
    base = spatial_global_worst(robot, template, region, gap=gap, max_boxes=max_boxes)
    if not base.certified:
        raise UnsupportedArchitectureError(f"no certified synthesis for a {robot.architecture}: {base.reason} "
                                           "(the grid synthesis, without a region, is available)", key="region")
    names = list(targets)
    upper = {name: base[_quantity(name)].upper / TARGETS[name][1] for name in names}   # mm or deg
    lower = {name: base[_quantity(name)].lower / TARGETS[name][1] for name in names}
    infinite = [name for name in names if not np.isfinite(upper[name])]
    if infinite:
        raise CertificationError(f"{', '.join(infinite)}: no finite certified upper bound over {region.describe()} "
                                 "(boxes not proven regular: near a singularity?); raise max_boxes or narrow the "
                                 "region")
    size = NO_EFFECT * _largest_source(robot, template)
    L = robot.characteristic_length
    moved = [name for name in names
             if upper[name] * TARGETS[name][1] * (L if name.endswith("_deg") else 1.0) > size]
    if not moved:
        raise ConfigError("the template's sources move none of the targeted quantities: no scale bounds them",
                          key="targets")
    ratios = {name: targets[name] / upper[name] for name in moved}
    binding = min(ratios, key=ratios.get)
    scale = float(ratios[binding])
    while any(upper[name] * scale > targets[name] for name in names):   # rounding of the division
        scale = float(np.nextafter(scale, 0.0))
    his = [targets[name] / lower[name] for name in moved if lower[name] > 0]
    scale_upper = float(min(his)) if his else np.inf
    cert = scaled_spatial_worst(base, scale)
    worst = {name: upper[name] * scale for name in names}
    pose = cert[_quantity(binding)].pose.copy()
    out = SpatialSynthesis(scale=scale, sources=template.scaled(scale), binding=binding,
                           binding_point=_region_point(robot, region, pose), worst=worst, targets=dict(targets),
                           points=int(base.boxes), region=region, certificate=cert,
                           lower={name: lower[name] * scale for name in names},
                           margin={name: targets[name] - worst[name] for name in names},
                           scale_upper=scale_upper, binding_pose=pose)
    bad = out.uncertified
    if bad:
        warnings.warn(f"the certified worst case over the region is not within the requested gap of {100 * gap:.3g} "
                      "% for " + ", ".join(f"{k} ({100 * g:.3g} %)" for k, g in bad.items()) + ": the sources "
                      "meet the targets (they rely on the upper bounds) but may be that much tighter than needed; "
                      "raise max_boxes", PlausibilityWarning, stacklevel=3)
    return out


__all__ = ["TARGETS", "SpatialSynthesis", "scaled_spatial_worst", "spatial_synthesize"]
