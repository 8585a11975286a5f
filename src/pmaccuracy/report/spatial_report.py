"""The accuracy report of a spatial robot (``pmaccuracy reproduce --robot stewart_6ups``).

The spatial counterpart of :mod:`pmaccuracy.report.accuracy_report`: the robot and its legs, its workspace
(volume, slices, a static and an interactive 3D view), the worst first-order errors over the workspace's grid
(:func:`pmaccuracy.accuracy.spatial_maps.spatial_error_map`), each error source's share at the reference pose
(:func:`pmaccuracy.accuracy.spatial_bounds.spatial_pose_errors`) and how the numbers were computed. It writes
``report.html`` (self-contained: figures embedded, the 3D view offline JavaScript), ``report.md``,
``results.json``, PNG figures and ``map.nc``. Sections run through
:class:`~pmaccuracy.report.sections.SectionRunner`: a failing section becomes a box (``strict=True`` raises).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from .. import __version__
from .._savefig import DEFAULT_DPI, save_figure
from ..accuracy.spatial_bounds import COMPONENTS, DEFAULT_GAP, spatial_pose_errors
from ..accuracy.spatial_maps import spatial_error_map
from ..io.resolve import robot_arg
from ..kinematics.spatial import coordinates, inverse_kinematics, reference_pose, singularity
from ..kinematics.spatial_workspace import spatial_workspace
from ..model.spatial import SpatialManipulator, is_spatial
from ..model.spatial_sources import JOINT_WORDS, JOINTS, SpatialErrorSources, default_preset
from ..errors import ConfigError
from .document import Document, provenance
from .sections import ReportDependencyError, Section, SectionRunner, estimate
from .spatial_design import check_targets, design_section, statistics_section
from .spatial_words import KEY_WORDS, ROLES, kind_of, source_description  # noqa: F401 - re-exported
from .spatial_figures import (robot_segments, save_map_slices_figure, save_spatial_workspace_figure,
                              write_spatial_workspace_page)
from .view3d_html import view3d_html
from .workspace3d_figures import FONT_PT, TITLE_PT, WIDTH_IN, value_with_error

#: Default grid (points per axis) of the spatial report's workspace and map.
DEFAULT_GRID = 30
#: Largest grid the report accepts (80^3 points: a few tens of seconds).
MAX_GRID = 80
#: Section titles (a failed section keeps its heading above the box that replaces it).
TITLES = {"summary": "Summary", "robot": "The robot", "workspace": "Workspace", "maps": "Error maps",
          "sources": "Error sources", "design": "Design: how loose may the joints be",
          "statistics": "Statistics", "method": "Method"}
#: Seconds per grid point (workspace, map) and fixed seconds of each section, measured on the project's 2-core
#: machine: the estimates printed before the report runs (never used for a decision).
MAP_SECONDS_PER_POINT = {"6": 3e-5, "3T": 4e-5, "2R1T": 7.5e-5}      # by mobility (2R1T: parasitic motions solved)
WORKSPACE_SECONDS_PER_POINT = 1e-5
FIXED_SECONDS = {"summary": 0.3, "robot": 0.4, "workspace": 1.2, "maps": 1.4, "sources": 0.3, "design": 2.0,
                 "statistics": 1.2, "method": 0.1}
_UNITS = ("mm", "mm", "mm", "deg", "deg", "deg")
#: Rows of the table of single sources (the rest summed in one row; all of them in results.json).
MAX_SOURCE_ROWS = 18


def spatial_accuracy_report(out_dir: str | Path, robot: str | SpatialManipulator, sources=None, *,
                            grid: int = DEFAULT_GRID, targets: dict | None = None, design: bool = True,
                            strict: bool = False, command: str | None = None, stream=None,
                            progress: bool | None = None) -> dict:
    """Write the accuracy report of the spatial ``robot`` with its error ``sources`` (a preset name, a file, a
    :class:`~pmaccuracy.model.spatial_sources.SpatialErrorSources`; default the architecture's
    :data:`~pmaccuracy.model.spatial_sources.DEFAULT_PRESET`) in ``out_dir``; returns ``results.json``'s content.

    ``grid``: points per axis of the workspace and of the error map (4 to :data:`MAX_GRID`). ``targets``: the
    design section's targets (``{"dp": mm, "dtheta_deg": deg, ...}``, names of
    :data:`pmaccuracy.accuracy.spatial_synthesis.TARGETS`; default
    :data:`pmaccuracy.report.spatial_design.TARGETS`); ``design=False`` leaves the design section out. ``strict``: a
    section that cannot be computed raises instead of becoming a box. ``stream`` (e.g. ``sys.stderr``) receives
    the sections' estimates before they run and, on a terminal or with ``progress=True``, a progress bar;
    ``command`` (the command line) goes to the footer.
    """
    t0 = time.perf_counter()
    robot = robot_arg(robot)
    if not is_spatial(robot):
        raise ConfigError(f"{robot.name} is a planar {robot.architecture}: use "
                          "pmaccuracy.report.accuracy_report.accuracy_report", key="robot")
    if not isinstance(grid, (int, np.integer)) or not 4 <= grid <= MAX_GRID:
        raise ConfigError(f"{grid!r} points per axis of a 3D grid: give 4 to {MAX_GRID}", key="grid")
    if targets is not None:
        check_targets(targets)
    if sources is None:
        sources = default_preset(robot)
    if not isinstance(sources, SpatialErrorSources):
        sources = SpatialErrorSources.load(sources, robot)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    doc = Document(f"pmaccuracy: accuracy of {robot.name} ({robot.label}) with error sources {sources.name}",
                   footer=provenance(command, __version__))
    results: dict = {"robot": robot.name, "architecture": robot.architecture, "label": robot.label,
                     "clearances": sources.name, "version": __version__, "grid": int(grid),
                     "controlled": list(robot.controlled), "figures": []}
    state: dict = {"ref": reference_pose(robot)}
    runner = SectionRunner(doc, results, stream=stream, progress=progress, strict=strict,
                           label=f"report of {robot.name}")

    def figure(path: Path, caption: str) -> int:
        results["figures"].append(path.name)
        return doc.figure(path, caption)

    def need(key: str, section: str):
        if key not in state:
            raise ReportDependencyError(f"needs the results of section '{section}', which could not be computed")
        return state[key]

    points = float(grid) ** 3
    sections = [
        Section(TITLES["summary"], lambda: _summary(doc, robot, sources, grid, out, state, results),
                estimate(points, seconds_per_point=MAP_SECONDS_PER_POINT[robot.mobility],
                         fixed=FIXED_SECONDS["summary"]),
                short="map"),
        Section(TITLES["robot"], lambda: _robot_section(doc, robot, state, out, results, figure),
                FIXED_SECONDS["robot"], short="robot"),
        Section(TITLES["workspace"], lambda: _workspace_section(doc, robot, grid, state, out, results, figure),
                estimate(points, seconds_per_point=WORKSPACE_SECONDS_PER_POINT, fixed=FIXED_SECONDS["workspace"]),
                short="workspace"),
        Section(TITLES["maps"], lambda: _maps_section(doc, robot, sources, need("ds", TITLES["summary"]), out,
                                                      results, figure),
                FIXED_SECONDS["maps"], short="map figures"),
        Section(TITLES["sources"], lambda: _sources_section(doc, robot, sources, need("bref", TITLES["summary"]),
                                                            results),
                FIXED_SECONDS["sources"], short="sources"),
    ]
    if design:
        sections.append(Section(TITLES["design"], lambda: _design(doc, robot, sources, need("ds", TITLES["summary"]),
                                                                  state, results, figure, out, targets),
                                FIXED_SECONDS["design"], short="design"))
    sections += [
        Section(TITLES["statistics"], lambda: _statistics(doc, robot, sources, state, results, figure, out, targets),
                FIXED_SECONDS["statistics"], short="statistics"),
        Section(TITLES["method"], lambda: _method_section(doc, robot, grid), FIXED_SECONDS["method"],
                short="method"),
    ]
    runner.run(sections)
    results["elapsed_s"] = round(time.perf_counter() - t0, 2)
    (out / "results.json").write_text(json.dumps(results, indent=2, default=_plain))
    (out / "report.md").write_text(doc.to_markdown(relative_to=out))
    (out / "report.html").write_text(doc.to_html())
    return results


def _plain(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    return float(value)


def _g(value: float, digits: int = 4) -> str:
    return f"{value:.{digits}g}"


def _vec(v, digits: int = 4) -> str:
    return "(" + ", ".join(f"{float(c):.{digits}g}" for c in v) + ")"


def _pose_text(robot: SpatialManipulator, pose: np.ndarray) -> str:
    """The controlled coordinates of ``pose`` in words: ``x = 0 mm, y = 0 mm, z = 400 mm, roll = 0 deg, ...``."""
    c = coordinates(pose, degrees=True)
    names = ("x", "y", "z", "roll", "pitch", "yaw")
    units = ("mm", "mm", "mm", "deg", "deg", "deg")
    shown = [i for i, n in enumerate(names) if n in robot.controlled]
    return ", ".join(f"{names[i]} = {_g(float(np.round(c[i], 6)))} {units[i]}" for i in shown)


def _dp_point_text(ds, variable: str) -> tuple[float, dict]:
    """The largest value of ``variable`` over the map and the grid point where it is (a dict of coordinates)."""
    values = ds[variable].values
    k = int(np.nanargmax(values))
    idx = np.unravel_index(k, values.shape)
    where = {d: float(ds[d].values[i]) for d, i in zip(ds[variable].dims, idx)}
    return float(values[idx]), where


def _where_text(ds, where: dict) -> str:
    return ", ".join(f"{d} = {_g(v)} {ds[d].attrs.get('units', '')}".strip() for d, v in where.items())


# ------------------------------------------------------------------------------------------------ sections
def _summary(doc, robot, sources, grid, out, state, results) -> None:
    doc.heading(TITLES["summary"])
    ref = state["ref"]
    if not np.all(np.isfinite(ref)):
        raise ReportDependencyError(f"{robot.name} has no reference pose within its joint limits")
    bref = spatial_pose_errors(robot, sources, ref[None])
    state["bref"] = bref
    ds = spatial_error_map(robot, sources, n=grid)
    ds.to_netcdf(out / "map.nc")
    state["ds"] = ds
    finite = np.isfinite(ds["dp_max"].values)
    n_in = int(finite.sum())
    if n_in == 0:
        raise ReportDependencyError("no point of the workspace's grid has a regular first-order model")
    dp_max, dp_where = _dp_point_text(ds, "dp_max")
    dth_max, dth_where = _dp_point_text(ds, "dtheta_max")
    comp = bref.components[0]
    ref_json = {"pose": ref.tolist(), "coordinates": coordinates(ref, degrees=True).tolist(),
                **{f"{c}_max" + ("_deg" if i >= 3 else ""): float(comp[i] * (np.degrees(1.0) if i >= 3 else 1))
                   for i, c in enumerate(COMPONENTS)},
                "dp_max": float(bref.dp_upper[0]), "dp_attained": float(bref.dp_lower[0]),
                "dtheta_max_deg": float(np.degrees(bref.dtheta_upper[0])),
                "dtheta_attained_deg": float(np.degrees(bref.dtheta_lower[0])),
                "certified": bool(bref.dp_certified[0] and bref.dtheta_certified[0])}
    results["reference"] = ref_json
    results["headline"] = {"dp_max_map": dp_max, "dp_max_at": dp_where,
                           "dtheta_max_map_deg": float(np.degrees(dth_max)), "dtheta_max_at": dth_where,
                           "dp_max_reference": ref_json["dp_max"],
                           "dtheta_max_reference_deg": ref_json["dtheta_max_deg"], "map_points": n_in,
                           "grid_points": int(finite.size)}
    n_src = sum(len(leg_j.items()) for leg in sources.legs for leg_j in leg)
    legs = ", ".join(JOINT_WORDS[j] for j in JOINTS[robot.architecture])
    doc.paragraph(f"Worst-case first-order pose errors of `{robot.name}`, a {robot.label} with {robot.n_legs} legs "
                  f"(joints from base to platform: {legs}), with the error sources `{sources.name}` ({n_src} "
                  f"non-zero half-widths). It controls {', '.join(robot.controlled)}. Lengths in mm, angles in "
                  "degrees; the values are worst cases over all the sources acting at once unless said otherwise.")
    worst_axis = int(np.argmax(comp[:3]))
    on_edge = _on_edge(finite, np.unravel_index(int(np.nanargmax(ds["dp_max"].values)), finite.shape))
    results["headline"]["dp_max_on_edge"] = on_edge
    state["summary"] = items = [
        f"Over the workspace ({n_in} of the {finite.size} points of a {grid} x {grid} x {grid} grid): worst "
        f"position error **|dp| = {_g(dp_max)} mm** (at {_where_text(ds, dp_where)}), worst rotation "
        f"**|dtheta| = {_g(np.degrees(dth_max))} deg** (at {_where_text(ds, dth_where)}).",
        f"At the reference pose ({_pose_text(robot, ref)}): **|dp| = {_g(ref_json['dp_max'])} mm**, "
        f"**|dtheta| = {_g(ref_json['dtheta_max_deg'])} deg**; its largest component is "
        f"{COMPONENTS[worst_axis]} = {_g(comp[worst_axis])} mm.",
        f"The map's worst |dp| is {_g(dp_max / ref_json['dp_max'], 3)} times the reference pose's; it is reached "
        + ("on the edge of the workspace (a neighbouring grid point is outside it)." if on_edge else
           "inside the workspace (every neighbouring grid point is inside it)."),
    ]
    doc.bullets(items)      # the design and statistics sections add their conclusions to this list


def _on_edge(inside: np.ndarray, index: tuple) -> bool:
    """Whether a grid point has a neighbour (along an axis) outside ``inside`` or outside the grid."""
    for axis in range(inside.ndim):
        for step in (-1, 1):
            j = list(index)
            j[axis] += step
            if not 0 <= j[axis] < inside.shape[axis] or not inside[tuple(j)]:
                return True
    return False


def _robot_section(doc, robot, state, out, results, figure) -> None:
    doc.heading(TITLES["robot"])
    ref = state["ref"]
    ik = inverse_kinematics(robot, ref)
    q = np.asarray(ik.q, dtype=float).reshape(-1)
    delta = robot.architecture == "delta"
    conv = np.degrees if delta else (lambda v: v)
    unit = "deg" if delta else "mm"
    rows, legs_json = [], []
    for i, leg in enumerate(robot.legs):
        lo, hi = leg.stroke
        cone = lambda a: "-" if a is None else f"{np.degrees(a):.4g}"   # noqa: E731
        extra = []
        if getattr(leg, "angle_range", None) is not None and not delta:
            a0, a1 = np.degrees(leg.angle_range)
            extra.append(f"revolute {a0:g} to {a1:g} deg")
        if delta:
            extra.append(f"arm {leg.arm:g}, rods {leg.rod:g}, spacing {leg.spacing:g} mm")
        if hasattr(leg, "rod") and not delta:
            extra.append(f"rod {leg.rod:g} mm")
        rows.append([i + 1, _vec(leg.base), _vec(leg.platform), f"[{conv(lo):.4g}, {conv(hi):.4g}] {unit}",
                     f"{conv(q[i]):.4g}", cone(leg.base_cone), cone(leg.platform_cone), "; ".join(extra) or "-"])
        legs_json.append({"base": list(leg.base), "platform": list(leg.platform),
                          "stroke": [float(conv(lo)), float(conv(hi))], "stroke_units": unit,
                          "at_reference": float(conv(q[i])),
                          "base_cone_deg": None if leg.base_cone is None else float(np.degrees(leg.base_cone)),
                          "platform_cone_deg": None if leg.platform_cone is None else
                          float(np.degrees(leg.platform_cone))})
    sing = singularity(robot, ref)
    results["legs"] = legs_json
    results["mobility"] = {"mobility": robot.mobility, "controlled": list(robot.controlled),
                           "reference_condition": float(sing.condition),
                           "reference_dexterity": float(sing.dexterity)}
    what = {"6": "all six coordinates of the platform's pose (x, y, z, roll, pitch, yaw)",
            "3T": "the position x, y, z of the platform, which moves in pure translation (its orientation is "
                  "held by the legs)",
            "2R1T": "z, roll and pitch; x, y and yaw follow from the legs' constraints (parasitic motions, "
                    "included in the errors)"}[robot.mobility]
    actuated = "arm angle" if delta else "slide travel" if robot.architecture == "3-PRS" else "leg length"
    doc.paragraph(f"{robot.n_legs} legs; the actuated joint of each is its {actuated} ({unit}). The robot controls "
                  f"{what}. Base joint centres in the base frame, platform joint centres in the platform frame "
                  f"(mm); cones are the largest angle of a passive joint about its axis (- : no limit).")
    doc.table(["leg", "base joint [mm]", "platform joint [mm]", "actuated range", "at reference",
               "base cone [deg]", "platform cone [deg]", "other"], rows)
    path = _save_robot_figure(robot, ref, out / "robot.png")
    n = figure(path, f"{robot.name} at its reference pose ({_pose_text(robot, ref)}): legs in blue, base in grey, "
                     f"platform in red, the platform point P marked x (mm).")
    doc.paragraph(f"At the reference pose (Figure {n}) the closure matrix's condition number is "
                  f"{_g(float(sing.condition))} (dexterity {_g(float(sing.dexterity), 3)}; 1 is isotropic, 0 "
                  "singular).")


def _save_robot_figure(robot, pose, path: Path) -> Path:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    seg = robot_segments(robot, pose)
    n_ring = 2 * robot.n_legs
    legs, base, plat = seg[:-n_ring], seg[-n_ring:-robot.n_legs], seg[-robot.n_legs:]
    fig = Figure(figsize=(WIDTH_IN, 5.8))
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0.02, 0.07, 0.96, 0.84), projection="3d")
    for group, colour, width in ((base, "#666666", 2.0), (plat, "#c0392b", 2.5), (legs, "#1f5fa8", 2.0)):
        for a, b in group:
            ax.plot(*np.stack([a, b]).T, color=colour, lw=width)
    rails = []
    if robot.architecture == "3-PRS":      # the slides' guides (robot_segments draws the rods from the carriages)
        for leg in robot.legs:
            lo, hi = leg.stroke
            rails.append(np.stack([leg.carriage(lo), leg.carriage(hi)]).reshape(2, 3))
        for a, b in rails:
            ax.plot(*np.stack([a, b]).T, color="#666666", lw=3.0, ls="--")
    pts = np.concatenate([seg.reshape(-1, 3)] + [r for r in rails])
    ax.scatter(*seg.reshape(-1, 3).T, s=8, color="#222222", depthshade=False)
    ax.scatter(*pose[:3], s=30, color="#c0392b", marker="x", depthshade=False)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    span = np.maximum(hi - lo, 1e-6 * max(1.0, float((hi - lo).max())))
    ax.set_xlim(lo[0], hi[0]), ax.set_ylim(lo[1], hi[1]), ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(tuple(span), zoom=0.88)     # room for the axis labels of a tall robot
    for setter, name in ((ax.set_xlabel, "x"), (ax.set_ylabel, "y"), (ax.set_zlabel, "z")):
        setter(f"{name} [mm]", fontsize=FONT_PT, labelpad=8)
    ax.tick_params(labelsize=FONT_PT - 1)
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):      # few ticks: a wide robot's labels must not run together
        axis.set_major_locator(MaxNLocator(4))
    ax.view_init(elev=22, azim=-60)
    fig.suptitle(f"{robot.name}, {robot.label}, at its reference pose", fontsize=TITLE_PT + 1, y=0.97)
    out = save_figure(fig, path, dpi=DEFAULT_DPI)
    fig.clear()
    return out


def _workspace_section(doc, robot, grid, state, out, results, figure) -> None:
    doc.heading(TITLES["workspace"])
    ws = spatial_workspace(robot, n=grid)
    summ = ws.summary()
    results["workspace"] = summ
    r = ws.region
    what = {"constant-orientation": "the positions of the platform point P (x, y, z) reachable at the reference "
                                    "orientation",
            "reachable": "the positions of the platform point P (x, y, z) it reaches",
            "z-roll-pitch": "the values of its controlled coordinates (roll, pitch, z) it reaches, the parasitic "
                            "motions solved at every point"}[ws.kind]
    unit = f"{r.units[0]}\u00b3" if len(set(r.units)) == 1 else "\u00b7".join(r.units)
    doc.paragraph(f"The {ws.kind} workspace: {what}, with every leg on its working mode, every actuated joint "
                  f"within its range, every passive joint within its cone or angle range and no two legs "
                  f"interfering. Sampled on a {grid} x {grid} x {grid} grid in a box found around the reference "
                  f"point, its boundary refined by bisection: volume **{value_with_error(r.volume, r.volume_error)}"
                  f" {unit}** ({r.cells} cells inside).")
    rows = [[f"{name} [{u}]", summ[f"{name}_min"], summ[f"{name}_max"]] for name, u in zip(r.names, r.units)]
    doc.table(["coordinate", "min", "max"], rows)
    if ws.orientations is not None:
        doc.paragraph(f"At the reference point {_vec(ws.reference)} mm the platform tilts up to "
                      f"**{_g(summ['max_tilt_deg'])} deg** in some direction and up to "
                      f"**{_g(summ['guaranteed_tilt_deg'])} deg** in every direction (zero torsion).")
    slices, view = save_spatial_workspace_figure(robot, ws, out / "workspace.png")
    figure(slices, f"Slices of the workspace along {r.names[2]}.")
    figure(view, "The workspace's boundary in 3D (static view).")
    segments = robot_segments(robot) if r.units == ("mm", "mm", "mm") else None
    fragment = view3d_html(r, title=f"{robot.name}: {ws.kind} workspace (interactive)", robot_segments=segments)
    page = write_spatial_workspace_page(robot, ws, out / "workspace_3d.html")
    results["interactive_view"] = page.name
    doc.paragraph("The interactive view below turns with the mouse or a finger; it works offline (plain "
                  "JavaScript in this page).")
    doc.raw_html(fragment, markdown=f"The interactive 3D view is in `report.html` and in [{page.name}]({page.name}).")


def _maps_section(doc, robot, sources, ds, out, results, figure) -> None:
    doc.heading(TITLES["maps"])
    rows, js = [], {}
    for name, var in ds.data_vars.items():
        u = var.attrs.get("units", "")
        scale = np.degrees(1.0) if u == "rad" else 1.0
        shown = name if u != "rad" else f"{name}_deg"
        lo, hi = float(var.min()) * scale, float(var.max()) * scale
        js[shown] = {"min": lo, "max": hi, "unit": "deg" if u == "rad" else u}
        rows.append([shown, lo, hi, "deg" if u == "rad" else u])
    results["map"] = {"file": "map.nc", "ranges": js, "dims": list(ds["dp_max"].dims),
                      "points": int(np.isfinite(ds["dp_max"].values).sum())}
    dims = ds["dp_max"].dims
    size = " x ".join(str(ds.sizes[d]) for d in dims)
    doc.paragraph(f"The worst first-order errors at every point of the workspace's grid ({size}"
                  f" points over {', '.join(dims)}; blank outside the workspace or where the closure is near-"
                  "singular). `*_max` of the components are exact; `dp_max` and `dtheta_max` are certified upper "
                  "bounds and `*_attained` values that a configuration of the sources reaches. The map is saved as "
                  "`map.nc` (NetCDF, `xarray.open_dataset`).")
    doc.table(["quantity", "min", "max", "unit"], rows)
    # slices drawn among the layers holding at least a tenth of the fullest layer's points (the tips of the
    # workspace, a few cells, say little); the colour scale stays the whole map's
    counts = np.isfinite(ds["dp_max"].values).sum(axis=(0, 1))
    keep = np.flatnonzero(counts >= max(1, 0.1 * counts.max()))
    shown = ds.isel({dims[2]: keep})
    note = "" if len(keep) == len(counts) or counts[np.setdiff1d(np.arange(len(counts)), keep)].sum() == 0 else \
        " Layers with fewer than a tenth of the fullest layer's points (the workspace's tips) are not drawn."
    for variable, name, unit, scale, file in (("dp_max", "|dp|", "mm", 1.0, "map_dp.png"),
                                               ("dtheta_max", "|dtheta|", "deg", np.degrees(1.0), "map_dtheta.png")):
        lo, hi = float(ds[variable].min()) * scale, float(ds[variable].max()) * scale
        path = save_map_slices_figure(robot, shown, out / file, variable=variable, vmin=lo, vmax=hi)
        figure(path, f"Worst {name} ({unit}) in slices along {dims[2]}; one colour scale, the whole map's range "
                     f"{_g(lo)} - {_g(hi)} {unit}.{note}")


def _sources_section(doc, robot, sources, bref, results) -> None:
    doc.heading(TITLES["sources"])
    shares = bref.shares()
    comp = bref.components[0]
    k = int(np.argmax(comp[:3]))
    scale = np.array([1, 1, 1, np.degrees(1.0), np.degrees(1.0), np.degrees(1.0)])
    items = sorted(((label, s[0] * scale) for label, s in shares.items()), key=lambda t: -t[1][k])
    total = comp[k]
    rows, js = [], []
    for n, (label, s) in enumerate(items):
        frac = 100 * s[k] / total if total > 0 else 0.0
        if n < MAX_SOURCE_ROWS or len(items) == MAX_SOURCE_ROWS + 1:
            rows.append([source_description(robot.architecture, label), f"`{label}`", *[_share(v) for v in s],
                         _percent(frac)])
        js.append({"source": label, "description": source_description(robot.architecture, label),
                   **{c + ("_deg" if i >= 3 else ""): float(s[i]) for i, c in enumerate(COMPONENTS)},
                   f"percent_of_{COMPONENTS[k]}": float(frac)})
    # the same grouped by kind (joint and key, summed over the legs: the components' shares add up)
    if len(items) > len(rows):
        rest = items[len(rows):]
        rest_sum = sum(v for _, v in rest)
        rows.append([f"the {len(rest)} other sources together (each at most "
                     f"{_percent(100 * rest[0][1][k] / total if total else 0.0)})", "-",
                     *[_share(v) for v in rest_sum], _percent(100 * rest_sum[k] / total if total else 0.0)])
    kinds: dict[str, np.ndarray] = {}
    for label, s in items:
        key = kind_of(robot.architecture, label)
        kinds[key] = kinds.get(key, 0) + s
    kind_items = sorted(kinds.items(), key=lambda t: -t[1][k])
    results["sources"] = {"pose": bref.poses[0].tolist(), "sorted_by": COMPONENTS[k], "each": js,
                          "by_kind": [{"kind": name, **{c + ("_deg" if i >= 3 else ""): float(v[i])
                                                         for i, c in enumerate(COMPONENTS)},
                                       f"percent_of_{COMPONENTS[k]}": float(100 * v[k] / total) if total else 0.0}
                                      for name, v in kind_items]}
    head = [f"{c} [{u}]" for c, u in zip(COMPONENTS, _UNITS)]
    if kind_items and total > 0:
        top, top_v = kind_items[0]
        second = f"; then {kind_items[1][0]} ({_percent(100 * kind_items[1][1][k] / total)})" \
            if len(kind_items) > 1 else ""
        lead, lead_v = items[0]
        doc.paragraph(f"Each source's share of each component's worst case at the reference pose (the shares add "
                      f"up to the component: {COMPONENTS[k]} = {_g(total)} mm, the largest position component "
                      f"there). By kind, summed over the legs, **{top}** dominates with "
                      f"{_percent(100 * top_v[k] / total)} of {COMPONENTS[k]}{second}. The single largest source is "
                      f"`{lead}` ({source_description(robot.architecture, lead)}, "
                      f"{_percent(100 * lead_v[k] / total)}).")
    else:
        doc.paragraph("Every error source is zero: the robot has no pose error at first order.")
    doc.table(["kind of source (all legs)", *head, f"share of {COMPONENTS[k]}"],
              [[name, *[_share(x) for x in v], _percent(100 * v[k] / total) if total else "-"]
               for name, v in kind_items])
    shown = "Every source" if len(rows) == len(items) else f"The {MAX_SOURCE_ROWS} largest of the {len(items)} sources"
    doc.paragraph(f"{shown}, sorted by their share of {COMPONENTS[k]} (labels as in the error sources' file: "
                  "`legs[i].joints[j].key`; all of them in `results.json`):")
    doc.table(["source", "label", *head, f"share of {COMPONENTS[k]}"], rows)


def _design(doc, robot, sources, ds, state, results, figure, out, targets) -> None:
    number = doc.heading(TITLES["design"])
    design_section(doc, robot, sources, ds, state, results, figure, out, targets)
    d = results["design"]
    tgt = " and ".join(f"{'|dtheta|' if n == 'dtheta_deg' else '|dp|' if n == 'dp' else n.removesuffix('_deg')} "
                       f"<= {_g(v)} {'deg' if n.endswith('_deg') else 'mm'}" for n, v in d["targets"].items())
    glob = d.get("global") or {}
    cert = glob.get("scale_certified")
    if cert is not None:
        lam, how = cert, "certified over the whole workspace"
    elif glob:
        lam = min(d["scale_grid"], glob["scale_attained_limit"])
        how = (f"from the worst poses found over the workspace, not certified; {_g(d['scale_grid'])} at the map's "
               "grid points")
    else:
        lam, how = d["scale_grid"], "at the map's grid points only"
    verb = (f"may grow up to {_g(lam, 3)} times its value" if lam > 1 else
            f"must shrink to at most {_g(lam, 3)} of its value")
    state.get("summary", []).append(f"Design (section {number}): for {tgt} everywhere, every half-width {verb} "
                                    f"({how}).")


def _statistics(doc, robot, sources, state, results, figure, out, targets) -> None:
    number = doc.heading(TITLES["statistics"])
    statistics_section(doc, robot, sources, state, results, figure, out, targets)
    q = results["statistics"]["poses"][0]["quantities"]["dp"]
    state.get("summary", []).append(
        f"Statistics (section {number}): with every source independent and uniform in its set, |dp| at the "
        f"reference pose is {_g(q['rms'], 3)} mm RMS and below {_g(q['p99'], 3)} mm in 99 % of the robots "
        f"({_percent(100 * q['p99'] / q['worst'])} of its worst case).")


def _percent(value: float) -> str:
    """A share in percent: 3 significant digits, ``0 %`` for a rounding residue."""
    return "0 %" if abs(value) < 1e-9 else f"{value:.3g} %"


def _share(value: float) -> str:
    return "0" if abs(value) < 1e-12 else f"{value:.4g}"


def _method_section(doc, robot, grid) -> None:
    doc.heading(TITLES["method"])
    doc.bullets([
        "**First order, exact.** Each error source is a small displacement of a joint's distal part (a segment, a "
        "disc or a ball of half-width h). Every leg's closure equations turn it into a platform twist "
        "`t = W^-1 [G | R] s`, linear in the sources; each component's worst case (dx, dy, dz, and the small "
        "rotations about the base axes) is the sum of the sources' support functions, attained by a "
        "configuration of the sources.",
        f"**|dp| and |dtheta|** are the largest norms of the Minkowski sum of the sources' images: exact when every "
        f"source is a segment, else certified by branch and bound to {100 * DEFAULT_GAP:g} % (an upper bound, and a "
        "configuration attaining a value at most that much lower).",
        f"**Grid.** The workspace and the error map use {grid} points per axis in a box around the workspace; "
        "points outside the workspace or where the closure is near-singular are left out (NaN in `map.nc`). The "
        "map's maxima are maxima over the grid's points, not certified maxima over the whole region.",
        "**Checked** against an independent brute force (every source applied as a finite displacement in the legs' "
        "nonlinear chains, the pose solved again): components to 1e-6 relative on random robots of every "
        "architecture.",
        "**Design.** The synthesis scales every half-width by one factor (the largest meeting the targets at "
        "every grid point of the map); the global worst case searches the whole workspace by a branch and bound "
        "over boxes, which certifies an upper bound where every box can be proven regular within its budget; a "
        "kind's share is the sum "
        "of its sources' support functions along the component, so the shares add up to the component.",
        "**Statistics.** First-order, every source independent and uniform in its set; the analytic RMS is exact "
        "for that model (the covariance `sum v_s M_s M_s^T`, `v_s` = 1/3, 1/4, 1/5 for a segment, disc, ball), the "
        "percentiles are Monte Carlo estimates with their 95 % intervals (order statistics).",
        "**Not included yet for spatial robots:** certified bounds of the nonlinear model (here the errors are "
        "first order), a certified global worst case for the architectures other than the 6-UPS, a synthesis "
        "giving each joint its own factor (minimum cost), errors under loads and calibration. They exist for "
        "planar robots and will come for spatial ones; this report does not claim them.",
    ])
