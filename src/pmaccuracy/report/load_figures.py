r"""Figures of clearances under load: the robot with the wrench, the joints' reactions and contact states.

:func:`plot_load` draws the robot at a pose (:func:`pmaccuracy.kinematics.workspace.draw_robot`) with

* the resultant external wrench on the platform at its centre ``P`` (weight included): the force as a red
  arrow, the moment as a curved red arrow (counter-clockwise positive);
* each joint's force on the part beyond it, ``lambda_i f_i`` (:func:`pmaccuracy.accuracy.loads.statics`), as a
  blue arrow at the joint, every force arrow drawn at one stated scale (N per mm of arrow);
* the contact state each reaction selects (:func:`pmaccuracy.accuracy.loads.loaded_pose_error`): an R joint's
  pin drawn offset in its bore along the distal part's shift, a P joint's block as its clearance rhombus
  ``|L tau +- 2 sigma| <= 2 eps`` (Eq. 16; axes: shift ``sigma`` normal to the rail, tilt ``tau``) with the
  vertex taken filled; glyphs are drawn enlarged, not to scale;
* the legs whose wrench intensity is below the threshold (unloaded: their state undetermined) in light grey;
* the platform displaced by the exact loaded pose error, magnified by a stated factor (dashed).

:func:`plot_preload` draws a preload design (:func:`pmaccuracy.accuracy.loads.design_preload`): the legs whose
contact flips over the box of process wrenches, the preload wrench, and beside it the loaded error's range
without preload, the constant offset with it and the unloaded worst case.

>>> fig = plot_load("aalborg_3ppr", "case2", [0.0, 0.0, 0.0], Load(fx=10.0))
>>> fig.axes[0].get_title()
'aalborg_3ppr, case2 at (0, 0) mm, 0 deg: fx = 10 N, fy = 0 N, m = 0 N mm'
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import FancyArrowPatch, Polygon
from matplotlib.path import Path as MplPath

from ..accuracy.bounds import max_pose_errors
from ..accuracy.loads import DEFAULT_THRESHOLD_N, Load, design_preload, loaded_pose_error, wrench_set_errors
from ..errors import ConfigError
from ..io.resolve import clearances_arg, robot_arg
from ..kinematics import as_poses, leg_states
from ..kinematics.workspace import draw_robot
from ..model.manipulator import Manipulator
from ..model.sources import ErrorSources, block_centre
from .figures import _renderer, FONT_PT, REPORT_WIDTH_IN, TITLE_PT, nice_step, plot_panels, wrap_text

#: Colours: the external wrench, the joints' forces, a leg's contact state, unloaded legs, the preload.
LOAD_COLOUR, REACTION_COLOUR, CONTACT_COLOUR, UNLOADED_COLOUR, PRELOAD_COLOUR = \
    "tab:red", "tab:blue", "tab:blue", "0.72", "tab:green"
#: Longest force arrow and displayed displacement, as shares of the drawing's size.
ARROW_SHARE, DISPLACEMENT_SHARE = 0.2, 0.08


def _sources(robot: Manipulator, clearances) -> ErrorSources:
    c = clearances_arg(clearances, robot)
    return c.check(robot) if isinstance(c, ErrorSources) else ErrorSources.from_clearance_set(c)


def _span(robot: Manipulator, pose: np.ndarray) -> float:
    """Size (mm) of the robot's drawing at ``pose``: the diagonal of the box around bases, joints and platform."""
    pts = [complex(*c.base) for c in robot.chains]
    for st in leg_states(robot, pose):
        pts += [complex(np.asarray(c)) for c in st.centres]
    pts += [complex(*p) for p in robot.platform_points(pose)]
    pts = np.array(pts)
    return float(np.hypot(np.ptp(pts.real), np.ptp(pts.imag))) or 1.0


def _moment_arrow(ax, centre: complex, radius: float, moment: float, colour: str, label: str | None) -> None:
    """A curved arrow of 270 deg around ``centre``: counter-clockwise for ``moment > 0``."""
    sweep = np.linspace(0.0, 1.5 * math.pi, 40) * (1.0 if moment > 0 else -1.0) + math.pi / 4
    pts = centre + radius * np.exp(1j * sweep)
    ax.add_patch(FancyArrowPatch(path=MplPath(np.column_stack([pts.real, pts.imag])), arrowstyle="-|>",
                                 mutation_scale=12, color=colour, linewidth=1.6, zorder=7))
    if label:
        ax.plot([], [], linestyle="none", marker=r"$\circlearrowleft$" if moment > 0 else r"$\circlearrowright$",
                markersize=11, color=colour, label=label)


