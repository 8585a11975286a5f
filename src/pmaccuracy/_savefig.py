"""Write a matplotlib figure in the format its file name asks for: the one function every figure goes through.

Every ``--plot`` of the command line and every figure writer of the package calls :func:`save_figure`, so a
``.pdf`` is a PDF, a ``.svg`` an SVG and a ``.png`` a PNG at :data:`DEFAULT_DPI` dots per inch (written in the
PNG's ``pHYs`` chunk). The suffixes are those matplotlib writes without extra packages
(:data:`FIGURE_TYPES`); :func:`check_figure_path` refuses any other before anything is computed.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

from .errors import ConfigError

#: Dots per inch of a raster figure (PNG, JPEG, TIFF, WebP) unless told otherwise.
DEFAULT_DPI = 200
#: Accepted range of ``dpi`` (a 10 in figure at 1200 dpi is already 12000 px wide).
DPI_RANGE = (20, 1200)
#: The narrowest width a figure is made to be read at (CSS px: a phone held upright, the report's image
#: scaled to the screen) and the smallest text allowed there (px). A figure ``W`` inches wide needs text of
#: at least :func:`min_font_pt` ``= MIN_TEXT_PX * 72 * W / NARROW_DISPLAY_PX`` points: 10.8 pt at 7.5 in.
NARROW_DISPLAY_PX = 400
MIN_TEXT_PX = 8.0
#: File suffix -> matplotlib format: what matplotlib writes with its own backends (Agg, PDF, SVG, PS; Pillow
#: for JPEG, TIFF and WebP is a dependency of matplotlib). ``.raw``/``.rgba`` (headerless pixels) and ``.pgf``
#: (needs LaTeX) are left out.
FIGURE_TYPES = {".png": "png", ".pdf": "pdf", ".svg": "svg", ".svgz": "svgz", ".eps": "eps", ".ps": "ps",
                ".jpg": "jpeg", ".jpeg": "jpeg", ".tif": "tiff", ".tiff": "tiff", ".webp": "webp"}


def check_dpi(dpi: float, option: str = "dpi") -> int:
    """``dpi`` as an int, or a :class:`~pmaccuracy.errors.ConfigError` naming ``option`` when it is not a
    whole number in :data:`DPI_RANGE`.

    >>> check_dpi(200)
    200
    """
    lo, hi = DPI_RANGE
    try:
        value = float(dpi)
    except (TypeError, ValueError):
        raise ConfigError(f"must be a number of dots per inch, got {dpi!r}", key=option) from None
    if not (math.isfinite(value) and value == int(value) and lo <= value <= hi):
        raise ConfigError(f"must be a whole number of dots per inch from {lo} to {hi}, got {dpi!r}", key=option)
    return int(value)


def figure_format(path: str | os.PathLike, option: str = "path") -> str:
    """The matplotlib format named by ``path``'s suffix (case-insensitive), or a ConfigError naming ``option``
    and the path.

    >>> figure_format("maps/fig9.PDF")
    'pdf'
    >>> figure_format("fig.jpg")
    'jpeg'
    """
    suffix = Path(os.fspath(path)).suffix.lower()
    if suffix not in FIGURE_TYPES:
        got = f"{suffix!r}" if suffix else "no file type"
        raise ConfigError(f"unsupported figure type {got}: use {', '.join(FIGURE_TYPES)}", source=os.fspath(path),
                          key=option)
    return FIGURE_TYPES[suffix]


def check_figure_path(path: str | os.PathLike, option: str = "path", dpi: float = DEFAULT_DPI) -> Path:
    """Check a figure's path (suffix, :func:`figure_format`) and ``dpi`` (:func:`check_dpi`) before computing."""
    figure_format(path, option)
    check_dpi(dpi, "dpi" if option == "path" else "--dpi")
    return Path(os.fspath(path))


def min_font_pt(width_in: float, display_px: float = NARROW_DISPLAY_PX, min_px: float = MIN_TEXT_PX) -> float:
    """The smallest font (points) that is still ``min_px`` pixels high when a figure ``width_in`` inches wide
    is shown ``display_px`` pixels wide.

    >>> round(min_font_pt(7.5), 2), round(min_font_pt(10.0), 2)
    (10.8, 14.4)
    """
    return min_px * 72.0 * float(width_in) / float(display_px)


