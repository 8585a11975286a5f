"""Figures of error maps (paper Figs. 9-12): :mod:`pmaccuracy.report.figures`.

Figures are inspected through matplotlib's object model (axes, colour bars,
collections, colour limits) and the saved PNG is read back and checked for
content. Every figure is closed implicitly: they are bare ``Figure`` objects,
never registered with pyplot.
"""

from __future__ import annotations

import io

import matplotlib

matplotlib.use("Agg")

import matplotlib.image as mpimg  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import xarray as xr  # noqa: E402
from matplotlib.collections import PathCollection, QuadMesh  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from pmaccuracy.report import figures  # noqa: E402
from pmaccuracy.model.clearances import ClearanceSet  # noqa: E402
from pmaccuracy.accuracy.maps import error_map  # noqa: E402

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
UNITS = {"dx_max": "mm", "dy_max": "mm", "dp_max": "mm", "dphi_max": "deg"}


@pytest.fixture(scope="module")
def case2_map() -> xr.Dataset:
    return error_map("aalborg_3ppr", "case2", np.radians([0.0, 30.0]), 25)


def _main_axes(fig: Figure) -> list:
    return [ax for ax in fig.axes if not hasattr(ax, "_colorbar")]


def _colorbar_axes(fig: Figure) -> list:
    return [ax for ax in fig.axes if hasattr(ax, "_colorbar")]


def _mesh(ax) -> QuadMesh:
    meshes = [c for c in ax.collections if isinstance(c, QuadMesh)]
    assert len(meshes) == 1
    return meshes[0]


def _render(fig: Figure) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=50)
    return buf.getvalue()


# ----------------------------------------------------------------------------- plot_error_map
def test_four_panels_with_unit_colorbars(case2_map):
    fig = figures.plot_error_map(case2_map, 0.0)
    assert isinstance(fig, Figure)
    main, cbars = _main_axes(fig), _colorbar_axes(fig)
    assert len(main) == 4 and len(cbars) == 4
    labels = [_bar_label(ax) for ax in cbars]
    assert sum("[mm]" in lab for lab in labels) == 3, labels
    assert sum("[deg]" in lab for lab in labels) == 1, labels
    for ax in main:
        assert "mm" in ax.get_xlabel() and "mm" in ax.get_ylabel()
        assert ax.get_title()
    # each panel draws its own variable of the phi = 0 layer with the variable's own range
    for ax, var in zip(main, ("dx_max", "dy_max", "dp_max", "dphi_max")):
        values = case2_map[var].sel(phi=0.0, method="nearest").values
        lo, hi = _mesh(ax).get_clim()
        assert lo <= np.nanmin(values) + 1e-12 and hi >= np.nanmax(values) - 1e-12
        assert UNITS[var] in ax.get_title()
    assert len(_render(fig)) > 1000


def test_selects_requested_orientation(case2_map):
    """phi = 30 deg: the panel shows the phi = 30 layer (its dx range), not phi = 0's."""
    fig = figures.plot_error_map(case2_map, 30.0)
    dx30 = case2_map.dx_max.sel(phi=30.0, method="nearest").values
    lo, hi = _mesh(_main_axes(fig)[0]).get_clim()
    assert lo == pytest.approx(np.nanmin(dx30), rel=1e-9)
    assert hi == pytest.approx(np.nanmax(dx30), rel=1e-9)
    assert "30" in fig.get_suptitle()


def test_constant_fields_do_not_crash():
    """Case 1 at phi = 0 has dy_max and dphi_max constant; zero clearances make every field 0."""
    ds = error_map("aalborg_3ppr", "case1", 0.0, 15)
    fig = figures.plot_error_map(ds, 0.0)
    main = _main_axes(fig)
    lo, hi = _mesh(main[1]).get_clim()  # dy_max: padded range around the constant
    assert lo < float(ds.dy_max.min()) <= float(ds.dy_max.max()) < hi
    _render(fig)
    zero = error_map("aalborg_3ppr", ClearanceSet(name="none"), 0.0, 9)
    assert float(abs(zero.dp_max).max()) == 0.0
    fig = figures.plot_error_map(zero, 0.0)
    for ax in _main_axes(fig):
        lo, hi = _mesh(ax).get_clim()
        assert lo < 0.0 < hi
    _render(fig)