def _arrow(ax, start: complex, vector: complex, colour: str, label: str | None = None, width: float = 1.6,
           gid: str | None = None) -> None:
    ax.add_patch(FancyArrowPatch((start.real, start.imag), ((start + vector).real, (start + vector).imag),
                                 arrowstyle="-|>", mutation_scale=11, color=colour, linewidth=width, zorder=7,
                                 shrinkA=0, shrinkB=0, gid=gid))
    if label:
        ax.plot([], [], color=colour, linewidth=width, marker=">", markevery=[1], markersize=6, label=label)


def _nice_floor(value: float) -> float:
    """The largest of 1, 2, 2.5, 5 x 10^k that is <= ``value`` (> 0)."""
    k = math.floor(math.log10(value))
    return next(v for v in (m * 10.0 ** k for m in (10.0, 5.0, 2.5, 2.0, 1.0)) if v <= value * (1 + 1e-12))


def _wrench(ax, centre: complex, w: np.ndarray, n_per_mm: float, radius: float, colour: str, what: str) -> None:
    """Force arrow and moment arrow of ``w`` = [fx N, fy N, m N mm] at ``centre``."""
    f = complex(w[0], w[1])
    if abs(f) > 0:
        _arrow(ax, centre, f / n_per_mm, colour, f"{what} force |f| = {abs(f):.3g} N", width=2.2, gid=what)
    if w[2] != 0:
        _moment_arrow(ax, centre, radius, w[2], colour, f"{what} moment m = {w[2]:.3g} N mm")


def _pose_text(robot: Manipulator, pose: np.ndarray) -> str:
    x, y, phi = (round(float(v), 9) + 0.0 for v in (pose[0], pose[1], math.degrees(pose[2])))   # no 1e-15 noise
    return f"({x:.4g}, {y:.4g}) mm, {phi:.4g} deg"


