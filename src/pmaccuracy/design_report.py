"""Deprecated alias of :mod:`pmaccuracy.report.design_report` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .report import design_report as _module

warnings.warn("pmaccuracy.design_report moved to pmaccuracy.report.design_report; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