def test_measured_overlay_adds_points(case2_map):
    rng = np.random.default_rng(3)
    n = 7
    measured = {"x": rng.uniform(-20, 20, n), "y": rng.uniform(-20, 20, n),
                "dx": rng.uniform(0.2, 0.5, n), "dy": rng.uniform(0.1, 0.2, n),
                "dp": rng.uniform(0.3, 0.6, n), "dphi_deg": rng.uniform(0.2, 0.4, n)}
    measured["dx"][0] = 0.9  # beyond the map's range: the colour scale must include it
    plain = figures.plot_error_map(case2_map, 0.0)
    fig = figures.plot_error_map(case2_map, 0.0, measured=measured)
    for ax0, ax in zip(_main_axes(plain), _main_axes(fig)):
        before = [c for c in ax0.collections if isinstance(c, PathCollection)]
        after = [c for c in ax.collections if isinstance(c, PathCollection)]
        assert len(after) == len(before) + 1
        np.testing.assert_allclose(after[-1].get_offsets(), np.column_stack([measured["x"], measured["y"]]))
    assert _mesh(_main_axes(fig)[0]).get_clim()[1] >= 0.9
    _render(fig)


def test_scale_multiplies_values(case2_map):
    fig = figures.plot_error_map(case2_map, 0.0, scale=2.0)
    dx = case2_map.dx_max.sel(phi=0.0, method="nearest").values
    lo, hi = _mesh(_main_axes(fig)[0]).get_clim()
    assert lo == pytest.approx(2 * np.nanmin(dx), rel=1e-9) and hi == pytest.approx(2 * np.nanmax(dx), rel=1e-9)


# ----------------------------------------------------------------------------- other figures
def test_plot_layers_common_scale(case2_map):
    fig = figures.plot_layers(case2_map, "dp_max")
    main = _main_axes(fig)
    assert len(main) == 2
    clims = {_mesh(ax).get_clim() for ax in main}
    assert len(clims) == 1
    lo, hi = clims.pop()
    assert lo == pytest.approx(float(case2_map.dp_max.min())) and hi == pytest.approx(float(case2_map.dp_max.max()))
    assert "mm" in _bar_label(_colorbar_axes(fig)[0])


def _panels():
    x, y = np.linspace(0, 1, 6), np.linspace(0, 2, 5)
    X, Y = np.meshgrid(x, y)
    return [(x, y, X + Y, "a", "mm"), (x, y, 10 + 3 * X, "b", "mm"), (x, y, np.full_like(X, 4.0), "c", "deg")]


def test_plot_panels_shared_scale():
    fig = figures.plot_panels(_panels(), suptitle="s", shared_scale=True)
    clims = [_mesh(ax).get_clim() for ax in _main_axes(fig) if ax.get_visible()]
    assert len(clims) == 3
    assert all(c == clims[0] for c in clims)
    assert clims[0] == pytest.approx((0.0, 13.0))  # min and max over all panels


def test_plot_panels_own_scales_and_grid_layout():
    fig = figures.plot_panels(_panels(), suptitle="s", shared_scale=False, ncols=2)
    visible = [ax for ax in _main_axes(fig) if ax.get_visible()]
    assert len(visible) == 3 and len(_main_axes(fig)) == 4  # 2 x 2 with the spare one hidden
    clims = [_mesh(ax).get_clim() for ax in visible]
    assert clims[0] == pytest.approx((0.0, 3.0))
    assert clims[1] == pytest.approx((10.0, 13.0))
    assert clims[2][0] < 4.0 < clims[2][1]  # constant panel gets a band
    _render(fig)


# ----------------------------------------------------------------------------- saving
def test_save_writes_valid_nontrivial_png(case2_map, tmp_path):
    path = figures.save(figures.plot_error_map(case2_map, 30.0), tmp_path / "sub" / "map.png", dpi=40)
    assert path == tmp_path / "sub" / "map.png"
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE
    image = mpimg.imread(path)
    assert image.ndim == 3 and image.shape[0] > 100 and image.shape[1] > 100
    pixels = image[..., :3].reshape(-1, 3)
    assert pixels.std(axis=0).max() > 0.05  # not a blank image
    assert len(np.unique(np.round(pixels * 255).astype(np.uint8), axis=0)) > 50  # many colours (viridis)


