"""Figures a reader can trust at a phone's width: legends in the shapes drawn, singular places drawn on the
maps, text of at least 8 px when a figure is shown 400 px wide."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgba
from matplotlib.contour import ContourSet
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from pmaccuracy.accuracy.maps import error_map
from pmaccuracy.kinematics import inverse_kinematics, singularity
from pmaccuracy.kinematics.workspace import plot_workspaces, workspace_figure
from pmaccuracy.model.manipulator import Manipulator
from pmaccuracy.report import figures
from pmaccuracy.report.document import Document, display_width


def _joint_markers(ax) -> tuple[set, set]:
    """(marker, face colour) of the joint symbols drawn with data, and of the legend's joint entries."""
    drawn, legend = set(), set()
    for line in ax.get_lines():
        if line.get_marker() not in ("o", "s"):
            continue
        key = (line.get_marker(), to_rgba(line.get_markerfacecolor()))
        (drawn if len(line.get_xdata()) else legend).add(key)
    handles, labels = ax.get_legend_handles_labels()
    named = {(h.get_marker(), to_rgba(h.get_markerfacecolor())) for h, lab in zip(handles, labels)
             if isinstance(h, Line2D) and "joint" in lab}
    return drawn, named


@pytest.mark.parametrize("name", ["symmetric_3prr", "symmetric_3rrr", "aalborg_3ppr", "symmetric_3rpr"])
def test_workspace_legend_shows_each_joint_symbol_in_the_shape_drawn(name):
    robot = Manipulator.preset(name)
    ax = plot_workspaces(robot)
    drawn, named = _joint_markers(ax)
    assert drawn and drawn == named, (drawn, named)
    red = to_rgba("tab:red")
    actuated_kind = {c.actuated.kind for c in robot.chains}
    assert {m for m, face in drawn if face == red} == {"o" if k == "R" else "s" for k in actuated_kind}
    assert sorted(t.get_text() for t in ax.texts) == ["1", "2", "3"]             # legs numbered
    labels = ax.get_legend_handles_labels()[1]
    assert any("platform centre" in lab for lab in labels) and "leg number" in labels


def test_workspace_figure_keeps_every_leg_number_inside_its_frame():
    fig = workspace_figure(Manipulator.preset("symmetric_3prr"))
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    full = [ax for ax in fig.axes if ax.texts][0]
    frame = full.get_window_extent(renderer)
    for t in full.texts:
        b = t.get_window_extent(renderer)
        assert frame.x0 <= b.x0 and b.x1 <= frame.x1 and frame.y0 <= b.y0 and b.y1 <= frame.y1, t.get_text()


BANDED = """architecture = "3-PRR"
name = "banded_3prr"
[[legs]]
guide_point = [-173.20508075688772, -100.0]
guide_deg = 300.0
platform = [-43.30127018922193, -25.0]
distal = 180.0
s_range = [-300.0, 100.0]
working_mode = 1
[[legs]]
guide_point = [173.20508075688772, -100.0]
guide_deg = 60.0
platform = [43.30127018922193, -25.0]
distal = 180.0
s_range = [-300.0, 100.0]
working_mode = 1
[[legs]]
guide_point = [0.0, 200.0]
guide_deg = 180.0
platform = [0.0, 50.0]
distal = 180.0
s_range = [-300.0, 100.0]
working_mode = -1
"""


@pytest.fixture(scope="module")
def banded(tmp_path_factory):
    """The symmetric 3-PRR with longer slides and leg 3 in the other working mode: at phi = -15 deg a band
    of its grid is near the parallel singularity."""
    path = tmp_path_factory.mktemp("robot") / "banded_3prr.toml"
    path.write_text(BANDED)
    robot = Manipulator.from_toml(path)
    return robot, error_map(robot, "prr_typical", np.radians([-15.0]), 41)


def _zero_lines(ax) -> list[np.ndarray]:
    out = []
    for c in ax.collections:
        if isinstance(c, ContourSet) and list(c.levels) == [0.0]:
            out += [p.vertices for p in c.get_paths() if len(p.vertices)]
    return out


