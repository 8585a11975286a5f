"""The examples of the README and of the guide's pages run verbatim and print what the documents show.

The documents: ``README.md``, then the guide's pages (``docs/guide/*.md``) in the order of the toctree of
``docs/guide.md``. Rules (also stated in the guide, "How the examples are checked"):

* Every ```` ```console ```` block is a sequence of ``$ COMMAND`` lines, each followed by the
  exact output it prints (stdout and stderr together, as a terminal shows them), up to the next
  ``$`` line or the end of the block. A command line ending in ``\\`` continues on the next line.
  Blank lines between examples are not output; trailing spaces are ignored. Text must match
  exactly; numbers must agree to a relative 1e-4 (:func:`same_output`): the camera calibration
  (OpenCV) varies in the seventh significant digit from run to run, everything else is exact.
* Every command runs through ``bash`` exactly as written (``# ...`` comments included), with the
  test environment's ``pmaccuracy`` first on ``PATH``, in a temporary working folder of its document
  (one test per document, so the pages run in parallel), in document order: a later example may read
  a file an earlier one of the same page wrote (``m.csv``, ``cal.toml``, ...). The exit status is not
  checked, the printed text is.
* A command whose comment contains ``not run by tests`` (with the reason: minutes of run time,
  50 GB of disk) is skipped; the test counts the skipped lines and checks that they are exactly
  the marked ones.
* Every ```` ```python ```` block runs with ``exec`` in a fresh namespace, in its document's folder
  after that document's console blocks (so ``map.nc`` etc. may be overwritten freely).

The commands run through ``tests/cli_forkserver.py``: one process per test worker imports the package once
and forks a child per command, which runs the console script's ``main`` with the command's descriptors,
folder and environment (the same output; :func:`test_fork_server_prints_what_the_console_script_prints`).
The whole module then costs about 42 s of CPU (was about 120 s with a fresh interpreter per command), under
30 s of wall time on two workers.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
GUIDE = ROOT / "docs" / "guide.md"
COMMANDS_PAGE = ROOT / "docs" / "guide" / "commands.md"
SKIP_MARK = "not run by tests"


def documents() -> list[Path]:
    """The README, then the guide's pages in the order of ``docs/guide.md``'s toctree."""
    text = GUIDE.read_text(encoding="utf-8")
    block = re.search(r"```\{toctree\}\n(.*?)```", text, flags=re.S)
    assert block, "docs/guide.md has no toctree"
    pages = [line.strip() for line in block.group(1).splitlines() if line.strip() and not line.startswith(":")]
    return [README] + [ROOT / "docs" / f"{page}.md" for page in pages]


@dataclass(frozen=True)
class Example:
    """One ``$`` command of a console block and the output lines the README shows after it."""

    line: int          # document line of the ``$``
    command: str       # continuation lines joined with newlines (bash understands ``\\`` + newline)
    expected: tuple[str, ...]

    @property
    def skipped(self) -> bool:
        return SKIP_MARK in self.command


def _blocks(text: str, lang: str) -> list[tuple[int, list[str]]]:
    """``(first line number, lines)`` of every fenced block of language ``lang``."""
    out, lines = [], text.splitlines()
    k = 0
    while k < len(lines):
        if lines[k].strip() == f"```{lang}":
            start = k + 1
            end = start
            while lines[end].strip() != "```":
                end += 1
            out.append((start + 1, lines[start:end]))
            k = end
        k += 1
    return out


def console_examples(text: str, name: str = "README.md") -> list[Example]:
    """Parse every ```` ```console ```` block of ``text`` into :class:`Example` s, in order."""
    examples: list[Example] = []
    for first, lines in _blocks(text, "console"):
        k = 0
        while k < len(lines):
            if not lines[k].startswith("$ "):
                if lines[k].strip():
                    raise AssertionError(f"{name} line {first + k}: output before any '$' command: {lines[k]!r}")
                k += 1
                continue
            start = k
            cmd = [lines[k][2:]]
            while cmd[-1].rstrip().endswith("\\"):
                k += 1
                cmd.append(lines[k])
            k += 1
            out = []
            while k < len(lines) and not lines[k].startswith("$ "):
                out.append(lines[k].rstrip())
                k += 1
            while out and not out[-1]:
                out.pop()
            examples.append(Example(first + start, "\n".join(cmd), tuple(out)))
    return examples


def python_blocks(text: str) -> list[tuple[int, str]]:
    return [(first, "\n".join(lines)) for first, lines in _blocks(text, "python")]


_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
#: Relative tolerance on numbers (see the module docstring): OpenCV's calibration moves the 6th digit of the
#: vision uncertainties between runs (seen: 8e-6 relative), so 1e-4.
RTOL = 1e-4


def _squeeze(text: str) -> str:
    """Every run of white space as one space (leading and trailing runs kept as one space)."""
    return re.sub(r"\s+", " ", text)


def same_output(got: tuple[str, ...] | list[str], expected: tuple[str, ...] | list[str]) -> bool:
    """Equal line by line, the text between numbers exactly and the numbers to a relative :data:`RTOL`."""
    if len(got) != len(expected):
        return False
    for a, b in zip(got, expected):
        if a == b:
            continue
        na, nb = _NUMBER.findall(a), _NUMBER.findall(b)
        ta, tb = _NUMBER.split(a), _NUMBER.split(b)
        if na != nb:  # numbers of other widths re-pad aligned columns: spacing compared only as "some space"
            ta, tb = ([_squeeze(t) for t in x] for x in (ta, tb))
        if ta != tb:
            return False
        if len(na) != len(nb) or any(abs(float(x) - float(y)) > RTOL * max(abs(float(x)), abs(float(y)))
                                     for x, y in zip(na, nb)):
            return False
    return True


def _env() -> dict[str, str]:
    env = dict(os.environ)
    bindir = str(Path(sys.executable).parent)
    env["PATH"] = bindir + os.pathsep + env.get("PATH", "")
    env["COLUMNS"] = "100"
    env.pop("PMACCURACY_PROGRESS", None)
    return env


@pytest.fixture(scope="module")
def shim(tmp_path_factory):
    """A folder holding a ``pmaccuracy`` that runs each command in a fork of one pre-imported process
    (``tests/cli_forkserver.py``: the same output, half a second less per command); None (the installed console
    script) where the server does not start."""
    import shutil
    import tempfile
    import time

    folder = Path(tempfile.mkdtemp(prefix="pmf"))          # short: a Unix socket path has at most 107 bytes
    sock = str(folder / "s")
    env = _env()
    env.pop("PYTHONUNBUFFERED", None)      # buffered as a console script writing to a pipe (the children inherit it)
    server = subprocess.Popen([sys.executable, str(Path(__file__).with_name("cli_forkserver.py")), sock],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    deadline = time.monotonic() + 60
    while not Path(sock + ".ready").exists() and server.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    if Path(sock + ".ready").exists():
        from cli_forkserver import client_script

        client = folder / "pmaccuracy"
        client.write_text(client_script(sys.executable, sock))
        client.chmod(0o755)
        yield folder
    else:
        yield None
    server.kill()
    server.wait()
    shutil.rmtree(folder, ignore_errors=True)


def _run(example: Example, cwd: Path, shim: Path | None = None) -> list[str]:
    env = _env()
    if shim is not None:
        env["PATH"] = str(shim) + os.pathsep + env["PATH"]
    proc = subprocess.run(["bash", "-c", example.command], cwd=cwd, env=env, stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True, timeout=300)
    lines = [ln.rstrip() for ln in proc.stdout.splitlines()]
    while lines and not lines[-1]:
        lines.pop()
    return lines


def test_parser_on_a_made_up_block():
    text = ("x\n```console\n$ pmaccuracy a \\\n    --b 1   # c\n out 1\n\n out 2\n\n$ pmaccuracy d  # not run by tests: slow\n"
            "```\n```python\nx = 1\n```\n")
    ex = console_examples(text)
    assert [e.command for e in ex] == ["pmaccuracy a \\\n    --b 1   # c", "pmaccuracy d  # not run by tests: slow"]
    assert ex[0].expected == (" out 1", "", " out 2") and ex[1].expected == ()
    assert [e.skipped for e in ex] == [False, True]
    assert python_blocks(text) == [(12, "x = 1")]


