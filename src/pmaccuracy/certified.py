"""Deprecated alias of :mod:`pmaccuracy.accuracy.certified` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .accuracy import certified as _module

warnings.warn("pmaccuracy.certified moved to pmaccuracy.accuracy.certified; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
