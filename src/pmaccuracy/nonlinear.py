"""Deprecated alias of :mod:`pmaccuracy.accuracy.nonlinear` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .accuracy import nonlinear as _module

warnings.warn("pmaccuracy.nonlinear moved to pmaccuracy.accuracy.nonlinear; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
