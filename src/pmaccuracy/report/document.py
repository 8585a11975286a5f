"""A tiny document model rendered both as Markdown and as self-contained HTML.

Reports are lists of blocks (headings, paragraphs, tables, figures, boxes for parts not computed); the HTML
embeds every figure as a base64 PNG so a single file can be mailed or archived.
"""

from __future__ import annotations

import base64
import html
import math
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

_CSS = """
html { -webkit-text-size-adjust: 100%; text-size-adjust: 100%; }
body { font-family: -apple-system, 'Segoe UI', Helvetica, Arial, sans-serif; font-size: 16px; max-width: 1100px;
       margin: 2em auto; padding: 0 1em; color: #222; line-height: 1.45; overflow-wrap: break-word; }
h1 { border-bottom: 2px solid #444; padding-bottom: .2em; font-size: 1.7em; }
h2 { border-bottom: 1px solid #bbb; padding-bottom: .1em; margin-top: 1.8em; }
.scroll { overflow-x: auto; max-width: 100%; margin: .8em 0; }
table { border-collapse: collapse; font-size: 0.92em; }
th, td { border: 1px solid #bbb; padding: .25em .6em; text-align: right; }
th { background: #eee; } td:first-child, th:first-child { text-align: left; }
figure { margin: 1em 0; } figure img { max-width: 100%; height: auto; border: 1px solid #ddd; }
figcaption { font-size: 0.9em; color: #444; }
nav.toc { background: #f7f7f7; border: 1px solid #ddd; padding: .4em 1em; margin: 1em 0; }
nav.toc ul { margin: .3em 0; padding-left: 0; list-style: none; }
footer { margin-top: 3em; padding-top: .5em; border-top: 1px solid #bbb; font-size: 0.9em; color: #444; }
.ok { color: #1a7f37; font-weight: bold; } .bad { color: #b42318; font-weight: bold; }
.failed { border: 2px solid #b42318; background: #fef3f2; padding: .6em 1em; margin: 1em 0; }
code { background: #f4f4f4; padding: 0 .2em; } td code { white-space: nowrap; }
@media (max-width: 600px) { body { margin: 1em auto; padding: 0 .6em; } h1 { font-size: 1.4em; } }
"""


