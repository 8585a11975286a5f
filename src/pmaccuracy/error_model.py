"""Deprecated alias of :mod:`pmaccuracy.accuracy.error_model` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .accuracy import error_model as _module

warnings.warn("pmaccuracy.error_model moved to pmaccuracy.accuracy.error_model; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
