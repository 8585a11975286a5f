"""Readable ``repr`` and notebook tables (``_repr_html_``) of the result objects: one rule for all of them.

A result's ``repr`` names the class, the number of poses and each quantity's range with its unit (mm, deg);
its HTML form is a table of the first :data:`MAX_ROWS` rows of its ``records()``.
"""

from __future__ import annotations

import html

import numpy as np

#: Rows shown by an HTML table (the rest are counted below it).
MAX_ROWS = 12


def value_range(values, unit: str, scale: float = 1.0) -> str:
    """``"0.1957 mm"`` for one finite value, ``"0.1957..0.2557 mm"`` for several, ``"nan"`` when none is finite.

    >>> value_range(np.array([0.2557, 0.1957]), "mm")
    '0.1957..0.2557 mm'
    """
    a = np.asarray(values, dtype=float).ravel() * scale
    a = a[np.isfinite(a)]
    if a.size == 0:
        return "nan"
    lo, hi = a.min(), a.max()
    return f"{lo:.4g} {unit}" if np.isclose(lo, hi, rtol=1e-12, atol=0) else f"{lo:.4g}..{hi:.4g} {unit}"


def summary(name: str, count: int, parts: list[str]) -> str:
    """``Name(n poses: part, part, ...)``."""
    what = f"{count} pose" + ("" if count == 1 else "s")
    return f"{name}({what}: " + ", ".join(parts) + ")"


def html_table(title: str, records: list[dict]) -> str:
    """An HTML table of ``records`` (dicts with the same keys), at most :data:`MAX_ROWS` rows shown."""
    if not records:
        return f"<p>{html.escape(title)}: empty</p>"
    keys = list(records[0])

    def cell(v):
        return f"{v:.6g}" if isinstance(v, float) else html.escape(str(v))

    head = "".join(f"<th>{html.escape(k)}</th>" for k in keys)
    rows = "".join("<tr>" + "".join(f"<td>{cell(r.get(k))}</td>" for k in keys) + "</tr>"
                   for r in records[:MAX_ROWS])
    more = f"<p>... {len(records) - MAX_ROWS} more rows</p>" if len(records) > MAX_ROWS else ""
    return f"<p><b>{html.escape(title)}</b></p><table><tr>{head}</tr>{rows}</table>{more}"
