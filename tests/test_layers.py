"""The package's layers: every import points down, and no modules import each other in a cycle.

Read from the source (``ast``), so imports inside functions count as much as those at the top of a module.
Layers, lowest first (docs/guide/layout.md); a module may import from its own layer and the layers below:
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "pmaccuracy"

LAYERS = [
    ("errors", "_optional", "_display", "_savefig", "_textfile"),
    ("numerics",),
    ("model",),
    ("kinematics",),
    ("io",),
    ("accuracy",),
    ("experiment",),
    ("vision",),
    ("report",),
    ("api",),
    ("cli",),
]

#: Imports that still point up or close a cycle, each with why it is still there. The list only shrinks:
#: a new entry needs a reason in review; an entry that no longer occurs fails the test (remove it).
ALLOWED: dict[tuple[str, str], str] = {}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def layer_of(module: str) -> int | None:
    """Index of the layer of ``pmaccuracy.<top>...`` (None for the package root)."""
    parts = module.split(".")
    if len(parts) < 2:
        return None
    for k, names in enumerate(LAYERS):
        if parts[1] in names:
            return k
    raise AssertionError(f"{module} is in no layer: add its top-level name to LAYERS")


def imports() -> dict[str, set[str]]:
    """Every module's intra-package imports (resolved to modules; inside functions too)."""
    files = {module_name(p): p for p in SRC.rglob("*.py")}
    out: dict[str, set[str]] = defaultdict(set)
    for mod, path in files.items():
        package = mod if path.name == "__init__.py" else mod.rsplit(".", 1)[0]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")
                    base = base[: len(base) - node.level + 1]
                    base = ".".join(base + ([node.module] if node.module else []))
                else:
                    base = node.module or ""
                if not base.startswith("pmaccuracy"):
                    continue
                for a in node.names:
                    target = f"{base}.{a.name}"
                    out[mod].add(target if target in files else base)
            elif isinstance(node, ast.Import):
                out[mod].update(a.name for a in node.names if a.name.startswith("pmaccuracy"))
    return {m: {t for t in ts if t != m} for m, ts in out.items()}


def test_every_module_is_in_a_layer():
    for path in SRC.rglob("*.py"):
        layer_of(module_name(path))


def test_imports_point_down():
    wrong = set()
    for mod, targets in imports().items():
        lm = layer_of(mod)
        if lm is None:
            continue
        for t in targets:
            lt = layer_of(t)
            if lt is not None and lt > lm:
                wrong.add((mod, t))
    unexpected = sorted(wrong - set(ALLOWED))
    assert not unexpected, "imports that point up a layer: " + ", ".join(f"{a} -> {b}" for a, b in unexpected)
    stale = sorted(set(ALLOWED) - wrong - set(_cycle_edges()))
    assert not stale, f"ALLOWED entries that no longer occur (remove them): {stale}"


def _cycle_edges() -> set[tuple[str, str]]:
    """Edges inside strongly connected components (Tarjan) of the module graph."""
    graph = {m: {t for t in ts if layer_of(t) is not None} for m, ts in imports().items() if layer_of(m) is not None}
    index, low, stack, on, comps, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = set()
            while True:
                w = stack.pop()
                on.discard(w)
                comp.add(w)
                if w == v:
                    break
            comps.append(comp)

    for v in list(graph):
        if v not in index:
            visit(v)
    return {(a, b) for comp in comps if len(comp) > 1 for a in comp for b in graph.get(a, ()) if b in comp}


def test_no_import_cycles():
    edges = _cycle_edges() - set(ALLOWED)
    assert not edges, "modules importing each other in a cycle: " + ", ".join(f"{a} -> {b}" for a, b in sorted(edges))


#: Where an import of the package's own modules may sit inside a function: the command line loads each
#: command's module (and what it needs) only when that command runs, so that ``pmaccuracy bounds`` starts
#: without the map, vision or report code (tests/io/test_csvio.py measures it).
LAZY_OK = ("pmaccuracy.cli",)


def test_imports_inside_functions_only_where_lazy_loading_is_the_point():
    """An import inside a function is for an optional heavy dependency (``_optional.require``) or the command
    line's lazy loading, never to hide a cycle."""
    found = []
    for path in SRC.rglob("*.py"):
        mod = module_name(path)
        if mod.startswith(LAZY_OK) or layer_of(mod) is None:
            continue
        for f in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for node in ast.walk(f):
                    if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").startswith("pmaccuracy")):
                        found.append(f"{mod}:{node.lineno}")
    assert not found, "imports of the package inside functions: " + ", ".join(sorted(found))
