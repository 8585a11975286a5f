"""Deprecated alias of :mod:`pmaccuracy.accuracy.designs` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .accuracy import designs as _module

warnings.warn("pmaccuracy.designs moved to pmaccuracy.accuracy.designs; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
