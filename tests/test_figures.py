"""Figures of error maps (paper Figs. 9-12): :mod:`pmaccuracy.figures`.

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

from pmaccuracy import figures  # noqa: E402
from pmaccuracy.clearances import ClearanceSet  # noqa: E402
from pmaccuracy.maps import error_map  # noqa: E402

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
    labels = [ax._colorbar.ax.get_ylabel() for ax in cbars]
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
    assert "mm" in _colorbar_axes(fig)[0].get_ylabel()


def _panels():
    x, y = np.linspace(0, 1, 6), np.linspace(0, 2, 5)
    X, Y = np.meshgrid(x, y)
    return [(x, y, X + Y, "a", "mm"), (x, y, 10 + 3 * X, "b", "mm"), (x, y, np.full_like(X, 4.0), "c", "deg")]


def test_plot_panels_shared_scale():
    fig = figures.plot_panels(_panels(), suptitle="s", shared_scale=True)
    clims = [_mesh(ax).get_clim() for ax in _main_axes(fig)]
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