@dataclass
class Document:
    """Blocks of a report; ``to_markdown`` and ``to_html`` render the same content.

    Level-2 headings are numbered ("2. Maps") unless ``numbered=False``; figures are numbered in order
    ("Figure 3.") and :meth:`figure` returns the number, so the text can point to it; the HTML has a table
    of contents, a viewport for phones (tables scroll sideways inside their box, figures scale) and a
    footer (:attr:`footer`: e.g. the command and the version that wrote it).
    """

    title: str
    blocks: list[tuple[str, object]] = field(default_factory=list)
    footer: str = ""
    _sections: int = 0
    _figures: int = 0

    def heading(self, text: str, level: int = 2, *, numbered: bool = True) -> int | None:
        """Add a heading; returns its section number (level 2, numbered) or ``None``."""
        number = None
        if level == 2 and numbered:
            self._sections += 1
            number = self._sections
            text = f"{number}. {text}"
        self.blocks.append(("heading", (level, text)))
        return number

    @property
    def next_section(self) -> int:
        """The number the next numbered section will get."""
        return self._sections + 1

    @property
    def next_figure(self) -> int:
        """The number the next figure will get."""
        return self._figures + 1

    def paragraph(self, text: str) -> None:
        """A paragraph; ``**bold**`` and ``code`` spans are rendered in both formats."""
        self.blocks.append(("paragraph", text))

    def bullets(self, items: list[str]) -> None:
        self.blocks.append(("bullets", items))

    def table(self, header: list[str], rows: list[list[object]]) -> None:
        self.blocks.append(("table", (header, rows)))

    def figure(self, path: str | Path, caption: str) -> int:
        """Add a figure captioned "Figure N. <caption>"; returns N."""
        self._figures += 1
        self.blocks.append(("figure", (Path(path), f"Figure {self._figures}. {caption}")))
        return self._figures

    def raw_html(self, fragment: str, markdown: str = "") -> None:
        """Embed an HTML fragment as is in the HTML (e.g. an offline interactive view,
        :func:`pmaccuracy.report.view3d_html.view3d_html`); the Markdown shows ``markdown`` in its place (nothing
        when empty). The fragment is trusted: it must be self-contained (no network resources)."""
        self.blocks.append(("html", (fragment, markdown)))

    def failure(self, section: str, reason: str, *, seconds: float | None = None) -> None:
        """A box in place of a section (or part) that could not be computed: its name and the reason."""
        took = "" if seconds is None else f" (after {seconds:.1f} s)"
        self.blocks.append(("failure", (f"{section}: not computed{took}.", f"Reason: {reason}")))

    def _headings(self) -> list[tuple[str, str]]:
        """``(anchor, text)`` of every level-2 heading, in order."""
        out = []
        for kind, payload in self.blocks:
            if kind == "heading" and payload[0] == 2:
                out.append((f"s{len(out) + 1}", payload[1]))
        return out

    # ------------------------------------------------------------------ rendering
    def to_markdown(self, relative_to: Path | None = None) -> str:
        out = [f"# {self.title}", ""]
        for kind, payload in self.blocks:
            if kind == "heading":
                level, text = payload
                out += ["#" * level + " " + text, ""]
            elif kind == "paragraph":
                out += [payload, ""]
            elif kind == "bullets":
                out += [f"- {item}" for item in payload] + [""]
            elif kind == "table":
                header, rows = payload
                # A literal "|" would split the Markdown row: escape it.
                out.append("| " + " | ".join(str(h).replace("|", "\\|") for h in header) + " |")
                out.append("|" + "|".join("---" for _ in header) + "|")
                out += ["| " + " | ".join(_cell(c).replace("|", "\\|") for c in row) + " |" for row in rows]
                out.append("")
            elif kind == "failure":
                head, reason = payload
                out += [f"> **{head}** {reason}", ""]
            elif kind == "html":
                if payload[1]:
                    out += [payload[1], ""]
            elif kind == "figure":
                path, caption = payload
                shown = path.relative_to(relative_to) if relative_to and path.is_relative_to(relative_to) else path
                out += [f"![{caption}]({shown.as_posix()})", "", f"*{caption}*", ""]
        if self.footer:
            out += ["---", "", self.footer, ""]
        return "\n".join(out)

    def to_html(self) -> str:
        parts = ["<!DOCTYPE html>", "<html lang='en'><head><meta charset='utf-8'>",
                 "<meta name='viewport' content='width=device-width, initial-scale=1'>",
                 f"<title>{html.escape(self.title)}</title><style>{_CSS}</style></head><body>",
                 f"<h1>{html.escape(self.title)}</h1>"]
        anchors = iter(self._headings())
        toc = self._headings()
        toc_done = False
        for kind, payload in self.blocks:
            if kind == "heading":
                level, text = payload
                if level == 2:
                    if not toc_done and len(toc) > 2:   # the contents, before the first section
                        parts.append("<nav class='toc'><b>Contents</b><ul>" + "".join(
                            f"<li><a href='#{a}'>{_inline(t)}</a></li>" for a, t in toc) + "</ul></nav>")
                    toc_done = True
                    anchor, _ = next(anchors)
                    parts.append(f"<h2 id='{anchor}'>{_inline(text)}</h2>")
                else:
                    parts.append(f"<h{level}>{_inline(text)}</h{level}>")
            elif kind == "paragraph":
                parts.append(f"<p>{_inline(payload)}</p>")
            elif kind == "bullets":
                parts.append("<ul>" + "".join(f"<li>{_inline(i)}</li>" for i in payload) + "</ul>")
            elif kind == "table":
                header, rows = payload
                parts.append("<div class='scroll'><table><thead><tr>"
                             + "".join(f"<th>{_inline(h)}</th>" for h in header) + "</tr></thead><tbody>")
                parts += ["<tr>" + "".join(f"<td>{_inline(_cell(c))}</td>" for c in row) + "</tr>" for row in rows]
                parts.append("</tbody></table></div>")
            elif kind == "html":
                parts.append(payload[0])
            elif kind == "failure":
                head, reason = payload
                parts.append(f"<div class='failed' role='note'><b>{html.escape(head)}</b> {_inline(reason)}</div>")
            elif kind == "figure":
                path, caption = payload
                data = base64.b64encode(Path(path).read_bytes()).decode("ascii")
                mime = _MIME.get(Path(path).suffix.lower(), "image/png")
                width = display_width(Path(path))
                size = f" width='{width}'" if width else ""
                parts.append(f"<figure><img alt='{html.escape(caption)}'{size} src='data:{mime};base64,{data}'>"
                             f"<figcaption>{_inline(caption)}</figcaption></figure>")
        if self.footer:
            parts.append(f"<footer>{_inline(self.footer)}</footer>")
        parts.append("</body></html>")
        return "\n".join(parts)


