"""The accuracy report of any robot and clearance set (``pmaccuracy reproduce --robot R --clearances C``).

The paper's reproduction report (:mod:`pmaccuracy.report`) is specific to its
3-PPR and its two clearance cases. This one works for every architecture and
every clearance file: the robot and its workspaces, error maps, what each kind
of error source contributes, the exact nonlinear check of the first-order
maxima, and a virtual experiment with the paper's protocol. It writes the same
files (``report.html``, ``report.md``, ``results.json``, PNG figures, NetCDF
maps); ``results.json`` keeps the keys of the paper report where they mean the
same (``robot``, ``version``, ``grid``, ``cases``, ``workspace``, ``elapsed_s``).
"""

from __future__ import annotations

import json
import time
from dataclasses import fields, replace
from pathlib import Path

import numpy as np

from .. import __version__
from . import figures
from ..accuracy.bounds import max_pose_errors
from .design_report import as_shape, describe_region, design_section, home_pose
from .document import Document, provenance
from .sections import ReportDependencyError, Section, SectionRunner
from ..model.manipulator import Manipulator
from ..kinematics import inverse_kinematics, regular_mask
from ..accuracy.maps import MAP_VARIABLES, error_map, save_map, summarize
from ..model.sources import (FIRST_ORDER_ONLY, ErrorSources, JointErrors, first_order_error,
                              worst_configuration)
from ..io.resolve import load_clearances
from ..kinematics.workspace import constant_orientation_workspace, save_workspace_figure
from ..io.resolve import robot_arg
from .. import experiment as ex
from ..accuracy.nonlinear import joint_displaced_pose

#: Orientations of the report's maps and workspaces (deg).
REPORT_PHIS_DEG = (0.0, 30.0)
#: The nonlinear check looks at the worst point among those this well conditioned (condition number of A and
#: inverse transmission): near a singularity the linear model no longer describes the robot anyway.
WELL_CONDITIONED = 10.0
#: The source kinds of a per-joint clearance file, grouped as the report lists them.
SOURCE_GROUPS = {"revolute clearance": ("radial",), "actuators": ("actuator",), "slide tilt": ("angular",),
                 "guide play": ("lateral",),
                 "tolerances": ("position", "direction", "length") + FIRST_ORDER_ONLY}
_JSON_KEYS = {"dx_max": "dx_max", "dy_max": "dy_max", "dphi_max": "dphi_max_deg", "dp_max": "dp_max"}


def only(sources: ErrorSources, keys: tuple[str, ...]) -> ErrorSources:
    """The sources with every key outside ``keys`` set to zero (block lengths kept)."""
    def keep(j: JointErrors) -> JointErrors:
        return replace(j, **{f.name: 0.0 for f in fields(j) if f.name != "block_length" and f.name not in keys})
    return ErrorSources(legs=tuple(tuple(keep(j) for j in leg) for leg in sources.legs), name=sources.name)


#: The report's section headings (a failed section keeps its heading above the box that replaces it).
TITLES = {"summary": "Summary", "robot": "The manipulator and its workspace",
          "maps": "Maximum pose errors over the workspace", "sources": "What each kind of error source contributes",
          "nonlinear": "Exact nonlinear check of the worst cases",
          "experiment": "Virtual experiment: simulated pushes (the paper's protocol)",
          "design": "Design decisions: certified worst cases, global maxima, tolerance synthesis, statistics"}
#: Seconds per grid point of a first-order map and fixed seconds of each section, measured on the project's
#: 2-core machine (cold process): the estimates printed before the report runs (never used for a decision).
MAP_SECONDS_PER_POINT = 1.5e-6
FIXED_SECONDS = {"summary": 1.0, "robot": 1.5, "maps": 1.0, "sources": 2.0, "nonlinear": 0.5, "experiment": 4.0,
                 "design": 12.0, "synthesis": 10.0}


