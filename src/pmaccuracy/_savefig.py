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


def save_figure(fig, path: str | os.PathLike, *, dpi: float = DEFAULT_DPI, option: str = "path") -> Path:
    """Write ``fig`` (a :class:`matplotlib.figure.Figure`) to ``path`` in the format its suffix names.

    ``.png`` -> PNG (``dpi`` dots per inch, also stored in the file), ``.pdf`` -> PDF, ``.svg`` -> SVG,
    ``.jpg``/``.jpeg`` -> JPEG, ``.tif``/``.tiff`` -> TIFF, ... (:data:`FIGURE_TYPES`); vector formats keep
    ``dpi`` for their embedded images only. Missing parent folders are created. An unknown suffix or a
    ``dpi`` outside :data:`DPI_RANGE` raises :class:`~pmaccuracy.errors.ConfigError` naming ``option``
    before anything is written. Returns the path.

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