def provenance(command: str | None, version: str) -> str:
    """A report's footer: the version (and the git commit when the package runs from a checkout), the date
    and the command that wrote it.

    >>> provenance("pmaccuracy reproduce --out out", "1.0").startswith("Written by pmaccuracy 1.0")
    True
    """
    commit = ""
    try:
        done = subprocess.run(["git", "-C", str(Path(__file__).resolve().parent), "rev-parse", "--short", "HEAD"],
                              capture_output=True, text=True, timeout=5)
        if done.returncode == 0 and done.stdout.strip():
            commit = f" (commit {done.stdout.strip()})"
    except (OSError, subprocess.SubprocessError):
        pass
    when = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    how = f" with `{command}`" if command else " from Python"
    return f"Written by pmaccuracy {version}{commit} on {when}{how}."


#: CSS pixels per inch of figure at which the HTML shows a PNG at most (a 7.5 in figure: 750 px), so that its
#: text is about the page's text size on a wide screen; narrower screens scale it down (``max-width: 100%``).
DISPLAY_PX_PER_IN = 100


def display_width(path: Path) -> int | None:
    """Width (CSS px) to show a PNG at: its width in inches (pixels over the ``pHYs`` resolution) times
    :data:`DISPLAY_PX_PER_IN`; None for other files or a PNG without a resolution."""
    import struct

    data = path.read_bytes()[:4096] if path.suffix.lower() == ".png" else b""
    if data[:8] != b"\x89PNG\r\n\x1a\n" or len(data) < 24:      # not a PNG, or too short for its header
        return None
    width_px = struct.unpack(">I", data[16:20])[0]
    at = data.find(b"pHYs")
    if at < 0 or len(data) < at + 13:
        return None
    ppu_x, _, unit = struct.unpack(">IIB", data[at + 4:at + 13])
    if unit != 1 or ppu_x == 0:                       # 1: pixels per metre
        return None
    return round(width_px / (ppu_x * 0.0254) * DISPLAY_PX_PER_IN)


#: Image types a figure may have in the HTML (data URI).
_MIME = {".png": "image/png", ".svg": "image/svg+xml", ".jpg": "image/jpeg", ".jpeg": "image/jpeg"}


def _cell(value: object) -> str:
    """Five significant digits for floats; ``-`` for a missing or non-finite value."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    if isinstance(value, float):
        return f"{value:.5g}"
    return str(value)


def _inline(text: str) -> str:
    """Escape HTML, then render ``**bold**`` and ```code``` spans."""
    import re

    text = html.escape(text)
    text = re.sub(r"\*\*(.+?)\*\*", r"<b>\1</b>", text)
    text = re.sub(r"`(.+?)`", r"<code>\1</code>", text)
    text = text.replace("PASS", "<span class='ok'>PASS</span>").replace("FAIL", "<span class='bad'>FAIL</span>")
    return text
