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

from .._optional import require
from ..errors import CertificationError, ConfigError, EmptyWorkspaceError, UnsupportedArchitectureError
from ..kinematics.spatial import complete_poses, inverse_kinematics
from ..kinematics.spatial_workspace import spatial_workspace
from ..model import _tomlio
from ..model.plausibility import PlausibilityWarning, check_angle_values
from ..model.spatial import SpatialManipulator
from ..model.spatial_sources import SpatialErrorSources
from ..numerics.spatial import euler_xyz_to_rotvec, rotvec_to_euler_xyz
from .spatial_bounds import error_sources_at, spatial_pose_errors
from .spatial_maps import grid_poses, spatial_error_map
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
    mode : str
        ``"uniform"`` (one scale) or ``"min-cost"`` (one factor per source; ``scale`` None).
    factors : dict or None
        Min-cost: ``{label: z_j}``, each free source's value over the template's
        (:func:`spatial_free_sources`; labels ``legs[i].joints[j].key``).
    cost : float or None
        Min-cost: ``sum_j b_j / z_j``.
    cuts : int
        Min-cost: rounds of cutting planes.
    """

    scale: float | None
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
    mode: str = "uniform"
    factors: dict | None = None
    cost: float | None = None
    cuts: int = 0

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
                       max_boxes: int = DEFAULT_MAX_BOXES, mode: str = "uniform", costs=None,
                       max_cuts: int = 10, error_map=None) -> SpatialSynthesis:
    """The largest uniform scaling of ``template`` meeting ``targets`` (``{"dp": mm, "dtheta_deg": deg, ...}``,
    names in :data:`TARGETS`): at every point of the workspace's ``n``-per-axis grid (Eq. 1, ``region=None``;
    ``orientation`` a 6-UPS's rotation vector, rad), or certified at every pose of ``region``
    (:func:`~pmaccuracy.accuracy.spatial_worst.spatial_region`; Eq. 2, with the branch and bound's ``gap`` and
    ``max_boxes``).

    ``template``: :class:`~pmaccuracy.model.spatial_sources.SpatialErrorSources`, a preset name or a file.
    ``error_map``: the template's grid map already computed
    (:func:`~pmaccuracy.accuracy.spatial_maps.spatial_error_map` of ``robot`` and ``template`` at ``orientation``,
    e.g. by a report), used by the grid mode instead of computing it again; its grid replaces ``n``.
    Certified mode raises :class:`~pmaccuracy.errors.UnsupportedArchitectureError` when the architecture's
    global worst case has no certified upper bound, :class:`~pmaccuracy.errors.CertificationError` when a
    targeted quantity's bound stays infinite (budget spent near a singularity), and warns
    (:class:`~pmaccuracy.model.plausibility.PlausibilityWarning`) when a certificate stops short of ``gap``
    (the targets hold; the scale may be smaller than the largest by that gap).

    ``mode="min-cost"``: one factor ``z_j`` per free source (:func:`spatial_free_sources`) minimizing the
    reciprocal cost ``sum_j b_j / z_j`` (weights ``costs``: :func:`load_spatial_costs`, default 1), as the
    planar :func:`pmaccuracy.accuracy.synthesis.synthesize`: a convex program (cvxpy) on a pose set (the workspace
    grid, or an ``min(n, 9)``-per-axis grid of the region), components as linear constraints and ``|dp|``,
    ``|dtheta|`` as support cuts ``sum_j z_j g_j(u) <= T`` (``g_j`` source ``j``'s support in direction ``u``),
    refined by cutting planes at the violated poses (and the certificate's worst poses, at most ``max_cuts``
    rounds); the result is then scaled by ``min T / worst`` (the grid's values, or the certified upper bounds),
    so the targets hold as in the uniform mode.

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
    if mode not in ("uniform", "min-cost"):
        raise ConfigError(f"mode must be 'uniform' or 'min-cost', got {mode!r}", key="mode")
    if costs is not None and mode != "min-cost":
        raise ConfigError("cost weights need mode='min-cost'", key="costs")
    if region is not None:
        if orientation is not None:
            raise ConfigError("a certified synthesis takes its orientation from the region (spatial_region)",
                              key="orientation")
        if not isinstance(region, SpatialRegion):
            raise ConfigError(f"the region of a spatial robot is a SpatialRegion (spatial_region), got "
                              f"{type(region).__name__}", key="region")
    if mode == "min-cost":
        return _min_cost(robot, template, dict(targets), costs, region, n, orientation, gap, max_boxes, max_cuts)
    if region is not None:
        return _certified(robot, template, dict(targets), region, gap, max_boxes)
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


__all__ = ["TARGETS", "SpatialSynthesis", "scaled_spatial_worst", "spatial_synthesize", "spatial_free_sources",
           "load_spatial_costs"]


# ---------------------------------------------------------------------------------------------------------------
# minimum cost: one factor per source
# ---------------------------------------------------------------------------------------------------------------

#: The quantities' rows of the error twist (components: one row; |dp|, |dtheta|: three).
_ROWS = {"dx": 0, "dy": 1, "dz": 2, "drx": 3, "dry": 4, "drz": 5, "dp": slice(0, 3), "dtheta": slice(3, 6)}
#: Fixed starting directions of the norms' cuts (axes and diagonals; u and -u are the same cut).
_DIRS = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1], [1, 1, -1], [1, -1, 1], [-1, 1, 1]], dtype=float)
_DIRS /= np.linalg.norm(_DIRS, axis=1)[:, None]


