"""Deprecated alias of :mod:`pmaccuracy.experiment.measure` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .experiment import measure as _module

warnings.warn("pmaccuracy.measure moved to pmaccuracy.experiment.measure; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
