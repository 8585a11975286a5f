"""The design and statistics sections of a spatial robot's accuracy report (:mod:`pmaccuracy.report.spatial_report`).

**Design** (:func:`design_section`): how loose may the joints be?

* the largest uniform scaling ``lam_grid`` of the report's error sources that keeps the worst ``|dp|`` and
  ``|dtheta|`` within :data:`TARGETS` at every point of the workspace's grid
  (:func:`pmaccuracy.accuracy.spatial_synthesis.spatial_synthesize`, Eq. 1 there, on the report's own map), the
  binding target and grid point, and each kind of source's allowed half-width (template times ``lam_grid``);
* which joints dominate there: each kind's share (summed over the legs) of the binding component at the binding
  pose (:func:`pmaccuracy.accuracy.spatial_bounds.spatial_pose_errors`);
* the global worst case over the whole workspace, not only its grid
  (:func:`pmaccuracy.accuracy.spatial_worst.spatial_global_worst`): an attained value ``L`` and, where the branch and
  bound closes, a certified upper bound ``U``. Every worst case is positively homogeneous of degree one in the half-widths, so
  ``lam_cert = min_k T_k / U_k`` meets every target over the whole region (certified), and no scale above
  ``lam_att = min_k T_k / L_k`` can (the attained pose would exceed its target).

**Statistics** (:func:`statistics_section`): the distribution of the first-order pose error when every source
takes an independent uniform value inside its set, at the reference pose and at the worst pose of ``|dp|``
(:func:`pmaccuracy.accuracy.spatial_statistics.spatial_pose_statistics`): mean, RMS by Monte Carlo beside the
exact analytic RSS from the covariance, percentiles with their 95 % intervals, the probability of exceeding the
design targets, and the histograms of ``|dp|`` and ``|dtheta|``.

Units: mm and rad inside, mm and deg in the text, the tables and ``results.json`` (keys ending in ``_deg``).
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np

from .._savefig import DEFAULT_DPI, save_figure
from ..accuracy.spatial_bounds import COMPONENTS, spatial_pose_errors
from ..accuracy.spatial_maps import grid_poses
from ..accuracy.spatial_statistics import spatial_pose_statistics
from ..accuracy.spatial_synthesis import TARGETS as SYNTHESIS_TARGETS, spatial_synthesize
from ..accuracy.spatial_worst import spatial_global_worst, spatial_region
from ..errors import ConfigError
from ..kinematics.spatial import coordinates
from .sections import SECTION_ERRORS, SectionFailedWarning, reason_of
from .spatial_words import is_angle, kind_of
from .workspace3d_figures import FONT_PT, TITLE_PT, WIDTH_IN

#: Default design targets of the synthesis: ``|dp|`` in mm, ``|dtheta|`` in deg (``reproduce --target``).
TARGETS = {"dp": 0.1, "dtheta_deg": 0.05}
#: Relative gap of the certified global worst case: 2 % (1 % takes about a third longer).
GLOBAL_GAP = 2e-2
#: Budget of boxes of the report's global worst case: a 6-UPS's workspace certifies within it (about 18 000
#: boxes, a few seconds); where the other architectures' border boxes cannot be proven regular the branch and bound
#: would otherwise run on for minutes, and the report keeps the attained values.
GLOBAL_BOXES = 25_000
#: Monte Carlo samples and seed of the statistics.
SAMPLES, SEED = 50_000, 0
#: Percentiles of the statistics.
PERCENTILES = (95.0, 99.0)
#: The global worst case's name of each synthesis target, and its factor to the target's unit.
_GLOBAL = {"dx": ("dx", 1.0), "dy": ("dy", 1.0), "dz": ("dz", 1.0), "drx_deg": ("drx", 180 / math.pi),
           "dry_deg": ("dry", 180 / math.pi), "drz_deg": ("drz", 180 / math.pi), "dp": ("dp", 1.0),
           "dtheta_deg": ("dtheta", 180 / math.pi)}
_WORDS = {"dp": "|dp|", "dtheta_deg": "|dtheta|", "dx": "dx", "dy": "dy", "dz": "dz", "drx_deg": "drx",
          "dry_deg": "dry", "drz_deg": "drz"}


def check_targets(targets: dict) -> dict:
    """Check design targets ``{name: value}`` (names of :data:`pmaccuracy.accuracy.spatial_synthesis.TARGETS`,
    values in mm or deg, finite and > 0) before a report starts; raises
    :class:`~pmaccuracy.errors.ConfigError` naming ``targets``. Returns them as a dict of floats."""
    if not isinstance(targets, dict) or not targets:
        raise ConfigError(f"give at least one target ({', '.join(SYNTHESIS_TARGETS)})", key="targets")
    out = {}
    for name, value in targets.items():
        if name not in SYNTHESIS_TARGETS:
            raise ConfigError(f"unknown target {name!r} for a spatial robot; targets: {', '.join(SYNTHESIS_TARGETS)} "
                              "(mm, deg)", key="targets")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (math.isfinite(value) and value > 0):
            raise ConfigError(f"{name} must be finite and > 0, got {value!r}", key="targets")
        out[name] = float(value)
    return out


def _unit(name: str) -> str:
    return "deg" if name.endswith("_deg") else "mm"


def _g(value: float, digits: int = 4) -> str:
    return f"{value:.{digits}g}"


def _percent(value: float) -> str:
    return "0 %" if abs(value) < 1e-9 else f"{value:.3g} %"


def _pose_compact(robot, pose: np.ndarray) -> str:
    """A full pose ``(6,)`` in the robot's controlled coordinates, compactly: ``(x, y, z) = (1, 2, 3) mm, (roll,
    pitch, yaw) = (0, 0, 0) deg``."""
    c = coordinates(pose, degrees=True)
    names = ("x", "y", "z", "roll", "pitch", "yaw")
    parts = []
    for group, unit in ((range(3), "mm"), (range(3, 6), "deg")):
        shown = [i for i in group if names[i] in robot.controlled]
        if len(shown) == 1:
            parts.append(f"{names[shown[0]]} = {c[shown[0]]:.4g} {unit}")
        elif shown:
            parts.append(f"({', '.join(names[i] for i in shown)}) = ({', '.join(f'{c[i]:.4g}' for i in shown)}) "
                         f"{unit}")
    return ", ".join(parts)


def _pose_words(robot, pose: np.ndarray) -> str:
    """A full pose ``(6,)`` in the robot's controlled coordinates: ``x = 1 mm, ..., roll = 2 deg``."""
    c = coordinates(pose, degrees=True)
    names = ("x", "y", "z", "roll", "pitch", "yaw")
    shown = [i for i, n in enumerate(names) if n in robot.controlled]
    return ", ".join(f"{names[i]} = {c[i]:.4g} {'deg' if i >= 3 else 'mm'}" for i in shown)