def plot_load(robot: Manipulator | str, clearances, pose, load: Load, *, threshold: float = DEFAULT_THRESHOLD_N,
              magnify: float | None = None, title: str | None = None) -> Figure:
    """The robot at ``pose`` ``(3,)`` [mm, mm, rad] under ``load`` (module docstring): wrench, joint forces,
    contact states, unloaded legs and the loaded platform magnified ``magnify`` times (default: a round factor
    that makes the displacement about :data:`DISPLACEMENT_SHARE` of the drawing). Returns the Figure."""
    robot = robot_arg(robot)
    sources = _sources(robot, clearances)
    pose = as_poses(pose).reshape(3)
    if magnify is not None and not (math.isfinite(magnify) and magnify > 0):
        raise ConfigError(f"must be a factor > 0, got {magnify}", key="magnify")
    if isinstance(load, Load) and not np.any(load.wrench(pose)):
        raise ConfigError("the load is zero: no reaction to draw (every clearance state is possible)", key="load")
    res = loaded_pose_error(robot, sources, pose, load, threshold=threshold)
    st = res.statics
    span = _span(robot, pose)
    fig = Figure(figsize=(REPORT_WIDTH_IN, 7.2))
    ax = fig.add_axes((0.08, 0.30, 0.88, 0.62))
    unloaded = np.asarray(res.unloaded)
    draw_robot(robot, pose, ax, label=False,
               leg_colors=tuple(UNLOADED_COLOUR if u else "0.25" for u in unloaded))
    # ------------------------------------------------------------ forces, one scale
    forces = np.abs(st.force)
    biggest = max(float(forces.max()), math.hypot(st.wrench[0], st.wrench[1]), 1e-300)
    n_per_mm = nice_step(biggest / (ARROW_SHARE * span))
    centre = complex(pose[0], pose[1])
    _wrench(ax, centre, st.wrench, n_per_mm, 0.06 * span, LOAD_COLOUR, "external")
    states = leg_states(robot, pose)
    glyph = 0.022 * span
    shown_r = shown_p = False
    for i, (chain, leg, lst) in enumerate(zip(robot.chains, sources.legs, states)):
        for k, (joint, e) in enumerate(zip(chain.joints, leg)):
            at = complex(np.asarray(lst.centres[k])) if joint.kind == "R" else complex(
                np.asarray(block_centre(joint, lst, k)))
            if not unloaded[i] and abs(st.force[i, k]) > 0:
                _arrow(ax, at, complex(st.force[i, k]) / n_per_mm, REACTION_COLOUR,
                       None if (i, k) != (0, 0) else f"joint force on the distal part (1 mm of arrow = {n_per_mm:g} N)",
                       width=1.3, gid=f"force {i} {k}")
            colour = UNLOADED_COLOUR if unloaded[i] else CONTACT_COLOUR
            if joint.kind == "R" and (e.radial or e.position):
                # the bore beside the joint, away from the platform centre, with a leader line
                out = at - centre
                spot = at + 3.2 * glyph * (out / abs(out) if abs(out) > 1e-9 else 1j)
                ring = spot + 1.3 * glyph * np.exp(1j * np.linspace(0, 2 * np.pi, 48, endpoint=False))
                ax.plot([at.real, spot.real], [at.imag, spot.imag], color=colour, linewidth=0.6, zorder=7)
                ax.add_patch(Polygon(np.column_stack([ring.real, ring.imag]), closed=True, facecolor="white",
                                     edgecolor=colour, linewidth=1.2, zorder=8, gid=f"bore {i} {k}"))
                shift = complex(res.configuration.shift[i, k])
                pin = spot + (0.65 * glyph * shift / abs(shift) if abs(shift) > 0 else 0)
                ax.plot(pin.real, pin.imag, "o", markersize=5.5, color=colour, zorder=9,
                        markerfacecolor=colour if abs(shift) > 0 else "white", gid=f"pin {i} {k}")
                if not shown_r:
                    ax.plot([], [], "o", markersize=9, markerfacecolor="white", markeredgecolor=CONTACT_COLOUR,
                            label="R joint (beside it, enlarged): bore, pin pressed opposite the joint force")
                shown_r = True
            if joint.kind == "P" and (e.lateral or e.angular):
                normal = 1j * complex(np.asarray(lst.dirs[k]))
                rail = complex(np.asarray(lst.dirs[k]))
                corner = at + 2.8 * glyph * normal * (1 if (i + k) % 2 else -1)     # beside the block
                verts = [corner + 1.4 * glyph * v for v in (normal, rail, -normal, -rail)]
                ax.add_patch(Polygon(np.column_stack([np.real(verts), np.imag(verts)]), closed=True,
                                     facecolor="white", edgecolor=colour, linewidth=1.1, zorder=8))
                if not shown_p:
                    ax.plot([], [], "D", markersize=9, markerfacecolor="white", markeredgecolor=CONTACT_COLOUR,
                            label="P block (beside it, enlarged): clearance rhombus, shift $\\sigma$ along the "
                                  "rail normal, tilt $\\tau$ along the rail; dot: the vertex taken")
                ax.plot([at.real, corner.real], [at.imag, corner.imag], color=colour, linewidth=0.6, zorder=7)
                sigma = float(res.configuration.sigma[i, k])
                tau = float(res.configuration.tau[i, k] + res.configuration.tilt[i, k])
                if sigma:
                    v = corner + 1.4 * glyph * normal * np.sign(sigma)
                elif tau:
                    v = corner + 1.4 * glyph * rail * np.sign(tau)
                else:
                    v = None
                if v is not None:
                    ax.plot(v.real, v.imag, "o", markersize=6, color=colour, zorder=9, gid=f"vertex {i} {k}")
                else:
                    ax.text(corner.real, corner.imag, "?", ha="center", va="center", fontsize=8, color="0.4",
                            zorder=9)
                shown_p = True
    # ------------------------------------------------------------ the loaded platform, magnified
    d = np.asarray(res.exact, dtype=float)
    if not np.all(np.isfinite(d)):
        d = np.asarray(res.first_order, dtype=float)
    reach = max(math.hypot(d[0], d[1]), abs(d[2]) * robot.characteristic_length, 1e-300)
    k = float(magnify) if magnify else _nice_floor(DISPLACEMENT_SHARE * span / reach)
    moved = robot.platform_points(pose + k * d)
    ax.add_patch(Polygon(moved, closed=True, fill=False, edgecolor="k", linestyle="--", linewidth=1.2, zorder=6,
                         gid=f"loaded platform x {k:g}",
                         label=f"loaded platform, displacement x {k:g}: dx = {d[0] * 1e3:.1f} um, "
                               f"dy = {d[1] * 1e3:.1f} um, dphi = {math.degrees(d[2]):.3f} deg"))
    if any(unloaded):
        legs = ", ".join(str(i + 1) for i in range(3) if unloaded[i])
        ax.plot([], [], color=UNLOADED_COLOUR, linewidth=3,
                label=f"unloaded leg {legs}: contact undetermined, the error a range: dx $\\pm$ "
                      f"{res.spread[0] * 1e3:.1f} um, dy $\\pm$ {res.spread[1] * 1e3:.1f} um, dphi $\\pm$ "
                      f"{math.degrees(res.spread[2]):.3f} deg")
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.margins(0.08)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.grid(True, linewidth=0.3, alpha=0.5)
    name = robot.name
    cname = getattr(clearances, "name", clearances) if not isinstance(clearances, str) else clearances
    _stack(fig, [(ax, title or f"{name}, {cname} at {_pose_text(robot, pose)}: fx = {load.fx:g} N, "
                             f"fy = {load.fy:g} N, m = {load.m:g} N mm"
                             + (f", mass {load.mass:g} kg" if load.mass else ""), None)])
    return fig


