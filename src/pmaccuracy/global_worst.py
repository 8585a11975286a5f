"""Deprecated alias of :mod:`pmaccuracy.accuracy.global_worst` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .accuracy import global_worst as _module

warnings.warn("pmaccuracy.global_worst moved to pmaccuracy.accuracy.global_worst; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