def spatial_free_sources(template: SpatialErrorSources) -> list[tuple[int, int, str, float]]:
    """The template's non-zero sources ``(leg, joint, key, half-width)`` (0-based), leg by leg, joint by joint:
    the unknowns of the min-cost synthesis. Their labels are ``legs[i].joints[j].key`` (1-based)."""
    return [(i, j, key, float(v)) for i, leg in enumerate(template.legs) for j, joint in enumerate(leg)
            for key, v in joint.items()]


def _label(src) -> str:
    return f"legs[{src[0] + 1}].joints[{src[1] + 1}].{src[2]}"


def load_spatial_costs(spec, template: SpatialErrorSources) -> np.ndarray:
    """Cost weights ``b_j > 0`` ``(m,)`` of the free sources (:func:`spatial_free_sources`) from a TOML file laid
    out like a spatial clearance file (``[[legs]] joints = [{key = weight}, ...]``, one table per leg, one per
    joint; sources not listed weigh 1), or an array ``(m,)``, or None (all 1). A key that is not a free source of
    the template, a weight that is not finite and > 0, or a wrong count raise :class:`ConfigError`."""
    free = spatial_free_sources(template)
    if spec is None:
        return np.ones(len(free))
    if isinstance(spec, (list, tuple, np.ndarray)):
        b = np.asarray(spec, dtype=float)
        if b.shape != (len(free),) or not np.all(np.isfinite(b) & (b > 0)):
            raise ConfigError(f"expected {len(free)} finite weights > 0 (one per free source), got {spec!r}",
                              key="costs")
        return b
    data, source = _tomlio.read_spec(spec, kind="cost", folder=None)
    _tomlio.reject_unknown(data, {"name", "description", "legs"}, source=source, where="")
    legs = data.get("legs")
    if not isinstance(legs, list) or not all(isinstance(t, dict) for t in legs) or len(legs) > len(template.legs):
        raise ConfigError(f"must be at most {len(template.legs)} tables [[legs]]", source=source, key="legs")
    index = {(i, j, key): n for n, (i, j, key, _) in enumerate(free)}
    b = np.ones(len(free))
    for i, table in enumerate(legs):
        _tomlio.reject_unknown(table, {"joints"}, source=source, where=f"legs[{i + 1}]")
        joints = table.get("joints", [])
        if not isinstance(joints, list) or not all(isinstance(j, dict) for j in joints) \
                or len(joints) > len(template.legs[i]):
            raise ConfigError(f"must be a list of at most {len(template.legs[i])} tables {{key = weight}}",
                              source=source, key=f"legs[{i + 1}].joints")
        for k, jt in enumerate(joints):
            where = f"legs[{i + 1}].joints[{k + 1}]"
            for key in jt:
                if (i, k, key) not in index:
                    raise ConfigError("not a free source of the template (its value there is 0)", source=source,
                                      key=f"{where}.{key}")
                b[index[(i, k, key)]] = _tomlio.number(jt, key, source=source, where=where, positive=True)
    return b


