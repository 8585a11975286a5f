"""Deprecated alias of :mod:`pmaccuracy.report.accuracy_report` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .report import accuracy_report as _module

warnings.warn("pmaccuracy.accuracy_report moved to pmaccuracy.report.accuracy_report; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
