"""Sphinx configuration of the pmaccuracy documentation (built offline: ``make docs``, warnings as errors)."""

import pmaccuracy

project = "pmaccuracy"
author = "the pmaccuracy developers"
release = version = pmaccuracy.__version__
copyright = "2026, the pmaccuracy developers"

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "myst_parser",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "generated/*.tmp"]

autosummary_generate = True
templates_path = ["_templates"]
autodoc_default_options = {"members": False, "show-inheritance": True}
autodoc_typehints = "none"          # the docstrings state shapes and units
napoleon_numpy_docstring = True
napoleon_google_docstring = False
napoleon_use_rtype = False
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath"]   # $\delta x_{max}$ in the guide, as GitHub renders it
# Console blocks are plain text (no lexer).
suppress_warnings = ["misc.highlighting_failure"]

html_theme = "pydata_sphinx_theme"
html_title = f"pmaccuracy {release}"
html_theme_options = {"navigation_with_keys": False, "show_toc_level": 2}
# Built offline: no intersphinx, no remote assets.
