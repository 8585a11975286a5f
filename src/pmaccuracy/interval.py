"""Deprecated alias of :mod:`pmaccuracy.accuracy.interval` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .accuracy import interval as _module

warnings.warn("pmaccuracy.interval moved to pmaccuracy.accuracy.interval; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