# ----------------------------------------------------------------------------- what a reader sees
# Layout checks on the drawn figures (after a draw, in display pixels): colour bars as high as their maps,
# no text outside the figure or over another text, legends outside the data axes, labels naming what is
# drawn (factor and units), workspace figures zoomed to the workspace with the whole robot beside,
# figures no wider than the report's column. Each check fails on the defect it names (see the negative cases).
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.text import Text  # noqa: E402

from pmaccuracy import experiment  # noqa: E402
from pmaccuracy.report import experiment_plots  # noqa: E402
from pmaccuracy.model.manipulator import Manipulator  # noqa: E402
from pmaccuracy.kinematics.workspace import constant_orientation_workspace, workspace_figure  # noqa: E402


def _drawn(fig: Figure) -> Figure:
    if fig.canvas is None or not isinstance(fig.canvas, FigureCanvasAgg):
        FigureCanvasAgg(fig)
    fig.canvas.draw()
    return fig


def _texts(fig: Figure) -> list[Text]:
    """Visible, non-empty texts the figure draws (titles, labels, tick labels, legends, colour-bar labels);
    labels of ticks outside an axis's view interval exist but are not drawn, so they are left out."""
    hidden = set()
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            lo, hi = sorted(axis.get_view_interval())
            tol = 1e-9 * max(abs(lo), abs(hi), 1.0)
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                if not lo - tol <= tick.get_loc() <= hi + tol:
                    hidden |= {id(tick.label1), id(tick.label2)}
    out = []
    for t in fig.findobj(Text):
        if id(t) in hidden or not t.get_visible() or not t.get_text().strip():
            continue
        ax = t.axes
        if ax is not None and not ax.get_visible():
            continue
        out.append(t)
    return out


def _boxes(fig: Figure, texts: list[Text]):
    renderer = fig.canvas.get_renderer()
    return [t.get_window_extent(renderer) for t in texts]


def texts_outside_figure(fig: Figure, tol: float = 1.0) -> list[str]:
    fb = fig.bbox
    return [t.get_text() for t, b in zip(_texts(fig), _boxes(fig, _texts(fig)))
            if b.x0 < fb.x0 - tol or b.y0 < fb.y0 - tol or b.x1 > fb.x1 + tol or b.y1 > fb.y1 + tol]


def overlapping_texts(fig: Figure, tol: float = 1.0) -> list[tuple[str, str]]:
    texts = _texts(fig)
    boxes = _boxes(fig, texts)
    pairs = []
    for i in range(len(texts)):
        for j in range(i + 1, len(texts)):
            a, b = boxes[i], boxes[j]
            if min(a.x1, b.x1) - max(a.x0, b.x0) > tol and min(a.y1, b.y1) - max(a.y0, b.y0) > tol:
                pairs.append((texts[i].get_text(), texts[j].get_text()))
    return pairs


def _data_axes(fig: Figure) -> list:
    return [ax for ax in fig.axes if ax.get_visible() and not hasattr(ax, "_colorbar")]


def legends_over_data(fig: Figure) -> list[str]:
    """Legends whose box overlaps the box of a data axes (colour bars excluded)."""
    renderer = fig.canvas.get_renderer()
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    bad = []
    for leg in legends:
        lb = leg.get_window_extent(renderer)
        for ax in _data_axes(fig):
            ab = ax.get_window_extent(renderer)
            if min(lb.x1, ab.x1) - max(lb.x0, ab.x0) > 1 and min(lb.y1, ab.y1) - max(lb.y0, ab.y0) > 1:
                bad.append(" / ".join(t.get_text() for t in leg.get_texts()))
    return bad


from matplotlib.transforms import Affine2D  # noqa: E402

_swap = Affine2D([[0, 1, 0], [1, 0, 0], [0, 0, 1]])


