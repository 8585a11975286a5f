"""Deprecated alias of :mod:`pmaccuracy.accuracy.synthesis` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .accuracy import synthesis as _module

warnings.warn("pmaccuracy.synthesis moved to pmaccuracy.accuracy.synthesis; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
