"""A tiny document model rendered both as Markdown and as self-contained HTML.

Reports are lists of blocks (headings, paragraphs, tables, figures); the HTML
embeds every figure as a base64 PNG so a single file can be mailed or archived.
"""

from __future__ import annotations

import base64
import html
import math
from dataclasses import dataclass, field
from pathlib import Path

_CSS = """
body { font-family: -apple-system, 'Segoe UI', Helvetica, Arial, sans-serif; max-width: 1100px; margin: 2em auto;
       padding: 0 1em; color: #222; line-height: 1.45; }
h1 { border-bottom: 2px solid #444; padding-bottom: .2em; }
h2 { border-bottom: 1px solid #bbb; padding-bottom: .1em; margin-top: 1.8em; }
table { border-collapse: collapse; margin: .8em 0; font-size: 0.92em; }
th, td { border: 1px solid #bbb; padding: .25em .6em; text-align: right; }
th { background: #eee; } td:first-child, th:first-child { text-align: left; }
figure { margin: 1em 0; } figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.9em; color: #555; }
.ok { color: #1a7f37; font-weight: bold; } .bad { color: #b42318; font-weight: bold; }
code { background: #f4f4f4; padding: 0 .2em; }
"""


@dataclass
class Document:
    """Blocks of a report; ``to_markdown`` and ``to_html`` render the same content."""

    title: str
    blocks: list[tuple[str, object]] = field(default_factory=list)

    def heading(self, text: str, level: int = 2) -> None:
        self.blocks.append(("heading", (level, text)))

    def paragraph(self, text: str) -> None:
        """A paragraph; ``**bold**`` and ``code`` spans are rendered in both formats."""
        self.blocks.append(("paragraph", text))

    def bullets(self, items: list[str]) -> None:
        self.blocks.append(("bullets", items))

    def table(self, header: list[str], rows: list[list[object]]) -> None:
        self.blocks.append(("table", (header, rows)))

    def figure(self, path: str | Path, caption: str) -> None:
        self.blocks.append(("figure", (Path(path), caption)))

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
            elif kind == "figure":
                path, caption = payload
                shown = path.relative_to(relative_to) if relative_to and path.is_relative_to(relative_to) else path
                out += [f"![{caption}]({shown.as_posix()})", "", f"*{caption}*", ""]
        return "\n".join(out)

    def to_html(self) -> str:
        parts = ["<!DOCTYPE html>", "<html lang='en'><head><meta charset='utf-8'>",
                 f"<title>{html.escape(self.title)}</title><style>{_CSS}</style></head><body>",
                 f"<h1>{html.escape(self.title)}</h1>"]
        for kind, payload in self.blocks:
            if kind == "heading":
                level, text = payload
                parts.append(f"<h{level}>{_inline(text)}</h{level}>")
            elif kind == "paragraph":
                parts.append(f"<p>{_inline(payload)}</p>")
            elif kind == "bullets":
                parts.append("<ul>" + "".join(f"<li>{_inline(i)}</li>" for i in payload) + "</ul>")
            elif kind == "table":
                header, rows = payload
                parts.append("<table><thead><tr>" + "".join(f"<th>{_inline(h)}</th>" for h in header)
                             + "</tr></thead><tbody>")
                parts += ["<tr>" + "".join(f"<td>{_inline(_cell(c))}</td>" for c in row) + "</tr>" for row in rows]
                parts.append("</tbody></table>")
            elif kind == "figure":
                path, caption = payload
                data = base64.b64encode(Path(path).read_bytes()).decode("ascii")
                parts.append(f"<figure><img alt='{html.escape(caption)}' src='data:image/png;base64,{data}'>"
                             f"<figcaption>{_inline(caption)}</figcaption></figure>")
        parts.append("</body></html>")
        return "\n".join(parts)


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