def test_same_output_tolerates_only_last_digits():
    assert same_output(["a 0.000750904  x"], ["a 0.000750905  x"])
    assert not same_output(["a 0.00075090  x"], ["a 0.00075190  x"])
    assert not same_output(["a 1  x"], ["a 1 x"])          # spacing is text
    assert same_output(["0.00074525   0.000845 x"], ["0.000745249  0.000845 x"])   # re-padded column
    assert not same_output(["0.00074525   0.000845 x"], ["0.000745249  0.000845x"])
    assert not same_output(["a 1"], ["b 1"]) and not same_output(["1"], ["1", ""])


def test_guide_pages_are_all_in_the_toctree():
    """A page left out of ``docs/guide.md`` would have its examples silently skipped (and warn in sphinx)."""
    pages = sorted(p.name for p in (ROOT / "docs" / "guide").glob("*.md"))
    assert sorted(p.name for p in documents()[1:]) == pages


def _label(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def test_documented_examples_are_collected():
    docs = [(path, path.read_text(encoding="utf-8")) for path in documents()]
    examples = [(path, ex) for path, text in docs for ex in console_examples(text, _label(path))]
    assert len(examples) > 40
    assert len(console_examples(docs[0][1])) >= 5          # the README has its own examples
    skipped = [ex for _, ex in examples if ex.skipped]
    # the only examples left out: the 50 GB map and the full reports (each minutes or gigabytes)
    assert len(skipped) <= 4, [e.command for e in skipped]
    assert all(re.search(r"#.*not run by tests: \S", e.command) for e in skipped)


@pytest.mark.parametrize("path", [p for p in documents()
                                  if "```console" in p.read_text(encoding="utf-8")
                                  or "```python" in p.read_text(encoding="utf-8")], ids=_label)
def test_documented_examples_run_verbatim(path, tmp_path, shim):
    """Each document's examples in order, in a folder of their own (a page's examples may use the files its
    earlier examples wrote, never another page's): the pages run in parallel."""
    text = path.read_text(encoding="utf-8")
    failures = []
    for ex in console_examples(text, _label(path)):
        if ex.skipped:
            continue
        got = _run(ex, tmp_path, shim)
        if not same_output(got, ex.expected):
            failures.append(f"{_label(path)} line {ex.line}: $ {ex.command}\n--- document\n"
                            + "\n".join(ex.expected) + "\n--- printed\n" + "\n".join(got))
    assert not failures, "\n\n".join(failures)
    for first, code in python_blocks(text):
        cwd = os.getcwd()
        os.chdir(tmp_path)
        try:
            exec(compile(code, f"{_label(path)} (python block at line {first})", "exec"), {"__name__": "docs"})
        finally:
            os.chdir(cwd)


def test_fork_server_prints_what_the_console_script_prints(shim, tmp_path):
    """The documentation's ``pmaccuracy`` (a fork of a pre-imported process) and the installed console script
    print the same text and exit with the same status: a result, an error with status 2, a pipe."""
    assert shim is not None, "the fork server did not start"
    for command in ("pmaccuracy bounds --pose 0 0 0 --pose 5 5 5", "pmaccuracy bounds --pose 0 0",
                    "pmaccuracy map --grid 5 --phi-deg 0 --out m.csv && head -n 3 m.csv; echo status $?",
                    "pmaccuracy bounds --robot stewart_6ups --pose 0 0 400 0 0 0 2>&1 | head -n 2; echo $?"):
        ex = Example(line=0, command=command + "; echo exit $?", expected=())
        assert _run(ex, tmp_path, shim) == _run(ex, tmp_path), command


def _leaf_parsers() -> dict[str, argparse.ArgumentParser]:
    """``{"bounds": parser, "experiment simulate": parser, ...}``: every command that runs something."""
    from pmaccuracy.cli import build_parser

    out = {}

    def walk(parser: argparse.ArgumentParser, prefix: str) -> None:
        subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        if not subs:
            out[prefix.strip()] = parser
        for action in subs:
            for name, child in action.choices.items():
                walk(child, f"{prefix} {name}")

    walk(build_parser([], load_all=True), "")
    return out


def _names(fragment: str) -> set[str]:
    """Command names in backticks, ``a b|c`` standing for ``a b`` and ``a c``."""
    names = set()
    for name in re.findall(r"`([a-z][a-z |-]*)`", fragment.replace("\n", " ")):
        head, _, alts = name.rpartition(" ")
        names |= {f"{head} {a}".strip() for a in alts.split("|")}
    return names


def test_readme_statement_of_common_options_is_exact():
    """The guide's common options name the commands with --robot and those without --format: check both lists."""
    text = " ".join(COMMANDS_PAGE.read_text(encoding="utf-8").split())
    robot = re.search(r"The commands about a robot \((.*?)\) take `--robot`", text)
    no_format = re.search(r"`--format table\|json\|csv` \(default `table`\): all but (.*?)\.", text)
    assert robot and no_format, "the guide's sentences on --robot and --format changed: update this test"
    parsers = _leaf_parsers()

    def has(parser: argparse.ArgumentParser, option: str) -> bool:
        return any(option in a.option_strings for a in parser._actions)

    assert {n for n, p in parsers.items() if has(p, "--robot")} == _names(robot.group(1))
    assert {n for n, p in parsers.items() if not has(p, "--format")} == _names(no_format.group(1))
    assert all(has(p, "--help") for p in parsers.values())


def _update(folder: Path) -> None:
    """Re-generate the documents' outputs by running every example (``python tests/test_readme.py --update DIR``)."""
    for path in documents():
        lines = path.read_text(encoding="utf-8").split("\n")
        replacements = []
        for ex in console_examples("\n".join(lines), _label(path)):
            if ex.skipped:
                continue
            got = _run(ex, folder)
            if not same_output(got, ex.expected):
                start = ex.line - 1 + ex.command.count("\n") + 1     # first line after the command
                replacements.append((start, start + len(ex.expected), got))
                print(f"{_label(path)} line {ex.line}: $ {ex.command}: output updated")
        for start, stop, got in reversed(replacements):
            lines[start:stop] = got
        path.write_text("\n".join(lines), encoding="utf-8")


if __name__ == "__main__":  # python tests/test_readme.py [--update] DIR: show (or write back) every example's output
    update = "--update" in sys.argv
    folder = Path([a for a in sys.argv[1:] if a != "--update"][0])
    folder.mkdir(parents=True, exist_ok=True)
    if update:
        _update(folder)
        sys.exit(0)
    for path in documents():
        for ex in console_examples(path.read_text(encoding="utf-8"), _label(path)):
            print(f"### {_label(path)} line {ex.line}: $ {ex.command}")
            if ex.skipped:
                print("(skipped)")
                continue
            got = _run(ex, folder)
            print("\n".join(got))
            print("### " + ("SAME" if same_output(got, ex.expected) else "DIFFERENT"))
