"""Deprecated alias of :mod:`pmaccuracy.report.figures` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .report import figures as _module

warnings.warn("pmaccuracy.figures moved to pmaccuracy.report.figures; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
