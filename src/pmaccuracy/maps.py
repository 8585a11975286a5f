"""Deprecated alias of :mod:`pmaccuracy.accuracy.maps` (the module moved there; this name stays for one release)."""

import sys
import warnings

from .accuracy import maps as _module

warnings.warn("pmaccuracy.maps moved to pmaccuracy.accuracy.maps; import it from there", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _module