def _with_factors(template: SpatialErrorSources, free, z: np.ndarray, name: str) -> SpatialErrorSources:
    """The template with free source ``j`` times ``z_j``."""
    legs = [list(leg) for leg in template.legs]
    for (i, j, key, v), f in zip(free, z):
        legs[i][j] = replace(legs[i][j], **{key: float(v * f)})
    return SpatialErrorSources(template.architecture, tuple(tuple(leg) for leg in legs), name, template.description,
                               template.specs)


def _atoms(robot, template: SpatialErrorSources, free, poses: np.ndarray):
    """Each source's contribution ``M_a`` ``(n, 6, d)`` at the poses (template half-widths) and its free source."""
    _, info = error_sources_at(robot, template, poses, strict=False, keep=True)
    index = {(i, j, key): n for n, (i, j, key, _) in enumerate(free)}
    return [(index[(a.leg, a.joint, a.key)], np.nan_to_num(a.matrix)) for a in info["sources"]]


def _support(atoms, m: int, rows: slice, U: np.ndarray) -> np.ndarray:
    """``g (n, K, m)``: each free source's support ``sum_a |M_a[rows]^T u|`` in the directions ``U (n, K, 3)``."""
    g = np.zeros(U.shape[:2] + (m,))
    for j, M in atoms:
        g[:, :, j] += np.linalg.norm(np.einsum("nrd,nkr->nkd", M[:, rows, :], U), axis=-1)
    return g


def _ascent(atoms, z: np.ndarray, rows: slice, U: np.ndarray, steps: int = 25) -> np.ndarray:
    """Directions ``(n, K, 3)`` of larger support of the set of factors ``z`` (fixed point ``u <- grad / |grad|``
    of the convex support function, from ``U``): the cuts of the norms."""
    for _ in range(steps):
        grad = np.zeros_like(U)
        for j, M in atoms:
            Mr = M[:, rows, :]
            y = np.einsum("nrd,nkr->nkd", Mr, U)
            ny = np.linalg.norm(y, axis=-1, keepdims=True)
            grad += z[j] * np.einsum("nrd,nkd->nkr", Mr, y / np.where(ny > 0, ny, 1.0))
        n = np.linalg.norm(grad, axis=-1, keepdims=True)
        U = np.where(n > 0, grad / np.where(n > 0, n, 1.0), U)
    return U


def _values(robot, sources: SpatialErrorSources, poses: np.ndarray) -> np.ndarray:
    """``(n, 8)`` the six components and certified ``|dp|``, ``|dtheta|`` upper bounds (mm, rad)."""
    b = spatial_pose_errors(robot, sources, poses, strict=False, details=False)
    return np.column_stack([b.components, b.dp_upper, b.dtheta_upper])


def _constraint_poses(robot, region: SpatialRegion | None, n: int, orientation) -> np.ndarray:
    """The poses ``(k, 6)`` the cone program is solved on: the workspace grid (grid mode) or an ``n``-per-axis
    grid of the region's box (3 per orientation range of a 6-UPS) in the region and within the joint limits."""
    if region is None:
        reg = spatial_workspace(robot, orientation=orientation, n=n, tilt=False).region
        grid = np.stack(np.meshgrid(*reg.axes, indexing="ij"), axis=-1)[reg.inside]
        poses = grid_poses(robot, grid, orientation)
    else:
        axes = [np.linspace(lo, hi, n if hi > lo else 1) for lo, hi in region.bounds]
        pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        pts = pts[region.contains(pts)]
        if robot.mobility == "6":
            o = [np.linspace(lo, hi, 3 if hi > lo else 1) for lo, hi in region.orientation]
            angles = np.stack(np.meshgrid(*o, indexing="ij"), axis=-1).reshape(-1, 3)
            rot = euler_xyz_to_rotvec(angles)
            poses = np.concatenate([np.repeat(pts, len(rot), axis=0), np.tile(rot, (len(pts), 1))], axis=1)
        elif robot.mobility == "2R1T":
            poses = complete_poses(robot, pts, strict=False)
        else:
            poses = np.concatenate([pts, np.zeros_like(pts)], axis=1)
    poses = poses[np.all(np.isfinite(poses), axis=1)]
    if poses.shape[0]:
        poses = poses[np.asarray(inverse_kinematics(robot, poses).within_limits)]
    if not poses.shape[0]:
        raise EmptyWorkspaceError("no pose of the grid is in the workspace")
    return poses