def binding_component(name: str, components: np.ndarray) -> int:
    """The component (index into ``dx, dy, dz, drx, dry, drz``) whose shares explain target ``name`` at a pose
    with worst components ``components`` ``(6,)``: the component itself, or for ``|dp|`` (``|dtheta|``) the
    largest position (rotation) component."""
    base = name[:-4] if name.endswith("_deg") else name
    if base in COMPONENTS:
        return COMPONENTS.index(base)
    return int(np.argmax(components[:3])) if base == "dp" else 3 + int(np.argmax(components[3:]))


def kind_shares(robot, bounds, k: int) -> list[tuple[str, float]]:
    """Each kind of source's share (summed over the legs and pins; mm, or rad for a rotation component ``k``)
    of component ``k`` at the pose of ``bounds`` (one pose, :func:`spatial_pose_errors` with details), largest
    first; the shares add up to the component."""
    kinds: dict[str, float] = {}
    for label, s in bounds.shares().items():
        key = kind_of(robot.architecture, label)
        kinds[key] = kinds.get(key, 0.0) + float(np.ravel(s)[k])
    return sorted(kinds.items(), key=lambda t: -t[1])


def kind_half_widths(robot, sources) -> list[dict]:
    """Each kind of source of ``sources`` (joint and key, whatever the leg) with its half-widths over the legs:
    ``{"kind", "min", "max", "unit"}`` (mm, or deg for angles), in the order of the joints."""
    out: dict[str, dict] = {}
    for i, leg in enumerate(sources.legs):
        spec = sources.spec(i)
        for j, joint in enumerate(leg):
            for key, value in joint.items():
                name = kind_of(robot.architecture, f"legs[{i + 1}].joints[{j + 1}].{key}")
                angle = is_angle(robot.architecture, j, key, spec)
                v = math.degrees(value) if angle else float(value)
                rec = out.setdefault(name, {"kind": name, "min": v, "max": v, "unit": "deg" if angle else "mm"})
                rec["min"], rec["max"] = min(rec["min"], v), max(rec["max"], v)
    return list(out.values())


