"""The calibration report's five figures (issue 33 item 4) as they are saved, at the report's font sizes
(:func:`pmaccuracy._savefig.legible` raises every text to 8 px at 400 px display width): every text that is
drawn lies inside the figure, no two texts overlap and no text lies over a plotting area.

The texts are the ones matplotlib actually draws (``Text.draw`` is watched during one draw of the saved
figure, so tick labels outside the view are left out), measured with the figure's renderer.
"""

from __future__ import annotations

from itertools import combinations
from unittest import mock

import numpy as np
import pytest
from matplotlib.text import Text

import pmaccuracy as pm
from pmaccuracy.model.serial import SerialArm
from pmaccuracy.report import calibration_report as cr

#: Overlap (px at the figure's 100 dpi) tolerated between two boxes: antialiasing, not a collision.
SLACK_PX = 0.5
NAMES = ("residuals", "parameters", "spectrum", "observability", "accuracy")


def _figures(tmp_path, pv, n, *, seed, clearances, simulated=True):
    """The figures of one calibration report, captured as save_figure writes them."""
    saved = {}
    real = cr.save_figure

    def keep(fig, path, **kw):
        out = real(fig, path, **kw)
        saved[path.stem] = fig
        return out

    ex = pm.simulate_calibration(pv, n, seed=seed, clearances=clearances, n_targets=20)
    with mock.patch.object(cr, "save_figure", keep):
        if simulated:
            cr.calibration_report(tmp_path / "c.html", ex.identification, ex.data, experiment=ex, seed=seed)
        else:
            cr.calibration_report(tmp_path / "c.html", ex.identification, ex.data, clearances=clearances,
                                  seed=seed)
    return saved


def drawn_text_boxes(fig) -> list[tuple[Text, object]]:
    """``(text, window extent)`` of every non-empty text drawn in one draw of ``fig``."""
    drawn = []
    real = Text.draw

    def watch(self, renderer):
        if self.get_visible() and self.get_text().strip():
            drawn.append(self)
        return real(self, renderer)

    with mock.patch.object(Text, "draw", watch):
        fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    return [(t, t.get_window_extent(renderer)) for t in dict.fromkeys(drawn)]


def _overlap(a, b) -> float:
    return min(min(a.x1, b.x1) - max(a.x0, b.x0), min(a.y1, b.y1) - max(a.y0, b.y0))


def layout_faults(fig) -> list[str]:
    """What is wrong with the text layout of ``fig``: texts outside it, overlapping texts, texts on an axes."""
    boxes = drawn_text_boxes(fig)
    renderer = fig.canvas.get_renderer()
    w, h = fig.bbox.width, fig.bbox.height
    faults = []
    for t, b in boxes:
        if b.x0 < -SLACK_PX or b.y0 < -SLACK_PX or b.x1 > w + SLACK_PX or b.y1 > h + SLACK_PX:
            faults.append(f"outside the figure: {t.get_text()!r}")
    for (s, a), (t, b) in combinations(boxes, 2):
        if _overlap(a, b) > SLACK_PX:
            faults.append(f"overlap: {s.get_text()!r} and {t.get_text()!r}")
    for ax in fig.axes:
        area = ax.get_window_extent(renderer)
        for t, b in boxes:
            if _overlap(area, b) > SLACK_PX:
                faults.append(f"over a plotting area: {t.get_text()!r}")
    return faults


@pytest.fixture(scope="module")
def rrr(tmp_path_factory):
    pv = pm.error_parameters(pm.Manipulator.preset("symmetric_3rrr"))
    return _figures(tmp_path_factory.mktemp("calfig_rrr"), pv, 30, seed=1, clearances="rrr_typical")


@pytest.fixture(scope="module")
def rpr_measured(tmp_path_factory):
    pv = pm.error_parameters(pm.Manipulator.preset("symmetric_3rpr"))
    return _figures(tmp_path_factory.mktemp("calfig_rpr"), pv, 24, seed=2, clearances="rpr_typical",
                    simulated=False)


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    pv = pm.error_parameters(SerialArm.preset("planar_3r_arm"))
    return _figures(tmp_path_factory.mktemp("calfig_arm"), pv, 14, seed=3, clearances="arm_typical")


@pytest.mark.parametrize("case", ["rrr", "rpr_measured", "arm"])
@pytest.mark.parametrize("name", NAMES)
def test_calibration_figure_texts_inside_and_apart(case, name, request):
    fig = request.getfixturevalue(case)[name]
    assert fig.get_figwidth() <= cr.REPORT_WIDTH_IN + 1e-9
    assert layout_faults(fig) == []


@pytest.mark.parametrize("name", NAMES)
def test_calibration_figures_are_laid_out_at_the_report_font(rrr, name):
    """Written at the report's sizes: saving raised no text (so the layout checked is the one designed)."""
    fig = rrr[name]
    sizes = {t.get_fontsize() for t, _ in drawn_text_boxes(fig)}
    assert min(sizes) >= cr.FONT_PT - 1e-9


def test_the_checks_see_a_collision_and_a_text_outside():
    """The checks themselves: two titles on one spot, a label past the edge, a note on the data."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(4, 3))
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0.2, 0.2, 0.6, 0.6))
    ax.plot(np.arange(3))
    fig.text(0.5, 0.95, "one title", ha="center")
    fig.text(0.52, 0.95, "another title", ha="center")
    assert any(f.startswith("overlap") for f in layout_faults(fig))
    fig2 = Figure(figsize=(4, 3))
    FigureCanvasAgg(fig2)
    ax2 = fig2.add_axes((0.02, 0.2, 0.9, 0.6))
    ax2.set_ylabel("cut off")
    ax2.text(0.3, 0.5, "note on the data")
    faults = layout_faults(fig2)
    assert any("outside the figure: 'cut off'" in f for f in faults)
    assert any("over a plotting area: 'note on the data'" in f for f in faults)
