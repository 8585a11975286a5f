"""Deprecated alias of :mod:`pmaccuracy.report.experiment_plots` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .report import experiment_plots as _module

warnings.warn("pmaccuracy.experiment_plots moved to pmaccuracy.report.experiment_plots; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