def _solve(rows: list, rhs: list, weights: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Minimize ``sum b_j / z_j`` over the ``free`` sources (the others at ``z = 1``) subject to ``A z <= t``
    (convex; cvxpy, Clarabel)."""
    cp = require("cvxpy", "the min-cost synthesis")
    A = np.vstack(rows)
    t = np.concatenate(rhs) - A[:, ~free].sum(axis=1)
    if np.any(t <= 0):
        raise ConfigError("the sources without first-order effect on some targets alone exceed them",
                          key="targets")
    A = A[:, free]
    scale = np.max(np.abs(A), axis=1)
    keep = scale > 0
    A, t = A[keep] / scale[keep, None], t[keep] / scale[keep]
    z = cp.Variable(A.shape[1], pos=True)
    prob = cp.Problem(cp.Minimize(weights[free] @ cp.inv_pos(z)), [A @ z <= t])
    try:
        prob.solve(solver=cp.CLARABEL)
    except cp.error.SolverError as exc:
        raise CertificationError(f"the min-cost program could not be solved ({exc}): narrow the region") from None
    if z.value is None or prob.status not in ("optimal", "optimal_inaccurate"):
        raise CertificationError(f"the min-cost program failed ({prob.status})")
    out = np.ones(len(free))
    out[free] = np.maximum(np.asarray(z.value, dtype=float), 1e-12)
    return out


def _min_cost(robot, template: SpatialErrorSources, targets: dict, costs, region, n: int, orientation, gap: float,
              max_boxes: int, max_cuts: int) -> SpatialSynthesis:
    """Per-source factors ``z_j`` minimizing ``sum b_j / z_j`` under the targets: cutting planes on a pose set
    (components: linear constraints; ``|dp|``, ``|dtheta|``: support cuts ``sum_j z_j g_j(u) <= T``), then scaled
    by ``min T / max`` (the grid's values, or the certificate over the region) so the targets hold."""
    free = spatial_free_sources(template)
    m = len(free)
    weights = load_spatial_costs(costs, template)
    poses = _constraint_poses(robot, region, n if region is None else min(n, 9), orientation)
    base = _values(robot, template, poses)
    ok = np.all(np.isfinite(base), axis=1)
    poses, base = poses[ok], base[ok]
    if not poses.shape[0]:
        raise EmptyWorkspaceError("no pose of the grid could be evaluated")
    atoms = _atoms(robot, template, free, poses)
    names = list(targets)
    qs = [_quantity(k) for k in names]
    T = {q: targets[k] * TARGETS[k][1] for k, q in zip(names, qs)}
    order = ("dx", "dy", "dz", "drx", "dry", "drz", "dp", "dtheta")
    cols = {q: order.index(q) for q in qs}
    # components: every pose (linear); norms: the template's 200 worst poses, fixed directions + ascent
    comp = {}
    for q in qs:
        if q not in ("dp", "dtheta"):
            C = np.zeros((poses.shape[0], m))
            for j, M in atoms:
                C[:, j] += np.linalg.norm(M[:, _ROWS[q], :], axis=-1)
            comp[q] = C
    cuts = {q: [] for q in qs if q in ("dp", "dtheta")}

    def add_cuts(q, idx, z):
        U0 = np.broadcast_to(_DIRS, (len(idx), len(_DIRS), 3)).copy()
        sub = [(j, M[idx]) for j, M in atoms]
        U = _ascent(sub, z, _ROWS[q], U0)
        cuts[q].append(_support(sub, m, _ROWS[q], np.concatenate([U0, U], axis=1)).reshape(-1, m))

    for q in cuts:
        idx = np.argsort(base[:, cols[q]])[-200:]
        add_cuts(q, idx, np.ones(m))
    z, rounds, cert, effect = np.ones(m), 0, None, None
    while True:
        cert = None
        A = [comp[q] for q in comp] + [np.vstack(cuts[q]) for q in cuts]
        t = [np.full(comp[q].shape[0], T[q]) for q in comp] + [np.full(sum(c.shape[0] for c in cuts[q]), T[q])
                                                                 for q in cuts]
        if effect is None:   # a source moving no targeted quantity anywhere keeps its template value
            effect = np.array([max(float(np.max(a[:, j] / T[q])) for a, q in zip(A, list(comp) + list(cuts)))
                               for j in range(m)])
            effect = effect > NO_EFFECT * np.max(effect)
            if not np.any(effect):
                raise ConfigError("the template's sources move none of the targeted quantities", key="targets")
            if not np.all(effect):
                warnings.warn(", ".join(_label(f) for f, e in zip(free, effect) if not e) + ": no first-order "
                              "effect on the targeted errors, kept at the template's value", PlausibilityWarning,
                              stacklevel=3)
        z = _solve(A, t, weights, effect)
        design = _with_factors(template, free, z, f"min_cost_{robot.name}")
        vals = _values(robot, design, poses)
        over = {q: np.flatnonzero(vals[:, cols[q]] > T[q] * (1 + 1e-6)) for q in cuts}
        if region is not None and not any(len(v) for v in over.values()):
            cert = spatial_global_worst(robot, design, region, gap=gap, max_boxes=max_boxes)
            extra = [cert[q].pose for q in qs if cert[q].upper > T[q] * (1 + gap)]
            if extra and rounds < max_cuts:
                new = np.array(extra)
                poses = np.vstack([poses, new])
                more = _atoms(robot, template, free, new)
                atoms = [(j, np.concatenate([M, M2])) for (j, M), (_, M2) in zip(atoms, more)]
                for q in comp:
                    C = np.zeros((len(new), m))
                    for j, M in more:
                        C[:, j] += np.linalg.norm(M[:, _ROWS[q], :], axis=-1)
                    comp[q] = np.vstack([comp[q], C])
                for q in cuts:
                    add_cuts(q, np.arange(poses.shape[0] - len(new), poses.shape[0]), z)
                rounds += 1
                continue
        if not any(len(v) for v in over.values()) or rounds >= max_cuts:
            break
        for q, idx in over.items():
            if len(idx):
                add_cuts(q, idx[np.argsort(vals[idx, cols[q]])[-200:]], z)
        rounds += 1
    design = _with_factors(template, free, z, f"min_cost_{robot.name}")
    if region is None:
        vals = _values(robot, design, poses)
        worst_q = {q: float(np.nanmax(vals[:, cols[q]])) for q in qs}
    else:
        cert = cert if cert is not None else spatial_global_worst(robot, design, region, gap=gap,
                                                                  max_boxes=max_boxes)
        if not cert.certified:
            raise UnsupportedArchitectureError(f"no certified synthesis for a {robot.architecture}: {cert.reason}",
                                               key="region")
        worst_q = {q: cert[q].upper for q in qs}
    shrink = min([1.0] + [T[q] / worst_q[q] for q in qs if worst_q[q] > 0])
    while any(worst_q[q] * shrink > T[q] for q in qs):
        shrink = float(np.nextafter(shrink, 0.0))
    z = z * shrink
    design = _with_factors(template, free, z, f"min_cost_{robot.name}")
    worst = {k: worst_q[q] * shrink / TARGETS[k][1] for k, q in zip(names, qs)}
    binding = max(names, key=lambda k: worst[k] / targets[k])
    common = dict(scale=None, sources=design, binding=binding, worst=worst, targets=dict(targets), mode="min-cost",
                  factors={_label(f): float(v) for f, v in zip(free, z)},
                  cost=float(weights[effect] @ (1.0 / z[effect])),
                  cuts=rounds)
    if region is None:
        k = int(np.nanargmax(vals[:, cols[_quantity(binding)]]))
        return SpatialSynthesis(binding_point=poses[k, :3].copy(), points=int(poses.shape[0]), **common)
    cert = scaled_spatial_worst(cert, shrink)
    pose = cert[_quantity(binding)].pose.copy()
    lower = {k: cert[q].lower / TARGETS[k][1] for k, q in zip(names, qs)}
    return SpatialSynthesis(binding_point=_region_point(robot, region, pose), points=int(cert.boxes), region=region,
                            certificate=cert, lower=lower, margin={k: targets[k] - worst[k] for k in names},
                            binding_pose=pose, **common)
