"""Figures and the interactive view of a 3D workspace: written, one panel per slice, text legible at 400 px
and apart; the HTML view is self-contained (no network), parses, and embeds the points it says it shows."""

from __future__ import annotations

import json
import math
from html.parser import HTMLParser
from itertools import combinations

import numpy as np
import pytest
from matplotlib.axes import Axes
from mpl_toolkits.mplot3d import Axes3D
from test_calibration_figures import SLACK_PX, _overlap, drawn_text_boxes

from pmaccuracy._savefig import MIN_TEXT_PX, NARROW_DISPLAY_PX, smallest_text_px
from pmaccuracy.errors import ConfigError, EmptyWorkspaceError
from pmaccuracy.kinematics.workspace3d import grid_workspace
from pmaccuracy.report.view3d_html import view3d_html, write_view3d_page
from pmaccuracy.report.workspace3d_figures import (save_slices_figure, save_view3d_figure, slices_figure,
                                                   view3d_figure)

C1, C2, R = np.array([0.0, 0.0, 0.0]), np.array([60.0, 10.0, 0.0]), 50.0


def _lens(p):
    return (np.sum((p - C1) ** 2, -1) <= R * R) & (np.sum((p - C2) ** 2, -1) <= R * R)


@pytest.fixture(scope="module")
def lens():
    return grid_workspace(_lens, [[5, 55], [-45, 55], [-50, 50]], 32)


def text_faults(fig) -> list[str]:
    """Texts outside the figure or overlapping each other (each drawn text's box, one draw)."""
    boxes = drawn_text_boxes(fig)
    w, h = fig.bbox.width, fig.bbox.height
    faults = [f"outside: {t.get_text()!r}" for t, b in boxes
              if b.x0 < -SLACK_PX or b.y0 < -SLACK_PX or b.x1 > w + SLACK_PX or b.y1 > h + SLACK_PX]
    faults += [f"overlap: {s.get_text()!r} / {t.get_text()!r}" for (s, a), (t, b) in combinations(boxes, 2)
               if _overlap(a, b) > SLACK_PX]
    return faults


def test_slices_figure_has_one_panel_per_value_titled_with_its_layer(lens, tmp_path):
    values = [-30, -15, 0, 15, 30]
    fig = slices_figure(lens, values, title="lens")
    panels = [ax for ax in fig.axes if isinstance(ax, Axes)]
    assert len(panels) == 5
    for ax, v in zip(panels, values):
        layer = lens.slice_value(2, v)
        assert ax.get_title() == f"z = {layer:.4g} mm"
        assert ax.get_xlabel() == "x [mm]" and ax.get_ylabel() == "y [mm]"
        assert ax.get_aspect() == 1.0
    fig.canvas.draw()
    assert smallest_text_px(fig, NARROW_DISPLAY_PX) >= MIN_TEXT_PX - 1e-9        # as built, before saving
    assert not text_faults(fig), text_faults(fig)
    path = save_slices_figure(lens, tmp_path / "slices.png", values, title="lens")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_slices_figure_draws_the_region_and_says_when_a_layer_is_empty(lens):
    fig = slices_figure(lens, [0.0, 48.0])
    full, empty = [ax for ax in fig.axes]
    assert full.collections and not empty.collections                # filled region only where there is one
    assert [t.get_text() for t in empty.texts] == ["empty"]
    # the boundary dots drawn in the z = 0 layer lie on the lens's outline in that plane
    x, y = full.lines[0].get_data()
    z = lens.slice_value(2, 0.0)
    f = np.maximum(np.sqrt(x ** 2 + y ** 2 + z ** 2) - R, np.sqrt((x - 60) ** 2 + (y - 10) ** 2 + z ** 2) - R)
    assert len(x) > 20 and np.abs(f).max() < 0.1
    with pytest.raises(ConfigError):
        slices_figure(lens, [500.0])


def test_view3d_figure_is_written_and_legible(lens, tmp_path):
    fig = view3d_figure(lens, title="lens")
    assert sum(isinstance(ax, Axes3D) for ax in fig.axes) == 1 and len(fig.axes) == 2   # the view, its colour bar
    view = [ax for ax in fig.axes if isinstance(ax, Axes3D)][0]
    assert view.get_xlabel() == "x [mm]" and view.get_zlabel() == "z [mm]"
    shown = view.collections[0].get_offsets()
    assert len(shown) == len(lens.boundary_points)
    fig.canvas.draw()
    assert smallest_text_px(fig, NARROW_DISPLAY_PX) >= MIN_TEXT_PX - 1e-9
    assert not text_faults(fig), text_faults(fig)
    assert any(f"{len(lens.boundary_points)} of {len(lens.boundary_points)} boundary points" in t.get_text()
               for t in fig.texts)
    path = save_view3d_figure(lens, tmp_path / "view.png", title="lens")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    small = view3d_figure(lens, title="lens", max_points=300)
    assert any(f"300 of {len(lens.boundary_points)}" in t.get_text() for t in small.texts)