def _range(lo: float, hi: float) -> str:
    return _g(lo) if math.isclose(lo, hi, rel_tol=1e-12) else f"{_g(lo)} to {_g(hi)}"


def save_shares_figure(names: list[str], shares: np.ndarray, path: Path, *, title: str, xlabel: str) -> Path:
    """Horizontal bars: each kind's share (percent) of a worst case, largest on top, its value beside it."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    n = len(names)
    height = 1.2 + 0.6 * n
    fig = Figure(figsize=(WIDTH_IN, height))
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0.03, 0.75 / height, 0.9, 1 - 1.2 / height))
    y = np.arange(n)[::-1]
    top = max(float(np.max(shares)), 1e-12)
    shares = np.where(shares < 1e-9 * top, 0.0, shares)      # rounding residues of a source that does not act
    ax.barh(y, shares, color="#1f5fa8", height=0.4)
    for yy, name, v in zip(y, names, shares):
        ax.text(0.005 * top, yy + 0.25, name, va="bottom", ha="left", fontsize=FONT_PT)
        ax.text(v + 0.01 * top, yy, _percent(v), va="center", ha="left", fontsize=FONT_PT)
    ax.set_ylim(-0.45, n - 0.2)
    ax.set_xlim(0, top * 1.18)
    ax.set_yticks([])
    ax.set_xlabel(xlabel, fontsize=FONT_PT)
    ax.tick_params(labelsize=FONT_PT)
    for side in ("top", "right"):
        ax.spines[side].set_visible(False)
    fig.suptitle(title, fontsize=TITLE_PT, y=1 - 0.12 / height, va="top")
    out = save_figure(fig, path, dpi=DEFAULT_DPI)
    fig.clear()
    return out


def _region_words(robot, region) -> str:
    """The global worst case's region in words: the workspace (at the 6-UPS's fixed orientation) or the region's
    own description."""
    if region.kind != "workspace":
        return region.describe()
    if robot.mobility == "6":
        o = np.degrees(region.orientation[:, 0])
        return "constant-orientation workspace (roll, pitch, yaw = " + ", ".join(f"{v:g}" for v in o) + " deg)"
    return {"3T": "reachable workspace (x, y, z)", "2R1T": "workspace (z, roll, pitch)"}.get(robot.mobility,
                                                                                            "workspace")


# ---------------------------------------------------------------------------------------------- design
def design_section(doc, robot, sources, ds, state, results, figure, out: Path, targets: dict | None = None) -> None:
    """Append the design section (module text) to ``doc`` and ``results["design"]``. ``ds``: the report's
    map of ``sources``; ``state`` receives ``worst_pose`` (the attained worst pose of ``|dp|``) for the
    statistics."""
    targets = dict(TARGETS if targets is None else targets)
    syn = spatial_synthesize(robot, sources, targets, error_map=ds)
    lam = syn.scale
    dims = list(ds["dp_max"].dims)
    units = [ds[d].attrs.get("units", "") for d in dims]
    point = {d: float(v) for d, v in zip(dims, syn.binding_point)}
    pose = grid_poses(robot, syn.binding_point[None])[0]
    at = spatial_pose_errors(robot, sources, pose[None])
    k = binding_component(syn.binding, at.components[0])
    comp_unit = "mm" if k < 3 else "deg"
    conv = 1.0 if k < 3 else math.degrees(1.0)
    total = float(at.components[0, k])
    shares = kind_shares(robot, at, k)
    kinds = kind_half_widths(robot, sources)
    share_of = dict(shares)
    # the global worst case over the whole workspace (not only the grid), at the map's orientation
    region = spatial_region(robot, orientation=(0.0, 0.0, 0.0)) if robot.mobility == "6" else spatial_region(robot)
    glob, glob_error = None, None
    try:
        glob = spatial_global_worst(robot, sources, region, gap=GLOBAL_GAP, max_boxes=GLOBAL_BOXES)
    except SECTION_ERRORS as exc:       # a region reaching a singularity: said in a box, the rest still written
        glob_error = reason_of(exc)
        warnings.warn(f"report part 'Design: global worst case' could not be computed ({glob_error}); the report "
                      "was written with a box in its place", SectionFailedWarning, stacklevel=2)
        results.setdefault("failed_sections", []).append({"section": "Design: global worst case",
                                                          "reason": glob_error})
    data: dict = {"targets": targets, "template": sources.name, "grid_points": syn.points,
                  "scale_grid": lam, "binding": syn.binding, "binding_point": point,
                  "binding_pose": pose.tolist(), "binding_component": COMPONENTS[k],
                  "worst_grid": syn.worst,
                  "kinds": [{**rec, "allowed_min": rec["min"] * lam, "allowed_max": rec["max"] * lam,
                             f"share_of_{COMPONENTS[k]}_pct": 100 * share_of.get(rec["kind"], 0.0) / total
                             if total > 0 else 0.0} for rec in kinds]}
    grid_max = {name: float(np.nanmax(ds[SYNTHESIS_TARGETS[name][0]].values)) / SYNTHESIS_TARGETS[name][1]
                for name in targets}
    if glob is not None:
        g = {}
        for name in targets:
            q, f = _GLOBAL[name]
            w = glob[q]
            g[name] = {"attained": w.lower * f, "upper": w.upper * f if math.isfinite(w.upper) else None,
                       "certified": bool(w.converged), "pose": w.pose.tolist(), "grid_max": grid_max[name]}
        # attained: the search's value, or a grid point's where the grid found more (both are reached)
        att = min(targets[n] / max(g[n]["attained"], g[n]["grid_max"]) for n in targets
                  if max(g[n]["attained"], g[n]["grid_max"]) > 0)
        cert = min(targets[n] / g[n]["upper"] for n in targets) if all(
            g[n]["upper"] for n in targets) and glob.certified else None
        data["global"] = {"region": _region_words(robot, region), "certified": cert is not None,
                          "reason": glob.reason or ("" if cert is not None else
                                                    f"boxes near the workspace's border could not be proven regular "
                                                    f"within the budget of {GLOBAL_BOXES} boxes"),
                          "gap": GLOBAL_GAP, "boxes": glob.boxes, "seconds": glob.seconds, "quantities": g,
                          "scale_attained_limit": att, "scale_certified": cert}
        dp_pose = glob["dp"].pose
        if np.all(np.isfinite(dp_pose)):
            state["worst_pose"] = (dp_pose, "worst pose of |dp| over the workspace")
    if "worst_pose" not in state:
        state["worst_pose"] = (pose, "binding grid point of the synthesis")
    results["design"] = data

    # ---- text
    tgt = ", ".join(f"{_WORDS[n]} <= {_g(v)} {_unit(n)}" for n, v in targets.items())
    where = ", ".join(f"{d} = {_g(v)} {u}".strip() for (d, v), u in zip(point.items(), units))
    now = ("may grow up to {} times its present value (the sources meet the targets with a margin)" if lam > 1 else
           "must shrink to at most {} of its present value (the sources miss the targets now)").format(_g(lam, 3))
    doc.paragraph(f"How loose may the joints be? The targets are **{tgt}** everywhere in the workspace (change "
                  f"them with `--target NAME=VALUE`). Every worst case grows in proportion to the half-widths, so "
                  f"the sources `{sources.name}` scaled by one factor meet them at every one of the {syn.points} "
                  f"grid points of the error maps when the factor is at most **{_g(lam)}**: every half-width "
                  f"{now}. The binding target is {_WORDS[syn.binding]}, at the grid point {where}.")
    rows = [[rec["kind"], f"{_range(rec['min'], rec['max'])} {rec['unit']}",
             f"{_range(rec['min'] * lam, rec['max'] * lam)} {rec['unit']}",
             _percent(100 * share_of.get(rec["kind"], 0.0) / total) if total > 0 else "-"] for rec in kinds]
    rows.sort(key=lambda r: -float(r[3].split()[0]) if r[3] != "-" else 0.0)
    doc.paragraph(f"Each kind of source (all legs), its half-width now and the largest it may have, and its share "
                  f"of {COMPONENTS[k]} = {_g(total * conv)} {comp_unit} at the binding point (the largest "
                  f"{'position' if k < 3 else 'rotation'} component there; the shares add up to it):")
    doc.table(["kind of source", "half-width now", f"allowed (x {_g(lam)})", f"share of {COMPONENTS[k]}"], rows)
    if shares and total > 0:
        lead = shares[0]
        second = f", then {shares[1][0]} ({_percent(100 * shares[1][1] / total)})" if len(shares) > 1 else ""
        names = [n for n, _ in shares]
        vals = np.array([100 * v / total for _, v in shares])
        path = save_shares_figure(names, vals, out / "design_shares.png",
                                  title=f"{robot.name}: share of {COMPONENTS[k]} at the binding point",
                                  xlabel=f"share of {COMPONENTS[k]} = {_g(total * conv)} {comp_unit} [%]")
        n = figure(path, f"Which joints dominate: each kind of source's share (summed over the legs) of "
                         f"{COMPONENTS[k]} at the binding point ({where}), sources `{sources.name}`.")
        doc.paragraph(f"**{lead[0]}** dominates ({_percent(100 * lead[1] / total)}){second} (Figure {n}): "
                      "tightening it pays most; a uniform scaling keeps every kind's share.")
    idle = [rec["kind"] for rec in kinds if not any(np.any(np.ravel(v) > 1e-12 * max(float(np.max(at.components[0])),
                                                                                    1e-300))
                                                  for lab, v in at.shares().items()
                                                  if kind_of(robot.architecture, lab) == rec["kind"])]
    data["idle_kinds"] = idle
    if idle:
        why = (" (a 6-UPS leg, a ball at one end and a universal joint at the other, only transmits its length: the "
               "rod's play in its guide does not change it)" if robot.architecture == "6-UPS" else "")
        doc.paragraph(f"No share at all at the binding point for: {'; '.join(idle)}. No component of the pose error "
                      f"moves with them at first order{why}, so these targets do not limit their half-widths there.")
    if glob_error is not None:
        doc.failure("Global worst case over the workspace", glob_error)
        return
    g = data["global"]
    grows, where_att = [], []
    for name in targets:
        rec = g["quantities"][name]
        up = "-" if rec["upper"] is None else _g(rec["upper"])
        grows.append([f"{_WORDS[name]} [{_unit(name)}]", _g(rec["grid_max"]), _g(rec["attained"]), up])
        where_att.append(f"{_WORDS[name]} at {_pose_compact(robot, np.asarray(rec['pose']))}")
    how = (f"a branch and bound over {glob.boxes} boxes certifies an upper bound" if g["certified"] else
           f"a search over {glob.boxes} boxes finds attained values" if glob.boxes else
           "a grid, then finer grids around the worst points, find attained values")
    doc.paragraph(f"Between grid points the errors may be larger. Over the whole {_region_words(robot, region)}, "
                  f"{how} ({glob.seconds:.1f} s; sources `{sources.name}`):")
    doc.table(["quantity", "grid maximum", "attained (at a pose)", "certified upper bound"], grows)
    doc.paragraph("Attained: " + "; ".join(where_att) + ".")
    if g["scale_certified"] is not None:
        doc.paragraph(f"The upper bounds are certified (relative gap at most {100 * GLOBAL_GAP:g} %): a scale of at "
                      f"most **{_g(g['scale_certified'])}** meets the targets at every pose of the workspace, not "
                      f"only at the grid points ({_g(lam)}); no scale above {_g(g['scale_attained_limit'])} can "
                      "(the attained pose would exceed its target).")
    else:
        reason = g["reason"].rstrip(".")
        doc.paragraph(f"No upper bound is certified here ({reason}): the attained "
                      f"values are lower bounds of the true worst case. So no scale above "
                      f"**{_g(g['scale_attained_limit'])}** can meet the targets (the attained pose would exceed "
                      f"its target); the grid's {_g(lam)} is "
                      + ("that limit (the grid's own worst point binds): keep a margin, the worst case between "
                         "points may be larger." if lam <= g["scale_attained_limit"] * (1 + 1e-9) else
                         f"{_percent(100 * (lam / g['scale_attained_limit'] - 1))} above it: keep a margin.")
                      )


# ---------------------------------------------------------------------------------------------- statistics
def save_histograms_figure(robot, panels: list[dict], path: Path, *, sources: str) -> Path:
    """Histograms of ``|dp|`` (mm) and ``|dtheta|`` (deg), one row per pose: each panel's samples with its
    95th and 99th percentiles, the analytic RMS and the worst case marked."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    rows = len(panels) // 2
    panel_h, top, gap, bottom = 2.1, 0.75, 0.95, 1.05
    height = top + rows * panel_h + (rows - 1) * gap + bottom
    fig = Figure(figsize=(WIDTH_IN, height))
    FigureCanvasAgg(fig)
    left, right, gap_x = 0.75, 0.2, 0.75
    w = (WIDTH_IN - left - right - gap_x) / 2
    handles = None
    for idx, p in enumerate(panels):
        r, c = divmod(idx, 2)
        x0 = left + c * (w + gap_x)
        y0 = height - top - (r + 1) * panel_h - r * gap
        ax = fig.add_axes((x0 / WIDTH_IN, y0 / height, w / WIDTH_IN, panel_h / height))
        counts, edges = np.histogram(p["values"], bins=100, range=(0, p["worst"]), density=True)
        ax.stairs(counts, edges, fill=True, color="#9ecae1")        # one artist: fast to draw
        ax.stairs(counts, edges, color="#4a90c2", linewidth=0.8)
        lines = [ax.axvline(p["p95"], color="#08306b", lw=1.4, label="95th percentile"),
                 ax.axvline(p["p99"], color="#08306b", lw=1.4, ls="--", label="99th percentile"),
                 ax.axvline(p["rss"], color="#1a7f37", lw=1.4, ls=":", label="RMS (analytic)"),
                 ax.axvline(p["worst"], color="#b42318", lw=1.6, label="worst case")]
        handles = lines
        ax.set_xlim(0, p["worst"] * 1.04)
        ax.set_title(p["title"], fontsize=TITLE_PT)
        ax.set_xlabel(p["xlabel"], fontsize=FONT_PT)
        ax.set_ylabel("density" if c == 0 else "", fontsize=FONT_PT)
        ax.set_yticks([])
        ax.tick_params(labelsize=FONT_PT)
    fig.legend(handles=handles, loc="lower center", ncol=2, fontsize=FONT_PT, frameon=False,
               bbox_to_anchor=(0.5, 0.02 / height))
    fig.suptitle(f"{robot.name}, sources {sources}: first-order pose error, uniform sources", fontsize=TITLE_PT + 1,
                 y=1 - 0.15 / height, va="top")
    out = save_figure(fig, path, dpi=DEFAULT_DPI)
    fig.clear()
    return out


