"""Deprecated alias of :mod:`pmaccuracy.report.experiment_report` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .report import experiment_report as _module

warnings.warn("pmaccuracy.experiment_report moved to pmaccuracy.report.experiment_report; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