def test_singular_band_of_a_3prr_map_is_drawn_and_named(banded):
    robot, ds = banded
    x, y = ds.x.values, ds.y.values
    X, Y = np.meshgrid(x, y)
    poses = np.stack([X, Y, np.full_like(X, np.radians(-15.0))], axis=-1)
    inside = inverse_kinematics(robot, poses).within_limits
    blank = inside & np.isnan(ds["dp_max"].sel(phi=-15.0).values)
    assert blank.sum() > 20                                   # the map itself leaves a band blank
    shape = figures.map_shape(robot, -15.0, x, y)
    np.testing.assert_array_equal(shape.near_singular, blank)  # the hatching covers exactly those points
    fig = figures.plot_error_map(ds, -15.0)
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert any("near-singular" in t and "left blank" in t for t in labels), labels
    assert any("det A = 0" in t for t in labels), labels
    maps = [ax for ax in fig.axes if not hasattr(ax, "_colorbar")]
    assert len(maps) == 4
    det_all = np.abs(singularity(robot, poses).det[inside])
    for ax in maps:
        lines = _zero_lines(ax)
        assert lines, ax.get_title()
        pts = np.vstack(lines)
        on = np.column_stack([pts, np.full(len(pts), np.radians(-15.0))])
        # independent check: det A recomputed on the drawn line is ~0 against its range over the workspace
        assert np.max(np.abs(singularity(robot, on).det)) < 0.02 * det_all.max()
        assert any("////" in list(c.hatches) for c in ax.collections if isinstance(c, ContourSet) and c.filled)


def test_a_map_without_singular_points_names_none(case2_like):
    fig = figures.plot_error_map(case2_like, 0.0)
    assert not fig.legends                                      # nothing to explain
    for ax in (a for a in fig.axes if not hasattr(a, "_colorbar")):
        assert not _zero_lines(ax)
        assert any(p.get_label() == "workspace boundary" for p in ax.patches)


@pytest.fixture(scope="module")
def case2_like():
    return error_map("aalborg_3ppr", "case2", np.radians([0.0]), 31)


def test_map_field_stops_at_the_exact_workspace_boundary(case2_like):
    fig = figures.plot_error_map(case2_like, 0.0)
    ax = [a for a in fig.axes if not hasattr(a, "_colorbar")][0]
    mesh = ax.collections[0]
    clip = mesh.get_clip_path()
    assert clip is not None
    from pmaccuracy.kinematics.workspace import constant_orientation_workspace

    ws = constant_orientation_workspace(Manipulator.preset("aalborg_3ppr"), 0.0)
    verts = clip.get_fully_transformed_path().vertices
    outline = ax.transData.transform(np.vstack(ws.loops))
    assert np.allclose(np.sort(verts[:len(outline)], axis=0), np.sort(outline, axis=0))


def test_text_floor_follows_the_figure_width():
    assert figures.min_font_pt(7.5) == pytest.approx(8 * 72 * 7.5 / 400)
    fig = Figure(figsize=(10.0, 4.0))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.plot([0, 1], [0, 1])
    ax.set_title("t", fontsize=6)
    ax.tick_params(labelsize=6)
    fig.canvas.draw()
    assert figures.smallest_text_px(fig) == pytest.approx(6 * 400 / 720)        # 3.3 px: unreadable
    figures.legible(fig)
    fig.canvas.draw()
    assert figures.smallest_text_px(fig) >= 8 - 1e-9


def test_report_maps_and_workspace_are_readable_at_400_px_as_built(case2_like, banded):
    """Designed at the floor: no text needs raising (so the layout checked is the one written)."""
    for fig in (figures.plot_error_map(case2_like, 0.0), figures.plot_error_map(banded[1], -15.0),
                workspace_figure(Manipulator.preset("symmetric_3rrr"))):
        if fig.canvas is None or not isinstance(fig.canvas, FigureCanvasAgg):
            FigureCanvasAgg(fig)
        fig.canvas.draw()
        assert fig.get_figwidth() <= figures.REPORT_WIDTH_IN + 1e-9
        assert figures.smallest_text_px(fig, 400) >= 8 - 1e-9


def test_html_shows_a_png_at_100_px_per_inch(tmp_path, case2_like):
    fig = figures.plot_error_map(case2_like, 0.0)
    path = figures.save(fig, tmp_path / "m.png", dpi=150)
    assert display_width(path) == round(fig.get_figwidth() * 100)
    doc = Document("t")
    doc.figure(path, "map")
    assert f"width='{round(fig.get_figwidth() * 100)}'" in doc.to_html()


def _clip_matches_workspace(ax, robot, phi_deg: float) -> bool:
    """Whether the field of ``ax`` is clipped to the exact workspace outline of ``robot`` at ``phi_deg``."""
    from pmaccuracy.kinematics.workspace import constant_orientation_workspace

    clip = ax.collections[0].get_clip_path()
    if clip is None:
        return False
    verts = clip.get_fully_transformed_path().vertices
    outline = ax.transData.transform(np.vstack(constant_orientation_workspace(robot, np.radians(phi_deg)).loops))
    return len(verts) == len(outline) and np.allclose(np.sort(verts, axis=0), np.sort(outline, axis=0))


