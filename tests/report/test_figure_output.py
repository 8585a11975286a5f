"""Every figure the package writes: the format its extension names, its dpi, colour options, one scale, MC bands.

Formats are read back by their magic bytes (written out here from the formats' specifications, not taken
from matplotlib); a PNG's resolution from its ``pHYs`` chunk (parsed here with ``struct``) and pixel size.
Bad options exit with status 2 and one line naming the option before anything is computed: the computing
functions are replaced by ones that fail the test if called.
"""

from __future__ import annotations

import gzip
import struct
import traceback
import zlib

import numpy as np
import pytest
from matplotlib.colors import BoundaryNorm, LogNorm
from matplotlib.figure import Figure

from pmaccuracy.accuracy import distributions, maps
from pmaccuracy.cli import main
from pmaccuracy.kinematics import workspace as ws_module
from pmaccuracy.report import figures

#: Magic bytes of each format (PNG spec, PDF 1.7 sec. 7.5.2, JFIF/EXIF SOI + marker, TIFF 6.0 header,
#: RIFF/WebP container, PostScript DSC header).
MAGIC = {
    "png": lambda b: b.startswith(b"\x89PNG\r\n\x1a\n"),
    "pdf": lambda b: b.startswith(b"%PDF-"),
    "svg": lambda b: b.lstrip().startswith(b"<?xml") and b"<svg" in b[:2000],
    "svgz": lambda b: b.startswith(b"\x1f\x8b") and b"<svg" in gzip.decompress(b)[:2000],
    "eps": lambda b: b.startswith(b"%!PS-Adobe") and b"EPSF" in b.split(b"\n", 1)[0],
    "ps": lambda b: b.startswith(b"%!PS-Adobe"),
    "jpg": lambda b: b.startswith(b"\xff\xd8\xff"),
    "jpeg": lambda b: b.startswith(b"\xff\xd8\xff"),
    "tif": lambda b: b[:4] in (b"II*\x00", b"MM\x00*"),
    "tiff": lambda b: b[:4] in (b"II*\x00", b"MM\x00*"),
    "webp": lambda b: b[:4] == b"RIFF" and b[8:12] == b"WEBP",
}


def run(argv, capsys):
    """(status, stdout, stderr) of the CLI; an unexpected exception becomes status ``"exception"``."""
    try:
        status = main([str(a) for a in argv])
    except SystemExit as exc:
        status = exc.code
    except BaseException:
        status = "exception"
        print(traceback.format_exc())
    out, err = capsys.readouterr()
    return status, out, err


