"""Every local link of the documents and of the reports' text points to something that exists.

Checked: the Markdown links ``[text](target)`` of the README and of the guide pages (relative targets must
exist, and an ``#anchor`` into a Markdown page must be one of its headings); the repository paths the
documents and the package's own texts (reports, docstrings, messages) name in backticks, such as
``tests/report/test_report.py`` or ``docs/guide/default-robot.md``. The report as written is checked by
``tests/report/test_report.py`` with :func:`local_targets`.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCUMENTS = sorted([ROOT / "README.md", *(ROOT / "docs").rglob("*.md"), *(ROOT / "docs").glob("*.rst")])
DOCUMENTS = [p for p in DOCUMENTS if "_build" not in p.parts and "generated" not in p.parts]

_LINK = re.compile(r"(?<!!)\[[^\]]*\]\(([^)\s]+)\)|!\[[^\]]*\]\(([^)\s]+)\)")
_HTML_LINK = re.compile(r"""(?:href|src)=["']([^"']+)["']""")
#: A repository path in backticks: under one of the repository's folders (or the external ``shared/`` folder
#: the report used to name), with a file type.
_REPO_PATH = re.compile(r"`((?:src|tests|docs|benchmarks|shared|\.\./shared)/[\w./-]+\.(?:md|py|toml|rst|csv|txt))`")


def _external(target: str) -> bool:
    return bool(re.match(r"^[a-z][a-z0-9+.-]*:", target)) or target.startswith("//")


def local_targets(text: str) -> list[str]:
    """The relative link targets of Markdown or HTML ``text`` (no URLs with a scheme, no ``#`` alone, no data)."""
    found = [a or b for a, b in _LINK.findall(text)] + _HTML_LINK.findall(text)
    return [t for t in found if t and not t.startswith("#") and not _external(t)]


def repository_paths(text: str) -> list[str]:
    """The repository paths named in backticks in ``text``."""
    return _REPO_PATH.findall(text)


def slug(heading: str) -> str:
    """The anchor of a Markdown heading, as GitHub and MyST write it (lower case, punctuation dropped)."""
    text = re.sub(r"[^\w\s-]", "", heading.strip().lower())
    return re.sub(r"\s", "-", text)


def headings(path: Path) -> set[str]:
    out, fence = set(), False
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("```"):
            fence = not fence
        elif not fence and re.match(r"^#{1,6} ", line):
            out.add(slug(line.lstrip("#")))
    return out


def test_slug_is_the_anchor_sphinx_writes():
    assert slug("`ik` and `fk`: kinematics") == "ik-and-fk-kinematics"
    assert slug("5. The worst case over a region, and the report") == "5-the-worst-case-over-a-region-and-the-report"


@pytest.mark.parametrize("path", DOCUMENTS, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_relative_links_of_the_documents_exist(path):
    text = path.read_text(encoding="utf-8")
    text = re.sub(r"```.*?```", "", text, flags=re.S)       # code blocks are not links
    missing = []
    for target in local_targets(text):
        file, _, anchor = target.partition("#")
        where = (path.parent / file).resolve() if file else path
        if not where.exists():
            missing.append(target)
        elif anchor and where.suffix == ".md" and anchor not in headings(where):
            missing.append(f"{target} (no such heading)")
    assert not missing, f"{path.relative_to(ROOT)}: {missing}"
    assert all((ROOT / p).exists() for p in repository_paths(text)), \
        [p for p in repository_paths(text) if not (ROOT / p).exists()]


def test_the_package_names_only_files_of_the_repository():
    """Reports, messages and docstrings name repository files (``docs/guide/default-robot.md``) that exist."""
    missing = []
    for path in (ROOT / "src" / "pmaccuracy").rglob("*.py"):
        for name in repository_paths(path.read_text(encoding="utf-8")):
            if not (ROOT / name).exists():
                missing.append(f"{path.relative_to(ROOT)}: {name}")
    assert not missing, missing


def test_the_checks_catch_a_missing_file(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("# Title\n\nSee [there](other.md#nowhere), [here](#title) and `shared/reference/x.md`.\n")
    (tmp_path / "other.md").write_text("# Other\n")
    assert local_targets(page.read_text()) == ["other.md#nowhere"]
    assert "nowhere" not in headings(tmp_path / "other.md") and "title" in headings(page)
    assert repository_paths(page.read_text()) == ["shared/reference/x.md"]
