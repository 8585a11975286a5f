"""Deprecated alias of :mod:`pmaccuracy.accuracy.bounds` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .accuracy import bounds as _module

warnings.warn("pmaccuracy.bounds moved to pmaccuracy.accuracy.bounds; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
