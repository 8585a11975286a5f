"""Deprecated alias of :mod:`pmaccuracy.accuracy.distributions` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .accuracy import distributions as _module

warnings.warn("pmaccuracy.distributions moved to pmaccuracy.accuracy.distributions; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