def png_chunks(data: bytes) -> dict[bytes, bytes]:
    """The chunks of a PNG (type -> data), CRCs checked."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, chunks = 8, {}
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind = data[pos + 4:pos + 8]
        body = data[pos + 8:pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])
        assert crc == zlib.crc32(kind + body) & 0xFFFFFFFF
        chunks.setdefault(kind, body)
        pos += 12 + length
    return chunks


def png_dpi(data: bytes) -> tuple[float, int, int]:
    """(dots per inch from pHYs, width px, height px)."""
    chunks = png_chunks(data)
    width, height = struct.unpack(">II", chunks[b"IHDR"][:8])
    ppx, ppy, unit = struct.unpack(">IIB", chunks[b"pHYs"])
    assert unit == 1 and ppx == ppy            # pixels per metre
    return ppx * 0.0254, width, height


# ----------------------------------------------------------------------------- one function, every format
@pytest.mark.parametrize("ext", sorted(MAGIC))
def test_save_figure_writes_the_format_its_extension_names(tmp_path, ext):
    fig = Figure(figsize=(2, 1.5))
    fig.add_subplot().plot([0, 1], [0, 1])
    path = figures.save_figure(fig, tmp_path / f"f.{ext.upper() if ext == 'pdf' else ext}")
    assert MAGIC[ext](path.read_bytes()), path.read_bytes()[:16]


def test_save_figure_png_dpi_default_200_and_given(tmp_path):
    fig = Figure(figsize=(3, 2))
    fig.add_subplot().plot([0, 1], [0, 1])
    dpi, w, h = png_dpi(figures.save_figure(fig, tmp_path / "a.png").read_bytes())
    assert dpi == pytest.approx(200, abs=0.05) and (w, h) == (600, 400)
    dpi, w, h = png_dpi(figures.save_figure(fig, tmp_path / "b.png", dpi=90).read_bytes())
    assert dpi == pytest.approx(90, abs=0.05) and (w, h) == (270, 180)


@pytest.mark.parametrize("name, dpi, key", [("f.xyz", 200, "path"), ("noext", 200, "path"), ("f.png", 5, "dpi"),
                                            ("f.png", 150.5, "dpi"), ("f.raw", 200, "path")])
def test_save_figure_refuses_before_writing(tmp_path, name, dpi, key):
    from pmaccuracy.errors import ConfigError

    with pytest.raises(ConfigError) as info:
        figures.save_figure(Figure(), tmp_path / name, dpi=dpi)
    assert info.value.key == key
    assert not (tmp_path / name).exists()


# ----------------------------------------------------------------------------- every --plot of the CLI
@pytest.mark.parametrize("ext", sorted(MAGIC))
def test_workspace_plot_every_extension(tmp_path, capsys, ext):
    path = tmp_path / f"ws.{ext}"
    status, _, err = run(["workspace", "--plot", path, "--format", "json"], capsys)
    assert status == 0, err
    assert MAGIC[ext](path.read_bytes())


def test_workspace_compare_pdf_and_dpi(tmp_path, capsys):
    pdf = tmp_path / "cmp.pdf"
    status, _, err = run(["workspace", "--compare", "aalborg_3ppr", "symmetric_3ppr", "--plot", pdf], capsys)
    assert status == 0, err
    assert MAGIC["pdf"](pdf.read_bytes())
    png = tmp_path / "one.png"
    status, _, err = run(["workspace", "--plot", png, "--dpi", "72"], capsys)
    assert status == 0, err
    assert png_dpi(png.read_bytes())[0] == pytest.approx(72, abs=0.05)


@pytest.mark.parametrize("ext", ["pdf", "svg", "jpg", "png"])
def test_compare_designs_plot_format(tmp_path, capsys, ext):
    path = tmp_path / f"designs.{ext}"
    status, _, err = run(["compare-designs", "--robot", "aalborg_3ppr", "--robot", "symmetric_3ppr",
                          "--clearances", "case2", "--phi-deg", "0", "--grid", "9", "--plot", path,
                          "--dpi", "60", "--format", "json"], capsys)
    assert status == 0, err
    data = path.read_bytes()
    assert MAGIC[ext](data)
    if ext == "png":
        assert png_dpi(data)[0] == pytest.approx(60, abs=0.05)


def test_map_plot_svg_and_png_dpi_with_colour_options(tmp_path, capsys):
    svg = tmp_path / "map.svg"
    status, _, err = run(["map", "--clearances", "case2", "--phi-deg", "0", "--grid", "9", "--out",
                          tmp_path / "m.nc", "--plot", svg, "--log", "--format", "json"], capsys)
    assert status == 0, err
    assert MAGIC["svg"](svg.read_bytes())
    png = tmp_path / "map.png"
    status, _, err = run(["map", "--clearances", "case2", "--phi-deg", "0", "--grid", "9", "--out",
                          tmp_path / "m.nc", "--plot", png, "--vmin", "0.1", "--vmax", "0.5", "--format", "json"],
                         capsys)
    assert status == 0, err
    dpi, w, _ = png_dpi(png.read_bytes())
    assert dpi == pytest.approx(200, abs=0.05) and w == round(figures.REPORT_WIDTH_IN * 200)   # at 200 dpi


def test_statistics_plot_pdf(tmp_path, capsys):
    pdf = tmp_path / "stats.pdf"
    status, _, err = run(["statistics", "--clearances", "case2", "--phi-deg", "0", "--grid", "5", "--samples",
                          "500", "--out", tmp_path / "s.nc", "--plot", pdf, "--format", "json"], capsys)
    assert status == 0, err
    assert MAGIC["pdf"](pdf.read_bytes())


def _no_computing(monkeypatch):
    def fail(*args, **kwargs):
        raise AssertionError("computed before the options were checked")
    monkeypatch.setattr(maps, "error_map", fail)
    monkeypatch.setattr(distributions, "region_statistics", fail)
    monkeypatch.setattr(ws_module, "constant_orientation_workspace", fail)
    from pmaccuracy.accuracy import designs
    monkeypatch.setattr(designs, "compare_designs", fail)


BAD = [
    (["workspace", "--plot", "{d}/w.xyz"], "--plot"),
    (["workspace", "--plot", "{d}/w.png", "--dpi", "0"], "--dpi"),
    (["compare-designs", "--robot", "aalborg_3ppr", "--robot", "symmetric_3ppr", "--clearances", "case2",
      "--phi-deg", "0", "--plot", "{d}/c.doc"], "--plot"),
    (["map", "--clearances", "case2", "--phi-deg", "0", "--grid", "9", "--out", "{d}/m.nc", "--plot", "{d}/m.gif"],
     "--plot"),
    (["map", "--clearances", "case2", "--phi-deg", "0", "--grid", "9", "--out", "{d}/m.nc", "--plot", "{d}/m.png",
      "--dpi", "5000"], "--dpi"),
    (["map", "--clearances", "case2", "--phi-deg", "0", "--grid", "9", "--out", "{d}/m.nc", "--plot", "{d}/m.png",
      "--vmin", "0.3", "--vmax", "0.2"], "--vmin"),
    (["map", "--clearances", "case2", "--phi-deg", "0", "--grid", "9", "--out", "{d}/m.nc", "--plot", "{d}/m.png",
      "--log", "--vmin", "0"], "--vmin"),
    (["map", "--clearances", "case2", "--phi-deg", "0", "--grid", "9", "--out", "{d}/m.nc", "--vmax", "1"], "--vmax"),
    (["statistics", "--clearances", "case2", "--phi-deg", "0", "--grid", "5", "--out", "{d}/s.nc", "--plot",
      "{d}/s.bmp"], "--plot"),
]


@pytest.mark.parametrize("argv, option", BAD, ids=[f"{a[0]}-{o}-{k}" for k, (a, o) in enumerate(BAD)])
def test_bad_figure_options_exit_2_before_computing(tmp_path, capsys, monkeypatch, argv, option):
    _no_computing(monkeypatch)
    status, out, err = run([a.format(d=tmp_path) for a in argv], capsys)
    assert status == 2, err + out
    lines = err.strip().splitlines()
    assert len(lines) == 1 and option in lines[0] and "Traceback" not in err
    assert not list(tmp_path.iterdir())           # nothing written, no folder created


# ----------------------------------------------------------------------------- style
def _field(x0, x1, y0, y1, n=21):
    x, y = np.linspace(x0, x1, n), np.linspace(y0, y1, n)
    X, Y = np.meshgrid(x, y)
    return x, y, 0.1 + 0.001 * (X ** 2 + Y ** 2)


def test_plot_panels_same_axes_draws_workspaces_to_one_scale():
    small = (*_field(-10, 10, -13, 13), "small, 520 mm^2", "mm")       # 20 x 26 = 520 mm^2
    large = (*_field(-15, 20, -17, 17.3), "large, 1201 mm^2", "mm")    # 35 x 34.3 = 1200.5 mm^2
    fig = figures.plot_panels([small, large], suptitle="s", shared_scale=True, same_axes=True)
    axes = [ax for ax in fig.axes if ax.get_title().startswith(("small", "large"))]
    assert len(axes) == 2
    (a, b) = axes
    assert a.get_xlim() == pytest.approx(b.get_xlim()) and a.get_ylim() == pytest.approx(b.get_ylim())
    # mm per inch equal in x and y, and equal across the panels
    scales = []
    for ax in axes:
        box = ax.get_position()
        w_in, h_in = box.width * fig.get_figwidth(), box.height * fig.get_figheight()
        scales += [np.ptp(ax.get_xlim()) / w_in, np.ptp(ax.get_ylim()) / h_in]
    assert np.allclose(scales, scales[0], rtol=1e-6)
    lo, hi = min(a.get_xlim()), max(a.get_xlim())
    assert lo <= -15 and hi >= 20                  # the union of both workspaces is shown
    # without same_axes each panel is zoomed on its own field (the small one drawn larger)
    fig = figures.plot_panels([small, large], suptitle="s")
    a, b = [ax for ax in fig.axes if ax.get_title().startswith(("small", "large"))]
    assert np.ptp(a.get_xlim()) < np.ptp(b.get_xlim())


def test_workspace_comparison_panels_share_limits():
    from pmaccuracy.model.manipulator import Manipulator

    robots = [Manipulator.preset("aalborg_3ppr"), Manipulator.preset("symmetric_3ppr")]
    fig = ws_module.comparison_figure(robots, (0.0,))
    axes = [ax for ax in fig.axes if ax.get_xlabel()]
    zoomed = [ax for ax in axes if "common scale" in ax.get_title()]
    assert len(zoomed) == 2
    assert np.ptp(zoomed[0].get_xlim()) == pytest.approx(np.ptp(zoomed[1].get_xlim()))
    assert np.ptp(zoomed[0].get_ylim()) == pytest.approx(np.ptp(zoomed[1].get_ylim()))


def test_error_map_notation_units_contour_labels_and_title(tmp_path):
    from pmaccuracy.model.manipulator import Manipulator

    ds = maps.error_map(Manipulator.preset("aalborg_3ppr"), "case1", [0.0], 21, progress=False)
    fig = figures.plot_error_map(ds, 0.0, vmin=0.15, vmax=0.3)
    maps_axes = [ax for ax in fig.axes if ax.get_xlabel() == "x [mm]"]
    titles = [ax.get_title() for ax in maps_axes]
    for symbol, unit in (("\\delta x_{max}", "mm"), ("\\delta y_{max}", "mm"), ("\\delta p_{max}", "mm"),
                         ("\\delta\\phi_{max}", "deg")):
        assert any(symbol in t and f"[{unit}]" in t for t in titles), titles
    bars = [ax for ax in fig.axes if ax not in maps_axes]
    assert all((ax.get_xlabel() + ax.get_ylabel()).strip() for ax in bars)   # every colour bar labelled
    assert all("[" in ax.get_xlabel() + ax.get_ylabel() for ax in bars)     # with units
    # the mm panels take the user's colour limits; dx_max varies, so it has labelled contour lines
    dx_ax = maps_axes[titles.index(next(t for t in titles if "x_{max}" in t))]
    mesh = dx_ax.collections[0]
    assert (mesh.norm.vmin, mesh.norm.vmax) == (0.15, 0.3)
    assert dx_ax.texts, "contour labels"
    assert "aalborg_3ppr" in fig._suptitle.get_text() and "case1" in fig._suptitle.get_text()
    assert "0 deg" in fig._suptitle.get_text()
    log = figures.plot_error_map(ds, 0.0, log=True)
    assert isinstance([ax for ax in log.axes if ax.get_xlabel() == "x [mm]"][0].collections[0].norm, LogNorm)


# ----------------------------------------------------------------------------- Monte Carlo maps
@pytest.fixture(scope="module")
def mc_maps():
    from pmaccuracy.model.manipulator import Manipulator

    robot = Manipulator.preset("aalborg_3ppr")
    return [distributions.region_statistics(robot, "case2", [0.0], 7, samples=400, seed=s) for s in (1, 2)]


def test_stated_percentile_error_matches_seed_to_seed_scatter(mc_maps):
    """The stated error (half-width of the 95 % interval) against two independent runs: the difference of two
    estimates has about sqrt(2) x (error / 1.96) standard deviation, so over 49 poses it stays below ~1.6 x
    the largest error, and a stated error far above the scatter would be useless (it must not be 10x)."""
    a, b = mc_maps
    for q in ("dp", "dphi"):
        err = float(a.attrs[f"{q}_p95_error"])
        diff = np.abs(a[f"{q}_p95"].values - b[f"{q}_p95"].values)
        assert np.nanmax(diff) <= 2.0 * err
        assert np.nanmax(diff) >= 0.1 * err


def test_percentile_map_colour_steps_no_finer_than_stated_error(mc_maps, tmp_path):
    ds = mc_maps[0]
    from pmaccuracy.report import statistics_report

    captured = {}
    real = figures.plot_panels

    def spy(*args, **kwargs):
        captured["fig"] = real(*args, **kwargs)
        return captured["fig"]

    try:
        figures.plot_panels = spy
        path = statistics_report.save_percentile_map_figure(ds, tmp_path / "p.png", dpi=50, log=True)
    finally:
        figures.plot_panels = real
    assert MAGIC["png"](path.read_bytes())
    fig = captured["fig"]
    checked = 0
    for ax in fig.axes:
        title = ax.get_title()
        if not ax.collections or not title:
            continue
        q = "dp" if "delta p" in title else "dphi"
        stated = {"percentile of": f"{q}_p95_error", "percentile / worst": f"{q}_p95_ratio_error"}
        for words, attr in stated.items():
            if title.startswith("95th") and words == "percentile of" or words in title:
                norm = ax.collections[0].norm
                assert isinstance(norm, BoundaryNorm)
                steps = np.diff(norm.boundaries)
                assert steps.min() >= float(ds.attrs[attr]) * (1 - 1e-12)
                checked += 1
    assert checked == 4


def test_monte_carlo_levels_bound_the_range_with_steps_at_least_the_error():
    for lo, hi, err in ((0.101, 0.118, 0.003), (0.5, 0.6, 1e-5), (0.0, 1.0, 0.3), (2.0, 2.0, 0.01)):
        levels = figures.monte_carlo_levels(lo, hi, err)
        assert levels[0] <= lo and levels[-1] >= hi
        assert np.diff(levels).min() >= err * (1 - 1e-12)
        assert len(levels) <= 14