def test_plot_panels_with_shapes_clips_each_panel_to_its_own_workspace():
    robot, other = Manipulator.preset("aalborg_3ppr"), Manipulator.preset("symmetric_3ppr")
    panels, shapes = [], []
    for rb, phi in ((robot, 0.0), (other, 30.0)):
        layer = error_map(rb, "case2", np.radians([phi]), 21).isel(phi=0)
        panels.append((layer.x.values, layer.y.values, layer.dp_max.values, rb.name, "mm"))
        shapes.append((rb, phi))
    fig = figures.plot_panels(panels + [panels[0]], suptitle="s", shapes=shapes + [None])
    maps = [a for a in fig.axes if not hasattr(a, "_colorbar") and a.get_visible()]
    assert len(maps) == 3
    assert _clip_matches_workspace(maps[0], robot, 0.0)
    assert _clip_matches_workspace(maps[1], other, 30.0)
    assert not _clip_matches_workspace(maps[1], robot, 0.0)       # the check tells the two workspaces apart
    assert not _clip_matches_workspace(maps[2], robot, 0.0)       # no shape: grid cells, no outline
    assert [p.get_label() for p in maps[1].patches] == ["workspace boundary"]
    assert not maps[2].patches
    with pytest.raises(ValueError):
        figures.plot_panels(panels, suptitle="s", shapes=shapes[:1])


def test_plot_panels_with_shapes_draws_and_names_the_singular_band(banded):
    robot, ds = banded
    layer = ds.isel(phi=0)
    fig = figures.plot_panels([(layer.x.values, layer.y.values, layer.dp_max.values, "dp_max", "mm")],
                              suptitle="s", shapes=[(robot, -15.0)])
    labels = [t.get_text().replace("\n", " ") for t in fig.legends[0].get_texts()]
    assert any("near-singular" in t and "left blank" in t for t in labels), labels
    assert any("det A = 0" in t for t in labels), labels
    ax = [a for a in fig.axes if not hasattr(a, "_colorbar")][0]
    assert _zero_lines(ax)
    assert _clip_matches_workspace(ax, robot, -15.0)
    FigureCanvasAgg(fig) if not isinstance(fig.canvas, FigureCanvasAgg) else None
    fig.canvas.draw()
    legend = fig.legends[0].get_window_extent()
    assert legend.y1 <= fig.bbox.y1 and legend.y0 >= ax.get_window_extent().y1   # between title and panel
    assert figures.smallest_text_px(fig, 400) >= 8 - 1e-9


def test_a_region_map_is_not_widened_past_its_region():
    """Blank cells inside the joint ranges (outside a map's region) stay blank: only cells outside the
    workspace are filled so that the field reaches the exact boundary."""
    robot = Manipulator.preset("symmetric_3prr")
    layer = error_map(robot, "prr_typical", np.radians([0.0]), 21).isel(phi=0)
    x, y = layer.x.values, layer.y.values
    Z = layer.dp_max.values.copy()
    Z[:, : len(x) // 2] = np.nan                                   # a region: the right half only
    shape = figures.map_shape(robot, 0.0, x, y)
    inside = np.isfinite(shape.det)
    assert (inside & np.isnan(Z)).sum() > 20 and (~inside).sum() > 20
    widened = figures._widen(Z, shape.outline(Z)[1])
    assert np.isnan(widened[inside & np.isnan(Z)]).all()
    assert (np.isfinite(widened) & ~inside).sum() > 5              # the outside rim is still filled


def test_plot_layers_clips_each_orientation_to_its_workspace():
    robot = Manipulator.preset("symmetric_3prr")
    ds = error_map(robot, "prr_typical", np.radians([0.0, 20.0]), 15)
    maps = [a for a in figures.plot_layers(ds, "dp_max").axes if not hasattr(a, "_colorbar")]
    assert len(maps) == 2
    assert _clip_matches_workspace(maps[0], robot, 0.0) and _clip_matches_workspace(maps[1], robot, 20.0)
    assert not _clip_matches_workspace(maps[1], robot, 0.0)


def _shows_whole_outline(ax, robot, phi_deg: float) -> bool:
    from pmaccuracy.kinematics.workspace import constant_orientation_workspace

    pts = np.vstack(constant_orientation_workspace(robot, np.radians(phi_deg)).loops)
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    return bool((pts[:, 0] >= x0).all() and (pts[:, 0] <= x1).all() and (pts[:, 1] >= y0).all()
                and (pts[:, 1] <= y1).all())


def test_shaped_panels_show_the_whole_workspace_not_only_the_grid_points_with_a_value():
    """A 3-PRR's workspace reaches past its grid points with a value (curved sides, a near-singular blank
    row): the axes hold all of its exact outline."""
    robot = Manipulator.preset("symmetric_3prr")
    ds = error_map(robot, "prr_typical", np.radians([0.0]), 21)
    for fig in (figures.plot_layers(ds, "dp_max"), figures.plot_error_map(ds, 0.0)):
        for ax in (a for a in fig.axes if not hasattr(a, "_colorbar")):
            assert _shows_whole_outline(ax, robot, 0.0), ax.get_title()
