"""Tolerance synthesis: the largest clearances / tolerances per joint that keep the worst-case errors within
targets everywhere in a region.

Unknowns. The free sources are the keys with a non-zero value in a template
(per-joint :class:`~pmaccuracy.model.sources.ErrorSources`, or the 3-PPR format
converted): ``eps_j = eps0_j z_j`` with the template value ``eps0_j`` and a
dimensionless ``z_j >= 0`` (block lengths are kept).

Linearity. Each leg's half-width is a sum over its sources of ``eps_j w_j(X)``
with ``w_j >= 0`` (:func:`pmaccuracy.model.sources.half_widths` of a unit source; the
guide rhombus's ``max(eps |shift|, 2 eps |tilt| / L)`` is ``eps`` times a
maximum too), so at a pose ``X`` with ``leg(j)`` the leg of source ``j``::

    dx(X)   = sum_j eps_j w_j(X) |A^-1[0, leg(j)]|                 (likewise dy, dphi: linear, >= 0)
    dp(X)   = max over t in {+-1}^3 of || sum_j eps_j t_leg(j) w_j(X) A^-1[:2, leg(j)] ||_2

``dx, dy, dphi <= target`` are linear inequalities and ``dp <= target`` four
second-order cones per pose.

Uniform scaling. Every quantity is homogeneous of degree 1 in ``eps``, so the
largest factor is ``s = min_q target_q / max_R Q(template)``, taken with the
certified upper bounds of :func:`pmaccuracy.accuracy.global_worst.global_worst`.

Minimum cost. The cost of tightness is the reciprocal model of tolerance
allocation, ``cost = sum_j b_j eps0_j / eps_j = sum_j b_j / z_j`` (each joint
costs ``b_j`` at the template's value and twice that at half of it; weights
``b_j > 0`` from a cost file, default 1). It is convex, so the problem is a
second-order cone program (cvxpy, Clarabel). The region's constraints are
imposed on a finite pose set, refined by cutting planes: solve on a grid, certify
with :func:`~pmaccuracy.accuracy.global_worst.global_worst`, add the poses attaining any
violated maximum, re-solve, until the certified upper bounds meet every target.
When the certificate's gap leaves a bound above a target the result is scaled by
``min_q target_q / upper_q`` (homogeneity), so the returned clearances are
certified to meet the targets.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace

import numpy as np

from ..model import _tomlio
from ..errors import CertificationError, ConfigError
from ..model.clearances import ClearanceSet
from ..model.manipulator import Manipulator
from ..model.spatial import is_spatial
from ..model.spatial_sources import default_preset
from .global_worst import DEFAULT_GAP, GlobalWorst, QuantityWorst, Region, as_sources, global_worst
from .spatial_synthesis import TARGETS as SPATIAL_TARGETS, spatial_synthesize
from .spatial_worst import SpatialRegion
from ..model.plausibility import PlausibilityWarning
from ..kinematics import inverse_3x3, inverse_kinematics
from ..model.sources import KEYS, ErrorSources, JointErrors, half_widths
from ..io.resolve import DEFAULT_CLEARANCES, default_clearances, load_clearances
from .._optional import require
from ..io.resolve import robot_arg
from ..kinematics.workspace import constant_orientation_workspace

#: Target names and their units on the command line / in files (dphi in degrees).
TARGETS = {"dx": "mm", "dy": "mm", "dp": "mm", "dphi_deg": "deg"}
#: Target name -> quantity of :data:`pmaccuracy.accuracy.bounds.QUANTITIES`.
QUANTITY = {"dx": "dx", "dy": "dy", "dp": "dp", "dphi_deg": "dphi"}
#: Default template per parallel architecture: the default clearances of every command
#: (:data:`pmaccuracy.io.resolve.DEFAULT_CLEARANCES`).
DEFAULT_TEMPLATES = {k: v for k, v in DEFAULT_CLEARANCES.items() if k != "serial"}
_SIGNS = np.array([[1, 1, 1], [1, 1, -1], [1, -1, 1], [1, -1, -1]], dtype=float)


def parse_targets(items) -> dict[str, float]:
    """Targets from ``["dp=0.3", "dphi_deg=0.3"]`` or a mapping: ``{quantity: value}`` in mm / rad.

    Raises :class:`ConfigError` (key ``--target``) for unknown names, repeated
    names, values that are not finite and > 0, and an empty list.
    """
    pairs = list(items.items()) if isinstance(items, dict) else []
    if not isinstance(items, dict):
        for item in items or []:
            name, sep, value = str(item).partition("=")
            if not sep:
                raise ConfigError(f"expected NAME=VALUE, got {item!r}", key="--target")
            pairs.append((name.strip(), value.strip()))
    if not pairs:
        raise ConfigError(f"give at least one target ({', '.join(TARGETS)})", key="--target")
    out: dict[str, float] = {}
    for name, value in pairs:
        if name not in TARGETS:
            hint = " (use dphi_deg, in degrees)" if name == "dphi" else ""
            raise ConfigError(f"unknown target {name!r}{hint}; targets: {', '.join(TARGETS)}", key="--target")
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise ConfigError(f"{name}: not a number: {value!r}", key="--target") from None
        if not (np.isfinite(v) and v > 0):
            raise ConfigError(f"{name} must be finite and > 0 {TARGETS[name]}, got {value}", key="--target")
        q = QUANTITY[name]
        if q in out:
            raise ConfigError(f"{name} given twice", key="--target")
        out[q] = np.radians(v) if name == "dphi_deg" else v
    return out


def default_template(robot: Manipulator) -> str:
    """The clearance preset used as template: the default clearances of every command
    (:func:`pmaccuracy.io.resolve.default_clearances`: ``case1`` for a 3-PPR, the architecture's ``*_typical``)."""
    return default_clearances(robot)


@dataclass(frozen=True)
class Source:
    """One free source: leg and joint (0-based), key of :data:`pmaccuracy.model.sources.KEYS`, template value."""

    leg: int
    joint: int
    key: str
    value: float

    @property
    def label(self) -> str:
        return f"legs[{self.leg + 1}].joints[{self.joint + 1}].{self.key}"


def free_sources(template: ErrorSources) -> list[Source]:
    """The template's non-zero keys (block lengths excluded), leg by leg, joint by joint."""
    out = []
    for i, leg in enumerate(template.legs):
        for k, joint in enumerate(leg):
            for f in fields(joint):
                if f.name != "block_length" and getattr(joint, f.name) > 0:
                    out.append(Source(i, k, f.name, float(getattr(joint, f.name))))
    if not out:
        raise ConfigError("the template has no non-zero clearance or tolerance to scale", key="--clearances")
    return out


def with_values(template: ErrorSources, sources: list[Source], values: np.ndarray, name: str) -> ErrorSources:
    """The template with every free source set to ``values`` (same units) and the others at 0."""
    legs = [[replace(j, **{f.name: 0.0 for f in fields(j) if f.name != "block_length"}) for j in leg]
            for leg in template.legs]
    for s, v in zip(sources, values):
        legs[s.leg][s.joint] = replace(legs[s.leg][s.joint], **{s.key: float(v)})
    return ErrorSources(legs=tuple(tuple(leg) for leg in legs), name=name)


def load_costs(spec, template: ErrorSources, sources: list[Source]) -> np.ndarray:
    """Cost weights ``b_j > 0`` ``(n_sources,)`` from a TOML file laid out like a per-joint clearance file
    (``[[legs]] joints = [{key = weight}, ...]``); sources not listed weigh 1. A key that is not a free
    source of the template, or a weight that is not finite and > 0, raises :class:`ConfigError`."""
    b = np.ones(len(sources))
    if spec is None:
        return b
    data, source = _tomlio.read_spec(spec, kind="cost", folder=None)
    _tomlio.reject_unknown(data, {"name", "description", "legs"}, source=source, where="")
    index = {(s.leg, s.joint, s.key): n for n, s in enumerate(sources)}
    for i, table in enumerate(_tomlio.legs_table(data, source=source)):
        joints = table.get("joints", [])
        if not isinstance(joints, list) or len(joints) > 3 or not all(isinstance(j, dict) for j in joints):
            raise ConfigError("must be a list of at most three tables {key = weight}", source=source,
                              key=f"legs[{i + 1}].joints")
        for k, jt in enumerate(joints):
            where = f"legs[{i + 1}].joints[{k + 1}]"
            for key in jt:
                if key not in KEYS or key == "block_length":
                    raise ConfigError(f"unknown source {key!r}", source=source, key=f"{where}.{key}")
                w = _tomlio.number(jt, key, source=source, where=where, positive=True)
                if (i, k, key) not in index:
                    raise ConfigError("not a free source of the template (its value there is 0)", source=source,
                                      key=f"{where}.{key}")
                b[index[(i, k, key)]] = w
    return b


def pose_coefficients(robot: Manipulator, template: ErrorSources, sources: list[Source], poses: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Coefficients of the quantities in the normalized unknowns ``z`` at poses ``(n, 3)`` in the workspace.

    Returns ``lin (n, 3, m)``: ``dx, dy, dphi = lin @ z``, and ``Mx, My (n, 4, m)``:
    ``dp = max over the 4 sign patterns of |(Mx @ z, My @ z)|`` (module docstring),
    with ``m`` free sources and ``eps_j = eps0_j z_j``.
    """
    ik = inverse_kinematics(robot, poses)
    A_inv, _ = inverse_3x3(ik.A)
    m = len(sources)
    W = np.empty((poses.shape[0], m))
    for j, s in enumerate(sources):
        unit = np.zeros(m)
        unit[j] = s.value
        W[:, j] = half_widths(robot, with_values(template, sources, unit, "unit"), ik.joints, poses)[:, s.leg]
    legs = np.array([s.leg for s in sources])
    cols = A_inv[:, :, legs] * W[:, None, :]                     # (n, 3, m): A^-1[:, leg(j)] w_j eps0_j
    lin = np.abs(cols)
    t = _SIGNS[:, legs]                                          # (4, m)
    Mx = cols[:, None, 0, :] * t[None]
    My = cols[:, None, 1, :] * t[None]
    return lin, Mx, My


@dataclass(frozen=True)
class Synthesis:
    """Result of :func:`synthesize`.

    clearances : the synthesized :class:`ErrorSources` (mm / rad);  sources : the free sources
    values : ``(m,)`` their half-widths (mm / rad);  template_values : ``(m,)``
    mode : ``"uniform"`` or ``"min-cost"``;  scale : the uniform factor (min-cost: None)
    cost : ``sum b_j eps0_j / eps_j`` (min-cost; None for uniform)
    targets : ``{quantity: target}`` mm / rad;  worst : the certificate of the result
    cuts : cutting-plane rounds; poses : constraint poses at the end
    certified : every targeted quantity's certificate reached the requested gap (:attr:`uncertified` lists
    the others with their gaps; the result still meets the targets, since it relies on the upper bounds, but
    may be up to that gap tighter than needed)
    """

    clearances: ErrorSources
    sources: list
    values: np.ndarray
    template_values: np.ndarray
    mode: str
    scale: float | None
    cost: float | None
    targets: dict
    worst: GlobalWorst
    cuts: int
    poses: int

    @property
    def uncertified(self) -> dict[str, float]:
        """``{quantity: gap}`` (relative) of the targeted quantities whose certificate did not reach the gap."""
        return {q: self.worst[q].gap for q in self.targets if not self.worst[q].converged}

    @property
    def certified(self) -> bool:
        return not self.uncertified


def scaled_worst(worst: GlobalWorst, factor: float) -> GlobalWorst:
    """The certificate of the clearances times ``factor > 0``: every quantity is homogeneous of degree 1 in
    the sources' values (module docstring), so its lower and upper bounds scale by ``factor`` at the same
    poses, with the same gap (no second branch and bound)."""
    out = {q: QuantityWorst(name=w.name, lower=w.lower * factor, upper=w.upper * factor, pose=w.pose.copy(),
                            gap=w.gap, converged=w.converged) for q, w in worst.quantities.items()}
    return replace(worst, quantities=out)


def _warn_uncertified(result: "Synthesis", target_gap: float) -> None:
    bad = result.uncertified
    if bad:
        warnings.warn("the certified worst case is not within the requested gap of "
                      f"{100 * target_gap:.3g} % for " + ", ".join(f"{q} ({100 * g:.3g} %)" for q, g in bad.items())
                      + ": the clearances meet the targets (they rely on the upper bounds) but may be that much "
                      "tighter than needed", PlausibilityWarning, stacklevel=3)


def _region_grid(robot, region: Region, n: int) -> np.ndarray:
    """Initial constraint poses: an ``n x n`` grid of the region's box cut to the workspace's bounds at
    ``max(3, n // 3)`` orientations (one for a fixed phi), poses in the region's shape and the workspace only."""

    out = [np.zeros((0, 3))]
    for phi in np.linspace(*region.phi, 1 if region.phi[0] == region.phi[1] else max(3, n // 3)):
        ws = constant_orientation_workspace(robot, float(phi))
        if ws.is_empty:
            continue
        (wx0, wx1), (wy0, wy1) = ws.bounds
        x0, x1, y0, y1 = max(region.x[0], wx0), min(region.x[1], wx1), max(region.y[0], wy0), min(region.y[1], wy1)
        if x0 > x1 or y0 > y1:
            continue
        X, Y = np.meshgrid(np.linspace(x0, x1, n), np.linspace(y0, y1, n), indexing="ij")
        keep = region.contains(X.ravel(), Y.ravel())
        out.append(np.column_stack([X.ravel()[keep], Y.ravel()[keep], np.full(int(keep.sum()), phi)]))
    g = np.vstack(out)
    return g[inverse_kinematics(robot, g).within_limits]


#: A source moving the platform by less than this fraction of its own size (lengths; angles times the
#: characteristic length) has no first-order effect: rounding noise of an exact zero.
NO_EFFECT = 1e-9


def _lengths(robot: Manipulator, sources: list[Source]) -> np.ndarray:
    """Template values as lengths (mm): angles (``angular``, ``direction``, an actuated revolute's
    ``actuator``) times the characteristic length."""
    L = robot.characteristic_length
    out = []
    for s in sources:
        angle = s.key in ("angular", "direction") or \
            (s.key == "actuator" and robot.chains[s.leg].joints[s.joint].kind == "R")
        out.append(s.value * (L if angle else 1.0))
    return np.array(out)


def _effective(robot, sources, lin, Mx, My, targets: dict) -> np.ndarray:
    """bool ``(m,)``: sources with a first-order effect on a targeted quantity at some of the poses
    (:data:`NO_EFFECT`)."""
    m = lin.shape[2]
    L = robot.characteristic_length
    parts = [np.abs(lin[:, r, :]) * (L if q == "dphi" else 1.0)
             for r, q in enumerate(("dx", "dy", "dphi")) if q in targets]
    if "dp" in targets:
        parts += [np.abs(Mx).reshape(-1, m), np.abs(My).reshape(-1, m)]
    size = np.max(np.concatenate(parts), axis=0)
    return size > NO_EFFECT * _lengths(robot, sources)


def _solve(lin, Mx, My, targets: dict, weights: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Minimize ``sum b_j / z_j`` over the ``free`` sources (the others at ``z = 1``) subject to the pose
    constraints (SOCP, Clarabel); returns ``z (m,)``."""
    cp = require("cvxpy")

    z = cp.Variable(int(free.sum()), pos=True)
    fixed = ~free

    def expr(M):   # M (k, m) @ z_full
        return M[:, free] @ z + M[:, fixed].sum(axis=1)

    cons = []
    for r, q in enumerate(("dx", "dy", "dphi")):
        if q in targets:
            cons.append(expr(lin[:, r, :]) <= targets[q])
    if "dp" in targets:
        m = lin.shape[2]
        X, Y = Mx.reshape(-1, m), My.reshape(-1, m)
        cons.append(cp.SOC(np.full(X.shape[0], targets["dp"]), cp.vstack([expr(X), expr(Y)]), axis=0))
    prob = cp.Problem(cp.Minimize(weights[free] @ cp.inv_pos(z)), cons)
    try:
        prob.solve(solver=cp.CLARABEL)
    except cp.error.SolverError as exc:   # numerically hopeless data, e.g. poses near a singularity
        worst = float(np.max(np.abs(lin))) if lin.size else float("nan")
        raise CertificationError(f"the cone program of the min-cost synthesis could not be solved ({exc}); its "
                                 f"pose coefficients reach {worst:.3g} (near a singularity they grow without "
                                 "bound): narrow the region or use the uniform mode") from None
    if z.value is None or prob.status not in ("optimal", "optimal_inaccurate"):
        raise ConfigError(f"the cone program failed ({prob.status}): the targets may be unreachable with the "
                          "sources kept fixed", key="--target")
    out = np.ones(lin.shape[2])
    out[free] = np.maximum(np.asarray(z.value, dtype=float), 0.0)
    return out


def targets_arg(targets) -> dict[str, float]:
    """Targets ``{quantity: value}`` (mm / rad) from what :func:`synthesize` takes: a mapping with the
    quantities ``dx, dy, dp`` (mm) and ``dphi`` (rad) or ``dphi_deg`` (deg), or ``["dp=0.3", "dphi_deg=0.3"]``
    (:func:`parse_targets`). Unknown or repeated names and values that are not finite and > 0 raise
    :class:`ConfigError` (key ``targets``)."""
    if isinstance(targets, Mapping):
        items = dict(targets)
        dphi = items.pop("dphi", None)
        if dphi is not None and "dphi_deg" in items:
            raise ConfigError("give dphi (rad) or dphi_deg (deg), not both", key="targets")
        try:
            out = parse_targets(items) if items or dphi is None else {}
        except ConfigError as exc:
            raise ConfigError(exc.message, key="targets") from None
        if dphi is not None:
            try:
                value = float(dphi)
            except (TypeError, ValueError):
                raise ConfigError(f"dphi: not a number: {dphi!r}", key="targets") from None
            if not (np.isfinite(value) and value > 0):
                raise ConfigError(f"dphi must be finite and > 0 rad, got {dphi}", key="targets")
            out["dphi"] = value
        return out
    if isinstance(targets, (list, tuple)) and all(isinstance(t, str) for t in targets):
        return parse_targets(targets)
    raise ConfigError(f"expected a mapping {{quantity: value}} (dx, dy, dp mm; dphi rad or dphi_deg deg) or "
                      f"['dp=0.3', ...], got {type(targets).__name__}", key="targets")


def synthesize(robot: Manipulator, region: Region, targets: dict, *, clearances=None, template=None,
               costs=None, mode: str = "uniform", gap: float | None = None, grid: int = 15, max_cuts: int = 10,
               name: str | None = None, max_boxes: int | None = None) -> Synthesis:
    """Largest clearances meeting ``targets`` over ``region`` (:func:`pmaccuracy.accuracy.global_worst.make_region`),
    certified by the global worst case.

    ``targets``: ``{quantity: value}`` with ``dx, dy, dp`` in mm and ``dphi`` in rad (or ``dphi_deg`` in
    deg), or ``["dp=0.3", "dphi_deg=0.3"]`` (:func:`targets_arg`).
    ``clearances``: your clearances (a preset name, a file or an object, as everywhere in the package): the
    template whose non-zero sources are the unknowns, starting from their values; ``template`` is the same
    argument under its older name (give one of them). Without either, :func:`default_template`.
    ``mode="uniform"``: the template times the largest factor (module docstring);
    ``"min-cost"``: per-source values minimizing ``sum b_j eps0_j / eps_j`` with
    the weights of ``costs`` (:func:`load_costs`: a file, or an array ``(m,)``). ``max_boxes``: the budget
    of each certificate (:func:`~pmaccuracy.accuracy.global_worst.global_worst`); the uniform mode certifies
    once, the template, and scales that certificate (:func:`scaled_worst`). Where a targeted quantity's
    certificate stops short of ``gap`` the result says so (``certified``, ``uncertified``) and a
    :class:`~pmaccuracy.model.plausibility.PlausibilityWarning` gives the gaps.

    ``gap``: default :data:`~pmaccuracy.accuracy.global_worst.DEFAULT_GAP`; ``max_boxes``: default 2 000 000.

    A spatial robot takes a :class:`~pmaccuracy.accuracy.spatial_worst.SpatialRegion`
    (:func:`~pmaccuracy.accuracy.spatial_worst.spatial_region`) and targets named as in
    :data:`pmaccuracy.accuracy.spatial_synthesis.TARGETS` (a mapping, or ``["dp=0.05", ...]``), both modes
    (``costs``: :func:`~pmaccuracy.accuracy.spatial_synthesis.load_spatial_costs`), and gives the certified
    :class:`~pmaccuracy.accuracy.spatial_synthesis.SpatialSynthesis` of
    :func:`~pmaccuracy.accuracy.spatial_synthesis.spatial_synthesize` (``gap`` default 1 %).

    Raises :class:`ConfigError` naming the argument: ``region`` not a :class:`Region` (clearances passed
    in its place, as the other functions' second argument: they go in ``clearances=``), ``clearances`` and
    ``template`` both given, unknown targets.
    """
    robot = robot_arg(robot)
    if clearances is not None and template is not None and clearances is not template:
        raise ConfigError("give the clearances to scale once: clearances= (template= is its older name)",
                          key="clearances")
    if is_spatial(robot):
        return _spatial(robot, region, targets, clearances if clearances is not None else template, costs, mode,
                        gap, max_boxes)
    gap = DEFAULT_GAP if gap is None else gap
    max_boxes = 2_000_000 if max_boxes is None else max_boxes
    if not isinstance(region, Region):
        hint = " (the clearances to scale go in clearances=)" \
            if isinstance(region, (ErrorSources, ClearanceSet, str)) else ""
        raise ConfigError(f"expected a Region (make_region), got {type(region).__name__}{hint}", key="region")
    targets = targets_arg(targets)
    if mode not in ("uniform", "min-cost"):
        raise ConfigError(f"mode must be 'uniform' or 'min-cost', got {mode!r}", key="mode")
    given = clearances if clearances is not None else template
    tpl = as_sources(robot, load_clearances(default_template(robot) if given is None else given, robot))
    sources = free_sources(tpl)
    eps0 = np.array([s.value for s in sources])
    name = name or f"synthesized_{robot.name}"
    tq = list(targets)
    if mode == "uniform":
        base = global_worst(robot, tpl, region, gap=gap, max_boxes=max_boxes)
        size = NO_EFFECT * float(np.max(_lengths(robot, sources)))
        L = robot.characteristic_length
        ratios = [targets[q] / base[q].upper for q in tq if base[q].upper * (L if q == "dphi" else 1.0) > size]
        if not ratios:
            raise ConfigError("the template's sources do not affect the targeted errors", key="--target")
        scale = min(ratios)
        result = with_values(tpl, sources, eps0 * scale, name)
        out = Synthesis(result, sources, eps0 * scale, eps0, mode, float(scale), None, dict(targets),
                        scaled_worst(base, float(scale)), 0, 0)
        _warn_uncertified(out, gap)
        return out
    weights = np.asarray(costs, dtype=float) if isinstance(costs, (list, tuple, np.ndarray)) else \
        load_costs(costs, tpl, sources)
    poses = _region_grid(robot, region, grid)
    start = global_worst(robot, tpl, region, gap=gap, max_boxes=max_boxes)
    poses = np.vstack([poses] + [start[q].pose[None] for q in tq])
    cuts = 0
    free = None
    while True:
        lin, Mx, My = pose_coefficients(robot, tpl, sources, poses)
        if free is None:
            free = _effective(robot, sources, lin, Mx, My, targets)
            if not np.any(free):
                raise ConfigError("no source of the template affects the targeted errors", key="--target")
            if not np.all(free):
                warnings.warn(", ".join(s.label for s, f in zip(sources, free) if not f) + ": no first-order "
                              "effect on the targeted errors in the region, kept at the template's value")
        z = _solve(lin, Mx, My, targets, weights, free)
        result = with_values(tpl, sources, eps0 * z, name)
        worst = global_worst(robot, result, region, gap=gap, max_boxes=max_boxes)
        over = [q for q in tq if worst[q].upper > targets[q]]
        if not over or cuts >= max_cuts:
            break
        new = np.array([worst[q].pose for q in over])
        fresh = ~np.any(np.all(np.isclose(new[:, None, :], poses[None], rtol=0, atol=1e-9), axis=-1), axis=1)
        if not np.any(fresh):
            break
        poses = np.vstack([poses, new[fresh]])
        cuts += 1
    shrink = min([1.0] + [targets[q] / worst[q].upper for q in tq if worst[q].upper > 0])
    if shrink < 1.0:
        z = z * shrink
        result = with_values(tpl, sources, eps0 * z, name)
        worst = scaled_worst(worst, shrink)   # homogeneity: the same certificate, scaled
    out = Synthesis(result, sources, eps0 * z, eps0, mode, None, float(weights[free] @ (1.0 / z[free])),
                    dict(targets), worst, cuts, poses.shape[0])
    _warn_uncertified(out, gap)
    return out


def _spatial(robot, region, targets, given, costs, mode: str, gap, max_boxes):
    """:func:`synthesize` of a spatial robot: :func:`~pmaccuracy.accuracy.spatial_synthesis.spatial_synthesize`
    certified over ``region``."""
    if not isinstance(region, SpatialRegion):
        raise ConfigError(f"the region of a spatial robot is a SpatialRegion (spatial_region), got "
                          f"{type(region).__name__}", key="region")
    if isinstance(targets, (list, tuple)) and all(isinstance(t, str) for t in targets):
        pairs = {}
        for item in targets:
            name, sep, value = item.partition("=")
            try:
                v = float(value)
            except ValueError:
                v = None
            if not sep or v is None or name.strip() in pairs:
                raise ConfigError(f"expected NAME=VALUE once per name (NAME one of {', '.join(SPATIAL_TARGETS)}), "
                                  f"got {item!r}", key="targets")
            pairs[name.strip()] = v
        targets = pairs
    elif not isinstance(targets, Mapping):
        raise ConfigError(f"expected a mapping {{target: value}} ({', '.join(SPATIAL_TARGETS)}; mm, deg) or "
                          f"['dp=0.05', ...], got {type(targets).__name__}", key="targets")
    kw = {k: v for k, v in (("gap", gap), ("max_boxes", max_boxes)) if v is not None}
    return spatial_synthesize(robot, default_preset(robot) if given is None else given, dict(targets),
                              region=region, mode=mode, costs=costs, **kw)


def clearance_toml(result: Synthesis, robot: Manipulator, region: Region) -> str:
    """The synthesized per-joint clearance file (TOML text, mm / rad), with its targets and certificate as
    comments; :func:`pmaccuracy.load_clearances` reads it back. ``robot``: an object, a preset name or a robot
    file (as everywhere); ``result`` and ``region`` must be a :class:`Synthesis` and a :class:`Region`
    (ConfigError naming the argument otherwise)."""
    import tomli_w

    robot = robot_arg(robot)
    for name, value, kind in (("result", result, Synthesis), ("region", region, Region)):
        if not isinstance(value, kind):
            raise ConfigError(f"expected a {kind.__name__} (from {'synthesize' if kind is Synthesis else 'make_region'}"
                              f"), got {type(value).__name__}", key=name)
    lines = [f"# Synthesized by pmaccuracy synthesize ({result.mode}) for {robot.name} over {region.describe()}."]
    lines.append("# Targets: " + ", ".join(
        f"{q}{'_deg' if q == 'dphi' else ''} <= {np.degrees(v) if q == 'dphi' else v:.6g}"
        for q, v in result.targets.items()))
    lines.append("# Certified worst cases: " + ", ".join(
        f"{q} <= {np.degrees(w.upper) if q == 'dphi' else w.upper:.6g}{' deg' if q == 'dphi' else ' mm'}"
        for q, w in result.worst.quantities.items()))
    data = result.clearances.to_dict()
    data["description"] = f"{result.mode} synthesis for {robot.name}"
    return "\n".join(lines) + "\n" + tomli_w.dumps(data)


__all__ = ["TARGETS", "Synthesis", "scaled_worst", "parse_targets", "targets_arg", "synthesize", "free_sources", "pose_coefficients",
           "clearance_toml", "load_costs", "default_template", "with_values", "JointErrors"]
