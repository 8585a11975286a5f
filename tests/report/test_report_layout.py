"""The HTML report as a reader sees it, on a desktop and on a phone (issue 25: no horizontal page scroll at
400 px, text of at least 12 px). Runs Chromium headless when it is installed (Debian's ``chromium``),
otherwise skips: the report is loaded in an iframe of the given width (its own viewport, so the page's
media queries apply) and a script measures the page's scroll width and the smallest font size of any text."""

from __future__ import annotations

import html
import json
import re
import shutil
import subprocess

import pytest

from pmaccuracy.report import reproduce

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="Chromium is not installed")

PROBE = """<!DOCTYPE html><html><body style='margin:0'>
<iframe id='f' width='{width}' height='900' style='border:0' srcdoc="{doc}"></iframe>
<script>
document.getElementById('f').addEventListener('load', function () {{
  var d = this.contentDocument, w = this.contentWindow, min = 1000, tag = '';
  d.querySelectorAll('body *').forEach(function (el) {{
    var text = Array.from(el.childNodes).some(function (n) {{ return n.nodeType === 3 && n.textContent.trim(); }});
    if (!text) return;
    var size = parseFloat(w.getComputedStyle(el).fontSize);
    if (size < min) {{ min = size; tag = el.tagName; }}
  }});
  var out = document.createElement('pre');
  out.id = 'probe';
  out.textContent = JSON.stringify({{scroll: d.documentElement.scrollWidth, width: w.innerWidth, font: min,
                                     tag: tag}});
  document.body.appendChild(out);
}});
</script></body></html>"""


def measure(report_html: str, width: int, tmp_path) -> dict:
    page = tmp_path / f"probe_{width}.html"
    page.write_text(PROBE.format(width=width, doc=html.escape(report_html, quote=True)), encoding="utf-8")
    dom = subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                          "--disable-background-networking", "--disable-component-update", "--disable-sync",
                          f"--user-data-dir={tmp_path / 'profile'}", "--window-size=1400,1000",
                          "--virtual-time-budget=10000", "--dump-dom", page.as_uri()],
                         capture_output=True, text=True, timeout=120).stdout
    found = re.search(r'<pre id="probe">([^<]*)</pre>', dom)
    assert found, "the probe did not run"
    return json.loads(html.unescape(found.group(1)))


@pytest.fixture(scope="module")
def report_html(tmp_path_factory):
    out = tmp_path_factory.mktemp("layout")
    reproduce(out, grid=9, experiment=False, workers=0)
    return (out / "report.html").read_text(encoding="utf-8")


@pytest.mark.parametrize("width", [1280, 400])
def test_report_fits_the_screen_with_readable_text(report_html, width, tmp_path):
    got = measure(report_html, width, tmp_path)
    assert got["width"] == width
    assert got["scroll"] <= width, got          # no horizontal scroll of the page (wide tables scroll in place)
    assert got["font"] >= 12.0, got


@pytest.fixture(scope="module")
def calibration_html(tmp_path_factory):
    import pmaccuracy as pm

    out = tmp_path_factory.mktemp("layout_calibration")
    pv = pm.error_parameters(pm.Manipulator.preset("symmetric_3rrr"))
    ex = pm.simulate_calibration(pv, 30, seed=1, clearances="rrr_typical", n_targets=20)
    pm.calibration_report(out / "calibration.html", ex.identification, ex.data, experiment=ex)
    return (out / "calibration.html").read_text(encoding="utf-8")


@pytest.mark.parametrize("width", [1280, 400])
def test_calibration_report_fits_the_screen_with_readable_text(calibration_html, width, tmp_path):
    got = measure(calibration_html, width, tmp_path)
    assert got["width"] == width
    assert got["scroll"] <= width, got
    assert got["font"] >= 12.0, got