def accuracy_report(out_dir: str | Path, robot: str | Manipulator, clearances, grid: int = 101, *,
                    phis_deg: tuple[float, ...] = REPORT_PHIS_DEG, seed: int = 0, experiment: bool = True,
                    workers: int = 2, design: bool = True, targets: dict | None = None,
                    phi_range_deg: tuple[float, float] | None = None, command: str | None = None,
                    region=None, strict: bool = False, stream=None, progress: bool | None = None) -> dict:
    """Write the accuracy report of ``robot`` with ``clearances`` in ``out_dir``; returns ``results.json``'s content.

    ``clearances`` is a per-joint clearance file or preset, or the 3-PPR format
    for a 3-PPR (converted to per-joint sources). With ``design`` the report ends with the design decisions
    (:func:`pmaccuracy.report.design_report.design_section` on these clearances): certified worst cases at
    named poses, the certified worst case over ``region`` for phi in ``phi_range_deg`` (deg; default the
    range of ``phis_deg``), tolerance synthesis for ``targets`` (``{"dp": mm, "dphi_deg": deg, ...}``; none:
    skipped, and the verdict says so) and statistics; ``region`` (a shape of :mod:`pmaccuracy.accuracy.regions`
    or a box; default the workspace) also sets the summary's headline values. ``command`` (the command line) goes
    to the footer.

    The sections run one after the other through :class:`pmaccuracy.report.sections.SectionRunner`: a section
    that fails (a pose where the loops cannot close, a singular region) is replaced by a box naming it and the
    reason, listed in ``results["failed_sections"]`` and announced by a
    :class:`~pmaccuracy.report.sections.SectionFailedWarning`; ``strict=True`` raises instead. ``stream`` (e.g.
    ``sys.stderr``) receives the estimate of each section before they run and, on a terminal or with
    ``progress=True``, a progress bar.
    """
    t0 = time.perf_counter()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    robot = robot_arg(robot)
    sources = load_clearances(clearances, robot)
    if not isinstance(sources, ErrorSources):
        sources = ErrorSources.from_clearance_set(sources)
    phis = np.radians(np.asarray(phis_deg, dtype=float))
    shape = as_shape(region)
    doc = Document(f"pmaccuracy: accuracy of {robot.name} ({robot.architecture}) with clearances {sources.name}",
                   footer=provenance(command, __version__))
    phi_range = tuple(phi_range_deg) if phi_range_deg is not None else (min(phis_deg), max(phis_deg))
    results: dict = {"robot": robot.name, "architecture": robot.architecture, "clearances": sources.name,
                     "version": __version__, "grid": grid, "region": describe_region(shape)}
    runner = SectionRunner(doc, results, stream=stream, progress=progress, strict=strict)
    state: dict = {}

    def needs_maps():
        if "ds" not in state:
            raise ReportDependencyError("needs the maps of section 'Maximum pose errors over the workspace', "
                                        "which could not be computed")
        return state["ds"]

    def maps():
        ds = error_map(robot, sources, phis, grid, progress=False)
        save_map(ds, out / "map.nc")
        state["ds"] = ds
        results["cases"] = {sources.name: summarize(ds)}
        _summary(doc, robot, sources, phis, grid, shape, results)

    map_s = MAP_SECONDS_PER_POINT * grid * grid * len(phis)
    with figures.Renderer(workers) as renderer:
        sections = [
            Section(TITLES["summary"], maps, FIXED_SECONDS["summary"] + map_s, heading=False,
                    short="maps"),
            Section(TITLES["robot"], lambda: _robot_section(doc, robot, phis_deg, out, results, renderer),
                    FIXED_SECONDS["robot"], short="workspace"),
            Section(TITLES["maps"], lambda: _maps_section(doc, needs_maps(), sources, out, renderer),
                    FIXED_SECONDS["maps"], short="map figures"),
            Section(TITLES["sources"], lambda: _sources_section(doc, robot, sources, phis, grid, results, out,
                                                                renderer),
                    FIXED_SECONDS["sources"] + 5 * map_s / 9, short="sources"),
            Section(TITLES["nonlinear"], lambda: _nonlinear_section(doc, robot, sources, needs_maps(), results),
                    FIXED_SECONDS["nonlinear"], short="nonlinear check")]
        if experiment:
            sections.append(Section(TITLES["experiment"], lambda: _experiment_section(
                doc, robot, sources, float(phis[0]), seed, out, results, renderer), FIXED_SECONDS["experiment"],
                short="virtual experiment"))
        if design:
            sections.append(Section(TITLES["design"], lambda: design_section(
                doc, robot, out, results, renderer, seed=seed, cases={sources.name: sources}, targets=targets,
                phi_range_deg=phi_range, region=region),
                FIXED_SECONDS["design"] + (FIXED_SECONDS["synthesis"] if targets else 0.0), short="design"))
        runner.run(sections)
    results["elapsed_s"] = round(time.perf_counter() - t0, 2)
    _method_section(doc)
    (out / "results.json").write_text(json.dumps(results, indent=2, default=float))
    (out / "report.md").write_text(doc.to_markdown(relative_to=out))
    (out / "report.html").write_text(doc.to_html())
    return results


