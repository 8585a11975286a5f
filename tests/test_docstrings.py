"""Every example in the package's docstrings runs and prints what it shows (doctest), so the
examples the style guide asks for stay true as the code changes."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import pmaccuracy

MODULES = sorted(m.name for m in pkgutil.walk_packages(pmaccuracy.__path__, "pmaccuracy.")
                 if not m.name.endswith("__main__"))


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE, report=False)
    assert result.failed == 0, f"{name}: {result.failed} of {result.attempted} examples fail (run doctest on it)"