def _stack(fig: Figure, rows: list, left: float = 1.0, right: float = 0.25, max_h: float = 4.6) -> None:
    """Lay ``rows`` ``[(axes, title, height or None), ...]`` out top to bottom on ``fig`` (:data:`REPORT_WIDTH_IN`
    wide), each with its title wrapped over it and its legend (the axes' legend entries, labels wrapped)
    under its x label; heights and widths measured in inches, so no text reaches the next row or leaves
    the figure. ``height`` None: an equal-aspect drawing sized to its data limits (at most ``max_h``)."""
    width = REPORT_WIDTH_IN
    w = width - left - right
    line = 1.25 * FONT_PT / 72.0
    laid, total = [], 0.1
    for ax, title, height in rows:
        if height is None:
            (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
            aw, height = w, w * (y1 - y0) / max(x1 - x0, 1e-12)
            if height > max_h:
                aw, height = max_h * (x1 - x0) / max(y1 - y0, 1e-12), max_h
        else:
            aw = w
        x0 = max(left, (width - aw + left - right) / 2)  # a narrow drawing centred (y labels on its left)
        centre = x0 + aw / 2                            # the title is centred over its axes
        text = wrap_text(fig, title, 2 * min(centre, width - centre) - 0.2, TITLE_PT)
        ax.set_title(text, fontsize=TITLE_PT)
        ax.tick_params(labelsize=FONT_PT)
        ax.xaxis.label.set_fontsize(FONT_PT)
        ax.yaxis.label.set_fontsize(FONT_PT)
        handles, labels = ax.get_legend_handles_labels()
        legend = None
        if handles:
            labels = [wrap_text(fig, lab, width - 1.2, FONT_PT) for lab in labels]
            legend = fig.legend(handles, labels, loc="upper left", fontsize=FONT_PT, frameon=False)
        leg_h = 0.0 if legend is None else legend.get_window_extent(_renderer(fig)).height / fig.dpi
        title_h = (text.count("\n") + 1) * line + 0.15
        under = 2 * line + 0.3
        laid.append((ax, x0, aw, height, title_h, under, legend, leg_h))
        total += title_h + height + under + leg_h + 0.2
    fig.set_size_inches(width, total)
    y = total - 0.1
    for ax, x0, aw, height, title_h, under, legend, leg_h in laid:
        y -= title_h + height
        ax.set_position((x0 / width, y / total, aw / width, height / total))
        y -= under
        if legend is not None:
            legend.set_bbox_to_anchor((0.3 / width, y / total), transform=fig.transFigure)
        y -= leg_h + 0.2


def plot_preload(robot: Manipulator | str, clearances, pose, center, half, *, title: str | None = None) -> Figure:
    """A preload design at ``pose`` ``(3,)`` [mm, mm, rad] for process wrenches in the box ``center +- half``
    ([N, N, N mm]): left, the robot with the legs whose contact flips over the box (orange) and the preload
    (green arrows); right, per quantity, the loaded error's range over the box without preload, the constant
    offset with the preload, and the unloaded worst case ``2 x max`` range (mm, deg). Returns the Figure."""
    robot = robot_arg(robot)
    sources = _sources(robot, clearances)
    pose = as_poses(pose).reshape(3)
    pre = design_preload(robot, sources, pose, center, half)
    rng = wrench_set_errors(robot, sources, pose[None], center, half)
    flips = rng.flips[0]
    span = _span(robot, pose)
    fig = Figure(figsize=(REPORT_WIDTH_IN, 6.4))
    ax = fig.add_axes((0.07, 0.30, 0.50, 0.62))
    draw_robot(robot, pose, ax, label=False, leg_colors=tuple("tab:orange" if f else "0.25" for f in flips))
    p = np.asarray(pre.wrench, dtype=float)
    c, h = np.asarray(center, float), np.asarray(half, float)
    biggest = max(math.hypot(p[0], p[1]), math.hypot(abs(c[0]) + h[0], abs(c[1]) + h[1]), 1e-300)
    n_per_mm = nice_step(biggest / (ARROW_SHARE * span))
    centre = complex(pose[0], pose[1])
    _wrench(ax, centre, p, n_per_mm, 0.07 * span, PRELOAD_COLOUR, "preload")
    # the process forces' box, drawn at the same scale around P
    box = [complex(c[0] + sx * h[0], c[1] + sy * h[1]) / n_per_mm for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    ax.add_patch(Polygon(np.column_stack([np.real(box), np.imag(box)]) + [pose[0], pose[1]], closed=True,
                         facecolor=LOAD_COLOUR, alpha=0.15, edgecolor=LOAD_COLOUR, zorder=6,
                         label=f"process forces fx, fy (box, 1 mm = {n_per_mm:g} N; m in "
                               f"[{c[2] - h[2]:g}, {c[2] + h[2]:g}] N mm)"))
    legs = ", ".join(str(i + 1) for i in range(3) if flips[i]) or "none"
    ax.plot([], [], color="tab:orange", linewidth=3, label=f"legs whose contact flips without preload: {legs}")
    ax.plot([], [], color=PRELOAD_COLOUR, linewidth=2,
            label=f"preload fx = {p[0] + 0:.3g} N, fy = {p[1] + 0:.3g} N, m = {p[2] + 0:.3g} N mm "
                  f"(size {pre.size:.3g} N)")
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.margins(0.08)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.grid(True, linewidth=0.3, alpha=0.5)
    # ------------------------------------------------------------ ranges beside the worst case
    bx = fig.add_axes((0.66, 0.30, 0.31, 0.62))
    scale = np.array([1.0, 1.0, 180.0 / math.pi])
    without = (rng.upper[0] - rng.lower[0]) * scale
    offset = np.abs(pre.offset) * scale
    worst = 2 * np.asarray(pre.worst) * scale
    x = np.arange(3)
    bx.bar(x - 0.27, without, 0.26, color="tab:orange", label="range over the box, no preload")
    bx.bar(x, np.zeros(3), 0.26, color=PRELOAD_COLOUR, label="range with the preload (0)")
    bx.plot(x, np.zeros(3), "_", color=PRELOAD_COLOUR, markersize=14, markeredgewidth=3)
    bx.bar(x + 0.27, worst, 0.26, color="0.6", label="unloaded worst case (2 x max)")
    bx.plot(x, offset, "D", color="k", markersize=5, label="|constant offset| with the preload")
    bx.set_xticks(x, [r"$\delta x$ [mm]", r"$\delta y$ [mm]", r"$\delta\phi$ [deg]"])
    bx.set_ylabel("mm or deg (as labelled)")
    bx.grid(True, axis="y", linewidth=0.3, alpha=0.5)
    _stack(fig, [(ax, title or f"{robot.name} at {_pose_text(robot, pose)}: preload for the process box", None),
                 (bx, "clearance error", 2.6)], max_h=3.6)
    return fig


__all__ = ["plot_load", "plot_preload"]


def plot_loaded_map(ds, phi_deg: float, *, vmin: float | None = None, vmax: float | None = None,
                    log: bool = False) -> Figure:
    """Panels of a loaded error map (:func:`pmaccuracy.accuracy.loads.loaded_error_map`) at ``phi_deg``: the
    signed first-order loaded errors ``dx, dy`` (mm) and ``dphi`` (deg), ``|dp|`` (mm), and, where some leg is
    unloaded, the half-width ``dp`` spread it leaves (``hypot(dx_spread, dy_spread)``, mm) and the number of
    unloaded legs. ``vmin``/``vmax``/``log`` apply to the mm panels.

    >>> from pmaccuracy.accuracy.loads import loaded_error_map
    >>> ds = loaded_error_map("aalborg_3ppr", "case2", Load(fx=5.0, fy=-3.0), [0.0], n=9)
    >>> len([ax for ax in plot_loaded_map(ds, 0.0).axes if ax.get_title()])     # every leg loaded: 4 panels
    4
    """
    d = ds.sel(phi=phi_deg, method="nearest")
    x, y = ds["x"].values, ds["y"].values
    panels = [(x, y, d["dx"].values, r"$\delta x$ [mm]", "mm"), (x, y, d["dy"].values, r"$\delta y$ [mm]", "mm"),
              (x, y, d["dp"].values, r"$|\delta p|$ [mm]", "mm"), (x, y, d["dphi"].values, r"$\delta\phi$ [deg]", "deg")]
    limited = [True, True, True, False]
    unloaded = d["unloaded_legs"].values
    if np.nanmax(unloaded, initial=0.0) > 0:
        panels += [(x, y, np.hypot(d["dx_spread"].values, d["dy_spread"].values), r"$\delta p$ spread of unloaded legs [mm]",
                    "mm"), (x, y, unloaded, "unloaded legs", "legs")]
        limited += [True, False]
    load = ds.attrs.get("load", "")
    fig = plot_panels(panels, suptitle=f"Loaded pose error of {ds.attrs.get('robot', '')} at phi = {phi_deg:g} deg\n"
                                       f"{load}", ncols=min(len(panels), 3), vmin=vmin, vmax=vmax, log=log,
                      limited=limited)
    return fig


def plot_wrench_set_map(ds, phi_deg: float, *, vmin: float | None = None, vmax: float | None = None,
                        log: bool = False) -> Figure:
    """Panels of a wrench-set map (:func:`pmaccuracy.accuracy.loads.wrench_set_map`) at ``phi_deg``: the width of
    the loaded error's range over the box of process wrenches, ``dx_hi - dx_lo``, ``dy_hi - dy_lo`` (mm) and
    ``dphi_hi - dphi_lo`` (deg), and the number of legs whose contact flips inside the box (where the error
    jumps). ``vmin``/``vmax``/``log`` apply to the mm panels.

    >>> from pmaccuracy.accuracy.loads import wrench_set_map
    >>> ds = wrench_set_map("aalborg_3ppr", "case2", [0.0, 0, 0], [5.0, 5, 100], [0.0], n=9)
    >>> len([ax for ax in plot_wrench_set_map(ds, 0.0).axes if ax.get_title()])
    4
    """
    d = ds.sel(phi=phi_deg, method="nearest")
    x, y = ds["x"].values, ds["y"].values
    panels = [(x, y, d["dx_hi"].values - d["dx_lo"].values, r"$\delta x$ range [mm]", "mm"),
              (x, y, d["dy_hi"].values - d["dy_lo"].values, r"$\delta y$ range [mm]", "mm"),
              (x, y, d["dphi_hi"].values - d["dphi_lo"].values, r"$\delta\phi$ range [deg]", "deg"),
              (x, y, d["flipping_legs"].values, "legs whose contact flips", "legs")]
    return plot_panels(panels, suptitle=f"Loaded error's range over the process wrenches: {ds.attrs.get('robot', '')}, "
                                        f"phi = {phi_deg:g} deg\n"
                                        f"{ds.attrs.get('wrench_box', '')}", ncols=2, vmin=vmin, vmax=vmax,
                       log=log, limited=[True, True, False, False])