def _range(pair, digits: int = 4) -> str:
    """``"lo - hi"`` at ``digits`` significant digits, or one value when both ends print the same."""
    lo, hi = (f"{v:.{digits}g}" for v in pair)
    return hi if lo == hi else f"{lo} - {hi}"


def _summary(doc: Document, robot: Manipulator, sources: ErrorSources, phis: np.ndarray, grid: int, shape,
             results: dict) -> None:
    """The report's opening: what was analysed and the headline ranges over the region the user gave (the
    workspace by default), kept in ``results["headline"]``."""
    doc.paragraph(f"Exact worst-case pose errors of `{robot.name}`, a {robot.architecture} "
                  f"({', '.join(c.label for c in robot.chains)}; an underscore marks the actuated joint), with the "
                  f"error sources `{sources.name}`. Lengths in mm, angles in degrees.")
    where = describe_region(shape)
    summary = results["cases"][sources.name] if shape is None else \
        summarize(error_map(robot, sources, phis, grid, progress=False, region=shape))
    results["headline"] = {"over": where, "orientations": summary}
    doc.bullets([f"phi = {phi} deg: dp_max {_range(v['dp_max'])} mm, dphi_max {_range(v['dphi_max_deg'])} deg over "
                 f"{where}" for phi, v in summary.items()])


def _robot_section(doc, robot, phis_deg, out, results, renderer) -> None:
    doc.heading("The manipulator and its workspace")
    rows = []
    for i, c in enumerate(robot.chains, start=1):
        act = c.actuated
        unit, conv = ("deg", np.degrees) if act.kind == "R" else ("mm", float)
        rows.append([i, c.label, f"({c.base[0]:.2f}, {c.base[1]:.2f})", f"{np.degrees(c.base_angle):.1f}",
                     f"({c.platform[0]:.2f}, {c.platform[1]:.2f})",
                     f"[{conv(act.range[0]):g}, {conv(act.range[1]):g}] {unit}", c.working_mode])
    doc.table(["leg", "joints", "base [mm]", "base angle [deg]", "platform point [mm]", "actuated range",
               "working mode"], rows)
    path = renderer.submit(out / "workspace.png", save_workspace_figure, robot, out / "workspace.png",
                           phis_deg=tuple(phis_deg))
    ws_rows, ws_json = [], {}
    for phi_deg in tuple(phis_deg):
        ws = constant_orientation_workspace(robot, np.radians(phi_deg))
        (x0, x1), (y0, y1) = ws.bounds
        ws_rows.append([f"{phi_deg:g}", ws.area, f"[{x0:.2f}, {x1:.2f}]", f"[{y0:.2f}, {y1:.2f}]"])
        ws_json[f"{phi_deg:g}"] = {"area": ws.area, "bounds": {"x": [x0, x1], "y": [y0, y1]}}
    results["workspace"] = ws_json
    doc.paragraph("Exact constant-orientation workspaces: each joint limit locks one joint and leaves a circle or "
                  "a line, the branch limits of the working modes add more; the region is bounded by their arcs "
                  "and segments and its area follows from Green's theorem.")
    doc.table(["phi [deg]", "area [mm^2]", "x range [mm]", "y range [mm]"], ws_rows)
    doc.figure(path, "The workspaces at each orientation, zoomed (left), and the whole robot at a pose inside them "
                     "with the zoomed region dashed (right).")


def _maps_section(doc, ds, sources, out, renderer) -> None:
    doc.heading("Maximum pose errors over the workspace")
    doc.paragraph("Exact worst cases at every point of a regular grid: each leg's sources bound its row of "
                  "A [dp; dphi] by a half-width c_i, so the error set is the parallelepiped A^-1 diag(c) [-1, 1]^3. "
                  "Points near a singularity (condition number of A above 100, or a leg's transmission below "
                  "0.01) are left blank.")
    rows = []
    for phi, ranges in summarize(ds).items():
        rows.append([phi] + [_range(ranges[_JSON_KEYS[v]]) for v in MAP_VARIABLES])
    doc.table(["phi [deg]", "dx_max [mm]", "dy_max [mm]", "dphi_max [deg]", "dp_max [mm]"], rows)
    for phi in ds.phi.values:
        path = renderer.submit(out / f"map_phi{phi:g}.png", figures.plot_error_map, ds.sel(phi=[phi]), float(phi),
                               title=f"{ds.attrs.get('robot', '')}, clearances {sources.name}: maximum pose "
                                     f"errors at phi = {phi:g} deg")
        doc.figure(path, f"phi = {phi:g} deg: dx_max, dy_max, dp_max (mm) and dphi_max (deg).")