def test_empty_workspace_has_no_3d_view():
    ws = grid_workspace(lambda p: np.zeros(p.shape[:-1], bool), [[0, 1]] * 3, 6)
    with pytest.raises(EmptyWorkspaceError):
        view3d_figure(ws)
    with pytest.raises(EmptyWorkspaceError):
        view3d_html(ws, title="t")


class _Tags(HTMLParser):
    def __init__(self):
        super().__init__()
        self.open, self.starts, self.scripts, self.data = [], [], [], {}
        self._in = None

    def handle_starttag(self, tag, attrs):
        self.starts.append((tag, dict(attrs)))
        if tag not in ("meta", "br", "img", "input", "link"):
            self.open.append(tag)
        if tag == "script":
            self._in = dict(attrs)
            self.scripts.append((dict(attrs), ""))

    def handle_endtag(self, tag):
        assert self.open and self.open[-1] == tag, (self.open[-3:], tag)
        self.open.pop()
        self._in = None

    def handle_data(self, data):
        if self._in is not None:
            attrs, text = self.scripts[-1]
            self.scripts[-1] = (attrs, text + data)


def _parse(text: str) -> _Tags:
    p = _Tags()
    p.feed(text)
    p.close()
    assert not p.open, p.open                                     # every element closed, in order
    return p


@pytest.mark.parametrize("max_points", [None, 500])
def test_html_fragment_is_self_contained_and_embeds_the_points(lens, max_points):
    segments = np.array([[[30, 5, -40], [30, 5, 40]], [[10, -30, 0], [50, 40, 0]]], float)
    kw = {} if max_points is None else {"max_points": max_points}
    text = view3d_html(lens, title="Lens <two balls>", robot_segments=segments, **kw)
    assert "http://" not in text and "https://" not in text and "//cdn" not in text
    assert "<script src" not in text.lower() and "src=" not in text.lower() and "<link" not in text.lower()
    assert "<canvas" in text and "Lens &lt;two balls&gt;" in text
    p = _parse(text)
    assert [t for t, _ in p.starts].count("canvas") == 1
    data = [s for a, s in p.scripts if a.get("type") == "application/json"]
    assert len(data) == 1 and len([s for a, s in p.scripts if not a]) == 1    # the data and one inline script
    payload = json.loads(data[0])
    m = len(lens.boundary_points)
    expected = m if max_points is None else min(m, max_points)
    assert len(payload["points"]) == 3 * expected
    assert p.starts[0][1]["data-points"] == str(expected)
    assert f"{expected} of {m} boundary points shown" in text
    pts = np.array(payload["points"]).reshape(-1, 3)
    # the embedded points are boundary points (rounded to a thousandth of a cell)
    f = np.maximum(np.linalg.norm(pts - C1, axis=1) - R, np.linalg.norm(pts - C2, axis=1) - R)
    assert np.abs(f).max() < 0.1
    assert np.array(payload["segments"]).shape == (2, 2, 3)
    assert [lab for lab in payload["labels"]] == ["x [mm]", "y [mm]", "z [mm]"]


def test_two_views_get_different_ids_and_bad_segments_are_refused(lens):
    a = view3d_html(lens, title="one")
    b = view3d_html(lens, title="two")
    ida, idb = (_parse(t).starts[0][1]["id"] for t in (a, b))
    assert ida != idb and ida == _parse(view3d_html(lens, title="one")).starts[0][1]["id"]
    with pytest.raises(ConfigError):
        view3d_html(lens, title="t", robot_segments=np.zeros((3, 3)))


def test_standalone_page(lens, tmp_path):
    path = write_view3d_page(lens, tmp_path / "view.html", "Lens")
    text = path.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>") and "<title>Lens</title>" in text and 'charset="utf-8"' in text
    assert "http://" not in text and "https://" not in text
    _parse(text.split("\n", 1)[1])
    with pytest.raises(ConfigError):
        write_view3d_page(lens, tmp_path / "view.png", "Lens")


def test_mixed_units_are_named_everywhere():
    ws = grid_workspace(lambda p: (p[..., 0] ** 2 + p[..., 1] ** 2) / 400 + (p[..., 2] / 5) ** 2 <= 1,
                        [[-25, 25], [-25, 25], [-6, 6]], 20, names=("tilt_x", "tilt_y", "z"),
                        units=("deg", "deg", "mm"))
    fig = view3d_figure(ws, title="mixed")
    assert any("deg\u00b7deg\u00b7mm" in t.get_text() for t in fig.texts)
    assert "tilt_x [deg]" in view3d_html(ws, title="m")
    s = slices_figure(ws, [0.0])
    assert s.axes[0].get_xlabel() == "tilt_x [deg]" and s.axes[0].get_title().endswith(" mm")
    assert math.isfinite(ws.volume)