def _bar_label(cax) -> str:
    """A colour bar's label, on its long side (y of a vertical bar, x of a horizontal one)."""
    return cax.get_xlabel() if cax._colorbar.orientation == "horizontal" else cax.get_ylabel()


def colourbar_mismatches(fig: Figure, tol_px: float = 1.0) -> list[str]:
    """Colour bars whose ends (outline, extension triangles included) differ from their map's sides (the
    axes holding the mappable): bottom and top of a vertical bar, left and right of a horizontal one."""
    renderer = fig.canvas.get_renderer()
    bad = []
    for cax in [ax for ax in fig.axes if hasattr(ax, "_colorbar")]:
        mappable = cax._colorbar.mappable
        ax = mappable.axes
        a, c = ax.get_window_extent(renderer), cax._colorbar.outline.get_window_extent(renderer)
        if cax._colorbar.orientation == "horizontal":
            a, c = a.transformed(_swap), c.transformed(_swap)
        if abs(a.y0 - c.y0) > tol_px or abs(a.y1 - c.y1) > tol_px:
            bad.append(f"{_bar_label(cax)!r}: bar {c.y0:.0f}-{c.y1:.0f} px, map {a.y0:.0f}-{a.y1:.0f} px")
    return bad


def assert_readable(fig: Figure, *, max_width_in: float = figures.REPORT_WIDTH_IN, min_px: float = 8.0):
    """The generic checks, on the figure as written (text raised to the floor, as ``save_figure`` does): drawn
    at most the report's width, every text at least ``min_px`` high when the figure is shown 400 px wide and
    inside the figure, no two texts on top of each other, legends off the data, colour bars matched to their
    maps."""
    figures.legible(_drawn(fig))
    _drawn(fig)
    assert fig.get_figwidth() <= max_width_in + 1e-9, fig.get_figwidth()
    px = 400 / (72 * fig.get_figwidth())
    small = [(t.get_text(), t.get_fontsize() * px) for t in _texts(fig) if t.get_fontsize() * px < min_px - 1e-9]
    assert not small, small
    assert not texts_outside_figure(fig), texts_outside_figure(fig)
    assert not overlapping_texts(fig), overlapping_texts(fig)
    assert not legends_over_data(fig), legends_over_data(fig)
    assert not colourbar_mismatches(fig), colourbar_mismatches(fig)


def test_layout_checks_catch_the_defects_they_name():
    """Each check on a figure built with its defect: a tall colour bar, a clipped title, a legend over
    the data, two labels on top of each other."""
    fig = Figure(figsize=(6, 4))
    ax = fig.add_axes((0.1, 0.3, 0.6, 0.3))
    cax = fig.add_axes((0.75, 0.1, 0.03, 0.8))                      # twice the map's height
    mesh = ax.pcolormesh(np.arange(4.0).reshape(2, 2))
    fig.colorbar(mesh, cax=cax)
    ax.scatter([0.5], [0.5], label="points")
    ax.legend(loc="center")
    ax.set_title("a title far too long to fit in this figure " * 4)
    ax.text(0.5, 0.5, "one", transform=ax.transAxes)
    ax.text(0.5, 0.5, "two", transform=ax.transAxes)
    _drawn(fig)
    assert colourbar_mismatches(fig)
    assert texts_outside_figure(fig)
    assert legends_over_data(fig) == ["points"]
    assert ("one", "two") in overlapping_texts(fig)


@pytest.fixture(scope="module")
def rrr_map() -> xr.Dataset:
    return error_map("symmetric_3rrr", "rrr_typical", np.radians([0.0]), 61)


def test_map_figures_pass_a_readers_look(case2_map, rrr_map):
    rng = np.random.default_rng(0)
    measured = {"x": rng.uniform(-10, 40, 12), "y": rng.uniform(-14, 10, 12), "dx": rng.uniform(0.5, 0.7, 12),
                "dy": rng.uniform(0.2, 0.3, 12), "dp": rng.uniform(0.5, 0.7, 12), "dphi_deg": rng.uniform(0.6, 0.8, 12)}
    for fig in (figures.plot_error_map(case2_map, 0.0), figures.plot_error_map(case2_map, 30.0),
                figures.plot_error_map(case2_map, 30.0, measured=measured, scale=2.0),
                figures.plot_error_map(rrr_map, 0.0), figures.plot_layers(case2_map, "dp_max"),
                figures.plot_panels(_panels(), suptitle="s", ncols=2)):
        assert_readable(fig)