def named_poses(robot: Manipulator, phi: float) -> tuple[np.ndarray, list[str]]:
    """Poses ``(n, 3)`` [mm, mm, rad] where the report lists each source's share, and their names: the home
    pose (:func:`pmaccuracy.report.design_report.home_pose`) and the centroid of the workspace at ``phi``."""
    poses, names = [home_pose(robot)], ["home"]
    ws = constant_orientation_workspace(robot, phi)
    if ws.area > 0:
        poses.append(np.array([*ws.vertices.mean(axis=0), phi]))
        names.append(f"workspace centre, phi = {np.degrees(phi):g} deg")
    return np.array(poses), names


def _sources_section(doc, robot, sources, phis, grid, results, out, renderer) -> None:
    doc.heading("What each kind of error source contributes")
    rows, js, panels, at_rows = [], {}, [], []
    coarse = max(21, grid // 3)
    poses, names = named_poses(robot, float(phis[0]))
    regular = np.asarray(regular_mask(robot, poses, WELL_CONDITIONED))
    for name, keys in SOURCE_GROUPS.items():
        part = only(sources, keys)
        if all(getattr(j, k) == 0 for leg in part.legs for j in leg for k in keys):
            continue
        ds = error_map(robot, part, phis, coarse, progress=False)
        summ = summarize(ds)
        b = max_pose_errors(robot, part, poses, allow_outside=True, singular="nan")
        at = {nm: {"dp_max": float(b.dp_max[k]), "dphi_max_deg": float(b.dphi_max_deg[k])}
              for k, nm in enumerate(names) if regular[k]}
        js[name] = {"maxima": summ, "at": at}
        for nm, v in at.items():
            at_rows.append([name, nm, _share(v['dp_max']), _share(v['dphi_max_deg'])])
        for phi, v in summ.items():
            rows.append([name, phi, _share(v['dx_max'][1]), _share(v['dy_max'][1]), _share(v['dphi_max_deg'][1]),
                         _share(v['dp_max'][1])])
        layer = ds.isel(phi=0)
        panels.append((layer.x.values, layer.y.values, layer.dp_max.values, f"{name} alone",
                       figures.quantity_label("dp_max")))
    results["sources"] = js
    doc.paragraph("Each kind of source alone (the others set to zero). First at named poses, where a designer "
                  "reads the share of each kind (mm; deg):")
    doc.table(["sources", "pose", "dp_max [mm]", "dphi_max [deg]"], at_rows)
    number = doc.next_figure
    doc.paragraph(f"Then as maps (Figure {number}, phi = {np.degrees(phis[0]):g} deg) and as the largest value over "
                  f"the workspace ({coarse} x {coarse} grid). A maximum over the workspace is reached near its "
                  "edge, where the robot approaches a singularity and every source is amplified: read it as the "
                  "edge's value, not as the typical share. Contributions add up in each leg's half-width, so "
                  "dx, dy and dphi maxima are additive over the kinds and dp sub-additive.")
    doc.figure(renderer.submit(out / "sources_dp_max.png", figures.plot_panels, panels,
                               suptitle=f"{figures.SYMBOLS['dp_max'][0]} of each kind of source alone, "
                                        f"phi = {np.degrees(phis[0]):g} deg",
                               shapes=[(robot, float(np.degrees(phis[0])))] * len(panels)),
               f"dp_max of each kind of error source alone at phi = {np.degrees(phis[0]):g} deg (mm).")
    doc.table(["sources", "phi [deg]", "max dx_max [mm]", "max dy_max [mm]", "max dphi_max [deg]",
               "max dp_max [mm]"], rows)


def _share(value: float) -> str:
    """A share in the per-source tables (mm or deg): 4 significant digits, and ``0`` for a rounding residue
    (below 1e-12, e.g. a source that does not move that quantity) instead of ``1.2e-17``."""
    return "0" if abs(value) < 1e-12 else f"{value:.4g}"


def _nonlinear_section(doc, robot, sources, ds, results) -> None:
    doc.heading("Exact nonlinear check of the worst cases")
    rows, js = [], []
    for phi in ds.phi.values:
        layer = ds.sel(phi=phi)
        X, Y = np.meshgrid(layer.x.values, layer.y.values)
        poses = np.stack([X, Y, np.full(X.shape, np.radians(float(phi)))], axis=-1)
        dp = layer["dp_max"].values.copy()
        finite = np.isfinite(dp)
        dp[finite & ~regular_mask(robot, np.where(finite[..., None], poses, 0.0), WELL_CONDITIONED)] = np.nan
        if not np.isfinite(dp).any():
            continue
        j, i = np.unravel_index(np.nanargmax(dp), dp.shape)
        pose = poses[j, i][None]
        b = max_pose_errors(robot, sources, pose, details=True)
        joints = inverse_kinematics(robot, pose).joints
        for q, row in (("dx", 0), ("dy", 1), ("dphi", 2), ("dp", None)):
            cfg = worst_configuration(robot, sources, joints, pose, b.worst_signs[q])
            lin = first_order_error(robot, joints, pose, cfg)[0]
            exact = (joint_displaced_pose(robot, pose, cfg) - pose)[0]
            first = float(np.hypot(*lin[:2])) if row is None else float(abs(lin[row]))
            true = float(np.hypot(*exact[:2])) if row is None else float(abs(exact[row]))
            scale = np.degrees if q == "dphi" else float
            rows.append([f"{phi:g}", f"({pose[0, 0]:.2f}, {pose[0, 1]:.2f})", q, f"{scale(first):.5g}",
                         f"{scale(true):.5g}", f"{100 * (true - first) / first:+.3f} %"])
            js.append({"phi_deg": float(phi), "pose": pose[0].tolist(), "quantity": q, "first_order": first,
                       "exact": true})
    results["nonlinear_check"] = js
    doc.paragraph("At the point of each map where dp_max is largest (among points whose condition number and "
                  f"inverse transmission are below {WELL_CONDITIONED:g}), every source is put at its worst-case value "
                  "and the exact loop closure is solved with the actuators locked (the virtual prototype). The "
                  "difference from the first-order maximum is of second order in the clearances (mm; dphi in deg); "
                  "it grows quickly towards a singularity, where the errors are amplified most and where a first-"
                  "order bound should not be trusted.")
    doc.table(["phi [deg]", "pose [mm]", "quantity", "first order", "exact", "difference"], rows)


def _experiment_section(doc, robot, sources, phi, seed, out, results, renderer) -> None:

    doc.heading("Virtual experiment: simulated pushes (the paper's protocol)")
    meas = ex.simulate_experiment(robot, sources, phi, 5, seed=seed)
    path = ex.write_measurements(out / "experiment" / "measurements.csv", meas)
    cmp_ = ex.compare(robot, sources, meas)
    paper, width = cmp_.rmsd(1.0), cmp_.rmsd(2.0)
    results["experiment"] = {"measurements": str(path.relative_to(out)), "points": len(meas), "seed": seed,
                             "phi_deg": float(np.degrees(phi)), "rmsd": paper, "rmsd_width_consistent": width}
    doc.paragraph(f"{len(meas)} points of a 5 x 5 grid of the phi = {np.degrees(phi):g} deg workspace; at each, six "
                  "pushes (+-x, +-y, +-rotation) drive every source to the extreme that moves the platform furthest "
                  "that way, the exact loop closure gives the reading, and camera noise (0.01 mm, 0.01 deg, seed "
                  f"{seed}) is added. **Simulated data**: the errors are ranges of the six simulated readings (Eq. 23), "
                  "which check the comparison and the model against itself, not the model against a real robot; "
                  "they are compared with the "
                  "one-sided predicted maxima as the paper does, and with twice them (the full width of the "
                  "symmetric error set).")
    doc.table(["quantity", "RMSD, paper's convention", "RMSD, simulated range - 2 x predicted"],
              [[q, f"{paper[q]:.4g}", f"{width[q]:.4g}"] for q in paper])


def _method_section(doc: Document) -> None:
    doc.heading("Method", numbered=False)
    doc.paragraph("Every leg is a chain of three one-DOF joints. With its actuated joint locked it constrains the "
                  "platform through the one wrench reciprocal to its two passive joints' twists (row i of A; its "
                  "pairing with the actuated twist is B_ii). Each error source is a small twist of the part of the "
                  "leg beyond it: a revolute clearance a translation within a disk, a slide's angular clearance a "
                  "tilt of its block (carriage or bushing) about the block's centre, guide play a shift normal to "
                  "the rail and a tilt about the block's centre within the rhombus of Eq. 16, an actuator error a "
                  "motion along its joint. Paired with the wrench each gives "
                  "its share of e_i; the shares of a leg add up to the half-width c_i, and the pose errors fill "
                  "A^-1 diag(c) [-1, 1]^3. dx, dy, dphi are its support functions and dp its largest vertex norm, "
                  "exactly.")