def statistics_section(doc, robot, sources, state, results, figure, out: Path, targets: dict | None = None) -> None:
    """Append the statistics section (module text) to ``doc`` and ``results["statistics"]``: at the reference
    pose ``state["ref"]`` and, when the design section found it, at ``state["worst_pose"]``."""
    targets = dict(TARGETS if targets is None else targets)
    thresholds = {n: v for n, v in targets.items() if n in ("dp", "dtheta_deg", "dx", "dy", "dz", "drx_deg",
                                                            "dry_deg", "drz_deg")}
    poses = [(state["ref"], "reference pose")]
    if "worst_pose" in state:
        poses.append(state["worst_pose"])
    results["statistics"] = {"samples": SAMPLES, "seed": SEED, "distribution": "uniform",
                             "thresholds": thresholds, "poses": []}
    doc.paragraph(f"How far is the platform off, typically? Every source takes an independent value uniformly "
                  f"distributed in its set (segment, disc or ball); {SAMPLES} Monte Carlo samples (seed {SEED}) "
                  "of the first-order error at each pose, beside the exact RMS from the error's covariance "
                  "(analytic) and the worst case. Percentiles of the magnitudes |q|, with their 95 % intervals in "
                  "brackets.")
    panels = []
    for pose, label in poses:
        short = "reference pose" if label == "reference pose" else "worst-|dp| pose"
        st = spatial_pose_statistics(robot, sources, pose, samples=SAMPLES, seed=SEED, percentiles=PERCENTILES,
                                     thresholds=thresholds, keep_samples=True)
        results["statistics"]["poses"].append({"label": label, "pose": pose.tolist(),
                                               "coordinates": coordinates(pose, degrees=True).tolist(),
                                               "within_worst": st.within_worst, "quantities": st.quantities})
        rows = []
        for q, rec in st.quantities.items():
            rows.append([f"{_WORDS.get(q, q).replace('|', '')} [{_unit(q)}]" if q not in ("dp", "dtheta_deg") else
                         f"{_WORDS[q]} [{_unit(q)}]", _g(rec["rms"]), _g(rec["rss"]),
                         f"{_g(rec['p95'])} [{_g(rec['p95_lo'])}, {_g(rec['p95_hi'])}]",
                         _g(rec["p99"]), _g(rec["worst"]), _percent(100 * rec["p99"] / rec["worst"])
                         if rec["worst"] > 0 else "-"])
        doc.paragraph(f"At the {label}, {_pose_compact(robot, pose)}:")
        doc.table(["quantity", "RMS (Monte Carlo)", "RMS (analytic)", "95th percentile [95 % interval]", "99th",
                   "worst case", "99th / worst"], rows)
        dev = max(abs(rec["rms"] - rec["rss"]) / rec["se_rms"] for rec in st.quantities.values() if rec["se_rms"] > 0)
        rel = [100 * rec["se_rms"] / rec["rms"] for rec in st.quantities.values() if rec["rms"] > 0]
        dp, dth = st.quantities["dp"], st.quantities["dtheta_deg"]
        exceed = "; ".join(f"P({_WORDS[n]} > {_g(v)} {_unit(n)}) = {_g(100 * st.quantities[n]['exceed'], 3)} % "
                           f"(± {_g(100 * st.quantities[n]['se_exceed'], 2)})" if st.quantities[n]["exceed"] > 0 else
                           f"no sample has {_WORDS[n]} > {_g(v)} {_unit(n)}" for n, v in thresholds.items())
        # the percentiles scale with the half-widths too: the scale whose 99th percentiles meet the targets here
        stat = {n: v / st.quantities[n]["p99"] for n, v in thresholds.items() if st.quantities[n]["p99"] > 0}
        stat_scale = min(stat.values()) if stat else None
        results["statistics"]["poses"][-1]["scale_p99"] = stat_scale
        doc.bullets([
            f"Typically |dp| is {_g(dp['rms'], 3)} mm (RMS) and 99 % of the samples stay below {_g(dp['p99'], 3)} "
            f"mm, {_percent(100 * dp['p99'] / dp['worst'])} of the worst case {_g(dp['worst'], 3)} mm; |dtheta|: "
            f"{_g(dth['rms'], 3)} deg RMS, 99th percentile {_g(dth['p99'], 3)} deg "
            f"({_percent(100 * dth['p99'] / dth['worst'])} of {_g(dth['worst'], 3)} deg).",
            f"Analytic and Monte Carlo RMS agree within {dev:.2g} standard errors of the Monte Carlo (largest over "
            f"the eight quantities; a standard error is {min(rel):.2g} to {max(rel):.2g} % of the RMS); "
            + ("no sample exceeds the worst case." if st.within_worst else
               "**some samples exceed the worst case: the first-order model is inconsistent here.**"),
            *([f"The design targets with these sources: {exceed}."] if exceed else []),
            *([f"If 1 % of the robots may miss the targets at this pose (a statistical tolerance instead of the "
               f"worst case), the half-widths may be scaled by up to **{_g(stat_scale, 3)}** (target / 99th "
               "percentile: the percentiles, too, grow in proportion to the half-widths)."]
              if stat_scale is not None else []),
        ])
        t = st.twists
        deg = math.degrees(1.0)
        for q, values, unit in (("dp", np.linalg.norm(t[:, :3], axis=1), "mm"),
                                ("dtheta_deg", np.linalg.norm(t[:, 3:], axis=1) * deg, "deg")):
            rec = st.quantities[q]
            panels.append({"values": values, "p95": rec["p95"], "p99": rec["p99"], "rss": rec["rss"],
                           "worst": rec["worst"], "title": f"{_WORDS[q]}, {short}",
                           "xlabel": f"{_WORDS[q]} [{unit}]"})
    path = save_histograms_figure(robot, panels, out / "statistics.png", sources=sources.name)
    which = " and at the worst pose of |dp| (bottom row)" if len(poses) > 1 else ""
    figure(path, f"Distribution of |dp| and |dtheta| at the reference pose{which}, {SAMPLES} samples each; the x "
                 "axis runs to the worst case (red), far beyond the bulk of the samples.")