def test_colourbar_labels_name_the_factor_and_units(case2_map):
    fig = figures.plot_error_map(case2_map, 30.0, scale=2.0)
    labels = [_bar_label(ax) for ax in _colorbar_axes(fig)]
    assert len(labels) == 4 and all(lab.startswith("2 x ") for lab in labels), labels
    assert [lab.endswith("[mm]") for lab in labels] == [True, True, True, False] and labels[3].endswith("[deg]")
    assert all(ax.get_title().startswith("2 x ") for ax in _main_axes(fig))


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def test_constant_field_named_in_title_not_drawn_over_the_map():
    ds = error_map("aalborg_3ppr", "case1", 0.0, 15)
    fig = figures.plot_error_map(ds, 0.0)
    dphi = float(ds.dphi_max.max())
    title = _main_axes(fig)[3].get_title()
    assert "constant" in title and f"{dphi:.4g}" in title
    # no box over the data: the only texts in the maps are the contour labels (numbers)
    assert all(_is_number(t.get_text()) for ax in _main_axes(fig) for t in ax.texts)
    assert not _main_axes(fig)[3].texts                              # nothing drawn on the constant field


def test_singular_edges_clip_the_colour_scale_at_the_stated_percentile(rrr_map, case2_map):
    fig = figures.plot_error_map(rrr_map, 0.0)
    for ax, cax, var in zip(_main_axes(fig), _colorbar_axes(fig), ("dx_max", "dy_max", "dp_max", "dphi_max")):
        values = rrr_map[var].sel(phi=0.0).values
        values = values[np.isfinite(values)]
        p95 = np.percentile(values, 95)                          # the near-singular top 5 % spans most of the range
        assert values.max() - p95 > p95 - values.min()
        lo, hi = _mesh(ax).get_clim()
        assert hi == pytest.approx(p95, rel=1e-12) and lo == pytest.approx(values.min(), rel=1e-12)
        assert cax._colorbar.extend == "max"
        assert "95th" in _bar_label(cax) and f"{values.max():.3g}" in _bar_label(cax)
    for cax in _colorbar_axes(figures.plot_error_map(case2_map, 0.0)):  # smooth maps are never clipped
        assert cax._colorbar.extend == "neither" and "pct" not in _bar_label(cax)


def _comparison():
    parts = [experiment.simulate_experiment("aalborg_3ppr", "case2", np.radians(p), 5, seed=k)
             for k, p in enumerate((0.0, 30.0))]
    m = experiment.Measurements(
        points=np.concatenate([[f"{k}.{lbl}" for lbl in mm.points] for k, mm in enumerate(parts)]),
        nominal=np.concatenate([mm.nominal for mm in parts]), readings=np.concatenate([mm.readings for mm in parts]))
    return experiment.compare("aalborg_3ppr", "case2", m)


def test_experiment_figures_show_and_name_every_orientation():
    comparison = _comparison()
    n0 = len(comparison.by_orientation()[0.0].measurements)
    acc = experiment_plots.plot_accuracy(comparison)
    assert_readable(acc)
    assert "0, 30 deg" in acc.get_suptitle()
    ax_p = acc.axes[0]
    colours = {tuple(p.get_facecolor()) for p in ax_p.patches}
    assert len(colours) == 2 and len(ax_p.patches) == len(comparison.measurements)
    heights = sorted(p.get_height() for p in ax_p.patches)           # the bars are the measured dp, Eq. 23d
    assert heights == pytest.approx(sorted(comparison.measured.dp))
    reg = experiment_plots.plot_regression(comparison, 2.0)
    assert_readable(reg)
    assert "0, 30 deg" in reg.get_suptitle()
    for ax in reg.axes:
        scatters = [c for c in ax.collections if isinstance(c, PathCollection)]
        assert [len(c.get_offsets()) for c in scatters] == [n0, len(comparison.measurements) - n0]
    box = experiment_plots.plot_boxplots({f"phi = {p:g} deg": c.measured for p, c in comparison.by_orientation().items()})
    assert_readable(box)