def drawn_texts(fig) -> list:
    """The visible, non-empty texts of ``fig`` (titles, labels, tick labels, legends, annotations)."""
    from matplotlib.text import Text

    out = []
    for t in fig.findobj(Text):
        if not t.get_visible() or not t.get_text().strip():
            continue
        if t.axes is not None and not t.axes.get_visible():
            continue
        out.append(t)
    return out


def smallest_text_px(fig, display_px: float = NARROW_DISPLAY_PX) -> float:
    """Height (px, font size) of the smallest text of ``fig`` when the figure is shown ``display_px`` wide
    (``inf`` for a figure without text)."""
    sizes = [t.get_fontsize() for t in drawn_texts(fig)]
    return min(sizes, default=math.inf) * display_px / (72.0 * fig.get_figwidth())


def legible(fig, display_px: float = NARROW_DISPLAY_PX, min_px: float = MIN_TEXT_PX):
    """Raise every text of ``fig`` smaller than :func:`min_font_pt` (for the figure's width) to that size, so
    that no text is under ``min_px`` pixels when the figure is shown ``display_px`` wide; returns ``fig``.

    The figures lay their text out at these sizes already; this is the guarantee for any text they missed.
    """
    floor = min_font_pt(fig.get_figwidth(), display_px, min_px)
    for ax in fig.axes:                      # tick labels made at draw time take the axis's size
        for axis in (ax.xaxis, ax.yaxis):
            for which, ticks in (("major", axis.get_major_ticks(1)), ("minor", axis.get_minor_ticks(1))):
                if ticks and ticks[0].label1.get_fontsize() < floor - 1e-9:
                    axis.set_tick_params(which=which, labelsize=floor)
    for t in drawn_texts(fig):
        if t.get_fontsize() < floor - 1e-9:
            t.set_fontsize(floor)
    return fig


def save_figure(fig, path: str | os.PathLike, *, dpi: float = DEFAULT_DPI, option: str = "path") -> Path:
    """Write ``fig`` (a :class:`matplotlib.figure.Figure`) to ``path`` in the format its suffix names.

    ``.png`` -> PNG (``dpi`` dots per inch, also stored in the file), ``.pdf`` -> PDF, ``.svg`` -> SVG,
    ``.jpg``/``.jpeg`` -> JPEG, ``.tif``/``.tiff`` -> TIFF, ... (:data:`FIGURE_TYPES`); vector formats keep
    ``dpi`` for their embedded images only. Missing parent folders are created. An unknown suffix or a
    ``dpi`` outside :data:`DPI_RANGE` raises :class:`~pmaccuracy.errors.ConfigError` naming ``option``
    before anything is written. Every text is made :func:`legible` at :data:`NARROW_DISPLAY_PX` first.
    Returns the path.

    >>> import tempfile
    >>> from matplotlib.figure import Figure
    >>> fig = Figure(figsize=(2, 1))
    >>> _ = fig.add_subplot().plot([0, 1], [0, 1])
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     save_figure(fig, Path(tmp) / "line.pdf").read_bytes()[:4]
    b'%PDF'
    """
    fmt = figure_format(path, option)
    dpi = check_dpi(dpi, "dpi" if option == "path" else "--dpi")
    path = Path(os.fspath(path))
    path.parent.mkdir(parents=True, exist_ok=True)
    if type(fig.canvas).__name__ == "FigureCanvasBase":   # a bare Figure(): draw with Agg (no pyplot state)
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        FigureCanvasAgg(fig)
    legible(fig)
    fig.savefig(path, dpi=dpi, format=fmt)
    return path


#: One notation for the worst-case errors in every figure: variable -> (symbol in matplotlib mathtext, unit).
#: Lengths in mm, the orientation error in degrees (the paper's Figs. 9-12).
SYMBOLS = {
    "dx_max": (r"$\delta x_{max}$", "mm"),
    "dy_max": (r"$\delta y_{max}$", "mm"),
    "dp_max": (r"$\delta p_{max}$", "mm"),
    "dphi_max": (r"$\delta\phi_{max}$", "deg"),
}


def quantity_label(var: str, unit: str | None = None) -> str:
    """``"<symbol> [<unit>]"`` of a worst-case error in every figure (:data:`SYMBOLS`); other names as given.

    >>> quantity_label("dphi_max")
    '$\\\\delta\\\\phi_{max}$ [deg]'
    >>> quantity_label("ratio", "1")
    'ratio [1]'
    """
    symbol, default = SYMBOLS.get(var, (var, unit or ""))
    unit = unit or default
    return f"{symbol} [{unit}]" if unit else symbol
