"""Deprecated alias of :mod:`pmaccuracy.report.document` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .report import document as _module

warnings.warn("pmaccuracy.document moved to pmaccuracy.report.document; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