def test_workspace_figure_zooms_to_the_workspace_with_the_whole_robot_beside():
    robot = Manipulator.preset("aalborg_3ppr")
    phis = (0.0, 30.0, -30.0)
    fig = _drawn(workspace_figure(robot, phis))
    assert_readable(fig)
    zoom, full = _data_axes(fig)
    boxes = [constant_orientation_workspace(robot, np.radians(p)).bounds for p in phis]
    x0, x1 = min(b[0][0] for b in boxes), max(b[0][1] for b in boxes)
    y0, y1 = min(b[1][0] for b in boxes), max(b[1][1] for b in boxes)
    (ax0, ax1), (ay0, ay1) = zoom.get_xlim(), zoom.get_ylim()
    assert ax0 < x0 and ax1 > x1 and ay0 < y0 and ay1 > y1             # every workspace inside
    assert (ax1 - ax0) * (ay1 - ay0) < 2.0 * (x1 - x0) * (y1 - y0)      # and it fills the frame
    # the overview holds the whole robot: every leg's base and the actuated rails
    bases = np.array([c.base for c in robot.chains])
    (fx0, fx1), (fy0, fy1) = full.get_xlim(), full.get_ylim()
    assert np.all((bases[:, 0] > fx0) & (bases[:, 0] < fx1) & (bases[:, 1] > fy0) & (bases[:, 1] < fy1))
    assert (fx1 - fx0) > 4 * (ax1 - ax0)


def test_workspace_comparison_has_a_common_scale_for_robots_and_for_workspaces():
    from pmaccuracy.kinematics.workspace import comparison_figure

    robots = [Manipulator.preset(r) for r in ("aalborg_3ppr", "symmetric_3rrr")]
    fig = comparison_figure(robots)
    assert_readable(fig, max_width_in=3.3 * 5 + 0.4)                  # sized for five robots side by side
    axes = _data_axes(fig)
    assert len(axes) == 4
    spans = [(np.ptp(ax.get_xlim()), np.ptp(ax.get_ylim())) for ax in axes]
    assert spans[0] == pytest.approx(spans[1]) and spans[2] == pytest.approx(spans[3])   # per row
    ws = constant_orientation_workspace(robots[1], 0.0)                # the largest workspace fits the zoom row
    (x0, x1), (y0, y1) = ws.bounds
    assert spans[2][0] >= x1 - x0 and spans[2][1] >= y1 - y0 and spans[2][0] < spans[0][0]


def test_long_panel_titles_and_suptitles_wrap_inside_the_figure():
    """A constant panel's note lengthens its title beyond its column and a long suptitle beyond the figure:
    both are wrapped, nothing leaves the figure or lands on another text."""
    x = np.linspace(-25, 25, 11)
    X, Y = np.meshgrid(x, x)
    panels = [(x, x, X, "dx offset at phi = 0 deg", "mm"), (x, x, np.full_like(X, -1.747), "dy offset at phi = 0 deg", "mm"),
              (x, x, Y, "dphi offset at phi = 0 deg", "deg")]
    fig = figures.plot_panels(panels, suptitle="Pose offset due to the assembly errors of Table 2 (phi = 0), " * 2)
    assert_readable(fig)
    assert "\n" in fig.get_suptitle() and any("\n" in ax.get_title() for ax in _main_axes(fig))


@pytest.mark.parametrize("name, clear", [("aalborg_3ppr", "case2"), ("symmetric_3rrr", "rrr_typical")])
def test_load_and_preload_figures_pass_a_readers_look(name, clear):
    from pmaccuracy.accuracy.loads import Load
    from pmaccuracy.kinematics.workspace import home_pose
    from pmaccuracy.report.load_figures import plot_load, plot_preload

    robot = Manipulator.preset(name)
    home = home_pose(robot)
    assert_readable(plot_load(robot, clear, home, Load(fy=10.0)))
    assert_readable(plot_preload(robot, clear, home, np.array([0.0, 0.0, 0.0]), np.array([5.0, 5.0, 100.0])))
